"""Gain design: the (P, D) that make the team converge fastest at its delays, or over a box of them.

Delay scheduling (:mod:`delayform.design.scheduling`) can only add delay;
most users can change the gains instead. This module picks the gains of
the paper's eq. 1 inside bounds that minimise the **spectral abscissa**

    alpha(P, D) = max { Re s : q_i(s) = 0 for a factor q_i of the paper's eq. 3 },

the centroid factor's persistent root s = 0 (paper, eq. 4) excluded, its
other roots included: exactly the real part of the root
:func:`~delayform.analysis.roots.dominant.dominant_root` reports. The disagreement
from the formation decays like e^{alpha t}, so -alpha is the decay rate and
ln(50) / |alpha| the predicted 2 % settling time.

Method (see docs/theory.md, "Gain design")
------------------------------------------
alpha is a max of the real parts of many roots: continuous, but non-smooth
where two roots tie for rightmost, not even Lipschitz where a root is
multiple, and with many local minima. So, as HANSO and TDS-STABIL do:

1. **A coarse certified map** of the gain plane: alpha at every point of a
   grid over the bounds, every factor's rightmost root certified by the
   argument principle, all grid points of a factor in one batch
   (:mod:`delayform.analysis.roots.family.gains`).
2. **Gradient sampling** (Burke, Lewis and Overton 2005) from the best few
   local minima of the map: the gradient of alpha is that of its active root,
   d Re s / dP = Re(-(dq/dP) / (dq/ds)) by implicit differentiation of
   q(s) = 0 (likewise for D); the descent direction is minus the shortest
   vector in the convex hull of gradients sampled in a ball around the
   iterate, which points downhill across the kinks where a plain gradient
   zig-zags. The step is chosen from a batch of step lengths evaluated at
   once; the ball shrinks when no step descends. All starts run together.
3. **The certificate**: the gains finally chosen (the best of the map and of
   the local searches) are recomputed with the certified
   :func:`~delayform.analysis.roots.dominant.dominant_root`.

**Robust design** over a box of delays minimises the worst case
max_{tau in box} alpha(P, D, tau) the same way, with the max taken over a
set of delay pairs that grows (an exchange method): the box's corners, edge
midpoints and centre, then the worst pair found at the current gains by a
certified dominant-root map of the box zoomed three times around its worst
point. The result is certified stable over the *whole* box by the exact CTCR
map at the chosen gains (:func:`~delayform.analysis.ctcr.stability_map.stability_map`): no
crossing curve meets the box and NU = 0 at its centre. The worst case
reported is the worst found (a certified root, so a lower bound on the true
worst abscissa).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from delayform._display import FigureRepr  # Jupyter shows the figure
from delayform._validation import check_delay, validated
from delayform.analysis.roots.single import require_reach
from delayform.analysis.roots.dominant import SETTLING_FACTOR, dominant_root, dominant_root_map
from delayform.characteristic import CharacteristicFactor
from delayform.analysis.roots.family.gains import gain_lines, rightmost_roots, root_gradients
from delayform.errors import DelayError, GainError, InputError, NoStableGainsError
from delayform.resources import require
from delayform.topology import Topology

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes

    from delayform.analysis.ctcr.stability_map import StabilityMap

__all__ = ["GainDesign", "GainPlaneMap", "design_gains", "box_is_stable", "gain_crossing_curves"]

_Arr = NDArray[np.float64]

#: Gradient-sampling points per iterate and step lengths tried per line search.
_SAMPLES = 6
_STEPS = 12
#: Sampling radius (fraction of the bound widths) below which a local search stops.
_EPS_MIN = 1e-6
_MAX_ITER = 60
#: Rounds of the exchange method of the robust design.
_ROBUST_ROUNDS = 3
#: Points per axis of the certified dominant-root map of the box in the robust design's worst-case search.
_BOX_GRID = 11
#: Measured CPU seconds per certified factor root in a map batch (benchmarks/bench_gains.py),
#: and the search after the map: about as much again (more for the robust design's rounds).
_SECONDS_PER_ROOT = 4.5e-5
#: Bytes per factor root kept (the roots of every map point are the local search's seeds).
_BYTES_PER_ROOT = 320.0


# =====================================================================
# results
# =====================================================================
@validated()
@dataclass(frozen=True, eq=False)
class GainPlaneMap(FigureRepr):
    """The spectral abscissa over a grid of gains (P, D) at fixed delays (or a box's worst case).

    Attributes
    ----------
    P_values, D_values
        Grid axes; ``abscissa[i, j]`` is at (P_values[i], D_values[j]).
    abscissa
        Re of the dominant root (the centroid's zero excluded) at each grid
        point; for a robust design the max over the delay pairs ``delays``.
    roots
        The dominant root at each grid point (the member with Im >= 0).
    delays
        The delay pairs (tau1, tau2) the map was computed at, shape (m, 2).
    chosen
        The designed gains (P, D), marked on the plot; None when not designed.
    boundary
        At one delay pair: the exact curves of the gain plane on which a root
        is on the imaginary axis (:func:`gain_crossing_curves`), each an
        (k, 2) array of (P, D); the stable region's edge is made of them.
        Empty for a map over several delay pairs.
    """

    P_values: _Arr
    D_values: _Arr
    abscissa: _Arr
    roots: NDArray[np.complex128]
    delays: _Arr
    chosen: tuple[float, float] | None = None
    boundary: tuple[_Arr, ...] = ()

    def __repr__(self) -> str:
        P, D = self.P_values, self.D_values
        return (
            f"GainPlaneMap(P in [{P[0]:g}, {P[-1]:g}] x D in [{D[0]:g}, {D[-1]:g}], grid {P.size} x {D.size}, "
            f"{self.delays.shape[0]} delay pair(s), stable fraction {float(np.mean(self.stable)):.3f}, "
            f"chosen={self.chosen})"
        )

    @property
    def stable(self) -> NDArray[np.bool_]:
        """True where the abscissa is negative: the formation converges (Lemma 2)."""
        return self.abscissa < 0.0

    def best(self) -> tuple[float, float, float]:
        """The grid point with the smallest abscissa: (P, D, abscissa)."""
        i, j = np.unravel_index(int(np.argmin(self.abscissa)), self.abscissa.shape)
        return float(self.P_values[i]), float(self.D_values[j]), float(self.abscissa[i, j])

    def plot(self, ax: Axes | None = None, points: dict[str, tuple[float, float]] | None = None) -> Axes:
        """Contour map of the abscissa, the stable region's edge (alpha = 0) and the chosen gains.

        Parameters
        ----------
        ax
            Axes to draw on; new ones when None.
        points
            Other labelled gains (P, D) to mark, e.g. ``{"paper": (1.0, 0.5)}``.
        """
        from delayform.plots import plot_gain_plane

        return plot_gain_plane(self, ax=ax, points=points)


@validated()
@dataclass(frozen=True, eq=False)
class GainDesign(FigureRepr):
    """Gains chosen by :func:`design_gains`, with the root they reach and how it was certified.

    Attributes
    ----------
    P, D
        The designed gains, inside the bounds.
    abscissa
        Re of the dominant root at the design delays; for a robust design the
        worst case found over the box.
    root
        That dominant root (certified by the argument principle), Im >= 0.
    factor
        The factor of the paper's eq. 3 it belongs to.
    tau1, tau2
        The delays of ``root``: the design delays, or the worst pair found in the box.
    certificate
        How the result was certified, in words.
    gain_map
        The coarse gain-plane map the search started from.
    P_bounds, D_bounds
        The bounds searched.
    tau1_box, tau2_box
        The delay intervals; equal ends for a design at one delay pair.
    stability_map
        The exact CTCR map at the designed gains (robust design only).
    """

    P: float
    D: float
    abscissa: float
    root: complex
    factor: CharacteristicFactor
    tau1: float
    tau2: float
    certificate: str
    gain_map: GainPlaneMap = field(repr=False)
    P_bounds: tuple[float, float]
    D_bounds: tuple[float, float]
    tau1_box: tuple[float, float]
    tau2_box: tuple[float, float]
    stability_map: StabilityMap | None = field(default=None, repr=False)

    @property
    def is_robust(self) -> bool:
        """True when designed over a box of delays rather than one delay pair."""
        return self.tau1_box[0] < self.tau1_box[1] or self.tau2_box[0] < self.tau2_box[1]

    @property
    def decay_rate(self) -> float:
        """-abscissa (1/s): how fast the disagreement decays (negative when unstable)."""
        return -self.abscissa

    @property
    def settling_time(self) -> float:
        """Predicted 2 % settling time ln(50) / |abscissa| (inf unless stable)."""
        return SETTLING_FACTOR / -self.abscissa if self.abscissa < 0.0 else math.inf

    def plot(self, ax: Axes | None = None, points: dict[str, tuple[float, float]] | None = None) -> Axes:
        """The gain-plane map with the designed gains marked (see :meth:`GainPlaneMap.plot`).

        Parameters
        ----------
        ax
            Axes to draw on; new ones when None.
        points
            Other labelled gains (P, D) to mark.
        """
        return self.gain_map.plot(ax=ax, points=points)


# =====================================================================
# the objective: alpha over a set of delay pairs, batched over gains
# =====================================================================
class _Objective:
    """max over factors and over the delay pairs of Re(rightmost root), and its gradient in (P, D).

    Every evaluation is certified (:func:`~delayform.analysis.roots.family.gains.rightmost_roots`);
    all points of a call share one batch per factor. After :meth:`keep_seeds`
    on a grid of gains, Newton starts from the roots at the nearest grid point
    (roots move continuously with the gains) instead of a new discretization;
    the certificate still decides.
    """

    def __init__(self, topology: Topology, delays: _Arr) -> None:
        self.groups = topology.eigenvalue_groups
        self._delays = np.asarray(delays, dtype=np.float64).reshape(-1, 2)
        self.lines = 0
        self._bank: tuple[_Arr, _Arr, list[NDArray[np.complex128]]] | None = None
        self._keep = False

    @property
    def delays(self) -> _Arr:
        """The delay pairs (m, 2) the max runs over."""
        return self._delays

    @delays.setter
    def delays(self, value: _Arr) -> None:
        self._delays = np.asarray(value, dtype=np.float64).reshape(-1, 2)
        self._bank = None  # seeds were for the old pairs

    def keep_seeds(self, P_axis: _Arr, D_axis: _Arr) -> tuple[_Arr, _Arr, NDArray[np.complex128], NDArray[np.int64]]:
        """Evaluate on the grid P_axis x D_axis and keep every line's roots as seeds for later calls."""
        PP, DD = np.meshgrid(P_axis, D_axis, indexing="ij")
        self._keep = True
        try:
            out = self(np.column_stack([PP.ravel(), DD.ravel()]))
        finally:
            self._keep = False
        return out

    def _seeds(self, X: _Arr) -> list[NDArray[np.complex128] | None]:
        if self._bank is None:
            return [None] * len(self.groups)
        P_axis, D_axis, found = self._bank
        i = np.clip(np.rint((X[:, 0] - P_axis[0]) / (P_axis[-1] - P_axis[0]) * (P_axis.size - 1)), 0, P_axis.size - 1)
        j = np.clip(np.rint((X[:, 1] - D_axis[0]) / (D_axis[-1] - D_axis[0]) * (D_axis.size - 1)), 0, D_axis.size - 1)
        m = self._delays.shape[0]
        rows = ((i.astype(int) * D_axis.size + j.astype(int))[:, None] * m + np.arange(m)).ravel()
        return [f[rows] for f in found]

    def __call__(self, X: _Arr) -> tuple[_Arr, _Arr, NDArray[np.complex128], NDArray[np.int64]]:
        """Values (n,), gradients (n, 2), active roots (n,) and active delay index (n,) at gains X (n, 2)."""
        X = np.asarray(X, dtype=np.float64).reshape(-1, 2)
        n, m = X.shape[0], self._delays.shape[0]
        L = gain_lines(X[:, 0, None], X[:, 1, None], self._delays[None, :, 0], self._delays[None, :, 1])
        results = [rightmost_roots(g, L, s) for g, s in zip(self.groups, self._seeds(X), strict=True)]
        if self._keep:
            self._bank = (np.unique(X[:, 0]), np.unique(X[:, 1]), [r[1] for r in results])
        per = np.stack([r[0] for r in results])  # (G, n*m)
        self.lines += L.size * len(self.groups)
        k = np.argmax(per.real, axis=0)
        root = per[k, np.arange(L.size)].reshape(n, m)
        j = np.argmax(root.real, axis=1)
        top = root[np.arange(n), j]
        flat = np.arange(n) * m + j
        kk = k[flat]
        grads = np.zeros((n, 2))
        for g in np.unique(kk):
            sel = np.flatnonzero(kk == g)
            dP, dD, _, _ = root_gradients(complex(self.groups[g].lam), L.take(flat[sel]), top[sel])
            grads[sel, 0], grads[sel, 1] = dP, dD
        return top.real.copy(), grads, top, j


# =====================================================================
# gradient sampling, all starts at once
# =====================================================================
def _min_norm_in_hull(G: _Arr) -> _Arr:
    """The shortest vector in the convex hull of the rows of G (a small QP, by NNLS)."""
    from scipy.optimize import nnls

    G = G[np.all(np.isfinite(G), axis=1)]
    if G.shape[0] == 0:
        return np.zeros(2)
    scale = max(1.0, float(np.abs(G).max()))
    # min ||G^T w|| with sum w = 1, w >= 0: the sum row weighted heavily (Lawson and Hanson)
    A = np.vstack([G.T / scale, 1e3 * np.ones(G.shape[0])])
    w, _ = nnls(A, np.concatenate([np.zeros(2), [1e3]]), maxiter=200)
    w = w / w.sum() if w.sum() > 0 else np.full(G.shape[0], 1.0 / G.shape[0])
    return w @ G


def _gradient_sampling(
    obj: _Objective, starts: _Arr, lo: _Arr, hi: _Arr, eps0: float, rng: np.random.Generator
) -> tuple[_Arr, _Arr]:
    """Local minima of obj from every start (gradient sampling, box-constrained; batched)."""
    width = hi - lo
    X = starts.copy()
    F, Gx, _, _ = obj(X)
    eps = np.full(X.shape[0], eps0)
    active = np.ones(X.shape[0], dtype=bool)
    for it in range(_MAX_ITER):
        if it >= 8:  # a start far behind the best by now is in a worse basin: stop spending on it
            active &= F <= F.min() + 0.02
        act = np.flatnonzero(active)
        if act.size == 0:
            break
        # sample the ball of radius eps (in units of the bound widths) around each iterate
        u = rng.normal(size=(act.size, _SAMPLES, 2))
        u *= (rng.uniform(size=(act.size, _SAMPLES, 1)) ** 0.5) / np.linalg.norm(u, axis=2, keepdims=True)
        pts = np.clip(X[act, None, :] + eps[act, None, None] * u * width, lo, hi)
        _, Gs, _, _ = obj(pts.reshape(-1, 2))
        Gs = Gs.reshape(act.size, _SAMPLES, 2)
        dirs = np.zeros((act.size, 2))
        for r, i in enumerate(act):
            g = _min_norm_in_hull(np.vstack([Gx[i], Gs[r]]) * width)  # scaled to the box
            d = -g * width
            at_lo, at_hi = X[i] <= lo + 1e-12 * width, X[i] >= hi - 1e-12 * width
            d[(at_lo & (d < 0)) | (at_hi & (d > 0))] = 0.0
            dirs[r] = d
        norms = np.linalg.norm(dirs / width, axis=1)
        flat = norms <= 1e-9
        moving = act[~flat]
        # a batch of step lengths along each direction, all evaluated at once
        if moving.size:
            unit = dirs[~flat] / norms[~flat, None]
            steps = 0.5 ** np.arange(_STEPS) * 0.25
            cand = np.clip(X[moving, None, :] + steps[None, :, None] * unit[:, None, :], lo, hi)
            Fc, Gc, _, _ = obj(cand.reshape(-1, 2))
            Fc, Gc = Fc.reshape(moving.size, _STEPS), Gc.reshape(moving.size, _STEPS, 2)
            best = np.argmin(Fc, axis=1)
            fb = Fc[np.arange(moving.size), best]
            gain = F[moving] - fb
            need = 1e-4 * steps[best] * norms[~flat]  # Armijo
            ok = gain > need
            take = moving[ok]
            X[take] = cand[ok, best[ok]]
            F[take] = fb[ok]
            Gx[take] = Gc[ok, best[ok]]
            stuck = moving[~ok]
        else:
            stuck = moving
        shrink = np.concatenate([act[flat], stuck])
        eps[shrink] *= 0.1
        active &= eps >= _EPS_MIN
    return X, F


# =====================================================================
# checks
# =====================================================================
def _interval(name: str, value: object, *, check: Any, error: type[InputError]) -> tuple[float, float]:
    """A number (a degenerate interval) or a pair (lo, hi) with lo <= hi."""
    if isinstance(value, (tuple, list, np.ndarray)):
        if len(value) != 2:
            raise error(f"{name} must be a number or a pair (lo, hi), got {value!r}")
        lo, hi = check(f"{name}[0]", value[0]), check(f"{name}[1]", value[1])
        if lo > hi:
            raise error(f"{name} must have lo <= hi, got ({lo:g}, {hi:g})")
        return lo, hi
    x = check(name, value)
    return x, x


def _bounds(name: str, value: object) -> tuple[float, float]:
    def positive(label: str, v: object) -> float:
        from delayform._validation import check_gain

        return check_gain(label, v)

    lo, hi = _interval(name, value, check=positive, error=GainError)
    if not lo < hi:
        raise GainError(f"{name} must be a pair (lo, hi) with 0 < lo < hi, got ({lo:g}, {hi:g})")
    return lo, hi


def _count(name: str, value: object, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


@validated()
def box_is_stable(smap: StabilityMap, tau1_box: tuple[float, float], tau2_box: tuple[float, float]) -> bool:
    """True when the exact CTCR map shows the whole delay box stable.

    A root can only cross the imaginary axis on a kernel or offspring curve,
    so a box that no curve meets has the same NU everywhere; NU = 0 at its
    centre then proves every delay pair in it stable. A curve is taken to meet
    the box when its polyline (vertices exactly on the curve, chords within the
    map's sampling tolerance of it) passes within four times that tolerance of
    the box. No sampling of the box is involved.

    Parameters
    ----------
    smap
        The map (from :func:`~delayform.analysis.ctcr.stability_map.stability_map`); its
        window must contain the box.
    tau1_box, tau2_box
        The intervals (lo, hi) of the box.

    Returns
    -------
    bool
    """
    from delayform.analysis.ctcr.phase import CHORD_TOL

    (a0, a1), (b0, b1) = tau1_box, tau2_box
    if a1 > smap.tau1_max or b1 > smap.tau2_max:
        raise DelayError("the box must lie inside the map's window")
    margin = 4.0 * CHORD_TOL * max(smap.tau1_max, smap.tau2_max)
    x0, x1, y0, y1 = a0 - margin, a1 + margin, b0 - margin, b1 + margin
    for c in smap.curves:
        if _polyline_meets_box(c.tau1, c.tau2, (x0, x1, y0, y1)):
            return False
    return bool(smap.is_stable(0.5 * (a0 + a1), 0.5 * (b0 + b1)))


def _polyline_meets_box(x: _Arr, y: _Arr, box: tuple[float, float, float, float]) -> bool:
    """Whether any segment of the polyline meets the closed rectangle (Liang-Barsky clipping)."""
    x0, x1, y0, y1 = box
    if x.size == 1:
        return bool(x0 <= x[0] <= x1 and y0 <= y[0] <= y1)
    px, py = x[:-1], y[:-1]
    dx, dy = np.diff(x), np.diff(y)
    t_lo = np.zeros(px.size)
    t_hi = np.ones(px.size)
    ok = np.ones(px.size, dtype=bool)
    for p, q in ((-dx, px - x0), (dx, x1 - px), (-dy, py - y0), (dy, y1 - py)):
        parallel = p == 0.0
        ok &= ~(parallel & (q < 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            r = q / p
        t_lo = np.where(~parallel & (p < 0.0), np.maximum(t_lo, r), t_lo)
        t_hi = np.where(~parallel & (p > 0.0), np.minimum(t_hi, r), t_hi)
    return bool(np.any(ok & (t_lo <= t_hi)))


# =====================================================================
# the exact stability boundary in the gain plane (D-decomposition)
# =====================================================================
@validated()
def gain_crossing_curves(
    topology: Topology, tau1: float, tau2: float, *, P_bounds: tuple[float, float],
    D_bounds: tuple[float, float], samples: int = 4000,
) -> tuple[_Arr, ...]:
    """The curves of the gain plane on which a characteristic root is on the imaginary axis.

    The gain-plane analogue of the CTCR kernel and offspring curves
    (D-decomposition, Neimark): every factor of the paper's eq. 3 is linear in
    the gains, ``q(j w) = -w^2 + P a(w) + D b(w)`` with
    ``a = 1 - lam e^{-j w tau1}`` and ``b = j w (1 - lam e^{-j w tau2})``,
    so ``q(j w) = 0`` has, for each frequency w, the single real solution
    ``P = w^2 Im b / det``, ``D = -w^2 Im a / det``
    (``det = Re a Im b - Re b Im a``). Roots change sides of the imaginary axis
    only where (P, D) crosses one of these curves, so the stable region's
    edge is made of them. Frequencies run up to the bound
    ``|w| <= D_max (1 + |lam|) + sqrt(P_max (1 + |lam|))`` of imaginary
    roots; negative ones too for a complex lam (its roots do not pair up).
    The vertices lie exactly on the curves; the polylines join them.

    Parameters
    ----------
    topology
        Communication topology with a spanning tree.
    tau1, tau2
        Non-negative delays (s).
    P_bounds, D_bounds
        The part of the gain plane wanted, (lo, hi) each.
    samples
        Frequencies per factor and sign.

    Returns
    -------
    tuple of ndarray
        Polylines, each (k, 2) of (P, D), clipped to the bounds.
    """
    t1, t2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    pb, db = _bounds("P_bounds", P_bounds), _bounds("D_bounds", D_bounds)
    samples = _count("samples", samples, 16)
    span = np.array([pb[1] - pb[0], db[1] - db[0]])
    out: list[_Arr] = []
    for group in topology.eigenvalue_groups:
        lam = complex(group.lam)
        top = db[1] * (1 + abs(lam)) + math.sqrt(pb[1] * (1 + abs(lam)))
        signs = (1.0,) if lam.imag == 0.0 else (1.0, -1.0)
        for sign in signs:
            w = sign * np.linspace(top / samples, top, samples)
            a = 1.0 - lam * np.exp(-1j * w * t1)
            b = 1j * w * (1.0 - lam * np.exp(-1j * w * t2))
            det = a.real * b.imag - b.real * a.imag
            with np.errstate(divide="ignore", invalid="ignore"):
                pts = np.column_stack([w * w * b.imag / det, -w * w * a.imag / det])
            inside = np.all(np.isfinite(pts), axis=1) & (pts[:, 0] >= pb[0]) & (pts[:, 0] <= pb[1]) \
                & (pts[:, 1] >= db[0]) & (pts[:, 1] <= db[1])
            jump = np.ones(w.size, dtype=bool)
            with np.errstate(invalid="ignore"):  # inf - inf next to a vanishing det: a gap anyway
                jump[1:] = np.any(np.abs(np.diff(pts, axis=0)) > 0.05 * span, axis=1)
            run = np.cumsum(~inside | jump)  # a new piece after every gap or jump
            for r in np.unique(run[inside]):
                piece = pts[inside & (run == r)]
                if piece.shape[0] >= 2:
                    out.append(piece)
    return tuple(out)


# =====================================================================
# the design
# =====================================================================
def _coarse_map(obj: _Objective, P_axis: _Arr, D_axis: _Arr) -> GainPlaneMap:
    F, _, roots, _ = obj.keep_seeds(P_axis, D_axis)
    shape = (P_axis.size, D_axis.size)
    return GainPlaneMap(P_axis, D_axis, F.reshape(shape), roots.reshape(shape), obj.delays.copy())


def _starts(gmap: GainPlaneMap, count: int) -> _Arr:
    """The ``count`` lowest local minima of the map (8-neighbourhood), lowest first."""
    A = gmap.abscissa
    pad = np.pad(A, 1, constant_values=np.inf)
    is_min = np.ones(A.shape, dtype=bool)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:
                is_min &= A <= pad[1 + di : 1 + di + A.shape[0], 1 + dj : 1 + dj + A.shape[1]]
    idx = np.flatnonzero(is_min.ravel())
    idx = idx[np.argsort(A.ravel()[idx])][:count]
    i, j = np.unravel_index(idx, A.shape)
    return np.column_stack([gmap.P_values[i], gmap.D_values[j]])


def _local_search(obj: _Objective, starts: _Arr, lo: _Arr, hi: _Arr, grid: int, seed: int) -> tuple[_Arr, float]:
    X, F = _gradient_sampling(obj, starts, lo, hi, 1.0 / (grid - 1), np.random.default_rng(seed))
    k = int(np.argmin(F))
    return X[k], float(F[k])


def _box_samples(box1: tuple[float, float], box2: tuple[float, float]) -> _Arr:
    a = np.unique(np.linspace(box1[0], box1[1], 3))
    b = np.unique(np.linspace(box2[0], box2[1], 3))
    A, B = np.meshgrid(a, b, indexing="ij")
    return np.column_stack([A.ravel(), B.ravel()])


def _worst_in_box(
    topology: Topology, P: float, D: float, box1: tuple[float, float], box2: tuple[float, float], grid: int
) -> tuple[float, float]:
    """The delay pair of the box with the rightmost dominant root found: a certified map, zoomed 3 times."""
    ax1 = np.unique(np.linspace(box1[0], box1[1], grid))
    ax2 = np.unique(np.linspace(box2[0], box2[1], grid))
    dmap = dominant_root_map(topology, P, D, ax1, ax2)
    i, j = np.unravel_index(int(np.argmax(dmap.real)), dmap.real.shape)
    t = np.array([ax1[i], ax2[j]])
    h = np.array([ax1[1] - ax1[0] if ax1.size > 1 else 0.0, ax2[1] - ax2[0] if ax2.size > 1 else 0.0])
    obj = _Objective(topology, np.zeros((1, 2)))
    for _ in range(3):
        g1 = np.clip(t[0] + np.linspace(-h[0], h[0], 7), *box1)
        g2 = np.clip(t[1] + np.linspace(-h[1], h[1], 7), *box2)
        A, B = np.meshgrid(g1, g2, indexing="ij")
        obj.delays = np.column_stack([A.ravel(), B.ravel()])
        _, _, _, j_best = obj(np.array([[P, D]]))
        t = obj.delays[j_best[0]]
        h = h / 3.0
    return float(t[0]), float(t[1])


@validated()
def design_gains(
    topology: Topology,
    tau1: float | tuple[float, float],
    tau2: float | tuple[float, float],
    *,
    P_bounds: tuple[float, float],
    D_bounds: tuple[float, float],
    grid: int = 21,
    starts: int = 4,
    seed: int = 0,
) -> GainDesign:
    """The gains (P, D) within bounds that make the formation converge fastest (smallest abscissa).

    At one delay pair, minimises the real part of the dominant root
    (:func:`~delayform.analysis.roots.dominant.dominant_root`: every factor of
    the paper's eq. 3, the centroid's persistent zero of the paper's eq. 4 excluded).
    Over a box of delays (``tau1`` and/or ``tau2`` given as an interval),
    minimises its worst case over the box and certifies the result stable on
    the whole box with the exact CTCR map. Method: module docstring and
    docs/theory.md.

    Parameters
    ----------
    topology
        Communication topology with a spanning tree.
    tau1, tau2
        Non-negative delays (s), or intervals (lo, hi) for a robust design.
    P_bounds, D_bounds
        Intervals (lo, hi), 0 < lo < hi, the gains may take.
    grid
        Points per axis of the coarse gain-plane map (>= 3); the robust
        design evaluates it at 9 delay pairs of the box.
    starts
        Local minima of the map refined by gradient sampling (>= 1).
    seed
        Seed of the gradient sampling's random points.

    Returns
    -------
    GainDesign

    Raises
    ------
    NoStableGainsError
        When no gains in the bounds make the team converge (at every delay pair of the box).
    DelayError
        Also for delays whose certified roots at the largest gains would need a
        discretization beyond the machine's memory or time budget.
    GainError, InputError
        For bad bounds, delays, grid or starts.
    ResourceLimitError
        When the map would need more memory or time than this machine allows
        (:mod:`delayform.resources`), refused up front with the estimate.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> g = design_gains(paper_six(), 1.0, 2.0, P_bounds=(0.05, 3), D_bounds=(0.05, 3), grid=9, starts=1)
    >>> g.abscissa < -0.1  # point c is unstable with P = 1, D = 0.5; these gains converge
    True
    """
    if not isinstance(topology, Topology):
        raise InputError(f"topology must be a Topology, got {type(topology).__name__}")
    topology.require_spanning_tree()
    box1 = _interval("tau1", tau1, check=check_delay, error=DelayError)
    box2 = _interval("tau2", tau2, check=check_delay, error=DelayError)
    pb, db = _bounds("P_bounds", P_bounds), _bounds("D_bounds", D_bounds)
    grid = _count("grid", grid, 3)
    starts = _count("starts", starts, 1)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise InputError(f"seed must be an integer, got {seed!r}")
    lo, hi = np.array([pb[0], db[0]]), np.array([pb[1], db[1]])
    robust = box1[0] < box1[1] or box2[0] < box2[1]
    if robust and box1[0] == 0.0:
        raise DelayError(
            "a delay box reaching tau1 = 0 has no worst-case decay rate to optimise: the centroid factor's "
            "root -P tau1 / (1 + D tau2) (paper, eq. 4) tends to 0 as tau1 -> 0 for every gain; start the box "
            "at tau1 > 0"
        )
    delays = _box_samples(box1, box2) if robust else np.array([[box1[0], box2[0]]])
    for group in topology.eigenvalue_groups:  # the largest gains and delays bound the roots' reach
        require_reach(CharacteristicFactor(group, pb[1], db[1]), box1[1], box2[1])
    need = float(grid * grid * delays.shape[0] * len(topology.eigenvalue_groups))
    require(
        what=(f"gain design with a {grid} x {grid} gain-plane map at {delays.shape[0]} delay pair(s) "
              f"and {len(topology.eigenvalue_groups)} factors"),
        setting="grid (--grid)",
        nbytes=need * _BYTES_PER_ROOT,
        seconds=need * _SECONDS_PER_ROOT * (4.0 if robust else 2.0),
    )  # fmt: skip
    obj = _Objective(topology, delays)
    gmap = _coarse_map(obj, np.linspace(pb[0], pb[1], grid), np.linspace(db[0], db[1], grid))
    x, fx = _local_search(obj, _starts(gmap, starts), lo, hi, grid, int(seed))
    Pg, Dg, fg = gmap.best()
    if fg < fx:  # the search is local; never worse than the certified map
        x, fx = np.array([Pg, Dg]), fg
    if not robust:
        dom = dominant_root(topology, float(x[0]), float(x[1]), box1[0], box2[0])
        if dom.stability_root.real > fg:  # cannot happen (both certified); never return worse than the map's best
            x = np.array([Pg, Dg])
            dom = dominant_root(topology, Pg, Dg, box1[0], box2[0])
        if not dom.is_stable:
            raise NoStableGainsError(
                f"no gains in P in [{pb[0]:g}, {pb[1]:g}], D in [{db[0]:g}, {db[1]:g}] make the team "
                f"converge at (tau1, tau2) = ({box1[0]:g}, {box2[0]:g}) s (best Re = {dom.stability_root.real:.4g})"
            )
        return GainDesign(
            float(x[0]), float(x[1]), float(dom.stability_root.real), complex(dom.stability_root), dom.factor,
            box1[0], box2[0],
            "dominant root certified by the argument principle (no root of any factor right of it)",
            _marked(gmap, x, gain_crossing_curves(topology, box1[0], box2[0], P_bounds=pb, D_bounds=db)),
            pb, db, box1, box2,
        )  # fmt: skip
    return _robust(topology, obj, gmap, x, lo, hi, box1, box2, grid, int(seed))


def _marked(gmap: GainPlaneMap, x: _Arr, boundary: tuple[_Arr, ...] = ()) -> GainPlaneMap:
    return GainPlaneMap(gmap.P_values, gmap.D_values, gmap.abscissa, gmap.roots, gmap.delays,
                        (float(x[0]), float(x[1])), boundary)  # fmt: skip


def _robust(
    topology: Topology, obj: _Objective, gmap: GainPlaneMap, x: _Arr, lo: _Arr, hi: _Arr,
    box1: tuple[float, float], box2: tuple[float, float], grid: int, seed: int,
) -> GainDesign:
    """The exchange method: add the box's worst delay pair at the current gains, search again."""
    from delayform.analysis.ctcr.stability_map import stability_map

    pb, db = (float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1]))
    worst = _worst_in_box(topology, float(x[0]), float(x[1]), box1, box2, _BOX_GRID)
    for _ in range(_ROBUST_ROUNDS):
        at_worst = float(_Objective(topology, np.array([worst]))(x[None, :])[0][0])
        if at_worst <= float(obj(x[None, :])[0][0]) + 1e-6:
            break  # the sampled pairs already hold the box's worst case
        obj.delays = np.vstack([obj.delays, worst])
        x, _ = _local_search(obj, np.vstack([x, _starts(gmap, 1)]), lo, hi, grid, seed)
        worst = _worst_in_box(topology, float(x[0]), float(x[1]), box1, box2, _BOX_GRID)
    t1w, t2w = worst
    dom = dominant_root(topology, float(x[0]), float(x[1]), t1w, t2w)
    where = f"tau1 in [{box1[0]:g}, {box1[1]:g}], tau2 in [{box2[0]:g}, {box2[1]:g}] s"
    if not dom.is_stable:
        raise NoStableGainsError(
            f"no gains in P in [{pb[0]:g}, {pb[1]:g}], D in [{db[0]:g}, {db[1]:g}] found that keep the team "
            f"stable over {where} (best worst case Re = {dom.stability_root.real:.4g} at ({t1w:g}, {t2w:g}))"
        )
    smap = stability_map(topology, float(x[0]), float(x[1]), 1.05 * box1[1] + 0.1, 1.05 * box2[1] + 0.1)
    if not box_is_stable(smap, box1, box2):
        raise NoStableGainsError(
            f"the gains P = {x[0]:.4g}, D = {x[1]:.4g} are stable at every delay pair sampled in {where}, "
            "but a crossing curve of the exact CTCR map meets the box (or passes within the map's tolerance "
            "of it): not certified"
        )
    return GainDesign(
        float(x[0]), float(x[1]), float(dom.stability_root.real), complex(dom.stability_root), dom.factor, t1w, t2w,
        f"stable on the whole box {where} by the exact CTCR map (no crossing curve meets the box, "
        f"NU = 0 at its centre); worst case from a certified {_BOX_GRID} x {_BOX_GRID} dominant-root map of the box "
        "zoomed 3 times (a lower bound on the true worst case)",
        _marked(gmap, x), pb, db, box1, box2, smap,
    )  # fmt: skip
