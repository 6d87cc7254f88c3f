"""Tests of delayform.analysis.roots.dominant: roots, dominant roots, maps and delay scheduling.

Every numerical claim is checked against an independent computation from
tests/ref_spectrum.py (full 2n x 2n determinant, mesh + Muller, dense
argument principle, Lambert W), never against the module's own code path.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ref_spectrum as ref
from delayform.analysis.roots import dominant as spectrum
from delayform.characteristic import TwoDelayQuasiPolynomial, factors, full_characteristic
from delayform.errors import (
    DelayError,
    InputError,
    NoSpanningTreeError,
    NotConvergedError,
)
from delayform.analysis.roots.dominant import (
    NoStableDelaysError,
    dominant_root,
    dominant_root_map,
    rightmost_root,
    roots_in,
)
from delayform.design.scheduling import schedule_delays
from delayform.topology import Topology, paper_six, ring

P, D = 1.0, 0.5

#: Points a..e of the paper's Fig. stability and whether the paper declares them stable.
PAPER_POINTS = {
    "a": ((0.3, 0.2), True),
    "b": ((2.0, 1.0), True),
    "c": ((1.0, 2.0), False),
    "d": ((1.0, 5.5), True),
    "e": ((3.5, 2.0), True),
}


def _relative(qp: TwoDelayQuasiPolynomial, s: complex, tau1: float, tau2: float) -> float:
    """|q(s)| over the sum of the moduli of its monomial terms, computed here from qp.evaluate."""
    scale = 0.0
    for c, a, b in qp.terms():
        powers = np.abs(s) ** np.arange(c.size)
        scale += float(np.sum(np.abs(c) * powers) * abs(np.exp(-(a * tau1 + b * tau2) * s)))
    value = abs(complex(qp.evaluate(s, tau1, tau2)))
    return 0.0 if value == 0.0 else value / scale


# ------------------------------------------------------------------ paper points
@pytest.mark.parametrize("label", sorted(PAPER_POINTS))
def test_dominant_root_at_paper_points_matches_full_determinant(label: str) -> None:
    (tau1, tau2), stable = PAPER_POINTS[label]
    team = paper_six()
    got = dominant_root(team, P, D, tau1, tau2)
    want = ref.reference_dominant_root(team, P, D, tau1, tau2)
    assert abs(got.root - want) < 1e-8
    assert got.is_stable is stable
    assert (got.root.real < 0) is stable
    # nothing right of it: dense argument principle on det(...)/s, a box far to the right
    f = ref.formation_function(team, P, D, tau1, tau2)
    assert round(ref.argument_count(f, (got.root.real + 1e-4, 3.0, -20.0, 20.0))) == 0
    if stable:
        assert got.time_constant == pytest.approx(1.0 / abs(want.real), rel=1e-7)
        assert got.growth_rate == 0.0
    else:  # an unstable root has no time constant, it has a growth rate
        assert got.time_constant == math.inf
        assert got.growth_rate == pytest.approx(want.real, rel=1e-7)


def test_dominant_root_is_a_root_of_the_full_characteristic() -> None:
    team = paper_six()
    got = dominant_root(team, P, D, 1.0, 2.0)
    value = abs(complex(full_characteristic(team, P, D, got.root, 1.0, 2.0)))
    scale = abs(complex(full_characteristic(team, P, D, got.root + 0.1, 1.0, 2.0)))
    assert value < 1e-10 * scale
    assert got.factor.lam == pytest.approx(-0.6369, abs=1e-3)  # the lam whose factor crosses first


# ------------------------------------------------------------------ one quasi-polynomial
@settings(max_examples=25)
@given(
    a=st.floats(0.1, 3.0), b=st.floats(-3.0, 3.0).filter(lambda v: abs(v) > 0.05), tau=st.floats(0.05, 4.0)
)
def test_rightmost_root_matches_lambert_w(a: float, b: float, tau: float) -> None:
    qp = TwoDelayQuasiPolynomial([a, 1.0], [b])  # s + a + b e^{-tau s}
    got = rightmost_root(qp, tau, 0.0)
    want = ref.lambert_rightmost(a, b, tau)
    assert abs(got.real - want.real) < 1e-8 * (1.0 + abs(want))
    assert abs(abs(got.imag) - abs(want.imag)) < 1e-8 * (1.0 + abs(want))


_coef = st.floats(-2.0, 2.0, allow_nan=False)


@settings(max_examples=25)
@given(
    g1=st.lists(_coef, min_size=2, max_size=3),
    g2=st.lists(_coef, min_size=1, max_size=2),
    g3=st.lists(_coef, min_size=1, max_size=2),
    g6=st.lists(_coef, min_size=1, max_size=1),
    tau1=st.floats(0.0, 3.0),
    tau2=st.floats(0.0, 3.0),
)
def test_polished_roots_satisfy_the_quasi_polynomial(g1, g2, g3, g6, tau1, tau2) -> None:
    qp = TwoDelayQuasiPolynomial(g1 + [1.0], g2[: len(g1)], g3[: len(g1)], [], [], g6)
    region = (-2.0, 1.0, -6.0, 6.0)
    try:
        roots = roots_in(qp, tau1, tau2, region)
    except NotConvergedError as exc:  # only allowed for a root on the boundary
        assert "boundary" in str(exc)
        return
    for s in roots:
        assert _relative(qp, complex(s), tau1, tau2) <= 1e-10
    top = rightmost_root(qp, tau1, tau2)
    assert _relative(qp, top, tau1, tau2) <= 1e-10
    # the rightmost root is at least as far right as anything in the region
    if roots.size:
        assert top.real >= roots.real.max() - 1e-9


@settings(max_examples=20)
@given(
    lam_index=st.integers(0, 4),
    tau1=st.floats(0.0, 6.0),
    tau2=st.floats(0.0, 6.0),
    x0=st.floats(-1.5, 0.3),
    width=st.floats(0.2, 1.5),
    y0=st.floats(-3.0, 2.0),
    height=st.floats(0.3, 3.0),
)
def test_roots_in_agrees_with_a_dense_argument_count(lam_index, tau1, tau2, x0, width, y0, height) -> None:
    factor = factors(paper_six(), P, D)[lam_index]
    qp = factor.quasi_polynomial
    region = (x0, x0 + width, y0, y0 + height)
    try:
        roots = roots_in(factor, tau1, tau2, region)
    except NotConvergedError as exc:
        assert "boundary" in str(exc)
        return

    def f(s):
        return qp.evaluate(s, tau1, tau2)

    count = ref.argument_count(f, region, points=40000)
    # a root within 1e-6 of the boundary makes the dense count itself unreliable
    grown = (region[0] - 0.01, region[1] + 0.01, region[2] - 0.01, region[3] + 0.01)
    near = ref.mesh_roots(f, grown, (121, 121))
    edge = [z for z in near if min(abs(z.real - region[0]), abs(z.real - region[1]),
                                   abs(z.imag - region[2]), abs(z.imag - region[3])) < 1e-6]  # fmt: skip
    if edge:
        return
    assert roots.size == round(count)
    for s in roots:
        assert _relative(qp, complex(s), tau1, tau2) <= 1e-10
        assert min(abs(s - z) for z in near) < 1e-8  # found independently by mesh + Muller


def test_roots_in_of_a_conjugate_pair_factor_matches_its_quartic() -> None:
    factor = factors(paper_six(), P, D)[4]
    assert factor.group.is_complex_pair
    roots = roots_in(factor, 1.0, 2.0, (-0.5, 0.5, -2.0, 2.0))
    quartic = factor.quasi_polynomial
    count = ref.argument_count(lambda s: quartic.evaluate(s, 1.0, 2.0), (-0.5, 0.5, -2.0, 2.0))
    assert roots.size == round(count) > 0
    for s in roots:
        assert _relative(quartic, complex(s), 1.0, 2.0) <= 1e-10
    assert np.allclose(np.sort_complex(roots), np.sort_complex(np.conj(roots)))


def test_rightmost_root_of_a_five_delay_quasi_polynomial_matches_mesh_and_muller() -> None:
    """The quartic of a conjugate pair has e^{-2 tau1 s}, e^{-2 tau2 s}, e^{-(tau1+tau2) s} terms."""
    quartic = factors(paper_six(), P, D)[4].quasi_polynomial
    assert all(c.size for c in quartic.coefficients)
    got = rightmost_root(quartic, 3.5, 2.0)  # a TwoDelayQuasiPolynomial: companion realization
    found = ref.mesh_roots(lambda s: quartic.evaluate(s, 3.5, 2.0), (-1.0, 0.5, -0.3, 3.0))
    want = max(found, key=lambda z: z.real)
    assert abs(got.real - want.real) < 1e-8 and abs(abs(got.imag) - abs(want.imag)) < 1e-8
    assert _relative(quartic, got, 3.5, 2.0) <= 1e-10


def test_centroid_persistent_zero_is_deflated_but_its_other_roots_count() -> None:
    centroid = factors(paper_six(), P, D)[0]
    assert centroid.is_centroid
    plain = roots_in(centroid, 1.0, 2.0, (-0.5, 0.5, -0.5, 0.5))
    assert np.min(np.abs(plain)) < 1e-12  # roots_in keeps s = 0
    top = rightmost_root(centroid, 1.0, 2.0)
    assert abs(top) > 1e-3  # the persistent zero is not the answer
    qp = centroid.quasi_polynomial
    deflated = ref.mesh_roots(lambda s: qp.evaluate(s, 1.0, 2.0) / s, (-2.0, 0.5, -0.3, 3.0))
    want = max(deflated, key=lambda z: z.real)
    assert abs(top.real - want.real) < 1e-8
    # at tau1 = 0 the zero is double: one copy survives the deflation
    assert abs(rightmost_root(centroid, 0.0, 2.0)) < 1e-12
    assert round(ref.argument_count(lambda s: qp.evaluate(s, 0.0, 2.0), (-0.05, 0.05, -0.05, 0.05))) == 2


def test_delay_free_roots_are_polynomial_roots() -> None:
    qp = TwoDelayQuasiPolynomial([6.0, 5.0, 1.0], [1.0], [0.0, 1.0])
    got = roots_in(qp, 0.0, 0.0, (-5.0, 5.0, -5.0, 5.0))
    want = np.roots(qp.delay_free()[::-1])
    assert np.allclose(np.sort_complex(got), np.sort_complex(want), atol=1e-10)


# ------------------------------------------------------------------ maps
def test_dominant_root_map_matches_reference_at_sampled_points(rng: np.random.Generator) -> None:
    team = paper_six()
    tau1 = np.linspace(0.0, 6.0, 31)
    tau2 = np.linspace(0.0, 6.0, 29)
    dmap = dominant_root_map(team, P, D, tau1, tau2)
    assert dmap.roots.shape == (31, 29)
    for _ in range(3):
        i, j = int(rng.integers(1, 31)), int(rng.integers(0, 29))
        want = ref.reference_dominant_root(team, P, D, tau1[i], tau2[j])
        assert abs(dmap.roots[i, j] - want) < 1e-8
    # paper: stable near the origin, unstable at tau1 = 4.6, tau2 = 0 (the bright valley of Fig. contour)
    assert dmap.stable[1, 1]
    assert not dmap.stable[np.argmin(np.abs(tau1 - 4.6)), 0]
    assert dmap.factor_index.shape == dmap.roots.shape


def test_dominant_root_map_figures_and_progress_bar() -> None:
    team = paper_six()
    grid = np.linspace(0.0, 10.0, 40)
    dmap = dominant_root_map(team, P, D, grid, grid)
    assert np.all(np.isfinite(dmap.roots))
    again = dominant_root_map(team, P, D, grid[:7], grid[:5], progress=True)
    assert np.allclose(again.roots, dmap.roots[:7, :5], rtol=0.0, atol=1e-12)
    ax = dmap.plot_contour()
    assert ax.collections  # filled contours were drawn
    ax3 = dmap.plot_surface()
    assert ax3.name == "3d"
    assert len(ax3.collections) == 2  # surface and the plane Re = 0


# ------------------------------------------------------------------ scheduling
def test_schedule_delays_recovers_stability_from_point_c() -> None:
    team = paper_six()
    out = schedule_delays(team, P, D, tau_min=(1.0, 2.0), tau_max=(4.0, 6.0), grid=17)
    assert 1.0 <= out.tau1 <= 4.0 and 2.0 <= out.tau2 <= 6.0
    want = ref.reference_dominant_root(team, P, D, out.tau1, out.tau2)
    assert abs(out.root - want) < 1e-8
    assert want.real < 0.0
    assert out.hardware_root.real > 0.0  # point c itself is unstable
    assert out.settling_time == pytest.approx(np.log(50.0) / abs(want.real), rel=1e-8)
    # no sampled pair in the box is better (independent reference at each)
    rng = np.random.default_rng(7)
    for t1, t2 in zip(rng.uniform(1.0, 4.0, 3), rng.uniform(2.0, 6.0, 3), strict=True):
        assert ref.reference_dominant_root(team, P, D, t1, t2).real >= want.real - 1e-9


def test_schedule_delays_without_a_stable_pair_raises() -> None:
    with pytest.raises(NoStableDelaysError, match="no stable delay pair"):
        schedule_delays(paper_six(), P, D, tau_min=(4.4, 0.0), tau_max=(4.8, 0.4), grid=5)


# ------------------------------------------------------------------ bad inputs
def test_bad_inputs_raise_named_errors() -> None:
    team = paper_six()
    qp = factors(team, P, D)[1].quasi_polynomial
    with pytest.raises(InputError, match="re_min < re_max"):
        roots_in(qp, 1.0, 1.0, (1.0, 0.0, -1.0, 1.0))
    with pytest.raises(InputError, match="four finite"):
        roots_in(qp, 1.0, 1.0, (0.0, 1.0, -1.0))
    with pytest.raises(DelayError, match="tau1"):
        rightmost_root(qp, -1.0, 1.0)
    # neutral (s + 1 + 0.5 s e^{-s}) is answered by analysis/neutral: its real root right of
    # the essential spectrum Re s = ln 0.5 (the root of s + 1 + 0.5 s e^{-s} on the reals, brentq)
    from scipy.optimize import brentq
    real_root = brentq(lambda x: x + 1.0 + 0.5 * x * np.exp(-x), -0.69, 0.0, xtol=1e-15)
    assert abs(rightmost_root(TwoDelayQuasiPolynomial([1.0, 1.0], [0.0, 0.5]), 1.0, 1.0) - real_root) < 1e-12
    with pytest.raises(DelayError, match="non-empty"):
        dominant_root_map(team, P, D, [], [1.0])
    with pytest.raises(DelayError, match="must not exceed"):
        schedule_delays(team, P, D, tau_min=(2.0, 1.0), tau_max=(1.0, 3.0))
    with pytest.raises(DelayError, match="non-negative"):
        schedule_delays(team, P, D, tau_min=(-1.0, 1.0), tau_max=(1.0, 3.0))
    split = Topology.from_edges([(0, 1), (1, 0), (2, 3), (3, 2)], 4)
    with pytest.raises(NoSpanningTreeError):
        dominant_root(split, P, D, 1.0, 1.0)


def test_ring_dominant_root_matches_reference() -> None:
    team = ring(5)
    got = dominant_root(team, P, D, 0.5, 0.7)
    want = ref.reference_dominant_root(team, P, D, 0.5, 0.7)
    assert abs(got.root - want) < 1e-8


# ------------------------------------------------------------------ CTCR agreement
def test_sign_of_dominant_root_agrees_with_ctcr_map() -> None:
    ctcr = pytest.importorskip("delayform.analysis.ctcr.stability_map")
    team = paper_six()
    chart = ctcr.stability_map(team, P, D, 10.0, 10.0)
    tau1 = np.linspace(0.05, 9.95, 23)
    tau2 = np.linspace(0.05, 9.95, 21)
    dmap = dominant_root_map(team, P, D, tau1, tau2)
    checked = 0
    for i, t1 in enumerate(tau1):
        for j, t2 in enumerate(tau2):
            re = dmap.real[i, j]
            if abs(re) > 1e-6:
                assert bool(chart.is_stable(t1, t2)) is bool(re < 0), (t1, t2, re)
                checked += 1
    assert checked > 400


def test_certified_unstable_root_count_agrees_with_ctcr_nu() -> None:
    ctcr = pytest.importorskip("delayform.analysis.ctcr.stability_map")
    team = paper_six()
    chart = ctcr.stability_map(team, P, D, 10.0, 10.0)
    fs = factors(team, P, D)
    rng = np.random.default_rng(11)
    for t1, t2 in zip(rng.uniform(0.05, 9.95, 12), rng.uniform(0.05, 9.95, 12), strict=True):
        if abs(dominant_root(team, P, D, t1, t2).root.real) < 1e-6:
            continue
        nu = sum(f.multiplicity * spectrum.count_roots_right_of(f, t1, t2, 1e-9) for f in fs)
        assert nu == int(chart.unstable_count(t1, t2)), (t1, t2)


def test_dominant_root_map_reports_progress_to_a_callback():
    calls: list[tuple[int, int]] = []
    grid = [0.3, 1.0, 2.0]
    with_callback = dominant_root_map(paper_six(), 1.0, 0.5, grid, grid, progress=lambda d, t: calls.append((d, t)))
    plain = dominant_root_map(paper_six(), 1.0, 0.5, grid, grid)
    total = 5 * 3 * 3  # factors x grid points
    assert calls and calls[-1] == (total, total)
    assert all(b[0] >= a[0] for a, b in zip(calls, calls[1:]))
    np.testing.assert_array_equal(with_callback.roots, plain.roots)
