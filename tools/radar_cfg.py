"""radar-cfg: validate a TI xWR18xx .cfg and show what it makes the radar do."""

from __future__ import annotations

import argparse
import logging
import os
import sys
import traceback
from importlib import resources
from typing import Sequence

from ..calibration import uncalibrated_note
from ..driver.tidemo.layout import (DEFAULT_BAUD, DEFAULT_MAX_POINTS, DemoGeometry, check_uart_budget,
                                     gui_selection, uart_budget)
from ..errors import ConfigError, RadarodomError, UsageError
from .. import strict_json
from ..dsp.config import DspConfig
from ..dsp.detection_range import detection_range
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
    ("measured_at_s", "chirps' middle", "ms after stamp", 1e3, ".3f"),
    ("frame_period_s", "frame period", "ms", 1e3, ".3f"),
    ("duty_cycle", "duty cycle", "%", 100, ".1f"),
    ("frame_bytes", "frame size", "bytes", 1, "d"),
    ("data_rate_mbps", "raw data rate", "Mbit/s", 1, ".2f"),
    ("dca1000_capacity_mbps", "DCA1000 capacity", "Mbit/s", 1, ".0f"),
    ("dca1000_load", "DCA1000 load", "%", 100, ".1f"),
)


class _Parser(argparse.ArgumentParser):
    def parse_args(self, args=None, namespace=None):  # type: ignore[override]
        ns = super().parse_args(args, namespace)
        if ns.copy is not None and len(ns.copy) > 2:
            self.error("--copy takes NAME and at most one DEST")
        given = [what for what, there in (("FILEs", bool(ns.cfg)), ("--list", ns.list), ("--copy", ns.copy is not None))
                 if there]
        if len(given) > 1:  # each is a command of its own
            self.error(f"{' and '.join(given)} do not go together: give one or more FILEs to check, or --list, "
                       f"or --copy NAME [DEST]")
        if not given:
            self.error("give one or more FILEs, or --list, or --copy NAME [DEST]")
        if ns.json and ns.copy is not None:
            self.error("--json goes with FILEs or --list, not --copy")
        if ns.overwrite and ns.copy is None:  # nothing else writes: taken and ignored, it misled
            self.error("--overwrite goes with --copy (FILEs and --list write nothing)")
        return ns


class _Formatter(argparse.HelpFormatter):
    """--copy takes one or two values, which nargs cannot say ("+" would print NAME [DEST ...])."""

    def _format_args(self, action, default_metavar):
        return "NAME [DEST]" if action.dest == "copy" else super()._format_args(action, default_metavar)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="radar-cfg", formatter_class=_Formatter,
        description="Validate TI mmWave SDK 3.x cfgs for the xWR18xx and print their derived "
                    "quantities. Exit 2, with file:line, on an invalid cfg (with several files: the worst "
                    "exit status of them). --list and --copy give the cfgs radarodom ships.")
    parser.add_argument("cfg", metavar="FILE", nargs="*", help="the .cfg files")
    parser.add_argument("--json", action="store_true",
                        help="print JSON with stable keys (several files: an object of them by file name; with --list, "
                             "an object of the shipped cfgs' descriptions by name)")
    parser.add_argument("--packet-delay-us", type=cli.float_in(*DCA1000_PACKET_DELAY_RANGE_US, unit="us"),
                        default=DCA1000_DEFAULT_PACKET_DELAY_US, metavar="US",
                        help="DCA1000 packet delay for the capacity figure, %g..%g us (default %%(default)g)"
                             % DCA1000_PACKET_DELAY_RANGE_US)
    parser.add_argument("--list", action="store_true",
                        help="list the cfgs radarodom ships, one line each (with --json: a JSON object)")
    parser.add_argument("--copy", nargs="+", metavar=("NAME", "DEST"),
                        help="copy a shipped cfg to DEST (a file or a directory; default: NAME in the "
                             "current directory), a new file unless --overwrite")
    cli.add_overwrite(parser)
    cli.add_verbosity(parser)
    return parser


def shipped_configs() -> dict[str, str]:
    """The cfgs radarodom ships (configs/*.cfg in the package): name -> its first comment line."""
    folder = resources.files(__package__.rpartition(".")[0]).joinpath("configs")
    found = {}
    for entry in sorted(folder.iterdir(), key=lambda e: e.name):
        if entry.name.endswith(".cfg"):
            first = entry.read_text(encoding="ascii", errors="replace").splitlines()[:1]
            text = first[0].lstrip("%").strip() if first and first[0].startswith("%") else ""
            found[entry.name] = text.removeprefix("radarodom:").strip() or "(no description)"
    return found


def _list(as_json: bool) -> int:
    configs = shipped_configs()
    if as_json:
        sys.stdout.write(strict_json.dumps(configs, indent=2) + "\n")
        return 0
    width = max(map(len, configs), default=0)
    for name, description in configs.items():
        print(f"{name:<{width}}  {description}")
    return 0


def _copy(names: list[str], overwrite: bool) -> int:
    from ..cfg import shipped_config_path

    configs = shipped_configs()
    name = names[0] if names[0].endswith(".cfg") else names[0] + ".cfg"
    if name not in configs:
        raise UsageError(f"no shipped cfg {names[0]!r}; radarodom ships: {', '.join(configs)} (radar-cfg --list)")
    dest = names[1] if len(names) > 1 else name
    if os.path.isdir(dest):
        dest = os.path.join(dest, name)
    what = f"the copy of {name}"
    cli.check_distinct([("DEST", dest)], [("the shipped cfg", str(shipped_config_path(name)))])
    cli.check_new_path(dest, overwrite=overwrite, what=what)
    with open(shipped_config_path(name), encoding="utf-8", newline="") as fh:
        cli.write_output(dest, fh.read(), overwrite=overwrite, what=what)
    print(f"radar-cfg: copied {name} to {dest}")
    return 0


def _main(args: argparse.Namespace) -> int:
    if args.list:
        return _list(args.json)
    if args.copy is not None:
        return _copy(args.copy, args.overwrite)
    if len(args.cfg) == 1:
        return _report(args.cfg[0], args, None)
    status = 0
    documents: dict | None = {} if args.json else None
    for index, path in enumerate(args.cfg):
        if index and not args.json:
            print()
        try:
            _report(path, args, documents)
        except RadarodomError as exc:
            sys.stdout.flush()
            print(f"radar-cfg: error: {exc}", file=sys.stderr)
            if args.verbose:
                traceback.print_exc()
            status = max(status, exc.exit_code)
            if documents is not None:
                documents[path] = {"error": str(exc)}
    if documents is not None:
        sys.stdout.write(strict_json.dumps(documents, indent=2) + "\n")
    return status


def _report(path: str, args: argparse.Namespace, documents: dict | None) -> int:
    """Validate the cfg at *path* and print what it makes the radar do (or, with --json and
    several files, put its summary into *documents*)."""
    cfg = RadarConfig.from_file(path)
    summary = cfg.summary(args.packet_delay_us)
    uart = _demo_uart(cfg)
    if uart is not None:
        summary["demo_uart_load"] = round(uart[0], 4)
    note = uncalibrated_note(cfg) if cfg.streams_raw_adc else None  # a cfg meant for a real board
    if note is not None:
        log.warning("%s", note)
    line = cfg.comp_range_bias_and_rx_chan_phase
    bias = line.range_bias_m if line is not None else 0.0
    detection_range(cfg, DspConfig(), bias)  # a window that leaves nothing to detect in is refused
    for note in (cfg.range_fov_note(bias), cfg.session_order_note()):
        if note is not None:
            log.warning("%s", note)
    if documents is not None:
        documents[path] = summary
        return 0
    if args.json:
        sys.stdout.write(strict_json.dumps(summary, indent=2) + "\n")
        return 0
    out = [f"{path}: valid xWR18xx configuration",
           f"  {'TX order':<24} {' '.join(f'TX{t}' for t in cfg.tx_order)}"
           f"  ({_antennas(cfg)})",
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
    if uart is not None:
        out.append(f"  {'demo UART load':<24} {100 * uart[0]:.1f} %  (tidemo://, without a DCA1000: "
                   f"{DEFAULT_MAX_POINTS} points a frame at {DEFAULT_BAUD} baud)")
        if uart[1]:  # (no "note:": the cfg may well be meant for the DCA1000, which carries it)
            out.append(f"  {'':<24} over 100 %: tidemo:// refuses it; it needs {uart[1]}")
    print("\n".join(out))
    return 0


def _demo_uart(cfg: RadarConfig) -> tuple[float, str | None] | None:
    """What the cfg's frames ask of TI's demo firmware's UART (``tidemo://`` by default): the
    load (a packet's time on the line over the time between the frame's chirps and the next
    frame) and, over 1, what to change; None where the demo's packets do not apply to the cfg."""
    try:
        layout = DemoGeometry.from_config(cfg).layout(gui_selection(cfg))
    except ConfigError:
        return None
    try:
        budget = check_uart_budget(cfg, layout, DEFAULT_BAUD, DEFAULT_MAX_POINTS)
    except ConfigError as exc:  # (the refusal's arithmetic again, for the load it says too much)
        budget = uart_budget(cfg, layout, DEFAULT_BAUD, DEFAULT_MAX_POINTS)
        return budget.transmit_s / budget.available_s, exc.message.partition("Fix: ")[2] or exc.message
    return budget.transmit_s / budget.available_s, None


def _antennas(cfg) -> str:
    """"3 TX, 4 RX, 12 virtual antennas"; a TX that fires twice a frame makes more channels than
    antennas: "2 TX in 3 chirps, 4 RX, 8 virtual antennas in 12 channels"."""
    antennas = cfg.num_tx * cfg.num_rx
    if cfg.num_tx_slots == cfg.num_tx:
        return f"{cfg.num_tx} TX, {cfg.num_rx} RX, {antennas} virtual antennas"
    return (f"{cfg.num_tx} TX in {cfg.num_tx_slots} chirps, {cfg.num_rx} RX, {antennas} virtual antennas in "
            f"{cfg.num_tx_slots * cfg.num_rx} channels")


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
