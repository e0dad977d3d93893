"""The pipeline's results as a ROS 2 bag in one MCAP file (``radar-capture --mcap FILE``).

Topics (docs/ros2.md has every field):

- ``/radar/odom`` (or the ROS 2 output's ``--ros2-topic``): ``nav_msgs/msg/Odometry``,
  odom -> base_link, with covariances;
- ``/tf``: ``tf2_msgs/msg/TFMessage``, odom -> base_link; ``/tf_static``: base_link -> radar
  (the mount), once, at the first frame;
- ``/radar/points``: ``sensor_msgs/msg/PointCloud2`` in ``radar``;
- ``/radar/heatmap``: ``sensor_msgs/msg/Image`` 32FC1 (dB) and ``/radar/heatmap/axes``:
  ``std_msgs/msg/Float32MultiArray``, its rows' ranges and columns' bearings;
- ``/diagnostics``: ``diagnostic_msgs/msg/DiagnosticArray``: the odometry's quality flags with
  every state (``radarodom: odometry``) and the pipeline's status (the Zenoh status message's
  figures, ``radarodom: pipeline``) every second of stream time and at the end;
- ``/radar/groundtruth``: ``geometry_msgs/msg/PoseStamped``, where the source knows the truth:
  base_link's true pose in odom (from the first frame with both an odometry state and a pose).

Every message's log time and stamp is its frame's timestamp, so a bag of a replay is the same
whatever the replay's rate.
"""

from __future__ import annotations

import os
from typing import Any

from .. import ros2_messages as rm
from ..driver.sources import Source
from ..mount import Mount
from ..publish import DEFAULT_ROS2_TOPIC
from ..ros2 import (DIAGNOSTICS_TOPIC, GROUNDTRUTH_TOPIC, HEATMAP_AXES_TOPIC, HEATMAP_TOPIC, POINTS_TOPIC,
                    TF_STATIC_TOPIC, TF_TOPIC, check_odometry_topic, ros2_typestore)
from ..ros2_bag import QOS_STATIC, BagWriter
from ..ros2_frames import TruthInOdom
from .sinks import FrameResult, Sink, remove_if_no_frame
from .stats import PipelineStats
from .zenoh_sink import status


class McapSink(Sink):
    """Writes the topics above to a new MCAP file at *path* (:class:`radarodom.ros2_bag.BagWriter`).
    *mount*: where the radar sits on the robot (base_link -> radar)."""

    wants_heatmaps = True

    def __init__(self, path: str | os.PathLike, source: Source, *, mount: Mount = Mount(),
                 odom_topic: str = DEFAULT_ROS2_TOPIC, status_period_s: float = 1.0, typestore: Any = None) -> None:
        check_odometry_topic(odom_topic)
        store = typestore if typestore is not None else ros2_typestore()
        self.types = store.types
        self.source = source
        self.mount = mount
        self.odom_topic = odom_topic
        self.period = status_period_s
        self.path = os.fspath(path)
        self.bag = BagWriter(path, store)
        for topic, msg_type in ((odom_topic, rm.ODOMETRY), (TF_TOPIC, rm.TF), (POINTS_TOPIC, rm.POINTCLOUD2),
                                (HEATMAP_TOPIC, rm.IMAGE), (HEATMAP_AXES_TOPIC, rm.AXES),
                                (DIAGNOSTICS_TOPIC, rm.DIAGNOSTICS), (GROUNDTRUTH_TOPIC, rm.POSE_STAMPED)):
            self.bag.topic(topic, msg_type)
        self.bag.topic(TF_STATIC_TOPIC, rm.TF, qos=QOS_STATIC)
        self._truth = TruthInOdom(mount)
        self._odometry_started = False
        self._next_status: float | None = None
        self._losses: dict[str, int] = {}
        self._t = 0.0

    def write(self, result: FrameResult, stats: PipelineStats) -> None:
        t, types, bag = result.frame.timestamp, self.types, self.bag
        if self._next_status is None:
            bag.write(TF_STATIC_TOPIC, rm.tf_mount(t, types, self.mount), t)
            self._next_status = t + self.period
        self._t = t
        state = result.state
        if state is not None:
            self._odometry_started = True
            odometry, tf = rm.odometry_and_tf(state, types, self.mount)
            bag.write(self.odom_topic, odometry, t)
            bag.write(TF_TOPIC, tf, t)
            bag.write(DIAGNOSTICS_TOPIC, rm.diagnostics(t, [rm.odometry_status(state)], types), t)
        if result.points is not None:
            bag.write(POINTS_TOPIC, rm.pointcloud2(t, result.points, types), t)
        if result.heatmap is not None:
            bag.write(HEATMAP_TOPIC, rm.heatmap_image(t, result.heatmap, types), t)
            bag.write(HEATMAP_AXES_TOPIC, rm.heatmap_axes(result.heatmap, types), t)
        if result.frame.pose is not None and self._odometry_started:
            bag.write(GROUNDTRUTH_TOPIC, rm.pose_stamped(t, self._truth(result.frame.pose), types), t)
        if t >= self._next_status:
            self._next_status = t + self.period
            self._write_status(stats, running=True)
        bag.flush()

    def _write_status(self, stats: PipelineStats, *, running: bool) -> None:
        entry, self._losses = rm.pipeline_status(status(stats, self.source, running=running), self._losses)
        self.bag.write(DIAGNOSTICS_TOPIC, rm.diagnostics(self._t, [entry], self.types), self._t)

    def close(self, stats: PipelineStats) -> None:
        try:
            if self._next_status is not None:
                self._write_status(stats, running=False)
        finally:
            self.bag.close()
            remove_if_no_frame(self.path, stats)
