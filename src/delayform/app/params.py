"""Query parameters of the explorer's endpoints: declared, parsed strictly, bounded.

Every endpoint declares its parameters as :class:`Param` objects; :func:`parse_query`
turns the raw ``(key, value)`` pairs of a request into checked Python values or
raises :class:`~delayform.errors.InputError` with one line naming the parameter,
what was expected and what came. An unknown key, a repeated key, a missing
required key, a value that is not a finite number and a value outside its
bounds are all errors: nothing is guessed and nothing is silently clipped.

The bounds are the explorer's work limits (:class:`ExplorerLimits`): they cap
what one request may cost (window size, grid size, simulated steps, frames),
so a single click can never ask the 2-core machine for minutes of work.

Examples
--------
>>> spec = (Param("tau1", "float", 0.0, 50.0), Param("P", "float", 0.0, 100.0, default=1.0, open_low=True))
>>> parse_query([("tau1", "0.3")], spec)
{'tau1': 0.3, 'P': 1.0}
>>> parse_query([("tau1", "x")], spec)
Traceback (most recent call last):
...
delayform.errors.InputError: tau1: expected a number, got 'x'
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, fields

from delayform._validation import validated
from delayform.errors import InputError

__all__ = ["Param", "ExplorerLimits", "parse_query"]

#: longest raw value accepted (a number never needs more)
_MAX_VALUE_CHARS = 40
#: most parameters one request may carry
_MAX_PARAMS = 16

_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:e[+-]?[0-9]+)?", re.ASCII)
_INTEGER = re.compile(r"[+-]?[0-9]+", re.ASCII)
_TRUE = ("1", "true", "on", "yes")
_FALSE = ("0", "false", "off", "no")


@validated()
@dataclass(frozen=True)
class ExplorerLimits:
    """The most work one request to the explorer may cause.

    Attributes
    ----------
    max_delay
        Largest delay and chart window side (s).
    max_gain
        Largest P and D.
    max_grid
        Largest shading grid of the chart, cells per axis.
    max_steps
        Most integration steps of one simulation (duration / dt).
    max_agent_steps
        Most agents x steps of one simulation.
    max_frames
        Most animation frames sent back.
    max_agents
        Largest team the explorer opens (checked once, when it starts).
    max_delay_bandwidth
        Largest delay (or chart window side) times the bound on crossing
        frequencies ``(D + sqrt(D^2 + 8 P)) / 2`` (rad): the number of CTCR
        curve periods and of roots near the axis, which set the cost of a map
        and of a certified root count, grow with it.
    """

    max_delay: float = 50.0
    max_gain: float = 20.0
    max_grid: int = 300
    max_steps: int = 30_000
    max_agent_steps: int = 3_000_000
    max_frames: int = 600
    max_agents: int = 100
    max_delay_bandwidth: float = 30.0

    def __post_init__(self) -> None:
        # a limit of zero or less would refuse every request; infinite, none would be refused
        for f in fields(self):
            value = getattr(self, f.name)
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"ExplorerLimits: {f.name} must be finite and positive, got {value!r}")


@dataclass(frozen=True)
class Param:
    """One query parameter: its name, kind and bounds.

    Attributes
    ----------
    name
        The key in the query string.
    kind
        ``"float"``, ``"int"`` or ``"bool"``.
    low, high
        Inclusive bounds for numbers (ignored for ``"bool"``).
    default
        Value when the key is absent; ``None`` makes the key required.
    open_low
        The lower bound is excluded (a gain must be > 0).
    limit
        Name of the :class:`ExplorerLimits` field that sets ``high``, quoted
        in the error so the user knows which limit refused the request.
    """

    name: str
    kind: str
    low: float = -math.inf
    high: float = math.inf
    default: float | int | bool | None = None
    open_low: bool = False
    limit: str | None = None

    def convert(self, raw: str) -> float | int | bool:
        """Parse and check one raw value.

        Parameters
        ----------
        raw
            The value as it came in the query string.

        Raises
        ------
        InputError
            One line naming the parameter.
        """
        if len(raw) > _MAX_VALUE_CHARS:
            raise InputError(f"{self.name}: value longer than {_MAX_VALUE_CHARS} characters")
        text = raw.lower()
        if self.kind == "bool":
            if text in _TRUE:
                return True
            if text in _FALSE:
                return False
            raise InputError(f"{self.name}: expected 0 or 1, got {raw!r}")
        # plain decimal notation only: Python would also take "1_0", "inf" or non-ASCII digits
        pattern = _INTEGER if self.kind == "int" else _DECIMAL
        if not pattern.fullmatch(text):
            what = "an integer" if self.kind == "int" else "a number"
            raise InputError(f"{self.name}: expected {what}, got {raw!r}")
        value: float | int = int(text) if self.kind == "int" else float(text)
        if not math.isfinite(value):
            raise InputError(f"{self.name}: expected a finite number, got {raw!r}")
        if value < self.low or (self.open_low and value == self.low):
            sign = ">" if self.open_low else ">="
            raise InputError(f"{self.name}: must be {sign} {self.low:g}, got {value:g}")
        if value > self.high:
            why = f" (explorer limit {self.limit})" if self.limit else ""
            raise InputError(f"{self.name}: must be <= {self.high:g}{why}, got {value:g}")
        return value


def parse_query(items: Iterable[tuple[str, str]], spec: Sequence[Param]) -> dict[str, float | int | bool]:
    """Checked values of a request's query parameters.

    Parameters
    ----------
    items
        The raw ``(key, value)`` pairs in request order (repeats kept).
    spec
        The parameters the endpoint accepts.

    Returns
    -------
    dict
        Every parameter of ``spec``: its checked value or its default.

    Raises
    ------
    InputError
        For an unknown, repeated, missing, malformed or out-of-bounds parameter.
    """
    known = {p.name: p for p in spec}
    seen: dict[str, float | int | bool] = {}
    for count, (key, raw) in enumerate(items, start=1):
        if count > _MAX_PARAMS:
            raise InputError(f"more than {_MAX_PARAMS} query parameters")
        param = known.get(key)
        if param is None:
            shown = key if len(key) <= _MAX_VALUE_CHARS else key[:_MAX_VALUE_CHARS] + "..."
            accepted = ", ".join(known) or "none"
            raise InputError(f"unknown parameter {shown!r} (accepted: {accepted})")
        if key in seen:
            raise InputError(f"{key}: given more than once")
        seen[key] = param.convert(raw)
    for param in spec:
        if param.name not in seen:
            if param.default is None:
                raise InputError(f"{param.name}: missing")
            seen[param.name] = param.default
    return {p.name: seen[p.name] for p in spec}
