"""Rightmost roots at long delays (the root-chain path) against closed forms and independent methods.

References
----------
* s + a + b e^{-tau s} = 0 with u = tau (s + a) is u e^u = -b tau e^{a tau}, so its
  roots are s = -a + W_k(-b tau e^{a tau}) / tau over the branches k of the
  Lambert W function (Corless, Gonnet, Hare, Jeffrey and Knuth, "On the Lambert W
  function", Adv. Comput. Math. 5, 1996), and for real a, b the rightmost one is
  on the principal branch W_0 (Shinozaki and Mori, Automatica 42, 2006); the
  tests check that branch claim themselves on the branches -3..3.
* scipy.special.lambertw evaluates W_k where -b tau e^{a tau} is a double; beyond
  (a tau > 700) W_k is the solution of w + Log w = Log x + 2 pi i k, whose
  logarithm Log x = ln|b tau| + a tau + i arg(-b) needs no overflow; that form is
  itself checked against scipy where both apply.
* Two delays: the discretization of :func:`roots_in` (no chains) and the
  argument-principle count right of lines beside the root.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import lambertw

from delayform.analysis.roots.dominant import dominant_root
from delayform.analysis.roots.generator import _require_degrees
from delayform.analysis.roots.long_delay import certifying_line, delay_groups, distinct
from delayform.analysis.roots.problem import _problem_of_quasi
from delayform.analysis.roots.single import count_roots_right_of, relative_residual, rightmost_root, roots_in
from delayform.characteristic import factors
from delayform.errors import DelayError
from delayform.quasipolynomial import QuasiPolynomial
from delayform.topology import paper_six


def _first_order(a: float, b: float) -> QuasiPolynomial:
    """s + a + b e^{-tau s}."""
    return QuasiPolynomial({(0,): [a, 1.0], (1,): [b]})


def _lambert_roots(a: float, b: float, tau: float, branches: range) -> list[complex]:
    """Roots -a + W_k(-b tau e^{a tau}) / tau of s + a + b e^{-tau s} by scipy (a tau <= 700)."""
    x = -b * tau * math.exp(a * tau)
    return [complex(-a + lambertw(x, k) / tau) for k in branches]


def _lambert_log_form(a: float, b: float, tau: float, k: int = 0) -> complex:
    """The same root from w + Log w = Log x + 2 pi i k (no overflow of e^{a tau}), by Newton's method."""
    target = complex(math.log(abs(b * tau)) + a * tau, math.pi if b > 0 else 0.0) + 2j * math.pi * k
    w = target - cmath.log(target)  # the asymptotic series' first terms (Corless et al., eq. 4.19)
    for _ in range(50):
        step = (w + cmath.log(w) - target) / (1.0 + 1.0 / w)
        w -= step
        if abs(step) <= 1e-16 * abs(w):
            break
    return -a + w / tau


@pytest.mark.parametrize("tau", [100.0, 300.0, 500.0])
@pytest.mark.parametrize("a, b", [(1.0, 0.5), (1.0, -0.5), (1.0, 2.0), (0.5, -3.0), (-0.2, 0.1)])
def test_rightmost_root_is_the_principal_lambert_branch(a: float, b: float, tau: float) -> None:
    branches = _lambert_roots(a, b, tau, range(-3, 4))
    w0 = branches[3]
    # the branch claim: W_0 gives the largest real part (its conjugate W_-1 ties when b > 0)
    assert all(w0.real >= z.real - 1e-15 for z in branches)
    s = rightmost_root(_first_order(a, b), tau)
    assert s.real == pytest.approx(w0.real, abs=1e-12)
    assert s.imag == pytest.approx(abs(w0.imag), abs=1e-12)
    # b < 0 (x > 0): a real rightmost root; b > 0 (x < -1/e): a complex pair
    assert (s.imag == 0.0) == (b < 0.0 or w0.imag == 0.0)


def test_the_log_form_of_lambert_w_agrees_with_scipy() -> None:
    for a, b in [(1.0, 0.5), (1.0, -0.5), (0.5, 2.0)]:
        for k in (0, -1, 1):
            assert _lambert_log_form(a, b, 500.0, k) == pytest.approx(_lambert_roots(a, b, 500.0, range(k, k + 1))[0],
                                                                      abs=1e-14)  # fmt: skip


@pytest.mark.parametrize("tau", [1000.0, 2000.0])
@pytest.mark.parametrize("a, b", [(1.0, 0.5), (1.0, -0.5)])
def test_very_long_delays_match_lambert_w(a: float, b: float, tau: float) -> None:
    w0 = _lambert_log_form(a, b, tau)
    s = rightmost_root(_first_order(a, b), tau)
    assert s.real == pytest.approx(w0.real, abs=1e-13)
    assert s.imag == pytest.approx(abs(w0.imag), abs=1e-13)


@settings(max_examples=12, deadline=None)
@given(a=st.floats(0.2, 1.1), b=st.floats(0.1, 3.0), negative=st.booleans(), tau=st.floats(60.0, 600.0))
def test_rightmost_root_matches_lambert_w_at_random_long_delays(a: float, b: float, negative: bool, tau: float) -> None:
    b = -b if negative else b
    w0 = _lambert_roots(a, b, tau, range(0, 1))[0]
    s = rightmost_root(_first_order(a, b), tau)
    assert abs(s - complex(w0.real, abs(w0.imag))) <= 1e-11 * (1.0 + abs(w0))


def test_two_delays_agree_with_the_discretization() -> None:
    """s + 1 + 0.3 e^{-30 s} + 0.4 e^{-50 s}: chains of three pairs; roots_in discretizes (no chains)."""
    q = QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 0): [0.3], (0, 1): [0.4]})
    s = rightmost_root(q, 30.0, 50.0)
    box = roots_in(q, 30.0, 50.0, (s.real - 0.05, 0.5, -3.0, 3.0))
    top = box[np.argmax(box.real)]
    assert s.real == pytest.approx(top.real, abs=1e-12)
    assert s.imag == pytest.approx(abs(top.imag), abs=1e-12)


@pytest.mark.parametrize("taus", [(300.0, 500.0), (700.0, 400.0)])
def test_two_long_delays_have_no_root_right_of_the_answer(taus: tuple[float, float]) -> None:
    """At 300/500 s (no discretization could list these roots): certified counts beside the answer."""
    q = QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 0): [0.3], (0, 1): [0.4]})
    s = rightmost_root(q, *taus)
    assert float(relative_residual(q, s, *taus)) <= 1e-10
    gap = 1e-9
    assert count_roots_right_of(q, *taus, s.real + gap) == 0
    assert count_roots_right_of(q, *taus, s.real - gap) >= 1


@pytest.mark.parametrize("taus", [(1000.0, 1000.0), (1000.0, 0.0)])
def test_paper_team_at_1000_s_is_answered_and_certified(taus: tuple[float, float]) -> None:
    """The paper's team (P = 1, D = 0.5) at 1000 s: every factor, counted beside the root.

    At (1000, 0) the centroid factor is s^2 + 1 - e^{-1000 s}: its rightmost roots sit next to
    the zeros +-i of the principal term, where the chain map contracts least.
    """
    dom = dominant_root(paper_six(), 1.0, 0.5, *taus)
    fs = factors(paper_six(), 1.0, 0.5)
    r = complex(dom.root)
    # no factor has a root right of the dominant one; its own has one there (two for a pair's lam, conj lam)
    assert all(count_roots_right_of(f, *taus, r.real + 1e-9) == 0 for f in fs)
    assert count_roots_right_of(dom.factor, *taus, r.real - 1e-9) >= 1


def test_the_factor_at_long_delay_agrees_with_the_discretization() -> None:
    fs = factors(paper_six(), 1.0, 0.5)
    f = next(f for f in fs if f.group.is_complex_pair)
    s = rightmost_root(f, 40.0, 40.0)
    box = roots_in(f, 40.0, 40.0, (s.real - 0.02, 0.5, -1.5, 1.5))
    top = box[np.argmax(box.real)]
    assert s.real == pytest.approx(top.real, abs=1e-12)


def test_terms_of_equal_delay_are_one_chain() -> None:
    prob = _problem_of_quasi(QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 0): [0.3], (0, 1): [0.4]}), (7.0, 7.0))
    groups = delay_groups(prob, 1.0, 0.0)
    assert [h for h, _ in groups] == [0.0, 7.0]
    assert groups[1][1].tolist() == [0.7 + 0j]


def test_distinct_merges_repeats_only() -> None:
    z = np.array([1 + 1j, 1 + 1j + 1e-13, 1 - 1j, 2 + 1j])
    assert sorted(distinct(z).tolist(), key=lambda v: (v.imag, v.real)) == [1 - 1j, 1 + 1j, 2 + 1j]


def test_the_certifying_line_keeps_away_from_every_root() -> None:
    reals = np.array([-1.0, -1.0, -1.001, -1.003, -1.0031, -2.0])
    c = certifying_line(reals, -1.0, 0.004)
    assert c == pytest.approx(-1.002)
    # an isolated top: the line sits at the window's edge, farthest from the roots below
    assert certifying_line(np.array([0.5, -1.0]), 0.5, 0.004) == pytest.approx(0.496)


def test_beyond_the_chains_budget_the_refusal_comes_first_in_one_line() -> None:
    with pytest.raises(DelayError) as info:
        dominant_root(paper_six(), 1.0, 0.5, 1e6, 1e6)
    message = str(info.value)
    assert "\n" not in message and "would need" in message and "delays up to 1e+06 s are too long" in message


def test_large_roots_are_refused_for_their_size_not_for_long_delays() -> None:
    """Large gains make large roots: the refusal names them, not the delays."""
    prob = _problem_of_quasi(QuasiPolynomial({(0,): [1e6, 2e3, 1.0], (1,): [5e5]}), (2.0,))
    with pytest.raises(DelayError, match="characteristic roots are large .* smaller gains or shorter delays"):
        _require_degrees(prob, (10**5,), 2.0)


def test_huge_gains_in_a_map_are_refused_for_large_roots() -> None:
    """A map at P = 1e4: refused up front, the message naming the roots' size and the gains."""
    from delayform.analysis.roots.dominant import dominant_root_map

    with pytest.raises(DelayError, match="characteristic roots are large") as info:
        dominant_root_map(paper_six(), 1e4, 100.0, np.linspace(0.0, 30.0, 3), np.linspace(0.0, 30.0, 3))
    assert "smaller gains" in str(info.value) and "\n" not in str(info.value)


def test_jitter_at_large_gains_and_long_delays_answers_unstable_at_once() -> None:
    """P = 20, D = 0.01 at 17 s: unstable, which a certified count confirms (a root right of 0)."""
    from delayform.analysis.network import jitter_margin

    m = jitter_margin(paper_six(), 20.0, 0.01, 17.0, 17.0)
    assert m.delta == 0.0 and m.nominal_root.real > 0.0
    fs = factors(paper_six(), 20.0, 0.01)
    assert sum(count_roots_right_of(f, 17.0, 17.0, 0.0) for f in fs if not f.is_centroid) >= 1


def test_jitter_nominal_root_from_the_factors_matches_the_per_link_finder() -> None:
    """Scalar delays take the factorized dominant root; the per-link matrix finder is independent."""
    from delayform.analysis.network import jitter_margin
    from delayform.analysis.network.links import link_team
    from delayform.analysis.network.per_link import dominant_of_team

    m = jitter_margin(paper_six(), 1.0, 0.5, 0.3, 0.2)
    per_link = dominant_of_team(link_team(paper_six(), 1.0, 0.5, 0.3, 0.2)).root
    assert abs(m.nominal_root - per_link) <= 1e-10 and m.delta > 0.0
