"""Seeds of the family's roots: the discretized generator of every factor in stacked eigenvalue calls.

The reduced Chebyshev discretization (:func:`_generator_blocks`) of the factor of
lam has the eigenvalues of ``K0 + lam K1``; ``K0`` and ``K1`` depend only on the
delays (cached per delay pair, or built for many pairs at once).
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.roots.generator import _chebyshev, _lagrange_rows
from delayform.analysis.roots.problem import _TINY_DELAY, MAX_DEGREE
from delayform.analysis.roots.family.rows import Gain, _at, _delay_free, _root_scales


try:  # the gufunc behind np.linalg.eigvals (see _eigvals)
    from numpy.linalg._umath_linalg import eigvals as _LAPACK_EIGVALS
except ImportError:  # pragma: no cover - NumPy moved its private kernel
    _LAPACK_EIGVALS = None


# =====================================================================
# seeds: the discretized generator of every factor in one stacked call
# =====================================================================
@lru_cache(maxsize=32)
def _generator_blocks(N: int, t1: float, t2: float, P: float, D: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(K0, K1) of size N + 2 whose K0 + lam K1 has the eigenvalues of the discretized generator.

    The degree-N Chebyshev discretization of the paper's eq. 8 of the second-order factor
    (A = [[0, 1], [-P, -D]], B1 = lam [[0, 0], [P, 0]], B2 = lam [[0, 0], [0, D]]) has size
    2 (N + 1): position y and velocity z at the N + 1 nodes of [-h_max, 0]. Its rows 1..N
    (u' = du/dtheta) act alike on y and z, so an eigenvector with y != 0 has z = mu y; N of
    its eigenvalues belong to y = 0 (z0 = 0, the spurious ones of the differentiation
    matrix alone). With w = mu y_0 the others solve a standard eigenproblem in (y, w):

        mu y_0 = w,   mu y_i = (Dm y)_i (i >= 1),
        mu w = -P y_0 - D w + lam (P L1 . y + D L2 . (mu y)),

    where mu y in the delayed velocity is (w, (Dm y)_1..N). Same eigenvalues as the full
    matrix (to rounding), without the spurious ones, at a third of the cost per call.
    Only the last row depends on lam (the delays enter through the interpolation rows
    L1, L2, hence the cache per delays).
    """
    K0, K1 = _generator_stack(N, np.array([t1]), np.array([t2]), P, D)
    return K0[0], K1[0]


def _generator_stack(
    N: int, t1: NDArray[np.float64], t2: NDArray[np.float64], P: Gain, D: Gain
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:func:`_generator_blocks` at many delay pairs (and gains, one or one per pair) at once, shape (B, N + 2, N + 2)."""
    _, Dm, _ = _chebyshev(N)
    h = np.stack([t1, t2], axis=-1)  # (B, 2)
    hmax = h.max(axis=-1)
    L = _lagrange_rows(N, 1.0 - 2.0 * h / hmax[:, None])  # (B, 2, N+1)
    Dh = (2.0 / hmax)[:, None, None] * Dm[1:]  # (B, N, N+1)
    B = t1.size
    K0 = np.zeros((B, N + 2, N + 2))
    K0[:, 0, N + 1] = 1.0
    K0[:, 1 : N + 1, : N + 1] = Dh
    K0[:, N + 1, 0], K0[:, N + 1, N + 1] = -P, -D
    K1 = np.zeros((B, N + 2, N + 2))
    Pc, Dc = np.reshape(P, (-1, 1)), np.reshape(D, (-1, 1))  # (1, 1) or (B, 1)
    K1[:, N + 1, : N + 1] = Pc * L[:, 0] + Dc * np.einsum("bj,bjk->bk", L[:, 1, 1:], Dh)
    K1[:, N + 1, N + 1] = D * L[:, 1, 0]
    return K0, K1


@lru_cache(maxsize=32)
def _seed_plan(
    lam_bytes: bytes, P: float, D: float
) -> tuple[float, NDArray[np.bool_], NDArray[np.float64] | None, NDArray[np.complex128] | None]:
    """What the seeds of a family need beyond the delays: the root scale, the real-lam mask, lam stacked.

    The scale is :func:`delayform.analysis.roots.generator._root_scale` over all factors (the
    delay-free roots and the norm of A); real lam are stacked as real (F_r, 1, 1), complex lam
    as complex (F_c, 1, 1) (None when there are none). Cached per (lam, P, D).
    """
    lam = np.frombuffer(lam_bytes, dtype=np.complex128)
    radius = float(_root_scales(lam, P, D).max())
    real = lam.imag == 0.0
    lam_real = lam.real[real][:, None, None].copy() if real.any() else None
    lam_cplx = lam[~real][:, None, None].copy() if not real.all() else None
    return radius, real, lam_real, lam_cplx


def _eigvals(a: NDArray[Any]) -> NDArray[np.complex128]:
    """Eigenvalues of a stack of small matrices, complex, NaN where LAPACK does not converge.

    The LAPACK kernel behind np.linalg.eigvals, called directly: its wrapper's checks
    (stacked, square, finite, then a scan for real results) cost as much as the solve
    itself on the 8 x 8 matrices of one delay pair. Callers build finite matrices and run
    under ``np.errstate(all="ignore")``; they treat a NaN seed as missing.
    """
    if _LAPACK_EIGVALS is None:  # a NumPy without the private kernel: the public route
        return np.linalg.eigvals(a).astype(np.complex128)
    return _LAPACK_EIGVALS(a, signature="d->D" if a.dtype == np.float64 else "D->D")  # type: ignore[no-any-return]


def _family_seeds(lam: NDArray[np.complex128], P: float, D: float, t1: float, t2: float, k: int) -> NDArray[np.complex128]:
    """The k rightmost eigenvalues of every factor's discretized generator at one pair (F, k)."""
    hmax = max(t1, t2)
    F = lam.size
    if hmax < _TINY_DELAY:  # delay-free: s^2 + D (1 - lam) s + P (1 - lam) = 0
        eig = _delay_free(lam, P, D)
    else:
        radius, real, lam_real, lam_cplx = _seed_plan(lam.tobytes(), float(P), float(D))
        N = min(max(math.ceil(0.6 * radius * hmax + 4), 6), MAX_DEGREE)
        M0, M1 = _generator_blocks(N, float(t1), float(t2), float(P), float(D))
        # real lam in one real stacked call (LAPACK's real solver is several times cheaper)
        if lam_cplx is None:
            eig = _eigvals(M0 + lam_real * M1)
        else:
            eig = np.empty((F, M0.shape[0]), dtype=np.complex128)
            if lam_real is not None:
                eig[real] = _eigvals(M0 + lam_real * M1)
            eig[~real] = _eigvals(M0 + lam_cplx * M1)
        # a real lam's matrix is real: its complex eigenvalues come in exact conjugate pairs,
        # and the certificate folds a real row's seeds to Im >= 0 -- keep one of each pair
        eig[real[:, None] & (eig.imag < 0.0)] = np.nan
    return _rightmost_k(eig, k)


def _rightmost_k(eig: NDArray[np.complex128], k: int) -> NDArray[np.complex128]:
    """The k entries of largest real part per row (NaN last, NaN-padded to k columns)."""
    F, width = eig.shape
    if width == k:  # the certificate's seed window selects anyway
        return eig
    order = np.argsort(np.where(np.isnan(eig.real), np.inf, -eig.real), axis=1)[:, :k]
    top = eig[np.arange(F)[:, None], order]
    if top.shape[1] == k:
        return top
    out = np.full((F, k), np.nan + 0j)
    out[:, : top.shape[1]] = top
    return out


def _row_seeds(
    lam: NDArray[np.complex128], t1: NDArray[np.float64], t2: NDArray[np.float64], P: Gain, D: Gain, k: int
) -> NDArray[np.complex128]:
    """:func:`_family_seeds` of rows each at its own delay pair, shape (R, k).

    Row r gets exactly the seeds of ``_family_seeds(lam[r:r+1], P, D, t1[r], t2[r], k)``;
    rows whose discretizations have the same size share one stacked eigenvalue call
    (the map's retries are scattered over many delay pairs, one factor each).
    """
    R = lam.size
    out = np.full((R, k), np.nan + 0j)
    hmax = np.maximum(t1, t2)
    tiny = hmax < _TINY_DELAY
    if tiny.any():  # delay-free: s^2 + D (1 - lam) s + P (1 - lam) = 0
        free_roots = _delay_free(lam, P, D)[tiny]
        order = np.argsort(-free_roots.real, axis=1)[:, :k]
        out[tiny, : order.shape[1]] = free_roots[np.arange(order.shape[0])[:, None], order]
    radius = _root_scales(lam, P, D)
    N = np.clip(np.ceil(0.6 * radius * hmax + 4), 6, MAX_DEGREE).astype(int)
    for n in np.unique(N[~tiny]):
        for real in (True, False):
            idx = np.flatnonzero(~tiny & (N == n) & ((lam.imag == 0.0) == real))
            if idx.size == 0:
                continue
            M0, M1 = _generator_stack(int(n), t1[idx], t2[idx], _at(P, idx), _at(D, idx))
            lr = lam[idx].real if real else lam[idx]
            eig = _eigvals(M0 + lr[:, None, None] * M1)
            if real:  # one of each conjugate pair (see _family_seeds)
                eig[eig.imag < 0.0] = np.nan
            top = _rightmost_k(eig, min(k, eig.shape[1]))
            out[idx, : top.shape[1]] = top
    return out
