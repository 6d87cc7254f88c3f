"""The problem solved for roots: a quasi-polynomial, its DDE realization, evaluation and Newton polishing.

The root finders' own (method in the module docstring of
:mod:`delayform.analysis.roots.dominant`): the paper's eq. 5 terms, q and dq/ds
evaluated with broadcasting, Newton's method on q itself (Maehly's deflation
of the persistent root 0 of the paper's eq. 4) and the multiplicity of polished
roots. :data:`Terms`, :data:`Region` and :func:`evaluate` are public: the
neutral solver and the CTCR count at degenerate crossings evaluate
quasi-polynomials with them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import NDArray

from delayform.characteristic import CharacteristicFactor, TwoDelayQuasiPolynomial
from delayform.errors import InputError
from delayform.quasipolynomial import QuasiPolynomial

#: Acceptance threshold of the relative residual of a polished root.
RESIDUAL_TOL = 1e-10
#: Largest Chebyshev discretization degree tried before giving up.
MAX_DEGREE = 192
#: Settling time (2 % criterion) = ln(50) / |Re s_dom| ~ 3.9 time constants.

_NEWTON_MAXITER = 50
#: Delays below this seed Newton from the delay-free roots (a discretization of
#: [-h, 0] would overflow; the polishing and the certificate use the exact q).
_TINY_DELAY = 1e-10

#: A rectangle ``(x0, x1, y0, y1)`` of the complex plane: x0 <= Re s <= x1, y0 <= Im s <= y1.
Region = tuple[float, float, float, float]
#: A quasi-polynomial as the solvers evaluate it: terms ``(c, a, b)`` standing for
#: ``p(s) e^{-(a tau1 + b tau2) s}`` with ``p``'s coefficients ``c`` in increasing powers of s
#: (the principal term first, ``a = b = 0``); ``a`` and ``b`` may be any non-negative reals.
Terms = tuple[tuple[NDArray[np.complex128], int, int], ...]


# =====================================================================
# the problem: a quasi-polynomial and a DDE whose characteristic function it is
# =====================================================================
@dataclass(frozen=True, eq=False)
class _Problem:
    """What the solvers work on.

    ``terms`` is the quasi-polynomial polished and counted (paper, eq. 5
    terms as (coefficients, multiple of tau1, multiple of tau2)); ``A`` and
    ``delayed`` a DDE realization whose characteristic function is q up to a
    constant; ``mirror`` adds complex conjugates of the roots (a conjugate
    pair factor solved through its complex second-order factor of lam);
    ``deflate_zero`` removes the persistent root s = 0 of the paper's eq. 4.
    """

    terms: Terms
    A: NDArray[np.complex128]
    delayed: tuple[tuple[NDArray[np.complex128], int, int], ...]
    mirror: bool = False
    deflate_zero: bool = False
    #: scale of the rightmost roots when known (0: from A and the delayed matrices, generator._root_scale)
    scale: float = 0.0

    @property
    def degree(self) -> int:
        return int(self.terms[0][0].size - 1)

    @property
    def d(self) -> int:
        return int(self.A.shape[0])

    @property
    def is_real(self) -> bool:
        mats = [self.A] + [b for b, _, _ in self.delayed]
        return all(np.all(m.imag == 0.0) for m in mats)


def _problem_of_qp(qp: TwoDelayQuasiPolynomial) -> _Problem:
    """Companion-form DDE of a retarded quasi-polynomial (paper, eq. 5), balanced (:func:`_companion`)."""
    qp.require_retarded()
    terms = qp.terms()
    A, delayed = _companion(terms)
    return _Problem(terms=terms, A=A, delayed=delayed, scale=_polynomial_scale(terms))


def _problem_of_quasi(qp: QuasiPolynomial, taus: tuple[float, ...]) -> _Problem:
    """The problem of a :class:`QuasiPolynomial` at fixed delays, on the two-delay machinery.

    At fixed delays each term is p_k(s) e^{-h_k s} with h_k = k . tau; terms
    of equal h_k are summed (commensurate delays, or a zero delay merging
    into the principal term). The solvers evaluate ``a t1 + b t2`` as each
    term's delay: here ``a = h_k``, ``b = 0`` and they are called with
    ``t1 = 1``, ``t2 = 0`` (:data:`UNIT_DELAYS`).
    """
    qp.require_retarded()
    merged: dict[float, NDArray[np.complex128]] = {}
    for k, c in qp.terms.items():
        h = float(sum(kk * t for kk, t in zip(k, taus, strict=True)))
        acc = merged.setdefault(h, np.zeros(qp.degree + 1, dtype=np.complex128))
        acc[: c.size] += c
    principal = merged.pop(0.0)
    if principal[-1] == 0.0:
        raise InputError(
            "at these delays the undelayed terms cancel in the highest power of s; "
            "the quasi-polynomial is then of another degree or type (give other delays)"
        )
    rows = [(principal, 0.0)] + sorted(((c, h) for h, c in merged.items()), key=lambda ch: ch[1])
    terms: Terms = tuple((np.trim_zeros(c, "b") if np.any(c) else c[:1], h, 0) for c, h in rows)  # type: ignore[misc]
    terms = tuple(term for term in terms if term is terms[0] or np.any(term[0]))
    A, delayed = _companion(terms)
    return _Problem(terms=terms, A=A, delayed=delayed, scale=_polynomial_scale(terms))


def _polynomial_scale(terms: Terms) -> float:
    """Radius of the roots of the principal and of the delay-free polynomial (at least 1).

    The scale of the rightmost roots, for the discretization's first degree
    (a companion matrix's norm is the size of the coefficients, far larger);
    a degree too low for a problem only costs a rejected certificate and a
    finer discretization.
    """
    free = np.zeros(terms[0][0].size, dtype=np.complex128)
    for c, _, _ in terms:
        free[: c.size] += c
    radius = 1.0
    for c in (terms[0][0], free):
        if c.size > 1 and c[-1] != 0.0:
            radius = max(radius, float(np.abs(np.roots(c[::-1])).max()))
    return radius


#: (t1, t2) at which a problem of :func:`_problem_of_quasi` is evaluated
UNIT_DELAYS = (1.0, 0.0)


def _companion(terms: Terms) -> tuple[NDArray[np.complex128], tuple[tuple[NDArray[np.complex128], Any, Any], ...]]:
    """A DDE realization x' = A x + sum B_k x(t - h_k) of a retarded quasi-polynomial, balanced.

    With x_i = y^(i) / rho^i (i = 0..N-1) and the principal polynomial made
    monic, A has rho on its superdiagonal and the last rows carry the scaled
    coefficients ``-c_i rho^(i - N + 1) / lead``; det(sI - A - sum B_k e^{-h_k s})
    is q / lead (a diagonal similarity of the plain companion form). ``rho``
    is Fujiwara's bound of the roots of ``|lead| r^N = sum_i (|g1_i| + sum_k |g_k,i|) r^i``
    (those with Re s >= 0 lie within it), so the entries,
    hence the discretization's root scale, are of the size of the roots
    instead of the size of the coefficients.
    """
    g1 = terms[0][0]
    n = g1.size - 1
    lead = g1[-1]
    low = np.abs(g1[:n]).astype(float)
    for c, _, _ in terms[1:]:
        low[: c.size] += np.abs(c)
    rho = 1.0
    if n and low.any():
        # Fujiwara's bound 2 max_i (low_i / |lead|)^(1 / (N - i)) of those roots: a closed form
        rho = max(2.0 * float(np.max((low / abs(lead)) ** (1.0 / (n - np.arange(n))))), 1e-300)
    powers = rho ** (np.arange(n) - n + 1.0)
    A = np.zeros((n, n), dtype=np.complex128)
    A[np.arange(n - 1), np.arange(1, n)] = rho
    A[-1, :] = -g1[:n] * powers / lead
    delayed = []
    for c, a, b in terms[1:]:
        B = np.zeros((n, n), dtype=np.complex128)
        B[-1, : c.size] = -c * powers[: c.size] / lead
        delayed.append((B, a, b))
    return A, tuple(delayed)


def _problem_of_factor(factor: CharacteristicFactor) -> _Problem:
    """Subsystem of a factor (paper, eq. 8); a pair is solved via lam alone.

    The fourth-order factor of (lam, conj lam) is q_lam(s) q_conj(lam)(s) with
    q_lam = s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s}), and the roots
    of q_conj(lam) are the conjugates of those of q_lam.
    """
    P, D, lam = factor.P, factor.D, complex(factor.lam)
    if factor.group.is_complex_pair:
        terms: Terms = (
            (np.array([P, D, 1.0], dtype=np.complex128), 0, 0),
            (np.array([-lam * P], dtype=np.complex128), 1, 0),
            (np.array([0.0, -lam * D], dtype=np.complex128), 0, 1),
        )
        A = np.array([[0.0, 1.0], [-P, -D]], dtype=np.complex128)
        B1 = lam * np.array([[0.0, 0.0], [P, 0.0]], dtype=np.complex128)
        B2 = lam * np.array([[0.0, 0.0], [0.0, D]], dtype=np.complex128)
        return _Problem(terms=terms, A=A, delayed=((B1, 1, 0), (B2, 0, 1)), mirror=True)
    A, B1, B2 = (np.asarray(m, dtype=np.complex128) for m in factor.state_matrices())
    return _Problem(
        terms=factor.quasi_polynomial.terms(),
        A=A,
        delayed=((B1, 1, 0), (B2, 0, 1)),
        deflate_zero=factor.is_centroid,
    )


def _problem(qp: TwoDelayQuasiPolynomial | CharacteristicFactor) -> _Problem:
    if isinstance(qp, CharacteristicFactor):
        return _problem_of_factor(qp)
    if isinstance(qp, TwoDelayQuasiPolynomial):
        return _problem_of_qp(qp)
    raise InputError(
        f"expected a TwoDelayQuasiPolynomial or CharacteristicFactor, got {type(qp).__name__}"
    )


# =====================================================================
# evaluation of q, q' and the term magnitudes (vectorized)
# =====================================================================
def _horner(c: NDArray[np.complex128], s: NDArray[Any]) -> NDArray[Any]:
    out = np.zeros(np.shape(s), dtype=np.result_type(c, s)) + c[-1]
    for coef in c[-2::-1]:
        out = out * s + coef
    return out


@lru_cache(maxsize=256)
def _derivative_coefficients(key: bytes, size: int) -> NDArray[np.complex128]:
    c = np.frombuffer(key, dtype=np.complex128, count=size)
    return npoly.polyder(c) if size > 1 else np.zeros(1, dtype=np.complex128)


def evaluate(
    terms: Terms, s: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64],
    *, magnitude: bool = True,
) -> tuple[NDArray[np.complex128], NDArray[np.complex128], NDArray[np.float64]]:
    """q(s), dq/ds and the sum of |monomial terms| (the residual's scale), broadcasting.

    Parameters
    ----------
    terms
        The quasi-polynomial (:data:`Terms`).
    s
        Points of the complex plane.
    t1, t2
        The delays (broadcast with ``s``).
    magnitude
        False: the third array is empty (Newton iterations skip it).

    Returns
    -------
    q, dq, mag
        Arrays of the broadcast shape; overflow far left gives inf or NaN,
        which the callers filter.
    """
    shape = np.broadcast_shapes(np.shape(s), np.shape(t1), np.shape(t2))
    q = np.zeros(shape, dtype=np.complex128)
    dq = np.zeros(shape, dtype=np.complex128)
    mag = np.zeros(shape if magnitude else (0,))
    abs_s = np.abs(s) if magnitude else None
    with np.errstate(all="ignore"):  # far-left spurious seeds overflow; filtered by callers
        for c, a, b in terms:
            p = _horner(c, s)
            dp = _horner(_derivative_coefficients(c.tobytes(), c.size), s)
            if a or b:
                h = a * t1 + b * t2
                e = np.exp(-h * s)
                q += p * e
                dq += (dp - h * p) * e
                if magnitude:
                    mag += _abs_poly(c, abs_s) * np.abs(e)
            else:
                q += p
                dq += dp
                if magnitude:
                    mag += _abs_poly(c, abs_s)
    return q, dq, mag



# =====================================================================
# Newton polishing
# =====================================================================
def _polish(
    prob: _Problem, s0: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """Newton's method on q from the seeds s0 (broadcasting with t1, t2).

    With ``deflate_zero`` the step is Maehly's q / (q' - q/s), Newton on q(s)/s,
    so seeds are not drawn into the persistent root 0. Only the seeds still
    moving are iterated. Returns the roots and a mask of those whose relative
    residual is <= RESIDUAL_TOL.
    """
    shape = np.broadcast_shapes(np.shape(s0), np.shape(t1), np.shape(t2))
    s = np.array(np.broadcast_to(s0, shape), dtype=np.complex128).ravel()
    b1 = np.broadcast_to(t1, shape).ravel()
    b2 = np.broadcast_to(t2, shape).ravel()
    finite = np.isfinite(s)
    s[~finite] = 0.0
    act = np.flatnonzero(finite)
    for _ in range(_NEWTON_MAXITER):
        if act.size == 0:
            break
        sa = s[act]
        q, dq, _ = evaluate(prob.terms, sa, b1[act], b2[act], magnitude=False)
        with np.errstate(all="ignore"):
            step = q / (dq - q / sa) if prob.deflate_zero else q / dq
        bad = ~np.isfinite(step)
        if prob.deflate_zero:
            bad |= sa == 0.0  # s = 0 hit exactly: settled by _deflated_zero
        step[bad] = 0.0
        s[act] = sa - step
        moving = ~bad & (np.abs(step) > 4e-16 * (1.0 + np.abs(sa)))
        act = act[moving]
    s = s.reshape(shape)
    b1, b2 = b1.reshape(shape), b2.reshape(shape)
    zero_ok = np.ones(shape, dtype=bool)
    if prob.deflate_zero:
        s, zero_ok = _deflated_zero(prob, s, b1, b2)
    q, _, mag = evaluate(prob.terms, s, b1, b2)
    with np.errstate(all="ignore"):
        ok = finite.reshape(shape) & np.isfinite(mag) & (np.abs(q) <= RESIDUAL_TOL * mag)
    return s, ok & zero_ok


def _deflated_zero(
    prob: _Problem, s: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """Settle seeds that reached s ~ 0 after deflating the persistent root of the paper's eq. 4.

    Near 0, Newton on q(s)/s cannot resolve a root better than about
    sqrt(eps) (q's terms cancel), so a seed that ended there is replaced by
    the root of the Taylor model of q(s)/s at 0,
    ``d1 + d2 s / 2 + d3 s^2 / 6`` (dk the k-th derivative of q at 0):
    exactly 0 when 0 is a double root (d1 = 0, e.g. tau1 = 0 for
    the paper's eq. 4), and otherwise the small genuine root a tiny delay puts next
    to 0 (about -P tau1 / (1 + D tau2) for the paper's eq. 4), accurate to O(s^3).
    A seed near 0 when that root is not (a spurious seed) is rejected.
    """
    near = np.abs(s) < 1e-6
    if not near.any():
        return s, np.ones(s.shape, dtype=bool)
    shape = np.broadcast_shapes(s.shape, np.shape(t1), np.shape(t2))
    b1, b2 = np.broadcast_to(t1, shape), np.broadcast_to(t2, shape)
    # derivatives at 0 of the terms p(s) e^{-h s}, each summed exactly (fsum): d1 is
    # tiny when large terms cancel, and its relative accuracy is the root's
    parts: list[list[list[complex]]] = [[[], [], []] for _ in range(int(np.prod(shape)))]
    for c, a, b in prob.terms:
        p0, p1, p2, p3 = (complex(c[k]) * math.factorial(k) if k < c.size else 0j for k in range(4))
        for idx, h in enumerate((a * b1 + b * b2).ravel().tolist()):
            parts[idx][0] += [p1, -h * p0]
            parts[idx][1] += [p2, -2 * h * p1, h**2 * p0]
            parts[idx][2] += [p3, -3 * h * p2, 3 * h**2 * p1, -(h**3) * p0]

    def exact(k: int) -> NDArray[np.complex128]:
        vals = [complex(math.fsum(z.real for z in part[k]), math.fsum(z.imag for z in part[k])) for part in parts]
        return np.array(vals, dtype=np.complex128).reshape(shape)

    d1, d2, d3 = exact(0), exact(1), exact(2)
    double = d1 == 0.0  # summed exactly: any other value is a genuine small root
    with np.errstate(all="ignore"):
        lin = -2.0 * d1 / d2  # root of d1 + d2 s / 2, then one correction for the cubic term
        model = lin - (d3 / 3.0) * lin**2 / d2
    model = np.where(double, 0.0, model)
    # q(s)/s is about linear within 1e-5 of 0, so its only root there is the model's
    genuine = np.isfinite(model) & (np.abs(model) < 1e-5)
    keep = ~near | double | genuine
    return np.where(near & keep, model, s), keep


def _cluster(roots: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """The distinct roots among polished seeds (many seeds may reach the same root)."""
    if roots.size == 0:
        return roots
    order = np.lexsort((roots.imag, roots.real))
    out: list[complex] = []
    for z in roots[order]:
        if not any(abs(z - y) <= 1e-7 * (1.0 + abs(y)) for y in out):
            out.append(complex(z))
    return np.asarray(out, dtype=np.complex128)


def _nth_derivative(
    terms: Terms, s: NDArray[np.complex128], t1: float, t2: float, k: int
) -> tuple[NDArray[np.complex128], NDArray[np.float64]]:
    """d^k q / ds^k and the sum of the moduli of its terms (Leibniz rule on p(s) e^{-h s})."""
    vals, mags = _derivatives_up_to(terms, s, t1, t2, k)
    return vals[k], mags[k]


def _derivatives_up_to(
    terms: Terms, s: NDArray[np.complex128], t1: float, t2: float, kmax: int
) -> tuple[list[NDArray[np.complex128]], list[NDArray[np.float64]]]:
    """d^k q / ds^k and the sum of the moduli of its terms for every k = 0..kmax (Leibniz rule on p(s) e^{-h s}).

    Each p^(j)(s) of a term is evaluated once: a pass of the argument principle's Taylor test
    needs every order, and recomputing the polynomial derivatives per order cost
    (kmax + 1)^2 / 2 of them per term. The moduli are taken at |s| floored at 1: near s = 0 a
    derivative like 2 s is "small" only against 1.
    """
    vals = [np.zeros(s.shape, dtype=np.complex128) for _ in range(kmax + 1)]
    mags = [np.zeros(s.shape) for _ in range(kmax + 1)]
    rho = np.maximum(np.abs(s), 1.0)
    for c, a, b in terms:
        h = a * t1 + b * t2
        e = np.exp(-h * s)
        abs_e = np.abs(e)
        p: list[NDArray[np.complex128] | None] = []
        bound: list[NDArray[np.float64] | None] = []
        for j in range(kmax + 1):
            dj = npoly.polyder(c, j) if j else c
            if dj.size == 0:
                p.append(None)
                bound.append(None)
                continue
            p.append(_horner(dj, s))
            bound.append(_abs_poly(dj, rho))
        for k in range(kmax + 1):
            for j in range(k + 1):
                pj, bj = p[j], bound[j]
                if pj is None or bj is None:
                    continue
                w = math.comb(k, j) * (-h) ** (k - j)
                if w == 0.0:
                    continue
                vals[k] = vals[k] + w * pj * e
                mags[k] = mags[k] + abs(w) * bj * abs_e
    return vals, mags


def _multiplicity(
    prob: _Problem, roots: NDArray[np.complex128], t1: float, t2: float
) -> NDArray[np.int64]:
    """Multiplicity of each polished root: the first derivative of q that is not negligible.

    A root of multiplicity m is only accurate to about eps^(1/m), so the
    derivatives below m are "negligible" at 1e-5 of their terms' scale; the
    certified count catches a wrong call, which then triggers a finer pass.
    """
    mult = np.ones(roots.shape, dtype=np.int64)
    if roots.size == 0:
        return mult
    undecided = np.ones(roots.shape, dtype=bool)
    for k in range(1, 5):
        val, mag = _nth_derivative(prob.terms, roots, t1, t2, k)
        small = undecided & (np.abs(val) <= 1e-5 * mag)
        mult = np.where(small, k + 1, mult)
        undecided = small
        if not undecided.any():
            break
    if prob.deflate_zero:  # the persistent zero is counted apart; q(s)/s has one less at 0
        mult = np.where(np.abs(roots) < 1e-7, mult - 1, mult)
    return mult


def _abs_poly(c: NDArray[np.complex128], rho: NDArray[np.float64]) -> NDArray[np.float64]:
    """sum_i |c_i| rho^i, the bound of |c(s)| on |s| <= rho."""
    absc = np.abs(c)
    out = np.zeros(np.shape(rho)) + absc[-1]
    for coef in absc[-2::-1]:
        out = out * rho + coef
    return out


def _abs_poly_der(c: NDArray[np.complex128], rho: NDArray[np.float64]) -> NDArray[np.float64]:
    if c.size < 2:
        return np.zeros(np.shape(rho))
    return _abs_poly(_abs_derivative(c.tobytes(), c.size), rho)


@lru_cache(maxsize=256)
def _abs_derivative(key: bytes, size: int) -> NDArray[np.complex128]:
    """Coefficients of the derivative of sum_i |c_i| s^i (cached: the certificates ask every round)."""
    c = np.frombuffer(key, dtype=np.complex128, count=size)
    return npoly.polyder(np.abs(c).astype(np.complex128))



def _mirror_problem(prob: _Problem) -> _Problem:
    terms = tuple((np.conj(c), a, b) for c, a, b in prob.terms)
    delayed = tuple((np.conj(m), a, b) for m, a, b in prob.delayed)
    return _Problem(terms, np.conj(prob.A), delayed, False, prob.deflate_zero)


