"""What ``--overwrite`` replaces, set aside until what replaces it holds data.

An output that ``--overwrite`` replaces (checked by :func:`.output_paths.check_new_path`) is not
removed before the run: a run that then fails before its first frame is written (another output
that cannot be created, a radar that does not answer, a full disk) would have lost the earlier
run's output and written nothing.  :class:`ReplacedOutputs` moves each one into a hidden directory
of its own (``.radarodom-replaced-XXXXXXXX``, made unique by :func:`tempfile.mkdtemp`): beside a
file, inside a capture or heatmap directory for the files radarodom wrote there (only those:
anything else there stays where it is).  Each old output is removed as soon as the new one holds
data (:meth:`ReplacedOutputs.drop_replaced`, called as frames are written: the disk gets its room
back at once), and when the run ends (:meth:`ReplacedOutputs.settle`) each whose new one holds none
is put back as it was.  A run killed outright (``kill -9``) leaves the hidden directories, to be
moved back by hand.
"""

from __future__ import annotations

import contextlib
import logging
import os
import tempfile
from dataclasses import dataclass, field
from typing import Iterable

from ..errors import CaptureError

log = logging.getLogger(__name__)

#: The prefix of the hidden directories the replaced outputs wait in.
HIDDEN_PREFIX = ".radarodom-replaced-"


def _own_files(directory: str, kind: str) -> list[str]:
    """The files radarodom wrote in a capture (*kind* "capture", its capture.json there) or
    heatmap ("heatmaps", its index.json there) *directory*; none in another directory."""
    from ..driver.recordings.recording_dir import RECORDING_FILES
    from ..pipeline.sinks import HeatmapSink

    if not os.path.isdir(directory):
        return []
    names = os.listdir(directory)
    if kind == "capture" and "capture.json" in names:
        return [name for name in RECORDING_FILES if name in names]
    if kind == "heatmaps" and HeatmapSink.INDEX in names:
        return sorted(name for name in names if HeatmapSink.owns(name))
    return []


def holds_data(path: str, kind: str) -> bool:
    """Whether the output at *path* holds what a run wrote: a file with a byte in it, a capture
    directory with a recording of radarodom's with data, a heatmap directory with a frame's heatmaps."""
    from ..driver.recordings.recording_dir import own_recording
    from ..pipeline.sinks import HeatmapSink

    try:
        if kind == "file":
            return os.path.isfile(path) and os.path.getsize(path) > 0
        if kind == "capture":
            return os.path.isdir(path) and own_recording(path) is not None
        return os.path.isdir(path) and any(HeatmapSink.owns(n) and not n.startswith(HeatmapSink.INDEX)
                                           for n in os.listdir(path))
    except OSError:
        return False


@dataclass
class _Aside:
    """One output set aside: where (*path*, its *kind*), and its files as (where each was, where it is)."""

    path: str
    kind: str
    moved: list[tuple[str, str]] = field(default_factory=list)


class ReplacedOutputs:
    """The existing outputs of a run with ``--overwrite``, set aside as it starts; see the module
    docstring.  *outputs*: (path, kind), *kind* "file", "capture" or "heatmaps"."""

    def __init__(self, outputs: Iterable[tuple[str, str]]) -> None:
        self._pending: list[_Aside] = []
        self._hidden: dict[str, str] = {}  # folder -> its hidden directory, made when first needed
        try:
            for path, kind in outputs:
                self._set_aside(path, kind)
        except BaseException as exc:  # (a Ctrl-C too): what was moved goes back
            self._put_back_all()
            if isinstance(exc, OSError):
                raise CaptureError(f"cannot replace {exc.filename}: {exc.strerror or exc}") from None
            raise

    def _hidden_dir(self, folder: str) -> str:
        if folder not in self._hidden:
            self._hidden[folder] = tempfile.mkdtemp(prefix=HIDDEN_PREFIX, dir=folder)
        return self._hidden[folder]

    def _set_aside(self, path: str, kind: str) -> None:
        if kind == "file":
            if not os.path.lexists(path) or os.path.isdir(path):  # (a link is moved, not what it names)
                return
            folder, names = os.path.dirname(os.path.abspath(path)), [os.path.basename(path)]
        else:
            folder, names = os.path.abspath(path), _own_files(path, kind)
            if not names:
                return
        aside = _Aside(path, kind)
        self._pending.append(aside)
        hidden = self._hidden_dir(folder)
        for name in names:
            was, now = os.path.join(folder, name), os.path.join(hidden, name)
            os.replace(was, now)
            aside.moved.append((was, now))

    def drop_replaced(self) -> None:
        """Remove each old output whose new one holds data now (cheap once all are: nothing left
        to look at)."""
        if not self._pending:
            return
        done = [aside for aside in self._pending if holds_data(aside.path, aside.kind)]
        for aside in done:
            self._pending.remove(aside)
            for _, now in aside.moved:
                try:
                    os.remove(now)
                except FileNotFoundError:
                    pass
                except OSError as exc:  # the run goes on; the old file stays where it waits
                    log.warning("could not remove %s, which --overwrite replaced: %s", now, exc.strerror or exc)
        if done:
            self._tidy()

    def settle(self) -> None:
        """The run has ended: each old output whose new one holds data is removed, each other
        put back as it was (over what the run left there, which holds nothing).  What could
        not be put back is said in one :class:`CaptureError`."""
        self.drop_replaced()
        failed = self._put_back_all()
        if failed:
            raise CaptureError(f"could not put the replaced output(s) back: {', '.join(failed)}; they are still "
                               "there under those names")

    def settle_after_error(self) -> None:
        """:meth:`settle` while the run's own error is on its way: a failure here is logged, so
        that the run's error is the one said."""
        try:
            self.settle()
        except CaptureError as exc:
            log.error("%s", exc)

    def _put_back_all(self) -> list[str]:
        failed: list[str] = []
        for aside in reversed(self._pending):
            for was, now in reversed(aside.moved):
                try:
                    os.replace(now, was)
                except FileNotFoundError:
                    pass
                except OSError as exc:
                    failed.append(f"{now} ({exc.strerror or exc})")
        self._pending = []
        self._tidy()
        return failed

    def _tidy(self) -> None:
        """Remove the hidden directories nothing waits in any more (only when empty)."""
        waiting = {os.path.dirname(now) for aside in self._pending for _, now in aside.moved}
        for folder, hidden in list(self._hidden.items()):
            if hidden not in waiting:
                with contextlib.suppress(OSError):
                    os.rmdir(hidden)
                del self._hidden[folder]
