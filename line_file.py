"""New text files written whole lines at a time, with nothing half-written left behind.

:class:`LineFile` writes each call's lines straight to the kernel (no buffer to lose when the
process is killed); where a write fails (a full disk, a file-size limit) it cuts the file back
to the lines before, so that the file holds whole lines only, and says so in one
:class:`~radarodom.errors.CaptureError` naming the file.  The odometry's TUM file, its JSON
lines and the point clouds' CSV use it.
"""

from __future__ import annotations

import contextlib
import os

from .errors import CaptureError, CaptureExistsError, why_not_written


def write_file_all(fd: int, data) -> None:
    """All of *data* (a bytes-like object) to the file descriptor *fd*, however many writes it takes."""
    view = memoryview(data).cast("B")
    while view:
        view = view[os.write(fd, view):]


class LineFile:
    """A new text file (ASCII, "\\n" lines) written a call's whole lines at a time, unbuffered:
    lines whose writing fails are cut off again, so the file holds the lines before them whole,
    and the error names the file (:class:`CaptureError`).  An existing file is refused
    (:class:`CaptureExistsError`): radarodom never writes over recorded data."""

    def __init__(self, path: str) -> None:
        self.path = path
        try:
            self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_APPEND, 0o666)
        except FileExistsError:
            raise CaptureExistsError(f"{path} already exists; choose a new file") from None
        except OSError as exc:
            raise CaptureError(f"cannot create {path}: {why_not_written(exc, path)}") from None
        self._size = 0

    def write(self, text: str) -> None:
        """*text*, whole lines."""
        if self._fd < 0:
            raise CaptureError(f"{self.path}: the file is closed")
        data = text.encode("ascii")
        try:
            write_file_all(self._fd, data)
        except OSError as exc:
            with contextlib.suppress(OSError):
                os.ftruncate(self._fd, self._size)
            raise CaptureError(f"writing {self.path} failed: {exc.strerror or exc}; the lines before are "
                               "kept whole") from None
        self._size += len(data)

    @property
    def closed(self) -> bool:
        return self._fd < 0

    def close(self) -> None:
        """Close the file, once (again: nothing)."""
        if self._fd >= 0:
            fd, self._fd = self._fd, -1
            try:
                os.close(fd)
            except OSError as exc:  # NFS reports some write errors only here
                raise CaptureError(f"closing {self.path} failed: {exc.strerror or exc}") from None
