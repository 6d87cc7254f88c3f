"""Benchmark: rightmost roots of general quasi-polynomials against qpmr, on qpmr's own catalogue (issue 19).

Prints markdown. For each retarded quasi-polynomial of ``qpmr.examples``
(the catalogue keyed by the paper it comes from) plus TDS-CONTROL's manual
Ex. 2.1 (expanded by :meth:`QuasiPolynomial.from_matrices`):

1. ``qpmr.qpmr(coefs, delays, region=R)`` (Python QPmR, Vyhlidal and Zitek;
   the ``bench`` extra) on a rectangle R that holds the rightmost root with
   room to spare: real parts from Re r - 2 to Re r + 1 and, the coefficients
   being real, Im s from 0 to max(10, 2 |Im r| + 5) -- a rectangle chosen
   knowing the answer, which favours qpmr (it needs no search for it). The
   rightmost root of its output is kept.
2. :func:`delayform.rightmost_root` on the same quasi-polynomial written as a
   :class:`~delayform.QuasiPolynomial` (one delay per distinct delay of the
   catalogue entry), certified (no root right of it is missed).

Interleaved repeats; medians of process CPU time (and wall time) per call.
Goal (issue 19): at least 10x per rightmost root. Agreement: the two
rightmost roots, and the published value where there is one.

The machine is shared (other jobs run on its two cores): the load average is
printed with the table; medians are the figures to trust.

Run: ``.venv/bin/python benchmarks/bench_general.py [--repeat 7]``.
"""

from __future__ import annotations

import argparse
import logging
import os
import platform
import statistics
import warnings
import numpy as np
from bench_spectrum import _clock  # the same (wall, CPU) clock as the paper-team benchmark

from delayform import QuasiPolynomial, rightmost_root

TDS_A0 = np.array([[-1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, -10, -4], [0, 0, 4, -10]])
TDS_A1 = np.array([[3.0, 3, 3, 3], [0, -1.5, 0, 0], [0, 0, 3, -5], [0, 5, 5, 5]])


def _from_rows(coefs: np.ndarray, delays: np.ndarray) -> tuple[QuasiPolynomial, tuple[float, ...]]:
    """qpmr's (coefs, delays) -- one row of ascending coefficients per delay -- as (QuasiPolynomial, taus)."""
    distinct = sorted({float(d) for d in delays if d != 0.0})
    m = max(len(distinct), 1)
    terms: dict[tuple[int, ...], np.ndarray] = {}
    for row, d in zip(coefs, delays, strict=True):
        key = tuple(int(float(d) == x) for x in distinct) if d != 0.0 else (0,) * m
        key = key or (0,)
        terms[key] = terms.get(key, np.zeros(coefs.shape[1])) + row
    return QuasiPolynomial(terms), tuple(distinct) or (0.0,)


def _to_rows(q: QuasiPolynomial, taus: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
    width = q.degree + 1
    coefs = np.zeros((len(q.terms), width))
    delays = np.zeros(len(q.terms))
    for i, (k, c) in enumerate(q.terms.items()):
        coefs[i, : c.size] = c.real
        delays[i] = float(np.dot(k, taus))
    return coefs, delays


Case = tuple[str, np.ndarray, np.ndarray, float | None, tuple[QuasiPolynomial, tuple[float, ...]] | None]


def _cases() -> list[Case]:
    import qpmr

    ex = qpmr.examples
    out = [
        ("Vyhlidal & Zitek 2009 Ex. 1: s + e^{-s}", *ex.vyhlidal2014qpmr_01(), None, None),
        ("Vyhlidal & Zitek 2009, 9 delays (degree 8)", *ex.vyhlidal2014qpmr_02(), None, None),
        ("Mazanti, Boussaada & Niculescu 2021 Prop. 6.1 (6-fold root)", *ex.mazanti2021multiplicity(), -6.021,
         None),
    ]
    q = QuasiPolynomial.from_matrices(TDS_A0, TDS_A1)  # one delay, terms e^{-k tau s}, k = 0..4
    out.append(("TDS-CONTROL manual Ex. 2.1 (4 x 4, from_matrices)", *_to_rows(q, (1.0,)), 0.6176424667764324,
                (q, (1.0,))))
    return out


def _qpmr_rightmost(coefs: np.ndarray, delays: np.ndarray, region: tuple[float, ...]) -> complex:
    import qpmr

    roots, _ = qpmr.qpmr(coefs, delays, region=region)
    roots = np.asarray(roots, dtype=complex)
    top = roots[np.argmax(roots.real)]
    return complex(top.real, abs(top.imag))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7, help="interleaved repeats of every timing")
    args = parser.parse_args()
    logging.getLogger("qpmr").setLevel(logging.ERROR)
    warnings.filterwarnings("ignore")  # qpmr's casts and its own warnings

    rows = []
    for name, coefs, delays, published, given in _cases():
        q, taus = given or _from_rows(np.asarray(coefs, dtype=float), np.asarray(delays, dtype=float))
        r = rightmost_root(q, *taus)  # warm-up, and the rectangle qpmr gets
        region = (r.real - 2.0, r.real + 1.0, 0.0, max(10.0, 2.0 * abs(r.imag) + 5.0))
        want = _qpmr_rightmost(coefs, delays, region)
        q_t, s_t = [], []
        for _ in range(args.repeat):
            w, c, want = _clock(lambda: _qpmr_rightmost(coefs, delays, region))
            q_t.append((w, c))
            w, c, got = _clock(lambda: rightmost_root(q, *taus))
            s_t.append((w, c))
        rows.append((name, q, taus, q_t, s_t, got, want, published))

    load = os.getloadavg()
    print(f"machine: {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}; "
          f"load average {load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (1 / 5 / 15 min; shared with other jobs); "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
    print(f"{args.repeat} interleaved repeats; medians of process CPU time (wall time in brackets)")
    print()
    print("| quasi-polynomial (qpmr.examples) | delays | qpmr CPU (wall) ms | rightmost_root CPU (wall) ms | "
          "speed-up CPU (wall) | goal >= 10x | rightmost root | vs qpmr | vs published |")
    print("|---|---|---|---|---|---|---|---|---|")
    ratios = []
    for name, q, taus, q_t, s_t, got, want, published in rows:
        qc, qw = statistics.median(x[1] for x in q_t), statistics.median(x[0] for x in q_t)
        sc, sw = statistics.median(x[1] for x in s_t), statistics.median(x[0] for x in s_t)
        ratios.append(qc / sc)
        pub = "" if published is None else f"{abs(got.real - published):.1e}"
        print(f"| {name} | {len(taus)} | {1e3 * qc:.1f} ({1e3 * qw:.1f}) | {1e3 * sc:.2f} ({1e3 * sw:.2f}) | "
              f"{qc / sc:.0f}x ({qw / sw:.0f}x) | {'met' if qc / sc >= 10 else 'NOT met'} | "
              f"{got.real:.10g} {got.imag:+.10g}j | {abs(got - want):.1e} | {pub} |")
    print()
    print(f"median speed-up over the catalogue: {statistics.median(ratios):.0f}x (lowest {min(ratios):.0f}x)")


if __name__ == "__main__":
    main()
