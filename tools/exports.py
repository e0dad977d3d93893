"""Per-frame exports of ``radar-capture``: point clouds as CSV, heatmaps as .npy.

Points CSV columns: ``frame, t, x, y, z, range, azimuth, elevation, velocity,
snr_db`` (TI sensor frame, m, rad, m/s, dB), one row per point, rows of a
frame together, flushed frame by frame.

Heatmap directory: ``NNNNNN_intensity.npy``, ``NNNNNN_static.npy``,
``NNNNNN_doppler.npy`` (float32, (n_range, n_azimuth): power over all Doppler
bins, in the zero-Doppler bin, and the dominant radial velocity in m/s) per
frame, and ``index.json`` with the axes (``range_m``, ``azimuth_rad``) and
one entry per frame (``frame``, ``t``).
"""

from __future__ import annotations

import os

import numpy as np

from ..driver.capture_dir import write_json_atomically
from ..dsp.heatmap import RangeAzimuth
from ..errors import CaptureError, CaptureExistsError

POINT_COLUMNS = ("x", "y", "z", "range", "azimuth", "elevation", "velocity", "snr_db")


class PointsCsvWriter:
    def __init__(self, path: str | os.PathLike) -> None:
        try:
            self._fh = open(path, "x", encoding="ascii", newline="\n")
        except FileExistsError:
            raise CaptureExistsError(f"{os.fspath(path)} already exists; choose a new file") from None
        except OSError as exc:
            raise CaptureError(f"cannot create {os.fspath(path)}: {exc.strerror or exc}") from None
        self._fh.write("frame,t," + ",".join(POINT_COLUMNS) + "\n")
        self._fh.flush()

    def write(self, frame: int, t: float, points: np.ndarray) -> None:
        if len(points):
            cols = np.column_stack([points[c].astype(float) for c in POINT_COLUMNS])
            prefix = f"{frame},{t:.6f},"
            self._fh.write("".join(prefix + ",".join(f"{v:.5g}" for v in row) + "\n" for row in cols))
        self._fh.flush()

    def close(self) -> None:
        self._fh.close()


class HeatmapWriter:
    def __init__(self, directory: str | os.PathLike) -> None:
        self.directory = os.fspath(directory)
        try:
            os.makedirs(self.directory, exist_ok=True)
        except OSError as exc:
            raise CaptureError(f"cannot create {self.directory}: {exc.strerror or exc}") from None
        if os.path.exists(os.path.join(self.directory, "index.json")):
            raise CaptureExistsError(f"{self.directory} already holds heatmaps; choose a new directory")
        self._index: dict = {"format": "radarodom-heatmaps", "format_version": 1,
                             "files": ["intensity", "static", "doppler"], "frames": []}

    def write(self, frame: int, t: float, heatmap: RangeAzimuth) -> None:
        if "range_m" not in self._index:
            self._index["range_m"] = heatmap.range_m.tolist()
            self._index["azimuth_rad"] = heatmap.azimuth_rad.tolist()
        for name in ("intensity", "static", "doppler"):
            arr = getattr(heatmap, name if name != "doppler" else "doppler_mps")
            np.save(os.path.join(self.directory, f"{frame:06d}_{name}.npy"), arr.astype(np.float32))
        self._index["frames"].append({"frame": frame, "t": t})
        if len(self._index["frames"]) % 50 == 1:
            self._write_index()

    def _write_index(self) -> None:
        write_json_atomically(os.path.join(self.directory, "index.json"), self._index)

    def close(self) -> None:
        self._write_index()
