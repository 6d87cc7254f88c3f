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

Per-link and per-message delays
-------------------------------
Each link may have its own pair ``(tau1_ik, tau2_ik)`` (``link_delays``, or
matrices given to :meth:`FormationController.from_design`, row i being what
robot i receives): the buffer then holds each neighbour's messages by its
own link's delays. A message may also carry its own pair (``delays`` of
:meth:`FormationController.receive`: the link's delay plus the packet's
jitter, as the simulator's network draws them): it becomes usable at
``stamp + d`` and the controller uses the newest message usable, the
simulator's hold-last-value of packet streams
(:mod:`delayform.simulation.delayed.reception`); an older message that becomes
usable after a newer one is never used again. With every link at
(tau1, tau2) and no per-message delay the arithmetic is that of one pair,
operation for operation.

This is the same arithmetic, operation for operation, as the simulation's
vectorized models, written for one robot in plain floats so that a tick
costs microseconds; ``tests/test_deploy_controller.py`` replays simulated
runs through it and finds the simulation's commands to 1e-9.
"""

from __future__ import annotations

import math
from bisect import bisect_right, insort
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from delayform._validation import check_delay, check_delay_array, check_gains, validated
from delayform.deploy.profiles import RobotProfile
from delayform.errors import ControllerInputError
from delayform.model.limits import IROBOT_CREATE, RobotLimits
from delayform.model.robot import REST_SPEED

if TYPE_CHECKING:  # pragma: no cover - typing only
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
    """One neighbour's messages, sorted by stamp (plain lists: bisect on floats is fast).

    ``tau1``, ``tau2`` are the link's delays. ``d1``, ``d2`` hold each
    message's own delays once a message has brought its own (None until
    then: the link's delays hold for every message, the one-pair path);
    ``low1``, ``low2`` are the shortest of them, where the search for the
    newest usable message starts.
    """

    __slots__ = ("stamps", "x", "y", "vx", "vy", "tau1", "tau2", "d1", "d2", "low1", "low2")

    def __init__(self, tau1: float, tau2: float) -> None:
        self.stamps: list[float] = []
        self.x: list[float] = []
        self.y: list[float] = []
        self.vx: list[float] = []
        self.vy: list[float] = []
        self.tau1, self.tau2 = tau1, tau2
        self.d1: list[float] | None = None
        self.d2: list[float] | None = None
        self.low1, self.low2 = tau1, tau2

    def add(self, m: NeighbourMessage, d1: float, d2: float) -> None:
        stamps = self.stamps
        if not stamps or m.stamp > stamps[-1]:
            k = len(stamps)
        else:
            k = bisect_right(stamps, m.stamp)
            if k and stamps[k - 1] == m.stamp:  # a repeated stamp replaces the message
                self.x[k - 1], self.y[k - 1], self.vx[k - 1], self.vy[k - 1] = m.x, m.y, m.vx, m.vy
                if self.d1 is not None and self.d2 is not None:
                    self.d1[k - 1], self.d2[k - 1] = d1, d2
                    self.low1, self.low2 = min(self.low1, d1), min(self.low2, d2)
                return
        if self.d1 is None and (d1 != self.tau1 or d2 != self.tau2):  # the first message with its own delays
            self.d1, self.d2 = [self.tau1] * len(stamps), [self.tau2] * len(stamps)
        stamps.insert(k, m.stamp)
        self.x.insert(k, m.x)
        self.y.insert(k, m.y)
        self.vx.insert(k, m.vx)
        self.vy.insert(k, m.vy)
        if self.d1 is not None and self.d2 is not None:
            self.d1.insert(k, d1)
            self.d2.insert(k, d2)
            self.low1, self.low2 = min(self.low1, d1), min(self.low2, d2)

    def newest(self, t: float, delays: list[float], low: float) -> int:
        """Index of the newest message usable at ``t`` (``stamp + d <= t``), or -1 (per-message delays)."""
        stamps = self.stamps
        j = bisect_right(stamps, t - low + STAMP_TOLERANCE) - 1  # none later can be usable
        while j >= 0 and stamps[j] + delays[j] > t + STAMP_TOLERANCE:
            j -= 1
        return j

    def prune(self, keep_from: int) -> None:
        lists = [self.stamps, self.x, self.y, self.vx, self.vy]
        if self.d1 is not None and self.d2 is not None:
            lists += [self.d1, self.d2]
        for lst in lists:
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
        The design's delays (s) on positions and velocities: every link's,
        unless ``link_delays`` says otherwise.
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
    link_delays
        Neighbour number -> ``(tau1_ik, tau2_ik)``, the delays of that link
        (module doc, Per-link and per-message delays); links not named keep
        ``(tau1, tau2)``.

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
        link_delays: Mapping[int, tuple[float, float]] | None = None,
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
        pairs = {k: (self.tau1, self.tau2) for k in clean}
        for k, pair in dict(link_delays or {}).items():
            if k not in pairs:
                raise ControllerInputError(f"link_delays names robot {k!r}, which robot {self.robot} does not hear "
                                           f"(its neighbours: {sorted(clean)})")  # fmt: skip
            try:
                d1, d2 = pair
            except (TypeError, ValueError):
                raise ControllerInputError(f"the delays of link {self.robot} <- {k} must be a pair (tau1, tau2), got {pair!r}") from None
            pairs[k] = (check_delay(f"tau1 of link {self.robot} <- {k}", d1), check_delay(f"tau2 of link {self.robot} <- {k}", d2))
        self.link_delays = pairs
        self._inbox = {k: _Inbox(*pairs[k]) for k in clean}
        self._order = tuple(clean.items())

    @classmethod
    def from_design(
        cls,
        topology: Topology,
        P: float,
        D: float,
        tau1: float | ArrayLike,
        tau2: float | ArrayLike,
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
        P, D
            The gains.
        tau1, tau2
            The design's delays: two numbers (every link), or two ``(n, n)``
            matrices whose row ``robot - 1`` gives this robot's links (entry
            ``[i, k]``: what i receives from k, as :class:`delayform.model.Delays`).
            With matrices, the controller's own ``tau1``, ``tau2`` are the
            largest of its links' delays.
        formation
            ``(n, 2)`` desired positions or a shape name.
        robot
            This robot's number, from 1.
        limits, rest_speed
            As for the constructor.
        """
        # here, not at the top: a robot's process builds its controller from weights alone and
        # starts without the team's sparse algebra (SciPy), a third of a second per process
        from delayform.formation import check_formation, formation_forcing
        from delayform.topology import Topology

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
        if np.ndim(tau1) == 0 and np.ndim(tau2) == 0:
            return cls(robot=int(robot), P=P, D=D, tau1=tau1, tau2=tau2, weights=weights,  # type: ignore[arg-type]
                       forcing=F, limits=limits, rest_speed=rest_speed)  # fmt: skip
        rows = []
        for name, value in (("tau1", tau1), ("tau2", tau2)):
            matrix = check_delay_array(name, value)
            if matrix.shape != (n, n):
                raise ControllerInputError(f"{name} must be a number or an {n} x {n} matrix (one entry per link), "
                                           f"got shape {matrix.shape}")  # fmt: skip
            rows.append(matrix[robot - 1])
        pairs = {k: (float(rows[0][k - 1]), float(rows[1][k - 1])) for k in weights}
        return cls(robot=int(robot), P=P, D=D, tau1=max(p[0] for p in pairs.values()),
                   tau2=max(p[1] for p in pairs.values()), weights=weights, forcing=F, limits=limits,
                   rest_speed=rest_speed, link_delays=pairs)  # fmt: skip

    @property
    def neighbours(self) -> tuple[int, ...]:
        """The robots this one hears, numbered from 1."""
        return tuple(self.weights)

    # ------------------------------------------------------------ messages
    def receive(self, message: NeighbourMessage, delays: tuple[float, float] | None = None) -> None:
        """Keep a neighbour's message (any order; a repeated stamp replaces the earlier message).

        Parameters
        ----------
        message
            A :class:`NeighbourMessage`; messages of robots this one does
            not hear are ignored (a broadcast reaches everybody).
        delays
            This message's own delays ``(d1, d2)`` (s) for its position and
            its velocity: usable from ``stamp + d`` on (module doc, Per-link
            and per-message delays); infinity for a part the network lost
            (never used). None: the link's.

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
        if delays is None:
            inbox.add(message, inbox.tau1, inbox.tau2)
            return
        try:
            d1, d2 = delays
            ok = bool(d1 >= 0.0 and d2 >= 0.0)  # NaN fails; infinity is a stream the network lost
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ControllerInputError(f"the delays of a message must be two non-negative numbers, got {delays!r}")
        inbox.add(message, float(d1), float(d2))

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
        # sum_k C_ik x_k(t - tau1_ik) and sum_k C_ik xdot_k(t - tau2_ik), from the playout buffer
        sx = sy = svx = svy = 0.0
        lag = 0.0
        for k, w in self._order:
            box = self._inbox[k]
            stamps = box.stamps
            if not stamps:
                raise ControllerInputError(f"robot {self.robot} has no message from its neighbour {k} yet")
            due1, due2, i1, i2 = self._pick(box, t)
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

    @staticmethod
    def _pick(box: _Inbox, t: float) -> tuple[float, float, int, int]:
        """``t - tau_ik`` (plus the tolerance) of both streams and the indices of the messages used at ``t``."""
        due1 = t - box.tau1 + STAMP_TOLERANCE
        due2 = t - box.tau2 + STAMP_TOLERANCE
        if box.d1 is None or box.d2 is None:  # one pair per link: the newest sent at or before t - tau
            i1 = bisect_right(box.stamps, due1) - 1
            i2 = bisect_right(box.stamps, due2) - 1
        else:  # per-message delays: the newest usable (stamp + d <= t)
            i1 = box.newest(t, box.d1, box.low1)
            i2 = box.newest(t, box.d2, box.low2)
        # before the first usable message: the oldest, as the constant history before t = 0
        return due1, due2, (i1 if i1 > 0 else 0), (i2 if i2 > 0 else 0)

    def heard(self, t: float) -> dict[int, tuple[float, float]]:
        """Neighbour -> the stamps of the messages a tick at ``t`` uses for its position and its velocity.

        Parameters
        ----------
        t
            The tick's time (s).

        Raises
        ------
        ControllerInputError
            For a neighbour not heard from yet.
        """
        out = {}
        for k, box in self._inbox.items():
            if not box.stamps:
                raise ControllerInputError(f"robot {self.robot} has no message from its neighbour {k} yet")
            _, _, i1, i2 = self._pick(box, float(t))
            out[k] = (box.stamps[i1], box.stamps[i2])
        return out

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
        demand = float(lim._turn_demand(v, along, across, ux * ux + uy * uy))  # a float: numpy scalars would spread
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
