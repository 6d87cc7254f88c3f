"""Delay scheduling: the larger delays that make the formation converge fastest.

The paper closes (Section "Simulation", Figs. 8 and 9) with
*delay scheduling* (Olgac et al.): the hardware fixes the smallest delays,
but the controller may wait longer before it uses what it hears. Inside the
stable region of the CTCR chart, pick the delays at least the hardware ones
whose dominant (rightmost) characteristic root lies furthest left, because
that root sets how fast the team settles into formation.

The search is steered by uncertified, warm-started roots; the pair it ends
at is recomputed with the certified :func:`~delayform.analysis.roots.dominant.dominant_root`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from delayform._validation import check_delay, validated
from delayform.analysis.roots.dominant import SETTLING_FACTOR, checked_factors, dominant_root, dominant_root_map
from delayform.analysis.roots.warm import WarmRightmost
from delayform.characteristic import CharacteristicFactor
from delayform.errors import DelayError, InputError, NoStableDelaysError
from delayform.topology import Topology

__all__ = ["DelaySchedule", "schedule_delays"]


@validated()
@dataclass(frozen=True)
class DelaySchedule:
    """Delays chosen by delay scheduling (paper Section "Simulation", Fig. 9).

    Attributes
    ----------
    tau1, tau2
        The scheduled delays, each at least its hardware value.
    root
        The dominant root there (Re < 0).
    factor
        The factor it belongs to.
    hardware_root
        The dominant root at the hardware delays ``tau_min`` (for comparison;
        may be unstable).
    """

    tau1: float
    tau2: float
    root: complex
    factor: CharacteristicFactor
    hardware_root: complex
    #: the actuation delay tau_a (s) the delays were scheduled for (0: the paper's model)
    actuation_delay: float = 0.0

    @property
    def time_constant(self) -> float:
        """1 / |Re root|."""
        return 1.0 / abs(self.root.real)

    @property
    def settling_time(self) -> float:
        """Predicted 2 % settling time ln(50) / |Re root| (about 3.9 time constants).

        The disagreement decays like e^{Re(root) t}; it is below 2 % of its
        initial size after ln(50) / |Re root| seconds (the dominant root alone,
        constant factors of the other modes ignored).
        """
        return SETTLING_FACTOR / abs(self.root.real)


def _delay_pair(name: str, value: object) -> tuple[float, float]:
    try:
        a, b = value  # type: ignore[misc]
    except (TypeError, ValueError) as exc:
        raise DelayError(f"{name} must be a pair (tau1, tau2)") from exc
    return check_delay(f"{name}[0]", a), check_delay(f"{name}[1]", b)


@validated()
def schedule_delays(
    topology: Topology,
    P: float,
    D: float,
    *,
    tau_min: tuple[float, float],
    tau_max: tuple[float, float],
    grid: int = 41,
    actuation_delay: float = 0.0,
) -> DelaySchedule:
    """Delays within ``tau_min <= tau <= tau_max`` that minimise Re(dominant root).

    Delays can only be increased from the hardware ones (delay scheduling,
    paper Section "Simulation"): a ``grid x grid`` dominant-root map of the box
    finds the basins, then Nelder-Mead (derivative-free, since the dominant
    real part is a max of smooth branches) refines the three best stable grid
    points inside the box.

    Parameters
    ----------
    topology
        Communication topology with a spanning tree.
    P, D
        Positive gains.
    tau_min
        Hardware delays (t1, t2): the smallest allowed.
    tau_max
        Largest allowed delays (T1, T2).
    grid
        Points per axis of the coarse map (>= 2).
    actuation_delay
        tau_a >= 0 (s): schedule for robots that apply their commands that late
        (every root in three delays; the local search then evaluates the
        certified :func:`dominant_root` at each step, slower than the warm start).

    Returns
    -------
    DelaySchedule
        Never an unstable pair.

    Raises
    ------
    NoStableDelaysError
        When no grid point of the box is stable.
    DelayError
        For negative delays or tau_min > tau_max.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> s = schedule_delays(paper_six(), 1.0, 0.5, tau_min=(1.0, 2.0), tau_max=(4.0, 6.0), grid=9)
    >>> s.root.real < 0 and s.tau1 >= 1.0 and s.tau2 >= 2.0
    True
    """
    lo = _delay_pair("tau_min", tau_min)
    hi = _delay_pair("tau_max", tau_max)
    if lo[0] > hi[0] or lo[1] > hi[1]:
        raise DelayError(f"tau_min {lo} must not exceed tau_max {hi}")
    if isinstance(grid, bool) or not isinstance(grid, (int, np.integer)) or grid < 2:
        raise InputError(f"grid must be an integer >= 2, got {grid!r}")
    fs = checked_factors(topology, P, D)
    ta = check_delay("actuation_delay", actuation_delay)
    ax1 = np.linspace(lo[0], hi[0], grid) if hi[0] > lo[0] else np.array([lo[0]])
    ax2 = np.linspace(lo[1], hi[1], grid) if hi[1] > lo[1] else np.array([lo[1]])
    coarse = dominant_root_map(topology, P, D, ax1, ax2, actuation_delay=ta)
    if not coarse.stable.any():
        raise NoStableDelaysError(
            f"no stable delay pair in the box tau1 in [{lo[0]:g}, {hi[0]:g}], "
            f"tau2 in [{lo[1]:g}, {hi[1]:g}] (grid {grid} x {grid}); allow larger delays (tau_max) "
            "or choose other gains"
        )

    objective: Callable[[NDArray[np.float64]], float]
    if ta > 0.0:  # no warm start in three delays: the certified root at every step of the search

        def certified(x: NDArray[np.float64]) -> float:
            t = np.clip(x, lo, hi)
            return float(dominant_root(topology, P, D, float(t[0]), float(t[1]), actuation_delay=ta).root.real)

        objective = certified
    else:
        # uncertified, warm-started values steer the search; the pair it ends at is certified below
        warm = WarmRightmost(fs)

        def steered(x: NDArray[np.float64]) -> float:
            t = np.clip(x, lo, hi)
            return warm(float(t[0]), float(t[1]))

        objective = steered

    flat = np.argsort(coarse.real, axis=None)[:2]
    candidates = [coarse.best()[:2]]
    for k in flat:
        i, j = np.unravel_index(int(k), coarse.real.shape)
        if coarse.real[i, j] < 0.0:
            candidates.append((float(ax1[i]), float(ax2[j])))
    best_x, best_f = np.array(candidates[0]), float(coarse.real.min())
    for x0 in candidates[1:]:
        x, fx = _refine(objective, np.array(x0), np.array(lo), np.array(hi), grid)
        if fx < best_f:
            best_x, best_f = x, fx
    final = dominant_root(topology, P, D, float(best_x[0]), float(best_x[1]), actuation_delay=ta)
    if not final.root.real <= float(coarse.real.min()):
        # the search was steered by uncertified values into something worse: keep the grid's best
        t1b, t2b, _ = coarse.best()
        final = dominant_root(topology, P, D, t1b, t2b, actuation_delay=ta)
    if not final.is_stable:  # cannot happen: the grid's best is certified and stable
        raise NoStableDelaysError("delay scheduling ended on an unstable pair")
    hardware = dominant_root(topology, P, D, lo[0], lo[1], actuation_delay=ta)
    return DelaySchedule(final.tau1, final.tau2, final.root, final.factor, hardware.root, ta)


def _refine(
    objective: Callable[[NDArray[np.float64]], float],
    x0: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64], grid: int,
) -> tuple[NDArray[np.float64], float]:
    """Nelder-Mead from a grid point over the free axes of the box (a flat axis stays fixed)."""
    from scipy.optimize import minimize

    free = hi > lo
    if not free.any():
        return x0, objective(x0)

    def along(y: NDArray[np.float64]) -> float:
        x = x0.copy()
        x[free] = y
        return objective(x)

    step = (hi - lo)[free] / grid
    y0 = x0[free]
    simplex = np.vstack([y0] + [y0 + np.eye(y0.size)[k] * step[k] for k in range(y0.size)])
    res = minimize(
        along, y0, method="Nelder-Mead", bounds=list(zip(lo[free], hi[free], strict=True)),
        options={"initial_simplex": np.clip(simplex, lo[free], hi[free]), "xatol": 1e-6,
                 "fatol": 1e-10, "maxfev": 60},
    )
    x = x0.copy()
    x[free] = np.clip(res.x, lo[free], hi[free])
    return x, float(res.fun)
