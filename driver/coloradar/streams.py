"""The streams of a ColoRadar run on disk: which numbered files each stream has, its timestamps,
the number of records, the up-front :meth:`~RunStreams.check` of a whole stream, and the raw read
of one file checked against its size.

Binary files are raw, headerless and little-endian (:data:`.files.ADC_SAMPLE`,
:data:`.files.HEATMAP_CELL`, :data:`.files.RADAR_POINT`, :data:`.files.LIDAR_POINT`).  Line ``k``
of a ``timestamps.txt`` (seconds) belongs to the ``k``-th data file in numeric order; numbering
starts at 0 in some downloads and at 1 in others, so the lowest index present is taken as the
first.

Split out of :mod:`.run` so that the run object there keeps what a run is (its calibration, the
radars' data, the poses) and this module how its files are found, counted and read.
:class:`RunStreams` is a mixin that :class:`.run.ColoRadarRun` inherits: it uses the attributes
``ColoRadarRun.__init__`` sets (``run_dir`` and the caches ``_times``, ``_time_lines``,
``_files``), and for the size of a heatmap or ADC file the run's :meth:`heatmap_config`,
:meth:`waveform_config` and :meth:`calib_path`.  It does not import :mod:`.run`.
"""

from __future__ import annotations

import logging
import os
import re
import stat

import numpy as np

from ...errors import CaptureError, CaptureFormatError, UsageError
from ..sources import TIMESTAMP_LIMIT_S
from .files import (
    _LAYOUT,
    ADC_SAMPLE,
    HEATMAP_CELL,
    LIDAR_POINT,
    RADAR_POINT,
    STREAMS,
    _read_lines,
    _read_table,
    _StreamLayout,
    check_file_size,
    check_run_file,
)

log = logging.getLogger(__name__)


class RunStreams:
    """The streams of one run (a mixin of :class:`.run.ColoRadarRun`): the paths of their files,
    their timestamps and record counts, the check of a whole stream, and raw reads."""

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
        return os.path.isfile(self.timestamps_file(stream))

    def timestamps_file(self, stream: str) -> str:
        """The path of *stream*'s timestamps.txt (there or not)."""
        return self._path(self._layout(stream).timestamps)

    def timestamps(self, stream: str) -> np.ndarray:
        """Times (n,) s of *stream*'s records, in file order; read once."""
        if stream not in self._times:
            path = self._path(self._layout(stream).timestamps)
            table, lines = _read_table(path, 1, "one timestamp (s)")
            times = table[:, 0]
            far = np.flatnonzero(np.abs(times) > TIMESTAMP_LIMIT_S)
            if len(far):  # (past the year 2286: no time of a recording; the estimator's steps overflowed)
                raise CaptureFormatError(f"{path}:{lines[far[0]]}: timestamp {float(times[far[0]])!r} s is out of "
                                         f"range (at most {TIMESTAMP_LIMIT_S:.0e} s from 1970)")
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
            except NotADirectoryError:
                raise CaptureFormatError(f"{folder}: a file, not a folder (the run is damaged)") from None
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
            shown = int(i) if isinstance(i, (int, np.integer)) else repr(i)  # no numpy repr
            raise UsageError(f"{stream}: frame {shown} out of range (the run has {n})")
        return self._data_files(stream)[int(i)]

    @staticmethod
    def _read_bytes(path: str) -> bytes:
        check_run_file(path)
        try:
            with open(path, "rb") as fh:
                return fh.read()
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
                    info = os.stat(path)
                except OSError as exc:
                    raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None
                if not stat.S_ISREG(info.st_mode):  # a directory's size says nothing of frames
                    raise CaptureFormatError(f"{path}: not a file (a record of the run is a file of its data)")
                check_file_size(path, info.st_size, dtype, shape, cfg_path)
        return n
