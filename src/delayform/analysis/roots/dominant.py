"""Characteristic roots, dominant roots, dominant-root maps and delay scheduling.

The paper closes (Section "Simulation", Figs. 8 and 9) with
*delay scheduling*: inside the stable region of the CTCR chart, pick the
delays whose dominant (rightmost) characteristic root lies furthest left,
because that root sets how fast the team settles into formation. This module
computes those roots for any retarded quasi-polynomial of the paper's eq. 5 and
for the factors of the paper's eq. 3.

Method
------
The roots come from :mod:`delayform.analysis.roots.single` (a Chebyshev discretization
of the generator for seeds, Newton on the quasi-polynomial, a certificate by the
argument principle: see that module); all factors at one or many delay pairs are
solved together as one vectorized family (:mod:`delayform.analysis.roots.family.solve`).

Guarantee
---------
:func:`dominant_root` and :func:`dominant_root_map` return roots such that the
certified number of roots of every factor right of a line placed left of them
equals the number of polished roots found there: no root to their right is missed.

Conventions: coefficients in increasing powers of s; delays in seconds,
``tau1`` on positions and ``tau2`` on velocities (paper, eq. 1); the
centroid factor's persistent root s = 0 (paper, eq. 4) is deflated with
Maehly's correction and excluded from dominant roots (its other roots count).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_delay, check_gains, validated
from delayform.analysis.roots import delegated
from delayform.model import Delays, Team
from delayform.model.loose import accepts_loose_team
from delayform.analysis.roots.actuated import actuated_beside_drift, actuated_factor, actuated_rightmost
from delayform.analysis.roots.family.solve import family_grid, family_rightmost
from delayform.analysis.roots.problem import (
    MAX_DEGREE,
    RESIDUAL_TOL,
    UNIT_DELAYS,
    _Problem,
    _problem_of_factor,
    _problem_of_qp,
    _problem_of_quasi,
)
from delayform.analysis.roots.single import (  # noqa: F401 - the roots of one quasi-polynomial, re-exported
    _check_reach,
    _rightmost,
    count_roots_right_of,
    relative_residual,
    rightmost_root,
    roots_in,
)
from delayform.characteristic import CharacteristicFactor, TwoDelayQuasiPolynomial, factors
from delayform.errors import DelayError, InputError, NoStableDelaysError
from delayform.resources import require
from delayform.topology import Topology

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes

__all__ = [
    "RESIDUAL_TOL",
    "MAX_DEGREE",
    "SETTLING_FACTOR",
    "roots_in",
    "rightmost_root",
    "count_roots_right_of",
    "relative_residual",
    "dominant_root",
    "dominant_root_map",
    "DominantRoot",
    "DominantRootMap",
    "NoStableDelaysError",
]

#: Settling time (2 % criterion) = ln(50) / |Re s_dom| ~ 3.9 time constants.
SETTLING_FACTOR = math.log(50.0)




# =====================================================================
# public: dominant root of the formation, maps, scheduling
# =====================================================================
@validated()
@dataclass(frozen=True)
class DominantRoot:
    """The dominant (rightmost) characteristic root of the formation at one delay pair.

    One meaning of *stable* throughout delayform (docs/theory.md): the team
    is stable when every root of every factor of the paper's eq. 3 has
    Re s < 0, except the centroid factor's roots at s = 0. The persistent
    root 0 of the paper's eq. 4 is the team's freedom to sit anywhere and is never
    reported; on the line tau1 = 0 the centroid factor has a second root at
    0, a centroid that drifts at constant speed. That root *is* reported
    (it is the limit of the centroid's slow root -P tau1 / (1 + D tau2) as
    tau1 -> 0, so maps stay continuous) but does not make the team unstable:
    the shape the agents reach is the same. The CTCR map treats the tau1 = 0
    line the same way.

    Attributes
    ----------
    root
        The rightmost root over all factors, the persistent root 0 of the
        centroid factor excluded; of a conjugate pair the member with Im >= 0.
    factor
        The factor it belongs to.
    tau1, tau2
        The delays.
    formation_root
        The rightmost root of the disagreement factors (every factor but the
        centroid's): how fast the agents reach the formation's *shape*.
    centroid_root
        The rightmost root of the centroid factor, its persistent 0 excluded:
        how fast the centroid's speed settles (exactly 0 on tau1 = 0: the drift).
    beside_drift
        On tau1 = 0: the rightmost root with both centroid zeros removed
        (see :attr:`stability_root`); None elsewhere.
    actuation_delay
        The actuation delay tau_a (s) of :func:`dominant_root`.
    """

    root: complex
    factor: CharacteristicFactor
    tau1: float
    tau2: float
    formation_root: complex | None = None
    centroid_root: complex | None = None
    beside_drift: complex | None = None
    #: tau_a (s), the actuation delay the roots were computed with (0: the paper's model)
    actuation_delay: float = 0.0

    @property
    def stability_root(self) -> complex:
        """The rightmost root that decides stability: ``root``, or beside the drift on tau1 = 0.

        On tau1 = 0, where ``root`` is the drift's s = 0, this is the rightmost
        root of every factor with both centroid zeros removed (its real part is
        the spectral abscissa the gain design minimises).
        """
        return self.beside_drift if self.is_drift and self.beside_drift is not None else self.root

    @property
    def is_stable(self) -> bool:
        """True when every mode decays except the centroid's drift at s = 0 (Lemma 2, docs/theory.md)."""
        return self.stability_root.real < 0.0 or (self.is_drift and _decays(self.formation_root))

    @property
    def is_drift(self) -> bool:
        """True when the dominant root is the centroid's drift: s = 0 exactly, on tau1 = 0."""
        return bool(self.factor.is_centroid) and self.root == 0.0

    @property
    def time_constant(self) -> float:
        """1 / |Re root| for a decaying root; ``math.inf`` when it does not decay (see growth_rate)."""
        return _decay_time(self.root)

    @property
    def growth_rate(self) -> float:
        """Re root when the root grows (unstable), else 0.0 (1/s)."""
        return max(self.root.real, 0.0)

    @property
    def formation_time_constant(self) -> float:
        """Time constant of the shape (disagreement) modes; ``math.inf`` when they do not decay."""
        return _decay_time(self.root if self.formation_root is None else self.formation_root)

    @property
    def centroid_time_constant(self) -> float:
        """Time constant of the centroid's speed; ``math.inf`` for the drift on tau1 = 0."""
        return _decay_time(self.root if self.centroid_root is None else self.centroid_root)

    @property
    def is_centroid_drift(self) -> bool:
        """True when the dominant root belongs to the centroid factor, not to the shape."""
        return bool(self.factor.is_centroid)


def _centroid_rightmost(factor: CharacteristicFactor, t1: float, t2: float) -> complex | None:
    """Rightmost root of the centroid factor with *both* its roots at s = 0 removed (design/gains uses it).

    For tau1 > 0 the factor has the single persistent root 0, deflated by
    :func:`rightmost_root`. On tau1 = 0 it is s (s + D - D e^{-tau2 s}): the
    second factor r has a simple root at 0 too (the drift), so its deflated
    rightmost root is the answer; for tau2 = 0 as well, r = s has no other root (None).
    """
    if t1 > 0.0:
        return rightmost_root(factor, t1, t2)
    if t2 == 0.0:
        return None
    D = factor.D
    prob = _problem_of_qp(TwoDelayQuasiPolynomial([D, 1.0], [], [-D]))
    return _rightmost(_Problem(prob.terms, prob.A, prob.delayed, prob.mirror, True), t1, t2)


def _decays(root: complex | None) -> bool:
    return root is None or root.real < 0.0


def _decay_time(root: complex) -> float:
    return 1.0 / -root.real if root.real < 0.0 else math.inf


def checked_factors(topology: Topology, P: float, D: float) -> tuple[CharacteristicFactor, ...]:
    """The factors of the paper's eq. 3 of a team, its topology and gains checked first.

    The same tuple for repeated calls on one (frozen) topology and gains.

    Raises
    ------
    InputError
        When ``topology`` is not a :class:`~delayform.topology.Topology`.
    TopologyError
        Without a spanning tree (Lemma 3).
    GainError
        For gains that are not positive or out of range.
    """
    if not isinstance(topology, Topology):
        raise InputError(f"topology must be a Topology, got {type(topology).__name__}")
    topology.require_spanning_tree()
    P, D = check_gains(P, D)
    return _factors_of(topology, P, D)


@lru_cache(maxsize=8)
def _factors_of(topology: Topology, P: float, D: float) -> tuple[CharacteristicFactor, ...]:
    # the same tuple for repeated calls on a (frozen) team, so the family path's per-factor
    # arrays (_family._lams, family_reach_scales) are built once, not on every call
    return factors(topology, P, D)


@accepts_loose_team(actuation="actuation_delay")
@validated()
def dominant_root(team: Team, delays: Delays) -> DominantRoot | delegated.PerLinkRoot:
    """The dominant root of the formation and its time constant.

    Which computation answers is said by :attr:`Delays.kind`: uniform delays
    go through the factors of the paper's eq. 3; per-link delays
    (``tau1[i, k]``: what agent i hears from k) give the certified dominant
    root of det of the N x N matrix quasi-polynomial, a
    :class:`~delayform.analysis.network.LinkDominantRoot`
    (:mod:`delayform.analysis.network.per_link`).

    Parameters
    ----------
    team
        Topology (with a spanning tree, Lemma 3) and the positive gains of the paper's eq. 1.
    delays
        tau1, tau2 on positions and velocities, uniform or per link (entries
        without a link ignored), and the actuation delay tau_a >= 0 (s): each
        robot applies its command tau_a late, so every factor gains the
        delayed own-state terms
        (:func:`~delayform.analysis.roots.actuated.actuated_factor`); 0
        (default) is the paper's model, solved by the vectorized family path.
        With per-link delays tau_a needs the same delays on every link (they
        are then the uniform pair); otherwise DelayError.

    Returns
    -------
    DominantRoot or LinkDominantRoot
        The rightmost root over the factors of the paper's eq. 3, excluding the
        persistent root 0 of the paper's eq. 4 (its other roots count).

    Notes
    -----
    The loose form ``dominant_root(topology, P, D, tau1, tau2, actuation_delay=0.0)``
    of earlier versions is still taken (:func:`delayform.model.loose.accepts_loose_team`).

    Examples
    --------
    >>> from delayform.model import Delays, Team
    >>> from delayform.topology import paper_six
    >>> r = dominant_root(Team(paper_six(), 1.0, 0.5), Delays(1.0, 2.0))  # point c of the paper's Fig. 3
    >>> r.is_stable, round(r.root.real, 4)
    (False, 0.0836)
    """
    topology, P, D, ta = team.topology, team.P, team.D, delays.actuation
    if delays.kind == "per_link":  # the matrix quasi-polynomial, no factorization
        delays.check_team(team.n)
        per_link = delegated.per_link()  # solved by analysis/network, which sits above roots
        if ta == 0.0:
            return per_link.dominant_root(topology, P, D, delays.tau1, delays.tau2)
        t1, t2 = per_link.uniform_delays(topology, P, D, delays.tau1, delays.tau2)
    else:
        t1, t2 = delays.pair
    fs = checked_factors(topology, P, D)
    if ta > 0.0:
        return _actuated_dominant(fs, t1, t2, ta)
    # all factors in one batch (one stacked discretization, one vectorized certificate); long delays
    # go to the root chains, and the discretization's budget is checked before it would start
    right = family_rightmost(fs, fs[0].P, fs[0].D, t1, t2)
    k0 = next(k for k, f in enumerate(fs) if f.is_centroid)
    centroid = fs[k0]
    # on tau1 = 0 the centroid factor is s (s + D - D e^{-tau2 s}): its second zero, the drift, is exact
    centroid_root = complex(right[k0]) if t1 > 0.0 else 0j
    formation = max(((complex(right[k]), f) for k, f in enumerate(fs) if not f.is_centroid),
                    key=lambda rf: rf[0].real)  # fmt: skip
    best = formation if formation[0].real >= centroid_root.real else (centroid_root, centroid)
    beside = None
    if best[1].is_centroid and best[0] == 0.0:  # the drift on tau1 = 0: what decides stability is next to it
        nxt = _centroid_rightmost(centroid, t1, t2)
        beside = formation[0] if nxt is None or formation[0].real >= nxt.real else nxt
    return DominantRoot(best[0], best[1], t1, t2, formation_root=formation[0], centroid_root=centroid_root,
                        beside_drift=beside)  # fmt: skip


def _actuated_dominant(fs: tuple[CharacteristicFactor, ...], t1: float, t2: float, ta: float) -> DominantRoot:
    """:func:`dominant_root` with an actuation delay: each factor in three delays, certified one by one."""
    right = [actuated_rightmost(f, t1, t2, ta) for f in fs]
    k0 = next(k for k, f in enumerate(fs) if f.is_centroid)
    centroid, centroid_root = fs[k0], right[k0]
    formation = max(((right[k], f) for k, f in enumerate(fs) if not f.is_centroid), key=lambda rf: rf[0].real)
    best = formation if formation[0].real >= centroid_root.real else (centroid_root, centroid)
    beside = None
    if best[1].is_centroid and best[0] == 0.0:  # the drift on tau1 = 0, as without the actuation delay
        nxt = actuated_beside_drift(centroid, t2, ta)
        beside = formation[0] if nxt is None or formation[0].real >= nxt.real else nxt
    return DominantRoot(best[0], best[1], t1, t2, formation_root=formation[0], centroid_root=centroid_root,
                        beside_drift=beside, actuation_delay=ta)  # fmt: skip


@validated()
@dataclass(frozen=True, eq=False)
class DominantRootMap:
    """Dominant roots over a grid of delays (paper, Figs. 8 and 9).

    Attributes
    ----------
    tau1_values, tau2_values
        The grid axes; ``roots[i, j]`` is at (tau1_values[i], tau2_values[j]).
    roots
        Dominant root at each grid point (complex array).
    factor_index
        Index into ``factors`` of the factor the dominant root belongs to.
    factors
        The factors of the paper's eq. 3.
    formation_real
        Re of the rightmost root of the disagreement factors (the shape), or
        None; decides stability where the dominant root is the centroid's drift.
    actuation_delay
        The actuation delay tau_a (s) the roots were computed with (0: the paper's model).
    """

    tau1_values: NDArray[np.float64]
    tau2_values: NDArray[np.float64]
    roots: NDArray[np.complex128]
    factor_index: NDArray[np.int64]
    factors: tuple[CharacteristicFactor, ...]
    formation_real: NDArray[np.float64] | None = None
    actuation_delay: float = 0.0

    @property
    def real(self) -> NDArray[np.float64]:
        """Re(dominant root) at each grid point, the surface of the paper's Fig. 8."""
        return self.roots.real

    @property
    def stable(self) -> NDArray[np.bool_]:
        """True where every mode decays but the centroid's drift (one meaning of stable, :class:`DominantRoot`).

        Where the dominant root is the centroid's drift s = 0 (on tau1 = 0)
        the shape's modes decide; the map keeps the drift's Re = 0, so the
        surface is continuous as tau1 -> 0.
        """
        centroid = np.array([f.is_centroid for f in self.factors])[self.factor_index]
        drift = centroid & (self.roots == 0.0)
        shape = self.formation_real if self.formation_real is not None else np.full(self.roots.shape, -np.inf)
        return (self.roots.real < 0.0) | (drift & (shape < 0.0))

    @property
    def time_constant(self) -> NDArray[np.float64]:
        """1 / |Re(dominant root)| where the root decays, ``inf`` where it does not (never a number for a growing root)."""
        re = self.roots.real
        with np.errstate(divide="ignore"):
            return np.where(re < 0.0, 1.0 / np.abs(re), np.inf)

    def best(self) -> tuple[float, float, complex]:
        """The grid point with the leftmost dominant root: (tau1, tau2, root)."""
        i, j = np.unravel_index(int(np.argmin(self.roots.real)), self.roots.shape)
        return float(self.tau1_values[i]), float(self.tau2_values[j]), complex(self.roots[i, j])

    def plot_surface(self, ax: Axes | None = None) -> Axes:
        """Surface of Re(dominant root) with the plane Re s = 0 (paper, Fig. 8)."""
        from delayform.plots import plot_dominant_surface

        return plot_dominant_surface(self, ax=ax)

    def plot_contour(self, ax: Axes | None = None) -> Axes:
        """Contour map of Re(dominant root) (paper, Fig. 9)."""
        from delayform.plots import plot_dominant_contour

        return plot_dominant_contour(self, ax=ax)


def _grid_axis(name: str, values: ArrayLike) -> NDArray[np.float64]:
    try:
        arr = np.atleast_1d(np.asarray(values, dtype=np.float64))
    except (TypeError, ValueError) as exc:
        raise DelayError(f"{name} must be a sequence of delays") from exc
    if arr.ndim != 1 or arr.size == 0:
        raise DelayError(f"{name} must be a non-empty 1-D sequence of delays")
    if not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
        raise DelayError(f"{name} must hold finite non-negative delays")
    return arr


@validated()
def dominant_root_map(
    topology: Topology,
    P: float,
    D: float,
    tau1_values: ArrayLike,
    tau2_values: ArrayLike,
    *,
    progress: bool | Callable[[int, int], None] = False,
    actuation_delay: float = 0.0,
) -> DominantRootMap:
    """Dominant root at every point of a delay grid (paper, Figs. 8 and 9).

    Fast by design: all factors (a conjugate pair through its second-order
    factor of lam) and all grid points are one vectorized family
    (:mod:`delayform.analysis.roots.family.solve`). The grid is visited coarse to fine:
    the coarsest points are seeded by the discretized generator, every later
    point by the roots of its nearest solved point; Newton's method and the
    argument-principle certificate run on all rows at once, and only rows the
    certificate rejects are redone (fresh discretization seeds, then the
    generic per-factor path). Every point is certified.

    Parameters
    ----------
    topology
        Communication topology with a spanning tree.
    P, D
        Positive gains.
    tau1_values, tau2_values
        Non-empty 1-D grids of non-negative delays.
    progress
        True shows a Rich progress bar on stderr; a callable is called as
        ``progress(done, total)`` (grid points times factors) as work finishes,
        for callers that draw their own bar.
    actuation_delay
        tau_a >= 0 (s): every factor in three delays
        (:func:`~delayform.analysis.roots.actuated.actuated_factor`), solved by
        the same continuation on the family of
        :mod:`delayform.analysis.roots.family.actuated`, every point certified;
        0 (default) is the paper's model.

    Returns
    -------
    DominantRootMap

    Raises
    ------
    ResourceLimitError
        When the grid would need more memory or time than the machine allows.
    DelayError
        When the grid's delays need a discretization beyond the machine's
        memory or time budget (there is no fixed reach: long delays get a finer discretization).

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> m = dominant_root_map(paper_six(), 1.0, 0.5, [0.3, 1.0], [0.2, 2.0])
    >>> m.stable.tolist()
    [[True, True], [True, False]]
    """
    fs = checked_factors(topology, P, D)
    ax1 = _grid_axis("tau1_values", tau1_values)
    ax2 = _grid_axis("tau2_values", tau2_values)
    ta = check_delay("actuation_delay", actuation_delay)
    points = float(ax1.size) * float(ax2.size)
    # measured: ~1.3e-4 s per grid point and factor on the paper's map; ~20 work arrays per point
    require(
        what=f"a dominant-root map of {ax1.size} x {ax2.size} delay pairs and {len(fs)} factors",
        setting="the grid size (map.size, --size)",
        nbytes=points * (320.0 + 16.0 * len(fs)),
        seconds=points * len(fs) * 2e-4,
    )
    for f in fs:
        if ta > 0.0:  # the longest delays of the map, each term's own: (tau1, tau2, tau_a)
            quasi = actuated_factor(f.P, f.D, complex(f.lam))
            _check_reach(_problem_of_quasi(quasi, (float(ax1.max()), float(ax2.max()), ta)), *UNIT_DELAYS)
        else:
            _check_reach(_problem_of_factor(f), float(ax1.max()), float(ax2.max()))
    per_factor = np.empty((len(fs), ax1.size, ax2.size), dtype=np.complex128)
    with _progress(progress, len(fs) * ax1.size * ax2.size) as advance:
        per_factor[:] = family_grid(fs, fs[0].P, fs[0].D, ax1, ax2, advance, ta)
        row0 = np.flatnonzero(ax1 == 0.0)
        if row0.size:  # on tau1 = 0 the centroid's second zero is its drift: kept (the surface stays
            # continuous as tau1 -> 0); `stable` reads the shape's modes there
            k0 = next(k for k, f in enumerate(fs) if f.is_centroid)
            per_factor[k0, row0, :] = 0.0
    index = np.argmax(per_factor.real, axis=0)
    roots = np.take_along_axis(per_factor, index[None], 0)[0]
    shape = np.array([not f.is_centroid for f in fs])
    formation_real = per_factor[shape].real.max(axis=0)
    return DominantRootMap(ax1, ax2, roots, index, fs, formation_real, ta)


class _progress:
    """Context manager yielding an ``advance(n)`` callback: a Rich bar, the caller's callback, or None."""

    def __init__(self, enabled: bool | Callable[[int, int], None], total: int) -> None:
        self.enabled, self.total = enabled, total
        self._bar: Any = None

    def __enter__(self) -> Callable[[int], None] | None:
        if callable(self.enabled):
            report, done = self.enabled, [0]

            def advance(n: int) -> None:
                done[0] += n
                report(min(done[0], self.total), self.total)

            return advance
        if not self.enabled:
            return None
        from rich.console import Console
        from rich.progress import Progress

        # stderr, so machine-readable output on stdout stays clean
        self._bar = Progress(transient=True, console=Console(stderr=True))
        self._bar.start()
        task = self._bar.add_task("dominant roots", total=self.total)
        return lambda n: self._bar.advance(task, n)

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()

