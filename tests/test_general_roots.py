"""Roots of general quasi-polynomials: published examples, multiple roots, long delays (issue 19).

Every number is checked against a source or an independent method:

* published values (TDS-CONTROL manual, Mazanti et al. 2021, NLEVP `time_delay`);
* closed forms (Lambert W: scipy.special.lambertw);
* a Chebyshev discretization of the *matrix* DDE written here (not the
  package's companion realization), its eigenvalues polished by Newton's
  method on det M(s) itself (d det M / ds = det M tr(M^-1 M'));
* contour integrals of q'/q by the trapezoidal rule on circles.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import lambertw

from delayform import QuasiPolynomial, TwoDelayQuasiPolynomial, count_roots_right_of, rightmost_root, roots_in
from delayform.analysis.roots.single import relative_residual
from delayform.characteristic import characteristic_matrix, factors
from delayform.analysis.roots.dominant import dominant_root
from delayform.errors import DelayError, InputError, NeutralQuasiPolynomialError, QuasiPolynomialError
from delayform.topology import paper_six


# ============================================================ independent references
def _cheb(N: int) -> tuple[np.ndarray, np.ndarray]:
    """Chebyshev points and differentiation matrix (Trefethen, Spectral Methods in MATLAB, cheb.m)."""
    x = np.cos(np.pi * np.arange(N + 1) / N)
    c = np.hstack([2.0, np.ones(N - 1), 2.0]) * (-1.0) ** np.arange(N + 1)
    X = np.tile(x, (N + 1, 1)).T
    Dm = np.outer(c, 1.0 / c) / (X - X.T + np.eye(N + 1))
    return x, Dm - np.diag(Dm.sum(axis=1))


def _generator_roots(A0: np.ndarray, delayed: list[tuple[np.ndarray, float]], N: int) -> np.ndarray:
    """Eigenvalues of the collocated infinitesimal generator of x' = A0 x + sum A_k x(t - h_k)."""
    n = A0.shape[0]
    hmax = max(h for _, h in delayed)
    x, Dm = _cheb(N)
    theta = hmax * (x - 1.0) / 2.0  # [-hmax, 0], theta_0 = 0
    M = np.zeros(((N + 1) * n, (N + 1) * n))
    M[n:, :] = np.kron(2.0 / hmax * Dm[1:], np.eye(n))
    M[:n, :n] += A0
    for Ak, h in delayed:  # Lagrange basis at -h (barycentric weights of Chebyshev points)
        w = (-1.0) ** np.arange(N + 1) * np.hstack([0.5, np.ones(N - 1), 0.5])
        d = -h - theta
        if np.any(np.abs(d) < 1e-14):
            ell = (np.abs(d) < 1e-14).astype(float)
        else:
            ell = (w / d) / np.sum(w / d)
        M[:n, :] += np.kron(ell[None, :], Ak)
    return np.linalg.eigvals(M)


def _newton_det(A0: np.ndarray, delayed: list[tuple[np.ndarray, float]], s: complex) -> complex:
    """Newton's method on det(sI - A0 - sum A_k e^{-h_k s}); d det/ds = det * tr(M^-1 M')."""
    n = A0.shape[0]
    for _ in range(60):
        M = s * np.eye(n) - A0 - sum(Ak * np.exp(-h * s) for Ak, h in delayed)
        dM = np.eye(n) + sum(h * Ak * np.exp(-h * s) for Ak, h in delayed)
        try:
            step = 1.0 / np.trace(np.linalg.solve(M, dM))
        except np.linalg.LinAlgError:  # M singular to working precision: s is a root
            break
        s -= step
        if abs(step) < 1e-15 * (1 + abs(s)):
            break
    return complex(s)


def _contour_count(f, center: complex, radius: float, points: int = 4096) -> float:
    """(1 / 2 pi i) \\oint f'/f by the trapezoidal rule on a circle (f' by the Cauchy integral as well)."""
    th = 2 * np.pi * np.arange(points) / points
    z = center + radius * np.exp(1j * th)
    v = f(z)
    # arg increments summed around the circle: the winding number of f
    return float(np.sum(np.angle(np.roll(v, -1) / v)) / (2 * np.pi))


# ============================================================ TDS-CONTROL manual, Example 2.1
# Appeltans, Silm, Michiels, TDS-CONTROL manual (KU Leuven, 2022), Ex. 2.1:
# x' = A0 x + A1 x(t - 1); published rightmost root 0.6176424667764324.
TDS_A0 = np.array([[-1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, -10, -4], [0, 0, 4, -10]])
TDS_A1 = np.array([[3.0, 3, 3, 3], [0, -1.5, 0, 0], [0, 0, 3, -5], [0, 5, 5, 5]])
TDS_RIGHTMOST = 0.6176424667764324


def test_tds_control_example_2_1_published_rightmost_root() -> None:
    q = QuasiPolynomial.from_matrices(TDS_A0, TDS_A1)
    r = rightmost_root(q, 1.0)
    assert r.imag == 0.0
    assert r.real == pytest.approx(TDS_RIGHTMOST, abs=1e-9)
    # independent: this file's discretization of the 4 x 4 DDE, polished on det M(s)
    eig = _generator_roots(TDS_A0, [(TDS_A1, 1.0)], 40)
    ref = _newton_det(TDS_A0, [(TDS_A1, 1.0)], complex(eig[np.argmax(eig.real)]))
    assert abs(r - ref) < 1e-9
    # and the certificate: one root right of 0.6, none right of 0.62
    assert count_roots_right_of(q, 1.0, 0.6) == 1
    assert count_roots_right_of(q, 1.0, 0.62) == 0


# ============================================================ Mazanti, Boussaada & Niculescu 2021
def _mazanti(kappa: float = 1.964, k: float = -0.67036, tau: float = 0.66) -> tuple[QuasiPolynomial, float]:
    """Prop. 6.1 of Mazanti, Boussaada, Niculescu, "Multiplicity-induced-dominancy for delay-differential
    equations of retarded type", J. Differential Equations 286 (2021) 84-118, eqs. (6.9)-(6.10):

    q(s) = s^3 + (2 omega xi + 1/kappa) s^2 + (omega^2 + 2 omega xi / kappa) s + omega^2 / kappa
           - (k omega^2 / kappa) (beta2 s^2 + beta1 s + beta0) e^{-tau s},

    parameters chosen so that s0 = r0 / tau - 1 / kappa, r0 = -3 - 9^(1/3) + 3^(1/3), is a root of
    multiplicity 6 (the largest possible, deg 3 + deg 2 + 1) and dominant.
    """
    r0 = -3.0 - 9.0 ** (1 / 3) + 3.0 ** (1 / 3)
    s0 = r0 / tau - 1.0 / kappa  # (6.10a)
    omega = math.sqrt(-kappa * (s0**3 + 9 / tau * s0**2 + 36 / tau**2 * s0 + 60 / tau**3))  # (6.10b)
    xi = -3 * s0 / (2 * omega) - 9 / (2 * omega * tau) - 1 / (2 * omega * kappa)  # (6.10c)
    e = math.exp(s0 * tau)
    beta0 = -3 * kappa * (s0**2 * tau**2 - 8 * s0 * tau + 20) * e / (k * omega**2 * tau**3)  # (6.10d)
    beta1 = 6 * kappa * (s0 * tau - 4) * e / (k * omega**2 * tau**2)  # (6.10e)
    beta2 = -3 * kappa * e / (k * omega**2 * tau)  # (6.10f)
    principal = [omega**2 / kappa, omega**2 + 2 * omega * xi / kappa, 2 * omega * xi + 1 / kappa, 1.0]
    delayed = [-k * omega**2 / kappa * b for b in (beta0, beta1, beta2)]
    return QuasiPolynomial({(0,): principal, (1,): delayed}), s0


def test_mazanti_six_fold_dominant_root() -> None:
    q, s0 = _mazanti()
    assert s0 == pytest.approx(-6.021, abs=5e-4)  # the published "near -6.021"
    # independent: q and its first five derivatives vanish at s0 (to rounding), the sixth does not
    for j in range(6):
        assert abs(complex(q.derivative(s0, 0.66, order=j))) < 1e-6 * (1 + abs(complex(q.derivative(s0, 0.66, order=6))))
    r = rightmost_root(q, 0.66)
    # multiplicity 6 in double precision: about eps^(1/6) ~ 2.5e-3 relative; the cluster's centre is closer
    assert r.imag == 0.0 and abs(r - s0) < 1e-3
    box = roots_in(q, 0.66, (-7.0, -5.0, -1.0, 1.0))
    assert box.size == 6 and np.all(box == box[0])
    assert count_roots_right_of(q, 0.66, s0 - 0.5) == 6  # dominant: the six, nothing else
    assert count_roots_right_of(q, 0.66, s0 + 0.05) == 0
    # the same through the paper's two-delay form (tau2 unused)
    q2 = TwoDelayQuasiPolynomial(q.terms[(0,)], q.terms[(1,)])
    assert abs(rightmost_root(q2, 0.66, 0.0) - r) < 1e-9
    assert _contour_count(lambda z: q.evaluate(z, 0.66), r, 0.3) == pytest.approx(6, abs=1e-6)


# ============================================================ Jarlebring & Michiels 2010 (NLEVP time_delay)
def _time_delay() -> QuasiPolynomial:
    """NLEVP `time_delay` (Betcke, Higham, Mehrmann, Schroder, Tisseur, ACM TOMS 39, 2013), from
    Jarlebring and Michiels, Automatica 46 (2010) 1112-1115 (b(2) as corrected there):
    -s I + A0 + A1 e^{-s} with companion A0, A1: double non-semisimple root 3 pi i at tau = 1."""
    pi = math.pi
    a1 = 2 * (65 * pi + 32) / (5 * (8 + 5 * pi))
    a2 = 9 * pi**2 * (13 + 5 * pi) / (8 + 5 * pi)
    a3 = 324 * pi**2 * (5 * pi + 4) / (5 * (8 + 5 * pi))
    b1 = (260 * pi + 128 + 225 * pi**2) / (10 * (8 + 5 * pi))
    b2 = 45 * pi**2 / (8 + 5 * pi)
    b3 = 81 * pi**2 * (40 * pi + 32 + 25 * pi**2) / (10 * (8 + 5 * pi))
    A0 = np.array([[0, 1, 0], [0, 0, 1], [-a3, -a2, -a1]])
    A1 = np.array([[0, 0, 0], [0, 0, 0], [-b3, -b2, -b1]])
    return QuasiPolynomial.from_matrices(A0, A1)


def test_time_delay_double_root_and_simple_root() -> None:
    q = _time_delay()
    roots = roots_in(q, 1.0, (-0.5, 0.5, 5.0, 15.0))
    assert roots.size == 3
    double = roots[np.abs(roots - 3j * math.pi) < 1e-6]
    assert double.size == 2 and np.all(double == double[0])  # one point, multiplicity 2
    assert abs(double[0] - 3j * math.pi) < 1e-7  # about sqrt(eps) for a double root
    simple = roots[np.abs(roots - 4.5j * math.pi) < 1e-6]
    assert simple.size == 1 and abs(simple[0] - 4.5j * math.pi) < 1e-9
    # independent: winding numbers on small circles
    f = lambda z: q.evaluate(z, 1.0)  # noqa: E731
    assert _contour_count(f, 3j * math.pi, 0.1) == pytest.approx(2, abs=1e-6)
    assert _contour_count(f, 4.5j * math.pi, 0.1) == pytest.approx(1, abs=1e-6)


# ============================================================ long delays (no reach limit)
@pytest.mark.parametrize("tau", [0.5, 50.0, 200.0])
def test_lambert_w_closed_form_at_long_delays(tau: float) -> None:
    """s = a + b e^{-tau s}: roots a + W_k(tau b e^{-a tau}) / tau; the rightmost is k = 0
    (Shinozaki and Mori, Automatica 42, 2006)."""
    a, b = -1.0, -0.5
    q = QuasiPolynomial({(0,): [-a, 1.0], (1,): [-b]})
    ref = a + complex(lambertw(tau * b * math.exp(-a * tau), 0)) / tau
    r = rightmost_root(q, tau)
    assert abs(r.real - ref.real) < 1e-9 and abs(r.imag - abs(ref.imag)) < 1e-9


def test_paper_team_at_stiff_gains_and_long_delays() -> None:
    """The paper's six robots at P = 20, D = 0.01, delays 4.7 s (refused before issue 19)."""
    P, D, tau = 20.0, 0.01, 4.7
    dom = dominant_root(paper_six(), P, D, tau, tau)
    # independent: the whole 12-state DDE discretized here, polished on det of eq. protocolss's matrix
    top = paper_six()
    C = top.C_sparse.toarray()
    A0 = np.kron(np.eye(top.n), [[0.0, 1.0], [-P, -D]])
    A1 = np.kron(C, [[0.0, 0.0], [P, 0.0]])
    A2 = np.kron(C, [[0.0, 0.0], [0.0, D]])
    eig = _generator_roots(A0, [(A1, tau), (A2, tau)], 90)
    eig = eig[np.abs(eig) > 1e-6]  # the centroid's persistent zero
    seeds = eig[np.argsort(-eig.real)[:6]]
    polished = [_newton_det(A0, [(A1, tau), (A2, tau)], complex(s)) for s in seeds]
    best = max(polished, key=lambda z: z.real)
    assert abs(dom.root.real - best.real) < 1e-9 and abs(dom.root.imag - abs(best.imag)) < 1e-9
    M = characteristic_matrix(top, P, D, dom.root, tau, tau)
    sv = np.linalg.svd(M, compute_uv=False)
    assert sv[-1] < 1e-9 * sv[0]


# ============================================================ properties
@settings(max_examples=12)
@given(n=st.integers(1, 3), m=st.integers(1, 4), seed=st.integers(0, 2**31 - 1))
def test_random_matrix_ddes_roots_satisfy_the_determinant(n: int, m: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    A0 = rng.normal(size=(n, n)) - np.eye(n)
    A = [0.6 * rng.normal(size=(n, n)) for _ in range(m)]
    taus = tuple(float(t) for t in rng.uniform(0.05, 2.0, size=m))
    q = QuasiPolynomial.from_matrices(A0, *A)
    r = rightmost_root(q, *taus)
    M = r * np.eye(n) - A0 - sum(Ak * np.exp(-t * r) for Ak, t in zip(A, taus, strict=True))
    sv = np.linalg.svd(M, compute_uv=False)
    assert sv[-1] <= 1e-8 * max(1.0, sv[0])
    assert count_roots_right_of(q, *taus, r.real + 1e-6 * (1 + abs(r))) == 0
    # the same root from this file's discretization of the matrices, polished on the determinant
    eig = _generator_roots(A0, list(zip(A, taus, strict=True)), 48)
    ref = _newton_det(A0, list(zip(A, taus, strict=True)), complex(eig[np.argmax(eig.real)]))
    assert ref.real <= r.real + 1e-8


@settings(max_examples=8)
@given(s0=st.floats(-2.0, 1.0), h=st.floats(0.1, 3.0), b0=st.floats(-2.0, 2.0), b1=st.floats(0.2, 2.0),
       a2=st.floats(-2.0, 2.0))  # fmt: skip
def test_double_roots_built_on_purpose(s0: float, h: float, b0: float, b1: float, a2: float) -> None:
    """q = s^3 + a2 s^2 + a1 s + a0 + (b0 + b1 s) e^{-h s} with a1, a0 solved so that q(s0) = q'(s0) = 0."""
    e = math.exp(-h * s0)
    p1, dp1 = b0 + b1 * s0, b1
    # q'(s0) = 3 s0^2 + 2 a2 s0 + a1 + (dp1 - h p1) e = 0;  q(s0) = s0^3 + a2 s0^2 + a1 s0 + a0 + p1 e = 0
    a1 = -(3 * s0**2 + 2 * a2 * s0 + (dp1 - h * p1) * e)
    a0 = -(s0**3 + a2 * s0**2 + a1 * s0 + p1 * e)
    q = QuasiPolynomial({(0,): [a0, a1, a2, 1.0], (1,): [b0, b1]})
    second = abs(complex(q.derivative(s0, h, order=2)))
    if second < 1e-3 * (1 + abs(s0)) ** 3:
        return  # a triple root by accident: not this property's case
    box = (s0 - 0.05, s0 + 0.05, -0.05, 0.05)
    n = _contour_count(lambda z: q.evaluate(z, h), s0, 0.04)
    roots = roots_in(q, h, box)
    assert roots.size == round(n) >= 2
    near = roots[np.abs(roots - s0) < 1e-5]
    assert near.size == 2 and np.all(near == near[0])
    assert abs(near[0] - s0) < 1e-6
    assert np.all(relative_residual(q, near, h) <= 1e-10)


# ============================================================ messages
def test_messages_name_what_was_given() -> None:
    q = QuasiPolynomial({(0, 0, 0): [1.0, 1.0], (1, 0, 0): [0.5], (0, 1, 2): [0.2]})
    with pytest.raises(InputError, match=r"rightmost_root\(qp, tau1, tau2, tau3\)"):
        rightmost_root(q, 1.0, 2.0)
    with pytest.raises(DelayError, match="tau3"):
        rightmost_root(q, 1.0, 2.0, -1.0)
    with pytest.raises(InputError, match="region"):
        roots_in(q, 1.0, 2.0, 3.0, (0.0, -1.0, 0.0, 1.0))
    with pytest.raises(InputError, match="Re s = c"):
        count_roots_right_of(q, 1.0, 2.0, 3.0, float("nan"))
    neutral = QuasiPolynomial({(0,): [1.0, 1.0], (1,): [0.0, 0.5]})
    with pytest.raises(NeutralQuasiPolynomialError, match="neutral"):
        rightmost_root(neutral, 1.0)
    with pytest.raises(InputError, match="QuasiPolynomial"):
        rightmost_root([1.0, 2.0], 1.0)  # type: ignore[arg-type]
    with pytest.raises(QuasiPolynomialError) as info:
        TwoDelayQuasiPolynomial([1.0, np.inf])
    assert "gain" not in str(info.value)
    # a delay beyond the machine's budget is refused in one line naming the delays
    with pytest.raises(DelayError, match=r"delays up to 1e\+06 s are too long"):
        rightmost_root(QuasiPolynomial({(0,): [1.0, 1.0], (1,): [0.5]}), 1e6)


def test_three_delays_agree_with_the_two_delay_form() -> None:
    """tau3 = 0 merges into the principal term; (1,1,0) with tau = (t1, t2, 0) is the paper's g6 term."""
    f = factors(paper_six(), 1.0, 0.5)[1]
    g = f.quasi_polynomial
    q3 = QuasiPolynomial({(a, b, 0): c for c, a, b in g.terms()} | {(0, 0, 1): [0.3]})
    shifted = TwoDelayQuasiPolynomial(g.g1 + np.array([0.3, 0, 0]), g.g2, g.g3, g.g4, g.g5, g.g6)
    assert abs(rightmost_root(q3, 0.7, 1.1, 0.0) - rightmost_root(shifted, 0.7, 1.1)) < 1e-10
    assert abs(rightmost_root(QuasiPolynomial.from_two_delay(g), 0.7, 1.1) - rightmost_root(g, 0.7, 1.1)) < 1e-10
