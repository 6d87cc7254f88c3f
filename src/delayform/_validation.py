"""Argument checks shared by the public functions.

Each check either returns the value in the form the caller computes with
(a float, a float64 array) or raises the named error of
:mod:`delayform.errors` with a one-line message that names the argument.
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform.errors import DelayError, GainError, InputError


def _real_scalar(name: str, value: object, error: type[InputError]) -> float:
    # a plain float or int first: the ABC check below costs more than the rest of a fast call
    if type(value) is not float and type(value) is not int:
        if isinstance(value, bool) or not isinstance(value, (numbers.Real, np.floating, np.integer)):
            raise error(f"{name} must be a real number, got {value!r}")
    out = float(value)  # type: ignore[arg-type]
    if not math.isfinite(out):
        raise error(f"{name} must be finite, got {out}")
    return out


#: gains outside this range overflow or underflow the characteristic equation's
#: coefficients (products like P D lam); rescale time instead
GAIN_RANGE = (1e-6, 1e6)


#: largest length (m) or speed (m/s) accepted for positions, formations and initial speeds: at
#: 1e6 m a float64 still resolves 1e-10 m, while far larger values (1e150) overflow the squared
#: distances of the error metrics and make a stable run look diverged at t = 0
MAX_MAGNITUDE = 1e6


def check_magnitude(name: str, arr: NDArray[np.float64], error: type[InputError] = InputError, unit: str = "m") -> None:
    """Raise ``error`` when an entry of a finite array exceeds :data:`MAX_MAGNITUDE` in size."""
    if arr.size and float(np.abs(arr).max()) > MAX_MAGNITUDE:
        raise error(f"{name} must be at most {MAX_MAGNITUDE:g} {unit} in size, got {float(np.abs(arr).max()):g}")


def check_gain(name: str, value: object) -> float:
    """Return a control gain (P or D of eq. protocol) as float, or raise GainError.

    >>> check_gain("P", 1)
    1.0
    """
    out = _real_scalar(name, value, GainError)
    if out <= 0.0:
        raise GainError(f"{name} must be positive (eq. protocol), got {out}")
    lo, hi = GAIN_RANGE
    if not lo <= out <= hi:
        raise GainError(
            f"{name} = {out:g} is outside the range {lo:g} to {hi:g} the analysis handles; "
            "choose a gain of moderate size (or rescale time)"
        )
    return out


def check_gains(P: object, D: object) -> tuple[float, float]:
    """Check both gains of eq. protocol."""
    return check_gain("P", P), check_gain("D", D)


def check_delay(name: str, value: object) -> float:
    """Return a delay as float, or raise DelayError when negative or not finite."""
    out = _real_scalar(name, value, DelayError)
    if out < 0.0:
        raise DelayError(f"{name} must be non-negative, got {out}")
    return out


def check_delay_array(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """Return delays as a float64 array, or raise DelayError."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise DelayError(f"{name} must be a real number or an array of them") from exc
    if not np.all(np.isfinite(arr)):
        raise DelayError(f"{name} must be finite")
    if np.any(arr < 0.0):
        raise DelayError(f"{name} must be non-negative, got minimum {arr.min()}")
    return arr


def check_positive(name: str, value: object, error: type[InputError] = InputError) -> float:
    """Return a finite positive float, or raise ``error``."""
    out = _real_scalar(name, value, error)
    if out <= 0.0:
        raise error(f"{name} must be positive, got {out}")
    return out


def check_complex_array(name: str, value: ArrayLike) -> NDArray[np.complex128]:
    """Return finite complex values as a complex128 array, or raise InputError."""
    try:
        arr = np.asarray(value, dtype=np.complex128)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be complex numbers") from exc
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite")
    return arr
