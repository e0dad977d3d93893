"""Where a real client could tell the emulators from the boards, they behave like the boards:

- the fake AWR1843 takes time to boot after RESET_AR_DEV, deaf meanwhile (what it is sent is
  lost, not echoed), then prints its banner; radarodom's driver sends a lost repeatable
  command again and never repeats a configuration line;
- the fake DCA1000 streams the frames of the configuration the client gave the radar: the
  simulator makes them anew in the client's TX order, a recording's TX slots are reordered;
- when the fake DCA1000 falls behind, its warning names the cause: the link (the frames do
  not fit the period at the packet delay) or its own CPU (the source makes frames too slowly).
"""

from __future__ import annotations

import logging
import time

import numpy as np
import pytest
import serial
from conftest import REPO, SMALL_CFG, make_capture, warning_messages
from live_helpers import URL_TIMEOUTS, collect, config
from radarodom.cfg import RadarConfig
from radarodom.driver.live.awr1843 import Awr1843Cli
from radarodom.driver.live.awr1843_protocol import PROMPT, Outcome
from radarodom.driver.live.dca1000_wire import PacketConfig, Command
from radarodom.driver.emulators.fake_awr1843 import BOOT_BANNER, BOOT_TIME_S, FakeAwr1843
from radarodom.driver.emulators.fake_dca1000 import FakeDca1000
from radarodom.driver.emulators.rig import EmulatedRig
from radarodom.driver.sources import open_source
from radarodom.errors import DeviceTimeout
from radarodom.rawframe import RawLayout
from test_fake_dca1000 import collect as collect_datagrams
from test_fake_dca1000 import command, pattern_frames, start_recording, udp_socket

#: TI's chirp order (TX masks 1, 4, 2: TX1, TX3, TX2), as in the shipped cfg and SMALL_CFG.
TI_ORDER = ("chirpCfg 1 1 0 0 0 0 0 4", "chirpCfg 2 2 0 0 0 0 0 2")
#: xwr's order (masks 1, 2, 4: TX1, TX2, TX3).
XWR_ORDER = ("chirpCfg 1 1 0 0 0 0 0 2", "chirpCfg 2 2 0 0 0 0 0 4")


def in_xwr_order(text: str) -> str:
    for ti, xwr in zip(TI_ORDER, XWR_ORDER):
        assert ti in text
        text = text.replace(ti, xwr)
    return text


# ---------------------------------------------------------------------- the radar's boot
def read_until_prompt(port, timeout: float) -> tuple[bytes, float]:
    """Bytes up to and including the next prompt, and time.monotonic() when it came."""
    data = bytearray()
    deadline = time.monotonic() + timeout
    while not data.endswith(PROMPT) and time.monotonic() < deadline:
        port.timeout = 0.05
        data += port.read(max(1, port.in_waiting))
    return bytes(data), time.monotonic()


def test_a_reset_radar_is_deaf_while_it_boots_then_prints_its_banner():
    assert BOOT_TIME_S == 0.5  # the default the docs give the source of (docs/live.md)
    with FakeAwr1843(boot_time_s=0.4) as radar:
        port = serial.serial_for_url(radar.open_pty(), baudrate=115200, timeout=0.05)
        try:
            reset = time.monotonic()
            radar.reset()
            assert radar.booting
            port.write(b"sensorStop\n")  # into a radar still booting: lost
            data, at = read_until_prompt(port, 5.0)
            assert at - reset >= 0.4, "the banner came before the boot time"
            assert b"sensorStop" not in data, data  # never echoed
            text = data.decode()
            assert all(line in text for line in BOOT_BANNER), text
            assert radar.received == [] and not radar.booting
            port.write(b"sensorStop\n")  # booted: answered as a real radar does
            data, _ = read_until_prompt(port, 5.0)
            assert data == b"sensorStop\nIgnored: Sensor is already stopped\n\rDone\n\rmmwDemo:/>"
        finally:
            port.close()


def test_the_driver_sends_a_repeatable_command_lost_in_the_boot_again(caplog):
    caplog.set_level(logging.INFO, logger="radarodom")
    with FakeAwr1843(boot_time_s=0.3) as radar, Awr1843Cli(radar.open_pty(), command_timeout_s=5.0) as cli:
        radar.reset()
        reply = cli.send("sensorStop")
        assert reply.outcome is Outcome.IGNORED
        assert radar.received == ["sensorStop"]  # the first one fell into the boot
    assert any("has just booted; sending 'sensorStop' again" in r.getMessage() for r in caplog.records)


def test_a_configuration_line_lost_in_the_boot_is_not_sent_again():
    """Sent twice, a chirpCfg would define its chirp twice: the driver waits and says so."""
    with FakeAwr1843(boot_time_s=0.3) as radar, Awr1843Cli(radar.open_pty(), command_timeout_s=1.0) as cli:
        radar.reset()
        with pytest.raises(DeviceTimeout) as info:
            cli.send("chirpCfg 0 0 0 0 0 0 0 1")
        assert radar.received == []
    assert "did not answer 'chirpCfg'" in str(info.value)


def test_a_live_session_right_after_a_reset_configures_the_booting_radar(tmp_path, small_cfg):
    directory = tmp_path / "src"
    frames = make_capture(directory, small_cfg, 3)
    with EmulatedRig(f"replay://{directory}", config=small_cfg, record_completed_delay_s=0.2) as rig:
        rig.radar.reset()  # a RESET_AR_DEV a moment ago (xwr resets at every stream())
        with open_source(rig.url(cli_timeout=5, **URL_TIMEOUTS), small_cfg) as src:
            got = collect(src, 3, timeout=10)
        assert rig.radar.received[:2] == ["sensorStop", "flushCfg"]  # the lost sensorStop is not there
    assert [g.raw for g in got] == frames


# ---------------------------------------------------------------------- the client's TX order
@pytest.mark.parametrize("scene, cfg", [("calibration", "shipped"), ("lab", "small")])
def test_the_simulator_makes_the_frames_in_the_clients_tx_order(scene, cfg):
    """The emulator streams the shipped order (TX1, TX3, TX2); the client configures xwr's."""
    text = (REPO / "configs" / "awr1843_raw.cfg").read_text() if cfg == "shipped" else SMALL_CFG
    shipped = RadarConfig.from_text(text, f"{cfg}.cfg")
    assert shipped.tx_order == (1, 3, 2)
    client = RadarConfig.from_text(in_xwr_order(text), "xwr-order.cfg")
    assert client.tx_order == (1, 2, 3)
    url = f"sim://{scene}?seed=4"
    # The emulator's simulator runs at its real-time fidelity.
    with open_source(url + "&rate=max&fidelity=fast", client) as sim:
        want = [bytes(f.raw) for _, f in zip(range(3), sim)]
    with open_source(url + "&rate=max&fidelity=fast", shipped) as sim:
        ti_order = [bytes(f.raw) for _, f in zip(range(3), sim)]
    assert want != ti_order  # the order matters to the bytes

    with EmulatedRig(url, config=shipped, record_completed_delay_s=0.2) as rig:
        with open_source(rig.url(timeout=0.3, start_timeout=10), client) as src:
            got = collect(src, 3, timeout=20)
        assert rig.board.config.tx_order == client.tx_order and rig.board.config.cube_shape == client.cube_shape
    assert [g.index for g in got] == [0, 1, 2]
    assert all(g.missing_bytes == 0 for g in got)
    assert [g.raw for g in got] == want, "the frames are not the simulator's, in the client's order"


def test_a_recordings_tx_slots_are_streamed_in_the_clients_order(tmp_path, small_cfg, warnings_log):
    client = config(in_xwr_order(SMALL_CFG), "xwr-order.cfg")
    assert small_cfg.tx_order == (1, 3, 2) and client.tx_order == (1, 2, 3)
    directory = tmp_path / "src"
    frames = make_capture(directory, small_cfg, 3)
    with EmulatedRig(f"replay://{directory}", config=small_cfg, record_completed_delay_s=0.2) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), client) as src:
            got = collect(src, 4)
    recorded, streamed = RawLayout.from_config(small_cfg), RawLayout.from_config(client)
    for g in got:
        want = recorded.decode(np.frombuffer(frames[g.index % 3], np.uint8))[:, [0, 2, 1]]
        assert np.array_equal(streamed.decode(np.frombuffer(g.raw, np.uint8)), want), g.index
        assert g.raw != frames[g.index % 3]
    assert not [m for m in warning_messages(warnings_log) if "fake DCA1000" in m], warning_messages(warnings_log)


# ---------------------------------------------------------------------- falling behind
def _stream_late(board: FakeDca1000, frames: int, *, delay_us: float = 25.0) -> None:
    client = udp_socket()
    try:
        command(client, board, Command.CONFIG_PACKET_DATA, PacketConfig(1472, delay_us).pack())
        start_recording(client, board)
        board.lvds_start()
        assert board.wait_frames(frames, timeout=20, streamed=True)
        board.lvds_stop()
    finally:
        client.close()


def test_a_source_slower_than_the_period_is_blamed_on_the_cpu_not_the_link(warnings_log):
    period = 0.02
    frames = pattern_frames(6)

    def slow():
        for raw in frames:
            time.sleep(2 * period)
            yield raw

    receiver = udp_socket(rcvbuf=1 << 22)
    try:
        with FakeDca1000(host_data_port=receiver.getsockname()[1], frames=slow, frame_period_s=period,
                         record_completed_delay_s=0.05) as board:
            _stream_late(board, 5)
            collect_datagrams(receiver, quiet=0.1)
    finally:
        receiver.close()
    late = [m for m in warning_messages(warnings_log) if "is" in m and "late" in m]
    assert len(late) == 1, late  # once per recording
    assert "makes frames slower than the 20.0 ms frame period on this computer's CPU" in late[0], late
    assert "325.0 Mbit/s link needs 0.1 ms a frame" in late[0], late


def test_frames_that_do_not_fit_the_link_are_blamed_on_the_link(warnings_log):
    period = 0.01
    frames = pattern_frames(4, 50 * 1456)  # 25 ms each at 500 us packet delay (23.2 Mbit/s)
    receiver = udp_socket(rcvbuf=1 << 23)
    try:
        with FakeDca1000(host_data_port=receiver.getsockname()[1], frames=lambda: iter(frames),
                         frame_period_s=period, record_completed_delay_s=0.05) as board:
            _stream_late(board, 4, delay_us=500)
            collect_datagrams(receiver, quiet=0.1)
    finally:
        receiver.close()
    late = [m for m in warning_messages(warnings_log) if "late" in m]
    assert len(late) == 1, late
    assert "the link, 23.2 Mbit/s at 500.0 us packet delay, needs 25.1 ms for a 72800-byte frame" in late[0], late
    assert "more than the 10.0 ms frame period" in late[0], late
