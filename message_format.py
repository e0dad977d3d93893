"""The published messages' format: schema names and versions, encodings, size bounds,
the binary headers' and records' dtypes, and the checks of a payload every reader shares.

Split off :mod:`radarodom.messages`, which describes the messages and re-exports every
public name here (``radarodom.messages.VERSION`` and so on stay where they were).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .errors import MessageError, quoted_json

ODOM_SCHEMA = "radarodom/odom"
STATUS_SCHEMA = "radarodom/status"
POINTCLOUD_SCHEMA = "radarodom/pointcloud"
HEATMAP_SCHEMA = "radarodom/heatmap"
#: The version this module writes and the newest it reads, of every schema.
VERSION = 1

JSON_ENCODING = "application/json"
POINTCLOUD_ENCODING = f"application/octet-stream;{POINTCLOUD_SCHEMA}/v{VERSION}"
HEATMAP_ENCODING = f"application/octet-stream;{HEATMAP_SCHEMA}/v{VERSION}"

#: The odometry's frames (REP-105 names).
ODOM_FRAME_ID = "odom"
CHILD_FRAME_ID = "base_radar"

#: The largest JSON message a reader parses: odometry and status are a few KB; a payload
#: beyond this is refused before it is parsed.
MAX_JSON_BYTES = 1 << 20
#: The largest binary message a reader takes (a heatmap of 1024 x 1024 cells is 12 MiB).
MAX_BINARY_BYTES = 64 << 20
#: Frame numbers travel as uint64.
MAX_FRAME = 2**64 - 1
#: How much of a bad value a message error quotes.
_QUOTE_CHARS = 60

POINTCLOUD_MAGIC = b"RPC1"
HEATMAP_MAGIC = b"RHM1"

#: Point cloud header (little-endian, no padding: offsets as in the module docstring).
POINTCLOUD_HEADER = np.dtype([
    ("magic", "S4"), ("version", "<u2"), ("header_bytes", "<u2"),
    ("frame", "<u8"), ("t", "<f8"),
    ("count", "<u4"), ("record_bytes", "<u2"), ("fields", "<u2"),
])
#: One point on the wire: the float fields of radarodom.dsp.processor.POINT_DTYPE.
POINTCLOUD_RECORD = np.dtype([
    ("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("range", "<f4"),
    ("azimuth", "<f4"), ("elevation", "<f4"), ("velocity", "<f4"),
    ("snr_db", "<f4"), ("noise_db", "<f4"),
])
#: Heatmap header (little-endian, no padding).
HEATMAP_HEADER = np.dtype([
    ("magic", "S4"), ("version", "<u2"), ("header_bytes", "<u2"),
    ("frame", "<u8"), ("t", "<f8"),
    ("n_range", "<u4"), ("n_azimuth", "<u4"), ("channels", "<u4"),
])
#: The heatmap's (n_range, n_azimuth) channels, in wire order; the names are
#: radarodom.dsp.heatmap.RangeAzimuth's attributes.
HEATMAP_CHANNELS = ("intensity", "static", "doppler_mps")


def _check_bound(size: int, limit: int, what: str) -> None:
    # A publisher never sends what every reader would refuse.
    if size > limit:
        raise MessageError(f"{what}: {size} bytes, more than the {limit} a message may have")


def _quote(value: Any) -> str:
    """*value* as a message error quotes it: mostly a decoded JSON message's, in JSON's words."""
    return quoted_json(value, _QUOTE_CHARS)


def _payload_bytes(payload: Any, schema: str, limit: int) -> bytes:
    """*payload* (any bytes-like object) as bytes, refused before the copy when over *limit*."""
    try:
        view = memoryview(payload)
    except TypeError:
        raise MessageError(f"{schema}: a payload is bytes, not {type(payload).__name__}") from None
    if view.nbytes > limit:
        raise MessageError(f"{schema}: {view.nbytes} bytes, more than the {limit} a message may have")
    return view.tobytes()


def _check_version(version: Any, schema: str) -> None:
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise MessageError(f"{schema}: bad version {_quote(version)}")
    if version > VERSION:
        raise MessageError(f"{schema} version {_quote(version)} is newer than this reader understands "
                           f"({VERSION}); upgrade radarodom")


def _finite(value: Any) -> bool:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an integer beyond every float
        return False
