"""Files written whole or not at all: a new file beside the one to write, renamed over it.

:func:`write_bytes_atomically` and :func:`write_text_atomically` serve the user's outputs (plots,
recordings' text files, cfgs) and the caches radarodom keeps (:mod:`.dsp.kept_scales`): a reader, or
a crash, never sees half a file.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile


def write_text_atomically(path: str, text: str, *, replace: bool = True) -> None:
    """Write *text* (UTF-8, its line ends as they are) to *path* as :func:`write_bytes_atomically`."""
    write_bytes_atomically(path, text.encode("utf-8"), replace=replace)


def write_bytes_atomically(path: str, data: bytes, *, replace: bool = True) -> None:
    """Write *data* to a user's output *path* whole or not at all, through a new file of its own
    beside it (``.NAME.XXXXXXXX.tmp``, never another file's: made exclusively, links not followed),
    renamed over *path*: a symbolic link at *path* is replaced itself, the file it named left as
    it was; a file replaced keeps its permissions, a new one gets the umask's.  Unless *replace*,
    a file that appeared at *path* meanwhile is not replaced (FileExistsError)."""
    directory, name = os.path.split(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "wb") as fh:
            os.fchmod(fh.fileno(), _mode_for(path))
            fh.write(data)
        if replace:
            os.replace(tmp, path)
        else:
            _put_new(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):  # a full disk: no empty copy left beside the file
            os.remove(tmp)
        raise


def _mode_for(path: str) -> int:
    """The permissions of the regular file at *path* (not through a link), else a new file's."""
    try:
        st = os.lstat(path)
        if stat.S_ISREG(st.st_mode):
            return stat.S_IMODE(st.st_mode)
    except FileNotFoundError:
        pass
    umask = os.umask(0o022)  # read by setting it back at once (no call reads it alone)
    os.umask(umask)
    return 0o666 & ~umask


def _put_new(tmp: str, path: str) -> None:
    """Move *tmp* to *path* only if nothing is there (FileExistsError otherwise)."""
    try:
        os.link(tmp, path)  # fails if *path* exists, whatever it is
    except FileExistsError:
        raise
    except OSError:  # a file system without hard links: checked, then renamed
        if os.path.lexists(path):
            raise FileExistsError(errno.EEXIST, "File exists", path) from None
        os.replace(tmp, path)
        return
    os.remove(tmp)
