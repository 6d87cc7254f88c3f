"""What the scenario's network does to each real state message: the simulator's draws, link by link, packet by packet.

A fleet run applies the network at the receiving side, where a real one
acts: robot i, on taking robot k's state message, looks up what the
simulator's network (:mod:`delayform.simulation.delayed.reception`) does to the
same packet on the link ``i <- k`` and hands the controller the message with
those delays, or not at all. The draws are the simulator's, from the same
seed: one ``numpy.random.SeedSequence(seed)`` split into five streams (link
delays, phases of the variation, jitter, loss, noise), each drawn in the
order and shape the simulator draws it, so that a run of ``simulate`` with
the same network, step and duration loses, delays and disturbs the same
packets on the same links (``tests/test_fleet_links.py`` checks it against
:func:`~delayform.simulation.delayed.reception.reception`).

Packets
    Packet m of a stream is the informer's state sampled at ``m p``, with p
    the sampling period (``1 / rate``), else the simulator's step: a robot's
    state message stamped t is packet ``floor(t / p)``.
Delays
    Each link's delay pair: the network's matrices, else (tau1, tau2), drawn
    around them with the spread. With jitter, packet m of stream s is
    delayed by the link's delay plus ``bound_s U(-1, 1)``. The position and
    the velocity of a message travel as two streams, each with its own delay.
Variation
    Delays that vary smoothly in time (:class:`~delayform.model.network.SmoothVariation`),
    each link with the phase the simulator draws for it. With packets, packet m
    is delayed by ``amplitude sin(2 pi m p / period + phase)`` more, as the
    simulator delays it. Without packets the simulator hears ``x(t - d(t))``
    at every time t: the value sent at s is heard when ``t - d(t) = s``, one
    time since the delay changes at a rate below 1, found by Newton's method;
    packet m is delayed by that ``t - s`` (``tests/test_fleet_links.py`` checks
    the value heard at every stage time against the simulator's).
Loss
    A stream's packet the network loses never becomes usable: its delay is
    infinite (the message may still carry the other stream).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from delayform.errors import FleetError
from delayform.model.network import Network, SmoothVariation, check_link_matrix
from delayform.simulation.delayed.reception import packet_draws
from delayform.topology import Topology

__all__ = ["LinkPlan", "link_plan", "packet_count"]

_Array = NDArray[np.float64]

#: the simulator's random streams, in the order it splits its seed (module doc)
_STREAMS = 5
_DELAY_STREAM, _PHASE_STREAM, _JITTER_STREAM = 0, 1, 2


def packet_count(duration: float, dt: float, period: float) -> int:
    """Packets per stream the simulator draws for a run of ``duration`` at step ``dt``, a packet every ``period``.

    Parameters
    ----------
    duration, dt, period
        Seconds: the run, the simulator's step, the packet period.
    """
    steps = max(1, math.ceil(duration / dt - 1e-9))  # as simulate counts its steps
    return math.floor((steps + 1) * dt / period + 1e-9) + 1


@dataclass(frozen=True, eq=False)
class LinkPlan:
    """The network's draws for every link (module doc), in the simulator's link order.

    Attributes
    ----------
    receivers, informers
        ``(E,)`` robot indices from 0 of each link (i hears k).
    tau1, tau2
        ``(E,)`` each link's constant delays (s).
    period
        Packet period (s): the sampling period, or the simulator's step.
    jitter
        ``(2, packets, E)`` what packet m of stream s on link e takes beyond
        the link's delay (s): its jitter and the delays' variation; or None.
    lost
        ``(2, packets, E)`` True where the network loses that packet, or None.
    noise
        ``(2, packets, E, 2)`` the noise a packet carries (m, m/s), or None.
    """

    receivers: NDArray[np.intp]
    informers: NDArray[np.intp]
    tau1: _Array
    tau2: _Array
    period: float
    jitter: _Array | None
    lost: NDArray[np.bool_] | None
    noise: _Array | None

    def delay_matrices(self, n: int) -> tuple[_Array, _Array]:
        """The links' delays as two ``(n, n)`` matrices (zero off the links)."""
        out = []
        for d in (self.tau1, self.tau2):
            m = np.zeros((n, n))
            m[self.receivers, self.informers] = d
            out.append(m)
        return out[0], out[1]

    def of_receiver(self, robot: int) -> NDArray[np.intp]:
        """The link numbers robot ``robot`` (from 1) receives on."""
        return np.flatnonzero((self.receivers == robot - 1) & (self.informers != robot - 1))


def _link_delays(network: Network, topology: Topology, rows: NDArray[np.intp], cols: NDArray[np.intp],
                 tau1: float, tau2: float) -> tuple[_Array, _Array]:  # fmt: skip
    """Each link's delay pair, drawn from the delay stream of the seed as the simulator draws it."""
    spec = network.delays
    rng = np.random.default_rng(np.random.SeedSequence(network.seed).spawn(_STREAMS)[_DELAY_STREAM])
    pairs = []
    for s, nominal in enumerate((tau1, tau2)):
        given = None if spec is None else (spec.tau1, spec.tau2)[s]
        u = rng.uniform(-1.0, 1.0, size=rows.size)  # one draw per stream whether or not a spread uses it
        if given is not None:
            check_link_matrix(f"delays.tau{s + 1}", given, topology.n)
            pairs.append(np.asarray(given, dtype=np.float64)[rows, cols])
        elif spec is not None and spec.spread > 0.0:
            pairs.append(nominal * (1.0 + spec.spread * u))
        else:
            pairs.append(np.full(rows.size, float(nominal)))
    return pairs[0], pairs[1]


def link_plan(network: Network, topology: Topology, tau1: float, tau2: float, *, dt: float, duration: float) -> LinkPlan:
    """The draws of ``simulate(..., network=network, dt=dt, duration=duration)`` for real messages (module doc).

    Parameters
    ----------
    network
        The scenario's network.
    topology
        Who hears whom.
    tau1, tau2
        The nominal delays (s): every link's unless the network says otherwise.
    dt
        The simulator's step (s): the packet period when the network does not sample.
    duration
        The run's duration (s).

    """
    C = topology.C_sparse.tocoo()
    order = np.lexsort((C.col, C.row))  # the simulator's link order: by receiver, then informer
    rows, cols = C.row[order].astype(np.intp), C.col[order].astype(np.intp)
    d1, d2 = _link_delays(network, topology, rows, cols, tau1, tau2)
    period = dt if network.sampling is None else 1.0 / network.sampling.rate
    packets = packet_count(duration, dt, period)
    jitter = lost = noise = None
    if network.packets:
        if network.jitter is not None and not network.jitter.is_off:
            rng = np.random.default_rng(np.random.SeedSequence(network.seed).spawn(_STREAMS)[_JITTER_STREAM])
            # the position stream's draws first, then the velocity stream's, each (packets, E)
            u = np.stack([rng.uniform(-1.0, 1.0, size=(packets, rows.size)) for _ in range(2)])
            jitter = np.array([network.jitter.bound1, network.jitter.bound2])[:, None, None] * u
        draws = packet_draws(network, topology, packets=packets)
        if not (np.array_equal(draws.receivers, rows) and np.array_equal(draws.informers, cols)):
            raise FleetError("internal: the simulator's link order changed")  # a guard, checked by the tests
        lost, noise = draws.lost, draws.noise
    variation = network.variation
    if variation is not None and not variation.is_off:
        extra = _variation(variation, network.seed, (d1, d2), period, packets, packets_on=network.packets)
        jitter = extra if jitter is None else jitter + extra
    return LinkPlan(receivers=rows, informers=cols, tau1=d1, tau2=d2, period=period, jitter=jitter, lost=lost, noise=noise)


def _variation(variation: SmoothVariation, seed: int | None, delays: tuple[_Array, _Array], period: float,
               packets: int, *, packets_on: bool) -> _Array:  # fmt: skip
    """``(2, packets, E)``: what the smooth variation adds to packet m's delay on each link (module doc, Variation)."""
    E = delays[0].size
    phases = np.random.default_rng(np.random.SeedSequence(seed).spawn(_STREAMS)[_PHASE_STREAM]).uniform(
        0.0, 2.0 * math.pi, size=(2, E))  # the simulator's draw, in its shape
    sent = np.arange(packets, dtype=np.float64)[:, None] * period
    omega = 2.0 * math.pi / variation.period
    out = np.zeros((2, packets, E))
    for s, amp in enumerate((variation.amplitude1, variation.amplitude2)):
        if amp == 0.0:
            continue
        if packets_on:  # the simulator delays packet m by the variation at its sampling time
            out[s] = amp * np.sin(omega * sent + phases[s])
            continue
        # heard at t with t - d(t) = sent: f(t) = t - base - amp sin(omega t + phase) - sent increases
        # (slope 1 - amp omega cos(.) >= 1 - amp omega > 0) and changes sign on [sent + base -+ amp]:
        # Newton's method kept inside that bracket (a step out of it bisects), to steps below 1e-13 s
        base = np.broadcast_to(delays[s][None, :], (packets, E))
        lo, hi = sent + base - amp, sent + base + amp
        t = sent + base
        for _ in range(200):
            f = t - base - amp * np.sin(omega * t + phases[s]) - sent
            lo, hi = np.where(f < 0.0, t, lo), np.where(f > 0.0, t, hi)
            newton = t - f / (1.0 - amp * omega * np.cos(omega * t + phases[s]))
            nxt = np.where((newton > lo) & (newton < hi), newton, 0.5 * (lo + hi))
            done = np.max(np.abs(nxt - t)) < 1e-13
            t = nxt
            if done:
                break
        else:  # not reached: a bracket halves at the least at every step
            raise FleetError("internal: the varying delays' reception times did not converge")
        out[s] = t - sent - base
    return out
