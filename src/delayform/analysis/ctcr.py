"""Exact CTCR stability maps in the (tau1, tau2) plane (Section "Stability Analysis Using CTCR").

Conventions
-----------
A quasi-polynomial ``qp`` is the two-delay form of eq. genfactor,
``q(s) = g1 + g2 z1 + g3 z2 + g4 z1^2 + g5 z2^2 + g6 z1 z2`` with
``z1 = e^{-tau1 s}``, ``z2 = e^{-tau2 s}``. On the imaginary axis ``s = j omega``
we write ``z_k = e^{-j theta_k}`` with the phases ``theta_k = omega tau_k mod 2 pi``.
NU is the number of characteristic roots with Re s > 0; a root s = 0 that is
there for every delay (the centroid factor, eq. factor1) is never counted
(Lemma 2: it is the rigid-body mode).

How the crossing curves are found (the paper does not give its half-angle method)
----------------------------------------------------------------------------------
Every point of a kernel or offspring curve is a triple (omega, theta1, theta2)
with ``q(j omega) = 0``; the plane point is ``tau_k = (theta_k + 2 pi i_k) / omega``
(eq. nltrans, i_k = 0 for the kernel, Definition "Kernel curves"). Only
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
  closed form. A fourth-order factor of eq. factorized is
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
Cepeda-Gomez and Perico, Section "Stability Analysis Using CTCR": eq. genfactor,
Definitions "Kernel curves", "Offspring curves" (eq. nltrans), "Root Tendency",
Proposition "Invariant root tendency"; Lemmas 1-2 for the factors.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_delay_array, check_positive
from delayform.resources import require
from delayform.characteristic import DELAY_MULTIPLES, TwoDelayQuasiPolynomial, factors
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

TWO_PI = 2.0 * np.pi
#: Points of the paper's Fig. stability (Section "Simulation Examples"): a, b, d, e stable, c not.
PAPER_POINTS: dict[str, tuple[float, float]] = {
    "a": (0.3, 0.2),
    "b": (2.0, 1.0),
    "c": (1.0, 2.0),
    "d": (1.0, 5.5),
    "e": (3.5, 2.0),
}
#: Relative residual every curve point satisfies: |q(j omega)| / sum_k |g_k(j omega)|.
CURVE_TOLERANCE = 1e-9
#: Chord deviation (fraction of the window size) below which a curve piece is not refined.
_CHORD_TOL = 2e-4
#: Longest chord (fraction of the window size) kept without refinement.
_MAX_CHORD = 0.02
_MAX_ROUNDS = 26
#: Cap on the samples of one phase path (a guard; real curves need a few thousand).
_MAX_POINTS = 200_000
#: Lowest crossing frequency traced, relative to the bound on crossing frequencies.
_OMEGA_FLOOR = 1e-4


# ===================================================================== results
@dataclass(frozen=True, eq=False)
class CrossingCurve:
    """One kernel or offspring curve piece inside (or touching) the window.

    Attributes
    ----------
    tau1, tau2
        Points of the curve, in order along it (a polyline).
    omega
        Crossing frequency at each point: ``s = j omega`` is a root there.
    rt1, rt2
        Root tendencies w.r.t. tau1 and tau2 at each point (Definition "Root Tendency").
    kind
        ``"kernel"`` when ``0 < omega tau_k < 2 pi`` for both delays, else ``"offspring"``.
    shift
        ``(i, k)`` of eq. nltrans: ``tau = tau_kernel + (2 pi i, 2 pi k) / omega``.
    weight
        Change of NU per unit of root tendency when the curve is crossed
        (2 for a conjugate pair, 1 for one root of a complex qp; times the multiplicity).
    source
        Index into :attr:`StabilityMap.traced` of the quasi-polynomial whose
        imaginary roots make the curve (``curve_residual(m.traced[c.source], c)``).
    factor
        Index of the characteristic factor (order of :func:`~delayform.characteristic.factors`;
        0 for :func:`crossing_map`).
    """

    tau1: NDArray[np.float64]
    tau2: NDArray[np.float64]
    omega: NDArray[np.float64]
    rt1: NDArray[np.int64]
    rt2: NDArray[np.int64]
    kind: str
    shift: tuple[int, int]
    weight: int
    source: int
    factor: int

    @property
    def is_kernel(self) -> bool:
        """True for a kernel curve (Definition "Kernel curves")."""
        return self.kind == "kernel"


@dataclass(frozen=True)
class _ZeroLine:
    """The line ``q'(0) = c0 + c1 tau1 + c2 tau2 = 0`` of a real qp with a root s = 0."""

    c0: float
    c1: float
    c2: float
    qp: TwoDelayQuasiPolynomial
    weight: int


@dataclass(frozen=True, eq=False)
class StabilityMap:
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
        three-term factors of lam and conj(lam)).
    """

    curves: tuple[CrossingCurve, ...]
    tau1_max: float
    tau2_max: float
    delay_free_count: int
    traced: tuple[TwoDelayQuasiPolynomial, ...] = field(repr=False)
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


# ===================================================================== polynomials in omega
def _horner(x: ArrayLike, c: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """p(x) for coefficients c in increasing powers (Horner; cheaper than numpy's polyval here)."""
    x = np.asarray(x)
    c = np.asarray(c)
    if c.size == 0:
        return np.zeros(x.shape, complex)
    out = np.full(x.shape, c[-1], dtype=np.result_type(x.dtype, c.dtype))
    for a in c[-2::-1]:
        out = out * x + a
    return out


def _deriv(c: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Coefficients of p'."""
    c = np.asarray(c)
    if c.size <= 1:
        return np.zeros(1, c.dtype)
    return c[1:] * np.arange(1, c.size)


def _at_j_omega(c: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Coefficients in omega of g(j omega), increasing powers."""
    return c * (1j ** np.arange(c.size)) if c.size else np.zeros(1, complex)


def _conj_poly(c: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Coefficients of conj(p(omega)) for real omega."""
    return np.conj(c)


def _mod2(c: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """|g(j omega)|^2 as a polynomial in omega (real up to rounding)."""
    w = _at_j_omega(c)
    return npoly.polymul(w, _conj_poly(w))


def _positive_real_roots(poly: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Positive real roots of a real polynomial (given as complex coefficients), polished."""
    p = np.asarray(poly).real.astype(float)
    scale = np.max(np.abs(p)) if p.size else 0.0
    if scale == 0.0:
        return np.zeros(0)
    p = p / scale
    nz = np.flatnonzero(np.abs(p) > 1e-14)
    p = p[: nz[-1] + 1]
    if p.size < 2:
        return np.zeros(0)
    roots = np.roots(p[::-1])
    real = np.sort(roots[np.abs(roots.imag) <= 1e-6 * np.maximum(1.0, np.abs(roots))].real)
    if real.size == 0:
        return real
    # A double root (the gain condition only touched) comes out as two values ~1e-8 apart:
    # merge such clusters and polish a double root as the simple root of p'.
    gaps = np.diff(real) > 1e-6 * np.maximum(1.0, np.abs(real[1:]))
    labels = np.concatenate([[0], np.cumsum(gaps)])
    size = np.bincount(labels)
    value = np.bincount(labels, weights=real) / size
    out = []
    for r, m in zip(value, size, strict=True):
        if m <= 2:
            f = p if m == 1 else _deriv(p)
            df = _deriv(f)
            for _ in range(4):
                d = _horner(r, df)
                step = _horner(r, f) / d if d != 0.0 else 0.0
                if not abs(step) <= 1e-6 * max(1.0, abs(r)):
                    break
                r = r - step
        out.append(float(r))
    arr = np.array(out)
    return arr[arr > 1e-12]


def _omega_bound(qp: TwoDelayQuasiPolynomial) -> float:
    """Upper bound on |s| of every root with Re s >= 0 (so on every crossing frequency).

    With |e^{-tau s}| <= 1 for Re s >= 0, a root needs
    ``|g1(s)| <= sum_{k>1} |g_k(s)|``; bounding both sides by the moduli of the
    coefficients gives a polynomial with one sign change (Descartes), whose
    positive root bounds |s| for every pair of delays.
    """
    coeffs = qp.coefficients
    d = qp.degree
    lower = np.zeros(d + 1)
    for c in coeffs:
        lower[: c.size] += np.abs(c)
    lower[d] = 0.0
    lower = lower / abs(qp.g1[d])
    # |s|^d > sum lower_i |s|^i holds for |s| > max(1, sum lower_i) (Cauchy-like bound).
    return float(max(1.0, lower.sum()) * 1.0001)


# ===================================================================== root tendency
def _tendency(
    qp: TwoDelayQuasiPolynomial, omega: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(RT1, RT2) = sgn Re ds/dtau_k at s = j omega (Definition "Root Tendency").

    Unchecked delays, because curve polylines may run a little past the axes.
    """
    return qp.root_tendencies(omega, t1, t2)


def curve_residual(qp: TwoDelayQuasiPolynomial, curve: CrossingCurve) -> NDArray[np.float64]:
    """Relative residual ``|q(j omega)| / sum_k |g_k(j omega)|`` at each point of a curve.

    Parameters
    ----------
    qp
        The quasi-polynomial of eq. genfactor whose imaginary roots make the
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


# ===================================================================== curves in phase space
@dataclass(frozen=True)
class _PhasePath:
    """A connected piece of crossing set: omega and unwrapped phases along it."""

    omega: NDArray[np.float64]
    theta1: NDArray[np.float64]
    theta2: NDArray[np.float64]


def _three_term_phases(
    g1w: NDArray[np.complex128], g2w: NDArray[np.complex128], g3w: NDArray[np.complex128],
    omega: NDArray[np.float64], branch: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Closed-form phases of ``g1 + g2 z1 + g3 z2 = 0`` at j omega (law of cosines).

    ``u = g2 z1`` has modulus |g2| and ``v = g3 z2 = -g1 - u`` modulus |g3|; the
    angle between u and -g1 is ``+-alpha`` with
    ``cos alpha = (|g1|^2 + |g2|^2 - |g3|^2) / (2 |g1| |g2|)``; ``branch`` is +-1.
    """
    a = _horner(omega, g1w)
    b = _horner(omega, g2w)
    c = _horner(omega, g3w)
    r1, r2, r3 = np.abs(a), np.abs(b), np.abs(c)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_alpha = np.clip((r1**2 + r2**2 - r3**2) / (2.0 * r1 * r2), -1.0, 1.0)
        w = -a
        u = r2 * np.exp(1j * (np.angle(w) + branch * np.arccos(cos_alpha)))
        z1 = u / b
        z2 = (w - u) / c
    return np.mod(-np.angle(z1), TWO_PI), np.mod(-np.angle(z2), TWO_PI)


def _three_term_paths(qp: TwoDelayQuasiPolynomial, window: tuple[float, float]) -> list[_PhasePath]:
    """Crossing set of ``g1 + g2 z1 + g3 z2`` (omega > 0), one path per frequency interval."""
    g1w, g2w, g3w = (_at_j_omega(c) for c in (qp.g1, qp.g2, qp.g3))
    A, B, C = _mod2(qp.g1), _mod2(qp.g2), _mod2(qp.g3)
    S = npoly.polysub(npoly.polysub(A, B), C)
    F = npoly.polysub(npoly.polymul(S, S), 4.0 * npoly.polymul(B, C))
    ends = _positive_real_roots(F)
    bound = _omega_bound(qp)
    grid = np.concatenate([[0.0], ends[ends < bound * 1.5], [bound * 1.5]])
    paths = []
    for lo, hi in zip(grid[:-1], grid[1:], strict=True):
        mid = 0.5 * (lo + hi)
        if hi - lo <= 1e-12 * hi or _horner(mid, F).real > 0.0:
            continue
        def phases(phi: NDArray[np.float64], lo: float = lo, hi: float = hi) -> tuple[NDArray, ...]:
            # phi in [0, 2 pi]: branch + for phi < pi (omega up), branch - back down.
            om = lo + (hi - lo) * 0.5 * (1.0 - np.cos(phi))
            br = np.where(phi <= np.pi, 1.0, -1.0)
            t1, t2 = _three_term_phases(g1w, g2w, g3w, om, br)
            return om, t1, t2
        start = 0.0
        stop = TWO_PI
        if lo == 0.0:
            # omega -> 0 is not a crossing: open the loop there. Below omega ~ 1e-4 bound the
            # delays tau = theta / omega lose ~ eps / omega^2 to rounding (the triangle
            # degenerates), so the path stops there; the piece left out is O(1e-4) long.
            start = float(np.arccos(1.0 - 2.0 * min(_OMEGA_FLOOR * bound / hi, 0.5)))
            stop = TWO_PI - start
        paths.extend(_adaptive_path(phases, start, stop, window))
    return paths


def _adaptive_path(phases: Any, start: float, stop: float, window: tuple[float, float]) -> list[_PhasePath]:
    """Sample a closed-form parametrised curve, refining where its plane image bends."""
    t = np.linspace(start, stop, 97)
    if start > 0.0:  # geometric points toward both omega -> 0 ends of an open path
        geo = start * np.geomspace(1.0, min(2e3, 1.5 / start), 24)
        t = np.unique(np.concatenate([t, geo, stop + start - geo]))
        t = t[(t >= start) & (t <= stop)]
    om, th1, th2 = phases(t)
    scale = max(window)
    for _ in range(_MAX_ROUNDS):
        u1, u2 = np.unwrap(th1), np.unwrap(th2)
        mid_t = 0.5 * (t[:-1] + t[1:])
        m_om, m1, m2 = phases(mid_t)
        m1 = u1[:-1] + np.angle(np.exp(1j * (m1 - u1[:-1])))
        m2 = u2[:-1] + np.angle(np.exp(1j * (m2 - u2[:-1])))
        need = _needs_refinement(om, u1, u2, m_om, m1, m2, window, scale)
        # Below this parameter step the phases are rounding noise (e.g. a flat curve whose
        # "turning points" are noise): refining further would only multiply points.
        need &= np.diff(t) > 1e-9 * (stop - start)
        if not np.any(need) or t.size > _MAX_POINTS:
            break
        t = np.sort(np.concatenate([t, mid_t[need]]))
        om, th1, th2 = phases(t)
    return [_PhasePath(om, np.unwrap(th1), np.unwrap(th2))]


def _needs_refinement(
    om: NDArray, u1: NDArray, u2: NDArray, m_om: NDArray, m1: NDArray, m2: NDArray,
    window: tuple[float, float], scale: float,
) -> NDArray[np.bool_]:
    """Intervals whose image (kernel and farthest offspring in the window) bends or is long."""
    inv = 1.0 / om
    m_inv = 1.0 / m_om
    # Only refine what can reach the window: the lowest image (tau >= 0) of both delays below tau_max.
    relevant = np.ones(m_om.shape, bool)
    for u, tmax in ((u1, window[0]), (u2, window[1])):
        lowest = np.minimum(np.mod(u[:-1], TWO_PI) * inv[:-1], np.mod(u[1:], TWO_PI) * inv[1:])
        relevant &= lowest <= tmax * 1.05
    need = np.zeros(m_om.shape, bool)
    for u, m, tmax in ((u1, m1, window[0]), (u2, m2, window[1])):
        n_far = np.ceil(tmax * np.maximum(om[:-1], om[1:]) / TWO_PI) + 1.0
        tau_a, tau_b, tau_m = u[:-1] * inv[:-1], u[1:] * inv[1:], m * m_inv
        dev = np.abs(tau_m - 0.5 * (tau_a + tau_b))
        dev_shift = TWO_PI * n_far * np.abs(m_inv - 0.5 * (inv[:-1] + inv[1:]))
        chord = np.abs(tau_b - tau_a) + TWO_PI * n_far * np.abs(inv[1:] - inv[:-1])
        need |= (dev + dev_shift > _CHORD_TOL * scale) | (chord > _MAX_CHORD * scale)
    need |= _turning_needs(om, u2, m_om, m2, window[1], scale)
    return need & relevant


def _turning_needs(
    om: NDArray, u2: NDArray, m_om: NDArray, m2: NDArray, t2max: float, scale: float
) -> NDArray[np.bool_]:
    """Intervals next to a turning point in tau2 of some image whose chord is off by > 1e-9 scale.

    Near a horizontal tangent a horizontal line meets the curve twice, close
    together; the polyline must be exact there for the count to be, so these
    intervals are refined far below the general chord tolerance.
    """
    need = np.zeros(m_om.shape, bool)
    if om.size < 3:
        return need
    k_lo = int(np.ceil(np.min(-u2) / TWO_PI))
    k_hi = int(np.floor(np.max(t2max * om - u2) / TWO_PI))
    if k_hi < k_lo:
        return need
    ks = np.arange(k_lo, k_hi + 1, dtype=float)[:, None]
    tau = (u2[None, :] + TWO_PI * ks) / om[None, :]
    d = np.diff(tau, axis=1)
    turn = (d[:, :-1] * d[:, 1:] < 0.0) & (tau[:, 1:-1] >= -0.02 * t2max) & (tau[:, 1:-1] <= 1.02 * t2max)
    if not np.any(turn):
        return need
    mid = (m2[None, :] + TWO_PI * ks) / m_om[None, :]
    dev = np.abs(mid - 0.5 * (tau[:, :-1] + tau[:, 1:])) > 1e-9 * scale
    near = np.zeros(d.shape, bool)
    near[:, :-1] |= turn
    near[:, 1:] |= turn
    return np.any(near & dev, axis=0)


# --------------------------------------------------------------------- general qps
def _batched_conv(a: NDArray[np.complex128], b: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Row-wise polynomial products of (n, p) and (n, q) coefficient arrays."""
    out = np.zeros((a.shape[0], a.shape[1] + b.shape[1] - 1), complex)
    for j in range(b.shape[1]):
        out[:, j : j + a.shape[1]] += a * b[:, j : j + 1]
    return out


def _general_solutions(qp: TwoDelayQuasiPolynomial, omega: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """All (theta1, theta2) with q(j omega) = 0 at each omega: resultant in z2, unit roots, Newton."""
    s = 1j * omega
    g = [_horner(s, c) if c.size else np.zeros(s.shape, complex) for c in qp.coefficients]
    g1, g2, g3, g4, g5, g6 = g
    n = omega.size
    b = np.stack([g2, g6], 1)              # powers z2^0..1
    c = np.stack([g1, g3, g5], 1)          # powers z2^0..2
    cbar = np.conj(c[:, ::-1])             # conj(c) z2^2, powers 0..2 (offset -2)
    bbar = np.conj(b[:, ::-1])             # conj(b) z2, powers 0..1 (offset -1)
    if np.all(g4 == 0):
        # Linear in z1: |z1| = 1 iff |c|^2 = |b|^2; times z2^2.
        cc = _batched_conv(c, cbar)                       # offset -2, len 5
        bb = np.zeros((n, 5), complex)
        bb[:, 1:4] = _batched_conv(b, bbar)               # offset -1 -> shift 1
        R = cc - bb
    else:
        a = g4[:, None]
        abar = np.conj(a)
        X0 = -_batched_conv(c, cbar)
        X0[:, 2] += (a * abar)[:, 0]                     # (|a|^2 - c cbar), offset -2, len 5
        Xs = _batched_conv(X0, X0)                        # offset -4, len 9
        U = np.zeros((n, 4), complex)                     # a bbar - b cbar, offset -2
        U[:, 1:3] += a * bbar
        U -= _batched_conv(b, cbar)
        V = np.zeros((n, 4), complex)                     # b abar - c bbar, offset -1
        V[:, 1:3] += b * abar
        V -= _batched_conv(c, bbar)
        R = Xs.copy()
        R[:, 1:8] -= _batched_conv(U, V)                  # offset -3 -> shift 1
    out: list[NDArray[np.float64]] = []
    for i in range(n):
        poly = R[i]
        scale = np.max(np.abs(poly))
        nz = np.flatnonzero(np.abs(poly) > 1e-13 * scale) if scale > 0 else np.zeros(0, int)
        if nz.size < 2:
            out.append(np.zeros((0, 2)))
            continue
        z2 = np.roots(poly[nz[0] : nz[-1] + 1][::-1])
        z2 = z2[np.abs(np.abs(z2) - 1.0) < 1e-4]
        sols = []
        for z in z2:
            bz = b[i, 0] + b[i, 1] * z
            cz = c[i, 0] + c[i, 1] * z + c[i, 2] * z * z
            if g4[i] == 0:
                cand = [-cz / bz] if bz != 0 else []
            else:
                cand = list(np.roots([g4[i], bz, cz]))
            for z1 in cand:
                if abs(abs(z1) - 1.0) > 1e-3:
                    continue
                th = _newton_phases(g, i, -np.angle(z1), -np.angle(z))
                if th is not None:
                    sols.append(th)
        out.append(_unique_phases(np.array(sols).reshape(-1, 2)))
    return out


def _newton_phases(g: list[NDArray], i: int, t1: float, t2: float) -> tuple[float, float] | None:
    """Polish (theta1, theta2) on sum_k g_k e^{-j(a theta1 + b theta2)} = 0 at one omega."""
    coef = np.array([gk[i] for gk in g])
    mult = np.array(DELAY_MULTIPLES, float)
    scale = np.sum(np.abs(coef))
    for _ in range(30):
        e = coef * np.exp(-1j * (mult[:, 0] * t1 + mult[:, 1] * t2))
        f = e.sum()
        d1 = (-1j * mult[:, 0] * e).sum()
        d2 = (-1j * mult[:, 1] * e).sum()
        J = np.array([[d1.real, d2.real], [d1.imag, d2.imag]])
        if abs(f) <= 1e-14 * scale:
            break
        try:
            step = np.linalg.solve(J, [f.real, f.imag])
        except np.linalg.LinAlgError:
            return None
        t1 -= step[0]
        t2 -= step[1]
    e = coef * np.exp(-1j * (mult[:, 0] * t1 + mult[:, 1] * t2))
    if abs(e.sum()) > 1e-11 * scale:
        return None
    return float(np.mod(t1, TWO_PI)), float(np.mod(t2, TWO_PI))


def _unique_phases(th: NDArray[np.float64]) -> NDArray[np.float64]:
    keep: list[NDArray[np.float64]] = []
    for row in th:
        if all(_torus_dist(row, k) > 1e-7 for k in keep):
            keep.append(row)
    return np.array(keep).reshape(-1, 2)


def _dist_matrix(A: NDArray[np.float64], B: NDArray[np.float64]) -> NDArray[np.float64]:
    """Torus (max-coordinate) distances between phase pairs, rows of A by rows of B."""
    d = np.mod(A[:, None, :] - B[None, :, :] + np.pi, TWO_PI) - np.pi
    return np.abs(d).max(axis=2)


def _torus_dist(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    d = np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))
    return float(np.max(d))


def _general_paths(qp: TwoDelayQuasiPolynomial, window: tuple[float, float]) -> list[_PhasePath]:
    """Crossing set of a general retarded qp: adaptive omega sweep joined into paths."""
    from scipy.optimize import linear_sum_assignment

    bound = _omega_bound(qp)
    omega = np.unique(np.concatenate([np.linspace(bound * 1e-3, bound, 600), bound * np.geomspace(_OMEGA_FLOOR, 1e-3, 12)]))
    sols = _general_solutions(qp, omega)
    # Bisect wherever the number of solutions changes or neighbours are far apart.
    for _ in range(40):
        extra = []
        for i in range(omega.size - 1):
            na, nb = len(sols[i]), len(sols[i + 1])
            gap = omega[i + 1] - omega[i]
            if gap <= 1e-12 * omega[i + 1]:
                continue
            far = na == nb and na > 0 and _max_match_dist(sols[i], sols[i + 1]) > 0.05
            if na != nb or (far and gap > 1e-9 * omega[i + 1]):
                extra.append(0.5 * (omega[i] + omega[i + 1]))
        if not extra:
            break
        new = np.array(extra)
        new_sols = _general_solutions(qp, new)
        allw = np.concatenate([omega, new])
        order = np.argsort(allw)
        merged = sols + new_sols
        omega = allw[order]
        sols = [merged[k] for k in order]
    # Graph: nodes (sample, index); edges by assignment; turning points pair the leftovers.
    nodes = [(i, j) for i in range(omega.size) for j in range(len(sols[i]))]
    adj: dict[tuple[int, int], list[tuple[int, int]]] = {v: [] for v in nodes}
    for i in range(omega.size - 1):
        A, Bs = sols[i], sols[i + 1]
        if len(A) and len(Bs):
            D = _dist_matrix(A, Bs)
            r, c = linear_sum_assignment(D)
            for ri, ci in zip(r, c, strict=True):
                if D[ri, ci] < 0.3:
                    adj[(i, ri)].append((i + 1, ci))
                    adj[(i + 1, ci)].append((i, ri))
        for side in (i, i + 1):
            loose = [v for v in ((side, j) for j in range(len(sols[side]))) if len(adj[v]) < 2 and _is_end(v, i, adj)]
            while len(loose) >= 2:
                best = min(
                    ((p, q) for p in loose for q in loose if p < q),
                    key=lambda pq: _torus_dist(sols[pq[0][0]][pq[0][1]], sols[pq[1][0]][pq[1][1]]),
                )
                if _torus_dist(sols[best[0][0]][best[0][1]], sols[best[1][0]][best[1][1]]) > 0.3:
                    break
                adj[best[0]].append(best[1])
                adj[best[1]].append(best[0])
                loose = [v for v in loose if v not in best]
    return _walk_paths(adj, omega, sols)


def _is_end(v: tuple[int, int], i: int, adj: dict[tuple[int, int], list[tuple[int, int]]]) -> bool:
    """A node of sample i or i + 1 not joined across the gap (i, i + 1)."""
    other = i + 1 if v[0] == i else i
    return not any(w[0] == other for w in adj[v])


def _max_match_dist(A: NDArray[np.float64], B: NDArray[np.float64]) -> float:
    from scipy.optimize import linear_sum_assignment

    D = _dist_matrix(A, B)
    r, c = linear_sum_assignment(D)
    return float(D[r, c].max())


def _walk_paths(
    adj: dict[tuple[int, int], list[tuple[int, int]]], omega: NDArray[np.float64], sols: list[NDArray[np.float64]]
) -> list[_PhasePath]:
    seen: set[tuple[int, int]] = set()
    paths: list[_PhasePath] = []
    starts = [v for v in adj if len(adj[v]) != 2] + list(adj)
    for v0 in starts:
        if v0 in seen:
            continue
        walk = [v0]
        seen.add(v0)
        prev, cur = None, v0
        while True:
            nxt = [w for w in adj[cur] if w != prev and w not in seen]
            if not nxt:
                if len(adj[cur]) == 2 and v0 in adj[cur] and len(walk) > 2:
                    walk.append(v0)  # close the loop
                break
            prev, cur = cur, nxt[0]
            walk.append(cur)
            seen.add(cur)
        if len(walk) < 2:
            continue
        om = np.array([omega[i] for i, _ in walk])
        th = np.array([sols[i][j] for i, j in walk])
        paths.append(_PhasePath(om, np.unwrap(th[:, 0]), np.unwrap(th[:, 1])))
    return paths


# --------------------------------------------------------------------- degenerate (one delay)
def _single_delay_roots(
    h0: NDArray[np.complex128], h1: NDArray[np.complex128], h2: NDArray[np.complex128]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """omega > 0 and theta in [0, 2 pi) with ``h0 + h1 z + h2 z^2 = 0``, ``z = e^{-j theta}``.

    The unit-circle condition is eliminated exactly: for h2 = 0 it is
    ``|h0|^2 = |h1|^2``; otherwise the resultant of the quadratic and its
    conjugate-reciprocal, ``(|h2|^2 - |h0|^2)^2 - |h2 conj(h1) - h1 conj(h0)|^2``.
    """
    if h1.size == 0 and h2.size == 0:
        return np.zeros(0), np.zeros(0)
    w0, w1, w2 = (_at_j_omega(h) for h in (h0, h1, h2))
    if h2.size == 0:
        poly = npoly.polysub(_mod2(h0), _mod2(h1))
    else:
        X = npoly.polysub(_mod2(h2), _mod2(h0))
        Y = npoly.polysub(npoly.polymul(w2, np.conj(w1)), npoly.polymul(w1, np.conj(w0)))
        poly = npoly.polysub(npoly.polymul(X, X), npoly.polymul(Y, np.conj(Y)))
    omegas = _positive_real_roots(poly)
    out_w, out_t = [], []
    for om in omegas:
        a, b, c = (_horner(om, w) for w in (w2, w1, w0))
        cands = [-c / b] if h2.size == 0 else list(np.roots([a, b, c]))
        for z in cands:
            if not np.isfinite(z) or abs(abs(z) - 1.0) > 1e-5:
                continue
            th0 = float(-np.angle(z))
            e = np.exp(-1j * th0)
            if abs(c + b * e + a * e * e) <= 1e-12 * (abs(a) + abs(b) + abs(c)):
                # omega is a polished polynomial root: keep it (at a touching root the 2x2
                # Newton below is singular and would move it off).
                om_p, th = float(om), th0
            else:
                om_p, th = _newton_single(w0, w1, w2, float(om), th0)
            if th is not None:
                out_w.append(om_p)
                out_t.append(np.mod(th, TWO_PI))
    return np.array(out_w), np.array(out_t)


def _newton_single(
    w0: NDArray, w1: NDArray, w2: NDArray, om: float, th: float
) -> tuple[float, float | None]:
    """Polish (omega, theta) on h0 + h1 e^{-j theta} + h2 e^{-2 j theta} = 0."""
    def f_and_j(om: float, th: float) -> tuple[complex, complex, complex, float]:
        e = np.exp(-1j * th)
        v = [_horner(om, w) for w in (w0, w1, w2)]
        dv = [_horner(om, _deriv(w)) if w.size > 1 else 0.0 for w in (w0, w1, w2)]
        f = v[0] + v[1] * e + v[2] * e * e
        fo = dv[0] + dv[1] * e + dv[2] * e * e
        ft = -1j * v[1] * e - 2j * v[2] * e * e
        return f, fo, ft, abs(v[0]) + abs(v[1]) + abs(v[2])
    for _ in range(20):
        f, fo, ft, scale = f_and_j(om, th)
        if abs(f) <= 1e-15 * scale:
            break
        J = np.array([[fo.real, ft.real], [fo.imag, ft.imag]])
        try:
            step = np.linalg.solve(J, [f.real, f.imag])
        except np.linalg.LinAlgError:
            break
        om, th = om - step[0], th - step[1]
    f, _, _, scale = f_and_j(om, th)
    return om, (th if abs(f) <= 1e-10 * scale and om > 0 else None)


# ===================================================================== embedding in the plane
def _embed(
    path: _PhasePath, qp: TwoDelayQuasiPolynomial, window: tuple[float, float], weight: int, source: int,
    factor: int,
) -> list[CrossingCurve]:
    """All kernel/offspring images (eq. nltrans) of a phase path that meet the window."""
    om, u1, u2 = path.omega, path.theta1, path.theta2
    t1max, t2max = window
    margin1, margin2 = 0.02 * t1max, 0.02 * t2max
    i_lo = int(np.ceil(np.min(-u1) / TWO_PI))
    i_hi = int(np.floor(np.max(t1max * om - u1) / TWO_PI))
    k_lo = int(np.ceil(np.min(-u2) / TWO_PI))
    k_hi = int(np.floor(np.max(t2max * om - u2) / TWO_PI))
    images = []
    for i in range(i_lo, i_hi + 1):
        p1 = u1 + TWO_PI * i
        tau1 = p1 / om
        in1 = (tau1 >= -margin1) & (tau1 <= t1max + margin1)
        if not np.any(in1):
            continue
        for k in range(k_lo, k_hi + 1):
            p2 = u2 + TWO_PI * k
            tau2 = p2 / om
            inside = in1 & (tau2 >= -margin2) & (tau2 <= t2max + margin2)
            if np.any(inside):
                images.append((tau1, tau2, p1, p2, inside))
    if not images:
        return []
    # Root tendencies of all images in one vectorized call, then cut into pieces.
    n = om.size
    rt1, rt2 = _tendency(qp, np.tile(om, len(images)), np.concatenate([im[0] for im in images]),
                         np.concatenate([im[1] for im in images]))
    curves: list[CrossingCurve] = []
    for j, (tau1, tau2, p1, p2, inside) in enumerate(images):
        rts = (rt1[j * n : (j + 1) * n], rt2[j * n : (j + 1) * n])
        curves.extend(_split_runs(om, tau1, tau2, p1, p2, inside, rts, weight, source, factor))
    return curves


def _split_runs(
    om: NDArray, tau1: NDArray, tau2: NDArray, p1: NDArray, p2: NDArray, inside: NDArray,
    rts: tuple[NDArray[np.int64], NDArray[np.int64]], weight: int, source: int, factor: int,
) -> list[CrossingCurve]:
    """Cut one image into runs near the window, each of one kind (kernel/offspring)."""
    # Keep each inside point and its neighbours, so segments crossing the border survive.
    keep = inside.copy()
    keep[:-1] |= inside[1:]
    keep[1:] |= inside[:-1]
    i1 = np.floor(p1 / TWO_PI).astype(np.int64)
    i2 = np.floor(p2 / TWO_PI).astype(np.int64)
    kernel = (i1 == 0) & (i2 == 0)
    # Run boundaries: where keep flips off, or the kind changes (shared vertex kept in both).
    out: list[CrossingCurve] = []
    idx = np.flatnonzero(keep)
    if idx.size == 0:
        return out
    breaks = np.flatnonzero(np.diff(idx) > 1)
    for run in np.split(idx, breaks + 1):
        if run.size < 2:
            continue
        kinds = kernel[run]
        # One piece per shift (i, k) of eq. nltrans; the last vertex is shared with the next piece.
        cut = np.flatnonzero((i1[run][1:] != i1[run][:-1]) | (i2[run][1:] != i2[run][:-1])) + 1
        bounds = np.concatenate([[0], cut, [run.size]])
        for a, b in zip(bounds[:-1], bounds[1:], strict=True):
            sel = run[a : min(b + 1, run.size)]  # share the vertex with the next piece
            if sel.size < 2:
                continue
            out.append(
                CrossingCurve(
                    tau1=tau1[sel], tau2=tau2[sel], omega=om[sel], rt1=rts[0][sel], rt2=rts[1][sel],
                    kind="kernel" if kinds[a] else "offspring",
                    shift=(int(i1[sel[0]]), int(i2[sel[0]])), weight=weight, source=source,
                    factor=factor,
                )
            )
    return out


# ===================================================================== counting helpers
def _segment_table(curves: tuple[CrossingCurve, ...]) -> NDArray[np.float64]:
    """Rows (x0, y0, x1, y1, w RT1, source, omega0, omega1, w, at_turn) of the non-horizontal segments.

    RT1 changes sign where the curve turns in tau2 (horizontal tangent). A
    segment ending at such a vertex takes RT1 from its other end and is marked
    ``at_turn``: its crossing keeps the polyline's value, because a line just
    under the turning point meets the curve twice, close together, and an exact
    solve from either segment could find the same one of the two. w RT1 is 0
    where the ends still disagree; it is then taken at the crossing point.
    """
    rows = []
    for c in curves:
        a, b = c.rt1[:-1], c.rt1[1:]
        dy = np.diff(c.tau2)
        ext = np.zeros(c.tau2.size, bool)
        ext[1:-1] = dy[:-1] * dy[1:] < 0.0
        ea, eb = ext[:-1], ext[1:]
        rt = np.where(a == b, a, 0)
        rt = np.where(ea & ~eb, b, np.where(eb & ~ea, a, np.where(ea & eb, 0, rt)))
        src = np.full(rt.shape, float(c.source))
        w = np.full(rt.shape, float(c.weight))
        rows.append(np.column_stack([c.tau1[:-1], c.tau2[:-1], c.tau1[1:], c.tau2[1:], c.weight * rt,
                                     src, c.omega[:-1], c.omega[1:], w, (ea | eb).astype(float)]))
    if not rows:
        return np.zeros((0, 10))
    seg = np.concatenate(rows)
    return seg[seg[:, 1] != seg[:, 3]]


def _horizontal_crossings(
    seg: NDArray[np.float64], x: NDArray[np.float64], y: NDArray[np.float64],
    traced: tuple[TwoDelayQuasiPolynomial, ...], scale: float,
) -> NDArray[np.int64]:
    """Sum of w RT1 over the curves met by each horizontal path (0, y) -> (x, y).

    Crossings are found once per distinct tau2 of the queries: the polyline
    gives where each segment meets the line, then the crossing is recomputed
    exactly, solving ``q(j omega; tau1, tau2) = 0`` for (omega, tau1) by Newton's
    method, so that points close to a curve land on the right side of it.
    Queries then read a cumulative sum over the crossings sorted by tau1.
    """
    out = np.zeros(x.size, np.int64)
    if seg.shape[0] == 0 or x.size == 0:
        return out
    uy, inv = np.unique(y, return_inverse=True)
    ylo = np.minimum(seg[:, 1], seg[:, 3])
    yhi = np.maximum(seg[:, 1], seg[:, 3])
    lo = np.searchsorted(uy, ylo, "left")
    hi = np.searchsorted(uy, yhi, "left")  # half-open [ylo, yhi): shared vertices count once
    counts = hi - lo
    n_pairs = int(counts.sum())
    if n_pairs > 20_000_000 and uy.size > 1:
        # Too many (segment, line) pairs at once: split the queries by tau2.
        cut = uy[uy.size // 2]
        low = y < cut
        out[low] = _horizontal_crossings(seg, x[low], y[low], traced, scale)
        out[~low] = _horizontal_crossings(seg, x[~low], y[~low], traced, scale)
        return out
    if n_pairs == 0:
        return out
    sid = np.repeat(np.arange(seg.shape[0]), counts)
    yi = np.arange(n_pairs) - np.repeat(np.cumsum(counts) - counts, counts) + lo[sid]
    x0, y0, x1, y1, w, src, om0, om1, weight, at_turn = seg[sid].T
    yy = uy[yi]
    frac = (yy - y0) / (y1 - y0)
    # The polyline is within ~_CHORD_TOL * scale of the curve in each coordinate, so the
    # crossing moves at most about that much times (1 + |dtau1/dtau2|).
    band = 8.0 * _CHORD_TOL * scale * (1.0 + np.abs((x1 - x0) / (y1 - y0)))
    band[at_turn > 0] = -1.0  # keep the polyline's crossing next to a turning point
    xc = _exact_crossing(traced, src.astype(np.int64), om0 + frac * (om1 - om0), x0 + frac * (x1 - x0), yy, band)
    turn = w == 0
    if np.any(turn):
        w = w.copy()
        w[turn] = weight[turn] * _crossing_tendency(
            traced, src[turn].astype(np.int64), (om0 + frac * (om1 - om0))[turn], xc[turn], yy[turn]
        )
    keep = xc > 0.0
    yi, xc, w = yi[keep], xc[keep], w[keep]
    # Sort crossings by (line, tau1) with one composite key; queries search the same key.
    width = 2.0 * (max(float(xc.max(initial=0.0)), float(x.max())) + 1.0)
    key = yi * width + xc
    order = np.argsort(key, kind="stable")
    key = key[order]
    cum = np.concatenate([[0.0], np.cumsum(w[order])])
    first = np.searchsorted(key, inv * width, "left")
    upto = np.searchsorted(key, inv * width + x, "left")
    return np.rint(cum[upto] - cum[first]).astype(np.int64)


def _crossing_tendency(
    traced: tuple[TwoDelayQuasiPolynomial, ...], src: NDArray[np.int64], omega: NDArray[np.float64],
    tau1: NDArray[np.float64], tau2: NDArray[np.float64],
) -> NDArray[np.int64]:
    """RT1 at crossing points (for segments whose ends disagree)."""
    out = np.zeros(src.shape, np.int64)
    for k in np.unique(src):
        sel = src == k
        out[sel] = _tendency(traced[int(k)], omega[sel], tau1[sel], tau2[sel])[0]
    return out


def _exact_crossing(
    traced: tuple[TwoDelayQuasiPolynomial, ...], src: NDArray[np.int64], omega: NDArray[np.float64],
    tau1: NDArray[np.float64], tau2: NDArray[np.float64], max_move: NDArray[np.float64],
) -> NDArray[np.float64]:
    """tau1 where the curve meets tau2 = const exactly: Newton on q(j omega; tau1, tau2) = 0.

    Starts from the polyline's interpolation; where Newton does not converge,
    or moves further than ``max_move`` (it would be another crossing), the
    interpolated value is kept.
    """
    out = tau1.copy()
    for k in np.unique(src):
        sel = src == k
        qp = traced[int(k)]
        om, t1, t2 = omega[sel].copy(), tau1[sel].copy(), tau2[sel]
        for _ in range(8):
            s = 1j * om
            f = np.zeros(s.shape, complex)
            fs = np.zeros(s.shape, complex)
            f1 = np.zeros(s.shape, complex)
            scale = np.zeros(s.shape)
            for c, a, b in qp.terms():
                h = a * t1 + b * t2
                e = np.exp(-h * s)
                g = _horner(s, c)
                f += g * e
                fs += (_horner(s, _deriv(c)) - h * g) * e
                f1 -= a * s * g * e
                scale += np.abs(g)
            # Unknowns (omega, tau1): dq/domega = j dq/ds.
            fo = 1j * fs
            det = fo.real * f1.imag - f1.real * fo.imag
            with np.errstate(divide="ignore", invalid="ignore"):
                d_om = (f.real * f1.imag - f1.real * f.imag) / det
                d_t1 = (fo.real * f.imag - f.real * fo.imag) / det
            ok = np.isfinite(d_om) & np.isfinite(d_t1)
            om = np.where(ok, om - d_om, om)
            t1 = np.where(ok, t1 - d_t1, t1)
        s = 1j * om
        res = np.abs(sum(_horner(s, c) * np.exp(-(a * t1 + b * t2) * s) for c, a, b in qp.terms()))
        good = (res <= 1e-10 * np.maximum(scale, 1e-300)) & (np.abs(t1 - tau1[sel]) <= max_move[sel])
        out[sel] = np.where(good, t1, tau1[sel])
    return out


def _axis_sum(axis: tuple[NDArray[np.float64], NDArray[np.float64]], t: NDArray[np.float64]) -> NDArray[np.int64]:
    """Sum of the NU changes of the axis crossings strictly below t (crossings sorted)."""
    where, delta = axis
    if where.size == 0:
        return np.zeros(t.shape, np.int64)
    cum = np.concatenate([[0], np.cumsum(delta)])
    return cum[np.searchsorted(where, t, "left")].astype(np.int64)


def _second_derivative_at_zero(qp: TwoDelayQuasiPolynomial, t1: NDArray, t2: NDArray) -> NDArray[np.float64]:
    """q''(0) at the given delays (real qp)."""
    out = np.zeros(np.broadcast(t1, t2).shape)
    for c, a, b in qp.terms():
        h = a * t1 + b * t2
        g0 = c[0].real
        g1 = c[1].real if c.size > 1 else 0.0
        g2 = 2.0 * c[2].real if c.size > 2 else 0.0
        out = out + g2 - 2.0 * h * g1 + h * h * g0
    return out


def _zero_line_count(line: _ZeroLine, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.int64]:
    """NU change from the real root that passes through s = 0 on the line q'(0) = 0."""
    with np.errstate(all="ignore"):  # t* is inf/nan where a path runs parallel to the line
        return _zero_line_count_raw(line, x, y)


def _zero_line_count_raw(line: _ZeroLine, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.int64]:
    tol = 1e-12 * max(1.0, abs(line.c0), abs(line.c1), abs(line.c2))
    out = np.zeros(x.size, np.int64)

    def after_positive(px: NDArray, py: NDArray, slope: NDArray) -> NDArray[np.bool_]:
        # Just past the line q'(0) has the sign of ``slope``; the small root is -2 q'(0)/q''(0).
        q2 = _second_derivative_at_zero(line.qp, px, py)
        return (-slope / np.where(q2 == 0.0, np.nan, q2)) > 0.0

    # Path 1: origin -> (0, y) (or -> (x, 0) when y = 0).
    along1 = y == 0.0
    length = np.where(along1, x, y)
    slope1 = np.where(along1, line.c1, line.c2) * length
    if abs(line.c0) <= tol:
        on = np.abs(slope1) > tol
        pos = after_positive(np.zeros_like(x), np.zeros_like(y), slope1)
        out += np.where(on & pos, line.weight, 0)
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            t_star = -line.c0 / slope1
        hit = (t_star > 0) & (t_star < 1)
        px = np.where(along1, t_star * x, 0.0)
        py = np.where(along1, 0.0, t_star * y)
        pos = after_positive(np.nan_to_num(px), np.nan_to_num(py), slope1)
        out += np.where(hit, np.where(pos, line.weight, -line.weight), 0)
    # Path 2: (0, y) -> (x, y).
    L0 = line.c0 + line.c2 * y
    slope2 = line.c1 * x
    with np.errstate(divide="ignore", invalid="ignore"):
        t_star = -L0 / slope2
    started_on = (np.abs(L0) <= tol) & (np.abs(slope2) > tol) & ~along1
    came_along = abs(line.c2) <= tol  # then path 1 ran on the line: nothing counted before
    pos = after_positive(np.nan_to_num(t_star * x), y, slope2)
    if came_along:
        out += np.where(started_on & pos, line.weight, 0)
    else:
        out += np.where(started_on, np.where(pos, line.weight, -line.weight), 0)
    hit = (t_star > 0) & (t_star < 1) & ~started_on & ~along1 & (np.abs(slope2) > tol)
    out += np.where(hit, np.where(pos, line.weight, -line.weight), 0)
    return out


# ===================================================================== assembling a map
@dataclass(frozen=True)
class _Part:
    """One qp traced for omega > 0 with its NU weight per unit RT."""

    qp: TwoDelayQuasiPolynomial
    weight: int
    factor: int


def _conjugate(qp: TwoDelayQuasiPolynomial) -> TwoDelayQuasiPolynomial:
    """conj(q(conj s)): its omega > 0 crossings are the omega < 0 crossings of q."""
    return TwoDelayQuasiPolynomial(*(np.conj(c) for c in qp.coefficients))


def _is_three_term(qp: TwoDelayQuasiPolynomial) -> bool:
    return qp.g4.size == 0 and qp.g5.size == 0 and qp.g6.size == 0


def _part_curves(part: _Part, window: tuple[float, float], source: int) -> list[CrossingCurve]:
    qp = part.qp
    has1 = any(c.size for c, a, _ in qp.terms() if a)
    has2 = any(c.size for c, _, b in qp.terms() if b)
    if not has1 and not has2:
        return []
    if not has1 or not has2:
        return _line_curves(part, window, source, vertical=has1)
    if _is_three_term(qp):
        paths = _three_term_paths(qp, window)
    else:
        paths = _general_paths(qp, window)
    out: list[CrossingCurve] = []
    for p in paths:
        out.extend(_embed(p, qp, window, part.weight, source, part.factor))
    return out


def _line_curves(part: _Part, window: tuple[float, float], source: int, *, vertical: bool) -> list[CrossingCurve]:
    """A qp in one delay only: its crossings are straight lines across the window."""
    qp = part.qp
    if vertical:
        h0, h1, h2 = qp.g1, qp.g2, qp.g4
    else:
        h0, h1, h2 = qp.g1, qp.g3, qp.g5
    omegas, thetas = _single_delay_roots(h0, h1, h2)
    tmax, other = (window[0], window[1]) if vertical else (window[1], window[0])
    out = []
    for om, th in zip(omegas, thetas, strict=True):
        for i in range(int(np.floor(tmax * om / TWO_PI)) + 1):
            tau = (th + TWO_PI * i) / om
            if tau <= 0 or tau > tmax:
                continue
            a = np.array([tau, tau])
            b = np.array([-0.02 * other, other * 1.02])
            t1, t2 = (a, b) if vertical else (b, a)
            w = np.array([om, om])
            rt1, rt2 = _tendency(qp, w, t1, t2)
            out.append(CrossingCurve(t1, t2, w, rt1, rt2, "kernel" if i == 0 else "offspring",
                                     (i, 0) if vertical else (0, i), part.weight, source, part.factor))
    return out


def _axis_crossings(parts: list[_Part], window: tuple[float, float], *, axis: int) -> tuple[NDArray, NDArray]:
    """Crossings on the tau1 = 0 axis (axis=2: along tau2) or tau2 = 0 axis (axis=1)."""
    where, delta = [], []
    tmax = window[axis - 1]
    for part in parts:
        g = part.qp.coefficients
        add = _padd
        if axis == 2:   # tau1 = 0: z1 = 1
            h0, h1, h2 = add(add(g[0], g[1]), g[3]), add(g[2], g[5]), g[4]
        else:           # tau2 = 0: z2 = 1
            h0, h1, h2 = add(add(g[0], g[2]), g[4]), add(g[1], g[5]), g[3]
        h0, h1, h2 = (np.trim_zeros(np.asarray(h, complex), "b") for h in (h0, h1, h2))
        omegas, thetas = _single_delay_roots(h0, h1, h2)
        for om, th in zip(omegas, thetas, strict=True):
            for i in range(int(np.floor(tmax * om / TWO_PI)) + 2):
                tau = (th + TWO_PI * i) / om
                if tau <= 1e-12 * tmax or tau > tmax:
                    continue
                t1, t2 = (np.array([0.0]), np.array([tau])) if axis == 2 else (np.array([tau]), np.array([0.0]))
                rt1, rt2 = _tendency(part.qp, np.array([om]), t1, t2)
                rt = rt2 if axis == 2 else rt1
                where.append(tau)
                delta.append(part.weight * int(rt[0]))
    order = np.argsort(where)
    return np.asarray(where, float)[order], np.asarray(delta, np.int64)[order]


def _padd(a: NDArray[np.complex128], b: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Sum of two coefficient arrays of any lengths (empty = zero polynomial)."""
    out = np.zeros(max(a.size, b.size), complex)
    out[: a.size] += a
    out[: b.size] += b
    return out


def _origin_counts(qp: TwoDelayQuasiPolynomial, weight: int) -> tuple[int, int, _ZeroLine | None]:
    """NU just off the origin along tau2 and along tau1, and the zero line if s = 0 is a root."""
    p = qp.delay_free()
    scale = np.max(np.abs(p))
    m0 = 0
    while m0 < p.size and abs(p[m0]) <= 1e-12 * scale:
        m0 += 1
    rest = p[m0:]
    nz = np.flatnonzero(np.abs(rest) > 0)
    rest = rest[: nz[-1] + 1]
    roots = np.roots(rest[::-1]) if rest.size > 1 else np.zeros(0, complex)
    tol = 1e-9 * np.maximum(1.0, np.abs(roots))
    base = int(np.sum(roots.real > tol))
    imag = roots[np.abs(roots.real) <= tol]
    start2 = start1 = base
    if imag.size:
        ds = []
        for k in (1, 2):
            num = qp.delay_derivative(imag, 0.0, 0.0, delay=k)
            ds.append((-num / qp.derivative(imag, 0.0, 0.0)).real)
        start1 += int(np.sum(ds[0] > 0))
        start2 += int(np.sum(ds[1] > 0))
    line = None
    if m0 >= 1 and qp.is_real:
        c0 = float(sum(c[1].real for c, _, _ in qp.terms() if c.size > 1))
        c1 = float(-sum(a * c[0].real for c, a, _ in qp.terms()))
        c2 = float(-sum(b * c[0].real for c, _, b in qp.terms()))
        line = _ZeroLine(c0, c1, c2, qp, weight)
    return weight * start1, weight * start2, line


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
    for source, part in enumerate(parts):
        curves.extend(_part_curves(part, window, source))
    return StabilityMap(
        curves=tuple(curves), tau1_max=tau1_max, tau2_max=tau2_max, delay_free_count=start2,
        traced=tuple(p.qp for p in parts),
        _start1=start1,
        _axis2=_axis_crossings(parts, window, axis=2),
        _axis1=_axis_crossings(parts, window, axis=1),
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
def crossing_map(qp: TwoDelayQuasiPolynomial, tau1_max: float, tau2_max: float) -> StabilityMap:
    """The CTCR stability map of one retarded quasi-polynomial of eq. genfactor.

    Parameters
    ----------
    qp
        Any retarded :class:`~delayform.characteristic.TwoDelayQuasiPolynomial`,
        real or complex coefficients.
    tau1_max, tau2_max
        The window [0, tau1_max] x [0, tau2_max]; positive.

    Returns
    -------
    StabilityMap
        Kernel and offspring curves with omega and root tendencies, and NU.

    Raises
    ------
    NeutralQuasiPolynomialError
        When a delayed term has the degree of g1.
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
    if not isinstance(qp, TwoDelayQuasiPolynomial):
        raise QuasiPolynomialError(f"qp must be a TwoDelayQuasiPolynomial, got {type(qp).__name__}")
    qp.require_retarded()
    t1, t2 = _check_window(tau1_max, tau2_max)
    if qp.is_real:
        parts = [_Part(qp, 2, 0)]
    else:
        parts = [_Part(qp, 1, 0), _Part(_conjugate(qp), 1, 1)]
    _guard_window([p.qp for p in parts], t1, t2)
    return _assemble([(qp, 1, parts)], t1, t2)


def stability_map(topology: Topology, P: float, D: float, tau1_max: float, tau2_max: float) -> StabilityMap:
    """The exact CTCR stability map of the formation protocol (eq. protocolss).

    Every factor of eq. factorized is traced: a real eigenvalue lam gives the
    real three-term factor ``s^2 + D s + P - lam (D s z2 + P z1)``; a conjugate
    pair gives the fourth-order factor, whose imaginary roots are those of the
    three-term factors of lam and conj(lam). NU sums the factors weighted by
    multiplicity; the centroid root s = 0 is not counted (Lemma 2).

    Parameters
    ----------
    topology
        Communication topology; must have a spanning tree (Lemma 3).
    P, D
        Positive gains of eq. protocol.
    tau1_max, tau2_max
        The window [0, tau1_max] x [0, tau2_max].

    Returns
    -------
    StabilityMap

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
    sources = []
    for idx, f in enumerate(factors(topology, P, D)):
        mult = f.multiplicity
        if not f.group.is_complex_pair:
            parts = [_Part(f.quasi_polynomial, 2 * mult, idx)]
        else:
            parts = [_Part(_lam_factor(f.P, f.D, lam), 2 * mult, idx) for lam in (f.lam, np.conj(f.lam))]
        sources.append((f.quasi_polynomial, mult, parts))
    _guard_window([p.qp for _, _, parts in sources for p in parts], t1, t2)
    return _assemble(sources, t1, t2)


def _lam_factor(P: float, D: float, lam: complex) -> TwoDelayQuasiPolynomial:
    """``s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s})``, a (complex) three-term qp."""
    return TwoDelayQuasiPolynomial([P, D, 1.0], [-lam * P], [0.0, -lam * D])
