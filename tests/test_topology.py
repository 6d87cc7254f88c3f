"""Topologies, C and its eigenvalues (issue 2)."""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given
from hypothesis import strategies as st

from delayform.errors import InputError, NoSpanningTreeError, TopologyError
from delayform.topology import (
    DENSE_LIMIT,
    Topology,
    complete,
    paper_six,
    random_digraph,
    ring,
    star,
)


def test_paper_eigenvalues_match_the_paper():
    # Section "Simulation Examples": {1, 0.46, -0.5, -0.64, -0.16 +- j0.21}
    got = np.sort_complex(np.round(paper_six().eigenvalues, 2))
    want = np.sort_complex(np.array([1, 0.46, -0.5, -0.64, -0.16 + 0.21j, -0.16 - 0.21j]))
    np.testing.assert_array_equal(got, want)


def test_paper_groups_make_four_second_order_and_one_fourth_order_factor():
    groups = paper_six().eigenvalue_groups
    assert [g.factor_order for g in groups] == [2, 2, 2, 2, 4]
    assert groups[0].is_centroid and groups[0].lam == 1.0
    assert sum(g.is_centroid for g in groups) == 1
    assert all(g.multiplicity == 1 for g in groups)


def test_paper_informers_follow_the_figure():
    t = paper_six()
    want = {1: {2, 5}, 2: {1, 5}, 3: {1, 5, 6}, 4: {2, 6}, 5: {1, 4}, 6: {3, 4}}
    for i, ks in want.items():
        assert {t.labels[k] for k in t.informers(i - 1)} == ks
    np.testing.assert_array_equal(t.in_degree, [2, 2, 3, 2, 2, 2])


def test_builders_agree_with_each_other():
    A = paper_six().adjacency
    from_edges = Topology.from_edges(paper_six().edges(), 6)
    np.testing.assert_array_equal(from_edges.adjacency, A)
    G = nx.DiGraph()
    G.add_edges_from(paper_six().edges())  # informer -> receiver
    from_nx = Topology.from_networkx(G)
    order = list(G.nodes)
    np.testing.assert_array_equal(from_nx.adjacency, A[np.ix_(order, order)])
    back = paper_six().to_networkx()
    assert set(back.edges) == {(paper_six().labels[k], paper_six().labels[i]) for k, i in paper_six().edges()}


@pytest.mark.parametrize("n", [2, 3, 5, 9])
def test_complete_graph_has_two_eigenvalue_groups(n):
    groups = complete(n).eigenvalue_groups
    assert len(groups) == 2
    assert groups[0].is_centroid and groups[0].multiplicity == 1
    assert groups[1].lam == pytest.approx(-1.0 / (n - 1), abs=1e-12)
    assert groups[1].multiplicity == n - 1


@pytest.mark.parametrize("n", [3, 4, 7, 12])
def test_ring_eigenvalues_are_roots_of_unity(n):
    vals = ring(n).eigenvalues
    np.testing.assert_allclose(vals**n, 1.0, atol=1e-10)
    groups = ring(n).eigenvalue_groups
    n_pairs = sum(g.is_complex_pair for g in groups)
    n_real = sum(not g.is_complex_pair for g in groups)
    assert n_real + 2 * n_pairs == n
    assert n_real == (2 if n % 2 == 0 else 1)


def test_star_eigenvalues():
    groups = {round(g.lam.real, 12): g.multiplicity for g in star(6).eigenvalue_groups}
    assert groups == {1.0: 1, 0.0: 4, -1.0: 1}


def test_defective_C_groups_algebraic_multiplicity():
    # Agents 0 <-> 1; 2 hears 1; 3 hears 2; 4 hears 3: eigenvalue 0 in a Jordan block of size 3.
    t = Topology.from_edges([(0, 1), (1, 0), (1, 2), (2, 3), (3, 4)])
    zero = [g for g in t.eigenvalue_groups if abs(g.lam) < 1e-9]
    assert len(zero) == 1 and zero[0].multiplicity == 3
    # geometric multiplicity of 0 is n - rank(C) = 1 < 3: C is not diagonalizable
    assert t.n - np.linalg.matrix_rank(t.C) == 1


def _reaches_all(G: nx.DiGraph) -> bool:
    """Independent spanning-tree test: some node reaches every other by BFS."""
    return any(len(nx.descendants(G, v)) == G.number_of_nodes() - 1 for v in G.nodes)


@given(n=st.integers(2, 25), p=st.floats(0.0, 0.4), seed=st.integers(0, 10_000))
def test_spanning_tree_matches_reachability(n, p, seed):
    rng = np.random.default_rng(seed)
    A = (rng.random((n, n)) < p).astype(float)
    np.fill_diagonal(A, 0.0)
    # give every agent an informer without forcing connectivity
    for i in np.flatnonzero(A.sum(axis=1) == 0):
        A[i, (i + 1 + rng.integers(0, n - 1)) % n] = 1.0
    t = Topology.from_adjacency(A)
    G = nx.DiGraph()
    G.add_nodes_from(range(n))
    G.add_edges_from(t.edges())
    assert t.has_spanning_tree() == _reaches_all(G)


@given(n=st.integers(2, 40), p=st.floats(0.0, 0.5), seed=st.integers(0, 10_000))
def test_C_is_row_stochastic_with_centroid_eigenvalue(n, p, seed):
    t = random_digraph(n, p, seed)
    C = t.C
    np.testing.assert_allclose(C.sum(axis=1), 1.0, rtol=0, atol=1e-14)
    assert t.has_spanning_tree()
    assert np.min(np.abs(t.eigenvalues - 1.0)) < 1e-9
    groups = t.eigenvalue_groups
    assert sum(g.multiplicity * g.factor_order for g in groups) == 2 * n
    assert groups[0].is_centroid
    # groups reproduce the spectrum: the characteristic polynomial of C, as a check
    # independent of the clustering (np.poly of the raw eigenvalues)
    vals = np.concatenate(
        [np.repeat(g.lam, g.multiplicity) for g in groups]
        + [np.repeat(np.conj(g.lam), g.multiplicity) for g in groups if g.is_complex_pair]
    )
    np.testing.assert_allclose(np.poly(vals), np.poly(C), atol=1e-7)


def test_large_team_is_sparse():
    t = random_digraph(DENSE_LIMIT + 500, 0.002, seed=1)
    assert sp.issparse(t.C) and sp.issparse(t.adjacency)
    np.testing.assert_allclose(np.asarray(t.C.sum(axis=1)).ravel(), 1.0)
    assert t.has_spanning_tree()


# ------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    "A, fragment",
    [
        ([[0, 1, 0], [1, 0, 1]], "square"),
        ([[0, 2], [1, 0]], "binary"),
        ([[0, 0.5], [1, 0]], "binary"),
        ([[1, 1], [1, 0]], "self-loops"),
        ([[0, 1, 0], [1, 0, 0], [0, 0, 0]], "no informer"),
        ([1, 0, 1], "2-D"),
        ([["a", "b"], ["c", "d"]], "numeric"),
        (np.zeros((0, 0)), "at least one"),
        ([[0, np.nan], [1, 0]], "binary"),
    ],
)
def test_bad_adjacency_raises_topology_error(A, fragment):
    with pytest.raises(TopologyError, match=fragment):
        Topology.from_adjacency(A)


def test_agents_without_informers_are_named():
    with pytest.raises(TopologyError, match=r"agents \['c'\]"):
        Topology.from_adjacency([[0, 1, 0], [1, 0, 0], [0, 0, 0]], labels=["a", "b", "c"])


@pytest.mark.parametrize(
    "call",
    [
        lambda: Topology.from_edges([]),
        lambda: Topology.from_edges([(0, 1, 2)]),
        lambda: Topology.from_edges([(0, -1)]),
        lambda: Topology.from_edges([(0, 5), (5, 0)], n=3),
        lambda: Topology.from_networkx("not a graph"),
        lambda: ring(1),
        lambda: complete(2.5),
        lambda: random_digraph(5, 1.5),
    ],
)
def test_bad_builder_arguments(call):
    with pytest.raises(TopologyError):
        call()


def test_no_spanning_tree_is_named():
    two_islands = Topology.from_edges([(0, 1), (1, 0), (2, 3), (3, 2)])
    assert not two_islands.has_spanning_tree()
    with pytest.raises(NoSpanningTreeError, match="Lemma 3"):
        two_islands.require_spanning_tree()
    # errors subclass the built-ins
    assert issubclass(NoSpanningTreeError, ValueError)
    assert issubclass(TopologyError, InputError)
