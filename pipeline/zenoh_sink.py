"""The pipeline's results over Zenoh: odometry, point clouds, heatmaps, and a status message
about once a second (rates, drops, losses, latency, the source's state)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..driver.sources import Source
from ..publish import Publisher
from .sinks import FrameResult, Sink
from .stats import PipelineStats


class PublisherSink(Sink):
    """Publishes each frame's odometry first, then its point cloud and heatmap (bulky, at low
    priority), and a status message every *status_period_s* and once more at the end.  The
    publisher stays the caller's to close."""

    wants_heatmaps = True

    def __init__(self, publisher: Publisher, source: Source, *, status_period_s: float = 1.0) -> None:
        self.publisher = publisher
        self.source = source
        self.period = status_period_s
        self._next = time.monotonic() + status_period_s

    def write(self, result: FrameResult, stats: PipelineStats) -> None:
        frame = result.frame
        if result.state is not None:
            self.publisher.odometry(result.state)
        if result.points is not None:
            self.publisher.pointcloud(frame.index, frame.timestamp, result.points)
        if result.heatmap is not None:
            self.publisher.heatmap(frame.index, frame.timestamp, result.heatmap)
        now = time.monotonic()
        if now >= self._next:
            self._next = now + self.period
            self.publisher.status(status(stats, self.source, running=True))

    def close(self, stats: PipelineStats) -> None:
        self.publisher.status(status(stats, self.source, running=False))


def status(stats: PipelineStats, source: Source, *, running: bool) -> dict[str, Any]:
    """The status message's content (messages.py documents the schema)."""
    info: dict[str, Any] = {
        "time": time.time(), "running": running, "frames": stats.frames, "rate_hz": round(stats.rate.rate_hz, 2),
        "incomplete_frames": stats.incomplete_frames, "missing_bytes": stats.missing_bytes,
        "lost_bytes": stats.lost_bytes, "cut_bytes": stats.cut_bytes, "stream_s": round(stats.stream_duration_s, 3)}
    live = source.describe()
    info["frames_dropped"] = live.get("frames_dropped", 0)
    info["packets_lost"] = live.get("packets_lost", 0)
    info["source"] = {k: v for k, v in live.items() if _plain(v)}  # radar and board state
    p50, p90, p99, worst = stats.latency.percentiles_ms(50, 90, 99, 100)
    info["latency_ms"] = {"p50": p50, "p90": p90, "p99": p99, "max": worst}
    if stats.estimator_s:
        info["estimator_ms"] = 1e3 * float(np.median(stats.estimator_s))
    st = stats.state
    if st is not None:
        info["odometry"] = {"ok": st.ok, "flags": list(st.flags), "frame": st.frame}
    return info


def _plain(value: Any) -> bool:
    """JSON-ready: a scalar, or a dict of scalars (the board's status counts)."""
    if isinstance(value, dict):
        return all(isinstance(k, str) and _plain(v) and not isinstance(v, dict) for k, v in value.items())
    return value is None or isinstance(value, (str, int, float, bool))
