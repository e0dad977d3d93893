"""USB discovery of the AWR1843BOOST (XDS110 0451:bef3) and the DCA1000 (FTDI 0451:fd03),
the udev rules, and ``radar-devices``.

No hardware: a fake ``/dev`` and ``/sys`` tree in tmp_path laid out like the
kernel's, and pyserial's own ``ListPortInfo`` objects filled in by hand (what
``comports()`` returns on Linux, minus the sysfs reading).
"""

from __future__ import annotations

import json
import pathlib
import re
import subprocess

import pytest
import usb.core
from conftest import REPO, console_command, warning_messages
from serial.tools.list_ports_common import ListPortInfo

from radarodom.driver.live import discovery
from radarodom.driver.live.device_report import DeviceReport, RadarInfo, scan
from radarodom.driver.live.discovery import (SerialPortInfo, UsbDeviceInfo, default_cli_port, find_cli_ports,
                                             find_data_ports, find_ports, find_usb_devices, require_cli_port)
from radarodom.errors import DeviceError
from radarodom.tools import radar_devices

RULES = REPO / "udev" / "99-radarodom.rules"

XDS110 = (0x0451, 0xBEF3)
DCA1000 = (0x0451, 0xFD03)


# --------------------------------------------------------------------------- fake tree

class Tree:
    """A fake /dev and /sys: USB devices with interfaces and ttys, as the kernel lays them out."""

    def __init__(self, root: pathlib.Path) -> None:
        self.dev = root / "dev"
        self.sys = root / "sys"
        self.dev.mkdir()
        (self.sys / "class" / "tty").mkdir(parents=True)
        (self.sys / "bus" / "usb" / "devices").mkdir(parents=True)

    def usb_device(self, path: str, vid_pid: tuple[int, int], *, bus: int, address: int,
                   serial: str | None = None, product: str = "XDS110") -> pathlib.Path:
        """/sys/devices/.../<path> with its attributes, /sys/bus/usb/devices/<path>, and
        /dev/bus/usb/BBB/DDD."""
        d = self.sys / "devices" / "pci0000:00" / f"usb{bus}" / path
        d.mkdir(parents=True)
        attrs = {"idVendor": f"{vid_pid[0]:04x}", "idProduct": f"{vid_pid[1]:04x}",
                 "busnum": str(bus), "devnum": str(address), "product": product}
        if serial is not None:
            attrs["serial"] = serial
        for name, value in attrs.items():
            (d / name).write_text(value + "\n")
        (self.sys / "bus" / "usb" / "devices" / path).symlink_to(d)
        node = self.dev / "bus" / "usb" / f"{bus:03d}" / f"{address:03d}"
        node.parent.mkdir(parents=True, exist_ok=True)
        node.touch(mode=0o660)
        return d

    def tty(self, device_dir: pathlib.Path, interface: int, name: str) -> pathlib.Path:
        """A CDC-ACM tty bound to USB *interface* of *device_dir*, and its /dev node."""
        iface = device_dir / f"{device_dir.name}:1.{interface}"
        iface.mkdir()
        (iface / "bInterfaceNumber").write_text(f"{interface:02x}\n")
        (self.sys / "class" / "tty" / name).mkdir()
        (self.sys / "class" / "tty" / name / "device").symlink_to(iface)
        node = self.dev / name
        node.touch(mode=0o660)
        return node

    def link(self, name: str, tty: str) -> pathlib.Path:
        """A udev symlink: relative, as udev makes them."""
        link = self.dev / name
        link.symlink_to(tty)
        return link

    def xds110(self, path: str, *, bus: int, address: int, serial: str | None,
               cli: str, data: str, links: bool = False) -> None:
        d = self.usb_device(path, XDS110, bus=bus, address=address, serial=serial)
        self.tty(d, 0, cli)
        self.tty(d, 3, data)
        if links:
            self.link("awr1843-cli", cli)
            self.link("awr1843-data", data)
            if serial:
                self.link(f"awr1843-cli-{serial}", cli)
                self.link(f"awr1843-data-{serial}", data)

    def roots(self) -> dict:
        return {"dev_root": str(self.dev), "sys_root": str(self.sys)}


@pytest.fixture
def tree(tmp_path) -> Tree:
    return Tree(tmp_path)


def port(device, vid_pid=XDS110, *, serial=None, location=None, interface=None,
         product="XDS110 (03.00.00.25) Embed with CMSIS-DAP") -> ListPortInfo:
    """pyserial's ListPortInfo as comports() fills it in on Linux."""
    info = ListPortInfo(str(device), skip_link_detection=True)
    info.vid, info.pid = vid_pid
    info.serial_number = serial
    info.location = location
    info.manufacturer = "Texas Instruments"
    info.product = product
    info.interface = interface
    info.apply_usb_info()
    return info


def comports_of(*ports):
    return lambda: list(ports)


def no_usb(**kwargs):
    raise usb.core.NoBackendError("No backend available")


# --------------------------------------------------------------------------- serial ports

def test_cli_port_is_interface_0_whatever_the_tty_order(tree):
    """ttyACM0 is the data port here (interface 3 enumerated first): the CLI is ttyACM1."""
    for name in ("ttyACM0", "ttyACM1", "ttyACM2", "ttyUSB0"):
        (tree.dev / name).touch()
    ports = comports_of(
        port(tree.dev / "ttyACM0", serial="R0061004", location="1-2:1.3",
             interface="XDS110 Class Auxiliary Data Port"),
        port(tree.dev / "ttyACM1", serial="R0061004", location="1-2:1.0",
             interface="XDS110 Class Application/User UART"),
        port(tree.dev / "ttyUSB0", (0x0403, 0x6001), serial="A12345", location="1-3"),
        port(tree.dev / "ttyACM2", (0x2341, 0x0043), location="1-4:1.0"),  # an Arduino
    )
    cli = find_cli_ports(comports=ports, **tree.roots())
    assert [(p.name, p.interface, p.role, p.baudrate) for p in cli] == [("ttyACM1", 0, "cli", 115200)]
    assert cli[0].serial_number == "R0061004" and cli[0].found_by == "pyserial"
    data = find_data_ports(comports=ports, **tree.roots())
    assert [(p.name, p.interface, p.baudrate) for p in data] == [("ttyACM0", 3, 921600)]
    assert default_cli_port(comports=ports, **tree.roots()) == str(tree.dev / "ttyACM1")
    assert {p.name for p in find_ports(comports=ports, **tree.roots())} == {"ttyACM0", "ttyACM1"}


def test_interface_number_from_sysfs_when_the_location_has_none(tree):
    tree.xds110("1-2", bus=1, address=5, serial="R0061004", cli="ttyACM1", data="ttyACM0")
    ports = comports_of(port(tree.dev / "ttyACM0", location="1-2"),
                        port(tree.dev / "ttyACM1", location="1-2"))
    (cli,) = find_cli_ports(comports=ports, **tree.roots())
    assert (cli.name, cli.interface, cli.serial_number) == ("ttyACM1", 0, "R0061004")
    assert (cli.bus, cli.address) == (1, 5)
    (data,) = find_data_ports(comports=ports, **tree.roots())
    assert (data.name, data.interface) == ("ttyACM0", 3)


def test_interface_name_is_the_last_resort(tree):
    """Neither location nor sysfs: pyserial's `interface` (a name, not a number) decides."""
    for name in ("ttyACM0", "ttyACM1"):
        (tree.dev / name).touch()
    ports = comports_of(
        port(tree.dev / "ttyACM0", interface="XDS110 Class Auxiliary Data Port"),
        port(tree.dev / "ttyACM1", interface="XDS110 Class Application/User UART"))
    assert [p.name for p in find_cli_ports(comports=ports, **tree.roots())] == ["ttyACM1"]
    assert [p.name for p in find_data_ports(comports=ports, **tree.roots())] == ["ttyACM0"]


def test_unknown_interface_is_never_the_cli(tree):
    (tree.dev / "ttyACM0").touch()
    ports = comports_of(port(tree.dev / "ttyACM0", location="1-2:1.5"))
    (only,) = find_ports(comports=ports, **tree.roots())
    assert (only.interface, only.role) == (5, None)
    assert find_cli_ports(comports=ports, **tree.roots()) == []
    assert default_cli_port(comports=ports, **tree.roots()) is None


def test_udev_symlink_is_preferred_and_ports_are_not_listed_twice(tree):
    tree.xds110("1-2", bus=1, address=5, serial="R0061004", cli="ttyACM0", data="ttyACM1",
                links=True)
    ports = comports_of(port(tree.dev / "ttyACM0", serial="R0061004", location="1-2:1.0"),
                        port(tree.dev / "ttyACM1", serial="R0061004", location="1-2:1.3"))
    found = find_ports(comports=ports, **tree.roots())
    assert len(found) == 2
    cli = next(p for p in found if p.role == "cli")
    assert cli.found_by == "udev" and cli.location == "1-2:1.0"
    assert cli.links == (str(tree.dev / "awr1843-cli-R0061004"), str(tree.dev / "awr1843-cli"))
    assert cli.device == str(tree.dev / "ttyACM0")
    assert default_cli_port(comports=ports, **tree.roots()) == str(tree.dev / "awr1843-cli-R0061004")
    (data,) = find_data_ports(comports=ports, **tree.roots())
    assert data.path == str(tree.dev / "awr1843-data-R0061004")


def test_udev_symlinks_alone_find_the_radar(tree):
    """pyserial lists nothing (e.g. another tty glob): the links still name both ports."""
    tree.xds110("1-2", bus=1, address=5, serial="R0061004", cli="ttyACM3", data="ttyACM4",
                links=True)
    cli = find_cli_ports(comports=comports_of(), **tree.roots())
    assert [(p.name, p.interface, p.serial_number) for p in cli] == [("ttyACM3", 0, "R0061004")]
    assert default_cli_port(comports=comports_of(), **tree.roots()).endswith("awr1843-cli-R0061004")


def test_generic_symlink_without_sysfs_or_serial(tree):
    (tree.dev / "ttyACM7").touch()
    tree.link("awr1843-cli", "ttyACM7")
    tree.link("awr1843-data-", "missing")  # dangling: ignored
    (cli,) = find_cli_ports(comports=comports_of(), **tree.roots())
    assert (cli.path, cli.interface, cli.vid, cli.pid) == (str(tree.dev / "awr1843-cli"), 0, *XDS110)
    assert find_data_ports(comports=comports_of(), **tree.roots()) == []


def test_several_radars_stable_order_and_a_warning(tree, warnings_log):
    tree.xds110("1-2", bus=1, address=5, serial="R0061009", cli="ttyACM0", data="ttyACM1")
    tree.xds110("1-10", bus=1, address=9, serial="R0061001", cli="ttyACM10", data="ttyACM11")
    listed = [port(tree.dev / n, location=loc) for n, loc in
              (("ttyACM0", "1-2:1.0"), ("ttyACM1", "1-2:1.3"),
               ("ttyACM10", "1-10:1.0"), ("ttyACM11", "1-10:1.3"))]
    orders = set()
    for ports in (listed, listed[::-1], listed[1::2] + listed[::2]):
        cli = find_cli_ports(comports=comports_of(*ports), **tree.roots())
        orders.add(tuple((p.serial_number, p.name) for p in cli))
    assert orders == {(("R0061001", "ttyACM10"), ("R0061009", "ttyACM0"))}
    warnings_log.clear()
    chosen = default_cli_port(comports=comports_of(*listed), **tree.roots())
    assert chosen == str(tree.dev / "ttyACM10")
    (msg,) = warning_messages(warnings_log)
    assert "2 radars" in msg and "R0061001" in msg and "R0061009" in msg and chosen in msg


def test_several_radars_without_serials_follow_the_usb_location(tree):
    for name in ("ttyACM2", "ttyACM10"):
        (tree.dev / name).touch()
    ports = comports_of(port(tree.dev / "ttyACM2", location="1-10:1.0"),
                        port(tree.dev / "ttyACM10", location="1-9:1.0"))
    assert [p.location for p in find_cli_ports(comports=ports, **tree.roots())] == [
        "1-9:1.0", "1-10:1.0"]


def test_no_radar(tree, warnings_log):
    assert find_cli_ports(comports=comports_of(), **tree.roots()) == []
    assert default_cli_port(comports=comports_of(), **tree.roots()) is None
    with pytest.raises(DeviceError) as err:
        require_cli_port(comports=comports_of(), **tree.roots())
    message = str(err.value)
    assert message.startswith("no radar found: looked for ")
    assert "0451:bef3" in message and "awr1843-cli" in message
    assert message.endswith("try sim:// or replay://")
    assert err.value.exit_code == 1
    assert warning_messages(warnings_log) == []


# --------------------------------------------------------------------------- USB devices

def test_find_usb_devices_on_this_machine_does_not_raise():
    devices = find_usb_devices()
    assert isinstance(devices, list)
    assert all(isinstance(d, UsbDeviceInfo) and d.kind in ("xds110", "dca1000") for d in devices)


def test_no_libusb_backend_is_a_note_not_a_crash(tree):
    assert find_usb_devices(usb_find=no_usb, **tree.roots()) == []
    report = scan(comports=comports_of(), usb_find=no_usb, **tree.roots())
    assert report.radars == [] and report.dca1000 == [] and not report.found_anything
    assert any("libusb" in n for n in report.notes)


def test_without_libusb_sysfs_lists_the_devices(tree):
    tree.xds110("1-2", bus=1, address=5, serial="R0061004", cli="ttyACM0", data="ttyACM1",
                links=True)
    tree.usb_device("1-3", DCA1000, bus=1, address=6, serial="FT1234", product="DCA1000")
    tree.usb_device("1-4", (0x046D, 0xC52B), bus=1, address=7)  # a mouse receiver
    devices = find_usb_devices(usb_find=no_usb, **tree.roots())
    assert [(d.kind, d.bus, d.address, d.serial_number, d.found_by) for d in devices] == [
        ("xds110", 1, 5, "R0061004", "sysfs"), ("dca1000", 1, 6, "FT1234", "sysfs")]
    assert devices[0].node == str(tree.dev / "bus" / "usb" / "001" / "005")
    assert devices[0].accessible is True

    report = scan(comports=comports_of(), usb_find=no_usb, **tree.roots())
    (radar,) = report.radars
    assert radar.serial_number == "R0061004" and radar.usb == devices[0]
    assert radar.cli.name == "ttyACM0" and radar.data.name == "ttyACM1" and radar.accessible
    assert [d.serial_number for d in report.dca1000] == ["FT1234"]
    assert report.default_cli_port == str(tree.dev / "awr1843-cli-R0061004")


class _PyusbDevice:
    """Stands in for a usb.core.Device: the attributes pyusb's find() objects carry; reading
    the serial number fails as it does without access to the device node."""

    def __init__(self, vid_pid, bus, address):
        self.idVendor, self.idProduct = vid_pid
        self.bus, self.address = bus, address

    @property
    def serial_number(self):
        raise ValueError("The device has no langid (permission issue, no string descriptors "
                         "supported or device error)")

    product = serial_number


def test_pyusb_devices_with_unreadable_serial_fall_back_to_sysfs(tree):
    tree.usb_device("1-2", XDS110, bus=1, address=5, serial="R0061004")
    found = [_PyusbDevice(XDS110, 1, 5), _PyusbDevice((0x046D, 0xC52B), 1, 7),
             _PyusbDevice(DCA1000, 2, 3)]
    devices = find_usb_devices(usb_find=lambda **kw: iter(found), **tree.roots())
    assert [(d.kind, d.bus, d.address, d.serial_number, d.found_by) for d in devices] == [
        ("xds110", 1, 5, "R0061004", "pyusb"), ("dca1000", 2, 3, None, "pyusb")]
    assert devices[1].accessible is None  # no /dev/bus/usb/002/003 in the tree


def test_xds110_without_serial_ports_gets_a_note(tree):
    tree.usb_device("1-2", XDS110, bus=1, address=5, serial="R0061004")
    report = scan(comports=comports_of(), usb_find=no_usb, **tree.roots())
    (radar,) = report.radars
    assert radar.cli is None and radar.usb is not None and not radar.accessible
    assert any("cdc_acm" in n for n in report.notes)


# --------------------------------------------------------------------------- udev rules

def _rules() -> list[tuple[int, list[tuple[str, str, str]]]]:
    """(line number, [(key, operator, value)]) for every rule line of the rules file."""
    pair = re.compile(r'\s*([A-Za-z_]+(?:\{[^}]+\})?)\s*(==|!=|\+=|-=|:=|=)\s*"([^"]*)"\s*(,|$)')
    rules = []
    for lineno, line in enumerate(RULES.read_text().splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        pairs, pos = [], 0
        while pos < len(line):
            m = pair.match(line, pos)
            assert m, f"{RULES.name}:{lineno}: cannot parse at {line[pos:]!r}"
            pairs.append(m.group(1, 2, 3))
            pos = m.end()
        assert pairs, f"{RULES.name}:{lineno}: empty rule"
        rules.append((lineno, pairs))
    return rules


def _get(pairs, key, op=None):
    return [v for k, o, v in pairs if k == key and (op is None or o == op)]


def test_rules_parse_as_key_operator_value_pairs():
    rules = _rules()
    assert len(rules) >= 8
    allowed = {"==", "!=", "=", "+=", ":="}
    for lineno, pairs in rules:
        assert {o for _, o, _ in pairs} <= allowed, lineno


def test_every_rule_line_has_a_comment_above_it():
    lines = RULES.read_text().splitlines()
    for i, line in enumerate(lines):
        if line.strip() and not line.lstrip().startswith("#"):
            assert i > 0 and lines[i - 1].lstrip().startswith("#"), f"line {i + 1} has no comment"


def test_rules_modes_are_0660_or_stricter_and_group_plugdev():
    modes = 0
    for lineno, pairs in _rules():
        for mode in _get(pairs, "MODE"):
            modes += 1
            value = int(mode, 8)
            assert value & ~0o660 == 0, f"line {lineno}: MODE {mode} is wider than 0660"
            assert _get(pairs, "GROUP", "=") == ["plugdev"], f"line {lineno}"
    assert modes >= 4


def _matches(pairs, vid, pid) -> bool:
    ids = set(_get(pairs, "ATTR{idVendor}", "==") + _get(pairs, "ATTRS{idVendor}", "=="))
    prods = set(_get(pairs, "ATTR{idProduct}", "==") + _get(pairs, "ATTRS{idProduct}", "=="))
    return ids == {vid} and prods == {pid}


def test_rules_cover_the_xds110_interfaces_and_the_dca1000():
    rules = [pairs for _, pairs in _rules()]
    links = {}
    for pairs in rules:
        if _matches(pairs, "0451", "bef3") and _get(pairs, "SYMLINK", "+="):
            assert _get(pairs, "SUBSYSTEM", "==") == ["tty"]
            (iface,) = _get(pairs, "ENV{ID_USB_INTERFACE_NUM}", "==")
            for link in _get(pairs, "SYMLINK", "+="):
                links.setdefault(iface, []).append(link)
    # The names discovery looks for, generic and per board.
    assert sorted(links) == ["00", "03"]
    assert discovery.LINK_PREFIX["cli"] in links["00"]
    assert discovery.LINK_PREFIX["data"] in links["03"]
    assert any(ln.startswith(discovery.LINK_PREFIX["cli"] + "-$env{ID_SERIAL_SHORT}")
               for ln in links["00"])
    assert any(ln.startswith(discovery.LINK_PREFIX["data"] + "-$env{ID_SERIAL_SHORT}")
               for ln in links["03"])
    for vid, pid in (("0451", "bef3"), ("0451", "fd03")):
        usb_rules = [p for p in rules if _matches(p, vid, pid) and _get(p, "SUBSYSTEM") == ["usb"]]
        assert usb_rules and all(_get(p, "MODE") == ["0660"] and
                                 _get(p, "ENV{ID_MM_DEVICE_IGNORE}", "=") == ["1"]
                                 for p in usb_rules), (vid, pid)


def test_rules_keep_modemmanager_off_the_ttys():
    ttys = [pairs for _, pairs in _rules()
            if _get(pairs, "SUBSYSTEM", "==") == ["tty"] and _get(pairs, "MODE")]
    assert {tuple(_get(p, "ATTRS{idProduct}", "==")) for p in ttys} == {("bef3",), ("fd03",)}
    for pairs in ttys:
        assert _get(pairs, "ENV{ID_MM_DEVICE_IGNORE}", "=") == ["1"]


# --------------------------------------------------------------------------- radar-devices

def test_report_lists_a_radar_with_ports_and_access(tree):
    tree.xds110("1-2", bus=1, address=5, serial="R0061004", cli="ttyACM0", data="ttyACM1",
                links=True)
    tree.usb_device("1-3", DCA1000, bus=1, address=6, serial="FT1234")
    report = scan(comports=comports_of(), usb_find=no_usb, **tree.roots())
    hints = radar_devices.access_hints(report)
    assert hints == []  # root or not: the fake nodes are the test user's own
    text = radar_devices.format_report(report, hints)
    assert "AWR1843BOOST radar" in text and "serial R0061004" in text
    assert re.search(r"CLI port\s+\S+awr1843-cli-R0061004 -> \S+ttyACM0\s+\(interface 0, "
                     r"115200 baud\)\s+ok", text)
    assert re.search(r"data port\s+\S+awr1843-data-R0061004 -> \S+ttyACM1\s+\(interface 3, "
                     r"921600 baud\)\s+ok", text)
    assert "DCA1000EVM FTDI" in text and "serial FT1234" in text
    assert "no radar found" not in text
    data = json.loads(json.dumps(report.to_dict()))
    assert data["radars"][0]["cli"]["interface"] == 0
    assert data["radars"][0]["usb"]["vid"] == "0451" and data["dca1000"][0]["pid"] == "fd03"


def test_hints_when_the_user_may_not_open_the_ports():
    cli = SerialPortInfo(device="/dev/ttyACM0", role="cli", interface=0, serial_number="R1")
    data = SerialPortInfo(device="/dev/ttyACM1", role="data", interface=3, serial_number="R1")
    report = DeviceReport(radars=[RadarInfo(serial_number="R1", cli=cli, data=data)],
                          dca1000=[], notes=[], looked_for="")
    hints = radar_devices.access_hints(report)
    text = "\n".join(hints)
    assert "/dev/ttyACM0" in text and radar_devices.INSTALL_RULES in text
    assert "plugdev" in text
    assert "no /dev/awr1843-cli link" in text
    listing = radar_devices.format_report(report, hints)
    assert "NO ACCESS" in listing and "hint: " in listing
    assert "hint: " not in radar_devices.format_report(report, hints, quiet=True)


def _skip_if_hardware():
    if scan().found_anything:
        pytest.skip("a radar or DCA1000 is attached to this machine")


def test_radar_devices_runs_and_finds_nothing_here():
    _skip_if_hardware()
    proc = subprocess.run(console_command("radar-devices"), stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "no radar found: looked for" in proc.stdout
    assert "sim://" in proc.stdout and "replay://" in proc.stdout
    assert "no DCA1000EVM" in proc.stdout
    assert "Traceback" not in proc.stderr


def test_radar_devices_json_runs_and_finds_nothing_here():
    _skip_if_hardware()
    proc = subprocess.run(console_command("radar-devices") + ["--json"], stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["radars"] == [] and data["dca1000"] == []
    assert data["default_cli_port"] is None
    assert isinstance(data["notes"], list) and isinstance(data["hints"], list)
    assert "0451:bef3" in data["looked_for"]


def test_radar_devices_usage_error_exits_2(capsys):
    assert radar_devices.main(["--bogus"]) == 2
    assert "usage: radar-devices" in capsys.readouterr().err


# --------------------------------------------------------------------------- the default source

def test_a_radar_without_a_dca1000_streams_over_its_uart_by_default(tree, warnings_log):
    """radar-capture without --source chose dca1000:// for any radar found, which without a
    DCA1000 failed asking for the board network's address: the board alone now goes tidemo://."""
    from radarodom.driver.live.default_source import live_source_url

    tree.xds110("1-2", bus=1, address=5, serial="R0061004", cli="ttyACM0", data="ttyACM1")
    cli = str(tree.dev / "ttyACM0")
    # 192.0.2.1 (TEST-NET-1) is no address of this machine: no sign of a DCA1000 at all.
    url = live_source_url(cli, usb_find=no_usb, host_ip="192.0.2.1", **tree.roots())
    assert url == f"tidemo://?cli={cli}"
    (msg,) = warning_messages(warnings_log)
    assert f"radar found on {cli}, and no DCA1000" in msg and "--source dca1000://" in msg
    warnings_log.clear()
    # This computer holding the board's host address is a DCA1000 set up (its USB need not be in).
    assert live_source_url(cli, usb_find=no_usb, host_ip="127.0.0.1", **tree.roots()) == f"dca1000://?cli={cli}"
    tree.usb_device("1-3", DCA1000, bus=1, address=6, serial="FT1234", product="DCA1000")
    assert live_source_url(cli, usb_find=no_usb, host_ip="192.0.2.1", **tree.roots()) == f"dca1000://?cli={cli}"
    assert warning_messages(warnings_log) == []
