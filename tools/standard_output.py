"""The programs' standard output, watched: a write to it that fails (a full disk it was sent
to) is told apart from the program's own errors, so that it is said in one line, not as an
"internal error" from inside ``print``; and what stays in its buffer is dropped, not reported
again by Python at exit.
"""

from __future__ import annotations

import contextlib
import errno
import os
import sys
from typing import Any, Iterator, TextIO


class StdoutFailed(Exception):
    """Writing to the standard output failed with :attr:`error` (not a closed pipe: that one
    ends a program quietly, as ``| head`` means)."""

    def __init__(self, error: OSError) -> None:
        super().__init__(str(error))
        self.error = error


class _Watched:
    """*stream* whose writes and flushes raise :class:`StdoutFailed` for an OSError."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        return self._call(self._stream.write, text)

    def flush(self) -> None:
        self._call(self._stream.flush)

    @staticmethod
    def _call(method: Any, *args: Any) -> Any:
        try:
            return method(*args)
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise StdoutFailed(exc) from None

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


class _Closed:
    """The standard output of a program started with it closed (``>&-``: Python's ``sys.stdout``
    is None): what is written to it fails as a write to a full disk does, instead of vanishing
    (``print``) or ending in an AttributeError (``sys.stdout.write``); nothing written, nothing
    said."""

    def write(self, text: str) -> int:
        if text:
            raise StdoutFailed(OSError(errno.EBADF, "it is closed"))
        return 0

    def flush(self) -> None:
        pass

    def isatty(self) -> bool:
        return False


@contextlib.contextmanager
def watched_stdout() -> Iterator[None]:
    """``sys.stdout`` watched while the block runs (a closed one stood in for)."""
    stream = sys.stdout
    if isinstance(stream, (_Watched, _Closed)):
        yield
        return
    sys.stdout = _Closed() if stream is None else _Watched(stream)  # type: ignore[assignment]
    try:
        yield
    finally:
        if sys.stdout.__class__ in (_Watched, _Closed):
            sys.stdout = stream


def flush_stdout() -> None:
    """Send what is buffered: a failure raises :class:`StdoutFailed` while still watched."""
    if sys.stdout is not None:
        sys.stdout.flush()


def stdout_failure(prog: str, failed: StdoutFailed) -> str:
    """The one line that says so, with the fix for a full disk; what the failed stream still
    buffers is sent to /dev/null, so that Python's flush at exit does not report it again."""
    exc = failed.error
    full = exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
    with contextlib.suppress(OSError, ValueError, AttributeError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.__stdout__.fileno())
        os.close(devnull)
    return (f"{prog}: error: cannot write to the standard output: {exc.strerror or exc}"
            + ("; free some space, or send it elsewhere" if full else ""))
