"""One BLAS thread while the per-link certificate runs: its matrices are small and many.

The certificate of :mod:`delayform.analysis.network.count` and the polish of
:mod:`delayform.analysis.network.per_link` spend their time in NumPy's batched
LAPACK on thousands of N x N matrices (N up to a few hundred). OpenBLAS splits
each of those small calls over its threads, and on a loaded machine the
hand-offs cost more than the arithmetic: measured on 2 shared cores, a batch of
100 x 100 complex inverses ran 3.7 times faster with one thread than with the
default (docs/benchmarks.md, "per-link dominant root"). Batching already keeps
the core busy, so one thread loses nothing when the machine is idle either.

OPENBLAS_NUM_THREADS only acts before NumPy is imported, so this module calls
OpenBLAS's own ``*_set_num_threads`` through ctypes (the copies NumPy and SciPy
loaded: NumPy's runs the batched LAPACK, SciPy's ARPACK and the dense eigensolver),
for the duration of a ``with`` block, and restores the previous count after.
The count is process-wide: another Python thread running BLAS meanwhile would
run single-threaded too (slower, never wrong). Where NumPy is not linked to
OpenBLAS (MKL, Accelerate) or the symbols are missing, the block does nothing.
"""

from __future__ import annotations

import ctypes
import glob
import os
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import lru_cache

import numpy as np

__all__ = ["single_threaded_blas"]

# NumPy's wheels ship scipy-openblas with 64-bit integers, SciPy's with 32; other builds the plain names
_NAMES = (
    ("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
    ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
    ("openblas_get_num_threads64_", "openblas_set_num_threads64_"),
    ("openblas_get_num_threads", "openblas_set_num_threads"),
)

_lock = threading.Lock()
_depth = 0
_saved: list[int] = []


def _candidates() -> list[str]:
    """Shared libraries that may be NumPy's OpenBLAS: the ones mapped into this process, then NumPy's own."""
    found: list[str] = []
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                path = line.rsplit(" ", 1)[-1].strip()
                if "openblas" in os.path.basename(path).lower() and path not in found:
                    found.append(path)
    except OSError:  # not Linux
        pass
    base = os.path.dirname(os.path.dirname(np.__file__))
    for pattern in ("numpy.libs/*openblas*", "numpy/.dylibs/*openblas*", "scipy.libs/*openblas*", "scipy/.dylibs/*openblas*"):
        found += [p for p in sorted(glob.glob(os.path.join(base, pattern))) if p not in found]
    # NumPy's copy first (blas_threads reports it)
    return sorted(found, key=lambda p: "numpy" not in p)


@lru_cache(maxsize=1)
def _controls() -> tuple[tuple[Callable[[], int], Callable[[int], None]], ...]:
    """(get, set) of every OpenBLAS found: NumPy's (batched LAPACK) and SciPy's (ARPACK, eig)."""
    out = []
    for path in _candidates():
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for get_name, set_name in _NAMES:
            get, put = getattr(lib, get_name, None), getattr(lib, set_name, None)
            if get is not None and put is not None:
                get.restype, get.argtypes = ctypes.c_int, []
                put.restype, put.argtypes = None, [ctypes.c_int]
                out.append((get, put))
                break
    return tuple(out)


def blas_threads() -> int | None:
    """Threads NumPy's OpenBLAS uses now (None when it cannot be told)."""
    ctl = _controls()
    return int(ctl[0][0]()) if ctl else None


@contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Run the block with every OpenBLAS on one thread, then restore the previous counts (re-entrant)."""
    global _depth, _saved
    ctl = _controls()
    with _lock:
        if _depth == 0:
            _saved = [int(get()) for get, _ in ctl]
            for (_, put), k in zip(ctl, _saved):
                if k != 1:
                    put(1)
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                for (_, put), k in zip(ctl, _saved):
                    if k != 1:
                        put(k)
