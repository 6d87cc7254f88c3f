"""Communication topologies, the matrix C and its eigenvalues.

Conventions (as in the paper, Section "Consensus Protocol"):

* Row i of the adjacency matrix is what agent i receives: ``a_ik = 1`` when
  agent i receives from agent k (k is an *informer* of i). No self-loops.
* An edge ``(k, i)`` in an edge list or a networkx digraph points from the
  informer k to the receiver i, the direction information flows.
* The in-degree of agent i is the row sum ``delta_i``; the protocol averages
  over informers, so every agent needs at least one.
* ``C = Delta^-1 A`` is row-stochastic: it always has the eigenvalue 1, the
  *centroid* (rigid-body) eigenvalue of the paper's eq. 4.

Agents are labelled 0..n-1 unless the topology came from a networkx graph or
a named builder that uses the paper's labels (``paper_six`` uses 1..6);
error messages name agents by label.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import csgraph

from delayform._validation import validated
from delayform.errors import NoSpanningTreeError, TopologyError

__all__ = [
    "Topology",
    "EigenvalueGroup",
    "paper_six",
    "ring",
    "complete",
    "star",
    "random_digraph",
    "grid",
    "DENSE_LIMIT",
]

#: Above this many agents, :attr:`Topology.C` and :attr:`Topology.adjacency`
#: are scipy.sparse arrays; at or below it, dense NumPy arrays.
DENSE_LIMIT = 1000

#: Eigenvalues of C closer than this are one group. Numerical eigenvalues of
#: a defective C split like eps**(1/k) for a Jordan block of size k, so the
#: tolerance must be far above eps; the mean of a split cluster is accurate
#: to about eps (the trace is preserved), and that mean is what we keep.
EIGENVALUE_CLUSTER_TOL = 1e-5


@validated(TopologyError)
@dataclass(frozen=True)
class EigenvalueGroup:
    """One distinct eigenvalue of C, or one complex-conjugate pair.

    Attributes
    ----------
    lam
        The eigenvalue; for a pair, the member with positive imaginary part.
    multiplicity
        Algebraic multiplicity of ``lam`` (of each member of a pair).
    is_complex_pair
        True when ``lam`` and its conjugate form one fourth-order factor of
        the paper's eq. 3.
    is_centroid
        True for lam = 1, the eigenvalue of the centroid factor (paper, eq. 4).
    """

    lam: complex
    multiplicity: int
    is_complex_pair: bool
    is_centroid: bool

    @property
    def factor_order(self) -> int:
        """Order in s of the factor this group makes in the paper's eq. 3 (2 or 4)."""
        return 4 if self.is_complex_pair else 2


def _as_label_tuple(labels: Sequence[Hashable] | None, n: int) -> tuple[Hashable, ...]:
    if labels is None:
        return tuple(range(n))
    out = tuple(labels)
    if len(out) != n:
        raise TopologyError(f"labels has {len(out)} entries for {n} agents")
    if len(set(out)) != n:
        raise TopologyError("labels must be distinct")
    return out


@validated(TopologyError)
@dataclass(frozen=True, eq=False)
class Topology:
    """A directed communication topology of n agents (paper, eq. 1).

    Build one with :meth:`from_adjacency`, :meth:`from_edges`,
    :meth:`from_networkx` or a named builder (:func:`paper_six`, :func:`ring`,
    :func:`complete`, :func:`star`, :func:`random_digraph`).

    Examples
    --------
    >>> from delayform.topology import ring
    >>> ring(3).C
    array([[0., 0., 1.],
           [1., 0., 0.],
           [0., 1., 0.]])
    """

    adjacency_sparse: sp.csr_array
    labels: tuple[Hashable, ...] = field(default=())
    name: str = "custom"

    def __post_init__(self) -> None:
        n = self.adjacency_sparse.shape[0]
        object.__setattr__(self, "labels", _as_label_tuple(self.labels or None, n))

    # ------------------------------------------------------------------ build
    @classmethod
    def from_adjacency(
        cls,
        A: ArrayLike | sp.sparray | sp.spmatrix,
        *,
        labels: Sequence[Hashable] | None = None,
        name: str = "custom",
    ) -> Topology:
        """Topology from a binary adjacency matrix, ``a_ik = 1`` when i receives from k.

        Raises
        ------
        TopologyError
            For a matrix that is not square, not binary, has self-loops, or
            leaves an agent without informers.
        """
        if sp.issparse(A):
            mat = sp.csr_array(A, dtype=np.float64)
        else:
            try:
                dense = np.asarray(A, dtype=np.float64)
            except (TypeError, ValueError) as exc:
                raise TopologyError("adjacency must be a numeric square matrix") from exc
            if dense.ndim != 2:
                raise TopologyError(f"adjacency must be a 2-D matrix, got {dense.ndim} dimension(s)")
            mat = sp.csr_array(dense)
        rows, cols = mat.shape
        if rows != cols:
            raise TopologyError(f"adjacency must be square, got shape {rows}x{cols}")
        if rows == 0:
            raise TopologyError("adjacency must describe at least one agent")
        mat.eliminate_zeros()
        data = mat.data
        if not np.all(np.isfinite(data)) or not np.all(data == 1.0):
            bad = data[~(data == 1.0)][:3]
            raise TopologyError(f"adjacency must be binary (0 or 1), found entries {bad.tolist()}")
        label_tuple = _as_label_tuple(labels, rows)
        diag = mat.diagonal()
        if np.any(diag != 0):
            agents = [label_tuple[i] for i in np.flatnonzero(diag)]
            raise TopologyError(f"self-loops are not allowed (a_ii = 1 for agents {agents})")
        indeg = np.asarray(mat.sum(axis=1)).ravel()
        if np.any(indeg == 0):
            agents = [label_tuple[i] for i in np.flatnonzero(indeg == 0)]
            raise TopologyError(
                f"agents {agents} have no informer; protocol (paper, eq. 1) averages over informers"
            )
        mat.sort_indices()
        return cls(adjacency_sparse=mat, labels=label_tuple, name=name)

    @classmethod
    def from_edges(
        cls,
        edges: Iterable[tuple[int, int]],
        n: int | None = None,
        *,
        name: str = "custom",
    ) -> Topology:
        """Topology from pairs ``(informer, receiver)`` of agent indices 0..n-1.

        ``n`` defaults to one more than the largest index. Duplicate edges
        are one edge.
        """
        try:
            pairs = list(edges)
            raw = np.asarray(pairs)
        except (TypeError, ValueError) as exc:
            raise TopologyError("edges must be pairs of integer agent indices") from exc
        # numpy turns True into 1 silently; a bool names no agent
        has_bool = any(
            isinstance(v, (bool, np.bool_)) for pair in pairs if isinstance(pair, (tuple, list)) for v in pair
        )
        if has_bool:
            raise TopologyError("agent indices in edges must be integers, got True or False")
        if raw.size and raw.dtype.kind not in "iu":
            # an index like 1.5 (or True) names no agent: refuse instead of truncating it
            flat = raw.astype(object).ravel().tolist()
            bad = [v for v in flat if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer))]
            if bad:
                raise TopologyError(f"agent indices in edges must be integers, got {bad[0]!r}")
        arr = raw.astype(np.int64) if raw.size else np.zeros((0, 2), dtype=np.int64)
        if arr.size == 0:
            raise TopologyError("edges is empty: every agent needs an informer")
        if arr.ndim != 2 or arr.shape[1] != 2:
            raise TopologyError("edges must be pairs (informer, receiver)")
        if np.any(arr < 0):
            raise TopologyError("agent indices in edges must be non-negative")
        size = int(arr.max()) + 1 if n is None else int(n)
        if arr.max() >= size:
            raise TopologyError(f"edge names agent {int(arr.max())} but n = {size}")
        informer, receiver = arr[:, 0], arr[:, 1]
        mat = sp.csr_array(
            (np.ones(len(arr)), (receiver, informer)), shape=(size, size), dtype=np.float64
        )
        mat.data[:] = 1.0  # duplicates were summed
        return cls.from_adjacency(mat, name=name)

    @classmethod
    def from_networkx(cls, G: object, *, name: str = "networkx") -> Topology:
        """Topology from a networkx graph; an edge u -> v means v receives from u.

        An undirected graph is taken as bidirectional links. Node labels are kept.
        """
        import networkx as nx

        if not isinstance(G, nx.Graph):
            raise TopologyError(f"expected a networkx graph, got {type(G).__name__}")
        nodes = list(G.nodes)
        # networkx rows are sources; protocol rows are receivers: transpose.
        out_adj = nx.to_scipy_sparse_array(G, nodelist=nodes, weight=None, format="csr")
        return cls.from_adjacency(sp.csr_array(out_adj.T), labels=nodes, name=name)

    # -------------------------------------------------------------- matrices
    @property
    def n(self) -> int:
        """Number of agents."""
        return int(self.adjacency_sparse.shape[0])

    @property
    def adjacency(self) -> NDArray[np.float64] | sp.csr_array:
        """Adjacency matrix A, dense up to :data:`DENSE_LIMIT` agents, sparse above."""
        if self.n <= DENSE_LIMIT:
            return self.adjacency_sparse.toarray()
        return self.adjacency_sparse

    @cached_property
    def in_degree(self) -> NDArray[np.float64]:
        """In-degrees delta_i (number of informers of each agent)."""
        return np.asarray(self.adjacency_sparse.sum(axis=1), dtype=np.float64).ravel()

    @cached_property
    def C_sparse(self) -> sp.csr_array:
        """C = Delta^-1 A as a scipy.sparse CSR array, at any size."""
        return sp.csr_array(sp.diags_array(1.0 / self.in_degree) @ self.adjacency_sparse)

    @cached_property
    def _C_dense(self) -> NDArray[np.float64]:
        # computed once and read-only: callers share it, none may change it
        dense = self.C_sparse.toarray()
        dense.flags.writeable = False
        return dense

    @property
    def C(self) -> NDArray[np.float64] | sp.csr_array:
        """C = Delta^-1 A (paper, eq. 2), dense (read-only) up to :data:`DENSE_LIMIT` agents."""
        if self.n <= DENSE_LIMIT:
            return self._C_dense
        return self.C_sparse

    def informers(self, agent: int) -> tuple[int, ...]:
        """Indices of the agents that ``agent`` (an index) receives from."""
        row = self.adjacency_sparse.indices[
            self.adjacency_sparse.indptr[agent] : self.adjacency_sparse.indptr[agent + 1]
        ]
        return tuple(int(k) for k in row)

    def edges(self) -> list[tuple[int, int]]:
        """Edges as pairs (informer, receiver) of agent indices."""
        coo = self.adjacency_sparse.tocoo()
        return sorted(zip(coo.col.tolist(), coo.row.tolist(), strict=True))

    def to_networkx(self) -> object:
        """The topology as a networkx DiGraph, edges from informer to receiver."""
        import networkx as nx

        G = nx.DiGraph()
        G.add_nodes_from(self.labels)
        G.add_edges_from((self.labels[k], self.labels[i]) for k, i in self.edges())
        return G

    # ---------------------------------------------------------- graph facts
    def has_spanning_tree(self) -> bool:
        """True when some agent's information reaches every agent (a rooted spanning tree).

        Equivalent: the condensation of the information-flow graph has
        exactly one strongly connected component without incoming edges.
        """
        return self._spanning_tree

    @cached_property
    def _spanning_tree(self) -> bool:
        # every certified root call checks it (Lemma 3); the team is frozen
        n_comp, comp = csgraph.connected_components(
            self.adjacency_sparse, directed=True, connection="strong"
        )
        if n_comp == 1:
            return True
        coo = self.adjacency_sparse.tocoo()
        # edge informer (col) -> receiver (row); a component fed from outside is not a source.
        fed = comp[coo.row][comp[coo.row] != comp[coo.col]]
        sources = n_comp - np.unique(fed).size
        return bool(sources == 1)

    def require_spanning_tree(self) -> None:
        """Raise :class:`NoSpanningTreeError` unless :meth:`has_spanning_tree`."""
        if not self.has_spanning_tree():
            raise NoSpanningTreeError(
                f"topology '{self.name}' has no spanning tree: the protocol cannot reach "
                "consensus or formation for any gains or delays (Lemma 3)"
            )

    # ----------------------------------------------------------- eigenvalues
    @cached_property
    def eigenvalues(self) -> NDArray[np.complex128]:
        """All n eigenvalues of C, sorted by decreasing real part then imaginary part."""
        vals = _circulant_eigenvalues(self.C_sparse)
        if vals is None:
            from delayform.resources import require

            # dense eigenvalues: about 5 copies of n x n doubles and ~25 n^3 flops at ~5 Gflop/s
            require(
                what=f"the eigenvalues of C for {self.n} agents",
                setting="the number of agents (topology.n, --n)",
                nbytes=5 * 8.0 * self.n**2,
                seconds=25 * float(self.n) ** 3 / 5e9,
            )
            C = self._C_dense if self.n <= DENSE_LIMIT else self.C_sparse.toarray()
            vals = np.linalg.eigvals(C).astype(np.complex128)
        order = np.lexsort((-vals.imag, -vals.real))
        return vals[order]

    @cached_property
    def eigenvalue_groups(self) -> tuple[EigenvalueGroup, ...]:
        """Eigenvalues of C grouped as the paper's eq. 3 groups them.

        Real eigenvalues each give a second-order factor, complex-conjugate
        pairs a fourth-order one; equal eigenvalues are one group with a
        multiplicity. Order: centroid (lam = 1) first, then real groups by
        decreasing value, then pairs by decreasing real part.
        """
        return _group_eigenvalues(self.eigenvalues)

    def __repr__(self) -> str:
        return f"Topology(name={self.name!r}, n={self.n}, edges={self.adjacency_sparse.nnz})"


def _cluster(values: NDArray[np.complex128], tol: float) -> list[NDArray[np.complex128]]:
    """Split ``values`` into clusters whose members chain within ``tol``."""
    if values.size == 0:
        return []
    from scipy.spatial import cKDTree

    points = np.column_stack([values.real, values.imag])
    pairs = cKDTree(points).query_pairs(tol, output_type="ndarray")
    graph = sp.csr_array(
        (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(values.size, values.size)
    )
    n_comp, labels = csgraph.connected_components(graph, directed=False)
    return [values[labels == k] for k in range(n_comp)]


def _circulant_eigenvalues(C: sp.csr_array) -> NDArray[np.complex128] | None:
    """Eigenvalues of a circulant C (C[i, j] depends on (j - i) mod n only), else None.

    Rings and other cyclic topologies are circulant; their eigenvalues are the
    discrete Fourier transform of the first row (O(n log n) instead of a dense
    O(n^3) eigenvalue problem), made exactly conjugate-symmetric.
    """
    n = C.shape[0]
    coo = C.tocoo()
    if n < 3 or coo.nnz == 0 or coo.nnz % n:
        return None
    offset = (coo.col - coo.row) % n
    first = np.zeros(n)
    row0 = coo.row == 0
    first[offset[row0]] = coo.data[row0]
    if np.count_nonzero(first) * n != coo.nnz or not np.array_equal(first[offset], coo.data):
        return None
    vals = np.fft.fft(first)
    k = np.arange(1, (n + 1) // 2)
    vals[n - k] = np.conj(vals[k])
    vals[0] = vals[0].real
    if n % 2 == 0:
        vals[n // 2] = vals[n // 2].real
    return vals.astype(np.complex128)


def _group_eigenvalues(vals: NDArray[np.complex128]) -> tuple[EigenvalueGroup, ...]:
    tol = EIGENVALUE_CLUSTER_TOL
    scale = max(1.0, float(np.max(np.abs(vals)))) if vals.size else 1.0
    groups: list[EigenvalueGroup] = []
    upper = vals[vals.imag > tol * scale]
    realish = vals[np.abs(vals.imag) <= tol * scale]
    for cluster in _cluster(realish, tol * scale):
        lam = complex(cluster.real.mean(), 0.0)
        centroid = abs(lam - 1.0) <= tol
        if centroid:
            lam = 1.0 + 0.0j  # exactly: C is row-stochastic
        groups.append(EigenvalueGroup(lam, int(cluster.size), False, centroid))
    for cluster in _cluster(upper, tol * scale):
        lam = complex(cluster.mean())
        groups.append(EigenvalueGroup(lam, int(cluster.size), True, False))
    groups.sort(
        key=lambda g: (not g.is_centroid, g.is_complex_pair, -g.lam.real, -g.lam.imag)
    )
    return tuple(groups)


# ---------------------------------------------------------------- builders
@validated(TopologyError)
def paper_six() -> Topology:
    """The six-agent topology of the paper's Fig. 2.

    Informers: 1:{2,5}, 2:{1,5}, 3:{1,5,6}, 4:{2,6}, 5:{1,4}, 6:{3,4}.
    C has eigenvalues {1, 0.46, -0.5, -0.64, -0.16 +- 0.21j}.
    Labels are the paper's 1..6.
    """
    informers = {1: (2, 5), 2: (1, 5), 3: (1, 5, 6), 4: (2, 6), 5: (1, 4), 6: (3, 4)}
    A = np.zeros((6, 6))
    for i, ks in informers.items():
        for k in ks:
            A[i - 1, k - 1] = 1.0
    return Topology.from_adjacency(A, labels=range(1, 7), name="paper_six")


def _check_count(n: object, minimum: int, what: str) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < minimum:
        raise TopologyError(f"{what} needs an integer number of agents >= {minimum}, got {n!r}")
    return int(n)


@validated(TopologyError)
def ring(n: int) -> Topology:
    """Directed cycle: agent i receives from agent i-1 (mod n)."""
    n = _check_count(n, 2, "ring")
    _require_team(n, n, f"a ring of {n} agents")
    idx = np.arange(n)
    return Topology.from_adjacency(_sparse_edges((idx - 1) % n, idx, n), name=f"ring({n})")


def _sparse_edges(informer: NDArray[np.int64], receiver: NDArray[np.int64], n: int) -> sp.csr_array:
    """The adjacency of the edges ``informer -> receiver``, built in NumPy (no Python loop over edges)."""
    return sp.csr_array((np.ones(receiver.size), (receiver, informer)), shape=(n, n))


#: measured while building 10^6 agents under load (ring, star, grid: 148, 219, 332 bytes and 2.4, 3.4,
#: 2.8 microseconds per agent): the labels, degrees and C per agent, the index arrays per edge
_BYTES_PER_AGENT, _BYTES_PER_EDGE = 150.0, 40.0
_SECONDS_PER_AGENT, _SECONDS_PER_EDGE = 2e-6, 5e-7


def _require_team(n: float, edges: float, what: str, setting: str | None = None) -> None:
    """Refuse, before anything is allocated, a team whose building would not fit the machine.

    The one estimate for a team's size, whoever asked for it: ``--n``, ``topology.n`` in a
    scenario file or a library call (:mod:`delayform.resources`).
    """
    from delayform.resources import require

    require(what=f"{what} (about {edges:.3g} edges)",
            setting=setting or "the number of agents (topology.n, --n)",
            nbytes=_BYTES_PER_AGENT * n + _BYTES_PER_EDGE * edges,
            seconds=_SECONDS_PER_AGENT * n + _SECONDS_PER_EDGE * edges)  # fmt: skip


@validated(TopologyError)
def complete(n: int) -> Topology:
    """Every agent receives from every other; C has eigenvalues 1 and -1/(n-1)."""
    n = _check_count(n, 2, "complete")
    _require_team(n, float(n) * (n - 1), f"a complete graph of {n} agents")
    A = np.ones((n, n)) - np.eye(n)
    return Topology.from_adjacency(A, name=f"complete({n})")


@validated(TopologyError)
def star(n: int) -> Topology:
    """Hub 0 linked both ways with each of the leaves 1..n-1."""
    n = _check_count(n, 2, "star")
    _require_team(n, 2.0 * (n - 1), f"a star of {n} agents")
    leaves = np.arange(1, n)
    hub = np.zeros_like(leaves)
    informer, receiver = np.concatenate([hub, leaves]), np.concatenate([leaves, hub])
    return Topology.from_adjacency(_sparse_edges(informer, receiver, n), name=f"star({n})")


@validated(TopologyError)
def random_digraph(n: int, p: float, seed: int | np.random.Generator | None = None) -> Topology:
    """Random digraph with a spanning tree: a directed ring plus each other edge with probability p.

    The ring guarantees every agent an informer and a spanning tree, so the
    result is always a valid formation topology; ``p`` sets how dense it is.
    For large n the extra edges are drawn sparsely (expected n*(n-1)*p of them).

    Parameters
    ----------
    n
        Number of agents, at least 2.
    p
        Probability of each extra directed edge, 0 <= p <= 1.
    seed
        Seed or generator for the draw; the same seed gives the same topology.

    Examples
    --------
    >>> t = random_digraph(8, 0.2, seed=1)
    >>> t.n, t.has_spanning_tree()
    (8, True)
    """
    n = _check_count(n, 2, "random_digraph")
    if not isinstance(p, (bool, np.bool_)) and isinstance(p, (int, float, np.floating)):
        _require_team(n, n + float(n) * (n - 1) * float(p), f"a random digraph of {n} agents with p = {float(p):g}",
                      "the number of agents (topology.n, --n) or the edge probability (topology.p, --p)")  # fmt: skip
    if isinstance(p, (bool, np.bool_)) or not (isinstance(p, (int, float, np.floating)) and 0.0 <= float(p) <= 1.0):
        raise TopologyError(f"random_digraph needs a probability 0 <= p <= 1, got {p!r}")
    rng = np.random.default_rng(seed)
    if n <= 2000:
        mask = rng.random((n, n)) < p
        receiver, informer = np.nonzero(mask)
    else:
        count = rng.binomial(n * (n - 1), float(p))
        receiver = rng.integers(0, n, size=count)
        informer = rng.integers(0, n, size=count)
    keep = receiver != informer
    idx = np.arange(n)
    rows = np.concatenate([receiver[keep], idx])
    cols = np.concatenate([informer[keep], (idx - 1) % n])
    mat = sp.csr_array((np.ones(rows.size), (rows, cols)), shape=(n, n))
    mat.data[:] = 1.0
    return Topology.from_adjacency(mat, name=f"random_digraph({n}, {float(p):g})")


@validated(TopologyError)
def grid(rows: int, cols: int) -> Topology:
    """Undirected 2-D grid graph: agent ``r * cols + c`` linked both ways with its 4 lattice neighbours.

    A communication topology; the formation *shape* with agents in rows and
    columns is :func:`delayform.formation.block`.

    C of an undirected graph is similar to a symmetric matrix, so its
    spectrum is real in [-1, 1]; a grid is bipartite, so -1 is an eigenvalue.
    Built sparse, so 10^5-10^6 agents take well under a second.

    Parameters
    ----------
    rows, cols
        Grid size, each at least 1 and ``rows * cols >= 2``.

    Examples
    --------
    >>> t = grid(2, 3)
    >>> t.n, int(t.adjacency_sparse.nnz)
    (6, 14)
    """
    r = _check_count(rows, 1, "grid rows")
    c = _check_count(cols, 1, "grid cols")
    if r * c < 2:
        raise TopologyError("grid needs at least 2 agents")
    _require_team(float(r) * c, 4.0 * r * c, f"a {r} x {c} grid of agents", "the grid size (rows, cols)")
    idx = np.arange(r * c).reshape(r, c)
    pairs = [np.column_stack([idx[:, :-1].ravel(), idx[:, 1:].ravel()]),
             np.column_stack([idx[:-1, :].ravel(), idx[1:, :].ravel()])]
    e = np.concatenate(pairs)
    rows_ = np.concatenate([e[:, 0], e[:, 1]])
    cols_ = np.concatenate([e[:, 1], e[:, 0]])
    mat = sp.csr_array((np.ones(rows_.size), (rows_, cols_)), shape=(r * c, r * c))
    return Topology.from_adjacency(mat, name=f"grid({r}x{c})")
