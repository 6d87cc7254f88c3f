"""Linear matrix inequalities: assembly in Clarabel's standard form, the solve, and an independent re-check.

An LMI problem here is a set of symmetric matrices ``M_i(x)``, each affine in
the decision variables ``x`` (symmetric or full matrix blocks), that must all
be positive definite. It is posed to Clarabel as

    maximize t   subject to   M_i(x) - t I  in the PSD cone (every i),
                              sum of the traces of the normalized blocks = 1,  t <= 1,

Clarabel's form ``A z + s = b, s in K`` with ``z = (x, t)``: every PSD
constraint enters as the vectorized upper triangle of its matrix, column by
column, the off-diagonal entries scaled by sqrt(2) (Clarabel's
``PSDTriangleConeT``). The conditions are homogeneous, so the trace condition
only fixes the scale (and excludes x = 0): a strictly feasible x exists if
and only if the optimum t is positive, and a clearly negative optimum is the
solver's word that none exists.

The solver's status is never the certificate. :func:`recheck` rounds the
returned variables to a dyadic grid, rebuilds every ``M_i`` from them in
floating point (smallest eigenvalue above a relative margin) and in exact
rational arithmetic (first an exact congruence X' M X, X from a float
Cholesky factor, shown strictly diagonally dominant; failing that, every
leading principal minor positive, computed fraction-free by Bareiss's
elimination: the pivots of an exact LDL^T are their ratios), from the same
rounded variables and the exactly represented data.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from numpy.typing import NDArray

from delayform._extras import require_extra

__all__ = ["LmiProblem", "Variables", "Recheck", "SdpSolution", "solve", "recheck", "exact_check", "leading_minors_positive", "dominant_after_congruence",
           "solver_says_infeasible", "svec", "margin_slope"]

#: Bits of the dyadic grid the decision variables are rounded to before the re-check.
_GRID_BITS = 40
#: Smallest eigenvalue accepted, relative to the matrix's 2-norm (float re-check).
EIG_MARGIN = 1e-9
#: Largest total size of the LMI matrices re-checked in exact arithmetic (cost grows as the cube).
EXACT_LIMIT = 400
#: Optimum t below -this is read as "no strictly feasible point" (the solver's word).
_INFEASIBLE_T = 1e-7


@functools.lru_cache(maxsize=64)
def _triu(n: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """np.triu_indices(n), computed once per order (the arrays are never written)."""
    return np.triu_indices(n)


@dataclass(frozen=True)
class _Block:
    name: str
    rows: int
    cols: int
    symmetric: bool
    offset: int

    @property
    def size(self) -> int:
        return self.rows * (self.rows + 1) // 2 if self.symmetric else self.rows * self.cols


@dataclass
class Variables:
    """The decision variables of an LMI problem: named symmetric or full matrix blocks."""

    blocks: list[_Block] = field(default_factory=list)
    normalized: list[str] = field(default_factory=list)

    @property
    def size(self) -> int:
        """Number of scalar decision variables."""
        return sum(b.size for b in self.blocks)

    def symmetric(self, name: str, n: int, *, normalize: bool = True) -> None:
        """Add an n x n symmetric block ``name`` (its trace counts in the normalization when ``normalize``)."""
        self.blocks.append(_Block(name, n, n, True, self.size))
        if normalize:
            self.normalized.append(name)

    def full(self, name: str, rows: int, cols: int) -> None:
        """Add a rows x cols block ``name`` without structure."""
        self.blocks.append(_Block(name, rows, cols, False, self.size))

    def unpack(self, x: NDArray[Any]) -> dict[str, NDArray[Any]]:
        """The blocks' matrices from ``x`` (float or object dtype of Fractions).

        ``x`` may carry leading batch axes (shape ``(..., size)``); the
        matrices then carry them too, which the builders broadcast over.
        """
        out: dict[str, NDArray[Any]] = {}
        batch = x.shape[:-1]
        for b in self.blocks:
            v = x[..., b.offset : b.offset + b.size]
            if b.symmetric:
                M = np.zeros(batch + (b.rows, b.rows), dtype=x.dtype)
                iu = _triu(b.rows)
                M[..., iu[0], iu[1]] = v
                M[..., iu[1], iu[0]] = v
            else:
                M = np.asarray(v).reshape(batch + (b.rows, b.cols))
            out[b.name] = M
        return out

    def pack(self, values: Mapping[str, NDArray[Any]]) -> NDArray[np.float64]:
        """The vector x whose :meth:`unpack` gives ``values`` (a certificate's matrices back into the variables)."""
        x = np.zeros(self.size)
        for b in self.blocks:
            M = np.asarray(values[b.name], dtype=float)
            if M.shape != (b.rows, b.cols):
                raise ValueError(f"block {b.name} must be {b.rows} x {b.cols}, got {M.shape}")
            x[b.offset : b.offset + b.size] = M[_triu(b.rows)] if b.symmetric else M.ravel()
        return x

    def trace_row(self) -> NDArray[np.float64]:
        """Coefficients of the summed traces of the normalized blocks."""
        row = np.zeros(self.size)
        for b in self.blocks:
            if b.name in self.normalized:
                r, c = _triu(b.rows)
                row[b.offset + np.flatnonzero(r == c)] = 1.0
        return row


#: build(values, exact) -> {name: symmetric matrix that must be positive definite}
Builder = Callable[[Mapping[str, NDArray[Any]], bool], dict[str, NDArray[Any]]]


@dataclass(frozen=True)
class LmiProblem:
    """Variables and the affine map from them to the matrices that must be positive definite.

    ``build(values, exact)`` must compute with float64 arrays when ``exact`` is
    False and with object arrays of :class:`fractions.Fraction` (the data
    converted exactly) when True, by the same formulas.
    """

    variables: Variables
    build: Builder


@dataclass(frozen=True)
class SdpSolution:
    """What Clarabel returned: the variables, the optimum t, the status name and the dual matrices.

    ``duals`` maps each LMI's name to the svec of its dual matrix (PSD at the optimum); empty
    when the solver returned none.
    """

    x: NDArray[np.float64]
    t: float
    status: str
    duals: Mapping[str, NDArray[np.float64]] = field(default_factory=dict, repr=False)


@functools.lru_cache(maxsize=64)
def _svec_order(m: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    # (row, col) of the upper triangle taken column by column
    cols, rows = np.tril_indices(m)
    return rows, cols


def svec(M: NDArray[np.float64]) -> NDArray[np.float64]:
    """The vector Clarabel's PSD triangle cone holds for the symmetric matrix ``M`` (batched on leading axes)."""
    rows, cols = _svec_order(M.shape[-1])
    v = M[..., rows, cols]
    return np.where(rows == cols, v, math.sqrt(2.0) * v)


#: Column patterns of linearizations done, per structure (the variables' blocks, the matrices' names and
#: orders): the next problem with that structure is linearized on a few combined columns (below).
_PATTERNS: dict[tuple[Any, ...], tuple[NDArray[np.intp], int, dict[str, NDArray[np.bool_]]]] = {}
_MAX_PATTERNS = 32
#: Per structure: the masks of _PATTERNS and their non-zero (row, column) pairs (recomputed when the masks change).
_Pairs = dict[str, tuple[NDArray[np.intp], NDArray[np.intp]]]
_NONZEROS: dict[tuple[Any, ...], tuple[dict[str, NDArray[np.bool_]], _Pairs]] = {}


def _colors(masks: Mapping[str, NDArray[np.bool_]], nv: int) -> tuple[NDArray[np.intp], int]:
    """Greedy colouring of the columns: two columns with a common non-zero row never share a colour."""
    support = np.vstack(list(masks.values())) if masks else np.zeros((0, nv), dtype=bool)
    used = np.zeros((0, support.shape[0]), dtype=bool)
    color = np.zeros(nv, dtype=np.intp)
    for j in range(nv):
        rows = np.flatnonzero(support[:, j])
        free = np.flatnonzero(~used[:, rows].any(axis=1)) if used.shape[0] else np.zeros(0, dtype=np.intp)
        c = int(free[0]) if free.size else used.shape[0]
        if c == used.shape[0]:
            used = np.vstack([used, np.zeros((1, support.shape[0]), dtype=bool)])
        used[c, rows] = True
        color[j] = c
    return color, used.shape[0]


def _linearize(problem: LmiProblem) -> tuple[dict[str, NDArray[np.float64]], dict[str, NDArray[np.float64]]]:
    """Constant svec and column matrix of each LMI: svec(M(x)) = c + J x (the map is affine).

    The builder is evaluated once at x = 0 and once on the batch of all unit
    vectors (the formulas broadcast over the batch axis). When a problem of the
    same structure was linearized before, its columns' non-zero rows are reused:
    columns without a common row are evaluated together (one sum of unit vectors
    per colour, Curtis, Powell and Reid's compression), each read back on its own
    rows, and the result is accepted only if it reproduces the builder at a random
    point (otherwise the full batch runs). Either way only the solver sees J; every
    answer is re-checked from the builder itself (:func:`recheck`).
    """
    nv = problem.variables.size
    unpack = problem.variables.unpack
    base = problem.build(unpack(np.zeros(nv)), False)
    const = {k: svec(np.asarray(v, dtype=float)) for k, v in base.items()}
    key = (tuple((b.name, b.rows, b.cols, b.symmetric) for b in problem.variables.blocks),
           tuple((k, c.size) for k, c in const.items()))  # fmt: skip
    known = _PATTERNS.get(key)
    if known is not None:
        color, ncolors, masks = known
        seeds = np.zeros((ncolors, nv))
        seeds[color, np.arange(nv)] = 1.0
        combined = problem.build(unpack(seeds), False)
        cols, largest = {}, {}
        cached = _NONZEROS.get(key)
        if cached is None or cached[0] is not masks:  # the masks' non-zero (row, column) pairs, once per pattern
            cached = _NONZEROS[key] = (masks, {k: np.nonzero(M) for k, M in masks.items()})
        nonzeros = cached[1]
        for k, c in const.items():  # column j read back on its rows from its colour's combined svec
            r, j = nonzeros[k]
            vals = (svec(np.asarray(combined[k], dtype=float)) - c)[color[j], r]
            cols[k] = np.zeros(masks[k].shape)
            cols[k][r, j] = vals
            largest[k] = float(np.abs(vals).max(initial=0.0))
        x = np.random.default_rng(nv).standard_normal(nv)
        probe = problem.build(unpack(x), False)
        if all(np.allclose(svec(np.asarray(probe[k], dtype=float)), c + cols[k] @ x, rtol=1e-9,
                           atol=1e-9 * (1.0 + largest[k])) for k, c in const.items()):  # fmt: skip
            return const, cols
    units = problem.build(unpack(np.eye(nv)), False)
    cols = {k: (svec(np.asarray(units[k], dtype=float)) - c).T for k, c in const.items()}
    masks = {k: J != 0.0 for k, J in cols.items()}
    if len(_PATTERNS) >= _MAX_PATTERNS:
        oldest = next(iter(_PATTERNS))
        _PATTERNS.pop(oldest)
        _NONZEROS.pop(oldest, None)
    _PATTERNS[key] = (*_colors(masks, nv), masks)
    return const, cols


def solve(problem: LmiProblem, *, tolerance: float | None = None, quick: bool = False,
          balance: bool = False) -> SdpSolution:  # fmt: skip
    """Maximize the common margin t of the LMIs with Clarabel (module docstring).

    Parameters
    ----------
    problem
        The variables and the LMI builder; the builder is linearized once per solve.
    tolerance
        Clarabel's duality-gap and feasibility tolerances (None: its defaults, 1e-8). Looser
        ones (1e-6) stop a few iterations earlier; the answer is re-checked either way, so
        this trades only a little of the margin t near the boundary, never soundness.
    quick
        Without Clarabel's iterative refinement and equilibration, the chordal cliques merged
        parent into child (measured on the team's order-3 LMIs: 0.6-0.8 s instead of 1.4 s of
        CPU, and fewer iterations). The answer is a little
        less accurate near the boundary of the feasible set, where it may then fail the re-check:
        a caller that wants the most from a solve re-solves without ``quick``.
    balance
        Pose each LMI to the solver as the congruent D M(x) D, D diagonal with powers of two that
        bring its diagonal's coefficients near 1 (:func:`_balance`). D M D and M are positive
        definite together (Sylvester's law of inertia), so the feasible x are the same, but the
        margin t is then that of D M D (its scale differs: about 300 times smaller on the team's
        order-3 LMIs, so pass a tighter ``tolerance``) and the dual matrices returned are
        D Z D, those of the LMIs as built. Near the boundary of the feasible set it needs fewer
        iterations (measured on the team's order-3 LMIs: 16-18 against 31). The re-check is of
        M itself, as always.

    Raises
    ------
    MissingExtraError
        Without Clarabel (the ``certificates`` extra).
    """
    require_extra("certificates")
    import clarabel

    const, cols = _linearize(problem)
    nv = problem.variables.size
    # A in coordinates (rows, columns, values), assembled once: the LMIs' columns are mostly zeros
    A_rows: list[NDArray[np.intp]] = []
    A_cols: list[NDArray[np.intp]] = []
    A_vals: list[NDArray[np.float64]] = []
    b_parts: list[NDArray[np.float64]] = []
    cones: list[Any] = [clarabel.ZeroConeT(1), clarabel.NonnegativeConeT(1)]
    # the normalization rows first: sum of traces = 1 (excludes x = 0, so an infeasible
    # problem has a negative optimum t) and t <= 1
    trace = np.flatnonzero(problem.variables.trace_row())
    A_rows += [np.zeros(trace.size, dtype=np.intp), np.ones(1, dtype=np.intp)]
    A_cols += [trace, np.full(1, nv)]
    A_vals += [np.ones(trace.size), np.ones(1)]
    b_parts.append(np.ones(2))
    start = 2
    weights: dict[str, NDArray[np.float64]] = {}
    for name, c in const.items():
        m = int(round((math.sqrt(8 * c.size + 1) - 1) / 2))
        J = cols[name]
        if balance:
            weights[name] = w = _balance(c, J, m)
            c, J = c * w, J * w[:, None]
        # s = c + J x - t svec(I) = b - A z with A = [-J, svec(I)], b = c
        r, k = np.nonzero(J)
        rows, cols_ = _svec_order(m)
        diag = np.flatnonzero(rows == cols_)
        A_rows += [start + r, start + diag]
        A_cols += [k, np.full(m, nv)]
        A_vals += [-J[r, k], np.ones(m)]
        b_parts.append(c)
        cones.append(clarabel.PSDTriangleConeT(m))
        start += c.size
    A = sp.csc_matrix((np.concatenate(A_vals), (np.concatenate(A_rows), np.concatenate(A_cols))), shape=(start, nv + 1))
    b = np.concatenate(b_parts)
    q = np.zeros(nv + 1)
    q[nv] = -1.0
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.max_iter = 200
    # faer's supernodal LDL^T: the PSD cones make dense KKT blocks, where it is 4-5x faster than qdldl
    settings.direct_solve_method = "faer"
    # one thread: these factorizations are too small for faer's threads to pay (measured: the same
    # wall time and half the CPU of the default, which uses every core)
    settings.max_threads = 1
    if tolerance is not None:
        settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = tolerance
        settings.tol_ktratio = 10.0 * tolerance
    if quick:
        settings.iterative_refinement_enable = False
        settings.equilibrate_enable = False
        # the chordal cliques merged parent into child: a few iterations fewer on the team's order-3 LMIs
        settings.chordal_decomposition_merge_method = "parent_child"
    sol = clarabel.DefaultSolver(sp.csc_matrix((nv + 1, nv + 1)), q, A, b, cones, settings).solve()
    z = np.asarray(sol.x, dtype=float)
    t = float(z[nv]) if z.size == nv + 1 and np.all(np.isfinite(z)) else math.nan
    y = np.asarray(sol.z, dtype=float)
    duals: dict[str, NDArray[np.float64]] = {}
    if y.size == b.size and np.all(np.isfinite(y)):
        start = 2
        for name, c in const.items():
            duals[name] = y[start : start + c.size] * weights.get(name, 1.0)
            start += c.size
    return SdpSolution(z[:nv] if z.size == nv + 1 else np.zeros(nv), t, str(sol.status), duals)


def _balance(c: NDArray[np.float64], J: NDArray[np.float64], m: int) -> NDArray[np.float64]:
    """The svec weights d_i d_j of the congruence D M D, D = diag(d), that :func:`solve` poses with ``balance``.

    d_i = 2^-round(log2(s_i) / 2), s_i the largest coefficient of the diagonal entry M_ii (its
    constant or any column of J): D M D's diagonal coefficients are then within a factor 2 of 1.
    Powers of two: the scaled coefficients are the same floats, only their exponents move.
    """
    rows, cols = _svec_order(m)
    diag = rows == cols
    size = np.maximum(np.abs(J[diag]).max(axis=1, initial=0.0), np.abs(c[diag]))
    d = np.ones(m)
    pos = size > 0.0
    d[pos] = np.exp2(-np.round(0.5 * np.log2(size[pos])))
    return d[rows] * d[cols]


def margin_slope(sol: SdpSolution, below: LmiProblem, above: LmiProblem, step: float) -> float:
    """The derivative of the optimum margin t with respect to a parameter of the LMIs, from the duals.

    The problems ``below`` and ``above`` are the same LMIs (same variables) at the parameter
    minus and plus ``step``; ``sol`` is the optimum at the parameter itself. By the envelope
    theorem (the optimum moves with the constraints weighted by their dual matrices Z_i),
    dt/dp = sum_i <Z_i, dM_i/dp> at the optimal variables, the derivative taken by central
    differences (exact for the quadratic dependence of these LMIs on the delays). A guess for
    a search, never part of a certificate: nan without duals.
    """
    if not sol.duals:
        return math.nan
    values = below.variables.unpack(sol.x)
    lo, hi = below.build(values, False), above.build(values, False)
    total = 0.0
    for name, z in sol.duals.items():
        dM = (svec(np.asarray(hi[name], dtype=float)) - svec(np.asarray(lo[name], dtype=float))) / (2.0 * step)
        total += float(z @ dM)
    return total


def solver_says_infeasible(sol: SdpSolution) -> bool:
    """The solver's optimum t in ``sol`` is clearly negative: no strictly feasible point (not re-checked)."""
    return sol.status == "Solved" and math.isfinite(sol.t) and sol.t < -_INFEASIBLE_T


def leading_minors_positive(M: NDArray[Any]) -> bool:
    """Exact positive definiteness of the symmetric rational matrix ``M`` (Sylvester's criterion).

    The matrix is scaled to integers by the least common denominator and
    Bareiss's fraction-free elimination produces its leading principal minors
    ``Delta_k`` as the successive pivots; the pivots of the exact LDL^T are
    ``d_k = Delta_k / Delta_{k-1}``, so all positive is the same test.
    """
    m = M.shape[0]
    fr = [[Fraction(M[i, j]) for j in range(m)] for i in range(m)]
    if any(fr[i][j] != fr[j][i] for i in range(m) for j in range(i)):
        return False
    den = 1
    for row in fr:
        for v in row:
            den = den * v.denominator // math.gcd(den, v.denominator)
    Z = [[int(v * den) for v in row] for row in fr]
    prev = 1
    for k in range(m):
        piv = Z[k][k]
        if piv <= 0:
            return False
        for i in range(k + 1, m):
            for j in range(k + 1, m):
                Z[i][j] = (Z[i][j] * piv - Z[i][k] * Z[k][j]) // prev
        prev = piv
    return True


@dataclass(frozen=True)
class Recheck:
    """The independent re-check of one solution: variables, matrices and their verdicts.

    Attributes
    ----------
    values
        The decision variables (rounded to the dyadic grid) the checks used.
    matrices
        Each LMI matrix rebuilt from them in floating point.
    min_eigenvalues
        Smallest eigenvalue of each, relative to its 2-norm; where the exact check can run (total
        size within :data:`EXACT_LIMIT`), of the matrix scaled to a unit diagonal.
    eigenvalues_ok
        Every relative smallest eigenvalue above :data:`EIG_MARGIN`.
    exact_ok
        Every matrix positive definite in exact arithmetic; None when too large to check.
    """

    values: dict[str, NDArray[np.float64]]
    rational: tuple[Fraction, ...] = field(repr=False)
    matrices: dict[str, NDArray[np.float64]]
    min_eigenvalues: dict[str, float]
    eigenvalues_ok: bool
    exact_ok: bool | None

    @property
    def passed(self) -> bool:
        """Both checks passed (the exact one where it was run)."""
        return self.eigenvalues_ok and self.exact_ok is not False


def _dyadic(x: NDArray[np.float64]) -> list[Fraction]:
    scale = 2**_GRID_BITS
    return [Fraction(round(float(v) * scale), scale) for v in x]


def _relative_min_eigenvalue(M: NDArray[np.float64], scaled: bool) -> float:
    """The smallest eigenvalue of the symmetric M relative to its 2-norm; ``scaled``: of D M D, D = diag(M)^(-1/2).

    D M D and M are positive definite together (Sylvester's law of inertia), and the scaled matrix's
    relative eigenvalue is not made small by rows of very different sizes (the team's LMIs mix
    windows of 0.2 s and 1 s, their diagonals spanning five decades). A diagonal entry that is not
    positive already shows M is not positive definite: its value relative to the largest is returned.
    """
    d = np.diag(M)
    if scaled:
        if not np.all(d > 0.0):
            return float(d.min() / max(np.abs(d).max(), np.finfo(float).tiny))
        inv = 1.0 / np.sqrt(d)
        M = inv[:, None] * M * inv[None, :]
    norm = float(np.linalg.norm(M, 2))
    return float(np.linalg.eigvalsh(M)[0]) / norm if norm > 0 else -math.inf


def exact_check(problem: LmiProblem, rational: tuple[Fraction, ...]) -> bool | None:
    """Every LMI matrix, rebuilt in exact arithmetic from the rounded variables, positive definite.

    Parameters
    ----------
    problem
        The LMI problem whose builder runs here on Fractions.
    rational
        The decision variables as exact dyadic rationals (:attr:`Recheck.rational`).

    Returns None when the matrices are too large for the exact check (:data:`EXACT_LIMIT`).
    """
    sizes = problem.build(problem.variables.unpack(np.zeros(len(rational))), False)
    if sum(M.shape[0] for M in sizes.values()) > EXACT_LIMIT:
        return None
    mats = problem.build(problem.variables.unpack(np.array(rational, dtype=object)), True)
    return all(dominant_after_congruence(M) or leading_minors_positive(M) for M in mats.values())


def _integers(M: NDArray[Any]) -> NDArray[Any]:
    """The rational matrix ``M`` times the least common denominator of its entries: Python ints, same signs."""
    flat = M.ravel().tolist()  # Python floats, ints or Fractions
    if M.dtype != object:
        ratios = [v.as_integer_ratio() for v in flat]
    else:
        ratios = [(v.numerator, v.denominator) if isinstance(v, (int, Fraction)) else Fraction(v).as_integer_ratio()
                  for v in flat]  # fmt: skip
    den = math.lcm(1, *(d for _, d in ratios))
    out = np.empty(M.shape, dtype=object)
    out.ravel()[:] = [n * (den // d) for n, d in ratios]
    return out


def _upper_congruence(X: NDArray[Any], M: NDArray[Any]) -> NDArray[Any]:
    """X' M X exactly, for X upper triangular and M symmetric (Python ints): the zeros and the symmetry skipped.

    Row i of X' M involves only X[:i+1, i]; column j of (X' M) X only rows :j+1 of X; and the
    result is symmetric, so only its upper triangle is formed and mirrored: about 0.8 m^3
    products instead of 2 m^3.
    """
    m = X.shape[0]
    Y = np.empty((m, m), dtype=object)
    for i in range(m):
        Y[i] = X[: i + 1, i] @ M[: i + 1]
    T = np.empty((m, m), dtype=object)
    for j in range(m):
        T[: j + 1, j] = Y[: j + 1, : j + 1] @ X[: j + 1, j]
        T[j, :j] = T[:j, j]
    return T


def dominant_after_congruence(M: NDArray[Any]) -> bool:
    """A fast exact sufficient test of positive definiteness: X' M X strictly diagonally dominant.

    X = L^-T from a floating-point Cholesky factor L of M (so X' M X is close to
    the identity) is a matrix of floats, hence of exact dyadic rationals; the
    product X' M X is formed exactly in integers (both scaled by a common
    denominator). A symmetric matrix with a positive diagonal that is strictly
    diagonally dominant is positive definite (Gershgorin), and X is triangular
    with a non-zero diagonal (its entries below the diagonal set to 0 exactly), so M is then
    positive definite too (Sylvester's law of inertia). M must be symmetric (checked exactly: a
    matrix that is not is rejected), and X' M X is then formed as a symmetric matrix
    (:func:`_upper_congruence`). False means only "not shown this way": the products
    stay the size of the entries, where Bareiss's minors grow with the
    dimension, so this is much cheaper when it succeeds.
    """
    approx = np.array([[float(v) for v in row] for row in M])
    try:
        L = np.linalg.cholesky(0.5 * (approx + approx.T))
    except np.linalg.LinAlgError:
        return False
    X = scipy.linalg.solve_triangular(L, np.eye(L.shape[0]), lower=True).T
    if not np.all(np.isfinite(X)) or np.any(np.diag(X) == 0.0):
        return False
    Mi = _integers(M)
    if any(Mi[i, j] != Mi[j, i] for i in range(Mi.shape[0]) for j in range(i)):
        return False  # not symmetric: the test below is for symmetric matrices only
    T = _upper_congruence(_integers(np.triu(X)), Mi)
    diag = np.diagonal(T)
    off = np.sum(np.abs(T), axis=1) - diag
    return bool(all(d > 0 for d in diag) and all(d > o for d, o in zip(diag, off, strict=True)))


def recheck(problem: LmiProblem, x: NDArray[np.float64], *, exact: bool = True) -> Recheck:
    """Rebuild every LMI matrix from rounded variables and check it positive definite twice.

    Parameters
    ----------
    problem
        The LMI problem.
    x
        The decision variables the solver returned (never trusted: only re-checked).
    exact
        Also run the exact check (False: only the eigenvalues, ``exact_ok`` None;
        :func:`exact_check` can complete it later).
    """
    rational = tuple(_dyadic(x))
    xr = np.array([float(v) for v in rational])  # exact: |v| 2^40 < 2^53 for the bounded variables
    values = problem.variables.unpack(xr)
    mats = {k: np.asarray(v, dtype=float) for k, v in problem.build(values, False).items()}
    rel: dict[str, float] = {}
    ok = True
    # the exact check follows wherever it can run: there the matrices are judged after scaling to a unit
    # diagonal (a filter only: the proof is exact); where it cannot, by the plain relative eigenvalue
    scaled = sum(M.shape[0] for M in mats.values()) <= EXACT_LIMIT
    for k, M in mats.items():
        if not np.all(np.isfinite(M)) or not np.allclose(M, M.T, rtol=0.0, atol=1e-12 * max(1.0, np.abs(M).max())):
            rel[k] = -math.inf
            ok = False
            continue
        rel[k] = _relative_min_eigenvalue(0.5 * (M + M.T), scaled)
        ok = ok and rel[k] > EIG_MARGIN
    done = exact_check(problem, rational) if ok and exact else None
    return Recheck(values, rational, mats, rel, ok, done)
