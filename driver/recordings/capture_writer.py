"""The writer of capture directories: :class:`CaptureWriter`, what ``--record`` and
``radar-sim`` record through, and the helpers only writing needs.

Kept apart from the reader (:mod:`.capture_dir`, which re-exports every name defined here, and whose
docstring is the format: the files, timestamps.txt, capture.json's schema, what the reader
takes of a directory cut short) so that each module holds one side of the format.  Also
here: :func:`write_json_atomically`, which the tidemo recorder, the pipeline's sinks and
radar-eval use for their own JSON files.  Which directories a recording may write into, and the
clearing of one, are :mod:`.recording_dir`'s.

Crash safety: the writer hands every frame to the kernel before the next one
(one unbuffered write for the data, then its timestamp line), and replaces
capture.json atomically, so a process killed at any moment leaves a directory
that reads back up to its last whole frame.  A capture that recorded no frame
is removed on close, and one left by a killed run is recorded over.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import time
from typing import Any, Sequence

from ... import __version__, strict_json
from ...cfg import RadarConfig
from ...errors import (CaptureError, CaptureFormatError, add_note, given_path,
                       why_not_written)
from ...line_file import write_file_all
from ...tum import format_tum_line
from ...whole_files import write_text_atomically
from . import capture_check
from .capture_check import ADC_DATA, FORMAT_NAME, FORMAT_VERSION, GROUNDTRUTH, METADATA, RADAR_CFG, TIMESTAMPS
from .recording_dir import (  # noqa: F401 (RECORDING_FILES, holds_frames re-exported: they were defined here)
    RECORDING_FILES, abandon_recording, claim_recording_directory, frames_kept, holds_frames,
    remove_capture_files)

log = logging.getLogger(__name__)

#: Incomplete frames listed in capture.json as soon as they are written, up to this many;
#: beyond, the list is rewritten at most every _INCOMPLETE_FLUSH_S seconds.
_IMMEDIATE_INCOMPLETE_LIMIT = 1000
_INCOMPLETE_FLUSH_S = 0.25


def json_text(obj: Any) -> str:
    """*obj* as the JSON radarodom writes: standard JSON (an undefined figure is null), indented."""
    return strict_json.dumps(obj, indent=1) + "\n"


def write_json_atomically(path: str, obj: Any) -> None:
    """Replace *path*, a file of a directory radarodom writes (capture.json, index.json), with
    *obj* as JSON through ``path.tmp``, a name its directory's owner knows: a reader (or a crash)
    never sees half a file."""
    tmp = path + ".tmp"
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(json_text(obj))
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):  # a full disk: no empty .tmp left beside the file
            os.remove(tmp)
        raise


def _new_file(path: str) -> int:
    """A new file of the capture, opened for appending without buffering."""
    return os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_APPEND, 0o644)



class CaptureWriter:
    """Append frames to a new capture directory.

    Use as a context manager; :meth:`close` marks the capture as closed in
    capture.json.  Refuses a directory that already holds a recording, or files of a
    recording's names that radarodom did not write (:mod:`.recording_dir`), before writing anything.
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
        self.directory = given_path(directory, CaptureError)
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
        claimed = False
        self._data_fd = self._ts_fd = self._gt_fd = None
        try:
            self._made_directory = not os.path.isdir(self.directory)
            os.makedirs(self.directory, exist_ok=True)
            claim_recording_directory(self.directory)
            claimed = True  # from here on, what is in the directory is this recording's
            # capture.json first: whatever a run killed from here on leaves is then known to be
            # a recording's, which the next recording clears (one of no frame) or keeps.
            self._write_metadata()
            write_text_atomically(os.path.join(self.directory, RADAR_CFG), config.to_text())
            # Unbuffered, each file's length counted: a frame whose writing fails is taken back
            # from all three, and nothing of it is left pending to be flushed at close.
            self._data_fd = _new_file(os.path.join(self.directory, ADC_DATA))
            self._ts_fd = _new_file(os.path.join(self.directory, TIMESTAMPS))
            self._ts_bytes = self._gt_bytes = 0
        except OSError as exc:  # the directory, or a file in it (exc.filename): why, and the fix
            failed = os.fsdecode(exc.filename) if isinstance(exc.filename, (str, bytes)) else self.directory
            if claimed:  # (the files are opened after the claim)
                abandon_recording(self.directory, self._made_directory, (self._data_fd, self._ts_fd))
            raise CaptureError(f"cannot create capture directory {self.directory}: "
                               f"{why_not_written(exc, failed)}") from None

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
        if not 0 <= cut_bytes <= missing_bytes <= self.frame_bytes:
            raise CaptureError(f"{cut_bytes} bytes cut at stop of a frame missing {missing_bytes} of "
                               f"{self.frame_bytes}")
        if self._closed:
            raise CaptureError(f"{self.directory}: the capture is closed")
        # The reader refuses such times, so recording them would lose the recording.
        try:
            timestamp = float(timestamp)
        except (TypeError, ValueError):
            raise CaptureError(f"{self.directory}: frame {self._frames}: timestamp {timestamp!r} is not a "
                               f"number") from None
        if not (math.isfinite(timestamp) and abs(timestamp) <= capture_check.TIMESTAMP_LIMIT_S):
            raise CaptureError(f"{self.directory}: frame {self._frames}: timestamp {timestamp!r} is not a finite "
                               f"time of at most {capture_check.TIMESTAMP_LIMIT_S:g} s; recording stops here")
        if self._last_ts is not None and not float(f"{timestamp:.9f}") > float(f"{self._last_ts:.9f}"):
            raise CaptureError(f"{self.directory}: frame {self._frames}: timestamp {timestamp:.9f} is not after "
                               f"the previous frame's {self._last_ts:.9f}; recording stops here")
        n = memoryview(raw).nbytes
        if n != self.frame_bytes:
            raise CaptureFormatError(f"frame of {n} bytes, the configuration needs {self.frame_bytes}")
        ts_line = f"{timestamp:.9f}\n".encode("ascii")
        gt_line = None if pose is None else format_tum_line(timestamp, pose[:3], pose[3:]).encode("ascii")
        try:
            write_file_all(self._data_fd, raw)
            write_file_all(self._ts_fd, ts_line)
            if gt_line is not None:
                if self._gt_fd is None:
                    self._gt_fd = _new_file(os.path.join(self.directory, GROUNDTRUTH))
                write_file_all(self._gt_fd, gt_line)
        except OSError as exc:
            # The frame's part is cut off again: what is left holds whole frames, and a full
            # disk gets the room back that closing the capture needs.
            for fd, length in ((self._data_fd, self._frames * self.frame_bytes), (self._ts_fd, self._ts_bytes),
                               (self._gt_fd, self._gt_bytes)):
                if fd is not None:
                    with contextlib.suppress(OSError):
                        os.ftruncate(fd, length)
            raise CaptureError(f"{self.directory}: writing frame {self._frames} failed: "
                               f"{why_not_written(exc, self.directory)}; {frames_kept(self._frames)}") from None
        self._ts_bytes += len(ts_line)
        self._gt_bytes += 0 if gt_line is None else len(gt_line)
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
            try:
                self._write_metadata()
            except OSError as exc:
                raise CaptureError(f"{self.directory}: writing capture.json after frame {index} failed: "
                                   f"{exc.strerror or exc}; the {self._frames} frames are kept") from None

    def _incomplete_unsaved(self) -> bool:
        return bool(self._incomplete) and self._incomplete[-1]["frame"] >= self._saved_frames

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
        """Mark the capture closed in capture.json; a capture of no frame (a radar that never
        started) is removed instead, so that the directory can take the next run."""
        if self._closed:
            return
        self._closed = True
        try:
            for fd in (self._data_fd, self._ts_fd, self._gt_fd):
                if fd is not None:
                    os.close(fd)
            if self._frames:
                self._write_closing_metadata()
                return
            remove_capture_files(self.directory)
            if self._made_directory:
                with contextlib.suppress(OSError):  # something else was put there: leave it
                    os.rmdir(self.directory)
            log.info("%s: no frame recorded; the capture directory was removed", self.directory)
        except OSError as exc:
            raise CaptureError(f"closing {self.directory} failed: {exc.strerror or exc}") from None

    def __enter__(self) -> "CaptureWriter":
        return self

    def __exit__(self, kind, value, tb) -> None:
        if kind is None:
            self.close()
            return
        try:  # the failure that stopped the recording is the one to report
            self.close()
        except CaptureError as exc:
            log.debug("closing the capture failed too: %s", exc)
            add_note(value, f"then {exc}")

    def _write_closing_metadata(self) -> None:
        """capture.json, closed; on a disk too full for its new copy, written over in place
        (a closed capture.json is hardly longer than the open one it replaces)."""
        try:
            self._write_metadata()
        except OSError:
            path = os.path.join(self.directory, METADATA)
            with open(path, "r+", encoding="utf-8") as fh:
                fh.write(json_text(self.metadata()))
                fh.truncate()
            log.warning("%s: the disk is full: capture.json was written over in place", self.directory)
