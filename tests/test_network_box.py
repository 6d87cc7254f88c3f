"""A box of constant per-link delays certified stable (issue 20, part 2).

A certified box is checked against the exact per-link roots of part 1 at random
assignments inside it (each link its own delays): none may be unstable.
"""

from __future__ import annotations

import numpy as np
import pytest

from delayform.analysis.network import link_dominant_root, robust_stability
from delayform.errors import DelayError
from delayform.topology import paper_six, random_digraph


@pytest.mark.parametrize(
    "box1, box2", [((0.95, 1.05), (0.45, 0.55)), ((0.2, 0.4), (0.1, 0.3)), ((1.95, 2.05), (0.38, 0.42))]
)
def test_random_assignments_inside_a_certified_box_are_stable(box1, box2, rng):
    T = paper_six()
    r = robust_stability(T, 1.0, 0.5, box1, box2)
    assert r.certified and r.margin > 0
    for _ in range(6):
        t1 = rng.uniform(*box1, (6, 6))
        t2 = rng.uniform(*box2, (6, 6))
        assert link_dominant_root(T, 1.0, 0.5, t1, t2).is_stable


def test_a_random_team_box_certified_is_stable_at_every_draw(rng):
    T = random_digraph(5, 0.3, seed=7)
    r = robust_stability(T, 1.0, 2.0, (0.3, 0.5), (0.2, 0.4))
    assert r.certified
    for _ in range(6):
        t1, t2 = rng.uniform(0.3, 0.5, (5, 5)), rng.uniform(0.2, 0.4, (5, 5))
        assert link_dominant_root(T, 1.0, 2.0, t1, t2).is_stable


def test_a_box_across_the_boundary_is_never_certified():
    # tau2 from 0.5 (stable) to 2.5 (point c region, unstable): the corner or a draw is unstable
    r = robust_stability(paper_six(), 1.0, 0.5, (0.9, 1.1), (0.5, 2.5))
    assert not r.certified
    assert r.status == "unstable"
    t1, t2 = r.witness
    assert not link_dominant_root(paper_six(), 1.0, 0.5, t1, t2).is_stable


def test_unstable_centre_is_reported_with_the_centre_as_witness():
    r = robust_stability(paper_six(), 1.0, 0.5, (0.9, 1.1), (1.9, 2.1))
    assert r.status == "unstable" and r.witness_root.real > 0


def test_per_link_box_ends():
    lo = np.full((6, 6), 0.95)
    hi = np.full((6, 6), 1.05)
    hi[0, 1] = 1.0
    assert robust_stability(paper_six(), 1.0, 0.5, (lo, hi), (0.45, 0.55)).certified


@pytest.mark.parametrize(
    "box1, match", [((1.1, 0.9), "lo > hi"), ((-0.1, 0.2), "non-negative"), ((0.1,), "tau1 must be a tuple of 2"), ((np.ones((2, 2)), 1.0), "6 x 6")]
)
def test_bad_boxes_are_named(box1, match):
    with pytest.raises(DelayError, match=match):
        robust_stability(paper_six(), 1.0, 0.5, box1, (0.4, 0.6))


def test_plot_box():
    ax = robust_stability(paper_six(), 1.0, 0.5, (0.95, 1.05), (0.45, 0.55)).plot()
    assert ax.get_xlabel() == "tau1 (s)"
