"""Benchmark: CTCR maps beyond the paper's form (issue 19, items 1, 3, 5). Prints a markdown table.

Cases, each a map over its window and NU on a 200 x 200 grid, against the
peer that answers the same question without CTCR: an argument-principle
count of the roots right of the axis at every grid point (the winding of q on
a half-disk, :mod:`tests.ref_roots_ctcr`), timed on 400 of the points and
scaled to the grid:

* the Jarlebring & Michiels ``time_delay`` example (NLEVP), one delay with a
  double root at tau = 1 and touching roots (degenerate crossings), [0, 3] x [0, 1];
* a general two-delay qp with ``z1 z2^2``, ``z1^3``, ``z2^3``, ``z1^2 z2`` terms, [0, 6]^2;
* a neutral two-delay qp whose difference operator is strongly stable, [0, 5]^2.

Also the time of ``neutral_spectrum`` at one delay pair of the neutral case.
The machine is shared: CPU time of this process is printed beside wall time.

Run: ``.venv/bin/python benchmarks/bench_ctcr_general.py``.
"""

from __future__ import annotations

import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from ref_roots_ctcr import coefficient_bound, count_unstable_function  # noqa: E402

from delayform import QuasiPolynomial  # noqa: E402
from delayform.analysis.ctcr.stability_map import crossing_map  # noqa: E402
from delayform.analysis.neutral import neutral_spectrum  # noqa: E402

PI = np.pi


def _jm() -> dict:
    a = [2 * (65 * PI + 32) / (5 * (8 + 5 * PI)), 9 * PI**2 * (13 + 5 * PI) / (8 + 5 * PI),
         324 * PI**2 * (5 * PI + 4) / (5 * (8 + 5 * PI))]
    b = [(260 * PI + 128 + 225 * PI**2) / (10 * (8 + 5 * PI)), 45 * PI**2 / (8 + 5 * PI),
         81 * PI**2 * (40 * PI + 32 + 25 * PI**2) / (10 * (8 + 5 * PI))]
    return {(0, 0): [a[2], a[1], a[0], 1.0], (1, 0): [b[2], b[1], b[0]]}


CASES = [
    ("Jarlebring-Michiels (double + touching roots)", _jm(), (3.0, 1.0), None),
    ("general terms z1 z2^2, z1^3, z2^3, z1^2 z2",
     {(0, 0): [1.0, 3.0, 2.0, 1.0], (1, 2): [0.5, 0.8], (3, 0): [0, 0, 0.7], (0, 3): [0.9], (2, 1): [0.3, 0.2]},
     (6.0, 6.0), None),
    ("neutral, D = 1 + 0.3 z1 + 0.1 z2 - 0.2 z1 z2^2",
     {(0, 0): [3.0, 2.0, 1.0], (1, 0): [-2.0, 0.5, 0.3], (1, 2): [0.4, 0.0, -0.2], (0, 1): [0.0, 1.0, 0.1]},
     (5.0, 5.0), 0.6),
]


def _radius(terms: dict, neutral_sum: float | None) -> float:
    if neutral_sum is None:
        return 1.05 * coefficient_bound([np.asarray(terms[(0, 0)], complex)] +
                                        [np.asarray(c, complex) for k, c in terms.items() if any(k)]) + 1.0
    n = len(terms[(0, 0)]) - 1
    low = sum(float(np.sum(np.abs(np.asarray(c)[:n]))) for c in terms.values())
    return 1.05 * max(1.0, low / (1.0 - neutral_sum)) + 1.0


def main() -> None:
    load = os.getloadavg()
    print(f"machine: {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}; "
          f"load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (shared with other jobs)\n")
    print("| case | map s (cpu) | NU 200x200 s (cpu) | peer: half-disk count, per point s (cpu) | peer x 40,000 s | agree |")
    print("|---|---|---|---|---|---|")
    pv = np.polynomial.polynomial.polyval
    for name, terms, (t1m, t2m), nsum in CASES:
        qp = QuasiPolynomial(terms)
        c0 = time.process_time()
        m = crossing_map(qp, t1m, t2m)
        t_map = time.process_time() - c0
        g1 = (np.arange(200) + 0.5) * t1m / 200
        g2 = (np.arange(200) + 0.5) * t2m / 200
        c0 = time.process_time()
        nu = m.unstable_count(g1[None, :], g2[:, None])
        t_nu = time.process_time() - c0
        rng = np.random.default_rng(0)
        i, j = rng.integers(0, 200, 400), rng.integers(0, 200, 400)

        def f(s, a, b, terms=terms):
            return sum(pv(s, np.asarray(c, complex)) * np.exp(-(k[0] * a + k[1] * b) * s) for k, c in terms.items())

        c0 = time.process_time()
        ref, unc = count_unstable_function(f, _radius(terms, nsum), g1[j], g2[i])
        t_ref = (time.process_time() - c0) / 400
        agree = int(np.sum((nu[i, j] == ref) & ~unc))
        print(f"| {name} | {t_map:.2f} | {t_nu:.3f} | {t_ref:.2e} | {t_ref * 40000:.1f} | "
              f"{agree} of {int(np.sum(~unc))} certain |")
    terms = CASES[2][1]
    c0 = time.process_time()
    rep = neutral_spectrum(QuasiPolynomial(terms), 1.0, 1.7)
    print(f"\n`neutral_spectrum` of the neutral case at (1, 1.7): {time.process_time() - c0:.2f} s cpu "
          f"(C_D = {rep.essential_abscissa:.6f}, strongly stable {rep.strongly_stable}, rightmost {rep.rightmost})")


if __name__ == "__main__":
    main()
