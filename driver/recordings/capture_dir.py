"""Capture directories: what ``--record`` writes and ``replay://`` reads.

Layout (docs/conventions.md)::

    DIR/radar.cfg        the TI CLI configuration that produced the data
    DIR/adc_data.bin     frames back to back, the DCA1000 raw stream bytes
    DIR/timestamps.txt   one line per frame: the time (s) of its first chirp
    DIR/capture.json     metadata (schema below)
    DIR/groundtruth.tum  optional: body-frame pose per frame (TUM)

timestamps.txt: one plain decimal number per line (digits, optional sign, point and
exponent: no ``0_5``, ``nan``, ``inf`` or hex), finite, at most 1e10 s in magnitude,
strictly increasing, one line per frame of adc_data.bin.

capture.json, format version 1: a JSON object of at most 1 MiB plus 128 bytes per frame
of adc_data.bin, nested at most 32 deep, every number finite.  Fields (others are kept and
ignored):

    format             string, required: "radarodom-capture"
    format_version     integer, required: 1 (a larger one is refused: a newer radarodom wrote it)
    frame_bytes        integer >= 1, required: bytes per frame; equals the cfg's frame size
    frame_count        integer >= 0, required: frames recorded when the file was last written
    closed             boolean, required: true once the writer closed the capture
    incomplete_frames  list, optional (default empty): one object per frame with lost bytes,
                       in increasing frame order:
        frame              integer, 0 <= frame < frame_count
        missing_bytes      integer, 1 <= missing_bytes <= frame_bytes (zero-filled in the data)
        cut_bytes          integer, optional, 0 <= cut_bytes <= missing_bytes: of them, those
                           never sent because the stream stopped
    lost_bytes         integer, optional: the sum of missing_bytes over incomplete_frames
    cut_bytes          integer, optional: the sum of cut_bytes over incomplete_frames
    software, source, start_time   strings, optional
    start_time_unix    number, optional: 0 to 1e10 (s)
    first_timestamp, last_timestamp   null or a number within +-1e10 (s), optional
    dropped_frames     integer >= 0, optional: frames a live stream dropped (not recorded)
    simulator          object, optional: the simulated scene, seed and board (a sim://
                       recording's; other fields kept and ignored):
        scene, board       strings, optional (a board not built in is taken as unknown
                           without board_calibration: never read from a file)
        seed               integer >= 0, optional
        noise_seed         integer >= 0, optional: the thermal noise's own seed, where not seed's
        board_calibration  object, optional: range_bias_m (a number, m) and coefficients
                           (12 [re, im] pairs, TX1 RX1 to TX3 RX4, each part within -1..1,
                           not both 0), the board's exact compRangeBiasAndRxChanPhase

Agreement: a closed capture holds exactly frame_count frames in adc_data.bin (no byte more)
and as many timestamp lines.  A capture that was not closed (its process died) plays its
whole frames with a warning: the data may end in a cut-off frame, the last frame may lack
its timestamp line, and frame_count may lag behind, but never exceed, the frames and the
timestamps.  Anything else is refused (:class:`~radarodom.errors.CaptureFormatError`) with
what disagrees.  Without capture.json (a directory put together by hand) the data's whole
frames are played, each needing its timestamp line if timestamps.txt is there.

This module holds the reader, :class:`CaptureDirectory` (and :func:`missing_data_message`,
why a directory without adc_data.bin cannot be played).  The writer, :class:`CaptureWriter`,
and its crash safety (every frame handed to the kernel before the next, capture.json replaced
atomically, a capture of no frame removed) are in :mod:`.capture_writer`; the file names
are defined in :mod:`.capture_check`.  Both are re-exported here, so every name callers
import from this module is still found here.
"""

from __future__ import annotations

import logging
import os
from typing import Any

import numpy as np

from ...cfg import RadarConfig
from ...errors import CaptureError, CaptureFormatError, ConfigError, given_path
from ...rawframe import RawLayout
from ...tum import read_tum
from . import capture_check
from .capture_check import (  # noqa: F401 (FORMAT_NAME, FORMAT_VERSION re-exported: they were imported here)
    ADC_DATA, FORMAT_NAME, FORMAT_VERSION, GROUNDTRUTH, METADATA, RADAR_CFG, TIMESTAMPS)
from .capture_writer import (  # noqa: F401 (re-exported: they were defined here)
    CaptureWriter,
    remove_capture_files,
    write_json_atomically,
)
from .recording_dir import metadata_format

log = logging.getLogger(__name__)


def missing_data_message(directory: str) -> str:
    """Why *directory* cannot be played for want of its frame data (raised instead, as
    :class:`CaptureFormatError`, when the demo recording's stream file is there but no file)."""
    present = [name for name in (RADAR_CFG, TIMESTAMPS, METADATA) if os.path.exists(os.path.join(directory, name))]
    if metadata_format(directory) == capture_check.TIDEMO_FORMAT_NAME:  # its stream file is the one missing
        from ..sources import REPLAY_FORMAT_FILES
        stream = REPLAY_FORMAT_FILES["tidemo"]
        capture_check.check_parts_are_files(directory, (stream,), "a demo recording's")  # a directory there
        return (f"{directory}: no {stream}: the demo UART recording's stream is missing "
                f"(the directory holds {', '.join(present)})")
    if present:
        return (f"{directory}: no {ADC_DATA}: the capture's frame data is missing "
                f"(the directory holds {', '.join(present)})")
    return f"{directory}: no {ADC_DATA}: not a capture directory"


class CaptureDirectory:
    """A capture directory opened for reading.

    Everything is checked on opening (:mod:`.capture_check`), before a frame is played;
    frames are then read through a memory map, so opening is cheap for any size.
    """

    def __init__(self, directory: str | os.PathLike, config: RadarConfig | None = None) -> None:
        self.directory = given_path(directory, CaptureError, "directory path")
        if not os.path.isdir(self.directory):
            raise CaptureError(f"{self.directory}: no such capture directory")
        cfg_path = os.path.join(self.directory, RADAR_CFG)
        data_path = os.path.join(self.directory, ADC_DATA)
        if not os.path.exists(data_path):
            raise CaptureFormatError(missing_data_message(self.directory))
        capture_check.check_parts_are_files(self.directory, (ADC_DATA, RADAR_CFG, METADATA, TIMESTAMPS, GROUNDTRUTH),
                                            "a capture's")
        if config is None:
            if not os.path.exists(cfg_path):
                raise ConfigError(f"missing {RADAR_CFG}: give the radar configuration with --cfg "
                                  "(open_source(url, config) in Python)",
                                  path=self.directory)
            config = RadarConfig.from_file(cfg_path)
        elif os.path.exists(cfg_path):
            recorded = RadarConfig.from_file(cfg_path)
            if recorded.frame_bytes != config.frame_bytes or recorded.cube_shape != config.cube_shape:
                log.warning("%s: the given configuration (%s) differs from the recorded %s; using "
                            "the given one", self.directory, config.path, RADAR_CFG)
        self.config = config
        self.layout = RawLayout.from_config(config)
        cfg_name = config.path or RADAR_CFG
        try:
            size = os.path.getsize(data_path)
        except OSError as exc:
            raise CaptureError(f"cannot read {data_path}: {exc.strerror or exc}") from None
        fb = config.frame_bytes
        meta = capture_check.read_metadata(os.path.join(self.directory, METADATA), size // fb)
        if meta is None:
            log.info("%s: no %s; assuming every frame complete", self.directory, METADATA)
        capture_check.check_frame_bytes(self.directory, meta, fb, cfg_name)
        self.metadata: dict[str, Any] = meta or {}
        capture_check.check_data_length(self.directory, size, fb, meta)
        ts_path = os.path.join(self.directory, TIMESTAMPS)
        stamps = (capture_check.read_timestamps(ts_path, size // fb, closed=bool(meta and meta["closed"]))
                  if os.path.exists(ts_path) else None)
        whole = capture_check.frame_count(self.directory, size, fb, cfg_name, meta, stamps)
        self.timestamps = capture_check.timestamps_for(self.directory, stamps, whole, config.frame_period_s)
        self.num_frames = whole
        first = self.metadata.get("first_timestamp")
        if stamps is not None and len(stamps) and first is not None and abs(float(stamps[0]) - first) > 1e-6:
            log.warning("%s: %s says the first frame is at %.6f s, %s at %.6f s: one was edited; the frames play "
                        "at %s's times", self.directory, METADATA, first, TIMESTAMPS, float(stamps[0]), TIMESTAMPS)
        self._data = (np.memmap(data_path, dtype=np.uint8, mode="r", shape=(whole * fb,))
                      if whole else np.empty(0, np.uint8))
        listed = self.metadata.get("incomplete_frames", [])
        self._missing = {e["frame"]: e["missing_bytes"] for e in listed}
        self._cut = {e["frame"]: e["cut_bytes"] for e in listed if e.get("cut_bytes")}
        gt_path = os.path.join(self.directory, GROUNDTRUTH)
        self.groundtruth = read_tum(gt_path) if os.path.exists(gt_path) else None
        self._pose_row = self._match_poses()

    def raw(self, i: int) -> np.ndarray:
        """Frame *i*'s bytes, a read-only uint8 view of ``frame_bytes``."""
        if not 0 <= i < self.num_frames:
            raise IndexError(f"frame {i} of {self.num_frames}")
        fb = self.config.frame_bytes
        return self._data[i * fb: (i + 1) * fb]

    def missing_bytes(self, i: int) -> int:
        return self._missing.get(i, 0)

    def cut_bytes(self, i: int) -> int:
        """Of frame *i*'s missing bytes, those cut when its live stream stopped."""
        return self._cut.get(i, 0)

    def _match_poses(self) -> np.ndarray:
        """Row of groundtruth.tum for each frame (by time), -1 where none."""
        rows = np.full(self.num_frames, -1)
        gt = self.groundtruth
        if gt is not None and not len(gt.times):
            log.warning("%s: %s holds no pose: the frames are played without a ground truth", self.directory,
                        GROUNDTRUTH)
        if gt is None or not len(gt.times) or not self.num_frames:
            return rows
        order = np.argsort(gt.times, kind="stable")
        times = gt.times[order]
        j = np.clip(np.searchsorted(times, self.timestamps), 1, len(times)) - 1
        # The nearest of the two neighbours, within a microsecond (TUM files keep 9 decimals).
        j = np.where((j + 1 < len(times)) & (np.abs(times[np.minimum(j + 1, len(times) - 1)] - self.timestamps)
                                               < np.abs(times[j] - self.timestamps)), j + 1, j)
        hit = np.abs(times[j] - self.timestamps) <= 1e-6
        rows[hit] = order[j[hit]]
        if not hit.all():
            log.warning("%s: %s has no pose for %d of %d frames", self.directory, GROUNDTRUTH,
                        int((~hit).sum()), self.num_frames)
        return rows

    def pose(self, i: int) -> tuple[float, ...] | None:
        """Ground-truth pose of frame *i* (the groundtruth.tum line with its timestamp), or None."""
        row = self._pose_row[i] if 0 <= i < self.num_frames else -1
        return self.groundtruth.pose(row) if row >= 0 else None

    def __len__(self) -> int:
        return self.num_frames
