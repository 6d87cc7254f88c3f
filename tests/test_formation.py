"""Tests of delayform.formation: named shapes, the forcing of eq. formation against the
paper's construction through the transform T (eq. subsystems, eq. xiss), and the
weighted centroid of eq. factor1."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delayform.errors import FormationError, NoSpanningTreeError
from delayform.formation import (
    SHAPES,
    centroid_weights,
    check_formation,
    final_centroid,
    formation_forcing,
    block,
    hexagon,
    line,
    named_formation,
    polygon,
    predicted_final_positions,
    v_shape,
)
from delayform.topology import Topology, complete, paper_six, random_digraph, ring, star

TOPOLOGIES = [paper_six(), ring(5), complete(4), star(5), random_digraph(9, 0.3, seed=2)]


# --------------------------------------------------------------- shapes
@given(n=st.integers(3, 40), spacing=st.floats(0.1, 10.0))
def test_polygon_sides_equal_spacing(n, spacing):
    pts = polygon(n, spacing=spacing)
    sides = np.linalg.norm(pts - np.roll(pts, 1, axis=0), axis=1)
    assert np.allclose(sides, spacing)
    assert np.allclose(pts.mean(axis=0), 0.0, atol=1e-9 * spacing * n)


@given(n=st.integers(1, 60), name=st.sampled_from(sorted(set(SHAPES) - {"hexagon"})))
def test_named_shapes_have_n_distinct_points(n, name):
    pts = named_formation(name, n, spacing=1.5)
    assert pts.shape == (n, 2) and np.all(np.isfinite(pts))
    if n > 1:
        d = np.linalg.norm(pts[:, None] - pts[None], axis=-1) + np.eye(n) * 1e9
        assert d.min() > 0.5  # no two agents asked to share a place


def test_line_block_v_geometry():
    assert np.allclose(np.diff(line(4, spacing=2.0)[:, 0]), 2.0)
    g = block(6)
    assert sorted({round(y, 9) for y in g[:, 1]}) == [-0.5, 0.5]  # 3 columns, 2 rows
    v = v_shape(5)
    assert np.allclose(v[1:, 1][::2], -v[1:, 1][1::2])  # the arms mirror each other
    assert np.allclose(hexagon(), polygon(6))


@pytest.mark.parametrize(
    "value, n, match",
    [
        ("pentagram", 6, "unknown formation shape"),
        ("hexagon", 5, "6 agents"),
        (np.zeros((5, 2)), 6, "5 agents"),
        (np.zeros((6, 3)), 6, "shape"),
        (np.full((6, 2), np.nan), 6, "finite"),
        ([["a", "b"]], 1, "array"),
    ],
)
def test_bad_formations_raise_formation_error(value, n, match):
    with pytest.raises(FormationError, match=match):
        check_formation(value, n)


# --------------------------------------------------------------- forcing
def paper_forcing(topology: Topology, P: float, desired: np.ndarray) -> np.ndarray:
    """F by the paper's route: real Jordan (real eigen) transform T, subsystems, back.

    Columns of T: a real eigenvector for each real lam; for a pair lam = a + jb with
    eigenvector u + jw, the columns (u, -w), so that T^-1 C T = blockdiag(J_i) with
    J_i = [[a, -b], [b, a]] as in eq. matrices4. In each subsystem (eq. subsystems)
    at rest the velocity rows give 0 = P (lam - 1) xi + phi (eq. xiss, 2nd order) and
    0 = P (J_i - I) xi + phi (4th order); the centroid forcing is zero.
    Valid for a diagonalizable C (all the topologies here).
    """
    C = np.asarray(topology.C)
    vals, vecs = np.linalg.eig(C)
    cols, blocks = [], []
    for k, lam in enumerate(vals):
        if abs(lam.imag) < 1e-9:
            cols.append(vecs[:, k].real)
            blocks.append(np.array([[lam.real]]))
        elif lam.imag > 0:
            cols += [vecs[:, k].real, -vecs[:, k].imag]
            blocks.append(np.array([[lam.real, -lam.imag], [lam.imag, lam.real]]))
    T = np.column_stack(cols)
    assert np.linalg.cond(T) < 1e8  # diagonalizable
    xi = np.linalg.solve(T, desired)  # xi_inf = T^-1 z_inf, positions only (per coordinate)
    phi = np.zeros_like(xi)
    row = 0
    for J in blocks:
        m = J.shape[0]
        is_centroid = m == 1 and abs(J[0, 0] - 1.0) < 1e-9
        if not is_centroid:  # the centroid dynamics is left undisturbed
            phi[row : row + m] = -P * (J - np.eye(m)) @ xi[row : row + m]
        row += m
    # T^-1 C T is the block diagonal of the J's: the transform is what the paper uses
    Jfull = np.zeros((row, row))
    r = 0
    for J in blocks:
        Jfull[r : r + J.shape[0], r : r + J.shape[0]] = J
        r += J.shape[0]
    assert np.allclose(np.linalg.solve(T, C @ T), Jfull, atol=1e-9)
    return T @ phi  # F = (T (x) I2) phi, velocity rows


@pytest.mark.parametrize("topology", TOPOLOGIES, ids=lambda t: t.name)
def test_forcing_equals_paper_construction_through_T(topology, rng):
    desired = rng.normal(size=(topology.n, 2))
    F = formation_forcing(topology, 1.7, desired)
    assert np.allclose(F, paper_forcing(topology, 1.7, desired), atol=1e-9)


def test_paper_eq_xiss_fourth_order_uses_the_transposed_block():
    # At rest, a 4th-order subsystem with J_i of eq. matrices4 gives phi = -P (J - I) xi.
    # eq. xiss as printed, xi = -(J - I) phi / (P |lam - 1|^2), inverts that only with
    # J^T in place of J (the transform with columns (u, w) instead of (u, -w)); the
    # library sidesteps the question with F = P (I - C) z (see paper_forcing).
    P, lam = 1.0, complex(-0.16, 0.21)
    J = np.array([[lam.real, -lam.imag], [lam.imag, lam.real]])
    xi = np.array([0.7, -1.1])
    printed = lambda phi: -(J - np.eye(2)) @ phi / (P * abs(lam - 1) ** 2)  # noqa: E731
    assert not np.allclose(printed(-P * (J - np.eye(2)) @ xi), xi)
    assert np.allclose(printed(-P * (J.T - np.eye(2)) @ xi), xi)


def test_forcing_holds_the_desired_formation_at_rest():
    # eq. formation at rest with z = desired: P (C - I) z + F = 0, for any delays
    topo = paper_six()
    z = named_formation("hexagon", 6)
    F = formation_forcing(topo, 2.0, z)
    assert np.allclose(2.0 * (topo.C @ z - z) + F, 0.0, atol=1e-12)


@settings(max_examples=20)
@given(seed=st.integers(0, 10_000), shift=st.tuples(st.floats(-50, 50), st.floats(-50, 50)))
def test_forcing_ignores_translation_and_spares_the_centroid(seed, shift):
    rng = np.random.default_rng(seed)
    topo = TOPOLOGIES[seed % len(TOPOLOGIES)]
    z = rng.normal(size=(topo.n, 2))
    F = formation_forcing(topo, 1.0, z)
    assert np.allclose(formation_forcing(topo, 1.0, z + np.array(shift)), F, atol=1e-9)
    assert np.allclose(centroid_weights(topo) @ F, 0.0, atol=1e-12)


def test_consensus_needs_no_forcing():
    assert np.all(formation_forcing(ring(4), 1.0, np.ones((4, 2))) == 0.0)


# -------------------------------------------------------------- centroid
@pytest.mark.parametrize("topology", TOPOLOGIES + [random_digraph(1200, 3 / 1200, seed=1)],
                         ids=lambda t: t.name)
def test_centroid_weights_are_the_left_eigenvector(topology):
    w = centroid_weights(topology)
    assert np.isclose(w.sum(), 1.0) and np.all(w > -1e-12)
    assert np.allclose(topology.C_sparse.T @ w, w, atol=1e-10)
    if topology.n <= 50:  # against numpy's eigenvectors
        vals, vecs = np.linalg.eig(np.asarray(topology.C).T)
        ref = np.real(vecs[:, np.argmin(np.abs(vals - 1.0))])
        assert np.allclose(w, ref / ref.sum())


def test_centroid_weights_need_a_spanning_tree():
    two_rings = Topology.from_edges([(0, 1), (1, 0), (2, 3), (3, 2)], 4)
    with pytest.raises(NoSpanningTreeError):
        centroid_weights(two_rings)


def test_final_centroid_formula_and_tau1_zero():
    topo = paper_six()
    x0 = np.arange(12.0).reshape(6, 2)
    v0 = np.ones((6, 2))
    c = final_centroid(topo, 1.0, 0.5, 0.3, 0.2, x0, v0)
    w = centroid_weights(topo)
    assert np.allclose(c, w @ x0 + (1 + 0.5 * 0.2) / 0.3)
    # at rest the centroid stays where it is, even without a position delay
    assert np.allclose(final_centroid(topo, 1.0, 0.5, 0.0, 0.2, x0, 0 * v0), w @ x0)
    with pytest.raises(FormationError, match="drifts"):
        final_centroid(topo, 1.0, 0.5, 0.0, 0.2, x0, v0)


def test_predicted_final_positions_keep_the_shape():
    topo = paper_six()
    z = named_formation("hexagon", 6)
    x0 = np.random.default_rng(3).normal(size=(6, 2))
    out = predicted_final_positions(topo, 1.0, 0.5, 0.3, 0.2, z, x0, np.zeros((6, 2)))
    offset = out - z
    assert np.allclose(offset, offset[0])  # desired shape plus a common offset
    assert np.allclose(centroid_weights(topo) @ out, centroid_weights(topo) @ x0)


# ------------------------------------------------- shape names vs topologies
def test_block_shape_and_grid_topology_are_distinct_names():
    import delayform
    from delayform import formation, topology
    from delayform.cli._common import FORMATION_NAMES, OLD_FORMATION_NAMES

    # the top-level `grid` is the communication graph; the shape has its own name
    assert delayform.grid is topology.grid and "grid" not in formation.__all__
    assert "block" in formation.__all__ and "block" not in topology.__all__ and "block" not in dir(delayform)
    assert not set(SHAPES) & set(topology.__all__)  # no shape name is also a topology builder
    assert FORMATION_NAMES == tuple(SHAPES) and OLD_FORMATION_NAMES == tuple(formation.SHAPE_ALIASES)
    assert delayform.grid(2, 3).n == 6 and block(6).shape == (6, 2)


def test_old_block_spellings_give_the_same_formation():
    from delayform import formation
    from delayform.scenario import paper_scenario, parse_scenario

    # independent of block(): 7 agents, 3 to a row, 1 m apart, rows towards -y, mean at 0
    cols, rows = np.arange(7) % 3, -(np.arange(7) // 3)
    expected = np.column_stack([cols, rows]) - [6 / 7, -5 / 7]  # means of 0,1,2,0,1,2,0 and 0,0,0,-1,-1,-1,-2
    assert np.allclose(block(7), expected)
    assert formation.grid is block
    for name in ("grid", "Grid", "block"):
        assert np.array_equal(named_formation(name, 7, spacing=2.0), 2.0 * expected)
    base = {"topology": {"name": "ring", "n": 7}, "gains": {"P": 1.0, "D": 0.5}, "delays": {"tau1": 0.1, "tau2": 0.2}}
    for name in ("grid", "block"):
        s = parse_scenario(base | {"formation": {"shape": name, "spacing": 2.0}})
        assert s.formation.shape == "block"  # written back under the current name
        assert np.array_equal(s.desired_positions(), 2.0 * expected)
    over = paper_scenario().with_changes(formation="grid")  # what --formation grid does
    assert over.formation.shape == "block" and np.array_equal(over.desired_positions(), block(6, spacing=2.0))
