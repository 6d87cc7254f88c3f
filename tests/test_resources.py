"""The budget guard refuses oversized jobs up front, in one line."""

from __future__ import annotations

import pytest

from delayform.errors import InputError, ResourceLimitError
from delayform.resources import format_bytes, format_seconds, memory_limit, require, time_budget


def test_small_job_passes() -> None:
    require(what="a small job", setting="nothing", nbytes=1e6, seconds=1.0)


@pytest.mark.parametrize(
    ("kwargs", "needle"),
    [
        ({"nbytes": 1e15}, "of memory"),
        ({"nbytes": float("nan")}, "of memory"),
        ({"seconds": 1e9}, "time budget"),
        ({"seconds": float("inf")}, "time budget"),
    ],
)
def test_large_job_refused_in_one_line(kwargs: dict[str, float], needle: str) -> None:
    with pytest.raises(ResourceLimitError) as info:
        require(what="a huge job", setting="the size (--size)", **kwargs)
    message = str(info.value)
    assert isinstance(info.value, InputError)
    assert "\n" not in message and needle in message and "--size" in message


def test_memory_limit_is_a_share_of_physical_memory() -> None:
    import os

    physical = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    assert 0 < memory_limit() < physical


def test_environment_overrides(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DELAYFORM_MEMORY_LIMIT", "2G")
    monkeypatch.setenv("DELAYFORM_TIME_BUDGET", "10")
    assert memory_limit() == 2 * 2**30 and time_budget() == 10.0
    with pytest.raises(ResourceLimitError, match="2 GiB"):
        require(what="job", setting="x", nbytes=3 * 2**30)
    monkeypatch.setenv("DELAYFORM_TIME_BUDGET", "soon")
    with pytest.raises(ResourceLimitError, match="DELAYFORM_TIME_BUDGET"):
        time_budget()


@pytest.mark.parametrize(
    ("value", "text"), [(512 * 2**20, "512 MiB"), (3 * 2**30, "3 GiB"), (100, "100 bytes")]
)
def test_format_bytes(value: float, text: str) -> None:
    assert format_bytes(value) == text


@pytest.mark.parametrize(("value", "text"), [(40, "40 s"), (720, "12 min"), (3 * 86400, "3 days")])
def test_format_seconds(value: float, text: str) -> None:
    assert format_seconds(value) == text
