"""Certified rightmost roots of all factors of the paper's eq. 3 at many delay pairs at once.

Every factor of the paper's eq. 3 is (for a conjugate pair, through its complex
second-order factor of lam) the same quasi-polynomial

    q(s) = s^2 + D s + P - lam (P e^{-tau1 s} + D s e^{-tau2 s})

with its own eigenvalue lam of C. So one *row* -- a factor at a delay pair --
is described by (lam, tau1, tau2), and the polishing, the line choice and
the argument-principle certificate of :mod:`delayform.analysis.roots.argument_principle`
run on flat arrays of rows, all factors and all delay pairs in one NumPy
expression each. The generic per-factor code pays a Python round trip per
term and per factor; here q, its derivatives, the bounds and the Cauchy radius
are written out for this family (the same formulas, specialized).

A map is solved by continuation: the delay grid is visited coarse to fine
(:data:`_LEVELS`); the first level is seeded by the Chebyshev discretization
of the generator, every later point by the roots of its nearest solved point
moved along their tangents (implicit function theorem), polished by Halley's
method and accepted by a Taylor bound of the residual. The certificate walks
the line Re s = c with samples spaced by how far e^{-i tau w} turns, accepts a
segment by the chord test (:func:`_count_rows`) and counts the winding as Arg
at the walk's ends plus 2 pi per crossing of Arg's branch cut. Every row is
certified; rows whose certificate fails are redone with fresh discretization
seeds, then by the generic batched path and, rarely, the robust single-pair
path. Levels are certified in chunks that stay in the processor's cache.

A single delay pair discretizes all factors in one stacked eigenvalue call,
whose matrices depend on lam only through their last row (cached per delays);
its handful of rows is polished and its lines chosen in plain Python
(:func:`_certify_few`), where NumPy's per-call cost would dominate.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.roots.family.actuated import (
    actuated_count,
    actuated_fallback,
    actuated_polish,
    actuated_seeds,
    actuated_slopes,
)
from delayform.analysis.roots.generator import _igd_seeds, _root_scale
from delayform.analysis.roots.long_delay import is_long
from delayform.analysis.roots.problem import _problem_of_factor
from delayform.analysis.roots.rightmost import (
    _BATCH_SEEDS,
    _certify,
    _pick_rightmost,
    _solve_rightmost,
)
from delayform.analysis.roots.family.polish import _newton_one, _polish_rows, _q
from delayform.analysis.roots.family.rows import _delay_free, _lams, _root_scales, _Rows
from delayform.analysis.roots.family.seeds import _family_seeds, _row_seeds
from delayform.analysis.roots.family.walk import _count_few, _count_rows
from delayform.analysis.roots.argument_principle import _LINE_OFFSET, _choose_line, _choose_lines
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
#: Rows certified together in a map (larger batches fall out of the processor's cache).
_CHUNK_ROWS = 8192
#: Rows (factors at one delay pair) up to which the line choice runs in plain Python.
_FEW_ROWS = 16


def _certify_rows(
    rows: _Rows, seeds: NDArray[np.complex128], fresh: int = 0, window: float = _SEED_WINDOW
) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.complex128]]:
    """Polish seeds (R, K) per row, certify the rightmost: (rightmost, certified, known roots).

    Only seeds within ``window`` of a row's rightmost seed are polished; with ``fresh`` > 0
    the window is set by the rightmost of the first ``fresh`` columns (a redo's new
    discretization seeds: a stale seed that converges nowhere would drop the good ones).

    The vectorized counterpart of :func:`delayform.analysis.roots.rightmost._certify`
    (same seed window, distinct roots, mirror images and line choice). The
    rightmost root is reported with Im >= 0 (real lam: of a conjugate pair;
    complex lam: the factor of conj(lam) mirrors it).
    """
    if rows.size <= _FEW_ROWS and not rows.ta:
        return _certify_few(rows, seeds, fresh, window)
    # an actuation delay (rows.ta > 0): the same steps on the family of family/actuated.py
    polish, count = (actuated_polish, actuated_count) if rows.ta else (_polish_rows, _count_rows)
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
    roots, ok = polish(seeds, rows)
    np.abs(roots.imag, out=roots.imag, where=real)
    right, c, expected, distinct = _lines_of_rows(roots, ok, rows.real, rows.deflate)
    good = np.isfinite(c)
    if good.all():
        counts = count(rows, c)
    else:
        counts = np.full(rows.size, np.nan)
        idx = np.flatnonzero(good)
        if idx.size:
            counts[idx] = count(rows.take(idx), c[idx])
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

    The vectorized :func:`delayform.analysis.roots.argument_principle._choose_line` on the distinct
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


def _certify_few(
    rows: _Rows, seeds: NDArray[np.complex128], fresh: int, window: float
) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.complex128]]:
    """:func:`_certify_rows` for a few rows (one delay pair): everything but the walk in plain Python.

    Row by row, the same steps as the vectorized path: seeds folded to Im >= 0 in real
    rows, the persistent zero moved off, the seed window, Newton (:func:`_newton_one`),
    the distinct roots (sorted, a root within 1e-7 relative of the previous one dropped),
    mirror images, the line (:func:`delayform.analysis.roots.argument_principle._choose_line`) and the
    expected count; then one :func:`_count_few` for all rows. On a handful of rows each
    NumPy call costs more than its arithmetic, and a single ``dominant_root`` is made of them.
    """
    R = rows.size
    Ps = rows.P.tolist() if isinstance(rows.P, np.ndarray) else [rows.P] * R
    Ds = rows.D.tolist() if isinstance(rows.D, np.ndarray) else [rows.D] * R
    c = [math.nan] * R
    expected = [0.0] * R
    right = [complex(math.nan)] * R
    kept: list[list[complex]] = []
    for i, (row, lam, t1, t2, real, deflate, P, D) in enumerate(zip(
        seeds.tolist(), rows.lam.tolist(), rows.t1.tolist(), rows.t2.tolist(), rows.real.tolist(), rows.deflate.tolist(),
        Ps, Ds,
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


def _without_persistent_zero(seeds: NDArray[np.complex128], deflate: NDArray[np.bool_]) -> NDArray[np.complex128]:
    """Seeds (R, K) with the centroid rows' discretized persistent zero (paper, eq. 4) dropped."""
    return np.where(deflate[:, None] & (np.abs(seeds) < 1e-9), np.nan, seeds)


def _fresh_seeds(rows: _Rows, k: int) -> NDArray[np.complex128]:
    """The k rightmost eigenvalues of every row's discretized generator (persistent zero dropped)."""
    if rows.ta:
        return actuated_seeds(rows, k)
    return _without_persistent_zero(_row_seeds(rows.lam, rows.t1, rows.t2, rows.P, rows.D, k), rows.deflate)


def _certify_afresh(
    rows: _Rows, seeds: NDArray[np.complex128], bad: NDArray[np.int64]
) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.complex128]]:
    """Rows ``bad`` that their seeds did not certify, again from twice as many fresh discretization seeds.

    The seed window is first set by the fresh seeds; where their rightmost is a spurious
    eigenvalue of the discretization (it converges elsewhere) every seed is polished.
    Returns (rightmost, certified, distinct roots) aligned with ``bad``.
    """
    both = np.concatenate([_fresh_seeds(rows.take(bad), 2 * _BATCH_SEEDS), seeds[bad]], axis=1)
    right = np.full(bad.size, np.nan + 0j)
    ok = np.zeros(bad.size, dtype=bool)
    found: list[tuple[NDArray[np.int64], NDArray[np.complex128]]] = []
    left = np.arange(bad.size)
    for cols, window in ((2 * _BATCH_SEEDS, _SEED_WINDOW), (0, np.inf)):
        r, good, roots = _certify_rows(rows.take(bad[left]), both[left], cols, window)
        right[left[good]], ok[left[good]] = r[good], True
        found.append((left[good], roots[good]))
        left = left[~good]
        if left.size == 0:
            break
    known = np.full((bad.size, max(1, max(r.shape[1] for _, r in found))), np.nan + 0j)
    for i, r in found:
        known[i, : r.shape[1]] = r
    return right, ok, known


def _generic_rightmost(
    f: CharacteristicFactor, t1: NDArray[np.float64], t2: NDArray[np.float64], ta: float = 0.0
) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
    """Rows the fast path could not certify, by the generic batched then robust path.

    Returns the certified rightmost roots (Im >= 0) and the known roots (seeds for neighbours).
    With an actuation delay ``ta`` > 0 each row goes to the robust path in three delays.
    """
    if ta:
        lam, P, D, defl = complex(f.lam), float(f.P), float(f.D), bool(f.is_centroid)
        out = np.array([actuated_fallback(lam, P, D, defl, a, b, ta) for a, b in zip(t1.tolist(), t2.tolist())])
        return out.astype(np.complex128).reshape(t1.shape), _pad(out.reshape(-1, 1).astype(np.complex128), _KEEP)
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
    # long delays: no low-degree seeds (too coarse for chains of spacing 2 pi / tau), the root chains
    # of the robust path at once
    longs = is_long(np.maximum(t1, t2), _root_scale(prob)) & ~free
    left = np.flatnonzero(~free & ~longs)
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
    for i in np.concatenate([left, np.flatnonzero(longs)]):
        res = _solve_rightmost(prob, float(t1[i]), float(t2[i]))
        out[i] = _pick_rightmost(prob, res.roots)
        known[i] = _pad(res.roots[None, :], _KEEP)[0]
    return out.real + 1j * np.abs(out.imag), known


def _delay_free_roots(lam: complex, P: float, D: float, deflate: bool) -> NDArray[np.complex128]:
    """Roots of s^2 + D (1 - lam) s + P (1 - lam) (one zero removed for the centroid's deflated root)."""
    roots = _delay_free(lam, P, D)
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
    """The root scale of every factor (:func:`delayform.analysis.roots.generator._root_scale`), in closed form.

    A + B1 + B2 of the factor of lam is [[0, 1], [-P (1 - lam), -D (1 - lam)]]:
    its eigenvalues are the delay-free roots of s^2 + D (1 - lam) s + P (1 - lam).
    """
    lam, _, _ = _lams(tuple(fs))
    scales = _root_scales(lam, float(fs[0].P), float(fs[0].D))
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
    if is_long(max(tau1, tau2), _smallest_scale(lam.tobytes(), float(P), float(D))):  # every factor on its chains
        return np.array([_generic_rightmost(f, rows.t1[:1], rows.t2[:1])[0][0] for f in fs])
    seeds = _without_persistent_zero(_family_seeds(lam, P, D, float(tau1), float(tau2), _BATCH_SEEDS), centroid)
    right, ok, _ = _certify_rows(rows, seeds)
    for k in np.flatnonzero(~ok):
        right[k] = _generic_rightmost(fs[k], rows.t1[k : k + 1], rows.t2[k : k + 1])[0][0]
    return right


@lru_cache(maxsize=16)
def _smallest_scale(lam_bytes: bytes, P: float, D: float) -> float:
    """The smallest root scale of the factors (cached on lam's bytes: one lookup per single-pair call)."""
    return float(_root_scales(np.frombuffer(lam_bytes, dtype=np.complex128), P, D).min())


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
    advance: Callable[[int], None] | None = None, ta: float = 0.0,
) -> NDArray[np.complex128]:
    """Certified rightmost root (Im >= 0) of every factor at every grid point, shape (F, n1, n2).

    ``ta`` > 0: the factors with that actuation delay (:mod:`delayform.analysis.roots.family.actuated`).
    """
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
        rows = _Rows(
            np.repeat(lam, pts.size), np.tile(t1[pts], F), np.tile(t2[pts], F),
            np.repeat(real, pts.size), np.repeat(centroid, pts.size), P, D, ta,
        )
        if prev1 is None:  # first level: seeds from the discretized generator (stacked by size)
            seeds = _fresh_seeds(rows, _BATCH_SEEDS)
        else:  # later levels: the roots of the nearest solved point, moved along their tangents
            i, j = pts // n2, pts % n2
            src = _nearest(i, prev1, ax1) * n2 + _nearest(j, prev2, ax2)
            seeds = _predict(*(np.take(x, src, axis=1) for x in (known, slope1, slope2)),
                             t1[pts] - t1[src], t2[pts] - t2[src])  # fmt: skip
            seeds = seeds.reshape(F * pts.size, _KEEP)
        r, ok, roots = _certify_in_chunks(rows, seeds)
        if not ok.all():  # a root the neighbours did not have: fresh discretization seeds
            bad = np.flatnonzero(~ok)
            r2, ok2, roots2 = _certify_afresh(rows, seeds, bad)
            r[bad[ok2]], ok[bad[ok2]], roots[bad[ok2]] = r2[ok2], True, _pad(roots2[ok2], _KEEP)
        r, ok, roots = r.reshape(F, -1), ok.reshape(F, -1), roots.reshape(F, pts.size, _KEEP)
        right[:, pts], known[:, pts] = r, roots
        for k in np.flatnonzero((~ok).any(axis=1)):
            bad = pts[~ok[k]]
            right[k, bad], known[k, bad] = _generic_rightmost(fs[k], t1[bad], t2[bad], ta)
        solved[pts] = True
        if not solved.all():  # a finer level follows
            slope1[:, pts], slope2[:, pts] = (
                actuated_slopes(known[:, pts], lam, t1[pts], t2[pts], ta, P, D) if ta
                else _root_slopes(known[:, pts], lam, t1[pts], t2[pts], P, D)
            )  # fmt: skip
        prev1, prev2 = lev1, lev2
        if advance is not None:
            advance(int(F * pts.size))
    return right.reshape(F, n1, n2)
