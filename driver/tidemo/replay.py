"""``replay://PATH?format=tidemo`` : a recorded demo UART stream played as the radar sent it.

PATH is either

- a file of the data port's bytes as a serial logger saves them (``cat /dev/ttyACM1 > uart.bin``;
  TI's mmWave Demo Visualizer's recorded ``.dat`` files hold the same stream, as far as TI's forum
  threads show), with ``--cfg`` the cfg the radar ran; or
- a directory :class:`~.recording.UartRecorder` wrote (``radar-capture --record`` of a
  ``tidemo://`` source): ``uart.bin``, ``timestamps.txt``, ``radar.cfg`` (the default cfg) and
  ``capture.json``; ``replay://DIR`` finds the format by its ``uart.bin``.

The stream is framed as the live source frames it (:mod:`.framer`: garbage, cut packets and lost
bytes are counted and skipped).  Frame times: ``timestamps.txt`` beside the file when there is
one, line k the time of frame number *first + k* (frames lost in the stream skip their lines,
the header's frame numbers say which); else the cfg's frame period from 0.

Options: ``rate`` (1.0: real time; ``max``), ``loop`` (passes, 0: until stopped), ``frames``
(how many to play).
"""

from __future__ import annotations

import collections
import logging
import math
import mmap
import os
import time
from typing import Iterator

import numpy as np

from ... import strict_json
from ...cfg import RadarConfig
from ...errors import CaptureError, CaptureFormatError, ConfigError, SourceError, quoted_json
from ..recordings.capture_check import check_parts_are_files, read_timestamps
from ..sources import Frame, Pacer, Source
from ..url_options import RATE_EXPECTED, UrlOptions, at_least, parse_rate
from .framer import FramerStats, TlvFramer
from .layout import DemoGeometry, gui_selection
from .products import FrameIndexer, PacketFrames
from .recording import FORMAT_NAME, FORMAT_VERSION, METADATA, RADAR_CFG, TIMESTAMPS, UART_DATA, UartRecorder
from .wire import parse_packet

log = logging.getLogger(__name__)

#: Bytes the framer is fed at a time while scanning a file.
_CHUNK = 1 << 20
#: Largest capture.json read.
_MAX_METADATA_BYTES = 1 << 20


class TidemoReplaySource(Source):
    """Plays the whole packets of a demo UART stream file."""

    carries_raw = False
    records_itself = True
    estimator_preset = "tidemo"

    def __init__(self, path: str, config: RadarConfig, *, timestamps: str | None = None, rate: float = 1.0,
                 loop: int = 1, frames: int | None = None) -> None:
        super().__init__()
        self.path, self.config, self.rate, self.loop = path, config, rate, loop
        self.geometry = DemoGeometry.from_config(config)
        layout = self.geometry.layout(gui_selection(config))
        self.framer = TlvFramer(layout.packet_bytes(self.geometry.range_bins * self.geometry.doppler_bins),
                                note_rejections=True)
        try:
            self._file = open(path, "rb")
        except OSError as exc:
            raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None
        size = os.fstat(self._file.fileno()).st_size
        self._data = mmap.mmap(self._file.fileno(), 0, access=mmap.ACCESS_READ) if size else b""
        # (offset, length, index) of every whole packet, found once.
        indexer, found = FrameIndexer(), []
        for at in range(0, size, _CHUNK):
            found += self.framer.feed(self._data[at:at + _CHUNK])
        found += self.framer.finish()
        self.packets = [(p.offset, len(p.data), indexer(p.frame_number)) for p in found]
        self._whole_file = frames is None or frames >= len(self.packets)
        if frames is not None:
            self.packets = self.packets[:frames]
        if not self.packets:
            raise CaptureFormatError(f"{path}: no whole demo packet in {size} bytes{_given_up(self.framer)}")
        last = self.packets[-1][2]
        if timestamps is not None:
            self.stamps = read_timestamps(timestamps, 1 << 40)
            if len(self.stamps) <= last:
                raise CaptureFormatError(f"{timestamps}: {len(self.stamps)} lines, but the stream's frame numbers "
                                         f"need {last + 1} (one line per frame number from the first packet's)")
        else:
            self.stamps = np.arange(last + 1) * config.frame_period_s
        self.timestamps_path = timestamps
        # What describe() tells of a part played, found once: it is asked for every status.
        self._played_bytes = np.cumsum([length for _, length, _ in self.packets])
        self._rejected_at = {reason: np.array([at for at, why in self.framer.rejections if why == reason])
                             for reason in {why for _, why in self.framer.rejections}}
        self.frames_played = 0
        self._passes_done, self._position = 0, -1  # the last packet played: its place in self.packets

    def _frames(self) -> Iterator[Frame]:
        stamps = self.stamps
        span = float(stamps[self.packets[-1][2]] - stamps[self.packets[0][2]]) + self.config.frame_period_s
        pacer, passes = Pacer(self.rate, self), 0
        period_indices = self.packets[-1][2] + 1
        while not self.stop_requested and (self.loop == 0 or passes < self.loop):
            offset_s, offset_i = passes * span, passes * period_indices
            frames = PacketFrames(self.geometry, lambda i, p: float(stamps[i]) + offset_s)
            for at, length, index in self.packets:
                if self.stop_requested:
                    return
                pacer.wait(float(stamps[index] - stamps[self.packets[0][2]]) + offset_s)
                packet = parse_packet(bytes(self._data[at:at + length]))
                packet.offset = at
                frame = frames(packet, 0.0)
                frame.index = index + offset_i
                frame.ready_monotonic = time.monotonic()
                if self.stop_requested:
                    return
                # Counted as handed on: a consumer that stops (a frame limit) does not come back.
                self.frames_played += 1
                self._position += 1
                yield frame
            passes += 1
            self._passes_done, self._position = passes, -1

    def time_span(self) -> tuple[float, float, str]:
        stamps = self.stamps
        return float(stamps[self.packets[0][2]]), float(stamps[self.packets[-1][2]]), self.timestamps_path or self.path

    def recorder(self, directory: str) -> UartRecorder:
        """A sink that records the packets played (:class:`.recording.UartRecorder`), as the live
        source's does: a part of a stream cut out (``frames``) is a recording of its own."""
        return UartRecorder(directory, self.config, source=self.url)

    def describe(self) -> dict:
        """The selection (``frames``: its packets) and what the part of the stream played so far
        lost (a run a frame or duration limit ended played less than the file): ``frames_skipped``
        (frame numbers missing between its packets) and the framer's counts (:class:`.FramerStats`:
        ``packets`` played, bytes discarded, packets rejected by reason).  A whole pass counts the
        whole file's losses, what follows the last packet included, unless ``frames`` cut it."""
        whole = self._pass_losses()
        part = self._losses_before(self._position) if self._position >= 0 else FramerStats()
        passes = self._passes_done
        lost = FramerStats(packets=self.frames_played, packet_bytes=passes * whole.packet_bytes + part.packet_bytes,
                           discarded_bytes=passes * whole.discarded_bytes + part.discarded_bytes,
                           rejected=collections.Counter({reason: passes * n for reason, n in whole.rejected.items()})
                           + part.rejected)
        skipped = passes * self._skipped_before(len(self.packets) - 1)
        if self._position >= 0:
            skipped += self._skipped_before(self._position)
        return {"url": self.url, "path": self.path, "frames": len(self.packets),
                "rate": "max" if self.rate == math.inf else self.rate, "loop": self.loop,
                "frames_skipped": skipped, **lost.as_dict()}

    def _skipped_before(self, k: int) -> int:
        """Frame numbers missing up to the selection's packet *k*."""
        return self.packets[k][2] - k

    def _losses_before(self, k: int) -> FramerStats:
        """What the stream lost before the selection's packet *k* and the packets it played to
        *k* included (every byte before a packet is in an earlier packet or was discarded)."""
        at, length, _ = self.packets[k]
        played = int(self._played_bytes[k])
        rejected = collections.Counter({reason: n for reason, offsets in self._rejected_at.items()
                                        if (n := int(np.searchsorted(offsets, at)))})
        return FramerStats(packets=k + 1, packet_bytes=played, discarded_bytes=at + length - played,
                           rejected=rejected)

    def _pass_losses(self) -> FramerStats:
        """What one whole pass over the selection lost."""
        if self._whole_file:
            return self.framer.stats
        return self._losses_before(len(self.packets) - 1)

    def _release(self) -> None:
        if isinstance(self._data, mmap.mmap):
            self._data.close()
        self._file.close()


def _check_given_cfg(given: RadarConfig | None, recorded: RadarConfig) -> None:
    """A cfg given for a demo recording makes packets of its recorded radar.cfg's shape (another
    calibration line is fine), else ConfigError naming both: its frames would not decode."""
    if given is None:
        return
    shape = [(g.range_bins, g.doppler_bins, len(g.heatmap_elements))
             for g in (DemoGeometry.from_config(given), DemoGeometry.from_config(recorded))]
    if shape[0] != shape[1]:
        said = [f"{r} range bins, {d} Doppler bins and {a} antennas" for r, d, a in shape]
        raise ConfigError(f"the cfg given makes the demo's packets of {said[0]}, and {recorded.path}, which the "
                          f"radar ran, of {said[1]}: leave the cfg out (the recording's is used) or give the one "
                          "it was recorded with", path=given.path)


def _given_up(framer: TlvFramer) -> str:
    """Why a stream held no whole packet, for its error: no magic word at all, or the packets begun
    with one and given up, by reason, and where the first was."""
    if not framer.rejections:
        return " (the UART stream of TI's SDK 3.x demo starts each packet with the magic word 02 01 04 03 06 05 08 07)"
    counts = ", ".join(f"{why} {n}" for why, n in framer.stats.rejected.most_common())
    header = "" if framer.first_bad_header is None else f"; the first bad header's {framer.first_bad_header}"
    return (f": {framer.stats.rejected_packets} begun with the magic word, all given up ({counts}; the first at byte "
            f"{framer.rejections[0][0]}{header})")


def _read_metadata(path: str) -> dict:
    """A recording's capture.json, its format and counts checked (a hand edit, a damaged file)."""
    try:
        with open(path, "rb") as fh:
            meta = strict_json.loads(fh.read(_MAX_METADATA_BYTES + 1), max_bytes=_MAX_METADATA_BYTES)
    except OSError as exc:
        raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise CaptureFormatError(f"{path}: {exc}; repair it or move it away (without it the stream plays "
                                 "unchecked)") from None
    if not isinstance(meta, dict):
        raise CaptureFormatError(f"{path}: expected a JSON object, got {type(meta).__name__}")
    if "format" not in meta:
        raise CaptureFormatError(f"{path}: format: missing (a required field; {FORMAT_NAME} here)")
    if meta["format"] != FORMAT_NAME:
        raise CaptureFormatError(f"{path}: not a {FORMAT_NAME} recording's metadata (format "
                                 f"{quoted_json(meta['format'])})")
    version = meta.get("format_version")
    if not isinstance(version, int) or isinstance(version, bool) or not 1 <= version <= FORMAT_VERSION:
        raise CaptureFormatError(f"{path}: format_version {quoted_json(version)}: this radarodom reads "
                                 f"{FORMAT_VERSION}")
    for key in ("packets", "frame_lines"):
        value = meta.get(key)
        if not isinstance(value, int) or isinstance(value, bool) or value < 0:
            raise CaptureFormatError(f"{path}: {key}: expected a whole number >= 0, got {quoted_json(value)}")
    baud = meta.get("baud")
    if baud is not None and (not isinstance(baud, int) or isinstance(baud, bool) or baud <= 0):
        raise CaptureFormatError(f"{path}: baud: expected a whole number > 0 or null, got {quoted_json(baud)}")
    if not isinstance(meta.get("closed", False), bool):
        raise CaptureFormatError(f"{path}: closed: expected true or false, got {quoted_json(meta['closed'])}")
    if not meta.get("closed", False):
        log.warning("%s: the recording was not closed (its process died): playing its whole packets", path)
    return meta


def _check_against_metadata(source: TidemoReplaySource, meta: dict) -> None:
    """A closed recording's uart.bin and timestamps.txt hold what its capture.json counted: a file
    cut short or changed since would play fewer packets, or at other times, without a word."""
    changed = "was cut short or changed since it was recorded; record it again or play the file alone " \
              "(replay://FILE?format=tidemo with --cfg)"
    found = source.framer.stats.packets
    if found != meta["packets"]:
        raise CaptureFormatError(f"{source.path}: {found} whole packets, but {METADATA} says the recording holds "
                                 f"{meta['packets']}: the file {changed}")
    if len(source.stamps) != meta["frame_lines"]:
        raise CaptureFormatError(f"{source.timestamps_path}: {len(source.stamps)} lines, but {METADATA} says the "
                                 f"recording wrote {meta['frame_lines']}: the file {changed}")


def open_tidemo_replay(path: str, options: UrlOptions, config: RadarConfig | None) -> TidemoReplaySource:
    rate = options.take("rate", parse_rate, 1.0, RATE_EXPECTED)
    loop = options.take("loop", at_least(0), 1, "a number of passes (0: forever)")
    frames = options.take("frames", at_least(1), None, "a whole number of frames >= 1")
    options.finish()
    if not path:
        raise SourceError(f"{options.url}: no path: use replay://FILE?format=tidemo")
    path = os.path.expanduser(path)
    meta = None
    recording = os.path.isdir(path)  # a directory UartRecorder wrote, else a serial logger's file
    if recording:
        directory, data = path, os.path.join(path, UART_DATA)
        check_parts_are_files(directory, (UART_DATA, METADATA, TIMESTAMPS, RADAR_CFG), "a demo recording's")
        if os.path.exists(os.path.join(directory, METADATA)):
            meta = _read_metadata(os.path.join(directory, METADATA))
        if os.path.exists(os.path.join(directory, RADAR_CFG)):
            recorded = RadarConfig.from_file(os.path.join(directory, RADAR_CFG))
            _check_given_cfg(config, recorded)
            config = config or recorded
    else:
        directory, data = os.path.dirname(path) or ".", path
    if not os.path.isfile(data):  # the stream first: without it the cfg is no help
        raise SourceError(f"{options.url}: {data}: no such file")
    if config is None and recording:
        raise ConfigError(f"no {RADAR_CFG}: the recording's cfg is missing; put it back, or give the cfg the "
                          "radar ran with --cfg (open_source(url, config) in Python)", path=directory)
    if config is None:
        raise ConfigError("the file holds the demo's UART stream: give the cfg the radar ran with --cfg "
                          "(open_source(url, config) in Python)", path=data)
    stamps = os.path.join(directory, TIMESTAMPS)
    if meta is not None and not os.path.isfile(stamps):  # a serial logger's file alone is timed by the cfg
        raise CaptureFormatError(f"{stamps}: no such file: the recording's frame times are in it (its "
                                 f"{METADATA} says radarodom recorded it); put it back, or play {data} alone "
                                 "(replay://FILE?format=tidemo with --cfg: timed by the cfg's frame period)")
    source = TidemoReplaySource(data, config, timestamps=stamps if os.path.isfile(stamps) else None, rate=rate,
                                loop=loop, frames=frames)
    if meta is not None and meta.get("closed", False):
        try:
            _check_against_metadata(source, meta)
        except BaseException:
            source.close()
            raise
    return source
