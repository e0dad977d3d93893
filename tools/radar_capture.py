"""radar-capture: stream radar frames from a source, show a live status, record.

    radar-capture --source replay://DIR [--cfg FILE] [--record OUT] [--frames N] [--duration S]

Ctrl-C (or SIGTERM) stops after the current frame and closes the recording;
a second Ctrl-C aborts at once (what was written stays readable).
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
from typing import Iterator, Sequence

from ..cfg import RadarConfig
from ..driver.capture import CaptureStats, run_capture
from ..driver.capture_dir import CaptureWriter
from ..driver.sources import SCHEMES, Frame, Source, open_source
from ..errors import UsageError
from . import cli
from .status import RateMeter, StatusAwareHandler, StatusLine, format_duration


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text}")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be above 0, got {text}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radar-capture",
        description="Stream raw radar frames from a source, show a live status, and optionally "
                    "record them to a capture directory.",
        epilog="Sources: replay://DIR[?rate=1.0|max&loop=N&start=K|Ss&frames=N] plays a capture "
               "directory or TI recorder files (with --cfg).")
    parser.add_argument("--cfg", metavar="FILE",
                        help="radar configuration (TI .cfg); for replay:// of a capture directory "
                             "it defaults to the directory's radar.cfg")
    parser.add_argument("--source", metavar="URL",
                        help=f"frame source ({', '.join(s + '://' for s in sorted(SCHEMES))})")
    parser.add_argument("--record", metavar="DIR", help="record the frames to this new capture directory")
    parser.add_argument("--frames", type=_positive_int, metavar="N", help="stop after N frames")
    parser.add_argument("--duration", type=_positive_float, metavar="S",
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


def _status_text(stats: CaptureStats, rate: RateMeter, recording: bool) -> str:
    text = (f"frames {stats.frames}  rate {rate.rate_hz:5.1f} Hz  incomplete {stats.incomplete_frames}"
            f"  elapsed {format_duration(stats.elapsed_s)}")
    return text + ("  [rec]" if recording else "")


def _summary(stats: CaptureStats, record: str | None) -> str:
    text = (f"{stats.frames} frames ({stats.incomplete_frames} incomplete, {stats.missing_bytes} bytes "
            f"lost) in {stats.elapsed_s:.1f} s, {stats.mean_rate_hz:.1f} Hz, "
            f"{stats.stream_duration_s:.2f} s of stream; {stats.reason}")
    if record:
        text += f"; recorded to {record}"
    return text


def _main(args: argparse.Namespace, status: StatusLine) -> int:
    status.enabled = not args.quiet
    cfg = RadarConfig.from_file(args.cfg) if args.cfg else None
    if not args.source:
        raise UsageError("no --source given; live capture from the radar (dca1000://) and the "
                         "simulator (sim://) are not available yet: use --source replay://DIR")
    rate = RateMeter()

    def on_frame(frame: Frame, stats: CaptureStats) -> None:
        rate.tick()
        status.update(_status_text(stats, rate, args.record is not None))

    with open_source(args.source, cfg) as source:
        writer = CaptureWriter(args.record, source.config, source=args.source) if args.record else None
        with _stop_on_signals(source):
            try:
                stats = run_capture(source, writer=writer, max_frames=args.frames,
                                    max_duration_s=args.duration, on_frame=on_frame)
            finally:
                status.clear()
    print(f"radar-capture: {_summary(stats, args.record)}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    status = StatusLine(sys.stderr)
    return cli.run(lambda args: _main(args, status), build_parser(), argv,
                   handler=StatusAwareHandler(status))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
