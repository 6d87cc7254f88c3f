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
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.analysis._generator import _chebyshev, _igd_seeds, _lagrange_rows
from delayform.analysis._quasi import _TINY_DELAY, MAX_DEGREE, RESIDUAL_TOL, _problem_of_factor
from delayform.analysis._rightmost import (
    _BATCH_SEEDS,
    _batch_distinct,
    _certify,
    _pick_rightmost,
    _solve_rightmost,
)
from delayform.analysis.certificate import _batch_lines
from delayform.characteristic import CharacteristicFactor

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
    """
    R, K = seeds.shape
    flat = seeds.ravel()
    live = np.flatnonzero(np.isfinite(flat))  # NaN seeds (padding) cost nothing
    rid = live // K
    s = flat[live].copy()
    lam, t1, t2, defl = rows.lam[rid], rows.t1[rid], rows.t2[rid], rows.deflate[rid]
    act = np.arange(s.size)
    for _ in range(_FAST_NEWTON_STEPS):
        if act.size == 0:
            break
        sa = s[act]
        q, dq, _, _ = _q(sa, lam[act], t1[act], t2[act], rows.P, rows.D)
        den = np.where(defl[act], dq - q / sa, dq)
        step = q / den
        bad = ~np.isfinite(step)
        step[bad] = 0.0
        s[act] = sa - step
        # quadratic convergence: after a step below 1e-8 |s| the error is ~1e-16 |s|
        moving = ~bad & (np.abs(step) > 1e-8 * (1.0 + np.abs(sa)))
        act = act[moving]
    q, _, a, b = _q(s, lam, t1, t2, rows.P, rows.D)
    abs_s = np.abs(s)
    mag = (abs_s + rows.D) * abs_s + rows.P + np.abs(a) + np.abs(b) * abs_s
    ok = np.isfinite(mag) & (np.abs(q) <= RESIDUAL_TOL * mag)
    # s ~ 0 in a centroid row is a root of q(s)/s when 0 is double (q'(0) = 0, as at
    # tau1 = 0); it is then exactly 0 (as _quasi._deflated_zero decides)
    near = defl & (abs_s < 1e-6)
    if near.any():
        lz = lam[near]
        # q'(0) = tau1 lam P + D (1 - lam), exactly 0 for the centroid (lam = 1) at tau1 = 0; a
        # tiny tau1 puts a genuine root beside 0, which the generic path resolves (rejected here)
        double = t1[near] * lz * rows.P + rows.D * (1.0 - lz) == 0.0
        s[near] = np.where(double, 0.0, s[near])
        ok[near] = double
    out = np.full(R * K, np.nan + 0j)
    out[live] = s
    good = np.zeros(R * K, dtype=bool)
    good[live] = ok
    return out.reshape(R, K), good.reshape(R, K)


# =====================================================================
# the certificate, vectorized over rows (same bounds as certificate.py)
# =====================================================================
def _chord_ok(
    qa: NDArray[np.complex128], qb: NDArray[np.complex128], wa: NDArray[np.float64], h: Any,
    m2_slope: Any, m2_offset: Any, c2: Any,
) -> NDArray[np.bool_]:
    """Segments [c + i wa, c + i (wa + h)] on which q keeps off 0 by the chord test (see _count_rows)."""
    wb = wa + h
    rho = np.sqrt(c2 + np.maximum(wa * wa, wb * wb))
    quad = (m2_slope * rho + m2_offset) * (0.125 * h * h)
    d = qb - qa
    dd = d.real * d.real + d.imag * d.imag
    t = np.clip(-(d.real * qa.real + d.imag * qa.imag) / np.where(dd > 0.0, dd, 1.0), 0.0, 1.0)
    near = qa + t * d  # the chord's point nearest 0
    return near.real * near.real + near.imag * near.imag > quad * quad


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
    # few lines: the Python cost of a bisection round outweighs extra samples
    m = _INITIAL_SAMPLES if n > 64 else 4 * _INITIAL_SAMPLES
    lo = np.where(rows.real, 0.0, -omega)
    h = (omega - lo) / (m - 1)

    w = lo + h * np.arange(m)[:, None]  # (m, n)

    def rotations(tau: NDArray[np.float64]) -> NDArray[np.complex128]:
        if n <= 64:  # a few lines: one exp call beats m Python-level rotations
            return np.exp(-1j * tau * w)
        z = np.empty((m, n), dtype=np.complex128)
        z[0] = np.exp(-1j * tau * lo)
        rot = np.exp(-1j * tau * h)
        for j in range(1, m):
            np.multiply(z[j - 1], rot, out=z[j])
        return z

    k1, k2 = rotations(t1), rotations(t2)
    sv = c + 1j * w
    q = (sv + D) * sv + P - A1 * k1 - (B1 * k2) * sv
    failed = ~(np.isfinite(q) & (q != 0.0)).all(axis=0)
    c2 = c * c
    # the initial segments are tested in their (m - 1, n) layout; only rejected ones are
    # gathered into flat arrays and bisected
    good = _chord_ok(q[:-1], q[1:], w[:-1], h, m2_slope, m2_offset, c2)
    total = np.where(good, np.angle(q[1:] * np.conj(q[:-1])), 0.0).sum(axis=0)
    if good.all():  # usually so for a single pair: no segment to bisect, nothing to gather
        line = np.zeros(0, dtype=np.int64)
    else:
        j, line = np.nonzero(~good)
        wa, qa, qb, ka, kb = w[j, line], q[j, line], q[j + 1, line], k1[j, line], k2[j, line]
    step = h.copy()
    for _ in range(52):
        if line.size == 0:
            break
        too_many = np.bincount(line, minlength=n) > max_segments
        if too_many.any():
            failed |= too_many
            keep = ~too_many[line]
            line, wa, qa, qb, ka, kb = line[keep], wa[keep], qa[keep], qb[keep], ka[keep], kb[keep]
        step = 0.5 * step
        wm = wa + step[line]
        km = ka * np.exp(-1j * t1 * step)[line]
        kbm = kb * np.exp(-1j * t2 * step)[line]
        sm = c[line] + 1j * wm
        qm = (sm + D) * sm + P - A1[line] * km - (B1[line] * kbm) * sm
        failed[line[~np.isfinite(qm) | (qm == 0.0)]] = True
        line = np.concatenate([line, line])
        wa = np.concatenate([wa, wm])
        qa, qb = np.concatenate([qa, qm]), np.concatenate([qm, qb])
        ka, kb = np.concatenate([ka, km]), np.concatenate([kb, kbm])
        good = _chord_ok(qa, qb, wa, step[line], m2_slope[line], m2_offset[line], c2[line])
        total += np.bincount(line[good], np.angle(qb[good] * np.conj(qa[good])), minlength=n)
        bad = ~good
        line, wa, qa, qb, ka, kb = line[bad], wa[bad], qa[bad], qb[bad], ka[bad], kb[bad]
    else:
        failed[line] = True
    # tails beyond +-Omega: arg q = arg g1 + Arg(q / g1), g1 = s^2 + D s + P (Rouche)
    # (the walk's end samples are the points c +- i Omega; real rows use only the top one)
    z = _free_roots(P, D)
    ends = sv[_ENDS]  # (2, n): the top end, then the bottom one
    ratio = np.angle(q[_ENDS] / ((ends + D) * ends + P))
    ang = np.angle(ends[..., None] - z)  # (2, n, 2)
    top = (np.pi / 2 - ang[0]).sum(axis=-1) - ratio[0]
    bottom = (ang[1] + np.pi / 2).sum(axis=-1) + ratio[1]
    delta = np.where(rows.real, 2.0 * (total + top), total + top + bottom)
    count = 1.0 - delta / (2.0 * np.pi)
    good = ~failed & np.isfinite(count) & (np.abs(count - np.round(count)) < 0.1)
    return np.where(good, np.round(count), np.nan)


@lru_cache(maxsize=64)
def _free_roots(P: float, D: float) -> NDArray[np.complex128]:
    """The roots of g1 = s^2 + D s + P (the tails' comparison polynomial), read-only."""
    disc = cmath.sqrt(D * D - 4.0 * P)
    z = np.array([(-D + disc) / 2.0, (-D - disc) / 2.0])
    z.flags.writeable = False
    return z


def _certify_rows(
    rows: _Rows, seeds: NDArray[np.complex128]
) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.complex128]]:
    """Polish seeds (R, K) per row, certify the rightmost: (rightmost, certified, known roots).

    The vectorized counterpart of :func:`delayform.analysis._rightmost._certify`
    (same seed window, distinct roots, mirror images and line choice). The
    rightmost root is reported with Im >= 0 (real lam: of a conjugate pair;
    complex lam: the factor of conj(lam) mirrors it).
    """
    real = rows.real[:, None]
    seeds = np.where(real & (seeds.imag < 0.0), np.conj(seeds), seeds)
    seeds = np.where(rows.deflate[:, None] & (np.abs(seeds) < 1e-6), -1e-2, seeds)
    top_seed = np.where(np.isfinite(seeds), seeds.real, -np.inf).max(axis=1)
    seeds = np.where(seeds.real >= top_seed[:, None] - _SEED_WINDOW, seeds, np.nan)
    roots, ok = _polish_rows(seeds, rows)
    ok &= np.isfinite(seeds)
    roots = np.where(real & (roots.imag < 0.0), np.conj(roots), roots)
    distinct = _batch_distinct(roots, ok)
    pair = real & (np.abs(distinct.imag) > 1e-9 * (1.0 + np.abs(distinct)))
    roots = np.concatenate([distinct, np.where(pair, np.conj(distinct), np.nan)], axis=1)
    c, expected, top = _batch_lines(rows.deflate, roots)
    good = np.isfinite(top) & np.isfinite(c)
    if good.all():
        counts = _count_rows(rows, c)
    else:
        counts = np.full(rows.size, np.nan)
        idx = np.flatnonzero(good)
        if idx.size:
            counts[idx] = _count_rows(rows.take(idx), c[idx])
    certified = good & (counts == expected)
    best = np.where(np.isnan(roots.real), -np.inf, roots.real).argmax(axis=1)
    right = roots[np.arange(rows.size), best]
    return right.real + 1j * np.abs(right.imag), certified, distinct


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
    _, Dm, _ = _chebyshev(N)
    h = np.array([t1, t2])
    hmax = float(h.max())
    L = _lagrange_rows(N, 1.0 - 2.0 * h / hmax)  # (2, N+1)
    Dh = (2.0 / hmax) * Dm
    K0 = np.zeros((N + 2, N + 2))
    K0[0, N + 1] = 1.0
    K0[1 : N + 1, : N + 1] = Dh[1:]
    K0[N + 1, 0], K0[N + 1, N + 1] = -P, -D
    K1 = np.zeros((N + 2, N + 2))
    K1[N + 1, : N + 1] = P * L[0] + D * (L[1, 1:] @ Dh[1:])
    K1[N + 1, N + 1] = D * L[1, 0]
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
            eig = np.linalg.eigvals(M0 + lam_real * M1)
        else:
            eig = np.empty((F, M0.shape[0]), dtype=np.complex128)
            if lam_real is not None:
                eig[real] = np.linalg.eigvals(M0 + lam_real * M1)
            eig[~real] = np.linalg.eigvals(M0 + lam_cplx * M1)
    order = np.argsort(-eig.real, axis=1)[:, :k]
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
            blocks = [_generator_blocks(int(n), float(t1[i]), float(t2[i]), float(P), float(D)) for i in idx]
            M0 = np.stack([m0 for m0, _ in blocks])
            M1 = np.stack([m1 for _, m1 in blocks])
            lr = lam[idx].real if real else lam[idx]
            eig = np.linalg.eigvals(M0 + lr[:, None, None] * M1)
            order = np.argsort(-eig.real, axis=1)[:, :k]
            out[idx, : order.shape[1]] = eig[np.arange(idx.size)[:, None], order]
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
    left = np.arange(t1.size)
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


def _pad(roots: NDArray[np.complex128], k: int) -> NDArray[np.complex128]:
    """The k rightmost entries per row (NaN-padded)."""
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
        else:  # later levels: the roots of the nearest solved point
            i, j = pts // n2, pts % n2
            src = _nearest(i, prev1, ax1) * n2 + _nearest(j, prev2, ax2)
            seeds = known[:, src].reshape(F * pts.size, _KEEP)
        rows = _Rows(
            np.repeat(lam, pts.size), np.tile(t1[pts], F), np.tile(t2[pts], F),
            np.repeat(real, pts.size), np.repeat(centroid, pts.size), P, D,
        )
        r, ok, roots = _certify_rows(rows, seeds)
        roots = _pad(roots, _KEEP)
        if not ok.all():  # a root the neighbours did not have: fresh discretization seeds
            bad = np.flatnonzero(~ok)
            fresh = _row_seeds(rows.lam[bad], rows.t1[bad], rows.t2[bad], P, D, 2 * _BATCH_SEEDS)
            fresh = np.where(rows.deflate[bad][:, None] & (np.abs(fresh) < 1e-9), np.nan, fresh)
            r2, ok2, roots2 = _certify_rows(rows.take(bad), np.concatenate([fresh, seeds[bad]], axis=1))
            r[bad[ok2]], ok[bad[ok2]], roots[bad[ok2]] = r2[ok2], True, _pad(roots2[ok2], _KEEP)
        r, ok, roots = r.reshape(F, -1), ok.reshape(F, -1), roots.reshape(F, pts.size, _KEEP)
        right[:, pts], known[:, pts] = r, roots
        for k in np.flatnonzero((~ok).any(axis=1)):
            bad = pts[~ok[k]]
            right[k, bad], known[k, bad] = _generic_rightmost(fs[k], t1[bad], t2[bad])
        solved[pts] = True
        prev1, prev2 = lev1, lev2
        if advance is not None:
            advance(int(F * pts.size))
    return right.reshape(F, n1, n2)
