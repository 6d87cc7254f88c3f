"""Robots with mass: the team stepped by MuJoCo, each robot's controller ticking at its control period.

Each robot is the body of :func:`~delayform.simulation.physics.mjcf.team_mjcf`.
At every tick of its controller (period ``chassis.control_period``, the
wheel commands held in between: zero-order hold) robot i

1. measures its pose (x, y, theta), its Cartesian velocity and its signed
   speed along its heading (the engine's state, as odometry and a motion
   capture system would give it);
2. hears its neighbours' positions sent ``tau1`` earlier and velocities
   sent ``tau2`` earlier, exactly as the kinematic models do (values between
   ticks are interpolated linearly in the recorded ticks; over a
   :class:`~delayform.model.Network` the send times of
   :func:`~delayform.simulation.delayed.reception.reception`);
3. computes the paper's eq. 1 plus the forcing of the paper's eq. 13, and turns it
   into (dv/dt, omega) by the softened feedback linearization of the paper's
   eq. 19 with the robot's limits: the same functions as the saturated
   kinematic unicycle (:meth:`LimitedUnicycle.command` and
   :meth:`LimitedUnicycle.apply`), evaluated on the measured pose and the
   speed set-point;
4. integrates dv/dt over the period into its speed set-point (within the
   speed cap) and sends the wheel speeds of (set-point, omega)
   (:func:`~delayform.simulation.models.robots.wheel_speeds`, clipped to
   ``max_wheel_speed``) to the two wheel servos.

The engine then steps the bodies (steps of at most :data:`~delayform.model.chassis.TIMESTEP`
that divide the period)
until the next tick: servos with finite gain and torque, tyres that slip
when the friction cone is left, bodies that push each other.

With a safety filter (``Robot(safety="barrier")``) step 3 first passes the
Cartesian command through the control barrier functions of
:mod:`delayform.simulation.bodies.safety`, evaluated on the measured positions and
velocities (on-board sensing, no delay), as the kinematic models do. The
filter's guarantee is for ``x'' = u``; the servos execute the command about
``tau_s`` (the identified lag, :mod:`~delayform.simulation.physics.identify`)
late, so two robots braking at ``a_max`` may come up to about
``2 a_max tau_s^2`` closer than its distance (about a millimetre for
the profiles), which its margin absorbs.

With an actuation delay ``tau_a`` (``Robot(actuation_delay=)``) the wheel
targets of step 4 wait in a queue (:class:`CommandQueue`) and reach the
servos ``tau_a`` after the tick that made them; before that the wheels hold
the initial speed without turning (the constant history, as the kinematic
models' zero command). The robot's own lag is still there: the analysis'
actuation delay of the run is ``tau_a`` plus the identified lag.

What it does not model: motor electrical dynamics, gear backlash, wheel
encoders' quantisation, a floor that is not flat, sensing noise other than
the network's.
"""

from __future__ import annotations

import math
import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from delayform._extras import require_extra
from delayform.simulation.delayed.integrator import Progress, Samples
from delayform.model import BarrierFilter, Network, RobotLimits
from delayform.model.chassis import Chassis
from delayform.simulation.physics.mjcf import QPOS_PER_ROBOT, QVEL_PER_ROBOT, team_mjcf
from delayform.simulation.models.robots import LimitedUnicycle, wheel_speeds
from delayform.simulation.bodies.safety import FilteredAgent
from delayform.topology import Topology

__all__ = ["integrate_physics", "tick_grid", "PhysicsTeam", "CommandQueue"]

_Array = NDArray[np.float64]

#: a run stops when a position leaves this many times the initial scale (as the kinematic models)
_BLOWUP = 1e8


def tick_grid(chassis: Chassis) -> tuple[float, int]:
    """The control period and the engine steps per tick (:meth:`Chassis.engine_grid`).

    >>> from delayform.model.chassis import CREATE_CHASSIS
    >>> tick_grid(CREATE_CHASSIS)
    (0.01, 5)
    """
    _, substeps = chassis.engine_grid()
    return chassis.control_period, substeps


class PhysicsTeam:
    """The compiled model of n robots and views of their state (one robot per row).

    Parameters
    ----------
    chassis, limits
        The robots' numbers.
    x0, th0, speed0
        ``(n, 2)`` positions, ``(n,)`` headings and signed speeds at t = 0.
    """

    def __init__(self, chassis: Chassis, limits: RobotLimits, x0: _Array, th0: _Array, speed0: _Array) -> None:
        require_extra("physics")
        import mujoco

        self.mujoco = mujoco
        self.n = x0.shape[0]
        self.limits = limits
        xml = team_mjcf(chassis, limits, np.column_stack([x0, th0]))
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.data = mujoco.MjData(self.model)
        qvel = self.data.qvel.reshape(self.n, QVEL_PER_ROBOT)
        qvel[:, 0] = speed0 * np.cos(th0)
        qvel[:, 1] = speed0 * np.sin(th0)
        qvel[:, 6:8] = (speed0 / limits.wheel_radius)[:, None]
        mujoco.mj_forward(self.model, self.data)
        self._qpos = self.data.qpos.reshape(self.n, QPOS_PER_ROBOT)
        self._qvel = qvel
        self._ctrl = self.data.ctrl.reshape(self.n, 2)

    def measure(self) -> tuple[_Array, _Array, _Array, _Array]:
        """Positions ``(n, 2)``, Cartesian velocities ``(n, 2)``, headings and signed speeds ``(n,)``."""
        q = self._qpos
        w, z = q[:, 3], q[:, 6]
        qx, qy = q[:, 4], q[:, 5]
        theta = np.arctan2(2.0 * (w * z + qx * qy), 1.0 - 2.0 * (qy * qy + z * z))
        vel = self._qvel[:, :2].copy()
        speed = vel[:, 0] * np.cos(theta) + vel[:, 1] * np.sin(theta)
        return q[:, :2].copy(), vel, theta, speed

    def wheel_rates(self) -> _Array:
        """``(n, 2)`` measured left and right wheel speeds (rad/s)."""
        return self._qvel[:, 6:8].copy()

    def command(self, left: _Array, right: _Array) -> None:
        """Set the wheel servos' targets (rad/s), held until the next call."""
        self._ctrl[:, 0] = left
        self._ctrl[:, 1] = right

    def step(self, substeps: int) -> None:
        """Advance the engine ``substeps`` steps."""
        self.mujoco.mj_step(self.model, self.data, nstep=substeps)

    def failed(self) -> bool:
        """Whether the engine found its accelerations not finite (it then resets the state)."""
        return bool(self.data.warning[self.mujoco.mjtWarning.mjWARN_BADQACC].number > 0)


class CommandQueue:
    """Wheel targets on their way to the servos: made at every tick, executed ``delay`` later.

    The target in force at time t is the one made at tick ``floor((t - delay) / period)``
    (the initial targets before the first arrives). The engine steps between
    ticks with piecewise constant targets; where an arrival falls inside an
    engine step (a delay that is not a whole number of engine steps) that step
    takes the time-weighted mean of the two targets, which gives the servo
    force's integral over the step (linear in the target below the torque limit).

    Parameters
    ----------
    delay
        tau_a (s), positive.
    period
        The control period (s).
    substeps
        Engine steps per period.
    initial
        ``(n, 2)`` targets before the first command arrives.
    """

    def __init__(self, delay: float, period: float, substeps: int, initial: _Array) -> None:
        self.lag = delay / period * substeps  # in engine steps
        self.substeps = substeps
        self.initial = np.array(initial, dtype=np.float64)
        self.size = math.ceil(delay / period) + 2
        self.values = np.repeat(self.initial[None], self.size, axis=0)

    def store(self, k: int, targets: _Array) -> None:
        """Keep the targets made at tick k."""
        self.values[k % self.size] = targets

    def _made(self, j: int) -> _Array:
        return self.initial if j < 0 else self.values[j % self.size]

    def segments(self, k: int) -> list[tuple[int, _Array]]:
        """The (engine steps, ``(n, 2)`` targets) runs from tick k to tick k + 1, in order."""
        runs: list[tuple[int, _Array]] = []
        key: tuple[int, float] | None = None
        for e in range(k * self.substeps, (k + 1) * self.substeps):
            start = (e - self.lag) / self.substeps  # in ticks of command time
            j = math.floor(start + 1e-9)
            # the share of the step before the next command arrives (1: none arrives inside)
            old = min(1.0, max(0.0, (j + 1 - start) * self.substeps))
            old = 1.0 if old > 1.0 - 1e-9 else old
            if key == (j, old):
                runs[-1] = (runs[-1][0] + 1, runs[-1][1])
                continue
            key = (j, old)
            targets = self._made(j) if old == 1.0 else old * self._made(j) + (1.0 - old) * self._made(j + 1)
            runs.append((1, targets))
        return runs


def _read(hist: _Array, s: _Array, k: int, who: NDArray[np.intp]) -> _Array:
    """Robot ``who[e]``'s record at fractional tick ``s[e]`` from ``hist[:k+1]`` (linear; constant before 0)."""
    s = np.clip(s, 0.0, float(k))
    lo = np.minimum(np.floor(s + 1e-9).astype(np.intp), k)  # on a tick to rounding: that tick
    hi = np.minimum(lo + 1, k)
    w = np.clip(s - lo, 0.0, 1.0)[:, None]
    return (1.0 - w) * hist[lo, who] + w * hist[hi, who]


class _Hearing:
    """What each robot hears at tick k: ``sum_k C_ik x_k(send)`` for positions and velocities."""

    def __init__(self, topology: Topology, tau1: float, tau2: float, period: float, ticks: int,
                 network: Network | None) -> None:  # fmt: skip
        from delayform.simulation.delayed.reception import reception

        self.period = period
        C = topology.C_sparse.tocoo()
        self.rows, self.cols, self.w = C.row.astype(np.intp), C.col.astype(np.intp), C.data.astype(np.float64)
        n = topology.n
        self.sum = sp.csr_matrix((self.w, (self.rows, np.arange(self.rows.size))), shape=(n, self.rows.size))
        self.rec = None
        self.delays = (tau1, tau2)
        if network is not None:
            self.rec = reception(network, topology, tau1, tau2, dt=period, steps=ticks)

    def heard(self, k: int, pos_hist: _Array, vel_hist: _Array) -> tuple[_Array, _Array]:
        out = []
        for s, hist in enumerate((pos_hist, vel_hist)):
            if self.rec is None:
                when = np.full(self.cols.size, k - self.delays[s] / self.period)
            else:
                when = self.rec.send[s][k, 0] / self.period
            values = _read(hist, when, k, self.cols)  # each informer's record at its send time
            if self.rec is not None and self.rec.noise[s] is not None:
                packet = self.rec.packet[s][k, 0]
                noise = self.rec.noise[s][np.maximum(packet, 0), np.arange(self.cols.size)]
                values = values + np.where((packet >= 0)[:, None], noise, 0.0)
            out.append(self.sum @ values)
        return out[0], out[1]


def integrate_physics(
    topology: Topology,
    F: _Array,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    *,
    chassis: Chassis,
    limits: RobotLimits,
    x0: _Array,
    th0: _Array,
    speed0: _Array,
    duration: float,
    save_every: int,
    network: Network | None = None,
    progress: Progress | None = None,
    safety: BarrierFilter | None = None,
    radius: float = 0.0,
    actuation_delay: float = 0.0,
) -> Samples:
    """Run the team in the engine (module doc) and sample it at every ``save_every``-th tick.

    Parameters
    ----------
    topology
        Who hears whom (C).
    F
        ``(n, 2)`` forcing of the paper's eq. 13.
    P, D, tau1, tau2
        Gains and delays of the paper's eq. 1.
    chassis, limits
        The robots' numbers.
    x0, th0, speed0
        Initial positions, headings and signed speeds (the history before t = 0 is constant).
    duration
        Length of the run (s); the run ends at a whole number of ticks, ``ceil(duration / period)``.
    save_every
        Keep every ``save_every``-th tick (and the last).
    network
        An imperfect network, or None for the constant delays.
    progress
        Optional ``progress(ticks_done, ticks)``, every 500 ticks.
    safety, radius
        A safety filter and the bodies' radius it keeps apart (module doc), or None.
    actuation_delay
        tau_a (s) between a tick and its wheel targets reaching the servos (module doc).

    Returns
    -------
    Samples
        Positions, velocities (measured), the commanded Cartesian
        acceleration, the states ``(x, y, theta, v)`` with the measured
        speed, and the extras of :class:`LimitedUnicycle` (executed and
        demanded dv/dt and omega, where the speed limit held; with a
        filter, where it acted and where a polygon was empty).
    """
    period, substeps = tick_grid(chassis)
    ticks = max(1, math.ceil(duration / period - 1e-9))
    team = PhysicsTeam(chassis, limits, x0, th0, speed0)
    n = team.n
    uni = LimitedUnicycle(x0, th0, speed0, limits)
    guard = None if safety is None else FilteredAgent(uni, safety, radius)
    names = uni.extras if guard is None else guard.extras
    hearing = _Hearing(topology, tau1, tau2, period, ticks, network)
    pos_hist = np.empty((ticks + 1, n, 2))
    vel_hist = np.empty((ticks + 1, n, 2))
    n_saved = ticks // save_every + 1 + (ticks % save_every != 0)
    times = np.empty(n_saved)
    pos, vel, acc = (np.empty((n_saved, n, 2)) for _ in range(3))
    states = np.empty((n_saved, n, 4))
    extras = {name: np.empty((n_saved, n)) for name in names}
    limit = _BLOWUP * (1.0 + float(np.abs(x0).max(initial=0.0)))
    cap, wmax = limits.speed_cap, limits.max_wheel_speed
    v_set = np.array(speed0, dtype=np.float64)
    queue = None
    if actuation_delay > 0.0:
        queue = CommandQueue(actuation_delay, period, substeps, np.column_stack(wheel_speeds(v_set, 0.0 * v_set, limits)))
    saved, stopped = 0, None
    for k in range(ticks + 1):
        if progress is not None and k % 500 == 0:
            progress(k, ticks)
        X, V, theta, speed = team.measure()
        if not (np.abs(X).max() <= limit) or team.failed():  # also catches NaN
            stopped = k * period
            break
        pos_hist[k], vel_hist[k] = X, V
        cx, cv = hearing.heard(k, pos_hist, vel_hist)
        u = P * (cx - X) + D * (cv - V) + F  # the paper's eq. 1 + forcing of the paper's eq. 13
        state = np.column_stack([X, theta, v_set])
        flags: tuple[_Array, ...] = ()
        if guard is not None:  # on the measured state, now (module doc)
            u, active, infeasible = guard.filter(X, V, u)
            flags = (active.astype(float), infeasible.astype(float))
        _, cart, extra = uni.apply(state, uni.command(state, u))  # the paper's eq. 19 under the limits
        extra = tuple(extra) + flags
        if k % save_every == 0 or k == ticks:
            times[saved] = k * period
            pos[saved], vel[saved], acc[saved] = X, V, cart
            states[saved] = np.column_stack([X, theta, speed])
            for name, value in zip(names, extra):
                extras[name][saved] = value
            saved += 1
        if k == ticks:
            break
        accel, omega = extra[0], extra[1]
        v_set = np.clip(v_set + accel * period, -cap, cap)
        left, right = wheel_speeds(v_set, omega, limits)
        left, right = np.clip(left, -wmax, wmax), np.clip(right, -wmax, wmax)
        if queue is None:
            team.command(left, right)
            team.step(substeps)
            continue
        queue.store(k, np.column_stack([left, right]))
        for steps, targets in queue.segments(k):
            team.command(targets[:, 0], targets[:, 1])
            team.step(steps)
    return Samples(times[:saved], pos[:saved], vel[:saved], acc[:saved],
                   {k: v[:saved] for k, v in extras.items()}, states[:saved], stopped)  # fmt: skip


def physics_resources(n: int, ticks: int, substeps: int) -> tuple[float, float]:
    """Estimated bytes and seconds of a run (docs/benchmarks.md: about 12 us per robot and engine step)."""
    nbytes = 8.0 * (ticks + 1) * n * 14 + 40_000.0 * n
    seconds = ticks * (1.5e-4 + substeps * 1.2e-5 * n)
    return nbytes, seconds

