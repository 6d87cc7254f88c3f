"""The certified jitter margin (issue 20, part 3).

Checks: the H-infinity bound is never below an independent dense sampling of
sigma_max(G(iw)) built here from the adjacency matrix; the margin is 0 at an
unstable point; and simulations with jitter and with smooth variations within
the certified delta settle at the paper's points a and b over several seeds.
"""

from __future__ import annotations

import numpy as np
import pytest

from delayform.analysis.ctcr import PAPER_POINTS
from delayform.analysis.network import jitter_margin, jitter_margin_map
from delayform.analysis.network.jitter import _Loop, hinf_bound
from delayform.analysis.network.links import link_team
from delayform.errors import DelayError
from delayform.formation import named_formation
from delayform.simulation import simulate
from delayform.model.network import Jitter, Network, SmoothVariation
from delayform.topology import paper_six


def _dense_peak(C, P, D, t1, t2, w):
    """max over w of sigma_max of the loop, from M(iw) assembled here, channel by channel."""
    rows, cols = np.nonzero(C)
    L = rows.size
    peak = 0.0
    for x in w:
        s = 1j * x
        M = (s * s + D * s + P) * np.eye(C.shape[0]) - C * (P * np.exp(-t1 * s) + D * s * np.exp(-t2 * s))
        H = np.linalg.inv(M)
        G = np.zeros((2 * L, 2 * L), complex)
        for a in range(2 * L):  # output channel: informer cols[a % L], velocity (a < L) or acceleration
            for b in range(2 * L):  # input channel: into agent rows[b % L], weight P C or D C
                gain = (P if b < L else D) * C[rows[b % L], cols[b % L]]
                G[a, b] = (s if a < L else s * s) * H[cols[a % L], rows[b % L]] * gain
        peak = max(peak, np.linalg.svd(G, compute_uv=False)[0])
    return peak


@pytest.mark.parametrize("point", ["a", "b"])
def test_the_certified_norm_bounds_an_independent_sampling(point):
    t1, t2 = PAPER_POINTS[point]
    team = link_team(paper_six(), 1.0, 0.5, t1, t2)
    bound, wpk, _, sampled = hinf_bound(_Loop(team))
    C = paper_six().C_sparse.toarray()
    dense = _dense_peak(C, 1.0, 0.5, t1, t2, np.concatenate([np.linspace(1e-4, 3.0, 600), [wpk]]))
    assert dense <= bound * (1 + 1e-9)
    assert bound <= 1.05 * dense  # and it is tight


def test_unstable_point_has_zero_margin():
    m = jitter_margin(paper_six(), 1.0, 0.5, *PAPER_POINTS["c"])
    assert m.delta == 0.0 and not m.nominal_stable


def test_per_link_nominal_delays():
    t1 = np.full((6, 6), 0.3)
    t1[0, 1] = 0.4
    m = jitter_margin(paper_six(), 1.0, 0.5, t1, 0.2)
    assert m.delta > 0.0


SHAPE = named_formation("hexagon", 6, spacing=2.0)
X0 = np.array([[-4.0, 1.0], [3.0, 4.0], [0.5, -3.0], [4.0, -1.0], [-2.0, -4.0], [1.0, 2.5]])


@pytest.mark.slow
@pytest.mark.parametrize("point", ["a", "b"])
def test_simulations_within_the_margin_settle(point):
    t1, t2 = PAPER_POINTS[point]
    delta = jitter_margin(paper_six(), 1.0, 0.5, t1, t2).delta
    assert delta > 0.01
    dt = 0.01
    bound = min(delta, min(t1, t2) - dt)  # the simulator needs every delay >= dt
    nets = [Network(jitter=Jitter(bound, bound), seed=s) for s in range(2)]
    # the smooth variation must change slower than 1 s/s: period > 2 pi delta
    nets += [Network(variation=SmoothVariation(bound, bound, period=8.0 * bound + 1.0), seed=s) for s in range(1)]
    for net in nets:
        traj = simulate(paper_six(), 1.0, 0.5, t1, t2, SHAPE, model="double_integrator", initial_positions=X0,
                        duration=80.0 if point == "a" else 160.0, dt=dt, network=net)  # fmt: skip
        assert traj.formation_error[-1] < 0.02 * traj.formation_error[0], net


def test_map_and_plot():
    m = jitter_margin_map(paper_six(), 1.0, 0.5, [0.3, 1.0], [0.2, 2.0])
    assert m.delta.shape == (2, 2)
    assert m.delta[0, 0] > 0 and m.delta[1, 1] == 0.0
    ax = m.plot()
    assert ax.get_xlabel() == "tau1 (s)"


def test_bad_map_axes():
    with pytest.raises(DelayError):
        jitter_margin_map(paper_six(), 1.0, 0.5, [], [0.2])


@pytest.mark.slow
def test_margin_map_is_zero_exactly_where_the_exact_chart_is_unstable():
    from delayform.analysis.ctcr import stability_map

    ax1, ax2 = [0.3, 2.0], [0.2, 2.0]
    m = jitter_margin_map(paper_six(), 1.0, 0.5, ax1, ax2)
    smap = stability_map(paper_six(), 1.0, 0.5, 3.0, 3.0)
    for i, a in enumerate(ax1):
        for j, b in enumerate(ax2):
            assert (m.delta[i, j] > 0) == smap.is_stable(a, b)
    ax = smap.plot()
    assert m.plot(ax=ax) is ax  # drawn on the stability chart


def test_margin_solves_the_gain_condition_of_the_worst_channel():
    from delayform.analysis.network.jitter import _delta_of_gain

    for gain, tau in [(6.6, 0.3), (2.0, 0.1), (50.0, 0.05), (3.0, 0.0)]:
        d = _delta_of_gain(gain, tau)
        assert d * (d + min(d, tau)) * gain**2 < 1.0  # the small-gain condition holds
        e = d * 1.001
        assert e * (e + min(e, tau)) * gain**2 >= 1.0 - 1e-6  # and it is the largest such delta


def test_the_map_is_the_point_margin_and_zero_where_the_exact_chart_is_unstable():
    from delayform.analysis.ctcr import stability_map

    ax1, ax2 = np.array([0.25, 1.0, 2.0]), np.array([0.25, 2.0])
    m = jitter_margin_map(paper_six(), 1.0, 0.5, ax1, ax2)
    smap = stability_map(paper_six(), 1.0, 0.5, 3.0, 3.0)
    for i, a in enumerate(ax1):
        for j, b in enumerate(ax2):
            if smap.is_stable(a, b):  # stable by the exact chart: the point certificate (its own nominal root)
                assert m.delta[i, j] == jitter_margin(paper_six(), 1.0, 0.5, a, b).delta > 0
            else:
                assert m.delta[i, j] == 0.0


def test_contour_lines_lie_over_the_stable_region():
    from delayform.analysis.ctcr import stability_map

    g = (np.arange(8) + 0.5) * 3.0 / 8
    m = jitter_margin_map(paper_six(), 1.0, 0.5, g, g)
    levels = m.levels()
    assert levels.size >= 2 and 0 < levels[0] and levels[-1] <= m.delta.max()
    ax = m.plot()  # the margin's lines alone on the axes
    vertices = np.concatenate([p.vertices for c in ax.collections for p in c.get_paths() if len(p.vertices)])
    assert len(vertices) > 10
    # every point of every line is stable by the exact chart: no line strays over the unstable region
    smap = stability_map(paper_six(), 1.0, 0.5, 3.0, 3.0)
    assert np.all(smap.is_stable(vertices[:, 0], vertices[:, 1]))
    assert m.plot(ax=smap.plot()).get_xlabel() == "tau1 (s)"


def test_filled_plot_and_a_map_with_nothing_certified():
    m = jitter_margin_map(paper_six(), 1.0, 0.5, [1.0, 1.1], [2.0, 2.1])  # around the unstable point c
    assert not m.delta.any() and m.levels().size == 0
    ax = m.plot()
    assert any("0 everywhere" in t.get_text() for t in ax.texts)
    g = [0.2, 0.4, 0.6]
    ax = jitter_margin_map(paper_six(), 1.0, 0.5, g, g).plot(filled=True)
    assert len(ax.figure.axes) == 2  # the colour bar


def test_a_map_beyond_the_time_budget_is_refused_before_any_work(monkeypatch):
    from delayform.errors import ResourceLimitError

    monkeypatch.setenv("DELAYFORM_TIME_BUDGET", "1")
    with pytest.raises(ResourceLimitError, match="jitter-margin map"):
        jitter_margin_map(paper_six(), 1.0, 0.5, np.linspace(0.1, 3, 100), np.linspace(0.1, 3, 100))
