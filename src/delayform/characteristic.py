"""The factorized characteristic equation of the formation protocol (Lemma 1).

The characteristic function of the paper's eq. 2,

    Q(s) = det( I_n (x) (sI - A0) - C (x) B(s) ),
    A0 = [[0, 1], [-P, -D]],  B(s) = [[0, 0], [P e^{-tau1 s}, D e^{-tau2 s}]],

splits over the eigenvalues lam of C (paper, eq. 3) into

* a second-order factor per real lam (paper, eq. 3, first product)::

      s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s})

* a fourth-order factor per complex-conjugate pair (lam, conj(lam))::

      (s^2 + D s + P)^2 - 2 Re(lam) (s^2 + D s + P)(D s e^{-tau2 s} + P e^{-tau1 s})
                        + |lam|^2 (D s e^{-tau2 s} + P e^{-tau1 s})^2

each raised to the algebraic multiplicity of lam. Every factor has the
general two-delay form of the paper's eq. 5, represented here by
:class:`TwoDelayQuasiPolynomial`, which the CTCR engine
(:mod:`delayform.analysis.ctcr.stability_map`) and the root finders (:mod:`delayform.analysis.roots.dominant`)
take as input.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_complex_array, check_delay_array, check_gains, validated
from delayform.errors import NeutralQuasiPolynomialError, QuasiPolynomialError
from delayform.topology import EigenvalueGroup, Topology

__all__ = [
    "DELAY_MULTIPLES",
    "TwoDelayQuasiPolynomial",
    "CharacteristicFactor",
    "factors",
    "full_characteristic",
    "characteristic_matrix",
    "product_of_factors",
    "tendency_sign",
    "format_number",
]

#: Delay of each term of the paper's eq. 5 as (multiple of tau1, multiple of tau2):
#: g1, g2 e^{-tau1 s}, g3 e^{-tau2 s}, g4 e^{-2 tau1 s}, g5 e^{-2 tau2 s},
#: g6 e^{-(tau1 + tau2) s}.
DELAY_MULTIPLES: tuple[tuple[int, int], ...] = ((0, 0), (1, 0), (0, 1), (2, 0), (0, 2), (1, 1))

#: |Re ds/dtau| below this fraction of |ds/dtau| is a touching root: RT = 0.
ROOT_TENDENCY_TOL = 1e-9

_TERM_NAMES = ("1", "e^{-tau1 s}", "e^{-tau2 s}", "e^{-2 tau1 s}", "e^{-2 tau2 s}", "e^{-(tau1+tau2) s}")


def _coefficients(name: str, value: ArrayLike) -> NDArray[np.complex128]:
    try:
        arr = np.atleast_1d(np.asarray(value, dtype=np.complex128))
    except (TypeError, ValueError) as exc:
        raise QuasiPolynomialError(f"{name} must be a sequence of numbers") from exc
    if arr.ndim != 1:
        raise QuasiPolynomialError(f"{name} must be a 1-D coefficient sequence, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise QuasiPolynomialError(
            f"the coefficients of {name} are not all finite numbers (infinite or NaN)"
        )
    nonzero = np.flatnonzero(arr)
    return arr[: nonzero[-1] + 1] if nonzero.size else np.zeros(0, dtype=np.complex128)


def _degree(c: NDArray[np.complex128]) -> int:
    """Degree of a trimmed coefficient array; -1 for the zero polynomial."""
    return c.size - 1


@validated(QuasiPolynomialError)
@dataclass(frozen=True, eq=False)
class TwoDelayQuasiPolynomial:
    """A two-delay quasi-polynomial of the paper's eq. 5.

        q(s) = g1(s) + g2(s) e^{-tau1 s} + g3(s) e^{-tau2 s}
               + g4(s) e^{-2 tau1 s} + g5(s) e^{-2 tau2 s} + g6(s) e^{-(tau1+tau2) s}

    Each ``g_k`` is a coefficient sequence in increasing powers of s
    (numpy.polynomial order), real or complex; trailing zeros are dropped.

    Parameters
    ----------
    g1, g2, g3, g4, g5, g6
        Coefficients of the six terms; g1 must not be zero.

    Examples
    --------
    The second-order factor of lam = 0.5 with P = 1, D = 0.5:

    >>> q = TwoDelayQuasiPolynomial([1, 0.5, 1], [-0.5], [0, -0.25])
    >>> q.is_retarded
    True
    >>> complex(q.evaluate(0.0, 1.0, 2.0))
    (0.5+0j)
    """

    g1: NDArray[np.complex128]
    g2: NDArray[np.complex128] = field(default_factory=lambda: np.zeros(0, dtype=np.complex128))
    g3: NDArray[np.complex128] = field(default_factory=lambda: np.zeros(0, dtype=np.complex128))
    g4: NDArray[np.complex128] = field(default_factory=lambda: np.zeros(0, dtype=np.complex128))
    g5: NDArray[np.complex128] = field(default_factory=lambda: np.zeros(0, dtype=np.complex128))
    g6: NDArray[np.complex128] = field(default_factory=lambda: np.zeros(0, dtype=np.complex128))

    def __post_init__(self) -> None:
        for k, name in enumerate(("g1", "g2", "g3", "g4", "g5", "g6")):
            object.__setattr__(self, name, _coefficients(name, getattr(self, name)))
        if self.g1.size == 0:
            raise QuasiPolynomialError("g1 must not be the zero polynomial")

    # ------------------------------------------------------------ structure
    @property
    def coefficients(self) -> tuple[NDArray[np.complex128], ...]:
        """(g1, ..., g6), each trimmed, in increasing powers of s."""
        return (self.g1, self.g2, self.g3, self.g4, self.g5, self.g6)

    @property
    def degree(self) -> int:
        """Degree of g1, the number of roots of the delay-free polynomial."""
        return _degree(self.g1)

    @property
    def is_real(self) -> bool:
        """True when every coefficient is real: roots then come in conjugate pairs."""
        return all(np.all(c.imag == 0.0) for c in self.coefficients)

    @property
    def is_retarded(self) -> bool:
        """True when every delayed term has lower degree than g1 (retarded type)."""
        return all(_degree(c) < self.degree for c in self.coefficients[1:])

    def require_retarded(self) -> None:
        """Raise :class:`NeutralQuasiPolynomialError` unless :attr:`is_retarded`."""
        if not self.is_retarded:
            degrees = [_degree(c) for c in self.coefficients]
            raise NeutralQuasiPolynomialError(
                f"quasi-polynomial is of neutral type (degrees of g1..g6 = {degrees}): "
                "a delayed term has the degree of g1; only retarded ones are supported"
            )

    def delay_free(self) -> NDArray[np.complex128]:
        """Coefficients of q at tau1 = tau2 = 0, the sum of all g_k."""
        out = np.zeros(max(c.size for c in self.coefficients), dtype=np.complex128)
        for c in self.coefficients:
            out[: c.size] += c
        return out

    def terms(self) -> tuple[tuple[NDArray[np.complex128], int, int], ...]:
        """The non-zero terms as (coefficients, multiple of tau1, multiple of tau2)."""
        return tuple(
            (c, a, b) for c, (a, b) in zip(self.coefficients, DELAY_MULTIPLES, strict=True) if c.size
        )

    # ------------------------------------------------------------ evaluation
    def _exponentials(
        self, s: NDArray[np.complex128], tau1: ArrayLike, tau2: ArrayLike
    ) -> list[tuple[NDArray[np.complex128], int, int, NDArray[np.complex128]]]:
        t1 = check_delay_array("tau1", tau1)
        t2 = check_delay_array("tau2", tau2)
        return [(c, a, b, np.exp(-(a * t1 + b * t2) * s)) for c, a, b in self.terms()]

    def evaluate(self, s: ArrayLike, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.complex128]:
        """q(s) at the given delays; s, tau1 and tau2 broadcast together."""
        s_arr = check_complex_array("s", s)
        return sum(
            (npoly.polyval(s_arr, c) * e for c, _, _, e in self._exponentials(s_arr, tau1, tau2)),
            start=np.zeros(np.broadcast_shapes(s_arr.shape, np.shape(tau1), np.shape(tau2)), complex),
        )

    def derivative(self, s: ArrayLike, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.complex128]:
        """dq/ds at the given delays (for Newton polishing and root tendencies)."""
        s_arr = check_complex_array("s", s)
        t1 = np.asarray(tau1, dtype=np.float64)
        t2 = np.asarray(tau2, dtype=np.float64)
        out = np.zeros(np.broadcast_shapes(s_arr.shape, t1.shape, t2.shape), complex)
        for c, a, b, e in self._exponentials(s_arr, t1, t2):
            h = a * t1 + b * t2
            out = out + (npoly.polyval(s_arr, npoly.polyder(c)) - h * npoly.polyval(s_arr, c)) * e
        return out

    def delay_derivative(
        self, s: ArrayLike, tau1: ArrayLike, tau2: ArrayLike, *, delay: int
    ) -> NDArray[np.complex128]:
        """dq/dtau_k at fixed s, for ``delay`` k = 1 or 2."""
        if delay not in (1, 2):
            raise QuasiPolynomialError(f"delay must be 1 or 2, got {delay!r}")
        s_arr = check_complex_array("s", s)
        out = np.zeros(np.broadcast_shapes(s_arr.shape, np.shape(tau1), np.shape(tau2)), complex)
        for c, a, b, e in self._exponentials(s_arr, tau1, tau2):
            mult = a if delay == 1 else b
            if mult:
                out = out - mult * s_arr * npoly.polyval(s_arr, c) * e
        return out

    def root_tendency(
        self, omega: ArrayLike, tau1: ArrayLike, tau2: ArrayLike, *, delay: int
    ) -> NDArray[np.int64]:
        """RT = sgn Re(ds/dtau_k) at s = j omega (Definition "Root Tendency").

        ds/dtau_k = -(dq/dtau_k) / (dq/ds) by the implicit function theorem.
        A root that only touches the axis has RT = 0 (see :func:`tendency_sign`).
        """
        if delay not in (1, 2):
            raise QuasiPolynomialError(f"delay must be 1 or 2, got {delay!r}")
        rt1, rt2 = self.root_tendencies(np.asarray(omega, dtype=np.float64),
                                        check_delay_array("tau1", tau1), check_delay_array("tau2", tau2))  # fmt: skip
        return rt1 if delay == 1 else rt2

    def root_tendencies(
        self, omega: NDArray[np.float64], tau1: NDArray[np.float64], tau2: NDArray[np.float64]
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """(RT1, RT2) at s = j omega in one pass, without checking the delays.

        For callers that already checked them, or, like the CTCR curve
        polylines, may step a rounding error past an axis.
        """
        s = 1j * omega
        shape = np.broadcast_shapes(s.shape, np.shape(tau1), np.shape(tau2))
        dq_ds = np.zeros(shape, complex)
        dq_1 = np.zeros(shape, complex)
        dq_2 = np.zeros(shape, complex)
        for c, a, b in self.terms():
            h = a * tau1 + b * tau2
            e = np.exp(-h * s)
            g = npoly.polyval(s, c)
            dq_ds += (npoly.polyval(s, npoly.polyder(c)) - h * g) * e
            dq_1 -= a * s * g * e
            dq_2 -= b * s * g * e
        with np.errstate(divide="ignore", invalid="ignore"):
            return tendency_sign(-dq_1 / dq_ds), tendency_sign(-dq_2 / dq_ds)

    def describe(self) -> str:
        """The quasi-polynomial written out, one term per non-zero g_k."""
        parts = []
        scale = max(float(np.abs(c).max(initial=0.0)) for c in self.coefficients)
        for c, name in zip(self.coefficients, _TERM_NAMES, strict=True):
            # a coefficient that is zero to working precision (e.g. 1 - lam for lam = 1) is dropped
            shown = [(p, v) for p, v in enumerate(c) if format_number(v, scale=scale) != "0"]
            if shown:
                poly = " + ".join(
                    f"{_fmt(v, scale)}" + ("" if p == 0 else (" s" if p == 1 else f" s^{p}")) for p, v in shown
                )
                parts.append(f"({poly})" + ("" if name == "1" else f" {name}"))
        return " + ".join(parts) or "0"


def tendency_sign(ds: NDArray[np.complex128]) -> NDArray[np.int64]:
    """sgn Re(ds/dtau), 0 where Re is rounding noise next to |ds| (a root touching the axis).

    Parameters
    ----------
    ds
        Values of ds/dtau_k at imaginary roots.
    """
    re = np.nan_to_num(ds.real)
    touching = np.abs(re) <= ROOT_TENDENCY_TOL * np.nan_to_num(np.abs(ds))
    return np.where(touching, 0, np.sign(re)).astype(np.int64)


#: parts below this fraction of the scale are rounding noise (about 100 eps)
_ZERO_TOL = 2e-14


def format_number(value: complex, *, scale: float | None = None, digits: int = 6) -> str:
    """A real or complex number for people: parts that are zero to working precision print as 0.

    ``-1.3878e-16 + 1j`` prints as ``1j`` and ``1 + 1e-17j`` as ``1``: a part
    smaller than about 100 machine epsilons of ``scale`` (default: the
    number's modulus, at least 1) is rounding noise of a computation whose
    exact result is 0.

    Parameters
    ----------
    value
        The number.
    scale
        The size the noise is relative to (e.g. the largest coefficient of
        the polynomial the number belongs to).
    digits
        Significant digits.

    >>> format_number(complex(-1.3878e-16, 1.0))
    '1j'
    >>> format_number(complex(-0.5, 0.25))
    '-0.5 + 0.25j'
    """
    v = complex(value)
    tol = _ZERO_TOL * max(1.0, abs(v) if scale is None else scale)
    re = 0.0 if abs(v.real) <= tol else v.real
    im = 0.0 if abs(v.imag) <= tol else v.imag
    if im == 0.0:
        return f"{re:.{digits}g}"
    if re == 0.0:
        return f"{im:.{digits}g}j"
    return f"{re:.{digits}g} {'+' if im > 0 else '-'} {abs(im):.{digits}g}j"


def _fmt(v: complex, scale: float = 1.0) -> str:
    text = format_number(v, scale=scale)
    return f"({text})" if " " in text else text


@validated(QuasiPolynomialError)
@dataclass(frozen=True, eq=False)
class CharacteristicFactor:
    """One factor of eq. factorized: the factor of an eigenvalue group of C.

    Attributes
    ----------
    group
        The eigenvalue (or conjugate pair) of C and its multiplicity.
    P, D
        The gains of the paper's eq. 1.
    """

    group: EigenvalueGroup
    P: float
    D: float

    @property
    def lam(self) -> complex:
        """The eigenvalue of C (for a pair, the member with Im > 0)."""
        return self.group.lam

    @property
    def multiplicity(self) -> int:
        """How many times this factor divides the characteristic function."""
        return self.group.multiplicity

    @property
    def order(self) -> int:
        """Degree in s: 2 for a real eigenvalue, 4 for a conjugate pair."""
        return self.group.factor_order

    @property
    def is_centroid(self) -> bool:
        """True for lam = 1 (paper, eq. 4): a root s = 0 at every delay."""
        return self.group.is_centroid

    @cached_property
    def quasi_polynomial(self) -> TwoDelayQuasiPolynomial:
        """The factor in the coefficient form of the paper's eq. 5."""
        P, D = self.P, self.D
        base = np.array([P, D, 1.0])  # s^2 + D s + P
        if not self.group.is_complex_pair:
            lam = self.lam.real
            return TwoDelayQuasiPolynomial(base, [-lam * P], [0.0, -lam * D])
        re, mod2 = self.lam.real, abs(self.lam) ** 2
        return TwoDelayQuasiPolynomial(
            npoly.polymul(base, base),
            -2.0 * re * P * base,
            -2.0 * re * D * np.concatenate([[0.0], base]),
            [mod2 * P * P],
            [0.0, 0.0, mod2 * D * D],
            [0.0, 2.0 * mod2 * P * D],
        )

    def evaluate(self, s: ArrayLike, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.complex128]:
        """The factor q_i(s) at the given delays (vectorized)."""
        return self.quasi_polynomial.evaluate(s, tau1, tau2)

    def derivative(self, s: ArrayLike, tau1: ArrayLike, tau2: ArrayLike) -> NDArray[np.complex128]:
        """dq_i/ds at the given delays (vectorized)."""
        return self.quasi_polynomial.derivative(s, tau1, tau2)

    def state_matrices(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(A, B1, B2) of the decoupled subsystem (paper, eq. 8).

        The paper's eq. 9 for a real eigenvalue, the paper's eq. 10 with J_i for a
        pair: the subsystem dx/dt = A x + B1 x(t - tau1) + B2 x(t - tau2)
        has this factor as its characteristic function.
        """
        P, D = self.P, self.D
        A = np.array([[0.0, 1.0], [-P, -D]])
        B1 = np.array([[0.0, 0.0], [P, 0.0]])
        B2 = np.array([[0.0, 0.0], [0.0, D]])
        if not self.group.is_complex_pair:
            return A, self.lam.real * B1, self.lam.real * B2
        J = np.array([[self.lam.real, -self.lam.imag], [self.lam.imag, self.lam.real]])
        return np.kron(np.eye(2), A), np.kron(J, B1), np.kron(J, B2)

    def describe(self) -> str:
        """One line: eigenvalue, order, multiplicity and role."""
        lam = self.lam
        if not self.group.is_complex_pair:
            value = format_number(lam.real, digits=4)
        else:  # the pair's real part may be zero to working precision (e.g. +-1j on a ring)
            re = format_number(complex(lam.real, 0.0), scale=abs(lam), digits=4)
            value = f"{'' if re == '0' else re + ' '}+- {abs(lam.imag):.4g}j"

        role = "centroid (rigid-body mode s = 0)" if self.is_centroid else "disagreement"
        mult = f", multiplicity {self.multiplicity}" if self.multiplicity > 1 else ""
        return f"lam = {value}: order {self.order}{mult}, {role}"


@validated(QuasiPolynomialError)
def factors(topology: Topology, P: float, D: float) -> tuple[CharacteristicFactor, ...]:
    """The factors of the characteristic equation, one per eigenvalue group (paper, eq. 3).

    Parameters
    ----------
    topology
        The communication topology; its C matrix supplies the eigenvalues.
    P, D
        Positive gains of the paper's eq. 1.

    Raises
    ------
    NoSpanningTreeError
        When the topology has no spanning tree (Lemma 3: no formation).

    Returns
    -------
    tuple of CharacteristicFactor
        Centroid factor first (paper, eq. 4), then real eigenvalues by
        decreasing value, then conjugate pairs. The product of
        ``f.evaluate(s, tau1, tau2) ** f.multiplicity`` over all factors is
        :func:`full_characteristic`.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> [f.order for f in factors(paper_six(), 1.0, 0.5)]
    [2, 2, 2, 2, 4]
    """
    P, D = check_gains(P, D)
    # Lemma 3: without a spanning tree C has eigenvalue 1 more than once, and the factor list
    # would hold a second "centroid" factor whose persistent zero no formation can remove
    topology.require_spanning_tree()
    return tuple(CharacteristicFactor(g, P, D) for g in topology.eigenvalue_groups)


def characteristic_matrix(
    topology: Topology, P: float, D: float, s: ArrayLike, tau1: float, tau2: float
) -> NDArray[np.complex128]:
    """The 2n x 2n characteristic matrix of the paper's eq. 2 at each s.

    ``M(s) = I_n (x) (s I - A0) - C (x) B(s)`` with ``A0 = [[0, 1], [-P, -D]]`` and
    ``B(s) = [[0, 0], [P e^{-tau1 s}, D e^{-tau2 s}]]``, state order
    ``[x1, x1', x2, x2', ...]`` as in the paper's eq. 2.

    Parameters
    ----------
    topology
        The communication topology (its dense C is used: meant for checks on small teams).
    P, D
        Positive gains of the paper's eq. 1.
    s
        Complex points, any shape.
    tau1, tau2
        Non-negative delays on positions and velocities.

    Returns
    -------
    ndarray
        Shape ``s.shape + (2n, 2n)``.
    """
    P, D = check_gains(P, D)
    s_arr = check_complex_array("s", s)
    t1 = check_delay_array("tau1", tau1)
    t2 = check_delay_array("tau2", tau2)
    C = topology.C_sparse.toarray()
    n = topology.n
    zero = np.zeros_like(s_arr)
    K = np.stack([np.stack([s_arr, zero - 1.0], -1), np.stack([zero + P, s_arr + D], -1)], -2)
    B = np.stack(
        [np.stack([zero, zero], -1), np.stack([P * np.exp(-t1 * s_arr), D * np.exp(-t2 * s_arr)], -1)], -2
    )
    # I (x) K - C (x) B by broadcasting (each entry one product, as the Kronecker products' einsum
    # computes it, several times faster: einsum's outer products do not reach BLAS)
    M = np.eye(n)[:, None, :, None] * K[..., None, :, None, :] - C[:, None, :, None] * B[..., None, :, None, :]
    return M.reshape(s_arr.shape + (2 * n, 2 * n))


@validated(QuasiPolynomialError)
def full_characteristic(
    topology: Topology, P: float, D: float, s: ArrayLike, tau1: float, tau2: float
) -> NDArray[np.complex128]:
    """det of the characteristic matrix of the paper's eq. 2, computed directly.

    Independent of the eigenvalues of C: it is the check on :func:`factors`.

    Parameters
    ----------
    topology
        The communication topology.
    P, D
        Positive gains of the paper's eq. 1.
    s
        Complex points, any shape.
    tau1, tau2
        Non-negative delays on positions and velocities.

    Returns
    -------
    ndarray of complex
        Q(s) of the same shape as ``s``.

    Examples
    --------
    >>> from delayform.topology import ring
    >>> complex(full_characteristic(ring(3), 1.0, 0.5, 0.0, 0.2, 0.1))
    0j
    """
    return np.linalg.det(characteristic_matrix(topology, P, D, s, tau1, tau2))


def product_of_factors(
    fs: Sequence[CharacteristicFactor], s: ArrayLike, tau1: ArrayLike, tau2: ArrayLike
) -> NDArray[np.complex128]:
    """Product of the factors raised to their multiplicities (paper, eq. 3).

    Parameters
    ----------
    fs
        Factors, as returned by :func:`factors`.
    s
        Complex points, any shape.
    tau1, tau2
        Non-negative delays, broadcast with ``s``.

    Returns
    -------
    ndarray of complex
        Q(s); equals :func:`full_characteristic` for the same topology and gains.
    """
    out: NDArray[np.complex128] | complex = 1.0 + 0.0j
    for f in fs:
        out = out * f.evaluate(s, tau1, tau2) ** f.multiplicity
    return np.asarray(out)
