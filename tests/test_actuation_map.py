"""Dominant-root maps with an actuation delay (issue 21, item 4): the vectorized family in three delays.

Checked against two independent methods: the Chebyshev discretization of the
generator of the *full* 2N-state delayed system (tests/test_general_roots.py,
polished by Newton on det M(s)), and the exact CTCR map of
:func:`delayform.analysis.ctcr.actuated.actuated_stability_map` (law of cosines,
a different algorithm) for the stable set.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_actuation import _reference_rightmost

from delayform.analysis.ctcr.actuated import actuated_stability_map
from delayform.analysis.roots.actuated import actuated_factor, actuated_rightmost
from delayform.analysis.roots.dominant import dominant_root_map
from delayform.analysis.roots.family.actuated import actuated_count
from delayform.analysis.roots.family.rows import _Rows
from delayform.analysis.roots.single import count_roots_right_of
from delayform.errors import DelayError
from delayform.topology import paper_six, ring


@pytest.mark.parametrize("ta", [0.1, 0.6])
def test_map_matches_the_full_system_discretization(ta: float) -> None:
    top = paper_six()
    ax1, ax2 = np.linspace(0.0, 1.6, 9), np.linspace(0.0, 2.4, 7)
    m = dominant_root_map(top, 1.0, 0.5, ax1, ax2, actuation_delay=ta)
    assert m.actuation_delay == ta and m.roots.shape == (9, 7)
    for i, j in [(1, 1), (3, 5), (6, 2), (8, 6), (4, 0)]:
        ref = _reference_rightmost(top, 1.0, 0.5, float(ax1[i]), float(ax2[j]), ta)
        assert abs(m.roots[i, j] - ref) <= 1e-8 * (1.0 + abs(ref)), (i, j)
        assert bool(m.stable[i, j]) == (ref.real < 0.0)


def test_map_with_complex_eigenvalues_matches_the_full_system() -> None:
    # a directed ring of 5: two conjugate pairs of lam, rows walked over the whole line
    top = ring(5)
    ax1, ax2 = np.linspace(0.05, 1.0, 5), np.linspace(0.0, 1.0, 4)
    m = dominant_root_map(top, 1.0, 1.5, ax1, ax2, actuation_delay=0.2)
    for i, j in [(0, 0), (2, 3), (4, 1)]:
        ref = _reference_rightmost(top, 1.0, 1.5, float(ax1[i]), float(ax2[j]), 0.2)
        assert abs(m.roots[i, j] - ref) <= 1e-8 * (1.0 + abs(ref)), (i, j)


def test_every_point_is_the_single_point_answer() -> None:
    # the continuation (seeds from neighbours) gives each factor the root the per-point robust path certifies
    top = paper_six()
    ax1, ax2 = np.linspace(0.0, 2.0, 11), np.linspace(0.0, 3.0, 11)
    m = dominant_root_map(top, 1.0, 0.5, ax1, ax2, actuation_delay=0.4)
    k0 = next(k for k, f in enumerate(m.factors) if f.is_centroid)
    for i in range(0, 11, 3):
        for j in range(0, 11, 2):
            per = [actuated_rightmost(f, float(ax1[i]), float(ax2[j]), 0.4) for f in m.factors]
            if ax1[i] == 0.0:
                per[k0] = 0j
            best = max(per, key=lambda z: z.real)
            assert abs(m.roots[i, j] - best) <= 1e-9 * (1.0 + abs(best))


def test_stable_set_agrees_with_the_exact_ctcr_map() -> None:
    top = paper_six()
    ta = 0.1
    ax1, ax2 = np.linspace(0.01, 1.5, 16), np.linspace(0.0, 2.0, 16)
    m = dominant_root_map(top, 1.0, 0.5, ax1, ax2, actuation_delay=ta)
    ctcr = actuated_stability_map(top, 1.0, 0.5, 1.5, 2.0, ta)
    exact = ctcr.is_stable(ax1[:, None], ax2[None, :])
    clear = np.abs(m.real) > 1e-3  # a point on a crossing curve is neither
    assert clear.mean() > 0.9
    np.testing.assert_array_equal(m.stable[clear], exact[clear])
    assert 0 < m.stable.sum() < m.stable.size  # both kinds of point in the window


def test_zero_actuation_delay_is_todays_map() -> None:
    top = paper_six()
    a = dominant_root_map(top, 1.0, 0.5, [0.0, 0.5], [0.3, 1.0])
    b = dominant_root_map(top, 1.0, 0.5, [0.0, 0.5], [0.3, 1.0], actuation_delay=0.0)
    np.testing.assert_array_equal(a.roots, b.roots)
    assert b.actuation_delay == 0.0


def test_the_walk_counts_as_the_generic_certificate() -> None:
    # the family's walk (chord test, tails against s^2) against the generic argument principle
    # on the QuasiPolynomial in three delays (its own bounds and sampling)
    lams = np.array([1.0, 0.46, -0.5, -0.16 + 0.21j, 0.3 - 0.8j])
    t1, t2, ta = np.array([0.3, 1.2, 2.0, 0.7, 0.1]), np.array([0.2, 0.0, 1.5, 2.5, 0.9]), 0.7
    rows = _Rows(lams, t1, t2, lams.imag == 0.0, np.zeros(5, bool), 1.0, 0.5, ta)
    for c in (-0.31, 0.0137, 0.2):
        got = actuated_count(rows, np.full(5, c))
        want = [count_roots_right_of(actuated_factor(1.0, 0.5, lam), t1[k], t2[k], ta, c) for k, lam in enumerate(lams)]
        np.testing.assert_array_equal(got, want)
    assert np.any(actuated_count(rows, np.full(5, -0.31)) > 0)


@pytest.mark.parametrize("bad", [-0.1, math.nan, math.inf])
def test_bad_actuation_delay(bad: float) -> None:
    with pytest.raises(DelayError, match="actuation_delay"):
        dominant_root_map(paper_six(), 1.0, 0.5, [0.3], [0.2], actuation_delay=bad)


# ============================================================ the command line
from test_hardening import cli, one_line_error  # noqa: E402


def test_cli_map_takes_the_actuation_delay(tmp_path, capsys) -> None:
    import json

    out = tmp_path / "m"
    code, stdout, _ = cli(capsys, "map", "--out", str(out), "--size", "5,4", "--tau1-range", "0,2",
                          "--tau2-range", "0,3", "--actuation-delay", "0.2", "--json")  # fmt: skip
    assert code == 0
    summary = json.loads(stdout)
    assert summary["actuation_delay"] == 0.2
    ref = dominant_root_map(paper_six(), 1.0, 0.5, np.linspace(0, 2, 5), np.linspace(0, 3, 4), actuation_delay=0.2)
    assert summary["stable_fraction"] == pytest.approx(float(np.mean(ref.stable)))
    with np.load(out / "dominant_map.npz") as npz:
        saved = dict(npz)
    np.testing.assert_allclose(saved["roots"], ref.roots, rtol=0, atol=1e-12)
    line = one_line_error(capsys, "map", "--out", str(tmp_path / "bad"), "--actuation-delay", "-1")
    assert "--actuation-delay" in line and not (tmp_path / "bad").exists()


def test_cli_report_refuses_an_actuation_delay_it_cannot_simulate_before_writing(tmp_path, capsys) -> None:
    # the paper's ideal robots: the report's simulation cannot apply a late (dv/dt, omega); said before anything
    line = one_line_error(capsys, "report", "--out", str(tmp_path / "r"), "--actuation-delay", "0.1")
    assert "actuation delay" in line and not (tmp_path / "r").exists()


# ============================================================ delay scheduling
def test_schedule_with_an_actuation_delay_is_certified_and_stable() -> None:
    from delayform.design.scheduling import schedule_delays

    top, ta = paper_six(), 0.1
    s = schedule_delays(top, 1.0, 0.5, tau_min=(0.2, 0.1), tau_max=(1.5, 2.0), grid=9, actuation_delay=ta)
    assert s.actuation_delay == ta and 0.2 <= s.tau1 <= 1.5 and 0.1 <= s.tau2 <= 2.0
    ref = _reference_rightmost(top, 1.0, 0.5, s.tau1, s.tau2, ta)  # the full system, discretized
    assert abs(s.root - ref) <= 1e-8 * (1.0 + abs(ref)) and ref.real < 0.0
    coarse = dominant_root_map(top, 1.0, 0.5, np.linspace(0.2, 1.5, 9), np.linspace(0.1, 2.0, 9), actuation_delay=ta)
    assert s.root.real <= coarse.real.min() + 1e-12  # at least as fast as the best grid point
    assert s.hardware_root == pytest.approx(_reference_rightmost(top, 1.0, 0.5, 0.2, 0.1, ta))


def test_cli_schedule_takes_the_actuation_delay(tmp_path, capsys) -> None:
    import json

    code, stdout, _ = cli(capsys, "schedule", "--out", str(tmp_path / "s"), "--tau-min", "0.2,0.1",
                          "--tau-max", "1.5,2", "--actuation-delay", "0.1", "--json")  # fmt: skip
    assert code == 0
    summary = json.loads(stdout)
    assert summary["actuation_delay"] == 0.1 and summary["stable_delays_found"]
    root = complex(summary["root"]["re"], summary["root"]["im"])
    assert abs(root - _reference_rightmost(paper_six(), 1.0, 0.5, summary["tau1"], summary["tau2"], 0.1)) < 1e-8


@pytest.mark.parametrize("command", [
    ["region"], ["safe-delays"], ["gains", "--grid", "5"], ["box", "--tau1-box", "0.1,0.2", "--tau2-box", "0.1,0.2"],
    ["jitter"], ["links"],
])  # fmt: skip
def test_commands_without_actuation_in_their_theory_refuse_a_scenario_with_one(tmp_path, capsys, command) -> None:
    from test_hardening import BASE

    path = tmp_path / "late.toml"
    path.write_text(BASE + "[robot]\nlimits = false\nactuation_delay = 0.1\n")
    out = ["--out", str(tmp_path / "o")] if command[0] in ("region", "safe-delays", "gains") else []
    line = one_line_error(capsys, command[0], str(path), *command[1:], *out)
    assert "actuation_delay = 0.1" in line and not (tmp_path / "o").exists()


def test_report_region_section_says_why_it_is_not_computed(tmp_path) -> None:
    import dataclasses

    from delayform.report.analysis import region_section
    from delayform.scenario import paper_scenario

    section = region_section(dataclasses.replace(paper_scenario(), actuation_delay=0.1), tmp_path)
    assert section.summary == {"actuation_delay": 0.1, "computed": False} and not list(tmp_path.iterdir())


# ============================================================ property: the walk counts what the generic certificate counts
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=25, deadline=None)
@given(
    r=st.floats(0.0, 1.0), phi=st.floats(-math.pi, math.pi), t1=st.floats(0.0, 3.0), t2=st.floats(0.0, 3.0),
    ta=st.floats(0.01, 2.0), c=st.floats(-0.4, 0.4),
)  # fmt: skip
def test_walk_equals_generic_certificate_at_random_rows(r, phi, t1, t2, ta, c) -> None:
    from hypothesis import assume

    from delayform.errors import NotConvergedError

    lam = complex(r * math.cos(phi), r * math.sin(phi))
    real = abs(lam.imag) < 1e-12
    lam = complex(lam.real, 0.0) if real else lam
    rows = _Rows(np.array([lam]), np.array([t1]), np.array([t2]), np.array([real]), np.zeros(1, bool), 1.0, 0.5, ta)
    got = actuated_count(rows, np.array([c]))[0]
    try:
        want = count_roots_right_of(actuated_factor(1.0, 0.5, lam), t1, t2, ta, c)
    except NotConvergedError:
        assume(False)  # a root on the line: neither may decide
    assume(np.isfinite(got))
    assert got == want
