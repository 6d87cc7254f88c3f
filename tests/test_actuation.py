"""Actuation delay (issue 21, item 4): each robot applies u(t - tau_a).

The roots are checked against an independent method: the Chebyshev
discretization of the infinitesimal generator of the *full* 2N-state delayed
system (written in tests/test_general_roots.py, not the package's companion
realization), x' = v, v' = -P x(t - ta) - D v(t - ta) + P C x(t - t1 - ta) + D C v(t - t2 - ta),
its eigenvalues polished by Newton's method on det M(s).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_general_roots import _generator_roots, _newton_det

from delayform.analysis.roots.actuated import actuated_factor
from delayform.analysis.roots.dominant import dominant_root
from delayform.errors import DelayError
from delayform.topology import Topology, paper_six


def _full_system(top: Topology, P: float, D: float, t1: float, t2: float, ta: float):
    C = top.C_sparse.toarray()
    n = C.shape[0]
    Z, I = np.zeros((n, n)), np.eye(n)
    A0 = np.block([[Z, I], [Z, Z]])
    delayed = [
        (np.block([[Z, Z], [-P * I, -D * I]]), ta),
        (np.block([[Z, Z], [P * C, Z]]), t1 + ta),
        (np.block([[Z, Z], [Z, D * C]]), t2 + ta),
    ]
    return A0, delayed


def _reference_rightmost(top: Topology, P: float, D: float, t1: float, t2: float, ta: float) -> complex:
    """Rightmost root of the full delayed system but the persistent zero: discretized, then Newton on det."""
    A0, delayed = _full_system(top, P, D, t1, t2, ta)
    ev = _generator_roots(A0, delayed, 24)
    ev = ev[np.abs(ev) > 1e-6]
    cand = ev[np.argsort(-ev.real)[:8]]
    polished = np.array([_newton_det(A0, delayed, complex(z)) for z in cand])
    polished = polished[np.abs(polished) > 1e-6]
    best = polished[np.argmax(polished.real)]
    return complex(best.real, abs(best.imag))


@pytest.mark.parametrize(
    ("t1", "t2", "ta"),
    [(0.3, 0.2, 0.1), (0.3, 0.2, 0.5), (2.0, 1.0, 0.05), (1.0, 0.0, 0.3), (0.5, 1.5, 0.8)],
)
def test_dominant_root_matches_full_system_discretization(t1: float, t2: float, ta: float) -> None:
    top = paper_six()
    r = dominant_root(top, 1.0, 0.5, t1, t2, actuation_delay=ta)
    ref = _reference_rightmost(top, 1.0, 0.5, t1, t2, ta)
    assert abs(r.root - ref) <= 1e-8 * (1.0 + abs(ref))
    assert r.is_stable == (ref.real < 0.0)
    assert r.actuation_delay == ta


def test_zero_actuation_delay_is_todays_answer_exactly() -> None:
    top = paper_six()
    for t1, t2 in [(0.3, 0.2), (1.0, 2.0), (0.0, 0.7)]:
        assert dominant_root(top, 1.0, 0.5, t1, t2, actuation_delay=0.0) == dominant_root(top, 1.0, 0.5, t1, t2)


def test_actuation_delay_can_destabilise_a_stable_point() -> None:
    # point a of Fig. stability is stable without actuation delay; the discretization decides with it
    top = paper_six()
    assert dominant_root(top, 1.0, 0.5, 0.3, 0.2).is_stable
    r = dominant_root(top, 1.0, 0.5, 0.3, 0.2, actuation_delay=1.5)
    ref = _reference_rightmost(top, 1.0, 0.5, 0.3, 0.2, 1.5)
    assert ref.real > 0.0 and not r.is_stable
    assert abs(r.root - ref) <= 1e-8 * (1.0 + abs(ref))


def test_drift_line_keeps_its_double_zero() -> None:
    # on tau1 = 0 the centroid factor is s (s + D e^{-ta s}(1 - e^{-t2 s})): the drift is reported as 0
    r = dominant_root(paper_six(), 1.0, 0.5, 0.0, 0.4, actuation_delay=0.2)
    assert r.is_drift and r.beside_drift is not None
    ref = _reference_rightmost(paper_six(), 1.0, 0.5, 1e-9, 0.4, 0.2)  # just off the line: the same shape modes
    assert abs(r.formation_root - ref) <= 1e-6


def test_actuated_factor_is_the_determinant_factor() -> None:
    # det of the full system's characteristic matrix = prod over eigenvalues of the factors (eq. factorized)
    top = paper_six()
    P, D, t1, t2, ta = 1.0, 0.5, 0.4, 0.9, 0.3
    A0, delayed = _full_system(top, P, D, t1, t2, ta)
    lams = np.linalg.eigvals(top.C_sparse.toarray())
    for s in (0.3 + 0.7j, -0.2 + 2.0j):
        M = s * np.eye(A0.shape[0]) - A0 - sum(Ak * np.exp(-h * s) for Ak, h in delayed)
        prod = np.prod([complex(actuated_factor(P, D, lam).evaluate(s, t1, t2, ta)) for lam in lams])
        assert np.linalg.det(M) == pytest.approx(prod, rel=1e-10)


@pytest.mark.parametrize("bad", [-0.1, math.nan, math.inf])
def test_bad_actuation_delay_is_a_delay_error(bad: float) -> None:
    with pytest.raises(DelayError, match="actuation_delay"):
        dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2, actuation_delay=bad)


# ============================================================ simulation
from delayform.errors import SimulationInputError  # noqa: E402
from delayform.simulation import simulate  # noqa: E402
from delayform.simulation.models.robots import IROBOT_CREATE, Robot  # noqa: E402


def _envelope_rate(times: np.ndarray, error: np.ndarray, t0: float, t1: float) -> float:
    """Slope of log(error) through its local maxima in [t0, t1] (the dominant pair's envelope)."""
    sel = np.flatnonzero((times > t0) & (times < t1))
    e = error[sel]
    peaks = sel[1:-1][(e[1:-1] > e[:-2]) & (e[1:-1] >= e[2:])]
    return float(np.polyfit(times[peaks], np.log(error[peaks]), 1)[0])


@pytest.mark.parametrize("ta", [0.1, 0.3])
def test_double_integrator_decay_rate_is_the_dominant_root(ta: float) -> None:
    top = paper_six()
    run = simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", model="double_integrator", duration=60.0, dt=0.01,
                   actuation_delay=ta)  # fmt: skip
    root = dominant_root(top, 1.0, 0.5, 0.3, 0.2, actuation_delay=ta).formation_root
    rate = _envelope_rate(run.times, run.formation_error, 20.0, 58.0)
    assert rate == pytest.approx(root.real, abs=0.005)
    assert run.actuation_delay == ta and run.stated_order == 2
    if ta == 0.3:  # stable without actuation delay, unstable with it: the analysis says so first
        assert root.real > 0.0 and run.status != "settled"


def test_command_buffer_converges_at_second_order() -> None:
    # halving dt divides the difference to a fine reference run by about 4 (interpolated commands)
    top = paper_six()
    # every delay a whole number of steps (module doc of delayform.simulation.delayed.actuation)
    kw = dict(model="double_integrator", duration=6.0, actuation_delay=0.2)
    ref = simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", dt=0.003125, **kw).positions[-1]
    errs = [np.abs(simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", dt=dt, **kw).positions[-1] - ref).max()
            for dt in (0.05, 0.025)]  # fmt: skip
    assert 2.5 < errs[0] / errs[1] < 8.0


def test_limited_robots_apply_their_commands_late() -> None:
    top = paper_six()
    kw = dict(limits=IROBOT_CREATE, duration=40.0, dt=0.01)
    base = simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", **kw)
    late = simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", actuation_delay=0.05, **kw)
    # nothing moves before the first command arrives: the heading and speed stay at their start
    first = late.times <= 0.05 - 1e-9
    assert np.all(late.speeds[first] == late.speeds[0])
    assert not np.array_equal(base.positions, late.positions)
    assert late.status == "settled"
    same = simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", robot=Robot(limits=IROBOT_CREATE), duration=40.0, dt=0.01)
    np.testing.assert_array_equal(same.positions, base.positions)


@pytest.mark.parametrize("bad", [-0.1, math.nan, math.inf, "0.1"])
def test_bad_robot_actuation_delay(bad: object) -> None:
    with pytest.raises(DelayError, match="actuation_delay"):  # a delay: DelayError, as in dominant_root
        Robot(actuation_delay=bad)  # type: ignore[arg-type]


def test_actuation_delay_refusals() -> None:
    top = paper_six()
    with pytest.raises(SimulationInputError, match="ideal robots"):
        simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", duration=1.0, dt=0.01, actuation_delay=0.1)
    with pytest.raises(SimulationInputError, match="at least one step"):
        simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", model="double_integrator", duration=1.0, dt=0.01,
                 actuation_delay=0.001)  # fmt: skip
    with pytest.raises(SimulationInputError, match="not both"):
        simulate(top, 1.0, 0.5, 0.3, 0.2, "hexagon", robot=Robot(), duration=1.0, dt=0.01, actuation_delay=0.1)


# ============================================================ scenario and command line
from test_cli import assert_one_line_error, run  # noqa: E402

from delayform.errors import ScenarioError  # noqa: E402
from delayform.scenario import PAPER_TOML, parse_scenario  # noqa: E402


def _scenario_with_robot(table: str):
    import tomllib

    return parse_scenario(tomllib.loads(PAPER_TOML + "\n[robot]\n" + table), source="<test>", default_name="t")


def test_scenario_key_maps_onto_the_robot() -> None:
    sc = _scenario_with_robot("actuation_delay = 0.05\n")
    assert sc.actuation_delay == 0.05 and sc.robot_spec.actuation_delay == 0.05
    for bad in ("-0.1", "nan", "inf", '"x"'):
        with pytest.raises(ScenarioError, match="actuation_delay"):
            _scenario_with_robot(f"actuation_delay = {bad}\n")


@pytest.mark.slow
def test_cli_roots_and_simulate_take_the_actuation_delay(tmp_path) -> None:
    import json

    proc = run("roots", "--actuation-delay", "0.3", "--json", "--out", str(tmp_path / "r"), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    ref = dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2, actuation_delay=0.3).root
    assert summary["actuation_delay"] == 0.3 and summary["stable"] is False
    assert complex(summary["dominant_root"]["re"], summary["dominant_root"]["im"]) == pytest.approx(ref)
    for bad in ("-1", "nan"):
        proc = run("roots", "--actuation-delay", bad, "--out", str(tmp_path / "bad"), cwd=tmp_path)
        assert_one_line_error(proc, "--actuation-delay")
    proc = run("simulate", "--actuation-delay", "0.1", "--duration", "1", "--out", str(tmp_path / "s"), cwd=tmp_path)
    assert_one_line_error(proc, "actuation delay")
    assert not (tmp_path / "s").exists()


# ============================================================ the exact map at a given actuation delay
from delayform.analysis.ctcr.stability_map import stability_map  # noqa: E402
from delayform.analysis.roots.single import count_roots_right_of  # noqa: E402
from delayform.characteristic import factors  # noqa: E402
from delayform.topology import ring  # noqa: E402


def _certified_nu(top: Topology, P: float, D: float, t1: float, t2: float, ta: float) -> int:
    """NU from the argument-principle count of every factor (the centroid's zero at s = 0 left out:
    it counts the roots with Re s > 1e-7, a random point is not that close to a crossing)."""
    total = 0
    for f in factors(top, P, D):
        c = 1e-7 if f.is_centroid else 0.0
        n = count_roots_right_of(actuated_factor(P, D, complex(f.lam)), t1, t2, ta, c)
        total += n * int(f.multiplicity) * (2 if f.group.is_complex_pair else 1)
    return total


def test_map_at_a_vanishing_actuation_delay_is_todays_map() -> None:
    top = paper_six()
    pts = np.random.default_rng(3).uniform(0.0, 8.0, (200, 2))
    today = stability_map(top, 1.0, 0.5, 8.0, 8.0).unstable_count(pts[:, 0], pts[:, 1])
    tiny = stability_map(top, 1.0, 0.5, 8.0, 8.0, actuation_delay=1e-7).unstable_count(pts[:, 0], pts[:, 1])
    np.testing.assert_array_equal(tiny, today)
    assert stability_map(top, 1.0, 0.5, 8.0, 8.0, actuation_delay=0.0).delay_free_count == 0


@pytest.mark.parametrize(("top", "P", "D", "ta", "seed"), [
    (paper_six(), 1.0, 0.5, 0.3, 0), (paper_six(), 1.0, 0.5, 1.0, 1), (ring(5), 2.0, 1.0, 0.2, 2),
])  # fmt: skip
def test_map_counts_equal_certified_counts_at_random_points(top: Topology, P: float, D: float, ta: float,
                                                            seed: int) -> None:  # fmt: skip
    m = stability_map(top, P, D, 6.0, 6.0, actuation_delay=ta)
    assert m.actuation_delay == ta
    pts = np.random.default_rng(seed).uniform(0.0, 6.0, (25, 2))
    got = m.unstable_count(pts[:, 0], pts[:, 1])
    ref = [_certified_nu(top, P, D, x, y, ta) for x, y in pts]
    np.testing.assert_array_equal(got, ref)
    assert int(m.unstable_count(0.0, 0.0)) == _certified_nu(top, P, D, 0.0, 0.0, ta)


def test_explorer_point_report_uses_the_scenarios_actuation_delay(tmp_path) -> None:
    import dataclasses

    from delayform.app import Explorer
    from delayform.scenario import paper_scenario

    ex = Explorer(dataclasses.replace(paper_scenario(), actuation_delay=0.3), out_dir=tmp_path)
    report = ex.point(1.0, 0.5, 0.3, 0.2).as_json()
    assert report["actuation_delay"] == 0.3 and report["stable"] is False
    assert report["unstable_count"] == _certified_nu(paper_six(), 1.0, 0.5, 0.3, 0.2, 0.3) == 2
    ref = dominant_root(paper_six(), 1.0, 0.5, 0.3, 0.2, actuation_delay=0.3).root
    assert complex(*report["dominant_root"]) == pytest.approx(ref)


def test_per_link_arrays_keep_the_actuation_delay() -> None:
    # N x N arrays equal on every link: the same question as scalar delays, actuation delay included
    # (once answered -0.1664 + 1.0772j, stable, the actuation delay silently dropped)
    top = paper_six()
    r = dominant_root(top, 1.0, 0.5, np.full((6, 6), 0.3), np.full((6, 6), 0.2), actuation_delay=0.3)
    ref = _reference_rightmost(top, 1.0, 0.5, 0.3, 0.2, 0.3)
    assert abs(r.root - ref) <= 1e-8 * (1.0 + abs(ref))
    assert r.root == pytest.approx(0.02519 + 1.13035j, abs=1e-5) and not r.is_stable
    assert r.actuation_delay == 0.3


def test_per_link_delays_that_differ_refuse_an_actuation_delay() -> None:
    t1 = np.full((6, 6), 0.3)
    t1[0, 1] = 0.4  # a link of paper_six
    with pytest.raises(DelayError, match="actuation_delay with per-link tau1 that differs"):
        dominant_root(paper_six(), 1.0, 0.5, t1, 0.2, actuation_delay=0.3)
    t1[0, 5] = 0.9  # no link: ignored, as without the actuation delay
    t1[0, 1] = 0.3
    assert dominant_root(paper_six(), 1.0, 0.5, t1, 0.2, actuation_delay=0.3).actuation_delay == 0.3
