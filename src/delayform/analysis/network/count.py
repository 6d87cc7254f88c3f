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
and ``||E||_inf <= r = ||(I - X(s_a))^{-1}||_inf L h``. Every eigenvalue of I - E
stays in the disc |z - 1| <= r, so when ``N asin(r) <= pi / 2`` f has no zero on
the piece and its continuous phase change is the principal argument of
f(s_b) / f(s_a). Pieces are split until every one passes; by the symmetry
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


def _samples(team: LinkTeam, s: NDArray[np.complex128], U: NDArray[np.float64], *, keep: bool) -> tuple[NDArray[Any], ...]:
    """f(s) = det(I - X(s)), ``|(I - X(s))^{-1}| @ U`` (inf where singular), and when ``keep`` I - X and its inverse."""
    p = s * s + team.D * s + team.P
    with np.errstate(all="ignore"):  # a zero of p on the line: f is inf there and the piece is split
        G = team.matrix(s) / p[:, None, None]  # = I - X(s)
        f = np.linalg.det(G)
    W = np.full(s.shape + U.shape, np.inf)
    inv = np.full(G.shape, np.nan + 0j) if keep else np.zeros((0,))
    ok = np.isfinite(f) & (np.abs(f) > 0.0)
    if ok.any():
        iv = np.linalg.inv(G[ok])
        W[ok] = np.abs(iv) @ U
        if keep:
            inv[ok] = iv
    return (f, W, G, inv) if keep else (f, W, np.zeros((0,)), inv)


#: Teams larger than this take each piece's phase from eigenvalues (longer pieces, dearer samples).
EIGEN_PHASE_N = 10
#: Bound on ||E||_inf per piece when the phase comes from eigenvalues.
_R_EIGEN = 0.9


def _phase_change(team: LinkTeam, c: float, R: float) -> float | None:
    """Continuous change of arg f along c + i y, y from 0 to R; None if the budget is exceeded.

    Small teams: pieces with ``N asin(r) <= pi / 2`` and the principal argument of
    f(s_b) / f(s_a). Larger teams: pieces with ``r <= 1/2`` and the sum of the
    principal arguments of the eigenvalues of ``(I - X(s_a))^{-1} (I - X(s_b))``,
    each in the disc |z - 1| <= r (module docstring): N times fewer pieces.
    """
    by_eigen = team.n > EIGEN_PHASE_N
    rmax = _R_EIGEN if by_eigen else math.sin(math.pi / (2.0 * team.n))
    y = np.linspace(0.0, R, 129 if not by_eigen else 33)
    U = _row_vectors(team, c)
    f, nrm, G, inv = _samples(team, c + 1j * y, U, keep=by_eigen)
    chunk = max(64, int(2e6 // max(team.n**2, 1)))
    while True:
        with np.errstate(invalid="ignore"):
            r = _growth(team, c, y[:-1], y[1:], nrm[:-1]) * np.diff(y)
        bad = ~(r <= rmax)
        if not bad.any():
            if not by_eigen:
                return float(np.angle(f[1:] / f[:-1]).sum())
            # pieces with N asin(r) <= pi / 2 need only the ratio of determinants
            cheap = team.n * np.arcsin(np.minimum(r, 1.0)) <= 0.5 * math.pi
            total = float(np.angle(f[1:][cheap] / f[:-1][cheap]).sum())
            dear = np.flatnonzero(~cheap)
            for i in range(0, dear.size, chunk):
                k = dear[i : i + chunk]
                total += float(np.angle(np.linalg.eigvals(inv[k] @ G[k + 1])).sum())
            return total
        if y.size > MAX_SAMPLES:
            return None
        # split each failing piece into as many parts as its bound asks for (at most 64)
        parts = np.where(np.isfinite(r), np.clip(np.ceil(r / rmax), 2, 64), 2).astype(np.int64)
        add = np.concatenate([np.linspace(y[k], y[k + 1], parts[k] + 1)[1:-1] for k in np.flatnonzero(bad)])
        if add.size + y.size > MAX_SAMPLES:
            return None
        pieces = [_samples(team, c + 1j * add[i : i + chunk], U, keep=by_eigen) for i in range(0, add.size, chunk)]
        order = np.argsort(np.concatenate([y, add]), kind="stable")
        y = np.concatenate([y, add])[order]
        f = np.concatenate([f] + [p[0] for p in pieces])[order]
        nrm = np.concatenate([nrm] + [p[1] for p in pieces])[order]
        if by_eigen:
            G = np.concatenate([G] + [p[2] for p in pieces])[order]
            inv = np.concatenate([inv] + [p[3] for p in pieces])[order]


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
