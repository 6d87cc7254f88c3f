"""The exact delay margin of a loop and its certificate (see :mod:`delayform.loops`)."""

from __future__ import annotations

import base64
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import NDArray

from delayform._display import FigureRepr
from delayform._validation import check_delay, validated
from delayform.analysis.roots import count_roots_right_of
from delayform.characteristic import TwoDelayQuasiPolynomial
from delayform.errors import LoopError, NotConvergedError, UnstableLoopError
from delayform.loops._read import _as_state_space, _check_proper, _is_mimo, _mimo_terms, _trim, loop_polynomials
from delayform.loops.crossings import Crossover, _confirm_no_crossing, _crossovers

if TYPE_CHECKING:
    from matplotlib.axes import Axes

#: a closed-loop pole with Re s above -POLE_TOL * max(1, |s|) counts as on the axis
POLE_TOL = 1e-10
#: the certifying count is taken at tau * (1 - CERTIFY_OFFSET)
CERTIFY_OFFSET = 1e-6


@validated(LoopError)
@dataclass(frozen=True, eq=False)
class DelayMargin(FigureRepr):
    """The exact delay margin of 1 + L(s) e^{-tau s} and how it was certified.

    Attributes
    ----------
    tau
        The delay margin (s): the closed loop is stable for every delay in
        [0, tau) and has a root on the imaginary axis at tau; ``math.inf``
        when it is stable for every delay (|L(j omega)| < 1 for all omega > 0).
    omega
        The frequency (rad/s) of the root on the axis at ``tau``; None when
        ``tau`` is infinite.
    phase_margin
        The phase margin (rad) of that crossover; None when ``tau`` is infinite.
    crossovers
        Every gain crossover, sorted by its first delay.
    closed_loop_poles
        The roots of D + N, the closed loop at tau = 0.
    certified
        True when a certified root count confirmed no root right of the axis
        just below ``tau`` (or at tau = 0 when ``tau`` is infinite).
    certificate
        What was checked, in words.
    quasi_polynomial
        D(s) + N(s) e^{-tau1 s}, or for a 2 x 2 loop
        g1 + g2 e^{-tau1 s} + g4 e^{-2 tau1 s} (eq. genfactor, tau2 unused).
    """

    tau: float
    omega: float | None
    phase_margin: float | None
    crossovers: tuple[Crossover, ...]
    closed_loop_poles: NDArray[np.complex128] = field(repr=False)
    certified: bool
    certificate: str = field(repr=False)
    quasi_polynomial: TwoDelayQuasiPolynomial = field(repr=False)

    def is_stable(self, tau: float) -> bool:
        """True when the closed loop with delay ``tau`` is below the margin (stable); DelayError for a negative delay."""
        return check_delay("tau", tau) < self.tau

    def _repr_html_(self) -> str:
        rows = "".join(
            f"<tr><td>{c.omega:.6g}</td><td>{math.degrees(c.phase_margin):.4g}</td>"
            f"<td>{c.tau:.6g}</td><td>{c.root_tendency:+d}</td></tr>"
            for c in self.crossovers
        )
        image = base64.b64encode(self._repr_png_()).decode("ascii")
        return (
            f'<img src="data:image/png;base64,{image}" alt="Nyquist plot of the loop"/>'
            f"<p><b>delay margin</b> tau = {self.tau:.8g} s"
            + (f" (root at j {self.omega:.6g})" if self.omega is not None else "")
            + f"; certified: {self.certified}</p>"
            "<table><tr><th>omega (rad/s)</th><th>phase margin (deg)</th><th>first delay (s)</th>"
            f"<th>RT</th></tr>{rows}</table>"
        )

    def plot(self, ax: Axes | None = None) -> Axes:
        """Nyquist plot with the unit circle and every crossover (:func:`delayform.plots.plot_delay_margin`)."""
        from delayform.plots import plot_delay_margin

        return plot_delay_margin(self, ax=ax)


def _closed_loop_poles(qp: TwoDelayQuasiPolynomial) -> NDArray[np.complex128]:
    closed = _trim(qp.delay_free().real)
    return npoly.polyroots(closed) if closed.size > 1 else np.zeros(0, complex)


def _require_stable_at_zero(
    poles: NDArray[np.complex128], qp: TwoDelayQuasiPolynomial, retarded: bool, name: str
) -> bool:
    """Raise UnstableLoopError unless 1 + L(s) is stable; True when a certified count agreed."""
    bad = poles[poles.real >= -POLE_TOL * np.maximum(1.0, np.abs(poles))]
    if bad.size:
        worst = bad[np.argmax(bad.real)]
        raise UnstableLoopError(
            f"{name} is not stable without delay: the closed loop 1 + L(s) has {bad.size} pole(s) on or "
            f"right of the imaginary axis (the rightmost at s = {worst.real + 0.0:.6g}{worst.imag + 0.0:+.6g}j); a delay margin needs a loop "
            "stable at tau = 0"
        )
    if not retarded:
        return False
    try:
        count = count_roots_right_of(qp, 0.0, 0.0, 0.0)
    except NotConvergedError:
        count = -1
    if count != 0:
        raise UnstableLoopError(
            f"{name} is not stable without delay: a certified root count finds {count} root(s) of "
            "1 + L(s) on or right of the imaginary axis"
        )
    return True


@validated(LoopError)
def delay_margin(loop: object, *, name: str = "loop") -> DelayMargin:
    """The exact delay margin of the loop 1 + L(s) e^{-tau s} (module docstring).

    Parameters
    ----------
    loop
        The loop gain L: a python-control ``TransferFunction`` or
        ``StateSpace`` (SISO, continuous time, proper), or ``(num, den)`` in
        decreasing powers of s.
    name
        How error messages call the loop.

    Returns
    -------
    DelayMargin
        The margin, the crossover that sets it, every crossover and the
        certificate.

    Raises
    ------
    LoopError
        For an object that is not a SISO continuous-time loop, an improper
        loop, or a biproper one with |L(j inf)| >= 1.
    UnstableLoopError
        When 1 + L(s) is not stable at tau = 0.

    Examples
    --------
    The loop 2 / (s + 1): crossover sqrt(3), phase margin 2 pi / 3, so the
    margin is 2 pi / (3 sqrt 3) (Hayes 1950, s + a + b e^{-tau s}):

    >>> m = delay_margin(([2.0], [1.0, 1.0]))
    >>> round(m.tau, 10), round(2 * math.pi / (3 * math.sqrt(3)), 10), m.certified
    (1.2091995762, 1.2091995762, True)
    """
    if _is_mimo(loop):
        qp = _mimo_terms(_as_state_space(loop, name), name, max_power=2)
        retarded = True  # strictly proper (checked): every delayed term has lower degree
        what = "every crossing from the resultant of q(j omega, z) and its conjugate reciprocal in z"
    else:
        num, den = loop_polynomials(loop, name=name)
        _check_proper(num, den, name)
        retarded = num.size < den.size
        qp = TwoDelayQuasiPolynomial(den, num)
        what = "every gain crossover from the exact polynomial |D(j omega)|^2 = |N(j omega)|^2"
    poles = _closed_loop_poles(qp)
    counted = _require_stable_at_zero(poles, qp, retarded, name)
    crossovers = _crossovers(qp)
    common = dict(crossovers=crossovers, closed_loop_poles=poles, quasi_polynomial=qp)
    if not crossovers:
        _confirm_no_crossing(qp, name)
        text = f"{what}: none, so no root reaches the axis at any delay; stable at tau = 0"
        how = " (closed-loop poles and a certified root count)" if counted else " (closed-loop poles)"
        return DelayMargin(tau=math.inf, omega=None, phase_margin=None, certified=counted,
                           certificate=text + how, **common)  # fmt: skip
    first = crossovers[0]
    certified, below = False, first.tau * (1.0 - CERTIFY_OFFSET)
    if retarded:
        try:
            certified = count_roots_right_of(qp, below, 0.0, 0.0) == 0
        except NotConvergedError:
            certified = False
    certificate = (
        f"stable at tau = 0; {what} ({len(crossovers)} found); the first root on the axis is "
        f"j {first.omega:.10g} at tau = {first.tau:.10g}; "
        + (
            f"certified root count 0 right of the axis at tau = {below:.10g}"
            if certified
            else ("neutral loop: no root count, the margin rests on |L(j inf)| < 1 (continuity of the roots)"
                  if not retarded else "the certified root count just below could not confirm it")
        )
    )
    return DelayMargin(tau=first.tau, omega=first.omega, phase_margin=first.phase_margin,
                       certified=certified, certificate=certificate, **common)  # fmt: skip
