"""The explorer's robot controls (issue 21, items 1-4): actuation delay, safety filter, slot assignment.

Every answer is checked against the library called directly (an independent
path: no server, no caches, no controls' routing): the point and chart
against the certified dominant root and the exact CTCR map at tau_a, the
runs against :func:`~delayform.simulation.simulate`, the downloads by reading
them back with the scenario parser.
"""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest
from test_actuation import _certified_nu
from test_explorer import get, get_json

from delayform.analysis.ctcr.stability_map import stability_map
from delayform.analysis.roots.dominant import dominant_root
from delayform.app import Explorer, start
from delayform.scenario import paper_scenario, parse_scenario
from delayform.simulation import IROBOT_CREATE, simulate
from delayform.simulation.models.robots import Robot
from delayform.topology import paper_six


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory):
    with start(Explorer(paper_scenario(), out_dir=tmp_path_factory.mktemp("robot") / "out")) as running:
        yield running


def _direct(duration: float, **robot: object):
    s = paper_scenario()
    assignment = str(robot.pop("assignment", "given"))
    return simulate(s.topology, 1.0, 0.5, 0.3, 0.2, s.desired_positions(),
                    robot=Robot(model="unicycle", radius=s.radius, **robot),  # type: ignore[arg-type]
                    initial_positions=s.initial_positions(), initial_headings=s.initial_headings(),
                    initial_speed=s.initial.speed, seed=s.initial.seed, duration=duration, dt=s.simulation.dt,
                    assignment=assignment)  # fmt: skip


def test_scenario_lists_the_controls_with_the_scenarios_defaults(server) -> None:
    rc = get_json(server, "/api/scenario")["robot_controls"]
    assert rc["defaults"] == {"actuation_delay": 0.0, "safety": False, "assignment": False}
    assert rc["max_actuation_delay"] > 0


def test_point_and_chart_at_the_pages_actuation_delay(server) -> None:
    r = get_json(server, "/api/point?tau1=0.3&tau2=0.2&actuation_delay=0.3")
    ref = dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2, actuation_delay=0.3).root
    assert complex(*r["dominant_root"]) == pytest.approx(ref) and r["actuation_delay"] == 0.3
    assert r["stable"] is False and r["unstable_count"] == _certified_nu(paper_six(), 1.0, 0.5, 0.3, 0.2, 0.3)
    assert get_json(server, "/api/point?tau1=0.3&tau2=0.2")["stable"] is True  # the default: tau_a = 0
    chart = get_json(server, "/api/chart?tau1_max=3&tau2_max=3&grid=12&actuation_delay=0.1")
    exact = stability_map(paper_six(), 1.0, 0.5, 3.0, 3.0, actuation_delay=0.1)
    t = (np.arange(12) + 0.5) * 3.0 / 12
    np.testing.assert_array_equal(np.array(chart["grid"]["unstable_count"]), exact.unstable_count(t[None, :], t[:, None]))
    roots = get_json(server, "/api/roots?tau1=0.3&tau2=0.2&actuation_delay=0.3")
    assert complex(*roots["dominant_root"]) == pytest.approx(ref)


def test_answers_without_actuation_in_their_theory_refuse_it(server) -> None:
    for path in ("/api/guarantee", "/api/region"):
        status, _, body = get(server, f"{path}?tau1=0.3&tau2=0.2&actuation_delay=0.1")
        assert status == 400 and "actuation_delay" in json.loads(body)["error"]
        assert get(server, f"{path}?tau1=0.3&tau2=0.2&actuation_delay=0")[0] == 200


def test_runs_follow_the_controls(server) -> None:
    query = "/api/simulate?tau1=0.3&tau2=0.2&duration=15&frames=20"
    late = get_json(server, query + "&limits=1&actuation_delay=0.05")
    direct = _direct(15.0, limits=IROBOT_CREATE, actuation_delay=0.05)
    assert late["final_error"] == pytest.approx(float(direct.formation_error[-1]), rel=1e-9)
    assert late["final_error"] != get_json(server, query + "&limits=1")["final_error"]
    safe = get_json(server, query + "&safety=1")
    assert safe["final_error"] == pytest.approx(float(_direct(15.0, safety="barrier").formation_error[-1]), rel=1e-9)
    assert safe["min_distance"] >= 2 * safe["radius"] - 1e-9 and safe["radius"] > 0 and not safe["contacts"]
    slots = get_json(server, query + "&assignment=1")
    assert slots["final_error"] == pytest.approx(float(_direct(15.0, assignment="optimal").formation_error[-1]), rel=1e-9)
    # the paper's ideal robots cannot apply a late command (simulate's refusal, with its reason)
    status, _, body = get(server, query + "&actuation_delay=0.05")
    assert status == 400 and "ideal robots" in json.loads(body)["error"]


@pytest.mark.parametrize("bad", [
    "/api/point?tau1=0.3&tau2=0.2&actuation_delay=-0.1",
    "/api/point?tau1=0.3&tau2=0.2&actuation_delay=nan",
    "/api/point?tau1=0.3&tau2=0.2&actuation_delay=abc",
    "/api/point?tau1=0.3&tau2=0.2&actuation_delay=51",
    "/api/point?tau1=0.3&tau2=0.2&safety=1",  # changes nothing there: refused, not ignored
    "/api/chart?assignment=1",
    "/api/simulate?tau1=0.3&tau2=0.2&safety=2",
    "/api/simulate?tau1=0.3&tau2=0.2&assignment=yes&assignment=no",
    "/download/scenario.toml?tau1=0.3&tau2=0.2&actuation_delay=-1",
])  # fmt: skip
def test_bad_control_values_get_400_and_one_line(server, bad: str) -> None:
    status, kind, body = get(server, bad)
    assert status == 400 and kind.startswith("application/json")
    assert "\n" not in body.decode().strip() and 0 < len(json.loads(body)["error"]) < 200


def test_downloads_carry_the_controls(tmp_path: Path) -> None:
    out = tmp_path / "out"
    base = "tau1=0.3&tau2=0.2&duration=10&tau1_max=8&tau2_max=8&limits=1"
    with start(Explorer(paper_scenario(), out_dir=out)) as running:
        names = {}
        for label, extra in (("plain", ""), ("all", "&actuation_delay=0.05&safety=1&assignment=1")):
            status, _, body = get(running, f"/download/scenario.toml?{base}{extra}")
            assert status == 200, body
            names[label] = body
        files = sorted(p.name for p in out.iterdir())
    assert len(files) == 2 and any(re.search(r"_ta0\.05_barrier_optimal_", f) for f in files)
    again = parse_scenario(tomllib.loads(names["all"].decode()))
    assert again.actuation_delay == 0.05 and again.safety == "barrier" and again.simulation.assignment == "optimal"
    plain = parse_scenario(tomllib.loads(names["plain"].decode()))
    assert plain.actuation_delay == 0.0 and plain.safety is None and plain.simulation.assignment == "given"


def test_download_names_differ_from_the_scenarios_own_setting(tmp_path: Path) -> None:
    import dataclasses

    late = dataclasses.replace(paper_scenario(), actuation_delay=0.05)  # the scenario's own tau_a
    out = tmp_path / "out"
    base = "tau1=0.3&tau2=0.2&duration=10&tau1_max=8&tau2_max=8&limits=1"
    with start(Explorer(late, out_dir=out)) as running:
        for extra in ("", "&actuation_delay=0", "&actuation_delay=0.05&safety=1"):
            assert get(running, f"/download/scenario.toml?{base}{extra}")[0] == 200
    names = sorted(p.name for p in out.iterdir())
    assert len(names) == 3 and any("_ta0_" in n for n in names) and any("_barrier_" in n for n in names)
    assert sorted(parse_scenario(tomllib.loads((out / n).read_text())).actuation_delay for n in names) == [0.0, 0.05, 0.05]
