"""Slot assignment: which robot takes which slot of the formation (docs/theory.md, "Slot assignment").

Problem
-------
Robot i given slot ``sigma(i)`` comes to rest at ``z_sigma(i) + a`` (paper,
eq. 13 at rest, :func:`delayform.formation.predicted_final_positions`),
the common offset ``a`` fixed by the weighted centroid: ``w^T x`` obeys the
centroid factor (paper, eq. 4) whatever the slots (``w^T F = 0``), so it comes
to rest at ``m`` (:func:`delayform.formation.final_centroid`) and
``a = m - u(sigma)`` with ``u(sigma) = sum_i w_i z_sigma(i)``. The optimal
assignment minimises the total squared distance each robot travels to its
predicted final position::

    J(sigma) = sum_i |x0_i - z_sigma(i) - m + u(sigma)|^2
             = A(sigma) + n |u(sigma) - u*|^2 + const,

``A(sigma) = sum_i |y_i - z_sigma(i)|^2`` with ``y = x0 - m`` and
``u* = (sum_j z_j - sum_i y_i) / n``.

Method
------
Uniform weights (balanced teams, e.g. undirected ones): ``u`` does not
depend on sigma, and J is a linear assignment problem, solved exactly by
:func:`scipy.optimize.linear_sum_assignment`. Otherwise the quadratic term
couples the slots; ``n |v|^2 = max_lam n (2 lam.v - |lam|^2)`` gives the
Lagrangian dual ``phi(lam) = min_sigma [A + 2 n lam.(u - u*) - n |lam|^2]``,
a linear assignment for each lam (the slot cost gains ``2 n w_i lam.z_j``),
concave in lam and a lower bound on ``min J``. Its maximum is sought by
damped fixed-point steps ``lam <- lam + (u(sigma_lam) - u* - lam) / k``;
every sigma met is a candidate, the best is improved by exchanging pairs of
slots while that lowers J (teams of up to 40 robots), and the result is **certified optimal** when J
meets the dual bound (to ``1e-9`` relative). Otherwise it is the best
assignment found, with the bound and the gap reported.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from delayform._validation import check_shaped, validated
from delayform.errors import FormationError, SimulationInputError
from delayform.formation import centroid_weights, check_formation, final_centroid
from delayform.topology import Topology

__all__ = ["ASSIGNMENTS", "SlotAssignment", "assign_slots", "assignment_cost"]

_Array = NDArray[np.float64]

#: what ``simulate(..., assignment=...)`` accepts
ASSIGNMENTS = ("given", "optimal")

#: dual steps at most
_DUAL_STEPS = 60

#: teams up to this size polish the best assignment by pair exchanges
_EXCHANGE_AGENTS = 40


@validated(SimulationInputError)
@dataclass(frozen=True)
class SlotAssignment:
    """Which slot each robot takes (:func:`assign_slots`).

    Attributes
    ----------
    slots
        ``(n,)``: robot i takes slot ``slots[i]`` of the formation.
    cost
        Total squared distance (m^2) from the start to the predicted final positions.
    lower_bound
        A lower bound on the smallest cost over all assignments (the dual bound).
    certified
        True when ``cost`` meets the bound: no assignment is better.
    final_positions
        ``(n, 2)`` predicted final positions of the robots.
    """

    slots: NDArray[np.intp]
    cost: float
    lower_bound: float
    certified: bool
    final_positions: _Array


def assignment_cost(slots: NDArray[np.intp], desired: _Array, x0: _Array, weights: _Array, rest: _Array) -> float:
    """``J(sigma)``: total squared distance from ``x0`` to the final positions ``z_sigma + m - w^T z_sigma``.

    Parameters
    ----------
    slots
        ``(n,)`` slot of each robot.
    desired
        ``(n, 2)`` formation slots z.
    x0
        ``(n, 2)`` initial positions.
    weights
        ``(n,)`` centroid weights w (:func:`~delayform.formation.centroid_weights`).
    rest
        ``(2,)`` where the weighted centroid comes to rest, m.
    """
    z = desired[slots]
    final = z + (rest - weights @ z)
    return float(((x0 - final) ** 2).sum())


@validated(SimulationInputError)
def assign_slots(
    topology: Topology, P: float, D: float, tau1: float, tau2: float, desired: _Array, x0: _Array, v0: _Array
) -> SlotAssignment:
    """The slots that minimise the total squared distance to the predicted final positions (module doc).

    Parameters
    ----------
    topology
        The team (its centroid weights w decide the final offset).
    P, D, tau1, tau2
        Gains and delays: where the weighted centroid comes to rest
        (paper, eq. 4; without a position delay the centroid drifts with
        the initial velocities, and its start ``w^T x0`` is used).
    desired
        ``(n, 2)`` formation slots.
    x0, v0
        ``(n, 2)`` initial positions and Cartesian velocities.

    Returns
    -------
    SlotAssignment

    Examples
    --------
    Two robots that start on each other's slot swap them:

    >>> from delayform.topology import ring
    >>> z = np.array([[0.0, 0.0], [4.0, 0.0]])
    >>> a = assign_slots(ring(2), 1.0, 0.5, 0.3, 0.2, z, z[::-1] + 0.1, np.zeros((2, 2)))
    >>> a.slots.tolist(), a.certified
    ([1, 0], True)
    """
    n = topology.n
    desired = check_formation(desired, n)
    x0 = check_shaped("x0", x0, (n, 2), SimulationInputError)
    v0 = check_shaped("v0", v0, (n, 2), SimulationInputError)
    w = centroid_weights(topology)
    try:
        m = final_centroid(topology, P, D, tau1, tau2, x0, v0)
    except FormationError:
        m = w @ x0  # no position delay: the centroid drifts; its start stands in for its rest
    y = x0 - m
    A = ((y[:, None, :] - desired[None, :, :]) ** 2).sum(axis=2)
    u_star = (desired.sum(axis=0) - y.sum(axis=0)) / n

    def u_of(slots: NDArray[np.intp]) -> _Array:
        return w @ desired[slots]

    def solve(lam: _Array) -> tuple[NDArray[np.intp], float]:
        cost = A + 2.0 * n * np.outer(w, desired @ lam)
        rows, cols = linear_sum_assignment(cost)
        slots = np.empty(n, dtype=np.intp)
        slots[rows] = cols
        dual = float(cost[rows, cols].sum() - 2.0 * n * lam @ u_star - n * lam @ lam)
        return slots, dual

    def J(slots: NDArray[np.intp]) -> float:
        return assignment_cost(slots, desired, x0, w, m)

    slots, dual0 = solve(np.zeros(2))
    best, best_J = slots, J(slots)
    # J(sigma) - (A(sigma) + n |u - u*|^2) is the same constant for every sigma
    const_shift = best_J - float(A[np.arange(n), slots].sum() + n * np.sum((u_of(slots) - u_star) ** 2))
    bound = dual0 + const_shift
    scale = 1.0 + abs(best_J)
    if np.allclose(w, w[0], rtol=1e-12, atol=0.0):
        bound = best_J  # u(sigma) is the same for every sigma: the linear assignment is exact
    else:
        lam = np.zeros(2)
        for k in range(1, _DUAL_STEPS + 1):
            if best_J - bound <= 1e-9 * scale:
                break
            lam = lam + (u_of(slots) - u_star - lam) / k
            slots, dual = solve(lam)
            bound = max(bound, dual + const_shift)
            value = J(slots)
            if value < best_J:
                best, best_J = slots, value
        best, best_J = _pair_exchanges(best, best_J, J)
    certified = best_J - bound <= 1e-9 * scale
    z = desired[best]
    return SlotAssignment(
        slots=best, cost=best_J, lower_bound=min(bound, best_J), certified=bool(certified),
        final_positions=z + (m - w @ z),
    )  # fmt: skip


def _pair_exchanges(
    slots: NDArray[np.intp], value: float, J: Callable[[NDArray[np.intp]], float]
) -> tuple[NDArray[np.intp], float]:
    """Swap the slots of two robots while that lowers J (first improvement, at most n passes).

    O(n^3) per pass: only for teams of at most :data:`_EXCHANGE_AGENTS` robots.
    """
    n = slots.size
    if n > _EXCHANGE_AGENTS:
        return slots, value
    for _ in range(n):
        improved = False
        for i in range(n - 1):
            for j in range(i + 1, n):
                trial = slots.copy()
                trial[i], trial[j] = slots[j], slots[i]
                cost = J(trial)
                if cost < value - 1e-12 * (1.0 + abs(value)):
                    slots, value, improved = trial, cost, True
        if not improved:
            break
    return slots, value


def check_assignment(name: object) -> str:
    """``name`` if it is one of :data:`ASSIGNMENTS`, else a :class:`SimulationInputError`."""
    if not isinstance(name, str) or name not in ASSIGNMENTS:
        raise SimulationInputError(f"unknown assignment {name!r}; choose one of {', '.join(ASSIGNMENTS)}")
    return name

