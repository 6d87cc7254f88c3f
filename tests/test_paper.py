"""Regression against the paper's statements on its delay-scheduling figures (Figs. dominant, contour).

Section "Simulation Examples": "the best delay combinations are those in the vicinity of the
origin, and in a small region for tau1 in (0, 1) and tau1 in (4, 6)". The second interval is
a typo for tau2 (tau1 cannot lie in both); delayform reads it as tau2 in (4, 6).
"""

from __future__ import annotations

import numpy as np

from delayform import dominant_root_map, paper_six, stability_map


def test_valleys_of_the_dominant_root_where_the_paper_says():
    team = paper_six()
    t1 = np.linspace(0.0, 1.5, 16)
    t2 = np.linspace(3.5, 7.0, 36)
    valley = dominant_root_map(team, 1.0, 0.5, t1, t2)
    i, j = np.unravel_index(np.argmin(valley.real), valley.real.shape)
    # the deepest point of this window lies inside tau1 in (0, 1), tau2 in (4, 6) ...
    assert 0.0 < t1[i] < 1.0 and 4.0 < t2[j] < 6.0
    # ... is a real valley (stable, with margin), lower than the window's edges ...
    assert valley.real[i, j] < -0.1
    edges = np.concatenate([valley.real[0], valley.real[-1], valley.real[:, 0], valley.real[:, -1]])
    assert valley.real[i, j] < edges.min()
    # ... and the CTCR map, an independent method, declares it stable
    assert stability_map(team, 1.0, 0.5, 8.0, 8.0).is_stable(t1[i], t2[j])


def test_best_delays_overall_are_near_the_origin():
    grid = np.linspace(0.0, 8.0, 41)
    whole = dominant_root_map(paper_six(), 1.0, 0.5, grid, grid)
    tau1, tau2, root = whole.best()
    assert np.hypot(tau1, tau2) < 0.5
    assert root.real < -0.15
