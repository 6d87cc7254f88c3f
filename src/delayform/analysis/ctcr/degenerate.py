"""Degenerate crossings of the imaginary axis: multiple roots and roots that touch and return.

The CTCR count adds ``w RT`` for every crossing met on its path, with
``RT = sgn Re ds/dtau_k`` (Definition "Root Tendency") and
``ds/dtau_k = -(dq/dtau_k) / (dq/ds)``. That first-order rule decides nothing
in two cases:

* a *multiple* imaginary root (``dq/ds = 0`` at ``s = j omega``): the m roots
  that meet there leave along the Puiseux branches
  ``s - j omega ~ c delta^(1/m)`` (Newton polygon of q in ``(s - j omega, delta)``),
  some to each side; the first-order quotient is 0/0 and its sign is noise;
* a simple root with ``Re ds/dtau_k = 0`` (it touches the axis): whether it
  crosses or returns is decided by the first non-zero higher derivative of
  ``Re s(tau_k)``.

In the Jarlebring & Michiels example (Automatica 46 (2010) 1112-1115, the
``time_delay`` problem of NLEVP) both happen on the same frequency: at tau = 1
a double non-semisimple root sits at ``3 pi j``, and at tau = 1/3, 5/3, ... the
same frequency is a simple root with ``ds/dtau = -3 pi j / (tau - 1)``, purely
imaginary.

Here such a point gets no formula: the change of NU is counted beside it.
With a small rectangle ``R = [-r, r] x [omega - r, omega + r]`` around
``j omega`` and its right half ``R+ = [0, r] x [...]``, the certified
argument-principle count (:func:`delayform.analysis.roots.argument_principle.count_in_region`,
Lipschitz-certified sampling) gives the roots in ``R+`` at ``tau_k - delta``
and ``tau_k + delta``; their difference is the number of roots that crossed
the axis inside R, multiplicity counted, whatever the order of contact.
The step is accepted only when the count in the whole of R is the same at
``tau_k - delta``, ``tau_k`` and ``tau_k + delta`` (no root entered or left
R through its other sides) and both half counts are certified; otherwise
smaller and larger steps are tried, and when none passes the point is
reported as undecidable (:class:`~delayform.errors.NotConvergedError`)
rather than guessed.
"""

from __future__ import annotations

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import NDArray

from delayform.analysis.roots.argument_principle import count_in_region
from delayform.characteristic import TwoDelayQuasiPolynomial, tendency_sign
from delayform.errors import NotConvergedError

__all__ = ["DOUBLE_ROOT_TOL", "degenerate_mask", "vertex_tendencies", "crossing_changes", "local_change"]

#: ``|dq/ds|`` below this fraction of its terms' moduli: a multiple root (its
#: first-order tendency is 0/0). Rounding leaves ~1e-14 at an exact double root;
#: a simple root this close to a double one is resolved by the count beside it.
DOUBLE_ROOT_TOL = 1e-7
#: ``|Re ds/dtau_k|`` below this fraction of ``|ds/dtau_k|``: the first-order sign is
#: too fragile to trust (touching, or a crossing point known only to ~1e-9); counted beside.
_FRAGILE = 1e-6
#: Half-width of the rectangle around ``j omega``, relative to ``max(1, omega)``.
_BOX = 1e-2
#: Steps in the delay tried, relative to ``max(1, tau_k)``, first to last.
_STEPS = (1e-6, 1e-8, 1e-4, 1e-10)


def _derivatives(
    qp: TwoDelayQuasiPolynomial, omega: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> tuple[NDArray[np.complex128], NDArray[np.complex128], NDArray[np.complex128], NDArray[np.float64]]:
    """dq/ds, dq/dtau1, dq/dtau2 at ``s = j omega`` and the scale of dq/ds (sum of its terms' moduli)."""
    s = 1j * np.asarray(omega, dtype=np.float64)
    shape = np.broadcast_shapes(s.shape, np.shape(t1), np.shape(t2))
    dq_ds = np.zeros(shape, complex)
    dq_1 = np.zeros(shape, complex)
    dq_2 = np.zeros(shape, complex)
    scale = np.zeros(shape)
    for c, a, b in qp.terms():
        h = a * np.asarray(t1) + b * np.asarray(t2)
        e = np.exp(-h * s)
        g = npoly.polyval(s, c)
        dg = npoly.polyval(s, npoly.polyder(c))
        dq_ds += (dg - h * g) * e
        dq_1 -= a * s * g * e
        dq_2 -= b * s * g * e
        scale += np.abs(dg) + h * np.abs(g)
    return dq_ds, dq_1, dq_2, scale


def degenerate_mask(
    qp: TwoDelayQuasiPolynomial, omega: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> NDArray[np.bool_]:
    """True where ``j omega`` is a multiple root of q at (t1, t2): ``|dq/ds|`` is rounding noise.

    Parameters
    ----------
    qp
        The traced quasi-polynomial.
    omega, t1, t2
        Crossing frequencies and delay pairs (broadcasting).
    """
    dq_ds, _, _, scale = _derivatives(qp, omega, t1, t2)
    return ~(np.abs(dq_ds) > DOUBLE_ROOT_TOL * scale)


def vertex_tendencies(
    qp: TwoDelayQuasiPolynomial, omega: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(RT1, RT2) at curve vertices; 0 at multiple roots, whose sign the quotient does not give.

    Parameters
    ----------
    qp
        The traced quasi-polynomial.
    omega, t1, t2
        Crossing frequencies and delay pairs (broadcasting).

    A 0 makes the CTCR count decide the crossing at the crossing point itself
    (:func:`crossing_changes`), as it already does for touching roots.
    """
    dq_ds, dq_1, dq_2, scale = _derivatives(qp, omega, t1, t2)
    simple = np.abs(dq_ds) > DOUBLE_ROOT_TOL * scale
    with np.errstate(divide="ignore", invalid="ignore"):
        rt1 = tendency_sign(-dq_1 / dq_ds)
        rt2 = tendency_sign(-dq_2 / dq_ds)
    return np.where(simple, rt1, 0), np.where(simple, rt2, 0)


def crossing_changes(
    qp: TwoDelayQuasiPolynomial, omega: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64],
    *, delay: int,
) -> NDArray[np.int64]:
    """Change of the number of roots right of the axis near ``j omega`` as tau_k grows through (t1, t2).

    Parameters
    ----------
    qp
        The traced quasi-polynomial.
    omega, t1, t2
        Crossing frequencies and delay pairs (broadcasting).
    delay
        1 or 2: the delay that grows.

    ``sgn Re ds/dtau_k`` at a simple root that crosses; the count beside the
    point (:func:`local_change`) at a multiple root or a touching one.

    Raises
    ------
    NotConvergedError
        When the count beside a degenerate point cannot be certified.
    """
    omega, t1, t2 = np.broadcast_arrays(np.asarray(omega, float), np.asarray(t1, float), np.asarray(t2, float))
    dq_ds, dq_1, dq_2, scale = _derivatives(qp, omega, t1, t2)
    with np.errstate(divide="ignore", invalid="ignore"):
        ds = -(dq_1 if delay == 1 else dq_2) / dq_ds
    out = tendency_sign(ds)
    re = np.nan_to_num(ds.real)
    undecided = ~(np.abs(dq_ds) > DOUBLE_ROOT_TOL * scale) | (
        np.abs(re) <= _FRAGILE * np.nan_to_num(np.abs(ds))
    )
    # a delay absent from q moves nothing: dq/dtau_k = 0 identically
    if not any((a if delay == 1 else b) for _, a, b in qp.terms()):
        return np.zeros(omega.shape, np.int64)
    # when q does not contain the other delay (one-delay qps: every horizontal path meets the
    # same vertical line), the change does not depend on it: count once per (omega, tau_k)
    other_absent = not any((b if delay == 1 else a) for _, a, b in qp.terms())
    flat = np.flatnonzero(undecided.ravel())
    seen: dict[tuple[float, ...], int] = {}
    for i in flat:
        idx = np.unravel_index(i, omega.shape)
        w, a1, a2 = float(omega[idx]), float(t1[idx]), float(t2[idx])
        if other_absent:
            a2 = 0.0 if delay == 1 else a2
            a1 = 0.0 if delay == 2 else a1
        key = (round(w, 9), round(a1, 9), round(a2, 9))
        if key not in seen:
            seen[key] = local_change(qp, w, a1, a2, delay=delay)
        out[idx] = seen[key]
    return out.astype(np.int64)


def local_change(qp: TwoDelayQuasiPolynomial, omega: float, tau1: float, tau2: float, *, delay: int) -> int:
    """Roots right of the axis near ``j omega`` at tau_k + delta minus those at tau_k - delta.

    Certified argument-principle counts in a small rectangle beside the point
    (module docstring); multiplicity counted.

    Parameters
    ----------
    qp
        The quasi-polynomial (paper, eq. 5); retarded or neutral.
    omega
        Crossing frequency: ``q(j omega; tau1, tau2) = 0``.
    tau1, tau2
        The crossing point in the delay plane.
    delay
        1 or 2: which delay grows.

    Returns
    -------
    int
        The change of NU contributed by the roots that meet at ``j omega``
        (for a real qp the conjugate ``-j omega`` adds the same).

    Raises
    ------
    NotConvergedError
        When no step gives certified, consistent counts.
    """
    terms = qp.terms()
    r = _BOX * max(1.0, abs(omega))
    whole = (-r, r, omega - r, omega + r)
    right = (0.0, r, omega - r, omega + r)
    base = tau1 if delay == 1 else tau2
    at = count_in_region(terms, tau1, tau2, whole)

    def moved(d: float) -> tuple[float, float]:
        return (tau1 + d, tau2) if delay == 1 else (tau1, tau2 + d)

    for rel in _STEPS:
        d = rel * max(1.0, base)
        if base > 0.0:
            d = min(d, 0.5 * base)
        counts = []
        for sign in (-1.0, 1.0):
            p1, p2 = moved(sign * d)
            if min(p1, p2) < 0.0:
                counts.append(None)
                continue
            full = count_in_region(terms, p1, p2, whole)
            half = count_in_region(terms, p1, p2, right)
            counts.append(half if (full is not None and full == at) else None)
        if at is not None and counts[0] is not None and counts[1] is not None:
            return int(counts[1] - counts[0])
    raise NotConvergedError(
        f"cannot decide the degenerate crossing at s = {omega:.12g}j, (tau1, tau2) = ({tau1:.12g}, {tau2:.12g}): "
        "the argument-principle counts beside it are not certified"
    )
