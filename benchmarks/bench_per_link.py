"""Benchmark: the certified per-link dominant root and how its cost grows with N (issue 20, item 1).

Teams: the paper's six agents (delays U(0.2, 0.4) / U(0.1, 0.3), goal 20 ms) and
``random_digraph(N, 2/N, seed=3)`` with delays U(0.2, 0.6) on both streams for
N = 10, 30, 100, 200 (goal 10 s at 100). Each time is split into seeds (Arnoldi or
dense collocation, and the band search), Newton and the certified count.

Peer: the spectral discretization alone, as TRACE-DDE computes spectra (Breda,
Maset & Vermiglio): dense eigenvalues of the Chebyshev-collocated generator at
M = 10 (not certified, no polish), for N <= 100, on one BLAS thread.

BLAS threads: a batch of 100 x 100 complex inverses, and link_dominant_root at 30
agents, each in a fresh process with OPENBLAS_NUM_THREADS=1 and with the default;
link_dominant_root runs on one thread by itself (delayform.analysis.network.blas),
so its "default" row disables that too.

Run: ``.venv/bin/python benchmarks/bench_per_link.py [--repeat 3] [--quick]`` (a few minutes).
The machine is shared with other jobs: the load average is printed.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import platform
import subprocess
import sys
import time

import numpy as np

import delayform.analysis.network.per_link as pl
from delayform.analysis.network.blas import single_threaded_blas
from delayform.analysis.network.discretization import generator_matrix
from delayform.analysis.network.links import link_team
from delayform.topology import paper_six, random_digraph

_PARTS = {"seeds": ("generator_seeds", "band_seeds"), "newton": ("polish_roots",), "count": ("count_right_of",)}


def _instrument() -> dict[str, float]:
    spent = {k: 0.0 for k in _PARTS}
    for key, names in _PARTS.items():
        for name in names:
            f = getattr(pl, name)

            def timed(*a, _f=f, _k=key, **kw):  # type: ignore[no-untyped-def]
                t = time.perf_counter()
                try:
                    return _f(*a, **kw)
                finally:
                    spent[_k] += time.perf_counter() - t

            setattr(pl, name, timed)
    return spent


def _teams(sizes: list[int]) -> list[tuple[str, object, float, np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(0)
    out = [("paper_six", paper_six(), 0.5, rng.uniform(0.2, 0.4, (6, 6)), rng.uniform(0.1, 0.3, (6, 6)))]
    for n in sizes:
        out.append((f"random_digraph({n}, 2/{n})", random_digraph(n, 2.0 / n, seed=3), 1.0,
                    rng.uniform(0.2, 0.6, (n, n)), rng.uniform(0.2, 0.6, (n, n))))  # fmt: skip
    return out


def _peer(team_args: tuple) -> float:  # type: ignore[type-arg]
    T, D, t1, t2 = team_args
    A = generator_matrix(link_team(T, 1.0, D, t1, t2), 10).toarray()
    with single_threaded_blas():  # as fast as it gets on this loaded machine (see the thread table)
        t = time.perf_counter()
        np.linalg.eigvals(A)
        return time.perf_counter() - t


def scaling(repeat: int, quick: bool) -> None:
    sizes = [10, 30, 100] if quick else [10, 30, 100, 200]
    spent = _instrument()
    print("| team | links | runs | median (s) | best (s) | seeds / Newton / count (s, median run) | "
          "certified roots right of the line | dominant root | peer: dense collocation M = 10 (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    prev = None
    for name, T, D, t1, t2 in _teams(sizes):
        n = T.n
        runs = repeat if n <= 100 else max(1, repeat // 2)
        if n == 6:
            runs = 21
            pl.link_dominant_root(T, 1.0, D, t1, t2)  # warm-up (imports)
        times, parts = [], []
        for _ in range(runs):
            for k in spent:
                spent[k] = 0.0
            t = time.perf_counter()
            r = pl.link_dominant_root(T, 1.0, D, t1, t2)
            times.append(time.perf_counter() - t)
            parts.append(dict(spent))
        mid = parts[int(np.argsort(times)[len(times) // 2])]
        peer = f"{_peer((T, D, t1, t2)):.3f}" if n <= 100 else "not run (4400 states dense)"
        split = " / ".join(f"{mid[k]:.3f}" for k in _PARTS)
        print(f"| {name} | {r.team.rows.size} | {runs} | {np.median(times):.3f} | {min(times):.3f} | {split} | "
              f"{r.count} (line {r.line:.4f}) | {r.root:.5f} | {peer} |", flush=True)
        if prev is not None and n > 6:
            print(f"|  | growth {prev[0]} -> {n}: x{np.median(times) / prev[1]:.1f}, "
                  f"exponent {np.log(np.median(times) / prev[1]) / np.log(n / prev[0]):.2f} | | | | | | | |")
        if n > 6:
            prev = (n, float(np.median(times)))


_CHILD_INV = """
import time, numpy as np
rng = np.random.default_rng(0)
G = np.eye(100) + 0.3 * (rng.standard_normal((50, 100, 100)) + 1j * rng.standard_normal((50, 100, 100))) / 10
ts = []
for _ in range(7):
    t = time.perf_counter(); np.linalg.inv(G); ts.append(time.perf_counter() - t)
print(1e3 * np.median(ts) / 50, 1e3 * min(ts) / 50)
"""

_CHILD_ROOT = """
import contextlib, time, numpy as np
import delayform.analysis.network.per_link as pl, delayform.analysis.network.count as cnt
from delayform.topology import random_digraph
if {off}:  # the library's own one-thread block disabled
    pl.single_threaded_blas = cnt.single_threaded_blas = contextlib.nullcontext
rng = np.random.default_rng(5)
T = random_digraph(30, 2.0 / 30, seed=3)
a, b = rng.uniform(0.2, 0.6, (30, 30)), rng.uniform(0.2, 0.6, (30, 30))
pl.link_dominant_root(T, 1.0, 1.0, a, b)
ts = []
for _ in range(5):
    t = time.perf_counter(); pl.link_dominant_root(T, 1.0, 1.0, a, b); ts.append(time.perf_counter() - t)
print(np.median(ts), min(ts))
"""


def threads() -> None:
    print("\n| what | OPENBLAS_NUM_THREADS=1: median / best | default threads: median / best |")
    print("|---|---|---|")
    for label, code_one, code_default in (
        ("batch of 50 inverses 100 x 100 complex (ms per matrix)", _CHILD_INV, _CHILD_INV),
        ("link_dominant_root, 30 agents (s)", _CHILD_ROOT.format(off=True), _CHILD_ROOT.format(off=True)),
    ):
        cells = []
        for code, env_threads in ((code_one, "1"), (code_default, None)):
            env = dict(os.environ)
            env.pop("OPENBLAS_NUM_THREADS", None)
            env.pop("OMP_NUM_THREADS", None)
            if env_threads:
                env["OPENBLAS_NUM_THREADS"] = env_threads
            out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
            med, best = (float(x) for x in out.stdout.split())
            cells.append(f"{med:.3f} / {best:.3f}")
        print(f"| {label} | {cells[0]} | {cells[1]} |", flush=True)
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", _CHILD_ROOT.format(off=False)], env=env, capture_output=True,
                         text=True, check=True)  # fmt: skip
    med, best = (float(x) for x in out.stdout.split())
    print(f"| link_dominant_root, 30 agents, default threads with its own one-thread block (s) | | "
          f"{med:.3f} / {best:.3f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="stop at 100 agents")
    args = parser.parse_args()
    load = os.getloadavg()
    print(f"machine: {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}; "
          f"load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (shared with other jobs); "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}\n")
    with contextlib.suppress(KeyboardInterrupt):
        scaling(args.repeat, args.quick)
        threads()
    load = os.getloadavg()
    print(f"\nload average at the end {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f}")


if __name__ == "__main__":
    main()
