"""The messages radarodom publishes: versioned wire schemas and pure encode/decode.

Nothing here opens a network session; :mod:`radarodom.publish` puts these
bytes on Zenoh keys under a prefix (default ``radar/awr1843``).  Everything
below is enough to read the messages without radarodom.

Odometry: ``<prefix>/odom``, encoding ``application/json``
    One UTF-8 JSON object per heatmap frame (schema ``radarodom/odom``,
    version 1)::

        {"schema": "radarodom/odom", "version": 1,
         "t": 1700000000.05,      # s, the frame's timestamp (host clock, or the recording's)
         "frame": 12,             # index of the estimator's frame, from 0
         "x": 1.2, "y": -0.3,     # m, position in the odom frame (REP-103: the body frame at frame 0)
         "yaw": 0.1,              # rad, counter-clockwise, unwrapped (not folded into +-pi)
         "vx": 0.5, "vy": 0.0,    # m/s, body frame: x forward, y left
         "yaw_rate": 0.02,        # rad/s
         "pose_covariance": [9 numbers],   # 3x3 row-major over (x, y, yaw)
         "twist_covariance": [9 numbers],  # 3x3 row-major over (vx, vy, yaw_rate)
         "flags": ["velocity_failed", ...],  # quality flags; empty when the step was good
         "ok": true,              # no flag other than "first_frame"
         "features": 180,         # heatmap features registered
         "compute_ms": 4.1,       # estimator time for this frame
         "frame_id": "odom", "child_frame_id": "base_radar"}

    No value is ever NaN or infinite (an encoder refuses; JSON has no NaN).
    Readers ignore keys they do not know; a change that would break a reader
    raises ``version``.  A reader refuses a JSON message larger than
    :data:`MAX_JSON_BYTES` or nested deeper than 32, before parsing it.

Status: ``<prefix>/status``, encoding ``application/json``
    A JSON object about once a second with ``"schema": "radarodom/status",
    "version": 1`` and whatever the publisher reports.  ``radar-capture``
    sends (readers ignore keys they do not know; keys are only ever added)::

        {"schema": "radarodom/status", "version": 1,
         "time": 1700000000.0,     # s, host clock, when the status was made
         "running": true,          # false in the last message of a run
         "frames": 412,            # frames processed so far
         "rate_hz": 10.0,          # frames per second, last 2 s
         "incomplete_frames": 3,   # frames processed with zero-filled bytes
         "missing_bytes": 4368,    # their zero-filled bytes = lost_bytes + cut_bytes
         "lost_bytes": 2912,       #   lost on the way (lost, truncated or late packets)
         "cut_bytes": 1456,        #   never sent before the stream stopped (cut at stop)
         "stream_s": 41.1,         # s of stream time (frame timestamps)
         "frames_dropped": 0,      # whole frames dropped for slow processing (live; else 0)
         "packets_lost": 2,        # data packets never received: sequence gaps (live; else 0)
         "source": {...},          # the source's own figures: for dca1000:// the packet counts
                                   # (packets, packets_lost, truncated_packets, late_packets,
                                   # duplicate_packets, foreign_packets, malformed_packets,
                                   # stale_packets),
                                   # frames_complete/incomplete/dropped, async_status, fpga, url
         "latency_ms": {"p50": 12.0, "p90": 15.0, "p99": 20.0, "max": 31.0},
         "estimator_ms": 4.1,      # median estimator time per frame
         "odometry": {"ok": true, "flags": [], "frame": 411}}

    ``lost_bytes``, ``cut_bytes`` and the source's ``packets_lost``,
    ``truncated_packets`` and ``frames_complete`` are newer than the rest: an
    older publisher does not send them.  A number the publisher does not have
    (the latency percentiles before the first frame) is ``null``: the publisher
    sends every NaN or infinite value as ``null``, as JSON has neither.

Binary messages.  A reader checks the header's sizes against the payload's
length before it reads an array, refuses a payload larger than
:data:`MAX_BINARY_BYTES`, and refuses a header whose ``t`` is NaN or infinite
(the arrays may hold NaN: see ``doppler_mps``).

Point cloud: ``<prefix>/pointcloud``, encoding ``application/octet-stream;radarodom/pointcloud/v1``
    A 32-byte little-endian header, then ``count`` records of 36 bytes::

        offset  type     field
        0       4 bytes  magic b"RPC1"
        4       uint16   version (1)
        6       uint16   header_bytes (32)
        8       uint64   frame
        16      float64  t (s)
        24      uint32   count
        28      uint16   record_bytes (36)
        30      uint16   fields (9)

    Each record is nine float32 in the TI sensor frame (x right, y along
    boresight, z up): ``x, y, z`` (m), ``range`` (m), ``azimuth``,
    ``elevation`` (rad, azimuth positive to the right), ``velocity`` (m/s
    radial, positive receding), ``snr_db``, ``noise_db`` (dB).  In numpy:
    ``np.frombuffer(payload, POINTCLOUD_RECORD, count, 32)``.

Heatmap: ``<prefix>/heatmap``, encoding ``application/octet-stream;radarodom/heatmap/v1``
    A 36-byte little-endian header, then float32 arrays back to back::

        offset  type     field
        0       4 bytes  magic b"RHM1"
        4       uint16   version (1)
        6       uint16   header_bytes (36)
        8       uint64   frame
        16      float64  t (s)
        24      uint32   n_range
        28      uint32   n_azimuth
        32      uint32   channels (3)

        range_m      float32 (n_range,)
        azimuth_rad  float32 (n_azimuth,), ascending, positive to the right
        intensity    float32 (n_range, n_azimuth) row-major: power over all Doppler bins, linear
        static       float32 (n_range, n_azimuth): power in the zero-Doppler bin(s), linear
                     (coloradar:// heatmaps: a copy of intensity, the dataset keeps no
                     zero-Doppler channel; their intensity is the dataset's own scale)
        doppler_mps  float32 (n_range, n_azimuth): radial velocity of each cell's strongest
                     Doppler bin, m/s; NaN where it was not computed

ROS 2: ``nav_msgs/msg/Odometry``, as rmw_zenoh publishes it: :mod:`radarodom.ros2`.
"""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from . import strict_json
from .errors import MessageError
# The format's constants and shared checks live in message_format; every public name stays
# importable from here, as before the split.
from .message_format import (  # noqa: F401
    CHILD_FRAME_ID, HEATMAP_CHANNELS, HEATMAP_ENCODING, HEATMAP_HEADER, HEATMAP_MAGIC, HEATMAP_SCHEMA,
    JSON_ENCODING, MAX_BINARY_BYTES, MAX_FRAME, MAX_JSON_BYTES, ODOM_FRAME_ID, ODOM_SCHEMA,
    POINTCLOUD_ENCODING, POINTCLOUD_HEADER, POINTCLOUD_MAGIC, POINTCLOUD_RECORD, POINTCLOUD_SCHEMA,
    STATUS_SCHEMA, VERSION, _check_bound, _check_version, _finite, _payload_bytes, _quote)
from .products import RangeAzimuth

if TYPE_CHECKING:  # the estimator is not needed to encode what it made
    from .estimator.odometry import OdometryState


# ---------------------------------------------------------------------- JSON
def _json_bytes(obj: Mapping[str, Any], what: str) -> bytes:
    try:
        data = json.dumps(obj, allow_nan=False, separators=(",", ":")).encode()
    except ValueError as exc:  # NaN or infinity: JSON has no way to say it
        raise MessageError(f"{what}: cannot encode a non-finite number ({exc})") from None
    except TypeError as exc:
        raise MessageError(f"{what}: {exc}") from None
    _check_bound(len(data), MAX_JSON_BYTES, what)
    return data


def _json_object(payload: bytes, schema: str) -> dict:
    """The JSON object in *payload*, checked to be of *schema* at a version this reader knows."""
    data = _payload_bytes(payload, schema, MAX_JSON_BYTES)
    try:
        obj = strict_json.loads(data, max_bytes=MAX_JSON_BYTES)
    except ValueError as exc:  # not UTF-8, not JSON, too deep, or NaN/Infinity/1e999 in it
        raise MessageError(f"not a {schema} message: {exc}") from None
    if not isinstance(obj, dict):
        raise MessageError(f"not a {schema} message: a JSON {type(obj).__name__}, not an object")
    if obj.get("schema") != schema:
        raise MessageError(f"not a {schema} message: schema {_quote(obj.get('schema'))}")
    _check_version(obj.get("version"), schema)
    return obj


def _count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= MAX_FRAME


def _covariance(value: Any) -> bool:
    return isinstance(value, list) and len(value) == 9 and all(_finite(v) for v in value)


def _strings(value: Any) -> bool:
    return isinstance(value, list) and all(isinstance(v, str) for v in value)


#: Every field of odometry v1 and what its value must be.
_ODOM_FIELDS = {
    "t": (_finite, "a finite number"),
    "frame": (_count, "a whole number from 0 to 2**64 - 1"),
    **{name: (_finite, "a finite number") for name in ("x", "y", "yaw", "vx", "vy", "yaw_rate", "compute_ms")},
    "pose_covariance": (_covariance, "a list of 9 finite numbers"),
    "twist_covariance": (_covariance, "a list of 9 finite numbers"),
    "flags": (_strings, "a list of strings"),
    "ok": (lambda v: isinstance(v, bool), "true or false"),
    "features": (_count, "a whole number from 0 to 2**64 - 1"),
    "frame_id": (lambda v: isinstance(v, str), "a string"),
    "child_frame_id": (lambda v: isinstance(v, str), "a string"),
}


def odometry_dict(state: OdometryState) -> dict:
    """The odometry v1 object of an :class:`radarodom.estimator.odometry.OdometryState`
    (or anything with its attributes)."""
    missing = [name for name in ("t", "frame", "x", "y", "yaw", "vx", "vy", "yaw_rate", "pose_covariance")
               if not hasattr(state, name)]
    if missing:
        raise MessageError(f"odometry: an OdometryState (radarodom.estimator.odometry), got {type(state).__name__} "
                           f"without {', '.join(missing)}")
    return {
        "schema": ODOM_SCHEMA, "version": VERSION,
        "t": float(state.t), "frame": int(state.frame),
        "x": float(state.x), "y": float(state.y), "yaw": float(state.yaw),
        "vx": float(state.vx), "vy": float(state.vy), "yaw_rate": float(state.yaw_rate),
        "pose_covariance": _flat3x3(state.pose_covariance, "pose_covariance"),
        "twist_covariance": _flat3x3(state.twist_covariance, "twist_covariance"),
        "flags": [str(f) for f in state.flags],
        "ok": bool(state.ok),
        "features": int(state.features),
        "compute_ms": 1e3 * float(state.compute_s),
        "frame_id": ODOM_FRAME_ID, "child_frame_id": CHILD_FRAME_ID,
    }


def _flat3x3(matrix: Any, name: str) -> list[float]:
    a = np.asarray(matrix, dtype=float)
    if a.shape != (3, 3):
        raise MessageError(f"odometry {name}: expected a 3x3 matrix, got shape {a.shape}")
    return a.ravel().tolist()


def odometry_json(state: OdometryState) -> bytes:
    """The odometry v1 message of *state*, UTF-8 JSON; refuses NaN and infinity."""
    return _json_bytes(odometry_dict(state), "odometry")


def parse_odometry(payload: bytes) -> dict:
    """The odometry object in *payload*, with every v1 field checked; raises
    :class:`MessageError` naming what is wrong."""
    obj = _json_object(payload, ODOM_SCHEMA)
    for name, (valid, what) in _ODOM_FIELDS.items():
        if name not in obj:
            raise MessageError(f"{ODOM_SCHEMA}: field {name!r} is missing")
        if not valid(obj[name]):
            raise MessageError(f"{ODOM_SCHEMA}: field {name!r} must be {what}, got {_quote(obj[name])}")
    return obj


def status_json(status: Mapping[str, Any]) -> bytes:
    """The status v1 message: *status*'s items after ``schema`` and ``version``
    (which it must not set itself); refuses NaN and infinity."""
    if not isinstance(status, Mapping):
        raise MessageError(f"status: a mapping of the status' items, got {type(status).__name__}")
    keys = [k for k in status if not isinstance(k, str)]
    if keys:  # JSON writes 1 as "1": a second "1" would be a key twice, which every reader refuses
        raise MessageError(f"status: its keys must be strings, got {_quote(keys[0])}")
    reserved = {"schema", "version"} & set(status)
    if reserved:
        raise MessageError(f"status: {', '.join(sorted(reserved))} are set by the schema, not the caller")
    return _json_bytes({"schema": STATUS_SCHEMA, "version": VERSION, **status}, "status")


def parse_status(payload: bytes) -> dict:
    """The status object in *payload* (schema and version checked; every number finite)."""
    return _json_object(payload, STATUS_SCHEMA)


# ---------------------------------------------------------------------- binary
def _header(dtype: np.dtype, magic: bytes, frame: int, t: float, **fields: int) -> np.ndarray:
    if isinstance(frame, bool) or not isinstance(frame, (int, np.integer)) or not 0 <= frame <= MAX_FRAME:
        raise MessageError(f"frame must be a whole number from 0 to 2**64 - 1, got {_quote(frame)}")
    if isinstance(t, bool) or not isinstance(t, (int, float, np.integer, np.floating)) or not _finite(float(t)):
        raise MessageError(f"t must be a finite number, got {_quote(t)}")
    header = np.zeros((), dtype)
    header["magic"], header["version"], header["header_bytes"] = magic, VERSION, dtype.itemsize
    header["frame"], header["t"] = frame, t
    for name, value in fields.items():
        header[name] = value
    return header


def _read_header(payload: bytes, dtype: np.dtype, magic: bytes, schema: str) -> np.ndarray:
    """The header of *payload* (already bytes, within the size bound), its magic, version,
    size and time checked."""
    if len(payload) < dtype.itemsize:
        raise MessageError(f"{schema}: {len(payload)} bytes, shorter than its {dtype.itemsize}-byte header")
    header = np.frombuffer(payload, dtype, 1)[0]
    if header["magic"] != magic:
        # The payload's own bytes: numpy's S4 drops trailing NULs (a zeroed magic would read b'').
        raise MessageError(f"not a {schema} message: magic {payload[:len(magic)]!r}, expected {magic!r}")
    _check_version(int(header["version"]), schema)
    if header["header_bytes"] != dtype.itemsize:
        raise MessageError(f"{schema}: header of {header['header_bytes']} bytes, expected {dtype.itemsize}")
    if not math.isfinite(header["t"]):
        raise MessageError(f"{schema}: t is {float(header['t'])}, not a finite time")
    return header


def _check_size(payload: bytes, expected: int, schema: str, what: str) -> None:
    if len(payload) != expected:
        raise MessageError(f"{schema}: {len(payload)} bytes, but its header says {what}: {expected} bytes")


def encode_pointcloud(frame: int, t: float, points: np.ndarray) -> bytes:
    """The point cloud v1 message of one frame; *points* is a structured array
    with at least the fields of :data:`POINTCLOUD_RECORD` (``POINT_DTYPE`` has them)."""
    if not isinstance(points, np.ndarray):
        raise MessageError(f"point cloud: a structured array of points (radarodom.products.POINT_DTYPE), got "
                           f"{type(points).__name__}")
    if points.ndim != 1:
        raise MessageError(f"point cloud: a (n,) array of points, got the shape {points.shape}")
    names = points.dtype.names or ()
    missing = [f for f in POINTCLOUD_RECORD.names if f not in names]
    if missing:
        raise MessageError(f"point cloud: the points lack field(s) {', '.join(missing)}")
    _check_bound(POINTCLOUD_HEADER.itemsize + len(points) * POINTCLOUD_RECORD.itemsize, MAX_BINARY_BYTES,
                 "point cloud")
    records = np.empty(len(points), POINTCLOUD_RECORD)
    for name in POINTCLOUD_RECORD.names:
        records[name] = points[name]
    header = _header(POINTCLOUD_HEADER, POINTCLOUD_MAGIC, frame, t, count=len(points),
                     record_bytes=POINTCLOUD_RECORD.itemsize, fields=len(POINTCLOUD_RECORD.names))
    return header.tobytes() + records.tobytes()


def decode_pointcloud(payload: bytes) -> tuple[dict, np.ndarray]:
    """(header, points) of a point cloud message; points are a writable
    :data:`POINTCLOUD_RECORD` array.  The header has ``schema, version, frame, t, count``."""
    payload = _payload_bytes(payload, POINTCLOUD_SCHEMA, MAX_BINARY_BYTES)
    header = _read_header(payload, POINTCLOUD_HEADER, POINTCLOUD_MAGIC, POINTCLOUD_SCHEMA)
    layout = (int(header["record_bytes"]), int(header["fields"]))
    if layout != (POINTCLOUD_RECORD.itemsize, len(POINTCLOUD_RECORD.names)):
        raise MessageError(f"{POINTCLOUD_SCHEMA}: records of {layout[0]} bytes in {layout[1]} fields, "
                           f"expected {POINTCLOUD_RECORD.itemsize} in {len(POINTCLOUD_RECORD.names)}")
    count = int(header["count"])
    _check_size(payload, POINTCLOUD_HEADER.itemsize + count * POINTCLOUD_RECORD.itemsize, POINTCLOUD_SCHEMA,
                f"{count} points")
    points = np.frombuffer(payload, POINTCLOUD_RECORD, count, POINTCLOUD_HEADER.itemsize).copy()
    info = {"schema": POINTCLOUD_SCHEMA, "version": int(header["version"]), "frame": int(header["frame"]),
            "t": float(header["t"]), "count": count}
    return info, points


def encode_heatmap(frame: int, t: float, heatmap: RangeAzimuth) -> bytes:
    """The heatmap v1 message of a :class:`radarodom.dsp.heatmap.RangeAzimuth`
    (or anything with its five arrays)."""
    if not all(hasattr(heatmap, name) for name in ("intensity", "static", "doppler_mps", "range_m", "azimuth_rad")):
        raise MessageError(f"heatmap: a range-azimuth heatmap (radarodom.products.RangeAzimuth), got "
                           f"{type(heatmap).__name__}")
    range_m = np.ascontiguousarray(heatmap.range_m, "<f4")
    azimuth = np.ascontiguousarray(heatmap.azimuth_rad, "<f4")
    if range_m.ndim != 1 or azimuth.ndim != 1:
        raise MessageError(f"heatmap: the axes must be 1-D, got range_m {range_m.shape} and "
                           f"azimuth_rad {azimuth.shape}")
    shape = (len(range_m), len(azimuth))
    _check_bound(HEATMAP_HEADER.itemsize + 4 * (sum(shape) + len(HEATMAP_CHANNELS) * shape[0] * shape[1]),
                 MAX_BINARY_BYTES, "heatmap")
    parts = [range_m, azimuth]
    for name in HEATMAP_CHANNELS:
        channel = np.ascontiguousarray(getattr(heatmap, name), "<f4")
        if channel.shape != shape:
            raise MessageError(f"heatmap: {name} has shape {channel.shape}, the axes say {shape}")
        parts.append(channel)
    header = _header(HEATMAP_HEADER, HEATMAP_MAGIC, frame, t, n_range=shape[0], n_azimuth=shape[1],
                     channels=len(HEATMAP_CHANNELS))
    # One copy of each array into the message (join takes their buffers as they are; a byte
    # view, as memoryview.cast refuses an empty 2-D array).
    return b"".join([header.tobytes(), *(p.reshape(-1).view(np.uint8) for p in parts)])


def decode_heatmap(payload: bytes) -> tuple[dict, dict[str, np.ndarray]]:
    """(header, arrays) of a heatmap message.  The arrays are float32 keyed like
    RangeAzimuth's attributes, so ``RangeAzimuth(**arrays)`` rebuilds one.  The
    header has ``schema, version, frame, t, n_range, n_azimuth, channels``."""
    payload = _payload_bytes(payload, HEATMAP_SCHEMA, MAX_BINARY_BYTES)
    header = _read_header(payload, HEATMAP_HEADER, HEATMAP_MAGIC, HEATMAP_SCHEMA)
    nr, na, channels = int(header["n_range"]), int(header["n_azimuth"]), int(header["channels"])
    if channels != len(HEATMAP_CHANNELS):
        raise MessageError(f"{HEATMAP_SCHEMA}: {channels} channels, expected {len(HEATMAP_CHANNELS)}")
    floats = nr + na + channels * nr * na
    _check_size(payload, HEATMAP_HEADER.itemsize + 4 * floats, HEATMAP_SCHEMA, f"{nr} x {na} x {channels}")
    data = np.frombuffer(payload, "<f4", floats, HEATMAP_HEADER.itemsize).astype(np.float32)
    arrays = {"range_m": data[:nr], "azimuth_rad": data[nr:nr + na]}
    cells = data[nr + na:].reshape(channels, nr, na)
    arrays.update(zip(HEATMAP_CHANNELS, cells))
    info = {"schema": HEATMAP_SCHEMA, "version": int(header["version"]), "frame": int(header["frame"]),
            "t": float(header["t"]), "n_range": nr, "n_azimuth": na, "channels": list(HEATMAP_CHANNELS)}
    return info, arrays
