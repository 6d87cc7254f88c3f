"""The fast per-link path (issue 20, item 1): the Frobenius piece rule, the band seeds, one BLAS thread.

Independent references: the factorized count and dominant root of delayform.analysis.roots
(equal per-link delays factorize by the eigenvalues of C, a different algorithm on scalar
quasi-polynomials), the test file's own finite-difference discretization of the 2N-state
DDE (tests/test_network_per_link.py), and the matrix E(s) itself, formed directly.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import delayform.analysis.network.discretization as disc
from delayform.analysis.network import link_dominant_root
from delayform.analysis.network import count as cnt
from delayform.analysis.network.blas import blas_threads, single_threaded_blas
from delayform.analysis.network.links import link_team
from delayform.analysis.roots import count_roots_right_of
from delayform.analysis.roots.dominant import dominant_root
from delayform.characteristic import factors
from delayform.topology import random_digraph

from test_network_per_link import _check_against_reference


def test_piece_bound_holds_inside_the_piece():
    # phi bounds ||E(s)||_F for every s of the piece, E = A (X(s) - X(s_a)) formed directly
    rng = np.random.default_rng(4)
    T = random_digraph(12, 0.25, seed=4)
    team = link_team(T, 1.0, 0.7, rng.uniform(0.1, 1.5, (12, 12)), rng.uniform(0.1, 1.5, (12, 12)))
    for c in (-0.4, -0.1, 0.2):
        line = cnt._Line(team, c)
        ya = rng.uniform(0.0, 3.0, 6)
        h = rng.uniform(0.01, 0.4, 6)
        _, norms, _, _ = line.evaluate(ya)
        phi = cnt._phi(norms, cnt._gammas(team, c, ya, ya + h), h)
        for k in range(ya.size):
            sa = c + 1j * ya[k]
            pa = sa * sa + team.D * sa + team.P
            Xa = np.eye(team.n) - team.matrix(np.array([sa]))[0] / pa
            A = np.linalg.inv(np.eye(team.n) - Xa)
            for t in np.linspace(0.0, 1.0, 9)[1:]:
                s = sa + 1j * h[k] * t
                X = np.eye(team.n) - team.matrix(np.array([s]))[0] / (s * s + team.D * s + team.P)
                assert np.linalg.norm(A @ (X - Xa), "fro") <= phi[k] * (1 + 1e-12)


@pytest.mark.parametrize("c", [-0.45, -0.2, -0.05, 0.02])
def test_count_of_a_40_agent_team_matches_the_factorized_count(c):
    T = random_digraph(40, 0.08, seed=8)
    P, D, t1, t2 = 1.0, 0.8, 0.9, 0.6
    expected = sum(f.multiplicity * count_roots_right_of(f, t1, t2, c) for f in factors(T, P, D))
    assert cnt.count_right_of(link_team(T, P, D, t1, t2), c) == expected


def test_sparse_seed_path_matches_the_finite_difference_reference(monkeypatch):
    # the Arnoldi and band seeds of large teams, forced on a small one, against the dense reference
    monkeypatch.setattr(disc, "DENSE_STATES", 40)
    rng = np.random.default_rng(11)
    T = random_digraph(5, 0.45, seed=11)
    _check_against_reference(T, 1.0, 0.8, rng.uniform(0.1, 1.2, (5, 5)), rng.uniform(0.1, 1.2, (5, 5)))


def test_band_seeds_cover_the_band(monkeypatch):
    # every eigenvalue of the (dense) generator inside the band is among the band's seeds
    monkeypatch.setattr(disc, "DENSE_STATES", 40)
    rng = np.random.default_rng(2)
    T = random_digraph(8, 0.3, seed=2)
    team = link_team(T, 1.0, 0.8, rng.uniform(0.2, 1.0, (8, 8)), rng.uniform(0.2, 1.0, (8, 8)))
    M = 8
    dense = np.linalg.eigvals(disc.generator_matrix(team, M).toarray())
    left, right, height = -0.6, -0.1, 3.0
    inside = dense[(dense.real >= left) & (dense.real <= right) & (dense.imag >= 0) & (dense.imag <= height)]
    assert inside.size > 3
    seeds = disc.band_seeds(team, M, left, right, height, nearest=6)
    for z in inside:
        assert np.min(np.abs(seeds - z)) < 1e-8 * (1 + abs(z))


def test_equal_link_delays_on_a_large_sparse_team_reproduce_the_factorized_root():
    # 80 agents: the sparse Arnoldi + band seeds and the large-team count
    T = random_digraph(80, 2.5 / 80, seed=6)
    old = dominant_root(T, 1.0, 1.0, 0.4, 0.3)
    new = link_dominant_root(T, 1.0, 1.0, np.full((80, 80), 0.4), np.full((80, 80), 0.3))
    assert abs(new.root - old.stability_root) < 1e-9


def _fd_sparse(C, P, D, t1, t2, K=40):
    """The finite-difference generator of tests/test_network_per_link.py, as a sparse matrix."""
    n = C.shape[0]
    m = 2 * n
    h = max(t1[C > 0].max(), t2[C > 0].max())
    dt = h / K
    rows, cols, vals = [], [], []

    def put(r, c, v):
        rows.append(r)
        cols.append(c)
        vals.append(v)

    for j in range(1, K + 1):
        for q in range(m):
            if j < K:
                put(j * m + q, (j - 1) * m + q, 1 / (2 * dt))
                put(j * m + q, (j + 1) * m + q, -1 / (2 * dt))
            else:
                put(j * m + q, (j - 2) * m + q, -1 / (2 * dt))
                put(j * m + q, (j - 1) * m + q, 4 / (2 * dt))
                put(j * m + q, j * m + q, -3 / (2 * dt))
    for i in range(n):
        put(i, n + i, 1.0)
        put(n + i, i, -P)
        put(n + i, n + i, -D)
    for i, k in zip(*np.nonzero(C)):
        for tau, g, off in ((t1[i, k], P, 0), (t2[i, k], D, n)):
            q = tau / dt
            j0 = min(int(np.floor(q)), K - 1)
            w = q - j0
            put(n + i, j0 * m + off + k, C[i, k] * g * (1 - w))
            put(n + i, (j0 + 1) * m + off + k, C[i, k] * g * w)
    size = m * (K + 1)
    return sp.csc_array((vals, (rows, cols)), shape=(size, size))


@pytest.mark.slow
def test_100_agent_per_link_root_matches_an_independent_discretization():
    # the benchmark's team: the roots right of the certified line, from the finite-difference
    # generator (shift-and-invert at the line's window) polished by a secant-Newton on det M
    n = 100
    rng = np.random.default_rng(0)
    T = random_digraph(n, 2.0 / n, seed=3)
    C = T.C_sparse.toarray()
    t1 = rng.uniform(0.2, 0.6, (n, n))
    t2 = rng.uniform(0.2, 0.6, (n, n))
    r = link_dominant_root(T, 1.0, 1.0, t1, t2)
    A = _fd_sparse(C, 1.0, 1.0, t1, t2, K=24)
    seeds: list[complex] = []
    with single_threaded_blas():  # only the thread count: ARPACK's small dense steps are slower threaded
        for y in np.arange(0.0, 2.01, 0.25):
            sig = 0.5 * (r.line + r.root.real) + 1j * y
            lu = spla.splu((A - sig * sp.eye(A.shape[0], format="csc")).tocsc())
            op = spla.LinearOperator(A.shape, matvec=lu.solve, dtype=np.complex128)
            seeds += list(sig + 1.0 / spla.eigs(op, k=12, which="LM", return_eigenvectors=False, tol=1e-9))
    ref: list[complex] = []
    for z in seeds:
        if z.real < r.line - 0.05:
            continue
        s = complex(z.real, abs(z.imag))
        for _ in range(40):  # Newton on det M: the step 1 / tr(M^-1 M'), M built from C here
            E1, E2 = np.exp(-t1 * s), np.exp(-t2 * s)
            M = (s * s + s + 1.0) * np.eye(n) - C * (E1 + s * E2)
            dM = (2 * s + 1.0) * np.eye(n) - C * (-t1 * E1 + E2 - s * t2 * E2)
            step = 1.0 / np.trace(np.linalg.solve(M, dM))
            s -= step
            if abs(step) < 1e-13:
                break
        if abs(step) < 1e-10 and s.real > r.line and abs(s) > 1e-9 and all(abs(s - w) > 1e-6 for w in ref):
            ref.append(s)
    ours = r.roots[r.roots != 0]
    assert len(ref) == ours.size
    for z in ref:
        assert np.min(np.abs(ours - z)) < 1e-7
    assert abs(max(w.real for w in ref) - r.root.real) < 1e-7


@pytest.fixture
def two_blas_threads() -> Iterator[int | None]:
    """OpenBLAS on two threads for the test (the xdist workers run on one, tests/conftest.py), then as before."""
    from delayform.analysis.network.blas import _controls

    saved = [int(get()) for get, _ in _controls()]
    for _, put in _controls():
        put(2)
    yield blas_threads()
    for (_, put), k in zip(_controls(), saved):
        put(k)


def test_single_threaded_blas_restores_the_thread_count(two_blas_threads: int | None):
    before = blas_threads()
    assert before == two_blas_threads and before in (None, 2)  # a count to restore that is not 1
    with single_threaded_blas():
        if before is not None:
            assert blas_threads() == 1
        with single_threaded_blas():  # re-entrant
            pass
        if before is not None:
            assert blas_threads() == 1
    assert blas_threads() == before


def test_phi_threshold_keeps_the_branch_tail_below_a_quarter_turn():
    tail = -math.log(1.0 - cnt.PHI_MAX) - cnt.PHI_MAX
    assert cnt.PHI_MAX < 1.0 and tail < 0.5 * math.pi - 0.5
