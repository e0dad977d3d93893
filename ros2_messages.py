"""radarodom's results as ROS 2 messages (instances of a rosbags typestore's classes), for the
live ROS 2 output (:mod:`radarodom.ros2`) and the MCAP recording (:mod:`radarodom.ros2_bag`)
alike: one builder per message, so that both carry the same bytes.

Frames (:mod:`radarodom.ros2_frames`): ``odom -> base_link -> radar``.  Every stamp is the
frame's timestamp (the radar's: host clock live, the recording's or the simulator's clock
otherwise).  docs/ros2.md lists the topics and the fields.

- :func:`odometry` (and :func:`odometry_and_tf`): ``nav_msgs/msg/Odometry``, odom -> base_link,
  the pose and twist with 6x6 covariances (the planar 3x3 ones in x, y, yaw;
  :data:`UNOBSERVED_VARIANCE` on z, roll, pitch).
- :func:`tf_odom` / :func:`tf_mount`: ``tf2_msgs/msg/TFMessage`` of odom -> base_link and of the
  static base_link -> radar.
- :func:`pointcloud2`: ``sensor_msgs/msg/PointCloud2`` in ``radar``: float32 fields
  :data:`POINTCLOUD2_FIELDS`.
- :func:`heatmap_image` and :func:`heatmap_axes`: the range-azimuth intensity as
  ``sensor_msgs/msg/Image`` 32FC1 in dB, and its axes as ``std_msgs/msg/Float32MultiArray``.
- :func:`diagnostics`: ``diagnostic_msgs/msg/DiagnosticArray`` of named key-value statuses
  (:func:`odometry_status`, :func:`pipeline_status`).
- :func:`pose_stamped`: ``geometry_msgs/msg/PoseStamped`` (the ground truth in odom).
"""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

import numpy as np

from .errors import MessageError
from .mount import Mount
from .products import RangeAzimuth
from .ros2_frames import BASE_FRAME_ID, ODOM_FRAME_ID, RADAR_FRAME_ID, BasePose, Rigid, base_pose, ti_to_radar

if TYPE_CHECKING:  # the estimator is not needed to encode what it made
    from .estimator.odometry import OdometryState

ODOMETRY = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"
POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
IMAGE = "sensor_msgs/msg/Image"
AXES = "std_msgs/msg/Float32MultiArray"
DIAGNOSTICS = "diagnostic_msgs/msg/DiagnosticArray"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
#: Covariance given to what a planar odometry does not observe (z, roll, pitch).
UNOBSERVED_VARIANCE = 1e6
#: Where (x, y, yaw) and (vx, vy, yaw_rate) sit in ROS's 6x6 covariances
#: (x, y, z, rotation about x, y, z).
_PLANAR_IN_6D = (0, 1, 5)
#: The point cloud's fields (all float32, in this order): x, y, z in the radar's REP-103 frame
#: (m), the radial velocity (m/s, positive receding), the SNR and the noise level (dB).
POINTCLOUD2_FIELDS = ("x", "y", "z", "velocity", "snr", "noise")
_POINTCLOUD2_RECORD = np.dtype([(name, "<f4") for name in POINTCLOUD2_FIELDS])
_FLOAT32 = 7  # sensor_msgs/msg/PointField.FLOAT32
#: The heatmap image's floor: 10 log10 of the intensity, not below this (dB), so that an empty
#: cell stays a finite number.
HEATMAP_FLOOR_DB = -300.0
#: The first second a ROS 2 stamp cannot hold (builtin_interfaces/Time's int32 seconds; 2038-01-19).
ROS2_TIME_END_S = 2**31
#: diagnostic_msgs/msg/DiagnosticStatus levels.
OK, WARN, ERROR = 0, 1, 2


def stamp(t: float) -> tuple[int, int]:
    """(sec, nanosec) of *t* seconds (0 <= t < 2**31), nanosec in [0, 1e9)."""
    if not math.isfinite(t):
        raise MessageError(f"ROS 2 stamp: {t} is not a finite time")
    # Split first: t * 1e9 of a present-day time in float would lose ~100 ns.
    sec = math.floor(t)
    nanosec = round((t - sec) * 1e9)
    if nanosec == 1_000_000_000:
        sec, nanosec = sec + 1, 0
    if sec < 0:
        # The message's int32 would hold it, but a C++ subscriber's rclcpp::Time(stamp) throws on it.
        raise MessageError(f"ROS 2 stamp: time {t} s is before 0, which a ROS 2 node's time cannot hold "
                           "(rclcpp::Time refuses a negative time point)")
    if sec >= ROS2_TIME_END_S:
        raise MessageError(f"ROS 2 stamp: time {t} s is beyond what ROS 2's time holds (its seconds are a "
                           f"32-bit integer: up to {ROS2_TIME_END_S - 1} s, 2038-01-19)")
    return sec, nanosec


def header(types: Mapping[str, Any], t: float, frame_id: str) -> Any:
    sec, nanosec = stamp(float(t))
    return types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                        frame_id=frame_id)


def _covariance_6x6(cov3: Any) -> np.ndarray:
    """ROS's 6x6 covariance (row-major, 36) holding a planar 3x3 one; what a
    planar odometry cannot see gets :data:`UNOBSERVED_VARIANCE`."""
    out = np.diag(np.full(6, UNOBSERVED_VARIANCE))
    out[np.ix_(_PLANAR_IN_6D, _PLANAR_IN_6D)] = np.asarray(cov3, float)
    return out.ravel()


def _quaternion(types: Mapping[str, Any], q: Sequence[float]) -> Any:
    return types["geometry_msgs/msg/Quaternion"](x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))


def _yaw_quaternion(types: Mapping[str, Any], yaw: float) -> Any:
    return _quaternion(types, (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)))


def _finite_state(state: OdometryState) -> None:
    if not all(math.isfinite(float(v)) for v in (state.t, state.x, state.y, state.yaw,
                                                 state.vx, state.vy, state.yaw_rate)):
        raise MessageError("ROS 2 odometry: cannot encode a non-finite value")


def odometry_and_tf(state: OdometryState, types: Mapping[str, Any], mount: Mount = Mount()) -> tuple[Any, Any]:
    """(:func:`odometry`, :func:`tf_odom`) of *state*, the base's pose worked out once."""
    _finite_state(state)
    base = base_pose(state, mount)
    return _odometry(state.t, base, types), _tf_odom(state.t, base, types)


def odometry(state: OdometryState, types: Mapping[str, Any], mount: Mount = Mount()) -> Any:
    """``nav_msgs/msg/Odometry`` of *state*: base_link in odom (the radar's motion moved onto the
    base through *mount*: :func:`radarodom.ros2_frames.base_pose`)."""
    return odometry_and_tf(state, types, mount)[0]


def _odometry(t: float, base: BasePose, types: Mapping[str, Any]) -> Any:
    vector, point = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Point"]
    pose = types["geometry_msgs/msg/PoseWithCovariance"](
        pose=types["geometry_msgs/msg/Pose"](position=point(x=base.x, y=base.y, z=0.0),
                                             orientation=_yaw_quaternion(types, base.yaw)),
        covariance=_covariance_6x6(base.pose_covariance))
    twist = types["geometry_msgs/msg/TwistWithCovariance"](
        twist=types["geometry_msgs/msg/Twist"](linear=vector(x=base.vx, y=base.vy, z=0.0),
                                               angular=vector(x=0.0, y=0.0, z=base.yaw_rate)),
        covariance=_covariance_6x6(base.twist_covariance))
    return types[ODOMETRY](header=header(types, t, ODOM_FRAME_ID), child_frame_id=BASE_FRAME_ID,
                           pose=pose, twist=twist)


def _transform(types: Mapping[str, Any], t: float, parent: str, child: str, transform: Rigid) -> Any:
    x, y, z = (float(v) for v in transform.translation)
    return types["geometry_msgs/msg/TransformStamped"](
        header=header(types, t, parent), child_frame_id=child,
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z),
            rotation=_quaternion(types, transform.rotation)))


def tf_odom(state: OdometryState, types: Mapping[str, Any], mount: Mount = Mount()) -> Any:
    """``tf2_msgs/msg/TFMessage`` of odom -> base_link: the pose :func:`odometry` gives."""
    return odometry_and_tf(state, types, mount)[1]


def _tf_odom(t: float, base: BasePose, types: Mapping[str, Any]) -> Any:
    return types[TF](transforms=[_transform(types, t, ODOM_FRAME_ID, BASE_FRAME_ID,
                                            Rigid.planar(base.x, base.y, base.yaw))])


def tf_mount(t: float, types: Mapping[str, Any], mount: Mount = Mount()) -> Any:
    """``tf2_msgs/msg/TFMessage`` of the static base_link -> radar (``/tf_static``)."""
    return types[TF](transforms=[_transform(types, t, BASE_FRAME_ID, RADAR_FRAME_ID, Rigid.of_mount(mount))])


def pointcloud2(t: float, points: np.ndarray, types: Mapping[str, Any]) -> Any:
    """``sensor_msgs/msg/PointCloud2`` of a :data:`radarodom.products.POINT_DTYPE` cloud (TI
    sensor frame) in the radar's REP-103 frame: one row, :data:`POINTCLOUD2_FIELDS`."""
    records = np.empty(len(points), _POINTCLOUD2_RECORD)
    records["x"], records["y"], records["z"] = ti_to_radar(points)
    records["velocity"], records["snr"], records["noise"] = points["velocity"], points["snr_db"], points["noise_db"]
    field = types["sensor_msgs/msg/PointField"]
    fields = [field(name=name, offset=4 * i, datatype=_FLOAT32, count=1) for i, name in enumerate(POINTCLOUD2_FIELDS)]
    step = _POINTCLOUD2_RECORD.itemsize
    return types[POINTCLOUD2](header=header(types, t, RADAR_FRAME_ID), height=1, width=len(records), fields=fields,
                              is_bigendian=False, point_step=step, row_step=step * len(records),
                              data=records.view(np.uint8).reshape(-1),
                              is_dense=bool(np.isfinite(records.view("<f4")).all()))


def heatmap_db(heatmap: RangeAzimuth) -> np.ndarray:
    """The image's pixels: float32 (n_range, n_azimuth), 10 log10 of the intensity (floored at
    :data:`HEATMAP_FLOOR_DB`), the farthest range in row 0 and the leftmost bearing (most negative
    TI azimuth) in column 0: the map as seen from above, boresight up."""
    intensity = np.asarray(heatmap.intensity, np.float64)
    with np.errstate(divide="ignore"):
        db = 10.0 * np.log10(np.maximum(intensity, 0.0))
    return np.maximum(db, HEATMAP_FLOOR_DB)[::-1].astype("<f4")


def heatmap_image(t: float, heatmap: RangeAzimuth, types: Mapping[str, Any]) -> Any:
    """``sensor_msgs/msg/Image`` (32FC1, little-endian) of :func:`heatmap_db`, frame ``radar``."""
    pixels = np.ascontiguousarray(heatmap_db(heatmap))
    rows, cols = pixels.shape
    return types[IMAGE](header=header(types, t, RADAR_FRAME_ID), height=rows, width=cols, encoding="32FC1",
                        is_bigendian=0, step=4 * cols, data=pixels.view(np.uint8).reshape(-1))


def heatmap_axes(heatmap: RangeAzimuth, types: Mapping[str, Any]) -> Any:
    """``std_msgs/msg/Float32MultiArray`` of the image's axes: two vectors back to back, labelled
    by the layout's dims: ``range_m`` (one per row, m, row 0 the farthest) then ``bearing_rad``
    (one per column, REP-103: positive left, so descending from column 0).  It has no header:
    it goes with the image of the same time."""
    range_m = np.asarray(heatmap.range_m, np.float32)[::-1]
    bearing = -np.asarray(heatmap.azimuth_rad, np.float32)
    dim = types["std_msgs/msg/MultiArrayDimension"]
    layout = types["std_msgs/msg/MultiArrayLayout"](
        dim=[dim(label="range_m", size=len(range_m), stride=len(range_m)),
             dim(label="bearing_rad", size=len(bearing), stride=len(bearing))], data_offset=0)
    return types[AXES](layout=layout, data=np.concatenate([range_m, bearing]).astype(np.float32))


def diagnostics(t: float, statuses: Iterable[tuple[str, int, str, Mapping[str, Any]]],
                types: Mapping[str, Any], hardware_id: str = RADAR_FRAME_ID) -> Any:
    """``diagnostic_msgs/msg/DiagnosticArray`` of (name, level, message, values) statuses; values
    as strings (numbers with repr, lists comma-separated)."""
    key_value, status = types["diagnostic_msgs/msg/KeyValue"], types["diagnostic_msgs/msg/DiagnosticStatus"]
    return types[DIAGNOSTICS](header=header(types, t, ""), status=[
        status(level=level, name=name, message=message, hardware_id=hardware_id,
               values=[key_value(key=k, value=_text(v)) for k, v in values.items()])
        for name, level, message, values in statuses])


#: The figures whose growth makes a pipeline status a warning: data was lost.
_LOSSES = ("incomplete_frames", "frames_dropped", "packets_lost")


def odometry_status(state: OdometryState) -> tuple[str, int, str, dict[str, Any]]:
    """The diagnostics entry of an odometry state: OK, or WARN with its quality flags."""
    flags = [str(f) for f in state.flags]
    values = {"frame": int(state.frame), "ok": bool(state.ok), "flags": flags, "features": int(state.features),
              "compute_ms": round(1e3 * float(state.compute_s), 3)}
    return "radarodom: odometry", OK if state.ok else WARN, ", ".join(flags) or "ok", values


def pipeline_status(info: Mapping[str, Any], previous: Mapping[str, int]) -> tuple[tuple, dict[str, int]]:
    """(the diagnostics entry of a status message's figures, the losses to compare the next one
    with): WARN when frames went incomplete or were dropped, or packets were lost, since *previous*."""
    grew = [k for k in _LOSSES if info.get(k, 0) > previous.get(k, 0)]
    message = f"{info.get('frames', '?')} frames, {info.get('rate_hz', '?')} Hz" + \
        ("" if info.get("running", True) else ", stopped")
    if grew:
        message += "; more " + ", ".join(k.replace("_", " ") for k in grew)
    entry = ("radarodom: pipeline", WARN if grew else OK, message, flat(info))
    return entry, {k: info.get(k, 0) for k in _LOSSES}


def flat(info: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested dicts as dotted keys (``latency_ms.p50``); lists of other than scalars as JSON."""
    out: dict[str, Any] = {}
    for key, value in info.items():
        if isinstance(value, Mapping):
            out.update(flat(value, f"{prefix}{key}."))
        elif isinstance(value, (list, tuple)) and not all(isinstance(v, (str, int, float)) for v in value):
            out[prefix + key] = json.dumps(value)
        else:
            out[prefix + key] = value
    return out


def _text(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return ",".join(_text(v) for v in value)
    if isinstance(value, bool) or value is None:
        return str(value).lower()
    return str(value)


def pose_stamped(t: float, pose: Rigid, types: Mapping[str, Any], frame_id: str = ODOM_FRAME_ID) -> Any:
    """``geometry_msgs/msg/PoseStamped`` of *pose* in *frame_id*."""
    x, y, z = (float(v) for v in pose.translation)
    point = types["geometry_msgs/msg/Point"](x=x, y=y, z=z)
    return types[POSE_STAMPED](header=header(types, t, frame_id),
                               pose=types["geometry_msgs/msg/Pose"](position=point,
                                                                    orientation=_quaternion(types, pose.rotation)))
