"""Benchmark: gain design (issue 12). Prints markdown tables.

1. :func:`delayform.design_gains` for the paper team (paper_six), bounds
   [0.05, 3]^2, default settings (21 x 21 map, 4 starts), at the paper's
   points a, b, c; goal < 10 s per design. Best and median wall time of
   ``--repeat`` runs, and the CPU time of the process (the machine is shared:
   wall time is inflated by other users' load, CPU time much less).
2. The robust design over boxes around b and c (15 x 15 map).
3. Baseline, at the same points in the same run: scipy's
   ``differential_evolution`` (a generic global optimiser, no gradients) on
   the certified :func:`delayform.dominant_root` per evaluation, with a
   budget of about 1,000 evaluations: the abscissa it reaches and its time.
   There is no peer tool that designs gains of a delayed multi-agent team.

Run: ``.venv/bin/python benchmarks/bench_gains.py [--repeat 3] [--no-baseline]``
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

import numpy as np

from delayform.analysis.ctcr.stability_map import PAPER_POINTS
from delayform.analysis.roots.dominant import dominant_root
from delayform.design.gains import design_gains
from delayform.topology import paper_six

BOUNDS = (0.05, 3.0)
BOXES = {"b +- 0.2": ((1.8, 2.2), (0.8, 1.2)), "c +- 0.2": ((0.8, 1.2), (1.8, 2.2))}


def _timed(fn):  # type: ignore[no-untyped-def]
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--no-baseline", action="store_true")
    args = parser.parse_args()
    team = paper_six()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.1f} at start, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}\n")  # fmt: skip
    design_gains(team, 1.0, 2.0, P_bounds=BOUNDS, D_bounds=BOUNDS, grid=5, starts=1)  # imports, caches

    print("| point | (P, D) | Re s_dom | wall best / median (s) | CPU median (s) |")
    print("|---|---|---|---|---|")
    designs = {}
    for k in "abc":
        runs = [_timed(lambda k=k: design_gains(team, *PAPER_POINTS[k], P_bounds=BOUNDS, D_bounds=BOUNDS))
                for _ in range(args.repeat)]  # fmt: skip
        g = runs[-1][0]
        designs[k] = g
        walls, cpus = [r[1] for r in runs], [r[2] for r in runs]
        print(f"| {k} {PAPER_POINTS[k]} | ({g.P:.4f}, {g.D:.4f}) | {g.abscissa:.5f} | "
              f"{min(walls):.2f} / {statistics.median(walls):.2f} | {statistics.median(cpus):.2f} |")  # fmt: skip

    print("\n| robust box (tau1, tau2) | (P, D) | worst Re s_dom found (at) | wall (s) | CPU (s) |")
    print("|---|---|---|---|---|")
    for name, (b1, b2) in BOXES.items():
        g, wall, cpu = _timed(lambda b1=b1, b2=b2: design_gains(team, b1, b2, P_bounds=BOUNDS, D_bounds=BOUNDS, grid=15))
        print(f"| {name}: {b1} x {b2} | ({g.P:.4f}, {g.D:.4f}) | {g.abscissa:.5f} ({g.tau1:.3g}, {g.tau2:.3g}) | "
              f"{wall:.2f} | {cpu:.2f} |")  # fmt: skip

    if args.no_baseline:
        return
    from scipy.optimize import differential_evolution

    print("\n| point | design_gains Re | differential_evolution Re (evaluations) | DE wall (s) | DE CPU (s) |")
    print("|---|---|---|---|---|")
    for k in "abc":
        t1, t2 = PAPER_POINTS[k]

        def f(x: np.ndarray, t1: float = t1, t2: float = t2) -> float:
            return float(dominant_root(team, float(x[0]), float(x[1]), t1, t2).root.real)

        res, wall, cpu = _timed(lambda f=f: differential_evolution(
            f, [BOUNDS, BOUNDS], seed=0, maxiter=32, popsize=15, tol=0.0, polish=False))  # fmt: skip
        print(f"| {k} | {designs[k].abscissa:.5f} | {res.fun:.5f} ({res.nfev}) | {wall:.1f} | {cpu:.1f} |")


if __name__ == "__main__":
    main()
