"""Roots of neutral quasi-polynomials: bounded regions, the rightmost root, the report.

A neutral quasi-polynomial has infinitely many roots in every vertical strip
that holds its essential spectrum (:mod:`delayform.analysis.neutral.difference`),
so it is solved in bounded regions only, by a method that needs no
discretization of a retarded DDE:

* **roots in a rectangle** -- the certified argument-principle count of
  :mod:`delayform.analysis.roots.argument_principle` (Lipschitz-certified
  sampling of arg q on each edge) splits the rectangle recursively; a box
  that holds one root is solved by Newton's method on q from its centre
  (accepted only inside the box with relative residual <= 1e-10); a box
  below 1e-7 of the scale that still holds m > 1 roots is a root of
  multiplicity m, polished on ``q^(m-1)`` (accuracy about eps^(1/m) for the
  root itself, as double precision allows). Each box's count is certified,
  so none is lost; a split line that passes through a root is moved.
* **the rightmost root** -- of the system as stated, at exactly the delays
  given. Right of ``sigma0 = C_nom + margin`` (C_nom the *nominal* essential
  abscissa of :mod:`delayform.analysis.neutral.nominal`: the roots of a
  polynomial in ``w = e^{-h s}`` for commensurate delays, the robust C_D for
  rationally independent ones) the roots are finitely many and lie in a
  rectangle: with a certified lower bound ``delta0`` of ``|D(e^{-s tau})|`` on
  ``Re s >= sigma0`` (of ``|P|`` on a disk, or of |D| on the torus),
  ``q(s) = p_0[n] s^n D(e^{-s tau}) + sum_{i<n} s^i (...)`` cannot vanish for
  ``|s| > max(1, sum_i B_i / (|p_0[n]| delta0))`` with ``B_i = sum_k |p_k[i]| e^{-sigma0 h_k}``.
  All roots there are found by the certified count on q itself; the one of
  largest real part is the answer. When none lies right of ``sigma0`` for
  margins down to 1e-3 of the scale, the rightmost root does not lie
  (separably) right of the essential spectrum and
  :class:`~delayform.errors.EssentialSpectrumError` gives C_nom and C_D.
* **strong stability** -- the robust abscissa C_D (reached under arbitrarily
  small changes of the delays) is reported beside the nominal answer. When
  ``C_D >= 0`` the system is *fragile*: an arbitrarily small change of the
  delays destabilizes it, even when it is exponentially stable at the delays
  given (``C_nom`` and every root left of the axis). :func:`neutral_rightmost_root`
  then warns (:class:`~delayform.errors.FragileNeutralWarning`) and
  :class:`NeutralSpectrum` says so in ``fragile`` and :meth:`NeutralSpectrum.describe`.
"""

from __future__ import annotations

import math
import os
import sys
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import NDArray

from delayform.analysis.neutral.difference import (
    DifferenceOperator,
    abscissa_rounding,
    as_general,
    difference_operator,
)
from delayform.analysis.neutral.nominal import (
    commensurate,
    nominal_abscissa,
    nominal_min_modulus,
    nominally_essentially_stable,
)
from delayform.analysis.roots.argument_principle import count_in_region
from delayform.analysis.roots.problem import Terms, evaluate
from delayform.characteristic import TwoDelayQuasiPolynomial
from delayform._validation import validated
from delayform.errors import (
    EssentialSpectrumError,
    FragileNeutralWarning,
    InputError,
    NotConvergedError,
    QuasiPolynomialError,
)
from delayform.quasipolynomial import QuasiPolynomial

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["NeutralSpectrum", "neutral_spectrum", "neutral_roots_in", "neutral_rightmost_root", "neutral_count_right_of"]

_NEWTON = 60
_RESIDUAL = 1e-10
#: Margins right of C_D tried by the rightmost root, relative to max(1, |C_D|); each search
#: after the first covers only the strip left of the previous line.
_MARGINS = (0.1, 0.03, 0.01, 1e-3)
#: Largest half-height times longest delay of the rectangle searched for the rightmost root.
_MAX_REACH = 5e3
#: Most boxes one search may open (a guard against a region holding very many roots).
_MAX_BOXES = 20_000


def _terms_at(qp: QuasiPolynomial, taus: tuple[float, ...]) -> Terms:
    """q at fixed delays as terms ``(p_k, h_k, 0)`` evaluated with ``tau1 = 1, tau2 = 0``."""
    h = qp.delays_of_terms(*taus)
    return tuple((c, h[k], 0) for k, c in qp.terms.items())  # type: ignore[misc]


def _q(terms: Terms, s: complex) -> tuple[complex, complex, float]:
    q, dq, mag = evaluate(terms, np.asarray(s, complex), np.asarray(1.0), np.asarray(0.0))
    return complex(q), complex(dq), float(mag)


def _newton(terms: Terms, s: complex) -> tuple[complex, bool]:
    for _ in range(_NEWTON):
        q, dq, _ = _q(terms, s)
        if dq == 0 or not np.isfinite(q):
            break
        step = q / dq
        s = s - step
        if abs(step) <= 4e-16 * (1.0 + abs(s)):
            break
    q, _, mag = _q(terms, s)
    return s, bool(np.isfinite(q) and abs(q) <= _RESIDUAL * mag)


def _derivative_terms(qp: QuasiPolynomial, taus: tuple[float, ...], order: int) -> Terms:
    """The terms of q^(order) (Leibniz on each p_k e^{-h_k s}), for polishing a multiple root."""
    h = qp.delays_of_terms(*taus)
    terms = []
    for k, c in qp.terms.items():
        acc = np.zeros(c.size, complex)
        for j in range(order + 1):
            d = npoly.polyder(c, j) if j else c
            w = math.comb(order, j) * (-h[k]) ** (order - j)
            acc[: d.size] += w * d
        terms.append((np.trim_zeros(acc, "b") if np.any(acc) else np.zeros(1, complex), h[k], 0))
    return tuple(terms)


def _vanishes(qp: QuasiPolynomial, taus: tuple[float, ...], s: complex, n: int) -> bool:
    """q^(j)(s) ~ 0 for j < n - 1, each relative to its terms' moduli, to 1e3 eps^((n-j)/n)."""
    for j in range(n - 1):
        q, _, mag = _q(_derivative_terms(qp, taus, j), s)
        if not abs(q) <= 1e3 * np.finfo(float).eps ** ((n - j) / n) * mag:
            return False
    return True


def _count(terms: Terms, box: tuple[float, float, float, float]) -> int | None:
    return count_in_region(terms, 1.0, 0.0, box)


def _solve_box(
    qp: QuasiPolynomial, taus: tuple[float, ...], terms: Terms, box: tuple[float, float, float, float],
    n: int, out: list[tuple[complex, int]], budget: list[int],
) -> None:
    x0, x1, y0, y1 = box
    if n == 0:
        return
    budget[0] -= 1
    if budget[0] < 0:
        raise NotConvergedError("the region holds too many roots to separate; give a smaller region")
    centre = complex(0.5 * (x0 + x1), 0.5 * (y0 + y1))
    size = max(x1 - x0, y1 - y0)
    if n == 1:
        s, ok = _newton(terms, centre)
        if ok and x0 <= s.real <= x1 and y0 <= s.imag <= y1:
            out.append((s, 1))
            return
    if n > 1:
        # try the n roots as one of multiplicity n first (the certified sampling is slow
        # next to a multiple root): a zero of q^(n-1) in the box where q, ..., q^(n-2) vanish
        # to the accuracy double precision allows (about eps^((n-j)/n) for q^(j))
        s, ok = _newton(_derivative_terms(qp, taus, n - 1), centre)
        if ok and x0 <= s.real <= x1 and y0 <= s.imag <= y1 and _vanishes(qp, taus, s, n):
            out.append((s, n))
            return
    if size <= 1e-7 * max(1.0, abs(centre)):
        # a cluster that does not separate: one root of multiplicity n, the root of q^(n-1)
        s, _ = _newton(_derivative_terms(qp, taus, n - 1), centre)
        out.append((s if abs(s - centre) <= size else centre, n))
        return
    # split the longer side near its middle; move the cut when it passes through a root
    for frac in (0.5, 0.5 + 1 / 17, 0.5 - 1 / 13, 0.5 + 1 / 7):
        if x1 - x0 >= y1 - y0:
            cut = x0 + frac * (x1 - x0)
            halves = [(x0, cut, y0, y1), (cut, x1, y0, y1)]
        else:
            cut = y0 + frac * (y1 - y0)
            halves = [(x0, x1, y0, cut), (x0, x1, cut, y1)]
        counts = [_count(terms, b) for b in halves]
        if all(c is not None for c in counts) and sum(counts) == n:  # type: ignore[arg-type]
            for b, c in zip(halves, counts, strict=True):
                _solve_box(qp, taus, terms, b, int(c), out, budget)  # type: ignore[arg-type]
            return
    if n > 1:
        # no cut separates them: a multiple root (its neighbourhood is too flat for the
        # certified sampling); its multiplicity is the box's certified count
        s, _ = _newton(_derivative_terms(qp, taus, n - 1), centre)
        if x0 <= s.real <= x1 and y0 <= s.imag <= y1:
            out.append((s, n))
            return
    raise NotConvergedError(f"cannot separate the roots in [{x0:g}, {x1:g}] x [{y0:g}, {y1:g}]")


def _roots_in(qp: QuasiPolynomial, taus: tuple[float, ...], region: tuple[float, float, float, float]) -> list[tuple[complex, int]]:
    terms = _terms_at(qp, taus)
    n = _count(terms, region)
    if n is None:
        raise NotConvergedError(f"a root lies on (or within rounding of) the boundary of the region {region}")
    out: list[tuple[complex, int]] = []
    _solve_box(qp, taus, terms, region, n, out, [_MAX_BOXES])
    return sorted(out, key=lambda r: (-r[0].real, -r[0].imag))


@validated(QuasiPolynomialError)
def neutral_roots_in(
    qp: QuasiPolynomial | TwoDelayQuasiPolynomial, *taus: float, region: tuple[float, float, float, float]
) -> tuple[NDArray[np.complex128], NDArray[np.int64]]:
    """Every root of q in a bounded rectangle, with multiplicity (any type: retarded or neutral).

    Parameters
    ----------
    qp
        The quasi-polynomial.
    *taus
        Its delays.
    region
        ``(re_min, re_max, im_min, im_max)``, bounded.

    Returns
    -------
    roots, multiplicity
        Distinct roots (largest real part first) and their multiplicities;
        ``multiplicity.sum()`` is the certified count in the region.

    Raises
    ------
    InputError
        For an unbounded or empty region.
    NotConvergedError
        When a root lies on the region's boundary.
    """
    g = as_general(qp)
    region = _check_region(region)
    found = _roots_in(g, tuple(float(t) for t in taus), region)
    return np.array([r for r, _ in found], complex), np.array([m for _, m in found], np.int64)


def _check_region(region: object) -> tuple[float, float, float, float]:
    try:
        x0, x1, y0, y1 = (float(v) for v in region)  # type: ignore[union-attr]
    except (TypeError, ValueError) as exc:
        raise InputError("region must be (re_min, re_max, im_min, im_max)") from exc
    if not all(np.isfinite([x0, x1, y0, y1])) or x0 >= x1 or y0 >= y1:
        raise InputError(f"region must be bounded and non-empty, got {(x0, x1, y0, y1)}")
    return x0, x1, y0, y1


def _abscissa_for_search(D: DifferenceOperator, taus: tuple[float, ...]) -> float:
    """The nominal essential abscissa, or its Hale bound where it is not computed."""
    c = nominal_abscissa(D, taus)
    return D.hale_bound(*taus) if np.isnan(c) else c


def _search_box(qp: QuasiPolynomial, D: DifferenceOperator, taus: tuple[float, ...], sigma0: float) -> tuple[float, float, float, float] | None:
    """A rectangle holding every root with Re s >= sigma0 (module docstring), None without a bound of |D|."""
    delta0, _ = nominal_min_modulus(D, taus, sigma0)
    if delta0 <= 0.0:
        return None
    n = qp.degree
    h = qp.delays_of_terms(*taus)
    B = np.zeros(n)
    for k, c in qp.terms.items():
        B[: min(n, c.size)] += np.abs(c[:n]) * np.exp(-sigma0 * h[k])
    omega = max(1.0, float(B.sum()) / (abs(qp.principal[n]) * delta0)) * (1.0 + 1e-9)
    # the count's samples grow like omega times the longest delay: beyond this it is not tried
    if omega * max(1.0, max(h.values())) > _MAX_REACH:
        return None
    # roots right of sigma0 have |s| <= omega; nudge the edges off round numbers
    return (sigma0, omega * 1.0001 + 1.0, -omega * 1.0001 - 0.9871, omega * 1.0001 + 1.0123)


def _search_lines(cN: float) -> list[float]:
    """Left edges tried for the rightmost root: just right of the nominal abscissa, ever closer.

    When D's terms cancel at these delays (``C_nom = -inf``: retarded there) a
    descending sequence of lines instead, until one's rectangle holds a root.
    """
    if np.isfinite(cN):
        return [cN + margin * max(1.0, abs(cN)) for margin in _MARGINS]
    return [1.0, 0.0, -1.0, -2.0, -4.0, -8.0, -16.0]


def _rightmost(g: QuasiPolynomial, taus: tuple[float, ...]) -> complex:
    """:func:`neutral_rightmost_root` without its warning (the report carries the flag instead)."""
    D = difference_operator(g)
    cN = _abscissa_for_search(D, taus)
    searched = None
    for sigma0 in _search_lines(cN):
        box = _search_box(g, D, taus, sigma0)
        if box is None:
            continue
        if searched is not None:
            # right of the last line searched there is no root: only the strip between is new
            box = (box[0], searched, box[2], box[3])
        try:
            found = _roots_in(g, taus, box)
        except NotConvergedError:
            continue
        if found:
            best = max(found, key=lambda r: (r[0].real, r[0].imag))[0]
            if g.is_real:  # of a conjugate pair the upper one; a real root exactly real
                im = abs(best.imag)
                return complex(best.real, 0.0 if im <= 1e-12 * max(1.0, abs(best)) else im)
            return best
        searched = sigma0
    cD = D.essential_abscissa(*taus)
    if searched is None:
        raise NotConvergedError(
            f"cannot bound the roots right of the essential abscissa {cN:.12g} at these delays: |D| is not "
            "certified away from 0 there, or the region it gives is too large to search"
        )
    if not np.isfinite(cN):
        raise NotConvergedError(
            f"the neutral terms cancel at these delays (the quasi-polynomial is retarded there) and no root "
            f"lies right of Re s = {searched:g}; the rightmost root lies further left than searched"
        )
    raise EssentialSpectrumError(
        f"no root lies right of Re s = {searched:.12g}, just right of the essential spectrum at these delays, "
        f"whose abscissa is {cN:.12g}: the supremum of the real parts of the roots is that abscissa (or a root "
        f"between the two); under arbitrarily small changes of the delays the essential abscissa becomes "
        f"C_D = {cD:.12g} (robust)",
        abscissa=cN, line=searched, robust_abscissa=cD,
    )


def _fragility(D: DifferenceOperator, taus: tuple[float, ...]) -> str:
    """Why the answer at these delays is fragile, or '' when D is not certified to be (C_D >= 0)."""
    if D.strongly_stable(*taus) is not False:
        return ""
    return (f"not strongly stable: the robust essential abscissa C_D = {D.essential_abscissa(*taus):.6g} >= 0, "
            "so an arbitrarily small change of the delays destabilizes the system")


@validated(QuasiPolynomialError)
def neutral_rightmost_root(qp: QuasiPolynomial | TwoDelayQuasiPolynomial, *taus: float) -> complex:
    """The rightmost root of a neutral quasi-polynomial at its delays as given, right of its essential spectrum.

    The essential spectrum is the one at exactly these delays (nominal: for
    commensurate delays the difference equation's own, module docstring), so
    a system stable only at the delays given gets its answer; see
    :func:`neutral_spectrum` for the robust abscissa beside it.

    Parameters
    ----------
    qp
        A QuasiPolynomial (any number of delays) or TwoDelayQuasiPolynomial.
    *taus
        Its delays (s), non-negative; those in the difference operator positive.

    Warns
    -----
    FragileNeutralWarning
        When the difference operator is not strongly stable (``C_D >= 0``):
        the root is right for the delays given, but an arbitrarily small
        change of the delays destabilizes the system.

    Raises
    ------
    EssentialSpectrumError
        When no root lies right of the nominal essential abscissa + margin
        (margins down to 1e-3 of the scale): the supremum of the real parts
        is then that abscissa (or a root within the margin of it), which the
        error gives, with the robust C_D.
    """
    g = as_general(qp)
    taus = tuple(float(x) for x in taus)
    root = _rightmost(g, taus)
    why = _fragility(difference_operator(g), taus)
    if why:
        warnings.warn(FragileNeutralWarning(f"rightmost root {root:.6g} at the delays given, but {why}"),
                      stacklevel=_user_level())
    return root


def _user_level() -> int:
    """The stacklevel of the first caller outside delayform (the warning points at the user's line)."""
    package = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    frame, level = sys._getframe(1), 2  # 1: the caller of warnings.warn, here neutral_rightmost_root
    while frame.f_back is not None and os.path.abspath(frame.f_code.co_filename).startswith(package):
        frame, level = frame.f_back, level + 1
    return level - 1


@validated(QuasiPolynomialError)
def neutral_count_right_of(qp: QuasiPolynomial | TwoDelayQuasiPolynomial, *taus: float, c: float) -> int:
    """Certified number of roots with Re s > c, for c right of the essential spectrum (multiplicity counted).

    Parameters
    ----------
    qp
        A QuasiPolynomial (any number of delays) or TwoDelayQuasiPolynomial.
    *taus
        Its delays (s), non-negative; those in the difference operator positive.
    c
        Abscissa of the line Re s = c.

    Raises
    ------
    EssentialSpectrumError
        When c is not right of the essential abscissa at these delays (by
        more than its rounding, 1e-9 of the scale): right
        of such a line lie infinitely many roots (a chain of the essential
        spectrum), or arbitrarily close to it.
    NotConvergedError
        When the roots right of c cannot be bounded (|D| not certified away
        from 0 there) or a root lies on the line.
    """
    g = as_general(qp)
    taus = tuple(float(x) for x in taus)
    D = difference_operator(g)
    cN = _abscissa_for_search(D, taus)
    # the abscissa is a root modulus's logarithm: a line within its rounding is not right of it
    if not float(c) > cN + abscissa_rounding(D, taus):
        raise EssentialSpectrumError(
            f"Re s > {float(c):g} holds infinitely many roots or roots arbitrarily close to the essential "
            f"spectrum: its abscissa at these delays, {cN:.12g}, is not left of the line", abscissa=cN,
            robust_abscissa=D.essential_abscissa(*taus),
        )
    box = _search_box(g, D, taus, float(c))
    if box is None:
        raise NotConvergedError(f"cannot bound the roots right of Re s = {float(c):g} (essential abscissa {cN:.12g})")
    n = _count(_terms_at(g, taus), box)
    if n is None:
        raise NotConvergedError(f"a root lies on (or within rounding of) the line Re s = {float(c):g}")
    return n


@validated(QuasiPolynomialError)
@dataclass(frozen=True)
class NeutralSpectrum:
    """What is known of a quasi-polynomial's spectrum through its difference operator.

    Two questions, both answered: the system *as stated* (its delays exactly
    as given, ``nominal_*``, ``rightmost``, ``nominally_stable``) and the system
    under arbitrarily small changes of its delays (``essential_abscissa`` C_D,
    ``strongly_stable``, ``stable``, ``fragile``).

    Attributes
    ----------
    is_neutral
        True when a delayed term has the principal term's degree.
    difference
        The difference operator D (trivial for a retarded qp).
    essential_abscissa
        C_D(tau), robust to delay changes (``-inf`` when retarded; NaN when not computed).
    hale_bound
        Upper bound of C_D: the r with ``sum |c_k| e^{-r k.tau} = 1``.
    strongly_stable
        True / False when certified, None when it cannot be decided.
    rightmost
        The rightmost root at the delays given when it lies right of the
        essential spectrum at these delays, else None.
    stable
        Robust stability: True only when the difference operator is certified
        strongly stable and the rightmost root (found) has Re s < 0; False when
        either is certified to fail; None otherwise. Never True when C_D >= 0.
    delays
        The delays the spectrum is of.
    nominal_abscissa
        The essential abscissa at exactly these delays (for commensurate delays
        from the difference equation's polynomial in ``w = e^{-h s}``; equal to
        C_D for rationally independent ones; ``-inf`` when retarded).
    base_delay
        h when the delays in D are commensurate (``tau_i = n_i h``), else None.
    nominally_stable
        Exponential stability at the delays given: True when the essential
        abscissa at these delays is certified < 0 and the rightmost root (or
        the line right of which none lies) is left of the axis; False when
        either is certified to fail; None otherwise. An essential spectrum
        that reaches Re s = 0 at these delays is never called stable.
    fragile
        True when the difference operator is certified not strongly stable
        (``C_D >= 0``): an arbitrarily small change of the delays destabilizes
        the system, whatever ``nominally_stable`` says.
    """

    is_neutral: bool
    difference: DifferenceOperator
    essential_abscissa: float
    hale_bound: float
    strongly_stable: bool | None
    rightmost: complex | None
    stable: bool | None
    delays: tuple[float, ...] = ()
    nominal_abscissa: float = float("nan")
    base_delay: float | None = None
    nominally_stable: bool | None = None
    fragile: bool = False

    def describe(self) -> str:
        """Both answers in a few lines: the system at its delays as given, and under small delay changes."""
        at = ", ".join(f"{t:g}" for t in self.delays)
        names = ", ".join(f"tau{i + 1}" for i in range(len(self.delays)))
        lines = [f"{'neutral' if self.is_neutral else 'retarded'} quasi-polynomial at ({names}) = ({at})"]
        root = "none right of the essential spectrum" if self.rightmost is None else _fmt(self.rightmost)
        if self.is_neutral:
            if self.base_delay is None:
                kind = "delays taken as rationally independent"
            elif self.nominal_abscissa == -np.inf:
                kind = "the neutral terms cancel at these delays: retarded there"
            else:
                kind = f"commensurate delays, base h = {self.base_delay:g}"
            lines += [
                f"  essential abscissa at these delays: {self.nominal_abscissa:.6g} ({kind})",
                f"  rightmost root at these delays: {root}",
                f"  robust (strong) essential abscissa C_D = {self.essential_abscissa:.6g} "
                "(reached under arbitrarily small changes of the delays)",
            ]
        else:
            lines.append(f"  rightmost root: {root}")
        lines.append(f"  verdict: {self._verdict()}")
        return "\n".join(lines)

    def _verdict(self) -> str:
        if self.nominally_stable is True:
            if self.strongly_stable is True:
                return "exponentially stable, and strongly stable (robust to small changes of the delays)"
            if self.fragile:
                return ("FRAGILE: exponentially stable at the delays given, but not strongly stable "
                        f"(C_D = {self.essential_abscissa:.6g} >= 0): an arbitrarily small change of the "
                        "delays destabilizes it")
            return "exponentially stable at the delays given; strong stability could not be decided"
        if self.nominally_stable is False:
            tail = " (and not strongly stable)" if self.fragile else ""
            if self.rightmost is not None and self.rightmost.real >= 0.0:
                return f"unstable at the delays given: a root has Re s >= 0{tail}"
            return f"not stable at the delays given: the essential spectrum reaches Re s = 0 or beyond{tail}"
        tail = "; not strongly stable either (fragile)" if self.fragile else ""
        return f"stability at the delays given could not be decided{tail}"

    def plot(self, ax: Axes | None = None) -> Axes:
        """The rightmost root, the essential abscissa at these delays and the robust C_D in the complex plane."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots()
        if np.isfinite(self.essential_abscissa):
            ax.axvline(self.essential_abscissa, color="tab:red", ls="--", label="robust essential abscissa $C_D$")
        if np.isfinite(self.nominal_abscissa) and self.nominal_abscissa != self.essential_abscissa:
            ax.axvline(self.nominal_abscissa, color="tab:purple", ls=":", label="essential abscissa at these delays")
        if self.rightmost is not None:
            ax.plot([self.rightmost.real], [self.rightmost.imag], "o", label="rightmost root")
        ax.axvline(0.0, color="0.5", lw=0.8)
        ax.set_xlabel("Re s")
        ax.set_ylabel("Im s")
        ax.legend(loc="best")
        return ax


def _fmt(s: complex) -> str:
    return f"{s.real:.6g} {'+' if s.imag >= 0 else '-'} {abs(s.imag):.6g}j"


def _verdict_of(essential: bool | None, right: complex | None, line: float | None) -> bool | None:
    """Stable when the essential part is certified and the rightmost root (or the line searched) is left of 0."""
    if essential is False or (right is not None and right.real >= 0.0):
        return False
    if essential is True:
        # the rightmost root when found; otherwise every root lies left of the line searched
        bound = right.real if right is not None else line
        return True if (bound is not None and bound < 0.0) else None
    return None


@validated(QuasiPolynomialError)
def neutral_spectrum(qp: QuasiPolynomial | TwoDelayQuasiPolynomial, *taus: float) -> NeutralSpectrum:
    """The spectrum at the delays given beside the robust essential abscissa and strong stability.

    Parameters
    ----------
    qp
        The quasi-polynomial, of any type (a retarded one reports D = 1).
    *taus
        The delay values, one per delay of qp.

    Examples
    --------
    (s + 1)(1 + 0.5 e^{-s}): root -1 and the chain Re s = -ln 2 ~ -0.693 (its essential spectrum).

    >>> from delayform.quasipolynomial import QuasiPolynomial
    >>> r = neutral_spectrum(QuasiPolynomial({(0,): [1, 1], (1,): [0.5, 0.5]}), 1.0)
    >>> r.is_neutral, round(r.essential_abscissa, 9), r.strongly_stable, r.rightmost, r.stable
    (True, -0.693147181, True, None, True)
    """
    g = as_general(qp)
    taus = tuple(float(x) for x in taus)
    D = difference_operator(g)
    strong = D.strongly_stable(*taus)
    cD = D.essential_abscissa(*taus)
    line: float | None = None  # no root right of it (certified), when no rightmost root is found
    try:
        right: complex | None = _rightmost(g, taus)
    except EssentialSpectrumError as err:
        right, line = None, err.line
    except NotConvergedError:
        right = None
    com = commensurate(D, taus)
    return NeutralSpectrum(
        g.is_neutral, D, cD, D.hale_bound(*taus), strong, right, _verdict_of(strong, right, line),
        delays=taus, nominal_abscissa=nominal_abscissa(D, taus), base_delay=None if com is None else com.base,
        nominally_stable=_verdict_of(nominally_essentially_stable(D, taus), right, line), fragile=strong is False,
    )
