"""crossing_map for any two-delay QuasiPolynomial (issue 19, item 1): general terms by elimination.

NU is checked against an independent argument-principle count of q itself
(:mod:`ref_roots_ctcr`), and every curve point against q (its residual).
"""

from __future__ import annotations

import numpy as np
import pytest

from delayform import QuasiPolynomial
from delayform.analysis.ctcr.general import TermsQP, as_traced, resultant_solutions, unit_roots_single
from delayform.analysis.ctcr.stability_map import crossing_map, curve_residual
from delayform.characteristic import TwoDelayQuasiPolynomial
from delayform.errors import NeutralQuasiPolynomialError, QuasiPolynomialError
from ref_roots_ctcr import coefficient_bound, count_unstable_function


def _reference(terms: dict, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pv = np.polynomial.polynomial.polyval

    def f(s, a, b):
        return sum(pv(s, np.asarray(c, complex)) * np.exp(-(k[0] * a + k[1] * b) * s) for k, c in terms.items())

    R = 1.05 * coefficient_bound([np.asarray(terms[(0, 0)], complex)] +
                                 [np.asarray(c, complex) for k, c in terms.items() if k != (0, 0)]) + 1.0
    return count_unstable_function(f, R, x, y)


def _check(terms: dict, t1max: float, t2max: float, n: int = 200, seed: int = 0) -> None:
    m = crossing_map(QuasiPolynomial(terms), t1max, t2max)
    for c in m.curves:
        assert np.all(curve_residual(m.traced[c.source], c) <= 1e-9)
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(0, t1max, n), rng.uniform(0, t2max, n)
    ref, uncertain = _reference(terms, x, y)
    assert uncertain.sum() <= n // 20
    got = m.unstable_count(x, y)
    np.testing.assert_array_equal(got[~uncertain], ref[~uncertain])
    assert len(np.unique(ref)) >= 2  # the window holds stable and unstable regions


def test_general_terms_z1_z2_squared_and_commensurate():
    _check({(0, 0): [1.0, 3.0, 2.0, 1.0], (1, 2): [0.5, 0.8], (3, 0): [0, 0, 0.7], (0, 3): [0.9],
            (2, 1): [0.3, 0.2]}, 6.0, 6.0)


def test_general_terms_complex_coefficients():
    _check({(0, 0): [1.0, 1.0, 1.0], (1, 2): [0.4 + 0.3j, 0.2j], (2, 1): [0.5]}, 5.0, 5.0, seed=1)


def test_commensurate_single_delay_lines():
    """Only tau1 appears, up to z1^3: the Chebyshev resultant gives the vertical lines."""
    terms = {(0, 0): [2.0, 1.5, 1.0], (1, 0): [0.5, 0.6], (3, 0): [1.2], (0, 1): [0.0]}
    _check(terms, 8.0, 2.0, seed=2)


def test_resultant_phases_solve_q():
    qp = TermsQP(((np.array([1.0, 3.0, 2.0, 1.0], complex), 0, 0), (np.array([1.5, 0.8], complex), 1, 2),
                  (np.array([0, 0, 1.2], complex), 3, 0)))
    omega = np.linspace(0.2, 3.0, 40)
    sols = resultant_solutions(qp, omega)
    assert sum(len(s) for s in sols) > 0
    for w, th in zip(omega, sols, strict=True):
        for t1, t2 in th:
            val = sum(np.polynomial.polynomial.polyval(1j * w, c) * np.exp(-1j * (a * t1 + b * t2))
                      for c, a, b in qp.terms())
            assert abs(val) < 1e-10 * 10


def test_unit_roots_single_against_closed_form():
    """s + a + b e^{-3 tau s}: |j omega + a| = |b| gives omega = sqrt(b^2 - a^2) (closed form)."""
    a, b = 0.5, 2.0
    om, th = unit_roots_single([np.array([a, 1.0], complex), np.zeros(0, complex), np.zeros(0, complex),
                                np.array([b], complex)])
    np.testing.assert_allclose(np.sort(np.unique(np.round(om, 9))), [np.sqrt(b * b - a * a)], rtol=1e-10)
    # theta is 3 omega tau mod 2 pi: e^{-3 j theta'} = -(j omega + a) / b for each of the three thetas
    assert th.size == 3


def test_six_term_quasi_polynomial_uses_the_paper_path_and_agrees_with_general():
    terms = {(0, 0): [1.0, 0.5, 1.0], (1, 0): [-0.5], (0, 1): [0.0, -0.25], (1, 1): [0.1]}
    qp = QuasiPolynomial(terms)
    assert isinstance(as_traced(qp), TwoDelayQuasiPolynomial)
    _check(terms, 10.0, 10.0, seed=3)


def test_refusals():
    with pytest.raises(NeutralQuasiPolynomialError):
        # neutral, D = 1 + 1.5 z1 z2^2 not strongly stable (neutral maps: tests/test_neutral.py)
        crossing_map(QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 2): [0.0, 1.5]}), 1.0, 1.0)
    with pytest.raises(QuasiPolynomialError, match="two delays"):
        crossing_map(QuasiPolynomial({(0, 0, 0): [1.0, 1.0], (1, 0, 1): [0.5]}), 1.0, 1.0)
    with pytest.raises(QuasiPolynomialError):
        crossing_map("s + 1", 1.0, 1.0)


@pytest.mark.parametrize("seed", [7, 11])
def test_matrix_dde_two_delays_against_the_determinant(seed):
    """x' = A0 x + A1 x(t - tau1) + A2 x(t - tau2), 3 x 3 (the form of Haag 2009 Ex. 7/8): terms up to
    z1^3, z1 z2^2, z1^2 z2; NU against a winding of det(sI - A0 - A1 z1 - A2 z2) (no expansion used)."""
    from ref_roots_ctcr import count_unstable

    rng = np.random.default_rng(seed)
    A0 = np.array([[-2.0, 0.5, 0.0], [0.3, -1.5, 0.4], [0.0, 0.2, -1.0]])
    A1 = rng.normal(size=(3, 3)) * 0.7
    A2 = rng.normal(size=(3, 3)) * 0.7
    q = QuasiPolynomial.from_matrices(A0, A1, A2)
    assert isinstance(as_traced(q), TermsQP) and (1, 2) in q.terms  # beyond eq. genfactor's six terms
    m = crossing_map(q, 4.0, 4.0)
    x, y = rng.uniform(0, 4, 120), rng.uniform(0, 4, 120)
    ref, uncertain = count_unstable(A0, A1, A2, x, y)
    assert uncertain.sum() <= 6
    np.testing.assert_array_equal(m.unstable_count(x, y)[~uncertain], ref[~uncertain])
