"""Every source honours a board's calibration line: a recording of the simulated uncalibrated
board replayed with its line in the cfg drives like the perfect board (issue 16's "Done when"),
and the same board's frames as a ColoRadar run (``single_chip_adc``) put the reflectors where
they are only with the line."""

from __future__ import annotations

import math
import subprocess

import numpy as np
import pytest
from conftest import console_command, run_together
from coloradar_synth import write_run_from_capture
from test_calibration import _check_reflectors, calibrated

from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.sim.board import load_board
from radarodom.driver.sim.scene import load_scene
from radarodom.driver.sim.simulator import Simulator
from radarodom.driver.sources import open_source
from radarodom.dsp.calibrate import measure
from radarodom.dsp.processor import FrameProcessor
from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.evaluation import evaluate
from radarodom.estimator.odometry import RadarOdometry
from radarodom.pipeline import FrameProducts
from radarodom.tum import TumTrajectory

#: Seconds of the furnished room recorded: 120 frames, along a wall (9.7 s) and a turn in place
#: at the corner.
ROOM_SECONDS = 12


def _call(tool: str, *args) -> dict:
    return dict(args=console_command(tool) + [str(a) for a in args], stdin=subprocess.DEVNULL, capture_output=True,
                text=True, timeout=600)


def _run(tool: str, *args) -> None:
    proc = subprocess.run(**_call(tool, *args))
    assert proc.returncode == 0, proc.stderr


@pytest.fixture(scope="module")
def measured():
    """(the shipped cfg, the uncalibrated board's line as radar-calibrate measures it on the
    calibration scene's 3 m reflector, that cfg with the line)."""
    cfg = RadarConfig.from_file(shipped_config_path())
    sim = Simulator(cfg, load_scene("calibration"), board=load_board("uncalibrated"))
    line = measure(cfg, (sim.layout.decode(sim.frame(i).raw) for i in range(10)), 3.0).calibration
    return cfg, line, calibrated(cfg, line)


def _odometry(url: str, cfg: RadarConfig) -> dict:
    """Yaw-increment RMSE (deg) and body-velocity RMSE (m/s) of the default estimator on a
    source whose frames carry their ground-truth pose, *cfg* overriding its configuration."""
    times, poses, velocity, truth = [], [], [], []
    with open_source(url, cfg) as source:
        products = FrameProducts.for_estimator(source.config, EstimatorConfig().features)
        odometry = RadarOdometry(EstimatorConfig())
        for frame in source:
            p = products(frame)
            st = odometry.step(frame.timestamp, p.points, p.heatmap)
            times.append(frame.timestamp)
            poses.append((st.x, st.y, st.yaw))
            velocity.append((st.vx, st.vy))
            truth.append(frame.pose)
    times, truth = np.array(times), np.array(truth)
    ref = TumTrajectory(times, truth[:, :3], truth[:, 3:])
    res = evaluate(TumTrajectory.from_se2(times, np.array(poses)), ref)
    yaw = np.unwrap([2 * math.atan2(q[2], q[3]) for q in truth[:, 3:]])
    world_v = np.gradient(truth[:, :2], times, axis=0)
    body_v = np.stack([np.cos(yaw) * world_v[:, 0] + np.sin(yaw) * world_v[:, 1],
                       -np.sin(yaw) * world_v[:, 0] + np.cos(yaw) * world_v[:, 1]], axis=1)
    v_rmse = float(np.sqrt(np.mean(np.sum((np.array(velocity)[1:] - body_v[1:]) ** 2, axis=1))))
    return {"yaw_rmse_deg": res.yaw_rmse_deg, "velocity_rmse": v_rmse}


def test_a_recording_of_an_uncalibrated_board_with_its_line_drives_like_a_perfect_one(tmp_path, measured):
    """12 s of the furnished room recorded (radar-capture --record from sim://) on the
    uncalibrated board and on the perfect one; the first replayed (replay://) with its measured
    line in the cfg: velocity RMSE within 10 % of the perfect board's, yaw-increment RMSE within
    25 %; with the identity line far worse.  (The drift over whole sequences, 18 of them, is in
    docs/dsp.md's DSP experiment.)"""
    cfg, _, line_cfg = measured
    # The two recordings are independent: made at the same time.
    for proc in run_together(*(_call("radar-capture", "--no-publish", "-q", "--no-odom", "--record", tmp_path / board,
                                     "--source", f"sim://room?rate=max&fidelity=fast&duration={ROOM_SECONDS}&board={board}")
                               for board in ("ideal", "uncalibrated"))):
        assert proc.returncode == 0, proc.stderr
    perfect = _odometry(f"replay://{tmp_path / 'ideal'}?rate=max", cfg)
    with_line = _odometry(f"replay://{tmp_path / 'uncalibrated'}?rate=max", line_cfg)
    identity = _odometry(f"replay://{tmp_path / 'uncalibrated'}?rate=max", cfg)
    # The yaw within 25 %: the points' registration, blended into the heading (docs/heading.md item
    # 30), reads what the line leaves of the phases' errors more than the heatmaps' does, and the
    # map's density weights (item 38) lowered the perfect board's yaw error, not the line's.
    assert with_line["velocity_rmse"] <= 1.1 * perfect["velocity_rmse"], (with_line, perfect)
    assert with_line["yaw_rmse_deg"] <= 1.25 * perfect["yaw_rmse_deg"], (with_line, perfect)
    # Still clearly worse: 1.8 times the perfect board's with issue 16's defaults, 1.26 with the
    # heatmaps' registration of issue 20's, 1.7 with the points' blended in (their bearings read
    # the uncalibrated phases).
    assert identity["yaw_rmse_deg"] > 1.25 * perfect["yaw_rmse_deg"], (identity, perfect)
    assert identity["velocity_rmse"] > 1.3 * perfect["velocity_rmse"], (identity, perfect)


def test_coloradar_adc_of_an_uncalibrated_board_honours_its_line(tmp_path, measured):
    """The uncalibrated board's frames of the calibration scene (radar-sim --board uncalibrated)
    as a ColoRadar run: coloradar://...single_chip_adc with a cfg carrying the line finds every
    reflector within a range bin and 4 degrees, the 3 m one at 3.0 m and 0 degrees up; with
    the cfg the run's waveform implies (no line) the ranges are long by the bias and the
    elevations far off."""
    cfg, line, line_cfg = measured
    rec = tmp_path / "rec"
    _run("radar-sim", "calibration", "--board", "uncalibrated", "--duration", "0.3", "--out", rec, "-q")
    run = write_run_from_capture(tmp_path, rec)
    url = f"coloradar://{run}?velocity=single_chip_adc&heatmap=single_chip_adc&rate=max"
    scene = load_scene("calibration")
    for config in (line_cfg, None):
        with open_source(url, config) as source:
            proc = FrameProcessor(source.config, calibrated=source.calibrated)
            points = [proc.process(frame.cube()).points for frame in source]
        assert len(points) == 3
        ahead = points[0][np.argmin(np.hypot(points[0]["x"], points[0]["y"] - 3.0))]
        ok, worst = _check_reflectors(cfg, points[0], scene, 0.0)
        if config is line_cfg:
            assert ok, worst
            assert abs(ahead["range"] - 3.0) <= cfg.range_resolution_m / 2, ahead
            assert abs(math.degrees(ahead["elevation"])) <= 1.0, ahead
        else:
            assert not proc.array_calibrated and not ok and worst[2] > 8.0, worst
            assert ahead["range"] - 3.0 == pytest.approx(line.range_bias_m, abs=cfg.range_resolution_m / 2), ahead
            assert math.degrees(ahead["elevation"]) < -8.0, ahead
