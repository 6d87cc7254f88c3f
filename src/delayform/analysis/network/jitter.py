"""A jitter margin: time-varying per-link delays, arbitrarily fast, certified by small gain.

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
needed, so it holds for arbitrarily fast variation, and for held packets as long
as the age of the value held stays in the interval. With packets sent every h
seconds and delays in [tau - b, tau + b] that age lies in [tau - b, tau + b + h]:
ask for the margin about tau + h/2 and compare it with b + h/2
(:mod:`delayform.report.guarantees` does).

Delays varying together
-----------------------
When the same h1(t), h2(t) hold on every link the team still factorizes, and
``jitter_margin(..., method="per-mode")`` certifies each mode by a
Lyapunov-Krasovskii functional
(:func:`~delayform.analysis.certificates.team.team_delay_margin`): a larger
margin, but only for that class of variations (``JitterMargin.covers`` says
which class a margin is about; ``method="best"`` keeps the per-link one in
``per_link_delta``).

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
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform.analysis.network.box import DelayBox
from delayform.analysis.network.links import LinkTeam, link_team
from delayform.analysis.network.per_link import dominant_of_team
from delayform._validation import FloatOrNaN, validated
from delayform.errors import DelayError, InputError, NotConvergedError
from delayform.topology import Topology

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes

__all__ = ["JitterMargin", "JitterMarginMap", "jitter_margin", "jitter_margin_map", "jitter_map_estimate", "METHODS",
           "PER_LINK", "SMALL_GAIN"]

#: The small-gain certificate, in words.
SMALL_GAIN = "small gain, Kao-Lincoln delay-difference bound, constant diagonal scaling"
#: What the small-gain margin covers.
PER_LINK = "every link's and stream's delay varying on its own (per link, independently), arbitrarily fast"
#: The methods :func:`jitter_margin` offers.
METHODS = ("small-gain", "per-mode", "best")

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
        The certificate that proves ``delta``.
    reason
        Why ``delta`` is 0 without a gain computed (an unstable nominal point,
        or the centroid's double zero at tau1 = 0); empty otherwise.
    covers
        Which variations ``delta`` is about: :data:`PER_LINK` (every link and
        stream on its own) for the small-gain margin, or
        :data:`~delayform.analysis.certificates.team.COVERS` (the same h1(t), h2(t)
        on every link) for the per-mode Lyapunov-Krasovskii margin.
    per_link_delta
        The small-gain margin, which covers independent per-link variations
        (equal to ``delta`` when that is the small-gain one).
    together_delta
        The per-mode Lyapunov-Krasovskii margin for delays varying together on
        every link; NaN when not computed (``method="small-gain"``, or per-link
        nominal delays, which do not factorize).
    """

    delta: float
    gain: float
    peak_frequency: FloatOrNaN
    scaled: bool
    nominal_root: complex
    method: str = SMALL_GAIN
    reason: str = ""
    covers: str = PER_LINK
    per_link_delta: FloatOrNaN = float("nan")
    together_delta: FloatOrNaN = float("nan")

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
        # sigma_max(diag(o) Sel K E) from N x N matrices only: with R = (E E^T)^{1/2} and
        # W = Sel^T |diag(o)|^2 Sel = |o_pos|^2 S1 + |o_vel|^2 S2, sigma_max^2 = lambda_max(R K^H W K R)
        self.S1, self.S2 = self.Sel[:L].T @ self.Sel[:L], self.Sel[L:].T @ self.Sel[L:]
        lam, U = np.linalg.eigh(self.E @ self.E.T)
        self.R = (U * np.sqrt(np.maximum(lam, 0.0))) @ U.T

    def _gain(self, K: NDArray[np.complex128], pos: NDArray[np.float64], vel: NDArray[np.float64]) -> NDArray[np.float64]:
        """sigma_max(diag(o) Sel K E) per sample, |o|^2 = pos on position channels, vel on velocity ones."""
        Y = K @ self.R
        W = pos[:, None, None] * self.S1 + vel[:, None, None] * self.S2
        gram = Y.conj().swapaxes(-1, -2) @ W @ Y
        return np.sqrt(np.maximum(np.linalg.eigvalsh(gram)[..., -1], 0.0)) * (1.0 + 1e-12)

    def _out(self, w: NDArray[np.float64]) -> NDArray[np.complex128]:
        # iw on position channels (z = velocity), (iw)^2 on velocity channels (z = acceleration)
        return np.where(np.arange(2 * self.L)[None, :] < self.L, 1j * w[:, None], -(w[:, None] ** 2) + 0j)

    def high_samples(self, w: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """sigma_max(G(iw)) at each w > 0 (from H = M^{-1}) and ||H(iw)||_2."""
        H = np.linalg.inv(self.t.matrix(1j * w))
        return self._gain(H, w**2, w**4), _norm2(H)

    def high_matrix(self, w: float) -> NDArray[np.complex128]:
        """G(iw) itself (2L x 2L), for the scaling at the peak."""
        H = np.linalg.inv(self.t.matrix(1j * np.array([w])))
        return (self._out(np.array([w]))[:, :, None] * (self.Sel[None] @ H @ self.E[None]))[0]

    def high_lipschitz(self, wa: NDArray[np.float64], wb: NDArray[np.float64], Hn: NDArray[np.float64]) -> NDArray[np.float64]:
        """Bound of ||dG/dw|| on each piece [wa, wb], from ||H(i wa)||."""
        t = self.t
        LM = _entrywise_norm(t, (2.0 * wb + t.D), t.weights * (t.P * t.tau1 + t.D * (1.0 + wb[:, None] * t.tau2)))
        Hmax = _inverse_growth(Hn, LM * (wb - wa))
        q = np.hypot(self.a * wb, self.b * wb**2)
        dq = np.hypot(self.a, 2.0 * self.b * wb)
        return (dq * Hmax + q * Hmax**2 * LM) * self.e

    def _low_factor(self, w: NDArray[np.float64]) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        Hh = np.linalg.inv(self.box.centre_matrix(w))
        s = 1j * w
        one_u = np.outer(np.ones(self.t.n), self.box.u)
        Z = s[:, None, None] * np.eye(self.t.n) + (1.0 - s)[:, None, None] * one_u
        return Z @ Hh, Hh

    def low_samples(self, w: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """As :meth:`high_samples`, from the deflated Mh (box module, step 2), valid down to w = 0.

        M = Mh T diag(s, 1, ...) T^{-1} gives s H = Z Mh^{-1} with Z = s I + (1 - s) 1 u^T,
        so G = diag(1, s) Sel Z Mh^{-1} E is analytic at s = 0.
        """
        K, Hh = self._low_factor(w)
        return self._gain(K, np.ones_like(w), w**2), _norm2(Hh)

    def low_matrix(self, w: float) -> NDArray[np.complex128]:
        """G(iw) itself from the deflated form (valid at w = 0)."""
        K, _ = self._low_factor(np.array([w]))
        return (self._low_out(np.array([w]))[:, :, None] * (self.Sel[None] @ K @ self.E[None]))[0]

    def low_lipschitz(self, wa: NDArray[np.float64], wb: NDArray[np.float64], Hn: NDArray[np.float64]) -> NDArray[np.float64]:
        """Bound of ||dG/dw|| on each piece of the low band, from ||Mh(i wa)^{-1}||."""
        L = self.box.lipschitz_stack(wb)
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
    rows = links @ _one_hot(t.rows, t.n)  # row sums of the link entries, every sample at once
    cols = links @ _one_hot(t.cols, t.n)
    return np.sqrt((diag + cols.max(axis=1)) * (diag + rows.max(axis=1)))


def _one_hot(index: NDArray[np.int64], n: int) -> NDArray[np.float64]:
    out = np.zeros((index.size, n))
    out[np.arange(index.size), index] = 1.0
    return out


def _certified_sup(sample, lipschitz, w: NDArray[np.float64], floor: float) -> tuple[float, float, float]:
    """Upper bound of sigma_max(G) over [w[0], w[-1]] from samples and derivative bounds (bisection).

    Returns (bound, frequency of the largest sample, largest sample).
    """
    sig, nrm = sample(w)
    while True:
        piece = sig[:-1] + lipschitz(w[:-1], w[1:], nrm[:-1]) * np.diff(w)
        bad = ~(piece <= _TIGHT * max(sig.max(), floor))
        if not bad.any() or w.size > _MAX_SAMPLES:
            k = int(np.argmax(sig))
            return float(max(piece.max(), sig.max())), float(w[k]), float(sig[k])
        add = 0.5 * (w[:-1] + w[1:])[bad]
        s2, n2 = sample(add)
        order = np.argsort(np.concatenate([w, add]), kind="stable")
        w = np.concatenate([w, add])[order]
        sig, nrm = np.concatenate([sig, s2])[order], np.concatenate([nrm, n2])[order]


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
    hi = _certified_sup(loop.high_samples, loop.high_lipschitz, np.linspace(w1, Omega, 513), lo[2])
    tail = loop.tail(Omega)
    wpk = lo[1] if lo[2] >= hi[2] else hi[1]
    Gpk = loop.low_matrix(wpk) if lo[2] >= hi[2] else loop.high_matrix(wpk)
    return float(max(lo[0], hi[0], tail)), wpk, Gpk, float(max(lo[2], hi[2]))


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


def margin_of_team(team: LinkTeam, nominal_root: complex | None = None) -> JitterMargin:
    """:func:`jitter_margin` of a checked :class:`LinkTeam` (0 where the nominal point is unstable).

    ``nominal_root``: the team's dominant root when already known (its
    persistent zero excluded, never on the drift); else the per-link finder computes it.
    """
    if nominal_root is None:
        nominal = dominant_of_team(team)
        root, drift = nominal.root, nominal.drift
    else:
        root, drift = complex(nominal_root), False
    if not root.real < 0.0:
        return JitterMargin(0.0, math.inf, float("nan"), False, root, reason="the nominal delays are unstable",
                            per_link_delta=0.0)  # fmt: skip
    if drift:
        # every position delay the centroid weighs is 0: s = 0 is a double root (the drift of the paper's eq. 4),
        # the loop's gain is unbounded as w -> 0 and no jitter is certified (rounding would print ~1e-17 s)
        return JitterMargin(0.0, math.inf, 0.0, False, root, reason=(
            "tau1 = 0 on every link the centroid weighs: the centroid's zero is double (the team drifts), "
            "the loop's gain is unbounded at w = 0 and no jitter of the delays is certified"), per_link_delta=0.0)  # fmt: skip
    bound, wpk, scaled = _scaled_bound(team)
    if not math.isfinite(bound):
        raise NotConvergedError("the H-infinity bound of the jitter loop did not converge", partial=bound)
    delta = _delta_of_gain(bound, _longest(team))
    return JitterMargin(delta, bound, wpk, scaled, root, per_link_delta=delta)


def _longest(team: LinkTeam) -> float:
    # gamma_j^2 = delta (delta + min(delta, tau_j)) grows with tau_j: the longest nominal delay is the worst channel
    return float(max(team.tau1.max(initial=0.0), team.tau2.max(initial=0.0)))


def _certified_delta(team: LinkTeam) -> float:
    """The margin of a team known to be nominally stable; 0 where the bound cannot be certified."""
    try:
        bound = _scaled_bound(team)[0]
    except np.linalg.LinAlgError:  # M(iw) singular at a sample: an imaginary root, nothing to certify
        return 0.0
    return _delta_of_gain(bound, _longest(team)) if math.isfinite(bound) else 0.0


def _scaled_bound(team: LinkTeam) -> tuple[float, float, bool]:
    """(certified ||S G S^{-1}||_inf, peak frequency, scaled): the better of no scaling and the Perron one."""
    plain = _Loop(team)
    bound, wpk, Gpk, _ = hinf_bound(plain)
    scaled = False
    S = _perron_scaling(Gpk / plain.S[:, None] * plain.S[None, :])
    if S is not None:
        b2, w2, _, _ = hinf_bound(_Loop(team, S))
        if b2 < bound:
            bound, wpk, scaled = b2, w2, True
    return bound, wpk, scaled


@validated()
def jitter_margin(topology: Topology, P: float, D: float, tau1: ArrayLike, tau2: ArrayLike, *,
                  method: str = "small-gain") -> JitterMargin:  # fmt: skip
    """The certified jitter margin at nominal delays (scalars or per-link N x N arrays).

    Parameters
    ----------
    topology, P, D, tau1, tau2
        The team, its gains and its nominal delays, as for
        :func:`~delayform.analysis.network.links.link_team`.
    method
        "small-gain" (default): the margin for every link's delays varying on
        their own (module docstring). "per-mode": the Lyapunov-Krasovskii
        margin per mode of the paper's eq. 3
        (:func:`~delayform.analysis.certificates.team.team_delay_margin`), which
        covers only the same h1(t), h2(t) on every link (scalar nominal delays
        only). "best": both, ``delta`` the larger and ``method`` / ``covers``
        naming the one that proves it; ``per_link_delta`` keeps the per-link one.

    Returns
    -------
    JitterMargin
        ``delta`` such that every time-varying delay within ``[tau - delta, tau + delta]``
        (clipped at 0), in the class of variations ``covers`` names, keeps the team
        stable; 0 where the nominal point is unstable.

    Raises
    ------
    InputError
        For an unknown method, or "per-mode" / "best" with per-link delays.

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> m = jitter_margin(paper_six(), 1.0, 0.5, 0.3, 0.2)
    >>> 0.0 < m.delta < 0.3
    True
    """
    if method not in METHODS:
        raise InputError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    scalar = np.ndim(tau1) == 0 and np.ndim(tau2) == 0
    if method != "small-gain" and not scalar:
        raise InputError(f"method {method!r} needs one delay pair for every link (the team factorizes only then); "
                         "per-link delays have the small-gain margin only")  # fmt: skip
    team = link_team(topology, P, D, tau1, tau2)
    nominal = None
    if scalar and float(tau1) > 0.0:  # type: ignore[arg-type]
        # one delay pair for every link: the nominal team factorizes (paper, eq. 3), and its
        # dominant root comes from the factors at once (long delays and large gains included)
        # instead of the per-link matrix discretization; tau1 = 0 (the drift) stays per link
        from delayform.analysis.roots.dominant import dominant_root  # roots imports network: not at the top

        nominal = complex(dominant_root(topology, P, D, float(tau1), float(tau2)).root)  # type: ignore[arg-type]
    small = margin_of_team(team, nominal)
    if method == "small-gain" or not small.nominal_stable or small.reason:
        return small
    from delayform.analysis.certificates.team import COVERS, team_delay_margin

    lk = team_delay_margin(topology, team.P, team.D, float(tau1), float(tau2))  # type: ignore[arg-type]
    if method == "per-mode" or lk.delta > small.delta:
        return replace(small, delta=lk.delta, method=lk.method, covers=COVERS, together_delta=lk.delta,
                       reason=lk.reason)  # fmt: skip
    return replace(small, together_delta=lk.delta)


#: seconds of one certified margin on the paper's six agents (12 links; a 13 x 13 map, benchmarks/bench_jitter_map.py)
_SECONDS_PER_POINT = 0.08
#: bytes per frequency sample and link pair kept while the H-infinity bound is refined
_BYTES_PER_SAMPLE = 16


def jitter_map_estimate(topology: Topology, points: int) -> tuple[float, float]:
    """Rough (seconds, bytes) of a :func:`jitter_margin_map` with ``points`` grid points.

    The cost of one certified margin grows with the links L (the loop is 2L x 2L at
    the peak, N x N at every frequency sample): about ``0.08 s (L / 12)^1.5``.

    Parameters
    ----------
    topology
        The team.
    points
        Grid points of the map.
    """
    n = topology.n
    links = max(1, int(topology.C_sparse.nnz))
    seconds = points * _SECONDS_PER_POINT * max(1.0, links / 12.0) ** 1.5
    nbytes = _MAX_SAMPLES * (n * n + 4 * links * links) * _BYTES_PER_SAMPLE
    return seconds, float(nbytes)


@validated()
@dataclass(frozen=True, eq=False)
class JitterMarginMap:
    """Certified jitter margins over a grid of (equal) nominal delays.

    Attributes
    ----------
    tau1_values, tau2_values
        The grid; ``delta[i, j]`` is at (tau1_values[i], tau2_values[j]).
    delta
        The margin (0 where the nominal point is unstable or on a crossing curve).
    """

    tau1_values: NDArray[np.float64]
    tau2_values: NDArray[np.float64]
    delta: NDArray[np.float64]

    def levels(self, count: int = 6) -> NDArray[np.float64]:
        """Round contour levels of the margin, strictly inside (0, max delta]; empty when nothing is certified."""
        top = float(self.delta.max(initial=0.0))
        if not top > 0.0:
            return np.zeros(0)
        step = 10.0 ** math.floor(math.log10(top / count))
        for mult in (1.0, 2.0, 2.5, 5.0, 10.0):
            if top / (mult * step) <= count:
                step *= mult
                break
        out = np.arange(1, int(top / step) + 1) * step
        return out[out <= top]

    def plot(self, ax: Axes | None = None, *, filled: bool = False) -> Axes:
        """Contour lines of the certified margin over the stable region (default), or filled contours.

        Lines (labelled in seconds) are drawn where delta > 0 only, so they sit on
        the stability chart's shaded region without retracing its boundary: draw
        :meth:`StabilityMap.plot` first on the same axes. ``filled=True`` draws
        filled contours with a colour bar instead (a figure of its own).
        """
        import matplotlib
        import matplotlib.pyplot as plt
        from matplotlib.lines import Line2D

        if ax is None:
            ax = plt.figure().add_subplot()
        z = np.where(self.delta > 0.0, self.delta, np.nan).T
        levels = self.levels()
        if levels.size == 0:  # nothing certified: say so on the axes rather than draw nothing silently
            ax.text(0.02, 0.02, "jitter margin: 0 everywhere", transform=ax.transAxes, fontsize="small")
        elif filled:
            cs = ax.contourf(self.tau1_values, self.tau2_values, z, levels=np.concatenate([[0.0], levels]),
                             cmap="viridis", alpha=0.8)  # fmt: skip
            ax.figure.colorbar(cs, ax=ax, label="certified jitter margin delta (s)")
        elif np.count_nonzero(np.isfinite(z)) >= 4:
            cs = ax.contour(self.tau1_values, self.tau2_values, z, levels=levels, cmap="viridis", linewidths=1.2)
            ax.clabel(cs, fmt=lambda v: f"{v:.3g} s", fontsize="x-small")
            _extend_legend(ax, Line2D([], [], color=matplotlib.colormaps["viridis"](0.5), label="certified jitter margin (s)"))
        ax.set_xlabel("tau1 (s)")
        ax.set_ylabel("tau2 (s)")
        return ax


def _extend_legend(ax: Axes, handle: object) -> None:
    """Add ``handle`` to the axes' legend, keeping the entries already there (a chart's proxies)."""
    old = ax.get_legend()
    handles = list(old.legend_handles) if old is not None else []
    labels = [t.get_text() for t in old.get_texts()] if old is not None else []
    ax.legend(handles=[*handles, handle], labels=[*labels, handle.get_label()],  # type: ignore[attr-defined]
              loc="upper right", fontsize="small", framealpha=0.9)  # fmt: skip


def _map_axis(name: str, v: ArrayLike) -> NDArray[np.float64]:
    try:
        arr = np.atleast_1d(np.asarray(v, dtype=np.float64))
    except (TypeError, ValueError):
        raise DelayError(f"{name} must be a non-empty 1-D sequence of finite non-negative delays") from None
    if arr.ndim != 1 or arr.size == 0 or not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise DelayError(f"{name} must be a non-empty 1-D sequence of finite non-negative delays")
    return arr


@validated()
def jitter_margin_map(
    topology: Topology, P: float, D: float, tau1_values: ArrayLike, tau2_values: ArrayLike
) -> JitterMarginMap:
    """:func:`jitter_margin` at every point of a grid of equal delays.

    Which points are nominally stable comes from the exact CTCR map
    (:func:`~delayform.analysis.ctcr.stability_map.stability_map`, NU = 0): the
    small-gain bound is computed there only, and a point where it cannot be
    certified (on a crossing curve, where the loop has an imaginary pole) gets 0.

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
    ResourceLimitError
        When the grid would take longer than the time budget (checked before any work).
    """
    from delayform.analysis.ctcr.stability_map import stability_map
    from delayform.resources import require

    axes = [_map_axis("tau1_values", tau1_values), _map_axis("tau2_values", tau2_values)]
    base = link_team(topology, P, D, 0.0, 0.0)
    seconds, nbytes = jitter_map_estimate(topology, axes[0].size * axes[1].size)
    require(what=f"a {axes[0].size} x {axes[1].size} jitter-margin map of {topology.n} agents",
            setting="the jitter-margin grid", nbytes=nbytes, seconds=seconds)  # fmt: skip
    # the exact chart decides nominal stability (G must be stable for small gain); its window needs sides > 0
    smap = stability_map(topology, base.P, base.D, max(float(axes[0].max()), 1e-3), max(float(axes[1].max()), 1e-3))
    stable = np.asarray(smap.is_stable(axes[0][:, None], axes[1][None, :]))
    out = np.zeros((axes[0].size, axes[1].size))
    for i, j in zip(*np.nonzero(stable), strict=True):
        team = LinkTeam(base.C, base.P, base.D, base.rows, base.cols, base.weights,
                        np.full(base.rows.size, axes[0][i]), np.full(base.rows.size, axes[1][j]))  # fmt: skip
        out[i, j] = _certified_delta(team)
    return JitterMarginMap(axes[0], axes[1], out)
