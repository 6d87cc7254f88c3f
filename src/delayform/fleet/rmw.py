"""The fleet's topics as rmw_zenoh publishes them, so that a ROS 2 node on rmw_zenoh hears the run (``--ros-domain``).

With a ROS domain every process of a fleet run also publishes its messages
the way ``rmw_zenoh_cpp`` (ROS 2 Jazzy) does, beside the plain keys the
fleet itself uses (:mod:`delayform.fleet.wire`); the payloads are the same
CDR bytes. Three things make a sample something a ROS 2 node takes
(rmw_zenoh's ``docs/design.md``, jazzy):

Key expression
    ``<domain>/<topic without its leading slash>/<DDS type name>/<type hash>``,
    e.g. ``0/robot_1/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc9...``
    (:func:`data_key`). The type hash is REP-2011's RIHS01 hash of the
    message's type description, kept here as constants (:data:`TYPES`;
    ``tests/test_fleet_rmw.py`` checks them against rosbags' Jazzy type store
    and against published values).
Attachment
    Every sample carries what ``AttachmentData::serialize_to_zbytes`` writes
    with ``zenoh::ext::Serializer``: the publisher's sequence number (int64),
    the source timestamp (int64, ns since 1970) and the publisher's 16-byte
    GID as a sequence (a LEB128 length, 16, then the bytes): 33 bytes
    (:func:`attachment`). rmw_zenoh drops a sample without one. rmw_zenoh
    makes the GID from a hash of the publisher's liveliness token; so does
    this module (BLAKE2b, not rmw_zenoh's XXH3: the GID only has to be unique
    and stable for the publisher).
Liveliness tokens
    The graph (``ros2 node list``, ``ros2 topic list``, the type that
    ``ros2 topic echo`` looks up) is built from tokens under ``@ros2_lv``:
    one per node (:func:`node_token`) and one per publisher
    (:func:`publisher_token`) with its topic, type, hash and QoS. Names are
    mangled with ``/`` -> ``%``; the enclave and the namespace are ``/``
    (``%``). The QoS chunk writes only what differs from rmw_zenoh's defaults
    (reliable, volatile, keep-last 42, no deadline, lifespan or lease): the
    fleet's publishers are reliable, volatile, keep-last 10, :data:`QOS`.

Each process is one node (:class:`RosNode`): ``delayform_robot_<i>``
publishes ``/robot_<i>/state`` and ``/robot_<i>/cmd_vel``, ``delayform_world``
publishes every ``/robot_<i>/odom``. The fleet's own subscriptions stay on the
plain keys, so no subscriber tokens are declared: a ROS 2 publisher on these
topics would not reach the robots.

Only the standard library is imported here: the robot and world processes
import this module before their loop.
"""

from __future__ import annotations

import hashlib
import struct
import time
from typing import Any

from delayform.errors import FleetError

__all__ = ["DOMAIN_MAX", "TYPES", "TOPIC_TYPES", "QOS", "check_domain", "mangle", "data_key", "node_token",
           "publisher_token", "attachment", "RosNode", "RosPublisher", "robot_node", "WORLD_NODE"]  # fmt: skip

#: the largest ROS_DOMAIN_ID ROS 2 allows
DOMAIN_MAX = 232

#: ROS 2 type -> (its DDS type name, its REP-2011 RIHS01 hash on Jazzy)
TYPES = {
    "nav_msgs/msg/Odometry": ("nav_msgs::msg::dds_::Odometry_",
                              "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0"),
    "geometry_msgs/msg/Twist": ("geometry_msgs::msg::dds_::Twist_",
                                "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a"),
}  # fmt: skip

#: the fleet's topics (last part of the name) -> their ROS 2 type
TOPIC_TYPES = {"odom": "nav_msgs/msg/Odometry", "state": "nav_msgs/msg/Odometry", "cmd_vel": "geometry_msgs/msg/Twist"}

#: the QoS chunk of a publisher's token: reliable, volatile, keep-last 10 (only the depth differs from the defaults)
QOS = "::,10:,:,:,,"

#: the node name of the world process
WORLD_NODE = "delayform_world"

_GID_SIZE = 16
_ATTACHMENT = struct.Struct("<qqB")


def robot_node(robot: int) -> str:
    """``delayform_robot_<i>``: the node name of robot i's process."""
    return f"delayform_robot_{robot}"


def check_domain(domain: Any) -> int:
    """A ROS domain id, checked: a whole number in 0..:data:`DOMAIN_MAX` (ROS_DOMAIN_ID's range).

    Raises
    ------
    FleetError
        For anything else.
    """
    if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= DOMAIN_MAX:
        raise FleetError(f"the ROS domain must be a whole number in 0..{DOMAIN_MAX}, got {domain!r}")
    return domain


def mangle(name: str) -> str:
    """A name inside a liveliness token: every ``/`` as ``%`` (the root ``/`` is ``%``).

    >>> mangle("/robot_1/odom"), mangle("/")
    ('%robot_1%odom', '%')
    """
    return name.replace("/", "%")


def _type(msgtype: str) -> tuple[str, str]:
    try:
        return TYPES[msgtype]
    except KeyError:
        raise FleetError(f"no rmw_zenoh type name for {msgtype!r}; known: {', '.join(TYPES)}") from None


def data_key(domain: int, topic: str, msgtype: str) -> str:
    """The key expression rmw_zenoh publishes topic ``topic`` of type ``msgtype`` on (module doc).

    Parameters
    ----------
    domain
        The ROS domain id.
    topic
        The ROS 2 topic name (``/robot_1/odom``; the leading slash is optional).
    msgtype
        Its ROS 2 type, one of :data:`TYPES` (``nav_msgs/msg/Odometry``).

    >>> data_key(0, "/robot_1/cmd_vel", "geometry_msgs/msg/Twist")[:51]
    '0/robot_1/cmd_vel/geometry_msgs::msg::dds_::Twist_/'
    """
    dds, rihs = _type(msgtype)
    return f"{domain}/{topic.strip('/')}/{dds}/{rihs}"


def node_token(domain: int, zid: str, node_id: int, name: str) -> str:
    """The liveliness token of a node in the root namespace and enclave.

    ``@ros2_lv/<domain>/<zid>/<nid>/<nid>/NN/<enclave>/<namespace>/<name>``.

    Parameters
    ----------
    domain
        The ROS domain id.
    zid
        The Zenoh session's id as text (``str(session.info.zid())``).
    node_id
        The node's id within its session (0 for the first).
    name
        The node's name.
    """
    return f"@ros2_lv/{domain}/{zid}/{node_id}/{node_id}/NN/%/%/{mangle(name)}"


def publisher_token(domain: int, zid: str, node_id: int, entity_id: int, node: str, topic: str, msgtype: str,
                    qos: str = QOS) -> str:  # fmt: skip
    """The liveliness token of a publisher of node ``node`` (module doc).

    ``@ros2_lv/<domain>/<zid>/<nid>/<eid>/MP/<enclave>/<namespace>/<node>/<topic>/<type>/<hash>/<qos>``.

    Parameters
    ----------
    domain, zid, node_id
        As for :func:`node_token`.
    entity_id
        The publisher's id within its session (after the node's).
    node
        The name of the node it belongs to.
    topic, msgtype
        As for :func:`data_key`.
    qos
        The QoS chunk (:data:`QOS`).
    """
    dds, rihs = _type(msgtype)
    name = "/" + topic.strip("/")
    return f"@ros2_lv/{domain}/{zid}/{node_id}/{entity_id}/MP/%/%/{mangle(node)}/{mangle(name)}/{dds}/{rihs}/{qos}"


def attachment(sequence: int, stamp_ns: int, gid: bytes) -> bytes:
    """The 33 bytes rmw_zenoh attaches to a sample: sequence number, source timestamp (ns), GID (module doc).

    Parameters
    ----------
    sequence
        The publisher's count of its samples, from 1.
    stamp_ns
        When it was published (ns since 1970).
    gid
        The publisher's 16-byte GID.

    >>> len(attachment(1, 0, bytes(16)))
    33
    """
    if len(gid) != _GID_SIZE:
        raise FleetError(f"a publisher's GID has {_GID_SIZE} bytes, got {len(gid)}")
    return _ATTACHMENT.pack(sequence, stamp_ns, _GID_SIZE) + gid


class RosPublisher:
    """A Zenoh publisher on an rmw_zenoh key: each :meth:`put` numbers, stamps and attaches (module doc).

    Parameters
    ----------
    session
        The process's Zenoh session.
    key
        Its key expression (:func:`data_key`).
    token
        Its liveliness token (:func:`publisher_token`), declared here and held while the publisher lives.
    """

    def __init__(self, session: Any, key: str, token: str) -> None:
        self.key, self.token = key, token
        self.gid = hashlib.blake2b(token.encode(), digest_size=_GID_SIZE).digest()
        self.sequence = 0
        self._pub = session.declare_publisher(key)
        self._token = session.liveliness().declare_token(token)

    def put(self, payload: bytes) -> None:
        """Publish a CDR payload with the next sequence number and the wall clock's time."""
        self.sequence += 1
        self._pub.put(payload, attachment=attachment(self.sequence, time.time_ns(), self.gid))


class RosNode:
    """One process as an rmw_zenoh node: its token, then a token per publisher (entity ids from 1).

    Parameters
    ----------
    session
        The process's Zenoh session.
    domain
        The ROS domain id (:func:`check_domain`).
    name
        The node's name (:func:`robot_node`, :data:`WORLD_NODE`).
    """

    def __init__(self, session: Any, domain: int, name: str) -> None:
        self.session, self.domain, self.name = session, check_domain(domain), name
        self.zid = str(session.info.zid())
        self.token = node_token(domain, self.zid, 0, name)
        self._token = session.liveliness().declare_token(self.token)
        self._entities = 0

    def publisher(self, topic: str) -> RosPublisher:
        """A publisher of one of the fleet's topics (``/robot_<i>/<odom|state|cmd_vel>``, :data:`TOPIC_TYPES`)."""
        msgtype = TOPIC_TYPES.get(topic.rpartition("/")[2])
        if msgtype is None:
            raise FleetError(f"{topic!r} is not one of the fleet's topics ({', '.join(TOPIC_TYPES)})")
        self._entities += 1
        token = publisher_token(self.domain, self.zid, 0, self._entities, self.name, topic, msgtype)
        return RosPublisher(self.session, data_key(self.domain, topic, msgtype), token)
