"""Argument-principle certificates: certified counts of roots right of a line or inside a rectangle.

The sampling of arg q is certified by a Lipschitz bound (the module
docstring of :mod:`delayform.analysis.roots.dominant`); the line Re s = c is
closed at infinity by a Cauchy-type radius (Rouche). Also the choice of the
certifying line in a gap left of the rightmost known root.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import math
from typing import Any

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import NDArray

from delayform.analysis.roots.problem import (
    Region,
    _derivatives_up_to,
    _abs_poly,
    _abs_poly_der,
    evaluate,
    _horner,
    _Problem,
    Terms,
)

#: Largest distance of the certifying line Re s = c from the roots it separates.
_LINE_OFFSET = 0.1
#: Most sample points spent on one certified contour before giving up.
_MAX_SAMPLES = 400_000


# =====================================================================
# argument principle with certified sampling
# =====================================================================
def _lipschitz(
    terms: Terms, rho: NDArray[np.float64], re_min: NDArray[np.float64], t1: Any, t2: Any
) -> NDArray[np.float64]:
    """Bound of |q'(s)| over |s| <= rho, Re s >= re_min (moduli of coefficients)."""
    out = np.zeros(np.broadcast_shapes(np.shape(rho), np.shape(re_min), np.shape(t1), np.shape(t2)))
    for c, a, b in terms:
        h = a * np.asarray(t1) + b * np.asarray(t2)
        with np.errstate(over="ignore"):
            w = np.exp(-h * re_min)
        out = out + w * (_abs_poly_der(c, rho) + h * _abs_poly(c, rho))
    return out


def _segment_winding(
    terms: Terms, t1: float, t2: float, s0: complex, s1: complex, *, budget: int
) -> tuple[float, int] | None:
    """Certified change of arg q along the segment s0 -> s1, and samples used.

    Segments of the sampling are bisected until every one satisfies the
    Lipschitz condition of the module docstring; None when ``budget`` samples
    do not suffice (a root on or extremely close to the segment).
    """
    length = abs(s1 - s0)
    t = np.linspace(0.0, 1.0, 65)
    a1, a2 = np.asarray(t1), np.asarray(t2)
    for _ in range(64):  # 64 bisections: segments far below rounding of s
        if t.size > budget:
            return None
        s = s0 + t * (s1 - s0)
        q, _, _ = evaluate(terms, s, a1, a2)
        absq = np.abs(q)
        if not np.all(np.isfinite(absq)) or np.any(absq == 0.0):
            return None
        rho = np.maximum(np.abs(s[:-1]), np.abs(s[1:]))
        re_min = np.minimum(s[:-1].real, s[1:].real)
        L = _lipschitz(terms, rho, re_min, t1, t2) * length * np.diff(t)
        bad = np.minimum(absq[:-1], absq[1:]) <= 0.5 * L
        if bad.any():  # near a multiple root q' is small too: the Taylor test certifies where L cannot
            idx = np.flatnonzero(bad)
            bad[idx] = ~_taylor_passes(terms, s[idx], absq[idx], rho[idx], re_min[idx],
                                       length * np.diff(t)[idx], t1, t2)  # fmt: skip
        if not bad.any():
            return float(np.angle(q[1:] / q[:-1]).sum()), int(t.size)
        mids = 0.5 * (t[:-1] + t[1:])[bad]
        t = np.sort(np.concatenate([t, mids]))
    return None


def _taylor_order(terms: Terms) -> int:
    """1 + the largest multiplicity a root of q can have, capped at 12.

    A quasi-polynomial with terms of degrees d_k has no root of multiplicity
    above sum_k (d_k + 1) - 1 (Polya and Szego, *Problems and Theorems in
    Analysis I*, Part Three, Problem 206.2).
    """
    return min(sum(int(c.size) for c, _, _ in terms) - 1, 11) + 1


def _taylor_passes(
    terms: Terms, a: NDArray[np.complex128], absq: NDArray[np.float64], rho: NDArray[np.float64],
    re_min: NDArray[np.float64], delta: NDArray[np.float64], t1: float, t2: float,
) -> NDArray[np.bool_]:
    """True where q has no zero within ``delta`` of ``a`` by Taylor's theorem of order K.

    ``|q(a + u) - q(a)| <= sum_{j<K} |q^(j)(a)| |u|^j / j! + M_K |u|^K / K!``
    with ``M_K`` a bound of ``|q^(K)|`` over ``|s| <= rho``, ``Re s >= re_min``
    (moduli of the coefficients); below ``|q(a)|`` the values on the segment
    stay in the open disk of radius ``|q(a)|`` about ``q(a)``, which excludes
    0, so the segment's arg increment is the principal one. Where q' nearly
    vanishes (a multiple root close by) this needs far fewer samples than the
    Lipschitz test. Each |q^(j)(a)|, and q(a) itself, is padded by its
    rounding error (64 eps of its terms' moduli, |s| floored at 1).
    """
    K = _taylor_order(terms)
    # q(a) itself carries rounding (large terms cancelling near a root): only its certain part counts
    vals, mags = _derivatives_up_to(terms, a, t1, t2, K - 1)
    bound = 64 * np.finfo(float).eps * mags[0]
    fact = 1.0
    for j in range(1, K):
        fact *= j
        bound += (np.abs(vals[j]) + 64 * np.finfo(float).eps * mags[j]) * delta**j / fact
    fact *= K
    M = np.zeros(a.shape)
    for c, ka, kb in terms:
        h = ka * t1 + kb * t2
        with np.errstate(over="ignore"):
            w = np.exp(-h * re_min)
        absc = np.abs(c).astype(np.complex128)
        for j in range(min(K, c.size - 1) + 1):
            M += math.comb(K, j) * h ** (K - j) * w * _abs_poly(npoly.polyder(absc, j) if j else absc, rho)
    with np.errstate(over="ignore", invalid="ignore"):
        return bound + M * delta**K / fact < absq


def count_in_region(
    terms: Terms, t1: float, t2: float, region: Region, *, budget: int = _MAX_SAMPLES
) -> int | None:
    """Certified number of roots of q inside a rectangle (multiplicity counted), or None.

    The winding of q along the rectangle's four edges, sampled with the
    Lipschitz-certified step (no root is skipped between samples): the count
    that the root finders, the neutral solver and the CTCR degenerate
    crossings rely on.

    Parameters
    ----------
    terms
        The quasi-polynomial (:data:`~delayform.analysis.roots.problem.Terms`).
    t1, t2
        The delays it is evaluated at (each term's delay is ``a t1 + b t2``).
    region
        ``(x0, x1, y0, y1)``: the rectangle x0 <= Re s <= x1, y0 <= Im s <= y1.
    budget
        Most samples spent on one edge.

    Returns
    -------
    int or None
        None when a root lies on (or within rounding of) an edge, or the
        budget ran out: no count is then certified.
    """
    x0, x1, y0, y1 = region
    corners = [complex(x0, y0), complex(x1, y0), complex(x1, y1), complex(x0, y1)]
    total = 0.0
    for k in range(4):
        piece = _segment_winding(terms, t1, t2, corners[k], corners[(k + 1) % 4], budget=budget)
        if piece is None:
            return None
        total += piece[0]
    count = total / (2.0 * np.pi)
    return int(round(count)) if abs(count - round(count)) < 0.1 else None


def _cauchy_radius(
    terms: Terms, c: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Omega with |g1(s)| > sum_k |g_k(s)| e^{-h_k c} whenever |s| >= Omega (Rouche on Re s = c).

    The positive root of |a_N| r^N - sum_{i<N} (|a_i| + sum_k e^{-h_k c} |b_k,i|) r^i
    (one sign change, so exactly one), found by bisection; the upper end is
    returned, where the polynomial is strictly positive.
    """
    g1 = np.abs(terms[0][0])
    n = g1.size - 1
    shape = np.broadcast_shapes(c.shape, t1.shape, t2.shape)
    low = np.zeros(shape + (n,))
    low[...] = g1[:n]
    for coef, a, b in terms[1:]:
        with np.errstate(over="ignore"):
            w = np.exp(-(a * t1 + b * t2) * c)
        low[..., : coef.size] += w[..., None] * np.abs(coef)
    lead = g1[n]
    if n == 2:  # the second-order factors of eq. factorized: the quadratic formula
        b1, b0 = low[..., 1], low[..., 0]
        root = (b1 + np.sqrt(b1 * b1 + 4.0 * lead * b0)) / (2.0 * lead)
        return root * (1.0 + 1e-9) + 1e-12
    hi = np.maximum(1.0, low.sum(axis=-1) / lead) * (1.0 + 1e-12)
    lo = np.zeros(shape)
    powers = np.arange(n)

    def p(r: NDArray[np.float64]) -> NDArray[np.float64]:
        return lead * r**n - (low * r[..., None] ** powers).sum(axis=-1)

    if shape == () and n > 0:
        # one line (the single-point paths): the positive root from the companion eigenvalues,
        # kept only where the polynomial is checked positive just above it (else bisection)
        z = np.roots(np.concatenate([[lead], -low[::-1]]))
        real = z.real[(np.abs(z.imag) <= 1e-9 * (1.0 + np.abs(z))) & (z.real > 0.0)]
        if real.size:
            guess = np.asarray(float(real.max()) * (1.0 + 1e-9) + 1e-12)
            if p(guess) > 0.0:
                return guess

    for _ in range(60):
        mid = 0.5 * (lo + hi)
        pos = p(mid) > 0.0
        hi = np.where(pos, mid, hi)
        lo = np.where(pos, lo, mid)
    return hi * (1.0 + 1e-9) + 1e-12


def _tail_winding(
    terms: Terms, g1_roots: NDArray[np.complex128], s_end: NDArray[np.complex128],
    t1: NDArray[np.float64], t2: NDArray[np.float64], *, upper: bool,
) -> NDArray[np.float64]:
    """Arg change of q from c + i Omega up to c + i inf (upper) or from c - i inf to c - i Omega.

    There |q/g1 - 1| < 1, so arg q = arg g1 + Arg(q/g1), with Arg(q/g1) -> 0
    at infinity and arg g1 moving by sum over its roots z of the angle of s - z.
    """
    q, _, _ = evaluate(terms, s_end, t1, t2)
    g1 = _horner(terms[0][0], s_end)
    ratio = np.angle(q / g1)
    ang = np.angle(s_end[..., None] - g1_roots)
    if upper:
        return (np.pi / 2 - ang).sum(axis=-1) - ratio
    return (ang + np.pi / 2).sum(axis=-1) + ratio


def _g1_roots(terms: Terms) -> NDArray[np.complex128]:
    g1 = terms[0][0]
    return np.roots(g1[::-1]) if g1.size > 1 else np.zeros(0, dtype=np.complex128)


def _count_right_single(prob: _Problem, t1: float, t2: float, c: float) -> int | None:
    """Certified number of roots of q with Re s > c (None if not certifiable)."""
    a1, a2, cc = np.asarray(t1), np.asarray(t2), np.asarray(c, dtype=float)
    omega = float(_cauchy_radius(prob.terms, cc, a1, a2))
    piece = _segment_winding(
        prob.terms, t1, t2, complex(c, -omega), complex(c, omega), budget=_MAX_SAMPLES
    )
    if piece is None:
        return None
    roots = _g1_roots(prob.terms)
    top = _tail_winding(prob.terms, roots, np.asarray(complex(c, omega)), a1, a2, upper=True)
    bottom = _tail_winding(prob.terms, roots, np.asarray(complex(c, -omega)), a1, a2, upper=False)
    delta = piece[0] + float(top) + float(bottom)
    count = prob.degree / 2.0 - delta / (2.0 * np.pi)
    return int(round(count)) if abs(count - round(count)) < 0.1 else None


def adaptive_winding(
    c: NDArray[np.float64],
    omega: NDArray[np.float64],
    evaluate: Callable[[NDArray[np.int64], NDArray[np.complex128]], NDArray[np.complex128]],
    lipschitz: Callable[[NDArray[np.int64], NDArray[np.float64]], NDArray[np.float64]],
    *,
    real: bool,
    initial: int = 17,
    max_segments: int = 4096,
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Certified arg change of q along the segments Re s = c_k, |Im s| <= omega_k, all lines at once.

    All lines' segments live in flat arrays; each round bisects, in one
    evaluation, the segments that fail ``min(|q(a)|, |q(b)|) > L |b - a| / 2``
    (``L`` a bound of |q'| on the segment), which keeps every arg increment
    below pi, and sums the increments of the segments that pass. For a real
    q only ``0 <= Im s <= omega`` is walked (the caller doubles it).

    Parameters
    ----------
    c, omega
        Abscissa and half-height of each line's segment.
    evaluate
        ``evaluate(line, s)``: q at the points ``s`` of the lines ``line`` (flat arrays).
    lipschitz
        ``lipschitz(line, rho)``: a bound of |q'| over ``|s| <= rho``, ``Re s >= c[line]``.
    real
        Walk only the upper half of each segment.
    initial
        Samples per line before any bisection.
    max_segments
        Segments per line after which the line is given up.

    Returns
    -------
    total, failed
        The summed arg increments per line, and the lines that could not be certified.
    """
    nline = c.size
    u = np.linspace(0.0 if real else -1.0, 1.0, initial)
    w = omega[:, None] * u  # (B, M)
    every = np.repeat(np.arange(nline), initial)
    q = evaluate(every, (c[:, None] + 1j * w).ravel()).reshape(nline, initial)
    line = np.repeat(np.arange(nline), initial - 1)
    wa, wb = w[:, :-1].ravel(), w[:, 1:].ravel()
    qa, qb = q[:, :-1].ravel(), q[:, 1:].ravel()
    total = np.zeros(nline)
    failed = ~np.all(np.isfinite(q) & (q != 0.0), axis=1)
    for _ in range(48):
        rho = np.sqrt(c[line] ** 2 + np.maximum(wa * wa, wb * wb))
        bound = lipschitz(line, rho) * (wb - wa)
        bad = np.minimum(np.abs(qa), np.abs(qb)) <= 0.5 * bound
        with np.errstate(all="ignore"):
            total += np.bincount(line[~bad], np.angle(qb[~bad] / qa[~bad]), minlength=nline)
        if not bad.any():
            break
        line, wa, wb, qa, qb = line[bad], wa[bad], wb[bad], qa[bad], qb[bad]
        too_many = np.bincount(line, minlength=nline) > max_segments
        failed |= too_many
        keep = ~too_many[line]
        line, wa, wb, qa, qb = line[keep], wa[keep], wb[keep], qa[keep], qb[keep]
        wm = 0.5 * (wa + wb)
        qm = evaluate(line, c[line] + 1j * wm)
        failed[line[~np.isfinite(qm) | (qm == 0.0)]] = True
        line = np.concatenate([line, line])
        wa, wb = np.concatenate([wa, wm]), np.concatenate([wm, wb])
        qa, qb = np.concatenate([qa, qm]), np.concatenate([qm, qb])
    else:
        failed[line] = True
    return total, failed


def _count_right_batch(
    prob: _Problem, t1: NDArray[np.float64], t2: NDArray[np.float64], c: NDArray[np.float64],
    *, initial: int = 17, max_segments: int = 4096,
) -> NDArray[np.float64]:
    """Certified counts of roots in Re s > c for many delay pairs at once (NaN: not certified).

    The adaptive sampling of :func:`_segment_winding`, vectorized: all lines'
    segments live in flat arrays; each round bisects, in one evaluation, the
    segments of every line that fail the Lipschitz condition, and the arg
    increments of the segments that pass are summed per line. For a real q
    only Im s >= 0 is walked (q(conj s) = conj q(s) doubles it).
    """
    omega = _cauchy_radius(prob.terms, c, t1, t2)
    real = all(np.all(cf.imag == 0.0) for cf, _, _ in prob.terms)

    def q_on(line: NDArray[np.int64], s: NDArray[np.complex128]) -> NDArray[np.complex128]:
        return evaluate(prob.terms, s, t1[line], t2[line], magnitude=False)[0]

    def lipschitz(line: NDArray[np.int64], rho: NDArray[np.float64]) -> NDArray[np.float64]:
        return _lipschitz(prob.terms, rho, c[line], t1[line], t2[line])

    total, failed = adaptive_winding(c, omega, q_on, lipschitz, real=real, initial=initial,
                                     max_segments=max_segments)  # fmt: skip
    roots = _g1_roots(prob.terms)
    top = _tail_winding(prob.terms, roots, c + 1j * omega, t1, t2, upper=True)
    if real:
        delta = 2.0 * (total + top)
    else:
        bottom = _tail_winding(prob.terms, roots, c - 1j * omega, t1, t2, upper=False)
        delta = total + top + bottom
    count = prob.degree / 2.0 - delta / (2.0 * np.pi)
    good = ~failed & (np.abs(count - np.round(count)) < 0.1)
    return np.where(good, np.round(count), np.nan)


def _choose_line(reals: Sequence[float], top: float, offset: float = _LINE_OFFSET) -> float:
    """A line Re s = c in a gap left of ``top`` (reals: known root real parts, descending).

    Roots whose real parts are within 1e-3 of each other stay on the same
    side, so the line is never closer than 5e-4 to a known root; it is at
    most :data:`_LINE_OFFSET` left of them, because e^{-h c} grows quickly as
    c moves left and with it the Cauchy radius and the Lipschitz bounds. ``top`` is
    the real part of the rightmost root wanted (the deflated zero of the paper's
    eq. 4 may lie right of it and is then simply counted). Plain Python: it
    runs on a handful of numbers per factor, where NumPy's per-call cost dominates.
    ``offset`` replaces :data:`_LINE_OFFSET` (the robust path's long delays:
    e^{-h c} must stay moderate, so the line keeps within about 1/h of the roots).
    """
    n = len(reals)
    k0 = next((k for k in range(n) if reals[k] <= top), 0)
    for k in range(k0, min(n - 1, k0 + 8)):
        gap = reals[k] - reals[k + 1]
        if gap > 1e-3 * (1.0 + abs(reals[k])):
            return float(reals[k] - min(0.5 * gap, offset))
    return float(reals[min(n - 1, k0 + 8)] - offset)


def _known_reals(
    prob: _Problem, roots: NDArray[np.complex128], mult: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Real parts (descending) and multiplicities of the roots of q, incl. the deflated zero."""
    if prob.deflate_zero:
        roots = np.concatenate([roots, [0.0]])
        mult = np.concatenate([mult, [1]])
    order = np.argsort(-roots.real)
    return roots.real[order], mult[order]



def _batch_lines(
    deflate_zero: bool | NDArray[np.bool_] | _Problem, roots: NDArray[np.complex128]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Vectorized :func:`_choose_line`: the line c, the expected count and the rightmost real part.

    ``deflate_zero`` (one flag, one per row, or a problem whose flag is read)
    adds the persistent root 0 of the paper's eq. 4 to the known roots of a row.
    """
    if isinstance(deflate_zero, _Problem):
        deflate_zero = deflate_zero.deflate_zero
    # plain fancy indexing and finite stand-ins for -inf: this runs on every certified
    # point, often for a handful of rows, where NumPy's per-call overhead is the cost
    key = roots.real
    key = np.where(key == key, key, -np.inf)  # NaN (missing) -> -inf
    top = key.max(axis=1)
    if isinstance(deflate_zero, np.ndarray) and deflate_zero.shape == top.shape:
        if deflate_zero.any():
            key = np.concatenate([key, np.where(deflate_zero, 0.0, -np.inf)[:, None]], axis=1)
    elif np.any(deflate_zero):
        zero = np.where(np.broadcast_to(deflate_zero, top.shape), 0.0, -np.inf)
        key = np.concatenate([key, zero[:, None]], axis=1)
    c = _choose_lines(key, top)
    expected = (key > c[:, None]).sum(axis=1).astype(float)
    return c, expected, top


def _choose_lines(key: NDArray[np.float64], top: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`delayform.analysis.roots.argument_principle._choose_line` per row of known real parts (-inf: none)."""
    R = key.shape[0]
    rix = np.arange(R)
    srt = -np.sort(-key, axis=1)  # descending; -inf (none) last
    width = srt.shape[1]
    n_known = (srt > -np.inf).sum(axis=1)
    k0 = (srt <= top[:, None]).argmax(axis=1)
    c = np.full(R, np.nan)
    if width >= 2:  # the first of the 8 gaps below the top that is wide enough
        fin = np.where(srt > -np.inf, srt, -1e300)  # finite stand-ins: -inf - -inf would warn
        gap = fin[:, :-1] - fin[:, 1:]
        pos = np.arange(width - 1)
        take = ((pos >= k0[:, None]) & (pos < np.minimum(k0 + 8, n_known - 1)[:, None])
                & (gap > 1e-3 * (1.0 + np.abs(srt[:, :-1]))))  # fmt: skip
        first = take.argmax(axis=1)
        c = np.where(take[rix, first], srt[rix, first] - np.minimum(0.5 * gap[rix, first], _LINE_OFFSET), c)
    last = srt[rix, np.maximum(np.minimum(k0 + 8, n_known - 1), 0)]
    return np.where(np.isnan(c), last - _LINE_OFFSET, c)
