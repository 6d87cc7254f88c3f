"""Every crossing of the imaginary axis of g1 + g2 z + g4 z^2, z = e^{-tau s}, by elimination.

For a SISO loop (g4 = 0) the crossings are the gain crossovers, the positive
real roots of |g1(j omega)|^2 - |g2(j omega)|^2; for a 2 x 2 loop, the roots
of the resultant in z of q(j omega, z) and its conjugate reciprocal. No
frequency grid: the polynomial in omega holds every crossing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import NDArray

from delayform._validation import validated
from delayform.characteristic import TwoDelayQuasiPolynomial
from delayform.errors import LoopError, NotConvergedError

#: (a tangency |L| = 1 is a double root, split by rounding into a near-real pair)
REAL_ROOT_TOL = 1e-6


@validated(LoopError)
@dataclass(frozen=True)
class Crossover:
    """One gain crossover |L(j omega)| = 1 and the delays at which it puts a root on the axis.

    Phase margins are in degrees, as python-control's ``margin`` and
    ``stability_margins`` give them; ``phase_margin_rad`` is the same angle
    in radians.

    Attributes
    ----------
    omega
        Crossover frequency (rad/s), a positive root of
        |D(j omega)|^2 - |N(j omega)|^2.
    phase_margin
        180 + arg L(j omega) in degrees, wrapped to [-180, 180], of the loop
        with its own dead time (if one was given to :func:`delay_margin`).
    tau
        The first extra delay (s) with the root j omega:
        (phase_margin_rad mod 2 pi) / omega.
    root_tendency
        Sign of Re ds/dtau there: +1 the root moves right (destabilizing),
        -1 left, 0 it only touches the axis (Definition "Root Tendency").
    """

    omega: float
    phase_margin: float
    tau: float
    root_tendency: int

    @property
    def phase_margin_rad(self) -> float:
        """The phase margin in radians, in [-pi, pi]."""
        return math.radians(self.phase_margin)

    @property
    def period(self) -> float:
        """2 pi / omega: the same root returns every period of delay."""
        return 2.0 * math.pi / self.omega

    def delays(self, tau_max: float) -> NDArray[np.float64]:
        """Every extra delay in [0, tau_max] at which this crossover puts j omega on the axis."""
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


def _crossovers(qp: TwoDelayQuasiPolynomial, delay: float = 0.0) -> tuple[Crossover, ...]:
    """Every crossover of the loop with its own dead time ``delay``, sorted by the first extra delay.

    The crossings of the delay-free loop do not depend on ``delay``: each
    (omega, tau0) recurs every 2 pi / omega, so the first one at or beyond
    ``delay`` is ``delay + ((tau0 - delay) mod 2 pi / omega)``, and the
    phase margin of L e^{-delay s} there is omega times that extra delay.
    """
    factor = _square_factor(qp) if qp.g4.size else qp
    if factor is None:
        pairs = _quadratic_crossings(qp)
        factor = qp
    else:
        pairs = _siso_crossings(factor.g1, factor.g2)
    out = []
    for w, tau0 in pairs:
        extra = (tau0 - delay) % (2.0 * math.pi / w) if delay else tau0
        pm = math.remainder(w * extra, 2.0 * math.pi)  # extra = (pm mod 2 pi) / omega
        rt = int(factor.root_tendency(np.array([w]), np.array([delay + extra]), np.array([0.0]), delay=1)[0])
        out.append(Crossover(omega=float(w), phase_margin=math.degrees(pm), tau=float(extra), root_tendency=rt))
    return tuple(sorted(out, key=lambda c: c.tau))
