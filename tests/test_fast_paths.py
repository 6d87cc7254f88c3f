"""The vectorized fast paths (issue 13) against independent computations.

* dominant-root maps by continuation and single points with all factors
  batched: against the full 2n x 2n determinant (Muller from the map's root,
  and a dense argument count that no root of the determinant lies right of it);
* the family certificate (second-order walk, rotated exponentials): against
  the first-order certified count of ``count_roots_right_of``;
* the CTCR family path: circulant eigenvalues against dense ``eigvals``;
  batched polynomial roots against polynomials built from known roots; the
  closed-form turning test against the dense scan over images; NU of a ring
  against the reference root count.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ref_spectrum as ref
from delayform.analysis.ctcr import family_curves as _family_curves, phase as _phase
from delayform.analysis.roots.family import rows as _rows, seeds as _seeds, solve as _family, walk as _walk
from delayform.analysis.ctcr.stability_map import stability_map
from delayform.analysis.roots.dominant import count_roots_right_of, dominant_root, dominant_root_map
from delayform.characteristic import TwoDelayQuasiPolynomial, factors
from delayform.topology import _circulant_eigenvalues, paper_six, random_digraph, ring, star
from ref_roots_ctcr import system_unstable

P, D = 1.0, 0.5


def _check_against_determinant(team, tau1: float, tau2: float, root: complex) -> None:
    """root is a root of det(...)/s (Muller from it stays within 1e-9) and none of it lies right of it."""
    f = ref.formation_function(team, P, D, tau1, tau2)
    # started next to it: at tau1 = 0 the centroid's zero is double and det/s is 0/0 at s = 0,
    # where the reference itself resolves the root only to a few 1e-9
    tol = 1e-9 if abs(root) > 1e-6 else 1e-8
    assert abs(ref.muller(f, root + 1e-6) - root) < tol
    # |s|^2 <= 3 |s| + 6 for a root with Re s > -0.2 and delays <= 8 (|lam| <= 1): |s| < 4.4
    count = ref.argument_count(f, (root.real + 0.01, 6.0, -6.0, 6.0), points=12000)
    assert abs(count) < 0.1, f"{count:.2f} roots right of the dominant root at ({tau1}, {tau2})"


@pytest.fixture(scope="module")
def paper_grid_map():
    grid = np.linspace(0.0, 8.0, 100)
    return grid, dominant_root_map(paper_six(), P, D, grid, grid)


@pytest.mark.parametrize("ij", [(1, 37), (12, 5), (71, 18), (99, 99)])
def test_continuation_map_equals_the_full_determinant(paper_grid_map, ij: tuple[int, int]) -> None:
    grid, dmap = paper_grid_map
    i, j = ij
    _check_against_determinant(paper_six(), float(grid[i]), float(grid[j]), complex(dmap.roots[i, j]))


def test_map_row_tau1_zero_drift_by_lambert_w_equals_the_certified_path(paper_grid_map) -> None:
    # on tau1 = 0 the centroid factor is s (s + D - D e^{-tau2 s}); the map takes the second
    # factor's rightmost non-zero root from Lambert's W, dominant_root from the certified path
    grid, dmap = paper_grid_map
    for j in (0, 1, 30, 62, 99):
        single = dominant_root(paper_six(), P, D, 0.0, float(grid[j]))
        assert abs(single.root - dmap.roots[0, j]) < 1e-9


def test_continuation_map_equals_batched_single_points(paper_grid_map) -> None:
    grid, dmap = paper_grid_map
    rng = np.random.default_rng(13)
    for i, j in rng.integers(0, grid.size, (12, 2)):
        single = dominant_root(paper_six(), P, D, float(grid[i]), float(grid[j]))
        assert abs(single.root - dmap.roots[i, j]) < 1e-9


@pytest.mark.parametrize(("team", "tau1", "tau2"), [(random_digraph(6, 0.4, seed=5), 0.7, 1.9),
                                                    (ring(5), 2.2, 0.4), (star(4), 0.05, 3.1)])
def test_batched_single_point_equals_the_full_determinant(team, tau1: float, tau2: float) -> None:
    _check_against_determinant(team, tau1, tau2, dominant_root(team, P, D, tau1, tau2).root)


@settings(max_examples=30, deadline=None)
@given(
    lam_re=st.floats(-1.0, 1.0), lam_im=st.floats(-1.0, 1.0),
    tau1=st.floats(0.0, 8.0), tau2=st.floats(0.0, 8.0), offset=st.floats(-0.6, 0.6),
)
def test_family_count_equals_first_order_count(lam_re: float, lam_im: float, tau1: float, tau2: float,
                                               offset: float) -> None:
    lam = complex(lam_re, lam_im)
    real = lam_im == 0.0
    rows = _rows._Rows(np.array([lam]), np.array([tau1]), np.array([tau2]), np.array([real]),
                         np.array([False]), P, D)
    got = _walk._count_rows(rows, np.array([offset]))[0]
    qp = TwoDelayQuasiPolynomial([P, D, 1.0], [-lam * P], [0.0, -lam * D])
    try:
        want = count_roots_right_of(qp, tau1, tau2, offset)
    except Exception:  # a root on the line: neither count is meaningful
        return
    if np.isfinite(got):
        # a real-lam row counts the conjugate half too; a complex one only q_lam's roots
        assert got == want


def _generic_count(lam: complex, tau1: float, tau2: float, c: float) -> float:
    """Roots of q_lam with Re s > c by the generic first-order certificate (NaN: a root on the line)."""
    qp = TwoDelayQuasiPolynomial([P, D, 1.0], [-lam * P], [0.0, -lam * D])
    try:
        return float(count_roots_right_of(qp, tau1, tau2, c))
    except Exception:
        return float("nan")


def _rows_of(lam, tau1, tau2):
    lam = np.asarray(lam, dtype=complex)
    return _rows._Rows(lam, np.asarray(tau1, float), np.asarray(tau2, float), lam.imag == 0.0,
                         np.zeros(lam.size, dtype=bool), P, D)


def test_many_line_walk_equals_first_order_count() -> None:
    # more than 64 lines: samples per line by how far e^{-i tau w} turns, bisection of the
    # rejected segments, the winding from Arg at the ends plus branch-cut crossings
    rng = np.random.default_rng(2026)
    n = 90
    lam = rng.uniform(-1.0, 1.0, n) + 1j * rng.uniform(-1.0, 1.0, n) * (rng.random(n) < 0.4)
    tau1, tau2, c = rng.uniform(0.0, 8.0, n), rng.uniform(0.0, 8.0, n), rng.uniform(-0.6, 0.4, n)
    with np.errstate(all="ignore"):
        got = _walk._count_rows(_rows_of(lam, tau1, tau2), c)
        few = np.concatenate([_walk._count_few(_rows_of(lam[k:k + 9], tau1[k:k + 9], tau2[k:k + 9]), c[k:k + 9])
                              for k in range(0, n, 9)])
    checked = 0
    for k in range(n):
        want = _generic_count(complex(lam[k]), tau1[k], tau2[k], c[k])
        if np.isfinite(want) and np.isfinite(got[k]):
            assert got[k] == want, k
            checked += 1
        if np.isfinite(want) and np.isfinite(few[k]):
            assert few[k] == want, k
    assert checked >= 0.9 * n


def test_long_walk_counts_hundreds_of_roots() -> None:
    # a line far left of long delays: e^{-i tau w} turns through hundreds of radians along the
    # walk and the line has hundreds of roots to its right; the count is the first-order one
    lam, tau1, tau2, c = -0.5 + 0j, 3.0, 7.5, -0.75
    with np.errstate(all="ignore"):
        got = _walk._count_rows(_rows_of([lam] * 65, [tau1] * 65, [tau2] * 65), np.full(65, c))
    want = _generic_count(lam, tau1, tau2, c)
    assert want > 100
    assert np.all(got == want)


@settings(max_examples=200, deadline=None)
@given(
    reals=st.lists(st.floats(-2.0, 0.5), min_size=1, max_size=5),
    imags=st.lists(st.floats(-3.0, 3.0), min_size=5, max_size=5),
    near=st.booleans(), real=st.booleans(), deflate=st.booleans(),
    accepted=st.lists(st.booleans(), min_size=5, max_size=5),
)
def test_vectorized_line_choice_equals_the_scalar_rule(reals, imags, near, real, deflate, accepted) -> None:
    # _lines_of_rows (the map's rows) against certificate._choose_line (the per-factor rule)
    from delayform.analysis.roots.argument_principle import _choose_line

    k = len(reals)
    roots = np.array(reals) + 1j * np.array(imags[:k])
    if near and k > 1:  # a gap narrower than the rule's 1e-3
        roots[1] = roots[0].real + 1e-5 + 1j * roots[1].imag
    if real:
        roots = roots.real + 1j * np.abs(roots.imag)
    ok = np.array(accepted[:k])
    with np.errstate(all="ignore"):  # as in the family's entry points (-inf - -inf for missing roots)
        right, c, expected, _ = _family._lines_of_rows(roots[None, :], ok[None, :], np.array([real]),
                                                       np.array([deflate]))
    acc = sorted((z for z, g in zip(roots.tolist(), ok.tolist()) if g), key=lambda z: (z.real, z.imag))
    distinct = [z for i, z in enumerate(acc) if i == 0 or abs(z - acc[i - 1]) > 1e-7 * (1.0 + abs(acc[i - 1]))]
    if not distinct:
        assert np.isnan(c[0])
        return
    best = max(distinct, key=lambda z: z.real)
    known = [z.real for z in distinct] + [z.real for z in distinct if real and abs(z.imag) > 1e-9 * (1 + abs(z))]
    known = sorted(known + [0.0] * deflate, reverse=True)
    want = _choose_line(known, best.real)
    assert c[0] == pytest.approx(want, abs=1e-12)
    assert expected[0] == sum(1 for x in known if x > want)
    assert right[0].real == best.real


@settings(max_examples=25, deadline=None)
@given(
    n=st.integers(3, 7), p=st.floats(0.2, 0.8), seed=st.integers(0, 50),
    gains=st.tuples(st.floats(0.3, 3.0), st.floats(0.3, 3.0)),
    tau1=st.floats(0.01, 5.0), tau2=st.floats(0.0, 5.0),
)
def test_dominant_root_equals_the_generic_path_per_factor(n, p, seed, gains, tau1, tau2) -> None:
    # the one-pair path (plain-Python polishing and lines, direct LAPACK seeds, few-line walk)
    # against the generic per-factor path (its own seeds, Newton and first-order certificate)
    from delayform.analysis.roots.single import _problem, _rightmost
    from delayform.errors import DelayError, NoSpanningTreeError

    P_, D_ = gains
    team = random_digraph(n, p, seed=seed)
    try:
        got = dominant_root(team, P_, D_, tau1, tau2)
    except (NoSpanningTreeError, DelayError):
        return
    fs = factors(team, P_, D_)
    roots = {f: _rightmost(_problem(f), tau1, tau2) for f in fs}
    formation = max((r for f, r in roots.items() if not f.is_centroid), key=lambda r: r.real)
    centroid = next(r for f, r in roots.items() if f.is_centroid)
    assert abs(got.formation_root - formation) < 1e-8 * (1.0 + abs(formation))
    assert abs(got.centroid_root - centroid) < 1e-8 * (1.0 + abs(centroid))


@pytest.mark.parametrize(("tau1", "tau2"), [(0.0, 0.0), (0.0, 1.3), (0.3, 0.2), (2.0, 1.0), (4.7, 6.1)])
def test_rightmost_root_of_a_factor_equals_the_generic_path(tau1: float, tau2: float) -> None:
    # a factor goes through the family path; the generic one (its own seeds, first-order walk) agrees
    from delayform.analysis.roots.single import _problem, _rightmost, rightmost_root

    for team in (paper_six(), ring(5)):
        for f in factors(team, P, D):
            assert abs(rightmost_root(f, tau1, tau2) - _rightmost(_problem(f), tau1, tau2)) < 1e-9


# ----------------------------------------------------------------------------- CTCR family path
@pytest.mark.parametrize("n", [3, 8, 25, 64])
def test_circulant_eigenvalues_match_dense_eigvals(n: int) -> None:
    C = ring(n).C_sparse
    got = np.sort_complex(_circulant_eigenvalues(C))
    want = np.sort_complex(np.linalg.eigvals(C.toarray()))
    assert np.abs(got - want).max() < 1e-12
    assert _circulant_eigenvalues(random_digraph(n, 0.3, seed=n).C_sparse) is None or n < 4


def test_batched_positive_roots_match_constructed_polynomials() -> None:
    rng = np.random.default_rng(7)
    roots = rng.uniform(0.1, 5.0, (40, 4))
    roots[::3, 1] = -roots[::3, 1]      # some negative roots, not reported
    roots[1::3, 2] = roots[1::3, 3]     # double roots, reported once
    coef = np.array([np.polynomial.polynomial.polyfromroots(r) for r in roots])
    got = _family_curves._batch_positive_roots(coef)
    for r, g in zip(roots, got, strict=True):
        want = np.unique(np.round(r[r > 0], 9))
        assert np.allclose(np.sort(g[np.isfinite(g)]), want, atol=1e-7)


def test_closed_form_turning_test_equals_dense_scan() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        n = int(rng.integers(5, 60))
        om = np.cumsum(rng.uniform(0.01, 0.3, n)) + 0.05
        om = om[rng.permutation(n)] if rng.random() < 0.2 else om
        u2 = np.cumsum(rng.normal(0.0, 0.8, n))
        m_om = 0.5 * (om[:-1] + om[1:]) * (1.0 + rng.normal(0.0, 0.01, n - 1))
        m2 = 0.5 * (u2[:-1] + u2[1:]) + rng.normal(0.0, 0.05, n - 1)
        want = _phase._turning_needs(om, u2, m_om, m2, 6.0, 6.0)
        pid = np.zeros(n, np.int64)
        got = _family_curves._turning_needs_flat(
            om, u2, m_om, m2, pid, np.array([0]), np.array([n]), np.ones(n - 1, bool), 6.0, 6.0
        )
        assert np.array_equal(got, want)


def test_family_ctcr_of_a_ring_matches_root_count() -> None:
    team = ring(16)  # circulant: eigenvalues by FFT, all |lam| = 1
    m = stability_map(team, 1.3, 0.6, 7.0, 7.0)
    rng = np.random.default_rng(16)
    t1, t2 = rng.uniform(0.0, 7.0, (2, 300))
    want, uncertain = system_unstable(factors(team, 1.3, 0.6), t1, t2)
    got = m.unstable_count(t1, t2)
    assert uncertain.sum() <= 6
    assert np.array_equal(got[~uncertain], want[~uncertain])


@settings(max_examples=25, deadline=None)
@given(
    st.floats(0.0, 8.0), st.floats(0.05, 8.0), st.integers(4, 12), st.floats(0.2, 5.0), st.floats(0.2, 5.0),
    st.booleans(),
)
def test_reduced_generator_has_the_full_discretizations_eigenvalues(
    t1: float, t2: float, N: int, P: float, D: float, swap: bool
) -> None:
    """The (N + 2) x (N + 2) generator of the family path against the generic 2 (N + 1) one.

    Every eigenvalue of K0 + lam K1 is an eigenvalue of the generic discretization of the
    same factor (built term by term from its quasi-polynomial), and the generic one's others
    are those of the differentiation matrix alone (the eigenvectors with zero position).
    """
    from delayform.analysis.roots.generator import _chebyshev, _igd_eigenvalues
    from delayform.analysis.roots.problem import _problem_of_factor

    if swap:
        t1, t2 = t2, t1
    for f in factors(paper_six(), P, D):
        K0, K1 = _seeds._generator_blocks(N, t1, t2, P, D)
        got = np.linalg.eigvals(K0 + complex(f.lam) * K1)
        full = _igd_eigenvalues(_problem_of_factor(f), N, np.array([t1]), np.array([t2]))[0]
        if f.group.is_complex_pair:  # the generic factor of a pair is of order 4 (lam and conj(lam))
            full = full[np.abs(full[:, None] - got[None, :]).min(axis=1) < 1e-6 * (1.0 + np.abs(full))]
        dist = np.abs(got[:, None] - full[None, :]).min(axis=1)
        # a double eigenvalue (e.g. 0 on tau1 = 0) is resolved only to sqrt(eps)
        assert np.all(dist <= 1e-6 * (1.0 + np.abs(got))), (f, dist.max())
        if not f.group.is_complex_pair:  # the rest are the N spurious eigenvalues of the differentiation
            _, Dm, _ = _chebyshev(N)
            spurious = np.linalg.eigvals((2.0 / max(t1, t2)) * Dm[1:, 1:])
            both = np.concatenate([got, spurious])
            miss = np.abs(full[:, None] - both[None, :]).min(axis=1)
            assert full.size == both.size and np.all(miss <= 1e-6 * (1.0 + np.abs(full))), (f, miss.max())


@settings(max_examples=40)
@given(st.lists(st.tuples(st.lists(st.complex_numbers(max_magnitude=5.0, allow_nan=False, allow_infinity=False),
                                   min_size=1, max_size=5),
                          st.integers(0, 2), st.integers(0, 2)), min_size=1, max_size=4),
       st.integers(0, 8), st.floats(0.0, 2.0), st.floats(0.0, 2.0))
def test_all_derivatives_at_once_against_cauchy_s_integral(raw, kmax: int, t1: float, t2: float) -> None:
    """q, q', ..., q^(kmax) in one pass against Cauchy's formula on q itself (trapezoid rule on a circle).

    ``q^(k)(a) = k! / (2 pi r^k) mean_j q(a + r w_j) w_j^-k`` over the N-th roots of unity w_j, an
    independent computation (no derivative of a polynomial, no Leibniz rule) whose error falls
    like r^N: within 1e-9 of the sum of the moduli of the terms.
    """
    from math import factorial

    from delayform.analysis.roots.problem import _derivatives_up_to

    terms = [(np.array(c, dtype=np.complex128), a, b) for c, a, b in raw]
    s = np.array([0.3 + 1.1j, -0.7 + 2.5j, 1.9 - 0.4j, 0.0])
    vals, mags = _derivatives_up_to(terms, s, t1, t2, kmax)
    r, n = 0.25, 64
    w = np.exp(2j * np.pi * np.arange(n) / n)
    z = s[:, None] + r * w[None, :]
    q = sum(np.polynomial.polynomial.polyval(z, c) * np.exp(-(a * t1 + b * t2) * z) for c, a, b in terms)
    for k in range(kmax + 1):
        cauchy = factorial(k) / r**k * np.mean(q * w[None, :] ** -k, axis=1)
        assert np.all(np.abs(vals[k] - cauchy) <= 1e-9 * (mags[k] + factorial(k) / r**k * np.abs(q).max(axis=1)))


def test_all_derivatives_at_once_against_the_closed_form() -> None:
    """q(s) = (s^2 + 1) e^{-2 s}: d^k/ds^k by the Leibniz rule written out, at a few points."""
    from math import comb

    from delayform.analysis.roots.problem import _derivatives_up_to

    s = np.array([0.5 + 0.5j, -1.0 + 3.0j])
    vals, _ = _derivatives_up_to([(np.array([1.0, 0.0, 1.0], dtype=np.complex128), 1, 0)], s, 2.0, 0.0, 5)
    p = [s**2 + 1, 2 * s, 2 + 0 * s]
    for k in range(6):
        want = sum(comb(k, j) * p[j] * (-2.0) ** (k - j) for j in range(min(k, 2) + 1)) * np.exp(-2.0 * s)
        np.testing.assert_allclose(vals[k], want, rtol=1e-13)
