"""The source to stream when none is named: the radar found on USB, through its DCA1000 where one
is attached, else the board alone through its demo firmware's UART (``tidemo://``).

Most AWR1843BOOST owners have no DCA1000, and ``dca1000://`` without one fails at its first
step asking for a network address the user has no reason to set.  A DCA1000 is taken to be
there when either sign of one is: its FTDI on USB (0451:fd03; its Ethernet streaming does not
need that cable, so it may be unplugged) or this computer holding the address the board sends
its data to (192.168.33.30, which set-up gives an interface: docs/live.md).  Neither opens the
radar's ports.
"""

from __future__ import annotations

import logging
import os
import socket
from urllib.parse import quote

from .dca1000_wire import HOST_IP
from .discovery import default_cli_port, no_radar_message
from .usb_devices import UsbFind, find_usb_devices

log = logging.getLogger(__name__)


def dca1000_sign(*, dev_root: str | os.PathLike = "/dev", sys_root: str | os.PathLike = "/sys",
                 host_ip: str = HOST_IP, usb_find: UsbFind | None = None) -> str | None:
    """What shows that a DCA1000 is attached (for the log), or None when nothing does."""
    if any(d.kind == "dca1000" for d in find_usb_devices(dev_root=dev_root, sys_root=sys_root, usb_find=usb_find)):
        return "the DCA1000's USB (0451:fd03) is plugged in"
    if _holds_address(host_ip):
        return f"this computer has {host_ip}, the address a DCA1000 sends to"
    return None


def _holds_address(ip: str) -> bool:
    """Whether one of this computer's interfaces has *ip* (a socket binds to it)."""
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
            sock.bind((ip, 0))
    except OSError:
        return False
    return True


def live_source_url(cli_port: str, *, dev_root: str | os.PathLike = "/dev", sys_root: str | os.PathLike = "/sys",
                    host_ip: str = HOST_IP, usb_find: UsbFind | None = None) -> str:
    """The URL that streams the radar whose CLI port is *cli_port*: ``dca1000://`` where a DCA1000
    shows (:func:`dca1000_sign`), else ``tidemo://``; the choice and why are logged."""
    cli = quote(cli_port, safe="/")
    sign = dca1000_sign(dev_root=dev_root, sys_root=sys_root, host_ip=host_ip, usb_find=usb_find)
    if sign:
        log.info("radar found on %s and %s: streaming its raw ADC frames through the DCA1000 at the standard "
                 "addresses", cli_port, sign)
        return f"dca1000://?cli={cli}"
    log.warning("radar found on %s, and no DCA1000 (its USB 0451:fd03 is not plugged in and this computer does "
                "not have %s): streaming the board's own points and heatmap over its UART, tidemo:// "
                "(docs/tidemo.md); --source dca1000:// takes the DCA1000 path", cli_port, host_ip)
    return f"tidemo://?cli={cli}"


def default_source_url(simulator_url: str) -> str:
    """The radar plugged in (:func:`live_source_url`), else *simulator_url*, with a warning."""
    port = default_cli_port()
    if port is not None:
        return live_source_url(port)
    log.warning("%s. Streaming the simulator meanwhile: %s (choose a source with --source)",
                no_radar_message(), simulator_url)
    return simulator_url
