"""Chebyshev collocation of the infinitesimal generator: the seeds of Newton polishing.

Breda, Maset and Vermiglio (SIAM J. Sci. Comput. 27, 2005): the eigenvalues
of the discretized generator of ``dx/dt = A x + sum_k B_k x(t - h_k)``
approximate the characteristic roots (paper, eq. 5); stacked over delay
pairs of equal degree, one np.linalg.eigvals call per bucket.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.roots.problem import _TINY_DELAY, MAX_DEGREE, _Problem
from delayform.errors import DelayError, ResourceLimitError
from delayform.resources import format_bytes, format_seconds, memory_limit, time_budget

#: Delay pairs per batched eigenvalue call (bounds memory).
_CHUNK = 2048


# =====================================================================
# spectral discretization of the infinitesimal generator (batched)
# =====================================================================
@lru_cache(maxsize=64)
def _chebyshev(N: int) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Chebyshev points cos(j pi / N), differentiation matrix and barycentric weights."""
    j = np.arange(N + 1)
    x = np.cos(np.pi * j / N)
    c = np.where((j == 0) | (j == N), 2.0, 1.0) * (-1.0) ** j
    dx = x[:, None] - x[None, :]
    Dm = np.outer(c, 1.0 / c) / (dx + np.eye(N + 1))
    Dm = Dm - np.diag(Dm.sum(axis=1))  # negative-sum trick (Trefethen, Spectral Methods in MATLAB)
    w = (-1.0) ** j * np.where((j == 0) | (j == N), 0.5, 1.0)
    return x, Dm, w


def _lagrange_rows(N: int, xq: NDArray[np.float64]) -> NDArray[np.float64]:
    """Values of the N+1 Lagrange basis polynomials at points xq (barycentric formula)."""
    x, _, w = _chebyshev(N)
    diff = xq[..., None] - x
    hit = np.abs(diff) < 1e-15
    safe = np.where(hit, 1.0, diff)
    t = w / safe
    rows = t / t.sum(axis=-1, keepdims=True)
    on_node = hit.any(axis=-1)
    return np.where(on_node[..., None], hit.astype(float), rows)


def _igd_eigenvalues(
    prob: _Problem, N: int, t1: NDArray[np.float64], t2: NDArray[np.float64]
) -> NDArray[np.complex128]:
    """Eigenvalues of the degree-N discretized generator at each delay pair (shape (B, d(N+1))).

    Rows 1..N collocate u' = d/dtheta u at the Chebyshev points of
    [-h_max, 0]; row 0 is the DDE itself, the delayed states read off the
    interpolating polynomial at theta = -h_k. All pairs must have h_max > 0.
    """
    d = prob.d
    x, Dm, _ = _chebyshev(N)
    Bstack = np.stack([b for b, _, _ in prob.delayed])  # (K, d, d)
    h = np.stack([a * t1 + b * t2 for _, a, b in prob.delayed], axis=-1)  # (B, K)
    hmax = h.max(axis=-1)
    L = _lagrange_rows(N, 1.0 - 2.0 * h / hmax[:, None])  # (B, K, N+1)
    real = prob.is_real
    dtype = np.float64 if real else np.complex128
    Bm = Bstack.real if real else Bstack
    M = np.zeros((t1.size, N + 1, d, N + 1, d), dtype=dtype)
    M[:, 0] = np.einsum("bkj,kpq->bpjq", L, Bm)
    M[:, 0, :, 0, :] += prob.A.real if real else prob.A
    M[:, 1:] = (2.0 / hmax)[:, None, None, None, None] * np.einsum(
        "ij,pq->ipjq", Dm[1:], np.eye(d)
    )
    size = (N + 1) * d
    return np.linalg.eigvals(M.reshape(t1.size, size, size)).astype(np.complex128)


def _eigenvalues_at(prob: _Problem, N: int, hmax: float, t1: float, t2: float) -> NDArray[np.complex128]:
    """Eigenvalues of the degree-N discretized generator at one delay pair (A + sum B_k when hmax = 0)."""
    if hmax == 0.0:
        return _delay_free_eigenvalues(prob)
    return _igd_eigenvalues(prob, N, np.array([t1], dtype=float), np.array([t2], dtype=float))[0]


def _delay_free_eigenvalues(prob: _Problem) -> NDArray[np.complex128]:
    """Roots at tau1 = tau2 = 0: eigenvalues of A + sum B_k."""
    total = prob.A + sum(b for b, _, _ in prob.delayed)
    return np.linalg.eigvals(total)


def _max_delay(prob: _Problem, t1: float, t2: float) -> float:
    """Largest delay of the realization; below :data:`_TINY_DELAY` it counts as none for seeding."""
    h = max([a * t1 + b * t2 for _, a, b in prob.delayed] + [0.0])
    return h if h >= _TINY_DELAY else 0.0


def _initial_degree(hmax: float, radius: float) -> int:
    """Chebyshev degree resolving roots up to |s| = radius over a delay interval hmax.

    A root s needs e^{s theta} resolved on [-hmax, 0]; Chebyshev interpolation
    of it converges once N exceeds about |s| hmax / 2 (Bernstein ellipse), so
    a margin of twice that plus a floor keeps the rightmost roots accurate
    enough to seed Newton.
    """
    return int(min(MAX_DEGREE, max(12, math.ceil(1.2 * radius * hmax + 10))))


def _needed_degree(hmax: float, radius: float) -> int:
    """:func:`_initial_degree` without its cap: the degree that resolves |s| <= radius over hmax."""
    need = 1.2 * radius * hmax + 10
    return int(max(12, math.ceil(min(need, 1e12))))  # 1e12: far beyond any budget, still an int


def _degree_cap(prob: _Problem, hmax: float) -> int:
    """Largest degree the robust rightmost-root path raises the discretization to.

    :data:`MAX_DEGREE` when the delay is short, else room for two doublings
    above the degree the root scale needs: the long-delay path, whose cost
    (dense eigenvalues of a d(N + 1) matrix, N proportional to delay times
    root scale) grows with the cube of the delay; :func:`_require_degree`
    refuses, before any work, a size beyond the machine's budget.
    """
    return max(MAX_DEGREE, 4 * _needed_degree(hmax, _root_scale(prob)))


def _cost(size: float) -> tuple[float, float]:
    """Memory (bytes) and time (s) of dense nonsymmetric eigenvalues of a size x size matrix.

    About 25 n^3 flops at ~1 GFlop/s on a shared core and ~4 n^2 complex words.
    """
    return 64.0 * size * size, 2.5e-8 * size**3


def _largest_degree(prob: _Problem) -> int:
    """The largest discretization degree N that :func:`_require_degree` accepts on this machine."""
    size = min(math.sqrt(memory_limit() / 64.0), (time_budget() / 2.5e-8) ** (1.0 / 3.0))
    while size > 1 and not all(c <= b for c, b in zip(_cost(size), (memory_limit(), time_budget()))):
        size = math.nextafter(size, 0.0)  # rounding of the roots above; at most a step or two
    return max(int(size // prob.d) - 1, MAX_DEGREE)


def _require_degree(prob: _Problem, N: int, hmax: float) -> None:
    """Refuse, in one line, a discretization of degree N beyond the machine's memory or time budget."""
    _require_degrees(prob, (N,), hmax)


def _doublings(N: int, cap: int) -> tuple[int, ...]:
    """The degrees the robust path may solve: N, 2N, 4N, ... up to ``cap`` (the last one capped)."""
    out = [N]
    while out[-1] < cap:
        out.append(min(cap, 2 * out[-1]))
    return tuple(out)


#: root scale above which a refusal names the size of the roots (the coefficients, e.g. large gains)
_LARGE_ROOTS = 4.0


def _require_degrees(prob: _Problem, degrees: tuple[int, ...], hmax: float) -> None:
    """Refuse, in one line and before any of them is solved, discretizations beyond the machine's budget.

    The memory needed is that of the largest degree, the time that of all
    of them (the robust path may double through each). Raises DelayError
    (the delays, or the size of the roots times the delays, are what to
    change): dense nonsymmetric eigenvalues cost about 25 n^3 flops (at
    ~1 GFlop/s on a shared core) and ~4 n^2 complex words for
    n = d (N + 1). The message names the right cause: the degree grows with
    the delay *times* the size of the roots, and roots are large when the
    coefficients are (large gains), not only when delays are long.
    """
    sizes = [float(prob.d * (N + 1)) for N in degrees]
    nbytes = _cost(max(sizes))[0]
    seconds = sum(_cost(n)[1] for n in sizes)
    limit, budget = memory_limit(), time_budget()
    if nbytes <= limit and seconds <= budget:
        return
    size, N = max(sizes), max(degrees)
    upto = "up to " if len(degrees) > 1 else ""
    need = (f"about {format_bytes(nbytes)} of memory (limit {format_bytes(limit)})" if not nbytes <= limit
            else f"{upto}about {format_seconds(seconds)} (time budget {format_seconds(budget)})")  # fmt: skip
    work = (f"its discretization of degree {upto}{N} (a {size:.0f} x {size:.0f} eigenvalue problem) "
            f"would need {need}")
    scale = _root_scale(prob)
    # the roots are the cause only when roots of ordinary size would fit at these delays (the degree
    # grows with delay times root size); else the delays are too long whatever the gains
    ordinary = [n * _LARGE_ROOTS / scale for n in sizes] if scale > _LARGE_ROOTS else sizes
    fits = _cost(max(ordinary))[0] <= limit and sum(_cost(n)[1] for n in ordinary) <= budget
    if scale > _LARGE_ROOTS and fits:
        raise DelayError(
            f"the characteristic roots are large (about {scale:.3g}, set by the coefficients: large gains "
            f"make large roots) for delays up to {hmax:.4g} s, too many for the certified root finder on "
            f"this machine: {work}; choose smaller gains or shorter delays (the stability chart has no such limit)"
        )
    raise DelayError(
        f"delays up to {hmax:.4g} s are too long for the certified root finder on this machine: "
        f"{work}; choose shorter delays (the stability chart has no such limit)"
    )


def _require_resolvable(region: tuple[float, float, float, float], hmax: float) -> None:
    """Refuse, in one line, a rectangle reaching too far from the origin to list its roots at delay hmax.

    Chebyshev needs a degree above |s| hmax / 2 to resolve e^{s theta} on
    [-hmax, 0], and the degree stops at :data:`MAX_DEGREE`; the message names
    the largest |s| allowed and a rectangle within it.
    """
    x0, x1, y0, y1 = region
    radius = max(abs(complex(x, y)) for x in (x0, x1) for y in (y0, y1))
    if 0.5 * radius * hmax <= MAX_DEGREE:
        return
    limit = 2 * MAX_DEGREE / hmax
    # the same rectangle cut to fit: Re kept within the limit, then Im cut where the corners reach it
    r0, r1 = max(x0, -0.99 * limit), min(x1, 0.99 * limit)
    i0 = i1 = 0.0
    if r0 < r1:
        reach = 0.99 * math.sqrt(limit**2 - max(r0 * r0, r1 * r1))  # a margin for the printed digits
        i0, i1 = max(y0, -reach), min(y1, reach)
    hint = (f", e.g. {r0:.4g},{r1:.4g},{i0:.4g},{i1:.4g}"
            if r0 < r1 and i0 < i1 else "")  # fmt: skip
    raise ResourceLimitError(
        f"the rectangle {tuple(region)} reaches |s| = {radius:.4g}, too far from the origin to list every "
        f"root at delays up to {hmax:.4g} s; choose a smaller rectangle, every corner within "
        f"|s| <= {limit:.4g}{hint}"
    )


def _root_scale(prob: _Problem) -> float:
    """Radius of the delay-free roots plus the delayed gains: scale of the rightmost roots."""
    if prob.scale > 0.0:
        return prob.scale
    total = prob.A + sum(b for b, _, _ in prob.delayed)
    return float(max(1.0, np.max(np.abs(np.linalg.eigvals(total))), np.linalg.norm(prob.A, 2)))



def _map_degree(hmax: NDArray[np.float64], radius: float) -> NDArray[np.int64]:
    """Degree for the batched pass: enough to seed Newton at the rightmost roots.

    Lower than :func:`_initial_degree` on purpose: the certificate decides,
    and the pairs it rejects get a discretization of twice the degree (then,
    rarely, the robust single-pair path).
    """
    return np.clip(np.ceil(0.6 * radius * hmax + 4), 6, MAX_DEGREE).astype(np.int64)



def _igd_seeds(
    prob: _Problem, t1: NDArray[np.float64], t2: NDArray[np.float64], *, scale: float, k: int
) -> NDArray[np.complex128]:
    """The k rightmost eigenvalues of the discretized generator at each pair (NaN-padded).

    One stacked np.linalg.eigvals call per bucket of equal degree; pairs
    with no delay get the eigenvalues of A + sum B_k. The persistent zero of
    the paper's eq. 4, which the discretization keeps exactly, is dropped.
    """
    out = np.full((t1.size, k), np.nan + 0j, dtype=np.complex128)
    hmax = np.maximum.reduce([a * t1 + b * t2 for _, a, b in prob.delayed] + [np.zeros(t1.size)])
    degree = np.minimum(MAX_DEGREE, np.ceil(scale * _map_degree(hmax, _root_scale(prob)))).astype(int)
    delayed = hmax >= _TINY_DELAY
    groups = [(np.flatnonzero(~delayed), 0)] + [
        (np.flatnonzero((degree == N) & delayed), int(N)) for N in np.unique(degree[delayed])
    ]
    for idx_all, N in groups:
        for start in range(0, idx_all.size, _CHUNK):
            idx = idx_all[start : start + _CHUNK]
            if N == 0:
                eig = np.tile(_delay_free_eigenvalues(prob), (idx.size, 1))
            else:
                eig = _igd_eigenvalues(prob, N, t1[idx], t2[idx])
            if prob.deflate_zero:
                eig[np.arange(idx.size), np.argmin(np.abs(eig), axis=1)] = -np.inf
            if prob.is_real:  # roots pair up: keep one member, _certify adds the other
                eig = np.where(eig.imag >= 0.0, eig, -np.inf)
            order = np.argsort(-eig.real, axis=1)[:, :k]
            top = np.take_along_axis(eig, order, 1)
            top[~np.isfinite(top)] = np.nan
            out[idx, : top.shape[1]] = top
    return out


