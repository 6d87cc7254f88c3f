"""The rightmost real part over a team's factors, warm-started, for local searches over the delays.

A local search (delay scheduling, :mod:`delayform.design.scheduling`) asks
for Re of the dominant root at many nearby delay pairs. Each factor's roots
at the previous pair seed Newton's method at the next (the search moves
little between evaluations), with discretization seeds
(:mod:`delayform.analysis.roots.generator`) only where no root survives.

These values are **not certified**: they steer a search. The point a search
ends at is recomputed with the certified
:func:`~delayform.analysis.roots.dominant.dominant_root`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.roots.generator import _igd_seeds
from delayform.analysis.roots.problem import _cluster, _polish, _problem_of_factor
from delayform.analysis.roots.rightmost import _BATCH_SEEDS, _solve_rightmost
from delayform.characteristic import CharacteristicFactor

__all__ = ["WarmRightmost"]


class WarmRightmost:
    """Re of the rightmost root over some factors, as a function of (tau1, tau2), warm-started.

    Parameters
    ----------
    factors
        The factors of the paper's eq. 3 (e.g. from
        :func:`~delayform.analysis.roots.dominant.checked_factors`).

    Examples
    --------
    >>> from delayform.analysis.roots.dominant import checked_factors
    >>> from delayform.topology import paper_six
    >>> alpha = WarmRightmost(checked_factors(paper_six(), 1.0, 0.5))
    >>> alpha(1.0, 2.0) > 0.0  # point c of the paper's stability chart is unstable
    True
    """

    def __init__(self, factors: tuple[CharacteristicFactor, ...]) -> None:
        self.problems = tuple(_problem_of_factor(f) for f in factors)
        self.seeds: list[NDArray[np.complex128] | None] = [None] * len(self.problems)

    def __call__(self, tau1: float, tau2: float) -> float:
        """The largest real part of the roots found at these delays (uncertified)."""
        t1, t2 = np.array([float(tau1)]), np.array([float(tau2)])
        best = -np.inf
        for k, prob in enumerate(self.problems):
            seeds = self.seeds[k]
            if seeds is None:  # several roots, so a runner-up that overtakes is followed too
                seeds = _igd_seeds(prob, t1, t2, scale=1.5, k=_BATCH_SEEDS)[0]
                seeds = seeds[np.isfinite(seeds)]
            roots, ok = _polish(prob, seeds, t1, t2)
            found = roots[ok]
            if found.size == 0:
                self.seeds[k] = None
                found = _solve_rightmost(prob, float(t1[0]), float(t2[0])).roots
            else:
                self.seeds[k] = _cluster(found)
            best = max(best, float(found.real.max()))
        return best
