"""Envelopes of CTCR curves over a family of eigenvalues: where a spectrum set's safe delays end.

For a family ``lam(t)`` of eigenvalues (the interior of a real interval, the
circle of a disc) the CTCR curves of the factors ``q(s, lam(t))`` sweep a region
of the delay plane; its boundary, besides the curves of the family's ends, is
the *envelope*: delays where ``q(j omega; lam, tau) = 0`` and the root does not
move off the axis when lam moves along the family,
``Re(dlam b(j omega) / q_s(j omega)) = 0`` (the curve ``L(j omega)`` is tangent to
the family there).

For fixed (omega, lam) the first equation is the triangle
``a(j omega) = lam (P z1 + j D omega z2)`` with sides ``P`` and ``D omega``: the phases
``omega tau_k mod 2 pi`` in closed form (two mirror branches), the delays on the
lattice ``tau_k = (theta_k + 2 pi n_k) / omega`` (paper, eq. 6). The second is then a
scalar function of (omega, t): every vertex drawn is its zero on an edge of a
grid of the (omega, t) plane, found by Brent's method on the closed form; the
grid only decides which vertices are joined (marching squares), so a piece
shorter than a grid cell can be missing from the drawing. No classification
of delay pairs uses these curves (:mod:`delayform.analysis.plane.spectrum_sets`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.plane.boundary_curve import ab_terms, omega_limit

__all__ = ["triangle_phases", "tangency", "envelope_of_family", "tangency_parabola"]


def triangle_phases(P: float, D: float, w: NDArray, x: NDArray, branch: float) -> tuple[NDArray, NDArray, NDArray]:
    """Phases (theta1, theta2) in [0, 2 pi) with a(j w) = x (P z1 + j D w z2), and the feasibility mask.

    ``u = P z1`` and ``v = j D w z2`` are the sides of the triangle ``u + v = a / x``
    (law of cosines; ``branch`` = +-1 picks the mirror triangle).

    Parameters
    ----------
    P, D
        Gains of the paper's eq. 1.
    w
        Frequencies omega > 0.
    x
        Eigenvalues (real or complex), broadcast with ``w``.
    branch
        +1 or -1: which of the two mirror triangles.

    Returns
    -------
    theta1, theta2, feasible
        Phases ``omega tau_k mod 2 pi`` and where the triangle exists.
    """
    A = -w * w + 1j * D * w + P
    with np.errstate(divide="ignore", invalid="ignore"):
        c = A / x
        rc = np.abs(c)
        cos_alpha = (rc * rc + P * P - (D * w) ** 2) / (2.0 * rc * P)
        ok = np.isfinite(cos_alpha) & (np.abs(cos_alpha) <= 1.0) & (w > 0)
        u = P * np.exp(1j * (np.angle(c) + branch * np.arccos(np.clip(cos_alpha, -1.0, 1.0))))
        v = c - u
        th1 = np.mod(-np.angle(u / P), 2.0 * np.pi)
        th2 = np.mod(-np.angle(v / (1j * D * w)), 2.0 * np.pi)
    return th1, th2, ok


def tangency(P: float, D: float, w: NDArray, lam: NDArray, dlam: NDArray, t1: NDArray, t2: NDArray) -> NDArray[np.float64]:
    """``Re(dlam b conj(q_s))`` at s = j w with ``b = a / lam``: zero where the imaginary root stops moving.

    Along a family of eigenvalues ``lam(t)`` the root j omega of q(s, lam)
    moves by ``ds = dlam b / q_s``; where ``Re ds = 0`` the curve ``L(j omega)`` is
    tangent to the family (the real axis, or the disc's circle) and the CTCR
    curves of the family have their envelope.

    Parameters
    ----------
    P, D
        Gains of the paper's eq. 1.
    w
        Frequencies omega.
    lam
        Eigenvalues of the family at which q(j omega, lam) = 0.
    dlam
        Direction of the family at ``lam`` (1 along the real axis, the tangent of a circle).
    t1, t2
        Delays (s) of the imaginary root.
    """
    A, _, da, db = ab_terms(P, D, t1, t2, w)
    return (dlam * (A / lam) * np.conj(da - lam * db)).real


def envelope_of_family(
    P: float, D: float, lam_of: Any, dlam_of: Any, t_lo: float, t_hi: float, radius: float,
    tau1_max: float, tau2_max: float, *, n_w: int = 240, n_t: int = 160,
) -> list[NDArray[np.float64]]:
    """Segments (tau1, tau2) of the envelope of the CTCR curves of the factors lam(t), t in (t_lo, t_hi).

    On a grid of (omega, t) the phases come in closed form (:func:`triangle_phases`)
    and the delays on each lattice image ``tau_k = (theta_k + 2 pi n_k) / omega``;
    the tangency function (:func:`tangency`) is zero on the envelope. Every
    vertex is the zero of the tangency function on a grid edge, found by
    Brent's method on the exact closed form (so it satisfies
    q(j omega; lam, tau) = 0 and the tangency to rounding); the grid only
    decides which vertices are joined.

    Parameters
    ----------
    P, D
        Gains of the paper's eq. 1.
    lam_of, dlam_of
        Vectorized ``t -> lam(t)`` and ``t -> d lam / d t`` of the family.
    t_lo, t_hi
        Range of the family's parameter (ends excluded).
    radius
        Largest |lam| of the family (sets the frequencies traced).
    tau1_max, tau2_max
        The delay window.
    n_w, n_t
        Grid points in omega and in t.

    Returns
    -------
    list of ndarray
        Segments, each of shape (2, 2): rows are points, columns tau1, tau2.
    """
    from scipy.optimize import brentq

    wmax = omega_limit(P, D, radius)
    w = np.linspace(wmax / n_w, wmax, n_w)
    t = np.linspace(t_lo, t_hi, n_t + 2)[1:-1]
    W, Tg = np.meshgrid(w, t, indexing="ij")
    L, dL = lam_of(Tg), dlam_of(Tg)
    n1max = int(np.ceil(tau1_max * wmax / (2 * np.pi)))
    n2max = int(np.ceil(tau2_max * wmax / (2 * np.pi)))
    segments: list[tuple[tuple[float, float], tuple[float, float]]] = []
    for branch in (1.0, -1.0):
        th1, th2, ok = triangle_phases(P, D, W, L, branch)

        def point(wv: float, tv: float, ref1: float, ref2: float, branch: float = branch) -> tuple[float, float, float]:
            # phases continued next to the cell's (unwrapped, lattice-shifted) reference phases
            lam = lam_of(np.array(tv))
            a1, a2, good = triangle_phases(P, D, np.array(wv), lam, branch)
            if not good:
                return np.nan, np.nan, np.nan
            p1 = ref1 + np.angle(np.exp(1j * (a1 - ref1)))
            p2 = ref2 + np.angle(np.exp(1j * (a2 - ref2)))
            tt1, tt2 = p1 / wv, p2 / wv
            g = tangency(P, D, np.array(wv), lam, dlam_of(np.array(tv)), tt1, tt2)
            return float(g), float(tt1), float(tt2)

        for n1 in range(n1max + 1):
            for n2 in range(n2max + 1):
                T1 = (th1 + 2 * np.pi * n1) / W
                T2 = (th2 + 2 * np.pi * n2) / W
                G = np.where(ok, tangency(P, D, W, L, dL, T1, T2), np.nan)
                segments.extend(_march(G, th1, th2, T1, T2, w, t, n1, n2, point, brentq, tau1_max, tau2_max))
    return [np.asarray(seg, dtype=float) for seg in segments]


def _wraps(th: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Cells in which a phase wraps around 2 pi."""
    big = np.pi
    return ((np.abs(np.diff(th, axis=0))[:, :-1] > big) | (np.abs(np.diff(th, axis=0))[:, 1:] > big)
            | (np.abs(np.diff(th, axis=1))[:-1, :] > big) | (np.abs(np.diff(th, axis=1))[1:, :] > big))


def _march(
    G: NDArray, th1: NDArray, th2: NDArray, T1: NDArray, T2: NDArray, w: NDArray, x: NDArray, n1: int, n2: int,
    point: Any, brentq: Any, tau1_max: float, tau2_max: float,
) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """Marching squares on the (omega, x) grid; vertices polished on the cell edges."""
    out = []
    near = ((T1 <= 1.05 * tau1_max) & (T2 <= 1.05 * tau2_max))
    sign = np.sign(G)
    wrapped = _wraps(th1) | _wraps(th2)
    cells = np.argwhere(
        np.isfinite(G[:-1, :-1]) & np.isfinite(G[1:, :-1]) & np.isfinite(G[:-1, 1:]) & np.isfinite(G[1:, 1:])
        & ((np.abs(sign[:-1, :-1] + sign[1:, :-1] + sign[:-1, 1:] + sign[1:, 1:]) < 4) | wrapped)
        & (near[:-1, :-1] | near[1:, 1:])
    )
    for i, j in cells:
        corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
        ref1 = th1[i, j] + 2 * np.pi * n1
        ref2 = th2[i, j] + 2 * np.pi * n2
        # the corners' phases continued from the first corner (a wrap inside the cell is not a jump)
        if wrapped[i, j]:
            g = {c: point(w[c[0]], x[c[1]], ref1, ref2)[0] for c in corners}
        else:
            g = {c: G[c] for c in corners}
        if not all(np.isfinite(v) for v in g.values()):
            continue
        verts = []
        for p, q in zip(corners, corners[1:] + corners[:1], strict=True):
            if g[p] * g[q] < 0:
                # the edge from corner p to q, (omega, t) = start + u (end - start), u in [0, 1]
                start = np.array([w[p[0]], x[p[1]]])
                step = np.array([w[q[0]], x[q[1]]]) - start

                def f(u: float, start: NDArray = start, step: NDArray = step) -> float:
                    return point(*(start + u * step), ref1, ref2)[0]

                try:
                    u = brentq(f, 0.0, 1.0, xtol=1e-14)
                except ValueError:  # no sign change on the exact edge (the phases left the branch)
                    continue
                _, tt1, tt2 = point(*(start + u * step), ref1, ref2)
                if np.isfinite(tt1):
                    verts.append((tt1, tt2))
        for k in range(0, len(verts) - 1, 2):
            out.append((verts[k], verts[k + 1]))
    return out


def tangency_parabola(P: float, D: float, rho: float, tau1_max: float, tau2_max: float) -> NDArray[np.float64] | None:
    """Delays where the boundary curve and a circle of radius rho through 1 (real centre) have equal curvature at 1.

    ``tau1^2 - 2 rho Re L2 = 0`` with ``L2 = (1 - D tau1 + D tau2) / P + tau1^2 / 2``, solved for tau2;
    None when it misses the window.

    Parameters
    ----------
    P, D
        Gains.
    rho
        Radius of the circle (centre 1 - rho).
    tau1_max, tau2_max
        The window.
    """
    x = np.linspace(0.0, tau1_max, 400)
    y = (x * x * (1.0 - rho) * P / (2.0 * rho) - 1.0 + D * x) / D
    keep = (y >= 0.0) & (y <= tau2_max)
    return np.column_stack([x[keep], y[keep]]) if np.count_nonzero(keep) >= 2 else None
