"""Every command answers for the scenario it was given: its per-link delays, its network, its safety filter.

Each test changes one scenario key and checks that the answer changes with
it (against an independent computation) or that the command refuses in one
line with exit 2; never the answer for the unchanged scenario.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from test_cli import assert_one_line_error, run

from delayform.analysis.roots.dominant import dominant_root
from delayform.scenario import load_scenario
from delayform.topology import paper_six

EXAMPLES = Path(__file__).resolve().parents[1] / "src" / "delayform" / "examples"


def _matrix(values: np.ndarray) -> str:
    return "[" + ", ".join("[" + ", ".join(f"{x:g}" for x in row) + "]" for row in values) + "]"


def _per_link(tmp_path: Path, t1: np.ndarray, t2: np.ndarray, name: str = "links.toml") -> Path:
    """examples/paper.toml ([delays] 0.3, 0.2) with per-link delays in a [network] table."""
    text = (EXAMPLES / "paper.toml").read_text() + f"\n[network]\ntau1 = {_matrix(t1)}\ntau2 = {_matrix(t2)}\n"
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.fixture
def point_c(tmp_path: Path) -> Path:
    """Every link at point c, (1, 2) s: unstable (paper, Fig. stability), while [delays] (0.3, 0.2) is stable."""
    return _per_link(tmp_path, np.full((6, 6), 1.0), np.full((6, 6), 2.0))


def test_links_answers_for_the_per_link_delays(point_c: Path, tmp_path: Path) -> None:
    proc = run("links", str(point_c), "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    # a second method: the factorized dominant root of the same delays on every link
    ref = dominant_root(paper_six(), 1.0, 0.5, 1.0, 2.0).root
    assert not out["stable"]
    assert complex(*out["dominant_root"]) == pytest.approx(ref, abs=1e-8)
    assert complex(*out["dominant_root"]) == pytest.approx(0.08359 + 1.207j, abs=1e-4)


def test_links_sees_one_changed_link(tmp_path: Path) -> None:
    t1 = np.full((6, 6), 0.3)
    base = json.loads(run("links", str(_per_link(tmp_path, t1, np.full((6, 6), 0.2), "a.toml")), "--json", cwd=tmp_path).stdout)
    t1[0, 1] = 1.5  # a link of paper_six
    changed = json.loads(run("links", str(_per_link(tmp_path, t1, np.full((6, 6), 0.2), "b.toml")), "--json", cwd=tmp_path).stdout)
    assert changed["dominant_root"] != pytest.approx(base["dominant_root"], abs=1e-6)
    # --tau1 on the command line puts one delay on every link again: the factorized answer at (0.3, 0.2)
    again = json.loads(run("links", str(tmp_path / "b.toml"), "--tau1", "0.3", "--json", cwd=tmp_path).stdout)
    assert complex(*again["dominant_root"]) == pytest.approx(dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2).root, abs=1e-8)


def test_jitter_refuses_unstable_per_link_delays(point_c: Path, tmp_path: Path) -> None:
    assert_one_line_error(run("jitter", str(point_c), cwd=tmp_path), "nominal delays are unstable", "0.08359")


def test_box_must_hold_the_scenarios_per_link_delays(point_c: Path, tmp_path: Path) -> None:
    assert_one_line_error(run("box", str(point_c), "--tau1-box", "0.25,0.35", "--tau2-box", "0.15,0.25", cwd=tmp_path),
                          "network.tau1", "not inside --tau1-box")  # fmt: skip
    proc = run("box", str(point_c), "--tau1-box", "0.9,1.1", "--tau2-box", "1.9,2.1", "--json", cwd=tmp_path)
    assert proc.returncode == 0 and json.loads(proc.stdout)["status"] == "unstable"


def test_spread_delays_are_not_certified_as_one_matrix(tmp_path: Path) -> None:
    # examples/lossy.toml draws per-link delays per run (delay_spread): no single constant answer
    assert_one_line_error(run("links", str(EXAMPLES / "lossy.toml"), cwd=tmp_path), "delay_spread")


@pytest.mark.parametrize(
    ("args", "needle"),
    [(("roots",), "roots"), (("gains",), "gain design"), (("check", "--robot", "create3"), "design check")],
)
def test_uniform_delay_commands_refuse_per_link_delays(point_c: Path, tmp_path: Path, args: tuple[str, ...],
                                                       needle: str) -> None:  # fmt: skip
    extra = () if args[0] == "check" else ("--out", str(tmp_path / "out"))
    proc = run(*args, str(point_c), *extra, cwd=tmp_path)
    assert_one_line_error(proc, needle, "per-link", "(0.3, 0.2)")
    assert not (tmp_path / "out").exists()


def test_simulate_runs_over_the_scenarios_network(point_c: Path, tmp_path: Path) -> None:
    ideal = json.loads(run("simulate", str(EXAMPLES / "paper.toml"), "--duration", "40", "--json",
                           "--out", str(tmp_path / "a"), cwd=tmp_path).stdout)  # fmt: skip
    links = json.loads(run("simulate", str(point_c), "--duration", "40", "--json",
                           "--out", str(tmp_path / "b"), cwd=tmp_path).stdout)  # fmt: skip
    assert ideal["status"] == "settled"
    # the certified root 0.0836 +- 1.207j: the error grows, it does not settle
    assert links["status"] != "settled"
    assert links["final_error"] > 100 * ideal["final_error"]


@pytest.mark.slow
def test_check_judges_the_robot_with_its_safety_filter(tmp_path: Path) -> None:
    from delayform.deploy import robot_profile
    from delayform.simulation import simulate

    text = (EXAMPLES / "paper.toml").read_text() + '\n[robot]\nprofile = "create3"\nsafety = "barrier"\n'
    path = tmp_path / "safe.toml"
    path.write_text(text)
    proc = run("check", str(path), "--json", cwd=tmp_path)
    out = json.loads(proc.stdout)
    radius = out["verdicts"]["radius"]
    # the independent run: the library's simulate of the same robot, limits and filter
    sc, limits = load_scenario(path), robot_profile("create3").limits
    common = dict(initial_positions=sc.initial_positions(), initial_headings=sc.initial_headings(),
                  initial_speed=sc.initial.speed, seed=sc.initial.seed, duration=sc.simulation.duration, dt=sc.simulation.dt)  # fmt: skip
    args = (sc.topology, sc.P, sc.D, sc.tau1, sc.tau2, sc.desired_positions())
    filtered = simulate(*args, limits=limits, safety="barrier", **common).min_distance
    unfiltered = simulate(*args, limits=limits, **common).min_distance
    assert radius["closest_approach"] == pytest.approx(filtered, rel=1e-9)
    assert filtered > 2 * limits.radius > unfiltered  # the filter keeps the bodies apart; without it they touch
    assert radius["fits"] is True
