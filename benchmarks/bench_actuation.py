"""Benchmark: the cost of an actuation delay (issue 21, item 4) in the analysis and the simulation.

Prints markdown: median process CPU time (and wall time) of, with tau_a = 0
(today's fast paths) and tau_a = 0.3 s (every factor in three delays):

* ``dominant_root(paper_six(), 1, 0.5, 0.3, 0.2, actuation_delay=tau_a)``;
* ``stability_map(paper_six(), 1, 0.5, 8, 8, actuation_delay=tau_a)`` and NU on a 200 x 200 grid;
* ``simulate`` of the six double integrators for 60 s at dt = 0.01 (the linear
  fast path without actuation delay, the generic loop with its command buffer with it);
* ``dominant_root_map`` on the paper's map grid, 81 x 81 over [0, 8] x [0, 8] s (the
  vectorized family with continuation, at tau_a = 0 and in three delays);
* ``simulate`` with the safety filter (the filter at the state predicted tau_a ahead);

and, at tau_a = 0.3 s, the map of a 21 x 21 grid by the family against the same grid
point by point with ``dominant_root`` (each point certified on its own: the peer the
family replaces).

The peer figure is tau_a = 0, the same library's paper model. No goal was
set by the issue; the figures say what the three-delay path costs. The
machine is shared (other jobs run on its two cores): the load average is
printed; medians are the figures to trust.

Run: ``.venv/bin/python benchmarks/bench_actuation.py [--repeat 5]``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

import numpy as np

from delayform.analysis.ctcr.stability_map import stability_map
from delayform.analysis.roots.dominant import dominant_root, dominant_root_map
from delayform.simulation import simulate
from delayform.simulation.models.robots import Robot
from delayform.topology import paper_six


#: six robots on a line 1 m apart: they collide unfiltered, so the filter acts
_LINE = np.column_stack([np.arange(6.0), np.zeros(6)])


def _measure(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    cpu, wall = [], []
    for _ in range(repeat):
        c0, w0 = time.process_time(), time.perf_counter()
        fn()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    return statistics.median(cpu), statistics.median(wall)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    repeat = parser.parse_args().repeat
    top = paper_six()
    grid = np.linspace(0.02, 7.98, 200)

    def chart(ta: float) -> None:
        stability_map(top, 1.0, 0.5, 8.0, 8.0, actuation_delay=ta).unstable_count(grid[None, :], grid[:, None])

    cases = {
        "dominant_root at point a": lambda ta: dominant_root(top, 1.0, 0.5, 0.3, 0.2, actuation_delay=ta),
        "stability_map 8 x 8 s + NU on 200 x 200": chart,
        "simulate 6 double integrators, 60 s, dt 0.01": lambda ta: simulate(
            top, 1.0, 0.5, 0.3, 0.2, "hexagon", model="double_integrator", duration=60.0, dt=0.01,
            actuation_delay=ta),
        "dominant_root_map 81 x 81 over [0, 8]^2 s": lambda ta: dominant_root_map(
            top, 1.0, 0.5, np.linspace(0.0, 8.0, 81), np.linspace(0.0, 8.0, 81), actuation_delay=ta),
        "simulate + safety filter, 6 double integrators, 30 s": lambda ta: simulate(
            top, 1.0, 0.5, 0.3, 0.2, "hexagon", duration=30.0, dt=0.01, initial_positions=_LINE, initial_speed=0.0,
            robot=Robot(model="double_integrator", radius=0.17, safety="barrier", actuation_delay=ta)),
    }  # fmt: skip
    print(f"load average {os.getloadavg()[0]:.2f} (2 cores, shared)\n")
    print("| task | tau_a = 0: CPU s (wall) | tau_a = 0.3 s: CPU s (wall) | ratio |")
    print("|---|---|---|---|")
    for name, fn in cases.items():
        fn(0.0), fn(0.3)  # warm caches and imports
        base = _measure(lambda fn=fn: fn(0.0), repeat)
        late = _measure(lambda fn=fn: fn(0.3), repeat)
        print(f"| {name} | {base[0]:.3f} ({base[1]:.3f}) | {late[0]:.3f} ({late[1]:.3f}) | {late[0] / base[0]:.1f}x |")
    ax = np.linspace(0.0, 4.0, 21)
    family = _measure(lambda: dominant_root_map(top, 1.0, 0.5, ax, ax, actuation_delay=0.3), repeat)
    single = _measure(lambda: [dominant_root(top, 1.0, 0.5, a, b, actuation_delay=0.3) for a in ax for b in ax], 1)
    print("\n| 21 x 21 grid over [0, 4]^2 s at tau_a = 0.3 s | CPU s (wall) |")
    print("|---|---|")
    print(f"| dominant_root_map (the family, continuation) | {family[0]:.3f} ({family[1]:.3f}) |")
    print(f"| dominant_root at every point (peer, one run) | {single[0]:.3f} ({single[1]:.3f}) |")
    print(f"| ratio | {single[0] / family[0]:.1f}x |")


if __name__ == "__main__":
    main()
