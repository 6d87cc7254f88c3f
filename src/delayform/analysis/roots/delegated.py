"""The solvers that roots' public functions hand two kinds of problem to, lent by the packages above.

``roots`` is the bottom of :mod:`delayform.analysis`. Two kinds of problem its
public functions accept are solved elsewhere, by packages that themselves
count roots with this package's argument principle and so sit above it:

* a **neutral** quasi-polynomial, given to :func:`~delayform.analysis.roots.roots_in`,
  :func:`~delayform.analysis.roots.count_roots_right_of` or
  :func:`~delayform.analysis.roots.rightmost_root`, is solved by
  :mod:`delayform.analysis.neutral` (only right of its essential spectrum);
* **per-link delays** (``N x N`` arrays), given to
  :func:`~delayform.analysis.roots.dominant_root`, are solved by
  :mod:`delayform.analysis.network` (the determinant of the matrix
  quasi-polynomial, no factorization).

roots cannot import them (that would be an import cycle), so they lend their
solvers here: :mod:`delayform.analysis` does so when it is first imported,
which Python does before any module inside it, so the functions above always
find them. :func:`neutral` and :func:`per_link` are how roots reaches them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform.topology import Topology

__all__ = ["NeutralSolver", "PerLinkSolver", "PerLinkRoot", "lend", "neutral", "per_link"]


class PerLinkRoot(Protocol):
    """What :func:`~delayform.analysis.roots.dominant_root` returns for per-link delays.

    :class:`~delayform.analysis.network.LinkDominantRoot` is the one type
    that has it; it answers like a
    :class:`~delayform.analysis.roots.DominantRoot` does.
    """

    @property
    def root(self) -> complex: ...  # pragma: no cover - a protocol

    @property
    def is_stable(self) -> bool: ...  # pragma: no cover - a protocol

    @property
    def time_constant(self) -> float: ...  # pragma: no cover - a protocol


@dataclass(frozen=True)
class NeutralSolver:
    """The solver of neutral quasi-polynomials (:mod:`delayform.analysis.neutral`).

    Attributes
    ----------
    roots_in
        ``roots_in(qp, *taus, region=...) -> (roots, multiplicities)``.
    count_right_of
        ``count_right_of(qp, *taus, c=...) -> int``.
    rightmost_root
        ``rightmost_root(qp, *taus) -> complex``.
    """

    roots_in: Callable[..., tuple[NDArray[np.complex128], NDArray[np.int64]]]
    count_right_of: Callable[..., int]
    rightmost_root: Callable[..., complex]


@dataclass(frozen=True)
class PerLinkSolver:
    """The solver of per-link delays (:mod:`delayform.analysis.network`).

    Attributes
    ----------
    dominant_root
        ``dominant_root(topology, P, D, tau1, tau2)`` with ``N x N`` delays:
        the certified dominant root of the matrix quasi-polynomial.
    uniform_delays
        ``uniform_delays(topology, P, D, tau1, tau2) -> (tau1, tau2)``: the
        one pair of per-link delays equal on every link; DelayError otherwise.
    """

    dominant_root: Callable[[Topology, float, float, ArrayLike, ArrayLike], PerLinkRoot]
    uniform_delays: Callable[[Topology, float, float, ArrayLike, ArrayLike], tuple[float, float]]


_lent: dict[str, NeutralSolver | PerLinkSolver] = {}


def lend(*, neutral: NeutralSolver, per_link: PerLinkSolver) -> None:
    """Hand roots the solvers of the packages above it (done once, by :mod:`delayform.analysis`).

    Parameters
    ----------
    neutral
        The solver of neutral quasi-polynomials.
    per_link
        The solver of per-link delays.
    """
    _lent["neutral"] = neutral
    _lent["per_link"] = per_link


def _lent_solver(kind: str) -> NeutralSolver | PerLinkSolver:
    try:
        return _lent[kind]
    except KeyError:  # only when this module was loaded without its package's __init__
        raise RuntimeError(f"no {kind} solver was lent to delayform.analysis.roots; "
                           "import delayform.analysis first") from None  # fmt: skip


def neutral() -> NeutralSolver:
    """The solver of neutral quasi-polynomials lent by :mod:`delayform.analysis.neutral`."""
    return _lent_solver("neutral")  # type: ignore[return-value]


def per_link() -> PerLinkSolver:
    """The solver of per-link delays lent by :mod:`delayform.analysis.network`."""
    return _lent_solver("per_link")  # type: ignore[return-value]
