"""A small synthetic ColoRadar run written in the dataset's exact on-disk layout
(``../shared/reference/coloradar.md``), for the reader's tests and end-to-end runs.

:func:`write_run` writes every stream (a few frames each, tiny sizes) and the calibration
folder; the default content comes from the ``default_*`` functions below, so a test can
rebuild exactly what was written.  Numbers in text files are written with ``repr`` so they read
back bit for bit.  *faults* names damage to do, one clear error each (:data:`FAULTS`).
"""

from __future__ import annotations

import math
import pathlib
import shutil
from collections.abc import Mapping, Sequence

import numpy as np
from radarodom.tum import yaw_quaternion

#: Start of the recording (a Unix time like the real data's), s.
T0 = 1608589800.0
#: Rate of each stream, Hz: ground truth faster than the radars, as in the dataset.
RATE_HZ = {"single_chip/pointclouds": 10.0, "single_chip/heatmaps": 10.0, "single_chip/adc_samples": 10.0,
           "cascade/heatmaps": 5.0, "cascade/adc_samples": 5.0, "lidar": 10.0, "imu": 50.0, "groundtruth": 20.0}
#: First time of each radar / lidar stream after T0, s: inside the ground truth's span.
OFFSET_S = {"single_chip/pointclouds": 0.05, "single_chip/heatmaps": 0.06, "single_chip/adc_samples": 0.06,
            "cascade/heatmaps": 0.07, "cascade/adc_samples": 0.07, "lidar": 0.02, "imu": 0.0, "groundtruth": 0.0}
#: Heatmap shape (elevation, azimuth, range) of each radar.
HEATMAP_SHAPE = {"single_chip": (4, 8, 16), "cascade": (4, 16, 32)}
#: Range bin width, m (exact in binary, so it reads back exactly).
RANGE_BIN_WIDTH = {"single_chip": 0.125, "cascade": 0.0625}
#: ADC frame shape (tx, rx, chirps, samples) of each radar.
ADC_SHAPE = {"single_chip": (3, 4, 8, 16), "cascade": (3, 4, 8, 16)}
#: waveform_cfg.txt values besides the shape (SI units, as the dataset stores them).
WAVEFORM = {
    "single_chip": {"adc_sample_frequency": 2.0e6, "start_frequency": 77.0e9, "idle_time": 1.0e-5,
                    "adc_start_time": 6.0e-6, "ramp_end_time": 6.0e-5, "frequency_slope": 6.0e13},
    "cascade": {"adc_sample_frequency": 8.0e6, "start_frequency": 77.0e9, "idle_time": 5.0e-6,
                "adc_start_time": 6.0e-6, "ramp_end_time": 4.0e-5, "frequency_slope": 7.9e13},
}
#: antenna_cfg.txt TX positions (horizontal, vertical; half wavelengths) of each radar, by TX
#: index.  The single chip's are the AWR1843BOOST's in TI's chirp order TX1, TX3, TX2.
TX_POSITIONS = {"single_chip": ((0, 0), (4, 0), (2, 1)), "cascade": ((0, 0), (4, 0), (8, 0))}
#: base_to_<sensor>.txt: translation (m) and a rotation about z (rad) of each sensor.
TRANSFORMS = {"single_chip": ((0.10, -0.05, 0.20), 0.30), "cascade": ((0.25, 0.0, 0.15), -0.20),
              "imu": ((0.0, 0.0, 0.05), 0.0), "lidar": ((0.0, 0.0, 0.30), math.pi / 2),
              "vicon": ((0.01, 0.02, 0.03), 0.0)}
#: Damage write_run can do; each gives one error naming the file.
FAULTS = ("heatmap_size", "adc_size", "timestamp_count", "numbering_gap", "missing_data_dir",
          "missing_heatmap_cfg", "missing_poses", "bad_timestamp", "bad_pose", "bad_heatmap_cfg")


def default_times(stream: str, n: int) -> np.ndarray:
    """Times (n,) s of a stream's records."""
    return T0 + OFFSET_S[stream] + np.arange(n) / RATE_HZ[stream]


def angle_bins(n: int, span_rad: float) -> np.ndarray:
    """*n* non-uniform ascending angles (rad) within +-span, spaced like an FFT's
    arcsin bins."""
    return np.arcsin(np.linspace(-1.0, 1.0, n) * math.sin(span_rad))


def default_heatmap_cfg(sensor: str, shape: tuple[int, int, int] | None = None) -> dict:
    """heatmap_cfg.txt values of *sensor* (its default shape unless *shape* (el, az, range))."""
    el, az, rng = shape or HEATMAP_SHAPE[sensor]
    return {"num_range_bins": rng, "num_elevation_bins": el, "num_azimuth_bins": az,
            "range_bin_width": RANGE_BIN_WIDTH[sensor], "azimuth_bins": angle_bins(az, math.radians(76.0)),
            "elevation_bins": angle_bins(el, math.radians(40.0))}


def default_waveform_cfg(sensor: str, shape: tuple[int, int, int, int] | None = None) -> dict:
    """waveform_cfg.txt values of *sensor* (its default ADC shape unless *shape*)."""
    tx, rx, chirps, samples = shape or ADC_SHAPE[sensor]
    return dict(num_rx=rx, num_tx=tx, num_adc_samples_per_chirp=samples, num_chirps_per_frame=chirps,
                **WAVEFORM[sensor])


def default_pointcloud(i: int) -> np.ndarray:
    """Point cloud *i*: (3 + i % 3, 5) float32 x, y, z, intensity, doppler, all distinct."""
    n = 3 + i % 3
    k = np.arange(n, dtype=np.float32)
    return np.column_stack([1.0 + k + i, 0.5 * k - 1.0, 0.25 * k, 10.0 + k + i, -0.5 + 0.125 * k]).astype(np.float32)


def default_heatmap(sensor: str, i: int) -> np.ndarray:
    """Heatmap *i* of *sensor*: (el, az, range, 2) float32 with every value distinct (exact)."""
    shape = (*HEATMAP_SHAPE[sensor], 2)
    return ((np.arange(math.prod(shape)) + 10000 * i) * 0.25).astype(np.float32).reshape(shape)


def default_adc(sensor: str, i: int) -> np.ndarray:
    """ADC frame *i* of *sensor*: (tx, rx, chirp, sample) complex64, integer I and Q spanning
    the int16 range."""
    shape = ADC_SHAPE[sensor]
    n = math.prod(shape)
    values = (np.arange(2 * n, dtype=np.int64) * 37 + 101 * i) % 65536 - 32768
    return (values[0::2] + 1j * values[1::2]).astype(np.complex64).reshape(shape)


def default_lidar(i: int) -> np.ndarray:
    """Lidar point cloud *i*: (6, 4) float32 x, y, z, intensity."""
    k = np.arange(6, dtype=np.float32)
    return np.column_stack([k + i, -k, 0.5 * k, 100.0 + k]).astype(np.float32)


def default_groundtruth(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """*n* base poses: times (n,) s, positions (n, 3) m (forward at 1 m/s, climbing 0.1 m/s)
    and yaw-only quaternions (n, 4) turning at 0.5 rad/s."""
    t = default_times("groundtruth", n)
    dt = t - T0
    positions = np.column_stack([dt, 0.2 * dt, 0.1 * dt])
    quats = yaw_quaternion(0.5 * dt)
    return t, positions, quats


def default_imu(n: int) -> np.ndarray:
    """*n* IMU records (n, 6): acceleration then angular rate."""
    k = np.arange(n, dtype=float)[:, None]
    return np.hstack([0.01 * k + np.array([0.0, 0.0, 9.81]), 0.001 * k + np.array([0.0, 0.0, 0.5])])


def _write_text(path: pathlib.Path, lines: Sequence[str]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(line + "\n" for line in lines), encoding="ascii")


def _row(values) -> str:
    return " ".join(repr(float(v)) for v in values)


def _write_cfg(path: pathlib.Path, values: Mapping) -> None:
    lines = []
    for key, value in values.items():
        if np.ndim(value):
            lines.append(f"{key} {_row(value)}")
        elif isinstance(value, (int, np.integer)):
            lines.append(f"{key} {int(value)}")
        else:
            lines.append(f"{key} {float(value)!r}")
    _write_text(path, lines)


def _write_numbered(folder: pathlib.Path, prefix: str, arrays: Sequence[np.ndarray], base: int,
                    gap: bool = False) -> None:
    """One file per array, numbered from *base* (skipping base + 1 when *gap*)."""
    folder.mkdir(parents=True, exist_ok=True)
    for k, data in enumerate(arrays):
        index = base + k + (1 if gap and k >= 1 else 0)
        (folder / f"{prefix}{index}.bin").write_bytes(data)


def _adc_bytes(cube: np.ndarray) -> bytes:
    """int16 I then Q interleaved, [tx][rx][chirp][sample]."""
    cube = np.asarray(cube)
    out = np.empty(cube.shape + (2,), "<i2")
    out[..., 0], out[..., 1] = np.rint(cube.real), np.rint(cube.imag)
    return out.tobytes()


def write_run(root, name: str = "ec_hallways_run0", *, numbering_base: int = 0, frames: int = 4,
              calib: str | None = "beside",
              pointclouds: Sequence[np.ndarray] | None = None,
              heatmaps: Mapping[str, Sequence[np.ndarray]] | None = None,
              heatmap_cfgs: Mapping[str, Mapping] | None = None,
              adc: Mapping[str, Sequence[np.ndarray]] | None = None,
              times: Mapping[str, Sequence[float]] | None = None,
              groundtruth: tuple | None = None,
              transforms: Mapping[str, tuple] | None = None,
              waveforms: Mapping[str, Mapping] | None = None,
              tx_positions: Mapping[str, Sequence | None] | None = None,
              faults: Sequence[str] = ()) -> pathlib.Path:
    """Write a run ``root/name`` and its calibration; returns the run's path.

    *frames*: records of each radar and lidar stream (their rates in :data:`RATE_HZ`); the
    ground truth covers them all, the IMU the same span.  *calib*: ``"beside"`` writes
    ``root/calib`` (as the dataset ships), ``"inside"`` writes ``root/name/calib``, None none.

    Given arrays replace the defaults (their count replaces *frames* for that stream):
    *pointclouds* [(n, 5) float32 per frame], *heatmaps* {sensor: [(el, az, range, 2)]} (the
    sensor's heatmap_cfg follows their shape unless *heatmap_cfgs* {sensor: values} says
    otherwise), *adc* {sensor: [(tx, rx, chirp, sample) complex]}, *times* {stream: (n,) s},
    *groundtruth* (times (n,), positions (n, 3), quaternions (n, 4) xyzw), *transforms*
    {sensor: (t (3,), q (4,) xyzw)}, *waveforms* {sensor: waveform_cfg values to replace},
    *tx_positions* {sensor: ((h, v) per TX index), or None for no antenna_cfg.txt}.
    """
    unknown = set(faults) - set(FAULTS)
    if unknown:
        raise ValueError(f"unknown faults {sorted(unknown)}; known: {FAULTS}")
    root = pathlib.Path(root)
    run = root / name
    run.mkdir(parents=True, exist_ok=False)
    heatmaps, adc, times = heatmaps or {}, adc or {}, times or {}
    hm_shapes: dict[str, tuple] = {}  # the heatmaps' shapes when given (the cfg follows them)
    adc_shapes: dict[str, tuple] = {}

    # Radar data.
    data = {
        "single_chip/pointclouds": [np.asarray(p, "<f4").tobytes() for p in
                                    (pointclouds if pointclouds is not None
                                     else [default_pointcloud(i) for i in range(frames)])],
        "lidar": [default_lidar(i).astype("<f4").tobytes() for i in range(frames)],
    }
    for sensor in HEATMAP_SHAPE:
        maps = heatmaps.get(sensor)
        maps = [default_heatmap(sensor, i) for i in range(frames)] if maps is None else list(maps)
        data[f"{sensor}/heatmaps"] = [np.asarray(h, "<f4").tobytes() for h in maps]
        if sensor in heatmaps and maps:
            hm_shapes[sensor] = np.asarray(maps[0]).shape[:3]
        cubes = adc.get(sensor)
        cubes = [default_adc(sensor, i) for i in range(frames)] if cubes is None else list(cubes)
        data[f"{sensor}/adc_samples"] = [_adc_bytes(c) for c in cubes]
        adc_shapes[sensor] = np.asarray(cubes[0]).shape if cubes else ADC_SHAPE[sensor]
    if "heatmap_size" in faults:
        data["single_chip/heatmaps"][1] = data["single_chip/heatmaps"][1][:-8]
    if "adc_size" in faults:
        data["single_chip/adc_samples"][1] = data["single_chip/adc_samples"][1] + b"\0\0\0\0"

    folders = {"single_chip/pointclouds": ("single_chip/pointclouds/data", "radar_pointcloud_"),
               "single_chip/heatmaps": ("single_chip/heatmaps/data", "heatmap_"),
               "single_chip/adc_samples": ("single_chip/adc_samples/data", "frame_"),
               "cascade/heatmaps": ("cascade/heatmaps/data", "heatmap_"),
               "cascade/adc_samples": ("cascade/adc_samples/data", "frame_"),
               "lidar": ("lidar/pointclouds", "lidar_pointcloud_")}
    last = T0
    for stream, (folder, prefix) in folders.items():
        _write_numbered(run / folder, prefix, data[stream], numbering_base,
                        gap="numbering_gap" in faults and stream == "single_chip/pointclouds")
        stamps = np.asarray(times.get(stream, default_times(stream, len(data[stream]))), float)
        if len(stamps):
            last = max(last, float(stamps[-1]))
        lines = [repr(float(t)) for t in stamps]
        if "timestamp_count" in faults and stream == "single_chip/heatmaps":
            lines.append(repr(float(stamps[-1]) + 0.1))
        if "bad_timestamp" in faults and stream == "cascade/heatmaps":
            lines[1] = "12x.5"
        ts_dir = folder.rsplit("/", 1)[0] if folder.endswith("/data") else stream
        _write_text(run / ts_dir / "timestamps.txt", lines)
    if "missing_data_dir" in faults:
        shutil.rmtree(run / "cascade" / "heatmaps" / "data")

    # Ground truth over the whole recording, and the IMU.
    if groundtruth is None:
        groundtruth = default_groundtruth(math.ceil((last - T0) * RATE_HZ["groundtruth"]) + 2)
    gt_t, gt_p, gt_q = (np.asarray(a, float) for a in groundtruth)
    _write_text(run / "groundtruth" / "timestamps.txt", [repr(float(t)) for t in gt_t])
    pose_lines = [_row([*p, *q]) for p, q in zip(gt_p, gt_q)]
    if "bad_pose" in faults:
        pose_lines[2] = _row(gt_p[2])
    if "missing_poses" not in faults:
        _write_text(run / "groundtruth" / "groundtruth_poses.txt", pose_lines)
    n_imu = int((last - T0) * RATE_HZ["imu"]) + 1
    _write_text(run / "imu" / "timestamps.txt", [repr(float(t)) for t in default_times("imu", n_imu)])
    _write_text(run / "imu" / "imu_data.txt", [_row(r) for r in default_imu(n_imu)])

    if calib is not None:
        _write_calib(root / "calib" if calib == "beside" else run / "calib", hm_shapes, heatmap_cfgs or {},
                     adc_shapes, transforms or {}, faults, waveforms or {}, tx_positions or {})
    return run


def _write_calib(folder: pathlib.Path, heatmap_shapes: Mapping, heatmap_cfgs: Mapping, adc_shapes: Mapping,
                 transforms: Mapping, faults: Sequence[str], waveforms: Mapping, tx_positions: Mapping) -> None:
    for sensor, (t, yaw) in TRANSFORMS.items():
        t, q = transforms.get(sensor, (t, yaw_quaternion(yaw)))
        _write_text(folder / "transforms" / f"base_to_{sensor}.txt", [_row(t), _row(q)])
    for sensor in HEATMAP_SHAPE:
        hm = dict(heatmap_cfgs.get(sensor) or default_heatmap_cfg(sensor, heatmap_shapes.get(sensor)))
        if "bad_heatmap_cfg" in faults and sensor == "single_chip":
            hm["azimuth_bins"] = hm["azimuth_bins"][:-1]
        if not ("missing_heatmap_cfg" in faults and sensor == "cascade"):
            _write_cfg(folder / sensor / "heatmap_cfg.txt", hm)
        wf = default_waveform_cfg(sensor, adc_shapes.get(sensor))
        wf.update(waveforms.get(sensor, {}))
        _write_cfg(folder / sensor / "waveform_cfg.txt", wf)
        # antenna_cfg.txt: the layout, in half-wavelength units.
        ant = ["# synthetic antenna layout", f"num_rx {wf['num_rx']}", f"num_tx {wf['num_tx']}", "F_design 77"]
        ant += [f"rx {k} {k} 0" for k in range(wf["num_rx"])]
        positions = tx_positions.get(sensor, TX_POSITIONS[sensor])
        if positions is not None:
            ant += [f"tx {k} {h} {v}" for k, (h, v) in enumerate(positions)]
            _write_text(folder / sensor / "antenna_cfg.txt", ant)
        n_range = int(wf["num_adc_samples_per_chirp"]) // 2  # the dataset's: the positive half, DC skipped
        coupling = ",".join(["0"] * (2 * wf["num_tx"] * wf["num_rx"] * n_range))
        _write_text(folder / sensor / "coupling_calib.txt",
                    [f"num_tx: {wf['num_tx']}", f"num_rx: {wf['num_rx']}", f"num_range_bins: {n_range}",
                     f"num_doppler_bins: {wf['num_chirps_per_frame']}", f"data: {coupling}"])


# ---------------------------------------------------------------------------------------------
# A moving platform

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
    # Reflectors at heights within +/- 0.8 m, as the dataset's 3-TX clouds measure them (z); not
    # drawn from rng, which the heatmaps share.
    z = 0.8 * np.sin(3.1 * np.arange(len(p)))
    r = np.hypot(p[:, 0], p[:, 1])
    keep = (p[:, 0] > 0.3) & (r < 8) & (np.abs(np.arctan2(p[:, 1], p[:, 0])) < math.radians(70))
    p, r, z = p[keep], r[keep], z[keep]
    # The sensor moves at (SPEED, 0) in its own frame; a static point has v_r = -v . u.
    doppler = -SPEED * p[:, 0] / np.hypot(r, z) + rng.normal(0, 0.01, len(r))
    return np.column_stack([p[:, 0], p[:, 1], z, np.full(len(r), 20.0), doppler]).astype("<f4")


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


def write_moving_run(root, name: str = "ec_hallways_run0") -> pathlib.Path:
    """A run of a radar platform driving a left arc through scattered reflectors: single-chip
    point clouds at 10 Hz, cascade-like heatmaps at 5 Hz (narrow beams), ground truth at 20 Hz,
    identity mounts; files numbered from 1."""
    rng = np.random.default_rng(8)
    world = _world(rng)
    azimuth_bins = np.arcsin(np.linspace(-0.97, 0.97, N_AZ))  # non-uniform in angle, ascending
    t_single = 0.05 + 0.1 * np.arange(int(DURATION * 10))
    t_cascade = 0.08 + 0.2 * np.arange(int(DURATION * 5))
    t_gt = 0.05 * np.arange(int(DURATION * 20) + 4)
    x, y, yaw = _pose(t_gt)
    gt = (t_gt, np.column_stack([x, y, np.zeros_like(x)]), yaw_quaternion(yaw))
    identity = (np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    run = write_run(root, name, numbering_base=1,
                    pointclouds=[_pointcloud(world, t, rng) for t in t_single],
                    heatmaps={"cascade": [_heatmap(world, t, azimuth_bins, rng) for t in t_cascade]},
                    heatmap_cfgs={"cascade": {"num_range_bins": N_RANGE, "num_elevation_bins": N_EL,
                                              "num_azimuth_bins": N_AZ, "range_bin_width": BIN_M,
                                              "azimuth_bins": azimuth_bins,
                                              "elevation_bins": np.linspace(-0.3, 0.3, N_EL)}},
                    times={"single_chip/pointclouds": t_single, "cascade/heatmaps": t_cascade},
                    groundtruth=gt, transforms={"single_chip": identity, "cascade": identity})
    return run


# ---------------------------------------------------------------------------------------------
# From a recording of ours


def write_run_from_capture(root, capture_dir, name: str = "sim_run0") -> pathlib.Path:
    """A run whose single-chip ADC frames, waveform, antenna layout and ground truth are those of
    a radarodom capture directory (a simulator recording): the same frames in ColoRadar's
    layout.  The ADC frame's tx axis is the capture's TX slot order (chirp order), and
    antenna_cfg.txt places each slot's TX; mounts are identity, so the single-chip radar's
    poses are the recording's."""
    from radarodom.antenna import TX_OFFSETS_HALF_WAVELENGTHS
    from radarodom.driver.recordings.capture_dir import CaptureDirectory

    store = CaptureDirectory(str(capture_dir))
    cfg = store.config
    cubes = [store.layout.decode(store.raw(i)).transpose(1, 2, 0, 3) for i in range(store.num_frames)]
    p = cfg.profile
    waveform = {"adc_sample_frequency": cfg.sample_rate_hz, "start_frequency": cfg.start_frequency_hz,
                "idle_time": p.idle_time_us * 1e-6, "adc_start_time": p.adc_start_time_us * 1e-6,
                "ramp_end_time": p.ramp_end_time_us * 1e-6, "frequency_slope": cfg.slope_hz_per_s}
    gt = store.groundtruth
    identity = (np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    return write_run(root, name, frames=len(cubes), adc={"single_chip": cubes},
                     times={"single_chip/adc_samples": np.asarray(store.timestamps, float)},
                     waveforms={"single_chip": waveform},
                     tx_positions={"single_chip": [TX_OFFSETS_HALF_WAVELENGTHS[t - 1] for t in cfg.tx_order]},
                     groundtruth=(gt.times, gt.positions, gt.quaternions),
                     transforms={"single_chip": identity, "cascade": identity})
