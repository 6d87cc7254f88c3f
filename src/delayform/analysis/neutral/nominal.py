"""The essential spectrum at the delays as given (nominal), beside the robust one.

At fixed delays tau the chains of roots of a neutral quasi-polynomial approach
the zeros of ``s -> D(e^{-tau_1 s}, ..., e^{-tau_m s})`` (Hale and Verduyn Lunel
1993, ch. 12; Michiels and Niculescu 2014, sec. 1.2). The supremum of their
real parts is the *nominal* essential abscissa ``C_nom(tau)``. It is never
above the robust abscissa ``C_D(tau)`` of :mod:`delayform.analysis.neutral.difference`
(the points ``e^{-s tau}`` lie on the torus of radii ``e^{-Re s tau_i}``), and
the two differ only when the delays that occur in D are rationally dependent:

* **commensurate delays** ``tau_i = n_i h`` (integers n_i, base h) turn D into
  a polynomial in one variable, ``P(w) = D(w^{n_1}, ..., w^{n_m})`` with
  ``w = e^{-h s}``, so ``C_nom = max_i -ln|w_i| / h`` over P's roots, exactly;
  ``C_nom < C_D`` is then typical, and an arbitrarily small change of the
  delays moves the essential spectrum to C_D (the abscissa is not continuous in
  the delays, which is why strong stability asks ``C_D < 0``);
* **rationally independent delays** give ``C_nom = C_D``: ``omega tau`` is dense
  on the torus (Kronecker; Avellar and Hale 1980), so the real parts of D's
  zeros fill the robust abscissa's range up to closure.

Delays are taken as commensurate when each ratio to the shortest matches a
fraction p/q to 1e-12 (relative) and P has degree at most
:data:`MAX_NOMINAL_DEGREE`; they are then understood as exactly ``n_i h``.
(Floating-point delays such as 0.1 and 0.3 are never exactly in ratio 3; read
literally, their ratio is a fraction with a denominator near 2^52, whose
essential spectrum reaches C_D only at ``|Im s| ~ 1e16``, a distinction no
physical system has.) The rest are treated as rationally independent. Root
bounds on ``Re s >= r0`` use a certified lower bound of ``|P|`` on the disk
``|w| <= e^{-r0 h}`` (:func:`disk_min_modulus`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.neutral.difference import DifferenceOperator, abscissa_rounding, certified_min_modulus

__all__ = ["MAX_NOMINAL_DEGREE", "Commensurate", "commensurate", "disk_min_modulus", "nominal_abscissa",
           "nominal_min_modulus", "nominally_essentially_stable"]

#: Largest degree of P(w) solved for the nominal essential spectrum of commensurate delays.
MAX_NOMINAL_DEGREE = 512
#: Relative mismatch up to which a delay ratio is taken as the fraction p/q.
_RATIO_TOL = 1e-12
#: Most samples of the circle |w| = rho in the certified lower bound of |P|.
_MAX_CIRCLE_SAMPLES = 1 << 20


@dataclass(frozen=True)
class Commensurate:
    """Delays of D as integer multiples ``n_i`` of a base h, and D at them as a polynomial in w.

    Attributes
    ----------
    base
        h, with ``tau_i ~ n_i h`` for the delays in D.
    multiples
        n_i per delay (0 for a delay that does not occur in D).
    polynomial
        ``P(w) = D(w^{n_1}, ..., w^{n_m})``, coefficients ascending (``P(0) = 1``).
    """

    base: float
    multiples: tuple[int, ...]
    polynomial: NDArray[np.complex128]


def commensurate(D: DifferenceOperator, taus: tuple[float, ...]) -> Commensurate | None:
    """The delays of D as multiples of one base (module docstring), None when they are not (or P is too large).

    Parameters
    ----------
    D
        The difference operator.
    taus
        All delays of the quasi-polynomial (those not in D are ignored).
    """
    t = D._check(tuple(float(x) for x in taus))
    inv = D.involved
    if not inv:
        return None
    ref = min(t[i] for i in inv)
    fracs = {i: Fraction(t[i] / ref).limit_denominator(MAX_NOMINAL_DEGREE) for i in inv}
    if any(abs(t[i] / ref - float(f)) > _RATIO_TOL * (t[i] / ref) for i, f in fracs.items()):
        return None
    lcm = math.lcm(*(f.denominator for f in fracs.values()))
    n = np.zeros(t.size, np.int64)
    for i, f in fracs.items():
        n[i] = f.numerator * (lcm // f.denominator)
    degrees = [int(np.dot(k, n)) for k in D.exponents]
    if max(degrees) > MAX_NOMINAL_DEGREE:
        return None
    base = float(np.dot(n, t) / np.dot(n, n))  # least squares: the closest common base
    poly = np.zeros(max(degrees) + 1, complex)
    poly[0] = 1.0
    for d, c in zip(degrees, D.coefficients, strict=True):
        poly[d] += c  # terms of equal k . n merge (e.g. z1^2 and z2 at tau2 = 2 tau1)
    return Commensurate(base, tuple(int(v) for v in n), np.trim_zeros(poly, "b"))


def nominal_abscissa(D: DifferenceOperator, taus: tuple[float, ...]) -> float:
    """C_nom(tau): the abscissa of the essential spectrum at exactly these delays (module docstring).

    ``-inf`` when D = 1 or when D's terms cancel at these delays (P = 1: the
    quasi-polynomial is then retarded there); for rationally independent
    delays the robust :meth:`DifferenceOperator.essential_abscissa` (NaN when
    not computed).

    Parameters
    ----------
    D
        The difference operator.
    taus
        All delays of the quasi-polynomial.
    """
    t = tuple(float(x) for x in taus)
    if D.is_trivial:
        return -np.inf
    com = commensurate(D, t)
    if com is None:
        return D.essential_abscissa(*t)
    if com.polynomial.size == 1:
        return -np.inf
    # the roots u = 1/w of the reversed polynomial u^K P(1/u), which is monic (P(0) = 1): a tiny
    # leading coefficient of P then gives a tiny u (a far-left chain) instead of an overflowing w
    u = np.roots(com.polynomial)
    with np.errstate(divide="ignore"):
        return float(np.max(np.log(np.abs(u))) / com.base)


def disk_min_modulus(poly: NDArray[np.complex128], rho: float) -> float:
    """A certified lower bound of ``|P|`` on the closed disk ``|w| <= rho``; 0 when P has a zero there.

    P has no zero inside when its winding number along ``|w| = rho`` is 0, and
    then ``min |P|`` over the disk is attained on the circle (minimum modulus
    principle). On the circle ``|dP/dtheta| <= L = sum_j j |a_j| rho^j``; with M
    samples and ``L 2 pi / M <= |P|/2`` at every sample each arg increment is
    below pi/6, so the winding is exact, and ``|P| >= min |P(w_i)| - L pi / M``.
    M doubles until that holds (at most :data:`_MAX_CIRCLE_SAMPLES`).

    Parameters
    ----------
    poly
        P's coefficients, ascending.
    rho
        The disk's radius.
    """
    a = np.asarray(poly, complex)
    if a.size == 1:
        return float(abs(a[0]))
    if not (np.isfinite(rho) and rho >= 0.0):
        return 0.0
    j = np.arange(a.size)
    with np.errstate(over="ignore", invalid="ignore"):
        L = float(np.sum(j * np.abs(a) * rho**j))
    if not np.isfinite(L):
        return 0.0
    if L == 0.0:
        return float(abs(a[0]))
    m = 64 * a.size
    while m <= _MAX_CIRCLE_SAMPLES:
        w = rho * np.exp(2j * np.pi * np.arange(m) / m)
        with np.errstate(over="ignore", invalid="ignore"):
            vals = np.polynomial.polynomial.polyval(w, a)
        mod = np.abs(vals)
        if not np.all(np.isfinite(mod)):
            return 0.0
        if L * 2.0 * np.pi / m <= 0.5 * mod.min():
            winding = np.sum(np.angle(np.roll(vals, -1) / vals)) / (2.0 * np.pi)
            if round(winding) != 0:
                return 0.0
            return float(mod.min() - L * np.pi / m)
        m *= 2
    return 0.0


def nominal_min_modulus(D: DifferenceOperator, taus: tuple[float, ...], r0: float) -> tuple[float, Commensurate | None]:
    """A certified lower bound of ``|D(e^{-s n h})|`` (commensurate) or of |D| on the torus, on Re s >= r0.

    Returns the bound (<= 0 when none was found) and the commensurate form
    (None for rationally independent delays: the robust bound of
    :func:`~delayform.analysis.neutral.difference.certified_min_modulus`).

    Parameters
    ----------
    D
        The difference operator.
    taus
        All delays of the quasi-polynomial.
    r0
        The half-plane's edge.
    """
    t = np.array([float(x) for x in taus])
    com = commensurate(D, tuple(t))
    if com is None:
        return certified_min_modulus(D, t, r0), None
    with np.errstate(over="ignore"):
        rho = float(np.exp(-r0 * com.base))
    return disk_min_modulus(com.polynomial, rho), com


def nominally_essentially_stable(D: DifferenceOperator, taus: tuple[float, ...]) -> bool | None:
    """True when ``C_nom(tau) < 0`` is certified, False when ``C_nom >= 0`` is, None when undecided.

    Certified: ``|P| > 0`` on the closed unit disk (commensurate delays, taken
    as exactly ``n_i h``: module docstring) or ``|D| > 0`` on
    ``{r >= 0} x torus`` (independent).

    Parameters
    ----------
    D
        The difference operator.
    taus
        All delays of the quasi-polynomial.
    """
    t = tuple(float(x) for x in taus)
    if D.is_trivial:
        return True
    c = nominal_abscissa(D, t)
    if np.isfinite(c) and c >= -abscissa_rounding(D, t):
        return False
    bound, _ = nominal_min_modulus(D, t, 0.0)
    return True if bound > 0.0 else None
