"""What a pipeline run did, kept as it goes: frames and their missing bytes, stream and wall
time, the frame rate, end-to-end latency, the estimator's time per frame and its last state."""

from __future__ import annotations

import collections
import time
from dataclasses import dataclass, field

from ..errors import UsageError
from ..plain_numbers import is_number
from ..estimator.odometry import OdometryState


class RateMeter:
    """Events per second over a sliding window of wall time."""

    def __init__(self, window_s: float = 2.0) -> None:
        self.window = window_s
        self._times: collections.deque[float] = collections.deque()

    def tick(self, now: float | None = None) -> None:
        now = time.monotonic() if now is None else now
        self._times.append(now)
        while self._times and now - self._times[0] > self.window:
            self._times.popleft()

    @property
    def rate_hz(self) -> float:
        if len(self._times) < 2:
            return 0.0
        span = self._times[-1] - self._times[0]
        return (len(self._times) - 1) / span if span > 0 else 0.0


class LatencyMeter:
    """Recent latencies (s) and their percentiles, over the last *size* samples."""

    def __init__(self, size: int = 300) -> None:
        self._values: collections.deque[float] = collections.deque(maxlen=size)
        self.count = 0

    def add(self, seconds: float) -> None:
        self._values.append(seconds)
        self.count += 1

    def percentiles_ms(self, *qs: float) -> tuple[float, ...]:
        """The *qs* percentiles (0-100) of the recent latencies, ms; NaN when there are none."""
        for q in qs:
            if not is_number(q) or not 0 <= q <= 100:
                raise UsageError(f"a percentile is a number from 0 to 100, got {q!r}")
        if not self._values:
            return tuple(float("nan") for _ in qs)
        values = sorted(self._values)
        last = len(values) - 1
        return tuple(1e3 * values[min(last, int(round(q / 100.0 * last)))] for q in qs)


@dataclass
class PipelineStats:
    """What a run did so far (updated frame by frame) and, at its end, why it ended."""

    frames: int = 0
    #: Of ``frames``, those every sink took (a frame whose writing failed, a full disk, is counted
    #: in ``frames`` only): an output file of a run with none holds no whole frame.
    frames_written: int = 0
    incomplete_frames: int = 0
    #: Zero-filled bytes of the frames streamed; of them, ``cut_bytes`` were never sent before
    #: the stream stopped, the rest were lost on the way (:attr:`lost_bytes`).
    missing_bytes: int = 0
    cut_bytes: int = 0
    #: Stream time (s) of the first and the last frame.
    first_timestamp: float | None = None
    last_timestamp: float | None = None
    started_monotonic: float = field(default_factory=time.monotonic)
    #: Wall time (monotonic) of the first and the last frame.
    first_frame_monotonic: float | None = None
    last_frame_monotonic: float | None = None
    elapsed_s: float = 0.0
    #: Why the run ended: "end of source", "frame limit", "duration limit", "stopped".
    reason: str = ""
    #: Frames per second over the last two seconds of wall time.
    rate: RateMeter = field(default_factory=RateMeter)
    #: Each frame's end-to-end latency: from ``Frame.ready_monotonic`` (its last packet, or its
    #: making or reading) until every sink has been given its products and odometry.
    latency: LatencyMeter = field(default_factory=LatencyMeter)
    #: The estimator's time per heatmap frame (``OdometryState.compute_s``), s, recent ones.
    estimator_s: collections.deque = field(default_factory=lambda: collections.deque(maxlen=1000))
    #: The latest odometry (None before the first heatmap frame, or without an estimator).
    state: OdometryState | None = None
    #: The frame the source gave past the duration limit (a frame's time is known once it is
    #: read), not streamed: its bytes lost on the way, which a live source's accounting holds.
    unstreamed_lost_bytes: int = 0

    @property
    def lost_bytes(self) -> int:
        return self.missing_bytes - self.cut_bytes

    @property
    def stream_duration_s(self) -> float:
        if self.first_timestamp is None or self.last_timestamp is None:
            return 0.0
        return self.last_timestamp - self.first_timestamp

    @property
    def mean_rate_hz(self) -> float:
        """Frames per second of wall time between the first and the last frame."""
        if self.frames < 2 or self.first_frame_monotonic is None:
            return 0.0
        span = self.last_frame_monotonic - self.first_frame_monotonic
        return (self.frames - 1) / span if span > 0 else 0.0

    def count(self, timestamp: float, missing_bytes: int, cut_bytes: int) -> None:
        """One more frame, taken at stream time *timestamp*, with its missing bytes."""
        self.frames += 1
        if missing_bytes:
            self.incomplete_frames += 1
            self.missing_bytes += missing_bytes
            self.cut_bytes += cut_bytes
        if self.first_timestamp is None:
            self.first_timestamp = timestamp
        self.last_timestamp = timestamp
        now = time.monotonic()
        if self.first_frame_monotonic is None:
            self.first_frame_monotonic = now
        self.last_frame_monotonic = now
        self.elapsed_s = now - self.started_monotonic
