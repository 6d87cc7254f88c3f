"""Quasi-polynomials with any number of delays, and the characteristic function of a matrix DDE.

A quasi-polynomial in m delays is

    q(s) = sum_k p_k(s) e^{-(k1 tau1 + ... + km taum) s},

one polynomial ``p_k`` per tuple ``k = (k1, ..., km)`` of non-negative
integers; ``k = (0, ..., 0)`` is the *principal* term. The paper's two-delay
factor (paper, eq. 5, :class:`~delayform.characteristic.TwoDelayQuasiPolynomial`)
is the case m = 2 with the six tuples of
:data:`~delayform.characteristic.DELAY_MULTIPLES`; commensurate delays (k1 = 3),
products like z1 z2^2 and three or more delays are written the same way.

Type (Hale and Verduyn Lunel, *Introduction to Functional Differential
Equations*, 1993, ch. 12; Michiels and Niculescu, *Stability, Control, and
Computation for Time-Delay Systems*, 2nd ed., 2014, sec. 1.1): q is
*retarded* when every delayed term has lower degree than the principal one,
*neutral* when some delayed term has the same degree, and *advanced* when one
has a higher degree; advanced quasi-polynomials have roots of arbitrarily
large real part and are refused here.

:meth:`QuasiPolynomial.from_matrices` expands the characteristic function of
``x'(t) = A0 x(t) + sum_k A_k x(t - tau_k) + sum_k B_k x'(t - tau_k)``,

    det( s (I - sum_k B_k z_k) - A0 - sum_k A_k z_k ),   z_k = e^{-tau_k s},

into its terms exactly up to rounding: the determinant is a polynomial of
degree at most n in s and in each z_k, so its values on a product grid of
(n + 1)-th roots of unity (scaled circles) determine it, and a
multidimensional FFT returns its coefficients (the discrete Fourier
transform is the exact inverse of evaluation at roots of unity).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_complex_array, check_delay_array, check_numbers, validated
from delayform.characteristic import (
    DELAY_MULTIPLES,
    CharacteristicFactor,
    TwoDelayQuasiPolynomial,
    format_number,
)
from delayform.errors import NeutralQuasiPolynomialError, QuasiPolynomialError

__all__ = ["QuasiPolynomial"]

Exponents = tuple[int, ...]

#: coefficients of an expanded determinant below this fraction of the largest
#: scaled one are rounding noise of the FFT (exactly zero in exact arithmetic)
_EXPANSION_NOISE = 1e-12
#: largest number of determinants evaluated at once by from_matrices (memory)
_DET_BATCH = 65536


def _exponents(key: object) -> Exponents:
    if not isinstance(key, tuple) or not key:
        raise QuasiPolynomialError(
            f"each term's key must be a non-empty tuple of delay multiples (k1, ..., km), got {key!r}"
        )
    out = []
    for k in key:
        if isinstance(k, bool) or not isinstance(k, (numbers.Integral, np.integer)) or int(k) < 0:
            raise QuasiPolynomialError(
                f"delay multiples must be non-negative integers, got {k!r} in the key {key!r}"
            )
        out.append(int(k))
    return tuple(out)


def _coefficients(key: Exponents, value: object) -> NDArray[np.complex128]:
    # numbers only: numpy would parse the strings "1", "2" (or read True as 1) without a word
    arr = np.atleast_1d(check_numbers(f"the coefficients of the term {key}", value, QuasiPolynomialError))
    if arr.ndim != 1:
        raise QuasiPolynomialError(
            f"the coefficients of the term {key} must be a 1-D sequence (ascending powers of s), "
            f"got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise QuasiPolynomialError(f"the coefficients of the term {key} are not all finite numbers")
    nonzero = np.flatnonzero(arr)
    out = arr[: nonzero[-1] + 1] if nonzero.size else np.zeros(0, dtype=np.complex128)
    out.setflags(write=False)
    return out


def _horner(c: NDArray[np.complex128], s: NDArray[np.complex128]) -> NDArray[np.complex128]:
    out = np.zeros(np.shape(s), dtype=np.complex128) + c[-1]
    for coef in c[-2::-1]:
        out = out * s + coef
    return out


@validated(QuasiPolynomialError)
@dataclass(frozen=True, eq=False, init=False)
class QuasiPolynomial:
    """A quasi-polynomial in any number of delays (module docstring).

    Parameters
    ----------
    terms
        Maps each tuple ``(k1, ..., km)`` of non-negative integers (all of
        the same length m >= 1) to the coefficients, in ascending powers of
        s, of the polynomial multiplying ``e^{-(k1 tau1 + ... + km taum) s}``.
        The principal term ``(0, ..., 0)`` must be present and non-zero;
        zero polynomials are dropped.

    Raises
    ------
    QuasiPolynomialError
        For a malformed key or coefficient sequence, a missing principal
        term, or a delayed term of higher degree than the principal one
        (advanced type).

    Examples
    --------
    s + 1 + e^{-tau1 s} + 0.5 e^{-(tau1 + 2 tau2) s}:

    >>> q = QuasiPolynomial({(0, 0): [1, 1], (1, 0): [1], (1, 2): [0.5]})
    >>> q.n_delays, q.degree, q.is_neutral
    (2, 1, False)
    >>> complex(q.evaluate(0.0, 1.0, 2.0))
    (2.5+0j)
    """

    terms: Mapping[Exponents, NDArray[np.complex128]]

    def __init__(self, terms: Mapping[Exponents, ArrayLike]) -> None:
        if not isinstance(terms, Mapping) or not terms:
            raise QuasiPolynomialError(
                "terms must be a non-empty mapping {(k1, ..., km): coefficients in ascending powers of s}"
            )
        parsed: dict[Exponents, NDArray[np.complex128]] = {}
        for key, value in terms.items():
            k = _exponents(key)
            if parsed and len(k) != len(next(iter(parsed))):
                raise QuasiPolynomialError(
                    f"every key must have the same number of delays: {next(iter(parsed))} and {k} differ"
                )
            c = _coefficients(k, value)
            if c.size:
                parsed[k] = c
        m = len(_exponents(next(iter(terms))))
        principal = (0,) * m
        if principal not in parsed:
            raise QuasiPolynomialError(
                f"the principal term {principal} (the polynomial without delay) must be present and non-zero"
            )
        degree = parsed[principal].size - 1
        for k, c in parsed.items():
            if c.size - 1 > degree:
                raise QuasiPolynomialError(
                    f"the term {k} has degree {c.size - 1} > {degree}, the principal term's: "
                    "a quasi-polynomial of advanced type has roots of unbounded real part"
                )
        # principal first, then by total delay multiple: a stable, readable order
        ordered = dict(sorted(parsed.items(), key=lambda kv: (sum(kv[0]), tuple(-x for x in kv[0]))))
        object.__setattr__(self, "terms", MappingProxyType(ordered))

    # ------------------------------------------------------------ structure
    @property
    def n_delays(self) -> int:
        """m, the number of independent delays the root functions take after q."""
        return len(next(iter(self.terms)))

    @property
    def principal(self) -> NDArray[np.complex128]:
        """Coefficients of the principal (undelayed) polynomial."""
        return self.terms[(0,) * self.n_delays]

    @property
    def degree(self) -> int:
        """Degree of the principal polynomial in s."""
        return int(self.principal.size - 1)

    @property
    def is_real(self) -> bool:
        """True when every coefficient is real: roots then come in conjugate pairs."""
        return all(bool(np.all(c.imag == 0.0)) for c in self.terms.values())

    @property
    def is_neutral(self) -> bool:
        """True when a delayed term has the principal term's degree (neutral type)."""
        principal = (0,) * self.n_delays
        return any(c.size - 1 == self.degree for k, c in self.terms.items() if k != principal)

    @property
    def is_retarded(self) -> bool:
        """True when every delayed term has lower degree than the principal one."""
        return not self.is_neutral

    def require_retarded(self) -> None:
        """Raise :class:`NeutralQuasiPolynomialError` unless :attr:`is_retarded`."""
        if self.is_neutral:
            same = [k for k, c in self.terms.items() if any(k) and c.size - 1 == self.degree]
            raise NeutralQuasiPolynomialError(
                f"the quasi-polynomial is of neutral type: the delayed term(s) {same} have the principal "
                f"term's degree {self.degree}; only retarded ones are supported here"
            )

    def delays_of_terms(self, *taus: float) -> dict[Exponents, float]:
        """The delay k1 tau1 + ... + km taum of each term at the given delays."""
        t = self._check_taus(taus)
        return {k: float(np.dot(k, [float(x) for x in t])) for k in self.terms}

    def delay_free(self) -> NDArray[np.complex128]:
        """Coefficients of q with every delay zero (the sum of all term polynomials)."""
        out = np.zeros(self.degree + 1, dtype=np.complex128)
        for c in self.terms.values():
            out[: c.size] += c
        return out

    def _check_taus(self, taus: tuple[ArrayLike, ...]) -> list[NDArray[np.float64]]:
        if len(taus) != self.n_delays:
            raise QuasiPolynomialError(
                f"this quasi-polynomial has {self.n_delays} delay(s); got {len(taus)} delay value(s)"
            )
        return [check_delay_array(f"tau{i + 1}", t) for i, t in enumerate(taus)]

    # ------------------------------------------------------------ evaluation
    def _prepared(
        self, s: ArrayLike, taus: tuple[ArrayLike, ...]
    ) -> tuple[NDArray[np.complex128], NDArray[np.complex128], list[NDArray[np.float64]]]:
        """s checked, a zero array of the broadcast shape, and each term's delay k . tau."""
        s_arr = check_complex_array("s", s)
        t = self._check_taus(taus)
        out = np.zeros(np.broadcast_shapes(s_arr.shape, *(x.shape for x in t)), dtype=np.complex128)
        delays = [sum((kk * tt for kk, tt in zip(k, t, strict=True) if kk), start=np.zeros(())) for k in self.terms]
        return s_arr, out, delays

    def evaluate(self, s: ArrayLike, *taus: ArrayLike) -> NDArray[np.complex128]:
        """q(s) at the delays ``tau1, ..., taum``; s and the delays broadcast together."""
        return self.derivative(s, *taus, order=0)

    def derivative(self, s: ArrayLike, *taus: ArrayLike, order: int = 1) -> NDArray[np.complex128]:
        """The ``order``-th derivative of q in s (order 0 is q itself), vectorized.

        Leibniz's rule on each term ``p(s) e^{-h s}``:
        ``sum_j C(order, j) p^(j)(s) (-h)^(order - j) e^{-h s}``.
        """
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 0:
            raise QuasiPolynomialError(f"order must be a non-negative integer, got {order!r}")
        s_arr, out, delays = self._prepared(s, taus)
        for (k, c), h in zip(self.terms.items(), delays, strict=True):
            e = np.exp(-h * s_arr) if np.any(h) else np.ones(())
            for j in range(min(order, c.size - 1) + 1):
                w = math.comb(order, j) * (-h) ** (order - j)
                if np.all(w == 0.0):
                    continue
                out = out + w * _horner(npoly.polyder(c, j) if j else c, s_arr) * e
        return out

    def delay_derivative(self, s: ArrayLike, *taus: ArrayLike, delay: int) -> NDArray[np.complex128]:
        """dq/dtau_k at fixed s for ``delay`` k in 1..m: ``-s sum k_k p(s) e^{-h s}``."""
        if isinstance(delay, bool) or not isinstance(delay, (int, np.integer)) or not 1 <= delay <= self.n_delays:
            raise QuasiPolynomialError(f"delay must be an integer from 1 to {self.n_delays}, got {delay!r}")
        s_arr, out, delays = self._prepared(s, taus)
        for (k, c), h in zip(self.terms.items(), delays, strict=True):
            if k[delay - 1]:
                out = out - k[delay - 1] * s_arr * _horner(c, s_arr) * np.exp(-h * s_arr)
        return out

    def describe(self) -> str:
        """The quasi-polynomial written out, one term per key."""
        scale = max(float(np.abs(c).max()) for c in self.terms.values())
        parts = []
        for k, c in self.terms.items():
            shown = [(p, v) for p, v in enumerate(c) if format_number(v, scale=scale) != "0"]
            if not shown:
                continue
            poly = " + ".join(
                (f"({t})" if " " in (t := format_number(v, scale=scale)) else t)
                + ("" if p == 0 else (" s" if p == 1 else f" s^{p}"))
                for p, v in shown
            )
            h = " + ".join(f"{str(kk) + ' ' if kk > 1 else ''}tau{i + 1}" for i, kk in enumerate(k) if kk)
            parts.append(f"({poly})" + (f" e^{{-({h}) s}}" if h else ""))
        return " + ".join(parts) or "0"

    # ------------------------------------------------------------ conversions
    @classmethod
    def from_two_delay(cls, qp: TwoDelayQuasiPolynomial | CharacteristicFactor) -> QuasiPolynomial:
        """The paper's two-delay form (paper, eq. 5) or a factor of the paper's eq. 3, as a QuasiPolynomial."""
        if isinstance(qp, CharacteristicFactor):
            qp = qp.quasi_polynomial
        if not isinstance(qp, TwoDelayQuasiPolynomial):
            raise QuasiPolynomialError(
                f"expected a TwoDelayQuasiPolynomial or CharacteristicFactor, got {type(qp).__name__}"
            )
        return cls({(a, b): c for c, a, b in qp.terms()})

    def to_two_delay(self) -> TwoDelayQuasiPolynomial:
        """The same quasi-polynomial as a :class:`TwoDelayQuasiPolynomial`, when its terms fit the paper's eq. 5."""
        extra = [k for k in self.terms if self.n_delays != 2 or k not in DELAY_MULTIPLES]
        if extra:
            raise QuasiPolynomialError(
                f"the terms {extra} are not among the six of the paper's eq. 5 {list(DELAY_MULTIPLES)}"
            )
        g = [self.terms.get(k, np.zeros(0, dtype=np.complex128)) for k in DELAY_MULTIPLES]
        return TwoDelayQuasiPolynomial(*g)

    @classmethod
    def from_matrices(
        cls, A0: ArrayLike, *A: ArrayLike, neutral: tuple[ArrayLike, ...] = ()
    ) -> QuasiPolynomial:
        """Characteristic quasi-polynomial of ``x' = A0 x + sum_k A_k x(t - tau_k) + sum_k B_k x'(t - tau_k)``.

        Parameters
        ----------
        A0
            The n x n matrix of the undelayed state.
        *A
            A_1, ..., A_m, one n x n matrix per delay (zero matrices allowed).
        neutral
            B_1, ..., B_m of the neutral terms (empty: a retarded DDE). Its
            length must be m.

        Returns
        -------
        QuasiPolynomial
            ``det(s (I - sum_k B_k z_k) - A0 - sum_k A_k z_k)`` with
            ``z_k = e^{-tau_k s}``, expanded by FFT on scaled roots of unity
            (module docstring). Coefficients that are rounding noise
            (below 1e-12 of the largest on the scaled grid) are dropped;
            for integer matrices the coefficients are rounded to the exact
            integers.

        Examples
        --------
        x' = -x(t - tau1) has q(s) = s + e^{-tau1 s}:

        >>> q = QuasiPolynomial.from_matrices([[0.0]], [[-1.0]])
        >>> {k: c.real.tolist() for k, c in q.terms.items()}
        {(0,): [0.0, 1.0], (1,): [1.0]}
        """
        mats = [_matrix("A0", A0)] + [_matrix(f"A{k + 1}", a) for k, a in enumerate(A)]
        m = len(A)
        if m == 0:
            raise QuasiPolynomialError("give at least one delayed matrix A1 (a DDE without delay has no delays)")
        if not isinstance(neutral, (tuple, list)):
            raise QuasiPolynomialError("neutral must be a tuple of matrices B1, ..., Bm")
        if neutral and len(neutral) != m:
            raise QuasiPolynomialError(f"neutral must hold {m} matrices B1..B{m} (one per delay), got {len(neutral)}")
        B = [_matrix(f"B{k + 1}", b) for k, b in enumerate(neutral)] or [np.zeros_like(mats[0])] * m
        n = mats[0].shape[0]
        for name, M in [(f"A{k}", M) for k, M in enumerate(mats)] + [(f"B{k + 1}", M) for k, M in enumerate(B)]:
            if M.shape != (n, n):
                raise QuasiPolynomialError(f"{name} has shape {M.shape}; every matrix must be {n} x {n} like A0")
        coeffs = _expand_determinant(mats[0], mats[1:], B)
        is_int = all(np.all(M == np.round(M.real)) for M in mats + B)
        if is_int:
            coeffs = np.round(coeffs.real) + 0j
        if all(np.all(M.imag == 0.0) for M in mats + B):
            coeffs = coeffs.real + 0j
        terms: dict[Exponents, NDArray[np.complex128]] = {}
        for idx in zip(*np.nonzero(coeffs), strict=True):
            j, k = int(idx[0]), tuple(int(x) for x in idx[1:])
            terms.setdefault(k, np.zeros(n + 1, dtype=np.complex128))[j] = coeffs[idx]
        if (0,) * m not in terms:  # cannot happen: the principal term holds s^n
            raise QuasiPolynomialError("the characteristic function has no undelayed term")
        return cls(terms)


def _matrix(name: str, value: ArrayLike) -> NDArray[np.complex128]:
    try:
        M = np.atleast_2d(np.asarray(value, dtype=np.complex128))
    except (TypeError, ValueError) as exc:
        raise QuasiPolynomialError(f"{name} must be a square matrix of numbers") from exc
    if M.ndim != 2 or M.shape[0] != M.shape[1] or M.shape[0] == 0:
        raise QuasiPolynomialError(f"{name} must be a non-empty square matrix, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise QuasiPolynomialError(f"{name} has entries that are not finite numbers")
    return M


def _expand_determinant(
    A0: NDArray[np.complex128], A: list[NDArray[np.complex128]], B: list[NDArray[np.complex128]]
) -> NDArray[np.complex128]:
    """Coefficients c[j, k1, ..., km] of s^j z1^k1 ... zm^km in det(s (I - sum B z) - A0 - sum A z).

    Every entry of the matrix is affine in s and in each z_k (s z_k for the
    neutral part), so the determinant has degree <= n in each variable and
    n + 1 samples per variable on a circle determine it. The circles are
    scaled (s on radius r ~ the size of the matrices, z_k on radius
    r / size of A_k, or 1 / size of B_k) so that all scaled coefficients are
    of the same order and the FFT's absolute rounding error is relative to
    each of them.
    """
    n, m = A0.shape[0], len(A)
    norm = lambda M: float(np.linalg.norm(M, 2))  # noqa: E731
    r = max(norm(A0), *(norm(a) for a in A), 1e-300)
    rho = [
        r / max(norm(a), r * norm(b)) if max(norm(a), norm(b)) > 0 else 1.0 for a, b in zip(A, B, strict=True)
    ]
    N = n + 1
    w = np.exp(2j * np.pi * np.arange(N) / N)
    grids = np.meshgrid(*([w * r] + [w * p for p in rho]), indexing="ij")
    pts = [g.ravel() for g in grids]
    vals = np.empty(pts[0].size, dtype=np.complex128)
    eye = np.eye(n)
    for lo in range(0, vals.size, _DET_BATCH):
        sl = slice(lo, lo + _DET_BATCH)
        s = pts[0][sl, None, None]
        M = s * eye - A0
        for k in range(m):
            z = pts[k + 1][sl, None, None]
            M = M - A[k] * z - s * z * B[k]
        vals[sl] = np.linalg.det(M)
    coeffs = np.fft.fftn(vals.reshape(grids[0].shape)) / vals.size
    # FFT with e^{-2 pi i} kernel of values at w^j returns coefficients in index order: undo the scaling
    scale = np.ones(coeffs.shape)
    for axis, radius in enumerate([r] + rho):
        shape = [1] * coeffs.ndim
        shape[axis] = N
        scale = scale * (radius ** np.arange(N, dtype=np.float64)).reshape(shape)
    noise = np.abs(coeffs) <= _EXPANSION_NOISE * np.abs(coeffs).max()
    coeffs[noise] = 0.0
    with np.errstate(over="ignore", under="ignore"):
        out: NDArray[Any] = coeffs / scale
    return out
