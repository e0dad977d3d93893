"""Frame sources opened from a URL, like pyserial's ``serial_for_url``.

``open_source("replay://DIR?rate=max")`` looks the scheme up in a registry of
backends (module path strings, imported only when used), hands the backend
the path and the query options, and returns a :class:`Source`: an iterator of
:class:`Frame` objects and a context manager.

Every backend declares the options it takes through
:class:`~.url_options.UrlOptions`, so an unknown scheme or option is one clear
:class:`~radarodom.errors.SourceError` that lists what is supported.
"""

from __future__ import annotations

import abc
import collections
import importlib
import logging
import os
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator

import numpy as np

from ..calibration import RangeCoupling
from ..cfg import RadarConfig
from ..errors import SourceError, UsageError
from ..products import RangeAzimuth
from ..rawframe import RawLayout
from ..tum import TumTrajectory
from .url_options import UrlOptions, one_of

log = logging.getLogger(__name__)

#: The schemes of a radar read live: an emulated board cannot stream from one, and none knows a
#: ground truth (:func:`live_scheme`).
LIVE_SCHEMES = ("dca1000", "tidemo")

#: scheme -> "module:function" of the backend's opener.  Openers take
#: (path, options: UrlOptions, config: RadarConfig | None) and return a Source.
SCHEMES: dict[str, str] = {
    "replay": "radarodom.driver.recordings.replay:open_replay",
    "sim": "radarodom.driver.sim.source:open_sim",
    "dca1000": "radarodom.driver.live.source:open_live",
    "coloradar": "radarodom.driver.coloradar.source:open_coloradar",
    "tidemo": "radarodom.driver.tidemo.source:open_tidemo",
}

#: ``replay://PATH?format=NAME`` -> "module:function" of the opener of recordings in another
#: format than a capture directory (same signature as a scheme's opener, without ``format``).
REPLAY_FORMATS: dict[str, str] = {
    "tidemo": "radarodom.driver.tidemo.replay:open_tidemo_replay",
}
#: Timestamps are seconds (Unix time or from the start of a stream); larger magnitudes are
#: no time any recording was made at (1e10 s is the year 2286).
TIMESTAMP_LIMIT_S = 1e10
#: The stream file a recording of another replay format keeps in its directory (a demo's UART
#: stream, which ``tidemo://`` records beside its capture.json): ``replay://DIR`` finds the
#: format by it, and a capture directory's files include it (``--overwrite`` replaces it).
REPLAY_FORMAT_FILES: dict[str, str] = {"tidemo": "uart.bin"}
#: The bytes a file of another replay format holds within its first :data:`REPLAY_SNIFF_BYTES`
#: (a demo's packets' magic word, ``tidemo/wire.MAGIC``: a serial logger's file starts mid-packet),
#: so that ``replay://FILE`` given the cfg plays it in its format, not as raw ADC samples (noise-like
#: samples hold these 8 bytes at a given place with odds of 2^-64, at any of the 65536 about 4e-15).
REPLAY_FORMAT_MAGIC: dict[str, bytes] = {"tidemo": bytes([0x02, 0x01, 0x04, 0x03, 0x06, 0x05, 0x08, 0x07])}
REPLAY_SNIFF_BYTES = 1 << 16


def live_scheme(url: str) -> str | None:
    """The scheme of *url* where it names a radar read live (:data:`LIVE_SCHEMES`), else None; told
    from the text alone, before any radar is looked for."""
    scheme = url.partition("://")[0]
    return scheme if scheme in LIVE_SCHEMES else None


def register_scheme(scheme: str, opener: str | Callable[..., "Source"]) -> None:
    """Add or replace a backend (an opener, or its "module:function" path)."""
    SCHEMES[scheme] = opener  # type: ignore[assignment]


#: What a frame feeds the estimator (:attr:`Frame.role`).
ROLES = ("both", "velocity", "heatmap")


@dataclass
class Frame:
    """One radar frame from a source.

    Most sources give raw ADC bytes, and the DSP makes the point cloud and the heatmap from
    them.  A dataset that ships products instead (ColoRadar's on-chip point clouds, its cascade
    radar's heatmaps) gives :attr:`points` or :attr:`heatmap` and no raw bytes.  :attr:`role`
    says which of the estimator's two streams the frame feeds: a multi-rate source interleaves
    velocity frames with heatmap frames, in time order.
    """

    #: Frame number in this stream, from 0.
    index: int
    #: Time of the frame's first chirp, s.
    timestamp: float
    #: The frame's raw bytes as the DCA1000 streams them, uint8 (frame_bytes,); None when the
    #: source gives products instead.
    raw: np.ndarray | None
    layout: RawLayout | None
    #: Bytes of the frame lost in transport (zero-filled in ``raw``).
    missing_bytes: int = 0
    #: Ground-truth body pose (x, y, z, qx, qy, qz, qw) where the source knows it.
    pose: tuple[float, ...] | None = None
    #: time.monotonic() when the frame was there to process: its last packet received (live),
    #: or made or read (simulator, replay).  End-to-end latencies are measured from it.
    ready_monotonic: float = field(default_factory=time.monotonic)
    #: A point cloud the source already holds (products.POINT_DTYPE, (n,), TI sensor frame).
    points: np.ndarray | None = None
    #: A range-azimuth heatmap the source already holds.
    heatmap: RangeAzimuth | None = None
    #: Which estimator stream the frame feeds: "both", "velocity" or "heatmap" (:data:`ROLES`).
    role: str = "both"
    #: Of ``missing_bytes``, those never sent before the stream stopped (cut at stop); the
    #: rest were lost on the way (lost, truncated or late packets).
    cut_bytes: int = 0
    #: The zero-Doppler values of the azimuth antennas a radar computed itself (TI's demo's
    #: azimuth static heatmap, ``tidemo://``): complex64 (range bins, antennas), the first
    #: antennas of the virtual array in chirp order, calibrated as the cfg's
    #: compRangeBiasAndRxChanPhase says.  The DSP turns them into :attr:`heatmap`'s kind.
    static_antennas: np.ndarray | None = None
    #: The bytes the frame came in, where they are not :attr:`raw` (a demo UART packet), for
    #: recording them as received.
    wire: bytes | None = None

    @property
    def complete(self) -> bool:
        return self.missing_bytes == 0

    @property
    def has_raw(self) -> bool:
        return self.raw is not None

    def cube(self, out: np.ndarray | None = None) -> np.ndarray:
        """The frame as complex64 (loops, tx_slots, rx, samples); fills *out* if given."""
        if self.raw is None or self.layout is None:
            raise SourceError(f"frame {self.index} carries no raw ADC samples (a product-only source)")
        return self.layout.decode(self.raw, out)


class Source(abc.ABC):
    """A stream of frames.  Iterate it; close it (or use ``with``): a closed source has let go of
    what it reads (ports, sockets, files) and refuses to stream again.  A source gives its frames
    from :meth:`_frames` and lets go of what it holds in :meth:`_release`."""

    #: The URL the source was opened from.
    url: str = ""
    #: The radar configuration the raw frames follow; None when no frame carries raw samples.
    config: RadarConfig | None
    #: True when every frame carries raw ADC bytes (so the stream can be recorded).
    carries_raw: bool = True
    #: True when :meth:`recorder` gives a sink of the source's own (tidemo://: its UART packets).
    records_itself: bool = False
    #: True when the first frame waits for a radar to start (sensorStart: seconds).
    starts_radar: bool = False
    #: The estimator settings this source's frames call for, by name (``EstimatorConfig.preset``:
    #: "tidemo" for TI's demo firmware's points and static heatmap); None: the defaults.
    estimator_preset: str | None = None
    #: The TX-to-RX coupling a dataset ships for its raw frames, removed by the DSP
    #: (:class:`radarodom.calibration.RangeCoupling`); None for most sources.
    coupling: RangeCoupling | None = None
    #: Whether the config's channel calibration (compRangeBiasAndRxChanPhase) is known to fit
    #: the board that made the frames: a simulation and its recordings know their board.  None:
    #: unknown (a real board), and then a line other than the identity is taken to fit.
    calibrated: bool | None = None
    #: The range cells of the heatmaps the source's frames carry, where it ships its own and
    #: knows them before the first frame (a ColoRadar run's); None: the DSP makes them from
    #: ``config`` (when :attr:`heatmaps_from_raw`), or not known until the frames come.
    heatmap_range_bins: int | None = None
    #: The farthest range those heatmaps reach, m (their last range cell's), known with them.
    heatmap_reach_m: float | None = None

    def __init__(self) -> None:
        self._stop_requested = False
        self._closed = False

    @property
    def heatmaps_from_raw(self) -> bool:
        """Whether the frames' heatmaps are the DSP's, made from their raw samples by ``config``."""
        return self.carries_raw

    def __iter__(self) -> Iterator[Frame]:
        if self._closed:
            raise UsageError(f"{self.url}: the source is closed; open a new one (open_source)")
        return self._frames()

    @abc.abstractmethod
    def _frames(self) -> Iterator[Frame]:
        """The stream's frames in order, from an open source."""

    def stop(self) -> None:
        """Ask the stream to end after the current frame.  Safe to call from a
        signal handler or another thread."""
        self._stop_requested = True

    @property
    def stop_requested(self) -> bool:
        return self._stop_requested

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._closed

    def close(self) -> None:
        """Release what the source holds.  Idempotent."""
        if not self._closed:
            self._closed = True
            self._release()

    def _release(self) -> None:
        """What :meth:`close` lets go of, once (nothing, for a source that holds nothing open)."""

    def describe(self) -> dict[str, Any]:
        """What a status display may show about the source."""
        return {"url": self.url}

    def recording_metadata(self) -> dict[str, Any]:
        """What a recording of this stream keeps in its metadata besides the frames (a
        simulation's scene, seed and board: :mod:`.replay` reads the board back)."""
        return {}

    def recorder(self, directory: str) -> Any | None:
        """A pipeline sink that records this stream as the source received it, for a source whose
        frames are not raw ADC frames but can be recorded all the same (``tidemo://``: its UART
        packets, which ``replay://`` plays again); None when the frames are recorded as raw ADC
        frames (a capture directory) or not at all."""
        return None

    def time_span(self) -> tuple[float, float, str] | None:
        """(first, last) of the frames' times in a pass, s, and the file they come from, where the
        source knows them before it streams (a recording's); None otherwise (a live radar's, a
        simulation's from 0).  Later passes of a loop go on from the last (a run may stop long
        before them: what they reach is checked as they come)."""
        return None

    def groundtruth(self) -> TumTrajectory | None:
        """The true poses of the stream's pose-giving frames, where the source knows them
        (a simulation's recording, a dataset with ground truth); None otherwise."""
        return None

    def __enter__(self) -> "Source":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


#: Longest single sleep while pacing, s: bounds how late a stop request is seen.
PACING_SLICE_S = 0.05
#: A wait longer than this, s, for a frame is said (a gap in a recording's times: the run looked hung).
LONG_WAIT_S = 10.0


class Pacer:
    """Releases frames at their stream time divided by a rate factor, measured
    from the first call; ``rate`` inf never waits.  Sleeps in short slices so a
    stop request is seen promptly."""

    def __init__(self, rate: float, source: "Source") -> None:
        self.rate = rate
        self.source = source
        self._wall0: float | None = None
        self._last_offset = 0.0
        self._steps: collections.deque[float] = collections.deque(maxlen=8)  # the last steps, s of stream

    def wait(self, stream_offset_s: float) -> None:
        """Block until *stream_offset_s* (seconds since the first frame) is due."""
        if self._wall0 is None:
            self._wall0 = time.monotonic()
        if self.rate == float("inf"):
            return
        due = self._wall0 + stream_offset_s / self.rate
        gap = stream_offset_s - self._last_offset
        usual = min(self._steps, default=None)  # (the smallest: a gap after a gap is one too)
        if gap > 0:
            self._last_offset = stream_offset_s
            self._steps.append(gap)
        # Said for a gap in the times (ten usual steps and more; with none before it, longer than
        # the wait said), not for every frame a slow rate spreads out.
        is_gap = gap > 10 * usual if usual else gap > LONG_WAIT_S
        if due - time.monotonic() > LONG_WAIT_S and is_gap:
            log.warning("%s: the next frame is due in %.0f s, at %.1f s of stream (a gap of %.1f s in the "
                        "recording's times); waiting for it (rate=max plays without waiting)",
                        self.source.url or "the source", due - time.monotonic(), stream_offset_s, gap)
        while not self.source.stop_requested:
            left = due - time.monotonic()
            if left <= 0:
                return
            time.sleep(min(left, PACING_SLICE_S))


def split_url(url: str) -> tuple[str, str, str]:
    """``scheme://path?query`` -> (scheme, path, query).  The path is kept as
    written (relative or absolute), unlike urllib's host/path split."""
    scheme, sep, rest = url.partition("://")
    if not sep or not scheme:
        raise SourceError(f"{url!r} is not a source URL (expected scheme://...); "
                          f"supported schemes: {', '.join(sorted(SCHEMES))}")
    path, _, query = rest.partition("?")
    return scheme.lower(), path, query


def _resolve(opener: str | Callable[..., Source]) -> Callable[..., Source]:
    if callable(opener):
        return opener
    module, _, func = opener.partition(":")
    return getattr(importlib.import_module(module), func)


def _replay_opener(path: str, options: UrlOptions, default: str | Callable[..., Source]):
    """The opener of ``replay://PATH``: by its ``format=`` option, else by the file a directory
    of a format holds (``uart.bin``: a demo's UART stream) or the bytes a file given holds
    (:data:`REPLAY_FORMAT_MAGIC`), else *default*."""
    kind = options.take("format", one_of("capture", *REPLAY_FORMATS), None,
                        " or ".join(("capture", *REPLAY_FORMATS)))
    if kind is None:
        kind = _replay_format(os.path.expanduser(path))
    return default if kind == "capture" else REPLAY_FORMATS[kind]


def _replay_format(path: str) -> str:
    """The replay format of the directory or file *path*, "capture" unless it is another's."""
    if os.path.isdir(path):
        return next((name for name, file in REPLAY_FORMAT_FILES.items()
                     if os.path.isfile(os.path.join(path, file))), "capture")
    try:
        with open(path, "rb") as fh:
            head = fh.read(REPLAY_SNIFF_BYTES)
    except OSError:  # missing or unreadable: the capture's opener says so
        return "capture"
    return next((name for name, magic in REPLAY_FORMAT_MAGIC.items() if magic in head), "capture")


def open_source(url: str, config: RadarConfig | None = None, *, shown_url: str | None = None) -> Source:
    """Open the frame source *url* names.  *config* overrides the radar
    configuration the source would otherwise use (required where the source
    carries none).  *shown_url*: the URL the user gave, named in messages about its
    options where *url* is it with options added (an emulated board's)."""
    if not isinstance(url, str):
        raise SourceError(f"a source URL is a str (scheme://...), got {type(url).__name__}")
    if config is not None and not isinstance(config, RadarConfig):
        raise SourceError(f"config: a RadarConfig (RadarConfig.from_file(path) reads one) or None, "
                          f"got {type(config).__name__}")
    scheme, path, query = split_url(url)
    if scheme not in SCHEMES:
        raise SourceError(f"unknown source scheme {scheme!r} in {url!r}; supported: "
                          f"{', '.join(s + '://' for s in sorted(SCHEMES))}")
    options = UrlOptions(shown_url or url, query)
    opener = SCHEMES[scheme]
    if scheme == "replay":
        opener = _replay_opener(path, options, opener)
    source = _resolve(opener)(path, options, config)
    try:
        options.finish()
    except SourceError:
        source.close()
        raise
    source.url = url
    log.debug("opened %s", url)
    return source
