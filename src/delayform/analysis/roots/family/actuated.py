"""The factor family with an actuation delay: q, polishing, seeds and the certificate, vectorized over rows.

A robot that applies its command tau_a late turns every factor of the paper's eq. 3 into
(docs/theory.md, "Actuation delay")

    q(s) = s^2 + e^{-tau_a s} r(s),   r(s) = D s + P - lam (P e^{-tau1 s} + D s e^{-tau2 s}),

r being the paper's factor without its s^2. A map at one tau_a is a family of rows
(lam, tau1, tau2) sharing tau_a (:class:`~delayform.analysis.roots.family.rows._Rows`
with ``ta > 0``); the drivers of :mod:`delayform.analysis.roots.family.solve`
(continuation from the nearest solved point, the line choice, redo with fresh seeds)
call the four pieces here instead of the tau_a = 0 ones:

* :func:`actuated_polish` -- Newton on q itself (Maehly's deflation q / s in the
  centroid rows, the paper's eq. 4), a root accepted when its relative residual is at most
  RESIDUAL_TOL, evaluated at the root (no Taylor shortcut);
* :func:`actuated_seeds` -- the Chebyshev discretization of the generator of the
  row's DDE, x'' = -P x(t - ta) - D x'(t - ta) + lam (P x(t - t1 - ta) + D x'(t - t2 - ta)),
  in the reduced form of :func:`~delayform.analysis.roots.family.seeds._generator_blocks`
  (the eigenvector's velocity is mu times its position), stacked per degree;
* :func:`actuated_count` -- the argument-principle certificate on Re s = c: on the line
  |e^{-h s}| = e^{-h c}, so ``|q - s^2| <= B1 |s| + B0`` with
  ``B1 = D e^{-ta c} + |lam| D e^{-(t2 + ta) c}``, ``B0 = P e^{-ta c} + |lam| P e^{-(t1 + ta) c}``
  (Rouche beyond the root Omega of r^2 = B1 r + B0, compared with s^2), and on |s| <= rho
  ``|q''| <= 2 + e^{-ta c} (2 ta D + ta^2 (D rho + P)) + (t1 + ta)^2 E1 + E2 (2 (t2 + ta) + (t2 + ta)^2 rho)``
  (term by term, E1, E2 the delayed terms' moduli), which the chord test of
  :func:`~delayform.analysis.roots.family.walk._chord_ok` needs;
* :func:`actuated_slopes` -- ds/dtau1 and ds/dtau2 by the implicit function theorem
  (dq/dtau1 = e^{-ta s} s a, dq/dtau2 = e^{-ta s} s^2 b).

Rows none of this certifies go to :func:`actuated_fallback`, the generic robust path
on the quasi-polynomial in three delays (:func:`actuated_quasi`).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.roots.family.polish import _scatter
from delayform.analysis.roots.family.rows import _at, _Rows
from delayform.analysis.roots.family.seeds import _eigvals, _rightmost_k
from delayform.analysis.roots.family.walk import _chord_ok, _drop_crowded, _quad2
from delayform.analysis.roots.generator import _chebyshev, _lagrange_rows
from delayform.analysis.roots.problem import MAX_DEGREE, RESIDUAL_TOL, UNIT_DELAYS, _problem_of_quasi
from delayform.analysis.roots.rightmost import _pick_rightmost, _solve_rightmost
from delayform.quasipolynomial import QuasiPolynomial

_Array = NDArray[np.float64]
_CArray = NDArray[np.complex128]

#: Newton steps before a seed still moving is judged by its residual where it stopped.
_NEWTON_STEPS = 30
#: Halvings of a rejected segment of the certificate's walk before the line is given up.
_HALVINGS = 52


def actuated_quasi(P: float, D: float, lam: complex) -> QuasiPolynomial:
    """q of the module docstring as a :class:`QuasiPolynomial` in the delays (tau1, tau2, tau_a)."""
    return QuasiPolynomial({
        (0, 0, 0): [0.0, 0.0, 1.0],
        (0, 0, 1): [P, D],
        (1, 0, 1): [-lam * P],
        (0, 1, 1): [0.0, -lam * D],
    })  # fmt: skip


def _evaluate(
    s: _CArray, lam: Any, t1: Any, t2: Any, ta: float, P: Any, D: Any
) -> tuple[_CArray, _CArray, _CArray, _CArray, _CArray]:
    """q(s), dq/ds, e^{-ta s} and the delayed terms a = lam P e^{-t1 s}, b = lam D e^{-t2 s} (broadcasting)."""
    E = np.exp(-ta * s)
    a = lam * P * np.exp(-t1 * s)
    b = lam * D * np.exp(-t2 * s)
    r = (D - b) * s + P - a
    dr = D + t1 * a - b + t2 * b * s
    return s * s + E * r, 2.0 * s + E * (dr - ta * r), E, a, b


def _scale(s: _CArray, E: _CArray, a: _CArray, b: _CArray, P: Any, D: Any) -> _Array:
    """Sum of the moduli of q's terms at s: the relative residual's denominator."""
    z = np.abs(s)
    return z * z + np.abs(E) * (D * z + P + np.abs(a) + np.abs(b) * z)  # type: ignore[no-any-return]


def actuated_polish(seeds: _CArray, rows: _Rows) -> tuple[_CArray, NDArray[np.bool_]]:
    """Newton on q from seeds (R, K) (Maehly's q / (q' - q / s) in deflated rows): (roots, accepted).

    A root is accepted when |q| <= RESIDUAL_TOL times the sum of its terms' moduli. A seed
    reaching s ~ 0 in a deflated (centroid) row is the double zero exactly when q'(0) = 0
    (tau1 = 0 for lam = 1: q'(0) = D (1 - lam) + tau1 lam P - tau_a P (1 - lam)) and is
    otherwise rejected (a genuine root beside the persistent zero: the fallback resolves it).
    """
    R, K = seeds.shape
    flat = seeds.ravel()
    live = np.flatnonzero(np.isfinite(flat))
    rid = live // K
    s = np.take(flat, live)
    ta = rows.ta
    P, D = _at(rows.P, rid), _at(rows.D, rid)
    lam, t1, t2, defl = (np.take(x, rid) for x in (rows.lam, rows.t1, rows.t2, rows.deflate))
    act = np.arange(s.size)
    for _ in range(_NEWTON_STEPS):
        if act.size == 0:
            break
        sa = s[act]
        q, dq, _, _, _ = _evaluate(sa, lam[act], t1[act], t2[act], ta, _at(P, act), _at(D, act))
        da = defl[act]
        step = np.where(da, q / (dq - q / np.where(sa == 0.0, np.nan, sa)), q / dq)
        bad = ~np.isfinite(step)
        s[act] = np.where(bad, sa, sa - step)
        act = act[~bad & (np.abs(step) > 1e-14 * (1.0 + np.abs(sa)))]
    q, _, E, a, b = _evaluate(s, lam, t1, t2, ta, P, D)
    mag = _scale(s, E, a, b, P, D)
    ok = np.isfinite(mag) & (np.abs(q) <= RESIDUAL_TOL * mag)
    near = defl & (np.abs(s) < 1e-6)
    if near.any():
        i = np.flatnonzero(near)
        lz, Pi, Di = lam[i], _at(P, i), _at(D, i)
        double = Di * (1.0 - lz) + t1[i] * lz * Pi - ta * Pi * (1.0 - lz) == 0.0
        s[i] = np.where(double, 0.0, s[i])
        ok[i] = double
    return _scatter(live, s, ok, (R, K))


def actuated_scale(lam: _CArray, P: Any, D: Any) -> _Array:
    """A bound of |s| for the roots with Re s >= 0 of the factor of lam: |s|^2 <= (1 + |lam|)(D |s| + P), at least 1."""
    k = 1.0 + np.abs(lam)
    kd = k * D
    return np.maximum(1.0, 0.5 * (kd + np.sqrt(kd * kd + 4.0 * k * P)))  # type: ignore[no-any-return]


def _generator_stack(N: int, t1: _Array, t2: _Array, ta: float, P: Any, D: Any) -> tuple[_Array, _Array]:
    """(K0, K1), shape (B, N + 2, N + 2): K0 + lam K1 is the reduced discretized generator of the row's DDE.

    As :func:`~delayform.analysis.roots.family.seeds._generator_stack` with three delays: in
    the unknowns (y at the N + 1 Chebyshev nodes of [-h_max, 0], w = velocity at 0) the last
    row is ``mu w = -P La.y - D La.(mu y) + lam (P L1.y + D L2.(mu y))``, La, L1, L2 the
    interpolation rows at -ta, -(t1 + ta), -(t2 + ta), and ``mu y = (w, (Dm y)_1..N)``.
    """
    _, Dm, _ = _chebyshev(N)
    h = np.stack([np.full(t1.shape, ta), t1 + ta, t2 + ta], axis=-1)  # (B, 3)
    hmax = h.max(axis=-1)
    L = _lagrange_rows(N, 1.0 - 2.0 * h / hmax[:, None])  # (B, 3, N + 1)
    Dh = (2.0 / hmax)[:, None, None] * Dm[1:]  # (B, N, N + 1)
    B = t1.size
    Pc, Dc = np.reshape(P, (-1, 1)), np.reshape(D, (-1, 1))
    K0 = np.zeros((B, N + 2, N + 2))
    K0[:, 0, N + 1] = 1.0
    K0[:, 1 : N + 1, : N + 1] = Dh
    K0[:, N + 1, : N + 1] = -(Pc * L[:, 0] + Dc * np.einsum("bj,bjk->bk", L[:, 0, 1:], Dh))
    K0[:, N + 1, N + 1] = -np.reshape(D, -1) * L[:, 0, 0]
    K1 = np.zeros((B, N + 2, N + 2))
    K1[:, N + 1, : N + 1] = Pc * L[:, 1] + Dc * np.einsum("bj,bjk->bk", L[:, 2, 1:], Dh)
    K1[:, N + 1, N + 1] = np.reshape(D, -1) * L[:, 2, 0]
    return K0, K1


def actuated_seeds(rows: _Rows, k: int, *, scale: float = 1.0) -> _CArray:
    """The k rightmost eigenvalues of every row's discretized generator (R, k); ``scale`` multiplies the degree.

    The degree follows the root bound and the longest delay as in the tau_a = 0 family
    (``0.6 x bound x h_max + 4``, at least 6, at most MAX_DEGREE); rows of equal degree
    and of real or complex lam share one stacked eigenvalue call. A real row keeps one of
    each conjugate pair (the certificate folds to Im >= 0); the centroid rows' persistent
    zero is dropped.
    """
    lam, t1, t2, ta = rows.lam, rows.t1, rows.t2, rows.ta
    R = lam.size
    out = np.full((R, k), np.nan + 0j)
    hmax = np.maximum(t1, t2) + ta
    radius = actuated_scale(lam, rows.P, rows.D)
    N = np.clip(np.ceil(scale * (0.6 * radius * hmax + 4.0)), 6, MAX_DEGREE).astype(int)
    for n in np.unique(N):
        for real in (True, False):
            idx = np.flatnonzero((N == n) & ((lam.imag == 0.0) == real))
            if idx.size == 0:
                continue
            M0, M1 = _generator_stack(int(n), t1[idx], t2[idx], ta, _at(rows.P, idx), _at(rows.D, idx))
            lr = lam[idx].real if real else lam[idx]
            eig = _eigvals(M0 + lr[:, None, None] * M1)
            if real:
                eig[eig.imag < 0.0] = np.nan
            eig[rows.deflate[idx, None] & (np.abs(eig) < 1e-9)] = np.nan
            top = _rightmost_k(eig, min(k, eig.shape[1]))
            out[idx, : top.shape[1]] = top
    return out


def actuated_slopes(roots: _CArray, lam: _CArray, t1: _Array, t2: _Array, ta: float, P: float, D: float) -> tuple[_CArray, _CArray]:
    """ds/dtau1, ds/dtau2 of roots (F, n, K) at delays (n,); undefined or large slopes set to 0 (only seeds)."""
    _, dq, E, a, b = _evaluate(roots, lam[:, None, None], t1[None, :, None], t2[None, :, None], ta, P, D)
    g1 = -E * roots * a / dq
    g2 = -E * roots * roots * b / dq
    for g in (g1, g2):
        g[~np.isfinite(g) | (np.abs(g) > 10.0)] = 0.0
    return g1, g2


def _on_line(c: _Array, w: _Array, rows: _Rows, idx: Any) -> _CArray:
    """q(c + i w) of rows idx (w and c broadcast)."""
    s = c + 1j * w
    return _evaluate(s, rows.lam[idx], rows.t1[idx], rows.t2[idx], rows.ta, _at(rows.P, idx), _at(rows.D, idx))[0]


def actuated_count(rows: _Rows, c: _Array, *, max_segments: int = 4096) -> _Array:
    """Certified number of roots of q with Re s > c per row (NaN: not certified); the module docstring's bounds.

    The walk along Re s = c from w = lo (0 for real lam, whose q is symmetric, else
    -Omega) to Omega: uniform samples about one radian of the fastest e^{-i h w} apart,
    each segment accepted by the chord test (its change of arg q is then exactly
    Arg(q_b conj q_a)) or halved up to :data:`_HALVINGS` times; beyond +-Omega
    arg q = arg s^2 + Arg(q / s^2), |q / s^2 - 1| < 1. Count = 1 - (change of arg) / 2 pi
    (degree 2). A line with more than ``max_segments`` pending segments, an exact zero or
    an overflow of q is not certified.
    """
    n = c.size
    ta = rows.ta
    lam_abs = np.abs(rows.lam)
    P, D = rows.P, rows.D
    t1, t2 = rows.t1, rows.t2
    Ea = np.exp(-ta * c)
    E1 = lam_abs * P * np.exp(-(t1 + ta) * c)
    E2 = lam_abs * D * np.exp(-(t2 + ta) * c)
    b1, b0 = D * Ea + E2, P * Ea + E1
    omega = (b1 + np.sqrt(b1 * b1 + 4.0 * b0)) / 2.0 * (1.0 + 1e-9) + 1e-12
    m2_slope = ta * ta * D * Ea + (t2 + ta) ** 2 * E2
    m2_offset = 2.0 + Ea * (2.0 * ta * D + ta * ta * P) + (t1 + ta) ** 2 * E1 + 2.0 * (t2 + ta) * E2
    lo = np.where(rows.real, 0.0, -omega)
    turn = (np.maximum(t1, t2) + ta) * (omega - lo)
    finite = np.isfinite(turn) & np.isfinite(m2_offset) & np.isfinite(m2_slope)
    sizes = np.where(finite, 2 ** np.ceil(np.log2(np.clip(np.where(finite, turn, 0.0) + 8.0, 16.0, 4096.0))), 16)
    sizes = sizes.astype(int)
    total = np.zeros(n)
    failed = ~finite
    pending: list[tuple[NDArray[np.int64], _Array, _Array, _CArray, _CArray]] = []
    for m in np.unique(sizes):
        idx = np.flatnonzero((sizes == m) & finite)
        if idx.size == 0:
            continue
        h = (omega[idx] - lo[idx]) / (m - 1)
        w = lo[idx] + h * np.arange(m)[:, None]  # (m, n_idx)
        q = _on_line(c[idx], w, rows, idx)
        failed[idx] |= ~np.isfinite(q).all(axis=0) | (q == 0.0).any(axis=0)
        rho = np.maximum(np.abs(c[idx] + 1j * w[:-1]), np.abs(c[idx] + 1j * w[1:]))
        good, turn_q = _chord_ok(q[:-1], q[1:], _quad2(rho, h, m2_slope[idx], m2_offset[idx]))
        total[idx] += np.where(good, np.angle(turn_q), 0.0).sum(axis=0)
        j, col = np.nonzero(~good)
        if j.size:
            pending.append((idx[col], w[j, col], h[col], q[j, col], q[j + 1, col]))
    if pending:
        line, wa, hh, qa, qb = (np.concatenate(p) for p in zip(*pending))
        for _ in range(_HALVINGS):
            if line.size == 0:
                break
            line, wa, hh, qa, qb = _drop_crowded(line, failed, max_segments, wa, hh, qa, qb)
            hh = 0.5 * hh
            wm = wa + hh
            qm = _on_line(c[line], wm, rows, line)
            failed[line[~np.isfinite(qm) | (qm == 0.0)]] = True
            line = np.concatenate([line, line])
            wa, hh = np.concatenate([wa, wm]), np.concatenate([hh, hh])
            qa, qb = np.concatenate([qa, qm]), np.concatenate([qm, qb])
            cl = c[line]
            rho = np.maximum(np.abs(cl + 1j * wa), np.abs(cl + 1j * (wa + hh)))
            good, turn_q = _chord_ok(qa, qb, _quad2(rho, hh, m2_slope[line], m2_offset[line]))
            total += np.bincount(line[good], np.angle(turn_q[good]), minlength=n)
            bad = ~good
            line, wa, hh, qa, qb = line[bad], wa[bad], hh[bad], qa[bad], qb[bad]
        failed[line] = True
    # the tails beyond +-Omega, compared with s^2 (whose argument is 2 arg s)
    e = c + 1j * omega
    top = 2.0 * (0.5 * math.pi - np.angle(e)) - np.angle(_on_line(c, omega, rows, np.arange(n)) / (e * e))
    delta = 2.0 * (total + top)
    cx = np.flatnonzero(~rows.real)
    if cx.size:
        e = c[cx] - 1j * omega[cx]
        bottom = 2.0 * (np.angle(e) + 0.5 * math.pi) + np.angle(_on_line(c[cx], -omega[cx], rows, cx) / (e * e))
        delta[cx] = total[cx] + top[cx] + bottom
    count = 1.0 - delta / (2.0 * math.pi)
    good = ~failed & np.isfinite(count) & (np.abs(count - np.round(count)) < 0.1)
    return np.where(good, np.round(count), np.nan)


def actuated_fallback(lam: complex, P: float, D: float, deflate: bool, t1: float, t2: float, ta: float) -> complex:
    """The certified rightmost root (Im >= 0) of one row by the generic robust path (degree doubling).

    On tau1 = 0 the centroid's second zero is its drift, returned as 0 exactly (the
    factor is s (s + D e^{-ta s} (1 - e^{-t2 s})) there).
    """
    if deflate and t1 == 0.0:
        return 0j
    prob = _problem_of_quasi(actuated_quasi(P, D, lam), (t1, t2, ta))
    if deflate:
        prob = replace(prob, deflate_zero=True)
    res = _solve_rightmost(prob, *UNIT_DELAYS, where=f"(tau1, tau2, tau_a) = ({t1:g}, {t2:g}, {ta:g})")
    root = _pick_rightmost(prob, res.roots)
    return complex(root.real, abs(root.imag))
