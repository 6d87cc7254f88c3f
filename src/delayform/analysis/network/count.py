"""A certified count of the roots of det M(s) right of a line (the argument principle).

M(s) = p(s) I - K(s) is the per-link characteristic matrix of
:mod:`delayform.analysis.network.links`. The count uses

    f(s) = det(I - X(s)),   X(s) = K(s) / p(s),

whose zeros are those of det M and whose poles are the two zeros of p (each of
order at most N): the roots of det M right of Re s = c number
``W + N #{zeros of p right of c}``, W the winding number of f around the
half-plane. Dividing by p^N keeps f near 1 at large |s|, where its phase is calm.

Closing at infinity
-------------------
For Re s >= c and |s| = rho, the row sums give ``||K(s)||_inf <= a + b rho`` with
``a = max_i sum_k C_ik P e^{-tau1_ik min(c, 0)}`` (b likewise with D), and
``|p(s)| >= (rho - |r1|)(rho - |r2|)``. Past the radius R where the second
exceeds the first, ``||X||_inf < 1``: there det M has no zero, and on that arc
``log f = sum_j log(1 - mu_j(X))`` (principal logs, |mu_j| < 1) is continuous, so
the phase change along the arc from c - iR to c + iR is ``2 Im log f(c + iR)``.

Certified sampling of the line
------------------------------
On a piece [s_a, s_b] of the line, ``||X(s) - X(s_a)||_inf <= L |s - s_a|`` with L
from the closed-form bounds of ``||K||``, ``||K'||`` and the distance to the zeros
of p. With ``E = (I - X(s_a))^{-1} (X(s) - X(s_a))``, ``f(s) = f(s_a) det(I - E)``
and ``||E||_inf <= r`` (the row sums of an entrywise bound of X' weighted by
``|(I - X(s_a))^{-1}|``, times h). Every eigenvalue of I - E stays in the disc
|z - 1| <= r < 1, so f has no zero on the piece and its continuous phase change is
``Im tr log(I - E) = -Im tr E - sum_{k >= 2} Im tr(E^k) / k``, the tail at most
``N r^2 / (2 (1 - r))``. Pieces are split until that is <= pi / 2: the change is then
the principal argument of f(s_b) / f(s_a) plus the multiple of 2 pi nearest the
first-order term ``Im tr((I - X(s_a))^{-1} (I - X(s_b)))``, O(N^2) per piece (when
``N asin(r) <= pi / 2`` on every piece the multiple is 0). Pieces are split until every one passes; by the symmetry
f(conj s) = conj f(s) (real C and delays) only 0 <= Im s <= R is sampled.
Soundness rests on floating point evaluation of f at the samples (as every
argument-principle method does); the bounds themselves are rigorous.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.network.links import LinkTeam

__all__ = ["count_right_of", "root_radius"]

#: Most samples spent on one line before giving up (a root on or very near it).
MAX_SAMPLES = 200_000


def _p_roots(team: LinkTeam) -> NDArray[np.complex128]:
    return np.roots([1.0, team.D, team.P]).astype(np.complex128)


def _row_bounds(team: LinkTeam, c: float) -> tuple[float, float]:
    """(a, b) with ||K(s)||_inf <= a + b |s| for every s with Re s >= c."""
    e1 = np.exp(-team.tau1 * min(c, 0.0))
    e2 = np.exp(-team.tau2 * min(c, 0.0))
    a = np.bincount(team.rows, team.weights * team.P * e1, minlength=team.n).max()
    b = np.bincount(team.rows, team.weights * team.D * e2, minlength=team.n).max()
    return float(a), float(b)


def root_radius(team: LinkTeam, c: float) -> float:
    """R such that det M(s) of ``team`` has no zero with Re s >= c and |s| >= R (module docstring)."""
    a, b = _row_bounds(team, c)
    m1, m2 = np.sort(np.abs(_p_roots(team)))
    # (rho - m1)(rho - m2) > a + b rho  <=>  rho^2 - (m1 + m2 + b) rho + m1 m2 - a > 0
    B = m1 + m2 + b
    disc = B * B - 4.0 * (m1 * m2 - a)
    rho = 0.5 * (B + math.sqrt(max(disc, 0.0)))
    return 1.05 * max(rho, m2) + 1e-9


def _row_vectors(team: LinkTeam, c: float) -> NDArray[np.float64]:
    """Per-row sums (N, 4) bounding the rows of X' on the line Re s = c (see :func:`_growth`).

    Row i of K and K' is bounded by ``kp_i + kd_i rho`` and ``(kp1_i + kd_i) + kd2_i rho``.
    """
    e1 = np.exp(-team.tau1 * c)
    e2 = np.exp(-team.tau2 * c)
    cols = [team.P * e1 * team.tau1, team.D * e2, team.D * e2 * team.tau2, team.P * e1]
    kp1, kd, kd2, kp = (np.bincount(team.rows, team.weights * v, minlength=team.n) for v in cols)
    return np.stack([kp1 + kd, kd2, kp, kd], axis=1)


def _growth(team: LinkTeam, c: float, y0: NDArray[np.float64], y1: NDArray[np.float64],
            W: NDArray[np.float64]) -> NDArray[np.float64]:  # fmt: skip
    """Bound of ||(I - X(s_a))^{-1} (X(s) - X(s_a))||_inf / |s - s_a| on each piece [y0, y1].

    ``W = |(I - X(s_a))^{-1}| @ _row_vectors`` at the pieces' left ends: the entrywise
    bound ``|X'_ik| <= (|K'_ik| |p| + |K_ik| |p'|) / |p|^2`` summed over each row, then
    weighted by ``|A|`` (for non-negative matrices the inf-norm is the largest row sum,
    so ``|| |A| L ||_inf = max (|A| (L 1))``): tighter than the product of the norms.
    """
    rho = np.hypot(c, y1)
    pmin = np.ones_like(y0)
    for r in _p_roots(team):  # |p| >= product of distances from the zeros of p to the piece
        dy = np.clip(r.imag, y0, y1) - r.imag
        pmin = pmin * np.hypot(c - r.real, dy)
    with np.errstate(divide="ignore", invalid="ignore"):
        rows = ((W[:, :, 0] + W[:, :, 1] * rho[:, None]) / pmin[:, None]
                + (W[:, :, 2] + W[:, :, 3] * rho[:, None]) * ((2.0 * rho + team.D) / pmin**2)[:, None])  # fmt: skip
        out = rows.max(axis=1)
    return np.where(np.isfinite(out), out, np.inf)


def _samples(team: LinkTeam, s: NDArray[np.complex128], U: NDArray[np.float64]) -> tuple[NDArray[Any], NDArray[Any]]:
    """f(s) = det(I - X(s)) and ``|(I - X(s))^{-1}| @ U`` (inf where singular)."""
    f, W, _, _ = _factored(team, s, U)
    return f, W


def _factored(team: LinkTeam, s: NDArray[np.complex128], U: NDArray[np.float64]) -> tuple[NDArray[Any], ...]:
    """f, ``|A| @ U``, G = I - X(s) and A = G^{-1} (NaN where singular) at each point."""
    p = s * s + team.D * s + team.P
    with np.errstate(all="ignore"):  # a zero of p on the line: f is inf there and the piece is split
        G = team.matrix(s) / p[:, None, None]  # = I - X(s)
        f = np.linalg.det(G)
    W = np.full(s.shape + U.shape, np.inf)
    inv = np.full(G.shape, np.nan + 0j)
    ok = np.isfinite(f) & (np.abs(f) > 0.0)
    if ok.any():
        inv[ok] = np.linalg.inv(G[ok])
        W[ok] = np.abs(inv[ok]) @ U
    return f, W, G, inv


#: Up to this many agents the phase comes from ratios of determinants alone.
SMALL_TEAM = 10


def _piece_radius(n: int) -> float:
    """Largest r with N r^2 / (2 (1 - r)) <= pi / 2: the first-order phase then picks the branch."""
    return (-math.pi + math.sqrt(math.pi**2 + 4.0 * n * math.pi)) / (2.0 * n)


def _branch_phase(team: LinkTeam, c: float, y: NDArray[np.float64], f: NDArray[np.complex128],
                  U: NDArray[np.float64], chunk: int) -> float:  # fmt: skip
    """Sum over the pieces of the continuous phase change of f (module docstring).

    On a piece, the change is ``Im tr log(I - E)`` (every eigenvalue of I - E in the disc
    |z - 1| <= r), ``= -Im tr E - sum_{k >= 2} Im tr(E^k) / k`` with the tail below
    ``N r^2 / (2 (1 - r)) <= pi / 2``; ``-Im tr E = Im tr(A_a G_b)`` costs O(N^2). The change is
    the principal argument of f(s_b) / f(s_a) plus the multiple of 2 pi nearest that estimate.
    """
    s = c + 1j * y
    theta = np.angle(f[1:] / f[:-1])
    est = np.empty(theta.size)
    for i in range(0, theta.size, chunk):
        k = np.arange(i, min(i + chunk, theta.size))
        _, _, G, A = _factored(team, s[np.concatenate([k, [k[-1] + 1]])], U)
        est[k] = np.einsum("kij,kji->k", A[:-1], G[1:]).imag
    return float(np.sum(theta + 2.0 * math.pi * np.round((est - theta) / (2.0 * math.pi))))


def _phase_change(team: LinkTeam, c: float, R: float) -> float | None:
    """Continuous change of arg f along c + i y, y from 0 to R; None if the budget is exceeded.

    Pieces are split until ``N asin(r) <= pi / 2`` (small teams: ratios of determinants
    alone) or ``r <= _piece_radius(N)``, about sqrt(pi / N) (larger teams: the branch
    from the first-order term).
    """
    # small teams: short pieces and determinants only; larger ones: longer pieces and one more
    # pass of inverses for the branch (cheaper once N asin(r) <= pi / 2 would need many pieces)
    small = team.n <= SMALL_TEAM
    rmax = math.sin(math.pi / (2.0 * team.n)) if small else _piece_radius(team.n)
    y = np.linspace(0.0, R, 129)
    U = _row_vectors(team, c)
    chunk = max(64, int(2e6 // max(team.n**2, 1)))
    f, nrm = _samples(team, c + 1j * y, U)
    while True:
        with np.errstate(invalid="ignore"):
            r = _growth(team, c, y[:-1], y[1:], nrm[:-1]) * np.diff(y)
        bad = ~(r <= rmax)
        if not bad.any():
            if np.all(team.n * np.arcsin(np.minimum(r, 1.0)) <= 0.5 * math.pi):
                return float(np.angle(f[1:] / f[:-1]).sum())
            return _branch_phase(team, c, y, f, U, chunk)
        # split each failing piece into as many parts as its bound asks for (at most 64)
        parts = np.where(np.isfinite(r), np.clip(np.ceil(r / rmax), 2, 64), 2).astype(np.int64)
        add = np.concatenate([np.linspace(y[k], y[k + 1], parts[k] + 1)[1:-1] for k in np.flatnonzero(bad)])
        if add.size + y.size > MAX_SAMPLES:
            return None
        pieces = [_samples(team, c + 1j * add[i : i + chunk], U) for i in range(0, add.size, chunk)]
        order = np.argsort(np.concatenate([y, add]), kind="stable")
        y = np.concatenate([y, add])[order]
        f = np.concatenate([f] + [p[0] for p in pieces])[order]
        nrm = np.concatenate([nrm] + [p[1] for p in pieces])[order]


def count_right_of(team: LinkTeam, c: float) -> int | None:
    """Certified number of roots of det M(s) with Re s > c, multiplicity counted (s = 0 included).

    ``team`` is the per-link team (:class:`~delayform.analysis.network.links.LinkTeam`).

    None when the line cannot be certified within the sampling budget (a root on
    or extremely close to Re s = c).
    """
    R = root_radius(team, c)
    delta = _phase_change(team, c, R)
    if delta is None:
        return None
    sR = np.array([c + 1j * R])
    X = np.eye(team.n) - team.matrix(sR)[0] / (sR[0] ** 2 + team.D * sR[0] + team.P)
    mu = np.linalg.eigvals(X)
    if not np.all(np.abs(mu) < 1.0):  # the closing radius is rigorous: this would be a bug of rounding
        return None
    arc = float(np.sum(np.log(1.0 - mu)).imag)
    w = (arc - delta) / math.pi
    if abs(w - round(w)) > 1e-3:
        return None
    poles = int(np.sum(_p_roots(team).real > c))
    return int(round(w)) + team.n * poles
