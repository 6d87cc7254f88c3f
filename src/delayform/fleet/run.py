"""A fleet run: the team as one process per robot and a world process, over Zenoh on the loopback.

:func:`run_fleet` checks everything it can before any process starts (the
team, the delays, the network parts, the endpoint and its port, whether
this machine has the cores and memory to keep the control period,
:mod:`delayform.fleet.budget`), simulates
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
the draws the simulator makes for the same seed (:mod:`delayform.fleet.plan`,
for the simulator stepping at the control period when the delays allow it):
with ``rate`` each robot sends its state at the first tick at or after every
``m / rate`` (else at every tick). On reception, packet m on link
``i <- k`` is held by robot i's playout buffer for that link's delays
(per-link matrices, or drawn with the spread), plus the jitter the simulator
draws for packet m of each stream; a stream the simulator loses is never
used (loss, Bernoulli or bursty), and each stream carries the noise the
simulator adds to it. A state message carries both streams, as one packet
does on a real robot; each becomes usable at its own time. Delays that vary
smoothly in time delay each message as the simulator's variation delays the
value it hears (:mod:`delayform.fleet.plan`, Variation).
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Callable, Iterable
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
from delayform.fleet.budget import check_machine
from delayform.fleet.faults import Fault, check_faults
from delayform.fleet.live import LIVE_EVERY, LiveView, check_live_port
from delayform.fleet.rmw import check_domain
from delayform.fleet.wire import DEFAULT_ENDPOINT, Codec, Odometry, check_endpoint, key, open_session, port_free
from delayform.fleet.world import WORLDS
from delayform.formation import check_formation, formation_forcing
from delayform.model import Delays, Start, Team
from delayform.fleet.plan import LinkPlan, link_plan
from delayform.model.network import Network
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
    """The network a fleet run applies; None when it is ideal (module doc, The network).

    Parameters
    ----------
    network
        The scenario's network, or None.

    """
    return None if network is None or network.is_ideal else network


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
    faults: Iterable[Fault] = (),
    foxglove: int | None = None,
    ros_domain: int | None = None,
    progress: Callable[[str], None] | None = None,
) -> FleetRun:
    """Run the team as processes on this machine and measure it against the analysis (module doc).

    Parameters
    ----------
    team
        Topology and gains (paper, eq. 1).
    delays
        The design's nominal delays (one pair; per-link delays come with the
        network, as for :func:`delayform.simulate`: ``Network(delays=LinkDelays(...))``).
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
        The scenario's network: its per-link delays, jitter, loss, sampling and
        noise act on the state messages (module doc).
    endpoint
        The Zenoh endpoint on the loopback the parent listens on.
    world
        The world model (:data:`delayform.fleet.world.WORLDS`).
    faults
        Robots' processes killed by SIGKILL and started again, at times of
        the run (:mod:`delayform.fleet.faults`); the summary names each silent robot and for how long.
    foxglove
        A port on 127.0.0.1 where the running team is served to Foxglove
        (:mod:`delayform.fleet.live`), or None.
    ros_domain
        A ROS domain id (0..232): every process also publishes its topics as
        rmw_zenoh does on that domain, with liveliness tokens for its node and
        publishers, so that a ROS 2 node on rmw_zenoh connected to ``endpoint``
        hears the run (:mod:`delayform.fleet.rmw`); None: the plain keys only.
    progress
        Optional callback with a few words at each stage.

    Returns
    -------
    FleetRun

    Raises
    ------
    FleetError
        Before any process starts: delay matrices in ``delays`` (they go in
        the network), an actuation delay, a delay its jitter and variation
        could bring to zero, an endpoint off the loopback or a port in use,
        a period or duration that is not positive, an unknown world, faults
        that do not fit the team or the run, a Foxglove port that is invalid
        or taken, a ROS domain that is not a whole number in 0..232, a team whose processes would need more cores than this
        machine has to keep the period (:mod:`delayform.fleet.budget`).
    ResourceLimitError
        Before any process starts: processes that would need more memory than the budget.
    MissingExtraError
        For ``foxglove`` without the Foxglove SDK.
    FleetRunError
        A child process that failed or never became ready.
    """
    require_extra("fleet")
    if not isinstance(team, Team) or not isinstance(delays, Delays):
        raise FleetError("run_fleet takes a Team and a Delays (delayform.model)")
    if delays.kind != "uniform":
        raise FleetError("per-link delays go in the network, as for simulate: network=Network(delays=LinkDelays(tau1, "
                         "tau2)) with the nominal pair in Delays")  # fmt: skip
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
    if not port_free(host, port):
        raise FleetError(f"the endpoint {endpoint} cannot be used: port {port} is already taken on {host}")
    faults = check_faults(faults, team.n, duration)
    if ros_domain is not None:
        check_domain(ros_domain)
    check_machine(team.n, int(team.topology.C_sparse.nnz), period, ros=ros_domain is not None)
    if foxglove is not None:
        check_live_port(foxglove, taken=port)
    out = Path(out)
    if not out.is_dir():
        raise FleetError(f"the output folder {out} does not exist")
    limits = robot.limits if isinstance(robot, RobotProfile) else robot
    topology, n = team.topology, team.n
    desired = check_formation(formation, n)
    say = progress or (lambda text: None)

    # the promise: the same team simulated at the same delays (and the initial states both start from)
    from delayform.simulation import simulate

    plan = link_plan(network or Network(), topology, tau1, tau2, dt=period, duration=duration)
    steps_dt = _step(plan, network, period)
    if steps_dt != period:
        plan = link_plan(network or Network(), topology, tau1, tau2, dt=steps_dt, duration=duration)
    say("simulating the same team")
    sim = simulate(team, delays, desired, robot=Robot(model="unicycle", limits=limits), network=network,
                   start=start, duration=duration, dt=steps_dt)  # fmt: skip
    state0 = np.column_stack([sim.positions[0], sim.headings[0], sim.speeds[0]])
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
                      "codec": recorder.codec_spec(),
                      "limits": _limits_dict(limits), "rate": rate, "ros_domain": ros_domain}  # fmt: skip
            specs = {}
            for i in range(n):
                lo, hi = C.indptr[i], C.indptr[i + 1]
                weights = {str(int(j) + 1): float(w) for j, w in zip(C.indices[lo:hi], C.data[lo:hi]) if j != i and w}
                mine = plan.of_receiver(i + 1)
                specs[i + 1] = {
                    **common, "role": "robot", "robot": i + 1, "P": team.P, "D": team.D, "tau1": tau1,
                    "tau2": tau2, "weights": weights, "forcing": F[i].tolist(), "packet_period": plan.period,
                    "link_delays": {str(int(plan.informers[e]) + 1): [float(plan.tau1[e]), float(plan.tau2[e])]
                                    for e in mine},
                    "draws": _save_draws(plan, mine, i + 1, folder)}  # fmt: skip
            live = None
            if foxglove is not None:
                live = LiveView(foxglove, desired=desired, radius=0.0 if limits is None else limits.radius,
                                edges=topology.adjacency)  # fmt: skip
            with Children(folder) as children:
                say("starting the processes")
                children.start("world", {**common, "role": "world", "world": world, "state0": state0.tolist(),
                                         "log": str(folder / "world.npz")})  # fmt: skip
                for i, spec in specs.items():
                    children.start(f"robot_{i}", {**spec, "log": str(folder / f"robot_{i}.npz")})
                children.expect("ready", _READY_TIMEOUT)
                t0 = time.time() + LEAD
                recorder.t0 = t0
                children.send(repr(t0))
                say(f"running {duration:g} s" + (f"; Foxglove on ws://127.0.0.1:{foxglove}" if live else ""))
                faulting = _Faults(faults, children, specs, folder, t0)
                shown = 0.0
                while (now := time.time()) < t0 + duration:
                    faulting.step(now)
                    failure = children.failed()
                    if failure:
                        raise FleetRunError(failure)
                    recorder.drain()
                    if live is not None and now >= shown:
                        live.show(recorder.latest_odometry(), faulting.running, now)
                        shown = now + LIVE_EVERY
                    time.sleep(_RECORDER_POLL)
                faulting.finish()
                children.expect("done", _DONE_TIMEOUT)
                children.wait(_DONE_TIMEOUT)
                failure = children.failed()
                if failure:
                    raise FleetRunError(failure)
                pids = children.pids
            if live is not None:
                live.stop()
            recorder.stop()
            say("writing the recording")
            mcap = recorder.write(out / MCAP_NAME, team, tau1, tau2, t0)
            with np.load(folder / "world.npz") as npz:
                logs = {"world": dict(npz)}
            for i in range(1, n + 1):
                logs[f"robot_{i}"] = _robot_log(faulting.logs(i), period)
        finally:
            session.close()
    say("measuring")
    heard = {i: recorder.times(key(i, "state"), t0) for i in range(1, n + 1)}
    return measure(team=team, tau1=tau1, tau2=tau2, plan=plan, desired=desired, limits=limits, period=period,
                   duration=duration, network=network, simulation=sim, logs=logs, recording=recorder.counts(),
                   pids=pids, mcap=mcap, world=world, endpoint=endpoint, faults=faulting.done,
                   heard=heard, ros_domain=ros_domain)  # fmt: skip


class _Faults:
    """The faults of a run carried out on the wall clock: kills by SIGKILL, restarts as new processes.

    Parameters
    ----------
    faults
        Checked, in time order (:func:`~delayform.fleet.faults.check_faults`).
    children
        The run's processes.
    specs
        Robot (from 1) -> its spec without the log's path.
    folder
        Where the logs go.
    t0
        The run's t = 0 (s since 1970).
    """

    def __init__(self, faults: tuple[Fault, ...], children: Children, specs: dict[int, dict[str, Any]],
                 folder: Path, t0: float) -> None:  # fmt: skip
        self._pending = list(faults)
        self._children, self._specs, self._folder, self._t0 = children, specs, folder, t0
        self._names = {i: f"robot_{i}" for i in specs}
        self._logs = {i: [folder / f"robot_{i}.npz"] for i in specs}
        self._starting: dict[str, int] = {}
        self.running = dict.fromkeys(specs, True)
        #: what was done: robot, action, planned and actual time (run clock)
        self.done: list[dict[str, Any]] = []

    def step(self, now: float) -> None:
        """Carry out the faults that are due; hand t0 to restarted robots that are ready."""
        while self._pending and now >= self._t0 + self._pending[0].at:
            f = self._pending.pop(0)
            name = self._names[f.robot]
            if f.action == "kill":
                self._children.kill(name)
                self._starting.pop(name, None)
                self.running[f.robot] = False
            else:
                name = f"robot_{f.robot}.{len(self._logs[f.robot])}"
                log = self._folder / f"{name}.npz"
                self._children.start(name, {**self._specs[f.robot], "log": str(log), "rejoin": True})
                self._names[f.robot] = name
                self._logs[f.robot].append(log)
                self._starting[name] = f.robot
            self.done.append({"robot": f.robot, "action": f.action, "planned_s": f.at, "at_s": time.time() - self._t0})
        for name in [nm for nm in self._starting if self._children.said(nm, "ready")]:
            self._children.tell(name, repr(self._t0))
            self.running[self._starting.pop(name)] = True

    def finish(self) -> None:
        """A restarted robot not ready by the end of the run is ended (it never rejoined: its journal is empty)."""
        for name in list(self._starting):
            self._children.kill(name)
        self._starting.clear()

    def logs(self, robot: int) -> list[Path]:
        """The log paths of each of the robot's processes, in order."""
        return self._logs[robot]


def _robot_log(paths: list[Path], period: float) -> dict[str, Any]:
    """A robot's log over all its processes: the NPZ of one that ended, the journal of one that was killed.

    A killed process's missed ticks are the deadlines missing between the
    ones it ran (its counter died with it).
    """
    from delayform.fleet.agents import TICK_COLUMNS, read_journal

    parts = []
    for path in paths:
        if path.exists():
            with np.load(path) as npz:
                parts.append(dict(npz))
            continue
        j = read_journal(str(path))
        deadlines = j["ticks"][:, 0]
        gaps = np.round(np.diff(deadlines) / period) - 1 if deadlines.size > 1 else np.zeros(0)
        parts.append({**j, "missed": int(np.sum(np.maximum(gaps, 0))), "error": ""})
    return {
        "received": np.concatenate([np.asarray(p["received"]).reshape(-1, 6) for p in parts]),
        "ticks": np.concatenate([np.asarray(p["ticks"]).reshape(-1, len(TICK_COLUMNS)) for p in parts]),
        "sent": np.concatenate([np.asarray(p["sent"]).reshape(-1) for p in parts]),
        "missed": sum(int(p["missed"]) for p in parts),
        "waiting": np.asarray(parts[-1].get("waiting", np.zeros(0)), dtype=np.int64),
        "error": "; ".join(str(p["error"]) for p in parts if str(p["error"])),
        "starts": np.array([np.asarray(p["ticks"]).reshape(-1, len(TICK_COLUMNS))[0, 0] if np.size(p["ticks"]) else math.nan
                            for p in parts]),  # fmt: skip
    }


def _step(plan: LinkPlan, network: Network | None, period: float) -> float:
    """The simulator's step: the control period, or the largest period / k under every delay less its jitter and variation.

    A packet stream is heard at the earliest one step after it is sent (the
    simulator's rule): a link delay shorter than the period needs a finer step.
    """
    bounds = np.zeros(2)
    if network is not None and network.jitter is not None:
        bounds += (network.jitter.bound1, network.jitter.bound2)
    if network is not None and network.variation is not None:
        bounds += (network.variation.amplitude1, network.variation.amplitude2)
    packets = network is not None and network.packets
    shortest = [float(d.min()) - b for d, b in ((plan.tau1, bounds[0]), (plan.tau2, bounds[1]))]
    floor = min([d for d, b in zip(shortest, bounds) if d > 0.0 or packets or b > 0.0], default=period)
    if floor <= 0.0:
        raise FleetError(f"a delay less its jitter and variation reaches {floor:g} s: every message must take "
                         "some time to arrive")  # fmt: skip
    return period / max(1, math.ceil(period / floor - 1e-9))


def _save_draws(plan: LinkPlan, mine: np.ndarray, robot: int, folder: Path) -> str | None:
    """Robot ``robot``'s share of the draws (the links ``mine`` it receives on) as an NPZ; its path, or None."""
    if plan.lost is None and plan.noise is None and plan.jitter is None:
        return None
    arrays: dict[str, np.ndarray] = {"informers": plan.informers[mine] + 1}
    if plan.lost is not None:
        arrays["lost"] = np.moveaxis(plan.lost[:, :, mine], 0, -1)  # (packets, links, stream)
    if plan.jitter is not None:
        arrays["jitter"] = np.moveaxis(plan.jitter[:, :, mine], 0, -1)
    if plan.noise is not None:
        arrays["noise"] = np.concatenate([plan.noise[0][:, mine], plan.noise[1][:, mine]], axis=-1)  # dx dy dvx dvy
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
        self._odom: dict[str, bytes] = {}
        self._codec = Codec(n)
        # taken by drain() in the parent's own loop: no Python callback on Zenoh's threads (agents._subscribe);
        # the fleet's own keys only (not their rmw_zenoh copies, delayform.fleet.rmw)
        self._sub = session.declare_subscriber("robot_$*/*", zenoh.handlers.FifoChannel(_RECORDER_CAPACITY))

    def codec_spec(self) -> dict[str, Any]:
        """The message layouts every process of the run encodes with (:meth:`Codec.spec`)."""
        return self._codec.spec()

    def drain(self) -> None:
        """Take every message waiting (log time: when taken, within the parent's polling interval)."""
        while (sample := self._sub.try_recv()) is not None:
            k = str(sample.key_expr)
            data = bytes(sample.payload.to_bytes())
            self._messages.append((k, time.time_ns(), data))
            if k.endswith("/odom"):
                self._odom[k] = data

    def latest_odometry(self) -> dict[int, Odometry]:
        """Robot (from 1) -> the newest odometry the world published of it."""
        return {i: self._codec.read_odometry(i, self._odom[key(i, "odom")])
                for i in range(1, self.n + 1) if key(i, "odom") in self._odom}  # fmt: skip

    def times(self, topic: str, t0: float) -> np.ndarray:
        """When the messages on ``topic`` were taken (s on the run's clock)."""
        return np.array([now * 1e-9 - t0 for k, now, _ in self._messages if k == topic])

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
