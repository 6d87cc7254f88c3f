"""Formation design: desired shapes, the forcing term of the paper's eq. 13, the final formation.

Conventions (paper, Section "Formation Control"):

* A formation is an ``(n, 2)`` array of desired positions, row i for agent i
  (the order of :attr:`Topology.labels`), columns x and y.
* The coordinates are decoupled (Section "Consensus Protocol"), so every
  per-coordinate quantity of the paper is a column here.
* The forcing of the paper's eq. 13 enters only the velocity rows of
  ``z = [x_1, xdot_1, ..., x_n, xdot_n]``; :func:`formation_forcing` returns
  those velocity rows, one column per coordinate: agent i receives the
  constant acceleration ``F[i]`` on top of protocol (paper, eq. 1).
* The forcing leaves the centroid factor (paper, eq. 4, lam = 1) untouched, so
  the team reaches the desired shape shifted by a common offset that the
  centroid dynamics and the initial history decide; see
  :func:`predicted_final_positions` for the derivation.

Shape names. Agents placed in rows and columns form a :func:`block`; the word
"grid" is kept for the communication graph :func:`delayform.topology.grid`
(``delayform.grid``), so that a shape and a topology never share a name. The
block was called ``grid`` before; ``delayform.formation.grid`` and the shape
name ``"grid"`` (scenario files, ``--formation``) still give the block, see
:data:`SHAPE_ALIASES`.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_delay, check_gain, check_magnitude, check_positive, validated
from delayform.errors import FormationError
from delayform.topology import DENSE_LIMIT, Topology

__all__ = [
    "SHAPES",
    "SHAPE_ALIASES",
    "polygon",
    "hexagon",
    "line",
    "block",
    "v_shape",
    "canonical_shape",
    "named_formation",
    "check_formation",
    "formation_forcing",
    "centroid_weights",
    "weighted_centroid",
    "final_centroid",
    "predicted_final_positions",
]


# ------------------------------------------------------------------ shapes
def _count(n: object) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise FormationError(f"a formation needs a positive integer number of agents, got {n!r}")
    return int(n)


@validated(FormationError)
def polygon(n: int, *, spacing: float = 1.0) -> NDArray[np.float64]:
    """Regular polygon with n vertices, neighbouring vertices ``spacing`` apart, centred at 0.

    >>> polygon(4).round(3)
    array([[ 0.707,  0.   ],
           [ 0.   ,  0.707],
           [-0.707,  0.   ],
           [-0.   , -0.707]])
    """
    n = _count(n)
    spacing = check_positive("spacing", spacing, FormationError)
    if n == 1:
        return np.zeros((1, 2))
    # circumradius of a regular n-gon with side length `spacing`
    radius = spacing / (2.0 * np.sin(np.pi / n))
    angle = 2.0 * np.pi * np.arange(n) / n
    return radius * np.column_stack([np.cos(angle), np.sin(angle)])


@validated(FormationError)
def hexagon(n: int = 6, *, spacing: float = 1.0) -> NDArray[np.float64]:
    """The hexagon of the demo: six agents on a regular hexagon (n must be 6).

    Parameters
    ----------
    n
        Number of agents; default 6, and any other count raises
        :class:`~delayform.errors.FormationError`.
    spacing
        Distance between neighbouring vertices (the side length); positive,
        default 1.0.

    Returns
    -------
    ndarray, shape (6, 2)
        The vertices of :func:`polygon` ``(6, spacing=spacing)``, centred at 0.
    """
    if _count(n) != 6:
        raise FormationError(f"a hexagon has 6 agents, the team has {n}")
    return polygon(6, spacing=spacing)


@validated(FormationError)
def line(n: int, *, spacing: float = 1.0) -> NDArray[np.float64]:
    """Agents on the x axis, ``spacing`` apart, centred at 0."""
    n = _count(n)
    spacing = check_positive("spacing", spacing, FormationError)
    x = spacing * (np.arange(n) - (n - 1) / 2.0)
    return np.column_stack([x, np.zeros(n)])


@validated(FormationError)
def block(n: int, *, spacing: float = 1.0) -> NDArray[np.float64]:
    """A block formation: agents row by row, ceil(sqrt(n)) to a row, centred at 0.

    Formerly ``grid`` (still importable under that name, and ``"grid"`` is
    still accepted as a shape name); renamed so that it is never mistaken
    for the grid communication graph :func:`delayform.topology.grid`.

    Parameters
    ----------
    n
        Number of agents; a positive integer. The last row is partly filled
        when n is not a multiple of ``ceil(sqrt(n))``.
    spacing
        Distance between neighbouring agents along a row, and between rows;
        positive, default 1.0.

    Returns
    -------
    ndarray, shape (n, 2)
        Agent i in column ``i % cols`` and row ``i // cols`` (rows go towards
        -y), shifted so that the mean position is 0.
    """
    n = _count(n)
    spacing = check_positive("spacing", spacing, FormationError)
    cols = int(np.ceil(np.sqrt(n)))
    idx = np.arange(n)
    pts = spacing * np.column_stack([idx % cols, -(idx // cols)]).astype(np.float64)
    return pts - pts.mean(axis=0)


#: the old name of :func:`block`, kept for code written before the rename
grid = block


@validated(FormationError)
def v_shape(n: int, *, spacing: float = 1.0, angle: float = np.pi / 6) -> NDArray[np.float64]:
    """A V (flock) opening to -x: leader at the tip, the others alternating on two arms.

    ``angle`` is the half-angle of the V in radians, ``spacing`` the distance
    along an arm between consecutive agents.
    """
    n = _count(n)
    spacing = check_positive("spacing", spacing, FormationError)
    angle = check_positive("angle", angle, FormationError)
    k = (np.arange(n) + 1) // 2  # position along the arm: 0, 1, 1, 2, 2, ...
    side = np.where(np.arange(n) % 2 == 1, 1.0, -1.0)
    pts = spacing * np.column_stack([-k * np.cos(angle), side * k * np.sin(angle)])
    return pts - pts.mean(axis=0)


#: named shapes accepted wherever a formation may be given by name
SHAPES = {
    "polygon": polygon,
    "hexagon": hexagon,
    "line": line,
    "block": block,
    "v": v_shape,
}

#: old shape names still accepted (scenario files, ``--formation``), mapped to the current one
SHAPE_ALIASES = {"grid": "block"}


def canonical_shape(name: str) -> str:
    """The current name of a shape: an old name of :data:`SHAPE_ALIASES` mapped, any other returned as given.

    Parameters
    ----------
    name
        A shape name, current (a key of :data:`SHAPES`) or old (a key of
        :data:`SHAPE_ALIASES`); case-insensitive for the old names. Unknown
        names come back unchanged, for the caller to reject.

    Examples
    --------
    >>> canonical_shape("grid"), canonical_shape("line")
    ('block', 'line')
    """
    return SHAPE_ALIASES.get(name.lower(), name)


@validated(FormationError)
def named_formation(name: str, n: int, *, spacing: float = 1.0) -> NDArray[np.float64]:
    """The named shape (one of :data:`SHAPES`) for n agents.

    Parameters
    ----------
    name
        Shape name, a key of :data:`SHAPES` (``"polygon"``, ``"hexagon"``,
        ``"line"``, ``"block"`` or ``"v"``) or the old name ``"grid"`` of
        ``"block"``; case-insensitive.
    n
        Number of agents; a positive integer (6 for ``"hexagon"``).
    spacing
        Distance between neighbouring agents of the shape, passed on to its
        builder; positive, default 1.0 (``"v"`` keeps its default angle).

    Returns
    -------
    ndarray, shape (n, 2)
        The desired positions, row i for agent i.

    Raises
    ------
    FormationError
        For an unknown name, or a hexagon for a team that is not six.
    """
    try:
        builder = SHAPES[canonical_shape(str(name).lower())]
    except KeyError:
        raise FormationError(
            f"unknown formation shape {name!r}; known shapes: {', '.join(sorted(SHAPES))}"
        ) from None
    return builder(n, spacing=spacing)


def check_formation(formation: ArrayLike | str, n: int) -> NDArray[np.float64]:
    """A desired formation as a finite ``(n, 2)`` float array, built from a name if given one.

    Raises
    ------
    FormationError
        For a wrong shape, a wrong number of agents or non-finite entries.
    """
    if isinstance(formation, str):
        return named_formation(formation, n)
    try:
        arr = np.asarray(formation, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FormationError("formation must be an (n, 2) array of positions or a shape name") from exc
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise FormationError(f"formation must have shape (n, 2), got {arr.shape}")
    if arr.shape[0] != n:
        raise FormationError(f"formation has {arr.shape[0]} agents, the topology has {n}")
    if not np.all(np.isfinite(arr)):
        raise FormationError("formation positions must be finite")
    check_magnitude("formation positions", arr, FormationError)
    return arr


# ----------------------------------------------------------------- forcing
@validated(FormationError)
def formation_forcing(topology: Topology, P: float, desired: ArrayLike | str) -> NDArray[np.float64]:
    """The forcing term F of the paper's eq. 13 that holds the team in the desired shape.

    At a constant formation, velocities vanish and the delayed positions equal
    the current ones, so the paper's eq. 13 reduces to ``0 = P (C - I) z + F`` per
    coordinate; hence ``F = P (I - C) z_desired``. This holds for any C,
    diagonalizable or not, and equals the paper's construction through the
    Jordan transform T (paper, eqs. 8 and 12, ``F = (T (x) I_2) phi``):
    ``T diag(P (I - J_i)) T^-1 = P (I - C)``. Its centroid component is zero
    (``w^T (I - C) = 0`` for the left eigenvector w of lam = 1), as the paper
    requires: the forcing acts only on the disagreement dynamics.

    Parameters
    ----------
    topology
        The communication topology (C = Delta^-1 A).
    P
        Proportional gain of the paper's eq. 1.
    desired
        ``(n, 2)`` desired positions, or a shape name from :data:`SHAPES`.

    Returns
    -------
    ndarray, shape (n, 2)
        The velocity rows of F: agent i adds ``F[i]`` to its acceleration.
        F is determined by the shape only up to a common translation of
        ``desired`` (translations lie in the kernel of I - C).

    Examples
    --------
    >>> from delayform.topology import ring
    >>> formation_forcing(ring(3), 1.0, [[0, 0], [1, 0], [0, 1]])
    array([[ 0., -1.],
           [ 1.,  0.],
           [-1.,  1.]])
    """
    P = check_gain("P", P)
    z = check_formation(desired, topology.n)
    return P * (z - topology.C_sparse @ z)


# ------------------------------------------------------- centroid dynamics
def centroid_weights(topology: Topology) -> NDArray[np.float64]:
    """The left eigenvector w of C for lam = 1, normalised to ``sum(w) = 1``.

    ``w^T x`` is the *weighted centroid* whose dynamics is the centroid factor
    the paper's eq. 4. With a spanning tree the eigenvalue 1 is simple, so
    ``(I - C)^T w = 0`` has a one-dimensional solution space. Since
    ``1^T (I - C)^T = 0``, the matrix ``(I - C)^T + 1 1^T`` is non-singular and
    ``((I - C)^T + 1 1^T) w = 1`` gives exactly that w with ``1^T w = 1``.
    Up to :data:`~delayform.topology.DENSE_LIMIT` agents it is solved densely;
    above, by GMRES with the rank-one term applied as an operator (a sparse LU
    of a random digraph fills in badly: 27 s at 10,000 agents), falling back
    to the sparse LU if GMRES does not reach a residual of 1e-12.
    """
    topology.require_spanning_tree()
    n = topology.n
    CT = sp.csr_array(topology.C_sparse.T)
    rhs = np.ones(n)
    if n <= DENSE_LIMIT:
        return np.linalg.solve(np.eye(n) - CT.toarray() + 1.0, rhs)
    op = spla.LinearOperator((n, n), matvec=lambda w: w - CT @ w + w.sum(), dtype=np.float64)
    w, _ = spla.gmres(op, rhs, x0=np.full(n, 1.0 / n), rtol=1e-14, atol=0.0, restart=200, maxiter=100)
    if np.abs(op.matvec(w) - rhs).max() > 1e-12:
        M = sp.lil_matrix(sp.identity(n, format="csr") - CT)
        M[n - 1, :] = np.ones(n)  # the n equations sum to zero: swap one for 1^T w = 1
        e = np.zeros(n)
        e[-1] = 1.0
        w = spla.spsolve(sp.csc_matrix(M), e)
    return np.asarray(w, dtype=np.float64)


def weighted_centroid(topology: Topology, positions: ArrayLike) -> NDArray[np.float64]:
    """``w^T x`` for ``(..., n, 2)`` positions: the weighted centroid of the paper's eq. 4.

    Parameters
    ----------
    topology
        The communication topology; must have a spanning tree (w is
        :func:`centroid_weights`).
    positions
        Positions of shape ``(..., n, 2)``, agents along the second-to-last
        axis (one formation, or e.g. a trajectory of shape ``(steps, n, 2)``).

    Returns
    -------
    ndarray, shape (..., 2)
        The weighted centroid (x, y) of each set of positions.
    """
    w = centroid_weights(topology)
    return np.einsum("i,...ik->...k", w, np.asarray(positions, dtype=np.float64))


def final_centroid(
    topology: Topology,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    initial_positions: ArrayLike,
    initial_velocities: ArrayLike,
) -> NDArray[np.float64]:
    """Where the weighted centroid comes to rest, for a constant initial history.

    Derivation. Multiply the paper's eq. 13 by ``w^T`` (left eigenvector of C for
    lam = 1, ``w^T 1 = 1``). Since ``w^T C = w^T`` and ``w^T F = 0``, the
    weighted centroid ``c = w^T x`` (one coordinate) obeys the centroid factor
    the paper's eq. 4 as a delay equation::

        c'' + D c' + P c = P c(t - tau1) + D c'(t - tau2),

    with the constant history ``c = c0, c' = d0`` for ``t <= 0`` (the state
    ``z`` of the paper's eq. 2 is constant before 0, velocities included).
    In the Laplace domain the history enters through
    ``L{c(t - tau)} = e^{-tau s} C(s) + c0 (1 - e^{-tau s}) / s`` and
    ``L{c'(t - tau)} = e^{-tau s} (s C(s) - c0) + d0 (1 - e^{-tau s}) / s``, so::

        q1(s) C(s) = N(s) = (s + D - D e^{-tau2 s}) c0 + d0
                            + P c0 (1 - e^{-tau1 s}) / s + D d0 (1 - e^{-tau2 s}) / s

    with ``q1`` the centroid factor (paper, eq. 4). ``q1`` has the simple root
    ``s = 0`` (``q1'(0) = P tau1``); when every other root lies in the left
    half plane the final-value theorem gives
    ``c_inf = lim_{s->0} s N(s) / q1(s) = N(0) / q1'(0)`` with
    ``N(0) = d0 (1 + D tau2) + P tau1 c0``, so::

        c_inf = c0 + d0 (1 + D tau2) / (P tau1).

    The same follows by integrating the delay equation over ``[0, inf)``.
    Without a position delay (``tau1 = 0``) the zero root is double and the
    centroid drifts at speed ``d0``; there is then no final position unless
    ``d0 = 0``.

    Parameters
    ----------
    topology
        The communication topology (C = Delta^-1 A); must have a spanning tree.
    P, D
        Positive gains of the paper's eq. 1.
    tau1, tau2
        Non-negative delays (s) on positions and on velocities.
    initial_positions
        ``(n, 2)`` positions of the constant history (``c0 = w^T x0``), or a
        shape name from :data:`SHAPES`.
    initial_velocities
        ``(n, 2)`` Cartesian velocities of the constant history
        (``d0 = w^T v0``).

    Returns
    -------
    ndarray, shape (2,)
        The final weighted centroid (x, y).

    Raises
    ------
    FormationError
        When ``tau1 = 0`` and the initial centroid velocity is not zero.
    """
    P = check_gain("P", P)
    D = check_gain("D", D)
    tau1 = check_delay("tau1", tau1)
    tau2 = check_delay("tau2", tau2)
    n = topology.n
    x0 = check_formation(initial_positions, n)
    v0 = check_formation(initial_velocities, n)
    w = centroid_weights(topology)
    c0, d0 = w @ x0, w @ v0
    if tau1 == 0.0:
        if np.any(d0 != 0.0):
            raise FormationError(
                "with tau1 = 0 the centroid factor (paper, eq. 4) has a double zero root: "
                "the weighted centroid drifts at its initial velocity and never settles"
            )
        return c0
    return c0 + d0 * (1.0 + D * tau2) / (P * tau1)


@validated(FormationError)
def predicted_final_positions(
    topology: Topology,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    desired: ArrayLike | str,
    initial_positions: ArrayLike,
    initial_velocities: ArrayLike,
) -> NDArray[np.float64]:
    """The final formation: the desired shape plus the common offset the centroid sets.

    At rest, the paper's eq. 13 gives ``(I - C)(x - z_desired) = 0``, so
    ``x = z_desired + 1 a`` for a common offset ``a`` (the kernel of ``I - C``
    is spanned by 1 when there is a spanning tree). The weighted centroid
    ``w^T x = w^T z_desired + a`` must equal :func:`final_centroid`, which fixes
    ``a``. Valid only where the disagreement factors are stable.

    Parameters
    ----------
    topology
        The communication topology (C = Delta^-1 A); must have a spanning tree.
    P, D
        Positive gains of the paper's eq. 1.
    tau1, tau2
        Non-negative delays (s) on positions and on velocities.
    desired
        ``(n, 2)`` desired positions, or a shape name from :data:`SHAPES`.
    initial_positions
        ``(n, 2)`` positions of the constant initial history.
    initial_velocities
        ``(n, 2)`` Cartesian velocities of the constant initial history.

    Returns
    -------
    ndarray, shape (n, 2)
        ``desired`` shifted by the common offset ``a``: where the agents
        come to rest.

    Raises
    ------
    FormationError
        As :func:`final_centroid`, and for a malformed ``desired``.
    """
    z = check_formation(desired, topology.n)
    c_inf = final_centroid(topology, P, D, tau1, tau2, initial_positions, initial_velocities)
    offset = c_inf - centroid_weights(topology) @ z
    return z + offset
