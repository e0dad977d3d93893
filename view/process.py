"""The view's drawing in a process of its own (what ``radar-capture --view`` runs).

Drawing with Rerun is mostly Python (colours, resampling, Rerun's own conversion of each entity):
in the radar's process it would hold the interpreter lock against the pipeline's thread.  Here the
sink's sender thread pickles each frame's tracks, point cloud and heatmap into a pipe (a copy of
about 0.2 MB) and a child process (started with ``spawn``: nothing of the radar's threads or
sockets is inherited) opens the Rerun target and draws.  When the child lags, the pipe fills, the
sender thread waits and the sink's queue drops the radar's newest frames.  A viewer that stops
reading can hold up Rerun's shutdown indefinitely: then the child is stopped after the sink's
close timeout, and the radar's process still ends.

Messages, parent to child: ``("draw", tracks, frame_or_None, dropped, offered)``, ``("end",)``;
child to parent: ``("ready", where)`` or ``("error", kind, message)`` once, then
``("done", drawn, failure)`` and ``("closed",)``.
"""

from __future__ import annotations

import logging
import multiprocessing
import signal
from typing import TYPE_CHECKING

from ..errors import CaptureError, RadarodomError, UsageError

if TYPE_CHECKING:
    from ..cfg import RadarConfig
    from ..estimator.config import EstimatorConfig
    from ..mount import Mount
    from .sink import FramePayload, Track
    from .target import ViewTarget

log = logging.getLogger(__name__)

#: How long the child may take to import Rerun and open its target, s.
START_TIMEOUT_S = 120.0
_ERRORS = {"UsageError": UsageError, "CaptureError": CaptureError}


class ProcessDrawer:
    """A child process that opens *target* and draws what it is sent (module docstring); raises
    what opening the target raised there (UsageError, CaptureError) or RadarodomError."""

    def __init__(self, target: ViewTarget, *, estimator: EstimatorConfig | None = None,
                 config: RadarConfig | None = None, mount: Mount | None = None) -> None:
        context = multiprocessing.get_context("spawn")
        self._conn, child = context.Pipe()
        self._process = context.Process(target=_child, args=(child, target, estimator, config, mount),
                                        name="radarodom-view", daemon=True)
        self._process.start()
        child.close()
        reply = self._receive(START_TIMEOUT_S)
        if reply is None or reply[0] != "ready":
            self._stop()
            if reply is None:
                raise RadarodomError(f"the view's process did not start within {START_TIMEOUT_S:.0f} s")
            raise _ERRORS.get(reply[1], RadarodomError)(reply[2])
        self.where: str = reply[1]

    def draw(self, tracks: list[Track], frame: FramePayload | None, dropped: int, offered: int) -> None:
        try:
            self._conn.send(("draw", tracks, frame, dropped, offered))
        except (BrokenPipeError, ConnectionResetError):
            pass  # the child is gone: close() says so

    def close(self, timeout_s: float) -> tuple[int | None, str | None]:
        try:
            self._conn.send(("end",))
        except (BrokenPipeError, ConnectionResetError):
            return self.abandon()
        done = self._receive(timeout_s)
        if done is None or done[0] != "done":
            return self.abandon()
        # Rerun's last flush: a viewer that stopped reading holds it up for good.
        closed = self._receive(timeout_s)
        if closed is None:
            log.warning("the viewer did not take the view's last data within %.0f s; the view's process was "
                        "stopped", timeout_s)
        self._stop()
        return done[1], done[2]

    def abandon(self) -> tuple[int | None, str | None]:
        self._stop()
        return None, None

    def _receive(self, timeout_s: float):
        try:
            return self._conn.recv() if self._conn.poll(timeout_s) else None
        except (EOFError, OSError):
            return None

    def _stop(self) -> None:
        self._process.join(1.0)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join(5.0)
        if self._process.is_alive():
            self._process.kill()
            self._process.join()
        self._conn.close()


def _child(conn, target: ViewTarget, estimator, config, mount) -> None:
    """The view's process: open *target*, draw until told to end (or the radar's process is gone)."""
    # Ctrl-C in a terminal reaches the whole process group: the radar's process decides when the
    # view ends (it drains what is queued first).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from .sink import ThreadDrawer
    from .target import open_scene

    try:
        scene, where = open_scene(target, estimator=estimator, config=config, mount=mount)
    except RadarodomError as exc:
        conn.send(("error", type(exc).__name__, str(exc)))
        return
    except Exception as exc:  # noqa: BLE001 (said to the parent, which raises it)
        conn.send(("error", "RadarodomError", f"the view could not open: {type(exc).__name__}: {exc}"))
        return
    conn.send(("ready", where))
    drawer = ThreadDrawer(scene, where)
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            break
        if message[0] == "end":
            break
        drawer.draw(*message[1:])
    try:
        conn.send(("done", drawer.drawn, drawer.failure))
    except (BrokenPipeError, OSError):
        pass
    drawer.close(0.0)
    try:
        conn.send(("closed",))
    except (BrokenPipeError, OSError):
        pass
