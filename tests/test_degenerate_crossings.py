"""Degenerate crossings (issue 19, item 3): multiple imaginary roots and roots that touch the axis.

Every NU of the CTCR map is checked against an independent argument-principle
count (:mod:`ref_roots_ctcr`: the winding of a determinant or of q sampled on
a half-disk, nothing of the curves or root tendencies).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from delayform.analysis.ctcr.degenerate import crossing_changes, degenerate_mask, local_change
from delayform.analysis.ctcr.stability_map import crossing_map
from delayform.characteristic import TwoDelayQuasiPolynomial
from ref_roots_ctcr import coefficient_bound, count_unstable, count_unstable_function

PI = np.pi


def _jarlebring_michiels() -> tuple[np.ndarray, np.ndarray]:
    """A0, A1 of the ``time_delay`` problem of NLEVP (Betcke et al. 2013), from Jarlebring & Michiels,
    Automatica 46 (2010) 1112-1115, with b2 as corrected there: x' = A0 x + A1 x(t - tau)."""
    a = [2 * (65 * PI + 32) / (5 * (8 + 5 * PI)), 9 * PI**2 * (13 + 5 * PI) / (8 + 5 * PI),
         324 * PI**2 * (5 * PI + 4) / (5 * (8 + 5 * PI))]
    b = [(260 * PI + 128 + 225 * PI**2) / (10 * (8 + 5 * PI)), 45 * PI**2 / (8 + 5 * PI),
         81 * PI**2 * (40 * PI + 32 + 25 * PI**2) / (10 * (8 + 5 * PI))]
    A0 = np.array([[0, 1, 0], [0, 0, 1], [-a[2], -a[1], -a[0]]], float)
    A1 = np.array([[0, 0, 0], [0, 0, 0], [-b[2], -b[1], -b[0]]], float)
    return A0, A1


def _jm_quasi_polynomial() -> TwoDelayQuasiPolynomial:
    # det(sI - A0 - A1 z) of the companion form: s^3 + (a1 + b1 z) s^2 + (a2 + b2 z) s + a3 + b3 z
    A0, A1 = _jarlebring_michiels()
    return TwoDelayQuasiPolynomial((-A0[2]).tolist() + [1.0], (-A1[2]).tolist())


def test_jarlebring_michiels_double_root_is_where_published():
    q = _jm_quasi_polynomial()
    # the published double non-semisimple root 3 pi j at tau = 1 and the simple one at 4.5 pi j
    assert abs(q.evaluate(3j * PI, 1.0, 0.0)) < 1e-10
    assert abs(q.derivative(3j * PI, 1.0, 0.0)) < 1e-10 * 100
    assert degenerate_mask(q, np.array([3 * PI]), np.array([1.0]), np.array([0.0]))[0]
    assert abs(q.evaluate(4.5j * PI, 1.0, 0.0)) < 1e-10
    assert not degenerate_mask(q, np.array([4.5 * PI]), np.array([1.0]), np.array([0.0]))[0]


def test_jarlebring_michiels_map_agrees_with_independent_count():
    """The map's NU on both sides of every crossing of 3 pi j (double at tau = 1, touching at 1/3, 5/3, 7/3)."""
    A0, A1 = _jarlebring_michiels()
    q = _jm_quasi_polynomial()
    m = crossing_map(q, 3.0, 1.0)
    points = [0.05, 0.2, 0.45, 0.8, 1.2, 1.3, 1.6, 2.0, 2.2, 2.5, 2.9]
    # a touching root leaves the axis like (tau - c)^2, the double one like sqrt(tau - 1)
    for c in (1 / 3, 5 / 3, 7 / 3):
        points += [c - 1e-2, c + 1e-2, c - 1e-3, c + 1e-3]
    points += [1 - 1e-3, 1 + 1e-3, 1 - 3e-6, 1 + 3e-6]
    tau = np.array(sorted(points))
    ref, uncertain = count_unstable(A0, A1, np.zeros((3, 3)), tau, np.zeros_like(tau))
    assert not uncertain.any()
    got = m.unstable_count(tau, 0.5)
    np.testing.assert_array_equal(got, ref)
    # for tau > 1 the double crossing adds nothing (the first-order rule said -2)
    assert int(m.unstable_count(1.2, 0.5)) == int(m.unstable_count(0.8, 0.5)) + 2


def test_local_change_of_the_double_and_touching_roots():
    q = _jm_quasi_polynomial()
    assert local_change(q, 3 * PI, 1.0, 0.0, delay=1) == 0
    for tau in (1 / 3, 5 / 3, 7 / 3):
        assert local_change(q, 3 * PI, tau, 0.0, delay=1) == 0
    # a simple transversal crossing: the count agrees with sgn Re ds/dtau
    assert local_change(q, 4.5 * PI, 1.0, 0.0, delay=1) == 1
    assert crossing_changes(q, np.array([4.5 * PI]), np.array([1.0]), np.array([0.0]), delay=1)[0] == 1


def _double_root_qp(seed: int, omega: float, tau1: float, tau2: float, *, two: bool) -> TwoDelayQuasiPolynomial:
    """Random real q = p0 + p1 z1 + p2 z2 with q(j omega) = q'(j omega) = 0 at (tau1, tau2), built on purpose.

    p1, p2 and the top coefficients of p0 are random; p0's four lowest
    coefficients solve the four real linear equations of the two conditions.
    """
    rng = np.random.default_rng(seed)
    n = 5
    p1 = rng.normal(size=3)
    p2 = rng.normal(size=3) * 0.5 * two
    top = np.concatenate([rng.normal(size=n - 4), [1.0]])
    s = 1j * omega
    e1, e2 = np.exp(-tau1 * s), np.exp(-tau2 * s)
    pv = np.polynomial.polynomial.polyval
    der = np.polynomial.polynomial.polyder
    # delayed part of q and of q' at s
    d0 = pv(s, p1) * e1 + pv(s, p2) * e2
    d1 = (pv(s, der(p1)) - tau1 * pv(s, p1)) * e1 + (pv(s, der(p2)) - tau2 * pv(s, p2)) * e2
    t0 = sum(top[k] * s ** (k + 4) for k in range(top.size))
    t1 = sum((k + 4) * top[k] * s ** (k + 3) for k in range(top.size))
    rows = np.array([[s**i for i in range(4)], [i * s ** (i - 1) if i else 0 for i in range(4)]])
    rhs = np.array([-(d0 + t0), -(d1 + t1)])
    M = np.vstack([rows.real, rows.imag])
    c = np.linalg.solve(M, np.concatenate([rhs.real, rhs.imag]))
    return TwoDelayQuasiPolynomial(np.concatenate([c, top]), p1, p2)


def _reference(q: TwoDelayQuasiPolynomial, t1: np.ndarray, t2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    coeffs = [np.asarray(c) if np.size(c) else np.zeros(1) for c in q.coefficients]

    def f(s, a, b):
        pv = np.polynomial.polynomial.polyval
        return pv(s, coeffs[0]) + pv(s, coeffs[1]) * np.exp(-a * s) + pv(s, coeffs[2]) * np.exp(-b * s)

    R = 1.05 * coefficient_bound([c for c in coeffs if c.size]) + 1.0
    return count_unstable_function(f, R, t1, t2)


@pytest.mark.parametrize(("seed", "two"), [(1, True), (2, True), (3, True), (4, False), (5, False), (6, False)])
def test_random_double_roots_counted_right(seed, two):
    """One delay: every horizontal path meets the double root; two delays: the paths through the point."""
    omega, tau1, tau2 = 1.3, 1.1, 0.7
    q = _double_root_qp(seed, omega, tau1, tau2, two=two)
    s = 1j * omega
    assert abs(q.evaluate(s, tau1, tau2)) < 1e-9 and abs(q.derivative(s, tau1, tau2)) < 1e-9
    m = crossing_map(q, 2.5, 2.0)
    # on the line through the double point, just either side of it, and around it
    x = np.array([tau1 - 1e-2, tau1 - 1e-4, tau1 + 1e-4, tau1 + 1e-2, 0.3, 2.2])
    xs, ys = np.meshgrid(x, [tau2 - 1e-3, tau2, tau2 + 1e-3])
    ref, uncertain = _reference(q, xs.ravel(), ys.ravel())
    got = m.unstable_count(xs.ravel(), ys.ravel())
    keep = ~uncertain
    assert keep.sum() >= 12
    np.testing.assert_array_equal(got[keep], ref[keep])


@settings(max_examples=6, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), omega=st.floats(0.5, 3.0), tau=st.floats(0.4, 1.6))
def test_property_built_double_roots_one_delay(seed, omega, tau):
    """Any one-delay real qp with q = q' = 0 at (j omega, tau): NU right on both sides of the double crossing."""
    q = _double_root_qp(seed, omega, tau, 0.0, two=False)
    m = crossing_map(q, 2.0, 1.0)
    x = np.array([tau - 1e-3, tau + 1e-3, tau - 0.05, tau + 0.05])
    ref, uncertain = _reference(q, x, np.full(x.size, 0.5))
    got = m.unstable_count(x, 0.5)
    np.testing.assert_array_equal(got[~uncertain], ref[~uncertain])
