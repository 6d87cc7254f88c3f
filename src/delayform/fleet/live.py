"""The running team served to Foxglove over its WebSocket protocol (``delayform fleet --foxglove PORT``).

The run's parent process, which already takes every message of the run,
serves a Foxglove WebSocket server (the ``foxglove-sdk`` package) on
``127.0.0.1:PORT`` and, every :data:`LIVE_EVERY` s, logs from the world's
newest odometry:

``/fleet/scene`` (``foxglove.SceneUpdate``)
    One entity per robot (``robot_<i>``: its body, a cylinder of the
    profile's radius, and its number; grey while its process is dead), the
    formation's slots (``slots``: flat discs where the shape wants the robots,
    placed at the team's centroid, since the formation is defined up to a
    common offset), and the communication graph (``graph``: a line between
    every pair of robots where one hears the other).
``/fleet/poses`` (``foxglove.PosesInFrame``)
    Every robot's pose, in robot order.

Everything is in the frame ``world`` (metres, the run's plane at z = 0).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from delayform.errors import FleetError, MissingExtraError
from delayform.fleet.wire import Odometry, port_free

__all__ = ["LiveView", "check_live_port", "LIVE_EVERY", "SCENE_TOPIC", "POSES_TOPIC", "FRAME"]

#: seconds between two scenes
LIVE_EVERY = 0.1

#: the topics and the frame of the live view
SCENE_TOPIC, POSES_TOPIC, FRAME = "/fleet/scene", "/fleet/poses", "world"

#: a robot drawn when the robots have no radius (ideal robots): its body's radius (m), for the eye only
_POINT_RADIUS = 0.05

#: the bodies' height (m) and the slots' thickness
_HEIGHT, _SLOT = 0.1, 0.005


def _require_sdk() -> None:
    import importlib.util

    if importlib.util.find_spec("foxglove") is None:  # the fleet extra brings it
        raise MissingExtraError("the live view (--foxglove): foxglove not installed; pip install 'delayform[fleet]'",
                                extra="fleet")  # fmt: skip


def check_live_port(port: int, *, taken: int | None = None) -> int:
    """The live view's port, checked before any process starts.

    Parameters
    ----------
    port
        A TCP port on 127.0.0.1.
    taken
        The run's own Zenoh port (refused: the two servers cannot share it).

    Raises
    ------
    FleetError
        For a port that is not a whole number in 1..65535, the run's own port, or one already taken.
    MissingExtraError
        When the Foxglove SDK is not installed.
    """
    if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535:
        raise FleetError(f"the Foxglove port must be a whole number in 1..65535, got {port!r}")
    if port == taken:
        raise FleetError(f"the Foxglove port {port} is the run's Zenoh endpoint's: give another")
    if not port_free("127.0.0.1", port):
        raise FleetError(f"the Foxglove port {port} is already taken on 127.0.0.1")
    _require_sdk()
    return port


class LiveView:
    """A Foxglove WebSocket server showing the team (module doc).

    Parameters
    ----------
    port
        Where it listens on 127.0.0.1 (checked with :func:`check_live_port`).
    desired
        ``(n, 2)`` the formation's slots.
    radius
        The robots' body radius (m); 0 draws small markers.
    edges
        ``(n, n)`` adjacency: robot i hears robot k where ``edges[i, k]``.

    Raises
    ------
    FleetError
        When the server cannot start (the port taken since the check).
    """

    def __init__(self, port: int, *, desired: NDArray[np.float64], radius: float, edges: Any) -> None:
        _require_sdk()
        import foxglove
        from foxglove.channels import PosesInFrameChannel, SceneUpdateChannel

        self.desired = np.asarray(desired, dtype=np.float64)
        self.radius = radius if radius > 0 else _POINT_RADIUS
        adj = np.asarray(edges.toarray() if hasattr(edges, "toarray") else edges) != 0
        self.pairs = [(i, k) for i in range(adj.shape[0]) for k in range(i + 1, adj.shape[0]) if adj[i, k] or adj[k, i]]
        self._context = foxglove.Context()  # its own: nothing else the process logs reaches the viewer
        try:
            self._server = foxglove.start_server(name="delayform fleet", host="127.0.0.1", port=port,
                                                 context=self._context)  # fmt: skip
        except Exception as exc:  # the SDK's own error (port taken since the check): one line
            raise FleetError(f"the Foxglove server cannot listen on 127.0.0.1:{port}: {str(exc).splitlines()[0][:200]}") from None
        self._scene = SceneUpdateChannel(SCENE_TOPIC, context=self._context)
        self._poses = PosesInFrameChannel(POSES_TOPIC, context=self._context)

    def show(self, odometry: dict[int, Odometry], running: dict[int, bool], now: float) -> None:
        """Log one scene and the poses from each robot's newest odometry (robots without one yet are left out).

        Parameters
        ----------
        odometry
            Robot (from 1) -> its newest odometry.
        running
            Robot (from 1) -> whether its process runs (a dead one is drawn grey).
        now
            Seconds since 1970, the messages' timestamp.
        """
        from foxglove.messages import (
            Color, CylinderPrimitive, LinePrimitive, LinePrimitiveLineType, Point3, Pose, PosesInFrame, Quaternion,
            SceneEntity, SceneUpdate, TextPrimitive, Timestamp, Vector3,
        )  # fmt: skip

        if not odometry:
            return
        stamp = Timestamp.from_epoch_secs(now)
        flat = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
        d = 2.0 * self.radius
        poses, entities = [], []
        for i, o in sorted(odometry.items()):
            turn = Quaternion(x=0.0, y=0.0, z=math.sin(0.5 * o.theta), w=math.cos(0.5 * o.theta))
            poses.append(Pose(position=Vector3(x=o.x, y=o.y, z=0.0), orientation=turn))
            alive = running.get(i, True)
            color = Color(r=0.12, g=0.47, b=0.71, a=0.9) if alive else Color(r=0.5, g=0.5, b=0.5, a=0.6)
            body = CylinderPrimitive(pose=Pose(position=Vector3(x=o.x, y=o.y, z=0.5 * _HEIGHT), orientation=turn),
                                     size=Vector3(x=d, y=d, z=_HEIGHT), bottom_scale=1.0, top_scale=1.0, color=color)  # fmt: skip
            label = TextPrimitive(pose=Pose(position=Vector3(x=o.x, y=o.y, z=2.0 * _HEIGHT), orientation=flat),
                                  billboard=True, font_size=14.0, scale_invariant=True,
                                  color=Color(r=0.0, g=0.0, b=0.0, a=1.0),
                                  text=f"{i}" if alive else f"{i} (dead)")  # fmt: skip
            entities.append(SceneEntity(timestamp=stamp, frame_id=FRAME, id=f"robot_{i}", cylinders=[body], texts=[label]))
        where = {i: (o.x, o.y) for i, o in odometry.items()}
        if len(where) == self.desired.shape[0]:  # the slots need every robot: they sit at the team's centroid
            offset = np.mean(list(where.values()), axis=0) - self.desired.mean(axis=0)
            slots = [CylinderPrimitive(pose=Pose(position=Vector3(x=float(px), y=float(py), z=0.0), orientation=flat),
                                       size=Vector3(x=d, y=d, z=_SLOT), bottom_scale=1.0, top_scale=1.0,
                                       color=Color(r=0.2, g=0.63, b=0.17, a=0.4))
                     for px, py in self.desired + offset]  # fmt: skip
            entities.append(SceneEntity(timestamp=stamp, frame_id=FRAME, id="slots", cylinders=slots))
        points = []
        for i, k in self.pairs:
            if i + 1 in where and k + 1 in where:
                points += [Point3(x=where[i + 1][0], y=where[i + 1][1], z=0.5 * _HEIGHT),
                           Point3(x=where[k + 1][0], y=where[k + 1][1], z=0.5 * _HEIGHT)]  # fmt: skip
        graph = LinePrimitive(type=LinePrimitiveLineType.LineList, pose=Pose(position=Vector3(), orientation=flat),
                              thickness=2.0, scale_invariant=True, points=points,
                              color=Color(r=0.4, g=0.4, b=0.4, a=0.8))  # fmt: skip
        entities.append(SceneEntity(timestamp=stamp, frame_id=FRAME, id="graph", lines=[graph]))
        ns = int(now * 1e9)
        self._scene.log(SceneUpdate(entities=entities), log_time=ns)
        self._poses.log(PosesInFrame(timestamp=stamp, frame_id=FRAME, poses=poses), log_time=ns)

    def stop(self) -> None:
        """Stop the server (clients are disconnected)."""
        self._server.stop()
