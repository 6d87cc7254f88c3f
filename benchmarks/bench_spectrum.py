"""Benchmark: dominant roots against qpmr, side by side in one run (issues 4 and 13). Prints markdown.

1. ``qpmr`` (Python QPmR, Vyhlidal and Zitek 2009 -- the method the paper
   used; the ``bench`` extra, never a run-time dependency) at the paper's
   points a, b, c (paper_six, P = 1, D = 0.5): each factor of eq. factorized
   is handed to ``qpmr.qpmr(coefs, delays, region=(-1, 1, 0, 3))`` (real
   coefficients, so Im >= 0 suffices; the centroid's zero removed) and the
   rightmost root over factors kept. Best and median of ``--repeat`` calls
   per point.
2. :func:`delayform.dominant_root` at the same points, same repeats.
3. A 100 x 100 :func:`delayform.dominant_root_map` of the same team over
   [0, 8]^2, certified at every point; per pair = map time / 10,000.
   Goal (issue 13): per pair at least 1000x faster than qpmr at a, b, c, and
   a single ``dominant_root`` at least 20x faster than qpmr at that pair.
4. Agreement: ``dominant_root`` against qpmr at a, b, c, and the map against
   qpmr at ``--sample`` seeded grid points.

The machine is shared (other jobs run on its two cores): the load average is
printed with the tables; medians are the figures to trust.

Run: ``.venv/bin/python benchmarks/bench_spectrum.py [--sample 24] [--repeat 7]``.
"""

from __future__ import annotations

import argparse
import logging
import os
import platform
import statistics
import time
import warnings
from collections.abc import Callable

import numpy as np

from delayform.analysis.spectrum import dominant_root, dominant_root_map
from delayform.characteristic import CharacteristicFactor, factors
from delayform.topology import paper_six

P, D = 1.0, 0.5
QPMR_REGION = (-1.0, 1.0, 0.0, 3.0)
POINTS = {"a": (0.3, 0.2), "b": (2.0, 1.0), "c": (1.0, 2.0)}


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


def _timed(fn: Callable[[], object], repeat: int) -> tuple[float, float, object]:
    """(best, median) wall time in seconds over ``repeat`` calls, and the last result."""
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), statistics.median(times), out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sample", type=int, default=24, help="grid points of the map compared with qpmr")
    parser.add_argument("--repeat", type=int, default=7, help="repeats of every timing")
    args = parser.parse_args()
    logging.getLogger("qpmr").setLevel(logging.ERROR)
    warnings.filterwarnings("ignore", module="numpy")  # qpmr's casts of complex arrays

    team = paper_six()
    fs = factors(team, P, D)
    grid = np.linspace(0.0, 8.0, 100)
    dominant_root_map(team, P, D, grid[:4], grid[:4])  # warm-up (imports, caches of Chebyshev nodes)
    _qpmr_dominant(fs, *POINTS["a"])

    rows, q_meds, q_bests, s_meds, diffs = [], [], [], [], []
    for name, (t1, t2) in POINTS.items():
        q_best, q_med, want = _timed(lambda t1=t1, t2=t2: _qpmr_dominant(fs, t1, t2), args.repeat)
        s_best, s_med, got = _timed(lambda t1=t1, t2=t2: dominant_root(team, P, D, t1, t2), args.repeat)
        diff = abs(got.root - want)  # type: ignore[union-attr]
        rows.append((name, t1, t2, q_best, q_med, s_best, s_med, diff))
        q_meds.append(q_med)
        q_bests.append(q_best)
        s_meds.append(s_med)
        diffs.append(diff)
    m_best, m_med, dmap = _timed(lambda: dominant_root_map(team, P, D, grid, grid), args.repeat)
    assert dmap is not None
    per_pair_best, per_pair_med = m_best / grid.size**2, m_med / grid.size**2
    q_ref = statistics.median(q_meds)

    load = os.getloadavg()
    print(f"machine: {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}; "
          f"load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (1 / 5 / 15 min; shared with other jobs)")
    print()
    print("| point (tau1, tau2) | qpmr best (ms) | qpmr median (ms) | dominant_root best (ms) | "
          "dominant_root median (ms) | speed-up (median) | goal | |delayform - qpmr| |")
    print("|---|---|---|---|---|---|---|---|")
    for name, t1, t2, qb, qm, sb, sm, diff in rows:
        ok = "met" if qm / sm >= 20 else "NOT met"
        print(f"| {name} ({t1:g}, {t2:g}) | {1e3 * qb:.1f} | {1e3 * qm:.1f} | {1e3 * sb:.2f} | {1e3 * sm:.2f} | "
              f"{qm / sm:.0f}x | >= 20x ({ok}) | {diff:.1e} |")
    print()
    ratio_med = q_ref / per_pair_med
    ratio_best = min(q_bests) / per_pair_best
    status = "met" if ratio_med >= 1000 else "NOT met"
    print("| dominant_root_map, paper team, [0, 8]^2 | grid | best (s) | median (s) | per pair best / median (ms) | "
          "speed-up vs qpmr at a, b, c (median / best) | goal | stable fraction |")
    print("|---|---|---|---|---|---|---|---|")
    print(f"| certified at every point | 100 x 100 | {m_best:.3f} | {m_med:.3f} | "
          f"{1e3 * per_pair_best:.4f} / {1e3 * per_pair_med:.4f} | {ratio_med:.0f}x / {ratio_best:.0f}x | "
          f">= 1000x ({status}) | {dmap.stable.mean():.3f} |")

    if args.sample > 0:
        rng = np.random.default_rng(20261123)
        idx = rng.integers(0, grid.size, size=(args.sample, 2))
        for i, j in idx:
            want = _qpmr_dominant(fs, float(grid[i]), float(grid[j]))
            diffs.append(abs(dmap.roots[i, j] - want))
        print()
        print(f"largest |delayform - qpmr| at a, b, c and {args.sample} seeded grid points of the map: "
              f"{max(diffs):.1e} (goal 1e-9)")


if __name__ == "__main__":
    main()
