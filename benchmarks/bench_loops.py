"""Benchmark: exact delay margins of python-control loops (issue 23). Prints a markdown table.

For loops of order 2 to 12 (stable, a lightly damped resonance so that |L| crosses
1 several times; seeded), the wall time of :func:`delayform.delay_margin`
(exact, certified) beside the two things a python-control user would do:

* ``control.stability_margins`` then PM / omega_c at the crossover it reports
  (fast, but one crossover only: the wrong answer when another decides);
* the Pade route: close the loop through ``control.pade(tau, 5)`` and scan
  600 delays for the first unstable pole, then bisect (what the tutorial's
  comparison does).

Reported: median wall time of ``--repeat`` runs and the relative error of each
answer against the exact margin. The machine is shared: times are inflated by
other users' load.

Run: ``.venv/bin/python benchmarks/bench_loops.py [--repeat 3]``
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import time

import control
import numpy as np

from delayform.loops import delay_margin


def _loop(order: int, rng: np.random.Generator) -> control.TransferFunction:
    while True:
        poles = [-rng.uniform(0.2, 3.0) for _ in range(order - 2)]
        den = np.polymul(np.poly(poles), [1.0, 0.06, 4.0])  # a resonance at 2 rad/s
        num = [rng.uniform(0.5, 1.5) * abs(np.polyval(den, 0.0)) * 1.5]
        loop = control.tf(num, den)
        try:
            delay_margin(loop)
            return loop
        except ValueError:  # unstable at tau = 0: draw again
            continue


def _pade_margin(loop: control.TransferFunction, tau_max: float, order: int = 5) -> float:
    num_l, den_l = np.asarray(loop.num[0][0], float), np.asarray(loop.den[0][0], float)

    def unstable(tau: float) -> bool:
        n, d = control.pade(tau, order)
        return bool(np.max(np.roots(np.polyadd(np.polymul(den_l, d), np.polymul(num_l, n))).real) >= 0.0)

    taus = np.linspace(tau_max / 600, tau_max, 600)
    hit = next((k for k, t in enumerate(taus) if unstable(t)), None)
    if hit is None:
        return math.inf
    lo, hi = (taus[hit - 1] if hit else 0.0), taus[hit]
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
    return hi


def _timed(fn, repeat: int):  # type: ignore[no-untyped-def]
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return out, statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.1f} at start, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}\n")  # fmt: skip
    rng = np.random.default_rng(23)
    print("| order | crossovers | delayform (ms) | stability_margins (ms), error | Pade-5 scan (ms), error |")
    print("|---|---|---|---|---|")
    for order in (2, 4, 6, 8, 12):
        loop = _loop(order, rng)
        exact, t_exact = _timed(lambda loop=loop: delay_margin(loop), args.repeat)

        def margins(loop=loop):  # type: ignore[no-untyped-def]
            _, pm, _, _, wgc, _ = control.stability_margins(loop)
            return math.radians(pm) / wgc

        sm, t_sm = _timed(margins, args.repeat)
        pade, t_pade = _timed(lambda loop=loop: _pade_margin(loop, 3 * exact.tau), 1)
        err = lambda x: f"{100 * (x - exact.tau) / exact.tau:+.3g} %"  # noqa: E731
        print(f"| {order} | {len(exact.crossovers)} | {1e3 * t_exact:.1f} | {1e3 * t_sm:.1f}, {err(sm)} | "
              f"{1e3 * t_pade:.0f}, {err(pade)} |")  # fmt: skip


if __name__ == "__main__":
    main()
