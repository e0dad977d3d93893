"""Another client than radarodom's own: xwr (PyPI ``xwr``, RadarML/xwr, 0.5.x), streaming the
emulators end to end through its high-level ``XWRSystem(...).stream()``.

xwr does what a user of the real boards does, with its own timing and its own expectations:
it resets the radar (RESET_AR_DEV) and talks to it at once, so the fake radar's boot must
behave like the board's (deaf, then a banner, which xwr takes as the answer to its first
command); it configures its own chirp order (TX1, TX2, TX3) and frame size, so the fake
board must stream that configuration's frames; it reads any datagram on its config socket
as the answer to its command, so no status message may come at the wrong moment (the
NO_LVDS_DATA timeout must outlast the boot and the configuration); and it sends commands to
the port number it binds on the host, so the fake board listens on that number.

The frames xwr assembles must be byte for byte what radarodom's simulator makes for the
equivalent cfg (the lines xwr sends), in xwr's TX order.  Skipped where xwr is not
installed; CI installs it with the test extra.
"""

from __future__ import annotations

import socket

import pytest
from conftest import REPO
from radarodom.cfg import RadarConfig
from radarodom.driver.live.dca1000_wire import AsyncStatus, Command
from radarodom.driver.emulators.rig import BOARD_IP, HOST_IP, EmulatedRig, free_udp_port
from radarodom.driver.sources import open_source

xwr = pytest.importorskip("xwr", reason="xwr is not installed (pip install 'radarodom[test]' installs it): "
                                        "the test of another client against the emulators needs it")

#: xwr's radar settings: its documented AWR1843 example (64 chirps per TX, 256 samples, 10 Hz).
XWR_RADAR = dict(device="AWR1843", frequency=77.0, idle_time=110.0, adc_start_time=4.0, ramp_end_time=56.0,
                 tx_start_time=1.0, freq_slope=70.006, adc_samples=256, sample_rate=5000, frame_length=64,
                 frame_period=100.0)

#: What xwr 0.5.1's AWR1843.setup sends for XWR_RADAR, line for line: radarodom's equivalent cfg.
XWR_CFG = """\
sensorStop
flushCfg
dfeDataOutputMode 1
adcCfg 2 1
adcbufCfg -1 0 1 1 1
profileCfg 0 77.0 110.0 4.0 56.0 0 0 70.006 1.0 256 5000 0 0 30
channelCfg 15 7 0
chirpCfg 0 0 0 0.0 0.0 0.0 0.0 1
chirpCfg 1 1 0 0.0 0.0 0.0 0.0 2
chirpCfg 2 2 0 0.0 0.0 0.0 0.0 4
frameCfg 0 2 64 0 100.0 1 0.0
compRangeBiasAndRxChanPhase 0.0 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1
lvdsStreamCfg -1 0 1 0
lowPower 0 0
guiMonitor -1 0 0 0 0 0 0
cfarCfg -1 0 0 4 2 3 1 15.0 1
cfarCfg -1 1 0 4 2 3 1 15.0 1
multiObjBeamForming -1 0 0.5
calibDcRangeSig -1 0 -5 8 256
clutterRemoval -1 0
aoaFovCfg -1 -90 90 -90 90
cfarFovCfg -1 0 0 0
cfarFovCfg -1 1 0 0
measureRangeBiasAndRxChanPhase 0 1.5 0.2
extendedMaxVelocity -1 0
CQRxSatMonitor 0 3 5 121 0
CQSigImgMonitor 0 127 4
analogMonitor 0 0
calibData 0 0 0
sensorStart
"""

#: The simulated scene the emulator streams, and its seed.
SCENE = "sim://calibration?seed=7"
FRAMES = 8


@pytest.fixture
def loopback_board_address():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind((BOARD_IP, 0))
        except OSError as exc:
            pytest.skip(f"{BOARD_IP} is not on this computer's loopback ({exc.strerror}): Linux has all of "
                        f"127.0.0.0/8, other systems need an alias")


def expected_frames(cfg: RadarConfig, n: int) -> list[bytes]:
    # The emulator's simulator runs at its real-time fidelity.
    with open_source(SCENE + "&rate=max&fidelity=fast", cfg) as sim:
        return [bytes(f.raw) for _, f in zip(range(n), sim)]


def stream_with_xwr(cli_path: str, config_port: int, data_port: int, n: int) -> list:
    """*n* frames from a fresh XWRSystem (xwr streams once per system), then its stop(); the
    sockets and the port xwr never closes are closed here."""
    system = xwr.XWRSystem(
        radar={**XWR_RADAR, "port": cli_path},
        capture=xwr.DCAConfig(sys_ip=HOST_IP, fpga_ip=BOARD_IP, config_port=config_port,
                              data_port=data_port, timeout=5.0, socket_buffer=4 * 786432, delay=5.0))
    try:
        frames = []
        for frame in system.stream():
            frames.append(frame)
            if len(frames) == n:
                break
        system.stop()
        return frames
    finally:
        system.dca.config_socket.close()
        system.dca.data_socket.close()
        system.xwr.port.close()


def test_xwr_streams_the_emulators_frames_byte_exact_in_its_tx_order(loopback_board_address):
    shipped = RadarConfig.from_file(REPO / "configs" / "awr1843_raw.cfg")
    equivalent = RadarConfig.from_text(XWR_CFG, "xwr.cfg")
    assert shipped.tx_order == (1, 3, 2) and equivalent.tx_order == (1, 2, 3)
    want = expected_frames(equivalent, FRAMES)
    ti_text = (XWR_CFG.replace("chirpCfg 1 1 0 0.0 0.0 0.0 0.0 2", "chirpCfg 1 1 0 0.0 0.0 0.0 0.0 4")
               .replace("chirpCfg 2 2 0 0.0 0.0 0.0 0.0 4", "chirpCfg 2 2 0 0.0 0.0 0.0 0.0 2"))
    ti_order = expected_frames(RadarConfig.from_text(ti_text, "ti-order.cfg"), 2)
    assert want[:2] != ti_order, "the TX order does not change the simulated bytes: the test proves nothing"

    # The emulator starts out streaming the shipped cfg (TI's order, TX1 TX3 TX2) and the boards'
    # own timings; xwr binds the same config port number on the host that it sends to.
    port = free_udp_port(HOST_IP, BOARD_IP)
    with EmulatedRig(SCENE, config=shipped, command_port=port) as rig:
        got = stream_with_xwr(rig.cli_path, rig.board.command_port, rig.data_port, FRAMES)
        radar_cfg = rig.board.config  # what the radar streamed (xwr's stop() resets the radar itself)
        received = list(rig.radar.received)
        commands = rig.board.commands
        statuses = rig.board.async_sent

    assert len(got) == FRAMES
    assert all(f.complete for f in got), [f.complete for f in got]
    assert all(len(f.data) == equivalent.frame_bytes for f in got)
    mismatched = [k for k, (f, w) in enumerate(zip(got, want)) if bytes(f.data) != w]
    assert not mismatched, f"frames {mismatched} differ from the simulator's in xwr's TX order"

    # What xwr configured is the equivalent cfg; its first command fell into the radar's boot.
    assert radar_cfg.tx_order == (1, 2, 3) and radar_cfg.cube_shape == equivalent.cube_shape
    assert radar_cfg.frame_period_s == equivalent.frame_period_s
    assert received[0] == "flushCfg", received[:3]  # sensorStop went to a radar still booting
    assert received[-2:] == ["calibData 0 0 0", "sensorStart"], received[-3:]
    assert commands[Command.RESET_AR_DEV] == 2 and commands[Command.RECORD_START] == 1
    assert commands[Command.RECORD_STOP] == 2  # stream() and stop() each send one
    # No status message reached xwr while it waited for command answers.
    assert AsyncStatus.NO_LVDS_DATA not in statuses, statuses


def test_xwr_streams_radar_emulate_on_the_ports_it_is_given(loopback_board_address):
    """As a user would try it: radar-emulate --command-port P --data-port D prints what to give
    xwr, and xwr's XWRSystem streams from it."""
    from live_helpers import Emulator

    port, data_port = free_udp_port(HOST_IP, BOARD_IP), free_udp_port(HOST_IP)
    with Emulator("--source", SCENE, "--command-port", port, "--data-port", data_port) as emu:
        hint = emu.stdout.wait_for(lambda ln: ln.startswith("xwr: "), timeout=10)
        assert hint == (f"xwr: XWRConfig(port={emu.cli_path!r}, ...), DCAConfig(sys_ip='{HOST_IP}', "
                        f"fpga_ip='{BOARD_IP}', config_port={port}, data_port={data_port})\n"), hint
        assert f"board_port={port}" in emu.command_line and f"data_port={data_port}" in emu.command_line
        got = stream_with_xwr(emu.cli_path, port, data_port, 3)
        assert emu.stop() == 0
    want = expected_frames(RadarConfig.from_text(XWR_CFG, "xwr.cfg"), 3)
    assert [bytes(f.data) for f in got] == want
