"""``replay://`` : recorded frames played back as a live stream.

``replay://PATH?rate=1.0&loop=1&start=0&frames=N``

- PATH: a capture directory, or TI recorder output (a ``*_Raw_<n>.bin`` file,
  a folder with one such series, or mmWave Studio's ``adc_data.bin``) with
  the cfg given separately.
- ``rate``: 1.0 plays in real time from the timestamps, 2 twice as fast,
  ``max`` as fast as the consumer takes frames.
- ``loop``: how many times to play the selection (0: until stopped).
- ``start``: first frame, as a frame number (``start=20``) or seconds from the
  first frame (``start=2.5s``).
- ``frames``: how many frames to play from ``start`` (default: to the end).
- ``reordered``: TI recorder files only: 1 when the recorder rewrote the
  samples to IQ order (the default for ``*_Raw_<n>.bin``, TI's
  ``reorderEnable``), 0 for the raw stream (the default for other files, such
  as mmWave Studio's ``adc_data.bin``).  I/Q order follows the cfg's
  ``adcbufCfg`` SampleSwap.
"""

from __future__ import annotations

import logging
import os
from typing import Iterator

import numpy as np

from ...calibration import ChannelCalibration
from ...cfg import RadarConfig
from ...errors import CaptureFormatError, ConfigError, SourceError, quoted
from ...plain_numbers import plain_float
from .capture_dir import ADC_DATA, METADATA, RADAR_CFG, TIMESTAMPS, CaptureDirectory, missing_data_message
from ..sim.board import BUILTIN_BOARDS, load_board
from ..sources import Frame, Pacer, Source
from ..url_options import RATE_EXPECTED, UrlOptions, at_least, parse_rate
from .ti_recorder import NO_RECORDING, SERIES_PATTERN as _TI_SERIES, TiRecording

log = logging.getLogger(__name__)

def _start(text: str) -> tuple[str, float]:
    if text.endswith("s"):
        value = plain_float(text[:-1])
        kind = "seconds"
    else:
        value = int(text) if text.isascii() and text.isdigit() else None
        kind = "frame"
    if value is None or not 0 <= value < float("inf"):
        raise ValueError(text)
    return kind, value


def _flag(text: str) -> bool:
    if text not in ("0", "1"):
        raise ValueError(text)
    return text == "1"


class ReplaySource(Source):
    """Plays the frames of a capture directory or TI recording."""

    def __init__(self, store, *, rate: float = 1.0, loop: int = 1, start: int = 0,
                 frames: int | None = None) -> None:
        super().__init__()
        if store.num_frames == 0:
            raise CaptureFormatError(f"{store.directory}: holds no whole frame")
        self.store = store
        self.config: RadarConfig = store.config
        self.calibrated = _board_fits(getattr(store, "metadata", {}), store.config)
        self.rate = rate
        self.loop = loop
        if start >= store.num_frames:
            raise SourceError(f"start={start} is past the recording's last frame ({store.num_frames} frames, "
                              f"numbered from 0)")
        self.first = start
        self.count = store.num_frames - start if frames is None else min(frames, store.num_frames - start)
        self.frames_played = 0

    def _frames(self) -> Iterator[Frame]:
        stamps = self.store.timestamps[self.first: self.first + self.count]
        span = float(stamps[-1] - stamps[0]) + self.config.frame_period_s
        pacer = Pacer(self.rate, self)
        passes = 0
        while not self.stop_requested and (self.loop == 0 or passes < self.loop):
            for j in range(self.count):
                if self.stop_requested:
                    return
                i = self.first + j
                # Later passes continue the clock, so timestamps never go back.
                timestamp = float(stamps[j]) + passes * span
                pacer.wait(timestamp - float(stamps[0]))
                if self.stop_requested:
                    return
                yield Frame(
                    index=passes * self.count + j,
                    timestamp=timestamp,
                    raw=self.store.raw(i),
                    layout=self.store.layout,
                    missing_bytes=self.store.missing_bytes(i),
                    pose=self.store.pose(i),
                    cut_bytes=self.store.cut_bytes(i),
                )
                self.frames_played += 1
            passes += 1

    def time_span(self) -> tuple[float, float, str]:
        stamps = self.store.timestamps[self.first: self.first + self.count]
        path = os.path.join(self.store.directory, TIMESTAMPS)
        return float(stamps[0]), float(stamps[-1]), path if os.path.isfile(path) else self.store.directory

    def groundtruth(self):
        """The recording's groundtruth.tum (TI recorder files have none)."""
        return getattr(self.store, "groundtruth", None)

    def recording_metadata(self) -> dict:
        """The simulated board a recording of a simulation was made on (its ``simulator`` block),
        so that a recording of this replay is checked against the same board (:func:`_board_fits`)."""
        sim = getattr(self.store, "metadata", {}).get("simulator")
        return {} if sim is None else {"simulator": sim}

    def describe(self) -> dict:
        return {"url": self.url, "path": self.store.directory, "frames": self.count,
                "rate": "max" if self.rate == float("inf") else self.rate, "loop": self.loop}


def _board_fits(metadata: dict, config: RadarConfig) -> bool | None:
    """Whether *config*'s channel calibration fits the simulated board a recording was made on
    (its metadata, checked by :func:`.capture_check.check_metadata`, names it); None for a real
    board's recording, or a board it cannot tell."""
    sim = metadata.get("simulator")
    if not isinstance(sim, dict):
        return None
    try:
        if "board_calibration" in sim:
            truth = ChannelCalibration.from_description(sim["board_calibration"])
        else:  # recorded before the board's calibration was kept: a built-in board by its name
            board = sim.get("board", "ideal")
            if board not in BUILTIN_BOARDS:  # a board file's name, never a path a recording may make us read
                raise ConfigError(f"{quoted(board)} is no built-in board ({', '.join(BUILTIN_BOARDS)})")
            truth = load_board(board).calibration()
        return ChannelCalibration.from_config(config).matches(truth)
    except ConfigError as exc:
        log.info("the simulated board of the recording is unknown (%s): its channel calibration is taken "
                 "from the cfg alone", exc)
        return None


def _capture_without_data(path: str) -> bool:
    """Whether directory *path* holds a capture's files but its adc_data.bin (and no TI recording)."""
    names = os.listdir(path)
    return (any(name in names for name in (RADAR_CFG, METADATA, TIMESTAMPS))
            and not any(_TI_SERIES.match(name) for name in names))


def open_replay(path: str, options: UrlOptions, config: RadarConfig | None) -> ReplaySource:
    rate = options.take("rate", parse_rate, 1.0, RATE_EXPECTED)
    loop = options.take("loop", at_least(0), 1, "a number of passes (0: forever)")
    start = options.take("start", _start, ("frame", 0), "a frame number or seconds like 2.5s")
    frames = options.take("frames", at_least(1), None, "a whole number of frames >= 1")
    reordered = options.take("reordered", _flag, None, "0 or 1 (TI recorder files)")
    options.finish()
    if not path:
        raise SourceError(f"{options.url}: no path: use replay://DIR")
    path = os.path.expanduser(path)
    if not os.path.exists(path):
        raise SourceError(f"{options.url}: {path}: no such file or directory")

    is_capture_dir = os.path.isdir(path) and os.path.exists(os.path.join(path, ADC_DATA))
    if os.path.isdir(path) and not is_capture_dir and _capture_without_data(path):
        raise CaptureFormatError(missing_data_message(path))
    if is_capture_dir:
        if reordered is not None:
            raise SourceError(f"{options.url}: reordered= applies to TI recorder files, not to a "
                              f"capture directory")
        store = CaptureDirectory(path, config)
    else:
        if config is None:
            if os.path.isdir(path) and not any(_TI_SERIES.match(name) for name in os.listdir(path)):
                what = NO_RECORDING
            elif os.path.isfile(path) and not path.endswith(".bin"):
                what = f"not a recording (a capture directory, or TI's {ADC_DATA} or *_Raw_<n>.bin files)"
            elif os.path.isfile(path) and os.path.basename(path) == ADC_DATA and \
                    os.path.exists(os.path.join(os.path.dirname(path), METADATA)):
                # A capture directory's frame data given alone: the directory holds its cfg and times.
                what = (f"the frame data of the capture directory {os.path.dirname(path) or '.'}: give the "
                        f"directory (replay://{os.path.dirname(path) or '.'})")
            else:
                what = (f"a recording without its {RADAR_CFG}: give the radar configuration with --cfg "
                        "(open_source(url, config) in Python)")
            raise ConfigError(what, path=path)
        if reordered is None:  # TI's CLI recorder reorders by default, mmWave Studio never
            reordered = bool(_TI_SERIES.match(os.path.basename(path))) or os.path.isdir(path)
        store = TiRecording(path, config, reordered=reordered)

    kind, value = start
    if kind == "seconds" and store.num_frames:
        first = int(np.searchsorted(store.timestamps - store.timestamps[0], value - 1e-9))
        if first >= store.num_frames:
            span = float(store.timestamps[-1] - store.timestamps[0])
            raise SourceError(f"{options.url}: start={value:g}s is past the recording's last frame, "
                              f"{span:.2f} s after its first")
    else:  # a frame number (or a recording without a whole frame, which ReplaySource refuses)
        first = int(value)
        if store.num_frames and first >= store.num_frames:
            raise SourceError(f"{options.url}: start={first} is past the recording's last frame "
                              f"({store.num_frames} frames, numbered from 0)")
    return ReplaySource(store, rate=rate, loop=loop, start=first, frames=frames)
