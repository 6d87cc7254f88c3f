"""Bounds on the spectrum of C for teams too large for dense eigenvalues (10^4 to 10^6 agents).

A team is stable at (tau1, tau2) when every eigenvalue of C (1 aside) lies
in the stable region of the eigenvalue plane, so a *set* that holds the
spectrum gives a certified **sufficient** answer: the delays that are safe for
the set (:func:`delayform.analysis.plane.spectrum_sets.safe_delays`) are stable for
the team. It is not necessary: delays outside may still be stable for this
particular team.

Undirected teams
----------------
``C = Delta^-1 A`` is similar to ``S = Delta^-1/2 A Delta^-1/2`` (symmetric),
so its spectrum is real and lies in [-1, 1]; ``S`` has the eigenvector
``Delta^1/2 1`` for the eigenvalue 1. The bound is an interval [low, high]:

* ``low = -1`` for a bipartite graph (then -1 is an eigenvalue); otherwise
  the smallest eigenvalue is estimated by shift-invert Lanczos
  (``scipy.sparse.linalg.eigsh``) near -1 and ``low`` is the estimate minus
  its residual norm and a margin, *certified* by Sylvester's law of inertia:
  ``S - low I`` is factored as ``L D L^T`` (sparse LU with diagonal pivots,
  symmetric ordering) and must have no negative pivot.
* ``high``: the second largest eigenvalue is estimated the same way near 1,
  and ``high`` = estimate + residual + margin is certified when ``S - high I``
  has exactly one positive pivot (the eigenvalue 1).

Before any factorization the memory it needs is estimated
(:func:`factor_memory_estimate`); above :data:`FACTOR_MEMORY_BUDGET` the
ends stay at the theorem's -1 and 1 and the method says why.
When a certificate fails (tiny pivots, an unsymmetric pivot order), the
corresponding end falls back to the theorem's -1 or 1, so the bound is always
valid. Rounding in the factorization is the only thing assumed: pivots
closer to 0 than 1e-10 of the matrix norm reject the certificate.

Directed teams
--------------
C has a zero diagonal and rows summing to 1, so Gershgorin's discs are all
the unit disc: the bound is the closed unit disc (``"any"``), the only bound
that holds for every directed team. For P = 1, D = 0.5 no delay pair is safe
for it (docs/theory.md), so for directed teams the sufficient answer is empty
there; compute the dense eigenvalues (:func:`delayform.analysis.ctcr.stability_map.stability_map`)
while the team is small enough.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.sparse import csgraph

from delayform._validation import validated
from delayform.analysis.plane.spectrum_sets import ANY, UNDIRECTED, SpectrumSet
from delayform.errors import InputError
from delayform.resources import memory_limit
from delayform.topology import Topology

__all__ = ["SpectrumBound", "spectrum_bound", "factor_memory_estimate", "FACTOR_MEMORY_BUDGET", "DENSE_BOUND_LIMIT"]

#: Below this many agents the bound comes from dense symmetric eigenvalues.
DENSE_BOUND_LIMIT = 2000
#: Largest estimated memory (bytes) a sparse factorization may take (and at most the job limit of
#: :func:`delayform.resources.memory_limit`); above it the ends stay -1 and 1.
FACTOR_MEMORY_BUDGET = 12 * 2**30
_PIVOT_TOL = 1e-10


def factor_memory_estimate(A: sp.csr_array) -> int:
    """Bytes of an envelope (skyline) LDL^T factor of a symmetric pattern in reverse Cuthill-McKee order.

    An upper estimate of what the sparse factorizations here take (their
    minimum-degree ordering fills in less: about 2.1 GiB in all for a
    1000 x 1000 grid, whose envelope estimate is 10 GiB), cheap to compute, and large for graphs that
    do not factor well (expanders, random graphs), which is what it guards against.

    Parameters
    ----------
    A
        Symmetric sparse adjacency (or any matrix with its pattern).
    """
    perm = csgraph.reverse_cuthill_mckee(sp.csr_array(A), symmetric_mode=True)
    B = sp.csr_array(A)[perm][:, perm].tocoo()
    first = np.arange(A.shape[0])
    np.minimum.at(first, B.row, B.col)
    profile = int(np.sum(np.arange(A.shape[0]) - first)) + A.shape[0]
    return 2 * 8 * profile  # L and the pivots' bookkeeping, float64


@validated()
@dataclass(frozen=True)
class SpectrumBound:
    """A set holding every eigenvalue of a team's C, and how it was obtained.

    Attributes
    ----------
    spectrum_set
        The set (an interval for undirected teams, the unit disc otherwise);
        pass the bound itself as ``spectrum=`` to :func:`~delayform.analysis.plane.spectrum_sets.safe_delays`.
    agents
        Number of agents.
    undirected
        True when the adjacency is symmetric.
    method
        How each end was found and certified, in words.
    low_certified, high_certified
        For an interval: whether the end is certified tighter than -1 / 1.
    estimates
        Estimated smallest and second-largest eigenvalue (NaN when not computed).
    seconds
        Wall-clock time spent.
    """

    spectrum_set: SpectrumSet
    agents: int
    undirected: bool
    method: str
    low_certified: bool
    high_certified: bool
    estimates: tuple[float, float]
    seconds: float

    @property
    def is_sufficient_only(self) -> bool:
        """Always True: delays safe for the bound are stable for the team, not conversely."""
        return True


def _is_bipartite(A: sp.csr_array) -> bool:
    """Two-colouring by breadth-first levels (A symmetric, connected)."""
    order, pred = csgraph.breadth_first_order(A, 0, directed=False, return_predecessors=True)
    depth = np.zeros(A.shape[0], np.int64)
    for v in order[1:]:  # order is breadth-first: a predecessor's depth is known
        depth[v] = depth[pred[v]] + 1
    coo = A.tocoo()
    return bool(np.all((depth[coo.row] - depth[coo.col]) % 2 == 1))


def _inertia(S: sp.csc_array, mu: float) -> tuple[int, int] | None:
    """(positive, negative) eigenvalue counts of S - mu I by LDL^T pivots, or None when not trustworthy."""
    from scipy.sparse.linalg import splu

    n = S.shape[0]
    M = sp.csc_array(S - mu * sp.eye_array(n, format="csc"))
    try:
        lu = splu(M, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    except RuntimeError:  # exactly singular
        return None
    if not np.array_equal(lu.perm_r, lu.perm_c):
        return None
    piv = lu.U.diagonal()
    scale = 1.0 + abs(mu)
    if np.any(np.abs(piv) <= _PIVOT_TOL * scale):
        return None
    return int(np.sum(piv > 0)), int(np.sum(piv < 0))


def _near(S: sp.csc_array, sigma: float, deflate: NDArray[np.float64] | None) -> tuple[float, float]:
    """The eigenvalue of S nearest sigma (shift-invert Lanczos) and its residual norm.

    ``deflate`` is a known unit eigenvector projected out of the iteration
    (the eigenvector Delta^1/2 1 of the eigenvalue 1), so sigma may sit just
    above 1, where the next eigenvalues separate well after inversion.
    """
    from scipy.sparse.linalg import LinearOperator, eigsh, splu

    n = S.shape[0]
    lu = splu(sp.csc_array(S - sigma * sp.eye_array(n, format="csc")), permc_spec="MMD_AT_PLUS_A",
              diag_pivot_thresh=0.0, options={"SymmetricMode": True})

    def project(x: NDArray[np.float64]) -> NDArray[np.float64]:
        x = np.asarray(x, dtype=float).ravel()
        return x if deflate is None else x - deflate * (deflate @ x)

    op = LinearOperator((n, n), matvec=lambda x: project(lu.solve(project(x))), dtype=float)
    v0 = project(np.random.default_rng(0).standard_normal(n))  # fixed: the same bound every run
    nu, vec = eigsh(op, k=1, which="LM", v0=v0, tol=1e-12)
    lam = float(sigma + 1.0 / nu[0])
    x = vec[:, 0] / np.linalg.norm(vec[:, 0])
    lam = float(x @ (S @ x))  # the Rayleigh quotient: residual-optimal for this vector
    return lam, float(np.linalg.norm(S @ x - lam * x))


@validated()
def spectrum_bound(topology: Topology) -> SpectrumBound:
    """A certified set holding every eigenvalue of C, without computing all of them.

    Parameters
    ----------
    topology
        The team; must have a spanning tree. Any size: sparse methods above
        :data:`DENSE_BOUND_LIMIT` agents.

    Returns
    -------
    SpectrumBound
        An interval [low, high] for an undirected team (see the module
        docstring for the certificates), the closed unit disc otherwise.

    Raises
    ------
    NoSpanningTreeError, InputError

    Examples
    --------
    >>> from delayform.topology import grid
    >>> b = spectrum_bound(grid(4, 5))
    >>> b.spectrum_set.kind, b.spectrum_set.low
    ('interval', -1.0)
    """
    if not isinstance(topology, Topology):
        raise InputError(f"topology must be a Topology, got {type(topology).__name__}")
    topology.require_spanning_tree()
    start = time.perf_counter()
    A = topology.adjacency_sparse
    n = topology.n
    if (A != A.T).nnz != 0:
        return SpectrumBound(ANY, n, False, "Gershgorin: zero diagonal, rows of C sum to 1 -> unit disc",
                             False, False, (np.nan, np.nan), time.perf_counter() - start)
    h = 1.0 / np.sqrt(topology.in_degree)
    S = sp.csc_array(sp.diags_array(h) @ A @ sp.diags_array(h))
    bipartite = _is_bipartite(sp.csr_array(A))
    if n <= DENSE_BOUND_LIMIT:
        vals = np.linalg.eigvalsh(S.toarray())
        lam_min, lam2 = float(vals[0]), float(vals[-2])
        res_min = res2 = 1e-12 * n
    elif (need := factor_memory_estimate(A)) > min(FACTOR_MEMORY_BUDGET, memory_limit()):
        # the sparse factorization could exhaust the machine: keep the theorem's ends -1 and 1
        method = (f"undirected: C similar to symmetric S, spectrum in [-1, 1] (theorem); not tightened: "
                  f"a sparse factorization would need about {need / 2**30:.1f} GiB "
                  f"(budget {min(FACTOR_MEMORY_BUDGET, memory_limit()) / 2**30:.0f} GiB)")
        return SpectrumBound(UNDIRECTED, n, True, method, bipartite, False, (-1.0 if bipartite else np.nan, np.nan),
                             time.perf_counter() - start)
    else:
        v1 = np.sqrt(topology.in_degree)
        lam2, res2 = _near(S, 1.0 + 1e-7, v1 / np.linalg.norm(v1))
        if bipartite:
            lam_min, res_min = -1.0, 0.0
        else:
            lam_min, res_min = _near(S, -1.0 - 1e-7, None)
    high, high_ok = 1.0, False
    mu = lam2 + res2 + 1e-9 + 1e-6 * (1.0 - lam2)
    if mu < 1.0:
        inert = _inertia(S, mu)
        if inert is not None and inert[0] == 1:
            high, high_ok = mu, True
    low, low_ok = -1.0, bipartite
    if not bipartite:
        mu = lam_min - res_min - 1e-9 - 1e-6 * (1.0 + lam_min)
        if mu > -1.0:
            inert = _inertia(S, mu)
            if inert is not None and inert[1] == 0:
                low, low_ok = mu, True
    how = "dense symmetric eigenvalues" if n <= DENSE_BOUND_LIMIT else "shift-invert Lanczos"
    method = (
        f"undirected: C similar to symmetric S; {how}; "
        f"low {'= -1 (bipartite)' if bipartite else ('certified by LDL^T inertia' if low_ok else '= -1 (theorem)')}; "
        f"high {'certified by LDL^T inertia' if high_ok else '= 1 (theorem)'}"
    )
    spectrum = SpectrumSet.interval(low, high, label=f"bound of {topology.name}: [{low:.6g}, {high:.6g}]")
    return SpectrumBound(spectrum, n, True, method, low_ok, high_ok, (lam_min, lam2), time.perf_counter() - start)
