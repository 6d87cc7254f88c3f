"""The explorer's answers: what each endpoint of the page returns, as frozen dataclasses with ``as_json``.

:class:`~delayform.app.explorer.Explorer` computes them with the library's own
functions; this module only holds the results and turns them into JSON for the
page (rounded far below a pixel; JSON has no NaN, so non-finite values become null).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform.analysis.ctcr.stability_map import StabilityMap
from delayform.analysis.network import JitterMargin
from delayform.analysis.roots.dominant import DominantRoot
from delayform.simulation import Trajectory
from delayform.model.network import Network

__all__ = ["PointReport", "GuaranteeReport", "RootsReport", "ChartData", "Animation", "GUARANTEE_AGENTS",
           "crossing_frequency_bound"]

#: decimals of delays and positions sent to the page (far below a pixel)
_DECIMALS = 5


def _rounded(values: ArrayLike, decimals: int = _DECIMALS) -> list[Any]:
    """A JSON-ready nested list rounded to ``decimals`` places (JSON has no NaN: it becomes None)."""
    arr = np.round(np.asarray(values, dtype=np.float64), decimals)
    if np.all(np.isfinite(arr)):
        return arr.tolist()
    return np.where(np.isfinite(arr), arr, None).tolist()


def _num(x: float) -> str:
    """The shortest exact decimal of x for a file name: 0.3, 150, 1e-05, 1e20 (no '+', no '.0')."""
    text = repr(float(x)).replace("+", "")
    return text[:-2] if text.endswith(".0") else text


def _complex_pairs(roots: NDArray[np.complex128]) -> list[list[float]]:
    return [[float(r.real), float(r.imag)] for r in roots]


def crossing_frequency_bound(P: float, D: float) -> float:
    """Largest frequency at which a characteristic root can cross the imaginary axis.

    A root ``s = j omega`` of a factor of the paper's eq. 3,
    ``s^2 + D s + P = lam (D s e^{-tau2 s} + P e^{-tau1 s})`` with ``|lam| <= 1``
    (C is row-stochastic), needs ``omega^2 - P <= |P - omega^2 + j D omega| <= D omega + P``,
    so ``omega <= (D + sqrt(D^2 + 8 P)) / 2`` whatever the delays. The CTCR
    curves repeat every ``2 pi / omega`` along each delay, so the work of a map,
    and the number of roots near the axis, grow with delay x this bound.

    Parameters
    ----------
    P, D
        Positive gains of the paper's eq. 1.

    Examples
    --------
    >>> round(crossing_frequency_bound(1.0, 0.5), 4)  # the paper's gains
    1.6861
    """
    return (D + math.sqrt(D * D + 8.0 * P)) / 2.0


# ==================================================================== results
@dataclass(frozen=True, eq=False)
class _AtPoint:
    """Gains and delays an answer belongs to."""

    P: float
    D: float
    tau1: float
    tau2: float

    def _where(self) -> dict[str, float]:
        return {"P": self.P, "D": self.D, "tau1": self.tau1, "tau2": self.tau2}


@dataclass(frozen=True, eq=False)
class PointReport(_AtPoint):
    """The verdict at one clicked delay pair.

    Attributes
    ----------
    P, D, tau1, tau2
        The gains and delays.
    unstable_count
        NU: roots of the characteristic equation with Re s > 0 (centroid's
        persistent zero excepted), from the exact CTCR map.
    dominant
        :func:`~delayform.analysis.roots.dominant.dominant_root` at the point.
    """

    unstable_count: int
    dominant: DominantRoot

    @property
    def stable(self) -> bool:
        """True when NU = 0 (the library's meaning, :meth:`StabilityMap.is_stable`)."""
        return self.unstable_count == 0

    def as_json(self) -> dict[str, Any]:
        """The report as JSON-ready values (``dominant_root`` as ``[re, im]``)."""
        root = self.dominant.root
        return self._where() | {
            "stable": self.stable,
            "unstable_count": self.unstable_count,
            "dominant_root": [root.real, root.imag],
            "dominant_root_stable": self.dominant.is_stable,
            "time_constant": None if math.isinf(self.dominant.time_constant) else self.dominant.time_constant,
            "growth_rate": max(root.real, 0.0),
            "dominant_factor": self.dominant.factor.describe(),
            "actuation_delay": self.dominant.actuation_delay,
        }  # fmt: skip


@dataclass(frozen=True, eq=False)
class GuaranteeReport(_AtPoint):
    """What is certified at one clicked delay pair beyond the chart.

    Attributes
    ----------
    P, D, tau1, tau2
        The gains and delays.
    jitter
        The certified jitter margin there
        (:func:`~delayform.analysis.network.jitter_margin`), or None for teams
        above :data:`GUARANTEE_AGENTS` agents (its cost grows as N^4).
    """

    jitter: JitterMargin | None

    def as_json(self) -> dict[str, Any]:
        """``jitter_margin`` in seconds (0 where the point is unstable; None when not computed)."""
        m = self.jitter
        return self._where() | {"jitter_margin": None if m is None else m.delta,
                                "jitter_method": None if m is None else m.method}  # fmt: skip


#: the explorer certifies a jitter margin for teams up to this size
GUARANTEE_AGENTS = 30


@dataclass(frozen=True, eq=False)
class RootsReport(_AtPoint):
    """The roots of every factor near the imaginary axis at one delay pair.

    Attributes
    ----------
    P, D, tau1, tau2
        The gains and delays.
    dominant
        The dominant root the window is placed around.
    roots
        Roots of every factor in :attr:`region`, each once (a factor of
        multiplicity m contributes each root m times to the characteristic
        equation), centroid's persistent zero removed.
    root_factors
        Index of the factor (order of :func:`~delayform.characteristic.factors`) of each root.
    factor_names
        ``describe()`` of each factor.
    region
        ``(re_min, re_max, im_min, im_max)`` of the window.
    certified
        False when :func:`roots_in` did not reach the certified count for some factor
        (the roots shown are then those found).
    """

    dominant: complex
    roots: NDArray[np.complex128]
    root_factors: tuple[int, ...]
    factor_names: tuple[str, ...]
    region: tuple[float, float, float, float]
    certified: bool

    def as_json(self) -> dict[str, Any]:
        """The roots as ``[re, im]`` pairs with their factors and the window."""
        return self._where() | {
            "dominant_root": [self.dominant.real, self.dominant.imag],
            "roots_near_axis": _complex_pairs(self.roots),
            "root_factors": list(self.root_factors),
            "factors": list(self.factor_names),
            "region": list(self.region),
            "roots_certified": self.certified,
        }  # fmt: skip


@dataclass(frozen=True, eq=False)
class ChartData:
    """The stability chart as the page draws it.

    Attributes
    ----------
    smap
        The exact CTCR map.
    tau1_centres, tau2_centres
        Cell centres of the shading grid.
    counts
        NU at the cell centres, ``(len(tau2_centres), len(tau1_centres))``.
    points
        The scenario's labelled points inside the window.
    """

    smap: StabilityMap
    tau1_centres: NDArray[np.float64]
    tau2_centres: NDArray[np.float64]
    counts: NDArray[np.int64]
    points: tuple[tuple[str, float, float], ...]

    def as_json(self) -> dict[str, Any]:
        """Curves as two polylines (kernel, offspring) with ``None`` between pieces, and the grid."""
        lines: dict[str, dict[str, list[Any]]] = {"kernel": {"tau1": [], "tau2": []},
                                                   "offspring": {"tau1": [], "tau2": []}}  # fmt: skip
        for c in self.smap.curves:
            target = lines["kernel" if c.is_kernel else "offspring"]
            target["tau1"] += _rounded(c.tau1) + [None]
            target["tau2"] += _rounded(c.tau2) + [None]
        return {
            "tau1_max": self.smap.tau1_max,
            "tau2_max": self.smap.tau2_max,
            "curves": lines,
            "grid": {"tau1": _rounded(self.tau1_centres), "tau2": _rounded(self.tau2_centres),
                     "unstable_count": self.counts.tolist()},  # fmt: skip
            "stable_fraction": float(np.mean(self.counts == 0)),
            "points": [{"label": k, "tau1": a, "tau2": b} for k, a, b in self.points],
        }


@dataclass(frozen=True, eq=False)
class Animation:
    """A simulated run thinned to animation frames.

    Attributes
    ----------
    trajectory
        The full run of :func:`~delayform.simulation.simulate`.
    frames
        Indices of the saved samples sent as frames (finite samples only).
    diverged_at
        Time of the first non-finite sample, or where integration stopped
        because the state passed 1e8 times its size (the time the run's
        warning names), or None.
    network
        The imperfect network of the run, or None (the paper's ideal links).
    """

    trajectory: Trajectory
    frames: NDArray[np.int64]
    diverged_at: float | None
    network: Network | None = None

    def as_json(self) -> dict[str, Any]:
        """Times, positions, headings and formation error at the frames, and the run's metrics."""
        tr, k = self.trajectory, self.frames
        pos = tr.positions[k]
        offset = np.mean(pos[-1] - tr.desired, axis=0)
        return {
            "model": tr.model, "dt": tr.dt, "n": tr.n, "tau1": tr.tau1, "tau2": tr.tau2,
            "times": _rounded(tr.times[k]),
            "x": _rounded(pos[:, :, 0]), "y": _rounded(pos[:, :, 1]),
            "heading": _rounded(tr.headings[k], 4),
            "formation_error": tr.formation_error[k].tolist(),
            "desired_final": _rounded(tr.desired + offset),
            "settling_time": None if math.isinf(tr.settling_time) else tr.settling_time,
            "final_error": float(tr.formation_error[k[-1]]),
            "min_distance": tr.min_distance if self.diverged_at is None else None,
            "radius": tr.radius,
            "contacts": [[c.agents[0], c.agents[1], c.start, c.end, c.closest] for c in tr.contacts],
            "diverged_at": self.diverged_at,
            "status": tr.status,
            "warnings": list(tr.warnings),
            "limits": None if tr.limits is None else tr.limits.describe(),
            "network": None if self.network is None else self.network.describe(),
            "labels": [str(x) for x in tr.labels] if tr.labels else [str(i) for i in range(tr.n)],
        }  # fmt: skip
