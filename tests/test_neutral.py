"""Neutral quasi-polynomials (issue 19, item 5): difference operator, essential spectrum, roots.

References are closed forms (products whose roots are known exactly, the
Hale-type equality when the phases of D's terms are independent), an
elimination in the *other* variable than the library's, and a mesh + Muller
root finder with a dense argument count (:mod:`ref_spectrum`).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from delayform.analysis.neutral import (
    difference_operator,
    neutral_rightmost_root,
    neutral_roots_in,
    neutral_spectrum,
)
from delayform.errors import DelayError, EssentialSpectrumError, InputError
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

    def g(r, th1):  # ln|z2| + r t2 with z2 solving D = 0 for z1 = e^{-r t1 + j th1}
        z1 = np.exp(-r * t1 + 1j * th1)
        z2 = (1 + 1.2 * z1 + 0.5 * z1 * z1) / (0.4 * z1)
        return np.log(np.abs(z2)) + r * t2

    def top(th1):  # the largest r with g = 0 at this phase
        rs = np.linspace(3.0, -3.0, 301)
        v = g(rs, th1)
        idx = np.flatnonzero(np.sign(v[:-1]) != np.sign(v[1:]))
        return brentq(lambda r: g(r, th1), rs[idx[0] + 1], rs[idx[0]], xtol=1e-14) if idx.size else -np.inf

    phases = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    k = int(np.argmax([top(t) for t in phases]))
    res = minimize_scalar(lambda t: -top(t), bounds=(phases[k] - 0.02, phases[k] + 0.02), method="bounded",
                          options={"xatol": 1e-10})
    best = -res.fun
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
