"""Polishing the family's roots on q itself: Halley and Newton steps, vectorized over rows.

Seeds (continuation predictions or eigenvalues of a discretization) are polished
on q (:mod:`delayform.analysis.roots.family.rows`); Maehly's deflation q / s in the centroid
rows (paper, eq. 4) keeps the persistent zero away. A converged root is accepted by a
Taylor bound of its residual, without evaluating q once more.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.roots.problem import RESIDUAL_TOL
from delayform.analysis.roots.family.rows import Gain, _at, _Rows


#: Newton steps of the fast path (a seed still moving after them is left to the fallback).
_FAST_NEWTON_STEPS = 16
#: Seeds up to which Newton iterates all of them together (no gathering of the active ones).
_FEW_SEEDS = 64


# =====================================================================
# q, dq/ds and the term moduli of the family
# =====================================================================
# Far-left seeds and lines overflow e^{-tau s}; such values fail the residual
# test or the certificate, so the entry points (family_rightmost, family_grid)
# silence floating-point warnings once instead of in every vectorized step.
def _q(
    s: NDArray[np.complex128], lam: NDArray[np.complex128], t1: NDArray[np.float64],
    t2: NDArray[np.float64], P: Gain, D: Gain,
) -> tuple[NDArray[np.complex128], NDArray[np.complex128], NDArray[np.complex128], NDArray[np.complex128]]:
    """q(s), dq/ds and the two delayed terms lam P e^{-tau1 s}, lam D e^{-tau2 s} (broadcasting)."""
    a = lam * P * np.exp(-t1 * s)
    b = lam * D * np.exp(-t2 * s)
    bs = b * s
    q = (s + D) * s + P - a - bs
    dq = 2.0 * s + D + t1 * a - b + t2 * bs
    return q, dq, a, b


def _polish_rows(seeds: NDArray[np.complex128], rows: _Rows) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """Halley's method on q from seeds (R, K) (on q / s, Maehly's deflation, in the centroid rows).

    Returns the roots and whether each has relative residual <= RESIDUAL_TOL
    (as :func:`delayform.analysis.roots.problem._polish`; seeds that reach s ~ 0 in a
    deflated row are rejected, the generic path settles a double zero). A few seeds
    (one delay pair) go through :func:`_newton_few` instead.

    The residual of the last iterate s' = s - step is bounded without evaluating
    q there: by Taylor's theorem on the segment [s, s'],

        |q(s')| <= |q(s) - q'(s) step| + |step|^2 / 2 max |q''|,

    the first term is computed from the values at hand (about |q''| |step|^2 / 2 for Halley's step), and
    |q''| <= 2 + tau1^2 |a| + 2 tau2 |b| + tau2^2 |b| |s| with |a|, |b| grown by
    e^{tau |step|} along the segment (a, b the delayed terms). So a converged seed costs
    one evaluation of q fewer.
    """
    R, K = seeds.shape
    flat = seeds.ravel()
    live = np.flatnonzero(np.isfinite(flat))  # NaN seeds (padding) cost nothing
    rid = live // K
    s = np.take(flat, live)
    P, D = _at(rows.P, rid), _at(rows.D, rid)  # per seed when the rows have their own gains
    lam, t1, t2, defl = (np.take(x, rid) for x in (rows.lam, rows.t1, rows.t2, rows.deflate))
    if s.size <= _FEW_SEEDS:
        s, ok = _newton_few(s, lam, t1, t2, defl, P, D)
        act = np.zeros(0, dtype=np.int64)
    else:
        ok = np.zeros(s.size, dtype=bool)
        act = np.arange(s.size)
    for _ in range(_FAST_NEWTON_STEPS if act.size else 0):
        if act.size == 0:
            break
        sa, la, t1a, t2a, da = (np.take(x, act) for x in (s, lam, t1, t2, defl))
        Pa, Da = _at(P, act), _at(D, act)
        q, dq, a, b = _q(sa, la, t1a, t2a, Pa, Da)
        step, cubic = _halley_step(sa, q, dq, a, b, t1a, t2a, da)
        bad = ~np.isfinite(step)
        step[bad] = 0.0
        s[act] = sa - step
        abs_s, abs_h = np.abs(sa), np.abs(step)
        # after a Halley step below 1e-7 |s| the error is ~1e-21 |s|^3 (cubic convergence), after
        # a Newton step below 1e-8 |s| ~1e-16 |s| (quadratic)
        done = bad | (abs_h <= np.where(cubic, 1e-7, 1e-8) * (1.0 + abs_s))
        if done.any():
            i = np.flatnonzero(done & ~bad)
            h, z, ab = abs_h[i], abs_s[i], np.abs(b[i])
            ea = np.abs(a[i]) * np.exp(t1a[i] * h)
            eb = ab * np.exp(t2a[i] * h)
            m2 = 2.0 + t1a[i] ** 2 * ea + t2a[i] * eb * (2.0 + t2a[i] * (z + h))
            lin = np.abs(q[i] - dq[i] * step[i])
            bound = lin + 0.5 * m2 * h * h
            mag = (z + _at(Da, i)) * z + _at(Pa, i) + np.abs(a[i]) + ab * z
            ok[act[i]] = np.isfinite(mag) & (bound <= RESIDUAL_TOL * mag)
            act = act[~done]
    if act.size:  # still moving after the budget: judged by the residual where it stopped
        Pa, Da = _at(P, act), _at(D, act)
        q, _, a, b = _q(s[act], lam[act], t1[act], t2[act], Pa, Da)
        z = np.abs(s[act])
        mag = (z + Da) * z + Pa + np.abs(a) + np.abs(b) * z
        ok[act] = np.isfinite(mag) & (np.abs(q) <= RESIDUAL_TOL * mag)
    abs_s = np.abs(s)
    # s ~ 0 in a centroid row is a root of q(s)/s when 0 is double (q'(0) = 0, as at
    # tau1 = 0); it is then exactly 0 (as _quasi._deflated_zero decides)
    near = defl & (abs_s < 1e-6)
    if near.any():
        lz = lam[near]
        # q'(0) = tau1 lam P + D (1 - lam), exactly 0 for the centroid (lam = 1) at tau1 = 0; a
        # tiny tau1 puts a genuine root beside 0, which the generic path resolves (rejected here)
        double = t1[near] * lz * _at(P, np.flatnonzero(near)) + _at(D, np.flatnonzero(near)) * (1.0 - lz) == 0.0
        s[near] = np.where(double, 0.0, s[near])
        ok[near] = double
    return _scatter(live, s, ok, (R, K))


def _scatter(
    live: NDArray[np.int64], s: NDArray[np.complex128], ok: NDArray[np.bool_], shape: tuple[int, int]
) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """The polished live seeds back in the seeds' (R, K) layout: NaN and not accepted where there was none."""
    out = np.full(shape[0] * shape[1], np.nan + 0j)
    out[live] = s
    good = np.zeros(out.size, dtype=bool)
    good[live] = ok
    return out.reshape(shape), good.reshape(shape)


def _halley_step(
    s: NDArray[np.complex128], q: NDArray[np.complex128], dq: NDArray[np.complex128], a: NDArray[np.complex128],
    b: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64], deflate: NDArray[np.bool_],
) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """Halley's step on g = q (g = q / s in deflated rows), Newton's where Halley's correction is large; which one.

    q'' = 2 - tau1^2 a + tau2 b (2 - tau2 s) costs a few products of values already at hand;
    the step g g' / (g'^2 - g g'' / 2) converges cubically, so a seed predicted to 1e-4
    is exact after one step and confirmed by the next: one evaluation of q fewer than Newton.
    """
    d2 = 2.0 - t1 * t1 * a + t2 * b * (2.0 - t2 * s)
    # one complex division: g g' / (g'^2 - g g'' / 2); Halley's where |g g''| < |g'|^2
    gg1, gg2, dq2 = q * dq, q * d2, dq * dq
    i = np.flatnonzero(deflate)
    if i.size:  # g = q / s: g' = (q' - g) / s, g'' = (q'' - 2 g') / s
        si = s[i]
        g = q[i] / si
        g1 = (dq[i] - g) / si
        gg1[i], gg2[i], dq2[i] = g * g1, g * ((d2[i] - 2.0 * g1) / si), g1 * g1
    cubic = np.abs(gg2) < np.abs(dq2)
    step = gg1 / (dq2 - 0.5 * gg2)
    newton = np.flatnonzero(~cubic)
    if newton.size:  # g / g' = g g' / g'^2
        step[newton] = gg1[newton] / dq2[newton]
    return step, cubic


def _newton_few(
    s: NDArray[np.complex128], lam: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64],
    defl: NDArray[np.bool_], P: Gain, D: Gain,
) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """:func:`_polish_rows`'s Newton on a few seeds, one at a time in plain Python.

    On a dozen seeds (one delay pair) a NumPy call costs more than its arithmetic;
    Python's complex numbers do the same steps and tests at a fraction of the cost.
    """
    n = s.size
    Ps = P.tolist() if isinstance(P, np.ndarray) else [P] * n
    Ds = D.tolist() if isinstance(D, np.ndarray) else [D] * n
    out = [_newton_one(*args) for args in zip(s.tolist(), lam.tolist(), t1.tolist(), t2.tolist(), defl.tolist(), Ps, Ds)]
    roots = np.array([r for r, _ in out], dtype=np.complex128)
    return roots, np.array([g for _, g in out], dtype=bool)


def _newton_one(s: complex, lam: complex, t1: float, t2: float, deflate: bool, P: float, D: float) -> tuple[complex, bool]:
    """Newton (Maehly's step if ``deflate``) from s on q; (root, accepted) as in :func:`_polish_rows`.

    The acceptance is tested from the second step on: seeds are eigenvalues of a
    discretization, never converged to 1e-8.
    """
    lp, ld = lam * P, lam * D
    try:
        for k in range(_FAST_NEWTON_STEPS):
            a = lp * cmath.exp(-t1 * s)
            b = ld * cmath.exp(-t2 * s)
            bs = b * s
            q = (s + D) * s + P - a - bs
            dq = 2.0 * s + D + t1 * a - b + t2 * bs
            step = q / (dq - q / s if deflate else dq)
            h = abs(step)
            if not math.isfinite(h):
                return s, False
            if k:
                z = abs(s)
                if h <= 1e-8 * (1.0 + z) and (t1 + t2) * h <= 0.69:
                    aa, ab = abs(a), abs(b)
                    # |q''| on the step's segment, e^{tau |step|} <= 2 for the growth of a, b
                    m2 = 2.0 + 2.0 * (t1 * t1 * aa + t2 * ab * (2.0 + t2 * (z + h)))
                    bound = abs(q - dq * step) + 0.5 * m2 * h * h
                    if bound <= RESIDUAL_TOL * ((z + D) * z + P + aa + ab * z):
                        return s - step, True
            s = s - step
    except (OverflowError, ZeroDivisionError):
        pass
    return s, False
