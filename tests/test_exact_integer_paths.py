"""The exact re-check's integer shortcuts against plain Fraction arithmetic.

The interval functional's derivative bound is summed in integers over one common denominator
(krasovskii._Sum) and the congruence X' M X of the fast positive-definiteness test is formed over
the triangle of X (lmi._upper_congruence). Both must give exactly what Fraction arithmetic gives,
and the test built on them must reject a matrix that misses positive definiteness by a hair.
"""

from __future__ import annotations

import random
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import delayform.analysis.certificates.intervals as intervals
from delayform.analysis.certificates.intervals import IntervalDelays, interval_delays
from delayform.analysis.certificates.krasovskii import _cross, _he, _Sum
from delayform.analysis.certificates.lmi import (
    LmiProblem,
    Variables,
    _integers,
    _upper_congruence,
    dominant_after_congruence,
    exact_check,
    leading_minors_positive,
)
from delayform.analysis.certificates.team import mode_system
from delayform.characteristic import factors
from delayform.topology import paper_six


class _FractionSum:
    """The reference: every term added as a Fraction matrix, one gcd per entry (what _Sum replaces)."""

    def __init__(self, size: int, exact: bool) -> None:
        assert exact
        self.M = np.zeros((size, size), dtype=object)

    def copy(self) -> _FractionSum:
        out = _FractionSum.__new__(_FractionSum)
        out.M = self.M.copy()
        return out

    def add(self, coef, G, W, H=None, *, sym=False):
        term = _cross(G, W, G if H is None else H)
        self.M = self.M + Fraction(coef) * (_he(term) if sym else term)

    def add_terms(self, sign, terms, W):
        for c, G in terms:
            self.add(sign * c, G, W)

    def value(self, sign=1):
        return np.vectorize(lambda v: Fraction(sign * v), otypes=[object])(self.M)


def _fraction_matrix(rng: random.Random, rows: int, cols: int, zeros: float = 0.3) -> np.ndarray:
    # dyadic and non-dyadic rationals, some zeros (selections are mostly zeros)
    return np.array([[Fraction(rng.randint(-10**6, 10**6), rng.choice([1, 3, 2**40, 7 * 2**20]))
                      if rng.random() > zeros else 0 for _ in range(cols)] for _ in range(rows)], dtype=object)


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 9), st.integers(1, 4), st.integers(0, 2**31 - 1))
def test_integer_sum_equals_the_fraction_sum_on_random_matrices(size: int, n: int, seed: int) -> None:
    rng = random.Random(seed)
    exact, reference = _Sum(size, True), _FractionSum(size, True)
    floats = _Sum(size, False)
    naive = np.zeros((size, size))
    for _ in range(rng.randint(1, 6)):
        G, H, W = _fraction_matrix(rng, n, size), _fraction_matrix(rng, n, size), _fraction_matrix(rng, n, n, 0.0)
        coef, sym = Fraction(rng.randint(-9, 9), rng.choice([1, 3, 2**30])), rng.random() < 0.5
        exact.add(coef, G, W, H, sym=sym)
        reference.add(coef, G, W, H, sym=sym)
        Gf, Hf, Wf = (np.asarray(M, dtype=float) for M in (G, H, W))
        floats.add(float(coef), Gf, Wf, Hf, sym=sym)
        term = Gf.T @ Wf @ Hf
        naive = naive + float(coef) * (term + term.T if sym else term)
    for sign in (1, -1):
        assert np.array_equal(exact.value(sign), reference.value(sign))
    assert np.allclose(floats.value(), naive, rtol=1e-12, atol=1e-12 * (1 + np.abs(naive).max()))
    copy = exact.copy()
    copy.add(1, np.eye(size, dtype=object), np.eye(size, dtype=object))
    assert np.array_equal(exact.value(), reference.value())  # the copy is independent


@pytest.mark.parametrize("order, outer, centroid", [(1, False, False), (2, True, True), (3, True, False)])
def test_interval_functional_in_integers_equals_its_fraction_build(monkeypatch, order, outer, centroid):
    fs = factors(paper_six(), 1.0, 0.5)
    f = next(g for g in fs if g.is_centroid) if centroid else next(g for g in fs if abs(g.lam + 0.6368889) < 1e-6)
    A0, ak, e = mode_system(f)
    d = 0.0984
    data = IntervalDelays(A0, ak, (2.0 - d, 1.0 - d), (2.0 + d, 1.0 + d), None, e)
    problem = interval_delays(data, order, outer=outer)
    rng = np.random.default_rng(order)
    x = np.round(rng.standard_normal(problem.variables.size) * 2**40) / 2**40
    rational = np.array([Fraction(v) for v in x], dtype=object)
    fast = problem.build(problem.variables.unpack(rational), True)
    monkeypatch.setattr(intervals, "_Sum", _FractionSum)
    slow = problem.build(problem.variables.unpack(rational), True)
    assert fast.keys() == slow.keys()
    for name in fast:
        assert np.array_equal(fast[name], slow[name]), name


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 30), st.integers(0, 2**31 - 1))
def test_triangular_congruence_equals_the_full_product(m: int, seed: int) -> None:
    rng = random.Random(seed)
    X = np.array([[rng.randint(-2**80, 2**80) if j >= i else 0 for j in range(m)] for i in range(m)], dtype=object)
    A = np.array([[rng.randint(-2**300, 2**300) for _ in range(m)] for _ in range(m)], dtype=object)
    M = A + A.T
    assert np.array_equal(_upper_congruence(X, M), X.T @ M @ X)


def _single(M: np.ndarray) -> LmiProblem:
    """A problem whose only LMI is the fixed matrix M (in Fractions when exact)."""
    var = Variables()
    var.symmetric("unused", 1)
    return LmiProblem(var, lambda v, exact: {"M": M if exact else np.asarray(M, dtype=float)})


@pytest.mark.parametrize("m, seed", [(3, 0), (12, 1), (30, 2), (44, 3)])
def test_a_matrix_short_of_positive_definite_by_a_hair_is_rejected(m: int, seed: int) -> None:
    # S = B B' with B of rank m - 1 is singular exactly; S - eps I misses by eps = 2^-70 (invisible in
    # float64 next to entries of size 1), S + eps I is positive definite by as little
    rng = random.Random(seed)
    B = np.array([[Fraction(rng.randint(-2**20, 2**20), 2**20) for _ in range(m - 1)] for _ in range(m)], dtype=object)
    S = B @ B.T
    eps = Fraction(1, 2**70)
    eye = np.array([[Fraction(int(i == j)) for j in range(m)] for i in range(m)], dtype=object)
    below, above = S - eps * eye, S + eps * eye
    assert not dominant_after_congruence(below) and not leading_minors_positive(below)
    assert exact_check(_single(below), (Fraction(0),)) is False
    assert leading_minors_positive(above) and exact_check(_single(above), (Fraction(0),)) is True
    # clearly positive definite: the fast test proves it, as the minors do
    clear = S + eye
    assert dominant_after_congruence(clear) and leading_minors_positive(clear)
    # an asymmetric matrix is never called positive definite by the congruence test
    skew = clear.copy()
    skew[0, m - 1] += Fraction(1, 2**50)
    assert not dominant_after_congruence(skew) and not leading_minors_positive(skew)


def test_integer_conversion_is_exact() -> None:
    M = np.array([[Fraction(1, 3), 2, Fraction(-5, 2**60)], [0.5, True, Fraction(7, 6)]], dtype=object)
    Z = _integers(M)
    den = 3 * 2**60
    assert all(Fraction(int(Z[i, j]), den) == Fraction(M[i, j]) for i in range(2) for j in range(3))
    F = np.array([[0.1, -2.5e-300], [1e300, 0.0]])
    Zf = _integers(F)
    scale = Fraction(int(Zf[0, 0])) / Fraction(0.1)
    assert all(Fraction(int(Zf[i, j])) == Fraction(F[i, j]) * scale for i in range(2) for j in range(2))
