"""Which directories a recording may write into: :func:`claim_recording_directory`, which every
recorder (:class:`~.capture_writer.CaptureWriter`, the TI demo's
:class:`~..tidemo.recording.UartRecorder`) calls before it writes anything, and the checks
``radar-capture`` makes of its outputs before a run (``tools/output_paths.py``).

A recording writes a handful of files of fixed names (:data:`RECORDING_FILES`) into its
directory, and removes them again when it recorded nothing.  A directory is a recording's when
its ``capture.json`` names one of radarodom's formats; any of those names there without one
belongs to someone else (a ground truth of their own, a cfg, another tool's ``capture.json``),
and a recording refuses the directory before touching it rather than replace or remove them.
"""

from __future__ import annotations

import contextlib
import logging
import os

from ... import strict_json
from ...errors import CaptureExistsError
from ..sources import REPLAY_FORMAT_FILES
from .capture_check import ADC_DATA, FORMAT_NAME, GROUNDTRUTH, METADATA, RADAR_CFG, TIDEMO_FORMAT_NAME, TIMESTAMPS

log = logging.getLogger(__name__)

_CAPTURE_FILES = (ADC_DATA, TIMESTAMPS, GROUNDTRUTH, METADATA, METADATA + ".tmp", RADAR_CFG)
#: The files a recording radarodom writes consists of, a replay format's stream file among them.
RECORDING_FILES = (*_CAPTURE_FILES, *REPLAY_FORMAT_FILES.values())
#: The files a recording writes its frames into: one with any byte in it holds a recording.
_DATA_FILES = (ADC_DATA, TIMESTAMPS, GROUNDTRUTH, *REPLAY_FORMAT_FILES.values())
#: capture.json's "format" in the directories radarodom records.
_OWN_FORMATS = (FORMAT_NAME, TIDEMO_FORMAT_NAME)
#: A capture.json longer than this is not one radarodom wrote (its incomplete-frame list aside,
#: it is a few hundred bytes; heavy loss lists a frame in some 40).
_METADATA_MAX_BYTES = 256 << 20


def metadata_format(directory: str):
    """The "format" *directory*'s capture.json names; None when it names none or cannot be read."""
    try:
        with open(os.path.join(directory, METADATA), "rb") as fh:
            meta = strict_json.loads(fh.read(_METADATA_MAX_BYTES + 1), max_bytes=_METADATA_MAX_BYTES)
    except (OSError, ValueError):
        return None
    return meta.get("format") if isinstance(meta, dict) else None


def _own_metadata(directory: str) -> bool:
    """Whether *directory*'s capture.json is one radarodom wrote (its format one of radarodom's)."""
    return metadata_format(directory) in _OWN_FORMATS


def _recording_files_in(directory: str) -> list[str]:
    """The files a recording writes that *directory* holds (a capture.json's leftover copy aside)."""
    return [name for name in RECORDING_FILES
            if name != METADATA + ".tmp" and os.path.lexists(os.path.join(directory, name))]


def recorded_data(directory: str) -> str | None:
    """The first file of *directory* that holds recorded data (frames, timestamps, poses or a
    demo's stream: any byte in it), None when none does."""
    for name in _DATA_FILES:
        try:
            if os.path.getsize(os.path.join(directory, name)):
                return name
        except OSError:
            pass
    return None


def _described(held: str) -> str:
    return f"a capture ({held})" if held == ADC_DATA else f"a recording ({held})"


def own_recording(directory: str) -> str | None:
    """What a recording of radarodom's in *directory* holds, said for a message ("a capture
    (adc_data.bin)"), None when *directory* holds no such recording with data in it."""
    held = recorded_data(directory) if _own_metadata(directory) else None
    return None if held is None else _described(held)


def holds_frames(directory: str) -> bool:
    """Whether *directory* holds a recording of radarodom's with data in it, which a recording
    refuses to write over and ``--overwrite`` replaces."""
    return own_recording(directory) is not None


def foreign_files(directory: str) -> list[str]:
    """The files a recording would write in *directory* that radarodom did not (there without a
    capture.json of radarodom's): a recording would replace or remove them."""
    return [] if _own_metadata(directory) else _recording_files_in(directory)


def foreign_files_message(directory: str, names: list[str]) -> str:
    return (f"{directory} already holds {', '.join(names)} not written by radarodom (no {METADATA} of its "
            f"own), which a recording would replace and --overwrite leaves alone; choose a new directory "
            f"or move them away (nothing in it was changed)")


def check_recording_directory(directory: str) -> None:
    """Refuse (:class:`CaptureExistsError`) an existing *directory* a new recording may not write
    into: one holding files of a recording's names that radarodom did not write, or a recording
    of radarodom's with data in it.  Nothing is changed."""
    names = foreign_files(directory)
    if names:
        raise CaptureExistsError(foreign_files_message(directory, names))
    held = recorded_data(directory)
    if held:
        raise CaptureExistsError(f"{directory} already holds {_described(held)}; choose a new directory")


def claim_recording_directory(directory: str) -> None:
    """Check *directory* (an existing one) for a new recording (:func:`check_recording_directory`)
    and clear the recording of no data a run killed before it could clean up left there, so that
    the new one is recorded over it."""
    check_recording_directory(directory)
    if _recording_files_in(directory):
        log.info("%s holds a recording of no frame; recording over it", directory)
        remove_capture_files(directory)


def frames_kept(count: int) -> str:
    """What a recording whose next frame failed keeps, said: its *count* frames before."""
    return {0: "no frame was recorded", 1: "the frame before it is kept"}.get(
        count, f"the {count} frames before it are kept")


def abandon_recording(directory: str, made_directory: bool, open_fds=()) -> None:
    """A recording that could not start (a full disk, say): the files it opened (*open_fds*, None
    for one not opened) closed, those it began removed, and its directory if it made it, so that
    nothing half-made is left in the user's way."""
    for fd in open_fds:
        if fd is not None:
            with contextlib.suppress(OSError):
                os.close(fd)
    with contextlib.suppress(OSError):
        remove_capture_files(directory)
    if made_directory:
        with contextlib.suppress(OSError):  # something else was put there: leave it
            os.rmdir(directory)


def remove_capture_files(directory: str) -> None:
    """Remove the files a capture consists of from *directory*, a replay format's stream file
    among them (nothing else in it)."""
    for name in RECORDING_FILES:
        try:
            os.remove(os.path.join(directory, name))
        except FileNotFoundError:
            pass
