"""Run the ``delayform`` command line for the tests, in this process or in a subprocess.

Both return a :class:`subprocess.CompletedProcess` (exit code, stdout, stderr),
so one assertion helper reads either. A subprocess pays Python's start-up, the
imports and matplotlib's font cache (one or more seconds each under load);
the in-process run pays none of them and is what most CLI tests use. The
tests of the entry point itself (``python -m delayform``: the exit code and
the text a terminal shows, signals, a fresh interpreter) use the subprocess.

The in-process run reproduces what the subprocess sees: the same working
directory, the same minimal environment, stdout and stderr as UTF-8 pipes,
and Python's warnings shown rather than raised (the CLI turns its own into
one-line notes; any other warning text on stderr fails the tests that check
it, as it does in a subprocess).
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import subprocess
import sys
import threading
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

import delayform

#: the ``src`` directory of the delayform under test (a worktree, not another install)
PACKAGE_ROOT = str(Path(delayform.__file__).resolve().parents[1])


#: the BLAS thread counts the test run chose (tests/conftest.py: one per xdist worker), passed on
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def cli_env(cwd: Path | None) -> dict[str, str]:
    """The environment of a CLI run: a headless backend, a bare PATH, HOME in the run's folder."""
    home = str(cwd) if cwd is not None else os.getcwd()
    env = {"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin", "HOME": home, "PYTHONPATH": PACKAGE_ROOT}
    return env | {k: os.environ[k] for k in THREAD_VARIABLES if k in os.environ}


def run_subprocess(*args: str, cwd: Path | None = None, timeout: float = 600,
                   env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:  # fmt: skip
    """``python -m delayform ARGS`` in a fresh interpreter, with captured text output."""
    return subprocess.run(
        [sys.executable, "-m", "delayform", *args],
        capture_output=True, text=True, cwd=cwd, timeout=timeout, env=env or cli_env(cwd),
    )  # fmt: skip


@contextlib.contextmanager
def _as_a_process(cwd: Path | None) -> Iterator[tuple[io.TextIOWrapper, io.TextIOWrapper]]:
    """The working directory, environment, streams and warning filters of a fresh CLI process."""
    saved_env, saved_cwd = dict(os.environ), os.getcwd()
    out = io.TextIOWrapper(io.BytesIO(), encoding="utf-8", write_through=True)
    err = io.TextIOWrapper(io.BytesIO(), encoding="utf-8", write_through=True)
    try:
        if cwd is not None:
            os.chdir(cwd)
        os.environ.clear()
        os.environ.update(cli_env(cwd))
        with warnings.catch_warnings(), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            # shown, not raised (the test run makes warnings errors): as the user's terminal would show them
            warnings.simplefilter("always")
            yield out, err
    finally:
        os.chdir(saved_cwd)
        os.environ.clear()
        os.environ.update(saved_env)


def _text(stream: io.TextIOWrapper) -> str:
    stream.flush()
    buffer = stream.buffer
    assert isinstance(buffer, io.BytesIO)
    # as subprocess.run(text=True) decodes a pipe: universal newlines
    return buffer.getvalue().decode("utf-8").replace("\r\n", "\n").replace("\r", "\n")


@contextlib.contextmanager
def time_limit(seconds: int, error: Callable[[], BaseException]) -> Iterator[None]:
    """Raise ``error()`` in the block once it has run ``seconds`` (SIGALRM; the main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum: int, frame: object) -> None:
        raise error()

    previous = signal.signal(signal.SIGALRM, stop)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def run_in_process(*args: str, cwd: Path | None = None, timeout: int = 600) -> subprocess.CompletedProcess[str]:
    """``delayform ARGS`` through :func:`delayform.cli.main` in this process.

    An exception the CLI does not handle propagates (a subprocess would print
    its traceback and exit 1), so the failing test shows where it came from;
    so does :class:`subprocess.TimeoutExpired` after ``timeout`` seconds.
    """
    from delayform.cli import main

    def hung() -> subprocess.TimeoutExpired:
        return subprocess.TimeoutExpired(["delayform (in-process)", *args], timeout)

    code: int | str | None = 0
    with _as_a_process(cwd) as (out, err), time_limit(timeout, hung):
        try:
            main(list(args))
        except SystemExit as exc:
            code = exc.code
    if isinstance(code, str):  # sys.exit("message"): the message on stderr, exit code 1
        return subprocess.CompletedProcess(list(args), 1, _text(out), _text(err) + code + "\n")
    return subprocess.CompletedProcess(list(args), int(code or 0), _text(out), _text(err))
