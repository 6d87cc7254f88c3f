"""Benchmark: the cost of the public API's argument checks (issue 24). Prints a markdown table.

Every name of ``delayform.__all__`` goes through ``delayform._validation.validated``,
which compares each argument given with its annotation before the body runs.
This measures what that costs against the same call without the layer
(``__wrapped__``: the undecorated function or ``__init__``):

* per call, for the small objects the library itself builds often
  (EigenvalueGroup, CharacteristicFactor, TwoDelayQuasiPolynomial) and for
  lambda_region; goal: under 10 microseconds a call;
* end to end, ``factors(ring(3000))`` (about 1500 factors, each an
  EigenvalueGroup and a CharacteristicFactor: the worst case, a loop of
  constructions and nothing else) and the paper's ``stability_map`` (22
  checked calls); goal: a few milliseconds at most, far below any map.

Run: ``python benchmarks/bench_validation.py``. The machine is shared with other
jobs: the load average is printed; each figure is the median of repeats.
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable

import numpy as np

from delayform.analysis.ctcr.stability_map import stability_map
from delayform.analysis.plane.region import LambdaRegion, lambda_region
from delayform.characteristic import CharacteristicFactor, TwoDelayQuasiPolynomial, factors
from delayform.quasipolynomial import QuasiPolynomial
from delayform.topology import EigenvalueGroup, paper_six, ring


def _median(fn: Callable[[], object], *, number: int, repeats: int = 7) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(number):
            fn()
        times.append((time.perf_counter() - start) / number)
    return statistics.median(times)


def _bare_init(cls: type, *args: object) -> Callable[[], object]:
    init = cls.__init__.__wrapped__  # type: ignore[misc]

    def build() -> object:
        obj = object.__new__(cls)
        init(obj, *args)
        return obj

    return build


def main() -> None:
    group = EigenvalueGroup(0.5 + 0j, 1, False, False)
    g = np.array([1.0, 0.5, 1.0])
    qp = QuasiPolynomial({(0, 0): [1.0, 0.5, 1.0], (1, 0): [-0.5], (0, 1): [0.0, -0.25]})
    rows = []
    per_call = [
        ("EigenvalueGroup(lam, 1, False, False)", lambda: EigenvalueGroup(0.5 + 0j, 1, False, False),
         _bare_init(EigenvalueGroup, 0.5 + 0j, 1, False, False)),
        ("CharacteristicFactor(group, P, D)", lambda: CharacteristicFactor(group, 1.0, 0.5),
         _bare_init(CharacteristicFactor, group, 1.0, 0.5)),
        ("TwoDelayQuasiPolynomial(g1, g2)", lambda: TwoDelayQuasiPolynomial(g, g), _bare_init(TwoDelayQuasiPolynomial, g, g)),
        ("lambda_region(P, D, tau1, tau2)", lambda: lambda_region(1.0, 0.5, 0.3, 0.2),
         lambda: lambda_region.__wrapped__(1.0, 0.5, 0.3, 0.2)),  # type: ignore[attr-defined]
        # a method the root finders call per Newton step (checked since the validate-new branch)
        ("QuasiPolynomial.evaluate(s, tau1, tau2)", lambda: qp.evaluate(0.3 + 1j, 0.3, 0.2),
         lambda: QuasiPolynomial.evaluate.__wrapped__(qp, 0.3 + 1j, 0.3, 0.2)),  # type: ignore[attr-defined]
    ]  # fmt: skip
    assert isinstance(lambda_region(1.0, 0.5, 0.3, 0.2), LambdaRegion)
    for label, checked, bare in per_call:
        a, b = _median(checked, number=2000), _median(bare, number=2000)
        rows.append((label, f"{a * 1e6:.2f} us", f"{b * 1e6:.2f} us", f"{(a - b) * 1e6:+.2f} us"))

    topo = ring(3000)
    topo.eigenvalues  # noqa: B018 - cached: both runs time the factors only
    end_to_end = [
        ("factors(ring(3000), 1, 0.5)", lambda: factors(topo, 1.0, 0.5),
         lambda: factors.__wrapped__(topo, 1.0, 0.5)),  # type: ignore[attr-defined]
        ("stability_map(paper_six(), 1, 0.5, 10, 10)", lambda: stability_map(paper_six(), 1.0, 0.5, 10.0, 10.0),
         lambda: stability_map.__wrapped__(paper_six(), 1.0, 0.5, 10.0, 10.0)),  # type: ignore[attr-defined]
    ]  # fmt: skip
    for label, checked, bare in end_to_end:
        a, b = _median(checked, number=1, repeats=5), _median(bare, number=1, repeats=5)
        rows.append((label, f"{a * 1e3:.1f} ms", f"{b * 1e3:.1f} ms", f"{(a - b) / b * 100:+.1f} %"))

    print(f"load average {os.getloadavg()[0]:.1f} (2 cores, shared)\n")
    print("| call | with the checks | without | cost |")
    print("|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
