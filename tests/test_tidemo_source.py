"""tidemo:// (driver/tidemo/source.py): the UART budget refused up front, the two ports found, the
radar configured over its CLI (the fake AWR1843 on a pty) and its data port's packets framed into
frames, with what the line did counted."""

from __future__ import annotations

import os
import threading
import time
import tty

import numpy as np
import pytest
from conftest import REPO
from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver import open_source
from radarodom.driver.emulators.fake_awr1843 import FakeAwr1843
from radarodom.driver.live.discovery import SerialPortInfo
from radarodom.driver.tidemo import wire
from radarodom.driver.tidemo.layout import DemoGeometry, demo_config, gui_selection
from radarodom.driver.tidemo.ports import demo_ports
from radarodom.errors import ConfigError, SourceError, UsageError

from tidemo_helpers import TIDEMO_CFG

SHIPPED = REPO / "configs" / "awr1843_raw.cfg"


def test_a_frame_rate_the_uart_cannot_carry_is_refused_before_any_port_is_opened():
    """The shipped cfg's 256 range bins x 8 antennas (8 KB a frame) do not leave a 921600-baud UART
    in the 73 ms between its chirps' end and the next frame: the error says so, with the fixes,
    and no port is looked for (these do not exist)."""
    with pytest.raises(ConfigError) as err:
        open_source("tidemo:///nonexistent-data?cli=/nonexistent-cli", RadarConfig.from_file(SHIPPED))
    msg = str(err.value)
    assert "the UART cannot carry this cfg's frames" in msg and "8200 static heatmap" in msg
    assert "ms at 921600 baud" in msg and "73.1 ms" in msg
    assert "frameCfg period of at least 130 ms" in msg and "numAdcSamples 128 or less" in msg
    assert err.value.command == "frameCfg" and "no cfg was given" not in msg
    # Given no cfg, the shipped tidemo cfg is used, which the default 921600 baud carries (the
    # raw-capture cfg was, and refused: every tidemo:// user had to make a cfg first) and a
    # slower rate does not: the error says so, and what to give.
    with pytest.raises(SourceError, match="no data port /nonexistent-data"):
        open_source("tidemo:///nonexistent-data?cli=/nonexistent-cli")
    with pytest.raises(ConfigError) as err:
        open_source("tidemo:///nonexistent-data?cli=/nonexistent-cli&baud=115200")
    said = str(err.value)
    tidemo_cfg = shipped_config_path("awr1843_tidemo.cfg")
    assert said.startswith(f"{tidemo_cfg}: frameCfg: the UART cannot carry") and said.endswith(
        "(no cfg was given, so the shipped awr1843_tidemo.cfg was used: give one the UART carries with --cfg; "
        "docs/tidemo.md says how to make it)"), said


def test_the_shipped_tidemo_cfg_is_the_raw_one_as_the_uart_needs_it():
    """configs/awr1843_tidemo.cfg: the raw-capture cfg's radar with 128 samples (its monitors'
    slices fitted to the shorter ADC window), the chip's CFAR at 10 dB, LVDS off; nothing else."""
    raw = RadarConfig.from_file(SHIPPED)
    demo = RadarConfig.from_file(shipped_config_path("awr1843_tidemo.cfg"))
    assert demo.profile.num_adc_samples == 128 and raw.profile.num_adc_samples == 256
    changed = {str(a) for a in demo.lines if a.kind == "command"} - {str(a) for a in raw.lines if a.kind == "command"}
    assert changed == {"profileCfg 0 77 100 6 40 0 0 96 1 128 8000 0 0 30", "cfarCfg -1 0 2 8 4 3 0 10 1",
                       "cfarCfg -1 1 0 8 4 4 1 10 1", "lvdsStreamCfg -1 0 0 0", "CQRxSatMonitor 0 3 4 49 0",
                       "CQSigImgMonitor 0 63 4"}
    assert demo.frame == raw.frame and demo.channel == raw.channel


def test_a_slower_uart_is_refused_and_a_faster_one_takes_configdataport():
    cfg = RadarConfig.from_text(TIDEMO_CFG, "t.cfg")
    with pytest.raises(ConfigError, match="at 115200 baud"):
        open_source("tidemo:///nonexistent?cli=/nonexistent&baud=115200", cfg)
    gui = gui_selection(cfg)
    sent = demo_config(cfg, gui, 1843200)
    assert str(sent.line_of("configDataPort")) == "configDataPort 1843200 0"
    assert str(sent.line_of("guiMonitor")) == "guiMonitor -1 1 0 0 1 0 0"
    with pytest.raises(ConfigError, match="baud=1843200 in the tidemo"):
        demo_config(sent, gui, 921600)


@pytest.mark.parametrize("baud", ["1199", "3125001", "92160000", "99999999999999999999999"])
def test_a_baud_rate_the_data_port_does_not_take_is_refused_in_the_url(baud):
    with pytest.raises(SourceError) as err:
        open_source(f"tidemo:///nonexistent?cli=/nonexistent&baud={baud}", RadarConfig.from_text(TIDEMO_CFG, "t.cfg"))
    assert f"option baud='{baud}': expected the data port's baud rate (from 1200 to 3125000)" in str(err.value)


def test_a_cfg_whose_data_port_rate_the_demo_does_not_take_is_refused_at_its_line():
    cfg = RadarConfig.from_text(TIDEMO_CFG.replace("sensorStart", "configDataPort 9216000 0\nsensorStart"), "t.cfg")
    with pytest.raises(ConfigError) as err:
        demo_config(cfg, gui_selection(cfg), 9216000)
    assert "configDataPort" in str(err.value) and str(err.value).startswith("t.cfg:")
    assert "sets the data port to 9216000 baud; the demo's data port takes 1200 to 3125000" in str(err.value)
    at_top = cfg.to_text().replace("9216000", "3125000")
    assert demo_config(RadarConfig.from_text(at_top, "t.cfg"), gui_selection(cfg), 3125000).line_of("configDataPort")


def test_guimonitor_is_set_to_what_the_estimator_needs():
    """Points with side info and the static heatmap are switched on; what else the cfg asks for
    (here the stats) is kept; a cfg without the line gets one."""
    cfg = RadarConfig.from_text(TIDEMO_CFG.replace("guiMonitor -1 1 0 0 1 0 0", "guiMonitor -1 2 0 0 0 0 1"), "t.cfg")
    assert str(demo_config(cfg, gui_selection(cfg)).line_of("guiMonitor")) == "guiMonitor -1 1 0 0 1 0 1"
    bare = RadarConfig.from_text(TIDEMO_CFG.replace("guiMonitor -1 1 0 0 1 0 0\n", ""), "t.cfg")
    sent = demo_config(bare, gui_selection(bare))
    assert [ln.text for ln in sent.commands()][-2:] == ["guiMonitor", "sensorStart"]


@pytest.mark.parametrize("option", ["max_points=-1", "policy=newest", "baud=fast", "buffers=1", "nonsense=1"])
def test_bad_url_options_are_one_error(option):
    with pytest.raises(SourceError, match=option.split("=")[0]):
        open_source(f"tidemo:///nonexistent?cli=/nonexistent&{option}", RadarConfig.from_text(TIDEMO_CFG, "t.cfg"))


def port(device, role, serial_number=None, links=()):
    return SerialPortInfo(device=device, role=role, interface=0 if role == "cli" else 3, serial_number=serial_number,
                          links=tuple(links))


def test_the_two_ports_of_one_board_are_found():
    boards = [port("/dev/ttyACM0", "cli", "A"), port("/dev/ttyACM1", "data", "A"),
              port("/dev/ttyACM2", "cli", "B"), port("/dev/ttyACM3", "data", "B")]
    assert demo_ports("/dev/ttyACM2", None, lambda: boards) == ("/dev/ttyACM2", "/dev/ttyACM3")
    assert demo_ports(None, "/dev/ttyACM1", lambda: boards) == ("/dev/ttyACM0", "/dev/ttyACM1")
    assert demo_ports(None, None, lambda: boards[:2]) == ("/dev/ttyACM0", "/dev/ttyACM1")
    with pytest.raises(SourceError, match="several radars"):
        demo_ports(None, None, lambda: boards)
    with pytest.raises(SourceError, match="no radar found"):
        demo_ports(None, None, lambda: [])
    assert demo_ports("/a", "/b", lambda: pytest.fail("no discovery when both are given")) == ("/a", "/b")


class CannedDataPort:
    """A data-port pty that writes the given byte chunks, one every *period* s, from sensorStart."""

    def __init__(self, chunks: list[bytes], period: float = 0.05) -> None:
        self.chunks, self.period = chunks, period
        master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.master = master
        self.path = os.ttyname(self.slave)
        self.started = threading.Event()
        self.sent = threading.Event()
        threading.Thread(target=self._write, daemon=True).start()

    def start(self, config) -> None:
        self.started.set()

    def _write(self) -> None:
        self.started.wait(30)
        for chunk in self.chunks:
            time.sleep(self.period)
            os.write(self.master, chunk)
        self.sent.set()

    def close(self) -> None:
        os.close(self.master)
        os.close(self.slave)


def encoded(cfg: RadarConfig, number: int, n_points: int) -> bytes:
    g = DemoGeometry.from_config(cfg)
    pts = np.zeros(n_points, wire.POINT_DTYPE)
    pts["y"] = np.arange(1, n_points + 1)
    heat = np.zeros((g.range_bins, len(g.heatmap_elements)), wire.HEATMAP_DTYPE)
    heat["real"][number % g.range_bins] = 1000
    return wire.encode_packet(g.layout(gui_selection(cfg)), number, pts, np.zeros(n_points, wire.SIDE_INFO_DTYPE), heat)


def test_the_source_configures_the_radar_and_frames_what_its_data_port_sends():
    """Over two ptys: the cfg is sent with guiMonitor set, the packets (after boot noise, one cut
    short, one lost) become frames indexed by frame number with their points and static values,
    and describe() says where every packet and byte went."""
    cfg = RadarConfig.from_text(TIDEMO_CFG, "t.cfg")
    p = [encoded(cfg, n, n % 3) for n in range(1, 7)]
    chunks = [b"\r\nstale boot text\r\n" + p[0], p[1], p[2][:-200], p[3], b"", p[5]]  # 3 cut short, 5 lost
    data = CannedDataPort(chunks, cfg.frame_period_s)
    radar = FakeAwr1843(on_sensor_start=data.start, boot_time_s=0.05, expects_lvds=False)
    try:
        cli = radar.open_pty()
        frames = []
        # max_points=1: the UART budget checked for one point a frame, which frame 2's two exceed.
        with open_source(f"tidemo://{data.path}?cli={cli}&max_points=1", cfg) as source:
            for frame in source:
                frames.append(frame)
                if frame.index == 5:
                    break
            about = source.describe()
            said = source.summary()
        # Closed, its ports released: iterating it again was pyserial's error on a closed port.
        with pytest.raises(UsageError, match=r"the source is closed; open a new one \(open_source\)"):
            next(iter(source))
        assert "guiMonitor -1 1 0 0 1 0 0" in radar.received and radar.received[-1] == "sensorStop"
        assert "lvdsStreamCfg" not in " ".join(radar.received)
        assert [f.index for f in frames] == [0, 1, 3, 5]
        assert [len(f.points) for f in frames] == [1, 2, 1, 0]
        assert frames[1].points["y"].tolist() == [1.0, 2.0] and frames[1].raw is None
        assert frames[3].static_antennas.shape == (64, 8) and frames[3].static_antennas[6, 0] == 1000
        assert frames[2].wire == p[3]
        # Times on the frame grid by frame number: the lost numbers keep their places (the grid
        # never stretches; the lower bound allows 150 ms of scheduling delay on the first frame).
        period = cfg.frame_period_s
        times = [f.timestamp for f in frames]
        assert times == sorted(times) and 3.5 * period <= times[3] - times[0] <= 5 * period + 1e-6
        assert about["frames"] == 4 and about["frames_skipped"] == 2 and about["rejected_cut_short"] == 1
        assert about["discarded_bytes"] == len(b"\r\nstale boot text\r\n") + len(p[2]) - 200
        assert about["over_budget"] == 1 and about["max_points"] == 1
        assert said.endswith("; 1 packets with more points than max_points=1, which the UART budget was checked "
                             "for (give a larger max_points)"), said
    finally:
        radar.close()
        data.close()


@pytest.mark.parametrize("url, words", [
    ("tidemo:///nonexistent/tty", "no data port /nonexistent/tty (radar-devices lists what is connected)"),
    ("tidemo:///dev/null?cli=/nonexistent/cli", "no CLI port /nonexistent/cli (radar-devices lists what is connected)"),
    # Two slashes for three: the path is read relative, and was pyserial's "No such file or directory".
    ("tidemo://dev/null?cli=/dev/null", "no data port dev/null (a device path takes a third slash: "
                                        "tidemo:///dev/null)"),
])
def test_a_port_path_that_is_not_there_is_named(url, words):
    # Once the cfg passes: the port named, not "cannot tell the radar's CLI port".
    from radarodom.errors import SourceError

    with pytest.raises(SourceError) as info:
        open_source(url, RadarConfig.from_text(TIDEMO_CFG, "t.cfg"))
    assert str(info.value) == f"{url}: {words}"


def test_one_port_given_as_both_cli_and_data_is_refused(tmp_path):
    # Swapped or doubled ports ended in "the radar did not answer 'sensorStop'" with no fix.
    dev = tmp_path / "ttyACM0"
    dev.write_text("")
    link = tmp_path / "radar"
    link.symlink_to(dev)
    with pytest.raises(SourceError, match="the CLI port and the data port are both .*USB interface 0"):
        open_source(f"tidemo://{dev}?cli={link}", RadarConfig.from_text(TIDEMO_CFG, "t.cfg"))


def test_swapped_ports_are_told_by_a_cli_port_that_never_says_anything():
    """The data port given as the CLI (ttyACM1 for ttyACM0): 'did not answer sensorStop' alone
    did not say where to look; a port that answered before and then went quiet does not get it."""
    from radarodom.driver.emulators.fake_demo_uart import DemoUartRig
    from radarodom.errors import DeviceTimeout

    cfg = RadarConfig.from_text(TIDEMO_CFG, "t.cfg")
    with DemoUartRig("sim://corridor", boot_time_s=0.05) as rig:
        swapped = f"tidemo://{rig.cli_path}?cli={rig.data_path}&cli_timeout=0.3"
        with pytest.raises(DeviceTimeout) as info:
            open_source(swapped, cfg)
    message = str(info.value)
    assert f"did not answer 'sensorStop' within 0.3 s on {rig.data_path}: nothing has come back on it since it " \
           "was opened; is it the radar's CLI port (the board's first, USB interface 0" in message, message


def test_a_cli_port_answering_bytes_that_are_no_text_is_told_as_the_wrong_port():
    """Hunt 5: a port that answers binary (a demo's data port streaming, another device) was quoted
    as some 200 replacement characters, without the hint a silent port gets."""
    import os
    import threading

    from radarodom.driver.live.awr1843 import Awr1843Cli
    from radarodom.errors import DeviceTimeout

    master, slave = os.openpty()
    done = threading.Event()

    def answer_binary() -> None:
        while not done.is_set():
            try:
                os.read(master, 4096)
                os.write(master, bytes(range(256)) * 2)
            except OSError:
                return

    threading.Thread(target=answer_binary, daemon=True).start()
    try:
        with Awr1843Cli(os.ttyname(slave), command_timeout_s=0.3) as cli:
            with pytest.raises(DeviceTimeout) as info:
                cli.send("sensorStop")
    finally:
        done.set()
        os.close(master)
        os.close(slave)
    message = str(info.value)
    assert " bytes that are no text: is it the radar's CLI port (the board's first, USB interface 0; radar-devices " \
           "lists them) rather than its data port, at the CLI's 115200 baud?)" in message, message
    assert "\ufffd" not in message and "it said" not in message, message


def test_a_command_the_cli_port_does_not_take_in_time_names_the_time_not_the_cable():
    """Hunt 5: cli_timeout=1e-9 was 'failed (Write timeout): was the USB cable unplugged or the board
    reset?'."""
    from radarodom.driver.emulators.fake_demo_uart import DemoUartRig
    from radarodom.errors import DeviceTimeout

    cfg = RadarConfig.from_text(TIDEMO_CFG, "t.cfg")
    with DemoUartRig("sim://corridor", boot_time_s=0.05) as rig:
        with pytest.raises(DeviceTimeout) as info:
            open_source(rig.url() + "&cli_timeout=1e-9", cfg)
    assert f"the radar's CLI port {rig.cli_path} did not take 'sensorStop' within 1e-09 s (cli_timeout=): is " \
           "another program holding the port, or the time too short?" in str(info.value), str(info.value)


def _broken_after_two_frames(break_it, error, **url_options) -> tuple[str, str]:
    """Stream the fake demo (its URL given *url_options*), call *break_it(rig)* after its second
    frame, and expect *error*: (the error's message, the rig's data port)."""
    from radarodom.driver.emulators.fake_demo_uart import DemoUartRig

    cfg = RadarConfig.from_text(TIDEMO_CFG, "t.cfg")
    frames = 0
    with DemoUartRig("sim://corridor", boot_time_s=0.05) as rig:
        with pytest.raises(error) as info:
            with open_source(rig.url(**url_options), cfg) as source:
                for frames, _ in enumerate(source, start=1):
                    if frames == 2:
                        break_it(rig)
    assert frames >= 2
    return str(info.value), rig.data_path


def test_a_data_port_that_goes_away_says_what_may_have_happened():
    """The board unplugged mid-run: pyserial's 'device reports readiness to read but returned no
    data' alone, where the CLI port's failure asks about the cable."""
    from radarodom.errors import DeviceError

    # The data port's other end gone, as with the cable pulled.
    message, data_path = _broken_after_two_frames(lambda rig: rig.data.close(), DeviceError)
    assert message.startswith(f"reading the radar's data port {data_path} failed (") and \
        message.endswith("): was the USB cable unplugged or the board reset?"), message


def test_a_demo_that_stops_streaming_is_reported_with_what_its_cli_said(caplog):
    """The demo's exception report on its CLI port (a packet that outlasted the frame period) was
    never read: the source only guessed at the cause when the data stopped."""
    from radarodom.driver.emulators.fake_demo_uart import ASSERT_LINE
    from radarodom.errors import DeviceTimeout

    def assert_and_stop(rig) -> None:
        rig.data.stop()
        time.sleep(0.3)  # the packet on the line finished: the exception comes after the last packet
        rig.radar.announce(ASSERT_LINE)

    message, _ = _broken_after_two_frames(assert_and_stop, DeviceTimeout)
    assert f"its CLI port said {ASSERT_LINE!r}: the demo stopped, as it does when a packet outlasts" in message, message
    assert caplog.text.count(f"the radar's CLI port says: {ASSERT_LINE}") == 1


def test_a_demo_that_goes_quiet_is_given_up_on_after_data_timeout():
    """The stream's stall limit is the URL's data_timeout where given (10 frame periods, at least
    2 s, otherwise): a host whose demo or emulator may pause longer can allow it; the error names
    the limit it applied."""
    from radarodom.errors import DeviceTimeout, SourceError

    message, data_path = _broken_after_two_frames(lambda rig: rig.data.stop(), DeviceTimeout, data_timeout=0.5)
    assert message.startswith(f"no packet from the demo on {data_path} for "), message
    assert "s (data_timeout=0.5, frame period 0.1 s): is the data port the radar's (USB interface 3)" in message
    with pytest.raises(SourceError, match=r"option data_timeout='0': expected seconds without a packet"):
        open_source("tidemo:///dev/null?cli=/dev/null&data_timeout=0", RadarConfig.from_text(TIDEMO_CFG, "t.cfg"))


def test_the_cli_lines_printed_unasked_are_whole_lines_however_they_arrive():
    """Awr1843Cli.unsolicited_lines, on a loopback port: a line cut across reads is kept until its
    end comes, line ends of either kind, and a prompt split across reads."""
    from radarodom.driver.live.awr1843 import Awr1843Cli

    cli = Awr1843Cli("loop://").open()
    port = cli._port
    steps = [(b"compRangeBiasAndRxChanPhase 0.01 0.5", []),
             (b" 0.2\n\r", ["compRangeBiasAndRxChanPhase 0.01 0.5 0.2"]),
             (b"line A\n\rline B", ["line A"]),
             (b"\n", ["line B"]),
             (b"xx mmwDemo:/", []),
             (b">yy\n", ["xx", "yy"]),
             (b"", [])]
    for data, lines in steps:
        port.write(data)
        assert cli.unsolicited_lines() == lines, data
    cli.close()

