"""Benchmark: rightmost roots at long delays (the root chains), with the Lambert W closed form beside them.

1. ``rightmost_root`` of ``s + 1 + 0.5 e^{-tau s}`` (a QuasiPolynomial in one
   delay) at tau = 100 ... 5000 s: best and median of ``--repeat`` calls, and
   the closed form ``s = -a + W_0(-b tau e^{a tau}) / tau`` (a = 1, b = 0.5)
   beside it: ``scipy.special.lambertw`` where ``b tau e^{a tau}`` is a double
   (a tau <= 700), else W_0 from ``w + Log w = Log x`` (no overflow), the same
   function in logarithmic form.
2. The paper's team (paper_six, P = 1, D = 0.5) at tau1 = tau2 = 1000 s:
   ``dominant_root``, and the certified count right of it (independent check).
3. Two delays, ``s + 1 + 0.3 e^{-tau1 s} + 0.4 e^{-tau2 s}`` at (300, 500) s.

The machine is shared (other jobs run on its two cores): the load average is
printed with the tables; medians are the figures to trust.

Run: ``.venv/bin/python benchmarks/bench_long_delays.py [--repeat 7]``.
"""

from __future__ import annotations

import argparse
import cmath
import math
import os
import platform
import statistics
import time
from collections.abc import Callable

from scipy.special import lambertw

from delayform.analysis.roots.dominant import dominant_root
from delayform.analysis.roots.single import count_roots_right_of, rightmost_root
from delayform.characteristic import factors
from delayform.quasipolynomial import QuasiPolynomial
from delayform.topology import paper_six

A, B = 1.0, 0.5
TAUS = (100.0, 300.0, 500.0, 1000.0, 2000.0, 5000.0)


def lambert_rightmost(a: float, b: float, tau: float) -> tuple[complex, str]:
    """-a + W_0(-b tau e^{a tau}) / tau (Im >= 0), and how W_0 was evaluated."""
    if a * tau <= 700.0:
        w = complex(lambertw(-b * tau * math.exp(a * tau), 0))
        how = "scipy.special.lambertw"
    else:  # W_0(x) solves w + Log w = Log x; Log x = ln|b tau| + a tau + i pi for b > 0
        target = complex(math.log(abs(b * tau)) + a * tau, math.pi if b > 0 else 0.0)
        w = target - cmath.log(target)
        for _ in range(50):
            w -= (w + cmath.log(w) - target) / (1.0 + 1.0 / w)
        how = "W_0 in log form"
    s = -a + w / tau
    return complex(s.real, abs(s.imag)), how


def _times(fn: Callable[[], object], repeat: int) -> tuple[float, float, object]:
    """(best, median) wall seconds of ``repeat`` calls, and the last result."""
    out: object = None
    walls = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - t0)
    return min(walls), statistics.median(walls), out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    print(f"machine: {platform.machine()} {platform.processor() or ''}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}; load average {os.getloadavg()[0]:.2f} (1 min)")  # fmt: skip
    print()
    print("| tau (s) | best (s) | median (s) | rightmost root | closed form | abs. difference | W_0 by |")
    print("|---|---|---|---|---|---|---|")
    q = QuasiPolynomial({(0,): [A, 1.0], (1,): [B]})
    for tau in TAUS:
        best, med, s = _times(lambda tau=tau: rightmost_root(q, tau), args.repeat)
        ref, how = lambert_rightmost(A, B, tau)
        print(f"| {tau:g} | {best:.3f} | {med:.3f} | {complex(s):.12g} | {ref:.12g} | "  # type: ignore[str-format]
              f"{abs(complex(s) - ref):.1e} | {how} |")  # type: ignore[arg-type]
    print()
    team, fs = paper_six(), factors(paper_six(), 1.0, 0.5)
    best, med, dom = _times(lambda: dominant_root(team, 1.0, 0.5, 1000.0, 1000.0), args.repeat)
    r = complex(dom.root)  # type: ignore[attr-defined]
    right = sum(count_roots_right_of(f, 1000.0, 1000.0, r.real + 1e-9) for f in fs)
    print(f"paper team, P = 1, D = 0.5, tau1 = tau2 = 1000 s: dominant_root best {best:.3f} s, median {med:.3f} s, "
          f"root {r:.10g}; certified count of roots right of Re = root + 1e-9 over all factors: {right}")  # fmt: skip
    q2 = QuasiPolynomial({(0, 0): [1.0, 1.0], (1, 0): [0.3], (0, 1): [0.4]})
    best, med, s2 = _times(lambda: rightmost_root(q2, 300.0, 500.0), args.repeat)
    z = complex(s2)  # type: ignore[arg-type]
    right = count_roots_right_of(q2, 300.0, 500.0, z.real + 1e-9)
    print(f"s + 1 + 0.3 e^(-300 s) + 0.4 e^(-500 s): rightmost_root best {best:.3f} s, median {med:.3f} s, "
          f"root {z:.10g}; certified count right of Re = root + 1e-9: {right}")  # fmt: skip
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
