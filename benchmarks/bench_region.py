"""Benchmarks of the eigenvalue plane (issue 11).

1. The certified sufficient stability map of an undirected 2-D grid team of
   100,000 agents over [0, 4]^2 (P = 1, D = 0.5): the spectrum bound
   (shift-invert Lanczos + LDL^T inertia certificates) and the safe set of the
   bound on a 200 x 200 grid of delay pairs. Goal: under 60 s.
2. The same for 1,000,000 agents (no goal; how it scales).
3. On a 400-agent grid team: the sufficient map against the exact CTCR map
   (never stable where the exact map is unstable; share of the exact stable
   area covered, goal >= 90 %).
4. ``LambdaRegion.is_stable`` on a 400 x 400 grid of the eigenvalue plane.

Run: ``PYTHONPATH=src python benchmarks/bench_region.py [--repeats 3] [--million]``.
Timings are wall clock on a shared 2-core machine: other work runs at the same
time, so the median of several repeats is the figure to read.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from delayform.analysis.plane.spectrum_bounds import spectrum_bound
from delayform.analysis.plane.spectrum_sets import safe_delays
from delayform.analysis.ctcr.stability_map import stability_map
from delayform.analysis.plane.region import lambda_region
from delayform.topology import grid


def sufficient_map(rows: int, cols: int, resolution: int = 200) -> tuple[float, float, float, dict[str, float]]:
    """(seconds, safe fraction, bound high end, stage times) for one grid team, from building the team."""
    stages: dict[str, float] = {}
    start = time.perf_counter()
    team = grid(rows, cols)
    stages["build team"] = time.perf_counter() - start
    t = time.perf_counter()
    bound = spectrum_bound(team)
    stages["spectrum bound"] = time.perf_counter() - t
    t = time.perf_counter()
    m = safe_delays(1.0, 0.5, 4.0, 4.0, spectrum=bound)
    fraction = m.safe_fraction(resolution=resolution)
    stages["safe map"] = time.perf_counter() - t
    return time.perf_counter() - start, fraction, bound.spectrum_set.high, stages


def coverage(rows: int = 20, cols: int = 20, resolution: int = 200) -> tuple[int, float, float, float]:
    """(violations, covered share of the exact stable area, exact seconds, sufficient seconds)."""
    team = grid(rows, cols)
    t = time.perf_counter()
    exact = stability_map(team, 1.0, 0.5, 4.0, 4.0)
    t_exact = time.perf_counter() - t
    t = time.perf_counter()
    m = safe_delays(1.0, 0.5, 4.0, 4.0, spectrum=spectrum_bound(team))
    t1, t2, safe = m.grid(resolution)
    t_suff = time.perf_counter() - t
    stable = exact.is_stable(*np.meshgrid(t1, t2))
    return int(np.sum(safe & ~stable)), float(np.sum(safe & stable) / np.sum(stable)), t_exact, t_suff


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--million", action="store_true", help="also the 1,000,000-agent grid (one run)")
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, numpy {np.__version__}, load {os.getloadavg()[0]:.2f}")  # fmt: skip
    runs = [sufficient_map(316, 317) for _ in range(args.repeats)]
    times = [r[0] for r in runs]
    print(f"100,172-agent grid, sufficient map over [0, 4]^2 (200 x 200): best {min(times):.2f} s, "
          f"median {np.median(times):.2f} s; safe fraction {runs[0][1]:.4f}; bound high end {runs[0][2]:.8f}")
    print("  stages of the median run:", {k: round(v, 2) for k, v in sorted(runs, key=lambda r: r[0])[len(runs) // 2][3].items()})
    if args.million:
        total, frac, high, stages = sufficient_map(1000, 1000)
        print(f"1,000,000-agent grid: {total:.2f} s, safe fraction {frac:.4f}, bound high end {high:.10f}, "
              f"stages {({k: round(v, 2) for k, v in stages.items()})}")
    bad, covered, t_exact, t_suff = coverage()
    print(f"400-agent grid: violations {bad}, covered {covered:.4f} of the exact stable area; "
          f"exact CTCR map {t_exact:.2f} s, sufficient map {t_suff:.2f} s")
    region = lambda_region(1.0, 0.5, 1.0, 2.0)
    x = np.linspace(-1.6, 1.6, 400)
    z = x[None, :] + 1j * x[:, None]
    ts = []
    for _ in range(args.repeats):
        t = time.perf_counter()
        lambda_region(1.0, 0.5, 1.0, 2.0).is_stable(z)
        ts.append(time.perf_counter() - t)
    print(f"is_stable on 160,000 eigenvalues: best {min(ts):.3f} s, median {np.median(ts):.3f} s "
          f"(stable share {np.mean(region.is_stable(z)):.4f})")


if __name__ == "__main__":
    main()
