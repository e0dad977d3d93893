"""Where a pipeline's results go: one small interface (:class:`Sink`), and the file outputs.

A sink is given every frame's :class:`FrameResult` (its point cloud, heatmap and new odometry,
whichever it has) in stream order, and is closed once at the end of the run with its
statistics.  A sink that sets :attr:`Sink.takes_raw` is given each frame as the source gave it
instead, before any processing (:meth:`Sink.write_raw`): what it keeps survives a frame whose
processing fails.  A new output is a new sink, not an edit of the loop.

- :class:`CaptureSink`: the raw frames, recorded to a new capture directory (before processing).
- :class:`TumSink`: the odometry, one TUM line per heatmap frame.
- :class:`OdometryJsonSink`: the odometry as JSON lines: each line exactly the odometry message
  radarodom publishes (``radarodom/odom`` v1, :mod:`radarodom.messages`), what
  ``radar-echo --json odom`` prints and ``radar-eval --odom`` reads.
- :class:`PointsCsvSink`: point clouds as CSV: ``frame, t, x, y, z, range, azimuth, elevation,
  velocity, snr_db`` (TI sensor frame, m, rad, m/s, dB), one row per point, rows of a frame
  together, flushed frame by frame.
- :class:`HeatmapSink`: a directory of ``NNNNNN_intensity.npy``, ``NNNNNN_static.npy``,
  ``NNNNNN_doppler.npy`` (float32, (n_range, n_azimuth): power over all Doppler bins, in the
  zero-Doppler bin, and the dominant radial velocity in m/s) per frame, and ``index.json`` with
  the axes (``range_m``, ``azimuth_rad``) and one entry per frame (``frame``, ``t``).

The Zenoh publisher's sink is :class:`radarodom.pipeline.zenoh_sink.PublisherSink`.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np

from .. import messages
from ..driver.recordings.capture_dir import CaptureWriter, write_json_atomically
from ..driver.sources import Frame, Source
from ..errors import CaptureError, CaptureExistsError, given_path, why_not_written
from ..estimator.odometry import OdometryState
from ..line_file import LineFile, write_file_all
from ..products import RangeAzimuth
from ..tum import TumWriter

if TYPE_CHECKING:
    from .stats import PipelineStats


@dataclass
class FrameResult:
    """One frame through the pipeline: the frame, its point cloud (POINT_DTYPE (n,)) and
    range-azimuth heatmap (either None when the frame has none or nothing needed it), and the
    odometry it produced (None for a velocity-only frame, or without an estimator)."""

    frame: Frame
    points: np.ndarray | None
    heatmap: RangeAzimuth | None
    state: OdometryState | None


class Sink:
    """Where results go.  Subclasses override :meth:`write` (or, with :attr:`takes_raw`,
    :meth:`write_raw`) and, when they hold resources, :meth:`close`."""

    #: Whether this sink takes each frame as the source gave it, before any processing
    #: (:meth:`write_raw`), instead of its results (:meth:`write`): a recorder, so that a frame
    #: is kept even when its processing raises.  Such sinks are closed first.
    takes_raw = False
    #: Whether this sink takes heatmaps: the DSP makes a frame's heatmap only when something
    #: needs it ...
    wants_heatmaps = False
    #: ... and whether it needs the full map (every cell's dominant Doppler), not the
    #: estimator's (the strongest cells' only).
    full_heatmaps = False

    def write(self, result: FrameResult, stats: PipelineStats) -> None:
        raise NotImplementedError

    def write_raw(self, frame: Frame, stats: PipelineStats) -> None:
        """(:attr:`takes_raw` sinks) One frame as it came, before the DSP or the estimator."""
        raise NotImplementedError

    def close(self, stats: PipelineStats) -> None:
        """The run ended (normally or not): flush and release."""


class CaptureSink(Sink):
    """The raw frames, recorded by *writer* (a new capture directory's :class:`CaptureWriter`,
    closed with the sink) as they come, before any processing: a frame whose processing raises
    is recorded, and nothing recorded is lost.  At the end, a live *source*'s count of the
    frames it dropped (``frames_dropped``) goes into capture.json as ``dropped_frames``: the
    recording lacks them."""

    takes_raw = True

    def __init__(self, writer: CaptureWriter, source: Source) -> None:
        self.writer = writer
        self.source = source

    def write_raw(self, frame: Frame, stats: PipelineStats) -> None:
        self.writer.write(frame.raw, frame.timestamp, frame.missing_bytes, frame.pose, cut_bytes=frame.cut_bytes)

    def close(self, stats: PipelineStats | None = None) -> None:
        try:
            dropped = self.source.describe().get("frames_dropped")
            if dropped is not None:  # a live stream
                self.writer.annotate(dropped_frames=dropped)
        finally:
            self.writer.close()


class TumSink(Sink):
    """The odometry as a TUM trajectory file (a new file)."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = given_path(path, CaptureError)
        self._writer = TumWriter(self.path)

    def write(self, result: FrameResult, stats: PipelineStats) -> None:
        st = result.state
        if st is not None:
            self._writer.write(st.t, st.x, st.y, st.yaw)

    def close(self, stats: PipelineStats) -> None:
        self._writer.close()
        remove_if_no_frame(self.path, stats)


def remove_if_no_frame(path: str, stats: PipelineStats | None) -> None:
    """Take back an output file of a run that wrote no whole frame (a source that failed to
    start, an output after it that could not be opened, a first frame the disk had no room for):
    it holds nothing whole, and left there it would block the same command's next run, as the
    recording's directory, removed then, would not."""
    if stats is not None and stats.frames_written == 0:
        with contextlib.suppress(OSError):
            os.remove(path)


class OdometryJsonSink(Sink):
    """The odometry as a new JSON-lines file (module docstring), written line by line."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = given_path(path, CaptureError)
        self._fh = LineFile(self.path)

    def write(self, result: FrameResult, stats: PipelineStats) -> None:
        if result.state is not None:
            self._fh.write(messages.odometry_json(result.state).decode("ascii") + "\n")

    def close(self, stats: PipelineStats | None = None) -> None:
        self._fh.close()
        remove_if_no_frame(self.path, stats)


POINT_COLUMNS = ("x", "y", "z", "range", "azimuth", "elevation", "velocity", "snr_db")


class PointsCsvSink(Sink):
    """Every point cloud as rows of a new CSV file (module docstring)."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = given_path(path, CaptureError)
        self._fh = LineFile(self.path)
        try:
            self._fh.write("frame,t," + ",".join(POINT_COLUMNS) + "\n")
        except CaptureError:  # an empty file left would block the same command's next run
            self._fh.close()
            with contextlib.suppress(OSError):
                os.remove(self.path)
            raise

    def write(self, result: FrameResult, stats: PipelineStats) -> None:
        if result.points is not None:
            self.write_points(result.frame.index, result.frame.timestamp, result.points)

    def write_points(self, frame: int, t: float, points: np.ndarray) -> None:
        if len(points):
            cols = np.column_stack([points[c].astype(float) for c in POINT_COLUMNS])
            prefix = f"{frame},{t:.6f},"
            self._fh.write("".join(prefix + ",".join(f"{v:.5g}" for v in row) + "\n" for row in cols))

    def close(self, stats: PipelineStats | None = None) -> None:
        self._fh.close()
        remove_if_no_frame(self.path, stats)


class HeatmapSink(Sink):
    """Every heatmap as .npy files in a new directory (module docstring)."""

    wants_heatmaps = full_heatmaps = True
    #: Each frame's arrays, ``NNNNNN_<name>.npy``, and the directory's index.
    FILES = ("intensity", "static", "doppler")
    INDEX = "index.json"

    @classmethod
    def owns(cls, name: str) -> bool:
        """Whether *name* is a file this writer makes in its directory (``--overwrite`` removes
        those, and only those)."""
        return (name in (cls.INDEX, cls.INDEX + ".tmp")
                or re.fullmatch(rf"\d{{6,}}_({'|'.join(cls.FILES)})\.npy", name) is not None)

    #: The index is written again when this much time has passed since it was last (s): a run
    #: killed outright leaves about this long of frames unlisted.  A long run's index grows, and
    #: once writing it takes longer than a tenth of this the wait grows to ten times the write, so
    #: rewriting it never takes more than a tenth of the run, on any disk.
    INDEX_EVERY_S = 1.0

    def __init__(self, directory: str | os.PathLike, *, clock: Callable[[], float] = time.monotonic) -> None:
        self.directory = given_path(directory, CaptureError, "directory path")
        self._clock = clock
        self._index_at = -math.inf
        self._index_every = self.INDEX_EVERY_S
        try:
            os.makedirs(self.directory, exist_ok=True)
        except OSError as exc:
            raise CaptureError(f"cannot create {self.directory}: {why_not_written(exc, self.directory)}") from None
        if os.path.exists(os.path.join(self.directory, self.INDEX)):
            raise CaptureExistsError(f"{self.directory} already holds heatmaps; choose a new directory")
        self._index: dict = {"format": "radarodom-heatmaps", "format_version": 1,
                             "files": list(self.FILES), "frames": []}

    def write(self, result: FrameResult, stats: PipelineStats) -> None:
        if result.heatmap is not None:
            self.write_heatmap(result.frame.index, result.frame.timestamp, result.heatmap)

    def write_heatmap(self, frame: int, t: float, heatmap: RangeAzimuth) -> None:
        if "range_m" not in self._index:
            self._index["range_m"] = heatmap.range_m.tolist()
            self._index["azimuth_rad"] = heatmap.azimuth_rad.tolist()
        paths = [os.path.join(self.directory, f"{frame:06d}_{name}.npy") for name in self.FILES]
        try:
            for name, path in zip(self.FILES, paths):
                _save_npy(path, getattr(heatmap, name if name != "doppler" else "doppler_mps").astype(np.float32))
        except OSError as exc:  # a full disk: the frame's files taken back, the frames before kept
            for path in paths:
                with contextlib.suppress(OSError):
                    os.remove(path)
            done = len(self._index["frames"])
            kept = {0: "no frame's heatmaps were written", 1: "the frame before is kept"}.get(
                done, f"the {done} frames before are kept")
            raise CaptureError(f"{self.directory}: writing frame {frame}'s heatmaps failed: "
                               f"{why_not_written(exc, self.directory)}; {kept}") from None
        self._index["frames"].append({"frame": frame, "t": t})
        began = self._clock()
        if began - self._index_at >= self._index_every:
            self._write_index()
            self._index_at = self._clock()
            self._index_every = max(self.INDEX_EVERY_S, 10 * (self._index_at - began))

    def _write_index(self) -> None:
        path = os.path.join(self.directory, self.INDEX)
        try:
            write_json_atomically(path, self._index)
        except OSError as exc:
            raise CaptureError(f"writing {path} failed: {exc.strerror or exc}") from None

    def close(self, stats: PipelineStats | None = None) -> None:
        self._write_index()


def _save_npy(path: str, array: np.ndarray) -> None:
    """*array* as a .npy file at *path*, through one write: a failure is the system's OSError
    (numpy's own writer says only how many bytes it wrote)."""
    buffer = io.BytesIO()
    np.save(buffer, array)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
    try:
        write_file_all(fd, buffer.getbuffer())
    finally:
        os.close(fd)
