"""Imperfect communication networks: per-link and varying delays, packet loss, sampling, noise.

The analysis of the paper assumes that every agent hears every informer
through two constant delays shared by all links: positions ``tau1`` and
velocities ``tau2`` old (paper, eq. 1). A :class:`Network` describes how a
real radio network departs from that, and
:func:`delayform.simulation.delayed.reception.integrate_network` runs
the paper's eq. 1 plus the forcing of the paper's eq. 13 with what each agent actually
HEARS from each informer::

    u_i(t) = P (sum_k C_ik xhat_ik(t) - x_i(t)) + D (sum_k C_ik vhat_ik(t) - xdot_i(t)) + F_i

where ``xhat_ik(t)`` and ``vhat_ik(t)`` are the position and velocity of agent
k as last received by agent i. :func:`delayform.simulation.simulate` calls it
when given ``network=``; the ideal network (every part off) is sent to the
ordinary integrator, so it gives exactly the results without a network.

Conventions
-----------
Links
    A link is a pair (receiver i, informer k) with ``a_ik = 1``. Position and
    velocity travel as two streams per link, each with its own delay
    (``tau1`` family for positions, ``tau2`` for velocities, as in the paper),
    its own losses and its own noise. Delay matrices are indexed like the
    adjacency: entry ``[i, k]`` is the delay of what i receives from k.
Continuous and packet streams
    Without jitter, loss, sampling or noise a stream is continuous: agent i
    hears ``x_k(t - d_ik(t))``, read from the computed solution by the cubic
    Hermite interpolation of :mod:`delayform.simulation.delayed.integrator`, with
    ``d_ik(t)`` the link's constant delay plus its smooth variation (the
    delay is that of the value heard at time t). With any of the four, the
    stream is a sequence of packets: agent k samples its state at
    ``t_m = m / rate`` (``m = 0, 1, ...``; every integration step without a
    :class:`Sampling`), the packet takes ``d_ikm`` = link delay + smooth
    variation at ``t_m`` + jitter to arrive, may be lost, and carries the
    sample plus noise. Agent i holds the newest sample it has received (zero-
    order hold, hold-last-value); an older packet arriving late, after a newer
    one, is discarded.
Before the first packet
    An agent that has received nothing yet from an informer hears the
    informer's initial state, exactly (no noise): the same convention as the
    constant history before ``t = 0`` of the ideal simulation (paper,
    eq. 2). A stream whose every packet is lost therefore holds the
    informer's initial state for the whole run.
Noise
    Additive, Gaussian, independent per packet and stream (standard
    deviations :attr:`MeasurementNoise.position` in m and
    :attr:`MeasurementNoise.velocity` in m/s). It models the informer's
    measurement of its own state; the receiving agent's own position and
    velocity in the paper's eq. 1 are exact.
Step
    Every delay a stream can take (link delay, minus the largest negative
    jitter or variation) must be 0 (only for continuous streams: then the
    current value is used) or at least the step ``dt``, so that every value
    heard is already computed; otherwise :class:`NetworkError`.
Randomness
    Everything random (delays drawn around tau1 / tau2, the phases of the
    variation, jitter, losses, noise) comes from :attr:`Network.seed`
    through one ``numpy.random.SeedSequence`` split into one stream per
    part, so switching one part on does not change the draws of another.

Agent models
------------
Double integrators are integrated directly. The unicycle is the ideal robot
of Section "Feedback Linearization": under the paper's eq. 19 its position obeys
``x'' = u`` exactly, so its motion is that of the double integrator and its
heading, speed and commands ``(dv/dt, omega)`` are rebuilt from the velocity
and acceleration (:func:`delayform.simulation.models.robots.ideal_commands`), as for
ideal robots without a network. Robots with actuator limits integrate the
true unicycle (x, y, theta, v) with saturated inputs
(:class:`delayform.simulation.models.robots.LimitedUnicycle`) computed from what
each robot hears; they send their Cartesian position and velocity
``v (cos theta, sin theta)``, and the stated order is 2 as without a network.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from delayform._validation import check_magnitude, validated
from delayform.errors import NetworkError

__all__ = [
    "LinkDelays",
    "Jitter",
    "SmoothVariation",
    "BernoulliLoss",
    "GilbertElliott",
    "Sampling",
    "MeasurementNoise",
    "Network",
]

_Array = NDArray[np.float64]


# ------------------------------------------------------------------ checks
def _number(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise NetworkError(f"{name} must be a real number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise NetworkError(f"{name} must be finite, got {out}")
    return out


def _non_negative(name: str, value: object) -> float:
    out = _number(name, value)
    if out < 0.0:
        raise NetworkError(f"{name} must be non-negative, got {out:g}")
    return out


def _probability(name: str, value: object) -> float:
    out = _number(name, value)
    if not 0.0 <= out <= 1.0:
        raise NetworkError(f"{name} must be a probability in [0, 1], got {out:g}")
    return out


def _matrix(name: str, value: ArrayLike | None, *, probability: bool = False) -> _Array | None:
    if value is None:
        return None
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise NetworkError(f"{name} must be a square matrix of numbers") from None
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or arr.shape[0] == 0:
        raise NetworkError(f"{name} must be a square n x n matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise NetworkError(f"{name} must be finite")
    if np.any(arr < 0.0) or (probability and np.any(arr > 1.0)):
        what = "probabilities in [0, 1]" if probability else "non-negative"
        raise NetworkError(f"{name} must be {what}; found {arr.min() if np.any(arr < 0) else arr.max():g}")
    arr.flags.writeable = False
    return arr


def _links_of(adjacency: ArrayLike, n: int, name: str) -> NDArray[np.bool_]:
    """Boolean ``(n, n)`` mask of the links of an adjacency, after checking it matches an n x n matrix."""
    links = np.asarray(adjacency.toarray() if hasattr(adjacency, "toarray") else adjacency) != 0
    if links.shape != (n, n):
        raise NetworkError(f"{name} must be {links.shape[0]} x {links.shape[0]} (one entry per pair of agents), "
                           f"got {n} x {n}")  # fmt: skip
    return links & ~np.eye(n, dtype=bool)


def check_link_matrix(name: str, matrix: NDArray[np.float64], n: int) -> None:
    """A per-link matrix (delays, loss) must be n x n for a team of n agents.

    Parameters
    ----------
    name
        The setting, for the message (``"loss.probability"``).
    matrix
        The checked square matrix.
    n
        Number of agents.

    Raises
    ------
    NetworkError
        Another size: a smaller matrix leaves links without a value, a larger
        one describes agents the team does not have.
    """
    if matrix.shape != (n, n):
        raise NetworkError(f"{name} must be {n} x {n} (one entry per pair of agents), "
                           f"got {matrix.shape[0]} x {matrix.shape[1]}")  # fmt: skip


# ------------------------------------------------------------ the model
@validated(NetworkError)
@dataclass(frozen=True, eq=False)
class LinkDelays:
    """Constant delays that differ from link to link.

    Parameters
    ----------
    tau1, tau2
        ``(n, n)`` matrices of position and velocity delays (s), entry
        ``[i, k]`` for what agent i receives from agent k (entries off the
        links are ignored); None draws them around the tau1 / tau2 given to
        :func:`~delayform.simulation.simulate`.
    spread
        Relative half-width of the draw: each link's delay is
        ``tau (1 + spread U(-1, 1))``, from :attr:`Network.seed`; in [0, 1).

    >>> LinkDelays(spread=0.25).spread
    0.25
    """

    tau1: ArrayLike | None = None
    tau2: ArrayLike | None = None
    spread: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "tau1", _matrix("delays.tau1", self.tau1))
        object.__setattr__(self, "tau2", _matrix("delays.tau2", self.tau2))
        spread = _non_negative("delays.spread", self.spread)
        if spread >= 1.0:
            raise NetworkError(f"delays.spread must be below 1 (a delay cannot be negative), got {spread:g}")
        object.__setattr__(self, "spread", spread)

    @property
    def is_uniform(self) -> bool:
        """True when this changes nothing: no matrix and no spread."""
        return self.tau1 is None and self.tau2 is None and self.spread == 0.0


@validated(NetworkError)
@dataclass(frozen=True)
class Jitter:
    """Bounded random jitter: each packet's delay is the link's delay plus ``U(-bound, bound)``.

    Parameters
    ----------
    bound1, bound2
        Largest deviation (s) of a position / velocity packet's delay from
        the link's delay; the jitter is symmetric, so the mean delay stays
        the link's. Drawn independently per packet from :attr:`Network.seed`.
    """

    bound1: float = 0.0
    bound2: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "bound1", _non_negative("jitter.bound1", self.bound1))
        object.__setattr__(self, "bound2", _non_negative("jitter.bound2", self.bound2))

    @property
    def is_off(self) -> bool:
        """True when both bounds are zero."""
        return self.bound1 == 0.0 and self.bound2 == 0.0


@validated(NetworkError)
@dataclass(frozen=True)
class SmoothVariation:
    """Delays that vary smoothly: ``d(t) = d_link + amplitude sin(2 pi t / period + phase_link)``.

    Parameters
    ----------
    amplitude1, amplitude2
        Amplitudes (s) for positions and velocities.
    period
        Period (s) of the variation; each link has its own random phase
        (from :attr:`Network.seed`). The delay's rate of change
        ``2 pi amplitude / period`` must stay below 1, or newer values would
        be heard before older ones.
    """

    amplitude1: float = 0.0
    amplitude2: float = 0.0
    period: float = 10.0

    def __post_init__(self) -> None:
        for name in ("amplitude1", "amplitude2"):
            object.__setattr__(self, name, _non_negative(f"variation.{name}", getattr(self, name)))
        period = _number("variation.period", self.period)
        if period <= 0.0:
            raise NetworkError(f"variation.period must be positive, got {period:g}")
        object.__setattr__(self, "period", period)
        rate = 2.0 * math.pi * max(self.amplitude1, self.amplitude2) / period
        if rate >= 1.0:
            raise NetworkError(
                f"variation: the delay would change at rate {rate:.3g} s/s (2 pi amplitude / period); it must stay below 1"
            )

    @property
    def is_off(self) -> bool:
        """True when both amplitudes are zero."""
        return self.amplitude1 == 0.0 and self.amplitude2 == 0.0


@validated(NetworkError)
@dataclass(frozen=True, eq=False)
class BernoulliLoss:
    """Independent packet loss: each packet is lost with ``probability``.

    Parameters
    ----------
    probability
        A probability in [0, 1], or an ``(n, n)`` matrix of them, entry
        ``[i, k]`` for the link from k to i (e.g. a row of ones cuts agent i off).
    """

    probability: float | ArrayLike = 0.0

    def __post_init__(self) -> None:
        if np.ndim(self.probability) == 0:
            object.__setattr__(self, "probability", _probability("loss.probability", self.probability))
        else:
            object.__setattr__(self, "probability", _matrix("loss.probability", self.probability, probability=True))

    @property
    def is_off(self) -> bool:
        """True when no packet can be lost."""
        return not np.any(np.asarray(self.probability) > 0.0)

    @property
    def loss_rate(self) -> float:
        """Long-run fraction of lost packets: the probability, or a matrix's mean over its off-diagonal entries.

        A matrix's entries off the links change nothing; :meth:`link_loss_rate`
        averages over the links of a topology only.
        """
        p = self.probability
        if not isinstance(p, np.ndarray):
            return float(p)
        n = p.shape[0]
        return float(p[~np.eye(n, dtype=bool)].mean()) if n > 1 else 0.0

    def link_loss_rate(self, adjacency: ArrayLike) -> float:
        """Long-run fraction of lost packets over the links ``a_ik = 1`` of an adjacency (module doc, Links).

        Parameters
        ----------
        adjacency
            The ``(n, n)`` adjacency of the team (row i: what agent i receives).

        >>> BernoulliLoss([[0, 1], [0.5, 0]]).link_loss_rate([[0, 0], [1, 0]])
        0.5
        """
        p = self.probability
        if not isinstance(p, np.ndarray):
            return float(p)
        links = _links_of(adjacency, p.shape[0], "loss.probability")
        return float(p[links].mean()) if links.any() else 0.0


@validated(NetworkError)
@dataclass(frozen=True)
class GilbertElliott:
    """Bursty loss: a two-state Markov chain per stream (Gilbert-Elliott channel).

    In the good state a packet is lost with ``loss_good``, in the bad state
    with ``loss_bad``; after each packet the chain moves good -> bad with
    ``p_good_to_bad`` and bad -> good with ``p_bad_to_good``. Each stream
    starts in the chain's stationary distribution.

    Parameters
    ----------
    p_good_to_bad, p_bad_to_good
        Transition probabilities per packet. The mean burst length is
        ``1 / p_bad_to_good`` packets. ``p_bad_to_good = 0`` is allowed, as
        Bernoulli loss 1 is: the bad state is then absorbing, its stationary
        probability is 1 (with ``p_good_to_bad > 0``) and every stream is in it
        from the first packet, i.e. Bernoulli loss ``loss_bad``. With both
        probabilities 0 the chain never moves; every stream stays in the good
        state (Bernoulli loss ``loss_good``).
    loss_good, loss_bad
        Loss probabilities in each state.

    >>> round(GilbertElliott(0.05, 0.2).loss_rate, 3)
    0.2
    """

    p_good_to_bad: float
    p_bad_to_good: float
    loss_good: float = 0.0
    loss_bad: float = 1.0

    def __post_init__(self) -> None:
        for name in ("p_good_to_bad", "p_bad_to_good", "loss_good", "loss_bad"):
            object.__setattr__(self, name, _probability(f"loss.{name}", getattr(self, name)))

    @property
    def bad_fraction(self) -> float:
        """Stationary probability of the bad state (0 for a chain that never moves, class doc)."""
        moves = self.p_good_to_bad + self.p_bad_to_good
        return self.p_good_to_bad / moves if moves > 0.0 else 0.0

    @property
    def loss_rate(self) -> float:
        """Long-run fraction of lost packets."""
        b = self.bad_fraction
        return (1.0 - b) * self.loss_good + b * self.loss_bad

    @property
    def is_off(self) -> bool:
        """True when no packet can be lost."""
        return self.loss_rate == 0.0 and self.loss_good == 0.0


@validated(NetworkError)
@dataclass(frozen=True)
class Sampling:
    """Sampled transmission: every agent sends its state ``rate`` times per second (zero-order hold).

    Parameters
    ----------
    rate
        Packets per second and stream, positive; the samples are taken at
        ``m / rate`` by all agents alike.
    """

    rate: float

    def __post_init__(self) -> None:
        rate = _number("sampling.rate", self.rate)
        if rate <= 0.0:
            raise NetworkError(f"sampling.rate must be positive (packets per second), got {rate:g}")
        object.__setattr__(self, "rate", rate)


@validated(NetworkError)
@dataclass(frozen=True)
class MeasurementNoise:
    """Additive Gaussian noise on what is sent: standard deviations per coordinate.

    Parameters
    ----------
    position
        Standard deviation (m) added to each coordinate of a sent position.
    velocity
        Standard deviation (m/s) added to each coordinate of a sent velocity.
    """

    position: float = 0.0
    velocity: float = 0.0

    def __post_init__(self) -> None:
        for name, unit in (("position", "m"), ("velocity", "m/s")):
            value = _non_negative(f"noise.{name}", getattr(self, name))
            # a deviation beyond the largest position or speed the simulator takes means nothing
            check_magnitude(f"noise.{name}", np.array([value]), NetworkError, unit)
            object.__setattr__(self, name, value)

    @property
    def is_off(self) -> bool:
        """True when both deviations are zero."""
        return self.position == 0.0 and self.velocity == 0.0


@validated(NetworkError)
@dataclass(frozen=True, eq=False)
class Network:
    """An imperfect communication network for :func:`~delayform.simulation.simulate` (module doc).

    Parameters
    ----------
    delays
        Per-link constant delays (:class:`LinkDelays`); None: every link has tau1, tau2.
    variation
        Smooth variation of every link's delays (:class:`SmoothVariation`).
    jitter
        Bounded random jitter per packet (:class:`Jitter`).
    loss
        Packet loss, :class:`BernoulliLoss` or :class:`GilbertElliott`.
    sampling
        Sampled transmission at a rate (:class:`Sampling`); None: a packet
        per integration step when packets are needed.
    noise
        Additive measurement noise (:class:`MeasurementNoise`).
    seed
        Non-negative integer seed of everything random in the network.

    Examples
    --------
    >>> Network().is_ideal
    True
    >>> Network(loss=BernoulliLoss(0.3), seed=4).is_ideal
    False
    """

    delays: LinkDelays | None = None
    variation: SmoothVariation | None = None
    jitter: Jitter | None = None
    loss: BernoulliLoss | GilbertElliott | None = None
    sampling: Sampling | None = None
    noise: MeasurementNoise | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        kinds: dict[str, tuple[type, ...]] = {
            "delays": (LinkDelays,), "variation": (SmoothVariation,), "jitter": (Jitter,),
            "loss": (BernoulliLoss, GilbertElliott), "sampling": (Sampling,), "noise": (MeasurementNoise,),
        }  # fmt: skip
        for name, types in kinds.items():
            value = getattr(self, name)
            if value is not None and not isinstance(value, types):
                expected = " or ".join(t.__name__ for t in types)
                raise NetworkError(f"network.{name} must be a {expected}, got {type(value).__name__}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, numbers.Integral) or self.seed < 0:
            raise NetworkError(f"network.seed must be a non-negative integer, got {self.seed!r}")
        object.__setattr__(self, "seed", int(self.seed))

    @property
    def packets(self) -> bool:
        """True when streams are packets (jitter, loss, sampling or noise is on)."""
        return not (
            (self.jitter is None or self.jitter.is_off)
            and (self.loss is None or self.loss.is_off)
            and self.sampling is None
            and (self.noise is None or self.noise.is_off)
        )

    @property
    def is_ideal(self) -> bool:
        """True when the network is the paper's: constant delays tau1, tau2 on every link."""
        return (
            not self.packets
            and (self.delays is None or self.delays.is_uniform)
            and (self.variation is None or self.variation.is_off)
        )

    def with_seed(self, seed: int) -> Network:
        """A copy with another seed (Monte Carlo runs).

        Parameters
        ----------
        seed
            Non-negative integer.
        """
        return replace(self, seed=seed)

    def describe(self, adjacency: ArrayLike | None = None) -> str:
        """One line for tables and titles.

        Parameters
        ----------
        adjacency
            The team's adjacency: a loss matrix is then summarised by its
            mean over the links only (entries off the links change nothing).
        """
        parts = []
        if self.delays is not None and not self.delays.is_uniform:
            parts.append("per-link delays" + (f" (spread {self.delays.spread:g})" if self.delays.spread else ""))
        if self.variation is not None and not self.variation.is_off:
            v = self.variation
            parts.append(f"variation +-({v.amplitude1:g}, {v.amplitude2:g}) s over {v.period:g} s")
        if self.jitter is not None and not self.jitter.is_off:
            parts.append(f"jitter +-({self.jitter.bound1:g}, {self.jitter.bound2:g}) s")
        if isinstance(self.loss, BernoulliLoss) and not self.loss.is_off:
            rate = self.loss.loss_rate if adjacency is None else self.loss.link_loss_rate(adjacency)
            per_link = isinstance(self.loss.probability, np.ndarray)
            parts.append(f"loss {rate:.3g}" + (" (mean over the links)" if per_link and adjacency is not None else ""))
        elif isinstance(self.loss, GilbertElliott) and not self.loss.is_off:
            g = self.loss
            bursts = f"bursts of {1 / g.p_bad_to_good:.3g}" if g.p_bad_to_good > 0 else "a burst never ends"
            parts.append(f"bursty loss {g.loss_rate:.3g} ({bursts})")
        if self.sampling is not None:
            parts.append(f"sampled at {self.sampling.rate:g} Hz")
        if self.noise is not None and not self.noise.is_off:
            parts.append(f"noise ({self.noise.position:g} m, {self.noise.velocity:g} m/s)")
        return ", ".join(parts) if parts else "ideal"


