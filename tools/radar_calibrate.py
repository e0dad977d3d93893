"""radar-calibrate: measure a board's compRangeBiasAndRxChanPhase line from a corner reflector.

    radar-calibrate --source URL --distance M [--search-window M] [--max-azimuth DEG] [--frames N]
                    [--cfg FILE] [--write-cfg OUT.cfg] [--json]

A corner reflector on the radar's boresight, at the antennas' height, alone, at a known
distance; the radar and the reflector still.  Works on any raw source: the live radar, a
recording, the simulator (``sim://calibration?board=uncalibrated`` has one at 3 m); and on a
board without a DCA1000 (``tidemo://``), whose demo firmware measures on the chip.
"""

from __future__ import annotations

import os

# One BLAS thread (as radar-capture: OpenBLAS threads stall when the other core is busy).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402  (after the BLAS setting)
import logging  # noqa: E402
import sys  # noqa: E402
from typing import Sequence  # noqa: E402

from .. import strict_json  # noqa: E402
from ..cfg import RadarConfig  # noqa: E402
from ..dsp.calibrate import MAX_APPARENT_AZIMUTH_DEG  # noqa: E402
from ..errors import CalibrationError, CaptureError, UsageError  # noqa: E402
from . import cli  # noqa: E402

log = logging.getLogger("radarodom.tools.radar_calibrate")

#: Frames averaged by default: a second at 10 Hz.
DEFAULT_FRAMES = 10
#: Frames of tidemo:// without a measurement line before the demo is taken not to measure.
DEMO_SILENCE_FRAMES = 10


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radar-calibrate",
        description="Measure the board's channel calibration (the cfg line compRangeBiasAndRxChanPhase: "
                    "range bias and a phase and gain correction per TX/RX path) from a corner reflector "
                    "on boresight at a known distance, as TI's measureRangeBiasAndRxChanPhase does.",
        epilog="Set-up: one corner reflector on the radar's boresight, at the antennas' height, 1.5-3 m away, "
               "nothing else within the search window (--search-window); the radar and the reflector still. Try "
               "it on the simulator: radar-calibrate --source 'sim://calibration?board=uncalibrated&rate=max' "
               "--distance 3; on a fake board without a DCA1000, whose firmware measures: radar-emulate --uart "
               "--source 'sim://calibration?board=uncalibrated', then radar-calibrate --source with the tidemo:// "
               "URL it prints, --distance 3")
    parser.add_argument("--source", metavar="URL",
                        help="raw frame source (dca1000://, replay://, sim://, coloradar://...adc), or tidemo:// "
                             "(a board without a DCA1000: its demo firmware measures; default: the live radar if "
                             "one is plugged in, through the DCA1000 if one shows)")
    parser.add_argument("--distance", type=cli.positive_float, required=True, metavar="M",
                        help="the reflector's true distance from the radar, m")
    parser.add_argument("--search-window", type=cli.positive_float, default=0.2, metavar="M",
                        help="search the reflector within distance +/- this, m (default %(default)g; TI's "
                             "searchWin is the whole width, twice this)")
    parser.add_argument("--max-azimuth", type=cli.boresight_angle, default=None, metavar="DEG",
                        help="the reflector's apparent direction allowed, degrees from boresight (default "
                             "%g: a board's own errors rarely look larger; raise it only with the reflector "
                             "surely on boresight)" % MAX_APPARENT_AZIMUTH_DEG)
    parser.add_argument("--frames", type=cli.positive_int, default=DEFAULT_FRAMES, metavar="N",
                        help="frames to average (default %(default)d; tidemo://: the demo's lines, 5 to 1000)")
    parser.add_argument("--cfg", metavar="FILE",
                        help="radar configuration (TI .cfg); for replay:// of a capture directory it defaults "
                             "to the directory's radar.cfg")
    parser.add_argument("--write-cfg", metavar="OUT.cfg",
                        help="write a copy of the cfg with the measured line in place of its own (a new file)")
    parser.add_argument("--json", action="store_true",
                        help="print JSON: range_bias_m, coefficients (12 [re, im] in TI's order), cfg_line, "
                             "snr_db, residual_phase_deg, gain_db, phase_deg, ...")
    cli.add_overwrite(parser)
    cli.add_verbosity(parser)
    return parser


def _default_source() -> str:
    from ..driver.live.default_source import live_source_url
    from ..driver.live.discovery import default_cli_port, no_radar_message

    port = default_cli_port()
    if port is None:
        raise UsageError(f"{no_radar_message()}; give --source (for instance "
                         "'sim://calibration?board=uncalibrated' to try it on the simulator)")
    return live_source_url(port)


def _measure(args: argparse.Namespace, cfg: RadarConfig | None):
    from ..driver.sources import open_source
    from ..dsp.calibrate import ChannelCalibrator

    if args.source.split(":", 1)[0].lower() == "tidemo":
        return _measure_on_chip(args, cfg)
    with open_source(args.source, cfg) as source:
        if not source.carries_raw or source.config is None:
            hint = ("; a ColoRadar run's single-chip ADC frames: coloradar://RUN?velocity=single_chip_adc&"
                    "heatmap=single_chip_adc" if args.source.startswith("coloradar:") else "")
            raise UsageError(f"{args.source} gives no raw ADC frames: the measurement needs them{hint}")
        options = {} if args.max_azimuth is None else {"max_azimuth_deg": args.max_azimuth}
        calibrator = ChannelCalibrator(source.config, args.distance, args.search_window, coupling=source.coupling,
                                       **options)
        skipped = 0
        for frame in source:
            if not frame.complete:  # zero-filled samples would pull the phases
                skipped += 1
                continue
            calibrator.add(frame.cube())
            if calibrator.frames >= args.frames:
                break
        if skipped and not calibrator.frames:
            raise CalibrationError(f"no frame to measure: all {skipped} frame(s) {args.source} gave were incomplete "
                                   "(packets lost); check the link (radar-capture names the cause)")
        if skipped:
            log.warning("%d incomplete frame(s) skipped", skipped)
        if calibrator.frames < args.frames:
            log.warning("the source ended after %d whole frame(s) of the %d asked", calibrator.frames, args.frames)
        return calibrator.result(), source.config


def _measure_on_chip(args: argparse.Namespace, cfg: RadarConfig | None):
    """tidemo://: the demo firmware measures (measureRangeBiasAndRxChanPhase 1 in the cfg sent)
    and prints a line a frame on its CLI port; the lines are combined."""
    from ..cfg import TIDEMO_CONFIG_NAME, shipped_config_path
    from ..cfg_commands import ClutterRemoval, MeasureRangeBiasAndRxChanPhase
    from ..driver.sources import open_source
    from ..driver.tidemo.source import CLI_LINES_KEPT
    from ..dsp.calibrate import ChannelCalibrator
    from ..dsp.demo_calibration import LINE_PREFIX, MIN_LINES, combine_demo_measurements

    MAX_DEMO_FRAMES = CLI_LINES_KEPT // 2  # the source keeps its last CLI_LINES_KEPT lines

    if not MIN_LINES <= args.frames <= MAX_DEMO_FRAMES:
        raise UsageError(f"--frames {args.frames}: the demo's lines are combined {MIN_LINES} to {MAX_DEMO_FRAMES} at "
                         f"a time (one chirp's line alone carries noise nothing would tell)")
    base = cfg if cfg is not None else RadarConfig.from_file(shipped_config_path(TIDEMO_CONFIG_NAME))
    options = {} if args.max_azimuth is None else {"max_azimuth_deg": args.max_azimuth}
    ChannelCalibrator(base, args.distance, args.search_window, **options)  # the cfg and window, before the radar
    searched = 2 * args.search_window  # TI's searchWin is the whole width
    asked = base.replace(MeasureRangeBiasAndRxChanPhase(1, args.distance, searched))
    clutter = base.clutter_removal
    if clutter is not None and clutter.enabled:  # the chip would take the still reflector out of what it measures
        log.info("%s: clutterRemoval is on; sent off while the demo measures (the cfg written keeps it)", base.path)
        asked = asked.replace(ClutterRemoval(clutter.subframe, 0))
    lines: list[str] = []
    frames = 0
    with open_source(args.source, asked) as source:
        for frames, _ in enumerate(source, start=1):
            lines = [ln for ln in source.cli_lines if ln.startswith(LINE_PREFIX)]
            if len(lines) >= args.frames or frames >= 2 * args.frames + DEMO_SILENCE_FRAMES:
                break
            if not lines and frames >= DEMO_SILENCE_FRAMES:
                raise CalibrationError(
                    f"the demo printed no {LINE_PREFIX} line on its CLI port in {frames} frames, though the cfg "
                    f"sent asked for it (measureRangeBiasAndRxChanPhase 1 {args.distance:g} {searched:g}): its "
                    "firmware does not measure (TI's mmWave SDK 3.x out-of-box demo does); measure with a DCA1000 "
                    "(--source dca1000://) instead")
    if len(lines) < args.frames:
        log.warning("the demo printed %d measurement(s) in %d frames, of the %d asked", len(lines), frames, args.frames)
    result = combine_demo_measurements(asked, lines[:args.frames], args.distance, args.search_window, **options)
    return result, base.replace(MeasureRangeBiasAndRxChanPhase(0, args.distance, searched))


def _main(args: argparse.Namespace) -> int:
    if args.write_cfg:  # never over what it reads (the cfg, the replayed recording's own files)
        cli.check_distinct([("--write-cfg", args.write_cfg)], cli.read_paths([("--cfg", args.cfg)], args.source))
        cli.check_new_path(args.write_cfg, overwrite=args.overwrite)
    args.source = args.source or _default_source()  # the live radar or the simulator: no file read
    cfg = RadarConfig.from_file(args.cfg) if args.cfg else None
    result, used_cfg = _measure(args, cfg)
    line = result.calibration.cfg_line()
    if args.write_cfg:
        try:
            cli.write_output(args.write_cfg, used_cfg.replace(result.calibration.to_command()).to_text(),
                             overwrite=args.overwrite)
        except CaptureError:
            print(json_report(result) if args.json else line)  # the measurement is not lost with the file
            raise
    if args.json:
        print(json_report(result))
        return 0
    frames = f"{result.frames} frame{'' if result.frames == 1 else 's'}"
    if result.measured_by == "radarodom":
        head = (f"SNR {result.snr_db:.1f} dB, {frames}; residual phase after correction "
                f"{result.residual_phase_deg:.2f} deg RMS")
    else:
        head = (f"measured by the demo firmware, {frames}; its measurements scatter by "
                f"{result.residual_phase_deg:.2f} deg RMS about their mean")
    out = [f"reflector at {result.measured_range_m:.3f} m ({result.distance_m:g} m true), {head}",
           "channel response corrected (relative to TX1 RX1):"]
    out += ["  " + text for text in result.calibration.table()]
    if args.write_cfg:
        out.append(f"wrote {args.write_cfg}: the cfg with this line")
    out.append(line)
    print("\n".join(out))
    return 0


def json_report(result) -> str:
    """--json's text of a measurement: standard JSON, a figure that is not finite as null."""
    return strict_json.dumps(result.describe(), indent=2)


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
