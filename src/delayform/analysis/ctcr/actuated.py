"""Exact CTCR stability maps in (tau1, tau2) at a given actuation delay tau_a.

Every factor of the paper's eq. 3 with an actuation delay is (docs/theory.md, "Actuation delay")::

    q(s) = s^2 + (D s + P) e^{-tau_a s} - lam (D s e^{-(tau2 + tau_a) s} + P e^{-(tau1 + tau_a) s})

On s = j omega the factor e^{-j omega tau_a} is a known unit complex number;
multiplying by its inverse leaves the three-term form of the paper's factors,

    g1(omega) + g2 e^{-j theta1} + g3 e^{-j theta2} = 0,
    g1 = -omega^2 e^{j omega tau_a} + P + j D omega,  g2 = -lam P,  g3 = -lam j D omega,

so the law-of-cosines closed form of :mod:`delayform.analysis.ctcr.stability_map`
still gives (theta1, theta2) at every crossing frequency, exactly. What
changes is that |g1|^2 is no longer a polynomial in omega: the ends of the
crossing-frequency intervals (where the triangle degenerates,
``|g1| = |g2| +- |g3|``) and the crossings of the tau1 = 0 axis
(``|g1 + g2| = |g3|``) are the zeros of functions
``e(omega) = poly(omega) - 2 omega^2 (C cos omega tau_a + (S0 + S1 omega) sin omega tau_a)``.
They are isolated with a certificate: a cell [u, v] is free of zeros when
``|e(mid)| > L (v - u) / 2`` with L a closed-form bound of |e'| on the cell;
cells that cannot be excluded are bisected down to 1e-13 relative, and a
sign change there is a zero (a cell without sign change is a tangency,
where the crossing set only touches: RT = 0, nothing changes).

NU(tau1, tau2) is the CTCR count along (0, 0) -> (0, tau2) -> (tau1, tau2):
the certified count (argument principle, :func:`count_roots_right_of`) of
every factor at (0, 0, tau_a) -- the centroid factor is exactly s^2 there --,
plus w RT2 for each crossing of the tau1 = 0 axis below tau2, plus w RT1 for
each curve point met by the horizontal segment (found on the curve sampled
in the smooth parameter ``omega = a + (b - a)(1 - cos phi)/2``, then solved
exactly by bisection on the closed form). w = 2 x multiplicity (a real lam:
conjugate pairs of crossings; a complex pair: lam and conj(lam) each traced
for omega > 0). The centroid factor keeps s = 0 for every delay and, on
tau1 = 0, the drift's double zero; off that axis its second zero moves to
about -P tau1 / (1 + D tau2) < 0 (q'(0) = P tau1 still), so no root
crosses at s = 0 anywhere: NU changes only on the omega > 0 crossings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_delay, check_delay_array, check_gains, validated
from delayform.analysis.ctcr.curves import CrossingCurve
from delayform.analysis.roots.actuated import actuated_factor
from delayform.analysis.roots.single import count_roots_right_of
from delayform.characteristic import factors
from delayform.errors import DelayError, NotConvergedError
from delayform.topology import Topology

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["ActuatedStabilityMap", "actuated_stability_map"]

TWO_PI = 2.0 * math.pi
#: frequencies below this fraction of the bound are not traced (tau = theta / omega loses eps / omega^2)
_OMEGA_FLOOR = 1e-4
_ISOLATION_CELLS = 4096
_MAX_CELLS = 2_000_000


@dataclass(frozen=True)
class _Trig:
    """``e(omega) = poly(omega) - 2 omega^2 (C cos omega ta + (S0 + S1 omega) sin omega ta)``."""

    poly: NDArray[np.float64]  # increasing powers
    C: float
    S0: float
    S1: float
    ta: float

    def __call__(self, w: NDArray[np.float64]) -> NDArray[np.float64]:
        x = w * self.ta
        trig = self.C * np.cos(x) + (self.S0 + self.S1 * w) * np.sin(x)
        return np.polynomial.polynomial.polyval(w, self.poly) - 2.0 * w * w * trig

    def _bounds(self, v: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
        """Bounds on [0, v] of |T|, |T'|, |T''| for T = C cos x + (S0 + S1 w) sin x (|cos|, |sin| <= 1)."""
        c, s0, s1, ta = abs(self.C), abs(self.S0), abs(self.S1), self.ta
        lin = s0 + s1 * v
        return c + lin, c * ta + s1 + lin * ta, c * ta * ta + 2.0 * s1 * ta + lin * ta * ta

    def derivative(self, w: NDArray[np.float64]) -> NDArray[np.float64]:
        """e'(w), exactly."""
        x = w * self.ta
        cos, sin = np.cos(x), np.sin(x)
        lin = self.S0 + self.S1 * w
        T = self.C * cos + lin * sin
        dT = -self.C * self.ta * sin + self.S1 * sin + lin * self.ta * cos
        dp = np.polynomial.polynomial.polyder(self.poly)
        return np.polynomial.polynomial.polyval(w, dp) - 2.0 * (2.0 * w * T + w * w * dT)

    def slope_bound(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """A bound of |e'| on [0, v] (term by term)."""
        dp = np.polynomial.polynomial.polyder(self.poly)
        b0, b1, _ = self._bounds(v)
        return np.polynomial.polynomial.polyval(v, np.abs(dp)) + 2.0 * (2.0 * v * b0 + v * v * b1)

    def curvature_bound(self, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """A bound of |e''| on [0, v] (term by term)."""
        d2 = np.polynomial.polynomial.polyder(self.poly, 2)
        b0, b1, b2 = self._bounds(v)
        return np.polynomial.polynomial.polyval(v, np.abs(d2)) + 2.0 * (2.0 * b0 + 4.0 * v * b1 + v * v * b2)


def _zeros(e: _Trig, lo: float, hi: float) -> NDArray[np.float64]:
    """Every zero of e in (lo, hi) where e changes sign, certified (module docstring)."""
    edges = np.linspace(lo, hi, _ISOLATION_CELLS + 1)
    a, b = edges[:-1], edges[1:]
    tol = 1e-13 * hi
    found: list[NDArray[np.float64]] = []
    total = a.size
    while a.size:
        mid = 0.5 * (a + b)
        h = b - a
        val = np.abs(e(mid))
        # zero-free when |e(mid)| beats a bound of |e - e(mid)| on the cell: first order (|e'| <= L),
        # or second order (|e'(mid)| h / 2 + max|e''| h^2 / 8; flat functions near omega = 0)
        first = val > e.slope_bound(b) * h / 2.0
        second = val > np.abs(e.derivative(mid)) * h / 2.0 + e.curvature_bound(b) * h * h / 8.0
        keep = ~(first | second)
        a, b = a[keep], b[keep]
        small = (b - a) <= tol
        if small.any():
            found.append(0.5 * (a[small] + b[small]))
            a, b = a[~small], b[~small]
        mid = 0.5 * (a + b)
        a, b = np.concatenate([a, mid]), np.concatenate([mid, b])
        total += a.size
        if total > _MAX_CELLS:
            raise NotConvergedError("the crossing frequencies with this actuation delay cannot be isolated")
    if not found:
        return np.zeros(0)
    pts = np.sort(np.concatenate(found))
    # neighbouring tiny cells hold one zero: group them, keep the groups where e changes sign
    groups = np.split(pts, np.flatnonzero(np.diff(pts) > 4 * tol) + 1)
    out = []
    for g in groups:
        left, right = g[0] - 2 * tol, g[-1] + 2 * tol
        if np.sign(e(np.array([left]))[0]) != np.sign(e(np.array([right]))[0]):
            out.append(0.5 * (left + right))
    return np.array(out)


@dataclass(frozen=True)
class _Part:
    """One traced three-term factor (lam), with its weight and factor index."""

    lam: complex
    weight: int
    factor: int
    P: float
    D: float
    ta: float

    def g(self, w: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
        g1 = -(w**2) * np.exp(1j * w * self.ta) + self.P + 1j * self.D * w
        return g1, np.full(w.shape, -self.lam * self.P), -self.lam * 1j * self.D * w

    def bound(self) -> float:
        """|s| of every root with Re s >= 0: |s|^2 <= (1 + |lam|)(D |s| + P)."""
        k = 1.0 + abs(self.lam)
        return 0.5 * (k * self.D + math.sqrt((k * self.D) ** 2 + 4.0 * k * self.P))

    def tendency(self, w: NDArray, t1: NDArray, t2: NDArray, wrt: int) -> NDArray[np.int64]:
        """sign Re(ds/dtau_wrt) at s = j w: -(dq/dtau) / (dq/ds)."""
        s = 1j * w
        P, D, lam, ta = self.P, self.D, self.lam, self.ta
        e0, e1, e2 = np.exp(-ta * s), np.exp(-(t1 + ta) * s), np.exp(-(t2 + ta) * s)
        dqds = 2 * s + D * e0 - ta * (D * s + P) * e0 - lam * (D * e2 - (t2 + ta) * D * s * e2) + lam * P * (t1 + ta) * e1
        dqdt = lam * P * s * e1 if wrt == 1 else lam * D * s * s * e2
        rt = (-dqdt / dqds).real
        scale = np.abs(dqdt / dqds)
        return np.where(np.abs(rt) <= 1e-9 * scale, 0, np.sign(rt)).astype(np.int64)

    def intervals(self) -> list[tuple[float, float, bool, bool]]:
        """Crossing-frequency intervals (a, b, a degenerate, b degenerate) in [floor, bound]."""
        P, D, L, ta = self.P, self.D, abs(self.lam), self.ta
        top = self.bound()
        lo = _OMEGA_FLOOR * top
        base = np.array([P * P, 0.0, D * D, 0.0, 1.0])
        ends = []
        for sign in (1.0, -1.0):  # m - (a +- b)^2 with a = L P, b = L D omega
            poly = base - np.array([(L * P) ** 2, sign * 2 * L * L * P * D, (L * D) ** 2, 0.0, 0.0])
            ends.append(_Trig(poly, P, 0.0, D, ta))
        cuts = np.unique(np.concatenate([[lo, top], *(_zeros(e, lo, top) for e in ends)]))
        out = []
        for a, b in zip(cuts[:-1], cuts[1:], strict=True):
            mid = np.array([0.5 * (a + b)])
            if ends[0](mid)[0] <= 0.0 <= ends[1](mid)[0]:
                out.append((float(a), float(b), a > lo, b < top))
        # merge touching intervals (a tangency zero between two crossing intervals)
        merged: list[tuple[float, float, bool, bool]] = []
        for iv in out:
            if merged and merged[-1][1] == iv[0]:
                merged[-1] = (merged[-1][0], iv[1], merged[-1][2], iv[3])
            else:
                merged.append(iv)
        return merged

    def phases(self, w: NDArray[np.float64], branch: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
        """(theta1, theta2) in [0, 2 pi) on the branch (+1 / -1) of the law of cosines, exact."""
        g1, g2, g3 = self.g(w)
        A = -g1
        a, b, r = np.abs(g2), np.abs(g3), np.abs(A)
        with np.errstate(invalid="ignore", divide="ignore"):
            cos = np.clip((r * r + a * a - b * b) / (2 * r * a), -1.0, 1.0)
        u = a * np.exp(1j * (np.angle(A) + branch * np.arccos(cos)))
        v = A - u
        th1 = np.mod(np.angle(g2) - np.angle(u), TWO_PI)
        th2 = np.mod(np.angle(g3) - np.angle(v), TWO_PI)
        return th1, th2

    def axis_crossings(self, tau2_max: float) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """(tau2, w RT2) of the imaginary roots on the tau1 = 0 axis, 0 < tau2 <= tau2_max."""
        P, D, lam, ta = self.P, self.D, self.lam, self.ta
        beta = (1.0 - lam) * P
        top = self.bound()
        poly = np.array([abs(beta) ** 2, 2 * beta.imag * D, D * D * (1.0 - abs(lam) ** 2), 0.0, 1.0])
        e = _Trig(poly, beta.real, beta.imag, D, ta)
        w = _zeros(e, _OMEGA_FLOOR * top, top)
        if w.size == 0:
            return np.zeros(0), np.zeros(0, np.int64)
        g1, g2, g3 = self.g(w)
        th2 = np.mod(-np.angle(-(g1 + g2) / g3), TWO_PI)
        taus, ws = [], []
        for om, th in zip(w, th2, strict=True):
            k = np.arange(0, int((tau2_max * om - th) / TWO_PI) + 1)
            t = (th + TWO_PI * k) / om
            t = t[(t > 0) & (t <= tau2_max)]
            taus.append(t)
            ws.append(np.full(t.shape, om))
        t2 = np.concatenate(taus)
        om = np.concatenate(ws)
        rt = self.tendency(om, np.zeros_like(om), t2, 2)
        return t2, self.weight * rt


@dataclass(frozen=True)
class _Branch:
    """One smooth branch of crossing points, sampled: omega, unwrapped phases."""

    part: int
    omega: NDArray[np.float64]
    th1: NDArray[np.float64]
    th2: NDArray[np.float64]
    sign: float


def _branches(part: _Part, index: int, window: tuple[float, float]) -> list[_Branch]:
    """The two law-of-cosines branches of every crossing interval, sampled finely enough.

    The parameter phi of ``omega = a + (b - a)(1 - cos phi)/2`` is smooth through
    the degenerate ends; an interval of phi is halved while the midpoint of the
    largest offspring reaching the window lies further than 2e-5 of the window
    from its chord.
    """
    out = []
    scale = np.array(window)
    for a, b, _, _ in part.intervals():
        k = scale * b / TWO_PI + 1.0  # the largest offspring that reaches the window

        def image(phi: NDArray, sgn: float) -> tuple[NDArray, NDArray, NDArray]:
            w = a + (b - a) * (1.0 - np.cos(phi)) / 2.0
            t1, t2 = part.phases(w, np.full(w.shape, sgn))
            return w, t1, t2

        for sgn in (1.0, -1.0):
            phi = np.linspace(0.0, math.pi, 257)
            for _ in range(20):
                w, t1, t2 = image(phi, sgn)
                u1, u2 = np.unwrap(t1), np.unwrap(t2)
                pm = 0.5 * (phi[:-1] + phi[1:])
                wm, s1, s2 = image(pm, sgn)
                s1 = s1 + TWO_PI * np.round((0.5 * (u1[:-1] + u1[1:]) - s1) / TWO_PI)
                s2 = s2 + TWO_PI * np.round((0.5 * (u2[:-1] + u2[1:]) - s2) / TWO_PI)
                dx = ((s1 + TWO_PI * k[0]) / wm - 0.5 * ((u1[:-1] + TWO_PI * k[0]) / w[:-1] + (u1[1:] + TWO_PI * k[0]) / w[1:])) / scale[0]
                dy = ((s2 + TWO_PI * k[1]) / wm - 0.5 * ((u2[:-1] + TWO_PI * k[1]) / w[:-1] + (u2[1:] + TWO_PI * k[1]) / w[1:])) / scale[1]
                bad = np.hypot(dx, dy) > 2e-5
                if not bad.any():
                    break
                phi = np.sort(np.concatenate([phi, pm[bad]]))
            w, t1, t2 = image(phi, sgn)
            out.append(_Branch(index, w, np.unwrap(t1), np.unwrap(t2), sgn))
    return out


def _near(th: NDArray, guess: NDArray) -> NDArray:
    """The value of a phase (mod 2 pi) nearest an unwrapped guess."""
    return th + TWO_PI * np.round((guess - th) / TWO_PI)


@validated()
@dataclass(frozen=True, eq=False)
class ActuatedStabilityMap:
    """The exact CTCR map in [0, tau1_max] x [0, tau2_max] at actuation delay tau_a (module docstring).

    Attributes
    ----------
    curves
        The crossing curves in the window, for drawing (kernel and offspring pieces).
    tau1_max, tau2_max
        The window.
    actuation_delay
        tau_a (s).
    delay_free_count
        NU at tau1 = tau2 = 0 (the certified count; tau_a is still there).
    """

    curves: tuple[CrossingCurve, ...]
    tau1_max: float
    tau2_max: float
    actuation_delay: float
    delay_free_count: int
    _parts: tuple[_Part, ...] = field(repr=False)
    _branches: tuple[_Branch, ...] = field(repr=False)
    _axis: tuple[NDArray[np.float64], NDArray[np.int64]] = field(repr=False)

    def unstable_count(self, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.int64]:
        """NU at delay pairs (broadcasting tau1 against tau2), the centroid's zeros not counted."""
        t1, t2 = check_delay_array("tau1", tau1), check_delay_array("tau2", tau2)
        x, y = np.broadcast_arrays(t1, t2)
        shape = x.shape
        x, y = x.ravel(), y.ravel()
        if np.any(x > self.tau1_max * (1 + 1e-12)) or np.any(y > self.tau2_max * (1 + 1e-12)):
            raise DelayError(f"delays must lie in the map's window [0, {self.tau1_max}] x [0, {self.tau2_max}]")
        where, delta = self._axis
        cum = np.concatenate([[0], np.cumsum(delta)])
        count = self.delay_free_count + cum[np.searchsorted(where, y, "left")]
        uy, inv = np.unique(y, return_inverse=True)
        xs, ws, rows = self._horizontal(uy)
        if xs.size:
            width = 2.0 * (max(float(xs.max()), float(x.max())) + 1.0)
            key = rows * width + xs
            order = np.argsort(key, kind="stable")
            key, csum = key[order], np.concatenate([[0], np.cumsum(ws[order])])
            first = np.searchsorted(key, inv * width, "left")
            upto = np.searchsorted(key, inv * width + x, "left")
            count = count + csum[upto] - csum[first]
        return count.reshape(shape).astype(np.int64)

    def is_stable(self, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.bool_]:
        """True where NU = 0."""
        return self.unstable_count(tau1, tau2) == 0

    def stable_fraction(self, *, resolution: int = 400) -> float:
        """Fraction of the window's area that is stable (cell centres of a resolution x resolution grid)."""
        centres = (np.arange(resolution) + 0.5) / resolution
        return float(np.mean(self.is_stable(centres[None, :] * self.tau1_max, centres[:, None] * self.tau2_max)))

    @property
    def kernel_curves(self) -> tuple[CrossingCurve, ...]:
        """The kernel curves only."""
        return tuple(c for c in self.curves if c.is_kernel)

    def plot(self, ax: Axes | None = None, points: dict[str, tuple[float, float]] | None = None) -> Axes:
        """Draw the chart (see :func:`delayform.plots.stability_chart`)."""
        from delayform.plots import stability_chart

        return stability_chart(self, ax=ax, points=points)  # type: ignore[arg-type]

    def _horizontal(self, uy: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
        """Crossings of the lines tau2 = uy with every curve: (tau1, w RT1, line index)."""
        xs, ws, rows = [], [], []
        for br in self._branches:
            part = self._parts[br.part]
            w = br.omega
            # every offspring tau2 = (theta2 + 2 pi k2) / omega that reaches [0, tau2_max]
            for k2 in range(math.ceil(-br.th2.max() / TWO_PI),
                            math.floor((self.tau2_max * w.max() - br.th2.min()) / TWO_PI) + 2):  # fmt: skip
                tau = (br.th2 + TWO_PI * k2) / w
                lo = np.minimum(tau[:-1], tau[1:])
                hi = np.maximum(tau[:-1], tau[1:])
                a = np.searchsorted(uy, lo, "left")
                b = np.searchsorted(uy, hi, "left")  # half-open [lo, hi): a shared vertex counts once
                n = b - a
                if not n.any():
                    continue
                seg = np.repeat(np.arange(n.size), n)
                yi = np.arange(seg.size) - np.repeat(np.cumsum(n) - n, n) + a[seg]
                yy = uy[yi]
                wl, wr = w[seg], w[seg + 1]
                gl, gr = br.th2[seg], br.th2[seg + 1]
                fl = (gl + TWO_PI * k2) / wl - yy
                for _ in range(60):  # bisection on the closed form: the crossing to rounding
                    wm = 0.5 * (wl + wr)
                    frac = (wm - w[seg]) / (w[seg + 1] - w[seg])
                    th = _near(part.phases(np.array(wm), np.full(wm.shape, br.sign))[1], gl + frac * (gr - gl))
                    fm = (th + TWO_PI * k2) / wm - yy
                    left = np.sign(fm) == np.sign(fl)
                    wl, fl = np.where(left, wm, wl), np.where(left, fm, fl)
                    wr = np.where(left, wr, wm)
                om = 0.5 * (wl + wr)
                frac = (om - w[seg]) / (w[seg + 1] - w[seg])
                t1p, _ = part.phases(om, np.full(om.shape, br.sign))
                u1 = _near(t1p, br.th1[seg] + frac * (br.th1[seg + 1] - br.th1[seg]))
                kmin = np.ceil(-u1 / TWO_PI)
                kmax = np.floor((self.tau1_max * 1.000001 * om - u1) / TWO_PI)
                for j in range(int(np.max(kmax - kmin, initial=-1)) + 1):
                    k1 = kmin + j
                    ok = k1 <= kmax
                    tau1 = (u1 + TWO_PI * k1) / om
                    ok &= tau1 > 0.0
                    if not ok.any():
                        continue
                    rt = part.tendency(om[ok], tau1[ok], yy[ok], 1)
                    xs.append(tau1[ok])
                    ws.append(part.weight * rt)
                    rows.append(yi[ok])
        if not xs:
            return np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(xs), np.concatenate(ws), np.concatenate(rows)


def _curves(parts: tuple[_Part, ...], branches: list[_Branch], window: tuple[float, float]) -> tuple[CrossingCurve, ...]:
    """The curve pieces inside the window, for drawing (tendencies at each point)."""
    out = []
    for br in branches:
        part = parts[br.part]
        w = br.omega
        for k1 in range(int(np.ceil(-br.th1.max() / TWO_PI)), int((window[0] * w.max() - br.th1.min()) / TWO_PI) + 1):
            tau1 = (br.th1 + TWO_PI * k1) / w
            for k2 in range(int(np.ceil(-br.th2.max() / TWO_PI)),
                            int((window[1] * w.max() - br.th2.min()) / TWO_PI) + 1):  # fmt: skip
                tau2 = (br.th2 + TWO_PI * k2) / w
                inside = (tau1 >= 0) & (tau2 >= 0) & (tau1 <= window[0]) & (tau2 <= window[1])
                if inside.sum() < 2:
                    continue
                sel = np.flatnonzero(inside)
                a, b = tau1[sel], tau2[sel]
                kernel = bool(np.all((br.th1[sel] + TWO_PI * k1 < TWO_PI) & (br.th2[sel] + TWO_PI * k2 < TWO_PI)))
                out.append(CrossingCurve(
                    tau1=a, tau2=b, omega=w[sel],
                    rt1=part.tendency(w[sel], a, b, 1).astype(np.int8), rt2=part.tendency(w[sel], a, b, 2).astype(np.int8),
                    kind="kernel" if kernel else "offspring", shift=(k1, k2), weight=part.weight,
                    source=br.part, factor=part.factor,
                ))  # fmt: skip
    return tuple(out)


def actuated_stability_map(
    topology: Topology, P: float, D: float, tau1_max: float, tau2_max: float, actuation_delay: float
) -> ActuatedStabilityMap:
    """The exact CTCR map of the formation in (tau1, tau2) with actuation delay tau_a (module docstring).

    Parameters
    ----------
    topology
        Communication topology with a spanning tree.
    P, D
        Positive gains of the paper's eq. 1.
    tau1_max, tau2_max
        The window; positive.
    actuation_delay
        tau_a > 0 (s); for tau_a = 0 use :func:`~delayform.analysis.ctcr.stability_map.stability_map`.

    Returns
    -------
    ActuatedStabilityMap
    """
    topology.require_spanning_tree()
    P, D = check_gains(P, D)
    t1m, t2m = check_delay("tau1_max", tau1_max), check_delay("tau2_max", tau2_max)
    if t1m <= 0.0 or t2m <= 0.0:
        raise DelayError("tau1_max and tau2_max must be positive")
    ta = check_delay("actuation_delay", actuation_delay)
    parts: list[_Part] = []
    start = 0
    for idx, f in enumerate(factors(topology, P, D)):
        mult = int(f.multiplicity)
        pair = bool(f.group.is_complex_pair)
        lams = (complex(f.lam), complex(np.conj(f.lam))) if pair else (complex(f.lam),)
        parts += [_Part(lam, 2 * mult, idx, P, D, ta) for lam in lams]
        if not f.is_centroid:  # the centroid factor is exactly s^2 at (0, 0): no root right of 0
            n = count_roots_right_of(actuated_factor(P, D, complex(f.lam)), 0.0, 0.0, ta, 0.0)
            start += n * mult * (2 if pair else 1)
    window = (t1m, t2m)
    branches = [b for i, part in enumerate(parts) for b in _branches(part, i, window)]
    axis = [part.axis_crossings(t2m) for part in parts]
    where = np.concatenate([a for a, _ in axis]) if axis else np.zeros(0)
    delta = np.concatenate([d for _, d in axis]) if axis else np.zeros(0, np.int64)
    order = np.argsort(where)
    return ActuatedStabilityMap(
        curves=_curves(tuple(parts), branches, window), tau1_max=t1m, tau2_max=t2m, actuation_delay=ta,
        delay_free_count=int(start), _parts=tuple(parts), _branches=tuple(branches),
        _axis=(where[order], delta[order].astype(np.int64)),
    )  # fmt: skip
