"""A simulated run as a ROS 2 recording: an MCAP file that Foxglove, RViz (via rosbag2) and ``ros2 bag`` read.

Topics, one message per robot per saved step, stamped with simulated time
(``log_time = publish_time = header.stamp``, in ns from t = 0), robots
numbered from 1:

``/robot_<i>/cmd_vel`` ``geometry_msgs/msg/Twist``
    ``linear.x`` the robot's signed speed v (m/s), ``angular.z`` its
    executed turn rate omega (rad/s): the columns ``v`` and ``omega`` of
    the command files (:meth:`RobotCommands.to_csv`).
``/robot_<i>/pose`` ``geometry_msgs/msg/PoseStamped``
    In the frame ``world``: position (x, y, 0) and the heading as the
    quaternion ``(0, 0, sin(theta/2), cos(theta/2))``.
``/tf`` ``tf2_msgs/msg/TFMessage``
    One message per saved step with a transform ``world ->
    robot_<i>/base_link`` for every robot, so a 3-D panel draws the team.

The messages are encoded in CDR by ``rosbags`` (its ROS 2 Humble type
store) and written by the ``mcap`` package, with the schemas as ``ros2msg``
text: what rosbag2's MCAP storage writes. Encoding 10^6 messages one by
one costs more than the rest of the export, so each message type's byte
layout is taken from rosbags once per file: rosbags serialises a message
whose fields hold distinct marker values, the marker bytes give each
field's offset, and the values of all robots and steps are written at
those offsets with NumPy (:class:`_Layout`). Nothing of the layout is
written here by hand; the first step of every file is encoded both ways
and compared byte for byte, and the tests decode whole files with
``mcap-ros2-support``'s independent decoder. The file is written under a
temporary name beside the target and renamed when complete, so a failed
export leaves nothing half-written.
"""

from __future__ import annotations

import os
import struct
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from delayform._extras import require_extra
from delayform._files import atomic_path
from delayform._validation import validated
from delayform.errors import RecordingError
from delayform.simulation.trajectory import Trajectory

__all__ = ["write_mcap", "check_mcap_path", "MCAP_TOPICS"]

#: message type of each kind of topic
MCAP_TOPICS = {
    "cmd_vel": "geometry_msgs/msg/Twist",
    "pose": "geometry_msgs/msg/PoseStamped",
    "tf": "tf2_msgs/msg/TFMessage",
}

#: the fixed frame of the poses and of /tf
WORLD_FRAME = "world"


def check_mcap_path(path: str | Path) -> Path:
    """The MCAP path, checked before any work: a file name in a folder that exists and can be written.

    Parameters
    ----------
    path
        Where the recording goes (``.mcap`` is customary, not required).

    Raises
    ------
    RecordingError
        For an empty name, a folder in its place, or a folder that is
        missing or cannot be written.
    MissingExtraError
        Without mcap or rosbags (the ``ros`` extra): no recording could be written.
    """
    require_extra("ros")
    if not isinstance(path, (str, os.PathLike)) or not str(path).strip():
        raise RecordingError(f"the MCAP path must be a file name, got {path!r}")
    if "\x00" in os.fspath(path):  # pathlib and the OS would raise their own ValueError
        raise RecordingError(f"the MCAP path {path!r} contains a NUL character, which no file name can hold")
    path = Path(path)
    if path.is_dir():
        raise RecordingError(f"the MCAP path {path} is a folder; give a file name such as {path / 'run.mcap'}")
    folder = path.parent
    if not folder.is_dir():
        blocker = next((p for p in (folder, *folder.parents) if p.exists()), None)
        if blocker is not None and not blocker.is_dir():
            raise RecordingError(f"cannot write the MCAP file {path}: {blocker} is a file, not a folder")
        raise RecordingError(f"cannot write the MCAP file {path}: the folder {folder} does not exist")
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise RecordingError(f"cannot write the MCAP file {path}: the folder {folder} is not writable "
                             f"({exc.strerror or type(exc).__name__})") from None  # fmt: skip
    return path


def _stamps_ns(times: np.ndarray) -> list[int]:
    return [int(v) for v in np.rint(np.asarray(times) * 1e9).astype(np.int64)]


@validated(RecordingError)
def write_mcap(trajectory: Trajectory, path: str | Path, *, compression: str = "zstd") -> Path:
    """Write a robots' run as an MCAP file of ROS 2 messages (module doc: topics and encodings).

    Parameters
    ----------
    trajectory
        A run of robots (``model="unicycle"``, ideal or with limits): it
        carries the commands the Twists hold.
    path
        The file to write; replaced atomically when complete.
    compression
        ``"zstd"`` (default, what rosbag2 uses), ``"lz4"`` or ``"none"``.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    RecordingError
        For a double-integrator run (no robot commands), a bad compression
        name or a path that cannot be written (:func:`check_mcap_path`).
    MissingExtraError
        Without mcap or rosbags (the ``ros`` extra).
    """
    require_extra("ros")
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    if not isinstance(trajectory, Trajectory):
        raise RecordingError(f"write_mcap takes a Trajectory, got {type(trajectory).__name__}")
    commands = trajectory.commands
    if commands is None:
        raise RecordingError("an MCAP recording holds robots' commands: simulate model 'unicycle', "
                             "not double integrators")  # fmt: skip
    kinds = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
    if compression not in kinds:
        raise RecordingError(f"compression must be one of {', '.join(kinds)}, got {compression!r}")
    path = check_mcap_path(path)
    store = get_typestore(Stores.ROS2_HUMBLE)
    with atomic_path(path) as tmp, open(tmp, "wb") as stream:
        writer = Writer(stream, compression=kinds[compression])
        writer.start(profile="ros2", library="delayform (mcap + rosbags)")
        _write_messages(writer, store, trajectory)
        writer.finish()
    return path


class _Layout:
    """The CDR bytes of one message, as rosbags lays them out, with the offsets of the fields that change.

    Parameters
    ----------
    store
        The rosbags type store.
    msgtype
        The message type.
    message
        A message object of that type (its other fields keep their values).
    slots
        ``(object, attribute, code)`` of each changing field, code ``"d"``
        (float64), ``"i"`` (int32) or ``"I"`` (uint32).
    """

    def __init__(self, store: Any, msgtype: str, message: Any, slots: Sequence[tuple[Any, str, str]]) -> None:
        markers = [_marker(j, code) for j, (_, _, code) in enumerate(slots)]
        for (obj, attr, _), value in zip(slots, markers):
            setattr(obj, attr, value)
        marked = bytes(store.serialize_cdr(message, msgtype))
        # the slots come in the order they are encoded: each search starts where the last ended
        offsets, start = [], 0
        for (_, attr, code), value in zip(slots, markers):
            at = marked.find(struct.pack("<" + code, value), start)
            if at < 0:
                raise RecordingError(f"internal: cannot locate {msgtype}.{attr} in its CDR encoding")
            offsets.append(at)
            start = at + struct.calcsize(code)
        for obj, attr, code in slots:
            setattr(obj, attr, 0.0 if code == "d" else 0)
        self.template = np.frombuffer(bytes(store.serialize_cdr(message, msgtype)), dtype=np.uint8)
        formats = {"d": "<f8", "i": "<i4", "I": "<u4"}
        self.dtype = np.dtype({"names": [f"f{j}" for j in range(len(slots))],
                               "formats": [formats[code] for _, _, code in slots],
                               "offsets": offsets, "itemsize": self.template.size})  # fmt: skip
        self.size = int(self.template.size)
        # the markers written at those offsets into the zero message must give rosbags' marked message
        # back, byte for byte: otherwise an offset was found in the wrong place
        if self.fill([np.array([m]) for m in markers]) != marked:
            raise RecordingError(f"internal: the layout of {msgtype} found from its markers is not rosbags' encoding")

    def fill(self, columns: Sequence[np.ndarray]) -> bytes:
        """The bytes of ``m`` messages back to back, field j of message r from ``columns[j].flat[r]``."""
        m = int(np.asarray(columns[0]).size)
        raw = np.tile(self.template, m)
        records = raw.view(self.dtype)
        for j, column in enumerate(columns):
            records[f"f{j}"] = np.asarray(column).reshape(-1)
        return raw.tobytes()


def _marker(j: int, code: str) -> float | int:
    """A value whose bytes occur nowhere else in a small message (distinct for each j)."""
    if code == "d":
        return 7.0e7 + 0.123456789 + 1.000000119 * j
    return 0x2D1C0B0A + 977 * j


#: steps laid out at once (bounds the memory of the byte buffers)
_STEPS_PER_BLOCK = 512


def _write_messages(writer: Any, store: Any, traj: Trajectory) -> None:
    """All messages, in time order (step by step, robot by robot)."""
    T = store.types
    Vector3, Twist = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Twist"]
    Point, Quaternion, Pose = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"], T["geometry_msgs/msg/Pose"]
    Header, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    PoseStamped, Transform = T["geometry_msgs/msg/PoseStamped"], T["geometry_msgs/msg/Transform"]
    TransformStamped, TFMessage = T["geometry_msgs/msg/TransformStamped"], T["tf2_msgs/msg/TFMessage"]

    schema = {}
    for kind, msgtype in MCAP_TOPICS.items():
        text, _ = store.generate_msgdef(msgtype, ros_version=2)
        schema[kind] = writer.register_schema(name=msgtype, encoding="ros2msg", data=text.encode())
    n = traj.positions.shape[1]
    twist_ch = [writer.register_channel(f"/robot_{i + 1}/cmd_vel", "cdr", schema["cmd_vel"]) for i in range(n)]
    pose_ch = [writer.register_channel(f"/robot_{i + 1}/pose", "cdr", schema["pose"]) for i in range(n)]
    tf_ch = writer.register_channel("/tf", "cdr", schema["tf"])

    def quaternion() -> Any:
        return Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)

    def header() -> Any:
        return Header(stamp=Time(sec=0, nanosec=0), frame_id=WORLD_FRAME)

    twist = Twist(linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0))
    twist_layout = _Layout(store, MCAP_TOPICS["cmd_vel"], twist, [(twist.linear, "x", "d"), (twist.angular, "z", "d")])
    pose = PoseStamped(header=header(), pose=Pose(position=Point(x=0.0, y=0.0, z=0.0), orientation=quaternion()))
    p, q = pose.pose.position, pose.pose.orientation
    pose_layout = _Layout(store, MCAP_TOPICS["pose"], pose,
                          [(pose.header.stamp, "sec", "i"), (pose.header.stamp, "nanosec", "I"),
                           (p, "x", "d"), (p, "y", "d"), (q, "z", "d"), (q, "w", "d")])  # fmt: skip
    transforms = [
        TransformStamped(header=header(), child_frame_id=f"robot_{i + 1}/base_link",
                         transform=Transform(translation=Vector3(x=0.0, y=0.0, z=0.0), rotation=quaternion()))
        for i in range(n)
    ]  # fmt: skip
    tf = TFMessage(transforms=transforms)
    tf_slots = []
    for tr in transforms:
        tf_slots += [(tr.header.stamp, "sec", "i"), (tr.header.stamp, "nanosec", "I"),
                     (tr.transform.translation, "x", "d"), (tr.transform.translation, "y", "d"),
                     (tr.transform.rotation, "z", "d"), (tr.transform.rotation, "w", "d")]  # fmt: skip
    tf_layout = _Layout(store, MCAP_TOPICS["tf"], tf, tf_slots)

    cmd = traj.commands
    assert cmd is not None
    ns = np.rint(np.asarray(traj.times) * 1e9).astype(np.int64)
    sec, nanosec = np.divmod(ns, 1_000_000_000)
    x, y = traj.positions[..., 0], traj.positions[..., 1]
    qz, qw = np.sin(0.5 * traj.headings), np.cos(0.5 * traj.headings)
    steps = ns.size
    _check_first_step(store, twist, pose, tf, twist_layout, pose_layout, tf_layout,
                      (cmd.speed[0], cmd.turn_rate[0], sec[0], nanosec[0], x[0], y[0], qz[0], qw[0]))  # fmt: skip
    add = writer.add_message
    st, sp, stf = twist_layout.size, pose_layout.size, tf_layout.size
    for a in range(0, steps, _STEPS_PER_BLOCK):
        b = min(a + _STEPS_PER_BLOCK, steps)
        s_rows = np.repeat(sec[a:b, None], n, axis=1)
        n_rows = np.repeat(nanosec[a:b, None], n, axis=1)
        twists = twist_layout.fill([cmd.speed[a:b], cmd.turn_rate[a:b]])
        poses = pose_layout.fill([s_rows, n_rows, x[a:b], y[a:b], qz[a:b], qw[a:b]])
        # TF: per step, the six fields of robot 1, then of robot 2, ...
        fields = np.stack([s_rows, n_rows, x[a:b], y[a:b], qz[a:b], qw[a:b]], axis=-1).reshape(b - a, 6 * n)
        tfs = tf_layout.fill(list(fields.T))
        for k in range(b - a):
            t = int(ns[a + k])
            seq = a + k
            base = k * n
            for i in range(n):
                o = base + i
                add(twist_ch[i], t, twists[o * st:(o + 1) * st], t, seq)
                add(pose_ch[i], t, poses[o * sp:(o + 1) * sp], t, seq)
            add(tf_ch, t, tfs[k * stf:(k + 1) * stf], t, seq)


def _check_first_step(store: Any, twist: Any, pose: Any, tf: Any, twist_layout: _Layout, pose_layout: _Layout,
                      tf_layout: _Layout, first: tuple[np.ndarray, ...]) -> None:  # fmt: skip
    """Encode the first step with rosbags' own serializer and with the layouts; they must agree byte for byte."""
    v, w, sec, nanosec, x, y, qz, qw = first
    twist.linear.x, twist.angular.z = float(v[0]), float(w[0])
    pose.header.stamp.sec, pose.header.stamp.nanosec = int(sec), int(nanosec)
    position, orientation = pose.pose.position, pose.pose.orientation
    position.x, position.y, orientation.z, orientation.w = float(x[0]), float(y[0]), float(qz[0]), float(qw[0])
    for i, tr in enumerate(tf.transforms):
        tr.header.stamp.sec, tr.header.stamp.nanosec = int(sec), int(nanosec)
        tr.transform.translation.x, tr.transform.translation.y = float(x[i]), float(y[i])
        tr.transform.rotation.z, tr.transform.rotation.w = float(qz[i]), float(qw[i])
    n = x.size
    expected = (
        (twist, MCAP_TOPICS["cmd_vel"], twist_layout.fill([v[:1], w[:1]])),
        (pose, MCAP_TOPICS["pose"], pose_layout.fill([np.array([sec]), np.array([nanosec]), x[:1], y[:1], qz[:1], qw[:1]])),
        (tf, MCAP_TOPICS["tf"], tf_layout.fill([c for i in range(n) for c in
                                                (np.array([sec]), np.array([nanosec]), x[i:i + 1], y[i:i + 1],
                                                 qz[i:i + 1], qw[i:i + 1])])),
    )  # fmt: skip
    for message, msgtype, laid_out in expected:
        if bytes(store.serialize_cdr(message, msgtype)) != laid_out:
            raise RecordingError(f"internal: the {msgtype} layout disagrees with rosbags' encoding")
