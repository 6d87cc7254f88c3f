"""The boundary curve of the eigenvalue plane, ``L(j omega) = a(j omega) / b(j omega)``.

Every factor of the paper's eq. 3 is ``q(s, lam) = a(s) - lam b(s)`` with
``a(s) = s^2 + D s + P`` and ``b(s) = D s e^{-tau2 s} + P e^{-tau1 s}``; q has the
root ``j omega`` exactly when ``lam = L(j omega)``. Shared by the region
(:mod:`delayform.analysis.plane.region`), the certificates
(:mod:`delayform.analysis.plane.spectrum_sets`) and the envelopes
(:mod:`delayform.analysis.plane.envelope`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["omega_limit", "ab_terms"]


def ab_terms(P: float, D: float, tau1: ArrayLike, tau2: ArrayLike, w: ArrayLike) -> tuple[NDArray[np.complex128], ...]:
    """a, b and their s-derivatives a', b' at s = j w (broadcasting delays against w).

    Parameters
    ----------
    P, D
        Gains of the paper's eq. 1.
    tau1, tau2
        Delays (s), scalars or arrays.
    w
        Frequencies omega.

    Returns
    -------
    tuple of ndarray
        ``(a, b, a', b')`` with ``b' = D e^{-tau2 s} (1 - tau2 s) - P tau1 e^{-tau1 s}``.
    """
    s = 1j * np.asarray(w)
    t1, t2 = np.asarray(tau1), np.asarray(tau2)
    e1, e2 = np.exp(-t1 * s), np.exp(-t2 * s)
    a = s * s + D * s + P
    b = D * s * e2 + P * e1
    return a, b, 2.0 * s + D, D * e2 * (1.0 - t2 * s) - P * t1 * e1


def omega_limit(P: float, D: float, radius: float) -> float:
    """A frequency beyond which ``|L(j omega)| > radius`` (so no crossing of |lam| <= radius).

    ``|a(j w)| >= w^2 - P`` and ``|b(j w)| <= P + D w``, so ``|L| > radius`` once
    ``w^2 - radius D w - P (1 + radius) > 0``.

    Parameters
    ----------
    P, D
        Gains of the paper's eq. 1.
    radius
        The largest |lam| of interest.
    """
    r = max(float(radius), 0.0)
    return float(0.5 * (r * D + np.sqrt((r * D) ** 2 + 4.0 * P * (1.0 + r)))) * 1.0001 + 1e-9
