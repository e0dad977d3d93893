"""The capture loop: frames from a source, optionally recorded, with counts.

:func:`run_capture` is what ``radar-capture`` runs; it holds no user
interface.  It stops at the end of the source, after ``max_frames`` frames or
``max_duration_s`` of stream time, or when ``source.stop()`` is called (a
signal handler does that); the recording is closed in every case.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Callable

from .capture_dir import CaptureWriter
from .sources import Frame, Source

log = logging.getLogger(__name__)

_DURATION_TOLERANCE_S = 1e-6


@dataclass
class CaptureStats:
    """What a capture run did."""

    frames: int = 0
    incomplete_frames: int = 0
    #: Zero-filled bytes of the frames streamed; of them, ``cut_bytes`` were never sent before
    #: the stream stopped, the rest were lost on the way (:attr:`lost_bytes`).
    missing_bytes: int = 0
    cut_bytes: int = 0
    first_timestamp: float | None = None
    last_timestamp: float | None = None
    started_monotonic: float = field(default_factory=time.monotonic)
    elapsed_s: float = 0.0
    #: Why the run ended: "end of source", "frame limit", "duration limit", "stopped".
    reason: str = ""

    @property
    def lost_bytes(self) -> int:
        return self.missing_bytes - self.cut_bytes

    @property
    def stream_duration_s(self) -> float:
        if self.first_timestamp is None or self.last_timestamp is None:
            return 0.0
        return self.last_timestamp - self.first_timestamp

    #: Wall time (monotonic) of the first and the last frame.
    first_frame_monotonic: float | None = None
    last_frame_monotonic: float | None = None

    @property
    def mean_rate_hz(self) -> float:
        """Frames per second of wall time between the first and the last frame."""
        if self.frames < 2 or self.first_frame_monotonic is None:
            return 0.0
        span = self.last_frame_monotonic - self.first_frame_monotonic
        return (self.frames - 1) / span if span > 0 else 0.0


def run_capture(
    source: Source,
    *,
    writer: CaptureWriter | None = None,
    max_frames: int | None = None,
    max_duration_s: float | None = None,
    on_frame: Callable[[Frame, CaptureStats], None] | None = None,
) -> CaptureStats:
    """Stream *source* until it ends or a limit is reached; record to *writer*.

    ``max_duration_s`` counts stream time (frame timestamps from the first
    frame), so a replay at ``rate=max`` records the same span as in real time.
    The writer is closed before returning or raising.
    """
    stats = CaptureStats()
    stats.reason = "end of source"
    try:
        for frame in source:
            # The tolerance keeps 1000.15 - 1000.0 (= 0.14999...) from counting as
            # short of 0.15 s; timestamps are only kept to the nanosecond anyway.
            if max_duration_s is not None and stats.first_timestamp is not None and \
                    frame.timestamp - stats.first_timestamp >= max_duration_s - _DURATION_TOLERANCE_S:
                stats.reason = "duration limit"
                break
            if writer is not None:
                writer.write(frame.raw, frame.timestamp, frame.missing_bytes, frame.pose,
                             cut_bytes=frame.cut_bytes)
            stats.frames += 1
            if frame.missing_bytes:
                stats.incomplete_frames += 1
                stats.missing_bytes += frame.missing_bytes
                stats.cut_bytes += frame.cut_bytes
            if stats.first_timestamp is None:
                stats.first_timestamp = frame.timestamp
            stats.last_timestamp = frame.timestamp
            now = time.monotonic()
            if stats.first_frame_monotonic is None:
                stats.first_frame_monotonic = now
            stats.last_frame_monotonic = now
            stats.elapsed_s = now - stats.started_monotonic
            if on_frame is not None:
                on_frame(frame, stats)
            if max_frames is not None and stats.frames >= max_frames:
                stats.reason = "frame limit"
                break
        if source.stop_requested:
            stats.reason = "stopped"
    finally:
        stats.elapsed_s = time.monotonic() - stats.started_monotonic
        if writer is not None:
            dropped = source.describe().get("frames_dropped")
            if dropped is not None:  # a live stream: the recording lacks the frames it dropped
                writer.annotate(dropped_frames=dropped)
            writer.close()
    log.debug("capture ended (%s) after %d frames", stats.reason, stats.frames)
    return stats
