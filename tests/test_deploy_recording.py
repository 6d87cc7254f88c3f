"""MCAP recordings: written with rosbags + mcap, read back with mcap-ros2-support's own CDR decoder.

The decoder builds its parser from the ``ros2msg`` schema text in the file,
independently of the rosbags encoder (and of the layouts
:mod:`delayform.deploy.recording` takes from it); what it reads must be the
trajectory and command files, value for value.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from delayform.deploy import robot_profile
from delayform.deploy.recording import check_mcap_path, write_mcap
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
    path = write_mcap(traj, folder / "run.mcap")
    traj.to_csv(folder / "traj.csv")
    traj.commands.to_csv(folder / "commands.csv")
    return traj, path, folder


def test_topics_types_and_one_message_per_robot_per_saved_step(run):
    traj, path, _ = run
    got = _read(path)
    n, T = traj.positions.shape[1], traj.times.size
    expected = {f"/robot_{i}/cmd_vel" for i in range(1, n + 1)} | {f"/robot_{i}/pose" for i in range(1, n + 1)} | {"/tf"}
    assert set(got) == expected
    for topic, msgs in got.items():
        assert len(msgs) == T
        kind = "tf2_msgs/msg/TFMessage" if topic == "/tf" else (
            "geometry_msgs/msg/Twist" if topic.endswith("cmd_vel") else "geometry_msgs/msg/PoseStamped")
        assert {name for _, name, _ in msgs} == {kind}
        stamps = np.array([t for t, _, _ in msgs])
        np.testing.assert_array_equal(stamps, np.rint(traj.times * 1e9).astype(np.int64))


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
        assert {m.header.frame_id for _, _, m in poses} == {"world"}
        secs = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for _, _, m in poses])
        np.testing.assert_allclose(secs, traj.times, atol=1e-9)
    k = T // 2
    tf = got["/tf"][k][2]
    assert [t.child_frame_id for t in tf.transforms] == [f"robot_{i}/base_link" for i in range(1, n + 1)]
    xy = np.array([[t.transform.translation.x, t.transform.translation.y] for t in tf.transforms])
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
