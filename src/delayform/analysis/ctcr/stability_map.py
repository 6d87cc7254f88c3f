"""Exact CTCR stability maps in the (tau1, tau2) plane (Section "Stability Analysis Using CTCR").

Conventions
-----------
A quasi-polynomial ``qp`` is the two-delay form of the paper's eq. 5,
``q(s) = g1 + g2 z1 + g3 z2 + g4 z1^2 + g5 z2^2 + g6 z1 z2`` with
``z1 = e^{-tau1 s}``, ``z2 = e^{-tau2 s}``. On the imaginary axis ``s = j omega``
we write ``z_k = e^{-j theta_k}`` with the phases ``theta_k = omega tau_k mod 2 pi``.
NU is the number of characteristic roots with Re s > 0; a root s = 0 that is
there for every delay (the centroid factor, the paper's eq. 4) is never counted
(Lemma 2: it is the rigid-body mode).

How the crossing curves are found (the paper does not give its half-angle method)
----------------------------------------------------------------------------------
Every point of a kernel or offspring curve is a triple (omega, theta1, theta2)
with ``q(j omega) = 0``; the plane point is ``tau_k = (theta_k + 2 pi i_k) / omega``
(paper, eq. 6, i_k = 0 for the kernel, Definition "Kernel curves"). Only
omega > 0 is traced: a real qp has its crossings in conjugate pairs (NU
changes by 2 RT); a complex qp (allowed in :func:`crossing_map`) is traced
twice, itself and its conjugate ``conj(q(conj s))``, whose omega > 0 crossings
are the omega < 0 crossings of q, each changing NU by 1 RT.

* Three-term quasi-polynomials ``g1 + g2 z1 + g3 z2`` -- every factor of the
  formation protocol is one after the split below -- have a closed form:
  ``g2 z1 + g3 z2 = -g1`` is a triangle with sides ``|g1|, |g2|, |g3|`` (all at
  ``j omega``). The crossing frequencies are exactly the omega where the
  triangle inequality holds, ``F(omega) = (|g1|^2-|g2|^2-|g3|^2)^2 - 4|g2|^2|g3|^2 <= 0``,
  a real polynomial in omega whose roots give the ends of the frequency
  intervals; inside one, the law of cosines gives theta1, theta2 for the two
  mirror triangles (the two branches, which join at the interval ends). This
  is the half-angle / triangle construction of two-delay CTCR written in
  closed form. A fourth-order factor of the paper's eq. 3 is
  ``q_lam(s) q_conj(lam)(s)`` with ``q_lam = s^2 + D s + P - lam (D s z2 + P z1)``
  (complex coefficients), so its curves are those of q_lam and of q_conj(lam).
* General retarded qps (commensurate ``2 tau`` terms, cross term): for each
  omega on an adaptive grid, q = 0 is a quadratic in z1; with ``conj(z1) = 1/z1``
  and ``conj(z2) = 1/z2`` on the unit circle, the resultant of the quadratic and
  its conjugate-reciprocal eliminates z1 and leaves a polynomial of degree
  <= 8 in z2 whose unit-circle roots are *all* solutions at that omega; z1
  follows from the common-root formula and a 2x2 Newton step polishes
  (theta1, theta2). Solutions of neighbouring frequencies are joined by an
  assignment on the torus; where their number changes the frequency step is
  bisected down to 1e-12 relative, and the two solutions that appear (or
  vanish) there are joined (a turning point of the curve).

Sampling is adaptive in a parameter that is smooth through the turning
points (``omega = a + (b - a)(1 - cos phi)/2``): an interval of the parameter is
halved while the image of its midpoint, for the largest offspring that reaches
the window, lies further than 2e-4 of the window size from the chord, or
(near a turning point of the curve in tau2, where a horizontal line meets it
twice close together) further than 1e-9 of the window size. Every point
satisfies ``|q(j omega)| <= 1e-9 sum_k |g_k(j omega)|`` (closed form: ~1e-15;
general path: ~1e-11). Frequencies below 1e-4 of the bound on crossing
frequencies are not traced: there ``tau = theta / omega`` loses ~eps/omega^2
to rounding; in practice those pieces lie far outside any window.

How NU is counted (the CTCR count)
----------------------------------
``NU(tau1, tau2)`` is the count just off the origin along the tau2 axis, plus
``w RT2`` for each crossing on the tau1 = 0 axis with ``0 < tau2' < tau2`` (an
exact single-delay problem: ``h0 + h1 z2 + h2 z2^2`` with ``h0 = g1 + g2 + g4``,
``h1 = g3 + g6``, ``h2 = g5``, solved by the same resultant), plus ``w RT1`` for
each curve met by the horizontal segment from (0, tau2) to (tau1, tau2); w is
2 for a real qp, 1 per traced half of a complex one, times the multiplicity.
Where the polyline meets the line tau2 = const, the crossing is recomputed
exactly (Newton on ``q(j omega; tau1, tau2) = 0`` in (omega, tau1)), so a query
point close to a curve is counted on its true side. Points with tau2 = 0 take
the path along the tau1 axis instead. A root that only touches the imaginary
axis (``Re ds/dtau`` zero to 1e-9 relative; e.g. lam = -1 on the tau1 = 0 axis,
where the gain polynomial has a double root) has RT = 0 and changes nothing.

The origin and the axes
-----------------------
* Delay-free roots with Re s > 0 count. A delay-free imaginary root
  ``j omega0 != 0`` is counted when ``Re ds/dtau2 > 0`` at the origin (it starts
  the path up the tau2 axis; ``ds/dtau1`` for the path along tau1).
* ``q(0) = sum_k g_k(0)`` does not depend on the delays, so a root at s = 0 is
  either there for all delays or never, and omega = 0 is never a crossing. When
  it is there, ``q(s) = s (q'(0) + q''(0) s / 2 + ...)`` with
  ``q'(0) = c0 + c1 tau1 + c2 tau2`` linear in the delays: on the line
  ``q'(0) = 0`` a second real root passes through s = 0 at
  ``r ~ -2 q'(0) / q''(0)``, and crossing the line changes NU by one (for a
  real qp; for a complex one this is generically a point and is ignored).
* The centroid factor ``s^2 + D s + P - D s z2 - P z1``: ``q(0) = 0`` always,
  ``q'(0) = P tau1`` and ``q''(0) = 2 (1 + D tau2)`` at tau1 = 0. At the origin the
  delay-free polynomial is ``s^2 + 0 s + 0``, a double zero; its line
  ``q'(0) = 0`` is the tau1 = 0 axis itself, along which s = 0 stays double
  (``s + D - D e^{-tau2 s}`` vanishes at 0). For tau1 > 0 the second root is
  ``r ~ -P tau1 / (1 + D tau2) < 0``: it leaves to the left, so the centroid
  contributes 0 unstable roots near the origin and the tau1 = 0 axis adds
  nothing; NU of the centroid factor changes only on its omega > 0 curves.

References
----------
Cepeda-Gomez and Perico, Section "Stability Analysis Using CTCR": the paper's eq. 5,
Definitions "Kernel curves", "Offspring curves" (paper, eq. 6), "Root Tendency",
Proposition "Invariant root tendency"; Lemmas 1-2 for the factors.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._display import FigureRepr  # Jupyter shows the figure
from delayform._validation import check_delay, check_delay_array, check_positive, validated
from delayform.analysis.ctcr.actuated import ActuatedStabilityMap, actuated_stability_map
# the curves and the count live in one module per concept; names other modules and
# tests import from here stay importable from here
from delayform.analysis.ctcr.count import (  # noqa: F401
    _axis_sum,
    _exact_crossing,
    _horizontal_crossings,
    _segment_table,
    _zero_line_count,
)
from delayform.analysis.ctcr.family_curves import family_axis_crossings, family_curves
from delayform.analysis.ctcr.phase import (  # noqa: F401
    CHORD_TOL,
    _MAX_CHORD,
    _OMEGA_FLOOR,
    TWO_PI,
    _horner,
    _omega_bound,
    _positive_real_roots,
    _single_delay_roots,
    _three_term_paths,
)
from delayform.analysis.ctcr.curves import (  # noqa: F401
    CrossingCurve,
    _axis_crossings,
    _conjugate,
    _origin_counts,
    _Part,
    _part_curves,
    _tendency,
    _ZeroLine,
)
from delayform.analysis.ctcr.factored import split_monomial_factors
from delayform.analysis.ctcr.general import TermsQP, as_traced
from delayform.characteristic import TwoDelayQuasiPolynomial, factors
from delayform.quasipolynomial import QuasiPolynomial
from delayform.resources import require
from delayform.errors import DelayError, QuasiPolynomialError
from delayform.topology import Topology

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = [
    "CrossingCurve",
    "StabilityMap",
    "crossing_map",
    "stability_map",
    "curve_residual",
    "PAPER_POINTS",
]

#: Points of the paper's Fig. 3 (Section "Simulation Examples"): a, b, d, e stable, c not.
PAPER_POINTS: dict[str, tuple[float, float]] = {
    "a": (0.3, 0.2),
    "b": (2.0, 1.0),
    "c": (1.0, 2.0),
    "d": (1.0, 5.5),
    "e": (3.5, 2.0),
}
#: Relative residual every curve point satisfies: |q(j omega)| / sum_k |g_k(j omega)|.
CURVE_TOLERANCE = 1e-9


@validated()
@dataclass(frozen=True, eq=False)
class StabilityMap(FigureRepr):
    """The exact stability map of CTCR in the window [0, tau1_max] x [0, tau2_max].

    Attributes
    ----------
    curves
        All kernel and offspring curve pieces meeting the window.
    tau1_max, tau2_max
        The window.
    delay_free_count
        NU just off the origin along the tau2 axis (delay-free count, see module docstring).
    traced
        The quasi-polynomials whose imaginary roots were traced for omega > 0
        (a complex one also as its conjugate; a fourth-order factor as the
        three-term factors of lam and conj(lam)); a :class:`TermsQP` for a
        quasi-polynomial given by its terms (general or neutral, :func:`crossing_map`).
    """

    curves: tuple[CrossingCurve, ...]
    tau1_max: float
    tau2_max: float
    delay_free_count: int
    traced: tuple[TwoDelayQuasiPolynomial | TermsQP, ...] = field(repr=False)
    _start1: int = field(repr=False)
    _axis2: tuple[NDArray[np.float64], NDArray[np.float64]] = field(repr=False)
    _axis1: tuple[NDArray[np.float64], NDArray[np.float64]] = field(repr=False)
    _zero_lines: tuple[_ZeroLine, ...] = field(repr=False)

    def __repr__(self) -> str:
        kernel = sum(c.is_kernel for c in self.curves)
        return (
            f"StabilityMap(window=[0, {self.tau1_max:g}] x [0, {self.tau2_max:g}], "
            f"kernel pieces={kernel}, offspring pieces={len(self.curves) - kernel}, "
            f"delay_free_count={self.delay_free_count})"
        )

    # ------------------------------------------------------------ counting
    def unstable_count(self, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.int64]:
        """NU at delay pairs (vectorized, broadcasting tau1 against tau2).

        Parameters
        ----------
        tau1, tau2
            Delays inside the window.

        Returns
        -------
        ndarray of int
            Number of characteristic roots with Re s > 0 (centroid zero root excepted).
        """
        t1 = check_delay_array("tau1", tau1)
        t2 = check_delay_array("tau2", tau2)
        x, y = np.broadcast_arrays(t1, t2)
        shape = x.shape
        x = x.ravel()
        y = y.ravel()
        if np.any(x > self.tau1_max * (1 + 1e-12)) or np.any(y > self.tau2_max * (1 + 1e-12)):
            raise DelayError(
                f"delays must lie in the map's window [0, {self.tau1_max}] x [0, {self.tau2_max}]"
            )
        count = np.full(x.shape, self.delay_free_count, dtype=np.int64)
        count += _axis_sum(self._axis2, y)
        count += _horizontal_crossings(self._segments, x, y, self.traced, max(self.tau1_max, self.tau2_max))
        on_axis = y == 0.0
        if all(t.is_retarded for t in self.traced):
            # Within a millionth of the window of the tau1 axis the horizontal path meets the curves
            # where they cross the axis, traced there only to the chord tolerance (2e-4 of the window):
            # a curve zig-zagging through tau2 = 0 was crossed several times and NU came out 30 too
            # high. A retarded qp's roots are continuous in the delays at tau2 = 0, so that close to
            # the axis NU is the axis walk's, exact to the map's resolution (a neutral qp may change
            # at tau2 = 0+, which is why it keeps the path).
            on_axis |= y <= 1e-6 * max(self.tau1_max, self.tau2_max)
        if np.any(on_axis):
            # tau2 = 0: walk along the tau1 axis instead of crossing the curves' ends.
            count[on_axis] = self._start1 + _axis_sum(self._axis1, x[on_axis])
        for line in self._zero_lines:
            count += _zero_line_count(line, x, y)
        return count.reshape(shape)

    def is_stable(self, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.bool_]:
        """True where NU = 0: every factor stable, the centroid marginally (Lemma 2)."""
        return self.unstable_count(tau1, tau2) == 0

    def stable_fraction(self, *, resolution: int = 400) -> float:
        """Fraction of the window's area that is stable, on a grid of cell centres."""
        t1 = (np.arange(resolution) + 0.5) * self.tau1_max / resolution
        t2 = (np.arange(resolution) + 0.5) * self.tau2_max / resolution
        return float(np.mean(self.is_stable(t1[None, :], t2[:, None])))

    @property
    def kernel_curves(self) -> tuple[CrossingCurve, ...]:
        """The kernel curves only."""
        return tuple(c for c in self.curves if c.is_kernel)

    @property
    def offspring_curves(self) -> tuple[CrossingCurve, ...]:
        """The offspring curves only."""
        return tuple(c for c in self.curves if not c.is_kernel)

    def plot(self, ax: Axes | None = None, points: dict[str, tuple[float, float]] | None = None) -> Axes:
        """Draw the chart (see :func:`delayform.plots.stability_chart`)."""
        from delayform.plots import stability_chart

        return stability_chart(self, ax=ax, points=points)

    # ------------------------------------------------------------ internals
    @property
    def _segments(self) -> NDArray[np.float64]:
        cached = self.__dict__.get("_segments_cache")
        if cached is None:
            cached = _segment_table(self.curves)
            object.__setattr__(self, "_segments_cache", cached)
        return cached


def curve_residual(qp: TwoDelayQuasiPolynomial, curve: CrossingCurve) -> NDArray[np.float64]:
    """Relative residual ``|q(j omega)| / sum_k |g_k(j omega)|`` at each point of a curve.

    Parameters
    ----------
    qp
        The quasi-polynomial of the paper's eq. 5 whose imaginary roots make the
        curve, usually ``m.traced[curve.source]`` of a :class:`StabilityMap` m.
    curve
        A :class:`CrossingCurve`; q is evaluated at ``s = j omega`` with the
        delays ``(tau1, tau2)`` of each of its points.

    Returns
    -------
    ndarray of float, shape of ``curve.omega``
        ``|q|`` over the sum of the moduli of its terms ``g_k(j omega)``
        (``|e^{-j omega h}| = 1``); every traced point has at most 1e-9
        (module docstring).
    """
    s = 1j * curve.omega
    total = np.zeros(s.shape, complex)
    scale = np.zeros(s.shape)
    for c, a, b in qp.terms():
        g = _horner(s, c)
        total += g * np.exp(-(a * curve.tau1 + b * curve.tau2) * s)
        scale += np.abs(g)
    return np.abs(total) / scale


def _assemble(
    sources: list[tuple[TwoDelayQuasiPolynomial, int, list[_Part]]], tau1_max: float, tau2_max: float
) -> StabilityMap:
    window = (tau1_max, tau2_max)
    curves: list[CrossingCurve] = []
    parts: list[_Part] = []
    start1 = start2 = 0
    lines: list[_ZeroLine] = []
    for qp, mult, qp_parts in sources:
        s1, s2, line = _origin_counts(qp, mult)
        start1 += s1
        start2 += s2
        if line is not None:
            lines.append(line)
        parts.extend(qp_parts)
    if parts and all(p.lam is not None for p in parts):
        # every part is a factor of eq. factorized: all traced at once (vectorized)
        lam = np.array([complex(p.lam) for p in parts])  # type: ignore[arg-type]
        P, D = float(parts[0].qp.g1[0].real), float(parts[0].qp.g1[1].real)
        curves = family_curves(parts, lam, P, D, window)
        axis2 = family_axis_crossings(parts, lam, P, D, window, axis=2)
        axis1 = family_axis_crossings(parts, lam, P, D, window, axis=1)
    else:
        for source, part in enumerate(parts):
            curves.extend(_part_curves(part, window, source))
        axis2 = _axis_crossings(parts, window, axis=2)
        axis1 = _axis_crossings(parts, window, axis=1)
    return StabilityMap(
        curves=tuple(curves), tau1_max=tau1_max, tau2_max=tau2_max, delay_free_count=start2,
        traced=tuple(p.qp for p in parts),
        _start1=start1,
        _axis2=axis2,
        _axis1=axis1,
        _zero_lines=tuple(lines),
    )


def _check_window(tau1_max: object, tau2_max: object) -> tuple[float, float]:
    return check_positive("tau1_max", tau1_max, DelayError), check_positive("tau2_max", tau2_max, DelayError)


#: rough cost of one traced curve (measured: ~0.35 ms and ~150 points on the paper's chart)
_SECONDS_PER_CURVE = 1e-3
_BYTES_PER_CURVE = 5_000.0


def _guard_window(qps: list[TwoDelayQuasiPolynomial], t1: float, t2: float) -> None:
    """Refuse a window whose offspring curves would not fit the machine (delayform.resources).

    Offspring repeat every 2 pi / omega along each delay, so a three-term
    part with crossing frequencies up to Omega has about
    (1 + tau1_max Omega / 2 pi)(1 + tau2_max Omega / 2 pi) curves in the window.
    """
    curves = sum(
        (1.0 + t1 * _omega_bound(q) / (2 * np.pi)) * (1.0 + t2 * _omega_bound(q) / (2 * np.pi)) for q in qps
    )
    require(
        what=f"a stability chart of the window [0, {t1:g}] x [0, {t2:g}] s (about {curves:.2g} crossing curves)",
        setting="the window (chart.tau1_max, chart.tau2_max, --tau1-max, --tau2-max)",
        nbytes=curves * _BYTES_PER_CURVE,
        seconds=curves * _SECONDS_PER_CURVE,
    )


# ===================================================================== public entry points
@validated()
def crossing_map(qp: TwoDelayQuasiPolynomial | QuasiPolynomial, tau1_max: float, tau2_max: float) -> StabilityMap:
    """The CTCR stability map of one retarded two-delay quasi-polynomial.

    Parameters
    ----------
    qp
        Any retarded :class:`~delayform.characteristic.TwoDelayQuasiPolynomial`
        (paper, eq. 5), or a :class:`~delayform.quasipolynomial.QuasiPolynomial`
        in two delays with any terms (commensurate ``z1^3``, ``z1 z2^2``, ...;
        :mod:`delayform.analysis.ctcr.general`); real or complex coefficients.
        A factor in one monomial ``z1^a z2^b`` (a product such as
        ``(s + 1 + 2 z1 z2)(s^2 + s + 1 + 0.5 z2)`` expanded) is split off
        exactly and drawn as its straight lines ``a tau1 + b tau2 = T``
        (:mod:`delayform.analysis.ctcr.factored`); ``traced`` then holds the pieces.
    tau1_max, tau2_max
        The window [0, tau1_max] x [0, tau2_max]; positive.

    Returns
    -------
    StabilityMap
        Kernel and offspring curves with omega and root tendencies, and NU.

    Raises
    ------
    NeutralQuasiPolynomialError
        For a neutral qp whose difference operator is not certified strongly
        stable for every delay pair (:func:`~delayform.analysis.ctcr.general.neutral_traced`);
        a neutral qp whose difference operator is gets its map.
    DelayError
        When the window is not positive and finite.
    ResourceLimitError
        When the window holds more crossing curves than the machine allows.

    Examples
    --------
    >>> from delayform.characteristic import TwoDelayQuasiPolynomial
    >>> q = TwoDelayQuasiPolynomial([1, 0.5, 1], [-0.5], [0, -0.25])
    >>> m = crossing_map(q, 10.0, 10.0)
    >>> int(m.unstable_count(0.1, 0.1)), bool(m.is_stable(0.1, 0.1))
    (0, True)
    """
    if isinstance(qp, TwoDelayQuasiPolynomial) and not qp.is_retarded:
        qp = QuasiPolynomial.from_two_delay(qp)  # neutral: the general path with D's frequency bound
    if isinstance(qp, QuasiPolynomial):
        traced = as_traced(qp)  # refuses what no map can answer (one delay, D not strongly stable)
        general = qp
    elif isinstance(qp, TwoDelayQuasiPolynomial):
        traced, general = qp, QuasiPolynomial.from_two_delay(qp)
    else:
        raise QuasiPolynomialError(
            f"qp must be a QuasiPolynomial in two delays or a TwoDelayQuasiPolynomial, got {type(qp).__name__}"
        )
    t1, t2 = _check_window(tau1_max, tau2_max)
    # a factor in one monomial has whole lines of crossings the two-delay sweep cannot see: split
    # off exactly, each factor is a one-delay problem (straight lines), and the NU of the pieces add
    split = split_monomial_factors(general)
    pieces = [as_traced(p) for p in split.pieces] if split.factors else [traced]
    sources = []
    for piece in pieces:
        if piece.is_real:
            parts = [_Part(piece, 2, 0)]
        else:
            parts = [_Part(piece, 1, 0), _Part(_conjugate(piece), 1, 1)]
        sources.append((piece, 1, parts))
    _guard_window([p.qp for _, _, parts in sources for p in parts], t1, t2)
    return _assemble(sources, t1, t2)


@validated()
def stability_map(
    topology: Topology, P: float, D: float, tau1_max: float, tau2_max: float, *, actuation_delay: float = 0.0
) -> StabilityMap | ActuatedStabilityMap:
    """The exact CTCR stability map of the formation protocol (paper, eq. 2).

    Every factor of the paper's eq. 3 is traced: a real eigenvalue lam gives the
    real three-term factor ``s^2 + D s + P - lam (D s z2 + P z1)``; a conjugate
    pair gives the fourth-order factor, whose imaginary roots are those of the
    three-term factors of lam and conj(lam). NU sums the factors weighted by
    multiplicity; the centroid root s = 0 is not counted (Lemma 2).

    Parameters
    ----------
    topology
        Communication topology; must have a spanning tree (Lemma 3).
    P, D
        Positive gains of the paper's eq. 1.
    tau1_max, tau2_max
        The window [0, tau1_max] x [0, tau2_max].
    actuation_delay
        tau_a >= 0 (s). Above 0 every factor gains the delayed own-state
        terms and the map, exact in (tau1, tau2) at this tau_a, is an
        :class:`~delayform.analysis.ctcr.actuated.ActuatedStabilityMap`
        (same counting and drawing interface); 0 (default): the paper's map.

    Returns
    -------
    StabilityMap or ActuatedStabilityMap

    Raises
    ------
    NoSpanningTreeError, GainError, DelayError
        For a topology without a spanning tree or bad gains or window.
    ResourceLimitError
        When the window holds more crossing curves than the machine's memory
        or the time budget allow (e.g. tau_max = 1e6).

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> m = stability_map(paper_six(), 1.0, 0.5, 8.0, 8.0)
    >>> [bool(m.is_stable(*PAPER_POINTS[k])) for k in "abcde"]
    [True, True, False, True, True]
    """
    topology.require_spanning_tree()
    t1, t2 = _check_window(tau1_max, tau2_max)
    ta = check_delay("actuation_delay", actuation_delay)
    sources = []
    for idx, f in enumerate(factors(topology, P, D)):
        mult = f.multiplicity
        if not f.group.is_complex_pair:
            parts = [_Part(f.quasi_polynomial, 2 * mult, idx, complex(f.lam))]
        else:
            parts = [_Part(lam_factor(f.P, f.D, lam), 2 * mult, idx, complex(lam)) for lam in (f.lam, np.conj(f.lam))]
        sources.append((f.quasi_polynomial, mult, parts))
    # with an actuation delay the crossing frequencies obey the same bound (|e^{-j w tau_a}| = 1)
    _guard_window([p.qp for _, _, parts in sources for p in parts], t1, t2)
    if ta > 0.0:
        return actuated_stability_map(topology, P, D, t1, t2, ta)
    return _assemble(sources, t1, t2)


def lam_factor(P: float, D: float, lam: complex) -> TwoDelayQuasiPolynomial:
    """The factor of one eigenvalue ``lam`` of C, ``s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s})``.

    A (complex, for complex ``lam``) three-term quasi-polynomial: the map of a
    conjugate pair is drawn from the factor of each member, and the eigenvalue
    plane (:mod:`delayform.analysis.plane`) maps any ``lam`` with it.

    Parameters
    ----------
    P, D
        The gains.
    lam
        An eigenvalue of C (any complex number).
    """
    return TwoDelayQuasiPolynomial([P, D, 1.0], [-lam * P], [0.0, -lam * D])

