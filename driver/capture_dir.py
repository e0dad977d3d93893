"""Capture directories: what ``--record`` writes and ``replay://`` reads.

Layout (conventions.md)::

    DIR/radar.cfg        the TI CLI configuration that produced the data
    DIR/adc_data.bin     frames back to back, the DCA1000 raw stream bytes
    DIR/timestamps.txt   one float per frame, s: time of the frame's first chirp
    DIR/capture.json     metadata (software, source, start time, frame count,
                         incomplete frames with their missing bytes)
    DIR/groundtruth.tum  optional: body-frame pose per frame (TUM)

Crash safety: the writer hands every frame to the kernel before the next one
(one unbuffered write for the data, then its timestamp line), and replaces
capture.json atomically, so a process killed at any moment leaves a directory
that reads back up to its last whole frame.
"""

from __future__ import annotations

import json
import logging
import os
import time
from typing import Any, Sequence

import numpy as np

from .. import __version__
from ..cfg import RadarConfig
from ..errors import CaptureError, CaptureExistsError, CaptureFormatError, ConfigError
from ..rawframe import RawLayout
from ..tum import TumWriter, read_tum

log = logging.getLogger(__name__)

RADAR_CFG = "radar.cfg"
ADC_DATA = "adc_data.bin"
TIMESTAMPS = "timestamps.txt"
METADATA = "capture.json"
GROUNDTRUTH = "groundtruth.tum"

#: Incomplete frames listed in capture.json as soon as they are written, up to this many;
#: beyond, the list is rewritten at most every _INCOMPLETE_FLUSH_S seconds.
_IMMEDIATE_INCOMPLETE_LIMIT = 1000
_INCOMPLETE_FLUSH_S = 0.25
#: Value of capture.json's "format" key, and its version.
FORMAT_NAME = "radarodom-capture"
FORMAT_VERSION = 1


def write_json_atomically(path: str, obj: Any) -> None:
    """Replace *path* with *obj* as JSON; a reader (or a crash) never sees half a file."""
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as fh:
        json.dump(obj, fh, indent=1)
        fh.write("\n")
    os.replace(tmp, path)


def _write_all(fd: int, data) -> None:
    view = memoryview(data).cast("B")
    while view:
        view = view[os.write(fd, view):]


class CaptureWriter:
    """Append frames to a new capture directory.

    Use as a context manager; :meth:`close` marks the capture as closed in
    capture.json.  Refuses a directory that already holds a capture.
    """

    def __init__(
        self,
        directory: str | os.PathLike,
        config: RadarConfig,
        *,
        source: str = "",
        metadata_interval_s: float = 1.0,
        extra: dict[str, Any] | None = None,
    ) -> None:
        self.directory = os.fspath(directory)
        self.config = config
        self.frame_bytes = config.frame_bytes
        self._source = source
        self._interval = metadata_interval_s
        self._extra = dict(extra or {})
        self._incomplete: list[dict[str, int]] = []
        self._frames = 0
        self._saved_frames = 0
        self._lost_bytes = 0
        self._cut_bytes = 0
        self._closed = False
        self._start_time = time.time()
        self._last_meta = 0.0
        self._first_ts: float | None = None
        self._last_ts: float | None = None
        try:
            os.makedirs(self.directory, exist_ok=True)
            if os.path.exists(os.path.join(self.directory, ADC_DATA)):
                raise CaptureExistsError(f"{self.directory} already holds a capture ({ADC_DATA}); "
                                   f"choose a new directory")
            config.write(os.path.join(self.directory, RADAR_CFG))
            self._data_fd = os.open(os.path.join(self.directory, ADC_DATA),
                                    os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_APPEND, 0o644)
            self._ts = open(os.path.join(self.directory, TIMESTAMPS), "x", buffering=1, encoding="ascii")
            self._gt: TumWriter | None = None
        except OSError as exc:
            raise CaptureError(f"cannot create capture directory {self.directory}: "
                               f"{exc.strerror or exc}") from None
        self._write_metadata()

    @property
    def frame_count(self) -> int:
        return self._frames

    def write(
        self,
        raw,
        timestamp: float,
        missing_bytes: int = 0,
        pose: Sequence[float] | None = None,
        *,
        cut_bytes: int = 0,
    ) -> None:
        """Append one frame: its *raw* bytes (exactly ``frame_bytes``), the time of
        its first chirp, how many of its bytes were lost (zero-filled), and
        optionally the ground-truth pose ``(x, y, z, qx, qy, qz, qw)``.  *cut_bytes*: of the
        missing bytes, those never sent because the stream stopped (listed with the frame)."""
        if not 0 <= cut_bytes <= missing_bytes:
            raise CaptureError(f"{cut_bytes} bytes cut at stop of a frame missing {missing_bytes}")
        if self._closed:
            raise CaptureError(f"{self.directory}: the capture is closed")
        n = memoryview(raw).nbytes
        if n != self.frame_bytes:
            raise CaptureFormatError(f"frame of {n} bytes, the configuration needs {self.frame_bytes}")
        try:
            _write_all(self._data_fd, raw)
            self._ts.write(f"{timestamp:.9f}\n")
            if pose is not None:
                self._write_pose(timestamp, pose)
        except OSError as exc:
            raise CaptureError(f"writing {self.directory} failed: {exc.strerror or exc}") from None
        index = self._frames
        self._frames += 1
        if self._first_ts is None:
            self._first_ts = timestamp
        self._last_ts = timestamp
        now = time.monotonic()
        if missing_bytes:
            entry = {"frame": index, "missing_bytes": int(missing_bytes)}
            if cut_bytes:
                entry["cut_bytes"] = int(cut_bytes)
            self._incomplete.append(entry)
            self._lost_bytes += int(missing_bytes)
            self._cut_bytes += int(cut_bytes)
        # capture.json is the only place that says a frame is zero-filled, so an
        # incomplete frame is listed before the next frame is written; once the
        # list is long (heavy loss), at most every quarter second to bound the cost.
        if self._incomplete_unsaved():
            due = 0.0 if len(self._incomplete) <= _IMMEDIATE_INCOMPLETE_LIMIT else _INCOMPLETE_FLUSH_S
        else:
            due = self._interval
        if now - self._last_meta >= due:
            self._write_metadata()

    def _incomplete_unsaved(self) -> bool:
        return bool(self._incomplete) and self._incomplete[-1]["frame"] >= self._saved_frames

    def _write_pose(self, timestamp: float, pose: Sequence[float]) -> None:
        if self._gt is None:
            self._gt = TumWriter(os.path.join(self.directory, GROUNDTRUTH))
        self._gt.write_pose(timestamp, pose[:3], pose[3:])

    def metadata(self) -> dict[str, Any]:
        """What capture.json holds now."""
        meta = {
            "format": FORMAT_NAME,
            "format_version": FORMAT_VERSION,
            "software": f"radarodom {__version__}",
            "source": self._source,
            "start_time_unix": self._start_time,
            "start_time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(self._start_time)),
            "frame_bytes": self.frame_bytes,
            "frame_count": self._frames,
            "first_timestamp": self._first_ts,
            "last_timestamp": self._last_ts,
            "incomplete_frames": list(self._incomplete),
            # Every zero-filled byte (the key predates cut_bytes, which it includes).
            "lost_bytes": self._lost_bytes,
            "cut_bytes": self._cut_bytes,
            "closed": self._closed,
        }
        meta.update(self._extra)
        return meta

    def annotate(self, **items: Any) -> None:
        """Add *items* to capture.json (written with the next update, at the latest on close)."""
        self._extra.update(items)

    def _write_metadata(self) -> None:
        self._saved_frames = self._frames
        write_json_atomically(os.path.join(self.directory, METADATA), self.metadata())
        self._last_meta = time.monotonic()

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            os.close(self._data_fd)
            self._ts.close()
            if self._gt is not None:
                self._gt.close()
            self._write_metadata()
        except OSError as exc:
            raise CaptureError(f"closing {self.directory} failed: {exc.strerror or exc}") from None

    def __enter__(self) -> "CaptureWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _read_timestamps(path: str) -> np.ndarray:
    values = []
    with open(path, encoding="ascii", errors="replace") as fh:
        for lineno, line in enumerate(fh, start=1):
            if not line.endswith("\n"):
                log.warning("%s:%d: ignoring a partly written last line", path, lineno)
                break
            try:
                values.append(float(line))
            except ValueError:
                raise CaptureFormatError(f"{path}:{lineno}: not a timestamp: {line.strip()[:40]!r}") from None
    return np.array(values, dtype=float)


class CaptureDirectory:
    """A capture directory opened for reading.

    Frames are read through a memory map, so opening is cheap for any size.
    """

    def __init__(self, directory: str | os.PathLike, config: RadarConfig | None = None) -> None:
        self.directory = os.fspath(directory)
        if not os.path.isdir(self.directory):
            raise CaptureError(f"{self.directory}: no such capture directory")
        cfg_path = os.path.join(self.directory, RADAR_CFG)
        data_path = os.path.join(self.directory, ADC_DATA)
        if not os.path.exists(data_path):
            raise CaptureFormatError(f"{self.directory}: no {ADC_DATA}: not a capture directory")
        if config is None:
            if not os.path.exists(cfg_path):
                raise ConfigError(f"missing {RADAR_CFG}: give the radar configuration with --cfg",
                                  path=self.directory)
            config = RadarConfig.from_file(cfg_path)
        elif os.path.exists(cfg_path):
            recorded = RadarConfig.from_file(cfg_path)
            if recorded.frame_bytes != config.frame_bytes or recorded.cube_shape != config.cube_shape:
                log.warning("%s: the given configuration (%s) differs from the recorded %s; using "
                            "the given one", self.directory, config.path, RADAR_CFG)
        self.config = config
        self.layout = RawLayout.from_config(config)
        self.metadata = self._read_metadata()

        size = os.path.getsize(data_path)
        whole, tail = divmod(size, config.frame_bytes)
        if tail and whole:
            log.warning("%s: %s ends with %d bytes of a cut-off frame after frame %d; they are ignored",
                        self.directory, ADC_DATA, tail, whole - 1)
        elif tail:
            log.warning("%s: %s holds %d bytes, less than one %d-byte frame of %s", self.directory,
                        ADC_DATA, tail, config.frame_bytes, config.path)
        ts_path = os.path.join(self.directory, TIMESTAMPS)
        stamps = _read_timestamps(ts_path) if os.path.exists(ts_path) else np.empty(0)
        if len(stamps) > whole:
            log.warning("%s: %d timestamps for %d whole frames; the extra ones are ignored",
                        self.directory, len(stamps), whole)
            stamps = stamps[:whole]
        elif len(stamps) < whole:
            # The frame's data reached the disk, its timestamp line did not.
            start = stamps[-1] + config.frame_period_s if len(stamps) else 0.0
            missing = whole - len(stamps)
            log.warning("%s: %d frame(s) have no timestamp; extrapolating from the frame period",
                        self.directory, missing)
            stamps = np.concatenate([stamps, start + config.frame_period_s * np.arange(missing)])
        self.timestamps = stamps
        self.num_frames = whole
        self._data = (np.memmap(data_path, dtype=np.uint8, mode="r", shape=(whole * config.frame_bytes,))
                      if whole else np.empty(0, np.uint8))
        listed = [e for e in self.metadata.get("incomplete_frames", [])
                  if isinstance(e, dict) and "frame" in e and "missing_bytes" in e]
        self._missing = {int(e["frame"]): int(e["missing_bytes"]) for e in listed}
        self._cut = {int(e["frame"]): int(e["cut_bytes"]) for e in listed if e.get("cut_bytes")}
        gt_path = os.path.join(self.directory, GROUNDTRUTH)
        self.groundtruth = read_tum(gt_path) if os.path.exists(gt_path) else None
        self._pose_row = self._match_poses()
        if self.metadata and not self.metadata.get("closed", False):
            log.warning("%s: the capture was not closed cleanly (process killed?); reading its "
                        "%d whole frames", self.directory, whole)

    def _read_metadata(self) -> dict[str, Any]:
        path = os.path.join(self.directory, METADATA)
        try:
            with open(path, encoding="utf-8") as fh:
                meta = json.load(fh)
        except FileNotFoundError:
            log.info("%s: no %s; assuming every frame complete", self.directory, METADATA)
            return {}
        except (OSError, ValueError) as exc:
            log.warning("%s: unreadable %s (%s); assuming every frame complete", self.directory,
                        METADATA, exc)
            return {}
        if not isinstance(meta, dict):
            log.warning("%s: %s is not a JSON object; ignored", self.directory, METADATA)
            return {}
        return meta

    def raw(self, i: int) -> np.ndarray:
        """Frame *i*'s bytes, a read-only uint8 view of ``frame_bytes``."""
        if not 0 <= i < self.num_frames:
            raise IndexError(f"frame {i} of {self.num_frames}")
        fb = self.config.frame_bytes
        return self._data[i * fb: (i + 1) * fb]

    def missing_bytes(self, i: int) -> int:
        return self._missing.get(i, 0)

    def cut_bytes(self, i: int) -> int:
        """Of frame *i*'s missing bytes, those cut when its live stream stopped."""
        return self._cut.get(i, 0)

    def _match_poses(self) -> np.ndarray:
        """Row of groundtruth.tum for each frame (by time), -1 where none."""
        rows = np.full(self.num_frames, -1)
        gt = self.groundtruth
        if gt is None or not len(gt.times) or not self.num_frames:
            return rows
        order = np.argsort(gt.times, kind="stable")
        times = gt.times[order]
        j = np.clip(np.searchsorted(times, self.timestamps), 1, len(times)) - 1
        # The nearest of the two neighbours, within a microsecond (TUM files keep 9 decimals).
        j = np.where((j + 1 < len(times)) & (np.abs(times[np.minimum(j + 1, len(times) - 1)] - self.timestamps)
                                               < np.abs(times[j] - self.timestamps)), j + 1, j)
        hit = np.abs(times[j] - self.timestamps) <= 1e-6
        rows[hit] = order[j[hit]]
        if not hit.all():
            log.warning("%s: %s has no pose for %d of %d frames", self.directory, GROUNDTRUTH,
                        int((~hit).sum()), self.num_frames)
        return rows

    def pose(self, i: int) -> tuple[float, ...] | None:
        """Ground-truth pose of frame *i* (the groundtruth.tum line with its timestamp), or None."""
        row = self._pose_row[i] if 0 <= i < self.num_frames else -1
        return self.groundtruth.pose(row) if row >= 0 else None

    def __len__(self) -> int:
        return self.num_frames
