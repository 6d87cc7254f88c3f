"""A safety filter: control barrier functions that keep the robots' bodies apart.

Method (Wang, Ames & Egerstedt, "Safety barrier certificates for collisions-free
multirobot systems", IEEE T-RO 33(3), 2017; as Robotarium filters commands)
--------------------------------------------------------------------------
The formation controller (paper, eq. 1) asks robot i for the Cartesian
acceleration ``u_hat_i``; for ideal robots the feedback linearization (paper,
eq. 19) makes ``x_i'' = u_i`` exactly, so the filter works on ``u``. For a
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
its own half). That QP in two variables is solved exactly: when ``u_hat``
is outside the polygon the minimiser lies on an edge, and each side's
edge is an interval of its line that the other sides cut out in closed
form, so the closest point of every edge is formed for all robots at once
(NumPy, padded to the most sides) and the closest taken. An active set
keeps the polygons small: a robot first takes its two most violated
sides and adds the most violated of those its answer still breaks (a
minimiser in the plane rests on at most two sides). A polygon can be
empty (a robot squeezed from opposite sides, its own halves in
conflict): then the squeezed robot's cluster (the robots linked to it
by pairs whose halves ``u_hat`` breaks) solves its pairs' full
constraints jointly, ``min sum |u_i - u_hat_i|^2`` (a sparse QP solved by
Clarabel over an active set of constraints), keeping its own half of
every pair with a robot outside; if that is infeasible the whole team
solves it, which is always feasible for ``x'' = u``. The run's safety
report counts those steps.

The joint QP is solved at every RK4 stage, not once a step: holding one
stage's answer over the step would make the command a sample-and-hold
and the guarantee below only first order in dt. What makes it cheap is
that consecutive stages' answers rest on nearly the same constraints.
Each answer is polished exactly (:func:`_polish`): on the rows whose
multipliers outgrow their slacks the KKT conditions are linear, solved by
a sparse LU, and the result is kept only if its multipliers are
non-negative and it meets every constraint (then it is the minimiser, to
rounding, not to Clarabel's tolerance). The next stage first polishes
the rows that bound this answer (and a few it then breaks,
:data:`_GUESS_ROUNDS`); where the KKT check passes Clarabel is not
called, else Clarabel starts its active set from those rows. The answer
is the same either way (the strictly convex QP has one minimiser).

What each robot knows, and when
-------------------------------
Its own position and velocity, and the positions and velocities of the
robots near enough that their constraint can bind, **now** (on-board
sensing, no delay and no network: the formation controller's delays tau1
and tau2 do not enter the filter). Since ``c_ij >= k^2 (d - Ds) - 2 k |dv|``
a pair farther apart than ``Ds + 2 u_max / k^2 + 4 v_max / k`` (the largest
command and speed) meets its halves whatever the robots do, so the filter
is the filter over all pairs, exactly; teams above 64 robots find the
nearer pairs with a Verlet list from a KD-tree (:class:`_Neighbours`).

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
(:meth:`~delayform.simulation.delayed.actuation.CommandBuffer.predict`, exact for
double integrators but on the last grid interval, where the previous command is
held). The guarantee above then holds from t = tau_a on (before it nothing the
filter decides is executed). The filter is assumed to know every robot's
commands in flight (a central filter, or robots that broadcast them). Robots with
limits under an actuation delay refuse the filter: their prediction would have to
pass through the saturations (docs/theory.md, "The safety filter with an actuation delay").
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform._validation import validated
from delayform.errors import SimulationInputError
from delayform.model.robot import SAFETY_FILTERS, BarrierFilter, check_safety
from delayform.simulation.bodies.approach import _complex

__all__ = [
    "SAFETY_FILTERS", "ActiveSet", "BarrierFilter", "FilteredAgent", "SafetyReport", "barrier_commands", "check_safety",
]

_Array = NDArray[np.float64]

#: teams up to this size test every pair; larger ones use a KD-tree per step
_ALL_PAIRS = 64

#: each round of the polygons' active set adds up to this many of a robot's most violated sides
_JOIN = 2

#: and of the joint QP's active set, per robot
_JOIN_QP = 3

#: rounds of the joint QP's polish (:func:`_polish`) that may drop rows of negative multipliers
_POLISH_ROUNDS = 4

#: rounds of the joint QP's warm guess (its last binding rows and those violated since) before Clarabel
_GUESS_ROUNDS = 3

#: a constraint counts as satisfied within this relative tolerance
_FEASIBLE = 1e-9


class _Neighbours:
    """Which pairs can bind: every pair in small teams, a Verlet list from a KD-tree in large ones.

    A pair's half can only bind when ``c_ij / 2 < |u_i|``; since
    ``c_ij >= k^2 (d - Ds) - 2 k |dv|``, no pair farther apart than
    ``need = Ds + 2 u_max / k^2 + 4 v_max / k`` can (``u_max`` the largest
    command asked for or given, ``v_max`` the fastest robot). The list holds
    the pairs within ``radius`` of the positions it was built at, so it
    holds every pair now within ``radius - 2 moved`` (``moved`` the farthest
    any robot went since); when that no longer covers ``need`` it is rebuilt
    with room to spare. The filter is therefore the filter over all pairs,
    exactly; the list only skips the pairs that provably cannot bind.
    """

    def __init__(self, n: int, safe: float, rate: float) -> None:
        self.n, self.safe, self.rate = n, safe, rate
        self.anchor: _Array | None = None
        self.radius = 0.0
        self.pairs = np.column_stack(np.triu_indices(n, k=1)).astype(np.intp)

    def need(self, v: _Array, *commands: _Array) -> float:
        """Distance within which a pair's constraint can bind (class doc)."""
        vmax = float(np.sqrt((v**2).sum(axis=1)).max())
        umax = max(float(np.sqrt((u**2).sum(axis=1)).max()) for u in commands)
        return self.safe + 2.0 * umax / self.rate**2 + 4.0 * vmax / self.rate

    def covers(self, x: _Array, need: float) -> bool:
        """Whether the list holds every pair closer than ``need`` at positions ``x``."""
        if self.n <= _ALL_PAIRS:
            return True
        if self.anchor is None:
            return False
        moved = float(np.sqrt(((x - self.anchor) ** 2).sum(axis=1)).max())
        return need <= self.radius - 2.0 * moved

    def __call__(self, x: _Array, need: float) -> NDArray[np.intp]:
        """The pairs at positions ``x`` (rebuilt when they do not cover ``need``)."""
        if not self.covers(x, need):
            from scipy.spatial import cKDTree

            self.radius = 1.5 * need + 1.0  # room to move before the next rebuild
            self.anchor = x.copy()
            found = cKDTree(x).query_pairs(self.radius, output_type="ndarray")
            self.pairs = found.astype(np.intp).reshape(-1, 2)
        return self.pairs


def _pair_terms(
    x: _Array, v: _Array, u_hat: _Array, pairs: NDArray[np.intp], safe: float, rate: float
) -> tuple[NDArray[np.complex128], _Array, NDArray[np.bool_], NDArray[np.bool_]]:
    """Every pair's unit normal (as x + iy), bound ``c`` and whether ``u_hat`` breaks robot i's / j's half.

    ``x, v, u_hat`` are ``(..., n, 2)``: leading axes are a batch of team states
    (:func:`binds`), the results ``(..., p)``.
    """
    i, j = pairs[:, 0], pairs[:, 1]
    # x + iy: fewer, larger NumPy calls (this runs at every RK4 stage)
    z, w, q = _complex(x), _complex(v), _complex(u_hat)
    dz, dw = z[..., i] - z[..., j], w[..., i] - w[..., j]
    d = np.abs(dz)
    apart = d > 1e-12
    normal = np.where(apart, dz / np.where(apart, d, 1.0), 1.0)  # (1, 0) for robots on the same spot: any will do
    d = np.maximum(d, 1e-12)
    back = normal.conjugate()
    along = (back * dw).real
    c = ((dw.real**2 + dw.imag**2) - along * along) / d + 2.0 * rate * along + rate * rate * (d - safe)
    half = 0.5 * c
    # robot i: -n.u_i <= c / 2; robot j: +n.u_j <= c / 2
    push_i, push_j = (back * q[..., i]).real, (back * q[..., j]).real
    tol = _FEASIBLE * (1.0 + np.abs(half))
    return normal, c, half + push_i < -tol, half - push_j < -tol


def binds(x: _Array, v: _Array, u_hat: _Array, safe: float, rate: float, pairs: NDArray[np.intp]) -> NDArray[np.bool_]:
    """For a batch of team states ``(..., n, 2)``: whether the filter would change any command (``(...,)``).

    The same test as :func:`barrier_commands` makes before it solves anything:
    where it is False the filtered command is ``u_hat`` exactly.
    """
    _, _, bad_i, bad_j = _pair_terms(x, v, u_hat, pairs, safe, rate)
    return (bad_i | bad_j).any(axis=-1)


def barrier_commands(
    x: _Array, v: _Array, u_hat: _Array, safe: float, rate: float, pairs: NDArray[np.intp] | None = None,
    memory: ActiveSet | None = None,
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
    memory
        The joint QP's binding constraints at the previous call (:class:`ActiveSet`),
        updated here; a warm start only, the answer does not depend on it.

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
    normal, c, bad_i, bad_j = _pair_terms(x, v, u_hat, pairs, safe, rate)
    if not (bad_i.any() or bad_j.any()):
        return u_hat, np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    half = 0.5 * c
    dp = np.column_stack([normal.real, normal.imag])  # from here on the constraints' normal
    u, active, squeezed = _solve_polygons(pairs, dp, half, u_hat, bad_i, bad_j)
    if squeezed.any():
        joint, cluster = _joint_qp(pairs, dp, c, u_hat, squeezed, bad_i | bad_j, memory)
        u[cluster] = joint[cluster]
        # the interior point leaves a robot no constraint binds at u_hat to its own rounding
        active = np.abs(u - u_hat).max(axis=1) > _FEASIBLE * (1.0 + np.abs(u_hat).max(axis=1))
    return u, active, squeezed


def _joint_qp(
    pairs: NDArray[np.intp], normal: _Array, c: _Array, u_hat: _Array, squeezed: NDArray[np.bool_],
    in_play: NDArray[np.bool_], memory: ActiveSet | None = None,
) -> tuple[_Array, NDArray[np.bool_]]:
    """The squeezed robots' clusters solve their pairs' full constraints jointly (module doc).

    A cluster is a connected component, containing a squeezed robot, of the
    graph whose edges are the pairs ``in_play`` (a half violated by
    ``u_hat``). Its robots take ``min sum |u_i - u_hat_i|^2`` subject to the
    full constraint ``-n_ij.(u_i - u_j) <= c_ij`` of every pair inside it and
    their own half of every pair with a robot outside (which keeps its
    half, so every pair stays safe). If that is infeasible the whole team
    solves it, which is always feasible for ``x'' = u``: pushing every
    robot away from the centroid, ``u_i = beta (x_i - x_bar)``, makes every
    left side ``-beta |dp|``, below any ``c_ij`` for beta large.

    Returns the cluster's commands (``u_hat`` elsewhere, to be replaced by
    the polygons' answer) and where the cluster is.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = u_hat.shape[0]
    p = pairs[in_play]
    graph = coo_matrix((np.ones(p.shape[0]), (p[:, 0], p[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    cluster = np.isin(label, label[squeezed])
    for members in (cluster, np.ones(n, dtype=bool)):
        u = _cluster_qp(pairs, normal, c, u_hat, members, memory)
        if u is not None:
            return u, members
    return u_hat, cluster  # cannot happen for x'' = u (see above); the run's contacts would show it


class ActiveSet:
    """The pairs whose constraint bound the joint QP's last answer: where the next active set starts.

    Consecutive calls (the RK4 stages of a step, the next step) see nearly the
    same squeezed clusters, so the constraints that bound the last answer are
    nearly those that bind the next; starting from them saves most of the
    active-set rounds, each a Clarabel solve. Only a warm start: the active set
    still ends only when the answer meets every constraint, so the answer is
    the same (to the solver's tolerance) with or without it.
    """

    def __init__(self) -> None:
        self.codes = np.empty(0, dtype=np.int64)  # i * n + j for the pair (i < j)


def _cluster_qp(
    pairs: NDArray[np.intp], normal: _Array, c: _Array, u_hat: _Array, members: NDArray[np.bool_],
    memory: ActiveSet | None = None,
) -> _Array | None:
    """``min sum_members |u_i - u_hat_i|^2`` (:func:`_joint_qp`) by Clarabel, over an active set of constraints.

    Only the constraints violated so far are handed to the solver; when its
    answer meets every other one it is the answer of the whole problem
    (the smaller problem's optimum is a lower bound), else the violated ones
    join. Clarabel's answer is then polished exactly (:func:`_polish`).
    With ``memory`` (:class:`ActiveSet`) the rows that bound the previous
    answer are polished first, with those the polish breaks joining for
    :data:`_GUESS_ROUNDS` rounds; an answer that passes the KKT check (every
    constraint met, multipliers non-negative) is the minimiser and Clarabel
    is not called; else Clarabel's active set starts from those rows.
    Returns the commands (``u_hat`` outside the members) or None when the
    problem is infeasible.
    """
    import clarabel
    import scipy.sparse as sp

    n = u_hat.shape[0]
    i, j = pairs[:, 0], pairs[:, 1]
    take = members[i] | members[j]
    i, j, normal, c = i[take], j[take], normal[take], c[take]
    both = members[i] & members[j]
    # a pair inside: the full constraint; across: the member's half (the other keeps its own)
    right = np.where(both, c, 0.5 * c)
    index = np.full(n, -1)
    index[members] = np.arange(int(members.sum()))
    m_vars = 2 * int(members.sum())
    u = u_hat.copy()

    # the left sides by columns: a row-wise sum over an axis of two is several times slower
    n0, n1 = normal[:, 0].copy(), normal[:, 1].copy()
    in_i, in_j = members[i], members[j]

    def lhs(cmd: _Array) -> _Array:
        c0, c1 = cmd[:, 0], cmd[:, 1]
        side_i = np.where(in_i, -(n0 * c0[i] + n1 * c1[i]), 0.0)
        side_j = np.where(in_j, n0 * c0[j] + n1 * c1[j], 0.0)
        return side_i + side_j

    tol = _FEASIBLE * (1.0 + np.abs(right))
    owner = np.where(members[i], i, j)  # whose constraint it is, for picking a few per robot
    target = u_hat[members].ravel()
    codes = np.minimum(i, j).astype(np.int64) * n + np.maximum(i, j)

    def matrix(rows: NDArray[np.intp]) -> Any:
        """The rows' left sides in the members' variables (sparse, two robots a row at most)."""
        ii, jj, nn = i[rows], j[rows], normal[rows]
        r_parts, c_parts, v_parts = [], [], []
        for who, sign in ((ii, -1.0), (jj, 1.0)):
            k = np.flatnonzero(members[who])
            col = 2 * index[who[k]]
            r_parts += [k, k]
            c_parts += [col, col + 1]
            v_parts += [sign * nn[k, 0], sign * nn[k, 1]]
        return sp.csc_matrix((np.concatenate(v_parts), (np.concatenate(r_parts), np.concatenate(c_parts))),
                             shape=(rows.size, m_vars))  # fmt: skip

    def certified(rows: NDArray[np.intp]) -> tuple[_Array | None, _Array]:
        """The polish on ``rows`` where it meets every constraint (then the KKT conditions hold: the
        answer), else None; and the excess of every constraint at the polish (``inf`` if none)."""
        found = _polish(matrix(rows).tocsr(), target, right[rows])
        if found is None:
            return None, np.full(right.size, np.inf)
        trial = u_hat.copy()
        trial[members] = found[0].reshape(-1, 2)
        excess = lhs(trial) - right
        if (excess > tol).any():
            return None, excess
        if memory is not None:
            memory.codes = codes[rows[found[1]]]
        return trial, excess

    excess = lhs(u) - right
    use = _most_violated(owner, excess, excess > tol, _JOIN_QP)
    if memory is not None and memory.codes.size:
        # the last answer's binding rows, polished: most often they, and a few that the motion
        # since made binding, are this answer's; the KKT check decides, else Clarabel does
        known = np.isin(codes, memory.codes)
        for _ in range(_GUESS_ROUNDS):
            guess, excess = certified(np.flatnonzero(known))
            if guess is not None:
                return guess
            violated = excess > tol
            if not np.isfinite(excess).all() or not violated.any():
                break
            known |= _most_violated(owner, excess, violated, _JOIN_QP)
        use |= known
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    while True:
        rows = np.flatnonzero(use)
        G = matrix(rows)
        solver = clarabel.DefaultSolver(sp.identity(m_vars, format="csc") * 2.0, -2.0 * target, G, right[rows],
                                        [clarabel.NonnegativeConeT(rows.size)], settings)  # fmt: skip
        sol = solver.solve()
        if str(sol.status) not in ("Solved", "AlmostSolved"):
            return None
        u[members] = np.asarray(sol.x, dtype=np.float64).reshape(-1, 2)
        # Clarabel meets its own constraints to its tolerance: only new ones count
        excess = lhs(u) - right
        violated = (excess > tol) & ~use
        if not violated.any():
            # the interior point's own indicator: a binding row's multiplier outgrows its slack
            binding = np.asarray(sol.z, dtype=np.float64) > np.asarray(sol.s, dtype=np.float64)
            exact, _ = certified(rows[binding])
            if exact is None and memory is not None:
                memory.codes = codes[rows[binding]]
            return u if exact is None else exact
        use |= _most_violated(owner, excess, violated, _JOIN_QP)


def _polish(G: Any, target: _Array, h: _Array) -> tuple[_Array, NDArray[np.bool_]] | None:
    """The exact minimiser of ``|u - target|^2`` with the binding rows ``G u = h`` as equalities, or None.

    The interior point meets its tolerances only (its answer moves by about
    1e-6 with the active set it was given); on the rows whose multipliers it
    found positive the KKT conditions are linear, ``u = target - G^T lam``,
    ``G G^T lam = G target - h``, solved by a sparse LU. The answer stands
    only where every multiplier is non-negative (the caller checks every
    constraint): then it is the QP's minimiser to rounding, whatever the
    warm start. A row of negative multiplier (taken for binding, pulling
    the wrong way) is dropped and the rest solved again, for up to
    :data:`_POLISH_ROUNDS` rounds. Returns the minimiser and which rows it
    kept; None when the rows are dependent (a degenerate vertex: the
    interior point's answer is kept) or the rounds run out.
    """
    import scipy.sparse.linalg as spla

    kept = np.ones(G.shape[0], dtype=bool)
    for _ in range(_POLISH_ROUNDS):
        if G.shape[0] == 0:
            return target.copy(), kept
        normal = (G @ G.T).tocsc()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # a singular factor warns: treat it as dependent rows
                lam = spla.splu(normal).solve(G @ target - h)
        except (RuntimeError, Warning):
            return None
        if not np.isfinite(lam).all():
            return None
        keep = lam >= -_FEASIBLE * (1.0 + np.abs(lam).max())
        if keep.all():
            return np.asarray(target - G.T @ lam, dtype=np.float64), kept
        G, h = G[keep], h[keep]  # a row taken for binding that pulls the wrong way: let it go
        kept[np.flatnonzero(kept)[~keep]] = False
    return None


def _solve_polygons(
    pairs: NDArray[np.intp], dp: _Array, half: _Array, u_hat: _Array, bad_i: NDArray[np.bool_], bad_j: NDArray[np.bool_]
) -> tuple[_Array, NDArray[np.bool_], NDArray[np.bool_]]:
    """Closest point to ``u_hat`` in each violating robot's polygon (module doc), by an active set.

    The polygon of a few sides is solved exactly (:func:`_closest_in_polygons`):
    at first each robot's :data:`_JOIN` most violated sides. Its minimiser is
    also the minimiser over all the robot's sides once it satisfies them all
    (the smaller problem's optimum is a lower bound); else the most violated
    of the sides it breaks join and the robots that broke one solve again.
    Every round adds a side, so it ends; a 2-D minimiser rests on at most
    two sides, so a robot facing tens of neighbours solves a polygon of a
    few sides, not of every neighbour.
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
    tol = _FEASIBLE * (1.0 + np.abs(b))
    a0, a1 = A[:, 0].copy(), A[:, 1].copy()

    def excess_at(cmd: _Array) -> _Array:  # by columns, as in _cluster_qp
        return a0 * cmd[:, 0][rows] + a1 * cmd[:, 1][rows] - b

    excess = excess_at(u_hat)
    use = _most_violated(rows, excess, excess > tol)
    u = u_hat.copy()
    squeezed = np.zeros(n, dtype=bool)
    again = moving.copy()
    while True:
        sel = use & again[rows]
        u_new, empty = _closest_in_polygons(rows[sel], A[sel], b[sel], u_hat, n)
        u[again] = u_new[again]
        squeezed |= empty  # the joint QP takes those over (barrier_commands)
        excess = excess_at(u)
        violated = (excess > tol) & ~use & ~squeezed[rows]
        if not violated.any():
            return u, moving, squeezed
        use |= _most_violated(rows, excess, violated)
        again = np.zeros(n, dtype=bool)
        again[rows[violated]] = True


def _most_violated(
    rows: NDArray[np.intp], excess: _Array, mask: NDArray[np.bool_], join: int = 0
) -> NDArray[np.bool_]:
    """Where ``mask``: each robot's ``join`` (default :data:`_JOIN`) rows of largest ``excess`` (unit normals)."""
    join = join or _JOIN
    pick = np.zeros(rows.size, dtype=bool)
    k = np.flatnonzero(mask)
    order = k[np.lexsort((-excess[k], rows[k]))]
    r = rows[order]
    first = np.ones(r.size, dtype=bool)
    first[1:] = r[1:] != r[:-1]
    start = np.maximum.accumulate(np.where(first, np.arange(r.size), 0))
    pick[order[np.arange(r.size) - start < join]] = True
    return pick


def _closest_in_polygons(
    rows: NDArray[np.intp], A: _Array, b: _Array, u_hat: _Array, n: int
) -> tuple[_Array, NDArray[np.bool_]]:
    """For each robot in ``rows``: the point of ``{u : A_k u <= b_k}`` closest to its ``u_hat``.

    Exact, by the polygon's edges: when ``u_hat`` is outside, the closest point
    lies on an edge, the part of some side's line that the other sides
    leave; on line k that part is an interval ``[lo_k, hi_k]`` of the
    coordinate along the line (each other side bounds it from one end, a
    parallel side keeps all or nothing of it), and the closest point of the
    line to ``u_hat``, its projection, clipped to the interval, is the edge's
    best point. The closest over the edges is the answer; no edge left
    means an empty polygon. Every robot and side at once (padded to the
    most sides): ``K^2`` work for K sides. Returns the commands (``u_hat``
    where a robot has no row) and where a polygon is empty.
    """
    order = np.argsort(rows, kind="stable")
    rows, A, b = rows[order], A[order], b[order]
    movers, robot_of = np.unique(rows, return_inverse=True)
    counts = np.bincount(robot_of, minlength=movers.size)
    K = int(counts.max())
    slot = np.arange(rows.size) - np.repeat(np.cumsum(counts) - counts, counts)
    M = movers.size
    norm = np.hypot(A[:, 0], A[:, 1])
    Ap = np.zeros((M, K, 2))
    bp = np.zeros((M, K))
    real = np.zeros((M, K), dtype=bool)  # padding rows are no constraint
    Ap[robot_of, slot] = A / norm[:, None]  # unit normals: the coordinate along a line is a length
    bp[robot_of, slot] = b / norm
    real[robot_of, slot] = True
    uh = u_hat[movers]
    tol = _FEASIBLE * (1.0 + np.abs(bp))
    over = Ap[..., 0] * uh[:, None, 0] + Ap[..., 1] * uh[:, None, 1] - bp  # (M, K)
    inside = ~(real & (over > tol)).any(axis=1)
    foot = uh[:, None] - over[..., None] * Ap  # projections of u_hat on the lines, (M, K, 2)
    tx, ty = -Ap[..., 1], Ap[..., 0]  # each line's direction
    # side l on line k: s (a_l . t_k) <= b_l - a_l . foot_k
    slope = Ap[:, None, :, 0] * tx[:, :, None] + Ap[:, None, :, 1] * ty[:, :, None]  # (M, k, l)
    room = bp[:, None, :] - (Ap[:, None, :, 0] * foot[:, :, None, 0] + Ap[:, None, :, 1] * foot[:, :, None, 1])
    other = real[:, None, :] & ~np.eye(K, dtype=bool)[None]
    flat = np.abs(slope) <= 1e-12
    safe_slope = np.where(flat, 1.0, slope)
    bound = room / safe_slope
    hi = np.where(other & ~flat & (slope > 0), bound, np.inf).min(axis=2)
    lo = np.where(other & ~flat & (slope < 0), bound, -np.inf).max(axis=2)
    shut = (other & flat & (room < -tol[:, None, :])).any(axis=2)  # a parallel side excludes the line
    # a polygon shrunk to a point may leave lo a rounding above hi
    slack = 1e-12 * (1.0 + np.abs(np.where(np.isfinite(lo), lo, 0.0)))
    edge = real & ~shut & (lo <= hi + slack)
    s = np.clip(0.0, lo, hi)
    dist = over**2 + s**2
    pick = np.argmin(np.where(edge, dist, np.inf), axis=1)
    m = np.arange(M)
    best = foot[m, pick] + s[m, pick, None] * np.stack([tx[m, pick], ty[m, pick]], axis=-1)
    u = u_hat.copy()
    u[movers] = np.where(inside[:, None], uh, best)
    empty = np.zeros(n, dtype=bool)
    empty[movers[~inside & ~edge.any(axis=1)]] = True
    return u, empty


class FilteredAgent:
    """An agent model whose commands pass through the :class:`BarrierFilter` first.

    Wraps any agent of :mod:`delayform.simulation.models.robots` (the integrators
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
        self.memory = ActiveSet()  # the joint QP's warm start from stage to stage
        self.extras = tuple(agent.extras) + ("safety_active", "safety_infeasible")
        self.name = agent.name

    def velocity(self, state: _Array) -> _Array:
        return self.agent.velocity(state)

    def _filter(self, x: _Array, v: _Array, u: _Array) -> tuple[_Array, NDArray[np.bool_], NDArray[np.bool_]]:
        """:func:`barrier_commands` over every pair that can bind (:class:`_Neighbours`)."""
        nb = self.neighbours
        if nb.n <= _ALL_PAIRS:  # small teams: every pair
            return barrier_commands(x, v, u, self.safe, self.safety.rate, nb.pairs, self.memory)
        need = nb.need(v, u)
        while True:
            found = barrier_commands(x, v, u, self.safe, self.safety.rate, nb(x, need), self.memory)
            need = nb.need(v, u, found[0])
            if nb.covers(x, need):  # else a pair left out might bind: again, with more pairs
                return found

    def filter(self, x: _Array, v: _Array, u: _Array) -> tuple[_Array, NDArray[np.bool_], NDArray[np.bool_]]:
        """The filtered commands at positions ``x`` and velocities ``v`` (as measured, for robots with mass),
        where the filter changed them, and where a polygon was empty."""
        return self._filter(x, v, u)

    def rhs(self, state: _Array, u: _Array) -> tuple[_Array, _Array, tuple[_Array, ...]]:
        filtered, active, infeasible = self._filter(state[:, :2], self.agent.velocity(state), u)
        deriv, cart, extra = self.agent.rhs(state, filtered)
        return deriv, cart, tuple(extra) + (active.astype(float), infeasible.astype(float))

    # ---- with an actuation delay: filter the command for the state it will be executed in
    def predict_with(self, buffer: Any) -> None:
        """Filter at the state tau_a ahead, predicted from the commands in flight (module doc, "Actuation delay").

        ``buffer`` is the run's :class:`~delayform.simulation.delayed.actuation.CommandBuffer`;
        only double integrators (x'' = the late command) are predicted exactly, so
        :func:`~delayform.simulation.runs.runner.check_actuation` refuses the filter for
        robots with limits under an actuation delay.
        """
        self._buffer = buffer
        n = self.state0.shape[0]
        self._flags = (np.zeros(n), np.zeros(n))

    def command(self, state: _Array, u: _Array) -> _Array:
        """The filtered command, made now and executed tau_a later, at the predicted state then."""
        x, v = self._buffer.predict(state[:, :2], self.agent.velocity(state))
        filtered, active, infeasible = self._filter(x, v, u)
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
