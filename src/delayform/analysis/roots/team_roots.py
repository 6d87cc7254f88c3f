"""Every characteristic root of every factor in a rectangle, for a whole team at once.

:func:`delayform.analysis.roots.dominant.roots_in` lists the roots of one factor of
the paper's eq. 3; a team of thousands of agents has thousands of factors, and a
loop over them pays a full-size discretization, a Python round trip per
Newton step and a rectangle-wide clustering for each. Here the factors of
the paper's eq. 3 are solved as one family (the structure of
:mod:`delayform.analysis.roots.family.solve`: every factor is
``s^2 + D s + P - lam (P e^{-tau1 s} + D s e^{-tau2 s})`` with its own lam):

1. the seeds of all factors come from stacked eigenvalue calls on the
   reduced Chebyshev generator of size N + 2 (``_seeds._generator_blocks``;
   the full one has size 2 (N + 1)), real lam in real arithmetic, at the
   degree :func:`roots_in` would start with;
2. Newton polishes every seed of every factor in one vectorized loop;
3. per factor, the roots found in the rectangle are checked against the
   count certified by the argument principle on its boundary, exactly as in
   :func:`roots_in`. A factor whose count is not met (or cannot be certified
   at once, a root on the boundary), the centroid factor (paper, eq. 4, its
   persistent zero) and factors without delay go through :func:`roots_in`
   itself, so the result is never less certain than the per-factor loop.

Conventions as in :mod:`delayform.analysis.roots.dominant`: a conjugate pair
factor lists the roots of lam and of conj(lam); the centroid factor's
persistent root 0 is included (the plain root set of q).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_delay, validated
from delayform.analysis.roots.actuated import actuated_roots_in
from delayform.analysis.roots.family.solve import family_reach_scales
from delayform.analysis.roots.family.polish import _polish_rows, _q
from delayform.analysis.roots.family.rows import _lams, _Rows
from delayform.analysis.roots.family.seeds import _generator_blocks
from delayform.analysis.roots.generator import _initial_degree, _require_resolvable
from delayform.analysis.roots.problem import _TINY_DELAY, Region, _cluster, _multiplicity, _problem_of_factor
from delayform.analysis.roots.single import _check_region, _in_region, roots_in
from delayform.analysis.roots.dominant import checked_factors
from delayform.characteristic import CharacteristicFactor
from delayform.topology import Topology

__all__ = ["factor_roots_in"]

#: Factors per stacked eigenvalue call (bounds memory: (N + 2)^2 complex numbers each).
_CHUNK = 128


@validated()
def factor_roots_in(
    topology: Topology,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    region: ArrayLike,
    *,
    progress: Callable[[int, int], None] | None = None,
    actuation_delay: float = 0.0,
) -> tuple[tuple[CharacteristicFactor, NDArray[np.complex128]], ...]:
    """The roots in a rectangle of every factor of eq. factorized: :func:`roots_in` for a whole team.

    Parameters
    ----------
    topology
        Communication topology (C = Delta^-1 A); it must have a spanning tree.
    P, D
        Positive gains of the paper's eq. 1.
    tau1, tau2
        Non-negative delays (s) on positions and on velocities.
    region
        (re_min, re_max, im_min, im_max) of the rectangle.
    progress
        Called as ``progress(done, total)`` while the factors are solved
        (total = the number of factors).
    actuation_delay
        tau_a >= 0 (s): the factors with the delayed own-state terms, one by
        one (:func:`~delayform.analysis.roots.actuated.actuated_roots_in`); 0: the batched path.

    Returns
    -------
    tuple of (CharacteristicFactor, ndarray of complex)
        One pair per factor, in the order of
        :func:`delayform.characteristic.factors`: the factor and its roots in
        the rectangle, as :func:`roots_in` returns them (multiplicity
        repeated, sorted by decreasing real part, each with relative residual
        <= RESIDUAL_TOL, the count certified on the rectangle's boundary).

    Raises
    ------
    ResourceLimitError
        Before any work, when the rectangle reaches too far from the origin
        for these delays (the message names the largest |s| allowed).
    NotConvergedError
        As :func:`roots_in`, for a factor whose roots cannot be listed.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> per_factor = factor_roots_in(paper_six(), 1.0, 0.5, 0.3, 0.2, (-2.0, 1.0, -0.01, 10.0))
    >>> [len(roots) for _, roots in per_factor]
    [2, 1, 1, 1, 2]
    """
    fs = checked_factors(topology, P, D)
    t1, t2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    region = _check_region(region)
    ta = check_delay("actuation_delay", actuation_delay)
    if ta > 0.0:
        found = []
        for k, f in enumerate(fs):
            found.append((f, actuated_roots_in(f, t1, t2, ta, region)))
            if progress is not None:
                progress(k + 1, len(fs))
        return tuple(found)
    hmax = max(t1, t2)
    if hmax >= _TINY_DELAY:
        _require_resolvable(region, hmax)  # every factor with lam != 0 has both delays
    done, total = 0, len(fs)
    out: list[NDArray[np.complex128] | None] = [None] * total
    lam, real, centroid = _lams(fs)
    batch = ~centroid & (lam != 0.0) & (hmax >= _TINY_DELAY)
    x0, x1, y0, y1 = region
    radius = max(abs(complex(x, y)) for x in (x0, x1) for y in (y0, y1))
    degree = np.array([_initial_degree(hmax, max(radius, s)) for s in family_reach_scales(fs)])
    for N in np.unique(degree[batch]):
        for is_real in (True, False):
            idx = np.flatnonzero(batch & (degree == N) & (real == is_real))
            for start in range(0, idx.size, _CHUNK):
                chunk = idx[start : start + _CHUNK]
                for k, roots in zip(chunk, _solve_chunk(fs, lam, chunk, int(N), is_real, t1, t2, region)):
                    out[k] = roots if roots is not None else roots_in(fs[k], t1, t2, region)
                done += chunk.size
                if progress is not None:
                    progress(done, total)
    for k in np.flatnonzero(~batch):
        out[k] = roots_in(fs[k], t1, t2, region)
        done += 1
        if progress is not None:
            progress(done, total)
    return tuple((f, roots) for f, roots in zip(fs, out, strict=True) if roots is not None)  # all are set


@np.errstate(all="ignore")  # far-left spurious seeds overflow e^{-tau s}; they fail the residual test
def _solve_chunk(
    fs: tuple[CharacteristicFactor, ...], lam: NDArray[np.complex128], chunk: NDArray[np.int64], N: int,
    is_real: bool, t1: float, t2: float, region: Region,
) -> list[NDArray[np.complex128] | None]:
    """The roots in the rectangle of the factors ``chunk`` (one degree N), None where the count is not met."""
    P, D = float(fs[0].P), float(fs[0].D)
    M0, M1 = _generator_blocks(N, t1, t2, P, D)
    lc = lam[chunk]
    seeds = np.linalg.eigvals(M0 + (lc.real if is_real else lc)[:, None, None] * M1).astype(np.complex128)
    F = chunk.size
    rows = _Rows(lc, np.full(F, t1), np.full(F, t2), np.full(F, is_real), np.zeros(F, dtype=bool), P, D)
    polished, ok = _polish_rows(seeds, rows)
    # a pair factor is solved through lam alone: its roots in the mirrored rectangle count too
    x0, x1, y0, y1 = region
    yy = max(abs(y0), abs(y1))
    counted = (x0, x1, y0, y1) if is_real else (x0, x1, -yy, yy)
    expected = _rectangle_counts(lc, t1, t2, P, D, counted)
    cx0, cx1, cy0, cy1 = counted
    pad = 1e-6 * (1.0 + max(abs(v) for v in counted))  # clustering next to an edge sees both sides
    out: list[NDArray[np.complex128] | None] = []
    for k, roots, good, want in zip(chunk, polished, ok, expected):
        if not np.isfinite(want):  # a root on (or next to) the boundary: roots_in nudges the rectangle
            out.append(None)
            continue
        cand = roots[good]
        near = (cand.real > cx0 - pad) & (cand.real < cx1 + pad) & (cand.imag > cy0 - pad) & (cand.imag < cy1 + pad)
        distinct = _cluster(cand[near])
        inside = distinct[(distinct.real > cx0) & (distinct.real < cx1) & (distinct.imag > cy0) & (distinct.imag < cy1)]
        if _simple(inside, lam[k], t1, t2, P, D).all():
            found = inside
        else:  # a (near-)multiple root: the generic test of every derivative
            prob = _problem_of_factor(fs[k])
            found = np.repeat(inside, np.maximum(_multiplicity(prob, inside, t1, t2), 1))
        if found.size != want:
            out.append(None)
            continue
        out.append(_in_region(found if is_real else np.concatenate([found, np.conj(found)]), region))
    return out


def _simple(
    s: NDArray[np.complex128], lam: complex, t1: float, t2: float, P: float, D: float
) -> NDArray[np.bool_]:
    """Roots that are simple by the first test of ``_quasi._multiplicity``: |q'(s)| above 1e-5 of its terms' scale.

    q'(s) = 2 s + D + lam P tau1 e^{-tau1 s} - lam D e^{-tau2 s} + lam D tau2 s e^{-tau2 s}; the
    scale sums the moduli of those terms with |s| floored at 1, as ``_quasi._nth_derivative`` does.
    """
    e1, e2 = np.abs(lam) * np.exp(-t1 * s), np.abs(lam) * np.exp(-t2 * s)
    _, dq, _, _ = _q(s, np.full(s.shape, lam), np.full(s.shape, t1), np.full(s.shape, t2), P, D)
    rho = np.maximum(np.abs(s), 1.0)
    scale = 2.0 * rho + D + P * t1 * np.abs(e1) + D * np.abs(e2) * (1.0 + t2 * rho)
    return np.abs(dq) > 1e-5 * scale


def _rectangle_counts(
    lam: NDArray[np.complex128], t1: float, t2: float, P: float, D: float, rect: Region,
    *, max_pieces: int = 100_000,
) -> NDArray[np.float64]:
    """Certified number of roots inside the rectangle for each lam of the family (NaN: not certified).

    The walk of ``certificate._segment_winding`` around the four edges, all
    factors' edges at once: 65 samples per edge, then every piece
    [s_a, s_b] with ``min(|q(s_a)|, |q(s_b)|) <= L |s_b - s_a| / 2`` is
    bisected, L the bound of |q'| over ``|s| <= max(|s_a|, |s_b|)``,
    ``Re s >= min(Re s_a, Re s_b)`` of ``certificate._lipschitz``, written out
    for the family: ``2 rho + D + |lam| (P tau1 e^{-tau1 x} + D e^{-tau2 x} (1 + tau2 rho))``.
    """
    F = lam.size
    x0, x1, y0, y1 = rect
    corners = np.array([complex(x0, y0), complex(x1, y0), complex(x1, y1), complex(x0, y1)])
    a = np.tile(corners, F)  # edge e of factor e // 4 runs from a[e] to b[e], counterclockwise
    b = np.tile(np.roll(corners, -1), F)
    owner = np.repeat(np.arange(F), 4)
    absl = np.abs(lam)

    def q_at(edge: NDArray[np.int64], u: NDArray[np.float64]) -> NDArray[np.complex128]:
        s = a[edge] + u * (b[edge] - a[edge])
        return _q(s, lam[owner[edge]], t1, t2, P, D)[0]

    u0 = np.linspace(0.0, 1.0, 65)
    edge = np.repeat(np.arange(4 * F), 64)
    ua, ub = np.tile(u0[:-1], 4 * F), np.tile(u0[1:], 4 * F)
    q0 = q_at(np.repeat(np.arange(4 * F), 65), np.tile(u0, 4 * F)).reshape(4 * F, 65)
    failed = ~np.all(np.isfinite(q0) & (q0 != 0.0), axis=1)
    qa, qb = q0[:, :-1].ravel(), q0[:, 1:].ravel()
    total = np.zeros(4 * F)
    for _ in range(64):  # 64 bisections: pieces far below the rounding of s
        sa, sb = a[edge] + ua * (b[edge] - a[edge]), a[edge] + ub * (b[edge] - a[edge])
        rho, x = np.maximum(np.abs(sa), np.abs(sb)), np.minimum(sa.real, sb.real)
        g = absl[owner[edge]]
        lip = 2.0 * rho + D + g * (P * t1 * np.exp(-t1 * x) + D * np.exp(-t2 * x) * (1.0 + t2 * rho))
        bad = np.minimum(np.abs(qa), np.abs(qb)) <= 0.5 * lip * np.abs(sb - sa)
        total += np.bincount(edge[~bad], np.angle(qb[~bad] / qa[~bad]), minlength=4 * F)
        if not bad.any():
            break
        edge, ua, ub, qa, qb = edge[bad], ua[bad], ub[bad], qa[bad], qb[bad]
        crowded = np.bincount(edge, minlength=4 * F) > max_pieces
        failed |= crowded
        keep = ~crowded[edge]
        edge, ua, ub, qa, qb = edge[keep], ua[keep], ub[keep], qa[keep], qb[keep]
        um = 0.5 * (ua + ub)
        qm = q_at(edge, um)
        failed[edge[~np.isfinite(qm) | (qm == 0.0)]] = True
        edge = np.concatenate([edge, edge])
        ua, ub = np.concatenate([ua, um]), np.concatenate([um, ub])
        qa, qb = np.concatenate([qa, qm]), np.concatenate([qm, qb])
    else:
        failed[edge] = True
    count = total.reshape(F, 4).sum(axis=1) / (2.0 * np.pi)
    good = ~failed.reshape(F, 4).any(axis=1) & (np.abs(count - np.round(count)) < 0.1)
    return np.where(good, np.round(count), np.nan)
