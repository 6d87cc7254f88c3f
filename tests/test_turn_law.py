"""The softened turn law of the paper's eq. 19 at rest: no resting point with the input across the heading.

The earlier law turned a robot at rest in proportion to ``(e_perp . u)(e . u)``
and accelerated it by ``e . u``: with u exactly across its heading it neither
turned nor drove, and the Create 3 example stopped 1.9 cm from its shape.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from delayform.deploy import FormationController, NeighbourMessage, robot_profile
from delayform.model import Delays, Start, Team
from delayform.model.limits import FORWARD_BIAS
from delayform.simulation import simulate
from delayform.simulation.models.robots import LimitedUnicycle, Robot
from delayform.topology import complete

LIMITS = robot_profile("create3").limits


def test_at_rest_with_u_across_the_robot_turns_towards_u_s_forward_direction() -> None:
    """Closed form at v = 0, e . u = 0: omega = b (e_perp . u) / v_s, towards u, for u to either side."""
    ux = 0.0
    for uy in (0.03, -0.03):
        state = np.array([[0.0, 0.0, 0.0, 0.0]])  # at rest, heading along +x
        model = LimitedUnicycle(state[:, :2], state[:, 2], state[:, 3], LIMITS)
        along, demand = model.command(state, np.array([[ux, uy]]))[0]
        vs = math.sqrt(LIMITS.slow_speed**2 + (LIMITS.turn_time_constant * abs(uy)) ** 2)
        assert along == 0.0
        assert demand == pytest.approx(FORWARD_BIAS * uy / vs, rel=1e-12)
        assert np.sign(demand) == np.sign(uy)  # towards u
        # the deployed controller computes the same
        ctrl = FormationController(robot=1, P=1.0, D=1.0, tau1=0.0, tau2=0.0, weights={2: 1.0}, limits=LIMITS)
        ctrl.receive(NeighbourMessage(2, 0.0, ux, uy, 0.0, 0.0))
        cmd = ctrl.tick(0.0, 0.0, 0.0, 0.0, 0.0)
        assert cmd.ideal_turn_rate == demand
        # plain floats: a numpy scalar fed back as the next speed broke the robots' processes
        assert all(type(x) is float for x in (cmd.turn_rate, cmd.acceleration, cmd.ideal_turn_rate))


def test_far_from_rest_the_law_is_the_paper_s_eq_19() -> None:
    """For |v| >> v_s the turn demand is e_perp . u / v (relative error of order v_s / v)."""
    v = np.array([0.3, -0.3, 0.1])
    th = np.array([0.4, 2.0, -1.0])
    u = np.array([[0.2, -0.1], [0.05, 0.3], [-0.2, -0.2]])
    state = np.column_stack([np.zeros((3, 2)), th, v])
    model = LimitedUnicycle(state[:, :2], th, v, LIMITS)
    across = np.cos(th) * u[:, 1] - np.sin(th) * u[:, 0]
    demand = model.command(state, u)[:, 1]
    vs = np.sqrt(LIMITS.slow_speed**2 + (LIMITS.turn_time_constant * np.hypot(u[:, 0], u[:, 1])) ** 2)
    assert np.all(np.abs(demand - across / v) <= 2.5 * vs / np.abs(v) * np.abs(across / v))


def test_two_robots_at_rest_with_their_inputs_exactly_across_their_headings_converge() -> None:
    """Both robots face +x, 5 cm off their slots in y, at rest: u is exactly across both headings.

    The earlier law left them there for ever (turn and acceleration both exactly
    0); with the forward bias they turn, drive and reach the shape.
    """
    desired = np.array([[0.0, 0.0], [1.0, 0.0]])
    start = Start(np.array([[0.0, 0.05], [1.0, -0.05]]), np.array([0.0, 0.0]), speed=0.0)
    run = simulate(Team(complete(2), 1.0, 1.5), Delays(0.3, 0.2), desired, robot=Robot(model="unicycle", limits=LIMITS),
                   start=start, duration=40.0, dt=0.01)  # fmt: skip
    e = run.formation_error
    assert e[0] == pytest.approx(0.05)
    c = run.commands
    assert np.all(c.ideal_acceleration[0] == 0.0)  # the input is exactly across at the start
    assert np.all(np.abs(c.turn_rate[0]) > 1.0)  # ... and the robots turn at once
    assert e[-1] < 1e-3 * e[0]


# the example's error far below the earlier floor, and its linear phase: tests/test_fleet_decay.py
