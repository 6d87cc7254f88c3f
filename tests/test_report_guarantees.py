"""What is guaranteed beside what the Monte Carlo observed (issue 20, part 5).

A run that diverges where a certificate holds is a bug: at the paper's point a,
jitter within the certified margin and sampled loss that is mean-square stable
must give no diverging run.
"""

from __future__ import annotations

import numpy as np

from delayform.formation import named_formation
from delayform.report.guarantees import Guarantee, contradictions, network_guarantees
from delayform.simulation.experiments.montecarlo import monte_carlo
from delayform.model.network import BernoulliLoss, Jitter, Network, Sampling
from delayform.topology import paper_six

SHAPE = named_formation("hexagon", 6, spacing=2.0)


def _runs(net, tau=(0.3, 0.2), runs=4):
    return monte_carlo(paper_six(), 1.0, 0.5, *tau, SHAPE, model="double_integrator", network=net, runs=runs, seed=3,
                       duration=40.0, dt=0.02)  # fmt: skip


def test_jitter_within_the_margin_never_diverges():
    net = Network(jitter=Jitter(0.08, 0.08), seed=1)  # with half the 0.02 s packet period: 0.09 s < delta
    gs = network_guarantees(paper_six(), 1.0, 0.5, 0.3, 0.2, net, dt=0.02)
    assert any(g.holds is True and "jitter" in g.name for g in gs)
    mc = _runs(net)
    assert contradictions(gs, mc.statuses) == []
    assert "diverging" not in mc.statuses


def test_sampled_loss_mean_square_stable_never_diverges():
    net = Network(loss=BernoulliLoss(0.4), sampling=Sampling(10.0), seed=2)
    gs = network_guarantees(paper_six(), 1.0, 0.5, 0.3, 0.2, net)
    ms = [g for g in gs if g.name.startswith("sampling")]
    assert ms and ms[0].holds is True
    mc = _runs(net)
    assert contradictions(gs, mc.statuses) == []


def test_point_c_is_proven_unstable_and_covers_nothing():
    gs = network_guarantees(paper_six(), 1.0, 0.5, 1.0, 2.0, Network(jitter=Jitter(0.05, 0.05)))
    assert gs[0].holds is False
    assert all(g.holds is not True for g in gs)


def test_a_diverging_run_under_a_holding_certificate_is_reported():
    gs = (Guarantee("jitter margin", True, "+-0.1 s"), Guarantee("constant", None, ""))
    bugs = contradictions(gs, ("settled", "diverging"))
    assert len(bugs) == 1 and "run 1" in bugs[0]
    assert contradictions(gs, ("settled", "not settled")) == []
    assert np.all([isinstance(b, str) for b in bugs])


def test_the_explorer_serves_the_certified_jitter_margin(tmp_path):
    import json
    import urllib.request

    from delayform.analysis.network import jitter_margin
    from delayform.app import Explorer, start
    from delayform.scenario import paper_scenario

    with start(Explorer(paper_scenario(), out_dir=tmp_path)) as running:
        with urllib.request.urlopen(f"{running.url}api/guarantee?tau1=0.3&tau2=0.2", timeout=60) as r:
            got = json.loads(r.read())
        with urllib.request.urlopen(f"{running.url}api/guarantee?tau1=1&tau2=2", timeout=60) as r:
            unstable = json.loads(r.read())
    assert abs(got["jitter_margin"] - jitter_margin(paper_six(), 1.0, 0.5, 0.3, 0.2).delta) < 1e-12
    assert unstable["jitter_margin"] == 0.0
