"""Benchmark: robots with mass (``model="physics"``, MuJoCo) beside the kinematic model with the same limits.

Run with ``.venv/bin/python benchmarks/bench_physics.py [--repeat 3]`` (the ``physics`` extra).
Prints a markdown table for docs/benchmarks.md.

1. The paper's six robots (Fig. topol) as Create 3s (the ``create3`` profile:
   limits and chassis) from the start of examples/create3_hexagon.toml into
   its 1 m hexagon at (tau1, tau2) = (0.3, 0.2), P = 1, D = 1.5, for 60 s:
   physics (2 ms engine steps, 10 ms control ticks) and the kinematic
   saturated unicycle (dt 0.01). Goal: physics under 5 s.
2. 50 Create 3s on ``random_digraph(50, 0.1, seed=1)`` into an 8 x 7 grid of
   1 m spacing from the same grid twice as wide (random headings), 60 s, same
   two models. Goal: physics under 60 s.
3. Run 1 with the safety filter (``safety="barrier"``) on both models: what
   the filter costs on robots with mass. No goal.

Wall and CPU time (``time.process_time``) of each run; the machine is shared,
so the CPU time is the figure to read under load. Runs alternate between the
two models; medians and bests of ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from delayform.deploy.profiles import robot_profile
from delayform.formation import named_formation
from delayform.simulation import simulate
from delayform.simulation.models.robots import Robot
from delayform.topology import paper_six, random_digraph

RING = np.array([[4.0, 0.0], [2.0, 3.464], [-2.0, 3.464], [-4.0, 0.0], [-2.0, -3.464], [2.0, -3.464]])
HEADINGS = np.array([3.1416, -2.0944, -1.0472, 0.0, 1.0472, 2.0944])


def _grid(n: int, spacing: float) -> np.ndarray:
    cols = int(np.ceil(np.sqrt(n)))
    k = np.arange(n)
    return np.column_stack([k % cols, k // cols]) * spacing


def _cases():
    c3 = robot_profile("create3")
    six = dict(topology=paper_six(), formation=named_formation("hexagon", 6, spacing=1.0), initial_positions=RING, initial_headings=HEADINGS, D=1.5)
    start = _grid(50, 2.0) - 3.0  # a grid twice as wide, centred on the formation's
    headings = np.random.default_rng(3).uniform(-np.pi, np.pi, 50)
    fifty = dict(topology=random_digraph(50, 0.1, seed=1), formation=_grid(50, 1.0), initial_positions=start,
                 initial_headings=headings, D=1.5)  # fmt: skip
    return c3, (("the paper's six Create 3s, 60 s", six, 5.0, None), ("50 Create 3s, random digraph, 60 s", fifty, 60.0, None),
                ("the paper's six Create 3s with the safety filter, 60 s", six, None, "barrier"))  # fmt: skip


def _run(case: dict, robot: Robot) -> tuple[float, float, object]:
    wall, cpu = time.perf_counter(), time.process_time()
    kw = {k: v for k, v in case.items() if k not in ("topology", "formation", "D")}
    traj = simulate(case["topology"], 1.0, case["D"], 0.3, 0.2, case["formation"], robot=robot, seed=3,
                    duration=60.0, dt=0.01, **kw)  # fmt: skip
    return time.perf_counter() - wall, time.process_time() - cpu, traj


def _verdict(cpu: float, goal: float | None) -> str:
    """The goal and status columns."""
    if goal is None:
        return "none | -"
    return f"< {goal:g} s | {'met' if cpu < goal else 'not met'}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--case", type=int, action="append", help="run only these cases (1, 2, 3; default all)")
    args = parser.parse_args()
    c3, cases = _cases()
    print(f"load average at start: {os.getloadavg()[0]:.1f}")
    print("| run | physics CPU best / median (s) | wall median (s) | kinematic CPU best / median (s) | ratio | "
          "physics settles (s) | kinematic settles (s) | contacts | goal | status |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|")
    for number, (label, case, goal, safety) in enumerate(cases, start=1):
        if args.case and number not in args.case:
            continue
        physics = Robot(model="physics", limits=c3.limits, chassis=c3.chassis, safety=safety)
        kinematic = Robot(model="unicycle", limits=c3.limits, safety=safety)
        p_cpu, p_wall, k_cpu = [], [], []
        for _ in range(args.repeat):
            w, c, tp = _run(case, physics)
            p_cpu.append(c)
            p_wall.append(w)
            _, c, tk = _run(case, kinematic)
            k_cpu.append(c)
        pm, km = statistics.median(p_cpu), statistics.median(k_cpu)
        print(f"| {label} | {min(p_cpu):.2f} / {pm:.2f} | {statistics.median(p_wall):.2f} | "
              f"{min(k_cpu):.2f} / {km:.2f} | {pm / km:.2g}x | {tp.settling_time:.4g} | {tk.settling_time:.4g} | "
              f"{len(tp.contacts)} | {_verdict(pm, goal)} |")  # fmt: skip
    print(f"load average at end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
