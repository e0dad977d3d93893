"""CFAR scales kept on disk once solved, so that the next program reads them instead.

A CFAR's scale for a false-alarm probability is solved by numerical integration and root finding
(:mod:`.cfar_pfa`, with scipy.integrate and scipy.optimize): importing those and solving took a
good part of the start of every program that builds a frame processor (docs/benchmarks.md,
"Start-up"). So each value solved is written to a small JSON file in the user's cache directory
and read back, bit for bit, by the programs that come after it.

The file's name carries a digest of :mod:`.cfar_pfa`'s source and of scipy's version: a change to
either starts a new file. Where: ``$RADARODOM_CACHE_DIR``, else ``$XDG_CACHE_HOME/radarodom``,
else ``~/.cache/radarodom``. A directory that cannot be read or written, or a damaged file (not
JSON, too large or deep, a scale that is no finite number above 0, a pipe or a directory in its
place), only means solving again (said at debug level; the file is then written anew); deleting
the files is always safe.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import math
import numbers
import os
import stat
from importlib import metadata
from typing import Callable

from .. import strict_json
from ..whole_files import write_text_atomically

log = logging.getLogger(__name__)

#: The largest kept-scales file read, bytes (a program's few dozen scales take a few kB).
MAX_FILE_BYTES = 1 << 20


def cache_dir() -> str:
    """The directory of the kept scales (see the module's docstring)."""
    given = os.environ.get("RADARODOM_CACHE_DIR")
    if given:
        return given
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "radarodom")


@functools.cache
def _version_digest() -> str:
    from . import cfar_pfa

    digest = hashlib.sha256()
    with open(cfar_pfa.__file__, "rb") as fh:
        digest.update(fh.read())
    try:
        digest.update(metadata.version("scipy").encode())
    except metadata.PackageNotFoundError:
        pass
    return digest.hexdigest()[:16]


def kept_path() -> str:
    """The file this program reads kept scales from and adds them to."""
    return os.path.join(cache_dir(), f"cfar-scales-{_version_digest()}.json")


def _read(path: str) -> dict[str, float]:
    """The scales in *path*; none when it is missing or damaged (a scale that is no finite number
    above 0, a file too deep or too large, or no regular file: a pipe there must not hang)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        return {}
    except OSError as exc:
        log.debug("kept CFAR scales in %s not read (%s): solving them again", path, exc)
        return {}
    try:
        with os.fdopen(fd, "rb") as fh:
            if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
                raise ValueError("not a regular file")
            data = strict_json.loads(fh.read(MAX_FILE_BYTES + 1), max_bytes=MAX_FILE_BYTES)
        if not isinstance(data, dict):
            raise ValueError("not a JSON object")
        for key, value in data.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
                raise ValueError(f"{key}: {value!r} is no scale (a finite number above 0)")
        return {key: float(value) for key, value in data.items()}
    except (OSError, ValueError) as exc:
        log.debug("kept CFAR scales in %s not read (%s): solving them again", path, exc)
        return {}


@functools.cache
def _entries(path: str) -> dict[str, float]:
    """The scales kept in *path*, read once a program; the program's own solves join them."""
    return _read(path)


def _write(path: str, key: str, value: float) -> None:
    # Read again and merged: other programs may have added to the file since this one read it
    # (two writing at once may each drop the other's newest entry, which is then solved again).
    entries = _read(path)
    entries[key] = value
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        write_text_atomically(path, json.dumps(entries, sort_keys=True, indent=0))
    except OSError as exc:
        log.debug("a solved CFAR scale not kept in %s (%s)", path, exc)


def _plain(arg):
    if isinstance(arg, bool) or arg is None or isinstance(arg, str):
        return arg
    if isinstance(arg, numbers.Integral):
        return int(arg)
    if isinstance(arg, numbers.Real):
        return float(arg)
    raise TypeError(f"a kept function's argument must be a number, a string or None, got {arg!r}")


def kept(fn: Callable[..., float]) -> Callable[..., float]:
    """*fn* (a pure function of numbers and strings, to a float) with its values kept on disk."""
    name = fn.__qualname__

    @functools.wraps(fn)
    def wrapper(*args) -> float:
        args = tuple(_plain(a) for a in args)
        key = f"{name}{args!r}"
        path = kept_path()
        entries = _entries(path)
        if key not in entries:
            entries[key] = float(fn(*args))
            _write(path, key, entries[key])
        return entries[key]

    return wrapper


__all__ = ["cache_dir", "kept", "kept_path"]
