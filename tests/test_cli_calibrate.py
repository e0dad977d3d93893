"""radar-calibrate: the board's line measured from a corner reflector, on simulated boards whose
true line is known (Board.calibration), and every bad set-up refused with its reason.

The program runs on sim:// scenes written here, in-process (its main(), conftest's run_main) where
its answer is the subject, and as a user runs it (the console script, in a subprocess) end to end;
the library function is checked on more boards than the CLI.
"""

from __future__ import annotations

import json
import pathlib
import math
import re
import subprocess

import numpy as np
import pytest
from conftest import console_command, run_together

from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.sim.board import Board, load_board
from radarodom.driver.sim.scene import load_scene, scene_from_dict
from radarodom.driver.sim.simulator import Simulator
from radarodom.dsp.calibrate import measure
from radarodom.errors import CalibrationError, ConfigError, UsageError


def run_script(*args, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(console_command("radar-calibrate") + [str(a) for a in args], stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=timeout)


@pytest.fixture
def run(run_main):
    """radar-calibrate in this process (conftest's run_main)."""
    return lambda *args: run_main("radar-calibrate", *args)


def reflector(r: float, azimuth_deg: float = 0.0, *, z: float = 0.4, rcs_dbsm: float = 15.0) -> dict:
    """A corner reflector *r* m away at *azimuth_deg* (positive right, as TI's azimuth), *z* m
    high (the sensor is at 0.4 m)."""
    a = math.radians(azimuth_deg)
    return {"type": "corner_reflector", "position": [r * math.cos(a), -r * math.sin(a), z], "rcs_dbsm": rcs_dbsm}


def scene_file(tmp_path, objects, segments=({"pause": 3.0},)) -> str:
    path = tmp_path / "scene.json"
    path.write_text(json.dumps({"name": "bench", "objects": list(objects),
                                "trajectory": {"height": 0.4, "segments": list(segments)}}))
    return str(path)


def errors_against(measured, board: Board) -> tuple[float, float, float]:
    """(worst gain error dB, worst phase error deg, bias error m) of a measured line against
    the board's true one."""
    true = board.calibration()
    gain = float(np.abs(measured.gain_db - true.gain_db).max())
    phase = float(np.abs((measured.phase_deg - true.phase_deg + 180.0) % 360.0 - 180.0).max())
    return gain, phase, abs(measured.range_bias_m - true.range_bias_m)


def random_board(seed: int) -> Board:
    rng = np.random.default_rng(seed)
    return Board(name=f"random{seed}", range_bias_m=float(rng.uniform(-0.05, 0.12)),
                 tx_gain_db=tuple(rng.uniform(-1.5, 1.5, 3)), tx_phase_deg=tuple(rng.uniform(-40, 40, 3)),
                 rx_gain_db=tuple(rng.uniform(-1.5, 1.5, 4)), rx_phase_deg=tuple(rng.uniform(-40, 40, 4)),
                 leakage_counts=float(rng.uniform(0, 400)))


# ------------------------------------------------------------------ it recovers the line
@pytest.mark.parametrize("board", [load_board("uncalibrated"), random_board(1), random_board(2), Board()],
                         ids=lambda b: b.name)
def test_measure_recovers_the_boards_line(board):
    """Within 0.5 degrees, 0.05 dB and 2 mm of the line that corrects the simulated board (ten
    times what the measurement makes on these boards: docs/calibration.md, "Accuracy")."""
    cfg = RadarConfig.from_file(shipped_config_path())
    sim = Simulator(cfg, load_scene("calibration"), seed=3, board=board)
    result = measure(cfg, (sim.layout.decode(sim.frame(i).raw) for i in range(10)), 3.0)
    gain, phase, bias = errors_against(result.calibration, board)
    assert gain <= 0.05 and phase <= 0.5 and bias <= 0.002, (gain, phase, bias)
    assert result.snr_db > 40 and result.residual_phase_deg < 1.0 and result.frames == 10
    if board.is_ideal:  # a perfect board's line is the identity, to the noise
        np.testing.assert_allclose(result.calibration.coefficients, 1.0, atol=0.01)
        assert abs(result.calibration.range_bias_m) < 1e-3


def test_cli_prints_the_line_and_writes_the_cfg(tmp_path, run):
    board = load_board("uncalibrated")
    out_cfg = tmp_path / "board.cfg"
    proc = run("--source", "sim://calibration?board=uncalibrated&rate=max", "--distance", 3, "--write-cfg", out_cfg)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("reflector at 3.06") and "SNR" in lines[0] and "residual phase" in lines[0]
    assert any(line.strip().startswith("range bias +6.5") for line in lines)
    assert sum(line.strip().startswith(("TX1", "TX2", "TX3")) for line in lines) == 3
    assert lines[-1].startswith("compRangeBiasAndRxChanPhase 0.06")
    written = RadarConfig.from_file(out_cfg)
    gain, phase, bias = errors_against(written.channel_calibration, board)
    assert gain <= 0.5 and phase <= 5.0 and bias <= 0.01
    # The rest of the cfg is the source's (the shipped one), line for line.
    shipped = RadarConfig.from_file(shipped_config_path())
    assert [str(ln) for ln in written.lines if "compRange" not in str(ln)] == \
        [str(ln) for ln in shipped.lines if "compRange" not in str(ln)]
    # Never over an existing file.
    again = run("--source", "sim://calibration?board=uncalibrated&rate=max", "--distance", 3, "--write-cfg", out_cfg)
    assert again.returncode == 2 and "already exists" in again.stderr


def test_cli_json(tmp_path):
    # The console script itself, end to end (the other runs of radar-calibrate are in this process).
    proc = run_script("--source", "sim://calibration?board=uncalibrated&rate=max", "--distance", 3, "--frames", 5,
                      "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    for key in ("range_bias_m", "coefficients", "cfg_line", "snr_db", "residual_phase_deg"):
        assert key in data, key
    assert len(data["coefficients"]) == 12 and all(len(pair) == 2 for pair in data["coefficients"])
    assert data["range_bias_m"] == pytest.approx(0.065, abs=0.01) and data["frames"] == 5
    true = load_board("uncalibrated").calibration()
    measured = np.array([complex(*pair) for pair in data["coefficients"]]).reshape(3, 4)
    np.testing.assert_allclose(np.angle(measured * np.conj(true.coefficients)), 0.0, atol=math.radians(5))


def _points_csv(path) -> np.ndarray:
    """radar-capture --points-out's rows: columns frame,t,x,y,z,range,azimuth,elevation,velocity,snr_db."""
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def test_measure_then_use_the_line_on_a_recording(tmp_path, run):
    """The user's round trip on a recording of the uncalibrated board (radar-sim): measure the
    line, write the cfg, replay the recording with it: the boresight reflector at 3 m comes out
    at 3 m, azimuth and elevation 0, and the raised one (6.0 m ahead, 0.6 m up) at its elevation;
    replayed with its own identity line, the elevations are wrong."""
    rec = tmp_path / "rec"
    # (radar-sim's console script end to end; radar-capture's below, two at once)
    sim = subprocess.run(console_command("radar-sim") + ["calibration", "--board", "uncalibrated", "--duration", "1",
                                                        "--out", str(rec), "-q"],
                         capture_output=True, text=True, timeout=120)
    assert sim.returncode == 0, sim.stderr
    assert json.loads((rec / "capture.json").read_text())["source"].endswith("board=uncalibrated")
    board_cfg = tmp_path / "board.cfg"
    proc = run("--source", f"replay://{rec}?rate=max", "--distance", 3, "--write-cfg", board_cfg)
    assert proc.returncode == 0, proc.stderr
    rows = {}
    cfgs = {"with": board_cfg, "without": rec / "radar.cfg"}
    captures = run_together(*(dict(args=console_command("radar-capture") + [  # both replays at the same time
        "--source", f"replay://{rec}?rate=max", "--cfg", str(cfg), "--no-odom", "--no-publish", "-q",
        "--points-out", str(tmp_path / f"{name}.csv")], capture_output=True, text=True, timeout=120)
        for name, cfg in cfgs.items()))
    for name, capture in zip(cfgs, captures):
        assert capture.returncode == 0, capture.stderr
        rows[name] = _points_csv(tmp_path / f"{name}.csv")
    for name, expect_ok in (("with", True), ("without", False)):
        pts = rows[name]
        boresight = pts[np.abs(pts[:, 5] - 3.0) < 0.1]
        raised = pts[np.abs(pts[:, 5] - math.hypot(6.0, 0.5, 0.6)) < 0.1]
        assert len(boresight) and len(raised)
        ok = (np.all(np.abs(boresight[:, 5] - 3.0) <= 0.025) and np.all(np.abs(np.degrees(boresight[:, 6])) < 1.0)
              and np.all(np.abs(np.degrees(boresight[:, 7])) < 1.0)
              and np.all(np.abs(np.degrees(raised[:, 7]) - math.degrees(math.asin(0.6 / math.hypot(6.0, 0.5, 0.6)))) < 1.5))
        assert ok == expect_ok, (name, boresight[:, 5:8], raised[:, 5:8])


# ------------------------------------------------------------------ bad set-ups, refused
REFUSALS = {  # objects, the words of the refusal, more arguments
    "too weak": ([reflector(3.0, rcs_dbsm=-25.0)], "strong enough", ()),
    "not alone": ([reflector(3.0), reflector(3.14, -15.0)], "not alone", ("--search-window", 0.25)),
    "second reflector at its range": ([reflector(3.0), reflector(3.0, 25.0, rcs_dbsm=0.0)], "one point", ()),
    "off boresight": ([reflector(3.0, 14.0)], "right of boresight", ()),
    "nothing there": ([reflector(5.0)], "strong enough", ()),
}


@pytest.mark.parametrize("case", list(REFUSALS))
def test_bad_set_ups_are_refused(tmp_path, case, run):
    objects, words, more = REFUSALS[case]
    url = f"sim://{scene_file(tmp_path, objects)}?board=uncalibrated&rate=max"
    proc = run("--source", url, "--distance", 3, "--frames", 5, *more)
    assert proc.returncode == 1, proc.stdout
    assert proc.stderr.startswith("radar-calibrate: error: ") and words in proc.stderr
    assert len(proc.stderr.splitlines()) == 1 and "Traceback" not in proc.stderr
    assert proc.stdout == ""


def test_moving_reflector_is_refused(tmp_path, run):
    """The radar creeping toward the reflector at 0.3 m/s: refused, nothing written."""
    url = f"sim://{scene_file(tmp_path, [reflector(3.0)], [{'straight': 2.0, 'speed': 0.3}])}?rate=max"
    out_cfg = tmp_path / "never.cfg"
    proc = run("--source", url, "--distance", 2.9, "--frames", 5, "--write-cfg", out_cfg)
    assert proc.returncode == 1 and "moves" in proc.stderr and "still" in proc.stderr
    assert not out_cfg.exists()


def test_creeping_reflector_is_refused_by_its_range(tmp_path, run):
    """Creeping at 0.05 m/s, under one Doppler bin (0.07 m/s) so the Doppler check lets it by:
    its range moves by a bin over the second the frames span, and that refuses it."""
    url = f"sim://{scene_file(tmp_path, [reflector(3.0)], [{'straight': 1.5, 'speed': 0.05}])}?rate=max"
    proc = run("--source", url, "--distance", 2.97, "--frames", 10)
    assert proc.returncode == 1, proc.stdout
    assert "moves: its range changed by" in proc.stderr and "still" in proc.stderr


def test_a_moving_reflector_is_refused_by_its_doppler_counted_in_frames(tmp_path, run):
    # It said "2.26 m/s radial" (the Doppler axis's edge: once things move, a bin's strongest
    # return may be anything's) for a reflector approached at 0.5 m/s.
    url = f"sim://{scene_file(tmp_path, [reflector(3.0)], [{'straight': 1.5, 'speed': 0.5}])}?rate=max"
    proc = run("--source", url, "--distance", 2.9, "--frames", 10)
    assert proc.returncode == 1, proc.stdout
    assert re.search(r"moves: its range bin's strongest return is off zero Doppler in \d+ of 10 frames", proc.stderr), \
        proc.stderr


def test_a_board_with_large_errors_of_its_own_can_be_allowed(tmp_path, run):
    """A reflector 14 degrees off looks like what a board's own errors could make: refused by
    default; --max-azimuth lets it through (the user's word that it is on boresight)."""
    url = f"sim://{scene_file(tmp_path, [reflector(3.0, 14.0)])}?rate=max"
    refused = run("--source", url, "--distance", 3, "--frames", 3)
    assert refused.returncode == 1 and "--max-azimuth" in refused.stderr
    allowed = run("--source", url, "--distance", 3, "--frames", 3, "--max-azimuth", 20, "--json")
    assert allowed.returncode == 0, allowed.stderr
    assert json.loads(allowed.stdout)["apparent_azimuth_deg"] == pytest.approx(14.0, abs=1.0)
    # 90, the top of what the option says it takes, was refused by the calibrator as out of range.
    anything = run("--source", url, "--distance", 3, "--frames", 3, "--max-azimuth", 90, "--json")
    assert anything.returncode == 0, anything.stderr


def test_a_source_of_incomplete_frames_only_says_so(tmp_path, shipped_cfg, run):
    from radarodom.driver.recordings.capture_dir import CaptureWriter

    sim = Simulator(shipped_cfg, load_scene("calibration"), duration_s=0.3)
    with CaptureWriter(tmp_path / "rec", shipped_cfg, source="test") as writer:
        for i in range(sim.num_frames):
            writer.write(sim.frame(i).raw, sim.frame_time(i), 1456)
    proc = run("--source", f"replay://{tmp_path / 'rec'}?rate=max", "--distance", 3)
    assert proc.returncode == 1
    assert f"all {sim.num_frames} frame(s)" in proc.stderr and "incomplete" in proc.stderr


def test_a_datasets_coupling_is_taken_out_first(shipped_cfg):
    """A static TX-to-RX coupling 30 cm behind the reflector (as ColoRadar's boards have, with its
    calibration file): left in, it is a second return in the window and refuses the set-up; taken
    out (the source's coupling), the board's line comes out as on a clean board."""
    from test_coloradar_coupling import coupling_values

    from radarodom.calibration import RangeCoupling
    from radarodom.driver.coloradar.coupling import FIRST_BIN, periodic_blackman

    board = load_board("uncalibrated")
    sim = Simulator(shipped_cfg, load_scene("calibration"), board=board, seed=3)
    rng = np.random.default_rng(1)
    cycles = 3.3 / shipped_cfg.range_resolution_m / shipped_cfg.num_samples
    amp = rng.uniform(400, 800, (3, 4)) * np.exp(1j * rng.uniform(0, 2 * np.pi, (3, 4)))
    signal = amp[..., None] * np.exp(2j * np.pi * cycles * np.arange(shipped_cfg.num_samples))[None, None, :]
    cubes = [sim.layout.decode(sim.frame(i).raw) + signal[None] for i in range(5)]
    with pytest.raises(CalibrationError, match="not alone"):
        measure(shipped_cfg, cubes, 3.0, 0.4)
    coupling = RangeCoupling(coupling_values(signal, 128), FIRST_BIN, periodic_blackman(shipped_cfg.num_samples))
    gain, phase, bias = errors_against(measure(shipped_cfg, cubes, 3.0, 0.4, coupling=coupling).calibration, board)
    assert gain <= 0.05 and phase <= 0.5 and bias <= 0.002, (gain, phase, bias)


def test_cfg_without_every_path_is_refused(tmp_path, shipped_cfg, run):
    text = shipped_cfg.to_text().replace("channelCfg 15 7 0", "channelCfg 3 7 0")
    path = tmp_path / "two_rx.cfg"
    path.write_text(text)
    proc = run("--source", "sim://calibration?rate=max", "--cfg", path, "--distance", 3)
    assert proc.returncode == 2
    assert f"{path}:" in proc.stderr and "channelCfg" in proc.stderr and "all four RX" in proc.stderr
    with pytest.raises(ConfigError):
        measure(RadarConfig.from_file(path), [], 3.0)


def test_library_refusals_say_which_limit(run):
    cfg = RadarConfig.from_file(shipped_config_path())
    sim = Simulator(cfg, scene_from_dict({"objects": [reflector(3.0, -14.0)],
                                          "trajectory": {"segments": [{"pause": 1.0}]}}))
    with pytest.raises(CalibrationError, match=r"looks 1\d\.\d deg left of boresight"):
        measure(cfg, [sim.layout.decode(sim.frame(0).raw)], 3.0)
    with pytest.raises(CalibrationError, match="no frame"):
        measure(cfg, [], 3.0)
    with pytest.raises(UsageError, match="range bin"):  # arguments that cannot work: exit 2
        measure(cfg, [], 3.0, window_m=0.03)
    with pytest.raises(UsageError, match="outside the range"):
        measure(cfg, [], 12.4)
    # The cfg's cfarFovCfg (10 m) is capped at the usable range, 80 % of the IF band (9.99 m).
    with pytest.raises(UsageError, match=r"outside the range this cfg measures well \(0.3 m to 9.99 m\)"):
        measure(cfg, [], 11.0)  # within the FFT, beyond the usable range: the IF filter's roll-off
    # A reflector within the range whose window is not: the window is what to change.
    with pytest.raises(UsageError, match=r"at 9.9 m \+/- 0.2 m .* narrow the search window \(at most \+/- 0.09 m"):
        measure(cfg, [], 9.9)
    with pytest.raises(UsageError, match=r"spans -2.00 m to 8.00 m, .*narrow the search window"):
        measure(cfg, [], 3.0, window_m=5.0)
    proc = run("--source", "sim://calibration?rate=max", "--distance", 3, "--search-window", 0.01)
    assert proc.returncode == 2 and "widen it" in proc.stderr


def test_a_cube_the_dsp_cannot_take_is_refused_by_add_and_the_rest_measured():
    """NaN, inf or samples too large for the float32 power, in the words FrameProcessor.process
    uses (rawframe.unusable_samples), with no numpy warning.  Once taken without a word: the NaN
    and inf frames then made result() blame the set-up ('no reflector peak within 3 m +/- 0.2 m:
    the strongest return there is at the window's edge'), inf after numpy's RuntimeWarning.
    Only the library meets them: every source's cubes decode from 16-bit samples."""
    import warnings

    from radarodom.dsp.calibrate import ChannelCalibrator

    cfg = RadarConfig.from_file(shipped_config_path())
    sim = Simulator(cfg, load_scene("calibration"), seed=3, board=load_board("uncalibrated"))
    cubes = [sim.layout.decode(sim.frame(i).raw) for i in range(4)]
    expected = measure(cfg, cubes, 3.0).calibration.coefficients
    nan_words = ("the frame's ADC samples hold 1 NaN or infinite value(s) of 196608 (the first at loop 5, TX slot 1, "
                 "RX 2, sample 100); the DSP takes finite I + jQ samples, as a radar's bytes decode to (Frame.cube())")
    for value, words in ((np.nan, nan_words), (complex(0, np.inf), nan_words), (-np.inf, nan_words),
                         (1e30, "the frame's ADC samples reach 1e+30, too large for the DSP's float32 power (a "
                                "radar's 16-bit samples reach 32768); scale the cube down")):
        calibrator = ChannelCalibrator(cfg, 3.0)
        bad = cubes[1].copy()
        bad[5, 1, 2, 100] = value
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            calibrator.add(cubes[0])
            with pytest.raises(UsageError) as info:
                calibrator.add(bad)
            assert str(info.value) == f"ChannelCalibrator.add (frame 2 of the measurement): {words}"
            for cube in cubes[1:]:  # the refused frame is not taken: the others measure as alone
                calibrator.add(cube)
            result = calibrator.result()
        assert result.frames == 4
        np.testing.assert_allclose(result.calibration.coefficients, expected, atol=1e-6)
    # Nor a cube of another shape or no numbers (numpy's broadcasting or type errors before).
    calibrator = ChannelCalibrator(cfg, 3.0)
    with pytest.raises(ConfigError, match=r"^ChannelCalibrator.add \(frame 1 of the measurement\): cube shaped "
                       r"\(64, 3, 4, 255\), the cfg gives \(64, 3, 4, 256\)$"):
        calibrator.add(cubes[0][..., :255])
    with pytest.raises(UsageError, match=r"^ChannelCalibrator.add \(frame 1 of the measurement\): cube must be a "
                       r"complex array shaped \(64, 3, 4, 256\) \(Frame.cube\(\) gives one\), got list$"):
        calibrator.add([1, 2])
    assert calibrator.frames == 0


def test_no_source_and_no_radar_says_what_to_do(run):
    proc = run("--distance", 3)
    assert proc.returncode == 2 and "no radar found" in proc.stderr and "sim://calibration" in proc.stderr


def test_a_distance_far_from_what_the_reflector_reads_is_said(run):
    # 22 cm off was written as the board's range bias without a word (a few cm is a board's).
    proc = run("--source", "sim://calibration?board=uncalibrated&rate=max", "--distance", 3.22, "--frames", 5)
    assert proc.returncode == 0, proc.stderr
    assert "from the distance given (3.22 m): a board's range bias is a few centimetres" in proc.stderr
    proc = run("--source", "sim://calibration?board=uncalibrated&rate=max", "--distance", 3, "--frames", 5)
    assert proc.returncode == 0 and "range bias is a few centimetres" not in proc.stderr


def test_a_coloradar_run_without_its_adc_frames_asked_for_says_how_to_ask(tmp_path, run):
    from coloradar_synth import write_run

    run_dir = write_run(tmp_path)
    proc = run("--source", f"coloradar://{run_dir}", "--distance", 3)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == (f"radar-calibrate: error: coloradar://{run_dir} gives no raw ADC frames: the measurement "
                           "needs them; a ColoRadar run's single-chip ADC frames: "
                           "coloradar://RUN?velocity=single_chip_adc&heatmap=single_chip_adc\n")


def test_write_cfg_over_the_shipped_cfg_read_without_cfg_is_refused(run):
    """With no --cfg the run reads the shipped cfg: --write-cfg there with --overwrite replaced its
    channel line with the board's, in the install (exit 0)."""
    shipped = pathlib.Path(shipped_config_path())
    before = shipped.read_bytes()
    proc = run("--source", "sim://calibration?board=uncalibrated&rate=max", "--distance", 3, "--frames", 2,
               "--write-cfg", shipped, "--overwrite")
    assert shipped.read_bytes() == before
    assert proc.returncode == 2 and proc.stderr.strip().splitlines() == [
        f"radar-calibrate: error: --write-cfg {shipped} would write over the input --cfg (not given: the shipped "
        f"cfg) {shipped}: choose another path"], proc.stderr
