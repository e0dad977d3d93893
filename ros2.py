"""ROS 2 without ROS: ``nav_msgs/msg/Odometry`` published over Zenoh as a ROS 2 node using
rmw_zenoh_cpp (>= 0.2.4, Jazzy) would, so that ``ros2 topic echo`` and every ROS 2 node see it
through the rmw_zenohd router.

- :func:`ros2_odometry` builds the message (with any rosbags typestore), serialized as CDR;
- :data:`ROS2_ATTACHMENT` is the attachment rmw_zenoh_cpp wants on every sample;
- :func:`ros2_topic_key` and :func:`ros2_liveliness_keys` are rmw_zenoh's key expressions of
  the topic and of the node's and publisher's liveliness tokens (what puts them in the graph);
- :class:`Ros2Odometry` declares them on a session and encodes each state
  (:class:`radarodom.publish.Publisher` uses it with ``--ros2``).
"""

from __future__ import annotations

import math
import os
import struct
import time
from typing import TYPE_CHECKING, Any

import numpy as np
import zenoh

from .errors import MessageError, PublishConfigError, quoted
from .messages import CHILD_FRAME_ID, ODOM_FRAME_ID
from .tum import yaw_quaternion

if TYPE_CHECKING:  # the estimator is not needed to publish what it made
    from .estimator.odometry import OdometryState

#: rmw_zenoh_cpp's per-sample attachment: sequence number (int64), source
#: timestamp (int64 ns), and the 16-byte publisher gid as a Zenoh-serialized
#: byte sequence (its length 16 as one LEB128 byte, then the bytes).  33 bytes.
ROS2_ATTACHMENT = struct.Struct("<qqB16s")
ROS2_GID_BYTES = 16
ROS2_ODOMETRY_TYPE = "nav_msgs/msg/Odometry"
#: Covariance given to what a planar odometry does not observe (z, roll, pitch).
ROS2_UNOBSERVED_VARIANCE = 1e6
#: Where (x, y, yaw) and (vx, vy, yaw_rate) sit in ROS's 6x6 covariances
#: (x, y, z, rotation about x, y, z).
_PLANAR_IN_6D = (0, 1, 5)
#: The node's name in the ROS graph.
ROS2_NODE_NAME = "radarodom"
#: rmw_zenoh's QoS of the publisher token: reliable, volatile, keep last 10
#: (only the depth differs from rmw_zenoh's defaults, so only it is written).
_ROS2_QOS = "::,10:,:,:,,"


def ros2_stamp(t: float) -> tuple[int, int]:
    """(sec, nanosec) of *t* seconds, nanosec in [0, 1e9)."""
    # Split first: t * 1e9 of a present-day time in float would lose ~100 ns.
    sec = math.floor(t)
    nanosec = round((t - sec) * 1e9)
    if nanosec == 1_000_000_000:
        return sec + 1, 0
    return sec, nanosec


def _covariance_6x6(cov3: Any) -> np.ndarray:
    """ROS's 6x6 covariance (row-major, 36) holding a planar 3x3 one; what a
    planar odometry cannot see gets :data:`ROS2_UNOBSERVED_VARIANCE`."""
    out = np.diag(np.full(6, ROS2_UNOBSERVED_VARIANCE))
    out[np.ix_(_PLANAR_IN_6D, _PLANAR_IN_6D)] = np.asarray(cov3, float)
    return out.ravel()


def ros2_odometry(state: OdometryState, typestore: Any) -> Any:
    """The ``nav_msgs/msg/Odometry`` of *state* as an instance of *typestore*'s
    (rosbags) class: stamp from ``t``, frames ``odom`` -> ``base_radar``, the
    planar pose and twist, and 6x6 covariances from the 3x3 ones."""
    if not all(math.isfinite(float(v)) for v in (state.t, state.x, state.y, state.yaw,
                                                 state.vx, state.vy, state.yaw_rate)):
        raise MessageError("ROS 2 odometry: cannot encode a non-finite value")
    types = typestore.types
    vector, point = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Point"]
    sec, nanosec = ros2_stamp(float(state.t))
    header = types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                          frame_id=ODOM_FRAME_ID)
    qx, qy, qz, qw = (float(v) for v in yaw_quaternion(float(state.yaw)))
    orientation = types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw)
    pose = types["geometry_msgs/msg/PoseWithCovariance"](
        pose=types["geometry_msgs/msg/Pose"](position=point(x=float(state.x), y=float(state.y), z=0.0),
                                             orientation=orientation),
        covariance=_covariance_6x6(state.pose_covariance))
    twist = types["geometry_msgs/msg/TwistWithCovariance"](
        twist=types["geometry_msgs/msg/Twist"](linear=vector(x=float(state.vx), y=float(state.vy), z=0.0),
                                               angular=vector(x=0.0, y=0.0, z=float(state.yaw_rate))),
        covariance=_covariance_6x6(state.twist_covariance))
    return types[ROS2_ODOMETRY_TYPE](header=header, child_frame_id=CHILD_FRAME_ID, pose=pose, twist=twist)


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
                         msg_type: str = ROS2_ODOMETRY_TYPE) -> tuple[str, str]:
    """rmw_zenoh's liveliness tokens of a node (in the root namespace, default
    enclave) and of its publisher of *topic*: what makes them part of the ROS
    graph (``ros2 node list``, ``ros2 topic list``)."""
    # /<admin>/<domain>/<zid>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node>: "/" is "%".
    node_key = f"@ros2_lv/{domain}/{zid}/0/0/NN/%/%/{node}"
    publisher_key = (f"@ros2_lv/{domain}/{zid}/0/10/MP/%/%/{node}/{topic.replace('/', '%')}/"
                     f"{_dds_type_name(msg_type)}/{type_hash}/{_ROS2_QOS}")
    return node_key, publisher_key


def ros2_typestore() -> Any:
    """rosbags' ROS 2 Jazzy typestore; a clear error when rosbags is missing."""
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise PublishConfigError('the ROS 2 output needs rosbags: pip install "radarodom[ros2]"') from None
    return get_typestore(Stores.ROS2_JAZZY)


class Ros2Odometry:
    """nav_msgs/msg/Odometry as a ROS 2 node using rmw_zenoh_cpp publishes it."""

    def __init__(self, session: zenoh.Session, options: Any, typestore: Any) -> None:
        self._store = typestore
        type_hash = typestore.hash_rihs01(ROS2_ODOMETRY_TYPE)
        self.key = ros2_topic_key(options.ros2_domain, options.ros2_topic, type_hash)
        self.publisher = session.declare_publisher(self.key, priority=zenoh.Priority.REAL_TIME,
                                                   congestion_control=zenoh.CongestionControl.DROP, express=True)
        # rmw_zenoh derives its gid from the token; any fixed 16 bytes per publisher serve.
        self._gid = os.urandom(ROS2_GID_BYTES)
        self._sequence = 0
        liveliness = session.liveliness()
        self._tokens = [liveliness.declare_token(k) for k in
                        ros2_liveliness_keys(options.ros2_domain, str(session.zid()), options.ros2_topic, type_hash)]

    def encode(self, state: OdometryState) -> tuple[bytes, bytes]:
        """(CDR payload, attachment) of the next sample."""
        msg = ros2_odometry(state, self._store)
        self._sequence += 1
        return (bytes(self._store.serialize_cdr(msg, ROS2_ODOMETRY_TYPE)),
                ros2_attachment(self._sequence, time.time_ns(), self._gid))
