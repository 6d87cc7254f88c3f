"""What travels between the processes of a fleet run: key expressions, CDR messages, the Zenoh session.

Key expressions follow the ROS 2 topic names without the domain, type and hash
rmw_zenoh adds (:mod:`delayform.fleet.rmw` publishes those copies), robots numbered from 1:

``robot_<i>/odom`` ``nav_msgs/msg/Odometry``, from the world
    The robot's true pose and motion at the stamp: position (x, y, 0), the
    heading as the quaternion ``(0, 0, sin(theta/2), cos(theta/2))``, twist in
    the body frame (``linear.x`` the signed speed v, ``angular.z`` the turn
    rate), ``header.stamp`` the world's clock (s since 1970, as ROS 2).
``robot_<i>/cmd_vel`` ``geometry_msgs/msg/Twist``, from robot i
    ``linear.x`` the speed set-point for the next control period, ``angular.z``
    the turn rate (the controller's :meth:`~delayform.deploy.controller.FormationController.speed_command`).
``robot_<i>/state`` ``nav_msgs/msg/Odometry``, from robot i
    What robot i tells its neighbours: the odometry it last heard, re-sent with
    that odometry's stamp (the sender's clock when the state was true). A
    unicycle cannot slide, so its Cartesian velocity is
    ``v (cos theta, sin theta)``.

Every payload is CDR as rosbags' ROS 2 Humble type store lays it out
(:func:`delayform.deploy.recording.odometry_layout`, :func:`~delayform.deploy.recording.twist_layout`):
the layout's template is filled with ``struct.pack_into`` at the offsets the
layout found, and read back with its NumPy dtype, so a message costs a few
microseconds and is byte for byte what rosbags writes.
"""

from __future__ import annotations

import json
import math
import socket
import struct
from typing import Any, NamedTuple

from delayform.errors import FleetError

__all__ = ["Codec", "Odometry", "key", "open_session", "check_endpoint", "port_free", "DEFAULT_ENDPOINT"]

#: where the run's processes meet: the parent listens there, every child connects to it
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"


def key(robot: int, topic: str) -> str:
    """``robot_<i>/<topic>``: the key expression of a robot's topic (ROS 2 name without the leading slash)."""
    return f"robot_{robot}/{topic}"


class Odometry(NamedTuple):
    """An odometry's fields: stamp (s since 1970), pose, signed speed and turn rate."""

    stamp: float
    x: float
    y: float
    theta: float
    v: float
    omega: float


class _Packer:
    """One layout's template, filled by ``struct.pack_into`` at the layout's offsets."""

    def __init__(self, template: bytes, offsets: list[int], codes: list[str]) -> None:
        self.template, self.offsets, self.codes = bytes(template), [int(o) for o in offsets], [str(c) for c in codes]
        self.size = len(self.template)
        if len(self.offsets) != len(self.codes) or any(
                not 0 <= o <= self.size - struct.calcsize(c) for o, c in zip(self.offsets, self.codes)):  # fmt: skip
            raise FleetError("internal: a message layout whose fields do not fit its template")

    @classmethod
    def of(cls, layout: Any) -> _Packer:
        """The packer of a :class:`~delayform.deploy._cdr.Layout` (rosbags' encoding, found once)."""
        fields = sorted(layout.dtype.fields.values(), key=lambda f: f[1])
        codes = ["<" + dt.str[1:].replace("f8", "d").replace("i4", "i").replace("u4", "I") for dt, _ in fields]
        return cls(bytes(layout.template), [off for _, off in fields], codes)

    def spec(self) -> dict[str, Any]:
        """Plain data (JSON) to build the same packer in another process without rosbags."""
        return {"template": self.template.hex(), "offsets": self.offsets, "codes": self.codes}

    def pack(self, values: tuple[float | int, ...]) -> bytes:
        buf = bytearray(self.template)
        for off, code, value in zip(self.offsets, self.codes, values):
            struct.pack_into(code, buf, off, value)
        return bytes(buf)

    def unpack(self, data: bytes) -> tuple[Any, ...]:
        if len(data) != self.size:
            raise FleetError(f"a message of {len(data)} bytes where {self.size} were expected")
        return tuple(struct.unpack_from(code, data, off)[0] for off, code in zip(self.offsets, self.codes))


class Codec:
    """The CDR encoder and decoder of a team's odometry and twists (module doc).

    Parameters
    ----------
    n
        Number of robots (each has its own odometry layout: its child frame's name is in the bytes).
    """

    def __init__(self, n: int) -> None:
        from rosbags.typesys import Stores, get_typestore

        from delayform.deploy.recording import odometry_layout, twist_layout

        store = get_typestore(Stores.ROS2_HUMBLE)
        self._odom = {i: _Packer.of(odometry_layout(store, i)) for i in range(1, n + 1)}
        self._twist = _Packer.of(twist_layout(store))

    def spec(self) -> dict[str, Any]:
        """The layouts as plain data (JSON): :meth:`from_spec` builds the same codec from them.

        The parent of a fleet run finds the layouts once, with rosbags' type store (its ROS 2
        message definitions take a seventh of a second to load); each robot's and the world's
        process rebuilds the codec from its spec and never imports rosbags.
        """
        return {"odometry": {str(i): p.spec() for i, p in self._odom.items()}, "twist": self._twist.spec()}

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> Codec:
        """The codec whose :meth:`spec` this is."""

        def packer(d: dict[str, Any]) -> _Packer:
            return _Packer(bytes.fromhex(d["template"]), d["offsets"], d["codes"])

        codec = cls.__new__(cls)
        codec._odom = {int(i): packer(d) for i, d in spec["odometry"].items()}
        codec._twist = packer(spec["twist"])
        return codec

    def odometry(self, robot: int, odom: Odometry) -> bytes:
        """The CDR bytes of robot ``robot``'s odometry."""
        sec = math.floor(odom.stamp)
        nanosec = min(int(round((odom.stamp - sec) * 1e9)), 999_999_999)
        half = 0.5 * odom.theta
        return self._odom[robot].pack((sec, nanosec, odom.x, odom.y, math.sin(half), math.cos(half),
                                       odom.v, 0.0, odom.omega))  # fmt: skip

    def read_odometry(self, robot: int, data: bytes) -> Odometry:
        """An odometry of robot ``robot`` back from its bytes."""
        sec, nanosec, x, y, qz, qw, v, _, omega = self._odom[robot].unpack(data)
        return Odometry(sec + nanosec * 1e-9, x, y, 2.0 * math.atan2(qz, qw), v, omega)

    def twist(self, speed: float, turn_rate: float) -> bytes:
        """The CDR bytes of a velocity command."""
        return self._twist.pack((speed, turn_rate))

    def read_twist(self, data: bytes) -> tuple[float, float]:
        """``(linear.x, angular.z)`` of a velocity command."""
        speed, turn = self._twist.unpack(data)
        return float(speed), float(turn)


def check_endpoint(endpoint: str) -> tuple[str, int]:
    """``tcp/HOST:PORT`` on the loopback, checked: the host and the port.

    Parameters
    ----------
    endpoint
        A Zenoh TCP endpoint on this machine (``tcp/127.0.0.1:7447``).

    Raises
    ------
    FleetError
        For another protocol, a host off the loopback, or a port out of range.
    """
    if not isinstance(endpoint, str):
        raise FleetError(f"the endpoint must be text such as {DEFAULT_ENDPOINT}, got {type(endpoint).__name__}")
    proto, sep, rest = endpoint.partition("/")
    host, colon, port_text = rest.rpartition(":")
    if not sep or proto != "tcp" or not colon or not host:
        raise FleetError(f"the endpoint must be tcp/HOST:PORT (e.g. {DEFAULT_ENDPOINT}), got {endpoint!r}")
    if host not in ("127.0.0.1", "localhost", "[::1]"):
        raise FleetError(f"the fleet runs on the loopback: the endpoint's host must be 127.0.0.1, localhost or [::1], got {host!r}")
    try:
        port = int(port_text)
    except ValueError:
        raise FleetError(f"the endpoint's port must be a number, got {port_text!r}") from None
    if not 1 <= port <= 65535:
        raise FleetError(f"the endpoint's port must be in 1..65535, got {port}")
    return host, port


def port_free(host: str, port: int) -> bool:
    """Whether a listener could bind ``host:port`` now (``host`` as in an endpoint: ``[::1]`` for IPv6)."""
    family = socket.AF_INET6 if host.startswith("[") else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        # as a listener binds: connections of an earlier run waiting out TIME_WAIT do not hold the port
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host.strip("[]"), port))
        except OSError:
            return False
    return True


def open_session(*, listen: list[str], connect: list[str]) -> Any:
    """A Zenoh session in peer mode on the loopback, without multicast scouting (no router needed).

    Parameters
    ----------
    listen
        Endpoints to listen on (the parent: the run's endpoint; a child: a free loopback port).
    connect
        Endpoints to connect to (a child: the run's endpoint); peers then find
        each other through it and connect directly.
    """
    import zenoh

    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("listen/endpoints", json.dumps(listen))
    config.insert_json5("connect/endpoints", json.dumps(connect))
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)
