"""Bursty (Gilbert-Elliott) packet loss, exactly in the mean square.

Model: the sampled team of :mod:`~delayform.analysis.network.loss` (period h, delays
whole multiples of h, hold-last-value), but every stream (link and kind: position
or velocity) loses its packets through its own two-state Markov chain, as the
simulator's :class:`~delayform.model.network.GilbertElliott`: in the good state
a packet is lost with ``loss_good``, in the bad one with ``loss_bad``; after each
packet the chain moves good -> bad with ``p_good_to_bad`` and bad -> good with
``p_bad_to_good``; each chain starts in its stationary distribution, independently
of the others.

Markov jump-linear system
-------------------------
The lifted state obeys ``S[m+1] = A(theta[m]) S[m]`` with
``A(theta) = A_0 + sum_j theta_j c_j r_j^T`` (loss module) and now theta_j[m] ~
Bernoulli(q(g_j)) given the state g_j of chain j (the packet that step m may
deliver was sent ``m_j`` periods earlier: its chain's state is that of a stationary
chain shifted by m_j, still a stationary chain; before the first packet a delivery
changes nothing, as the held value is the constant history). With the joint mode
sigma = (g_1, ..., g_J) of all J = 2L chains and Q_sigma[m] = E[S S^T 1{g[m] = sigma}],

    Q_sigma'[m+1] = sum_sigma T(sigma, sigma') [ A_sigma Q_sigma A_sigma^T
                    + sum_j q_j(sigma) (1 - q_j(sigma)) (r_j^T Q_sigma r_j) c_j c_j^T ],
    A_sigma = A_0 + sum_j q_j(sigma) c_j r_j^T,   T = kron of the chains' 2 x 2 matrices,

exact (Costa, Fragoso & Marques, *Discrete-Time Markov Jump Linear Systems*, 2005,
Ch. 3, the second-moment operator; the loss of step m and the chain's next state are
drawn independently given the present one, as in the simulator). The team is
mean-square stable iff the spectral radius of this linear map, on the quotient by the
consensus direction, is below one (ibid., Ch. 3; every chain that moves is
irreducible, so every mode is visited); the decay rate is -ln(rho) / (2 h).

The state space
---------------
The recursion has 2^J modes, each an s x s matrix (s: the lifted size): exact, but
exponential in the number of streams. A chain that never leaves one state (both
probabilities 0, or an absorbing bad state) is Bernoulli loss and adds no mode;
:data:`MAX_CHAINS` moving chains (1024 modes) are the most delayform computes, which
is a team of up to 5 links (a 3-agent ring: 3 links, 64 modes). Larger teams are
refused up front with the numbers (for the paper's six agents, 24 chains: 1.7e7
modes), before anything is allocated.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla
from numpy.typing import ArrayLike, NDArray

from delayform._validation import validated
from delayform.analysis.network.links import link_team
from delayform.analysis.network.loss import MeanSquareStability, _lags, _lift, _Lifted, lifted_size, require_lift
from delayform.errors import InputError, ResourceLimitError
from delayform.model.network import GilbertElliott
from delayform.topology import Topology

__all__ = ["MAX_CHAINS", "bursty_mean_square_stability"]

#: most Gilbert-Elliott chains that move (2^MAX_CHAINS modes of the jump-linear recursion)
MAX_CHAINS = 10


class _Bursty:
    """The Markov jump-linear second-moment recursion; the lifted model's layout by delegation."""

    def __init__(self, base: _Lifted, A_modes: NDArray[np.float64], var: NDArray[np.float64],
                 T: NDArray[np.float64], pi: NDArray[np.float64], chains: int) -> None:  # fmt: skip
        self.base, self.A_modes, self.var, self.T, self.pi, self.chains = base, A_modes, var, T, pi, chains

    def __getattr__(self, name: str) -> Any:  # positions, held values, buffers: the lifted model's
        return getattr(self.base, name)

    @property
    def A(self) -> NDArray[np.float64]:
        """The mean matrix over the stationary modes (its shape is the lifted state's)."""
        return np.tensordot(self.pi.ravel(), self.A_modes, axes=1)

    def start(self, Q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Q_sigma[0] = pi(sigma) Q: the chains start stationary, independent of the initial state."""
        return self.pi.reshape(-1, 1, 1) * Q[None]

    def total(self, Qs: NDArray[np.float64]) -> NDArray[np.float64]:
        """E[S S^T] = sum over modes."""
        return Qs.sum(axis=0)

    def step(self, Qs: NDArray[np.float64]) -> NDArray[np.float64]:
        """One step of the recursion (module docstring), all modes at once."""
        return _step(Qs, self.A_modes, self.base.c, self.base.r, self.var, self.T, self.chains)


def _step(Qs: NDArray[np.float64], A: NDArray[np.float64], c: NDArray[np.float64], r: NDArray[np.float64],
          var: NDArray[np.float64], T: NDArray[np.float64], chains: int) -> NDArray[np.float64]:  # fmt: skip
    w = var * np.einsum("aj,mab,bj->mj", r, Qs, r)
    X = A @ Qs @ A.transpose(0, 2, 1) + np.einsum("aj,mj,bj->mab", c, w, c)
    # the chains move independently: apply each one's 2 x 2 transition matrix along its axis of the mode index
    k = Qs.shape[-1]
    X = X.reshape((2,) * chains + (k, k))
    for axis in range(chains):
        X = np.moveaxis(np.tensordot(T, X, axes=([0], [axis])), 0, axis)
    return X.reshape(-1, k, k)


def _probability(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InputError(f"{name} must be a probability, got {value!r}")
    out = float(value)
    if not (math.isfinite(out) and 0.0 <= out <= 1.0):
        raise InputError(f"{name} must be a probability in [0, 1], got {value!r}")
    return out


def _chain(loss: GilbertElliott | None, *numbers: float | None) -> tuple[float, float, float, float]:
    """``(p_good_to_bad, p_bad_to_good, loss_good, loss_bad)`` of the loss model or of the four numbers, not both."""
    names = ("p_good_to_bad", "p_bad_to_good", "loss_good", "loss_bad")
    if loss is not None:
        if any(x is not None for x in numbers):
            raise InputError("give the chain as loss=GilbertElliott(...) or as its four numbers, not both")
        return loss.p_good_to_bad, loss.p_bad_to_good, loss.loss_good, loss.loss_bad
    if numbers[0] is None or numbers[1] is None:
        raise InputError("give the chain: loss=GilbertElliott(p_good_to_bad, p_bad_to_good), or those two numbers")
    values = (*numbers[:2], 0.0 if numbers[2] is None else numbers[2], 1.0 if numbers[3] is None else numbers[3])
    return tuple(_probability(n, v) for n, v in zip(names, values))  # type: ignore[return-value]


@validated()
def bursty_mean_square_stability(
    topology: Topology, P: float, D: float, tau1: ArrayLike, tau2: ArrayLike, *, rate: float,
    loss: GilbertElliott | None = None, p_good_to_bad: float | None = None, p_bad_to_good: float | None = None,
    loss_good: float | None = None, loss_bad: float | None = None,
) -> MeanSquareStability:  # fmt: skip
    """Exact mean-square stability and decay rate under Gilbert-Elliott (bursty) packet loss.

    Parameters
    ----------
    topology, P, D, tau1, tau2
        The team, its gains and its (per-link) delays, each a whole multiple of the period.
    rate
        Packets per second and stream (the period is h = 1 / rate).
    loss
        The chain of every stream, a :class:`~delayform.model.GilbertElliott`
        (the network's own loss model).
    p_good_to_bad, p_bad_to_good, loss_good, loss_bad
        The same chain as four numbers (``loss_good`` 0 and ``loss_bad`` 1
        unless given), instead of ``loss``.

    Returns
    -------
    MeanSquareStability
        ``rho``, ``stable``, ``decay_rate`` and the exact ``disagreement`` over time.

    Raises
    ------
    ResourceLimitError
        When the team has more than :data:`MAX_CHAINS` moving chains (2 per link), or the
        recursion would not fit in memory: refused before anything is allocated.
    InputError, DelayError
        For probabilities outside [0, 1], a bad rate, delays that are not multiples of the period,
        or a chain that loses every packet for ever (stationary loss 1).

    Examples
    --------
    >>> from delayform.topology import ring
    >>> from delayform.model import GilbertElliott
    >>> r = bursty_mean_square_stability(ring(3), 1.0, 1.0, 0.2, 0.1, rate=10.0, loss=GilbertElliott(0.1, 0.3))
    >>> r.stable
    True
    """
    from delayform.resources import require

    team = link_team(topology, P, D, tau1, tau2)
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not math.isfinite(rate) or rate <= 0:
        raise InputError(f"rate must be a positive number of packets per second, got {rate!r}")
    a, b, lg, lb = _chain(loss, p_good_to_bad, p_bad_to_good, loss_good, loss_bad)
    h = 1.0 / float(rate)
    m1, m2 = _lags("tau1", team.tau1, h), _lags("tau2", team.tau2, h)
    L = team.rows.size
    moving = a > 0.0 and b > 0.0
    # a chain that never moves is Bernoulli loss in the state it keeps (the simulator's convention)
    fixed = lg if (a == 0.0 and b == 0.0) or not moving and b > 0.0 else lb if a > 0.0 else lg
    stationary_loss = (b * lg + a * lb) / (a + b) if moving else fixed
    if stationary_loss >= 1.0 or (moving and lg >= 1.0 and lb >= 1.0):
        raise InputError("this chain loses every packet for ever: the team never converges")
    chains = 2 * L if moving else 0
    size = lifted_size(team, m1, m2)
    if chains > MAX_CHAINS:
        raise ResourceLimitError(
            f"Gilbert-Elliott loss is exact on the joint state of the {chains} link chains "
            f"(2 streams x {L} links): 2^{chains} = {2.0 ** chains:.3g} modes of {size} x {size} matrices, "
            f"beyond the 2^{MAX_CHAINS} modes delayform computes; use a team of at most {MAX_CHAINS // 2} links, "
            "or Bernoulli loss (mean_square_stability)"
        )  # fmt: skip
    modes = 2**chains
    require_lift(size, what="the Gilbert-Elliott mean-square recursion", modes=modes)
    require(what=f"the Gilbert-Elliott mean-square recursion ({modes} modes of {size} x {size})",
            setting="the team, the delays or the sampling rate", nbytes=16.0 * modes * size * size * 8)  # fmt: skip
    base = _lift(team, h, m1, m2, np.zeros(L))  # q = 1: A_full = A_0 + sum_j c_j r_j^T
    A0 = base.A - base.c @ base.r.T
    if chains:
        state = (np.arange(modes)[:, None] >> np.arange(chains - 1, -1, -1)[None, :]) & 1  # 1 = bad, axis order
        q = np.where(state == 1, 1.0 - lb, 1.0 - lg)
        pi_bad = a / (a + b)
        pi = np.prod(np.where(state == 1, pi_bad, 1.0 - pi_bad), axis=1)
        T = np.array([[1.0 - a, a], [b, 1.0 - b]])
    else:
        q = np.full((1, 2 * L), 1.0 - fixed)
        pi, T = np.ones(1), np.eye(2)
    A_modes = A0[None] + np.einsum("aj,mj,bj->mab", base.c, q, base.r)
    model = _Bursty(base, A_modes, q * (1.0 - q), T, pi, chains)
    return MeanSquareStability(_radius(model), h, m1, m2, model)


def _radius(model: _Bursty) -> float:
    """Spectral radius of the mode recursion on the quotient by the consensus direction."""
    e = model.base.consensus / np.linalg.norm(model.base.consensus)
    V = sla.null_space(e[None, :])
    A = V.T @ model.A_modes @ V
    c, r = V.T @ model.base.c, V.T @ model.base.r
    k, M = V.shape[1], model.A_modes.shape[0]

    def apply(vec: NDArray[np.float64]) -> NDArray[np.float64]:
        Qs = vec.reshape(M, k, k)
        Qs = 0.5 * (Qs + Qs.transpose(0, 2, 1))
        return _step(Qs, A, c, r, model.var, model.T, model.chains).ravel()

    dim = M * k * k
    if dim <= 900:
        L = np.column_stack([apply(col) for col in np.eye(dim)])
        return float(np.max(np.abs(np.linalg.eigvals(L))))
    op = spla.LinearOperator((dim, dim), matvec=apply, dtype=np.float64)
    start = np.tile(np.eye(k).ravel(), M) * np.repeat(model.pi, k * k)  # a positive start: the Perron vector's cone
    vals = spla.eigs(op, k=1, which="LM", v0=start, return_eigenvectors=False, tol=1e-10, maxiter=5000)
    return float(np.max(np.abs(vals)))
