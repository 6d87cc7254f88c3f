"""Benchmark: the on-robot controller's tick, and MCAP export of 10^6 robot-steps (issue 22).

Run with ``.venv/bin/python benchmarks/bench_deploy.py``. Prints markdown
for docs/benchmarks.md.

1. ``FormationController.tick`` for one robot with 10 neighbours (C_ik =
   1/10), Create 3 limits, delays (0.3, 0.2) s, every neighbour sending at
   100 Hz (so each playout buffer holds about 30 messages): the median of
   many ticks, with and without receiving the ten messages of the period.
   Goal: under 50 microseconds. Peer: the simulation's own vectorized model
   (``LimitedUnicycle.rhs`` on one robot, after the same neighbour sums with
   NumPy), the code the tick is checked against.
2. ``write_mcap`` of 100 ideal robots (complete graph, a settling run) over 100 s at 100 Hz (10^4 saved
   steps: 10^6 Twists, 10^6 PoseStamped, 10^4 TFMessages of 100 transforms).
   Goal: under 20 s. Peer: the plain way with the same libraries, one
   ``Typestore.serialize_cdr`` and one ``Writer.add_message`` per message,
   timed on the first 500 steps and scaled (it is linear in the messages).
3. ``write_mcap`` of the paper's six robots (Create 3 limits) over 60 s at dt = 0.01 and 0.03
   (6,001 and 2,001 saved steps) with the topology: Odometry, Twist, PoseStamped, /tf, the
   markers and the metadata; best and median of 5, and the file size. ``--paper`` runs only this.
"""

from __future__ import annotations

import io
import os
import platform
import statistics
import tempfile
import time

import numpy as np

from delayform.deploy import FormationController, NeighbourMessage, robot_profile
from delayform.deploy.recording import MCAP_TOPICS, write_mcap
from delayform.simulation import simulate
from delayform.simulation.models.robots import LimitedUnicycle
from delayform.topology import complete


def bench_tick(repeats: int = 20000) -> dict[str, float]:
    limits = robot_profile("create3").limits
    ctrl = FormationController(robot=1, P=1.0, D=0.5, tau1=0.3, tau2=0.2, weights={k: 0.1 for k in range(2, 12)},
                               forcing=(0.2, -0.1), limits=limits)  # fmt: skip
    rng = np.random.default_rng(0)
    period = 0.01
    for j in range(40):
        for k in range(2, 12):
            ctrl.receive(NeighbourMessage(k, j * period, *rng.normal(size=4)))
    t = 40 * period
    ticks, with_receive = [], []
    msgs = [NeighbourMessage(k, t, *rng.normal(size=4)) for k in range(2, 12)]
    for r in range(repeats):
        now = t + r * period
        msgs = [m._replace(stamp=now) for m in msgs]
        a = time.perf_counter()
        ctrl.receive_all(msgs)
        b = time.perf_counter()
        ctrl.tick(now, 0.1, -0.2, 0.3, 0.15)
        c = time.perf_counter()
        ticks.append(c - b)
        with_receive.append(c - a)
    # the peer: the simulation's model for one robot, neighbour sums with NumPy
    model = LimitedUnicycle(np.zeros((1, 2)), np.zeros(1), np.zeros(1), limits)
    w = np.full(10, 0.1)
    X, V = rng.normal(size=(10, 2)), rng.normal(size=(10, 2))
    state = np.array([[0.1, -0.2, 0.3, 0.15]])
    peer = []
    for _ in range(repeats // 4):
        a = time.perf_counter()
        cx, cv = w @ X, w @ V
        vel = model.velocity(state)
        u = 1.0 * (cx - state[:, :2]) + 0.5 * (cv - vel) + np.array([[0.2, -0.1]])
        model.rhs(state, u)
        peer.append(time.perf_counter() - a)
    return {"tick": statistics.median(ticks), "tick_p99": float(np.quantile(ticks, 0.99)),
            "tick_receive": statistics.median(with_receive), "peer": statistics.median(peer)}  # fmt: skip


def bench_mcap() -> dict[str, float]:
    n = 100
    traj = simulate(complete(n), 1.0, 1.0, 0.2, 0.1, "polygon", duration=100.0, dt=0.01, save_every=1,
                    initial_speed=0.05, seed=0)  # fmt: skip
    assert traj.times.size == 10001
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "run.mcap")
        a = time.perf_counter()
        write_mcap(traj, path)
        seconds = time.perf_counter() - a
        size = os.path.getsize(path)
    return {"seconds": seconds, "bytes": float(size), "steps": float(traj.times.size), "peer_seconds": _peer(traj)}


def bench_mcap_paper(repeats: int = 5) -> list[dict[str, float]]:
    from delayform.topology import paper_six

    out = []
    for dt in (0.01, 0.03):
        traj = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", limits=robot_profile("create3").limits,
                        duration=60.0, dt=dt, seed=0)  # fmt: skip
        with tempfile.TemporaryDirectory() as folder:
            path = os.path.join(folder, "run.mcap")
            times = []
            for _ in range(repeats):
                a = time.perf_counter()
                write_mcap(traj, path, topology=paper_six())
                times.append(time.perf_counter() - a)
            size = os.path.getsize(path)
        out.append({"dt": dt, "steps": float(traj.times.size), "best": min(times), "median": statistics.median(times),
                    "bytes": float(size)})  # fmt: skip
    return out


def _peer(traj, steps: int = 500) -> float:
    """The plain way: one serialize_cdr and one add_message per message; scaled to the whole run."""
    from mcap.writer import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    V3 = T["geometry_msgs/msg/Vector3"]
    n = traj.positions.shape[1]
    writer = Writer(io.BytesIO())
    writer.start("ros2", "peer")
    sid = writer.register_schema(MCAP_TOPICS["cmd_vel"], "ros2msg", b"")
    sid2 = writer.register_schema(MCAP_TOPICS["pose"], "ros2msg", b"")
    tw = [writer.register_channel(f"/robot_{i + 1}/cmd_vel", "cdr", sid) for i in range(n)]
    po = [writer.register_channel(f"/robot_{i + 1}/pose", "cdr", sid2) for i in range(n)]
    Twist, PS = T["geometry_msgs/msg/Twist"], T["geometry_msgs/msg/PoseStamped"]
    Pose, Pt, Q = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    H, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    cmd = traj.commands
    a = time.perf_counter()
    for k in range(steps):
        ns = int(round(traj.times[k] * 1e9))
        for i in range(n):
            twist = Twist(linear=V3(x=float(cmd.speed[k, i]), y=0.0, z=0.0), angular=V3(x=0.0, y=0.0, z=float(cmd.turn_rate[k, i])))
            writer.add_message(tw[i], ns, store.serialize_cdr(twist, MCAP_TOPICS["cmd_vel"]), ns)
            th = float(traj.headings[k, i])
            pose = PS(header=H(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="world"),
                      pose=Pose(position=Pt(x=float(traj.positions[k, i, 0]), y=float(traj.positions[k, i, 1]), z=0.0),
                                orientation=Q(x=0.0, y=0.0, z=np.sin(th / 2), w=np.cos(th / 2))))  # fmt: skip
            writer.add_message(po[i], ns, store.serialize_cdr(pose, MCAP_TOPICS["pose"]), ns)
    writer.finish()
    return (time.perf_counter() - a) * traj.times.size / steps


def main() -> None:
    import sys

    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    load = os.getloadavg()[0]
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, {when}, load average {load:.1f} (shared machine)")  # fmt: skip
    print("\n| paper's six robots, 60 s | saved steps | best (s) | median (s) | size (MiB) |\n|---|---|---|---|---|")
    for r in bench_mcap_paper():
        print(f"| dt = {r['dt']:g} | {r['steps']:.0f} | {r['best']:.2f} | {r['median']:.2f} | {r['bytes'] / 2**20:.2f} |")
    if "--paper" in sys.argv:
        return
    tick = bench_tick()
    print("\n| what | median | goal |\n|---|---|---|")
    print(f"| `tick` (10 neighbours, Create 3 limits) | {tick['tick'] * 1e6:.1f} us (99 %: {tick['tick_p99'] * 1e6:.1f} us) | < 50 us |")
    print(f"| `receive` x 10 + `tick` | {tick['tick_receive'] * 1e6:.1f} us | |")
    print(f"| peer: the simulation's NumPy model for one robot | {tick['peer'] * 1e6:.1f} us | |")
    mc = bench_mcap()
    print("\n| what | seconds | goal |\n|---|---|---|")
    print(f"| `write_mcap`: 100 robots x 10^4 steps (2 x 10^6 + 10^4 messages, {mc['bytes'] / 1e6:.0f} MB) "
          f"| {mc['seconds']:.1f} | < 20 |")  # fmt: skip
    print(f"| peer: one serialize_cdr + add_message per message (500 steps, scaled) | {mc['peer_seconds']:.1f} | |")


if __name__ == "__main__":
    main()
