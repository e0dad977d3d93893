"""Reader of the ColoRadar dataset (Kramer et al., IJRR 2022) as it lies on disk.

One run directory (``ec_hallways_run0/`` or ``12_21_2020_ec_hallways_run0/``) holds::

    groundtruth/{timestamps.txt, groundtruth_poses.txt}
    imu/{timestamps.txt, imu_data.txt}
    lidar/timestamps.txt, lidar/pointclouds/lidar_pointcloud_<i>.bin
    single_chip/{adc_samples,heatmaps,pointclouds}/{timestamps.txt, data/<prefix>_<i>.bin}
    cascade/{adc_samples,heatmaps}/{timestamps.txt, data/<prefix>_<i>.bin}

and the calibration lies beside the runs (``calib/``): ``transforms/base_to_<sensor>.txt`` and
``<sensor>/{heatmap_cfg,waveform_cfg,antenna_cfg,coupling_calib}.txt``.

Binary files are raw, headerless and little-endian (:data:`ADC_SAMPLE`, :data:`HEATMAP_CELL`,
:data:`RADAR_POINT`, :data:`LIDAR_POINT`).  Line ``k`` of a ``timestamps.txt`` (seconds) belongs
to the ``k``-th data file in numeric order; numbering starts at 0 in some downloads and at 1 in
others, so the lowest index present is taken as the first.

Frames: the dataset's sensor frames are x forward, y left, z up (azimuth positive to the left).
radarodom's point clouds and heatmaps are in the TI sensor frame (x right, y forward;
azimuth positive to the right, conventions.md): :func:`pointcloud_to_points` and
:func:`heatmap_to_polar` convert.  Poses are Hamilton quaternions (qx, qy, qz, qw).
"""

from __future__ import annotations

import logging
import math
import os
import re
from dataclasses import dataclass

import numpy as np

from ..dsp.heatmap import RangeAzimuth
from ..dsp.processor import POINT_DTYPE
from ..errors import CaptureError, CaptureFormatError, UsageError
from ..tum import TumTrajectory, parse_numbers, quaternion_yaw

log = logging.getLogger(__name__)

#: Every stream a run may hold, by its folder inside the run.
STREAMS = ("single_chip/pointclouds", "single_chip/heatmaps", "single_chip/adc_samples",
           "cascade/heatmaps", "cascade/adc_samples", "groundtruth", "imu", "lidar")
#: The two radars.
RADARS = ("single_chip", "cascade")

#: One ADC sample of an ADC frame: int16 I then Q; a frame is [tx][rx][chirp][sample].
ADC_SAMPLE = np.dtype([("i", "<i2"), ("q", "<i2")])
#: One heatmap cell: peak Doppler-bin intensity and that peak's radial velocity (m/s).
#: A heatmap is [elevation][azimuth][range] of these.
HEATMAP_CELL = np.dtype([("intensity", "<f4"), ("doppler", "<f4")])
#: One point of a single-chip radar point cloud (TI on-chip processing): m, SNR dB, m/s.
RADAR_POINT = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("doppler", "<f4")])
#: One lidar point: m and the lidar's intensity.
LIDAR_POINT = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")])


@dataclass(frozen=True)
class _StreamLayout:
    """Where a stream's files lie inside a run."""

    timestamps: str  # relative path of timestamps.txt
    data_dir: str | None = None  # folder of numbered files, or None for a text stream
    prefix: str = ""  # file name before the index
    text_file: str | None = None  # for text streams: the file with one record per line


_LAYOUT = {
    "single_chip/pointclouds": _StreamLayout("single_chip/pointclouds/timestamps.txt",
                                             "single_chip/pointclouds/data", "radar_pointcloud_"),
    "single_chip/heatmaps": _StreamLayout("single_chip/heatmaps/timestamps.txt",
                                          "single_chip/heatmaps/data", "heatmap_"),
    "single_chip/adc_samples": _StreamLayout("single_chip/adc_samples/timestamps.txt",
                                             "single_chip/adc_samples/data", "frame_"),
    "cascade/heatmaps": _StreamLayout("cascade/heatmaps/timestamps.txt", "cascade/heatmaps/data", "heatmap_"),
    "cascade/adc_samples": _StreamLayout("cascade/adc_samples/timestamps.txt",
                                         "cascade/adc_samples/data", "frame_"),
    "groundtruth": _StreamLayout("groundtruth/timestamps.txt", text_file="groundtruth/groundtruth_poses.txt"),
    "imu": _StreamLayout("imu/timestamps.txt", text_file="imu/imu_data.txt"),
    "lidar": _StreamLayout("lidar/timestamps.txt", "lidar/pointclouds", "lidar_pointcloud_"),
}


@dataclass(frozen=True, eq=False)
class HeatmapConfig:
    """A radar's heatmap axes, from ``calib/<sensor>/heatmap_cfg.txt``.

    Angles follow the dataset: azimuth positive to the LEFT (x forward, y left), elevation
    positive up; both non-uniform and ascending.
    """

    num_range_bins: int
    num_elevation_bins: int
    num_azimuth_bins: int
    range_bin_width: float  # m
    azimuth_bins: np.ndarray  # (num_azimuth_bins,) rad, ascending, positive to the left
    elevation_bins: np.ndarray  # (num_elevation_bins,) rad, ascending

    @property
    def range_m(self) -> np.ndarray:
        """Range of each bin (num_range_bins,) m: index * range_bin_width.  (The official
        pipeline drops the DC bin, so real data may sit one bin further than this.)"""
        return np.arange(self.num_range_bins) * self.range_bin_width

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """Shape of one heatmap: (elevation, azimuth, range, 2)."""
        return (self.num_elevation_bins, self.num_azimuth_bins, self.num_range_bins, 2)


@dataclass(frozen=True)
class WaveformConfig:
    """A radar's chirp waveform, from ``calib/<sensor>/waveform_cfg.txt`` (SI units as stored)."""

    num_rx: int
    num_tx: int
    num_adc_samples_per_chirp: int
    num_chirps_per_frame: int  # chirps per TX in a frame (the ADC frame's chirp axis)
    adc_sample_frequency: float  # Hz
    start_frequency: float  # Hz
    idle_time: float  # s
    adc_start_time: float  # s
    ramp_end_time: float  # s
    frequency_slope: float  # Hz/s

    @property
    def adc_shape(self) -> tuple[int, int, int, int]:
        """Shape of one ADC frame: (tx, rx, chirp, sample)."""
        return (self.num_tx, self.num_rx, self.num_chirps_per_frame, self.num_adc_samples_per_chirp)


_HEATMAP_INT_KEYS = ("num_range_bins", "num_elevation_bins", "num_azimuth_bins")
_HEATMAP_KEYS = _HEATMAP_INT_KEYS + ("range_bin_width", "azimuth_bins", "elevation_bins")
_WAVEFORM_INT_KEYS = ("num_rx", "num_tx", "num_adc_samples_per_chirp", "num_chirps_per_frame")
_WAVEFORM_KEYS = _WAVEFORM_INT_KEYS + ("adc_sample_frequency", "start_frequency", "idle_time",
                                       "adc_start_time", "ramp_end_time", "frequency_slope")


# ---------------------------------------------------------------------------------------------
# Text files


def _read_lines(path: str) -> list[tuple[int, str]]:
    """(1-based line number, stripped text) of the non-blank lines of *path*."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return [(n, s) for n, line in enumerate(fh, start=1) if (s := line.strip())]
    except FileNotFoundError:
        raise CaptureFormatError(f"{path}: no such file (the run is incomplete)") from None
    except OSError as exc:
        raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None


def _read_table(path: str, columns: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Rows (n, columns) float64 of a whitespace-separated text file and their line numbers (n,)."""
    lines = _read_lines(path)
    rows = [parse_numbers(path, n, text, columns, what) for n, text in lines]
    return (np.array(rows, dtype=float).reshape(-1, columns),
            np.array([n for n, _ in lines], dtype=int))


def _read_keyed(path: str, keys: tuple[str, ...], int_keys: tuple[str, ...]) -> dict:
    """``key value...`` lines (``#`` comments allowed): every key in *keys* must be there.

    Integer keys take one integer; other keys one float, or a list for the angle bins.
    Unknown keys are logged and skipped: the dataset's cfg files may grow.
    """
    out: dict = {}
    for lineno, text in _read_lines(path):
        if text.startswith("#"):
            continue
        # coloradar-library also accepts "key: value" and "key=value".
        m = re.fullmatch(r"([^\s:=]+)\s*[:=\s]\s*(.*)", text)
        key, rest = (m.group(1), m.group(2)) if m else (text, "")
        if key not in keys:
            log.debug("%s:%d: ignoring unknown key %r", path, lineno, key)
            continue
        if key in out:
            raise CaptureFormatError(f"{path}:{lineno}: {key} given twice")
        multi = key in ("azimuth_bins", "elevation_bins")
        values = parse_numbers(path, lineno, rest, None if multi else 1, f"{key} and its value(s)")
        if key in int_keys:
            if values[0] != int(values[0]) or values[0] <= 0:
                raise CaptureFormatError(f"{path}:{lineno}: {key} must be a positive integer, got {rest!r}")
            out[key] = int(values[0])
        else:
            out[key] = np.array(values) if multi else values[0]
    missing = [k for k in keys if k not in out]
    if missing:
        raise CaptureFormatError(f"{path}: missing {', '.join(missing)}")
    return out


def read_heatmap_config(path: str | os.PathLike) -> HeatmapConfig:
    """Parse a ``heatmap_cfg.txt``; the angle lists must match their counts and ascend."""
    path = os.fspath(path)
    v = _read_keyed(path, _HEATMAP_KEYS, _HEATMAP_INT_KEYS)
    for key, count in (("azimuth_bins", "num_azimuth_bins"), ("elevation_bins", "num_elevation_bins")):
        bins = v[key]
        if len(bins) != v[count]:
            raise CaptureFormatError(f"{path}: {key} holds {len(bins)} angles but {count} is {v[count]}")
        if np.any(np.diff(bins) <= 0):
            raise CaptureFormatError(f"{path}: {key} are not ascending")
        bins.setflags(write=False)  # the config is frozen: so are its arrays
    if v["range_bin_width"] <= 0:
        raise CaptureFormatError(f"{path}: range_bin_width must be positive, got {v['range_bin_width']}")
    return HeatmapConfig(**v)


def read_waveform_config(path: str | os.PathLike) -> WaveformConfig:
    """Parse a ``waveform_cfg.txt``."""
    path = os.fspath(path)
    return WaveformConfig(**_read_keyed(path, _WAVEFORM_KEYS, _WAVEFORM_INT_KEYS))


def read_transform(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """A ``base_to_<sensor>.txt``: translation (3,) m on line 1, quaternion (4,) xyzw on line 2
    (normalised).  It maps sensor-frame points into the base frame."""
    path = os.fspath(path)
    lines = _read_lines(path)
    if len(lines) < 2:
        raise CaptureFormatError(f"{path}: expected 'tx ty tz' and 'qx qy qz qw' lines, found {len(lines)} line(s)")
    t = np.array(parse_numbers(path, lines[0][0], lines[0][1], 3, "'tx ty tz'"))
    q = np.array(parse_numbers(path, lines[1][0], lines[1][1], 4, "'qx qy qz qw'"))
    norm = np.linalg.norm(q)
    if norm == 0:
        raise CaptureFormatError(f"{path}:{lines[1][0]}: the quaternion is zero")
    return t, q / norm


# ---------------------------------------------------------------------------------------------
# Quaternions (xyzw, Hamilton)


def quaternion_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b of quaternions (..., 4) xyzw (broadcasting)."""
    ax, ay, az, aw = np.moveaxis(np.asarray(a, float), -1, 0)
    bx, by, bz, bw = np.moveaxis(np.asarray(b, float), -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def quaternion_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectors (..., 3) rotated by unit quaternions (..., 4) xyzw (broadcasting)."""
    q = np.asarray(q, float)
    u, w = q[..., :3], q[..., 3:]
    # v' = v + 2 w (u x v) + 2 u x (u x v): the rotation without building matrices.
    uv = np.cross(u, v)
    return v + 2.0 * (w * uv + np.cross(u, uv))


def slerp(q0: np.ndarray, q1: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Spherical interpolation between unit quaternions (n, 4) at fractions *alpha* (n,) in [0, 1],
    along the shorter arc."""
    q0 = np.asarray(q0, float)
    q1 = np.asarray(q1, float).copy()
    alpha = np.asarray(alpha, float)[:, None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1[dot[:, 0] < 0] *= -1.0  # q and -q are the same rotation: take the short way
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    near = sin_theta < 1e-6  # (almost) equal: the linear blend is exact to rounding
    safe = np.where(near, 1.0, sin_theta)
    w0 = np.where(near, 1.0 - alpha, np.sin((1.0 - alpha) * theta) / safe)
    w1 = np.where(near, alpha, np.sin(alpha * theta) / safe)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


# ---------------------------------------------------------------------------------------------
# Pure conversions


def adc_to_cube(adc: np.ndarray) -> np.ndarray:
    """A ColoRadar ADC frame (tx, rx, chirp, sample) as radarodom's cube (loops, tx_slots, rx,
    samples) complex64 (rawframe.RawLayout): a chirp of ColoRadar's frame is one loop of ours,
    its TX is the slot.  The values are unchanged (I real, Q imaginary, ADC counts)."""
    adc = np.asarray(adc)
    if adc.ndim != 4:
        raise UsageError(f"an ADC frame is (tx, rx, chirp, sample), got shape {adc.shape}")
    return np.ascontiguousarray(adc.transpose(2, 0, 1, 3), dtype=np.complex64)


def pointcloud_to_points(pc: np.ndarray) -> np.ndarray:
    """A ColoRadar radar point cloud (n, 5) x, y, z (m; x forward, y left, z up), intensity (SNR
    dB), doppler (m/s, positive receding) as POINT_DTYPE (n,) in the TI sensor frame:
    x_TI = -y, y_TI = x, z_TI = z; azimuth atan2(x_TI, y_TI) (positive to the right); elevation
    asin(z / r).  TI's point clouds carry no noise estimate nor bins: noise_db 0, bins -1."""
    pc = np.asarray(pc)
    if pc.ndim != 2 or pc.shape[1] != 5:
        raise UsageError(f"a ColoRadar point cloud is (n, 5), got shape {pc.shape}")
    pts = np.zeros(len(pc), POINT_DTYPE)
    x_ti, y_ti, z_ti = -pc[:, 1], pc[:, 0], pc[:, 2]
    r = np.sqrt(x_ti.astype(float) ** 2 + y_ti.astype(float) ** 2 + z_ti.astype(float) ** 2)
    pts["x"], pts["y"], pts["z"], pts["range"] = x_ti, y_ti, z_ti, r
    pts["azimuth"] = np.arctan2(x_ti, y_ti)
    pts["elevation"] = np.arcsin(np.clip(z_ti / np.maximum(r, 1e-9), -1.0, 1.0))
    pts["velocity"] = pc[:, 4]
    pts["snr_db"] = pc[:, 3]
    pts["range_bin"] = -1
    pts["doppler_bin"] = -1
    return pts


def points_in_frame(points: np.ndarray, bearing_offset_rad: float) -> np.ndarray:
    """*points* (POINT_DTYPE, TI sensor frame of one radar) as seen from a radar at the same
    place turned *bearing_offset_rad* to the right of it (the lever arm between the two is
    ignored, as the paper does): azimuth minus the offset, x and y turned with it."""
    out = points.copy()
    out["azimuth"] = points["azimuth"] - bearing_offset_rad
    horizontal = np.hypot(points["x"], points["y"])
    out["x"] = horizontal * np.sin(out["azimuth"])
    out["y"] = horizontal * np.cos(out["azimuth"])
    return out


def heatmap_to_polar(hm: np.ndarray, cfg: HeatmapConfig, *, reduce: str = "max") -> RangeAzimuth:
    """A ColoRadar heatmap (el, az, range, 2) as a range-azimuth map in the TI convention.

    The elevation axis is reduced by ``"max"`` or ``"sum"`` of the intensity; the Doppler of
    each cell is that of its brightest elevation bin in both cases.  ColoRadar's azimuth is
    positive to the left, TI's to the right: azimuth_TI = -az, and the azimuth axis is reversed
    so that it ascends.  Returns arrays (range, az) float32; ``static`` is a copy of the
    intensity (ColoRadar keeps no zero-Doppler channel).
    """
    if reduce not in ("max", "sum"):
        raise UsageError(f"reduce must be 'max' or 'sum', got {reduce!r}")
    hm = np.asarray(hm)
    if hm.shape != cfg.shape:
        raise UsageError(f"the heatmap is shaped {hm.shape}, its config says {cfg.shape}")
    intensity, doppler = hm[..., 0], hm[..., 1]  # (el, az, range)
    best = np.argmax(intensity, axis=0)[None]  # (1, az, range)
    best_doppler = np.take_along_axis(doppler, best, axis=0)[0]
    reduced = intensity.max(axis=0) if reduce == "max" else intensity.sum(axis=0)
    # (az, range) -> (range, az), then reverse the azimuth axis for TI's sign.
    inten = np.ascontiguousarray(reduced.T[:, ::-1], dtype=np.float32)
    return RangeAzimuth(intensity=inten, static=inten.copy(),
                        doppler_mps=np.ascontiguousarray(best_doppler.T[:, ::-1], dtype=np.float32),
                        range_m=cfg.range_m, azimuth_rad=-np.asarray(cfg.azimuth_bins)[::-1].copy())


# ---------------------------------------------------------------------------------------------
# A run


def _directory(path, what: str) -> str:
    """*path* made absolute; :class:`UsageError` when it is no directory."""
    if not isinstance(path, (str, os.PathLike)) or isinstance(os.fspath(path), bytes):
        raise UsageError(f"a ColoRadar {what} is a path, got {type(path).__name__}")
    text = os.fspath(path)
    if "\0" in text:
        raise UsageError(f"{what} {text[:200]!r}: a path cannot hold a NUL byte")
    full = os.path.abspath(text)
    if not os.path.isdir(full):
        raise UsageError(f"{full}: no such {what}")
    return full


def check_file_size(path: str, size: int, dtype: np.dtype, shape: tuple[int, ...] | None = None,
                    cfg_path: str | None = None) -> None:
    """One data file's size against what it must hold: exactly *shape* cells of *dtype* (the
    calib file *cfg_path* says so), or with no *shape* a whole number of *dtype* points.  The one
    check of both the up-front :meth:`ColoRadarRun.check` and every read."""
    if shape is not None:
        expected = math.prod(shape) * dtype.itemsize
        if size != expected:
            raise CaptureFormatError(f"{path}: {size} bytes, expected {expected} for shape {shape} "
                                     f"of {dtype.itemsize}-byte cells ({cfg_path})")
    elif size % dtype.itemsize:
        raise CaptureFormatError(f"{path}: {size} bytes is not a whole number of {dtype.itemsize}-byte points")


def _finite(path: str, values: np.ndarray) -> np.ndarray:
    """*values* (little-endian float32 as read) as native float32; a NaN or an infinity is a
    broken file: every consumer would have to guess what it means.  Found when the file is read
    (a run's data is too large to read twice), the file named."""
    out = values.astype(np.float32)
    bad = ~np.isfinite(out)
    if bad.any():
        raise CaptureFormatError(f"{path}: {int(bad.sum())} of {out.size} values are NaN or infinite")
    return out


class ColoRadarRun:
    """One ColoRadar run on disk.

    *calib_dir* defaults to ``<run_dir>/../calib`` when it exists, else ``<run_dir>/calib``
    (None when neither does: then only the calibration-free readers work).  Everything read is
    checked against its layout, and errors name the file (and line for text).
    """

    def __init__(self, run_dir: str | os.PathLike, calib_dir: str | os.PathLike | None = None) -> None:
        # A directory that is not there is the caller's mistake (exit 2, as replay:// says).
        self.run_dir = _directory(run_dir, "run directory")
        self.name = os.path.basename(self.run_dir)
        if calib_dir is not None:
            calib_dir = _directory(calib_dir, "calibration directory")
            self.calib_dir: str | None = calib_dir
        else:
            beside = os.path.join(os.path.dirname(self.run_dir), "calib")
            inside = os.path.join(self.run_dir, "calib")
            self.calib_dir = next((d for d in (beside, inside) if os.path.isdir(d)), None)
            if self.calib_dir is None:
                log.info("%s: no calib/ beside or inside the run", self.run_dir)
        self._times: dict[str, np.ndarray] = {}
        self._time_lines: dict[str, np.ndarray] = {}  # the line of each time in its file
        self._files: dict[str, list[str]] = {}
        self._heatmap_cfg: dict[str, HeatmapConfig] = {}
        self._waveform_cfg: dict[str, WaveformConfig] = {}
        self._transforms: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._groundtruth: TumTrajectory | None = None

    def __repr__(self) -> str:
        return f"ColoRadarRun({self.run_dir!r}, calib_dir={self.calib_dir!r})"

    # -- streams -----------------------------------------------------------------------------

    @staticmethod
    def _layout(stream: str) -> _StreamLayout:
        try:
            return _LAYOUT[stream]
        except KeyError:
            raise UsageError(f"unknown ColoRadar stream {stream!r}; one of {', '.join(STREAMS)}") from None

    def _path(self, relative: str) -> str:
        return os.path.join(self.run_dir, *relative.split("/"))

    def has(self, stream: str) -> bool:
        """True when the run holds *stream* (its timestamps file is there)."""
        return os.path.isfile(self._path(self._layout(stream).timestamps))

    def timestamps(self, stream: str) -> np.ndarray:
        """Times (n,) s of *stream*'s records, in file order; read once."""
        if stream not in self._times:
            path = self._path(self._layout(stream).timestamps)
            table, lines = _read_table(path, 1, "one timestamp (s)")
            times = table[:, 0]
            back = np.flatnonzero(np.diff(times) < 0)
            if len(back):
                # Data files are matched to lines by position: a step back means a broken file.
                raise CaptureFormatError(f"{path}:{lines[back[0] + 1]}: time goes backwards "
                                         f"({float(times[back[0] + 1])!r} after {float(times[back[0]])!r})")
            times.setflags(write=False)  # shared by every caller: the cache must not change
            self._times[stream] = times
            self._time_lines[stream] = lines
        return self._times[stream]

    def _data_files(self, stream: str) -> list[str]:
        """Paths of *stream*'s numbered files in numeric order; the numbering has no gap."""
        if stream not in self._files:
            layout = self._layout(stream)
            folder = self._path(layout.data_dir)
            pattern = re.compile(re.escape(layout.prefix) + r"(\d+)\.bin")
            try:
                names = os.listdir(folder)
            except FileNotFoundError:
                raise CaptureFormatError(f"{folder}: no such folder (the run is incomplete)") from None
            except OSError as exc:
                raise CaptureError(f"cannot list {folder}: {exc.strerror or exc}") from None
            indices = sorted(int(m.group(1)) for name in names if (m := pattern.fullmatch(name)))
            if indices:
                expected = range(indices[0], indices[0] + len(indices))
                for want, have in zip(expected, indices):
                    if want != have:
                        missing = os.path.join(folder, f"{layout.prefix}{want}.bin")
                        raise CaptureFormatError(f"{missing}: missing (the numbering jumps from "
                                                 f"{want - 1} to {have})")
                log.debug("%s: %d files numbered from %d", folder, len(indices), indices[0])
            self._files[stream] = [os.path.join(folder, f"{layout.prefix}{i}.bin") for i in indices]
        return self._files[stream]

    def count(self, stream: str) -> int:
        """Number of records of *stream* (data files, or lines of the ground truth / IMU text
        file), checked equal to the number of its timestamps."""
        layout = self._layout(stream)
        times_path = self._path(layout.timestamps)
        n_times = len(self.timestamps(stream))
        if layout.data_dir is not None:
            n, what = len(self._data_files(stream)), f"files in {self._path(layout.data_dir)}"
        else:
            n, what = len(_read_lines(self._path(layout.text_file))), f"lines in {self._path(layout.text_file)}"
        if n != n_times:
            raise CaptureFormatError(f"{times_path} has {n_times} timestamps but there are {n} {what}")
        return n

    def _file(self, stream: str, i: int) -> str:
        n = self.count(stream)
        if not isinstance(i, (int, np.integer)) or not 0 <= i < n:
            raise UsageError(f"{stream}: frame {i!r} out of range (the run has {n})")
        return self._data_files(stream)[int(i)]

    @staticmethod
    def _read_bytes(path: str) -> bytes:
        try:
            with open(path, "rb") as fh:
                return fh.read()
        except FileNotFoundError:
            raise CaptureFormatError(f"{path}: no such file (the run is incomplete)") from None
        except OSError as exc:
            raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None

    def _record_layout(self, stream: str) -> tuple[np.dtype, tuple[int, ...] | None, str | None]:
        """What one file of *stream* holds: its cell type, and for fixed-size files their shape
        and the calib file that gives it (None, None: any number of points)."""
        if stream.endswith("/heatmaps"):
            sensor = stream.split("/")[0]
            return (HEATMAP_CELL, self.heatmap_config(sensor).shape[:3],
                    self.calib_path(sensor, "heatmap_cfg.txt"))
        if stream.endswith("/adc_samples"):
            sensor = stream.split("/")[0]
            return ADC_SAMPLE, self.waveform_config(sensor).adc_shape, self.calib_path(sensor, "waveform_cfg.txt")
        return (RADAR_POINT if stream == "single_chip/pointclouds" else LIDAR_POINT), None, None

    def _read_fixed(self, path: str, dtype: np.dtype, shape: tuple[int, ...], cfg_path: str) -> np.ndarray:
        """Records of *dtype* shaped *shape* from *path*; its size must match exactly."""
        data = self._read_bytes(path)
        check_file_size(path, len(data), dtype, shape, cfg_path)
        return np.frombuffer(data, dtype).reshape(shape)

    def _read_records(self, path: str, dtype: np.dtype) -> np.ndarray:
        """All records of *dtype* in *path* (n,); the size must be a whole number of them."""
        data = self._read_bytes(path)
        check_file_size(path, len(data), dtype)
        return np.frombuffer(data, dtype)

    def check(self, stream: str) -> int:
        """Check *stream* whole before any of it is played, so that a broken run is refused
        before anything is written: its timestamps parse and advance line after line, there is
        one file (or text line) per timestamp and at least one, and every file's size is what the
        calibration's heatmap or waveform config says (point clouds: whole points).  Sizes come
        from the directory, nothing is read.  Returns the number of records."""
        n = self.count(stream)
        layout = self._layout(stream)
        times_path = self._path(layout.timestamps)
        if n == 0:
            raise CaptureFormatError(f"{times_path}: the run's {stream} holds no records (no timestamps, "
                                     "no files): nothing to play")
        times, lines = self.timestamps(stream), self._time_lines[stream]
        same = np.flatnonzero(np.diff(times) <= 0)
        if len(same):
            # Two records at one time cannot both be a frame of the radar.
            raise CaptureFormatError(f"{times_path}:{lines[same[0] + 1]}: time does not advance "
                                     f"({float(times[same[0] + 1])!r} after {float(times[same[0]])!r})")
        if layout.data_dir is not None:
            dtype, shape, cfg_path = self._record_layout(stream)
            for path in self._data_files(stream):
                try:
                    size = os.stat(path).st_size
                except OSError as exc:
                    raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None
                check_file_size(path, size, dtype, shape, cfg_path)
        return n

    # -- radar data --------------------------------------------------------------------------

    def pointcloud(self, i: int) -> np.ndarray:
        """Single-chip point cloud *i* (0-based, time order): (n, 5) float32 x, y, z (m, sensor
        frame as stored: x forward, y left, z up), intensity (SNR dB), doppler (m/s)."""
        path = self._file("single_chip/pointclouds", i)
        return _finite(path, self._read_records(path, RADAR_POINT).view("<f4").reshape(-1, 5))

    def lidar_pointcloud(self, i: int) -> np.ndarray:
        """Lidar point cloud *i*: (n, 4) float32 x, y, z (m, lidar frame), intensity."""
        path = self._file("lidar", i)
        return _finite(path, self._read_records(path, LIDAR_POINT).view("<f4").reshape(-1, 4))

    @staticmethod
    def _radar(sensor: str) -> str:
        if sensor not in RADARS:
            raise UsageError(f"unknown ColoRadar radar {sensor!r}; one of {', '.join(RADARS)}")
        return sensor

    def calib_path(self, *parts: str) -> str:
        """The path of calib/<parts...>; raises when the run has no calibration folder."""
        if self.calib_dir is None:
            raise UsageError(f"{self.run_dir}: no calibration: neither "
                               f"{os.path.join(os.path.dirname(self.run_dir), 'calib')} nor "
                               f"{os.path.join(self.run_dir, 'calib')} exists (give calib_dir)")
        return os.path.join(self.calib_dir, *parts)

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
        from .coloradar_coupling import read_coupling

        path = self.calib_path(sensor, "coupling_calib.txt")
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
        return _finite(path, cells.view("<f4").reshape(cfg.shape))

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
            self.count("groundtruth")  # the poses and their timestamps pair up line by line
            times = self.timestamps("groundtruth")
            rows, lines = _read_table(path, 7, "'x y z qx qy qz qw'")
            norms = np.linalg.norm(rows[:, 3:], axis=1)
            if np.any(norms == 0):
                raise CaptureFormatError(f"{path}:{lines[np.argmax(norms == 0)]}: the quaternion is zero")
            self._groundtruth = TumTrajectory(np.array(times), rows[:, :3], rows[:, 3:] / norms[:, None],
                                              path, lines)
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
