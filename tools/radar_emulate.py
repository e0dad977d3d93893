"""radar-emulate: a fake AWR1843 (on a pty) and a fake DCA1000 (on loopback UDP)
streaming a recording or the simulator, to try the live path without hardware; or, with
``--uart``, the fake AWR1843's demo firmware output on its data port (a second pty), to try
``tidemo://``.

    radar-emulate --capture DIR [--loss P] [--reorder P] ...
    radar-emulate --source sim://lab [--command-port 4096 --data-port 4098]
    radar-emulate --uart --source sim://corridor [--cfg my_tidemo.cfg] [--uart-drop P] ...

It prints the --source URL (and --cfg) to give to radar-capture (and, with --command-port,
the settings for xwr), then runs until Ctrl-C.  docs/live.md describes the emulators' timings,
docs/tidemo.md the data port's.
"""

from __future__ import annotations

import argparse
import errno
import os
import shlex
import sys
import threading
from typing import Sequence

from ..cfg import RadarConfig
from ..driver.recordings.capture_dir import RADAR_CFG
from ..driver.emulators.fake_awr1843 import CliFaults
from ..driver.emulators.fake_dca1000 import Faults
from ..driver.emulators.fake_demo_uart import DemoUartRig, UartFaults
from ..driver.emulators.rig import BOARD_IP, EmulatedRig
from ..errors import UsageError
from . import cli


#: The per-packet faults of the fake DCA1000 (driver.emulators.fake_dca1000.Faults) and what each does.
_PACKET_FAULTS = {
    "loss": "a packet is not sent: a sequence gap, its bytes lost",
    "duplicate": "a packet is sent twice in a row",
    "reorder": "a packet is held back and sent after the next 1-3 packets (it still arrives)",
    "truncate": "a packet's data is cut short (its header unchanged): a truncated packet",
    "malformed": "a garbage datagram shorter than a header is sent instead of the packet (which is lost)",
    "foreign": "the packet is also sent from another address (127.0.0.3) with its data inverted: "
               "a host that does not filter by source address would corrupt its frames",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radar-emulate",
        description="Emulate the AWR1843BOOST CLI (pseudo-terminal) and the DCA1000EVM (UDP on "
                    "127.0.0.2) streaming a capture or the simulator; prints the radar-capture "
                    "command to use, and runs until Ctrl-C.")
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--capture", metavar="DIR", help="a capture directory to stream (looped)")
    what.add_argument("--source", metavar="URL", help="any frame source, e.g. sim://lab")
    parser.add_argument("--cfg", metavar="FILE", help="radar configuration for --source "
                                                       "(default: the source's own)")
    parser.add_argument("--uart", action="store_true",
                        help="no DCA1000: the fake radar runs TI's demo firmware and streams its points and static "
                             "heatmap on its data port (a second pty) for tidemo:// (docs/tidemo.md); it runs the "
                             "cfg radar-capture sends (--cfg, passed on; without it tidemo://'s own, "
                             "configs/awr1843_tidemo.cfg)")
    faults = parser.add_argument_group(
        "faults", "Each P is a probability per data packet, 0 to 1, drawn independently (--seed reproduces a "
                  "run); what radar-capture should then report is in docs/live.md.")
    for name, what in _PACKET_FAULTS.items():
        faults.add_argument(f"--{name}", type=cli.probability, default=0.0, metavar="P", help=what)
    uart = parser.add_argument_group(
        "data-port faults (--uart)", "Each P is a probability per packet of the demo's UART output, drawn from --seed.")
    uart.add_argument("--uart-garbage", type=cli.probability, default=0.0, metavar="P",
                      help="line noise (24 stray bytes) before a packet")
    uart.add_argument("--uart-truncate", type=cli.probability, default=0.0, metavar="P",
                      help="a packet is cut short: its tail is never sent")
    uart.add_argument("--uart-drop", type=cli.probability, default=0.0, metavar="P",
                      help="a run of up to 64 bytes inside a packet is lost")
    faults.add_argument("--burst-flush", action="store_true",
                        help="end every frame with a short packet instead of straddling frames")
    faults.add_argument("--hang-on-start", action="store_true",
                        help="the radar never answers sensorStart (until RESET_AR_DEV; with --uart, until the "
                             "emulator stops)")
    ports = parser.add_argument_group("ports (default: free ones)")
    ports.add_argument("--command-port", type=cli.port, default=0, metavar="PORT",
                       help="the board's config port (a real board's is 4096; xwr sends to the port "
                            "number it binds on the host, so give it that one, free on both addresses)")
    ports.add_argument("--data-port", type=cli.port, default=0, metavar="PORT",
                       help="the host port the board streams data to (a real board's: 4098)")
    parser.add_argument("--max-rate", action="store_true", help="stream as fast as possible, not paced")
    parser.add_argument("--seed", type=cli.non_negative_int, default=0, metavar="N",
                        help="seed of the fault draws: the same seed, the same faults on the same packets")
    cli.add_verbosity(parser)
    return parser


def _main(args: argparse.Namespace) -> int:
    if args.capture:
        if not os.path.isdir(args.capture):
            what = "not a directory (give the capture directory that holds it)" if os.path.exists(args.capture) \
                else "no such directory"
            raise UsageError(f"--capture {args.capture}: {what}")
        url, cfg_path = f"replay://{args.capture}", args.cfg or os.path.join(args.capture, RADAR_CFG)
        if not os.path.exists(cfg_path):  # a folder that is no recording is told so, as replay:// tells it
            from ..driver.sources import open_source

            open_source(url).close()
    else:
        url, cfg_path = args.source, args.cfg
    config = RadarConfig.from_file(cfg_path) if cfg_path else None
    if args.uart:
        return _serve_uart(url, cfg_path, config, args)
    uart_faults = [option for option, value in (("--uart-garbage", args.uart_garbage),
                                                ("--uart-truncate", args.uart_truncate),
                                                ("--uart-drop", args.uart_drop)) if value]
    if uart_faults:
        raise UsageError(f"{uart_faults[0]} is a fault of the demo's UART data port: add --uart (the DCA1000's "
                         "packet faults are --loss, --duplicate, --reorder, --truncate, --malformed, --foreign)")
    faults = Faults(loss=args.loss, duplicate=args.duplicate, reorder=args.reorder, truncate=args.truncate,
                    malformed=args.malformed, foreign=args.foreign, burst_flush=args.burst_flush)
    stop = threading.Event()
    with cli.on_stop_signals(lambda *_: stop.set()):
        with _open_rig(url, args, config=config, faults=faults,
                       cli_faults=CliFaults(hang_on_start=args.hang_on_start),
                       rate="max" if args.max_rate else "paced", seed=args.seed) as rig:
            command = ["radar-capture", "--source", rig.url()]
            if cfg_path:
                command += ["--cfg", cfg_path]
            print(f"radar-emulate: radar CLI on {rig.cli_path}, DCA1000 at {rig.board.command_address[0]}; "
                  f"streaming {url}")
            print(shlex.join(command), flush=True)
            if args.command_port:  # a client that sends to the port number it binds (xwr)
                print(f"xwr: XWRConfig(port={rig.cli_path!r}, ...), DCAConfig(sys_ip={rig.host_ip!r}, "
                      f"fpga_ip={rig.board.board_ip!r}, config_port={rig.board.command_port}, "
                      f"data_port={rig.data_port})", flush=True)
            while not stop.wait(0.5):
                pass
            stats = rig.board.stats
            held = stats.frames_in - stats.frames_sent
            print(f"radar-emulate: sent {stats.frames_sent} frames in {stats.packets_sent} packets "
                  f"({stats.dropped} dropped, {stats.duplicates} duplicated, {stats.reordered} reordered, "
                  f"{stats.truncated} truncated, {stats.malformed} replaced by garbage and {stats.foreign} copied "
                  f"from another address by the fault injector)"
                  + (f"; the tail of {held} more was held back (its recording had not ended)" if held else ""))
    return 0


def _serve_uart(url: str, cfg_path: str | None, config: RadarConfig | None, args: argparse.Namespace) -> int:
    """The fake radar with the demo's data port, until Ctrl-C."""
    from ..driver.emulators.source_url import emulated_source_url, no_raw_frames_message
    from ..driver.sources import open_source
    from ..driver.tidemo.layout import DEFAULT_BAUD, DEFAULT_MAX_POINTS, DemoGeometry, check_uart_budget, gui_selection

    packet_faults = [name for name in _PACKET_FAULTS if getattr(args, name)]
    if packet_faults or args.burst_flush or args.command_port or args.data_port:
        raise UsageError("--uart has no DCA1000: its packet faults and ports do not apply (the data port's faults "
                         "are --uart-garbage, --uart-truncate, --uart-drop)")
    if config is not None:  # radar-capture would refuse it: say so now
        check_uart_budget(config, DemoGeometry.from_config(config).layout(gui_selection(config)), DEFAULT_BAUD,
                          DEFAULT_MAX_POINTS)
    # The fake radar opens the source only when radar-capture starts it: its URL is checked now.
    with open_source(emulated_source_url(url, defaults={"rate": "max", "loop": "0"}), config, shown_url=url) as source:
        if not source.carries_raw:
            raise UsageError(no_raw_frames_message(url))
    faults = UartFaults(garbage=args.uart_garbage, truncate=args.uart_truncate, drop=args.uart_drop, seed=args.seed)
    stop = threading.Event()
    with cli.on_stop_signals(lambda *_: stop.set()):
        with DemoUartRig(url, faults=faults, cli_faults=CliFaults(hang_on_start=args.hang_on_start),
                         rate="max" if args.max_rate else "paced") as rig:
            command = ["radar-capture", "--source", rig.url()] + (["--cfg", cfg_path] if cfg_path else [])
            print(f"radar-emulate: radar CLI on {rig.cli_path}, demo data port on {rig.data_path}; streaming "
                  f"{url} as the demo's UART output")
            print(shlex.join(command), flush=True)
            while not stop.wait(0.5):
                pass
            s = rig.data.stats
            print(f"radar-emulate: sent {s.packets} packets ({len(s.truncated)} cut short, {len(s.dropped)} with "
                  f"bytes lost, {len(s.garbage_before)} after line noise by the fault injector)"
                  + ("; the demo asserted: a packet outlasted the UART's time between frames" if s.asserted else ""))
    return 0


def _open_rig(url: str, args: argparse.Namespace, **kw) -> EmulatedRig:
    try:
        return EmulatedRig(url, command_port=args.command_port, data_port=args.data_port, **kw)
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE and args.command_port:
            raise UsageError(f"--command-port {args.command_port}: in use on {BOARD_IP} by another program "
                             f"(a radar-emulate still running?): choose another port") from None
        if exc.errno == errno.EADDRNOTAVAIL:
            raise UsageError(f"cannot bind {BOARD_IP}, the fake board's address: {exc.strerror}. Linux has all "
                             f"of 127.0.0.0/8 on its loopback; elsewhere add it, e.g. 'sudo ifconfig lo0 "
                             f"alias {BOARD_IP}' on macOS") from None
        raise


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
