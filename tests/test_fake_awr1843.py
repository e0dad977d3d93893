"""The fake AWR1843 CLI (driver/emulators/fake_awr1843.py) on real pseudo-terminals,
talked to through pyserial and checked with the driver's own reply framer."""

from __future__ import annotations

import threading
import time

import pytest
import serial
from conftest import REPO, SMALL_CFG
from radarodom import cfg_commands as cc
from radarodom.cfg import RadarConfig
from radarodom.driver.live.awr1843_protocol import (
    ALREADY_STARTED,
    ALREADY_STOPPED,
    FULL_CONFIG_NEEDED,
    NOT_ALLOWED_AFTER_START,
    NOT_RECOGNIZED,
    PROMPT,
    Outcome,
    Reply,
    ReplyFramer,
    classify,
)
from radarodom.driver.emulators.fake_awr1843 import BOOT_BANNER, CliFaults, FakeAwr1843

SHIPPED = REPO / "configs" / "awr1843_raw.cfg"
#: The reply to sensorStop on a stopped radar, byte for byte (pyRadar issue #2).
REAL_TRACE = b"sensorStop\nIgnored: Sensor is already stopped\n\rDone\n\rmmwDemo:/>"


def small_cfg_commands() -> list[str]:
    """SMALL_CFG's configuration lines (no comments, no session commands)."""
    return [ln for ln in SMALL_CFG.splitlines()
            if ln and not ln.startswith("%") and ln.split()[0] not in ("sensorStop", "flushCfg",
                                                                        "sensorStart")]


class Client:
    """A pyserial client of the fake that frames replies with ReplyFramer."""

    def __init__(self, path: str) -> None:
        self.port = serial.serial_for_url(path, baudrate=115200, timeout=1)
        self.framer = ReplyFramer()
        self.replies: list[str] = []
        self.raw = bytearray()
        self.reads = 0

    def read_reply(self, timeout: float = 2.0) -> str | None:
        """The next reply's text (before its prompt), or None after *timeout*."""
        deadline = time.monotonic() + timeout
        while not self.replies:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self.port.timeout = min(1.0, left)
            data = self.port.read(max(1, self.port.in_waiting))
            if data:
                self.reads += 1
                self.raw += data
                self.replies += self.framer.feed(data)
        return self.replies.pop(0)

    def command(self, line: str, *, eol: bytes = b"\n", timeout: float = 2.0) -> Reply:
        self.port.write(line.encode() + eol)
        text = self.read_reply(timeout)
        assert text is not None, f"no prompt after {line!r}"
        reply = classify(text, line)
        assert reply.echo == line.strip(), (line, text)
        return reply

    def configure(self, lines) -> None:
        for line in lines:
            assert self.command(line).outcome is Outcome.DONE, line

    def close(self) -> None:
        self.port.close()


@pytest.fixture
def fake():
    with FakeAwr1843() as radar:
        yield radar


@pytest.fixture
def client(fake):
    c = Client(fake.open_pty())
    yield c
    c.close()


def typed_values(cfg: RadarConfig) -> dict[str, list]:
    return {name: [ln.value for ln in cfg.commands() if ln.text == name] for name in cc.TYPED_COMMANDS}


# ------------------------------------------------------------------ the shipped cfg
def test_shipped_cfg_line_by_line(fake, client):
    started: list[RadarConfig] = []
    fake.on_sensor_start = started.append
    expected_cfg = RadarConfig.from_file(SHIPPED)
    lines = SHIPPED.read_text().splitlines()
    seen_stop = False
    for line in lines:
        client.port.write(line.encode() + b"\n")
        text = client.read_reply()
        assert text is not None, line
        assert text.startswith(line + "\n")  # the echo, exactly as sent
        if not line.strip():
            assert text == ""
            continue
        reply = classify(text, line)
        assert reply.echo == line.strip()
        name = line.split()[0]
        if line.startswith("%"):
            assert reply.outcome is Outcome.SKIPPED, line
        elif name == "sensorStop" and not seen_stop:
            seen_stop = True
            assert reply.outcome is Outcome.IGNORED
            assert reply.lines == (ALREADY_STOPPED, "Done")
        else:
            assert reply.outcome is Outcome.DONE, (line, reply)
            assert reply.lines == ("Done",)
    assert fake.started
    assert len(started) == 1 and started[0] is fake.config
    cfg = started[0]
    assert cfg.frame_bytes == expected_cfg.frame_bytes == 786432
    assert cfg.tx_order == expected_cfg.tx_order
    assert cfg.profile == expected_cfg.profile
    assert typed_values(cfg) == typed_values(expected_cfg)
    assert cfg.streams_raw_adc
    assert fake.received == lines
    assert client.replies == [] and client.framer.pending == b""


def test_sensor_stop_when_stopped_is_byte_exact(fake, client):
    client.port.write(b"sensorStop\n")
    assert client.port.read_until(PROMPT) == REAL_TRACE


# --------------------------------------------------------------------- commands
def test_unknown_command(client):
    reply = client.command("frobnicate 1 2")
    assert reply.outcome is Outcome.UNKNOWN_COMMAND
    assert reply.lines == (f"'frobnicate' {NOT_RECOGNIZED}",)


@pytest.mark.parametrize("line", [
    "channelCfg 15 7",  # typed, too few arguments
    "profileCfg 0 77 100 6 40 0 0 96 1 256 8000 0 0 30 9",  # too many
    "guiMonitor -1 0 0",  # verbatim, wrong count
    "sensorStop now",
    "channelCfg 15 7 1",  # cascading must be 0
    "adcCfg two 1",  # not a number
])
def test_malformed_command_is_error_minus_one(fake, client, line):
    reply = client.command(line)
    assert reply.outcome is Outcome.ERROR and reply.error_code == -1
    assert reply.lines[-1] == "Error -1"
    assert reply.lines[0].startswith("Error: Invalid usage of the CLI command")
    assert not fake.started


def test_empty_line_gets_the_prompt_only(client):
    client.port.write(b"\n")
    assert client.read_reply() == ""
    client.port.write(b"\r\n")
    assert client.read_reply() == ""


def test_version_and_help(client):
    reply = client.command("version")
    assert reply.outcome is Outcome.DONE
    assert any("xWR18xx" in ln for ln in reply.lines)
    assert any("mmWave SDK Version" in ln and "03." in ln for ln in reply.lines)
    reply = client.command("help")
    assert reply.outcome is Outcome.DONE
    assert any(ln.startswith("profileCfg:") for ln in reply.lines)
    assert any(ln.startswith("sensorStart:") for ln in reply.lines)


def test_sensor_start_without_config(fake, client):
    reply = client.command("sensorStart")
    assert reply.outcome is Outcome.ERROR and reply.error_code == -1
    assert reply.lines == (FULL_CONFIG_NEEDED, "Error -1")
    assert not fake.started
    reply = client.command("sensorStart 0")  # no previous config to restart either
    assert reply.lines == (FULL_CONFIG_NEEDED, "Error -1")


def test_start_stop_restart_and_callbacks(fake, client):
    events = []
    fake.on_sensor_start = lambda cfg: events.append(("start", cfg))
    fake.on_sensor_stop = lambda: events.append(("stop",))
    client.configure(small_cfg_commands())
    assert client.command("sensorStart").outcome is Outcome.DONE
    expected = RadarConfig.from_text(SMALL_CFG)
    assert fake.started and fake.config.frame_bytes == expected.frame_bytes == 3072

    reply = client.command("sensorStart")
    assert reply.outcome is Outcome.IGNORED and reply.lines == (ALREADY_STARTED, "Done")

    reply = client.command("profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30")
    assert reply.outcome is Outcome.IGNORED and reply.lines == (NOT_ALLOWED_AFTER_START, "Done")
    assert client.command("flushCfg").lines == (NOT_ALLOWED_AFTER_START, "Done")
    assert fake.started  # the firmware keeps running
    assert client.command("queryDemoStatus").lines[0] == "Sensor State: 2"

    assert client.command("sensorStop").lines == ("Done",)
    assert not fake.started
    assert client.command("sensorStart 0").outcome is Outcome.DONE  # previous config
    assert [e[0] for e in events] == ["start", "stop", "start"]
    assert events[0][1] == events[2][1] == fake.config
    assert typed_values(fake.config) == typed_values(expected)


def test_flush_then_start_needs_a_config_again(fake, client):
    client.configure(small_cfg_commands())
    assert client.command("flushCfg").outcome is Outcome.DONE
    reply = client.command("sensorStart")
    assert reply.lines == (FULL_CONFIG_NEEDED, "Error -1")
    assert not fake.started


def test_invalid_config_is_refused_with_the_reason(fake, client):
    lines = [ln.replace("frameCfg 0 2 4 0 50 1 0", "frameCfg 0 2 4 0 0.1 1 0")
             for ln in small_cfg_commands()]
    client.configure(lines)
    reply = client.command("sensorStart")
    assert reply.outcome is Outcome.ERROR and reply.error_code == -1
    assert "framePeriodicity" in reply.text and "shorter than the active frame time" in reply.text
    assert not fake.started and fake.config is None


def test_repeated_command_replaces_the_earlier_one(fake, client):
    client.configure(small_cfg_commands())
    client.configure(["frameCfg 0 2 4 0 100 1 0"])  # the firmware overwrites its setting
    assert client.command("sensorStart").outcome is Outcome.DONE
    assert fake.config.frame.frame_period_ms == 100


def test_start_without_raw_lvds_still_starts(fake, client):
    lines = [ln.replace("lvdsStreamCfg -1 0 1 0", "lvdsStreamCfg -1 0 0 0") for ln in small_cfg_commands()]
    client.configure(lines)
    assert client.command("sensorStart").outcome is Outcome.DONE
    assert fake.started and not fake.config.streams_raw_adc


def test_advanced_frame_commands_are_known_but_refused_at_start(fake, client):
    client.configure(small_cfg_commands())
    assert client.command("advFrameCfg 1 0 0 1 0").outcome is Outcome.DONE
    reply = client.command("sensorStart")
    assert reply.outcome is Outcome.ERROR and "not supported" in reply.text


# ------------------------------------------------------------------- line framing
def test_crlf_input(fake, client):
    reply = client.command("sensorStop", eol=b"\r\n")
    assert reply.outcome is Outcome.IGNORED
    assert bytes(client.raw) == REAL_TRACE  # the CR is not echoed
    assert fake.received == ["sensorStop"]


def test_line_split_across_many_writes(fake, client):
    line = "profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30"
    data = line.encode() + b"\r\n"
    for i in range(0, len(data), 3):
        client.port.write(data[i:i + 3])
        client.port.flush()
        time.sleep(0.002)
    text = client.read_reply()
    assert classify(text, line).outcome is Outcome.DONE
    assert text.startswith(line + "\n")
    # and two lines in one write get two replies
    client.port.write(b"sensorStop\nversion\n")
    assert classify(client.read_reply(), "sensorStop").outcome is Outcome.IGNORED
    assert classify(client.read_reply(), "version").outcome is Outcome.DONE
    assert fake.received == [line, "sensorStop", "version"]


# ------------------------------------------------------------------------ faults
def test_fault_error_on(fake, client):
    fake.faults.error_on = {"channelCfg": -5}
    reply = client.command("channelCfg 15 7 0")
    assert reply.outcome is Outcome.ERROR and reply.error_code == -5
    assert reply.lines == ("Error -5",)
    assert client.command("adcCfg 2 1").outcome is Outcome.DONE


def test_fault_silent_on_hangs_until_reset(fake, client):
    fake.faults.silent_on = {"adcCfg"}
    client.port.write(b"adcCfg 2 1\n")
    assert client.read_reply(timeout=0.5) is None
    assert bytes(client.raw) == b"adcCfg 2 1\n"  # echoed, then nothing
    client.port.write(b"version\n")  # the CLI task is stuck: no answer to anything
    assert client.read_reply(timeout=0.3) is None
    fake.faults.silent_on = set()
    fake.reset()
    text = client.read_reply()
    assert BOOT_BANNER[1] in text
    assert client.command("version").outcome is Outcome.DONE


def test_fault_hang_on_start_then_reset_and_restart(fake, client):
    stops = []
    fake.on_sensor_stop = lambda: stops.append(1)
    fake.faults.hang_on_start = True
    client.configure(small_cfg_commands())
    client.port.write(b"sensorStart\n")
    assert client.read_reply(timeout=0.5) is None
    assert not fake.started

    fake.reset()  # the DCA1000's RESET_AR_DEV
    banner = client.read_reply()
    assert banner is not None
    for ln in BOOT_BANNER:
        assert ln in banner
    assert not fake.started and fake.config is None and stops == []

    fake.faults.hang_on_start = False
    assert client.command("sensorStart").lines == (FULL_CONFIG_NEEDED, "Error -1")  # config gone
    client.configure(small_cfg_commands())
    assert client.command("sensorStart").outcome is Outcome.DONE
    assert fake.started and fake.config.frame_bytes == 3072

    fake.reset()  # a reset of a running radar stops it
    assert stops == [1] and not fake.started
    assert BOOT_BANNER[1] in client.read_reply()


def test_fault_garbage_before_replies(fake, client):
    fake.faults.garbage = b"\x00\xff\xfe~?\x80junk"
    client.port.write(b"channelCfg 15 7 0\n")
    text = client.read_reply()
    assert text.startswith("\x00") and "junkchannelCfg 15 7 0\n" in text  # noise, then the echo
    reply = classify(text, "channelCfg 15 7 0")
    assert reply.outcome is Outcome.DONE
    client.port.write(b"sensorStart\n")
    assert classify(client.read_reply(), "sensorStart").outcome is Outcome.ERROR


def test_fault_disappear_on(fake, client):
    fake.faults.disappear_on = "sensorStart"
    assert client.command("sensorStop").outcome is Outcome.IGNORED
    client.port.timeout = 2
    client.port.write(b"sensorStart\n")
    # On Linux the closed master hangs the pty up: select reports the slave
    # readable and read() either returns nothing, which pyserial turns into an
    # error, or fails with EIO itself (which one depends on when the read lands
    # against the hang-up; CI has seen both); writing, and even changing a
    # setting (tcsetattr), fail with EIO.
    with pytest.raises(serial.SerialException, match="returned no data|Input/output error"):
        client.port.read(1)
    with pytest.raises(serial.SerialException, match="Input/output error"):
        client.port.write(b"version\n")
    with pytest.raises(serial.SerialException, match="Input/output error"):
        client.port.timeout = 1
    assert fake.disappeared and fake.path is None
    assert fake.received[-1] == "sensorStart" and not fake.started
    fake.close()  # still fine after the port vanished


def test_fault_char_delay(fake, client):
    fake.faults.char_delay_s = 0.002
    line = "sensorStop"
    t0 = time.monotonic()
    client.port.write(line.encode() + b"\n")
    text = client.read_reply()
    elapsed = time.monotonic() - t0
    assert classify(text, line).outcome is Outcome.IGNORED
    assert elapsed >= 0.8 * len(REAL_TRACE) * 0.002
    assert client.reads > 5  # the reply arrived in pieces
    assert bytes(client.raw) == REAL_TRACE


def test_faults_at_construction():
    with FakeAwr1843(CliFaults(error_on={"version": 3})) as radar:
        c = Client(radar.open_pty())
        try:
            assert c.command("version").error_code == 3
        finally:
            c.close()


# --------------------------------------------------------------------- lifecycle
def test_close_is_idempotent_and_pty_can_reopen():
    radar = FakeAwr1843()
    path = radar.open_pty()
    with pytest.raises(RuntimeError):
        radar.open_pty()
    radar.close()
    radar.close()
    assert radar.path is None
    assert not any(t.name == f"fake-awr1843 {path}" and t.is_alive() for t in threading.enumerate())
    c = Client(radar.open_pty())  # plugged in again
    try:
        assert c.command("version").outcome is Outcome.DONE
    finally:
        c.close()
        radar.close()


def test_clients_can_come_and_go(fake):
    path = fake.open_pty()
    for _ in range(2):
        c = Client(path)
        try:
            assert c.command("sensorStop").outcome is Outcome.IGNORED
        finally:
            c.close()


def test_pyserial_url_handler():
    port = serial.serial_for_url("fakeawr1843://", baudrate=115200, timeout=1)
    try:
        port.write(b"sensorStop\n")
        assert port.read_until(PROMPT) == REAL_TRACE
        assert port.fake.received == ["sensorStop"]
    finally:
        port.close()
    assert port.fake.path is None  # the private fake closed with the port

    with FakeAwr1843(name="bench") as radar:
        port = serial.serial_for_url("fakeawr1843://bench", timeout=1)
        try:
            port.write(b"version\n")
            assert b"xWR18xx" in port.read_until(PROMPT)
            assert port.fake is radar and radar.received == ["version"]
        finally:
            port.close()
    with pytest.raises(serial.SerialException):
        serial.serial_for_url("fakeawr1843://nobody")


# --------------------------------------------------------------------------- the emulators' pty writes
def test_a_pty_write_to_a_client_that_does_not_read_loses_the_rest_after_its_timeout(caplog):
    # The CLI's and the demo data port's writes share write_all: a real pty whose slave nobody
    # reads fills up; the write gives up after its timeout with what went in, as a UART loses
    # bytes, and says so.  Stopped or closed, it writes nothing.
    import os
    import tty

    from radarodom.driver.emulators.awr1843_pty import write_all

    master, slave = os.openpty()
    tty.setraw(slave)  # as the emulators' ptys: bytes as they are, no line discipline
    os.set_blocking(master, False)
    try:
        data = bytes(range(256)) * 4096  # 1 MiB: far more than a pty buffers
        with caplog.at_level("WARNING"):
            written = write_all(lambda: master, data, 0.2, lambda: False, "test pty")
        assert 0 < written < len(data)
        assert f"{len(data) - written} bytes lost" in caplog.text
        assert os.read(slave, 256) == data[:256]  # in order, from the start
        assert write_all(lambda: master, b"more", 0.2, lambda: True, "test pty") == 0
        assert write_all(lambda: None, b"more", 0.2, lambda: False, "test pty") == 0
    finally:
        os.close(master)
        os.close(slave)
