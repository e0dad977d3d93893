"""The checks every program makes of the paths it writes, before the work: each output new (or,
with ``--overwrite``, replaceable), none an input of the same run nor a file a recording, a
ColoRadar run or its calibration holds, none another output's; and the writes themselves, whole
or not at all.  Each refusal a :class:`UsageError` (exit 2) or :class:`CaptureError` naming the
path and the option."""

from __future__ import annotations

import os
from typing import Mapping, Sequence

# The explanations live with the errors, for the library's writers too (the view's .rrd).
from ..errors import (CHOOSE_WRITABLE, CaptureError, CaptureExistsError, UsageError, kind_of_file, no_directory,
                      why_not_written)


def check_new_path(path: str, *, is_dir: bool = False, overwrite: bool = False, what: str | None = None,
                   kind: str = "capture", option: str | None = None) -> None:
    """Refuse an output that exists (a file, or a directory holding what radarodom wrote of its
    *kind*; the rest of a directory is checked by its writer) or cannot be created (no parent
    directory): radarodom never overwrites what a user has.

    With *overwrite* (the programs' ``--overwrite``) an existing file is accepted, and
    :class:`.replaced_outputs.ReplacedOutputs` then sets it aside (and radarodom's own files
    from a capture or heatmap directory it wrote), removed once the run has written a frame.  A
    directory in place of a file is still refused, and so is, by its writer, a directory that
    holds data radarodom did not write.  *what*: what is written there,
    for the message ("cannot write the copy of NAME to PATH").  *kind*: what a directory output
    holds ("capture", the default, or "heatmaps"): an existing one of that kind radarodom wrote is
    refused here without *overwrite*, with the option's name (its writer would refuse it without).
    *option*: the option that names *path*, for the message that refuses a recording's file."""
    target = f"write {what} to {path}" if what else f"create {path}"
    longest = _longest_path(_nearest_there(os.path.dirname(os.path.abspath(path))))
    if len(os.fsencode(os.path.abspath(path))) >= longest:  # no mkdir -p could make its directory
        raise UsageError(f"cannot create {_shortened_path(path)}: the path is longer than this system takes "
                         f"({longest} bytes); choose a shorter one")
    if not is_dir:
        _refuse_a_directory_name(path, f"cannot {target}")
        _refuse_a_recordings_file(path, f"{option} {path}" if option else f"cannot {target}")
    if is_dir and os.path.exists(path) and not os.path.isdir(path):
        raise CaptureExistsError(f"{path} is {kind_of_file(path)}, not a directory"
                                 + ("; --overwrite replaces only a directory radarodom wrote" if overwrite else ""))
    if not is_dir and os.path.lexists(path):
        if os.path.isdir(path):  # --overwrite would not help: said before it is tried
            raise CaptureExistsError(f"{path} is a directory; choose a file's name (--overwrite replaces only a file)")
        if not os.path.isfile(path):  # a device (/dev/null), a pipe, a socket, a dangling link
            raise CaptureExistsError(f"{path} is not a regular file: outputs are written to files, new ones or, "
                                     "with --overwrite, files replaced; choose a file's name (to write nothing, "
                                     "leave the option out)")
        if not overwrite:
            raise CaptureExistsError(f"{path} already exists; choose a new file (or --overwrite)")
    if is_dir and os.path.isdir(path):  # an existing directory: written into, whatever is above it
        if not os.access(path, os.W_OK | os.X_OK):
            raise UsageError(f"cannot write into {path}: the directory is not writable; {CHOOSE_WRITABLE}")
        held = None if overwrite else _own_output_in(path, kind)
        if held:  # its writer would refuse it too, but without the option that replaces it
            raise CaptureExistsError(f"{path} already holds {held}; choose a new directory (or --overwrite)")
        return
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):  # a path mistyped: a usage error, as a file where a directory goes
        raise UsageError(f"cannot {target}: {no_directory(parent)}")
    if not os.access(parent, os.W_OK | os.X_OK):  # before the work, not after (a replacement is a new file too)
        raise UsageError(f"cannot {target}: the directory {parent} is not writable; {CHOOSE_WRITABLE}")
    if not is_dir:
        name_bytes, longest = len(os.fsencode(os.path.basename(path))), _longest_name(parent)
        if name_bytes > longest:  # it failed after the source had opened
            raise UsageError(f"cannot {target}: its name is {name_bytes} bytes, more than the {longest} this "
                             "file system takes; choose a shorter name")


def _refuse_a_directory_name(path: str, what: str) -> None:
    """A file's path that ends in a separator names a directory (``runs/new/``): the checks of
    its parent, made on the path without it, passed, and the write failed after the work."""
    if path.endswith(tuple(sep for sep in (os.sep, os.altsep) if sep)):
        raise UsageError(f"{what}: the path ends in '{path[-1]}', which names a directory; give a file's name")


def _refuse_a_recordings_file(path: str, what: str) -> None:
    """A file of a recording of radarodom's (its ground truth, timestamps, cfg, ...) is no output's
    to replace, ``--overwrite`` or not: the recording would be changed or lost without a word
    (another run's odometry as its ground truth, another calibration line over its frames)."""
    real = os.path.realpath(path)
    directory = os.path.dirname(real)
    if _recordings_own(directory, real) and _own_output_in(directory, "capture"):
        raise UsageError(f"{what}: {os.path.basename(real)} is a file of the recording in "
                         f"{os.path.dirname(path) or os.curdir}, which no output replaces (--overwrite or not); "
                         f"choose another name or directory")


def _own_output_in(directory: str, kind: str) -> str | None:
    """What of *kind* radarodom wrote that *directory* holds, which ``--overwrite`` replaces: a
    capture of a frame or more (with its capture.json) or heatmaps; None when it holds none."""
    from ..driver.recordings.recording_dir import own_recording
    from ..pipeline.sinks import HeatmapSink

    if kind == "capture":
        return own_recording(directory)
    if kind == "heatmaps" and os.path.exists(os.path.join(directory, HeatmapSink.INDEX)):
        return "heatmaps"
    return None


def missing_directories(path: str) -> list[str]:
    """The directories ``os.makedirs(path)`` would make, deepest first (none when *path* is there)."""
    missing, there = [], os.path.abspath(path)
    while not os.path.exists(there):
        missing.append(there)
        there = os.path.dirname(there)
    return missing


def _nearest_there(path: str) -> str:
    """*path* (absolute) when it is there, else the nearest directory above it that is."""
    missing = missing_directories(path)
    return os.path.dirname(missing[-1]) if missing else os.path.abspath(path)


#: Bytes a directory output's path leaves for the names written in it: '/', the longest name (a
#: temporary '.groundtruth.tum.XXXXXXXX.tmp' or a frame's '1000000_intensity.npy' is about 30)
#: with room to spare; PATH_MAX counts the NUL that ends a path too (hence >=).
ROOM_FOR_NAMES = 48


def check_writable_directory(path: str, option: str) -> None:
    """Refuse a directory output (made when missing, with its parents) that could not be written
    into: itself, or the nearest directory above it that is there."""
    link = next((p for p in (path, *missing_directories(path)) if os.path.islink(p)), None)
    if link is not None:  # a link to nothing (or a loop) where a directory is to be made: not "File exists"
        raise UsageError(f"{option} {path}: {link} is {kind_of_file(link)}, not a directory; "
                         f"choose a directory's name")
    there = _nearest_there(path)
    longest = _longest_path(there)
    if len(os.fsencode(os.path.abspath(path))) + ROOM_FOR_NAMES >= longest:
        # made part by part, the directories were made before the first file's name failed
        raise UsageError(f"{option} {_shortened_path(path)}: the path is longer than this system takes "
                         f"({longest} bytes with the files written in it); choose a shorter one")
    if not os.path.isdir(there):  # a file where a directory goes (notes.txt/run)
        raise UsageError(f"{option} {path}: {no_directory(os.path.abspath(path))}")
    if not os.access(there, os.W_OK | os.X_OK):
        raise UsageError(f"{option} {path}: the directory {there} is not writable; {CHOOSE_WRITABLE}")


def _longest_name(directory: str) -> int:
    try:
        return os.pathconf(directory, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def _longest_path(directory: str) -> int:
    try:
        return os.pathconf(directory, "PC_PATH_MAX")
    except (OSError, ValueError):
        return 4096


def _shortened_path(path: str) -> str:
    return path if len(path) <= 100 else f"{path[:45]}...{path[-45:]} ({len(path)} characters)"


def check_room(path: str, needed_bytes: int, option: str, what: str, reclaimed_bytes: int = 0) -> None:
    """Refuse an output of *needed_bytes* where the file system it would be on (*path*'s, or the
    nearest directory above it that is there) has not that much free, counting *reclaimed_bytes*
    that replacing an earlier output frees; where the free space cannot be told, nothing is said."""
    try:
        st = os.statvfs(_nearest_there(path))
    except (OSError, AttributeError):  # no statvfs (Windows): the write itself says so
        return
    if st.f_blocks == 0:  # a file system of no size (/proc): the write itself says what it takes
        return
    free = st.f_bavail * st.f_frsize + reclaimed_bytes
    if needed_bytes > free:
        raise UsageError(f"{option} {path}: {what} takes {_gigabytes(needed_bytes)}, and {_gigabytes(free)} is "
                         f"free there: ask for less, free some space, or choose another disk")


def _gigabytes(n: int) -> str:
    return f"{n / 1e9:,.1f} GB" if n >= 1e8 else f"{n / 1e6:,.1f} MB"


def check_distinct(outputs: Sequence[tuple[str, str]], inputs: Sequence[tuple[str, str]] = ()) -> None:
    """Refuse two outputs that name one path, or an output that names an input of the same run
    or one of the files of a recording or run given as an input directory (new files beside
    them, or written there before, are fine); each (what, path), *what* an option's name."""
    seen: dict[str, str] = {}
    for what, path in outputs:
        real = os.path.realpath(path)
        if real in seen:
            raise UsageError(f"{seen[real]} and {what} both name {path}: give each its own")
        seen[real] = what
        for source, given in inputs:
            src = os.path.realpath(given)
            owns = os.path.isdir(src) and (_recordings_own(src, real) or _calibrations_own(src, real))
            if real == src or owns and os.path.lexists(real):
                raise UsageError(f"{what} {path} would write over the input {source} {given}: "
                                 "choose another path")
            if owns:  # a new file, in one of the recording's or dataset's own folders: left as they came
                raise UsageError(f"{what} {path} would write into the input {source} {given}'s own folders: "
                                 "choose another path (beside them is fine)")


def read_paths(options: Sequence[tuple[str, str | None]], source: str | None = None,
               source_option: str = "--source") -> list[tuple[str, str]]:
    """(option, path) of what a run reads, for :func:`check_distinct`: the files given in
    *options* ((option, path or None); a ``--cfg`` not given is the shipped cfg) and the
    recording or ColoRadar run the *source* URL streams (``replay://DIR``, ``coloradar://DIR``) or
    the scene file it simulates (``sim://FILE``), named *source_option*."""
    from ..cfg import shipped_config_path
    from ..driver.sources import split_url

    # --cfg not given: the shipped cfg is what the run reads (a writer over it changed the install).
    inputs = [(option, path) if path or option != "--cfg" else ("--cfg (not given: the shipped cfg)",
                                                                str(shipped_config_path()))
              for option, path in options]
    if source:
        scheme, path, query = split_url(source)
        path = os.path.expanduser(path or "")
        if scheme in ("replay", "coloradar") and path or scheme == "sim" and os.path.isfile(path):
            inputs.append((source_option, path))
        if scheme == "coloradar" and path:
            inputs.append(("the run's calibration", _coloradar_calibration(path, query)))
    return [(what, path) for what, path in inputs if path]


def _coloradar_calibration(run: str, query: str) -> str | None:
    """The calibration folder a ColoRadar run is read with: ``calib=``, else the one found."""
    from urllib.parse import parse_qs

    from ..driver.coloradar.run import found_calibration

    given = parse_qs(query).get("calib")
    return os.path.expanduser(given[-1]) if given else found_calibration(run)


def _calibrations_own(directory: str, path: str) -> bool:
    """Whether *path* lies in *directory*, a ColoRadar calibration folder (its transforms/):
    every file of it is the dataset's."""
    return path.startswith(directory + os.sep) and os.path.isdir(os.path.join(directory, "transforms"))


def _recordings_own(directory: str, path: str) -> bool:
    """Whether *path* is (or lies in) a file or folder the recording or run in *directory* came
    with: a capture's or a TI recording's files, a ColoRadar run's stream folders."""
    if not path.startswith(directory + os.sep):
        return False
    first = path[len(directory) + 1:].split(os.sep)[0]
    from ..driver.coloradar.files import STREAMS
    from ..driver.recordings.capture_writer import RECORDING_FILES
    from ..driver.recordings.ti_recorder import SERIES_PATTERN

    return (first in RECORDING_FILES or bool(SERIES_PATTERN.match(first))
            or first in {stream.split("/")[0] for stream in STREAMS} or first == "calib")


def check_files_in_directories(outputs: Sequence[tuple[str, str, str]]) -> None:
    """Refuse a file output that names a file a directory output of the same run writes (a
    recording's ``timestamps.txt``, a heatmap directory's ``index.json``); each (path, kind,
    option), *kind* as :class:`.replaced_outputs.ReplacedOutputs` takes it."""
    for directory, kind, option in outputs:
        if kind == "file":
            continue
        real_dir = os.path.realpath(directory)
        for path, file_kind, file_option in outputs:
            if file_kind != "file":
                continue
            real = os.path.realpath(path)
            if real == real_dir:
                raise UsageError(f"{file_option} and {option} both name {path}: give each its own")
            if (_recordings_own(real_dir, real) if kind == "capture" else
                    os.path.dirname(real) == real_dir and _heatmaps_own(os.path.basename(real))):
                raise UsageError(f"{file_option} {path} is a file {option} writes: choose another name")


def check_new_outputs(outputs: Sequence[tuple[str, str, str]], *, overwrite: bool,
                      what: Mapping[str, str] | None = None) -> None:
    """Each output new, or with *overwrite* replaceable (:func:`check_new_path`); each (path,
    kind, option), *kind* as :class:`.replaced_outputs.ReplacedOutputs` takes it; *what*: what an option writes, by
    option, for its messages ("cannot write the view to PATH").  A file may go into a directory
    output the run makes (its writer is opened after the directory's); a recording directory
    holding files of a recording's names that radarodom did not write is refused here, before
    ``--overwrite`` replaces the other outputs (its writer would refuse it only then)."""
    from ..driver.recordings.recording_dir import foreign_files, foreign_files_message

    made = {os.path.realpath(path) for path, kind, _ in outputs if kind != "file" and not os.path.exists(path)}
    for path, kind, option in outputs:
        if kind == "file":
            _refuse_a_directory_name(path, f"{option} {path}")
        if kind != "file" and not os.path.exists(path):
            check_writable_directory(path, option)  # the rest by its writer (which makes its parents)
            continue
        if kind == "file" and os.path.dirname(os.path.realpath(path)) in made:
            continue
        theirs = kind == "capture" and os.path.isdir(path) and foreign_files(path)
        if theirs:
            raise CaptureExistsError(foreign_files_message(path, theirs))
        check_new_path(path, is_dir=kind != "file", overwrite=overwrite, what=(what or {}).get(option), kind=kind,
                       option=option)


def _heatmaps_own(name: str) -> bool:
    """Whether *name* is one of the files radarodom writes in a heatmap directory."""
    from ..pipeline.sinks import HeatmapSink

    return HeatmapSink.owns(name)


def write_output(path: str, text: str, *, overwrite: bool, what: str | None = None) -> None:
    """Write a file output (checked by :func:`check_new_path`) whole or not at all: a symbolic
    link in its place is replaced, as ``--overwrite`` replaces every output, never the file it
    names; without *overwrite* a file that appeared there while the program ran is left alone.
    A failure is a :class:`CaptureError` naming the file (and *what* was written to it), why
    and what to do."""
    from ..whole_files import write_text_atomically

    try:
        write_text_atomically(path, text, replace=overwrite)
    except FileExistsError:
        raise CaptureError(f"{path} appeared while this ran; not replaced (without --overwrite)") from None
    except OSError as exc:
        written = f"{what} to {path}" if what else path
        raise CaptureError(f"cannot write {written}: {why_not_written(exc, path)}") from None
