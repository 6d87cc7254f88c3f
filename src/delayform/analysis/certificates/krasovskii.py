"""Lyapunov-Krasovskii functionals with Bessel-Legendre inequalities for x' = A0 x + A1 x(t - h(t)).

Two functionals (derivations in docs/theory.md, "Certificates for time-varying
delays"); both give LMIs in which the integral terms are bounded by the
Bessel-Legendre inequality of order N (Seuret and Gouaisbaut, Systems &
Control Letters 2015): N = 0 is Jensen's inequality, N = 1 Wirtinger's.

``constant_delay``
    Constant delays h in [h1, h2]: the augmented functional of the
    Bessel-Legendre hierarchy, V = eta' P eta + int S + h int int R with
    ``eta = (x, h Omega_0, ..., h Omega_{N-1})`` (Legendre moments of the
    state over [t - h, t]). Its derivative bound Phi(h) is a quadratic
    matrix polynomial in h whose h^2 coefficient ``F' R F`` is positive
    semidefinite, so Phi is matrix-convex in h: one set of matrices with
    Phi(h1) < 0 and Phi(h2) < 0 makes Phi(h) < 0 on all of [h1, h2].
``time_varying``
    h(t) in [h1, h2] with dh/dt <= mu (or any variation, mu None): V = x' P x +
    int_{t-h1}^t S1 + int_{t-h2}^{t-h1} S2 + int_{t-h(t)}^t Q (only with mu) +
    double integrals of R1 and R2; the integral of R2 over [t - h2, t - h1] is
    split at t - h(t), each part bounded by the Bessel-Legendre inequality and
    the two combined by the reciprocally convex combination lemma (Park, Ko
    and Jeong 2011; Seuret and Gouaisbaut 2013), which removes h(t) from the
    LMI.

Both build their matrices with float64 or exact rational arithmetic by the
same formulas (see :class:`~delayform.analysis.certificates.lmi.LmiProblem`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.certificates.lmi import LmiProblem, Variables

__all__ = ["SystemData", "constant_delay", "time_varying"]

Matrix = NDArray[Any]


@dataclass(frozen=True)
class SystemData:
    """A0, A1 and the delay bounds, in float64 and as exact Fractions (floats are dyadic rationals)."""

    A0: NDArray[np.float64]
    A1: NDArray[np.float64]
    h1: float
    h2: float
    mu: float | None

    def matrices(self, exact: bool) -> tuple[Matrix, Matrix]:
        """(A0, A1) as float64, or (``exact``) as object arrays of Fractions equal to the floats."""
        if not exact:
            return self.A0, self.A1
        conv = np.vectorize(Fraction, otypes=[object])
        return conv(self.A0), conv(self.A1)

    def number(self, value: float, exact: bool) -> Any:
        """The scalar ``value`` in the requested arithmetic (``exact``: a Fraction)."""
        return Fraction(value) if exact else value


class _Signals:
    """The blocks of the vector zeta the derivative bound is a quadratic form in (aliases allowed)."""

    def __init__(self, names: Sequence[str], n: int, exact: bool, aliases: Mapping[str, str] | None = None,
                 basis: Matrix | None = None) -> None:  # fmt: skip
        self.index = {name: i for i, name in enumerate(names)}
        for alias, target in (aliases or {}).items():
            self.index[alias] = self.index[target]
        self.n = n
        self.basis = basis
        self.size = n * len(names) if basis is None else basis.shape[1]
        self.dtype: Any = object if exact else float

    def e(self, name: str) -> Matrix:
        """The n x size matrix picking the block ``name`` of zeta.

        With a ``basis`` B (zeta = B z, zeta confined to its range), the block of zeta in terms of z: rows of B.
        """
        i = self.index[name]
        if self.basis is not None:
            return np.array(self.basis[i * self.n : (i + 1) * self.n, :], dtype=self.dtype)
        E = np.zeros((self.n, self.size), dtype=self.dtype)
        for r in range(self.n):
            E[r, i * self.n + r] = 1
        return E

    def legendre(self, top: str, bottom: str, moments: Sequence[str], k: int) -> Matrix:
        """Gamma_k = int l_k(u) x'(s) ds over an interval (top = its end, bottom = its start).

        With the shifted Legendre polynomials l_k on [0, 1] (l_k(1) = 1,
        l_k(0) = (-1)^k) and the normalized moments Omega_j = (1/len) int l_j x,
        integration by parts and l_k' = 2 sum_{j<k, k-j odd} (2j+1) l_j give
        Gamma_k = x(top) - (-1)^k x(bottom) - 2 sum (2j+1) Omega_j.
        """
        G = self.e(top) - (-1) ** k * self.e(bottom)
        for j in range(k - 1, -1, -2):
            G = G - 2 * (2 * j + 1) * self.e(moments[j])
        return G


def _he(M: Matrix) -> Matrix:
    return M + _t(M)


def _t(M: Matrix) -> Matrix:
    # transpose of the last two axes: the variables may carry a batch axis (lmi._linearize)
    return np.swapaxes(M, -1, -2)


def _quad(E: Matrix, W: Matrix) -> Matrix:
    return _cross(E, W, E)


def _cross(G: Matrix, W: Matrix, H: Matrix) -> Matrix:
    """G' W H; in exact arithmetic only over the non-zero columns (selections: most of zeta is not involved)."""
    if G.dtype != object:
        return G.T @ W @ H
    gi, hi, Z, den = _cross_integer(G, W, H)
    out = np.zeros((G.shape[1], H.shape[1]), dtype=object)
    out[np.ix_(gi, hi)] = np.frompyfunc(lambda v: Fraction(v, den), 1, 1)(Z)
    return out


def _cross_integer(G: Matrix, W: Matrix, H: Matrix) -> tuple[NDArray[np.intp], NDArray[np.intp], Matrix, int]:
    """(gi, hi, Z, d): G' W H restricted to the rows gi and columns hi outside which it is 0, equal to Z / d.

    In integers over common denominators (no gcd at every step): Z holds Python ints.
    """
    gi, hi = np.flatnonzero(np.any(G != 0, axis=0)), np.flatnonzero(np.any(H != 0, axis=0))
    (g, dg), (w, dw), (h, dh) = _integer(G[:, gi]), _integer(W), _integer(H[:, hi])
    return gi, hi, g.T @ w @ h, dg * dw * dh


def _integer(M: Matrix) -> tuple[Matrix, int]:
    """(Z, d) with M = Z / d exactly: Z Python ints, d the least common denominator of M's entries.

    The entries must be ints or Fractions (both carry ``numerator`` and ``denominator``).
    """
    flat = M.ravel().tolist()
    try:
        den = math.lcm(1, *(v.denominator for v in flat))
    except AttributeError:  # a float or a NumPy scalar among them: converted exactly
        flat = [Fraction(v) for v in flat]
        den = math.lcm(1, *(v.denominator for v in flat))
    Z = np.empty(M.shape, dtype=object)
    Z.ravel()[:] = [v.numerator * (den // v.denominator) for v in flat]
    return Z, den


class _Sum:
    """A symmetric matrix built as a sum of terms c G' W H, the same way in both arithmetics.

    In floating point each term is added in turn as the builders always did (the same operations,
    so the same float result); in exact arithmetic the terms are accumulated as Python integers
    over one common denominator (an addition of two Fraction matrices costs a gcd per entry) and
    turned into Fractions once, by :meth:`value`.
    """

    def __init__(self, size: int, exact: bool) -> None:
        self.exact = exact
        self.M: Matrix = np.zeros((size, size), dtype=object if exact else float)
        self.den = 1

    def copy(self) -> _Sum:
        """An independent copy (the corners of a box share a common part)."""
        out = _Sum.__new__(_Sum)
        out.exact, out.M, out.den = self.exact, self.M.copy(), self.den
        return out

    @staticmethod
    def _scaled(Z: Matrix, den: int, coef: Any) -> tuple[Matrix, int]:
        c = Fraction(coef)
        return Z * c.numerator, den * c.denominator

    def _merge(self, rows: NDArray[np.intp], cols: NDArray[np.intp], Z: Matrix, den: int, transpose: bool) -> None:
        common = self.den * den // math.gcd(self.den, den)
        if common != self.den:
            self.M = self.M * (common // self.den)
            self.den = common
        Z = Z * (common // den) if common != den else Z
        self.M[np.ix_(rows, cols)] += Z
        if transpose:
            self.M[np.ix_(cols, rows)] += Z.T

    def add(self, coef: Any, G: Matrix, W: Matrix, H: Matrix | None = None, *, sym: bool = False) -> None:
        """Add coef G' W H (H None: G), plus its transpose when ``sym``."""
        H = G if H is None else H
        if not self.exact:
            term = _cross(G, W, H)
            term = _he(term) if sym else term
            if coef == 1:
                self.M = self.M + term
            elif coef == -1:
                self.M = self.M - term
            else:
                self.M = self.M + coef * term
            return
        gi, hi, Z, den = _cross_integer(G, W, H)
        Z, den = self._scaled(Z, den, coef)
        self._merge(gi, hi, Z, den, sym)

    def add_terms(self, sign: int, terms: Sequence[tuple[int, Matrix]], W: Matrix) -> None:
        """Add sign * sum c G' W G over ``terms`` (c, G) (in floats summed first by :func:`_quads`, as :func:`_bessel`)."""
        if not self.exact:
            out = _quads(terms, W, self.M.shape[-1], float)
            self.M = self.M + out if sign == 1 else self.M - out
            return
        for c, G in terms:
            self.add(sign * c, G, W)

    def value(self, sign: int = 1) -> Matrix:
        """sign times the sum: float64, or Fractions."""
        if not self.exact:
            return self.M if sign == 1 else -self.M
        den = self.den
        flat = [Fraction(sign * v, den) for v in self.M.ravel().tolist()]
        out = np.empty(self.M.shape, dtype=object)
        out.ravel()[:] = flat
        return out


def _bessel(sig: _Signals, top: str, bottom: str, moments: Sequence[str], R: Matrix, order: int) -> Matrix:
    """sum_{k<=N} (2k+1) Gamma_k' R Gamma_k: the Bessel-Legendre lower bound of len * int x' R x'."""
    return _quads(_bessel_terms(sig, top, bottom, moments, order), R, sig.size, sig.dtype)


def _quads(terms: Sequence[tuple[int, Matrix]], W: Matrix, size: int, dtype: Any) -> Matrix:
    """sum c G' W G over ``terms`` (c, G), added in turn (the order fixes the float result)."""
    out: Matrix = np.zeros((size, size), dtype=dtype)
    for c, G in terms:
        out = out + c * _quad(G, W)
    return out


def _bessel_terms(sig: _Signals, top: str, bottom: str, moments: Sequence[str], order: int) -> list[tuple[int, Matrix]]:
    """The terms (2k + 1, Gamma_k) of :func:`_bessel`."""
    return [(2 * k + 1, sig.legendre(top, bottom, moments, k)) for k in range(order + 1)]


def _moments(prefix: str, order: int) -> list[str]:
    return [f"{prefix}{j}" for j in range(order)]


def constant_delay(data: SystemData, order: int) -> LmiProblem:
    """The Bessel-Legendre hierarchy's LMIs for every constant delay h in [h1, h2] (module docstring).

    Parameters
    ----------
    data
        The system and the interval (``data.mu`` is not used: the delay is constant).
    order
        The Bessel-Legendre order N; the state holds N Legendre moments.
    """
    n = data.A0.shape[0]
    om = _moments("w", order)
    var = Variables()
    var.symmetric("P", n * (order + 1))
    var.symmetric("S", n)
    var.symmetric("R", n)
    ends = sorted({data.h1, data.h2})

    def build(v: Mapping[str, Matrix], exact: bool) -> dict[str, Matrix]:
        A0, A1 = data.matrices(exact)
        sig = _Signals(["x", "xh", *om], n, exact)
        F = A0 @ sig.e("x") + A1 @ sig.e("xh")
        # eta' = (x', Gamma_0, ..., Gamma_{N-2}) since d/dt (h Omega_j) = Gamma_j
        H = np.vstack([F] + [sig.legendre("x", "xh", om, j) for j in range(order)])
        fixed = _quad(sig.e("x"), v["S"]) - _quad(sig.e("xh"), v["S"]) - _bessel(sig, "x", "xh", om, v["R"], order)
        out: dict[str, Matrix] = {}
        for h in ends:
            hh = data.number(h, exact)
            G = np.vstack([sig.e("x")] + [hh * sig.e(w) for w in om])
            out[f"-Phi(h={h:g})"] = -(_he(G.T @ v["P"] @ H) + fixed + hh * hh * _quad(F, v["R"]))
        out.update(P=v["P"], S=v["S"], R=v["R"])
        return out

    return LmiProblem(var, build)


def time_varying(data: SystemData, order: int) -> LmiProblem:
    """LMIs for every h(t) in [h1, h2] with |dh/dt| <= mu (any rate when mu is None), h2 > h1.

    With a rate bound (and order >= 1) the state is augmented by the integrals of x over
    [t - h1, t], [t - h(t), t - h1] and [t - h2, t - h(t)]: their derivatives
    are affine in dh/dt and their values in h(t), so the derivative bound is
    bilinear in (h, dh/dt) and holds on the whole box when it holds at its four
    vertices. Without a rate bound only x'Px is used (no term may depend on dh/dt).

    Parameters
    ----------
    data
        The system, the interval [h1, h2] (h2 > h1) and the rate bound mu (None: any rate).
    order
        The Bessel-Legendre order N of the bounds on both parts of the split integral.
    """
    n = data.A0.shape[0]
    inner = data.h1 > 0.0
    # the augmented state needs the moments Omega_0 inside a Bessel bound (order >= 1): at order 0
    # they would enter the derivative bound only linearly, which no negative definite form allows
    rated = data.mu is not None and order >= 1
    nm = order
    w1, wa, wb = _moments("w1_", nm), _moments("wa_", nm), _moments("wb_", nm)
    m = n * (order + 1)
    var = Variables()
    var.symmetric("P", n * ((3 + inner) if rated else 1))
    if inner:
        var.symmetric("S1", n)
        var.symmetric("R1", n)
    var.symmetric("S2", n)
    var.symmetric("R2", n)
    if data.mu is not None:
        var.symmetric("Q", n)
    var.full("X", m, m)

    def build(v: Mapping[str, Matrix], exact: bool) -> dict[str, Matrix]:
        A0, A1 = data.matrices(exact)
        num = data.number
        names = ["x", "xh", "x2", *(["x1", *w1] if inner else []), *wa, *wb]
        sig = _Signals(names, n, exact, None if inner else {"x1": "x"})
        e0, eh, e1, e2 = sig.e("x"), sig.e("xh"), sig.e("x1"), sig.e("x2")
        F = A0 @ e0 + A1 @ eh
        h1, h2 = num(data.h1, exact), num(data.h2, exact)
        d = h2 - h1
        Phi = _quad(e1, v["S2"]) - _quad(e2, v["S2"]) + d * d * _quad(F, v["R2"])
        if inner:
            Phi = Phi + _quad(e0, v["S1"]) - _quad(e1, v["S1"]) + h1 * h1 * _quad(F, v["R1"])
            Phi = Phi - _bessel(sig, "x", "x1", w1, v["R1"], order)
        # the R2 integral split at t - h(t); reciprocal convexity with the slack X
        Psi = np.vstack(
            [sig.legendre("x1", "xh", wa, k) for k in range(order + 1)]
            + [sig.legendre("xh", "x2", wb, k) for k in range(order + 1)]
        )
        Rt = np.zeros(v["R2"].shape[:-2] + (m, m), dtype=sig.dtype)
        for k in range(order + 1):
            Rt[..., k * n : (k + 1) * n, k * n : (k + 1) * n] = (2 * k + 1) * v["R2"]
        rcc = np.block([[Rt, v["X"]], [_t(v["X"]), Rt]])
        Phi = Phi - _quad(Psi, rcc)
        out: dict[str, Matrix] = {}
        if not rated:
            if data.mu is not None:  # order 0 with a rate bound: dh/dt <= mu is the worst case of the Q term
                Phi = Phi + _quad(e0, v["Q"]) - (1 - num(data.mu, exact)) * _quad(eh, v["Q"])
            out["-Phi"] = -(Phi + _he(e0.T @ v["P"] @ F))
        else:
            mu = num(data.mu, exact)  # type: ignore[arg-type]
            for h_name, h in (("h1", h1), ("h2", h2)):
                for r_name, rate in (("-mu", -mu), ("+mu", mu)):
                    # eta = (x, int_{t-h1}^t x, int_{t-h(t)}^{t-h1} x, int_{t-h2}^{t-h(t)} x)
                    G = [e0, *([h1 * sig.e(w1[0])] if inner else []), (h - h1) * sig.e(wa[0]), (h2 - h) * sig.e(wb[0])]
                    H = [F, *([e0 - e1] if inner else []), e1 - (1 - rate) * eh, (1 - rate) * eh - e2]
                    # d/dt int_{t-h(t)}^t x'Qx = x'Qx - (1 - h') xh'Q xh
                    q = _quad(e0, v["Q"]) - (1 - rate) * _quad(eh, v["Q"])
                    out[f"-Phi(h={h_name}, dh={r_name})"] = -(Phi + q + _he(np.vstack(G).T @ v["P"] @ np.vstack(H)))
        out.update(P=v["P"], S2=v["S2"], R2=v["R2"], RCC=rcc)
        if inner:
            out.update(S1=v["S1"], R1=v["R1"])
        if data.mu is not None:
            out["Q"] = v["Q"]
        return out

    return LmiProblem(var, build)
