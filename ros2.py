"""ROS 2 without ROS: radarodom's topics published over Zenoh as a ROS 2 node using
rmw_zenoh_cpp (>= 0.2.4, Jazzy) would, so that ``ros2 topic echo``, rviz2 and every ROS 2 node
see them through the rmw_zenohd router.

- :data:`ROS2_ATTACHMENT` is the attachment rmw_zenoh_cpp wants on every sample;
- :func:`ros2_topic_key` and :func:`ros2_liveliness_keys` are rmw_zenoh's key expressions of
  a topic and of the node's and a publisher's liveliness tokens (what puts them in the graph);
- :class:`Ros2Node` declares the node and its publishers on a session: ``nav_msgs/msg/Odometry``
  (``--ros2-topic``, default ``/radar/odom``), ``sensor_msgs/msg/PointCloud2`` on
  :data:`POINTS_TOPIC`, ``tf2_msgs/msg/TFMessage`` on ``/tf`` (odom -> base_link) and, transient
  local as tf2's static broadcaster, on ``/tf_static`` (base_link -> radar), the heatmap's
  ``sensor_msgs/msg/Image`` and axes, and ``diagnostic_msgs/msg/DiagnosticArray`` on
  ``/diagnostics``, and encodes each message (:class:`radarodom.publish.Publisher` uses it with
  ``--ros2``).  The same topics as the bag (:mod:`radarodom.pipeline.mcap_sink`) but the ground
  truth.

The messages themselves: :mod:`radarodom.ros2_messages`; the frames: :mod:`radarodom.ros2_frames`.
"""

from __future__ import annotations

import os
import struct
import time
from typing import TYPE_CHECKING, Any

import zenoh
import zenoh.ext

from . import ros2_messages
from .errors import MessageError, PublishConfigError, quoted
from .mount import Mount

if TYPE_CHECKING:  # the estimator is not needed to publish what it made
    from .estimator.odometry import OdometryState

#: rmw_zenoh_cpp's per-sample attachment: sequence number (int64), source
#: timestamp (int64 ns), and the 16-byte publisher gid as a Zenoh-serialized
#: byte sequence (its length 16 as one LEB128 byte, then the bytes).  33 bytes.
ROS2_ATTACHMENT = struct.Struct("<qqB16s")
ROS2_GID_BYTES = 16
ROS2_ODOMETRY_TYPE = ros2_messages.ODOMETRY
ROS2_UNOBSERVED_VARIANCE = ros2_messages.UNOBSERVED_VARIANCE
#: The node's name in the ROS graph.
ROS2_NODE_NAME = "radarodom"
POINTS_TOPIC = "/radar/points"
TF_TOPIC = "/tf"
TF_STATIC_TOPIC = "/tf_static"
HEATMAP_TOPIC = "/radar/heatmap"
HEATMAP_AXES_TOPIC = "/radar/heatmap/axes"
DIAGNOSTICS_TOPIC = "/diagnostics"
#: The ground truth's topic in an MCAP bag (``radar-capture --mcap``; not published).
GROUNDTRUTH_TOPIC = "/radar/groundtruth"
#: Every topic radarodom writes but the odometry's, whose name the user chooses (``--ros2-topic``).
OTHER_TOPICS = (POINTS_TOPIC, TF_TOPIC, TF_STATIC_TOPIC, HEATMAP_TOPIC, HEATMAP_AXES_TOPIC, DIAGNOSTICS_TOPIC,
                GROUNDTRUTH_TOPIC)
#: The topics every ROS 2 node has, with their messages' type: no odometry's to take.
ROS2_SYSTEM_TOPICS = {"/rosout": "rcl_interfaces/msg/Log", "/parameter_events": "rcl_interfaces/msg/ParameterEvent"}

#: rmw_zenoh's QoS of a publisher token: reliable, volatile, keep last 10 (only the depth differs
#: from rmw_zenoh's defaults, so only it is written) ...
_ROS2_QOS = "::,10:,:,:,,"
#: ... and of /tf_static, as tf2's static broadcaster: transient local (1), keep last 1.
_ROS2_QOS_STATIC = ":1:,1:,:,:,,"
#: rmw_zenoh's heartbeat of a reliable transient-local publisher (s): lets a subscriber that
#: missed the last sample fetch it from the publisher's cache.
_STATIC_HEARTBEAT_S = 0.5

ros2_stamp = ros2_messages.stamp


def check_odometry_topic(topic: str) -> str:
    """*topic* if it is neither one of radarodom's other topics nor one of ROS 2's own
    (PublishConfigError otherwise): the odometry on /tf would be TF messages of another type, on
    /rosout Odometry where every ROS 2 tool reads log messages."""
    if topic in OTHER_TOPICS:
        raise PublishConfigError(f"{topic} is one of radarodom's other topics ({', '.join(OTHER_TOPICS)}): "
                                 "give the odometry its own")
    if topic in ROS2_SYSTEM_TOPICS:
        raise PublishConfigError(f"{topic} is ROS 2's own topic ({ROS2_SYSTEM_TOPICS[topic]}, which every ROS 2 "
                                 "node and tool uses): give the odometry its own")
    return topic


def ros2_odometry(state: OdometryState, typestore: Any, mount: Mount = Mount()) -> Any:
    """The ``nav_msgs/msg/Odometry`` of *state* as an instance of *typestore*'s (rosbags) class:
    odom -> base_link (:func:`radarodom.ros2_messages.odometry`)."""
    return ros2_messages.odometry(state, typestore.types, mount)


def ros2_attachment(sequence: int, timestamp_ns: int, gid: bytes) -> bytes:
    """rmw_zenoh_cpp's attachment of one sample (see :data:`ROS2_ATTACHMENT`)."""
    if not isinstance(gid, bytes) or len(gid) != ROS2_GID_BYTES:
        raise MessageError(f"ROS 2 gid must be {ROS2_GID_BYTES} bytes, got {quoted(gid, 60)}")
    try:
        return ROS2_ATTACHMENT.pack(sequence, timestamp_ns, ROS2_GID_BYTES, gid)
    except struct.error as exc:  # a sequence or time beyond int64
        raise MessageError(f"ROS 2 attachment: {exc}") from None


def ros2_topic_key(domain: int, topic: str, type_hash: str, msg_type: str = ROS2_ODOMETRY_TYPE) -> str:
    """rmw_zenoh's key expression of a topic: ``<domain>/<topic>/<DDS type>/<RIHS01 hash>``."""
    return f"{domain}/{topic.strip('/')}/{_dds_type_name(msg_type)}/{type_hash}"


def _dds_type_name(msg_type: str) -> str:
    package, kind, name = msg_type.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def ros2_liveliness_keys(domain: int, zid: str, topic: str, type_hash: str, node: str = ROS2_NODE_NAME,
                         msg_type: str = ROS2_ODOMETRY_TYPE, *, entity: int = 10,
                         qos: str = _ROS2_QOS) -> tuple[str, str]:
    """rmw_zenoh's liveliness tokens of a node (in the root namespace, default
    enclave) and of its publisher (entity id *entity*) of *topic*: what makes them part of the
    ROS graph (``ros2 node list``, ``ros2 topic list``)."""
    # /<admin>/<domain>/<zid>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node>: "/" is "%".
    node_key = f"@ros2_lv/{domain}/{zid}/0/0/NN/%/%/{node}"
    publisher_key = (f"@ros2_lv/{domain}/{zid}/0/{entity}/MP/%/%/{node}/{topic.replace('/', '%')}/"
                     f"{_dds_type_name(msg_type)}/{type_hash}/{qos}")
    return node_key, publisher_key


def ros2_typestore() -> Any:
    """rosbags' ROS 2 Jazzy typestore; a clear error when rosbags is missing."""
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise PublishConfigError('the ROS 2 output needs rosbags: pip install "radarodom[ros2]"') from None
    return get_typestore(Stores.ROS2_JAZZY)


class Ros2Topic:
    """One publisher of a ROS 2 node using rmw_zenoh_cpp: its key, its liveliness token, its gid
    and sequence numbers.  *transient_local*: late subscribers get the last sample (rmw_zenoh's
    AdvancedPublisher with a cache of one and publisher detection, as for ``/tf_static``)."""

    def __init__(self, session: zenoh.Session, domain: int, topic: str, msg_type: str, entity: int,
                 typestore: Any, *, transient_local: bool = False, urgent: bool = False) -> None:
        self._store = typestore
        self.topic, self.msg_type = topic, msg_type
        type_hash = typestore.hash_rihs01(msg_type)
        typestore.get_msgdef(msg_type)  # its serializer made now, not in the first frame's time
        self.key = ros2_topic_key(domain, topic, type_hash, msg_type)
        if transient_local:
            self.publisher = zenoh.ext.declare_advanced_publisher(
                session, self.key, congestion_control=zenoh.CongestionControl.DROP,
                cache=zenoh.ext.CacheConfig(1), publisher_detection=True,
                sample_miss_detection=zenoh.ext.MissDetectionConfig(heartbeat=None,
                                                                    sporadic_heartbeat=_STATIC_HEARTBEAT_S))
        elif urgent:  # the odometry, as the plain Zenoh one
            self.publisher = session.declare_publisher(self.key, priority=zenoh.Priority.REAL_TIME,
                                                       congestion_control=zenoh.CongestionControl.DROP,
                                                       express=True)
        else:  # batched, at rmw_zenoh's (and Zenoh's) default priority, whose queue is the deepest
            self.publisher = session.declare_publisher(self.key, priority=zenoh.Priority.DATA,
                                                       congestion_control=zenoh.CongestionControl.DROP)
        # rmw_zenoh derives its gid from the token; any fixed 16 bytes per publisher serve.
        self._gid = os.urandom(ROS2_GID_BYTES)
        self._sequence = 0
        _, token = ros2_liveliness_keys(domain, str(session.zid()), topic, type_hash, msg_type=msg_type,
                                        entity=entity, qos=_ROS2_QOS_STATIC if transient_local else _ROS2_QOS)
        self._token = session.liveliness().declare_token(token)

    def encode(self, msg: Any) -> tuple[bytes, bytes]:
        """(CDR payload, attachment) of the next sample."""
        self._sequence += 1
        return (bytes(self._store.serialize_cdr(msg, self.msg_type)),
                ros2_attachment(self._sequence, time.time_ns(), self._gid))


class Ros2Node:
    """The node ``radarodom`` and its publishers (module docstring), keyed by the
    :class:`radarodom.publish.Publisher`'s kinds: ``ros2`` (odometry), ``ros2_points``,
    ``ros2_tf``, ``ros2_tf_static``.  *mount* places the radar on the base (base_link -> radar)."""

    def __init__(self, session: zenoh.Session, options: Any, typestore: Any, mount: Mount = Mount()) -> None:
        self.types = typestore.types
        self.mount = mount
        domain = options.ros2_domain
        self.topics = {
            "ros2": Ros2Topic(session, domain, options.ros2_topic, ros2_messages.ODOMETRY, 10, typestore,
                              urgent=True),
            "ros2_points": Ros2Topic(session, domain, POINTS_TOPIC, ros2_messages.POINTCLOUD2, 11, typestore),
            "ros2_tf": Ros2Topic(session, domain, TF_TOPIC, ros2_messages.TF, 12, typestore),
            "ros2_tf_static": Ros2Topic(session, domain, TF_STATIC_TOPIC, ros2_messages.TF, 13, typestore,
                                        transient_local=True),
            "ros2_heatmap": Ros2Topic(session, domain, HEATMAP_TOPIC, ros2_messages.IMAGE, 14, typestore),
            "ros2_heatmap_axes": Ros2Topic(session, domain, HEATMAP_AXES_TOPIC, ros2_messages.AXES, 15, typestore),
            "ros2_diagnostics": Ros2Topic(session, domain, DIAGNOSTICS_TOPIC, ros2_messages.DIAGNOSTICS, 16,
                                          typestore),
        }
        node_key, _ = ros2_liveliness_keys(domain, str(session.zid()), options.ros2_topic, "")
        self._node_token = session.liveliness().declare_token(node_key)
        self.static_sent = False
        self._t = 0.0  # the latest frame's time: a status message's stamp
        self._losses: dict[str, int] = {}

    @property
    def key(self) -> str:
        """The odometry's key."""
        return self.topics["ros2"].key

    def odometry(self, state: OdometryState) -> list[tuple[str, bytes, bytes]]:
        """(kind, payload, attachment) of the odometry, its odom -> base_link transform and its
        diagnostics, and of base_link -> radar before the first message."""
        t = float(state.t)
        odometry, tf = ros2_messages.odometry_and_tf(state, self.types, self.mount)
        diagnostics = ros2_messages.diagnostics(t, [ros2_messages.odometry_status(state)], self.types)
        return self._encode(t, [("ros2", odometry), ("ros2_tf", tf), ("ros2_diagnostics", diagnostics)])

    def pointcloud(self, t: float, points: Any) -> list[tuple[str, bytes, bytes]]:
        return self._encode(t, [("ros2_points", ros2_messages.pointcloud2(t, points, self.types))])

    def heatmap(self, t: float, heatmap: Any) -> list[tuple[str, bytes, bytes]]:
        return self._encode(t, [("ros2_heatmap", ros2_messages.heatmap_image(t, heatmap, self.types)),
                                ("ros2_heatmap_axes", ros2_messages.heatmap_axes(heatmap, self.types))])

    def status(self, info: Any) -> list[tuple[str, bytes, bytes]]:
        """The pipeline's status message as diagnostics, stamped with the latest frame's time."""
        entry, self._losses = ros2_messages.pipeline_status(info, self._losses)
        return self._encode(self._t, [("ros2_diagnostics", ros2_messages.diagnostics(self._t, [entry], self.types))])

    def _encode(self, t: float, msgs: list[tuple[str, Any]]) -> list[tuple[str, bytes, bytes]]:
        self._t = t
        out = [] if self.static_sent else [self._static(t)]
        out += [(kind, *self.topics[kind].encode(msg)) for kind, msg in msgs]
        return out

    def _static(self, t: float) -> tuple[str, bytes, bytes]:
        self.static_sent = True
        return ("ros2_tf_static", *self.topics["ros2_tf_static"].encode(ros2_messages.tf_mount(t, self.types,
                                                                                               self.mount)))
