"""Typed access to parsed TOML, and the size checks shared by parsing and :meth:`Scenario.with_changes`."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from delayform.errors import InputError, ScenarioError


class _Reader:
    """Typed access to parsed TOML that raises one-line ScenarioErrors naming file and key."""

    def __init__(self, source: str) -> None:
        self.source = source

    def error(self, key: str, expected: str, got: object = ..., *, found: str | None = None) -> ScenarioError:
        """``<file>: <key>: expected <expected>, got <value>`` (``found`` is said as is)."""
        tail = f", got {found}" if found is not None else ("" if got is ... else f", got {_show(got)}")
        return ScenarioError(f"{self.source}: {key}: expected {expected}{tail}")

    def table(self, data: Mapping[str, Any], key: str, *, required: bool) -> Mapping[str, Any] | None:
        value = data.get(key.rsplit(".", 1)[-1])
        if value is None:
            if required:
                raise ScenarioError(f"{self.source}: [{key}]: missing required table")
            return None
        if not isinstance(value, Mapping):
            raise self.error(key, "a table", value)
        return value

    def keys(self, data: Mapping[str, Any], prefix: str, allowed: tuple[str, ...]) -> None:
        for key in data:
            if key not in allowed:
                where = f"{prefix}.{key}" if prefix else key
                raise ScenarioError(
                    f"{self.source}: {where}: unknown key (expected one of: {', '.join(allowed)})"
                )

    def string(self, key: str, value: object, choices: tuple[str, ...] | None = None) -> str:
        if not isinstance(value, str):
            raise self.error(key, "a string" if choices is None else f"one of {', '.join(choices)}", value)
        if choices is not None and value not in choices:
            raise self.error(key, f"one of {', '.join(choices)}", value)
        return value

    def shape(self, key: str, value: object) -> str:
        """A formation shape name, an old name (``"grid"``) replaced by the current one (``"block"``)."""
        from delayform.formation import SHAPES, canonical_shape

        return self.string(key, canonical_shape(value) if isinstance(value, str) else value, tuple(SHAPES))

    def integer(self, key: str, value: object, *, minimum: int | None = None) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, "an integer", value)
        if minimum is not None and value < minimum:
            raise self.error(key, f"an integer >= {minimum}", value)
        return value

    def number(self, key: str, value: object) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(key, "a number", value)
        out = float(value)
        if not math.isfinite(out):
            raise self.error(key, "a finite number", value)
        return out

    def length(self, key: str, value: object, *, unit: str = "metres") -> float:
        """A coordinate or speed no larger than MAX_MAGNITUDE in size (see delayform._validation)."""
        from delayform._validation import MAX_MAGNITUDE

        out = self.number(key, value)
        if abs(out) > MAX_MAGNITUDE:
            raise self.error(key, f"a value of at most {MAX_MAGNITUDE:g} in size ({unit})", value)
        return out

    def gain(self, key: str, value: object) -> float:
        from delayform._validation import GAIN_RANGE

        out = self.number(key, value)
        if out <= 0.0:
            raise self.error(key, "a positive number (paper, eq. 1)", value)
        if not GAIN_RANGE[0] <= out <= GAIN_RANGE[1]:
            raise self.error(key, f"a gain between {GAIN_RANGE[0]:g} and {GAIN_RANGE[1]:g}", value)
        return out

    def positive(self, key: str, value: object) -> float:
        out = self.number(key, value)
        if out <= 0.0:
            raise self.error(key, "a positive number", value)
        return out

    def non_negative(self, key: str, value: object) -> float:
        out = self.number(key, value)
        if out < 0.0:
            raise self.error(key, "a non-negative number (seconds)", value)
        return out

    def pair(self, key: str, value: object, *, what: str = "number") -> tuple[float, float]:
        if not isinstance(value, list) or len(value) != 2:
            raise self.error(key, f"an array of two {what}s", value)
        return (self.non_negative(f"{key}[0]", value[0]), self.non_negative(f"{key}[1]", value[1]))

    def points(self, key: str, value: object, n: int | None) -> tuple[tuple[float, float], ...]:
        if not isinstance(value, list) or not value:
            raise self.error(key, "a non-empty array of [x, y] pairs", value)
        out = []
        for i, row in enumerate(value):
            if not isinstance(row, list) or len(row) != 2:
                raise self.error(f"{key}[{i}]", "a pair [x, y]", row)
            out.append((self.length(f"{key}[{i}][0]", row[0]), self.length(f"{key}[{i}][1]", row[1])))
        if n is not None and len(out) != n:
            raise self.error(key, f"{n} rows, one per agent", found=f"{len(out)} rows")
        return tuple(out)


def _show(value: object) -> str:
    """A short rendering of a TOML value for an error message."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."



def _check_sizes(reader: _Reader, n: int, formation: Any, initial: Any) -> None:
    if formation.shape is not None:
        from delayform.formation import named_formation

        try:
            named_formation(formation.shape, n, spacing=formation.spacing)
        except InputError as exc:
            raise ScenarioError(
                f"{reader.source}: formation.shape: {exc}; choose a shape that fits {n} agents (e.g. --formation polygon)"
            ) from None
    if formation.positions is not None and len(formation.positions) != n:
        raise reader.error("formation.positions", f"{n} rows, one per agent", found=f"{len(formation.positions)} rows")
    if initial.positions is not None and len(initial.positions) != n:
        raise reader.error("initial.positions", f"{n} rows, one per agent", found=f"{len(initial.positions)} rows")
    if initial.headings is not None and len(initial.headings) != n:
        raise reader.error("initial.headings", f"{n} angles, one per agent", found=f"{len(initial.headings)} angles")

