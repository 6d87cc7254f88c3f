"""Benchmark: certified delay margins of a linear DDE with time-varying delays, beside the published figures. Prints markdown.

The system (Gu, Kharitonov and Chen 2003): x' = A0 x + A1 x(t - h(t)), A0 = [[-2, 0], [0, -0.9]],
A1 = [[-1, 0], [-1, -1]]; exact constant-delay margin arccos(-0.9) / sqrt(0.19) = 6.17258.

Rows: ``time_varying_delay_margin`` for constant delays (mu = 0) at N = 0..5, for |h'| <= mu at
mu = 0.1, 0.5, 0.9 (N = 0, 1, 2), for any variation (mu None), and for interval delays
[h1, h2]; each with its wall time (median and best of the repeats), the number of SDPs solved
and the published figure:

- constant delays: Seuret and Gouaisbaut, Systems & Control Letters 2015, Table 1;
- rate-bounded, N = 1: Seuret and Gouaisbaut, Automatica 2013, Table 2.

Goal: under 5 s per margin. Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_tv_certificates.py
[--quick]`` (about 2 minutes; --quick: one repeat). The machine may be shared: the load average is printed.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time

import numpy as np

from delayform import time_varying_delay_margin

A0 = np.array([[-2.0, 0.0], [0.0, -0.9]])
A1 = np.array([[-1.0, 0.0], [-1.0, -1.0]])
EXACT = math.acos(-0.9) / math.sqrt(0.19)

#: (h1, mu, order) -> published margin (source in the module docstring)
PUBLISHED: dict[tuple[float, float | None, int], float] = {
    (0.0, 0.0, 0): 4.472,
    (0.0, 0.0, 1): 6.059,
    (0.0, 0.0, 2): 6.166,
    (0.0, 0.0, 3): 6.1717,
    (0.0, 0.0, 4): 6.1724,
    (0.0, 0.1, 1): 4.703,
    (0.0, 0.5, 1): 2.420,
    (0.0, 0.9, 1): 2.137,
}

CASES: list[tuple[float, float | None, int]] = (
    [(0.0, 0.0, n) for n in range(6)]
    + [(0.0, mu, n) for mu in (0.1, 0.5, 0.9) for n in (0, 1, 2)]
    + [(0.0, None, n) for n in (0, 1, 2)]
    + [(h1, mu, 1) for h1 in (1.0, 3.0) for mu in (0.0, 0.5, None)]
)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    repeats = 1 if args.quick else 3
    print(f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.2f} at start")  # fmt: skip
    print(f"\nExact constant-delay margin (closed form): {EXACT:.5f}\n")
    print("| h1 | mu | N | margin | published | SDPs | median (s) | best (s) | CPU best (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for h1, mu, order in CASES:
        times, cpu, res = [], [], None
        for _ in range(repeats):
            t, c = time.perf_counter(), time.process_time()  # CPU time: the fair figure on a shared machine
            res = time_varying_delay_margin(A0, A1, h1=h1, mu=mu, order=order)
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        assert res is not None and (res.margin is None or res.margin <= EXACT)
        pub = PUBLISHED.get((h1, mu, order))
        margin = "none" if res.margin is None else f"{res.margin:.4f}"
        rate = "any" if mu is None else f"{mu:g}"
        print(f"| {h1:g} | {rate} | {order} | {margin} | {'' if pub is None else pub} | {len(res.tried)} | "
              f"{float(np.median(times)):.2f} | {min(times):.2f} | {min(cpu):.2f} |")  # fmt: skip
    print(f"\nload average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
