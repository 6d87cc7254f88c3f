"""CTCR crossing sets in phase space: (omega, theta1, theta2) with q(j omega) = 0.

Internal to :mod:`delayform.analysis.ctcr.stability_map` (method in its module docstring):
polynomials in omega, the closed form of three-term quasi-polynomials (law of
cosines), the resultant elimination of general ones, the adaptive sampling of
a path, and the exact single-delay problems of the axes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.polynomial.polynomial as npoly
from numpy.typing import ArrayLike, NDArray

from delayform.analysis.ctcr.general import TermsQP, near_fold, newton_phases, resultant_solutions, unit_circle_roots
from delayform.analysis.ctcr.single import line_frequencies
from delayform.characteristic import DELAY_MULTIPLES, TwoDelayQuasiPolynomial

TWO_PI = 2.0 * np.pi
#: Chord deviation (fraction of the window size) below which a curve piece is not refined: every
#: polyline of a map lies within this times the window of its curve (the design uses it as a margin).
CHORD_TOL = 2e-4
#: Longest chord (fraction of the window size) kept without refinement.
_MAX_CHORD = 0.02
_MAX_ROUNDS = 26
#: Cap on the samples of one phase path (a guard; real curves need a few thousand).
_MAX_POINTS = 200_000
#: Lowest crossing frequency traced, relative to the bound on crossing frequencies.
_OMEGA_FLOOR = 1e-4
#: Lines theta_1 = const (and as many theta_2 = const) whose exact crossings seed the general sweep.
_SEED_LINES = 24


# ===================================================================== polynomials in omega
def _horner(x: ArrayLike, c: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """p(x) for coefficients c in increasing powers (Horner; cheaper than numpy's polyval here)."""
    x = np.asarray(x)
    c = np.asarray(c)
    if c.size == 0:
        return np.zeros(x.shape, complex)
    out = np.full(x.shape, c[-1], dtype=np.result_type(x.dtype, c.dtype))
    for a in c[-2::-1]:
        out = out * x + a
    return out


def _deriv(c: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Coefficients of p'."""
    c = np.asarray(c)
    if c.size <= 1:
        return np.zeros(1, c.dtype)
    return c[1:] * np.arange(1, c.size)


def _at_j_omega(c: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Coefficients in omega of g(j omega), increasing powers."""
    return c * (1j ** np.arange(c.size)) if c.size else np.zeros(1, complex)


def _conj_poly(c: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Coefficients of conj(p(omega)) for real omega."""
    return np.conj(c)


def _mod2(c: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """|g(j omega)|^2 as a polynomial in omega (real up to rounding)."""
    w = _at_j_omega(c)
    return npoly.polymul(w, _conj_poly(w))


def _positive_real_roots(poly: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Positive real roots of a real polynomial (given as complex coefficients), polished."""
    p = np.asarray(poly).real.astype(float)
    scale = np.max(np.abs(p)) if p.size else 0.0
    if scale == 0.0:
        return np.zeros(0)
    p = p / scale
    nz = np.flatnonzero(np.abs(p) > 1e-14)
    p = p[: nz[-1] + 1]
    if p.size < 2:
        return np.zeros(0)
    roots = np.roots(p[::-1])
    real = np.sort(roots[np.abs(roots.imag) <= 1e-6 * np.maximum(1.0, np.abs(roots))].real)
    if real.size == 0:
        return real
    # A double root (the gain condition only touched) comes out as two values ~1e-8 apart:
    # merge such clusters and polish a double root as the simple root of p'.
    gaps = np.diff(real) > 1e-6 * np.maximum(1.0, np.abs(real[1:]))
    labels = np.concatenate([[0], np.cumsum(gaps)])
    size = np.bincount(labels)
    value = np.bincount(labels, weights=real) / size
    out = []
    for r, m in zip(value, size, strict=True):
        if m <= 2:
            f = p if m == 1 else _deriv(p)
            df = _deriv(f)
            for _ in range(4):
                d = _horner(r, df)
                step = _horner(r, f) / d if d != 0.0 else 0.0
                if not abs(step) <= 1e-6 * max(1.0, abs(r)):
                    break
                r = r - step
        out.append(float(r))
    arr = np.array(out)
    return arr[arr > 1e-12]


def _omega_bound(qp: TwoDelayQuasiPolynomial) -> float:
    """Upper bound on |s| of every root with Re s >= 0 (so on every crossing frequency).

    With |e^{-tau s}| <= 1 for Re s >= 0, a root needs
    ``|g1(s)| <= sum_{k>1} |g_k(s)|``; bounding both sides by the moduli of the
    coefficients gives a polynomial with one sign change (Descartes), whose
    positive root bounds |s| for every pair of delays.
    """
    if isinstance(qp, TermsQP) and qp.crossing_bound is not None:
        return qp.crossing_bound  # a neutral qp: the bound of its difference operator
    coeffs = qp.coefficients
    d = qp.degree
    lower = np.zeros(d + 1)
    for c in coeffs:
        lower[: c.size] += np.abs(c)
    lower[d] = 0.0
    lower = lower / abs(qp.g1[d])
    # |s|^d > sum lower_i |s|^i holds for |s| > max(1, sum lower_i) (Cauchy-like bound).
    return float(max(1.0, lower.sum()) * 1.0001)



# ===================================================================== curves in phase space
@dataclass(frozen=True)
class _PhasePath:
    """A connected piece of crossing set: omega and unwrapped phases along it."""

    omega: NDArray[np.float64]
    theta1: NDArray[np.float64]
    theta2: NDArray[np.float64]


def _three_term_phases(
    g1w: NDArray[np.complex128], g2w: NDArray[np.complex128], g3w: NDArray[np.complex128],
    omega: NDArray[np.float64], branch: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Closed-form phases of ``g1 + g2 z1 + g3 z2 = 0`` at j omega (law of cosines).

    ``u = g2 z1`` has modulus |g2| and ``v = g3 z2 = -g1 - u`` modulus |g3|; the
    angle between u and -g1 is ``+-alpha`` with
    ``cos alpha = (|g1|^2 + |g2|^2 - |g3|^2) / (2 |g1| |g2|)``; ``branch`` is +-1.
    """
    a = _horner(omega, g1w)
    b = _horner(omega, g2w)
    c = _horner(omega, g3w)
    r1, r2, r3 = np.abs(a), np.abs(b), np.abs(c)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_alpha = np.clip((r1**2 + r2**2 - r3**2) / (2.0 * r1 * r2), -1.0, 1.0)
        w = -a
        u = r2 * np.exp(1j * (np.angle(w) + branch * np.arccos(cos_alpha)))
        z1 = u / b
        z2 = (w - u) / c
    return np.mod(-np.angle(z1), TWO_PI), np.mod(-np.angle(z2), TWO_PI)


def _three_term_paths(qp: TwoDelayQuasiPolynomial, window: tuple[float, float]) -> list[_PhasePath]:
    """Crossing set of ``g1 + g2 z1 + g3 z2`` (omega > 0), one path per frequency interval."""
    g1w, g2w, g3w = (_at_j_omega(c) for c in (qp.g1, qp.g2, qp.g3))
    A, B, C = _mod2(qp.g1), _mod2(qp.g2), _mod2(qp.g3)
    S = npoly.polysub(npoly.polysub(A, B), C)
    F = npoly.polysub(npoly.polymul(S, S), 4.0 * npoly.polymul(B, C))
    ends = _positive_real_roots(F)
    bound = _omega_bound(qp)
    grid = np.concatenate([[0.0], ends[ends < bound * 1.5], [bound * 1.5]])
    paths = []
    for lo, hi in zip(grid[:-1], grid[1:], strict=True):
        mid = 0.5 * (lo + hi)
        if hi - lo <= 1e-12 * hi or _horner(mid, F).real > 0.0:
            continue
        def phases(phi: NDArray[np.float64], lo: float = lo, hi: float = hi) -> tuple[NDArray, ...]:
            # phi in [0, 2 pi]: branch + for phi < pi (omega up), branch - back down.
            om = lo + (hi - lo) * 0.5 * (1.0 - np.cos(phi))
            br = np.where(phi <= np.pi, 1.0, -1.0)
            t1, t2 = _three_term_phases(g1w, g2w, g3w, om, br)
            return om, t1, t2
        start = 0.0
        stop = TWO_PI
        if lo == 0.0:
            # omega -> 0 is not a crossing: open the loop there. Below omega ~ 1e-4 bound the
            # delays tau = theta / omega lose ~ eps / omega^2 to rounding (the triangle
            # degenerates), so the path stops there; the piece left out is O(1e-4) long.
            start = float(np.arccos(1.0 - 2.0 * min(_OMEGA_FLOOR * bound / hi, 0.5)))
            stop = TWO_PI - start
        paths.extend(_adaptive_path(phases, start, stop, window))
    return paths


def _adaptive_path(phases: Any, start: float, stop: float, window: tuple[float, float]) -> list[_PhasePath]:
    """Sample a closed-form parametrised curve, refining where its plane image bends."""
    t = np.linspace(start, stop, 97)
    if start > 0.0:  # geometric points toward both omega -> 0 ends of an open path
        geo = start * np.geomspace(1.0, min(2e3, 1.5 / start), 24)
        t = np.unique(np.concatenate([t, geo, stop + start - geo]))
        t = t[(t >= start) & (t <= stop)]
    om, th1, th2 = phases(t)
    scale = max(window)
    for _ in range(_MAX_ROUNDS):
        u1, u2 = np.unwrap(th1), np.unwrap(th2)
        mid_t = 0.5 * (t[:-1] + t[1:])
        m_om, m1, m2 = phases(mid_t)
        m1 = u1[:-1] + np.angle(np.exp(1j * (m1 - u1[:-1])))
        m2 = u2[:-1] + np.angle(np.exp(1j * (m2 - u2[:-1])))
        need = _needs_refinement(om, u1, u2, m_om, m1, m2, window, scale)
        # Below this parameter step the phases are rounding noise (e.g. a flat curve whose
        # "turning points" are noise): refining further would only multiply points.
        need &= np.diff(t) > 1e-9 * (stop - start)
        if not np.any(need) or t.size > _MAX_POINTS:
            break
        t = np.sort(np.concatenate([t, mid_t[need]]))
        om, th1, th2 = phases(t)
    return [_PhasePath(om, np.unwrap(th1), np.unwrap(th2))]


def _needs_refinement(
    om: NDArray, u1: NDArray, u2: NDArray, m_om: NDArray, m1: NDArray, m2: NDArray,
    window: tuple[float, float], scale: float,
) -> NDArray[np.bool_]:
    """Intervals whose image (kernel and farthest offspring in the window) bends or is long."""
    inv = 1.0 / om
    m_inv = 1.0 / m_om
    # Only refine what can reach the window: the lowest image (tau >= 0) of both delays below tau_max.
    relevant = np.ones(m_om.shape, bool)
    for u, tmax in ((u1, window[0]), (u2, window[1])):
        lowest = np.minimum(np.mod(u[:-1], TWO_PI) * inv[:-1], np.mod(u[1:], TWO_PI) * inv[1:])
        relevant &= lowest <= tmax * 1.05
    need = np.zeros(m_om.shape, bool)
    for u, m, tmax in ((u1, m1, window[0]), (u2, m2, window[1])):
        n_far = np.ceil(tmax * np.maximum(om[:-1], om[1:]) / TWO_PI) + 1.0
        tau_a, tau_b, tau_m = u[:-1] * inv[:-1], u[1:] * inv[1:], m * m_inv
        dev = np.abs(tau_m - 0.5 * (tau_a + tau_b))
        dev_shift = TWO_PI * n_far * np.abs(m_inv - 0.5 * (inv[:-1] + inv[1:]))
        chord = np.abs(tau_b - tau_a) + TWO_PI * n_far * np.abs(inv[1:] - inv[:-1])
        need |= (dev + dev_shift > CHORD_TOL * scale) | (chord > _MAX_CHORD * scale)
    need |= _turning_needs(om, u2, m_om, m2, window[1], scale)
    return need & relevant


def _turning_needs(
    om: NDArray, u2: NDArray, m_om: NDArray, m2: NDArray, t2max: float, scale: float
) -> NDArray[np.bool_]:
    """Intervals next to a turning point in tau2 of some image whose chord is off by > 1e-9 scale.

    Near a horizontal tangent a horizontal line meets the curve twice, close
    together; the polyline must be exact there for the count to be, so these
    intervals are refined far below the general chord tolerance.
    """
    need = np.zeros(m_om.shape, bool)
    if om.size < 3:
        return need
    k_lo = int(np.ceil(np.min(-u2) / TWO_PI))
    k_hi = int(np.floor(np.max(t2max * om - u2) / TWO_PI))
    if k_hi < k_lo:
        return need
    ks = np.arange(k_lo, k_hi + 1, dtype=float)[:, None]
    tau = (u2[None, :] + TWO_PI * ks) / om[None, :]
    d = np.diff(tau, axis=1)
    turn = (d[:, :-1] * d[:, 1:] < 0.0) & (tau[:, 1:-1] >= -0.02 * t2max) & (tau[:, 1:-1] <= 1.02 * t2max)
    if not np.any(turn):
        return need
    mid = (m2[None, :] + TWO_PI * ks) / m_om[None, :]
    dev = np.abs(mid - 0.5 * (tau[:, :-1] + tau[:, 1:])) > 1e-9 * scale
    near = np.zeros(d.shape, bool)
    near[:, :-1] |= turn
    near[:, 1:] |= turn
    return np.any(near & dev, axis=0)


# --------------------------------------------------------------------- general qps
def _batched_conv(a: NDArray[np.complex128], b: NDArray[np.complex128]) -> NDArray[np.complex128]:
    """Row-wise polynomial products of (n, p) and (n, q) coefficient arrays."""
    out = np.zeros((a.shape[0], a.shape[1] + b.shape[1] - 1), complex)
    for j in range(b.shape[1]):
        out[:, j : j + a.shape[1]] += a * b[:, j : j + 1]
    return out


def _general_solutions(qp: TwoDelayQuasiPolynomial | TermsQP, omega: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """All (theta1, theta2) with q(j omega) = 0 at each omega: resultant in z2, unit roots, Newton.

    Terms beyond the paper's eq. 5's six: :func:`~delayform.analysis.ctcr.general.resultant_solutions`.
    """
    if isinstance(qp, TermsQP):
        return resultant_solutions(qp, omega)
    s = 1j * omega
    g = [_horner(s, c) if c.size else np.zeros(s.shape, complex) for c in qp.coefficients]
    g1, g2, g3, g4, g5, g6 = g
    n = omega.size
    b = np.stack([g2, g6], 1)              # powers z2^0..1
    c = np.stack([g1, g3, g5], 1)          # powers z2^0..2
    cbar = np.conj(c[:, ::-1])             # conj(c) z2^2, powers 0..2 (offset -2)
    bbar = np.conj(b[:, ::-1])             # conj(b) z2, powers 0..1 (offset -1)
    if np.all(g4 == 0):
        # Linear in z1: |z1| = 1 iff |c|^2 = |b|^2; times z2^2.
        cc = _batched_conv(c, cbar)                       # offset -2, len 5
        bb = np.zeros((n, 5), complex)
        bb[:, 1:4] = _batched_conv(b, bbar)               # offset -1 -> shift 1
        R = cc - bb
    else:
        a = g4[:, None]
        abar = np.conj(a)
        X0 = -_batched_conv(c, cbar)
        X0[:, 2] += (a * abar)[:, 0]                     # (|a|^2 - c cbar), offset -2, len 5
        Xs = _batched_conv(X0, X0)                        # offset -4, len 9
        U = np.zeros((n, 4), complex)                     # a bbar - b cbar, offset -2
        U[:, 1:3] += a * bbar
        U -= _batched_conv(b, cbar)
        V = np.zeros((n, 4), complex)                     # b abar - c bbar, offset -1
        V[:, 1:3] += b * abar
        V -= _batched_conv(c, bbar)
        R = Xs.copy()
        R[:, 1:8] -= _batched_conv(U, V)                  # offset -3 -> shift 1
        if not (np.any(g2) or np.any(g6)):
            # q in z1^2 alone (no odd power of z1): U = V = 0 and R = X0^2, a square whose double
            # unit roots rounding splits by ~1e-8 (a near-double one, next to an end of a frequency
            # band, by ~1e-4): the solution count flickered from sample to sample and the bisection
            # below ran 40 rounds over the whole sweep (the map property, seed 15: more than a
            # minute). In w = z1^2 the quadratic is linear, |w| = 1 iff |c|^2 = |a|^2: R = X0 itself.
            R = X0
    out: list[NDArray[np.float64]] = []
    for i in range(n):
        z2 = unit_circle_roots(R[i], 1e-13)
        sols = []
        for z in z2:
            bz = b[i, 0] + b[i, 1] * z
            cz = c[i, 0] + c[i, 1] * z + c[i, 2] * z * z
            if g4[i] == 0:
                cand = [-cz / bz] if bz != 0 else []
            else:
                cand = list(np.roots([g4[i], bz, cz]))
            for z1 in cand:
                if abs(abs(z1) - 1.0) > 1e-3:
                    continue
                th = _newton_phases(g, i, -np.angle(z1), -np.angle(z))
                if th is not None:
                    sols.append(th)
        out.append(_unique_phases(np.array(sols).reshape(-1, 2)))
    return out


def _newton_phases(g: list[NDArray], i: int, t1: float, t2: float) -> tuple[float, float] | None:
    """Polish (theta1, theta2) on sum_k g_k e^{-j(a theta1 + b theta2)} = 0 at one omega (paper, eq. 5's terms)."""
    return newton_phases(np.array([gk[i] for gk in g]), np.array(DELAY_MULTIPLES, float), t1, t2)


def _unique_phases(th: NDArray[np.float64]) -> NDArray[np.float64]:
    keep: list[NDArray[np.float64]] = []
    for row in th:
        if all(_torus_dist(row, k) > 1e-7 for k in keep):
            keep.append(row)
    return np.array(keep).reshape(-1, 2)


def _dist_matrix(A: NDArray[np.float64], B: NDArray[np.float64]) -> NDArray[np.float64]:
    """Torus (max-coordinate) distances between phase pairs, rows of A by rows of B."""
    d = np.mod(A[:, None, :] - B[None, :, :] + np.pi, TWO_PI) - np.pi
    return np.abs(d).max(axis=2)


def _torus_dist(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    d = np.abs(np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b)))))
    return float(np.max(d))


def _general_paths(qp: TwoDelayQuasiPolynomial, window: tuple[float, float]) -> list[_PhasePath]:
    """Crossing set of a general retarded qp: adaptive omega sweep joined into paths."""
    from scipy.optimize import linear_sum_assignment

    bound = _omega_bound(qp)
    # The grid alone misses a curve whose band of frequencies falls between two samples (a small
    # term: s + 1 + 2 z1^3 + 0.001 z2 spans 0.002); the exact crossings on lines theta_k = const
    # put a sample on every curve that meets one of them, whatever its band.
    seeds = line_frequencies(list(qp.terms()), _SEED_LINES)
    seeds = seeds[(seeds >= bound * _OMEGA_FLOOR) & (seeds <= bound * 1.5)]
    omega = np.unique(np.concatenate([np.linspace(bound * 1e-3, bound, 600),
                                      bound * np.geomspace(_OMEGA_FLOOR, 1e-3, 12), seeds]))
    sols = _general_solutions(qp, omega)
    fold = [near_fold(qp, w, th) for w, th in zip(omega, sols, strict=True)]
    # Bisect wherever the number of solutions changes or neighbours are far apart. A change of the
    # count next to a sample whose solutions are at the limit of certification (a turning point
    # resolved as far as rounding allows: which twins are found there is chance) is not chased.
    for _ in range(40):
        extra = []
        for i in range(omega.size - 1):
            na, nb = len(sols[i]), len(sols[i + 1])
            gap = omega[i + 1] - omega[i]
            if gap <= 1e-12 * omega[i + 1]:
                continue
            far = na == nb and na > 0 and _max_match_dist(sols[i], sols[i + 1]) > 0.05
            if (na != nb and not (fold[i] or fold[i + 1])) or (far and gap > 1e-9 * omega[i + 1]):
                extra.append(0.5 * (omega[i] + omega[i + 1]))
        if not extra:
            break
        new = np.array(extra)
        new_sols = _general_solutions(qp, new)
        allw = np.concatenate([omega, new])
        order = np.argsort(allw)
        merged = sols + new_sols
        merged_fold = fold + [near_fold(qp, w, th) for w, th in zip(new, new_sols, strict=True)]
        omega = allw[order]
        sols = [merged[k] for k in order]
        fold = [merged_fold[k] for k in order]
    # Graph: nodes (sample, index); edges by assignment; turning points pair the leftovers.
    nodes = [(i, j) for i in range(omega.size) for j in range(len(sols[i]))]
    adj: dict[tuple[int, int], list[tuple[int, int]]] = {v: [] for v in nodes}
    for i in range(omega.size - 1):
        A, Bs = sols[i], sols[i + 1]
        if len(A) and len(Bs):
            D = _dist_matrix(A, Bs)
            r, c = linear_sum_assignment(D)
            for ri, ci in zip(r, c, strict=True):
                if D[ri, ci] < 0.3:
                    adj[(i, ri)].append((i + 1, ci))
                    adj[(i + 1, ci)].append((i, ri))
        for side in (i, i + 1):
            loose = [v for v in ((side, j) for j in range(len(sols[side]))) if len(adj[v]) < 2 and _is_end(v, i, adj)]
            while len(loose) >= 2:
                best = min(
                    ((p, q) for p in loose for q in loose if p < q),
                    key=lambda pq: _torus_dist(sols[pq[0][0]][pq[0][1]], sols[pq[1][0]][pq[1][1]]),
                )
                if _torus_dist(sols[best[0][0]][best[0][1]], sols[best[1][0]][best[1][1]]) > 0.3:
                    break
                adj[best[0]].append(best[1])
                adj[best[1]].append(best[0])
                loose = [v for v in loose if v not in best]
    return _walk_paths(adj, omega, sols)


def _is_end(v: tuple[int, int], i: int, adj: dict[tuple[int, int], list[tuple[int, int]]]) -> bool:
    """A node of sample i or i + 1 not joined across the gap (i, i + 1)."""
    other = i + 1 if v[0] == i else i
    return not any(w[0] == other for w in adj[v])


def _max_match_dist(A: NDArray[np.float64], B: NDArray[np.float64]) -> float:
    from scipy.optimize import linear_sum_assignment

    D = _dist_matrix(A, B)
    r, c = linear_sum_assignment(D)
    return float(D[r, c].max())


def _walk_paths(
    adj: dict[tuple[int, int], list[tuple[int, int]]], omega: NDArray[np.float64], sols: list[NDArray[np.float64]]
) -> list[_PhasePath]:
    seen: set[tuple[int, int]] = set()
    paths: list[_PhasePath] = []
    starts = [v for v in adj if len(adj[v]) != 2] + list(adj)
    for v0 in starts:
        if v0 in seen:
            continue
        walk = [v0]
        seen.add(v0)
        prev, cur = None, v0
        while True:
            nxt = [w for w in adj[cur] if w != prev and w not in seen]
            if not nxt:
                if len(adj[cur]) == 2 and v0 in adj[cur] and len(walk) > 2:
                    walk.append(v0)  # close the loop
                break
            prev, cur = cur, nxt[0]
            walk.append(cur)
            seen.add(cur)
        if len(walk) < 2:
            continue
        om = np.array([omega[i] for i, _ in walk])
        th = np.array([sols[i][j] for i, j in walk])
        paths.append(_PhasePath(om, np.unwrap(th[:, 0]), np.unwrap(th[:, 1])))
    return paths


# --------------------------------------------------------------------- degenerate (one delay)
def _single_delay_roots(
    h0: NDArray[np.complex128], h1: NDArray[np.complex128], h2: NDArray[np.complex128]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """omega > 0 and theta in [0, 2 pi) with ``h0 + h1 z + h2 z^2 = 0``, ``z = e^{-j theta}``.

    The unit-circle condition is eliminated exactly: for h2 = 0 it is
    ``|h0|^2 = |h1|^2``; otherwise the resultant of the quadratic and its
    conjugate-reciprocal, ``(|h2|^2 - |h0|^2)^2 - |h2 conj(h1) - h1 conj(h0)|^2``.
    """
    if h1.size == 0 and h2.size == 0:
        return np.zeros(0), np.zeros(0)
    w0, w1, w2 = (_at_j_omega(h) for h in (h0, h1, h2))
    if h2.size == 0:
        poly = npoly.polysub(_mod2(h0), _mod2(h1))
    else:
        X = npoly.polysub(_mod2(h2), _mod2(h0))
        Y = npoly.polysub(npoly.polymul(w2, np.conj(w1)), npoly.polymul(w1, np.conj(w0)))
        poly = npoly.polysub(npoly.polymul(X, X), npoly.polymul(Y, np.conj(Y)))
    omegas = _positive_real_roots(poly)
    out_w, out_t = [], []
    for om in omegas:
        a, b, c = (_horner(om, w) for w in (w2, w1, w0))
        cands = [-c / b] if h2.size == 0 else list(np.roots([a, b, c]))
        for z in cands:
            if not np.isfinite(z) or abs(abs(z) - 1.0) > 1e-5:
                continue
            th0 = float(-np.angle(z))
            e = np.exp(-1j * th0)
            if abs(c + b * e + a * e * e) <= 1e-12 * (abs(a) + abs(b) + abs(c)):
                # omega is a polished polynomial root: keep it (at a touching root the 2x2
                # Newton below is singular and would move it off).
                om_p, th = float(om), th0
            else:
                om_p, th = _newton_single(w0, w1, w2, float(om), th0)
            if th is not None:
                out_w.append(om_p)
                out_t.append(np.mod(th, TWO_PI))
    return np.array(out_w), np.array(out_t)


def _newton_single(
    w0: NDArray, w1: NDArray, w2: NDArray, om: float, th: float
) -> tuple[float, float | None]:
    """Polish (omega, theta) on h0 + h1 e^{-j theta} + h2 e^{-2 j theta} = 0."""
    def f_and_j(om: float, th: float) -> tuple[complex, complex, complex, float]:
        e = np.exp(-1j * th)
        v = [_horner(om, w) for w in (w0, w1, w2)]
        dv = [_horner(om, _deriv(w)) if w.size > 1 else 0.0 for w in (w0, w1, w2)]
        f = v[0] + v[1] * e + v[2] * e * e
        fo = dv[0] + dv[1] * e + dv[2] * e * e
        ft = -1j * v[1] * e - 2j * v[2] * e * e
        return f, fo, ft, abs(v[0]) + abs(v[1]) + abs(v[2])
    for _ in range(20):
        f, fo, ft, scale = f_and_j(om, th)
        if abs(f) <= 1e-15 * scale:
            break
        J = np.array([[fo.real, ft.real], [fo.imag, ft.imag]])
        try:
            step = np.linalg.solve(J, [f.real, f.imag])
        except np.linalg.LinAlgError:
            break
        om, th = om - step[0], th - step[1]
    f, _, _, scale = f_and_j(om, th)
    return om, (th if abs(f) <= 1e-10 * scale and om > 0 else None)


