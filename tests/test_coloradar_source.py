"""The ``coloradar://`` source: a ColoRadar run played through radar-capture and scored by
radar-eval against the run's own ground truth.

Two kinds of synthetic runs in the dataset's exact layout:

- a simulator recording of ours rewritten as ColoRadar single-chip ADC frames (waveform_cfg,
  antenna_cfg, ground truth).  Played with both streams from ADC, the run must give exactly the
  odometry the recording gives through ``replay://``: the waveform -> cfg mapping, the TX order
  from the antenna layout and the ADC layout conversion are all exact or the numbers differ.
  Recorded once in TI's TX order (chirp masks 1, 4, 2) and once in xwr's (1, 2, 4).
- a platform on a left arc with on-chip point clouds at 10 Hz and cascade-like heatmaps at
  5 Hz (coloradar_synth.write_moving_run): the paper's two-radar setup.
"""

from __future__ import annotations

import json
import math
import pathlib
import shutil
import subprocess

import numpy as np
import pytest
from conftest import CORRIDOR_URL, SMALL_CFG, console_command, make_capture, run_together
from coloradar_synth import TX_POSITIONS, write_moving_run, write_run, write_run_from_capture
from test_cli_capture import one_error_line

from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.coloradar.run import ColoRadarRun, WaveformConfig
from radarodom.driver.coloradar.waveform import (AntennaConfig, read_antenna_config, tx_order_from_antennas,
                                                 waveform_to_config)
from radarodom.driver.sources import open_source
from radarodom.errors import CaptureFormatError, ConfigError, SourceError
from radarodom.tum import read_tum

SIM_SECONDS = 3


def _capture_call(*args) -> dict:
    """_capture's subprocess.run arguments (for conftest.run_together)."""
    return dict(args=console_command("radar-capture") + ["--no-publish", "-q", *map(str, args)],
                stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=300)


def _capture(*args) -> subprocess.CompletedProcess:
    return subprocess.run(**_capture_call(*args))


def _eval_call(*args) -> dict:
    return dict(args=console_command("radar-eval") + [str(a) for a in args], stdin=subprocess.DEVNULL,
                capture_output=True, text=True, timeout=120)


def _eval(*args) -> subprocess.CompletedProcess:
    return subprocess.run(**_eval_call(*args))


def _xwr_order_cfg(path: pathlib.Path) -> pathlib.Path:
    """The shipped cfg with the chirps on TX1, TX2, TX3 (masks 1, 2, 4) instead of TI's 1, 4, 2."""
    text = pathlib.Path(shipped_config_path()).read_text()
    text = text.replace("chirpCfg 1 1 0 0 0 0 0 4", "chirpCfg 1 1 0 0 0 0 0 2")
    text = text.replace("chirpCfg 2 2 0 0 0 0 0 2", "chirpCfg 2 2 0 0 0 0 0 4")
    path.write_text(text)
    assert RadarConfig.from_file(path).tx_order == (1, 2, 3)
    return path


@pytest.fixture(scope="module", params=["ti_order", "xwr_order"])
def sim_pair(request, tmp_path_factory):
    """(recording, its odometry TUM, the same frames as a ColoRadar run)."""
    root = tmp_path_factory.mktemp(f"coloradar_{request.param}")
    rec, odom = root / "rec", root / "replay.tum"
    url = f"sim://corridor?rate=max&fidelity=fast&duration={SIM_SECONDS}"
    if request.param == "ti_order":
        # The shipped cfg's recording of this URL is conftest's session-wide corridor_run: a copy
        # of it (edited below).
        corridor_run = request.getfixturevalue("corridor_run")
        assert url == CORRIDOR_URL and corridor_run.proc.returncode == 0
        shutil.copytree(corridor_run.rec, rec)
    else:
        # What is compared is this recording with itself (replay:// and coloradar://), so the
        # simulator's fast fidelity (half the exact one's cost) makes as good a recording.
        proc = _capture("--source", url, "--cfg", _xwr_order_cfg(root / "xwr.cfg"), "--record", rec,
                        "--no-odom")
        assert proc.returncode == 0, proc.stderr
    # As a real board's recording: a ColoRadar run cannot know that the identity line fits its board
    # (one azimuth a cell, docs/calibration.md), so neither may the replay it is compared with.
    meta_path = rec / "capture.json"
    meta = json.loads(meta_path.read_text())
    assert meta.pop("simulator")["board"] == "ideal"
    meta_path.write_text(json.dumps(meta))
    proc = _capture("--source", f"replay://{rec}?rate=max", "--odom-out", odom)
    assert proc.returncode == 0, proc.stderr
    return rec, odom, write_run_from_capture(root, rec)


def test_adc_frames_give_exactly_the_recordings_odometry(sim_pair, tmp_path):
    rec, replay_odom, run = sim_pair
    odom = tmp_path / "coloradar.tum"
    url = f"coloradar://{run}?velocity=single_chip_adc&heatmap=single_chip_adc&rate=max"
    proc = _capture("--source", url, "--odom-out", odom)
    assert proc.returncode == 0, proc.stderr
    assert odom.read_text() == replay_odom.read_text()  # bit for bit
    assert len(odom.read_text().splitlines()) == 10 * SIM_SECONDS
    # The run's ground truth, through the source URL, is the recording's (both evaluated at once).
    a, b = run_together(*(_eval_call(odom, reference) for reference in (url, f"replay://{rec}")))
    assert a.returncode == 0 and b.returncode == 0, a.stderr + b.stderr
    assert a.stdout.splitlines()[1:] == b.stdout.splitlines()[1:]  # all but the header naming the files


def test_the_derived_cfg_matches_the_recordings(sim_pair):
    rec, _, run = sim_pair
    with open_source(f"coloradar://{run}?velocity=single_chip_adc&heatmap=single_chip_adc") as source:
        derived = source.config
        frames = iter(source)
        first = next(frames)
    original = RadarConfig.from_file(rec / "radar.cfg")
    assert derived.tx_order == original.tx_order
    assert derived.cube_shape == original.cube_shape
    for prop in ("range_resolution_m", "max_velocity_mps", "carrier_frequency_hz", "frame_period_s",
                 "chirp_repetition_s"):
        assert getattr(derived, prop) == pytest.approx(getattr(original, prop), rel=1e-9), prop
    assert first.role == "both" and first.pose is not None
    np.testing.assert_array_equal(first.raw, np.fromfile(rec / "adc_data.bin", np.uint8, count=first.raw.size))


def test_a_coloradar_adc_run_records_to_a_capture_directory(sim_pair, tmp_path):
    rec, replay_odom, run = sim_pair
    out = tmp_path / "from_coloradar"
    proc = _capture("--source", f"coloradar://{run}?velocity=single_chip_adc&heatmap=single_chip_adc&rate=max",
                    "--record", out, "--no-odom")
    assert proc.returncode == 0, proc.stderr
    assert (out / "adc_data.bin").read_bytes() == (rec / "adc_data.bin").read_bytes()
    gt, gt0 = read_tum(out / "groundtruth.tum"), read_tum(rec / "groundtruth.tum")
    np.testing.assert_allclose(gt.positions, gt0.positions, atol=1e-9)


@pytest.fixture(scope="module")
def moving_run(tmp_path_factory):
    return write_moving_run(tmp_path_factory.mktemp("coloradar_moving"))


@pytest.fixture(scope="module")
def moving_capture(moving_run, tmp_path_factory):
    """radar-capture's odometry of the paper setup (the same command for the tests that read it,
    made once): (the CompletedProcess, its --odom-out TUM)."""
    odom = tmp_path_factory.mktemp("coloradar_moving_capture") / "est.tum"
    return _capture("--source", f"coloradar://{moving_run}?rate=max", "--odom-out", odom), odom


def test_the_paper_setup_plays_velocity_and_heatmap_frames_in_time_order(moving_run):
    with open_source(f"coloradar://{moving_run}?rate=max") as source:
        assert source.config is None and not source.carries_raw
        frames = list(source)
    roles = [f.role for f in frames]
    assert roles.count("velocity") == 40 and roles.count("heatmap") == 20
    times = [f.timestamp for f in frames]
    assert times == sorted(times) and [f.index for f in frames] == list(range(60))
    for f in frames:
        assert f.raw is None
        assert (f.points is not None) == (f.role == "velocity")
        assert (f.heatmap is not None) == (f.role == "heatmap")
    with pytest.raises(SourceError, match="no raw ADC samples"):
        frames[0].cube()


def test_the_paper_setup_through_radar_capture_and_radar_eval(moving_run, moving_capture, tmp_path):
    proc, odom = moving_capture
    assert proc.returncode == 0, proc.stderr
    assert "60 frames" in proc.stdout
    est = read_tum(odom)
    assert len(est.times) == 20  # one pose per cascade heatmap
    ev = _eval(odom, f"coloradar://{moving_run}", "--json", tmp_path / "e.json")
    assert ev.returncode == 0, ev.stderr
    numbers = json.loads((tmp_path / "e.json").read_text())
    assert numbers["poses"]["matched"] == 20
    # 10 deg/s on a 2.9 m radius: the arc is followed (cascade-like beams, exact velocities).
    assert numbers["yaw_increment_error_deg"]["rmse"] < 0.3  # 0.10 when written, 0.05 now
    assert numbers["final_drift"]["percent_of_path"] < 1.0  # 0.22 (0.18 on a flat world, before its z)


def test_radar_capture_and_radar_coloradar_agree(moving_run, moving_capture, tmp_path):
    """Both run the default estimator on the same frames: the same trajectory."""
    (proc, odom), out = moving_capture, tmp_path / "tables"
    assert proc.returncode == 0, proc.stderr
    proc = subprocess.run(console_command("radar-coloradar") + [str(moving_run), "--out", str(out)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    a, b = read_tum(odom), read_tum(out / "radarodom_default.tum")
    np.testing.assert_allclose(a.times, b.times)
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-4)


def test_point_clouds_are_turned_into_the_heatmap_radars_frame(tmp_path):
    run = write_run(tmp_path, "aspen_run5", frames=6)  # mounts differ: single chip 0.30 rad, cascade -0.20
    with open_source(f"coloradar://{run}?rate=max&heatmap=single_chip") as source:
        assert source.sensor == "single_chip"
        direct = [f.points for f in source if f.role == "velocity"]
    with open_source(f"coloradar://{run}?rate=max") as source:
        turned = [f.points for f in source if f.role == "velocity"]
    offset = 0.30 - (-0.20)
    for p, q in zip(direct, turned):
        np.testing.assert_allclose(q["azimuth"], p["azimuth"] - offset, atol=1e-6)
        np.testing.assert_allclose(np.hypot(q["x"], q["y"]), np.hypot(p["x"], p["y"]), atol=1e-5)
        np.testing.assert_allclose(np.arctan2(q["x"], q["y"]), q["azimuth"], atol=1e-5)


@pytest.mark.parametrize("query, message", [
    ("velocity=single_chip_adc&heatmap=cascade", "velocity=single_chip_adc needs heatmap=single_chip"),
    ("heatmap=lidar", "option heatmap='lidar': expected cascade|single_chip|single_chip_adc"),
    ("speed=2", "unknown option(s) speed"),
    ("start=99s", "start=99s is past"),
    ("start=1_0", "option start='1_0'"),  # float() would read 10 s
    ("start=\u0663", "option start="),  # an Arabic-Indic three
])
def test_bad_urls_give_one_error_line(tmp_path, query, message):
    run = write_run(tmp_path, "ec_hallways_run0", frames=3)
    proc = _capture("--source", f"coloradar://{run}?{query}")
    assert proc.returncode == 2
    assert message in one_error_line(proc)


def test_a_missing_stream_is_named(tmp_path):
    run = write_run(tmp_path, "ec_hallways_run0", frames=3)
    (run / "cascade" / "heatmaps" / "timestamps.txt").unlink()
    proc = _capture("--source", f"coloradar://{run}")
    assert proc.returncode != 0
    assert "cascade/heatmaps" in one_error_line(proc)


def test_a_directory_in_place_of_a_streams_timestamps_is_named_so(tmp_path):
    """It was 'timestamps.txt is missing', with the directory right there."""
    run = write_run(tmp_path, "ec_hallways_run0", frames=3)
    times = run / "cascade" / "heatmaps" / "timestamps.txt"
    times.unlink()
    times.mkdir()
    with pytest.raises(SourceError) as err:
        open_source(f"coloradar://{run}")
    assert str(err.value).endswith(f"the run has no cascade/heatmaps ({times} is a directory, not a file)")


def test_the_datasets_folder_given_for_a_run_lists_its_runs(tmp_path):
    for name in ("ec_hallways_run0", "aspen_run1"):
        write_run(tmp_path, name, frames=3)
    proc = _capture("--source", f"coloradar://{tmp_path}")
    assert proc.returncode == 2
    assert one_error_line(proc) == (f"radar-capture: error: coloradar://{tmp_path}: {tmp_path}: not a run but a "
                                    "folder of runs (aspen_run1, ec_hallways_run0): give one run")


def test_record_and_cfg_are_refused_where_there_are_no_raw_frames(tmp_path):
    run = write_run(tmp_path, "ec_hallways_run0", frames=3)
    proc, with_cfg = run_together(  # the two refusals, made at the same time
        _capture_call("--source", f"coloradar://{run}?rate=max", "--record", tmp_path / "rec"),
        _capture_call("--source", f"coloradar://{run}?rate=max", "--cfg", shipped_config_path()))
    assert proc.returncode == 2 and "--record needs a raw source" in one_error_line(proc)
    assert not (tmp_path / "rec").exists()
    proc = with_cfg
    assert proc.returncode == 2 and "applies to ADC frames" in one_error_line(proc)


def test_without_antenna_cfg_tis_order_is_assumed(tmp_path, caplog):
    run = write_run(tmp_path, "ec_hallways_run0", frames=3, tx_positions={"single_chip": None})
    with open_source(f"coloradar://{run}?velocity=single_chip_adc&heatmap=single_chip_adc") as source:
        assert source.config.tx_order == (1, 3, 2)
    assert "assuming TI's TX order" in caplog.text


def test_radar_eval_refuses_a_source_without_ground_truth(tmp_path):
    est = tmp_path / "est.tum"
    est.write_text("0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0 1\n")
    make_capture(tmp_path / "real", RadarConfig.from_text(SMALL_CFG), 3)  # a real board's: no groundtruth.tum
    proc = _eval(est, f"replay://{tmp_path / 'real'}")
    assert proc.returncode != 0 and "knows no ground truth" in proc.stderr and "Traceback" not in proc.stderr


# --------------------------------------------------------------------------- waveform -> cfg


def _waveform(**changes) -> WaveformConfig:
    values = dict(num_rx=4, num_tx=3, num_adc_samples_per_chirp=128, num_chirps_per_frame=128,
                  adc_sample_frequency=4.0e6, start_frequency=77.0e9, idle_time=1.0e-5, adc_start_time=6.0e-6,
                  ramp_end_time=6.0e-5, frequency_slope=6.0e13)
    values.update(changes)
    return WaveformConfig(**values)


def test_the_waveform_maps_to_the_radar_physics():
    cfg = waveform_to_config(_waveform(), frame_period_s=0.1)
    c = 299792458.0
    assert cfg.cube_shape == (128, 3, 4, 128)
    assert cfg.sample_rate_hz == 4.0e6 and cfg.slope_hz_per_s == pytest.approx(6.0e13)
    assert cfg.range_resolution_m == pytest.approx(c / (2 * 6.0e13 * 128 / 4.0e6))
    assert cfg.chirp_time_s == pytest.approx(7.0e-5)
    assert cfg.frame_period_s == pytest.approx(0.1)
    assert cfg.tx_order == (1, 3, 2)


@pytest.mark.parametrize("change, message", [
    (dict(num_tx=12, num_rx=16), "not supported"),
    (dict(adc_sample_frequency=1.0e6), "ADC sampling ends"),
])
def test_a_waveform_that_is_no_awr1843_is_refused(change, message):
    with pytest.raises(CaptureFormatError, match=message):
        waveform_to_config(_waveform(**change), origin="calib/single_chip/waveform_cfg.txt")


RX = np.array([[0, 0], [1, 0], [2, 0], [3, 0]], float)


@pytest.mark.parametrize("tx, rx, order", [
    (TX_POSITIONS["single_chip"], RX, (1, 3, 2)),  # TI's chirp order
    (((0, 0), (2, 1), (4, 0)), RX, (1, 2, 3)),  # xwr's
    (((4, 0), (0, 0), (2, 1)), RX, (3, 1, 2)),
    (((3, 0), (-1, 0), (1, -1)), RX[::-1], (1, 3, 2)),  # RX counted the other way, rows downwards
    (((0, 0), (8, 0), (4, 2)), RX * 2, (1, 3, 2)),  # in quarter wavelengths
])
def test_the_tx_order_follows_the_antenna_positions(tx, rx, order):
    assert tx_order_from_antennas(AntennaConfig(np.asarray(rx, float), np.asarray(tx, float), 77.0)) == order


@pytest.mark.parametrize("tx", [((0, 0), (4, 0), (8, 0)), ((0, 0), (4, 0), (3, 1)), ((0, 0), (2, 0), (1, 1))])
def test_a_layout_that_is_no_awr1843_is_refused(tx):
    with pytest.raises(CaptureFormatError, match="not an AWR1843BOOST's"):
        tx_order_from_antennas(AntennaConfig(RX, np.asarray(tx, float), 77.0, "antenna_cfg.txt"))


def test_antenna_cfg_errors_name_file_and_line(tmp_path):
    path = tmp_path / "antenna_cfg.txt"
    path.write_text("# layout\nnum_rx 4\nnum_tx 3\nrx 0 0 0\nrx 1 1 0\nrx 2 2 0\nrx 3 3 0\ntx 0 0 0\ntx 1 4 0\ntx 1 2 1\n")
    with pytest.raises(CaptureFormatError, match=r"antenna_cfg.txt:10: tx 1 placed twice"):
        read_antenna_config(path)
    path.write_text("num_rx 4\nnum_tx 3\nrx 0 0 0\nrx 1 1 0\nrx 2 2 0\nrx 3 3 0\ntx 0 0 0\ntx 1 4 x\n")
    with pytest.raises(CaptureFormatError, match=r"antenna_cfg.txt:8"):
        read_antenna_config(path)
    path.write_text("num_rx 4\nnum_tx 3\nrx 0 0 0\nrx 1 1 0\nrx 2 2 0\nrx 3 3 0\ntx 0 0 0\ntx 2 2 1\nF_design 77\n")
    with pytest.raises(CaptureFormatError, match=r"num_tx is 3 but tx lines place \[0, 2\]"):
        read_antenna_config(path)


def test_the_run_reader_gives_the_mount_yaw(tmp_path):
    run = ColoRadarRun(write_run(tmp_path, "ec_hallways_run0", frames=2))
    assert run.mount_yaw("single_chip") == pytest.approx(0.30)
    assert run.mount_yaw("cascade") == pytest.approx(-0.20)
    assert math.isclose(run.mount_yaw("imu"), 0.0, abs_tol=1e-12)


def test_radar_coloradar_runs_the_tables_on_the_adc_frames(sim_pair, tmp_path):
    """The single-chip-only path (ADC -> radarodom's DSP -> points and heatmaps) in the paper's
    tables; its default trajectory is the one radar-capture makes from the recording."""
    rec, replay_odom, run = sim_pair
    out, js = tmp_path / "out", tmp_path / "numbers.json"
    proc = subprocess.run(console_command("radar-coloradar") + [str(run), "--heatmap", "single_chip_adc", "--velocity",
                                                                  "single_chip_adc", "--out", str(out), "--json", str(js)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    numbers = json.loads(js.read_text())
    assert numbers["heatmap"] == "single_chip_adc" and numbers["velocity"] == "single_chip_adc"
    assert set(numbers["results"]) >= {"CFAR", "Ray-max", "Top-k", "Sampling + mwICP", "radarodom default"}
    a, b = read_tum(out / "radarodom_default.tum"), read_tum(replay_odom)
    np.testing.assert_allclose(a.times, b.times)
    np.testing.assert_allclose(a.positions, b.positions, atol=1e-6)
    np.testing.assert_allclose(a.quaternions, b.quaternions, atol=1e-6)


def test_the_features_are_checked_against_the_heatmaps_the_source_gives(moving_run, sim_pair):
    """A run's own heatmaps (128 range cells here) are what the estimator's CFAR runs on, not what
    the DSP would make of a cfg: a window that fits them runs, one longer is refused when the
    pipeline is built, before any frame; the DSP's heatmaps count where the DSP makes them."""
    from radarodom.estimator.config import EstimatorConfig
    from radarodom.pipeline import Pipeline
    from radarodom.pipeline.products import check_features_fit

    base = EstimatorConfig().features.to_dict()
    def features(guard):
        return EstimatorConfig.from_dict({"features": {**base, "method": "cfar",
                                                       "cfar": {**base["cfar"], "guard": guard}}})
    with open_source(f"coloradar://{moving_run}?rate=max") as source:
        assert source.heatmap_range_bins == 128 and not source.heatmaps_from_raw
        check_features_fit(source, features(55).features)  # 2 * (55 + 8) + 1 = 127 cells
        with pytest.raises(ConfigError, match=r"^features.cfar: a window of guard 56 and train 8 spans 129 range "
                                              r"cells, more than the heatmap's 128"):
            Pipeline(source, estimator=features(56))
        stats = Pipeline(source, estimator=features(2), max_frames=12).run()
        assert stats.frames == 12
    _, _, adc_run = sim_pair
    with open_source(f"coloradar://{adc_run}?velocity=single_chip_adc&heatmap=single_chip_adc") as source:
        assert source.heatmap_range_bins is None and source.heatmaps_from_raw
        with pytest.raises(ConfigError, match="more than the heatmap's 205"):
            check_features_fit(source, features(100).features)


def test_a_waveform_that_makes_no_valid_cfg_names_the_field_not_a_made_up_line(tmp_path):
    """'waveform_cfg.txt (as a cfg):8: ...' named a line of the cfg made from the file."""
    import dataclasses

    wf = ColoRadarRun(write_run(tmp_path)).waveform_config("single_chip")
    with pytest.raises(CaptureFormatError) as info:
        waveform_to_config(dataclasses.replace(wf, frequency_slope=1e20))
    assert str(info.value) == ("waveform_cfg.txt: frequency_slope 1e+20 Hz/s (the cfg's profileCfg: "
                               "freqSlopeConst): the waveform does not make a valid AWR1843 configuration: "
                               "100000000.0 is outside 0.001..100 MHz/us")
    # A whole number of ksps out of range was 'expected an integer, got 1e+06' (the made-up cfg's
    # number written with an exponent).
    with pytest.raises(CaptureFormatError) as info:
        waveform_to_config(dataclasses.replace(wf, adc_sample_frequency=1e9))
    assert str(info.value).startswith("waveform_cfg.txt: adc_sample_frequency 1e+09 Hz (the cfg's profileCfg: "
                                      "digOutSampleRate): ") and "1000000 is outside 1000..12500 ksps" in str(info.value)


def test_a_huge_waveform_value_is_said_in_a_short_line(tmp_path):
    """A frequency_slope of 1e300 was written out in 301 digits in the refusal."""
    import dataclasses

    wf = ColoRadarRun(write_run(tmp_path)).waveform_config("single_chip")
    with pytest.raises(CaptureFormatError) as info:
        waveform_to_config(dataclasses.replace(wf, frequency_slope=1e300))
    assert "frequency_slope 1e+300 Hz/s" in str(info.value) and len(str(info.value)) < 250, info.value


def test_a_frame_period_too_short_names_the_timestamps_it_came_from(tmp_path):
    """The period is the ADC stream's median step: refused, it blamed waveform_cfg.txt."""
    run = write_run(tmp_path, frames=4)
    times = run / "single_chip" / "adc_samples" / "timestamps.txt"
    times.write_text("".join(f"{100 + 0.0005 * i:.6f}\n" for i in range(4)))
    with pytest.raises(CaptureFormatError) as info:
        open_source(f"coloradar://{run}?heatmap=single_chip_adc&velocity=single_chip_adc&rate=max")
    assert str(info.value).startswith(f"{times}: the frames' period, 0.5 ms (the median step of its times), makes "
                                      "no valid AWR1843 frame: frameCfg: framePeriodicity: 0.5 ms is shorter"), info.value


@pytest.mark.parametrize("heatmap", ["cascade", "single_chip"])
def test_features_beyond_the_runs_own_heatmaps_reach_are_refused_before_the_run(tmp_path, heatmap):
    """features.min_range_m beyond a ColoRadar run's own heatmaps (their axes from its calib) ran
    with no feature and no word, exit 0, as sim:// no longer did."""
    from radarodom.estimator.config import EstimatorConfig
    from radarodom.pipeline.products import check_features_fit

    run = write_run(tmp_path, "ec_hallways_run0", frames=3)
    with open_source(f"coloradar://{run}?heatmap={heatmap}&rate=max") as source:
        reach = source.heatmap_reach_m
        axes = ColoRadarRun(str(run)).heatmap_config(heatmap)
        assert reach == pytest.approx(axes.range_m[-1]) and reach > 0
        check_features_fit(source, EstimatorConfig().with_(features={"min_range_m": reach * 0.9}).features)
        with pytest.raises(ConfigError) as err:
            check_features_fit(source, EstimatorConfig().with_(features={"min_range_m": 100.0}).features)
    assert str(err.value).startswith(f"features.min_range_m: 100 m: the heatmaps reach {reach:.2f} m at most")
