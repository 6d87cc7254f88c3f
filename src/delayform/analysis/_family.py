"""Certified rightmost roots of all factors of eq. factorized at many delay pairs at once.

Every factor of eq. factorized is (for a conjugate pair, through its complex
second-order factor of lam) the same quasi-polynomial

    q(s) = s^2 + D s + P - lam (P e^{-tau1 s} + D s e^{-tau2 s})

with its own eigenvalue lam of C. So one *row* -- a factor at a delay pair --
is described by (lam, tau1, tau2), and Newton's method, the line choice and
the argument-principle certificate of :mod:`delayform.analysis.certificate`
run on flat arrays of rows, all factors and all delay pairs in one NumPy
expression each. The generic per-factor code pays a Python round trip per
term and per factor; here q, dq/ds, the Lipschitz bound and the Cauchy radius
are written out for this family (the same formulas, specialized).

A map is solved by continuation: the delay grid is visited coarse to fine
(:data:`_LEVELS`); the first level is seeded by the Chebyshev discretization
of the generator, every later point by the roots of its nearest solved point.
Every row is certified; rows whose certificate fails are redone by the
generic batched path and, rarely, the robust single-pair path, exactly as
before. A single delay pair discretizes all factors in one stacked eigenvalue
call, whose matrices depend on lam only through their last row (cached per delays).
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Callable, Sequence
from functools import lru_cache, partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.analysis._generator import _chebyshev, _igd_seeds, _lagrange_rows
from delayform.analysis._quasi import _TINY_DELAY, MAX_DEGREE, RESIDUAL_TOL, _problem_of_factor
from delayform.analysis._rightmost import (
    _BATCH_SEEDS,
    _certify,
    _pick_rightmost,
    _solve_rightmost,
)
from delayform.analysis.certificate import _LINE_OFFSET, _choose_line
from delayform.characteristic import CharacteristicFactor

try:  # the gufunc behind np.linalg.eigvals (see _eigvals)
    from numpy.linalg._umath_linalg import eigvals as _LAPACK_EIGVALS
except ImportError:  # pragma: no cover - NumPy moved its private kernel
    _LAPACK_EIGVALS = None

#: Grid strides visited coarse to fine; the first level is seeded by discretization.
_LEVELS = (27, 9, 3, 1)
#: Known roots kept per row as seeds for its neighbours.
_KEEP = 4
#: Seeds polished per row: those within this distance of the row's rightmost seed. The line
#: usually lies within 0.1 (certificate._LINE_OFFSET) of the rightmost root, so deeper roots
#: mostly cost Newton steps; a root a dropped seed would have found fails the certificate and
#: the row is redone (paper team: 0 of 300 random single pairs, 5 of 50,000 map rows redone).
_SEED_WINDOW = 0.3
#: Newton steps of the fast path (a seed still moving after them is left to the fallback).
_FAST_NEWTON_STEPS = 16
#: Rows of the walk's samples at its two ends (top, bottom), for the tails.
_ENDS = np.array([-1, 0])
#: Seeds up to which Newton iterates all of them together (no gathering of the active ones).
_FEW_SEEDS = 64
#: Rows certified together in a map (larger batches fall out of the processor's cache).
_CHUNK_ROWS = 8192
#: Rows (factors at one delay pair) up to which the line choice runs in plain Python.
_FEW_ROWS = 16
#: Initial samples of the certified walk along Re s = c (bisected where needed).
_INITIAL_SAMPLES = 12


class _Rows:
    """Flat arrays describing rows (factor, delay pair): lam, tau1, tau2 and two flags."""

    __slots__ = ("lam", "t1", "t2", "real", "deflate", "P", "D")

    def __init__(
        self, lam: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64],
        real: NDArray[np.bool_], deflate: NDArray[np.bool_], P: float, D: float,
    ) -> None:
        self.lam, self.t1, self.t2, self.real, self.deflate = lam, t1, t2, real, deflate
        self.P, self.D = P, D

    def take(self, idx: NDArray[np.int64]) -> _Rows:
        return _Rows(self.lam[idx], self.t1[idx], self.t2[idx], self.real[idx], self.deflate[idx], self.P, self.D)

    @property
    def size(self) -> int:
        return int(self.lam.size)


@lru_cache(maxsize=16)
def _lams(fs: tuple[CharacteristicFactor, ...]) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.bool_]]:
    """(lam, real lam, centroid) per factor; cached per factor tuple (read-only arrays)."""
    lam = np.array([complex(f.lam) for f in fs], dtype=np.complex128)
    real = ~np.array([f.group.is_complex_pair for f in fs], dtype=bool)
    centroid = np.array([f.is_centroid for f in fs], dtype=bool)
    for a in (lam, real, centroid):
        a.flags.writeable = False
    return lam, real, centroid


# =====================================================================
# q, dq/ds and the term moduli of the family
# =====================================================================
# Far-left seeds and lines overflow e^{-tau s}; such values fail the residual
# test or the certificate, so the entry points (family_rightmost, family_grid)
# silence floating-point warnings once instead of in every vectorized step.
def _q(
    s: NDArray[np.complex128], lam: NDArray[np.complex128], t1: NDArray[np.float64],
    t2: NDArray[np.float64], P: float, D: float,
) -> tuple[NDArray[np.complex128], NDArray[np.complex128], NDArray[np.complex128], NDArray[np.complex128]]:
    """q(s), dq/ds and the two delayed terms lam P e^{-tau1 s}, lam D e^{-tau2 s} (broadcasting)."""
    a = lam * P * np.exp(-t1 * s)
    b = lam * D * np.exp(-t2 * s)
    bs = b * s
    q = (s + D) * s + P - a - bs
    dq = 2.0 * s + D + t1 * a - b + t2 * bs
    return q, dq, a, b


def _polish_rows(seeds: NDArray[np.complex128], rows: _Rows) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """Newton on q from seeds (R, K); Maehly's step q / (q' - q/s) for the centroid rows.

    Returns the roots and whether each has relative residual <= RESIDUAL_TOL
    (as :func:`delayform.analysis._quasi._polish`; seeds that reach s ~ 0 in a
    deflated row are rejected, the generic path settles a double zero).

    The residual of the last iterate s' = s - step is bounded without evaluating
    q there: by Taylor's theorem on the segment [s, s'],

        |q(s')| <= |q(s) - q'(s) step| + |step|^2 / 2 max |q''|,

    the first term is 0 for Newton's step (rounding) and |step q(s) / s| for Maehly's, and
    |q''| <= 2 + tau1^2 |a| + 2 tau2 |b| + tau2^2 |b| |s| with |a|, |b| grown by
    e^{tau |step|} along the segment (a, b the delayed terms). So a converged seed costs
    one evaluation of q fewer.
    """
    R, K = seeds.shape
    flat = seeds.ravel()
    live = np.flatnonzero(np.isfinite(flat))  # NaN seeds (padding) cost nothing
    rid = live // K
    s = np.take(flat, live)
    P, D = rows.P, rows.D
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
        q, dq, a, b = _q(sa, la, t1a, t2a, P, D)
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
            mag = (z + D) * z + P + np.abs(a[i]) + ab * z
            ok[act[i]] = np.isfinite(mag) & (bound <= RESIDUAL_TOL * mag)
            act = act[~done]
    if act.size:  # still moving after the budget: judged by the residual where it stopped
        q, _, a, b = _q(s[act], lam[act], t1[act], t2[act], P, D)
        z = np.abs(s[act])
        mag = (z + D) * z + P + np.abs(a) + np.abs(b) * z
        ok[act] = np.isfinite(mag) & (np.abs(q) <= RESIDUAL_TOL * mag)
    abs_s = np.abs(s)
    # s ~ 0 in a centroid row is a root of q(s)/s when 0 is double (q'(0) = 0, as at
    # tau1 = 0); it is then exactly 0 (as _quasi._deflated_zero decides)
    near = defl & (abs_s < 1e-6)
    if near.any():
        lz = lam[near]
        # q'(0) = tau1 lam P + D (1 - lam), exactly 0 for the centroid (lam = 1) at tau1 = 0; a
        # tiny tau1 puts a genuine root beside 0, which the generic path resolves (rejected here)
        double = t1[near] * lz * P + D * (1.0 - lz) == 0.0
        s[near] = np.where(double, 0.0, s[near])
        ok[near] = double
    out = np.full(R * K, np.nan + 0j)
    out[live] = s
    good = np.zeros(R * K, dtype=bool)
    good[live] = ok
    return out.reshape(R, K), good.reshape(R, K)


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
    defl: NDArray[np.bool_], P: float, D: float,
) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """:func:`_polish_rows`'s Newton on a few seeds, one at a time in plain Python.

    On a dozen seeds (one delay pair) a NumPy call costs more than its arithmetic;
    Python's complex numbers do the same steps and tests at a fraction of the cost.
    """
    out = [_newton_one(*args, P, D) for args in zip(s.tolist(), lam.tolist(), t1.tolist(), t2.tolist(), defl.tolist())]
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


# =====================================================================
# the certificate, vectorized over rows (same bounds as certificate.py)
# =====================================================================
def _chord_ok(
    qa: NDArray[np.complex128], qb: NDArray[np.complex128], quad2: NDArray[np.float64],
    qa2: NDArray[np.float64] | None = None, qb2: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.complex128]]:
    """The chord test of :func:`_count_rows`: segments whose chord [q_a, q_b] keeps off 0 by more than sqrt(quad2).

    From t = q_b conj(q_a): the chord's point nearest 0 lies inside it when Re t < |q_a|^2
    and Re t < |q_b|^2, at distance |Im t| / |q_b - q_a|; otherwise the nearer end is the
    nearest point. Returns the accepted segments and t, whose argument is the segment's
    change of arg q where accepted. |q_a|^2, |q_b|^2 may be passed when already known.
    """
    if qa2 is None:
        qa2 = qa.real * qa.real + qa.imag * qa.imag
    if qb2 is None:
        qb2 = qb.real * qb.real + qb.imag * qb.imag
    turn = qb * np.conj(qa)
    dd = qa2 + qb2 - 2.0 * turn.real  # |q_b - q_a|^2
    inside = (turn.real < qa2) & (turn.real < qb2)
    good = np.where(inside, turn.imag * turn.imag > quad2 * dd, np.minimum(qa2, qb2) > quad2)
    return good, turn


def _quad2(
    rho: NDArray[np.float64], h: Any, m2_slope: Any, m2_offset: Any
) -> NDArray[np.float64]:
    """(M2 h^2 / 8)^2: the squared bound of |q - chord| on a segment of length h within |s| <= rho."""
    quad = (m2_slope * rho + m2_offset) * (0.125 * h * h)
    return quad * quad  # type: ignore[no-any-return]


class _Walk:
    """The lines Re s = c of a walk: what bisecting a rejected segment needs (see :func:`_count_rows`)."""

    def __init__(
        self, c: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64], A1: NDArray[np.complex128],
        B1: NDArray[np.complex128], m2_slope: NDArray[np.float64], m2_offset: NDArray[np.float64], P: float, D: float,
    ) -> None:
        self.c, self.t1, self.t2, self.A1, self.B1 = c, t1, t2, A1, B1
        self.m2_slope, self.m2_offset, self.P, self.D = m2_slope, m2_offset, P, D

    def bisect(
        self, total: NDArray[np.float64], failed: NDArray[np.bool_], line: NDArray[np.int64], wa: NDArray[np.float64],
        qa: NDArray[np.complex128], qb: NDArray[np.complex128], ka: NDArray[np.complex128], kb: NDArray[np.complex128],
        h: NDArray[np.float64], max_segments: int,
    ) -> None:
        """Bisect the rejected segments [c + i wa, c + i (wa + h)] of each line until the chord test accepts them.

        Adds 2 pi times their crossings of the branch cut of Arg (:func:`_cut_crossings`) to
        ``total`` -- the rest of their change of arg q telescopes to the Arg of the rejected
        segments' ends, which the caller has counted -- and marks in ``failed`` the lines that
        need more than ``max_segments`` segments, 52 halvings, or meet a zero or an
        overflow of q. ``ka``, ``kb``: e^{-i tau1 wa}, e^{-i tau2 wa} (rotated, not recomputed).
        """
        c, t1, t2, A1, B1, P, D = self.c, self.t1, self.t2, self.A1, self.B1, self.P, self.D
        n = c.size
        c2 = c * c
        step = h.copy()
        for _ in range(52):
            if line.size == 0:
                return
            too_many = np.bincount(line, minlength=n) > max_segments
            if too_many.any():
                failed |= too_many
                keep = ~too_many[line]
                line, wa, qa, qb, ka, kb = line[keep], wa[keep], qa[keep], qb[keep], ka[keep], kb[keep]
            step = 0.5 * step
            take = partial(np.take, indices=line)  # 1-D gathers: np.take beats fancy indexing
            wm = wa + take(step)
            # the midpoints' unit factors: one rotation per line still walking (not per line of the batch)
            walking = np.zeros(n, dtype=bool)
            walking[line] = True
            wl = np.flatnonzero(walking)
            rot1, rot2 = np.empty(n, dtype=np.complex128), np.empty(n, dtype=np.complex128)
            rot1[wl] = np.exp(-1j * (t1[wl] * step[wl]))
            rot2[wl] = np.exp(-1j * (t2[wl] * step[wl]))
            km, kbm = ka * take(rot1), kb * take(rot2)
            sm = take(c) + 1j * wm
            qm = (sm + D) * sm + P - take(A1) * km - (take(B1) * kbm) * sm
            failed[line[~np.isfinite(qm) | (qm == 0.0)]] = True
            line = np.concatenate([line, line])
            take = partial(np.take, indices=line)
            wa = np.concatenate([wa, wm])
            qa, qb = np.concatenate([qa, qm]), np.concatenate([qm, qb])
            ka, kb = np.concatenate([ka, km]), np.concatenate([kb, kbm])
            hl = take(step)
            rho = np.sqrt(take(c2) + np.maximum(wa * wa, (wa + hl) ** 2))
            good, turn = _chord_ok(qa, qb, _quad2(rho, hl, take(self.m2_slope), take(self.m2_offset)))
            cut = _cut_crossings(np.signbit(qa.imag), np.signbit(qb.imag), turn.imag)
            g = np.flatnonzero(good)
            total += (2.0 * np.pi) * np.bincount(np.take(line, g), np.take(cut, g), minlength=n)
            bad = np.flatnonzero(~good)
            line, wa, qa, qb, ka, kb = (np.take(x, bad) for x in (line, wa, qa, qb, ka, kb))
        failed[line] = True


def _count_rows(
    rows: _Rows, c: NDArray[np.float64], *, max_segments: int = 4096
) -> NDArray[np.float64]:
    """Certified number of roots of q with Re s > c per row (NaN: not certified).

    The walk of :func:`delayform.analysis.certificate._count_right_batch` with
    a chord test: on the line Re s = c the delayed terms have constant moduli
    E1 = |lam| P e^{-tau1 c}, E2 = |lam| D e^{-tau2 c}, so

        |q''(s)| <= M2 = 2 + tau1^2 E1 + 2 tau2 E2 + tau2^2 E2 rho   (|s| <= rho),

    and on a segment [s_a, s_b] of length h q differs from its chord
    (the linear interpolation of q(s_a), q(s_b)) by at most M2 h^2 / 8 (the
    Green's function of the second derivative). A segment is accepted when the
    chord keeps a distance greater than that from 0: then q does not vanish on
    it and arg q stays within pi / 2 of the chord's argument, which is exact at
    both ends, so the segment's change of arg q is exactly Arg(q(s_b) / q(s_a)).
    Near a root at distance delta from the line this accepts steps of order
    sqrt(delta) instead of the first-order test's delta, and needs no q'.
    The line is closed at infinity by the Cauchy radius (root of
    ``r^2 = (D + E2) r + P + E1``, Rouche). Rows with real lam walk Im s >= 0
    only (q(conj s) = conj q(s)).

    On the line e^{-tau s} = e^{-tau c} e^{-i tau w}: the unit factors are
    carried along the uniform initial samples by repeated rotation, and all
    segments bisected in round k have the same length per line, so their
    midpoints need one rotation per line and round instead of two complex
    exponentials per sample.
    """
    P, D = rows.P, rows.D
    n = c.size
    lam, t1, t2 = rows.lam, rows.t1, rows.t2
    x1, x2 = np.exp(-t1 * c), np.exp(-t2 * c)
    A1, B1 = lam * (P * x1), lam * (D * x2)  # a = A1 e^{-i tau1 w}, b = B1 e^{-i tau2 w}
    absl = np.abs(lam)
    E1, E2 = absl * P * x1, absl * D * x2
    b1, b0 = D + E2, P + E1
    omega = (b1 + np.sqrt(b1 * b1 + 4.0 * b0)) / 2.0 * (1.0 + 1e-9) + 1e-12
    m2_slope, m2_offset = t2 * t2 * E2, 2.0 + t1 * t1 * E1 + 2.0 * t2 * E2
    lo = np.where(rows.real, 0.0, -omega)
    if n <= 64:  # few lines: the Python cost of a bisection round outweighs extra samples
        sizes = np.full(n, 4 * _INITIAL_SAMPLES)
    else:  # samples in proportion to how far e^{-i tau w} turns along the walk (about 1.8 rad apart)
        turn = np.maximum(t1, t2) * (omega - lo)
        sizes = _WALK_SIZES[np.minimum(np.searchsorted(_WALK_SIZES, turn / 1.8 + 2.0), _WALK_SIZES.size - 1)]
    h = (omega - lo) / (sizes - 1)
    total = np.zeros(n)
    failed = np.zeros(n, dtype=bool)
    ends = np.empty((2, n), dtype=np.complex128)  # q at the top and the bottom end of each walk
    rejected = []
    buckets = np.unique(sizes)
    for m in buckets:
        idx = np.flatnonzero(sizes == m) if buckets.size > 1 else np.arange(n)
        tot, fail, q_ends, rej = _walk_uniform(
            int(m), c[idx], t1[idx], t2[idx], lo[idx], h[idx], A1[idx], B1[idx], m2_slope[idx], m2_offset[idx], P, D
        )
        total[idx], failed[idx], ends[:, idx] = tot, fail, q_ends
        if rej is not None:
            rejected.append((idx[rej[0]],) + rej[1:])
    if rejected:
        line, wa, qa, qb, ka, kb = (np.concatenate(parts) for parts in zip(*rejected))
        _Walk(c, t1, t2, A1, B1, m2_slope, m2_offset, P, D).bisect(total, failed, line, wa, qa, qb, ka, kb, h, max_segments)
    # tails beyond +-Omega: arg q = arg g1 + Arg(q / g1), g1 = s^2 + D s + P (Rouche)
    # (the walk's end points are c + i Omega and c + i lo; real rows use only the top one)
    z = _free_roots(P, D)
    e = c + 1j * omega  # the top end
    top = (np.pi / 2 - np.angle(e[:, None] - z)).sum(axis=-1) - np.angle(ends[0] / ((e + D) * e + P))
    delta = 2.0 * (total + top)
    cx = np.flatnonzero(~rows.real)
    if cx.size:  # complex lam: the whole line, and the bottom tail
        e = c[cx] - 1j * omega[cx]
        bottom = (np.angle(e[:, None] - z) + np.pi / 2).sum(axis=-1) + np.angle(ends[1, cx] / ((e + D) * e + P))
        delta[cx] = total[cx] + top[cx] + bottom
    count = 1.0 - delta / (2.0 * np.pi)
    good = ~failed & np.isfinite(count) & (np.abs(count - np.round(count)) < 0.1)
    return np.where(good, np.round(count), np.nan)


#: Sample counts of a walk's uniform first pass (chosen per line by how far e^{-i tau w} turns).
_WALK_SIZES = np.array([6, 8, 12, 16, 24, 32, 48])


def _walk_uniform(
    m: int, c: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64], lo: NDArray[np.float64],
    h: NDArray[np.float64], A1: NDArray[np.complex128], B1: NDArray[np.complex128],
    m2_slope: NDArray[np.float64], m2_offset: NDArray[np.float64], P: float, D: float,
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.complex128], tuple[NDArray[Any], ...] | None]:
    """The first pass of :func:`_count_rows` over lines sampled at m uniform points each.

    Returns the change of arg q over the accepted segments, the lines that failed (an
    overflow), q at the two ends of each walk, and the rejected segments (line index,
    start w, q at both ends, the unit factors at the start), or None when all passed.
    """
    n = c.size
    w = lo + h * np.arange(m)[:, None]  # (m, n)
    # e^{-i tau (lo + j h)} for both delays by repeated rotation (no exponential per sample)
    zr = np.empty((m, 2, n), dtype=np.complex128)
    tau = np.stack([t1, t2])
    zr[0] = np.exp(-1j * (tau * lo))
    rot = np.exp(-1j * (tau * h))
    if n <= 64:  # few lines: one accumulate call
        zr[1:] = rot
        np.cumprod(zr, axis=0, out=zr)
    else:  # many lines: NumPy's accumulate along axis 0 is not vectorized
        for j in range(1, m):
            np.multiply(zr[j - 1], rot, out=zr[j])
    k1, k2 = zr[:, 0], zr[:, 1]
    sv = np.empty((m, n), dtype=np.complex128)
    sv.real, sv.imag = c, w
    q = sv * (sv + D - B1 * k2) + (P - A1 * k1)
    # an overflow poisons the line's sum; an exact zero of q on a sample fails the chord
    # test of both its segments in every round, so the line ends as not certified
    failed = ~np.isfinite(q.sum(axis=0))
    # the segments are tested in their (m - 1, n) layout (the chord test of _chord_ok with
    # rho = the larger |s| of a segment's ends); only rejected ones are gathered and bisected
    abs_s = np.abs(sv)
    qq = q.real * q.real + q.imag * q.imag
    good, turn = _chord_ok(q[:-1], q[1:], _quad2(np.maximum(abs_s[:-1], abs_s[1:]), h, m2_slope, m2_offset),
                           qq[:-1], qq[1:])  # fmt: skip
    # the change of arg q over the whole walk, whatever its final segments: Arg at the ends plus
    # 2 pi per crossing of Arg's branch cut (accepted segments here, bisected ones in _Walk.bisect)
    lower = np.signbit(q.imag)
    cut = np.where(good, _cut_crossings(lower[:-1], lower[1:], turn.imag), 0).sum(axis=0)
    ends = q[_ENDS]
    total = np.angle(ends[0]) - np.angle(ends[1]) + (2.0 * np.pi) * cut
    rejected = None
    if not good.all():
        j, line = np.nonzero(~good)
        rejected = (line, w[j, line], q[j, line], q[j + 1, line], k1[j, line], k2[j, line])
    return total, failed, ends, rejected


def _cut_crossings(
    lower_a: NDArray[np.bool_], lower_b: NDArray[np.bool_], turn_imag: NDArray[np.float64]
) -> NDArray[np.int64]:
    """+1 / -1 where a segment of q's path crosses Arg's branch cut (the negative reals) counterclockwise / clockwise.

    For a segment whose change of arg q lies in (-pi, pi) (every segment the chord test
    accepts) the change is Arg(q_b) - Arg(q_a) + 2 pi times this; counterclockwise
    (Im(q_b conj(q_a)) > 0) from Im q >= 0 to Im q < 0 passes the negative reals, and the
    reverse. ``lower``: the sign bit of Im q, the branch NumPy's Arg follows for -0.0.
    """
    ccw = turn_imag > 0.0
    return (~lower_a & lower_b & ccw).astype(np.int64) - (lower_a & ~lower_b & (turn_imag < 0.0))


def _count_few(rows: _Rows, c: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`_count_rows` for a few rows: per-row constants and the tails in plain Python.

    The same walk (4 x the initial samples, chord test, Cauchy radius, tails) with only
    the samples along the lines in NumPy; rows whose walk needs a bisection are handed
    to :func:`_count_rows`.
    """
    P, D = rows.P, rows.D
    m = 4 * _INITIAL_SAMPLES
    n = c.size
    consts, cplx = [], []
    try:
        for lam, t1, t2, real, ci in zip(rows.lam.tolist(), rows.t1.tolist(), rows.t2.tolist(),
                                         rows.real.tolist(), c.tolist()):  # fmt: skip
            x1, x2 = math.exp(-t1 * ci), math.exp(-t2 * ci)
            al = abs(lam)
            E1, E2 = al * P * x1, al * D * x2
            b1 = D + E2
            omega = (b1 + math.sqrt(b1 * b1 + 4.0 * (P + E1))) / 2.0 * (1.0 + 1e-9) + 1e-12
            lo = 0.0 if real else -omega
            h = (omega - lo) / (m - 1)
            consts.append((ci, lo, h, t2 * t2 * E2, 2.0 + t1 * t1 * E1 + 2.0 * t2 * E2, 0.125 * h * h, omega))
            cplx.append((lam * (P * x1), lam * (D * x2), -1j * t1, -1j * t2))
    except OverflowError:  # a line far left of long delays: the general walk refuses it
        return _count_rows(rows, c)
    cc, lo, h, m2_slope, m2_offset, h2, omega = np.array(consts).T
    A1, B1, i1, i2 = np.array(cplx).T
    w = lo + h * _sample_index(m)
    sv = cc + 1j * w
    k1, k2 = np.exp(i1 * w), np.exp(i2 * w)
    q = sv * (sv + D - B1 * k2) + (P - A1 * k1)
    abs_s = np.abs(sv)
    quad = (m2_slope * np.maximum(abs_s[:-1], abs_s[1:]) + m2_offset) * h2
    good, turn = _chord_ok(q[:-1], q[1:], quad * quad)
    if good.all():
        total = np.arctan2(turn.imag, turn.real).sum(axis=0)
        failed = None
    else:  # the rejected segments' change: Arg at their ends here, their crossings in bisect
        arg = np.angle(q)
        total = np.where(good, np.arctan2(turn.imag, turn.real), arg[1:] - arg[:-1]).sum(axis=0)
        failed = ~np.isfinite(q.sum(axis=0))
        j, line = np.nonzero(~good)
        _Walk(cc, rows.t1, rows.t2, A1, B1, m2_slope, m2_offset, P, D).bisect(
            total, failed, line, w[j, line], q[j, line], q[j + 1, line], k1[j, line], k2[j, line], h, 4096
        )
    z1, z2 = _free_roots(P, D).tolist()
    counts = np.full(n, np.nan)
    for i, (tot, q_top, q_bot, real, (ci, _, _, _, _, _, om)) in enumerate(
        zip(total.tolist(), q[-1].tolist(), q[0].tolist(), rows.real.tolist(), consts)
    ):
        # tails beyond +-Omega: arg q = arg g1 + Arg(q / g1), g1 = s^2 + D s + P (Rouche)
        e = complex(ci, om)
        top = math.pi - cmath.phase(e - z1) - cmath.phase(e - z2) - cmath.phase(q_top / ((e + D) * e + P))
        if real:
            delta = 2.0 * (tot + top)
        else:
            e = complex(ci, -om)
            bottom = math.pi + cmath.phase(e - z1) + cmath.phase(e - z2) + cmath.phase(q_bot / ((e + D) * e + P))
            delta = tot + top + bottom
        count = 1.0 - delta / (2.0 * math.pi)
        if math.isfinite(count) and abs(count - round(count)) < 0.1 and (failed is None or not failed[i]):
            counts[i] = round(count)
    return counts


@lru_cache(maxsize=8)
def _sample_index(m: int) -> NDArray[np.float64]:
    """0, 1, ..., m - 1 as a column (read-only): the sample positions of a walk."""
    j = np.arange(m, dtype=np.float64)[:, None]
    j.flags.writeable = False
    return j


@lru_cache(maxsize=64)
def _free_roots(P: float, D: float) -> NDArray[np.complex128]:
    """The roots of g1 = s^2 + D s + P (the tails' comparison polynomial), read-only."""
    disc = cmath.sqrt(D * D - 4.0 * P)
    z = np.array([(-D + disc) / 2.0, (-D - disc) / 2.0])
    z.flags.writeable = False
    return z


def _certify_rows(
    rows: _Rows, seeds: NDArray[np.complex128], fresh: int = 0, window: float = _SEED_WINDOW
) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.complex128]]:
    """Polish seeds (R, K) per row, certify the rightmost: (rightmost, certified, known roots).

    Only seeds within ``window`` of a row's rightmost seed are polished; with ``fresh`` > 0
    the window is set by the rightmost of the first ``fresh`` columns (a redo's new
    discretization seeds: a stale seed that converges nowhere would drop the good ones).

    The vectorized counterpart of :func:`delayform.analysis._rightmost._certify`
    (same seed window, distinct roots, mirror images and line choice). The
    rightmost root is reported with Im >= 0 (real lam: of a conjugate pair;
    complex lam: the factor of conj(lam) mirrors it).
    """
    if rows.size <= _FEW_ROWS:
        return _certify_few(rows, seeds, fresh, window)
    real = rows.real[:, None]
    seeds = seeds.copy()  # the caller's seeds stay as they are
    np.abs(seeds.imag, out=seeds.imag, where=real)  # real rows: the member of a pair with Im >= 0
    # a seed at the centroid's persistent 0 is moved off it (Maehly's step cannot leave 0) and
    # kept, but it does not set the window: the window then would drop every genuine seed
    moved = rows.deflate[:, None] & (np.abs(seeds) < 1e-6)
    any_moved = bool(moved.any())
    if any_moved:
        seeds[moved] = np.nan
    top_seed = np.fmax.reduce(seeds.real[:, : fresh or None], axis=1)  # NaN (padding) ignored
    seeds[seeds.real < top_seed[:, None] - window] = np.nan
    if any_moved:
        seeds[moved] = -1e-2
    roots, ok = _polish_rows(seeds, rows)
    np.abs(roots.imag, out=roots.imag, where=real)
    right, c, expected, distinct = _lines_of_rows(roots, ok, rows.real, rows.deflate)
    good = np.isfinite(c)
    if good.all():
        counts = _count_rows(rows, c)
    else:
        counts = np.full(rows.size, np.nan)
        idx = np.flatnonzero(good)
        if idx.size:
            counts[idx] = _count_rows(rows.take(idx), c[idx])
    return right, good & (counts == expected), distinct


def _certify_in_chunks(
    rows: _Rows, seeds: NDArray[np.complex128]
) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.complex128]]:
    """:func:`_certify_rows` over chunks of :data:`_CHUNK_ROWS` rows; known roots padded to :data:`_KEEP`.

    The steps are memory-bound NumPy operations on arrays of rows x samples: in chunks
    that stay in the processor's cache a map runs about 15 % faster than in one piece.
    """
    if rows.size <= _CHUNK_ROWS:
        r, ok, roots = _certify_rows(rows, seeds)
        return r, ok, _pad(roots, _KEEP)
    parts = [_certify_rows(rows.take(idx), seeds[idx])
             for idx in np.array_split(np.arange(rows.size), -(-rows.size // _CHUNK_ROWS))]  # fmt: skip
    return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
            np.concatenate([_pad(p[2], _KEEP) for p in parts]))  # fmt: skip


def _lines_of_rows(
    roots: NDArray[np.complex128], ok: NDArray[np.bool_], real: NDArray[np.bool_], deflate: NDArray[np.bool_]
) -> tuple[NDArray[np.complex128], NDArray[np.float64], NDArray[np.float64], NDArray[np.complex128]]:
    """Per row: the rightmost root (Im >= 0), the certifying line, the expected count, the distinct roots.

    The vectorized :func:`delayform.analysis.certificate._choose_line` on the distinct
    accepted roots (sorted; a root within 1e-7 relative of its predecessor dropped), a
    complex root of a real row counted twice (with its mirror image), and the centroid's
    persistent zero added. NaN line: no root accepted.
    """
    R = roots.shape[0]
    rix = np.arange(R)
    r = np.sort(np.where(ok, roots, np.nan), axis=1)  # by real part; NaN last
    if r.shape[1] > 1:
        close = np.abs(r[:, 1:] - r[:, :-1]) <= 1e-7 * (1.0 + np.abs(r[:, :-1]))
        r[:, 1:][close] = np.nan
    x = r.real
    known = x == x  # not NaN
    mult = np.where(known, 1.0 + (real[:, None] & (np.abs(r.imag) > 1e-9 * (1.0 + np.abs(r)))), 0.0)
    key = np.where(known, x, -np.inf)
    best = key.argmax(axis=1)
    top = key[rix, best]
    right = r[rix, best]
    right = right.real + 1j * np.abs(right.imag)
    # usually the rightmost root stands clear of the next (and of the centroid's zero, which
    # then lies right of it): the line goes in that first gap; the other rows take the full rule
    srt = -np.sort(-key, axis=1)  # descending; -inf (none) last
    gap = srt[:, 0] - srt[:, 1] if srt.shape[1] > 1 else np.full(R, np.inf)
    c = top - np.minimum(0.5 * gap, _LINE_OFFSET)
    hard = (gap <= 1e-3 * (1.0 + np.abs(top))) | (deflate & (top >= 0.0))
    if hard.any():
        h = np.flatnonzero(hard)
        c[h] = _choose_lines(np.where(deflate[h, None], np.concatenate([srt[h], np.zeros((h.size, 1))], axis=1),
                                      np.concatenate([srt[h], np.full((h.size, 1), -np.inf)], axis=1)), top[h])
    c[~(top > -np.inf)] = np.nan
    expected = np.where(key > c[:, None], mult, 0.0).sum(axis=1) + (deflate & (0.0 > c))
    return right, c, expected, r


def _choose_lines(key: NDArray[np.float64], top: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`delayform.analysis.certificate._choose_line` per row of known real parts (-inf: none)."""
    R = key.shape[0]
    rix = np.arange(R)
    srt = -np.sort(-key, axis=1)  # descending; -inf (none) last
    width = srt.shape[1]
    n_known = (srt > -np.inf).sum(axis=1)
    k0 = (srt <= top[:, None]).argmax(axis=1)
    c = np.full(R, np.nan)
    if width >= 2:  # the first of the 8 gaps below the top that is wide enough
        gap = srt[:, :-1] - srt[:, 1:]
        pos = np.arange(width - 1)
        take = ((pos >= k0[:, None]) & (pos < np.minimum(k0 + 8, n_known - 1)[:, None])
                & (gap > 1e-3 * (1.0 + np.abs(srt[:, :-1]))))  # fmt: skip
        first = take.argmax(axis=1)
        c = np.where(take[rix, first], srt[rix, first] - np.minimum(0.5 * gap[rix, first], _LINE_OFFSET), c)
    last = srt[rix, np.maximum(np.minimum(k0 + 8, n_known - 1), 0)]
    return np.where(np.isnan(c), last - _LINE_OFFSET, c)


def _certify_few(
    rows: _Rows, seeds: NDArray[np.complex128], fresh: int, window: float
) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.complex128]]:
    """:func:`_certify_rows` for a few rows (one delay pair): everything but the walk in plain Python.

    Row by row, the same steps as the vectorized path: seeds folded to Im >= 0 in real
    rows, the persistent zero moved off, the seed window, Newton (:func:`_newton_one`),
    the distinct roots (sorted, a root within 1e-7 relative of the previous one dropped),
    mirror images, the line (:func:`delayform.analysis.certificate._choose_line`) and the
    expected count; then one :func:`_count_few` for all rows. On a handful of rows each
    NumPy call costs more than its arithmetic, and a single ``dominant_root`` is made of them.
    """
    R = rows.size
    P, D = rows.P, rows.D
    c = [math.nan] * R
    expected = [0.0] * R
    right = [complex(math.nan)] * R
    kept: list[list[complex]] = []
    for i, (row, lam, t1, t2, real, deflate) in enumerate(zip(
        seeds.tolist(), rows.lam.tolist(), rows.t1.tolist(), rows.t2.tolist(), rows.real.tolist(), rows.deflate.tolist()
    )):  # fmt: skip
        live, moved, top = [], False, -math.inf
        for j, z in enumerate(row):
            if z != z:  # NaN: padding
                continue
            if real and z.imag < 0.0:
                z = z.conjugate()
            if deflate and abs(z) < 1e-6:
                moved = True
                continue
            live.append(z)
            if z.real > top and (not fresh or j < fresh):
                top = z.real
        if moved:
            live.append(complex(-1e-2))
        found = []
        for z in live:
            if z.real < top - window:
                continue
            r, ok = _newton_one(z, lam, t1, t2, deflate, P, D)
            if ok and deflate and abs(r) < 1e-6:  # a root beside the persistent zero: as _polish_rows
                ok, r = t1 * lam * P + D * (1.0 - lam) == 0.0, 0j
            if ok:
                found.append(r.conjugate() if real and r.imag < 0.0 else r)
        if not found:
            kept.append(found)
            continue
        found.sort(key=_real_imag)
        distinct, reals, best = [found[0]], [], found[0]
        for a, b in zip(found, found[1:]):
            if abs(b - a) > 1e-7 * (1.0 + abs(a)):
                distinct.append(b)
        kept.append(distinct)
        for z in distinct:
            reals.append(z.real)
            if real and abs(z.imag) > 1e-9 * (1.0 + abs(z)):  # and its mirror image
                reals.append(z.real)
            if z.real > best.real:
                best = z
        right[i] = complex(best.real, abs(best.imag))
        if deflate:
            reals.append(0.0)
        reals.sort(reverse=True)
        ci = _choose_line(reals, best.real)
        c[i] = ci
        expected[i] = float(sum(1 for x in reals if x > ci))
    line = np.array(c)
    good = line == line  # not NaN
    counts = np.full(R, np.nan)
    if good.all():
        counts = _count_few(rows, line)
    elif good.any():
        idx = np.flatnonzero(good)
        counts[idx] = _count_few(rows.take(idx), line[idx])
    distinct_rows = np.full((R, max(1, max(len(k) for k in kept))), np.nan + 0j)
    for i, k in enumerate(kept):
        distinct_rows[i, : len(k)] = k
    return np.array(right), good & (counts == np.array(expected)), distinct_rows


def _real_imag(z: complex) -> tuple[float, float]:
    return z.real, z.imag


# =====================================================================
# seeds: the discretized generator of every factor in one stacked call
# =====================================================================
@lru_cache(maxsize=32)
def _generator_blocks(N: int, t1: float, t2: float, P: float, D: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(K0, K1) of size N + 2 whose K0 + lam K1 has the eigenvalues of the discretized generator.

    The degree-N Chebyshev discretization of eq. subsystems of the second-order factor
    (A = [[0, 1], [-P, -D]], B1 = lam [[0, 0], [P, 0]], B2 = lam [[0, 0], [0, D]]) has size
    2 (N + 1): position y and velocity z at the N + 1 nodes of [-h_max, 0]. Its rows 1..N
    (u' = du/dtheta) act alike on y and z, so an eigenvector with y != 0 has z = mu y; N of
    its eigenvalues belong to y = 0 (z0 = 0, the spurious ones of the differentiation
    matrix alone). With w = mu y_0 the others solve a standard eigenproblem in (y, w):

        mu y_0 = w,   mu y_i = (Dm y)_i (i >= 1),
        mu w = -P y_0 - D w + lam (P L1 . y + D L2 . (mu y)),

    where mu y in the delayed velocity is (w, (Dm y)_1..N). Same eigenvalues as the full
    matrix (to rounding), without the spurious ones, at a third of the cost per call.
    Only the last row depends on lam (the delays enter through the interpolation rows
    L1, L2, hence the cache per delays).
    """
    K0, K1 = _generator_stack(N, np.array([t1]), np.array([t2]), P, D)
    return K0[0], K1[0]


def _generator_stack(
    N: int, t1: NDArray[np.float64], t2: NDArray[np.float64], P: float, D: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`_generator_blocks` at many delay pairs at once, shape (B, N + 2, N + 2) each."""
    _, Dm, _ = _chebyshev(N)
    h = np.stack([t1, t2], axis=-1)  # (B, 2)
    hmax = h.max(axis=-1)
    L = _lagrange_rows(N, 1.0 - 2.0 * h / hmax[:, None])  # (B, 2, N+1)
    Dh = (2.0 / hmax)[:, None, None] * Dm[1:]  # (B, N, N+1)
    B = t1.size
    K0 = np.zeros((B, N + 2, N + 2))
    K0[:, 0, N + 1] = 1.0
    K0[:, 1 : N + 1, : N + 1] = Dh
    K0[:, N + 1, 0], K0[:, N + 1, N + 1] = -P, -D
    K1 = np.zeros((B, N + 2, N + 2))
    K1[:, N + 1, : N + 1] = P * L[:, 0] + D * np.einsum("bj,bjk->bk", L[:, 1, 1:], Dh)
    K1[:, N + 1, N + 1] = D * L[:, 1, 0]
    return K0, K1


@lru_cache(maxsize=64)
def _norm_a(P: float, D: float) -> float:
    return float(np.linalg.norm(np.array([[0.0, 1.0], [-P, -D]]), 2))


@lru_cache(maxsize=32)
def _seed_plan(
    lam_bytes: bytes, P: float, D: float
) -> tuple[float, NDArray[np.bool_], NDArray[np.float64] | None, NDArray[np.complex128] | None]:
    """What the seeds of a family need beyond the delays: the root scale, the real-lam mask, lam stacked.

    The scale is :func:`delayform.analysis._generator._root_scale` over all factors (the
    delay-free roots and the norm of A); real lam are stacked as real (F_r, 1, 1), complex lam
    as complex (F_c, 1, 1) (None when there are none). Cached per (lam, P, D).
    """
    lam = np.frombuffer(lam_bytes, dtype=np.complex128)
    b, c0 = D * (1.0 - lam), P * (1.0 - lam)
    disc = np.sqrt(b * b - 4.0 * c0 + 0j)
    free = max(float(np.max(np.abs(-b + disc))), float(np.max(np.abs(-b - disc)))) / 2.0
    radius = max(1.0, free, _norm_a(P, D))
    real = lam.imag == 0.0
    lam_real = lam.real[real][:, None, None].copy() if real.any() else None
    lam_cplx = lam[~real][:, None, None].copy() if not real.all() else None
    return radius, real, lam_real, lam_cplx


def _eigvals(a: NDArray[Any]) -> NDArray[np.complex128]:
    """Eigenvalues of a stack of small matrices, complex, NaN where LAPACK does not converge.

    The LAPACK kernel behind np.linalg.eigvals, called directly: its wrapper's checks
    (stacked, square, finite, then a scan for real results) cost as much as the solve
    itself on the 8 x 8 matrices of one delay pair. Callers build finite matrices and run
    under ``np.errstate(all="ignore")``; they treat a NaN seed as missing.
    """
    if _LAPACK_EIGVALS is None:  # a NumPy without the private kernel: the public route
        return np.linalg.eigvals(a).astype(np.complex128)
    return _LAPACK_EIGVALS(a, signature="d->D" if a.dtype == np.float64 else "D->D")  # type: ignore[no-any-return]


def _family_seeds(lam: NDArray[np.complex128], P: float, D: float, t1: float, t2: float, k: int) -> NDArray[np.complex128]:
    """The k rightmost eigenvalues of every factor's discretized generator at one pair (F, k)."""
    hmax = max(t1, t2)
    F = lam.size
    if hmax < _TINY_DELAY:  # delay-free: s^2 + D (1 - lam) s + P (1 - lam) = 0
        b, c0 = D * (1.0 - lam), P * (1.0 - lam)
        disc = np.sqrt(b * b - 4.0 * c0 + 0j)
        eig = np.stack([(-b + disc) / 2.0, (-b - disc) / 2.0], axis=1)
    else:
        radius, real, lam_real, lam_cplx = _seed_plan(lam.tobytes(), float(P), float(D))
        N = min(max(math.ceil(0.6 * radius * hmax + 4), 6), MAX_DEGREE)
        M0, M1 = _generator_blocks(N, float(t1), float(t2), float(P), float(D))
        # real lam in one real stacked call (LAPACK's real solver is several times cheaper)
        if lam_cplx is None:
            eig = _eigvals(M0 + lam_real * M1)
        else:
            eig = np.empty((F, M0.shape[0]), dtype=np.complex128)
            if lam_real is not None:
                eig[real] = _eigvals(M0 + lam_real * M1)
            eig[~real] = _eigvals(M0 + lam_cplx * M1)
        # a real lam's matrix is real: its complex eigenvalues come in exact conjugate pairs,
        # and the certificate folds a real row's seeds to Im >= 0 -- keep one of each pair
        eig[real[:, None] & (eig.imag < 0.0)] = np.nan
    return _rightmost_k(eig, k)


def _rightmost_k(eig: NDArray[np.complex128], k: int) -> NDArray[np.complex128]:
    """The k entries of largest real part per row (NaN last, NaN-padded to k columns)."""
    F, width = eig.shape
    if width == k:  # the certificate's seed window selects anyway
        return eig
    order = np.argsort(np.where(np.isnan(eig.real), np.inf, -eig.real), axis=1)[:, :k]
    top = eig[np.arange(F)[:, None], order]
    if top.shape[1] == k:
        return top
    out = np.full((F, k), np.nan + 0j)
    out[:, : top.shape[1]] = top
    return out


def _row_seeds(
    lam: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64], P: float, D: float, k: int
) -> NDArray[np.complex128]:
    """:func:`_family_seeds` of rows each at its own delay pair, shape (R, k).

    Row r gets exactly the seeds of ``_family_seeds(lam[r:r+1], P, D, t1[r], t2[r], k)``;
    rows whose discretizations have the same size share one stacked eigenvalue call
    (the map's retries are scattered over many delay pairs, one factor each).
    """
    R = lam.size
    out = np.full((R, k), np.nan + 0j)
    hmax = np.maximum(t1, t2)
    b, c0 = D * (1.0 - lam), P * (1.0 - lam)
    disc = np.sqrt(b * b - 4.0 * c0 + 0j)
    tiny = hmax < _TINY_DELAY
    if tiny.any():  # delay-free: s^2 + D (1 - lam) s + P (1 - lam) = 0
        free_roots = np.stack([(-b + disc) / 2.0, (-b - disc) / 2.0], axis=1)[tiny]
        order = np.argsort(-free_roots.real, axis=1)[:, :k]
        out[tiny, : order.shape[1]] = free_roots[np.arange(order.shape[0])[:, None], order]
    free = np.maximum(np.abs(-b + disc), np.abs(-b - disc)) / 2.0
    radius = np.maximum(np.maximum(1.0, free), _norm_a(P, D))
    N = np.clip(np.ceil(0.6 * radius * hmax + 4), 6, MAX_DEGREE).astype(int)
    for n in np.unique(N[~tiny]):
        for real in (True, False):
            idx = np.flatnonzero(~tiny & (N == n) & ((lam.imag == 0.0) == real))
            if idx.size == 0:
                continue
            M0, M1 = _generator_stack(int(n), t1[idx], t2[idx], P, D)
            lr = lam[idx].real if real else lam[idx]
            eig = _eigvals(M0 + lr[:, None, None] * M1)
            if real:  # one of each conjugate pair (see _family_seeds)
                eig[eig.imag < 0.0] = np.nan
            top = _rightmost_k(eig, min(k, eig.shape[1]))
            out[idx, : top.shape[1]] = top
    return out


def _generic_rightmost(
    f: CharacteristicFactor, t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Rows the fast path could not certify, by the generic batched then robust path.

    Returns the certified rightmost roots (Im >= 0) and the known roots (seeds for neighbours).
    """
    prob = _problem_of_factor(f)
    out = np.full(t1.size, np.nan + 0j)
    known = np.full((t1.size, _KEEP), np.nan + 0j)
    # without delays the factor is s^2 + D (1 - lam) s + P (1 - lam): its roots in closed form
    # (the centroid's is s^2, whose second zero, the drift, no seed can certify numerically)
    free = (t1 == 0.0) & (t2 == 0.0)
    if free.any():
        roots = _delay_free_roots(complex(f.lam), float(f.P), float(f.D), f.is_centroid)
        out[free] = roots[np.argmax(roots.real)]
        known[free] = _pad(roots[None, :], _KEEP)[0]
    left = np.flatnonzero(~free)
    for scale, k in ((1.0, _BATCH_SEEDS), (2.0, 2 * _BATCH_SEEDS)):
        if left.size == 0:
            break
        seeds = _igd_seeds(prob, t1[left], t2[left], scale=scale, k=k)
        r, ok, roots = _certify(prob, t1[left], t2[left], seeds)
        out[left[ok]] = r[ok]
        if prob.is_real:  # mirror images are no new seeds
            roots = np.where(roots.imag >= 0.0, roots, np.nan)
        known[left[ok]] = _pad(roots[ok], _KEEP)
        left = left[~ok]
    for i in left:
        res = _solve_rightmost(prob, float(t1[i]), float(t2[i]))
        out[i] = _pick_rightmost(prob, res.roots)
        known[i] = _pad(res.roots[None, :], _KEEP)[0]
    return out.real + 1j * np.abs(out.imag), known


def _delay_free_roots(lam: complex, P: float, D: float, deflate: bool) -> NDArray[np.complex128]:
    """Roots of s^2 + D (1 - lam) s + P (1 - lam) (one zero removed for the centroid's deflated root)."""
    b, c0 = D * (1.0 - lam), P * (1.0 - lam)
    disc = cmath.sqrt(b * b - 4.0 * c0)
    roots = np.array([(-b + disc) / 2.0, (-b - disc) / 2.0])
    if deflate:  # lam = 1: s^2, the persistent zero removed leaves the drift 0
        roots = np.delete(roots, np.argmin(np.abs(roots)))
    return roots


def _pad(roots: NDArray[np.complex128], k: int) -> NDArray[np.complex128]:
    """The k rightmost entries per row (NaN-padded; in no particular order when all fit)."""
    if roots.shape[1] <= k:  # all kept: only the padding to k columns
        out = np.full((roots.shape[0], k), np.nan + 0j)
        out[:, : roots.shape[1]] = roots
        return out
    key = np.where(np.isnan(roots.real), np.inf, -roots.real)
    order = np.argsort(key, axis=1)[:, :k]
    top = roots[np.arange(roots.shape[0])[:, None], order]
    if top.shape[1] == k:
        return top
    out = np.full((roots.shape[0], k), np.nan + 0j)
    out[:, : top.shape[1]] = top
    return out


@lru_cache(maxsize=16)
def family_reach_scales(fs: tuple[CharacteristicFactor, ...]) -> NDArray[np.float64]:
    """The root scale of every factor (:func:`delayform.analysis._generator._root_scale`), in closed form.

    A + B1 + B2 of the factor of lam is [[0, 1], [-P (1 - lam), -D (1 - lam)]]:
    its eigenvalues are the delay-free roots of s^2 + D (1 - lam) s + P (1 - lam).
    """
    lam, _, _ = _lams(tuple(fs))
    P, D = float(fs[0].P), float(fs[0].D)
    b, c0 = D * (1.0 - lam), P * (1.0 - lam)
    disc = np.sqrt(b * b - 4.0 * c0 + 0j)
    free = np.maximum(np.abs(-b + disc), np.abs(-b - disc)) / 2.0
    scales = np.maximum(np.maximum(1.0, free), _norm_a(P, D))
    scales.flags.writeable = False  # cached per factor tuple
    return scales


# =====================================================================
# drivers: one delay pair, a grid of delay pairs
# =====================================================================
@np.errstate(all="ignore")
def family_rightmost(
    fs: Sequence[CharacteristicFactor], P: float, D: float, tau1: float, tau2: float
) -> NDArray[np.complex128]:
    """Certified rightmost root (Im >= 0) of every factor at one delay pair, shape (F,)."""
    lam, real, centroid = _lams(tuple(fs))
    F = lam.size
    rows = _Rows(lam, np.full(F, float(tau1)), np.full(F, float(tau2)), real, centroid, P, D)
    seeds = _family_seeds(lam, P, D, float(tau1), float(tau2), _BATCH_SEEDS)
    seeds = np.where(centroid[:, None] & (np.abs(seeds) < 1e-9), np.nan, seeds)
    right, ok, _ = _certify_rows(rows, seeds)
    for k in np.flatnonzero(~ok):
        right[k] = _generic_rightmost(fs[k], rows.t1[k : k + 1], rows.t2[k : k + 1])[0][0]
    return right


def _axis_levels(n: int) -> list[NDArray[np.int64]]:
    """Grid indices of each level (coarse to fine), each level containing the previous."""
    out = []
    for stride in _LEVELS:
        idx = np.arange(0, n, stride)
        out.append(idx if idx[-1] == n - 1 else np.append(idx, n - 1))
    return out


def _nearest(target: NDArray[np.int64], solved: NDArray[np.int64], axis: NDArray[np.float64]) -> NDArray[np.int64]:
    """For each target index, the solved index with the nearest delay."""
    pos = np.searchsorted(axis[solved], axis[target])
    lo = solved[np.clip(pos - 1, 0, solved.size - 1)]
    hi = solved[np.clip(pos, 0, solved.size - 1)]
    return np.where(np.abs(axis[target] - axis[lo]) <= np.abs(axis[target] - axis[hi]), lo, hi)


def _root_slopes(
    roots: NDArray[np.complex128], lam: NDArray[np.complex128], t1: NDArray[np.float64],
    t2: NDArray[np.float64], P: float, D: float,
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """ds/dtau1 and ds/dtau2 of roots (F, n, K) at delays (n,), by the implicit function theorem.

    q(s; tau) = 0 with dq/dtau1 = s a and dq/dtau2 = s^2 b (a = lam P e^{-tau1 s},
    b = lam D e^{-tau2 s}) gives ds/dtau = -(dq/dtau) / (dq/ds). Undefined (a double
    root, a missing one) and large slopes are set to 0: the prediction is only a seed.
    """
    _, dq, a, b = _q(roots, lam[:, None, None], t1[None, :, None], t2[None, :, None], P, D)
    g1 = -roots * a / dq
    g2 = -roots * roots * b / dq
    for g in (g1, g2):
        g[~np.isfinite(g) | (np.abs(g) > 10.0)] = 0.0
    return g1, g2


def _predict(
    roots: NDArray[np.complex128], g1: NDArray[np.complex128], g2: NDArray[np.complex128],
    d1: NDArray[np.float64], d2: NDArray[np.float64],
) -> NDArray[np.complex128]:
    """Roots (F, n, K) moved by the delay steps (n,) along their slopes (first-order prediction)."""
    return roots + g1 * d1[None, :, None] + g2 * d2[None, :, None]


@np.errstate(all="ignore")
def family_grid(
    fs: Sequence[CharacteristicFactor], P: float, D: float,
    ax1: NDArray[np.float64], ax2: NDArray[np.float64],
    advance: Callable[[int], None] | None = None,
) -> NDArray[np.complex128]:
    """Certified rightmost root (Im >= 0) of every factor at every grid point, shape (F, n1, n2)."""
    lam, real, centroid = _lams(tuple(fs))
    F, n1, n2 = lam.size, ax1.size, ax2.size
    npts = n1 * n2
    right = np.full((F, npts), np.nan + 0j)
    known = np.full((F, npts, _KEEP), np.nan + 0j)
    solved = np.zeros(npts, dtype=bool)
    # ds/dtau1, ds/dtau2 of the known roots (zero where undefined): first-order prediction
    # of a neighbour's roots, so its Newton iteration starts an order of magnitude closer
    slope1 = np.zeros((F, npts, _KEEP), dtype=np.complex128)
    slope2 = np.zeros((F, npts, _KEEP), dtype=np.complex128)
    T1, T2 = np.meshgrid(ax1, ax2, indexing="ij")
    t1, t2 = T1.ravel(), T2.ravel()
    prev1 = prev2 = None
    for lev1, lev2 in zip(_axis_levels(n1), _axis_levels(n2)):
        pts = (lev1[:, None] * n2 + lev2[None, :]).ravel()
        pts = pts[~solved[pts]]
        if pts.size == 0:
            continue
        if prev1 is None:  # first level: seeds from the discretized generator
            seeds = np.concatenate(
                [_family_seeds(lam, P, D, float(t1[p]), float(t2[p]), _BATCH_SEEDS) for p in pts], axis=1
            ).reshape(F * pts.size, _BATCH_SEEDS)
            seeds = np.where(np.repeat(centroid, pts.size)[:, None] & (np.abs(seeds) < 1e-9), np.nan, seeds)
        else:  # later levels: the roots of the nearest solved point, moved along their tangents
            i, j = pts // n2, pts % n2
            src = _nearest(i, prev1, ax1) * n2 + _nearest(j, prev2, ax2)
            seeds = _predict(*(np.take(x, src, axis=1) for x in (known, slope1, slope2)),
                             t1[pts] - t1[src], t2[pts] - t2[src])  # fmt: skip
            seeds = seeds.reshape(F * pts.size, _KEEP)
        rows = _Rows(
            np.repeat(lam, pts.size), np.tile(t1[pts], F), np.tile(t2[pts], F),
            np.repeat(real, pts.size), np.repeat(centroid, pts.size), P, D,
        )
        r, ok, roots = _certify_in_chunks(rows, seeds)
        if not ok.all():  # a root the neighbours did not have: fresh discretization seeds
            bad = np.flatnonzero(~ok)
            fresh = _row_seeds(rows.lam[bad], rows.t1[bad], rows.t2[bad], P, D, 2 * _BATCH_SEEDS)
            fresh = np.where(rows.deflate[bad][:, None] & (np.abs(fresh) < 1e-9), np.nan, fresh)
            both = np.concatenate([fresh, seeds[bad]], axis=1)
            # the window set by the new seeds; where their rightmost is a spurious eigenvalue
            # of the discretization (it converges elsewhere), every seed polished
            for cols, window in ((fresh.shape[1], _SEED_WINDOW), (0, np.inf)):
                r2, ok2, roots2 = _certify_rows(rows.take(bad), both, cols, window)
                r[bad[ok2]], ok[bad[ok2]], roots[bad[ok2]] = r2[ok2], True, _pad(roots2[ok2], _KEEP)
                bad, both = bad[~ok2], both[~ok2]
                if bad.size == 0:
                    break
        r, ok, roots = r.reshape(F, -1), ok.reshape(F, -1), roots.reshape(F, pts.size, _KEEP)
        right[:, pts], known[:, pts] = r, roots
        for k in np.flatnonzero((~ok).any(axis=1)):
            bad = pts[~ok[k]]
            right[k, bad], known[k, bad] = _generic_rightmost(fs[k], t1[bad], t2[bad])
        solved[pts] = True
        if not solved.all():  # a finer level follows
            slope1[:, pts], slope2[:, pts] = _root_slopes(known[:, pts], lam, t1[pts], t2[pts], P, D)
        prev1, prev2 = lev1, lev2
        if advance is not None:
            advance(int(F * pts.size))
    return right.reshape(F, n1, n2)
