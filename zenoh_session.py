"""Zenoh sessions: the options a publisher or a subscriber opens one with, and opening it.

Without a config file the session is a peer with multicast
scouting off that listens on :data:`DEFAULT_ENDPOINT` (``tcp/127.0.0.1:7448``,
loopback only) and retries its connect endpoints every 0.1 s growing to 1 s,
so a peer or router that is down at start is joined when it comes up.  A
link's handshake may take 2 s (zenoh's default is 10 s, and closing a session
waits for pending handshakes).  A subscriber (``radar-echo``,
:meth:`ZenohOptions.for_subscriber`) connects to that endpoint and listens on
nothing: on one machine nothing goes on the network and no router is needed.
When the port is taken (a second publisher, or another program) the publisher
listens on a free loopback port instead, says which in a warning, and connects
to :data:`DEFAULT_ENDPOINT`: when a Zenoh peer holds it (another radarodom
publisher), subscribers connected there learn of this one through gossip
scouting.  Endpoints given (``listen``, ``connect``) replace the defaults and
never fall back.  A config file (JSON5, zenoh's own format) replaces all of
these defaults; options given explicitly override it.

Split off :mod:`radarodom.publish`, which re-exports the names here.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import os
import re
import socket
from dataclasses import dataclass
from typing import Any, Sequence

import zenoh

from .errors import PublishConfigError, PublishError
from .json5_brackets import unbalanced
from .zenoh_endpoints import check_config_file_settings, endpoint_list

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

DEFAULT_KEY_PREFIX = "radar/awr1843"
#: Where a publisher listens and a subscriber connects by default: a fixed
#: loopback port, so the two find each other on one machine without scouting
#: or network (7447 is a Zenoh router's, which ROS 2's rmw_zenohd takes).
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7448"
#: The router every ROS 2 node using rmw_zenoh connects to.
ROS2_ROUTER_ENDPOINT = "tcp/localhost:7447"
DEFAULT_ROS2_TOPIC = "/radar/odom"
MODES = ("peer", "client")
#: The largest Zenoh config file read, bytes (as the cfg and settings readers' limit).
MAX_CONFIG_BYTES = 1 << 20
#: Retry a connect endpoint after 0.1 s, doubling up to 1 s: a peer that comes
#: up is joined within about a second.
CONNECT_RETRY = "{period_init_ms: 100, period_max_ms: 1000, period_increase_factor: 2}"
#: A link's handshake must finish within this (zenoh's default is 10 s): closing
#: a session waits for pending handshakes, and an endpoint that accepts TCP but
#: never answers (not Zenoh, or a dead link) would hold Ctrl-C that long.
HANDSHAKE_TIMEOUT_MS = 2000
_ROS_TOPIC = re.compile(r"(/[A-Za-z_][A-Za-z0-9_]*)+")

#: The source location zenoh appends to its error messages.
_RUST_LOCATION = re.compile(r"\s+at\s+\S+\.rs:\d+\.?")


def check_ros2_topic(topic: Any) -> str:
    """*topic* if it is an absolute ROS name (``/radar/odom``); PublishConfigError otherwise."""
    if not isinstance(topic, str) or not _ROS_TOPIC.fullmatch(topic):
        raise PublishConfigError(f"ROS 2 topic must be an absolute ROS name like /radar/odom, got {topic!r}")
    return topic


def zenoh_reason(exc: BaseException) -> str:
    """A zenoh error's message without the Rust source locations."""
    return _RUST_LOCATION.sub("", str(exc)).strip()


def _json5_where(path: str, reason: str) -> str:
    """A JSON5 parse error as one line, ``path:line:column: what`` (zenoh reports it as a
    multi-line drawing: ``--> L:C``, the text with a caret, ``= what``); other reasons as
    ``path: reason``."""
    where = re.search(r"-->\s*(\d+):(\d+)", reason)
    what = re.search(r"^\s*=\s*(.+)$", reason, re.MULTILINE)
    if where and what:
        return f"{path}:{where.group(1)}:{where.group(2)}: {what.group(1).strip()}"
    # A value the config's schema refuses comes as the Rust error's debug form, JSON5's
    # Message { msg: "...", location: Some(Location { line: L, column: C }) } and YAML's
    # Error("...", line: L, column: C).
    for form in (r'msg: "((?:[^"\\]|\\.)*)", location: Some\(Location \{ line: (\d+), column: (\d+)',
                 r'Error\("((?:[^"\\]|\\.)*)", line: (\d+), column: (\d+)\)'):
        found = re.search(form, reason)
        if found:
            message = found.group(1).replace('\\"', '"').replace("`", "'")
            return f"{path}:{found.group(2)}:{found.group(3)}: {message}"
    # YAML syntax: Error { kind: SCANNER, problem: "...", problem_mark: Mark { line: L, column: C },
    # context: "while ...", context_mark: Mark { ... } }
    mark = r'Mark \{ line: (\d+), column: (\d+) \}'
    found = re.search(rf'problem: "((?:[^"\\]|\\.)*)", problem_mark: {mark}', reason)
    if found:
        context = re.search(rf'context: "((?:[^"\\]|\\.)*)", context_mark: {mark}', reason)
        started = f" {context.group(1)} begun at {context.group(2)}:{context.group(3)}" if context else ""
        return f"{path}:{found.group(2)}:{found.group(3)}: {found.group(1)}{started}"
    return f"{path}: {reason}"


@dataclass(frozen=True)
class ZenohOptions:
    """How to open the Zenoh session and where to publish.

    ``None`` means "the default" (see the module docstring); an empty
    ``listen`` or ``connect`` means none at all.  Invalid values raise
    :class:`PublishConfigError`.
    """

    mode: str | None = None  # "peer" | "client"; default peer (or the config file's)
    connect: Sequence[str] | None = None
    listen: Sequence[str] | None = None
    config_file: str | os.PathLike | None = None  # JSON5, zenoh's format
    key_prefix: str = DEFAULT_KEY_PREFIX
    ros2: bool = False
    ros2_domain: int = 0
    ros2_topic: str = DEFAULT_ROS2_TOPIC

    def __post_init__(self) -> None:
        if self.mode is not None and self.mode not in MODES:
            raise PublishConfigError(f"zenoh mode must be one of {', '.join(MODES)}, got {self.mode!r}")
        object.__setattr__(self, "connect", endpoint_list(self.connect, "connect", connect=True))
        object.__setattr__(self, "listen", endpoint_list(self.listen, "listen", connect=False))
        _check_key_prefix(self.key_prefix)
        if isinstance(self.ros2_domain, bool) or not isinstance(self.ros2_domain, int) \
                or not 0 <= self.ros2_domain <= 232:
            raise PublishConfigError(f"ROS 2 domain must be a whole number from 0 to 232, got {self.ros2_domain!r}")
        check_ros2_topic(self.ros2_topic)
        if self.config_file is None and self.effective_mode == "client":
            if self.listen:
                raise PublishConfigError("a Zenoh client does not listen: drop --listen, or use --mode peer")
            if not self.effective_connect:
                raise PublishConfigError("--mode client needs --connect with a Zenoh router's endpoint, "
                                         "e.g. tcp/192.168.1.10:7447")

    @property
    def effective_mode(self) -> str | None:
        """The mode set on the session; None: the config file's."""
        return self.mode or (None if self.config_file else "peer")

    @property
    def effective_listen(self) -> tuple[str, ...] | None:
        """The listen endpoints set on the session; None: the config file's."""
        if self.listen is not None or self.config_file:
            return self.listen
        return (DEFAULT_ENDPOINT,) if self.effective_mode == "peer" else ()

    @property
    def effective_connect(self) -> tuple[str, ...] | None:
        """The connect endpoints set on the session; None: the config file's."""
        if self.connect is not None or self.config_file:
            return self.connect
        return (ROS2_ROUTER_ENDPOINT,) if self.ros2 else ()

    def key(self, kind: str) -> str:
        """The key of one published stream (``odom``, ``pointcloud``, ...) under the prefix."""
        return f"{self.key_prefix}/{kind}"

    def for_subscriber(self) -> ZenohOptions:
        """These options for a program that subscribes: it never takes the
        publisher's default endpoint (listens on nothing unless told), and with
        no endpoint given connects to it.  A config file is left as it is."""
        if self.config_file:
            return self
        connect = self.connect
        if connect is None:
            connect = (DEFAULT_ENDPOINT,) if self.listen is None else ()
        return dataclasses.replace(self, connect=connect, listen=self.listen or ())

    def describe(self) -> str:
        """Where the session goes, for messages: ``listen ... connect ...``."""
        parts = [f"config {os.fspath(self.config_file)}"] if self.config_file else []
        for name, endpoints in (("listen", self.effective_listen), ("connect", self.effective_connect)):
            if endpoints:
                parts.append(f"{name} {' '.join(endpoints)}")
        return f"{self.effective_mode or 'as configured'}" + (f", {', '.join(parts)}" if parts else "")

    def to_config(self) -> zenoh.Config:
        """The zenoh.Config: the config file (if any), then these options."""
        if self.config_file:
            path = os.fspath(self.config_file)
            _check_config_file(path)
            try:
                config = zenoh.Config.from_file(path)
            except zenoh.ZError as exc:
                # A text cut short, zenoh reports as a value expected elsewhere.
                broken = _read_text(path) if path.endswith((".json", ".json5")) else None
                where = unbalanced(broken) if broken is not None else None
                raise PublishConfigError(f"zenoh config {path}:{where}" if where else
                                         f"zenoh config {_json5_where(path, zenoh_reason(exc))}") from None
            check_config_file_settings(config.get_json, path, _read_text(path), mode=self.mode, listen=self.listen,
                                       connect=self.connect)
        else:
            config = zenoh.Config()
            # One machine, no network: no multicast; peers found by endpoint only.
            _insert(config, "scouting/multicast/enabled", "false")
            _insert(config, "connect/retry", CONNECT_RETRY)
            _insert(config, "transport/unicast/open_timeout", str(HANDSHAKE_TIMEOUT_MS))
        if self.effective_mode is not None:
            _insert(config, "mode", json.dumps(self.effective_mode))
        for name, endpoints in (("listen", self.effective_listen), ("connect", self.effective_connect)):
            if endpoints is not None:
                _insert(config, f"{name}/endpoints", json.dumps(list(endpoints)))
        return config


def _read_text(path: str) -> str:
    with open(path, encoding="utf-8", errors="replace") as fh:
        return fh.read()


def _check_config_file(path: str) -> None:
    """A config file zenoh can read whole: a regular file (zenoh reads /dev/zero for ever) of
    at most :data:`MAX_CONFIG_BYTES`."""
    if not os.path.isfile(path):
        what = "not a regular file" if os.path.exists(path) else "no such file"
        raise PublishConfigError(f"zenoh config {path}: {what}")
    size = os.path.getsize(path)
    if size > MAX_CONFIG_BYTES:
        raise PublishConfigError(f"zenoh config {path}: {size} bytes, more than the {MAX_CONFIG_BYTES} "
                                 "a config may be")
    if path.endswith((".json", ".json5")):  # zenoh takes a list, or nothing, for an empty config
        with open(path, "rb") as fh:
            text = fh.read().decode("utf-8-sig", "replace")  # a BOM, as zenoh takes it
        body = re.sub(r"^(?:\s+|//[^\n]*(?:\n|$)|/\*.*?\*/)*", "", text, flags=re.DOTALL)
        if not body.startswith("{"):
            raise PublishConfigError(f"zenoh config {path}: not a JSON5 object ({{ mode: \"peer\", ... }})")


def _check_key_prefix(prefix: Any) -> None:
    if not isinstance(prefix, str) or not prefix:
        raise PublishConfigError(f"key prefix must be a non-empty string, got {prefix!r}")
    if any(c in prefix for c in "*$?#"):
        raise PublishConfigError(f"key prefix {prefix!r}: wildcards and the characters $ ? # are not allowed")
    if any(c.isspace() or not c.isprintable() for c in prefix):  # a newline split the status line in two
        raise PublishConfigError(f"key prefix {prefix!r}: spaces and control characters are not allowed")
    try:
        zenoh.KeyExpr(prefix)
    except zenoh.ZError as exc:
        raise PublishConfigError(f"key prefix {prefix!r} is not a Zenoh key expression "
                                 f"(chunks separated by single slashes): {zenoh_reason(exc)}") from None


def _insert(config: zenoh.Config, key: str, value: str) -> None:
    try:
        config.insert_json5(key, value)
    except zenoh.ZError as exc:
        raise PublishConfigError(f"zenoh config {key} = {value}: {zenoh_reason(exc)}") from None


def _free_loopback_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def open_session(options: ZenohOptions) -> tuple[zenoh.Session, ZenohOptions]:
    """Open a Zenoh session; returns it and the options it was opened with.

    When the default listen endpoint is taken, falls back (see the module
    docstring) and returns the options of the fallback.  Raises
    :class:`PublishConfigError` for unusable options and :class:`PublishError`
    when the session cannot open.
    """
    try:
        return zenoh.open(options.to_config()), options
    except zenoh.ZError as exc:
        reason = zenoh_reason(exc)
        unsupported = _unsupported_protocol(options, reason)
        if unsupported:
            raise PublishConfigError(unsupported) from None
        # Only the built-in default falls back: an endpoint the user chose is meant.
        if not (options.effective_listen == (DEFAULT_ENDPOINT,) and options.listen is None
                and "already in use" in reason):
            raise PublishError(_open_failure(options, reason)) from None
    fallback = dataclasses.replace(options, listen=(f"tcp/127.0.0.1:{_free_loopback_port()}",),
                                   connect=tuple(options.effective_connect or ()) + (DEFAULT_ENDPOINT,))
    log.warning("%s is in use: listening on %s instead (subscribers connect there, or reach this "
                "publisher through a Zenoh peer on %s)", DEFAULT_ENDPOINT, fallback.listen[0], DEFAULT_ENDPOINT)
    try:
        return zenoh.open(fallback.to_config()), fallback
    except zenoh.ZError as exc:
        raise PublishError(_open_failure(fallback, zenoh_reason(exc))) from None


def _unsupported_protocol(options: ZenohOptions, reason: str) -> str | None:
    """What to say of an endpoint whose protocol this Zenoh does not have (a typo such as tcpx/):
    a usage error naming the option or the config file that gave it; None for other failures."""
    found = re.search(r"not supported for (\S+) protocol", reason)
    if not found:
        return None
    protocol = found.group(1)
    given = [f"--{name} {e}" for name, endpoints in (("listen", options.listen), ("connect", options.connect))
             for e in endpoints or () if e.split("/", 1)[0] == protocol]
    where = ", ".join(given) or (f"zenoh config {os.fspath(options.config_file)}" if options.config_file
                                 else "an endpoint")
    return (f"{where}: Zenoh has no {protocol!r} protocol ({reason}); give one it has, e.g. "
            f"tcp/192.168.1.10:7447 (tcp, udp, tls, quic, ws)")


def _open_failure(options: ZenohOptions, reason: str) -> str:
    text = f"cannot open the Zenoh session ({options.describe()}): {reason}"
    if options.effective_mode == "client" or (options.config_file and "Unable to connect" in reason):
        text += " (is the Zenoh router running? Without a router use --mode peer)"
    elif "already in use" in reason:
        text += " (another program listens there: choose another --listen)"
    elif "TLS" in reason:  # tls/ and quic/ endpoints
        text += (" (tls/ and quic/ endpoints need TLS certificates, given in a Zenoh config file "
                 "(--zenoh-config) under transport/link/tls: listen_certificate and listen_private_key "
                 "to listen, root_ca_certificate to connect; or use tcp/)")
    return text


def _close_session(session: zenoh.Session) -> None:
    try:
        session.close()
    except zenoh.ZError as exc:
        log.warning("closing the Zenoh session: %s", zenoh_reason(exc))
