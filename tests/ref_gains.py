"""An independent spectral abscissa over the gains, for tests/test_gains.py.

Nothing here uses :mod:`delayform.analysis.roots.dominant` or :mod:`delayform.design`.
Each factor of eq. factorized is written out from the paper,

    q_lam(s) = s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s}),

every exponential is replaced by its [m/m] Pade approximant (accurate to
~1e-12 for |tau s| <= 11 at m = 16, and a Newton seed well beyond), the resulting polynomial's roots come
from ``numpy.roots``, and each is polished by Newton's method on the exact
q_lam. The rightmost roots of a retarded factor have |s| of a few units, where
the approximant is exact to rounding; the roots it gets wrong lie far out,
far left. The search over the gains is brute force (a grid) followed by
scipy's Nelder-Mead from the best grid points: a different optimiser on a
different root computation.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.optimize import minimize

PADE_ORDER = 16


def _pade(m: int) -> np.ndarray:
    """Coefficients c_k (increasing powers) with e^x ~ p(x) / p(-x), p(x) = sum c_k x^k."""
    return np.array([
        math.factorial(2 * m - k) * math.factorial(m) / (math.factorial(2 * m) * math.factorial(k) * math.factorial(m - k))
        for k in range(m + 1)
    ])  # fmt: skip


_C = _pade(PADE_ORDER)


def _scaled(c: np.ndarray, a: float) -> np.ndarray:
    """Coefficients of p(a s) in s."""
    return c * a ** np.arange(c.size)


def _q(lam: complex, P: float, D: float, t1: float, t2: float, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e1, e2 = np.exp(-t1 * s), np.exp(-t2 * s)  # callers silence overflow of far-left spurious roots
    q = s * s + D * s + P - lam * (D * s * e2 + P * e1)
    dq = 2 * s + D - lam * (D * e2 - D * t2 * s * e2 - t1 * P * e1)
    return q, dq


@lru_cache(maxsize=64)
def _factor_polynomials(lam: complex, t1: float, t2: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A0, AP, AD): the Pade-cleared q_lam is A0 + P AP + D AD (it is linear in the gains)."""
    P1, P1m = _scaled(_C, t1), _scaled(_C, -t1)  # p(t1 s) and p(-t1 s)
    P2, P2m = _scaled(_C, t2), _scaled(_C, -t2)
    mul, sub = np.polynomial.polynomial.polymul, np.polynomial.polynomial.polysub
    s1 = np.array([0.0, 1.0])
    A0 = mul(mul(np.array([0.0, 0.0, 1.0]), P1), P2)
    AP = sub(mul(P1, P2), lam * mul(P1m, P2))
    AD = sub(mul(s1, mul(P1, P2)), lam * mul(s1, mul(P2m, P1)))
    n = max(A0.size, AP.size, AD.size)
    pad = [np.pad(np.asarray(a, dtype=complex), (0, n - a.size)) for a in (A0, AP, AD)]
    return pad[0], pad[1], pad[2]


def factor_rightmost(lam: complex, P: np.ndarray, D: np.ndarray, t1: float, t2: float) -> np.ndarray:
    """Re of the rightmost root of q_lam at each (P[i], D[i]) (centroid: the zero excluded)."""
    A0, AP, AD = _factor_polynomials(lam, t1, t2)
    coef = A0 + P[:, None] * AP + D[:, None] * AD  # increasing powers, leading coefficient A0[-1] != 0
    coef = coef[:, : int(np.max(np.flatnonzero(np.any(coef != 0, axis=0)))) + 1]
    n = coef.shape[1] - 1
    real = lam.imag == 0.0
    comp = np.zeros((P.size, n, n), dtype=float if real else complex)
    comp[:, 0, :] = (-coef[:, -2::-1] / coef[:, -1:]).real if real else -coef[:, -2::-1] / coef[:, -1:]
    comp[:, np.arange(1, n), np.arange(n - 1)] = 1.0
    s = np.linalg.eigvals(comp).astype(complex)
    if real:  # conjugate pairs: the member with Im >= 0 has the same real part
        s = np.where(s.imag >= 0.0, s, np.nan)
    Pc, Dc = P[:, None], D[:, None]
    with np.errstate(all="ignore"):
        for _ in range(8):
            q, dq = _q(lam, Pc, Dc, t1, t2, s)
            s = s - np.where(dq != 0, q / dq, 0)
        q, _ = _q(lam, Pc, Dc, t1, t2, s)
    a = np.abs(s)
    with np.errstate(all="ignore"):
        scale = a * a + Dc * a + Pc + abs(lam) * (Dc * a * np.exp(-t2 * s.real) + Pc * np.exp(-t1 * s.real))
        good = np.abs(q) <= 1e-9 * scale  # a spurious Pade root either polishes into a true root or fails here
    if abs(lam - 1.0) < 1e-9:
        good &= a > 1e-7  # the persistent root of eq. factor1
    with np.errstate(invalid="ignore"):
        return np.where(good, s.real, -np.inf).max(axis=1)


def abscissa(eigenvalues: list[complex], P: np.ndarray | float, D: np.ndarray | float, t1: float, t2: float) -> np.ndarray:
    """max Re over the roots of every factor, the centroid's persistent zero excluded."""
    P, D = np.broadcast_arrays(np.atleast_1d(np.asarray(P, float)), np.atleast_1d(np.asarray(D, float)))
    lams = [lam for lam in eigenvalues if lam.imag >= 0.0]  # conj(lam) has the mirrored roots
    return np.max([factor_rightmost(lam, P.ravel(), D.ravel(), t1, t2) for lam in lams], axis=0)


def best_gains(
    eigenvalues: list[complex], t1: float, t2: float, bounds: tuple[float, float], *,
    grid: int = 31, starts: int = 6,
) -> tuple[float, float, float]:
    """Brute-force grid, then Nelder-Mead from the best ``starts`` grid points: (P, D, abscissa)."""
    axis = np.linspace(bounds[0], bounds[1], grid)
    PP, DD = np.meshgrid(axis, axis, indexing="ij")
    values = abscissa(eigenvalues, PP.ravel(), DD.ravel(), t1, t2).reshape(grid, grid)
    order = np.argsort(values, axis=None)[:starts]
    best = (np.nan, np.nan, np.inf)

    def f(x: np.ndarray) -> float:
        p, d = np.clip(x, bounds[0], bounds[1])
        return float(abscissa(eigenvalues, p, d, t1, t2)[0])

    for k in order:
        i, j = np.unravel_index(int(k), values.shape)
        h = (bounds[1] - bounds[0]) / (grid - 1)
        x0 = np.array([axis[i], axis[j]])
        res = minimize(f, x0, method="Nelder-Mead",
                       options={"initial_simplex": np.array([x0, x0 + [h, 0], x0 + [0, h]]),
                                "xatol": 1e-7, "fatol": 1e-9, "maxfev": 150})  # fmt: skip
        if res.fun < best[2]:
            p, d = np.clip(res.x, bounds[0], bounds[1])
            best = (float(p), float(d), float(res.fun))
    return best
