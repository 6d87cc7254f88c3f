"""Characteristic quasi-polynomials of loops with one, two or m delays (paper, eq. 5)."""

from __future__ import annotations

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import NDArray

from delayform._validation import validated
from delayform.characteristic import TwoDelayQuasiPolynomial
from delayform.errors import LoopError
from delayform.loops._read import (
    _as_state_space,
    _check_strictly_proper,
    _is_mimo,
    _mimo_characteristic,
    _mimo_terms,
    loop_polynomials,
)
from delayform.quasipolynomial import QuasiPolynomial

@validated(LoopError)
def loop_quasi_polynomial(
    loop1: object, loop2: object | None = None, *, name: str = "loop"
) -> TwoDelayQuasiPolynomial:
    """The characteristic quasi-polynomial of a loop with one or two delays (paper, eq. 5).

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
