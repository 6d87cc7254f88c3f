"""The ``delayform`` command line: its exit codes, its messages and its ``--json``.

Most tests call the CLI in this process (``tests/cli_runner.py``: the same
working directory, environment and pipes a subprocess sees, at a fraction of
the cost); the tests of the entry point itself run ``python -m delayform`` in
a subprocess, as users run it: no command, a malformed file, a bad option, an
unknown command, a note on stderr, and ``paper``.

* every malformed scenario file gives exit code 2 and one line naming the problem;
* bad options do the same;
* ``--json`` output parses and equals the library's numbers, computed here directly;
* ``paper`` writes every file it lists.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from cli_runner import PACKAGE_ROOT, run_in_process, run_subprocess
from test_scenario import MALFORMED  # the same malformed files as the in-process tests

ROOT = Path(__file__).resolve().parents[1]
__all__ = ["PACKAGE_ROOT", "ROOT", "assert_no_warning_text", "assert_one_line_error", "run", "run_entry_point"]
COMMANDS = ("chart", "roots", "map", "schedule", "simulate", "report")


#: what Python's and numpy's warnings, and matplotlib's, print on stderr
WARNING_TEXT = ("Warning:", "warnings.warn", "RuntimeWarning", "UserWarning", "No artists with labels")


def assert_no_warning_text(stderr: str) -> None:
    """No warning of any kind reaches the user's terminal (BRIEF: no warning text on stderr)."""
    for text in WARNING_TEXT:
        assert text not in stderr, stderr


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """``delayform ARGS`` in this process, output captured as a subprocess's; checked for warning text."""
    proc = run_in_process(*args, cwd=cwd or ROOT)
    assert_no_warning_text(proc.stderr)
    return proc


def run_entry_point(*args: str, cwd: Path | None = None, timeout: float = 600) -> subprocess.CompletedProcess[str]:
    """``python -m delayform ARGS`` in a subprocess, as users run it; checked for warning text.

    The subprocess imports the same delayform as this test run (a worktree, not another install).
    """
    proc = run_subprocess(*args, cwd=cwd or ROOT, timeout=timeout)
    assert_no_warning_text(proc.stderr)
    return proc


def assert_one_line_error(proc: subprocess.CompletedProcess[str], *needles: str) -> None:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("delayform: error: ")
    assert "Traceback" not in proc.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    assert proc.stdout == ""


# ------------------------------------------------------------ input errors
@pytest.mark.parametrize(
    ("index", "text", "key"),
    [(i, c[1], c[2]) for i, c in enumerate(MALFORMED)],
    ids=[c[0] for c in MALFORMED],
)
def test_malformed_scenario_exits_2_with_one_line(tmp_path: Path, index: int, text: str, key: str) -> None:
    assert len(MALFORMED) >= 20
    path = tmp_path / f"bad{index}.toml"
    path.write_text(text)
    command = COMMANDS[index % len(COMMANDS)]  # every subcommand meets some of them
    runner = run_entry_point if index == 0 else run  # the first as users run it, in a subprocess
    proc = runner(command, str(path), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert_one_line_error(proc, str(path), key)
    assert not (tmp_path / "out").exists()  # nothing computed, nothing written


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("chart", "--tau1-max", "-1"), "--tau1-max"),
        (("chart", "--point", "a=0.3"), "--point"),
        (("chart", "--point", "z=9,1"), "outside the window"),
        (("roots", "--region", "1,2"), "--region"),
        (("roots", "--region", "1,0,0,1"), "--region"),
        (("map", "--size", "1,5"), "--size"),
        (("map", "--tau1-range", "2,1"), "--tau1-range"),
        (("schedule", "--tau-min", "1,1", "--tau-max", "0.5,2"), "--tau-max"),
        (("simulate", "--dt", "0"), "--dt"),
        (("simulate", "--model", "tank"), "--model"),
        (("simulate", "--duration", "1", "--dt", "2"), "--dt"),
        (("chart", "--P", "-1"), "--P"),
        (("chart", "--topology", "ring"), "--n"),
        (("chart", "--colour", "red"), "--colour"),
        (("chart", "no/such/file.toml"), "no/such/file.toml"),
        (("frobnicate",), "frobnicate"),
        (("factors", "--P", "0"), "P"),
    ],
    ids=lambda v: " ".join(v) if isinstance(v, tuple) else None,
)
def test_bad_option_exits_2_with_one_line(tmp_path: Path, args: tuple[str, ...], needle: str) -> None:
    # a bad value and an unknown command as users meet them, in a subprocess; the rest in-process
    runner = run_entry_point if args in {("chart", "--tau1-max", "-1"), ("frobnicate",)} else run
    assert_one_line_error(runner(*args, cwd=tmp_path), needle)


def test_override_that_does_not_fit_the_scenario(tmp_path: Path) -> None:
    # the paper's hexagon cannot hold a ring of five: only the commands that move robots need it
    proc = run("report", "--topology", "ring", "--n", "5", "--out", str(tmp_path / "r"), cwd=tmp_path)
    assert_one_line_error(proc, "formation.shape", "hexagon", "--formation")
    assert not (tmp_path / "r").exists()  # refused before anything was computed or created


# -------------------------------------------------------------- --help
def test_every_option_has_help() -> None:
    from delayform.cli import cli

    assert set(cli.commands) >= {"factors", *COMMANDS, "paper"}
    for name, command in cli.commands.items():
        assert command.help and len(command.help.split()) >= 8, name
        for param in command.params:
            if param.param_type_name == "option":
                assert param.help, (name, param.name)


def test_no_command_shows_help() -> None:
    proc = run_entry_point()
    assert proc.returncode == 0
    assert proc.stdout.startswith("Usage: delayform") and "paper" in proc.stdout


@pytest.mark.parametrize("command", ["factors", *COMMANDS, "paper"])
def test_help_runs(command: str) -> None:
    proc = run(command, "--help")
    assert proc.returncode == 0
    assert proc.stdout.startswith(f"Usage: delayform {command}")
    assert proc.stderr == ""


# ------------------------------------------------------- --json = library
def _json(proc: subprocess.CompletedProcess[str]) -> dict:
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def _complex(value: dict) -> complex:
    return complex(value["re"], value["im"])


def test_chart_json_matches_library(tmp_path: Path) -> None:
    from delayform.analysis.ctcr.stability_map import stability_map
    from delayform.topology import paper_six

    out = _json(run("chart", "--json", "--out", str(tmp_path), "--tau1-max", "6", "--tau2-max", "7", cwd=tmp_path))
    smap = stability_map(paper_six(), 1.0, 0.5, 6.0, 7.0)
    assert out["window"] == [6.0, 7.0]
    assert out["curves"] == len(smap.curves)
    assert out["stable_fraction"] == pytest.approx(smap.stable_fraction(), rel=1e-12)
    labels = {p["label"]: p for p in out["points"]}
    assert sorted(labels) == ["a", "b", "c", "d", "e"]
    for label, point in labels.items():
        assert point["unstable_roots"] == int(smap.unstable_count(point["tau1"], point["tau2"])), label
    # the paper: a, b, d, e stable; c unstable
    assert [labels[k]["stable"] for k in "abcde"] == [True, True, False, True, True]
    for name in ("stability_chart.png", "stability_chart.svg", "ctcr_curves.csv", "ctcr_curves.npz"):
        assert (tmp_path / name).stat().st_size > 0


def test_roots_json_matches_library(tmp_path: Path) -> None:
    from delayform.analysis.roots.dominant import dominant_root, roots_in
    from delayform.characteristic import factors
    from delayform.topology import ring

    args = ("roots", "--json", "--topology", "ring", "--n", "5", "--P", "0.5", "--D", "1.5",
            "--tau1", "0.4", "--tau2", "0.1", "--region", "-3,1,-0.5,6", "--out", str(tmp_path))  # fmt: skip
    # ring(5) cannot take the paper's hexagon: give the scenario a line instead
    scenario = tmp_path / "ring5.toml"
    scenario.write_text('[topology]\nname = "ring"\nn = 5\n[gains]\nP = 0.5\nD = 1.5\n'
                        '[delays]\ntau1 = 0.4\ntau2 = 0.1\n[formation]\nshape = "line"\n')  # fmt: skip
    out = _json(run(*args[:2], str(scenario), *args[6:], cwd=tmp_path))
    team = ring(5)
    expected = dominant_root(team, 0.5, 1.5, 0.4, 0.1)
    assert _complex(out["dominant_root"]) == pytest.approx(complex(expected.root), abs=1e-9)
    listed = sorted((_complex(r["root"]) for r in out["roots_in_region"]), key=lambda s: (s.real, s.imag))
    direct = sorted(
        (complex(s) for f in factors(team, 0.5, 1.5) for s in roots_in(f, 0.4, 0.1, (-3, 1, -0.5, 6))),
        key=lambda s: (s.real, s.imag),
    )
    np.testing.assert_allclose(listed, direct, atol=1e-9)


def test_schedule_json_matches_library(tmp_path: Path) -> None:
    from delayform.design.scheduling import schedule_delays
    from delayform.topology import paper_six

    out = _json(run("schedule", "--json", "--tau-min", "0.3,0.2", "--tau-max", "2,2", "--out", str(tmp_path), cwd=tmp_path))
    direct = schedule_delays(paper_six(), 1.0, 0.5, tau_min=(0.3, 0.2), tau_max=(2.0, 2.0))
    assert (out["tau1"], out["tau2"]) == pytest.approx((direct.tau1, direct.tau2), abs=1e-12)
    assert _complex(out["root"]) == pytest.approx(complex(direct.root), abs=1e-12)
    assert out["tau1"] >= 0.3 and out["tau2"] >= 0.2 and out["root"]["re"] < 0


def test_map_json_matches_library(tmp_path: Path) -> None:
    from delayform.analysis.roots.dominant import dominant_root_map
    from delayform.topology import paper_six

    out = _json(run("map", "--json", "--tau1-range", "0,4", "--tau2-range", "0,3", "--size", "9,7",
                    "--out", str(tmp_path), cwd=tmp_path))  # fmt: skip
    t1, t2 = np.linspace(0, 4, 9), np.linspace(0, 3, 7)
    direct = np.asarray(dominant_root_map(paper_six(), 1.0, 0.5, t1, t2).real)
    with np.load(tmp_path / "dominant_map.npz") as npz:
        saved = dict(npz)
    np.testing.assert_allclose(saved["real_part"], direct, atol=1e-12)
    assert out["min_real_part"] == pytest.approx(direct.min(), abs=1e-12)
    # the CTCR chart on the same grid (issue 24: the tau1 = 0 row, the centroid's drift, is stable in both)
    from delayform.analysis.ctcr.stability_map import stability_map

    chart = stability_map(paper_six(), 1.0, 0.5, 4.0, 3.0).is_stable(t1[:, None], t2[None, :])
    assert out["stable_fraction"] == pytest.approx(float(np.mean(chart)))
    for name in ("dominant_surface.png", "dominant_contour.svg", "dominant_map.csv"):
        assert (tmp_path / name).stat().st_size > 0


def test_simulate_json_matches_library(tmp_path: Path) -> None:
    from delayform.formation import named_formation
    from delayform.simulation import simulate
    from delayform.topology import paper_six

    out = _json(run("simulate", "--json", "--duration", "20", "--dt", "0.05", "--seed", "3",
                    "--out", str(tmp_path), cwd=tmp_path))  # fmt: skip
    traj = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, named_formation("hexagon", 6, spacing=2.0),
                    seed=3, duration=20.0, dt=0.05)  # fmt: skip
    assert out["settling_time"] == (None if not np.isfinite(traj.settling_time) else pytest.approx(traj.settling_time))
    assert out["final_error"] == pytest.approx(traj.formation_error[-1], rel=1e-9)
    assert out["min_distance"] == pytest.approx(traj.min_distance, rel=1e-9)
    with np.load(tmp_path / "sim_operating.npz") as npz:
        saved = dict(npz)
    np.testing.assert_allclose(saved["positions"], traj.positions, atol=1e-12)
    for name in ("sim_operating_xy.png", "sim_operating_traces.svg", "sim_operating.csv",
                 "sim_operating_commands.png", "sim_operating_commands.npz"):  # fmt: skip
        assert (tmp_path / name).stat().st_size > 0
    assert out["status"] == traj.status and out["limits_exceeded"] == traj.commands.summary()


# ------------------------------------------------------------- robot limits
def test_simulate_with_limits_from_options_and_scenario(tmp_path: Path) -> None:
    from dataclasses import replace

    from delayform.formation import named_formation
    from delayform.simulation import IROBOT_CREATE, simulate
    from delayform.topology import paper_six

    out = _json(run("simulate", "--json", "--duration", "6", "--dt", "0.02", "--max-turn-rate", "1.5",
                    "--out", str(tmp_path), cwd=tmp_path))  # fmt: skip
    lim = replace(IROBOT_CREATE, max_turn_rate=1.5)
    traj = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, named_formation("hexagon", 6, spacing=2.0),
                    limits=lim, duration=6.0, dt=0.02)  # fmt: skip
    assert out["robot_limits"] == lim.describe() and "the limit is 1.5" in out["limits_exceeded"]
    assert out["final_error"] == pytest.approx(traj.formation_error[-1], rel=1e-9)
    with np.load(tmp_path / "sim_operating_commands.npz") as npz:
        saved = dict(npz)
    assert np.abs(saved["omega"]).max() <= 1.5 * (1 + 1e-9)
    scenario = tmp_path / "robots.toml"
    from delayform.scenario import PAPER_TOML

    scenario.write_text(PAPER_TOML + "\n[robot]\nmax_speed = 0.3\n")
    out = _json(run("simulate", str(scenario), "--json", "--duration", "4", "--dt", "0.02",
                    "--out", str(tmp_path / "s"), cwd=tmp_path))  # fmt: skip
    assert "|v| <= 0.3 m/s" in out["robot_limits"]
    out = _json(run("simulate", str(scenario), "--json", "--duration", "4", "--dt", "0.02", "--no-limits",
                    "--out", str(tmp_path / "s"), cwd=tmp_path))  # fmt: skip
    assert out["robot_limits"] is None


@pytest.mark.parametrize("args, needle", [
    (("--max-turn-rate", "-1"), "--max-turn-rate"),
    (("--max-speed", "fast"), "--max-speed"),
    (("--no-limits", "--max-speed", "1"), "--no-limits"),
    (("--model", "double_integrator", "--limits"), "limits"),
])  # fmt: skip
def test_malformed_limits_exit_2_with_one_line(tmp_path: Path, args: tuple[str, ...], needle: str) -> None:
    proc = run("simulate", *args, "--duration", "1", "--out", str(tmp_path / "o"), cwd=tmp_path)
    assert_one_line_error(proc, needle)


def test_simulate_huge_delays_run_and_huge_runs_are_refused(tmp_path: Path) -> None:
    import time

    start = time.perf_counter()
    proc = run("simulate", "--tau1", "1e6", "--tau2", "1e6", "--duration", "5", "--no-csv",
               "--radius", "0", "--out", str(tmp_path), cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0 and proc.stderr.strip() == "", proc.stderr
    assert time.perf_counter() - start < 15.0  # the interpreter's start and the figures included
    assert not (tmp_path / "sim_operating.csv").exists() and (tmp_path / "sim_operating.npz").exists()
    proc = run("simulate", "--duration", "1e7", "--dt", "1e-4", "--out", str(tmp_path / "big"), cwd=tmp_path)
    assert_one_line_error(proc, "would", "duration")


def test_simulate_notes_a_diverging_run_on_stderr(tmp_path: Path) -> None:
    # in a subprocess: the note goes through Python's own warning display, as on a user's terminal
    proc = run_entry_point("simulate", "--tau1", "1", "--tau2", "2", "--duration", "600", "--dt", "0.05",
               "--model", "double_integrator", "--out", str(tmp_path), cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("delayform: note: the run diverged"), proc.stderr
    assert "Warning" not in proc.stderr and "Traceback" not in proc.stderr
    assert "no: stopped" in proc.stdout


# ------------------------------------------------------------------ paper
PAPER_FILES = (
    "index.html", "summary.json", "factors.csv",
    "stability_chart.png", "stability_chart.svg", "ctcr_curves.csv", "ctcr_curves.npz",
    "sim_a_xy.png", "sim_a_xy.svg", "sim_a_traces.png", "sim_a_traces.svg", "sim_a.csv", "sim_a.npz", "sim_a.gif",
    "sim_a_commands.png", "sim_a_commands.svg", "sim_a_commands.npz", "sim_a_commands.csv",
    "sim_b_traces.png", "sim_b_traces.svg", "sim_b.csv", "sim_b.npz",
    "roots.csv", "dominant_surface.png", "dominant_surface.svg", "dominant_contour.png",
    "dominant_contour.svg", "dominant_map.npz", "dominant_map.csv", "schedule.json", "schedule_c.json",
)  # fmt: skip


def paper_output(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """Run ``delayform paper`` once per test session; return its directory and printed JSON.

    The browser test reuses the same output, so the slowest command runs once: in the session's
    folder, which its pytest-xdist workers share (each has its own folder inside it), under a lock
    that makes a second worker wait for the run instead of repeating it. ``make test`` schedules
    both tests on one worker (tests/conftest.py), so that nobody waits.
    """
    import fcntl
    import os

    base = tmp_path_factory.getbasetemp()
    if "PYTEST_XDIST_WORKER" in os.environ:
        base = base.parent
    base = base / "paper-run"
    base.mkdir(exist_ok=True)
    done = base / "stdout.json"
    with (base / "lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            proc = run_entry_point("paper", "--out", str(base / "paper"), "--json", cwd=base)
            done.write_text(json.dumps(_json(proc)))
    return base / "paper", json.loads(done.read_text())


@pytest.mark.slow
def test_paper_writes_every_file_it_lists(tmp_path_factory: pytest.TempPathFactory) -> None:
    out, printed = paper_output(tmp_path_factory)
    summary = json.loads((out / "summary.json").read_text())
    listed = summary["files"]
    assert set(PAPER_FILES) <= set(listed)
    for name in listed:
        assert (out / name).stat().st_size > 0, name
    assert printed["index"] == str(out / "index.html")
    sections = summary["sections"]
    # the paper's numbers: eigenvalues of C, points a..e, settling at a (~30 s) and b (> 100 s)
    eig = sorted((_complex(v) for v in sections["factors"]["eigenvalues"]), key=lambda s: (s.real, s.imag))
    np.testing.assert_allclose(
        eig, [-0.64, -0.5, -0.16 - 0.21j, -0.16 + 0.21j, 0.46, 1.0], atol=0.006
    )
    assert [p["stable"] for p in sections["chart"]["points"]] == [True, True, False, True, True]
    # Section "Simulation Examples": settled "after about 30 seconds" at a, "more than 100 seconds" at b
    assert 15.0 < sections["simulation_a"]["settling_time"] < 45.0
    assert sections["simulation_b"]["settling_time"] > 100.0
    assert sections["schedule"]["root"]["re"] < 0
    # from the unstable point c, scheduling finds stable delays no smaller than c
    assert sections["schedule_c"]["hardware_root"]["re"] > 0 > sections["schedule_c"]["root"]["re"]
    assert sections["schedule_c"]["tau1"] >= 1.0 and sections["schedule_c"]["tau2"] >= 2.0
    html = (out / "index.html").read_text()
    assert html.count("<img ") == sum(1 for n in listed if n.endswith((".png", ".gif")))
    assert "data:image/gif;base64," in html
    assert "data:image/png;base64," in html


def test_report_on_a_scenario_file(tmp_path: Path) -> None:
    scenario = tmp_path / "small.toml"
    scenario.write_text(
        'name = "small"\n[topology]\nedges = [[0, 1], [1, 2], [2, 3], [3, 0], [1, 0]]\n'
        "[gains]\nP = 1.0\nD = 1.0\n[delays]\ntau1 = 0.2\ntau2 = 0.1\n"
        "[formation]\npositions = [[0, 0], [2, 0], [2, 2], [0, 2]]\n"
        '[simulation]\nmodel = "double_integrator"\nduration = 20.0\ndt = 0.05\n'
        "[initial]\nseed = 4\n[chart]\ntau1_max = 3.0\ntau2_max = 3.0\n"
        "[map]\nsize = [11, 11]\n"
    )
    out = tmp_path / "report"
    printed = _json(run("report", str(scenario), "--out", str(out), "--json", cwd=tmp_path))
    assert set(printed) >= {"factors", "chart", "roots", "map", "schedule", "simulation_operating", "index"}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenario"]["agents"] == 4 and summary["scenario"]["topology"] == "edge list, 5 edges"
    for name in summary["files"]:
        assert (out / name).stat().st_size > 0, name
    html = (out / "index.html").read_text()
    # self-contained: every figure embedded, none fetched from elsewhere
    # chart, eigenvalue plane, surface, contour, x/y and paths: six figures, all embedded
    assert html.count('src="data:image/png;base64,') == html.count("<img ") == 6
    # the map grid came from the file: [0, tau1_max] x [0, tau2_max] by default
    with np.load(out / "dominant_map.npz") as npz:
        grid = dict(npz)
    assert grid["real_part"].shape == (11, 11) and grid["tau1"][-1] == 3.0


def test_report_says_when_no_delays_are_stable(tmp_path: Path) -> None:
    # a directed ring of six with little damping is unstable at every delay in [0, 2]^2
    scenario = tmp_path / "weak.toml"
    scenario.write_text(
        '[topology]\nname = "ring"\nn = 6\n[gains]\nP = 1.0\nD = 0.2\n[delays]\ntau1 = 0.2\ntau2 = 0.1\n'
        '[formation]\nshape = "hexagon"\n[simulation]\nmodel = "double_integrator"\nduration = 5.0\ndt = 0.05\n'
        "[chart]\ntau1_max = 2.0\ntau2_max = 2.0\n[map]\nsize = [5, 5]\n"
    )
    printed = _json(run("report", str(scenario), "--out", str(tmp_path / "out"), "--json", cwd=tmp_path))
    assert printed["chart"]["stable_fraction"] == 0.0
    assert printed["schedule"]["stable_delays_found"] is False
    assert "no stable delays" in (tmp_path / "out" / "index.html").read_text()
    # the schedule command alone reports it as one line
    proc = run("schedule", str(scenario), "--out", str(tmp_path / "out2"), cwd=tmp_path)
    assert_one_line_error(proc, "no stable delay pair")
