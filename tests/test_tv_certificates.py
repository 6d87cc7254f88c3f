"""Lyapunov-Krasovskii certificates for x' = A0 x + A1 x(t - h(t)) against the literature and the exact spectrum.

The benchmark (Gu, Kharitonov and Chen, *Stability of Time-Delay Systems*, 2003):
A0 = [[-2, 0], [0, -0.9]], A1 = [[-1, 0], [-1, -1]]. Its characteristic
function factors as (s + 2 + e^{-hs}) (s + 0.9 + e^{-hs}); the first factor is
stable for every delay (2 > 1), the second crosses at omega = sqrt(1 - 0.81),
h* = arccos(-0.9) / omega = 6.17258 (closed form below, and the project's
rightmost root on both sides of it).

Published LMI margins for it:
- constant delay, Bessel-Legendre hierarchy (Seuret and Gouaisbaut, "Hierarchy
  of LMI conditions for the stability analysis of time-delay systems", Systems
  & Control Letters 2015, Table 1): N = 0 (Jensen) 4.472, N = 1 (Wirtinger,
  also Seuret and Gouaisbaut, Automatica 2013) 6.059, N = 2 6.166, N = 3 6.1717,
  N = 4 6.1724;
- time-varying delay in [0, h] with |h'| <= mu, Wirtinger-based with reciprocal
  convexity (Seuret and Gouaisbaut, Automatica 2013, Table 2): 4.703 (mu = 0.1),
  2.420 (0.5), 2.137 (0.9).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delayform import QuasiPolynomial, certify_time_varying, rightmost_root, time_varying_delay_margin
from delayform.analysis.certificates.krasovskii import SystemData, constant_delay
from delayform.analysis.certificates.lmi import dominant_after_congruence, leading_minors_positive, recheck, solve
from delayform.errors import DelayError, InputError

A0 = np.array([[-2.0, 0.0], [0.0, -0.9]])
A1 = np.array([[-1.0, 0.0], [-1.0, -1.0]])
#: the exact constant-delay margin, closed form of the factor s + 0.9 + e^{-hs}
EXACT = math.acos(-0.9) / math.sqrt(1.0 - 0.81)


def test_the_exact_margin_by_closed_form_and_by_the_spectrum() -> None:
    assert EXACT == pytest.approx(6.17258, abs=1e-5)  # Gu, Kharitonov and Chen (2003)
    q = QuasiPolynomial.from_matrices(A0, A1)
    assert rightmost_root(q, EXACT - 1e-3).real < 0.0 < rightmost_root(q, EXACT + 1e-3).real


# (order, published margin), Seuret and Gouaisbaut 2015, Table 1
HIERARCHY = [(0, 4.472), (1, 6.059), (2, 6.166), (3, 6.1717), (4, 6.1724)]


@pytest.mark.parametrize(("order", "published"), HIERARCHY)
def test_constant_delay_margins_match_the_hierarchy(order: int, published: float) -> None:
    res = time_varying_delay_margin(A0, A1, mu=0.0, order=order)
    assert res.margin is not None
    assert res.margin <= EXACT  # never beyond the exact margin
    assert res.margin == pytest.approx(published, abs=2e-3)
    # the certified intervals chain from 0 to the margin, each re-checked exactly
    assert res.certificates[0].h1 == 0.0 and res.certificates[-1].h2 == res.margin
    assert all(a.h2 == b.h1 for a, b in zip(res.certificates, res.certificates[1:]))
    assert all(c.holds and c.exact for c in res.certificates)


def test_the_highest_order_offered_reaches_6_16() -> None:
    from delayform.analysis.certificates import MAX_ORDER

    res = time_varying_delay_margin(A0, A1, mu=0.0, order=MAX_ORDER, rtol=1e-3)
    assert res.margin is not None and 6.16 <= res.margin <= EXACT


# mu -> published Wirtinger-based figure, Seuret and Gouaisbaut 2013, Table 2
TIME_VARYING = [(0.1, 4.703), (0.5, 2.420), (0.9, 2.137)]


@pytest.mark.parametrize(("mu", "published"), TIME_VARYING)
def test_time_varying_margins_near_the_wirtinger_tables(mu: float, published: float) -> None:
    res = time_varying_delay_margin(A0, A1, mu=mu, order=1)
    assert res.margin is not None and res.margin <= EXACT
    # 4.7036 and 2.4208 agree to the published digits; 2.1324 is 0.2 % below 2.137
    assert res.margin == pytest.approx(published, rel=3e-3)
    (cert,) = res.certificates
    assert cert.holds and cert.exact and cert.h1 == 0.0 and cert.h2 == res.margin and cert.mu == mu


def test_jensen_is_below_wirtinger_for_varying_delays() -> None:
    jensen = time_varying_delay_margin(A0, A1, mu=0.5, order=0, rtol=1e-3).margin
    wirtinger = time_varying_delay_margin(A0, A1, mu=0.5, order=1, rtol=1e-3).margin
    assert jensen is not None and wirtinger is not None and jensen < wirtinger


@pytest.mark.parametrize("mu", [0.0, 0.5, None])
def test_interval_delays_stay_below_the_exact_margin(mu: float | None) -> None:
    # every delay set [h1, h2] contains the constant delay h2, so the exact margin bounds any certificate
    res = time_varying_delay_margin(A0, A1, h1=2.0, mu=mu, order=1, rtol=1e-3)
    assert res.margin is not None and 2.0 < res.margin <= EXACT
    assert res.certificates[0].h1 == 2.0


def test_an_interval_of_unstable_constant_delays_is_not_certified() -> None:
    q = QuasiPolynomial.from_matrices(A0, A1)
    assert rightmost_root(q, 6.4).real > 0.0
    for mu in (0.0, 0.5, None):
        assert not certify_time_varying(A0, A1, 6.5, h1=6.3, mu=mu, order=3).holds


def test_a_certificate_carries_its_lmis_and_they_are_positive_definite() -> None:
    cert = certify_time_varying(A0, A1, 4.0, mu=0.1, order=1)
    assert cert.holds and cert.exact and cert.order == 1 and cert.mu == 0.1
    assert "Wirtinger" in cert.method and "reciprocally convex" in cert.method
    assert {"P", "Q", "R2", "S2", "RCC"} <= set(cert.lmis) and "X" in cert.variables
    for M in cert.lmis.values():
        assert np.allclose(M, M.T) and np.linalg.eigvalsh(M)[0] > 0.0


def test_the_recheck_refuses_variables_that_do_not_satisfy_the_lmis() -> None:
    problem = constant_delay(SystemData(A0, A1, 3.0, 3.0, 0.0), 1)
    sol = solve(problem)
    assert sol.t > 0 and recheck(problem, sol.x).passed
    bad = recheck(problem, -sol.x)  # P, S, R negated: a solver answer that is wrong
    assert not bad.passed and not bad.eigenvalues_ok


def test_exact_positive_definiteness_beyond_floating_point() -> None:
    eps = Fraction(1, 2**60)  # 1 + eps == 1 in float64: only exact arithmetic sees the sign of det
    pd = np.array([[Fraction(1), Fraction(1)], [Fraction(1), 1 + eps]], dtype=object)
    nd = np.array([[Fraction(1), Fraction(1)], [Fraction(1), 1 - eps]], dtype=object)
    assert leading_minors_positive(pd) and not leading_minors_positive(nd)
    # the Hilbert matrix is positive definite (a Cauchy matrix), its determinant tiny
    hilbert = np.array([[Fraction(1, i + j + 1) for j in range(8)] for i in range(8)], dtype=object)
    assert leading_minors_positive(hilbert)
    assert not leading_minors_positive(-hilbert)


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 12), st.floats(-1.0, 1.0), st.integers(0, 2**31 - 1))
def test_the_congruence_test_never_calls_an_indefinite_matrix_positive(m: int, shift: float, seed: int) -> None:
    # random symmetric rational matrices near the boundary: the fast test may only say "positive" when
    # Bareiss's leading minors (an independent exact method) agree
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((m, m))
    S = B @ B.T / m
    S -= (float(np.linalg.eigvalsh(S)[0]) + shift * 1e-3) * np.eye(m)
    M = np.array([[Fraction(float(v)) for v in row] for row in S], dtype=object)
    M = (M + M.T) / 2
    if dominant_after_congruence(M):
        assert leading_minors_positive(M)
    if shift < -0.1:  # clearly positive definite (smallest eigenvalue 1e-4): the fast test proves it
        assert dominant_after_congruence(M)


def test_arbitrarily_fast_variation() -> None:
    res = time_varying_delay_margin(A0, A1, mu=None, order=1, rtol=1e-3)
    assert res.margin is not None and 0.5 < res.margin <= EXACT
    assert "Q" not in res.certificates[0].lmis  # no term may depend on dh/dt


def _stable_by_spectrum(a0: np.ndarray, a1: np.ndarray, h: float) -> bool:
    return rightmost_root(QuasiPolynomial.from_matrices(a0, a1), h).real < 0.0


entries = st.floats(-3.0, 3.0, allow_nan=False).map(lambda v: round(v, 2))


@settings(max_examples=12)
@given(st.lists(entries, min_size=8, max_size=8), st.floats(0.1, 3.0), st.sampled_from([0, 1, 2]))
def test_no_certified_constant_delay_is_unstable(vals: list[float], h: float, order: int) -> None:
    a0 = np.array(vals[:4]).reshape(2, 2) - 2.0 * np.eye(2)  # lean towards stable systems
    a1 = np.array(vals[4:]).reshape(2, 2)
    cert = certify_time_varying(a0, a1, h, mu=0.0, h1=0.0, order=order)
    if cert.holds:  # stable for every constant delay in [0, h]: check both ends and the middle
        for tau in (1e-3, 0.5 * h, h):
            assert _stable_by_spectrum(a0, a1, tau)


@settings(max_examples=10)
@given(st.lists(entries, min_size=8, max_size=8), st.floats(0.0, 1.0), st.floats(0.1, 2.0),
       st.sampled_from([0.3, None]))  # fmt: skip
def test_no_certified_interval_of_varying_delays_holds_an_unstable_constant_delay(
    vals: list[float], h1: float, width: float, mu: float | None
) -> None:
    # constant delays are among the delays varying in [h1, h2] (at any rate bound)
    a0 = np.array(vals[:4]).reshape(2, 2) - 2.0 * np.eye(2)
    a1 = np.array(vals[4:]).reshape(2, 2)
    cert = certify_time_varying(a0, a1, h1 + width, h1=h1, mu=mu, order=1)
    if cert.holds:
        for tau in (max(h1, 1e-3), h1 + 0.5 * width, h1 + width):
            assert _stable_by_spectrum(a0, a1, tau)


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"A0": [[1.0, 2.0]]}, InputError),
        ({"A0": np.eye(3)}, InputError),
        ({"A0": [[math.nan, 0.0], [0.0, 1.0]]}, InputError),
        ({"A0": [[1j, 0.0], [0.0, 1.0]]}, InputError),
        ({"A0": np.eye(9), "A1": np.eye(9)}, InputError),
        ({"h": -1.0}, DelayError),
        ({"h": math.inf}, DelayError),
        ({"h": True}, DelayError),
        ({"h1": 3.0}, DelayError),
        ({"mu": -0.1}, DelayError),
        ({"order": 9}, InputError),
        ({"order": 1.0}, InputError),
    ],
)
def test_bad_input_is_refused_by_name(kwargs: dict[str, object], error: type[Exception]) -> None:
    args: dict[str, object] = {"A0": A0, "A1": A1, "h": 2.0, "mu": 0.1, "order": 1} | kwargs
    with pytest.raises(error):
        certify_time_varying(args.pop("A0"), args.pop("A1"), args.pop("h"), **args)  # type: ignore[arg-type]


def test_bad_margin_arguments() -> None:
    with pytest.raises(InputError):
        time_varying_delay_margin(A0, A1, rtol=0.0)
    with pytest.raises(DelayError):
        time_varying_delay_margin(A0, A1, h1=5.0, max_delay=4.0)


def test_a_delay_independent_system_reaches_the_cap() -> None:
    # x' = -2x - x(t - h): stable for every constant delay (2 > 1)
    res = time_varying_delay_margin([[-2.0]], [[-1.0]], mu=0.0, order=1, max_delay=50.0)
    assert res.reached_cap and res.margin == 50.0


def test_an_unstable_delay_free_system_has_no_margin() -> None:
    res = time_varying_delay_margin([[1.0]], [[-0.5]], mu=0.5, order=1)
    assert res.margin is None and res.certificates == ()


def test_plot_draws_the_search() -> None:
    import matplotlib

    matplotlib.use("Agg")
    res = time_varying_delay_margin(A0, A1, mu=0.5, order=0, rtol=1e-2)
    ax = res.plot()
    assert "margin" in ax.get_title()


def test_a_job_beyond_the_time_budget_is_refused_up_front(monkeypatch: pytest.MonkeyPatch) -> None:
    from delayform.errors import ResourceLimitError

    monkeypatch.setenv("DELAYFORM_TIME_BUDGET", "5")
    a0, a1 = -3.0 * np.eye(8), 0.5 * np.eye(8)
    with pytest.raises(ResourceLimitError, match="DELAYFORM_TIME_BUDGET"):
        time_varying_delay_margin(a0, a1, h1=0.2, mu=0.3, order=1)
    assert time_varying_delay_margin(A0, A1, mu=0.0, order=1, rtol=1e-2).margin is not None  # small jobs pass


def _simulate(a0: np.ndarray, a1: np.ndarray, delay, t_end: float, dt: float = 0.005) -> np.ndarray:
    """|x(t)| of x' = a0 x + a1 x(t - delay(t)) from x = (1, 1) on [-max delay, 0]: Heun steps, history linear."""
    n = int(round(t_end / dt))
    xs = np.zeros((n + 1, 2))
    xs[0] = 1.0

    def past(t: float) -> np.ndarray:
        if t <= 0.0:
            return xs[0]
        k = min(int(t / dt), n - 1)
        w = t / dt - k
        return (1 - w) * xs[k] + w * xs[k + 1]

    for k in range(n):
        t = k * dt
        f0 = a0 @ xs[k] + a1 @ past(t - delay(t))
        guess = xs[k] + dt * f0
        xs[k + 1] = guess  # past() may read the step being made when the delay is below dt
        f1 = a0 @ guess + a1 @ past(t + dt - delay(t + dt))
        xs[k + 1] = xs[k] + 0.5 * dt * (f0 + f1)
    return np.linalg.norm(xs, axis=1)


def test_a_simulated_delay_varying_inside_the_certificate_decays() -> None:
    # an independent look at the time-varying claim: h(t) sweeps [0, h2] with |h'| = mu at its fastest
    mu = 0.5
    h2 = time_varying_delay_margin(A0, A1, mu=mu, order=1, rtol=1e-3).margin
    assert h2 is not None
    w = 2.0 * mu / h2
    norm = _simulate(A0, A1, lambda t: 0.5 * h2 * (1.0 + math.sin(w * t)), 60.0)
    assert norm[-1] < 1e-3 * norm[0]
    # the same integrator shows the growth of an unstable constant delay (it can tell the two apart)
    grow = _simulate(A0, A1, lambda t: 6.6, 400.0, dt=0.01)
    assert grow[-1] > grow[int(0.5 * len(grow))] > 0
