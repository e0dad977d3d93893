"""The one exception family of radarodom.

Every error the library raises on purpose derives from :class:`RadarodomError`.
Each class carries the process exit code the command-line tools map it to
(one place: :func:`radarodom.tools.cli.run`): 2 for usage and configuration
errors, 1 for failures at run time.
"""

from __future__ import annotations

import errno
import json
import os
import stat
import unicodedata
from typing import Any


#: Characters of a bad value an error message quotes; longer input is cut with its length said.
QUOTED_CHARS = 40


def quoted(value: Any, limit: int = QUOTED_CHARS) -> str:
    """*value* as an error message quotes it: its repr, cut after *limit* characters (of the text
    itself for a string, of the repr otherwise) with the length said, so that a megabyte of
    hostile input is never echoed whole."""
    if isinstance(value, str):
        return repr(value) if len(value) <= limit else f"{value[:limit]!r}... ({len(value)} characters)"
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def quoted_json(value: Any, limit: int = QUOTED_CHARS) -> str:
    """*value* read from a JSON file as an error message quotes it: :func:`quoted`, with JSON's
    own spelling of ``null``, ``true`` and ``false`` (the file's words, not Python's)."""
    if isinstance(value, str):
        return quoted(value, limit)
    try:
        text = json.dumps(value, allow_nan=False)
    except (TypeError, ValueError):  # not a JSON value after all
        return quoted(value, limit)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def one_line(text: str) -> str:
    """*text* as a terminal line shows it: its control characters (a path's newline, an escape
    sequence that would clear the screen) written as Python escapes, ``\\n``, ``\\x1b``."""
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() else ch.encode("unicode_escape").decode("ascii") for ch in text)


def named_character(ch: str) -> str:
    """A character as an error message names it, whatever a terminal would make of it:
    ``U+00A0 (no-break space)``."""
    return f"U+{ord(ch):04X} ({(unicodedata.name(ch, '') or 'control character').lower()})"


def given_path(path: Any, error: type[RadarodomError], what: str = "file path") -> str:
    """A file or directory path given to the public API, as text: a str, an os.PathLike or bytes
    (decoded as the file system does).  Anything else, or a path with a NUL character (which no
    file system allows), raises *error*, the caller's own kind of error, saying so (*what*: the
    kind of path expected)."""
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if not isinstance(path, (str, os.PathLike)):
        raise error(f"expected a {what}, got {type(path).__name__}")
    text = os.fspath(path)
    if isinstance(text, bytes):  # an os.PathLike may give bytes
        text = os.fsdecode(text)
    if "\0" in text:
        raise error(f"a path cannot contain a NUL character: {quoted(text)}")
    return text


#: The fix for an output that cannot be written where it was asked.
CHOOSE_WRITABLE = "choose a writable destination"


def kind_of_file(path: str) -> str:
    """What stands at *path*, which is no directory, as a message names it: "a file", "a device",
    "a pipe", "a socket", "a link to nothing" or "a link in a loop"."""
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        return "a link in a loop" if exc.errno == errno.ELOOP else "a link to nothing"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISFIFO(mode):
        return "a pipe"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a file"


def no_directory(parent: str) -> str:
    """Why no file can be made in *parent*, a directory that is not there, and the fix: the nearest
    path above it that is there is a file ("no directory a/b" would hide that a is a file), or
    the directory is missing (a path mistyped, or a directory not made yet)."""
    above = parent
    while not os.path.lexists(above):
        above = os.path.dirname(above)
    if not os.path.isdir(above):
        return f"{above} is {kind_of_file(above)}, not a directory; {CHOOSE_WRITABLE}"
    return f"no directory {parent}; make it first (mkdir -p {parent}) or {CHOOSE_WRITABLE}"


def why_not_written(exc: OSError, path: str) -> str:
    """Why the file *path* could not be written (*exc*), in the user's terms, and the fix: the
    kernel's words alone ("No such file or directory" for a new file in /proc, whose directory
    is there) name neither the directory nor what to do."""
    said = exc.strerror or str(exc)
    parent = os.path.dirname(os.path.abspath(path))
    if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
        return f"{said}; free some space, or choose another disk"
    if exc.errno == errno.EROFS:
        return f"the directory {parent} is on a read-only file system ({said}); {CHOOSE_WRITABLE}"
    if exc.errno in (errno.EACCES, errno.EPERM):
        return f"no permission to make a file in the directory {parent} ({said}); {CHOOSE_WRITABLE}"
    if exc.errno == errno.ENOENT and os.path.isdir(parent):  # /proc, /sys: the kernel's, no storage
        return f"the directory {parent} takes no new files (the system says: {said}); {CHOOSE_WRITABLE}"
    if exc.errno in (errno.ENOENT, errno.ENOTDIR) and not os.path.isdir(parent):  # a path not checked before
        return no_directory(parent)
    return f"{said}; {CHOOSE_WRITABLE}"


class RadarodomError(Exception):
    """Base class of all radarodom errors."""

    #: Exit code of a command-line tool that stops on this error.
    exit_code = 1


class UsageError(RadarodomError):
    """The caller asked for something that cannot be done as asked
    (bad option, bad URL, missing argument)."""

    exit_code = 2


class SourceError(UsageError):
    """A source URL names an unknown scheme or option, or a bad value."""


class ConfigError(RadarodomError):
    """A radar configuration (TI ``.cfg``) is malformed, inconsistent or
    asks for a mode radarodom does not support.

    The message names where: ``file:line: command: field: what is wrong``.
    """

    exit_code = 2

    def __init__(
        self,
        message: str,
        *,
        path: str | os.PathLike | None = None,
        line: int | None = None,
        command: str | None = None,
        field: str | None = None,
    ) -> None:
        self.message = message
        self.path = None if path is None else os.fspath(path)
        self.line = line
        self.command = command
        self.field = field
        super().__init__(self._render())

    def located(self, *, path: str | os.PathLike | None = None, field: str | None = None,
                command: str | None = ...) -> "ConfigError":
        """This error, told where it is as it travels up: the file it came from (*path*, when
        it names none yet), its field's full path (*field*), its command (None: none); returns
        itself, its message rendered again."""
        if path is not None and self.path is None:
            self.path = os.fspath(path)
        if field is not None:
            self.field = field
        if command is not ...:
            self.command = command
        self.args = (self._render(),)
        return self

    def _render(self) -> str:
        where = self.path or ("<cfg>" if self.line is not None else "")  # settings made in code have no file
        if self.line is not None:
            where += f":{self.line}"
        parts = [where] if where else []
        if self.command:
            parts.append(self.command)
        if self.field:
            parts.append(self.field)
        return ": ".join(parts + [self.message])


class DeviceError(RadarodomError):
    """The radar or the DCA1000 did not do what was asked: no answer in time,
    an error reply, a failure status, a port that went away."""


class DeviceTimeout(DeviceError):
    """A device did not answer within its timeout."""


class RadarCommandError(DeviceError):
    """The radar refused a configuration line; the message names the cfg line
    and quotes the radar."""


class CaptureError(RadarodomError):
    """Reading or writing captured radar data failed (missing or corrupt
    capture directory, I/O error while recording)."""


class CaptureExistsError(CaptureError):
    """Recording was asked into a directory that already holds a capture;
    radarodom never overwrites recorded data."""

    exit_code = 2


class CaptureFormatError(CaptureError):
    """A capture file does not have the layout its configuration implies."""

    exit_code = 2


class CalibrationError(RadarodomError):
    """A channel calibration cannot be measured from what the radar sees: the corner reflector
    too weak, not alone, off boresight or moving, or a cfg that does not use every path.  The
    message says which, and how to set it up."""


class EvaluationError(UsageError):
    """Two trajectories cannot be compared as given: too few poses match in
    time, timestamps out of order, a bad evaluation parameter."""


class TimeOrderError(RadarodomError):
    """Measurements reached the estimator out of time order: a velocity earlier than the last
    one, or a heatmap frame not after the previous.  The source's timestamps are not strictly
    increasing; the message gives both times."""


class MessageError(RadarodomError):
    """A message on the wire does not follow its schema (wrong magic, version,
    size or field), or a value cannot be encoded (NaN, infinity, bad shape)."""


class PublishError(RadarodomError):
    """Publishing over Zenoh failed at run time: the session could not open
    (a router that does not answer in client mode, a port in use), or a
    publisher was used after it was closed."""


class PublishConfigError(PublishError):
    """The Zenoh session options are unusable as given: an unreadable or
    invalid config file, a malformed endpoint, key prefix or mode, or the ROS 2
    output asked for without its dependency."""

    exit_code = 2


def add_note(exc: BaseException, note: str) -> None:
    """``exc.add_note(note)``, on Python 3.10 too (its ``__notes__``, which 3.11 prints and the
    programs print after the error's line): what failed after *exc*, such as closing outputs."""
    if hasattr(exc, "add_note"):
        exc.add_note(note)
    else:  # pragma: no cover - Python 3.10
        exc.__notes__ = [*getattr(exc, "__notes__", []), note]  # type: ignore[attr-defined]
