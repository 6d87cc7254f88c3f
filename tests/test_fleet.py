"""delayform fleet: the team as processes over Zenoh, measured against the analysis (delayform.fleet)."""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("zenoh")
pytest.importorskip("mcap_ros2")

from cli_runner import run_in_process

from delayform import dominant_root
from delayform.cli.fleet import WORLD_NAMES
from delayform.deploy import robot_profile
from delayform.errors import FleetError
from delayform.fleet import decay_rate, run_fleet
from delayform.fleet.run import check_network
from delayform.fleet.wire import Codec, Odometry, check_endpoint
from delayform.fleet.world import WORLDS, KinematicWorld
from delayform.formation import named_formation
from delayform.model import Delays, Start, Team
from delayform.simulation import simulate
from delayform.model.network import BernoulliLoss, Jitter, MeasurementNoise, Network, Sampling, SmoothVariation
from delayform.simulation.delayed.reception import packet_draws, reception
from delayform.topology import complete, paper_six

ROOT = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie (ended, not yet reaped by a parent that is itself gone) counts as ended
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except OSError:
        return False


def _children_of(folder: Path) -> list[int]:
    """PIDs of fleet processes whose spec lies in ``folder`` (from the process table)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmd = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"delayform.fleet.agents" in cmd and any(str(folder).encode() in c for c in cmd):
            found.append(int(entry.name))
    return [p for p in found if _alive(p)]


# ------------------------------------------------------------------ fast pieces
def test_world_names_of_the_cli_are_the_library_s() -> None:
    assert WORLD_NAMES == WORLDS


def test_codec_round_trips_and_matches_rosbags() -> None:
    from rosbags.typesys import Stores, get_typestore

    codec = Codec(3)
    odom = Odometry(1733390000.25, 1.5, -2.0, 0.7, 0.3, -0.2)
    data = codec.odometry(2, odom)
    back = codec.read_odometry(2, data)
    assert back.stamp == pytest.approx(odom.stamp, abs=1e-9)
    assert back[1:] == pytest.approx(odom[1:], abs=1e-12)
    # rosbags' own deserializer (a second decoder) reads the same fields
    store = get_typestore(Stores.ROS2_HUMBLE)
    msg = store.deserialize_cdr(data, "nav_msgs/msg/Odometry")
    assert msg.child_frame_id == "robot_2/base_link"
    assert msg.pose.pose.position.x == 1.5 and msg.twist.twist.linear.x == 0.3
    assert msg.header.stamp.sec == 1733390000 and msg.header.stamp.nanosec == 250_000_000
    tw = store.deserialize_cdr(codec.twist(0.1, -0.4), "geometry_msgs/msg/Twist")
    assert (tw.linear.x, tw.angular.z) == (0.1, -0.4)


def test_kinematic_world_reaches_the_set_point_in_one_period_and_drives_a_circle() -> None:
    world = KinematicWorld(np.array([[0.0, 0.0, 0.0, 0.0]]), period=0.1, limits=None, step=0.001)
    world.command(0, 0.2, 0.0)
    world.advance(0.1)
    assert world.state[0, 3] == pytest.approx(0.2, abs=1e-12)
    assert world.state[0, 0] == pytest.approx(0.5 * 0.2 * 0.1, rel=1e-9)  # constant acceleration 2 m/s^2
    world.advance(0.3)  # a command that comes late leaves the robot at its set-point
    assert world.state[0, 3] == pytest.approx(0.2, abs=1e-12)
    # a full turn at v = 0.2, omega = 1: back where it started (closed form: a circle of radius 0.2)
    w2 = KinematicWorld(np.array([[0.0, 0.0, 0.0, 0.2]]), period=0.1, limits=None, step=0.001)
    w2.command(0, 0.2, 1.0)
    w2.advance(2 * math.pi)
    assert np.hypot(*w2.state[0, :2]) < 1e-6


def test_endpoint_checks() -> None:
    assert check_endpoint("tcp/127.0.0.1:7447") == ("127.0.0.1", 7447)
    for bad in ("udp/127.0.0.1:7447", "tcp/10.0.0.1:7447", "tcp/127.0.0.1:x", "tcp/127.0.0.1:70000", "127.0.0.1:7447"):
        with pytest.raises(FleetError):
            check_endpoint(bad)


def test_every_part_of_a_network_is_applied() -> None:
    assert check_network(Network()) is None
    assert check_network(Network(loss=BernoulliLoss(0.1))) is not None
    assert check_network(Network(sampling=Sampling(20.0), noise=MeasurementNoise(0.01, 0.01))) is not None
    assert check_network(Network(jitter=Jitter(0.01, 0.01))) is not None  # applied per message (test_fleet_links)
    assert check_network(Network(variation=SmoothVariation(0.05, 0.05, 5.0))) is not None  # test_fleet_links


def test_packet_draws_are_the_simulator_s() -> None:
    """The packets the simulator's reception never hears are exactly the ones packet_draws drops."""
    topo = complete(3)
    net = Network(loss=BernoulliLoss(0.3), seed=7)
    dt, steps = 0.05, 60
    rec = reception(net, topo, 0.3, 0.2, dt=dt, steps=steps)
    packets = math.floor((steps + 1) * dt / dt + 1e-9) + 1
    draws = packet_draws(net, topo, packets=packets)
    rows, cols, lost = draws.receivers, draws.informers, draws.lost
    assert lost is not None and draws.noise is None
    assert (rows == rec.receivers).all() and (cols == rec.informers).all()
    for s in range(2):
        heard = rec.packet[s]
        for e in range(rows.size):
            got = set(np.unique(heard[..., e])) - {-1}
            # every packet that arrives before the end is heard (constant delays, one packet per step)
            arrived = {m for m in range(packets) if m * dt + (0.3, 0.2)[s] <= (steps + 1) * dt + 1e-9}
            assert got == {m for m in arrived if not lost[s, m, e]}


def test_packet_noise_is_the_simulator_s() -> None:
    topo = paper_six()
    net = Network(loss=BernoulliLoss(0.1), noise=MeasurementNoise(0.02, 0.01), seed=5)
    rec = reception(net, topo, 0.3, 0.2, dt=0.05, steps=40)
    draws = packet_draws(net, topo, packets=42)
    assert draws.noise is not None
    for s in range(2):
        assert rec.noise[s] is not None and np.array_equal(draws.noise[s], rec.noise[s])


def test_decay_rate_of_an_exponential() -> None:
    t = np.linspace(0.0, 20.0, 2001)
    assert decay_rate(t, 2.0 * np.exp(-0.3 * t)) == pytest.approx(0.3, rel=1e-9)


# ------------------------------------------------------------------ runs
def _near_hexagon() -> np.ndarray:
    """The hexagon with each robot moved along x: the unicycles start where they need no turn (linear regime)."""
    x0 = named_formation("hexagon", 6, spacing=2.0)
    x0[:, 0] += np.array([0.35, -0.3, 0.2, -0.25, 0.3, -0.15])
    return x0


@pytest.mark.slow
def test_a_run_of_the_paper_s_six(tmp_path: Path) -> None:
    """One run (seven processes, 10 s), four checks: one test, so that xdist workers do not each start the run."""
    out = tmp_path
    run = run_fleet(Team(paper_six(), 1.0, 1.5), Delays(0.3, 0.2), named_formation("hexagon", 6, spacing=2.0),
                    out=out, duration=10.0, period=0.01,
                    robot=robot_profile("create3"), start=Start(_near_hexagon(), np.zeros(6), speed=0.0), endpoint=f"tcp/127.0.0.1:{_free_port()}")  # fmt: skip
    _converges_at_the_dominant_root_s_rate(run)
    _applies_the_design_s_delays(run)
    _recording_decodes_with_mcap_ros2(run, out)
    _no_process_survives(run, out)


def _converges_at_the_dominant_root_s_rate(run: Any) -> None:
    """Six processes at the paper's delays (0.3, 0.2), D = 1.5: error down 10x in 10 s, decay within 30 % of -Re s."""
    team = run.summary["team"]
    root = dominant_root(paper_six(), 1.0, 1.5, 0.3, 0.2).formation_root
    assert team["chart_verdict"] == "stable"
    assert team["dominant_decay_rate"] == pytest.approx(-root.real)
    assert team["error_reduction"] > 10.0
    assert team["measured_decay_rate"] == pytest.approx(-root.real, rel=0.3)
    # the fit itself, on the simulator's run of the same team (its own check, independent of the processes)
    assert team["simulator_decay_rate"] == pytest.approx(-root.real, rel=0.3)


def _applies_the_design_s_delays(run: Any) -> None:
    """The playout buffer applies tau1, tau2 within one control period on every link (the median tick)."""
    h = 0.01
    links = run.summary["links"]
    assert len(links) == int(paper_six().adjacency.sum())
    for link in links:
        assert 0.3 - 1e-6 <= link["applied_tau1_s"]["median"] <= 0.3 + h
        assert 0.2 - 1e-6 <= link["applied_tau2_s"]["median"] <= 0.2 + h
        assert link["latency_s"]["median"] < 0.2  # the loopback is faster than the design
        assert link["received"] >= 0.95 * link["sent"]


def _recording_decodes_with_mcap_ros2(run: Any, out: Path) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    counts: dict[str, int] = {}
    frames = set()
    with open(out / "fleet.mcap", "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for _, channel, message, decoded in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic.endswith("/odom"):
                frames.add(decoded.child_frame_id)
                assert math.isfinite(decoded.pose.pose.position.x)
            elif channel.topic.endswith("/cmd_vel"):
                assert abs(decoded.linear.x) <= robot_profile("create3").limits.max_speed + 1e-9
    recorded = run.summary["run"]["messages_recorded"]
    assert counts == {"/" + k: v for k, v in recorded.items()}
    assert frames == {f"robot_{i}/base_link" for i in range(1, 7)}
    assert counts["/robot_1/cmd_vel"] >= 0.9 * 10.0 / 0.01


def _no_process_survives(run: Any, out: Path) -> None:
    pids = run.summary["run"]["pids"]
    assert len(pids) == 7
    assert not [p for p in pids.values() if _alive(p)]
    assert not list(out.glob(".fleet-*"))  # the specs and logs went with the run


@pytest.mark.slow
def test_the_paper_s_unstable_point_c_does_not_converge(tmp_path: Path) -> None:
    """D = 0.5, delays (1, 2): the chart says unstable, and from the start where D = 1.5 converges 10x, the fleet does not.

    The fleet's error follows the simulator's (which the chart's verdict is checked against elsewhere):
    its largest swing over the second half of the run within 50 % of the simulator's.
    """
    root = dominant_root(paper_six(), 1.0, 0.5, 1.0, 2.0).formation_root
    assert root.real > 0.0
    duration = 10.0
    run = run_fleet(Team(paper_six(), 1.0, 0.5), Delays(1.0, 2.0), named_formation("hexagon", 6, spacing=2.0),
                    out=tmp_path, duration=duration, period=0.02, robot=robot_profile("create3"),
                    start=Start(_near_hexagon(), np.zeros(6), speed=0.0), endpoint=f"tcp/127.0.0.1:{_free_port()}")  # fmt: skip
    team = run.summary["team"]
    assert team["chart_verdict"] == "unstable"
    assert team["error_reduction"] < 10.0
    assert team["final_error_m"] > 0.3 * team["initial_error_m"]
    late, sim_late = run.times >= duration / 2, run.sim_times >= duration / 2
    assert run.error[late].max() == pytest.approx(run.sim_error[sim_late].max(), rel=0.5)


@pytest.mark.slow
def test_network_loss_drops_messages_at_its_rate(tmp_path: Path) -> None:
    """Bernoulli loss 0.2 and sampling at 50 Hz: 50 states a second per link, 20 % dropped (4-sigma binomial bound)."""
    p, rate, duration = 0.2, 50.0, 6.0
    net = Network(loss=BernoulliLoss(p), sampling=Sampling(rate), seed=3)
    run = run_fleet(Team(complete(3), 1.0, 1.5), Delays(0.3, 0.2), "polygon", out=tmp_path, duration=duration,
                    period=0.01, robot=robot_profile("create3"), start=Start(seed=1), network=net,
                    endpoint=f"tcp/127.0.0.1:{_free_port()}")  # fmt: skip
    links = run.summary["links"]
    assert len(links) == 6
    for link in links:  # one state per 20 ms period (the run's last 0.1 s not counted)
        assert abs(link["sent"] - rate * (duration - 0.1)) <= 3
        assert link["received"] >= 0.99 * link["sent"]
    received = sum(link["received"] for link in links)
    dropped = sum(link["dropped_by_network"] for link in links)
    assert abs(dropped - p * received) <= 4 * math.sqrt(received * p * (1 - p))
    assert run.summary["team"]["network_loss_rate"] == p


def _cli(*args: str, **kw: object) -> subprocess.Popen[bytes]:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    return subprocess.Popen([sys.executable, "-m", "delayform", "fleet", *args], env=env, cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)  # type: ignore[call-overload]


@pytest.mark.slow
def test_the_command_writes_its_page_and_prints_json(tmp_path: Path) -> None:
    scenario = tmp_path / "three.toml"
    scenario.write_text('name = "three"\n[topology]\nname = "complete"\nn = 3\n[gains]\nP = 1.0\nD = 1.5\n'
                        '[delays]\ntau1 = 0.3\ntau2 = 0.2\n[formation]\nshape = "polygon"\n[robot]\nprofile = "create3"\n')  # fmt: skip
    out = tmp_path / "out"
    proc = _cli(str(scenario), "--duration", "3", "--out", str(out), "--json", "--endpoint", f"tcp/127.0.0.1:{_free_port()}")
    stdout, stderr = proc.communicate(timeout=180)
    assert proc.returncode == 0, stderr
    summary = json.loads(stdout)
    assert summary["run"]["period"] == 0.01  # the Create 3's control period
    assert summary["team"]["chart_verdict"] == "stable"
    assert {p.name for p in out.iterdir()} >= {"fleet.mcap", "summary.json", "summary.txt", "fleet_error.png", "fleet_error.svg"}
    assert json.loads((out / "summary.json").read_text())["links"] == summary["links"]
    text = (out / "summary.txt").read_text()
    assert "dominant root" in text and "3 <- 1" in text


def test_a_bad_scenario_exits_2_with_one_line_before_any_process(tmp_path: Path) -> None:
    bad = tmp_path / "variation.toml"  # the velocity delay 0.2 s less its variation 0.25 s: messages from the future
    bad.write_text((ROOT / "examples" / "paper.toml").read_text()
                   + "\n[network]\nvariation = { amplitude = [0.05, 0.25], period = 5.0 }\n")
    for args in ([str(bad)], ["--endpoint", "tcp/10.1.2.3:7447"], ["--tau1", "-1"]):
        # in this process (a fresh interpreter per case cost a second each): the refusal is the CLI's own
        proc = run_in_process("fleet", *args, "--duration", "5", "--out", str(tmp_path / "out"), cwd=tmp_path, timeout=120)
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 2, proc.stderr
        assert len(lines) == 1 and lines[0].startswith("delayform: error:"), lines
        assert not _children_of(tmp_path)
    assert not (tmp_path / "out" / "fleet.mcap").exists()


def test_a_port_in_use_exits_2(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc = run_in_process("fleet", "--duration", "5", "--endpoint", f"tcp/127.0.0.1:{port}", "--out", str(tmp_path),
                              cwd=tmp_path, timeout=120)  # fmt: skip
    assert proc.returncode == 2
    assert "already taken" in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


@pytest.mark.slow
@pytest.mark.parametrize("how", ["SIGINT", "SIGKILL"])
def test_no_orphan_when_the_command_is_interrupted_or_killed(tmp_path: Path, how: str) -> None:
    """Ctrl-C (SIGINT to the command) and SIGKILL of the command: every robot and world process ends."""
    scenario = tmp_path / "three.toml"
    scenario.write_text('name = "three"\n[topology]\nname = "complete"\nn = 3\n[gains]\nP = 1.0\nD = 1.5\n'
                        '[delays]\ntau1 = 0.3\ntau2 = 0.2\n[formation]\nshape = "polygon"\n')  # fmt: skip
    proc = _cli(str(scenario), "--duration", "60", "--out", str(tmp_path / "out"),
                "--endpoint", f"tcp/127.0.0.1:{_free_port()}")  # fmt: skip
    try:
        deadline = time.monotonic() + 90
        while len(kids := _children_of(tmp_path)) < 4:
            assert proc.poll() is None, proc.communicate()[1]
            assert time.monotonic() < deadline, "the processes did not start"
            time.sleep(0.2)
        time.sleep(1.0)
        proc.send_signal(getattr(signal, how))
        proc.wait(timeout=30)
        deadline = time.monotonic() + 10
        while [p for p in kids if _alive(p)] and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not [p for p in kids if _alive(p)]
        if how == "SIGINT":
            assert proc.returncode == 130
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


def test_a_robot_and_the_world_start_without_scipy_or_the_simulator() -> None:
    """What a robot's and the world's process import to reach 'ready': no SciPy, simulator, formation algebra or rosbags.

    Seven processes start at once on the machine that runs the team; each used to import SciPy
    (half a second of CPU), which held the start of a six-robot run by about 3.5 s on two cores.
    """
    code = (
        "import sys\n"
        "from delayform.fleet.agents import ReceivingSide\n"
        "from delayform.deploy.controller import FormationController, NeighbourMessage\n"
        "from delayform.fleet.wire import Codec, Odometry, key, open_session\n"
        "from delayform.fleet.world import COMMAND_TIMEOUT, world_model\n"
        "from delayform.model.limits import RobotLimits\n"
        "FormationController(robot=1, P=1.0, D=1.5, tau1=0.3, tau2=0.2, weights={2: 1.0}, forcing=[0.0, 0.0])\n"
        "import json\n"
        "Codec.from_spec(json.loads(sys.argv[1])).odometry(2, Odometry(1.5, 0.1, 0.2, 0.3, 0.4, 0.5))\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'matplotlib', 'networkx', 'rosbags'}),"
        " sorted(m for m in sys.modules if m.startswith(('delayform.simulation.', 'delayform.formation', 'delayform.topology'))))\n"
    )
    done = subprocess.run([sys.executable, "-c", code, json.dumps(Codec(3).spec())], capture_output=True, text=True,
                          timeout=120, check=False,
                          env={**os.environ, "PYTHONPATH": str(ROOT / "src")})  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[] []", done.stdout


def test_a_codec_rebuilt_from_its_spec_encodes_the_same_bytes() -> None:
    """The parent's layouts, as the JSON each process gets, give rosbags' bytes back (the codec's own check above)."""
    codec = Codec(4)
    copy = Codec.from_spec(json.loads(json.dumps(codec.spec())))
    rng = np.random.default_rng(8)
    for i in range(1, 5):
        odom = Odometry(1.7e9 + rng.uniform(0, 100), *rng.normal(size=5))
        assert copy.odometry(i, odom) == codec.odometry(i, odom)
        assert copy.read_odometry(i, codec.odometry(i, odom)) == codec.read_odometry(i, codec.odometry(i, odom))
    assert copy.twist(0.3, -0.2) == codec.twist(0.3, -0.2)
    spec = codec.spec()
    spec["twist"]["offsets"] = [10_000] * len(spec["twist"]["offsets"])  # a field outside its template: refused
    with pytest.raises(FleetError, match="do not fit"):
        Codec.from_spec(spec)
