"""Robots with mass in a physics engine: the bodies, the wheels, the contacts, and the team.

Independent references: the differential drive's closed forms (v = r (wl + wr) / 2,
omega = r (wr - wl) / L) for the engine's bodies; the kinematic saturated unicycle
(another integrator of another model) for the team; the first-order servo's closed form
(Chassis.servo_time_constant) for the identification.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("mujoco")

import delayform.simulation.physics as physics  # noqa: E402
from delayform.errors import RobotProfileError, SimulationInputError  # noqa: E402
from delayform.formation import formation_forcing  # noqa: E402
from delayform.model import (  # noqa: E402
    CREATE_CHASSIS,
    IROBOT_CREATE,
    PROFILES,
    Chassis,
    Delays,
    LinkDelays,
    Network,
    Robot,
    RobotProfile,
    Start,
    Team,
    robot_profile,
)
from delayform.simulation import monte_carlo, simulate  # noqa: E402
from delayform.simulation.runs.compat import MONTE_CARLO_KEYWORDS  # noqa: E402
from delayform.simulation.runs.integrators import INTEGRATORS, PhysicsModel  # noqa: E402
from delayform.simulation.physics.engine import PhysicsTeam, integrate_physics, tick_grid  # noqa: E402
from delayform.simulation.physics.mjcf import team_mjcf  # noqa: E402
from delayform.topology import complete, paper_six  # noqa: E402

#: examples/create3_hexagon.toml's start: a ring twice as wide as the 1 m hexagon
RING = np.array([[4.0, 0.0], [2.0, 3.464], [-2.0, 3.464], [-4.0, 0.0], [-2.0, -3.464], [2.0, -3.464]])
HEADINGS = np.array([3.1416, -2.0944, -1.0472, 0.0, 1.0472, 2.0944])


def _drive(profile: RobotProfile, left: float, right: float, seconds: float, n: int = 1, poses=None):
    """One or more robots of ``profile`` at rest, both wheels commanded; the measured state each engine step."""
    lim, ch = profile.limits, profile.chassis
    if poses is None:
        poses = np.zeros((n, 3))
    team = PhysicsTeam(ch, lim, poses[:, :2], poses[:, 2], np.zeros(len(poses)))
    team.command(np.full(len(poses), left), np.full(len(poses), right))
    out = []
    for _ in range(round(seconds / team.model.opt.timestep)):
        team.step(1)
        out.append(team.measure())
    X, V, th, v = (np.array(a) for a in zip(*out))
    return team, X, V, np.unwrap(th, axis=0), v


def _second(team) -> int:
    """Engine steps in one second."""
    return round(1.0 / team.model.opt.timestep)


# ------------------------------------------------------------------ the model
@pytest.mark.parametrize("name", list(PROFILES))
def test_mjcf_builds_for_every_profile_with_its_masses_and_rests_level(name):
    import mujoco

    profile = PROFILES[name]
    ch, lim = profile.chassis, profile.limits
    poses = np.array([[0.0, 0.0, 0.3], [1.0, 0.0, -1.0], [0.0, 1.0, 2.0]])
    model = mujoco.MjModel.from_xml_string(team_mjcf(ch, lim, poses))
    assert (model.nu, model.njnt) == (6, 9)
    # every robot weighs its chassis and two wheels (the world body weighs nothing)
    assert model.body_mass.sum() == pytest.approx(3 * (ch.mass + 2 * ch.wheel_mass), rel=1e-12)
    assert model.opt.timestep == pytest.approx(ch.engine_grid()[0]) and model.opt.timestep <= 0.002
    # at rest on its wheels and caster: level, still, where it was put
    team, X, V, th, v = _drive(profile, 0.0, 0.0, 0.5, poses=poses)
    q = team.data.qpos.reshape(3, 9)
    roll_pitch = 2 * np.hypot(q[:, 4], q[:, 5])  # quaternion x, y: twice the half-angle sines
    assert roll_pitch.max() < 1e-2
    np.testing.assert_allclose(X[-1], poses[:, :2], atol=1e-3)
    np.testing.assert_allclose(th[-1], poses[:, 2], atol=1e-3)


@pytest.mark.parametrize("name", ["create3", "turtlebot3_burger", "robotarium"])
def test_straight_line_speed_is_wheel_speed_times_radius(name):
    profile = PROFILES[name]
    r = profile.limits.wheel_radius
    w = 0.5 * profile.limits.max_wheel_speed
    team, X, _, th, v = _drive(profile, w, w, 3.0)
    # after the servo's transient (a few time constants): v = w r, straight ahead
    assert v[-1] == pytest.approx(w * r, rel=5e-3)
    travelled = X[-1, 0, 0] - X[-1 - _second(team), 0, 0]  # the last second
    assert travelled == pytest.approx(w * r * 1.0, rel=5e-3)
    assert abs(th[-1, 0]) < 1e-6 and abs(X[-1, 0, 1]) < 1e-6


@pytest.mark.parametrize("name", ["create3", "turtlebot3_burger"])
def test_turn_matches_differential_drive_kinematics(name):
    profile = PROFILES[name]
    r, L = profile.limits.wheel_radius, profile.limits.axle_length
    wl, wr = 0.2 * profile.limits.max_wheel_speed, 0.5 * profile.limits.max_wheel_speed
    team, X, _, th, v = _drive(profile, wl, wr, 4.0)
    omega = (th[-1, 0] - th[-1 - _second(team), 0]) / 1.0
    assert omega == pytest.approx(r * (wr - wl) / L, rel=2e-2)
    assert v[-1, 0] == pytest.approx(r * (wl + wr) / 2, rel=1e-2)
    # the path of the last second lies on the circle of radius v / omega
    centre_offset = np.array([-np.sin(th[-1, 0]), np.cos(th[-1, 0])]) * (v[-1, 0] / omega)
    centre = X[-1, 0] + centre_offset
    radii = np.hypot(*(X[-_second(team):, 0] - centre).T)
    assert np.ptp(radii) < 2e-3


def test_head_on_bodies_touch_and_do_not_pass_through():
    profile = PROFILES["create3"]
    R = profile.limits.radius
    w = profile.limits.max_wheel_speed
    poses = np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, math.pi]])
    _, X, _, _, _ = _drive(profile, w, w, 4.0, poses=poses)
    gap = np.hypot(*(X[:, 0] - X[:, 1]).T)
    assert gap.min() <= 2 * R + 1e-3  # they met ...
    assert gap.min() >= 2 * R - 2e-3  # ... and pushed at full torque: no deeper than the soft contact's 2 mm
    assert np.all(X[:, 0, 0] < X[:, 1, 0])  # nobody passed through


def test_two_robots_into_touching_slots_report_their_contacts():
    """Two robots cross to touching slots: the run reports the contact, as for the kinematic models."""
    R = PROFILES["create3"].limits.radius
    slots = np.array([[R, 0.0], [-R, 0.0]])
    traj = simulate(complete(2), 1.0, 1.5, 0.1, 0.1, slots, model="physics",
                    limits=PROFILES["create3"].limits, initial_positions=[[-1.0, 0.0], [1.0, 0.0]],
                    initial_headings=[0.0, math.pi], duration=20.0, dt=0.01)  # fmt: skip
    assert traj.model == "physics"
    assert traj.contacts  # they touched
    assert traj.min_distance >= 2 * R - 5e-3  # and stayed apart


# --------------------------------------------------------------- the team
def test_physics_run_is_a_trajectory_settling_near_the_kinematic_run():
    create3 = robot_profile("create3")
    kw = dict(initial_positions=RING / 2, initial_headings=HEADINGS, initial_speed=1e-3, duration=20.0, dt=0.01)
    phys = simulate(paper_six(), 1.0, 1.5, 0.3, 0.2, "hexagon",
                    robot=Robot(model="physics", limits=create3.limits, chassis=create3.chassis), **kw)  # fmt: skip
    kin = simulate(paper_six(), 1.0, 1.5, 0.3, 0.2, "hexagon", limits=create3.limits, **kw)
    assert type(phys) is type(kin) and phys.model == "physics"
    assert phys.status == "settled" and kin.status == "settled"
    assert phys.times[1] == pytest.approx(create3.chassis.control_period)
    assert phys.commands is not None and phys.commands.limited
    assert phys.commands.speed.max() <= create3.limits.speed_cap * 1.05
    # the same formation, placed by the same dynamics of the centroid
    assert np.abs(phys.positions[-1] - kin.positions[-1]).max() < 0.1
    assert abs(phys.settling_time - kin.settling_time) < 2.0


def test_network_with_the_design_delays_on_every_link_is_the_plain_run():
    topo = paper_six()
    lim, ch = IROBOT_CREATE, CREATE_CHASSIS
    F = formation_forcing(topo, 1.0, RING / 4)
    common = dict(chassis=ch, limits=lim, x0=RING / 2, th0=HEADINGS, speed0=np.full(6, 1e-3), duration=3.0,
                  save_every=1)  # fmt: skip
    plain = integrate_physics(topo, F, 1.0, 1.5, 0.3, 0.2, **common)
    links = Network(delays=LinkDelays(tau1=np.full((6, 6), 0.3), tau2=np.full((6, 6), 0.2)))
    heard = integrate_physics(topo, F, 1.0, 1.5, 0.3, 0.2, network=links, **common)
    np.testing.assert_allclose(heard.positions, plain.positions, atol=1e-12)
    slower = Network(delays=LinkDelays(tau1=np.full((6, 6), 0.6), tau2=np.full((6, 6), 0.2)))
    late = integrate_physics(topo, F, 1.0, 1.5, 0.3, 0.2, network=slower, **common)
    assert np.abs(late.positions[-1] - plain.positions[-1]).max() > 1e-3  # the network reaches the run


def test_the_noun_form_runs_the_profile_s_chassis_as_the_loose_form_does():
    """Robot(model="physics", profile=...) is one entry of the integrator table, reached from both call forms."""
    burger = robot_profile("turtlebot3_burger")
    robot = Robot(model="physics", profile="turtlebot3_burger")
    assert robot.chassis is burger.chassis and robot.limits == burger.limits
    assert isinstance(INTEGRATORS["physics"], PhysicsModel) and physics.Chassis is Chassis
    nouns = simulate(Team(paper_six(), 1.0, 1.5), Delays(0.3, 0.2), "hexagon", robot=robot,
                     start=Start(RING / 4, HEADINGS, 1e-3), duration=1.0, dt=0.03)  # fmt: skip
    loose = simulate(paper_six(), 1.0, 1.5, 0.3, 0.2, "hexagon", robot=Robot(model="physics", limits=burger.limits,
                     chassis=burger.chassis), initial_positions=RING / 4, initial_headings=HEADINGS,
                     initial_speed=1e-3, duration=1.0, dt=0.03)  # fmt: skip
    np.testing.assert_array_equal(nouns.positions, loose.positions)
    # dt is the sampling, on whole control ticks (3 of 10 ms), and the run ends on the duration's tick;
    # the trajectory's step is the tick
    np.testing.assert_allclose(np.diff(nouns.times[:-1]), 0.03, atol=1e-12)
    assert nouns.times[-1] == pytest.approx(1.0)
    assert nouns.dt == burger.chassis.control_period


def test_monte_carlo_s_chassis_travels_on_the_robot():
    light = CREATE_CHASSIS.with_changes(mass=2.0)
    assert MONTE_CARLO_KEYWORDS["chassis"] == "Robot.chassis"
    loose = monte_carlo(paper_six(), 1.0, 1.5, 0.3, 0.2, "hexagon", model="physics", chassis=light,
                        initial_positions=RING / 2, runs=1, duration=0.5, dt=0.05)  # fmt: skip
    nouns = monte_carlo(Team(paper_six(), 1.0, 1.5), Delays(0.3, 0.2), "hexagon",
                        robot=Robot(model="physics", chassis=light), start=Start(RING / 2),
                        runs=1, duration=0.5, dt=0.05)  # fmt: skip
    assert loose.setup.robot.chassis == nouns.setup.robot.chassis == light
    np.testing.assert_array_equal(loose.final_errors, nouns.final_errors)
    with pytest.raises(SimulationInputError, match="physics"):  # the loose form's model stays the double integrator
        monte_carlo(paper_six(), 1.0, 1.5, 0.3, 0.2, "hexagon", chassis=light, runs=1, duration=0.5, dt=0.05)


def test_tick_grid_rounds_the_control_period_to_engine_steps():
    # the period stays exact; the engine's step is the longest up to 2 ms that divides it
    assert tick_grid(CREATE_CHASSIS.with_changes(control_period=0.033)) == (0.033, 17)
    assert CREATE_CHASSIS.with_changes(control_period=0.033).engine_grid()[0] == pytest.approx(0.033 / 17)
    assert CREATE_CHASSIS.with_changes(control_period=1e-4).engine_grid() == (1e-4, 1)


# ---------------------------------------------------------------- refusals
@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(model="unicycle", chassis=CREATE_CHASSIS), "physics"),
        (dict(model="physics", chassis="create3"), "Chassis"),
    ],
)
def test_robot_refuses_what_the_physics_model_does_not_model(kwargs, words):
    with pytest.raises(SimulationInputError, match=words):
        Robot(**kwargs)


@pytest.mark.parametrize("field, value", [("mass", 0.0), ("servo_gain", -1.0), ("caster_offset", 0.0),
                                          ("max_torque", math.inf), ("tyre_friction", "high")])  # fmt: skip
def test_chassis_refuses_bad_numbers_by_name(field, value):
    with pytest.raises(SimulationInputError, match=field):
        CREATE_CHASSIS.with_changes(**{field: value})


def test_profile_without_physical_numbers_is_refused_naming_them():
    bare = RobotProfile(name="mine", title="Mine", limits=IROBOT_CREATE)
    with pytest.raises(RobotProfileError, match="missing: mass, height, wheel_mass"):
        bare.physics_chassis()
    with pytest.raises(RobotProfileError, match="'mine' has no physical numbers"):
        Robot(model="physics", profile=bare)


def test_every_profile_names_a_source_or_an_assumption_for_each_physical_number():
    for profile in PROFILES.values():
        assert isinstance(profile.chassis, Chassis)
        for field in ("mass", "height", "wheel_mass", "wheel_width", "caster_offset", "tyre_friction",
                      "servo_gain", "max_torque", "control_period"):  # fmt: skip
            assert profile.sources[f"chassis.{field}"], (profile.name, field)
    assert "1 kg" in PROFILES["turtlebot3_burger"].sources["chassis.mass"]
    assert "assumption" in PROFILES["create3"].sources["chassis.servo_gain"]


# ------------------------------------------------------ what the dynamics cost
def _stiffer(chassis: Chassis, factor: float) -> Chassis:
    """Servo gain, torque and tyre friction all ``factor`` times the profile's."""
    return chassis.with_changes(servo_gain=chassis.servo_gain * factor, max_torque=chassis.max_torque * factor,
                                tyre_friction=chassis.tyre_friction * factor)  # fmt: skip


@pytest.mark.slow
def test_stiffer_servos_and_grippier_tyres_converge_to_the_kinematic_model():
    """The independent reference is the kinematic saturated unicycle (RK4 on another model)."""
    from delayform.simulation.physics import compare_with_kinematic

    create3 = robot_profile("create3")
    worst = []
    for factor in (1.0, 4.0, 16.0):
        robot = Robot(model="physics", limits=create3.limits, chassis=_stiffer(create3.chassis, factor))
        cmp = compare_with_kinematic(paper_six(), 1.0, 1.5, 0.3, 0.2, "hexagon", robot=robot,
                                     initial_positions=RING / 2, initial_headings=HEADINGS,
                                     duration=15.0, dt=0.01)  # fmt: skip
        worst.append(cmp.max_deviation)
        assert cmp.physics.status == cmp.kinematic.status == "settled"
    assert worst[0] > worst[1] > worst[2]
    # the stiff limit: within 1 cm of the kinematic robots (settled at 5.3 s; the largest deviation is at
    # 2.6 s, and 60 s of run gave the same 3.3 mm)
    assert worst[2] < 0.01


def test_comparison_reports_positions_and_settling_of_both_runs():
    from delayform.simulation.physics import KinematicComparison, compare_with_kinematic

    cmp = compare_with_kinematic(paper_six(), 1.0, 1.5, 0.3, 0.2, "hexagon", initial_positions=RING / 2,
                                 initial_headings=HEADINGS, duration=6.0, dt=0.01)  # fmt: skip
    assert cmp.physics.model == "physics" and cmp.kinematic.model == "unicycle"
    assert cmp.kinematic.limits == cmp.physics.limits == IROBOT_CREATE
    assert cmp.deviation.shape == cmp.times.shape and cmp.deviation[0] == 0.0
    assert 0.0 < cmp.max_deviation < 0.2
    direct = np.hypot(*(cmp.physics.positions[-1] - cmp.kinematic.positions[-1]).T).max()
    assert cmp.final_deviation == pytest.approx(direct, rel=1e-9)  # both sampled at 6 s
    assert "cm of the kinematic robots" in cmp.describe()
    again = KinematicComparison.of(cmp.physics, cmp.kinematic)
    np.testing.assert_array_equal(again.deviation, cmp.deviation)
    nouns = compare_with_kinematic(Team(paper_six(), 1.0, 1.5), Delays(0.3, 0.2), "hexagon",
                                   start=Start(RING / 2, HEADINGS), duration=6.0, dt=0.01)  # fmt: skip
    np.testing.assert_array_equal(nouns.deviation, cmp.deviation)  # the loose form is the noun form
    with pytest.raises(SimulationInputError, match="physics"):
        compare_with_kinematic(paper_six(), 1.0, 1.5, 0.3, 0.2, "hexagon", robot=Robot(), duration=1.0, dt=0.01)


@pytest.mark.parametrize("name", ["create3", "turtlebot3_burger"])
def test_identification_recovers_the_servo_time_constant(name):
    """Against the closed form of a first-order servo driving the wheel, rotor and half the chassis."""
    from delayform.simulation.physics import identify_actuation

    profile = robot_profile(name)
    for factor in (0.5, 1.0):
        chassis = profile.chassis.with_changes(servo_gain=profile.chassis.servo_gain * factor)
        ident = identify_actuation(chassis, profile.limits)
        assert ident.time_constant == pytest.approx(chassis.servo_time_constant(profile.limits.wheel_radius), rel=0.06)
        assert ident.gain == pytest.approx(1.0, abs=5e-3)
        assert ident.dead_time < 0.005
        assert ident.effective_delay == pytest.approx(ident.dead_time + ident.time_constant)
        assert ident.rms_error < 0.02 * ident.step_speed


def test_the_identified_lag_changes_verdicts_where_the_dominant_root_crosses():
    """The chart with tau_a (CTCR) against the dominant root with tau_a (root finding) at the pairs that change."""
    from delayform.analysis.roots.dominant import dominant_root
    from delayform.simulation.physics import actuation_verdict, identify_actuation

    create3 = robot_profile("create3")
    ta = identify_actuation(create3.chassis, create3.limits).effective_delay
    verdict = actuation_verdict(paper_six(), 1.0, 0.5, 4.0, 4.0, ta, resolution=41)
    assert verdict.lost.any()
    rows, cols = np.nonzero(verdict.lost)
    for k in np.linspace(0, rows.size - 1, 3).astype(int):
        t1, t2 = verdict.tau1[cols[k]], verdict.tau2[rows[k]]
        assert dominant_root(paper_six(), 1.0, 0.5, t1, t2).root.real < 0
        assert dominant_root(paper_six(), 1.0, 0.5, t1, t2, actuation_delay=ta).root.real > 0
    assert "loses stability" in verdict.describe()
