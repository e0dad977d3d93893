"""What ``--overwrite`` replaces, set aside until the run has something to put in its place.

An output that ``--overwrite`` replaces (checked by :func:`.output_paths.check_new_path`) is not
removed before the run: a run that then fails before its first frame (another output that cannot
be created, a radar that does not answer) would have lost the earlier run's file and written
nothing.  :class:`ReplacedOutputs` renames each one beside itself instead: a file to a hidden
name in its directory (``.NAME.replaced-PID``), and the files radarodom wrote in a capture or
heatmap directory (only those: anything else there stays where it is) into a hidden directory in
it (``.radarodom-replaced-PID``).  Once the run has written a frame, :meth:`ReplacedOutputs.settle`
removes what was set aside; when it wrote none (its own new outputs then removed by their
writers), it puts everything back as it was.  A run killed outright (``kill -9``) leaves the
hidden names, to be renamed back by hand.
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
from typing import Iterable

from ..errors import CaptureError

log = logging.getLogger(__name__)


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


class ReplacedOutputs:
    """The existing outputs of a run with ``--overwrite``, set aside as it starts; see the module
    docstring.  *outputs*: (path, kind), *kind* "file", "capture" or "heatmaps"."""

    def __init__(self, outputs: Iterable[tuple[str, str]]) -> None:
        #: (where it was, where it is now, the hidden directory it is in or None for a file).
        self._aside: list[tuple[str, str, str | None]] = []
        try:
            for path, kind in outputs:
                self._set_aside(path, kind)
        except OSError as exc:
            self.settle(kept=False)
            raise CaptureError(f"cannot replace {exc.filename}: {exc.strerror or exc}") from None

    def _set_aside(self, path: str, kind: str) -> None:
        if kind == "file":
            if os.path.lexists(path) and not os.path.isdir(path):  # a link is replaced, not what it names
                folder, name = os.path.split(os.path.abspath(path))
                hidden = os.path.join(folder, f".{name}.replaced-{os.getpid()}")
                os.replace(path, hidden)
                self._aside.append((path, hidden, None))
            return
        names = _own_files(path, kind)
        if not names:
            return
        hidden_dir = os.path.join(path, f".radarodom-replaced-{os.getpid()}")
        os.makedirs(hidden_dir, exist_ok=True)
        for name in names:
            os.replace(os.path.join(path, name), os.path.join(hidden_dir, name))
            self._aside.append((os.path.join(path, name), os.path.join(hidden_dir, name), hidden_dir))

    def settle(self, kept: bool) -> None:
        """Remove what was set aside when the run *kept* frames in its outputs; else put it back
        (over what the run left there, which holds no frame).  Each step is tried whatever the
        others do; what could not be done is said in one :class:`CaptureError`."""
        failed: list[str] = []
        for was, now, _ in reversed(self._aside):
            try:
                if kept:
                    os.remove(now)
                else:
                    os.replace(now, was)
            except FileNotFoundError:
                pass
            except OSError as exc:
                failed.append(f"{now} ({exc.strerror or exc})")
        for hidden_dir in dict.fromkeys(d for _, _, d in self._aside if d is not None):
            if kept:
                shutil.rmtree(hidden_dir, ignore_errors=True)
            else:  # only when empty: what could not be put back stays in it
                with contextlib.suppress(OSError):
                    os.rmdir(hidden_dir)
        self._aside = []
        if failed:
            what = "remove the replaced output(s)" if kept else "put the replaced output(s) back"
            raise CaptureError(f"could not {what}: {', '.join(failed)}; they are still there under those names")

    def settle_after_error(self, kept: bool) -> None:
        """:meth:`settle` while the run's own error is on its way: a failure here is logged, so
        that the run's error is the one said."""
        try:
            self.settle(kept)
        except CaptureError as exc:
            log.error("%s", exc)
