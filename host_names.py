"""A network host as a user writes it (``192.168.1.10``, ``robot.local``, ``[::1]``), checked
before a library that would take a typo for a name to look up (Zenoh retries it for ever, Rerun
fails in a thread of its own): what is wrong with it, said with an example of the right form."""

from __future__ import annotations

import ipaddress
import re
from typing import Callable

#: A host name (RFC 1123 labels; underscores, which some networks use, allowed).
HOST_NAME = re.compile(r"(?=.{1,253}\.?$)[A-Za-z0-9_](?:[A-Za-z0-9_-]{0,61}[A-Za-z0-9_])?"
                       r"(?:\.[A-Za-z0-9_](?:[A-Za-z0-9_-]{0,61}[A-Za-z0-9_])?)*\.?")


def host_problem(host: str, written: Callable[[str], str]) -> str | None:
    """What is wrong with *host* (an IPv4 address, a host name, or an IPv6 address in brackets with
    an optional ``%scope``), or None; *written* gives an example host as the user writes it in
    its context (``lambda h: f"tcp/{h}:7447"``)."""
    if host.startswith("[") or host.endswith("]"):
        try:
            if not (host.startswith("[") and host.endswith("]")):
                raise ValueError
            ipaddress.IPv6Address(host[1:-1].partition("%")[0])
        except ValueError:
            return f"{host} is not an IPv6 address in brackets, e.g. {written('[::1]')}"
        return None
    if ":" in host:
        return f"an IPv6 address goes in brackets, e.g. {written(f'[{host}]')}"
    if re.fullmatch(r"[0-9.]+", host):  # dotted digits: an IPv4 address, or a typo of one
        try:
            ipaddress.IPv4Address(host)
        except ValueError:
            return f"{host} is not an IPv4 address"
        return None
    if not HOST_NAME.fullmatch(host):
        return f"{host!r} is not a host name or an IP address"
    return None
