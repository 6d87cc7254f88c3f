"""CTCR for any two-delay quasi-polynomial: commensurate terms, z1 z2^2, ...

A :class:`~delayform.quasipolynomial.QuasiPolynomial` in two delays is
``q(s) = sum_{a,b} p_ab(s) z1^a z2^b`` with ``z_k = e^{-tau_k s}``. When its
terms are the six of the paper's eq. 5 it is traced exactly as the paper's form;
otherwise the same CTCR construction runs on :class:`TermsQP` with two
eliminations that hold for any degrees K1 (in z1) and K2 (in z2):

* On the imaginary axis ``|z_k| = 1``, so ``conj(z_k) = 1 / z_k``. With the
  conjugate-reciprocal ``q~(z1, z2) = z1^K1 z2^K2 conj(q(1/conj z1, 1/conj z2))``
  every solution on the torus is a common zero of q and q~. Their resultant
  in z1 (a 2 K1 x 2 K1 Sylvester determinant whose entries are polynomials in
  z2) is a polynomial of degree <= 2 K1 K2 in z2; it is evaluated on that many
  roots of unity plus one and its coefficients recovered by the FFT (the
  exact inverse of evaluation there). Its unit-modulus roots give z2, the
  roots of q(., z2) of unit modulus give z1, and Newton's method on the two
  phases polishes each pair on q itself. Frequencies are then joined into
  paths as for the paper's general path (:func:`~delayform.analysis.ctcr.phase._general_paths`).
* On an axis (one delay zero), for a qp in one delay and on the lines
  ``theta_k = const`` that seed the two-delay sweep: the frequency is
  eliminated instead, a resultant in z on the unit circle
  (:mod:`delayform.analysis.ctcr.single`), which needs no bound on the
  crossing frequencies.
* When every power of z1 is a multiple of g, q is eliminated in ``w = z1^g``
  (in z1 the resultant would be a g-th power, with g-fold roots).
* When every delayed term is a power of one monomial ``z1^a z2^b``, q is a
  one-delay qp in ``a tau1 + b tau2`` and its crossings are straight lines
  (:func:`~delayform.analysis.ctcr.curves.line_direction`); a q with a
  *factor* in one monomial has that factor split off first
  (:mod:`delayform.analysis.ctcr.factored`): at its crossing frequencies whole
  lines of the torus solve q, which the sweep in omega cannot see.

Both are eliminations, not sign changes on a grid: a frequency or phase is
found whenever it is a root of the eliminant, however close two of them lie.
"""

from __future__ import annotations

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import ArrayLike, NDArray

from delayform.analysis.ctcr.single import sylvester, unit_roots_single
from delayform.analysis.neutral.difference import certified_polydisk_min, difference_operator
from delayform.characteristic import DELAY_MULTIPLES, TwoDelayQuasiPolynomial
from delayform.errors import NeutralQuasiPolynomialError, QuasiPolynomialError
from delayform.quasipolynomial import QuasiPolynomial

__all__ = ["TermsQP", "as_traced", "resultant_solutions", "unit_roots_single", "collapse", "newton_phases", "unit_circle_roots"]

TWO_PI = 2.0 * np.pi


class TermsQP:
    """A two-delay quasi-polynomial given by its terms, with the interface the CTCR engine reads.

    Parameters
    ----------
    terms
        ``(coefficients ascending in s, multiple of tau1, multiple of tau2)``,
        the principal term (0, 0) first.
    """

    def __init__(
        self, terms: tuple[tuple[NDArray[np.complex128], int, int], ...], *, crossing_bound: float | None = None
    ) -> None:
        self._terms = tuple((np.asarray(c, np.complex128), int(a), int(b)) for c, a, b in terms)
        #: for a neutral qp, the bound on crossing frequencies from its difference operator
        #: (:func:`neutral_traced`); None: the retarded Cauchy-like bound
        self.crossing_bound = crossing_bound
        if self._terms[0][1:] != (0, 0):
            raise QuasiPolynomialError("the principal term (0, 0) must come first")

    def terms(self) -> tuple[tuple[NDArray[np.complex128], int, int], ...]:
        """The non-zero terms as (coefficients, multiple of tau1, multiple of tau2)."""
        return self._terms

    @property
    def g1(self) -> NDArray[np.complex128]:
        """The principal polynomial (named as in the paper's eq. 5)."""
        return self._terms[0][0]

    @property
    def coefficients(self) -> tuple[NDArray[np.complex128], ...]:
        """Coefficients of every term, principal first."""
        return tuple(c for c, _, _ in self._terms)

    @property
    def degree(self) -> int:
        """Degree of the principal polynomial."""
        return int(self.g1.size - 1)

    @property
    def is_real(self) -> bool:
        """True when every coefficient is real."""
        return all(bool(np.all(c.imag == 0.0)) for c in self.coefficients)

    @property
    def is_retarded(self) -> bool:
        """True when every delayed term has lower degree than the principal one."""
        return all(c.size - 1 < self.degree for c, _, _ in self._terms[1:])

    def delay_free(self) -> NDArray[np.complex128]:
        """Coefficients of q at tau1 = tau2 = 0."""
        out = np.zeros(max(c.size for c in self.coefficients), np.complex128)
        for c in self.coefficients:
            out[: c.size] += c
        return out

    def conjugate(self) -> TermsQP:
        """conj(q(conj s)): its omega > 0 crossings are the omega < 0 crossings of q."""
        return TermsQP(tuple((np.conj(c), a, b) for c, a, b in self._terms), crossing_bound=self.crossing_bound)

    def evaluate(self, s: ArrayLike, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.complex128]:
        """q(s) at the delays (broadcasting)."""
        s = np.asarray(s, complex)
        return sum((npoly.polyval(s, c) * np.exp(-(a * np.asarray(tau1) + b * np.asarray(tau2)) * s)
                    for c, a, b in self._terms), start=np.zeros(np.broadcast_shapes(s.shape, np.shape(tau1),
                                                                                  np.shape(tau2)), complex))

    def derivative(self, s: ArrayLike, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.complex128]:
        """dq/ds at the delays."""
        s = np.asarray(s, complex)
        out = np.zeros(np.broadcast_shapes(s.shape, np.shape(tau1), np.shape(tau2)), complex)
        for c, a, b in self._terms:
            h = a * np.asarray(tau1) + b * np.asarray(tau2)
            out = out + (npoly.polyval(s, npoly.polyder(c)) - h * npoly.polyval(s, c)) * np.exp(-h * s)
        return out

    def delay_derivative(self, s: ArrayLike, tau1: ArrayLike, tau2: ArrayLike, *, delay: int) -> NDArray[np.complex128]:
        """dq/dtau_k at fixed s."""
        s = np.asarray(s, complex)
        out = np.zeros(np.broadcast_shapes(s.shape, np.shape(tau1), np.shape(tau2)), complex)
        for c, a, b in self._terms:
            k = a if delay == 1 else b
            if k:
                h = a * np.asarray(tau1) + b * np.asarray(tau2)
                out = out - k * s * npoly.polyval(s, c) * np.exp(-h * s)
        return out

    def describe(self) -> str:
        """The terms written out."""
        return QuasiPolynomial({(a, b): c for c, a, b in self._terms}).describe()


def neutral_traced(qp: QuasiPolynomial) -> TermsQP:
    """A neutral two-delay qp prepared for CTCR, or NeutralQuasiPolynomialError when its D does not allow it.

    CTCR counts roots where they cross the imaginary axis; a neutral system
    can also gain roots from infinity. It cannot when the difference operator
    D is strongly stable for every delay pair (D zero-free on the closed unit
    polydisk, certified by :func:`~delayform.analysis.neutral.difference.certified_polydisk_min`
    with a lower bound delta of |D| there). Then on the axis
    ``|q(j omega)| >= |p_0[n]| delta omega^n - sum_{i<n} sum_k |p_k[i]| omega^i``,
    so every crossing frequency is below
    ``max(1, sum_{i<n} sum_k |p_k[i]| / (|p_0[n]| delta))``, the bound the
    curves and axes are traced to.

    Parameters
    ----------
    qp
        A neutral quasi-polynomial in two delays.
    """
    D = difference_operator(qp)
    delta = certified_polydisk_min(D)
    if not delta > 0.0:
        raise NeutralQuasiPolynomialError(
            "the quasi-polynomial is neutral and its difference operator is not certified strongly stable for "
            "every delay pair (D has, or may have, a zero in the closed unit polydisk): roots can reach the "
            "right half-plane from infinity, which a crossing map does not see; use neutral_spectrum at "
            "given delays instead"
        )
    n = qp.degree
    low = sum(float(np.sum(np.abs(c[:n]))) for c in qp.terms.values())
    bound = max(1.0, low / (abs(qp.principal[n]) * delta)) * (1.0 + 1e-9)
    return TermsQP(tuple((c, k[0], k[1]) for k, c in qp.terms.items()), crossing_bound=bound)


def as_traced(qp: QuasiPolynomial) -> TwoDelayQuasiPolynomial | TermsQP:
    """The paper's form when q's terms are among the paper's eq. 5's six, else :class:`TermsQP`.

    Parameters
    ----------
    qp
        A quasi-polynomial in two delays.
    """
    if qp.n_delays != 2:
        raise QuasiPolynomialError(
            f"crossing_map needs a quasi-polynomial in two delays; this one has {qp.n_delays}"
        )
    if qp.is_neutral:
        return neutral_traced(qp)
    if all(k in DELAY_MULTIPLES for k in qp.terms):
        return qp.to_two_delay()
    return TermsQP(tuple((c, k[0], k[1]) for k, c in qp.terms.items()))


def collapse(qp: TwoDelayQuasiPolynomial | TermsQP, delay: int) -> list[NDArray[np.complex128]]:
    """h_j(s) of ``q = sum_j h_j(s) z^j`` with the *other* delay set to zero (z = e^{-tau_delay s}).

    Parameters
    ----------
    qp
        The two-delay quasi-polynomial.
    delay
        1 or 2: the delay kept; the other is zero.
    """
    degs = [(a if delay == 1 else b) for _, a, b in qp.terms()]
    out = [np.zeros(0, complex) for _ in range(max(degs) + 1)]
    for (c, _, _), j in zip(qp.terms(), degs, strict=True):
        acc = np.zeros(max(out[j].size, c.size), complex)
        acc[: out[j].size] += out[j]
        acc[: c.size] += c
        out[j] = acc
    return [np.trim_zeros(h, "b") for h in out]


def omega_bound(qp: TwoDelayQuasiPolynomial | TermsQP) -> float:
    """Bound on |s| of every root with Re s >= 0 (Cauchy-like; see phase._omega_bound; a neutral qp's own)."""
    if isinstance(qp, TermsQP) and qp.crossing_bound is not None:
        return qp.crossing_bound
    d = qp.degree
    lower = np.zeros(d + 1)
    for c in qp.coefficients:
        lower[: c.size] += np.abs(c)
    lower[d] = 0.0
    lower = lower / abs(qp.g1[d])
    return float(max(1.0, lower.sum()) * 1.0001)


# ===================================================================== two delays (curves)
def resultant_solutions(qp: TermsQP, omega: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """All (theta1, theta2) on the torus with q(j omega) = 0 at each omega (module docstring).

    Parameters
    ----------
    qp
        The quasi-polynomial by its terms.
    omega
        Frequencies.
    """
    terms = qp.terms()
    # q is a polynomial in w = z1^g (g the gcd of the powers of z1): eliminating z1 itself would
    # give the g-th power of the resultant in w, whose g-fold roots rounding spreads by eps^(1/g)
    g = max(1, int(np.gcd.reduce([a for _, a, _ in terms])))
    K1 = max(a for _, a, _ in terms) // g
    K2 = max(b for _, _, b in terms)
    s = 1j * np.asarray(omega, float)
    vals = [npoly.polyval(s, c) for c, _, _ in terms]
    mult = np.array([(a, b) for _, a, b in terms], float)
    reduced = [(a // g, b) for _, a, b in terms]
    n_z = 2 * K1 * K2 + 1
    z2 = np.exp(2j * np.pi * np.arange(n_z) / n_z)
    # P[w, m, a] = sum_b c_ab(omega_w) z2_m^b ; Pt[w, m, a] = sum_b conj(c_ab) z2_m^(K2 - b)
    P = np.zeros((s.size, n_z, K1 + 1), complex)
    Pt = np.zeros((s.size, n_z, K1 + 1), complex)
    for v, (a, b) in zip(vals, reduced, strict=True):
        P[:, :, a] += v[:, None] * z2[None, :] ** b
        Pt[:, :, K1 - a] += np.conj(v)[:, None] * z2[None, :] ** (K2 - b)
    R = np.linalg.det(sylvester(P[..., ::-1], Pt[..., ::-1]))
    coef = np.fft.fft(R, axis=1) / n_z  # R(z2_m) = sum_k coef_k z2_m^k on the n_z-th roots of unity
    # candidates (sample, theta1, theta2) from the unit roots, then one batched Newton on q for all
    terms_at = np.stack(vals, axis=1)  # (omega, term)
    pairs = [(i, z) for i in range(s.size) for z in unit_circle_roots(coef[i], 1e-11)]
    at = np.array([i for i, _ in pairs], np.int64)
    z2s = np.array([z for _, z in pairs], complex)
    poly1 = np.zeros((at.size, K1 + 1), complex)  # q(., z2) in w, ascending, one row per (omega, z2)
    for k, (a, b) in enumerate(reduced):
        poly1[:, a] += terms_at[at, k] * z2s**b
    idx: list[int] = []
    starts: list[tuple[float, float]] = []
    for row, w in _poly_roots(poly1):
        if abs(abs(w) - 1.0) > 1e-2:  # a start only: Newton and the certificate decide
            continue
        for k in range(g):  # the g phases theta1 with e^{-j g theta1} = w
            idx.append(int(at[row]))
            starts.append(((-np.angle(w) + TWO_PI * k) / g, -np.angle(z2s[row])))
    where = np.asarray(idx, np.int64)
    th, ok = _newton_phases_batch(terms_at[where], mult, np.asarray(starts, float).reshape(-1, 2))
    where, th = where[ok], th[ok]
    return [_unique(th[where == i]) for i in range(s.size)]


def _poly_roots(poly: NDArray[np.complex128]) -> list[tuple[int, complex]]:
    """(row, root) of every row's polynomial (ascending): full-degree rows by one batched eigensolve."""
    out: list[tuple[int, complex]] = []
    if poly.shape[0] == 0 or poly.shape[1] < 2:
        return out
    n = poly.shape[1] - 1
    lead = poly[:, n]
    full = np.abs(lead) > 1e-12 * np.max(np.abs(poly), axis=1)
    rows = np.flatnonzero(full)
    if rows.size:
        comp = np.zeros((rows.size, n, n), complex)  # companion matrices of the monic rows
        comp[:, 0, :] = -(poly[rows, ::-1][:, 1:] / lead[rows, None])
        comp[:, np.arange(1, n), np.arange(n - 1)] = 1.0
        roots = np.linalg.eigvals(comp)
        out.extend((int(r), complex(w)) for r, ws in zip(rows, roots, strict=True) for w in ws)
    for r in np.flatnonzero(~full):  # a degree drop: the roots of the rest (those at infinity dropped)
        nz = np.flatnonzero(np.abs(poly[r]) > 0)
        if nz.size >= 2:
            out.extend((int(r), complex(w)) for w in np.roots(poly[r, : nz[-1] + 1][::-1]))
    return out


def _newton_phases_batch(
    g: NDArray[np.complex128], mult: NDArray[np.float64], th: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """:func:`newton_phases` for many starts at once: rows of g (terms at j omega) and of th (theta1, theta2).

    Returns the polished phases in [0, 2 pi) and which of them solve q to 1e-11 of its terms' moduli.
    """
    t1, t2 = th[:, 0].copy(), th[:, 1].copy()
    scale = np.sum(np.abs(g), axis=1)
    live = np.ones(t1.size, bool)
    for _ in range(30):
        if not np.any(live):
            break
        e = g * np.exp(-1j * (mult[None, :, 0] * t1[:, None] + mult[None, :, 1] * t2[:, None]))
        f = e.sum(axis=1)
        d1 = (-1j * mult[None, :, 0] * e).sum(axis=1)
        d2 = (-1j * mult[None, :, 1] * e).sum(axis=1)
        det = d1.real * d2.imag - d2.real * d1.imag
        # as one start would: stop where converged, or where J is singular (a tangency)
        live &= (np.abs(f) > 1e-14 * scale) & (np.abs(det) > 1e-14 * (np.abs(d1) * np.abs(d2) + 1e-300))
        with np.errstate(divide="ignore", invalid="ignore"):
            step1 = (f.real * d2.imag - d2.real * f.imag) / det
            step2 = (d1.real * f.imag - f.real * d1.imag) / det
        t1 = np.where(live, t1 - step1, t1)
        t2 = np.where(live, t2 - step2, t2)
    ok = _kantorovich_ok(g, mult, t1, t2)
    return np.column_stack([np.mod(t1, TWO_PI), np.mod(t2, TWO_PI)]), ok


def _kantorovich_ok(
    g: NDArray[np.complex128], mult: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> NDArray[np.bool_]:
    """Whether a zero of q provably lies next to each (theta1, theta2): rows of g are the terms at j omega.

    A small residual alone is no proof: next to the end of a frequency band (two solutions merging,
    the Jacobian nearly singular) |q| stays below any fixed residual tolerance over a range of
    frequencies *past* the end, where no solution exists, and Newton stalls there on a near-solution;
    the solution count then flickered from sample to sample. Kantorovich's theorem decides instead:
    with beta >= |J^-1|, eta the Newton step and L = sum_k |g_k| |(a_k, b_k)|^2 a Lipschitz constant
    of J, ``beta L eta <= 1/2`` proves a zero within 2 eta. Past a band's end nothing passes it; twins
    so close that rounding hides them (J singular to working precision) fail it too, and the sweep
    does not chase the count's changes among those (:func:`near_fold`).
    """
    h, f = _kantorovich_ratio(g, mult, t1, t2)
    ok = h <= 0.5
    return ok & (np.abs(f) <= 1e-11 * np.sum(np.abs(g), axis=1))


def _kantorovich_ratio(
    g: NDArray[np.complex128], mult: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.complex128]]:
    """Kantorovich's ``h = beta L eta`` (and q) at each (theta1, theta2); rows of g are the terms at j omega."""
    e = g * np.exp(-1j * (mult[None, :, 0] * t1[:, None] + mult[None, :, 1] * t2[:, None]))
    f = e.sum(axis=1)
    d1 = (-1j * mult[None, :, 0] * e).sum(axis=1)
    d2 = (-1j * mult[None, :, 1] * e).sum(axis=1)
    det = np.abs(d1.real * d2.imag - d2.real * d1.imag)
    frob = np.sqrt(np.abs(d1) ** 2 + np.abs(d2) ** 2)
    lip = np.sum(np.abs(g) * np.sum(mult**2, axis=1)[None, :], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        beta = frob / det  # |J^-1|_2 <= |J|_F / |det J| for a 2 x 2 matrix
        h = beta * lip * (beta * np.abs(f))  # beta |f| >= the Newton step's length
    return np.where(np.isfinite(h), h, np.inf), f


def near_fold(qp: TwoDelayQuasiPolynomial | TermsQP, omega: float, th: NDArray[np.float64]) -> bool:
    """Whether some solution (row of th) at omega is near the limit of what can be certified.

    Next to a turning point in omega (two solutions merging, J nearly singular) Kantorovich's ratio
    grows toward 1/2; from ``h > 1e-2`` on rounding decides which of the twins are found, so a
    change of the solution count there says nothing more about where the turn is.
    """
    if th.shape[0] == 0:
        return False
    terms = list(qp.terms())
    g = np.array([npoly.polyval(1j * omega, c) for c, _, _ in terms])
    mult = np.array([(a, b) for _, a, b in terms], float)
    h, _ = _kantorovich_ratio(np.broadcast_to(g, (th.shape[0], g.size)), mult, th[:, 0], th[:, 1])
    return bool(np.any(h > 1e-2))


def unit_circle_roots(poly: NDArray[np.complex128], rel_tol: float) -> NDArray[np.complex128]:
    """Roots within 1e-2 of the unit circle of a polynomial (ascending coefficients).

    Coefficients below ``rel_tol`` of the largest are rounding noise of the
    elimination and are dropped at both ends (a root at 0 or at infinity).
    They are only Newton's starting points, each solution certified on q
    itself: a double unit root of the eliminant (two torus solutions sharing
    their z2) comes out split by rounding as far as 1e-4 off the circle, and
    the narrower window of before dropped one, both or neither of the pair at
    random from one frequency to the next.
    """
    scale = np.max(np.abs(poly)) if poly.size else 0.0
    nz = np.flatnonzero(np.abs(poly) > rel_tol * scale) if scale > 0 else np.zeros(0, int)
    if nz.size < 2:
        return np.zeros(0, complex)
    roots = np.roots(poly[nz[0] : nz[-1] + 1][::-1])
    return roots[np.abs(np.abs(roots) - 1.0) < 1e-2]


def newton_phases(g: NDArray[np.complex128], mult: NDArray[np.float64], t1: float, t2: float) -> tuple[float, float] | None:
    """Polish (theta1, theta2) on ``sum_k g_k e^{-j(a_k theta1 + b_k theta2)} = 0`` at one omega.

    Parameters
    ----------
    g
        The terms' polynomials at j omega.
    mult
        Their delay multiples, one row (a, b) per term.
    t1, t2
        Starting phases.
    """
    scale = float(np.sum(np.abs(g)))
    for _ in range(30):
        e = g * np.exp(-1j * (mult[:, 0] * t1 + mult[:, 1] * t2))
        f = e.sum()
        if abs(f) <= 1e-14 * scale:
            break
        d1 = (-1j * mult[:, 0] * e).sum()
        d2 = (-1j * mult[:, 1] * e).sum()
        J = np.array([[d1.real, d2.real], [d1.imag, d2.imag]])
        # the system is 2 real equations in 2 unknowns; a singular J (a tangency) stops here
        if abs(np.linalg.det(J)) <= 1e-14 * (abs(d1) * abs(d2) + 1e-300):
            break
        step = np.linalg.solve(J, [f.real, f.imag])
        t1 -= step[0]
        t2 -= step[1]
    if not _kantorovich_ok(g[None, :], mult, np.array([t1]), np.array([t2]))[0]:
        return None
    return float(np.mod(t1, TWO_PI)), float(np.mod(t2, TWO_PI))


def _unique(th: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rows of th once: a row within 1e-7 (torus, per phase) of an earlier kept row is dropped."""
    d = np.abs(np.mod(th[:, None, :] - th[None, :, :] + np.pi, TWO_PI) - np.pi).max(axis=2)
    keep: list[int] = []
    for r in range(th.shape[0]):
        if all(d[r, k] > 1e-7 for k in keep):
            keep.append(r)
    return th[keep].reshape(-1, 2)
