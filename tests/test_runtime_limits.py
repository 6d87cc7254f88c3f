"""Hardening (issue 24, items 4-5): network options, and limits that must agree across commands.

Each example of the issue is a test; each numerical claim is checked by an
independent route (a simulation against a root, Python's ``statistics``
against our quantiles, a hand count of links).
"""

from __future__ import annotations

import math
import re
import statistics
from dataclasses import replace

import numpy as np
import pytest

from delayform.analysis.ctcr.stability_map import stability_map
from delayform.analysis.roots.dominant import dominant_root, dominant_root_map
from delayform.analysis.roots.single import count_roots_right_of, delay_reach
from delayform.app import Explorer
from delayform.characteristic import factors
from delayform.errors import InputError, NetworkError, SimulationInputError
from delayform.scenario import paper_scenario
from delayform.simulation import simulate
from delayform.simulation.experiments.montecarlo import make_setup, monte_carlo, run_quantile
from delayform.model.network import BernoulliLoss, GilbertElliott, Jitter, Network, SmoothVariation
from delayform.simulation.delayed.reception import _loss_mask
from delayform.topology import paper_six, ring
from test_runtime import cli, one_line


def run(network: Network, tau: tuple[float, float] = (0.3, 0.2), n: int = 3, dt: float = 0.05):
    topo = ring(n) if n != 6 else paper_six()
    return simulate(topo, 1.0, 0.5, *tau, "polygon", model="double_integrator", duration=2.0, dt=dt, network=network)


# ----------------------------------------------------------------- item 4: network options
def test_zero_delay_with_loss_states_the_rule_without_a_jitter_that_was_never_set() -> None:
    with pytest.raises(NetworkError) as info:
        run(Network(loss=BernoulliLoss(0.3)), tau=(0.3, 0.0))
    text = str(info.value)
    assert "tau2 = 0 s is below the step dt = 0.05 s" in text and "every delay must be >= dt" in text
    assert "jitter" not in text and "variation" not in text and "smaller dt" not in text


def test_jitter_and_variation_are_named_only_when_set() -> None:
    with pytest.raises(NetworkError) as info:
        run(Network(jitter=Jitter(0.28, 0.0)))
    text = str(info.value)
    assert "tau1 0.3 s - jitter 0.28 s = 0.02 s" in text
    assert "every delay minus its jitter must be >= dt" in text and "variation" not in text
    with pytest.raises(NetworkError) as info:
        run(Network(variation=SmoothVariation(0.28, 0.0, period=10.0)))
    assert "minus its variation must be >= dt" in str(info.value) and "jitter" not in str(info.value)


def test_cli_montecarlo_tau2_zero_with_loss_and_the_rule_in_its_help(capsys: pytest.CaptureFixture[str], tmp_path) -> None:
    code, out, err = cli(capsys, "montecarlo", "--runs", "2", "--tau2", "0", "--loss", "0.3", "--out", str(tmp_path / "o"))
    line = one_line(err)
    assert code == 2 and out == "" and "tau2 = 0 s" in line and "jitter" not in line
    assert not (tmp_path / "o").exists()
    code, out, _ = cli(capsys, "montecarlo", "--help")
    assert code == 0 and "every delay minus its jitter must be >= --dt" in " ".join(out.split())


def test_gilbert_elliott_that_never_leaves_the_bad_state_is_bernoulli_loss_bad() -> None:
    """p_bad_to_good = 0 is accepted like Bernoulli loss 1: the bad state absorbs, from the first packet."""
    ge = GilbertElliott(0.2, 0.0, loss_good=0.0, loss_bad=0.3)
    assert ge.bad_fraction == 1.0 and ge.loss_rate == pytest.approx(0.3)
    rows = cols = np.arange(40)
    lost = _loss_mask(ge, rows, cols, 2000, np.random.default_rng(1))
    # 80 000 independent Bernoulli(0.3) draws: the mean is within 5 standard errors of 0.3
    assert abs(lost.mean() - 0.3) < 5 * math.sqrt(0.3 * 0.7 / lost.size)
    still = _loss_mask(GilbertElliott(0.0, 0.0, loss_good=0.1), rows, cols, 2000, np.random.default_rng(2))
    assert abs(still.mean() - 0.1) < 5 * math.sqrt(0.1 * 0.9 / still.size)
    assert "a burst never ends" in Network(loss=GilbertElliott(0.1, 0.0)).describe()


def test_every_packet_lost_is_the_same_run_whichever_loss_model_says_so() -> None:
    bursty = run(Network(loss=GilbertElliott(0.1, 0.0, loss_bad=1.0)))
    bernoulli = run(Network(loss=BernoulliLoss(1.0)))
    np.testing.assert_array_equal(bursty.positions, bernoulli.positions)


@pytest.mark.parametrize("size", [3, 7])
def test_a_loss_matrix_of_the_wrong_size_is_a_network_error(size: int) -> None:
    with pytest.raises(NetworkError, match=f"loss.probability must be 6 x 6 .* got {size} x {size}"):
        run(Network(loss=BernoulliLoss(np.full((size, size), 0.2))), n=6)


def test_the_mean_loss_counts_the_links_only() -> None:
    topo = ring(3)  # 3 links of 6 off-diagonal pairs
    links = np.asarray(topo.adjacency) != 0
    p = np.where(links, 0.2, 1.0)
    np.fill_diagonal(p, 1.0)
    loss = BernoulliLoss(p)
    assert loss.link_loss_rate(topo.adjacency) == pytest.approx(0.2)
    assert loss.loss_rate == pytest.approx((3 * 0.2 + 3 * 1.0) / 6)  # every possible link, the diagonal never
    setup = make_setup(topo, 1.0, 0.5, 0.3, 0.2, "polygon", network=Network(loss=loss), duration=1.0, dt=0.05)
    assert setup.describe()["network"] == "loss 0.2 (mean over the links)"


@pytest.fixture(scope="module")
def explorer(tmp_path_factory: pytest.TempPathFactory) -> Explorer:
    return Explorer(paper_scenario(), out_dir=tmp_path_factory.mktemp("explorer"))


def test_explorer_refuses_loss_with_the_network_off_instead_of_ignoring_it(explorer: Explorer) -> None:
    with pytest.raises(InputError, match=r"network=0.*add network=1"):
        explorer.animation(1.0, 0.5, 0.3, 0.2, 5.0, 10, network=False, loss=0.3)
    with pytest.raises(InputError, match=r"network=0"):  # the downloads alike
        explorer.scenario_file(1.0, 0.5, 0.3, 0.2, 5.0, 8.0, 8.0, limits=False, network=False, loss=0.0, jitter=0.07)
    lossy = explorer.animation(1.0, 0.5, 0.3, 0.2, 5.0, 10, network=True, loss=0.3, jitter=0.0)
    assert lossy.as_json()["network"] == "loss 0.3"
    assert explorer.animation(1.0, 0.5, 0.3, 0.2, 5.0, 10).as_json()["network"] is None


def test_explorer_diverged_at_is_the_time_its_message_names(explorer: Explorer) -> None:
    """Point c of Fig. stability (unstable): the run stops at 1e8 times its size; diverged_at says when."""
    body = explorer.animation(1.0, 0.5, 1.0, 2.0, 290.0, 20).as_json()
    assert body["status"] == "stopped"
    said = float(re.search(r"at t = ([0-9.]+) s", body["warnings"][0]).group(1))
    assert body["diverged_at"] is not None and body["diverged_at"] == pytest.approx(said, abs=0.05)
    assert body["times"][-1] <= body["diverged_at"]


# ----------------------------------------------------------------- item 5: limits that agree
def test_map_chart_and_roots_agree_on_the_tau1_zero_row() -> None:
    """The same grid: the dominant-root map's stable cells are the CTCR chart's, the tau1 = 0 row included."""
    from delayform.report.analysis import map_section

    t1 = t2 = np.linspace(0.0, 2.0, 5)
    chart = stability_map(paper_six(), 1.0, 0.5, 2.0, 2.0).is_stable(t1[:, None], t2[None, :])
    dmap = dominant_root_map(paper_six(), 1.0, 0.5, t1, t2)
    np.testing.assert_array_equal(dmap.stable, chart)
    assert chart[0].all() and dominant_root(paper_six(), 1.0, 0.5, 0.0, 0.2).is_stable
    sc = paper_scenario()
    sc = replace(sc, map=replace(sc.map, tau1=(0.0, 2.0), tau2=(0.0, 2.0), size=(5, 5)))
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as folder:
        summary = map_section(sc, Path(folder)).summary
    assert summary["stable_fraction"] == pytest.approx(float(chart.mean()))


def test_the_tau1_zero_row_is_stable_in_the_time_domain_at_the_formation_root_rate() -> None:
    """Independent of both: simulate at (0, 0.2); the shape error decays at Re of the formation root."""
    root = dominant_root(paper_six(), 1.0, 0.5, 0.0, 0.2).formation_root
    tr = simulate(paper_six(), 1.0, 0.5, 0.0, 0.2, "hexagon", model="double_integrator", duration=50.0, dt=0.01, seed=3)
    assert tr.status == "settled"
    window = (tr.times > 20.0) & (tr.times < 50.0)
    rate = np.polyfit(tr.times[window], np.log(tr.formation_error[window]), 1)[0]
    assert rate == pytest.approx(root.real, rel=0.1)


def test_quantiles_are_the_ordinary_ones_of_python_statistics() -> None:
    rng = np.random.default_rng(4)
    for n in (2, 3, 10, 41):
        v = rng.exponential(size=n)
        assert float(run_quantile(v, 0.5)) == pytest.approx(statistics.median(v.tolist()), rel=1e-14)
        cuts = statistics.quantiles(v.tolist(), n=20, method="inclusive")  # 5 %, 10 %, ..., 95 %
        np.testing.assert_allclose(run_quantile(v, np.arange(1, 20) / 20), cuts, rtol=1e-12)
    assert float(run_quantile([10.0, math.inf], 0.5)) == math.inf == statistics.median([10.0, math.inf])
    assert float(run_quantile([1.0, 2.0, 3.0, math.inf], 0.5)) == 2.5
    with pytest.raises(SimulationInputError):
        run_quantile([], 0.5)


def test_the_monte_carlo_median_of_two_runs_is_their_mean() -> None:
    result = monte_carlo(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", network=Network(loss=BernoulliLoss(0.3)),
                         runs=2, seed=5, duration=30.0, dt=0.05)  # fmt: skip
    final = result.final_errors
    assert final[0] != final[1]
    assert result.summary()["final_error"]["median"] == pytest.approx(statistics.median(final.tolist()), rel=1e-14)


def test_the_explorer_table_says_what_the_root_finder_accepts() -> None:
    """P = 20, D = 0.01 (the issue's example): the table said 4.74 s where the finder stopped near 2 s.

    The finder's fixed reach is gone (issue 19); its only limit is the machine's budget, which
    delay_reach reports, so the table now allows the chart's 4.74 s and the point report answers there.
    """
    explorer = Explorer(paper_scenario(), out_dir="unused-out")
    limits = explorer.delay_limits(20.0, 0.01)
    reach = delay_reach(tuple(factors(paper_six(), 20.0, 0.01)))
    assert limits["roots"] == limits["chart"] == pytest.approx(4.7397, rel=1e-4)
    assert limits["chart"] < reach
    # past the discretization's reach the point finder answers on the root chains, certified by
    # the argument-principle count: no root of any factor right of the answer
    past = dominant_root(paper_six(), 20.0, 0.01, 1.01 * reach, 1.01 * reach)
    assert all(count_roots_right_of(f, 1.01 * reach, 1.01 * reach, past.root.real + 1e-9) == 0
               for f in factors(paper_six(), 20.0, 0.01))  # fmt: skip
    tau = 0.99 * limits["roots"]
    report = explorer.point(20.0, 0.01, tau, tau)
    assert np.isclose(report.dominant.root, dominant_root(paper_six(), 20.0, 0.01, tau, tau).root)
    assert explorer.delay_limits(1.0, 0.5)["roots"] == explorer.delay_limits(1.0, 0.5)["chart"]
