"""Benchmark: the team's margin for delays varying together, per mode (Lyapunov-Krasovskii), at the paper's point b.

Beside it: the small-gain margin (per link, ``jitter_margin``), the smallest deviation at which a
greedy bang-bang switching adversary destabilizes each mode (delays varying together: each step
h1, h2 in {tau - A, tau + A}, whichever pumps energy into the mode; own semi-implicit Euler,
dt = 0.005 s, 240 s, bisection), the same for the stronger family of weighted energies, the smallest
deviation (on the grid of dt = 0.005 s, every delay inside the interval) at which a periodic signal is
proved destabilizing by its Floquet multiplier (the greedy signals' periods refined by the maximum
principle, ``periodic_switching_adversary``; its growth rate re-checked by Runge-Kutta at dt / 4,
``replay_growth_rate``; for the limiting mode also the grid point below at dt = 0.0025 s), and the
smallest constant offset (2 +- d, 1 +- d) that is unstable by the exact spectrum of the factors
(rightmost roots on the square's boundary, bisection).

Run: ``OMP_NUM_THREADS=1 python benchmarks/bench_team_certificates.py [--repeat 3] [--max-order 3]
[--upper-cuts] [--cover-intervals] [--rtol 0.02] [--no-adversary]`` (the options are those of ``team_delay_margin``).
The machine is shared: the load average is printed, with medians and bests.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from delayform.analysis.certificates.adversary import (
    SwitchingSignal,
    greedy_switching_grows,
    periodic_switching_adversary,
    replay_growth_rate,
    weighted_switching_grows,
)
from delayform.analysis.certificates.team import team_delay_margin
from delayform.analysis.network import jitter_margin
from delayform.analysis.roots.single import rightmost_root
from delayform.characteristic import factors
from delayform.topology import paper_six

T1, T2, P, D = 2.0, 1.0, 1.0, 0.5


def grows(lam: float, A: float) -> bool:
    return greedy_switching_grows(lam, P, D, T1, T2, A)


def grows_weighted(lam: float, A: float) -> bool:
    return weighted_switching_grows(lam, P, D, T1, T2, A)


def periodic_threshold(lam: float, dt: float = 0.005, cap: float = 0.6) -> tuple[float, SwitchingSignal] | None:
    """The smallest deviation on the grid of dt at which the periodic adversary proves growth (bisection)."""
    found: dict[int, SwitchingSignal] = {}

    def grows(m: int) -> bool:
        found[m] = periodic_switching_adversary(lam, P, D, T1, T2, m * dt, dt=dt)
        return found[m].grows

    lo, hi = 0, int(round(cap / dt))
    if not grows(hi):
        return None
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if grows(mid) else (mid, hi)
    return hi * dt, found[hi]


def bisect(bad, hi: float, steps: int = 9) -> float | None:
    if not bad(hi):
        return None
    lo = 0.0
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if bad(mid) else (mid, hi)
    return hi


def constant_unstable(f, d: float, m: int = 48) -> bool:
    u = np.linspace(-1.0, 1.0, m)
    pts = [(T1 + d * a, T2 + s * d) for a in u for s in (-1, 1)] + [(T1 + s * d, T2 + d * a) for a in u for s in (-1, 1)]
    return max(rightmost_root(f, max(a, 0.0), max(b, 0.0)).real for a, b in pts) >= 0.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--max-order", type=int, default=3)
    parser.add_argument("--upper-cuts", action="store_true")
    parser.add_argument("--cover-intervals", action="store_true")
    parser.add_argument("--rtol", type=float, default=0.02)
    parser.add_argument("--no-adversary", action="store_true", help="only the certified margin and its cost")
    args = parser.parse_args()
    options = dict(max_order=args.max_order, upper_cuts=args.upper_cuts, cover_intervals=args.cover_intervals,
                   rtol=args.rtol)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.1f}, OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}")  # fmt: skip
    times, cpu, m = [], [], None
    for _ in range(args.repeat):
        t, c = time.perf_counter(), time.process_time()
        m = team_delay_margin(paper_six(), P, D, T1, T2, **options)
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    small = jitter_margin(paper_six(), P, D, T1, T2)
    richest = sum(m.modes[0].functional in verdict for _, verdict in m.tried)
    print(f"\nteam margin (delays varying together): {m.delta:.4f} s, limiting lam = {m.limiting:.4f}; "
          f"time median {np.median(times):.1f} s, best {min(times):.1f} s, CPU median {np.median(cpu):.2f} s, best {min(cpu):.2f} s "
          f"({args.repeat} runs, {len(m.tried)} SDPs each, {richest} of them the richest functional); load now "
          f"{os.getloadavg()[0]:.1f}; options {options}")  # fmt: skip
    if args.no_adversary:
        return
    print(f"small gain (per link): {small.delta:.4f} s\n")
    print("| mode lam | functional that holds | greedy switching destabilizes at | weighted family at | periodic signal (Floquet) at "
          "| its rate, replayed (1/s) | constant offset unstable at |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for md, f in zip(m.modes, [next(g for g in factors(paper_six(), P, D) if g.lam == md.lam) for md in m.modes], strict=True):
        # the adversary's growth test needs a mode that decays to 0: not the centroid (it settles anywhere)
        skip = "n/a (pair)" if f.group.is_complex_pair else ("n/a (centroid)" if f.is_centroid else None)
        adv = bisect(lambda A: grows(f.lam.real, A), 0.6) if skip is None else None
        wadv = bisect(lambda A: grows_weighted(f.lam.real, A), 0.6) if skip is None else None
        c = time.process_time()
        per = periodic_threshold(f.lam.real) if skip is None else None
        per_cpu = time.process_time() - c
        const = bisect(lambda d: constant_unstable(f, d), 0.6)
        adv_s = skip or ("none up to 0.6" if adv is None else f"{adv:.4f}")
        wadv_s = skip or ("none up to 0.6" if wadv is None else f"{wadv:.4f}")
        const_s = "none up to 0.6" if const is None else f"{const:.4f}"
        per_s = skip or ("none up to 0.6" if per is None else f"{per[0]:.4f} ({per_cpu:.0f} CPU s)")
        rate_s = "" if per is None else f"{per[1].rate:.2e}, {replay_growth_rate(per[1], periods=60):.2e}"
        print(f"| {md.lam:.4f} | {md.functional} | {adv_s} | {wadv_s} | {per_s} | {rate_s} | {const_s} |")
        if md.lam == m.limiting and per is not None:
            below = periodic_switching_adversary(f.lam.real, P, D, T1, T2, per[0] - 0.0025, dt=0.0025)
            print(f"  limiting mode at {per[0] - 0.0025:.4f} (dt = 0.0025 s): multiplier {abs(below.multiplier):.6f}, "
                  f"rate {below.rate:.2e} per s; at the certified {m.delta:.4f}: "
                  f"{periodic_switching_adversary(f.lam.real, P, D, T1, T2, m.delta).rate:.2e} per s")  # fmt: skip


if __name__ == "__main__":
    main()
