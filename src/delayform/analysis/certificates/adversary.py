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

:func:`periodic_switching_adversary` turns the greedy rules into a *proof* of
instability and then improves on them. The greedy signals settle into a
periodic switching pattern; one period of it, repeated, is a periodic linear
delay system whose discretized monodromy matrix (the map of the whole history
over one period, semi-implicit Euler with step dt) has a dominant Floquet
multiplier mu: |mu| > 1 proves that the periodic signal destabilizes the
(discretized) mode, with growth rate ln|mu| / period. The pattern is then
refined by Pontryagin's maximum principle on the discretized system (the
method of successive approximations): the forward solution along the dominant
right eigenvector and the backward adjoint along the left one give, at every
step, the first-order change of mu for each admissible delayed value; each
step takes the delay (anywhere in [tau - delta, tau + delta], not only at the
ends) that maximizes it, and the iteration stops at a fixed point (an
extremal) or when |mu| stops growing. :func:`replay_growth_rate` re-checks a
signal with another integrator (classical Runge-Kutta at a finer step, the
delayed values interpolated linearly in the stored history).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy.sparse.linalg import eigs

from delayform.errors import InputError

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["greedy_switching_grows", "weighted_switching_grows", "WEIGHTS", "SwitchingSignal",
           "floquet_multiplier", "periodic_switching_adversary", "replay_growth_rate"]

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
    late, _, _ = _greedy_family(lam, P, D, tau1, tau2, delta, weights, dt, duration, record=False)
    return bool(np.any(late > 1.0))


def _lags(tau1: float, tau2: float, delta: float, dt: float, *, inward: bool = False) -> tuple[int, int, int, int]:
    """The lags (in steps) of tau1 - delta, tau1 + delta, tau2 - delta, tau2 + delta, at least one step.

    Rounded to the nearest step (the greedy rules' convention, which may step outside the
    interval by up to dt / 2) or, with ``inward``, into the interval: then every delay used
    lies in [tau - delta, tau + delta] (the effective deviation is delta rounded down to the
    grid of dt around tau).
    """
    if not inward:
        lo1, hi1, lo2, hi2 = (max(int(round(max(t - s * delta, dt) / dt)), 1) for t in (tau1, tau2) for s in (1, -1))
        return lo1, hi1, lo2, hi2
    ends = [(math.ceil((t - delta) / dt - 1e-9), math.floor((t + delta) / dt + 1e-9)) for t in (tau1, tau2)]
    (lo1, hi1), (lo2, hi2) = [(max(lo, 1), max(hi, lo, 1)) for lo, hi in ends]
    return lo1, hi1, lo2, hi2


def _greedy_family(lam: float, P: float, D: float, tau1: float, tau2: float, delta: float,
                   weights: tuple[float, ...], dt: float, duration: float, *, record: bool,
                   inward: bool = False) -> tuple[NDArray[np.float64], NDArray[np.int32] | None, NDArray[np.int32] | None]:  # fmt: skip
    """Run the weighted greedy rules side by side: late energies and, when recorded, the lags chosen (steps x members)."""
    b = np.asarray(weights, dtype=float)
    lags = _lags(tau1, tau2, delta, dt, inward=inward)
    depth = max(lags) + 1
    hx, hv = np.ones((depth, b.size)), np.zeros((depth, b.size))
    x, v, late = np.ones(b.size), np.zeros(b.size), np.zeros(b.size)
    steps = int(duration / dt)
    j1 = np.empty((steps, b.size), np.int32) if record else None
    j2 = np.empty((steps, b.size), np.int32) if record else None
    for k in range(steps):
        xa, xb = hx[(k - lags[0]) % depth], hx[(k - lags[1]) % depth]
        va, vb = hv[(k - lags[2]) % depth], hv[(k - lags[3]) % depth]
        w = lam * (b * x + v)  # dV_b/dt grows with w (P x_delayed + D v_delayed)
        pick_x, pick_v = w * (xa - xb) > 0, w * (va - vb) > 0
        xs, vs = np.where(pick_x, xa, xb), np.where(pick_v, va, vb)
        if j1 is not None and j2 is not None:
            j1[k], j2[k] = np.where(pick_x, lags[0], lags[1]), np.where(pick_v, lags[2], lags[3])
        v = v + dt * (-P * x - D * v + lam * (P * xs + D * vs))
        x = x + dt * v
        hx[(k + 1) % depth], hv[(k + 1) % depth] = x, v
        if k > steps - int(20.0 / dt):
            late = np.maximum(late, x * x + v * v)
    return late, j1, j2


@dataclass(frozen=True)
class SwitchingSignal:
    """A periodic delay signal for one mode, with the dominant Floquet multiplier it gives.

    Attributes
    ----------
    lam, P, D, tau1, tau2, delta
        The mode (eigenvalue of C), the gains, the nominal delays and the deviation.
    dt
        The step (s): h1(t) = ``h1[k]`` for k dt <= t mod period < (k + 1) dt, the same for h2.
    h1, h2
        One period of the delays (s), each in [tau - delta, tau + delta] (multiples of dt).
    multiplier
        The dominant Floquet multiplier of the semi-implicit Euler discretization with step dt.
    """

    lam: float
    P: float
    D: float
    tau1: float
    tau2: float
    delta: float
    dt: float
    h1: NDArray[np.float64]
    h2: NDArray[np.float64]
    multiplier: complex

    @property
    def period(self) -> float:
        """The period of the signal (s)."""
        return self.h1.size * self.dt

    @property
    def rate(self) -> float:
        """The growth rate ln|multiplier| / period (1/s): positive when the signal destabilizes the mode."""
        return math.log(abs(self.multiplier)) / self.period

    @property
    def grows(self) -> bool:
        """True when the dominant multiplier lies outside the unit circle."""
        return abs(self.multiplier) > 1.0

    def plot(self, ax: Axes | None = None) -> Axes:
        """The two delays over one period of the signal, inside their interval tau +- delta."""
        import matplotlib.pyplot as plt

        if ax is None:
            ax = plt.figure().add_subplot()
        t = np.arange(self.h1.size) * self.dt
        for h, tau, name in ((self.h1, self.tau1, "h1 (positions)"), (self.h2, self.tau2, "h2 (velocities)")):
            line = ax.step(t, h, where="post", label=name)[0]
            ax.fill_between(t, tau - self.delta, tau + self.delta, color=line.get_color(), alpha=0.1)
        ax.set_xlabel("t within one period (s)")
        ax.set_ylabel("delay (s)")
        ax.set_title(f"lam = {self.lam:g}: multiplier {abs(self.multiplier):.4f} per {self.period:.3g} s")
        ax.legend(loc="best", fontsize="small")
        return ax


def _march(lam: float, P: float, D: float, j1: NDArray[np.int_], j2: NDArray[np.int_], depth: int, dt: float,
           start: NDArray[np.generic]) -> tuple[NDArray[np.generic], NDArray[np.generic]]:  # fmt: skip
    """Semi-implicit Euler over one period from histories ``start`` ((2 depth, m): x then v, oldest first)."""
    n = j1.size
    X = np.empty((depth + n, start.shape[1]), start.dtype)
    V = np.empty_like(X)
    X[:depth], V[:depth] = start[:depth], start[depth:]
    for k in range(n):
        i = depth - 1 + k
        V[i + 1] = V[i] + dt * (-P * X[i] - D * V[i] + lam * (P * X[i - j1[k]] + D * V[i - j2[k]]))
        X[i + 1] = X[i] + dt * V[i + 1]
    return X, V


def _adjoint(lam: float, P: float, D: float, j1: NDArray[np.int_], j2: NDArray[np.int_], depth: int, dt: float,
             final: NDArray[np.complex128]) -> NDArray[np.complex128]:  # fmt: skip
    """Reverse mode of :func:`_march` for the functional final . (x, v) at the end: its derivative per step's acceleration."""
    n = j1.size
    gx, gv = np.zeros(depth + n, complex), np.zeros(depth + n, complex)
    gx[n:], gv[n:] = final[:depth], final[depth:]
    ga = np.empty(n, complex)
    for k in range(n - 1, -1, -1):
        i = depth - 1 + k
        gx[i] += gx[i + 1]
        gv[i + 1] += dt * gx[i + 1]
        gv[i] += gv[i + 1]
        ga[k] = g = dt * gv[i + 1]
        gx[i] -= P * g
        gv[i] -= D * g
        gx[i - j1[k]] += lam * P * g
        gv[i - j2[k]] += lam * D * g
    return ga


def _monodromy(lam: float, P: float, D: float, j1: NDArray[np.int_], j2: NDArray[np.int_], depth: int,
               dt: float) -> NDArray[np.float64]:  # fmt: skip
    """The map of the discretized history (x then v, depth samples each) over one period."""
    X, V = _march(lam, P, D, j1, j2, depth, dt, np.eye(2 * depth))
    return np.vstack([X[-depth:], V[-depth:]])


def _multiplier(lam: float, P: float, D: float, j1: NDArray[np.int_], j2: NDArray[np.int_], depth: int,
                dt: float) -> complex:  # fmt: skip
    """The dominant Floquet multiplier of the discretized mode under the periodic lags j1, j2 (steps)."""
    return _dominant(_monodromy(lam, P, D, j1, j2, depth, dt), vectors=False)[0]


def _dominant(M: NDArray[np.float64], *, vectors: bool) -> tuple[complex, NDArray[np.complex128] | None]:
    """The eigenvalue of largest modulus (Arnoldi; dense for small matrices) and, when asked, its eigenvector."""
    if M.shape[0] < 16:
        mu, vec = np.linalg.eig(M)
        q = int(np.argmax(np.abs(mu)))
        return complex(mu[q]), (vec[:, q].astype(complex) if vectors else None)
    start = np.ones(M.shape[0])  # a fixed start: the same answer every run
    if vectors:
        mu, vec = eigs(M, k=4, which="LM", tol=1e-12, v0=start)
        q = int(np.argmax(np.abs(mu)))
        return complex(mu[q]), vec[:, q]
    mu = eigs(M, k=4, which="LM", tol=1e-12, v0=start, return_eigenvectors=False)
    return complex(mu[int(np.argmax(np.abs(mu)))]), None


def floquet_multiplier(lam: float, P: float, D: float, h1: NDArray[np.float64], h2: NDArray[np.float64],
                       dt: float) -> complex:  # fmt: skip
    """The dominant Floquet multiplier of one mode under periodic delays, semi-implicit Euler with step dt.

    Parameters
    ----------
    lam, P, D
        The (real) eigenvalue of C and the gains: x'' = -P x - D x' + lam (P x(t - h1) + D x'(t - h2)).
    h1, h2
        One period of each delay (s), one value per step, positive multiples of dt (rounded to them).
    dt
        The step (s).

    Returns
    -------
    complex
        The eigenvalue of largest modulus of the map of the history over one period.

    Examples
    --------
    >>> import numpy as np
    >>> mu = floquet_multiplier(-0.637, 1.0, 0.5, np.full(100, 2.0), np.full(100, 1.0), 0.01)
    >>> round(float(np.log(abs(mu))), 3)  # one second at the constant delays: the rightmost root's real part
    -0.031
    """
    j1, j2 = _steps(h1, dt), _steps(h2, dt)
    if j1.size != j2.size or j1.size == 0:
        raise InputError("h1 and h2 must be non-empty and of the same length (one value per step)")
    depth = int(max(j1.max(), j2.max())) + 1
    return _multiplier(lam, P, D, j1, j2, depth, dt)


def _steps(h: NDArray[np.float64], dt: float) -> NDArray[np.int_]:
    """Delays (s) as whole steps, at least one."""
    if not dt > 0:
        raise InputError(f"dt must be positive, got {dt}")
    h = np.asarray(h, dtype=float)
    if h.ndim != 1 or not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise InputError("the delays must be a one-dimensional array of positive finite values (s)")
    return np.maximum(np.rint(h / dt).astype(int), 1)


def _periods(j: NDArray[np.int32], most: int = 4) -> list[int]:
    """Candidate periods (steps) of a settled switching sequence: spans of 2, 4, ... switches at its end."""
    switches = np.flatnonzero(np.diff(j))
    return [int(switches[-1] - switches[-1 - 2 * m]) for m in range(1, most + 1) if 2 * m < switches.size]


def _improve(lam: float, P: float, D: float, j1: NDArray[np.int_], j2: NDArray[np.int_],
             bounds: tuple[int, int, int, int], dt: float) -> tuple[NDArray[np.int_], NDArray[np.int_]]:  # fmt: skip
    """One step of the maximum principle: the delays that maximize the first-order change of the dominant multiplier."""
    lo1, hi1, lo2, hi2 = bounds
    depth = max(hi1, hi2) + 1
    M = _monodromy(lam, P, D, j1, j2, depth, dt)
    mu, z = _dominant(M, vectors=True)
    nu, w = _dominant(M.T, vectors=True)  # the left eigenvector: M^T w = mu w (mu real or nu = mu or its conjugate)
    assert z is not None and w is not None
    if abs(nu - mu) > abs(nu - np.conj(mu)):
        w = np.conj(w)
    X, V = _march(lam, P, D, j1, j2, depth, dt, z[:, None].astype(complex))
    ga = _adjoint(lam, P, D, j1, j2, depth, dt, w)  # d(w . z_end) per step's acceleration; d mu = that / (w . z)
    c = np.conj(mu) / (w @ z) * lam * ga  # d|mu| is proportional to Re(c * the delayed value)
    rows = depth - 1 + np.arange(j1.size)
    c1, c2 = np.arange(lo1, hi1 + 1), np.arange(lo2, hi2 + 1)
    score1 = np.real(c[:, None] * P * X[rows[:, None] - c1[None, :], 0])
    score2 = np.real(c[:, None] * D * V[rows[:, None] - c2[None, :], 0])
    return c1[np.argmax(score1, axis=1)], c2[np.argmax(score2, axis=1)]


def periodic_switching_adversary(lam: float, P: float, D: float, tau1: float, tau2: float, delta: float, *,
                                 dt: float = 0.005, weights: tuple[float, ...] = WEIGHTS,
                                 duration: float = 240.0, members: int = 3,
                                 iterations: int = 8) -> SwitchingSignal:  # fmt: skip
    """A periodic delay signal that destabilizes the mode if the search finds one (module docstring).

    The weighted greedy rules (:func:`weighted_switching_grows`) are run and their
    signals recorded; for the ``members`` that end with the most energy, the last
    2, 4, 6 or 8 switches of either delay give candidate periods, each scored by
    its Floquet multiplier; the best is refined by the maximum principle.

    Parameters
    ----------
    lam, P, D, tau1, tau2, delta
        The (real) eigenvalue of C (not the centroid's 1), the gains, the nominal delays and the
        deviation: each delay varies in [tau - delta, tau + delta] (at least dt), on the grid of
        dt (so the signal's own deviation is delta rounded down to that grid).
    dt, duration
        The step (s) of the discretization and the length (s) of the greedy runs.
    weights
        The cross weights of the greedy rules (:data:`WEIGHTS`).
    members
        How many greedy rules (those ending with the most energy) give candidate periods.
    iterations
        The most steps of the maximum principle.

    Returns
    -------
    SwitchingSignal
        The signal with the largest multiplier found; ``grows`` proves instability of the
        discretized mode under it (re-check it with :func:`replay_growth_rate`).

    Examples
    --------
    >>> s = periodic_switching_adversary(-0.637, 1.0, 0.5, 2.0, 1.0, 0.16, dt=0.01, members=1, iterations=2)
    >>> s.grows, s.rate > 0.003, round(s.period, 1)  # two oscillations of the mode
    (True, True, 12.5)
    """
    if not (dt > 0 and delta >= 0 and duration > 20.0 and members >= 1 and iterations >= 0):
        raise InputError("need dt > 0, delta >= 0, duration > 20 s, members >= 1 and iterations >= 0")
    if lam == 1.0:
        raise InputError("lam = 1 is the centroid's mode: it settles at any constant, so it has no growth to find")
    bounds = _lags(tau1, tau2, delta, dt, inward=True)
    depth = max(bounds) + 1
    late, j1, j2 = _greedy_family(lam, P, D, tau1, tau2, delta, weights, dt, duration, record=True, inward=True)
    assert j1 is not None and j2 is not None
    best: tuple[float, complex, NDArray[np.int_], NDArray[np.int_]] | None = None
    for m in np.argsort(late)[::-1][:members]:
        for n in sorted(set(_periods(j1[:, m]) + _periods(j2[:, m]))) or [int(round(tau1 / dt))]:
            s1, s2 = j1[-n:, m].astype(int), j2[-n:, m].astype(int)
            mu = _multiplier(lam, P, D, s1, s2, depth, dt)
            if best is None or math.log(abs(mu)) / n > best[0]:
                best = (math.log(abs(mu)) / n, mu, s1, s2)
    assert best is not None
    _, mu, s1, s2 = best
    for _ in range(iterations):
        n1, n2 = _improve(lam, P, D, s1, s2, bounds, dt)
        if np.array_equal(n1, s1) and np.array_equal(n2, s2):
            break
        trial = _multiplier(lam, P, D, n1, n2, depth, dt)
        if abs(trial) <= abs(mu):
            break
        s1, s2, mu = n1, n2, trial
    return SwitchingSignal(lam, P, D, tau1, tau2, delta, dt, s1 * dt, s2 * dt, mu)


def replay_growth_rate(signal: SwitchingSignal, *, periods: int = 40, refine: int = 4) -> float:
    """The growth rate of the mode under the signal, by classical Runge-Kutta (an independent re-check).

    The signal is repeated ``periods`` times from the history x = 1, v = 0, with step
    ``signal.dt / refine``, the delayed values interpolated linearly in the stored
    solution; the rate is ln(E2 / E1) / (2 t) from the peak energies x^2 + v^2 over
    the last period of each half (t apart).

    Parameters
    ----------
    signal
        A signal from :func:`periodic_switching_adversary` (or built by hand).
    periods
        How many periods to run (at least 4).
    refine
        Runge-Kutta steps per step of the signal.

    Returns
    -------
    float
        The measured growth rate (1/s), to compare with ``signal.rate``.
    """
    if periods < 4 or refine < 1:
        raise InputError("need periods >= 4 and refine >= 1")
    lam, P, D, h = signal.lam, signal.P, signal.D, signal.dt / refine
    n = signal.h1.size * refine
    d1, d2 = np.repeat(signal.h1, refine), np.repeat(signal.h2, refine)
    lead = int(math.ceil(max(d1.max(), d2.max()) / h)) + 2
    total = periods * n
    X, V = np.ones(lead + total + 1), np.zeros(lead + total + 1)

    def delayed(arr: NDArray[np.float64], t: float) -> float:  # t in units of h, relative to index lead
        u = lead + t
        i = min(int(math.floor(u)), lead + total - 1)
        return arr[i] + (u - i) * (arr[i + 1] - arr[i])

    def accel(k: int, t: float, x: float, v: float) -> float:
        return -P * x - D * v + lam * (P * delayed(X, t - d1[k % n] / h) + D * delayed(V, t - d2[k % n] / h))

    for k in range(total):
        i = lead + k
        x, v = X[i], V[i]
        a1 = accel(k, k, x, v)
        a2 = accel(k, k + 0.5, x + 0.5 * h * v, v + 0.5 * h * a1)
        a3 = accel(k, k + 0.5, x + 0.5 * h * (v + 0.5 * h * a1), v + 0.5 * h * a2)
        a4 = accel(k, k + 1.0, x + h * (v + 0.5 * h * a2), v + h * a3)
        X[i + 1] = x + h / 6.0 * (v + 2 * (v + 0.5 * h * a1) + 2 * (v + 0.5 * h * a2) + (v + h * a3))
        V[i + 1] = v + h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
    E = X[lead:] ** 2 + V[lead:] ** 2
    half = (periods // 2) * n
    e1, e2 = E[half - n:half].max(), E[total - n:total].max()
    return math.log(e2 / e1) / (2.0 * (total - half) * h)
