"""Zenoh endpoints checked before a session opens: their text (``PROTOCOL/HOST:PORT``), two
that name one socket, and the mode and endpoints a Zenoh config file sets.

Zenoh itself reports a bad endpoint late and vaguely: a connect endpoint it cannot parse is
retried for ever without a word, a listen endpoint's bad port fails the session naming no
endpoint, and a socket listened on twice reads "address already in use" as if another program
held it.  Split off :mod:`radarodom.zenoh_session`.
"""

from __future__ import annotations

import ipaddress
import json
import os
import re
import socket
import stat
from typing import Any, Callable

from .errors import PublishConfigError
from .host_names import host_problem

#: Protocols whose address is host:port.
INET_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws")
#: The transport under each host:port protocol: two endpoints on one port share its socket.
_TRANSPORT = {"tcp": "tcp", "tls": "tcp", "ws": "tcp", "udp": "udp", "quic": "udp"}
#: Addresses that listen on every interface: ``0.0.0.0`` takes the port on every IPv4 address,
#: ``::`` on every address (Linux's IPv6 sockets take IPv4 too unless told otherwise).
_EVERY_IPV4, _EVERY_ADDRESS = "0.0.0.0", "::"
_LOOPBACK_NAMES = {"localhost": "127.0.0.1", "ip6-localhost": "::1"}


def check_endpoint(endpoint: Any, option: str, *, connect: bool) -> str:
    """*endpoint* if Zenoh can use it (PublishConfigError naming *option* otherwise); a connect
    endpoint needs a port other than 0 (a listen endpoint on port 0 takes a free one)."""
    if not isinstance(endpoint, str) or "/" not in endpoint:
        raise PublishConfigError(f"{option}: {endpoint!r} is not an endpoint; expected "
                                 "PROTOCOL/ADDRESS, e.g. tcp/192.168.1.10:7447")
    protocol, _ = endpoint.split("/", 1)
    if protocol == "unixsock-stream" and not connect:
        _check_socket_path(endpoint, option)
    if protocol not in INET_PROTOCOLS:
        return endpoint
    _, port = _host_port(endpoint, option)
    if port == 0 and connect:
        raise PublishConfigError(f"{option}: {endpoint!r}: port 0 is no port to connect to; give the "
                                 "port the peer or router listens on, e.g. 7447")
    return endpoint


def _check_socket_path(endpoint: str, option: str) -> None:
    """A Unix socket's path to listen on: Zenoh deletes whatever is there, and PATH.lock beside it,
    to make its socket.  What a Zenoh session left there (killed: its socket and its empty lock
    file) may go; anything else is the user's and refused, as is a path in no directory."""
    path = re.split(r"[?#]", endpoint.split("/", 1)[1], maxsplit=1)[0]
    fix = "give a path of its own, e.g. unixsock-stream//tmp/radarodom.sock"
    if not os.path.isdir(os.path.dirname(os.path.abspath(path))):
        raise PublishConfigError(f"{option}: {endpoint!r}: no directory {os.path.dirname(path)!r} to make the "
                                 "socket in: make it first, or give a path in one")
    left_by_zenoh = ((path, "socket", lambda st: stat.S_ISSOCK(st.st_mode)),
                     (path + ".lock", "empty lock file", lambda st: stat.S_ISREG(st.st_mode) and not st.st_size))
    for place, what, is_left in left_by_zenoh:
        try:
            found = os.lstat(place)
        except FileNotFoundError:
            continue
        if not is_left(found):
            raise PublishConfigError(f"{option}: {endpoint!r}: {place} is there and is not the {what} a Zenoh "
                                     f"session leaves: Zenoh would delete it to listen there; {fix}")


def _host_port(endpoint: str, option: str) -> tuple[str, int]:
    """The host (an IP address's text, or a name) and port of a host:port endpoint."""
    protocol, address = endpoint.split("/", 1)
    address = re.split(r"[?#]", address, maxsplit=1)[0]
    host, _, port = address.rpartition(":")
    if not host or not port.isascii() or not port.isdigit():
        raise PublishConfigError(f"{option}: {endpoint!r} needs HOST:PORT after {protocol}/, "
                                 f"e.g. {protocol}/192.168.1.10:7447")
    if int(port) > 65535:
        raise PublishConfigError(f"{option}: {endpoint!r}: port {port} is above 65535")
    problem = host_problem(host, lambda example: f"{protocol}/{example}:{port}")
    if problem:
        raise PublishConfigError(f"{option}: {endpoint!r}: {problem}")
    if host.startswith("["):
        address, _, scope = host[1:-1].partition("%")
        address = str(ipaddress.IPv6Address(address))
        if scope and not scope.isdigit():
            raise PublishConfigError(f"{option}: {endpoint!r}: {_scope_by_number(protocol, address, scope, port)}")
        return address, int(port)
    if re.fullmatch(r"[0-9.]+", host):
        return str(ipaddress.IPv4Address(host)), int(port)
    return _LOOPBACK_NAMES.get(host.lower(), host.lower()), int(port)


def _scope_by_number(protocol: str, address: str, scope: str, port: str) -> str:
    """What to write instead of an interface's name after an IPv6 address's ``%``: Zenoh looks the
    whole text up as a host name, which fails, and retries a connect endpoint for ever."""
    try:
        number = socket.if_nametoindex(scope)
    except OSError:
        return (f"Zenoh takes the interface by its number, not its name, and this machine has no interface "
                f"named {scope!r}; `ip link` lists them with their numbers: {protocol}/[{address}%NUMBER]:{port}")
    return (f"Zenoh takes the interface by its number, not its name: {protocol}/[{address}%{number}]:{port} "
            f"({scope} is interface {number} here)")


def endpoint_list(value: Any, option: str, *, connect: bool) -> tuple[str, ...] | None:
    """The endpoints of an option (a string or a sequence of them; None stays None), each
    checked, no two on one socket."""
    if value is None:
        return None
    if isinstance(value, str):
        value = (value,)
    endpoints = tuple(check_endpoint(e, option, connect=connect) for e in value)
    check_distinct(endpoints, option, connect=connect)
    return endpoints


def check_distinct(endpoints: tuple[str, ...], option: str, *, connect: bool) -> None:
    """PublishConfigError when an endpoint is given twice or, to listen on, two name one socket
    (localhost and 127.0.0.1, or an address and every interface on the same port): Zenoh's
    second listener found the first there and said another program listens.  Two connect
    endpoints to one peer are two links (``?prio=`` ranges, say), so only their text is compared."""
    seen: list[tuple[str, tuple[str, str, int] | None]] = []
    for endpoint in endpoints:
        place = None if connect else _place(endpoint)
        for earlier, earlier_place in seen:
            if endpoint == earlier:
                raise PublishConfigError(f"{option}: {endpoint} is given twice: give each endpoint once")
            if place and earlier_place and _same_socket(place, earlier_place):
                wildcard = {place[1], earlier_place[1]} & {_EVERY_IPV4, _EVERY_ADDRESS}
                raise PublishConfigError(f"{option}: {earlier} and {endpoint} are the same socket"
                                         + (" (0.0.0.0 listens on every IPv4 address, [::] on every address, "
                                            "taking the port on all of them)" if wildcard else "") + ": give one")
        seen.append((endpoint, place))


def _place(endpoint: str) -> tuple[str, str, int] | None:
    protocol = endpoint.split("/", 1)[0]
    if protocol not in _TRANSPORT:
        return None
    host, port = _host_port(endpoint, "")
    return _TRANSPORT[protocol], host, port


def _same_socket(a: tuple[str, str, int], b: tuple[str, str, int]) -> bool:
    """Whether listening on *a* and on *b* (transport, host, port) takes one socket twice."""
    if a[0] != b[0] or a[2] != b[2] or a[2] == 0:
        return False
    hosts = {a[1], b[1]}
    if a[1] == b[1] or _EVERY_ADDRESS in hosts:
        return True
    return _EVERY_IPV4 in hosts and all(_is_ipv4(host) for host in hosts)


def _is_ipv4(host: str) -> bool:
    try:
        ipaddress.IPv4Address(host)
    except ValueError:
        return False
    return True


def check_config_file_settings(get_json: Callable[[str], str], path: str, text: str, *, mode: str | None,
                               listen: tuple[str, ...] | None, connect: tuple[str, ...] | None) -> None:
    """Check what a Zenoh config file sets, as the options are checked: its endpoints (those
    the options given replace are left alone) and a client's need of a router.  *get_json* reads
    a key of the loaded config (``zenoh.Config.get_json``), *text* is the file's, for lines;
    *mode*, *listen*, *connect* the options given (None: the file's)."""
    mode = mode or json.loads(get_json("mode")) or "peer"
    given = {"listen": listen, "connect": connect}
    chosen: dict[str, tuple[str, ...]] = {}
    for name in ("listen", "connect"):
        if given[name] is not None:
            chosen[name] = given[name]
            continue
        value = json.loads(get_json(f"{name}/endpoints"))
        per_mode = value if isinstance(value, dict) else {None: value}  # Zenoh's {router: [...], peer: [...]}
        for each_mode, endpoints in per_mode.items():
            keys = (name, "endpoints") + ((each_mode,) if each_mode else ())
            for endpoint in endpoints:
                check_endpoint(endpoint, _where(path, text, endpoint, keys), connect=name == "connect")
        chosen[name] = tuple(per_mode.get(mode if isinstance(value, dict) else None) or ())
        check_distinct(chosen[name], f"zenoh config {path}: {name}/endpoints", connect=name == "connect")
    # A client finds a router by multicast scouting, Zenoh's default, unless the file turns it off.
    if mode == "client" and not chosen["connect"] and json.loads(get_json("scouting/multicast/enabled")) is False:
        raise PublishConfigError(f"zenoh config {path}: mode \"client\" with multicast scouting off needs a Zenoh "
                                 "router's endpoint to connect to: add connect: { endpoints: "
                                 "[\"tcp/192.168.1.10:7447\"] }, give --connect, or turn scouting/multicast on")


def _where(path: str, text: str, endpoint: str, keys: tuple[str, ...]) -> str:
    """``zenoh config PATH:LINE: KEY``: the line of the endpoint's text that follows its keys
    (``connect``, ``endpoints``, a mode) outside comments, quoted or (YAML) bare; none if not found."""
    code = re.sub(r"(?m)^[ \t]*(?://|#).*$", lambda comment: " " * len(comment.group()), text)
    at = 0
    for key in keys:
        found = re.compile(rf"(?<![\w-])[\"']?{re.escape(key)}[\"']?\s*:").search(code, at)
        at = found.end() if found else at
    bare = re.escape(endpoint)
    found = re.compile(rf"([\"']){bare}\1|(?<=[\s\[,-]){bare}(?=[ \t]*(?:$|[,\]#]))", re.M).search(code, at)
    line = f":{text.count(chr(10), 0, found.start()) + 1}" if found else ""
    return f"zenoh config {path}{line}: {'/'.join(keys)}"
