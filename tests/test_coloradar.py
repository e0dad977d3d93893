"""The ColoRadar reader on synthetic runs written in the dataset's exact layout
(tests/coloradar_synth.py): every value read back exactly, both file numberings and both run
namings, ground truth interpolated to sensor times, the frame conversions to radarodom's TI
convention, and one clear error per fault."""

from __future__ import annotations

import math
import os
import re

import coloradar_synth as synth
import numpy as np
import pytest
from radarodom.driver.coloradar.run import (
    STREAMS,
    ColoRadarRun,
    HeatmapConfig,
    adc_to_cube,
    heatmap_to_polar,
    pointcloud_to_points,
)
from radarodom.errors import CaptureError, CaptureFormatError, UsageError
from radarodom.tum import yaw_quaternion
from scipy.spatial.transform import Rotation, Slerp


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    return ColoRadarRun(synth.write_run(tmp_path_factory.mktemp("coloradar")))


# ---------------------------------------------------------------------------------------------
# Everything read back


@pytest.mark.parametrize("base", [0, 1])
@pytest.mark.parametrize("name", ["ec_hallways_run0", "12_21_2020_ec_hallways_run0"])
def test_every_stream_reads_back_exactly(tmp_path, base, name):
    path = synth.write_run(tmp_path, name, numbering_base=base, frames=4)
    run = ColoRadarRun(path)
    assert run.name == name
    assert run.run_dir == str(path)
    assert run.calib_dir == str(tmp_path / "calib")
    for stream in STREAMS:
        assert run.has(stream)
    for stream in STREAMS[:5] + ("lidar",):
        assert run.count(stream) == 4
        np.testing.assert_array_equal(run.timestamps(stream), synth.default_times(stream, 4))
    for i in range(4):
        pc = run.pointcloud(i)
        assert pc.dtype == np.float32
        np.testing.assert_array_equal(pc, synth.default_pointcloud(i))
        np.testing.assert_array_equal(run.lidar_pointcloud(i), synth.default_lidar(i))
        for sensor in ("single_chip", "cascade"):
            hm = run.heatmap(sensor, i)
            assert hm.dtype == np.float32 and hm.shape == (*synth.HEATMAP_SHAPE[sensor], 2)
            np.testing.assert_array_equal(hm, synth.default_heatmap(sensor, i))
            cube = run.adc(sensor, i)
            assert cube.dtype == np.complex64
            np.testing.assert_array_equal(cube, synth.default_adc(sensor, i))

    for sensor in ("single_chip", "cascade"):
        cfg, want = run.heatmap_config(sensor), synth.default_heatmap_cfg(sensor)
        for key, value in want.items():
            np.testing.assert_array_equal(getattr(cfg, key), value)
        np.testing.assert_array_equal(cfg.range_m, np.arange(want["num_range_bins"]) * want["range_bin_width"])
        wf = run.waveform_config(sensor)
        for key, value in synth.default_waveform_cfg(sensor).items():
            assert getattr(wf, key) == value and type(getattr(wf, key)) is type(value), key
    for sensor, (t, yaw) in synth.TRANSFORMS.items():
        got_t, got_q = run.base_to_sensor(sensor)
        np.testing.assert_array_equal(got_t, t)
        np.testing.assert_allclose(got_q, yaw_quaternion(yaw), rtol=0, atol=1e-15)

    gt = run.groundtruth()
    t, p, q = synth.default_groundtruth(run.count("groundtruth"))
    np.testing.assert_array_equal(gt.times, t)
    np.testing.assert_array_equal(gt.positions, p)
    np.testing.assert_allclose(gt.quaternions, q, rtol=0, atol=1e-15)
    assert gt.times[0] < run.timestamps("single_chip/pointclouds")[0]
    assert len(gt) > 2 * run.count("cascade/heatmaps")  # ground truth faster than the radars
    n_imu = run.count("imu")
    np.testing.assert_array_equal(run.imu(), synth.default_imu(n_imu))


def test_files_sort_numerically_not_lexically(tmp_path):
    run = ColoRadarRun(synth.write_run(tmp_path, frames=12, numbering_base=1))
    assert run.count("single_chip/pointclouds") == 12
    for i in (1, 2, 9, 10, 11):  # lexical order would read radar_pointcloud_10.bin second
        np.testing.assert_array_equal(run.pointcloud(i), synth.default_pointcloud(i))


def test_timestamps_are_cached_and_read_only(default_run):
    t = default_run.timestamps("cascade/heatmaps")
    assert t is default_run.timestamps("cascade/heatmaps")
    with pytest.raises(ValueError):
        t[0] = 0.0


def test_calib_inside_the_run_given_or_absent(tmp_path):
    inside = synth.write_run(tmp_path / "a", calib="inside")
    assert ColoRadarRun(inside).calib_dir == str(inside / "calib")
    assert ColoRadarRun(inside).heatmap_config("cascade").num_azimuth_bins == 16

    bare = synth.write_run(tmp_path / "b", calib=None)
    run = ColoRadarRun(bare)
    assert run.calib_dir is None
    np.testing.assert_array_equal(run.pointcloud(0), synth.default_pointcloud(0))  # no calib needed
    with pytest.raises(UsageError, match="no calibration") as exc:
        run.heatmap("single_chip", 0)
    assert str(tmp_path / "b" / "calib") in str(exc.value)
    assert ColoRadarRun(bare, calib_dir=inside / "calib").waveform_config("cascade").num_tx == 3
    with pytest.raises(UsageError, match=re.escape(str(tmp_path / "nowhere"))):
        ColoRadarRun(bare, calib_dir=tmp_path / "nowhere")
    # The run given as its own calibration (--calib RUN): the calibration's file is missing, not the run's.
    with pytest.raises(CaptureFormatError) as exc:
        ColoRadarRun(bare, calib_dir=bare).heatmap_config("cascade")
    assert str(exc.value) == (f"{bare / 'cascade' / 'heatmap_cfg.txt'}: no such file: {bare}, the calibration "
                              "folder given, is not a whole ColoRadar calib folder (cascade/, single_chip/, "
                              "transforms/)")


def test_the_adc_file_layout_is_tx_rx_chirp_sample_iq(default_run):
    """Against the documented flat index 2 * (s + Ns * (c + Nc * (r + Nr * t))) of the raw file."""
    raw = np.fromfile(os.path.join(default_run.run_dir, "single_chip/adc_samples/data/frame_2.bin"), "<i2")
    cube = default_run.adc("single_chip", 2)
    _, nr, nc, ns = cube.shape
    for t, r, c, s in [(0, 0, 0, 1), (2, 1, 5, 7), (1, 3, 7, 15)]:
        k = 2 * (s + ns * (c + nc * (r + nr * t)))
        assert cube[t, r, c, s] == complex(raw[k], raw[k + 1])


def test_heatmap_cells_are_elevation_azimuth_range(default_run):
    raw = np.fromfile(os.path.join(default_run.run_dir, "cascade/heatmaps/data/heatmap_1.bin"), "<f4")
    hm = default_run.heatmap("cascade", 1)
    _, na, nr, _ = hm.shape
    el, az, rng = 3, 10, 17
    k = 2 * (rng + nr * (az + na * el))
    assert (hm[el, az, rng, 0], hm[el, az, rng, 1]) == (raw[k], raw[k + 1])


# ---------------------------------------------------------------------------------------------
# Ground truth at sensor times


def _yaw_of(q):
    return Rotation.from_quat(q).as_euler("ZYX")[..., 0]


def test_sensor_poses_interpolate_and_drop_times_outside(tmp_path):
    gt = (np.array([10.0, 11.0, 12.0]), np.array([[0.0, 0.0, 0.0], [2.0, 4.0, 6.0], [2.0, 4.0, 6.0]]),
          np.array([yaw_quaternion(a) for a in (0.0, math.pi / 2, math.pi / 2)]))
    identity = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    run = ColoRadarRun(synth.write_run(tmp_path, groundtruth=gt, transforms={"single_chip": identity}))
    times = np.array([9.5, 10.0, 10.5, 11.0, 11.25, 12.0, 12.5])
    traj, mask = run.sensor_poses("single_chip", times)
    np.testing.assert_array_equal(mask, [False, True, True, True, True, True, False])
    np.testing.assert_array_equal(traj.times, times[mask])
    np.testing.assert_allclose(traj.positions, [[0, 0, 0], [1, 2, 3], [2, 4, 6], [2, 4, 6], [2, 4, 6]], atol=1e-12)
    np.testing.assert_allclose(_yaw_of(traj.quaternions), [0, math.pi / 4, math.pi / 2, math.pi / 2, math.pi / 2],
                               atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(traj.quaternions, axis=1), 1.0, atol=1e-12)


def test_slerp_matches_scipy_on_a_general_rotation(tmp_path):
    rots = Rotation.from_euler("ZYX", [[10.0, 20.0, -30.0], [120.0, -40.0, 60.0]], degrees=True)
    q = rots.as_quat()
    q[1] *= -1.0  # the other sign of the same rotation: interpolation must take the short way
    gt = (np.array([0.0, 2.0]), np.zeros((2, 3)), q)
    run = ColoRadarRun(synth.write_run(tmp_path, groundtruth=gt,
                                       transforms={"cascade": ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))}))
    times = np.array([0.0, 0.3, 1.0, 1.7, 2.0])
    traj, _ = run.sensor_poses("cascade", times)
    want = Slerp([0.0, 2.0], rots)(times)
    got = Rotation.from_quat(traj.quaternions)
    np.testing.assert_allclose((got.inv() * want).magnitude(), 0.0, atol=1e-9)


def test_sensor_pose_composes_base_pose_with_base_to_sensor(default_run):
    """T_world_sensor = T_world_base * T_base_sensor: at the ground-truth times themselves."""
    gt = default_run.groundtruth()
    t_bs, q_bs = default_run.base_to_sensor("single_chip")
    traj, mask = default_run.sensor_poses("single_chip", gt.times)
    assert mask.all()
    r_wb = Rotation.from_quat(gt.quaternions)
    np.testing.assert_allclose(traj.positions, gt.positions + r_wb.apply(t_bs), atol=1e-12)
    want = r_wb * Rotation.from_quat(q_bs)
    np.testing.assert_allclose((Rotation.from_quat(traj.quaternions).inv() * want).magnitude(), 0.0, atol=1e-9)
    # A known case: base at yaw 0.5 t, sensor yawed 0.3 rad on it.
    np.testing.assert_allclose(_yaw_of(traj.quaternions), 0.5 * (gt.times - synth.T0) + 0.3, atol=1e-9)


def test_sensor_poses_of_the_radar_frames(default_run):
    times = default_run.timestamps("cascade/heatmaps")
    traj, mask = default_run.sensor_poses("cascade", times)
    assert mask.all() and len(traj) == len(times)
    assert "groundtruth_poses.txt" in traj.source


# ---------------------------------------------------------------------------------------------
# Conversions to radarodom's layout and frames


def test_adc_to_cube_puts_chirps_on_loops_and_tx_on_slots():
    adc = np.zeros((3, 4, 8, 16), np.complex64)
    adc[2, 1, 5, 7] = 3 + 4j
    cube = adc_to_cube(adc)
    assert cube.shape == (8, 3, 4, 16) and cube.dtype == np.complex64 and cube.flags.c_contiguous
    assert cube[5, 2, 1, 7] == 3 + 4j and np.count_nonzero(cube) == 1
    with pytest.raises(UsageError):
        adc_to_cube(np.zeros((3, 4, 8)))


def test_pointcloud_to_points_goes_to_the_ti_frame():
    pc = np.array([[2.0, 0.0, 0.0, 12.0, -0.5],   # straight ahead
                   [0.0, 3.0, 0.0, 7.0, 1.25],    # to the left
                   [0.0, -1.0, 0.0, 5.0, 0.0],    # to the right
                   [3.0, 0.0, 4.0, 9.0, 0.0]], np.float32)  # ahead and up
    pts = pointcloud_to_points(pc)
    np.testing.assert_allclose(pts["x"], [0.0, -3.0, 1.0, 0.0])
    np.testing.assert_allclose(pts["y"], [2.0, 0.0, 0.0, 3.0])
    np.testing.assert_allclose(pts["z"], [0.0, 0.0, 0.0, 4.0])
    np.testing.assert_allclose(pts["range"], [2.0, 3.0, 1.0, 5.0])
    np.testing.assert_allclose(pts["azimuth"], [0.0, -math.pi / 2, math.pi / 2, 0.0], atol=1e-7)
    np.testing.assert_allclose(pts["elevation"], [0.0, 0.0, 0.0, math.asin(0.8)], atol=1e-7)
    np.testing.assert_array_equal(pts["velocity"], pc[:, 4])
    np.testing.assert_array_equal(pts["snr_db"], pc[:, 3])
    np.testing.assert_array_equal(pts["noise_db"], 0.0)
    np.testing.assert_array_equal(pts["range_bin"], -1)
    np.testing.assert_array_equal(pts["doppler_bin"], -1)
    assert len(pointcloud_to_points(np.zeros((0, 5), np.float32))) == 0
    with pytest.raises(UsageError):
        pointcloud_to_points(np.zeros((3, 4)))


def _hot_heatmap(cfg: HeatmapConfig) -> np.ndarray:
    """A cold heatmap with one cell at positive (left) ColoRadar azimuth lit in two elevations."""
    hm = np.zeros(cfg.shape, np.float32)
    hm[..., 0] = 0.5
    hm[1, 6, 5] = (10.0, -1.5)  # the brightest elevation: its Doppler wins
    hm[2, 6, 5] = (4.0, 2.0)
    return hm


@pytest.mark.parametrize("reduce, value", [("max", 10.0), ("sum", 15.0)])
def test_heatmap_to_polar_flips_azimuth_to_ti(default_run, reduce, value):
    cfg = default_run.heatmap_config("single_chip")
    assert cfg.azimuth_bins[6] > 0  # to the left in ColoRadar's convention
    ra = heatmap_to_polar(_hot_heatmap(cfg), cfg, reduce=reduce)
    n_el, n_az, n_r, _ = cfg.shape
    assert ra.intensity.shape == ra.doppler_mps.shape == ra.static.shape == (n_r, n_az)
    assert ra.intensity.dtype == ra.doppler_mps.dtype == np.float32
    assert np.all(np.diff(ra.azimuth_rad) > 0)
    np.testing.assert_array_equal(ra.azimuth_rad, -cfg.azimuth_bins[::-1])
    np.testing.assert_array_equal(ra.range_m, cfg.range_m)
    r, j = np.unravel_index(np.argmax(ra.intensity), ra.intensity.shape)
    assert r == 5 and ra.azimuth_rad[j] == -cfg.azimuth_bins[6] < 0  # now to the right (negative TI)
    assert ra.intensity[r, j] == value and ra.doppler_mps[r, j] == -1.5
    assert ra.intensity[0, 0] == (0.5 if reduce == "max" else 0.5 * n_el)
    np.testing.assert_array_equal(ra.static, ra.intensity)


def test_heatmap_to_polar_rejects_bad_arguments(default_run):
    cfg = default_run.heatmap_config("single_chip")
    with pytest.raises(UsageError, match="reduce"):
        heatmap_to_polar(np.zeros(cfg.shape, np.float32), cfg, reduce="mean")
    with pytest.raises(UsageError, match="shaped"):
        heatmap_to_polar(np.zeros((4, 8, 15, 2), np.float32), cfg)


# ---------------------------------------------------------------------------------------------
# Faults: one clear error each, naming the file


def _call(run: ColoRadarRun, what: str):
    return {
        "heatmap1": lambda: run.heatmap("single_chip", 1),
        "adc1": lambda: run.adc("single_chip", 1),
        "count_heatmaps": lambda: run.count("single_chip/heatmaps"),
        "pointcloud0": lambda: run.pointcloud(0),
        "cascade_heatmap0": lambda: run.heatmap("cascade", 0),
        "cascade_cfg": lambda: run.heatmap_config("cascade"),
        "groundtruth": lambda: run.groundtruth(),
        "cascade_times": lambda: run.timestamps("cascade/heatmaps"),
        "single_chip_cfg": lambda: run.heatmap_config("single_chip"),
    }[what]()


@pytest.mark.parametrize("base", [0, 1])
@pytest.mark.parametrize("fault, call, error, names", [
    ("heatmap_size", "heatmap1", CaptureFormatError,
     ["single_chip/heatmaps/data/heatmap_{b1}.bin", "4088 bytes, expected 4096"]),
    ("adc_size", "adc1", CaptureFormatError, ["single_chip/adc_samples/data/frame_{b1}.bin", "6148 bytes, expected 6144"]),
    ("timestamp_count", "count_heatmaps", CaptureFormatError,
     ["single_chip/heatmaps/timestamps.txt has 5 timestamps", "4 files in", "single_chip/heatmaps/data"]),
    ("numbering_gap", "pointcloud0", CaptureFormatError,
     ["single_chip/pointclouds/data/radar_pointcloud_{b1}.bin: missing"]),
    ("missing_data_dir", "cascade_heatmap0", CaptureError, ["cascade/heatmaps/data: no such folder"]),
    ("missing_heatmap_cfg", "cascade_cfg", CaptureError, ["calib/cascade/heatmap_cfg.txt: no such file"]),
    ("missing_poses", "groundtruth", CaptureError, ["groundtruth/groundtruth_poses.txt: no such file"]),
    ("bad_timestamp", "cascade_times", CaptureFormatError, ["cascade/heatmaps/timestamps.txt:2:", "12x.5"]),
    ("bad_pose", "groundtruth", CaptureFormatError, ["groundtruth/groundtruth_poses.txt:3:", "x y z qx qy qz qw"]),
    ("bad_heatmap_cfg", "single_chip_cfg", CaptureFormatError,
     ["calib/single_chip/heatmap_cfg.txt:5: azimuth_bins holds 7 angles but num_azimuth_bins (line 3) is 8"]),
])
def test_each_fault_gives_one_clear_error(tmp_path, base, fault, call, error, names):
    run = ColoRadarRun(synth.write_run(tmp_path, numbering_base=base, faults=[fault]))
    with pytest.raises(error) as exc:
        _call(run, call)
    for name in names:
        assert name.format(b1=base + 1) in str(exc.value)


def test_a_good_frame_still_reads_beside_a_bad_one(tmp_path):
    run = ColoRadarRun(synth.write_run(tmp_path, faults=["heatmap_size"]))
    np.testing.assert_array_equal(run.heatmap("single_chip", 0), synth.default_heatmap("single_chip", 0))


def _rewrite_line(path, lineno: int, text: str) -> None:
    with open(path) as fh:
        lines = fh.read().splitlines()
    lines[lineno - 1] = text
    with open(path, "w", errors="surrogateescape") as fh:  # a line of undecodable bytes too
        fh.write("\n".join(lines) + "\n")


def test_a_timestamps_file_with_a_byte_order_mark_reads_and_a_directory_in_a_files_place_is_named(tmp_path):
    """A BOM (a Windows editor's) was 'expected one timestamp (s), got '\\ufeff1608...''; a directory
    in the ground truth's place was 'cannot read ...: Is a directory', exit 1."""
    run = ColoRadarRun(synth.write_run(tmp_path))
    times = tmp_path / "ec_hallways_run0" / "single_chip" / "pointclouds" / "timestamps.txt"
    before = run.timestamps("single_chip/pointclouds").copy()
    times.write_bytes(b"\xef\xbb\xbf" + times.read_bytes())
    np.testing.assert_array_equal(ColoRadarRun(tmp_path / "ec_hallways_run0").timestamps("single_chip/pointclouds"),
                                  before)
    transform = tmp_path / "calib" / "transforms" / "base_to_cascade.txt"
    transform.unlink()
    transform.mkdir()
    with pytest.raises(CaptureFormatError) as exc:
        ColoRadarRun(tmp_path / "ec_hallways_run0").base_to_sensor("cascade")
    assert str(exc.value) == f"{transform}: a directory, not a file (the run is damaged)"


@pytest.mark.parametrize("relative, lineno, text, method, expect", [
    ("calib/single_chip/heatmap_cfg.txt", 1, "num_range_bins sixteen", "cfg", ":1: expected num_range_bins"),
    ("calib/single_chip/heatmap_cfg.txt", 1, "num_range_bins 16.5", "cfg", ":1: num_range_bins must be a positive"),
    ("calib/single_chip/heatmap_cfg.txt", 4, "# range_bin_width gone", "cfg", "heatmap_cfg.txt: missing range_bin_width"),
    # Degrees where radians go, or an angle of -7 rad, were read as given:
    ("calib/single_chip/heatmap_cfg.txt", 5, "azimuth_bins -76 -44 -25 -8 8 25 44 76", "cfg",
     "heatmap_cfg.txt:5: azimuth_bins reach 76 rad, beyond +/- pi/2 (90 degrees): the angles are radians"),
    ("calib/single_chip/heatmap_cfg.txt", 6, "elevation_bins -7 -0.2 0.2 0.7", "cfg",
     "heatmap_cfg.txt:6: elevation_bins reach 7 rad, beyond +/- pi/2"),
    ("calib/single_chip/heatmap_cfg.txt", 5, "azimuth_bins -1 -0.7 -0.4 -0.1 -0.1 0.4 0.7 1", "cfg",
     "heatmap_cfg.txt:5: azimuth_bins are not ascending"),
    # A bin of 1e300 m went on into the registration's overflow warnings.
    ("calib/single_chip/heatmap_cfg.txt", 4, "range_bin_width 1e300", "cfg",
     "heatmap_cfg.txt:4: range_bin_width must be a positive number of metres, at most 10, got 1e+300"),
    ("calib/single_chip/waveform_cfg.txt", 5, "adc_sample_frequency nan", "waveform", ":5: not a finite number"),
    # 1e300 chirps made a frame whose expected size the data file's check wrote in 300 digits.
    ("calib/single_chip/waveform_cfg.txt", 4, "num_chirps_per_frame 1e300", "waveform",
     ":4: num_chirps_per_frame must be a positive integer of at most 1000000"),
    ("calib/transforms/base_to_cascade.txt", 2, "0 0 0", "transform", "base_to_cascade.txt:2: expected"),
    ("calib/transforms/base_to_cascade.txt", 2, "0 0 0 0", "transform", "base_to_cascade.txt:2: the quaternion is zero"),
    ("calib/transforms/base_to_cascade.txt", 1, "v^\x00\udcff\udcfeB", "transform",
     "base_to_cascade.txt:1: binary data, not text (the file is damaged, or another file is in its place)"),
    ("ec_hallways_run0/single_chip/pointclouds/timestamps.txt", 3, "1.0", "times", "timestamps.txt:3: time goes backwards"),
])
def test_malformed_text_lines_name_file_and_line(tmp_path, relative, lineno, text, method, expect):
    run = ColoRadarRun(synth.write_run(tmp_path))
    _rewrite_line(tmp_path / relative, lineno, text)
    call = {"cfg": lambda: run.heatmap_config("single_chip"), "waveform": lambda: run.waveform_config("single_chip"),
            "transform": lambda: run.base_to_sensor("cascade"),
            "times": lambda: run.timestamps("single_chip/pointclouds")}[method]
    with pytest.raises(CaptureFormatError) as exc:
        call()
    assert expect in str(exc.value)


def test_cfg_accepts_comments_and_key_separators(tmp_path):
    run = ColoRadarRun(synth.write_run(tmp_path))
    path = tmp_path / "calib/single_chip/heatmap_cfg.txt"
    text = path.read_text().replace("num_range_bins 16", "# comment\nnum_range_bins: 16\nsomething_new 3")
    path.write_text(text)
    assert run.heatmap_config("single_chip").num_range_bins == 16


def test_bad_arguments_and_missing_run(tmp_path, default_run):
    with pytest.raises(UsageError, match="no such run directory"):
        ColoRadarRun(tmp_path / "absent")
    with pytest.raises(UsageError, match="unknown ColoRadar stream"):
        default_run.timestamps("single_chip/imu")
    with pytest.raises(UsageError, match="unknown ColoRadar radar"):
        default_run.heatmap("lidar", 0)
    with pytest.raises(UsageError, match="out of range"):
        default_run.pointcloud(4)
    with pytest.raises(UsageError, match="out of range"):
        default_run.adc("cascade", -1)
    bare = tmp_path / "bare_run"
    bare.mkdir()
    assert not ColoRadarRun(bare).has("cascade/heatmaps")


def test_given_arrays_replace_the_defaults(tmp_path):
    """What an end-to-end test passes in: its own clouds (an empty one too), heatmaps of
    another shape (the cfg follows), times."""
    clouds = [np.zeros((0, 5), np.float32), synth.default_pointcloud(7)]
    maps = [np.full((2, 6, 10, 2), k, np.float32) for k in range(3)]
    times = {"cascade/heatmaps": synth.T0 + np.array([0.1, 0.3, 0.5])}
    run = ColoRadarRun(synth.write_run(tmp_path, frames=2, pointclouds=clouds, heatmaps={"cascade": maps},
                                       times=times))
    assert run.pointcloud(0).shape == (0, 5) and len(pointcloud_to_points(run.pointcloud(0))) == 0
    np.testing.assert_array_equal(run.pointcloud(1), synth.default_pointcloud(7))
    cfg = run.heatmap_config("cascade")
    assert cfg.shape == (2, 6, 10, 2)
    np.testing.assert_array_equal(run.timestamps("cascade/heatmaps"), times["cascade/heatmaps"])
    for k in range(3):
        np.testing.assert_array_equal(run.heatmap("cascade", k), maps[k])
    assert run.sensor_poses("cascade", run.timestamps("cascade/heatmaps"))[1].all()
