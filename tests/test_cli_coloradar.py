"""radar-coloradar end to end on a synthetic run written in the exact ColoRadar layout:
single-chip point clouds at 10 Hz (velocity), cascade heatmaps at 5 Hz (yaw), lidar ground
truth at 20 Hz; the paper's multi-rate pipeline and its two tables."""

from __future__ import annotations

import json
import math
import subprocess

import numpy as np
import pytest
from conftest import console_command
from coloradar_synth import write_run

from radarodom.tum import read_tum, yaw_quaternion

SPEED = 0.5  # m/s forward
YAW_RATE = math.radians(10.0)  # rad/s
DURATION = 4.0
N_AZ, N_EL, N_RANGE, BIN_M = 64, 4, 128, 0.06


def _pose(t):
    """Base pose (x, y, yaw) at time t: a left arc, starting at the origin."""
    yaw = YAW_RATE * t
    radius = SPEED / YAW_RATE
    return radius * np.sin(yaw), radius * (1 - np.cos(yaw)), yaw


def _in_sensor(world: np.ndarray, t: float) -> np.ndarray:
    x, y, yaw = _pose(t)
    c, s = math.cos(yaw), math.sin(yaw)
    d = world - [x, y]
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])  # x forward, y left


def _world(rng) -> np.ndarray:
    pts = np.column_stack([rng.uniform(-2, 9, 60), rng.uniform(-6, 7, 60)])
    return pts[np.hypot(pts[:, 0] - 1.0, pts[:, 1]) > 1.5]


def _pointcloud(world, t, rng) -> np.ndarray:
    p = _in_sensor(world, t)
    r = np.hypot(p[:, 0], p[:, 1])
    keep = (p[:, 0] > 0.3) & (r < 8) & (np.abs(np.arctan2(p[:, 1], p[:, 0])) < math.radians(70))
    p, r = p[keep], r[keep]
    # The sensor moves at (SPEED, 0) in its own frame; a static point has v_r = -v . u.
    doppler = -SPEED * p[:, 0] / r + rng.normal(0, 0.01, len(r))
    return np.column_stack([p[:, 0], p[:, 1], np.zeros(len(r)), np.full(len(r), 20.0), doppler]).astype("<f4")


def _heatmap(world, t, azimuth_bins, rng) -> np.ndarray:
    p = _in_sensor(world, t)
    r, az = np.hypot(p[:, 0], p[:, 1]), np.arctan2(p[:, 1], p[:, 0])
    keep = (p[:, 0] > 0.3) & (r < N_RANGE * BIN_M - 0.3) & (np.abs(az) < math.radians(75))
    r, az = r[keep], az[keep]
    ranges = BIN_M * np.arange(N_RANGE)
    # A cascade-like beam: narrow in sin(azimuth), about a bin in range.
    beam_az = np.exp(-0.5 * ((np.sin(azimuth_bins)[None, :] - np.sin(az)[:, None]) / 0.015) ** 2)
    beam_r = np.exp(-0.5 * ((ranges[None, :] - r[:, None]) / BIN_M) ** 2)
    intensity = np.einsum("na,nr->ar", beam_az, beam_r) + rng.exponential(1e-3, (len(azimuth_bins), N_RANGE))
    hm = np.zeros((N_EL, len(azimuth_bins), N_RANGE, 2), "<f4")
    hm[N_EL // 2, :, :, 0] = intensity
    hm[N_EL // 2 - 1, :, :, 0] = 0.5 * intensity
    hm[..., 1] = -SPEED * np.cos(azimuth_bins)[None, :, None]  # what a static world shows
    return hm


@pytest.fixture(scope="module")
def synthetic_run(tmp_path_factory):
    rng = np.random.default_rng(8)
    world = _world(rng)
    azimuth_bins = np.arcsin(np.linspace(-0.97, 0.97, N_AZ))  # non-uniform in angle, ascending
    t_single = 0.05 + 0.1 * np.arange(int(DURATION * 10))
    t_cascade = 0.08 + 0.2 * np.arange(int(DURATION * 5))
    t_gt = 0.05 * np.arange(int(DURATION * 20) + 4)
    x, y, yaw = _pose(t_gt)
    gt = (t_gt, np.column_stack([x, y, np.zeros_like(x)]), yaw_quaternion(yaw))
    identity = (np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    root = tmp_path_factory.mktemp("coloradar")
    run = write_run(root, "ec_hallways_run0", numbering_base=1,
                    pointclouds=[_pointcloud(world, t, rng) for t in t_single],
                    heatmaps={"cascade": [_heatmap(world, t, azimuth_bins, rng) for t in t_cascade]},
                    heatmap_cfgs={"cascade": {"num_range_bins": N_RANGE, "num_elevation_bins": N_EL,
                                              "num_azimuth_bins": N_AZ, "range_bin_width": BIN_M,
                                              "azimuth_bins": azimuth_bins,
                                              "elevation_bins": np.linspace(-0.3, 0.3, N_EL)}},
                    times={"single_chip/pointclouds": t_single, "cascade/heatmaps": t_cascade},
                    groundtruth=gt, transforms={"single_chip": identity, "cascade": identity})
    return run


def test_the_paper_pipeline_runs_and_prints_both_tables(synthetic_run, tmp_path):
    out, js = tmp_path / "out", tmp_path / "numbers.json"
    proc = subprocess.run(console_command("radar-coloradar") + [str(synthetic_run), "--out", str(out),
                                                                  "--json", str(js)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    assert "yaw RMSE [deg] by preprocessing" in text and "relative pose error [m]" in text
    assert "| paper | 4.66 | 3.09 | 2.06 |" in text  # ec_hallways_run0's published numbers beside ours
    numbers = json.loads(js.read_text())
    results = numbers["results"]
    assert set(results) == {"CFAR", "Ray-max", "Top-k", "wICP", "Sampling + wICP", "Sampling + mwICP",
                            "radarodom default"}
    # 2 degrees a heatmap frame at 5 Hz, cascade-like beams: the method follows the arc.
    assert results["radarodom default"]["yaw_rmse_deg"] < 0.5, results
    assert results["Top-k"]["yaw_rmse_deg"] < 1.5, results
    assert results["radarodom default"]["rpe_m"] < 0.02
    # The trajectories and the ground truth for radar-eval.
    gt = read_tum(out / "groundtruth.tum")
    est = read_tum(out / "radarodom_default.tum")
    assert len(gt.times) == len(est.times) >= 15
    np.testing.assert_allclose(gt.times, est.times)
    ev = subprocess.run(console_command("radar-eval") + [str(out / "radarodom_default.tum"), str(out / "groundtruth.tum")],
                        capture_output=True, text=True, timeout=120)
    assert ev.returncode == 0, ev.stderr


def test_a_run_without_point_clouds_is_refused(tmp_path):
    run = write_run(tmp_path, "aspen_run5", faults=())
    (run / "single_chip" / "pointclouds" / "timestamps.txt").unlink()
    proc = subprocess.run(console_command("radar-coloradar") + [str(run)], capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0
    assert "Traceback" not in proc.stderr and "pointclouds" in proc.stderr
