"""Reader of the ColoRadar dataset (Kramer et al., IJRR 2022) as it lies on disk.

One run directory (``ec_hallways_run0/`` or ``12_21_2020_ec_hallways_run0/``) holds::

    groundtruth/{timestamps.txt, groundtruth_poses.txt}
    imu/{timestamps.txt, imu_data.txt}
    lidar/timestamps.txt, lidar/pointclouds/lidar_pointcloud_<i>.bin
    single_chip/{adc_samples,heatmaps,pointclouds}/{timestamps.txt, data/<prefix>_<i>.bin}
    cascade/{adc_samples,heatmaps}/{timestamps.txt, data/<prefix>_<i>.bin}

and the calibration lies beside the runs (``calib/``): ``transforms/base_to_<sensor>.txt`` and
``<sensor>/{heatmap_cfg,waveform_cfg,antenna_cfg,coupling_calib}.txt``.

This module holds the run, :class:`ColoRadarRun`: where its calibration is, the radars' configs,
coupling, heatmaps and ADC frames, the point clouds, and the poses (ground truth, IMU,
base-to-sensor transforms, sensor poses).  How a stream's files are found, paired with their
timestamps, counted, checked and read is :mod:`.streams` (:class:`~.streams.RunStreams`, which
the run inherits; the binary files and the timestamps' numbering are described there); the file
formats and text readers are :mod:`.files`, the frame conversions :mod:`.geometry`.

Frames: the dataset's sensor frames are x forward, y left, z up (azimuth positive to the left).
radarodom's point clouds and heatmaps are in the TI sensor frame (x right, y forward;
azimuth positive to the right, docs/conventions.md): :func:`pointcloud_to_points` and
:func:`heatmap_to_polar` convert.  Poses are Hamilton quaternions (qx, qy, qz, qw).
"""

from __future__ import annotations

import logging
import math
import os
import re

import numpy as np

from ...errors import CaptureError, CaptureFormatError, UsageError  # noqa: F401 (CaptureError: importable here as before)
from ...tum import TumTrajectory, quaternion_yaw

# The reader's public names live in two modules; they are all importable from here.
from .files import (  # noqa: F401
    _LAYOUT,
    ADC_SAMPLE,
    HEATMAP_CELL,
    LIDAR_POINT,
    RADAR_POINT,
    MAX_POSITION_M,
    RADARS,
    STREAMS,
    HeatmapConfig,
    WaveformConfig,
    _read_table,
    check_file_size,
    finite_values,
    read_heatmap_config,
    read_transform,
    read_waveform_config,
    unit_quaternions,
)
from .geometry import (
    adc_to_cube,
    heatmap_to_polar,
    pointcloud_to_points,
    points_in_frame,
    quaternion_multiply,
    quaternion_rotate,
    slerp,
)
from .streams import RunStreams

__all__ = [
    "ADC_SAMPLE",
    "HEATMAP_CELL",
    "LIDAR_POINT",
    "RADARS",
    "RADAR_POINT",
    "STREAMS",
    "ColoRadarRun",
    "HeatmapConfig",
    "WaveformConfig",
    "adc_to_cube",
    "check_file_size",
    "heatmap_to_polar",
    "pointcloud_to_points",
    "points_in_frame",
    "quaternion_multiply",
    "quaternion_rotate",
    "read_heatmap_config",
    "read_transform",
    "read_waveform_config",
    "slerp",
]

log = logging.getLogger(__name__)


# ---------------------------------------------------------------------------------------------
# A run


def found_calibration(run_dir: str) -> str | None:
    """The calibration folder of the run in *run_dir* when none is given: ``calib/`` beside the
    run (the dataset's layout), else inside it; None when neither is there."""
    run_dir = os.path.normpath(run_dir)
    beside = os.path.join(os.path.dirname(run_dir), "calib")
    inside = os.path.join(run_dir, "calib")
    return next((d for d in (beside, inside) if os.path.isdir(d)), None)


def _directory(path, what: str) -> str:
    """*path* made absolute; :class:`UsageError` when it is no directory."""
    if not isinstance(path, (str, os.PathLike)) or isinstance(os.fspath(path), bytes):
        raise UsageError(f"a ColoRadar {what} is a path, got {type(path).__name__}")
    text = os.fspath(path)
    if "\0" in text:
        raise UsageError(f"{what} {text[:200]!r}: a path cannot hold a NUL byte")
    full = os.path.abspath(text)
    if os.path.exists(full) and not os.path.isdir(full):
        raise UsageError(f"{full}: a file, not a ColoRadar {what}")
    if not os.path.isdir(full):
        raise UsageError(f"{full}: no such {what}")
    return full


class ColoRadarRun(RunStreams):
    """One ColoRadar run on disk.

    *calib_dir* defaults to ``<run_dir>/../calib`` when it exists, else ``<run_dir>/calib``
    (None when neither does: then only the calibration-free readers work).  Everything read is
    checked against its layout, and errors name the file (and line for text).
    """

    def __init__(self, run_dir: str | os.PathLike, calib_dir: str | os.PathLike | None = None) -> None:
        # A directory that is not there is the caller's mistake (exit 2, as replay:// says).
        self.run_dir = _directory(run_dir, "run directory")
        self.name = os.path.basename(self.run_dir)
        self._calib_given = calib_dir is not None
        if calib_dir is not None:
            calib_dir = _directory(calib_dir, "calibration directory")
            self.calib_dir: str | None = calib_dir
        else:
            self.calib_dir = found_calibration(self.run_dir)
            if self.calib_dir is None:
                log.info("%s: no calib/ beside or inside the run", self.run_dir)
        self._said_negative = False  # a heatmap's negative intensities, warned of once
        self._times: dict[str, np.ndarray] = {}
        self._time_lines: dict[str, np.ndarray] = {}  # the line of each time in its file
        self._files: dict[str, list[str]] = {}
        self._heatmap_cfg: dict[str, HeatmapConfig] = {}
        self._waveform_cfg: dict[str, WaveformConfig] = {}
        self._transforms: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._groundtruth: TumTrajectory | None = None

    def __repr__(self) -> str:
        return f"ColoRadarRun({self.run_dir!r}, calib_dir={self.calib_dir!r})"

    # -- radar data --------------------------------------------------------------------------

    def pointcloud(self, i: int) -> np.ndarray:
        """Single-chip point cloud *i* (0-based, time order): (n, 5) float32 x, y, z (m, sensor
        frame as stored: x forward, y left, z up), intensity (SNR dB), doppler (m/s)."""
        path = self._file("single_chip/pointclouds", i)
        return finite_values(path, self._read_records(path, RADAR_POINT).view("<f4").reshape(-1, 5))

    def lidar_pointcloud(self, i: int) -> np.ndarray:
        """Lidar point cloud *i*: (n, 4) float32 x, y, z (m, lidar frame), intensity."""
        path = self._file("lidar", i)
        return finite_values(path, self._read_records(path, LIDAR_POINT).view("<f4").reshape(-1, 4))

    @staticmethod
    def _radar(sensor: str) -> str:
        if sensor not in RADARS:
            raise UsageError(f"unknown ColoRadar radar {sensor!r}; one of {', '.join(RADARS)}")
        return sensor

    def calib_path(self, *parts: str, required: bool = True) -> str:
        """The path of calib/<parts...>; raises when the run has no calibration folder, or when
        the file is *required* and not there."""
        if self.calib_dir is None:
            raise UsageError(f"{self.run_dir}: no calibration: neither "
                               f"{os.path.join(os.path.dirname(self.run_dir), 'calib')} nor "
                               f"{os.path.join(self.run_dir, 'calib')} exists (give it: --calib DIR, or "
                               "calib= in a coloradar:// URL)")
        path = os.path.join(self.calib_dir, *parts)
        if required and not os.path.exists(path):  # the calibration's, not the run's: say whose
            how = "the calibration folder given" if self._calib_given else "the calib/ found for the run"
            raise CaptureFormatError(f"{path}: no such file: {self.calib_dir}, {how}, is not a whole ColoRadar "
                                     "calib folder (cascade/, single_chip/, transforms/)")
        return path

    def heatmap_config(self, sensor: str) -> HeatmapConfig:
        """The axes of *sensor*'s heatmaps (calib/<sensor>/heatmap_cfg.txt)."""
        if self._radar(sensor) not in self._heatmap_cfg:
            self._heatmap_cfg[sensor] = read_heatmap_config(self.calib_path(sensor, "heatmap_cfg.txt"))
        return self._heatmap_cfg[sensor]

    def waveform_config(self, sensor: str) -> WaveformConfig:
        """The chirp waveform of *sensor* (calib/<sensor>/waveform_cfg.txt)."""
        if self._radar(sensor) not in self._waveform_cfg:
            self._waveform_cfg[sensor] = read_waveform_config(self.calib_path(sensor, "waveform_cfg.txt"))
        return self._waveform_cfg[sensor]

    def coupling(self, sensor: str):
        """*sensor*'s TX-to-RX coupling (calib/<sensor>/coupling_calib.txt) as a
        :class:`radarodom.calibration.RangeCoupling`, or None when the file is not there."""
        from .coupling import read_coupling

        path = self.calib_path(sensor, "coupling_calib.txt", required=False)
        if not os.path.exists(path):
            log.info("%s: missing: no coupling removed", path)
            return None
        return read_coupling(path, self.waveform_config(sensor).num_adc_samples_per_chirp)

    def heatmap(self, sensor: str, i: int) -> np.ndarray:
        """Heatmap *i* of *sensor*: (el, az, range, 2) float32, [..., 0] the intensity and
        [..., 1] the Doppler (m/s), axes as in :meth:`heatmap_config`."""
        cfg = self.heatmap_config(sensor)
        path = self._file(f"{sensor}/heatmaps", i)
        cells = self._read_fixed(path, HEATMAP_CELL, cfg.shape[:3],
                                 self.calib_path(sensor, "heatmap_cfg.txt"))
        values = finite_values(path, cells.view("<f4").reshape(cfg.shape))
        negative = values[..., 0] < 0
        if negative.any():  # (the estimator's CFAR stopped on them, naming neither file nor frame)
            (log.debug if self._said_negative else log.warning)(
                "%s: %d of %d intensities are negative (a power is >= 0): taken as 0 (said once a run)", path,
                int(negative.sum()), negative.size)
            self._said_negative = True
            values[..., 0][negative] = 0
        return values

    def adc(self, sensor: str, i: int) -> np.ndarray:
        """ADC frame *i* of *sensor*: complex64 (tx, rx, chirp, sample) as stored, I real and Q
        imaginary, in ADC counts."""
        wf = self.waveform_config(sensor)
        path = self._file(f"{sensor}/adc_samples", i)
        samples = self._read_fixed(path, ADC_SAMPLE, wf.adc_shape, self.calib_path(sensor, "waveform_cfg.txt"))
        out = np.empty(wf.adc_shape, np.complex64)
        out.real, out.imag = samples["i"], samples["q"]
        return out

    # -- poses -------------------------------------------------------------------------------

    def base_to_sensor(self, sensor: str) -> tuple[np.ndarray, np.ndarray]:
        """(t (3,) m, q (4,) xyzw) of calib/transforms/base_to_<sensor>.txt: p_base = R(q) p_sensor + t.
        *sensor* is any transform there (single_chip, cascade, imu, lidar, vicon)."""
        if not isinstance(sensor, str) or not re.fullmatch(r"[A-Za-z0-9_]+", sensor):
            raise UsageError(f"bad sensor name {sensor!r}")
        if sensor not in self._transforms:
            self._transforms[sensor] = read_transform(self.calib_path("transforms", f"base_to_{sensor}.txt"))
        t, q = self._transforms[sensor]
        return t.copy(), q.copy()

    def mount_yaw(self, sensor: str) -> float:
        """Yaw (rad, counter-clockwise) of *sensor*'s frame in the base frame, from its calib
        quaternion."""
        _, q = self.base_to_sensor(sensor)
        return float(quaternion_yaw(q[None])[0])

    def groundtruth(self) -> TumTrajectory:
        """The base frame's pose in the world at the ground-truth times (lines of
        groundtruth_poses.txt: ``x y z qx qy qz qw``; quaternions normalised)."""
        if self._groundtruth is None:
            layout = _LAYOUT["groundtruth"]
            path = self._path(layout.text_file)
            # The poses and their timestamps pair up line by line, and the times advance (an
            # interpolation between two poses at one time is undefined).
            self.check("groundtruth")
            times = self.timestamps("groundtruth")
            rows, lines = _read_table(path, 7, "'x y z qx qy qz qw'")
            far = np.flatnonzero(np.abs(rows[:, :3]).max(axis=1) > MAX_POSITION_M)
            if len(far):  # (squared on the way to the metrics: inf and numpy's warnings)
                raise CaptureFormatError(f"{path}:{lines[far[0]]}: a position {np.abs(rows[far[0], :3]).max():g} m "
                                         f"from the origin (at most {MAX_POSITION_M:g} m; metres expected)")
            self._groundtruth = TumTrajectory(np.array(times), rows[:, :3],
                                              unit_quaternions(rows[:, 3:], path, lines), path, lines)
        gt = self._groundtruth
        return TumTrajectory(gt.times.copy(), gt.positions.copy(), gt.quaternions.copy(), gt.source, gt.lines.copy())

    def imu(self) -> np.ndarray:
        """IMU measurements (n, 6): acceleration (m/s^2) then angular rate (rad/s), IMU frame,
        one per line of imu/imu_data.txt (times: ``timestamps("imu")``)."""
        self.count("imu")
        return _read_table(self._path(_LAYOUT["imu"].text_file), 6, "'ax ay az wx wy wz'")[0]

    def sensor_poses(self, sensor: str, times) -> tuple[TumTrajectory, np.ndarray]:
        """The pose of *sensor* in the world at *times* (n,) s.

        The base pose is interpolated between the ground-truth poses around each time (linear in
        position, slerp in rotation) and composed with base_to_<sensor>.  Times outside the
        ground truth's span are dropped.  Returns the trajectory of the kept times and the mask
        (n,) bool of them.
        """
        times = np.asarray(times, dtype=float).reshape(-1)
        gt = self.groundtruth()
        t_sb, q_sb = self.base_to_sensor(sensor)
        if len(gt) == 0:
            mask = np.zeros(len(times), bool)
        else:
            mask = (times >= gt.times[0]) & (times <= gt.times[-1])
        kept = times[mask]
        if len(gt) == 1:
            k = np.zeros(len(kept), int)
            alpha = np.zeros(len(kept))
            k1 = k
        else:
            k = np.clip(np.searchsorted(gt.times, kept, side="right") - 1, 0, len(gt) - 2)
            k1 = k + 1
            dt = gt.times[k1] - gt.times[k]
            # Repeated ground-truth times (dt 0) take the first pose rather than divide by zero.
            alpha = np.where(dt > 0, (kept - gt.times[k]) / np.where(dt > 0, dt, 1.0), 0.0)
        position = gt.positions[k] + alpha[:, None] * (gt.positions[k1] - gt.positions[k])
        q_wb = slerp(gt.quaternions[k], gt.quaternions[k1], alpha) if len(kept) else np.zeros((0, 4))
        q_ws = quaternion_multiply(q_wb, q_sb)
        p_ws = position + quaternion_rotate(q_wb, t_sb)
        q_ws = q_ws / np.linalg.norm(q_ws, axis=-1, keepdims=True) if len(kept) else q_ws
        dropped = len(times) - len(kept)
        if dropped:
            log.info("%s: %d of %d %s times fall outside the ground truth (%.3f..%.3f s): dropped",
                     self.name, dropped, len(times), sensor,
                     gt.times[0] if len(gt) else math.nan, gt.times[-1] if len(gt) else math.nan)
        traj = TumTrajectory(kept, p_ws.reshape(-1, 3), q_ws.reshape(-1, 4), source=f"{gt.source} ({sensor})")
        return traj, mask
