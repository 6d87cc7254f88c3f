"""Neutral quasi-polynomials (issue 19, item 5): difference operator, essential spectrum, roots.

References are closed forms (products whose roots are known exactly, the
Hale-type equality when the phases of D's terms are independent), an
elimination in the *other* variable than the library's, and a mesh + Muller
root finder with a dense argument count (:mod:`ref_spectrum`).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq, minimize_scalar

from delayform.analysis.neutral import (
    difference_operator,
    neutral_count_right_of,
    neutral_rightmost_root,
    neutral_roots_in,
    neutral_spectrum,
)
from delayform.analysis.neutral.nominal import commensurate, disk_min_modulus, nominal_abscissa
from delayform.analysis.roots import relative_residual, rightmost_root
from delayform.errors import DelayError, EssentialSpectrumError, FragileNeutralWarning, InputError
from delayform.quasipolynomial import QuasiPolynomial
from ref_spectrum import argument_count, mesh_roots

pv = np.polynomial.polynomial.polyval


def _f(terms: dict, taus: tuple[float, ...]):
    def f(s):
        s = np.asarray(s, complex)
        return sum(pv(s, np.asarray(c, complex)) * np.exp(-np.dot(k, taus) * s) for k, c in terms.items())
    return f


def _product(a: float, c: float) -> QuasiPolynomial:
    """(s + a)(1 + c e^{-s tau}): the root -a and the chain Re s = ln|c| / tau exactly."""
    return QuasiPolynomial({(0,): [a, 1.0], (1,): [a * c, c]})


def _z2_elimination_abscissa(d: dict, t1: float, t2: float) -> float:
    """C_D of a D linear in z2 (``D = a(z1) + z2 b(z1)``) by eliminating z2, maximized over the phase of z1.

    For z1 = e^{-r t1 + j th1} the zero is z2 = -a(z1)/b(z1); C_D is the largest r
    with ``|z2| = e^{-r t2}`` over th1 (scan, bisection, then a bounded 1-D maximization).
    """
    a = np.zeros(1 + max(k[0] for k in d), complex)
    b = np.zeros_like(a)
    a[0] = 1.0
    for (k1, k2), c in d.items():
        (a if k2 == 0 else b)[k1] += c

    def g(r, th1):
        z1 = np.exp(-r * t1 + 1j * th1)
        return np.log(np.abs(pv(z1, a) / pv(z1, b))) + r * t2

    def top(th1):
        rs = np.linspace(3.0, -3.0, 601)
        v = g(rs, th1)
        idx = np.flatnonzero(np.sign(v[:-1]) != np.sign(v[1:]))
        return brentq(lambda r: g(r, th1), rs[idx[0] + 1], rs[idx[0]], xtol=1e-14) if idx.size else -np.inf

    phases = np.linspace(0, 2 * np.pi, 720, endpoint=False)
    k = int(np.argmax([top(t) for t in phases]))
    res = minimize_scalar(lambda t: -top(t), bounds=(phases[k] - 0.01, phases[k] + 0.01), method="bounded",
                          options={"xatol": 1e-11})
    return -res.fun


def test_detection_and_difference_operator():
    q = QuasiPolynomial({(0, 0): [1.0, 2, 1], (1, 0): [0.2, 0.3, 0.4], (0, 1): [0.5, 0, -0.3], (1, 1): [0.1, 0, 0.2]})
    assert q.is_neutral
    D = difference_operator(q)
    assert dict(zip(D.exponents, D.coefficients, strict=True)) == {(1, 0): 0.4, (0, 1): -0.3, (1, 1): 0.2}
    retarded = QuasiPolynomial({(0,): [1.0, 1.0], (1,): [0.5]})
    assert difference_operator(retarded).is_trivial
    assert neutral_spectrum(retarded, 1.0).essential_abscissa == -np.inf


@pytest.mark.parametrize(("c", "tau"), [(0.5, 2.0), (-0.9, 1.0), (1.5, 0.5), (0.3j, 3.0)])
def test_one_delay_abscissa_closed_form(c, tau):
    D = difference_operator(QuasiPolynomial({(0,): [1.0, 1.0], (1,): [0.0, c]}))
    assert D.essential_abscissa(tau) == pytest.approx(np.log(abs(c)) / tau, abs=1e-13)
    assert D.strongly_stable(tau) is (abs(c) < 1)


def test_two_delays_independent_phases_reach_the_hale_bound():
    """D = 1 + a z1 + b z2: the phases align, so C_D solves |a| e^{-r t1} + |b| e^{-r t2} = 1."""
    q = QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 0): [0.0, 0.7], (0, 1): [0.3, -0.6]})
    t1, t2 = 1.0, 2.0
    ref = brentq(lambda r: 0.7 * np.exp(-r * t1) + 0.6 * np.exp(-r * t2) - 1.0, -5, 5, xtol=1e-15)
    D = difference_operator(q)
    assert D.essential_abscissa(t1, t2) == pytest.approx(ref, abs=1e-10)
    assert D.strongly_stable(t1, t2) is False  # ref > 0


def test_two_delays_structured_against_elimination_of_z2():
    """D = 1 + 1.2 z1 + 0.5 z1^2 - 0.4 z1 z2 (phases not free): eliminate z2 instead of z1."""
    q = QuasiPolynomial({(0, 0): [1.0, 1], (1, 0): [0, 1.2], (2, 0): [0.3, 0.5], (1, 1): [0, -0.4]})
    t1, t2 = 1.0, 0.7
    best = _z2_elimination_abscissa({(1, 0): 1.2, (2, 0): 0.5, (1, 1): -0.4}, t1, t2)
    D = difference_operator(q)
    assert D.essential_abscissa(t1, t2) == pytest.approx(best, abs=1e-6)
    assert D.essential_abscissa(t1, t2) < D.hale_bound(t1, t2) - 0.1


def test_rightmost_root_right_of_the_essential_spectrum_closed_form():
    q = _product(-0.3, 0.5)  # root 0.3, chain at -ln 2
    assert neutral_rightmost_root(q, 1.0) == pytest.approx(0.3, abs=1e-12)
    rep = neutral_spectrum(q, 1.0)
    assert rep.strongly_stable is True and rep.stable is False


def test_rightmost_root_left_of_the_essential_spectrum_raises_with_the_abscissa():
    q = _product(1.0, 0.5)  # root -1 left of the chain at -ln 2 / 2
    with pytest.raises(EssentialSpectrumError) as err:
        neutral_rightmost_root(q, 2.0)
    assert err.value.abscissa == pytest.approx(-np.log(2.0) / 2.0, abs=1e-13)
    rep = neutral_spectrum(q, 2.0)
    assert rep.rightmost is None and rep.stable is True and rep.essential_abscissa < 0


@pytest.mark.parametrize("c", [1.0, -1.0, 1.5])
def test_essential_spectrum_on_or_right_of_the_axis_is_never_stable(c):
    rep = neutral_spectrum(_product(2.0, c), 1.0)
    assert rep.essential_abscissa >= -1e-12
    assert rep.strongly_stable is False
    assert rep.stable is False


def test_rightmost_root_against_mesh_and_muller():
    terms = {(0, 0): [3.0, 2, 1], (1, 0): [-4, 0.3, 0.4], (0, 1): [0.5, 0, -0.3]}
    taus = (1.0, 1.7)
    s = neutral_rightmost_root(QuasiPolynomial(terms), *taus)
    f = _f(terms, taus)
    ref = mesh_roots(f, (-0.2, 2.0, -30.0, 30.0), shape=(221, 1201))
    assert abs(s - ref[np.argmax(ref.real)]) < 1e-9 or abs(s - np.conj(ref[np.argmax(ref.real)])) < 1e-9
    assert abs(f(np.asarray(s))) < 1e-10 * 10


def test_roots_in_a_region_against_mesh_and_dense_count():
    terms = {(0, 0): [1.0, 2, 1], (1, 0): [0.2, 0.3, 0.4], (0, 1): [0.5, 0, -0.3], (1, 1): [0.1, 0, 0.2]}
    taus = (1.0, 1.7)
    box = (-1.5, 0.5, -12.0, 12.0)
    roots, mult = neutral_roots_in(QuasiPolynomial(terms), *taus, region=box)
    f = _f(terms, taus)
    assert int(mult.sum()) == round(argument_count(f, box, points=40000))
    ref = mesh_roots(f, box, shape=(201, 1201))
    assert len(ref) == len(roots)
    for r in roots:
        assert np.min(np.abs(ref - r)) < 1e-8


def test_double_root_reported_with_multiplicity():
    """(s + 1)^2 (1 + 0.5 e^{-s}): -1 is a double root."""
    q = QuasiPolynomial({(0,): [1.0, 2.0, 1.0], (1,): [0.5, 1.0, 0.5]})
    roots, mult = neutral_roots_in(q, 1.0, region=(-1.3, -0.8, -1.0, 1.0))
    assert list(mult) == [2]
    assert abs(roots[0] + 1.0) < 1e-6  # a double root: about sqrt(eps) in double precision


def test_bad_input():
    q = _product(1.0, 0.5)
    with pytest.raises(InputError):
        neutral_roots_in(q, 1.0, region=(0, -1, 0, 1))
    with pytest.raises(DelayError):
        difference_operator(q).essential_abscissa(0.0)


# ----------------------------------------------------------------------------- CTCR maps of neutral systems
def _half_disk_reference(terms: dict, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Independent count: on Re s >= 0, |D| >= 1 - sum |c_k| (> 0 here), which bounds |s| of unstable roots."""
    from ref_roots_ctcr import count_unstable_function

    n = len(terms[(0, 0)]) - 1
    lead = terms[(0, 0)][n]
    c_sum = sum(abs(c[n] / lead) for k, c in terms.items() if any(k) and len(c) == n + 1)
    assert c_sum < 1.0
    low = sum(float(np.sum(np.abs(np.asarray(c)[:n]))) for c in terms.values())
    R = 1.05 * max(1.0, low / (abs(lead) * (1.0 - c_sum))) + 1.0

    def f(s, a, b):
        return sum(pv(s, np.asarray(c, complex)) * np.exp(-(k[0] * a + k[1] * b) * s) for k, c in terms.items())

    return count_unstable_function(f, R, x, y)


@pytest.mark.parametrize("terms", [
    {(0, 0): [3.0, 2.0, 1.0], (1, 0): [-2.0, 0.5, 0.3], (1, 2): [0.4, 0.0, -0.2], (0, 1): [0.0, 1.0, 0.1]},
    {(0, 0): [1.0, 1.0], (1, 0): [0.0, 0.5], (0, 1): [-1.5, 0.2]},
])
def test_neutral_crossing_map_against_independent_count(terms):
    from delayform.analysis.ctcr.stability_map import crossing_map, curve_residual

    m = crossing_map(QuasiPolynomial(terms), 5.0, 5.0)
    for c in m.curves:
        assert np.all(curve_residual(m.traced[c.source], c) <= 1e-9)
    rng = np.random.default_rng(4)
    x, y = rng.uniform(0, 5, 150), rng.uniform(0, 5, 150)
    ref, uncertain = _half_disk_reference(terms, x, y)
    assert uncertain.sum() <= 7
    np.testing.assert_array_equal(m.unstable_count(x, y)[~uncertain], ref[~uncertain])
    assert len(np.unique(ref)) >= 2


def test_neutral_crossing_map_refused_without_strong_stability():
    from delayform.analysis.ctcr.stability_map import crossing_map
    from delayform.characteristic import TwoDelayQuasiPolynomial
    from delayform.errors import NeutralQuasiPolynomialError

    with pytest.raises(NeutralQuasiPolynomialError, match="strongly stable"):
        crossing_map(TwoDelayQuasiPolynomial([1.0, 1.0], [0.0, 1.5]), 1.0, 1.0)
    with pytest.raises(NeutralQuasiPolynomialError, match="strongly stable"):
        crossing_map(QuasiPolynomial({(0, 0): [1.0, 1], (1, 0): [0, 1.2], (2, 0): [0.3, 0.5], (1, 1): [0, -0.4]}),
                     1.0, 1.0)


def test_stability_claim_uses_the_line_actually_searched():
    """No rightmost root: stable only because no root lies right of the certified line, which is < 0."""
    with pytest.raises(EssentialSpectrumError) as err:
        neutral_rightmost_root(_product(1.0, 0.5), 2.0)
    assert err.value.line is not None and err.value.abscissa < err.value.line < 0.0


# ----------------------------------------------------------------------------- the delays as given vs strong stability
#: TDS-CONTROL manual (Appeltans and Michiels), Ex. 2.6: a neutral system, not strongly stable, at (1, 2)
EX26 = {(0, 0): [-0.25, 1.0], (1, 0): [1 / 3, -0.75], (0, 1): [0.0, 0.5]}
#: its rightmost root at (tau1, tau2) = (1, 2) and robust essential abscissa, as published (5 and 4 digits)
EX26_ROOT, EX26_CD = complex(-0.17012, 0.82383), 0.1616


def _commensurate_reference(d: dict, multiples: tuple[int, int], h: float) -> float:
    """max -ln|w| / h over the roots (numpy.roots) of D(w^n1, w^n2), built here from D's coefficients."""
    poly = np.zeros(1 + max(k[0] * multiples[0] + k[1] * multiples[1] for k in d), complex)
    poly[0] = 1.0
    for (k1, k2), c in d.items():
        poly[k1 * multiples[0] + k2 * multiples[1]] += c
    return float(np.max(-np.log(np.abs(np.roots(poly[::-1])))) / h)


def test_example_2_6_answered_at_its_own_delays_and_flagged_fragile():
    q = QuasiPolynomial(EX26)
    f = _f(EX26, (1.0, 2.0))
    with pytest.warns(FragileNeutralWarning, match="arbitrarily small change of the delays"):
        s = rightmost_root(q, 1.0, 2.0)
    assert abs(s - EX26_ROOT) < 1e-5  # the published digits
    ref = mesh_roots(f, (-0.3, 2.0, -40.0, 40.0), shape=(116, 4001))  # mesh + Muller, a different method
    top = ref[np.argmax(ref.real)]
    assert abs(s - complex(top.real, abs(top.imag))) < 1e-10
    assert float(relative_residual(q, s, 1.0, 2.0)) <= 1e-12
    rep = neutral_spectrum(q, 1.0, 2.0)
    # D(w, w^2) = 1 - 0.75 w + 0.5 w^2 has two conjugate roots with |w|^2 = 1/0.5: abscissa -ln(2)/2
    assert rep.nominal_abscissa == pytest.approx(-np.log(2.0) / 2.0, abs=1e-13)
    assert rep.base_delay == 1.0
    # C_D: the phases of D's two terms are free, so 0.75 x + 0.5 x^2 = 1 with x = e^{-C_D}
    x = (-0.75 + np.sqrt(0.75**2 + 2.0)) / 1.0
    assert rep.essential_abscissa == pytest.approx(-np.log(x), abs=1e-10)
    assert rep.essential_abscissa == pytest.approx(EX26_CD, abs=5e-5)
    assert rep.rightmost == s
    assert (rep.nominally_stable, rep.strongly_stable, rep.stable, rep.fragile) == (True, False, False, True)
    text = rep.describe()
    assert "FRAGILE" in text and "not strongly stable" in text and "-0.170118 + 0.823827j" in text
    assert "0.1616" in text and "-0.346574" in text


def test_example_2_6_count_between_the_essential_abscissa_and_the_root():
    """Certified count right of a line between C_nom and the rightmost root against a dense winding count."""
    q = QuasiPolynomial(EX26)
    f = _f(EX26, (1.0, 2.0))
    c = -0.26
    assert neutral_count_right_of(q, 1.0, 2.0, c=c) == 3  # the pair and the real root -0.18328
    assert round(argument_count(f, (c, 3.0, -40.0, 40.0), points=40000)) == 3
    with pytest.raises(EssentialSpectrumError) as err:
        neutral_count_right_of(q, 1.0, 2.0, c=-0.4)
    assert err.value.abscissa == pytest.approx(-np.log(2.0) / 2.0, abs=1e-13)
    assert err.value.robust_abscissa == pytest.approx(EX26_CD, abs=5e-5)


def test_product_with_commensurate_chains_closed_form():
    """(s + a)(1 - 0.75 e^{-s} + 0.5 e^{-2 s}): the root -a and chains exactly on Re s = -ln(2)/2."""
    def qp(a):
        return QuasiPolynomial({(0, 0): [a, 1.0], (1, 0): [-0.75 * a, -0.75], (0, 1): [0.5 * a, 0.5]})

    with pytest.warns(FragileNeutralWarning):
        assert rightmost_root(qp(0.2), 1.0, 2.0) == pytest.approx(-0.2, abs=1e-12)
    rep = neutral_spectrum(qp(0.2), 1.0, 2.0)
    assert rep.nominally_stable is True and rep.fragile and rep.stable is False
    # left of the chains: no rightmost root, the supremum is the nominal abscissa; stable there, still fragile
    with pytest.raises(EssentialSpectrumError) as err:
        neutral_rightmost_root(qp(1.0), 1.0, 2.0)
    assert err.value.abscissa == pytest.approx(-np.log(2.0) / 2.0, abs=1e-13)
    assert err.value.abscissa < err.value.line < 0.0
    assert err.value.robust_abscissa == pytest.approx(EX26_CD, abs=5e-5)
    rep = neutral_spectrum(qp(1.0), 1.0, 2.0)
    assert rep.rightmost is None and rep.nominally_stable is True and rep.fragile
    assert "FRAGILE" in rep.describe()
    # unstable at the delays given: a root right of the axis
    rep = neutral_spectrum(qp(-0.1), 1.0, 2.0)
    assert rep.rightmost == pytest.approx(0.1, abs=1e-12) and rep.nominally_stable is False
    assert "unstable at the delays given" in rep.describe()


def test_commensurate_strongly_stable_nominal_and_robust_differ():
    """D = 1 + 0.6 z1 + 0.5 z1^2 + 0.45 z1 z2: at (1, 1.5) and (1, 2) the nominal abscissa (numpy.roots of
    D(w^n1, w^n2)) lies far left of C_D (elimination of z2 over the torus); both < 0: strongly stable."""
    d = {(1, 0): 0.6, (2, 0): 0.5, (1, 1): 0.45}
    q = QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 0): [0, 0.6], (2, 0): [0.2, 0.5], (1, 1): [0.1, 0.45]})
    D = difference_operator(q)
    for taus, mult, h in (((1.0, 1.5), (2, 3), 0.5), ((1.0, 2.0), (1, 2), 1.0)):
        nominal = _commensurate_reference(d, mult, h)
        robust = _z2_elimination_abscissa(d, *taus)
        rep = neutral_spectrum(q, *taus)
        assert rep.nominal_abscissa == pytest.approx(nominal, abs=1e-10)
        assert rep.essential_abscissa == pytest.approx(robust, abs=1e-7)
        assert rep.nominal_abscissa < rep.essential_abscissa - 0.05
        assert D.strongly_stable(*taus) is True and not rep.fragile
        # the rightmost root against mesh + Muller right of the nominal abscissa
        f = _f(q.terms, taus)
        box = (nominal + 0.02, 2.0, -30.0, 30.0)
        ref = mesh_roots(f, box, shape=(201, 2401))
        top = ref[np.argmax(ref.real)]
        assert abs(rep.rightmost - complex(top.real, abs(top.imag))) < 1e-9
        # in the strip between the two abscissae: a search right of C_D alone would have missed it
        assert rep.nominal_abscissa < rep.rightmost.real < rep.essential_abscissa
        assert rep.nominally_stable is True and rep.stable is True


@pytest.mark.parametrize(("b", "tau"), [(0.5, 1.0), (-0.8, 2.0), (1.25, 0.7)])
def test_one_delay_nominal_is_robust_closed_form(b, tau):
    """s + 1 + b s e^{-tau s}: one delay in D, so both abscissae are ln|b| / tau."""
    rep = neutral_spectrum(QuasiPolynomial({(0,): [1.0, 1.0], (1,): [0.0, b]}), tau)
    assert rep.nominal_abscissa == pytest.approx(np.log(abs(b)) / tau, abs=1e-13)
    assert rep.essential_abscissa == pytest.approx(np.log(abs(b)) / tau, abs=1e-13)
    assert rep.fragile is (abs(b) >= 1)


def test_rationally_independent_delays_nominal_is_robust():
    q = QuasiPolynomial(EX26)
    rep = neutral_spectrum(q, 1.0, np.sqrt(2.0))
    assert rep.base_delay is None
    assert rep.nominal_abscissa == rep.essential_abscissa
    # 0.75 x + 0.5 x^sqrt2 = 1, x = e^{-C_D}: the phases are free
    ref = brentq(lambda r: 0.75 * np.exp(-r) + 0.5 * np.exp(-r * np.sqrt(2.0)) - 1.0, -2, 2, xtol=1e-15)
    assert rep.essential_abscissa == pytest.approx(ref, abs=1e-10)
    assert rep.nominally_stable is False and rep.stable is False


@pytest.mark.parametrize(("c2", "nominal"), [(1.5, 0.5 * np.log(1.5)), (1.0, 0.0)])
def test_nominal_essential_spectrum_on_or_right_of_the_axis_is_never_stable(c2, nominal):
    """(s + 1)(1 - 0.5 e^{-s} + c2 e^{-2 s}): |w|^2 = 1/c2 for P's conjugate roots, closed form."""
    q = QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 0): [-0.5, -0.5], (0, 1): [c2, c2]})
    rep = neutral_spectrum(q, 1.0, 2.0)
    assert rep.nominal_abscissa == pytest.approx(nominal, abs=1e-12)
    assert rep.nominally_stable is False and rep.stable is False and rep.fragile
    assert "exponentially stable" not in rep.describe() and "not stable at the delays given" in rep.describe()
    with pytest.raises(EssentialSpectrumError):
        neutral_count_right_of(q, 1.0, 2.0, c=0.0)


def test_neutral_terms_cancel_at_the_delays_given():
    """(s + 0.5)(1 + 0.5 e^{-2 s tau1} - 0.5 e^{-s tau2}) is s + 0.5 at tau2 = 2 tau1, yet C_D = 0 (fragile)."""
    q = QuasiPolynomial({(0, 0): [0.5, 1.0], (2, 0): [0.25, 0.5], (0, 1): [-0.25, -0.5]})
    with pytest.warns(FragileNeutralWarning):
        assert rightmost_root(q, 1.0, 2.0) == pytest.approx(-0.5, abs=1e-12)
    rep = neutral_spectrum(q, 1.0, 2.0)
    assert rep.nominal_abscissa == -np.inf
    assert rep.essential_abscissa == pytest.approx(0.0, abs=1e-12)  # 0.5 x^2 + 0.5 x^2 = 1: x = 1
    assert rep.nominally_stable is True and rep.fragile and rep.stable is False


def test_commensurate_detection():
    D = difference_operator(QuasiPolynomial(EX26))
    com = commensurate(D, (0.1, 0.3))  # 0.3 / 0.1 is 3 to rounding
    assert com is not None and com.multiples == (1, 3) and com.base == pytest.approx(0.1, rel=1e-15)
    com = commensurate(D, (2.0, 5.0))
    assert com is not None and com.multiples == (2, 5) and com.base == 1.0
    assert commensurate(D, (1.0, np.pi)) is None
    with pytest.raises(DelayError):
        commensurate(D, (1.0, -2.0))


@given(st.lists(st.complex_numbers(max_magnitude=3.0, allow_nan=False), min_size=1, max_size=5),
       st.floats(0.2, 2.0))
def test_disk_min_modulus_is_a_lower_bound(roots, rho):
    """Against a dense polar grid of |P| on the disk, and 0 whenever numpy.roots puts a root inside."""
    poly = np.polynomial.polynomial.polyfromroots(roots)
    bound = disk_min_modulus(poly, rho)
    rr, th = np.meshgrid(np.linspace(0, rho, 81), np.linspace(0, 2 * np.pi, 721))
    assert bound <= np.abs(pv(rr * np.exp(1j * th), poly)).min() + 1e-12
    if np.any(np.abs(np.asarray(roots)) < rho * (1 - 1e-6)):
        assert bound == 0.0
    elif np.all(np.abs(np.asarray(roots)) > rho * 1.1):
        assert bound > 0.0


@settings(max_examples=40)
@given(st.lists(st.floats(-1.2, 1.2), min_size=3, max_size=3), st.integers(1, 3), st.integers(1, 4))
def test_nominal_abscissa_never_exceeds_the_robust_one(c, n1, n2):
    """The points e^{-s tau} lie on the torus of radii e^{-Re s tau_i}: C_nom <= C_D (two algorithms)."""
    q = QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 0): [0.0, c[0]], (0, 1): [0.0, c[1]], (1, 1): [0.0, c[2]]})
    D = difference_operator(q)
    taus = (float(n1), float(n2))
    assert nominal_abscissa(D, taus) <= D.essential_abscissa(*taus) + 1e-8


def test_robust_abscissa_where_one_elimination_misses_the_zeros():
    """Found by the property above. D = (1 + z2)(1 + 0.5 z1): z2 = -1 is a zero for every z1, so
    C_D = max(0, -ln 2) = 0 (closed form); D = 1 + z2 + z1 z2 / 32 at (1, 2): the phases are free, so C_D
    is the Hale bound (brentq), reached only in a window of r narrower than the first scan's step."""
    D = difference_operator(QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 0): [0, 0.5], (0, 1): [0, 1.0], (1, 1): [0, 0.5]}))
    assert D.essential_abscissa(1.0, 1.0) == pytest.approx(0.0, abs=1e-9)
    assert D.strongly_stable(1.0, 1.0) is False
    D = difference_operator(QuasiPolynomial({(0, 0): [1.0, 1.0], (0, 1): [0, 1.0], (1, 1): [0, 0.03125]}))
    ref = brentq(lambda r: np.exp(-2 * r) + 0.03125 * np.exp(-3 * r) - 1.0, -1, 1, xtol=1e-15)
    assert D.essential_abscissa(1.0, 2.0) == pytest.approx(ref, abs=1e-8)
