"""The live view of a fleet run: a Foxglove WebSocket client on the loopback receives the scene.

The client is the ``websockets`` package speaking Foxglove's WebSocket
protocol by hand (JSON ``serverInfo``, ``advertise``, ``subscribe``; binary
message frames), and the scene's protobuf bytes are decoded by a few lines
of wire-format parsing below, with the field numbers read from the schema the
server advertises; the robots' positions in the scene are checked against the
world's odometry decoded from the run's MCAP recording with mcap-ros2-support.
"""

from __future__ import annotations

import base64
import json
import os
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("zenoh")
pytest.importorskip("mcap_ros2")

from cli_runner import run_in_process
from test_fleet import ROOT, _alive, _children_of, _free_port
from test_fleet_faults import FOUR, _t0_of

from delayform.errors import FleetError
from delayform.fleet.live import check_live_port

#: the protocol the SDK's server speaks (it refuses a client offering only the older foxglove.websocket.v1)
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


def test_bad_live_ports_are_refused() -> None:
    for bad in (0, 70000, -1, True, "8765"):
        with pytest.raises(FleetError, match="1..65535"):
            check_live_port(bad)  # type: ignore[arg-type]
    with pytest.raises(FleetError, match="Zenoh"):
        check_live_port(7447, taken=7447)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        with pytest.raises(FleetError, match="already taken"):
            check_live_port(taken.getsockname()[1])


def test_a_live_port_in_use_exits_2_before_the_team_starts(tmp_path: Path) -> None:
    scenario = tmp_path / "four.toml"
    scenario.write_text(FOUR)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        proc = run_in_process("fleet", str(scenario), "--duration", "5", "--foxglove", str(taken.getsockname()[1]),
                              "--out", str(tmp_path / "out"), "--endpoint", f"tcp/127.0.0.1:{_free_port()}",
                              cwd=tmp_path, timeout=120)  # fmt: skip
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and "already taken" in lines[0], lines
    assert not _children_of(tmp_path)
    assert not (tmp_path / "out" / "fleet.mcap").exists()


# ------------------------------------------------------------------ protobuf, by hand
def _varint(data: bytes, i: int) -> tuple[int, int]:
    value = shift = 0
    while True:
        b = data[i]
        i += 1
        value |= (b & 0x7F) << shift
        shift += 7
        if not b & 0x80:
            return value, i


def _fields(data: bytes) -> list[tuple[int, Any]]:
    """(field number, value) of one protobuf message: ints for varints, floats for fixed64 doubles, bytes else."""
    out, i = [], 0
    while i < len(data):
        tag, i = _varint(data, i)
        number, wire = tag >> 3, tag & 7
        if wire == 0:
            value, i = _varint(data, i)
        elif wire == 1:
            value, i = struct.unpack_from("<d", data, i)[0], i + 8
        elif wire == 2:
            size, i = _varint(data, i)
            value, i = data[i:i + size], i + size
        elif wire == 5:
            value, i = struct.unpack_from("<f", data, i)[0], i + 4
        else:
            raise AssertionError(f"wire type {wire}")
        out.append((number, value))
    return out


def _numbers(schema_b64: str) -> dict[tuple[str, str], int]:
    """(message, field) -> field number, from the FileDescriptorSet the server advertises (descriptor.proto's own numbers)."""
    found = {}
    for n1, fdp in _fields(base64.b64decode(schema_b64)):  # FileDescriptorSet.file = 1
        assert n1 == 1
        for n2, msg in _fields(fdp):
            if n2 != 4:  # FileDescriptorProto.message_type
                continue
            parts = _fields(msg)
            name = next(v for k, v in parts if k == 1).decode()
            for k, fd in parts:
                if k == 2:  # DescriptorProto.field: FieldDescriptorProto name = 1, number = 3
                    f = dict(_fields(fd))
                    found[(name, f[1].decode())] = f[3]
    return found


def _scene(payload: bytes, num: dict[tuple[str, str], int]) -> dict[str, Any]:
    """Entity id -> (cylinder centres, number of line points) of one SceneUpdate."""
    out = {}
    for k, entity in _fields(payload):
        if k != num[("SceneUpdate", "entities")]:
            continue
        fields = _fields(entity)
        eid = next(v for n, v in fields if n == num[("SceneEntity", "id")]).decode()
        centres, points = [], 0
        for n, v in fields:
            if n == num[("SceneEntity", "cylinders")]:
                pose = dict(_fields(v))[num[("CylinderPrimitive", "pose")]]
                pos = dict(_fields(dict(_fields(pose))[num[("Pose", "position")]]))
                centres.append((pos.get(num[("Vector3", "x")], 0.0), pos.get(num[("Vector3", "y")], 0.0)))
            elif n == num[("SceneEntity", "lines")]:
                points += sum(1 for m, _ in _fields(v) if m == num[("LinePrimitive", "points")])
        out[eid] = (centres, points)
    return out


def _odometry(mcap: Path, t0: float) -> dict[str, list[tuple[int, float, float]]]:
    """Topic -> (log time ns, x, y) of the world's odometry, decoded by mcap-ros2-support."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out: dict[str, list[tuple[int, float, float]]] = {}
    with open(mcap, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        for _, channel, message, decoded in reader.iter_decoded_messages():
            if channel.topic.endswith("/odom"):
                p = decoded.pose.pose.position
                out.setdefault(channel.topic, []).append((message.log_time, p.x, p.y))
    return out


def test_without_the_sdk_the_option_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib.util

    from delayform.errors import MissingExtraError

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "foxglove" else real(name, *a))
    with pytest.raises(MissingExtraError, match=r"pip install 'delayform\[fleet\]'"):
        check_live_port(_free_port())


@pytest.mark.slow
def test_a_foxglove_client_receives_the_scene(tmp_path: Path) -> None:
    foxglove = pytest.importorskip("foxglove")
    if not hasattr(foxglove, "start_server"):
        pytest.skip("the foxglove module here is not the Foxglove SDK")
    from websockets.sync.client import connect

    scenario = tmp_path / "four.toml"
    scenario.write_text(FOUR)
    out, port = tmp_path / "out", _free_port()
    # the command sees the SDK where this process does
    where = os.pathsep.join([str(ROOT / "src"), str(Path(foxglove.__file__).resolve().parents[1])])
    proc = subprocess.Popen([sys.executable, "-m", "delayform", "fleet", str(scenario), "--duration", "5",
                             "--period", "0.02", "--out", str(out), "--foxglove", str(port),
                             "--endpoint", f"tcp/127.0.0.1:{_free_port()}"],
                            env={**os.environ, "PYTHONPATH": where}, cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    scenes: list[tuple[int, bytes]] = []
    poses: list[bytes] = []
    try:
        deadline = time.monotonic() + 90
        while True:
            assert proc.poll() is None, proc.communicate()[1]
            assert time.monotonic() < deadline, "the Foxglove server never listened"
            try:
                ws = connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS, open_timeout=5)  # type: ignore[arg-type]
                break
            except OSError:
                time.sleep(0.2)
        with ws:
            info = json.loads(ws.recv(timeout=10))
            assert info["op"] == "serverInfo" and info["name"] == "delayform fleet"
            adv = json.loads(ws.recv(timeout=10))
            assert adv["op"] == "advertise"
            channels = {c["topic"]: c for c in adv["channels"]}
            assert channels["/fleet/scene"]["schemaName"] == "foxglove.SceneUpdate"
            assert channels["/fleet/poses"]["schemaName"] == "foxglove.PosesInFrame"
            scene_channel = channels["/fleet/scene"]
            poses_schema = channels["/fleet/poses"]["schema"]
            assert scene_channel["encoding"] == "protobuf"
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": 1, "channelId": scene_channel["id"]}, {"id": 2, "channelId": channels["/fleet/poses"]["id"]}]}))
            end = time.monotonic() + 30
            while len(scenes) < 5 and time.monotonic() < end:
                frame = ws.recv(timeout=30)
                if isinstance(frame, bytes) and frame[0] == 0x01:  # message data: op, subscription, log time, payload
                    sub, log_time = struct.unpack_from("<IQ", frame, 1)
                    (scenes.append((log_time, frame[13:])) if sub == 1 else poses.append(frame[13:]))
        _, stderr = proc.communicate(timeout=120)
        assert proc.returncode == 0, stderr
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert len(scenes) >= 5 and poses
    num = _numbers(scene_channel["schema"])
    odom = _odometry(out / "fleet.mcap", _t0_of(out / "fleet.mcap"))
    star_pairs = 3  # the hub with each leaf
    for log_time, payload in scenes[-3:]:
        scene = _scene(payload, num)
        assert set(scene) == {"robot_1", "robot_2", "robot_3", "robot_4", "slots", "graph"}
        assert len(scene["slots"][0]) == 4 and scene["graph"][1] == 2 * star_pairs
        for i in range(1, 5):
            ((x, y),) = scene[f"robot_{i}"][0]
            # the world's newest odometry of the robot when the scene was made (the recording's log time is
            # when the same process took it: up to one polling interval after the scene's time)
            before = [(t, ox, oy) for t, ox, oy in odom[f"/robot_{i}/odom"] if t <= log_time + 10_000_000]
            _, ox, oy = before[-1]
            assert abs(x - ox) < 0.01 and abs(y - oy) < 0.01
    # the poses: one per robot, in the frame "world"
    pnum = _numbers(poses_schema)
    fields = _fields(poses[-1])
    assert sum(1 for k, _ in fields if k == pnum[("PosesInFrame", "poses")]) == 4
    assert dict(fields)[pnum[("PosesInFrame", "frame_id")]] == b"world"
    assert not _children_of(tmp_path)
    pids = json.loads((out / "summary.json").read_text())["run"]["pids"]
    assert not [p for p in pids.values() if _alive(p)]
