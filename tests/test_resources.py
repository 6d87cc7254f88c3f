"""The budget guard refuses oversized jobs up front, in one line."""

from __future__ import annotations

import pytest

from delayform.errors import InputError, ResourceLimitError
from delayform.resources import format_bytes, format_seconds, memory_limit, require, time_budget


def test_small_job_passes() -> None:
    require(what="a small job", setting="nothing", nbytes=1e6, seconds=1.0)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"nbytes": 1e15}, "of memory"),
        ({"nbytes": float("nan")}, "of memory"),
        ({"seconds": 1e9}, "time budget"),
        ({"seconds": float("inf")}, "time budget"),
    ],
)
def test_large_job_refused_in_one_line(kwargs: dict[str, float], needle: str) -> None:
    with pytest.raises(ResourceLimitError) as info:
        require(what="a huge job", setting="the size (--size)", **kwargs)
    message = str(info.value)
    assert isinstance(info.value, InputError)
    assert "\n" not in message and needle in message and "--size" in message


def test_memory_limit_is_a_share_of_physical_memory() -> None:
    import os

    physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    assert 0 < memory_limit() < physical


def test_environment_overrides(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DELAYFORM_MEMORY_LIMIT", "2G")
    monkeypatch.setenv("DELAYFORM_TIME_BUDGET", "10")
    assert memory_limit() == 2 * 2**30 and time_budget() == 10.0
    with pytest.raises(ResourceLimitError, match="2 GiB"):
        require(what="job", setting="x", nbytes=3 * 2**30)
    monkeypatch.setenv("DELAYFORM_TIME_BUDGET", "soon")
    with pytest.raises(ResourceLimitError, match="DELAYFORM_TIME_BUDGET"):
        time_budget()


@pytest.mark.parametrize(
    ("value", "text"), [(512 * 2**20, "512 MiB"), (3 * 2**30, "3 GiB"), (100, "100 bytes")]
)
def test_format_bytes(value: float, text: str) -> None:
    assert format_bytes(value) == text


@pytest.mark.parametrize(("value", "text"), [(40, "40 s"), (720, "12 min"), (3 * 86400, "3 days")])
def test_format_seconds(value: float, text: str) -> None:
    assert format_seconds(value) == text


# ============================================== every size a user gives is budgeted before the work
from collections.abc import Callable  # noqa: E402
from contextlib import AbstractContextManager  # noqa: E402

import numpy as np  # noqa: E402

from cli_runner import time_limit  # noqa: E402
from delayform.resources import sized_by  # noqa: E402

#: a refusal comes before any work: well under this many seconds (the alarm stops a job that started)
REFUSED_WITHIN = 5


def alarm(seconds: int = REFUSED_WITHIN) -> AbstractContextManager[None]:
    """Fail (instead of hanging or allocating for minutes) when the block runs longer than ``seconds``."""
    return time_limit(seconds, lambda: AssertionError(f"not refused within {seconds} s: the work started"))


def _refusal(job: Callable[[], object]) -> str:
    with alarm(), pytest.raises(ResourceLimitError) as info:
        job()
    message = str(info.value)
    assert "\n" not in message and "reduce" in message
    assert ("would need about" in message) or ("would take about" in message)
    return message


def _ring_of_a_billion() -> object:
    from delayform.topology import ring

    return ring(10**9)


def _grid_of_1e10() -> object:
    from delayform.topology import grid

    return grid(100_000, 100_000)


def _link_root_of_5000() -> object:
    from delayform.analysis.network import link_dominant_root
    from delayform.topology import ring

    return link_dominant_root(ring(5000), 1.0, 0.5, 0.3, 0.2)


def _box_to_100_s() -> object:
    from delayform.analysis.network import robust_stability
    from delayform.topology import paper_six

    return robust_stability(paper_six(), 1.0, 0.5, (0.0, 100.0), (0.0, 100.0))


def _per_link_team_of_1e5() -> object:
    from delayform.analysis.network import jitter_margin
    from delayform.topology import ring

    return jitter_margin(ring(100_000), 1.0, 0.5, 0.3, 0.2)


def _loss_at_a_megahertz() -> object:
    from delayform.analysis.network import mean_square_stability
    from delayform.topology import paper_six

    return mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=1e6, loss=0.1)


def _simulation_of_1e5() -> object:
    from delayform.simulation import simulate
    from delayform.topology import ring

    return simulate(ring(100_000), 1.0, 0.5, 0.3, 0.2, "polygon", duration=150.0, dt=0.01)


def _sweep_grid_of_1e10() -> object:
    from delayform.simulation.experiments.montecarlo import make_setup
    from delayform.simulation.experiments.sweeps import delay_sweep
    from delayform.topology import ring

    setup = make_setup(ring(3), 1.0, 0.5, 0.3, 0.2, "polygon", duration=2.0, dt=0.05)
    axis = np.linspace(0.1, 1.0, 100_000)
    return delay_sweep(setup, axis, axis, runs=1)


@pytest.mark.parametrize(
    ("job", "needle"),
    [
        (_ring_of_a_billion, "topology.n"),
        (_grid_of_1e10, "grid size"),
        (_link_root_of_5000, "would take about"),
        (_box_to_100_s, "delays"),
        (_per_link_team_of_1e5, "100,000 agents"),
        (_loss_at_a_megahertz, "rate"),
        (_simulation_of_1e5, "100,000 agents"),
        (_sweep_grid_of_1e10, "grid"),
    ],
    ids=["ring 1e9", "grid 1e5 x 1e5", "link root ring 5000", "box 0-100 s", "jitter ring 1e5",
         "loss rate 1e6", "simulate ring 1e5", "delay sweep 1e5 x 1e5"],
)
def test_library_refuses_before_the_work(job: Callable[[], object], needle: str) -> None:
    assert needle in _refusal(job)


def test_sized_by_names_the_inputs_that_set_the_size() -> None:
    with sized_by("the delays (--tau1, --tau2)"), pytest.raises(ResourceLimitError) as info:
        require(what="a chart", setting="the window (--tau1-max)", nbytes=1e30)
    assert "--tau1, --tau2" in str(info.value) and "--tau1-max" not in str(info.value)
    with pytest.raises(ResourceLimitError, match="--tau1-max"):  # outside the block: the job's own setting
        require(what="a chart", setting="the window (--tau1-max)", nbytes=1e30)


def test_scenario_file_team_is_budgeted_like_the_option(tmp_path: object) -> None:
    from pathlib import Path

    from delayform.scenario import load_scenario

    path = Path(str(tmp_path)) / "big.toml"
    path.write_text('[topology]\nname = "ring"\nn = 1000000000\n[gains]\nP = 1.0\nD = 0.5\n'
                    "[delays]\ntau1 = 0.3\ntau2 = 0.2\n")  # fmt: skip
    message = _refusal(lambda: load_scenario(path))
    assert "big.toml" in message and "topology.n" in message


# ------------------------------------------------------------ honest estimates: just under the limit runs
def test_per_link_root_runs_just_under_its_budget(monkeypatch: pytest.MonkeyPatch) -> None:
    """A 30-agent per-link root is estimated at about 0.1 s; with a budget of 2x that it is not refused."""
    from delayform.analysis.network import link_dominant_root, link_team
    from delayform.analysis.network.per_link import dominant_cost
    from delayform.topology import ring

    team = ring(30)
    _, seconds = dominant_cost(link_team(team, 1.0, 0.5, 0.3, 0.2))
    monkeypatch.setenv("DELAYFORM_TIME_BUDGET", repr(2 * seconds))
    root = link_dominant_root(team, 1.0, 0.5, 0.3, 0.2)
    assert root.count >= 1
    monkeypatch.setenv("DELAYFORM_TIME_BUDGET", repr(0.5 * seconds))
    with pytest.raises(ResourceLimitError):
        link_dominant_root(team, 1.0, 0.5, 0.3, 0.2)


def test_large_teams_below_the_limit_are_built(monkeypatch: pytest.MonkeyPatch) -> None:
    """10^5 agents are built (no refusal), and the limit falls where the estimate puts it."""
    from delayform.topology import _BYTES_PER_AGENT, _BYTES_PER_EDGE, ring, star

    assert ring(100_000).n == 100_000 and star(100_000).n == 100_000
    need = _BYTES_PER_AGENT * 100_000 + _BYTES_PER_EDGE * 100_000
    monkeypatch.setenv("DELAYFORM_MEMORY_LIMIT", str(int(1.01 * need)))
    assert ring(100_000).n == 100_000
    monkeypatch.setenv("DELAYFORM_MEMORY_LIMIT", str(int(0.99 * need)))
    with pytest.raises(ResourceLimitError, match="100000 agents"):
        ring(100_000)


def test_lifted_size_counts_the_states_the_model_has() -> None:
    """The budget's state count equals the size of the model actually built (independent: its matrix)."""
    from delayform.analysis.network import link_team
    from delayform.analysis.network.loss import _lags, _lift, lifted_size
    from delayform.topology import paper_six, ring

    for topo, tau1, tau2, h in ((paper_six(), 0.3, 0.2, 0.1), (ring(4), 0.5, 0.0, 0.05)):
        team = link_team(topo, 1.0, 0.5, tau1, tau2)
        m1, m2 = _lags("tau1", team.tau1, h), _lags("tau2", team.tau2, h)
        model = _lift(team, h, m1, m2, np.zeros(team.rows.size))
        assert lifted_size(team, m1, m2) == model.A.shape[0]


def test_moderate_loss_model_runs() -> None:
    from delayform.analysis.network import mean_square_stability
    from delayform.topology import paper_six

    r = mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=10.0, loss=0.1)
    assert 0.0 < r.rho < 1.0

