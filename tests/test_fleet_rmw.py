"""A fleet run as rmw_zenoh publishes it (delayform.fleet.rmw, ``--ros-domain``).

No ROS 2 process runs here: what a ROS 2 node on rmw_zenoh would need is
checked piece by piece against independent sources: the type hashes against
rosbags' Jazzy type store and published values, the key expressions and
liveliness tokens against the examples of rmw_zenoh's design document, the
attachment with zenoh-python's own deserializer, the payloads with rosbags'.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

zenoh = pytest.importorskip("zenoh")
pytest.importorskip("mcap_ros2")

from delayform.errors import FleetError
from delayform.fleet import run_fleet
from delayform.fleet.budget import ROS_TICK_SECONDS, fleet_demand
from delayform.fleet.rmw import (
    QOS,
    TYPES,
    RosNode,
    attachment,
    check_domain,
    data_key,
    node_token,
    publisher_token,
)
from delayform.fleet.wire import Codec, Odometry, open_session
from delayform.formation import named_formation
from delayform.model import Delays, Start, Team
from delayform.topology import complete

ROOT = Path(__file__).resolve().parents[1]

#: rmw_zenoh's docs/design.md (jazzy): the String type's hash, a node's token and a publisher's
DESIGN_STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
DESIGN_DATA_KEY = f"0/chatter/std_msgs::msg::dds_::String_/{DESIGN_STRING_HASH}"
DESIGN_NODE = "@ros2_lv/0/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
DESIGN_PUBLISHER = ("@ros2_lv/0/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
                    f"std_msgs::msg::dds_::String_/{DESIGN_STRING_HASH}/::,7:,:,:,,")  # fmt: skip
#: the Odometry key on domain 0, as an independent implementation of rmw_zenoh's format states it in its tests
PUBLISHED_ODOM_KEY = ("0/robot_1/odom/nav_msgs::msg::dds_::Odometry_/"
                      "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0")  # fmt: skip


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _decode(att: bytes) -> tuple[int, int, list[int]]:
    """The attachment by zenoh-python's own deserializer (a decoder independent of ours)."""
    from zenoh.ext import Int64, UInt8, z_deserialize

    seq, stamp, gid = z_deserialize(tuple[Int64, Int64, list[UInt8]], zenoh.ZBytes(att))
    return int(seq), int(stamp), [int(b) for b in gid]


# ------------------------------------------------------------------ fast pieces
def test_type_hashes_are_rosbags_jazzy_and_the_published_ones() -> None:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    assert store.hash_rihs01("std_msgs/msg/String") == DESIGN_STRING_HASH  # rosbags agrees with rmw_zenoh's docs
    for msgtype, (dds, rihs) in TYPES.items():
        assert rihs == store.hash_rihs01(msgtype)
        package, _, name = msgtype.split("/")
        assert dds == f"{package}::msg::dds_::{name}_"
    assert data_key(0, "/robot_1/odom", "nav_msgs/msg/Odometry") == PUBLISHED_ODOM_KEY


def test_keys_and_tokens_match_rmw_zenoh_s_design_examples(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(TYPES, "std_msgs/msg/String", ("std_msgs::msg::dds_::String_", DESIGN_STRING_HASH))
    assert data_key(0, "/chatter", "std_msgs/msg/String") == DESIGN_DATA_KEY
    assert node_token(0, "aac3178e146ba6f1fc6e6a4085e77f21", 0, "listener") == DESIGN_NODE
    assert publisher_token(0, "8b20917502ee955ac4476e0266340d5c", 0, 10, "talker", "/chatter",
                           "std_msgs/msg/String", qos="::,7:,:,:,,") == DESIGN_PUBLISHER  # fmt: skip
    # the fleet's own: reliable, volatile, keep-last 10 differs from rmw_zenoh's defaults by the depth only
    assert QOS == "::,10:,:,:,,"
    token = publisher_token(7, "ab12", 0, 2, "delayform_robot_1", "/robot_1/cmd_vel", "geometry_msgs/msg/Twist")
    assert token == ("@ros2_lv/7/ab12/0/2/MP/%/%/delayform_robot_1/%robot_1%cmd_vel/geometry_msgs::msg::dds_::Twist_/"
                     f"{TYPES['geometry_msgs/msg/Twist'][1]}/::,10:,:,:,,")  # fmt: skip
    with pytest.raises(FleetError, match="no rmw_zenoh type"):
        data_key(0, "/x", "std_msgs/msg/Int32")


def test_attachment_is_what_zenoh_s_serializer_writes() -> None:
    from zenoh.ext import Int64, UInt8, z_serialize

    gid = bytes(range(200, 216))
    att = attachment(42, 1_733_390_000_123_456_789, gid)
    assert len(att) == 33
    assert _decode(att) == (42, 1_733_390_000_123_456_789, list(gid))
    assert att == z_serialize((Int64(42), Int64(1_733_390_000_123_456_789), [UInt8(b) for b in gid])).to_bytes()
    with pytest.raises(FleetError, match="16 bytes"):
        attachment(1, 0, b"short")


@pytest.mark.parametrize("bad", [-1, 233, 1.0, True, "7", None])
def test_a_bad_domain_is_refused(bad: Any) -> None:
    with pytest.raises(FleetError, match=r"0\.\.232"):
        check_domain(bad)
    assert check_domain(0) == 0 and check_domain(232) == 232


def test_the_budget_counts_the_copies() -> None:
    plain, ros = fleet_demand(6, 13, 0.01), fleet_demand(6, 13, 0.01, ros=True)
    assert ros - plain == pytest.approx(6 * ROS_TICK_SECONDS / 0.01)


def test_a_node_s_publishers_number_stamp_and_announce(tmp_path: Path) -> None:
    """Two sessions on the loopback: the samples carry consecutive numbers and the wall clock; the graph sees the node."""
    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    listener = open_session(listen=[endpoint], connect=[])
    talker = open_session(listen=["tcp/127.0.0.1:0"], connect=[endpoint])
    try:
        sub = listener.declare_subscriber("3/**", zenoh.handlers.FifoChannel(100))
        node = RosNode(talker, 3, "delayform_robot_2")
        pubs = [node.publisher("/robot_2/state"), node.publisher("/robot_2/cmd_vel")]
        time.sleep(0.5)
        codec = Codec(2)
        payload = codec.odometry(2, Odometry(time.time(), 1.0, 2.0, 0.5, 0.1, 0.0))
        for _ in range(3):
            pubs[0].put(payload)
        pubs[1].put(codec.twist(0.2, 0.1))
        got = _collect(sub, 4, 3.0)
        assert [s.key_expr for s in got] == [pubs[0].key] * 3 + [pubs[1].key]
        assert got[0].key_expr == data_key(3, "/robot_2/state", "nav_msgs/msg/Odometry")
        decoded = [_decode(s.attachment) for s in got]
        assert [d[0] for d in decoded] == [1, 2, 3, 1]
        assert all(abs(d[1] * 1e-9 - time.time()) < 2.0 for d in decoded)
        assert [bytes(d[2]) for d in decoded] == [pubs[0].gid] * 3 + [pubs[1].gid]
        assert pubs[0].gid != pubs[1].gid
        assert bytes(got[0].payload) == payload
        tokens = _tokens(listener, 3)
        assert tokens == {node.token, pubs[0].token, pubs[1].token}
        assert node.token == f"@ros2_lv/3/{talker.info.zid()}/0/0/NN/%/%/delayform_robot_2"
    finally:
        talker.close()
        listener.close()


def _collect(sub: Any, count: int, timeout: float) -> list[Any]:
    got: list[Any] = []
    end = time.time() + timeout
    while len(got) < count and time.time() < end:
        sample = sub.try_recv()
        if sample is None:
            time.sleep(0.005)
        else:
            got.append(sample)
    return [_Sample(s) for s in got]


class _Sample:
    def __init__(self, s: Any) -> None:
        self.key_expr = str(s.key_expr)
        self.payload = s.payload.to_bytes()
        self.attachment = None if s.attachment is None else s.attachment.to_bytes()


def _tokens(session: Any, count: int, timeout: float = 3.0) -> set[str]:
    """The liveliness tokens under ``@ros2_lv/**`` a second session sees (asked until ``count`` answer)."""
    end = time.time() + timeout
    while True:
        replies = session.liveliness().get("@ros2_lv/**", timeout=1.0)
        found = {str(r.ok.key_expr) for r in replies if r.ok is not None}
        if len(found) >= count or time.time() > end:
            return found
        time.sleep(0.1)


def test_the_command_refuses_a_bad_domain_with_one_line(tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-m", "delayform", "fleet", "--ros-domain", "233", "--duration", "5",
                           "--out", str(tmp_path / "out")], capture_output=True, cwd=ROOT, timeout=120,
                          env={**__import__("os").environ, "PYTHONPATH": str(ROOT / "src")})  # fmt: skip
    lines = proc.stderr.decode().strip().splitlines()
    assert proc.returncode == 2
    assert len(lines) == 1 and "--ros-domain" in lines[0], lines
    assert not (tmp_path / "out" / "fleet.mcap").exists()


# ------------------------------------------------------------------ a run
def test_a_run_on_ros_domain_7_is_heard_as_rmw_zenoh_publishes(tmp_path: Path) -> None:
    """Three robots, 2.5 s: a second session on the endpoint hears /robot_1/odom as a ROS 2 node would."""
    from rosbags.typesys import Stores, get_typestore

    endpoint = f"tcp/127.0.0.1:{_free_port()}"
    seen: dict[str, Any] = {}

    def progress(text: str) -> None:  # the processes are ready (their tokens declared); t = 0 is a second away
        if text.startswith("running"):
            session = open_session(listen=["tcp/127.0.0.1:0"], connect=[endpoint])
            seen["session"] = session
            seen["rmw"] = session.declare_subscriber("7/robot_1/odom/**", zenoh.handlers.FifoChannel(10_000))
            seen["plain"] = session.declare_subscriber("robot_1/odom", zenoh.handlers.FifoChannel(10_000))
            seen["tokens"] = _tokens(session, 4 + 3 + 2 * 3)

    run = run_fleet(Team(complete(3), 1.0, 1.5), Delays(0.3, 0.2), named_formation("polygon", 3, spacing=1.0),
                    out=tmp_path, duration=2.5, period=0.02, start=Start(seed=3), endpoint=endpoint, ros_domain=7,
                    progress=progress)  # fmt: skip
    session = seen["session"]
    try:
        rmw = _collect(seen["rmw"], 10_000, 0.5)
        plain = _collect(seen["plain"], 10_000, 0.5)
    finally:
        session.close()
    # the graph: one node per process, a publisher per topic it publishes
    tokens = seen["tokens"]
    nodes = sorted(t.rpartition("/")[2] for t in tokens if "/NN/" in t)
    assert nodes == ["delayform_robot_1", "delayform_robot_2", "delayform_robot_3", "delayform_world"]
    publishers = sorted((t.split("/")[8], t.split("/")[9]) for t in tokens if "/MP/" in t)
    assert publishers == sorted([("delayform_world", f"%robot_{i}%odom") for i in (1, 2, 3)]
                                + [(f"delayform_robot_{i}", f"%robot_{i}%{topic}") for i in (1, 2, 3)
                                   for topic in ("state", "cmd_vel")])  # fmt: skip
    assert all(t.startswith("@ros2_lv/7/") and t.endswith("/" + QOS) for t in tokens if "/MP/" in t)
    # the samples: the rmw_zenoh key, the same CDR bytes, an Odometry for rosbags' Jazzy store, attachments
    assert len(rmw) > 50
    assert {s.key_expr for s in rmw} == {data_key(7, "/robot_1/odom", "nav_msgs/msg/Odometry")}
    assert {s.payload for s in rmw} <= {s.payload for s in plain}
    store = get_typestore(Stores.ROS2_JAZZY)
    msg = store.deserialize_cdr(rmw[-1].payload, "nav_msgs/msg/Odometry")
    assert msg.child_frame_id == "robot_1/base_link"
    decoded = [_decode(s.attachment) for s in rmw]
    assert np.all(np.diff([d[0] for d in decoded]) == 1)
    stamps = np.array([d[1] for d in decoded]) * 1e-9
    assert np.all(np.diff(stamps) > 0)
    stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
    assert abs(stamps[-1] - stamp) < 0.1  # the source timestamp is when the world published that odometry
    assert len({bytes(d[2]) for d in decoded}) == 1
    # the run itself: the fleet's own keys only in its recording, the domain in its summary
    assert run.summary["run"]["ros_domain"] == 7
    from delayform.report.fleet import fleet_text

    assert "also as rmw_zenoh on ROS domain 7" in fleet_text(run, "three")
    assert all(k.startswith("robot_") for k in run.summary["run"]["messages_recorded"])
