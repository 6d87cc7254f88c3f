"""python-control loops (delayform.loops, issue 23).

Delay margins are checked against closed forms (Hayes 1950 for
s + a + b e^{-tau s}; k / s; k / (s (s + a))), against python-control's own
phase margin for one-crossover loops, against an independent computation over
every gain crossover written here (a frequency grid of python-control's
frequency response, brentq on |L| = 1, phase from the response), and against
the spectrum itself (the rightmost root just below and just above the margin).
Two-delay loops are checked against the CTCR map of the paper's factor.
"""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq
from scipy.special import lambertw

import delayform as df
from delayform.errors import LoopError, UnstableLoopError
from delayform.loops import delay_margin, loop_characteristic, loop_polynomials, loop_quasi_polynomial


# ------------------------------------------------------------------ closed forms
@settings(max_examples=25, deadline=None)
@given(a=st.floats(-2.0, 3.0), ratio=st.floats(1.05, 6.0))
def test_first_order_loop_matches_hayes(a: float, ratio: float) -> None:
    # s + a + b e^{-tau s}, b > |a|: tau* = arccos(-a / b) / sqrt(b^2 - a^2) (Hayes 1950)
    b = ratio * max(abs(a), 0.2)
    m = delay_margin(control.tf([b], [1.0, a]))
    expected = math.acos(-a / b) / math.sqrt(b * b - a * a)
    assert m.tau == pytest.approx(expected, rel=1e-10)
    assert m.omega == pytest.approx(math.sqrt(b * b - a * a), rel=1e-10)
    assert m.certified


def test_first_order_loop_with_small_gain_is_delay_independent() -> None:
    # a > |b|: stable for every delay (Hayes 1950)
    m = delay_margin(control.tf([0.7], [1.0, 1.0]))
    assert m.tau == math.inf and m.crossovers == () and m.certified


@pytest.mark.parametrize("k", [0.1, 1.0, 7.5])
def test_integrator_loop(k: float) -> None:
    assert delay_margin(control.tf([k], [1.0, 0.0])).tau == pytest.approx(math.pi / (2 * k), rel=1e-12)


@pytest.mark.parametrize(("k", "a"), [(1.0, 1.0), (4.0, 0.5), (0.3, 2.0)])
def test_integrator_and_lag_loop(k: float, a: float) -> None:
    # L = k / (s (s + a)): omega_c^2 = (-a^2 + sqrt(a^4 + 4 k^2)) / 2, PM = pi/2 - atan(omega_c / a)
    wc = math.sqrt((-a * a + math.sqrt(a**4 + 4 * k * k)) / 2)
    m = delay_margin(control.tf([k], [1.0, a, 0.0]))
    assert m.tau == pytest.approx((math.pi / 2 - math.atan(wc / a)) / wc, rel=1e-10)


@pytest.mark.parametrize(
    "loop",
    [
        control.tf([1.0], [1.0, 1.0, 0.0]),
        control.tf([2.0, 1.0], [1.0, 3.0, 3.0, 1.0]),
        control.tf([15.0], [1.0, 6.0, 11.0, 6.0]),
        control.tf([0.5, 2.0], [1.0, 0.2, 0.0]),
    ],
)
def test_one_crossover_loops_agree_with_python_control_margin(loop: control.TransferFunction) -> None:
    _, pm_deg, _, _, wgc, _ = control.stability_margins(loop)
    m = delay_margin(loop)
    assert len(m.crossovers) == 1
    assert m.tau == pytest.approx(math.radians(pm_deg) / wgc, rel=1e-6)


def test_state_space_gives_the_transfer_function_margin() -> None:
    loop = control.tf([2.0, 1.0], [1.0, 3.0, 3.0, 1.0])
    assert delay_margin(control.ss(loop)).tau == pytest.approx(delay_margin(loop).tau, rel=1e-10)


# ------------------------------------------------------------------ every crossover
def _independent_margin(loop: control.TransferFunction) -> float:
    """min over every crossover of (PM mod 2 pi) / omega, from a frequency grid and brentq."""

    def log_gain(w: float) -> float:
        return math.log(abs(complex(loop(1j * w))))

    w = np.geomspace(1e-4, 1e3, 200_000)
    g = np.log(np.abs(control.frequency_response(loop, w).complex.ravel()))
    taus = []
    for i in np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:])):
        wc = brentq(log_gain, w[i], w[i + 1], xtol=1e-15, rtol=1e-15)
        pm = math.pi + np.angle(complex(loop(1j * wc)))
        taus.append((pm % (2 * math.pi)) / wc)
    return min(taus)


#: loops whose |L(j omega)| crosses 1 two or three times (a lightly damped resonance); in each the
#: margin is set by a crossover other than the lowest-frequency one
MULTI_CROSSOVER = [
    control.tf([1.2, 0.0], np.polymul([1.0, 1.0], [1.0, 0.05, 1.0])),
    control.tf([2.7, 2.7], np.polymul([1.0, 0.0], [1.0, 0.3, 9.0])),
    control.tf([8.0, 0.0], np.polymul([1.0, 0.5], [1.0, 0.2, 16.0])),
]


@pytest.mark.parametrize("loop", MULTI_CROSSOVER)
def test_margin_is_the_minimum_over_every_crossover(loop: control.TransferFunction) -> None:
    m = delay_margin(loop)
    assert len(m.crossovers) >= 2
    assert m.tau == pytest.approx(_independent_margin(loop), rel=1e-9)
    # the lowest-frequency crossover, the one a Bode plot reads first, is not the one that decides
    assert m.omega != min(c.omega for c in m.crossovers)


@pytest.mark.parametrize("loop", MULTI_CROSSOVER + [control.tf([2.0, 1.0], [1.0, 3.0, 3.0, 1.0])])
def test_spectrum_changes_exactly_at_the_margin(loop: control.TransferFunction) -> None:
    # an independent algorithm: the certified rightmost root (collocation + Newton), not the crossover formula
    m = delay_margin(loop)
    qp = m.quasi_polynomial
    below = df.rightmost_root(qp, m.tau * (1 - 1e-3), 0.0)
    above = df.rightmost_root(qp, m.tau * (1 + 1e-3), 0.0)
    assert below.real < 0.0 < above.real
    assert abs(abs(df.rightmost_root(qp, m.tau, 0.0).imag) - m.omega) < 1e-6 * m.omega


def test_crossover_delays_repeat_with_the_period() -> None:
    c = delay_margin(control.tf([2.0], [1.0, 1.0])).crossovers[0]
    d = c.delays(10.0)
    assert np.allclose(np.diff(d), 2 * math.pi / c.omega) and d[0] == c.tau


def test_biproper_loop_with_small_feedthrough_is_accepted_but_not_counted() -> None:
    # (0.5 s + 2) / (s + 1): neutral type with |L(j inf)| = 0.5; crossover omega^2 = 4
    m = delay_margin(control.tf([0.5, 2.0], [1.0, 1.0]))
    wc = math.sqrt((4.0 - 1.0) / (1.0 - 0.25))
    pm = math.pi + np.angle((0.5j * wc + 2.0) / (1j * wc + 1.0))
    assert m.tau == pytest.approx(pm / wc, rel=1e-10)
    assert not m.certified and "neutral" in m.certificate


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    ("loop", "words"),
    [
        (control.tf([1.0, 0.0, 0.0], [1.0, 1.0]), "improper"),
        (control.tf([2.0, 1.0], [1.0, 1.0]), "|L(j inf)| = 2 >= 1"),
        (control.tf([1.0], [1.0, 1.0], 0.1), "discrete-time"),
        (control.tf([[[1.0]], [[1.0]]], [[[1.0, 1.0]], [[1.0, 2.0]]]), "needs a square loop"),
        (control.frd([1.0, 0.5], [1.0, 2.0]), "FrequencyResponseData"),
        ("1/(s+1)", "got str"),
        (([1.0], [0.0]), "zero denominator"),
        (([float("nan")], [1.0, 1.0]), "not finite"),
    ],
)
def test_bad_loops_raise_one_clear_error(loop: object, words: str) -> None:
    with pytest.raises(LoopError, match=None) as info:
        delay_margin(loop)
    assert words in str(info.value)
    assert isinstance(info.value, ValueError)


class DelayLTI(control.TransferFunction):
    """Stands in for python-control's proposed DelayLTI (PR #1148): a loop carrying internal delays."""

    tau = (0.5,)


def test_loop_with_its_own_delays_is_refused() -> None:
    with pytest.raises(LoopError, match="carries time delays of its own"):
        delay_margin(DelayLTI([1.0], [1.0, 1.0]))


@pytest.mark.parametrize("loop", [control.tf([1.0], [1.0, -1.0]), control.tf([1.0], [1.0, -2.0, 0.0])])
def test_loop_unstable_without_delay_is_refused(loop: control.TransferFunction) -> None:
    with pytest.raises(UnstableLoopError, match="not stable without delay"):
        delay_margin(loop)


def test_non_strictly_proper_loop_has_no_retarded_quasi_polynomial() -> None:
    with pytest.raises(LoopError, match="not strictly proper"):
        loop_quasi_polynomial(control.tf([0.5, 1.0], [1.0, 1.0]))


# ------------------------------------------------------------------ two delays, MIMO
def test_two_delay_loop_map_equals_the_paper_factor_map() -> None:
    P, D, lam = 1.0, 0.5, 0.5
    L1 = control.tf([-lam * P], [1.0, D, P])
    L2 = control.tf([-lam * D, 0.0], [1.0, D, P])
    q = loop_quasi_polynomial(L1, L2)
    paper = df.TwoDelayQuasiPolynomial([P, D, 1.0], [-lam * P], [0.0, -lam * D])
    for a, b in zip(q.coefficients, paper.coefficients, strict=True):
        assert np.allclose(a, b)
    # the same loop through separate denominators, L2 = -lam D s (s + 3) / ((s^2 + D s + P)(s + 3)):
    # the product adds fixed stable roots only, so the CTCR map must not change
    L2b = control.tf([-lam * D, -3 * lam * D, 0.0], np.polymul([1.0, D, P], [1.0, 3.0]))
    q2 = loop_quasi_polynomial(L1, L2b)
    assert q2.degree == 5
    g = np.linspace(0.05, 9.95, 30)
    t1, t2 = np.meshgrid(g, g)
    expected = df.crossing_map(paper, 10.0, 10.0).unstable_count(t1, t2)
    assert np.array_equal(df.crossing_map(q2, 10.0, 10.0).unstable_count(t1, t2), expected)


def test_one_delay_loop_map_agrees_with_the_margin() -> None:
    loop = control.tf([2.0], [1.0, 1.0])
    smap = df.crossing_map(loop_quasi_polynomial(loop), 6.0, 1.0)
    tau = delay_margin(loop).tau
    assert smap.is_stable(tau * 0.99, 0.3) and not smap.is_stable(tau * 1.01, 0.3)


def test_mimo_loop_quasi_polynomial_is_the_closed_loop_determinant() -> None:
    A = np.array([[-1.0, 0.3], [0.0, -2.0]])
    C = np.array([[1.0, 0.5], [0.2, 1.0]])
    sys = control.ss(A, np.eye(2), C, np.zeros((2, 2)))
    q = loop_quasi_polynomial(sys)
    rng = np.random.default_rng(0)
    for s, tau in zip(rng.normal(size=5) + 1j * rng.normal(size=5), rng.uniform(0, 2, 5), strict=True):
        expected = np.linalg.det(np.eye(2) + sys(s) * np.exp(-tau * s)) * np.linalg.det(s * np.eye(2) - A)
        assert complex(q.evaluate(s, tau, 0.0)) == pytest.approx(expected, rel=1e-12)


def test_mimo_loop_too_large_or_with_feedthrough_is_refused() -> None:
    with pytest.raises(LoopError, match="rank of BC = 3"):
        loop_quasi_polynomial(control.ss(-np.eye(3), np.eye(3), np.eye(3), np.zeros((3, 3))))
    with pytest.raises(LoopError, match="feedthrough"):
        loop_quasi_polynomial(control.ss(-np.eye(2), np.eye(2), np.eye(2), np.eye(2)))


def test_pair_input_without_python_control_objects() -> None:
    num, den = loop_polynomials(([1.0, 2.0], [1.0, 3.0, 2.0]))
    assert num.tolist() == [2.0, 1.0] and den.tolist() == [2.0, 3.0, 1.0]


def test_margin_displays_itself() -> None:
    m = delay_margin(control.tf([2.0], [1.0, 1.0]))
    assert m._repr_png_().startswith(b"\x89PNG")
    assert "delay margin" in m._repr_html_()


def _coupled_mimo(coupling: float) -> control.StateSpace:
    A = np.array([[-1.0, 0.0, 0.0], [0.0, -0.5, 1.0], [0.0, -1.0, -0.5]])
    B = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])
    C = np.array([[1.5, coupling, 0.0], [coupling, 1.2, 0.0]])
    return control.ss(A, B, C, np.zeros((2, 2)))


def test_diagonal_mimo_margin_is_the_smaller_siso_margin() -> None:
    la, lb = control.tf([2.0], [1.0, 1.0]), control.tf([1.0], [1.0, 1.0, 0.0])
    sa, sb = control.ss(la), control.ss(lb)
    A = np.block([[sa.A, np.zeros((1, 2))], [np.zeros((2, 1)), sb.A]])
    B = np.block([[sa.B, np.zeros((1, 1))], [np.zeros((2, 1)), sb.B]])
    C = np.block([[sa.C, np.zeros((1, 2))], [np.zeros((1, 1)), sb.C]])
    m = delay_margin(control.ss(A, B, C, np.zeros((2, 2))))
    assert m.tau == pytest.approx(min(delay_margin(la).tau, delay_margin(lb).tau), rel=1e-10)
    assert m.certified and len(m.crossovers) == 2


@pytest.mark.parametrize("coupling", [0.0, 0.3, 0.8])
def test_coupled_mimo_margin_is_where_the_spectrum_crosses(coupling: float) -> None:
    m = delay_margin(_coupled_mimo(coupling))
    assert m.certified and math.isfinite(m.tau)
    qp = m.quasi_polynomial
    assert qp.g4.size  # a genuinely 2 x 2 loop: the e^{-2 tau s} term is there
    assert m._repr_png_().startswith(b"\x89PNG")  # the characteristic loci
    below = df.rightmost_root(qp, m.tau * (1 - 1e-3), 0.0)
    above = df.rightmost_root(qp, m.tau * (1 + 1e-3), 0.0)
    assert below.real < 0.0 < above.real
    # and through the general QuasiPolynomial of the same loop (matrix expansion by FFT)
    general = loop_characteristic(_coupled_mimo(coupling))
    assert df.rightmost_root(general, m.tau * (1 + 1e-3)).real == pytest.approx(above.real, abs=1e-8)


def test_loop_characteristic_of_three_delays_is_the_closed_loop() -> None:
    loops = [control.tf([1.0], [1.0, 1.0]), control.tf([0.5, 0.0], [1.0, 2.0, 2.0]), control.tf([0.2], [1.0, 3.0])]
    q = loop_characteristic(*loops)
    assert q.n_delays == 3
    dens = np.prod([np.polyval(loop.den[0][0], 0.3 + 0.7j) for loop in loops])
    s, taus = 0.3 + 0.7j, (0.4, 1.1, 2.0)
    expected = (1 + sum(complex(loop(s)) * np.exp(-t * s) for loop, t in zip(loops, taus, strict=True))) * dens
    assert complex(q.evaluate(s, *taus)) == pytest.approx(expected, rel=1e-12)
    with pytest.raises(LoopError, match="at least one"):
        loop_characteristic()


def test_one_delay_characteristic_changes_stability_at_the_margin() -> None:
    loop = control.tf([1.2, 0.0], np.polymul([1.0, 1.0], [1.0, 0.05, 1.0]))
    tau = delay_margin(loop).tau
    q = loop_characteristic(loop)
    assert df.count_roots_right_of(q, tau * (1 - 1e-3), 0.0) == 0
    assert df.count_roots_right_of(q, tau * (1 + 1e-3), 0.0) == 2


def test_zero_loop_has_no_crossover() -> None:
    m = delay_margin(([0.0], [1.0, 2.0]))
    assert m.tau == math.inf and m.certified


# ------------------------------------------------------------------ answers that must not be lost
def _lambert_root(c: complex, tau: float) -> complex:
    """The rightmost root of s + 1 + c e^{-tau s}: s = -1 + W0(-c tau e^tau) / tau (Lambert W, a closed form)."""
    return -1.0 + complex(lambertw(-c * tau * math.exp(tau), 0)) / tau


@settings(max_examples=25, deadline=None)
@given(log_gain=st.floats(0.5, 12.0), a=st.floats(-0.5, 2.0))
def test_high_gain_first_order_margin_is_exact(log_gain: float, a: float) -> None:
    # s + a + K e^{-tau s}: tau* = arccos(-a / K) / sqrt(K^2 - a^2) (Hayes 1950); the coefficients of
    # |D|^2 - |N|^2 span K^2 here, which once lost the crossover and answered "infinite, certified"
    k = 10.0**log_gain
    m = delay_margin(control.tf([k], [1.0, a]))
    assert m.tau == pytest.approx(math.acos(-a / k) / math.sqrt(k * k - a * a), rel=1e-9)
    assert m.omega == pytest.approx(math.sqrt(k * k - a * a), rel=1e-9)


@pytest.mark.parametrize("k", [3e7, 1e8, 1e10])
def test_high_gain_margin_is_where_the_lambert_root_crosses(k: float) -> None:
    w = math.sqrt(k * k - 1.0)
    tau = (math.pi - math.atan(w)) / w
    m = delay_margin(control.tf([k], [1.0, 1.0]))
    assert m.tau == pytest.approx(tau, rel=1e-10) and m.certified
    # the closed-form root of s + 1 + K e^{-tau s} on either side of the margin (Lambert W, principal branch)
    assert _lambert_root(k, tau * (1 - 1e-6)).real < 0.0 < _lambert_root(k, tau * (1 + 1e-6)).real


def _two_channels(c: np.ndarray) -> control.StateSpace:
    eye = np.eye(2)
    return control.ss(-eye, eye, c, np.zeros((2, 2)))


def test_two_identical_channels_keep_the_single_channel_margin() -> None:
    # det(I + L e^{-tau s}) = (s + 1 + 2 e^{-tau s})^2: a repeated factor, every crossing a fourfold
    # root of the resultant; the margin is that of 2 / (s + 1), 2 pi / (3 sqrt 3) (Hayes 1950)
    m = delay_margin(_two_channels(2.0 * np.eye(2)))
    assert m.tau == pytest.approx(2 * math.pi / (3 * math.sqrt(3)), rel=1e-10)
    assert m.omega == pytest.approx(math.sqrt(3.0), rel=1e-10) and m.certified
    assert m.crossovers[0].root_tendency == 1
    root = _lambert_root(2.0, 1.25)  # beyond the margin: unstable
    assert root == pytest.approx(0.0125 + 1.6887j, abs=1e-4) and root.real > 0
    assert df.rightmost_root(m.quasi_polynomial, 1.25, 0.0).real == pytest.approx(root.real, abs=1e-8)


def test_rotation_loop_without_a_single_delay_term_has_its_margin() -> None:
    # L = [[0, 2], [-2, 0]] / (s + 1): det = (s + 1 + 2j e^{-tau s})(s + 1 - 2j e^{-tau s}), no e^{-tau s}
    # term; crossing at sqrt 3 with phase margin pi / 6: tau* = pi / (6 sqrt 3)
    m = delay_margin(_two_channels(np.array([[0.0, 2.0], [-2.0, 0.0]])))
    tau = math.pi / (6 * math.sqrt(3))
    assert m.tau == pytest.approx(tau, rel=1e-10) and m.certified
    assert _lambert_root(2j, tau * (1 - 1e-6)).real < 0.0 < _lambert_root(2j, tau * (1 + 1e-6)).real


@pytest.mark.parametrize("loop", [([], [1.0, 1.0]), ([1.0], [])])
def test_empty_coefficients_are_refused_not_certified(loop: tuple[list[float], list[float]]) -> None:
    with pytest.raises(LoopError, match="is empty"):
        delay_margin(loop)


def test_infinite_margin_is_refused_when_a_crossing_was_lost(monkeypatch: pytest.MonkeyPatch) -> None:
    # the guard behind "infinite": if the elimination drops a crossover, the unit-circle test catches it
    import delayform.loops.crossings as crossings

    monkeypatch.setattr(crossings, "_siso_crossings", lambda g1, g2: [])
    with pytest.raises(df.errors.NotConvergedError, match="lost a crossover"):
        delay_margin(control.tf([2.0], [1.0, 1.0]))
    assert delay_margin(control.tf([0.7], [1.0, 1.0])).tau == math.inf  # a true infinite margin stands
