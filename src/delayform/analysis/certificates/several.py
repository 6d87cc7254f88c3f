"""Certified margins of x' = A0 x + sum_k A_k x(t - h_k(t)), each delay varying in its own interval.

:func:`certify_interval_delays` answers one question: is the system stable for
every h_k(t) in [lo_k, hi_k] (any variation, or |h_k'| <= mu)?
:func:`interval_delay_margin` finds the largest delta such that it is for every
h_k(t) in [h_k - delta, h_k + delta] (clipped at 0) around nominal delays h_k.
The functional is :func:`~delayform.analysis.certificates.intervals.interval_delays`;
the solve and the independent re-check are those of
:mod:`~delayform.analysis.certificates.margin` ("holds" only after both the
eigenvalue and the exact rational re-check).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform.analysis.certificates.intervals import IntervalDelays, interval_delays
from delayform.analysis.certificates.lmi import LmiProblem, recheck, solve, solver_says_infeasible
from delayform.analysis.certificates.margin import (
    _INEQUALITY,
    MAX_STATES,
    DelayCertificate,
    _Attempt,
    _delay,
    _matrix,
    _order,
    _rate,
)
from delayform.errors import DelayError, InputError

__all__ = ["IntervalMargin", "certify_interval_delays", "interval_delay_margin", "MAX_DELAYS", "Functional"]

#: Most delayed terms (the derivative bound is checked at the 2^K corners of the delays).
MAX_DELAYS = 4
#: Most constant windows per gap (delay partitioning).
MAX_SPLIT = 4


@dataclass(frozen=True)
class Functional:
    """Which functional: Bessel-Legendre order N, pieces per constant window, outer integrals (with the improved bound).

    ``upper``: the constant windows are also cut at the delays' upper ends. ``cover``: they go on over
    the delays' intervals (cut at every upper end), the integral over each interval tied to its parts'.
    """

    order: int = 2
    split: int = 1
    outer: bool = True
    upper: bool = False
    cover: bool = False

    def describe(self) -> str:
        """One line naming the functional."""
        ineq = _INEQUALITY.get(self.order, f"Bessel-Legendre N={self.order}")
        parts = f", {self.split} pieces per constant window" if self.split > 1 else ""
        parts += ", windows cut at the upper ends" if self.upper and not self.cover else ""
        parts += ", windows over the delays' intervals" if self.cover else ""
        rcc = "improved reciprocally convex, outer integrals" if self.outer and self.order >= 1 else "reciprocally convex"
        return f"Lyapunov-Krasovskii, several interval delays, {ineq}{parts}, {rcc}"

    def problem(self, data: IntervalDelays) -> LmiProblem:
        """This functional's LMIs on ``data``."""
        return interval_delays(data, self.order, split=self.split, outer=self.outer, upper=self.upper, cover=self.cover)


def system_of(A0: ArrayLike, delayed: Sequence[ArrayLike]) -> tuple[NDArray[np.float64], tuple[NDArray[np.float64], ...]]:
    """A0 and the delayed matrices, checked: real, square, one shape, at most :data:`MAX_DELAYS` of them."""
    a0 = _matrix("A0", A0)
    if isinstance(delayed, np.ndarray) and delayed.ndim == 2:
        delayed = [delayed]
    if not isinstance(delayed, (list, tuple, np.ndarray)) or not 1 <= len(delayed) <= MAX_DELAYS:
        raise InputError(f"delayed must be a sequence of 1 to {MAX_DELAYS} matrices A_k")
    out = tuple(_matrix(f"A_{k + 1}", A) for k, A in enumerate(delayed))
    if any(A.shape != a0.shape for A in out):
        raise InputError(f"every A_k must have the shape of A0 {a0.shape}")
    if a0.shape[0] > MAX_STATES:
        raise InputError(f"at most {MAX_STATES} states are certified (the LMIs grow fast), got {a0.shape[0]}")
    return a0, out


def invariant_of(a0: NDArray[np.float64], delayed: tuple[NDArray[np.float64], ...],
                 e: ArrayLike | None) -> NDArray[np.float64] | None:  # fmt: skip
    """The direction of constant solutions, checked exactly: (A0 + sum A_k) e = 0 in rational arithmetic."""
    if e is None:
        return None
    try:
        v = np.asarray(e, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"invariant must be a vector of {a0.shape[0]} real numbers") from None
    if v.shape != (a0.shape[0],) or not np.all(np.isfinite(v)) or not np.any(v != 0.0):
        raise InputError(f"invariant must be a finite non-zero vector of length {a0.shape[0]}")
    total = [[Fraction(a0[i, j]) + sum(Fraction(A[i, j]) for A in delayed) for j in range(a0.shape[0])]
             for i in range(a0.shape[0])]  # fmt: skip
    if any(sum(row[j] * Fraction(v[j]) for j in range(v.size)) != 0 for row in total):
        raise InputError("invariant e must satisfy (A0 + sum A_k) e = 0 exactly: constants along e must be solutions")
    return v


def functional_of(order: object, split: object, outer: object, cover: object = False) -> Functional:
    """The functional's options, checked."""
    if isinstance(split, bool) or not isinstance(split, (int, np.integer)) or not 1 <= int(split) <= MAX_SPLIT:
        raise InputError(f"split must be an integer from 1 to {MAX_SPLIT}, got {split!r}")
    if not isinstance(outer, bool):
        raise InputError(f"outer must be True or False, got {outer!r}")
    if not isinstance(cover, bool):
        raise InputError(f"cover must be True or False, got {cover!r}")
    return Functional(_order(order), int(split), outer, cover=cover)


def attempt(data: IntervalDelays, fun: Functional, *, exact: bool = True, tolerance: float | None = None,
            quick: bool = False, balance: bool = False) -> _Attempt:  # fmt: skip
    """Solve the functional's LMIs on ``data`` and re-check the answer (exactly unless ``exact`` is False).

    ``tolerance``, ``quick``, ``balance``: the solver's (:func:`~delayform.analysis.certificates.lmi.solve`); the
    re-check is the same.
    """
    problem = fun.problem(data)
    sol = solve(problem, tolerance=tolerance, quick=quick, balance=balance)
    lo, hi = min(data.lo), max(data.hi)
    empty: dict[str, NDArray[np.float64]] = {}
    method = fun.describe()
    if not (math.isfinite(sol.t) and sol.t > 0.0):
        status = "does not hold" if solver_says_infeasible(sol) else "undecided"
        return _Attempt(DelayCertificate(status, method, fun.order, lo, hi, data.mu, empty, empty, {}, None, sol.status,
                                         sol.t), None, None, sol)  # fmt: skip
    check = recheck(problem, sol.x, exact=exact)
    cert = DelayCertificate("holds" if check.passed else "undecided", method, fun.order, lo, hi, data.mu, check.values,
                            check.matrices, check.min_eigenvalues, check.exact_ok, sol.status, sol.t)  # fmt: skip
    return _Attempt(cert, problem, check, sol)


def _intervals(lo: Sequence[float], hi: Sequence[float], k: int) -> tuple[tuple[float, ...], tuple[float, ...]]:
    if len(lo) != k or len(hi) != k:
        raise DelayError(f"lo and hi must give one interval per delayed matrix ({k}), got {len(lo)} and {len(hi)}")
    a = tuple(_delay(f"lo[{i}]", v) for i, v in enumerate(lo))
    b = tuple(_delay(f"hi[{i}]", v) for i, v in enumerate(hi))
    for i in range(k):
        if not b[i] > a[i]:
            raise DelayError(f"interval {i}: hi = {b[i]:g} must exceed lo = {a[i]:g} (a constant delay is [h, h + tiny])")
    return a, b


def certify_interval_delays(A0: ArrayLike, delayed: Sequence[ArrayLike], lo: Sequence[float], hi: Sequence[float], *,
                            mu: float | None = None, order: int = 2, split: int = 1, outer: bool = True,
                            cover: bool = False, invariant: ArrayLike | None = None) -> DelayCertificate:  # fmt: skip
    """Certify x' = A0 x + sum_k A_k x(t - h_k(t)) stable for every h_k(t) in [lo_k, hi_k].

    Parameters
    ----------
    A0, delayed
        Real n x n matrices (n <= 8), one to :data:`MAX_DELAYS` delayed ones.
    lo, hi
        The interval of each delay (hi_k > lo_k >= 0).
    mu
        Bound on every |dh_k/dt|; None (default) for any variation.
    order, split, outer, cover
        The functional (:class:`Functional`): Bessel-Legendre order N, pieces per
        constant window, outer-window integrals with the improved reciprocally convex bound,
        constant windows also over the delays' intervals (tighter, larger LMIs; docs/theory.md).
    invariant
        A vector e with (A0 + sum A_k) e = 0 exactly: constants along e are solutions
        for any delays, and what is certified is the rest (the solution converges to
        such a constant). None: plain stability.

    Returns
    -------
    DelayCertificate
        ``h1``, ``h2`` are the smallest lo and largest hi; "holds" only after the
        independent re-check (eigenvalues and exact rational arithmetic).

    Examples
    --------
    One delay is the single-delay case: the benchmark of Gu, Kharitonov and Chen, any variation in [0, 1]:

    >>> A0, A1 = [[-2.0, 0.0], [0.0, -0.9]], [[-1.0, 0.0], [-1.0, -1.0]]
    >>> certify_interval_delays(A0, [A1], [0.0], [1.0]).holds
    True
    """
    a0, ak = system_of(A0, delayed)
    a, b = _intervals(lo, hi, len(ak))
    fun = functional_of(order, split, outer, cover)
    data = IntervalDelays(a0, ak, a, b, _rate(mu), invariant_of(a0, ak, invariant))
    return attempt(data, fun).cert


@dataclass(frozen=True)
class IntervalMargin:
    """The largest certified deviation delta around nominal delays, with its certificate.

    Attributes
    ----------
    delta
        Every h_k(t) in [h_k - delta, h_k + delta] (clipped at 0) is certified; 0 when
        not even a small deviation was (or the nominal system itself was not certified).
    nominal
        The nominal delays h_k.
    certificate
        The certificate at ``delta`` (None when delta is 0).
    tried
        Every (delta, status) tried by the search, in order.
    tolerance
        The gap to the first uncertified delta when the search stopped.
    """

    delta: float
    nominal: tuple[float, ...]
    certificate: DelayCertificate | None = field(repr=False)
    tried: tuple[tuple[float, str], ...] = field(repr=False)
    tolerance: float


def interval_data(a0: NDArray[np.float64], ak: tuple[NDArray[np.float64], ...], nominal: Sequence[float], delta: float,
                  mu: float | None, e: NDArray[np.float64] | None) -> IntervalDelays:  # fmt: skip
    """The intervals [h_k - delta, h_k + delta] clipped at 0."""
    return IntervalDelays(a0, ak, tuple(max(h - delta, 0.0) for h in nominal), tuple(h + delta for h in nominal), mu, e)


def search_delta(holds: Callable[[float], _Attempt | None], start: float, cap: float, rtol: float
                 ) -> tuple[float, _Attempt | None, list[tuple[float, str]], float]:  # fmt: skip
    """Largest delta in (0, cap] with ``holds(delta)`` not None: doubling from ``start``, then bisection to ``rtol``.

    Returns (delta, its attempt, the steps tried, the final gap); (0, None, ...) when nothing held.
    """
    tried: list[tuple[float, str]] = []
    best: tuple[float, _Attempt] | None = None

    def step(d: float) -> bool:
        att = holds(d)
        tried.append((d, "holds" if att is not None else "not certified"))
        nonlocal best
        if att is not None and (best is None or d > best[0]):
            best = (d, att)
        return att is not None

    lo, hi = 0.0, min(start, cap)
    while step(hi):
        lo = hi
        if hi >= cap:
            return hi, best[1] if best else None, tried, 0.0
        hi = min(2.0 * hi, cap)
    while hi - lo > rtol * max(lo, 1e-3 * start) and (lo > 0.0 or hi > 1e-3 * start):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if step(mid) else (lo, mid)
    if best is None:
        return 0.0, None, tried, hi
    return best[0], best[1], tried, hi - best[0]


def interval_delay_margin(A0: ArrayLike, delayed: Sequence[ArrayLike], nominal: Sequence[float], *,
                          mu: float | None = None, order: int = 2, split: int = 1, outer: bool = True,
                          cover: bool = False, invariant: ArrayLike | None = None, rtol: float = 0.01,
                          max_delta: float | None = None) -> IntervalMargin:  # fmt: skip
    """The largest delta such that every h_k(t) in [h_k - delta, h_k + delta] (clipped at 0) is certified.

    Parameters
    ----------
    A0, delayed, mu, order, split, outer, cover, invariant
        As for :func:`certify_interval_delays`.
    nominal
        The nominal delays h_k, one per delayed matrix.
    rtol
        Relative width at which the search stops (0.001 to 0.1).
    max_delta
        The search does not look past this (default the largest nominal delay, or 1).

    Returns
    -------
    IntervalMargin
        The answer's certificate passed the exact re-check (the search itself
        re-checks by eigenvalues, and steps back if the exact check fails).
    """
    a0, ak = system_of(A0, delayed)
    if len(nominal) != len(ak):
        raise DelayError(f"nominal must give one delay per delayed matrix ({len(ak)}), got {len(nominal)}")
    hs = tuple(_delay(f"nominal[{i}]", v) for i, v in enumerate(nominal))
    if not (isinstance(rtol, (int, float)) and 1e-3 <= rtol <= 0.1):
        raise InputError(f"rtol must be a number from 0.001 to 0.1, got {rtol!r}")
    cap = _delay("max_delta", max_delta) if max_delta is not None else max(max(hs), 1.0)
    if not cap > 0.0:
        raise DelayError("max_delta must be positive")
    fun = functional_of(order, split, outer, cover)
    rate, e = _rate(mu), invariant_of(a0, ak, invariant)

    def holds(d: float) -> _Attempt | None:
        att = attempt(interval_data(a0, ak, hs, d, rate, e), fun, exact=False)
        return att if att.cert.holds else None

    return confirm_margin(holds, hs, cap, rtol)


def confirm_margin(holds: Callable[[float], _Attempt | None], hs: tuple[float, ...], cap: float,
                   rtol: float) -> IntervalMargin:  # fmt: skip
    """The search, then the exact re-check of its answer (halving delta while it fails)."""
    start = 0.05 * max(max(hs), 0.2)
    delta, att, tried, gap = search_delta(holds, start, cap, rtol)
    while att is not None:
        cert = att.confirmed()
        if cert.holds:
            return IntervalMargin(delta, hs, cert, tuple(tried), gap)
        tried.append((delta, cert.status))
        delta *= 0.5
        att = holds(delta) if delta > 1e-3 * start else None
    return IntervalMargin(0.0, hs, None, tuple(tried), gap)

