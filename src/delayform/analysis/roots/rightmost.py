"""Certified rightmost roots: one delay pair (robust path) and many pairs at once (batched path)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.roots.generator import (
    _degree_cap,
    _eigenvalues_at,
    _max_delay,
    _doublings,
    _needed_degree,
    _require_degrees,
    _root_scale,
)
from delayform.analysis.roots.long_delay import is_long, long_delay_roots
from delayform.analysis.roots.multiple import distinct_roots
from delayform.analysis.roots.problem import _polish, _Problem
from delayform.analysis.roots.argument_principle import (
    _batch_lines,
    _choose_line,
    _count_right_batch,
    _count_right_single,
    _known_reals,
    _LINE_OFFSET,
)
from delayform.errors import NotConvergedError

# =====================================================================
# batched rightmost roots over many delay pairs (for maps)
# =====================================================================
#: Seeds per delay pair polished in the batched path (the rightmost eigenvalues).
_BATCH_SEEDS = 8
#: Seeds further than this left of a pair's rightmost seed are not polished.
_SEED_WINDOW = 1.0
#: Spacing (in grid points) of the coarse sub-grid solved by discretization in maps.
_STRIDE = 5
#: Spacing (in grid points) of the coarse sub-grid solved by discretization in maps.


@dataclass(frozen=True)
class _SolveResult:
    """Roots right of the certified line Re s = ``line`` at discretization ``degree``.

    ``roots`` are roots of the solved q (no mirror images; the persistent zero
    of the paper's eq. 4 deflated), ``mult`` their multiplicities; ``degree`` is 0
    when the roots come from the long-delay chains
    (:mod:`~delayform.analysis.roots.long_delay`).
    """

    roots: NDArray[np.complex128]
    mult: NDArray[np.int64]
    line: float
    degree: int


def _solve_rightmost(prob: _Problem, t1: float, t2: float, *, where: str | None = None) -> _SolveResult:
    """All roots right of a certified line, for one delay pair (the robust path).

    Long delays (delay x root scale above
    :data:`~delayform.analysis.roots.long_delay.LONG_REACH`) are first solved
    on the root chains, with no discretization. Otherwise, or when that is not
    certified, the discretization's degree starts where the root scale needs it and
    doubles up to :func:`_degree_cap`; the cost of every degree it may reach
    is checked against the machine's budget before the first one is solved. ``where`` names the
    delays in messages (default ``(tau1, tau2) = (t1, t2)``).
    """
    where = where or f"(tau1, tau2) = ({t1:g}, {t2:g})"
    hmax = _max_delay(prob, t1, t2)
    if is_long(hmax, _root_scale(prob)):  # long delays: the root chains, linear in the delay
        found = long_delay_roots(prob, float(t1), float(t2))
        if found is not None:
            return _SolveResult(found[0], found[1], found[2], 0)
    a1, a2 = np.asarray(t1), np.asarray(t2)
    N = min(_needed_degree(hmax, _root_scale(prob)), _degree_cap(prob, hmax))
    cap = _degree_cap(prob, hmax)
    # up front, the whole path: every degree it may double through, not only the first
    _require_degrees(prob, _doublings(N, cap), hmax)
    partial: NDArray[np.complex128] = np.zeros(0, dtype=np.complex128)
    while True:
        eig = _eigenvalues_at(prob, N, hmax, float(t1), float(t2))
        if prob.deflate_zero:
            eig = np.delete(eig, np.argmin(np.abs(eig)))
        roots, ok = _polish(prob, eig, a1, a2)
        roots, mult = distinct_roots(prob, roots[ok], float(t1), float(t2))
        partial = roots
        if roots.size:
            reals, m = _known_reals(prob, roots, mult)
            c = _choose_line(reals, float(roots.real.max()), min(_LINE_OFFSET, 2.0 / max(hmax, 1e-300)))
            expected = int(m[reals > c].sum())
            if _count_right_single(prob, t1, t2, c) == expected:
                keep = roots.real > c
                return _SolveResult(roots[keep], mult[keep], c, N)
        if hmax == 0.0 or N >= cap:
            raise NotConvergedError(
                f"could not make sure that no characteristic root lies right of the rightmost one found "
                f"at {where}; roots there are too many or too close together, "
                "try slightly different delays",
                partial=partial,
            )
        N = min(cap, 2 * N)



def _pick_rightmost(prob: _Problem, roots: NDArray[np.complex128]) -> complex:
    if roots.size == 0:
        raise NotConvergedError(
            "no characteristic root was found right of the line that was checked; try slightly different delays",
            partial=roots,
        )
    top = roots[np.argmax(roots.real)]
    # of a conjugate pair (or the mirror image), report the member with Im >= 0
    if prob.mirror or prob.is_real or np.all([np.all(c.imag == 0) for c, _, _ in prob.terms]):
        # a real root's Newton iterate may keep an imaginary part far below rounding (1e-49)
        imag = 0.0 if abs(top.imag) <= 1e-15 * (1.0 + abs(top.real)) else abs(top.imag)
        top = complex(top.real, imag)
    return complex(top)



def _batch_distinct(
    roots: NDArray[np.complex128], ok: NDArray[np.bool_]
) -> NDArray[np.complex128]:
    """Per row, the distinct accepted roots first (sorted), NaN after them.

    Rows are sorted (numpy orders complex numbers by real, then imaginary
    part), so seeds that reached the same root sit side by side; a repeat
    that is not adjacent only inflates the expected count, which the
    certificate then rejects (the point is recomputed), never a wrong root.
    """
    r = np.sort(np.where(ok, roots, np.nan), axis=1)  # NaN sorts last
    close = np.abs(r[:, 1:] - r[:, :-1]) <= 1e-7 * (1.0 + np.abs(r[:, :-1]))
    dup = np.concatenate([np.zeros((r.shape[0], 1), dtype=bool), close], axis=1)
    r = np.where(dup, np.nan, r)
    keep = np.isfinite(r).sum(axis=1).max(initial=0)
    order = np.argsort(~np.isfinite(r), axis=1, kind="stable")
    return r[np.arange(r.shape[0])[:, None], order[:, : max(int(keep), 1)]]



def _certify(
    prob: _Problem, t1: NDArray[np.float64], t2: NDArray[np.float64], seeds: NDArray[np.complex128]
) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.complex128]]:
    """Polish seeds (B, K) at each pair; certify the rightmost; return (rightmost, certified, roots).

    For a real q only seeds with Im >= 0 are polished and the conjugates of
    the roots added afterwards (half the Newton work).
    """
    if prob.is_real:
        seeds = np.where(seeds.imag >= 0.0, seeds, np.nan)
    if prob.deflate_zero:  # a seed at the persistent 0 cannot move under Maehly's step
        seeds = np.where(np.abs(seeds) < 1e-6, -1e-2, seeds)
    # seeds far left of a row's rightmost one cannot matter for the line c (within
    # _LINE_OFFSET of the top); dropping them saves Newton steps, and a wrong
    # drop only costs a rejected certificate
    with np.errstate(invalid="ignore"):
        top_seed = np.nanmax(np.where(np.isfinite(seeds), seeds.real, -np.inf), axis=1)
        seeds = np.where(seeds.real >= top_seed[:, None] - _SEED_WINDOW, seeds, np.nan)
    roots, ok = _polish(prob, seeds, t1[:, None], t2[:, None])
    ok &= np.isfinite(seeds)
    if prob.is_real:  # distinct members with Im >= 0 first, then their mirror images
        roots = _batch_distinct(np.where(roots.imag < 0.0, np.conj(roots), roots), ok)
        pair = np.abs(roots.imag) > 1e-9 * (1.0 + np.abs(roots))
        roots = np.concatenate([roots, np.where(pair, np.conj(roots), np.nan)], axis=1)
    else:
        roots = _batch_distinct(roots, ok)
    c, expected, top = _batch_lines(prob.deflate_zero, roots)
    good = np.isfinite(top) & np.isfinite(c)
    counts = np.full(t1.size, np.nan)
    if good.any():
        counts[good] = _count_right_batch(prob, t1[good], t2[good], c[good])
    certified = good & (counts == expected)
    best = np.argmax(np.where(np.isnan(roots.real), -np.inf, roots.real), axis=1)
    return roots[np.arange(t1.size), best], certified, roots


