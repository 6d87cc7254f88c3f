"""A fleet run: the team as one process per robot and a world process, over Zenoh on the loopback.

:func:`run_fleet` checks everything it can before any process starts (the
team, the delays, the network parts, the endpoint and its port), simulates
the same team at the same delays (the promise the run is measured against,
and the initial states both start from), then starts the world and the
robots (:mod:`delayform.fleet.agents`, :mod:`delayform.fleet.lifecycle`),
records every message they exchange into an MCAP file, and measures what
happened (:mod:`delayform.fleet.outcome`).

The network
-----------
The loopback loses nothing and takes a fraction of a millisecond; the
design's delays are made by each robot's playout buffer. The scenario's
``[network]`` acts where a real network would, on the state messages, with
the draws the simulator makes for the same seed
(:func:`delayform.simulation.delayed.reception.packet_draws`, for the simulator
stepping at the control period): with ``rate`` each robot sends its state at
the first tick at or after every ``m / rate`` (else at every tick: packet m is
the one sent in period m); on reception, packet m on a link is dropped when the
simulator's position stream loses packet m of that link (loss, Bernoulli or
bursty), and carries the noise the simulator adds to it, stream by stream
(positions, velocities). A state message carries both streams, as one packet
does on a real robot, so the velocity stream's separate loss draws are not
used. Delays that differ per link or in time (per-link matrices, spread,
variation, jitter) decide when each stream arrives, and one message cannot
arrive twice: a network with them is refused
(:class:`~delayform.errors.FleetError`) rather than run without them.
"""

from __future__ import annotations

import math
import socket
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from delayform._extras import require_extra
from delayform._files import atomic_path
from delayform._validation import validated
from delayform.deploy.profiles import RobotProfile
from delayform.errors import FleetError, FleetRunError
from delayform.fleet.lifecycle import Children, terminate_as_exit
from delayform.fleet.outcome import FleetRun, measure
from delayform.fleet.wire import DEFAULT_ENDPOINT, check_endpoint, open_session
from delayform.fleet.world import WORLDS
from delayform.formation import check_formation, formation_forcing
from delayform.model import Delays, Start, Team
from delayform.model.network import BernoulliLoss, GilbertElliott, Network
from delayform.simulation.models.robots import Robot, RobotLimits

__all__ = ["run_fleet", "check_network", "MCAP_NAME", "LEAD"]

#: the recording's file name in the output folder
MCAP_NAME = "fleet.mcap"

#: seconds the processes exchange states before t = 0 (the playout buffers fill with the initial state)
LEAD = 1.0

#: the recorder takes its messages this often (s), and holds at most this many between two looks
_RECORDER_POLL, _RECORDER_CAPACITY = 0.002, 1_000_000

#: seconds the children get to start (import, open the session) and to write their logs
_READY_TIMEOUT, _DONE_TIMEOUT = 60.0, 30.0


def check_network(network: Network | None) -> Network | None:
    """The network a fleet run applies: loss, sampling and noise; None when it is ideal (module doc, The network).

    Parameters
    ----------
    network
        The scenario's network, or None.

    Raises
    ------
    FleetError
        For a network with parts not applied to real messages (per-link or
        varying delays, jitter).
    """
    if network is None or network.is_ideal:
        return None
    parts = [name for name, on in (
        ("per-link delays", network.delays is not None and not network.delays.is_uniform),
        ("delay variation", network.variation is not None and not network.variation.is_off),
        ("jitter", network.jitter is not None and not network.jitter.is_off),
    ) if on]  # fmt: skip
    if parts:
        raise FleetError(f"the scenario's [network] has {', '.join(parts)}: a fleet run applies loss, sampling and "
                         f"noise to real messages, not delays that differ per link or in time; remove them, or run "
                         f"simulate for the whole network")  # fmt: skip
    return network


def _port_free(host: str, port: int) -> bool:
    family = socket.AF_INET6 if host.startswith("[") else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        # as a listener binds: connections of an earlier run waiting out TIME_WAIT do not hold the port
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host.strip("[]"), port))
        except OSError:
            return False
    return True


def _limits_dict(limits: RobotLimits | None) -> dict[str, float] | None:
    import dataclasses

    return None if limits is None else dataclasses.asdict(limits)


@validated(FleetError)
def run_fleet(
    team: Team,
    delays: Delays,
    formation: ArrayLike | str,
    *,
    out: str | Path,
    duration: float,
    period: float,
    robot: RobotProfile | RobotLimits | None = None,
    start: Start | None = None,
    network: Network | None = None,
    endpoint: str = DEFAULT_ENDPOINT,
    world: str = "kinematic",
    progress: Callable[[str], None] | None = None,
) -> FleetRun:
    """Run the team as processes on this machine and measure it against the analysis (module doc).

    Parameters
    ----------
    team
        Topology and gains (paper, eq. 1).
    delays
        The design's delays: one pair on every link (the playout buffers hold them).
    formation
        ``(n, 2)`` desired positions or a shape name.
    out
        Folder for ``fleet.mcap`` (the outputs of :class:`FleetRun` are written by the caller).
    duration
        Seconds of wall clock from t = 0.
    period
        Control period h (s) of every robot; the world publishes odometry as often.
    robot
        The robots' profile or limits (the kinematic world and the controller
        both use them); None: ideal robots.
    start
        The initial state (:class:`~delayform.model.Start`), as :func:`delayform.simulate`
        takes it; None: ``Start()``, drawn from seed 0.
    network
        The scenario's network: its loss, sampling and noise act on the state messages (module doc).
    endpoint
        The Zenoh endpoint on the loopback the parent listens on.
    world
        The world model (:data:`delayform.fleet.world.WORLDS`).
    progress
        Optional callback with a few words at each stage.

    Returns
    -------
    FleetRun

    Raises
    ------
    FleetError
        Before any process starts: per-link delays, an actuation delay, a
        network part not applied, an endpoint off the loopback or a port in use,
        a period or duration that is not positive, an unknown world.
    FleetRunError
        A child process that failed or never became ready.
    """
    require_extra("fleet")
    if not isinstance(team, Team) or not isinstance(delays, Delays):
        raise FleetError("run_fleet takes a Team and a Delays (delayform.model)")
    if delays.kind != "uniform":
        raise FleetError("the on-robot controller holds one delay pair on every link; these delays differ per link")
    if delays.actuation:
        raise FleetError("an actuation delay is what the robots do, not what the fleet adds: give Delays without it")
    tau1, tau2 = delays.pair
    for name, value in (("duration", duration), ("period", period)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
            raise FleetError(f"{name} must be a positive number of seconds, got {value!r}")
    if period >= duration:
        raise FleetError(f"the control period {period:g} s must be shorter than the duration {duration:g} s")
    if world not in WORLDS:
        raise FleetError(f"unknown world model {world!r}; known: {', '.join(WORLDS)}")
    network = check_network(network)
    host, port = check_endpoint(endpoint)
    if not _port_free(host, port):
        raise FleetError(f"the endpoint {endpoint} cannot be used: port {port} is already taken on {host}")
    out = Path(out)
    if not out.is_dir():
        raise FleetError(f"the output folder {out} does not exist")
    limits = robot.limits if isinstance(robot, RobotProfile) else robot
    topology, n = team.topology, team.n
    desired = check_formation(formation, n)
    say = progress or (lambda text: None)

    # the promise: the same team simulated at the same delays (and the initial states both start from)
    from delayform.simulation import simulate

    steps_dt = min([period] + [t for t in (tau1, tau2) if t > 0])
    say("simulating the same team")
    sim = simulate(team, delays, desired, robot=Robot(model="unicycle", limits=limits), network=network,
                   start=start, duration=duration, dt=steps_dt)  # fmt: skip
    state0 = np.column_stack([sim.positions[0], sim.headings[0], sim.speeds[0]])
    draws = _draws(network, team, duration, steps_dt, period)
    rate = None if network is None or network.sampling is None else network.sampling.rate
    F = formation_forcing(topology, team.P, desired)
    C = topology.C_sparse.tocsr()

    with tempfile.TemporaryDirectory(dir=out, prefix=".fleet-") as tmp, terminate_as_exit():
        folder = Path(tmp)
        try:
            session = open_session(listen=[endpoint], connect=[])
        except Exception as exc:  # zenoh's own error (a port taken since the check, a bad address): one line
            raise FleetError(f"cannot listen on the endpoint {endpoint}: {str(exc).splitlines()[0][:200]}") from None
        try:
            recorder = _Recorder(session, n)
            common = {"n": n, "endpoint": endpoint, "period": period, "duration": duration, "lead": LEAD,
                      "limits": _limits_dict(limits), "rate": rate}  # fmt: skip
            with Children(folder) as children:
                say("starting the processes")
                children.start("world", {**common, "role": "world", "world": world, "state0": state0.tolist(),
                                         "log": str(folder / "world.npz")})  # fmt: skip
                for i in range(n):
                    lo, hi = C.indptr[i], C.indptr[i + 1]
                    weights = {str(int(j) + 1): float(w) for j, w in zip(C.indices[lo:hi], C.data[lo:hi]) if j != i and w}
                    children.start(f"robot_{i + 1}", {
                        **common, "role": "robot", "robot": i + 1, "P": team.P, "D": team.D, "tau1": tau1,
                        "tau2": tau2, "weights": weights, "forcing": F[i].tolist(),
                        "draws": _save_draws(draws, i + 1, folder), "log": str(folder / f"robot_{i + 1}.npz")})  # fmt: skip
                pids = children.pids
                children.expect("ready", _READY_TIMEOUT)
                t0 = time.time() + LEAD
                recorder.t0 = t0
                children.send(repr(t0))
                say(f"running {duration:g} s")
                while time.time() < t0 + duration:
                    failure = children.failed()
                    if failure:
                        raise FleetRunError(failure)
                    recorder.drain()
                    time.sleep(_RECORDER_POLL)
                children.expect("done", _DONE_TIMEOUT)
                children.wait(_DONE_TIMEOUT)
                failure = children.failed()
                if failure:
                    raise FleetRunError(failure)
            recorder.stop()
            say("writing the recording")
            mcap = recorder.write(out / MCAP_NAME, team, tau1, tau2, t0)
            logs = {name: dict(np.load(folder / f"{name}.npz")) for name in ["world"] + [f"robot_{i}" for i in range(1, n + 1)]}
        finally:
            session.close()
    say("measuring")
    return measure(team=team, tau1=tau1, tau2=tau2, desired=desired, limits=limits, period=period,
                   duration=duration, network=network, simulation=sim, logs=logs, recording=recorder.counts(),
                   pids=pids, mcap=mcap, world=world, endpoint=endpoint)  # fmt: skip


def _draws(network: Network | None, team: Team, duration: float, dt: float, period: float) -> Any:
    """The simulator's draws for the state messages (module doc), or None for a network that draws nothing."""
    if network is None or not network.packets:
        return None
    from delayform.simulation.delayed.reception import packet_draws

    # as reception(): the simulator stepping at dt sends a packet every sampling period (or step)
    every = dt if network.sampling is None else 1.0 / network.sampling.rate
    steps = round(duration / dt)
    packets = math.floor((steps + 1) * dt / every + 1e-9) + 1
    return packet_draws(network, team.topology, packets=packets)


def _save_draws(draws: Any, robot: int, folder: Path) -> str | None:
    """Robot ``robot``'s share of the draws (the links it receives on) as an NPZ; its path, or None."""
    if draws is None:
        return None
    mine = np.flatnonzero((draws.receivers == robot - 1) & (draws.informers != robot - 1))
    arrays: dict[str, np.ndarray] = {"informers": draws.informers[mine] + 1}
    if draws.lost is not None:
        arrays["lost"] = draws.lost[0][:, mine]  # the position stream's: one message carries both
    if draws.noise is not None:
        arrays["noise"] = np.concatenate([draws.noise[0][:, mine], draws.noise[1][:, mine]], axis=-1)  # dx dy dvx dvy
    path = folder / f"draws_{robot}.npz"
    with atomic_path(path) as tmp:
        np.savez(tmp, **arrays)
    return str(path)


class _Recorder:
    """Every message of the run, as the parent's session receives it, into an MCAP file at the end."""

    def __init__(self, session: Any, n: int) -> None:
        import zenoh

        self.n = n
        self.t0 = math.inf
        self._messages: list[tuple[str, int, bytes]] = []
        # taken by drain() in the parent's own loop: no Python callback on Zenoh's threads (agents._subscribe)
        self._sub = session.declare_subscriber("**", zenoh.handlers.FifoChannel(_RECORDER_CAPACITY))

    def drain(self) -> None:
        """Take every message waiting (log time: when taken, within the parent's polling interval)."""
        while (sample := self._sub.try_recv()) is not None:
            self._messages.append((str(sample.key_expr), time.time_ns(), bytes(sample.payload.to_bytes())))

    def stop(self) -> None:
        self.drain()
        self._sub.undeclare()

    def counts(self) -> dict[str, int]:
        """Messages recorded per key expression."""
        out: dict[str, int] = {}
        for k, _, _ in self._messages:
            out[k] = out.get(k, 0) + 1
        return out

    def write(self, path: Path, team: Team, tau1: float, tau2: float, t0: float) -> Path:
        """The MCAP file: one channel per key (topic ``/<key>``), CDR with the ROS 2 schemas, log time = receipt."""
        from mcap.writer import CompressionType, Writer
        from rosbags.typesys import Stores, get_typestore

        from delayform.deploy.recording import MCAP_TOPICS

        store = get_typestore(Stores.ROS2_HUMBLE)
        kinds = {"odom": MCAP_TOPICS["odom"], "state": MCAP_TOPICS["odom"], "cmd_vel": MCAP_TOPICS["cmd_vel"]}
        with atomic_path(path) as tmp, open(tmp, "wb") as stream:
            writer = Writer(stream, compression=CompressionType.ZSTD)
            writer.start(profile="ros2", library="delayform fleet (zenoh + mcap + rosbags)")
            schemas: dict[str, int] = {}
            channels: dict[str, int] = {}
            for k, now, data in self._messages:
                if k not in channels:
                    msgtype = kinds.get(k.rpartition("/")[2])
                    if msgtype is None:
                        continue
                    if msgtype not in schemas:
                        text, _ = store.generate_msgdef(msgtype, ros_version=2)
                        schemas[msgtype] = writer.register_schema(name=msgtype, encoding="ros2msg", data=text.encode())
                    channels[k] = writer.register_channel("/" + k, "cdr", schemas[msgtype])
                writer.add_message(channels[k], now, data, now)
            writer.add_metadata("delayform/fleet", {
                "robots": str(self.n), "P": repr(team.P), "D": repr(team.D), "tau1": repr(tau1), "tau2": repr(tau2),
                "t0_ns": str(int(round(t0 * 1e9))), "topology": team.topology.name,
                "log_time": "when the recording process took the message (ns since 1970, within 2 ms of its arrival)"})  # fmt: skip
            writer.finish()
        return path
