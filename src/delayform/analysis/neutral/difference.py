"""The difference operator of a neutral quasi-polynomial: essential spectrum and strong stability.

A quasi-polynomial ``q(s) = sum_k p_k(s) e^{-(k . tau) s}`` whose principal
polynomial has degree n is *neutral* when some delayed ``p_k`` also has degree
n (Hale and Verduyn Lunel 1993, ch. 12; Michiels and Niculescu 2014, sec. 1.2).
Dividing by ``s^n`` and letting ``|s| -> infinity`` leaves the characteristic
function of the difference equation ``x(t) + sum_k c_k x(t - k . tau) = 0``,

    D(z) = 1 + sum_k c_k z^k,   c_k = p_k[n] / p_0[n],   z = (e^{-tau_1 s}, ..., e^{-tau_m s}),

whose zeros the roots of q approach along chains ``|Im s| -> infinity``: the
*essential spectrum*. Its abscissa, made robust against infinitesimal changes
of the delays as a physical system requires (Hale and Verduyn Lunel 2002,
"Strong stabilization of neutral functional differential equations";
Michiels and Niculescu 2014, Theorem 1.39 and Prop. 1.41; Avellar and Hale
1980 for the rationally independent case), is

    C_D(tau) = max { r : D(e^{-r tau_1 + j theta_1}, ..., e^{-r tau_m + j theta_m}) = 0 for some theta },

the largest r for which D has a zero on the torus of radii ``e^{-r tau_i}``
(for rationally independent delays the points ``e^{-j omega tau}`` are dense
on the torus, Kronecker, so this is the closure of the real parts of D's
zeros; rational ratios can only give less, and a perturbation restores it).
The difference operator is *strongly stable* at tau when ``C_D(tau) < 0``; a
neutral system whose C_D is >= 0 has roots (or a root chain) arbitrarily
close to or right of the imaginary axis under arbitrarily small delay changes
and is never called stable here.

How it is computed
------------------
* Only the delays that occur in D matter. With one (D a polynomial in one z
  of degree K), ``C_D = max_i -ln|z_i| / tau`` over D's roots: exact.
* With two, for each phase theta_2 on a grid the largest r with a root z_1 of
  ``D(., e^{-r tau_2 + j theta_2})`` of modulus ``e^{-r tau_1}`` is bracketed
  below the Hale bound ``sum_k |c_k| e^{-r k.tau} = 1`` (no zero above it) and
  bisected; the best phase is then refined (golden section). The same with
  the roles of the two delays swapped, and the larger value kept (a factor
  of D in one variable alone is seen only by one of the two). Accurate to
  ~1e-9, but a sampled maximum over theta_2: it is a value, not a proof.
* The proofs are separate: *strongly stable* is claimed only when a certified
  lower bound of ``|D|`` over ``r >= 0`` and the whole torus is positive
  (grid with the Lipschitz bounds of D in r and theta, refined until the
  bound is positive or the grid is exhausted; beyond the Hale point
  ``sum |c_k| e^{-r k.tau} <= 1/2``, ``|D| >= 1/2``), and *not strongly stable*
  only when the computed C_D is >= 0 by more than its accuracy. Otherwise the
  answer is "cannot decide" (``None``).
* With three or more delays in D the value is not computed (the Hale bound is
  reported as an upper bound) and the certificate still decides when it can.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from delayform.characteristic import TwoDelayQuasiPolynomial
from delayform._validation import validated
from delayform.errors import DelayError, QuasiPolynomialError
from delayform.quasipolynomial import QuasiPolynomial

__all__ = ["DifferenceOperator", "difference_operator", "abscissa_rounding", "as_general", "certified_min_modulus", "certified_polydisk_min"]

#: Phases of theta_2 sampled before refining the best one.
_PHASES = 256
#: C_D of recent (operator, delays): the report, the strong-stability test and the
#: rightmost root all ask for it.
_ABSCISSAE: dict[tuple[object, tuple[float, ...]], float] = {}
#: Most cells the certified lower bound of |D| evaluates before it gives up.
_CERT_BUDGET = 2_000_000


def as_general(qp: QuasiPolynomial | TwoDelayQuasiPolynomial) -> QuasiPolynomial:
    """Any accepted quasi-polynomial as a :class:`~delayform.quasipolynomial.QuasiPolynomial`.

    Parameters
    ----------
    qp
        A QuasiPolynomial or TwoDelayQuasiPolynomial.
    """
    if isinstance(qp, QuasiPolynomial):
        return qp
    if isinstance(qp, TwoDelayQuasiPolynomial):
        return QuasiPolynomial({(a, b): c for c, a, b in qp.terms()})
    raise QuasiPolynomialError(
        f"expected a QuasiPolynomial or TwoDelayQuasiPolynomial, got {type(qp).__name__}"
    )


@validated(QuasiPolynomialError)
@dataclass(frozen=True)
class DifferenceOperator:
    """``D(z) = 1 + sum_k c_k z^k``, the difference equation of a neutral quasi-polynomial.

    Attributes
    ----------
    exponents
        The delay multiples k of its delayed terms.
    coefficients
        c_k, the ratio of the term's leading coefficient to the principal one's.
    n_delays
        m, the number of delays of the quasi-polynomial.
    """

    exponents: tuple[tuple[int, ...], ...]
    coefficients: tuple[complex, ...]
    n_delays: int

    @property
    def is_trivial(self) -> bool:
        """True when D = 1: the quasi-polynomial is retarded."""
        return not self.exponents

    @property
    def involved(self) -> tuple[int, ...]:
        """Indices (0-based) of the delays that occur in D."""
        return tuple(i for i in range(self.n_delays) if any(k[i] for k in self.exponents))

    def evaluate(self, z: NDArray[np.complex128]) -> NDArray[np.complex128]:
        """D at points z (last axis: z_1..z_m)."""
        out = np.ones(z.shape[:-1], complex)
        for k, c in zip(self.exponents, self.coefficients, strict=True):
            out = out + c * np.prod(z ** np.array(k), axis=-1)
        return out

    def _check(self, taus: tuple[float, ...]) -> NDArray[np.float64]:
        if len(taus) != self.n_delays:
            raise QuasiPolynomialError(f"give {self.n_delays} delay(s), got {len(taus)}")
        t = np.array([float(x) for x in taus])
        if not np.all(np.isfinite(t)) or np.any(t < 0):
            raise DelayError(f"delays must be finite and non-negative, got {tuple(taus)}")
        for i in self.involved:
            if t[i] == 0.0:
                raise DelayError(
                    f"tau{i + 1} = 0 but it occurs in the neutral (difference) part: the system is then "
                    "a different one (the neutral term acts without delay); give tau > 0"
                )
        return t

    def one_delay_polynomial(self) -> NDArray[np.complex128]:
        """D as a polynomial in the one delay's z (ascending), when only one delay occurs in D."""
        (i,) = self.involved
        poly = np.zeros(max(k[i] for k in self.exponents) + 1, complex)
        poly[0] = 1.0
        for k, c in zip(self.exponents, self.coefficients, strict=True):
            poly[k[i]] += c
        return np.trim_zeros(poly, "b")

    def hale_bound(self, *taus: float) -> float:
        """The r with ``sum_k |c_k| e^{-r k.tau} = 1``: D has no zero with real part above it."""
        t = self._check(taus)
        if self.is_trivial:
            return -np.inf
        return _decreasing_root(np.abs(np.array(self.coefficients)), self._delays(t), 1.0)

    def _delays(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array([float(np.dot(k, t)) for k in self.exponents])

    def essential_abscissa(self, *taus: float) -> float:
        """C_D(tau), the robust abscissa of the essential spectrum (module docstring).

        ``-inf`` for a retarded quasi-polynomial (D = 1); NaN when three or more
        delays occur in D (not computed; see :meth:`hale_bound`).
        """
        key = (self, tuple(float(x) for x in taus))
        if key not in _ABSCISSAE:
            if len(_ABSCISSAE) > 256:
                _ABSCISSAE.clear()
            _ABSCISSAE[key] = self._essential_abscissa(*taus)
        return _ABSCISSAE[key]

    def _essential_abscissa(self, *taus: float) -> float:
        t = self._check(taus)
        inv = self.involved
        if self.is_trivial:
            return -np.inf
        if len(inv) == 1:
            i = inv[0]
            roots = np.roots(self.one_delay_polynomial()[::-1])
            if roots.size == 0:
                return -np.inf
            return float(np.max(-np.log(np.abs(roots))) / t[i])
        if len(inv) == 2:
            return _two_delay_abscissa(self, t, inv)
        return float("nan")

    def strongly_stable(self, *taus: float) -> bool | None:
        """True when C_D(tau) < 0 is certified, False when C_D >= 0 is, None when it cannot be decided."""
        t = self._check(taus)
        if self.is_trivial:
            return True
        c = self.essential_abscissa(*taus)
        if np.isfinite(c) and c >= -abscissa_rounding(self, taus):
            return False
        if certified_min_modulus(self, t, 0.0) > 0.0:
            return True
        return None


@validated(QuasiPolynomialError)
def difference_operator(qp: QuasiPolynomial | TwoDelayQuasiPolynomial) -> DifferenceOperator:
    """The difference operator of a quasi-polynomial (D = 1 when it is retarded).

    Parameters
    ----------
    qp
        A :class:`~delayform.quasipolynomial.QuasiPolynomial` or the paper's
        :class:`~delayform.characteristic.TwoDelayQuasiPolynomial`.

    Examples
    --------
    s + 1 + 0.5 s e^{-tau s} (x' + 0.5 x'(t - tau) = -x): D(z) = 1 + 0.5 z, C_D = -ln 2 / tau.

    >>> from delayform.quasipolynomial import QuasiPolynomial
    >>> D = difference_operator(QuasiPolynomial({(0,): [1, 1], (1,): [0, 0.5]}))
    >>> round(D.essential_abscissa(1.0), 12), D.strongly_stable(1.0)
    (-0.69314718056, True)
    """
    g = as_general(qp)
    n = g.degree
    lead = complex(g.principal[n])
    ks, cs = [], []
    for k, c in g.terms.items():
        if any(k) and c.size - 1 == n:
            ks.append(k)
            cs.append(complex(c[n]) / lead)
    return DifferenceOperator(tuple(ks), tuple(cs), g.n_delays)


# ===================================================================== helpers
def abscissa_rounding(D: DifferenceOperator, taus: tuple[float, ...]) -> float:
    """How far from a line an essential abscissa must be to count as on one side: 1e-9 of the scale.

    The abscissa is ``ln|u| / h`` of a computed root; a value within this of 0
    (or of a line) is taken as on it, so it is never called left of it.

    Parameters
    ----------
    D
        The difference operator (not trivial).
    taus
        All delays of the quasi-polynomial.
    """
    return 1e-9 * max(1.0, 1.0 / min(float(taus[i]) for i in D.involved))


def _decreasing_root(a: NDArray[np.float64], h: NDArray[np.float64], level: float) -> float:
    """r with ``sum a_i e^{-r h_i} = level`` (h_i > 0: strictly decreasing in r), by bisection."""
    def f(r: float) -> float:
        with np.errstate(over="ignore"):  # a tiny coefficient puts the root far left: inf only says "above"
            return float(np.sum(a * np.exp(-r * h))) - level

    lo, hi = -1.0, 1.0
    while f(lo) < 0.0:
        lo *= 2.0
    while f(hi) > 0.0:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if f(mid) > 0.0:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * max(1.0, abs(hi)):
            break
    return hi


def _z1_moduli(D: DifferenceOperator, t: NDArray, inv: tuple[int, int], r: NDArray, th2: NDArray) -> NDArray:
    """max_i (-ln|z1_i| / tau_a - r) over the roots z1 of D(., e^{-r tau_b + j theta_2}) (batched)."""
    a, b = inv
    K1 = max(k[a] for k in D.exponents)
    z2 = np.exp(-r * t[b] + 1j * th2)
    poly = np.zeros(z2.shape + (K1 + 1,), complex)
    poly[..., 0] = 1.0
    for k, c in zip(D.exponents, D.coefficients, strict=True):
        poly[..., k[a]] += c * z2 ** k[b]
    if K1 == 1:
        with np.errstate(divide="ignore"):
            z1 = -poly[..., 0] / poly[..., 1]
            return -np.log(np.abs(z1)) / t[a] - r
    lead = poly[..., K1]
    safe = np.where(np.abs(lead) > 1e-300, lead, 1e-300)
    comp = np.zeros(z2.shape + (K1, K1), complex)
    comp[..., np.arange(1, K1), np.arange(K1 - 1)] = 1.0
    comp[..., :, K1 - 1] = -poly[..., :K1] / safe[..., None]
    z1 = np.linalg.eigvals(comp)
    with np.errstate(divide="ignore"):
        return np.max(-np.log(np.abs(z1)), axis=-1) / t[a] - r


def _largest_r(D: DifferenceOperator, t: NDArray, inv: tuple[int, int], th2: NDArray, top: float) -> NDArray:
    """Per phase, the largest r <= top with g(r) = 0 (g = _z1_moduli), NaN when none above the scan's end."""
    # 40 e-foldings of the shorter delay below the Hale bound, but never where e^{-r tau} overflows
    bottom = max(top - 40.0 / min(t[i] for i in inv), -600.0 / max(t[i] for i in inv))
    # denser in the first e-folding below the bound: a zero set can be a narrow window in r there
    # (e.g. D = 1 + z2 + 0.03125 z1 z2, where |1 + z2| is small only for r in (0, 0.015))
    near = max(bottom, top - 1.0 / min(t[i] for i in inv))
    rs = np.concatenate([np.linspace(top, near, 801, endpoint=False), np.linspace(near, bottom, 801)])
    with np.errstate(all="ignore"):  # a vanishing leading coefficient sends a root to infinity (NaN, skipped)
        g = _z1_moduli(D, t, inv, rs[:, None], th2[None, :])  # (nr, nth)
    pos = g >= 0.0
    first = np.argmax(pos, axis=0)
    found = pos[first, np.arange(th2.size)]
    out = np.full(th2.size, np.nan)
    j = np.flatnonzero(found)
    i = first[j]
    at_top = i == 0
    out[j[at_top]] = top
    j, i = j[~at_top], i[~at_top]
    hi, lo = rs[i - 1], rs[i]  # g(hi) < 0 <= g(lo), bisected for all phases at once
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        with np.errstate(all="ignore"):
            up = _z1_moduli(D, t, inv, mid, th2[j]) >= 0.0
        lo = np.where(up, mid, lo)
        hi = np.where(up, hi, mid)
    out[j] = lo
    return out


def _two_delay_abscissa(D: DifferenceOperator, t: NDArray, inv: tuple[int, ...]) -> float:
    """C_D by eliminating each variable in turn, the larger of the two.

    One elimination misses a factor of D in the other variable alone: with
    ``D = (1 + z2)(1 + 0.5 z1)`` the polynomial in z1 vanishes identically at
    ``z2 = -1`` and has no roots there, while the other sees ``|z2| = 1``.
    """
    return max(_eliminated_abscissa(D, t, (inv[0], inv[1])), _eliminated_abscissa(D, t, (inv[1], inv[0])))


def _eliminated_abscissa(D: DifferenceOperator, t: NDArray, pair: tuple[int, int]) -> float:
    """C_D from the roots in the first delay's z of D at the second's phases (module docstring)."""
    top = D.hale_bound(*t)
    th = np.linspace(0.0, 2 * np.pi, _PHASES, endpoint=False)
    r = _largest_r(D, t, pair, th, top)
    if not np.any(np.isfinite(r)):
        return -np.inf
    j = int(np.nanargmax(r))
    # golden-section refinement of the best phase (r*(theta_2) is smooth near its maximum)
    h = 2 * np.pi / _PHASES
    lo, hi = th[j] - h, th[j] + h
    best = float(r[j])
    gr = (np.sqrt(5.0) - 1.0) / 2.0
    for _ in range(40):
        a = hi - gr * (hi - lo)
        b = lo + gr * (hi - lo)
        ra, rb = _largest_r(D, t, pair, np.array([a, b]), top)
        ra = -np.inf if np.isnan(ra) else ra
        rb = -np.inf if np.isnan(rb) else rb
        best = max(best, ra, rb)
        if ra >= rb:
            hi = b
        else:
            lo = a
    return best


def certified_min_modulus(D: DifferenceOperator, t: NDArray[np.float64], r0: float) -> float:
    """A certified lower bound of |D| on ``{r >= r0} x torus`` (module docstring); <= 0 when none was found.

    Cells in r (from r0 up to the Hale half point, beyond which ``|D| >= 1/2``)
    times the phases of the delays in D. A cell with centre x and half-widths
    w_i has ``|D| >= |D(x)| - sum_i L_i w_i``, L_i bounds of the partial
    derivatives of D on the cell (moduli of the terms at the cell's lowest r);
    cells where this is below a quarter of ``|D(x)|`` are split, until every
    cell passes or the budget of evaluations is spent.
    """
    if D.is_trivial:
        return 1.0
    inv = list(D.involved)
    a = np.abs(np.array(D.coefficients))
    coef = np.array(D.coefficients)
    h = D._delays(t)
    r_half = _decreasing_root(a, h, 0.5)
    if r_half <= r0:
        return 0.5
    ks = np.array(D.exponents, float)[:, inv]  # (terms, J)
    J = len(inv)
    n_r, n_th = 16, 32
    rw = (r_half - r0) / n_r / 2
    tw = np.pi / n_th
    grids = np.meshgrid(r0 + rw * (2 * np.arange(n_r) + 1), *([tw * (2 * np.arange(n_th) + 1)] * J), indexing="ij")
    centre = np.stack([g.ravel() for g in grids], -1)  # (cells, 1 + J)
    half = np.tile(np.array([rw] + [tw] * J), (centre.shape[0], 1))
    def value_and_slack(centre: NDArray, half: NDArray) -> tuple[NDArray, NDArray]:
        r, th = centre[:, :1], centre[:, 1:]
        w = a * np.exp(-(r - half[:, :1]) * h)  # (cells, terms): moduli of the terms at the cell's lowest r
        vals = 1.0 + np.sum(coef * np.exp(-r * h + 1j * (th @ ks.T)), axis=-1)
        slack = np.sum(w * h, axis=-1) * half[:, 0] + np.sum((w @ np.abs(ks)) * half[:, 1:], axis=-1)
        return np.abs(vals), slack

    best = _certify_cells(centre, half, value_and_slack)
    return min(best, 0.5)


def certified_polydisk_min(D: DifferenceOperator) -> float:
    """A certified lower bound of |D| on the closed unit polydisk ``|z_i| <= 1``; <= 0 when none was found.

    Positive exactly when D is strongly stable for *every* choice of delays
    (``C_D(tau) < 0`` for all tau: the radii ``e^{-r tau_i}``, r >= 0, sweep
    the polydisk), the condition under which a CTCR map of a neutral system
    counts roots only where they cross the imaginary axis (none comes from
    infinity into the right half-plane). One delay: D's roots, exactly
    (``|D(z)| >= |lead| prod (|z_i| - 1)``). Two: cells over the moduli
    ``rho in [0, 1]^2`` and the phases, with Lipschitz bounds as in
    :func:`certified_min_modulus`. More: not attempted (0).
    """
    if D.is_trivial:
        return 1.0
    inv = list(D.involved)
    if len(inv) == 1:
        poly = D.one_delay_polynomial()
        roots = np.roots(poly[::-1])
        if roots.size == 0:
            return 1.0
        if np.any(np.abs(roots) <= 1.0):
            return 0.0
        return float(abs(poly[-1]) * np.prod(np.abs(roots) - 1.0))
    if len(inv) > 2:
        return 0.0
    # a zero in the polydisk shows as C_D >= 0 along some direction of the delays: look at a few first
    for u in ((1.0, 1.0), (1.0, 0.2), (0.2, 1.0), (1.0, 0.02), (0.02, 1.0)):
        taus = np.ones(D.n_delays)
        taus[inv] = u
        if D.essential_abscissa(*taus) >= 0.0:
            return 0.0
    coef = np.array(D.coefficients)
    a = np.abs(coef)
    ks = np.array(D.exponents, float)[:, inv]  # (terms, 2)
    n_rho, n_th = 8, 32
    g_rho = (2 * np.arange(n_rho) + 1) / (2 * n_rho)
    g_th = np.pi * (2 * np.arange(n_th) + 1) / n_th
    grids = np.meshgrid(g_rho, g_rho, g_th, g_th, indexing="ij")
    centre = np.stack([g.ravel() for g in grids], -1)  # (rho1, rho2, th1, th2)
    half = np.tile([0.5 / n_rho, 0.5 / n_rho, np.pi / n_th, np.pi / n_th], (centre.shape[0], 1))

    def value_and_slack(centre: NDArray, half: NDArray) -> tuple[NDArray, NDArray]:
        rho, th = centre[:, :2], centre[:, 2:]
        hi = np.minimum(rho + half[:, :2], 1.0)
        mono = np.prod(rho[:, None, :] ** ks[None, :, :], axis=-1)  # (cells, terms)
        vals = 1.0 + np.sum(coef * mono * np.exp(1j * (th @ ks.T)), axis=-1)
        # |d/d rho_i| <= sum |c| k_i (rho <= 1);  |d/d theta_i| <= sum |c| k_i rho_hi^k
        top = np.prod(hi[:, None, :] ** ks[None, :, :], axis=-1) * a  # (cells, terms)
        slack = np.sum((a @ ks)[None, :] * half[:, :2], axis=-1) + np.sum((top @ ks) * half[:, 2:], axis=-1)
        return np.abs(vals), slack

    best = _certify_cells(centre, half, value_and_slack)
    return min(best, 1.0)


def _certify_cells(centre: NDArray, half: NDArray, value_and_slack: object) -> float:
    """min over cells of ``|D(centre)| - slack``, splitting cells until each passes; 0 past the budget.

    A cell passes once its slack is under 3/4 of |D| at its centre, so the
    bound is within a factor 4 of the true minimum instead of barely positive.
    A failing cell is split in half along every axis.
    """
    dim = centre.shape[1]
    signs = np.array(np.meshgrid(*([[-0.5, 0.5]] * dim), indexing="ij")).reshape(dim, -1).T
    best, spent = np.inf, 0
    while centre.shape[0]:
        spent += centre.shape[0]
        if spent > _CERT_BUDGET:
            return 0.0
        value, slack = value_and_slack(centre, half)  # type: ignore[operator]
        ok = value - slack >= 0.25 * value
        if np.any(ok):
            best = min(best, float((value - slack)[ok].min()))
        centre, half = centre[~ok], half[~ok]
        centre = (centre[:, None, :] + signs[None, :, :] * half[:, None, :]).reshape(-1, dim)
        half = np.repeat(half / 2.0, signs.shape[0], axis=0)
    return best
