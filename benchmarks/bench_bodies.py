"""Benchmark: robots with bodies (issue 21): the safety filter for 200 robots, the cost of contacts.

Run with ``.venv/bin/python benchmarks/bench_bodies.py``; prints markdown for docs/benchmarks.md.

1. 200 ideal unicycle robots (iRobot Create bodies, radius 0.17 m) on
   ``random_digraph(200, 3 / 200, seed=1)`` at (tau1, tau2) = (0.3, 0.2),
   P = 1, D = 0.5, from the seeded random start into a block of spacing 1 m,
   over 100 s with dt = 0.05: wall time with ``safety="barrier"`` (goal:
   under 60 s) and without, contacts and closest approach of both.
2. What the exact closest approach and contacts add to a run without the
   filter (goal: under 10 %): :func:`delayform.simulation.closest_approach`
   timed alone on the saved trajectory, against the whole ``simulate`` call,
   for the paper's six robots at point a (150 s, dt = 0.01, every step saved)
   and for the 200 robots above.
Each timing is the median of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

from delayform.simulation import closest_approach, simulate
from delayform.topology import paper_six, random_digraph


def _timed(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
          f"load average {os.getloadavg()[0]:.1f} at the start (shared machine)")  # fmt: skip
    team = random_digraph(200, 3.0 / 200, seed=1)
    kw = dict(duration=100.0, dt=0.05, seed=1)
    rows = []
    for safety in (None, "barrier"):
        sec, tr = _timed(lambda: simulate(team, 1.0, 0.5, 0.3, 0.2, "block", safety=safety, **kw), args.repeat)
        active = "" if tr.safety is None else f"{tr.safety.active_fraction:.1%} of steps"
        rows.append((safety or "none", sec, len(tr.contacts), tr.min_distance, tr.status, active))
    print("\n| 200 robots, 100 s, dt 0.05 | wall time (s) | contacts | closest approach (m) | status | filter active |")
    print("|---|---|---|---|---|---|")
    for name, sec, contacts, closest, status, active in rows:
        print(f"| safety = {name} | {sec:.1f} | {contacts} | {closest:.3f} | {status} | {active} |")

    print("\n| run | simulate (s) | closest_approach (s) | share |")
    print("|---|---|---|---|")
    cases = [
        ("paper, point a, 150 s, dt 0.01", lambda: simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon",
                                                            duration=150.0, dt=0.01)),
        ("200 robots, 100 s, dt 0.05", lambda: simulate(team, 1.0, 0.5, 0.3, 0.2, "block", **kw)),
    ]  # fmt: skip
    for name, run in cases:
        sec, tr = _timed(run, args.repeat)
        alone, _ = _timed(lambda: closest_approach(tr.times, tr.positions, tr.velocities, 2 * tr.radius), args.repeat)
        print(f"| {name} | {sec:.3f} | {alone:.3f} | {alone / sec:.1%} |")


if __name__ == "__main__":
    main()
