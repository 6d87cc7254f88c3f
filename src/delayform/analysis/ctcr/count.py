"""The CTCR count NU(tau1, tau2) from the curves: horizontal paths, exact crossings, axes, zero lines."""

from __future__ import annotations


import numpy as np
from numpy.typing import NDArray

from delayform.analysis.ctcr.phase import CHORD_TOL, _deriv, _horner
from delayform.analysis.ctcr.curves import CrossingCurve, _ZeroLine
from delayform.analysis.ctcr.degenerate import crossing_changes
from delayform.characteristic import TwoDelayQuasiPolynomial

#: |det| of the crossing's Newton Jacobian below this fraction of its columns' product: singular.
_SINGULAR = 1e-6


# ===================================================================== counting helpers
def _segment_table(curves: tuple[CrossingCurve, ...]) -> NDArray[np.float64]:
    """Rows (x0, y0, x1, y1, w RT1, source, omega0, omega1, w, at_turn) of the non-horizontal segments.

    RT1 changes sign where the curve turns in tau2 (horizontal tangent). A
    segment ending at such a vertex takes RT1 from its other end and is marked
    ``at_turn``: its crossing keeps the polyline's value, because a line just
    under the turning point meets the curve twice, close together, and an exact
    solve from either segment could find the same one of the two. w RT1 is 0
    where the ends still disagree; it is then taken at the crossing point.
    """
    rows = []
    for c in curves:
        rt1 = c.rt1.astype(np.int64)  # stored as int8
        a, b = rt1[:-1], rt1[1:]
        dy = np.diff(c.tau2)
        ext = np.zeros(c.tau2.size, bool)
        ext[1:-1] = dy[:-1] * dy[1:] < 0.0
        ea, eb = ext[:-1], ext[1:]
        rt = np.where(a == b, a, 0)
        rt = np.where(ea & ~eb, b, np.where(eb & ~ea, a, np.where(ea & eb, 0, rt)))
        src = np.full(rt.shape, float(c.source))
        w = np.full(rt.shape, float(c.weight))
        rows.append(np.column_stack([c.tau1[:-1], c.tau2[:-1], c.tau1[1:], c.tau2[1:], c.weight * rt,
                                     src, c.omega[:-1], c.omega[1:], w, (ea | eb).astype(float)]))
    if not rows:
        return np.zeros((0, 10))
    seg = np.concatenate(rows)
    return seg[seg[:, 1] != seg[:, 3]]


def _horizontal_crossings(
    seg: NDArray[np.float64], x: NDArray[np.float64], y: NDArray[np.float64],
    traced: tuple[TwoDelayQuasiPolynomial, ...], scale: float,
) -> NDArray[np.int64]:
    """Sum of w RT1 over the curves met by each horizontal path (0, y) -> (x, y).

    Crossings are found once per distinct tau2 of the queries: the polyline
    gives where each segment meets the line, then the crossing is recomputed
    exactly, solving ``q(j omega; tau1, tau2) = 0`` for (omega, tau1) by Newton's
    method, so that points close to a curve land on the right side of it.
    Queries then read a cumulative sum over the crossings sorted by tau1.
    """
    out = np.zeros(x.size, np.int64)
    if seg.shape[0] == 0 or x.size == 0:
        return out
    uy, inv = np.unique(y, return_inverse=True)
    ylo = np.minimum(seg[:, 1], seg[:, 3])
    yhi = np.maximum(seg[:, 1], seg[:, 3])
    lo = np.searchsorted(uy, ylo, "left")
    hi = np.searchsorted(uy, yhi, "left")  # half-open [ylo, yhi): shared vertices count once
    counts = hi - lo
    n_pairs = int(counts.sum())
    if n_pairs > 20_000_000 and uy.size > 1:
        # Too many (segment, line) pairs at once: split the queries by tau2.
        cut = uy[uy.size // 2]
        low = y < cut
        out[low] = _horizontal_crossings(seg, x[low], y[low], traced, scale)
        out[~low] = _horizontal_crossings(seg, x[~low], y[~low], traced, scale)
        return out
    if n_pairs == 0:
        return out
    sid = np.repeat(np.arange(seg.shape[0]), counts)
    yi = np.arange(n_pairs) - np.repeat(np.cumsum(counts) - counts, counts) + lo[sid]
    x0, y0, x1, y1, w, src, om0, om1, weight, at_turn = seg[sid].T
    yy = uy[yi]
    frac = (yy - y0) / (y1 - y0)
    # The polyline is within ~CHORD_TOL * scale of the curve in each coordinate, so the
    # crossing moves at most about that much times (1 + |dtau1/dtau2|).
    band = 8.0 * CHORD_TOL * scale * (1.0 + np.abs((x1 - x0) / (y1 - y0)))
    band[at_turn > 0] = -1.0  # keep the polyline's crossing next to a turning point
    xc = _exact_crossing(traced, src.astype(np.int64), om0 + frac * (om1 - om0), x0 + frac * (x1 - x0), yy, band)
    turn = w == 0
    if np.any(turn):
        w = w.copy()
        w[turn] = weight[turn] * _crossing_tendency(
            traced, src[turn].astype(np.int64), (om0 + frac * (om1 - om0))[turn], xc[turn], yy[turn]
        )
    keep = xc > 0.0
    yi, xc, w = yi[keep], xc[keep], w[keep]
    # Sort crossings by (line, tau1) with one composite key; queries search the same key.
    width = 2.0 * (max(float(xc.max(initial=0.0)), float(x.max())) + 1.0)
    key = yi * width + xc
    order = np.argsort(key, kind="stable")
    key = key[order]
    cum = np.concatenate([[0.0], np.cumsum(w[order])])
    first = np.searchsorted(key, inv * width, "left")
    upto = np.searchsorted(key, inv * width + x, "left")
    return np.rint(cum[upto] - cum[first]).astype(np.int64)


def _crossing_tendency(
    traced: tuple[TwoDelayQuasiPolynomial, ...], src: NDArray[np.int64], omega: NDArray[np.float64],
    tau1: NDArray[np.float64], tau2: NDArray[np.float64],
) -> NDArray[np.int64]:
    """RT1 at crossing points (segments whose ends disagree, touching or multiple roots).

    At a degenerate point the change of NU is counted beside it
    (:func:`~delayform.analysis.ctcr.degenerate.crossing_changes`); points
    left of the tau2 axis are dropped by the caller and get 0.
    """
    out = np.zeros(src.shape, np.int64)
    for k in np.unique(src):
        sel = (src == k) & (tau1 > 0.0)
        if np.any(sel):
            out[sel] = crossing_changes(traced[int(k)], omega[sel], tau1[sel], tau2[sel], delay=1)
    return out


def _exact_crossing(
    traced: tuple[TwoDelayQuasiPolynomial, ...], src: NDArray[np.int64], omega: NDArray[np.float64],
    tau1: NDArray[np.float64], tau2: NDArray[np.float64], max_move: NDArray[np.float64],
) -> NDArray[np.float64]:
    """tau1 where the curve meets tau2 = const exactly: Newton on q(j omega; tau1, tau2) = 0.

    Starts from the polyline's interpolation; where Newton does not converge,
    or moves further than ``max_move`` (it would be another crossing), the
    interpolated value is kept.
    """
    out = tau1.copy()
    for k in np.unique(src):
        sel = src == k
        qp = traced[int(k)]
        om, t1, t2 = omega[sel].copy(), tau1[sel].copy(), tau2[sel]
        for _ in range(8):
            s = 1j * om
            f = np.zeros(s.shape, complex)
            fs = np.zeros(s.shape, complex)
            f1 = np.zeros(s.shape, complex)
            scale = np.zeros(s.shape)
            for c, a, b in qp.terms():
                h = a * t1 + b * t2
                e = np.exp(-h * s)
                g = _horner(s, c)
                f += g * e
                fs += (_horner(s, _deriv(c)) - h * g) * e
                f1 -= a * s * g * e
                scale += np.abs(g)
            # Unknowns (omega, tau1): dq/domega = j dq/ds.
            fo = 1j * fs
            det = fo.real * f1.imag - f1.real * fo.imag
            with np.errstate(divide="ignore", invalid="ignore"):
                d_om = (f.real * f1.imag - f1.real * f.imag) / det
                d_t1 = (fo.real * f.imag - f.real * fo.imag) / det
            # At a touching or multiple root the two columns are parallel (or zero): the
            # crossing is then a flat zero of q and Newton drifts along it; keep the polyline.
            ok = np.isfinite(d_om) & np.isfinite(d_t1) & (np.abs(det) > _SINGULAR * np.abs(fo) * np.abs(f1))
            om = np.where(ok, om - d_om, om)
            t1 = np.where(ok, t1 - d_t1, t1)
        s = 1j * om
        res = np.abs(sum(_horner(s, c) * np.exp(-(a * t1 + b * t2) * s) for c, a, b in qp.terms()))
        good = (res <= 1e-10 * np.maximum(scale, 1e-300)) & (np.abs(t1 - tau1[sel]) <= max_move[sel])
        out[sel] = np.where(good, t1, tau1[sel])
    return out


def _axis_sum(axis: tuple[NDArray[np.float64], NDArray[np.float64]], t: NDArray[np.float64]) -> NDArray[np.int64]:
    """Sum of the NU changes of the axis crossings strictly below t (crossings sorted)."""
    where, delta = axis
    if where.size == 0:
        return np.zeros(t.shape, np.int64)
    cum = np.concatenate([[0], np.cumsum(delta)])
    return cum[np.searchsorted(where, t, "left")].astype(np.int64)


def _second_derivative_at_zero(qp: TwoDelayQuasiPolynomial, t1: NDArray, t2: NDArray) -> NDArray[np.float64]:
    """q''(0) at the given delays (real qp)."""
    out = np.zeros(np.broadcast(t1, t2).shape)
    for c, a, b in qp.terms():
        h = a * t1 + b * t2
        g0 = c[0].real
        g1 = c[1].real if c.size > 1 else 0.0
        g2 = 2.0 * c[2].real if c.size > 2 else 0.0
        out = out + g2 - 2.0 * h * g1 + h * h * g0
    return out


def _zero_line_count(line: _ZeroLine, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.int64]:
    """NU change from the real root that passes through s = 0 on the line q'(0) = 0."""
    with np.errstate(all="ignore"):  # t* is inf/nan where a path runs parallel to the line
        return _zero_line_count_raw(line, x, y)


def _zero_line_count_raw(line: _ZeroLine, x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.int64]:
    tol = 1e-12 * max(1.0, abs(line.c0), abs(line.c1), abs(line.c2))
    out = np.zeros(x.size, np.int64)

    def after_positive(px: NDArray, py: NDArray, slope: NDArray) -> NDArray[np.bool_]:
        # Just past the line q'(0) has the sign of ``slope``; the small root is -2 q'(0)/q''(0).
        q2 = _second_derivative_at_zero(line.qp, px, py)
        return (-slope / np.where(q2 == 0.0, np.nan, q2)) > 0.0

    # Path 1: origin -> (0, y) (or -> (x, 0) when y = 0).
    along1 = y == 0.0
    length = np.where(along1, x, y)
    slope1 = np.where(along1, line.c1, line.c2) * length
    if abs(line.c0) <= tol:
        on = np.abs(slope1) > tol
        pos = after_positive(np.zeros_like(x), np.zeros_like(y), slope1)
        out += np.where(on & pos, line.weight, 0)
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            t_star = -line.c0 / slope1
        hit = (t_star > 0) & (t_star < 1)
        px = np.where(along1, t_star * x, 0.0)
        py = np.where(along1, 0.0, t_star * y)
        pos = after_positive(np.nan_to_num(px), np.nan_to_num(py), slope1)
        out += np.where(hit, np.where(pos, line.weight, -line.weight), 0)
    # Path 2: (0, y) -> (x, y).
    L0 = line.c0 + line.c2 * y
    slope2 = line.c1 * x
    with np.errstate(divide="ignore", invalid="ignore"):
        t_star = -L0 / slope2
    started_on = (np.abs(L0) <= tol) & (np.abs(slope2) > tol) & ~along1
    came_along = abs(line.c2) <= tol  # then path 1 ran on the line: nothing counted before
    pos = after_positive(np.nan_to_num(t_star * x), y, slope2)
    if came_along:
        out += np.where(started_on & pos, line.weight, 0)
    else:
        out += np.where(started_on, np.where(pos, line.weight, -line.weight), 0)
    hit = (t_star > 0) & (t_star < 1) & ~started_on & ~along1 & (np.abs(slope2) > tol)
    out += np.where(hit, np.where(pos, line.weight, -line.weight), 0)
    return out


