"""The eigenvalue plane: which eigenvalues of C are stable at fixed gains and delays.

Every factor of the paper's eq. 3 is the same quasi-polynomial in s with the
eigenvalue lam of C as a parameter (a conjugate pair gives the product of the
factors of lam and conj(lam), so the complex second-order form is used):

    q(s, lam) = a(s) - lam b(s),   a(s) = s^2 + D s + P,   b(s) = D s e^{-tau2 s} + P e^{-tau1 s}.

For fixed (P, D, tau1, tau2), q(j omega, lam) = 0 exactly when
``lam = L(j omega) := a(j omega) / b(j omega)``. The roots of q cross the
imaginary axis only when lam crosses the *boundary curve* ``L(j omega)``,
omega real (both signs: lam is complex); ``L(-j omega) = conj L(j omega)``.
NU(lam), the number of roots with Re s > 0, is constant on each component of
the complement of the curve and NU(0) = 0 (``s^2 + D s + P`` is stable).

How NU(lam) is counted (signed crossings of the segment from 0 to lam)
----------------------------------------------------------------------
When lam moves across the curve at ``L(j omega0)`` in the direction d, one root
crosses at ``s = j omega0`` with ``ds = d / L'(j omega0)``; with the tangent
``T = dL(j omega)/d omega = j L'(j omega)`` this gives
``sign Re ds = sign Im(conj(d) T)``. Moving outward along the segment from 0
to lam (d = lam / |lam|) and writing ``L(j omega) = rho e^{j theta}``, the sign is
``sign d theta / d omega``. Hence

    NU(lam) = sum over omega with theta(omega) = arg lam (mod 2 pi) and rho(omega) < |lam|
              of sign theta'(omega),

the omega < 0 half being the omega > 0 half of conj(lam). The curve is sampled
adaptively in omega > 0 (phase steps below 0.25 rad, log-modulus steps below
0.25, midpoints within 1e-3 of the chord) up to the frequency beyond which
``|L| > |lam|`` for every queried lam (``|a(j w)| >= w^2 - P`` and
``|b(j w)| <= P + D w``). On each sample interval the *net* signed number of
solutions of ``theta = target`` is exact (it only depends on theta at the
interval ends); each crossing is polished by safeguarded Newton on
``theta(omega) - target`` and kept when ``rho < |lam|``. The count is therefore
exact except for lam within the curve's sampling deviation of the boundary
(where two crossings of one interval would straddle |lam|).

The centroid eigenvalue
-----------------------
``L(0) = 1``: lam = 1 is always on the boundary, with the root s = 0 of
the paper's eq. 4. As elsewhere in the package that root is not counted: NU(1) is
the count of the other roots, which equals ``NU(1 - eps)`` (for tau1 > 0 the
small root is ``s ~ (lam - 1) / tau1``). Eigenvalues within
:data:`CENTROID_TOL` of 1 are taken as the centroid eigenvalue. For real
``lam > 1`` one real root is unstable (q(0) < 0 < q(+inf)): the crossing at
omega = 0 adds 1.

References
----------
Cepeda-Gomez and Perico, Lemma 1 (paper, eq. 3), the paper's eq. 4, Lemma 2.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._display import FigureRepr  # Jupyter shows the figure
from delayform._validation import check_complex_array, check_delay, check_gains, validated
from delayform.analysis.plane.boundary_curve import ab_terms, omega_limit
from delayform.errors import InputError, ResourceLimitError
from delayform.topology import Topology

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes

__all__ = [
    "CENTROID_TOL",
    "LambdaRegion",
    "lambda_region",
]

#: Eigenvalues closer than this to 1 are the centroid eigenvalue (paper, eq. 4).
CENTROID_TOL = 1e-9
#: Largest |lam| accepted (eigenvalues of C lie in the unit disc; the curve's samples grow like |lam| tau).
MAX_MODULUS = 1e4
_PHASE_STEP = 0.25
_LOGRHO_STEP = 0.25
_CHORD_TOL = 1e-3
_MAX_ROUNDS = 40
_NEWTON_STEPS = 40
#: Most samples of the boundary curve (the phase turns about omega_max * max(tau) radians); at
#: this many the adaptive sampling takes seconds, past it minutes (2.7 million: 47 s, shared machine)
MAX_SAMPLES = 1_000_000


# ===================================================================== the curve L(j omega)
@dataclass(frozen=True)
class _Curve:
    """Samples of L(j omega) for 0 <= omega <= omega_max: phase unwrapped, log-modulus."""

    omega: NDArray[np.float64]
    theta: NDArray[np.float64]
    logrho: NDArray[np.float64]
    radius: float


def _phase_and_modulus(P: float, D: float, t1: float, t2: float, w: NDArray) -> tuple[NDArray, NDArray]:
    a, b, _, _ = ab_terms(P, D, t1, t2, w)
    with np.errstate(divide="ignore"):
        return np.angle(a) - np.angle(b), np.log(np.abs(a)) - np.log(np.abs(b))


def _sample_curve(P: float, D: float, t1: float, t2: float, radius: float) -> _Curve:
    """Adaptive samples of the boundary curve for omega in [0, omega_limit(radius)]."""
    wmax = omega_limit(P, D, radius)
    w = np.linspace(0.0, wmax, 257)
    th, lr = _phase_and_modulus(P, D, t1, t2, w)
    big = np.log(radius) + 1.0
    for _ in range(_MAX_ROUNDS):
        dth = np.angle(np.exp(1j * (th[1:] - th[:-1])))
        mid = 0.5 * (w[:-1] + w[1:])
        mth, mlr = _phase_and_modulus(P, D, t1, t2, mid)
        mth = th[:-1] + np.angle(np.exp(1j * (mth - th[:-1])))
        dev = np.hypot(mth - (th[:-1] + 0.5 * dth), np.minimum(mlr, big) - 0.5 * (np.minimum(lr[:-1], big) + np.minimum(lr[1:], big)))
        relevant = np.minimum(np.minimum(lr[:-1], lr[1:]), mlr) < big
        need = (np.abs(dth) > _PHASE_STEP) | (relevant & (np.abs(np.diff(np.minimum(lr, big))) > _LOGRHO_STEP))
        need |= relevant & (dev > _CHORD_TOL)
        need &= np.diff(w) > 1e-13 * wmax
        if not np.any(need):
            break
        w = np.concatenate([w, mid[need]])
        th = np.concatenate([th, mth[need]])
        lr = np.concatenate([lr, mlr[need]])
        order = np.argsort(w)
        w, th, lr = w[order], th[order], lr[order]
    th = np.concatenate([[0.0], th[0] + np.cumsum(np.angle(np.exp(1j * np.diff(th))))])
    return _Curve(w, th, lr, float(radius))


def _theta_at(P: float, D: float, t1: float, t2: float, w: NDArray, ref: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """theta (unwrapped next to ``ref``), d theta / d omega and log rho at omega."""
    a, b, da, db = ab_terms(P, D, t1, t2, w)
    th = np.angle(a) - np.angle(b)
    th = ref + np.angle(np.exp(1j * (th - ref)))
    dth = (da / a - db / b).real  # d/domega arg L(j omega) = Re(L'/L)
    return th, dth, np.log(np.abs(a)) - np.log(np.abs(b))


def _crossings(
    curve: _Curve, P: float, D: float, t1: float, t2: float, psi: NDArray, rad: NDArray
) -> NDArray[np.int64]:
    """Signed count, per query (psi = arg, rad = modulus), of omega > 0 with theta = psi mod 2 pi, rho < rad."""
    th, w, lr = curve.theta, curve.omega, curve.logrho
    out = np.zeros(psi.size, np.int64)
    logr = np.where(rad > 0, np.log(np.maximum(rad, 1e-300)), -np.inf)
    seg_lr = np.minimum(lr[:-1], lr[1:])
    q_idx, s_idx, targets = [], [], []
    for s0, s1 in _monotone_runs(th):
        run = th[s0 : s1 + 1]
        up = run[-1] > run[0]
        asc = run if up else run[::-1]
        for k in range(int(np.floor((asc[0] - np.pi) / (2 * np.pi))), int(np.ceil((asc[-1] + np.pi) / (2 * np.pi))) + 1):
            T = psi + 2.0 * np.pi * k
            # half-open in omega order: [theta_i, theta_i+1) upward, (theta_i+1, theta_i] downward
            if up:
                j = np.searchsorted(asc, T, "right") - 1
            else:
                j = run.size - 2 - (np.searchsorted(asc, T, "left") - 1)
            ok = (j >= 0) & (j < run.size - 1)
            qi = np.flatnonzero(ok)
            si = s0 + j[ok]
            near = seg_lr[si] < logr[qi] + 1.0
            if np.any(near):
                q_idx.append(qi[near])
                s_idx.append(si[near])
                targets.append(T[qi[near]])
    if not q_idx:
        return out
    qi = np.concatenate(q_idx)
    si = np.concatenate(s_idx)
    T = np.concatenate(targets)
    up = th[si + 1] > th[si]
    # omega = 0 is the centroid's crossing at L = 1, handled by the caller.
    keep = ~((si == 0) & (T == th[0]))
    qi, si, T, up = qi[keep], si[keep], T[keep], up[keep]
    wl, wr = w[si].copy(), w[si + 1].copy()
    fl = th[si] - T  # sign at the left end
    x = wl + (wr - wl) * np.clip((T - th[si]) / (th[si + 1] - th[si]), 0.0, 1.0)
    x = _polish_phase(P, D, t1, t2, x, wl, wr, T, np.sign(fl))
    lrx = _theta_at(P, D, t1, t2, x, T)[2]
    sign = np.where(up, 1, -1)
    counted = lrx < logr[qi]
    np.add.at(out, qi[counted], sign[counted])
    return out


def _polish_phase(
    P: float, D: float, t1: float, t2: float, x: NDArray, wl: NDArray, wr: NDArray, T: NDArray, sl: NDArray
) -> NDArray[np.float64]:
    """omega in [wl, wr] with theta(omega) = T: Newton kept inside the shrinking bracket (bisection otherwise)."""
    x, wl, wr = x.copy(), wl.copy(), wr.copy()
    active = np.arange(x.size)
    for _ in range(_NEWTON_STEPS):
        if active.size == 0:
            break
        xa, la, ra = x[active], wl[active], wr[active]
        f, df, _ = _theta_at(P, D, t1, t2, xa, T[active])
        f = f - T[active]
        same = (np.sign(f) == sl[active]) & (f != 0)
        la = np.where(same, xa, la)
        ra = np.where(same, ra, xa)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = xa - f / df
        ok = np.isfinite(step) & (step > la) & (step < ra)
        nxt = np.where(ok, step, 0.5 * (la + ra))
        nxt = np.where(f == 0, xa, nxt)
        done = (np.abs(nxt - xa) <= 1e-14 * np.maximum(1.0, np.abs(xa))) | (ra - la <= 1e-15 * np.maximum(1.0, ra))
        x[active], wl[active], wr[active] = nxt, la, ra
        active = active[~done]
    return x


def _monotone_runs(th: NDArray[np.float64]) -> list[tuple[int, int]]:
    """(first, last) sample indices of the maximal runs on which the sampled theta is monotone."""
    d = np.sign(np.diff(th))
    d[d == 0] = 1.0
    cut = np.flatnonzero(d[1:] != d[:-1]) + 1
    starts = np.concatenate([[0], cut])
    ends = np.concatenate([cut, [th.size - 1]])
    return list(zip(starts.tolist(), ends.tolist(), strict=True))


# ===================================================================== the result
@validated()
@dataclass(frozen=True, eq=False)
class LambdaRegion(FigureRepr):
    """The stable region of the eigenvalue plane at fixed gains and delays.

    An eigenvalue lam of C is stable when every root of
    ``q(s, lam) = s^2 + D s + P - lam (D s e^{-tau2 s} + P e^{-tau1 s})``
    (paper, eq. 3) has Re s < 0; a team is stable at these delays exactly
    when every eigenvalue of its C lies in the region, the centroid's root
    s = 0 aside (Lemma 2). See the module docstring for the method.

    Attributes
    ----------
    P, D
        Gains of the paper's eq. 1.
    tau1, tau2
        Delays (s) on positions and on velocities.
    """

    P: float
    D: float
    tau1: float
    tau2: float
    _cache: dict = field(default_factory=dict, repr=False)

    def _curve(self, radius: float) -> _Curve:
        r = max(2.0, float(radius))
        # the adaptive samples come out about 1.5 times the phase turn over the step (measured:
        # 2.72 million for tau = 1e5, radius 2), so the estimate is 3 turns per step, not 2
        need = 3.0 * omega_limit(self.P, self.D, r) * max(self.tau1, self.tau2) / _PHASE_STEP
        if need > MAX_SAMPLES:
            raise ResourceLimitError(
                f"the eigenvalue plane at delays ({self.tau1:g}, {self.tau2:g}) with |lam| up to {r:g} would need about "
                f"{need:,.0f} samples of the boundary curve, more than {MAX_SAMPLES:,}; reduce the delays"
            )
        best = self._cache.get("curve")
        if best is None or best.radius < r:
            best = _sample_curve(self.P, self.D, self.tau1, self.tau2, max(r, 2.0 * (best.radius if best else 0.0)))
            self._cache["curve"] = best
        return best

    def unstable_count(self, lam: ArrayLike) -> NDArray[np.int64]:
        """Number of roots of ``q(s, lam)`` with Re s > 0 (vectorized).

        Parameters
        ----------
        lam
            Complex eigenvalue(s), any shape, anywhere in the plane with
            ``|lam| <= MAX_MODULUS``. Values
            within :data:`CENTROID_TOL` of 1 are the centroid eigenvalue,
            whose root s = 0 is not counted.

        Returns
        -------
        ndarray of int, shape of ``lam``
        """
        z = check_complex_array("lam", lam)
        shape = z.shape
        z = z.ravel().copy()
        centroid = np.abs(z - 1.0) <= CENTROID_TOL
        z[centroid] = 1.0
        out = np.zeros(z.size, np.int64)
        if z.size == 0:
            return out.reshape(shape)
        rad = np.abs(z)
        if rad.max() > MAX_MODULUS:
            raise InputError(f"|lam| must be at most {MAX_MODULUS:g} (eigenvalues of C lie in the unit disc), got {rad.max():g}")
        curve = self._curve(float(rad.max()) * 1.01)
        psi = np.angle(z)
        for sign in (1.0, -1.0):  # omega > 0 for lam, omega < 0 as omega > 0 for conj(lam)
            out += _crossings(curve, self.P, self.D, self.tau1, self.tau2, sign * psi, rad)
        # omega = 0: L = 1; a real lam > 1 has one unstable real root.
        out += ((z.imag == 0.0) & (z.real > 1.0)).astype(np.int64)
        return out.reshape(shape)

    def is_stable(self, lam: ArrayLike) -> NDArray[np.bool_]:
        """True where every root of ``q(s, lam)`` has Re s < 0 (the centroid's s = 0 aside).

        Parameters
        ----------
        lam
            Complex eigenvalue(s), any shape.
        """
        return self.unstable_count(lam) == 0

    def team_unstable_count(self, topology: Topology) -> int:
        """NU of the whole team: the sum over the eigenvalues of C, multiplicity counted.

        Parameters
        ----------
        topology
            The team's communication topology (dense eigenvalues).
        """
        if not isinstance(topology, Topology):
            raise InputError(f"topology must be a Topology, got {type(topology).__name__}")
        topology.require_spanning_tree()
        lam = topology.eigenvalues
        return int(self.unstable_count(lam).sum())

    def team_is_stable(self, topology: Topology) -> bool:
        """True when every eigenvalue of the team's C lies in the stable region.

        Parameters
        ----------
        topology
            The team's communication topology.
        """
        return self.team_unstable_count(topology) == 0

    def boundary(self, radius: float = 3.0) -> NDArray[np.complex128]:
        """Points of the boundary curve ``L(j omega)`` with ``|L| <= radius``, omega from -max to max.

        Parameters
        ----------
        radius
            Points farther from 0 are replaced by NaN (breaks in the line).

        Returns
        -------
        ndarray of complex
            The omega < 0 half (the mirror image) first, then omega >= 0.
        """
        curve = self._curve(float(radius))
        lam = np.exp(curve.logrho + 1j * curve.theta)
        lam = np.where(np.abs(lam) <= radius, lam, np.nan)
        return np.concatenate([np.conj(lam[::-1]), lam[1:]])

    def stable_fraction_of_disc(self, *, resolution: int = 201) -> float:
        """Fraction of the closed unit disc (area) that is stable, on a grid.

        Parameters
        ----------
        resolution
            Grid points per axis over [-1, 1]^2.
        """
        x = np.linspace(-1.0, 1.0, resolution)
        z = x[None, :] + 1j * x[:, None]
        inside = np.abs(z) <= 1.0
        return float(np.mean(self.is_stable(z[inside])))

    def plot(self, ax: Axes | None = None, topology: Topology | None = None, *, radius: float = 1.6) -> Axes:
        """Draw the region (shaded), its boundary, the unit disc and a team's eigenvalues.

        Parameters
        ----------
        ax
            Axes to draw on; new ones when None.
        topology
            Optional team whose eigenvalues of C are marked (green: stable, red: not).
        radius
            Half-width of the drawn square of the lam plane.
        """
        from delayform.plots import lambda_region_plot

        eig = None if topology is None else topology.eigenvalues
        return lambda_region_plot(self, ax=ax, eigenvalues=eig, radius=radius)


@validated()
def lambda_region(P: float, D: float, tau1: float, tau2: float) -> LambdaRegion:
    """The stable region of the eigenvalue plane of the paper's eq. 3 at fixed gains and delays.

    Parameters
    ----------
    P, D
        Positive gains of the paper's eq. 1.
    tau1, tau2
        Non-negative delays (s) on positions and on velocities.

    Returns
    -------
    LambdaRegion
        ``.unstable_count(lam)``, ``.is_stable(lam)`` (vectorized), ``.boundary()``,
        ``.team_is_stable(topology)`` and ``.plot(ax, topology)``.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> region = lambda_region(1.0, 0.5, 1.0, 2.0)  # point c of the paper's Fig. 3
    >>> region.team_is_stable(paper_six())
    False
    >>> bool(region.is_stable(0.0)), int(region.unstable_count(1.5))
    (True, 1)
    """
    P, D = check_gains(P, D)
    t1, t2 = check_delay("tau1", tau1), check_delay("tau2", tau2)
    return LambdaRegion(P, D, t1, t2)
