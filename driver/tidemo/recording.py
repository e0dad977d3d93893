"""Recording the demo's UART stream: a directory ``replay://DIR`` plays again.

Layout::

    DIR/radar.cfg       the cfg the radar was given (as the user wrote it)
    DIR/uart.bin        the whole packets as received, back to back (a serial logger's file
                        without what the framer discarded)
    DIR/timestamps.txt  one line per frame *number* from the first packet's to the last's: the
                        time (s) of the frame's first chirp; a frame lost on the line keeps its
                        line (between its neighbours' times), so that line k is frame number
                        first + k, as for a serial logger's file (docs/tidemo.md)
    DIR/capture.json    format "radarodom-tidemo" version 1, source, baud, frame and packet
                        counts, first and last timestamp, closed

:class:`UartRecorder` is a pipeline sink that takes the frames as they came (``takes_raw``,
``write_raw(frame, stats)``, ``close(stats)``, as ``pipeline.CaptureSink``) and records each one's
:attr:`~radarodom.driver.sources.Frame.wire` bytes; :meth:`UartRecorder.write_packet` is the same
without the pipeline.  Every packet goes to the kernel before the next, and
capture.json is replaced atomically, as the raw recorder does.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import time
from typing import Any

from ... import __version__
from ...cfg import RadarConfig
from ...errors import CaptureError, why_not_written
from ...line_file import write_file_all
from ...whole_files import write_text_atomically
from ..recordings.capture_check import TIDEMO_FORMAT_NAME
from ..recordings.capture_dir import write_json_atomically
from ..recordings.recording_dir import abandon_recording, claim_recording_directory, frames_kept

log = logging.getLogger(__name__)

UART_DATA = "uart.bin"
TIMESTAMPS = "timestamps.txt"
METADATA = "capture.json"
RADAR_CFG = "radar.cfg"
FORMAT_NAME = TIDEMO_FORMAT_NAME
FORMAT_VERSION = 1


class UartRecorder:
    """Records a ``tidemo://`` stream's packets into a new directory; see the module docstring."""

    #: A pipeline sink that takes each frame as the source gave it (pipeline.Sink.takes_raw).
    takes_raw = True
    wants_heatmaps = False
    full_heatmaps = False

    def __init__(self, directory: str | os.PathLike, config: RadarConfig, *, source: str = "",
                 baud: int | None = None) -> None:
        self.directory = os.fspath(directory)
        self._meta: dict[str, Any] = {"format": FORMAT_NAME, "format_version": FORMAT_VERSION,
                                      "software": f"radarodom {__version__}", "source": source, "baud": baud,
                                      "start_time_unix": time.time(), "packets": 0, "frame_lines": 0,
                                      "first_timestamp": None, "last_timestamp": None, "closed": False}
        self._last: tuple[int, float] | None = None  # (index, timestamp) of the last packet
        self._closed = False
        data = os.path.join(self.directory, UART_DATA)
        claimed = False
        self._fd = self._ts = None
        try:
            self._made_directory = not os.path.isdir(self.directory)
            os.makedirs(self.directory, exist_ok=True)
            claim_recording_directory(self.directory)
            claimed = True  # from here on, what is in the directory is this recording's
            self._save()  # first: the files written next are then known to be a recording's
            write_text_atomically(os.path.join(self.directory, RADAR_CFG), config.to_text())
            # Unbuffered, each file's length counted: a packet whose writing fails is taken back.
            self._fd = os.open(data, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o644)
            self._ts = os.open(os.path.join(self.directory, TIMESTAMPS), os.O_WRONLY | os.O_CREAT | os.O_TRUNC
                               | os.O_APPEND, 0o644)
            self._bytes = self._ts_bytes = 0
        except OSError as exc:  # the directory, or a file in it (exc.filename)
            failed = os.fsdecode(exc.filename) if isinstance(exc.filename, (str, bytes)) else self.directory
            if claimed:  # (the files are opened after the claim)
                abandon_recording(self.directory, self._made_directory, (self._fd, self._ts))
            raise CaptureError(f"cannot create recording directory {self.directory}: "
                               f"{why_not_written(exc, failed)}") from None

    # A pipeline sink taking the frames as they came (before any processing).
    def write_raw(self, frame, stats) -> None:
        if frame.wire is None:
            raise CaptureError(f"frame {frame.index} carries no UART packet to record")
        self.write_packet(frame.wire, frame.index, frame.timestamp)

    def close(self, stats=None) -> None:
        """Mark the recording closed; one without a packet is removed."""
        if self._closed:
            return
        self._closed = True
        try:
            os.close(self._fd)
            os.close(self._ts)
            if self._meta["packets"]:
                self._meta["closed"] = True
                self._save()
                return
            for name in (UART_DATA, TIMESTAMPS, METADATA, RADAR_CFG):
                with contextlib.suppress(FileNotFoundError):
                    os.remove(os.path.join(self.directory, name))
            if self._made_directory:
                with contextlib.suppress(OSError):
                    os.rmdir(self.directory)
        except OSError as exc:
            raise CaptureError(f"closing {self.directory} failed: {exc.strerror or exc}") from None

    def write_packet(self, data: bytes, index: int, timestamp: float) -> None:
        """Append one packet, the frame's *index* in the stream (its frame number from the first)
        and the time of its first chirp; lines for the frame numbers skipped since the last."""
        if self._closed:
            raise CaptureError(f"{self.directory}: the recording is closed")
        timestamp = float(timestamp)
        lines = [timestamp]
        if self._last is not None:
            last_index, last_t = self._last
            if index <= last_index or not timestamp > last_t or not math.isfinite(timestamp):
                raise CaptureError(f"{self.directory}: frame {index} at {timestamp!r} s does not follow frame "
                                   f"{last_index} at {last_t:.9f} s; recording stops here")
            step = (timestamp - last_t) / (index - last_index)
            lines = [last_t + step * k for k in range(1, index - last_index)] + lines
        text = "".join(f"{t:.9f}\n" for t in lines).encode("ascii")
        try:
            write_file_all(self._fd, data)
            write_file_all(self._ts, text)
        except OSError as exc:  # a full disk: the packet's part taken back, the recording whole
            for fd, length in ((self._fd, self._bytes), (self._ts, self._ts_bytes)):
                with contextlib.suppress(OSError):
                    os.ftruncate(fd, length)
            raise CaptureError(f"{self.directory}: writing frame {index}'s packet failed: "
                               f"{why_not_written(exc, self.directory)}; {frames_kept(self._meta['packets'])}"
                               ) from None
        self._bytes += len(data)
        self._ts_bytes += len(text)
        self._last = (index, timestamp)
        meta = self._meta
        meta["packets"] += 1
        meta["frame_lines"] += len(lines)
        meta["first_timestamp"] = meta["first_timestamp"] if meta["first_timestamp"] is not None else timestamp
        meta["last_timestamp"] = timestamp
        if meta["packets"] % 10 == 1:
            self._save()

    def _save(self) -> None:
        write_json_atomically(os.path.join(self.directory, METADATA), self._meta)
