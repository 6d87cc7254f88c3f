"""Feedback loops from python-control: exact delay margins and quasi-polynomials.

A loop gain L(s) = N(s) / D(s) closed through a delay tau,

    1 + L(s) e^{-tau s} = 0,

has the characteristic quasi-polynomial (paper, eq. 5 with g1 = D, g2 = N)

    q(s) = D(s) + N(s) e^{-tau s}.

Its **delay margin** is the first delay at which a root reaches the
imaginary axis. A root s = j omega exists at some tau only where
|L(j omega)| = 1, the gain crossovers, which are the positive real roots of
the polynomial

    p(omega) = |D(j omega)|^2 - |N(j omega)|^2

(an elimination of tau: exact, no frequency grid). At a crossover omega_c with
phase margin PM = pi + arg L(j omega_c) the root is on the axis exactly at

    tau = (PM mod 2 pi) / omega_c + k 2 pi / omega_c,   k = 0, 1, ...

so the delay margin is the smallest of (PM mod 2 pi) / omega_c over every
crossover (not only the one a Bode plot shows; RobustAndOptimalControl.jl
PR #152 fixed a margin computed from a disk margin instead). The closed loop
must be stable at tau = 0; the roots then move continuously with tau
(retarded case), so none crosses before that delay. The answer is checked
by a certified root count (argument principle,
:func:`delayform.analysis.roots.count_roots_right_of`) of zero just below
the margin. python-control's ``margin`` reports the crossover with the
smallest |PM| only; pm / omega_c there can overstate the delay margin when
another crossover, at a higher frequency, has the smaller delay.

A loop that already contains its dead time theta, L(s) e^{-theta s} (the
first-order-plus-dead-time plant), is ``delay_margin(L, delay=theta)``:
the margin is then the extra delay it tolerates, the first crossing beyond
theta, and stability at theta itself is certified. Phase margins are in
degrees, as python-control gives them; plots return python-control's
``ControlPlot``.

Loops are python-control ``TransferFunction`` or ``StateSpace`` objects
(imported only when such an object is passed; ``pip install
delayform[control]``) or a pair ``(num, den)`` in decreasing powers of s,
python-control's and SciPy's order. A state-space loop keeps its hidden
modes: its denominator is det(sI - A), its numerator det(sI - A + BC) -
det(sI - A) + D det(sI - A) (the matrix determinant lemma), so the
quasi-polynomial is det(sI - A + e^{-tau s} BC), that of the delayed
feedback u(t) = -y(t - tau) itself.

Two loops with their own delays, 1 + L1 e^{-tau1 s} + L2 e^{-tau2 s} (a
plant with a position channel and a velocity channel, as in the paper's eq. 1),
and a 2 x 2 MIMO state-space loop with one delay, det(I + L(s) e^{-tau s}),
are quasi-polynomials of the paper's eq. 5 too: :func:`loop_quasi_polynomial`
builds them for :func:`~delayform.crossing_map` and
:func:`~delayform.rightmost_root`. In a SISO loop delays at the plant's
input and output add up (they commute with L), so one delay tau = tau_in +
tau_out covers both.
"""

from __future__ import annotations

from delayform.loops._read import loop_polynomials
from delayform.loops.characteristic import loop_characteristic, loop_quasi_polynomial
from delayform.loops.crossings import Crossover
from delayform.loops.margin import DelayMargin, delay_margin

__all__ = [
    "Crossover",
    "DelayMargin",
    "delay_margin",
    "loop_quasi_polynomial",
    "loop_polynomials",
    "loop_characteristic",
]
