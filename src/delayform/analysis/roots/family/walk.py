"""The family's argument-principle certificate: certified root counts right of lines Re s = c.

The walk of :func:`delayform.analysis.roots.argument_principle._count_right_batch`, written
out for the family of :mod:`delayform.analysis.roots.family.rows` and vectorized over rows,
with a chord test for the samples and the winding counted from Arg at the walk's
ends plus its crossings of Arg's branch cut (:func:`_count_rows`).
"""

from __future__ import annotations

import cmath
import math
from functools import lru_cache, partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.analysis.roots.family.rows import Gain, _at, _delay_free, _Rows


#: Rows of the walk's samples at its two ends (top, bottom), for the tails.
_ENDS = np.array([-1, 0])
#: Initial samples of the certified walk along Re s = c (bisected where needed).
_INITIAL_SAMPLES = 12


# =====================================================================
# the certificate, vectorized over rows (same bounds as certificate.py)
# =====================================================================
def _chord_ok(
    qa: NDArray[np.complex128], qb: NDArray[np.complex128], quad2: NDArray[np.float64],
    qa2: NDArray[np.float64] | None = None, qb2: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.complex128]]:
    """The chord test of :func:`_count_rows`: segments whose chord [q_a, q_b] keeps off 0 by more than sqrt(quad2).

    From t = q_b conj(q_a): the chord's point nearest 0 lies inside it when Re t < |q_a|^2
    and Re t < |q_b|^2, at distance |Im t| / |q_b - q_a|; otherwise the nearer end is the
    nearest point. Returns the accepted segments and t, whose argument is the segment's
    change of arg q where accepted. |q_a|^2, |q_b|^2 may be passed when already known.
    """
    if qa2 is None:
        qa2 = qa.real * qa.real + qa.imag * qa.imag
    if qb2 is None:
        qb2 = qb.real * qb.real + qb.imag * qb.imag
    turn = qb * np.conj(qa)
    dd = qa2 + qb2 - 2.0 * turn.real  # |q_b - q_a|^2
    inside = (turn.real < qa2) & (turn.real < qb2)
    good = np.where(inside, turn.imag * turn.imag > quad2 * dd, np.minimum(qa2, qb2) > quad2)
    return good, turn


def _drop_crowded(line: NDArray[np.intp], failed: NDArray[np.bool_], max_segments: int,
                  *per_segment: NDArray[Any]) -> tuple[NDArray[Any], ...]:  # fmt: skip
    """Drop the segments of lines that hold more than ``max_segments`` of them, marking those lines failed.

    ``line`` names each pending segment's line; ``per_segment`` are the segments' other
    arrays, filtered alike. Returns ``(line, *per_segment)``; ``failed`` is updated in place.
    """
    crowded = np.bincount(line, minlength=failed.size) > max_segments
    if not crowded.any():
        return (line, *per_segment)
    failed |= crowded
    keep = ~crowded[line]
    return (line[keep], *(a[keep] for a in per_segment))


def _quad2(
    rho: NDArray[np.float64], h: Any, m2_slope: Any, m2_offset: Any
) -> NDArray[np.float64]:
    """(M2 h^2 / 8)^2: the squared bound of |q - chord| on a segment of length h within |s| <= rho."""
    quad = (m2_slope * rho + m2_offset) * (0.125 * h * h)
    return quad * quad  # type: ignore[no-any-return]


class _Walk:
    """The lines Re s = c of a walk: what bisecting a rejected segment needs (see :func:`_count_rows`)."""

    def __init__(
        self, c: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64], A1: NDArray[np.complex128],
        B1: NDArray[np.complex128], m2_slope: NDArray[np.float64], m2_offset: NDArray[np.float64], P: Gain, D: Gain,
    ) -> None:
        self.c, self.t1, self.t2, self.A1, self.B1 = c, t1, t2, A1, B1
        self.m2_slope, self.m2_offset, self.P, self.D = m2_slope, m2_offset, P, D

    def bisect(
        self, total: NDArray[np.float64], failed: NDArray[np.bool_], line: NDArray[np.int64], wa: NDArray[np.float64],
        qa: NDArray[np.complex128], qb: NDArray[np.complex128], ka: NDArray[np.complex128], kb: NDArray[np.complex128],
        h: NDArray[np.float64], max_segments: int,
    ) -> None:
        """Bisect the rejected segments [c + i wa, c + i (wa + h)] of each line until the chord test accepts them.

        Adds 2 pi times their crossings of the branch cut of Arg (:func:`_cut_crossings`) to
        ``total`` -- the rest of their change of arg q telescopes to the Arg of the rejected
        segments' ends, which the caller has counted -- and marks in ``failed`` the lines that
        need more than ``max_segments`` segments, 52 halvings, or meet a zero or an
        overflow of q. ``ka``, ``kb``: e^{-i tau1 wa}, e^{-i tau2 wa} (rotated, not recomputed).
        """
        c, t1, t2, A1, B1, P, D = self.c, self.t1, self.t2, self.A1, self.B1, self.P, self.D
        n = c.size
        c2 = c * c
        step = h.copy()
        for _ in range(52):
            if line.size == 0:
                return
            line, wa, qa, qb, ka, kb = _drop_crowded(line, failed, max_segments, wa, qa, qb, ka, kb)
            step = 0.5 * step
            take = partial(np.take, indices=line)  # 1-D gathers: np.take beats fancy indexing
            wm = wa + take(step)
            # the midpoints' unit factors: one rotation per line still walking (not per line of the batch)
            walking = np.zeros(n, dtype=bool)
            walking[line] = True
            wl = np.flatnonzero(walking)
            rot1, rot2 = np.empty(n, dtype=np.complex128), np.empty(n, dtype=np.complex128)
            rot1[wl] = np.exp(-1j * (t1[wl] * step[wl]))
            rot2[wl] = np.exp(-1j * (t2[wl] * step[wl]))
            km, kbm = ka * take(rot1), kb * take(rot2)
            sm = take(c) + 1j * wm
            Dl, Pl = _at(D, line), _at(P, line)
            qm = (sm + Dl) * sm + Pl - take(A1) * km - (take(B1) * kbm) * sm
            failed[line[~np.isfinite(qm) | (qm == 0.0)]] = True
            line = np.concatenate([line, line])
            take = partial(np.take, indices=line)
            wa = np.concatenate([wa, wm])
            qa, qb = np.concatenate([qa, qm]), np.concatenate([qm, qb])
            ka, kb = np.concatenate([ka, km]), np.concatenate([kb, kbm])
            hl = take(step)
            rho = np.sqrt(take(c2) + np.maximum(wa * wa, (wa + hl) ** 2))
            good, turn = _chord_ok(qa, qb, _quad2(rho, hl, take(self.m2_slope), take(self.m2_offset)))
            cut = _cut_crossings(np.signbit(qa.imag), np.signbit(qb.imag), turn.imag)
            g = np.flatnonzero(good)
            total += (2.0 * np.pi) * np.bincount(np.take(line, g), np.take(cut, g), minlength=n)
            bad = np.flatnonzero(~good)
            line, wa, qa, qb, ka, kb = (np.take(x, bad) for x in (line, wa, qa, qb, ka, kb))
        failed[line] = True


def _count_rows(
    rows: _Rows, c: NDArray[np.float64], *, max_segments: int = 4096
) -> NDArray[np.float64]:
    """Certified number of roots of q with Re s > c per row (NaN: not certified).

    The walk of :func:`delayform.analysis.roots.argument_principle._count_right_batch` with
    a chord test: on the line Re s = c the delayed terms have constant moduli
    E1 = |lam| P e^{-tau1 c}, E2 = |lam| D e^{-tau2 c}, so

        |q''(s)| <= M2 = 2 + tau1^2 E1 + 2 tau2 E2 + tau2^2 E2 rho   (|s| <= rho),

    and on a segment [s_a, s_b] of length h q differs from its chord
    (the linear interpolation of q(s_a), q(s_b)) by at most M2 h^2 / 8 (the
    Green's function of the second derivative). A segment is accepted when the
    chord keeps a distance greater than that from 0: then q does not vanish on
    it and arg q stays within pi / 2 of the chord's argument, which is exact at
    both ends, so the segment's change of arg q is exactly Arg(q(s_b) / q(s_a)).
    Near a root at distance delta from the line this accepts steps of order
    sqrt(delta) instead of the first-order test's delta, and needs no q'.
    The line is closed at infinity by the Cauchy radius (root of
    ``r^2 = (D + E2) r + P + E1``, Rouche). Rows with real lam walk Im s >= 0
    only (q(conj s) = conj q(s)).

    On the line e^{-tau s} = e^{-tau c} e^{-i tau w}: the unit factors are
    carried along the uniform initial samples by repeated rotation, and all
    segments bisected in round k have the same length per line, so their
    midpoints need one rotation per line and round instead of two complex
    exponentials per sample.
    """
    P, D = rows.P, rows.D
    n = c.size
    lam, t1, t2 = rows.lam, rows.t1, rows.t2
    x1, x2 = np.exp(-t1 * c), np.exp(-t2 * c)
    A1, B1 = lam * (P * x1), lam * (D * x2)  # a = A1 e^{-i tau1 w}, b = B1 e^{-i tau2 w}
    absl = np.abs(lam)
    E1, E2 = absl * P * x1, absl * D * x2
    b1, b0 = D + E2, P + E1
    omega = (b1 + np.sqrt(b1 * b1 + 4.0 * b0)) / 2.0 * (1.0 + 1e-9) + 1e-12
    m2_slope, m2_offset = t2 * t2 * E2, 2.0 + t1 * t1 * E1 + 2.0 * t2 * E2
    lo = np.where(rows.real, 0.0, -omega)
    if n <= 64:  # few lines: the Python cost of a bisection round outweighs extra samples
        sizes = np.full(n, 4 * _INITIAL_SAMPLES)
    else:  # samples in proportion to how far e^{-i tau w} turns along the walk (about 1.8 rad apart)
        turn = np.maximum(t1, t2) * (omega - lo)
        sizes = _WALK_SIZES[np.minimum(np.searchsorted(_WALK_SIZES, turn / 1.8 + 2.0), _WALK_SIZES.size - 1)]
    h = (omega - lo) / (sizes - 1)
    total = np.zeros(n)
    failed = np.zeros(n, dtype=bool)
    ends = np.empty((2, n), dtype=np.complex128)  # q at the top and the bottom end of each walk
    rejected = []
    buckets = np.unique(sizes)
    for m in buckets:
        idx = np.flatnonzero(sizes == m) if buckets.size > 1 else np.arange(n)
        tot, fail, q_ends, rej = _walk_uniform(
            int(m), c[idx], t1[idx], t2[idx], lo[idx], h[idx], A1[idx], B1[idx], m2_slope[idx], m2_offset[idx],
            _at(P, idx), _at(D, idx),
        )
        total[idx], failed[idx], ends[:, idx] = tot, fail, q_ends
        if rej is not None:
            rejected.append((idx[rej[0]],) + rej[1:])
    if rejected:
        line, wa, qa, qb, ka, kb = (np.concatenate(parts) for parts in zip(*rejected))
        _Walk(c, t1, t2, A1, B1, m2_slope, m2_offset, P, D).bisect(total, failed, line, wa, qa, qb, ka, kb, h, max_segments)
    # tails beyond +-Omega: arg q = arg g1 + Arg(q / g1), g1 = s^2 + D s + P (Rouche)
    # (the walk's end points are c + i Omega and c + i lo; real rows use only the top one)
    z = _free_roots(P, D) if not isinstance(P, np.ndarray) else _delay_free(0.0, P, D)  # (2,) or (n, 2)
    e = c + 1j * omega  # the top end
    top = (np.pi / 2 - np.angle(e[:, None] - z)).sum(axis=-1) - np.angle(ends[0] / ((e + D) * e + P))
    delta = 2.0 * (total + top)
    cx = np.flatnonzero(~rows.real)
    if cx.size:  # complex lam: the whole line, and the bottom tail
        e = c[cx] - 1j * omega[cx]
        zc, Pc, Dc = (z[cx] if z.ndim == 2 else z), _at(P, cx), _at(D, cx)
        bottom = (np.angle(e[:, None] - zc) + np.pi / 2).sum(axis=-1) + np.angle(ends[1, cx] / ((e + Dc) * e + Pc))
        delta[cx] = total[cx] + top[cx] + bottom
    count = 1.0 - delta / (2.0 * np.pi)
    good = ~failed & np.isfinite(count) & (np.abs(count - np.round(count)) < 0.1)
    return np.where(good, np.round(count), np.nan)


#: Sample counts of a walk's uniform first pass (chosen per line by how far e^{-i tau w} turns).
_WALK_SIZES = np.array([6, 8, 12, 16, 24, 32, 48])


def _walk_uniform(
    m: int, c: NDArray[np.float64], t1: NDArray[np.float64], t2: NDArray[np.float64], lo: NDArray[np.float64],
    h: NDArray[np.float64], A1: NDArray[np.complex128], B1: NDArray[np.complex128],
    m2_slope: NDArray[np.float64], m2_offset: NDArray[np.float64], P: Gain, D: Gain,
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.complex128], tuple[NDArray[Any], ...] | None]:
    """The first pass of :func:`_count_rows` over lines sampled at m uniform points each.

    Returns the change of arg q over the accepted segments, the lines that failed (an
    overflow), q at the two ends of each walk, and the rejected segments (line index,
    start w, q at both ends, the unit factors at the start), or None when all passed.
    """
    n = c.size
    w = lo + h * np.arange(m)[:, None]  # (m, n)
    # e^{-i tau (lo + j h)} for both delays by repeated rotation (no exponential per sample)
    zr = np.empty((m, 2, n), dtype=np.complex128)
    tau = np.stack([t1, t2])
    zr[0] = np.exp(-1j * (tau * lo))
    rot = np.exp(-1j * (tau * h))
    if n <= 64:  # few lines: one accumulate call
        zr[1:] = rot
        np.cumprod(zr, axis=0, out=zr)
    else:  # many lines: NumPy's accumulate along axis 0 is not vectorized
        for j in range(1, m):
            np.multiply(zr[j - 1], rot, out=zr[j])
    k1, k2 = zr[:, 0], zr[:, 1]
    sv = np.empty((m, n), dtype=np.complex128)
    sv.real, sv.imag = c, w
    q = sv * (sv + D - B1 * k2) + (P - A1 * k1)
    # an overflow poisons the line's sum; an exact zero of q on a sample fails the chord
    # test of both its segments in every round, so the line ends as not certified
    failed = ~np.isfinite(q.sum(axis=0))
    # the segments are tested in their (m - 1, n) layout (the chord test of _chord_ok with
    # rho = the larger |s| of a segment's ends); only rejected ones are gathered and bisected
    abs_s = np.abs(sv)
    qq = q.real * q.real + q.imag * q.imag
    good, turn = _chord_ok(q[:-1], q[1:], _quad2(np.maximum(abs_s[:-1], abs_s[1:]), h, m2_slope, m2_offset),
                           qq[:-1], qq[1:])  # fmt: skip
    # the change of arg q over the whole walk, whatever its final segments: Arg at the ends plus
    # 2 pi per crossing of Arg's branch cut (accepted segments here, bisected ones in _Walk.bisect)
    lower = np.signbit(q.imag)
    cut = np.where(good, _cut_crossings(lower[:-1], lower[1:], turn.imag), 0).sum(axis=0)
    ends = q[_ENDS]
    total = np.angle(ends[0]) - np.angle(ends[1]) + (2.0 * np.pi) * cut
    rejected = None
    if not good.all():
        j, line = np.nonzero(~good)
        rejected = (line, w[j, line], q[j, line], q[j + 1, line], k1[j, line], k2[j, line])
    return total, failed, ends, rejected


def _cut_crossings(
    lower_a: NDArray[np.bool_], lower_b: NDArray[np.bool_], turn_imag: NDArray[np.float64]
) -> NDArray[np.int64]:
    """+1 / -1 where a segment of q's path crosses Arg's branch cut (the negative reals) counterclockwise / clockwise.

    For a segment whose change of arg q lies in (-pi, pi) (every segment the chord test
    accepts) the change is Arg(q_b) - Arg(q_a) + 2 pi times this; counterclockwise
    (Im(q_b conj(q_a)) > 0) from Im q >= 0 to Im q < 0 passes the negative reals, and the
    reverse. ``lower``: the sign bit of Im q, the branch NumPy's Arg follows for -0.0.
    """
    ccw = turn_imag > 0.0
    return (~lower_a & lower_b & ccw).astype(np.int64) - (lower_a & ~lower_b & (turn_imag < 0.0))


def _count_few(rows: _Rows, c: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`_count_rows` for a few rows: per-row constants and the tails in plain Python.

    The same walk (4 x the initial samples, chord test, Cauchy radius, tails) with only
    the samples along the lines in NumPy; rows whose walk needs a bisection are handed
    to :func:`_count_rows`.
    """
    P, D = rows.P, rows.D
    m = 4 * _INITIAL_SAMPLES
    n = c.size
    Ps = P.tolist() if isinstance(P, np.ndarray) else [P] * n
    Ds = D.tolist() if isinstance(D, np.ndarray) else [D] * n
    consts, cplx = [], []
    try:
        for lam, t1, t2, real, ci, P, D in zip(rows.lam.tolist(), rows.t1.tolist(), rows.t2.tolist(),
                                               rows.real.tolist(), c.tolist(), Ps, Ds):  # fmt: skip
            x1, x2 = math.exp(-t1 * ci), math.exp(-t2 * ci)
            al = abs(lam)
            E1, E2 = al * P * x1, al * D * x2
            b1 = D + E2
            omega = (b1 + math.sqrt(b1 * b1 + 4.0 * (P + E1))) / 2.0 * (1.0 + 1e-9) + 1e-12
            lo = 0.0 if real else -omega
            h = (omega - lo) / (m - 1)
            consts.append((ci, lo, h, t2 * t2 * E2, 2.0 + t1 * t1 * E1 + 2.0 * t2 * E2, 0.125 * h * h, omega))
            cplx.append((lam * (P * x1), lam * (D * x2), -1j * t1, -1j * t2))
    except OverflowError:  # a line far left of long delays: the general walk refuses it
        return _count_rows(rows, c)
    cc, lo, h, m2_slope, m2_offset, h2, omega = np.array(consts).T
    A1, B1, i1, i2 = np.array(cplx).T
    P, D = rows.P, rows.D
    w = lo + h * _sample_index(m)
    sv = cc + 1j * w
    k1, k2 = np.exp(i1 * w), np.exp(i2 * w)
    q = sv * (sv + D - B1 * k2) + (P - A1 * k1)
    abs_s = np.abs(sv)
    quad = (m2_slope * np.maximum(abs_s[:-1], abs_s[1:]) + m2_offset) * h2
    good, turn = _chord_ok(q[:-1], q[1:], quad * quad)
    if good.all():
        total = np.arctan2(turn.imag, turn.real).sum(axis=0)
        failed = None
    else:  # the rejected segments' change: Arg at their ends here, their crossings in bisect
        arg = np.angle(q)
        total = np.where(good, np.arctan2(turn.imag, turn.real), arg[1:] - arg[:-1]).sum(axis=0)
        failed = ~np.isfinite(q.sum(axis=0))
        j, line = np.nonzero(~good)
        _Walk(cc, rows.t1, rows.t2, A1, B1, m2_slope, m2_offset, P, D).bisect(
            total, failed, line, w[j, line], q[j, line], q[j + 1, line], k1[j, line], k2[j, line], h, 4096
        )
    counts = np.full(n, np.nan)
    for i, (tot, q_top, q_bot, real, (ci, _, _, _, _, _, om), P, D) in enumerate(
        zip(total.tolist(), q[-1].tolist(), q[0].tolist(), rows.real.tolist(), consts, Ps, Ds)
    ):
        # tails beyond +-Omega: arg q = arg g1 + Arg(q / g1), g1 = s^2 + D s + P (Rouche)
        z1, z2 = _free_roots(P, D).tolist()
        e = complex(ci, om)
        top = math.pi - cmath.phase(e - z1) - cmath.phase(e - z2) - cmath.phase(q_top / ((e + D) * e + P))
        if real:
            delta = 2.0 * (tot + top)
        else:
            e = complex(ci, -om)
            bottom = math.pi + cmath.phase(e - z1) + cmath.phase(e - z2) + cmath.phase(q_bot / ((e + D) * e + P))
            delta = tot + top + bottom
        count = 1.0 - delta / (2.0 * math.pi)
        if math.isfinite(count) and abs(count - round(count)) < 0.1 and (failed is None or not failed[i]):
            counts[i] = round(count)
    return counts


@lru_cache(maxsize=8)
def _sample_index(m: int) -> NDArray[np.float64]:
    """0, 1, ..., m - 1 as a column (read-only): the sample positions of a walk."""
    j = np.arange(m, dtype=np.float64)[:, None]
    j.flags.writeable = False
    return j


@lru_cache(maxsize=64)
def _free_roots(P: float, D: float) -> NDArray[np.complex128]:
    """The roots of g1 = s^2 + D s + P (the tails' comparison polynomial), read-only."""
    z = _delay_free(0.0, P, D)
    z.flags.writeable = False
    return z
