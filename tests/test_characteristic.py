"""The factorized characteristic equation of Lemma 1 (issue 2).

The factors come from the eigenvalues of C; the check is the determinant of
the 2n x 2n characteristic matrix of eq. protocolss, which never looks at
the eigenvalues.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from delayform.characteristic import (
    CharacteristicFactor,
    TwoDelayQuasiPolynomial,
    characteristic_matrix,
    factors,
    full_characteristic,
    product_of_factors,
)
from delayform.errors import (
    DelayError,
    GainError,
    NeutralQuasiPolynomialError,
    QuasiPolynomialError,
)
from delayform.topology import Topology, complete, paper_six, random_digraph, ring, star


def _relative_gap(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b) / np.abs(b)))


def _random_s(rng: np.random.Generator, k: int = 6) -> np.ndarray:
    return rng.uniform(-2, 2, k) + 1j * rng.uniform(-4, 4, k)


def _check_factorization(t: Topology, P: float, D: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    s = _random_s(rng)
    tau1, tau2 = rng.uniform(0, 5, 2)
    fs = factors(t, P, D)
    assert sum(f.order * f.multiplicity for f in fs) == 2 * t.n
    got = product_of_factors(fs, s, tau1, tau2)
    want = full_characteristic(t, P, D, s, tau1, tau2)
    assert _relative_gap(got, want) < 1e-9


@given(
    n=st.integers(2, 40),
    p=st.floats(0.0, 0.6),
    seed=st.integers(0, 2**31),
    P=st.floats(0.05, 20),
    D=st.floats(0.05, 20),
)
def test_product_of_factors_is_the_determinant_random_digraphs(n, p, seed, P, D):
    _check_factorization(random_digraph(n, p, seed), P, D, seed)


@pytest.mark.parametrize(
    "t",
    [
        paper_six(),
        complete(2),
        complete(7),
        complete(25),  # one eigenvalue of multiplicity 24
        ring(5),
        ring(16),
        star(9),  # eigenvalue 0 of multiplicity 7
        # non-diagonalizable: 0 in a Jordan block of size 3
        Topology.from_edges([(0, 1), (1, 0), (1, 2), (2, 3), (3, 4)]),
        # non-diagonalizable with a non-zero defective eigenvalue: two chains off a ring
        Topology.from_edges([(0, 1), (1, 2), (2, 0), (2, 3), (3, 4), (2, 5), (5, 6), (6, 7)]),
    ],
    ids=lambda t: t.name if t.name != "custom" else f"custom{t.n}",
)
def test_product_of_factors_is_the_determinant_special(t):
    for seed in range(5):
        _check_factorization(t, 1.3, 0.7, seed)


def test_paper_factors_are_the_equations_of_the_paper():
    P, D = 1.0, 0.5
    fs = factors(paper_six(), P, D)
    rng = np.random.default_rng(3)
    s = _random_s(rng)
    t1, t2 = 0.8, 1.7
    e1, e2 = np.exp(-t1 * s), np.exp(-t2 * s)
    for f in fs:
        lam = f.lam
        if f.order == 2:  # eq. factorized, first product
            want = s**2 + D * s + P - lam.real * (D * s * e2 + P * e1)
        else:  # eq. factorized, second product
            want = (
                s**4 + 2 * D * s**3 + (D**2 + 2 * P) * s**2 + 2 * D * P * s + P**2
                - 2 * lam.real * (s**2 + D * s + P) * (D * s * e2 + P * e1)
                + abs(lam) ** 2 * (D * s * e2 + P * e1) ** 2
            )
        np.testing.assert_allclose(f.evaluate(s, t1, t2), want, rtol=1e-13)
    centroid = fs[0]
    assert centroid.is_centroid
    np.testing.assert_allclose(centroid.evaluate(0.0, [0.1, 3.0, 7.0], [5.0, 0.2, 0.0]), 0.0, atol=1e-15)


def test_state_matrices_realise_each_factor():
    """eq. subsystems with eq. matrices2 / matrices4 have the factor as characteristic function."""
    rng = np.random.default_rng(11)
    for f in factors(paper_six(), 2.0, 0.3):
        A, B1, B2 = f.state_matrices()
        assert A.shape == (f.order, f.order)
        for s in _random_s(rng, 3):
            t1, t2 = rng.uniform(0, 4, 2)
            M = s * np.eye(f.order) - A - B1 * np.exp(-s * t1) - B2 * np.exp(-s * t2)
            assert abs(np.linalg.det(M) - f.evaluate(s, t1, t2)) <= 1e-11 * abs(np.linalg.det(M))


@given(
    coeffs=st.lists(
        st.lists(st.complex_numbers(max_magnitude=5, allow_nan=False, allow_infinity=False), min_size=1, max_size=4),
        min_size=6,
        max_size=6,
    ),
    s=st.complex_numbers(max_magnitude=3, allow_nan=False, allow_infinity=False),
    tau1=st.floats(0, 4),
    tau2=st.floats(0, 4),
)
def test_derivatives_match_finite_differences(coeffs, s, tau1, tau2):
    qp = TwoDelayQuasiPolynomial([*coeffs[0], 1.0], *coeffs[1:])  # a leading 1 keeps g1 non-zero
    h = 1e-6
    fd_s = (qp.evaluate(s + h, tau1, tau2) - qp.evaluate(s - h, tau1, tau2)) / (2 * h)
    # Rounding in the central difference is eps x (the size of the terms, not of their sum) / h,
    # and cancellation can make the sum far smaller than its terms: scale by the terms.
    terms = sum(np.polynomial.polynomial.polyval(abs(s), np.abs(c)) * (1 + abs(s)) * abs(np.exp(-(a * tau1 + b * tau2) * s))
                * (1 + a * tau1 + b * tau2) for c, a, b in qp.terms())  # fmt: skip
    scale = 1 + np.abs(qp.evaluate(s, tau1, tau2)) + np.abs(fd_s) + terms
    assert abs(qp.derivative(s, tau1, tau2) - fd_s) <= 1e-5 * scale
    t1p, t1m = tau1 + h, max(tau1 - h, 0.0)
    fd_t1 = (qp.evaluate(s, t1p, tau2) - qp.evaluate(s, t1m, tau2)) / (t1p - t1m)
    assert abs(qp.delay_derivative(s, tau1, tau2, delay=1) - fd_t1) <= 1e-5 * scale
    t2p, t2m = tau2 + h, max(tau2 - h, 0.0)
    fd_t2 = (qp.evaluate(s, tau1, t2p) - qp.evaluate(s, tau1, t2m)) / (t2p - t2m)
    assert abs(qp.delay_derivative(s, tau1, tau2, delay=2) - fd_t2) <= 1e-5 * scale


def test_root_tendency_of_a_single_delay_factor():
    # s + a e^{-tau s}: crossing at omega = a, tau = pi/(2a), always destabilising (Re ds/dtau > 0)
    a = 2.0
    qp = TwoDelayQuasiPolynomial([0, 1], [a])
    tau = np.pi / (2 * a)
    assert abs(qp.evaluate(1j * a, tau, 0.0)) < 1e-12
    assert qp.root_tendency(a, tau, 0.0, delay=1) == 1
    assert qp.root_tendency(a, tau, 0.0, delay=2) == 0


def test_quasi_polynomial_structure():
    qp = TwoDelayQuasiPolynomial([1, 2, 1, 0, 0], [3], [0, 1])
    assert qp.degree == 2 and qp.is_retarded and qp.is_real
    np.testing.assert_array_equal(qp.delay_free(), [4, 3, 1])
    assert len(qp.terms()) == 3
    assert "e^{-tau1 s}" in qp.describe()
    neutral = TwoDelayQuasiPolynomial([1, 1], [0, 0.5])
    assert not neutral.is_retarded
    with pytest.raises(NeutralQuasiPolynomialError, match="neutral"):
        neutral.require_retarded()
    assert not TwoDelayQuasiPolynomial([1, 1j]).is_real


@pytest.mark.parametrize(
    "args",
    [([],), ([0, 0],), ([1, np.inf],), ([[1, 2], [3, 4]],), (["a"],), ([1, 1], [np.nan])],
)
def test_bad_quasi_polynomial(args):
    with pytest.raises(QuasiPolynomialError):
        TwoDelayQuasiPolynomial(*args)


@pytest.mark.parametrize("P, D", [(0, 1), (-1, 1), (1, 0), (1, -2), (np.nan, 1), (1, np.inf), ("1", 1), (True, 1)])
def test_bad_gains(P, D):
    with pytest.raises(GainError):
        factors(paper_six(), P, D)
    with pytest.raises(GainError):
        full_characteristic(paper_six(), P, D, 1j, 0.1, 0.1)


@pytest.mark.parametrize("tau1, tau2", [(-0.1, 1), (1, -1e-9), (np.nan, 1), (1, np.inf), ([0.1, -1], 0)])
def test_bad_delays(tau1, tau2):
    f = factors(paper_six(), 1, 0.5)[1]
    with pytest.raises(DelayError):
        f.evaluate(1j, tau1, tau2)
    with pytest.raises(DelayError):
        characteristic_matrix(paper_six(), 1, 0.5, 1j, tau1, tau2)


def test_factor_describes_itself():
    fs = factors(paper_six(), 1, 0.5)
    assert "centroid" in fs[0].describe()
    assert "+-" in fs[-1].describe() and "order 4" in fs[-1].describe()
    assert isinstance(fs[0], CharacteristicFactor)


def test_root_tendency_is_zero_where_a_root_only_touches_the_axis():
    # lam = -1 at tau1 = 0: s^2 + D s + 2P + D s e^{-tau2 s} has s = j sqrt(2P) at tau2 = pi/sqrt(2P),
    # where ds/dtau2 = D omega^2 / (j omega (2 + D tau2)) is purely imaginary.
    P, D = 1.0, 0.5
    qp = TwoDelayQuasiPolynomial([P, D, 1.0], [P], [0.0, D])
    omega = np.sqrt(2 * P)
    tau2 = np.pi / omega
    assert abs(qp.evaluate(1j * omega, 0.0, tau2)) < 1e-12
    assert qp.root_tendency(omega, 0.0, tau2, delay=2) == 0
    assert qp.root_tendency(omega, 0.0, tau2, delay=1) != 0
