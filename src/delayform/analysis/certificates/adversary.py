"""The other side of a certificate: a switching adversary that tries to destabilize one mode.

:func:`greedy_switching_grows` simulates one real mode of the paper's eq. 3 with the
delays switching, every step, between tau - delta and tau + delta (the same on
every link), picking whichever pumps energy into the mode: the delayed value
that maximizes v * lam (P x(t - h1) + D v(t - h2)) (bang-bang, greedy). Its own
semi-implicit Euler integrator, independent of the LMIs; a growth it finds
inside a certified interval would be a bug of the certificate.

:func:`weighted_switching_grows` is a stronger adversary of the same kind: a
family of greedy rules run side by side (vectorized), each pumping a different
quadratic energy V_b = a x^2 + 2 b x v + v^2 (a > b^2, so any real b) whose rate
depends on the delayed values only through (b x + v) lam (P x(t - h1) + D v(t - h2)),
so the rule depends on b alone and the family covers every quadratic energy; b = 0
is the rule above. Any member that grows is a destabilizing delay signal: the
smallest deviation at which one does is an upper bound of the true margin for
delays varying together.
"""

from __future__ import annotations

import numpy as np

__all__ = ["greedy_switching_grows", "weighted_switching_grows", "WEIGHTS"]

#: The cross weights b of the energies the stronger adversary pumps (b = 0: the plain energy), tan-spaced.
WEIGHTS = tuple(np.round(np.tan(np.linspace(-1.45, 1.45, 59)), 4))


def greedy_switching_grows(lam: float, P: float, D: float, tau1: float, tau2: float, delta: float, *,
                           dt: float = 0.005, duration: float = 240.0) -> bool:  # fmt: skip
    """True when the mode's energy x^2 + v^2 over the last 20 s exceeds its initial value (x = 1, v = 0).

    Parameters
    ----------
    lam
        The (real) eigenvalue of C; not the centroid's 1, whose mode settles at any constant.
    P, D, tau1, tau2
        Gains and nominal delays.
    delta
        The switching amplitude: each delay takes tau - delta (at least dt) or tau + delta.
    dt, duration
        Step and length of the run (s).
    """
    lags = [max(int(round(max(t - s * delta, dt) / dt)), 1) for t in (tau1, tau2) for s in (1, -1)]
    depth = max(lags) + 1
    hx, hv = np.ones(depth), np.zeros(depth)  # the history: x = 1, v = 0 before t = 0
    x, v, late = 1.0, 0.0, 0.0
    steps = int(duration / dt)
    for k in range(steps):
        xa, xb = hx[(k - lags[0]) % depth], hx[(k - lags[1]) % depth]
        va, vb = hv[(k - lags[2]) % depth], hv[(k - lags[3]) % depth]
        xs = xa if lam * (xa - xb) * v > 0 else xb
        vs = va if lam * (va - vb) * v > 0 else vb
        v += dt * (-P * x - D * v + lam * (P * xs + D * vs))
        x += dt * v
        hx[(k + 1) % depth], hv[(k + 1) % depth] = x, v
        if k > steps - int(20.0 / dt):
            late = max(late, x * x + v * v)
    return late > 1.0


def weighted_switching_grows(lam: float, P: float, D: float, tau1: float, tau2: float, delta: float, *,
                             weights: tuple[float, ...] = WEIGHTS, dt: float = 0.005,
                             duration: float = 240.0) -> bool:  # fmt: skip
    """True when some greedy rule of the family (module docstring) makes the mode grow.

    Parameters
    ----------
    lam, P, D, tau1, tau2, delta, dt, duration
        As for :func:`greedy_switching_grows` (the same test of growth, per member).
    weights
        The cross weights b of the energies pumped (any real numbers).
    """
    b = np.asarray(weights, dtype=float)
    lags = [max(int(round(max(t - s * delta, dt) / dt)), 1) for t in (tau1, tau2) for s in (1, -1)]
    depth = max(lags) + 1
    hx, hv = np.ones((depth, b.size)), np.zeros((depth, b.size))
    x, v, late = np.ones(b.size), np.zeros(b.size), np.zeros(b.size)
    steps = int(duration / dt)
    for k in range(steps):
        xa, xb = hx[(k - lags[0]) % depth], hx[(k - lags[1]) % depth]
        va, vb = hv[(k - lags[2]) % depth], hv[(k - lags[3]) % depth]
        w = lam * (b * x + v)  # dV_b/dt grows with w (P x_delayed + D v_delayed)
        xs = np.where(w * (xa - xb) > 0, xa, xb)
        vs = np.where(w * (va - vb) > 0, va, vb)
        v = v + dt * (-P * x - D * v + lam * (P * xs + D * vs))
        x = x + dt * v
        hx[(k + 1) % depth], hv[(k + 1) % depth] = x, v
        if k > steps - int(20.0 / dt):
            late = np.maximum(late, x * x + v * v)
    return bool(np.any(late > 1.0))
