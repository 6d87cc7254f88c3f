"""Benchmark: dominant-root maps and delayform's roots against qpmr (issue 4). Prints markdown tables.

1. A 100 x 100 dominant-root map of the paper's example (paper_six, P = 1,
   D = 0.5) over [0, 10]^2 with :func:`delayform.dominant_root_map`; goal
   < 2 s. Best and median of ``--repeat`` runs (the first run includes
   imports' warm-up).
2. The PyPI package ``qpmr`` (Python QPmR, Vyhlidal and Zitek 2009 — the
   method the paper used) on a seeded sample of the same grid points: each
   factor of eq. factorized is handed to ``qpmr.qpmr(coefs, delays,
   region=(-1, 1, 0, 3))`` (real coefficients, so Im >= 0 suffices; the
   centroid's zero removed) and the rightmost root over factors is compared
   with the map's dominant root at that point. Times: qpmr per grid point,
   delayform's single-point :func:`delayform.dominant_root` per point, and
   the map's time per point (amortized).

Run: ``.venv/bin/python benchmarks/bench_spectrum.py [--sample 24] [--repeat 3]``
(qpmr comes with the ``bench`` extra; it is never a run-time dependency).
"""

from __future__ import annotations

import argparse
import logging
import os
import platform
import statistics
import time
import warnings

import numpy as np

from delayform.characteristic import CharacteristicFactor, factors
from delayform.analysis.spectrum import dominant_root, dominant_root_map
from delayform.topology import paper_six

P, D = 1.0, 0.5
QPMR_REGION = (-1.0, 1.0, 0.0, 3.0)


def _qpmr_rows(f: CharacteristicFactor, tau1: float, tau2: float) -> tuple[np.ndarray, np.ndarray]:
    """qpmr's (coefs, delays): one row of increasing-power coefficients per delay."""
    terms = f.quasi_polynomial.terms()
    width = max(c.size for c, _, _ in terms)
    coefs = np.zeros((len(terms), width))
    delays = np.zeros(len(terms))
    for k, (c, a, b) in enumerate(terms):
        coefs[k, : c.size] = c.real
        delays[k] = a * tau1 + b * tau2
    return coefs, delays


def _qpmr_dominant(fs: tuple[CharacteristicFactor, ...], tau1: float, tau2: float) -> complex:
    import qpmr

    best = complex(-np.inf, 0.0)
    for f in fs:
        coefs, delays = _qpmr_rows(f, tau1, tau2)
        roots, _ = qpmr.qpmr(coefs, delays, region=QPMR_REGION)
        roots = np.asarray(roots, dtype=complex)
        if f.is_centroid:
            roots = roots[np.abs(roots) > 1e-6]
        if roots.size and roots.real.max() > best.real:
            best = complex(roots[np.argmax(roots.real)])
    return complex(best.real, abs(best.imag))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sample", type=int, default=24, help="grid points compared with qpmr")
    parser.add_argument("--repeat", type=int, default=3, help="runs of the 100 x 100 map")
    args = parser.parse_args()
    logging.getLogger("qpmr").setLevel(logging.ERROR)
    warnings.filterwarnings("ignore", module="numpy")  # qpmr's casts of complex arrays

    team = paper_six()
    fs = factors(team, P, D)
    grid = np.linspace(0.0, 10.0, 100)
    times = []
    dmap = None
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        dmap = dominant_root_map(team, P, D, grid, grid)
        times.append(time.perf_counter() - t0)
    assert dmap is not None
    best, median = min(times), statistics.median(times)
    per_point_map = best / grid.size**2

    print(f"machine: {os.cpu_count()} cores, {platform.python_version()}, {platform.platform()}")
    print()
    print("| case | grid | best (s) | median (s) | per point (ms) | stable fraction | goal | status |")
    print("|---|---|---|---|---|---|---|---|")
    status = "met" if best < 2.0 else "NOT met"
    print(
        f"| paper example, [0, 10]^2 | 100 x 100 | {best:.2f} | {median:.2f} | "
        f"{1e3 * per_point_map:.3f} | {dmap.stable.mean():.3f} | < 2 s | {status} |"
    )

    if args.sample <= 0:
        return
    rng = np.random.default_rng(20261123)
    idx = rng.integers(0, grid.size, size=(args.sample, 2))
    qpmr_times, single_times, diffs = [], [], []
    for i, j in idx:
        t1, t2 = float(grid[i]), float(grid[j])
        t0 = time.perf_counter()
        want = _qpmr_dominant(fs, t1, t2)
        qpmr_times.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        single = dominant_root(team, P, D, t1, t2).root
        single_times.append(time.perf_counter() - t0)
        diffs.append(max(abs(dmap.roots[i, j] - want), abs(single - want)))
    q_mean, q_med, q_max = np.mean(qpmr_times), np.median(qpmr_times), np.max(qpmr_times)
    s_med = float(np.median(single_times))
    print()
    print(f"qpmr on {args.sample} seeded grid points of the same map (region {QPMR_REGION}, all 5 factors):")
    print()
    print("| method | mean per point (ms) | median (ms) | max (ms) | speed-up vs qpmr (mean / median) |")
    print("|---|---|---|---|---|")
    print(f"| qpmr 0.1.0 | {1e3 * q_mean:.1f} | {1e3 * q_med:.1f} | {1e3 * q_max:.1f} | 1 / 1 |")
    s_mean = float(np.mean(single_times))
    print(
        f"| delayform dominant_root (one point) | {1e3 * s_mean:.1f} | {1e3 * s_med:.1f} | "
        f"{1e3 * np.max(single_times):.1f} | {q_mean / s_mean:.0f}x / {q_med / s_med:.0f}x |"
    )
    print(
        f"| delayform dominant_root_map (amortized) | {1e3 * per_point_map:.3f} | - | - | "
        f"{q_mean / per_point_map:.0f}x / {q_med / per_point_map:.0f}x |"
    )
    print()
    print(f"largest |delayform - qpmr| over the sample: {max(diffs):.2e}")


if __name__ == "__main__":
    main()
