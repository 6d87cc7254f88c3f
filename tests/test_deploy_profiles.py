"""Robot profiles, the [robot] profile key, `--robot`, `--mcap` and `delayform check`.

Profile numbers are compared with the makers' published figures (each
source named in :mod:`delayform.deploy.profiles`); the check's
control-rate verdict, a CTCR certificate, is compared with the rightmost
characteristic root at the far corner of its box (an independent method).
"""

from __future__ import annotations

import dataclasses
import subprocess
from pathlib import Path

import numpy as np
import pytest
from cli_runner import run_in_process

from delayform.deploy import PROFILES, robot_profile
from delayform.deploy.fit import formation_fit, require_formation_fit
from delayform.errors import RobotProfileError, ScenarioError
from delayform.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "create3_hexagon.toml"

#: published figures: (profile, field, value, source)
PUBLISHED = [
    ("robotarium", "max_speed", 0.2, "Robotarium simulator, max_linear_velocity"),
    ("robotarium", "wheel_radius", 0.016, "Robotarium simulator"),
    ("robotarium", "axle_length", 0.105, "Robotarium simulator, base_length"),
    ("robotarium", "radius", 0.055, "Robotarium simulator, robot_diameter 0.11"),
    ("create3", "max_speed", 0.306, "Create 3 docs, Safety Overrides"),
    ("create3", "max_acceleration", 0.9, "Create 3 docs, wheel_accel_limit 900 mm/s^2"),
    ("create3", "axle_length", 0.233, "create3_sim control.yaml"),
    ("turtlebot3_burger", "max_speed", 0.22, "ROBOTIS e-Manual"),
    ("turtlebot3_burger", "max_turn_rate", 2.84, "ROBOTIS e-Manual"),
    ("create2", "axle_length", 0.235, "libcreate CREATE_2"),
    ("create2", "max_speed", 0.5, "Create 2 OI"),
]


@pytest.mark.parametrize(("name", "key", "value", "source"), PUBLISHED)
def test_profile_numbers_are_the_published_ones(name, key, value, source):
    assert getattr(PROFILES[name].limits, key) == pytest.approx(value, rel=1e-12), source


@pytest.mark.parametrize("name", list(PROFILES))
def test_every_number_has_a_source_and_derived_numbers_add_up(name):
    p = PROFILES[name]
    physical = {f.name for f in dataclasses.fields(p.limits)} - {"slow_speed", "turn_time_constant"}
    assert physical <= set(p.sources), physical - set(p.sources)
    lim = p.limits
    for key, text in p.sources.items():
        assert text.strip(), key
        if key == "max_wheel_speed" and text.startswith("derived"):
            assert lim.max_wheel_speed * lim.wheel_radius == pytest.approx(lim.max_speed)
        if key == "max_turn_rate" and text.startswith("derived"):
            assert lim.max_turn_rate == pytest.approx(2 * lim.max_speed / lim.axle_length)
    if p.arena is not None:
        assert "arena" in p.sources


def test_create_is_todays_default_and_robotarium_has_its_arena():
    from delayform.simulation import IROBOT_CREATE

    assert robot_profile("create").limits == IROBOT_CREATE
    arena = robot_profile("gritsbot").arena
    assert (arena.width, arena.height, arena.x_min, arena.y_min) == (3.2, 2.0, -1.6, -1.0)
    assert robot_profile("Turtlebot3-Burger") is PROFILES["turtlebot3_burger"]


def test_unknown_profile_says_what_exists():
    with pytest.raises(RobotProfileError, match="did you mean 'create3'"):
        robot_profile("creat3")
    with pytest.raises(ValueError, match="known: create, create2"):
        robot_profile("roomba")


def test_cli_names_are_the_profiles():
    from delayform.cli._common import ROBOT_NAMES

    assert ROBOT_NAMES == tuple(PROFILES)


def test_formation_fit_against_brute_force():
    rng = np.random.default_rng(5)
    z = rng.uniform(-1, 1, size=(40, 2))
    d = np.hypot(*(z[:, None] - z[None]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    fit = formation_fit(z, robot_profile("robotarium"))
    assert fit.closest_places == pytest.approx(d.min(), rel=1e-12)
    assert fit.arena_fits is False  # 2 m of centres in y plus a body radius each side exceeds the 2 m arena
    assert formation_fit(0.8 * z, robot_profile("robotarium")).arena_fits is True
    with pytest.raises(RobotProfileError, match="more than the arena"):
        require_formation_fit(z * 1.5, robot_profile("robotarium"))


def _scenario_text(profile: str, extra: str = "") -> str:
    return ("[topology]\nname = \"paper_six\"\n[gains]\nP = 1.0\nD = 0.5\n[delays]\ntau1 = 0.3\ntau2 = 0.2\n"
            f"[formation]\nshape = \"hexagon\"\n[robot]\nprofile = \"{profile}\"\n{extra}")  # fmt: skip


def test_scenario_profile_key(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(_scenario_text("robotarium", "max_speed = 0.1\n"))
    sc = load_scenario(path)
    assert sc.robot_profile == "robotarium"
    assert sc.robot == dataclasses.replace(robot_profile("robotarium").limits, max_speed=0.1)
    path.write_text(_scenario_text("robotariun"))
    with pytest.raises(ScenarioError, match="robot.profile: unknown robot profile 'robotariun'"):
        load_scenario(path)


# ------------------------------------------------------------------ command line
def run(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``delayform ARGS`` in-process (``tests/test_cli.py`` runs the entry point in a subprocess)."""
    return run_in_process(*args, cwd=cwd)


def one_line_error(proc, *needles):
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("delayform: error: "), proc.stderr
    for needle in needles:
        assert needle in lines[0]


@pytest.mark.slow
def test_simulate_robot_and_mcap(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    (tmp_path / "small.toml").write_text(_scenario_text("create").replace('shape = "hexagon"',
                                                                          'shape = "hexagon"\nspacing = 0.4'))  # fmt: skip
    proc = run("simulate", "small.toml", "--robot", "robotarium", "--duration", "4", "--dt", "0.02", "--out", "o",
               "--mcap", "run.mcap", cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    with open(tmp_path / "run.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        speeds = [abs(m.linear.x) for _, ch, _, m in reader.iter_decoded_messages() if ch.topic.endswith("cmd_vel")]
    assert len(speeds) == 6 * 201
    assert 0.15 < max(speeds) <= 0.2
    with np.load(tmp_path / "o" / "sim_operating_commands.npz") as saved:
        npz = dict(saved)
    assert float(np.abs(npz["v"]).max()) == pytest.approx(max(speeds), rel=1e-12)


@pytest.mark.slow
def test_simulate_bad_robot_inputs_leave_nothing(tmp_path):
    one_line_error(run("simulate", "--robot", "roomba", "--out", "o", cwd=tmp_path), "unknown robot profile 'roomba'")
    # (an --mcap folder that does not exist is created as --out is: tests/test_hardening_inputs.py)
    (tmp_path / "tight.toml").write_text(_scenario_text("robotarium").replace('shape = "hexagon"',
                                                                              'shape = "hexagon"\nspacing = 0.1'))  # fmt: skip
    one_line_error(run("simulate", "tight.toml", "--out", "o", "--mcap", "r.mcap", cwd=tmp_path),
                   "does not fit Robotarium GRITSbot", "0.11 m")  # fmt: skip
    one_line_error(run("simulate", "--robot", "create3", "--no-limits", "--out", "o", cwd=tmp_path), "--robot")
    one_line_error(run("montecarlo", "--robot", "robotarium", "--runs", "2", "--out", "o", cwd=tmp_path),
                   "more than the arena's 3.2 m x 2 m")  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tight.toml"]


@pytest.mark.slow
def test_check_page_and_exit_codes(tmp_path):
    proc = run("check", str(EXAMPLE), cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for key in ("limits", "radius", "arena", "control rate", "jitter", "The design fits the robot."):
        assert key in proc.stdout
    proc = run("check", "--robot", "robotarium", "--duration", "20", cwd=tmp_path)
    assert proc.returncode == 1
    assert "arena         does not fit" in proc.stdout
    one_line_error(run("check", cwd=tmp_path), "--robot NAME")


def test_control_rate_certificate_against_the_rightmost_root():
    from delayform.analysis.roots import dominant_root
    from delayform.report.check import _delay_verdicts

    sc = load_scenario(EXAMPLE)
    rate, jitter = _delay_verdicts(sc, robot_profile("create3"))
    assert rate.fits is True
    h = rate.numbers["control_period"]
    for t1, t2 in ((sc.tau1 + h, sc.tau2 + h), (sc.tau1 + h, sc.tau2), (sc.tau1, sc.tau2 + h)):
        assert dominant_root(sc.topology, sc.P, sc.D, t1, t2).is_stable
    # a design near the edge: the margin is finite and the roots agree on both sides of it
    tight = dataclasses.replace(sc, P=1.0, D=0.5, tau1=0.3, tau2=1.0)
    _, j = _delay_verdicts(tight, robot_profile("create3"))
    margin = j.numbers["jitter_margin"]
    assert 0.0 < margin < 1.0
    assert dominant_root(tight.topology, 1.0, 0.5, 0.3 + 0.9 * margin, 1.0 + 0.9 * margin).is_stable


@pytest.mark.slow
def test_robot_check_numbers_and_plot():
    from delayform.report.check import robot_check
    from delayform.scenario import SimulationSpec

    sc = load_scenario(EXAMPLE)
    sc = dataclasses.replace(sc, simulation=SimulationSpec(model="unicycle", duration=30.0, dt=0.02))
    result = robot_check(sc, "create3")
    assert result.fits, result.page()
    traj = result.trajectory
    assert float(np.abs(traj.commands.speed).max()) <= 0.306  # the profile's limits drove the run
    pos = traj.positions
    brute = min(float(np.hypot(*(pos[:, i] - pos[:, j]).T).min()) for i in range(6) for j in range(i))
    radius = next(v for v in result.verdicts if v.key == "radius")
    # the run's closest approach is exact between saved steps (simulation.bodies.approach): at most the sampled
    # minimum, and within what two robots at 0.306 m/s close in one saved step (0.02 s) of it
    approach = radius.numbers["closest_approach"]
    assert approach == traj.min_distance and brute - 2 * 0.306 * 0.02 <= approach <= brute
    assert [v.key for v in result.verdicts] == ["limits", "radius", "arena", "control rate", "jitter"]
    assert result.summary()["verdicts"]["arena"]["fits"] is None
    ax = result.plot()
    assert len(ax.patches) == 6  # one body per robot, no arena


def test_check_jitter_margins_agree_with_the_exact_map():
    """The time-varying (small-gain) margin implies the constant one, which the exact CTCR map measures.

    Delays varying within tau +- delta include every constant pair in [tau, tau + delta]^2, so the
    exact map's constant margin can never be smaller than the certified time-varying one: two
    independent methods, and a certificate that said more than the map would be unsound.
    """
    from delayform.report.check import robot_check

    for tau in ((0.3, 0.2), (2.0, 1.0)):
        sc = dataclasses.replace(load_scenario(EXAMPLE), tau1=tau[0], tau2=tau[1])
        numbers = next(v for v in robot_check(sc, "create3").verdicts if v.key == "jitter").numbers
        varying, constant = numbers["time_varying_jitter_margin"], numbers["jitter_margin"]
        assert 0.0 < varying
        assert constant >= varying * (1 - 1e-4)
        assert numbers["tick_variation_certified"] == (numbers["tick_jitter_margin"] >= 0.005)
