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

from delayform.analysis.roots.dominant import dominant_root, dominant_root_map
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


def _clock(fn: Callable[[], object]) -> tuple[float, float, object]:
    """(wall, process CPU) seconds of one call, and its result."""
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - w0, time.process_time() - c0, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sample", type=int, default=24, help="grid points of the map compared with qpmr")
    parser.add_argument("--repeat", type=int, default=7, help="interleaved repeats of every timing")
    args = parser.parse_args()
    logging.getLogger("qpmr").setLevel(logging.ERROR)
    warnings.filterwarnings("ignore", module="numpy")  # qpmr's casts of complex arrays

    team = paper_six()
    fs = factors(team, P, D)
    grid = np.linspace(0.0, 8.0, 100)
    dominant_root_map(team, P, D, grid[:4], grid[:4])  # warm-up (imports, caches of Chebyshev nodes)
    _qpmr_dominant(fs, *POINTS["a"])

    # Interleaved: every repeat times qpmr and delayform at a, b, c and the map back to back,
    # so load from other jobs on the shared machine hits both alike.
    q_t: dict[str, list[tuple[float, float]]] = {k: [] for k in POINTS}
    s_t: dict[str, list[tuple[float, float]]] = {k: [] for k in POINTS}
    m_t: list[tuple[float, float]] = []
    diffs: list[float] = []
    dmap = None
    for _ in range(args.repeat):
        for name, (t1, t2) in POINTS.items():
            w, c, want = _clock(lambda t1=t1, t2=t2: _qpmr_dominant(fs, t1, t2))
            q_t[name].append((w, c))
            w, c, got = _clock(lambda t1=t1, t2=t2: dominant_root(team, P, D, t1, t2))
            s_t[name].append((w, c))
            diffs.append(abs(got.root - want))  # type: ignore[union-attr, operator]
        w, c, dmap = _clock(lambda: dominant_root_map(team, P, D, grid, grid))
        m_t.append((w, c))
    assert dmap is not None

    def med(xs: list[tuple[float, float]], k: int) -> float:
        return statistics.median(x[k] for x in xs)

    def best(xs: list[tuple[float, float]], k: int) -> float:
        return min(x[k] for x in xs)

    load = os.getloadavg()
    print(f"machine: {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}; "
          f"load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (1 / 5 / 15 min; shared with other jobs)")
    print(f"{args.repeat} interleaved repeats; medians of wall time (and of process CPU time, less "
          "sensitive to the other jobs); best = fastest repeat; goals judged on the median CPU times")
    print()
    print("| point (tau1, tau2) | qpmr wall (CPU) ms | dominant_root wall (CPU) ms | speed-up wall (CPU) | "
          "best: qpmr / dominant_root CPU ms, speed-up | goal |")
    print("|---|---|---|---|---|---|")
    for name, (t1, t2) in POINTS.items():
        qw, qc, sw, sc = med(q_t[name], 0), med(q_t[name], 1), med(s_t[name], 0), med(s_t[name], 1)
        qb, sb = best(q_t[name], 1), best(s_t[name], 1)
        ok = "met" if qc / sc >= 20 else "NOT met"
        print(f"| {name} ({t1:g}, {t2:g}) | {1e3 * qw:.1f} ({1e3 * qc:.1f}) | {1e3 * sw:.2f} ({1e3 * sc:.2f}) | "
              f"{qw / sw:.0f}x ({qc / sc:.0f}x) | {1e3 * qb:.1f} / {1e3 * sb:.2f}, {qb / sb:.0f}x | >= 20x ({ok}) |")
    q_w = statistics.median(med(q_t[k], 0) for k in POINTS)
    q_c = statistics.median(med(q_t[k], 1) for k in POINTS)
    mw, mc = med(m_t, 0), med(m_t, 1)
    pw, pc = mw / grid.size**2, mc / grid.size**2
    status = "met" if q_c / pc >= 1000 else "NOT met"
    q_best = statistics.median(best(q_t[k], 1) for k in POINTS)
    m_best = best(m_t, 1)
    print()
    print("| dominant_root_map, paper team, [0, 8]^2, certified at every point | wall (CPU) s | per pair wall (CPU) ms | "
          "speed-up vs qpmr at a, b, c, wall (CPU) | best CPU s, speed-up vs qpmr's best | goal | stable fraction |")
    print("|---|---|---|---|---|---|---|")
    print(f"| 100 x 100 | {mw:.3f} ({mc:.3f}) | {1e3 * pw:.4f} ({1e3 * pc:.4f}) | {q_w / pw:.0f}x ({q_c / pc:.0f}x) | "
          f"{m_best:.3f}, {q_best / (m_best / grid.size**2):.0f}x | >= 1000x ({status}) | {dmap.stable.mean():.3f} |")

    if args.sample > 0:
        rng = np.random.default_rng(20261123)
        idx = rng.integers(0, grid.size, size=(args.sample, 2))
        ratios, q_pt, s_pt = [], [], []
        for i, j in idx:
            t1, t2 = float(grid[i]), float(grid[j])
            _, qc, want = _clock(lambda t1=t1, t2=t2: _qpmr_dominant(fs, t1, t2))
            _, sc, got = _clock(lambda t1=t1, t2=t2: dominant_root(team, P, D, t1, t2))
            diffs.append(abs(dmap.roots[i, j] - want))  # type: ignore[operator]
            diffs.append(abs(got.root - want))  # type: ignore[union-attr, operator]
            ratios.append(qc / sc)
            q_pt.append(qc)
            s_pt.append(sc)
        print()
        print(f"{args.sample} seeded grid points of the map, one call each, interleaved (the points a sweep "
              f"visits, larger delays than a, b, c): qpmr median {1e3 * statistics.median(q_pt):.1f} ms CPU, "
              f"dominant_root median {1e3 * statistics.median(s_pt):.2f} ms; speed-up per point: median "
              f"{statistics.median(ratios):.0f}x, lowest {min(ratios):.0f}x")
        print(f"largest |delayform - qpmr| at a, b, c and at those points (map and dominant_root): "
              f"{max(diffs):.1e} (goal 1e-9)")


if __name__ == "__main__":
    main()
