"""Guaranteed beside observed (issue 20, part 5): a run that diverges where a certificate holds is a bug.

The pipeline is driven end to end with a planted certificate that claims
stability at the paper's unstable point c: the Monte Carlo section must put the
BUG first, the report's highlights must carry it, and `delayform montecarlo` must
print it on stderr and exit 1. With the real certificates, bursty loss on a small
team that is certified mean-square stable gives no diverging run, and saturating
robots are covered by no certificate.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from delayform.formation import named_formation
from delayform.report import guarantees as G
from delayform.report import montecarlo_section
from delayform.report.page import highlights
from delayform.scenario import paper_scenario
from delayform.simulation import IROBOT_CREATE
from delayform.simulation.experiments.montecarlo import monte_carlo
from delayform.model.network import GilbertElliott, Jitter, Network, Sampling
from delayform.topology import ring

PLANTED = (G.Guarantee("planted certificate", True, "claims stability at point c"),)


def _at_c():
    sc = paper_scenario()
    return replace(sc, tau1=1.0, tau2=2.0, network=Network(jitter=Jitter(0.05, 0.05), seed=1),
                   simulation=replace(sc.simulation, model="double_integrator", duration=90.0, dt=0.05))  # fmt: skip


def test_a_run_violating_a_holding_certificate_is_a_loud_bug(tmp_path, monkeypatch):
    monkeypatch.setattr(G, "_guarantees", lambda *args: PLANTED)
    section = montecarlo_section(_at_c(), tmp_path, runs=2)
    bugs = section.summary["contradictions"]
    assert len(bugs) == 2 and all("planted certificate" in b for b in bugs)
    assert section.table[0][0] == "BUG" and "BUG" in section.text
    rows = dict(highlights([section]))
    assert "planted certificate" in rows["BUG: a run diverged where a certificate holds"]
    assert rows["observed"] == "2 of 2 runs diverged"


def test_the_real_certificate_at_c_proves_instability_and_claims_nothing(tmp_path):
    section = montecarlo_section(_at_c(), tmp_path, runs=2)
    assert section.summary["contradictions"] == []
    held = [g for g in section.summary["guarantees"] if g["holds"] is True]
    assert held == [] and section.summary["guarantees"][0]["holds"] is False
    assert dict(highlights([section]))["guaranteed for this network"].startswith("nothing")


def test_the_montecarlo_command_exits_1_and_says_bug(tmp_path, monkeypatch, capsys):
    from delayform.cli import main

    monkeypatch.setattr(G, "_guarantees", lambda *args: PLANTED)
    with pytest.raises(SystemExit) as info:
        main(["montecarlo", "--tau1", "1", "--tau2", "2", "--jitter", "0.05,0.05", "--runs", "2", "--duration", "90",
              "--dt", "0.05", "--model", "double_integrator", "--out", str(tmp_path / "o")])  # fmt: skip
    err = capsys.readouterr().err
    assert info.value.code == 1 and err.count("delayform: BUG: run") == 2, err
    assert (tmp_path / "o" / "montecarlo_runs.csv").exists()  # the evidence is kept


def test_stopped_runs_count_as_diverged():
    assert len(G.contradictions(PLANTED, ("settled", "stopped"))) == 1


def test_bursty_loss_certified_on_a_small_team_never_diverges():
    team, shape = ring(3), named_formation("polygon", 3, spacing=2.0)
    net = Network(sampling=Sampling(10.0), loss=GilbertElliott(0.1, 0.3), seed=4)
    gs = G.network_guarantees(team, 1.0, 1.0, 0.2, 0.1, net)
    bursty = [g for g in gs if "bursty" in g.name]
    assert bursty and bursty[0].holds is True, gs
    mc = monte_carlo(team, 1.0, 1.0, 0.2, 0.1, shape, model="double_integrator", network=net, runs=6, seed=5,
                     duration=30.0, dt=0.02)  # fmt: skip
    assert G.contradictions(gs, mc.statuses) == []
    assert "diverging" not in mc.statuses and "stopped" not in mc.statuses


def test_bursty_loss_on_a_large_team_is_not_covered_and_says_why():
    sc = paper_scenario()
    gs = G.network_guarantees(sc.topology, 1.0, 0.5, 0.3, 0.2, Network(sampling=Sampling(10.0), loss=GilbertElliott(0.1, 0.3)))
    ms = [g for g in gs if "mean square" in g.name]
    assert ms and ms[0].holds is None and "2^26" in ms[0].detail


def test_saturating_robots_are_covered_by_no_certificate(tmp_path):
    sc = replace(paper_scenario(), robot=IROBOT_CREATE, network=Network(jitter=Jitter(0.05, 0.05), seed=1),
                 simulation=replace(paper_scenario().simulation, duration=5.0))  # fmt: skip
    section = montecarlo_section(sc, tmp_path, runs=1)
    assert section.summary["guarantees"] and all(g["holds"] is not True for g in section.summary["guarantees"])
    assert any("actuator limits" in g["detail"] for g in section.summary["guarantees"])
    assert np.isfinite(section.summary["settled_fraction"])


# ---------------------------------------------------------------- which certificate covers which network
def _names(gs):
    return {g.name: g.holds for g in gs}


def test_per_link_spread_is_covered_by_the_box_certificate_and_its_runs_settle():
    from delayform.model.network import LinkDelays
    from delayform.topology import paper_six

    net = Network(delays=LinkDelays(spread=0.2), seed=6)
    gs = G.network_guarantees(paper_six(), 1.0, 0.5, 0.3, 0.2, net, dt=0.02)
    held = _names(gs)
    assert held["per-link delays in a box (certified)"] is True
    assert held["constant delays (exact, per link)"] is None  # the runs' delays are not the nominal ones
    mc = monte_carlo(paper_six(), 1.0, 0.5, 0.3, 0.2, named_formation("hexagon", 6, spacing=2.0),
                     model="double_integrator", network=net, runs=4, seed=7, duration=40.0, dt=0.02)  # fmt: skip
    assert G.contradictions(gs, mc.statuses) == [] and set(mc.statuses) == {"settled"}


def test_the_jitter_margin_is_asked_for_the_whole_deviation():
    from delayform.analysis.network import jitter_margin
    from delayform.model.network import LinkDelays, SmoothVariation
    from delayform.topology import paper_six

    delta = jitter_margin(paper_six(), 1.0, 0.5, 0.305, 0.205).delta  # about tau + dt / 2
    inside, outside = 0.9 * delta - 0.01, 1.1 * delta
    holds = lambda net: _names(G.network_guarantees(paper_six(), 1.0, 0.5, 0.3, 0.2, net, dt=0.01))[  # noqa: E731
        "time-varying delays (jitter margin)"]
    assert holds(Network(jitter=Jitter(inside, inside))) is True
    assert holds(Network(jitter=Jitter(outside, outside))) is None
    # jitter and variation add up; a spread per-link delay is a constant deviation on top
    half = 0.55 * delta
    assert holds(Network(jitter=Jitter(half, half), variation=SmoothVariation(half, half, period=5.0))) is None
    assert holds(Network(jitter=Jitter(0.5 * inside, 0.5 * inside), delays=LinkDelays(spread=0.1))) is (
        0.5 * inside + 0.1 * 0.3 + 0.005 <= delta)
    # with loss a held value ages without bound: nothing time-varying is covered
    from delayform.model.network import BernoulliLoss

    assert holds(Network(jitter=Jitter(0.01, 0.01), loss=BernoulliLoss(0.1))) is None


def test_an_actuation_delay_leaves_every_certificate_not_covered(tmp_path):
    sc = replace(_at_c(), actuation_delay=0.05, simulation=replace(_at_c().simulation, duration=5.0))
    section = montecarlo_section(sc, tmp_path, runs=1)
    gs = section.summary["guarantees"]
    # at tau_a = 0 point c is proven unstable; with tau_a the proof does not carry over either
    assert gs and all(g["holds"] is None and "actuation delay 0.05 s" in g["detail"] for g in gs)
    assert G.with_actuation_delay(PLANTED, 0.0) == PLANTED
