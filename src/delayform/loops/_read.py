"""Loops in: python-control objects and coefficient pairs read as N(s) / D(s).

A SISO ``TransferFunction`` gives its coefficients; a ``StateSpace`` keeps
its hidden modes (denominator det(sI - A), numerator from the matrix
determinant lemma); a square MIMO loop is read as det(sI - A + z BC). Python-
control is imported only when such an object is passed.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform._extras import require_extra
from delayform._validation import validated
from delayform.errors import LoopError
from delayform.characteristic import TwoDelayQuasiPolynomial
from delayform.quasipolynomial import QuasiPolynomial

def _trim(c: NDArray[np.float64]) -> NDArray[np.float64]:
    nz = np.flatnonzero(c)
    return c[: nz[-1] + 1] if nz.size else np.zeros(0)


def _real_coefficients(name: str, value: object) -> NDArray[np.float64]:
    try:
        arr = np.atleast_1d(np.asarray(value, dtype=np.float64)).ravel()
    except (TypeError, ValueError) as exc:
        raise LoopError(f"{name} must be a sequence of real coefficients") from exc
    if not np.all(np.isfinite(arr)):
        raise LoopError(f"{name} has coefficients that are not finite numbers")
    return arr


def _from_pair(loop: tuple[Any, Any], name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    num = _real_coefficients(f"{name} numerator", loop[0])[::-1]
    den = _real_coefficients(f"{name} denominator", loop[1])[::-1]
    for part, coefficients in (("numerator", num), ("denominator", den)):
        if coefficients.size == 0:
            # an empty sequence is no polynomial: reading it as L = 0 would certify a loop never given
            raise LoopError(f"{name} {part} is empty; give its coefficients (write [0] for a zero numerator)")
    return _trim(num), _trim(den)


def _control_module() -> Any:
    """python-control, for a loop that is not a pair (num, den) of coefficients (the ``control`` extra)."""
    require_extra("control")
    import control

    return control


def _check_continuous(loop: Any, name: str) -> None:
    dt = getattr(loop, "dt", 0)
    if dt is not None and dt is not False and dt != 0:
        raise LoopError(
            f"{name} is a discrete-time system (dt = {dt}): its delays are shifts z^-k, "
            "not e^{-tau s}; pass the continuous-time loop"
        )


def _check_siso(loop: Any, name: str) -> None:
    if loop.ninputs != 1 or loop.noutputs != 1:
        raise LoopError(
            f"{name} has {loop.noutputs} outputs and {loop.ninputs} inputs; this needs a SISO loop "
            "(for a 2 x 2 state-space loop use loop_quasi_polynomial)"
        )


def _state_space_siso(loop: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    A, B, C, D = (np.asarray(m, dtype=np.float64) for m in (loop.A, loop.B, loop.C, loop.D))
    den = np.poly(A)[::-1] if A.size else np.ones(1)
    # matrix determinant lemma: det(sI - A + BC) = det(sI - A) (1 + C (sI - A)^-1 B);
    # the leading s^n terms cancel exactly, so the strictly proper part has degree < n
    strict = (np.poly(A - B @ C)[::-1] - den) if A.size else np.zeros(1)
    strict[-1] = 0.0
    num = strict + float(D[0, 0]) * den
    return _trim(num), _trim(den)


@validated(LoopError)
def loop_polynomials(loop: object, *, name: str = "loop") -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Numerator and denominator of a SISO loop gain, in increasing powers of s.

    Parameters
    ----------
    loop
        A python-control ``TransferFunction`` or ``StateSpace`` (continuous
        time, one input and one output), or a pair ``(num, den)`` of real
        coefficients in decreasing powers of s (python-control's order).
    name
        How error messages call the loop.

    Returns
    -------
    (num, den)
        Real coefficient arrays, trailing zeros dropped, numpy.polynomial order.

    Raises
    ------
    LoopError
        For an object that is not one of the above, a discrete-time loop, a
        MIMO loop, a zero denominator or non-finite coefficients.

    Examples
    --------
    >>> num, den = loop_polynomials(([2.0], [1.0, 1.0]))  # 2 / (s + 1)
    >>> num.tolist(), den.tolist()
    ([2.0], [1.0, 1.0])
    """
    if isinstance(loop, tuple) and len(loop) == 2:
        num, den = _from_pair(loop, name)
    else:
        control = _control_module()
        if not isinstance(loop, (control.TransferFunction, control.StateSpace, control.FrequencyResponseData)):
            raise LoopError(
                f"{name} must be a python-control TransferFunction or StateSpace, or a pair "
                f"(num, den), got {type(loop).__name__}"
            )
        if type(loop).__name__ == "DelayLTI" or hasattr(loop, "tau") or hasattr(loop, "delays"):
            raise LoopError(
                f"{name} carries time delays of its own ({type(loop).__name__}), which cannot be read "
                "as one loop gain; pass the delay-free loop and its dead time as delay_margin(loop, delay=theta)"
            )
        if isinstance(loop, control.TransferFunction):
            _check_continuous(loop, name)
            _check_siso(loop, name)
            num = _trim(_real_coefficients(f"{name} numerator", loop.num[0][0])[::-1])
            den = _trim(_real_coefficients(f"{name} denominator", loop.den[0][0])[::-1])
        elif isinstance(loop, control.StateSpace):
            _check_continuous(loop, name)
            _check_siso(loop, name)
            num, den = _state_space_siso(loop)
        else:
            raise LoopError(
                f"{name} is a python-control {type(loop).__name__}; only linear TransferFunction and "
                "StateSpace loops have a characteristic quasi-polynomial"
            )
    if den.size == 0:
        raise LoopError(f"{name} has a zero denominator")
    return (num if num.size else np.zeros(1)), den


def _check_proper(num: NDArray[np.float64], den: NDArray[np.float64], name: str) -> None:
    n, m = den.size - 1, num.size - 1
    if m > n:
        raise LoopError(
            f"{name} is improper (numerator degree {m} > denominator degree {n}): "
            "1 + L(s) e^{-tau s} is of advanced type, unstable for every tau > 0"
        )
    if m == n and abs(num[-1] / den[-1]) >= 1.0:
        raise LoopError(
            f"{name} is biproper with |L(j inf)| = {abs(num[-1] / den[-1]):.6g} >= 1: "
            "1 + L(s) e^{-tau s} is of neutral type with roots near or right of the axis "
            "for every tau > 0, so it has no delay margin"
        )


def _check_strictly_proper(num: NDArray[np.float64], den: NDArray[np.float64], name: str) -> None:
    if num.size >= den.size and np.any(num):
        raise LoopError(
            f"{name} is not strictly proper (numerator degree {num.size - 1}, denominator degree "
            f"{den.size - 1}): the quasi-polynomial would be of neutral or advanced type, which "
            "crossing_map and rightmost_root do not treat"
        )



def _is_mimo(loop: object) -> bool:
    module = type(loop).__module__ or ""
    return module.startswith("control") and getattr(loop, "ninputs", 1) * getattr(loop, "noutputs", 1) > 1


def _as_state_space(loop: Any, name: str) -> Any:
    control = _control_module()
    _check_continuous(loop, name)
    if loop.ninputs != loop.noutputs:
        raise LoopError(
            f"{name} has {loop.noutputs} outputs and {loop.ninputs} inputs; closing u = -y(t - tau) needs a square loop"
        )
    if isinstance(loop, control.TransferFunction):
        try:
            return control.ss(loop)
        except Exception as exc:  # python-control needs slycot to realize a MIMO transfer function
            raise LoopError(
                f"{name}: python-control could not realize this MIMO TransferFunction as a StateSpace "
                f"({type(exc).__name__}); pass a StateSpace"
            ) from exc
    if not isinstance(loop, control.StateSpace):
        raise LoopError(f"{name} is a python-control {type(loop).__name__}; a MIMO loop must be a StateSpace or TransferFunction")
    return loop


def _mimo_characteristic(loop: Any, name: str) -> QuasiPolynomial:
    """det(sI - A + z BC), the delayed feedback u(t) = -y(t - tau) of x' = A x + B u, y = C x."""
    A, B, C, D = (np.asarray(m, dtype=np.float64) for m in (loop.A, loop.B, loop.C, loop.D))
    if loop.ninputs != loop.noutputs:
        raise LoopError(
            f"{name} has {loop.noutputs} outputs and {loop.ninputs} inputs; closing u = -y(t - tau) needs a square loop"
        )
    if np.any(D != 0.0):
        raise LoopError(
            f"{name} has a direct feedthrough D != 0: a MIMO loop must be strictly proper here "
            "(with D the delayed loop is of neutral type)"
        )
    return QuasiPolynomial.from_matrices(A, -B @ C)


def _mimo_terms(loop: Any, name: str, *, max_power: int) -> TwoDelayQuasiPolynomial:
    """det(sI - A + z BC) = g1 + g2 z + g4 z^2 as the paper's eq. 5 (z = e^{-tau1 s})."""
    q = _mimo_characteristic(loop, name)
    top = max(k for (k,) in q.terms)
    if top > max_power:
        raise LoopError(
            f"{name}: det(I + L e^{{-tau s}}) has a term e^{{-{top} tau s}} (rank of BC = {top}); "
            "the paper's eq. 5 and the delay margin here take loops whose BC has rank at most 2 "
            "(use loop_characteristic for the general quasi-polynomial)"
        )
    empty = np.zeros(0)
    return TwoDelayQuasiPolynomial(q.terms[(0,)], q.terms.get((1,), empty), empty, q.terms.get((2,), empty))
