"""Tests of delayform.analysis.ctcr.stability_map: exact crossing curves and the CTCR count of unstable roots.

The counts are checked against an independent argument-principle root counter
(tests/ref_roots_ctcr.py) that uses only the subsystem matrices of eq.
subsystems (or C itself), never the curves.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from delayform.characteristic import TwoDelayQuasiPolynomial, factors
from delayform.analysis.ctcr.stability_map import (
    PAPER_POINTS,
    CrossingCurve,
    StabilityMap,
    crossing_map,
    curve_residual,
    stability_map,
)
from delayform.errors import DelayError, NeutralQuasiPolynomialError, NoSpanningTreeError, QuasiPolynomialError
from delayform.topology import Topology, paper_six, random_digraph, ring, star

from ref_roots_ctcr import coefficient_bound, count_unstable, count_unstable_function, system_unstable

TWO_PI = 2.0 * np.pi


@pytest.fixture(scope="module")
def paper_map() -> StabilityMap:
    return stability_map(paper_six(), 1.0, 0.5, 8.0, 8.0)


def _compare(nu: np.ndarray, ref: np.ndarray, uncertain: np.ndarray) -> None:
    """NU from the curves equals the reference wherever the reference is sure; few skipped."""
    assert uncertain.sum() <= 0.02 * nu.size, f"{uncertain.sum()} of {nu.size} points skipped"
    bad = (nu != ref) & ~uncertain
    assert not bad.any(), f"{bad.sum()} mismatches, first: NU={nu[bad][:5]} ref={ref[bad][:5]}"


# ----------------------------------------------------------------------------- the paper's example
def test_paper_points_stability(paper_map: StabilityMap) -> None:
    # Section "Simulation Examples": a, b, d, e stable; c unstable ("in the unstable region").
    stable = {k: bool(paper_map.is_stable(*p)) for k, p in PAPER_POINTS.items()}
    assert stable == {"a": True, "b": True, "c": False, "d": True, "e": True}


def test_paper_points_against_reference(paper_map: StabilityMap) -> None:
    t1, t2 = np.array(list(PAPER_POINTS.values())).T
    ref, uncertain = system_unstable(factors(paper_six(), 1.0, 0.5), t1, t2)
    assert not uncertain.any()
    assert np.array_equal(paper_map.unstable_count(t1, t2), ref)
    assert ref[2] > 0 and ref[[0, 1, 3, 4]].sum() == 0


def test_paper_map_matches_root_count_at_500_points(paper_map: StabilityMap) -> None:
    rng = np.random.default_rng(3)
    t1, t2 = rng.uniform(0.0, 8.0, (2, 500))
    ref, uncertain = system_unstable(factors(paper_six(), 1.0, 0.5), t1, t2)
    nu = paper_map.unstable_count(t1, t2)
    _compare(nu, ref, uncertain)
    assert len(set(nu.tolist())) >= 3  # the window really has regions with different NU


def _whole_system_count(topology: Topology, P: float, D: float, t1: np.ndarray, t2: np.ndarray):
    """Argument principle on det of the 2n x 2n characteristic matrix of eq. protocolss, built from C.

    Independent of the factorization (Lemma 1) and of the eigenvalues of C;
    divided by s to leave out the rigid-body root of the centroid.
    """
    C = np.asarray(topology.C if not hasattr(topology.C, "toarray") else topology.C.toarray())
    n = C.shape[0]
    A0 = np.kron(np.eye(n), np.array([[0.0, 1.0], [-P, -D]]))
    B1 = np.kron(C, np.array([[0.0, 0.0], [P, 0.0]]))
    B2 = np.kron(C, np.array([[0.0, 0.0], [0.0, D]]))
    R = 1.05 * sum(np.linalg.norm(M, 2) for M in (A0, B1, B2)) + 1.0

    def f(s, a, b):
        M = s[..., None, None] * np.eye(2 * n) - A0 - B1 * np.exp(-a * s)[..., None, None] - B2 * np.exp(
            -b * s
        )[..., None, None]
        return np.linalg.det(M) / s

    return count_unstable_function(f, R, t1, t2)


def test_paper_map_matches_unfactorized_system(paper_map: StabilityMap) -> None:
    rng = np.random.default_rng(11)
    t1, t2 = rng.uniform(0.0, 8.0, (2, 60))
    ref, uncertain = _whole_system_count(paper_six(), 1.0, 0.5, t1, t2)
    _compare(paper_map.unstable_count(t1, t2), ref, uncertain)


# ----------------------------------------------------------------------------- random teams
@pytest.mark.parametrize("seed", range(6))
def test_random_team_matches_root_count(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    n = int([3, 30][seed] if seed < 2 else rng.integers(3, 31))  # the ends of 3..30, then random
    P = float(rng.uniform(0.2, 4.0))
    D = float(rng.uniform(0.1, 3.0))
    topology = random_digraph(n, float(rng.uniform(0.02, 0.4)), seed=seed)
    T1, T2 = rng.uniform(3.0, 8.0, 2)
    m = stability_map(topology, P, D, T1, T2)
    t1, t2 = rng.uniform(0.0, T1, 500), rng.uniform(0.0, T2, 500)
    ref, uncertain = system_unstable(factors(topology, P, D), t1, t2)
    _compare(m.unstable_count(t1, t2), ref, uncertain)


@pytest.mark.parametrize(("topology", "P", "D"), [(star(10), 3.8, 1.09), (ring(4), 0.88, 0.17), (ring(22), 2.5, 1.95)])
def test_unit_modulus_eigenvalues_match_root_count(topology: Topology, P: float, D: float) -> None:
    # |lam| = 1 (lam = -1 of a star or an even ring, +-j of ring(4)): on the tau1 = 0 axis the
    # root only touches the imaginary axis (RT = 0) and the gain polynomial has double roots.
    m = stability_map(topology, P, D, 6.0, 6.0)
    rng = np.random.default_rng(topology.n)
    t1, t2 = rng.uniform(0.0, 6.0, (2, 500))
    ref, uncertain = system_unstable(factors(topology, P, D), t1, t2)
    _compare(m.unstable_count(t1, t2), ref, uncertain)


# ----------------------------------------------------------------------------- curves are exact
def _check_curves(m: StabilityMap) -> None:
    for c in m.curves:
        res = curve_residual(m.traced[c.source], c)
        assert res.max() <= 1e-9, f"curve point residual {res.max():.2e}"
        i, k = c.shift
        # eq. nltrans: removing the shift leaves kernel phases in [0, 2 pi). The last
        # vertex of a piece is shared with the next piece (next shift), so it is left out.
        p1 = (c.omega * c.tau1 - TWO_PI * i)[:-1]
        p2 = (c.omega * c.tau2 - TWO_PI * k)[:-1]
        assert np.all((p1 > -1e-6) & (p1 < TWO_PI + 1e-6)) and np.all((p2 > -1e-6) & (p2 < TWO_PI + 1e-6))
        assert (c.kind == "kernel") == (c.shift == (0, 0))
        assert np.all(c.omega > 0)


@settings(max_examples=25)
@given(
    lam_re=st.floats(-1.0, 1.0),
    lam_im=st.floats(-1.0, 1.0),
    P=st.floats(0.1, 5.0),
    D=st.floats(0.05, 3.0),
)
def test_property_protocol_factor_curves_are_roots(lam_re: float, lam_im: float, P: float, D: float) -> None:
    lam = complex(lam_re, lam_im)
    qp = TwoDelayQuasiPolynomial([P, D, 1.0], [-lam * P], [0.0, -lam * D])
    m = crossing_map(qp, 6.0, 6.0)
    _check_curves(m)


@st.composite
def retarded_qps(draw: st.DrawFn, general: bool) -> TwoDelayQuasiPolynomial:
    """Random retarded qps: g1 of degree d (monic-ish), delayed terms of lower degree."""
    d = draw(st.integers(1, 3))
    real = draw(st.booleans())
    coef = st.floats(-2.0, 2.0)

    def poly(deg: int) -> list[complex]:
        re = draw(st.lists(coef, min_size=deg + 1, max_size=deg + 1))
        im = [0.0] * (deg + 1) if real else draw(st.lists(coef, min_size=deg + 1, max_size=deg + 1))
        return [complex(a, b) for a, b in zip(re, im, strict=True)]

    g1 = poly(d - 1) + [1.0]
    terms = [poly(d - 1) for _ in range(2)]
    extra = [poly(d - 1) if (general and draw(st.booleans())) else [] for _ in range(3)]
    if general and not any(extra):
        extra[2] = poly(d - 1)
    return TwoDelayQuasiPolynomial(g1, *terms, *extra)


@settings(max_examples=20)
@given(qp=retarded_qps(general=False))
def test_property_three_term_curves_are_roots(qp: TwoDelayQuasiPolynomial) -> None:
    _check_curves(crossing_map(qp, 5.0, 5.0))


_TINY_TERM = TwoDelayQuasiPolynomial(  # a term at the smallest normal double: no factor to split off
    [4.26232568e-37, 1.0], [1.0], [2.2250738585072014e-308], [], [], [1.0]
)


@settings(max_examples=4)
@given(qp=retarded_qps(general=True))
@example(qp=_TINY_TERM)
def test_property_general_curves_are_roots(qp: TwoDelayQuasiPolynomial) -> None:
    _check_curves(crossing_map(qp, 3.0, 3.0))


# ----------------------------------------------------------------------------- general and complex qps
def test_general_fourth_order_factor_matches_root_count() -> None:
    f = factors(ring(5), 1.0, 0.5)[-1]
    assert f.order == 4
    m = crossing_map(f.quasi_polynomial, 6.0, 6.0)  # resultant elimination path (2 tau and cross terms)
    assert len(m.curves) > 0
    rng = np.random.default_rng(7)
    t1, t2 = rng.uniform(0.0, 6.0, (2, 500))
    ref, uncertain = count_unstable(*f.state_matrices(), t1, t2)
    nu = m.unstable_count(t1, t2)
    _compare(nu, ref, uncertain)
    # The same factor through the closed form of lam and conj(lam): NU(q4) = 2 NU(q_lam).
    lam = f.lam
    q_lam = TwoDelayQuasiPolynomial([1.0, 0.5, 1.0], [-lam], [0.0, -0.5 * lam])
    assert np.array_equal(2 * crossing_map(q_lam, 6.0, 6.0).unstable_count(t1, t2), nu)


def test_complex_qp_counts_each_root_once() -> None:
    lam = 0.9 * np.exp(2.2j)
    P, D = 1.5, 0.8
    q = TwoDelayQuasiPolynomial([P, D, 1.0], [-lam * P], [0.0, -lam * D])
    m = crossing_map(q, 6.0, 6.0)
    A = np.array([[0.0, 1.0], [-P, -D]], complex)
    B1 = lam * np.array([[0.0, 0.0], [P, 0.0]])
    B2 = lam * np.array([[0.0, 0.0], [0.0, D]])
    rng = np.random.default_rng(9)
    t1, t2 = rng.uniform(0.0, 6.0, (2, 500))
    ref, uncertain = count_unstable(A, B1, B2, t1, t2)
    nu = m.unstable_count(t1, t2)
    _compare(nu, ref, uncertain)
    assert np.any(nu % 2 == 1)  # single (non-paired) roots do cross
    assert {c.weight for c in m.curves} == {1}


def test_random_general_qp_matches_argument_principle() -> None:
    qp = TwoDelayQuasiPolynomial([2.0, 1.2, 1.0], [0.6, -0.3], [-0.4, 0.5], [0.3], [0.2, 0.1], [-0.35, 0.2])
    m = crossing_map(qp, 4.0, 4.0)
    rng = np.random.default_rng(5)
    t1, t2 = rng.uniform(0.0, 4.0, (2, 500))
    coefficients = [np.asarray(c) for c in ([2.0, 1.2, 1.0], [0.6, -0.3], [-0.4, 0.5], [0.3], [0.2, 0.1], [-0.35, 0.2])]
    multiples = [(0, 0), (1, 0), (0, 1), (2, 0), (0, 2), (1, 1)]

    def f(s, a, b):
        return sum(np.polyval(c[::-1], s) * np.exp(-(i * a + k * b) * s) for c, (i, k) in zip(coefficients, multiples))

    ref, uncertain = count_unstable_function(f, 1.05 * coefficient_bound(coefficients) + 1.0, t1, t2)
    nu = m.unstable_count(t1, t2)
    _compare(nu, ref, uncertain)
    assert nu.max() > 0


def test_single_delay_qp_gives_straight_lines() -> None:
    # s^2 + s + 2 - 1.5 e^{-tau1 s}: no tau2 dependence, vertical lines tau1 = const.
    qp = TwoDelayQuasiPolynomial([2.0, 1.0, 1.0], [-1.5])
    m = crossing_map(qp, 10.0, 5.0)
    assert m.curves and all(np.ptp(c.tau1) == 0.0 for c in m.curves)
    rng = np.random.default_rng(2)
    t1, t2 = rng.uniform(0.0, 10.0, 500), rng.uniform(0.0, 5.0, 500)
    ref, uncertain = count_unstable(
        np.array([[0.0, 1.0], [-2.0, -1.0]]), np.array([[0.0, 0.0], [1.5, 0.0]]), np.zeros((2, 2)), t1, t2
    )
    _compare(m.unstable_count(t1, t2), ref, uncertain)


# ----------------------------------------------------------------------------- centroid and axes
def test_centroid_factor_near_origin_and_on_axes() -> None:
    f = factors(paper_six(), 1.0, 0.5)[0]
    assert f.is_centroid
    m = crossing_map(f.quasi_polynomial, 8.0, 8.0)
    # s = 0 is never counted; the second zero root leaves to the left (module docstring).
    assert m.delay_free_count == 0
    assert int(m.unstable_count(1e-3, 1e-3)) == 0
    t2 = np.linspace(0.0, 8.0, 41)
    t1 = np.zeros_like(t2)
    ref, uncertain = count_unstable(*f.state_matrices(), t1 + 1e-4, t2, centroid=True)
    assert not uncertain[1:].any()
    assert np.array_equal(m.unstable_count(t1 + 1e-4, t2)[1:], ref[1:])
    # Points on the tau2 = 0 axis use the path along tau1.
    t1 = np.linspace(0.05, 8.0, 40)
    ref, uncertain = count_unstable(*f.state_matrices(), t1, np.zeros_like(t1), centroid=True)
    ok = ~uncertain
    assert np.array_equal(m.unstable_count(t1, 0.0)[ok], ref[ok])


def test_zero_root_line_inside_the_window() -> None:
    # q(0) = 0 for every delay and q'(0) = -0.6 + 0.5 tau1 + 0.5 tau2: a real root passes
    # through s = 0 on the line tau1 + tau2 = 1.2 (module docstring, "The origin and the axes").
    gs = [np.array([1.0, 0.2, 1.0]), np.array([-0.5]), np.array([-0.5, -0.8])]
    m = crossing_map(TwoDelayQuasiPolynomial(*gs), 4.0, 4.0)
    multiples = [(0, 0), (1, 0), (0, 1)]

    def f_over_s(s, a, b):  # the persistent root s = 0 divided out
        return sum(np.polyval(c[::-1], s) * np.exp(-(i * a + k * b) * s) for c, (i, k) in zip(gs, multiples)) / s

    rng = np.random.default_rng(4)
    t1, t2 = rng.uniform(0.0, 4.0, (2, 500))
    t1 = np.concatenate([t1, np.zeros(20), np.linspace(0.01, 4.0, 20)])
    t2 = np.concatenate([t2, np.linspace(0.01, 4.0, 20), np.zeros(20)])  # both axes too
    ref, uncertain = count_unstable_function(f_over_s, 1.05 * coefficient_bound(gs) + 1.0, t1, t2)
    nu = m.unstable_count(t1, t2)
    _compare(nu, ref, uncertain)
    below = t1 + t2 < 1.1
    assert np.any(nu[below] != nu[t1 + t2 > 1.3].min())  # the line really changes NU


def test_unstable_count_broadcasts(paper_map: StabilityMap) -> None:
    t1 = np.linspace(0.0, 8.0, 7)
    t2 = np.linspace(0.0, 8.0, 5)
    grid = paper_map.unstable_count(t1[None, :], t2[:, None])
    assert grid.shape == (5, 7)
    assert grid[2, 3] == paper_map.unstable_count(t1[3], t2[2])
    assert np.all(grid >= 0) and np.all(grid % 2 == 0)
    assert 0.0 < paper_map.stable_fraction(resolution=100) < 1.0


def test_curve_kinds_and_tendencies(paper_map: StabilityMap) -> None:
    assert paper_map.kernel_curves and paper_map.offspring_curves
    assert all(isinstance(c, CrossingCurve) for c in paper_map.curves)
    assert all(c.weight == 2 for c in paper_map.curves)
    rts = np.concatenate([np.concatenate([c.rt1, c.rt2]) for c in paper_map.curves])
    assert set(np.unique(rts)) <= {-1, 0, 1} and {-1, 1} <= set(np.unique(rts))


# ----------------------------------------------------------------------------- errors
def test_errors() -> None:
    # neutral with a difference operator 1 + 1.5 z1 that is not strongly stable (tests/test_neutral.py)
    with pytest.raises(NeutralQuasiPolynomialError):
        crossing_map(TwoDelayQuasiPolynomial([1.0, 1.0], [0.0, 1.5]), 1.0, 1.0)
    qp = TwoDelayQuasiPolynomial([1.0, 0.5, 1.0], [-0.5], [0.0, -0.25])
    for bad in (0.0, -1.0, float("inf"), float("nan")):
        with pytest.raises(DelayError):
            crossing_map(qp, bad, 1.0)
        with pytest.raises(DelayError):
            stability_map(paper_six(), 1.0, 0.5, 1.0, bad)
    with pytest.raises(QuasiPolynomialError):
        crossing_map([1.0, 2.0], 1.0, 1.0)  # type: ignore[arg-type]
    no_tree = Topology.from_edges([(0, 1), (1, 0), (2, 3), (3, 2)], 4)
    with pytest.raises(NoSpanningTreeError):
        stability_map(no_tree, 1.0, 0.5, 1.0, 1.0)
    m = crossing_map(qp, 2.0, 2.0)
    with pytest.raises(DelayError):
        m.unstable_count(3.0, 1.0)
    with pytest.raises(DelayError):
        m.unstable_count(-0.1, 1.0)


# ----------------------------------------------------------------------------- figures
def test_chart_and_save(paper_map: StabilityMap, tmp_path) -> None:
    from delayform import plots

    ax = paper_map.plot(points=PAPER_POINTS)
    colors = {tuple(np.round(c.get_colors()[0][:3], 3)) for c in ax.collections if hasattr(c, "get_segments")}
    assert (1.0, 0.0, 0.0) in colors and (0.0, 0.0, 1.0) in colors
    assert {t.get_text() for t in ax.texts} == set("abcde")
    paths = plots.save_figure(ax, tmp_path / "sub" / "chart")
    assert [p.suffix for p in paths] == [".png", ".svg"]
    assert all(p.stat().st_size > 1000 for p in paths)
