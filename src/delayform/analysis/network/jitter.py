"""A jitter margin: time-varying per-link delays, arbitrarily fast, certified by small gain (issue 20, part 3).

Question: the largest delta such that the team is stable for *any* time-varying
delays ``tau1_ik(t) in [tau1_ik - delta, tau1_ik + delta]`` and
``tau2_ik(t) in [tau2_ik - delta, tau2_ik + delta]`` (clipped at 0), each link
and stream varying on its own, as fast as it likes (jitter, switching, packets
held).

Loop
----
Write x_k(t - tau(t)) = x_k(t - tau) + w(t) on every link and stream. The
nominal (constant-delay) team is the LTI system G from the 2L deviations w
(L links, a position and a velocity stream each) to the 2L signals z whose
*derivatives* the deviations are made of: the informer's velocity for a
position stream, its acceleration for a velocity stream. With
H(s) = M(s)^{-1} (:mod:`~delayform.analysis.network.links`),

    G(s) = diag(s, ..., s^2, ...) Sel H(s) E,

Sel picking the informer of each channel and E feeding channel (i, k) into
agent i's acceleration with weight P C_ik or D C_ik. G is stable when the
nominal point is (its persistent zero is cancelled by the factor s).

The bound (Kao & Lincoln, Automatica 2004, Lemma 1, in its symmetric form)
------------------------------------------------------------------------
w(t) = -int_{t - tau(t)}^{t - tau} z'(theta) d theta, so by Cauchy-Schwarz
|w(t)|^2 <= delta int_{t - tau - delta}^{t - max(tau - delta, 0)} |z'|^2, and
integrating over t (Fubini) ``||w||_2 <= gamma ||z'||_2`` with
``gamma^2 = delta (delta + min(delta, tau))``: no bound on the rate of change is
needed, so it holds for arbitrarily fast variation (and for held packets: the
age of the newest packet received stays in the same interval).

Small gain with constant scalings
---------------------------------
Each deviation operator acts on its own scalar channel, so a constant positive
diagonal scaling S commutes with the block of all of them: the loop is stable if
``gamma_max ||S G S^{-1}||_inf < 1`` (Zames; constant D-scalings). Frequency-
dependent scalings, or the multipliers valid for constant delays, are *not*
used: they need the perturbation to be time invariant. S is the Perron scaling
of |G| at the frequency of the peak (Safonov 1982), kept only if it lowers the
bound. The H-infinity norm is bounded rigorously: samples of sigma_max(S G S^{-1}),
closed-form bounds on its derivative between samples, and a monotone bound past
a cut-off frequency.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform.analysis.network.box import DelayBox
from delayform.analysis.network.links import LinkTeam, link_team
from delayform.analysis.network.per_link import dominant_of_team
from delayform._validation import FloatOrNaN, validated
from delayform.errors import DelayError, NotConvergedError
from delayform.topology import Topology

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes

__all__ = ["JitterMargin", "JitterMarginMap", "jitter_margin", "jitter_margin_map"]

#: The certified norm is accepted when within this factor of the sampled peak.
_TIGHT = 1.01
#: Most frequency samples spent on one norm.
_MAX_SAMPLES = 50_000


@validated()
@dataclass(frozen=True, eq=False)
class JitterMargin:
    """The certified jitter margin at one (per-link) delay point.

    Attributes
    ----------
    delta
        Largest certified deviation (s) of every time-varying delay from its
        nominal value; 0 where the nominal point is unstable.
    gain
        Certified upper bound of ||S G S^{-1}||_inf (inf where unstable).
    peak_frequency
        Where the sampled gain is largest (rad/s); NaN where the nominal
        point is unstable (no gain is sampled there).
    scaled
        True when the Perron scaling lowered the bound.
    nominal_root
        The dominant root at the nominal delays.
    method
        The certificate used.
    """

    delta: float
    gain: float
    peak_frequency: FloatOrNaN
    scaled: bool
    nominal_root: complex
    method: str = "small gain, Kao-Lincoln delay-difference bound, constant diagonal scaling"

    @property
    def nominal_stable(self) -> bool:
        """True when the nominal constant-delay point is stable."""
        return self.nominal_root.real < 0.0


def _delta_of_gain(gain: float, tau: float) -> float:
    """Largest delta with delta (delta + min(delta, tau)) < 1 / gain^2 (tau: the longest nominal delay)."""
    g = 1.0 / gain
    d = g / math.sqrt(2.0)
    if d > tau:
        d = 0.5 * (-tau + math.sqrt(tau * tau + 4.0 * g * g))
    return d * (1.0 - 1e-9)


class _Loop:
    """G(iw) = diag(iw, (iw)^2) Sel H(iw) E with the channel scaling S."""

    def __init__(self, team: LinkTeam, scale: NDArray[np.float64] | None = None) -> None:
        self.t = team
        L = team.rows.size
        self.S = np.ones(2 * L) if scale is None else scale
        E = np.zeros((team.n, 2 * L))
        E[team.rows, np.arange(L)] = team.P * team.weights
        E[team.rows, L + np.arange(L)] = team.D * team.weights
        self.E = E / self.S[None, :]
        Sel = np.zeros((2 * L, team.n))
        Sel[np.arange(L), team.cols] = 1.0
        Sel[L + np.arange(L), team.cols] = 1.0
        self.Sel = Sel * self.S[:, None]
        self.L = L
        self.a = float(np.linalg.norm(self.Sel[:L], 2))  # ||S1 Sel1||
        self.b = float(np.linalg.norm(self.Sel[L:], 2))  # ||S2 Sel2||
        self.e = float(np.linalg.norm(self.E, 2))
        self.hf = float(np.linalg.norm(self.Sel[L:] @ self.E, 2))  # the high-frequency gain
        self.c2 = float(np.linalg.norm(team.C, 2))
        self.box = DelayBox(team, np.zeros(L), np.zeros(L), team.tau1, team.tau2)

    def _out(self, w: NDArray[np.float64]) -> NDArray[np.complex128]:
        # iw on position channels (z = velocity), (iw)^2 on velocity channels (z = acceleration)
        return np.where(np.arange(2 * self.L)[None, :] < self.L, 1j * w[:, None], -(w[:, None] ** 2) + 0j)

    def high_samples(self, w: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.complex128], NDArray[np.float64]]:
        """sigma_max(G(iw)) at each w > 0 (from H = M^{-1}), G there, and ||H(iw)||_2."""
        H = np.linalg.inv(self.t.matrix(1j * w))
        G = self._out(w)[:, :, None] * (self.Sel[None] @ H @ self.E[None])
        return _norm2(G), G, _norm2(H)

    def high_lipschitz(self, wa: NDArray[np.float64], wb: NDArray[np.float64], Hn: NDArray[np.float64]) -> NDArray[np.float64]:
        """Bound of ||dG/dw|| on each piece [wa, wb], from ||H(i wa)||."""
        t = self.t
        LM = _entrywise_norm(t, (2.0 * wb + t.D), t.weights * (t.P * t.tau1 + t.D * (1.0 + wb[:, None] * t.tau2)))
        Hmax = _inverse_growth(Hn, LM * (wb - wa))
        q = np.hypot(self.a * wb, self.b * wb**2)
        dq = np.hypot(self.a, 2.0 * self.b * wb)
        return (dq * Hmax + q * Hmax**2 * LM) * self.e

    def low_samples(self, w: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.complex128], NDArray[np.float64]]:
        """As :meth:`high_samples`, from the deflated Mh (box module, step 2), valid down to w = 0.

        M = Mh T diag(s, 1, ...) T^{-1} gives s H = Z Mh^{-1} with Z = s I + (1 - s) 1 u^T,
        so G = diag(1, s) Sel Z Mh^{-1} E is analytic at s = 0.
        """
        Hh = np.linalg.inv(self.box.centre_matrix(w))
        s = 1j * w
        one_u = np.outer(np.ones(self.t.n), self.box.u)
        Z = s[:, None, None] * np.eye(self.t.n) + (1.0 - s)[:, None, None] * one_u
        G = self._low_out(w)[:, :, None] * (self.Sel[None] @ Z @ Hh @ self.E[None])
        return _norm2(G), G, _norm2(Hh)

    def low_lipschitz(self, wa: NDArray[np.float64], wb: NDArray[np.float64], Hn: NDArray[np.float64]) -> NDArray[np.float64]:
        """Bound of ||dG/dw|| on each piece of the low band, from ||Mh(i wa)^{-1}||."""
        L = np.stack([self.box.lipschitz(float(x)) for x in wb])
        LM = np.sqrt(L.sum(axis=1).max(axis=1) * L.sum(axis=2).max(axis=1))  # ||.||_2 <= sqrt(||.||_1 ||.||_inf)
        Hmax = _inverse_growth(Hn, LM * (wb - wa))
        nu = math.sqrt(self.t.n) * float(np.linalg.norm(self.box.u))  # ||1 u^T||_2
        zb, dz = wb + np.hypot(1.0, wb) * nu, 1.0 + nu
        q, dq = np.hypot(self.a, self.b * wb), self.b
        return (dq * zb * Hmax + q * dz * Hmax + q * zb * Hmax**2 * LM) * self.e

    def _low_out(self, w: NDArray[np.float64]) -> NDArray[np.complex128]:
        return np.where(np.arange(2 * self.L)[None, :] < self.L, 1.0 + 0j * w[:, None], 1j * w[:, None])

    def tail(self, w: float) -> float:
        """Bound of ||G(iw')|| for every w' >= w (each factor monotone there), inf if w is too low."""
        t = self.t
        den = w * w - t.P
        x = (t.P + t.D * w) * self.c2 / den if den > 0 else math.inf
        if not x < 1.0:
            return math.inf
        g2 = (w * w / den) * (self.hf + self.b * self.e * x / (1.0 - x))
        g1 = (w / den) * self.a * self.e / (1.0 - x)
        return math.hypot(g1, g2)


def _inverse_growth(n0: NDArray[np.float64], dm: NDArray[np.float64]) -> NDArray[np.float64]:
    """||A(w)^{-1}|| <= ||A(w_a)^{-1}|| / (1 - ||A(w_a)^{-1}|| ||A(w) - A(w_a)||) on a piece (inf when >= 1)."""
    r = n0 * dm
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(r < 1.0, n0 / (1.0 - r), np.inf)


def _norm2(X: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Largest singular value of each matrix of a stack (from the eigenvalues of X^H X or X X^H)."""
    Y = X.conj().swapaxes(-1, -2) @ X if X.shape[-1] <= X.shape[-2] else X @ X.conj().swapaxes(-1, -2)
    return np.sqrt(np.maximum(np.linalg.eigvalsh(Y)[..., -1], 0.0)) * (1.0 + 1e-12)


def _entrywise_norm(t: LinkTeam, diag: NDArray[np.float64], links: NDArray[np.float64]) -> NDArray[np.float64]:
    """sqrt(||W||_1 ||W||_inf) >= ||W||_2 for the non-negative W with that diagonal and link entries."""
    rows = np.stack([np.bincount(t.rows, x, minlength=t.n) for x in links])
    cols = np.stack([np.bincount(t.cols, x, minlength=t.n) for x in links])
    return np.sqrt((diag + cols.max(axis=1)) * (diag + rows.max(axis=1)))


def _certified_sup(sample, lipschitz, w: NDArray[np.float64], floor: float) -> tuple[float, float, NDArray[np.complex128], float]:
    """Upper bound of sigma_max(G) over [w[0], w[-1]] from samples and derivative bounds (bisection)."""
    sig, G, nrm = sample(w)
    while True:
        k = int(np.argmax(sig))
        piece = sig[:-1] + lipschitz(w[:-1], w[1:], nrm[:-1]) * np.diff(w)
        bad = ~(piece <= _TIGHT * max(sig.max(), floor))
        if not bad.any() or w.size > _MAX_SAMPLES:
            return float(max(piece.max(), sig.max())), float(w[k]), G[k], float(sig.max())
        add = 0.5 * (w[:-1] + w[1:])[bad]
        s2, G2, n2 = sample(add)
        order = np.argsort(np.concatenate([w, add]), kind="stable")
        w = np.concatenate([w, add])[order]
        sig, G, nrm = (np.concatenate([a, b])[order] for a, b in ((sig, s2), (G, G2), (nrm, n2)))


def hinf_bound(loop: _Loop) -> tuple[float, float, NDArray[np.complex128], float]:
    """Certified upper bound of ||S G S^{-1}||_inf: (bound, peak frequency, G at the peak, sampled peak).

    [0, w1] with the deflated form (:meth:`_Loop.low_samples`), [w1, Omega] with H = M^{-1}
    (:meth:`_Loop.high_samples`), and the monotone tail bound past Omega.
    """
    t = loop.t
    Omega = max(4.0, 2.0 * math.sqrt(t.P) + 4.0 * t.D * loop.c2)
    while loop.tail(Omega) > _TIGHT * 1.05 * max(loop.hf, 1e-300) and Omega < 1e4:
        Omega *= 1.5
    w1 = min(0.25 * math.sqrt(t.P), 0.5)
    lo = _certified_sup(loop.low_samples, loop.low_lipschitz, np.linspace(0.0, w1, 65), 0.0)
    hi = _certified_sup(loop.high_samples, loop.high_lipschitz, np.linspace(w1, Omega, 513), lo[3])
    tail = loop.tail(Omega)
    best = lo if lo[3] >= hi[3] else hi
    return float(max(lo[0], hi[0], tail)), best[1], best[2], float(max(lo[3], hi[3]))


def _perron_scaling(G: NDArray[np.complex128]) -> NDArray[np.float64] | None:
    """S = sqrt(y / x) from the Perron vectors of |G| (Safonov): S |G| S^{-1} has norm near rho(|G|)."""
    A = np.abs(G)
    vals, right = np.linalg.eig(A)
    valsl, left = np.linalg.eig(A.T)
    x = np.abs(right[:, int(np.argmax(vals.real))].real)
    y = np.abs(left[:, int(np.argmax(valsl.real))].real)
    if np.any(x <= 1e-12 * x.max()) or np.any(y <= 1e-12 * y.max()):
        return None
    return np.sqrt(y / x)


def margin_of_team(team: LinkTeam) -> JitterMargin:
    """:func:`jitter_margin` of a checked :class:`LinkTeam` (0 where the nominal point is unstable)."""
    nominal = dominant_of_team(team)
    if not nominal.is_stable:
        return JitterMargin(0.0, math.inf, float("nan"), False, nominal.root)
    plain = _Loop(team)
    bound, wpk, Gpk, _ = hinf_bound(plain)
    scaled = False
    S = _perron_scaling(Gpk / plain.S[:, None] * plain.S[None, :])
    if S is not None:
        b2, w2, _, _ = hinf_bound(_Loop(team, S))
        if b2 < bound:
            bound, wpk, scaled = b2, w2, True
    if not math.isfinite(bound):
        raise NotConvergedError("the H-infinity bound of the jitter loop did not converge", partial=bound)
    # gamma_j^2 = delta (delta + min(delta, tau_j)) grows with tau_j: the longest nominal delay is the worst channel
    tau_max = float(max(team.tau1.max(initial=0.0), team.tau2.max(initial=0.0)))
    return JitterMargin(_delta_of_gain(bound, tau_max), bound, wpk, scaled, nominal.root)


@validated()
def jitter_margin(topology: Topology, P: float, D: float, tau1: ArrayLike, tau2: ArrayLike) -> JitterMargin:
    """The certified jitter margin at nominal delays (scalars or per-link N x N arrays).

    Parameters
    ----------
    topology, P, D, tau1, tau2
        The team, its gains and its nominal delays, as for
        :func:`~delayform.analysis.network.links.link_team`.

    Returns
    -------
    JitterMargin
        ``delta`` such that every time-varying delay within ``[tau - delta, tau + delta]``
        (clipped at 0), per link and arbitrarily fast, keeps the team stable
        (module docstring); 0 where the nominal point is unstable.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> m = jitter_margin(paper_six(), 1.0, 0.5, 0.3, 0.2)
    >>> 0.0 < m.delta < 0.3
    True
    """
    return margin_of_team(link_team(topology, P, D, tau1, tau2))


@validated()
@dataclass(frozen=True, eq=False)
class JitterMarginMap:
    """Certified jitter margins over a grid of (equal) nominal delays.

    Attributes
    ----------
    tau1_values, tau2_values
        The grid; ``delta[i, j]`` is at (tau1_values[i], tau2_values[j]).
    delta
        The margin (0 where the nominal point is unstable).
    """

    tau1_values: NDArray[np.float64]
    tau2_values: NDArray[np.float64]
    delta: NDArray[np.float64]

    def plot(self, ax: Axes | None = None) -> Axes:
        """Filled contours of the margin over the delay plane (draw the stability chart on the same axes)."""
        import matplotlib.pyplot as plt

        if ax is None:
            ax = plt.figure().add_subplot()
        cs = ax.contourf(self.tau1_values, self.tau2_values, self.delta.T, levels=12, cmap="viridis", alpha=0.8)
        ax.figure.colorbar(cs, ax=ax, label="certified jitter margin delta (s)")
        ax.set_xlabel("tau1 (s)")
        ax.set_ylabel("tau2 (s)")
        return ax


@validated()
def jitter_margin_map(
    topology: Topology, P: float, D: float, tau1_values: ArrayLike, tau2_values: ArrayLike
) -> JitterMarginMap:
    """:func:`jitter_margin` at every point of a grid of equal delays.

    Parameters
    ----------
    topology, P, D
        The team and its gains.
    tau1_values, tau2_values
        The grid's axes (non-empty 1-D sequences of delays); the map is drawn
        over the stability chart with :meth:`JitterMarginMap.plot`.

    Raises
    ------
    DelayError
        When an axis is empty, not 1-D, negative or not finite.
    """
    axes = []
    for name, v in (("tau1_values", tau1_values), ("tau2_values", tau2_values)):
        arr = np.atleast_1d(np.asarray(v, dtype=np.float64))
        if arr.ndim != 1 or arr.size == 0 or not np.all(np.isfinite(arr)) or np.any(arr < 0):
            raise DelayError(f"{name} must be a non-empty 1-D sequence of finite non-negative delays")
        axes.append(arr)
    base = link_team(topology, P, D, 0.0, 0.0)
    out = np.zeros((axes[0].size, axes[1].size))
    for i, a in enumerate(axes[0]):
        for j, b in enumerate(axes[1]):
            team = LinkTeam(base.C, base.P, base.D, base.rows, base.cols, base.weights,
                            np.full(base.rows.size, a), np.full(base.rows.size, b))  # fmt: skip
            out[i, j] = margin_of_team(team).delta
    return JitterMarginMap(axes[0], axes[1], out)
