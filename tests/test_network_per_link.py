"""Per-link constant delays: the certified dominant root of det M(s) (issue 20, part 1).

The reference here is independent of delayform's code: a uniform-grid
finite-difference discretization of the full 2N-state DDE (second-order
backward differences, linear interpolation of the delayed values), dense
eigenvalues, then Newton with a numerical derivative on det M(s) built from the
adjacency matrix directly.
"""

from __future__ import annotations

import numpy as np
import pytest

from delayform.analysis.network import link_dominant_root
from delayform.analysis.network.blas import single_threaded_blas
from delayform.analysis.network.count import count_right_of
from delayform.analysis.network.links import link_team
from delayform.analysis.roots.dominant import dominant_root
from delayform.errors import DelayError
from delayform.topology import Topology, paper_six, random_digraph


def _det(C: np.ndarray, P: float, D: float, t1: np.ndarray, t2: np.ndarray, s: complex) -> complex:
    K = C * (P * np.exp(-t1 * s) + D * s * np.exp(-t2 * s))
    return complex(np.linalg.det((s * s + D * s + P) * np.eye(C.shape[0]) - K))


def _reference_roots(C, P, D, t1, t2, K=70):
    """Eigenvalues of a finite-difference generator of the 2N-state DDE, polished by a secant-Newton on det."""
    n = C.shape[0]
    m = 2 * n
    h = max(t1[C > 0].max(), t2[C > 0].max())
    dt = h / K
    size = m * (K + 1)  # block j: z(-j dt)
    A = np.zeros((size, size))
    for j in range(1, K + 1):  # dz/dtheta at theta_j, one-sided second order (interior: central)
        r = slice(j * m, (j + 1) * m)
        if j < K:
            A[r, (j - 1) * m : j * m] += np.eye(m) / (2 * dt)
            A[r, (j + 1) * m : (j + 2) * m] -= np.eye(m) / (2 * dt)
        else:
            A[r, (j - 2) * m : (j - 1) * m] += -np.eye(m) / (2 * dt)
            A[r, (j - 1) * m : j * m] += 4 * np.eye(m) / (2 * dt)
            A[r, j * m : (j + 1) * m] += -3 * np.eye(m) / (2 * dt)
    idx = np.arange(n)
    A[idx, n + idx] = 1.0
    A[n + idx, idx] = -P
    A[n + idx, n + idx] = -D
    for i, k in zip(*np.nonzero(C)):
        for tau, g, off in ((t1[i, k], P, 0), (t2[i, k], D, n)):
            q = tau / dt
            j0 = min(int(np.floor(q)), K - 1)
            w = q - j0
            A[n + i, j0 * m + off + k] += C[i, k] * g * (1 - w)
            A[n + i, (j0 + 1) * m + off + k] += C[i, k] * g * w
    vals = np.linalg.eigvals(A)
    vals = vals[(vals.real > -0.6) & (vals.imag >= 0) & (np.abs(vals) < 4)]
    out = []
    for s in vals:
        for _ in range(60):
            f = _det(C, P, D, t1, t2, s)
            e = 1e-7 * (1 + abs(s))
            df = (_det(C, P, D, t1, t2, s + e) - _det(C, P, D, t1, t2, s - e)) / (2 * e)
            step = f / df
            s = s - step
            if abs(step) < 1e-14 * (1 + abs(s)):
                break
        if abs(step) < 1e-11 and not any(abs(s - o) < 1e-6 for o in out):
            out.append(s)
    return np.array(out)


def _check_against_reference(T, P, D, t1, t2):
    """The certified roots right of the line are those of the finite-difference reference, to 1e-7."""
    r = link_dominant_root(T, P, D, t1, t2)
    with single_threaded_blas():  # only the thread count (a dense eigensolve of ~600 states)
        ref = _reference_roots(T.C_sparse.toarray(), P, D, t1, t2)
    ref_right = ref[(ref.real > r.line) & (np.abs(ref) > 1e-9)]
    ours = r.roots[r.roots != 0]
    assert ref_right.size == ours.size
    for z in ref_right:
        assert np.min(np.abs(ours - z)) < 1e-7
    assert abs(ref_right[np.argmax(ref_right.real)].real - r.root.real) < 1e-7
    return r


def test_equal_link_delays_reproduce_the_factorized_answer():
    T = paper_six()
    for t1, t2 in [(1.0, 0.5), (0.3, 0.2), (1.0, 2.0), (2.0, 0.4)]:
        old = dominant_root(T, 1.0, 0.5, t1, t2)
        new = dominant_root(T, 1.0, 0.5, np.full((6, 6), t1), np.full((6, 6), t2))
        assert abs(new.root - old.stability_root) < 1e-9
        assert new.is_stable == old.is_stable


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_per_link_roots_match_an_independent_discretization(seed):
    rng = np.random.default_rng(seed)
    T = random_digraph(4, 0.4, seed=seed)
    C = T.C_sparse.toarray()
    t1 = rng.uniform(0.1, 1.2, (4, 4))
    t2 = rng.uniform(0.1, 1.2, (4, 4))
    P, D = 1.0, 0.8
    r = _check_against_reference(T, P, D, t1, t2)
    # every returned root satisfies det M = 0, relative to the size of the terms
    for z in r.roots:
        scale = abs(z * z + D * z + P) ** 4 + 1.0
        assert abs(_det(C, P, D, t1, t2, z)) < 1e-9 * scale


def test_count_sees_a_root_moved_across_the_line():
    # point c of Fig. stability: unstable pairs at Re 0.0836 and 0.0267 (factor roots by roots_in)
    team = link_team(paper_six(), 1.0, 0.5, 1.0, 2.0)
    assert count_right_of(team, 0.1) == 0
    assert count_right_of(team, 0.05) == 2
    assert count_right_of(team, 0.01) == 4
    assert count_right_of(team, -0.01) == 5  # the centroid's zero joins


def test_unstable_per_link_point_is_reported_unstable():
    t1 = np.full((6, 6), 1.0)
    t2 = np.full((6, 6), 2.0)
    t2[2, 1] = 2.3
    r = link_dominant_root(paper_six(), 1.0, 0.5, t1, t2)
    assert not r.is_stable and r.growth_rate > 0


def test_drift_on_zero_position_delays():
    r = link_dominant_root(paper_six(), 1.0, 0.5, np.zeros((6, 6)), np.full((6, 6), 0.3))
    old = dominant_root(paper_six(), 1.0, 0.5, 0.0, 0.3)
    assert r.drift
    assert abs(r.root - old.stability_root) < 1e-9


def test_entries_without_a_link_are_ignored():
    t1 = np.full((6, 6), 0.6)
    C = paper_six().C_sparse.toarray()
    t1[C == 0] = np.nan
    a = link_dominant_root(paper_six(), 1.0, 0.5, t1, 0.4)
    b = link_dominant_root(paper_six(), 1.0, 0.5, 0.6, 0.4)
    assert abs(a.root - b.root) < 1e-12


@pytest.mark.parametrize(
    "tau1, match",
    [(np.ones((5, 5)), "6 x 6"), (-np.ones((6, 6)), "non-negative"), (np.full((6, 6), np.inf), "finite")],
)
def test_bad_per_link_delays_are_named(tau1, match):
    with pytest.raises(DelayError, match=match):
        link_dominant_root(paper_six(), 1.0, 0.5, tau1, 0.5)


def test_plot_draws_roots():
    r = link_dominant_root(Topology.from_adjacency(np.array([[0, 1], [1, 0]])), 1.0, 1.0, 0.5, 0.5)
    ax = r.plot()
    assert ax.get_xlabel() == "Re s"


@pytest.mark.parametrize("c", [-0.3, 0.05])
def test_count_of_a_larger_team_matches_the_factorized_count(c):
    # 14 agents: the large-team phase rule (first-order branch); equal delays factorize, so the
    # per-factor argument-principle counts of delayform.analysis.roots are an independent check
    from delayform.analysis.roots import count_roots_right_of
    from delayform.characteristic import factors

    T = random_digraph(14, 0.15, seed=5)
    expected = sum(f.multiplicity * count_roots_right_of(f, 1.0, 0.8, c) for f in factors(T, 1.0, 0.5))
    assert count_right_of(link_team(T, 1.0, 0.5, 1.0, 0.8), c) == expected


# ------------------------------------------------------------ every option reaches the answer
def test_every_per_link_entry_point_option_changes_its_answer():
    # one changed keyword, one changed answer: no option of these entry points is dropped on the way
    from delayform.analysis.network import jitter_margin, mean_square_stability
    from delayform.analysis.network.bursty import bursty_mean_square_stability
    from delayform.analysis.roots.dominant import dominant_root

    top = paper_six()
    t1 = np.full((6, 6), 0.3)
    t1b = t1.copy()
    t1b[0, 1] = 0.9  # a link of paper_six
    assert jitter_margin(top, 1.0, 0.5, t1, 0.2).delta != jitter_margin(top, 1.0, 0.5, t1b, 0.2).delta
    ms = [mean_square_stability(top, 1.0, 0.5, 0.3, 0.2, rate=10.0, loss=p).rho for p in (0.1, 0.4)]
    assert ms[0] != ms[1]
    assert mean_square_stability(top, 1.0, 0.5, 0.4, 0.2, rate=5.0, loss=0.1).rho != mean_square_stability(top, 1.0, 0.5, 0.4, 0.2, rate=10.0, loss=0.1).rho
    from delayform.topology import ring

    bursty = [bursty_mean_square_stability(ring(3), 1.0, 1.0, 0.2, 0.1, rate=10.0, p_good_to_bad=0.1, p_bad_to_good=q).rho
              for q in (0.3, 0.8)]  # fmt: skip
    assert bursty[0] != bursty[1]
    with_ta = dominant_root(top, 1.0, 0.5, t1, np.full((6, 6), 0.2), actuation_delay=0.3).root
    assert with_ta != dominant_root(top, 1.0, 0.5, t1, np.full((6, 6), 0.2)).root
