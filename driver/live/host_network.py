"""This computer's side of the DCA1000's network: what a failed bind means, and its fix.

The board talks to one fixed host address (192.168.33.30 unless its EEPROM says otherwise),
so the usual first-run failure is a computer without that address; the message says which
command gives it one.
"""

from __future__ import annotations

import errno
import socket

#: Interface name prefixes that cannot be the cable to a DCA1000 (loopback, bridges, tunnels,
#: containers' virtual pairs), left out of the set-up hint.
_VIRTUAL_INTERFACES = ("lo", "ifb", "docker", "veth", "br-", "virbr", "tun", "tap", "wg", "zt", "vmnet")


def _candidate_interfaces() -> list[str]:
    """Network interfaces a DCA1000 may be plugged into, by name."""
    if not hasattr(socket, "if_nameindex"):
        return []
    return [name for _, name in socket.if_nameindex() if not name.startswith(_VIRTUAL_INTERFACES)]


def bind_problem(exc: OSError, ip: str, port: int, what: str) -> str:
    """One line saying why binding *what* to ip:port failed, and the fix."""
    base = f"cannot {what} on {ip}:{port}: {exc.strerror or exc}"
    if exc.errno == errno.EADDRNOTAVAIL:
        names = _candidate_interfaces()
        iface = names[0] if len(names) == 1 else "IFACE"
        listed = f" (interfaces here: {', '.join(names)})" if names else ""
        return (f"{base}. This computer has no address {ip}: give it to the network interface the DCA1000 "
                f"is plugged into{listed}, e.g. 'sudo ip addr add {ip}/24 dev {iface}', or to keep it, "
                f"'sudo nmcli con add type ethernet ifname {iface} con-name dca1000 ipv4.method manual "
                f"ipv4.addresses {ip}/24 && sudo nmcli con up dca1000'; or give this host's address with "
                f"?host= in the dca1000:// URL")
    if exc.errno == errno.EADDRINUSE:
        return (f"{base}. Another program holds that port (TI's DCA1000 CLI, mmWave Studio, another "
                f"radar-capture?): stop it ('sudo ss -ulpn sport = :{port}' shows which)")
    if exc.errno == errno.EACCES:
        return f"{base}. Ports below 1024 need root: use the board's default ports (4096, 4098)"
    return f"{base}. Does this host have the address {ip} (ip addr), and is no other capture program running?"


#: sendto's errors when this host address has no route to the board's.
_NO_ROUTE = (errno.EINVAL, errno.ENETUNREACH, errno.EHOSTUNREACH, errno.EADDRNOTAVAIL)


def send_problem(exc: OSError, what: str, board: tuple[str, int], host_ip: str) -> str:
    """What a failed send of *what* to the board at *board* from *host_ip* means, and the fix where
    it is the address."""
    text = f"cannot send {what} to the DCA1000 at {board[0]}:{board[1]} from {host_ip}: {exc.strerror or exc}"
    if exc.errno in _NO_ROUTE:
        text += ("; the board answers on its own network (192.168.33.x by default): give this computer an address "
                 "there and name it in the URL (dca1000://BOARD?host=ADDRESS)")
    return text
