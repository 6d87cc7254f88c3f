"""Certified delay margins of x' = A0 x + A1 x(t - h(t)) for constant and time-varying delays.

:func:`certify_time_varying` answers one question: is the system stable for
every delay h(t) in [h1, h2] with |dh/dt| <= mu (any variation for mu None;
constant delays for mu = 0)? :func:`time_varying_delay_margin` finds the
largest such h2. Both use the Lyapunov-Krasovskii functionals of
:mod:`~delayform.analysis.certificates.krasovskii` with the Bessel-Legendre
inequality of the order the caller picks, solved by Clarabel and re-checked
independently (:func:`~delayform.analysis.certificates.lmi.recheck`): a
certificate "holds" only when its rebuilt matrices are positive definite by
their eigenvalues and, for these small matrices, in exact arithmetic.

The conditions are sufficient: "does not hold" means that the solver found no
strictly feasible point of *this* LMI (its word, not re-checked), never that
the system is unstable.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform.analysis.certificates.krasovskii import SystemData, constant_delay, time_varying
from delayform.analysis.certificates.lmi import (
    LmiProblem,
    Recheck,
    SdpSolution,
    exact_check,
    recheck,
    solve,
    solver_says_infeasible,
)
from delayform._validation import validated
from delayform.resources import require
from delayform.errors import DelayError, InputError

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes

__all__ = ["DelayCertificate", "TimeVaryingMargin", "certify_time_varying", "time_varying_delay_margin", "MAX_ORDER"]

#: Highest Bessel-Legendre order offered (the LMIs grow as (N + 2) n; N = 4 already reaches 6.1724 of 6.1726).
MAX_ORDER = 5
#: Largest state dimension accepted (the exact re-check grows as the cube of the LMI size).
MAX_STATES = 8
#: Largest entry of A0, A1 accepted in size (the LMIs square it with h).
_MAX_ENTRY = 1e6

Status = Literal["holds", "does not hold", "undecided"]
_INEQUALITY = {0: "Jensen", 1: "Wirtinger"}


@validated()
@dataclass(frozen=True)
class DelayCertificate:
    """A stability certificate (or its absence) for delays h(t) in [h1, h2].

    Attributes
    ----------
    status
        "holds": the LMIs are satisfied by ``variables``, re-checked
        independently; "does not hold": the solver reports no strictly
        feasible point of these LMIs, its optimum margin clearly negative (a
        sufficient condition: the system may still be stable); "undecided":
        neither, e.g. an optimum margin of about zero (the boundary of the
        feasible set, or a decoupled part certified alone), a solver that
        stopped short, or an answer that failed the re-check.
    method, order
        The functional and the Bessel-Legendre order N (0 Jensen, 1 Wirtinger).
    h1, h2, mu
        The delay interval and the rate bound (0: constant delays; None: any variation).
    variables
        The decision matrices (P, S, R, ... and the slack X), rounded to the
        dyadic grid the re-check used.
    lmis
        Every matrix that must be positive definite, rebuilt from ``variables``.
    min_eigenvalues
        Smallest eigenvalue of each, relative to its 2-norm.
    exact
        True when every matrix was positive definite in exact rational
        arithmetic too; None when not run.
    solver_status, solver_margin
        Clarabel's status and its optimum common margin t.
    """

    status: Status
    method: str
    order: int
    h1: float
    h2: float
    mu: float | None
    variables: Mapping[str, NDArray[np.float64]] = field(repr=False)
    lmis: Mapping[str, NDArray[np.float64]] = field(repr=False)
    min_eigenvalues: Mapping[str, float] = field(repr=False)
    exact: bool | None
    solver_status: str
    solver_margin: float

    @property
    def holds(self) -> bool:
        """The certificate proves stability on [h1, h2]."""
        return self.status == "holds"


@validated()
@dataclass(frozen=True)
class TimeVaryingMargin:
    """The largest certified h2 and the certificates that prove it.

    Attributes
    ----------
    margin
        The largest h2 found for which stability on [h1, h2] is certified;
        None when not even a short interval above h1 was.
    h1, mu, order, method
        As for :func:`time_varying_delay_margin`.
    certificates
        The proof: one certificate on [h1, margin] for varying delays; for
        constant delays (mu = 0) consecutive intervals covering [h1, margin],
        each with its own matrices (a constant delay needs one functional).
    tried
        Every (h2, status) tried by the search, in order.
    tolerance
        The search stopped when the gap to the first uncertified h2 was below
        this (absolute).
    reached_cap
        The search stopped at ``max_delay`` with every step certified.
    """

    margin: float | None
    h1: float
    mu: float | None
    order: int
    method: str
    certificates: tuple[DelayCertificate, ...] = field(repr=False)
    tried: tuple[tuple[float, str], ...] = field(repr=False)
    tolerance: float
    reached_cap: bool

    def plot(self, ax: Axes | None = None) -> Axes:
        """The search: each tried h2 marked by its status, the certified interval shaded."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(6.0, 2.2))
        if self.margin is not None:
            ax.axvspan(self.h1, self.margin, color="tab:green", alpha=0.2, label="certified")
        colours = {"holds": "tab:green", "does not hold": "tab:red", "undecided": "tab:orange"}
        for status, colour in colours.items():
            hs = [h for h, s in self.tried if s == status]
            if hs:
                ax.plot(hs, np.zeros(len(hs)), "|", ms=18, color=colour, label=status)
        ax.set_yticks([])
        ax.set_xlabel("h2")
        rate = "any rate" if self.mu is None else f"|h'| <= {self.mu:g}"
        ax.set_title(f"{self.method}, {rate}: margin {self.margin if self.margin is None else round(self.margin, 5)}")
        ax.legend(loc="upper left", fontsize="small")
        return ax


def _matrix(name: str, value: ArrayLike) -> NDArray[np.float64]:
    try:
        M = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be a real square matrix: {exc}") from None
    if M.dtype == bool or not (np.issubdtype(M.dtype, np.integer) or np.issubdtype(M.dtype, np.floating)):
        raise InputError(f"{name} must be a real square matrix of numbers, got dtype {M.dtype}")
    M = M.astype(float)
    if M.ndim != 2 or M.shape[0] != M.shape[1] or M.shape[0] == 0:
        raise InputError(f"{name} must be a square matrix, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise InputError(f"{name} must be finite")
    if np.abs(M).max() > _MAX_ENTRY:
        raise InputError(f"{name} has an entry larger than {_MAX_ENTRY:g} in size; rescale time")
    return M


def _delay(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise DelayError(f"{name} must be a real number, got {value!r}")
    out = float(value)
    if not math.isfinite(out) or out < 0.0:
        raise DelayError(f"{name} must be finite and non-negative, got {out}")
    return out


def _rate(mu: object) -> float | None:
    if mu is None:
        return None
    return _delay("mu", mu)


def _order(order: object) -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 0 <= int(order) <= MAX_ORDER:
        raise InputError(f"order must be an integer from 0 to {MAX_ORDER}, got {order!r}")
    return int(order)


def _system(A0: ArrayLike, A1: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    a0, a1 = _matrix("A0", A0), _matrix("A1", A1)
    if a0.shape != a1.shape:
        raise InputError(f"A0 and A1 must have the same shape, got {a0.shape} and {a1.shape}")
    if a0.shape[0] > MAX_STATES:
        raise InputError(f"at most {MAX_STATES} states are certified (the LMIs grow fast), got {a0.shape[0]}")
    return a0, a1


def _method(order: int, mu: float | None, constant: bool) -> str:
    ineq = _INEQUALITY.get(order, f"Bessel-Legendre N={order}")
    if constant:
        return f"Lyapunov-Krasovskii, augmented, {ineq} (constant delay)"
    state = "augmented" if mu is not None and order >= 1 else "x'Px"
    return f"Lyapunov-Krasovskii, {state}, {ineq}, reciprocally convex"


@dataclass(frozen=True)
class _Attempt:
    """A certificate with what it takes to finish its exact re-check later."""

    cert: DelayCertificate
    problem: LmiProblem | None
    check: Recheck | None
    solution: SdpSolution | None = field(default=None, repr=False)

    def confirmed(self) -> DelayCertificate:
        """The certificate after the exact re-check ("undecided" when it fails)."""
        if not self.cert.holds or self.cert.exact is not None or self.problem is None or self.check is None:
            return self.cert
        exact = exact_check(self.problem, self.check.rational)
        return replace(self.cert, exact=exact, status="undecided" if exact is False else "holds")


def _problem(a0: NDArray[np.float64], a1: NDArray[np.float64], h1: float, h2: float, mu: float | None,
             order: int) -> tuple[LmiProblem, bool]:  # fmt: skip
    constant = mu == 0.0 or h1 == h2
    data = SystemData(a0, a1, h1, h2, 0.0 if constant else mu)
    return (constant_delay(data, order) if constant else time_varying(data, order)), constant


#: Seconds of one SDP with 1000 rows of PSD cones, and the growth exponent (measured on the
#: project's 2-core machine under load: 2 states about 0.1 s, 3 states 1 s, 6 states 17 s)
_SDP_SECONDS, _SDP_GROWTH = 1.0, 2.2


def _check_budget(a0: NDArray[np.float64], a1: NDArray[np.float64], h1: float, mu: float | None, order: int,
                  solves: int, what: str) -> None:  # fmt: skip
    """Refuse up front a job whose SDPs would exceed the time budget (DELAYFORM_TIME_BUDGET)."""
    problem, _ = _problem(a0, a1, h1, h1 + 1.0, mu, order)
    sizes = problem.build(problem.variables.unpack(np.zeros(problem.variables.size)), False)
    rows = sum(M.shape[0] * (M.shape[0] + 1) // 2 for M in sizes.values())
    require(what=what, setting="the number of states or the order",
            seconds=solves * _SDP_SECONDS * (rows / 1000.0) ** _SDP_GROWTH)  # fmt: skip


def _attempt(a0: NDArray[np.float64], a1: NDArray[np.float64], h1: float, h2: float, mu: float | None,
             order: int, *, exact: bool = True) -> _Attempt:  # fmt: skip
    problem, constant = _problem(a0, a1, h1, h2, mu, order)
    sol = solve(problem)
    method = _method(order, mu, constant)
    empty: dict[str, NDArray[np.float64]] = {}
    if not (math.isfinite(sol.t) and sol.t > 0.0):
        status: Status = "does not hold" if solver_says_infeasible(sol) else "undecided"
        cert = DelayCertificate(status, method, order, h1, h2, mu, empty, empty, {}, None, sol.status, sol.t)
        return _Attempt(cert, None, None)
    check = recheck(problem, sol.x, exact=exact)
    status = "holds" if check.passed else "undecided"
    cert = DelayCertificate(status, method, order, h1, h2, mu, check.values, check.matrices, check.min_eigenvalues,
                            check.exact_ok, sol.status, sol.t)  # fmt: skip
    return _Attempt(cert, problem, check)


@validated(DelayError)
def certify_time_varying(A0: ArrayLike, A1: ArrayLike, h: float, *, mu: float | None = None, h1: float | None = None,
                         order: int = 1) -> DelayCertificate:  # fmt: skip
    """Certify x' = A0 x + A1 x(t - h(t)) stable for every delay h(t) in [h1, h] with |h'(t)| <= mu.

    Parameters
    ----------
    A0, A1
        Real n x n matrices (n <= 8).
    h
        The upper end h2 of the delay interval.
    mu
        Bound on the rate |dh/dt|; 0 for constant delays; None (default) for
        delays that vary arbitrarily fast (the functional then has no term
        whose derivative involves dh/dt).
    h1
        The lower end; default ``h`` for constant delays (a certificate for
        the single delay h), 0 for varying ones.
    order
        Bessel-Legendre order N, 0 (Jensen) to :data:`MAX_ORDER`; 1 (Wirtinger)
        by default. Higher orders are less conservative and cost more.

    Returns
    -------
    DelayCertificate
        Its ``status`` is "holds" only after the independent re-check.

    Examples
    --------
    The benchmark of Gu, Kharitonov and Chen (2003), stable for constant delays below 6.17258:

    >>> A0, A1 = [[-2.0, 0.0], [0.0, -0.9]], [[-1.0, 0.0], [-1.0, -1.0]]
    >>> certify_time_varying(A0, A1, 6.0, mu=0.0, h1=0.0).status
    'holds'
    >>> certify_time_varying(A0, A1, 6.0, mu=0.0, order=0).holds  # Jensen's bound stops at 4.472
    False
    """
    a0, a1 = _system(A0, A1)
    rate, n_order, h2 = _rate(mu), _order(order), _delay("h", h)
    lo = (h2 if rate == 0.0 else 0.0) if h1 is None else _delay("h1", h1)
    if lo > h2:
        raise DelayError(f"h1 = {lo:g} must not exceed h = {h2:g}")
    _check_budget(a0, a1, lo, rate, n_order, 1, f"a certificate for {a0.shape[0]} states at order {n_order}")
    return _attempt(a0, a1, lo, h2, rate, n_order).cert


@validated(DelayError)
def time_varying_delay_margin(A0: ArrayLike, A1: ArrayLike, *, h1: float = 0.0, mu: float | None = None,
                              order: int = 1, rtol: float = 1e-4, max_delay: float = 1000.0) -> TimeVaryingMargin:  # fmt: skip
    """The largest h2 such that x' = A0 x + A1 x(t - h(t)) is certified stable for every h(t) in [h1, h2].

    Parameters
    ----------
    A0, A1
        Real n x n matrices (n <= 8).
    h1
        Lower end of the delay interval (default 0).
    mu
        Bound on |dh/dt|: 0 for constant delays, None (default) for any variation.
    order
        Bessel-Legendre order N, 0 (Jensen) to :data:`MAX_ORDER`.
    rtol
        Relative width at which the search stops.
    max_delay
        The search does not look past this h2 (``reached_cap`` says it got there).

    Returns
    -------
    TimeVaryingMargin
        The margin with its certificates. For varying delays the search
        bisects on h2, each step one certificate on [h1, h2]. For constant
        delays it extends a chain of certified intervals [a, b], each with
        its own matrices, so the margin approaches the pointwise one.

    Examples
    --------
    >>> A0, A1 = [[-2.0, 0.0], [0.0, -0.9]], [[-1.0, 0.0], [-1.0, -1.0]]
    >>> round(time_varying_delay_margin(A0, A1, mu=0.0, order=1, rtol=1e-3).margin, 2)  # Wirtinger: 6.059
    6.06
    """
    a0, a1 = _system(A0, A1)
    rate, n_order, lo = _rate(mu), _order(order), _delay("h1", h1)
    cap = _delay("max_delay", max_delay)
    if not (isinstance(rtol, (int, float)) and 1e-8 <= rtol <= 0.1):
        raise InputError(f"rtol must be a number from 1e-8 to 0.1, got {rtol!r}")
    if cap <= lo:
        raise DelayError(f"max_delay = {cap:g} must exceed h1 = {lo:g}")
    _check_budget(a0, a1, lo, rate, n_order, 20, f"a delay margin for {a0.shape[0]} states at order {n_order}")
    # the natural time scale: 1 / the size of the matrices
    step = min(1.0 / max(float(np.linalg.norm(np.hstack([a0, a1]), 2)), 1e-12), cap - lo)
    search = _chain if rate == 0.0 else _bisect
    return search(a0, a1, lo, rate, n_order, step, rtol, cap)


def _bisect(a0: NDArray[np.float64], a1: NDArray[np.float64], h1: float, mu: float | None, order: int, step: float,
            rtol: float, cap: float) -> TimeVaryingMargin:  # fmt: skip
    tried: list[tuple[float, str]] = []
    held: list[_Attempt] = []

    def attempt(h2: float) -> bool:
        # the search re-checks by eigenvalues; the exact check is for the answer (below)
        att = _attempt(a0, a1, h1, h2, mu, order, exact=False)
        tried.append((h2, att.cert.status))
        if att.cert.holds:
            held.append(att)
        return att.cert.holds

    hi, lo = h1 + step, None
    capped = False
    while attempt(hi):  # grow until a failure or the cap
        lo = hi
        if hi >= cap:
            capped = True
            break
        hi = min(h1 + 2.0 * (hi - h1), cap)
    if lo is None:  # shrink until a success, or give up below the tolerance
        while lo is None and hi - h1 > rtol * max(step, h1):
            hi = h1 + 0.5 * (hi - h1)
            if attempt(hi):
                lo, hi = hi, h1 + 2.0 * (hi - h1)
    while lo is not None and not capped and hi - lo > rtol * hi:
        mid = 0.5 * (lo + hi)
        if attempt(mid):
            lo = mid
        else:
            hi = mid
    # the answer is the largest h2 whose certificate also passes the exact check
    for att in sorted(held, key=lambda a: -a.cert.h2):
        cert = att.confirmed()
        if cert.holds:
            return _result(cert, h1, mu, order, tried, hi - cert.h2, capped and cert.h2 >= cap, (cert,))
        tried.append((cert.h2, cert.status))
    return _result(None, h1, mu, order, tried, rtol * max(step, h1), False, ())


def _chain(a0: NDArray[np.float64], a1: NDArray[np.float64], h1: float, mu: float | None, order: int, step: float,
           rtol: float, cap: float) -> TimeVaryingMargin:  # fmt: skip
    tried: list[tuple[float, str]] = []
    pieces: list[DelayCertificate] = []
    first = _attempt(a0, a1, h1, h1, 0.0, order).cert  # the chain starts at a certified delay h1
    tried.append((h1, first.status))
    if not first.holds:
        return _result(None, h1, 0.0, order, tried, 0.0, False, ())
    a, grow, floor = h1, True, rtol * max(h1, step)
    while step > max(rtol * a, floor):
        b = min(a + step, cap)
        cert = _attempt(a0, a1, a, b, 0.0, order).cert  # every piece is part of the answer: checked exactly now
        tried.append((b, cert.status))
        if cert.holds:
            pieces.append(cert)
            a = b
            if a >= cap:
                return _result(cert, h1, 0.0, order, tried, 0.0, True, tuple(pieces))
            step = 2.0 * step if grow else step
        else:
            grow = False
            step *= 0.5
    best = pieces[-1] if pieces else first
    return _result(best, h1, 0.0, order, tried, step, False, tuple(pieces) or (first,))


def _result(best: DelayCertificate | None, h1: float, mu: float | None, order: int, tried: list[tuple[float, str]],
            tol: float, capped: bool, certs: tuple[DelayCertificate, ...]) -> TimeVaryingMargin:  # fmt: skip
    margin = None if best is None else best.h2
    method = _method(order, mu, mu == 0.0)
    return TimeVaryingMargin(margin, h1, mu, order, method, certs, tuple(tried), tol, capped)
