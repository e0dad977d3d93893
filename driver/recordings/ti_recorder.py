"""Recordings made by TI's tools: the DCA1000 CLI's ``<prefix>_Raw_<n>.bin``
series (split at 1 GiB, IQ-reordered by default) and mmWave Studio's single
``adc_data.bin``.  They carry no configuration and no timestamps: the cfg is
given separately and frame times follow from its frame period.
"""

from __future__ import annotations

import logging
import os
import re

import numpy as np

from ...cfg import RadarConfig
from ...errors import CaptureError, CaptureFormatError, given_path
from ...rawframe import RawLayout

log = logging.getLogger(__name__)

SERIES_PATTERN = re.compile(r"^(?P<prefix>.*_Raw_)(?P<n>\d+)\.bin$")
#: What a directory holding neither kind of recording is told.
NO_RECORDING = ("holds no recording: neither a capture (adc_data.bin with capture.json) nor a TI recording "
                "(*_Raw_<n>.bin)")


def series_files(path: str) -> list[str]:
    """The files of the recording *path* names, in stream order.

    *path* is one file of a ``*_Raw_<n>.bin`` series (the whole series is
    used, from its lowest number), any other single file, or a directory
    holding exactly one such series.
    """
    if os.path.isdir(path):
        heads = sorted(f for f in os.listdir(path) if SERIES_PATTERN.match(f))
        prefixes = {SERIES_PATTERN.match(f)["prefix"] for f in heads}
        if len(prefixes) != 1:
            if not prefixes:
                raise CaptureFormatError(f"{path}: {NO_RECORDING}")
            raise CaptureFormatError(f"{path}: expected one *_Raw_<n>.bin series, found {', '.join(sorted(prefixes))}")
        path = os.path.join(path, heads[0])
    if os.path.isdir(path):
        raise CaptureFormatError(f"{path}: is a directory: a TI recording's {os.path.basename(path)} is a file")
    if not os.path.isfile(path):
        raise CaptureError(f"{path}: no such file")
    match = SERIES_PATTERN.match(os.path.basename(path))
    if not match:
        return [path]
    folder = os.path.dirname(path)
    numbered = {}
    for f in os.listdir(folder or "."):
        m = SERIES_PATTERN.match(f)
        if m and m["prefix"] == match["prefix"]:
            numbered[int(m["n"])] = os.path.join(folder, f)
    first = min(numbered)
    if first != 0:  # TI's recorder numbers from 0, and each file goes on where the one before ended
        missing = os.path.join(folder, f"{match['prefix']}0.bin")
        raise CaptureFormatError(f"{numbered[first]}: the series starts at number {first}: {missing} is missing, "
                                 "and without the stream's start its frames cannot be found (each file goes on "
                                 "where the one before ended); put it back beside the others")
    files = []
    while first + len(files) in numbered:
        files.append(numbered[first + len(files)])
    if len(files) < len(numbered):
        log.warning("%s: the series has a gap after %s; later files are ignored", folder, files[-1])
    return files


class TiRecording:
    """A TI recorder file series read as whole frames (same interface as
    :class:`~radarodom.driver.recordings.capture_dir.CaptureDirectory`)."""

    def __init__(self, path: str | os.PathLike, config: RadarConfig, *, reordered: bool = True) -> None:
        self.directory = given_path(path, CaptureError)
        self.config = config
        self.files = series_files(self.directory)
        self.layout = RawLayout.from_config(config, iq_interleaved=reordered)
        self._maps = [np.memmap(f, dtype=np.uint8, mode="r") for f in self.files if os.path.getsize(f)]
        self._starts = np.cumsum([0] + [len(m) for m in self._maps])
        total = int(self._starts[-1])
        whole, tail = divmod(total, config.frame_bytes)
        if whole == 0:
            raise CaptureFormatError(f"{self.directory}: {total} bytes, less than one "
                                     f"{config.frame_bytes}-byte frame of {config.path}")
        if tail:
            log.warning("%s: %d bytes of a cut-off frame after frame %d are ignored",
                        self.directory, tail, whole - 1)
        self.num_frames = whole
        self.timestamps = np.arange(whole) * config.frame_period_s
        self.groundtruth = None
        self.metadata: dict = {"source": f"TI recorder: {', '.join(map(os.path.basename, self.files))}"}

    def raw(self, i: int) -> np.ndarray:
        """Frame *i*'s bytes (a view when the frame lies within one file)."""
        if not 0 <= i < self.num_frames:
            raise IndexError(f"frame {i} of {self.num_frames}")
        fb = self.config.frame_bytes
        begin, end = i * fb, (i + 1) * fb
        k = int(np.searchsorted(self._starts, begin, side="right")) - 1
        if end <= self._starts[k + 1]:
            return self._maps[k][begin - self._starts[k]: end - self._starts[k]]
        parts = []
        while begin < end:  # the frame spans the 1 GiB split
            stop = min(end, int(self._starts[k + 1]))
            parts.append(self._maps[k][begin - self._starts[k]: stop - self._starts[k]])
            begin, k = stop, k + 1
        return np.concatenate(parts)

    def cut_bytes(self, i: int) -> int:
        return 0

    def missing_bytes(self, i: int) -> int:
        return 0

    def pose(self, i: int):
        return None

    def __len__(self) -> int:
        return self.num_frames
