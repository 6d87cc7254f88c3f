"""Benchmark: building exact CTCR stability maps (issue 3). Prints a markdown table.

Cases (goals from issues 3 and 13):

* the paper's example (paper_six, P = 1, D = 0.5) over [0, 10]^2, goal < 0.5 s;
* a 500-agent random_digraph(500, 0.01, seed=1) team (a ring plus ~2500 random
  edges, about 6 informers per agent), P = 1, D = 0.5, over [0, 10]^2, goal < 5 s;
* (issue 13; ``--quick`` skips them; each run in a fresh process so its peak memory is its
  own) random_digraph(1500, 3/1500, seed=1) over [0, 8]^2, goal < 3 s, and
  ring(3000) over [0, 8]^2, goal < 15 s and 300 MB. The time is split into the
  eigenvalues of C (Lemma 1; dense for the random team, FFT for the circulant
  ring) and the map itself; the peak resident memory of the process includes
  the interpreter and libraries (~60 MB, printed as "baseline").

Each map is built from a fresh Topology, so the time includes the eigenvalues
of C (Lemma 1); the eigenvalue time is also shown on its own. The chart rows
time NU on the 400 x 400 grid that shades a stability chart.

Run: ``python benchmarks/bench_ctcr.py [--quick]`` (``make bench`` runs every benchmark).
The machine is shared with other jobs: the load average is printed; trust medians.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from collections.abc import Callable

import numpy as np

from delayform.analysis.ctcr.stability_map import stability_map
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


_CHILD = """
import json, resource, time
from delayform.analysis.ctcr.stability_map import stability_map
from delayform.topology import random_digraph, ring
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # after the imports
t0 = time.perf_counter()
topology = {make}
topology.eigenvalue_groups
t1 = time.perf_counter()
c1 = time.process_time()
m = stability_map(topology, 1.0, 0.5, 8.0, 8.0)
t2 = time.perf_counter()
print(json.dumps(dict(eig=t1 - t0, map=t2 - t1, total=t2 - t0, base=base, map_cpu=time.process_time() - c1,
                      peak=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                      factors=len(topology.eigenvalue_groups), curves=len(m.curves),
                      points=int(sum(c.tau1.size for c in m.curves)))))
"""


def _large_row(name: str, make: str, goal_s: float, goal_mb: float | None, repeat: int) -> list[str]:
    """One large team, ``repeat`` fresh processes: times (best / median) and peak memory."""
    runs = []
    for _ in range(repeat):
        out = subprocess.run([sys.executable, "-c", _CHILD.format(make=make)], capture_output=True, text=True,
                             check=True)
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    med = {k: statistics.median(r[k] for r in runs) for k in ("eig", "map", "total", "peak", "base", "map_cpu")}
    best_map = min(r["map"] for r in runs)
    best_total = min(r["total"] for r in runs)
    time_ok = med["map"] < goal_s  # the map; eig(C) is the topology's, shared by every analysis
    mem_ok = goal_mb is None or med["peak"] < goal_mb
    goal = f"< {goal_s:g} s" + ("" if goal_mb is None else f", < {goal_mb:g} MB")
    status = "met" if time_ok and mem_ok else "NOT met"
    return [name, str(runs[0]["factors"]), str(runs[0]["curves"]), str(runs[0]["points"]),
            f"{med['eig']:.2f}", f"{best_map:.2f} / {med['map']:.2f} ({med['map_cpu']:.2f})",
            f"{best_total:.2f} / {med['total']:.2f}",
            f"{med['peak']:.0f} (baseline {med['base']:.0f})", f"{goal} ({status})"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="skip the 1500- and 3000-agent teams of issue 13")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each large case")
    args = parser.parse_args()
    # the large cases first: a child's peak memory counts the parent's resident size at the
    # fork, so they are spawned while this process is still small
    large = [] if args.quick else [
        _large_row("random_digraph(1500, 3/1500, seed=1), [0,8]^2", "random_digraph(1500, 3 / 1500, seed=1)",
                   3.0, None, args.repeat),
        _large_row("ring(3000), [0,8]^2", "ring(3000)", 15.0, 300.0, args.repeat),
    ]
    rows = [
        _row("paper_six, P=1, D=0.5, [0,10]^2", paper_six, 10.0, 0.5, 7),
        _row("random_digraph(500, 0.01, seed=1), P=1, D=0.5, [0,10]^2",
             lambda: random_digraph(500, 0.01, seed=1), 10.0, 5.0, 3),
    ]
    head = ["case", "agents", "factors", "curve pieces", "curve points", "eig(C) s",
            "map best s", "map median s", "goal", "NU on 400x400 s"]
    load = os.getloadavg()
    print(f"machine: {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}; "
          f"load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (shared with other jobs)")
    print()
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        print("| " + " | ".join(r) + " |")
    if not large:
        return
    head = ["case (P=1, D=0.5)", "factors", "curve pieces", "curve points", "eig(C) median s",
            "map best / median s (median CPU)", "eig + map best / median s", "peak memory MB", "goal (map median; memory median)"]
    print()
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in large:
        print("| " + " | ".join(r) + " |")


if __name__ == "__main__":
    main()
