"""Characteristic roots with an actuation delay: the factors of the paper's eq. 3 in three delays.

A robot that applies its command ``tau_a`` late, ``x_i'' = u_i(t - tau_a)``
with u of the paper's eq. 1, reads its *own* state late too. Every factor of
the paper's eq. 3 becomes (docs/theory.md, "Actuation delay")::

    q(s) = s^2 + (D s + P) e^{-tau_a s} - lam (D s e^{-(tau2 + tau_a) s} + P e^{-(tau1 + tau_a) s})

a retarded quasi-polynomial in the three delays (tau1, tau2, tau_a), solved
and certified by the general machinery of
:class:`~delayform.quasipolynomial.QuasiPolynomial` (Chebyshev seeds,
Newton on q itself, argument-principle certificate). A conjugate pair of
eigenvalues is solved through lam alone: the roots of the conj(lam) factor
are the conjugates. The centroid factor (lam = 1) keeps its persistent root
s = 0 (q(0) = P - P = 0 for every delay), deflated as in the paper's eq. 4; on
tau1 = 0 it is ``s (s + D e^{-tau_a s} (1 - e^{-tau2 s}))``, the drift's
double zero, as without the actuation delay.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from delayform._validation import validated
from delayform.analysis.roots.family.actuated import actuated_quasi
from delayform.analysis.roots.problem import UNIT_DELAYS, _problem_of_quasi
from delayform.analysis.roots.single import _rightmost, roots_in
from delayform.characteristic import CharacteristicFactor
from delayform.quasipolynomial import QuasiPolynomial

__all__ = ["actuated_factor"]


@validated()
def actuated_factor(P: float, D: float, lam: complex) -> QuasiPolynomial:
    """The factor of the paper's eq. 3 for eigenvalue lam with an actuation delay, in delays (tau1, tau2, tau_a).

    Parameters
    ----------
    P, D
        Gains of the paper's eq. 1.
    lam
        An eigenvalue of C (paper, eq. 3); complex for a conjugate pair.

    Returns
    -------
    QuasiPolynomial
        ``s^2 + (D s + P) e^{-tau_a s} - lam (D s e^{-(tau2 + tau_a) s} + P e^{-(tau1 + tau_a) s})``
        with exponent keys over (tau1, tau2, tau_a).

    Examples
    --------
    >>> q = actuated_factor(1.0, 0.5, 1.0)
    >>> complex(q.evaluate(0.0, 0.3, 0.2, 0.1))  # the centroid's persistent zero
    0j
    """
    return actuated_quasi(P, D, complex(lam))


def actuated_rightmost(factor: CharacteristicFactor, t1: float, t2: float, ta: float) -> complex:
    """Certified rightmost root of one factor with actuation delay ``ta`` (Im >= 0 of a pair).

    The centroid factor's persistent zero is deflated (its other roots count);
    on tau1 = 0 its second zero, the drift, is returned as 0 (exact).
    """
    qp = actuated_factor(factor.P, factor.D, complex(factor.lam))
    if factor.is_centroid and t1 == 0.0:
        return 0j  # s (s + D e^{-ta s}(1 - e^{-t2 s})): the drift's double zero, exactly
    prob = _problem_of_quasi(qp, (t1, t2, ta))
    if factor.is_centroid:
        prob = replace(prob, deflate_zero=True)
    root = _rightmost(prob, *UNIT_DELAYS, where=f"(tau1, tau2, tau_a) = ({t1:g}, {t2:g}, {ta:g})")
    return complex(root.real, abs(root.imag))


def actuated_beside_drift(factor: CharacteristicFactor, t2: float, ta: float) -> complex | None:
    """On tau1 = 0: rightmost root of the centroid factor beside its two zeros, or None.

    The factor is ``s r(s)`` with ``r = s + D e^{-ta s} - D e^{-(t2 + ta) s}``;
    r(0) = 0 is simple (r'(0) = 1 + D t2), deflated; for t2 = 0, r = s has no other root.
    """
    if t2 == 0.0:
        return None
    D = factor.D
    qp = QuasiPolynomial({(0, 0): [0.0, 1.0], (1, 0): [D], (1, 1): [-D]})  # delays (ta, t2)
    prob = replace(_problem_of_quasi(qp, (ta, t2)), deflate_zero=True)
    root = _rightmost(prob, *UNIT_DELAYS, where=f"(tau2, tau_a) = ({t2:g}, {ta:g})")
    return complex(root.real, abs(root.imag))


def actuated_roots_in(
    factor: CharacteristicFactor, t1: float, t2: float, ta: float, region: tuple[float, float, float, float]
) -> NDArray[np.complex128]:
    """Every root of one factor in the rectangle with actuation delay ``ta`` (certified, as :func:`roots_in`).

    A conjugate pair's factor has the roots of lam and their conjugates: the
    roots of lam in the rectangle and in its mirror image, the latter conjugated.
    """
    qp = actuated_factor(factor.P, factor.D, complex(factor.lam))
    x0, x1, y0, y1 = region
    roots = roots_in(qp, t1, t2, ta, region)
    if factor.group.is_complex_pair:
        roots = np.concatenate([roots, np.conj(roots_in(qp, t1, t2, ta, (x0, x1, -y1, -y0)))])
    return roots[np.lexsort((-roots.imag, -roots.real))]
