"""Gain design for a python-control plant under delayed PD feedback.

The plant G = N / D (any SISO loop :func:`delayform.loops.loop_polynomials`
reads) is driven by the paper's protocol structure (paper, eq. 1): a
proportional channel that sees the output after tau1 and a derivative
channel that sees its rate after tau2,

    u(t) = -P y(t - tau1) - D y'(t - tau2),

so the closed loop is 1 + P G e^{-tau1 s} + D s G e^{-tau2 s} = 0, the
quasi-polynomial (paper, eq. 5)

    q(s) = D(s) + P N(s) e^{-tau1 s} + D s N(s) e^{-tau2 s}.

It is retarded when G has relative degree at least 2 (otherwise the rate
channel makes it neutral, refused). The design maximizes the decay rate
-Re of the rightmost root over the box of gains: the certified rightmost
root (:func:`delayform.analysis.roots.rightmost_root`) on a grid of the box,
then Nelder-Mead from the best grid point, clipped to the box; the result is
certified by an argument-principle count of zero roots right of its own
abscissa (plus a relative 1e-6), or says it could not be.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from delayform._display import FigureRepr, control_plot
from delayform._validation import check_delay, check_positive, validated
from delayform.analysis.roots import count_roots_right_of, rightmost_root
from delayform.characteristic import TwoDelayQuasiPolynomial
from delayform.errors import GainError, LoopError, NoStableGainsError, NotConvergedError
from delayform.loops import loop_polynomials

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["LoopGainDesign", "design_loop_gains", "pd_loop_quasi_polynomial"]


def _plant(plant: object) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    num, den = loop_polynomials(plant, name="plant")
    if not np.any(num):
        raise LoopError("plant has a zero numerator: no gain reaches it")
    if den.size - num.size < 2:
        raise LoopError(
            f"plant has relative degree {den.size - num.size}; delayed PD feedback needs at least 2 "
            "(the rate channel D s G would make the closed loop of neutral type)"
        )
    return num, den


def _qp(num: NDArray[np.float64], den: NDArray[np.float64], P: float, D: float) -> TwoDelayQuasiPolynomial:
    return TwoDelayQuasiPolynomial(den, P * num, D * np.concatenate([[0.0], num]))


@validated(LoopError)
def pd_loop_quasi_polynomial(plant: object, P: float, D: float) -> TwoDelayQuasiPolynomial:
    """D(s) + P N(s) e^{-tau1 s} + D s N(s) e^{-tau2 s} for the plant N / D (module docstring).

    Parameters
    ----------
    plant
        A SISO plant as read by :func:`delayform.loops.loop_polynomials`,
        of relative degree at least 2.
    P, D
        The proportional and derivative gains.

    Returns
    -------
    TwoDelayQuasiPolynomial
        For :func:`~delayform.crossing_map` and :func:`~delayform.rightmost_root`.

    Raises
    ------
    LoopError
        For a plant of relative degree below 2 or a zero numerator.
    GainError
        For a gain that is not positive and finite.

    Examples
    --------
    The double integrator 1 / s^2 gives the paper's factor of lam = -1 without its
    undelayed D s + P: s^2 + P e^{-tau1 s} + D s e^{-tau2 s}.

    >>> q = pd_loop_quasi_polynomial(([1.0], [1.0, 0.0, 0.0]), 1.0, 0.5)
    >>> [c.real.tolist() for c in q.coefficients[:3]]
    [[0.0, 0.0, 1.0], [1.0], [0.0, 0.5]]
    """
    num, den = _plant(plant)
    return _qp(num, den, check_positive("P", P, GainError), check_positive("D", D, GainError))


def _rightmost(q: TwoDelayQuasiPolynomial, t1: float, t2: float) -> complex:
    if t1 == 0.0 and t2 == 0.0:  # no delay: a polynomial, its roots directly (and exactly so at a double root)
        roots = np.polynomial.polynomial.polyroots(q.delay_free())
        top = roots[np.argmax(roots.real)]
        return complex(top.real, abs(top.imag))
    return rightmost_root(q, t1, t2)


def _bounds(name: str, bounds: object) -> tuple[float, float]:
    try:
        lo, hi = (float(b) for b in bounds)  # type: ignore[union-attr]
    except (TypeError, ValueError) as exc:
        raise GainError(f"{name} must be a pair (low, high) of positive numbers, got {bounds!r}") from exc
    if not (np.isfinite(lo) and np.isfinite(hi) and 0.0 < lo < hi):
        raise GainError(f"{name} must satisfy 0 < low < high (finite), got ({lo}, {hi})")
    return lo, hi


@validated(LoopError)
@dataclass(frozen=True, eq=False)
class LoopGainDesign(FigureRepr):
    """Gains P, D for a plant under delayed PD feedback, and the evidence.

    Attributes
    ----------
    P, D
        The designed gains.
    abscissa
        Re of the rightmost closed-loop root at those gains (negative: stable).
    root
        That root (Im >= 0).
    tau1, tau2
        The delays designed for.
    certified
        True when an argument-principle count confirmed no root right of
        ``abscissa`` (plus 1e-6 relative).
    certificate
        What was checked, in words.
    P_values, D_values, grid_abscissa
        The grid of the search: ``grid_abscissa[i, j]`` at ``(P_values[j], D_values[i])``.
    """

    P: float
    D: float
    abscissa: float
    root: complex
    tau1: float
    tau2: float
    certified: bool
    certificate: str = field(repr=False)
    P_values: NDArray[np.float64] = field(repr=False)
    D_values: NDArray[np.float64] = field(repr=False)
    grid_abscissa: NDArray[np.float64] = field(repr=False)

    @property
    def decay_rate(self) -> float:
        """-abscissa (1/s): how fast the slowest mode decays."""
        return -self.abscissa

    def plot(self, ax: Axes | None = None) -> Any:
        """The abscissa over the gain grid, its zero contour and the design (:func:`delayform.plots.plot_loop_gains`).

        Returns python-control's ``ControlPlot`` (``.lines``, ``.axes``,
        ``.figure``, ``.legend``) when python-control is installed, else a
        :class:`delayform._display.LoopPlot` with the same attributes.
        """
        from delayform.plots import plot_loop_gains

        return control_plot(lambda axes: plot_loop_gains(self, ax=axes), ax)


@validated(LoopError)
def design_loop_gains(
    plant: object,
    tau1: float,
    tau2: float,
    *,
    P_bounds: tuple[float, float],
    D_bounds: tuple[float, float],
    grid: int = 11,
) -> LoopGainDesign:
    """The P, D in the box that make u = -P y(t - tau1) - D y'(t - tau2) decay fastest on the plant.

    Parameters
    ----------
    plant
        A SISO plant (python-control ``TransferFunction`` / ``StateSpace``
        or ``(num, den)``) of relative degree at least 2.
    tau1, tau2
        The delays of the proportional and of the derivative channel (s).
    P_bounds, D_bounds
        The box of gains, each ``(low, high)`` with 0 < low < high.
    grid
        Grid points per gain for the global search (at least 3).

    Returns
    -------
    LoopGainDesign
        The gains, the rightmost root there and its certificate.

    Raises
    ------
    LoopError
        For a plant that is not a SISO loop of relative degree >= 2.
    GainError
        For a malformed box or grid.
    DelayError
        For a negative or non-finite delay.
    NoStableGainsError
        When no gain pair of the search is stable.

    Examples
    --------
    >>> d = design_loop_gains(([1.0], [1.0, 0.0, 0.0]), 0.3, 0.2, P_bounds=(0.1, 2), D_bounds=(0.1, 2), grid=5)
    >>> d.abscissa < 0, d.certified
    (True, True)
    """
    num, den = _plant(plant)
    t1, t2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    (p_lo, p_hi), (d_lo, d_hi) = _bounds("P_bounds", P_bounds), _bounds("D_bounds", D_bounds)
    if isinstance(grid, bool) or not isinstance(grid, (int, np.integer)) or grid < 3:
        raise GainError(f"grid must be an integer >= 3, got {grid!r}")
    Ps, Ds = np.linspace(p_lo, p_hi, int(grid)), np.linspace(d_lo, d_hi, int(grid))

    def abscissa(x: NDArray[np.float64]) -> float:
        P, D = float(np.clip(x[0], p_lo, p_hi)), float(np.clip(x[1], d_lo, d_hi))
        return _rightmost(_qp(num, den, P, D), t1, t2).real

    table = np.array([[abscissa(np.array([P, D])) for P in Ps] for D in Ds])
    i, j = np.unravel_index(int(np.argmin(table)), table.shape)
    start = np.array([Ps[j], Ds[i]])
    # the abscissa is continuous but not smooth (where two roots tie): a derivative-free refinement
    step = np.array([(p_hi - p_lo), (d_hi - d_lo)]) / (grid - 1)
    simplex = np.array([start, start + [step[0] / 2, 0.0], start + [0.0, step[1] / 2]])
    best = minimize(abscissa, start, method="Nelder-Mead",
                    options={"initial_simplex": simplex, "maxfev": 60, "xatol": 1e-4, "fatol": 1e-6})  # fmt: skip
    x = start if best.fun > table[i, j] else best.x
    P, D = float(np.clip(x[0], p_lo, p_hi)), float(np.clip(x[1], d_lo, d_hi))
    q = _qp(num, den, P, D)
    root = _rightmost(q, t1, t2)
    if root.real >= 0.0:
        raise NoStableGainsError(
            f"no gains in P {P_bounds}, D {D_bounds} stabilize the plant at (tau1, tau2) = ({t1:g}, {t2:g}): "
            f"the best rightmost root found has Re = {root.real:.4g}"
        )
    line = root.real + 1e-6 * max(1.0, abs(root))
    try:
        certified = count_roots_right_of(q, t1, t2, line) == 0
    except NotConvergedError:
        certified = False
    certificate = (
        f"argument principle: no root right of Re s = {line:.6g}" if certified
        else "cannot decide: the count right of the design's abscissa did not confirm it"
    )  # fmt: skip
    return LoopGainDesign(P=P, D=D, abscissa=float(root.real), root=complex(root), tau1=t1, tau2=t2,
                          certified=certified, certificate=certificate, P_values=Ps, D_values=Ds,
                          grid_abscissa=table)  # fmt: skip
