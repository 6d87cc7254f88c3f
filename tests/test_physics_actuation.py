"""Robots with mass behind the safety filter, with an actuation delay, and recorded as ROS 2 messages.

Independent references: the filter's distance and the engine's contact (the bodies'
radii); the undelayed step response shifted by the delay; the dominant root of the
characteristic equation (root finding, not simulation) at the identified lag; the
kinematic unicycle (another integrator) at the same delay; mcap-ros2-support's own
CDR decoder for the recording.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco")

from delayform.analysis.roots.dominant import dominant_root  # noqa: E402
from delayform.errors import SimulationInputError  # noqa: E402
from delayform.model import Robot, robot_profile  # noqa: E402
from delayform.simulation import simulate  # noqa: E402
from delayform.simulation.physics import identify_actuation  # noqa: E402
from delayform.simulation.physics.engine import CommandQueue, PhysicsTeam, tick_grid  # noqa: E402
from delayform.topology import complete, paper_six  # noqa: E402

CREATE3 = robot_profile("create3")
RING = np.array([[4.0, 0.0], [2.0, 3.464], [-2.0, 3.464], [-4.0, 0.0], [-2.0, -3.464], [2.0, -3.464]])
HEADINGS = np.array([3.1416, -2.0944, -1.0472, 0.0, 1.0472, 2.0944])


# ------------------------------------------------------------------ safety filter
def _head_on(safety: str | None):
    """Two Create 3s sent head-on to each other's side: slots at the filter's distance, 2 m apart at the start."""
    lim = CREATE3.limits
    safe = 2 * lim.radius + 0.02  # the filter's default margin
    slots = np.array([[safe / 2, 0.0], [-safe / 2, 0.0]])
    robot = Robot(model="physics", limits=lim, safety=safety)
    return simulate(complete(2), 1.0, 1.5, 0.1, 0.1, slots, robot=robot, initial_positions=[[-1.0, 0.0], [1.0, 0.0]],
                    initial_headings=[0.0, math.pi], duration=12.0, dt=0.01), safe  # fmt: skip


def test_without_the_filter_two_create3s_sent_through_each_other_touch():
    traj, _ = _head_on(None)
    assert traj.safety is None
    assert traj.contacts  # the engine's bodies met
    assert traj.min_distance >= 2 * CREATE3.limits.radius - 2e-3  # and did not pass through


def test_with_the_filter_robots_with_mass_keep_its_distance_within_the_servo_lag():
    traj, safe = _head_on("barrier")
    assert not traj.contacts
    assert traj.safety is not None and traj.safety.was_active
    assert traj.safety.safe_distance == pytest.approx(safe)
    lag = identify_actuation(CREATE3.chassis, CREATE3.limits).effective_delay
    slack = 2 * CREATE3.limits.max_acceleration * lag**2  # braking about tau_s late (engine module doc)
    assert traj.min_distance >= safe - slack
    assert traj.status == "deadlock"  # held apart short of their slots, and said so


def test_the_filter_with_an_actuation_delay_is_refused_for_robots_with_mass():
    with pytest.raises(SimulationInputError, match="actuation delay with the safety filter"):
        simulate(complete(2), 1.0, 1.5, 0.1, 0.1, np.array([[0.5, 0.0], [-0.5, 0.0]]),
                 robot=Robot(model="physics", safety="barrier", actuation_delay=0.05), duration=1.0, dt=0.01)  # fmt: skip


# ------------------------------------------------------------------ actuation delay
def _step_response(delay: float) -> tuple[float, np.ndarray]:
    """One Create 3 at rest, wheel targets stepped at tick 0 through the queue; (engine step, speeds)."""
    ch, lim = CREATE3.chassis, CREATE3.limits
    period, substeps = tick_grid(ch)
    team = PhysicsTeam(ch, lim, np.zeros((1, 2)), np.zeros(1), np.zeros(1))
    team.step(round(0.2 * substeps / period))  # settle on the floor first
    target = np.full((1, 2), 0.05 / lim.wheel_radius)
    queue = CommandQueue(delay, period, substeps, np.zeros((1, 2)))
    speeds = []
    for k in range(round(0.4 / period)):
        queue.store(k, target)
        for steps, targets in queue.segments(k):
            team.command(targets[:, 0], targets[:, 1])
            for _ in range(steps):
                team.step(1)
                speeds.append(team.measure()[3][0])
    return period / substeps, np.array(speeds)


def _crossing(dt: float, v: np.ndarray, level: float) -> float:
    """When ``v`` first reaches ``level`` (linear between engine steps)."""
    i = int(np.argmax(v >= level))
    return dt * (i + (level - v[i - 1]) / (v[i] - v[i - 1]))  # step i ends at (i + 1) dt; v[i-1] at i dt


@pytest.mark.parametrize("delay", [0.0373, 0.1])
def test_the_queue_shifts_the_servo_step_response_by_the_delay(delay):
    dt, plain = _step_response(1e-12)  # a queue that delays by nothing: every target at its own tick
    _, late = _step_response(delay)
    for level in (0.2, 0.5, 0.632, 0.9):
        shift = _crossing(dt, late, level * 0.05) - _crossing(dt, plain, level * 0.05)
        assert shift == pytest.approx(delay, abs=0.25 * dt)


def _late_decay(traj) -> float:
    """The formation error's decay rate (1/s): a line through the log of its peaks over the last 30 s."""
    from scipy.signal import find_peaks

    e, t = traj.formation_error, traj.times
    peaks, _ = find_peaks(np.log(e))
    peaks = peaks[t[peaks] >= 30.0]
    return float(np.polyfit(t[peaks], np.log(e[peaks]), 1)[0])


def _hexagon(model: str, period: float = 0.01, **robot):
    chassis = {"chassis": CREATE3.chassis.with_changes(control_period=period)} if model == "physics" else {}
    return simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon",
                    robot=Robot(model=model, limits=CREATE3.limits, **chassis, **robot),
                    initial_positions=RING, initial_headings=HEADINGS, initial_speed=1e-3, duration=60.0, dt=0.01)  # fmt: skip


@pytest.mark.slow
def test_the_identified_lag_is_L_plus_T_without_half_a_period():
    """At 50 ms ticks the formation decays as the root at L + T says, not at L + T + h/2."""
    period = 0.05
    ident = identify_actuation(CREATE3.chassis.with_changes(control_period=period), CREATE3.limits)
    measured = _late_decay(_hexagon("physics", period))
    at = dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2, actuation_delay=ident.effective_delay).root.real
    half = dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2, actuation_delay=ident.effective_delay + period / 2).root.real
    assert measured == pytest.approx(at, abs=0.005)  # -0.155 against -0.153
    assert abs(measured - half) > 0.012  # -0.139 is ruled out


@pytest.mark.slow
def test_an_actuation_delay_on_robots_with_mass_moves_the_decay_to_the_root_at_tau_a_plus_the_lag():
    """tau_a = 0.1 s at 50 ms ticks, a team on the move (where eq. transform2 is exact): the root at tau_a + L + T.

    From rest the unicycle turns before it moves, which no linear root sees (the
    kinematic unicycle with the same delay shows the same); at 0.15 m/s it does not.
    """
    ta, period = 0.1, 0.05
    chassis = CREATE3.chassis.with_changes(control_period=period)
    lag = identify_actuation(chassis, CREATE3.limits).effective_delay
    slots = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", limits=CREATE3.limits, duration=0.1, dt=0.01).desired
    start = slots + 0.3 * np.random.default_rng(1).standard_normal(slots.shape)
    traj = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon",
                    robot=Robot(model="physics", limits=CREATE3.limits, chassis=chassis, actuation_delay=ta),
                    initial_positions=start, initial_headings=np.zeros(6), initial_speed=0.15, duration=60.0, dt=0.01)  # fmt: skip
    assert traj.actuation_delay == ta and traj.status == "settled"
    measured = _late_decay(traj)
    root = dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2, actuation_delay=ta + lag).root.real
    assert measured == pytest.approx(root, abs=0.006)  # -0.092 against -0.0936
    assert abs(measured - dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2, actuation_delay=ta + lag + period / 2).root.real) > 0.01
    assert abs(measured - dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2, actuation_delay=lag).root.real) > 0.05


# ------------------------------------------------------------------ the recording
def test_simulate_physics_writes_the_ros2_topics_of_the_kinematic_model(tmp_path: Path) -> None:
    pytest.importorskip("mcap_ros2")
    from cli_runner import run_in_process
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    example = str(Path(__file__).resolve().parents[1] / "examples" / "create3_hexagon.toml")
    topics = {}
    for model in ("physics", "unicycle"):
        out = tmp_path / f"{model}.mcap"
        r = run_in_process("simulate", example, "--model", model, "--duration", "2", "--dt", "0.05",
                           "--out", str(tmp_path / model), "--mcap", str(out))  # fmt: skip
        assert r.returncode == 0, r.stderr
        with open(out, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            decoded = [(c.topic, s.name, m) for s, c, _, m in reader.iter_decoded_messages(log_time_order=True)]
        topics[model] = {(t, name) for t, name, _ in decoded}
        if model == "physics":
            odom = [m for t, _, m in decoded if t == "/robot_1/odom"]
            assert len(odom) == 41  # every saved sample, 0 to 2 s
            start = odom[0].pose.pose.position
            assert (start.x, start.y) == pytest.approx((4.0, 0.0), abs=1e-3)  # the scenario's first robot
    assert topics["physics"] == topics["unicycle"]
    points = run_in_process("simulate", example, "--model", "double_integrator", "--no-limits", "--duration", "2",
                            "--out", str(tmp_path / "di"), "--mcap", str(tmp_path / "di.mcap"))  # fmt: skip
    assert points.returncode == 2 and "use --model unicycle or physics" in points.stderr
    assert {"/robot_1/cmd_vel", "/robot_6/odom", "/tf", "/formation/links"} <= {t for t, _ in topics["physics"]}


def test_the_scenario_s_safety_and_actuation_delay_reach_the_physics_run(tmp_path: Path) -> None:
    import json

    from cli_runner import run_in_process

    example = str(Path(__file__).resolve().parents[1] / "examples" / "create3_hexagon.toml")
    common = ("simulate", example, "--model", "physics", "--duration", "4", "--dt", "0.05", "--json")
    filtered = run_in_process(*common, "--safety", "barrier", "--out", str(tmp_path / "f"))
    assert filtered.returncode == 0, filtered.stderr
    summary = json.loads(filtered.stdout)
    assert summary["model"] == "physics"
    assert summary["safety"]["safe_distance"] == pytest.approx(2 * CREATE3.limits.radius + 0.02)
    assert "contacts_without_filter" in summary  # the same run without the filter, for its cost
    plain = json.loads(run_in_process(*common, "--out", str(tmp_path / "p")).stdout)
    late = run_in_process(*common, "--actuation-delay", "0.3", "--out", str(tmp_path / "a"))
    assert late.returncode == 0, late.stderr
    # a robot whose wheels wait 0.3 s has moved less after 4 s than the one without
    assert json.loads(late.stdout)["final_error"] > plain["final_error"] + 0.05
    both = run_in_process(*common, "--safety", "barrier", "--actuation-delay", "0.1", "--out", str(tmp_path / "b"))
    assert both.returncode == 2 and "actuation delay with the safety filter" in both.stderr
