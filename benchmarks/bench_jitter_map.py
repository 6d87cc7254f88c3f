"""Benchmark: the jitter-margin map on the chart and bursty loss in the mean square (issue 20). Prints markdown.

Parts
-----
1. ``jitter_margin_map`` of the paper's team over [0, 3] x [0, 3] s (cell centres,
   as the chart overlay and the explorer's layer), 8 x 8 and 16 x 16: wall time,
   certified points, time per certified point; peer: the point certificate
   ``jitter_margin`` called at every grid point (its own nominal root by the 2N-state
   discretization), on the 8 x 8 grid. The two agree to the last digit (checked here).
2. The explorer's ``/api/jitter_map`` (12 x 12, the default): first request and a cached one.
3. ``bursty_mean_square_stability`` (Gilbert-Elliott, p_gb = 0.1, p_bg = 0.3, rate 10/s):
   a 3-agent ring (3 links, 64 modes) and a 3-agent star (4 links, 256 modes): time and rho;
   and the ring's exact E|disagreement|^2 against the simulator's Monte Carlo (40 runs, dt = 0.01 s)
   with its 95 % interval, beside the Bernoulli prediction at the same loss rate.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_jitter_map.py [--quick]`` (about 2 minutes;
--quick: 30 s). The machine may be shared: the load average is printed.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import urllib.request

import numpy as np

from delayform.analysis.network import bursty_mean_square_stability, jitter_margin, jitter_margin_map, mean_square_stability
from delayform.formation import named_formation
from delayform.simulation import simulate
from delayform.model.network import GilbertElliott, Network, Sampling
from delayform.topology import paper_six, ring, star


def _timed(f, repeats: int) -> tuple[float, float, object]:
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return float(np.median(times)), float(min(times)), out


def maps(quick: bool) -> None:
    print("\n### 1. Jitter-margin map, paper's team, [0, 3] x [0, 3] s\n")
    print("| grid | method | median (s) | best (s) | certified points | ms per certified point |")
    print("|---|---|---|---|---|---|")
    for n in (8,) if quick else (8, 16):
        g = (np.arange(n) + 0.5) * 3.0 / n
        med, best, m = _timed(lambda g=g: jitter_margin_map(paper_six(), 1.0, 0.5, g, g), 1 if n > 8 or quick else 3)
        k = int(np.count_nonzero(m.delta > 0))
        print(f"| {n} x {n} | jitter_margin_map | {med:.2f} | {best:.2f} | {k} | {1e3 * best / max(k, 1):.0f} |")
        if n == 8:
            t = time.perf_counter()
            pts = np.array([[jitter_margin(paper_six(), 1.0, 0.5, a, b).delta for b in g] for a in g])
            peer = time.perf_counter() - t
            assert np.array_equal(pts, m.delta), "the map and the point certificate disagree"
            print(f"| {n} x {n} | peer: jitter_margin at every point | {peer:.2f} | {peer:.2f} | {k} | {1e3 * peer / max(k, 1):.0f} |")


def explorer(quick: bool) -> None:
    from delayform.app import Explorer, start
    from delayform.scenario import paper_scenario

    print("\n### 2. Explorer layer /api/jitter_map (12 x 12, chart window [0, 3] x [0, 3])\n")
    with start(Explorer(paper_scenario(), out_dir="/tmp/bench_jitter_map_unused")) as r:
        url = f"{r.url}api/jitter_map?tau1_max=3&tau2_max=3&grid=12"
        rows = []
        for what in ("first request", "cached"):
            t = time.perf_counter()
            with urllib.request.urlopen(url, timeout=300) as resp:
                body = json.loads(resp.read())
            rows.append((what, time.perf_counter() - t))
    print("| request | time (s) |\n|---|---|")
    for what, sec in rows:
        print(f"| {what} | {sec:.3f} |")
    print(f"\nlargest certified delta {body['largest']:.4f} s at {body['largest_at']}")


def bursty(quick: bool) -> None:
    print("\n### 3. Gilbert-Elliott loss in the mean square (p_gb = 0.1, p_bg = 0.3, rate 10/s)\n")
    print("| team | links | modes | time (s) | rho per period | decay rate (1/s) | Bernoulli rho at the same loss rate |")
    print("|---|---|---|---|---|---|---|")
    for name, team, D in (("ring(3)", ring(3), 1.0), ("star(3)", star(3), 1.0)):
        med, best, r = _timed(lambda team=team, D=D: bursty_mean_square_stability(
            team, 1.0, D, 0.2, 0.1, rate=10.0, p_good_to_bad=0.1, p_bad_to_good=0.3), 1 if quick else 3)
        links = int(team.C_sparse.nnz)
        bern = mean_square_stability(team, 1.0, D, 0.2, 0.1, rate=10.0, loss=0.25).rho
        print(f"| {name} | {links} | {2 ** (2 * links)} | {best:.2f} | {r.rho:.5f} | {r.decay_rate:.4f} | {bern:.5f} |")
    shape = named_formation("polygon", 3, spacing=2.0)
    x0 = np.array([[-3.0, 1.0], [2.0, 3.0], [0.5, -2.5]])
    r = bursty_mean_square_stability(ring(3), 1.0, 1.0, 0.2, 0.1, rate=10.0, p_good_to_bad=0.1, p_bad_to_good=0.3)
    exact = r.disagreement(x0 - shape, steps=100)
    bern = mean_square_stability(ring(3), 1.0, 1.0, 0.2, 0.1, rate=10.0, loss=0.25).disagreement(x0 - shape, steps=100)
    runs = []
    for s in range(10 if quick else 40):
        tr = simulate(ring(3), 1.0, 1.0, 0.2, 0.1, shape, model="double_integrator", initial_positions=x0,
                      initial_speed=0.0, duration=10.0, dt=0.01, save_every=10,
                      network=Network(sampling=Sampling(10.0), loss=GilbertElliott(0.1, 0.3), seed=s))  # fmt: skip
        y = tr.positions - shape[None]
        runs.append(((y - y.mean(axis=1, keepdims=True)) ** 2).sum(axis=(1, 2)))
    runs_a = np.array(runs)
    mean, half = runs_a.mean(0), 1.96 * runs_a.std(0, ddof=1) / np.sqrt(len(runs))
    print(f"\nring(3), E|disagreement|^2 (m^2), {len(runs)} Monte Carlo runs:\n")
    print("| t (s) | exact (bursty) | Monte Carlo mean +- 95 % | Bernoulli at loss 0.25 |\n|---|---|---|---|")
    for k in (10, 20, 40, 60, 100):
        print(f"| {k / 10:g} | {exact[k]:.4g} | {mean[k]:.4g} +- {half[k]:.2g} | {bern[k]:.4g} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    quick = parser.parse_args().quick
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, {platform.python_version()}; "
          f"load average {os.getloadavg()[0]:.2f} (shared machine); {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}")  # fmt: skip
    maps(quick)
    explorer(quick)
    bursty(quick)


if __name__ == "__main__":
    main()
