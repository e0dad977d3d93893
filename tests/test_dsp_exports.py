"""radar-capture's DSP exports (--points-out FILE.csv, --heatmap-out DIR) on the
simulator's calibration scene, run as a subprocess (the installed console script).

The calibration scene (driver/sim/scenes/calibration.toml) has five corner
reflectors at known positions in the body frame of the start pose (x forward,
y left, z up, the sensor 0.4 m high) and the sensor stands still for 2 s, so in
each of the first second's 10 frames every reflector is seen at
x_TI = -y_body, y_TI = x_body, z_TI = z - 0.4.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import REPO, console_command, private_zenoh

from radarodom.cfg import RadarConfig, shipped_config_path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

CAPTURE = console_command("radar-capture")
SOURCE = "sim://calibration?rate=max&duration=1"
HEADER = "frame,t,x,y,z,range,azimuth,elevation,velocity,snr_db"
N_FRAMES = 10  # 1 s at the shipped cfg's 10 frames/s
N_RANGE, N_AZ = 205, 64  # shipped cfg: range bins up to its cfarFovCfg 10 m (of 256), 64-point azimuth FFT
XY_TOL_M = 0.3
#: The shipped cfg's Doppler bin, m/s.
VELOCITY_BIN_MPS = RadarConfig.from_file(shipped_config_path()).velocity_resolution_mps


def run_capture(*args, timeout=120) -> subprocess.CompletedProcess:
    return subprocess.run(CAPTURE + private_zenoh(args), stdin=subprocess.DEVNULL, check=False,
                          capture_output=True, text=True, timeout=timeout)


def reflectors_ti() -> np.ndarray:
    """The calibration scene's corner reflectors in the TI frame of the start pose, (5, 3)."""
    spec = tomllib.loads((REPO / "driver" / "sim" / "scenes" / "calibration.toml").read_text())
    height = spec["trajectory"]["height"]
    assert spec["trajectory"]["start"] == [0.0, 0.0, 0.0]
    assert spec["trajectory"]["segments"][0] == {"pause": 2.0}
    body = np.array([o["position"] for o in spec["objects"] if o["type"] == "corner_reflector"])
    assert len(body) == 5
    return np.column_stack([-body[:, 1], body[:, 0], body[:, 2] - height])


def read_points(path) -> tuple[list[str], np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], dtype=float).reshape(-1, len(rows[0]))


def snapshot(directory) -> dict:
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())}


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """One run of radar-capture writing both exports: (process, csv path, heatmap dir)."""
    out = tmp_path_factory.mktemp("exports")
    csv_path, hm_dir = out / "points.csv", out / "heatmaps"
    proc = run_capture("--source", SOURCE, "--points-out", csv_path, "--heatmap-out", hm_dir)
    return proc, csv_path, hm_dir


def test_capture_with_exports_exits_zero(exported):
    proc, csv_path, hm_dir = exported
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert f"radar-capture: {N_FRAMES} frames" in proc.stdout
    assert csv_path.is_file() and hm_dir.is_dir()
    # The summary says where they are, as it does for a recording and a trajectory.
    assert f"; point clouds in {csv_path}, heatmaps in {hm_dir}" in proc.stdout.splitlines()[-1], proc.stdout


def test_points_csv_header_and_frames(exported):
    proc, csv_path, _ = exported
    assert proc.returncode == 0, proc.stderr
    assert csv_path.read_text().splitlines()[0] == HEADER
    header, rows = read_points(csv_path)
    assert header == HEADER.split(",")
    frames = rows[:, 0].astype(int)
    assert sorted(set(frames)) == list(range(N_FRAMES))
    assert np.all(np.diff(frames) >= 0)  # rows of a frame together, frames in order
    t = rows[:, 1]
    np.testing.assert_allclose(t, frames * 0.1, atol=1e-6)
    col = {name: rows[:, i] for i, name in enumerate(header)}
    # Columns agree with each other: range = |(x, y, z)|, azimuth = atan2(x, y), z = r sin(el).
    np.testing.assert_allclose(np.sqrt(col["x"] ** 2 + col["y"] ** 2 + col["z"] ** 2), col["range"],
                               rtol=1e-3, atol=1e-3)
    np.testing.assert_allclose(np.arctan2(col["x"], col["y"]), col["azimuth"], atol=1e-3)
    np.testing.assert_allclose(col["range"] * np.sin(col["elevation"]), col["z"], atol=1e-3)


def test_points_csv_finds_every_reflector_in_every_frame(exported):
    proc, csv_path, _ = exported
    assert proc.returncode == 0, proc.stderr
    header, rows = read_points(csv_path)
    col = {name: i for i, name in enumerate(header)}
    truth = reflectors_ti()
    for frame in range(N_FRAMES):
        pts = rows[rows[:, col["frame"]] == frame]
        xy = pts[:, [col["x"], col["y"]]]
        for ref in truth:
            d = np.hypot(*(xy - ref[:2]).T)
            i = int(np.argmin(d))
            assert d[i] <= XY_TOL_M, (frame, ref, pts[i])
            assert abs(pts[i, col["z"]] - ref[2]) <= XY_TOL_M, (frame, ref, pts[i])
            # The sensor stands still.  Velocities lie between Doppler bins (DspConfig.doppler_interpolation),
            # so noise moves a static point off exactly zero, by well under a tenth of a bin.
            assert abs(pts[i, col["velocity"]]) <= 0.1 * VELOCITY_BIN_MPS
            assert pts[i, col["snr_db"]] > 15.0
    # The first frame: exactly the five reflectors, nothing else.
    first = rows[rows[:, col["frame"]] == 0]
    assert len(first) == len(truth), first
    for p in first:
        assert np.min(np.hypot(*(truth[:, :2] - p[[col["x"], col["y"]]]).T)) <= XY_TOL_M
    # The raised reflector (z_TI = +0.6) comes out above the others.
    raised = first[np.argmin(np.hypot(*(first[:, [col["x"], col["y"]]] - truth[3, :2]).T))]
    assert raised[col["z"]] > 0.4 and raised[col["elevation"]] > 0


def test_heatmap_directory(exported):
    proc, _, hm_dir = exported
    assert proc.returncode == 0, proc.stderr
    index = json.loads((hm_dir / "index.json").read_text())
    assert len(index["range_m"]) == N_RANGE and index["range_m"][0] == 0.0
    az = np.array(index["azimuth_rad"])
    assert az.shape == (N_AZ,) and np.all(np.diff(az) > 0) and abs(az[N_AZ // 2]) < 1e-12
    assert [e["frame"] for e in index["frames"]] == list(range(N_FRAMES))
    np.testing.assert_allclose([e["t"] for e in index["frames"]], np.arange(N_FRAMES) * 0.1, atol=1e-9)
    expected = {f"{i:06d}_{name}.npy" for i in range(N_FRAMES) for name in ("intensity", "static", "doppler")}
    assert {p.name for p in hm_dir.iterdir()} == expected | {"index.json"}
    for i in range(N_FRAMES):
        maps = {name: np.load(hm_dir / f"{i:06d}_{name}.npy") for name in ("intensity", "static", "doppler")}
        for name, arr in maps.items():
            assert arr.shape == (N_RANGE, N_AZ) and arr.dtype == np.float32, name
            assert np.all(np.isfinite(arr)), name
        assert np.all(maps["static"] <= maps["intensity"] * (1 + 1e-5) + 1e-3)
        assert np.all(np.abs(maps["doppler"]) <= 2.3)


def test_heatmap_peaks_at_reflectors(exported):
    """First frame: the intensity at each reflector's (range, azimuth) cell (+/- 1 cell)
    stands far above the median, and there the dominant Doppler is zero."""
    proc, _, hm_dir = exported
    assert proc.returncode == 0, proc.stderr
    index = json.loads((hm_dir / "index.json").read_text())
    r_axis, az_axis = np.array(index["range_m"]), np.array(index["azimuth_rad"])
    intensity = np.load(hm_dir / "000000_intensity.npy")
    doppler = np.load(hm_dir / "000000_doppler.npy")
    floor = float(np.median(intensity))
    for ref in reflectors_ti():
        r = np.linalg.norm(ref)
        az = np.arctan2(ref[0], ref[1])
        ri, ai = int(np.argmin(np.abs(r_axis - r))), int(np.argmin(np.abs(az_axis - az)))
        cell = intensity[ri - 1:ri + 2, ai - 1:ai + 2]
        assert cell.max() > 1e4 * floor, ref
        rr, aa = np.unravel_index(int(np.argmax(cell)), cell.shape)
        assert doppler[ri - 1 + rr, ai - 1 + aa] == 0.0


def test_points_out_into_existing_file_fails_and_keeps_it(tmp_path):
    """An existing CSV is never overwritten: exit 1 (a CaptureError; --record into an
    existing capture exits 2), one error line, the file untouched."""
    path = tmp_path / "points.csv"
    path.write_text("precious data\n")
    proc = run_capture("--source", SOURCE, "--points-out", path)
    assert proc.returncode == 2, (proc.returncode, proc.stderr)  # like --record: never overwrite
    assert "Traceback" not in proc.stderr
    errors = [ln for ln in proc.stderr.splitlines() if ln.startswith("radar-capture: error:")]
    assert len(errors) == 1 and "exists" in errors[0], proc.stderr
    assert path.read_text() == "precious data\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["points.csv"]


def test_heatmap_out_into_existing_heatmap_dir_fails_and_keeps_it(tmp_path):
    hm_dir = tmp_path / "heatmaps"
    hm_dir.mkdir()
    (hm_dir / "index.json").write_text('{"format": "radarodom-heatmaps", "frames": []}')
    np.save(hm_dir / "000000_intensity.npy", np.ones((2, 2), np.float32))
    before = snapshot(hm_dir)
    proc = run_capture("--source", SOURCE, "--heatmap-out", hm_dir)
    assert proc.returncode == 2, (proc.returncode, proc.stderr)  # like --record: never overwrite
    assert "Traceback" not in proc.stderr
    errors = [ln for ln in proc.stderr.splitlines() if ln.startswith("radar-capture: error:")]
    assert len(errors) == 1 and "already holds heatmaps" in errors[0], proc.stderr
    assert snapshot(hm_dir) == before


def test_failed_heatmap_export_leaves_no_csv_behind(tmp_path):
    hm_dir = tmp_path / "heatmaps"
    hm_dir.mkdir()
    (hm_dir / "index.json").write_text('{"format": "radarodom-heatmaps", "frames": []}')
    csv_path = tmp_path / "points.csv"
    proc = run_capture("--source", "sim://calibration?rate=max&duration=0.2", "--points-out", csv_path,
                       "--heatmap-out", hm_dir)
    assert proc.returncode == 2, proc.stderr
    assert not csv_path.exists(), csv_path.read_text()


def test_the_heatmap_index_lists_all_but_the_last_second_of_frames_before_the_end(tmp_path):
    """What a run killed outright (SIGKILL) leaves: the index as last written.  It was written
    every 50 frames: killed after 4 s at 10 Hz, 28 frames' files and an index listing 1."""
    from radarodom.pipeline.sinks import HeatmapSink
    from radarodom.products import RangeAzimuth

    ticks = iter(np.arange(100) * 0.1)  # a frame every 0.1 s
    sink = HeatmapSink(tmp_path / "maps", clock=lambda: float(next(ticks)))
    cells = np.ones((4, 3), np.float32)
    for frame in range(35):
        sink.write_heatmap(frame, frame * 0.1, RangeAzimuth(cells, cells, cells, np.arange(4.0),
                                                            np.linspace(-0.5, 0.5, 3)))
    listed = [e["frame"] for e in json.loads((tmp_path / "maps" / "index.json").read_text())["frames"]]
    assert listed == list(range(len(listed))) and 35 - len(listed) <= 10  # a second at most unlisted
    assert all((tmp_path / "maps" / f"{frame:06d}_intensity.npy").exists() for frame in range(35))
    sink.close()
    assert len(json.loads((tmp_path / "maps" / "index.json").read_text())["frames"]) == 35


def test_a_slow_index_write_is_not_repeated_every_frame(tmp_path):
    """On a disk where writing the index takes 1.5 s, it was written again with every frame
    (its time was taken before the write); the wait now grows to ten times the write's."""
    from radarodom.pipeline.sinks import HeatmapSink
    from radarodom.products import RangeAzimuth

    ticks = iter(np.arange(1000) * 1.5)  # every look at the clock, 1.5 s later: frames and writes alike
    sink = HeatmapSink(tmp_path / "maps", clock=lambda: float(next(ticks)))
    cells = np.ones((4, 3), np.float32)
    index = tmp_path / "maps" / "index.json"
    writes, last = 0, None
    for frame in range(40):
        sink.write_heatmap(frame, frame * 0.1, RangeAzimuth(cells, cells, cells, np.arange(4.0),
                                                            np.linspace(-0.5, 0.5, 3)))
        inode = index.stat().st_ino, index.stat().st_mtime_ns  # each write replaces the file
        writes, last = writes + (inode != last), inode
    assert 1 < writes <= 5, writes  # about every 10 frames (15 s), not 40 times
    sink.close()
    assert len(json.loads(index.read_text())["frames"]) == 40
