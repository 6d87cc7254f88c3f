"""Seeds for the per-link roots: Chebyshev collocation of the 2N-state DDE's generator.

The state of the paper's eq. 1 with per-link delays is z = (x, x') in R^{2N} with

    x' = v,   v_i' = -P x_i - D v_i + sum_k C_ik (P x_k(t - tau1_ik) + D v_k(t - tau2_ik)).

Its infinitesimal generator acts on the history z(theta), theta in [-h, 0]
(h the longest delay). Collocating the history at the M + 1 Chebyshev points
theta_j = h (x_j - 1) / 2, x_j = cos(j pi / M) (Breda, Maset & Vermiglio,
SIAM J. Sci. Comput. 2005) gives a matrix of size 2N (M + 1) whose rightmost
eigenvalues converge spectrally to the rightmost characteristic roots: the rows
j >= 1 are the differentiation matrix, row 0 is the DDE itself with each
delayed value read by barycentric interpolation at theta = -tau_ik. Only the
links enter row 0, so the matrix is sparse for a sparse team; its eigenvalues
are seeds, polished on det M(s) (:mod:`delayform.analysis.network.per_link`).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from delayform.analysis.network.links import LinkTeam

__all__ = ["generator_matrix", "generator_seeds", "band_seeds"]

#: Above this many states the eigenvalues come from shift-and-invert Arnoldi, not a dense solve.
DENSE_STATES = 900


def _nodes(M: int) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Chebyshev points x_j = cos(j pi / M), their barycentric weights and differentiation matrix."""
    j = np.arange(M + 1)
    x = np.cos(np.pi * j / M)
    w = (-1.0) ** j
    w[[0, -1]] *= 0.5
    dx = x[:, None] - x[None, :]
    np.fill_diagonal(dx, 1.0)
    Dm = (w[None, :] / w[:, None]) / dx
    np.fill_diagonal(Dm, 0.0)
    np.fill_diagonal(Dm, -Dm.sum(axis=1))  # rows of a differentiation matrix annihilate constants
    return x, w, Dm


def _interpolation_rows(x: NDArray[np.float64], w: NDArray[np.float64], xq: NDArray[np.float64]) -> NDArray[np.float64]:
    """Barycentric Lagrange basis at the points xq: shape (len(xq), M + 1)."""
    diff = xq[:, None] - x[None, :]
    exact = np.isclose(diff, 0.0, atol=1e-15)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = w[None, :] / diff
        rows = terms / terms.sum(axis=1, keepdims=True)
    hit = exact.any(axis=1)
    rows[hit] = exact[hit].astype(np.float64)
    return rows


def _entries(team: LinkTeam, M: int) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], int]:
    """Rows, columns and values of the collocated generator (duplicates add), and its size 2N (M + 1).

    Unknowns ordered node-major: block j holds z(theta_j) = (x, v).
    """
    n = team.n
    m = 2 * n
    h = max(team.max_delay, 1e-12)
    x, w, Dm = _nodes(M)
    scale = 2.0 / h  # d/dtheta = (2 / h) d/dx
    # rows j >= 1: z'(theta_j) = sum_l scale Dm[j, l] z(theta_l), every component q alike (kron(Dm, I))
    j, l, q = np.meshgrid(np.arange(1, M + 1), np.arange(M + 1), np.arange(m), indexing="ij")
    r = [(j * m + q).ravel()]
    c = [(l * m + q).ravel()]
    v = [np.repeat((scale * Dm[1:, :]).ravel(), m)]
    idx = np.arange(n)
    # row 0: the DDE at theta = 0 (own state undelayed, the paper's eq. 1)
    r += [idx, n + idx, n + idx]
    c += [n + idx, idx, n + idx]
    v += [np.ones(n), np.full(n, -team.P), np.full(n, -team.D)]
    for taus, gain, comp in ((team.tau1, team.P, 0), (team.tau2, team.D, n)):
        L = _interpolation_rows(x, w, 1.0 - 2.0 * taus / h)  # theta = -tau  <->  x = 1 - 2 tau / h
        jj, nodes = np.nonzero(L)
        r.append(n + team.rows[jj])
        c.append(nodes * m + comp + team.cols[jj])
        v.append(gain * team.weights[jj] * L[jj, nodes])
    return np.concatenate(r), np.concatenate(c), np.concatenate(v), m * (M + 1)


def generator_matrix(team: LinkTeam, M: int) -> sp.csr_array:
    """The collocated generator of ``team`` (module docstring) as a sparse matrix of size 2N (M + 1).

    Unknowns ordered node-major: block j holds z(theta_j) = (x, v).
    """
    r, c, v, size = _entries(team, M)
    return sp.coo_array((v, (r, c)), shape=(size, size)).tocsr()


#: distance between the shifts of :func:`generator_seeds` along the imaginary axis
SHIFT_SPACING = 0.75


def generator_seeds(team: LinkTeam, M: int, radius: float, *, centre: float = 0.0, nearest: int = 40,
                    spacing: float = SHIFT_SPACING) -> NDArray[np.complex128]:  # fmt: skip
    """Eigenvalues of the generator of ``team`` collocated at M + 1 points, with |s| <= radius (conjugates included).

    Dense for small problems; otherwise shift-and-invert Arnoldi (sparse LU of the
    generator) at the shifts ``centre + i y``, y = 0, ``spacing``, ... up to ``radius``,
    each giving its ``nearest`` eigenvalues: the ones near the line Re s = centre,
    where the dominant roots are. Seeds only: the caller's certified count decides
    whether they found every root that matters.
    """
    r, c, v, size = _entries(team, M)
    if size <= DENSE_STATES:
        dense = np.zeros((size, size))
        np.add.at(dense, (r, c), v)
        vals = sla.eigvals(dense, overwrite_a=True, check_finite=False)
    else:
        A = sp.coo_array((v, (r, c)), shape=(size, size)).tocsr()
        k = min(nearest, size - 2)
        shifts = centre + 1j * np.arange(0.0, radius + spacing, spacing)
        found = [_nearest(A, sig, k) for sig in shifts]
        vals = np.concatenate(found)
        vals = np.concatenate([vals, vals.conj()])
    vals = vals[np.isfinite(vals)]
    return vals[np.abs(vals) <= radius]


def _nearest(A: sp.csr_array, sig: complex, k: int) -> NDArray[np.complex128]:
    """The k eigenvalues of A nearest ``sig`` (shift-and-invert Arnoldi on a sparse LU)."""
    size = A.shape[0]
    op = spla.splu((A - sig * sp.eye(size, format="csc")).astype(np.complex128).tocsc())
    lin = spla.LinearOperator((size, size), matvec=op.solve, dtype=np.complex128)
    # a fixed start vector: the same seeds, line and count on every run (ARPACK's default is random)
    v0 = np.random.default_rng(size).standard_normal(size).astype(np.complex128)
    try:
        mu = spla.eigs(lin, k=k, which="LM", v0=v0, return_eigenvectors=False, tol=1e-8, maxiter=2000)
    except spla.ArpackNoConvergence as err:  # the converged ones are still eigenvalues; coverage shrinks with them
        mu = err.eigenvalues
    return sig + 1.0 / mu


#: Most shifts one band may take (seeds only: the certified count judges what they found).
MAX_SHIFTS = 60


def band_seeds(team: LinkTeam, M: int, left: float, right: float, height: float,
               *, nearest: int = 30) -> NDArray[np.complex128]:  # fmt: skip
    """Every eigenvalue of the collocated generator in the band left <= Re s <= right, 0 <= Im s <= height.

    Empty when the generator is small enough for :func:`generator_seeds` to have
    returned all its eigenvalues. Otherwise shift-and-invert Arnoldi at shifts
    ``x0 + i y`` on the band's midline x0: the k eigenvalues nearest a shift are all
    those within the distance d of the k-th, so that shift covers the band for
    ``|Im s - y| <= sqrt(d^2 - w^2)`` (w the half-width). Shifts advance by the
    coverage they achieve (long strides where the band is empty, short ones in a
    cluster; k doubles when the disc does not even span the band) until 0..height
    is covered or :data:`MAX_SHIFTS` is spent. As complete as Arnoldi's convergence;
    the certified count of :mod:`delayform.analysis.network.count` decides.

    Parameters
    ----------
    team
        The team and its per-link delays.
    M
        Chebyshev intervals of the collocation.
    left, right, height
        The band: ``left <= Re s <= right``, ``0 <= Im s <= height``.
    nearest
        Eigenvalues asked of each shift at first (doubled in a crowded band).

    Returns
    -------
    NDArray
        Every eigenvalue found (those of the band and others near it); empty when
        the generator is small enough for a dense solve.
    """
    if 2 * team.n * (M + 1) <= DENSE_STATES:
        return np.zeros(0, np.complex128)
    r, c, v, size = _entries(team, M)
    A = sp.coo_array((v, (r, c)), shape=(size, size)).tocsr()
    x0, w = 0.5 * (left + right), 0.5 * (right - left)
    k = min(nearest, size - 2)
    found: list[NDArray[np.complex128]] = []
    covered, y, stride = 0.0, 0.0, w
    for _ in range(MAX_SHIFTS):
        lam = _nearest(A, x0 + 1j * y, k)
        found.append(lam)
        # the k nearest are known only when all k converged
        d = float(np.abs(lam - (x0 + 1j * y)).max()) if lam.size == k else 0.0
        if d <= 1.05 * w and k < min(8 * nearest, size - 2):
            k = min(2 * k, size - 2)  # a crowded band: more eigenvalues per shift
            continue
        half = math.sqrt(max(d * d - w * w, 0.0))
        if y - half <= covered:
            covered = max(covered, y + half)
        if covered >= height:
            break
        stride = max(half, 0.05 * w)
        y = covered + 0.9 * stride
    return np.concatenate(found) if found else np.zeros(0, np.complex128)
