"""Certified rightmost roots of retarded quasi-polynomials at long delays, without a discretization.

At a delay H far above the root scale (H |s| of 100 to 1000 and more) the
roots near the rightmost one are many and close together: they lie on
*chains* with spacing about 2 pi / H along the imaginary direction, so the
number of roots in a fixed box grows linearly with H, and the Chebyshev
discretization of the generator, which must resolve e^{s theta} on
[-H, 0], needs a degree proportional to H and a dense eigenvalue problem of
cost proportional to H^3. This path finds the roots near the rightmost one
directly on their chains.

Method
------
With the terms grouped by delay, ``q(s) = sum_j p_j(s) e^{-h_j s}`` with
``h_0 = 0`` (the principal term; the paper's eq. 5 at fixed delays, or a
:class:`~delayform.quasipolynomial.QuasiPolynomial`). Where two terms
i < j dominate, the roots satisfy ``e^{-(h_j - h_i) s} = -p_i(s) / p_j(s)``
(the classical root chains, Bellman and Cooke, *Differential-Difference
Equations*, 1963, ch. 12), i.e. they are fixed points of

    s = -(Log(-p_i(s) / p_j(s)) + 2 pi i k) / (h_j - h_i),   k an integer.

In the scaled variable ``w = (h_j - h_i) s`` this is a problem with unit
delay and a large parameter: the map contracts by about
``|p_i'/p_i - p_j'/p_j| / (h_j - h_i)``, so a few iterations from
``s = -2 pi i k / (h_j - h_i)`` put one seed on each root of the chain, on
the curve ``Re s ~ ln |p_i(s) / p_j(s)| / (h_j - h_i)``. For one delay every
root is such a fixed point (for one k). The roots of the principal and of the
delay-free polynomial seed the roots far right of the chains (where e^{-H s}
is small). Newton's method on q itself polishes every seed
(:func:`~delayform.analysis.roots.problem._polish`); for a real q the mirror
image of every root found is added (a seed next to a zero of p_i, where the
map contracts least, may reach a root whose conjugate's seed went elsewhere).

Certificate: the line Re s = c is placed in the widest gap between the real
parts of the roots found within ``2 / H`` of the rightmost one (so that
e^{-H c} and with it the Cauchy radius stay moderate), and the
argument-principle count on q along it
(:func:`~delayform.analysis.roots.argument_principle._count_right_single`)
must equal the number of roots found right of it. Seeds cover every chain up
to the Cauchy radius of that line, beyond which q has no root right of it;
a root that no seed reached makes the count larger, and the caller then
uses the discretization (never a wrong root).

Cost: about ``Omega H / pi`` seeds per pair of delay groups (``Omega`` the
Cauchy radius, of the size of the roots), a fixed number of vectorized
iterations each, and a certificate whose samples also grow linearly with H:
linear in the delay instead of cubic.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.roots.argument_principle import _cauchy_radius, _count_right_single, _known_reals
from delayform.analysis.roots.problem import _horner, _multiplicity, _polish, _Problem

#: Fixed-point iterations on a chain before Newton on q takes over.
_CHAIN_STEPS = 12
#: Most seeds the chain path polishes (beyond, the discretization's budget decides).
_MAX_SEEDS = 400_000
#: delay x root scale above which the chain path is tried before any discretization
LONG_REACH = 40.0
#: The certifying line keeps within this many 1/H of the rightmost root (e^{-H c} stays below e^2 |e^{-H top}|).
_WINDOW = 2.0

Groups = tuple[tuple[float, NDArray[np.complex128]], ...]


def delay_groups(prob: _Problem, t1: float, t2: float) -> Groups:
    """The terms of q at (t1, t2) summed per delay: ``((h_0 = 0, p_0), (h_1, p_1), ...)``, h ascending.

    Terms with equal delays (tau1 = tau2 in the paper's eq. 5, commensurate
    delays) are one group, as they are one term of q at these delays.
    """
    merged: dict[float, NDArray[np.complex128]] = {}
    for c, a, b in prob.terms:
        h = float(a * t1 + b * t2)
        acc = merged.get(h)
        if acc is None:
            merged[h] = np.array(c, dtype=np.complex128)
        else:
            size = max(acc.size, c.size)
            total = np.zeros(size, dtype=np.complex128)
            total[: acc.size] += acc
            total[: c.size] += c
            merged[h] = total
    return tuple((h, merged[h]) for h in sorted(merged) if h == 0.0 or np.any(merged[h]))


def longest_delay(prob: _Problem, t1: float, t2: float) -> float:
    """The largest delay of q's terms at (t1, t2)."""
    return max(float(a * t1 + b * t2) for _, a, b in prob.terms)


def _chain_pairs(groups: Groups) -> list[tuple[NDArray[np.complex128], NDArray[np.complex128], float]]:
    """Every pair (p_i, p_j, h_j - h_i) of delay groups with h_i < h_j: the possible chains."""
    return [(groups[i][1], groups[j][1], groups[j][0] - groups[i][0])
            for i in range(len(groups)) for j in range(i + 1, len(groups))]  # fmt: skip


def seed_count(groups: Groups, omega: float) -> int:
    """Seeds :func:`chain_seeds` places for chains up to |Im s| <= omega (its memory and time scale)."""
    return sum(2 * _k_reach(dh, omega) + 1 for _, _, dh in _chain_pairs(groups))


def _k_reach(dh: float, omega: float) -> int:
    # Im s = -(arg + 2 pi k) / dh covers |Im s| <= omega for |k| <= omega dh / (2 pi) + 1
    return int(math.ceil(omega * dh / (2.0 * math.pi))) + 1


def chain_seeds(groups: Groups, omega: float) -> NDArray[np.complex128]:
    """Seeds on every chain of every pair of delay groups, up to |Im s| <= omega (module docstring)."""
    out = []
    for p_i, p_j, dh in _chain_pairs(groups):
        kk = _k_reach(dh, omega)
        twopik = 2j * np.pi * np.arange(-kk, kk + 1, dtype=float)
        s = -twopik / dh
        with np.errstate(all="ignore"):  # near a zero of p_i or p_j the map leaves: Newton or the count decides
            # one branch of arg(-p_i / p_j) for the whole chain, unwrapped along the starting points
            # (spaced 2 pi / dh, over which it turns little): with principal values two k would share
            # a root where -p_i / p_j crosses the negative axis, and one root would get no seed
            theta = _unwrapped(np.angle(-_horner(p_i, s) / _horner(p_j, s)))
            for _ in range(_CHAIN_STEPS):
                v = -_horner(p_i, s) / _horner(p_j, s)
                theta = theta + np.angle(v * np.exp(-1j * theta))  # the branch continued from the seed's
                s = -(np.log(np.abs(v)) + 1j * theta + twopik) / dh
        out.append(s[np.isfinite(s)])
    return np.concatenate(out) if out else np.zeros(0, dtype=np.complex128)


def _unwrapped(angle: NDArray[np.float64]) -> NDArray[np.float64]:
    """np.unwrap over the finite entries (a seed on a zero of p_i or p_j gives NaN)."""
    out = angle.copy()
    ok = np.isfinite(angle)
    out[ok] = np.unwrap(angle[ok])
    return out


def polynomial_seeds(groups: Groups) -> NDArray[np.complex128]:
    """Roots of the principal polynomial and of the delay-free one (every delay set to 0)."""
    free = np.zeros(max(p.size for _, p in groups), dtype=np.complex128)
    for _, p in groups:
        free[: p.size] += p
    seeds = [np.roots(c[::-1]) for c in (groups[0][1], free) if c.size > 1 and c[-1] != 0.0]
    out = np.concatenate(seeds) if seeds else np.zeros(0, dtype=np.complex128)
    return out + 1e-3 * (1.0 + np.abs(out)) * (out == 0.0)  # Newton cannot leave an exact 0 of q'


def distinct(roots: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """The distinct points among polished seeds (vectorized; many seeds reach the same root).

    Sorted by imaginary then real part, a point within 1e-9 (relative) of its
    predecessor is a repeat. A repeat that sorts apart only inflates the
    expected count, which the certificate then rejects, never a wrong root.
    """
    if roots.size == 0:
        return roots
    r = roots[np.lexsort((roots.real, roots.imag))]
    repeat = np.abs(np.diff(r)) <= 1e-9 * (1.0 + np.abs(r[1:]))
    return r[np.concatenate([[True], ~repeat])]


def certifying_line(reals: NDArray[np.float64], top: float, window: float) -> float:
    """A line Re s = c in [top - window, top) as far as possible from every known real part.

    ``reals`` are the known roots' real parts (any order). The candidates are
    the midpoints of the gaps between consecutive real parts, clamped to the
    window; the one farthest from its nearest root is taken (the certificate
    then needs the fewest samples near the line).
    """
    lo = top - window
    below = reals[reals < lo]
    pts = np.unique(np.concatenate([reals[reals >= lo], below.max(initial=-np.inf) * np.ones(1)]))[::-1]
    upper, lower = pts[:-1], pts[1:]
    c = np.clip(0.5 * (upper + lower), lo, top)
    clearance = np.minimum(upper - c, c - lower)
    return float(c[np.argmax(clearance)]) if c.size else lo


def is_long(hmax: float, scale: float) -> bool:
    """True when the delay times the root scale is long enough for the chain path to be tried first."""
    return hmax * scale > LONG_REACH


def long_delay_roots(
    prob: _Problem, t1: float, t2: float
) -> tuple[NDArray[np.complex128], NDArray[np.int64], float] | None:
    """The roots right of a certified line Re s = c by the chain seeds (module docstring), or None.

    Returns ``(roots, mult, c)``: every root of q (no mirror images; the
    persistent zero of the paper's eq. 4 deflated) right of c, with
    multiplicities. None when the count does not confirm them, or when the
    chains would need more than :data:`_MAX_SEEDS` seeds; the caller then
    falls back on the discretization (with its own budget).
    """
    groups = delay_groups(prob, t1, t2)
    H = groups[-1][0]
    if H <= 0.0:
        return None
    window = _WINDOW / H
    a1, a2 = np.asarray(t1, dtype=float), np.asarray(t2, dtype=float)
    polynomial = polynomial_seeds(groups)
    real = all(np.all(p.imag == 0.0) for _, p in groups)
    # the chains' reach: first up to the Cauchy radius of Re s = 0 (every root right of 0 lies
    # within it), then up to that of the line the certificate may use, left of the roots found
    c_lo, covered = 0.0, -1.0
    roots = np.zeros(0, dtype=np.complex128)
    for _ in range(6):
        omega = float(_cauchy_radius(prob.terms, np.asarray(c_lo), a1, a2))
        if not math.isfinite(omega) or seed_count(groups, omega) > _MAX_SEEDS:
            return None
        if omega > covered:
            seeds = np.concatenate([polynomial, chain_seeds(groups, omega)])
            polished, ok = _polish(prob, seeds, a1, a2)
            roots = polished[ok]
            if real:  # q(conj s) = conj q(s): a root's mirror image is one too, with the same residual
                roots = np.concatenate([roots, np.conj(roots)])
            roots = distinct(roots)
            covered = omega
        if roots.size == 0:
            c_lo -= 4.0 * window  # no root within reach yet: look further left
            continue
        top = float(roots.real.max())
        if top - window >= c_lo:
            return _certified(prob, roots, top, window, t1, t2)
        c_lo = top - window
    return None


def _certified(
    prob: _Problem, roots: NDArray[np.complex128], top: float, window: float, t1: float, t2: float
) -> tuple[NDArray[np.complex128], NDArray[np.int64], float] | None:
    """``roots`` right of a line in the window, with multiplicities, when the count there confirms them."""
    near = roots[roots.real >= top - 2.0 * window]
    mult = _multiplicity(prob, near, t1, t2)
    reals, m = _known_reals(prob, near, mult)  # with the persistent zero of the paper's eq. 4 when deflated
    c = certifying_line(reals, top, window)
    expected = int(m[reals > c].sum())
    if _count_right_single(prob, t1, t2, c) != expected:
        return None
    right = near.real > c
    return near[right], mult[right], c
