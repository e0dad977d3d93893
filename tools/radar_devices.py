"""radar-devices: list the AWR1843BOOST radars and DCA1000 boards attached, and whether
this user may open them.

Finding nothing is not an error: it says so, suggests sim:// and replay://, and
exits 0.
"""

from __future__ import annotations

import argparse
import grp
import os
import sys
from typing import Sequence

from .. import strict_json
from ..driver.live import discovery
from ..driver.live.device_report import DeviceReport, RadarInfo, scan
from ..driver.live.discovery import SerialPortInfo, UsbDeviceInfo
from . import cli

#: The commands of the access hint (from a clone of radarodom).
INSTALL_RULES = ("sudo cp udev/99-radarodom.rules /etc/udev/rules.d/ && "
                 "sudo udevadm control --reload && sudo udevadm trigger")
JOIN_PLUGDEV = "sudo usermod -aG plugdev $USER"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="radar-devices",
        description="List the AWR1843BOOST radars (TI XDS110, USB 0451:bef3: CLI and data ports) "
                    "and DCA1000EVM boards (FTDI, USB 0451:fd03) attached, and whether you may "
                    "open them. Exit 0 also when nothing is attached.")
    parser.add_argument("--json", action="store_true", help="print JSON with stable keys")
    cli.add_verbosity(parser)
    return parser


def _main(args: argparse.Namespace) -> int:
    report = scan()
    hints = access_hints(report)
    if args.json:
        data = report.to_dict()
        data["hints"] = hints
        print(strict_json.dumps(data, indent=2))
        return 0
    print(format_report(report, hints, quiet=args.quiet))
    return 0


def format_report(report: DeviceReport, hints: Sequence[str] = (), *, quiet: bool = False) -> str:
    """The human listing: radars, DCA1000s, then hints and notes (left out when *quiet*)."""
    out: list[str] = []
    for radar in report.radars:
        out.extend(_radar_lines(radar))
    if not report.radars:
        out.append(discovery.no_radar_message())
    for board in report.dca1000:
        out.append(f"DCA1000EVM FTDI (USB {board.vid:04x}:{board.pid:04x})"
                   f"{_serial_text(board.serial_number)}{_bus_text(board)}"
                   " - not needed for Ethernet streaming")
        out.append(_usb_line(board))
    if not report.dca1000:
        out.append(f"no DCA1000EVM FTDI found (USB {discovery.DCA1000_VID:04x}:"
                   f"{discovery.DCA1000_PID:04x}; not needed for Ethernet streaming)")
    if not report.found_anything:
        out.append("to run without hardware: radar-capture --source sim://corridor (the simulator) "
                   "or --source replay://DIR (a recording)")
    if not quiet:
        out.extend(f"hint: {h}" for h in hints)
        out.extend(f"note: {n}" for n in report.notes)
    return "\n".join(out)


def _radar_lines(radar: RadarInfo) -> list[str]:
    title = (f"AWR1843BOOST radar (TI XDS110, USB {discovery.XDS110_VID:04x}:"
             f"{discovery.XDS110_PID:04x}){_serial_text(radar.serial_number)}"
             f"{_bus_text(radar.usb) if radar.usb else ''}")
    lines = [title]
    for label, port in (("CLI port", radar.cli), ("data port", radar.data)):
        lines.append(_port_line(label, port))
    for port in radar.other_ports:
        lines.append(_port_line("other port", port))
    if radar.usb is not None:
        lines.append(_usb_line(radar.usb))
    return lines


def _port_line(label: str, port: SerialPortInfo | None) -> str:
    if port is None:
        return f"  {label:<10} not found"
    where = port.path if port.path == port.device else f"{port.path} -> {port.device}"
    detail = [f"interface {port.interface}" if port.interface is not None else "interface ?"]
    if port.baudrate:
        detail.append(f"{port.baudrate} baud")
    return (f"  {label:<10} {where}  ({', '.join(detail)})  "
            f"{'ok' if port.accessible else 'NO ACCESS'}")


def _usb_line(device: UsbDeviceInfo) -> str:
    if device.node is None:
        return "  USB node   unknown (no bus/address)"
    state = {True: "ok", False: "NO ACCESS", None: "node absent"}[device.accessible]
    return f"  USB node   {device.node}  {state}"


def _serial_text(serial: str | None) -> str:
    return f", serial {serial}" if serial else ""


def _bus_text(device: UsbDeviceInfo) -> str:
    return f", USB bus {device.bus} device {device.address}" if device.bus is not None else ""


def access_hints(report: DeviceReport) -> list[str]:
    """What to do when something listed cannot be opened, or has no stable name."""
    hints: list[str] = []
    ports = [p for r in report.radars for p in r.ports]
    nodes = [d.node for d in [r.usb for r in report.radars if r.usb] + list(report.dca1000)
             if d is not None and d.node and d.accessible is False]
    denied = [p.device for p in ports if not p.accessible] + nodes
    if denied:
        rules = discovery.shipped_rules()
        hints.append(f"you may not open {', '.join(denied)}: install the udev rules "
                     f"({INSTALL_RULES})" + (f"; the rules file is also at {rules}" if rules else ""))
        hints.append(_plugdev_hint())
    if ports and not any(p.links for p in ports):
        hints.append(f"no /dev/awr1843-cli link: the udev rules are not installed ({INSTALL_RULES}); "
                     "they give the ports stable names and keep ModemManager off them")
    return hints


def _plugdev_hint() -> str:
    try:
        group = grp.getgrnam("plugdev")
    except KeyError:
        return f"there is no plugdev group: sudo groupadd plugdev, then {JOIN_PLUGDEV} and log in again"
    user = os.environ.get("USER") or os.environ.get("LOGNAME") or ""
    if group.gr_gid in os.getgroups():
        return "you are in plugdev already: replug the radar so the rules apply"
    if user and user in group.gr_mem:
        return "you were added to plugdev but this session predates it: log out and in again"
    return f"join the plugdev group: {JOIN_PLUGDEV}, then log out and in again"


def main(argv: Sequence[str] | None = None) -> int:
    return cli.run(_main, build_parser(), argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
