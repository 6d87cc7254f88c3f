"""The explorer's server over real HTTP on the loopback: answers, refusals, limits, files.

Every answer is compared with an independent computation: the dominant root
with :func:`dominant_root`, NU with the argument principle
(:func:`count_roots_right_of`, factor by factor) and with the exact map, the
downloaded TOML with :func:`parse_scenario`.
"""

from __future__ import annotations

import http.client
import io
import json
import os
import tomllib
import urllib.error
import urllib.request
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from delayform.analysis.ctcr.stability_map import PAPER_POINTS, stability_map
from delayform.analysis.plane.region import lambda_region
from delayform.analysis.roots.dominant import count_roots_right_of, dominant_root, rightmost_root
from delayform.app import LOOPBACK, Explorer, ExplorerLimits, check_host, scenario_toml, start
from delayform.app.server import bind
from delayform.characteristic import factors
from delayform.cli import main
from delayform.errors import InputError
from delayform.scenario import load_scenario, paper_scenario, parse_scenario
from delayform.simulation import IROBOT_CREATE, simulate
from delayform.model.network import BernoulliLoss, Network

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("explorer") / "out"


@pytest.fixture(scope="module")
def server(out_dir: Path):
    with start(Explorer(paper_scenario(), out_dir=out_dir)) as running:
        yield running


def get(server, path: str, headers: dict[str, str] | None = None) -> tuple[int, str, bytes]:
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=60)
    try:
        conn.request("GET", path, headers=headers or {})
        resp = conn.getresponse()
        return resp.status, resp.getheader("Content-Type", ""), resp.read()
    finally:
        conn.close()


def get_json(server, path: str) -> dict:
    status, kind, body = get(server, path)
    assert status == 200, body
    assert kind.startswith("application/json")
    return json.loads(body)


# ---------------------------------------------------------------- answers
@pytest.mark.parametrize("label", sorted(PAPER_POINTS))
def test_point_agrees_with_dominant_root_and_the_argument_principle(server, label: str) -> None:
    t1, t2 = PAPER_POINTS[label]
    got = get_json(server, f"/api/point?tau1={t1}&tau2={t2}")
    team = paper_scenario().topology
    want = dominant_root(team, 1.0, 0.5, t1, t2).root
    assert abs(complex(*got["dominant_root"]) - want) <= 1e-9
    # NU by the argument principle along Re s = 1e-6, factor by factor: independent of CTCR
    nu = sum(f.multiplicity * count_roots_right_of(f, t1, t2, 1e-6) for f in factors(team, 1.0, 0.5))
    assert got["unstable_count"] == nu
    assert got["stable"] is (nu == 0) is (label != "c")  # Fig. stability: only c is unstable
    assert got["dominant_root_stable"] is got["stable"]
    # the dominant root is among the roots listed near the axis, and nothing lies right of it
    near = get_json(server, f"/api/roots?tau1={t1}&tau2={t2}")
    assert near["roots_certified"] and complex(*near["dominant_root"]) == complex(*got["dominant_root"])
    roots = np.array([complex(*r) for r in near["roots_near_axis"]])
    assert np.min(np.abs(roots - want)) <= 1e-8
    assert roots.real.max() <= want.real + 1e-9


@pytest.mark.parametrize("label", sorted(PAPER_POINTS))
def test_region_verdicts_agree_with_the_argument_principle_per_factor(server, label: str) -> None:
    t1, t2 = PAPER_POINTS[label]
    got = get_json(server, f"/api/region?tau1={t1}&tau2={t2}")
    team = paper_scenario().topology
    eig = np.array(got["eigenvalues"]["re"]) + 1j * np.array(got["eigenvalues"]["im"])
    counts = np.array(got["eigenvalue_unstable_count"])
    assert np.allclose(np.sort_complex(eig), np.sort_complex(team.eigenvalues), atol=1e-5)
    # each factor of eq. factorized counted by the argument principle in s, not in the lam plane
    for f in factors(team, 1.0, 0.5):
        members = np.abs(eig - f.lam) < 1e-4
        if f.group.is_complex_pair:
            members |= np.abs(eig - np.conj(f.lam)) < 1e-4
        want = f.multiplicity * count_roots_right_of(f, t1, t2, 1e-6)
        assert counts[members].sum() == want, (label, f.describe())
        # and against the factor's rightmost root (the per-factor root behind dominant_root)
        right = rightmost_root(f, t1, t2).real
        assert bool(np.all(np.array(got["eigenvalue_stable"])[members])) is (right < 0), (label, right)
    direct = lambda_region(1.0, 0.5, t1, t2).unstable_count(team.eigenvalues)
    assert np.array_equal(np.sort(direct), np.sort(counts))
    # the team's NU is the exact CTCR map's, and c is the only unstable point
    assert got["unstable_count"] == get_json(server, f"/api/point?tau1={t1}&tau2={t2}")["unstable_count"]
    assert got["stable"] is (label != "c")


def test_region_boundary_is_the_closed_form_curve(server) -> None:
    from scipy.spatial import cKDTree

    got = get_json(server, "/api/region?tau1=1&tau2=2")
    lam = np.array([complex(a, b) for a, b in zip(got["boundary"]["re"], got["boundary"]["im"], strict=True)
                    if a is not None])  # fmt: skip
    assert lam.size > 100 and np.all(np.abs(lam) <= got["radius"] + 1e-9)
    # L(j omega) = (s^2 + D s + P) / (D s e^{-tau2 s} + P e^{-tau1 s}) densely sampled
    s = 1j * np.linspace(-6.0, 6.0, 400_001)
    closed = (s * s + 0.5 * s + 1.0) / (0.5 * s * np.exp(-2.0 * s) + np.exp(-1.0 * s))
    closed = closed[np.abs(closed) <= got["radius"] + 0.1]
    dist, _ = cKDTree(np.c_[closed.real, closed.imag]).query(np.c_[lam.real, lam.imag])
    assert dist.max() < 2e-3
    grid = np.array(got["grid"]["unstable_count"])
    assert grid.shape == (len(got["grid"]["values"]),) * 2 and grid[grid.shape[0] // 2, grid.shape[1] // 2] == 0


def test_point_with_other_gains_uses_them(server) -> None:
    got = get_json(server, "/api/point?tau1=1&tau2=2&P=0.4&D=1.5")
    want = dominant_root(paper_scenario().topology, 0.4, 1.5, 1.0, 2.0)
    assert abs(complex(*got["dominant_root"]) - want.root) <= 1e-9
    assert got["stable"] is want.is_stable


def test_chart_shading_is_the_exact_map(server) -> None:
    chart = get_json(server, "/api/chart?P=1&D=0.5&tau1_max=8&tau2_max=8&grid=40")
    t1, t2 = np.array(chart["grid"]["tau1"]), np.array(chart["grid"]["tau2"])
    counts = np.array(chart["grid"]["unstable_count"])
    assert counts.shape == (40, 40)
    smap = stability_map(paper_scenario().topology, 1.0, 0.5, 8.0, 8.0)
    assert np.array_equal(counts, smap.unstable_count(t1[None, :], t2[:, None]))
    kernel = [x for x in chart["curves"]["kernel"]["tau1"] if x is not None]
    assert len(kernel) > 100 and sorted(p["label"] for p in chart["points"]) == list("abcde")


def test_animation_frames_are_a_run_of_simulate(server) -> None:
    sim = get_json(server, "/api/simulate?tau1=0.3&tau2=0.2&duration=30&frames=50")
    assert len(sim["times"]) == 50 and sim["times"][-1] == pytest.approx(30.0)
    assert np.array(sim["x"]).shape == (50, 6) and np.array(sim["heading"]).shape == (50, 6)
    assert sim["formation_error"][-1] < 0.05 * sim["formation_error"][0]  # point a settles
    # an unstable run (point c) grows and still comes back as plain JSON numbers
    status, _, body = get(server, "/api/simulate?tau1=1&tau2=2&duration=60&frames=20")
    grow = json.loads(body, parse_constant=lambda c: pytest.fail(f"non-JSON number {c}"))
    assert status == 200 and grow["formation_error"][-1] > 10 * grow["formation_error"][0]


def test_limits_switch_runs_the_saturated_robots(server) -> None:
    # the paper's robots are ideal, over the paper's network
    assert get_json(server, "/api/scenario")["toggles"] == {"limits": False, "network": False}
    query = "/api/simulate?tau1=0.3&tau2=0.2&duration=20&frames=400"
    ideal, limited = get_json(server, query), get_json(server, query + "&limits=1")
    assert ideal["limits"] is None and limited["limits"].startswith("|v| <= 0.5 m/s")

    def fastest(sim: dict) -> float:  # mean speed between frames: never above the top speed
        xy = np.stack([np.array(sim["x"]), np.array(sim["y"])], axis=-1)
        step = np.linalg.norm(np.diff(xy, axis=0), axis=-1) / np.diff(sim["times"])[:, None]
        return float(step.max())

    # positions travel with 5 decimals: over 0.05 s between frames that is up to 6e-4 m/s
    assert fastest(ideal) > 1.0 > 0.5 + 1e-3 >= fastest(limited)
    assert get(server, query + "&limits=2")[0] == 400


def test_network_switch_runs_the_lossy_network(server) -> None:
    query = "/api/simulate?tau1=0.3&tau2=0.2&duration=40&frames=50"
    lossy = get_json(server, query + "&network=1&loss=0.3&jitter=0")
    assert lossy["network"] == "loss 0.3" and lossy["limits"] is None
    assert lossy["formation_error"][-1] < 0.05 * lossy["formation_error"][0]  # point a still settles
    s = paper_scenario()
    direct = simulate(s.topology, 1.0, 0.5, 0.3, 0.2, s.desired_positions(), model=s.simulation.model,
                      network=Network(loss=BernoulliLoss(0.3), seed=s.initial.seed),
                      initial_positions=s.initial_positions(), initial_headings=s.initial_headings(),
                      initial_speed=s.initial.speed, seed=s.initial.seed, duration=40.0, dt=s.simulation.dt)  # fmt: skip
    assert lossy["final_error"] == pytest.approx(float(direct.formation_error[-1]), rel=1e-9)
    ideal = get_json(server, query)
    assert ideal["network"] is None and ideal["final_error"] != lossy["final_error"]
    both = get_json(server, query + "&network=1&loss=0.3&jitter=0&limits=1")  # limited robots, lossy network
    assert both["network"] == "loss 0.3" and both["limits"] is not None
    assert both["final_error"] != lossy["final_error"]
    jittery = get_json(server, query + "&network=1&loss=0.1&jitter=0.05")
    assert jittery["network"] == "jitter +-(0.05, 0.05) s, loss 0.1"


def test_network_download_round_trips(tmp_path: Path) -> None:
    query = "tau1=0.3&tau2=0.2&duration=20&tau1_max=8&tau2_max=8&network=1&loss=0.3&jitter=0.05"
    with start(Explorer(paper_scenario(), out_dir=tmp_path / "paper")) as running:
        status, _, body = get(running, f"/download/scenario.toml?{query}")
    assert status == 200
    again = parse_scenario(tomllib.loads(body.decode()))
    assert again.robot is None and again.network is not None
    assert again.network.loss.probability == 0.3 and (again.network.jitter.bound1, again.network.jitter.bound2) == (0.05, 0.05)
    # a scenario with its own network keeps its other parts; the page sets loss and jitter
    lossy = load_scenario(EXAMPLES / "lossy.toml")
    explorer = Explorer(lossy, out_dir=tmp_path)
    assert explorer.toggles == {"network": True}
    path = explorer.scenario_file(1.0, 0.5, 0.3, 0.2, 30.0, 8.0, 8.0, network=True, loss=0.25, jitter=0.02)
    net = load_scenario(path).network
    assert net.loss.probability == 0.25 and net.jitter.bound1 == 0.02
    assert (net.sampling, net.noise, net.delays.spread) == (lossy.network.sampling, lossy.network.noise, 0.2)
    assert load_scenario(explorer.scenario_file(1.0, 0.5, 0.3, 0.2, 30.0, 8.0, 8.0)).network is None


def test_no_limits_switch_for_double_integrators(tmp_path: Path) -> None:
    agents = replace(paper_scenario(), simulation=replace(paper_scenario().simulation, model="double_integrator"))
    explorer = Explorer(agents, out_dir=tmp_path)
    assert explorer.toggles == {"network": False}
    with start(explorer) as running:
        assert get(running, "/api/simulate?tau1=0.3&tau2=0.2&limits=1")[0] == 400


def test_page_and_assets_come_from_this_server(server) -> None:
    status, kind, page = get(server, "/")
    assert status == 200 and kind.startswith("text/html")
    html = page.decode()
    assert 'src="/static/plotly.min.js"' in html and "http" not in html.replace("http-equiv", "")
    status, _, js = get(server, "/static/plotly.min.js")
    assert status == 200 and len(js) > 1_000_000 and b"plotly" in js[:2000].lower()


# ---------------------------------------------------------------- refusals
MALFORMED = [
    "/api/point",
    "/api/point?tau1=0.3",
    "/api/point?tau2=0.2",
    "/api/point?tau1=abc&tau2=0.2",
    "/api/point?tau1=&tau2=0.2",
    "/api/point?tau1=nan&tau2=0.2",
    "/api/point?tau1=inf&tau2=0.2",
    "/api/point?tau1=-0.1&tau2=0.2",
    "/api/point?tau1=1e400&tau2=0.2",
    "/api/point?tau1=51&tau2=0.2",
    "/api/point?tau1=0.3&tau2=0.2&tau1=0.4",
    "/api/point?tau1=0.3&tau2=0.2&P=0",
    "/api/point?tau1=0.3&tau2=0.2&P=-1",
    "/api/point?tau1=0.3&tau2=0.2&P=abc",
    "/api/point?tau1=0.3&tau2=0.2&P=21",
    "/api/point?tau1=0.3&tau2=0.2&D=0",
    "/api/point?tau1=0.3&tau2=0.2&D=nan",
    "/api/point?tau1=0.3&tau2=0.2&grid=10",
    "/api/point?tau1=0x10&tau2=0.2",
    "/api/point?tau1=0.3&tau2=0.2&foo=1",
    "/api/roots?tau1=20&tau2=0.2",  # 20 s x 1.69 rad/s: beyond max_delay_bandwidth
    "/api/point?tau1=1,2&tau2=0.2",
    "/api/point?tau1=0.3%200.4&tau2=0.2",
    "/api/point?tau1=" + "1" * 60 + "&tau2=0.2",
    "/api/point?tau1=true&tau2=0.2",
    "/api/point?tau1=%00&tau2=0.2",
    "/api/point?tau1=1_0&tau2=0.2",
    "/api/point?tau1=%zz&tau2=0.2",
    "/api/point?tau1=%D9%A1&tau2=0.2",  # an Arabic-Indic digit one
    "/api/chart?grid=5",
    "/api/chart?grid=301",
    "/api/chart?grid=1.5",
    "/api/chart?grid=abc",
    "/api/chart?tau1_max=0",
    "/api/chart?tau2_max=51",
    "/api/chart?tau1_max=18",  # max_delay_bandwidth at the paper's gains: 17.8 s
    "/api/chart?P=0",
    "/api/chart?tau1_max=nan&grid=20",
    "/api/simulate?tau1=0.3&tau2=0.2&duration=0",
    "/api/simulate?tau1=0.3&tau2=0.2&duration=-5",
    "/api/simulate?tau1=0.3&tau2=0.2&duration=1e6",
    "/api/simulate?tau1=0.3&tau2=0.2&duration=301",
    "/api/simulate?tau1=0.3&tau2=0.2&frames=1",
    "/api/simulate?tau1=0.3&tau2=0.2&frames=601",
    "/api/simulate?tau1=0.3&tau2=0.2&frames=abc&frames=2",
    "/api/simulate?tau1=0.001&tau2=0.2&duration=60",  # the step shrinks to 0.001: 60000 steps
    "/api/simulate?tau1=0.3&tau2=0.2&network=1&loss=1",
    "/api/simulate?tau1=0.3&tau2=0.2&network=1&loss=-0.1",
    "/api/simulate?tau1=0.3&tau2=0.2&network=1&jitter=abc",
    "/api/simulate?tau1=0.3&tau2=0.2&network=1&jitter=6",
    "/api/simulate?tau1=0.3&tau2=0.2&network=1&jitter=0.2",  # tau2 - jitter < dt: NetworkError
    "/api/simulate?tau1=0.3&tau2=0.2&network=maybe",
    "/api/region",
    "/api/region?tau1=0.3",
    "/api/region?tau1=abc&tau2=0.2",
    "/api/region?tau1=0.3&tau2=0.2&P=0",
    "/api/region?tau1=20&tau2=0.2",  # beyond max_delay_bandwidth
    "/api/region?tau1=0.3&tau2=0.2&grid=81",
    "/download/scenario.toml",
    "/download/scenario.toml?tau1=0.3&tau2=0.2&tau1_max=0",
    "/download/figures.zip?tau1=0.3&tau2=0.2&duration=1e9",
    "/?x=1",
]


@pytest.mark.parametrize("path", MALFORMED)
def test_malformed_request_gets_400_and_one_line(server, path: str) -> None:
    status, kind, body = get(server, path)
    assert status == 400, body
    assert kind.startswith("application/json")
    text = body.decode()
    assert "\n" not in text.strip() and "Traceback" not in text
    message = json.loads(text)["error"]
    assert 0 < len(message) < 200


def test_limits_are_named_when_they_refuse(server) -> None:
    assert "max_steps" in json.loads(get(server, "/api/simulate?tau1=0.3&tau2=0.2&duration=301")[2])["error"]
    assert "max_grid" in json.loads(get(server, "/api/chart?grid=301")[2])["error"]
    assert "max_delay" in json.loads(get(server, "/api/point?tau1=51&tau2=0.2")[2])["error"]
    # the delay-bandwidth bound follows the gains: 10 s is refused at P = 10 and allowed at P = 1
    assert "max_delay_bandwidth" in json.loads(get(server, "/api/point?tau1=10&tau2=0&P=10")[2])["error"]
    assert get(server, "/api/point?tau1=10&tau2=0&P=1")[0] == 200
    big = parse_scenario({"topology": {"name": "ring", "n": 101}, "gains": {"P": 1, "D": 0.5},
                          "delays": {"tau1": 0.1, "tau2": 0.1}, "formation": {"shape": "polygon"}})  # fmt: skip
    with pytest.raises(InputError, match="max_agents"):
        Explorer(big, out_dir="unused", limits=ExplorerLimits(max_agents=100))


def test_unknown_paths_and_foreign_host_headers_are_refused(server) -> None:
    assert get(server, "/static/../../etc/passwd")[0] == 404
    assert get(server, "/static/index.html")[0] == 404  # only the fixed asset names are served
    # DNS rebinding: a page elsewhere that resolves its own name to 127.0.0.1 is refused
    assert get(server, "/api/scenario", headers={"Host": "attacker.example"})[0] == 400


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.168.1.10", "10.0.0.1", "example.com", "127.0.0.2", ""])
def test_refuses_to_bind_anything_but_loopback(host: str) -> None:
    with pytest.raises(InputError, match="127.0.0.1 only"):
        check_host(host)
    with pytest.raises(InputError, match="127.0.0.1 only"):
        bind(host, 0)


def test_binds_the_loopback_and_the_cli_refuses_other_hosts(capsys: pytest.CaptureFixture[str]) -> None:
    sock = bind("localhost", 0)
    try:
        assert sock.getsockname()[0] == "127.0.0.1"
    finally:
        sock.close()
    with pytest.raises(SystemExit) as exit_info:
        main(["explore", "--host", "0.0.0.0", "--no-browser"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "127.0.0.1 only" in err


def test_cli_refuses_a_port_in_use_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    taken = bind(LOOPBACK, 0)
    try:
        with pytest.raises(SystemExit) as exit_info:
            main(["explore", "--port", str(taken.getsockname()[1]), "--no-browser", "--out", str(tmp_path)])
    finally:
        taken.close()
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot listen on 127.0.0.1" in err


# ---------------------------------------------------------------- files
def test_downloads_round_trip_and_stay_in_the_output_folder(
    server, out_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    query = "tau1=1.5&tau2=0.7&P=0.8&D=0.9&duration=20&tau1_max=10&tau2_max=6"
    status, kind, body = get(server, f"/download/scenario.toml?{query}")
    assert status == 200 and kind.startswith("application/toml")
    again = parse_scenario(tomllib.loads(body.decode()))
    assert (again.P, again.D, again.tau1, again.tau2) == (0.8, 0.9, 1.5, 0.7)
    assert (again.chart.tau1_max, again.chart.tau2_max, again.simulation.duration) == (10.0, 6.0, 20.0)
    assert again.topology_spec.name == "paper_six" and again.chart.points == paper_scenario().chart.points
    assert again.robot is None
    status, _, body = get(server, f"/download/scenario.toml?{query}&limits=1")
    assert status == 200 and parse_scenario(tomllib.loads(body.decode())).robot == IROBOT_CREATE

    status, kind, body = get(server, f"/download/figures.zip?{query}")
    assert status == 200 and kind == "application/zip"
    with zipfile.ZipFile(io.BytesIO(body)) as zf:
        names = set(zf.namelist())
        assert {"stability_chart.png", "stability_chart.svg", "traces.png", "xy.svg", "point.json"} <= names
        assert zf.read("traces.png")[:8] == b"\x89PNG\r\n\x1a\n"
        assert json.loads(zf.read("point.json"))["tau1"] == 1.5
    saved = sorted(p.name for p in out_dir.iterdir())
    stem = "paper_P0.8_D0.9_tau1.5_0.7_T20_win10x6"  # one name per setting: the limits file kept apart
    assert saved == [f"{stem}.toml", f"{stem}_figures.zip", f"{stem}_limits.toml"]
    assert os.listdir(tmp_path) == []  # nothing written in the working directory


def test_download_names_carry_every_setting_that_changes_the_content(tmp_path: Path) -> None:
    import re

    base = "tau1=0.3&tau2=0.2&duration=20&tau1_max=8&tau2_max=8"
    variants = {  # each changes what the file holds
        "plain": base, "limits": base + "&limits=1", "network": base + "&network=1&loss=0.1&jitter=0.05",
        "more loss": base + "&network=1&loss=0.2&jitter=0.05", "more jitter": base + "&network=1&loss=0.1&jitter=0.06",
        "both": base + "&limits=1&network=1&loss=0.1&jitter=0.05", "longer": base.replace("duration=20", "duration=25"),
        "window": base.replace("tau2_max=8", "tau2_max=9"), "gain": base + "&P=0.9",
        "fine": base.replace("tau1=0.3", "tau1=0.3000001"),
    }  # fmt: skip
    out = tmp_path / "out"
    names, bodies = {}, {}
    with start(Explorer(paper_scenario(), out_dir=out)) as running:
        for label, query in variants.items():
            conn = http.client.HTTPConnection("127.0.0.1", running.port, timeout=60)
            conn.request("GET", f"/download/scenario.toml?{query}")
            resp = conn.getresponse()
            bodies[label] = resp.read()
            assert resp.status == 200, bodies[label]
            names[label] = re.fullmatch(r'attachment; filename="(.+)"', resp.getheader("Content-Disposition"))[1]
            conn.close()
        # loss and jitter without the network are refused, never silently ignored (issue 24)
        status, _, again = get(running, f"/download/scenario.toml?{base}&loss=0.3&jitter=0.01")
        assert status == 400 and b"network=0" in again
        for label in ("plain", "network"):
            status, _, _ = get(running, f"/download/figures.zip?{variants[label]}")
            assert status == 200
    assert len(set(names.values())) == len(variants)  # no download overwrites another
    assert len(set(bodies.values())) == len(variants)  # and each name stands for its own content
    for name in names.values():
        assert re.fullmatch(r"[A-Za-z0-9._-]+\.toml", name) and len(name) < 100, name
    assert names["plain"] == "paper_P1_D0.5_tau0.3_0.2_T20_win8x8.toml"
    assert names["both"] == "paper_P1_D0.5_tau0.3_0.2_T20_win8x8_limits_net-loss0.1-jitter0.05.toml"
    # the name says what the file holds
    for label, name in names.items():
        s = load_scenario(out / name)
        net = s.network
        assert ("_limits" in name) is (s.robot is not None), label
        assert ("_net-" in name) is (net is not None), label
        if net is not None:
            assert f"loss{net.loss.probability:g}-jitter{net.jitter.bound1:g}" in name, label
        assert f"_T{s.simulation.duration:g}_win{s.chart.tau1_max:g}x{s.chart.tau2_max:g}" in name, label
    saved = sorted(p.name for p in out.iterdir())
    assert saved == sorted([*names.values(), names["plain"].replace(".toml", "_figures.zip"),
                            names["network"].replace(".toml", "_figures.zip")])  # fmt: skip


def test_a_scenario_name_never_leads_outside_the_output_folder(tmp_path: Path) -> None:
    sneaky = replace(paper_scenario(), name="../../x/..")
    path = Explorer(sneaky, out_dir=tmp_path / "out").scenario_file(1.0, 0.5, 0.3, 0.2, 10.0, 8.0, 8.0)
    assert path.parent == (tmp_path / "out").resolve() and path.name == "_.._x__P1_D0.5_tau0.3_0.2_T10_win8x8.toml"
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == [path.name]


@pytest.mark.parametrize("example", sorted(EXAMPLES.glob("*.toml")), ids=lambda p: p.stem)
def test_scenario_toml_reads_back_to_the_same_scenario(example: Path) -> None:
    s = load_scenario(example)
    again = parse_scenario(tomllib.loads(scenario_toml(s)), source=s.source)
    assert again.summary() == s.summary()
    assert np.array_equal(again.topology.adjacency_sparse.toarray(), s.topology.adjacency_sparse.toarray())
    assert np.array_equal(again.desired_positions(), s.desired_positions())


def test_scenario_endpoint_lists_defaults_and_limits(server) -> None:
    info = get_json(server, "/api/scenario")
    assert info["defaults"]["tau1"] == 0.3 and info["defaults"]["P"] == 1.0
    assert info["limits"]["max_grid"] == ExplorerLimits().max_grid
    assert info["scenario"]["agents"] == 6


def test_urlopen_sees_one_json_line_for_a_server_side_refusal(server) -> None:
    # the same through the standard library's client a script would use
    with pytest.raises(urllib.error.HTTPError) as info:
        urllib.request.urlopen(f"{server.url}api/point?tau1=-1&tau2=0", timeout=30)
    assert info.value.code == 400
    assert json.loads(info.value.read())["error"].startswith("tau1: must be >= 0")
