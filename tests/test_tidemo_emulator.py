"""The fake AWR1843's demo data port (driver/emulators/fake_demo_uart.py, demo_frames.py): packets
made as the chip would from the simulator's scene, streamed on a pty on sensorStart, with line
faults whose ground truth the tidemo:// source's accounting is checked against."""

from __future__ import annotations

import subprocess
import time

import numpy as np
import pytest
import serial
from radarodom.cfg import RadarConfig
from radarodom.driver import open_source
from radarodom.driver.emulators.demo_frames import DemoFrameMaker
from radarodom.driver.emulators.fake_demo_uart import ASSERT_LINE, DemoUartRig, UartFaults
from radarodom.driver.live.awr1843 import Awr1843Cli
from radarodom.driver.tidemo import wire
from radarodom.driver.tidemo.layout import DemoGeometry
from radarodom.driver.tidemo.products import static_antennas
from radarodom.dsp.config import DspConfig
from radarodom.dsp.heatmap import HeatmapMaker
from radarodom.dsp.processor import FrameProcessor
from radarodom.dsp.static_heatmap import StaticHeatmapMaker

from tidemo_helpers import TIDEMO_CFG


@pytest.fixture(scope="module")
def cfg() -> RadarConfig:
    return RadarConfig.from_text(TIDEMO_CFG, "tidemo.cfg")


def test_packets_hold_the_chips_cfar_points_and_the_raw_paths_static_map(cfg):
    """The emulated chip's points are the DSP's in TI's mode (the cfg's 15 dB CFAR), placed on the
    FFTs' bins as the demo places them: each radial velocity a whole number of Doppler steps, each
    Wx = x / range a whole number of 2 / 64; its static map, through the tidemo heatmap, is the
    raw path's zero-Doppler heatmap of the same frame (up to int16 rounding)."""
    maker = DemoFrameMaker(cfg)
    ti = FrameProcessor(cfg, DspConfig(ti_like=True, doppler_interpolation=False, azimuth_interpolation=False))
    step = cfg.velocity_resolution_mps * cfg.num_loops / ti.n_doppler
    raw = FrameProcessor(cfg, DspConfig())
    heatmaps, static = HeatmapMaker(raw), StaticHeatmapMaker(raw)
    geometry = DemoGeometry.from_config(cfg)
    seen, moving = 0, False
    with open_source("sim://room?rate=max&duration=0.5", cfg) as source:
        for frame in source:
            data, n = maker.packet(frame.raw, frame.index + 1, frame.timestamp)
            packet = wire.parse_packet(data)
            assert not isinstance(packet, str) and packet.frame_number == frame.index + 1
            expected = ti.process(frame.cube()).points
            chip = packet.array(wire.Tlv.DETECTED_POINTS, wire.POINT_DTYPE)
            assert n == len(expected) and len(chip) == n
            for name in ("x", "y", "z", "velocity"):
                np.testing.assert_array_equal(chip[name], expected[name])
            np.testing.assert_allclose(chip["velocity"] / step, np.round(chip["velocity"] / step), atol=1e-4)
            wx = chip["x"] / np.sqrt(chip["x"] ** 2 + chip["y"] ** 2 + chip["z"] ** 2) * 32
            np.testing.assert_allclose(wx, np.round(wx), atol=1e-3)
            moving |= bool(np.any(chip["velocity"] != 0))
            side = packet.array(wire.Tlv.DETECTED_POINTS_SIDE_INFO, wire.SIDE_INFO_DTYPE)
            if n:
                np.testing.assert_array_equal(side["snr"], np.round(expected["snr_db"] * 10).astype(np.int16))
            mine = static.range_azimuth(static_antennas(packet, geometry)).static
            truth = heatmaps.range_azimuth(raw.process(frame.cube()).spectrum).static
            assert mine.shape == truth.shape
            np.testing.assert_allclose(mine / mine.max(), truth / truth.max(), atol=1e-3)
            seen += 1
    assert seen == 5 and maker.saturated == 0 and moving


def test_the_source_counts_what_the_line_did_to_the_emulators_packets(cfg):
    """Seeded noise, cut packets and lost bytes on the data port: every frame handed on is one the
    emulator sent whole, every damaged one is rejected and counted, and a whole packet is lost
    only when line noise follows it before the line is quiet."""
    faults = UartFaults(garbage=0.25, truncate=0.15, drop=0.15, seed=7)
    with DemoUartRig("sim://corridor", faults=faults, boot_time_s=0.05) as rig:
        with open_source(rig.url(), cfg) as source:
            numbers = []
            for frame in source:
                numbers.append(frame.index)
                if rig.data.stats.packets >= 24:
                    source.stop()
            about = source.describe()
        truth = rig.data.stats
    first = min(truth.whole + truth.truncated + truth.dropped)
    delivered = {n + first for n in numbers}
    damaged = set(truth.truncated) | set(truth.dropped)
    assert damaged and truth.garbage_before, "the seed must exercise every fault"
    assert delivered <= set(truth.whole)
    noisy_after = {n - 1 for n in truth.garbage_before}
    assert set(truth.whole) - delivered <= noisy_after
    assert about["rejected_packets"] >= len(damaged)
    assert about["frames"] == len(numbers) and about["packets"] == len(numbers)
    assert about["frames_skipped"] == max(numbers) + 1 - len(numbers)


def test_a_packet_the_uart_cannot_carry_stops_the_demo_with_its_exception(cfg):
    """A client that ignores the budget (here Awr1843Cli, not tidemo://) at 25 ms frames: the
    emulated demo asserts after its first packet, as the chip's frame start does, and says so on
    its CLI."""
    fast = RadarConfig.from_text(TIDEMO_CFG.replace("frameCfg 0 2 16 0 100 1 0", "frameCfg 0 2 16 0 25 1 0"), "fast")
    with DemoUartRig("sim://corridor", boot_time_s=0.05) as rig:
        data = serial.serial_for_url(rig.data_path, baudrate=921600, timeout=0.1)
        with Awr1843Cli(rig.cli_path) as radar:
            radar.configure(fast)
            radar.start()
        cli = serial.serial_for_url(rig.cli_path, baudrate=115200, timeout=0.1)  # what the CLI says next
        deadline = time.monotonic() + 30
        while not rig.data.stats.asserted and time.monotonic() < deadline:
            data.read(4096)
        heard = b""
        while ASSERT_LINE.encode() not in heard and time.monotonic() < deadline:
            heard += cli.read(256)
        cli.close()
        data.close()
    assert rig.data.stats.asserted and rig.data.stats.packets == 1
    assert ASSERT_LINE.encode() in heard


def _capture_through(emu, frames: int) -> None:
    """radar-capture, as the emulator printed it, takes *frames* whole frames from it.  The fake
    demo simulates its frames on this CPU: on a loaded machine it may pause longer than a board
    would, so the stream's stall limit is raised."""
    from live_helpers import Process

    capture = Process(emu.capture_argv("--frames", frames, "--no-publish", url_extra="data_timeout=60"))
    code = capture.wait(120)
    capture.kill()
    stdout, stderr = capture.output()
    assert code == 0, stderr
    assert f"{frames} frames (0 incomplete, 0 bytes missing)" in stdout


def test_radar_emulate_uart_prints_the_radar_capture_command_that_reaches_it(tmp_path):
    from conftest import REPO, console_command
    from live_helpers import Emulator, Process

    cfg_file = tmp_path / "tidemo.cfg"
    cfg_file.write_text(TIDEMO_CFG)
    with Emulator("--uart", "--source", "sim://corridor", "--cfg", cfg_file) as emu:
        assert emu.command[:2] == ["radar-capture", "--source"] and emu.command[2].startswith("tidemo:///dev/")
        assert emu.command[3:] == ["--cfg", str(cfg_file)]
        _capture_through(emu, 5)
        assert emu.stop() == 0
    assert "radar-emulate: sent" in emu.output()[0]
    # Without --cfg, radar-capture's tidemo:// sends its own shipped cfg, which the fake demo runs
    # (it had to be told to give one: the raw-capture cfg it used was refused).
    with Emulator("--uart", "--source", "sim://corridor") as emu:
        assert "--cfg" not in emu.command
        _capture_through(emu, 3)
    shipped = Process([*console_command("radar-emulate"), "--uart", "--source", "sim://corridor", "--cfg",
                       str(REPO / "configs" / "awr1843_raw.cfg")])
    assert shipped.wait(60) == 2
    assert "the UART cannot carry this cfg's frames" in shipped.output()[1]


@pytest.mark.parametrize("argv, words", [
    (["--source", "sim://corridor", "--uart-drop", "0.5"],
     "--uart-drop is a fault of the demo's UART data port: add --uart"),
    (["--capture", "FILE"], "--capture FILE: not a directory (give the capture directory that holds it)"),
    # (hunt 5: a folder that is no recording was "DIR/radar.cfg: cannot read the file")
    (["--capture", "EMPTY"], "error: EMPTY: holds no recording: neither a capture (adc_data.bin with capture.json) "
                             "nor a TI recording (*_Raw_<n>.bin)"),
    # The URL quoted is the one given, without the options the board adds to it (rate, fidelity).
    (["--source", "sim://lab?foo=1"], "error: sim://lab?foo=1: unknown option(s) foo; supported: "),
    # The demo's fake opens its source only when radar-capture starts the radar: checked at once.
    (["--uart", "--source", "sim://lab?foo=1"], "error: sim://lab?foo=1: unknown option(s) foo; supported: "),
    (["--source", "dca1000://127.0.0.2"], "error: dca1000://127.0.0.2: a live radar (dca1000://) cannot be "
                                          "emulated; give a recording (--capture DIR) or a sim://, replay:// or "
                                          "coloradar:// source"),
])
def test_radar_emulate_refuses_what_it_would_ignore(tmp_path, capsys, argv, words):
    from radarodom.tools import radar_emulate

    (tmp_path / "adc_data.bin").write_bytes(b"\0" * 16)
    (tmp_path / "empty").mkdir()
    given = {"FILE": str(tmp_path / "adc_data.bin"), "EMPTY": str(tmp_path / "empty")}
    assert radar_emulate.main([given.get(a, a) for a in argv]) == 2
    assert words.replace("FILE", given["FILE"]).replace("EMPTY", given["EMPTY"]) in capsys.readouterr().err


def test_radar_emulate_refuses_a_recording_of_the_demos_stream_at_start(tmp_path, cfg):
    """Such a recording has no ADC frames to stream: both boards started, printed their command,
    and failed only when radar-capture started the radar ('streaming failed', no reason)."""
    from conftest import console_command
    from live_helpers import Process
    from test_tidemo_replay import packets

    rec = tmp_path / "rec"
    rec.mkdir()
    (rec / "uart.bin").write_bytes(b"".join(packets(cfg, range(1, 6))))
    (rec / "radar.cfg").write_text(TIDEMO_CFG)
    for extra in ([], ["--uart"]):
        emulator = Process([*console_command("radar-emulate"), "--capture", str(rec), *extra])
        code = emulator.wait(60)  # (one that starts runs until stopped)
        emulator.kill()
        err = emulator.output()[1]
        assert code == 2, err
        assert f"replay://{rec}: its frames carry no raw ADC samples" in err and \
            f"play it with radar-capture --source replay://{rec}" in err, err


def test_radar_emulate_says_how_a_coloradar_run_gives_raw_frames(tmp_path):
    """It said a ColoRadar run was a recording of the demo's UART stream."""
    from coloradar_synth import write_run
    from conftest import console_command

    run = write_run(tmp_path)
    url = f"coloradar://{run}"
    proc = subprocess.run([*console_command("radar-emulate"), "--source", url], capture_output=True, text=True,
                          timeout=60, stdin=subprocess.DEVNULL)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip().splitlines() == [
        f"radar-emulate: error: {url}: its frames carry no raw ADC samples (a ColoRadar run plays its point "
        "clouds and heatmaps unless told otherwise), and an emulated board streams raw frames: add "
        "velocity=single_chip_adc&heatmap=single_chip_adc to the URL (the run's single-chip ADC frames), or "
        f"play it with radar-capture --source {url}"], proc.stderr


def test_radar_emulate_uart_hangs_on_start_when_told(tmp_path):
    """--hang-on-start was taken with --uart and ignored: the radar answered sensorStart."""
    from live_helpers import Emulator, Process

    cfg_file = tmp_path / "tidemo.cfg"
    cfg_file.write_text(TIDEMO_CFG)
    with Emulator("--uart", "--source", "sim://corridor", "--cfg", cfg_file, "--hang-on-start") as emu:
        capture = Process(emu.capture_argv("--frames", 5, "--no-publish", "--record", tmp_path / "rec",
                                           url_extra="start_timeout=0.5"))
        code = capture.wait(120)
        capture.kill()
        stdout, stderr = capture.output()
        assert code == 1 and "sensorStart got no answer within 0.5 s" in stderr, stderr
        # (hunt 5: no DCA1000 resets it, and the next run blamed the port or the firmware)
        assert ("it stays hung until reset: press the board's reset button (NRST) or unplug its USB and plug it "
                "in again, then run again") in stderr, stderr
        assert not (tmp_path / "rec").exists()
        assert emu.stop() == 0


def test_what_the_line_did_is_counted_up_to_where_the_consumer_left(cfg):
    """A consumer that leaves (a frame or duration limit) before the source closes: the reader
    keeps reading until then, and the figures counted what came after too (the summary's frame
    numbers skipped grew while the run shut down); they stay as they were when it left."""
    faults = UartFaults(garbage=0.25, truncate=0.15, drop=0.15, seed=7)
    with DemoUartRig("sim://corridor", faults=faults, boot_time_s=0.05) as rig:
        with open_source(rig.url(), cfg) as source:
            frames = iter(source)
            numbers = [next(frames).index for _ in range(6)]
            frames.close()  # the consumer leaves: the radar still sends
            left = source.describe()
            sent = rig.data.stats.packets
            deadline = time.monotonic() + 10
            while rig.data.stats.packets < sent + 4 and time.monotonic() < deadline:
                time.sleep(0.05)
            assert rig.data.stats.packets >= sent + 4, "the emulator sent nothing more: the test proves nothing"
            assert source.describe() == left
    assert left["frames"] == len(numbers)
