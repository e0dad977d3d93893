"""What ``radar-devices`` shows: every AWR1843BOOST found, its XDS110 on USB and its two serial
ports grouped by board (:func:`scan`), with notes on what could not be seen and why.  The
serial ports come from :mod:`.discovery`, the USB devices from :mod:`.usb_devices`."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any, Sequence

from .discovery import ComportsSource, SerialPortInfo, _numsplit, describe_search, find_ports
from .usb_devices import UsbDeviceInfo, UsbFind, _usb_scan


@dataclass
class RadarInfo:
    """One AWR1843BOOST: its XDS110 on USB and its two serial ports, as far as seen."""

    serial_number: str | None
    usb: UsbDeviceInfo | None = None
    cli: SerialPortInfo | None = None
    data: SerialPortInfo | None = None
    #: Ports of the same XDS110 on other interfaces, or a second port for a role.
    other_ports: list[SerialPortInfo] = field(default_factory=list)

    @property
    def ports(self) -> list[SerialPortInfo]:
        return [p for p in (self.cli, self.data) if p is not None] + self.other_ports

    @property
    def accessible(self) -> bool:
        """Both UART ports are there and the current user may open them."""
        return all(p is not None and p.accessible for p in (self.cli, self.data))

    def to_dict(self) -> dict[str, Any]:
        return {
            "serial_number": self.serial_number,
            "usb": self.usb.to_dict() if self.usb else None,
            "cli": self.cli.to_dict() if self.cli else None,
            "data": self.data.to_dict() if self.data else None,
            "other_ports": [p.to_dict() for p in self.other_ports],
            "accessible": self.accessible,
        }


@dataclass
class DeviceReport:
    """Everything :func:`scan` found, with notes on what it could not look at."""

    radars: list[RadarInfo]
    dca1000: list[UsbDeviceInfo]
    notes: list[str]
    #: What was looked for (:func:`describe_search`).
    looked_for: str

    @property
    def found_anything(self) -> bool:
        return bool(self.radars or self.dca1000)

    @property
    def default_cli_port(self) -> str | None:
        for radar in self.radars:
            if radar.cli is not None:
                return radar.cli.path
        return None

    def to_dict(self) -> dict[str, Any]:
        return {
            "radars": [r.to_dict() for r in self.radars],
            "dca1000": [d.to_dict() for d in self.dca1000],
            "default_cli_port": self.default_cli_port,
            "notes": list(self.notes),
            "looked_for": self.looked_for,
        }


def scan(*, dev_root: str | os.PathLike = "/dev", sys_root: str | os.PathLike = "/sys",
         comports: ComportsSource | None = None, usb_find: UsbFind | None = None) -> DeviceReport:
    """Serial ports and USB devices, grouped by radar, with notes (what ``radar-devices`` shows)."""
    dev_root, sys_root = os.fspath(dev_root), os.fspath(sys_root)
    ports = find_ports(dev_root=dev_root, sys_root=sys_root, comports=comports)
    usb_devices, notes = _usb_scan(dev_root, sys_root, usb_find)
    radars = _group(ports, [d for d in usb_devices if d.kind == "xds110"])
    cli_count = sum(1 for r in radars if r.cli is not None)
    if cli_count > 1:
        notes.append(f"{cli_count} radars found; radarodom uses the first CLI port listed "
                     "unless one is named")
    for radar in radars:
        if radar.usb is not None and not radar.ports:
            notes.append(f"XDS110 on USB bus {radar.usb.bus} device {radar.usb.address} has no "
                         "serial ports: is the cdc_acm kernel module loaded?")
    return DeviceReport(radars=radars,
                        dca1000=[d for d in usb_devices if d.kind == "dca1000"],
                        notes=notes, looked_for=describe_search(dev_root=dev_root))


def _group(ports: Sequence[SerialPortInfo], xds110s: Sequence[UsbDeviceInfo]) -> list[RadarInfo]:
    """One :class:`RadarInfo` per XDS110: ports of one board share its serial number
    (or, without one, its bus/address or USB location)."""
    radars: dict[tuple, RadarInfo] = {}
    for port in ports:
        key = _board_key(port.serial_number, port.bus, port.address, port.location, port.name)
        radar = radars.setdefault(key, RadarInfo(serial_number=port.serial_number))
        if port.role == "cli" and radar.cli is None:
            radar.cli = port
        elif port.role == "data" and radar.data is None:
            radar.data = port
        else:
            radar.other_ports.append(port)
    for device in xds110s:
        radar = next((r for r in radars.values() if _same_board(r, device)), None)
        if radar is None:
            radar = radars.setdefault(("usb", device.bus, device.address),
                                      RadarInfo(serial_number=device.serial_number))
        radar.usb = device
        radar.serial_number = radar.serial_number or device.serial_number
    return sorted(radars.values(), key=lambda r: (
        r.serial_number is None, r.serial_number or "",
        _numsplit(next((p.location or p.name for p in r.ports), "")),
        (r.usb.bus or 0, r.usb.address or 0) if r.usb else (0, 0)))


def _board_key(serial: str | None, bus: int | None, address: int | None,
               location: str | None, name: str) -> tuple:
    if serial:
        return ("serial", serial)
    if bus is not None and address is not None:
        return ("usb", bus, address)
    if location and ":" in location:
        return ("location", location.split(":", 1)[0])
    return ("tty", name)


def _same_board(radar: RadarInfo, device: UsbDeviceInfo) -> bool:
    if radar.serial_number and device.serial_number:
        return radar.serial_number == device.serial_number
    return any(p.bus is not None and (p.bus, p.address) == (device.bus, device.address)
               for p in radar.ports)
