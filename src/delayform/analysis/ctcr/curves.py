"""CTCR curves in the delay plane: kernel and offspring images of phase paths (paper, eq. 6).

A traced quasi-polynomial (:class:`_Part`) gives phase paths
(:mod:`delayform.analysis.ctcr.phase`); every image ``tau = (theta + 2 pi i) / omega``
that meets the window becomes a :class:`CrossingCurve` with its root
tendencies; the axes' crossings and the counts at the origin complete the data
the CTCR count needs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.ctcr.phase import (
    TWO_PI,
    _general_paths,
    _single_delay_roots,
    _three_term_paths,
    _PhasePath,
)
from delayform.analysis.ctcr.degenerate import crossing_changes, vertex_tendencies
from delayform.analysis.ctcr.factored import factor_direction
from delayform.analysis.ctcr.general import TermsQP, collapse, unit_roots_single
from delayform.characteristic import TwoDelayQuasiPolynomial
from delayform.errors import QuasiPolynomialError

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
        Root tendencies w.r.t. tau1 and tau2 at each point (Definition "Root Tendency"),
        -1, 0 or +1 (stored as int8: large teams have millions of curve points).
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
    rt1: NDArray[np.int8]
    rt2: NDArray[np.int8]
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



# ===================================================================== root tendency
def _tendency(
    qp: TwoDelayQuasiPolynomial, omega: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(RT1, RT2) = sgn Re ds/dtau_k at s = j omega (Definition "Root Tendency").

    Unchecked delays, because curve polylines may run a little past the axes.
    0 at a multiple root: its crossing is decided where the count meets it
    (:mod:`delayform.analysis.ctcr.degenerate`).
    """
    return vertex_tendencies(qp, omega, t1, t2)



# ===================================================================== embedding in the plane
def _embed(
    path: _PhasePath, qp: TwoDelayQuasiPolynomial, window: tuple[float, float], weight: int, source: int,
    factor: int,
) -> list[CrossingCurve]:
    """All kernel/offspring images (paper, eq. 6) of a phase path that meet the window."""
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
        # One piece per shift (i, k) of the paper's eq. 6; the last vertex is shared with the next piece.
        cut = np.flatnonzero((i1[run][1:] != i1[run][:-1]) | (i2[run][1:] != i2[run][:-1])) + 1
        bounds = np.concatenate([[0], cut, [run.size]])
        for a, b in zip(bounds[:-1], bounds[1:], strict=True):
            sel = run[a : min(b + 1, run.size)]  # share the vertex with the next piece
            if sel.size < 2:
                continue
            out.append(
                CrossingCurve(
                    tau1=tau1[sel], tau2=tau2[sel], omega=om[sel], rt1=rts[0][sel].astype(np.int8), rt2=rts[1][sel].astype(np.int8),
                    kind="kernel" if kinds[a] else "offspring",
                    shift=(int(i1[sel[0]]), int(i2[sel[0]])), weight=weight, source=source,
                    factor=factor,
                )
            )
    return out


# ===================================================================== assembling a map
@dataclass(frozen=True)
class _Part:
    """One qp traced for omega > 0 with its NU weight per unit RT.

    ``lam`` is set when qp is the three-term factor of the paper's eq. 3 of that
    eigenvalue of C (``s^2 + D s + P - lam (P z1 + D s z2)``): all such parts
    are traced together by :mod:`delayform.analysis.ctcr.family_curves`.
    """

    qp: TwoDelayQuasiPolynomial
    weight: int
    factor: int
    lam: complex | None = None


def _conjugate(qp: TwoDelayQuasiPolynomial) -> TwoDelayQuasiPolynomial:
    """conj(q(conj s)): its omega > 0 crossings are the omega < 0 crossings of q."""
    if isinstance(qp, TermsQP):
        return qp.conjugate()  # type: ignore[return-value]
    return TwoDelayQuasiPolynomial(*(np.conj(c) for c in qp.coefficients))


def _is_three_term(qp: TwoDelayQuasiPolynomial) -> bool:
    if isinstance(qp, TermsQP):
        return False
    return qp.g4.size == 0 and qp.g5.size == 0 and qp.g6.size == 0


def _part_curves(part: _Part, window: tuple[float, float], source: int) -> list[CrossingCurve]:
    qp = part.qp
    if not any(c.size and (a or b) for c, a, b in qp.terms()):
        return []
    direction = line_direction(qp)
    if direction is not None:
        return _line_curves(part, window, source, direction)
    if _is_three_term(qp):
        paths = _three_term_paths(qp, window)
    else:
        # crossing_map splits such factors off first; a qp reaching here with one (built by hand)
        # would have whole lines of crossings the sweep cannot see: refused, never mapped without them
        factor = factor_direction({(a, b): c for c, a, b in qp.terms()})
        if factor is not None:
            a, b = factor
            raise QuasiPolynomialError(
                f"the quasi-polynomial has a factor in z1^{a} z2^{b} alone (a function of {a} tau1 + {b} tau2); "
                "its crossings are whole lines the two-delay trace cannot follow: split it off first "
                "(delayform.analysis.ctcr.factored.split_monomial_factors) and map the factors (NU adds up)"
            )
        paths = _general_paths(qp, window)
    out: list[CrossingCurve] = []
    for p in paths:
        out.extend(_embed(p, qp, window, part.weight, source, part.factor))
    return out


def line_direction(qp: TwoDelayQuasiPolynomial) -> tuple[int, int] | None:
    """The primitive (a, b) of which every delayed term's (k1, k2) is a multiple, or None.

    Then q depends on the delays only through ``T = a tau1 + b tau2``: it is
    ``sum_j h_j(s) w^j`` with ``w = z1^a z2^b = e^{-T s}``, a one-delay qp in T,
    and its crossing set is the family of straight lines ``a tau1 + b tau2 = T_i``.
    (1, 0): tau1 alone; (0, 1): tau2 alone; (1, 1): tau1 + tau2; (1, 2), (2, 3), ...
    The two-delay sweep cannot trace it: at a crossing frequency every point of
    a line ``a theta1 + b theta2 = const`` of the torus solves q, so its
    eliminant vanishes identically there, and at every other frequency there is
    no solution at all.
    """
    keys = {(a, b) for c, a, b in qp.terms() if (a or b) and c.size and np.any(c != 0.0)}
    if not keys:
        return None
    a0, b0 = next(iter(keys))
    a, b = a0 // int(np.gcd(a0, b0)), b0 // int(np.gcd(a0, b0))
    if all(k1 * b == k2 * a for k1, k2 in keys):
        return a, b
    return None


def _line_polynomials(qp: TwoDelayQuasiPolynomial, direction: tuple[int, int]) -> list[NDArray[np.complex128]]:
    """h_j(s) of ``q = sum_j h_j(s) w^j``, ``w = z1^a z2^b`` (:func:`line_direction`)."""
    a, b = direction
    h: dict[int, NDArray[np.complex128]] = {}
    for c, k1, k2 in qp.terms():
        j = k1 // a if a else k2 // b
        acc = np.zeros(max(h.get(j, np.zeros(0)).size, c.size), complex)
        acc[: h.get(j, np.zeros(0)).size] += h.get(j, np.zeros(0, complex))
        acc[: c.size] += c
        h[j] = acc
    return [np.trim_zeros(h.get(j, np.zeros(0, complex)), "b") for j in range(max(h) + 1)]


def _line_curves(
    part: _Part, window: tuple[float, float], source: int, direction: tuple[int, int]
) -> list[CrossingCurve]:
    """A qp in ``T = a tau1 + b tau2`` alone: its crossings are the straight lines ``a tau1 + b tau2 = T_i``.

    ``T_i = (theta + 2 pi i) / omega`` for the exact one-delay crossings (omega,
    theta) of ``sum_j h_j(s) w^j`` (:func:`_one_delay_roots`); each line is drawn
    across the window and 2 % beyond it, with the root tendencies of q itself
    (``ds/dtau1 = a ds/dT``, ``ds/dtau2 = b ds/dT``: the same sign along the line).
    """
    qp = part.qp
    a, b = direction
    omegas, thetas = _one_delay_roots(_line_polynomials(qp, direction))
    t1max, t2max = window
    lo1, hi1, lo2, hi2 = -0.02 * t1max, 1.02 * t1max, -0.02 * t2max, 1.02 * t2max
    tmax = a * t1max + b * t2max
    out = []
    for om, th in zip(omegas, thetas, strict=True):
        for i in range(int(np.floor(tmax * om / TWO_PI)) + 1):
            T = (th + TWO_PI * i) / om
            if T <= 0 or T > tmax:
                continue
            ends = _clip_line(a, b, T, (lo1, hi1, lo2, hi2))
            if ends is None:
                continue
            t1, t2 = ends
            w = np.array([om, om])
            rt1, rt2 = _tendency(qp, w, t1, t2)
            shift = (i, 0) if a else (0, i)
            out.append(CrossingCurve(t1, t2, w, rt1.astype(np.int8), rt2.astype(np.int8),
                                     "kernel" if i == 0 else "offspring", shift, part.weight, source, part.factor))
    return out


def _clip_line(a: int, b: int, T: float, box: tuple[float, float, float, float]) -> tuple[NDArray, NDArray] | None:
    """The two ends of the line ``a tau1 + b tau2 = T`` inside the box (lo1, hi1, lo2, hi2), or None."""
    lo1, hi1, lo2, hi2 = box
    if b == 0:
        return (np.array([T / a, T / a]), np.array([lo2, hi2])) if lo1 <= T / a <= hi1 else None
    if a == 0:
        return (np.array([lo1, hi1]), np.array([T / b, T / b])) if lo2 <= T / b <= hi2 else None
    # tau2 = (T - a tau1) / b decreases along tau1: clip tau1 to where tau2 lies in [lo2, hi2]
    x0 = max(lo1, (T - b * hi2) / a)
    x1 = min(hi1, (T - b * lo2) / a)
    if not x0 < x1:
        return None
    x = np.array([x0, x1])
    return x, (T - a * x) / b


def _axis_crossings(parts: list[_Part], window: tuple[float, float], *, axis: int) -> tuple[NDArray, NDArray]:
    """Crossings on the tau1 = 0 axis (axis=2: along tau2) or tau2 = 0 axis (axis=1)."""
    where, delta = [], []
    tmax = window[axis - 1]
    for part in parts:
        # tau1 = 0 (axis 2): z1 = 1, a problem in z2 alone; tau2 = 0 (axis 1): in z1 alone
        omegas, thetas = _unit_roots(part.qp, axis)
        near = _origin_axis_roots(part.qp, axis)
        for om, th in zip(omegas, thetas, strict=True):
            for i in range(int(np.floor(tmax * om / TWO_PI)) + 2):
                tau = (th + TWO_PI * i) / om
                if tau <= 1e-12 * tmax or tau > tmax:
                    continue
                if any(abs(om - w0) <= width and tau <= reach for w0, reach, width in near):
                    continue  # the origin count already took this root's departure
                t1, t2 = (np.array([0.0]), np.array([tau])) if axis == 2 else (np.array([tau]), np.array([0.0]))
                rt = crossing_changes(part.qp, np.array([om]), t1, t2, delay=axis)
                where.append(tau)
                delta.append(part.weight * int(rt[0]))
    order = np.argsort(where)
    return np.asarray(where, float)[order], np.asarray(delta, np.int64)[order]


#: delay-free roots this close to the axis (relative to max(1, |s|)) count as on it at the origin
_ORIGIN_TOL = 1e-9


def _delay_free_roots(qp: TwoDelayQuasiPolynomial) -> tuple[NDArray[np.complex128], int]:
    """Roots of the delay-free polynomial other than s = 0, and the multiplicity m0 of s = 0."""
    p = qp.delay_free()
    scale = np.max(np.abs(p))
    m0 = 0
    while m0 < p.size and abs(p[m0]) <= 1e-12 * scale:
        m0 += 1
    rest = p[m0:]
    nz = np.flatnonzero(np.abs(rest) > 0)
    rest = rest[: nz[-1] + 1]
    return (np.roots(rest[::-1]) if rest.size > 1 else np.zeros(0, complex)), m0


#: a delay-free root further than this from the axis (relative to max(1, |s|)) is off it: rounding
#: of the roots of a well-conditioned polynomial is ~1e-16
_OFF_AXIS = 1e-13


def _origin_departures(qp: TwoDelayQuasiPolynomial, delay: int) -> list[tuple[complex, complex, bool]]:
    """(root, ds/dtau, counted) of each delay-free root within :data:`_ORIGIN_TOL` of the axis.

    A root on the axis to rounding (:data:`_OFF_AXIS`) is counted off the origin along
    ``tau_delay`` by where it goes, the sign of ``Re ds/dtau`` (``counted``: True when right).
    A root measurably off the axis is counted by the side it is on, and its crossing of the
    axis further on is an event of its own (found by the map property: a pair 1.15e-11 right
    of the axis, tangent to it, crossed the tau1 = 0 axis at tau2 = 5.7e-6 and was counted
    both at the origin and there).
    """
    roots, _ = _delay_free_roots(qp)
    near = roots[np.abs(roots.real) <= _ORIGIN_TOL * np.maximum(1.0, np.abs(roots))]
    if near.size == 0:
        return []
    ds = -qp.delay_derivative(near, 0.0, 0.0, delay=delay) / qp.derivative(near, 0.0, 0.0)
    out = []
    for r, d in zip(near, ds, strict=True):
        off = abs(r.real) > _OFF_AXIS * max(1.0, abs(r))
        out.append((complex(r), complex(d), bool(r.real > 0.0) if off else bool(d.real > 0.0)))
    return out


def _origin_axis_roots(qp: TwoDelayQuasiPolynomial, delay: int) -> list[tuple[float, float, float]]:
    """(omega0, reach, width) of the roots ``j omega0`` (omega0 > 0) counted at the origin by their departure.

    :func:`_origin_counts` counts such a root (on the axis to rounding) by where it goes as the
    delay grows, so its own crossing of the axis a little further on is not a second event:
    ``reach`` is the delay by which, at ``|Re ds/dtau|``, it leaves the rounding band, and
    ``width`` how far its frequency moves meanwhile (a crossing of the axis at tau <= reach
    within width of omega0 is that root's). A root tangent to the axis, or counted by its side,
    is not listed.
    """
    out = []
    for r, d, _ in _origin_departures(qp, delay):
        if r.imag <= 0.0 or abs(r.real) > _OFF_AXIS * max(1.0, abs(r)) or not abs(d.real) > 1e-9 * abs(d):
            continue
        reach = 2.0 * _OFF_AXIS * max(1.0, abs(r)) / abs(d.real)
        out.append((r.imag, reach, 2.0 * abs(d) * reach + 1e-6 * max(1.0, r.imag)))
    return out


def _unit_roots(qp: TwoDelayQuasiPolynomial, delay: int) -> tuple[NDArray, NDArray]:
    """(omega, theta) of the single-delay problem in z_delay with the other delay zero.

    Up to z^2 (every the paper's eq. 5 qp) the closed resultant of
    :func:`~delayform.analysis.ctcr.phase._single_delay_roots`; higher powers
    (commensurate terms) the frequency-eliminating resultant in z of
    :func:`~delayform.analysis.ctcr.general.unit_roots_single`.
    """
    return _one_delay_roots(collapse(qp, delay))


def _one_delay_roots(h: list[NDArray[np.complex128]]) -> tuple[NDArray, NDArray]:
    """(omega, theta) of ``sum_j h_j(j omega) e^{-j j theta} = 0`` (see :func:`_unit_roots`).

    A problem in ``z^g`` alone (``h_j = 0`` unless g divides j; e.g. ``h0 + h2 z^2``) is solved in
    ``w = z^g`` and each solution rotated g ways: eliminated in z, its unit-circle condition is the
    g-th power of the one in w, and a near-double root of that (a pair tangent to the axis, grazing
    it at a tiny delay) became a near-4-fold root that rounding spread off the real line, so the
    crossing was lost (found by the map property: a pair 1e-11 right of the axis at zero delay).
    """
    powers = [j for j, c in enumerate(h) if j and c.size and np.any(c != 0.0)]
    g = int(np.gcd.reduce(powers)) if powers else 1
    if g > 1:
        om, th = _one_delay_roots(h[::g])
        k = np.arange(g)
        return np.repeat(om, g), np.mod((th[:, None] + TWO_PI * k[None, :]) / g, TWO_PI).ravel()
    if len(h) <= 3:
        h = h + [np.zeros(0, complex)] * (3 - len(h))
        return _single_delay_roots(h[0], h[1], h[2])
    return unit_roots_single(h)


def _origin_counts(qp: TwoDelayQuasiPolynomial, weight: int) -> tuple[int, int, _ZeroLine | None]:
    """NU just off the origin along tau2 and along tau1, and the zero line if s = 0 is a root."""
    roots, m0 = _delay_free_roots(qp)
    base = int(np.sum(roots.real > _ORIGIN_TOL * np.maximum(1.0, np.abs(roots))))
    start1 = base + sum(counted for _, _, counted in _origin_departures(qp, 1))
    start2 = base + sum(counted for _, _, counted in _origin_departures(qp, 2))
    line = None
    if m0 >= 1 and qp.is_real:
        c0 = float(sum(c[1].real for c, _, _ in qp.terms() if c.size > 1))
        c1 = float(-sum(a * c[0].real for c, a, _ in qp.terms()))
        c2 = float(-sum(b * c[0].real for c, _, b in qp.terms()))
        line = _ZeroLine(c0, c1, c2, qp, weight)
    return weight * start1, weight * start2, line


