"""radar-capture: stream radar frames from a source, run the DSP and the odometry
on them, show a live status, record.

    radar-capture --source replay://DIR [--cfg FILE] [--record OUT] [--odom-out FILE.tum]
                  [--frames N] [--duration S] [--no-odom]

Ctrl-C (or SIGTERM) stops after the current frame and closes the recording;
a second Ctrl-C aborts at once (what was written stays readable).
"""

from __future__ import annotations

import os

# One BLAS thread: the DSP's matrix products are small, and OpenBLAS threads spin and stall
# when the other core is busy with capture (measured: 14 ms instead of 0.2 ms per product).
# Set before numpy loads; an explicit setting in the environment wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402  (after the BLAS setting)
import collections
import contextlib
import logging
import math
import signal
import sys
import time

import numpy as np
from typing import Iterator, Sequence

from ..cfg import RadarConfig
from ..driver.capture import CaptureStats, run_capture
from ..driver.capture_dir import CaptureWriter
from ..driver.sources import SCHEMES, Frame, Source, open_source
from ..errors import CaptureError, UsageError
from ..estimator.config import EstimatorConfig
from . import cli
from .status import LatencyMeter, RateMeter, StatusLine, format_duration
from .zenoh_args import add_zenoh_arguments


log = logging.getLogger("radarodom.tools.radar_capture")

#: What runs when no source is given and no radar is attached.
DEFAULT_SIM_URL = "sim://corridor"


def _default_source() -> str:
    """The live radar when one is plugged in (standard addresses), else the simulator."""
    from ..driver.discovery import default_cli_port, no_radar_message

    port = default_cli_port()
    if port is not None:
        log.info("radar found on %s: streaming it through the DCA1000 at the standard addresses", port)
        return f"dca1000://?cli={port}"
    log.warning("%s. Streaming the simulator meanwhile: %s (choose a source with --source)",
                no_radar_message(), DEFAULT_SIM_URL)
    return DEFAULT_SIM_URL


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radar-capture",
        description="Stream raw radar frames from a source, run the DSP and the odometry on every "
                    "frame, publish them over Zenoh, show a live status, and optionally record the frames "
                    "to a capture directory.",
        epilog="Sources: replay://DIR[?rate=1.0|max&loop=N&start=K|Ss&frames=N] plays a capture "
               "directory or TI recorder files (with --cfg); sim://SCENE[?seed=N&rate=1.0|max&duration=S] "
               "simulates a scene (corridor, room, lab, calibration, or a .toml/.json file). "
               "dca1000://[BOARD_IP][?cli=PORT&host=IP&delay=US&policy=latest|queue] streams the live "
               "radar. coloradar://RUN_DIR[?velocity=single_chip|single_chip_adc&heatmap=cascade|single_chip|"
               "single_chip_adc&rate=1.0|max&start=S&calib=DIR] plays a ColoRadar run. Without --source: the live radar when one is plugged in, else "
               f"{DEFAULT_SIM_URL}.")
    parser.add_argument("--cfg", metavar="FILE",
                        help="radar configuration (TI .cfg); for replay:// of a capture directory "
                             "it defaults to the directory's radar.cfg")
    parser.add_argument("--source", metavar="URL",
                        help=f"frame source ({', '.join(s + '://' for s in sorted(SCHEMES))}; default: "
                             f"the live radar if one is plugged in, else {DEFAULT_SIM_URL})")
    parser.add_argument("--record", metavar="DIR", help="record the frames to this new capture directory")
    parser.add_argument("--points-out", metavar="FILE.csv",
                        help="run the DSP and write every frame's point cloud to this new CSV file")
    parser.add_argument("--heatmap-out", metavar="DIR",
                        help="run the DSP and write every frame's range-azimuth heatmaps (.npy) here")
    parser.add_argument("--odom-out", metavar="FILE.tum",
                        help="write the odometry (body frame in the first frame's, one TUM line per frame) "
                             "to this new file")
    parser.add_argument("--no-odom", action="store_true",
                        help="do not run the estimator (capture, record and DSP exports only)")
    parser.add_argument("--estimator-config", metavar="FILE.json",
                        help="estimator settings (JSON, as EstimatorConfig.dump writes; default: the built-in ones)")
    parser.add_argument("--no-publish", action="store_true",
                        help="do not publish over Zenoh (offline runs and evaluation)")
    add_zenoh_arguments(parser, ros2=True)
    parser.add_argument("--frames", type=cli.positive_int, metavar="N", help="stop after N frames")
    parser.add_argument("--duration", type=cli.positive_float, metavar="S",
                        help="stop after S seconds of stream time")
    cli.add_verbosity(parser)
    return parser


@contextlib.contextmanager
def _stop_on_signals(source: Source) -> Iterator[None]:
    """First SIGINT/SIGTERM: ask the source to stop after the current frame.
    Second: abort now (KeyboardInterrupt)."""
    received = 0

    def handler(signum, frame):
        nonlocal received
        received += 1
        if received > 1:
            raise KeyboardInterrupt
        source.stop()

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _status_text(stats: CaptureStats, rate: RateMeter, recording: bool, source: Source) -> str:
    text = (f"frames {stats.frames}  rate {rate.rate_hz:5.1f} Hz  incomplete {stats.incomplete_frames}"
            f"  elapsed {format_duration(stats.elapsed_s)}")
    live = source.describe()
    if "frames_dropped" in live:  # a live capture: why frames are incomplete or missing
        text += f"  dropped {live['frames_dropped']}  lost packets {live['packets_lost']}"
        for key, name in (("truncated_packets", "truncated"), ("late_packets", "late")):
            if live.get(key):
                text += f"  {name} {live[key]}"
    return text + ("  [rec]" if recording else "")


def _missing_text(stats: CaptureStats) -> str:
    """"3 incomplete, 4368 bytes missing: 2912 lost on the way, 1456 cut at stop"."""
    text = f"{stats.incomplete_frames} incomplete, {stats.missing_bytes} bytes missing"
    causes = [f"{n} {cause}" for n, cause in ((stats.lost_bytes, "lost on the way"),
                                              (stats.cut_bytes, "cut at stop")) if n]
    return text + (": " + ", ".join(causes) if causes else "")


def _summary(stats: CaptureStats, record: str | None) -> str:
    text = (f"{stats.frames} frame{'' if stats.frames == 1 else 's'} ({_missing_text(stats)}) in "
            f"{stats.elapsed_s:.1f} s, {stats.mean_rate_hz:.1f} Hz, {stats.stream_duration_s:.2f} s of stream; "
            f"{stats.reason}")
    if record:
        text += f"; recorded to {record}"
    return text


def _live_summary(live: dict) -> str:
    """Where a live stream's frames and packets went (describe()'s accounting)."""
    return (f"; {live['frames_dropped']} frames dropped by slow processing, {live['packets_lost']} packets "
            f"lost (sequence gaps), {live['truncated_packets']} truncated and {live['late_packets']} late "
            f"of {live['packets']} received; {live['duplicate_packets']} duplicate, {live['foreign_packets']} "
            f"foreign and {live['malformed_packets']} malformed packets ignored")


class _Processing:
    """The per-frame DSP and estimator, and the files they write (--points-out,
    --heatmap-out, --odom-out)."""

    def __init__(self, source: Source, args: argparse.Namespace, outputs: contextlib.ExitStack,
                 publisher=None) -> None:
        from ..estimator.odometry import RadarOdometry
        from ..products import FrameProducts
        from ..tum import TumWriter
        from .exports import HeatmapWriter, PointsCsvWriter

        # Check every destination before writing to any, so a refusal leaves nothing behind.
        for path in (args.points_out, args.odom_out if not args.no_odom else None, args.heatmap_out):
            if path:
                cli.check_new_path(path, is_dir=path == args.heatmap_out)
        estimator_cfg = args.estimator
        # The heatmap export gets the full map; the estimator needs less.
        self.products = (FrameProducts(source.config, coupling=source.coupling, calibrated=source.calibrated)
                         if args.heatmap_out
                         else FrameProducts.for_estimator(source.config, estimator_cfg.features.k,
                                                          coupling=source.coupling, calibrated=source.calibrated))
        self.odometry = None if args.no_odom else RadarOdometry(estimator_cfg)
        self.state = None
        # Recent figures only: a sensor node runs for days.
        self.estimator_s: collections.deque[float] = collections.deque(maxlen=1000)
        self.latency = LatencyMeter()
        self.heatmap_out = HeatmapWriter(args.heatmap_out) if args.heatmap_out else None
        self.points_out = PointsCsvWriter(args.points_out) if args.points_out else None
        self.odom_out = TumWriter(args.odom_out) if args.odom_out and self.odometry else None
        for writer in (self.heatmap_out, self.points_out, self.odom_out):
            if writer is not None:
                outputs.callback(writer.close)
        self.publisher = publisher

    def __call__(self, frame: Frame) -> None:
        wanted = self.heatmap_out is not None or self.odometry is not None or self.publisher is not None
        # A velocity-only frame of a two-stream source needs no heatmap for the odometry.
        products = self.products(frame, heatmap=wanted and (frame.role != "velocity" or self.heatmap_out is not None))
        points, heatmap = products.points, products.heatmap
        if points is not None and self.points_out is not None:
            self.points_out.write(frame.index, frame.timestamp, points)
        if heatmap is not None and self.heatmap_out is not None:
            self.heatmap_out.write(frame.index, frame.timestamp, heatmap)
        if self.odometry is not None:
            state = self._estimate(frame, points, heatmap)
            if state is not None:
                self.state = state
                self.estimator_s.append(state.compute_s)
                if self.publisher is not None:
                    self.publisher.odometry(state)
                if self.odom_out is not None:
                    self.odom_out.write(state.t, state.x, state.y, state.yaw)
        # End to end: the frame's last packet (or its making) -> its odometry out.
        self.latency.add(time.monotonic() - frame.ready_monotonic)
        if self.publisher is not None:  # the bulky messages after the odometry, at low priority
            if points is not None:
                self.publisher.pointcloud(frame.index, frame.timestamp, points)
            if heatmap is not None:
                self.publisher.heatmap(frame.index, frame.timestamp, heatmap)

    def _estimate(self, frame: Frame, points, heatmap):
        """Feed the frame to the estimator's stream(s) its role names; the new state, or None
        for a velocity-only frame (the pose moves on the heatmap frames)."""
        if frame.role == "velocity":
            if points is None:
                raise CaptureError(f"frame {frame.index}: a velocity frame without a point cloud")
            self.odometry.add_points(frame.timestamp, points)
            return None
        if heatmap is None:
            raise CaptureError(f"frame {frame.index}: a {frame.role} frame without a heatmap")
        if frame.role == "heatmap":
            return self.odometry.add_heatmap(frame.timestamp, heatmap)
        return self.odometry.step(frame.timestamp, points, heatmap)

    def status(self) -> str:
        st = self.state
        if st is None:
            return ""
        p50, p99 = self.latency.percentiles_ms(50, 99)
        return (f"  x {st.x:6.2f} y {st.y:6.2f} m yaw {math.degrees(st.yaw):6.1f} deg"
                f"  v {st.vx:5.2f} m/s  latency {p50:.0f}/{p99:.0f} ms"
                + ("" if st.ok else "  [" + ",".join(st.flags) + "]"))

    def summary(self) -> str:
        if self.state is None:
            return ""
        st = self.state
        p50, p99 = self.latency.percentiles_ms(50, 99)
        text = (f"; odometry: x {st.x:.2f} m, y {st.y:.2f} m, yaw {math.degrees(st.yaw):.1f} deg, "
                f"estimator median {1e3 * float(np.median(self.estimator_s)):.1f} ms/frame, "
                f"latency p50 {p50:.1f} ms, p99 {p99:.1f} ms")
        if self.odom_out is not None:
            text += f", trajectory in {self.odom_out.path}"
        return text


def _main(args: argparse.Namespace, status: StatusLine) -> int:
    status.enabled = not args.quiet
    if args.no_odom and (args.odom_out or args.estimator_config):
        raise UsageError("--no-odom turns the estimator off: it cannot also write --odom-out or "
                         "take --estimator-config")
    cfg = RadarConfig.from_file(args.cfg) if args.cfg else None
    # Read the estimator's settings before any hardware is touched.
    args.estimator = (EstimatorConfig.load(args.estimator_config) if args.estimator_config
                      else EstimatorConfig())
    if not args.source:
        args.source = _default_source()
    rate = RateMeter()

    with contextlib.ExitStack() as session:
        # The Zenoh session opens before the radar is touched, so a bad option costs nothing.
        publisher = None if args.no_publish else session.enter_context(_open_publisher(args))
        summary = _run(args, cfg, publisher, status, rate)
    print(f"radar-capture: {summary}")
    return 0


def _open_publisher(args: argparse.Namespace):
    from ..publish import Publisher
    from .zenoh_args import options_from_args

    return Publisher(options_from_args(args))


def _run(args: argparse.Namespace, cfg: RadarConfig | None, publisher, status: StatusLine, rate: RateMeter) -> str:
    with open_source(args.source, cfg) as source, contextlib.ExitStack() as outputs:
        if args.record and not source.carries_raw:
            raise UsageError(f"{args.source} gives point clouds and heatmaps, not raw ADC frames only: "
                             "--record needs a raw source (for ColoRadar: velocity=single_chip_adc"
                             "&heatmap=single_chip_adc)")
        needed = not args.no_odom or args.points_out or args.heatmap_out or publisher is not None
        process = _Processing(source, args, outputs, publisher) if needed else None
        reporter = None if publisher is None else _StatusReporter(publisher, source, process, rate)

        def on_frame(frame: Frame, stats: CaptureStats) -> None:
            if process is not None:
                process(frame)
            rate.tick()
            if reporter is not None:
                reporter.maybe_send(stats)
            status.update(_status_text(stats, rate, args.record is not None, source)
                          + (process.status() if process is not None else ""))

        writer = (CaptureWriter(args.record, source.config, source=args.source, extra=source.recording_metadata())
                  if args.record else None)
        with _stop_on_signals(source):
            try:
                stats = run_capture(source, writer=writer, max_frames=args.frames,
                                    max_duration_s=args.duration, on_frame=on_frame)
            finally:
                status.clear()
        if reporter is not None:
            reporter.send(stats, final=True)
        live = source.describe()
    summary = _summary(stats, args.record) + (process.summary() if process is not None else "")
    if "frames_dropped" in live:
        summary += _live_summary(live)
    if publisher is not None:
        counts = publisher.counts
        summary += (f"; published {counts['odom']} odometry, {counts['pointcloud']} point cloud, "
                    f"{counts['heatmap']} heatmap and {counts['status']} status messages under "
                    f"{publisher.options.key_prefix}")
    return summary


def _plain(value) -> bool:
    """JSON-ready: a scalar, or a dict of scalars (the board's status counts)."""
    if isinstance(value, dict):
        return all(isinstance(k, str) and _plain(v) and not isinstance(v, dict) for k, v in value.items())
    return value is None or isinstance(value, (str, int, float, bool))


class _StatusReporter:
    """Status messages about once a second: rates, drops, losses, latency, source state."""

    def __init__(self, publisher, source: Source, process: "_Processing | None", rate: RateMeter,
                 period_s: float = 1.0) -> None:
        self.publisher, self.source, self.process, self.rate = publisher, source, process, rate
        self.period = period_s
        self._next = time.monotonic() + period_s

    def maybe_send(self, stats: CaptureStats) -> None:
        now = time.monotonic()
        if now >= self._next:
            self._next = now + self.period
            self.send(stats)

    def send(self, stats: CaptureStats, final: bool = False) -> None:
        info = {"time": time.time(), "running": not final, "frames": stats.frames,
                "rate_hz": round(self.rate.rate_hz, 2), "incomplete_frames": stats.incomplete_frames,
                "missing_bytes": stats.missing_bytes, "lost_bytes": stats.lost_bytes,
                "cut_bytes": stats.cut_bytes, "stream_s": round(stats.stream_duration_s, 3)}
        live = self.source.describe()
        info["frames_dropped"] = live.get("frames_dropped", 0)
        info["packets_lost"] = live.get("packets_lost", 0)
        info["source"] = {k: v for k, v in live.items() if _plain(v)}  # radar and board state
        if self.process is not None:
            p50, p90, p99, worst = self.process.latency.percentiles_ms(50, 90, 99, 100)
            info["latency_ms"] = {"p50": p50, "p90": p90, "p99": p99, "max": worst}
            if self.process.estimator_s:
                info["estimator_ms"] = 1e3 * float(np.median(self.process.estimator_s))
            st = self.process.state
            if st is not None:
                info["odometry"] = {"ok": st.ok, "flags": list(st.flags), "frame": st.frame}
        self.publisher.status(info)


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run_with_status(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
