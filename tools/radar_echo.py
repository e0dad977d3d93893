"""radar-echo: subscribe to what radarodom publishes over Zenoh and print it live,
one line per message.

    radar-echo [--key-prefix P] [--connect EP] [--listen EP] [--mode peer|client]
               [--zenoh-config FILE] [--count N] [--json] [odom|status|pointcloud|heatmap ...]

Without endpoints it connects to a publisher on this machine (its default
endpoint, tcp/127.0.0.1:7448).  Stops after --count messages, or on Ctrl-C;
the session is always closed.

Any peer may put anything on these keys: a message that does not decode is
skipped with one warning line on stderr (its key and why), and the listing goes
on.  When messages arrive faster than they are printed, those beyond a backlog
of :data:`_BACKLOG` are dropped, and a warning says how many.
"""

from __future__ import annotations

import argparse
import logging
import math
import queue
import re
import sys
import threading
import time
from typing import Any, Callable, Sequence

import zenoh

from .. import messages, strict_json
from ..errors import MessageError, one_line
from ..publish import DEFAULT_ENDPOINT, KINDS, open_session
from . import cli
from .zenoh_args import add_zenoh_arguments, options_from_args

log = logging.getLogger("radarodom.tools.radar_echo")

DEFAULT_KINDS = ("odom", "status")
#: How long the receive loop waits before looking again (Ctrl-C, the "nothing yet" hint).
_POLL_S = 0.25
#: After this long with nothing received and no peer, say what to check.
_QUIET_HINT_S = 5.0
#: Messages received and not yet printed, at most; a flood beyond is dropped and counted.
_BACKLOG = 1000
#: The longest reason a warning about a bad message quotes.
_REASON_CHARS = 200
#: A number at least this large is printed as 1.23e+15, not digit by digit.
_FIXED_BELOW = 1e15
#: The largest payload taken off the network, per kind (the readers' own bounds).
_MAX_BYTES = {"odom": messages.MAX_JSON_BYTES, "status": messages.MAX_JSON_BYTES,
              "pointcloud": messages.MAX_BINARY_BYTES, "heatmap": messages.MAX_BINARY_BYTES}


class _EchoParser(argparse.ArgumentParser):
    """Checks the KINDs after the options: an unknown option's value ('--duration 2') taken as a
    KIND was reported as a bad KIND, not as the unknown option it follows."""

    def parse_args(self, args=None, namespace=None):  # type: ignore[override]
        parsed = super().parse_args(args, namespace)
        bad = [kind for kind in parsed.kinds if kind not in KINDS]
        if bad:
            self.error(f"argument KIND: expected one of {', '.join(KINDS)}, got {bad[0]!r}")
        return parsed


def build_parser() -> argparse.ArgumentParser:
    parser = _EchoParser(
        prog="radar-echo",
        description="Print what radarodom publishes over Zenoh, live, one line per message: odometry "
                    "(t, frame, x, y, yaw, speed, flags), status (JSON), point clouds (frame, t, count), "
                    "heatmaps (frame, t, shape).")
    parser.add_argument("kinds", nargs="*", metavar="KIND",
                        help=f"what to print: {', '.join(KINDS)} (default: {' '.join(DEFAULT_KINDS)})")
    parser.add_argument("--count", type=cli.positive_int, metavar="N", help="exit after N messages")
    parser.add_argument("--json", action="store_true",
                        help="print one JSON object per message (odometry and status whole, the headers "
                             "of point clouds and heatmaps), with its key")
    add_zenoh_arguments(parser)
    cli.add_verbosity(parser)
    return parser


def _printable(text: str, limit: int) -> str:
    """*text* safe on one terminal line (:func:`radarodom.errors.one_line`: control characters and
    lone surrogates escaped), cut to *limit* characters."""
    text = one_line(text)
    return text if len(text) <= limit else text[:limit] + "..."


def _fixed(value: float, decimals: int) -> str:
    """*value* with *decimals* decimals, as ``1e+300`` where that would take hundreds of digits (a
    peer's numbers: finite, any size)."""
    return f"{value:.{decimals}f}" if abs(value) < _FIXED_BELOW else f"{value:.3g}"


def _odom_line(payload: bytes) -> tuple[str, dict]:
    m = messages.parse_odometry(payload)
    yaw_deg = math.degrees(m["yaw"])  # inf past 1.8e306 rad: then said in radians
    yaw = f"{_fixed(yaw_deg, 2)} deg" if math.isfinite(yaw_deg) else f"{_fixed(m['yaw'], 2)} rad"
    text = (f"odom frame {m['frame']} t {_fixed(m['t'], 3)} x {_fixed(m['x'], 3)} y {_fixed(m['y'], 3)} m "
            f"yaw {yaw} v {_fixed(math.hypot(m['vx'], m['vy']), 3)} m/s")
    # The flags are any peer's strings: escaped and cut, so a message stays one line.
    return text + (f" [{_printable(','.join(m['flags']), _REASON_CHARS)}]" if m["flags"] else ""), m


def _status_line(payload: bytes) -> tuple[str, dict]:
    m = messages.parse_status(payload)
    return "status " + strict_json.dumps(m, separators=(",", ":")), m


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
    """The line radar-echo prints for one message (raises MessageError when it is malformed).
    With *as_json*, standard JSON (ASCII, no NaN or infinity) with ``key`` first: the Zenoh
    key, which wins over a ``key`` field of the message."""
    text, obj = _FORMATS[kind](payload)
    if not as_json:
        return text
    return strict_json.dumps({"key": key, **{k: v for k, v in obj.items() if k != "key"}}, separators=(",", ":"))


#: What the inbox holds for a key's DELETE (a Zenoh sample of no message: a program's
#: session.delete() on the key), told apart from a malformed message.
DELETED = object()


class _Inbox:
    """What the Zenoh threads received, for the main thread: (kind, key, payload or None,
    size).  At most *backlog* wait; the rest are counted, not kept.  A payload over its kind's
    bound is not copied off the network (None, with its size)."""

    def __init__(self, backlog: int = _BACKLOG) -> None:
        self._queue: queue.Queue = queue.Queue(backlog)
        self._lock = threading.Lock()
        self._dropped: dict[str, int] = {}

    def receiver(self, kind: str) -> Callable[[Any], None]:
        limit = _MAX_BYTES[kind]

        # Runs on a zenoh thread: it must never raise, and never wait on the main thread.
        def receive(sample: Any) -> None:
            key, size = str(sample.key_expr), len(sample.payload)
            if sample.kind == zenoh.SampleKind.DELETE:  # another program's session.delete() on the key
                payload = DELETED
            else:
                payload = sample.payload.to_bytes() if size <= limit else None
            try:
                self._queue.put_nowait((kind, key, payload, size))
            except queue.Full:
                with self._lock:
                    self._dropped[key] = self._dropped.get(key, 0) + 1
        return receive

    def get(self, timeout: float) -> tuple[str, str, bytes | None, int]:
        return self._queue.get(timeout=timeout)

    def take_dropped(self) -> dict[str, int]:
        with self._lock:
            dropped, self._dropped = self._dropped, {}
        return dropped


def _main(args: argparse.Namespace) -> int:
    options = options_from_args(args).for_subscriber()
    kinds = list(dict.fromkeys(args.kinds or DEFAULT_KINDS))
    inbox = _Inbox()
    session, options = open_session(options)
    try:
        # Kept referenced while the loop runs.
        _subscribers = [session.declare_subscriber(options.key(kind), inbox.receiver(kind)) for kind in kinds]
        if not args.quiet:
            print(f"radar-echo: {', '.join(options.key(k) for k in kinds)} via {options.describe()}; "
                  "Ctrl-C stops", file=sys.stderr, flush=True)
        return _print_loop(args, session, inbox, _no_peer_hint(options))
    except KeyboardInterrupt:
        return 0  # Ctrl-C is how a live listing ends: a normal exit
    finally:
        session.close()


def _no_peer_hint(options) -> str:
    """What to check when no peer is reached, for where this session looks for one."""
    connect, listen = tuple(options.effective_connect or ()), tuple(options.effective_listen or ())
    if options.config_file:
        return f"no Zenoh peer or router reached yet (config {options.config_file}): is the publisher running?"
    if connect == (DEFAULT_ENDPOINT,):
        return ("no Zenoh peer reached yet: is radar-capture publishing on this machine? "
                "(otherwise give --connect with its endpoint)")
    if connect:
        return (f"no Zenoh peer reached yet at {' '.join(connect)}: is a publisher listening there "
                f"(radar-capture --listen {connect[0]})?")
    if listen and re.search(r":0(?:[?#]|$)", listen[0]):
        return (f"no Zenoh peer has connected yet to {' '.join(listen)}: port 0 takes a free port the publisher "
                "cannot know; listen on a port of your own (e.g. tcp/127.0.0.1:7450) and give the publisher "
                "--connect to it")
    # A publisher connects to this machine's address where this one listens on every interface.
    target = re.sub(r"/(0\.0\.0\.0|\[::\]):", "/THIS_MACHINE:", listen[0]) if listen else "ENDPOINT"
    return f"no Zenoh peer has connected yet to {' '.join(listen)}: give the publisher --connect {target}"


def _print_loop(args: argparse.Namespace, session, inbox: _Inbox, no_peer_hint: str) -> int:
    printed = received = 0
    started = time.monotonic()
    hinted = False
    while args.count is None or printed < args.count:
        for key, n in inbox.take_dropped().items():
            log.warning("%s: dropped %d message(s): they came faster than they could be printed", key, n)
        try:
            kind, key, payload, size = inbox.get(timeout=_POLL_S)
        except queue.Empty:
            # Only when nothing came at all: malformed messages came from a peer (gone since, perhaps).
            if not hinted and not received and time.monotonic() - started > _QUIET_HINT_S:
                hinted = True
                if not list(session.info.peers_zid()) and not list(session.info.routers_zid()):
                    log.warning("%s", no_peer_hint)
            continue
        received += 1
        if payload is DELETED:
            log.warning("%s: ignored a DELETE (no message: a program deleted the key)", key)
            continue
        try:
            if payload is None:
                raise MessageError(f"{size} bytes, more than the {_MAX_BYTES[kind]} a message may have "
                                   "(not read)")
            line = format_message(kind, key, payload, args.json)
        except MessageError as exc:
            log.warning("%s: ignored a malformed message: %s", key, _printable(str(exc), _REASON_CHARS))
            continue
        print(line, flush=True)
        printed += 1
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
