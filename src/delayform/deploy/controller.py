"""The controller as it runs on one robot: the paper's eq. 1, the formation forcing, the paper's eq. 19 and the limits.

At each control tick robot i knows its own pose and speed and the
timestamped messages its neighbours sent (position and Cartesian velocity,
each stamped with the sender's clock). It computes (paper, eq. 1 plus the
forcing of the paper's eq. 13, per coordinate)::

    u_i(t) = P (sum_k C_ik x_k(t - tau1) - x_i(t)) + D (sum_k C_ik xdot_k(t - tau2) - xdot_i(t)) + F_i

and turns u into the unicycle's inputs by the paper's eq. 19, ``dv/dt = e . u``
and ``omega = e_perp . u / v`` with ``e = (cos theta, sin theta)``: for a
robot with limits, softened, clipped and braked exactly as the simulated
saturated unicycle (:class:`delayform.simulation.models.robots.LimitedUnicycle`);
for an ideal robot, the plain transform, holding the heading at rest
(:func:`delayform.simulation.models.robots.ideal_commands`). Wheel speeds follow
from the differential drive's geometry.

Which message is used
---------------------
The design promises the delays (tau1, tau2). A network that is faster than
that is made exactly that slow: the controller keeps each neighbour's
messages and uses, for positions, the newest one sent at or before
``t - tau1`` and, for velocities, the newest one sent at or before
``t - tau2`` (a playout buffer). Before the first such message it uses the
oldest message it has, as the simulation uses the constant initial
history before ``t = 0``. A network slower than the design cannot be made
faster: the newest message is then older than promised. Either way
:attr:`Command.lag` says how much older than ``t - tau`` the oldest value
used was (0 when the design's delays hold exactly; up to one message
period when the delays are not multiples of it).
This assumes the robots' clocks agree (NTP or PTP on a real team); the
stamps are the sender's.

This is the same arithmetic, operation for operation, as the simulation's
vectorized models, written for one robot in plain floats so that a tick
costs microseconds; ``tests/test_deploy_controller.py`` replays simulated
runs through it and finds the simulation's commands to 1e-9.
"""

from __future__ import annotations

import math
from bisect import bisect_right, insort
from collections.abc import Iterable, Mapping
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from delayform._validation import check_delay, check_gains, validated
from delayform.deploy.profiles import RobotProfile
from delayform.errors import ControllerInputError
from delayform.formation import check_formation, formation_forcing
from delayform.simulation.models.robots import IROBOT_CREATE, REST_SPEED, RobotLimits
from delayform.topology import Topology

__all__ = ["FormationController", "NeighbourMessage", "Command"]

#: a message stamped up to this long (s) after ``t - tau`` still counts as sent at ``t - tau``
#: (the stamps and the tick times are sums of rounded periods)
STAMP_TOLERANCE = 1e-9

#: how far from 1 the sum of a robot's weights may be (a row of C, rounded)
_WEIGHT_SUM_TOL = 1e-9

#: a neighbour's inbox is pruned when this many messages older than the ones in use pile up
_PRUNE = 256


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)


class NeighbourMessage(NamedTuple):
    """What a neighbour sends: who, when (its clock, s), its position (m) and Cartesian velocity (m/s)."""

    sender: int
    stamp: float
    x: float
    y: float
    vx: float
    vy: float


class Command(NamedTuple):
    """The commands of one tick (units: m/s, rad/s, m/s^2).

    ``speed`` is the robot's signed speed v the tick was computed at;
    ``turn_rate`` and ``acceleration`` are what the robot executes (after
    the limits); ``ideal_turn_rate`` and ``ideal_acceleration`` what the paper's
    eq. 19 asks before them; ``u`` the Cartesian acceleration of the paper's
    eq. 1; ``lag`` how much older (s) than the design's delays the
    newest usable message of the slowest neighbour was (0 when they hold).
    """

    time: float
    speed: float
    turn_rate: float
    acceleration: float
    wheel_left: float
    wheel_right: float
    ideal_turn_rate: float
    ideal_acceleration: float
    ux: float
    uy: float
    lag: float


class _Inbox:
    """One neighbour's messages, sorted by stamp (plain lists: bisect on floats is fast)."""

    __slots__ = ("stamps", "x", "y", "vx", "vy")

    def __init__(self) -> None:
        self.stamps: list[float] = []
        self.x: list[float] = []
        self.y: list[float] = []
        self.vx: list[float] = []
        self.vy: list[float] = []

    def add(self, m: NeighbourMessage) -> None:
        stamps = self.stamps
        if not stamps or m.stamp > stamps[-1]:
            k = len(stamps)
        else:
            k = bisect_right(stamps, m.stamp)
            if k and stamps[k - 1] == m.stamp:  # a repeated stamp replaces the message
                self.x[k - 1], self.y[k - 1], self.vx[k - 1], self.vy[k - 1] = m.x, m.y, m.vx, m.vy
                return
        stamps.insert(k, m.stamp)
        self.x.insert(k, m.x)
        self.y.insert(k, m.y)
        self.vx.insert(k, m.vx)
        self.vy.insert(k, m.vy)

    def prune(self, keep_from: int) -> None:
        for lst in (self.stamps, self.x, self.y, self.vx, self.vy):
            del lst[:keep_from]


# methods=False: tick and receive run on the robot every period (a 50 us budget, docs/benchmarks.md)
# and check their own values; the layer checks the construction, done once
@validated(ControllerInputError, methods=False)
class FormationController:
    """One robot's formation controller: neighbour messages and own state in, (v, omega) and wheel speeds out.

    Parameters
    ----------
    robot
        This robot's number, counted from 1.
    P, D
        Gains of the paper's eq. 1.
    tau1, tau2
        The design's delays (s) on positions and velocities.
    weights
        Neighbour number (from 1) -> ``C_ik``, the row of ``C = Delta^-1 A``
        that robot i receives (non-zero entries only). They must sum to 1
        (to 1e-9): other weights are not the designed protocol, and no
        stability certificate covers them, so they are refused, not rescaled.
    forcing
        ``F_i`` of the paper's eq. 13, ``P (z_i - sum_k C_ik z_k)`` (m/s^2).
    limits
        Actuator limits (a :class:`RobotLimits` or a profile): the
        saturated model. None: an ideal robot, whose wheel speeds use the
        geometry of :data:`IROBOT_CREATE` (as the simulation reports them).
    rest_speed
        Ideal robots whose speed and |u| are both below this hold their heading.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> ctrl = FormationController.from_design(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", robot=1)
    >>> for k in ctrl.neighbours:
    ...     ctrl.receive(NeighbourMessage(k, 0.0, float(k), 0.0, 0.0, 0.0))
    >>> cmd = ctrl.tick(0.0, 0.0, 0.0, 0.0, 0.1)
    >>> round(cmd.speed, 3), cmd.lag
    (0.1, 0.0)
    """

    def __init__(
        self,
        *,
        robot: int,
        P: float,
        D: float,
        tau1: float,
        tau2: float,
        weights: Mapping[int, float],
        forcing: ArrayLike = (0.0, 0.0),
        limits: RobotLimits | RobotProfile | None = None,
        rest_speed: float = REST_SPEED,
    ) -> None:
        if isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or robot < 1:
            raise ControllerInputError(f"robot must be a number from 1, got {robot!r}")
        self.robot = int(robot)
        self.P, self.D = check_gains(P, D)
        self.tau1, self.tau2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
        if isinstance(limits, RobotProfile):
            limits = limits.limits
        if limits is not None and not isinstance(limits, RobotLimits):
            raise ControllerInputError(f"limits must be RobotLimits, a RobotProfile or None, got {type(limits).__name__}")
        self.limits = limits
        self.geometry = IROBOT_CREATE if limits is None else limits
        if not (isinstance(rest_speed, (int, float)) and math.isfinite(rest_speed) and rest_speed > 0):
            raise ControllerInputError(f"rest_speed must be finite and positive, got {rest_speed!r}")
        self.rest_speed = float(rest_speed)
        clean: dict[int, float] = {}
        for k, w in dict(weights).items():
            if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1 or k == self.robot:
                raise ControllerInputError(f"weights are keyed by neighbour numbers from 1 other than {self.robot}, got {k!r}")
            if not _is_number(w) or not (math.isfinite(w) and w > 0):
                raise ControllerInputError(f"weight of neighbour {k} must be a finite positive number, got {w!r}")
            clean[int(k)] = float(w)
        if not clean:
            raise ControllerInputError(f"robot {self.robot} hears no neighbour: the protocol needs at least one")
        total = math.fsum(clean.values())
        if abs(total - 1.0) > _WEIGHT_SUM_TOL:
            # a row of C = Delta^-1 A sums to 1; other weights are another protocol, which no certificate covers
            raise ControllerInputError(
                f"the weights of robot {self.robot} must sum to 1 (a row of C = Delta^-1 A, the paper's eq. 1), "
                f"got {total:.6g}; divide each by {total:.6g} for the designed protocol")  # fmt: skip
        self.weights = clean
        F = np.asarray(forcing, dtype=np.float64)
        if F.shape != (2,) or not np.all(np.isfinite(F)):
            raise ControllerInputError(f"forcing must be two finite numbers, got {forcing!r}")
        self.forcing = (float(F[0]), float(F[1]))
        self._inbox = {k: _Inbox() for k in clean}
        self._order = tuple(clean.items())

    @classmethod
    def from_design(
        cls,
        topology: Topology,
        P: float,
        D: float,
        tau1: float,
        tau2: float,
        formation: ArrayLike | str,
        *,
        robot: int,
        limits: RobotLimits | RobotProfile | None = None,
        rest_speed: float = REST_SPEED,
    ) -> FormationController:
        """Robot ``robot``'s controller for a designed team (the arguments of :func:`delayform.simulate`).

        Parameters
        ----------
        topology
            The communication topology; row ``robot - 1`` of C is what this robot hears.
        P, D, tau1, tau2
            The design.
        formation
            ``(n, 2)`` desired positions or a shape name.
        robot
            This robot's number, from 1.
        limits, rest_speed
            As for the constructor.
        """
        if not isinstance(topology, Topology):
            raise ControllerInputError(f"topology must be a Topology, got {type(topology).__name__}")
        n = topology.n
        if isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or not 1 <= robot <= n:
            raise ControllerInputError(f"robot must be a number from 1 to {n}, got {robot!r}")
        P, D = check_gains(P, D)
        desired = check_formation(formation, n)
        F = formation_forcing(topology, P, desired)[robot - 1]
        C = topology.C_sparse.tocsr()
        lo, hi = C.indptr[robot - 1], C.indptr[robot]
        weights = {int(j) + 1: float(w) for j, w in zip(C.indices[lo:hi], C.data[lo:hi]) if w != 0.0 and j != robot - 1}
        return cls(robot=int(robot), P=P, D=D, tau1=tau1, tau2=tau2, weights=weights, forcing=F,
                   limits=limits, rest_speed=rest_speed)  # fmt: skip

    @property
    def neighbours(self) -> tuple[int, ...]:
        """The robots this one hears, numbered from 1."""
        return tuple(self.weights)

    # ------------------------------------------------------------ messages
    def receive(self, message: NeighbourMessage) -> None:
        """Keep a neighbour's message (any order; a repeated stamp replaces the earlier message).

        Parameters
        ----------
        message
            A :class:`NeighbourMessage`; messages of robots this one does
            not hear are ignored (a broadcast reaches everybody).

        Raises
        ------
        ControllerInputError
            For a stamp or value that is not a finite number.
        """
        # a try costs nothing on the way through (Python 3.11): NeighbourMessage is a plain
        # NamedTuple, not checked on construction, so a wrong field surfaces here as one of ours
        try:
            inbox = self._inbox.get(message.sender)
            if inbox is None:  # a robot this one does not hear; but a sender that is no number is a bug
                if isinstance(message.sender, bool) or not isinstance(message.sender, (int, np.integer)):
                    raise TypeError(message.sender)
                return
            finite = all(map(math.isfinite, message[1:]))
        except (AttributeError, TypeError, IndexError) as exc:
            raise ControllerInputError(f"message must be a NeighbourMessage of numbers, got {message!r}"[:200]) from exc
        if not finite:
            raise ControllerInputError(f"message of robot {message.sender} has a value that is not finite: {message}")
        inbox.add(message)

    def receive_all(self, messages: Iterable[NeighbourMessage]) -> None:
        """:meth:`receive` each message."""
        try:
            it = iter(messages)
        except TypeError:
            raise ControllerInputError(f"messages must be an iterable of NeighbourMessage, got {type(messages).__name__}") from None
        for m in it:
            self.receive(m)

    # ------------------------------------------------------------ the tick
    def tick(self, t: float, x: float, y: float, theta: float, v: float) -> Command:
        """The commands at time t from the robot's own state and the messages received so far.

        Parameters
        ----------
        t
            Now (s), on the clock the neighbours stamp with.
        x, y, theta
            The robot's pose (m, m, rad).
        v
            Its signed speed (m/s), e.g. from odometry.

        Returns
        -------
        Command

        Raises
        ------
        ControllerInputError
            For a state that is not finite, or a neighbour not heard from yet.
        """
        try:  # free when it does not raise: the tick's budget is 50 us
            finite = math.isfinite(t) and math.isfinite(x) and math.isfinite(y) and math.isfinite(theta) and math.isfinite(v)
        except TypeError as exc:
            raise ControllerInputError(f"the state must be real numbers: t={t!r}, x={x!r}, y={y!r}, theta={theta!r}, v={v!r}") from exc
        if not finite:
            raise ControllerInputError(f"the state at t = {t!r} must be finite: x={x!r}, y={y!r}, theta={theta!r}, v={v!r}")
        c, s = math.cos(theta), math.sin(theta)
        # sum_k C_ik x_k(t - tau1) and sum_k C_ik xdot_k(t - tau2), from the playout buffer
        due1 = t - self.tau1 + STAMP_TOLERANCE
        due2 = t - self.tau2 + STAMP_TOLERANCE
        sx = sy = svx = svy = 0.0
        lag = 0.0
        for k, w in self._order:
            box = self._inbox[k]
            stamps = box.stamps
            if not stamps:
                raise ControllerInputError(f"robot {self.robot} has no message from its neighbour {k} yet")
            i1 = bisect_right(stamps, due1) - 1
            i2 = bisect_right(stamps, due2) - 1
            if i1 < 0:
                i1 = 0
            if i2 < 0:
                i2 = 0
            sx += w * box.x[i1]
            sy += w * box.y[i1]
            svx += w * box.vx[i2]
            svy += w * box.vy[i2]
            late = max(due1 - stamps[i1], due2 - stamps[i2])  # still includes the tolerance
            if late > lag:
                lag = late
            first = i1 if i1 < i2 else i2
            if first > _PRUNE:
                box.prune(first)
        vx, vy = v * c, v * s
        P, D = self.P, self.D
        ux = P * (sx - x) + D * (svx - vx) + self.forcing[0]  # the paper's eq. 1 + forcing of the paper's eq. 13
        uy = P * (sy - y) + D * (svy - vy) + self.forcing[1]
        if self.limits is None:
            turn, accel, ideal_turn, ideal_accel = self._ideal(c, s, v, ux, uy)
        else:
            turn, accel, ideal_turn, ideal_accel = self._limited(c, s, v, ux, uy)
        geo = self.geometry
        half = 0.5 * geo.axle_length * turn
        left, right = (v - half) / geo.wheel_radius, (v + half) / geo.wheel_radius
        # never a non-finite command: the ideal model divides by the speed, and huge states overflow
        if not (math.isfinite(left) and math.isfinite(right) and math.isfinite(accel) and math.isfinite(ideal_turn)):
            raise ControllerInputError(
                f"robot {self.robot} at t = {t!r}: the command is not finite (u = ({ux:.3g}, {uy:.3g}) m/s^2, "
                f"speed {v:.3g} m/s, turn rate {ideal_turn:.3g} rad/s); "
                + ("the ideal model turns at (u across) / speed: give the robot limits"
                   if self.limits is None and math.isfinite(ux) and math.isfinite(uy)
                   else "the state or the neighbours' messages are too large"))  # fmt: skip
        return Command(t, v, turn, accel, left, right,
                       ideal_turn, ideal_accel, ux, uy, lag - STAMP_TOLERANCE if lag > 2 * STAMP_TOLERANCE else 0.0)  # fmt: skip

    def _ideal(self, c: float, s: float, v: float, ux: float, uy: float) -> tuple[float, float, float, float]:
        """The paper's eq. 19 without limits; the heading is held at rest (as ``ideal_commands``)."""
        along = ux * c + uy * s
        across = c * uy - s * ux
        rest = self.rest_speed
        if (abs(v) < rest and math.hypot(ux, uy) < rest) or v == 0.0:
            turn = 0.0
        else:
            turn = across / v
        return turn, along, turn, along

    def _limited(self, c: float, s: float, v: float, ux: float, uy: float) -> tuple[float, float, float, float]:
        """The paper's eq. 19 softened, clipped and braked: ``LimitedUnicycle.rhs`` for one robot."""
        lim = self.limits
        assert lim is not None
        along = c * ux + s * uy
        across = c * uy - s * ux
        speed = abs(v)
        amax = lim.max_acceleration
        accel = min(max(along, -amax), amax)
        if accel * v > 0.0:
            accel = accel * max(1.0 - (speed / lim.speed_cap) ** 8, 0.0)
        size2 = ux * ux + uy * uy
        vs = math.sqrt(lim.slow_speed**2 + lim.turn_time_constant**2 * size2)
        toward = along / math.sqrt(size2 + 1e-24)
        demand = across * (v + toward * vs) / (v * v + vs * vs)
        wmax = lim.max_turn_rate
        wanted = min(max(demand, -wmax), wmax)
        rim = lim.wheel_radius * lim.max_wheel_speed
        allowed = max(rim - 0.5 * lim.axle_length * abs(wanted), 0.0)
        brake = min(max((speed - allowed) / (0.1 * amax), 0.0), 1.0)
        sign = (v > 0.0) - (v < 0.0)
        accel = (1.0 - brake) * accel - brake * sign * amax
        cap = min(max(2.0 * (rim - speed) / lim.axle_length, 0.0), wmax)
        turn = min(max(wanted, -cap), cap)
        return turn, accel, demand, along

    def speed_command(self, command: Command, period: float) -> float:
        """The speed to send (e.g. as ``Twist.linear.x``) for a robot that takes speed set-points.

        A velocity-controlled robot (Create 3, TurtleBot3, GRITSbot) takes
        (v, omega), not dv/dt: the set-point for the next period is
        ``v + (dv/dt) period``, within the speed cap.

        Parameters
        ----------
        command
            The tick's command.
        period
            The control period (s).
        """
        if not (_is_number(period) and math.isfinite(period) and period > 0):
            raise ControllerInputError(f"period must be finite and positive, got {period!r}")
        target = command.speed + command.acceleration * period
        if self.limits is None:
            return target
        cap = self.limits.speed_cap
        return min(max(target, -cap), cap)
