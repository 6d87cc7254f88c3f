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

from test_cli import assert_one_line_error, run, run_entry_point

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


@pytest.fixture
def one_link(tmp_path: Path) -> Path:
    """examples/paper.toml with one link's tau1 at 1.5 s, every other link at [delays] (0.3, 0.2)."""
    t1 = np.full((6, 6), 0.3)
    t1[0, 1] = 1.5  # a link of paper_six
    return _per_link(tmp_path, t1, np.full((6, 6), 0.2), "one_link.toml")


def _point_c_count() -> int:
    """Unstable roots at (1, 2), factor by factor (the certified count of each factor, eq. factorized)."""
    from delayform.analysis.roots.single import count_roots_right_of
    from delayform.characteristic import factors

    # right of 1e-9: the centroid's root at s = 0 (every delay) is not a disagreement mode
    return sum(f.multiplicity * count_roots_right_of(f, 1.0, 2.0, 1e-9) for f in factors(paper_six(), 1.0, 0.5))


def test_roots_takes_one_delay_pair_on_every_link_as_the_point(point_c: Path, tmp_path: Path) -> None:
    out = json.loads(run("roots", str(point_c), "--json", "--out", str(tmp_path / "o"), cwd=tmp_path).stdout)
    assert (out["tau1"], out["tau2"]) == (1.0, 2.0)  # the matrices' delay, not [delays] (0.3, 0.2)
    # a second method: the per-link determinant of the same matrices (no factorization)
    from delayform.analysis.network import link_dominant_root

    ref = link_dominant_root(paper_six(), 1.0, 0.5, np.full((6, 6), 1.0), np.full((6, 6), 2.0)).root
    assert complex(out["dominant_root"]["re"], out["dominant_root"]["im"]) == pytest.approx(ref, abs=1e-8)
    assert not out["stable"]


def test_chart_classifies_the_per_link_point(point_c: Path, tmp_path: Path) -> None:
    out = json.loads(run("chart", str(point_c), "--tau1-max", "2.5", "--tau2-max", "2.5", "--json",
                         "--out", str(tmp_path / "o"), cwd=tmp_path).stdout)  # fmt: skip
    # the paper's point c is where every link is: it is the operating point, not [delays] (0.3, 0.2)
    assert [p["label"] for p in out["points"] if (p["tau1"], p["tau2"]) == (0.3, 0.2)] == ["a"]
    c = next(p for p in out["points"] if (p["tau1"], p["tau2"]) == (1.0, 2.0))
    # the chart counts by crossing curves (CTCR); the reference by the argument principle, factor by factor
    assert not c["stable"] and c["unstable_roots"] == _point_c_count() > 0


def test_region_is_at_the_per_link_point(point_c: Path, tmp_path: Path) -> None:
    base = json.loads(run("region", str(EXAMPLES / "paper.toml"), "--json", "--out", str(tmp_path / "a"), cwd=tmp_path).stdout)
    out = json.loads(run("region", str(point_c), "--json", "--out", str(tmp_path / "b"), cwd=tmp_path).stdout)
    assert base["team_stable"] and (base["tau1"], base["tau2"]) == (0.3, 0.2)
    assert (out["tau1"], out["tau2"]) == (1.0, 2.0) and not out["team_stable"]
    assert sum(out["unstable_roots"]) == _point_c_count()


def test_schedule_starts_from_the_per_link_hardware_delays(point_c: Path, tmp_path: Path) -> None:
    out = json.loads(run("schedule", str(point_c), "--tau-max", "4,6", "--json", "--out", str(tmp_path / "o"),
                         cwd=tmp_path).stdout)  # fmt: skip
    assert out["tau_min"] == [1.0, 2.0]
    ref = dominant_root(paper_six(), 1.0, 0.5, 1.0, 2.0).root
    assert complex(out["hardware_root"]["re"], out["hardware_root"]["im"]) == pytest.approx(ref, abs=1e-8)
    # delays only added from c: the best pair lies above it and is stable (the factorized dominant root there)
    assert out["tau1"] >= 1.0 and out["tau2"] >= 2.0
    best = dominant_root(paper_six(), 1.0, 0.5, out["tau1"], out["tau2"])
    assert best.is_stable and complex(out["root"]["re"], out["root"]["im"]) == pytest.approx(best.root, abs=1e-6)


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("chart",), "chart"), (("roots",), "roots"), (("region",), "region"), (("schedule",), "schedule"),
        (("gains",), "gain design"), (("report",), "report"),
        (("sweep", "--tau1-values", "0.2,0.3", "--tau2-values", "0.2", "--runs", "1"), "sweep"),
    ],
)  # fmt: skip
def test_one_pair_commands_refuse_delays_that_differ_between_links(one_link: Path, tmp_path: Path,
                                                                  args: tuple[str, ...], needle: str) -> None:  # fmt: skip
    proc = run(args[0], str(one_link), *args[1:], "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert_one_line_error(proc, needle, "network.tau1 (per-link, 0.3 to 1.5 s)", "[delays] (0.3, 0.2)")
    assert not (tmp_path / "out").exists()  # refused before anything is written


def test_check_and_explore_refuse_delays_that_differ_between_links(one_link: Path, tmp_path: Path) -> None:
    assert_one_line_error(run("check", str(one_link), "--robot", "create3", cwd=tmp_path), "check", "network.tau1")
    # in a subprocess with a timeout: were it not refused, the explorer would serve until stopped
    proc = run_entry_point("explore", str(one_link), "--no-browser", "--port", "0", "--out", str(tmp_path / "out"),
                           cwd=tmp_path, timeout=60)  # fmt: skip
    assert_one_line_error(proc, "explorer", "network.tau1")
    assert not (tmp_path / "out").exists()


def test_explorer_starts_at_the_per_link_point(point_c: Path, tmp_path: Path) -> None:
    from delayform.app import Explorer

    explorer = Explorer(load_scenario(point_c), out_dir=tmp_path)
    assert (explorer.scenario.tau1, explorer.scenario.tau2) == (1.0, 2.0)
    assert explorer.scenario.network is None  # nothing but the one delay pair was in the [network] table


def test_tau1_on_the_command_line_replaces_that_streams_matrix(one_link: Path, tmp_path: Path) -> None:
    out = json.loads(run("roots", str(one_link), "--tau1", "0.3", "--json", "--out", str(tmp_path / "o"), cwd=tmp_path).stdout)
    ref = dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2).root
    assert complex(out["dominant_root"]["re"], out["dominant_root"]["im"]) == pytest.approx(ref, abs=1e-8)
    sims = [json.loads(run("simulate", str(path), *extra, "--duration", "10", "--json", "--out", str(tmp_path / name),
                           cwd=tmp_path).stdout)  # fmt: skip
            for path, extra, name in ((one_link, ("--tau1", "0.3"), "a"), (EXAMPLES / "paper.toml", (), "b"), (one_link, (), "c"))]
    assert sims[0]["final_error"] == pytest.approx(sims[1]["final_error"], rel=1e-12)  # the same run as [delays]
    assert sims[2]["final_error"] != pytest.approx(sims[1]["final_error"], rel=1e-6)  # the one slow link counts
    assert sims[2]["per_link_delays"] == "network.tau1 (per-link, 0.3 to 1.5 s)"


def test_map_and_safe_delays_do_not_read_the_scenarios_delays(one_link: Path, tmp_path: Path) -> None:
    # their question is the plane itself: the grid / window, not the scenario's operating point
    proc = run("map", str(one_link), "--tau1-range", "0.5,2", "--tau2-range", "0.5,2", "--size", "2,2", "--json",
               "--out", str(tmp_path / "m"), cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    with np.load(tmp_path / "m" / "dominant_map.npz") as npz:
        grid = dict(npz)
    for i, a in enumerate((0.5, 2.0)):
        for k, b in enumerate((0.5, 2.0)):  # the factorized dominant root at each grid point
            assert grid["real_part"][i, k] == pytest.approx(dominant_root(paper_six(), 1.0, 0.5, a, b).root.real, abs=1e-8)
    safe = [json.loads(run("safe-delays", str(path), "--tau1-max", "2", "--tau2-max", "2", "--json",
                           "--out", str(tmp_path / name), cwd=tmp_path).stdout)  # fmt: skip
            for path, name in ((one_link, "s1"), (EXAMPLES / "paper.toml", "s2"))]
    assert safe[0]["safe_fraction"] == safe[1]["safe_fraction"] > 0.0


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

    # 30 s of the paper's 150: the closest approach, with the filter and without, comes in the first
    # seconds of the transient (the same distances as over 150 s), at a fifth of the filter's QPs
    text = (EXAMPLES / "paper.toml").read_text().replace("duration = 150.0", "duration = 30.0")
    text += '\n[robot]\nprofile = "create3"\nsafety = "barrier"\n'
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


def _with_tables(tmp_path: Path, name: str, extra: str, base: Path = EXAMPLES / "paper.toml") -> Path:
    path = tmp_path / name
    path.write_text(base.read_text() + extra)
    return path


def test_check_runs_over_the_scenarios_network(tmp_path: Path) -> None:
    from delayform.deploy import robot_profile
    from delayform.simulation import simulate

    robot = '\n[robot]\nprofile = "create3"\n'
    lossy = _with_tables(tmp_path, "lossy.toml", robot + "\n[network]\nseed = 3\nloss = 0.4\nrate = 10.0\n")
    ideal = _with_tables(tmp_path, "ideal.toml", robot)
    args = ("--duration", "30", "--json")
    out, base = (json.loads(run("check", str(p), *args, cwd=tmp_path).stdout) for p in (lossy, ideal))
    assert out["network"] == "loss 0.4, sampled at 10 Hz" and base["network"] == "ideal"
    # the same run, made by the library's simulate over the scenario's network
    sc, limits = load_scenario(lossy), robot_profile("create3").limits
    ref = simulate(sc.topology, sc.P, sc.D, sc.tau1, sc.tau2, sc.desired_positions(), limits=limits, network=sc.network,
                   initial_speed=sc.initial.speed, seed=sc.initial.seed, duration=30.0, dt=sc.simulation.dt)  # fmt: skip
    assert out["verdicts"]["radius"]["closest_approach"] == pytest.approx(ref.min_distance, rel=1e-12)
    assert out["verdicts"]["radius"]["closest_approach"] != pytest.approx(base["verdicts"]["radius"]["closest_approach"], rel=1e-6)


@pytest.mark.slow  # a whole report with its Monte Carlo: about 20 s under load
def test_report_simulates_over_the_scenarios_network(tmp_path: Path) -> None:
    # a small team, a short run: the report's run is the one `simulate` makes, over [network]
    small = ('name = "small"\n[topology]\nname = "ring"\nn = 4\n[gains]\nP = 1.0\nD = 1.0\n[delays]\ntau1 = 0.2\ntau2 = 0.1\n'
             '[formation]\nshape = "line"\n[simulation]\nmodel = "double_integrator"\nduration = 8.0\ndt = 0.05\n'
             "[chart]\ntau1_max = 1.0\ntau2_max = 1.0\n[map]\nsize = [3, 3]\n[schedule]\ntau_max = [0.5, 0.5]\n")  # fmt: skip
    plain = tmp_path / "plain.toml"
    plain.write_text(small)
    lossy = _with_tables(tmp_path, "net.toml", "[network]\nseed = 1\nloss = 0.5\nrate = 10.0\n", base=plain)
    report = json.loads(run("report", str(lossy), "--json", "--out", str(tmp_path / "r"), cwd=tmp_path).stdout)
    sim = json.loads(run("simulate", str(lossy), "--json", "--out", str(tmp_path / "s"), cwd=tmp_path).stdout)
    ideal = json.loads(run("simulate", str(plain), "--json", "--out", str(tmp_path / "i"), cwd=tmp_path).stdout)
    assert report["simulation_operating"]["final_error"] == pytest.approx(sim["final_error"], rel=1e-12)
    assert sim["final_error"] != pytest.approx(ideal["final_error"], rel=1e-6)
    assert "montecarlo" in report  # and the Monte Carlo over the same network beside it
