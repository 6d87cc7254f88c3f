"""The delayed integrator: fixed-step RK4 with Hermite look-ups into a bounded history.

Method
------
Classical fixed-step Runge-Kutta (RK4) for the current state; the delayed
terms ``C x(t - tau1)`` and ``C xdot(t - tau2)`` of the paper's eq. 1 are read
from the computed solution by cubic Hermite interpolation between grid
points, using the derivatives the solution carries (``(C x)' = C xdot``,
``(C xdot)' = C a`` with ``a`` the agents' Cartesian acceleration). Both are
fourth order, so the method is fourth order on a smooth problem when the
points where the solution loses smoothness fall on grid points. The constant
history makes ``x'`` and ``xdot'`` jump at ``t = 0``; the delays carry these
to kinks of the protocol input at ``t = tau1`` and ``t = tau2``. **Stated
order (smooth agents): 4 when tau1 and tau2 are each 0 or an integer
multiple of dt, 2 otherwise** (a kink of u inside a step costs two orders).

History
-------
Before ``t = 0`` the state is constant (positions ``x0``, velocities
``v0``, zero derivatives). A look-up that falls before ``t = 0`` reads that
constant, whatever the delay, so a delay longer than the run reads nothing
but the constant history: the integrators replace such a delay by the
shortest on-grid delay beyond the run (:func:`effective_delay`), which
changes no value, and the history buffer never holds more than
``min(max(tau1, tau2), duration) / dt + 3`` steps.

Two loops
---------
``integrate`` runs any agent model stage by stage (C applied three times
per step, sparse for large teams). ``integrate_linear`` is the same RK4 for
double integrators in small teams: every step is linear in the state, the
few history values it reads and the forcing, so it is precomputed as
matrices and advanced in blocks of steps whose delayed reads are already
known (module :func:`integrate_linear`). Both stop cleanly when the state
leaves :data:`BLOWUP` times its initial scale or turns non-finite.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from numpy.lib.stride_tricks import as_strided
from numpy.typing import NDArray

from delayform.simulation.delayed.actuation import CommandBuffer

__all__ = ["stated_order", "effective_delay", "BLOWUP"]

_Array = NDArray[np.float64]

#: integration stops when a state component exceeds this times the initial scale
BLOWUP = 1e8

#: the blocked linear path multiplies matrices of at most this many rows (block x 3 n)
_BLOCK_ROWS = 96

_STAGE_C = (0.0, 0.5, 0.5, 1.0)

#: called with (steps done, steps in all) while a run is integrated
Progress = Callable[[int, int], None]


def stated_order(tau1: float, tau2: float, dt: float) -> int:
    """Order of accuracy of the RK4 + Hermite integrator for these delays and step (module doc).

    This is the order for agents with smooth dynamics (double integrators,
    ideal robots); robots with actuator limits are order 2 (see
    :func:`delayform.simulation.simulate`).

    Parameters
    ----------
    tau1, tau2
        Delays (s) on positions and on velocities.
    dt
        Fixed step (s); positive.

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


def effective_delay(tau: float, dt: float, steps: int) -> float:
    """A delay that reads the same values as ``tau`` over ``steps`` steps of ``dt``.

    Every look-up of a delay longer than the run falls in the constant
    history ``t <= 0``; such a delay is replaced by ``(steps + 2) dt``, which
    reads the same constant, so buffers and matrices stay the size of the run.

    Parameters
    ----------
    tau
        The delay (s).
    dt
        The step (s).
    steps
        Number of steps of the run.

    >>> effective_delay(1e6, 0.01, 500)
    5.0200000000000005
    """
    longest = (steps + 2) * dt
    return tau if tau <= longest else longest


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


def _lookups(tau1: float, tau2: float, dt: float) -> tuple[list[_Lookup], list[_Lookup]]:
    return [_lookup(c, tau1, dt) for c in _STAGE_C], [_lookup(c, tau2, dt) for c in _STAGE_C]


def history_steps(tau1: float, tau2: float, dt: float) -> int:
    """Steps of ``C x``, ``C xdot``, ``C a`` the generic loop keeps for these (effective) delays."""
    look1, look2 = _lookups(tau1, tau2, dt)
    return 3 - min(lk.right for lk in look1 + look2)


class _History:
    """Ring buffer of ``C x``, ``C xdot`` and ``C a`` at the last grid points.

    Before t = 0 the history is constant, ``C x0`` and ``C v0``, with zero
    derivatives (not ``C v0`` and ``C a(0)``, the state's derivatives at 0+).
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


# ------------------------------------------------------------ generic loop
class Agent(Protocol):
    """What the generic loop needs of an agent model (see :mod:`delayform.simulation.models.robots`)."""

    state0: _Array
    extras: tuple[str, ...]

    def velocity(self, state: _Array) -> _Array: ...

    def rhs(self, state: _Array, u: _Array) -> tuple[_Array, _Array, tuple[_Array, ...]]: ...


@dataclass(frozen=True)
class Samples:
    """Saved samples of a run: times, positions, velocities, accelerations, model extras.

    ``stopped`` is the time at which integration stopped because the state
    left :data:`BLOWUP` times its initial scale (None if it ran to the end).
    ``states`` holds the agent state rows at each sample (the generic loop only).
    """

    times: _Array
    positions: _Array
    velocities: _Array
    accelerations: _Array
    extras: dict[str, _Array]
    states: _Array | None
    stopped: float | None


def _blowup_scale(*arrays: _Array) -> float:
    return BLOWUP * (1.0 + max(float(np.abs(a).max(initial=0.0)) for a in arrays))


def integrate(
    agent: Agent,
    C: Any,
    F: _Array,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    dt: float,
    steps: int,
    save_every: int,
    progress: Progress | None = None,
    actuation_delay: float = 0.0,
) -> Samples:
    """RK4 with Hermite look-ups of the delayed terms (module doc), stage by stage.

    ``progress(done, steps)`` is called every 1000 steps when given. With
    ``actuation_delay`` > 0 (at least dt) each stage executes the command of
    ``actuation_delay`` earlier (:mod:`delayform.simulation.delayed.actuation`); the
    agent then needs ``command`` and ``apply``.
    """
    n = F.shape[0]
    look1, look2 = _lookups(tau1, tau2, dt)
    state = agent.state0
    cx, cv = C @ state[:, :2], C @ agent.velocity(state)
    hist = _History(history_steps(tau1, tau2, dt), dt, cx, cv)
    limit = _blowup_scale(state)

    n_saved = steps // save_every + 1 + (steps % save_every != 0)
    times = np.empty(n_saved)
    pos = np.empty((n_saved, n, 2))
    vel = np.empty((n_saved, n, 2))
    acc = np.empty((n_saved, n, 2))
    states = np.empty((n_saved,) + state.shape)
    extras = {name: np.empty((n_saved, n)) for name in agent.extras}
    saved = 0
    stopped = None

    # Stages 2 and 3 share their time t_k + dt/2, hence their delayed values.
    midpoint: dict[bool, _Array] = {}

    def delayed(k: int, j: int, lk: _Lookup, positions: bool) -> _Array:
        if j == 2:
            return midpoint[positions]
        value = hist.read(k, lk, positions)
        if j == 1:
            midpoint[positions] = value
        return value

    late = CommandBuffer(actuation_delay, dt, steps, F.shape) if actuation_delay > 0.0 else None
    if late is not None and hasattr(agent, "predict_with"):  # a filter that must see the commands in flight
        agent.predict_with(late)

    def stage(k: int, j: int, st: _Array) -> tuple[_Array, _Array, tuple[_Array, ...]]:
        X, V = st[:, :2], agent.velocity(st)
        cxd = C @ X if look1[j].current else delayed(k, j, look1[j], True)
        cvd = C @ V if look2[j].current else delayed(k, j, look2[j], False)
        u = P * (cxd - X) + D * (cvd - V) + F  # the paper's eq. 1 + forcing of the paper's eq. 13
        if late is None:
            return agent.rhs(st, u)
        if j == 0:  # the command made at the grid point, executed actuation_delay later
            late.store(k, agent.command(st, u))  # type: ignore[attr-defined]
        return agent.apply(st, late.read(k, _STAGE_C[j]))  # type: ignore[attr-defined]

    for k in range(steps + 1):
        if progress is not None and k % 1000 == 0:
            progress(k, steps)
        hist.store_state(k, cx, cv)
        k1, accel, extra = stage(k, 0, state)
        hist.store_accel(k, C @ accel)
        if k % save_every == 0 or k == steps:
            times[saved] = k * dt
            pos[saved] = state[:, :2]
            vel[saved] = agent.velocity(state)
            acc[saved] = accel
            states[saved] = state
            for name, value in zip(agent.extras, extra):
                extras[name][saved] = value
            saved += 1
        if k == steps:
            break
        k2 = stage(k, 1, state + (0.5 * dt) * k1)[0]
        k3 = stage(k, 2, state + (0.5 * dt) * k2)[0]
        k4 = stage(k, 3, state + dt * k3)[0]
        new = state + (dt / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
        if k % 8 == 7 and not np.abs(new).max() <= limit:  # also catches NaN
            stopped = k * dt
            break
        state = new
        cx, cv = C @ state[:, :2], C @ agent.velocity(state)
    return Samples(
        times[:saved], pos[:saved], vel[:saved], acc[:saved],
        {k: v[:saved] for k, v in extras.items()}, states[:saved], stopped,
    )  # fmt: skip


# ------------------------------------------- double integrator, linear map
def _linear_step_map(
    C: _Array,
    P: float,
    D: float,
    dt: float,
    look1: list[_Lookup],
    look2: list[_Lookup],
    lo: int,
    constant: tuple[bool, ...],
    stages: list[tuple[Any, Any, Any]] | None = None,
) -> tuple[dict[int, _Array], _Array]:
    """One RK4 step of the double integrator as matrices, for one coordinate.

    The step of :func:`integrate` is linear in the current state, the
    buffered history and F, and (x, y) never mix. With the record
    ``r_i = (a_{i-1}, x_i, xdot_i)`` (the stage-1 acceleration u of step i - 1
    and the state at step i) the step is ``r_{k+1} = r_k + sum_l M_l r_{k+l} + G F``
    over the few lags l (``lo <= l <= 0``) the look-ups read. It is computed
    here on "symbolic" vectors: each quantity is a dict lag -> ``(n, 3n)``
    matrix plus an ``(n, n)`` matrix for F. The operations are those of
    ``_History.read`` and ``stage`` in the same order, so the result matches
    the generic loop up to rounding, and only the lags read are ever formed
    (a delay of 1e4 steps costs the same as one of 4). ``constant[j]`` says
    look-up j of ``look1 + look2`` still lies in the constant history.

    Returns ``({lag: M_lag}, G)``: the ``(3n, 3n)`` increment matrices and
    the ``(3n, n)`` forcing matrix. A given ``stages`` list receives each
    stage's ``(X, V, u)`` as ``({lag: (n, 3n)}, (n, n) F part)`` maps of the records.
    """
    n = C.shape[0]
    Lin = tuple[dict[int, _Array], _Array]  # (lag -> (n, 3n), F part (n, n))

    def add(*terms: tuple[float, Lin]) -> Lin:
        out: dict[int, _Array] = {}
        f = np.zeros((n, n))
        for coef, (parts, fpart) in terms:
            for lag, mat in parts.items():
                out[lag] = out[lag] + coef * mat if lag in out else coef * mat
            f = f + coef * fpart
        return out, f

    def apply_c(v: Lin) -> Lin:
        return {lag: C @ m for lag, m in v[0].items()}, C @ v[1]

    def rec(rel: int, part: int) -> Lin:  # part 0: a_{i-1}, 1: x_i, 2: xdot_i
        m = np.zeros((n, 3 * n))
        m[:, part * n : (part + 1) * n] = np.eye(n)
        return {rel: m}, np.zeros((n, n))

    X0, V0 = rec(0, 1), rec(0, 2)
    F: Lin = ({}, np.eye(n))
    accel: list[Lin] = []  # a_k, known after stage 1 (a read at index k needs it)

    def grid(rel: int, positions: bool) -> tuple[Lin, Lin]:
        """``C x`` and ``C xdot`` (positions), or ``C xdot`` and ``C a``, at step k + rel."""
        if positions:
            return apply_c(rec(rel, 1)), apply_c(rec(rel, 2))
        a = accel[0] if rel == 0 else rec(rel + 1, 0)
        return apply_c(rec(rel, 2)), apply_c(a)

    def read(lk: _Lookup, positions: bool, const: bool) -> Lin:
        if lk.theta == 1.0 or const:
            return grid(lk.right, positions)[0]
        h00, h10, h01, h11 = lk.weights
        v0, d0 = grid(lk.right - 1, positions)
        v1, d1 = grid(lk.right, positions)
        return add((h00, v0), (h10 * dt, d0), (h01, v1), (h11 * dt, d1))

    def stage(j: int, X: Lin, V: Lin) -> Lin:
        cxd = apply_c(X) if look1[j].current else read(look1[j], True, constant[j])
        cvd = apply_c(V) if look2[j].current else read(look2[j], False, constant[4 + j])
        # the paper's eq. 1 + forcing of the paper's eq. 13
        return add((P, cxd), (-P, X), (D, cvd), (-D, V), (1.0, F))

    h = 0.5 * dt
    u1 = stage(0, X0, V0)
    accel.append(u1)
    X2, V2 = add((1, X0), (h, V0)), add((1, V0), (h, u1))
    u2 = stage(1, X2, V2)
    X3, V3 = add((1, X0), (h, V2)), add((1, V0), (h, u2))
    u3 = stage(2, X3, V3)
    X4, V4 = add((1, X0), (dt, V3)), add((1, V0), (dt, u3))
    u4 = stage(3, X4, V4)
    if stages is not None:
        stages += [(X0, V0, u1), (X2, V2, u2), (X3, V3, u3), (X4, V4, u4)]
    s = dt / 6.0
    dX = add((s, V0), (2 * s, V2), (2 * s, V3), (s, V4))
    dV = add((s, u1), (2 * s, u2), (2 * s, u3), (s, u4))
    da = add((1, u1), (-1, rec(0, 0)))
    lags = sorted(set(da[0]) | set(dX[0]) | set(dV[0]))
    zero = np.zeros((n, 3 * n))
    mats = {lag: np.vstack([part[0].get(lag, zero) for part in (da, dX, dV)]) for lag in lags}
    return mats, np.vstack([da[1], dX[1], dV[1]])


def _lag_clusters(lags: NDArray[np.int_], gap: int = 8) -> list[tuple[int, int]]:
    """Runs of lags no more than ``gap`` apart: ``[(first, last), ...]``."""
    out: list[tuple[int, int]] = []
    for lag in (int(v) for v in lags):
        if out and lag - out[-1][1] <= gap:
            out[-1] = (out[-1][0], lag)
        else:
            out.append((lag, lag))
    return out


def _window_kernel(mats: dict[int, _Array], first: int, last: int, n: int) -> _Array:
    """``((last - first + 1) 6n, 6n)`` matrix mapping the flat records r_first..r_last to d.

    Records are stored ``(3n, 2)`` row-major (coordinate fastest), so each
    ``(3n, 3n)`` increment matrix acts as ``kron(M^T, I_2)`` on a flat record.
    """
    eye2 = np.eye(2)
    zero = np.zeros((6 * n, 6 * n))
    return np.vstack([np.kron(mats[lag].T, eye2) if lag in mats else zero for lag in range(first, last + 1)])


def _records(x0: _Array, v0: _Array, pad: int, rows: int) -> tuple[_Array, _Array]:
    """The records array ``H[pad + i] = r_i`` (and its flat view); before t = 0 the state is x0, v0, no acceleration."""
    n = x0.shape[0]
    H = np.empty((rows, 3 * n, 2))
    H[: pad + 1, :n] = 0.0
    H[: pad + 1, n : 2 * n] = x0
    H[: pad + 1, 2 * n :] = v0
    return H, H.reshape(-1)


def integrate_linear(
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
    progress: Progress | None = None,
) -> Samples | None:
    """The RK4 of :func:`integrate` for double integrators, advanced in blocks of steps.

    For a handful of agents the generic loop spends its time in Python
    overhead of many small NumPy calls per stage, not in arithmetic. The
    double integrator is linear and the Hermite weights are fixed, so every
    step is ``r_{k+1} = A0 r_k + d_k`` where ``A0 = I + M_0`` acts on the
    current record and ``d_k = sum_{l<0} M_l r_{k+l} + G F`` collects the
    delayed reads (:func:`_linear_step_map`). Within a block of ``m`` steps,
    ``m`` no longer than the shortest delayed lag, every ``d_k`` reads
    records computed before the block: all of them are one matrix product,
    and the block's records follow from powers of ``A0`` in one more
    (``r_{k+j} = A0^j r_k + sum_{i<j} A0^{j-1-i} d_{k+i}``). Same results
    as :func:`integrate` up to rounding. While a look-up still falls in the
    constant history t <= 0 the step differs (``_History.read``), so the
    first steps use their own maps. Every record is kept (6 n floats per
    step, about as much as saving every step).

    Returns None where this path does not apply (a first-stage read of the
    current step). ``progress(done, steps)`` is called every 256 blocks when given.
    """
    n = F.shape[0]
    look1, look2 = _lookups(tau1, tau2, dt)
    looks = look1 + look2
    if any(lk.right >= 0 and not lk.current for lk in (look1[0], look2[0])):
        return None  # stage 1 would read a_k before it exists; the generic loop handles it
    lo = min([lk.right - 1 for lk in looks] + [0])  # deepest record read (a_i lives in r_{i+1})
    pad = -lo
    rows = pad + steps + 2

    # Step k sees look-up j in the constant history while k + right_j <= 0
    # (interpolated look-ups only); so the map changes at most once per look-up.
    def constant(k: int) -> tuple[bool, ...]:
        return tuple(not lk.current and lk.theta != 1.0 and k + lk.right <= 0 for lk in looks)

    changes = sorted({0} | {min(max(1 - lk.right, 0), steps + 1) for lk in looks})
    bounds = [k for k in changes if k <= steps] + [steps + 1]

    H, flat = _records(x0, v0, pad, rows)
    limit = _blowup_scale(x0, v0)
    done = steps + 1  # steps advanced (the last one only for a_steps)
    for start, stop in zip(bounds[:-1], bounds[1:]):
        mats, G = _linear_step_map(C, P, D, dt, look1, look2, lo, constant(start))
        A0 = np.eye(3 * n) + mats.pop(0, 0.0)
        lags = np.array(sorted(mats), dtype=int)
        B = G @ F
        # The delayed reads of step k + j are rows r_{k+j+l}: for a run of neighbouring
        # lags they form one contiguous window of the flat history, whose sliding view
        # over j is a matrix, so all reads of a block are one product per run of lags.
        clusters = _lag_clusters(lags)
        kernels = [_window_kernel(mats, lo_l, hi_l, n) for lo_l, hi_l in clusters]
        # row i of windows[c] is the flat records r_{i - pad + first} .. r_{i - pad + last}
        windows = [
            as_strided(flat, shape=(rows - (hi_l - lo_l), (hi_l - lo_l + 1) * 6 * n),
                       strides=(6 * n * 8, 8), writeable=False)
            for lo_l, hi_l in clusters
        ]  # fmt: skip
        # Without zero delays the current record only feeds each agent's own state,
        # the same 3 x 3 map for every agent: A0 = kron(a0, I_n) in the record layout
        # (a, x, xdot) x agents, so powers and sums over the block act on 3 rows, not 3n.
        a0 = A0[::n, ::n]
        per_agent = bool(np.array_equal(A0, np.kron(a0, np.eye(n))))
        width = 3 if per_agent else 3 * n
        base = a0 if per_agent else A0
        block = min(1 - int(lags.max()) if lags.size else steps + 1, max(1, _BLOCK_ROWS // width))
        powers = [np.eye(width)]
        for _ in range(block):
            powers.append(base @ powers[-1])
        Pw = np.vstack(powers[1:])  # A0^1 .. A0^block
        T = np.zeros((block * width, block * width))
        for j in range(block):  # block row j (record k + j + 1) gets A0^(j - i) d_{k+i}
            for i in range(j + 1):
                T[j * width : (j + 1) * width, i * width : (i + 1) * width] = powers[j - i]
        cols = 2 * n if per_agent else 2
        still = np.tile(B.reshape(1, 6 * n), (block, 1))  # d without delayed reads
        checked = start  # records up to r_checked are known to be below the blow-up limit
        for b, k in enumerate(range(start, stop, block)):
            if progress is not None and b % 256 == 0:
                progress(k, steps)
            m = min(block, stop - k)
            r = pad + k
            d = still[:m]
            for (lo_l, _), K, W in zip(clusters, kernels, windows):
                d = d + W[r + lo_l : r + lo_l + m] @ K
            rm = m * width
            new = Pw[:rm] @ H[r].reshape(width, cols) + T[:rm, :rm] @ d.reshape(rm, cols)
            H[r + 1 : r + 1 + m] = new.reshape(m, 3 * n, 2)
            if k + m - checked >= 256 or k + m >= stop:
                # checked in stretches: cheap, and a blow-up is caught long before overflow
                if not np.abs(H[pad + checked + 1 : r + 1 + m]).max() <= limit:  # also NaN
                    done = checked
                    break
                checked = k + m
        if done <= steps:
            break

    last = max(0, min(steps, done - 1))  # a_k lives in r_{k+1}
    saved = np.arange(0, last + 1, save_every)
    if saved[-1] != last:
        saved = np.append(saved, last)
    return Samples(
        times=saved * dt,
        positions=H[pad + saved, n : 2 * n],
        velocities=H[pad + saved, 2 * n :],
        accelerations=H[pad + saved + 1, :n],
        extras={},
        states=None,
        stopped=None if done > steps else done * dt,
    )
