"""Packet loss, exactly in the mean square.

Model (the simulator's, :mod:`delayform.model.network`, with ``Sampling`` and
``BernoulliLoss``): every agent samples its position and velocity every h = 1/rate
seconds; the packet of stream (i, k) sent at m h arrives m_ik h later (the delays are
whole multiples of h) unless it is lost, independently with probability p_ik per
packet and stream; agent i holds the newest value received (hold-last-value, before
the first packet the informer's initial state). Between arrivals the held values are
constant and agent i's own state enters the paper's eq. 1 exactly, so over one period

    z_i[m+1] = Phi z_i[m] + Gamma (P sum_k C_ik xhat_ik[m] + D sum_k C_ik vhat_ik[m]),
    Phi = e^{A0 h},  Gamma = int_0^h e^{A0 t} dt (0, 1)^T,  A0 = [[0, 1], [-P, -D]],
    xhat_ik[m] = theta xk[m - m1_ik] + (1 - theta) xhat_ik[m - 1],   theta ~ Bernoulli(1 - p_ik).

With buffers of past samples and the held values the lifted state S obeys a jump-linear
recursion ``S[m+1] = A(theta[m]) S[m]`` with ``A(theta) = A_0 + sum_j theta_j c_j r_j^T``
(a received packet replaces the held value: rank one per stream). For independent
Bernoulli theta_j with mean q_j the second moment Q = E[S S^T] obeys the *linear* recursion

    Q[m+1] = A_q Q A_q^T + sum_j q_j (1 - q_j) (r_j^T Q r_j) c_j c_j^T,   A_q = E A(theta),

exact, no approximation (Costa, Fragoso & Marques, *Discrete-Time Markov Jump Linear
Systems*, 2005, for the i.i.d. case). Consensus states are fixed by every A(theta), so
stability is decided on the quotient by them: the team is mean-square stable (the
disagreement's second moment decays) iff the spectral radius rho of the quotient
recursion is below one, and E|disagreement|^2 decays like rho^m: the expected decay rate
is ``-ln(rho) / (2 h)`` per second for its root mean square.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla
from numpy.typing import ArrayLike, NDArray

from delayform.analysis.network.links import LinkTeam, link_team
from delayform._validation import validated
from delayform.errors import DelayError, InputError
from delayform.model.network import BernoulliLoss
from delayform.topology import Topology

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.axes import Axes

__all__ = ["MeanSquareStability", "mean_square_stability"]


@dataclass(frozen=True, eq=False)
class _Lifted:
    """The lifted jump-linear model: A_q, the rank-one pieces c_j r_j^T and their variances."""

    A: NDArray[np.float64]
    c: NDArray[np.float64]  # (n_s, streams)
    r: NDArray[np.float64]  # (n_s, streams)
    var: NDArray[np.float64]  # q (1 - q) per stream
    consensus: NDArray[np.float64]  # the fixed consensus direction
    positions: NDArray[np.int64]  # indices of x_i in S
    b1: int  # periods of position history kept
    b2: int
    held_x: NDArray[np.int64]  # indices of the held values in S
    held_v: NDArray[np.int64]
    informers: NDArray[np.int64]  # informer of each link

    def step(self, Q: NDArray[np.float64]) -> NDArray[np.float64]:
        """One step of the second-moment recursion (module docstring)."""
        w = self.var * np.einsum("aj,ab,bj->j", self.r, Q, self.r)
        return self.A @ Q @ self.A.T + (self.c * w) @ self.c.T

    def start(self, Q: NDArray[np.float64]) -> NDArray[np.float64]:
        """The recursion's state for the initial second moment Q (one mode: Q itself)."""
        return Q

    def total(self, Q: NDArray[np.float64]) -> NDArray[np.float64]:
        """E[S S^T] from the recursion's state."""
        return Q


def lifted_size(team: LinkTeam, m1: NDArray[np.int64], m2: NDArray[np.int64]) -> int:
    """States of the lifted model (:func:`_lift`): x, v, the buffers of the longest lags, the held values."""
    b1, b2 = int(m1.max(initial=0)), int(m2.max(initial=0))
    return 2 * team.n + team.n * (b1 + b2) + 2 * team.rows.size


def require_lift(size: int, *, what: str, modes: int = 1) -> None:
    """Refuse, before the lifted model is built, a recursion beyond the budget (:mod:`delayform.resources`).

    The model holds a few dense ``size x size`` matrices (A, its update, the quotient
    basis and A in it) per mode, and the quotient's change of basis costs about
    4 size^3 flops; the second-moment operator then acts on ``size^2`` entries: an
    Arnoldi run of up to :data:`_PRODUCTS` products, each about
    :data:`_SECONDS_PER_CUBE` size^3 seconds (measured: the paper's team at 20
    packets per second, 98 and 158 states: 642 and 2,932 products in 9.9 and 218 s under load).
    The message names the sampling rate first: the buffers hold (delay x rate) periods.
    """
    from delayform.resources import require

    cube = float(size) ** 3
    arnoldi = _PRODUCTS * _SECONDS_PER_CUBE * cube if size * size > 900 else 0.0
    require(what=f"{what} ({modes} mode(s) of {size:,} x {size:,} states)",
            setting="the sampling rate (rate, network.rate, --rate), the delays or the team",
            nbytes=(modes * 6 + 25) * 8.0 * float(size) ** 2, seconds=modes * (4.0 * cube / 5e9 + arnoldi))  # fmt: skip


#: products of the second-moment operator one Arnoldi run may take, and seconds per size^3 of one
_PRODUCTS = 3000
_SECONDS_PER_CUBE = 2e-8


def _lift(team: LinkTeam, h: float, m1: NDArray[np.int64], m2: NDArray[np.int64], p: NDArray[np.float64]) -> _Lifted:
    n, L = team.n, team.rows.size
    A0 = np.array([[0.0, 1.0], [-team.P, -team.D]])
    E = sla.expm(np.block([[A0, np.array([[0.0], [1.0]])], [np.zeros((1, 3))]]) * h)
    Phi, Gam = E[:2, :2], E[:2, 2]
    b1, b2 = int(m1.max(initial=0)), int(m2.max(initial=0))
    # S = [x (n), v (n), x[m-1..m-b1] (n b1), v[m-1..m-b2] (n b2), xhat (L), vhat (L)]
    ix, iv = np.arange(n), n + np.arange(n)
    bx = 2 * n + np.arange(n * b1).reshape(b1, n) if b1 else np.zeros((0, n), np.int64)
    bv = 2 * n + n * b1 + np.arange(n * b2).reshape(b2, n) if b2 else np.zeros((0, n), np.int64)
    hx = 2 * n + n * (b1 + b2) + np.arange(L)
    hv = hx + L
    size = int(hv[-1] + 1) if L else 2 * n + n * (b1 + b2)

    def source(lag: NDArray[np.int64], cur: NDArray[np.int64], buf: NDArray[np.int64]) -> NDArray[np.int64]:
        return np.where(lag == 0, cur[team.cols], buf[np.maximum(lag - 1, 0), team.cols] if buf.size else 0)

    src1, src2 = source(m1, ix, bx), source(m2, iv, bv)
    # held values at step m before the update: the new held value is theta src + (1 - theta) old
    A = np.zeros((size, size))
    c = np.zeros((size, 2 * L))
    r = np.zeros((size, 2 * L))
    A[hx, hx] = 1.0
    A[hv, hv] = 1.0
    # z[m+1] from z[m] and the (updated) held values; write the update as held_new = old + theta (src - old)
    for a, ia in enumerate((ix, iv)):
        for b, ib in enumerate((ix, iv)):
            A[ia, ib] += Phi[a, b]
    gain_x = team.P * team.weights
    gain_v = team.D * team.weights
    for j in range(L):
        i = team.rows[j]
        for comp, g in ((ix, Gam[0]), (iv, Gam[1])):
            A[comp[i], hx[j]] += g * gain_x[j]
            A[comp[i], hv[j]] += g * gain_v[j]
        # a received packet: held_j += (src - held_j), and z[m+1] sees it through Gamma
        for col, (hold, src, gain) in enumerate(((hx[j], src1[j], gain_x[j]), (hv[j], src2[j], gain_v[j]))):
            k = j + col * L
            c[hold, k] = 1.0
            c[ix[i], k] = Gam[0] * gain
            c[iv[i], k] = Gam[1] * gain
            r[src, k] += 1.0
            r[hold, k] -= 1.0
    # buffers shift: x[m-1] <- x[m], x[m-l] <- x[m-l+1]
    for buf, cur in ((bx, ix), (bv, iv)):
        if buf.size:
            A[buf[0], cur] = 1.0
            for lvl in range(1, buf.shape[0]):
                A[buf[lvl], buf[lvl - 1]] = 1.0
    q = 1.0 - np.concatenate([p, p])
    Aq = A + (c * q) @ r.T
    cons = np.zeros(size)
    cons[ix] = 1.0
    cons[bx.ravel()] = 1.0
    cons[hx] = 1.0
    return _Lifted(Aq, c, r, q * (1.0 - q), cons, ix, b1, b2, hx, hv, team.cols)


@validated()
@dataclass(frozen=True, eq=False)
class MeanSquareStability:
    """Mean-square stability of the sampled team under independent packet loss (exact).

    Attributes
    ----------
    rho
        Spectral radius of the second-moment recursion of the disagreement (per period).
    period
        The sampling period h (s).
    lags1, lags2
        The delays in periods per link (aligned with the team's links).
    """

    rho: float
    period: float
    lags1: NDArray[np.int64]
    lags2: NDArray[np.int64]
    _model: Any  # _Lifted, or the bursty module's Markov jump-linear model (same step/start/total)

    @property
    def stable(self) -> bool:
        """True when E|disagreement|^2 tends to 0 (rho < 1)."""
        return self.rho < 1.0

    @property
    def decay_rate(self) -> float:
        """Expected decay rate (1/s) of the disagreement's root mean square: -ln(rho) / (2 h)."""
        return -math.log(self.rho) / (2.0 * self.period) if self.rho > 0 else math.inf

    def disagreement(self, positions: ArrayLike, velocities: ArrayLike | None = None, *, steps: int) -> NDArray[np.float64]:
        """E sum_i |x_i - mean x|^2 at every period 0..steps, exactly, from a constant initial history.

        Parameters
        ----------
        positions, velocities
            ``(N, d)`` initial positions and velocities (d coordinates; velocities default 0),
            in the coordinates of the formation error (desired offsets subtracted).
        steps
            Number of sampling periods.
        """
        x = np.atleast_2d(np.asarray(positions, dtype=np.float64))
        n = self._model.positions.size
        if x.shape[0] != n:
            raise InputError(f"positions must have {n} rows, got shape {x.shape}")
        v = np.zeros_like(x) if velocities is None else np.atleast_2d(np.asarray(velocities, dtype=np.float64))
        if v.shape != x.shape:
            raise InputError(f"velocities must have the shape of positions {x.shape}, got {v.shape}")
        model = self._model
        size = model.A.shape[0]
        Q = np.zeros((size, size))
        for d in range(x.shape[1]):  # coordinates see the same packets: their second moments add
            S0 = _initial_state(model, x[:, d], v[:, d], size)
            Q += np.outer(S0, S0)
        ix = model.positions
        out = np.empty(steps + 1)
        centre = np.eye(n) - 1.0 / n
        state = model.start(Q)
        for m in range(steps + 1):
            out[m] = float(np.trace(centre @ model.total(state)[np.ix_(ix, ix)] @ centre))
            state = model.step(state)
        return out

    def plot(self, ax: Axes | None = None, *, positions: ArrayLike | None = None, steps: int = 200) -> Axes:
        """The exact E|disagreement|^2 over time from ``positions`` (default: agents on a unit line)."""
        import matplotlib.pyplot as plt

        if ax is None:
            ax = plt.figure().add_subplot()
        n = self._model.positions.size
        x0 = np.arange(n, dtype=float)[:, None] if positions is None else positions
        y = self.disagreement(x0, steps=steps)
        ax.semilogy(np.arange(steps + 1) * self.period, y, label=f"exact, rho = {self.rho:.4f} per period")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("E |disagreement|^2")
        ax.legend(loc="best", fontsize="small")
        return ax


def _initial_state(model: _Lifted, x: NDArray[np.float64], v: NDArray[np.float64], size: int) -> NDArray[np.float64]:
    """Lifted state of a constant history: buffers and held values are copies of the initial state."""
    n = x.size
    S = np.zeros(size)
    S[:n], S[n : 2 * n] = x, v
    S[2 * n : 2 * n + n * model.b1] = np.tile(x, model.b1)
    S[2 * n + n * model.b1 : 2 * n + n * (model.b1 + model.b2)] = np.tile(v, model.b2)
    S[model.held_x] = x[model.informers]  # before the first packet: the informer's initial state
    S[model.held_v] = v[model.informers]
    return S


def _lags(name: str, taus: NDArray[np.float64], h: float) -> NDArray[np.int64]:
    m = np.rint(taus / h)
    if np.any(np.abs(taus - m * h) > 1e-9 * max(1.0, float(taus.max(initial=0.0)))):
        raise DelayError(f"{name}: every delay must be a whole multiple of the sampling period {h:g} s")
    return m.astype(np.int64)


@validated()
def mean_square_stability(
    topology: Topology, P: float, D: float, tau1: ArrayLike, tau2: ArrayLike, *, rate: float,
    loss: BernoulliLoss | ArrayLike,
) -> MeanSquareStability:
    """Exact mean-square stability and decay rate of the sampled team under independent packet loss.

    Parameters
    ----------
    topology, P, D, tau1, tau2
        The team, its gains and its (per-link) delays, as for
        :func:`~delayform.analysis.network.links.link_team`; every delay a whole
        multiple of the sampling period.
    rate
        Packets per second and stream (the period is h = 1 / rate).
    loss
        The network's loss model, a :class:`~delayform.model.BernoulliLoss`,
        or its probability that a packet is lost: a number, or an N x N
        array per link.

    Returns
    -------
    MeanSquareStability

    Examples
    --------
    >>> from delayform.topology import paper_six
    >>> r = mean_square_stability(paper_six(), 1.0, 0.5, 0.3, 0.2, rate=10.0, loss=0.3)
    >>> r.stable
    True
    """
    team = link_team(topology, P, D, tau1, tau2)
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not math.isfinite(rate) or rate <= 0:
        raise InputError(f"rate must be a positive number of packets per second, got {rate!r}")
    h = 1.0 / float(rate)
    if isinstance(loss, BernoulliLoss):
        loss = loss.probability
    try:
        lp = np.asarray(loss, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError("loss must be a probability or an N x N array of them") from None
    if lp.ndim == 0:
        lp = np.full(team.rows.size, float(lp))
    elif lp.shape == (team.n, team.n):
        lp = lp[team.rows, team.cols]
    else:
        raise InputError(f"loss must be a probability or a {team.n} x {team.n} array, got shape {lp.shape}")
    if not np.all(np.isfinite(lp)) or np.any(lp < 0.0) or np.any(lp >= 1.0):
        raise InputError("loss probabilities must lie in [0, 1) (a link that loses everything never converges)")
    m1, m2 = _lags("tau1", team.tau1, h), _lags("tau2", team.tau2, h)
    require_lift(lifted_size(team, m1, m2), what="the mean-square recursion under packet loss")
    model = _lift(team, h, m1, m2, lp)
    return MeanSquareStability(_quotient_radius(model), h, m1, m2, model)


def _quotient_radius(model: _Lifted) -> float:
    """Spectral radius of the second-moment recursion on the quotient by the consensus direction."""
    e = model.consensus / np.linalg.norm(model.consensus)
    V = sla.null_space(e[None, :])  # orthonormal complement of e: the quotient coordinates
    Ab = V.T @ model.A @ V
    cb, rb = V.T @ model.c, V.T @ model.r
    k = V.shape[1]

    def apply(vec: NDArray[np.float64]) -> NDArray[np.float64]:
        Q = vec.reshape(k, k)
        Q = 0.5 * (Q + Q.T)
        w = model.var * np.einsum("aj,ab,bj->j", rb, Q, rb)
        return (Ab @ Q @ Ab.T + (cb * w) @ cb.T).ravel()

    if k * k <= 900:
        L = np.column_stack([apply(col) for col in np.eye(k * k)])
        return float(np.max(np.abs(np.linalg.eigvals(L))))
    op = spla.LinearOperator((k * k, k * k), matvec=apply, dtype=np.float64)
    vals = spla.eigs(op, k=1, which="LM", return_eigenvectors=False, tol=1e-10, maxiter=5000)
    return float(np.max(np.abs(vals)))
