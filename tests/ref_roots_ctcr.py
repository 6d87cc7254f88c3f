"""An independent count of unstable characteristic roots, for checking the CTCR map.

Nothing here uses the curves, the quasi-polynomial coefficients or the root
tendencies of :mod:`delayform.analysis.ctcr.stability_map`. A subsystem of eq. subsystems,
``dx/dt = A x + B1 x(t - tau1) + B2 x(t - tau2)``, has the characteristic
function ``f(s) = det(s I - A - B1 e^{-tau1 s} - B2 e^{-tau2 s})``. A root with
Re s >= 0 is an eigenvalue of ``A + B1 e^{-tau1 s} + B2 e^{-tau2 s}`` with
``|e^{-tau s}| <= 1``, so ``|s| <= ||A|| + ||B1|| + ||B2|| = R``. The number of roots
with Re s > 0 is then the winding number of f along the boundary of the right
half-disk of radius 1.05 R + 1 (argument principle), sampled until the phase
moves less than 0.5 rad between neighbouring samples. A root within about
1e-6 of the imaginary axis forces a finer and finer sampling there: such
contours are reported as *uncertain* and the caller skips the point.

The centroid factor (lam = 1) has s = 0 for every delay: f(s)/s is used
instead, so the rigid-body mode lies neither inside nor on the contour.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: Largest phase step accepted between neighbouring contour samples (rad).
MAX_STEP = 0.5
#: Below this interval length on the imaginary axis a still-unresolved phase means a root near it.
NEAR_AXIS = 2e-6


def radius(A: NDArray[np.float64], B1: NDArray[np.float64], B2: NDArray[np.float64]) -> float:
    """Bound on |s| of every root with Re s >= 0, for any delays."""
    return float(sum(np.linalg.norm(M, 2) for M in (A, B1, B2)))


def characteristic(
    A: NDArray[np.float64], B1: NDArray[np.float64], B2: NDArray[np.float64],
    s: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64], *, centroid: bool,
) -> NDArray[np.complex128]:
    """det(s I - A - B1 e^{-tau1 s} - B2 e^{-tau2 s}), divided by s for the centroid factor."""
    n = A.shape[0]
    e1 = np.exp(-t1 * s)
    e2 = np.exp(-t2 * s)

    def entry(i: int, j: int) -> NDArray[np.complex128]:
        # s I - A - B1 e1 - B2 e2, entry by entry (zero coefficients skipped: no big temporaries).
        out = (s if i == j else np.zeros(s.shape, complex)) - A[i, j]
        if B1[i, j] != 0:
            out = out - B1[i, j] * e1
        if B2[i, j] != 0:
            out = out - B2[i, j] * e2
        return out

    if n == 2:
        f = entry(0, 0) * entry(1, 1) - entry(0, 1) * entry(1, 0)
    elif n == 4:
        f = _det4([[entry(i, j) for j in range(4)] for i in range(4)])
    else:
        M = np.stack([np.stack([entry(i, j) for j in range(n)], -1) for i in range(n)], -2)
        f = np.linalg.det(M)
    if centroid:
        f = f / s
    return f


def _det4(a: list[list[NDArray[np.complex128]]]) -> NDArray[np.complex128]:
    """Determinant of 4x4 matrices given entry-wise, by the Laplace expansion in 2x2 minors."""
    s0 = a[0][0] * a[1][1] - a[1][0] * a[0][1]
    s1 = a[0][0] * a[1][2] - a[1][0] * a[0][2]
    s2 = a[0][0] * a[1][3] - a[1][0] * a[0][3]
    s3 = a[0][1] * a[1][2] - a[1][1] * a[0][2]
    s4 = a[0][1] * a[1][3] - a[1][1] * a[0][3]
    s5 = a[0][2] * a[1][3] - a[1][2] * a[0][3]
    c5 = a[2][2] * a[3][3] - a[3][2] * a[2][3]
    c4 = a[2][1] * a[3][3] - a[3][1] * a[2][3]
    c3 = a[2][1] * a[3][2] - a[3][1] * a[2][2]
    c2 = a[2][0] * a[3][3] - a[3][0] * a[2][3]
    c1 = a[2][0] * a[3][2] - a[3][0] * a[2][2]
    c0 = a[2][0] * a[3][1] - a[3][0] * a[2][1]
    return s0 * c5 - s1 * c4 + s2 * c3 + s3 * c2 - s4 * c1 + s5 * c0


def _contour(t: NDArray[np.float64], R: float) -> NDArray[np.complex128]:
    """t in [0, 1]: arc from -jR through R to jR; t in [1, 2]: down the imaginary axis."""
    arc = R * np.exp(1j * np.pi * (np.minimum(t, 1.0) - 0.5))
    axis = 1j * R * (1.0 - 2.0 * (t - 1.0))
    s = np.where(t <= 1.0, arc, axis)
    # The centroid's f(s)/s is analytic at 0; never evaluate exactly there.
    return np.where(s == 0, 1e-9j, s)


def count_unstable(
    A: NDArray[np.float64], B1: NDArray[np.float64], B2: NDArray[np.float64],
    tau1: NDArray[np.float64], tau2: NDArray[np.float64], *, centroid: bool = False,
) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Roots with Re s > 0 at each delay pair, and whether the count is uncertain.

    Returns
    -------
    count, uncertain
        ``uncertain`` is True where a root lies (about) within 1e-6 of the
        imaginary axis, so the count there is not to be trusted.
    """
    def f(s: NDArray, t1: NDArray, t2: NDArray) -> NDArray:
        return characteristic(A, B1, B2, s, t1, t2, centroid=centroid)

    return count_unstable_function(f, 1.05 * radius(A, B1, B2) + 1.0, tau1, tau2)


def coefficient_bound(coefficients: list[NDArray[np.complex128]]) -> float:
    """|s| bound for roots with Re s >= 0 of sum_k g_k(s) e^{-h_k s}, g_1 of top degree.

    On Re s >= 0 every exponential has modulus <= 1, so a root has
    ``|lead| |s|^d <= sum_{i<d} (sum_k |g_k,i|) |s|^i``, impossible for
    ``|s| > max(1, sum_{i<d} sum_k |g_k,i| / |lead|)``.
    """
    d = len(coefficients[0]) - 1
    lead = abs(coefficients[0][d])
    total = sum(float(np.sum(np.abs(np.asarray(c)[:d]))) for c in coefficients)
    return max(1.0, total / lead)


def count_unstable_function(
    f: object, R: float, tau1: NDArray[np.float64], tau2: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """The argument-principle count for any analytic ``f(s, tau1, tau2)`` with no root of |s| >= R, Re s >= 0."""
    tau1 = np.asarray(tau1, float).ravel()
    tau2 = np.asarray(tau2, float).ravel()
    R = float(R)
    characteristic_fn = f
    q = tau1.size
    # Phase of e^{-tau s} turns at rate tau along the axis: a few samples per radian of it.
    n_axis = 128 + 4 * int(np.ceil(R * (tau1.max(initial=0) + tau2.max(initial=0))))
    t = np.concatenate([np.linspace(0.0, 1.0, 65)[:-1], np.linspace(1.0, 2.0, n_axis + 1)])
    t = t + 1e-13 * np.pi  # keep off s = 0 and the exact corners by an irrational nudge
    t[0], t[-1] = 0.0, 2.0
    T = np.broadcast_to(t, (q, t.size))
    F = characteristic_fn(_contour(T, R), tau1[:, None], tau2[:, None])
    steps = np.angle(F[:, 1:] / F[:, :-1])
    winding = steps.sum(axis=1)
    uncertain = np.zeros(q, bool)
    # Refine the intervals whose phase step is too large, eight sub-intervals at a time.
    qi, ji = np.nonzero(np.abs(steps) > MAX_STEP)
    ta, tb = T[qi, ji], T[qi, ji + 1]
    fa, fb = F[qi, ji], F[qi, ji + 1]
    np.subtract.at(winding, qi, steps[qi, ji])
    for _ in range(60):
        if qi.size == 0:
            break
        width = (tb - ta) * 2.0 * R  # length in s on the axis (or more on the arc)
        tiny = (width < NEAR_AXIS) & (ta >= 1.0)
        uncertain[qi[tiny]] = True
        keep = ~tiny
        qi, ta, tb, fa, fb = qi[keep], ta[keep], tb[keep], fa[keep], fb[keep]
        if qi.size == 0:
            break
        sub = ta[:, None] + (tb - ta)[:, None] * np.linspace(0.0, 1.0, 9)[None, :]
        fs = characteristic_fn(_contour(sub[:, 1:-1], R), tau1[qi][:, None], tau2[qi][:, None])
        fs = np.concatenate([fa[:, None], fs, fb[:, None]], axis=1)
        st = np.angle(fs[:, 1:] / fs[:, :-1])
        good = np.abs(st) <= MAX_STEP
        np.add.at(winding, np.repeat(qi, 8)[good.ravel()], st[good])
        bad_q, bad_j = np.nonzero(~good)
        qi = qi[bad_q]
        ta, tb = sub[bad_q, bad_j], sub[bad_q, bad_j + 1]
        fa, fb = fs[bad_q, bad_j], fs[bad_q, bad_j + 1]
    uncertain[qi] = True
    count = np.rint(winding / (2.0 * np.pi)).astype(np.int64)
    uncertain |= np.abs(winding / (2.0 * np.pi) - count) > 1e-3
    return count, uncertain


def system_unstable(factors: tuple, tau1: NDArray[np.float64], tau2: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """NU of the whole system: each factor's count times its multiplicity (eq. factorized)."""
    total = np.zeros(np.size(tau1), np.int64)
    uncertain = np.zeros(np.size(tau1), bool)
    for f in factors:
        A, B1, B2 = f.state_matrices()
        c, u = count_unstable(A, B1, B2, tau1, tau2, centroid=f.is_centroid)
        total += f.multiplicity * c
        uncertain |= u
    return total, uncertain
