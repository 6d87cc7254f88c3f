"""The eigenvalue plane (issue 11): region, certificates for classes of teams, large-team bounds.

Every claim is checked against an independent construction: the argument
principle in s (tests/ref_region.py), the exact CTCR maps of single factors
(:func:`delayform.analysis.ctcr.stability_map.crossing_map`), dominant roots and dense eigenvalues.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from ref_region import rhp_count

from delayform.analysis.plane.spectrum_bounds import spectrum_bound
from delayform.analysis.plane.spectrum_sets import SpectrumSet, parse_spectrum, safe_delays
from delayform.analysis.ctcr.stability_map import PAPER_POINTS, lam_factor, crossing_map, stability_map
from delayform.analysis.plane.region import lambda_region
from delayform.analysis.roots.dominant import dominant_root, rightmost_root
from delayform.characteristic import factors
from delayform.errors import DelayError, GainError, InputError, ResourceLimitError
from delayform.topology import Topology, grid, paper_six, ring


# ------------------------------------------------------------------ the region
def test_unstable_count_matches_argument_principle_on_160_random_cases(rng: np.random.Generator) -> None:
    checked = 0
    for _ in range(160):
        P, D = rng.uniform(0.2, 3.0), rng.uniform(0.1, 2.0)
        t1, t2 = rng.uniform(0.0, 6.0), rng.uniform(0.0, 6.0)
        lam = complex(rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0))  # inside and outside the unit disc
        ref = rhp_count(lam, P, D, t1, t2)
        if ref is None:  # a root next to the imaginary axis: the reference cannot decide
            continue
        region = lambda_region(P, D, t1, t2)
        assert int(region.unstable_count(lam)) == ref, (P, D, t1, t2, lam)
        assert bool(region.is_stable(lam)) == (ref == 0)
        checked += 1
    assert checked >= 150


def test_vectorised_count_equals_one_by_one() -> None:
    region = lambda_region(1.0, 0.5, 1.3, 0.7)
    lam = np.array([[0.2 + 0.3j, -0.9, 1.7 - 0.2j], [2.5j, -2.0 - 1.0j, 0.99]])
    one = np.array([[int(region.unstable_count(z)) for z in row] for row in lam])
    assert np.array_equal(region.unstable_count(lam), one)
    assert region.unstable_count(lam).shape == (2, 3)


@pytest.mark.parametrize("label", list(PAPER_POINTS))
def test_paper_team_eigenvalues_agree_with_dominant_roots(label: str) -> None:
    t1, t2 = PAPER_POINTS[label]
    topo = paper_six()
    region = lambda_region(1.0, 0.5, t1, t2)
    for f in factors(topo, 1.0, 0.5):
        if f.is_centroid:
            continue
        assert bool(region.is_stable(f.lam)) == (rightmost_root(f, t1, t2).real < 0.0), (label, f.lam)
    assert region.team_is_stable(topo) == dominant_root(topo, 1.0, 0.5, t1, t2).is_stable


def test_centroid_and_real_eigenvalues_above_one() -> None:
    region = lambda_region(1.0, 0.5, 0.3, 0.2)
    assert region.unstable_count(1.0) == 0  # the zero root of eq. factor1 is not counted
    assert region.unstable_count(1.0 + 1e-12) == 0  # within CENTROID_TOL
    assert region.unstable_count(1.01) == 1  # q(0) < 0 < q(+inf): one positive real root
    assert region.unstable_count(0.0) == 0


@given(
    st.floats(0.2, 3.0), st.floats(0.1, 2.0), st.floats(0.0, 5.0), st.floats(0.0, 5.0),
    st.floats(-3.0, 3.0), st.floats(0.01, 3.0),
)
def test_conjugate_symmetry_and_non_negative(P: float, D: float, t1: float, t2: float, x: float, y: float) -> None:
    region = lambda_region(P, D, t1, t2)
    z = complex(x, y)
    n = region.unstable_count(np.array([z, np.conj(z)]))
    assert n[0] == n[1] >= 0


def test_boundary_points_are_imaginary_roots() -> None:
    P, D, t1, t2 = 1.0, 0.5, 1.0, 2.0
    lam = lambda_region(P, D, t1, t2).boundary(2.0)
    lam = lam[np.isfinite(lam)]
    # each boundary point L(j w) has a root on the imaginary axis: |q(j w, lam)| ~ 0 for some w
    assert lam.size > 100
    w = np.linspace(-4.0, 4.0, 400001)
    s = 1j * w
    a, b = s * s + D * s + P, D * s * np.exp(-t2 * s) + P * np.exp(-t1 * s)
    L = a / b
    for z in lam[:: max(1, lam.size // 40)]:
        assert np.min(np.abs(L - z)) < 5e-3


def test_region_plot_marks_eigenvalues() -> None:
    ax = lambda_region(1.0, 0.5, 1.0, 2.0).plot(topology=paper_six())
    assert ax.get_xlabel() == r"Re $\lambda$"
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "eigenvalue, unstable" in labels


def test_region_input_errors() -> None:
    with pytest.raises(GainError):
        lambda_region(0.0, 0.5, 1.0, 1.0)
    with pytest.raises(DelayError):
        lambda_region(1.0, 0.5, -1.0, 1.0)
    with pytest.raises(InputError):
        lambda_region(1.0, 0.5, 1.0, 1.0).unstable_count(np.nan)
    with pytest.raises(InputError, match="at most"):
        lambda_region(1.0, 0.5, 1.0, 1.0).unstable_count(1e6)
    with pytest.raises(ResourceLimitError, match="samples"):  # refused up front, with what it would need
        lambda_region(1.0, 0.5, 1e6, 1.0).is_stable(0.5)
    with pytest.raises(InputError):
        lambda_region(1.0, 0.5, 1.0, 1.0).team_is_stable("paper")  # type: ignore[arg-type]


# ------------------------------------------------------------------ certificates
def _reference_safe(P: float, D: float, lams: np.ndarray, T1: np.ndarray, T2: np.ndarray, w1: float, w2: float) -> np.ndarray:
    """Safe where every sampled eigenvalue's factor has NU = 0 in its exact CTCR map."""
    ok = np.ones(T1.shape, bool)
    for lam in lams:
        ok &= crossing_map(lam_factor(P, D, lam), w1, w2).unstable_count(T1, T2) == 0
    return ok


def _away_from_change(ref: np.ndarray) -> np.ndarray:
    """Cells whose 4 neighbours have the same reference value (away from the boundary)."""
    keep = np.ones(ref.shape, bool)
    keep[1:] &= ref[1:] == ref[:-1]
    keep[:-1] &= ref[:-1] == ref[1:]
    keep[:, 1:] &= ref[:, 1:] == ref[:, :-1]
    keep[:, :-1] &= ref[:, :-1] == ref[:, 1:]
    return keep


def test_undirected_safe_delays_agree_with_dense_eigenvalue_sample() -> None:
    m = safe_delays(1.0, 0.5, 4.0, 4.0, spectrum="undirected")
    t1, t2, safe = m.grid(60)
    T1, T2 = np.meshgrid(t1, t2)
    lams = np.concatenate([np.linspace(-1.0, 1.0, 121)[:-1], 1.0 - np.geomspace(1e-4, 1e-2, 4)])
    ref = _reference_safe(1.0, 0.5, lams, T1, T2, 4.0, 4.0)
    keep = _away_from_change(ref)
    assert np.array_equal(safe[keep], ref[keep])
    assert 0.08 < safe.mean() < 0.2
    assert bool(m.is_safe(*PAPER_POINTS["a"])) and not bool(m.is_safe(*PAPER_POINTS["c"]))


def test_any_team_is_never_safe_for_the_paper_gains() -> None:
    m = safe_delays(1.0, 0.5, 4.0, 4.0, spectrum="any")
    assert m.safe_fraction(resolution=40) == 0.0
    # The reasons (docs/theory.md), checked with the region: where D (tau1 - tau2) < 1 the
    # curve enters the unit disc next to lam = 1; elsewhere lam = -1 or the centroid is unstable.
    phi = np.geomspace(1e-3, 0.3, 40)
    for a in np.linspace(0.05, 3.95, 9):
        for b in np.linspace(0.05, 3.95, 9):
            region = lambda_region(1.0, 0.5, a, b)
            if 0.5 * (a - b) < 1.0:
                assert np.any(region.unstable_count(np.exp(1j * phi)) > 0), (a, b)
            else:
                assert region.unstable_count(-1.0) > 0 or region.unstable_count(1.0) > 0, (a, b)


def test_directed_ring_is_unstable_where_the_unit_circle_is() -> None:
    # A ring of n agents has the eigenvalues e^{2 pi j k / n}: near 1 for large n.
    a, b = 0.3, 0.2  # stable for the paper team, yet D (tau1 - tau2) < 1
    region = lambda_region(1.0, 0.5, a, b)
    n = 40
    assert not region.team_is_stable(ring(n))
    assert not dominant_root(ring(n), 1.0, 0.5, a, b).is_stable


def test_interior_eigenvalue_envelope() -> None:
    # Gains where the stable real eigenvalues form two intervals: an eigenvalue inside
    # [low, high] becomes unstable while both ends are stable (the envelope bounds the set).
    P, D, low, high = 4.72, 0.366, -0.8, 0.5
    m = safe_delays(P, D, 0.6, 10.0, spectrum=f"interval:{low},{high}")
    t1, t2, safe = m.grid(50)
    T1, T2 = np.meshgrid(t1, t2)
    lams = np.linspace(low, high, 81)
    ref = _reference_safe(P, D, lams, T1, T2, 0.6, 10.0)
    ends = _reference_safe(P, D, np.array([low, high]), T1, T2, 0.6, 10.0)
    keep = _away_from_change(ref)
    assert np.array_equal(safe[keep], ref[keep])
    assert np.any(ends & ~ref)  # interior-only instability exists here
    assert len(m.envelope) > 50
    # every envelope vertex: q(j w; x, tau) = 0 for some real x with a tangency: the
    # factor of some x in (low, high) has an imaginary root there (its CTCR curve passes)
    pts = np.concatenate(m.envelope)[::25]
    for tt1, tt2 in pts:
        if not (0.0 < tt1 < 0.6 and 0.0 < tt2 < 10.0):
            continue
        region = lambda_region(P, D, tt1, tt2)
        curve = region.boundary(2.0)
        real_pts = curve[np.isfinite(curve) & (np.abs(curve.imag) < 1e-3)]
        assert np.any((real_pts.real > low) & (real_pts.real < high)), (tt1, tt2)


def test_spectrum_sets_and_errors() -> None:
    assert parse_spectrum("undirected").kind == "interval"
    assert parse_spectrum("any").radius == 1.0
    assert parse_spectrum("disc:0.5,0.5").center == 0.5
    assert parse_spectrum("disc:0,0.2,0.5").center == 0.2j
    s = SpectrumSet.interval(-0.5, 0.5)
    assert s.contains(0.1).item() and not s.contains(0.6).item()
    for bad in ("interval:1", "disc:a,b", "ball:1,2", 3):
        with pytest.raises(InputError):
            parse_spectrum(bad)
    with pytest.raises(InputError):
        SpectrumSet.interval(1.0, 0.0)
    assert safe_delays(1.0, 0.5, 2.0, 2.0, spectrum="interval:-0.5,1.5").safe_fraction(resolution=10) == 0.0
    m = safe_delays(1.0, 0.5, 2.0, 2.0, spectrum="interval:-0.5,0.5")
    with pytest.raises(DelayError):
        m.is_safe(3.0, 1.0)


@pytest.mark.parametrize(("c", "r"), [(-0.2 + 0.1j, 0.4), (0.5 + 0j, 0.5)])
def test_disc_against_region(c: complex, r: float) -> None:
    # A disc away from 1, and one tangent to the boundary curve at 1: safe exactly where the
    # region holds the disc (sampled densely).
    P, D = 1.0, 0.5
    m = safe_delays(P, D, 4.0, 4.0, spectrum=f"disc:{c.real},{c.imag},{r}")
    t = (np.arange(10) + 0.5) * 4.0 / 10
    rho, ang = np.meshgrid(np.linspace(0.0, r, 12), np.linspace(0.0, 2 * np.pi, 48, endpoint=False))
    disc = (c + rho * np.exp(1j * ang)).ravel()
    disc = disc[np.abs(disc - 1.0) > 1e-6]
    agree = 0
    for a in t:
        for b in t:
            ref = bool(np.all(lambda_region(P, D, a, b).is_stable(disc)))
            got = bool(m.is_safe(a, b))
            assert not got or ref, (a, b)  # safe is certified: never where a sampled eigenvalue is unstable
            agree += got == ref  # the sample can miss a thin unstable sliver the scan finds
    assert agree >= 0.95 * t.size**2
    assert 0.0 < m.safe_fraction(resolution=20) < 1.0


def test_safe_chart_draws() -> None:
    ax = safe_delays(1.0, 0.5, 4.0, 4.0, spectrum="undirected").plot(points={"a": (0.3, 0.2)})
    assert "undirected" in ax.get_title()


# ------------------------------------------------------------------ large teams
def test_grid_sufficient_map_is_inside_the_exact_map_and_covers_it() -> None:
    topo = grid(20, 20)
    bound = spectrum_bound(topo)
    assert bound.spectrum_set.low == -1.0 and bound.high_certified
    exact = stability_map(topo, 1.0, 0.5, 4.0, 4.0)
    m = safe_delays(1.0, 0.5, 4.0, 4.0, spectrum=bound)
    t1, t2, safe = m.grid(80)
    T1, T2 = np.meshgrid(t1, t2)
    stable = exact.is_stable(T1, T2)
    assert not np.any(safe & ~stable)  # sufficient: never stable where the exact map says unstable
    assert (safe & stable).sum() >= 0.9 * stable.sum()


def _extreme_eigenvalues(topo: Topology) -> tuple[float, float]:
    """Smallest and second-largest eigenvalue of C by plain Lanczos (no shift-invert, no deflation)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import eigsh

    h = 1.0 / np.sqrt(topo.in_degree)
    S = sp.diags_array(h) @ topo.adjacency_sparse @ sp.diags_array(h)
    v0 = np.random.default_rng(1).standard_normal(topo.n)
    top = np.sort(eigsh(S, k=3, which="LA", tol=1e-13, v0=v0, ncv=60, return_eigenvectors=False))
    low = eigsh(S, k=1, which="SA", tol=1e-13, v0=v0, ncv=60, return_eigenvectors=False)
    return float(low[0]), float(top[-2])


def test_sparse_bound_holds_and_is_tight() -> None:
    rows, cols = 45, 46
    topo = grid(rows, cols)  # above the dense limit: shift-invert Lanczos + inertia certificates
    b = spectrum_bound(topo)
    lo, lam2 = _extreme_eigenvalues(topo)
    assert b.high_certified and b.spectrum_set.low == -1.0 and lo == pytest.approx(-1.0, abs=1e-9)
    assert lam2 <= b.spectrum_set.high <= lam2 + 1e-5
    # not bipartite: a grid with one diagonal per cell
    idx = np.arange(rows * cols).reshape(rows, cols)
    i, j = idx[:-1, :-1].ravel(), idx[1:, 1:].ravel()
    diag = np.zeros((rows * cols, rows * cols))
    diag[i, j] = diag[j, i] = 1.0
    tri = Topology.from_adjacency(topo.adjacency_sparse.toarray() + diag, name="triangulated")
    b2 = spectrum_bound(tri)
    lo2, lam22 = _extreme_eigenvalues(tri)
    assert b2.low_certified and b2.high_certified
    assert lo2 - 1e-5 <= b2.spectrum_set.low <= lo2
    assert lam22 <= b2.spectrum_set.high <= lam22 + 1e-5


def test_directed_bound_is_the_unit_disc() -> None:
    b = spectrum_bound(ring(5))
    assert b.spectrum_set.kind == "disc" and b.spectrum_set.radius == 1.0 and not b.undirected
    assert np.all(b.spectrum_set.contains(ring(5).eigenvalues))


def test_grid_builder() -> None:
    t = grid(3, 4)
    A = t.adjacency_sparse.toarray()
    assert t.n == 12 and np.array_equal(A, A.T) and A.sum() == 2 * (3 * 3 + 2 * 4)
    assert np.isclose(t.eigenvalues.real.min(), -1.0)  # bipartite
    with pytest.raises(InputError):
        grid(1, 1)


def test_bound_falls_back_to_the_theorem_when_a_factorization_would_not_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    import delayform.analysis.plane.spectrum_bounds as bounds

    monkeypatch.setattr(bounds, "FACTOR_MEMORY_BUDGET", 1)
    b = bounds.spectrum_bound(grid(45, 46))
    assert (b.spectrum_set.low, b.spectrum_set.high) == (-1.0, 1.0) and not b.high_certified
    assert "not tightened" in b.method and "GiB" in b.method
    # the estimate is an upper estimate of the real fill for grids (minimum-degree LU: ~n log n)
    assert bounds.factor_memory_estimate(grid(40, 40).adjacency_sparse) >= 8 * 40**3


def test_undirected_certificate_holds_for_random_undirected_teams(rng: np.random.Generator) -> None:
    import networkx as nx

    m = safe_delays(1.0, 0.5, 4.0, 4.0, spectrum="undirected")
    t1, t2, safe = m.grid(40)
    pairs = np.argwhere(safe)
    picks = pairs[rng.choice(len(pairs), size=6, replace=False)]
    for seed in range(3):
        G = nx.connected_watts_strogatz_graph(10 + 3 * seed, 4, 0.3, seed=seed)
        team = Topology.from_networkx(G)
        for i2, i1 in picks:
            # certified safe for every undirected team: this one is stable, by its own dominant root
            assert dominant_root(team, 1.0, 0.5, t1[i1], t2[i2]).is_stable, (seed, t1[i1], t2[i2])


def _curve_points(m: object) -> np.ndarray:
    pts = [np.column_stack([c.tau1, c.tau2]) for base in m.base_maps for c in base.curves]  # type: ignore[attr-defined]
    for line in m.envelope:  # type: ignore[attr-defined]
        # densify: segments may be longer than a cell
        t = np.linspace(0.0, 1.0, 20)[:, None]
        pts += [a + t * (b - a) for a, b in zip(line[:-1], line[1:], strict=True)]
    return np.concatenate(pts)


@pytest.mark.parametrize(
    ("P", "D", "spectrum", "window"),
    [(4.72, 0.366, "interval:-0.8,0.5", (0.6, 10.0)), (1.0, 0.5, "disc:-0.2,0.1,0.4", (4.0, 4.0)),
     (1.0, 0.5, "disc:0.5,0.5", (4.0, 4.0))],
)
def test_safe_set_boundary_lies_on_the_drawn_curves(P: float, D: float, spectrum: str, window: tuple[float, float]) -> None:
    from scipy.spatial import cKDTree

    m = safe_delays(P, D, *window, spectrum=spectrum)
    t1, t2, safe = m.grid(60)
    tree = cKDTree(_curve_points(m) / np.array(window))
    cell = 1.0 / 60
    for axis in (0, 1):
        change = np.diff(safe.astype(int), axis=axis) != 0
        i2, i1 = np.nonzero(change)
        if axis == 0:
            mid = np.column_stack([t1[i1], 0.5 * (t2[i2] + t2[i2 + 1])])
        else:
            mid = np.column_stack([0.5 * (t1[i1] + t1[i1 + 1]), t2[i2]])
        dist, _ = tree.query(mid / np.array(window))
        assert np.all(dist < 2.0 * cell), (axis, mid[dist >= 2.0 * cell][:5])


def test_too_large_a_window_is_refused_up_front() -> None:
    with pytest.raises(ResourceLimitError, match="GiB"):
        safe_delays(1.0, 0.5, 2000.0, 2000.0)
    m = safe_delays(1.0, 0.5, 4.0, 4.0, spectrum="interval:-0.5,0.9")
    assert m.envelope_note == ""
