"""radar-calibrate on a board without a DCA1000 (tidemo://): the demo firmware measures the line
on the chip (measureRangeBiasAndRxChanPhase) and prints it on its CLI port a frame at a time; the
fake AWR1843 does so from the simulated uncalibrated board's frames as TI's DPC does, and the lines
are combined (dsp/demo_calibration.py) with the raw path's checks where a line can tell."""

from __future__ import annotations

import math
import subprocess

import numpy as np
import pytest
from conftest import console_command
from test_cli_calibrate import errors_against, random_board

from radarodom.calibration import ChannelCalibration
from radarodom.cfg import TIDEMO_CONFIG_NAME, RadarConfig, shipped_config_path
from radarodom.driver.emulators.fake_demo_uart import DemoUartRig
from radarodom.cfg_commands import MeasureRangeBiasAndRxChanPhase
from radarodom.driver.emulators.demo_frames import DemoFrameMaker
from radarodom.driver.sim.board import Board, load_board
from radarodom.driver.sim.scene import load_scene
from radarodom.driver.sim.simulator import Simulator
from radarodom.driver.sources import open_source
from radarodom.dsp.calibrate import measure
from radarodom.dsp.demo_calibration import combine_demo_measurements
from radarodom.errors import CalibrationError, ConfigError

SCENE = "sim://calibration?board=uncalibrated"


@pytest.fixture(scope="module")
def tidemo_cfg() -> RadarConfig:
    return RadarConfig.from_file(shipped_config_path(TIDEMO_CONFIG_NAME))


def calibrate(url: str, *args) -> subprocess.CompletedProcess:
    return subprocess.run(console_command("radar-calibrate") + ["--source", url, "--distance", "3"]
                          + [str(a) for a in args], stdin=subprocess.DEVNULL, capture_output=True, text=True,
                          timeout=120)


def reflector_points(url: str, cfg: RadarConfig, frames: int = 8) -> np.ndarray:
    """The chip's points within 0.3 m of 3 m and 10 degrees of boresight, over *frames* frames."""
    kept = []
    with open_source(url, cfg) as source:
        for n, frame in enumerate(source, start=1):
            p = frame.points
            kept.append(p[(np.abs(p["range"] - 3.0) < 0.3) & (np.abs(np.degrees(p["azimuth"])) < 10)])
            if n >= frames:
                break
    return np.concatenate(kept)


def test_the_chip_measures_the_board_and_its_line_puts_the_reflector_on_boresight(tmp_path, tidemo_cfg, caplog):
    """The line measured through tidemo:// is the simulated board's (within 1 degree, 0.1 dB and 1 cm;
    the range bias is TI's parabola through three bins), agrees with the raw path's measurement of
    the same board, and is written into the shipped tidemo cfg with the measurement turned off;
    streamed with it, the chip puts the boresight reflector at azimuth and elevation 0, where
    without it the elevation is far off."""
    board = load_board("uncalibrated")
    out = tmp_path / "board.cfg"
    with DemoUartRig(SCENE, boot_time_s=0.05) as rig:
        proc = calibrate(rig.url(), "--write-cfg", out)
        assert proc.returncode == 0, proc.stderr
        written = RadarConfig.from_file(out)
        before = reflector_points(rig.url(), tidemo_cfg)
        # Streamed with the identity line, the board is said to be uncalibrated; with its line, not.
        assert "compRangeBiasAndRxChanPhase is the identity: the board's TX and RX paths are uncalibrated" \
            in caplog.text
        caplog.clear()
        after = reflector_points(rig.url(), written)
        assert "uncalibrated" not in caplog.text
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("reflector at 3.0") and "measured by the demo firmware, 10 frames" in lines[0], lines
    assert lines[-1].startswith("compRangeBiasAndRxChanPhase 0.0")
    gain, phase, bias = errors_against(written.channel_calibration, board)
    assert gain <= 0.1 and phase <= 1.0 and bias <= 0.01, (gain, phase, bias)
    raw_cfg = RadarConfig.from_file(shipped_config_path())
    sim = Simulator(raw_cfg, load_scene("calibration"), seed=3, board=board)
    raw = measure(raw_cfg, (sim.layout.decode(sim.frame(i).raw) for i in range(10)), 3.0)
    assert written.channel_calibration.matches(raw.calibration, phase_deg=1.0, gain_db=0.1, bias_m=0.01)
    # The rest of the cfg is the shipped tidemo one; the measurement is off again, at its distance.
    assert str(written.line_of("measureRangeBiasAndRxChanPhase")) == "measureRangeBiasAndRxChanPhase 0 3 0.4"
    changed = ("compRange", "measureRange")
    assert [str(ln) for ln in written.lines if not str(ln).startswith(changed)] == \
        [str(ln) for ln in tidemo_cfg.lines if not str(ln).startswith(changed)]
    assert len(before) and len(after)
    assert np.degrees(np.abs(before["elevation"])).min() > 5.0, before[["azimuth", "elevation"]]
    assert np.degrees(np.abs(after["azimuth"])).max() <= 1.0, after["azimuth"]
    assert np.degrees(np.abs(after["elevation"])).max() <= 2.0, after["elevation"]


def test_json_says_the_demo_measured(tmp_path):
    with DemoUartRig(SCENE, boot_time_s=0.05, rate="max") as rig:
        proc = calibrate(rig.url(), "--frames", 5, "--json")
    assert proc.returncode == 0, proc.stderr
    import json

    data = json.loads(proc.stdout)
    assert data["measured_by"] == "demo firmware" and data["frames"] == 5 and data["snr_db"] is None
    assert data["range_bias_m"] == pytest.approx(0.065, abs=0.01) and data["residual_phase_deg"] < 2.0


def test_a_demo_that_does_not_measure_is_said_to(tmp_path):
    """A firmware that prints no measurement (one built without it): refused after ten frames with
    what to do, not a line made of nothing."""
    with DemoUartRig(SCENE, boot_time_s=0.05, rate="max") as rig:
        rig.data.on_measurement = None
        proc = calibrate(rig.url())
    assert proc.returncode != 0 and "Traceback" not in proc.stderr
    assert "the demo printed no compRangeBiasAndRxChanPhase line on its CLI port in 10 frames" in proc.stderr
    assert "--source dca1000://" in proc.stderr


def test_a_cfg_with_clutter_removal_is_measured_without_it_and_written_with_it(tmp_path, tidemo_cfg):
    """The DPC takes the static clutter out of the cube before it measures, so a still reflector
    measured as noise ("no still reflector"); the measurement now runs with it off."""
    on = tmp_path / "clutter.cfg"
    on.write_text(tidemo_cfg.to_text().replace("clutterRemoval -1 0", "clutterRemoval -1 1"))
    out = tmp_path / "board.cfg"
    with DemoUartRig(SCENE, boot_time_s=0.05, rate="max") as rig:
        proc = calibrate(rig.url(), "--cfg", on, "--write-cfg", out)
    assert proc.returncode == 0, proc.stderr
    written = RadarConfig.from_file(out)
    assert written.clutter_removal.enabled == 1
    gain, phase, bias = errors_against(written.channel_calibration, load_board("uncalibrated"))
    assert gain <= 0.1 and phase <= 1.0 and bias <= 0.01, (gain, phase, bias)
    # What the chip measures with it on: the reflector is gone from its cube.
    cfg = RadarConfig.from_file(on).replace(MeasureRangeBiasAndRxChanPhase(1, 3.0, 0.4))
    sim = Simulator(cfg, load_scene("calibration"), seed=3, board=load_board("uncalibrated"))
    maker = DemoFrameMaker(cfg)
    lines = []
    for i in range(10):
        maker.packet(sim.frame(i).raw, i + 1, 0.1 * i)
        lines.append(maker.measurement)
    with pytest.raises(CalibrationError):
        combine_demo_measurements(cfg, lines, 3.0)


def test_too_few_or_too_many_frames_are_refused_before_the_radar_starts():
    with DemoUartRig(SCENE, boot_time_s=0.05) as rig:
        for frames in (1, 4, 1001):
            proc = calibrate(rig.url(), "--frames", frames)
            assert proc.returncode == 2 and f"--frames {frames}: the demo's lines are combined 5 to 1000 at a time" \
                in proc.stderr, proc.stderr
        assert rig.data.stats.packets == 0


def test_a_cfg_without_every_path_is_refused_before_the_radar_starts(tmp_path, tidemo_cfg):
    two_tx = tmp_path / "two.cfg"
    two_tx.write_text(tidemo_cfg.to_text().replace("chirpCfg 2 2 0 0 0 0 0 2", "chirpCfg 2 2 0 0 0 0 0 1"))
    with DemoUartRig(SCENE, boot_time_s=0.05) as rig:
        proc = calibrate(rig.url(), "--cfg", two_tx)
        assert not rig.radar.started and rig.data.stats.packets == 0
    assert proc.returncode != 0 and "uses TX1, TX2 and TX3 once a loop" in proc.stderr, proc.stderr


@pytest.mark.parametrize("board", [load_board("uncalibrated"), random_board(1), random_board(2), Board()],
                         ids=lambda b: b.name)
def test_the_emulated_chips_lines_recover_the_boards_line(board, tidemo_cfg):
    """Ten lines as the fake demo measures them (one chirp each, TI's parabola for the range) give
    the board's line within 1 degree, 0.1 dB and 1 cm (measured: 0.4 degrees, 0.05 dB, 5 mm;
    docs/calibration.md)."""
    cfg = tidemo_cfg.replace(MeasureRangeBiasAndRxChanPhase(1, 3.0, 0.4))
    sim = Simulator(cfg, load_scene("calibration"), seed=3, board=board)
    maker = DemoFrameMaker(cfg)
    lines = []
    for i in range(10):
        maker.packet(sim.frame(i).raw, i + 1, 0.1 * i)
        lines.append(maker.measurement)
    result = combine_demo_measurements(cfg, lines, 3.0)
    gain, phase, bias = errors_against(result.calibration, board)
    assert gain <= 0.1 and phase <= 1.0 and bias <= 0.01, (gain, phase, bias)
    assert result.residual_phase_deg < 1.0 and result.frames == 10


def test_the_fake_demo_measures_a_window_past_its_range_as_the_chip_would(tidemo_cfg):
    """A cfg's window beyond the last range bin (radar-capture sends any cfg): the fake's frame
    maker raised and its data port stopped streaming; the chip prints a line of its window's edge."""
    cfg = tidemo_cfg.replace(MeasureRangeBiasAndRxChanPhase(1, 50.0, 0.4))
    sim = Simulator(cfg, load_scene("calibration"), seed=3)
    maker = DemoFrameMaker(cfg)
    maker.packet(sim.frame(0).raw, 1, 0.0)
    name, *values = maker.measurement.split()
    assert name == "compRangeBiasAndRxChanPhase" and len(values) == 25 and float(values[0]) < -30


# ------------------------------------------------------------------ combining the demo's lines
def _lines(n: int, *, phase_noise_deg: float = 0.0, bias_noise_m: float = 0.0, seed: int = 0,
           response: np.ndarray | None = None) -> list[str]:
    """Lines as the demo prints them for the uncalibrated board, each with its own noise and an
    arbitrary common phase (the chip does not turn TX1 RX1 real)."""
    board = load_board("uncalibrated")
    rng = np.random.default_rng(seed)
    base = board.response if response is None else response
    out = []
    for _ in range(n):
        noisy = base * np.exp(1j * np.radians(rng.normal(0, phase_noise_deg, base.shape) + rng.uniform(-180, 180)))
        mag2 = np.abs(noisy) ** 2
        c = np.conj(noisy) * math.sqrt(mag2.min()) / mag2
        bias = board.range_bias_m + rng.normal(0, bias_noise_m)
        out.append(f"compRangeBiasAndRxChanPhase {bias:.7f} " + " ".join(f"{v.real:.5f} {v.imag:.5f}"
                                                                        for v in c.ravel()))
    return out


def test_lines_combine_to_the_boards_line(tidemo_cfg):
    """Ten lines with 1 degree of noise on each path: each path's phase against TX1 RX1's within
    1.5 degrees (the mean leaves 0.45 degrees RMS of that difference)."""
    result = combine_demo_measurements(tidemo_cfg, _lines(10, phase_noise_deg=1.0, bias_noise_m=0.002), 3.0)
    gain, phase, bias = errors_against(result.calibration, load_board("uncalibrated"))
    assert gain <= 0.1 and phase <= 1.5 and bias <= 0.002, (gain, phase, bias)
    assert 0.7 < result.residual_phase_deg < 1.3 and result.frames == 10 and math.isnan(result.snr_db)
    assert result.measured_by == "demo firmware"


def test_garbled_lines_are_left_out_and_said(tidemo_cfg, caplog):
    lines = _lines(8)
    lines[2] = lines[2][:80]  # cut on the line
    lines[4] = lines[4].replace("compRangeBiasAndRxChanPhase", "compRangeBiasAndRxChanPhas")
    result = combine_demo_measurements(tidemo_cfg, lines, 3.0)
    assert result.frames == 6
    assert "2 of the demo's 8 measurement line(s) could not be read" in caplog.text
    # Too few whole lines to tell their noise: one chirp's line alone can be degrees off unseen.
    with pytest.raises(CalibrationError, match=r"^only 4 whole measurement line\(s\) from the demo \(2 unreadable\): at "
                                               r"least 5 are needed"):
        combine_demo_measurements(tidemo_cfg, lines[:6], 3.0)
    with pytest.raises(CalibrationError, match=r"^no measurement to combine: the demo printed no whole "
                                               r"compRangeBiasAndRxChanPhase line \(2 unreadable\)$"):
        combine_demo_measurements(tidemo_cfg, [lines[2], lines[4]], 3.0)


@pytest.mark.parametrize("case, lines, message", [
    ("noisy", dict(n=5, phase_noise_deg=8.0), r"the demo's 5 measurements of the reflector at 3\.\d\d m disagree by "
                                              r"\d+\.\d deg RMS, so their mean is uncertain by \d\.\d deg"),
    ("moving", dict(n=10, bias_noise_m=0.02), r"the reflector at 3\.\d\d m moves: its range changed by \d+\.\d cm over "
                                              r"the demo's 10 measurements"),
    ("nothing there", dict(n=10, bias_noise_m=0.2), r"^no still reflector within 3 m \+/- 0\.2 m: the demo's 10 "
                                                    r"measurements put the strongest return anywhere from \d\.\d\d m to "
                                                    r"\d\.\d\d m; nothing strong is there \(check --distance"),
])
def test_lines_that_disagree_are_refused(tidemo_cfg, case, lines, message):
    with pytest.raises(CalibrationError, match=message):
        combine_demo_measurements(tidemo_cfg, _lines(**lines), 3.0)


def test_a_reflector_off_boresight_is_refused_as_on_the_raw_path(tidemo_cfg):
    board = load_board("uncalibrated")
    cfg = tidemo_cfg
    # The azimuth row of a plane wave from 15 degrees right, on top of the board's own errors.
    h = np.zeros((3, 4))
    for slot, tx in enumerate(cfg.tx_order):
        for i, rx in enumerate(cfg.rx_indices):
            h[tx - 1, rx] = cfg.virtual_array.h[slot, i]
    turned = board.response * np.exp(1j * np.pi * math.sin(math.radians(15)) * h)
    with pytest.raises(CalibrationError, match=r"looks 1\d\.\d deg (right|left) of boresight"):
        combine_demo_measurements(cfg, _lines(5, response=turned), 3.0)


def test_a_line_that_is_no_measurement_is_a_config_error():
    from radarodom.dsp.demo_calibration import parse_measurement

    for text in ("Obj Det DPC Exception: objectdetection.c, line 428.", "", "  \r"):
        with pytest.raises(ConfigError, match="not a compRangeBiasAndRxChanPhase line"):
            parse_measurement(text)
    assert parse_measurement(_lines(1)[0]).matches(load_board("uncalibrated").calibration(), bias_m=1e-6)
    assert isinstance(parse_measurement(_lines(1)[0]), ChannelCalibration)
