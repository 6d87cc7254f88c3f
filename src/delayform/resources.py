"""Memory and time budgets: refuse a request up front instead of running out of memory.

A computation that can be asked for arbitrarily large arrays or run times
estimates what it needs and calls :func:`check_budget` before it allocates
anything. The memory budget is the memory available on the machine now
(free physical pages from ``os.sysconf``; page cache the kernel could
release is not counted, so the estimate errs on the safe side); the time budget is :data:`MAX_SECONDS` unless the caller
gives one. This module is a leaf: it imports only :mod:`delayform.errors`.
"""

from __future__ import annotations

import os

from delayform.errors import ResourceError

__all__ = ["MAX_SECONDS", "available_memory", "check_budget", "describe_bytes"]

#: default longest run a single request may take (s) before it is refused
MAX_SECONDS = 3600.0

#: share of the available memory one request may take
_MEMORY_SHARE = 0.8


def available_memory() -> int:
    """Bytes of memory available to a new allocation now (an estimate).

    >>> available_memory() > 0
    True
    """
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):  # not POSIX: no way to tell, assume 8 GiB
        return 8 * 2**30


def describe_bytes(nbytes: float) -> str:
    """A byte count for people: ``'1.5 GiB'``.

    Parameters
    ----------
    nbytes
        Number of bytes.

    >>> describe_bytes(3 * 2**30)
    '3.0 GiB'
    """
    value = float(nbytes)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if value < 1024 or unit == "PiB":
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.1f} {unit}"
        value /= 1024
    raise AssertionError("unreachable")


def _describe_seconds(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def check_budget(
    what: str,
    *,
    nbytes: float = 0.0,
    seconds: float = 0.0,
    setting: str,
    max_seconds: float = MAX_SECONDS,
) -> None:
    """Raise :class:`~delayform.errors.ResourceError` when a request exceeds the machine.

    Parameters
    ----------
    what
        The request, as the message names it (``"this simulation"``).
    nbytes
        Estimated peak memory of the request in bytes.
    seconds
        Estimated run time in seconds.
    setting
        Which settings would make the request smaller (named in the message).
    max_seconds
        Longest acceptable run time; default :data:`MAX_SECONDS`.

    Raises
    ------
    ResourceError
        One line: how much the request needs, how much there is, what to change.

    >>> check_budget("a small run", nbytes=1e3, seconds=1.0, setting="dt")
    """
    limit = _MEMORY_SHARE * available_memory()
    if nbytes > limit:
        raise ResourceError(
            f"{what} would need about {describe_bytes(nbytes)} of memory but "
            f"{describe_bytes(limit)} is available; change {setting}"
        )
    if seconds > max_seconds:
        raise ResourceError(
            f"{what} would take about {_describe_seconds(seconds)} "
            f"(limit {_describe_seconds(max_seconds)}); change {setting}"
        )
