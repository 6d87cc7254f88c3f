"""The eigenvalue plane of a clicked point, as the explorer's region panel draws it.

At fixed gains and delays every factor of the paper's eq. 3 is
``q(s, lam) = s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s})`` with an
eigenvalue lam of C as parameter, and
:func:`delayform.analysis.plane.region.lambda_region` gives, for every lam, the
number NU(lam) of roots with Re s > 0. The panel shows the boundary curve
``L(j omega)`` (where roots cross the imaginary axis), NU(lam) on a grid of the
square ``|Re lam|, |Im lam| <= radius`` (the stable set is where it is 0), the
unit circle (C is row-stochastic, so its eigenvalues lie in the closed unit
disc) and the team's eigenvalues, each with its own NU. The team is stable
exactly when every eigenvalue, the centroid's lam = 1 aside (Lemma 2), has
NU = 0; the sum over the eigenvalues, multiplicity counted, is the team's NU.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.plane.region import LambdaRegion, lambda_region
from delayform.topology import Topology

__all__ = ["RegionReport", "region_report"]

#: half-width of the drawn square of the lam plane (the unit disc and a margin)
RADIUS = 1.6
#: points per axis of the NU shading (about 10 ms at the paper's points)
GRID = 81
_DECIMALS = 5


def _pairs(z: NDArray[np.complex128]) -> dict[str, list[Any]]:
    """Real and imaginary parts as two JSON lists, NaN (a break in the curve) as None."""
    re = np.round(z.real, _DECIMALS)
    im = np.round(z.imag, _DECIMALS)
    ok = np.isfinite(re) & np.isfinite(im)
    return {"re": np.where(ok, re, None).tolist(), "im": np.where(ok, im, None).tolist()}


@dataclass(frozen=True, eq=False)
class RegionReport:
    """The eigenvalue plane at one point: boundary curve, NU shading, the team's eigenvalues.

    Attributes
    ----------
    region
        The :class:`~delayform.analysis.plane.region.LambdaRegion` (gains and delays inside).
    boundary
        ``L(j omega)`` for omega from -max to max, NaN where ``|L| > radius``.
    grid
        The ``GRID`` abscissae (and ordinates) of the shading, over ``[-radius, radius]``.
    counts
        NU(lam) on the grid, ``(GRID, GRID)``, row = imaginary part.
    eigenvalues
        The eigenvalues of C.
    eigenvalue_counts
        NU of each eigenvalue (0: stable; the centroid's root s = 0 not counted).
    radius
        Half-width of the square drawn.
    """

    region: LambdaRegion
    boundary: NDArray[np.complex128]
    grid: NDArray[np.float64]
    counts: NDArray[np.int64]
    eigenvalues: NDArray[np.complex128]
    eigenvalue_counts: NDArray[np.int64]
    radius: float

    @property
    def unstable_count(self) -> int:
        """The team's NU: the sum of the eigenvalues' counts."""
        return int(self.eigenvalue_counts.sum())

    def as_json(self) -> dict[str, Any]:
        """The curve, the shading, the eigenvalues with their counts and the team's verdict."""
        r = self.region
        return {
            "P": r.P, "D": r.D, "tau1": r.tau1, "tau2": r.tau2, "radius": self.radius,
            "boundary": _pairs(self.boundary),
            "grid": {"values": np.round(self.grid, _DECIMALS).tolist(), "unstable_count": self.counts.tolist()},
            "eigenvalues": _pairs(self.eigenvalues),
            "eigenvalue_unstable_count": self.eigenvalue_counts.tolist(),
            "eigenvalue_stable": (self.eigenvalue_counts == 0).tolist(),
            "unstable_count": self.unstable_count,
            "stable": self.unstable_count == 0,
        }  # fmt: skip


def region_report(topology: Topology, P: float, D: float, tau1: float, tau2: float) -> RegionReport:
    """The eigenvalue plane of the paper's eq. 3 at one point, for the explorer's panel.

    Parameters
    ----------
    topology
        The team (its eigenvalues of C are marked).
    P, D
        Gains of the paper's eq. 1.
    tau1, tau2
        The delays.

    Returns
    -------
    RegionReport
        Shading on a ``GRID x GRID`` square of half-width ``max(RADIUS, 1.1 max|lam|)``.
    """
    eig = np.asarray(topology.eigenvalues, dtype=np.complex128)
    radius = max(RADIUS, 1.1 * float(np.max(np.abs(eig))))
    region = lambda_region(P, D, tau1, tau2)
    axis = np.linspace(-radius, radius, GRID)
    counts = region.unstable_count(axis[None, :] + 1j * axis[:, None])
    return RegionReport(region, region.boundary(radius), axis, counts, eig, region.unstable_count(eig), radius)
