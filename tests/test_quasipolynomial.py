"""QuasiPolynomial: validation, evaluation, derivatives, and the expansion of matrix DDEs.

Independent references: numpy.linalg.det of the characteristic matrix at
random points (for from_matrices), the paper's TwoDelayQuasiPolynomial (for
the conversion), Cauchy-integral derivatives (for derivative), and
hand-expanded determinants.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import delayform
from delayform.characteristic import TwoDelayQuasiPolynomial, factors
from delayform.errors import NeutralQuasiPolynomialError, QuasiPolynomialError
from delayform.quasipolynomial import QuasiPolynomial
from delayform.topology import paper_six


def _det(A0, A, B, s, taus):
    """det(s (I - sum B_k z_k) - A0 - sum A_k z_k) by numpy at each s (the independent reference)."""
    s = np.asarray(s, dtype=complex)
    n = A0.shape[0]
    M = s[:, None, None] * np.eye(n) - A0
    for Ak, Bk, tau in zip(A, B, taus, strict=True):
        z = np.exp(-tau * s)[:, None, None]
        M = M - Ak * z - s[:, None, None] * z * Bk
    return np.linalg.det(M)


def test_exported_lazily():
    assert delayform.QuasiPolynomial is QuasiPolynomial


def test_structure_and_value():
    q = QuasiPolynomial({(0, 0, 0): [2.0, 0.0, 1.0], (1, 0, 0): [0.0, 3.0], (0, 2, 1): [1.0]})
    assert (q.n_delays, q.degree, q.is_neutral, q.is_retarded, q.is_real) == (3, 2, False, True, True)
    s, taus = 0.3 - 0.7j, (0.4, 1.1, 0.25)
    by_hand = (2 + s**2) + 3 * s * np.exp(-0.4 * s) + np.exp(-(2 * 1.1 + 0.25) * s)
    assert complex(q.evaluate(s, *taus)) == pytest.approx(by_hand, rel=1e-14)
    assert q.delays_of_terms(*taus)[(0, 2, 1)] == pytest.approx(2.45)
    np.testing.assert_allclose(q.delay_free(), [3.0, 3.0, 1.0])
    assert "tau1" in q.describe() and "2 tau2 + tau3" in q.describe()


def test_evaluate_broadcasts():
    q = QuasiPolynomial({(0,): [1.0, 1.0], (1,): [0.5]})
    s = np.linspace(-1, 1, 5)[:, None] + 1j
    tau = np.array([0.0, 0.5, 2.0])
    out = q.evaluate(s, tau)
    assert out.shape == (5, 3)
    np.testing.assert_allclose(out, s + 1 + 0.5 * np.exp(-tau * s), rtol=1e-14)


@pytest.mark.parametrize(
    ("terms", "match"),
    [
        ({}, "non-empty mapping"),
        ([1, 2], "non-empty mapping"),
        ({(1,): [1.0]}, "principal term"),
        ({(0,): [0.0]}, "principal term"),
        ({(0,): [1.0], (0, 1): [1.0]}, "same number of delays"),
        ({(0,): [1.0], (-1,): [1.0]}, "non-negative integers"),
        ({(0,): [1.0], (0.5,): [1.0]}, "non-negative integers"),
        ({0: [1.0]}, "tuple of delay multiples"),
        ({(0,): [1.0, np.nan]}, "not all finite"),
        ({(0,): [[1.0, 2.0]]}, "1-D"),
        ({(0,): ["a"]}, "sequence of numbers"),
        ({(0,): [1.0, 1.0], (1,): [0.0, 0.0, 1.0]}, "advanced type"),
    ],
)
def test_bad_terms_are_named(terms, match):
    with pytest.raises(QuasiPolynomialError, match=match):
        QuasiPolynomial(terms)


def test_wrong_number_of_delays_and_frozen():
    q = QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 1): [1.0]})
    with pytest.raises(QuasiPolynomialError, match="2 delay"):
        q.evaluate(0.0, 1.0)
    with pytest.raises(delayform.errors.DelayError):
        q.evaluate(0.0, 1.0, -1.0)
    with pytest.raises(AttributeError):
        q.terms = {}  # type: ignore[misc]
    with pytest.raises(TypeError):
        q.terms[(0, 0)] = [1.0]  # type: ignore[index]
    with pytest.raises(ValueError):
        q.terms[(0, 0)][0] = 2.0


def test_neutral_detected():
    q = QuasiPolynomial({(0, 0): [1.0, 1.0], (0, 1): [0.0, 0.5]})
    assert q.is_neutral
    with pytest.raises(NeutralQuasiPolynomialError, match=r"\(0, 1\)"):
        q.require_retarded()


@pytest.mark.parametrize("order", [1, 2, 3, 6])
def test_derivative_against_cauchy_integral(order):
    """d^k q / ds^k = k! / (2 pi i) \\oint q(z) / (z - s)^(k+1) dz, trapezoidal on a circle (spectrally exact)."""
    q = QuasiPolynomial({(0, 0): [1.0, -2.0, 0.5, 1.0], (1, 0): [0.3, 1.0], (2, 1): [-0.7]})
    s0, taus, r = 0.4 + 0.9j, (0.8, 0.35), 0.5
    theta = 2 * np.pi * np.arange(256) / 256
    z = s0 + r * np.exp(1j * theta)
    cauchy = np.mean(q.evaluate(z, *taus) / (r * np.exp(1j * theta)) ** order) * np.prod(np.arange(1, order + 1))
    assert complex(q.derivative(s0, *taus, order=order)) == pytest.approx(cauchy, rel=1e-10)


def test_delay_derivative_against_difference():
    q = QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 0): [0.5], (1, 2): [0.0, 0.2]})
    s, t = 0.2 + 1.3j, (0.7, 0.4)
    h = 1e-6
    fd = (q.evaluate(s, t[0], t[1] + h) - q.evaluate(s, t[0], t[1] - h)) / (2 * h)
    assert complex(q.delay_derivative(s, *t, delay=2)) == pytest.approx(complex(fd), rel=1e-7)
    with pytest.raises(QuasiPolynomialError, match="from 1 to 2"):
        q.delay_derivative(s, *t, delay=3)


def test_two_delay_round_trip_on_the_paper_factors():
    for f in factors(paper_six(), 1.0, 0.5):
        q = QuasiPolynomial.from_two_delay(f)
        s = np.array([0.1 + 2j, -0.5 - 0.3j])
        np.testing.assert_allclose(q.evaluate(s, 0.4, 0.9), f.evaluate(s, 0.4, 0.9), rtol=1e-13)
        back = q.to_two_delay()
        assert isinstance(back, TwoDelayQuasiPolynomial)
        np.testing.assert_allclose(back.evaluate(s, 0.4, 0.9), f.evaluate(s, 0.4, 0.9), rtol=1e-13)
    with pytest.raises(QuasiPolynomialError, match="not among the six"):
        QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 2): [1.0]}).to_two_delay()


def test_from_matrices_scalar_and_hand_expanded():
    q = QuasiPolynomial.from_matrices([[0.0]], [[-1.0]])
    assert {k: c.real.tolist() for k, c in q.terms.items()} == {(0,): [0.0, 1.0], (1,): [1.0]}
    # Haag 2009 style: 2x2 with two delays, det by hand:
    # det([[s - a, -b z1], [-c z2, s - d]]) = s^2 - (a + d) s + a d - b c z1 z2
    a, b, c, d = -1.0, 2.0, 0.5, -3.0
    A0 = np.diag([a, d])
    A1 = np.array([[0.0, b], [0.0, 0.0]])
    A2 = np.array([[0.0, 0.0], [c, 0.0]])
    q = QuasiPolynomial.from_matrices(A0, A1, A2)
    assert set(q.terms) == {(0, 0), (1, 1)}
    np.testing.assert_allclose(q.terms[(0, 0)], [a * d, -(a + d), 1.0], rtol=1e-14)
    np.testing.assert_allclose(q.terms[(1, 1)], [-b * c], rtol=1e-14)


def test_from_matrices_neutral():
    # x' = -x + 0.5 x'(t - tau): (s + 1) - 0.5 s e^{-tau s}
    q = QuasiPolynomial.from_matrices([[-1.0]], [[0.0]], neutral=([[0.5]],))
    assert q.is_neutral
    np.testing.assert_allclose(q.terms[(1,)], [0.0, -0.5])


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        (([[1.0, 2.0]],), {}, "square"),
        (([[1.0]],), {}, "at least one delayed matrix"),
        (([[1.0]], [[1.0, 0.0], [0.0, 1.0]]), {}, "1 x 1 like A0"),
        (([[1.0]], [[np.inf]]), {}, "not finite"),
        (([[1.0]], [[1.0]]), {"neutral": ([[1.0]], [[1.0]])}, "one per delay"),
    ],
)
def test_from_matrices_bad_input(args, kwargs, match):
    with pytest.raises(QuasiPolynomialError, match=match):
        QuasiPolynomial.from_matrices(*args, **kwargs)


@settings(max_examples=30, deadline=None)
@given(
    n=st.integers(1, 4),
    m=st.integers(1, 4),
    seed=st.integers(0, 2**32 - 1),
    neutral=st.booleans(),
    scale=st.sampled_from([1e-3, 1.0, 50.0]),
)
def test_from_matrices_matches_numeric_determinant(n, m, seed, neutral, scale):
    """Random matrix DDEs with 1-4 delays: the expansion equals numpy's determinant at random points."""
    rng = np.random.default_rng(seed)
    A0 = scale * rng.normal(size=(n, n))
    A = [scale * rng.normal(size=(n, n)) * rng.integers(0, 2) for _ in range(m)]
    B = [0.3 * rng.normal(size=(n, n)) for _ in range(m)] if neutral else [np.zeros((n, n))] * m
    q = QuasiPolynomial.from_matrices(A0, *A, neutral=tuple(B) if neutral else ())
    taus = rng.uniform(0.0, 2.0, size=m)
    s = scale * (rng.normal(size=6) + 1j * rng.normal(size=6))
    ref = _det(A0, A, B, s, taus)
    # both sides carry rounding of the size of the largest term of the expansion at s
    size = sum(np.abs(c[None, :]) @ (np.abs(s)[None, :] ** np.arange(c.size)[:, None])
               * np.exp(-np.dot(k, taus) * s.real) for k, c in q.terms.items()).ravel()  # fmt: skip
    np.testing.assert_array_less(np.abs(q.evaluate(s, *taus) - ref), 1e-10 * size + 1e-300)
    assert q.is_neutral == neutral  # random B_k: det(I - sum B_k z_k) has z-terms almost surely


def test_integer_matrices_give_integer_coefficients():
    rng = np.random.default_rng(3)
    A0, A1, A2 = (rng.integers(-5, 6, size=(4, 4)).astype(float) for _ in range(3))
    q = QuasiPolynomial.from_matrices(A0, A1, A2)
    for c in q.terms.values():
        np.testing.assert_array_equal(c.real, np.round(c.real))
        assert np.all(c.imag == 0.0)
    # the principal term is det(sI - A0): numpy.poly of A0 (eigenvalues) independently
    np.testing.assert_allclose(q.terms[(0, 0)].real, np.poly(A0)[::-1], atol=1e-9)
