"""A ROS 2 bag as one MCAP file: what ``ros2 bag``, Foxglove, PlotJuggler and Rerun open.

The container is the ``mcap`` package's chunked, indexed writer (profile ``ros2``; zstd chunks
with CRCs; message, chunk and summary indexes; a data-section CRC); every channel's schema is
the message definition in ``ros2msg`` form and its messages are CDR, both from rosbags (the
messages: :mod:`radarodom.ros2_messages`, the same bytes the live ROS 2 output sends).  Each
channel carries its QoS as ``offered_qos_profiles`` (``ros2 bag play`` offers ``/tf_static``
transient local, as tf2 does).

A file cut short (the process killed) keeps every chunk written before: the writer hands a
chunk to the file once it holds :data:`CHUNK_BYTES` of messages, and :meth:`BagWriter.flush`
pushes it out of Python's buffer.  What is lost: the messages of the chunk being filled and the
summary at the end (the index and statistics; readers that scan the file, or ``mcap recover``,
read the chunks without it).
"""

from __future__ import annotations

import contextlib

import logging
import os
from typing import Any

from . import __version__
from .errors import CaptureError, CaptureExistsError, MessageError, UsageError, why_not_written

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

#: Uncompressed size at which a chunk is closed and written: what a killed recording loses at
#: most (docs/ros2.md says how many seconds of the simulator's corridor that is).
CHUNK_BYTES = 1 << 20
PROFILE = "ros2"
SCHEMA_ENCODING = "ros2msg"
MESSAGE_ENCODING = "cdr"

_QOS = """- history: keep_last
  depth: {depth}
  reliability: reliable
  durability: {durability}
  deadline:
    sec: 0
    nsec: 0
  lifespan:
    sec: 0
    nsec: 0
  liveliness: automatic
  liveliness_lease_duration:
    sec: 0
    nsec: 0
  avoid_ros_namespace_conventions: false"""
#: rosbag2's (Jazzy) QoS of a channel: a topic's, and /tf_static's (transient local, keep last 1).
QOS = _QOS.format(depth=10, durability="volatile")
QOS_STATIC = _QOS.format(depth=1, durability="transient_local")


def _mcap():
    try:
        import mcap.writer
    except ImportError:
        raise UsageError('--mcap needs the mcap package: pip install "radarodom[ros2]"') from None
    return mcap.writer


class BagWriter:
    """Writes ROS 2 messages (rosbags typestore instances) to a new MCAP file at *path*.

    Declare each topic once with :meth:`topic`, then :meth:`write` messages in any order
    (readers sort by log time); :meth:`close` writes the summary.  Raises
    :class:`CaptureExistsError` when *path* exists, :class:`CaptureError` when it cannot be
    written, :class:`MessageError` for a message its type cannot hold.
    """

    def __init__(self, path: str | os.PathLike, typestore: Any, *, chunk_bytes: int = CHUNK_BYTES) -> None:
        writer_module = _mcap()
        self.path = os.fspath(path)
        self._store = typestore
        try:
            self._file = open(self.path, "xb")
        except FileExistsError:
            raise CaptureExistsError(f"{self.path} already exists; choose a new file") from None
        except OSError as exc:
            raise CaptureError(f"cannot create {self.path}: {why_not_written(exc, self.path)}") from None
        try:
            self._writer = writer_module.Writer(self._file, chunk_size=chunk_bytes,
                                                compression=writer_module.CompressionType.ZSTD,
                                                enable_data_crcs=True)
            self._writer.start(profile=PROFILE, library=f"radarodom {__version__}; {writer_module.LIBRARY_IDENTIFIER}")
        except OSError as exc:
            self._file.close()
            raise CaptureError(f"cannot write {self.path}: {exc.strerror or exc}") from None
        self._schemas: dict[str, int] = {}
        #: topic -> (channel id, message type)
        self._channels: dict[str, tuple[int, str]] = {}
        #: Messages written per topic.
        self.counts: dict[str, int] = {}
        self.closed = False
        self._failed = False  # a write failed (said then)

    def topic(self, name: str, msg_type: str, *, qos: str = QOS) -> None:
        """Declare *name* as a topic of *msg_type* (e.g. ``sensor_msgs/msg/PointCloud2``)."""
        if msg_type not in self._schemas:
            # rosbags makes a type's serializer on first use: now, not in the first frame's time.
            self._store.get_msgdef(msg_type)
            definition, _ = self._store.generate_msgdef(msg_type, ros_version=2)
            self._schemas[msg_type] = self._writer.register_schema(msg_type, SCHEMA_ENCODING, definition.encode())
        channel = self._writer.register_channel(name, MESSAGE_ENCODING, self._schemas[msg_type],
                                                {"offered_qos_profiles": qos})
        self._channels[name] = (channel, msg_type)
        self.counts[name] = 0

    def write(self, topic: str, msg: Any, t: float) -> None:
        """Write *msg* on *topic* (declared) at *t* s (log and publish time)."""
        channel, msg_type = self._channels[topic]
        if not 0.0 <= t < 2**31:  # a message's ROS 2 stamp: 32-bit seconds
            raise MessageError(f"MCAP {topic}: time {t} s is outside what a bag holds (0 to {2**31 - 1} s, "
                               "2038-01-19: ROS 2's time counts its seconds in 32 bits)")
        try:
            data = bytes(self._store.serialize_cdr(msg, msg_type))
        except (TypeError, ValueError, OverflowError) as exc:
            raise MessageError(f"MCAP {topic}: cannot encode a {msg_type}: {exc}") from None
        time_ns = round(float(t) * 1e9)
        self.counts[topic] += 1
        try:
            self._writer.add_message(channel, log_time=time_ns, data=data, publish_time=time_ns,
                                     sequence=self.counts[topic])
        except OSError as exc:
            raise self._write_failed(exc) from None

    def _write_failed(self, exc: OSError) -> CaptureError:
        """A write that failed (a full disk): what the file keeps."""
        self._failed = True
        return CaptureError(f"cannot write {self.path}: {exc.strerror or exc}; the chunks written before it are "
                            "kept, without the summary and index a finished file ends with (a reader that streams "
                            "the file, such as mcap's StreamReader, reads them)")

    def flush(self) -> None:
        """Hand what the writer wrote (whole chunks) to the operating system, so that a kill of
        the process keeps it.  Cheap when no chunk was closed since the last call."""
        try:
            self._file.flush()
        except OSError as exc:
            raise self._write_failed(exc) from None

    def close(self) -> None:
        """Write the last chunk and the summary, and close the file; safe to call twice."""
        if self.closed:
            return
        self.closed = True
        try:
            self._writer.finish()
        except OSError as exc:
            with contextlib.suppress(OSError):  # (its own flush fails the same way)
                self._file.close()
            if self._failed:  # said when the write failed: once is enough
                return
            raise self._write_failed(exc) from None
        try:
            self._file.close()
        except OSError as exc:
            raise self._write_failed(exc) from None
        log.info("wrote %s: %d messages on %d topics", self.path, sum(self.counts.values()), len(self.counts))
