"""Multiple roots: a cluster of polished seeds replaced by one root and its certified multiplicity.

Near a root of multiplicity m, q is flat: Newton's method converges only
linearly, the discretization's eigenvalues split into m points on a circle
of radius about eps^(1/m) (times the root's scale), and seeds stop anywhere
in a neighbourhood where |q| is below the acceptance test. The convention
used everywhere in delayform: **a root of multiplicity m is one point,
reported m times by** :func:`~delayform.analysis.roots.single.roots_in`
**and counted m times by every count**, like ``numpy.roots``.

Method, for each accepted seed whose first derivatives are small (a
candidate of multiplicity m >= 2 by the test of :func:`_loose_multiplicity`):

1. Newton's method on q^(m-1), which has a *simple* root at an m-fold root
   of q (quadratic convergence; Rall, "Convergence of the Newton process to
   multiple solutions", Numer. Math. 9, 1966, and the derivative-deflation
   variant in Ypma, "Finding a multiple zero by transformations and Newton-like
   methods", SIAM Review 25, 1983). Where q's coefficients carry rounding,
   the m-fold root is itself only defined to about eps^(1/m): the point found
   is the centre of the cluster, accurate to that order, which is what
   double precision allows.
2. The multiplicity is then *certified*: the argument principle
   (:func:`~delayform.analysis.roots.argument_principle.count_in_region`) counts
   the roots in a small square about the point, enclosing the seeds that
   reached it; only when that count equals m are the seeds replaced by the
   one point of multiplicity m. Otherwise they stay as they were (and the
   caller's count check decides).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.roots.argument_principle import count_in_region
from delayform.analysis.roots.problem import _cluster, _multiplicity, _nth_derivative, _Problem

#: |q^(j)| below this fraction of its terms' moduli counts as "zero" for a multiplicity candidate
_LOOSE = 1e-3
_NEWTON_STEPS = 40
#: samples spent on one square's count: a square that needs more is not the right one
_COUNT_BUDGET = 20_000


def _loose_multiplicity(prob: _Problem, z: complex, t1: float, t2: float, cap: int) -> int:
    """The first k with |q^(k)(z)| above _LOOSE of its scale (1 when q' is not small)."""
    arr = np.array([z], dtype=np.complex128)
    for k in range(1, cap + 1):
        val, mag = _nth_derivative(prob.terms, arr, t1, t2, k)
        if not abs(val[0]) <= _LOOSE * mag[0]:
            return k
    return cap + 1


def _refine(prob: _Problem, z: complex, t1: float, t2: float, m: int) -> complex | None:
    """Newton's method on q^(m-1) from z; None when it does not settle."""
    s = np.array([z], dtype=np.complex128)
    for _ in range(_NEWTON_STEPS):
        f, _ = _nth_derivative(prob.terms, s, t1, t2, m - 1)
        df, _ = _nth_derivative(prob.terms, s, t1, t2, m)
        if not (np.isfinite(f[0]) and np.isfinite(df[0])) or df[0] == 0:
            return None
        step = f / df
        s = s - step
        if abs(step[0]) <= 4e-16 * (1.0 + abs(s[0])):
            break
    return complex(s[0]) if abs(s[0] - z) < 0.5 * (1.0 + abs(z)) else None


def distinct_roots(
    prob: _Problem, polished: NDArray[np.complex128], t1: float, t2: float
) -> tuple[NDArray[np.complex128], NDArray[np.int64]]:
    """The distinct roots among accepted seeds and their multiplicities (module docstring).

    Parameters
    ----------
    prob
        The problem whose q the seeds were polished on.
    polished
        Accepted (polished) seeds, in any order, repeats allowed.
    t1, t2
        The delays of the problem.

    Returns
    -------
    roots, mult
        Distinct roots (a cluster about a certified m-fold root replaced by
        its centre) and their multiplicities.
    """
    roots = _cluster(polished)
    mult = _multiplicity(prob, roots, t1, t2)
    if roots.size == 0:
        return roots, mult
    cap = min(sum(int(c.size) for c, _, _ in prob.terms) - 1, 12)  # Polya-Szego bound
    eps = np.finfo(float).eps
    keep = np.ones(roots.size, dtype=bool)
    extra_r: list[complex] = []
    extra_m: list[int] = []
    for i in np.argsort(-mult, kind="stable"):
        if not keep[i] or (prob.deflate_zero and abs(roots[i]) < 1e-5):
            continue
        m = _loose_multiplicity(prob, complex(roots[i]), t1, t2, cap)
        if m < 2:
            continue
        z = _refine(prob, complex(roots[i]), t1, t2, m)
        if z is None:
            continue
        m = _loose_multiplicity(prob, z, t1, t2, cap)
        if m < 2:
            continue
        scale = 1.0 + abs(z)
        near = keep & (np.abs(roots - z) <= 0.5 * scale * eps ** (1.0 / (2 * m)))
        w = 1.5 * float(np.abs(roots[near] - z).max(initial=0.0)) + 4.0 * scale * eps ** (1.0 / m)
        # on the square's edges |q| ~ |q^(m)| w^m / m! must stand well above q's rounding error
        arr = np.array([z], dtype=np.complex128)
        _, mag0 = _nth_derivative(prob.terms, arr, t1, t2, 0)
        qm, _ = _nth_derivative(prob.terms, arr, t1, t2, m)
        if abs(qm[0]) > 0.0:
            w = max(w, (1e4 * eps * float(mag0[0]) * math.factorial(m) / abs(qm[0])) ** (1.0 / m))
        for _ in range(3):  # a root on the square's edge: a slightly larger square
            n = count_in_region(prob.terms, t1, t2, (z.real - w, z.real + w, z.imag - w, z.imag + w),
                              budget=_COUNT_BUDGET)  # fmt: skip
            if n is not None:
                break
            w *= 1.3
        if n != m:
            continue
        if abs(z.imag) <= 1e-12 * scale and all(np.all(c.imag == 0.0) for c, _, _ in prob.terms):
            z = complex(z.real, 0.0)  # a real q: the centre of a cluster straddling the axis is real
        inside = keep & (np.abs(roots.real - z.real) < w) & (np.abs(roots.imag - z.imag) < w)
        keep &= ~inside
        extra_r.append(z)
        extra_m.append(m)
    out_r = np.concatenate([roots[keep], np.asarray(extra_r, dtype=np.complex128)])
    out_m = np.concatenate([mult[keep], np.asarray(extra_m, dtype=np.int64)])
    return out_r, out_m
