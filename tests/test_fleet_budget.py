"""A fleet the machine cannot run at its control period is refused before any process starts, in one line."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest

from delayform.errors import FleetError, ResourceLimitError
from delayform.fleet.budget import HEADROOM, check_machine, fleet_demand, speed_factor
from tests.cli_runner import run_in_process

ROOT = Path(__file__).resolve().parents[1]


def test_the_demand_grows_with_robots_links_and_rate() -> None:
    base = fleet_demand(6, 13, 0.01)
    assert fleet_demand(12, 13, 0.01) > base and fleet_demand(6, 30, 0.01) > base and fleet_demand(6, 13, 0.005) > base
    # halving the period doubles the per-tick part only; the polling part stays
    poll = fleet_demand(6, 13, math.inf)
    assert fleet_demand(6, 13, 0.005) - poll == pytest.approx(2.0 * (base - poll))
    assert fleet_demand(6, 13, 0.01, factor=2.0) == pytest.approx(2.0 * base)


def test_the_paper_s_six_fit_two_cores_and_forty_on_the_complete_graph_do_not() -> None:
    assert check_machine(6, 13, 0.01, cores=2, factor=1.0) < HEADROOM * 2
    with pytest.raises(FleetError, match=r"40 robot processes at a 15 ms control period .* this machine has 2") as info:
        check_machine(40, 40 * 39, 0.015, cores=2, factor=1.0)
    assert "\n" not in str(info.value)
    # the period the message suggests is accepted, a tenth less is not
    longest = float(str(info.value).split("at least ")[1].split(" ms")[0]) * 1e-3
    check_machine(40, 40 * 39, longest * 1.01, cores=2, factor=1.0)
    with pytest.raises(FleetError):
        check_machine(40, 40 * 39, longest * 0.9, cores=2, factor=1.0)


def test_a_team_whose_polling_alone_fills_the_cores_is_told_to_be_smaller() -> None:
    with pytest.raises(FleetError, match="fewer robots"):
        check_machine(60, 60, 10.0, cores=2, factor=1.0)


def test_the_memory_budget_refuses_too_many_processes(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DELAYFORM_MEMORY_LIMIT", "500M")
    with pytest.raises(ResourceLimitError, match="robot processes"):
        check_machine(6, 13, 0.01, cores=2, factor=1.0)


def test_the_machine_s_measured_speed_scales_the_demand(monkeypatch: pytest.MonkeyPatch) -> None:
    """A machine whose controller ticks take twice the reference's CPU is planned at twice the demand, within [0.25, 4]."""
    import delayform.fleet.budget as budget

    for ratio, factor in ((2.0, 2.0), (10.0, 4.0), (0.1, 0.25)):
        monkeypatch.setattr(budget, "_reference_ticks", lambda r=ratio: r * budget.REFERENCE_TICKS_SECONDS)
        assert speed_factor() == pytest.approx(factor)
        assert check_machine(6, 13, 0.04, cores=64) == pytest.approx(fleet_demand(6, 13, 0.04, factor=factor))


def test_the_command_refuses_a_period_this_machine_cannot_keep_in_one_line_before_any_process(tmp_path: Path) -> None:
    start = time.perf_counter()
    out = tmp_path / "out"
    out.mkdir()
    r = run_in_process("fleet", str(ROOT / "examples" / "paper.toml"), "--period", "0.0002", "--duration", "5",
                       "--out", str(out))  # fmt: skip
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "control period" in lines[0] and "this machine has" in lines[0], lines
    assert not any(out.iterdir())  # nothing written, no simulation run
    assert time.perf_counter() - start < 10.0
