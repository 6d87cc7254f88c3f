"""A memory and time budget guard, checked before a job starts.

Every computation that a user can make arbitrarily large (a grid of
10^5 x 10^5 delay pairs, a chart window reaching a delay of 10^6 s, a long
simulation with a tiny step) first estimates what it would need, and
:func:`require` refuses it up front with one line, saying how much it would
need, what this machine has and which setting to change, instead of running
into the out-of-memory killer or hanging without a word.

The limits:

* memory: a fraction (:data:`MEMORY_FRACTION`) of the machine's physical
  memory, read with ``os.sysconf``; ``DELAYFORM_MEMORY_LIMIT`` (bytes, or with
  a suffix K, M, G) overrides it, e.g. for a container smaller than the host;
* time: :data:`DEFAULT_TIME_BUDGET` seconds, overridden by
  ``DELAYFORM_TIME_BUDGET`` (seconds).

Estimates are deliberately rough (a factor of two either way): the guard is
for jobs that are off by orders of magnitude, not for tuning. Each estimate
sits at the library entry point of its computation (building a team, the
per-link root, a simulation, a chart, a loss model, a sweep), so the command
line, a scenario file and the explorer, which all call the library, share it:
a team of 10^9 agents from a file is refused as ``--n`` would be.

A job whose size follows from other inputs (the ``check`` command charts a
window twice its delays) names those inputs with :func:`sized_by`, so the
message tells the user what they can actually change.

Examples
--------
>>> require(what="a test job", nbytes=1024, seconds=0.1, setting="nothing")
>>> format_bytes(3 * 2**30)
'3 GiB'
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

from delayform.errors import ResourceLimitError

__all__ = [
    "MEMORY_FRACTION",
    "DEFAULT_TIME_BUDGET",
    "memory_limit",
    "time_budget",
    "require",
    "sized_by",
    "format_bytes",
    "format_seconds",
]

#: share of the physical memory one job may plan to use (the rest: the OS, other processes, copies)
MEMORY_FRACTION = 0.75

#: seconds a single command may plan to run before it is refused (one hour)
DEFAULT_TIME_BUDGET = 3600.0

#: the setting named by a refusal inside :func:`sized_by` (None: the job's own)
_SIZED_BY: ContextVar[str | None] = ContextVar("delayform_sized_by", default=None)

_SUFFIX = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


def _physical_memory() -> int:
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # not POSIX: assume a modest machine
        return 8 * 2**30


def memory_limit() -> int:
    """Bytes one job may use: ``DELAYFORM_MEMORY_LIMIT`` or a share of physical memory.

    Returns
    -------
    int
        The limit in bytes.

    Raises
    ------
    ResourceLimitError
        When ``DELAYFORM_MEMORY_LIMIT`` is set but is not a size like ``4G``.
    """
    text = os.environ.get("DELAYFORM_MEMORY_LIMIT", "").strip().upper().removesuffix("B").removesuffix("I")
    if not text:
        return int(MEMORY_FRACTION * _physical_memory())
    unit = text[-1] if text[-1] in _SUFFIX else ""
    try:
        value = float(text[: len(text) - len(unit)]) * _SUFFIX[unit]
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value <= 0:
        raise ResourceLimitError(f"DELAYFORM_MEMORY_LIMIT must be a size like 4G, got {os.environ['DELAYFORM_MEMORY_LIMIT']!r}")
    return int(value)


def time_budget() -> float:
    """Seconds one job may plan to run: ``DELAYFORM_TIME_BUDGET`` or :data:`DEFAULT_TIME_BUDGET`.

    Returns
    -------
    float
        The budget in seconds.

    Raises
    ------
    ResourceLimitError
        When ``DELAYFORM_TIME_BUDGET`` is set but is not a positive number.
    """
    text = os.environ.get("DELAYFORM_TIME_BUDGET", "").strip()
    if not text:
        return DEFAULT_TIME_BUDGET
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value <= 0:
        raise ResourceLimitError(f"DELAYFORM_TIME_BUDGET must be a positive number of seconds, got {text!r}")
    return value


def format_bytes(nbytes: float) -> str:
    """A size for a message: ``'512 MiB'``, ``'3 GiB'``, ``'7.5e+04 TiB'``.

    Parameters
    ----------
    nbytes
        The size in bytes.
    """
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if nbytes >= size:
            return f"{nbytes / size:.3g} {unit}"
    return f"{nbytes:.0f} bytes"


def format_seconds(seconds: float) -> str:
    """A duration for a message: ``'40 s'``, ``'12 min'``, ``'3.1 h'``, ``'2.5e+03 days'``.

    Parameters
    ----------
    seconds
        The duration in seconds.
    """
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= 2 * size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.3g} s"


@contextmanager
def sized_by(setting: str) -> Iterator[None]:
    """Name ``setting`` in every refusal of :func:`require` inside the block.

    For a job whose size is derived from other inputs: ``check`` charts the
    window ``[0, 2 tau1] x [0, 2 tau2]``, so a refused chart must say "reduce
    the delays (--tau1, --tau2)", not name chart options ``check`` has not.

    Parameters
    ----------
    setting
        What the user changes, e.g. ``"the delays (delays.tau1, delays.tau2, --tau1, --tau2)"``.

    Examples
    --------
    >>> with sized_by("the delays (--tau1)"):
    ...     require(what="a chart", setting="the window (--tau1-max)", seconds=1.0)
    """
    token = _SIZED_BY.set(setting)
    try:
        yield
    finally:
        _SIZED_BY.reset(token)


def require(*, what: str, setting: str, nbytes: float = 0.0, seconds: float = 0.0) -> None:
    """Refuse a job, in one line, when its estimate exceeds the machine's memory or the time budget.

    Parameters
    ----------
    what
        The job, as the user asked for it, e.g. ``"a 100000 x 100000 dominant-root map"``.
    setting
        What to change, e.g. ``"map.size (--size)"``.
    nbytes
        Estimated peak memory in bytes (not finite: refused).
    seconds
        Estimated run time in seconds on this machine (not finite: refused).

    Raises
    ------
    ResourceLimitError
        ``<what> would need about <x> of memory (limit <y> ...); reduce <setting>``.
    """
    setting = _SIZED_BY.get() or setting
    limit = memory_limit()
    if not nbytes <= limit:  # also catches NaN
        raise ResourceLimitError(
            f"{what} would need about {format_bytes(nbytes)} of memory, more than the "
            f"{format_bytes(limit)} this machine allows one job (DELAYFORM_MEMORY_LIMIT); reduce {setting}"
        )
    budget = time_budget()
    if not seconds <= budget:
        raise ResourceLimitError(
            f"{what} would take about {format_seconds(seconds)}, more than the time budget of "
            f"{format_seconds(budget)} (DELAYFORM_TIME_BUDGET); reduce {setting}"
        )
