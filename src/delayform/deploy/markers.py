"""Foxglove / RViz markers of a recorded run: the robots' bodies, the formation's slots, the communication graph.

Each function returns a rosbags ``visualization_msgs/msg/MarkerArray``
object (types from a rosbags type store, so nothing of the ROS message
definitions is written here). Bodies and slots are published once, locked
to moving frames (``frame_locked``): a body to ``robot_<i>/base_link``, a
slot to ``formation`` (the frame whose origin is the weighted centroid's
offset, :mod:`delayform.deploy.recording`), so the viewer moves them with
``/tf``. The communication graph changes with the robots' positions, so it
is one ``LINE_LIST`` whose points are refilled at every published step.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.deploy._cdr import Slot

__all__ = ["body_markers", "slot_markers", "link_marker", "link_pairs", "BODY_HEIGHT"]

#: height (m) of the cylinders that stand for the robots' bodies (a 2-D run has none)
BODY_HEIGHT = 0.1

#: colours (r, g, b, a): bodies, slots, labels; a link heard both ways; a one-way link's sender and receiver ends
_BODY, _SLOT, _LABEL = (0.2, 0.5, 0.9, 0.6), (0.2, 0.8, 0.3, 0.35), (1.0, 1.0, 1.0, 1.0)
_BOTH, _SENDER, _RECEIVER = (0.75, 0.75, 0.75, 0.9), (0.3, 0.5, 1.0, 0.9), (1.0, 0.55, 0.1, 0.9)


def _marker(T: Any, frame: str, stamp: tuple[int, int], ns: str, ident: int, kind: str, *,
            at: tuple[float, float, float] = (0.0, 0.0, 0.0), scale: tuple[float, float, float],
            color: tuple[float, float, float, float], text: str = "", locked: bool = True) -> Any:  # fmt: skip
    """One ADD marker that lives until replaced (lifetime 0)."""
    M = T["visualization_msgs/msg/Marker"]
    return M(
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=stamp[0], nanosec=stamp[1]),
                                        frame_id=frame),
        ns=ns, id=ident, type=getattr(M, kind), action=M.ADD,
        pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=at[0], y=at[1], z=at[2]),
                                         orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)),
        scale=T["geometry_msgs/msg/Vector3"](x=scale[0], y=scale[1], z=scale[2]),
        color=T["std_msgs/msg/ColorRGBA"](r=color[0], g=color[1], b=color[2], a=color[3]),
        lifetime=T["builtin_interfaces/msg/Duration"](sec=0, nanosec=0), frame_locked=locked,
        points=[], colors=[], texture_resource="",
        texture=T["sensor_msgs/msg/CompressedImage"](
            header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id=""),
            format="", data=np.zeros(0, dtype=np.uint8)),
        uv_coordinates=[], text=text, mesh_resource="",
        mesh_file=T["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, dtype=np.uint8)),
        mesh_use_embedded_materials=False,
    )  # fmt: skip


def body_markers(T: Any, n: int, radius: float, stamp: tuple[int, int]) -> Any:
    """Each robot's footprint (a cylinder of the body radius, when there is one) and its number.

    Parameters
    ----------
    T
        The type store's ``types``.
    n
        Robots, numbered from 1.
    radius
        Body radius (m); 0 (point agents): the numbers only.
    stamp
        ``(sec, nanosec)`` of the headers.
    """
    markers = []
    for i in range(1, n + 1):
        frame = f"robot_{i}/base_link"
        if radius > 0:
            markers.append(_marker(T, frame, stamp, "bodies", i, "CYLINDER", at=(0.0, 0.0, 0.5 * BODY_HEIGHT),
                                   scale=(2 * radius, 2 * radius, BODY_HEIGHT), color=_BODY))  # fmt: skip
        size = max(2 * radius, 0.1)
        markers.append(_marker(T, frame, stamp, "labels", i, "TEXT_VIEW_FACING", at=(0.0, 0.0, BODY_HEIGHT + 0.5 * size),
                               scale=(0.0, 0.0, size), color=_LABEL, text=str(i)))  # fmt: skip
    return T["visualization_msgs/msg/MarkerArray"](markers=markers)


def slot_markers(T: Any, desired: NDArray[np.float64], slots: Sequence[int], radius: float, stamp: tuple[int, int]) -> Any:
    """The formation's places in the frame ``formation``: a flat disc per slot, named by the robot that takes it.

    Parameters
    ----------
    T
        The type store's ``types``.
    desired
        ``(n, 2)`` robot i's place z_i (already in the robots' order).
    slots
        Which slot of the formation robot i took (from 0).
    radius
        Disc radius (m): the body radius, or for point agents a tenth of the closest two places' distance.
    stamp
        ``(sec, nanosec)`` of the headers.
    """
    markers = []
    for i, ((x, y), k) in enumerate(zip(desired, slots), start=1):
        markers.append(_marker(T, "formation", stamp, "slots", i, "CYLINDER", at=(float(x), float(y), 0.005),
                               scale=(2 * radius, 2 * radius, 0.01), color=_SLOT))  # fmt: skip
        markers.append(_marker(T, "formation", stamp, "slot_labels", i, "TEXT_VIEW_FACING",
                               at=(float(x), float(y), 0.05), scale=(0.0, 0.0, max(radius, 0.05)), color=_SLOT[:3] + (1.0,),
                               text=f"slot {int(k) + 1} (robot {i})"))  # fmt: skip
    return T["visualization_msgs/msg/MarkerArray"](markers=markers)


def link_pairs(adjacency: Any) -> list[tuple[int, int, str]]:
    """The unordered pairs (a, b), a < b (from 0), of robots joined by a link, and who hears whom.

    Row i of the adjacency (dense or SciPy sparse) is what robot i hears
    (``a_ik > 0``: k sends to i). The third entry is ``"both"``, ``"a->b"``
    (a sends, b hears) or ``"b->a"``.
    """
    rows, cols = adjacency.nonzero()  # a NumPy array and a SciPy sparse array alike
    heard = {(int(i), int(k)) for i, k in zip(rows, cols) if i != k}  # (receiver, sender)
    out = []
    for a, b in sorted({(min(i, k), max(i, k)) for i, k in heard}):
        forward, backward = (b, a) in heard, (a, b) in heard
        out.append((a, b, "both" if forward and backward else ("a->b" if forward else "b->a")))
    return out


def link_marker(T: Any, pairs: Sequence[tuple[int, int, str]]) -> tuple[Any, list[Slot]]:
    """The communication graph as one ``LINE_LIST`` in ``odom``, and the fields to refill at each step.

    A link heard both ways is grey; a one-way link goes from blue (the
    sender) to orange (the receiver).

    Returns
    -------
    (MarkerArray, slots)
        The message (zero stamp and points) and its changing fields: the
        stamp's sec and nanosec, then x and y of each pair's two ends, pair
        by pair, the lower-numbered robot first (``pairs``: :func:`link_pairs`).
    """
    P, C = T["geometry_msgs/msg/Point"], T["std_msgs/msg/ColorRGBA"]
    line = _marker(T, "odom", (0, 0), "links", 0, "LINE_LIST", scale=(0.02, 0.0, 0.0), color=_BOTH, locked=False)
    line.points = [P(x=0.0, y=0.0, z=0.0) for _ in range(2 * len(pairs))]
    colors = []
    ends_of = {"both": (_BOTH, _BOTH), "a->b": (_SENDER, _RECEIVER), "b->a": (_RECEIVER, _SENDER)}
    for _, _, heard in pairs:
        ends = ends_of[heard]
        colors += [C(r=c[0], g=c[1], b=c[2], a=c[3]) for c in ends]
    line.colors = colors
    slots: list[Slot] = [(line.header.stamp, "sec", "i"), (line.header.stamp, "nanosec", "I")]
    for p in line.points:
        slots += [(p, "x", "d"), (p, "y", "d")]
    return T["visualization_msgs/msg/MarkerArray"](markers=[line]), slots
