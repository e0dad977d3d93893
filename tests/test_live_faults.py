"""The live driver (``dca1000://``) under faults, against the emulated rig.

Data stream faults (loss, duplicates, reordering, truncation, malformed and
foreign packets) are checked frame by frame against the fake board's ground
truth (``lost_bytes_per_frame``); radar CLI faults (error replies, silence,
line noise, a hung sensorStart, a port that disappears) and board faults (no
answer, failure status, asynchronous status) must end in one clear
radarodom error, with the radar stopped and every resource released.

Loss tests use LOSS_CFG (12288-byte frames every 10 ms); the others SMALL_CFG
(3072 bytes every 50 ms).
"""

from __future__ import annotations

import time

import pytest
from conftest import SMALL_CFG, warning_messages
from live_helpers import (
    NO_LVDS_CFG,
    URL_TIMEOUTS,
    assert_drops_accounted,
    assert_frames_match,
    cfg_line,
    collect,
    config,
    fds_open_on,
    port_is_free,
    receiver_threads,
    wait_until,
)
from radarodom.driver.live.awr1843 import COMMAND_TIMEOUT_S, SensorStartHung
from radarodom.driver.live.awr1843_protocol import REPEATABLE
from radarodom.driver.live.dca1000_wire import AsyncStatus, Command, FpgaVersion
from radarodom.driver.emulators.fake_awr1843 import CliFaults
from radarodom.driver.emulators.fake_dca1000 import Faults
from radarodom.driver.emulators.rig import BOARD_IP, HOST_IP, EmulatedRig, free_udp_port
from radarodom.driver.sources import open_source
from radarodom.errors import ConfigError, DeviceError, DeviceTimeout, RadarCommandError

N_SRC = 7


def assert_released(rig: EmulatedRig) -> None:
    """The driver holds nothing any more: data port, CLI pty, receiver thread."""
    assert port_is_free(HOST_IP, rig.data_port), "the data socket is still open"
    if rig.radar.path is not None:
        assert fds_open_on(rig.radar.path) <= 1, "the radar's CLI port is still open"  # the fake's own slave fd
    assert wait_until(lambda: not receiver_threads(), 2.0), "the receiver thread still runs"


def stream_under(faults: Faults, directory: str, cfg, n: int, seed: int = 7, **url):
    """Stream *n* frames from a rig with *faults*; (frames, describe() while running,
    the board's ground truth of lost bytes per frame, the board's stream stats)."""
    with EmulatedRig(f"replay://{directory}", config=cfg, faults=faults, seed=seed) as rig:
        with open_source(rig.url(**URL_TIMEOUTS, **url), cfg) as src:
            got = collect(src, n, timeout=8.0)
            described = src.describe()
        lost = rig.board.lost_bytes_per_frame
        stats = rig.board.stats
        assert_released(rig)
    return got, described, lost, stats


def assert_exact_accounting(got, lost) -> None:
    """Each delivered frame's missing bytes are the board's ground truth, exactly."""
    wrong = [(g.index, g.missing_bytes, lost.get(g.index, 0)) for g in got
             if g.missing_bytes != lost.get(g.index, 0)]
    assert not wrong, f"(frame, missing_bytes reported, lost by the board): {wrong[:10]}"


# ---------------------------------------------------------------------- packet loss
@pytest.mark.parametrize("loss, n", [(0.01, 100), (0.10, 60), (0.50, 60)])
def test_packet_loss_is_accounted_exactly_per_frame(loss_capture, loss_cfg, loss, n):
    directory, frames = loss_capture
    got, described, lost, stats = stream_under(Faults(loss=loss), directory, loss_cfg, n)
    assert len(got) == n
    assert_drops_accounted([g.index for g in got], described["frames_dropped"])
    assert stats.dropped > 0, "nothing was lost: the test proves nothing"
    assert_exact_accounting(got, lost)
    assert_frames_match(got, frames)
    assert any(g.missing_bytes for g in got)
    assert described["foreign_packets"] == described["malformed_packets"] == 0
    assert described["missing_bytes"] >= sum(g.missing_bytes for g in got)


def test_packet_loss_with_small_frames_is_accounted_exactly_per_frame(small_capture, small_cfg):
    directory, frames = small_capture
    got, described, lost, _ = stream_under(Faults(loss=0.1), directory, small_cfg, 25, seed=5)
    assert_exact_accounting(got, lost)
    assert_frames_match(got, frames)
    assert len(got) == 25
    assert_drops_accounted([g.index for g in got], described["frames_dropped"])


# ---------------------------------------------------------------------- other stream faults
STREAM_FAULTS = {
    "duplicate": Faults(duplicate=0.2),
    "reorder": Faults(reorder=0.2),
    "truncate": Faults(truncate=0.1),
    "malformed": Faults(malformed=0.1),
    "foreign": Faults(foreign=0.2),
    "all": Faults(loss=0.05, duplicate=0.1, reorder=0.1, truncate=0.05, malformed=0.05, foreign=0.1),
}


@pytest.mark.parametrize("name", list(STREAM_FAULTS))
def test_stream_faults_never_corrupt_or_misalign_a_frame(loss_capture, loss_cfg, name):
    directory, frames = loss_capture
    faults = STREAM_FAULTS[name]
    got, d, lost, stats = stream_under(faults, directory, loss_cfg, 50)
    assert len(got) == 50
    assert_drops_accounted([g.index for g in got], d["frames_dropped"])
    assert_exact_accounting(got, lost)
    assert_frames_match(got, frames)
    assert d["late_packets"] == 0, d
    if faults.duplicate:
        assert stats.duplicates > 0 and d["duplicate_packets"] > 0, d
    if faults.foreign:
        assert stats.foreign > 0 and d["foreign_packets"] > 0, d
    else:
        assert d["foreign_packets"] == 0, d
    if faults.malformed:
        assert stats.malformed > 0 and d["malformed_packets"] > 0, d
    else:
        assert d["malformed_packets"] == 0, d
    if faults.truncate:
        assert stats.truncated > 0 and any(g.missing_bytes for g in got)
        assert 0 < d["truncated_packets"] <= stats.truncated, d
    else:  # neither loss, nor duplicates, nor reordering look like truncation
        assert d["truncated_packets"] == 0, d
    if name in ("duplicate", "reorder", "foreign"):  # nothing is lost
        assert not lost and all(g.missing_bytes == 0 for g in got)
        assert d["missing_bytes"] == 0, d
    if name == "reorder":
        assert stats.reordered > 0


def test_reordering_alone_reports_no_lost_packets(loss_capture, loss_cfg):
    directory, _ = loss_capture
    faults = Faults(reorder=0.2)
    _, d, lost, stats = stream_under(faults, directory, loss_cfg, 40)
    assert stats.reordered > 0 and not lost
    # At most the packets still held back at the moment of describe() may look lost.
    assert d["seq_gaps"] <= faults.reorder_depth, d


# ---------------------------------------------------------------------- radar CLI faults
def test_radar_error_reply_names_the_cfg_line_quotes_the_radar_and_stops_it(small_capture, small_cfg):
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg,
                     cli_faults=CliFaults(error_on={"profileCfg": -1})) as rig:
        with pytest.raises(RadarCommandError) as info:
            open_source(rig.url(**URL_TIMEOUTS), small_cfg)
        received = list(rig.radar.received)
        assert_released(rig)
        commands = rig.board.commands
    message = str(info.value)
    assert f"small.cfg:{cfg_line(SMALL_CFG, 'profileCfg')}: profileCfg" in message, message
    assert "Error -1" in message, message
    assert received[-1] == "sensorStop", received  # stopped after the error
    assert received.index("profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30") == len(received) - 2
    assert "sensorStart" not in received
    assert Command.RECORD_START not in commands


def test_radar_silent_on_a_command_times_out_naming_it(small_capture, small_cfg):
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg,
                     cli_faults=CliFaults(silent_on={"channelCfg"})) as rig:
        t0 = time.monotonic()
        with pytest.raises(DeviceTimeout) as info:
            open_source(rig.url(**URL_TIMEOUTS), small_cfg)
        elapsed = time.monotonic() - t0
        received = list(rig.radar.received)
        assert_released(rig)
    message = str(info.value)
    assert f"small.cfg:{cfg_line(SMALL_CFG, 'channelCfg')}: channelCfg" in message, message
    assert "did not answer 'channelCfg'" in message and f"{COMMAND_TIMEOUT_S:g} s" in message, message
    # It waited the command's timeout (at least; a loaded machine may add any delay).
    assert COMMAND_TIMEOUT_S <= elapsed, elapsed
    assert received[-1] == "sensorStop", received


def test_radar_cli_timeout_is_set_by_the_url(small_capture, small_cfg):
    """cli_timeout=S bounds each radar command instead of the default 2 s."""
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg,
                     cli_faults=CliFaults(silent_on={"channelCfg"})) as rig:
        t0 = time.monotonic()
        with pytest.raises(DeviceTimeout) as info:
            open_source(rig.url(**URL_TIMEOUTS, cli_timeout=0.3), small_cfg)
        elapsed = time.monotonic() - t0
        assert_released(rig)
    assert "did not answer 'channelCfg' within 0.3 s" in str(info.value), str(info.value)
    assert elapsed >= 0.3, elapsed


@pytest.mark.parametrize("garbage", [b"\x00\xfe\xff\x1b[0m line noise Done\r\n",
                                     b"\n\r****\n\rxWR18xx MMW Demo 03.05.00.04\n\rmmwDemo:/>"],
                         ids=["noise", "stale-banner-and-prompt"])
def test_radar_line_noise_does_not_break_configuration(small_capture, small_cfg, garbage):
    directory, frames = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg,
                     cli_faults=CliFaults(garbage=garbage)) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            got = collect(src, 3)
        # A banner in front of an echo looks like a boot that lost the command, so the driver may
        # send sensorStop or flushCfg twice (harmless); no configuration line is ever repeated.
        received = rig.radar.received
        once = [c for i, c in enumerate(received) if i == 0 or c != received[i - 1] or c not in REPEATABLE]
        assert once[-2:] == ["sensorStart", "sensorStop"]
        lines = [c for c in once if c not in REPEATABLE]
        assert len(set(lines)) == len(lines)
        assert not rig.radar.started
        assert rig.radar.config is not None and rig.radar.config.frame_bytes == small_cfg.frame_bytes
    assert [g.index for g in got] == [0, 1, 2]
    assert_frames_match(got, frames)


def test_hung_sensor_start_is_reported_and_recovered_with_reset_ar_dev(small_capture, small_cfg):
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg,
                     cli_faults=CliFaults(hang_on_start=True)) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            t0 = time.monotonic()
            with pytest.raises(SensorStartHung) as info:
                collect(src, 1)
            elapsed = time.monotonic() - t0
            assert rig.board.commands.get(Command.RESET_AR_DEV) == 1
            assert rig.radar.config is None and not rig.radar.started  # reset: configuration gone
        assert not rig.board.recording
        assert rig.board.commands.get(Command.RECORD_STOP) == 1
        assert_released(rig)
    message = str(info.value)
    assert "sensorStart got no answer within 1 s" in message, message
    assert "reset it through the DCA1000 (RESET_AR_DEV)" in message, message
    assert elapsed >= 1.0, elapsed  # it waited start_timeout before giving up


@pytest.mark.parametrize("command", ["sensorStop", "profileCfg"])
def test_cli_port_disappearing_during_configuration_is_a_device_error(small_capture, small_cfg, command):
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg,
                     cli_faults=CliFaults(disappear_on=command)) as rig:
        path = rig.cli_path
        with pytest.raises(DeviceError) as info:
            # A generous CLI timeout: on a busy machine the fake's thread may take seconds to read
            # the command; the driver, timing out first, met the vanishing while it closed instead.
            open_source(rig.url(**URL_TIMEOUTS, cli_timeout=30.0), small_cfg)
        assert rig.radar.disappeared
        assert port_is_free(HOST_IP, rig.data_port)
        assert fds_open_on(path) == 0, "the driver still holds the vanished CLI port"
        assert Command.RECORD_START not in rig.board.commands
    message = str(info.value)
    assert not isinstance(info.value, DeviceTimeout)
    assert path in message and "unplugged" in message, message
    if command == "profileCfg":  # a cfg line, not the preamble: the message says which
        line = cfg_line(SMALL_CFG, "profileCfg")
        assert message.startswith(f"{small_cfg.path}:{line}: profileCfg"), message


def test_cli_port_disappearing_at_stop_is_a_warning_and_the_board_still_stops(small_capture, small_cfg,
                                                                             warnings_log):
    directory, frames = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        path = rig.cli_path
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            got = collect(src, 3)
            rig.radar.faults.disappear_on = "sensorStop"  # the cable is pulled before we stop
        # close() did not raise; it told what failed and stopped the board anyway.
        assert rig.radar.disappeared
        assert not rig.board.recording and rig.board.commands.get(Command.RECORD_STOP) == 1
        assert port_is_free(HOST_IP, rig.data_port)
        assert fds_open_on(path) == 0
    assert_frames_match(got, frames)
    warned = [m for m in warning_messages(warnings_log) if "while stopping" in m]
    assert len(warned) == 1 and path in warned[0] and "unplugged" in warned[0], warning_messages(warnings_log)


def test_stream_stopping_mid_run_raises_instead_of_waiting_forever(small_capture, small_cfg):
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            def radar_dies(frame, got):
                if len(got) == 3:
                    rig.board.lvds_stop()  # the radar stops streaming, nothing else says so

            # The source raises (collect's own 3 s limit would end in an AssertionError instead).
            with pytest.raises(DeviceError):
                collect(src, 1000, timeout=3.0, on_frame=radar_dies)


# ---------------------------------------------------------------------- board faults
def test_no_board_at_the_address_times_out_with_what_to_check(small_capture, small_cfg):
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        t0 = time.monotonic()
        with pytest.raises(DeviceTimeout) as info:
            open_source(rig.url(board_port=free_udp_port(BOARD_IP), timeout=0.2), small_cfg)
        elapsed = time.monotonic() - t0
        assert rig.radar.received == []  # the board is checked before the radar is touched
        assert_released(rig)
    message = str(info.value)
    assert "SYSTEM_CONNECT" in message and "3 tries of 0.2 s" in message, message
    assert "powered" in message and "cable" in message and HOST_IP in message, message
    assert 3 * 0.2 - 0.05 <= elapsed, elapsed  # three tries, each waited out


def test_board_silent_on_system_connect_times_out_after_retries(small_capture, small_cfg):
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg,
                     faults=Faults(silent_commands={Command.SYSTEM_CONNECT})) as rig:
        t0 = time.monotonic()
        with pytest.raises(DeviceTimeout) as info:
            open_source(rig.url(**URL_TIMEOUTS), small_cfg)
        elapsed = time.monotonic() - t0
        assert rig.board.commands == {Command.SYSTEM_CONNECT: 3}
        assert_released(rig)
    assert "did not answer SYSTEM_CONNECT after 3 tries of 0.3 s" in str(info.value)
    assert 0.85 <= elapsed, elapsed  # three tries, each waited out


def test_board_failure_status_names_the_command(small_capture, small_cfg):
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg,
                     faults=Faults(fail_commands={Command.CONFIG_FPGA_GEN})) as rig:
        with pytest.raises(DeviceError) as info:
            open_source(rig.url(**URL_TIMEOUTS), small_cfg)
        assert rig.radar.received == []
        assert Command.RECORD_START not in rig.board.commands
        assert_released(rig)
    assert not isinstance(info.value, DeviceTimeout)
    assert "CONFIG_FPGA_GEN" in str(info.value), str(info.value)


def test_board_in_playback_mode_is_refused(small_capture, small_cfg):
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        rig.board.fpga_version = FpgaVersion(2, 8, True)
        with pytest.raises(DeviceError) as info:
            open_source(rig.url(**URL_TIMEOUTS), small_cfg)
        assert rig.radar.received == []
        assert_released(rig)
    assert "playback" in str(info.value).lower()


ASYNC = Faults(async_errors=((2, AsyncStatus.LVDS_BUFFER_FULL),))


def test_async_status_becomes_a_warning_and_a_count(small_capture, small_cfg, warnings_log):
    directory, frames = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg, faults=ASYNC) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            got = collect(src, 5)
        described = src.describe()
        assert rig.board.async_sent[0] == AsyncStatus.LVDS_BUFFER_FULL
    assert_frames_match(got, frames)
    assert described["async_status"].get("LVDS_BUFFER_FULL") == 1, described
    assert [m for m in warning_messages(warnings_log) if "LVDS buffer is full" in m]


def test_async_status_is_seen_while_frames_flow(small_capture, small_cfg, warnings_log):
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg, faults=ASYNC) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            collect(src, 10)  # the status was sent at frame 2, 0.35 s ago
            assert rig.board.async_sent, "the board sent no status"
            described = src.describe()
            warned = [m for m in warning_messages(warnings_log) if "LVDS buffer is full" in m]
    assert described["async_status"].get("LVDS_BUFFER_FULL") == 1, described
    assert warned


# ---------------------------------------------------------------------- cfg
def test_cfg_without_raw_lvds_streaming_is_refused_before_anything_is_sent(small_capture, small_cfg):
    directory, _ = small_capture
    cfg = config(NO_LVDS_CFG, "nolvds.cfg")
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        with pytest.raises(ConfigError) as info:
            open_source(rig.url(**URL_TIMEOUTS), cfg)
        assert rig.radar.received == []
        assert rig.board.commands == {}
        assert port_is_free(HOST_IP, rig.data_port)
    message = str(info.value)
    assert f"nolvds.cfg:{cfg_line(NO_LVDS_CFG, 'lvdsStreamCfg')}" in message, message
    assert "lvdsStreamCfg -1 0 1 0" in message, message
