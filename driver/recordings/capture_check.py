"""What a capture directory must hold before a frame of it is played.

:func:`read_metadata` checks capture.json against the schema written down in
:mod:`.capture_dir`; :func:`read_timestamps` checks timestamps.txt line by line;
:func:`frame_count` decides how many frames the data, the timestamps and the metadata
agree on, telling a recording cut by a crash (played, with a warning) from one whose
files contradict each other (refused, saying what disagrees).  Every refusal is a
:class:`~radarodom.errors.CaptureFormatError` naming the file and, where there is one,
its line or field.

The format's names are defined here too (the files' names, the format's name and version, the
timestamps' bound), so that the writer (:mod:`.capture_writer`) and the reader
(:mod:`.capture_dir`) share them without importing each other.
"""

from __future__ import annotations

import logging
import os
from typing import Any

import numpy as np

from ... import strict_json
from ...antenna import NUM_RX_ANTENNAS, NUM_TX_ANTENNAS
from ...cfg_commands import coefficient_ok, coefficient_part_ok
from ...errors import CaptureError, CaptureFormatError, named_character, quoted, quoted_json
from ...plain_numbers import finite_float, plain_float
from ..sources import TIMESTAMP_LIMIT_S

log = logging.getLogger(__name__)

FORMAT_NAME = "radarodom-capture"
#: The format of a recording of the TI demo's UART stream (driver/tidemo/recording.py).
TIDEMO_FORMAT_NAME = "radarodom-tidemo"
FORMAT_VERSION = 1
#: The files of a capture directory (:mod:`.capture_dir` describes each).
RADAR_CFG = "radar.cfg"
ADC_DATA = "adc_data.bin"
TIMESTAMPS = "timestamps.txt"
METADATA = "capture.json"
GROUNDTRUTH = "groundtruth.tum"
#: capture.json without its list of incomplete frames is a few hundred bytes; the list adds
#: well under this much per frame of the data file.
_METADATA_BASE_BYTES = 1 << 20
_METADATA_BYTES_PER_FRAME = 128
#: The writer's lines are about 20 characters.
_MAX_TIMESTAMP_LINE = 256
#: Blank lines taken at the end of timestamps.txt (an editor or a copy adds one or a few).
_MAX_TRAILING_BLANK_LINES = 100
#: What a timestamp line's characters may be besides printable ASCII.
_LINE_SPACE = b" \t\r\n"


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return finite_float(value) is not None


class _Checker:
    def __init__(self, path: str) -> None:
        self.path = path

    def fail(self, field: str, expected: str, value: Any) -> CaptureFormatError:
        return CaptureFormatError(f"{self.path}: {field}: expected {expected}, got {quoted_json(value)}")

    def int_field(self, meta: dict, key: str, low: int, high: int | None = None, *, name: str | None = None,
                  required: bool = True, default: int = 0) -> int:
        name = name or key
        if key not in meta:
            if required:
                raise CaptureFormatError(f"{self.path}: {name}: missing (a required field)")
            return default
        value = meta[key]
        expected = f"an integer >= {low}" if high is None else f"an integer from {low} to {high}"
        if not _is_int(value) or value < low or (high is not None and value > high):
            raise self.fail(name, expected, value)
        return value


def _check_simulator(ck: _Checker, sim: Any) -> None:
    """capture.json's ``simulator`` object (what a ``sim://`` recording keeps: driver/sim/source.py),
    each field it has of its type (others kept and ignored): a replay reads the board's
    calibration from it, and took any value for any field without a word."""
    if not isinstance(sim, dict):
        raise ck.fail("simulator", "an object {scene, seed, board, board_calibration}", sim)
    for key in ("scene", "board"):
        if key in sim and not isinstance(sim[key], str):
            raise ck.fail(f"simulator.{key}", "a string", sim[key])
    ck.int_field(sim, "seed", 0, required=False, name="simulator.seed")
    ck.int_field(sim, "noise_seed", 0, required=False, name="simulator.noise_seed")
    if "board_calibration" not in sim:
        return
    where, cal = "simulator.board_calibration", sim["board_calibration"]
    if not isinstance(cal, dict):
        raise ck.fail(where, "an object {range_bias_m, coefficients}", cal)
    for key in ("range_bias_m", "coefficients"):
        if key not in cal:
            raise CaptureFormatError(f"{ck.path}: {where}.{key}: missing (a required field)")
    if not _is_number(cal["range_bias_m"]) or not -10.0 <= cal["range_bias_m"] <= 10.0:
        # the cfg line's own range (compRangeBiasAndRxChanPhase's rangeBias)
        raise ck.fail(f"{where}.range_bias_m", "a number of metres within -10..10", cal["range_bias_m"])
    pairs, count = cal["coefficients"], NUM_TX_ANTENNAS * NUM_RX_ANTENNAS
    if not isinstance(pairs, list) or len(pairs) != count:
        raise ck.fail(f"{where}.coefficients", f"a list of {count} [re, im] pairs (TX1 RX1 to TX3 RX4)", pairs)
    for k, pair in enumerate(pairs):
        # The cfg line's own rule (compRangeBiasAndRxChanPhase: cfg_commands.coefficient_ok), on two JSON
        # numbers; each part's range is asked as it is met, before the next part's type is.
        if not (isinstance(pair, list) and len(pair) == 2
                and all(_is_number(x) and coefficient_part_ok(x) for x in pair) and coefficient_ok(*pair)):
            raise ck.fail(f"{where}.coefficients[{k}]", "[re, im]: two numbers within -1..1, not both 0", pair)


def check_metadata(meta: Any, path: str) -> dict[str, Any]:
    """*meta* (capture.json's parsed contents) when it follows the schema, else
    :class:`CaptureFormatError` naming *path*, the field and what was expected."""
    ck = _Checker(path)
    if not isinstance(meta, dict):
        raise CaptureFormatError(f"{path}: expected a JSON object, got {type(meta).__name__}")
    if meta.get("format") != FORMAT_NAME:
        if "format" not in meta:
            raise CaptureFormatError(f"{path}: format: missing (a required field)")
        raise ck.fail("format", repr(FORMAT_NAME), meta["format"])
    version = meta.get("format_version")
    if not _is_int(version) or version < 1:
        raise ck.fail("format_version", f"the integer {FORMAT_VERSION}", version)
    if version > FORMAT_VERSION:
        raise CaptureFormatError(f"{path}: format_version: {version}: written by a newer radarodom "
                                 f"(this one reads version {FORMAT_VERSION}); update radarodom")
    frame_bytes = ck.int_field(meta, "frame_bytes", 1)
    frame_count = ck.int_field(meta, "frame_count", 0)
    if not isinstance(meta.get("closed"), bool):
        if "closed" not in meta:
            raise CaptureFormatError(f"{path}: closed: missing (a required field)")
        raise ck.fail("closed", "true or false", meta["closed"])
    for key in ("software", "source", "start_time"):
        if key in meta and not isinstance(meta[key], str):
            raise ck.fail(key, "a string", meta[key])
    if "start_time_unix" in meta and not (_is_number(meta["start_time_unix"])
                                         and 0 <= meta["start_time_unix"] <= TIMESTAMP_LIMIT_S):
        raise ck.fail("start_time_unix", f"a number of seconds from 0 to {TIMESTAMP_LIMIT_S:g}",
                      meta["start_time_unix"])
    for key in ("first_timestamp", "last_timestamp"):
        value = meta.get(key)
        if value is not None and not (_is_number(value) and abs(value) <= TIMESTAMP_LIMIT_S):
            raise ck.fail(key, f"null or a number of seconds within +-{TIMESTAMP_LIMIT_S:g}", value)
    ck.int_field(meta, "dropped_frames", 0, required=False)
    if "simulator" in meta:
        _check_simulator(ck, meta["simulator"])

    entries = meta.get("incomplete_frames", [])
    if not isinstance(entries, list):
        raise ck.fail("incomplete_frames", "a list of {frame, missing_bytes[, cut_bytes]} objects", entries)
    lost = cut = 0
    previous = -1
    for k, entry in enumerate(entries):
        where = f"incomplete_frames[{k}]"
        if not isinstance(entry, dict):
            raise ck.fail(where, "an object {frame, missing_bytes[, cut_bytes]}", entry)
        if frame_count == 0:
            raise CaptureFormatError(f"{path}: {where}: lists a frame of a recording of 0 frames (frame_count)")
        frame = ck.int_field(entry, "frame", previous + 1, frame_count - 1, name=f"{where}.frame")
        missing = ck.int_field(entry, "missing_bytes", 1, frame_bytes, name=f"{where}.missing_bytes")
        entry_cut = ck.int_field(entry, "cut_bytes", 0, missing, name=f"{where}.cut_bytes", required=False)
        previous = frame
        lost += missing
        cut += entry_cut
    for key, total in (("lost_bytes", lost), ("cut_bytes", cut)):
        if key in meta and meta[key] != total:
            what = "missing_bytes" if key == "lost_bytes" else "cut_bytes"
            raise ck.fail(key, f"{total}, the sum of the {what} of incomplete_frames", meta[key])
    return meta


def read_metadata(path: str, frames_in_data: int) -> dict[str, Any] | None:
    """capture.json at *path*, checked (:func:`check_metadata`); None when there is none.
    Its size is bounded by what the list of incomplete frames of *frames_in_data* frames
    can take."""
    limit = _METADATA_BASE_BYTES + _METADATA_BYTES_PER_FRAME * frames_in_data
    try:
        with open(path, "rb") as fh:
            data = fh.read(limit + 1)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None
    try:
        meta = strict_json.loads(data, max_bytes=limit)
    except ValueError as exc:
        raise CaptureFormatError(f"{path}: {exc}; repair it or move it away (without it every frame "
                                 f"of the data file is played, as complete)") from None
    return check_metadata(meta, path)


def check_parts_are_files(directory: str, names, whose: str) -> None:
    """Each of a recording's files *names* that is in *directory* is a file (a directory in its
    place was read as missing, or failed to open); *whose*: "a capture's", "a demo recording's"."""
    for name in names:
        part = os.path.join(directory, name)
        if os.path.exists(part) and not os.path.isfile(part):
            what = "a directory" if os.path.isdir(part) else "not a regular file"
            raise CaptureFormatError(f"{part}: is {what}: {whose} {name} is a file; put the recording's own back "
                                     "in its place")


def read_timestamps(path: str, max_lines: int, *, closed: bool = False) -> np.ndarray:
    """The frame times in timestamps.txt: one plain decimal number per line, finite, within
    +-:data:`TIMESTAMP_LIMIT_S`, strictly increasing.  A last line without its end of line
    is the writer cut off, ignored with a warning, unless the recording was *closed* (then an
    editor saved it so, and it is read); blank lines at the end (up to
    :data:`_MAX_TRAILING_BLANK_LINES`) are ignored, a blank line before a timestamp is refused.
    More than *max_lines* timestamps (the whole frames of the data file) are refused as soon as
    they are met."""
    values: list[float] = []
    try:
        fh = open(path, "rb")
    except OSError as exc:
        raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None
    with fh:
        lineno = 0
        blank: list[int] = []  # the blank lines since the last timestamp
        while True:
            line = fh.readline(_MAX_TIMESTAMP_LINE)
            if not line:
                break
            lineno += 1
            if b"\r" in line.rstrip(b"\r\n"):
                raise CaptureFormatError(f"{path}:{lineno}: a line ended by a carriage return alone (an old Mac's line "
                                         "ends): one timestamp a line, ended by LF or CR LF; convert the file "
                                         "(tr '\\r' '\\n')")
            if not line.strip(_LINE_SPACE):
                blank.append(lineno)
                if len(blank) > _MAX_TRAILING_BLANK_LINES:
                    raise CaptureFormatError(f"{path}:{blank[0]}: {len(blank)} blank lines from here on: "
                                             f"not a timestamps file (one line per frame)")
                continue
            if not line.endswith(b"\n"):
                if len(line) >= _MAX_TIMESTAMP_LINE:
                    raise CaptureFormatError(f"{path}:{lineno}: a line longer than {_MAX_TIMESTAMP_LINE} "
                                             f"bytes: not a timestamp")
                if not closed:
                    log.warning("%s:%d: ignoring a partly written last line", path, lineno)
                    break
            if blank:
                raise CaptureFormatError(f"{path}:{blank[0]}: a blank line among the timestamps: every "
                                         f"line is one frame's time (only the end may have blank lines)")
            if len(values) >= max_lines:
                raise CaptureFormatError(f"{path}:{lineno}: more lines than the {max_lines} whole frames "
                                         f"of adc_data.bin (one line per frame)")
            values.append(_timestamp(path, lineno, line, values[-1] if values else None))
    return np.array(values, dtype=float)


def _odd_character(line: bytes) -> str | None:
    """Where *line* holds what no timestamp does, named readably ("column 3: character U+00A0
    (no-break space)"): a byte that is no UTF-8, or a character other than printable ASCII and
    spaces; None when there is none."""
    try:
        text = line.decode("utf-8")
    except UnicodeDecodeError as exc:
        return f"column {exc.start + 1}: byte 0x{line[exc.start]:02X}, which is not UTF-8 text"
    for column, ch in enumerate(text, start=1):
        if not (" " <= ch <= "~" or ch in "\t\r\n"):
            return f"column {column}: character {named_character(ch)}"
    return None


def _timestamp(path: str, lineno: int, line: bytes, previous: float | None) -> float:
    odd = _odd_character(line)
    if odd is not None:
        raise CaptureFormatError(f"{path}:{lineno}: {odd}: expected a timestamp (a plain decimal number "
                                 f"of seconds in ASCII)")
    text = line.decode("ascii").strip(" \t\r\n")
    value = plain_float(text)
    if value is None:
        raise CaptureFormatError(f"{path}:{lineno}: expected a timestamp (a plain decimal number of "
                                 f"seconds), got {quoted(text)}")
    if not abs(value) <= TIMESTAMP_LIMIT_S:
        raise CaptureFormatError(f"{path}:{lineno}: timestamp {text[:40]} is out of range (at most "
                                 f"{TIMESTAMP_LIMIT_S:g} s in magnitude)")
    if previous is not None and value <= previous:
        raise CaptureFormatError(f"{path}:{lineno}: timestamp {text[:40]} is not after the previous "
                                 f"line's {previous:.9f}: frame times must increase")
    return value


def check_frame_bytes(directory: str, meta: dict[str, Any] | None, frame_bytes: int, cfg_name: str) -> None:
    """The frame size of the configuration *cfg_name* against the one capture.json recorded."""
    if meta is not None and meta["frame_bytes"] != frame_bytes:
        raise CaptureFormatError(
            f"{directory}: {cfg_name} makes frames of {frame_bytes} bytes, capture.json says the "
            f"recording's are {meta['frame_bytes']} bytes: the data was recorded with another "
            f"configuration (use the radar.cfg it was recorded with)")


def check_data_length(directory: str, data_bytes: int, frame_bytes: int, meta: dict[str, Any] | None) -> None:
    """A closed recording's adc_data.bin shorter than its frames: the data file was cut (a copy
    that stopped part way), which is what to say, before its timestamps seem too many."""
    if meta is not None and meta["closed"] and data_bytes < meta["frame_count"] * frame_bytes:
        whole, tail = divmod(data_bytes, frame_bytes)
        raise CaptureFormatError(
            f"{directory}: capture.json says the closed recording has {meta['frame_count']} frames, adc_data.bin "
            f"holds fewer ({data_bytes} bytes: {whole} frames of {frame_bytes} bytes"
            + (f" and {tail} bytes more" if tail else "") + "): was it cut short (a copy that stopped part way)?")


def frame_count(directory: str, data_bytes: int, frame_bytes: int, cfg_name: str,
                meta: dict[str, Any] | None, stamps: np.ndarray | None) -> int:
    """How many frames of the data file to play: all its whole frames when the metadata (when
    there is one) and the timestamps (when there are) agree with them, allowing for what a
    process killed while recording leaves (a cut-off frame, the last frame without its
    timestamp, metadata behind the data); :class:`CaptureFormatError` saying what disagrees
    otherwise."""
    whole, tail = divmod(data_bytes, frame_bytes)
    data = f"adc_data.bin ({data_bytes} bytes: {whole} frames of {frame_bytes} bytes" + \
        (f" and {tail} bytes more)" if tail else ")")
    n_ts = None if stamps is None else len(stamps)
    if meta is not None:
        check_frame_bytes(directory, meta, frame_bytes, cfg_name)
        recorded = meta["frame_count"]
        if n_ts is None:
            raise CaptureFormatError(f"{directory}: timestamps.txt is missing, capture.json counts "
                                     f"{recorded} frames")
        if meta["closed"]:
            if whole != recorded or tail or n_ts != recorded:
                raise CaptureFormatError(
                    f"{directory}: the files disagree: capture.json says the closed recording has "
                    f"{recorded} frames, {data}, timestamps.txt has {n_ts} lines"
                    + ("; data appended after the recording?" if data_bytes > recorded * frame_bytes else ""))
            return whole
        if recorded > min(whole, n_ts):
            raise CaptureFormatError(
                f"{directory}: capture.json counts {recorded} frames, more than {data} and the "
                f"{n_ts} lines of timestamps.txt hold")
    if n_ts is not None and not whole - 1 <= n_ts <= whole:
        raise CaptureFormatError(
            f"{directory}: timestamps.txt has {n_ts} lines for {data}: every frame needs its line "
            f"(a recording cut by a crash lacks at most the last one)")
    if meta is not None:
        log.warning("%s: the recording was not closed (its process was killed or crashed); playing "
                    "its %d whole frame%s%s", directory, whole, "" if whole == 1 else "s",
                    f", ignoring {tail} bytes of a cut-off frame" if tail else "")
    elif tail:
        log.warning("%s: adc_data.bin ends with %d bytes of a cut-off frame after frame %d of %s; they "
                    "are ignored", directory, tail, whole - 1, cfg_name)
    return whole


def timestamps_for(directory: str, stamps: np.ndarray | None, whole: int, period_s: float) -> np.ndarray:
    """One time per frame: *stamps*, with the last frame's extrapolated when its line never
    reached the disk, or the frame period from 0 when there is no timestamps.txt."""
    if stamps is None:
        log.info("%s: no timestamps.txt: frame times follow the frame period from 0", directory)
        return period_s * np.arange(whole, dtype=float)
    if len(stamps) < whole:
        log.warning("%s: the last frame has no timestamp (its line was never written); "
                    "extrapolating from the frame period", directory)
        start = stamps[-1] + period_s if len(stamps) else 0.0
        stamps = np.concatenate([stamps, [start]])
    return stamps


__all__ = ["ADC_DATA", "FORMAT_NAME", "FORMAT_VERSION", "GROUNDTRUTH", "METADATA", "RADAR_CFG", "TIMESTAMPS",
           "TIMESTAMP_LIMIT_S", "check_frame_bytes", "check_metadata", "frame_count", "read_metadata",
           "read_timestamps", "timestamps_for"]

