"""The on-robot controller: replaying a simulated run's messages gives that run's commands.

The simulation computes the commands with the vectorized models of
:mod:`delayform.simulation.models.robots` on the integrator's history; the
controller recomputes them for one robot at a time from the messages the
robot received (its neighbours' saved states, stamped with their send
times). The two are independent codes of the same equations.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delayform.deploy import FormationController, NeighbourMessage, robot_profile
from delayform.errors import ControllerInputError, InputError
from delayform.simulation import IROBOT_CREATE, simulate
from delayform.simulation.models.robots import LimitedUnicycle
from delayform.topology import paper_six, ring


def _replay(traj, topology, P, D, tau1, tau2, limits):
    """Each robot's controller fed the saved states as messages; returns (T, n) arrays of its commands."""
    n = topology.n
    ctrls = [FormationController.from_design(topology, P, D, tau1, tau2, traj.desired, robot=i + 1, limits=limits)
             for i in range(n)]  # fmt: skip
    T = traj.times.size
    out = {name: np.empty((T, n)) for name in ("turn_rate", "acceleration", "wheel_left", "wheel_right",
                                                 "ideal_turn_rate", "ideal_acceleration", "lag")}  # fmt: skip
    for k, t in enumerate(traj.times):
        msgs = [NeighbourMessage(j + 1, float(t), *traj.positions[k, j], *traj.velocities[k, j]) for j in range(n)]
        for i, ctrl in enumerate(ctrls):
            ctrl.receive_all(msgs)
            cmd = ctrl.tick(float(t), *traj.positions[k, i], float(traj.headings[k, i]), float(traj.speeds[k, i]))
            for name in out:
                out[name][k, i] = getattr(cmd, name)
    return out


def _assert_close(a, b, what):
    scale = 1.0 + np.abs(b)
    err = float(np.max(np.abs(a - b) / scale))
    assert err < 1e-9, f"{what}: relative difference {err:.2e}"


@pytest.mark.parametrize("limits", [IROBOT_CREATE, robot_profile("robotarium").limits], ids=["create", "robotarium"])
def test_replay_of_a_saturated_run_gives_its_commands(limits):
    topo = paper_six()
    P, D, tau1, tau2 = 1.0, 0.5, 0.3, 0.2
    traj = simulate(topo, P, D, tau1, tau2, "hexagon", limits=limits, duration=12.0, dt=0.01, save_every=1, seed=3)
    cmd = traj.commands
    assert cmd is not None and cmd.limited
    # the run does reach the limits, so the clipping and braking branches are exercised
    assert cmd.exceedances(), "the test run should push a limit"
    got = _replay(traj, topo, P, D, tau1, tau2, limits)
    _assert_close(got["turn_rate"], cmd.turn_rate, "omega")
    _assert_close(got["acceleration"], cmd.acceleration, "dv/dt")
    _assert_close(got["wheel_left"], cmd.wheel_left, "left wheel")
    _assert_close(got["wheel_right"], cmd.wheel_right, "right wheel")
    _assert_close(got["ideal_turn_rate"], cmd.ideal_turn_rate, "ideal omega")
    _assert_close(got["ideal_acceleration"], cmd.ideal_acceleration, "ideal dv/dt")
    assert np.all(got["lag"] == 0.0)  # on-grid delays, a message every step: the design's delays hold


def test_replay_of_an_ideal_run_gives_its_commands():
    topo = ring(5)
    P, D, tau1, tau2 = 1.0, 1.0, 0.2, 0.1
    traj = simulate(topo, P, D, tau1, tau2, "polygon", duration=8.0, dt=0.01, save_every=1, seed=1, initial_speed=0.05)
    cmd = traj.commands
    got = _replay(traj, topo, P, D, tau1, tau2, None)
    _assert_close(got["turn_rate"], cmd.turn_rate, "omega")
    _assert_close(got["acceleration"], cmd.acceleration, "dv/dt")
    _assert_close(got["wheel_left"], cmd.wheel_left, "left wheel")


def test_the_playout_buffer_uses_the_message_sent_tau_earlier():
    ctrl = FormationController(robot=1, P=2.0, D=1.0, tau1=0.3, tau2=0.1, weights={2: 1.0})
    for k in range(11):  # neighbour 2 at x = k (m) moving at k/10 m/s, sent at t = k/10
        ctrl.receive(NeighbourMessage(2, k / 10, float(k), 0.0, k / 10, 0.0))
    cmd = ctrl.tick(1.0, 0.0, 0.0, 0.0, 1e-3)
    # u = P (x_2(0.7) - 0) + D (xdot_2(0.9) - 1e-3) = 2 * 7 + 0.9 - 1e-3
    assert cmd.ux == pytest.approx(14.0 + 0.9 - 1e-3, rel=1e-12)
    assert cmd.lag == 0.0
    # a message from the future of t - tau (arrived early, stamped later) is not used yet
    late = ctrl.tick(0.35, 0.0, 0.0, 0.0, 1e-3)
    assert late.ux == pytest.approx(2.0 * 0.0 + (0.2 - 1e-3), rel=1e-12)


def test_lag_says_how_much_older_the_messages_are_than_the_design():
    ctrl = FormationController(robot=1, P=1.0, D=1.0, tau1=0.2, tau2=0.2, weights={2: 1.0})
    ctrl.receive(NeighbourMessage(2, 0.0, 1.0, 0.0, 0.0, 0.0))
    assert ctrl.tick(0.1, 0.0, 0.0, 0.0, 0.1).lag == 0.0  # still inside the initial history
    assert ctrl.tick(0.5, 0.0, 0.0, 0.0, 0.1).lag == pytest.approx(0.3)


def test_out_of_order_and_repeated_messages():
    a = FormationController(robot=3, P=1.0, D=0.5, tau1=0.0, tau2=0.0, weights={1: 0.5, 2: 0.5})
    b = FormationController(robot=3, P=1.0, D=0.5, tau1=0.0, tau2=0.0, weights={1: 0.5, 2: 0.5})
    msgs = [NeighbourMessage(s, t, s * t, 1.0, 0.1, 0.2) for t in (0.0, 0.1, 0.2) for s in (1, 2)]
    a.receive_all(msgs)
    b.receive_all(reversed(msgs))
    b.receive(NeighbourMessage(9, 0.2, 1e9, 0.0, 0.0, 0.0))  # not a neighbour: ignored
    assert a.tick(0.2, 0.1, 0.0, 0.5, 0.2) == b.tick(0.2, 0.1, 0.0, 0.5, 0.2)


def test_limited_commands_stay_within_the_profile():
    lim = robot_profile("robotarium").limits
    ctrl = FormationController(robot=1, P=5.0, D=1.0, tau1=0.1, tau2=0.1, weights={2: 1.0}, limits=lim)
    ctrl.receive(NeighbourMessage(2, 0.0, 50.0, -30.0, 0.0, 0.0))
    rng = np.random.default_rng(0)
    for _ in range(200):
        v = float(rng.uniform(-lim.speed_cap, lim.speed_cap))
        cmd = ctrl.tick(1.0, *rng.normal(size=2), float(rng.uniform(-math.pi, math.pi)), v)
        assert abs(cmd.turn_rate) <= lim.max_turn_rate * (1 + 1e-12)
        assert abs(cmd.acceleration) <= lim.max_acceleration * (1 + 1e-12)
        assert max(abs(cmd.wheel_left), abs(cmd.wheel_right)) <= lim.max_wheel_speed * (1 + 1e-9)
        assert abs(ctrl.speed_command(cmd, 0.033)) <= lim.max_speed


def test_bad_input_is_a_named_error():
    with pytest.raises(ControllerInputError, match="no neighbour"):
        FormationController(robot=1, P=1.0, D=1.0, tau1=0.1, tau2=0.1, weights={})
    with pytest.raises(ControllerInputError, match="other than 1"):
        FormationController(robot=1, P=1.0, D=1.0, tau1=0.1, tau2=0.1, weights={1: 1.0})
    ctrl = FormationController(robot=1, P=1.0, D=1.0, tau1=0.1, tau2=0.1, weights={2: 1.0})
    with pytest.raises(ControllerInputError, match="no message from its neighbour 2"):
        ctrl.tick(0.0, 0.0, 0.0, 0.0, 0.0)
    with pytest.raises(ControllerInputError, match="not finite"):
        ctrl.receive(NeighbourMessage(2, 0.0, math.nan, 0.0, 0.0, 0.0))
    ctrl.receive(NeighbourMessage(2, 0.0, 1.0, 0.0, 0.0, 0.0))
    with pytest.raises(ControllerInputError, match="finite"):
        ctrl.tick(0.0, math.inf, 0.0, 0.0, 0.0)
    with pytest.raises(InputError):
        FormationController.from_design(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", robot=7)
    with pytest.raises(ValueError):
        FormationController(robot=1, P=-1.0, D=1.0, tau1=0.1, tau2=0.1, weights={2: 1.0})


_finite = st.floats(-20.0, 20.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(x=_finite, y=_finite, theta=st.floats(-7.0, 7.0), v=st.floats(-0.3, 0.3), nx=_finite, ny=_finite,
       nvx=st.floats(-1.0, 1.0), nvy=st.floats(-1.0, 1.0))  # fmt: skip
def test_tick_is_the_saturated_model_at_any_state(x, y, theta, v, nx, ny, nvx, nvy):
    """Every branch (clipping, fading, braking, reversing): the tick equals LimitedUnicycle.rhs for the same u."""
    lim = robot_profile("create3").limits
    ctrl = FormationController(robot=1, P=1.3, D=0.7, tau1=0.0, tau2=0.0, weights={2: 1.0}, forcing=(0.1, -0.2),
                               limits=lim)  # fmt: skip
    ctrl.receive(NeighbourMessage(2, 0.0, nx, ny, nvx, nvy))
    cmd = ctrl.tick(0.0, x, y, theta, v)
    state = np.array([[x, y, theta, v]])
    model = LimitedUnicycle(state[:, :2], state[:, 2], state[:, 3], lim)
    vel = model.velocity(state)
    u = 1.3 * (np.array([[nx, ny]]) - state[:, :2]) + 0.7 * (np.array([[nvx, nvy]]) - vel) + np.array([[0.1, -0.2]])
    _, _, (accel, omega, along, demand, _) = model.rhs(state, u)
    assert cmd.ux == pytest.approx(u[0, 0], rel=1e-12, abs=1e-12)
    assert cmd.turn_rate == pytest.approx(omega[0], rel=1e-9, abs=1e-12)
    assert cmd.acceleration == pytest.approx(accel[0], rel=1e-9, abs=1e-12)
    assert cmd.ideal_turn_rate == pytest.approx(demand[0], rel=1e-9, abs=1e-12)
    assert cmd.ideal_acceleration == pytest.approx(along[0], rel=1e-9, abs=1e-12)
