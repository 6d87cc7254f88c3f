"""Starting and ending the child processes of a fleet run: none outlives the run.

Each child is ``python -m delayform.fleet.agents SPEC`` with pipes on its
stdin and stdout (the start time goes in, ``ready`` and ``done`` come out)
and its stderr in a file. Four guards end every child:

- the run ending, by error or not: :class:`Children` closes the pipes,
  sends SIGTERM, waits, then SIGKILL (its ``__exit__``);
- Ctrl-C: the terminal sends SIGINT to the whole process group; the
  children ignore it and the parent's ``__exit__`` ends them;
- SIGTERM to the parent: turned into ``SystemExit`` while the run lasts
  (:func:`terminate_as_exit`), so the same ``__exit__`` runs;
- the parent's death by SIGKILL, which nothing in it can catch: each child
  asked the kernel for SIGKILL when its parent dies (``PR_SET_PDEATHSIG``)
  and also watches its parent's PID (:func:`delayform.fleet.agents.tie_to_parent`).
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from delayform._files import atomic_path
from delayform.errors import FleetRunError

__all__ = ["Children", "terminate_as_exit"]

#: seconds a child gets to end after SIGTERM before SIGKILL
_GRACE = 2.0


@contextmanager
def terminate_as_exit() -> Iterator[None]:
    """SIGTERM raises ``SystemExit(143)`` in the main thread while the block runs (so cleanup runs)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class Children:
    """The run's child processes, ended on leaving the ``with`` block (module doc).

    Parameters
    ----------
    folder
        Where the specs and the children's stderr go.
    """

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self._errs: dict[str, Path] = {}
        self._started: dict[str, int] = {}

    def __enter__(self) -> Children:
        return self

    def __exit__(self, *exc: object) -> None:
        self.end()

    @property
    def pids(self) -> dict[str, int]:
        """Name -> PID of every child started (those killed by a fault too)."""
        return dict(self._started)

    def start(self, name: str, spec: dict[str, Any]) -> None:
        """Start child ``name`` with its spec (``parent`` is added)."""
        path = self.folder / f"{name}.json"
        with atomic_path(path) as tmp:  # a child never reads half a spec
            tmp.write_text(json.dumps({**spec, "parent": os.getpid()}))
        err = self.folder / f"{name}.err"
        self._errs[name] = err
        with open(err, "wb") as stderr:
            self.procs[name] = subprocess.Popen(
                [sys.executable, "-m", "delayform.fleet.agents", str(path)],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=stderr, close_fds=True,
            )  # fmt: skip
        self._started[name] = self.procs[name].pid

    def kill(self, name: str) -> None:
        """SIGKILL child ``name`` now (a fault: it gets no chance to clean up) and forget it; it is reaped at once."""
        p = self.procs.pop(name)
        p.kill()
        p.wait()
        for stream in (p.stdin, p.stdout):
            if stream is not None:
                stream.close()

    def said(self, name: str, word: str) -> bool:
        """Whether child ``name`` has printed ``word`` (one line) yet, without waiting.

        Raises
        ------
        FleetRunError
            When it ended, or printed something else.
        """
        p = self.procs[name]
        assert p.stdout is not None
        if not select.select([p.stdout.fileno()], [], [], 0.0)[0]:
            return False
        line = p.stdout.readline().decode(errors="replace").strip()
        if line == word:
            return True
        p.wait()
        raise FleetRunError(f"the {name} process ended before '{word}': {self.why(name)}")

    def tell(self, name: str, text: str) -> None:
        """Write one line to child ``name``'s stdin."""
        p = self.procs[name]
        assert p.stdin is not None
        p.stdin.write((text + "\n").encode())
        p.stdin.flush()

    def why(self, name: str) -> str:
        """The last line a child wrote on stderr (its error), or its exit status."""
        lines = [ln for ln in self._errs[name].read_text(errors="replace").splitlines() if ln.strip()]
        code = self.procs[name].poll()
        return lines[-1].strip() if lines else f"it exited with status {code}"

    def expect(self, word: str, timeout: float) -> None:
        """Wait until every child has printed ``word`` (one line), or raise FleetRunError naming the first that did not."""
        waiting = {p.stdout.fileno(): name for name, p in self.procs.items() if p.stdout is not None}
        end = time.monotonic() + timeout
        while waiting:
            left = end - time.monotonic()
            if left <= 0:
                names = ", ".join(sorted(waiting.values()))
                for name in waiting.values():  # where each silent child is, in its stderr file
                    if self.procs[name].poll() is None:
                        self.procs[name].send_signal(signal.SIGUSR1)
                raise FleetRunError(f"no '{word}' from {names} within {timeout:g} s (the machine may be too busy)")
            ready, _, _ = select.select(list(waiting), [], [], min(left, 0.5))
            for fd in ready:
                name = waiting[fd]
                line = self.procs[name].stdout.readline().decode(errors="replace").strip()  # type: ignore[union-attr]
                if line == word:
                    del waiting[fd]
                elif not line:
                    self.procs[name].wait()
                    raise FleetRunError(f"the {name} process ended before '{word}': {self.why(name)}")

    def wait(self, timeout: float) -> None:
        """Wait up to ``timeout`` s in all for every child to exit (those still running are ended on leaving)."""
        deadline = time.monotonic() + timeout
        for p in self.procs.values():
            try:
                p.wait(max(deadline - time.monotonic(), 0.01))
            except subprocess.TimeoutExpired:
                return

    def send(self, text: str) -> None:
        """Write one line to every child's stdin."""
        for name in self.procs:
            self.tell(name, text)

    def failed(self) -> str | None:
        """The first child that has ended with a non-zero status, said as a sentence; None while all run or succeeded."""
        for name, p in self.procs.items():
            code = p.poll()
            if code not in (None, 0):
                return f"the {name} process failed: {self.why(name)}"
        return None

    def end(self) -> None:
        """End every child: close its pipes, SIGTERM, wait, SIGKILL, wait (module doc)."""
        for p in self.procs.values():
            for stream in (p.stdin, p.stdout):
                if stream is not None:
                    try:
                        stream.close()
                    except OSError:
                        pass
        alive = [p for p in self.procs.values() if p.poll() is None]
        for p in alive:
            p.terminate()
        deadline = time.monotonic() + _GRACE
        for p in alive:
            try:
                p.wait(max(deadline - time.monotonic(), 0.01))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
