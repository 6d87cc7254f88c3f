"""Simulation of the formation protocol with two constant delays (eq. protocol, eq. formation).

Agent i applies (per coordinate, eq. protocol plus the forcing of eq. formation)::

    u_i(t) = P (sum_k C_ik x_k(t - tau1) - x_i(t)) + D (sum_k C_ik xdot_k(t - tau2) - xdot_i(t)) + F_i

with ``F = P (I - C) z_desired`` (:func:`delayform.formation.formation_forcing`).

Agent models
------------
``double_integrator``
    ``x'' = u`` (Section "Consensus Protocol"); state x, y, xdot, ydot.
``unicycle``
    Differential-drive robot with the dynamic extension of Section "Feedback
    Linearization": state x, y, theta, v with ``x' = v cos(theta)``,
    ``y' = v sin(theta)`` (eq. kinem:uni) and inputs ``dv/dt`` and ``omega``
    from eq. transform2::

        dv/dt = cos(theta) u_1 + sin(theta) u_2
        omega = (-sin(theta) u_1 + cos(theta) u_2) / v

    so that the robot's position obeys ``x'' = u`` exactly while v != 0.

History
-------
The state is constant before ``t = 0``: positions ``x0`` and Cartesian
velocities ``v0 = initial_speed (cos theta0, sin theta0)`` (the state ``z`` of
eq. protocolss is constant, velocities included). Agents send positions and
Cartesian velocities; headings are private.

Integration method
------------------
Classical fixed-step Runge-Kutta (RK4) for the current state; the delayed
terms ``C x(t - tau1)`` and ``C xdot(t - tau2)`` are read from the computed
solution by cubic Hermite interpolation between grid points, using the
derivatives the solution carries (``(C x)' = C xdot``, ``(C xdot)' = C u``).
Both are fourth order, so the method is fourth order when the points where
the solution loses smoothness fall on grid points. The constant history makes
``x'`` jump at ``t = 0`` (the position history is at rest, the state then moves with ``v0``)
and ``xdot'`` jump at ``t = 0``; the delays carry these to kinks of the
protocol input u at ``t = tau1`` and ``t = tau2``. **Stated order: 4 when tau1
and tau2 are each 0 or an integer multiple of dt, 2 otherwise** (a kink of u
inside a step costs two orders; the observed error then also depends on
where the kinks fall within their steps, so it decreases unevenly).
Because the delays are constant, every stage
reads its delayed values at the same offset from the current step, so the
interpolation weights are computed once. Only ``C x``, ``C xdot`` and ``C u``
of the last ``max(tau1, tau2) / dt + 3`` steps are kept, and C is applied three
times per step, so time and memory grow linearly with the number of agents
and of edges. Non-zero delays must be at least ``dt`` (then every value a
stage reads is already computed); a zero delay uses the current stage value.
For double integrators in teams of up to 64 agents the same step, being
linear, is precomputed as one matrix applied to the state and the few
history values it reads (``_integrate_linear``): same results up to
rounding, without the Python overhead of the stage-by-stage loop.

Regularisation of eq. transform2
--------------------------------
``omega`` divides by the speed v. Near ``v = 0`` the heading dynamics
``theta' ~ -(|u| / v) sin(theta - angle(u))`` turns stiff with rate ``|u| / |v|``,
and explicit RK4 is stable only while that rate times dt stays below 2.78.
Where ``|v| < v_reg = max(min_speed, |u| dt)`` the division uses
``sign(v) v_reg`` instead (``sign(0) = +1``): the heading then turns towards
the commanded acceleration at rate at most ``1 / dt`` and never produces NaN.
Every (agent, step) in which some stage was regularised is counted in
:attr:`Trajectory.regularisation_count`; where the count is zero the unicycle
reproduces the double integrator exactly (up to the integration error).
As dt -> 0 the regularised band shrinks to ``min_speed``. A regularised
robot leaves the double integrator's path; the formation is still reached
but its common offset moves: on the paper's robots with a velocity passing
close to zero, by about 4e-2 at dt = 0.01 and 1e-4 at dt = 0.0025 (tests).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_delay, check_gains, check_positive
from delayform.errors import SimulationInputError
from delayform.formation import (
    centroid_weights,
    check_formation,
    formation_forcing,
    named_formation,
)
from delayform.simulation.network import Network
from delayform.simulation.reception import integrate_network, unicycle_outputs
from delayform.topology import Topology, paper_six

__all__ = [
    "MODELS",
    "MIN_SPEED",
    "SETTLING_FRACTION",
    "Trajectory",
    "simulate",
    "stated_order",
    "paper_simulations",
]

#: agent models accepted by :func:`simulate`
MODELS = ("double_integrator", "unicycle")

#: lower bound of the regularisation threshold of eq. transform2 (m/s)
MIN_SPEED = 1e-6

#: settling: the formation error stays below this fraction of its initial value
SETTLING_FRACTION = 0.02

#: teams up to this size multiply by a dense C, larger ones by the sparse C
_DENSE_AGENTS = 64

#: at most this many float64 samples (times x agents) are saved by default
_SAVE_BUDGET = 2_000_000

_Array = NDArray[np.float64]


# ------------------------------------------------------------- the result
@dataclass(frozen=True, eq=False)
class Trajectory:
    """A simulated run of eq. formation: the motion and its metrics.

    Attributes
    ----------
    times
        Saved time points ``(T,)``.
    positions
        ``(T, n, 2)`` positions x, y.
    headings
        ``(T, n)`` headings theta in (-pi, pi]; for the double integrator the
        direction of the velocity.
    speeds
        ``(T, n)`` speeds: the signed v of the unicycle, ``|xdot|`` for the
        double integrator.
    inputs
        ``(T, n, 2)``: ``(dv/dt, omega)`` of eq. transform2 for the unicycle,
        ``u`` of eq. protocol for the double integrator.
    desired
        ``(n, 2)`` desired formation.
    model, P, D, tau1, tau2, dt
        What was simulated.
    stated_order
        Order of accuracy of the integrator for these delays and step.
    formation_error
        ``(T,)`` root-mean-square distance of the agents from the desired
        shape after removing the common offset (the mean of positions minus
        desired positions).
    settling_time
        First saved time after which the formation error stays below
        :data:`SETTLING_FRACTION` of its initial value; ``inf`` if it never does.
    final_centroid
        Weighted centroid ``w^T x`` (eq. factor1) at the last time.
    min_distance
        Smallest distance between any two robots over the saved times.
    regularisation_count
        Number of (agent, step) pairs where eq. transform2 was regularised.
    """

    times: _Array
    positions: _Array
    headings: _Array
    speeds: _Array
    inputs: _Array
    desired: _Array
    model: str
    P: float
    D: float
    tau1: float
    tau2: float
    dt: float
    stated_order: int
    formation_error: _Array
    settling_time: float
    final_centroid: _Array
    min_distance: float
    regularisation_count: int
    labels: tuple[Any, ...] = field(default=())

    @property
    def n(self) -> int:
        """Number of agents."""
        return int(self.positions.shape[1])

    @property
    def final_positions(self) -> _Array:
        """``(n, 2)`` positions at the last saved time."""
        return self.positions[-1]

    def plot_xy(self, ax: Any = None) -> Any:
        """x and y of every agent versus time (paper Figs. xy1, xy2); returns the axes (pair)."""
        from delayform.plots import plot_trajectory_xy

        return plot_trajectory_xy(self, ax=ax)

    def plot_traces(self, ax: Any = None, *, snapshots: int = 6) -> Any:
        """Paths in the plane with heading marks at snapshots (paper Fig. traces)."""
        from delayform.plots import plot_trajectory_traces

        return plot_trajectory_traces(self, ax=ax, snapshots=snapshots)

    def save_gif(self, path: str | Path, *, frames: int = 80, fps: int = 15) -> Path:
        """Write an animated GIF of the robots moving into formation."""
        from delayform.plots import save_trajectory_gif

        return save_trajectory_gif(self, path, frames=frames, fps=fps)

    def to_csv(self, path: str | Path) -> Path:
        """Write one row per (time, agent): time, agent, x, y, heading, speed, input1, input2."""
        path = Path(path)
        T, n = self.headings.shape
        cols = np.column_stack(
            [
                np.repeat(self.times, n),
                np.tile(np.arange(n), T),
                self.positions.reshape(-1, 2),
                self.headings.reshape(-1),
                self.speeds.reshape(-1),
                self.inputs.reshape(-1, 2),
            ]
        )
        input_names = "dv_dt,omega" if self.model == "unicycle" else "u_x,u_y"
        header = f"time,agent,x,y,heading,speed,{input_names}"
        np.savetxt(path, cols, delimiter=",", header=header, comments="", fmt="%.10g")
        return path


# ------------------------------------------------------ delayed look-ups
@dataclass(frozen=True)
class _Lookup:
    """Where a stage reads a delayed value: Hermite weights on a fixed interval.

    The value at ``t_k + c dt - tau`` lies on ``[t_{k+right-1}, t_{k+right}]``
    at fraction ``theta``; ``current`` marks a zero delay (use the stage value).
    """

    right: int
    theta: float
    current: bool = False
    weights: tuple[float, float, float, float] = field(init=False)

    def __post_init__(self) -> None:
        # cubic Hermite basis (h00, h10, h01, h11) at theta, computed once per run
        t = self.theta
        basis = (2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t, -2 * t**3 + 3 * t**2, t**3 - t**2)
        object.__setattr__(self, "weights", basis)


def _lookup(c: float, tau: float, dt: float) -> _Lookup:
    if tau == 0.0:
        return _Lookup(0, 1.0, current=True)
    m = c - tau / dt
    right = math.ceil(m - 1e-9)
    theta = m - (right - 1)
    if abs(theta - 1.0) < 1e-9:  # on a grid point: read it, no interpolation
        theta = 1.0
    return _Lookup(right, theta)


class _History:
    """Ring buffer of ``C x``, ``C xdot`` and ``C u`` at the last grid points.

    Before t = 0 the history is constant, ``C x0`` and ``C v0``, with zero
    derivatives (not ``C v0`` and ``C u(0)``, the state's derivatives at 0+).
    """

    def __init__(self, size: int, dt: float, cx0: _Array, cv0: _Array) -> None:
        self.size = size
        self.dt = dt
        self.cx = np.repeat(cx0[None], size, axis=0)
        self.cv = np.repeat(cv0[None], size, axis=0)
        self.ca = np.zeros_like(self.cx)

    def store_state(self, k: int, cx: _Array, cv: _Array) -> None:
        self.cx[k % self.size] = cx
        self.cv[k % self.size] = cv

    def store_accel(self, k: int, ca: _Array) -> None:
        self.ca[k % self.size] = ca

    def read(self, k: int, lk: _Lookup, positions: bool) -> _Array:
        """Interpolated ``C x`` (positions) or ``C xdot`` at the look-up of step k."""
        i1 = k + lk.right
        val, der = (self.cx, self.cv) if positions else (self.cv, self.ca)
        if lk.theta == 1.0 or i1 <= 0:
            # a grid point, or an interval within the constant history t <= 0; there
            # the derivative of the history is zero, not the state's velocity.
            return val[i1 % self.size]
        i0 = i1 - 1
        h00, h10, h01, h11 = lk.weights
        return (
            h00 * val[i0 % self.size]
            + (h10 * self.dt) * der[i0 % self.size]
            + h01 * val[i1 % self.size]
            + (h11 * self.dt) * der[i1 % self.size]
        )


# ------------------------------------------------------------ agent models
class _DoubleIntegrator:
    """State rows (x, y, xdot, ydot): ``x'' = u`` (Section "Consensus Protocol")."""

    name = "double_integrator"

    def __init__(self, x0: _Array, v0: _Array) -> None:
        self.state0 = np.column_stack([x0, v0])

    @staticmethod
    def velocity(state: _Array) -> _Array:
        return state[:, 2:]

    @staticmethod
    def rhs(state: _Array, u: _Array, dt: float, min_speed: float):
        """(state derivative, inputs, Cartesian acceleration, regularised mask or None)."""
        return np.concatenate([state[:, 2:], u], axis=1), u, u, None

    @staticmethod
    def outputs(state: _Array) -> tuple[_Array, _Array]:
        vx, vy = state[:, 2], state[:, 3]
        return np.arctan2(vy, vx), np.hypot(vx, vy)


class _Unicycle:
    """State rows (x, y, theta, v) with the dynamic extension and eq. transform2."""

    name = "unicycle"

    def __init__(self, x0: _Array, theta0: _Array, speed0: _Array) -> None:
        self.state0 = np.column_stack([x0, theta0, speed0])

    @staticmethod
    def velocity(state: _Array) -> _Array:
        th = state[:, 2]
        return state[:, 3:4] * np.column_stack([np.cos(th), np.sin(th)])

    @staticmethod
    def rhs(state: _Array, u: _Array, dt: float, min_speed: float):
        """(state derivative, inputs, Cartesian acceleration, regularised mask)."""
        th, v = state[:, 2], state[:, 3]
        c, s = np.cos(th), np.sin(th)
        u1, u2 = u[:, 0], u[:, 1]
        vdot = c * u1 + s * u2  # eq. transform2, first row
        # Regularise 1/v where the heading dynamics would be too stiff for the step (module doc).
        v_reg = np.maximum(min_speed, dt * np.hypot(u1, u2))
        small = np.abs(v) < v_reg
        v_div = np.where(small, np.where(v < 0.0, -v_reg, v_reg), v)
        omega = (-s * u1 + c * u2) / v_div  # eq. transform2, second row
        deriv = np.column_stack([v * c, v * s, omega, vdot])
        # Cartesian acceleration actually produced; equals u wherever not regularised.
        vw = v * omega
        accel = np.column_stack([vdot * c - vw * s, vdot * s + vw * c])
        return deriv, deriv[:, 3:1:-1], accel, small  # inputs (dv/dt, omega) as a view

    @staticmethod
    def outputs(state: _Array) -> tuple[_Array, _Array]:
        return np.angle(np.exp(1j * state[:, 2])), state[:, 3].copy()


# ----------------------------------------------------------------- checks
def stated_order(tau1: float, tau2: float, dt: float) -> int:
    """Order of accuracy of :func:`simulate` for these delays and step (module doc).

    Parameters
    ----------
    tau1, tau2
        Delays (s) on positions and on velocities, as given to :func:`simulate`.
    dt
        Fixed step (s) of :func:`simulate`; positive.

    Returns
    -------
    int
        4 when tau1 and tau2 are each 0 or an integer multiple of dt (to a
        relative 1e-9), else 2.

    >>> stated_order(0.3, 0.2, 0.05), stated_order(0.3, 0.21, 0.05)
    (4, 2)
    """

    def on_grid(tau: float) -> bool:
        ratio = tau / dt
        return abs(ratio - round(ratio)) <= 1e-9 * max(1.0, ratio)

    return 4 if on_grid(tau1) and on_grid(tau2) else 2


def _check_array(name: str, value: ArrayLike, shape: tuple[int, ...]) -> _Array:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise SimulationInputError(f"{name} must be numbers of shape {shape}") from exc
    if arr.shape != shape:
        if arr.ndim == 0 and len(shape) == 1:
            return _check_array(name, np.full(shape, float(arr)), shape)
        raise SimulationInputError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise SimulationInputError(f"{name} must be finite")
    return arr


def _initial_state(
    n: int,
    initial_positions: ArrayLike | None,
    initial_headings: ArrayLike | None,
    initial_speed: ArrayLike,
    seed: int | np.random.Generator | None,
) -> tuple[_Array, _Array, _Array]:
    """Positions, headings, speeds; missing ones drawn with ``seed``.

    Random positions are uniform in ``[-L, L]^2`` with ``L = 5 max(1, sqrt(n / 6))``
    (the density of the paper's six robots in a 10 x 10 square), headings
    uniform in ``[-pi, pi)``.
    """
    rng = np.random.default_rng(seed)
    half = 5.0 * max(1.0, math.sqrt(n / 6.0))
    if initial_positions is None:
        x0 = rng.uniform(-half, half, size=(n, 2))
    else:
        x0 = _check_array("initial_positions", initial_positions, (n, 2))
    if initial_headings is None:
        th0 = rng.uniform(-np.pi, np.pi, size=n)
    else:
        th0 = _check_array("initial_headings", initial_headings, (n,))
    v0 = _check_array("initial_speed", initial_speed, (n,))
    return x0, th0, v0


# ------------------------------------------------------------------- core
def simulate(
    topology: Topology,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    formation: ArrayLike | str,
    *,
    model: str = "unicycle",
    initial_positions: ArrayLike | None = None,
    initial_headings: ArrayLike | None = None,
    initial_speed: ArrayLike = 1e-3,
    seed: int | np.random.Generator | None = 0,
    duration: float,
    dt: float,
    min_speed: float = MIN_SPEED,
    save_every: int | None = None,
    network: Network | None = None,
) -> Trajectory:
    """Simulate n agents under eq. formation with delays tau1 (positions) and tau2 (velocities).

    Parameters
    ----------
    topology
        Communication topology; C is applied as a sparse product above 64 agents.
    P, D
        Positive gains of eq. protocol.
    tau1, tau2
        Non-negative delays (s); a non-zero delay must be at least ``dt``.
    formation
        ``(n, 2)`` desired positions or a shape name (:data:`delayform.formation.SHAPES`).
    model
        ``"unicycle"`` (differential-drive robot, eq. transform2) or ``"double_integrator"``.
    initial_positions
        ``(n, 2)``; default: uniform random (see ``_initial_state``) from ``seed``.
    initial_headings
        ``(n,)`` radians; default: uniform random from ``seed``.
    initial_speed
        Scalar or ``(n,)``; default 1e-3 as in the paper (avoids v = 0 in eq. transform2).
        The initial Cartesian velocity is ``speed (cos theta, sin theta)`` for both models.
    seed
        Seed of the random initial state.
    duration, dt
        Length of the run and the fixed step (s); the run ends at
        ``ceil(duration / dt) dt``.
    min_speed
        Lower bound of the regularisation threshold of eq. transform2 (module doc).
    save_every
        Keep every ``save_every``-th step; default: every step while
        ``samples x n <= 2e6``, else the smallest stride that fits.
    network
        An imperfect network (:class:`delayform.simulation.network.Network`:
        per-link and varying delays, loss, sampling, noise); None or the
        ideal network runs the integrator above, unchanged.

    Returns
    -------
    Trajectory

    Raises
    ------
    GainError, DelayError, FormationError, SimulationInputError, NoSpanningTreeError
        For bad gains, delays, formation, step, duration, model or initial state.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> traj = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", duration=60.0, dt=0.05)
    >>> bool(traj.formation_error[-1] < 0.02 * traj.formation_error[0])
    True
    """
    if not isinstance(topology, Topology):
        raise SimulationInputError(f"topology must be a Topology, got {type(topology).__name__}")
    if network is not None and not isinstance(network, Network):
        raise SimulationInputError(f"network must be a Network, got {type(network).__name__}")
    P, D = check_gains(P, D)
    tau1, tau2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    dt = check_positive("dt", dt, SimulationInputError)
    duration = check_positive("duration", duration, SimulationInputError)
    min_speed = check_positive("min_speed", min_speed, SimulationInputError)
    if model not in MODELS:
        raise SimulationInputError(f"unknown model {model!r}; choose one of {', '.join(MODELS)}")
    for name, tau in (("tau1", tau1), ("tau2", tau2)):
        if 0.0 < tau < dt * (1.0 - 1e-9):
            raise SimulationInputError(
                f"dt = {dt} exceeds {name} = {tau}: a non-zero delay must be at least one step"
            )
    n = topology.n
    desired = check_formation(formation, n)
    x0, th0, speed0 = _initial_state(n, initial_positions, initial_headings, initial_speed, seed)
    v0 = speed0[:, None] * np.column_stack([np.cos(th0), np.sin(th0)])
    steps = max(1, math.ceil(duration / dt - 1e-9))
    if save_every is None:
        save_every = max(1, math.ceil((steps + 1) * n / _SAVE_BUDGET))
    elif isinstance(save_every, bool) or not isinstance(save_every, int) or save_every < 1:
        raise SimulationInputError(f"save_every must be a positive integer, got {save_every!r}")

    agent = _DoubleIntegrator(x0, v0) if model == "double_integrator" else _Unicycle(x0, th0, speed0)
    # A dense product is faster for a handful of agents; sparse wins long before 1000.
    C = topology.C_sparse.toarray() if n <= _DENSE_AGENTS else topology.C_sparse
    F = formation_forcing(topology, P, desired)
    out = None
    if network is not None and not network.is_ideal:
        run = integrate_network(x0, v0, topology, F, P, D, tau1, tau2, network=network, dt=dt, steps=steps,
                                save_every=save_every)  # fmt: skip
        if model == "unicycle":  # the ideal robot rebuilt from its double-integrator motion
            head, spd, inp = unicycle_outputs(run.velocities, run.accelerations)
        else:
            vel = run.velocities
            head, spd, inp = np.arctan2(vel[..., 1], vel[..., 0]), np.hypot(vel[..., 0], vel[..., 1]), run.accelerations
        out = (run.times, run.positions, head, spd, inp, 0)
    elif isinstance(agent, _DoubleIntegrator) and n <= _DENSE_AGENTS:
        out = _integrate_linear(x0, v0, C, F, P, D, tau1, tau2, dt, steps, save_every)
    if out is None:
        out = _integrate(agent, C, F, P, D, tau1, tau2, dt, steps, save_every, min_speed)
    times, pos, head, spd, inp, reg = out
    return _trajectory(
        topology, desired, model, P, D, tau1, tau2, dt, times, pos, head, spd, inp, reg
    )


def _integrate(
    agent: _DoubleIntegrator | _Unicycle,
    C: Any,
    F: _Array,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    dt: float,
    steps: int,
    save_every: int,
    min_speed: float,
) -> tuple[_Array, _Array, _Array, _Array, _Array, int]:
    """RK4 with Hermite look-ups of the delayed terms (module doc); returns saved samples."""
    n = F.shape[0]
    stage_c = (0.0, 0.5, 0.5, 1.0)
    look1 = [_lookup(c, tau1, dt) for c in stage_c]
    look2 = [_lookup(c, tau2, dt) for c in stage_c]
    deepest = min(lk.right for lk in look1 + look2)
    state = agent.state0
    cx, cv = C @ state[:, :2], C @ agent.velocity(state)
    hist = _History(3 - deepest, dt, cx, cv)

    n_saved = steps // save_every + 1 + (steps % save_every != 0)
    times = np.empty(n_saved)
    pos = np.empty((n_saved, n, 2))
    head = np.empty((n_saved, n))
    spd = np.empty((n_saved, n))
    inp = np.empty((n_saved, n, 2))
    regularised = 0
    saved = 0

    # Stages 2 and 3 share their time t_k + dt/2, hence their delayed values.
    midpoint: dict[bool, _Array] = {}

    def delayed(k: int, j: int, lk: _Lookup, positions: bool) -> _Array:
        if j == 2:
            return midpoint[positions]
        value = hist.read(k, lk, positions)
        if j == 1:
            midpoint[positions] = value
        return value

    def stage(k: int, j: int, st: _Array):
        X, V = st[:, :2], agent.velocity(st)
        cxd = C @ X if look1[j].current else delayed(k, j, look1[j], True)
        cvd = C @ V if look2[j].current else delayed(k, j, look2[j], False)
        u = P * (cxd - X) + D * (cvd - V) + F  # eq. protocol + forcing of eq. formation
        return agent.rhs(st, u, dt, min_speed)

    for k in range(steps + 1):
        hist.store_state(k, cx, cv)
        k1, inputs, accel, small = stage(k, 0, state)
        hist.store_accel(k, C @ accel)
        if k % save_every == 0 or k == steps:
            times[saved] = k * dt
            pos[saved] = state[:, :2]
            head[saved], spd[saved] = agent.outputs(state)
            inp[saved] = inputs
            saved += 1
        if k == steps:
            break
        mask = small
        k2, _, _, small2 = stage(k, 1, state + (0.5 * dt) * k1)
        k3, _, _, small3 = stage(k, 2, state + (0.5 * dt) * k2)
        k4, _, _, small4 = stage(k, 3, state + dt * k3)
        if mask is not None:
            regularised += int(np.count_nonzero(mask | small2 | small3 | small4))
        state = state + (dt / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
        cx, cv = C @ state[:, :2], C @ agent.velocity(state)
    return times[:saved], pos[:saved], head[:saved], spd[:saved], inp[:saved], regularised


# ------------------------------------------- double integrator, linear map
#: the linear path keeps every step's record; above this many floats it is not used
_LINEAR_BUDGET = 10_000_000


def _linear_step_map(
    C: _Array,
    P: float,
    D: float,
    dt: float,
    look1: list[_Lookup],
    look2: list[_Lookup],
    lo: int,
    constant: tuple[bool, ...],
) -> _Array:
    """One RK4 step of the double integrator as a matrix, for one coordinate.

    The step of :func:`_integrate` is linear in the current state, the buffered
    history and F, and (x, y) never mix, so it is computed here once on
    "symbolic" vectors: each quantity is an ``(n, N)`` matrix mapping the inputs
    ``Z = (records r_{k+lo} .. r_k, F)`` to its value, where the record
    ``r_i = (a_{i-1}, x_i, xdot_i)`` holds the stage-1 acceleration u of step
    i - 1 and the state at step i. The operations are those of ``_History.read``
    and ``stage`` in the same order, so the map reproduces them up to rounding.
    ``constant[j]`` says the look-up of entry j of ``look1 + look2`` still lies
    in the constant history (``_History.read`` then reads the grid value).

    Returns the ``(3n, N)`` matrix of the increment ``r_{k+1} - r_k``.
    """
    n = C.shape[0]
    nrec = (1 - lo) * 3 * n
    eye = np.eye(nrec + n)

    def rec(rel: int, part: int) -> _Array:  # part 0: a_{i-1}, 1: x_i, 2: xdot_i
        start = ((rel - lo) * 3 + part) * n
        return eye[start : start + n]

    X0, V0, F = rec(0, 1), rec(0, 2), eye[nrec:]
    accel: list[_Array] = []  # a_k, known after stage 1 (a read at index k needs it)

    def grid(rel: int, positions: bool) -> tuple[_Array, _Array]:
        """``C x`` and ``C xdot`` (positions), or ``C xdot`` and ``C a``, at step k + rel."""
        if positions:
            return C @ rec(rel, 1), C @ rec(rel, 2)
        a = accel[0] if rel == 0 else rec(rel + 1, 0)
        return C @ rec(rel, 2), C @ a

    def read(lk: _Lookup, positions: bool, const: bool) -> _Array:
        if lk.theta == 1.0 or const:
            return grid(lk.right, positions)[0]
        h00, h10, h01, h11 = lk.weights
        v0, d0 = grid(lk.right - 1, positions)
        v1, d1 = grid(lk.right, positions)
        return h00 * v0 + (h10 * dt) * d0 + h01 * v1 + (h11 * dt) * d1

    def stage(j: int, X: _Array, V: _Array) -> _Array:
        cxd = C @ X if look1[j].current else read(look1[j], True, constant[j])
        cvd = C @ V if look2[j].current else read(look2[j], False, constant[4 + j])
        return P * (cxd - X) + D * (cvd - V) + F  # eq. protocol + forcing of eq. formation

    u1 = stage(0, X0, V0)
    accel.append(u1)
    X2, V2 = X0 + (0.5 * dt) * V0, V0 + (0.5 * dt) * u1
    u2 = stage(1, X2, V2)
    X3, V3 = X0 + (0.5 * dt) * V2, V0 + (0.5 * dt) * u2
    u3 = stage(2, X3, V3)
    X4, V4 = X0 + dt * V3, V0 + dt * u3
    u4 = stage(3, X4, V4)
    # Increments, as in ``state + (dt / 6) (k1 + ...)``: added to r_k in the loop, their
    # rounding stays relative to the step's change, not to the state.
    dX = (dt / 6.0) * (V0 + 2.0 * (V2 + V3) + V4)
    dV = (dt / 6.0) * (u1 + 2.0 * (u2 + u3) + u4)
    return np.vstack([u1 - rec(0, 0), dX, dV])


def _integrate_linear(
    x0: _Array,
    v0: _Array,
    C: _Array,
    F: _Array,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    dt: float,
    steps: int,
    save_every: int,
) -> tuple[_Array, _Array, _Array, _Array, _Array, int] | None:
    """The RK4 of :func:`_integrate` for double integrators, each step one matrix product.

    For a handful of agents the generic loop spends its time in Python overhead
    of many small NumPy calls per stage, not in arithmetic. The double
    integrator is linear and the Hermite weights are fixed, so every step is
    ``r_{k+1} = r_k + M Z_k + B`` (:func:`_linear_step_map`): a handful of
    NumPy calls per step instead of about a hundred, with the results of
    :func:`_integrate` up to rounding. While a look-up still falls in the
    constant history t <= 0 the step differs (``_History.read``), so the first
    steps use their own maps. Every record is kept (6 n floats per step, about
    as much as saving every step), so saving costs nothing in the loop.
    Returns None where this path does not apply (a first-stage read of the
    current step, or records above :data:`_LINEAR_BUDGET`).
    """
    n = F.shape[0]
    stage_c = (0.0, 0.5, 0.5, 1.0)
    look1 = [_lookup(c, tau1, dt) for c in stage_c]
    look2 = [_lookup(c, tau2, dt) for c in stage_c]
    looks = look1 + look2
    if any(lk.right >= 0 and not lk.current for lk in (look1[0], look2[0])):
        return None  # stage 1 would read a_k before it exists; the generic loop handles it
    lo = min([lk.right - 1 for lk in looks] + [0])  # deepest record read (a_i lives in r_{i+1})
    pad = -lo
    rows = pad + steps + 2
    if rows * 3 * n * 2 > _LINEAR_BUDGET:
        return None

    # Step k sees look-up j in the constant history while k + right_j <= 0
    # (interpolated look-ups only); so the map changes at most once per look-up.
    def constant(k: int) -> tuple[bool, ...]:
        return tuple(not lk.current and lk.theta != 1.0 and k + lk.right <= 0 for lk in looks)

    changes = sorted({0} | {min(max(1 - lk.right, 0), steps + 1) for lk in looks})
    bounds = [k for k in changes if k <= steps] + [steps + 1]
    maps = [_linear_step_map(C, P, D, dt, look1, look2, lo, constant(k)) for k in bounds[:-1]]
    # Keep only the records some map reads (each delay reads a few of them): the
    # product then costs the same for tau = 2 dt as for tau = 200 dt.
    nrec = 1 - lo
    blocks = [m[:, : nrec * 3 * n].reshape(3 * n, nrec, 3 * n) for m in maps]
    used = np.flatnonzero(np.any([np.any(b != 0, axis=(0, 2)) for b in blocks], axis=0))
    lags = used + lo  # step of each record read, relative to k
    linear = [np.ascontiguousarray(b[:, used].reshape(3 * n, -1)) for b in blocks]
    affine = [m[:, nrec * 3 * n :] @ F for m in maps]  # the forcing F, a constant input

    # H[pad + i] = r_i; before t = 0 the state is x0, v0 and no acceleration.
    H = np.empty((rows, 3 * n, 2))
    H[: pad + 1, :n] = 0.0
    H[: pad + 1, n : 2 * n] = x0
    H[: pad + 1, 2 * n :] = v0
    for M, B, start, stop in zip(linear, affine, bounds[:-1], bounds[1:]):
        read_rows = lags + pad
        for k in range(start, stop):
            # r_{k+1} = r_k + M (records of steps k + lags) + B; the last step
            # (k = steps) is only there for a_steps, the input saved at t_steps.
            r = pad + k
            np.add(H[r], M @ H[read_rows + k].reshape(-1, 2), out=H[r + 1])
            H[r + 1] += B

    saved = np.arange(0, steps + 1, save_every)
    if saved[-1] != steps:
        saved = np.append(saved, steps)
    pos = H[pad + saved, n : 2 * n]
    vel = H[pad + saved, 2 * n :]
    inp = H[pad + saved + 1, :n]
    head = np.arctan2(vel[..., 1], vel[..., 0])
    spd = np.hypot(vel[..., 0], vel[..., 1])
    return saved * dt, pos, head, spd, inp, 0


# ---------------------------------------------------------------- metrics
def _formation_error(positions: _Array, desired: _Array) -> _Array:
    """RMS distance from the desired shape after removing the common (mean) offset."""
    dev = positions - desired[None]
    dev -= dev.mean(axis=1, keepdims=True)
    return np.sqrt(np.mean(np.sum(dev**2, axis=2), axis=1))


def _settling_time(times: _Array, error: _Array, scale: float) -> float:
    """First time after which ``error`` stays below SETTLING_FRACTION of ``error[0]``.

    Errors below ``1e-12 scale`` (rounding, for a team that starts in formation) count as settled.
    """
    above = np.flatnonzero(error > max(SETTLING_FRACTION * error[0], 1e-12 * scale))
    if above.size == 0:
        return float(times[0])
    last = above[-1]
    return float(times[last + 1]) if last + 1 < times.size else math.inf


def _min_distance(positions: _Array) -> float:
    """Smallest distance between two robots over all samples, without an n x n matrix for large n."""
    T, n, _ = positions.shape
    if n < 2:
        return math.inf
    if n <= 64:
        diff = positions[:, :, None, :] - positions[:, None, :, :]
        dist = np.sqrt(np.sum(diff**2, axis=-1))
        dist[:, np.arange(n), np.arange(n)] = np.inf
        return float(dist.min())
    from scipy.spatial import cKDTree

    best = math.inf
    for frame in positions:
        d, _ = cKDTree(frame).query(frame, k=2)
        best = min(best, float(d[:, 1].min()))
    return best


def _trajectory(
    topology: Topology,
    desired: _Array,
    model: str,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    dt: float,
    times: _Array,
    pos: _Array,
    head: _Array,
    spd: _Array,
    inp: _Array,
    regularised: int,
) -> Trajectory:
    error = _formation_error(pos, desired)
    return Trajectory(
        times=times,
        positions=pos,
        headings=head,
        speeds=spd,
        inputs=inp,
        desired=desired,
        model=model,
        P=P,
        D=D,
        tau1=tau1,
        tau2=tau2,
        dt=dt,
        stated_order=stated_order(tau1, tau2, dt),
        formation_error=error,
        settling_time=_settling_time(times, error, 1.0 + float(np.abs(pos[0]).max())),
        final_centroid=centroid_weights(topology) @ pos[-1],
        min_distance=_min_distance(pos),
        regularisation_count=regularised,
        labels=topology.labels,
    )


# ------------------------------------------------------------ paper demo
def paper_simulations(
    *, seed: int = 0, duration: float = 150.0, dt: float = 0.01, spacing: float = 2.0
) -> tuple[Trajectory, Trajectory]:
    """The paper's six robots (Fig. topol, P = 1, D = 0.5) into a hexagon at points a and b.

    Unicycle robots from random positions and headings (``seed``) with initial
    speed 1e-3 (Section "Simulation Examples"); point a is
    ``(tau1, tau2) = (0.3, 0.2)``, point b is ``(2, 1)``.

    Parameters
    ----------
    seed
        Seed of the random initial positions and headings; both runs start
        from the same state. Default 0.
    duration
        Length of each run (s); default 150.
    dt
        Fixed RK4 step (s); default 0.01, at most 0.2 (the delay tau2 at
        point a).
    spacing
        Side length of the desired hexagon; default 2.0.

    Returns
    -------
    (Trajectory, Trajectory)
        The runs at point a and at point b.
    """
    topo = paper_six()
    shape = named_formation("hexagon", topo.n, spacing=spacing)
    runs = tuple(
        simulate(topo, 1.0, 0.5, t1, t2, shape, seed=seed, duration=duration, dt=dt)
        for t1, t2 in ((0.3, 0.2), (2.0, 1.0))
    )
    return runs[0], runs[1]
