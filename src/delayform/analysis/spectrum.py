"""Characteristic roots, dominant roots, dominant-root maps and delay scheduling.

The paper closes (Section "Simulation", Figs. dominant and contour) with
*delay scheduling*: inside the stable region of the CTCR chart, pick the
delays whose dominant (rightmost) characteristic root lies furthest left,
because that root sets how fast the team settles into formation. This module
computes those roots for any retarded quasi-polynomial of eq. genfactor and
for the factors of eq. factorized.

Method
------
1. **Global approximation.** The infinitesimal generator of the DDE
   ``dx/dt = A x + sum_k B_k x(t - h_k)`` is discretized by Chebyshev
   collocation on ``[-h_max, 0]`` (Breda, Maset and Vermiglio, "Pseudospectral
   differencing methods for characteristic roots of delay differential
   equations", SIAM J. Sci. Comput. 27, 2005). Its eigenvalues approximate
   the characteristic roots. A factor of eq. factorized is realized by its own
   subsystem eq. subsystems (eq. matrices2; a conjugate pair, eq. matrices4,
   splits into the complex second-order factor of ``lam`` and its mirror image,
   which halves the work); a general retarded quasi-polynomial of degree N is
   realized in companion form with the delays tau1, tau2, 2 tau1, 2 tau2 and
   tau1 + tau2 of eq. genfactor.
2. **Newton polishing** on the quasi-polynomial itself. A root is accepted
   when its *relative residual*
   ``|q(s)| / sum_k sum_i |g_k,i| |s|^i |e^{-h_k s}|`` (the modulus of q over
   the sum of the moduli of its monomial terms, i.e. a backward error) is at
   most :data:`RESIDUAL_TOL` = 1e-10.
3. **Certificate by the argument principle.** No root may be missed. The
   number of roots inside a contour is computed from the winding of q along
   it, with a *certified* sampling: between two samples ``s_j, s_j+1`` the
   change of q is bounded by a Lipschitz bound ``L_j |s_j+1 - s_j|`` built
   from the moduli of the coefficients, and the sampling is refined until
   ``min(|q(s_j)|, |q(s_j+1)|) > L_j |s_j+1 - s_j| / 2``, which keeps each
   arg increment below pi, so the unwrapped phase, hence the count, is exact
   (up to floating-point rounding in evaluating q). For a right half-plane
   ``Re s > c`` the contour is the line ``Re s = c`` closed at infinity: a
   Cauchy-type bound ``Omega`` gives ``|g1(s)| > sum_k |g_k(s) e^{-h_k s}|``
   for ``|Im s| >= Omega`` on the line (Rouche), so the tails contribute the
   arg change of g1 in closed form. When the count differs from the number of
   polished roots found, the discretization degree is raised and the step
   repeated; after :data:`MAX_DEGREE`, :class:`~delayform.errors.NotConvergedError`
   carries the roots found so far.

Guarantee
---------
:func:`roots_in` returns every root in the rectangle (the count inside the
rectangle is certified). :func:`rightmost_root` and everything built on it
(:func:`dominant_root`, :func:`dominant_root_map`, :func:`schedule_delays`)
return a root such that the certified number of roots in ``Re s > c`` equals
the number of polished roots found there, for a line ``c`` placed in a gap
left of the returned root: no root to its right is missed.

Conventions: coefficients in increasing powers of s; delays in seconds,
``tau1`` on positions and ``tau2`` on velocities (eq. protocol); the
centroid factor's persistent root s = 0 (eq. factor1) is deflated with
Maehly's correction and excluded from dominant roots (its other roots count).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_delay, check_gains
from delayform.characteristic import CharacteristicFactor, TwoDelayQuasiPolynomial, factors
from delayform.errors import DelayError, InputError, NoStableDelaysError, NotConvergedError, ResourceLimitError
from delayform.resources import require
from delayform.topology import Topology

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes

__all__ = [
    "RESIDUAL_TOL",
    "MAX_DEGREE",
    "SETTLING_FACTOR",
    "roots_in",
    "rightmost_root",
    "count_roots_right_of",
    "relative_residual",
    "dominant_root",
    "dominant_root_map",
    "DominantRoot",
    "DominantRootMap",
    "NoStableDelaysError",
]

#: Acceptance threshold of the relative residual of a polished root.
RESIDUAL_TOL = 1e-10
#: Largest Chebyshev discretization degree tried before giving up.
MAX_DEGREE = 192
#: Settling time (2 % criterion) = ln(50) / |Re s_dom| ~ 3.9 time constants.
SETTLING_FACTOR = math.log(50.0)

_NEWTON_MAXITER = 50
#: Delays below this seed Newton from the delay-free roots (a discretization of
#: [-h, 0] would overflow; the polishing and the certificate use the exact q).
_TINY_DELAY = 1e-10
#: Largest distance of the certifying line Re s = c from the roots it separates.
_LINE_OFFSET = 0.1
#: Most sample points spent on one certified contour before giving up.
_MAX_SAMPLES = 400_000

Region = tuple[float, float, float, float]
_Terms = tuple[tuple[NDArray[np.complex128], int, int], ...]


# =====================================================================
# the problem: a quasi-polynomial and a DDE whose characteristic function it is
# =====================================================================
@dataclass(frozen=True, eq=False)
class _Problem:
    """What the solvers work on.

    ``terms`` is the quasi-polynomial polished and counted (eq. genfactor
    terms as (coefficients, multiple of tau1, multiple of tau2)); ``A`` and
    ``delayed`` a DDE realization whose characteristic function is q up to a
    constant; ``mirror`` adds complex conjugates of the roots (a conjugate
    pair factor solved through its complex second-order factor of lam);
    ``deflate_zero`` removes the persistent root s = 0 of eq. factor1.
    """

    terms: _Terms
    A: NDArray[np.complex128]
    delayed: tuple[tuple[NDArray[np.complex128], int, int], ...]
    mirror: bool = False
    deflate_zero: bool = False

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
    """Companion-form DDE of a retarded quasi-polynomial (eq. genfactor).

    With x = (y, y', ..., y^(N-1)) and g1 made monic, the last row carries
    -g1's lower coefficients (undelayed) and -g_k (delayed by h_k); the
    characteristic function det(sI - A - sum B_k e^{-h_k s}) is q / lead(g1).
    """
    qp.require_retarded()
    terms = qp.terms()
    g1 = terms[0][0]
    n = g1.size - 1
    lead = g1[-1]
    A = np.zeros((n, n), dtype=np.complex128)
    A[np.arange(n - 1), np.arange(1, n)] = 1.0
    A[-1, :] = -g1[:n] / lead
    delayed = []
    for c, a, b in terms[1:]:
        B = np.zeros((n, n), dtype=np.complex128)
        B[-1, : c.size] = -c / lead
        delayed.append((B, a, b))
    return _Problem(terms=terms, A=A, delayed=tuple(delayed))


def _problem_of_factor(factor: CharacteristicFactor) -> _Problem:
    """Subsystem of a factor (eq. subsystems); a pair is solved via lam alone.

    The fourth-order factor of (lam, conj lam) is q_lam(s) q_conj(lam)(s) with
    q_lam = s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s}), and the roots
    of q_conj(lam) are the conjugates of those of q_lam.
    """
    P, D, lam = factor.P, factor.D, complex(factor.lam)
    if factor.group.is_complex_pair:
        terms: _Terms = (
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


def _evaluate(
    terms: _Terms, s: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64],
    *, magnitude: bool = True,
) -> tuple[NDArray[np.complex128], NDArray[np.complex128], NDArray[np.float64]]:
    """q(s), dq/ds and sum of |monomial terms| (the residual's scale), broadcasting.

    With ``magnitude=False`` the third array is empty (Newton iterations skip it).
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


def relative_residual(
    qp: TwoDelayQuasiPolynomial, s: ArrayLike, tau1: ArrayLike, tau2: ArrayLike
) -> NDArray[np.float64]:
    """|q(s)| over the sum of the moduli of its monomial terms (a backward error).

    This is the "relative" of the acceptance test ``<= RESIDUAL_TOL`` for
    every root this module returns.

    Parameters
    ----------
    qp
        A quasi-polynomial of eq. genfactor.
    s
        Complex point(s) at which q is evaluated.
    tau1, tau2
        Delays (s) on positions and on velocities; broadcast with ``s``.
        Not validated.

    Returns
    -------
    ndarray of float
        ``|q(s)| / sum_k sum_i |g_k,i| |s|^i |e^{-h_k s}|`` in the broadcast
        shape of s, tau1 and tau2.

    >>> q = TwoDelayQuasiPolynomial([-1.0, 1.0])
    >>> float(relative_residual(q, 1.0, 0.0, 0.0))
    0.0
    """
    s_arr = np.asarray(s, dtype=np.complex128)
    q, _, mag = _evaluate(
        qp.terms(), s_arr, np.asarray(tau1, dtype=float), np.asarray(tau2, dtype=float)
    )
    return np.abs(q) / mag


# =====================================================================
# spectral discretization of the infinitesimal generator (batched)
# =====================================================================
@lru_cache(maxsize=64)
def _chebyshev(N: int) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Chebyshev points cos(j pi / N), differentiation matrix and barycentric weights."""
    j = np.arange(N + 1)
    x = np.cos(np.pi * j / N)
    c = np.where((j == 0) | (j == N), 2.0, 1.0) * (-1.0) ** j
    dx = x[:, None] - x[None, :]
    Dm = np.outer(c, 1.0 / c) / (dx + np.eye(N + 1))
    Dm = Dm - np.diag(Dm.sum(axis=1))  # negative-sum trick (Trefethen, Spectral Methods in MATLAB)
    w = (-1.0) ** j * np.where((j == 0) | (j == N), 0.5, 1.0)
    return x, Dm, w


def _lagrange_rows(N: int, xq: NDArray[np.float64]) -> NDArray[np.float64]:
    """Values of the N+1 Lagrange basis polynomials at points xq (barycentric formula)."""
    x, _, w = _chebyshev(N)
    diff = xq[..., None] - x
    hit = np.abs(diff) < 1e-15
    safe = np.where(hit, 1.0, diff)
    t = w / safe
    rows = t / t.sum(axis=-1, keepdims=True)
    on_node = hit.any(axis=-1)
    return np.where(on_node[..., None], hit.astype(float), rows)


def _igd_eigenvalues(
    prob: _Problem, N: int, t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> NDArray[np.complex128]:
    """Eigenvalues of the degree-N discretized generator at each delay pair (shape (B, d(N+1))).

    Rows 1..N collocate u' = d/dtheta u at the Chebyshev points of
    [-h_max, 0]; row 0 is the DDE itself, the delayed states read off the
    interpolating polynomial at theta = -h_k. All pairs must have h_max > 0.
    """
    d = prob.d
    x, Dm, _ = _chebyshev(N)
    Bstack = np.stack([b for b, _, _ in prob.delayed])  # (K, d, d)
    h = np.stack([a * t1 + b * t2 for _, a, b in prob.delayed], axis=-1)  # (B, K)
    hmax = h.max(axis=-1)
    L = _lagrange_rows(N, 1.0 - 2.0 * h / hmax[:, None])  # (B, K, N+1)
    real = prob.is_real
    dtype = np.float64 if real else np.complex128
    Bm = Bstack.real if real else Bstack
    M = np.zeros((t1.size, N + 1, d, N + 1, d), dtype=dtype)
    M[:, 0] = np.einsum("bkj,kpq->bpjq", L, Bm)
    M[:, 0, :, 0, :] += prob.A.real if real else prob.A
    M[:, 1:] = (2.0 / hmax)[:, None, None, None, None] * np.einsum(
        "ij,pq->ipjq", Dm[1:], np.eye(d)
    )
    size = (N + 1) * d
    return np.linalg.eigvals(M.reshape(t1.size, size, size)).astype(np.complex128)


def _delay_free_eigenvalues(prob: _Problem) -> NDArray[np.complex128]:
    """Roots at tau1 = tau2 = 0: eigenvalues of A + sum B_k."""
    total = prob.A + sum(b for b, _, _ in prob.delayed)
    return np.linalg.eigvals(total)


def _max_delay(prob: _Problem, t1: float, t2: float) -> float:
    """Largest delay of the realization; below :data:`_TINY_DELAY` it counts as none for seeding."""
    h = max([a * t1 + b * t2 for _, a, b in prob.delayed] + [0.0])
    return h if h >= _TINY_DELAY else 0.0


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
        q, dq, _ = _evaluate(prob.terms, sa, b1[act], b2[act], magnitude=False)
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
    q, _, mag = _evaluate(prob.terms, s, b1, b2)
    with np.errstate(all="ignore"):
        ok = finite.reshape(shape) & np.isfinite(mag) & (np.abs(q) <= RESIDUAL_TOL * mag)
    return s, ok & zero_ok


def _deflated_zero(
    prob: _Problem, s: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> tuple[NDArray[np.complex128], NDArray[np.bool_]]:
    """Settle seeds that reached s ~ 0 after deflating the persistent root of eq. factor1.

    Near 0, Newton on q(s)/s cannot resolve a root better than about
    sqrt(eps) (q's terms cancel), so a seed that ended there is replaced by
    the root of the Taylor model of q(s)/s at 0,
    ``d1 + d2 s / 2 + d3 s^2 / 6`` (dk the k-th derivative of q at 0):
    exactly 0 when 0 is a double root (d1 = 0, e.g. tau1 = 0 for
    eq. factor1), and otherwise the small genuine root a tiny delay puts next
    to 0 (about -P tau1 / (1 + D tau2) for eq. factor1), accurate to O(s^3).
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
    terms: _Terms, s: NDArray[np.complex128], t1: float, t2: float, k: int
) -> tuple[NDArray[np.complex128], NDArray[np.float64]]:
    """d^k q / ds^k and the sum of the moduli of its terms (Leibniz rule on p(s) e^{-h s})."""
    val = np.zeros(s.shape, dtype=np.complex128)
    mag = np.zeros(s.shape)
    for c, a, b in terms:
        h = a * t1 + b * t2
        e = np.exp(-h * s)
        for j in range(k + 1):
            dj = npoly.polyder(c, j) if j else c
            if dj.size == 0:
                continue
            w = math.comb(k, j) * (-h) ** (k - j)
            if w == 0.0:
                continue
            p = _horner(dj, s)
            val = val + w * p * e
            # scale at |s| >= 1: near s = 0 a derivative like 2 s is "small" only against 1
            mag = mag + abs(w) * _abs_poly(dj, np.maximum(np.abs(s), 1.0)) * np.abs(e)
    return val, mag


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


# =====================================================================
# argument principle with certified sampling
# =====================================================================
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
    return _abs_poly(npoly.polyder(np.abs(c).astype(np.complex128)), rho)


def _lipschitz(
    terms: _Terms, rho: NDArray[np.float64], re_min: NDArray[np.float64], t1: Any, t2: Any
) -> NDArray[np.float64]:
    """Bound of |q'(s)| over |s| <= rho, Re s >= re_min (moduli of coefficients)."""
    out = np.zeros(np.broadcast_shapes(np.shape(rho), np.shape(re_min), np.shape(t1), np.shape(t2)))
    for c, a, b in terms:
        h = a * np.asarray(t1) + b * np.asarray(t2)
        with np.errstate(over="ignore"):
            w = np.exp(-h * re_min)
        out = out + w * (_abs_poly_der(c, rho) + h * _abs_poly(c, rho))
    return out


def _segment_winding(
    terms: _Terms, t1: float, t2: float, s0: complex, s1: complex, *, budget: int
) -> tuple[float, int] | None:
    """Certified change of arg q along the segment s0 -> s1, and samples used.

    Segments of the sampling are bisected until every one satisfies the
    Lipschitz condition of the module docstring; None when ``budget`` samples
    do not suffice (a root on or extremely close to the segment).
    """
    length = abs(s1 - s0)
    t = np.linspace(0.0, 1.0, 65)
    a1, a2 = np.asarray(t1), np.asarray(t2)
    for _ in range(64):  # 64 bisections: segments far below rounding of s
        if t.size > budget:
            return None
        s = s0 + t * (s1 - s0)
        q, _, _ = _evaluate(terms, s, a1, a2)
        absq = np.abs(q)
        if not np.all(np.isfinite(absq)) or np.any(absq == 0.0):
            return None
        rho = np.maximum(np.abs(s[:-1]), np.abs(s[1:]))
        re_min = np.minimum(s[:-1].real, s[1:].real)
        L = _lipschitz(terms, rho, re_min, t1, t2) * length * np.diff(t)
        bad = np.minimum(absq[:-1], absq[1:]) <= 0.5 * L
        if not bad.any():
            return float(np.angle(q[1:] / q[:-1]).sum()), int(t.size)
        mids = 0.5 * (t[:-1] + t[1:])[bad]
        t = np.sort(np.concatenate([t, mids]))
    return None


def _region_count(
    prob: _Problem, t1: float, t2: float, region: Region, *, budget: int = _MAX_SAMPLES
) -> int | None:
    """Certified number of roots of q inside the rectangle (multiplicity counted)."""
    x0, x1, y0, y1 = region
    corners = [complex(x0, y0), complex(x1, y0), complex(x1, y1), complex(x0, y1)]
    total = 0.0
    for k in range(4):
        piece = _segment_winding(prob.terms, t1, t2, corners[k], corners[(k + 1) % 4], budget=budget)
        if piece is None:
            return None
        total += piece[0]
    count = total / (2.0 * np.pi)
    return int(round(count)) if abs(count - round(count)) < 0.1 else None


def _cauchy_radius(
    terms: _Terms, c: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Omega with |g1(s)| > sum_k |g_k(s)| e^{-h_k c} whenever |s| >= Omega (Rouche on Re s = c).

    The positive root of |a_N| r^N - sum_{i<N} (|a_i| + sum_k e^{-h_k c} |b_k,i|) r^i
    (one sign change, so exactly one), found by bisection; the upper end is
    returned, where the polynomial is strictly positive.
    """
    g1 = np.abs(terms[0][0])
    n = g1.size - 1
    shape = np.broadcast_shapes(c.shape, t1.shape, t2.shape)
    low = np.zeros(shape + (n,))
    low[...] = g1[:n]
    for coef, a, b in terms[1:]:
        with np.errstate(over="ignore"):
            w = np.exp(-(a * t1 + b * t2) * c)
        low[..., : coef.size] += w[..., None] * np.abs(coef)
    lead = g1[n]
    if n == 2:  # the second-order factors of eq. factorized: the quadratic formula
        b1, b0 = low[..., 1], low[..., 0]
        root = (b1 + np.sqrt(b1 * b1 + 4.0 * lead * b0)) / (2.0 * lead)
        return root * (1.0 + 1e-9) + 1e-12
    hi = np.maximum(1.0, low.sum(axis=-1) / lead) * (1.0 + 1e-12)
    lo = np.zeros(shape)
    powers = np.arange(n)

    def p(r: NDArray[np.float64]) -> NDArray[np.float64]:
        return lead * r**n - (low * r[..., None] ** powers).sum(axis=-1)

    for _ in range(60):
        mid = 0.5 * (lo + hi)
        pos = p(mid) > 0.0
        hi = np.where(pos, mid, hi)
        lo = np.where(pos, lo, mid)
    return hi * (1.0 + 1e-9) + 1e-12


def _tail_winding(
    terms: _Terms, g1_roots: NDArray[np.complex128], s_end: NDArray[np.complex128],
    t1: NDArray[np.float64], t2: NDArray[np.float64], *, upper: bool,
) -> NDArray[np.float64]:
    """Arg change of q from c + i Omega up to c + i inf (upper) or from c - i inf to c - i Omega.

    There |q/g1 - 1| < 1, so arg q = arg g1 + Arg(q/g1), with Arg(q/g1) -> 0
    at infinity and arg g1 moving by sum over its roots z of the angle of s - z.
    """
    q, _, _ = _evaluate(terms, s_end, t1, t2)
    g1 = _horner(terms[0][0], s_end)
    ratio = np.angle(q / g1)
    ang = np.angle(s_end[..., None] - g1_roots)
    if upper:
        return (np.pi / 2 - ang).sum(axis=-1) - ratio
    return (ang + np.pi / 2).sum(axis=-1) + ratio


def _g1_roots(terms: _Terms) -> NDArray[np.complex128]:
    g1 = terms[0][0]
    return np.roots(g1[::-1]) if g1.size > 1 else np.zeros(0, dtype=np.complex128)


def _count_right_single(prob: _Problem, t1: float, t2: float, c: float) -> int | None:
    """Certified number of roots of q with Re s > c (None if not certifiable)."""
    a1, a2, cc = np.asarray(t1), np.asarray(t2), np.asarray(c, dtype=float)
    omega = float(_cauchy_radius(prob.terms, cc, a1, a2))
    piece = _segment_winding(
        prob.terms, t1, t2, complex(c, -omega), complex(c, omega), budget=_MAX_SAMPLES
    )
    if piece is None:
        return None
    roots = _g1_roots(prob.terms)
    top = _tail_winding(prob.terms, roots, np.asarray(complex(c, omega)), a1, a2, upper=True)
    bottom = _tail_winding(prob.terms, roots, np.asarray(complex(c, -omega)), a1, a2, upper=False)
    delta = piece[0] + float(top) + float(bottom)
    count = prob.degree / 2.0 - delta / (2.0 * np.pi)
    return int(round(count)) if abs(count - round(count)) < 0.1 else None


def _count_right_batch(
    prob: _Problem, t1: NDArray[np.float64], t2: NDArray[np.float64], c: NDArray[np.float64],
    *, initial: int = 17, max_segments: int = 4096,
) -> NDArray[np.float64]:
    """Certified counts of roots in Re s > c for many delay pairs at once (NaN: not certified).

    The adaptive sampling of :func:`_segment_winding`, vectorized: all lines'
    segments live in flat arrays; each round bisects, in one evaluation, the
    segments of every line that fail the Lipschitz condition, and the arg
    increments of the segments that pass are summed per line. For a real q
    only Im s >= 0 is walked (q(conj s) = conj q(s) doubles it).
    """
    nline = c.size
    omega = _cauchy_radius(prob.terms, c, t1, t2)
    real = all(np.all(cf.imag == 0.0) for cf, _, _ in prob.terms)
    u = np.linspace(0.0 if real else -1.0, 1.0, initial)
    w = omega[:, None] * u  # (B, M)
    q, _, _ = _evaluate(prob.terms, c[:, None] + 1j * w, t1[:, None], t2[:, None], magnitude=False)
    line = np.repeat(np.arange(nline), initial - 1)
    wa, wb = w[:, :-1].ravel(), w[:, 1:].ravel()
    qa, qb = q[:, :-1].ravel(), q[:, 1:].ravel()
    total = np.zeros(nline)
    failed = ~np.all(np.isfinite(q) & (q != 0.0), axis=1)
    for _ in range(48):
        rho = np.sqrt(c[line] ** 2 + np.maximum(wa * wa, wb * wb))
        L = _lipschitz(prob.terms, rho, c[line], t1[line], t2[line]) * (wb - wa)
        bad = np.minimum(np.abs(qa), np.abs(qb)) <= 0.5 * L
        with np.errstate(all="ignore"):
            total += np.bincount(line[~bad], np.angle(qb[~bad] / qa[~bad]), minlength=nline)
        if not bad.any():
            break
        line, wa, wb, qa, qb = line[bad], wa[bad], wb[bad], qa[bad], qb[bad]
        too_many = np.bincount(line, minlength=nline) > max_segments
        failed |= too_many
        keep = ~too_many[line]
        line, wa, wb, qa, qb = line[keep], wa[keep], wb[keep], qa[keep], qb[keep]
        wm = 0.5 * (wa + wb)
        qm, _, _ = _evaluate(prob.terms, c[line] + 1j * wm, t1[line], t2[line], magnitude=False)
        failed[line[~np.isfinite(qm) | (qm == 0.0)]] = True
        line = np.concatenate([line, line])
        wa, wb = np.concatenate([wa, wm]), np.concatenate([wm, wb])
        qa, qb = np.concatenate([qa, qm]), np.concatenate([qm, qb])
    else:
        failed[line] = True
    roots = _g1_roots(prob.terms)
    top = _tail_winding(prob.terms, roots, c + 1j * omega, t1, t2, upper=True)
    if real:
        delta = 2.0 * (total + top)
    else:
        bottom = _tail_winding(prob.terms, roots, c - 1j * omega, t1, t2, upper=False)
        delta = total + top + bottom
    count = prob.degree / 2.0 - delta / (2.0 * np.pi)
    good = ~failed & (np.abs(count - np.round(count)) < 0.1)
    return np.where(good, np.round(count), np.nan)


# =====================================================================
# choosing the discretization and the certifying line
# =====================================================================
def _initial_degree(hmax: float, radius: float) -> int:
    """Chebyshev degree resolving roots up to |s| = radius over a delay interval hmax.

    A root s needs e^{s theta} resolved on [-hmax, 0]; Chebyshev interpolation
    of it converges once N exceeds about |s| hmax / 2 (Bernstein ellipse), so
    a margin of twice that plus a floor keeps the rightmost roots accurate
    enough to seed Newton.
    """
    return int(min(MAX_DEGREE, max(12, math.ceil(1.2 * radius * hmax + 10))))


def _root_scale(prob: _Problem) -> float:
    """Radius of the delay-free roots plus the delayed gains: scale of the rightmost roots."""
    total = prob.A + sum(b for b, _, _ in prob.delayed)
    return float(max(1.0, np.max(np.abs(np.linalg.eigvals(total))), np.linalg.norm(prob.A, 2)))


#: largest (delay x root scale) the rightmost-root path certifies reliably (measured on the
#: paper's factors: 30 s works, 60 s does not; the scale there is about 1.2)
_MAX_REACH = 40.0


def _check_reach(prob: _Problem, t1: float, t2: float) -> None:
    """Refuse, in one line, delays too long for the certified root finder (not for CTCR charts)."""
    h = max([a * t1 + b * t2 for _, a, b in prob.delayed] + [0.0])
    scale = _root_scale(prob)
    if h * scale > _MAX_REACH:
        raise DelayError(
            f"a delay of {h:.4g} s is too long for the dominant-root finder with these gains (it handles "
            f"delays up to about {_MAX_REACH / scale:.3g} s); choose shorter delays (the stability chart has no such limit)"
        )


def _choose_line(reals: NDArray[np.float64], top: float) -> float:
    """A line Re s = c in a gap left of ``top`` (reals: known root real parts, descending).

    Roots whose real parts are within 1e-3 of each other stay on the same
    side, so the line is never closer than 5e-4 to a known root; it is at
    most :data:`_LINE_OFFSET` left of them, because e^{-h c} grows quickly as
    c moves left and with it the Cauchy radius and the Lipschitz bounds. ``top`` is
    the real part of the rightmost root wanted (the deflated zero of eq.
    factor1 may lie right of it and is then simply counted).
    """
    k0 = int(np.argmax(reals <= top))
    for k in range(k0, min(reals.size - 1, k0 + 8)):
        gap = reals[k] - reals[k + 1]
        if gap > 1e-3 * (1.0 + abs(reals[k])):
            return float(reals[k] - min(0.5 * gap, _LINE_OFFSET))
    return float(reals[min(reals.size - 1, k0 + 8)] - _LINE_OFFSET)


def _known_reals(
    prob: _Problem, roots: NDArray[np.complex128], mult: NDArray[np.int64]
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Real parts (descending) and multiplicities of the roots of q, incl. the deflated zero."""
    if prob.deflate_zero:
        roots = np.concatenate([roots, [0.0]])
        mult = np.concatenate([mult, [1]])
    order = np.argsort(-roots.real)
    return roots.real[order], mult[order]


@dataclass(frozen=True)
class _SolveResult:
    """Roots right of the certified line Re s = ``line`` at discretization ``degree``.

    ``roots`` are roots of the solved q (no mirror images; the persistent zero
    of eq. factor1 deflated), ``mult`` their multiplicities.
    """

    roots: NDArray[np.complex128]
    mult: NDArray[np.int64]
    line: float
    degree: int


def _solve_rightmost(prob: _Problem, t1: float, t2: float) -> _SolveResult:
    """All roots right of a certified line, for one delay pair (the robust path)."""
    hmax = _max_delay(prob, t1, t2)
    a1, a2 = np.asarray(t1), np.asarray(t2)
    N = _initial_degree(hmax, _root_scale(prob))
    partial: NDArray[np.complex128] = np.zeros(0, dtype=np.complex128)
    while True:
        if hmax == 0.0:
            eig = _delay_free_eigenvalues(prob)
        else:
            eig = _igd_eigenvalues(prob, N, a1.reshape(1), a2.reshape(1))[0]
        if prob.deflate_zero:
            eig = np.delete(eig, np.argmin(np.abs(eig)))
        roots, ok = _polish(prob, eig, a1, a2)
        roots = _cluster(roots[ok])
        mult = _multiplicity(prob, roots, t1, t2)
        partial = roots
        if roots.size:
            reals, m = _known_reals(prob, roots, mult)
            c = _choose_line(reals, float(roots.real.max()))
            expected = int(m[reals > c].sum())
            if _count_right_single(prob, t1, t2, c) == expected:
                keep = roots.real > c
                return _SolveResult(roots[keep], mult[keep], c, N)
        if hmax == 0.0 or N >= MAX_DEGREE:
            raise NotConvergedError(
                f"could not make sure that no characteristic root lies right of the rightmost one found "
                f"at (tau1, tau2) = ({t1:g}, {t2:g}); roots there are too many or too close together, "
                "try slightly different delays",
                partial=partial,
            )
        N = min(MAX_DEGREE, 2 * N)


# =====================================================================
# public: roots of one quasi-polynomial
# =====================================================================
def _check_region(region: object) -> Region:
    try:
        vals = tuple(float(v) for v in region)  # type: ignore[union-attr]
    except (TypeError, ValueError) as exc:
        raise InputError("region must be (re_min, re_max, im_min, im_max)") from exc
    if len(vals) != 4 or not all(math.isfinite(v) for v in vals):
        raise InputError("region must be four finite numbers (re_min, re_max, im_min, im_max)")
    if not (vals[0] < vals[1] and vals[2] < vals[3]):
        raise InputError(f"region must have re_min < re_max and im_min < im_max, got {vals}")
    return vals  # type: ignore[return-value]


def _with_mirror(prob: _Problem, roots: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Roots of q_lam and their conjugates, the roots of q_conj(lam) (a pair factor)."""
    if not prob.mirror:
        return roots
    return np.concatenate([roots, np.conj(roots)])


def roots_in(
    qp: TwoDelayQuasiPolynomial | CharacteristicFactor, tau1: float, tau2: float, region: Region
) -> NDArray[np.complex128]:
    """All characteristic roots in a rectangle of the complex plane.

    Parameters
    ----------
    qp
        A retarded quasi-polynomial of eq. genfactor, or a factor of
        eq. factorized (for the centroid factor eq. factor1 the persistent
        root 0 is *included*: this is the plain root set of q).
    tau1, tau2
        Non-negative delays.
    region
        (re_min, re_max, im_min, im_max).

    Returns
    -------
    ndarray of complex
        The roots in the rectangle, a multiple root repeated by its
        multiplicity (as numpy.roots does), sorted by decreasing real part,
        each with relative residual <= RESIDUAL_TOL (:func:`relative_residual`).
        The count, with multiplicity, is certified by the argument principle
        on the rectangle's boundary.

    Raises
    ------
    NeutralQuasiPolynomialError
        For a quasi-polynomial of neutral type.
    ResourceLimitError
        When the rectangle reaches so far from the origin that the roots
        there cannot be resolved (|s| above about 2 MAX_DEGREE / largest delay).
    NotConvergedError
        When the count is not reached up to :data:`MAX_DEGREE`, or roots lie
        on the boundary of the rectangle and of slightly larger ones (a root
        on the boundary is otherwise reported, the rectangle taken closed);
        ``.partial`` holds the roots found.

    Examples
    --------
    >>> from delayform.characteristic import TwoDelayQuasiPolynomial
    >>> q = TwoDelayQuasiPolynomial([2.0, 3.0, 1.0])  # (s + 1)(s + 2)
    >>> roots_in(q, 0.0, 0.0, (-3, 0, -1, 1)).real.round(12)
    array([-1., -2.])
    """
    region = asked = _check_region(region)
    t1, t2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    prob = _problem(qp)
    base = prob if not prob.deflate_zero else _Problem(prob.terms, prob.A, prob.delayed, prob.mirror)
    x0, x1, y0, y1 = region
    hmax = _max_delay(base, t1, t2)
    radius = max(abs(complex(x, y)) for x in (x0, x1) for y in (y0, y1))
    if 0.5 * radius * hmax > MAX_DEGREE:  # Chebyshev needs degree > |s| h / 2 to resolve e^{s theta}
        raise ResourceLimitError(
            f"the rectangle {asked} reaches |s| = {radius:.4g}, too far from the origin to list every "
            f"root at delays up to {hmax:.4g} s (the limit is about |s| = {2 * MAX_DEGREE / hmax:.4g}); "
            "choose a smaller rectangle"
        )
    # when mirroring, roots of the lam-factor in the mirrored region are needed too
    yy = max(abs(y0), abs(y1))
    count_regions = [region] if not base.mirror else [(x0, x1, -yy, yy)]
    expected = _region_count(base, t1, t2, count_regions[0])
    # a root on the boundary (e.g. a real root on Im s = 0): count on a slightly larger
    # rectangle and report the roots of the closed one, boundary roots included
    size = max(abs(v) for v in region) + 1.0
    for nudge in (1e-9, 1e-7, 1e-5):
        if expected is not None:
            break
        d = nudge * size
        rx0, rx1, ry0, ry1 = count_regions[0]
        count_regions = [(rx0 - d, rx1 + d, ry0 - d, ry1 + d)]
        region = (x0 - d, x1 + d, y0 - d, y1 + d)
        expected = _region_count(base, t1, t2, count_regions[0])
    if expected is None:
        raise NotConvergedError(
            f"roots lie on (or within rounding of) the boundary of the rectangle {asked} "
            "and of every slightly larger rectangle tried; move the rectangle's edges",
            partial=np.zeros(0, dtype=np.complex128),
        )
    N = _initial_degree(hmax, max(radius, _root_scale(base)))
    a1, a2 = np.asarray(t1), np.asarray(t2)
    found = np.zeros(0, dtype=np.complex128)
    while True:
        if hmax == 0.0:
            eig = _delay_free_eigenvalues(base)
        else:
            eig = _igd_eigenvalues(base, N, a1.reshape(1), a2.reshape(1))[0]
        if prob.deflate_zero:
            roots, mult = _roots_beside_zero(prob, base, eig, t1, t2)
        else:
            polished, ok = _polish(base, eig, a1, a2)
            roots = _cluster(polished[ok])
            mult = _multiplicity(base, roots, t1, t2)
        rx0, rx1, ry0, ry1 = count_regions[0]
        inside = (roots.real > rx0) & (roots.real < rx1) & (roots.imag > ry0) & (roots.imag < ry1)
        found = np.repeat(roots[inside], np.maximum(mult[inside], 1))
        if found.size == expected:
            break
        if hmax == 0.0 or N >= MAX_DEGREE:
            raise NotConvergedError(
                f"found {found.size} of the {expected} characteristic roots in the rectangle {asked} "
                f"at (tau1, tau2) = ({t1:g}, {t2:g}); choose a smaller rectangle",
                partial=_in_region(_with_mirror(base, found), region),
            )
        N = min(MAX_DEGREE, 2 * N)
    return _in_region(_with_mirror(base, found), region)


def _roots_beside_zero(
    prob: _Problem, base: _Problem, eig: NDArray[np.complex128], t1: float, t2: float
) -> tuple[NDArray[np.complex128], NDArray[np.int64]]:
    """Roots and multiplicities of the centroid factor (eq. factor1), its root 0 included.

    Polished with the persistent zero deflated, so a tiny delay's genuine
    root next to 0 (about -P tau1 / (1 + D tau2)) is resolved
    (:func:`_deflated_zero`) instead of being mistaken for a double root at 0;
    0 itself is simple, or double when the deflated polish also ends there
    (tau1 = 0, the centroid's drift).
    """
    a1, a2 = np.asarray(t1), np.asarray(t2)
    polished, ok = _polish(prob, eig, a1, a2)
    roots = _cluster(polished[ok])
    zero_is_double = bool(np.any(roots == 0.0))
    mult = _multiplicity(base, roots, t1, t2)
    near = np.abs(roots) < 1e-5  # q(s)/s is about linear there: its roots are simple
    mult = np.where(near, 1, mult)
    roots, mult = roots[roots != 0.0], mult[roots != 0.0]
    return np.append(roots, 0.0), np.append(mult, 2 if zero_is_double else 1)


def _in_region(roots: NDArray[np.complex128], region: Region) -> NDArray[np.complex128]:
    x0, x1, y0, y1 = region
    keep = (roots.real > x0) & (roots.real < x1) & (roots.imag > y0) & (roots.imag < y1)
    out = roots[keep]
    return out[np.lexsort((-out.imag, -out.real))]


def count_roots_right_of(
    qp: TwoDelayQuasiPolynomial | CharacteristicFactor, tau1: float, tau2: float, c: float
) -> int:
    """Certified number of roots with Re s > c (multiplicity counted, persistent zero included).

    The argument principle along Re s = c closed at infinity (module
    docstring). Raises NotConvergedError when a root lies on the line.

    Parameters
    ----------
    qp
        A retarded quasi-polynomial of eq. genfactor or a factor of
        eq. factorized (a conjugate-pair factor counts the roots of lam and
        of conj(lam)). The centroid factor's persistent root s = 0
        (eq. factor1) is not deflated here: it counts when ``c < 0``.
    tau1, tau2
        Non-negative delays (s) on positions and on velocities.
    c
        Abscissa of the vertical line Re s = c; any real number.

    Returns
    -------
    int
        The number of roots strictly right of the line.

    Raises
    ------
    DelayError
        For a negative or non-finite delay.
    InputError
        When qp is neither a quasi-polynomial nor a factor.
    NotConvergedError
        When a root lies on (or within rounding of) the line.
    """
    t1, t2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    prob = _problem(qp)
    base = _Problem(prob.terms, prob.A, prob.delayed, prob.mirror)
    n = _count_right_single(base, t1, t2, float(c))
    if n is None:
        raise NotConvergedError(f"a root lies on (or within rounding of) the line Re s = {c:g}")
    if base.mirror:
        n += _count_right_single(_mirror_problem(base), t1, t2, float(c)) or 0
    return n


def _mirror_problem(prob: _Problem) -> _Problem:
    terms = tuple((np.conj(c), a, b) for c, a, b in prob.terms)
    delayed = tuple((np.conj(m), a, b) for m, a, b in prob.delayed)
    return _Problem(terms, np.conj(prob.A), delayed, False, prob.deflate_zero)


def rightmost_root(
    qp: TwoDelayQuasiPolynomial | CharacteristicFactor, tau1: float, tau2: float
) -> complex:
    """The rightmost characteristic root (for a factor, the centroid's zero excluded).

    Parameters
    ----------
    qp
        A retarded quasi-polynomial of eq. genfactor or a factor of
        eq. factorized. For the centroid factor (eq. factor1) the persistent
        root s = 0 is deflated; its other roots count (a second root at 0,
        as at tau1 = 0, is returned).
    tau1, tau2
        Non-negative delays.

    Returns
    -------
    complex
        The root with the largest real part (of a conjugate pair, the one
        with Im >= 0), relative residual <= RESIDUAL_TOL, certified as in the
        module docstring.

    Examples
    --------
    >>> from delayform.characteristic import TwoDelayQuasiPolynomial
    >>> q = TwoDelayQuasiPolynomial([1.0, 1.0], [1.0])  # s + 1 + e^{-s}
    >>> s = rightmost_root(q, 1.0, 0.0)
    >>> round(s.real, 6), round(s.imag, 6)
    (-0.605021, 1.788188)
    """
    t1, t2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    return _rightmost(_problem(qp), t1, t2)


def _rightmost(prob: _Problem, t1: float, t2: float) -> complex:
    _check_reach(prob, t1, t2)
    a1, a2 = np.array([t1]), np.array([t2])
    # fast path: the map's low-degree seeds; the certificate decides, else the robust path
    root, certified, _ = _certify(prob, a1, a2, _igd_seeds(prob, a1, a2, scale=1.0, k=_BATCH_SEEDS))
    if certified[0]:
        return _pick_rightmost(prob, root)
    res = _solve_rightmost(prob, t1, t2)
    return _pick_rightmost(prob, res.roots)


def _pick_rightmost(prob: _Problem, roots: NDArray[np.complex128]) -> complex:
    if roots.size == 0:
        raise NotConvergedError("no root right of the certified line", partial=roots)
    top = roots[np.argmax(roots.real)]
    # of a conjugate pair (or the mirror image), report the member with Im >= 0
    if prob.mirror or prob.is_real or np.all([np.all(c.imag == 0) for c, _, _ in prob.terms]):
        top = complex(top.real, abs(top.imag))
    return complex(top)


# =====================================================================
# batched rightmost roots over many delay pairs (for maps)
# =====================================================================
#: Seeds per delay pair polished in the batched path (the rightmost eigenvalues).
_BATCH_SEEDS = 8
#: Seeds further than this left of a pair's rightmost seed are not polished.
_SEED_WINDOW = 1.0
#: Spacing (in grid points) of the coarse sub-grid solved by discretization in maps.
_STRIDE = 5
#: Delay pairs per batched eigenvalue call (bounds memory).
_CHUNK = 2048


def _map_degree(hmax: NDArray[np.float64], radius: float) -> NDArray[np.int64]:
    """Degree for the batched pass: enough to seed Newton at the rightmost roots.

    Lower than :func:`_initial_degree` on purpose: the certificate decides,
    and the pairs it rejects get a discretization of twice the degree (then,
    rarely, the robust single-pair path).
    """
    return np.clip(np.ceil(0.6 * radius * hmax + 4), 6, MAX_DEGREE).astype(np.int64)


def _batch_distinct(
    roots: NDArray[np.complex128], ok: NDArray[np.bool_]
) -> NDArray[np.complex128]:
    """Per row, the distinct accepted roots first (sorted), NaN after them.

    Rows are sorted (numpy orders complex numbers by real, then imaginary
    part), so seeds that reached the same root sit side by side; a repeat
    that is not adjacent only inflates the expected count, which the
    certificate then rejects (the point is recomputed), never a wrong root.
    """
    r = np.sort(np.where(ok, roots, np.nan), axis=1)  # NaN sorts last
    close = np.abs(r[:, 1:] - r[:, :-1]) <= 1e-7 * (1.0 + np.abs(r[:, :-1]))
    dup = np.concatenate([np.zeros((r.shape[0], 1), dtype=bool), close], axis=1)
    r = np.where(dup, np.nan, r)
    keep = np.isfinite(r).sum(axis=1).max(initial=0)
    order = np.argsort(~np.isfinite(r), axis=1, kind="stable")
    return np.take_along_axis(r, order, 1)[:, : max(int(keep), 1)]


def _batch_lines(
    prob: _Problem, roots: NDArray[np.complex128]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Vectorized :func:`_choose_line`: the line c, the expected count and the rightmost real part."""
    reals = roots.real  # NaN for missing
    top = np.nanmax(np.where(np.isnan(reals), -np.inf, reals), axis=1)
    if prob.deflate_zero:
        reals = np.concatenate([reals, np.zeros((reals.shape[0], 1))], axis=1)
    srt = -np.sort(np.where(np.isnan(reals), np.inf, -reals), axis=1)  # descending, -inf for missing
    n_known = np.sum(np.isfinite(srt), axis=1)
    c = np.full(srt.shape[0], np.nan)
    k0 = np.argmax(srt <= top[:, None], axis=1)
    for step in range(8):
        k = k0 + step
        valid = (k + 1 < n_known) & np.isnan(c)
        kk = np.minimum(k, srt.shape[1] - 2)
        hi = np.take_along_axis(srt, kk[:, None], 1)[:, 0]
        lo = np.take_along_axis(srt, (kk + 1)[:, None], 1)[:, 0]
        with np.errstate(invalid="ignore"):  # -inf - -inf where fewer roots are known
            gap = hi - lo
        take = valid & (gap > 1e-3 * (1.0 + np.abs(hi)))
        c = np.where(take, hi - np.minimum(0.5 * gap, _LINE_OFFSET), c)
    last = np.take_along_axis(srt, np.clip(np.minimum(k0 + 8, n_known - 1), 0, None)[:, None], 1)[:, 0]
    c = np.where(np.isnan(c), last - _LINE_OFFSET, c)
    expected = np.sum(srt > c[:, None], axis=1).astype(float)
    return c, expected, top


def _igd_seeds(
    prob: _Problem, t1: NDArray[np.float64], t2: NDArray[np.float64], *, scale: float, k: int
) -> NDArray[np.complex128]:
    """The k rightmost eigenvalues of the discretized generator at each pair (NaN-padded).

    One stacked np.linalg.eigvals call per bucket of equal degree; pairs
    with no delay get the eigenvalues of A + sum B_k. The persistent zero of
    eq. factor1, which the discretization keeps exactly, is dropped.
    """
    out = np.full((t1.size, k), np.nan + 0j, dtype=np.complex128)
    hmax = np.maximum.reduce([a * t1 + b * t2 for _, a, b in prob.delayed] + [np.zeros(t1.size)])
    degree = np.minimum(MAX_DEGREE, np.ceil(scale * _map_degree(hmax, _root_scale(prob)))).astype(int)
    delayed = hmax >= _TINY_DELAY
    groups = [(np.flatnonzero(~delayed), 0)] + [
        (np.flatnonzero((degree == N) & delayed), int(N)) for N in np.unique(degree[delayed])
    ]
    for idx_all, N in groups:
        for start in range(0, idx_all.size, _CHUNK):
            idx = idx_all[start : start + _CHUNK]
            if N == 0:
                eig = np.tile(_delay_free_eigenvalues(prob), (idx.size, 1))
            else:
                eig = _igd_eigenvalues(prob, N, t1[idx], t2[idx])
            if prob.deflate_zero:
                eig[np.arange(idx.size), np.argmin(np.abs(eig), axis=1)] = -np.inf
            if prob.is_real:  # roots pair up: keep one member, _certify adds the other
                eig = np.where(eig.imag >= 0.0, eig, -np.inf)
            order = np.argsort(-eig.real, axis=1)[:, :k]
            top = np.take_along_axis(eig, order, 1)
            top[~np.isfinite(top)] = np.nan
            out[idx, : top.shape[1]] = top
    return out


def _certify(
    prob: _Problem, t1: NDArray[np.float64], t2: NDArray[np.float64], seeds: NDArray[np.complex128]
) -> tuple[NDArray[np.complex128], NDArray[np.bool_], NDArray[np.complex128]]:
    """Polish seeds (B, K) at each pair; certify the rightmost; return (rightmost, certified, roots).

    For a real q only seeds with Im >= 0 are polished and the conjugates of
    the roots added afterwards (half the Newton work).
    """
    if prob.is_real:
        seeds = np.where(seeds.imag >= 0.0, seeds, np.nan)
    if prob.deflate_zero:  # a seed at the persistent 0 cannot move under Maehly's step
        seeds = np.where(np.abs(seeds) < 1e-6, -1e-2, seeds)
    # seeds far left of a row's rightmost one cannot matter for the line c (within
    # _LINE_OFFSET of the top); dropping them saves Newton steps, and a wrong
    # drop only costs a rejected certificate
    with np.errstate(invalid="ignore"):
        top_seed = np.nanmax(np.where(np.isfinite(seeds), seeds.real, -np.inf), axis=1)
        seeds = np.where(seeds.real >= top_seed[:, None] - _SEED_WINDOW, seeds, np.nan)
    roots, ok = _polish(prob, seeds, t1[:, None], t2[:, None])
    ok &= np.isfinite(seeds)
    if prob.is_real:  # distinct members with Im >= 0 first, then their mirror images
        roots = _batch_distinct(np.where(roots.imag < 0.0, np.conj(roots), roots), ok)
        pair = np.abs(roots.imag) > 1e-9 * (1.0 + np.abs(roots))
        roots = np.concatenate([roots, np.where(pair, np.conj(roots), np.nan)], axis=1)
    else:
        roots = _batch_distinct(roots, ok)
    c, expected, top = _batch_lines(prob, roots)
    good = np.isfinite(top) & np.isfinite(c)
    counts = np.full(t1.size, np.nan)
    if good.any():
        counts[good] = _count_right_batch(prob, t1[good], t2[good], c[good])
    certified = good & (counts == expected)
    best = np.argmax(np.where(np.isnan(roots.real), -np.inf, roots.real), axis=1)
    return roots[np.arange(t1.size), best], certified, roots


def _coarse_axis(n: int, stride: int) -> NDArray[np.int64]:
    idx = np.arange(0, n, stride)
    return idx if idx[-1] == n - 1 else np.append(idx, n - 1)


def _rightmost_grid(
    prob: _Problem, ax1: NDArray[np.float64], ax2: NDArray[np.float64],
    advance: Callable[[int], None] | None = None, *, stride: int = _STRIDE,
) -> NDArray[np.complex128]:
    """Certified rightmost root of one factor at every point of a delay grid (shape (n1, n2)).

    1. A coarse sub-grid (every ``stride``-th point) is solved by the stacked
       discretization (:func:`_igd_seeds`) and Newton.
    2. Every other grid point starts Newton from the roots of its nearest
       coarse point (roots move continuously with the delays), all at once.
    3. Every point is certified by the argument principle
       (:func:`_count_right_batch`); points that fail get their own stacked
       discretization at a higher degree, and the few left the robust
       single-pair path (:func:`_solve_rightmost`).
    """
    n1, n2 = ax1.size, ax2.size
    T1, T2 = np.meshgrid(ax1, ax2, indexing="ij")
    t1, t2 = T1.ravel(), T2.ravel()
    out = np.full(t1.size, np.nan + 0j, dtype=np.complex128)
    done = np.zeros(t1.size, dtype=bool)
    c1, c2 = _coarse_axis(n1, stride), _coarse_axis(n2, stride)
    coarse = (c1[:, None] * n2 + c2[None, :]).ravel()
    seeds = _igd_seeds(prob, t1[coarse], t2[coarse], scale=1.0, k=_BATCH_SEEDS)
    root, cert, roots = _certify(prob, t1[coarse], t2[coarse], seeds)
    out[coarse[cert]], done[coarse[cert]] = root[cert], True
    if advance is not None:
        advance(int(coarse.size))
    # nearest coarse point of every grid point; coarse rows of roots as seeds
    near1 = np.abs(np.arange(n1)[:, None] - c1[None, :]).argmin(axis=1)
    near2 = np.abs(np.arange(n2)[:, None] - c2[None, :]).argmin(axis=1)
    nearest = (near1[:, None] * c2.size + near2[None, :]).ravel()
    rest = np.flatnonzero(~done)
    rest = rest[~np.isin(rest, coarse[~cert])]  # failed coarse points go to the fallback
    for start in range(0, rest.size, 4 * _CHUNK):
        idx = rest[start : start + 4 * _CHUNK]
        seed = roots[nearest[idx]]
        r, ok, _ = _certify(prob, t1[idx], t2[idx], seed)
        out[idx[ok]], done[idx[ok]] = r[ok], True
        if advance is not None:
            advance(int(idx.size))
    left = np.flatnonzero(~done)
    if left.size:
        seeds = _igd_seeds(prob, t1[left], t2[left], scale=2.0, k=2 * _BATCH_SEEDS)
        r, ok, _ = _certify(prob, t1[left], t2[left], seeds)
        out[left[ok]], done[left[ok]] = r[ok], True
    for i in np.flatnonzero(~done):
        res = _solve_rightmost(prob, float(t1[i]), float(t2[i]))
        out[i] = _pick_rightmost(prob, res.roots)
    if prob.mirror or prob.is_real:
        out = out.real + 1j * np.abs(out.imag)
    return out.reshape(n1, n2)


# =====================================================================
# public: dominant root of the formation, maps, scheduling
# =====================================================================
@dataclass(frozen=True)
class DominantRoot:
    """The dominant (rightmost) characteristic root of the formation at one delay pair.

    One meaning of *stable* throughout delayform (docs/theory.md): the team
    is stable when every root of every factor of eq. factorized has
    Re s < 0, except the centroid factor's roots at s = 0. The persistent
    root 0 of eq. factor1 is the team's freedom to sit anywhere; on the line
    tau1 = 0 the centroid factor has a second root at 0, a centroid that
    drifts at constant speed. Neither changes the shape the agents reach,
    so neither counts (the CTCR map treats the tau1 = 0 line the same way).

    Attributes
    ----------
    root
        The rightmost root over all factors, the centroid factor's roots at
        s = 0 excluded; of a conjugate pair the member with Im >= 0.
    factor
        The factor it belongs to.
    tau1, tau2
        The delays.
    formation_root
        The rightmost root of the disagreement factors (every factor but the
        centroid's): how fast the agents reach the formation's *shape*.
    centroid_root
        The rightmost non-zero root of the centroid factor (how fast the
        centroid's velocity settles), or None when it has none (tau1 = tau2 = 0).
    """

    root: complex
    factor: CharacteristicFactor
    tau1: float
    tau2: float
    formation_root: complex | None = None
    centroid_root: complex | None = None

    @property
    def is_stable(self) -> bool:
        """True when Re root < 0: every mode except the centroid's drift decays (Lemma 2)."""
        return self.root.real < 0.0

    @property
    def time_constant(self) -> float:
        """1 / |Re root| for a decaying root; ``math.inf`` when it does not decay (see growth_rate)."""
        return _decay_time(self.root)

    @property
    def growth_rate(self) -> float:
        """Re root when the root grows (unstable), else 0.0 (1/s)."""
        return max(self.root.real, 0.0)

    @property
    def formation_time_constant(self) -> float:
        """Time constant of the shape (disagreement) modes; ``math.inf`` when they do not decay."""
        return _decay_time(self.root if self.formation_root is None else self.formation_root)

    @property
    def centroid_time_constant(self) -> float | None:
        """Time constant of the centroid's velocity, None when the centroid factor has no non-zero root."""
        return None if self.centroid_root is None else _decay_time(self.centroid_root)

    @property
    def is_centroid_drift(self) -> bool:
        """True when the dominant root belongs to the centroid factor, not to the shape."""
        return bool(self.factor.is_centroid)


def _decay_time(root: complex) -> float:
    return 1.0 / -root.real if root.real < 0.0 else math.inf


def _centroid_rightmost(factor: CharacteristicFactor, t1: float, t2: float) -> complex | None:
    """Rightmost root of the centroid factor with its roots at s = 0 removed.

    For tau1 > 0 the factor has the single persistent root 0, deflated by
    :func:`rightmost_root`. On tau1 = 0 it is s (s + D - D e^{-tau2 s}): the
    second factor r has a simple root at 0 too (the drift), so its deflated
    rightmost root is the answer; for tau2 = 0 as well, r = s has no other root.
    """
    if t1 > 0.0:
        return rightmost_root(factor, t1, t2)
    if t2 == 0.0:
        return None
    D = factor.D
    r = TwoDelayQuasiPolynomial([D, 1.0], [], [-D])
    prob = _problem_of_qp(r)
    return _rightmost(_Problem(prob.terms, prob.A, prob.delayed, prob.mirror, True), t1, t2)


def _checked_factors(topology: Topology, P: float, D: float) -> tuple[CharacteristicFactor, ...]:
    if not isinstance(topology, Topology):
        raise InputError(f"topology must be a Topology, got {type(topology).__name__}")
    topology.require_spanning_tree()
    P, D = check_gains(P, D)
    return factors(topology, P, D)


def dominant_root(topology: Topology, P: float, D: float, tau1: float, tau2: float) -> DominantRoot:
    """The dominant root of the formation and its time constant.

    Parameters
    ----------
    topology
        Communication topology; it must have a spanning tree (Lemma 3).
    P, D
        Positive gains of eq. protocol.
    tau1, tau2
        Non-negative delays on positions and velocities.

    Returns
    -------
    DominantRoot
        The rightmost root over the factors of eq. factorized, excluding the
        persistent root 0 of eq. factor1 (its other roots count).

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> r = dominant_root(paper_six(), 1.0, 0.5, 1.0, 2.0)  # point c of Fig. stability
    >>> r.is_stable, round(r.root.real, 4)
    (False, 0.0836)
    """
    t1, t2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    fs = _checked_factors(topology, P, D)
    centroid = next(f for f in fs if f.is_centroid)
    shape = [(rightmost_root(f, t1, t2), f) for f in fs if not f.is_centroid]
    drift = _centroid_rightmost(centroid, t1, t2)
    formation = max(shape, key=lambda rf: rf[0].real)
    best = formation if drift is None or formation[0].real >= drift.real else (drift, centroid)
    return DominantRoot(best[0], best[1], t1, t2, formation_root=formation[0], centroid_root=drift)


@dataclass(frozen=True, eq=False)
class DominantRootMap:
    """Dominant roots over a grid of delays (paper Figs. dominant and contour).

    Attributes
    ----------
    tau1_values, tau2_values
        The grid axes; ``roots[i, j]`` is at (tau1_values[i], tau2_values[j]).
    roots
        Dominant root at each grid point (complex array).
    factor_index
        Index into ``factors`` of the factor the dominant root belongs to.
    factors
        The factors of eq. factorized.
    """

    tau1_values: NDArray[np.float64]
    tau2_values: NDArray[np.float64]
    roots: NDArray[np.complex128]
    factor_index: NDArray[np.int64]
    factors: tuple[CharacteristicFactor, ...]

    @property
    def real(self) -> NDArray[np.float64]:
        """Re(dominant root) at each grid point, the surface of Fig. dominant."""
        return self.roots.real

    @property
    def stable(self) -> NDArray[np.bool_]:
        """True where Re(dominant root) < 0."""
        return self.roots.real < 0.0

    @property
    def time_constant(self) -> NDArray[np.float64]:
        """1 / |Re(dominant root)| at each grid point."""
        with np.errstate(divide="ignore"):
            return 1.0 / np.abs(self.roots.real)

    def best(self) -> tuple[float, float, complex]:
        """The grid point with the leftmost dominant root: (tau1, tau2, root)."""
        i, j = np.unravel_index(int(np.argmin(self.roots.real)), self.roots.shape)
        return float(self.tau1_values[i]), float(self.tau2_values[j]), complex(self.roots[i, j])

    def plot_surface(self, ax: Axes | None = None) -> Axes:
        """Surface of Re(dominant root) with the plane Re s = 0 (paper Fig. dominant)."""
        from delayform.plots import plot_dominant_surface

        return plot_dominant_surface(self, ax=ax)

    def plot_contour(self, ax: Axes | None = None) -> Axes:
        """Contour map of Re(dominant root) (paper Fig. contour)."""
        from delayform.plots import plot_dominant_contour

        return plot_dominant_contour(self, ax=ax)


def _grid_axis(name: str, values: ArrayLike) -> NDArray[np.float64]:
    try:
        arr = np.atleast_1d(np.asarray(values, dtype=np.float64))
    except (TypeError, ValueError) as exc:
        raise DelayError(f"{name} must be a sequence of delays") from exc
    if arr.ndim != 1 or arr.size == 0:
        raise DelayError(f"{name} must be a non-empty 1-D sequence of delays")
    if not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
        raise DelayError(f"{name} must hold finite non-negative delays")
    return arr


def dominant_root_map(
    topology: Topology,
    P: float,
    D: float,
    tau1_values: ArrayLike,
    tau2_values: ArrayLike,
    *,
    progress: bool | Callable[[int, int], None] = False,
) -> DominantRootMap:
    """Dominant root at every point of a delay grid (paper Figs. dominant and contour).

    Fast by design: per factor, every grid point's discretized generator is
    solved in stacked eigenvalue calls (one degree per bucket of the largest
    delay), the rightmost eigenvalues of all points are Newton-polished
    together and certified together by the argument principle; only the
    points the certificate rejects are redone one by one at higher degree.
    A conjugate-pair factor is solved through its second-order factor of lam.

    Parameters
    ----------
    topology
        Communication topology with a spanning tree.
    P, D
        Positive gains.
    tau1_values, tau2_values
        Non-empty 1-D grids of non-negative delays.
    progress
        True shows a Rich progress bar on stderr; a callable is called as
        ``progress(done, total)`` (grid points times factors) as work finishes,
        for callers that draw their own bar.

    Returns
    -------
    DominantRootMap

    Raises
    ------
    ResourceLimitError
        When the grid would need more memory or time than the machine allows.
    DelayError
        When the grid's delays are too long for the root finder (about 30 s
        for gains of order 1).

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> m = dominant_root_map(paper_six(), 1.0, 0.5, [0.3, 1.0], [0.2, 2.0])
    >>> m.stable.tolist()
    [[True, True], [True, False]]
    """
    fs = _checked_factors(topology, P, D)
    ax1 = _grid_axis("tau1_values", tau1_values)
    ax2 = _grid_axis("tau2_values", tau2_values)
    points = float(ax1.size) * float(ax2.size)
    # measured: ~1.3e-4 s per grid point and factor on the paper's map; ~20 work arrays per point
    require(
        what=f"a dominant-root map of {ax1.size} x {ax2.size} delay pairs and {len(fs)} factors",
        setting="the grid size (map.size, --size)",
        nbytes=points * (320.0 + 16.0 * len(fs)),
        seconds=points * len(fs) * 2e-4,
    )
    for f in fs:
        _check_reach(_problem_of_factor(f), float(ax1.max()), float(ax2.max()))
    per_factor = np.empty((len(fs), ax1.size, ax2.size), dtype=np.complex128)
    with _progress(progress, len(fs) * ax1.size * ax2.size) as advance:
        for k, f in enumerate(fs):
            per_factor[k] = _rightmost_grid(_problem_of_factor(f), ax1, ax2, advance)
            if f.is_centroid:  # on tau1 = 0 the centroid's second zero is its drift, not instability
                for i in np.flatnonzero(ax1 == 0.0):
                    for j, t2 in enumerate(ax2):
                        r = _centroid_rightmost(f, 0.0, float(t2))
                        per_factor[k, i, j] = -np.inf if r is None else r
    index = np.argmax(per_factor.real, axis=0)
    roots = np.take_along_axis(per_factor, index[None], 0)[0]
    return DominantRootMap(ax1, ax2, roots, index, fs)


class _progress:
    """Context manager yielding an ``advance(n)`` callback: a Rich bar, the caller's callback, or None."""

    def __init__(self, enabled: bool | Callable[[int, int], None], total: int) -> None:
        self.enabled, self.total = enabled, total
        self._bar: Any = None

    def __enter__(self) -> Callable[[int], None] | None:
        if callable(self.enabled):
            report, done = self.enabled, [0]

            def advance(n: int) -> None:
                done[0] += n
                report(min(done[0], self.total), self.total)

            return advance
        if not self.enabled:
            return None
        from rich.console import Console
        from rich.progress import Progress

        # stderr, so machine-readable output on stdout stays clean
        self._bar = Progress(transient=True, console=Console(stderr=True))
        self._bar.start()
        task = self._bar.add_task("dominant roots", total=self.total)
        return lambda n: self._bar.advance(task, n)

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()
