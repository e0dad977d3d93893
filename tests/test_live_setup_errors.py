"""The network set-up errors a first live capture meets, and what they tell the user to do:
this computer without the board's host address, and a port another program holds.  The
library raises one DeviceError naming the fix; radar-capture prints it as one line and exits
1, without a traceback, having released what it opened."""

from __future__ import annotations

import errno
import socket
import subprocess

import pytest
from conftest import console_command, make_capture
from live_helpers import URL_TIMEOUTS, port_is_free
from radarodom.driver.emulators.rig import HOST_IP, EmulatedRig, free_udp_port
from radarodom.driver.live.host_network import bind_problem
from radarodom.driver.sources import open_source
from radarodom.errors import DeviceError, DeviceTimeout

#: TEST-NET-1 (RFC 5737): documentation only, on no interface of a test machine.
ABSENT_IP = "192.0.2.1"


def _address_is_absent(ip: str) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind((ip, 0))
        except OSError as exc:
            return exc.errno == errno.EADDRNOTAVAIL
        return False


@pytest.fixture
def absent_ip():
    for ip in (ABSENT_IP, "192.168.33.30"):
        if _address_is_absent(ip):
            return ip
    pytest.skip(f"this machine has both {ABSENT_IP} and 192.168.33.30: no absent address to test with")


@pytest.fixture
def small_capture(tmp_path, small_cfg):
    directory = tmp_path / "src"
    make_capture(directory, small_cfg, 3)
    return str(directory)


def assert_names_the_fix(message: str, ip: str) -> None:
    assert f"This computer has no address {ip}" in message, message
    assert f"sudo ip addr add {ip}/24 dev " in message, message
    assert "nmcli con add" in message and f"ipv4.addresses {ip}/24" in message, message
    assert "?host=" in message, message


def test_host_address_not_on_any_interface_names_the_command_that_adds_it(absent_ip, small_cfg):
    # The data socket is bound first: no board and no radar are needed to hit this.
    with pytest.raises(DeviceError) as info:
        open_source(f"dca1000://192.168.33.180?host={absent_ip}&cli=/dev/null", small_cfg)
    message = str(info.value)
    assert not isinstance(info.value, DeviceTimeout)
    assert message.startswith(f"cannot receive DCA1000 data on {absent_ip}:4098: "), message
    assert_names_the_fix(message, absent_ip)


def test_the_hint_names_the_one_wired_interface_and_skips_virtual_ones(monkeypatch):
    monkeypatch.setattr(socket, "if_nameindex", lambda: [(1, "lo"), (2, "docker0"), (3, "veth12ab"),
                                                          (4, "enp3s0"), (5, "ifb0")])
    message = bind_problem(OSError(errno.EADDRNOTAVAIL, "Cannot assign requested address"),
                           "192.168.33.30", 4098, "receive DCA1000 data")
    assert "(interfaces here: enp3s0)" in message
    assert "'sudo ip addr add 192.168.33.30/24 dev enp3s0'" in message
    assert "ifname enp3s0 con-name dca1000" in message
    monkeypatch.setattr(socket, "if_nameindex", lambda: [(1, "lo"), (2, "eth0"), (3, "eth1")])
    message = bind_problem(OSError(errno.EADDRNOTAVAIL, "Cannot assign requested address"),
                           "192.168.33.30", 4098, "receive DCA1000 data")
    assert "(interfaces here: eth0, eth1)" in message and "dev IFACE" in message, message


def test_radar_capture_says_it_in_one_line_and_exits_1(absent_ip):
    proc = subprocess.run([*console_command("radar-capture"), "--source",
                           f"dca1000://?host={absent_ip}&cli=/dev/null", "--no-publish"],
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    errors = [ln for ln in proc.stderr.splitlines() if ln.startswith("radar-capture: error: ")]
    assert len(errors) == 1, proc.stderr
    assert_names_the_fix(errors[0], absent_ip)


@pytest.mark.parametrize("which", ["data_port", "config_port"])
def test_a_port_another_program_holds_says_so_and_how_to_find_it(small_capture, small_cfg, which):
    port = free_udp_port(HOST_IP)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder, \
            EmulatedRig(f"replay://{small_capture}", config=small_cfg) as rig:
        holder.bind((HOST_IP, port))  # no SO_REUSEADDR: like a program that owns the port
        with pytest.raises(DeviceError) as info:
            open_source(rig.url(**{which: port}, **URL_TIMEOUTS), small_cfg)
        assert rig.radar.received == [] and rig.board.commands == {}
        if which == "config_port":
            assert port_is_free(HOST_IP, rig.data_port), "the data socket was left open"
    message = str(info.value)
    what = "receive DCA1000 data" if which == "data_port" else "talk to the DCA1000's config port"
    assert message.startswith(f"cannot {what} on {HOST_IP}:{port}: "), message
    assert "Another program holds that port" in message, message
    assert f"sudo ss -ulpn sport = :{port}" in message, message


def test_radar_emulate_refuses_a_command_port_in_use_in_one_line():
    from radarodom.driver.emulators.rig import BOARD_IP

    port = free_udp_port(BOARD_IP)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.bind((BOARD_IP, port))
        proc = subprocess.run([*console_command("radar-emulate"), "--source", "sim://calibration",
                               "--command-port", str(port)],
                              stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert proc.stderr.splitlines() == [f"radar-emulate: error: --command-port {port}: in use on {BOARD_IP} by "
                                        f"another program (a radar-emulate still running?): choose another port"]


@pytest.mark.parametrize("url, words", [
    ("dca1000://999.1.1.1?cli=/dev/null", ("board address '999.1.1.1' is not an IPv4 address", "192.168.33.180")),
    ("dca1000://192.168.33.180:4096?cli=/dev/null", ("'192.168.33.180:4096'", "board_port=")),
    ("dca1000://?host=my-laptop&cli=/dev/null", ("host 'my-laptop' is not an IPv4 address",)),
    ("dca1000://board.local", ("board address 'board.local'",)),  # said before a CLI port is looked for
    # (hunt 5: taken, then "does this host have the address 255.255.255.255?")
    ("dca1000://?host=255.255.255.255&cli=/dev/null", ("host 255.255.255.255 is no one machine's address",)),
    ("dca1000://224.0.0.1?cli=/dev/null", ("board address 224.0.0.1 is no one machine's address",)),
    ("dca1000://0.0.0.0?cli=/dev/null", ("board address 0.0.0.0 is no one machine's address",)),
    # An internal struct error, a stream thread that died, 71 TiB asked for:
    ("dca1000://?cli=/dev/null&delay=600", ("option delay='600'", "from 5 to 500")),
    ("dca1000://?cli=/dev/null&delay=3", ("option delay='3'", "from 5 to 500")),
    ("dca1000://?cli=/dev/null&buffers=100000000", ("option buffers=100000000", "GiB of memory", "at most 2730")),
    # (hunt 5: taken, then "no data packet ... reached 127.0.0.1:0 ... no firewall drops UDP to port 0")
    ("dca1000://?cli=/dev/null&data_port=0", ("data_port=0: the board sends its data to the port stored in its "
                                              "EEPROM (4098 unless changed)",)),
    # (hunt 5: "1e9" is 2 or more, but no whole number as written)
    ("dca1000://?cli=/dev/null&buffers=1e9", ("option buffers='1e9': expected a whole number of frames >= 2",)),
    # It blamed another program for the port radarodom's own data socket held:
    ("dca1000://?cli=/dev/null&config_port=5003&data_port=5003", ("config_port and data_port are both 5003",
                                                                  "must differ", "4096 and 4098")),
])
def test_a_board_or_host_that_is_not_an_ipv4_address_is_a_usage_error(url, words):
    proc = subprocess.run(console_command("radar-capture") + ["--source", url, "--no-publish", "--frames", "1"],
                          capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1, proc.stderr
    assert proc.stderr.startswith(f"radar-capture: error: {url}: ") and all(w in proc.stderr for w in words)


def test_a_host_address_with_no_route_to_the_board_is_one_line_naming_both_and_exits_1():
    # Bound to loopback, this computer can send nothing to the board's 192.168.33.180: Linux
    # refuses the datagram (EINVAL) before any packet leaves.
    data_port = free_udp_port("127.0.0.1")
    proc = subprocess.run([*console_command("radar-capture"), "--source",
                           f"dca1000://?host=127.0.0.1&cli=/dev/null&config_port=0&data_port={data_port}",
                           "--no-publish"],
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr, proc.stderr
    errors = [ln for ln in proc.stderr.splitlines() if ln.startswith("radar-capture: error: ")]
    assert len(errors) == 1, proc.stderr
    assert "cannot send SYSTEM_CONNECT to the DCA1000 at 192.168.33.180:4096 from 127.0.0.1" in errors[0], errors[0]
    assert "dca1000://BOARD?host=ADDRESS" in errors[0]
