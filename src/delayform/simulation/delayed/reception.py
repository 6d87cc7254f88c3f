"""What each agent hears over an imperfect network, and the integrator that uses it.

:func:`reception` turns a :class:`~delayform.model.network.Network` into
the send time of every value each agent hears at every RK4 stage time
(the conventions are those of :mod:`delayform.model.network`: continuous
streams read ``t - d(t)``, packet streams hold the newest packet received,
the initial state before the first one). :func:`integrate_network` runs
the paper's eq. 1 plus the forcing of the paper's eq. 13 on those values for any
agent model (double integrators, or robots with actuator limits), with the
step of :mod:`delayform.simulation.delayed.integrator` (classical RK4, cubic Hermite
reads of the computed solution), so that with every link at (tau1, tau2) it
is the ordinary integrator up to rounding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from delayform.errors import NetworkError
from delayform.resources import require
from delayform.simulation.delayed.actuation import CommandBuffer
from delayform.simulation.delayed.integrator import Agent, Progress, Samples
from delayform.model.network import BernoulliLoss, GilbertElliott, Network, check_link_matrix
from delayform.topology import Topology

__all__ = ["Reception", "reception", "integrate_network", "network_memory", "packet_draws", "PacketDraws"]

_Array = NDArray[np.float64]

#: stage times of one RK4 step, as fractions of dt (stages 2 and 3 share the middle)
_SUBSTEPS = (0.0, 0.5, 1.0)

#: teams up to this size sum what they hear with a dense matrix
_DENSE_AGENTS = 64

#: a run stops when a position leaves this many times the initial scale
_BLOWUP = 1e8


# ------------------------------------------------------------ reception
@dataclass(frozen=True, eq=False)
class Reception:
    """What every agent hears, as send times: the schedule :func:`integrate_network` reads.

    For stream s (0: positions, 1: velocities), step k, sub-time j (the RK4
    stage times ``t_k``, ``t_k + dt/2``, ``t_k + dt``) and link e,
    ``send[s][k, j, e]`` is the time at which the value heard was sent
    (the informer's state at that time is heard): ``t - d(t)`` for a
    continuous stream, the sample time of the newest packet received for a
    packet stream, and 0 (the initial state) before the first packet.

    Attributes
    ----------
    receivers, informers
        ``(E,)`` agent indices of each link (i hears k).
    weights
        ``(E,)`` entries ``C_ik`` of the paper's eq. 1.
    dt
        The integration step.
    send
        Two ``(steps + 1, 3, E)`` arrays of send times.
    packet
        Two ``(steps + 1, 3, E)`` arrays of the packet index heard (-1: none
        yet, or a continuous stream).
    current
        Two ``(E,)`` masks of continuous zero-delay streams (the current value is heard).
    noise
        Two ``(packets, E, 2)`` arrays of the noise each packet carries, or None.
    """

    receivers: NDArray[np.intp]
    informers: NDArray[np.intp]
    weights: _Array
    dt: float
    send: tuple[_Array, _Array]
    packet: tuple[NDArray[np.intp], NDArray[np.intp]]
    current: tuple[NDArray[np.bool_], NDArray[np.bool_]]
    noise: tuple[_Array | None, _Array | None] = field(default=(None, None))


def network_memory(n_links: int, steps: int, packets: int, n: int) -> float:
    """Rough peak memory (bytes) of :func:`integrate_network`.

    Parameters
    ----------
    n_links
        Number of links (edges) of the topology.
    steps
        Integration steps.
    packets
        Packets per stream (0 for continuous streams).
    n
        Number of agents.
    """
    per_query = 2 * 3 * (steps + 1) * n_links * (8 + 8 + 8 + 4 * 8 + 2 * 8)  # send, packet, index, weights, noise
    per_packet = 2 * packets * n_links * (8 * 6)  # arrival, order, noise, loss
    return float(per_query + per_packet + 3 * (steps + 2) * n * 2 * 8)


def _check_memory(network: Network, topology: Topology, dt: float, steps: int) -> None:
    """Refuse, in one line, a run whose schedules would not fit this machine (:mod:`delayform.resources`)."""
    packets = 0
    if network.packets:
        period = dt if network.sampling is None else 1.0 / network.sampling.rate
        packets = int((steps + 1) * dt / period) + 2
    need = network_memory(int(topology.adjacency_sparse.nnz), steps, packets, topology.n)
    require(what="a run over this network", setting="the duration, dt or the sampling rate", nbytes=need)


def _links(topology: Topology) -> tuple[NDArray[np.intp], NDArray[np.intp], _Array]:
    C = topology.C_sparse.tocoo()
    order = np.lexsort((C.col, C.row))
    return C.row[order].astype(np.intp), C.col[order].astype(np.intp), C.data[order].astype(np.float64)


def _link_delays(
    network: Network, rows: NDArray[np.intp], cols: NDArray[np.intp], n: int, taus: tuple[float, float], rng: np.random.Generator
) -> tuple[_Array, _Array]:
    spec = network.delays
    out = []
    for s, tau in enumerate(taus):
        matrix = None if spec is None else (spec.tau1, spec.tau2)[s]
        if matrix is not None:
            check_link_matrix(f"delays.tau{s + 1}", matrix, n)
            d = matrix[rows, cols].astype(np.float64)
        else:
            d = np.full(rows.size, tau)
        draw = rng.uniform(-1.0, 1.0, size=rows.size)  # drawn always: the stream does not depend on spread
        if spec is not None and matrix is None and spec.spread > 0.0:
            d = d * (1.0 + spec.spread * draw)
        out.append(d)
    return out[0], out[1]


def _loss_mask(
    loss: BernoulliLoss | GilbertElliott | None, rows: NDArray[np.intp], cols: NDArray[np.intp], packets: int, rng: np.random.Generator
) -> NDArray[np.bool_] | None:
    """``(packets, E)`` True where a packet is lost; None when nothing is lost."""
    if loss is None or loss.is_off:
        return None
    E = rows.size
    if isinstance(loss, BernoulliLoss):
        p = loss.probability
        p_link = p[rows, cols] if isinstance(p, np.ndarray) else np.full(E, p)
        return rng.random((packets, E)) < p_link
    # Gilbert-Elliott: one chain per stream, started in its stationary distribution.
    u_state = rng.random((packets, E))
    u_loss = rng.random((packets, E))
    bad = u_state[0] < loss.bad_fraction
    lost = np.empty((packets, E), dtype=bool)
    for m in range(packets):
        lost[m] = u_loss[m] < np.where(bad, loss.loss_bad, loss.loss_good)
        if m + 1 < packets:
            flip = u_state[m + 1] < np.where(bad, loss.p_bad_to_good, loss.p_good_to_bad)
            bad = bad ^ flip
    return lost


@dataclass(frozen=True, eq=False)
class PacketDraws:
    """Which packets a network loses and the noise each carries: the draws of :func:`reception`.

    Attributes
    ----------
    receivers, informers
        ``(E,)`` agent indices of each link (i hears k), in :func:`reception`'s order.
    lost
        ``(2, packets, E)``: True where packet m of stream s (0: positions,
        1: velocities) on link e is lost; None when nothing is lost.
    noise
        ``(2, packets, E, 2)``: the noise packet m of stream s carries on link
        e (m or m/s per coordinate); None without noise.
    """

    receivers: NDArray[np.intp]
    informers: NDArray[np.intp]
    lost: NDArray[np.bool_] | None
    noise: _Array | None


def packet_draws(network: Network, topology: Topology, *, packets: int) -> PacketDraws:
    """The losses and noise :func:`reception` draws, for packets that travel elsewhere (real messages).

    A run of ``simulate(..., network=network, dt=dt, duration=T)`` whose streams
    are packets draws them for ``packets = floor((steps + 1) dt / period) + 1``
    packets per stream (``steps = T / dt``, ``period`` the sampling period, or
    dt): with that count and the same seed the masks and the noise are the
    simulator's, packet for packet and link for link, so a team of real
    processes can lose the messages the simulator loses.

    Parameters
    ----------
    network
        The network (its ``loss``, ``noise`` and ``seed`` are used).
    topology
        Who hears whom: the links, in the order :func:`reception` uses.
    packets
        Packets per stream.
    """
    if isinstance(network.loss, BernoulliLoss) and isinstance(network.loss.probability, np.ndarray):
        check_link_matrix("loss.probability", network.loss.probability, topology.n)
    rows, cols, _ = _links(topology)
    seeds = np.random.SeedSequence(network.seed).spawn(5)  # reception's streams: the fourth loses, the fifth adds noise
    rng_loss, rng_noise = np.random.default_rng(seeds[3]), np.random.default_rng(seeds[4])
    masks = [_loss_mask(network.loss, rows, cols, packets, rng_loss) for _ in range(2)]
    sigmas = (0.0, 0.0) if network.noise is None else (network.noise.position, network.noise.velocity)
    draws = [rng_noise.standard_normal((packets, rows.size, 2)) for _ in range(2)]  # drawn always, as reception
    noise = None if not any(sigmas) else np.stack([sigma * d for sigma, d in zip(sigmas, draws)])
    return PacketDraws(receivers=rows, informers=cols, lost=None if masks[0] is None else np.stack(masks), noise=noise)


def _packet_causes(network: Network) -> str:
    """What makes the streams packets, in words: "packet loss", "sampling", ... (only what is set)."""
    causes = [("jitter", network.jitter is not None and not network.jitter.is_off),
              ("packet loss", network.loss is not None and not network.loss.is_off),
              ("sampling", network.sampling is not None),
              ("noise", network.noise is not None and not network.noise.is_off)]  # fmt: skip
    return " and ".join(w for w, on in causes if on)


def _check_delay_floor(stream: int, base: float, amplitude: float, bound: float, dt: float, *,
                       packets: str, per_link: bool) -> None:  # fmt: skip
    """The rule "every delay minus its jitter and variation >= dt", stated with only the parts that are set.

    Every value an agent hears is read from the computed solution, so it must
    be at least one step old (a continuous stream may also have delay exactly
    0: the current value). ``base`` is the shortest link delay of the stream,
    ``amplitude`` and ``bound`` its variation and jitter (0 when not set);
    ``packets`` says what makes the streams packets ("" for continuous ones).
    """
    name, tau = ("position", "tau1") if stream == 0 else ("velocity", "tau2")
    if per_link:  # LinkDelays: the shortest link's delay, not tau itself
        tau = f"the shortest {name} link delay"
    shortest = base - amplitude - bound
    if not packets and base == 0.0 and amplitude == 0.0:
        return
    if shortest >= dt * (1.0 - 1e-9):
        return
    cut = [(w, v) for w, v in (("variation", amplitude), ("jitter", bound)) if v > 0.0]
    if cut:
        terms = " - ".join([f"{tau} {base:g} s"] + [f"{w} {v:g} s" for w, v in cut])
        words = [w for w, _ in cut]
        raise NetworkError(
            f"a {name} delay can fall to {terms} = {shortest:.3g} s, below the step dt = {dt:g} s "
            f"(every delay minus its {' and '.join(words)} must be >= dt); reduce the {' or '.join(words)}, "
            f"raise {tau} or choose a smaller dt"
        )
    why = f"with {packets} on, values travel as packets, and a packet is" if packets else "a non-zero delay is"
    fix = f"raise {tau} to >= {dt:g} s" + (f" or choose dt <= {base:g} s" if base > 0.0 else "")
    what = tau if per_link else f"the {name} delay {tau}"
    raise NetworkError(
        f"{what} = {base:g} s is below the step dt = {dt:g} s: {why} heard at the earliest "
        f"one step after being sent (every delay must be >= dt); {fix}"
    )


def reception(
    network: Network, topology: Topology, tau1: float, tau2: float, *, dt: float, steps: int
) -> Reception:
    """The send time of every value each agent hears, at every RK4 stage time (module doc).

    Parameters
    ----------
    network
        The imperfect network.
    topology
        Who hears whom; links are the non-zero entries of C.
    tau1, tau2
        Nominal delays (s) of positions and velocities: every link's, unless
        ``network.delays`` gives a matrix or a spread.
    dt
        Integration step (s).
    steps
        Number of steps; stage times run to ``steps dt + dt``.

    Returns
    -------
    Reception

    Raises
    ------
    NetworkError
        For a delay matrix of the wrong size, or delays that jitter or
        variation could make negative or shorter than ``dt``.
    """
    if isinstance(network.loss, BernoulliLoss) and isinstance(network.loss.probability, np.ndarray):
        check_link_matrix("loss.probability", network.loss.probability, topology.n)
    rows, cols, weights = _links(topology)
    E = rows.size
    seeds = np.random.SeedSequence(network.seed).spawn(5)
    rng_delay, rng_phase, rng_jitter, rng_loss, rng_noise = (np.random.default_rng(s) for s in seeds)
    d_link = _link_delays(network, rows, cols, topology.n, (tau1, tau2), rng_delay)
    variation = network.variation if network.variation is not None and not network.variation.is_off else None
    amplitudes = (0.0, 0.0) if variation is None else (variation.amplitude1, variation.amplitude2)
    phases = rng_phase.uniform(0.0, 2.0 * math.pi, size=(2, E))
    jitter = network.jitter if network.jitter is not None and not network.jitter.is_off else None
    bounds = (0.0, 0.0) if jitter is None else (jitter.bound1, jitter.bound2)
    packets_on = network.packets
    causes = _packet_causes(network)
    per_link = network.delays is not None and not network.delays.is_uniform

    k = np.arange(steps + 1, dtype=np.float64)[:, None, None]
    c = np.array(_SUBSTEPS)[None, :, None]
    send: list[_Array] = []
    packet: list[NDArray[np.intp]] = []
    current: list[NDArray[np.bool_]] = []
    noise: list[_Array | None] = []
    period = dt if network.sampling is None else 1.0 / network.sampling.rate
    n_packets = math.floor((steps + 1) * dt / period + 1e-9) + 1
    sample_times = np.arange(n_packets) * period
    sigmas = (0.0, 0.0) if network.noise is None else (network.noise.position, network.noise.velocity)
    for s in range(2):
        name = ("position", "velocity")[s]
        base = d_link[s]
        amp = amplitudes[s]
        if not packets_on:
            zero = (base == 0.0) & (amp == 0.0)
            if np.any(~zero):
                _check_delay_floor(s, float(base[~zero].min()), amp, 0.0, dt, packets="", per_link=per_link)
            # relative position m = c - d(t) / dt of the value heard, in steps from t_k (as in integrator._lookup)
            t = (k + c) * dt
            d = base[None, None, :] + (amp * np.sin(2.0 * math.pi * t / variation.period + phases[s]) if amp else 0.0)
            send.append(t - d)
            packet.append(np.full(send[-1].shape, -1, dtype=np.intp))
            current.append(zero)
            noise.append(None)
            continue
        _check_delay_floor(s, float(base.min()), amp, bounds[s], dt, packets=causes, per_link=per_link)
        delay = np.broadcast_to(base, (n_packets, E)).copy()
        if amp:
            delay += amp * np.sin(2.0 * math.pi * sample_times[:, None] / variation.period + phases[s])
        jit = rng_jitter.uniform(-1.0, 1.0, size=(n_packets, E))  # drawn always, for stable streams
        if bounds[s]:
            delay += bounds[s] * jit
        arrival = sample_times[:, None] + delay
        lost = _loss_mask(network.loss, rows, cols, n_packets, rng_loss)
        draws = rng_noise.standard_normal((n_packets, E, 2))
        noise.append(sigmas[s] * draws if sigmas[s] > 0.0 else None)
        queries = ((k + c) * dt).reshape(-1)
        heard = np.empty((queries.size, E), dtype=np.intp)
        index = np.arange(n_packets)
        for e in range(E):
            order = np.argsort(arrival[:, e], kind="stable")
            received = index[order] if lost is None else np.where(lost[order, e], -1, index[order])
            newest = np.maximum.accumulate(received)
            # a packet arriving exactly at a stage time is heard then (tolerance: rounding of t_m + d)
            pos = np.searchsorted(arrival[order, e], queries + 1e-9 * dt, side="right") - 1
            heard[:, e] = np.where(pos >= 0, newest[np.maximum(pos, 0)], -1)
        heard = heard.reshape(steps + 1, 3, E)
        packet.append(heard)
        send.append(np.where(heard >= 0, sample_times[np.maximum(heard, 0)], 0.0))
        current.append(np.zeros(E, dtype=bool))
    return Reception(
        receivers=rows, informers=cols, weights=weights, dt=dt,
        send=(send[0], send[1]), packet=(packet[0], packet[1]),
        current=(current[0], current[1]), noise=(noise[0], noise[1]),
    )  # fmt: skip


# ------------------------------------------------------------ integration
def _hermite_reads(send: _Array, dt: float, n: int, informers: NDArray[np.intp]) -> tuple[NDArray[np.intp], _Array]:
    """Flat row indices ``(steps+1, 3, E)`` of the left grid point and the Hermite weights ``(4, ...)``.

    Mirrors ``integrator._lookup`` / ``_History.read``: a value within 1e-9 step of a
    grid point is read there; an interval that ends at or before t = 0 lies in
    the constant history and reads its value.
    """
    k = np.arange(send.shape[0], dtype=np.float64)[:, None, None]
    m = send / dt - k  # steps from t_k, as ``c - tau / dt`` in integrator._lookup
    right = np.ceil(m - 1e-9)
    theta = m - (right - 1.0)
    on_grid = np.abs(theta - 1.0) < 1e-9
    absolute_right = k + right
    constant = absolute_right <= 0.0
    point = on_grid | constant
    left = np.where(point, np.maximum(absolute_right, 0.0), absolute_right - 1.0).astype(np.intp)
    t = np.where(point, 0.0, theta)
    weights = np.stack(
        [2 * t**3 - 3 * t**2 + 1, (t**3 - 2 * t**2 + t) * dt, -2 * t**3 + 3 * t**2, (t**3 - t**2) * dt]
    )
    return left * n + informers, weights


def integrate_network(
    agent: Agent,
    topology: Topology,
    F: _Array,
    P: float,
    D: float,
    tau1: float,
    tau2: float,
    *,
    network: Network,
    dt: float,
    steps: int,
    save_every: int,
    progress: Progress | None = None,
    actuation_delay: float = 0.0,
) -> Samples:
    """RK4 of the paper's eq. 1 + forcing for ``agent`` with what each agent hears over ``network`` (module doc).

    The step is that of :func:`delayform.simulation.delayed.integrator.integrate`
    (classical RK4 on the agent's state, cubic Hermite reads of the computed
    Cartesian solution), with the delayed terms read per link at the send
    times of :func:`reception` and summed with the weights ``C_ik``: with
    every link at (tau1, tau2) it is the ordinary integrator up to rounding,
    for double integrators and for robots with actuator limits alike.

    Parameters
    ----------
    agent
        The agent model and its initial state (``DoubleIntegrator`` or
        ``LimitedUnicycle`` of :mod:`delayform.simulation.models.robots`); its
        Cartesian position, velocity and acceleration are what it sends
        (constant before t = 0, zero acceleration).
    topology
        Who hears whom.
    F
        ``(n, 2)`` forcing of the paper's eq. 13.
    P, D
        Gains of the paper's eq. 1.
    tau1, tau2
        Nominal delays (s).
    network
        The imperfect network.
    dt, steps
        Step (s) and number of steps.
    save_every
        Keep every ``save_every``-th step (and the last).
    progress
        Optional callback ``progress(steps_done, steps)``, every 1000 steps.
    actuation_delay
        tau_a (s, 0 or at least dt): each agent executes its command that late, through the
        command buffer of :mod:`delayform.simulation.delayed.actuation` as in the ordinary integrator
        (what it sends is what it does: its actual state and acceleration).

    Returns
    -------
    Samples
        Positions, velocities, accelerations, agent states and the model's
        extras at the saved steps; a run whose state leaves ``1e8`` times its
        initial scale stops there (``stopped``), before it overflows.
    """
    state0 = agent.state0
    n = state0.shape[0]
    _check_memory(network, topology, dt, steps)
    rec = reception(network, topology, tau1, tau2, dt=dt, steps=steps)
    E = rec.receivers.size
    # One gather per stage reads, for every link, both streams at both ends of their
    # Hermite interval: rows (position-left, velocity-left, position-right, velocity-right)
    # of the records (x, xdot, a) at a grid point. ``terms`` weighs (x, xdot, a) of each row.
    index, terms = _gather_plan(rec, dt, n)
    cur = rec.current
    Wl = sp.csr_array((rec.weights, (rec.receivers, np.arange(E))), shape=(n, E)).toarray()
    blocks = [Wl * ~c[None, :] for c in cur]  # continuous zero-delay links are read below
    zero = np.zeros((n, E))
    summed = np.block([[blocks[0], zero, blocks[0], zero], [zero, blocks[1], zero, blocks[1]]])
    if n > _DENSE_AGENTS:
        summed = sp.csr_array(summed)
    # zero-delay continuous links hear the current stage value: C restricted to them
    now = [sp.csr_array((rec.weights * c, (rec.receivers, rec.informers)), shape=(n, n)) for c in cur]
    now_on = [bool(c.any()) for c in cur]
    if n <= _DENSE_AGENTS:
        now = [m.toarray() for m in now]
    noise_sum = _summed_noise(rec, n)

    rows = steps + 2
    S = np.zeros((rows, n, 3, 2))  # records (x, xdot, a) at every grid point
    S[0, :, 0], S[0, :, 1] = state0[:, :2], agent.velocity(state0)
    flat = S.reshape(rows * n, 3, 2)
    states = np.empty((rows,) + state0.shape)
    extras = np.empty((len(agent.extras), rows, n))

    def delayed(k: int, j: int) -> _Array:
        """``(2n, 2)``: sum_k C_ik xhat_ik over links, then the same for velocities."""
        contrib = np.einsum("ab,abc->ac", terms[k, j], flat[index[k, j]])
        out = summed @ contrib
        if noise_sum is not None:
            out = out + noise_sum[k, j]
        return out

    late = CommandBuffer(actuation_delay, dt, steps, F.shape) if actuation_delay > 0.0 else None
    if late is not None and hasattr(agent, "predict_with"):  # a filter that must see the commands in flight
        agent.predict_with(late)

    def stage(heard: _Array, st: _Array, k: int = 0, c: float = 0.0) -> tuple[_Array, _Array, tuple[_Array, ...]]:
        x, v = st[:, :2], agent.velocity(st)
        cxd, cvd = heard[:n], heard[n:]
        if now_on[0]:
            cxd = cxd + now[0] @ x
        if now_on[1]:
            cvd = cvd + now[1] @ v
        u = P * (cxd - x) + D * (cvd - v) + F  # the paper's eq. 1 + forcing of the paper's eq. 13
        if late is None:
            return agent.rhs(st, u)
        if c == 0.0:  # the command made at the grid point t_k, executed actuation_delay later
            late.store(k, agent.command(st, u))
        return agent.apply(st, late.read(k, c))

    half = 0.5 * dt
    limit = _BLOWUP * (1.0 + float(np.abs(state0).max(initial=0.0)))
    last, stopped = steps, None
    state = state0
    for k in range(steps + 1):
        if progress is not None and k % 1000 == 0:
            progress(k, steps)
        k1, S[k, :, 2], extra = stage(delayed(k, 0), state, k, 0.0)
        states[k] = state
        for e, value in enumerate(extra):
            extras[e, k] = value
        if k == last:
            break
        middle = delayed(k, 1)  # stages 2 and 3 share their time, hence what is heard
        k2 = stage(middle, state + half * k1, k, 0.5)[0]
        k3 = stage(middle, state + half * k2, k, 0.5)[0]
        k4 = stage(delayed(k, 2), state + dt * k3, k, 1.0)[0]
        state = state + (dt / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
        S[k + 1, :, 0], S[k + 1, :, 1] = state[:, :2], agent.velocity(state)
        # an unstable run grows exponentially: stop before it overflows (the run reports where)
        if k % 32 == 31 and not np.abs(state).max() < limit:
            last, stopped = k + 1, (k + 1) * dt

    saved = np.arange(0, last + 1, save_every)
    if saved[-1] != last:
        saved = np.append(saved, last)
    return Samples(
        times=saved * dt, positions=S[saved, :, 0], velocities=S[saved, :, 1], accelerations=S[saved, :, 2],
        extras={name: extras[e, saved] for e, name in enumerate(agent.extras)}, states=states[saved],
        stopped=stopped,
    )  # fmt: skip


def _gather_plan(rec: Reception, dt: float, n: int) -> tuple[NDArray[np.intp], _Array]:
    """Row indices ``(steps+1, 3, 4E)`` into the flat records and weights ``(steps+1, 3, 4E, 3)``.

    Rows are (position streams at the left grid point, velocity streams at the
    left point, positions at the right point, velocities at the right point);
    the weights multiply the records (x, xdot, a): a position reads x with
    h00 (h01) and xdot with h10 dt (h11 dt), a velocity reads xdot and a.
    """
    (i_pos, w_pos), (i_vel, w_vel) = (_hermite_reads(rec.send[s], dt, n, rec.informers) for s in range(2))
    index = np.concatenate([i_pos, i_vel, i_pos + n, i_vel + n], axis=-1)
    shape = i_pos.shape
    zero = np.zeros(shape)
    left_pos = np.stack([w_pos[0], w_pos[1], zero], axis=-1)
    left_vel = np.stack([zero, w_vel[0], w_vel[1]], axis=-1)
    right_pos = np.stack([w_pos[2], w_pos[3], zero], axis=-1)
    right_vel = np.stack([zero, w_vel[2], w_vel[3]], axis=-1)
    return index, np.concatenate([left_pos, left_vel, right_pos, right_vel], axis=-2)


def _summed_noise(rec: Reception, n: int) -> _Array | None:
    """``(steps+1, 3, 2n, 2)``: the noise of the packets heard, summed with the weights C_ik."""
    if rec.noise[0] is None and rec.noise[1] is None:
        return None
    E = rec.receivers.size
    parts = []
    for s in range(2):
        heard = rec.packet[s]
        if rec.noise[s] is None:
            parts.append(np.zeros(heard.shape[:2] + (n, 2)))
            continue
        values = rec.noise[s][np.maximum(heard, 0), np.arange(E)]  # (steps+1, 3, E, 2)
        values = np.where((heard >= 0)[..., None], values, 0.0) * rec.weights[:, None]
        summed = np.zeros(heard.shape[:2] + (n, 2))
        np.add.at(summed, (slice(None), slice(None), rec.receivers), values)
        parts.append(summed)
    return np.concatenate(parts, axis=2)
