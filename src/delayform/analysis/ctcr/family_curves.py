"""CTCR curves of all factors of the paper's eq. 3 at once (the lam family), vectorized.

Every traced part of :func:`delayform.analysis.ctcr.stability_map.stability_map` is the
three-term quasi-polynomial ``q_lam(s) = s^2 + D s + P - lam (P z1 + D s z2)``
of one eigenvalue lam of C. The per-part code of :mod:`delayform.analysis.ctcr.phase`
and :mod:`delayform.analysis.ctcr.curves` pays a Python round trip per part, per
refinement round and per image, which for a team of thousands of agents is
most of the time. Here the same constructions run on flat arrays of all parts:

* the frequency intervals: at s = j omega, ``|g1|^2 = (P - w)^2 + D^2 w``,
  ``|g2|^2 = r^2 P^2``, ``|g3|^2 = r^2 D^2 w`` with ``w = omega^2``, ``r = |lam|``,
  so the triangle condition ``F = (|g1|^2 - |g2|^2 - |g3|^2)^2 - 4 |g2|^2 |g3|^2``
  is a quartic in w; its roots for all parts come from one stacked
  companion-matrix eigenvalue call and are polished by Newton's method;
* the law-of-cosines phases and the adaptive sampling of every path
  (:func:`delayform.analysis.ctcr.phase._adaptive_path`, same tests, same
  parametrisation) with all paths' samples in one array; the turning-point
  test, which per path scans every tau2 image k, uses that the chord
  differences of image k are linear in k, so the set of k with a turn at a
  sample is an interval found in closed form;
* root tendencies (Definition "Root Tendency") in closed form,
  ``ds/dtau1 = -lam P s z1 / q'(s)``, ``ds/dtau2 = -lam D s^2 z2 / q'(s)``;
* the exact single-delay problems on the axes (``|h0(j omega)|^2 = |h1|^2``,
  a quartic in omega) with a vectorized 2 x 2 Newton polish.

Paths are embedded in chunks, so memory stays proportional to the curve
points kept in the window.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.ctcr.phase import _MAX_POINTS, _MAX_ROUNDS, _OMEGA_FLOOR, TWO_PI, CHORD_TOL, _MAX_CHORD
from delayform.analysis.ctcr.curves import CrossingCurve, _Part
from delayform.characteristic import tendency_sign

#: Samples of the paths sampled and embedded together: bounds the transient memory (about
#: 150 bytes per sample, and 200 per curve point of their images).
_SAMPLE_BUDGET = 30_000


# ===================================================================== polynomial roots, batched
def _batch_positive_roots(p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Positive real roots of real polynomials (rows, increasing powers), NaN-padded, polished.

    The rules of :func:`delayform.analysis.ctcr.phase._positive_real_roots` for
    every row at once: roots whose imaginary part is below 1e-6 of their size
    count as real; values closer than 1e-6 relative form one (double) root;
    a simple root is polished by Newton on p, a double one on p'.
    """
    n, width = p.shape
    scale = np.max(np.abs(p), axis=1, keepdims=True)
    scale[scale == 0.0] = 1.0
    p = p / scale
    p = np.where(np.abs(p) > 1e-14, p, 0.0)
    deg = np.where(np.any(p != 0.0, axis=1), width - 1 - np.argmax(p[:, ::-1] != 0.0, axis=1), 0)
    out = np.full((n, width - 1), np.nan)
    for d in np.unique(deg):
        if d < 1:
            continue
        rows = np.flatnonzero(deg == d)
        c = p[rows, : d + 1]
        comp = np.zeros((rows.size, d, d))
        comp[:, 0, :] = -c[:, d - 1 :: -1] / c[:, d : d + 1]
        if d > 1:
            comp[:, np.arange(1, d), np.arange(d - 1)] = 1.0
        roots = np.linalg.eigvals(comp)
        real = np.abs(roots.imag) <= 1e-6 * np.maximum(1.0, np.abs(roots))
        vals = np.sort(np.where(real, roots.real, np.nan), axis=1)
        out[rows, :d] = _merge_and_polish(vals, c)
    return np.where(out > 1e-12, out, np.nan)


def _merge_and_polish(vals: NDArray[np.float64], c: NDArray[np.float64]) -> NDArray[np.float64]:
    """Merge sorted real roots closer than 1e-6 relative; Newton-polish simple and double ones."""
    n, d = vals.shape
    gap = np.diff(vals, axis=1) > 1e-6 * np.maximum(1.0, np.abs(vals[:, 1:]))
    first = np.concatenate([np.isfinite(vals[:, :1]), gap | ~np.isfinite(vals[:, :-1])], axis=1)
    label = np.cumsum(first, axis=1) - 1 + (np.arange(n) * d)[:, None]
    finite = np.isfinite(vals)
    size = np.bincount(label[finite], minlength=n * d)
    total = np.bincount(label[finite], weights=vals[finite], minlength=n * d)
    heads = finite & first
    r = np.where(heads, total[label] / np.maximum(size[label], 1), np.nan)
    mult = np.where(heads, size[label], 0)
    dc = c[:, 1:] * np.arange(1, c.shape[1])
    ddc = dc[:, 1:] * np.arange(1, dc.shape[1]) if dc.shape[1] > 1 else np.zeros((n, 1))
    f_c = np.where((mult == 2)[..., None], _pad_cols(dc, c.shape[1])[:, None, :], c[:, None, :])
    df_c = np.where((mult == 2)[..., None], _pad_cols(ddc, c.shape[1])[:, None, :], _pad_cols(dc, c.shape[1])[:, None, :])
    live = heads & (mult <= 2)
    for _ in range(4):
        f = _horner_rows(f_c, r)
        df = _horner_rows(df_c, r)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(df != 0.0, f / df, 0.0)
        live &= np.abs(step) <= 1e-6 * np.maximum(1.0, np.abs(r))
        r = np.where(live, r - step, r)
    return r


def _pad_cols(c: NDArray[np.float64], width: int) -> NDArray[np.float64]:
    out = np.zeros((c.shape[0], width))
    out[:, : c.shape[1]] = c
    return out


def _horner_rows(c: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]:
    """p(x) with per-element coefficients c[..., k] (increasing powers)."""
    out = np.zeros(x.shape) + c[..., -1]
    for k in range(c.shape[-1] - 2, -1, -1):
        out = out * x + c[..., k]
    return out


# ===================================================================== phase paths of all parts
class _Paths:
    """Flat samples of many phase paths: parameter t, omega and the phases, path id per sample."""

    def __init__(self, lam: NDArray[np.complex128], lo: NDArray[np.float64], hi: NDArray[np.float64],
                 start: NDArray[np.float64], stop: NDArray[np.float64], P: float, D: float) -> None:
        self.lam, self.lo, self.hi, self.start, self.stop, self.P, self.D = lam, lo, hi, start, stop, P, D

    def phases(self, t: NDArray[np.float64], pid: NDArray[np.int64]) -> tuple[NDArray, NDArray, NDArray]:
        """omega and (theta1, theta2) in [0, 2 pi) at parameters t of paths pid (law of cosines).

        As :func:`delayform.analysis.ctcr.phase._three_term_phases` with
        g1 = P - omega^2 + j D omega, g2 = -lam P, g3 = -j lam D omega.
        """
        P, D = self.P, self.D
        lo, hi, lam = self.lo[pid], self.hi[pid], self.lam[pid]
        om = lo + (hi - lo) * 0.5 * (1.0 - np.cos(t))
        br = np.where(t <= np.pi, 1.0, -1.0)
        a = (P - om * om) + 1j * (D * om)
        b = -lam * P
        c = -1j * lam * D * om
        r1, r2, r3 = np.abs(a), np.abs(b), np.abs(c)
        with np.errstate(divide="ignore", invalid="ignore"):
            cos_alpha = np.clip((r1**2 + r2**2 - r3**2) / (2.0 * r1 * r2), -1.0, 1.0)
            w = -a
            u = r2 * np.exp(1j * (np.angle(w) + br * np.arccos(cos_alpha)))
            z1 = u / b
            z2 = (w - u) / c
        return om, np.mod(-np.angle(z1), TWO_PI), np.mod(-np.angle(z2), TWO_PI)


def _frequency_paths(
    lam: NDArray[np.complex128], P: float, D: float
) -> tuple[NDArray[np.int64], _Paths]:
    """One phase path per frequency interval of every part: (part index of each path, the paths)."""
    r2 = np.abs(lam) ** 2
    s0 = P * P * (1.0 - r2)
    s1 = D * D - 2.0 * P - r2 * D * D
    F = np.stack([s0 * s0, 2.0 * s0 * s1 - 4.0 * r2 * r2 * P * P * D * D, s1 * s1 + 2.0 * s0, 2.0 * s1,
                  np.ones_like(s0)], axis=1)  # in w = omega^2
    w_roots = _batch_positive_roots(F)
    ends = np.sort(np.sqrt(w_roots), axis=1)  # NaN last
    bound = np.maximum(1.0, (P + D) * (1.0 + np.sqrt(r2))) * 1.0001
    part_of, los, his = [], [], []
    for k in range(lam.size):
        e = ends[k][np.isfinite(ends[k])]
        top = 1.5 * bound[k]
        grid = np.concatenate([[0.0], e[e < top], [top]])
        lo, hi = grid[:-1], grid[1:]
        mid2 = (0.5 * (lo + hi)) ** 2
        Fm = (((F[k, 4] * mid2 + F[k, 3]) * mid2 + F[k, 2]) * mid2 + F[k, 1]) * mid2 + F[k, 0]
        keep = (hi - lo > 1e-12 * hi) & ~(Fm > 0.0)
        part_of.extend([k] * int(keep.sum()))
        los.extend(lo[keep])
        his.extend(hi[keep])
    part = np.asarray(part_of, dtype=np.int64)
    lo_a, hi_a = np.asarray(los, float), np.asarray(his, float)
    start = np.where(lo_a == 0.0, np.arccos(1.0 - 2.0 * np.minimum(_OMEGA_FLOOR * bound[part] / hi_a, 0.5)), 0.0)
    stop = np.where(lo_a == 0.0, TWO_PI - start, TWO_PI)
    return part, _Paths(lam[part], lo_a, hi_a, start, stop, P, D)


def _initial_samples(paths: _Paths) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The initial parameters of :func:`_adaptive_path` for every path (97 uniform, geometric ends)."""
    ts = []
    for a, b in zip(paths.start, paths.stop, strict=True):
        t = np.linspace(a, b, 97)
        if a > 0.0:
            geo = a * np.geomspace(1.0, min(2e3, 1.5 / a), 24)
            t = np.unique(np.concatenate([t, geo, b + a - geo]))
            t = t[(t >= a) & (t <= b)]
        ts.append(t)
    pid = np.repeat(np.arange(len(ts)), [t.size for t in ts])
    return np.concatenate(ts) if ts else np.zeros(0), pid


def _segmented_unwrap(th: NDArray[np.float64], same: NDArray[np.bool_], first: NDArray[np.int64],
                      pid: NDArray[np.int64]) -> NDArray[np.float64]:
    """np.unwrap of every path (samples contiguous per path; ``same[j]``: j and j+1 on one path)."""
    d = np.diff(th)
    dd = np.mod(d + np.pi, TWO_PI) - np.pi
    dd[(dd == -np.pi) & (d > 0)] = np.pi
    corr = np.where((np.abs(d) < np.pi) | ~same, 0.0, dd - d)
    cs = np.concatenate([[0.0], np.cumsum(corr)])
    return th + cs - cs[first][pid]


def _k_range(om: NDArray, u2: NDArray, first: NDArray[np.int64], t2max: float) -> tuple[NDArray, NDArray]:
    """Per path, the tau2 images k that can meet [0, t2max] (as in _phase._turning_needs)."""
    return (np.ceil(np.minimum.reduceat(-u2, first) / TWO_PI),
            np.floor(np.maximum.reduceat(t2max * om - u2, first) / TWO_PI))


def _turning_needs_flat(
    om: NDArray, u2: NDArray, m_om: NDArray, m2: NDArray, pid: NDArray[np.int64], first: NDArray[np.int64],
    count: NDArray[np.int64], same: NDArray[np.bool_], t2max: float, scale: float,
    points: NDArray[np.bool_] | None = None,
) -> NDArray[np.bool_]:
    """:func:`delayform.analysis.ctcr.phase._turning_needs` of every path, per interval j (j, j+1).

    tau_k = (u2 + 2 pi k) / omega, so every difference along the path and the
    midpoint's deviation from the chord are linear in k: the k with a turn at a
    sample form at most two integer intervals, and |deviation| is largest at
    their ends.
    """
    n = om.size
    need = np.zeros(max(n - 1, 0), bool)
    if n < 3:
        return need
    k_lo, k_hi = _k_range(om, u2, first, t2max)
    inv = 1.0 / om
    a = np.diff(u2 * inv)                 # d_j(k) = a_j + k b_j on interval j
    b = TWO_PI * np.diff(inv)
    # the point j (1..n-2) is interior when both neighbouring intervals are on its path
    interior = np.zeros(n, bool)
    interior[1:-1] = same[:-1] & same[1:] & (count[pid[1:-1]] >= 3)
    if points is not None:
        interior &= points
    j = np.flatnonzero(interior)
    if j.size == 0:
        return need
    p = pid[j]
    aL, bL, aR, bR = a[j - 1], b[j - 1], a[j], b[j]
    lo_t = np.ceil((-0.02 * t2max * om[j] - u2[j]) / TWO_PI)
    hi_t = np.floor((1.02 * t2max * om[j] - u2[j]) / TWO_PI)
    klo, khi = np.maximum(k_lo[p], lo_t), np.minimum(k_hi[p], hi_t)
    big = 1e18
    with np.errstate(divide="ignore", invalid="ignore"):
        rL, rR = -aL / bL, -aR / bR
    rmin, rmax = np.fmin(rL, rR), np.fmax(rL, rR)
    prod_b = bL * bR
    # sets where d_L(k) d_R(k) < 0, as up to two integer intervals [l1, h1], [l2, h2]
    l1 = np.full(j.size, big)
    h1 = np.full(j.size, -big)
    l2 = np.full(j.size, big)
    h2 = np.full(j.size, -big)
    between = prod_b > 0.0
    l1 = np.where(between, np.floor(rmin) + 1.0, l1)
    h1 = np.where(between, np.ceil(rmax) - 1.0, h1)
    outside = prod_b < 0.0
    l1 = np.where(outside, -big, l1)
    h1 = np.where(outside, np.ceil(rmin) - 1.0, h1)
    l2 = np.where(outside, np.floor(rmax) + 1.0, l2)
    h2 = np.where(outside, big, h2)
    # one slope zero: a ray (or everything / nothing)
    for zero, a_c, a_o, b_o in ((bL == 0.0, aL, aR, bR), (bR == 0.0, aR, aL, bL)):
        sel = zero & (prod_b == 0.0)
        if not sel.any():
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            root = -a_o / b_o
        # a_c (a_o + k b_o) < 0
        up = (a_c * b_o) < 0.0          # holds for k > root
        down = (a_c * b_o) > 0.0        # holds for k < root
        flat = b_o == 0.0
        all_k = flat & (a_c * a_o < 0.0)
        l1 = np.where(sel, np.where(up, np.floor(root) + 1.0, np.where(down | all_k, -big, big)), l1)
        h1 = np.where(sel, np.where(up | all_k, big, np.where(down, np.ceil(root) - 1.0, -big)), h1)
        l2 = np.where(sel, big, l2)
        h2 = np.where(sel, -big, h2)
    thr = 1e-9 * scale
    minv = 1.0 / m_om
    for iv in (j - 1, j):  # the intervals left and right of the turning sample
        e = m2[iv] * minv[iv] - 0.5 * (u2[iv] * inv[iv] + u2[iv + 1] * inv[iv + 1])
        f = TWO_PI * (minv[iv] - 0.5 * (inv[iv] + inv[iv + 1]))
        hit = np.zeros(j.size, bool)
        for lo_k, hi_k in ((l1, h1), (l2, h2)):
            ka, kb = np.maximum(lo_k, klo), np.minimum(hi_k, khi)
            ok = ka <= kb
            dev = np.maximum(np.abs(e + ka * f), np.abs(e + kb * f))
            hit |= ok & (dev > thr)
        need[iv[hit]] = True
    return need


def _sample_paths(paths: _Paths, window: tuple[float, float]) -> tuple[NDArray, NDArray, NDArray, NDArray[np.int64]]:
    """Adaptive sampling of all paths at once: (omega, unwrapped theta1, theta2, path id) per sample."""
    t, pid = _initial_samples(paths)
    om, th1, th2 = paths.phases(t, pid)
    scale = max(window)
    npaths = paths.lo.size
    active = np.ones(npaths, bool)
    span = paths.stop - paths.start
    # Only intervals next to new samples are tested again (the others' tests see the
    # same samples), unless a path's range of tau2 images grew (then all of it).
    dirty = np.ones(max(t.size - 1, 0), bool)
    k_prev: tuple[NDArray, NDArray] | None = None
    for _ in range(_MAX_ROUNDS):
        count = np.bincount(pid, minlength=npaths)
        first = np.concatenate([[0], np.cumsum(count)[:-1]])
        same = pid[1:] == pid[:-1]
        u1 = _segmented_unwrap(th1, same, first, pid)
        u2 = _segmented_unwrap(th2, same, first, pid)
        k_now = _k_range(om, u2, first, window[1])
        if k_prev is not None:
            grown = (k_now[0] < k_prev[0]) | (k_now[1] > k_prev[1])
            dirty |= grown[pid[:-1]]
        k_prev = k_now
        iv = np.flatnonzero(same & dirty & active[pid[:-1]])
        if iv.size == 0:
            break
        ip = pid[iv]
        mid_t = 0.5 * (t[iv] + t[iv + 1])
        m_om, m1, m2 = paths.phases(mid_t, ip)
        m1 = u1[iv] + np.angle(np.exp(1j * (m1 - u1[iv])))
        m2 = u2[iv] + np.angle(np.exp(1j * (m2 - u2[iv])))
        full_m_om = np.ones(max(om.size - 1, 0))
        full_m2 = np.zeros(max(om.size - 1, 0))
        full_m_om[iv], full_m2[iv] = m_om, m2
        points = np.zeros(om.size, bool)
        points[iv] = True
        points[iv + 1] = True
        turn = _turning_needs_flat(om, u2, full_m_om, full_m2, pid, first, count, same, window[1], scale, points)
        need_iv = (_chord_needs(om, u1, u2, iv, m_om, m1, m2, window, scale) | turn[iv]) & _relevant(
            om, u1, u2, iv, window
        )
        need_iv &= (t[iv + 1] - t[iv]) > 1e-9 * span[ip]
        has = np.bincount(ip[need_iv], minlength=npaths) > 0
        stop = ~has | (count > _MAX_POINTS)
        active &= ~stop
        need_iv &= active[ip]
        if not need_iv.any():
            break
        # insert the midpoints right after their left sample (paths stay contiguous, sorted)
        ins = np.zeros(t.size, np.int64)
        ins[iv[need_iv]] = 1
        shift = np.concatenate([[0], np.cumsum(ins)[:-1]])
        new_size = t.size + int(ins.sum())
        pos_old = np.arange(t.size) + shift
        pos_mid = pos_old[iv[need_iv]] + 1
        t, om, th1, th2, pid = (
            _interleave(x, xm, pos_old, pos_mid, new_size)
            for x, xm in ((t, mid_t[need_iv]), (om, m_om[need_iv]), (th1, np.mod(m1[need_iv], TWO_PI)),
                          (th2, np.mod(m2[need_iv], TWO_PI)), (pid, ip[need_iv]))
        )
        # intervals touching a new sample, and their neighbours (the turning test looks one further)
        dirty = np.zeros(new_size - 1, bool)
        for off in (-2, -1, 0, 1):
            q = pos_mid + off
            dirty[q[(q >= 0) & (q < new_size - 1)]] = True
    count = np.bincount(pid, minlength=npaths)
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    same = pid[1:] == pid[:-1]
    return om, _segmented_unwrap(th1, same, first, pid), _segmented_unwrap(th2, same, first, pid), pid


def _interleave(x: NDArray, xm: NDArray, pos_old: NDArray[np.int64], pos_mid: NDArray[np.int64], size: int) -> NDArray:
    out = np.empty(size, dtype=np.result_type(x, xm))
    out[pos_old] = x
    out[pos_mid] = xm
    return out


def _relevant(om: NDArray, u1: NDArray, u2: NDArray, iv: NDArray[np.int64], window: tuple[float, float]) -> NDArray[np.bool_]:
    """Intervals whose lowest image (tau >= 0) of both delays is below tau_max (can reach the window)."""
    inv = 1.0 / om
    rel = np.ones(iv.size, bool)
    for u, tmax in ((u1, window[0]), (u2, window[1])):
        lowest = np.minimum(np.mod(u[iv], TWO_PI) * inv[iv], np.mod(u[iv + 1], TWO_PI) * inv[iv + 1])
        rel &= lowest <= tmax * 1.05
    return rel


def _chord_needs(
    om: NDArray, u1: NDArray, u2: NDArray, iv: NDArray[np.int64], m_om: NDArray, m1: NDArray, m2: NDArray,
    window: tuple[float, float], scale: float,
) -> NDArray[np.bool_]:
    """The chord tests of :func:`delayform.analysis.ctcr.phase._needs_refinement` on intervals iv."""
    inv = 1.0 / om
    ia, ib = inv[iv], inv[iv + 1]
    m_inv = 1.0 / m_om
    need = np.zeros(iv.size, bool)
    for u, m, tmax in ((u1, m1, window[0]), (u2, m2, window[1])):
        n_far = np.ceil(tmax * np.maximum(om[iv], om[iv + 1]) / TWO_PI) + 1.0
        tau_a, tau_b, tau_m = u[iv] * ia, u[iv + 1] * ib, m * m_inv
        dev = np.abs(tau_m - 0.5 * (tau_a + tau_b))
        dev_shift = TWO_PI * n_far * np.abs(m_inv - 0.5 * (ia + ib))
        chord = np.abs(tau_b - tau_a) + TWO_PI * n_far * np.abs(ib - ia)
        need |= (dev + dev_shift > CHORD_TOL * scale) | (chord > _MAX_CHORD * scale)
    return need


# ===================================================================== tendencies and embedding
def _tendencies(
    lam: NDArray[np.complex128], P: float, D: float, omega: NDArray[np.float64],
    t1: NDArray[np.float64], t2: NDArray[np.float64],
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(RT1, RT2) at s = j omega of q_lam (closed form of the implicit-function derivative)."""
    s = 1j * omega
    a = lam * P * np.exp(-t1 * s)
    b = lam * D * np.exp(-t2 * s)
    dq_ds = 2.0 * s + D + t1 * a - b + t2 * b * s
    with np.errstate(divide="ignore", invalid="ignore"):
        return tendency_sign(-(a * s) / dq_ds), tendency_sign(-(b * s * s) / dq_ds)


def family_curves(parts: Sequence[_Part], lam: NDArray[np.complex128], P: float, D: float,
                  window: tuple[float, float]) -> list[CrossingCurve]:
    """All kernel and offspring curves of the lam-family parts (source = index into parts)."""
    path_part, paths = _frequency_paths(lam, P, D)
    if path_part.size == 0:
        return []
    curves: list[CrossingCurve] = []
    lo, chunk = 0, 8
    while lo < path_part.size:
        sel = np.arange(lo, min(lo + chunk, path_part.size))
        sub = _Paths(paths.lam[sel], paths.lo[sel], paths.hi[sel], paths.start[sel], paths.stop[sel], P, D)
        om, u1, u2, pid = _sample_paths(sub, window)
        curves.extend(_embed_all(om, u1, u2, pid, path_part[sel], parts, lam, P, D, window))
        # the next chunk holds about _SAMPLE_BUDGET samples (paths of one team are alike)
        lo += sel.size
        chunk = int(np.clip(_SAMPLE_BUDGET * sel.size / max(om.size, 1), 8, 4096))
    return curves


def _embed_all(
    om: NDArray, u1: NDArray, u2: NDArray, pid: NDArray[np.int64], path_part: NDArray[np.int64],
    parts: Sequence[_Part], lam: NDArray[np.complex128], P: float, D: float, window: tuple[float, float],
) -> list[CrossingCurve]:
    """:func:`delayform.analysis.ctcr.curves._embed` of every sampled path, tendencies in one call.

    Only the samples an image keeps (inside the window, or next to such a
    sample) are stored, so memory follows the curve points kept.
    """
    t1max, t2max = window
    margin1, margin2 = 0.02 * t1max, 0.02 * t2max
    count = np.bincount(pid, minlength=path_part.size)
    bounds = np.concatenate([[0], np.cumsum(count)])
    images = []
    for p in range(path_part.size):
        a, b = bounds[p], bounds[p + 1]
        if b - a == 0:
            continue
        w, v1, v2 = om[a:b], u1[a:b], u2[a:b]
        i_lo = int(np.ceil(np.min(-v1) / TWO_PI))
        i_hi = int(np.floor(np.max(t1max * w - v1) / TWO_PI))
        k_lo = int(np.ceil(np.min(-v2) / TWO_PI))
        k_hi = int(np.floor(np.max(t2max * w - v2) / TWO_PI))
        inv = 1.0 / w
        for i in range(i_lo, i_hi + 1):
            p1 = v1 + TWO_PI * i
            tau1 = p1 * inv
            in1 = (tau1 >= -margin1) & (tau1 <= t1max + margin1)
            if not np.any(in1):
                continue
            sub = np.flatnonzero(in1)
            for k in range(k_lo, k_hi + 1):
                tau2_sub = (v2[sub] + TWO_PI * k) * inv[sub]
                ok = (tau2_sub >= -margin2) & (tau2_sub <= t2max + margin2)
                if not np.any(ok):
                    continue
                inside = np.zeros(b - a, bool)
                inside[sub[ok]] = True
                keep = inside.copy()
                keep[:-1] |= inside[1:]
                keep[1:] |= inside[:-1]
                kept = np.flatnonzero(keep)
                p2 = v2[kept] + TWO_PI * k
                images.append((p, a + kept, tau1[kept], p2 * inv[kept], p1[kept], p2, inside[kept], i, k))
    if not images:
        return []
    # tendencies of all kept samples of all images in one vectorized call
    idx = np.concatenate([im[1] for im in images])
    lam_pt = np.repeat(lam[path_part[[im[0] for im in images]]], [im[1].size for im in images])
    t1_pt = np.concatenate([im[2] for im in images])
    t2_pt = np.concatenate([im[3] for im in images])
    rt1_all = np.empty(idx.size, np.int8)
    rt2_all = np.empty(idx.size, np.int8)
    for lo in range(0, idx.size, 65536):  # blocks: the complex temporaries stay small
        blk = slice(lo, lo + 65536)
        rt1_all[blk], rt2_all[blk] = _tendencies(lam_pt[blk], P, D, om[idx[blk]], t1_pt[blk], t2_pt[blk])
    del t1_pt, t2_pt, lam_pt
    curves: list[CrossingCurve] = []
    pos = 0
    for p, gidx, tau1, tau2, p1, p2, inside, _, _ in images:
        n = gidx.size
        part = parts[int(path_part[p])]
        curves.extend(_split_kept(gidx, om[gidx], tau1, tau2, p1, p2, (rt1_all[pos : pos + n], rt2_all[pos : pos + n]),
                                  part.weight, int(path_part[p]), part.factor))
        pos += n
    return curves


def _split_kept(
    gidx: NDArray[np.int64], om: NDArray, tau1: NDArray, tau2: NDArray, p1: NDArray, p2: NDArray,
    rts: tuple[NDArray[np.int64], NDArray[np.int64]], weight: int, source: int, factor: int,
) -> list[CrossingCurve]:
    """:func:`delayform.analysis.ctcr.curves._split_runs` on the kept samples (gidx: their sample indices)."""
    i1 = np.floor(p1 / TWO_PI).astype(np.int64)
    i2 = np.floor(p2 / TWO_PI).astype(np.int64)
    kernel = (i1 == 0) & (i2 == 0)
    out: list[CrossingCurve] = []
    breaks = np.flatnonzero(np.diff(gidx) > 1) + 1
    for lo, hi in zip(np.concatenate([[0], breaks]), np.concatenate([breaks, [gidx.size]]), strict=True):
        if hi - lo < 2:
            continue
        # one piece per shift (i, k) of the paper's eq. 6; the last vertex is shared with the next piece
        cut = np.flatnonzero((i1[lo + 1 : hi] != i1[lo : hi - 1]) | (i2[lo + 1 : hi] != i2[lo : hi - 1])) + 1 + lo
        edges = np.concatenate([[lo], cut, [hi]])
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            sel = slice(a, min(b + 1, hi))
            if min(b + 1, hi) - a < 2:
                continue
            out.append(
                CrossingCurve(
                    tau1=tau1[sel], tau2=tau2[sel], omega=om[sel],
                    rt1=rts[0][sel], rt2=rts[1][sel],
                    kind="kernel" if kernel[a] else "offspring",
                    shift=(int(i1[a]), int(i2[a])), weight=weight, source=source, factor=factor,
                )
            )
    return out


# ===================================================================== axis crossings
def family_axis_crossings(
    parts: Sequence[_Part], lam: NDArray[np.complex128], P: float, D: float,
    window: tuple[float, float], *, axis: int,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """:func:`delayform.analysis.ctcr.curves._axis_crossings` of all lam-family parts at once.

    On tau1 = 0: ``h0 = s^2 + D s + P (1 - lam)``, ``h1 = -lam D s``; on tau2 = 0:
    ``h0 = s^2 + D s (1 - lam) + P``, ``h1 = -lam P``. A crossing frequency solves
    ``|h0(j omega)|^2 = |h1(j omega)|^2`` (a quartic in omega), the phase
    ``e^{-j theta} = -h0 / h1``, polished by Newton's method in (omega, theta).
    """
    a, b = lam.real, lam.imag
    r2 = a * a + b * b
    one = np.ones_like(a)
    if axis == 2:
        # h0(j w) = P(1-a) - w^2 + j (D w - P b)
        re0, re2 = P * (1.0 - a), -one
        # |h0|^2 - r2 D^2 w^2
        poly = np.stack([re0**2 + (P * b) ** 2, -2.0 * D * P * b, 2.0 * re0 * re2 + D * D - r2 * D * D,
                         np.zeros_like(a), one], axis=1)
    else:
        # h0(j w) = P - w^2 + D b w + j D (1 - a) w ; |h1|^2 = r2 P^2
        poly = np.stack([P * P - r2 * P * P, 2.0 * P * D * b, -2.0 * P + (D * b) ** 2 + (D * (1.0 - a)) ** 2,
                         -2.0 * D * b, one], axis=1)
    roots = _batch_positive_roots(poly)
    k, col = np.nonzero(np.isfinite(roots))
    om = roots[k, col]
    lk = lam[k]

    def h(om: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        s = 1j * om
        if axis == 2:
            return s * s + D * s + P * (1.0 - lk), -lk * D * s, 2.0 * s + D, -lk * D
        return s * s + D * s * (1.0 - lk) + P, -lk * P + 0.0 * s, 2.0 * s + D * (1.0 - lk), 0.0 * s

    h0, h1, _, _ = h(om)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = -h0 / h1
    ok = np.isfinite(z) & (np.abs(np.abs(z) - 1.0) <= 1e-5)
    om, lk, k, z = om[ok], lk[ok], k[ok], z[ok]
    th = -np.angle(z)
    h0, h1, d0, d1 = h(om)
    e = np.exp(-1j * th)
    exact = np.abs(h0 + h1 * e) <= 1e-12 * (np.abs(h0) + np.abs(h1))
    omn, thn = om.copy(), th.copy()
    for _ in range(20):  # 2 x 2 Newton on f(omega, theta) = h0 + h1 e^{-j theta} (j d/ds in omega)
        h0, h1, d0, d1 = h(omn)
        e = np.exp(-1j * thn)
        f = h0 + h1 * e
        fo = 1j * (d0 + d1 * e)
        ft = -1j * h1 * e
        det = fo.real * ft.imag - ft.real * fo.imag
        with np.errstate(divide="ignore", invalid="ignore"):
            d_om = (f.real * ft.imag - ft.real * f.imag) / det
            d_th = (fo.real * f.imag - f.real * fo.imag) / det
        move = ~exact & np.isfinite(d_om) & np.isfinite(d_th) & (np.abs(f) > 1e-15 * (np.abs(h0) + np.abs(h1)))
        omn = np.where(move, omn - d_om, omn)
        thn = np.where(move, thn - d_th, thn)
    h0, h1, _, _ = h(omn)
    good = exact | ((np.abs(h0 + h1 * np.exp(-1j * thn)) <= 1e-10 * (np.abs(h0) + np.abs(h1))) & (omn > 0))
    om, th, k = np.where(exact, om, omn)[good], np.mod(np.where(exact, th, thn)[good], TWO_PI), k[good]
    tmax = window[axis - 1]
    reps = (np.floor(tmax * om / TWO_PI) + 2).astype(np.int64)
    rk = np.repeat(np.arange(om.size), reps)
    i = np.arange(rk.size) - np.repeat(np.cumsum(reps) - reps, reps)
    tau = (th[rk] + TWO_PI * i) / om[rk]
    keep = (tau > 1e-12 * tmax) & (tau <= tmax)
    rk, tau = rk[keep], tau[keep]
    zero = np.zeros(tau.size)
    t1, t2 = (zero, tau) if axis == 2 else (tau, zero)
    rt1, rt2 = _tendencies(lam[k[rk]], P, D, om[rk], t1, t2)
    weight = np.array([parts[int(j)].weight for j in k[rk]], dtype=np.int64)
    delta = weight * (rt2 if axis == 2 else rt1)
    order = np.argsort(tau, kind="stable")
    return tau[order], delta[order]
