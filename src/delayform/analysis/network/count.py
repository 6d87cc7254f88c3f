"""A certified count of the roots of det M(s) right of a line (the argument principle).

M(s) = p(s) I - K(s) is the per-link characteristic matrix of
:mod:`delayform.analysis.network.links`. The count uses

    f(s) = det G(s),   G(s) = I - X(s),   X(s) = K(s) / p(s),

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
By the symmetry f(conj s) = conj f(s) (real C and delays) only 0 <= Im s <= R is
sampled. On a piece [s_a, s_b] of the line write ``A = G(s_a)^{-1}`` and

    f(s) = f(s_a) det(I - E(s)),   E(s) = A (X(s) - X(s_a)).

*A bound for the whole piece.* X is supported on the links, and entrywise
``|X(s) - X(s_a)| <= |s - s_a| sum_m gamma_m Lambda_m`` with four non-negative link
matrices ``Lambda_m`` (from ``|K|``, ``|K'|`` on the line, :func:`_link_bounds`) and
scalars ``gamma_m`` of the piece (its largest |s| and the least |p| on it, from the
distances to the zeros of p; :func:`_gammas`): ``|X'| <= (|K'| |p| + |K| |p'|) / |p|^2``.
Hence ``|E(s)| <= h |A| sum_m gamma_m Lambda_m`` entrywise and, for every s of the piece,

    ||E(s)||_2 <= ||E(s)||_F <= phi = h sum_m gamma_m ||(|A| Lambda_m)||_F,

h the piece's length (the Frobenius norm is monotone in the entries' moduli; the
triangle inequality splits the sum). The four norms cost one product of |A| with a
sparse matrix per sample.

*The phase change on the piece.* When phi < 1 every eigenvalue of E(s) stays in the
disc |z| <= phi < 1 along the piece, so f has no zero there and ``sum_j Log(1 - lambda_j)``
(principal logs, 1 - lambda_j in the right half-plane) is the continuous logarithm of
f(s) / f(s_a). Its imaginary part at s_b is the phase change, equal to

    Im tr log(I - E) = -Im tr E - Im sum_{k >= 2} tr(E^k) / k,

and by Weyl's majorant theorem ``|tr E^k| <= sum_j sigma_j^k <= ||E||_F^2 ||E||_2^{k - 2}``,
so the tail is at most ``sum_{k >= 2} phi^k / k = -log(1 - phi) - phi`` (1.05 at
phi = 0.85, below pi / 2). The first-order term is exact and cheap:
``-tr E(s_b) = tr(A G(s_b)) - N`` needs only the diagonal of A and its entries at the
transposed links, since G(s_b) is the identity plus link entries; those N + links
numbers are kept per sample, so no inverse is formed twice. The change is then the
principal argument of f(s_b) / f(s_a) plus the one multiple of 2 pi within pi / 2 of
that estimate. Each piece may take either end as s_a (the smaller phi); pieces with
phi > 0.85 are split in as many parts as the bound asks for.

*Why this rule.* Its threshold does not depend on N. The row-sum rule it replaces,
``N r^2 / (2 (1 - r)) <= pi / 2`` with r an inf-norm bound of E, needed r ~ sqrt(pi / N);
near a root, where A is nearly of rank one (u v^H / lambda), ``||(|A| Lambda)||_F``
is about ``|| Lambda^T |v| || / |lambda|`` while N^(1/2) times the row-sum bound grows
like N^(1/2) times that, so at 100 agents the pieces are several times longer
where the roots crowd the line (6710 -> 795 samples on the benchmark's team).

Soundness rests on floating point evaluation of f, A and the bounds at the samples (as
every argument-principle method does): the tolerance left (pi / 2 - 1.05 in the branch,
1e-3 in the final integer) is many orders of magnitude above the rounding of a
well-conditioned sample, and a sample where G is numerically singular makes its pieces
split, never pass.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from delayform.analysis.network.blas import single_threaded_blas
from delayform.analysis.network.links import LinkTeam

__all__ = ["count_right_of", "root_radius"]

#: Most samples spent on one line before giving up (a root on or very near it), for a team
#: of ``_BUDGET_AGENTS`` agents or fewer; larger teams get fewer (an N x N inverse each):
#: the budget falls as 1 / N^2, about a minute on one core at 100 or 200 agents.
MAX_SAMPLES = 200_000
_BUDGET_AGENTS = 40
#: A piece passes when phi <= this (module docstring): its tail -log(1 - phi) - phi = 1.05 < pi / 2.
PHI_MAX = 0.85


def _p_roots(team: LinkTeam) -> NDArray[np.complex128]:
    """The zeros of p(s) = s^2 + D s + P (closed form)."""
    d = np.sqrt(complex(team.D * team.D - 4.0 * team.P))
    return np.array([0.5 * (-team.D + d), 0.5 * (-team.D - d)], dtype=np.complex128)


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


def _link_bounds(team: LinkTeam, c: float) -> NDArray[np.float64]:
    """The four link matrices Lambda_m on the line Re s = c, shape (links, 4).

    On the line ``|K_ik| <= C_ik (P e1 + D e2 rho)`` and
    ``|K'_ik| <= C_ik ((P tau1 e1 + D e2) + D tau2 e2 rho)`` (e = e^{-tau c}, rho = |s|), so
    ``|X'_ik| <= sum_m gamma_m Lambda_m`` with the columns below and
    gamma = (1, rho, |p'|, rho |p'|) / (|p|, |p|, |p|^2, |p|^2) (:func:`_gammas`).
    """
    e1 = np.exp(-team.tau1 * c)
    e2 = np.exp(-team.tau2 * c)
    w = team.weights
    return np.stack([w * (team.P * team.tau1 * e1 + team.D * e2), w * team.D * team.tau2 * e2,
                     w * team.P * e1, w * team.D * e2], axis=1)  # fmt: skip


def _gammas(team: LinkTeam, c: float, y0: NDArray[np.float64], y1: NDArray[np.float64]) -> NDArray[np.float64]:
    """Scalars gamma_m of each piece [c + i y0, c + i y1] (:func:`_link_bounds`), shape (pieces, 4); inf on a zero of p."""
    rho = np.hypot(c, np.maximum(np.abs(y0), np.abs(y1)))
    pmin = np.ones_like(y0)
    for r in _p_roots(team):  # |p| >= product of distances from the zeros of p to the piece
        dy = np.clip(r.imag, y0, y1) - r.imag
        pmin = pmin * np.hypot(c - r.real, dy)
    dp = 2.0 * rho + team.D  # |p'(s)| = |2 s + D| <= 2 |s| + D
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.stack([1.0 / pmin, rho / pmin, dp / pmin**2, rho * dp / pmin**2], axis=1)
    return np.where(np.isfinite(g), g, np.inf)


class _Line:
    """The samples of the line Re s = c and what each piece's certificate needs from them."""

    def __init__(self, team: LinkTeam, c: float) -> None:
        self.team = team
        self.c = c
        n = team.n
        lam = _link_bounds(team, c)
        # Lambda_m^T stacked (4N x N): row m N + k, column j holds Lambda_m[j, k] (link j -> k)
        r = (team.cols[None, :] + n * np.arange(4)[:, None]).ravel()
        self.lamT = sp.csr_array((lam.T.ravel(), (r, np.tile(team.rows, 4))), shape=(4 * n, n))
        # a few MB per batch: larger batches spend more on fresh memory than they save in calls
        self.chunk = max(8, int(5e5 // max(n * n, 1)))

    def links(self, s: NDArray[np.complex128]) -> NDArray[np.complex128]:
        """X(s) on the links, shape (samples, links)."""
        t = self.team
        sl = s[:, None]
        p = sl * sl + t.D * sl + t.P
        with np.errstate(all="ignore"):
            return t.weights * (t.P * np.exp(-t.tau1 * sl) + t.D * sl * np.exp(-t.tau2 * sl)) / p

    def evaluate(self, y: NDArray[np.float64]) -> tuple[NDArray[np.complex128], NDArray[np.float64],
                                                         NDArray[np.complex128], NDArray[np.complex128]]:  # fmt: skip
        """f, ||(|A| Lambda_m)||_F (samples, 4), tr A and A at the transposed links at the points c + i y (chunked)."""
        parts = [self._evaluate(y[i : i + self.chunk]) for i in range(0, y.size, self.chunk)]
        return tuple(np.concatenate([p[k] for p in parts]) for k in range(4))  # type: ignore[return-value]

    def _evaluate(self, y: NDArray[np.float64]) -> tuple[NDArray[np.complex128], NDArray[np.float64],
                                                          NDArray[np.complex128], NDArray[np.complex128]]:  # fmt: skip
        t = self.team
        n, B = t.n, y.size
        xl = self.links(self.c + 1j * y)
        G = np.zeros((B, n, n), dtype=np.complex128)
        idx = np.arange(n)
        G[:, idx, idx] = 1.0
        G[:, t.rows, t.cols] -= xl
        norms = np.full((B, 4), np.inf)
        trA = np.full(B, np.nan + 0j)
        AT = np.full((B, t.rows.size), np.nan + 0j)
        with np.errstate(all="ignore"):
            f = np.linalg.det(G)
        ok = np.flatnonzero(np.isfinite(f) & (np.abs(f) > 0.0))
        if ok.size:
            A = _inverses(G[ok])
            absA = np.abs(A)
            # row m N + k, column b N + i of R is (|A_b| Lambda_m)[i, k]: one sparse product for the batch
            R = self.lamT @ absA.reshape(ok.size * n, n).T
            with np.errstate(invalid="ignore", over="ignore"):
                np.square(R, out=R)
                norms[ok] = np.sqrt(R.reshape(4, n, ok.size, n).sum(axis=(1, 3))).T
            trA[ok] = np.einsum("bii->b", A)
            AT[ok] = A[:, t.cols, t.rows]
        norms = np.where(np.isfinite(norms), norms, np.inf)
        return f, norms, trA, AT


def _inverses(G: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """G^{-1} of each matrix; NaN for one LAPACK finds exactly singular (its pieces then split)."""
    with np.errstate(all="ignore"):
        try:
            return np.linalg.inv(G)
        except np.linalg.LinAlgError:
            out = np.full(G.shape, np.nan + 0j)
            for k in range(G.shape[0]):
                try:
                    out[k] = np.linalg.inv(G[k])
                except np.linalg.LinAlgError:
                    pass
            return out


def _phi(norms: NDArray[np.float64], gam: NDArray[np.float64], h: NDArray[np.float64]) -> NDArray[np.float64]:
    """phi = h sum_m gamma_m ||(|A| Lambda_m)||_F of each piece (inf where a sample is singular)."""
    with np.errstate(invalid="ignore", over="ignore"):
        q = h * np.sum(gam * norms, axis=1)
    return np.where(np.isfinite(q), q, np.inf)


def _budget(n: int) -> int:
    return int(MAX_SAMPLES * min(1.0, (_BUDGET_AGENTS / max(n, 1)) ** 2)) + 1000


def _phase_change(team: LinkTeam, c: float, R: float) -> float | None:
    """Continuous change of arg f along c + i y, y from 0 to R; None if the budget is exceeded."""
    line = _Line(team, c)
    y = np.linspace(0.0, R, 129)
    f, norms, trA, AT = line.evaluate(y)
    budget = _budget(team.n)
    while True:
        gam = _gammas(team, c, y[:-1], y[1:])
        h = np.diff(y)
        phi_a, phi_b = _phi(norms[:-1], gam, h), _phi(norms[1:], gam, h)
        phi = np.minimum(phi_a, phi_b)
        valid = np.isfinite(f) & (f != 0.0)  # both ends' f enter the phase: a failed evaluation never passes
        bad = ~(phi <= PHI_MAX) | ~(valid[:-1] & valid[1:])
        if not bad.any():
            return _sum_pieces(line, y, f, trA, AT, phi_a <= phi_b)
        # split each failing piece into as many parts as its bound asks for (at most 64)
        k = np.flatnonzero(bad)
        parts = np.where(np.isfinite(phi[k]), np.clip(np.ceil(1.15 * phi[k] / PHI_MAX), 2, 64), 2).astype(np.int64)
        piece = np.repeat(np.arange(k.size), parts - 1)
        step = np.arange(piece.size) - np.repeat(np.cumsum(parts - 1) - (parts - 1), parts - 1) + 1  # 1 .. parts - 1
        add = y[k][piece] + (y[k + 1] - y[k])[piece] * (step / parts[piece])
        if add.size + y.size > budget:
            return None
        new = line.evaluate(add)
        order = np.argsort(np.concatenate([y, add]), kind="stable")
        y = np.concatenate([y, add])[order]
        f, norms, trA, AT = (np.concatenate([old, nw])[order] for old, nw in zip((f, norms, trA, AT), new))


def _sum_pieces(line: _Line, y: NDArray[np.float64], f: NDArray[np.complex128], trA: NDArray[np.complex128],
                AT: NDArray[np.complex128], from_left: NDArray[np.bool_]) -> float:  # fmt: skip
    """Sum of the certified phase changes of the pieces (module docstring).

    From the left end a the estimate of the change is ``Im tr(A_a G_b)``; from the right end
    b it is ``-Im tr(A_b G_a)`` (the change from b back to a, reversed).
    """
    xl = line.links(line.c + 1j * y)
    # tr(A G) with G = I - X on the links: tr A - sum over links (j, k) of A[k, j] X[j, k]
    fwd = (trA[:-1] - np.einsum("bl,bl->b", AT[:-1], xl[1:])).imag
    bwd = -(trA[1:] - np.einsum("bl,bl->b", AT[1:], xl[:-1])).imag
    est = np.where(from_left, fwd, bwd)
    theta = np.angle(f[1:] / f[:-1])
    return float(np.sum(theta + 2.0 * math.pi * np.round((est - theta) / (2.0 * math.pi))))


def count_right_of(team: LinkTeam, c: float) -> int | None:
    """Certified number of roots of det M(s) with Re s > c, multiplicity counted (s = 0 included).

    ``team`` is the per-link team (:class:`~delayform.analysis.network.links.LinkTeam`).

    None when the line cannot be certified within the sampling budget (a root on
    or extremely close to Re s = c).
    """
    with single_threaded_blas():
        return _count(team, c)


def _count(team: LinkTeam, c: float) -> int | None:
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
    if not math.isfinite(w) or abs(w - round(w)) > 1e-3:
        return None
    poles = int(np.sum(_p_roots(team).real > c))
    return int(round(w)) + team.n * poles
