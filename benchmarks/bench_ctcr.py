"""Benchmark: building exact CTCR stability maps (issue 3). Prints a markdown table.

Cases (goals from issue 3):

* the paper's example (paper_six, P = 1, D = 0.5) over [0, 10]^2, goal < 0.5 s;
* a 500-agent random_digraph(500, 0.01, seed=1) team (a ring plus ~2500 random
  edges, about 6 informers per agent), P = 1, D = 0.5, over [0, 10]^2, goal < 5 s.

Each map is built from a fresh Topology, so the time includes the eigenvalues
of C (Lemma 1); the eigenvalue time is also shown on its own. The chart rows
time NU on the 400 x 400 grid that shades a stability chart.

Run: ``python benchmarks/bench_ctcr.py`` (``make bench`` runs every benchmark).
"""

from __future__ import annotations

import os
import platform
import statistics
import time
from collections.abc import Callable

import numpy as np

from delayform.analysis.ctcr import stability_map
from delayform.topology import Topology, paper_six, random_digraph


def _best(fn: Callable[[], object], repeat: int) -> tuple[float, float, object]:
    """(best, median) wall time in seconds over ``repeat`` runs, and the last result."""
    times = []
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), statistics.median(times), out


def _row(name: str, make: Callable[[], Topology], tmax: float, goal: float, repeat: int) -> list[str]:
    topology = make()
    eig_best, _, groups = _best(lambda: make().eigenvalue_groups, repeat)
    best, median, smap = _best(lambda: stability_map(make(), 1.0, 0.5, tmax, tmax), repeat)
    points = sum(c.tau1.size for c in smap.curves)
    t = (np.arange(400) + 0.5) * tmax / 400
    grid_best, _, _ = _best(lambda: smap.unstable_count(t[None, :], t[:, None]), max(1, repeat // 2))
    status = "met" if median < goal else "NOT met"
    return [
        name, str(topology.n), str(len(groups)), str(len(smap.curves)), str(points),
        f"{eig_best:.3f}", f"{best:.3f}", f"{median:.3f}", f"< {goal:g} ({status})", f"{grid_best:.3f}",
    ]


def main() -> None:
    rows = [
        _row("paper_six, P=1, D=0.5, [0,10]^2", paper_six, 10.0, 0.5, 7),
        _row("random_digraph(500, 0.01, seed=1), P=1, D=0.5, [0,10]^2",
             lambda: random_digraph(500, 0.01, seed=1), 10.0, 5.0, 3),
    ]
    head = ["case", "agents", "factors", "curve pieces", "curve points", "eig(C) s",
            "map best s", "map median s", "goal", "NU on 400x400 s"]
    print(f"machine: {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}")
    print()
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        print("| " + " | ".join(r) + " |")


if __name__ == "__main__":
    main()
