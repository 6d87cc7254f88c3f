"""Benchmark: the paper's six robots as seven processes over Zenoh for 60 s (delayform fleet).

Run with ``PYTHONPATH=src .venv/bin/python benchmarks/bench_fleet.py [--duration 60] [--period 0.015 0.01]``,
or ``--startup 5`` for the start-up alone (starting the seven processes until every one is ready).
Prints markdown for docs/benchmarks.md.

For each control period (default: the Create's 15 ms, then the Create 3's
10 ms): the paper's example (six robots of Fig. topol, P = 1, D = 0.5,
delays (0.3, 0.2), the Create's limits) run by ``run_fleet`` for the
duration, and from its summary: control ticks missed (a deadline that passed
while the process waited for the CPU) and late (woken more than 0.2 period
after the deadline), the lateness's median / p99 / max, the state messages'
latency (receipt minus the sender's stamp) median / p99 over all links, and
the world's odometry lateness. Goal: no tick missed at the Create's period on
a quiet machine. Peer, in the same run: a bare Zenoh publisher and subscriber
in two processes on the loopback, 100 Hz for 10 s, the one-way latency of the
same 700-byte payload (the transport alone, no delayform). The machine's load
average is printed beside each figure: 2 cores are shared.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from delayform.deploy import robot_profile
from delayform.fleet import run_fleet
from delayform.model import Delays, Team
from delayform.topology import paper_six

_PEER = r"""
import os, sys, time, json, zenoh
mode, port = sys.argv[1], sys.argv[2]
c = zenoh.Config()
c.insert_json5("mode", '"peer"')
c.insert_json5("scouting/multicast/enabled", "false")
if mode == "sub":
    c.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    s = zenoh.open(c)
    lat = []
    sub = s.declare_subscriber("peer/x", lambda m: lat.append(time.time() - float(bytes(m.payload.to_bytes())[:20])))
    print("ready", flush=True)
    end = time.time() + 30
    while len(lat) < 1000 and time.time() < end:
        time.sleep(0.1)
    print(json.dumps(lat), flush=True)
    os._exit(0)
else:
    c.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    s = zenoh.open(c)
    p = s.declare_publisher("peer/x")
    time.sleep(1.0)
    t0 = time.time()
    for k in range(1000):
        while time.time() < t0 + 0.01 * k:
            time.sleep(0.0005)
        p.put(f"{time.time():<20.6f}".encode() + b"x" * 680)
    time.sleep(0.5)
    os._exit(0)
"""


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def peer_latency() -> dict[str, float]:
    """One-way latency of bare Zenoh on the loopback (two processes, 100 Hz, 10 s)."""
    port = str(_free_port())
    sub = subprocess.Popen([sys.executable, "-c", _PEER, "sub", port], stdout=subprocess.PIPE, text=True)
    assert sub.stdout is not None
    sub.stdout.readline()
    pub = subprocess.Popen([sys.executable, "-c", _PEER, "pub", port])
    pub.wait(60)
    import json

    lat = np.array(json.loads(sub.stdout.readline()))
    sub.wait(60)
    return {"count": int(lat.size), "median_ms": 1e3 * float(np.median(lat)), "p99_ms": 1e3 * float(np.quantile(lat, 0.99))}


def bench_fleet(duration: float, period: float) -> dict[str, object]:
    with tempfile.TemporaryDirectory() as out:
        load = os.getloadavg()[0]
        t = time.perf_counter()
        run = run_fleet(Team(paper_six(), 1.0, 0.5), Delays(0.3, 0.2), "hexagon", out=Path(out), duration=duration,
                        period=period, robot=robot_profile("create"), endpoint=f"tcp/127.0.0.1:{_free_port()}")  # fmt: skip
        wall = time.perf_counter() - t
    s = run.summary
    lateness = np.array([r["lateness_s"]["p99"] for r in s["robots"]])
    latency_med = np.median([link["latency_s"]["median"] for link in s["links"]])
    latency_p99 = np.max([link["latency_s"]["p99"] for link in s["links"]])
    return {
        "period": period, "load": load, "wall": wall, "ticks": sum(r["ticks_run"] for r in s["robots"]),
        "missed": s["team"]["ticks_missed"], "late": s["team"]["ticks_late"],
        "lateness_median_ms": 1e3 * float(np.median([r["lateness_s"]["median"] for r in s["robots"]])),
        "lateness_p99_ms": 1e3 * float(lateness.max()),
        "lateness_max_ms": 1e3 * max(r["lateness_s"]["max"] for r in s["robots"]),
        "latency_median_ms": 1e3 * float(latency_med), "latency_p99_ms": 1e3 * float(latency_p99),
        "world_p99_ms": 1e3 * s["run"]["world_lateness_s"]["p99"],
        "decay": (s["team"]["dominant_decay_rate"], s["team"]["measured_decay_rate"], s["team"]["simulator_decay_rate"]),
    }  # fmt: skip


#: what a robot's process imports before it says 'ready' (delayform.fleet.agents.robot_main), timed alone
_CHILD_IMPORTS = (
    "import time; t = time.perf_counter()\n"
    "import json, sys\n"
    "from delayform.deploy.controller import FormationController\n"
    "from delayform.fleet.wire import Codec, open_session\n"
    "Codec.from_spec(json.loads(sys.argv[1]))\n"
    "print(time.perf_counter() - t)\n"
)


def bench_startup(repeat: int) -> None:
    """Seconds from starting the seven processes to the run's start (every one 'ready'), median and best."""
    waits = []
    for _ in range(repeat):
        marks: dict[str, float] = {}
        with tempfile.TemporaryDirectory() as out:
            run_fleet(Team(paper_six(), 1.0, 0.5), Delays(0.3, 0.2), "hexagon", out=Path(out), duration=1.0,
                      period=0.01, robot=robot_profile("create3"), endpoint=f"tcp/127.0.0.1:{_free_port()}",
                      progress=lambda text: marks.setdefault(text.split()[0], time.perf_counter()))  # fmt: skip
        waits.append(marks["running"] - marks["starting"])
    from delayform.fleet.wire import Codec

    spec = json.dumps(Codec(6).spec())  # what the parent hands each process
    imports = [float(subprocess.run([sys.executable, "-c", _CHILD_IMPORTS, spec], capture_output=True, text=True,
                                    check=True).stdout) for _ in range(repeat)]  # fmt: skip
    print(f"Start-up of the paper's six (seven processes, Create 3), {repeat} runs, load avg "
          f"{os.getloadavg()[0]:.2f}: median {np.median(waits):.2f} s, best {min(waits):.2f} s; one robot "
          f"process's imports alone: median {np.median(imports):.3f} s")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--period", type=float, nargs="+", default=[0.015, 0.01])
    parser.add_argument("--startup", type=int, default=0, help="only the start-up, this many runs")
    args = parser.parse_args()
    print(f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}\n")  # fmt: skip
    if args.startup:
        bench_startup(args.startup)
        return
    print("| period | load avg | ticks run | missed | late (>0.2 h) | lateness median / p99 / max | "
          "state latency median / p99 | world odometry p99 | wall |")
    print("|---|---|---|---|---|---|---|---|---|")
    for h in args.period:
        r = bench_fleet(args.duration, h)
        print(f"| {1e3 * h:g} ms | {r['load']:.2f} | {r['ticks']} | {r['missed']} | {r['late']} | "
              f"{r['lateness_median_ms']:.2f} / {r['lateness_p99_ms']:.2f} / {r['lateness_max_ms']:.1f} ms | "
              f"{r['latency_median_ms']:.2f} / {r['latency_p99_ms']:.2f} ms | {r['world_p99_ms']:.2f} ms | "
              f"{r['wall']:.0f} s |", flush=True)  # fmt: skip
        print(f"<!-- decay rate: dominant root / fleet / simulator: {r['decay']} -->", flush=True)
    load = os.getloadavg()[0]
    p = peer_latency()
    print(f"\nPeer (bare Zenoh, two processes, 100 Hz, 700-byte payload, load avg {load:.2f}): "
          f"{p['count']} messages, one-way latency median {p['median_ms']:.3f} ms, p99 {p['p99_ms']:.3f} ms")  # fmt: skip


if __name__ == "__main__":
    main()
