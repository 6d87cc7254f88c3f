"""The certified jitter margin on the stability chart: `delayform chart --jitter-margin`, the report's chart.

Checks the drawn map against the point certificate (an independent call of
jitter_margin at a grid point, with its own nominal root), and that every refusal
(time budget, actuation delay) is one line, exit 2, before any file is written.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from delayform.analysis.network import jitter_margin
from delayform.cli import main
from delayform.topology import paper_six
from test_cli import assert_one_line_error, run


def test_chart_with_the_jitter_margin(tmp_path):
    proc = run("chart", "--tau1-max", "2", "--tau2-max", "2", "--jitter-margin", "--jitter-grid", "4",
               "--out", str(tmp_path / "o"), "--json", cwd=tmp_path)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)["jitter_margin"]
    with np.load(tmp_path / "o" / "jitter_margin_map.npz") as npz:
        data = dict(npz)
    assert np.allclose(data["tau1"], [0.25, 0.75, 1.25, 1.75])  # cell centres, the axes left out
    i, j = np.unravel_index(int(np.argmax(data["delta"])), data["delta"].shape)
    assert summary["largest_delta"] == pytest.approx(data["delta"][i, j])
    point = jitter_margin(paper_six(), 1.0, 0.5, float(data["tau1"][i]), float(data["tau2"][j])).delta
    assert summary["largest_delta"] == pytest.approx(point, rel=1e-12)
    assert (tmp_path / "o" / "stability_chart.png").stat().st_size > 1000


def test_the_chart_without_the_flag_draws_no_margin(tmp_path):
    proc = run("chart", "--tau1-max", "2", "--tau2-max", "2", "--out", str(tmp_path / "o"), "--json", cwd=tmp_path)
    assert proc.returncode == 0 and "jitter_margin" not in json.loads(proc.stdout)
    assert not (tmp_path / "o" / "jitter_margin_map.npz").exists()


def test_refused_before_anything_is_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("DELAYFORM_TIME_BUDGET", "2")
    for args in (["chart", "--jitter-margin", "--jitter-grid", "50"], ["report", "--jitter-grid", "50"]):
        with pytest.raises(SystemExit) as info:
            main([*args, "--out", str(tmp_path / "o")])
        err = capsys.readouterr().err.strip().splitlines()
        assert info.value.code == 2 and len(err) == 1 and "jitter-margin map" in err[0] and "--jitter-grid" in err[0]
        assert not (tmp_path / "o").exists()


def test_refused_with_an_actuation_delay(tmp_path):
    proc = run("chart", "--jitter-margin", "--actuation-delay", "0.05", "--out", str(tmp_path / "o"), cwd=tmp_path)
    assert_one_line_error(proc, "tau_a = 0")
    assert not (tmp_path / "o").exists()


def test_the_report_draws_it_when_the_network_jitters():
    from delayform.report.jitter_overlay import DEFAULT_GRID, auto_grid
    from delayform.scenario import paper_scenario
    from delayform.model.network import BernoulliLoss, Jitter, Network

    sc = paper_scenario()
    assert auto_grid(sc) == 0
    from dataclasses import replace

    assert auto_grid(replace(sc, network=Network(jitter=Jitter(0.05, 0.05)))) == DEFAULT_GRID
    assert auto_grid(replace(sc, network=Network(loss=BernoulliLoss(0.2)))) == 0  # loss does not vary delays
    assert auto_grid(replace(sc, network=Network(jitter=Jitter(0.05, 0.05)), actuation_delay=0.05)) == 0


def test_the_report_does_not_draw_a_costly_overlay_unasked():
    from dataclasses import replace

    from delayform.report.jitter_overlay import auto_grid
    from delayform.scenario import parse_scenario
    from delayform.model.network import Jitter, Network

    big = parse_scenario({"topology": {"name": "complete", "n": 12}, "gains": {"P": 1, "D": 0.5},
                          "delays": {"tau1": 0.1, "tau2": 0.1}, "formation": {"shape": "polygon"}})  # fmt: skip
    assert auto_grid(replace(big, network=Network(jitter=Jitter(0.01, 0.01)))) == 0  # 132 links: minutes
