"""Hardening of the newer features: per-link analysis, the on-robot controller, recordings, bodies, safety.

One test per class of bad input: a traceback or foreign exception where a
named delayform error is due, input accepted silently where it changes the
answer, messages that do not name what the user gave, and a safety margin
the formation cannot satisfy. CLI cases run in-process (``delayform.cli.main``)
and assert exit code 2 with one line on stderr.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from delayform.errors import (
    ControllerInputError,
    DelayError,
    InputError,
    QuasiPolynomialError,
    RecordingError,
    ResourceLimitError,
    SimulationInputError,
)
from delayform.topology import paper_six, ring
from test_hardening import cli, one_line_error


# ------------------------------------------------ tracebacks: finite input, overflowing work
@pytest.mark.parametrize("args", [
    ("box", "--tau1-box", "0,1e6", "--tau2-box", "0,1e6"),
    ("jitter", "--tau1", "1e6", "--tau2", "1e6"),
    ("links", "--tau1", "1e6"),
    ("links", "--tau1", "1000"),  # a root bound of 1e108: the shifts alone would not fit in memory
    ("links", "--tau1", "100"),  # finite, but 1e11 Arnoldi solves
])  # fmt: skip
def test_per_link_long_delays_refused_up_front(capsys: pytest.CaptureFixture[str], args: tuple[str, ...]) -> None:
    line = one_line_error(capsys, *args)
    # equal delays on every link: `jitter` finds the nominal root on the factors, whose finder refuses instead
    assert "delays up to" in line and "root finder" in line


def test_per_link_long_delays_library() -> None:
    from delayform.analysis.network import link_dominant_root

    with pytest.raises(DelayError, match="too long"):
        link_dominant_root(paper_six(), 1.0, 0.5, 1e6, 0.2)
    with pytest.raises(ResourceLimitError, match="Arnoldi"):
        link_dominant_root(paper_six(), 1.0, 0.5, 100.0, 0.2)


def test_constant_quasi_polynomial_has_no_roots() -> None:
    from delayform.analysis.roots.single import rightmost_root
    from delayform.characteristic import TwoDelayQuasiPolynomial
    from delayform.quasipolynomial import QuasiPolynomial

    with pytest.raises(QuasiPolynomialError, match="non-zero constant"):
        rightmost_root(QuasiPolynomial({(0,): [2.0]}), 1.0)
    with pytest.raises(QuasiPolynomialError, match="non-zero constant"):
        rightmost_root(TwoDelayQuasiPolynomial([2.0], []), 1.0, 1.0)


def test_too_big_refused_by_the_budget() -> None:
    from delayform.analysis.network.loss import mean_square_stability
    from delayform.topology import grid

    with pytest.raises(ResourceLimitError, match="mean-square"):
        mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=1e6, loss=0.1)
    with pytest.raises(ResourceLimitError, match="grid"):
        grid(100000, 100000)


def test_report_with_an_actuation_delay_highlights(tmp_path: Path) -> None:
    """The eigenvalue plane is not computed under an actuation delay: its highlight says so (was a KeyError)."""
    from dataclasses import replace

    from delayform.report.analysis import region_section
    from delayform.report.page import highlights
    from delayform.scenario import paper_scenario

    sc = replace(paper_scenario(), actuation_delay=0.1)
    rows = dict(highlights([region_section(sc, tmp_path)]))
    assert rows == {"eigenvalue plane": "not computed (see its section)"}


# ------------------------------------------------ the controller
def _controller(**kw: object) -> object:
    from delayform.deploy.controller import FormationController

    args = dict(robot=1, P=1.0, D=0.5, tau1=0.1, tau2=0.1, weights={2: 1.0})
    return FormationController(**{**args, **kw})  # type: ignore[arg-type]


@pytest.mark.parametrize("weights, text", [
    ({2: "abc"}, "finite positive number, got 'abc'"),
    ({2: 5.0}, "must sum to 1"),
    ({2: 0.5, 3: 0.25}, "got 0.75"),
])  # fmt: skip
def test_controller_weights(weights: dict[int, object], text: str) -> None:
    with pytest.raises(ControllerInputError, match=text):
        _controller(weights=weights)


def test_controller_never_emits_a_non_finite_command() -> None:
    from delayform.deploy.controller import NeighbourMessage

    ctrl = _controller()
    with pytest.raises(ControllerInputError, match="iterable"):
        ctrl.receive_all(5)  # type: ignore[attr-defined]
    ctrl.receive(NeighbourMessage(2, 0.0, 0.0, 1.0, 0.0, 0.0))  # type: ignore[attr-defined]
    # ideal robot: turn rate = (u across) / v, with v the smallest subnormal
    with pytest.raises(ControllerInputError, match="not finite.*give the robot limits"):
        ctrl.tick(0.0, 0.0, 0.0, 0.0, 5e-324)  # type: ignore[attr-defined]
    with pytest.raises(ControllerInputError, match="not finite"):
        ctrl.tick(0.0, 1e308, -1e308, 0.0, 0.1)  # type: ignore[attr-defined]
    cmd = ctrl.tick(0.0, 0.0, 0.0, 0.0, 0.1)  # type: ignore[attr-defined]
    # eq. protocol by hand: u = P (0 - 0, 1 - 0) + D (0 - 0.1, 0); turn = (u across) / v = 1 / 0.1
    assert math.isclose(cmd.ux, -0.05) and math.isclose(cmd.uy, 1.0) and math.isclose(cmd.turn_rate, 10.0)


# ------------------------------------------------ silently accepted delays and coefficients
@pytest.mark.parametrize("value, given", [
    (np.full((6, 6), 0.3 + 1e-3j), "complex numbers"),
    (np.ones((6, 6), bool), "booleans"),
    (True, "booleans"),
    ("0.3", "strings"),
])  # fmt: skip
def test_per_link_delays_real_only(value: object, given: str) -> None:
    from delayform.analysis.network.links import link_team

    with pytest.raises(DelayError, match=given):
        link_team(paper_six(), 1.0, 0.5, value, 0.2)  # type: ignore[arg-type]


def test_delay_files_real_only_and_no_conflict(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    np.save(tmp_path / "c.npy", np.full((6, 6), 0.3 + 1j))
    np.save(tmp_path / "b.npy", np.ones((6, 6), bool))
    np.savetxt(tmp_path / "r.csv", np.full((6, 6), 0.3), delimiter=",")
    assert "complex numbers" in one_line_error(capsys, "links", "--tau1-file", str(tmp_path / "c.npy"))
    assert "booleans" in one_line_error(capsys, "links", "--tau2-file", str(tmp_path / "b.npy"))
    line = one_line_error(capsys, "links", "--tau1-file", str(tmp_path / "r.csv"), "--tau1", "0.5")
    assert "--tau1 and --tau1-file" in line


def test_quasi_polynomial_coefficients_are_numbers() -> None:
    from delayform.quasipolynomial import QuasiPolynomial

    for bad in (["1", "2"], "12", [None, 1.0]):
        with pytest.raises(QuasiPolynomialError, match="sequence of numbers"):
            QuasiPolynomial({(0,): bad})


def test_counts_and_delays_in_range() -> None:
    from delayform.analysis.network.box import robust_stability
    from delayform.loops import DelayMargin

    with pytest.raises(InputError, match="samples must be at least 0, got -1"):
        robust_stability(paper_six(), 1.0, 0.5, (0.1, 0.2), (0.1, 0.2), samples=-1)
    margin = DelayMargin.__new__(DelayMargin)
    object.__setattr__(margin, "tau", 1.0)
    with pytest.raises(DelayError, match="non-negative"):
        margin.is_stable(-0.5)
    assert margin.is_stable(0.5) and not margin.is_stable(1.0)


def _run(T: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 1.0, T)
    x = np.zeros((T, 2, 2))
    x[:, 1, 0] = 1.0
    return t, x, np.zeros_like(x)


@pytest.mark.parametrize("change, text", [
    (lambda t, x, v: (t[::-1], x, v), "times must increase"),
    (lambda t, x, v: (np.zeros(3), x, v), "times must increase"),
    (lambda t, x, v: (t, x[:, :, :1], v), "positions must have shape"),
    (lambda t, x, v: (t, x, v[:2]), "velocities must have shape"),
    (lambda t, x, v: (t, x * np.nan, v), "positions must be finite"),
])  # fmt: skip
def test_closest_approach_checks_its_run(change: object, text: str) -> None:
    from delayform.simulation.bodies.approach import closest_approach

    with pytest.raises(SimulationInputError, match=text):
        closest_approach(*change(*_run()))  # type: ignore[operator]
    assert closest_approach(*_run()).min_distance == 1.0  # two robots 1 m apart, at rest


def test_assign_slots_checks_shapes() -> None:
    from delayform.simulation.bodies.assignment import assign_slots

    z = np.array([[0.0, 0.0], [4.0, 0.0]])
    with pytest.raises(SimulationInputError, match=r"x0 must have shape \(2, 2\), got \(1, 2\)"):
        assign_slots(ring(2), 1.0, 0.5, 0.3, 0.2, z, z[:1], np.zeros((2, 2)))
    with pytest.raises(SimulationInputError, match="v0 must be finite"):
        assign_slots(ring(2), 1.0, 0.5, 0.3, 0.2, z, z, np.full((2, 2), np.nan))


# ------------------------------------------------ messages
def test_overlapping_slots_named_distinct() -> None:
    from delayform.simulation.models.robots import Robot

    z = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 0.0], [9.0, 9.0]])
    for k in range(4):  # wherever the twins sit, the two named are the twins
        with pytest.raises(SimulationInputError) as info:
            Robot().check_slots(np.roll(z, k, axis=0))
        twins = sorted(((0 + k) % 4 + 1, (2 + k) % 4 + 1))
        assert f"slots {twins[0]} and {twins[1]} are 0 m apart" in str(info.value)


def test_jitter_margin_at_the_drift(capsys: pytest.CaptureFixture[str]) -> None:
    from delayform.analysis.network import jitter_margin

    m = jitter_margin(paper_six(), 1.0, 0.5, 0.0, 0.2)
    assert m.delta == 0.0 and m.nominal_stable and "double" in m.reason
    code, out, _ = cli(capsys, "jitter", "--tau1", "0")
    assert code == 0 and out.startswith("jitter margin delta = 0 s: tau1 = 0")


def test_mcap_paths(capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "afile").write_text("x")
    with pytest.raises(RecordingError, match="NUL"):
        from delayform.deploy.recording import check_mcap_path

        check_mcap_path("a\x00b.mcap")
    with pytest.raises(RecordingError, match="afile is a file, not a folder"):
        check_mcap_path(tmp_path / "afile" / "run.mcap")
    monkeypatch.chdir(tmp_path)
    line = one_line_error(capsys, "simulate", "--duration", "1", "--mcap", "afile/run.mcap")
    assert "afile is a file, not a folder" in line
    # the folder of --mcap is created as --out's is
    code, _, _ = cli(capsys, "simulate", "--duration", "0.5", "--out", "o1", "--mcap", "o1/run.mcap")
    assert code == 0 and (tmp_path / "o1" / "run.mcap").is_file()


def test_montecarlo_title_names_per_link_delays(tmp_path: Path) -> None:
    from dataclasses import replace

    from delayform.report.network import _delays_phrase
    from delayform.scenario import paper_scenario
    from delayform.model.network import LinkDelays, Network

    sc = paper_scenario()
    t1 = np.where(paper_six().adjacency != 0, 0.25, 9.0)  # 9 s off the links: ignored
    t1[0, np.flatnonzero(paper_six().adjacency[0])[0]] = 0.4
    net = Network(delays=LinkDelays(tau1=t1))
    assert _delays_phrase(sc, net) == "with per-link delays: tau1 from 0.25 to 0.4 s, tau2 = 0.2 s"
    assert _delays_phrase(sc, Network(delays=LinkDelays(spread=0.1))).endswith("tau2 = 0.2 s (1 +- 0.1)")
    assert _delays_phrase(replace(sc), None) == "at (tau1, tau2) = (0.3, 0.2) s"


# ------------------------------------------------ a safety filter that cannot be satisfied
def test_safety_margin_the_formation_cannot_satisfy() -> None:
    from delayform import simulate
    from delayform.simulation.bodies.safety import BarrierFilter

    with pytest.raises(SimulationInputError, match="safety margin"):
        simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", safety=BarrierFilter(margin=100.0), duration=1.0, dt=0.01)
