"""MCAP recordings: written with rosbags + mcap, read back with mcap-ros2-support's own CDR decoder.

The decoder builds its parser from the ``ros2msg`` schema text in the file,
independently of the rosbags encoder (and of the layouts
:mod:`delayform.deploy.recording` takes from it); what it reads must be the
trajectory and command files, value for value. The replay tests read the
odometry back from the file and feed it to each robot's
:class:`FormationController`, built from the file's metadata alone; the
commands it computes must be the recorded Twists.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from delayform.deploy import FormationController, NeighbourMessage, robot_profile
from delayform.deploy.recording import check_mcap_path, recording_start, write_mcap
from delayform.simulation.models.robots import RobotLimits
from delayform.errors import RecordingError
from delayform.simulation import simulate
from delayform.topology import paper_six


def _read(path: Path) -> dict[str, list]:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out: dict[str, list] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=True):
            out.setdefault(channel.topic, []).append((message.log_time, schema.name, decoded))
    return out


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mcap")
    traj = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", limits=robot_profile("robotarium").limits,
                    duration=6.0, dt=0.02, save_every=2, seed=4)  # fmt: skip
    path = write_mcap(traj, folder / "run.mcap", topology=paper_six())
    traj.to_csv(folder / "traj.csv")
    traj.commands.to_csv(folder / "commands.csv")
    return traj, path, folder


_PER_STEP = {"cmd_vel": "geometry_msgs/msg/Twist", "pose": "geometry_msgs/msg/PoseStamped", "odom": "nav_msgs/msg/Odometry"}


def test_topics_types_and_one_message_per_robot_per_saved_step(run):
    traj, path, _ = run
    got = _read(path)
    n, T = traj.positions.shape[1], traj.times.size
    expected = {f"/robot_{i}/{k}" for i in range(1, n + 1) for k in _PER_STEP} | {
        "/tf", "/tf_static", "/formation/bodies", "/formation/slots", "/formation/links"}
    assert set(got) == expected
    stamps = np.rint(traj.times * 1e9).astype(np.int64)
    for topic, msgs in got.items():
        kind = topic.rsplit("/", 1)[1]
        if kind in _PER_STEP or topic == "/tf":
            assert {name for _, name, _ in msgs} == {_PER_STEP.get(kind, "tf2_msgs/msg/TFMessage")}
            np.testing.assert_array_equal([t for t, _, _ in msgs], stamps)
        elif topic in ("/tf_static", "/formation/bodies", "/formation/slots"):
            assert [t for t, _, _ in msgs] == [0]  # once, at the start
    # the graph at 20 Hz: the saved steps are 0.04 s apart, so every other one
    np.testing.assert_array_equal([t for t, _, _ in got["/formation/links"]], stamps[::2])


def test_values_are_those_of_the_command_and_trajectory_files(run):
    traj, path, folder = run
    got = _read(path)
    n, T = traj.positions.shape[1], traj.times.size
    cmd = np.loadtxt(folder / "commands.csv", delimiter=",", skiprows=1)  # time, robot, v, omega, ...
    tr = np.loadtxt(folder / "traj.csv", delimiter=",", skiprows=1)  # time, agent, x, y, heading, speed, ...
    v = np.array([[m.linear.x for _, _, m in got[f"/robot_{i}/cmd_vel"]] for i in range(1, n + 1)]).T
    w = np.array([[m.angular.z for _, _, m in got[f"/robot_{i}/cmd_vel"]] for i in range(1, n + 1)]).T
    np.testing.assert_allclose(v.reshape(-1), cmd[:, 2], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(w.reshape(-1), cmd[:, 3], rtol=1e-9, atol=1e-12)
    for i in range(1, n + 1):
        poses = got[f"/robot_{i}/pose"]
        xy = np.array([[m.pose.position.x, m.pose.position.y] for _, _, m in poses])
        yaw = np.array([2 * math.atan2(m.pose.orientation.z, m.pose.orientation.w) for _, _, m in poses])
        rows = tr[i - 1 :: n]
        np.testing.assert_allclose(xy, rows[:, 2:4], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - rows[:, 4]))), 0.0, atol=1e-9)
        assert {m.header.frame_id for _, _, m in poses} == {"odom"}
        secs = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for _, _, m in poses])
        np.testing.assert_allclose(secs, traj.times, atol=1e-9)
    k = T // 2
    tf = got["/tf"][k][2]
    assert [t.child_frame_id for t in tf.transforms[:n]] == [f"robot_{i}/base_link" for i in range(1, n + 1)]
    xy = np.array([[t.transform.translation.x, t.transform.translation.y] for t in tf.transforms[:n]])
    np.testing.assert_array_equal(xy, traj.positions[k])  # exact: the same doubles


def test_robotarium_twists_never_exceed_its_speed(run):
    traj, path, _ = run
    got = _read(path)
    speeds = [abs(m.linear.x) for topic, msgs in got.items() if topic.endswith("cmd_vel") for _, _, m in msgs]
    assert max(speeds) <= 0.2
    assert max(speeds) > 0.1  # the run does drive near the limit


def test_nothing_half_written(tmp_path, run, monkeypatch):
    traj, _, _ = run
    import delayform.deploy.recording as rec

    def broken(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(rec, "_write_messages", broken)
    with pytest.raises(RuntimeError):
        write_mcap(traj, tmp_path / "x.mcap")
    assert list(tmp_path.iterdir()) == []


def test_bad_paths_and_runs(tmp_path):
    with pytest.raises(RecordingError, match="does not exist"):
        check_mcap_path(tmp_path / "missing" / "run.mcap")
    with pytest.raises(RecordingError, match="is a folder"):
        check_mcap_path(tmp_path)
    with pytest.raises(RecordingError, match="file name"):
        check_mcap_path("")
    if os.geteuid() != 0:  # root writes anywhere
        locked = tmp_path / "locked"
        locked.mkdir()
        locked.chmod(0o500)
        with pytest.raises(RecordingError, match="not writable"):
            check_mcap_path(locked / "run.mcap")
    di = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", model="double_integrator", duration=1.0, dt=0.1)
    with pytest.raises(RecordingError, match="double integrators"):
        write_mcap(di, tmp_path / "di.mcap")
    assert not (tmp_path / "di.mcap").exists()


def _metadata(path: Path) -> dict[str, dict[str, str]]:
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}


def test_odometry_is_the_trajectory_as_rep_105_says(run):
    traj, path, _ = run
    got = _read(path)
    for i in range(1, traj.n + 1):
        odom = [m for _, _, m in got[f"/robot_{i}/odom"]]
        assert {(m.header.frame_id, m.child_frame_id) for m in odom} == {("odom", f"robot_{i}/base_link")}
        pose = np.array([[m.pose.pose.position.x, m.pose.pose.position.y,
                          2 * math.atan2(m.pose.pose.orientation.z, m.pose.pose.orientation.w)] for m in odom])
        np.testing.assert_array_equal(pose[:, :2], traj.positions[:, i - 1])  # the same doubles
        np.testing.assert_allclose(np.angle(np.exp(1j * (pose[:, 2] - traj.headings[:, i - 1]))), 0.0, atol=1e-12)
        # the twist in the body frame: forward speed, no sliding, the turn rate the heading follows
        twist = np.array([[m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.angular.z] for m in odom])
        np.testing.assert_array_equal(twist[:, 0], traj.speeds[:, i - 1])
        np.testing.assert_allclose(twist[:, 1], 0.0, atol=1e-15)
        np.testing.assert_array_equal(twist[:, 2], traj.commands.turn_rate[:, i - 1])
        # omega is the heading's rate: the executed turn rates integrate to the heading change (trapezoid, 2nd order)
        dtheta = np.unwrap(traj.headings[:, i - 1])
        integral = np.concatenate([[0.0], np.cumsum(0.5 * (twist[1:, 2] + twist[:-1, 2]) * np.diff(traj.times))])
        assert np.max(np.abs(dtheta - dtheta[0] - integral)) < 0.05
        assert all(not np.any(m.pose.covariance) and not np.any(m.twist.covariance) for m in odom)


def test_static_frames_and_the_formation_frame(run):
    from scipy.linalg import null_space

    traj, path, _ = run
    got = _read(path)
    (static,) = [m for _, _, m in got["/tf_static"]]
    (tr,) = static.transforms
    assert (tr.header.frame_id, tr.child_frame_id) == ("map", "odom")
    assert (tr.transform.translation.x, tr.transform.rotation.w) == (0.0, 1.0)
    # the weighted centroid's weights, independently: the left null vector of I - C, summing to 1
    C = paper_six().C
    w = null_space((np.eye(6) - C).T)[:, 0]
    w /= w.sum()
    k = traj.times.size - 1
    last = got["/tf"][k][2].transforms
    assert [t.child_frame_id for t in last] == [f"robot_{i}/base_link" for i in range(1, 7)] + ["formation"]
    offset = w @ (traj.positions[k] - traj.desired)
    np.testing.assert_allclose([last[-1].transform.translation.x, last[-1].transform.translation.y], offset, atol=1e-12)


def test_markers_bodies_slots_and_links(run):
    traj, path, _ = run
    got = _read(path)
    radius = robot_profile("robotarium").limits.radius
    bodies = got["/formation/bodies"][0][2].markers
    cylinders = [m for m in bodies if m.ns == "bodies"]
    assert [m.header.frame_id for m in cylinders] == [f"robot_{i}/base_link" for i in range(1, 7)]
    assert all(m.type == 3 and m.frame_locked and m.scale.x == pytest.approx(2 * radius) for m in cylinders)
    assert [m.text for m in bodies if m.ns == "labels"] == [str(i) for i in range(1, 7)]
    slots = [m for m in got["/formation/slots"][0][2].markers if m.ns == "slots"]
    assert {m.header.frame_id for m in slots} == {"formation"}
    np.testing.assert_array_equal([[m.pose.position.x, m.pose.position.y] for m in slots], traj.desired)
    # the graph: one line per pair of robots with a link either way, read off the adjacency
    A = paper_six().adjacency
    pairs = [(a, b) for a in range(6) for b in range(a + 1, 6) if A[a, b] or A[b, a]]
    k = 10  # the 11th published graph: saved step 20
    (line,) = got["/formation/links"][k][2].markers
    ends = np.array([[p.x, p.y] for p in line.points]).reshape(-1, 2, 2)
    assert len(ends) == len(pairs) and line.type == 5
    np.testing.assert_array_equal(ends, traj.positions[2 * k][np.array(pairs)])


def test_run_metadata_is_readable_and_says_why_this_replay_is_not_exact(run):
    traj, path, _ = run
    record = _metadata(path)["delayform/run"]
    assert (float(record["tau1"]), float(record["P"]), int(record["robots"])) == (0.3, 1.0, 6)
    assert float(record["saved_period"]) == pytest.approx(0.04)
    assert record["start_time"] == "1970-01-01T00:00:00.000000000Z"
    C = paper_six().C
    for i, row in enumerate(json.loads(record["weights"])):
        np.testing.assert_array_equal([row.get(str(k + 1), 0.0) for k in range(6) if k != i], np.delete(C[i], i))
    # saved every 0.04 s, tau1 = 0.3 s falls between two samples: the simulation reads x(t - 0.3) interpolated,
    # a playout buffer can only hold the sample before it
    assert record["controller_replay"].startswith("not exact") and "tau1 = 0.3" in record["controller_replay"]
    ticks = _replay(path)
    assert max(t["lag"] for t in ticks) == pytest.approx(0.02, abs=1e-9)  # 0.3 s = 7.5 periods: half a period late


def _replay(path: Path) -> list[dict]:
    """Every robot's controller, built from the file's metadata, fed the recorded odometry: its commands per tick."""
    record = _metadata(path)["delayform/run"]
    start = int(record["start_time_ns"])
    limits = None if record["limits"] == "none" else RobotLimits(**json.loads(record["limits"]))
    n = int(record["robots"])
    ctrls = [FormationController(robot=i + 1, P=float(record["P"]), D=float(record["D"]), tau1=float(record["tau1"]),
                                 tau2=float(record["tau2"]), weights={int(k): w for k, w in row.items()},
                                 forcing=f, limits=limits)
             for i, (row, f) in enumerate(zip(json.loads(record["weights"]), json.loads(record["forcing"])))]  # fmt: skip
    got = _read(path)
    odom = [got[f"/robot_{i}/odom"] for i in range(1, n + 1)]
    ticks = []
    for k in range(len(odom[0])):
        states = []
        for i in range(n):
            stamp, _, m = odom[i][k]
            assert stamp == m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
            # seconds since the recording's start: float64 epoch seconds resolve only 0.24 us, coarser
            # than the playout buffer's 1 ns tolerance
            t = (stamp - start) * 1e-9
            p, q, tw = m.pose.pose.position, m.pose.pose.orientation, m.twist.twist
            th = 2.0 * math.atan2(q.z, q.w)
            c, s = math.cos(th), math.sin(th)
            states.append((t, p.x, p.y, th, tw.linear.x, c * tw.linear.x - s * tw.linear.y, s * tw.linear.x + c * tw.linear.y))
        msgs = [NeighbourMessage(i + 1, t, x, y, vx, vy) for i, (t, x, y, _, _, vx, vy) in enumerate(states)]
        for i, ctrl in enumerate(ctrls):
            ctrl.receive_all(msgs)
            t, x, y, th, v, _, _ = states[i]
            cmd = ctrl.tick(t, x, y, th, v)
            ticks.append({"robot": i + 1, "step": k, "speed": cmd.speed, "turn_rate": cmd.turn_rate, "lag": cmd.lag})
    return ticks


@pytest.mark.parametrize("limits", [robot_profile("robotarium").limits, None], ids=["robotarium", "ideal"])
def test_replaying_the_recorded_odometry_through_the_controller_gives_the_recorded_twists(tmp_path, limits):
    import datetime as dt

    traj = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", limits=limits, duration=6.0, dt=0.01, save_every=1,
                    seed=4, initial_speed=0.05)  # fmt: skip
    start = dt.datetime(2026, 12, 3, 10, 0, 0, 123456, tzinfo=dt.timezone(dt.timedelta(hours=1)))
    path = write_mcap(traj, tmp_path / "run.mcap", topology=paper_six(), start_time=start)
    assert _metadata(path)["delayform/run"]["controller_replay"].startswith("exact")
    got = _read(path)
    ticks = _replay(path)
    assert max(t["lag"] for t in ticks) == 0.0  # the design's delays hold exactly
    for name, field in (("turn_rate", "angular"), ("speed", "linear")):
        mine = np.array([t[name] for t in ticks]).reshape(-1, 6)
        recorded = np.array([[getattr(getattr(m, field), "z" if field == "angular" else "x")
                              for _, _, m in got[f"/robot_{i}/cmd_vel"]] for i in range(1, 7)]).T
        err = np.max(np.abs(mine - recorded) / (1.0 + np.abs(recorded)))
        assert err < 1e-9, f"{name}: {err:.2e}"
    assert np.abs(traj.commands.turn_rate).max() > 0.5  # the robots do turn


def test_start_time(tmp_path):
    import calendar
    import datetime as dt
    import time

    when = dt.datetime(2026, 12, 3, 10, 0, 0, 250000, tzinfo=dt.timezone.utc)
    expected = calendar.timegm((2026, 12, 3, 10, 0, 0)) * 10**9 + 250_000_000
    assert recording_start(when) == expected
    assert recording_start("2026-12-03T11:00:00.25+01:00") == expected
    assert recording_start("2026-12-03T10:00:00.25Z") == expected
    assert recording_start(1796292000.25) == recording_start("1796292000.25") == 1_796_292_000_250_000_000
    before = time.time_ns()
    assert before <= recording_start("now") <= time.time_ns()
    assert recording_start(None) == 0
    for bad, match in ((dt.datetime(2026, 12, 3), "no time zone"), ("2026-12-03T10:00", "no time zone"),
                       (-1.0, "before 1970"), (float("nan"), "finite"), ("tomorrow", "ISO 8601"),
                       (2.2e9, "2038"), (True, "datetime")):  # fmt: skip
        with pytest.raises(RecordingError, match=match):
            recording_start(bad)
    traj = simulate(paper_six(), 1.0, 0.5, 0.3, 0.2, "hexagon", duration=0.5, dt=0.1, initial_speed=0.05)
    got = _read(write_mcap(traj, tmp_path / "t.mcap", start_time=when))
    stamps = [(t, m.header.stamp.sec, m.header.stamp.nanosec) for t, _, m in got["/robot_1/odom"]]
    assert stamps[0] == (expected, expected // 10**9, 250_000_000)
    assert [t for t, _, _ in stamps] == [expected + k * 100_000_000 for k in range(6)]
    with pytest.raises(RecordingError, match="2038"):
        write_mcap(traj, tmp_path / "late.mcap", start_time=2**31 - 0.25)
    assert not (tmp_path / "late.mcap").exists()


def test_simulate_mcap_carries_the_scenario_and_the_verdict(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from delayform.cli import cli

    monkeypatch.chdir(tmp_path)
    text = ('[topology]\nname = "paper_six"\n[gains]\nP = 1.0\nD = 0.5\n[delays]\ntau1 = 0.3\ntau2 = 0.2\n'
            '[formation]\nshape = "hexagon"\n[simulation]\nduration = 1.0\n')
    Path("team.toml").write_text(text)
    runner = CliRunner()
    # the paper: point a (0.3, 0.2) is stable, point c (1, 2) unstable (Section "Simulation Examples")
    for extra, verdict in (((), "stable"), (("--tau1", "1", "--tau2", "2"), "unstable")):
        result = runner.invoke(cli, ["simulate", "team.toml", "--out", "o", "--mcap", "run.mcap",
                                     "--mcap-start", "2026-12-03T10:00:00Z", *extra])  # fmt: skip
        assert result.exit_code == 0, result.output
        meta = _metadata(tmp_path / "run.mcap")
        assert meta["delayform/analysis"]["verdict"] == verdict
        assert meta["delayform/scenario"]["toml"] == text
        assert json.loads(meta["delayform/scenario"]["parameters"])["tau1"] == (float(extra[1]) if extra else 0.3)
        assert meta["delayform/run"]["start_time"] == "2026-12-03T10:00:00.000000000Z"
    bad = runner.invoke(cli, ["simulate", "team.toml", "--out", "p", "--mcap", "r.mcap", "--mcap-start", "noon"])
    assert bad.exit_code == 2 and "--mcap-start" in bad.output and not Path("p").exists()
