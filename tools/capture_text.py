"""What radar-capture says of a run: the live status line's fields and the summary at its end
(the frames, the bytes missing and why, the odometry, what a live or serial stream lost)."""

from __future__ import annotations

import argparse
import math
import os

import numpy as np

from ..driver.sources import Source
from ..pipeline import PipelineStats
from .status import Field, fit_fields, format_duration, format_yaw, wrap_degrees


def status_fields(stats: PipelineStats, recording: bool, source: Source) -> list[Field]:
    """The live status line's fields, the most important with priority 1 (:func:`fit_fields`
    drops the others first on a narrow terminal)."""
    fields = [Field(f"frames {stats.frames}", priority=2),
              Field(f"rate {stats.rate.rate_hz:5.1f} Hz", f"{stats.rate.rate_hz:.1f} Hz", 3),
              Field(f"incomplete {stats.incomplete_frames}", f"inc {stats.incomplete_frames}",
                    2 if stats.incomplete_frames else 4),
              Field(f"elapsed {format_duration(stats.elapsed_s)}", format_duration(stats.elapsed_s), 6)]
    live = source.describe()
    if "frames_dropped" in live:  # a live capture: why frames are incomplete or missing
        fields += [Field(f"dropped {live['frames_dropped']}", priority=2 if live["frames_dropped"] else 4),
                   Field(f"lost packets {live['packets_lost']}", f"lost {live['packets_lost']}",
                         2 if live["packets_lost"] else 4)]
        for key, name in (("truncated_packets", "truncated"), ("late_packets", "late")):
            if live.get(key):
                fields.append(Field(f"{name} {live[key]}", priority=4))
    if recording:
        fields.append(Field("[rec]", priority=2))
    return fields


def status_text(stats: PipelineStats, recording: bool, source: Source, width: int | None = None) -> str:
    """The live status line fitted into *width* columns (None: whole, for a log)."""
    return fit_fields(status_fields(stats, recording, source) + odometry_fields(stats), width)


def missing_text(stats: PipelineStats) -> str:
    """"3 incomplete, 4368 bytes missing: 2912 lost on the way, 1456 cut at stop"."""
    text = f"{stats.incomplete_frames} incomplete, {stats.missing_bytes} bytes missing"
    causes = [f"{n} {cause}" for n, cause in ((stats.lost_bytes, "lost on the way"),
                                              (stats.cut_bytes, "cut at stop")) if n]
    return text + (": " + ", ".join(causes) if causes else "")


def summary(stats: PipelineStats, record: str | None, recorded: int | None = None) -> str:
    """The frames streamed and why the run ended; with *record*, where they were recorded, and how
    many of them when that is fewer (*recorded*: a recording a failed write ended), or that nothing
    was where the directory is not there (a run stopped before its first frame takes its empty
    recording with it)."""
    rate = f"{stats.mean_rate_hz:.1f} Hz, " if stats.frames >= 2 else ""  # one frame has no rate (was "0.0 Hz")
    text = (f"{stats.frames} frame{'' if stats.frames == 1 else 's'} ({missing_text(stats)}) in "
            f"{stats.elapsed_s:.1f} s, {rate}{stats.stream_duration_s:.2f} s of stream; {stats.reason}")
    if record and not os.path.isdir(record):
        text += f"; nothing recorded ({record} not made)"
    elif record:
        some = f" {recorded} of them" if recorded is not None and recorded != stats.frames else ""
        text += f"; recorded{some} to {record}"
    return text


def recorded_frames(sinks) -> int | None:
    """The frames the run's capture directory holds (None without one)."""
    for sink in sinks:
        count = getattr(getattr(sink, "writer", None), "frame_count", None)
        if isinstance(count, int):
            return count
    return None


def stream_summary(args: argparse.Namespace, source: Source, stats: PipelineStats, sinks=()) -> str:
    """The frames, the odometry and what the stream lost (a live source's or a serial stream's
    accounting); *sinks*: the run's, for the frames its recording holds."""
    live = source.describe()
    text = (summary(stats, args.record, recorded_frames(sinks))
            + odometry_summary(stats, None if args.no_odom else args.odom_out))
    if "frames_dropped" in live:
        text += live_summary(live, stats)
    elif "discarded_bytes" in live:  # a serial stream (tidemo://, its replay): what the framer lost
        text += (f"; {_counted(live['frames_skipped'], 'frame number')} skipped, "
                 f"{_counted(live['rejected_packets'], 'packet')} rejected, "
                 f"{_counted(live['discarded_bytes'], 'byte')} discarded")
        if live.get("over_budget"):
            text += (f", {_counted(live['over_budget'], 'packet')} over max_points={live['max_points']} (the UART "
                     "budget's; give a larger one)")
    return text + files_text(args, stats)


def files_text(args: argparse.Namespace, stats: PipelineStats) -> str:
    """Where the point clouds, heatmaps and odometry messages were written (the recording, the
    trajectory, the ROS 2 bag and the view say it in their own parts); nothing without a frame,
    whose files are removed."""
    named = [(what, path) for what, path in (("point clouds", getattr(args, "points_out", None)),
                                             ("heatmaps", getattr(args, "heatmap_out", None)),
                                             ("odometry messages", getattr(args, "odom_json", None))) if path]
    if not named or not stats.frames:
        return ""
    return "; " + ", ".join(f"{what} in {path}" for what, path in named)


def _counted(n: int, thing: str) -> str:
    """"1 packet", "2 packets"."""
    return f"{n} {thing}{'' if n == 1 else 's'}"


def live_summary(live: dict, stats: PipelineStats) -> str:
    """Where a live stream's frames and packets went (describe()'s accounting), and any missing
    bytes the packet headers do not account for."""
    tail = live.get("tail_packets_lost", 0)
    text = (f"; {live['frames_dropped']} frames dropped by slow processing, {live['packets_lost']} packets "
            f"lost (sequence gaps{f', {tail} after the last received' if tail else ''}), "
            f"{live['truncated_packets']} truncated and {live['late_packets']} late "
            f"of {live['packets']} received; {live['duplicate_packets']} duplicate, {live['foreign_packets']} "
            f"foreign and {live['malformed_packets']} malformed packets ignored")
    if live.get("stale_packets"):
        text += f"; {live['stale_packets']} packets of an earlier recording ignored (a board left streaming)"
    headers = live.get("lost_bytes")
    counted = stats.lost_bytes + stats.unstreamed_lost_bytes
    if headers is not None and headers != counted:
        text += (f"; of the bytes missing, the packet headers account for {headers} lost on the way, "
                 f"not {counted} (see docs/live.md)")
    return text


def odometry_fields(stats: PipelineStats) -> list[Field]:
    st = stats.state
    if st is None:
        return []
    p50, p99 = stats.latency.percentiles_ms(50, 99)
    fields = [Field(f"x {st.x:6.2f} y {st.y:6.2f} m", f"x {st.x:.2f} y {st.y:.2f} m", 1),
              Field(f"yaw {format_yaw(st.yaw)}", f"yaw {wrap_degrees(math.degrees(st.yaw)):.1f} deg", 1),
              Field(f"v {st.vx:5.2f} m/s", f"v {st.vx:.2f} m/s", 3),
              Field(f"latency {p50:.0f}/{p99:.0f} ms", f"{p50:.0f}/{p99:.0f} ms", 5)]
    if not st.ok:
        flags = [str(flag) for flag in st.flags]
        short = f"[{flags[0]},+{len(flags) - 1}]" if len(flags) > 1 else None
        fields.append(Field("[" + ",".join(flags) + "]", short, 1))  # the estimate is off: say so
    return fields


def odometry_summary(stats: PipelineStats, odom_out: str | None) -> str:
    st = stats.state
    if st is None:
        return ""
    p50, p99 = stats.latency.percentiles_ms(50, 99)
    text = (f"; odometry: x {st.x:.2f} m, y {st.y:.2f} m, yaw {format_yaw(st.yaw)}, "
            f"estimator median {1e3 * float(np.median(stats.estimator_s)):.1f} ms/frame")
    if stats.latency.count:  # none when the first frame's outputs failed
        text += f", latency p50 {p50:.1f} ms, p99 {p99:.1f} ms"
    if odom_out:
        text += f", trajectory in {odom_out}"
    return text
