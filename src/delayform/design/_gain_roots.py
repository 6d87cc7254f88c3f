"""Certified rightmost roots of the formation's factors for many (P, D, tau1, tau2) at once.

:mod:`delayform.analysis.spectrum` batches over delays for fixed gains (one
quasi-polynomial, many delay pairs). Gain design needs the other direction:
many gains (and, for the robust design, many delays) per factor. Every factor
of eq. factorized is, through its eigenvalue lam of C (a conjugate pair
through lam alone, as in :mod:`delayform.analysis.spectrum`),

    q(s) = s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s}),

so each *line* of a batch is one (P, D, tau1, tau2) and the same three steps
as the spectrum module run on all lines together:

1. seeds: the rightmost eigenvalues of the Chebyshev discretization of the
   infinitesimal generator of each line's subsystem (eq. subsystems), stacked
   into one ``np.linalg.eigvals`` call per discretization degree;
2. Newton on q itself (Maehly's deflation of the persistent zero of
   eq. factor1), accepting relative residuals <= ``RESIDUAL_TOL``;
3. the certificate: the argument principle along a line Re s = c left of the
   roots found, with the Lipschitz-certified sampling of the spectrum module
   written for per-line coefficients; the count must equal the number of
   polished roots right of c.

Lines the certificate rejects are redone at twice the degree, and any still
rejected by the spectrum module's robust single-pair path
(:func:`~delayform.analysis.spectrum.rightmost_root`). Every root returned is
therefore certified: no root of its factor lies to its right. As in
:func:`~delayform.analysis.spectrum.dominant_root`, the centroid factor's
roots at s = 0 are not counted: the persistent one, and on tau1 = 0 the
second one (the centroid's drift), for which the spectrum module's
centroid path is used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.certificate import adaptive_winding
from delayform.analysis._generator import _chebyshev, _lagrange_rows, _map_degree
from delayform.analysis._quasi import MAX_DEGREE, RESIDUAL_TOL, _problem_of_factor
from delayform.analysis._rightmost import _BATCH_SEEDS, _SEED_WINDOW, _batch_distinct
from delayform.analysis.certificate import _batch_lines
from delayform.analysis.roots import rightmost_root
from delayform.analysis.spectrum import _centroid_rightmost
from delayform.characteristic import CharacteristicFactor
from delayform.topology import EigenvalueGroup

_Arr = NDArray[np.float64]
_CArr = NDArray[np.complex128]

#: Lines per stacked eigenvalue call (bounds memory).
_CHUNK = 2048
_NEWTON_MAXITER = 50


@dataclass(frozen=True)
class _Lines:
    """A batch: line i is the factor at gains (P[i], D[i]) and delays (t1[i], t2[i])."""

    P: _Arr
    D: _Arr
    t1: _Arr
    t2: _Arr

    @property
    def size(self) -> int:
        return int(self.P.size)

    def take(self, idx: NDArray[np.int64]) -> _Lines:
        return _Lines(self.P[idx], self.D[idx], self.t1[idx], self.t2[idx])


def _lines(P: object, D: object, t1: object, t2: object) -> _Lines:
    arrays = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (P, D, t1, t2)))
    return _Lines(*(np.ascontiguousarray(a).ravel() for a in arrays))


# ------------------------------------------------------------------ evaluation
def _q(
    lam: complex, L: _Lines, s: _CArr, *, magnitude: bool = False
) -> tuple[_CArr, _CArr, _Arr]:
    """q(s), dq/ds and (optionally) the sum of the moduli of its terms; s has shape (B,) or (B, K)."""
    col = (slice(None),) + (None,) * (s.ndim - 1)
    P, D, t1, t2 = L.P[col], L.D[col], L.t1[col], L.t2[col]
    with np.errstate(all="ignore"):  # far-left seeds overflow; callers drop non-finite values
        e1, e2 = np.exp(-t1 * s), np.exp(-t2 * s)
        q = s * (s + D) + P - lam * (D * s * e2 + P * e1)
        dq = 2.0 * s + D - lam * (D * e2 * (1.0 - t2 * s) - t1 * P * e1)
        if not magnitude:
            return q, dq, np.zeros(0)
        a = np.abs(s)
        mag = a * (a + D) + P + abs(lam) * (D * a * np.abs(e2) + P * np.abs(e1))
    return q, dq, mag


def _polish(lam: complex, centroid: bool, L: _Lines, s0: _CArr) -> tuple[_CArr, NDArray[np.bool_]]:
    """Newton on q from seeds s0 (B, K); Maehly's step q / (q' - q/s) for the centroid factor."""
    s = np.where(np.isfinite(s0), s0, 0.0).astype(np.complex128)
    finite = np.isfinite(s0)
    rows, cols = np.nonzero(finite)
    for _ in range(_NEWTON_MAXITER):
        if rows.size == 0:
            break
        sub = L.take(rows)
        sa = s[rows, cols]
        q, dq, _ = _q(lam, sub, sa)
        with np.errstate(all="ignore"):
            step = q / (dq - q / sa) if centroid else q / dq
        bad = ~np.isfinite(step) | ((sa == 0.0) if centroid else False)
        step[bad] = 0.0
        s[rows, cols] = sa - step
        moving = ~bad & (np.abs(step) > 4e-16 * (1.0 + np.abs(sa)))
        rows, cols = rows[moving], cols[moving]
    q, _, mag = _q(lam, L, s, magnitude=True)
    with np.errstate(all="ignore"):
        ok = finite & np.isfinite(mag) & (np.abs(q) <= RESIDUAL_TOL * mag)
    if centroid:  # a seed that fell into the persistent zero is a root of q(s)/s only if 0 is double
        near = np.abs(s) < 1e-6
        double = (L.P * L.t1 <= 1e-12 * (1.0 + L.P + L.D))[:, None]
        s = np.where(near & double, 0.0, s)
        ok &= ~near | double
    return s, ok


# ------------------------------------------------------------------ seeds
def _root_scale(lam: complex, L: _Lines) -> _Arr:
    """Per line: the size of the delay-free roots and of A (as the spectrum module's ``_root_scale``)."""
    b, c = L.D * (1.0 - lam), L.P * (1.0 - lam)
    disc = np.sqrt(b * b - 4.0 * c + 0j)
    delay_free = np.maximum(np.abs(-b + disc), np.abs(-b - disc)) / 2.0
    norm_a = np.sqrt(1.0 + L.P**2 + L.D**2)  # Frobenius bound of ||A||_2
    return np.maximum.reduce([np.ones(L.size), delay_free, norm_a])


def _generator_eigenvalues(lam: complex, L: _Lines, N: int) -> _CArr:
    """Eigenvalues of the degree-N discretized generator of each line's subsystem (eq. subsystems)."""
    x, Dm, _ = _chebyshev(N)
    B = L.size
    h = np.stack([L.t1, L.t2], axis=-1)  # (B, 2)
    hmax = h.max(axis=-1)
    Lr = _lagrange_rows(N, 1.0 - 2.0 * h / hmax[:, None])  # (B, 2, N+1)
    real = complex(lam).imag == 0.0
    dtype = np.float64 if real else np.complex128
    lam_v = lam.real if real else lam
    Bk = np.zeros((B, 2, 2, 2), dtype=dtype)
    Bk[:, 0, 1, 0] = lam_v * L.P
    Bk[:, 1, 1, 1] = lam_v * L.D
    M = np.zeros((B, N + 1, 2, N + 1, 2), dtype=dtype)
    M[:, 0] = np.einsum("bkj,bkpq->bpjq", Lr, Bk)
    M[:, 0, 0, 0, 1] += 1.0
    M[:, 0, 1, 0, 0] -= L.P
    M[:, 0, 1, 0, 1] -= L.D
    M[:, 1:] = (2.0 / hmax)[:, None, None, None, None] * np.einsum("ij,pq->ipjq", Dm[1:], np.eye(2))
    size = 2 * (N + 1)
    return np.linalg.eigvals(M.reshape(B, size, size)).astype(np.complex128)


def _seeds(lam: complex, centroid: bool, L: _Lines, *, scale: float, k: int) -> _CArr:
    """The k rightmost eigenvalues per line (NaN-padded), the persistent zero of eq. factor1 dropped."""
    out = np.full((L.size, k), np.nan + 0j)
    hmax = np.maximum(L.t1, L.t2)
    radius = _root_scale(lam, L)
    degree = np.minimum(MAX_DEGREE, np.ceil(scale * _map_degree(hmax, radius))).astype(int)  # type: ignore[arg-type]
    delayed = hmax >= 1e-10
    real = complex(lam).imag == 0.0
    groups = [(np.flatnonzero(~delayed), 0)] + [
        (np.flatnonzero(delayed & (degree == N)), int(N)) for N in np.unique(degree[delayed])
    ]
    for idx_all, N in groups:
        for start in range(0, idx_all.size, _CHUNK):
            idx = idx_all[start : start + _CHUNK]
            sub = L.take(idx)
            if N == 0:  # delay-free: s^2 + D (1 - lam) s + P (1 - lam)
                b, c = sub.D * (1.0 - lam), sub.P * (1.0 - lam)
                disc = np.sqrt(b * b - 4.0 * c + 0j)
                eig = np.stack([(-b + disc) / 2.0, (-b - disc) / 2.0], axis=1)
            else:
                eig = _generator_eigenvalues(lam, sub, N)
            if centroid:
                eig[np.arange(idx.size), np.argmin(np.abs(eig), axis=1)] = -np.inf
            if real:  # conjugate pairs: one member, the certificate adds the other
                eig = np.where(eig.imag >= 0.0, eig, -np.inf)
            order = np.argsort(-eig.real, axis=1)[:, :k]
            top = np.take_along_axis(eig, order, 1)
            top[~np.isfinite(top)] = np.nan
            out[idx, : top.shape[1]] = top
    return out


# ------------------------------------------------------------------ certificate
def _lipschitz(lam: complex, L: _Lines, rho: _Arr, re_min: _Arr) -> _Arr:
    """Bound of |q'(s)| over |s| <= rho, Re s >= re_min, per line."""
    a = abs(lam)
    with np.errstate(over="ignore"):
        w1, w2 = np.exp(-L.t1 * re_min), np.exp(-L.t2 * re_min)
    return 2.0 * rho + L.D + a * w1 * L.t1 * L.P + a * w2 * L.D * (1.0 + L.t2 * rho)


def _cauchy_radius(lam: complex, L: _Lines, c: _Arr) -> _Arr:
    """Omega with |s^2 + D s + P| > |lam| (D |s| e^{-tau2 c} + P e^{-tau1 c}) for |s| >= Omega on Re s = c."""
    a = abs(lam)
    with np.errstate(over="ignore"):
        b1 = L.D + a * L.D * np.exp(-L.t2 * c)
        b0 = L.P + a * L.P * np.exp(-L.t1 * c)
    return (b1 + np.sqrt(b1 * b1 + 4.0 * b0)) / 2.0 * (1.0 + 1e-9) + 1e-12


def _tail(lam: complex, L: _Lines, s_end: _CArr, *, upper: bool) -> _Arr:
    """Arg change of q beyond s_end = c +- i Omega, where |q / g1 - 1| < 1 (Rouche)."""
    q, _, _ = _q(lam, L, s_end)
    g1 = s_end * (s_end + L.D) + L.P
    disc = np.sqrt(L.D * L.D - 4.0 * L.P + 0j)
    roots = np.stack([(-L.D + disc) / 2.0, (-L.D - disc) / 2.0], axis=1)
    ratio = np.angle(q / g1)
    ang = np.angle(s_end[:, None] - roots)
    if upper:
        return (np.pi / 2 - ang).sum(axis=1) - ratio
    return (ang + np.pi / 2).sum(axis=1) + ratio


def _count_right(
    lam: complex, L: _Lines, c: _Arr, *, initial: int = 17, max_segments: int = 4096
) -> _Arr:
    """Certified number of roots with Re s > c per line (NaN: not certified).

    The certified walk of :func:`~delayform.analysis.certificate.adaptive_winding`
    on the factor of ``lam`` with its own gains and delays per line, closed at
    infinity by the Rouche tails.
    """
    omega = _cauchy_radius(lam, L, c)
    real = complex(lam).imag == 0.0
    total, failed = adaptive_winding(
        c, omega,
        lambda line, s: _q(lam, L.take(line), s)[0],
        lambda line, rho: _lipschitz(lam, L.take(line), rho, c[line]),
        real=real, initial=initial, max_segments=max_segments,
    )  # fmt: skip
    top = _tail(lam, L, c + 1j * omega, upper=True)
    if real:
        delta = 2.0 * (total + top)
    else:
        delta = total + top + _tail(lam, L, c - 1j * omega, upper=False)
    count = 1.0 - delta / (2.0 * np.pi)  # q has degree 2
    good = ~failed & (np.abs(count - np.round(count)) < 0.1)
    return np.where(good, np.round(count), np.nan)


def _certify(
    group: EigenvalueGroup, L: _Lines, seeds: _CArr
) -> tuple[_CArr, NDArray[np.bool_], _CArr]:
    """Polish seeds (B, K), certify the rightmost per line: (rightmost, certified, distinct roots)."""
    lam = complex(group.lam)
    centroid = group.is_centroid
    real = lam.imag == 0.0
    if real:
        seeds = np.where(seeds.imag >= 0.0, seeds, np.nan)
    if centroid:
        seeds = np.where(np.abs(seeds) < 1e-6, -1e-2, seeds)
    with np.errstate(invalid="ignore"):
        top_seed = np.nanmax(np.where(np.isfinite(seeds), seeds.real, -np.inf), axis=1)
        seeds = np.where(seeds.real >= top_seed[:, None] - _SEED_WINDOW, seeds, np.nan)
    roots, ok = _polish(lam, centroid, L, seeds)
    ok &= np.isfinite(seeds)
    if real:
        roots = _batch_distinct(np.where(roots.imag < 0.0, np.conj(roots), roots), ok)
        pair = np.abs(roots.imag) > 1e-9 * (1.0 + np.abs(roots))
        roots = np.concatenate([roots, np.where(pair, np.conj(roots), np.nan)], axis=1)
    else:
        roots = _batch_distinct(roots, ok)
    # the line choice reads only whether the persistent zero is deflated
    prob = _problem_of_factor(CharacteristicFactor(group, 1.0, 1.0))
    c, expected, top = _batch_lines(prob, roots)
    good = np.isfinite(top) & np.isfinite(c)
    counts = np.full(L.size, np.nan)
    if good.any():
        idx = np.flatnonzero(good)
        counts[idx] = _count_right(lam, L.take(idx), c[idx])
    certified = good & (counts == expected)
    best = np.argmax(np.where(np.isnan(roots.real), -np.inf, roots.real), axis=1)
    return roots[np.arange(L.size), best], certified, roots


def rightmost_roots(
    group: EigenvalueGroup, L: _Lines, seeds: _CArr | None = None
) -> tuple[_CArr, _CArr]:
    """Certified rightmost root (Im >= 0 member) of the factor of ``group`` on every line.

    ``seeds`` (B, K), e.g. the roots of a nearby line (roots move continuously
    with the gains), replace the discretization where the certificate accepts
    them. Returns the rightmost roots and every line's distinct roots found
    (NaN-padded), the seeds for the next nearby batch.
    """
    lam = complex(group.lam)
    out = np.full(L.size, np.nan + 0j)
    if seeds is None:
        seeds = _seeds(lam, group.is_centroid, L, scale=1.0, k=_BATCH_SEEDS)
    root, cert, found = _certify(group, L, seeds)
    out[cert] = root[cert]
    if group.is_centroid:  # on tau1 = 0 the second root at 0 is the centroid's drift: not counted either
        for i in np.flatnonzero(L.t1 == 0.0):
            f = CharacteristicFactor(group, float(L.P[i]), float(L.D[i]))
            r = _centroid_rightmost(f, 0.0, float(L.t2[i]))
            out[i] = complex(-np.inf, 0.0) if r is None else r
            cert[i] = True
            found = _merge_rows(found, np.array([i]), np.array([[out[i]]]))
    left = np.flatnonzero(~cert)
    if left.size:
        sub = L.take(left)
        for scale, k in ((1.0, _BATCH_SEEDS), (2.0, 2 * _BATCH_SEEDS)):
            r, ok, more = _certify(group, sub, _seeds(lam, group.is_centroid, sub, scale=scale, k=k))
            out[left[ok]] = r[ok]
            found = _merge_rows(found, left[ok], more[ok])
            left, sub = left[~ok], sub.take(np.flatnonzero(~ok))
            if left.size == 0:
                break
        for i in left:  # the spectrum module's robust path, certified or raising
            f = CharacteristicFactor(group, float(L.P[i]), float(L.D[i]))
            out[i] = rightmost_root(f, float(L.t1[i]), float(L.t2[i]))
            found = _merge_rows(found, np.array([i]), np.array([[out[i]]]))
    return out.real + 1j * np.abs(out.imag), found


def _merge_rows(found: _CArr, rows: NDArray[np.int64], new: _CArr) -> _CArr:
    """``found`` with the given rows replaced by ``new`` (widened with NaN as needed)."""
    if rows.size == 0:
        return found
    width = max(found.shape[1], new.shape[1])
    out = np.full((found.shape[0], width), np.nan + 0j)
    out[:, : found.shape[1]] = found
    out[rows] = np.nan
    out[rows, : new.shape[1]] = new
    return out


def root_gradients(
    lam: complex, L: _Lines, s: _CArr
) -> tuple[_Arr, _Arr, _Arr, _Arr]:
    """d Re s / d(P, D, tau1, tau2) of simple roots s, by implicit differentiation of q(s) = 0.

    ds/dx = -(dq/dx) / (dq/ds) with dq/dP = 1 - lam e^{-tau1 s},
    dq/dD = s (1 - lam e^{-tau2 s}), dq/dtau1 = lam P s e^{-tau1 s} and
    dq/dtau2 = lam D s^2 e^{-tau2 s}. For a conjugate-pair factor the
    conjugate root of the conjugate factor has the same real part, so ``s``
    may be either member; a real-coefficient factor's mirror image likewise.
    """
    s = np.asarray(s, dtype=np.complex128)
    # the member of lam's own factor (for a complex lam the Im >= 0 member may be conj(lam)'s)
    q_now, _, mag = _q(lam, L, s, magnitude=True)
    s = np.where(np.abs(q_now) > 1e-6 * mag, np.conj(s), s)
    _, dq, _ = _q(lam, L, s)
    with np.errstate(all="ignore"):
        e1, e2 = np.exp(-L.t1 * s), np.exp(-L.t2 * s)
        parts = (1.0 - lam * e1, s * (1.0 - lam * e2), lam * L.P * s * e1, lam * L.D * s * s * e2)
        grads = tuple(np.real(-p / dq) for p in parts)
    return grads  # type: ignore[return-value]
