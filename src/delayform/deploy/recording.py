"""A simulated run as a ROS 2 recording: an MCAP file that Foxglove, RViz (via rosbag2) and ``ros2 bag`` read.

Topics (robots numbered from 1), one message per robot per saved step
unless said otherwise, stamped ``log_time = publish_time = header.stamp =
start + t`` (ns; ``start`` is 0, i.e. 1970-01-01, unless ``start_time`` is
given):

``/robot_<i>/odom`` ``nav_msgs/msg/Odometry``
    As REP 105 and nav_msgs say: ``header.frame_id = "odom"``,
    ``child_frame_id = "robot_<i>/base_link"``; the pose in ``odom``:
    position (x, y, 0) and the heading as the quaternion
    ``(0, 0, sin(theta/2), cos(theta/2))``; the twist in the body frame:
    ``linear.x`` the signed speed v, ``linear.y`` the velocity across the
    heading (0 for a robot, which cannot slide; an ideal robot at rest holds
    its heading while the double integrator it follows may drift), and
    ``angular.z`` the turn rate omega. Covariances are 0: simulated states
    are exact.
``/robot_<i>/cmd_vel`` ``geometry_msgs/msg/Twist``
    ``linear.x`` = v (m/s), ``angular.z`` = the executed omega (rad/s): the
    columns ``v`` and ``omega`` of the command files
    (:meth:`RobotCommands.to_csv`).
``/robot_<i>/pose`` ``geometry_msgs/msg/PoseStamped``
    The odometry's pose on its own (frame ``odom``).
``/tf`` ``tf2_msgs/msg/TFMessage``
    Per saved step ``odom -> robot_<i>/base_link`` for every robot and,
    with the topology, ``odom -> formation``: the origin the slots are
    drawn from, the weighted centroid's offset ``sum_i w_i (x_i - z_i)``
    (paper, eq. 4), where the formation settles.
``/tf_static`` ``tf2_msgs/msg/TFMessage``
    Once: ``map -> odom``, the identity (the simulation has one shared,
    drift-free frame, what a motion-capture system gives a real team).
``/formation/bodies``, ``/formation/slots`` ``visualization_msgs/msg/MarkerArray``
    Once, locked to the moving frames: each robot's footprint (a cylinder
    of the body radius, when the run has one) and number; each slot as a
    disc in ``formation`` (:mod:`delayform.deploy.markers`).
``/formation/links`` ``visualization_msgs/msg/MarkerArray``
    With the topology: the communication graph as lines between the robots
    at most :data:`LINK_RATE` times a second (every saved step below that).

Metadata records (``mcap.reader``'s ``iter_metadata``; all values strings,
numbers in ``repr`` so they read back exactly): ``delayform/run`` (the
design, the saved period, the start time, the limits, each robot's weights
and forcing as JSON, and whether a replay through
:class:`~delayform.deploy.controller.FormationController` is exact), plus
the records the caller adds (``simulate --mcap``: ``delayform/scenario``
and ``delayform/analysis``).

The messages are encoded in CDR by ``rosbags`` (its ROS 2 Humble type
store) and written by the ``mcap`` package, with the schemas as ``ros2msg``
text: what rosbag2's MCAP storage writes. The messages of each shape are
laid out by :class:`~delayform.deploy._cdr.Layout` (rosbags' own bytes, filled
with NumPy); the first step of every file is encoded both ways and compared
byte for byte, and the tests decode whole files with ``mcap-ros2-support``'s
independent decoder. The file is written under a temporary name beside the
target and renamed when complete, so a failed export leaves nothing
half-written.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
import os
import tempfile
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from delayform._extras import require_extra
from delayform._files import atomic_path
from delayform._validation import validated
from delayform.deploy._cdr import Layout, Slot
from delayform.deploy.markers import body_markers, link_marker, link_pairs, slot_markers
from delayform.errors import RecordingError

if TYPE_CHECKING:  # pragma: no cover - typing only
    from delayform.model.network import Network
    from delayform.simulation.runs.trajectory import Trajectory
    from delayform.topology import Topology

__all__ = ["write_mcap", "check_mcap_path", "recording_start", "odometry_layout", "twist_layout",
           "MCAP_TOPICS", "LINK_RATE", "LINK_LIMIT"]

#: message type of each kind of topic
MCAP_TOPICS = {
    "odom": "nav_msgs/msg/Odometry",
    "cmd_vel": "geometry_msgs/msg/Twist",
    "pose": "geometry_msgs/msg/PoseStamped",
    "tf": "tf2_msgs/msg/TFMessage",
    "tf_static": "tf2_msgs/msg/TFMessage",
    "markers": "visualization_msgs/msg/MarkerArray",
}

#: the fixed frame of odometry, poses and /tf (REP 105), and the frame above it on /tf_static
ODOM_FRAME, MAP_FRAME = "odom", "map"

#: the frame of the slots: its origin is where the weighted centroid puts the formation
FORMATION_FRAME = "formation"

#: the communication graph is published at most this often (Hz): it only follows the robots
LINK_RATE = 20.0

#: teams with more linked pairs than this get no graph (a line per pair per step would dwarf the rest)
LINK_LIMIT = 500

#: ROS 2 time stamps hold the seconds in an int32
_MAX_SECONDS = 2**31 - 1

#: steps laid out at once (bounds the memory of the byte buffers)
_STEPS_PER_BLOCK = 512

_EPOCH = _dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc)


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


def recording_start(value: object) -> int:
    """The recording's start time in ns since 1970-01-01 UTC (what stamps add to the simulated time).

    Parameters
    ----------
    value
        None or 0: 1970-01-01 (simulated time as it is); a timezone-aware
        ``datetime``; seconds since the epoch (a float or int, >= 0); or a
        string: ``"now"`` (the clock when this is called), seconds, or ISO
        8601 with an offset (``2026-12-03T10:00:00Z``, ``...+01:00``).

    Raises
    ------
    RecordingError
        For a naive datetime or ISO time without offset (it names no
        instant), a negative or non-finite number, or text that is neither.
    """
    if value is None:
        return 0
    if isinstance(value, str):
        text = value.strip()
        if text.lower() == "now":
            return time.time_ns()
        try:
            value = float(text)
        except ValueError:
            value = None
        try:
            value = _dt.datetime.fromisoformat(text) if value is None else value
        except ValueError:
            raise RecordingError(f"the start time must be 'now', ISO 8601 such as 2026-12-03T10:00:00Z, "
                                 f"or seconds since 1970, got {text!r}") from None  # fmt: skip
    if isinstance(value, _dt.datetime):
        if value.tzinfo is None or value.utcoffset() is None:
            raise RecordingError(f"the start time {value.isoformat()} has no time zone: add one (Z for UTC, or +01:00)")
        delta = value - _EPOCH  # exact: days, seconds and microseconds are integers
        ns = (delta.days * 86_400 + delta.seconds) * 10**9 + delta.microseconds * 1_000
    elif isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        if not math.isfinite(value):
            raise RecordingError(f"the start time must be finite seconds since 1970, got {value!r}")
        ns = round(Fraction(float(value)) * 10**9)  # the float's own value, not value * 1e9 rounded to 256 ns
    else:
        raise RecordingError(f"the start time must be a datetime, seconds since 1970 or a string, got {type(value).__name__}")
    if ns < 0:
        raise RecordingError(f"the start time must not be before 1970-01-01 (ROS 2 time), got {value!r}")
    if ns // 10**9 > _MAX_SECONDS:
        raise RecordingError(f"the start time {value!r} is after 2038-01-19, the last second a ROS 2 stamp holds")
    return int(ns)


def _iso(ns: int) -> str:
    whole = _EPOCH + _dt.timedelta(seconds=ns // 10**9)
    return whole.strftime("%Y-%m-%dT%H:%M:%S") + f".{ns % 10**9:09d}Z"


@validated(RecordingError)
def write_mcap(
    trajectory: Trajectory,
    path: str | Path,
    *,
    compression: str = "zstd",
    topology: Topology | None = None,
    start_time: _dt.datetime | float | str | None = None,
    metadata: Mapping[str, Mapping[str, str]] | None = None,
    network: Network | None = None,
) -> Path:
    """Write a robots' run as an MCAP file of ROS 2 messages (module doc: topics, frames, metadata).

    Parameters
    ----------
    trajectory
        A run of robots (``model="unicycle"``, ideal or with limits, or ``"physics"``): it
        carries the commands the Twists hold.
    path
        The file to write; replaced atomically when complete.
    compression
        ``"zstd"`` (default, what rosbag2 uses), ``"lz4"`` or ``"none"``.
    topology
        The team the run simulated: adds the slots, the ``formation`` frame,
        the communication graph and each robot's weights and forcing (what
        its controller needs, in the metadata). It must be the run's.
    start_time
        When t = 0 is (:func:`recording_start`); default 1970-01-01, so that
        stamps are the simulated time and the same run gives the same file.
    metadata
        More metadata records, name -> {key: text}.
    network
        The imperfect network the run went over, if any (the metadata then
        says a replay of the odometry is not what the robots heard).

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    RecordingError
        For a double-integrator run (no robot commands), a topology of
        another size, a bad compression name, start time or metadata, or a
        path that cannot be written (:func:`check_mcap_path`).
    MissingExtraError
        Without mcap or rosbags (the ``ros`` extra).
    """
    require_extra("ros")
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    # here, not at the top: the fleet's robot processes import this module for the message layouts
    # alone (delayform.fleet.wire) and start without the simulator, the formation's algebra and SciPy
    from delayform.model.network import Network
    from delayform.simulation.runs.trajectory import Trajectory
    from delayform.topology import Topology

    if not isinstance(trajectory, Trajectory):
        raise RecordingError(f"write_mcap takes a Trajectory, got {type(trajectory).__name__}")
    if trajectory.commands is None:
        raise RecordingError("an MCAP recording holds robots' commands: simulate model 'unicycle' or 'physics', "
                             "not double integrators")  # fmt: skip
    kinds = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
    if compression not in kinds:
        raise RecordingError(f"compression must be one of {', '.join(kinds)}, got {compression!r}")
    if topology is not None and (not isinstance(topology, Topology) or topology.n != trajectory.n):
        raise RecordingError(f"topology must be the run's Topology of {trajectory.n} robots, got {topology!r:.80}")
    if network is not None and not isinstance(network, Network):
        raise RecordingError(f"network must be a Network or None, got {type(network).__name__}")
    start = recording_start(start_time)
    last = start + int(np.rint(trajectory.times[-1] * 1e9))
    if last // 10**9 > _MAX_SECONDS:
        raise RecordingError(f"the run would end after 2038-01-19 ({_iso(last)}), the last second a ROS 2 stamp holds")
    records = {"delayform/run": _run_record(trajectory, topology, start, network)}
    for name, record in (metadata or {}).items():
        if not isinstance(name, str) or not isinstance(record, Mapping) or not all(
                isinstance(k, str) and isinstance(v, str) for k, v in record.items()):  # fmt: skip
            raise RecordingError(f"metadata must map names to {{text: text}} records, got {name!r}: {record!r:.80}")
        records[name] = dict(record)
    path = check_mcap_path(path)
    store = get_typestore(Stores.ROS2_HUMBLE)
    with atomic_path(path) as tmp, open(tmp, "wb") as stream:
        writer = Writer(stream, compression=kinds[compression])
        writer.start(profile="ros2", library="delayform (mcap + rosbags)")
        _write_messages(writer, store, trajectory, topology, start)
        for name, record in records.items():
            writer.add_metadata(name, record)
        writer.finish()
    return path


def _saved_period(traj: Trajectory) -> float:
    return float(traj.times[1] - traj.times[0]) if traj.times.size > 1 else float(traj.dt)


def _replay_note(traj: Trajectory, network: Network | None) -> str:
    """Whether the recorded odometry is all a robot's controller needs to recompute the recorded commands."""
    h = _saved_period(traj)
    reasons = []
    if network is not None:
        reasons.append("the run went over an imperfect network: the robots heard other states than the odometry")
    if traj.safety is not None:
        reasons.append("the safety filter changed the commands (the controller does not include it)")
    if traj.actuation_delay > 0:
        reasons.append("the robots executed their commands late (an actuation delay)")
    for name, tau in (("tau1", traj.tau1), ("tau2", traj.tau2)):
        if abs(tau / h - round(tau / h)) > 1e-9:
            reasons.append(f"{name} = {tau!r} s is not a multiple of the saved period {h!r} s: the simulation "
                           f"interpolates between steps, a playout buffer holds the last sample")  # fmt: skip
    if reasons:
        return "not exact: " + "; ".join(reasons)
    return ("exact: each robot's controller, fed its neighbours' odometry as messages and its own, "
            "recomputes the recorded turn rates")  # fmt: skip


def _run_record(traj: Trajectory, topology: Topology | None, start: int, network: Network | None) -> dict[str, str]:
    """The ``delayform/run`` metadata: the design, the frames, and what each robot's controller needs."""
    from delayform.formation import formation_forcing

    record = {
        "model": traj.model + (" with limits" if traj.limits is not None else " (ideal robots)"),
        "robots": str(traj.n), "P": repr(traj.P), "D": repr(traj.D), "tau1": repr(traj.tau1), "tau2": repr(traj.tau2),
        "dt": repr(traj.dt), "saved_period": repr(_saved_period(traj)), "steps_saved": str(traj.times.size),
        "actuation_delay": repr(traj.actuation_delay), "body_radius": repr(traj.radius),
        "limits": "none" if traj.limits is None else json.dumps(dataclasses.asdict(traj.limits)),
        "network": "ideal" if network is None else network.describe(),
        "status": traj.status, "settling_time": repr(traj.settling_time),
        "start_time_ns": str(start), "start_time": _iso(start),
        "frames": f"{MAP_FRAME} -> {ODOM_FRAME} (static, identity); {ODOM_FRAME} -> robot_<i>/base_link; "
                  f"{ODOM_FRAME} -> {FORMATION_FRAME} (the slots' origin)",
        "desired": json.dumps(traj.desired.tolist()),
        "slots": json.dumps([int(k) + 1 for k in (traj.slots if traj.slots is not None else range(traj.n))]),
        "controller_replay": _replay_note(traj, network),
    }  # fmt: skip
    if topology is not None:
        C = topology.C_sparse.tocsr()
        weights = [{str(int(j) + 1): float(w) for j, w in zip(C.indices[C.indptr[i]:C.indptr[i + 1]],
                                                               C.data[C.indptr[i]:C.indptr[i + 1]]) if j != i and w != 0}
                   for i in range(traj.n)]  # fmt: skip
        record["weights"] = json.dumps(weights)
        record["forcing"] = json.dumps(formation_forcing(topology, traj.P, traj.desired).tolist())
    return record


@dataclass
class _Lane:
    """One channel's messages: its layout and, for the steps of a block, its columns (one array per field)."""

    channel: int
    layout: Layout
    columns: Callable[[np.ndarray], list[np.ndarray]]
    stride: int = 1  # published at every stride-th saved step


def _header(T: Any, frame: str) -> Any:
    return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id=frame)


def _zero_pose(T: Any) -> Any:
    return T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                                       orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0))  # fmt: skip


def _transform(T: Any, parent: str, child: str) -> Any:
    V3, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    return T["geometry_msgs/msg/TransformStamped"](
        header=_header(T, parent), child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](translation=V3(x=0.0, y=0.0, z=0.0), rotation=Q(x=0.0, y=0.0, z=0.0, w=1.0)))  # fmt: skip


def _stamp_slots(header: Any) -> list[Slot]:
    return [(header.stamp, "sec", "i"), (header.stamp, "nanosec", "I")]


def _odometry(T: Any, child: str) -> tuple[Any, list[Slot]]:
    """An Odometry message of a robot and its changing fields: stamp, x, y, qz, qw, v, lateral v, omega."""
    V3 = T["geometry_msgs/msg/Vector3"]
    zeros = np.zeros(36, dtype=np.float64)
    odom = T["nav_msgs/msg/Odometry"](
        header=_header(T, ODOM_FRAME), child_frame_id=child,
        pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=_zero_pose(T), covariance=zeros.copy()),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=V3(x=0.0, y=0.0, z=0.0), angular=V3(x=0.0, y=0.0, z=0.0)),
            covariance=zeros.copy()))  # fmt: skip
    p, q, tw = odom.pose.pose.position, odom.pose.pose.orientation, odom.twist.twist
    return odom, _stamp_slots(odom.header) + [(p, "x", "d"), (p, "y", "d"), (q, "z", "d"), (q, "w", "d"),
                                              (tw.linear, "x", "d"), (tw.linear, "y", "d"), (tw.angular, "z", "d")]  # fmt: skip


def odometry_layout(store: Any, robot: int) -> Layout:
    """The CDR layout of robot ``robot``'s ``nav_msgs/msg/Odometry`` (module doc: frames and fields).

    Its changing fields, in order: ``header.stamp.sec``, ``header.stamp.nanosec``,
    position x, y, orientation z, w, twist linear x (the signed speed), linear y
    (across the heading) and angular z (the turn rate).

    Parameters
    ----------
    store
        The rosbags type store (ROS 2 Humble).
    robot
        The robot's number, from 1 (the child frame ``robot_<i>/base_link`` is part of the bytes).
    """
    odom, slots = _odometry(store.types, f"robot_{robot}/base_link")
    return Layout(store, MCAP_TOPICS["odom"], odom, slots)


def twist_layout(store: Any) -> Layout:
    """The CDR layout of a ``geometry_msgs/msg/Twist`` command: ``linear.x`` (m/s), then ``angular.z`` (rad/s).

    Parameters
    ----------
    store
        The rosbags type store (ROS 2 Humble).
    """
    T = store.types
    V3 = T["geometry_msgs/msg/Vector3"]
    twist = T["geometry_msgs/msg/Twist"](linear=V3(x=0.0, y=0.0, z=0.0), angular=V3(x=0.0, y=0.0, z=0.0))
    return Layout(store, MCAP_TOPICS["cmd_vel"], twist, [(twist.linear, "x", "d"), (twist.angular, "z", "d")])


def _write_messages(writer: Any, store: Any, traj: Trajectory, topology: Topology | None, start: int) -> None:
    """All messages in time order: the once-only ones at the start, then step by step, robot by robot."""
    T = store.types
    schema: dict[str, int] = {}

    def channel(topic: str, kind: str) -> int:
        msgtype = MCAP_TOPICS[kind]
        if msgtype not in schema:
            text, _ = store.generate_msgdef(msgtype, ros_version=2)
            schema[msgtype] = writer.register_schema(name=msgtype, encoding="ros2msg", data=text.encode())
        return writer.register_channel(topic, "cdr", schema[msgtype])

    n = traj.n
    cmd = traj.commands
    assert cmd is not None
    ns = start + np.rint(np.asarray(traj.times) * 1e9).astype(np.int64)
    sec, nanosec = np.divmod(ns, 1_000_000_000)
    x, y = traj.positions[..., 0], traj.positions[..., 1]
    th = traj.headings
    qz, qw = np.sin(0.5 * th), np.cos(0.5 * th)
    # the velocity in the body frame (REP 105: the odometry's twist is in child_frame_id)
    c, s = np.cos(th), np.sin(th)
    across = c * traj.velocities[..., 1] - s * traj.velocities[..., 0]
    lanes: list[_Lane] = []
    twists = twist_layout(store)
    pose = T["geometry_msgs/msg/PoseStamped"](header=_header(T, ODOM_FRAME), pose=_zero_pose(T))
    p, q = pose.pose.position, pose.pose.orientation
    pose_layout = Layout(store, MCAP_TOPICS["pose"], pose, _stamp_slots(pose.header) + [
        (p, "x", "d"), (p, "y", "d"), (q, "z", "d"), (q, "w", "d")])  # fmt: skip
    for i in range(n):
        # the child frame's name changes the layout
        lanes.append(_Lane(channel(f"/robot_{i + 1}/odom", "odom"), odometry_layout(store, i + 1),
                           lambda k, i=i: [sec[k], nanosec[k], x[k, i], y[k, i], qz[k, i], qw[k, i],
                                           traj.speeds[k, i], across[k, i], cmd.turn_rate[k, i]]))  # fmt: skip
        lanes.append(_Lane(channel(f"/robot_{i + 1}/cmd_vel", "cmd_vel"), twists,
                           lambda k, i=i: [cmd.speed[k, i], cmd.turn_rate[k, i]]))  # fmt: skip
        lanes.append(_Lane(channel(f"/robot_{i + 1}/pose", "pose"), pose_layout,
                           lambda k, i=i: [sec[k], nanosec[k], x[k, i], y[k, i], qz[k, i], qw[k, i]]))  # fmt: skip
    transforms = [_transform(T, ODOM_FRAME, f"robot_{i + 1}/base_link") for i in range(n)]
    per_robot = [x, y, qz, qw]
    if topology is not None:
        transforms.append(_transform(T, ODOM_FRAME, FORMATION_FRAME))
        # the offset the weighted centroid gives the formation (paper, eq. 4): where the slots are
        from delayform.formation import centroid_weights

        w = centroid_weights(topology)
        offset = np.einsum("i,tij->tj", w, traj.positions - traj.desired[None])
    tf_slots: list[Slot] = []
    for tr in transforms:
        tf_slots += _stamp_slots(tr.header) + [(tr.transform.translation, "x", "d"), (tr.transform.translation, "y", "d"),
                                               (tr.transform.rotation, "z", "d"), (tr.transform.rotation, "w", "d")]  # fmt: skip

    def tf_columns(k: np.ndarray) -> list[np.ndarray]:
        cols = [col for i in range(n) for col in (sec[k], nanosec[k], *(a[k, i] for a in per_robot))]
        if topology is not None:
            cols += [sec[k], nanosec[k], offset[k, 0], offset[k, 1], np.zeros(k.size), np.ones(k.size)]
        return cols

    tf = T["tf2_msgs/msg/TFMessage"](transforms=transforms)
    lanes.append(_Lane(channel("/tf", "tf"), Layout(store, MCAP_TOPICS["tf"], tf, tf_slots), tf_columns))
    pairs = link_pairs(topology.adjacency_sparse) if topology is not None else []
    if pairs and len(pairs) <= LINK_LIMIT:
        links, link_slots = link_marker(T, pairs)
        ends = np.array([[a, b] for a, b, _ in pairs]).reshape(-1)  # robot of each line end

        def link_columns(k: np.ndarray) -> list[np.ndarray]:
            return [sec[k], nanosec[k]] + [col for r in ends for col in (x[k, r], y[k, r])]

        stride = max(1, math.ceil(1.0 / (LINK_RATE * _saved_period(traj)) - 1e-9))
        lanes.append(_Lane(channel("/formation/links", "markers"), Layout(store, MCAP_TOPICS["markers"], links, link_slots),
                           link_columns, stride))  # fmt: skip
    for lane in lanes:  # before anything is written: every layout against rosbags' own encoding
        lane.layout.verify([col[0] for col in lane.columns(np.array([0]))])
    _write_once(writer, store, traj, topology, channel, (int(sec[0]), int(nanosec[0])), int(ns[0]))
    _write_steps(writer, lanes, ns)


def _write_once(writer: Any, store: Any, traj: Trajectory, topology: Topology | None,
                channel: Callable[[str, str], int], stamp: tuple[int, int], t0: int) -> None:  # fmt: skip
    """/tf_static and the markers locked to frames, at the first stamp."""
    T = store.types
    static = _transform(T, MAP_FRAME, ODOM_FRAME)
    static.header.stamp.sec, static.header.stamp.nanosec = stamp
    once = [(channel("/tf_static", "tf_static"), MCAP_TOPICS["tf_static"], T["tf2_msgs/msg/TFMessage"](transforms=[static])),
            (channel("/formation/bodies", "markers"), MCAP_TOPICS["markers"], body_markers(T, traj.n, traj.radius, stamp))]  # fmt: skip
    if topology is not None:
        d = traj.desired
        gaps = np.hypot(*(d[:, None] - d[None]).transpose(2, 0, 1))[np.triu_indices(traj.n, 1)]
        radius = traj.radius if traj.radius > 0 else (0.1 * float(gaps.min()) if gaps.size and gaps.min() > 0 else 0.05)
        slots = traj.slots if traj.slots is not None else range(traj.n)
        once.append((channel("/formation/slots", "markers"), MCAP_TOPICS["markers"],
                     slot_markers(T, d, [int(k) for k in slots], radius, stamp)))  # fmt: skip
    for ch, msgtype, message in once:
        writer.add_message(ch, t0, bytes(store.serialize_cdr(message, msgtype)), t0, 0)


def _write_steps(writer: Any, lanes: list[_Lane], ns: np.ndarray) -> None:
    """Every lane's message at each saved step (of its stride), in blocks laid out with NumPy."""
    add = writer.add_message
    steps = ns.size
    for a in range(0, steps, _STEPS_PER_BLOCK):
        b = min(a + _STEPS_PER_BLOCK, steps)
        blocks = []
        for lane in lanes:
            k = np.arange(a + (-a) % lane.stride, b, lane.stride)
            blocks.append((lane, k, lane.layout.fill(lane.columns(k)) if k.size else b""))
        for step in range(a, b):
            t = int(ns[step])
            for lane, k, data in blocks:
                if step % lane.stride:
                    continue
                r = (step - int(k[0])) // lane.stride
                size = lane.layout.size
                add(lane.channel, t, data[r * size:(r + 1) * size], t, step)
