"""A safety filter: control barrier functions that keep the robots' bodies apart.

Method (Wang, Ames & Egerstedt, "Safety barrier certificates for collisions-free
multirobot systems", IEEE T-RO 33(3), 2017; as Robotarium filters commands)
--------------------------------------------------------------------------
The formation controller (eq. protocol) asks robot i for the Cartesian
acceleration ``u_hat_i``; for ideal robots the feedback linearization eq.
transform2 makes ``x_i'' = u_i`` exactly, so the filter works on ``u``. For a
pair at distance ``d = |dp|``, ``dp = x_i - x_j``, ``n = dp / d``,
``dv = x_i' - x_j'`` and safe distance ``Ds`` (the sum of the radii plus
:attr:`BarrierFilter.margin`), the barrier ``h = d - Ds`` has relative degree
two: ``h' = n.dv``, ``h'' = (|dv|^2 - (n.dv)^2) / d + n.(u_i - u_j)``.
Requiring ``h'' + 2 k h' + k^2 h >= 0`` (a double pole at ``-k``,
:attr:`BarrierFilter.rate`) keeps ``h >= 0`` for all time once
``h' + k h >= 0`` holds (an exponential CBF: ``h(t) >= (h0 + (h0' + k h0) t) e^{-k t}``).
It is linear in the commands::

    -n.(u_i - u_j) <= c_ij = (|dv|^2 - (n.dv)^2) / d + 2 k n.dv + k^2 (d - Ds).

(The distance, not its square, as the barrier: then far-apart robots are
not braked for accelerating towards each other, since ``k^2 (d - Ds)``
grows with d as fast as the distance the acceleration can close.)

Decentralized, as in Wang et al.: each robot takes half of every pair's
constraint, ``-n.u_i <= c_ij / 2``, so robot i's command is the closest
to ``u_hat_i`` in a polygon of half-planes of the plane (the two halves sum
to the pair's constraint, so the pair is safe whatever the other does within
its own half). That QP in two variables is solved exactly in closed form:
its minimiser is ``u_hat_i``, the projection onto one constraint line, or
the intersection of two lines; every candidate is formed for all robots at
once (NumPy, padded to the largest neighbour count) and the closest
feasible one is taken. A polygon can be empty (a robot squeezed from
opposite sides, its own halves in conflict): then the robots solve the
pairs' full constraints jointly, ``min sum_i |u_i - u_hat_i|^2`` over all
commands (a sparse QP solved by Clarabel), which is always feasible for
``x'' = u``, and the run's safety report counts those steps.

What each robot knows, and when
-------------------------------
Its own position and velocity, and the positions and velocities of the
robots within its sensing range, **now** (on-board sensing, no delay and no
network: the formation controller's delays tau1 and tau2 do not enter the
filter). Teams above 64 robots keep a Verlet list of neighbours from a
KD-tree, every pair within ``reach = Ds + 2 v_max / k + 1`` m (v_max twice
the fastest robot when the list was built; it is rebuilt when a robot goes
faster or has moved half the list's skin). A pair farther apart than
``reach`` closes at most at ``2 v_max <= k (d - Ds)``, so it still has
``h' + k h >= 0`` when it enters the list, which is what the barrier needs
from then on.

What it guarantees
------------------
For ideal robots and double integrators (``x'' = u``) the continuous-time
filter keeps every pair at least ``Ds`` apart whenever its polygons are non-empty;
the RK4 step resolves it to its (second) order, and the margin absorbs that.
Robots with actuator limits cannot always execute the filtered command: the
filter is then applied before the limits and contacts are still checked.
Where no constraint binds, ``u = u_hat``: the run is the unfiltered run.

Actuation delay
---------------
A command made at t is executed at t + tau_a, so the filter is applied at the
state predicted for then from the commands in flight
(:meth:`~delayform.simulation.actuation.CommandBuffer.predict`, exact for
double integrators but on the last grid interval, where the previous command is
held). The guarantee above then holds from t = tau_a on (before it nothing the
filter decides is executed). The filter is assumed to know every robot's
commands in flight (a central filter, or robots that broadcast them). Robots with
limits under an actuation delay refuse the filter: their prediction would have to
pass through the saturations (docs/theory.md, "The safety filter with an actuation delay").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform._validation import validated
from delayform.errors import SimulationInputError

__all__ = ["SAFETY_FILTERS", "BarrierFilter", "FilteredAgent", "SafetyReport", "barrier_commands", "check_safety"]

_Array = NDArray[np.float64]

#: what ``simulate(..., safety=...)`` accepts by name
SAFETY_FILTERS = ("barrier",)

#: teams up to this size test every pair; larger ones use a KD-tree per step
_ALL_PAIRS = 64

#: rounds of the active set before every side of the polygons is taken
_ROUNDS = 3

#: a constraint counts as satisfied within this relative tolerance
_FEASIBLE = 1e-9


@validated(SimulationInputError)
@dataclass(frozen=True)
class BarrierFilter:
    """The control-barrier-function safety filter (module doc).

    Attributes
    ----------
    rate
        k (1/s): the barrier's double pole; larger lets robots approach faster
        and brake harder. Default 2.
    margin
        Added to the sum of the radii (m): the safe distance ``Ds``. Default 0.02.
    """

    rate: float = 2.0
    margin: float = 0.02

    def __post_init__(self) -> None:
        for name in ("rate", "margin"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise SimulationInputError(f"safety.{name} must be a number, got {value!r}")
            if not math.isfinite(value) or value < 0 or (name == "rate" and value == 0):
                raise SimulationInputError(f"safety.{name} must be finite and {'positive' if name == 'rate' else 'non-negative'}, got {value!r}")
            object.__setattr__(self, name, float(value))


def check_safety(safety: object) -> BarrierFilter | None:
    """``None``, a :class:`BarrierFilter`, or a name of :data:`SAFETY_FILTERS` -> the filter (or None).

    Parameters
    ----------
    safety
        What ``simulate(..., safety=...)`` or ``Robot(safety=...)`` was given.

    Raises
    ------
    SimulationInputError
        For anything else.
    """
    if safety is None or isinstance(safety, BarrierFilter):
        return safety
    if isinstance(safety, str) and safety in SAFETY_FILTERS:
        return BarrierFilter()
    raise SimulationInputError(f"unknown safety filter {safety!r}; choose one of {', '.join(SAFETY_FILTERS)} or None")


class _Neighbours:
    """Who senses whom: every pair in small teams, a Verlet list from a KD-tree in large ones.

    The list holds the pairs within ``reach + skin`` of the positions it was
    built at and is rebuilt once any robot has moved ``skin / 2`` from
    there, so it always contains every pair within ``reach`` (two robots
    each ``skin / 2`` closer). ``reach = Ds + 2 v_max / k + 1`` m, with
    v_max the fastest robot when the list was built (module doc).
    """

    def __init__(self, n: int, safe: float, rate: float) -> None:
        self.n, self.safe, self.rate = n, safe, rate
        self.anchor: _Array | None = None
        self.vmax = 0.0
        self.pairs = np.column_stack(np.triu_indices(n, k=1)).astype(np.intp)
        self.skin = 0.0

    def __call__(self, x: _Array, v: _Array) -> NDArray[np.intp]:
        if self.n <= _ALL_PAIRS:
            return self.pairs
        vmax = float(np.sqrt((v**2).sum(axis=1)).max())
        moved = math.inf if self.anchor is None else float(np.abs(x - self.anchor).max()) * math.sqrt(2.0)
        if moved > 0.5 * self.skin or vmax > self.vmax:
            from scipy.spatial import cKDTree

            self.vmax = max(2.0 * vmax, 0.1)
            reach = self.safe + 2.0 * self.vmax / self.rate + 1.0
            self.skin = 0.5 * reach
            self.anchor = x.copy()
            found = cKDTree(x).query_pairs(reach + self.skin, output_type="ndarray")
            self.pairs = found.astype(np.intp).reshape(-1, 2)
        return self.pairs


def barrier_commands(
    x: _Array, v: _Array, u_hat: _Array, safe: float, rate: float, pairs: NDArray[np.intp] | None = None
) -> tuple[_Array, NDArray[np.bool_], NDArray[np.bool_]]:
    """The filtered commands: each robot's closest point to ``u_hat`` in its polygon (module doc).

    Parameters
    ----------
    x, v, u_hat
        ``(n, 2)`` positions, velocities and the formation controller's accelerations.
    safe
        Safe distance Ds (m).
    rate
        k of the barrier (1/s).
    pairs
        ``(p, 2)`` pairs that sense each other; default all pairs.

    Returns
    -------
    (u, active, infeasible)
        ``(n, 2)`` commands; ``(n,)`` where the filter changed the command; where
        the robot's polygon was empty (then every command comes from the joint QP, :func:`_joint_qp`).
    """
    n = x.shape[0]
    if pairs is None:
        pairs = np.column_stack(np.triu_indices(n, k=1)).astype(np.intp)
    if n < 2 or pairs.shape[0] == 0:
        return u_hat, np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    i, j = pairs[:, 0], pairs[:, 1]
    dp, dv = x[i] - x[j], v[i] - v[j]
    d = np.maximum(np.hypot(dp[:, 0], dp[:, 1]), 1e-12)
    nx, ny = dp[:, 0] / d, dp[:, 1] / d  # (1, 0) for robots on the same spot: any direction will do
    nx = np.where(d > 1e-12, nx, 1.0)
    dvx, dvy = dv[:, 0], dv[:, 1]
    along = nx * dvx + ny * dvy
    c = (dvx * dvx + dvy * dvy - along * along) / d + 2.0 * rate * along + rate * rate * (d - safe)
    half = 0.5 * c
    # robot i: -n.u_i <= c / 2; robot j: +n.u_j <= c / 2
    ui, uj = u_hat[i], u_hat[j]
    push_i = nx * ui[:, 0] + ny * ui[:, 1]
    push_j = nx * uj[:, 0] + ny * uj[:, 1]
    dp = np.column_stack([nx, ny])  # from here on the constraints' normal
    tol = _FEASIBLE * (1.0 + np.abs(half))
    bad_i, bad_j = half + push_i < -tol, half - push_j < -tol
    if not (bad_i.any() or bad_j.any()):
        return u_hat, np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    u, active, squeezed = _solve_polygons(pairs, dp, half, u_hat, bad_i, bad_j)
    if squeezed.any():
        u = _joint_qp(pairs, dp, c, u_hat)
        active = np.abs(u - u_hat).max(axis=1) > 0.0
    return u, active, squeezed


def _joint_qp(pairs: NDArray[np.intp], normal: _Array, c: _Array, u_hat: _Array) -> _Array:
    """All commands at once: ``min sum |u_i - u_hat_i|^2`` s.t. ``-n_ij.(u_i - u_j) <= c_ij`` for every pair.

    Used when a robot's own halves conflict. Always feasible for
    ``x'' = u``: pushing every robot away from the centroid,
    ``u_i = beta (x_i - x_bar)``, makes every left side ``-beta |dp|``,
    below any ``c_ij`` for beta large. Solved by Clarabel (interior point).
    """
    import clarabel
    import scipy.sparse as sp

    n, m = u_hat.shape[0], pairs.shape[0]
    i, j = pairs[:, 0], pairs[:, 1]
    r = np.repeat(np.arange(m), 4)
    cols = np.column_stack([2 * i, 2 * i + 1, 2 * j, 2 * j + 1]).ravel()
    vals = np.column_stack([-normal, normal]).ravel()
    G = sp.csc_matrix((vals, (r, cols)), shape=(m, 2 * n))
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    solver = clarabel.DefaultSolver(sp.identity(2 * n, format="csc") * 2.0, -2.0 * u_hat.ravel(), G, c,
                                    [clarabel.NonnegativeConeT(m)], settings)  # fmt: skip
    sol = solver.solve()
    if str(sol.status) not in ("Solved", "AlmostSolved"):
        return u_hat  # cannot happen for x'' = u (see above); the run's contacts would show it
    return np.asarray(sol.x, dtype=np.float64).reshape(n, 2)


def _solve_polygons(
    pairs: NDArray[np.intp], dp: _Array, half: _Array, u_hat: _Array, bad_i: NDArray[np.bool_], bad_j: NDArray[np.bool_]
) -> tuple[_Array, NDArray[np.bool_], NDArray[np.bool_]]:
    """Closest point to ``u_hat`` in each violating robot's polygon (module doc), by an active set.

    The polygon of the constraints violated so far is solved exactly
    (:func:`_closest_in_polygons`); its minimiser is also the minimiser over
    all the robot's constraints once it satisfies them all (the smaller
    problem's optimum is a lower bound), else the newly violated ones join
    and it is solved again. Dense teams thus solve polygons of a few sides,
    not of every neighbour.
    """
    n = u_hat.shape[0]
    moving = np.zeros(n, dtype=bool)
    moving[pairs[bad_i, 0]] = True
    moving[pairs[bad_j, 1]] = True
    rows = np.concatenate([pairs[:, 0], pairs[:, 1]])
    A = np.concatenate([-dp, dp])
    b = np.concatenate([half, half])
    keep = moving[rows]  # a violating robot keeps all its constraints
    rows, A, b = rows[keep], A[keep], b[keep]
    use = np.concatenate([bad_i, bad_j])[keep]
    tol = _FEASIBLE * (1.0 + np.abs(b))
    u = u_hat.copy()
    squeezed = np.zeros(n, dtype=bool)
    rounds = 0
    while True:
        u_new, empty = _closest_in_polygons(rows[use], A[use], b[use], u_hat, n)
        u[moving] = u_new[moving]
        squeezed |= empty
        if squeezed.any():  # the joint QP takes over (barrier_commands): no need to go on
            return u, moving, squeezed
        violated = ((A * u[rows]).sum(axis=1) - b > tol) & ~use & ~squeezed[rows]
        if not violated.any():
            return u, moving, squeezed
        rounds += 1
        # after a few rounds take every side at once: as exact, and the rounds stay bounded
        use |= violated if rounds < _ROUNDS else np.ones_like(use)


def _closest_in_polygons(
    rows: NDArray[np.intp], A: _Array, b: _Array, u_hat: _Array, n: int
) -> tuple[_Array, NDArray[np.bool_]]:
    """For each robot in ``rows``: the point of ``{u : A_k u <= b_k}`` closest to its ``u_hat``.

    The minimiser of a 2-D QP is ``u_hat``, the projection on one line or the
    intersection of two; all are formed at once (padded to the most sides)
    and the closest feasible one is taken. Returns the commands (``u_hat``
    where a robot has no row) and where a polygon is empty.
    """
    order = np.argsort(rows, kind="stable")
    rows, A, b = rows[order], A[order], b[order]
    movers, robot_of = np.unique(rows, return_inverse=True)
    counts = np.bincount(robot_of, minlength=movers.size)
    K = int(counts.max())
    slot = np.arange(rows.size) - np.repeat(np.cumsum(counts) - counts, counts)
    M = movers.size
    Ap = np.zeros((M, K, 2))
    bp = np.zeros((M, K))
    real = np.zeros((M, K), dtype=bool)  # padding rows are no constraint
    Ap[robot_of, slot] = A
    bp[robot_of, slot] = b
    real[robot_of, slot] = True
    uh = u_hat[movers]
    norm2 = Ap[..., 0] ** 2 + Ap[..., 1] ** 2
    over = Ap[..., 0] * uh[:, None, 0] + Ap[..., 1] * uh[:, None, 1] - bp
    t = np.where(real, over / np.where(real, norm2, 1.0), 0.0)
    cand = [uh[:, None], uh[:, None] - t[..., None] * Ap]
    valid = [np.ones((M, 1), dtype=bool), real]
    if K > 1:
        p, q = np.triu_indices(K, k=1)
        a1, a2, b1, b2 = Ap[:, p], Ap[:, q], bp[:, p], bp[:, q]
        det = a1[..., 0] * a2[..., 1] - a1[..., 1] * a2[..., 0]
        ok = real[:, p] & real[:, q] & (np.abs(det) > 1e-12 * (norm2[:, p] + norm2[:, q]))
        d = np.where(ok, det, 1.0)
        vx = (b1 * a2[..., 1] - b2 * a1[..., 1]) / d
        vy = (a1[..., 0] * b2 - a2[..., 0] * b1) / d
        cand.append(np.stack([vx, vy], axis=-1))
        valid.append(ok)
    C = np.concatenate(cand, axis=1)  # (M, candidates, 2)
    ok_c = np.concatenate(valid, axis=1)
    lhs = C[..., 0, None] * Ap[:, None, :, 0] + C[..., 1, None] * Ap[:, None, :, 1]  # (M, cands, K)
    excess = np.where(real[:, None, :], lhs - bp[:, None, :] - _FEASIBLE * (1.0 + np.abs(bp))[:, None, :], -np.inf)
    feasible = ok_c & (excess.max(axis=2) <= 0.0)
    dist = ((C - uh[:, None]) ** 2).sum(axis=2)
    pick = np.argmin(np.where(feasible, dist, np.inf), axis=1)
    u = u_hat.copy()
    u[movers] = C[np.arange(M), pick]
    empty = np.zeros(n, dtype=bool)
    empty[movers[~feasible.any(axis=1)]] = True
    return u, empty


class FilteredAgent:
    """An agent model whose commands pass through the :class:`BarrierFilter` first.

    Wraps any agent of :mod:`delayform.simulation.robots` (the integrators
    only call ``state0``, ``extras``, ``velocity`` and ``rhs``). Extras
    ``safety_active`` and ``safety_infeasible`` (1.0 where the filter changed
    the robot's command, where its polygon was empty) are saved with the run.
    """

    def __init__(self, agent: Any, safety: BarrierFilter, radius: float) -> None:
        self.agent = agent
        self.safety = safety
        self.safe = 2.0 * radius + safety.margin
        self.state0 = agent.state0
        self.neighbours = _Neighbours(agent.state0.shape[0], self.safe, safety.rate)
        self.extras = tuple(agent.extras) + ("safety_active", "safety_infeasible")
        self.name = agent.name

    def velocity(self, state: _Array) -> _Array:
        return self.agent.velocity(state)

    def rhs(self, state: _Array, u: _Array) -> tuple[_Array, _Array, tuple[_Array, ...]]:
        x, v = state[:, :2], self.agent.velocity(state)
        filtered, active, infeasible = barrier_commands(x, v, u, self.safe, self.safety.rate, self.neighbours(x, v))
        deriv, cart, extra = self.agent.rhs(state, filtered)
        return deriv, cart, tuple(extra) + (active.astype(float), infeasible.astype(float))

    # ---- with an actuation delay: filter the command for the state it will be executed in
    def predict_with(self, buffer: Any) -> None:
        """Filter at the state tau_a ahead, predicted from the commands in flight (module doc, "Actuation delay").

        ``buffer`` is the run's :class:`~delayform.simulation.actuation.CommandBuffer`;
        only double integrators (x'' = the late command) are predicted exactly, so
        :func:`~delayform.simulation.runner.check_actuation` refuses the filter for
        robots with limits under an actuation delay.
        """
        self._buffer = buffer
        n = self.state0.shape[0]
        self._flags = (np.zeros(n), np.zeros(n))

    def command(self, state: _Array, u: _Array) -> _Array:
        """The filtered command, made now and executed tau_a later, at the predicted state then."""
        x, v = self._buffer.predict(state[:, :2], self.agent.velocity(state))
        filtered, active, infeasible = barrier_commands(x, v, u, self.safe, self.safety.rate, self.neighbours(x, v))
        self._flags = (active.astype(float), infeasible.astype(float))
        return self.agent.command(state, filtered)  # type: ignore[no-any-return]

    def apply(self, state: _Array, command: _Array) -> tuple[_Array, _Array, tuple[_Array, ...]]:
        """Execute a (late, already filtered) command; the extras flag the command made last."""
        deriv, cart, extra = self.agent.apply(state, command)
        return deriv, cart, tuple(extra) + self._flags


@validated(SimulationInputError)
@dataclass(frozen=True)
class SafetyReport:
    """When the safety filter acted during a run (from the saved samples).

    Attributes
    ----------
    safe_distance
        The distance ``Ds`` the filter keeps between robot centres (m).
    active
        ``(T, n)`` True where the filter changed robot i's command at saved sample t.
    infeasible
        ``(T, n)`` True where robot i's polygon was empty (the team's joint QP was solved).
    times
        ``(T,)`` the saved times.
    """

    safe_distance: float
    active: NDArray[np.bool_]
    infeasible: NDArray[np.bool_]
    times: _Array

    @property
    def was_active(self) -> bool:
        """Whether the filter changed any command at a saved sample."""
        return bool(self.active.any())

    @property
    def active_fraction(self) -> float:
        """Fraction of saved samples at which it changed at least one robot's command."""
        return float(self.active.any(axis=1).mean()) if self.active.size else 0.0

    @property
    def first_active(self) -> float:
        """First saved time it acted (NaN if never)."""
        hit = np.flatnonzero(self.active.any(axis=1))
        return float(self.times[hit[0]]) if hit.size else math.nan

    @property
    def last_active(self) -> float:
        """Last saved time it acted (NaN if never)."""
        hit = np.flatnonzero(self.active.any(axis=1))
        return float(self.times[hit[-1]]) if hit.size else math.nan

    def sentence(self) -> str:
        """One line for a reader."""
        if not self.was_active:
            return f"the safety filter (distance {self.safe_distance:.3g} m) never had to act"
        text = (
            f"the safety filter (distance {self.safe_distance:.3g} m) acted from t = {self.first_active:.4g} s "
            f"to {self.last_active:.4g} s, at {self.active_fraction:.1%} of the saved steps"
        )
        if self.infeasible.any():
            text += (f"; at {int(self.infeasible.any(axis=1).sum())} saved steps a robot was squeezed "
                     "(its own half-constraints conflicted) and the team solved its joint QP")  # fmt: skip
        return text
