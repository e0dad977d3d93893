"""The radar's and the capture board's USB devices: the AWR1843BOOST's XDS110 debug probe and
the DCA1000EVM's FTDI, from pyusb or, without a libusb backend, from sysfs (with a note saying
so), and the sysfs and access helpers the serial-port discovery shares (:mod:`.discovery`).

Every function takes the ``/dev`` and ``/sys`` roots as parameters, so tests can point them at
a fake tree.  Nothing here opens a device.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from typing import Any, Callable

log = logging.getLogger(__name__)

#: TI XDS110 debug probe on the AWR1843BOOST.
XDS110_VID, XDS110_PID = 0x0451, 0xBEF3
#: FTDI FT4232H on the DCA1000EVM, with TI's IDs.
DCA1000_VID, DCA1000_PID = 0x0451, 0xFD03

UsbFind = Callable[..., Any]

_KINDS = {(XDS110_VID, XDS110_PID): "xds110", (DCA1000_VID, DCA1000_PID): "dca1000"}


@dataclass
class UsbDeviceInfo:
    """One XDS110 or DCA1000 FTDI on the USB bus."""

    #: ``"xds110"`` or ``"dca1000"``.
    kind: str
    vid: int
    pid: int
    bus: int | None
    address: int | None
    #: None where it could not be read (pyusb needs access to the device; sysfs does not).
    serial_number: str | None = None
    product: str | None = None
    #: ``/dev/bus/usb/BBB/DDD``, None without bus and address.
    node: str | None = None
    #: The current user may open :attr:`node` read-write; None when the node does not exist.
    accessible: bool | None = None
    #: ``"pyusb"`` or ``"sysfs"``.
    found_by: str = "pyusb"

    @property
    def label(self) -> str:
        return ("AWR1843BOOST XDS110" if self.kind == "xds110" else "DCA1000EVM FTDI")

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind, "label": self.label, "vid": _hex4(self.vid), "pid": _hex4(self.pid),
            "bus": self.bus, "address": self.address, "serial_number": self.serial_number,
            "product": self.product, "node": self.node, "accessible": self.accessible,
            "found_by": self.found_by,
        }


def _sysfs_usb_attrs(device_dir: str) -> dict[str, Any]:
    """vid, pid, serial, product, bus, address of a USB device directory in sysfs."""
    info: dict[str, Any] = {}
    for key, attr, base in (("vid", "idVendor", 16), ("pid", "idProduct", 16),
                            ("bus", "busnum", 10), ("address", "devnum", 10)):
        text = _read_attr(device_dir, attr)
        if text is not None:
            try:
                info[key] = int(text, base)
            except ValueError:
                pass
    for key, attr in (("serial", "serial"), ("product", "product")):
        text = _read_attr(device_dir, attr)
        if text:
            info[key] = text
    return info


def _read_attr(directory: str, name: str) -> str | None:
    try:
        with open(os.path.join(directory, name), encoding="utf-8", errors="replace") as f:
            return f.readline().strip()
    except OSError:
        return None


def _rw_access(path: str) -> bool:
    return os.access(path, os.R_OK | os.W_OK)


def find_usb_devices(*, dev_root: str | os.PathLike = "/dev", sys_root: str | os.PathLike = "/sys",
                     usb_find: UsbFind | None = None) -> list[UsbDeviceInfo]:
    """XDS110s (0451:bef3) and DCA1000 FTDIs (0451:fd03) on the USB bus.

    Uses pyusb (*usb_find*, default ``usb.core.find``).  Without a libusb
    backend (``usb.core.NoBackendError``) or without pyusb it reads sysfs
    instead and logs why; :func:`scan` returns that as a note.  Never raises
    for a missing backend.
    """
    devices, notes = _usb_scan(os.fspath(dev_root), os.fspath(sys_root), usb_find)
    for note in notes:
        log.info("%s", note)
    return devices


def _usb_scan(dev_root: str, sys_root: str,
              usb_find: UsbFind | None) -> tuple[list[UsbDeviceInfo], list[str]]:
    notes: list[str] = []
    sysfs = _sysfs_usb_devices(sys_root)
    found: list[UsbDeviceInfo] | None = None
    try:
        found = _pyusb_devices(usb_find, sysfs)
    except ImportError as exc:
        notes.append(f"pyusb is not installed ({exc}); USB devices listed from sysfs")
    except Exception as exc:  # noqa: BLE001 - a missing backend or a libusb failure is a note
        if type(exc).__name__ == "NoBackendError":
            notes.append("pyusb found no libusb backend (install libusb-1.0, e.g. 'sudo apt install "
                         "libusb-1.0-0'); USB devices listed from sysfs")
        else:
            notes.append(f"pyusb failed ({type(exc).__name__}: {exc}); USB devices listed from sysfs")
    if found is None:
        found = [UsbDeviceInfo(kind=_KINDS[(d["vid"], d["pid"])], vid=d["vid"], pid=d["pid"],
                               bus=d.get("bus"), address=d.get("address"),
                               serial_number=d.get("serial"), product=d.get("product"),
                               found_by="sysfs")
                 for d in sysfs if (d.get("vid"), d.get("pid")) in _KINDS]
    for device in found:
        if device.bus is not None and device.address is not None:
            device.node = os.path.join(dev_root, "bus", "usb", f"{device.bus:03d}",
                                       f"{device.address:03d}")
            device.accessible = _rw_access(device.node) if os.path.exists(device.node) else None
    found.sort(key=lambda d: (d.kind != "xds110", d.serial_number is None, d.serial_number or "",
                              d.bus or 0, d.address or 0))
    return found, notes


def _pyusb_devices(usb_find: UsbFind | None, sysfs: list[dict[str, Any]]) -> list[UsbDeviceInfo]:
    if usb_find is None:
        import usb.core
        usb_find = usb.core.find
    devices = []
    for dev in list(usb_find(find_all=True) or ()):
        key = (getattr(dev, "idVendor", None), getattr(dev, "idProduct", None))
        if key not in _KINDS:
            continue
        bus, address = getattr(dev, "bus", None), getattr(dev, "address", None)
        same = next((d for d in sysfs if (d.get("bus"), d.get("address")) == (bus, address)), {})
        devices.append(UsbDeviceInfo(
            kind=_KINDS[key], vid=key[0], pid=key[1], bus=bus, address=address,
            serial_number=_usb_string(dev, "serial_number") or same.get("serial"),
            product=_usb_string(dev, "product") or same.get("product"), found_by="pyusb"))
        _dispose(dev)
    return devices


def _usb_string(dev: Any, attr: str) -> str | None:
    """A string descriptor via pyusb, or None: reading it opens the device, which
    needs access to /dev/bus/usb (ValueError 'no langid' or USBError without)."""
    try:
        value = getattr(dev, attr)
    except Exception as exc:  # noqa: BLE001 - pyusb raises ValueError, USBError, NotImplementedError
        log.debug("cannot read %s of USB %s:%s: %s", attr, getattr(dev, "bus", "?"),
                  getattr(dev, "address", "?"), exc)
        return None
    return value or None


def _dispose(dev: Any) -> None:
    try:
        import usb.util
        usb.util.dispose_resources(dev)
    except Exception:  # noqa: BLE001 - nothing to release on a stand-in or without a backend
        pass


def _sysfs_usb_devices(sys_root: str) -> list[dict[str, Any]]:
    """Every USB device in ``<sys>/bus/usb/devices`` (interfaces skipped), with its attributes."""
    base = os.path.join(sys_root, "bus", "usb", "devices")
    try:
        entries = sorted(os.listdir(base))
    except OSError:
        return []
    devices = []
    for entry in entries:
        if ":" in entry:  # '1-2:1.0' is an interface, not a device
            continue
        attrs = _sysfs_usb_attrs(os.path.join(base, entry))
        if "vid" in attrs and "pid" in attrs:
            attrs["sysfs_name"] = entry
            devices.append(attrs)
    return devices


def _hex4(value: int | None) -> str | None:
    return None if value is None else f"{value:04x}"
