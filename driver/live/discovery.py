"""Finding the radar on USB: the AWR1843BOOST's XDS110 serial ports and the DCA1000's FTDI.

The AWR1843BOOST carries a TI XDS110 debug probe (USB ``0451:bef3``) that
enumerates as a composite device with two CDC-ACM serial ports: the one on USB
interface 0 is the radar's CLI (115200 baud), the one on interface 3 its data
port (921600 baud).  Which ``/dev/ttyACM<n>`` each becomes depends on plug-in
order, so the port is chosen by its USB interface number, never by its tty
number or by "the lowest one":

1. the symlinks our udev rules make (``udev/99-radarodom.rules``):
   ``/dev/awr1843-cli``, ``/dev/awr1843-data`` and, per board,
   ``/dev/awr1843-cli-<serial>``, ``/dev/awr1843-data-<serial>``;
2. else pyserial's ``serial.tools.list_ports.comports()`` filtered on
   ``0451:bef3``, with the interface number taken from the port's ``location``
   (``'1-2:1.0'`` -> interface 0; pyserial's ``interface`` attribute is the
   interface's *name*, not its number) or, failing that, from sysfs
   (``/sys/class/tty/<name>/device/bInterfaceNumber``).

USB devices (:func:`find_usb_devices`, in :mod:`.usb_devices`) come from pyusb; without a libusb
backend they come from sysfs instead, with a note saying so.  The DCA1000EVM's
FTDI (``0451:fd03``) is listed for completeness: Ethernet streaming does not
need it.

Every function takes the ``/dev`` and ``/sys`` roots and the ``comports``
source as parameters, so tests can point them at a fake tree.  Nothing here
opens a port.
"""

from __future__ import annotations

import logging
import os
import pathlib
import re
from dataclasses import dataclass
from typing import Any, Callable, Iterable

from ...errors import DeviceError
from .usb_devices import (DCA1000_PID, DCA1000_VID, XDS110_PID, XDS110_VID, UsbDeviceInfo, UsbFind,  # noqa: F401
                          _hex4, _read_attr, _rw_access, _sysfs_usb_attrs, _usb_scan, find_usb_devices)

log = logging.getLogger(__name__)


#: USB interface number -> role of the XDS110's serial ports.
CLI_INTERFACE = 0
DATA_INTERFACE = 3
ROLES = {CLI_INTERFACE: "cli", DATA_INTERFACE: "data"}
BAUDRATES = {"cli": 115200, "data": 921600}

#: Symlink names made by udev/99-radarodom.rules (the per-board ones add "-<serial>").
LINK_PREFIX = {"cli": "awr1843-cli", "data": "awr1843-data"}

#: The XDS110's interface names (USB string descriptors), a last resort when
#: neither the location nor sysfs gives the interface number.
_INTERFACE_NAMES = {"application/user uart": "cli", "auxiliary data port": "data"}

#: '<bus>-<ports>:<config>.<interface>' (Linux) or '...:x.<interface>' (Windows).
_LOCATION_RE = re.compile(r":(?:\d+|x)\.(\d+)$")

ComportsSource = Callable[[], Iterable[Any]]


# --------------------------------------------------------------------------- results

@dataclass
class SerialPortInfo:
    """One serial port of an XDS110 (0451:bef3)."""

    #: Kernel device node, e.g. ``/dev/ttyACM0`` (symlinks resolved).
    device: str
    #: ``"cli"``, ``"data"``, or None when the interface number is neither 0 nor 3 or unknown.
    role: str | None
    #: USB interface number (0 = CLI, 3 = data), None when unknown.
    interface: int | None
    vid: int | None = None
    pid: int | None = None
    #: The XDS110's serial number (same for both ports of a board).
    serial_number: str | None = None
    #: pyserial's location, e.g. ``'1-2:1.0'``.
    location: str | None = None
    description: str | None = None
    #: Our udev symlinks that point to this port, most specific first.
    links: tuple[str, ...] = ()
    #: USB bus and device address of the XDS110, where sysfs tells.
    bus: int | None = None
    address: int | None = None
    #: The current user may open the node for reading and writing.
    accessible: bool = False
    #: How it was found: ``"udev"`` (our symlinks) or ``"pyserial"``.
    found_by: str = "pyserial"

    @property
    def name(self) -> str:
        return os.path.basename(self.device)

    @property
    def path(self) -> str:
        """The path to open: the per-board udev symlink, else the generic one, else the node."""
        return self.links[0] if self.links else self.device

    @property
    def baudrate(self) -> int | None:
        return BAUDRATES.get(self.role or "")

    def to_dict(self) -> dict[str, Any]:
        return {
            "path": self.path, "device": self.device, "role": self.role,
            "interface": self.interface, "baudrate": self.baudrate,
            "vid": _hex4(self.vid), "pid": _hex4(self.pid), "serial_number": self.serial_number,
            "location": self.location, "description": self.description, "links": list(self.links),
            "bus": self.bus, "address": self.address, "accessible": self.accessible,
            "found_by": self.found_by,
        }


# --------------------------------------------------------------------------- serial ports

def find_ports(*, dev_root: str | os.PathLike = "/dev", sys_root: str | os.PathLike = "/sys",
               comports: ComportsSource | None = None) -> list[SerialPortInfo]:
    """All serial ports of XDS110s (0451:bef3), CLI and data and any other, in a stable order.

    Ports reached through our udev symlinks come first-hand from the links
    (their role is in the link's name); ports the links do not cover come from
    *comports* (default ``serial.tools.list_ports.comports``): any object with
    pyserial's ``ListPortInfo`` attributes (``device``, ``vid``, ``pid``,
    ``serial_number``, ``location``, ``interface``, ``description``).
    """
    dev_root, sys_root = os.fspath(dev_root), os.fspath(sys_root)
    by_name: dict[str, SerialPortInfo] = {}
    for port in _ports_from_links(dev_root, sys_root):
        by_name[port.name] = port
    for port in _ports_from_comports(dev_root, sys_root, comports):
        known = by_name.get(port.name)
        if known is None:
            by_name[port.name] = port
            continue
        # The link already named this port; fill in what pyserial knows better.
        known.location = known.location or port.location
        known.description = known.description or port.description
        known.serial_number = known.serial_number or port.serial_number
        if known.interface is None:
            known.interface = port.interface
    ports = sorted(by_name.values(), key=_port_order)
    for port in ports:
        log.debug("XDS110 port %s: role %s, interface %s, serial %s, links %s, %s",
                  port.device, port.role, port.interface, port.serial_number,
                  ", ".join(port.links) or "none",
                  "accessible" if port.accessible else "no read-write access")
    return ports


def find_cli_ports(*, dev_root: str | os.PathLike = "/dev", sys_root: str | os.PathLike = "/sys",
                   comports: ComportsSource | None = None) -> list[SerialPortInfo]:
    """The XDS110 CLI ports (USB interface 0), one per radar, in a stable order
    (serial number, then USB location, then tty name)."""
    return [p for p in find_ports(dev_root=dev_root, sys_root=sys_root, comports=comports)
            if p.role == "cli"]


def find_data_ports(*, dev_root: str | os.PathLike = "/dev", sys_root: str | os.PathLike = "/sys",
                    comports: ComportsSource | None = None) -> list[SerialPortInfo]:
    """The XDS110 data ports (USB interface 3), one per radar, in the same order as
    :func:`find_cli_ports`."""
    return [p for p in find_ports(dev_root=dev_root, sys_root=sys_root, comports=comports)
            if p.role == "data"]


def default_cli_port(*, dev_root: str | os.PathLike = "/dev", sys_root: str | os.PathLike = "/sys",
                     comports: ComportsSource | None = None) -> str | None:
    """The CLI port to use when none is named: the one radar's, None without a radar.

    With several radars the first in :func:`find_cli_ports` order is chosen,
    with a warning that lists the others.  The path is a udev symlink where
    our rules are installed, else the tty node.
    """
    ports = find_cli_ports(dev_root=dev_root, sys_root=sys_root, comports=comports)
    if not ports:
        return None
    chosen = ports[0]
    if len(ports) > 1:
        log.warning("%d radars found (%s); using %s; name the CLI port to choose another",
                    len(ports), ", ".join(_port_label(p) for p in ports), chosen.path)
    return chosen.path


def require_cli_port(*, dev_root: str | os.PathLike = "/dev", sys_root: str | os.PathLike = "/sys",
                     comports: ComportsSource | None = None) -> str:
    """:func:`default_cli_port`, or :class:`~radarodom.errors.DeviceError` saying what
    was looked for when there is no radar."""
    port = default_cli_port(dev_root=dev_root, sys_root=sys_root, comports=comports)
    if port is None:
        raise DeviceError(no_radar_message(dev_root=dev_root))
    return port


def describe_search(*, dev_root: str | os.PathLike = "/dev") -> str:
    """What the search for a radar looks at, in words."""
    root = os.fspath(dev_root).rstrip("/") or "/"
    return (f"the udev symlinks {os.path.join(root, LINK_PREFIX['cli'])}* and serial ports of "
            f"a TI XDS110 (USB {XDS110_VID:04x}:{XDS110_PID:04x}) on USB interface "
            f"{CLI_INTERFACE} (CLI) or {DATA_INTERFACE} (data)")


def no_radar_message(*, dev_root: str | os.PathLike = "/dev") -> str:
    """One line for when no radar is attached."""
    return f"no radar found: looked for {describe_search(dev_root=dev_root)}; try sim:// or replay://"


def _port_label(port: SerialPortInfo) -> str:
    return port.path + (f" (serial {port.serial_number})" if port.serial_number else "")


def _port_order(port: SerialPortInfo) -> tuple:
    """Stable across plug-in order: serial number, then USB location, then tty name."""
    return (port.serial_number is None, port.serial_number or "",
            _numsplit(port.location or ""), _numsplit(port.name))


def _ports_from_links(dev_root: str, sys_root: str) -> list[SerialPortInfo]:
    """Ports named by our udev symlinks, grouped by the tty they point to."""
    links_of: dict[str, list[tuple[str, str, str | None]]] = {}  # tty path -> (link, role, serial)
    try:
        entries = sorted(os.listdir(dev_root))
    except OSError as exc:
        log.debug("cannot list %s: %s", dev_root, exc)
        return []
    for entry in entries:
        for role, prefix in LINK_PREFIX.items():
            if entry == prefix or entry.startswith(prefix + "-"):
                link = os.path.join(dev_root, entry)
                if not os.path.islink(link):
                    continue
                target = os.path.realpath(link)
                if not os.path.exists(target):
                    log.debug("udev link %s points to missing %s; ignored", link, target)
                    continue
                serial = entry[len(prefix) + 1:] or None
                links_of.setdefault(target, []).append((link, role, serial))
    ports = []
    for target, links in links_of.items():
        # Per-board links (with a serial) first: they name one board whatever else is plugged.
        links.sort(key=lambda item: (item[2] is None, item[0]))
        link_role = links[0][1]
        name = os.path.basename(target)
        info = _sysfs_tty_info(sys_root, name)
        interface = info.get("interface")
        role = ROLES.get(interface) if interface is not None else link_role
        if role != link_role:
            log.warning("udev link %s says %s but %s is on USB interface %s (%s); check the rules",
                        links[0][0], link_role, target, interface, role or "neither CLI nor data")
        if interface is None:
            interface = CLI_INTERFACE if link_role == "cli" else DATA_INTERFACE
        serial = info.get("serial") or next((s for _, _, s in links if s), None)
        ports.append(SerialPortInfo(
            device=target, role=role, interface=interface,
            vid=info.get("vid", XDS110_VID), pid=info.get("pid", XDS110_PID),
            serial_number=serial, links=tuple(link for link, _, _ in links),
            bus=info.get("bus"), address=info.get("address"),
            accessible=_rw_access(target), found_by="udev"))
    return ports


def _ports_from_comports(dev_root: str, sys_root: str,
                         comports: ComportsSource | None) -> list[SerialPortInfo]:
    if comports is None:
        from serial.tools.list_ports import comports as pyserial_comports
        comports = pyserial_comports
    ports = []
    for item in comports():
        if (getattr(item, "vid", None), getattr(item, "pid", None)) != (XDS110_VID, XDS110_PID):
            continue
        device = os.path.realpath(item.device)
        name = os.path.basename(device)
        if not os.path.exists(device):
            # pyserial lists /dev names; in a fake tree, find the node under dev_root.
            candidate = os.path.join(dev_root, name)
            if os.path.exists(candidate):
                device = os.path.realpath(candidate)
        info = _sysfs_tty_info(sys_root, name)
        location = getattr(item, "location", None)
        interface = _interface_from_location(location)
        if interface is None:
            interface = info.get("interface")
        role = ROLES.get(interface) if interface is not None else None
        if interface is None:
            role = _role_from_interface_name(getattr(item, "interface", None))
            if role is not None:
                interface = CLI_INTERFACE if role == "cli" else DATA_INTERFACE
        if role is None:
            log.debug("XDS110 port %s: USB interface %s is neither CLI (%d) nor data (%d)",
                      device, interface, CLI_INTERFACE, DATA_INTERFACE)
        description = getattr(item, "description", None)
        ports.append(SerialPortInfo(
            device=device, role=role, interface=interface, vid=item.vid, pid=item.pid,
            serial_number=getattr(item, "serial_number", None) or info.get("serial"),
            location=location, description=None if description in (None, "n/a") else description,
            bus=info.get("bus"), address=info.get("address"),
            accessible=_rw_access(device), found_by="pyserial"))
    return ports


def _interface_from_location(location: str | None) -> int | None:
    """``'1-2:1.3'`` -> 3; None for a location without an interface part."""
    if not location:
        return None
    match = _LOCATION_RE.search(location)
    return int(match.group(1)) if match else None


def _role_from_interface_name(name: str | None) -> str | None:
    if not name:
        return None
    lowered = name.lower()
    for key, role in _INTERFACE_NAMES.items():
        if key in lowered:
            return role
    return None


def _sysfs_tty_info(sys_root: str, name: str) -> dict[str, Any]:
    """Interface number, VID/PID, serial, bus and address of a USB tty, from sysfs."""
    interface_dir = os.path.join(sys_root, "class", "tty", name, "device")
    if not os.path.isdir(interface_dir):
        return {}
    interface_dir = os.path.realpath(interface_dir)
    info: dict[str, Any] = {}
    number = _read_attr(interface_dir, "bInterfaceNumber")
    if number is not None:
        try:
            info["interface"] = int(number, 16)
        except ValueError:
            pass
    info.update(_sysfs_usb_attrs(os.path.dirname(interface_dir)))
    return info


def shipped_rules() -> pathlib.Path | None:
    """The udev rules file installed with the package, if present."""
    path = pathlib.Path(__file__).resolve().parent.parent / "udev" / "99-radarodom.rules"
    return path if path.is_file() else None


def _numsplit(text: str) -> list:
    """'ttyACM10' -> ['ttyACM', 10]: natural order, ttyACM2 before ttyACM10.
    Numbers and text are tagged so mixed keys stay comparable."""
    return [(0, int(part), "") if part.isdigit() else (1, 0, part)
            for part in re.split(r"(\d+)", text) if part]


