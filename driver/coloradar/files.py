"""The files of a ColoRadar run and its calibration: the binary cells, where each stream lies,
the heatmap and waveform configs, and the text readers (every error names its file and line).

Split out of the reader (:mod:`.run`), which re-exports all of it; see there for the dataset's
layout (and :mod:`.streams` for how the streams' files are numbered and paired with their times).
"""

from __future__ import annotations

import logging
import math
import os
import re
import stat
from dataclasses import dataclass

import numpy as np

from ...errors import CaptureError, CaptureFormatError
from ...tum import parse_numbers, refuse_binary

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


def check_run_file(path: str) -> None:
    """Refuse a run's or calibration's file that is missing or is no regular file: a directory,
    or a pipe or device, which a read would wait on or never finish (a link to /dev/zero)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise CaptureFormatError(f"{path}: no such file (the run is incomplete)") from None
    except OSError as exc:
        raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(mode):
        raise CaptureFormatError(f"{path}: a directory, not a file (the run is damaged)")
    if not stat.S_ISREG(mode):
        raise CaptureFormatError(f"{path}: not a regular file (a pipe or a device; the run is damaged)")


def _read_lines(path: str) -> list[tuple[int, str]]:
    """(1-based line number, stripped text) of the non-blank lines of *path*."""
    check_run_file(path)
    try:
        # (utf-8-sig: a BOM, a Windows editor's, ignored, as the other text readers do)
        with open(path, encoding="utf-8-sig", errors="replace") as fh:
            lines = [(n, s) for n, line in enumerate(fh, start=1) if (s := line.strip())]
    except OSError as exc:
        raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None
    for n, text in lines:
        refuse_binary(path, n, text, " (the file is damaged, or another file is in its place)")
    return lines


def _read_table(path: str, columns: int, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Rows (n, columns) float64 of a whitespace-separated text file and their line numbers (n,)."""
    lines = _read_lines(path)
    rows = [parse_numbers(path, n, text, columns, what) for n, text in lines]
    return (np.array(rows, dtype=float).reshape(-1, columns),
            np.array([n for n, _ in lines], dtype=int))


#: The largest count (antennas, samples, chirps, bins) a calib file gives: far beyond any radar's
#: (1e300 chirps made a frame of a 300-digit size).
MAX_COUNT = 1_000_000


def _read_keyed(path: str, keys: tuple[str, ...], int_keys: tuple[str, ...],
                lines: dict[str, int] | None = None) -> dict:
    """``key value...`` lines (``#`` comments allowed): every key in *keys* must be there; each
    key's line number put in *lines* when given.

    Integer keys take one integer; other keys one float, or a list for the angle bins.
    Unknown keys are logged and skipped: the dataset's cfg files may grow.
    """
    out: dict = {}
    lines = {} if lines is None else lines
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
        lines[key] = lineno
        multi = key in ("azimuth_bins", "elevation_bins")
        values = parse_numbers(path, lineno, rest, None if multi else 1, f"{key} and its value(s)")
        if key in int_keys:
            if values[0] != int(values[0]) or not 0 < values[0] <= MAX_COUNT:
                raise CaptureFormatError(f"{path}:{lineno}: {key} must be a positive integer of at most {MAX_COUNT} "
                                         f"(a count of antennas, samples, chirps or bins), got {rest[:40]!r}")
            out[key] = int(values[0])
        else:
            out[key] = np.array(values) if multi else values[0]
    missing = [k for k in keys if k not in out]
    if missing:
        raise CaptureFormatError(f"{path}: missing {', '.join(missing)}")
    return out


def read_heatmap_config(path: str | os.PathLike) -> HeatmapConfig:
    """Parse a ``heatmap_cfg.txt``; the angle lists must match their counts, ascend and lie within
    +/- pi/2 rad."""
    path = os.fspath(path)
    at: dict[str, int] = {}
    v = _read_keyed(path, _HEATMAP_KEYS, _HEATMAP_INT_KEYS, at)
    for key, count in (("azimuth_bins", "num_azimuth_bins"), ("elevation_bins", "num_elevation_bins")):
        bins = v[key]
        if len(bins) != v[count]:
            raise CaptureFormatError(f"{path}:{at[key]}: {key} holds {len(bins)} angles but {count} (line "
                                     f"{at[count]}) is {v[count]}")
        if np.any(np.diff(bins) <= 0):
            raise CaptureFormatError(f"{path}:{at[key]}: {key} are not ascending")
        if np.any(np.abs(bins) > np.pi / 2 + 1e-9):  # a radar's view is within +/- 90 degrees
            raise CaptureFormatError(f"{path}:{at[key]}: {key} reach {np.max(np.abs(bins)):.4g} rad, beyond +/- pi/2 "
                                     "(90 degrees): the angles are radians within the radar's view")
        bins.setflags(write=False)  # the config is frozen: so are its arrays
    if not 0 < v["range_bin_width"] <= MAX_RANGE_BIN_M:
        raise CaptureFormatError(f"{path}:{at['range_bin_width']}: range_bin_width must be a positive number of "
                                 f"metres, at most {MAX_RANGE_BIN_M:g}, got {v['range_bin_width']:g}")
    return HeatmapConfig(**v)


#: A heatmap's range bin wider than this is no radar's, m (ColoRadar's are a few centimetres).
MAX_RANGE_BIN_M = 10.0


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
    if np.abs(t).max() > MAX_MOUNT_M:
        raise CaptureFormatError(f"{path}:{lines[0][0]}: a sensor {np.abs(t).max():g} m from its base is no "
                                 f"mounting (at most {MAX_MOUNT_M:g} m; metres expected)")
    q = np.array(parse_numbers(path, lines[1][0], lines[1][1], 4, "'qx qy qz qw'"))
    return t, unit_quaternions(q[None], path, np.array([lines[1][0]]))[0]


#: A sensor farther than this from its base's origin is no mounting, m.
MAX_MOUNT_M = 1000.0
#: A ground-truth position farther than this from its frame's origin is no place on Earth, m.
MAX_POSITION_M = 1e8


def unit_quaternions(q: np.ndarray, path: str, lines: np.ndarray) -> np.ndarray:
    """Quaternions (n, 4) scaled to unit length (their largest part first, so that neither 1e300 nor
    1e-300 overflows or underflows), *path*:*lines* (n,) named for one that is zero."""
    largest = np.abs(q).max(axis=1)
    if np.any(largest == 0):
        raise CaptureFormatError(f"{path}:{lines[np.argmax(largest == 0)]}: the quaternion is zero")
    q = q / largest[:, None]
    return q / np.linalg.norm(q, axis=1)[:, None]


def check_file_size(path: str, size: int, dtype: np.dtype, shape: tuple[int, ...] | None = None,
                    cfg_path: str | None = None) -> None:
    """One data file's size against what it must hold: exactly *shape* cells of *dtype* (the
    calib file *cfg_path* says so), or with no *shape* a whole number of *dtype* points.  The one
    check of both the up-front :meth:`.ColoRadarRun.check` and every read."""
    if shape is not None:
        expected = math.prod(shape) * dtype.itemsize
        if size != expected:
            raise CaptureFormatError(f"{path}: {size} bytes, expected {expected} for shape {shape} "
                                     f"of {dtype.itemsize}-byte cells ({cfg_path})")
    elif size % dtype.itemsize:
        raise CaptureFormatError(f"{path}: {size} bytes is not a whole number of {dtype.itemsize}-byte points")


def finite_values(path: str, values: np.ndarray) -> np.ndarray:
    """*values* (little-endian float32 as read) as native float32; a NaN or an infinity is a
    broken file: every consumer would have to guess what it means.  Found when the file is read
    (a run's data is too large to read twice), the file named."""
    out = values.astype(np.float32)
    bad = ~np.isfinite(out)
    if bad.any():
        raise CaptureFormatError(f"{path}: {int(bad.sum())} of {out.size} values are NaN or infinite")
    return out
