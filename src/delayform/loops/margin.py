"""The exact delay margin of a loop and its certificate (see :mod:`delayform.loops`)."""

from __future__ import annotations

import base64
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import NDArray

from delayform._display import FigureRepr, control_plot
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
    """The exact delay margin of 1 + L(s) e^{-(delay + tau) s} and how it was certified.

    Phase margins are in degrees, as in python-control (``phase_margin_rad``
    in radians).

    Attributes
    ----------
    tau
        The delay margin (s), the extra delay the loop tolerates: the closed
        loop is stable for every extra delay in [0, tau) beyond its own
        dead time ``delay`` and has a root on the imaginary axis at tau;
        ``math.inf`` when it is stable for every delay (|L(j omega)| < 1 for
        all omega > 0).
    omega
        The frequency (rad/s) of the root on the axis at ``tau``; None when
        ``tau`` is infinite.
    phase_margin
        The phase margin (degrees) of that crossover, of the loop with its
        dead time; None when ``tau`` is infinite.
    crossovers
        Every gain crossover, sorted by its first extra delay.
    closed_loop_poles
        The roots of D + N, the closed loop without delay.
    certified
        True when a certified root count confirmed no root right of the axis
        at the loop's own delay and just below ``delay + tau``.
    certificate
        What was checked, in words.
    quasi_polynomial
        D(s) + N(s) e^{-tau1 s}, or for a 2 x 2 loop
        g1 + g2 e^{-tau1 s} + g4 e^{-2 tau1 s} (paper, eq. 5, tau2 unused),
        tau1 the total delay.
    delay
        The dead time already in the loop (s), 0 unless given.
    """

    tau: float
    omega: float | None
    phase_margin: float | None
    crossovers: tuple[Crossover, ...]
    closed_loop_poles: NDArray[np.complex128] = field(repr=False)
    certified: bool
    certificate: str = field(repr=False)
    quasi_polynomial: TwoDelayQuasiPolynomial = field(repr=False)
    delay: float = 0.0

    @property
    def phase_margin_rad(self) -> float | None:
        """The phase margin in radians; None when ``tau`` is infinite."""
        return None if self.phase_margin is None else math.radians(self.phase_margin)

    @property
    def total(self) -> float:
        """delay + tau: the total delay at which the first root reaches the axis."""
        return self.delay + self.tau

    def is_stable(self, tau: float) -> bool:
        """True when the loop with ``tau`` more delay than its own is below the margin (stable); DelayError for a negative delay."""
        return check_delay("tau", tau) < self.tau

    def _repr_html_(self) -> str:
        rows = "".join(
            f"<tr><td>{c.omega:.6g}</td><td>{c.phase_margin:.4g}</td>"
            f"<td>{c.tau:.6g}</td><td>{c.root_tendency:+d}</td></tr>"
            for c in self.crossovers
        )
        image = base64.b64encode(self._repr_png_()).decode("ascii")
        own = f" beyond the loop's own {self.delay:.6g} s" if self.delay else ""
        return (
            f'<img src="data:image/png;base64,{image}" alt="Nyquist plot of the loop"/>'
            f"<p><b>delay margin</b> tau = {self.tau:.8g} s{own}"
            + (f" (root at j {self.omega:.6g})" if self.omega is not None else "")
            + f"; certified: {self.certified}</p>"
            "<table><tr><th>omega (rad/s)</th><th>phase margin (deg)</th><th>first extra delay (s)</th>"
            f"<th>RT</th></tr>{rows}</table>"
        )

    def plot(self, ax: Axes | None = None) -> Any:
        """Nyquist plot with the unit circle and every crossover (:func:`delayform.plots.plot_delay_margin`).

        Returns python-control's ``ControlPlot`` (``.lines``, ``.axes``,
        ``.figure``, ``.legend``) when python-control is installed, else a
        :class:`delayform._display.LoopPlot` with the same attributes; on
        the given ``ax`` when one is passed.
        """
        from delayform.plots import plot_delay_margin

        return control_plot(lambda axes: plot_delay_margin(self, ax=axes), ax)


def _closed_loop_poles(qp: TwoDelayQuasiPolynomial) -> NDArray[np.complex128]:
    closed = _trim(qp.delay_free().real)
    return npoly.polyroots(closed) if closed.size > 1 else np.zeros(0, complex)


def _count_right(qp: TwoDelayQuasiPolynomial, tau: float) -> int:
    """Certified number of roots with Re s > 0 at delay tau; -1 when a root on the axis stops the count."""
    try:
        return count_roots_right_of(qp, tau, 0.0, 0.0)
    except NotConvergedError:
        return -1


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
    count = _count_right(qp, 0.0)
    if count != 0:
        raise UnstableLoopError(
            f"{name} is not stable without delay: a certified root count finds {count} root(s) of "
            "1 + L(s) on or right of the imaginary axis"
        )
    return True


def _require_stable_at_delay(
    qp: TwoDelayQuasiPolynomial, delay: float, crossovers: tuple[Crossover, ...], retarded: bool, name: str
) -> bool:
    """Raise UnstableLoopError unless 1 + L(s) e^{-delay s} is stable; True when a certified count says so.

    A retarded loop is counted at ``delay`` itself (argument principle), so
    a loop unstable without delay but stabilized by its dead time is
    accepted. A neutral loop has no certified count: it must be stable
    without delay, and every crossing in (0, delay] moves a pair of roots
    across the axis in the direction of its root tendency.
    """
    for c in crossovers:
        if min(c.tau, c.period - c.tau) <= 1e-12 * c.period:
            raise UnstableLoopError(
                f"{name} has a root on the imaginary axis at j {c.omega:.6g} with its delay {delay:.6g} s "
                "(phase margin 0 there): it is marginally stable, with no margin left"
            )
    if retarded:
        count = _count_right(qp, delay)
        if count != 0:
            found = "cannot be certified (a root too near the axis)" if count < 0 else f"finds {count} root(s)"
            raise UnstableLoopError(
                f"{name} is not stable with its delay {delay:.6g} s: a certified root count of "
                f"1 + L(s) e^{{-{delay:.6g} s}} on or right of the imaginary axis {found}"
            )
        return True
    _require_stable_at_zero(_closed_loop_poles(qp), qp, retarded, name)
    # the delays at which crossover c put j omega on the axis before, delay + c.tau - k period in (0, delay]
    # (root tendency is the same at every k: Re ds/dtau changes with tau only by an imaginary term)
    passed = [(c, math.ceil((delay + c.tau) / c.period) - 1) for c in crossovers]
    if any(c.root_tendency == 0 and n for c, n in passed):
        raise UnstableLoopError(
            f"{name} is neutral and a root touches the axis before its delay {delay:.6g} s without crossing: "
            "its stability there is not decided"
        )
    unstable = 2 * sum(c.root_tendency * n for c, n in passed)
    if unstable != 0:
        raise UnstableLoopError(
            f"{name} is not stable with its delay {delay:.6g} s: {unstable} root(s) crossed into the right "
            "half-plane before it"
        )
    return False


def _loop_terms(loop: object, name: str) -> tuple[TwoDelayQuasiPolynomial, bool, str]:
    """The quasi-polynomial of 1 + L e^{-tau s}, whether it is retarded, and how its crossings are found."""
    if _is_mimo(loop):
        qp = _mimo_terms(_as_state_space(loop, name), name, max_power=2)
        # strictly proper (checked): every delayed term has lower degree
        return qp, True, "every crossing from the resultant of q(j omega, z) and its conjugate reciprocal in z"
    num, den = loop_polynomials(loop, name=name)
    _check_proper(num, den, name)
    qp = TwoDelayQuasiPolynomial(den, num)
    return qp, num.size < den.size, "every gain crossover from the exact polynomial |D(j omega)|^2 = |N(j omega)|^2"


@validated(LoopError)
def delay_margin(loop: object, *, delay: float = 0.0, name: str = "loop") -> DelayMargin:
    """The exact delay margin of the loop 1 + L(s) e^{-(delay + tau) s} (module docstring).

    Parameters
    ----------
    loop
        The loop gain L without its dead time: a python-control
        ``TransferFunction`` or ``StateSpace`` (SISO, continuous time,
        proper, or a square 2 x 2 strictly proper loop), or ``(num, den)``
        in decreasing powers of s. python-control has no delay object
        (``control.pade`` approximates one), so a dead time is given as
        ``delay``.
    delay
        The dead time already in the loop (s), e.g. theta of a
        first-order-plus-dead-time plant: the loop is L(s) e^{-delay s} and
        the margin is the extra delay it tolerates.
    name
        How error messages call the loop.

    Returns
    -------
    DelayMargin
        The margin, the crossover that sets it, every crossover (phase
        margins in degrees, of the loop with its dead time) and the
        certificate.

    Raises
    ------
    LoopError
        For an object that is not a SISO continuous-time loop, an improper
        loop, or a biproper one with |L(j inf)| >= 1.
    DelayError
        For a negative or non-finite ``delay``.
    UnstableLoopError
        When the loop is not stable with its dead time (without delay when
        ``delay`` is 0).

    Examples
    --------
    The loop 2 / (s + 1): crossover sqrt(3), phase margin 120 degrees, so
    the margin is 2 pi / (3 sqrt 3) (Hayes 1950, s + a + b e^{-tau s}):

    >>> m = delay_margin(([2.0], [1.0, 1.0]))
    >>> round(m.tau, 10), round(2 * math.pi / (3 * math.sqrt(3)), 10), round(m.phase_margin, 10), m.certified
    (1.2091995762, 1.2091995762, 120.0, True)

    A PI controller 1 + 1/s on the plant e^{-0.3 s} / (s + 1) is the loop
    e^{-0.3 s} / s: crossover 1 rad/s, so pi / 2 - 0.3 s are left:

    >>> pi_loop = ([1.0, 1.0], [1.0, 1.0, 0.0])  # (s + 1) / (s (s + 1))
    >>> round(delay_margin(pi_loop, delay=0.3).tau, 12), round(math.pi / 2 - 0.3, 12)
    (1.270796326795, 1.270796326795)
    """
    delay = check_delay("delay", delay)
    qp, retarded, what = _loop_terms(loop, name)
    poles = _closed_loop_poles(qp)
    crossovers = _crossovers(qp, delay)
    if delay:
        counted = _require_stable_at_delay(qp, delay, crossovers, retarded, name)
        stable = f"stable with the loop's delay {delay:.10g} s" + (" (certified root count 0)" if counted else "")
    else:
        counted = _require_stable_at_zero(poles, qp, retarded, name)
        stable = "stable at tau = 0"
    common = dict(crossovers=crossovers, closed_loop_poles=poles, quasi_polynomial=qp, delay=delay)
    if not crossovers:
        _confirm_no_crossing(qp, name)
        text = f"{what}: none, so no root reaches the axis at any delay; {stable}"
        # with a dead time, ``stable`` already says how stability at it was established
        how = "" if delay else (" (closed-loop poles and a certified root count)" if counted else " (closed-loop poles)")
        return DelayMargin(tau=math.inf, omega=None, phase_margin=None, certified=counted,
                           certificate=text + how, **common)  # fmt: skip
    first = crossovers[0]
    certified, below = False, delay + first.tau * (1.0 - CERTIFY_OFFSET)
    if retarded:
        certified = _count_right(qp, below) == 0
    certificate = (
        f"{stable}; {what} ({len(crossovers)} found); the first root on the axis is "
        f"j {first.omega:.10g} at "
        + (f"{first.tau:.10g} s more delay (total {delay + first.tau:.10g} s); " if delay else f"tau = {first.tau:.10g}; ")
        + (
            f"certified root count 0 right of the axis at tau = {below:.10g}"
            if certified
            else ("neutral loop: no root count, the margin rests on |L(j inf)| < 1 (continuity of the roots)"
                  if not retarded else "the certified root count just below could not confirm it")
        )
    )
    return DelayMargin(tau=first.tau, omega=first.omega, phase_margin=first.phase_margin,
                       certified=certified, certificate=certificate, **common)  # fmt: skip
