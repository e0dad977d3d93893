"""Publishing odometry, point clouds, heatmaps and status over Zenoh (eclipse-zenoh 1.x).

    with Publisher(ZenohOptions()) as pub:      # the default: one machine, no router, no network
        pub.odometry(state)                     # <prefix>/odom, JSON, real-time priority, express
        pub.pointcloud(frame, t, points)        # <prefix>/pointcloud, binary, low priority
        pub.heatmap(frame, t, range_azimuth)    # <prefix>/heatmap, binary, low priority
        pub.status({"rate_hz": 10.0})           # <prefix>/status, JSON

The message formats are in :mod:`radarodom.messages`.  Every put drops rather
than waits when the network is congested, so publishing never holds up the
caller.  ``<prefix>/odom`` is also a queryable that answers a ``get`` with the
latest odometry (for late joiners), and ``<prefix>/alive`` a liveliness token
that exists while the publisher runs.

Sessions (defaults, the fallback when the default port is taken, config files):
:mod:`radarodom.zenoh_session`.

A session that is not closed keeps the interpreter from exiting (its callback
threads are not daemons: zenoh-python #434), so :class:`Publisher` is a
context manager and its :meth:`Publisher.close` always closes the session.

ROS 2 (``ros2=True``): ``nav_msgs/msg/Odometry``, ``sensor_msgs/msg/PointCloud2``, the TF
tree (``/tf``: odom -> base_link; ``/tf_static``: base_link -> radar, the *mount*), the heatmap
as ``sensor_msgs/msg/Image`` and the status and quality flags as ``/diagnostics`` in CDR
(rosbags' Jazzy typestore) on the key expressions rmw_zenoh_cpp uses, with the attachment and
the liveliness tokens it requires (rmw_zenoh_cpp >= 0.2.4 on Jazzy), so a ROS 2 node using
rmw_zenoh receives them (:mod:`radarodom.ros2`).  Without ``connect`` it also connects to the
ROS 2 router, :data:`ROS2_ROUTER_ENDPOINT`.
"""

from __future__ import annotations

import logging
import weakref
from typing import TYPE_CHECKING, Any, Mapping

import zenoh

from . import messages, strict_json
from .errors import PublishError
from .mount import Mount
from .products import RangeAzimuth
from .ros2 import Ros2Node, check_odometry_topic, ros2_typestore
# The session's options and opening live in zenoh_session; every name stays importable from
# here, as before the split.
from .zenoh_session import (  # noqa: F401
    CONNECT_RETRY, DEFAULT_ENDPOINT, DEFAULT_KEY_PREFIX, DEFAULT_ROS2_TOPIC, HANDSHAKE_TIMEOUT_MS, MODES,
    ROS2_ROUTER_ENDPOINT, ZenohOptions, _close_session, open_session, zenoh_reason)

if TYPE_CHECKING:  # the estimator is not needed to publish what it made
    import numpy as np

    from .estimator.odometry import OdometryState

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

#: The published keys under the prefix.
KINDS = ("odom", "pointcloud", "heatmap", "status")
#: The ROS 2 publishers (:class:`radarodom.ros2.Ros2Node`).
ROS2_KINDS = ("ros2", "ros2_points", "ros2_tf", "ros2_tf_static", "ros2_heatmap", "ros2_heatmap_axes",
              "ros2_diagnostics")
ALIVE = "alive"


class _LatestReply:
    """A queryable's handler: answers every query with the latest payload (none
    before the first).  Holds no reference to the Publisher, so that a
    publisher dropped unclosed can still be collected (and its session closed)."""

    def __init__(self, key: str, encoding: str) -> None:
        self.key = key
        self.encoding = zenoh.Encoding(encoding)
        self.payload: bytes | None = None

    def __call__(self, query: zenoh.Query) -> None:
        # Runs on a zenoh thread: never raise into it.
        payload = self.payload
        if payload is None:
            return
        try:
            query.reply(self.key, payload, encoding=self.encoding)
        except zenoh.ZError as exc:
            log.debug("could not answer a query on %s: %s", self.key, zenoh_reason(exc))


class Publisher:
    """radarodom's Zenoh publisher: odometry, point clouds, heatmaps, status.

    Opens the session at once (raising :class:`PublishConfigError` or
    :class:`PublishError`); close it with :meth:`close` or a ``with`` block.
    Methods may be called from any one thread at a time.
    """

    def __init__(self, options: ZenohOptions | None = None, *, mount: Mount = Mount()) -> None:
        options = options or ZenohOptions()
        #: Where the radar sits on the robot: the ROS 2 output's base_link -> radar.
        self.mount = mount
        # rosbags is checked before anything opens: a missing extra is an option error.
        if options.ros2:
            check_odometry_topic(options.ros2_topic)
        typestore = ros2_typestore() if options.ros2 else None
        self._session, self.options = open_session(options)
        # Closes the session once: on close(), or when the publisher is collected unclosed.
        self._close_session = weakref.finalize(self, _close_session, self._session)
        self.keys = {kind: self.options.key(kind) for kind in KINDS}
        self._latest = _LatestReply(self.keys["odom"], messages.JSON_ENCODING)
        #: Messages put per kind (``ros2``: the ROS 2 odometry; ``ros2_points``, ``ros2_tf``, ...:
        #: the other ROS 2 topics, :data:`ROS2_KINDS`).
        self.counts = dict.fromkeys(KINDS + (ROS2_KINDS if options.ros2 else ()), 0)
        try:
            self._declare(typestore)
        except BaseException:
            self.close()
            raise
        log.info("publishing on %s/{%s} (%s)", self.options.key_prefix, ",".join(KINDS), self.options.describe())

    def _declare(self, typestore: Any) -> None:
        session, keys = self._session, self.keys
        drop = zenoh.CongestionControl.DROP
        json_encoding = zenoh.Encoding(messages.JSON_ENCODING)
        try:
            self._publishers = {
                "odom": session.declare_publisher(keys["odom"], encoding=json_encoding,
                                                  priority=zenoh.Priority.REAL_TIME, congestion_control=drop,
                                                  express=True),
                "pointcloud": session.declare_publisher(keys["pointcloud"],
                                                        encoding=zenoh.Encoding(messages.POINTCLOUD_ENCODING),
                                                        priority=zenoh.Priority.DATA_LOW, congestion_control=drop),
                "heatmap": session.declare_publisher(keys["heatmap"],
                                                     encoding=zenoh.Encoding(messages.HEATMAP_ENCODING),
                                                     priority=zenoh.Priority.DATA_LOW, congestion_control=drop),
                "status": session.declare_publisher(keys["status"], encoding=json_encoding,
                                                    priority=zenoh.Priority.DATA, congestion_control=drop),
            }
            self._queryable = session.declare_queryable(keys["odom"], self._latest)
            self._alive = session.liveliness().declare_token(self.options.key(ALIVE))
            self._ros2 = None if typestore is None else Ros2Node(session, self.options, typestore, self.mount)
            if self._ros2 is not None:
                self._publishers.update({kind: topic.publisher for kind, topic in self._ros2.topics.items()})
        except zenoh.ZError as exc:
            raise PublishError(f"cannot declare the publishers under {self.options.key_prefix}: "
                               f"{zenoh_reason(exc)}") from None

    @property
    def zid(self) -> str:
        """The session's Zenoh id."""
        return str(self._session.zid())

    @property
    def ros2_key(self) -> str | None:
        """The rmw_zenoh key the ROS 2 odometry goes to, or None."""
        return None if self._ros2 is None else self._ros2.key

    @property
    def ros2_keys(self) -> dict[str, str]:
        """The rmw_zenoh key of each ROS 2 publisher, by kind (empty without ROS 2)."""
        return {} if self._ros2 is None else {kind: t.key for kind, t in self._ros2.topics.items()}

    @property
    def closed(self) -> bool:
        return not self._close_session.alive

    def _put(self, kind: str, payload: bytes, attachment: bytes | None = None) -> None:
        if self.closed:
            raise PublishError("the publisher is closed")
        try:
            self._publishers[kind].put(payload, attachment=attachment)
        except zenoh.ZError as exc:
            raise PublishError(f"publishing {kind}: {zenoh_reason(exc)}") from None
        self.counts[kind] += 1

    def odometry(self, state: OdometryState) -> None:
        """Publish an :class:`~radarodom.estimator.odometry.OdometryState` (and
        keep it for queries; and on ROS 2 when enabled)."""
        payload = messages.odometry_json(state)
        self._put("odom", payload)
        self._latest.payload = payload
        if self._ros2 is not None:
            self._put_ros2(self._ros2.odometry(state))

    def pointcloud(self, frame: int, t: float, points: np.ndarray) -> None:
        """Publish one frame's point cloud (POINT_DTYPE or any array with the wire fields; for
        ROS 2, POINT_DTYPE's)."""
        self._put("pointcloud", messages.encode_pointcloud(frame, t, points))
        if self._ros2 is not None:
            self._put_ros2(self._ros2.pointcloud(t, points))

    def heatmap(self, frame: int, t: float, heatmap: RangeAzimuth) -> None:
        """Publish one frame's range-azimuth heatmap (a RangeAzimuth)."""
        self._put("heatmap", messages.encode_heatmap(frame, t, heatmap))
        if self._ros2 is not None:
            self._put_ros2(self._ros2.heatmap(t, heatmap))

    def status(self, info: Mapping[str, Any]) -> None:
        """Publish a status message: *info* with the schema's ``schema`` and ``version``.
        A NaN or infinite value in *info* (a figure not known yet, such as the latency before
        the first frame) goes out as ``null``, and numpy values as plain numbers and lists: a
        status is never lost for one unknown figure."""
        self._put("status", messages.status_json(strict_json.finite(info)))
        if self._ros2 is not None:
            self._put_ros2(self._ros2.status(info))

    def _put_ros2(self, samples: list[tuple[str, bytes, bytes]]) -> None:
        for kind, payload, attachment in samples:
            self._put(kind, payload, attachment)

    def close(self) -> None:
        """Close the session (undeclaring everything); safe to call twice."""
        self._close_session()

    def __enter__(self) -> Publisher:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
