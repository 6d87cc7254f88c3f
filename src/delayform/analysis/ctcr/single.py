"""Imaginary-axis roots of a quasi-polynomial in one delay, for any power of the delay.

The problem: all ``omega > 0`` and ``theta`` with ``h(j omega, z) = 0`` where
``h(s, z) = sum_{j=0}^{K} h_j(s) z^j`` and ``z = e^{-j theta}`` on the unit
circle. It is the axis problem of CTCR (one delay zero), the crossing lines
of a quasi-polynomial in one delay, and the problem on a line ``theta_2 =
const`` of a two-delay one (then the ``h_j`` are complex).

Method: the frequency is eliminated, not the delay
---------------------------------------------------
With ``s = rho mu`` (rho balances the coefficients) write
``P(mu, z) = h(rho mu, z)`` and ``Q(mu, z) = z^K conj-coefficients P(-mu, 1/z)``.
For real omega and ``|z| = 1``, ``Q(j omega / rho, z) = z^K conj(P(j omega / rho, z))``,
so every crossing ``(j omega, z)`` is a common root in mu of P and Q. Their
resultant in mu, ``R(z) = Res_mu(P, Q)`` (a ``2n x 2n`` Sylvester determinant,
n the degree in s after removing a factor ``s^m`` common to every h_j, a root
s = 0 for every delay), is a polynomial of degree ``<= 2 n K`` in z. It is
evaluated on ``2 n K + 1`` roots of unity and its coefficients recovered by
the FFT, the exact (unitary) inverse of evaluation there; its roots within
1e-4 of the unit circle give z, the roots of ``P(., z)`` within 1e-4 of the
imaginary axis give omega, and Newton's method on (omega, theta) polishes each
pair on h itself.

Why this and not a resultant in z interpolated in omega: z ranges over the
unit circle, a compact set on which R neither grows nor needs a bound on the
crossing frequencies; a polynomial in omega of degree ``2 n K`` sampled on
``[0, Omega]`` spans ``Omega^{2 n K}`` orders of magnitude, so its low
crossings drown in the rounding of its values near Omega (for ``n K >= 6``
every crossing could be lost). And a qp in ``z^g`` alone (``h_j = 0`` unless
g divides j) has a g-fold resultant in z at each crossing frequency, a root
Chebyshev root-finding cannot resolve, while in z its g crossings are
distinct simple roots (rotations by ``2 pi / g``).

The leading coefficient of P in mu is the principal polynomial's for a
retarded qp, a nonzero constant; for a neutral qp admitted by the crossing
map it is ``D(z) p_0[n]`` with D zero-free on the closed unit disk. Either
way R vanishes at a unit z exactly when P and Q share a root there.
"""

from __future__ import annotations

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import NDArray

from delayform.errors import QuasiPolynomialError

__all__ = ["unit_roots_single", "line_frequencies", "sylvester"]

TWO_PI = 2.0 * np.pi
#: Distance to the unit circle (for z) and to the imaginary axis (for s / |s|) of a candidate.
_CANDIDATE_TOL = 1e-4
_EVERY_DELAY = ("the quasi-polynomial has a root on the imaginary axis for every delay (all its terms share a "
                "factor with such a root); divide that factor out before mapping crossings")


def sylvester(p: NDArray, q: NDArray) -> NDArray:
    """Batched Sylvester matrices of p and q (last axis: coefficients, descending powers, same degree K)."""
    K = p.shape[-1] - 1
    n = 2 * K
    S = np.zeros(p.shape[:-1] + (n, n), complex)
    for i in range(K):
        S[..., i, i : i + K + 1] = p
        S[..., K + i, i : i + K + 1] = q
    return S


def _coefficient_table(h: list[NDArray[np.complex128]]) -> NDArray[np.complex128]:
    """``A[j, i]``: coefficient of ``s^i z^j``, with the factor ``s^m`` common to every h_j removed."""
    n = max(c.size for c in h)
    A = np.zeros((len(h), n), complex)
    for j, c in enumerate(h):
        A[j, : c.size] = c
    cols = np.flatnonzero(np.any(A != 0.0, axis=0))
    return A[:, cols[0] : cols[-1] + 1]


def unit_roots_single(h: list[NDArray[np.complex128]]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """omega > 0 and theta in [0, 2 pi) with ``sum_j h_j(j omega) e^{-j j theta} = 0`` (module docstring).

    Parameters
    ----------
    h
        ``h_j``, coefficients ascending in s, one per power of z.

    Returns
    -------
    omega, theta
        Every solution once (theta of each of the g rotations of a qp in z^g).

    Raises
    ------
    QuasiPolynomialError
        When every h_j shares a factor with a root on the imaginary axis other
        than s = 0 (q has that root for every delay: no crossing is defined).
    """
    K = len(h) - 1
    if K < 1 or all(c.size == 0 or not np.any(c) for c in h[1:]):
        return np.zeros(0), np.zeros(0)
    A = _coefficient_table(h)
    n = A.shape[1] - 1
    if n == 0:
        # h(s, z) = s^m c(z): besides s = 0 its roots solve c(e^{-tau s}) = 0, imaginary for every tau
        # when c has a unit root (then no crossing is defined), else there are none
        c = np.trim_zeros(A[:, 0], "b")
        if c.size > 1 and np.any(np.abs(np.abs(np.roots(c[::-1])) - 1.0) < _CANDIDATE_TOL):
            raise QuasiPolynomialError(_EVERY_DELAY)
        return np.zeros(0), np.zeros(0)
    out_w: list[float] = []
    out_t: list[float] = []
    for om, th in zip(*_candidates(A, K), strict=True):
        res = _polish_single(h, float(om), float(th))
        if res is not None and all(abs(res[0] - w) > 1e-9 * max(1.0, w) or
                                   abs(np.angle(np.exp(1j * (res[1] - t)))) > 1e-7
                                   for w, t in zip(out_w, out_t, strict=True)):
            out_w.append(res[0])
            out_t.append(res[1])
    return np.array(out_w), np.array(out_t)


def _candidates(A: NDArray[np.complex128], K: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unpolished (omega, theta) of the elimination of the module docstring; A from :func:`_coefficient_table`."""
    n = A.shape[1] - 1
    # rho: the geometric scale of the roots in s, so the coefficients of P in mu are balanced
    rho = float((np.max(np.abs(A[:, 0])) / np.max(np.abs(A[:, n]))) ** (1.0 / n))
    B = A * rho ** np.arange(n + 1)[None, :]
    B = B / np.max(np.abs(B))
    N = 2 * n * K + 1
    z = np.exp(2j * np.pi * np.arange(N) / N)
    powers = z[:, None] ** np.arange(K + 1)[None, :]                 # (N, K + 1)
    P = powers @ B                                                    # P_i(z): ascending in mu
    sign = (-1.0) ** np.arange(n + 1)
    Q = (powers[:, ::-1] @ np.conj(B)) * sign[None, :]                # z^K conj-coefficients P(-mu, 1/z)
    S = sylvester(P[:, ::-1], Q[:, ::-1])
    coef = np.fft.fft(np.linalg.det(S)) / N                           # R(z_m) = sum_k coef_k z_m^k
    scale = float(np.max(np.abs(coef)))
    # Hadamard's bound on |R| on the circle: R below 1e-12 of it everywhere is a resultant that
    # vanishes identically (rounding leaves ~1e-16 of it), i.e. P and Q share a factor for every z
    if not scale > 1e-12 * float(np.max(np.prod(np.linalg.norm(S, axis=-1), axis=-1))):
        raise QuasiPolynomialError(_EVERY_DELAY)
    keep = np.flatnonzero(np.abs(coef) > 1e-13 * scale)
    roots_z = np.roots(coef[keep[0] : keep[-1] + 1][::-1]) if keep.size > 1 else np.zeros(0, complex)
    roots_z = roots_z[np.abs(np.abs(roots_z) - 1.0) < _CANDIDATE_TOL]
    out_w: list[float] = []
    out_t: list[float] = []
    for zc in roots_z:
        pz = (zc ** np.arange(K + 1)) @ B
        nzp = np.flatnonzero(pz != 0.0)
        if nzp.size < 2:
            continue
        mu = np.roots(pz[: nzp[-1] + 1][::-1])
        mu = mu[(mu.imag > 0.0) & (np.abs(mu.real) <= _CANDIDATE_TOL * np.abs(mu))]
        out_w.extend(rho * mu.imag)
        out_t.extend([float(-np.angle(zc))] * mu.size)
    return np.array(out_w, float), np.array(out_t, float)


def line_frequencies(terms: list[tuple[NDArray[np.complex128], int, int]], n_lines: int) -> NDArray[np.float64]:
    """Crossing frequencies (unpolished) on ``n_lines`` lines theta_2 = const and as many theta_1 = const.

    On such a line a two-delay qp ``sum c_ab(s) z1^a z2^b`` is a one-delay
    problem in the other phase, solved by the elimination of the module
    docstring: every point of the crossing set on the line is found, however
    narrow the band of frequencies its curve spans.

    Parameters
    ----------
    terms
        ``(coefficients ascending in s, multiple of tau1, multiple of tau2)``.
    n_lines
        Lines per phase, at ``theta = 2 pi (k + 1/3) / n_lines``.
    """
    out = []
    theta = TWO_PI * (np.arange(n_lines) + 1.0 / 3.0) / n_lines
    for kept in (0, 1):
        K = max(t[1 + kept] for t in terms)
        if K == 0:
            continue
        n = max(c.size for c, _, _ in terms)
        for th in theta:
            A = np.zeros((K + 1, n), complex)
            for c, a, b in terms:
                j, other = (a, b) if kept == 0 else (b, a)
                A[j, : c.size] += c * np.exp(-1j * other * th)
            cols = np.flatnonzero(np.any(A != 0.0, axis=0))
            A = A[:, cols[0] : cols[-1] + 1]
            if A.shape[1] > 1 and np.any(A[1:] != 0.0):
                try:
                    out.append(_candidates(A, K)[0])
                except QuasiPolynomialError:
                    continue  # a whole circle of solutions on this line: the seeds of the others remain
    return np.concatenate(out) if out else np.zeros(0)


def _polish_single(h: list[NDArray[np.complex128]], om: float, th: float) -> tuple[float, float] | None:
    """Newton on (omega, theta) for ``sum_j h_j(j omega) e^{-j j theta} = 0``; keeps a flat (touching) start."""
    js = np.arange(len(h))

    def f_j(om: float, th: float) -> tuple[complex, complex, complex, float]:
        s = 1j * om
        v = np.array([npoly.polyval(s, c) if c.size else 0j for c in h])
        dv = np.array([1j * npoly.polyval(s, npoly.polyder(c)) if c.size > 1 else 0j for c in h])
        e = np.exp(-1j * js * th)
        return (v * e).sum(), (dv * e).sum(), (-1j * js * v * e).sum(), float(np.abs(v).sum())

    f, fo, ft, scale = f_j(om, th)
    if abs(f) <= 1e-12 * scale:
        return om, float(np.mod(th, TWO_PI))
    for _ in range(20):
        J = np.array([[fo.real, ft.real], [fo.imag, ft.imag]])
        if abs(np.linalg.det(J)) <= 1e-14 * (abs(fo) * abs(ft) + 1e-300):
            break
        step = np.linalg.solve(J, [f.real, f.imag])
        om, th = om - step[0], th - step[1]
        f, fo, ft, scale = f_j(om, th)
        if abs(f) <= 1e-15 * scale:
            break
    return (om, float(np.mod(th, TWO_PI))) if abs(f) <= 1e-10 * scale and om > 0 else None
