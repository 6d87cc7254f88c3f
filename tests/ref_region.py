"""Independent references for tests/test_region.py (nothing here uses delayform.analysis).

* :func:`rhp_count`: the number of roots of ``q(s) = s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s})``
  with Re s > 0 by the argument principle *in s*: the phase of q densely
  sampled (np.unwrap) down the imaginary axis from j W to -j W and back along
  the right half circle |s| = W, where q ~ s^2 dominates. Returns None when q
  comes close to zero on the contour (a root on or next to the axis: the
  reference cannot decide).
"""

from __future__ import annotations

import numpy as np


def _q(s: np.ndarray, lam: complex, P: float, D: float, tau1: float, tau2: float) -> np.ndarray:
    return s * s + D * s + P - lam * (D * s * np.exp(-tau2 * s) + P * np.exp(-tau1 * s))


def rhp_count(lam: complex, P: float, D: float, tau1: float, tau2: float) -> int | None:
    """Roots of q(., lam) with Re s > 0, by the argument principle in s (None when undecidable)."""
    # |q / s^2 - 1| < 1/2 on |s| = W, Re s >= 0: |lam| (D W + P) + D W + P < W^2 / 2
    R = abs(lam)
    W = 4.0 * (1.0 + (R + 1.0) * (D + P)) + 4.0
    step = 0.01 / max(1.0, tau1, tau2)
    w = np.linspace(W, -W, int(2 * W / step) + 1)
    arc = W * np.exp(1j * np.linspace(-np.pi / 2, np.pi / 2, 20001))
    path = np.concatenate([1j * w, arc[1:]])
    q = _q(path, lam, P, D, tau1, tau2)
    scale = np.abs(path) ** 2 + D * np.abs(path) + P + R * (D * np.abs(path) + P)
    if np.min(np.abs(q) / scale) < 1e-5:
        return None
    phase = np.unwrap(np.angle(q))
    return int(round((phase[-1] - phase[0]) / (2.0 * np.pi)))
