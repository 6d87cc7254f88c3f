"""Gain design (issue 12), checked against an independent search and an independent root finder.

* the designed gains reach an abscissa within 0.005 of the best a brute-force
  grid + Nelder-Mead search finds on Pade-based roots (tests/ref_gains.py,
  no delayform root finder), at the paper's points a, b, c;
* the abscissa returned is honest: the rightmost root of det(...)/s of the
  full 12 x 12 characteristic matrix (tests/ref_spectrum.py: mesh + Muller, no
  factorization) at the returned gains agrees to 1e-6;
* the robust design is stable on the whole box by the exact CTCR map, and a
  sampling of the box by the independent roots agrees with its worst case;
* simulations at the designed gains settle faster than at the paper's gains at
  a and b, and converge at c (unstable with the paper's gains).
"""

from __future__ import annotations

import json
import math
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ref_gains
from cli_runner import run_in_process
from ref_spectrum import reference_dominant_root

from delayform.analysis.ctcr.stability_map import PAPER_POINTS, stability_map
from delayform.analysis.roots.dominant import SETTLING_FACTOR
from delayform.analysis.roots.family.gains import gain_lines, rightmost_roots, root_gradients
from delayform.design.gains import GainDesign, box_is_stable, design_gains
from delayform.errors import DelayError, GainError, InputError, NoStableGainsError
from delayform.topology import paper_six

BOUNDS = (0.05, 3.0)
TEAM = paper_six()
EIG = [complex(v) for v in TEAM.eigenvalues]
#: Re of the dominant root with the paper's gains P = 1, D = 0.5 (tests/test_spectrum.py checks these)
PAPER_GAINS = (1.0, 0.5)


@pytest.fixture(scope="module")
def designs() -> dict[str, GainDesign]:
    return {k: design_gains(TEAM, *PAPER_POINTS[k], P_bounds=BOUNDS, D_bounds=BOUNDS) for k in "abc"}


@pytest.mark.parametrize("point", ["a", "b", "c"])
def test_design_reaches_the_best_an_independent_search_finds(designs: dict[str, GainDesign], point: str) -> None:
    t1, t2 = PAPER_POINTS[point]
    g = designs[point]
    _, _, best = ref_gains.best_gains(EIG, t1, t2, BOUNDS, grid=21, starts=3)
    assert g.abscissa <= best + 0.005, (g.P, g.D, g.abscissa, best)
    assert BOUNDS[0] <= g.P <= BOUNDS[1] and BOUNDS[0] <= g.D <= BOUNDS[1]
    # honest: two independent root computations at the returned gains
    assert abs(float(ref_gains.abscissa(EIG, g.P, g.D, t1, t2)[0]) - g.abscissa) < 1e-6
    full = reference_dominant_root(TEAM, g.P, g.D, t1, t2)
    assert abs(full.real - g.abscissa) < 1e-6
    assert g.root.real == g.abscissa and g.settling_time == pytest.approx(SETTLING_FACTOR / -g.abscissa)


def test_the_issue_numbers(designs: dict[str, GainDesign]) -> None:
    paper_b = float(ref_gains.abscissa(EIG, *PAPER_GAINS, *PAPER_POINTS["b"])[0])
    paper_c = float(ref_gains.abscissa(EIG, *PAPER_GAINS, *PAPER_POINTS["c"])[0])
    assert paper_c > 0.0  # c is unstable with the paper's gains ...
    assert designs["c"].decay_rate == pytest.approx(0.15, abs=0.01)  # ... and converges at ~0.15 1/s with these
    assert designs["b"].decay_rate > 10.0 * -paper_b  # more than ten times faster at b
    assert "argument principle" in designs["a"].certificate


def test_gain_plane_map_is_the_independent_abscissa(designs: dict[str, GainDesign]) -> None:
    gm = designs["c"].gain_map
    P, D = np.meshgrid(gm.P_values, gm.D_values, indexing="ij")
    ref = ref_gains.abscissa(EIG, P.ravel(), D.ravel(), *PAPER_POINTS["c"]).reshape(P.shape)
    assert np.max(np.abs(ref - gm.abscissa)) < 1e-8
    assert gm.stable.any() and not gm.stable.all()
    assert gm.chosen == (designs["c"].P, designs["c"].D)
    ax = designs["c"].plot(points={"paper": PAPER_GAINS})
    assert ax.get_xlabel().startswith("P")


def test_exact_gain_plane_boundary(designs: dict[str, GainDesign]) -> None:
    gm = designs["c"].gain_map
    curves = gm.boundary
    assert curves
    vertices = np.vstack(curves)
    # every vertex has a root on the imaginary axis: the independent abscissa there is >= 0
    sample = vertices[:: max(1, len(vertices) // 60)]
    alpha = ref_gains.abscissa(EIG, sample[:, 0], sample[:, 1], *PAPER_POINTS["c"])
    assert np.all(alpha > -1e-7), alpha.min()
    # where the certified map changes sign between neighbours, an exact curve passes close by
    h = gm.P_values[1] - gm.P_values[0]
    change = np.flatnonzero((np.sign(gm.abscissa[:-1]) != np.sign(gm.abscissa[1:])).ravel())
    i, j = np.unravel_index(change, (gm.P_values.size - 1, gm.D_values.size))
    mids = np.column_stack([(gm.P_values[i] + gm.P_values[i + 1]) / 2, gm.D_values[j]])
    dist = np.min(np.linalg.norm(mids[:, None, :] - vertices[None, :, :], axis=2), axis=1)
    assert change.size and np.all(dist < h), dist.max()


@settings(max_examples=30)
@given(
    P=st.floats(0.05, 3.0), D=st.floats(0.05, 3.0), t1=st.floats(0.01, 3.0),
    # zero, or a delay whose Pade polynomial is representable: near 1e-190 its 16th power underflows
    # and the reference has no leading coefficient left (the certified roots are right there too)
    t2=st.just(0.0) | st.floats(1e-6, 3.0),
)
def test_batched_certified_roots_agree_with_pade_roots(P: float, D: float, t1: float, t2: float) -> None:
    L = gain_lines(P, D, t1, t2)
    for group in TEAM.eigenvalue_groups:
        s = rightmost_roots(group, L)[0][0]
        ref = ref_gains.factor_rightmost(complex(group.lam), np.array([P]), np.array([D]), t1, t2)[0]
        assert abs(s.real - ref) < 1e-7, (group.lam, s, ref)


def test_root_gradients_match_finite_differences() -> None:
    P, D, t1, t2, h = 0.7, 1.3, 1.1, 0.6, 1e-6
    for group in TEAM.eigenvalue_groups:
        lam = complex(group.lam)
        s = rightmost_roots(group, gain_lines(P, D, t1, t2))[0]
        grads = root_gradients(lam, gain_lines(P, D, t1, t2), s)
        args = [P, D, t1, t2]
        for k, g in enumerate(grads):
            up, down = list(args), list(args)
            up[k] += h
            down[k] -= h
            f = lambda a: ref_gains.factor_rightmost(lam, np.array([a[0]]), np.array([a[1]]), a[2], a[3])[0]  # noqa: E731
            assert g[0] == pytest.approx((f(up) - f(down)) / (2 * h), rel=1e-4, abs=1e-7)


def test_robust_design_is_stable_on_the_whole_box() -> None:
    box1, box2 = (0.8, 1.2), (1.8, 2.2)  # around the paper's point c
    g = design_gains(TEAM, box1, box2, P_bounds=BOUNDS, D_bounds=BOUNDS, grid=9, starts=2)
    assert g.is_robust and g.stability_map is not None
    assert box_is_stable(g.stability_map, box1, box2)
    assert "CTCR" in g.certificate
    # an independent sampling of the box: every pair stable, none worse than the reported worst case
    worst = -np.inf
    for a in np.linspace(*box1, 5):
        for b in np.linspace(*box2, 5):
            worst = max(worst, float(ref_gains.abscissa(EIG, g.P, g.D, a, b)[0]))
    assert worst < 0.0
    assert g.abscissa >= worst - 1e-9
    assert g.abscissa == pytest.approx(float(ref_gains.abscissa(EIG, g.P, g.D, g.tau1, g.tau2)[0]), abs=1e-6)
    # the paper's gains fail on that box (c is inside), and the map says so
    assert not box_is_stable(stability_map(TEAM, *PAPER_GAINS, 2.0, 3.0), box1, box2)


def test_box_check_sees_a_curve_between_stable_corners() -> None:
    smap = stability_map(TEAM, *PAPER_GAINS, 8.0, 8.0)
    box1, box2 = (0.45, 2.85), (0.85, 1.45)
    corners = [(a, b) for a in box1 for b in box2] + [(1.65, 1.15)]
    assert all(bool(smap.is_stable(a, b)) for a, b in corners)  # sampling corners and centre: "stable"
    grid = np.linspace(0, 1, 41)
    inside = smap.is_stable(box1[0] + grid[:, None] * 2.4, box2[0] + grid[None, :] * 0.6)
    assert not inside.all()  # yet part of the box is unstable
    assert not box_is_stable(smap, box1, box2)
    assert box_is_stable(smap, (0.2, 0.4), (0.1, 0.3))


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"P_bounds": (0.0, 1.0)}, GainError),
        ({"P_bounds": (2.0, 1.0)}, GainError),
        ({"D_bounds": (1.0,)}, GainError),
        ({"grid": 2}, InputError),
        ({"starts": 0}, InputError),
        ({"tau1": -1.0}, DelayError),
        ({"tau1": (2.0, 1.0)}, DelayError),
        ({"tau2": float("nan")}, DelayError),
    ],
)
def test_bad_input_is_a_named_error(kwargs: dict, error: type[Exception]) -> None:
    args = {"tau1": 1.0, "tau2": 2.0, "P_bounds": BOUNDS, "D_bounds": BOUNDS, "grid": 5} | kwargs
    t1, t2 = args.pop("tau1"), args.pop("tau2")
    with pytest.raises(error):
        design_gains(TEAM, t1, t2, **args)


def test_a_map_too_large_is_refused_up_front(monkeypatch: pytest.MonkeyPatch) -> None:
    from delayform.errors import ResourceLimitError

    monkeypatch.setenv("DELAYFORM_TIME_BUDGET", "20")
    with pytest.raises(ResourceLimitError, match=r"gain design with a 101 x 101 .* would take about"):
        design_gains(TEAM, (1.0, 2.0), 1.0, P_bounds=BOUNDS, D_bounds=BOUNDS, grid=101)


def test_no_stable_gains_is_an_error_not_an_answer() -> None:
    with pytest.raises(NoStableGainsError, match="converge"):
        design_gains(TEAM, 8.0, 8.0, P_bounds=(2.9, 3.0), D_bounds=(2.9, 3.0), grid=4, starts=1)
    with pytest.raises(DelayError, match="tau1 -> 0"):  # no uniform decay rate near tau1 = 0
        design_gains(TEAM, (0.0, 0.3), 0.2, P_bounds=BOUNDS, D_bounds=BOUNDS, grid=4, starts=1)
    with pytest.raises(DelayError, match="too long"):
        design_gains(TEAM, 1e6, 1.0, P_bounds=BOUNDS, D_bounds=BOUNDS, grid=4, starts=1)


def test_on_tau1_zero_the_drift_does_not_count() -> None:
    g = design_gains(TEAM, 0.0, 0.2, P_bounds=BOUNDS, D_bounds=BOUNDS, grid=7, starts=1)
    ref = float(ref_gains.abscissa(EIG, g.P, g.D, 0.0, 0.2)[0])  # both roots at 0 excluded there
    assert g.abscissa < 0 and abs(g.abscissa - ref) < 1e-6


def test_designed_gains_settle_faster_in_simulation(designs: dict[str, GainDesign]) -> None:
    from delayform.simulation import simulate

    def settling(P: float, D: float, point: str) -> float:
        traj = simulate(TEAM, P, D, *PAPER_POINTS[point], "hexagon", model="double_integrator",
                        duration=150.0, dt=0.01)  # fmt: skip
        return float(traj.settling_time)

    for point in "ab":
        assert settling(designs[point].P, designs[point].D, point) < settling(*PAPER_GAINS, point)
    assert math.isfinite(settling(designs["c"].P, designs["c"].D, "c"))
    assert not math.isfinite(settling(*PAPER_GAINS, "c"))


def _run(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``delayform ARGS`` in-process (``tests/test_cli.py`` runs the entry point in a subprocess)."""
    return run_in_process(*args, cwd=cwd)


def test_cli_json_equals_the_library(tmp_path: Path) -> None:
    proc = _run("gains", "--tau1", "1", "--tau2", "2", "--grid", "7", "--json", "--out", str(tmp_path), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    lib = design_gains(TEAM, 1.0, 2.0, P_bounds=BOUNDS, D_bounds=BOUNDS, grid=7)
    assert data["P"] == pytest.approx(lib.P) and data["D"] == pytest.approx(lib.D)
    assert data["abscissa"] == pytest.approx(lib.abscissa)
    for name in ("gain_plane.png", "gain_plane.svg", "gain_plane.npz", "gains.json"):
        assert (tmp_path / name).exists()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--tau1", "1", "--tau1-box", "1,2"), "--tau1-box"),
        (("--tau2-box", "3,1"), "--tau2-box"),
        (("--P-bounds", "0,1"), "--P-bounds"),
        (("--D-bounds", "1"), "--D-bounds"),
        (("--grid", "2"), "--grid"),
    ],
)
def test_cli_errors_are_one_line_exit_2(tmp_path: Path, args: tuple[str, ...], needle: str) -> None:
    proc = _run("gains", *args, "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("delayform: error: ") and needle in lines[0], proc.stderr
    assert proc.stdout == ""


def test_report_sections_write_their_files(tmp_path: Path) -> None:
    from delayform.report import gain_comparison_section, gains_section
    from delayform.scenario import paper_scenario

    sc = paper_scenario()
    sc = replace(sc, chart=replace(sc.chart, tau1_max=2.0, tau2_max=4.0))  # a small window: quick scheduling
    s = gains_section(sc, tmp_path, grid=7, label="a")
    assert not s.summary["robust"] and s.summary["abscissa"] < s.summary["scenario_root"].real < 0
    comp = gain_comparison_section(sc, tmp_path, {"c": PAPER_POINTS["c"]}, grid=9, duration=80.0)
    rows = {r["method"]: r for r in comp.summary["rows"]}
    assert rows["scenario gains"]["root"].real > 0 and not math.isfinite(rows["scenario gains"]["simulated_settling"])
    assert math.isfinite(rows["gain design"]["simulated_settling"])
    # the window [0, 2] x [0, 4] holds no stable delays at least c: scheduling says so, gain design succeeds
    assert rows["delay scheduling"] == {"point": "c", "method": "delay scheduling", "found": False}
    assert ("c: delay scheduling", "nothing stable found") in comp.table
    assert rows["gain design"]["root"].real < -0.14
    for name in (*s.files, *comp.files):
        assert (tmp_path / name).exists()
