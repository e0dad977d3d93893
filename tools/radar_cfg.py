"""radar-cfg: validate a TI xWR18xx .cfg and show what it makes the radar do."""

from __future__ import annotations

import argparse
import logging
import sys
from typing import Sequence

from ..calibration import uncalibrated_note
from .. import strict_json
from ..cfg import DCA1000_DEFAULT_PACKET_DELAY_US, DCA1000_PACKET_DELAY_RANGE_US, RAW_LVDS_LINE, RadarConfig
from . import cli

log = logging.getLogger("radarodom.tools.radar_cfg")

#: (summary key, label, unit, scale, format) for the human table.
_ROWS = (
    ("range_resolution_m", "range resolution", "m", 1, ".4f"),
    ("max_range_m", "max range (80% IF)", "m", 1, ".2f"),
    ("velocity_resolution_mps", "velocity resolution", "m/s", 1, ".4f"),
    ("max_velocity_mps", "max velocity (+/-)", "m/s", 1, ".3f"),
    ("carrier_frequency_hz", "carrier (ADC centre)", "GHz", 1e-9, ".3f"),
    ("bandwidth_hz", "sampled bandwidth", "MHz", 1e-6, ".1f"),
    ("chirp_time_s", "chirp time", "us", 1e6, ".2f"),
    ("active_frame_time_s", "active frame time", "ms", 1e3, ".3f"),
    ("frame_period_s", "frame period", "ms", 1e3, ".3f"),
    ("duty_cycle", "duty cycle", "%", 100, ".1f"),
    ("frame_bytes", "frame size", "bytes", 1, "d"),
    ("data_rate_mbps", "raw data rate", "Mbit/s", 1, ".2f"),
    ("dca1000_capacity_mbps", "DCA1000 capacity", "Mbit/s", 1, ".0f"),
    ("dca1000_load", "DCA1000 load", "%", 100, ".1f"),
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radar-cfg",
        description="Validate a TI mmWave SDK 3.x cfg for the xWR18xx and print its derived "
                    "quantities. Exit 2, with file:line, on an invalid cfg.")
    parser.add_argument("cfg", metavar="FILE", help="the .cfg file")
    parser.add_argument("--json", action="store_true", help="print JSON with stable keys")
    parser.add_argument("--packet-delay-us", type=cli.float_in(*DCA1000_PACKET_DELAY_RANGE_US, unit="us"),
                        default=DCA1000_DEFAULT_PACKET_DELAY_US, metavar="US",
                        help="DCA1000 packet delay for the capacity figure, %g..%g us (default %%(default)g)"
                             % DCA1000_PACKET_DELAY_RANGE_US)
    cli.add_verbosity(parser)
    return parser


def _main(args: argparse.Namespace) -> int:
    cfg = RadarConfig.from_file(args.cfg)
    summary = cfg.summary(args.packet_delay_us)
    note = uncalibrated_note(cfg) if cfg.streams_raw_adc else None  # a cfg meant for a real board
    if note is not None:
        log.warning("%s", note)
    if args.json:
        sys.stdout.write(strict_json.dumps(summary, indent=2) + "\n")
        return 0
    out = [f"{args.cfg}: valid xWR18xx configuration",
           f"  {'TX order':<24} {' '.join(f'TX{t}' for t in cfg.tx_order)}"
           f"  ({cfg.num_tx} TX, {cfg.num_rx} RX, {cfg.num_tx_slots * cfg.num_rx} virtual antennas)",
           f"  {'frame':<24} {cfg.num_loops} loops x {cfg.num_tx_slots} chirps x "
           f"{cfg.num_samples} samples"]
    for key, label, unit, scale, fmt in _ROWS:
        value = summary[key] * scale
        out.append(f"  {label:<24} {value:{fmt}} {unit}")
    calibration = cfg.channel_calibration
    if calibration.is_identity:
        out.append(f"  {'channel calibration':<24} identity (compRangeBiasAndRxChanPhase corrects nothing)")
    else:
        out.append(f"  {'channel calibration':<24} the board's paths, as its compRangeBiasAndRxChanPhase line "
                   "corrects them (relative to TX1 RX1):")
        out += [f"    {text}" for text in calibration.table()]
    if not cfg.streams_raw_adc:
        ln = cfg.line_of("lvdsStreamCfg")
        where = f"line {ln.line}: '{ln}'" if ln else "no lvdsStreamCfg line"
        out.append(f"  note: not set up for raw capture with a DCA1000 ({where}); "
                   f"use '{RAW_LVDS_LINE}'")
    if summary["dca1000_load"] > 1:
        out.append(f"  note: the raw data rate exceeds the DCA1000's capacity at "
                   f"{args.packet_delay_us:g} us packet delay")
    print("\n".join(out))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
