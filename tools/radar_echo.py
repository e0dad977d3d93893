"""radar-echo: subscribe to what radarodom publishes over Zenoh and print it live,
one line per message.

    radar-echo [--key-prefix P] [--connect EP] [--listen EP] [--mode peer|client]
               [--zenoh-config FILE] [--count N] [--json] [odom|status|pointcloud|heatmap ...]

Without endpoints it connects to a publisher on this machine (its default
endpoint, tcp/127.0.0.1:7448).  Stops after --count messages, or on Ctrl-C;
the session is always closed.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import queue
import sys
import time
from typing import Callable, Sequence

from .. import messages
from ..errors import MessageError
from ..publish import KINDS, open_session
from . import cli
from .zenoh_args import add_zenoh_arguments, options_from_args

log = logging.getLogger("radarodom.tools.radar_echo")

DEFAULT_KINDS = ("odom", "status")
#: How long the receive loop waits before looking again (Ctrl-C, the "nothing yet" hint).
_POLL_S = 0.25
#: After this long with nothing received and no peer, say what to check.
_QUIET_HINT_S = 5.0


def _kind(text: str) -> str:
    if text not in KINDS:
        raise argparse.ArgumentTypeError(f"expected one of {', '.join(KINDS)}, got {text!r}")
    return text


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radar-echo",
        description="Print what radarodom publishes over Zenoh, live, one line per message: odometry "
                    "(t, frame, x, y, yaw, speed, flags), status (JSON), point clouds (frame, t, count), "
                    "heatmaps (frame, t, shape).")
    parser.add_argument("kinds", nargs="*", type=_kind, metavar="KIND",
                        help=f"what to print: {', '.join(KINDS)} (default: {' '.join(DEFAULT_KINDS)})")
    parser.add_argument("--count", type=cli.positive_int, metavar="N", help="exit after N messages")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object per message (odometry and status whole, the headers "
                             "of point clouds and heatmaps), with its key")
    add_zenoh_arguments(parser)
    cli.add_verbosity(parser)
    return parser


def _odom_line(payload: bytes) -> tuple[str, dict]:
    m = messages.parse_odometry(payload)
    text = (f"odom frame {m['frame']} t {m['t']:.3f} x {m['x']:.3f} y {m['y']:.3f} m "
            f"yaw {math.degrees(m['yaw']):.2f} deg v {math.hypot(m['vx'], m['vy']):.3f} m/s")
    return text + (f" [{','.join(m['flags'])}]" if m["flags"] else ""), m


def _status_line(payload: bytes) -> tuple[str, dict]:
    m = messages.parse_status(payload)
    return "status " + json.dumps(m, separators=(",", ":")), m


def _pointcloud_line(payload: bytes) -> tuple[str, dict]:
    header, _ = messages.decode_pointcloud(payload)
    return f"pointcloud frame {header['frame']} t {header['t']:.3f} points {header['count']}", header


def _heatmap_line(payload: bytes) -> tuple[str, dict]:
    header, _ = messages.decode_heatmap(payload)
    return (f"heatmap frame {header['frame']} t {header['t']:.3f} "
            f"shape {header['n_range']}x{header['n_azimuth']}"), header


#: Each kind's (text line, JSON object) of a payload.
_FORMATS: dict[str, Callable[[bytes], tuple[str, dict]]] = {
    "odom": _odom_line, "status": _status_line, "pointcloud": _pointcloud_line, "heatmap": _heatmap_line,
}


def format_message(kind: str, key: str, payload: bytes, as_json: bool = False) -> str:
    """The line radar-echo prints for one message (raises MessageError when it is malformed)."""
    text, obj = _FORMATS[kind](payload)
    return json.dumps({"key": key, **obj}, separators=(",", ":")) if as_json else text


def _main(args: argparse.Namespace) -> int:
    options = options_from_args(args).for_subscriber()
    kinds = list(dict.fromkeys(args.kinds or DEFAULT_KINDS))
    inbox: queue.SimpleQueue = queue.SimpleQueue()
    session, options = open_session(options)
    try:
        subscribers = []  # kept referenced while the loop runs
        for kind in kinds:
            # Runs on a zenoh thread: copy the bytes out and hand them to the main thread.
            def receive(sample, kind=kind):
                inbox.put((kind, str(sample.key_expr), sample.payload.to_bytes()))
            subscribers.append(session.declare_subscriber(options.key(kind), receive))
        if not args.quiet:
            print(f"radar-echo: {', '.join(options.key(k) for k in kinds)} via {options.describe()}; "
                  "Ctrl-C stops", file=sys.stderr, flush=True)
        return _print_loop(args, session, inbox)
    except KeyboardInterrupt:
        return 0  # Ctrl-C is how a live listing ends: a normal exit
    finally:
        session.close()


def _print_loop(args: argparse.Namespace, session, inbox: queue.SimpleQueue) -> int:
    printed = 0
    started = time.monotonic()
    hinted = False
    while args.count is None or printed < args.count:
        try:
            kind, key, payload = inbox.get(timeout=_POLL_S)
        except queue.Empty:
            if not hinted and not printed and time.monotonic() - started > _QUIET_HINT_S:
                hinted = True
                if not list(session.info.peers_zid()) and not list(session.info.routers_zid()):
                    log.warning("no Zenoh peer reached yet: is radar-capture publishing on this machine? "
                                "(otherwise give --connect with its endpoint)")
            continue
        try:
            line = format_message(kind, key, payload, args.json)
        except MessageError as exc:
            log.warning("%s: ignored a malformed message: %s", key, exc)
            continue
        print(line, flush=True)
        printed += 1
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
