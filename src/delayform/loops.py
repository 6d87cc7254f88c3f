"""Feedback loops from python-control: exact delay margins and quasi-polynomials.

A loop gain L(s) = N(s) / D(s) closed through a delay tau,

    1 + L(s) e^{-tau s} = 0,

has the characteristic quasi-polynomial (eq. genfactor with g1 = D, g2 = N)

    q(s) = D(s) + N(s) e^{-tau s}.

Its **delay margin** is the first delay at which a root reaches the
imaginary axis. A root s = j omega exists at some tau only where
|L(j omega)| = 1, the gain crossovers, which are the positive real roots of
the polynomial

    p(omega) = |D(j omega)|^2 - |N(j omega)|^2

(an elimination of tau: exact, no frequency grid). At a crossover omega_c with
phase margin PM = pi + arg L(j omega_c) the root is on the axis exactly at

    tau = (PM mod 2 pi) / omega_c + k 2 pi / omega_c,   k = 0, 1, ...

so the delay margin is the smallest of (PM mod 2 pi) / omega_c over every
crossover (not only the one a Bode plot shows; RobustAndOptimalControl.jl
PR #152 fixed a margin computed from a disk margin instead). The closed loop
must be stable at tau = 0; the roots then move continuously with tau
(retarded case), so none crosses before that delay. The answer is checked
by a certified root count (argument principle,
:func:`delayform.analysis.roots.count_roots_right_of`) of zero just below
the margin.

Loops are python-control ``TransferFunction`` or ``StateSpace`` objects
(imported only when such an object is passed; ``pip install
delayform[control]``) or a pair ``(num, den)`` in decreasing powers of s,
python-control's and SciPy's order. A state-space loop keeps its hidden
modes: its denominator is det(sI - A), its numerator det(sI - A + BC) -
det(sI - A) + D det(sI - A) (the matrix determinant lemma), so the
quasi-polynomial is det(sI - A + e^{-tau s} BC), that of the delayed
feedback u(t) = -y(t - tau) itself.

Two loops with their own delays, 1 + L1 e^{-tau1 s} + L2 e^{-tau2 s} (a
plant with a position channel and a velocity channel, as in eq. protocol),
and a 2 x 2 MIMO state-space loop with one delay, det(I + L(s) e^{-tau s}),
are quasi-polynomials of eq. genfactor too: :func:`loop_quasi_polynomial`
builds them for :func:`~delayform.crossing_map` and
:func:`~delayform.rightmost_root`. In a SISO loop delays at the plant's
input and output add up (they commute with L), so one delay tau = tau_in +
tau_out covers both.
"""

from __future__ import annotations

import base64
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import NDArray

from delayform._display import FigureRepr
from delayform._extras import require_extra
from delayform.analysis.roots import count_roots_right_of
from delayform.characteristic import TwoDelayQuasiPolynomial
from delayform._validation import check_delay, validated
from delayform.errors import LoopError, NotConvergedError, UnstableLoopError
from delayform.quasipolynomial import QuasiPolynomial

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = [
    "Crossover",
    "DelayMargin",
    "delay_margin",
    "loop_quasi_polynomial",
    "loop_polynomials",
    "loop_characteristic",
]

#: a closed-loop pole with Re s above -POLE_TOL * max(1, |s|) counts as on the axis
POLE_TOL = 1e-10
#: a root of p(omega) with |Im| below this fraction of its modulus is a real crossover
#: (a tangency |L| = 1 is a double root, split by rounding into a near-real pair)
REAL_ROOT_TOL = 1e-6
#: the certifying count is taken at tau * (1 - CERTIFY_OFFSET)
CERTIFY_OFFSET = 1e-6


# ===================================================================== loops in
def _trim(c: NDArray[np.float64]) -> NDArray[np.float64]:
    nz = np.flatnonzero(c)
    return c[: nz[-1] + 1] if nz.size else np.zeros(0)


def _real_coefficients(name: str, value: object) -> NDArray[np.float64]:
    try:
        arr = np.atleast_1d(np.asarray(value, dtype=np.float64)).ravel()
    except (TypeError, ValueError) as exc:
        raise LoopError(f"{name} must be a sequence of real coefficients") from exc
    if not np.all(np.isfinite(arr)):
        raise LoopError(f"{name} has coefficients that are not finite numbers")
    return arr


def _from_pair(loop: tuple[Any, Any], name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    num = _real_coefficients(f"{name} numerator", loop[0])[::-1]
    den = _real_coefficients(f"{name} denominator", loop[1])[::-1]
    for part, coefficients in (("numerator", num), ("denominator", den)):
        if coefficients.size == 0:
            # an empty sequence is no polynomial: reading it as L = 0 would certify a loop never given
            raise LoopError(f"{name} {part} is empty; give its coefficients (write [0] for a zero numerator)")
    return _trim(num), _trim(den)


def _control_module() -> Any:
    """python-control, for a loop that is not a pair (num, den) of coefficients."""
    require_extra("control")
    import control

    return control


def _check_continuous(loop: Any, name: str) -> None:
    dt = getattr(loop, "dt", 0)
    if dt is not None and dt is not False and dt != 0:
        raise LoopError(
            f"{name} is a discrete-time system (dt = {dt}): its delays are shifts z^-k, "
            "not e^{-tau s}; pass the continuous-time loop"
        )


def _check_siso(loop: Any, name: str) -> None:
    if loop.ninputs != 1 or loop.noutputs != 1:
        raise LoopError(
            f"{name} has {loop.noutputs} outputs and {loop.ninputs} inputs; this needs a SISO loop "
            "(for a 2 x 2 state-space loop use loop_quasi_polynomial)"
        )


def _state_space_siso(loop: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    A, B, C, D = (np.asarray(m, dtype=np.float64) for m in (loop.A, loop.B, loop.C, loop.D))
    den = np.poly(A)[::-1] if A.size else np.ones(1)
    # matrix determinant lemma: det(sI - A + BC) = det(sI - A) (1 + C (sI - A)^-1 B);
    # the leading s^n terms cancel exactly, so the strictly proper part has degree < n
    strict = (np.poly(A - B @ C)[::-1] - den) if A.size else np.zeros(1)
    strict[-1] = 0.0
    num = strict + float(D[0, 0]) * den
    return _trim(num), _trim(den)


@validated(LoopError)
def loop_polynomials(loop: object, *, name: str = "loop") -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and denominator of a SISO loop gain, in increasing powers of s.

    Parameters
    ----------
    loop
        A python-control ``TransferFunction`` or ``StateSpace`` (continuous
        time, one input and one output), or a pair ``(num, den)`` of real
        coefficients in decreasing powers of s (python-control's order).
    name
        How error messages call the loop.

    Returns
    -------
    (num, den)
        Real coefficient arrays, trailing zeros dropped, numpy.polynomial order.

    Raises
    ------
    LoopError
        For an object that is not one of the above, a discrete-time loop, a
        MIMO loop, a zero denominator or non-finite coefficients.

    Examples
    --------
    >>> num, den = loop_polynomials(([2.0], [1.0, 1.0]))  # 2 / (s + 1)
    >>> num.tolist(), den.tolist()
    ([2.0], [1.0, 1.0])
    """
    if isinstance(loop, tuple) and len(loop) == 2:
        num, den = _from_pair(loop, name)
    else:
        control = _control_module()
        if not isinstance(loop, (control.TransferFunction, control.StateSpace, control.FrequencyResponseData)):
            raise LoopError(
                f"{name} must be a python-control TransferFunction or StateSpace, or a pair "
                f"(num, den), got {type(loop).__name__}"
            )
        if type(loop).__name__ == "DelayLTI" or hasattr(loop, "tau") or hasattr(loop, "delays"):
            raise LoopError(
                f"{name} carries time delays of its own ({type(loop).__name__}), which cannot be read "
                "as one loop gain; pass the delay-free loop and give the delay to delay_margin"
            )
        if isinstance(loop, control.TransferFunction):
            _check_continuous(loop, name)
            _check_siso(loop, name)
            num = _trim(_real_coefficients(f"{name} numerator", loop.num[0][0])[::-1])
            den = _trim(_real_coefficients(f"{name} denominator", loop.den[0][0])[::-1])
        elif isinstance(loop, control.StateSpace):
            _check_continuous(loop, name)
            _check_siso(loop, name)
            num, den = _state_space_siso(loop)
        else:
            raise LoopError(
                f"{name} is a python-control {type(loop).__name__}; only linear TransferFunction and "
                "StateSpace loops have a characteristic quasi-polynomial"
            )
    if den.size == 0:
        raise LoopError(f"{name} has a zero denominator")
    return (num if num.size else np.zeros(1)), den


def _check_proper(num: NDArray[np.float64], den: NDArray[np.float64], name: str) -> None:
    n, m = den.size - 1, num.size - 1
    if m > n:
        raise LoopError(
            f"{name} is improper (numerator degree {m} > denominator degree {n}): "
            "1 + L(s) e^{-tau s} is of advanced type, unstable for every tau > 0"
        )
    if m == n and abs(num[-1] / den[-1]) >= 1.0:
        raise LoopError(
            f"{name} is biproper with |L(j inf)| = {abs(num[-1] / den[-1]):.6g} >= 1: "
            "1 + L(s) e^{-tau s} is of neutral type with roots near or right of the axis "
            "for every tau > 0, so it has no delay margin"
        )


# ===================================================================== crossovers
@validated(LoopError)
@dataclass(frozen=True)
class Crossover:
    """One gain crossover |L(j omega)| = 1 and the delays at which it puts a root on the axis.

    Attributes
    ----------
    omega
        Crossover frequency (rad/s), a positive root of
        |D(j omega)|^2 - |N(j omega)|^2.
    phase_margin
        pi + arg L(j omega) wrapped to (-pi, pi] (rad).
    tau
        The first delay (s) with the root j omega: (phase_margin mod 2 pi) / omega.
    root_tendency
        Sign of Re ds/dtau there: +1 the root moves right (destabilizing),
        -1 left, 0 it only touches the axis (Definition "Root Tendency").
    """

    omega: float
    phase_margin: float
    tau: float
    root_tendency: int

    @property
    def period(self) -> float:
        """2 pi / omega: the same root returns every period of delay."""
        return 2.0 * math.pi / self.omega

    def delays(self, tau_max: float) -> NDArray[np.float64]:
        """Every delay in [0, tau_max] at which this crossover puts j omega on the axis."""
        if tau_max < self.tau:
            return np.zeros(0)
        return self.tau + self.period * np.arange(int((tau_max - self.tau) // self.period) + 1)


def _log_gain(num: NDArray[np.float64], den: NDArray[np.float64], w: float) -> tuple[float, float]:
    """log|L(j w)| and its derivative in w."""
    s = 1j * w
    n, d = npoly.polyval(s, num), npoly.polyval(s, den)
    dn, dd = npoly.polyval(s, npoly.polyder(num)), npoly.polyval(s, npoly.polyder(den))
    value = math.log(abs(n)) - math.log(abs(d))
    slope = (1j * dn / n).real - (1j * dd / d).real
    return value, slope


def _polish(num: NDArray[np.float64], den: NDArray[np.float64], w: float) -> float | None:
    """Newton on log|L(j w)| = 0 from a root of p; None when it is not a crossover."""
    best = w
    for _ in range(60):
        value, slope = _log_gain(num, den, w)
        if abs(value) < 1e-14:
            return w
        if slope == 0.0 or not math.isfinite(slope):
            break
        step = value / slope
        w_new = w - step
        if not (w_new > 0.0 and math.isfinite(w_new)) or abs(step) > 0.5 * w:
            break
        w = w_new
        if abs(step) <= 1e-15 * w:
            best = w
            break
        best = w
    value, _ = _log_gain(num, den, best)
    # a tangency (double root) converges only linearly: accept a small gain error there
    return best if abs(value) < 1e-8 else None


def _in_omega(c: NDArray[np.complex128], sign: float = 1.0) -> NDArray[np.complex128]:
    """Coefficients in omega of c(sign j omega) (for real c, sign -1 gives the conjugate)."""
    return c * (sign * 1j) ** np.arange(c.size)


def _scaled_roots(p: NDArray[np.complex128], size: NDArray[np.float64]) -> NDArray[np.complex128]:
    """Every root of p(omega), whose coefficient k sums terms of magnitude at most size[k].

    A leading coefficient is dropped only when it is a cancellation (below
    rounding of the terms that made it), never for being small beside the
    others: at a high loop gain K the coefficients of p span K^2, and a
    relative cut there loses the crossover. The roots are found in a scaled
    frequency x = omega / sigma, sigma the geometric size of the roots, so
    that "near real" is judged relative to the crossover's own size.
    """
    keep = np.flatnonzero(np.abs(p) > 64.0 * np.finfo(float).eps * size)
    if keep.size == 0 or keep[-1] == 0:
        return np.zeros(0, complex)
    p = p[: keep[-1] + 1]
    low = int(keep[0])
    sigma = float(abs(p[low] / p[-1]) ** (1.0 / (p.size - 1 - low))) if p.size - 1 > low else 1.0
    scaled = p * sigma ** np.arange(p.size)
    return npoly.polyroots(scaled / np.abs(scaled).max()) * sigma


def _positive_real_roots(roots: NDArray[np.complex128]) -> NDArray[np.float64]:
    real = (np.abs(roots.imag) <= REAL_ROOT_TOL * np.abs(roots)) & (roots.real > 0)
    return np.sort(roots[real].real)


def _magnitude(c: NDArray[np.complex128]) -> NDArray[np.float64]:
    return np.abs(c).astype(np.float64)


def _gain_polynomial(g1: NDArray[np.complex128], g2: NDArray[np.complex128], sub: Any) -> NDArray[np.complex128]:
    """|g1(j omega)|^2 - |g2(j omega)|^2 in omega (with ``sub = polyadd`` on magnitudes: its size)."""
    mul = npoly.polymul
    return sub(mul(_in_omega(g1), _in_omega(g1, -1.0)), mul(_in_omega(g2), _in_omega(g2, -1.0)))


def _unique(values: list[tuple[float, float]]) -> list[tuple[float, float]]:
    out: list[tuple[float, float]] = []
    for w, tau in sorted(values):
        if all(abs(w - u) > 1e-9 * w or abs(tau - t) > 1e-9 * tau for u, t in out):
            out.append((w, tau))
    return out


def _first_delay(z: complex, w: float) -> tuple[float, float]:
    """(phase margin, first delay) of a root z = e^{-j omega tau} on the unit circle."""
    pm = float(np.angle(1.0 / z))  # pi + arg(mu) for the loop eigenvalue mu = -1/z
    return pm, (pm if pm > 0.0 else pm + 2.0 * math.pi) / w


def _gain_roots(g1: NDArray[np.complex128], g2: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Every root in omega of |g1(j omega)|^2 = |g2(j omega)|^2."""
    p = _gain_polynomial(g1, g2, npoly.polysub)
    return _scaled_roots(p, _gain_polynomial(_magnitude(g1), _magnitude(g2), npoly.polyadd).real)


def _siso_crossings(g1: NDArray[np.complex128], g2: NDArray[np.complex128]) -> list[tuple[float, float]]:
    """g1 + g2 z: |z| = 1 where |g1(j omega)|^2 = |g2(j omega)|^2, the gain crossovers of L = g2 / g1."""
    if g2.size == 0 or not np.any(g2):  # L = 0: the delay never enters
        return []
    out = []
    for w0 in _positive_real_roots(_gain_roots(g1, g2)):
        w = _polish(g2.real, g1.real, float(w0))
        if w is not None:
            out.append((w, _first_delay(-npoly.polyval(1j * w, g1) / npoly.polyval(1j * w, g2), w)[1]))
    return _unique(out)


def _newton_axis_root(qp: TwoDelayQuasiPolynomial, w: float, tau: float) -> tuple[float, float] | None:
    """Newton on q(j omega, tau) = 0 for (omega, tau): the root polished on the quasi-polynomial itself."""
    for _ in range(30):
        s = 1j * w
        f = complex(qp.evaluate(s, tau, 0.0))
        scale = sum(abs(complex(npoly.polyval(s, c))) for c, _, _ in qp.terms())
        if abs(f) <= 1e-14 * scale:
            return w, tau
        jac_w = 1j * complex(qp.derivative(s, tau, 0.0))
        jac_t = complex(qp.delay_derivative(s, tau, 0.0, delay=1))
        jac = np.array([[jac_w.real, jac_t.real], [jac_w.imag, jac_t.imag]])
        try:
            dw, dt = np.linalg.solve(jac, [-f.real, -f.imag])
        except np.linalg.LinAlgError:
            break
        w, tau = w + dw, tau + dt
        if not (w > 0 and tau >= 0):
            return None
    s = 1j * w
    scale = sum(abs(complex(npoly.polyval(s, c))) for c, _, _ in qp.terms())
    return (w, tau) if abs(complex(qp.evaluate(s, tau, 0.0))) <= 1e-10 * scale else None


def _resultant(g1: NDArray[Any], g2: NDArray[Any], g4: NDArray[Any], sub: Any) -> NDArray[np.complex128]:
    """Res_z of g1 + g2 z + g4 z^2 and its conjugate reciprocal, in omega (``sub = polyadd`` on magnitudes: its size)."""
    a, b, c = (_in_omega(g) for g in (g4, g2, g1))
    a2, b2, c2 = (_in_omega(g, -1.0) for g in (g1, g2, g4))
    mul = npoly.polymul
    ac = sub(mul(a, c2), mul(c, a2))
    return sub(mul(ac, ac), mul(sub(mul(a, b2), mul(b, a2)), sub(mul(b, c2), mul(c, b2))))


def _nonempty(c: NDArray[np.complex128]) -> NDArray[np.complex128]:
    return c if c.size else np.zeros(1, complex)


def _square_factor(qp: TwoDelayQuasiPolynomial) -> TwoDelayQuasiPolynomial | None:
    """g2 + 2 g4 z when g1 + g2 z + g4 z^2 = g4 (z + g2 / (2 g4))^2 (zero discriminant), else None.

    Two identical decoupled channels give such a square: every crossing is
    then a fourfold root of the resultant, which rounding splits far off the
    real axis, and a double root in z, on which Newton stalls; the crossings
    are those of the single channel.
    """
    g1, g2, g4 = (_nonempty(g) for g in (qp.g1, qp.g2, qp.g4))
    mul = npoly.polymul
    disc = npoly.polysub(mul(g2, g2), 4.0 * mul(g1, g4))
    size = npoly.polyadd(mul(np.abs(g2), np.abs(g2)), 4.0 * mul(np.abs(g1), np.abs(g4)))
    if np.any(np.abs(disc) > 1e-9 * size.max()):
        return None
    return TwoDelayQuasiPolynomial(g2.real, 2.0 * g4.real)


def _resultant_roots(qp: TwoDelayQuasiPolynomial) -> NDArray[np.complex128]:
    """Every root in omega of the resultant of q(j omega, z) and its conjugate reciprocal."""
    g1, g2, g4 = (_nonempty(g) for g in (qp.g1, qp.g2, qp.g4))
    size = _resultant(*(np.abs(g) for g in (g1, g2, g4)), npoly.polyadd).real
    return _scaled_roots(_resultant(g1, g2, g4, npoly.polysub), size)


def _quadratic_crossings(qp: TwoDelayQuasiPolynomial) -> list[tuple[float, float]]:
    """g1 + g2 z + g4 z^2 (a 2 x 2 loop): omega where a root z lies on the unit circle.

    On s = j omega, z on the unit circle is also a root of the conjugate
    reciprocal z^2 conj(q)(1 / conj z); the resultant of the two quadratics
    in z, (a c' - c a')^2 - (a b' - b a')(b c' - c b'), is a polynomial in
    omega whose positive real roots hold every crossing (elimination, as
    for the SISO loop).
    """
    g1, g2, g4 = (_nonempty(g) for g in (qp.g1, qp.g2, qp.g4))
    out = []
    for w0 in _positive_real_roots(_resultant_roots(qp)):
        s = 1j * w0
        for z in npoly.polyroots([npoly.polyval(s, g1), npoly.polyval(s, g2), npoly.polyval(s, g4)]):
            if abs(abs(z) - 1.0) < 1e-5:
                polished = _newton_axis_root(qp, float(w0), _first_delay(z, float(w0))[1])
                if polished is not None:
                    w = polished[0]
                    out.append((w, polished[1] % (2.0 * math.pi / w)))
    return _unique(out)


def _confirm_no_crossing(qp: TwoDelayQuasiPolynomial, name: str) -> None:
    """Raise NotConvergedError unless every root z of q(j omega, z) is outside the unit circle where it matters.

    With no crossing found, the loop is stable for every delay only if
    |z| > 1 for every omega >= 0. Rounding can push a true crossing off the
    real axis (a clustered root of the eliminant), so the claim is tested at
    omega = 0 and at the modulus of every root of the eliminant, exactly
    where a lost crossing would sit.
    """
    if not (np.any(qp.g2) or np.any(qp.g4)):
        return  # L = 0: the delay never enters
    factor = _square_factor(qp) if qp.g4.size else qp
    roots = _resultant_roots(qp) if factor is None else _gain_roots(factor.g1, factor.g2)
    g1, g2, g4 = (_nonempty(g) for g in (qp.g1, qp.g2, qp.g4))
    for w in np.concatenate([[0.0], np.abs(roots[roots.real > 0])]):
        s = 1j * float(w)
        at = _trim_complex([npoly.polyval(s, g1), npoly.polyval(s, g2), npoly.polyval(s, g4)])
        z = npoly.polyroots(at) if at.size > 1 else np.zeros(0)
        if np.any(np.abs(z) <= 1.0 + 1e-9):
            raise NotConvergedError(
                f"{name}: no gain crossover was found, yet a root e^(-j omega tau) sits on or inside the unit "
                f"circle at omega = {w:.6g}; the exact elimination lost a crossover to rounding, so no margin "
                "(finite or infinite) is claimed"
            )


def _trim_complex(c: list[complex]) -> NDArray[np.complex128]:
    arr = np.asarray(c, dtype=complex)
    nz = np.flatnonzero(arr)
    return arr[: nz[-1] + 1] if nz.size else arr[:1]


def _crossovers(qp: TwoDelayQuasiPolynomial) -> tuple[Crossover, ...]:
    factor = _square_factor(qp) if qp.g4.size else qp
    if factor is None:
        pairs = _quadratic_crossings(qp)
        factor = qp
    else:
        pairs = _siso_crossings(factor.g1, factor.g2)
    out = []
    for w, tau in pairs:
        pm = math.remainder(w * tau, 2.0 * math.pi)  # tau = (pm mod 2 pi) / omega
        rt = int(factor.root_tendency(np.array([w]), np.array([tau]), np.array([0.0]), delay=1)[0])
        out.append(Crossover(omega=float(w), phase_margin=pm, tau=float(tau), root_tendency=rt))
    return tuple(sorted(out, key=lambda c: c.tau))


# ===================================================================== the margin
@validated(LoopError)
@dataclass(frozen=True, eq=False)
class DelayMargin(FigureRepr):
    """The exact delay margin of 1 + L(s) e^{-tau s} and how it was certified.

    Attributes
    ----------
    tau
        The delay margin (s): the closed loop is stable for every delay in
        [0, tau) and has a root on the imaginary axis at tau; ``math.inf``
        when it is stable for every delay (|L(j omega)| < 1 for all omega > 0).
    omega
        The frequency (rad/s) of the root on the axis at ``tau``; None when
        ``tau`` is infinite.
    phase_margin
        The phase margin (rad) of that crossover; None when ``tau`` is infinite.
    crossovers
        Every gain crossover, sorted by its first delay.
    closed_loop_poles
        The roots of D + N, the closed loop at tau = 0.
    certified
        True when a certified root count confirmed no root right of the axis
        just below ``tau`` (or at tau = 0 when ``tau`` is infinite).
    certificate
        What was checked, in words.
    quasi_polynomial
        D(s) + N(s) e^{-tau1 s}, or for a 2 x 2 loop
        g1 + g2 e^{-tau1 s} + g4 e^{-2 tau1 s} (eq. genfactor, tau2 unused).
    """

    tau: float
    omega: float | None
    phase_margin: float | None
    crossovers: tuple[Crossover, ...]
    closed_loop_poles: NDArray[np.complex128] = field(repr=False)
    certified: bool
    certificate: str = field(repr=False)
    quasi_polynomial: TwoDelayQuasiPolynomial = field(repr=False)

    def is_stable(self, tau: float) -> bool:
        """True when the closed loop with delay ``tau`` is below the margin (stable); DelayError for a negative delay."""
        return check_delay("tau", tau) < self.tau

    def _repr_html_(self) -> str:
        rows = "".join(
            f"<tr><td>{c.omega:.6g}</td><td>{math.degrees(c.phase_margin):.4g}</td>"
            f"<td>{c.tau:.6g}</td><td>{c.root_tendency:+d}</td></tr>"
            for c in self.crossovers
        )
        image = base64.b64encode(self._repr_png_()).decode("ascii")
        return (
            f'<img src="data:image/png;base64,{image}" alt="Nyquist plot of the loop"/>'
            f"<p><b>delay margin</b> tau = {self.tau:.8g} s"
            + (f" (root at j {self.omega:.6g})" if self.omega is not None else "")
            + f"; certified: {self.certified}</p>"
            "<table><tr><th>omega (rad/s)</th><th>phase margin (deg)</th><th>first delay (s)</th>"
            f"<th>RT</th></tr>{rows}</table>"
        )

    def plot(self, ax: Axes | None = None) -> Axes:
        """Nyquist plot with the unit circle and every crossover (:func:`delayform.plots.plot_delay_margin`)."""
        from delayform.plots import plot_delay_margin

        return plot_delay_margin(self, ax=ax)


def _closed_loop_poles(qp: TwoDelayQuasiPolynomial) -> NDArray[np.complex128]:
    closed = _trim(qp.delay_free().real)
    return npoly.polyroots(closed) if closed.size > 1 else np.zeros(0, complex)


def _require_stable_at_zero(
    poles: NDArray[np.complex128], qp: TwoDelayQuasiPolynomial, retarded: bool, name: str
) -> bool:
    """Raise UnstableLoopError unless 1 + L(s) is stable; True when a certified count agreed."""
    bad = poles[poles.real >= -POLE_TOL * np.maximum(1.0, np.abs(poles))]
    if bad.size:
        worst = bad[np.argmax(bad.real)]
        raise UnstableLoopError(
            f"{name} is not stable without delay: the closed loop 1 + L(s) has {bad.size} pole(s) on or "
            f"right of the imaginary axis (the rightmost at s = {worst.real + 0.0:.6g}{worst.imag + 0.0:+.6g}j); a delay margin needs a loop "
            "stable at tau = 0"
        )
    if not retarded:
        return False
    try:
        count = count_roots_right_of(qp, 0.0, 0.0, 0.0)
    except NotConvergedError:
        count = -1
    if count != 0:
        raise UnstableLoopError(
            f"{name} is not stable without delay: a certified root count finds {count} root(s) of "
            "1 + L(s) on or right of the imaginary axis"
        )
    return True


@validated(LoopError)
def delay_margin(loop: object, *, name: str = "loop") -> DelayMargin:
    """The exact delay margin of the loop 1 + L(s) e^{-tau s} (module docstring).

    Parameters
    ----------
    loop
        The loop gain L: a python-control ``TransferFunction`` or
        ``StateSpace`` (SISO, continuous time, proper), or ``(num, den)`` in
        decreasing powers of s.
    name
        How error messages call the loop.

    Returns
    -------
    DelayMargin
        The margin, the crossover that sets it, every crossover and the
        certificate.

    Raises
    ------
    LoopError
        For an object that is not a SISO continuous-time loop, an improper
        loop, or a biproper one with |L(j inf)| >= 1.
    UnstableLoopError
        When 1 + L(s) is not stable at tau = 0.

    Examples
    --------
    The loop 2 / (s + 1): crossover sqrt(3), phase margin 2 pi / 3, so the
    margin is 2 pi / (3 sqrt 3) (Hayes 1950, s + a + b e^{-tau s}):

    >>> m = delay_margin(([2.0], [1.0, 1.0]))
    >>> round(m.tau, 10), round(2 * math.pi / (3 * math.sqrt(3)), 10), m.certified
    (1.2091995762, 1.2091995762, True)
    """
    if _is_mimo(loop):
        qp = _mimo_terms(_as_state_space(loop, name), name, max_power=2)
        retarded = True  # strictly proper (checked): every delayed term has lower degree
        what = "every crossing from the resultant of q(j omega, z) and its conjugate reciprocal in z"
    else:
        num, den = loop_polynomials(loop, name=name)
        _check_proper(num, den, name)
        retarded = num.size < den.size
        qp = TwoDelayQuasiPolynomial(den, num)
        what = "every gain crossover from the exact polynomial |D(j omega)|^2 = |N(j omega)|^2"
    poles = _closed_loop_poles(qp)
    counted = _require_stable_at_zero(poles, qp, retarded, name)
    crossovers = _crossovers(qp)
    common = dict(crossovers=crossovers, closed_loop_poles=poles, quasi_polynomial=qp)
    if not crossovers:
        _confirm_no_crossing(qp, name)
        text = f"{what}: none, so no root reaches the axis at any delay; stable at tau = 0"
        how = " (closed-loop poles and a certified root count)" if counted else " (closed-loop poles)"
        return DelayMargin(tau=math.inf, omega=None, phase_margin=None, certified=counted,
                           certificate=text + how, **common)  # fmt: skip
    first = crossovers[0]
    certified, below = False, first.tau * (1.0 - CERTIFY_OFFSET)
    if retarded:
        try:
            certified = count_roots_right_of(qp, below, 0.0, 0.0) == 0
        except NotConvergedError:
            certified = False
    certificate = (
        f"stable at tau = 0; {what} ({len(crossovers)} found); the first root on the axis is "
        f"j {first.omega:.10g} at tau = {first.tau:.10g}; "
        + (
            f"certified root count 0 right of the axis at tau = {below:.10g}"
            if certified
            else ("neutral loop: no root count, the margin rests on |L(j inf)| < 1 (continuity of the roots)"
                  if not retarded else "the certified root count just below could not confirm it")
        )
    )
    return DelayMargin(tau=first.tau, omega=first.omega, phase_margin=first.phase_margin,
                       certified=certified, certificate=certificate, **common)  # fmt: skip


# ===================================================================== quasi-polynomials
def _is_mimo(loop: object) -> bool:
    module = type(loop).__module__ or ""
    return module.startswith("control") and getattr(loop, "ninputs", 1) * getattr(loop, "noutputs", 1) > 1


def _as_state_space(loop: Any, name: str) -> Any:
    control = _control_module()
    _check_continuous(loop, name)
    if loop.ninputs != loop.noutputs:
        raise LoopError(
            f"{name} has {loop.noutputs} outputs and {loop.ninputs} inputs; closing u = -y(t - tau) needs a square loop"
        )
    if isinstance(loop, control.TransferFunction):
        try:
            return control.ss(loop)
        except Exception as exc:  # python-control needs slycot to realize a MIMO transfer function
            raise LoopError(
                f"{name}: python-control could not realize this MIMO TransferFunction as a StateSpace "
                f"({type(exc).__name__}); pass a StateSpace"
            ) from exc
    if not isinstance(loop, control.StateSpace):
        raise LoopError(f"{name} is a python-control {type(loop).__name__}; a MIMO loop must be a StateSpace or TransferFunction")
    return loop


def _mimo_characteristic(loop: Any, name: str) -> QuasiPolynomial:
    """det(sI - A + z BC), the delayed feedback u(t) = -y(t - tau) of x' = A x + B u, y = C x."""
    A, B, C, D = (np.asarray(m, dtype=np.float64) for m in (loop.A, loop.B, loop.C, loop.D))
    if loop.ninputs != loop.noutputs:
        raise LoopError(
            f"{name} has {loop.noutputs} outputs and {loop.ninputs} inputs; closing u = -y(t - tau) needs a square loop"
        )
    if np.any(D != 0.0):
        raise LoopError(
            f"{name} has a direct feedthrough D != 0: a MIMO loop must be strictly proper here "
            "(with D the delayed loop is of neutral type)"
        )
    return QuasiPolynomial.from_matrices(A, -B @ C)


def _mimo_terms(loop: Any, name: str, *, max_power: int) -> TwoDelayQuasiPolynomial:
    """det(sI - A + z BC) = g1 + g2 z + g4 z^2 as eq. genfactor (z = e^{-tau1 s})."""
    q = _mimo_characteristic(loop, name)
    top = max(k for (k,) in q.terms)
    if top > max_power:
        raise LoopError(
            f"{name}: det(I + L e^{{-tau s}}) has a term e^{{-{top} tau s}} (rank of BC = {top}); "
            "eq. genfactor and the delay margin here take loops whose BC has rank at most 2 "
            "(use loop_characteristic for the general quasi-polynomial)"
        )
    empty = np.zeros(0)
    return TwoDelayQuasiPolynomial(q.terms[(0,)], q.terms.get((1,), empty), empty, q.terms.get((2,), empty))


@validated(LoopError)
def loop_quasi_polynomial(
    loop1: object, loop2: object | None = None, *, name: str = "loop"
) -> TwoDelayQuasiPolynomial:
    """The characteristic quasi-polynomial of a loop with one or two delays (eq. genfactor).

    * ``loop_quasi_polynomial(L)`` for 1 + L(s) e^{-tau1 s}: D + N e^{-tau1 s};
      a 2 x 2 strictly proper ``StateSpace`` gives det(sI - A + e^{-tau1 s} BC)
      = g1 + g2 e^{-tau1 s} + g4 e^{-2 tau1 s}.
    * ``loop_quasi_polynomial(L1, L2)`` for 1 + L1 e^{-tau1 s} + L2 e^{-tau2 s}
      (SISO): D1 D2 + N1 D2 e^{-tau1 s} + N2 D1 e^{-tau2 s}, with one
      denominator when L1 and L2 share it (the same plant).

    Parameters
    ----------
    loop1, loop2
        Loop gains as accepted by :func:`loop_polynomials`.
    name
        How error messages call the loop.

    Returns
    -------
    TwoDelayQuasiPolynomial
        For :func:`~delayform.crossing_map`, :func:`~delayform.rightmost_root`
        and :func:`~delayform.count_roots_right_of`.

    Raises
    ------
    LoopError
        As :func:`loop_polynomials`, and for an improper loop.

    Examples
    --------
    The paper's factor s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s})
    is 1 + L1 e^{-tau1 s} + L2 e^{-tau2 s} with L1 = -lam P / (s^2 + D s + P),
    L2 = -lam D s / (s^2 + D s + P):

    >>> q = loop_quasi_polynomial(([-0.5], [1, 0.5, 1]), ([-0.25, 0], [1, 0.5, 1]))
    >>> [c.real.tolist() for c in q.coefficients[:3]]
    [[1.0, 0.5, 1.0], [-0.5], [0.0, -0.25]]
    """
    if loop2 is None:
        if _is_mimo(loop1):
            return _mimo_terms(_as_state_space(loop1, name), name, max_power=2)
        num, den = loop_polynomials(loop1, name=name)
        _check_strictly_proper(num, den, name)
        return TwoDelayQuasiPolynomial(den, num)
    n1, d1 = loop_polynomials(loop1, name=f"{name} 1")
    n2, d2 = loop_polynomials(loop2, name=f"{name} 2")
    _check_strictly_proper(n1, d1, f"{name} 1")
    _check_strictly_proper(n2, d2, f"{name} 2")
    if d1.size == d2.size and np.allclose(d1 / d1[-1], d2 / d2[-1], rtol=1e-14, atol=0.0):
        return TwoDelayQuasiPolynomial(d1, n1, n2 * (d1[-1] / d2[-1]))
    return TwoDelayQuasiPolynomial(npoly.polymul(d1, d2), npoly.polymul(n1, d2), npoly.polymul(n2, d1))


def _check_strictly_proper(num: NDArray[np.float64], den: NDArray[np.float64], name: str) -> None:
    if num.size >= den.size and np.any(num):
        raise LoopError(
            f"{name} is not strictly proper (numerator degree {num.size - 1}, denominator degree "
            f"{den.size - 1}): the quasi-polynomial would be of neutral or advanced type, which "
            "crossing_map and rightmost_root do not treat"
        )


@validated(LoopError)
def loop_characteristic(*loops: object, name: str = "loop") -> QuasiPolynomial:
    """The characteristic quasi-polynomial of 1 + L1 e^{-tau1 s} + ... + Lm e^{-taum s}, any m.

    For the root finders of :mod:`delayform.analysis.roots`
    (``rightmost_root(q, tau1, ..., taum)``, ``count_roots_right_of``,
    ``roots_in``), which take a :class:`~delayform.QuasiPolynomial` with any
    number of delays.

    * SISO loops L_k = N_k / D_k: the principal term is the product of the
      denominators (one denominator when all share it), the term of delay k
      is N_k times the other denominators.
    * One square strictly proper MIMO ``StateSpace`` (or ``TransferFunction``)
      loop, any size: det(sI - A + e^{-tau1 s} BC), with powers of
      e^{-tau1 s} up to the rank of BC.

    Parameters
    ----------
    *loops
        One or more loop gains, as accepted by :func:`loop_polynomials`, or
        one MIMO loop.
    name
        How error messages call the loops.

    Returns
    -------
    QuasiPolynomial
        Terms keyed by delay multiples, one delay per loop.

    Raises
    ------
    LoopError
        For no loop, a MIMO loop among several, a loop that is not strictly
        proper, and as :func:`loop_polynomials`.

    Examples
    --------
    >>> q = loop_characteristic(([1.0], [1.0, 1.0]), ([0.5], [1.0, 1.0]))  # shared plant 1 / (s + 1)
    >>> {k: c.real.tolist() for k, c in q.terms.items()}
    {(0, 0): [1.0, 1.0], (1, 0): [1.0], (0, 1): [0.5]}
    """
    if not loops:
        raise LoopError("give at least one loop gain")
    if any(_is_mimo(loop) for loop in loops):
        if len(loops) > 1:
            raise LoopError(f"{name}: a MIMO loop is taken alone (one delay); got {len(loops)} loops")
        return _mimo_characteristic(_as_state_space(loops[0], name), name)
    pairs = [loop_polynomials(loop, name=f"{name} {k + 1}") for k, loop in enumerate(loops)]
    for k, (num, den) in enumerate(pairs):
        _check_strictly_proper(num, den, f"{name} {k + 1}")
    m = len(pairs)
    unit = [tuple(int(j == k) for j in range(m)) for k in range(m)]
    first = pairs[0][1] / pairs[0][1][-1]
    if all(den.size == first.size and np.allclose(den / den[-1], first, rtol=1e-14, atol=0.0) for _, den in pairs):
        # one plant: one denominator, each numerator rescaled to it
        return QuasiPolynomial({(0,) * m: first, **{unit[k]: num / den[-1] for k, (num, den) in enumerate(pairs)}})
    terms: dict[tuple[int, ...], NDArray[np.float64]] = {(0,) * m: np.ones(1)}
    for _, den in pairs:
        terms[(0,) * m] = npoly.polymul(terms[(0,) * m], den)
    for k, (num, _) in enumerate(pairs):
        others = np.ones(1)
        for j, (_, den) in enumerate(pairs):
            if j != k:
                others = npoly.polymul(others, den)
        terms[unit[k]] = npoly.polymul(num, others)
    return QuasiPolynomial(terms)
