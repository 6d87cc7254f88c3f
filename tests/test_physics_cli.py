"""Robots with mass from the scenario file and the command line (``--model physics``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from cli_runner import run_in_process

pytest.importorskip("mujoco")

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = str(ROOT / "examples" / "create3_hexagon.toml")

SMALL = """\
[topology]
name = "ring"
n = 3
[gains]
P = 1.0
D = 1.5
[delays]
tau1 = 0.3
tau2 = 0.2
[formation]
shape = "polygon"
spacing = 1.0
[simulation]
model = "physics"
duration = 3.0
dt = 0.02
[robot]
profile = "turtlebot3_burger"
"""


def test_scenario_model_physics_takes_the_profile_chassis(tmp_path: Path) -> None:
    from delayform.deploy.profiles import robot_profile
    from delayform.scenario import load_scenario

    path = tmp_path / "s.toml"
    path.write_text(SMALL)
    robot = load_scenario(path).robot_spec
    burger = robot_profile("turtlebot3_burger")
    assert robot.model == "physics" and robot.chassis == burger.chassis and robot.limits == burger.limits


def test_montecarlo_runs_robots_with_mass(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(SMALL)
    proc = run_in_process("montecarlo", str(path), "--runs", "2", "--out", "mc", "--json", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    printed = json.loads(proc.stdout)
    assert printed["runs"] == 2 and printed["setup"]["model"] == "physics"


@pytest.mark.slow
def test_simulate_physics_settles_at_the_design_and_not_at_point_c(tmp_path: Path) -> None:
    """The exact chart says (0.3, 0.2) with D = 1.5 is stable and the paper's point c is not."""
    from delayform.analysis.roots.dominant import dominant_root
    from delayform.topology import paper_six

    # 20 s of the example's 60: the team settles at about 11 s and stays settled the 9 s after (the
    # status needs the error below its band to the end); point c, unstable, has not settled at 30 s
    good = run_in_process("simulate", EXAMPLE, "--model", "physics", "--duration", "20", "--out", "a", "--json",
                          cwd=tmp_path)  # fmt: skip
    assert good.returncode == 0, good.stderr
    summary = json.loads(good.stdout)
    assert dominant_root(paper_six(), 1.0, 1.5, 0.3, 0.2).root.real < 0
    assert summary["status"] == "settled" and summary["model"] == "physics"
    # what the dynamics cost, beside the kinematic robots with the same limits
    assert summary["kinematic"]["status"] == "settled"
    assert 0.0 < summary["kinematic"]["max_deviation"] < 0.1
    assert abs(summary["kinematic"]["settling_time"] - summary["settling_time"]) < 1.0
    bad = run_in_process("simulate", EXAMPLE, "--model", "physics", "--D", "0.5", "--tau1", "1", "--tau2", "2",
                         "--duration", "30", "--out", "c", "--json", cwd=tmp_path)  # fmt: skip
    assert bad.returncode == 0, bad.stderr
    assert dominant_root(paper_six(), 1.0, 0.5, 1.0, 2.0).root.real > 0
    assert json.loads(bad.stdout)["status"] != "settled"
    rows = np.loadtxt(tmp_path / "a" / "sim_operating.csv", delimiter=",", skiprows=1, max_rows=12)
    assert rows.shape[1] == 8  # time, agent, x, y, heading, speed, dv_dt, omega
