"""The processes of a fleet run: one per robot and one world, each started as ``python -m delayform.fleet.agents SPEC``.

Every child reads its JSON spec, ties its life to its parent's
(:func:`tie_to_parent`), opens its Zenoh session, declares its subscribers
and prints ``ready``; it then reads ``t0`` (seconds since 1970 of the run's
t = 0) on stdin and runs on the wall clock until ``t0 + duration``, writes
its log (NPZ) and prints ``done``.

A robot (:func:`robot_main`) ticks every control period h at ``t0 + k h``:
from its own latest odometry it publishes its state, extrapolated along its
heading to the tick (stamped with the tick's time: the sender's clock), and
from t = 0 on it runs :class:`~delayform.deploy.controller.FormationController`
on its neighbours' states and publishes the velocity command. Before t = 0
it only publishes its state: the neighbours' playout buffers then hold the
initial state, the constant history of the simulation. A tick that wakes
more than a period late skips the deadlines it missed (counted).
The scenario's network acts where a real one would, on reception
(:mod:`delayform.fleet.plan`): each link's delays are the controller's
playout delays, a packet's jitter delays that message's position and
velocity, and a stream the network loses is never used.

A robot also appends its log to a journal every :data:`JOURNAL_EVERY` s
(:func:`read_journal`): a robot killed by a fault (:mod:`delayform.fleet.faults`)
writes no log at its end, and its journal is what the run knows of it. A
robot started again mid-run (``rejoin`` in its spec) joins at its next
deadline, takes its own state from the world's odometry, and ticks once it
has heard from every neighbour (its playout buffers start with their next
messages): with a neighbour that stays silent (dead too) it never ticks, and
its log names the neighbours it waited for.

With a ROS domain in its spec a process is also an rmw_zenoh node and
publishes each message a second time, on its rmw_zenoh key with an
attachment (:mod:`delayform.fleet.rmw`): same payload, same moment.

Every process takes its messages from Zenoh channels in its own thread, looking
every millisecond while it waits for its next deadline (:func:`_wait_until`):
no Python code runs on Zenoh's threads, and a message's receipt time is when the
process took it. A child that fails prints its traceback and ends at once.

The world (:func:`world_main`) holds the robots still before t = 0, then
applies each command when it arrives and integrates its model
(:mod:`delayform.fleet.world`) in real time, publishing every robot's
odometry every period. A robot whose commands stop for
:data:`~delayform.fleet.world.COMMAND_TIMEOUT` is stopped (set-point zero),
as a velocity-controlled base does when its commands time out.
"""

from __future__ import annotations

import ctypes
import faulthandler
import gc
import json
import math
import os
import signal
import sys
import threading
import time
import traceback
from pathlib import Path
from typing import Any

# only the standard library at the top: a child ties its life to its parent's before the slow imports

__all__ = ["tie_to_parent", "ReceivingSide", "robot_main", "world_main", "main", "read_journal", "JOURNAL_EVERY",
           "TICK_COLUMNS"]

_PR_SET_PDEATHSIG = 1


def tie_to_parent(parent: int) -> None:
    """End this process when its parent ends, however it ends (Linux: PR_SET_PDEATHSIG; else a watchdog).

    Ctrl-C at the terminal reaches the whole process group: the children
    ignore it and the parent, which handles it, ends them.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda *_: os._exit(143))
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the watchdog below is the only guard
        pass
    if os.getppid() != parent:  # the parent died before the signal was armed
        os._exit(1)

    def watch() -> None:
        while True:
            time.sleep(0.2)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, daemon=True).start()


def _say(text: str) -> None:
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def _start_time() -> float:
    # no garbage-collector pauses in the loop: what it allocates (floats, tuples) holds no cycles, and a
    # collection scanning the growing logs would cost milliseconds at random ticks
    gc.collect()
    gc.freeze()
    gc.disable()
    line = sys.stdin.readline()
    if not line:  # the parent closed the pipe: the run was called off
        os._exit(0)
    return float(line)


def _close(session: Any) -> None:
    """Close the Zenoh session politely for at most a second, then end: the log is already written."""
    closer = threading.Thread(target=session.close, daemon=True)
    closer.start()
    closer.join(1.0)
    sys.stdout.flush()
    os._exit(0)


#: how often a process looks for messages while it waits for its next deadline (s): the receipt times are this exact
_POLL = 0.001

#: messages a subscriber holds between two looks
_CAPACITY = 4096


def _subscribe(session: Any, keyexpr: str) -> Any:
    """A subscriber whose messages wait in a channel until this process takes them.

    No Python callback runs on Zenoh's threads: a callback there needs the GIL
    while the main thread may hold it inside a Zenoh call, a deadlock seen in
    a few runs out of twenty.
    """
    import zenoh

    return session.declare_subscriber(keyexpr, zenoh.handlers.FifoChannel(_CAPACITY))


def _drain(subs: list[tuple[Any, Any]]) -> None:
    """Hand every waiting message to its handler."""
    for sub, handle in subs:
        while (sample := sub.try_recv()) is not None:
            handle(sample)


def _wait_until(epoch: float, subs: list[tuple[Any, Any]]) -> None:
    """Take messages as they come until ``epoch`` (s since 1970)."""
    while True:
        _drain(subs)
        left = epoch - time.time()
        if left <= 0:
            return
        time.sleep(min(left, _POLL))


# ------------------------------------------------------------------ robot
class ReceivingSide:
    """What the scenario's network does to the state messages one robot receives (:mod:`delayform.fleet.plan`).

    Parameters
    ----------
    links
        Informer (from 1) -> the link's delays ``(tau1_ik, tau2_ik)``.
    period
        The packet period (s): a message stamped t (run clock) is packet ``floor(t / period)``.
    draws
        The NPZ of this robot's draws (:func:`delayform.fleet.run.run_fleet` writes it), or None:
        ``informers``, and per link ``lost`` (packets, 2), ``jitter`` (packets, 2), ``noise`` (packets, 4).
    """

    def __init__(self, links: dict[int, tuple[float, float]], period: float, draws: str | None) -> None:
        import numpy as np

        self.links, self.period = links, period
        self.lost: dict[int, Any] = {}
        self.noise: dict[int, Any] = {}
        self.jitter: dict[int, Any] = {}
        if draws:
            with np.load(draws) as d:
                for e, k in enumerate(d["informers"]):
                    for name, box in (("lost", self.lost), ("noise", self.noise), ("jitter", self.jitter)):
                        if name in d:
                            box[int(k)] = d[name][:, e].tolist()  # plain floats: looked up at every message

    def apply(self, message: Any) -> tuple[Any, tuple[float, float]]:
        """The message as the network delivers it (noise added) and its delays (infinite: that stream is lost)."""
        k, stamp = message.sender, message.stamp
        d1, d2 = self.links[k]
        if stamp < 0.0:  # before t = 0: the exact initial history, as the simulator's
            return message, (d1, d2)
        m = math.floor(stamp / self.period + 1e-9)
        jit = self.jitter.get(k)
        if jit is not None and m < len(jit):
            d1, d2 = d1 + jit[m][0], d2 + jit[m][1]
        lost = self.lost.get(k)
        if lost is not None and m < len(lost):
            d1, d2 = (math.inf if lost[m][0] else d1), (math.inf if lost[m][1] else d2)
        extra = self.noise.get(k)
        if extra is not None and m < len(extra):
            dx, dy, dvx, dvy = extra[m]
            message = message._replace(x=message.x + dx, y=message.y + dy, vx=message.vx + dvx, vy=message.vy + dvy)
        return message, (d1, d2)


#: seconds between two appends of a robot's journal (what survives a SIGKILL: all but the last this many seconds)
JOURNAL_EVERY = 0.1

#: a tick's row: deadline, lateness, lag, compute time, speed sent, then what the limits did to the command
#: (the speed the tick was computed at, the turn rate executed and wanted, the acceleration executed and wanted)
TICK_COLUMNS = ("deadline", "lateness", "lag", "compute", "speed_sent",
                "speed", "turn_rate", "ideal_turn_rate", "acceleration", "ideal_acceleration")  # fmt: skip

#: the journal's files (suffix of the log's path) and the width of their float64 rows
JOURNAL = {"received": 6, "ticks": len(TICK_COLUMNS), "sent": 1}


class _Journal:
    """A robot's log appended to raw float64 files as the run goes: a process killed by a fault leaves it behind."""

    def __init__(self, log: str) -> None:
        self._fds = {name: os.open(f"{log}.{name}", os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644) for name in JOURNAL}
        self._done = dict.fromkeys(JOURNAL, 0)

    def append(self, rows: dict[str, list[Any]]) -> None:
        """Write the rows added since the last call (one write per file: a kill never splits a row)."""
        import numpy as np

        for name, fd in self._fds.items():
            new = rows[name][self._done[name]:]
            if new:
                os.write(fd, np.asarray(new, dtype=np.float64).tobytes())
                self._done[name] += len(new)


def read_journal(log: str) -> dict[str, Any]:
    """The rows a robot's journal holds (:data:`JOURNAL`), as arrays; a row cut by a kill is left out.

    Parameters
    ----------
    log
        The path the robot's log would have had (its spec's ``log``); the journal's files end with ``.<name>``.
    """
    import numpy as np

    out: dict[str, Any] = {}
    for name, width in JOURNAL.items():
        path = Path(f"{log}.{name}")
        data = np.fromfile(path, dtype=np.float64) if path.exists() else np.zeros(0)
        out[name] = data[: data.size - data.size % width].reshape(-1, width)
    out["sent"] = out["sent"].reshape(-1)
    return out


def robot_main(spec: dict[str, Any]) -> None:
    """One robot: odometry and neighbours' states in, state and velocity commands out (module doc).

    Parameters
    ----------
    spec
        The robot's part of the run, as :func:`delayform.fleet.run.run_fleet` writes it: its number,
        gains, delays, weights, forcing, limits, period, the endpoint and which messages the network drops.
    """
    import numpy as np

    from delayform.deploy.controller import FormationController, NeighbourMessage
    from delayform.fleet.wire import Codec, Odometry, key, open_session
    from delayform.model.limits import RobotLimits

    me, n, h = int(spec["robot"]), int(spec["n"]), float(spec["period"])
    limits = None if spec["limits"] is None else RobotLimits(**spec["limits"])
    links = {int(k): (float(d[0]), float(d[1])) for k, d in spec["link_delays"].items()}
    ctrl = FormationController(robot=me, P=spec["P"], D=spec["D"], tau1=spec["tau1"], tau2=spec["tau2"],
                               weights={int(k): w for k, w in spec["weights"].items()},
                               forcing=spec["forcing"], limits=limits, link_delays=links)  # fmt: skip
    network = ReceivingSide(links, float(spec["packet_period"]), spec.get("draws"))
    rate = spec.get("rate")
    packet = network.period
    codec = Codec.from_spec(spec["codec"])  # the parent's layouts: no rosbags here
    session = open_session(listen=["tcp/127.0.0.1:0"], connect=[spec["endpoint"]])
    odom: list[Odometry | None] = [None]
    t0_box = [math.inf]
    # sender, stamp, receipt (run clock), lost by the network (position stream), the message's delays (inf: lost)
    received: list[tuple[int, float, float, bool, float, float]] = []

    heard: set[int] = set()

    def on_state(sample: Any) -> None:
        now = time.time()
        sender = int(str(sample.key_expr).split("/")[0].removeprefix("robot_"))
        heard.add(sender)
        o = codec.read_odometry(sender, bytes(sample.payload.to_bytes()))
        t0 = t0_box[0]
        stamp = o.stamp - t0
        c, s = math.cos(o.theta), math.sin(o.theta)
        message, delays = network.apply(NeighbourMessage(sender, stamp, o.x, o.y, o.v * c, o.v * s))
        received.append((sender, stamp, now - t0, delays[0] == math.inf, delays[0], delays[1]))
        if delays[0] < math.inf or delays[1] < math.inf:  # a message with neither part is lost whole
            ctrl.receive(message, delays)

    def on_odom(sample: Any) -> None:
        odom[0] = codec.read_odometry(me, bytes(sample.payload.to_bytes()))

    subs = [(_subscribe(session, key(k, "state")), on_state) for k in ctrl.neighbours]
    subs.append((_subscribe(session, key(me, "odom")), on_odom))
    pub_state = session.declare_publisher(key(me, "state"))
    pub_cmd = session.declare_publisher(key(me, "cmd_vel"))
    put_state, put_cmd = [pub_state.put], [pub_cmd.put]
    if spec.get("ros_domain") is not None:  # also as rmw_zenoh publishes them (delayform.fleet.rmw)
        from delayform.fleet.rmw import RosNode, robot_node

        node = RosNode(session, int(spec["ros_domain"]), robot_node(me))
        put_state.append(node.publisher(f"/{key(me, 'state')}").put)
        put_cmd.append(node.publisher(f"/{key(me, 'cmd_vel')}").put)
    _say("ready")
    t0 = _start_time()
    t0_box[0] = t0
    end = t0 + float(spec["duration"])
    lead = float(spec["lead"])
    # a robot started again mid-run (a fault's restart) joins at its next deadline and ticks once it has heard
    # from every neighbour; until then it only publishes its state (from the world's odometry)
    rejoin = bool(spec.get("rejoin"))
    k = math.ceil((time.time() - t0 - (0.0 if rejoin else lead)) / h)
    ticks: list[tuple[float, ...]] = []  # TICK_COLUMNS
    journal = _Journal(spec["log"])
    flush_at = 0.0
    missed = 0
    accel = 0.0  # the acceleration of the last command (m/s^2)
    sent = 0  # with a sampling rate: the next packet period to send in
    stamps: list[float] = []  # of the states sent since t = 0
    error = ""
    while True:
        deadline = t0 + k * h
        if deadline >= end:
            break
        _wait_until(deadline, subs)
        woke = time.time()
        late = woke - deadline
        if late >= h:  # this deadline and the ones after it passed while the process waited for the CPU
            skip = int(late // h)
            missed += skip if k >= 0 else 0
            k += skip
            continue
        o = odom[0]
        if o is None:  # no odometry yet (only before t = 0: the world publishes from the start)
            k += 1
            continue
        t = woke - t0
        # dead reckoning from the odometry's stamp to the tick, with the acceleration last commanded: the
        # odometry is up to a period old, and a set-point built on its stale speed would cut every acceleration
        age = min(max(woke - o.stamp, 0.0), h)
        v = o.v + accel * age
        th = o.theta + o.omega * age
        mid, vm = 0.5 * (o.theta + th), 0.5 * (o.v + v)
        x, y = o.x + vm * math.cos(mid) * age, o.y + vm * math.sin(mid) * age
        if rate is None or k < 0 or t >= sent * packet - 1e-9:  # sampled: the first tick at or after m / rate
            payload = codec.odometry(me, Odometry(woke, x, y, th, v, o.omega))
            for put in put_state:
                put(payload)
            if k >= 0:
                sent = math.floor(t / packet + 1e-9) + 1
                stamps.append(t)
        if woke >= flush_at:
            journal.append({"received": received, "ticks": ticks, "sent": stamps})
            flush_at = woke + JOURNAL_EVERY
        if rejoin:
            if len(heard) < len(ctrl.neighbours):
                k += 1
                continue
            rejoin = False
        if k >= 0:
            try:
                cmd = ctrl.tick(t, x, y, th, v)
            except Exception as exc:  # a neighbour never heard from, a state that blew up: stop, say why
                error = f"robot {me} at t = {t:.3f} s: {exc}"
                break
            speed = ctrl.speed_command(cmd, h)
            accel = (speed - v) / h
            payload = codec.twist(speed, cmd.turn_rate)
            for put in put_cmd:
                put(payload)
            ticks.append((k * h, late, cmd.lag, time.time() - woke, speed,
                          cmd.speed, cmd.turn_rate, cmd.ideal_turn_rate, cmd.acceleration, cmd.ideal_acceleration))
        k += 1
    rec = np.array(received, dtype=np.float64).reshape(-1, 6)
    tk = np.array(ticks, dtype=np.float64).reshape(-1, len(TICK_COLUMNS))
    from delayform._files import atomic_path

    with atomic_path(spec["log"]) as tmp:  # the parent reads the log whole or not at all
        np.savez(tmp, received=rec, ticks=tk, missed=missed, error=error, sent=np.array(stamps),
                 waiting=np.array(sorted(set(ctrl.neighbours) - heard) if rejoin else [], dtype=np.int64))
    _say("done")
    _close(session)


# ------------------------------------------------------------------ world
def world_main(spec: dict[str, Any]) -> None:
    """The world: commands in, the model integrated in real time, odometry out (module doc).

    Parameters
    ----------
    spec
        The world's part of the run: the model's name, the initial states, the limits, the period and the endpoint.
    """
    import numpy as np

    from delayform.fleet.wire import Codec, Odometry, key, open_session
    from delayform.fleet.world import COMMAND_TIMEOUT, world_model
    from delayform.model.limits import RobotLimits

    n, h = int(spec["n"]), float(spec["period"])
    limits = None if spec["limits"] is None else RobotLimits(**spec["limits"])
    world = world_model(spec["world"], np.asarray(spec["state0"], dtype=np.float64), period=h, limits=limits)
    codec = Codec.from_spec(spec["codec"])  # the parent's layouts: no rosbags here
    session = open_session(listen=["tcp/127.0.0.1:0"], connect=[spec["endpoint"]])
    applied = 0
    t0_box = [math.inf]
    last_cmd = [0.0] * n  # run clock of each robot's last command (t = 0 before the first)
    stopped: list[tuple[int, float]] = []  # (robot from 1, when) the command timeout stopped a robot

    def on_cmd(sample: Any) -> None:  # applied when it arrives (within the polling interval)
        nonlocal applied
        robot = int(str(sample.key_expr).split("/")[0].removeprefix("robot_"))
        speed, turn = codec.read_twist(bytes(sample.payload.to_bytes()))
        at = time.time() - t0_box[0]
        if at >= 0.0:
            world.advance(at)
            last_cmd[robot - 1] = at
        world.command(robot - 1, speed, turn)
        applied += 1

    def time_out(t: float) -> None:  # a robot without commands for COMMAND_TIMEOUT stops, from then on
        for i in range(n):
            due = last_cmd[i] + COMMAND_TIMEOUT
            if due <= t:
                world.advance(max(due, world.time))
                world.command(i, 0.0, 0.0)
                stopped.append((i + 1, due))
                last_cmd[i] = math.inf  # until its next command

    subs = [(_subscribe(session, key(i, "cmd_vel")), on_cmd) for i in range(1, n + 1)]
    puts = [[session.declare_publisher(key(i, "odom")).put] for i in range(1, n + 1)]
    if spec.get("ros_domain") is not None:  # also as rmw_zenoh publishes them (delayform.fleet.rmw)
        from delayform.fleet.rmw import WORLD_NODE, RosNode

        node = RosNode(session, int(spec["ros_domain"]), WORLD_NODE)
        for i in range(1, n + 1):
            puts[i - 1].append(node.publisher(f"/{key(i, 'odom')}").put)
    _say("ready")
    t0 = _start_time()
    t0_box[0] = t0
    end = t0 + float(spec["duration"])
    lead = float(spec["lead"])
    k = math.ceil((time.time() - t0 - lead) / h)
    times, states, omegas, lateness = [], [], [], []
    while True:
        deadline = t0 + k * h
        if deadline > end + 1e-9:
            break
        _wait_until(deadline, subs)  # commands are applied as they arrive, until the next odometry is due
        now = time.time()
        if now - deadline >= h:  # the world fell a period behind: publish now, skip the missed deadlines
            k += int((now - deadline) // h)
            deadline = t0 + k * h
        t = max(now - t0, 0.0)
        if t > 0.0:
            time_out(t)
            world.advance(t)
        s = world.state
        stamp = t0 + world.time if now >= t0 else now  # before t = 0 the robots stand still at their start
        for i in range(n):
            payload = codec.odometry(i + 1, Odometry(stamp, s[i, 0], s[i, 1], s[i, 2], s[i, 3], world.omega[i]))
            for put in puts[i]:
                put(payload)
        if now >= t0:
            times.append(world.time)
            states.append(s.copy())
            omegas.append(world.omega.copy())
            lateness.append(now - deadline)
        k += 1
    from delayform._files import atomic_path

    with atomic_path(spec["log"]) as tmp:  # the parent reads the log whole or not at all
        np.savez(tmp, times=np.array(times), states=np.array(states).reshape(-1, n, 4),
                 omega=np.array(omegas).reshape(-1, n), lateness=np.array(lateness), applied=applied,
                 stopped=np.array(stopped, dtype=np.float64).reshape(-1, 2))  # fmt: skip
    _say("done")
    _close(session)


def main(argv: list[str] | None = None) -> None:
    """Entry point of a child: ``python -m delayform.fleet.agents SPEC.json``.

    Parameters
    ----------
    argv
        The arguments (the spec's path); None reads ``sys.argv``.
    """
    args = sys.argv[1:] if argv is None else argv
    spec = json.loads(Path(args[0]).read_text())
    tie_to_parent(int(spec["parent"]))
    faulthandler.register(signal.SIGUSR1)  # the parent asks a child that does not answer where it is
    try:
        if spec["role"] == "robot":
            robot_main(spec)
        else:
            world_main(spec)
    except BaseException:  # say why on stderr (the parent quotes its last line) and end now: Zenoh's threads
        traceback.print_exc()  # would otherwise keep a failed process alive
        sys.stderr.flush()
        os._exit(1)


if __name__ == "__main__":
    main()
