"""Benchmark: robots with bodies (issue 21): the safety filter for 200 robots, the cost of contacts.

Run with ``.venv/bin/python benchmarks/bench_bodies.py``; prints markdown for docs/benchmarks.md
(about three minutes on two shared cores).

1. 200 ideal unicycle robots (iRobot Create bodies, radius 0.17 m) on
   ``random_digraph(200, 0.05, seed=1)`` at (tau1, tau2) = (0.3, 0.2) (stable:
   dominant root -0.082 +- 0.968i; with p = 3 / 200 it is +0.039 +- 0.973i),
   P = 1, D = 0.5, dt = 0.05, over 100 s (goal: under 60 s with
   ``safety="barrier"``). They start apart at random (a shuffled grid of
   1.5 m cells, jittered by up to 0.3 m, seeded) and close into a block of
   spacing 1 m, taking the slots nearest their predicted end positions
   (``assignment="optimal"``, as a real team would): neighbours come within
   a body's width of each other on the way, so the filter acts. Reported
   with and without the filter: wall time, contacts, closest approach,
   status (deadlock included), settling time, the fraction of saved steps
   at which the filter acted and those at which a robot was squeezed.
   The same team taking its slots in index order (random slots: robots cross
   the block and a fifth of the steps squeeze some robot, so the joint QP
   dominates), ``--random-repeat`` runs (default 1).
2. The paper's six robots at point a (hexagon of side 2, 150 s, dt 0.01),
   with and without the filter.
3. What the exact closest approach and contacts add to a run without the
   filter (goal: under 10 %): :func:`delayform.simulation.closest_approach`
   timed alone on the saved trajectory, against the rest of the
   ``simulate`` call, for the runs above, for the 200 robots taking random
   slots (thousands of contacts in a stable run) and for 200 robots piling
   up (ring, polygon, 20 s, dt 0.01: an unstable point, the run diverges
   and robots fly past each other at km/s).
Each timing is the median and the best of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from delayform.simulation import closest_approach, simulate
from delayform.topology import paper_six, random_digraph, ring


def _timed(fn: Callable[[], Any], repeat: int) -> tuple[float, float, Any]:
    times, out = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), min(times), out


def scattered_start(n: int, seed: int, cell: float = 1.5) -> np.ndarray:
    """Robots on a shuffled grid of ``cell`` m cells, jittered by up to 0.3 m: apart, at random."""
    rng = np.random.default_rng(seed)
    side = math.ceil(math.sqrt(n))
    cells = np.array([(a, b) for a in range(side) for b in range(side)], dtype=float)[rng.permutation(side * side)[:n]]
    return cell * (cells - side / 2) + rng.uniform(-0.3, 0.3, (n, 2))


def _settle(tr: Any) -> str:
    return f"{tr.settling_time:.1f}" if math.isfinite(tr.settling_time) else "-"


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--random-repeat", type=int, default=1, help="repeats of the random-slot run (slowest)")
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
          f"load average {os.getloadavg()[0]:.1f} at the start (shared machine)")  # fmt: skip
    team = random_digraph(200, 0.05, seed=1)  # stable at (0.3, 0.2): dominant root -0.082 +- 0.968i
    big = dict(duration=100.0, dt=0.05, seed=1, initial_positions=scattered_start(200, 1), assignment="optimal")
    paper = dict(duration=150.0, dt=0.01)
    runs = {
        "200 robots, 100 s, dt 0.05": lambda s: simulate(team, 1.0, 0.5, 0.3, 0.2, "block", safety=s, **big),
        "200 robots, random slots, 100 s, dt 0.05": lambda s: simulate(
            team, 1.0, 0.5, 0.3, 0.2, "block", safety=s, **{**big, "assignment": "given"}),
        "paper, point a, 150 s, dt 0.01": lambda s: simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", safety=s, **paper),
    }  # fmt: skip
    print("\n| run | filter | wall time median / best (s) | contacts | closest (m) | status | settles (s) "
          "| filter acted | squeezed |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    bare: dict[str, Any] = {}
    for name, run in runs.items():
        for safety in (None, "barrier"):
            med, best, tr = _timed(lambda: run(safety), args.random_repeat if "random" in name else args.repeat)
            if safety is None:
                bare[name] = tr
            rep = tr.safety
            acted = "-" if rep is None else f"{rep.active_fraction:.1%} of steps"
            squeezed = "-" if rep is None else f"{rep.infeasible.any(axis=1).mean():.1%} of steps"
            print(f"| {name} | {safety or 'none'} | {med:.2f} / {best:.2f} | {len(tr.contacts)} | "
                  f"{tr.min_distance:.3f} | {tr.status} | {_settle(tr)} | {acted} | {squeezed} |")  # fmt: skip

    print("\n| run without the filter | simulate median / best (s) | closest_approach median / best (s) | "
          "added to the rest of the run (best) |")  # fmt: skip
    print("|---|---|---|---|")
    pile = lambda: simulate(ring(200), 1.0, 0.5, 0.3, 0.2, "polygon", duration=20.0, dt=0.01)  # noqa: E731
    crowd = dict(big, assignment="given")  # random slots: robots cross the block, thousands of contacts
    cases = [(name, lambda name=name: runs[name](None)) for name in runs if "random" not in name] + [
        ("200 robots, random slots, 100 s, dt 0.05", lambda: simulate(team, 1.0, 0.5, 0.3, 0.2, "block", **crowd)),
        ("200 robots piling up, ring, 20 s, dt 0.01 (diverging: root +0.317 +- 0.835i)", pile),
    ]
    for name, run in cases:
        med, best, tr = _timed(run, args.repeat)
        a_med, a_best, found = _timed(
            lambda: closest_approach(tr.times, tr.positions, tr.velocities, 2 * tr.radius), args.repeat
        )
        assert found.min_distance == tr.min_distance
        print(f"| {name} ({len(tr.contacts)} contacts) | {med:.3f} / {best:.3f} | {a_med:.4f} / {a_best:.4f} | "
              f"{a_best / max(best - a_best, 1e-9):.1%} |")  # fmt: skip


if __name__ == "__main__":
    main()
