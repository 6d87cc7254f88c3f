"""Output files that are complete or absent: one mechanism for every file delayform writes.

Every figure, table, animation, array and page is written to a temporary
name in its own folder and renamed onto its real name only once it is
complete (:func:`atomic_path`). ``os.replace`` within one folder is atomic on
POSIX and Windows, so a reader, or a user after Ctrl-C, sees either the old
file or the new one, never a truncated one. The temporary names start with
a dot and contain ``.partial-`` so that a file left by a killed process
(SIGKILL, power loss: nothing can clean up then) is recognisably unfinished.

A report is many files that refer to each other (index.html embeds the
charts), so it is built in a hidden folder inside the output folder and
committed at the end (:func:`staged_folder`): the files of the previous
report that the new one does not write are removed, the new files are moved
in, and Ctrl-C is held back for the few milliseconds this takes. An
interrupted build leaves the previous report as it was; files in the output
folder that no report wrote are never touched.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

__all__ = ["atomic_path", "write_text", "save_npz", "staged_folder", "PARTIAL_MARK"]

#: part of every temporary name, so unfinished files can be recognised
PARTIAL_MARK = ".partial-"


def _temporary_name(path: Path) -> Path:
    # the real suffix stays last: matplotlib, Pillow and numpy choose the format by it
    return path.with_name(f".{path.stem}{PARTIAL_MARK}{secrets.token_hex(4)}{path.suffix}")


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path to write ``path`` to; renamed onto ``path`` when the block completes.

    Parameters
    ----------
    path
        The file to (re)write; its folder must exist.

    Yields
    ------
    Path
        A hidden name in the same folder with the same suffix. If the block
        raises (KeyboardInterrupt included), the temporary file is removed and
        ``path`` keeps its previous content.

    >>> import tempfile
    >>> folder = Path(tempfile.mkdtemp())
    >>> with atomic_path(folder / "a.txt") as tmp:
    ...     _ = tmp.write_text("done")
    >>> [p.name for p in folder.iterdir()]
    ['a.txt']
    """
    target = Path(path)
    tmp = _temporary_name(target)
    try:
        yield tmp
        try:
            os.replace(tmp, target)
        except OSError as exc:  # e.g. the name is taken by a folder: name the file the user asked for
            raise type(exc)(exc.errno, exc.strerror, str(target)) from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through :func:`atomic_path`; return the path.

    Parameters
    ----------
    path
        The file.
    text
        Its whole content.
    """
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


@contextmanager
def _sigint_held() -> Iterator[None]:
    """Hold Ctrl-C back until the block is done (main thread only; elsewhere a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[Any] = []
    previous = signal.signal(signal.SIGINT, lambda *args: caught.append(args))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if caught:
            raise KeyboardInterrupt


def _previous_files(folder: Path, manifest: str) -> set[str]:
    """The file names the previous report in ``folder`` listed in its manifest (none if unreadable)."""
    try:
        listed = json.loads((folder / manifest).read_text(encoding="utf-8")).get("files", [])
    except (OSError, ValueError, AttributeError):
        return set()
    # only plain names directly in the folder: a manifest is data, never a path to follow
    return {f for f in listed if isinstance(f, str) and f and Path(f).name == f and not f.startswith(".")}


@contextmanager
def staged_folder(folder: str | os.PathLike[str], *, manifest: str = "summary.json") -> Iterator[Path]:
    """Build a multi-file output in a hidden folder inside ``folder``; commit it when the block completes.

    Parameters
    ----------
    folder
        The output folder (created if missing, and removed again if the block
        raises before anything was committed into it).
    manifest
        The file of the output that lists its files (JSON with a ``"files"``
        list): the previous output's files that the new one does not write
        are removed on commit, so the folder never mixes two runs.

    Yields
    ------
    Path
        The folder to write into. If the block raises (KeyboardInterrupt
        included) it is removed and ``folder`` is left as it was.
    """
    target = Path(folder)
    made = _missing_folders(target)
    target.mkdir(parents=True, exist_ok=True)
    build = target / f"{PARTIAL_MARK}{secrets.token_hex(4)}"  # hidden: the mark starts with a dot
    build.mkdir()
    try:
        yield build
        new = {p.name for p in build.iterdir()}
        with _sigint_held():
            for stale in _previous_files(target, manifest) - new:
                path = target / stale
                if path.is_file() or path.is_symlink():
                    path.unlink()
            # the manifest last: until it is replaced, the old one still describes what is there
            for name in sorted(new, key=lambda n: n == manifest):
                os.replace(build / name, target / name)
            build.rmdir()
    except BaseException:
        shutil.rmtree(build, ignore_errors=True)
        for made_here in made:  # input refused by the build leaves no folder behind, as if never run
            try:
                made_here.rmdir()  # only if still empty: nothing else is ever removed
            except OSError:
                break
        raise


def _missing_folders(folder: Path) -> list[Path]:
    """The folders ``folder.mkdir(parents=True)`` would create, innermost first."""
    missing = []
    for p in (folder, *folder.parents):
        if p.exists():
            break
        missing.append(p)
    return missing


def save_npz(path: str | os.PathLike[str], **arrays: Any) -> Path:
    """``numpy.savez_compressed(path, **arrays)`` through :func:`atomic_path`; return the path.

    Parameters
    ----------
    path
        The file, ending in ``.npz``.
    **arrays
        The named arrays.
    """
    import numpy as np

    target = Path(path)
    if target.suffix != ".npz":  # numpy's rule: the suffix is added when missing
        target = target.with_name(target.name + ".npz")
    with atomic_path(target) as tmp:
        np.savez_compressed(tmp, **arrays)
    return target
