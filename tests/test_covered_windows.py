"""Constant windows over the delays' intervals, their integral tied to the two parts' at t - h(t).

Checked against what the functional does not compute: the integral relation against Gauss-Legendre
quadrature of a smooth history, the exact spectrum of constant delays inside every certified box
(random systems), and greedy switching at the team's point b.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("clarabel")

from delayform.analysis.certificates.adversary import greedy_switching_grows  # noqa: E402
from test_team_certificates import _hard_mode_data  # noqa: E402
from delayform.analysis.certificates.intervals import (  # noqa: E402
    IntervalDelays,
    constant_nodes,
    integral_tie,
    interval_delays,
)
from delayform.analysis.certificates.krasovskii import _Signals  # noqa: E402
from delayform.analysis.certificates.lmi import LmiProblem, Variables, exact_check, recheck  # noqa: E402
from delayform.analysis.certificates.several import Functional, attempt, certify_interval_delays  # noqa: E402
from delayform.analysis.certificates.team import certify_team_delays, mode_system, team_delay_margin  # noqa: E402
from delayform.analysis.roots.single import rightmost_root  # noqa: E402
from delayform.characteristic import factors  # noqa: E402
from delayform.errors import DelayError, InputError  # noqa: E402
from delayform.quasipolynomial import QuasiPolynomial  # noqa: E402
from delayform.topology import paper_six  # noqa: E402


def _history(seed: int):
    """A smooth 2-vector history x(s) = sum of sinusoids, and its mean over [u, w] by Gauss-Legendre quadrature."""
    rng = np.random.default_rng(seed)
    amp, freq, phase = rng.normal(size=(3, 2, 4))
    freq = 3.0 * np.abs(freq)

    def x(s: np.ndarray) -> np.ndarray:
        return np.sum(amp[None] * np.sin(freq[None] * np.asarray(s)[:, None, None] + phase[None]), axis=2)

    nodes, weights = np.polynomial.legendre.leggauss(40)

    def mean(u: float, w: float) -> np.ndarray:
        s = 0.5 * (w - u) * nodes + 0.5 * (w + u)
        return 0.5 * (weights @ x(s))

    return x, mean


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 1.0), st.integers(1, 3))
def test_the_integral_tie_vanishes_on_every_history(seed, alpha, pieces):
    """C(h) zeta = 0 for a history's own signals, at the corners and between them; the parts swapped, it does not."""
    _, mean = _history(seed)
    a, b = 1.9, 2.1
    h = a + alpha * (b - a)
    cuts = np.linspace(a, b, pieces + 1)
    windows = [(w - u, f"w{i}") for i, (u, w) in enumerate(zip(cuts[:-1], cuts[1:]))]
    names = ["p", "q", *(name for _, name in windows)]
    sig = _Signals(names, 2, exact=False)
    zeta = np.concatenate([mean(a, h) if h > a else np.zeros(2), mean(h, b) if h < b else np.zeros(2),
                           *(mean(u, w) for u, w in zip(cuts[:-1], cuts[1:]))])  # fmt: skip
    C = integral_tie(sig, a, b, h, ("p", "q"), windows)
    assert np.abs(C @ zeta).max() < 1e-12 * (1.0 + np.abs(zeta).max())
    if 0.05 < alpha < 0.95:  # the parts' lengths swapped: the relation no longer holds
        wrong = integral_tie(sig, a, b, a + b - h, ("p", "q"), windows)
        assert np.abs(wrong @ zeta).max() > 1e-6


def test_covered_windows_reach_the_interval_ends():
    # lower ends 1.9, 0.9 and upper ends 2.1, 1.1: every end a cut, the windows on to 2.1
    assert constant_nodes([1.9, 0.9], 1, [2.1, 1.1], cover=True) == [0.9, 1.1, 1.9, 2.1]
    assert constant_nodes([0.0, 0.9], 1, [0.4, 1.1], cover=True) == [0.4, 0.9, 1.1]  # a delay clipped at 0
    # (0.5, 1.0) +- 0.24: the upper end 0.74 would leave a window of 0.02 s beside 0.76: not a cut
    assert constant_nodes([0.26, 0.76], 1, [0.74, 1.24], cover=True) == [0.26, 0.76, 1.24]


def test_only_a_tiled_interval_is_tied():
    """Where an upper end is not a cut its interval is not tiled by windows: no relation is imposed for it."""
    f = next(g for g in factors(paper_six(), 1.0, 0.5) if abs(g.lam - (-0.6368889)) < 1e-6)
    A0, ak, e = mode_system(f)
    names = lambda p: {b.name for b in p.variables.blocks}  # noqa: E731
    near = interval_delays(IntervalDelays(A0, ak, (0.26, 0.76), (0.74, 1.24), None, e), 1, cover=True)
    assert "Y_1" in names(near) and "Y_0" not in names(near)
    assert {"Y_0", "Y_1"} <= names(interval_delays(_hard_mode_data(0.1), 1, cover=True))


entries = st.floats(-2.0, 2.0, allow_nan=False).map(lambda v: round(v, 2))


@settings(max_examples=6, deadline=None)
@given(st.lists(entries, min_size=12, max_size=12), st.floats(0.05, 1.5), st.floats(0.05, 1.5), st.floats(0.01, 0.5))
def test_no_covered_certificate_holds_an_unstable_constant_delay(vals, tau1, tau2, delta):
    """Random two-delay systems: a certified box contains no constant delays the exact spectrum finds unstable."""
    a0 = np.array(vals[:4]).reshape(2, 2) - 2.5 * np.eye(2)  # lean towards stable systems
    a1, a2 = np.array(vals[4:8]).reshape(2, 2), np.array(vals[8:]).reshape(2, 2)
    lo, hi = [max(tau1 - delta, 0.0), max(tau2 - delta, 0.0)], [tau1 + delta, tau2 + delta]
    cert = certify_interval_delays(a0, [a1, a2], lo, hi, order=1, cover=True)
    if cert.holds:
        qp = QuasiPolynomial.from_matrices(a0, a1, a2)
        for t1 in (lo[0], tau1, hi[0]):
            for t2 in (lo[1], tau2, hi[1]):
                assert rightmost_root(qp, t1, t2).real < 0.0


def test_a_badly_scaled_positive_definite_matrix_passes_the_float_filter_and_the_exact_check():
    """Rows of very different sizes: the plain relative eigenvalue is below the margin, the scaled one is not.

    D M D is positive definite exactly when M is; the exact check (Fractions) decides. An indefinite
    matrix of the same scales is still rejected by both.
    """
    scales = np.array([1e-5, 1.0, 1e4])
    base = np.array([[1.0, 0.3, -0.2], [0.3, 1.0, 0.4], [-0.2, 0.4, 1.0]])
    var = Variables()
    var.symmetric("Q", 3)

    def build(v, exact):
        s = np.array([Fraction(x) for x in scales], dtype=object) if exact else scales
        return {"M": s[:, None] * v["Q"] * s[None, :]}

    problem = LmiProblem(var, build)
    x = problem.variables.pack({"Q": base})
    M = scales[:, None] * base * scales[None, :]
    assert np.linalg.eigvalsh(M)[0] / np.linalg.norm(M, 2) < 1e-9  # what the plain filter saw
    check = recheck(problem, x)
    assert check.passed and check.exact_ok is True and check.min_eigenvalues["M"] > 0.1
    bad = base.copy()
    bad[0, 2] = bad[2, 0] = -0.99  # indefinite, the same scales
    assert np.linalg.eigvalsh(bad)[0] < 0
    check = recheck(problem, problem.variables.pack({"Q": bad}))
    assert not check.passed and check.min_eigenvalues["M"] < 0
    assert exact_check(problem, check.rational) is False


@pytest.mark.parametrize("kwargs", [dict(cover_intervals=1), dict(rtol=0.0005)])
def test_team_margin_refuses_bad_cover_options(kwargs):
    with pytest.raises(InputError):
        team_delay_margin(paper_six(), 1.0, 0.5, 2.0, 1.0, **kwargs)


def test_certify_refuses_a_cover_that_is_not_a_boolean():
    with pytest.raises(InputError, match="cover"):
        certify_interval_delays(np.diag([-1.0, -1.0]), [0.1 * np.eye(2)], [0.5], [1.0], cover="yes")


def test_covered_windows_add_the_interval_windows_to_the_state():
    data = _hard_mode_data(0.1)
    plain, covered = interval_delays(data, 2), interval_delays(data, 2, cover=True)
    zero = lambda p: p.build(p.variables.unpack(np.zeros(p.variables.size)), False)  # noqa: E731
    # windows [0, 0.9], [0.9, 1.9] become [0, 0.9], [0.9, 1.1], [1.1, 1.9], [1.9, 2.1]: eta gains 2 x 2 moments of 2 states
    assert zero(covered)["P"].shape[0] == zero(plain)["P"].shape[0] + 8
    assert {"Y_0", "Y_1"} <= {b.name for b in covered.variables.blocks}
    assert not any(b.name.startswith("Y_") and b.name[2:].isdigit() for b in plain.variables.blocks)


@pytest.mark.slow  # the team at b, delta = 0.1, with and without the covered windows: about 15 s of CPU
def test_the_team_is_certified_at_the_goal_with_the_covered_windows_only():
    """Every mode at +-0.1 s, re-checked exactly; without the covered windows the limiting mode is refused, named.

    The limiting mode's certificate is rebuilt from what was returned and re-checked; a perturbed
    multiplier of the integral tie is rejected. The square of constant offsets of half-width 0.1 is
    stable by the exact spectrum, and greedy switching inside it decays.
    """
    m = certify_team_delays(paper_six(), 1.0, 0.5, 2.0, 1.0, 0.1, cover_intervals=True)
    assert m.delta == 0.1 and not m.reason and len(m.modes) == len(factors(paper_six(), 1.0, 0.5))
    assert all(md.certificate.holds and md.certificate.exact and md.solved_at == 0.1 for md in m.modes)
    hard = next(md for md in m.modes if abs(md.lam - (-0.6368889)) < 1e-6)
    assert "windows over the delays' intervals" in hard.functional
    problem = hard.options.problem(_hard_mode_data(0.1))
    assert recheck(problem, problem.variables.pack(hard.certificate.variables)).passed
    values = dict(hard.certificate.variables)
    values["Y_0"] = values["Y_0"] * 1.5  # a multiplier of the tie perturbed: the bound no longer negative
    assert not recheck(problem, problem.variables.pack(values)).passed
    # without the covered windows: the richest default functional (the cut one fails at 0.1 too, docs/theory.md)
    assert not attempt(_hard_mode_data(0.1), Functional(3, 1, True), exact=False).cert.holds
    wirtinger = certify_team_delays(paper_six(), 1.0, 0.5, 2.0, 1.0, 0.1, max_order=1)  # refused, and named
    assert wirtinger.delta == 0.0 and wirtinger.limiting == hard.lam and "not certified at delta = 0.1" in wirtinger.reason
    f = next(g for g in factors(paper_six(), 1.0, 0.5) if g.lam == hard.lam)
    assert all(rightmost_root(f, 2 + u * 0.1, 1 + v * 0.1).real < 0 for u in (-1, 0, 1) for v in (-1, 0, 1))
    assert not greedy_switching_grows(f.lam.real, 1.0, 0.5, 2.0, 1.0, 0.1)


@pytest.mark.parametrize("delta", [0.0, -0.1, 2.0, float("nan")])
def test_certify_team_refuses_a_deviation_outside_0_tau1(delta):
    with pytest.raises((InputError, DelayError)):
        certify_team_delays(paper_six(), 1.0, 0.5, 2.0, 1.0, delta)
