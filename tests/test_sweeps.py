"""Monte Carlo and sweeps: seeds make runs reproducible in any order and on any executor; guards; cluster errors."""

from __future__ import annotations

import random

import numpy as np
import pytest

from delayform.analysis.roots.dominant import dominant_root
from delayform.errors import ClusterError, ResourceLimitError, SimulationInputError
from delayform.simulation.experiments.montecarlo import (
    collect,
    monte_carlo,
    run_seeds,
    simulate_run,
)
from delayform.model.network import BernoulliLoss, Jitter, Network
from delayform.simulation.experiments.sweeps import delay_sweep, executor_for, make_setup, network_sweep, sweep
from delayform.topology import paper_six, ring

NET = Network(loss=BernoulliLoss(0.3), jitter=Jitter(0.1, 0.05))
TINY = dict(network=NET, seed=5, duration=3.0, dt=0.05)


def _same(a, b) -> None:
    for name in ("errors", "settling_times", "final_errors", "initial_errors", "peak_commands", "times"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_forty_runs_serially_and_on_a_two_worker_dask_cluster_are_identical() -> None:
    serial = monte_carlo(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", runs=40, **TINY)
    setup = make_setup(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", network=NET, duration=3.0, dt=0.05)
    nets = [None, NET]
    sweep_serial = network_sweep(setup, nets, ["ideal", "lossy"], runs=4, seed=2)
    seen: list[tuple[int, int]] = []
    with executor_for(workers=2) as ex:
        assert ex.workers == 2
        parallel = monte_carlo(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", runs=40, executor=ex,
                               progress=lambda done, total: seen.append((done, total)), **TINY)  # fmt: skip
        # the same cluster reached by its address: the "existing cluster" path
        address = ex.client.scheduler.address
        sweep_remote = network_sweep(setup, nets, ["ideal", "lossy"], runs=4, seed=2, scheduler=address)
    _same(serial, parallel)
    assert seen[-1] == (40, 40) and len(seen) == 40
    for a, b in zip(sweep_serial.results, sweep_remote.results, strict=True):
        _same(a, b)
    assert np.unique(serial.final_errors).size == 40  # the runs do differ from each other


def test_results_do_not_depend_on_the_order_runs_finish() -> None:
    setup = make_setup(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", network=NET, duration=3.0, dt=0.05)
    outcomes = [simulate_run((setup, r, s)) for r, s in enumerate(run_seeds(9, 6))]
    shuffled = outcomes[:]
    random.Random(1).shuffle(shuffled)
    _same(collect(setup, 6, 9, outcomes), collect(setup, 6, 9, shuffled))
    # run r's seeds do not depend on how many runs there are
    assert run_seeds(9, 6) == run_seeds(9, 10)[:6]
    assert len(set(run_seeds(9, 100))) == 100


def test_a_sweep_of_the_ideal_network_agrees_with_the_dominant_root() -> None:
    """Points a, b (stable) and c (unstable) of the paper: Monte Carlo settles exactly where Re s < 0."""
    setup = make_setup(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", duration=100.0, dt=0.05)
    points = [(0.3, 0.2), (2.0, 1.0), (1.0, 2.0)]
    result = sweep(setup, [{"tau1": a, "tau2": b} for a, b in points], values=points, runs=2, seed=1)
    for (t1, t2), r in zip(result.values, result.results, strict=True):
        stable = dominant_root(paper_six(), 1.0, 0.5, t1, t2).is_stable
        assert (r.settled_fraction == 1.0) == stable, (t1, t2)
        assert (r.final_errors < r.initial_errors).all() == stable
        assert set(r.statuses) == ({"settled"} if stable else {"diverging"})


def test_delay_sweep_grid_and_labels() -> None:
    setup = make_setup(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", duration=2.0, dt=0.05)
    result = delay_sweep(setup, [0.3, 1.0], [0.2, 2.0], runs=1, seed=1, progress=True)  # a Rich bar on stderr
    assert [label for label, _ in result.table()] == ["(0.3, 0.2)", "(0.3, 2)", "(1, 0.2)", "(1, 2)"]
    assert result.summary()["points"][3]["value"] == (1.0, 2.0)
    assert [r.setup.tau2 for r in result.results] == [0.2, 2.0, 0.2, 2.0]


def test_bad_cluster_settings_and_budgets_are_refused() -> None:
    with pytest.raises(ClusterError, match="not both"):
        with executor_for(workers=2, scheduler="tcp://127.0.0.1:1"):
            pass
    with pytest.raises(ClusterError, match="positive integer"):
        with executor_for(workers=0):
            pass
    with pytest.raises(ClusterError, match="cannot reach"):
        with executor_for(scheduler="tcp://127.0.0.1:1", timeout=1.0):
            pass
    with pytest.raises(ResourceLimitError, match="would take about"):
        monte_carlo(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", runs=10_000, duration=1e4, dt=0.01)
    with pytest.raises(SimulationInputError, match="runs must be"):
        monte_carlo(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", runs=0, duration=1.0, dt=0.05)


def test_monte_carlo_result_figures_and_table() -> None:
    mc = monte_carlo(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", runs=6, model="unicycle", **TINY)
    assert mc.command_names == ("|dv/dt|", "|omega|")
    ax = mc.plot()
    assert ax.get_yscale() == "log"
    assert len(mc.plot_histograms()) == 4
    rows = dict(mc.table())
    assert set(rows) >= {"settling time: median [5 %, 95 %]", "final formation error", "peak |omega|"}
    q = mc.quantiles((0.1, 0.9))
    assert np.all(q[0] <= q[1])


def test_gain_and_topology_sweeps_change_what_they_say() -> None:
    from delayform.simulation.experiments.sweeps import gain_sweep, topology_sweep

    setup = make_setup(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", duration=2.0, dt=0.05)
    gains = gain_sweep(setup, [0.5, 1.0], [0.5], runs=1, seed=1)
    assert [(r.setup.P, r.setup.D) for r in gains.results] == [(0.5, 0.5), (1.0, 0.5)]
    assert gains.labels == ("P=0.5, D=0.5", "P=1, D=0.5")
    teams = topology_sweep(setup, [ring(3), ring(5)], shape="polygon", runs=1, seed=1)
    assert [r.setup.topology.n for r in teams.results] == [3, 5]
    assert [r.errors.shape[0] for r in teams.results] == [1, 1]
    with pytest.raises(SimulationInputError, match="unknown sweep field"):
        sweep(setup, [{"colour": 1}], runs=1)
