"""Small filtered teams: the blocked linear RK4 wherever the safety filter is idle, the filter's step elsewhere.

Method
------
Where no constraint binds the safety filter returns ``u_hat`` exactly
(:mod:`delayform.simulation.bodies.safety`), so the filtered run is the unfiltered
one, which for double integrators in small teams the blocked linear path
computes fast (:func:`delayform.simulation.delayed.integrator.integrate_linear`).
This loop keeps the same records ``r_i = (a_{i-1}, x_i, xdot_i)`` and
advances by either of two steps:

* a **linear block** of up to ``m`` steps, then checked: every RK4 stage's
  state and command of those steps is itself a linear map of the records
  (:func:`~delayform.simulation.delayed.integrator._linear_step_map` gives them),
  so all ``4 m`` of them are formed at once and the filter's own test
  (:func:`~delayform.simulation.bodies.safety.binds`) is applied to each. Steps
  before the first stage at which the filter would act are kept;
* a **filtered step** at that step: the RK4 of the generic loop, its
  delayed values read from the records by the same Hermite interpolation,
  each stage's command passed through the filter.

After a filtered step at which the filter did not act in any stage the
linear blocks resume, growing from one step. The result equals the generic
loop with the filter (:func:`delayform.simulation.delayed.integrator.integrate`) to
rounding; the tests compare the two.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.lib.stride_tricks import as_strided
from numpy.typing import NDArray

from delayform.simulation.delayed.integrator import (
    Progress,
    Samples,
    _blowup_scale,
    _lag_clusters,
    _linear_step_map,
    _Lookup,
    _lookups,
    _records,
    _window_kernel,
)
from delayform.simulation.bodies.safety import ActiveSet, barrier_commands, binds

__all__ = ["integrate_filtered"]

_Array = NDArray[np.float64]

#: most steps in one linear block
_BLOCK = 64


def _stage_kernels(stages: list[tuple[Any, Any, Any]], lo: int, n: int) -> tuple[list[tuple[int, _Array]], _Array]:
    """The stages' ``(X, V, u)`` maps as one matrix per lag: ``(12 n, 3 n)`` acting on record ``r_{k+lag}``."""
    parts = [q for stage in stages for q in stage]  # 12 maps of (n, 3n) per lag
    lags = sorted({lag for q in parts for lag in q[0]})
    zero = np.zeros((n, 3 * n))
    mats = [(lag, np.vstack([q[0].get(lag, zero) for q in parts])) for lag in lags]
    return mats, np.vstack([q[1] for q in parts])  # (12 n, n) forcing part


class _Segment:
    """The linear step maps of one stretch of steps (a fixed set of constant-history look-ups)."""

    def __init__(self, C: _Array, F: _Array, P: float, D: float, dt: float, look1: list[_Lookup],
                 look2: list[_Lookup], lo: int, constant: tuple[bool, ...], flat: _Array, rows: int) -> None:  # fmt: skip
        n = C.shape[0]
        stages: list[tuple[Any, Any, Any]] = []
        mats, G = _linear_step_map(C, P, D, dt, look1, look2, lo, constant, stages)
        self.n = n
        self.A0 = np.eye(3 * n) + mats.pop(0, 0.0)
        lags = np.array(sorted(mats), dtype=int)
        self.B = (G @ F).reshape(1, 6 * n)
        self.clusters = _lag_clusters(lags)
        self.kernels = [_window_kernel(mats, a, b, n) for a, b in self.clusters]
        self.windows = [as_strided(flat, shape=(rows - (b - a), (b - a + 1) * 6 * n), strides=(6 * n * 8, 8),
                                   writeable=False) for a, b in self.clusters]  # fmt: skip
        # a block reads only records from before it; its steps are then one product each
        self.block = max(1, min(1 - int(lags.max()) if lags.size else _BLOCK, _BLOCK))
        self.stage_mats, stage_f = _stage_kernels(stages, lo, n)
        self.stage_f = stage_f @ F  # (12 n, 2)

    def advance(self, H: _Array, pad: int, k: int, m: int) -> None:
        """Records ``r_{k+1} .. r_{k+m}`` from the records before (``m`` at most the block)."""
        r = pad + k
        d = np.repeat(self.B, m, axis=0)
        for (a, _), K, W in zip(self.clusters, self.kernels, self.windows):
            d = d + W[r + a : r + a + m] @ K
        d = d.reshape(m, 3 * self.n, 2)
        rec = H[r]
        for j in range(m):  # m <= block: a few small products
            rec = self.A0 @ rec + d[j]
            H[r + 1 + j] = rec

    def stage_states(self, H: _Array, pad: int, k: int, m: int) -> _Array:
        """``(m, 12 n, 2)``: stages' (X, V, u) of steps ``k .. k + m - 1`` from the records."""
        out = np.broadcast_to(self.stage_f, (m,) + self.stage_f.shape).copy()
        for lag, M in self.stage_mats:
            out += np.matmul(M, H[pad + k + lag : pad + k + lag + m])
        return out


def integrate_filtered(
    x0: _Array, v0: _Array, C: _Array, F: _Array, P: float, D: float, tau1: float, tau2: float, dt: float,
    steps: int, save_every: int, safe: float, rate: float, progress: Progress | None = None,
) -> Samples | None:  # fmt: skip
    """Filtered double integrators in a small team (module doc); None where the linear path does not apply.

    Parameters
    ----------
    x0, v0
        ``(n, 2)`` initial positions and velocities (the constant history).
    C
        ``(n, n)`` dense weight matrix (paper, eq. 1).
    F
        ``(n, 2)`` forcing of the paper's eq. 13.
    P, D
        Gains of the paper's eq. 1.
    tau1, tau2
        Effective delays (s) on positions and velocities.
    dt
        Fixed RK4 step (s).
    steps
        Number of steps.
    save_every
        Save every this many steps (and the last).
    safe, rate
        The filter's distance Ds (m) and its k (1/s)
        (:class:`~delayform.simulation.bodies.safety.BarrierFilter`).
    progress
        Called with (steps done, steps in all) every 1000 steps when given.

    Returns
    -------
    Samples or None
        As the generic loop's, with extras ``safety_active`` and
        ``safety_infeasible`` (the filter's stage-1 flags); None when stage 1
        would read the current step's acceleration (the generic loop then runs).
    """
    n = F.shape[0]
    look1, look2 = _lookups(tau1, tau2, dt)
    looks = look1 + look2
    if any(lk.right >= 0 and not lk.current for lk in (look1[0], look2[0])):
        return None
    lo = min([lk.right - 1 for lk in looks] + [0])
    pad = -lo
    rows = pad + steps + 2
    H, flat = _records(x0, v0, pad, rows)
    limit = _blowup_scale(x0, v0)
    pairs = np.column_stack(np.triu_indices(n, k=1)).astype(np.intp)
    memory = ActiveSet()  # the joint QP's warm start from stage to stage
    active = np.zeros((steps + 1, n), dtype=bool)
    squeezed = np.zeros((steps + 1, n), dtype=bool)

    def constant(k: int) -> tuple[bool, ...]:
        return tuple(not lk.current and lk.theta != 1.0 and k + lk.right <= 0 for lk in looks)

    segments: dict[tuple[bool, ...], _Segment] = {}

    def segment(k: int) -> _Segment:
        key = constant(k)
        if key not in segments:
            segments[key] = _Segment(C, F, P, D, dt, look1, look2, lo, key, flat, rows)
        return segments[key]

    def next_change(k: int) -> int:
        """First step after k whose look-ups leave the constant history differently (a new segment)."""
        later = [1 - lk.right for lk in looks if not lk.current and lk.theta != 1.0 and 1 - lk.right > k]
        return min(later + [steps + 1])

    def read(k: int, lk: _Lookup, positions: bool, a_k: _Array) -> _Array:
        """``C x`` or ``C xdot`` at look-up lk of step k, from the records (``_History.read``)."""
        i1 = k + lk.right
        part = 1 if positions else 2
        val = lambda i: H[pad + i, part * n : (part + 1) * n]  # noqa: E731
        if lk.theta == 1.0 or i1 <= 0:
            return C @ val(i1)
        i0 = i1 - 1
        if positions:
            der = lambda i: H[pad + i, 2 * n :]  # noqa: E731
        else:
            der = lambda i: a_k if i == k else H[pad + i + 1, :n]  # noqa: E731
        h00, h10, h01, h11 = lk.weights
        return C @ (h00 * val(i0) + (h10 * dt) * der(i0) + h01 * val(i1) + (h11 * dt) * der(i1))

    def filtered_step(k: int) -> bool:
        """One RK4 step with the filter at every stage; True if it acted at any."""
        x, v = H[pad + k, n : 2 * n].copy(), H[pad + k, 2 * n :].copy()
        a_k = np.zeros((n, 2))
        mid: dict[bool, _Array] = {}
        acted = False

        def command(j: int, X: _Array, V: _Array) -> _Array:
            nonlocal acted
            reads = []
            for lk, pos, S in ((look1[j], True, X), (look2[j], False, V)):
                if lk.current:
                    reads.append(C @ S)
                elif j == 2:
                    reads.append(mid[pos])
                else:
                    reads.append(read(k, lk, pos, a_k))
                    if j == 1:
                        mid[pos] = reads[-1]
            u_hat = P * (reads[0] - X) + D * (reads[1] - V) + F
            u, on, empty = barrier_commands(X, V, u_hat, safe, rate, pairs, memory)
            acted |= bool(on.any())
            if j == 0:
                active[k], squeezed[k] = on, empty
            return u

        u1 = command(0, x, v)
        a_k[:] = u1
        h = 0.5 * dt
        X2, V2 = x + h * v, v + h * u1
        u2 = command(1, X2, V2)
        X3, V3 = x + h * V2, v + h * u2
        u3 = command(2, X3, V3)
        X4, V4 = x + dt * V3, v + dt * u3
        u4 = command(3, X4, V4)
        H[pad + k + 1, :n] = u1
        H[pad + k + 1, n : 2 * n] = x + (dt / 6.0) * (v + 2.0 * (V2 + V3) + V4)
        H[pad + k + 1, 2 * n :] = v + (dt / 6.0) * (u1 + 2.0 * (u2 + u3) + u4)
        return acted

    k, size, done = 0, 1, steps + 1
    while k <= steps:
        if progress is not None and k % 1000 == 0:
            progress(k, steps)
        seg, begin = segment(k), k
        m = min(size, seg.block, next_change(k) - k, steps + 1 - k)
        seg.advance(H, pad, k, m)
        st = seg.stage_states(H, pad, k, m).reshape(m, 4, 3, n, 2)
        acts = binds(st[:, :, 0], st[:, :, 1], st[:, :, 2], safe, rate, pairs).any(axis=1)
        first = int(np.argmax(acts)) if acts.any() else m
        k += first
        if first < m:
            size = 1
            while k <= steps and filtered_step(k):
                k += 1
            k += 1  # the last filtered step did not act, or the run ended
        else:
            size = min(2 * size, seg.block)
        top = min(k, steps + 1)
        if not np.abs(H[pad + begin + 1 : pad + top + 1]).max(initial=0.0) <= limit:  # also NaN
            done = begin
            break

    last = max(0, min(steps, done - 1))
    saved = np.arange(0, last + 1, save_every)
    if saved[-1] != last:
        saved = np.append(saved, last)
    return Samples(
        times=saved * dt, positions=H[pad + saved, n : 2 * n], velocities=H[pad + saved, 2 * n :],
        accelerations=H[pad + saved + 1, :n],
        extras={"safety_active": active[saved].astype(float), "safety_infeasible": squeezed[saved].astype(float)},
        states=None, stopped=None if done > steps else done * dt,
    )  # fmt: skip

