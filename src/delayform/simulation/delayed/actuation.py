"""Actuation delay in the integrators: a buffer of the commands each robot applies late.

A robot with actuation delay tau_a executes at time t the command it made
at t - tau_a (:attr:`~delayform.simulation.models.robots.Robot.actuation_delay`).
The generic RK4 loop (:func:`delayform.simulation.delayed.integrator.integrate`)
stores the command made at every grid point t_k (from the state at t_k and
its delayed reads) and each stage at ``t_k + c dt`` reads the command of
``t_k + c dt - tau_a`` by **linear interpolation** between the two grid
commands around it (any tau_a >= dt, not only whole steps). Before t = 0
the robots rest in the constant history: the command there is zero
(no acceleration, no turn), so the first command arrives as a jump at
t = tau_a. The interpolation is second order: a run with an actuation
delay is **order 2 when tau_a, tau1 and tau2 are whole numbers of steps**,
and order 1 otherwise (the jump then falls inside a step; the stated order
of :class:`~delayform.simulation.Trajectory` is 2, the tests measure it
on-grid). Without actuation delay nothing changes: the loop builds no buffer.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

_Array = NDArray[np.float64]


class CommandBuffer:
    """Ring buffer of the commands made at the last grid points (module docstring).

    Parameters
    ----------
    delay
        tau_a (s), at least ``dt``.
    dt
        The step (s).
    steps
        Steps of the run: a delay beyond the run reads only the zero history.
    shape
        Shape of one command (robots x components).
    """

    def __init__(self, delay: float, dt: float, steps: int, shape: tuple[int, ...]) -> None:
        self.lag = delay / dt
        self.delay, self.dt = delay, dt
        self.size = min(math.ceil(self.lag), steps + 1) + 3
        self.values = np.zeros((self.size,) + shape)
        self.last = -1  # the grid point of the last command stored

    def store(self, k: int, command: _Array) -> None:
        """Keep the command made at grid point k."""
        self.values[k % self.size] = command
        self.last = k

    def predict(self, x: _Array, v: _Array) -> tuple[_Array, _Array]:
        """Where double integrators at (x, v) now will be tau_a later, executing the commands in flight.

        Now is the grid point t_k of the command about to be made (the last stored is
        t_{k-1}). Over [t_k, t_k + tau_a] each robot executes the commands made over
        [t_k - tau_a, t_k], linear between grid commands (:meth:`read`), zero before the
        first: x'' = a(s) integrates exactly piece by piece (a linear on each piece),

            v(t_k + ta) = v + int a,   x(t_k + ta) = x + ta v + int (ta - sigma) a(sigma) d sigma.

        On the last piece, [t_{k-1}, t_k] in command time, the command being made is not
        known yet: the previous one is held there (an error of O(dt^2) times the change
        of the command over one step, which the filter's margin absorbs).
        """
        k = self.last + 1
        lo = k - self.lag
        edges = np.unique(np.concatenate([[lo], np.arange(math.floor(lo) + 1, k), [float(k)]]))
        a, b = edges[:-1], edges[1:]
        i = np.floor(a + 1e-9).astype(np.int64)  # each piece lies in [i, i + 1] of command time
        u0 = self.values[i % self.size]
        u1 = np.where((i + 1 >= k)[:, None, None], u0, self.values[(i + 1) % self.size])
        before = (i < 0)[:, None, None]  # commands of t < 0: the robots rested (the jump at tau_a)
        u0, u1 = np.where(before, 0.0, u0), np.where(before, 0.0, u1)
        va = u0 + (a - i)[:, None, None] * (u1 - u0)
        vb = u0 + (b - i)[:, None, None] * (u1 - u0)
        dt, ta = self.dt, self.delay
        length = ((b - a) * dt)[:, None, None]
        rest = ((a - lo) * dt)[:, None, None]  # sigma at the piece's start
        dv = (0.5 * length * (va + vb)).sum(axis=0)
        dx = (length * (0.5 * (ta - rest) * (va + vb) - length * (va / 6.0 + vb / 3.0))).sum(axis=0)
        return x + ta * v + dx, v + dv

    def read(self, k: int, c: float) -> _Array:
        """The command made at ``t_k + c dt - tau_a``, linear between grid commands (zero before 0)."""
        m = k + c - self.lag
        i0 = math.floor(m + 1e-9)  # a grid point within rounding reads that point
        frac = m - i0
        # made before t = 0: the robots rested, exactly; the first command is a jump at tau_a, and
        # a stage at the end of a step (c > 0) landing on it sees the left limit, the rest
        if i0 < 0 or (i0 == 0 and c > 0.0 and frac <= 1e-9):
            return np.zeros(self.values.shape[1:])
        v0 = self.values[i0 % self.size]
        if frac <= 1e-9:
            return v0.copy()
        return (1.0 - frac) * v0 + frac * self.values[(i0 + 1) % self.size]
