"""Argument checks shared by the public functions.

Each check either returns the value in the form the caller computes with
(a float, a float64 array) or raises the named error of
:mod:`delayform.errors` with a one-line message that names the argument.
"""

from __future__ import annotations

import math
import numbers
from typing import Any

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
    """Return a control gain (P or D of the paper's eq. 1) as float, or raise GainError.

    >>> check_gain("P", 1)
    1.0
    """
    out = _real_scalar(name, value, GainError)
    if out <= 0.0:
        raise GainError(f"{name} must be positive (paper, eq. 1), got {out}")
    lo, hi = GAIN_RANGE
    if not lo <= out <= hi:
        raise GainError(
            f"{name} = {out:g} is outside the range {lo:g} to {hi:g} the analysis handles; "
            "choose a gain of moderate size (or rescale time)"
        )
    return out


def check_gains(P: object, D: object) -> tuple[float, float]:
    """Check both gains of the paper's eq. 1."""
    return check_gain("P", P), check_gain("D", D)


def check_delay(name: str, value: object) -> float:
    """Return a delay as float, or raise DelayError when negative or not finite."""
    out = _real_scalar(name, value, DelayError)
    if out < 0.0:
        raise DelayError(f"{name} must be non-negative, got {out}")
    return out


#: what a numpy dtype holds, for messages naming what the user gave
_KIND_NAMES = {"b": "booleans", "c": "complex numbers", "U": "strings", "S": "bytes", "O": "objects"}


def _numbers(name: str, value: ArrayLike, dtype: type, what: str, error: type[InputError]) -> NDArray[Any]:
    """``np.asarray(value, dtype)`` for numbers only.

    numpy would parse the string "0.5", read True as 1 and, for a real
    ``dtype``, drop an imaginary part with only a warning: each is refused
    here, naming what was given.
    """
    allowed = "iuf" if np.dtype(dtype).kind == "f" else "iufc"
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError, OverflowError) as exc:  # ragged lists
        raise error(f"{name} must be {what}, got {type(value).__name__}") from exc
    if raw.dtype.kind not in allowed:
        given = _KIND_NAMES.get(raw.dtype.kind, f"dtype {raw.dtype}")
        raise error(f"{name} must be {what}, got {given}" + (f" ({_short(value)})" if raw.ndim == 0 else ""))
    return np.asarray(raw, dtype=dtype)


def real_numbers(name: str, value: ArrayLike, error: type[InputError] = InputError,
                 what: str = "real numbers") -> NDArray[np.float64]:  # fmt: skip
    """``value`` as a float64 array of any shape, NaN and infinity kept; booleans, complex numbers and strings refused."""
    return _numbers(name, value, np.float64, what, error)


def check_real_array(name: str, value: ArrayLike, error: type[InputError] = InputError) -> NDArray[np.float64]:
    """Return finite real numbers as a float64 array, or raise ``error`` (no booleans, complex numbers, strings)."""
    arr = real_numbers(name, value, error)
    if not np.all(np.isfinite(arr)):
        raise error(f"{name} must be finite")
    return arr


def check_delay_array(name: str, value: ArrayLike) -> NDArray[np.float64]:
    """Return delays as a float64 array, or raise DelayError."""
    arr = _numbers(name, value, np.float64, "a real number or an array of them", DelayError)
    if not np.all(np.isfinite(arr)):
        raise DelayError(f"{name} must be finite")
    if np.any(arr < 0.0):
        raise DelayError(f"{name} must be non-negative, got minimum {arr.min()}")
    return arr


def check_non_negative(name: str, value: object, error: type[InputError] = InputError) -> float:
    """Return a finite float >= 0, or raise ``error``."""
    out = _real_scalar(name, value, error)
    if out < 0.0:
        raise error(f"{name} must be non-negative, got {out}")
    return out


def check_positive(name: str, value: object, error: type[InputError] = InputError) -> float:
    """Return a finite positive float, or raise ``error``."""
    out = _real_scalar(name, value, error)
    if out <= 0.0:
        raise error(f"{name} must be positive, got {out}")
    return out


def check_shaped(name: str, value: ArrayLike, shape: tuple[int | None, ...],
                 error: type[InputError] = InputError) -> NDArray[np.float64]:  # fmt: skip
    """Finite real numbers of the given ``shape`` (None: any length) as float64, or raise ``error`` naming both shapes.

    >>> check_shaped("x0", [[0.0, 1.0]], (None, 2)).shape
    (1, 2)
    """
    arr = check_real_array(name, value, error)
    if arr.ndim != len(shape) or any(want is not None and got != want for got, want in zip(arr.shape, shape)):
        wanted = "(" + ", ".join("any" if d is None else str(d) for d in shape) + ("," if len(shape) == 1 else "") + ")"
        raise error(f"{name} must have shape {wanted}, got {arr.shape}")
    return arr


def check_count(name: str, value: object, minimum: int = 0, error: type[InputError] = InputError) -> int:
    """Return a whole number >= ``minimum`` as int, or raise ``error`` (booleans and floats refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Integral, np.integer)):
        raise error(f"{name} must be a whole number, got {value!r}")
    if int(value) < minimum:
        raise error(f"{name} must be at least {minimum}, got {int(value)}")
    return int(value)


def check_numbers(name: str, value: ArrayLike, error: type[InputError] = InputError,
                  what: str = "a sequence of numbers") -> NDArray[np.complex128]:  # fmt: skip
    """``value`` as a complex128 array (NaN kept); booleans, strings and other objects refused, naming them."""
    return _numbers(name, value, np.complex128, what, error)


def check_complex_array(name: str, value: ArrayLike) -> NDArray[np.complex128]:
    """Return finite complex values as a complex128 array, or raise InputError."""
    arr = check_numbers(name, value, InputError, "complex numbers")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite")
    return arr


# ============================================================ the checking layer of the public API
# One decorator, :func:`validated`, on every public function and class (``delayform.__all__``):
# before the body runs, each argument the caller gave is compared with the parameter's
# annotation, and a mismatch raises a delayform.errors exception in one line naming the
# function, the parameter, what it takes and what it got. Values (ranges, shapes) stay the
# business of each function; this layer makes sure that no wrong *type* reaches numpy,
# SciPy or Dask, whose own errors (TypeError, AttributeError) would name none of ours.

import functools  # noqa: E402
import inspect  # noqa: E402
import os  # noqa: E402
import types  # noqa: E402
import typing  # noqa: E402
from collections.abc import Callable as _CallableABC  # noqa: E402
from collections.abc import Mapping as _MappingABC  # noqa: E402
from collections.abc import Sequence as _SequenceABC  # noqa: E402
from typing import TypeVar  # noqa: E402

from delayform.errors import QuasiPolynomialError, TopologyError  # noqa: E402

_F = TypeVar("_F")

#: a parameter's name -> the error its mismatch raises (else the decorator's own error)
_ERROR_BY_NAME: dict[str, type[InputError]] = {
    "P": GainError, "D": GainError, "P_bounds": GainError, "D_bounds": GainError,
    "tau1": DelayError, "tau2": DelayError, "tau_min": DelayError, "tau_max": DelayError,
    "tau1_max": DelayError, "tau2_max": DelayError, "actuation_delay": DelayError,
    "topology": TopologyError, "qp": QuasiPolynomialError,
}  # fmt: skip

#: a check: True when the value fits, with what the parameter takes (for the message)
_Check = tuple[_CallableABC[[object], bool], str]


def _is_real(v: object) -> bool:
    return not isinstance(v, (bool, np.bool_)) and isinstance(v, (numbers.Real, np.floating, np.integer))


def _scalar_check(tp: type) -> _Check | None:
    """Checks of the plain types; None for a class checked with isinstance."""
    if tp is float:
        # NaN is never a meaningful argument of this library: it would poison every comparison
        return (lambda v: v == v if type(v) is float else (_is_real(v) and not (isinstance(v, float) and math.isnan(v)))), "a finite real number"
    if tp is int:
        return (lambda v: not isinstance(v, (bool, np.bool_)) and isinstance(v, (numbers.Integral, np.integer))), "an integer"
    if tp is complex:
        return (lambda v: v == v if type(v) in (float, complex) else (
            not isinstance(v, (bool, np.bool_)) and isinstance(v, numbers.Number)
            and not (isinstance(v, (float, complex, np.inexact)) and v != v))), "a number"  # fmt: skip
    if tp is bool:
        return (lambda v: isinstance(v, (bool, np.bool_))), "True or False"
    if tp is str:
        return (lambda v: isinstance(v, str)), "a string"
    if tp is type(None):
        return (lambda v: v is None), "None"
    if tp is os.PathLike or (isinstance(tp, type) and issubclass(tp, os.PathLike)):
        return (lambda v: isinstance(v, os.PathLike)), "a path"
    return None


def _numeric_array(v: object) -> bool:
    """ArrayLike as this library uses it: numbers, of any shape numpy can hold."""
    if isinstance(v, np.ndarray):
        return v.dtype.kind in "biufc"
    if isinstance(v, (str, bytes, bytearray)) or v is None:
        return False
    try:
        arr = np.asarray(v)
    except (TypeError, ValueError, OverflowError):  # ragged lists, objects numpy refuses
        return False
    return arr.dtype.kind in "biufc"


def _sequence(v: object) -> bool:
    return (isinstance(v, (_SequenceABC, np.ndarray)) and not isinstance(v, (str, bytes, bytearray)))


#: the members of numpy's ArrayLike union
_ARRAY_LIKE = set(typing.get_args(ArrayLike))


#: a float inside a container: NaN allowed (data, not an argument)
_REAL_OR_NAN: _Check = (_is_real, "a real number")
_COUNTS = {2: "two", 3: "three", 4: "four", 5: "five", 6: "six"}

#: the annotation of a float field of a result that is NaN where it was not computed (the peak
#: frequency of an unstable point): the layer takes NaN there and still refuses what is no number
FloatOrNaN = typing.Annotated[float, "NaN where not computed"]


def _check_of(tp: object) -> _Check | None:
    """The check of an annotation; None when it cannot be checked (the function checks it)."""
    if tp is Any or tp is object or isinstance(tp, TypeVar):
        return None
    if tp is None:
        tp = type(None)
    if tp is ArrayLike or tp is NDArray:
        return _numeric_array, "numeric values (an array)"
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin is typing.Annotated:
        return _REAL_OR_NAN if tp is FloatOrNaN else _check_of(args[0])
    if origin is typing.Union or origin is types.UnionType:
        if _ARRAY_LIKE <= set(args):  # ArrayLike is itself a Union: `ArrayLike | str` flattens
            rest = [a for a in args if a not in _ARRAY_LIKE]
            checks = [_numeric_array] + [c[0] for c in map(_check_of, rest) if c is not None]
            if len(checks) != 1 + len(rest):
                return None
            return (lambda v: any(c(v) for c in checks)), " or ".join(["numeric values (an array)"] + [_check_of(a)[1] for a in rest])  # type: ignore[index]
        parts = [_check_of(a) for a in args]
        if any(p is None for p in parts):
            return None
        fns = [p[0] for p in parts]  # type: ignore[index]
        return (lambda v: any(f(v) for f in fns)), " or ".join(p[1] for p in parts)  # type: ignore[index]
    if origin is typing.Literal:
        return (lambda v: any(type(v) is type(a) and v == a for a in args)), "one of " + ", ".join(map(repr, args))
    if origin is np.ndarray:  # NDArray[...]: numbers the function converts
        return _numeric_array, "numeric values (an array)"
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            inner = _check_of(args[0])
            fn = inner[0] if inner else (lambda v: True)
            return (lambda v: _sequence(v) and all(fn(x) for x in v)), f"a tuple of {inner[1] if inner else 'values'}"
        # inside a tuple, a float may be NaN: a result's "no estimate" (SpectrumBound.estimates)
        inners = [(_REAL_OR_NAN if a is float else _check_of(a)) for a in args]
        fns2 = [c[0] if c else (lambda v: True) for c in inners]
        kinds = {c[1] if c else "any" for c in inners}
        if kinds == {"a real number"} and len(args) in _COUNTS:
            what = f"a tuple of {_COUNTS[len(args)]} finite real numbers"
        else:
            what = f"a tuple of {len(args)} ({', '.join(c[1] if c else 'any' for c in inners)})"
        return (lambda v: _sequence(v) and len(v) == len(fns2) and all(f(x) for f, x in zip(fns2, v))), what  # type: ignore[arg-type]
    if origin in (list, _SequenceABC, typing.Sequence):
        inner = _check_of(args[0]) if args else None
        fn3 = inner[0] if inner else (lambda v: True)
        return (lambda v: _sequence(v) and all(fn3(x) for x in v)), f"a sequence of {inner[1] if inner else 'values'}"
    if origin in (dict, _MappingABC, typing.Mapping):
        return (lambda v: isinstance(v, _MappingABC)), "a mapping"
    if origin is _CallableABC or tp is _CallableABC:
        return callable, "a function"
    if origin is not None:
        return None  # other generics (Iterator, ...): the function checks them
    plain = _scalar_check(tp) if isinstance(tp, type) else None
    if plain is not None:
        return plain
    if isinstance(tp, type):
        if getattr(tp, "_is_protocol", False) and not getattr(tp, "_is_runtime_protocol", False):
            return None  # a Protocol without runtime_checkable: duck-typed, left to the function
        return (lambda v: isinstance(v, tp)), f"a {tp.__name__}"
    return None


def _split_union(text: str) -> list[str]:
    """``"ArrayLike | str"`` -> ``["ArrayLike", "str"]``, split only outside brackets."""
    parts, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        depth += ch in "[(" and 1 or (-1 if ch in "])" else 0)
        if ch == "|" and depth == 0:
            parts.append(text[start:i].strip())
            start = i + 1
    return [*parts, text[start:].strip()]


def _sure_types(tp: object) -> set[type]:
    """Exact types that always pass the check of ``tp``: a set lookup instead of the check (speed)."""
    if tp is None or tp is type(None):
        return {type(None)}
    if tp is float or tp is complex:
        return {int, np.int64}  # floats may be NaN: checked
    if tp is int:
        return {int, np.int64}
    if tp in (bool, str):
        return {tp, np.bool_} if tp is bool else {str}  # type: ignore[return-value]
    if isinstance(tp, type) and typing.get_origin(tp) is None and not getattr(tp, "_is_protocol", False):
        return {tp}
    return set()


def _annotation_check(text: object, namespace: dict[str, Any]) -> tuple[_Check, frozenset[type]] | None:
    check = _annotation_check_of(text, namespace)
    if check is None:
        return None
    sure: set[type] = set()
    if isinstance(text, str):
        for part in _split_union(text):
            sure |= _sure_types(eval(part, namespace))  # noqa: S307 - evaluated once already
    return check, frozenset(sure)


def _annotation_check_of(text: object, namespace: dict[str, Any]) -> _Check | None:
    """The check of a (string) annotation; None when it names what is not importable here.

    A string is split at its top-level ``|`` before evaluation: numpy's
    ArrayLike is itself a Union (with ``str`` in it), and ``ArrayLike | str``
    evaluated whole would flatten into members no longer recognisable.
    """
    if not isinstance(text, str):
        return _check_of(text)
    checks = []
    for part in _split_union(text):
        try:
            tp = eval(part, namespace)  # noqa: S307 - the library's own annotations, not user text
        except Exception:  # a name imported only for type checkers: left to the function
            return None
        check = _check_of(tp)
        if check is None:
            return None
        checks.append(check)
    if len(checks) == 1:
        return checks[0]
    fns = [c[0] for c in checks]
    return (lambda v: any(f(v) for f in fns)), " or ".join(c[1] for c in checks)


def _short(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _compile(func: _CallableABC[..., Any], skip_first: bool) -> tuple[list[str], dict[str, tuple[_Check, frozenset[type]]]]:
    """Parameter names in order, and the check of each checkable one."""
    sig = inspect.signature(func)
    namespace = {**vars(typing), "np": np, "ArrayLike": ArrayLike, "NDArray": NDArray, **func.__globals__}
    names: list[str] = []
    checks: dict[str, tuple[_Check, frozenset[type]]] = {}
    for i, (name, param) in enumerate(sig.parameters.items()):
        if skip_first and i == 0:
            continue
        if param.kind in (param.VAR_POSITIONAL, param.VAR_KEYWORD):
            continue
        if param.kind != param.KEYWORD_ONLY:
            names.append(name)
        if param.annotation is param.empty:
            continue
        check = _annotation_check(param.annotation, namespace)
        if check is not None:
            checks[name] = check
    return names, checks


def validated(error: type[InputError] = InputError, *, methods: bool = True) -> _CallableABC[[_F], _F]:
    """Check the argument types of a public function or class against its annotations.

    Parameters
    ----------
    error
        The delayform.errors class raised for a mismatch, except for the
        gains (:class:`GainError`), delays (:class:`DelayError`) and the
        topology (:class:`TopologyError`), named by their parameter.
    methods
        Whether a class's public methods are checked too (False where the
        methods check their arguments themselves in the user's terms, e.g.
        ``Scenario.with_changes`` naming scenario keys).

    Each argument given is checked once, before the body runs; defaults are
    not. A class gets the check on its ``__init__`` (a dataclass's fields)
    and on its public methods and class methods.

    >>> @validated()
    ... def half(x: float) -> float:
    ...     return x / 2
    >>> half("1")
    Traceback (most recent call last):
    ...
    delayform.errors.InputError: half: x must be a finite real number, got '1'
    """

    def decorate(obj: _F) -> _F:
        if not isinstance(obj, type):
            return _wrap(obj, obj.__name__, error, skip_first=False)  # type: ignore[attr-defined,return-value]
        init = obj.__init__  # type: ignore[misc]
        if hasattr(init, "__globals__"):  # not object.__init__, which takes no arguments
            obj.__init__ = _wrap(init, obj.__name__, error, skip_first=True)  # type: ignore[misc]
        # the public methods too (what users call on results: .to_csv(path), .grid(resolution));
        # properties and underscored names are left alone
        for name, attr in list(vars(obj).items()) if methods else ():
            if name.startswith("_"):
                continue
            if isinstance(attr, classmethod):
                wrapped = _wrap(attr.__func__, f"{obj.__name__}.{name}", error, skip_first=True)
                setattr(obj, name, classmethod(wrapped))
            elif inspect.isfunction(attr):
                setattr(obj, name, _wrap(attr, f"{obj.__name__}.{name}", error, skip_first=True))
        obj.__delayform_checked__ = True  # type: ignore[attr-defined]
        return obj

    return decorate


def _wrap(target: _CallableABC[..., Any], where: str, error: type[InputError], *, skip_first: bool) -> Any:
    """``target`` with its arguments checked first (``skip_first``: self or cls is not checked)."""
    compiled: list[tuple[list[str], dict[str, tuple[_Check, frozenset[type]]], bool, tuple[tuple[int, str], ...]]] = []

    def fail(name: str, what: str, value: object) -> None:
        raise _ERROR_BY_NAME.get(name, error)(f"{where}: {name} must be {what}, got {_short(value)}")

    def check(args: tuple[Any, ...], kwargs: dict[str, Any]) -> None:
        if not compiled:  # annotations are resolved at the first call: the imports are done by then
            names0, checks0 = _compile(target, skip_first=skip_first)
            params = inspect.signature(target).parameters.values()
            open_ended = any(p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD) for p in params)
            # (position, name) of each required parameter; position -1 for a keyword-only one
            required0 = tuple((names0.index(p.name) if p.name in names0 else -1, p.name) for p in params
                              if p.default is p.empty and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
                              and not (skip_first and p.name == next(iter(inspect.signature(target).parameters))))
            compiled.append((names0, checks0, open_ended, required0))
        names, checks, open_ended, required = compiled[0]
        if not open_ended and len(args) > len(names):  # Python's TypeError would name no error of ours
            raise error(f"{where} takes {len(names)} positional argument(s), got {len(args)}")
        for position, name in required:  # likewise for a missing argument
            if not (0 <= position < len(args)) and name not in kwargs:
                raise _ERROR_BY_NAME.get(name, error)(f"{where}: {name} is required and was not given")
        for name, value in zip(names, args):
            entry = checks.get(name)
            if entry is not None and type(value) not in entry[1] and not entry[0][0](value):
                fail(name, entry[0][1], value)
        for name, value in kwargs.items():
            entry = checks.get(name)
            if entry is not None and type(value) not in entry[1] and not entry[0][0](value):
                fail(name, entry[0][1], value)

    if skip_first:
        @functools.wraps(target)
        def method(self: Any, *args: Any, **kwargs: Any) -> Any:
            check(args, kwargs)
            return target(self, *args, **kwargs)

        method.__delayform_checked__ = True  # type: ignore[attr-defined]
        return method

    @functools.wraps(target)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        check(args, kwargs)
        return target(*args, **kwargs)

    wrapper.__delayform_checked__ = True  # type: ignore[attr-defined]
    return wrapper
