"""Certificates for several interval delays and the team's margin for delays varying together.

Every number is checked against something the certificates do not compute:
the exact spectrum of the constant-delay factors (rightmost roots), an
adversarial switching simulation with its own integrator, the published
constant-delay margin of the Gu-Kharitonov-Chen benchmark, and the algebra of
the improved reciprocally convex inequality.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("clarabel")

from delayform.analysis.certificates.adversary import greedy_switching_grows, weighted_switching_grows  # noqa: E402
from delayform.analysis.certificates.intervals import IntervalDelays, constant_nodes, interval_delays  # noqa: E402
from delayform.analysis.certificates.lmi import exact_check, margin_slope, recheck, solve  # noqa: E402
from delayform.analysis.certificates.margin import _Attempt  # noqa: E402
from delayform.analysis.certificates.several import (  # noqa: E402
    Functional,
    attempt,
    certify_interval_delays,
    interval_delay_margin,
)
from delayform.analysis.certificates.team import COVERS, _Modes, mode_system, team_delay_margin  # noqa: E402
from delayform.analysis.network import jitter_margin  # noqa: E402
from delayform.analysis.network.jitter import PER_LINK  # noqa: E402
from delayform.analysis.roots.single import rightmost_root  # noqa: E402
from delayform.characteristic import factors  # noqa: E402
from delayform.errors import InputError  # noqa: E402
from delayform.topology import paper_six  # noqa: E402

GU_A0, GU_A1 = [[-2.0, 0.0], [0.0, -0.9]], [[-1.0, 0.0], [-1.0, -1.0]]
#: exact constant-delay margin of the benchmark, arccos(-0.9) / sqrt(0.19) (Gu, Kharitonov and Chen 2003)
GU_MARGIN = math.acos(-0.9) / math.sqrt(0.19)


def _grows(lam: float, delta: float) -> bool:
    return greedy_switching_grows(lam, 1.0, 0.5, 2.0, 1.0, delta)


@pytest.fixture(scope="module")
def team_b():
    return team_delay_margin(paper_six(), 1.0, 0.5, 2.0, 1.0)


@pytest.mark.slow  # one team margin at b: half a minute to a minute under load
def test_team_margin_at_b_is_below_the_constant_offset_bound_and_the_adversary(team_b):
    m = team_b
    assert m.covers == COVERS and not m.reason
    assert m.delta > 0.09  # the small-gain margin here is 0.035 s
    assert all(md.certificate is not None and md.certificate.holds and md.certificate.exact for md in m.modes)
    fs = factors(paper_six(), 1.0, 0.5)
    # exact spectrum: every constant pair in the certified square is stable (corners and edge midpoints) ...
    d = m.delta
    square = [(2 + a * d, 1 + b * d) for a in (-1, 0, 1) for b in (-1, 0, 1)]
    assert all(rightmost_root(f, t1, t2).real < 0 for f in fs for t1, t2 in square)
    # ... and a constant offset just beyond 0.2622 (the hardest mode, lam = -0.637) is unstable: delta is far below it
    hard = next(f for f in fs if abs(f.lam - (-0.6368889)) < 1e-6)
    assert max(rightmost_root(hard, 2 + u, 1 + v).real for u in (-0.27, 0.27) for v in (-0.27, 0.27)) > 0
    assert d < 0.2622
    # the greedy switching adversary destabilizes the hardest mode, but only beyond the certified delta
    assert _grows(hard.lam.real, 0.2)
    assert not _grows(hard.lam.real, d)
    assert m.limiting == hard.lam
    # the family of weighted energies is stronger (it destabilizes where the plain greedy rule does not,
    # 0.1426 against 0.148) and still finds nothing inside the certified interval
    assert weighted_switching_grows(hard.lam.real, 1.0, 0.5, 2.0, 1.0, 0.145)
    assert not _grows(hard.lam.real, 0.145)
    assert not weighted_switching_grows(hard.lam.real, 1.0, 0.5, 2.0, 1.0, d)
    # the certified delta is below the strongest adversary (weighted greedy switching, 0.143 s) too
    assert d < 0.143
    # the search: one mode at a time, and the expensive functional (N = 3) only a few times: its step
    # from the dual slope of the optimum margin lands within rtol of the boundary (0.0984 of about 0.0987)
    assert sum("N=3" in verdict for _, verdict in m.tried) <= 4
    assert d >= 0.0982  # the previous search's margin (bisection and secant on t)


def _mode_problem(md, tau=(2.0, 1.0)):
    """The LMIs of a mode's certificate, rebuilt from what the margin returned (not from the search)."""
    f = next(g for g in factors(paper_six(), 1.0, 0.5) if g.lam == md.lam)
    A0, ak, e = mode_system(f)
    d = md.solved_at
    data = IntervalDelays(A0, ak, tuple(max(t - d, 0.0) for t in tau), tuple(t + d for t in tau), None, e)
    return md.options.problem(data)


@pytest.mark.slow  # team_b
def test_team_certificates_recheck_and_a_perturbed_one_is_rejected(team_b):
    for md in team_b.modes:
        problem = _mode_problem(md)
        x = problem.variables.pack(md.certificate.variables)
        assert md.solved_at >= team_b.delta
        check = recheck(problem, x)
        assert check.passed and check.exact_ok  # the same verdict from the returned matrices alone
    # perturb the limiting mode's certificate: P loses its positive definiteness by a hair
    md = team_b.modes[0]
    assert md.lam == team_b.limiting
    problem = _mode_problem(md)
    values = dict(md.certificate.variables)
    P = values["P"]
    lam_min = np.linalg.eigvalsh(P)[0]
    values["P"] = P - (lam_min + 1e-6 * np.linalg.norm(P, 2)) * np.eye(P.shape[0])
    bad = recheck(problem, problem.variables.pack(values))
    assert not bad.passed and bad.min_eigenvalues["P"] < 0
    # the exact check alone rejects it too (exact rational arithmetic, no float margin)
    assert exact_check(problem, bad.rational) is False
    # and a negated weight of the derivative terms (the outer window of the position delay)
    values = dict(md.certificate.variables)
    values["R2_0"] = -values["R2_0"]
    assert not recheck(problem, problem.variables.pack(values)).passed


@pytest.mark.slow  # two order-3 SDPs with the larger LMIs: about 15 s of CPU
def test_windows_cut_at_upper_ends_certify_beyond_the_plain_functional():
    """At delta = 0.0995 the plain order-3 functional fails; cut at the upper ends it holds, re-checked exactly.

    Both stay below the strongest adversary (0.143 s) and the exact constant-offset bound (0.2625 s).
    """
    f = next(g for g in factors(paper_six(), 1.0, 0.5) if abs(g.lam - (-0.6368889)) < 1e-6)
    A0, ak, e = mode_system(f)
    d = 0.0995
    data = IntervalDelays(A0, ak, (2.0 - d, 1.0 - d), (2.0 + d, 1.0 + d), None, e)
    assert not attempt(data, Functional(3, 1, True)).cert.holds
    cut = attempt(data, Functional(3, 1, True, upper=True), tolerance=1e-6)  # the search's tolerance: the margin is 4e-7 here
    assert cut.cert.holds and cut.cert.exact
    assert "windows cut at the upper ends" in cut.cert.method
    # the cut windows share x(t - hi_k) with the delay's own term: one signal, not two
    problem = interval_delays(data, 3, upper=True)
    assert problem.build(problem.variables.unpack(np.zeros(problem.variables.size)), False)["-Phi--"].shape[0] == 47  # 56 signals, 9 solved for by the delay-free row
    # the constant-offset square of half-width d is stable by the exact spectrum (corners and edge midpoints)
    assert all(rightmost_root(f, 2 + a * d, 1 + b * d).real < 0 for a in (-1, 0, 1) for b in (-1, 0, 1))


def test_team_margin_where_another_mode_than_the_hardest_limits():
    # at a (0.3, 0.2) the centroid limits (not the mode with the rightmost root): searched below the
    # hardest mode's margin; every constant pair of the certified square is stable by the exact spectrum
    m = team_delay_margin(paper_six(), 1.0, 0.5, 0.3, 0.2, max_order=1)
    assert m.limiting == 1 and 0.05 < m.delta < 0.3
    assert all(md.certificate.holds and md.certificate.exact and md.solved_at >= m.delta for md in m.modes)
    d = m.delta
    square = [(max(0.3 + a * d, 0.0), max(0.2 + b * d, 0.0)) for a in (-1, 0, 1) for b in (-1, 0, 1)]
    fs = factors(paper_six(), 1.0, 0.5)
    assert all(rightmost_root(f, t1, t2).real < 0 for f in fs if not f.is_centroid for t1, t2 in square)


def _hard_mode_data(d):
    f = next(g for g in factors(paper_six(), 1.0, 0.5) if abs(g.lam - (-0.6368889)) < 1e-6)
    A0, ak, e = mode_system(f)
    return IntervalDelays(A0, ak, (2.0 - d, 1.0 - d), (2.0 + d, 1.0 + d), None, e)


@pytest.mark.parametrize("balance", [False, True])
def test_dual_slope_of_the_optimum_margin_matches_the_secant_of_two_solves(balance):
    """dt/d delta from one solve's dual matrices (envelope theorem) against the secant of t at delta +- h.

    The limiting mode at b with the Wirtinger functional (no outer integrals): small LMIs, solved at
    Clarabel's default tolerance; t is smooth in delta away from the boundary (0.068). Balanced
    (the LMIs posed as D M D), t is another function of delta, and the duals returned (D Z D, for
    the LMIs as built) give its slope.
    """
    d, h = 0.04, 1e-3
    problem = lambda x: interval_delays(_hard_mode_data(x), 1, outer=False)  # noqa: E731
    sol = solve(problem(d), balance=balance)
    slope = margin_slope(sol, problem(d - 1e-6), problem(d + 1e-6), 1e-6)
    secant = (solve(problem(d + h), balance=balance).t - solve(problem(d - h), balance=balance).t) / (2 * h)
    assert slope < 0 and secant < 0
    assert abs(slope - secant) < 0.05 * abs(secant)


def test_a_balanced_solve_certifies_the_same_points_near_the_boundary():
    """The order-3 functional at 0.0984, next to its boundary: the balanced quick solve (D M D, D powers
    of two) returns variables whose LMIs, as built, pass the re-check, exactly too; its margin t is that
    of D M D, smaller than the plain one's. The balance leaves the powers of two it scales by exact."""
    from delayform.analysis.certificates.lmi import _balance, _linearize, _svec_order  # noqa: PLC0415

    problem = interval_delays(_hard_mode_data(0.0984), 3, outer=True)
    sol = solve(problem, tolerance=1e-7, quick=True, balance=True)
    check = recheck(problem, sol.x)
    assert sol.t > 0.0 and check.passed and check.exact_ok is True
    const, cols = _linearize(problem)
    for name, c in const.items():
        m = int(round((np.sqrt(8 * c.size + 1) - 1) / 2))
        rows, cs = _svec_order(m)
        w = _balance(c, cols[name], m)
        d = np.sqrt(w[rows == cs])  # the diagonal's weights are d_i^2
        assert np.all(np.frexp(d)[0] == 0.5)  # powers of two
        assert np.array_equal(w, d[rows] * d[cs])  # D M D entry by entry
        size = np.maximum(np.abs(cols[name][rows == cs]).max(axis=1), np.abs(c[rows == cs]))
        assert np.all((size == 0) | ((0.5 <= size * d**2) & (size * d**2 <= 2.0)))  # the diagonal's coefficients near 1


def test_compressed_linearization_equals_the_full_one(monkeypatch):
    """A second problem of the same structure is linearized on combined columns: the J of unit vectors.

    A poisoned pattern (one column's rows dropped) fails the random-point check and the full batch runs.
    """
    import delayform.analysis.certificates.lmi as lmi

    monkeypatch.setattr(lmi, "_PATTERNS", {})
    first, second = (interval_delays(_hard_mode_data(d), 2) for d in (0.05, 0.09))
    lmi._linearize(first)
    (key, (color, ncolors, masks)), = lmi._PATTERNS.items()
    assert ncolors < first.variables.size // 3
    const, cols = lmi._linearize(second)
    nv = second.variables.size
    units = second.build(second.variables.unpack(np.eye(nv)), False)  # the full batch, by hand
    for name, c in const.items():
        full = lmi.svec(np.asarray(units[name])).T - c[:, None]
        assert np.allclose(cols[name], full, rtol=0.0, atol=1e-13 * (1.0 + np.abs(full).max()))  # sums of columns: rounding
    poisoned = {k: m.copy() for k, m in masks.items()}
    poisoned["-Phi--"][:, 0] = False
    lmi._PATTERNS[key] = (color, ncolors, poisoned)
    _, again = lmi._linearize(second)
    assert np.allclose(again["-Phi--"], cols["-Phi--"], rtol=0.0, atol=1e-12) and np.any(again["-Phi--"][:, 0] != 0)
    assert lmi._PATTERNS[key][2]["-Phi--"][:, 0].any()  # the full batch ran and the pattern was refreshed


def test_predicted_zero_of_the_optimum_margin():
    # t = c (z - delta)^p: r = t / |t'| = (z - delta) / p, and two points give p and z exactly
    z, c = 0.1, 3.0
    for p in (1.0, 1.4, 2.5):
        held = [(d, c * (z - d) ** p, -c * p * (z - d) ** (p - 1)) for d in (0.07, 0.09)]
        assert _Modes._zero(held) == pytest.approx(z, rel=1e-12)
        # one point: a Newton step, below the zero when t is convex (p >= 1)
        assert held[-1][0] < _Modes._zero(held[-1:]) <= z + 1e-15
    # without slopes (nan): the zero of the line through the last two t's
    assert _Modes._zero([(0.05, 2.0, math.nan), (0.06, 1.0, math.nan)]) == pytest.approx(0.07)


def test_an_answer_that_fails_the_exact_recheck_steps_back_to_the_previous_certificate(monkeypatch):
    """The limiting mode's largest certificate made to fail its exact re-check: the margin is its next one below.

    The margin is rebuilt and re-checked independently (recheck on the returned matrices) and stays
    below the greedy switching adversary of that mode.
    """
    first = team_delay_margin(paper_six(), 1.0, 0.5, 2.0, 1.0, rtol=0.1, max_order=1)
    held = sorted(d for d, verdict in first.tried if verdict.startswith("mode 0") and verdict.endswith("holds"))
    assert held[-1] == first.delta and len(held) >= 2
    real = _Attempt.confirmed
    calls = []

    def fails_at_the_top(self):  # the first confirmation at the top: the limiting mode's (modes hardest first)
        cert = real(self)
        calls.append(cert.h2)
        return replace(cert, status="undecided", exact=False) if calls == [2.0 + first.delta] else cert

    monkeypatch.setattr(_Attempt, "confirmed", fails_at_the_top)
    m = team_delay_margin(paper_six(), 1.0, 0.5, 2.0, 1.0, rtol=0.1, max_order=1)
    assert m.delta == held[-2] and (first.delta, "failed the exact re-check") in m.tried
    for md in m.modes:
        assert md.solved_at >= m.delta and md.certificate.holds and md.certificate.exact
        problem = _mode_problem(md)
        assert recheck(problem, problem.variables.pack(md.certificate.variables)).passed
    assert not _grows(m.limiting.real, m.delta)


def test_constant_nodes_cut_at_upper_ends():
    # lower ends 1.9, 0.9; upper ends 2.1 (beyond the last lower end: not a cut) and 1.1
    assert constant_nodes([1.9, 0.9], 1) == [0.9, 1.9]
    assert constant_nodes([1.9, 0.9], 1, [2.1, 1.1]) == [0.9, 1.1, 1.9]
    assert constant_nodes([1.9, 0.9], 2, [2.1, 1.1]) == [0.45, 0.9, 1.0, 1.1, 1.5, 1.9]


@pytest.mark.slow
def test_jitter_margin_names_what_each_margin_covers(team_b):
    small = jitter_margin(paper_six(), 1.0, 0.5, 2.0, 1.0)
    assert small.covers == PER_LINK and small.per_link_delta == small.delta and math.isnan(small.together_delta)
    assert small.delta < team_b.delta  # per link, small gain: 0.035 s
    with pytest.raises(InputError, match="one delay pair"):
        jitter_margin(paper_six(), 1.0, 0.5, np.full((6, 6), 2.0), np.full((6, 6), 1.0), method="best")
    with pytest.raises(InputError, match="method must be one of"):
        jitter_margin(paper_six(), 1.0, 0.5, 2.0, 1.0, method="lmi")


def test_centroid_mode_is_certified_only_with_its_constant_solutions_projected_out():
    f = factors(paper_six(), 1.0, 0.5)[0]
    assert f.is_centroid
    A0, ak, e = mode_system(f)
    lo, hi = [1.9, 0.9], [2.1, 1.1]
    assert certify_interval_delays(A0, ak, lo, hi, order=1, outer=False, invariant=e).holds
    # without the projection no functional V >= eps |x|^2 exists (x = const is a solution): the solver says so
    assert not certify_interval_delays(A0, ak, lo, hi, order=1, outer=False).holds
    with pytest.raises(InputError, match="exactly"):
        certify_interval_delays(A0, ak, lo, hi, invariant=[0.0, 1.0])


def test_one_delay_stays_below_the_exact_constant_delay_margin():
    # any variation in [0, h]: constant delays included, so no certified h may pass 6.17258
    m = interval_delay_margin(GU_A0, [GU_A1], [3.0], order=1, outer=False, rtol=0.02, max_delta=3.5)
    assert 0.0 < m.delta and 3.0 + m.delta < GU_MARGIN
    assert m.certificate is not None and m.certificate.exact
    assert not certify_interval_delays(GU_A0, [GU_A1], [0.0], [GU_MARGIN + 0.05], order=2).holds


@pytest.mark.parametrize("bad", [dict(lo=[1.0], hi=[0.5]), dict(lo=[0.0, 0.0], hi=[1.0]), dict(lo=[-1.0], hi=[1.0])])
def test_bad_intervals_are_named(bad):
    with pytest.raises(InputError):
        certify_interval_delays(GU_A0, [GU_A1], bad["lo"], bad["hi"])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.01, 0.99))
def test_improved_reciprocally_convex_inequality(seed, alpha):
    # (1/a) x'Rx + (1/(1-a)) y'Ry >= [x; y]' [[R + (1-a) Z1, a Y1 + (1-a) Y2], [*, R + a Z2]] [x; y]
    # whenever [[R - Z1, Y1], [Y1', R]] >= 0 and [[R, Y2], [Y2', R - Z2]] >= 0
    rng = np.random.default_rng(seed)
    m = 3
    B = rng.normal(size=(m, m))
    R = B @ B.T + 0.1 * np.eye(m)
    L = np.linalg.cholesky(R)
    Y1 = 0.5 * L @ rng.normal(size=(m, m)) @ L.T / 3
    Y2 = 0.5 * L @ rng.normal(size=(m, m)) @ L.T / 3
    Ri = np.linalg.inv(R)
    Z1 = R - Y1 @ Ri @ Y1.T - 0.01 * np.eye(m)  # the largest Z1 the first condition allows (Schur)
    Z2 = R - Y2.T @ Ri @ Y2 - 0.01 * np.eye(m)
    x, y = rng.normal(size=m), rng.normal(size=m)
    lhs = x @ R @ x / alpha + y @ R @ y / (1 - alpha)
    M = np.block([[R + (1 - alpha) * Z1, alpha * Y1 + (1 - alpha) * Y2], [(alpha * Y1 + (1 - alpha) * Y2).T, R + alpha * Z2]])
    z = np.concatenate([x, y])
    assert lhs >= z @ M @ z - 1e-9 * (1 + abs(lhs))


def test_cli_per_mode_refuses_per_link_delays(tmp_path):
    from test_cli import assert_one_line_error, run

    np.savetxt(tmp_path / "t1.csv", np.full((6, 6), 0.3), delimiter=",")
    proc = run("jitter", "--tau1-file", str(tmp_path / "t1.csv"), "--tau2", "0.2", "--method", "per-mode", cwd=tmp_path)
    assert_one_line_error(proc, "--method per-mode", "small-gain margin only")


@pytest.mark.slow  # the team margin at b: team_b, shared with the tests above
def test_cli_best_prints_both_margins_with_what_they_cover(tmp_path, team_b, monkeypatch):
    """The command asks for the team margin at b once, with the library's defaults, and prints it.

    That margin is team_b, computed once for this module and checked above against the spectrum
    and the adversary: the command's own call is answered with it (and its arguments checked)
    instead of a third computation of the same margin.
    """
    import delayform.analysis.certificates.team as team_module
    from test_cli import run

    calls = []

    def shared(topology, P, D, tau1, tau2, **options):
        calls.append((topology, P, D, tau1, tau2, options))
        return team_b

    monkeypatch.setattr(team_module, "team_delay_margin", shared)
    proc = run("jitter", "--tau1", "2", "--tau2", "1", "--method", "best", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    ((topology, P, D, tau1, tau2, options),) = calls
    np.testing.assert_array_equal(topology.adjacency, paper_six().adjacency)
    assert (P, D, tau1, tau2, options) == (1.0, 0.5, 2.0, 1.0, {})
    lines = proc.stdout.splitlines()
    assert lines[0].startswith(f"jitter margin delta = {team_b.delta:.4g} s")
    assert "Lyapunov-Krasovskii per mode" in lines[0]
    assert lines[1].startswith("covers the same time-varying delays h1(t), h2(t) on every link")
    assert lines[2].startswith("per link, each delay varying on its own: 0.035")  # the small-gain margin
    assert "does not cover independent per-link variations" in lines[2]


@pytest.mark.parametrize("kwargs", [dict(max_order=5), dict(max_order=True), dict(rtol=0.5), dict(upper_cuts=1)])
def test_team_margin_bad_options_are_named(kwargs):
    with pytest.raises(InputError):
        team_delay_margin(paper_six(), 1.0, 0.5, 2.0, 1.0, **kwargs)


def test_agreeing_predictions_bring_the_next_step_closer_to_the_zero():
    """Phase 2's step: 2 % below the predicted zero, or (two predictions agreeing) twice their spread, at least rtol."""
    modes = object.__new__(_Modes)
    modes.rtol = 0.001
    lo, hi, zero = 0.0990, 0.1010, 0.1000
    assert modes._next(lo, hi, zero, False, 0) == pytest.approx(lo + 0.25 * 0.001 * lo)  # 0.098 < lo: a small step up
    assert modes._next(lo, hi, zero, False, 0, spread=2e-3) == pytest.approx(zero * (1 - 4e-3))
    assert modes._next(lo, hi, zero, False, 0, spread=1e-6) == pytest.approx(zero * (1 - 0.001))  # not below rtol
    modes.rtol = 0.02  # the default: unchanged by the spread
    assert modes._next(0.09, 0.11, zero, False, 0, spread=1e-6) == pytest.approx(zero * 0.98)
