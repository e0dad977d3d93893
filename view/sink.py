"""The view as a pipeline sink that never slows the pipeline.

For every frame the pipeline's thread keeps the frame's :class:`~.frames.Track` (time, odometry state,
point count, latency, true pose), which the view does not drop (unless the drawer takes nothing
for :data:`MAX_TRACKS` frames: then the oldest go, counted).  Then, if the drawer is ready for
another frame, it hands over the tracks kept so far and the frame's point cloud and heatmap
without waiting (:meth:`Drawer.offer`); if the drawer is still busy with earlier frames (the
drawing, or the viewer, lags behind the radar), the frame's drawing is dropped and counted, and
its track waits for the next frame handed over.  The drawers:

- :class:`ThreadDrawer` (``--view save:``, and a Rerun recording of your own: a notebook's, a
  test's): draws in a thread of this process from a queue of *queue_frames*.
- :class:`~.process.ProcessDrawer` (``--view spawn``, ``web`` and ``connect:``): draws in a
  process of its own, which a lagging or stopped reader holds up alone; the pipeline's thread
  pickles the frame and writes it to a socket without blocking.
"""

from __future__ import annotations

import collections
import logging
import queue
import threading
import time
from typing import TYPE_CHECKING, Callable, Protocol

from ..pipeline.sinks import FrameResult, Sink, remove_if_no_frame
from .frames import FramePayload, Track, ViewHeatmap

if TYPE_CHECKING:
    from ..pipeline.stats import PipelineStats
    from .scene import Scene

log = logging.getLogger(__name__)

_END = object()
#: Tracks kept for a drawer that takes nothing (5 minutes at 10 Hz): beyond, the oldest go, counted.
MAX_TRACKS = 3000


class Drawer(Protocol):
    """What a :class:`ViewSink` hands the frames to; every method but :meth:`close` is called from
    the pipeline's thread and returns at once."""

    #: Where the view goes, for the user (one line).
    where: str
    #: Why the view reaches no viewer, found when it opened (:attr:`.scene.Scene.unreachable`): it
    #: then draws nothing, every frame counted as dropped; None: it may.
    unreachable: str | None

    def ready(self) -> bool:
        """Whether another frame can be handed over now."""

    def offer(self, tracks: list[Track], frame: FramePayload, dropped: int, offered: int) -> None:
        """(After :meth:`ready`) Draw *tracks* in order, then *frame*; *dropped* of *offered* frames
        were dropped so far.  Nothing handed over may be changed by the pipeline afterwards."""

    def close(self, tracks: list[Track], dropped: int, offered: int, timeout_s: float) -> tuple[int | None, str | None]:
        """Draw the last *tracks* and finish, within about *timeout_s*: the frames drawn (None:
        unknown, the drawing did not finish) and what went wrong, if anything."""


class ViewSink(Sink):
    """Hands each frame's results to *drawer* without ever waiting for it (module docstring).

    *close_timeout_s*: how long :meth:`close` lets the drawer finish; *path*: the file the drawer
    saves to, if it does (taken back, as the run's other new files, when the run saw no frame).  :attr:`offered` and
    :attr:`dropped` count the frames as the run goes; once closed, :attr:`drawn` is what was
    drawn and ``offered = drawn + dropped`` (frames a failure or the timeout left undrawn, or that
    reached no viewer, count as dropped), and :attr:`summary` says so in a line.
    """

    wants_heatmaps = True

    def __init__(self, drawer: Drawer, *, close_timeout_s: float = 30.0, path: str | None = None) -> None:
        self.drawer = drawer
        self.path = path
        self.close_timeout_s = close_timeout_s
        self.offered = self.dropped = self.drawn = 0
        #: What went wrong with the view, if anything (a drawing error, a viewer that stopped reading).
        self.problem: str | None = None
        self.finished = True
        #: Tracks that went unsent (the drawer took nothing for MAX_TRACKS frames).
        self.tracks_dropped = 0
        self._tracks: collections.deque[Track] = collections.deque(maxlen=MAX_TRACKS)
        self._closed = False

    @property
    def where(self) -> str:
        return self.drawer.where

    def write(self, result: FrameResult, stats: PipelineStats) -> None:
        frame = result.frame
        points = result.points
        track = Track(frame.index, frame.timestamp, result.state, None if points is None else len(points),
                      time.monotonic() - frame.ready_monotonic, frame.pose)
        if len(self._tracks) == MAX_TRACKS:
            self.tracks_dropped += 1
        self._tracks.append(track)
        self.offered += 1
        if not self.drawer.ready():
            self.dropped += 1
            return
        self.drawer.offer(self._take_tracks(), (track, points, ViewHeatmap.of(result.heatmap)), self.dropped,
                          self.offered)

    def close(self, stats: PipelineStats | None = None) -> None:
        """Let the drawer draw what it has and finish, within *close_timeout_s*."""
        if self._closed:
            return
        self._closed = True
        drawn, self.problem = self.drawer.close(self._take_tracks(), self.dropped, self.offered, self.close_timeout_s)
        self.finished = drawn is not None
        if drawn is None:
            log.warning("the view did not finish within %.0f s; what it had not drawn is lost", self.close_timeout_s)
        self.drawn = drawn or 0
        self.dropped = self.offered - self.drawn
        if self.path is not None and self.finished:  # an unfinished drawer may still write it
            remove_if_no_frame(self.path, stats)

    def _take_tracks(self) -> list[Track]:
        tracks = list(self._tracks)
        self._tracks.clear()
        return tracks

    @property
    def summary(self) -> str:
        """"300 frames drawn, 2 dropped (the view fell behind the radar)"."""
        text = f"{self.drawn} frame{'' if self.drawn == 1 else 's'} drawn, {self.dropped} dropped"
        if self.tracks_dropped:
            text += f", {self.tracks_dropped} missing from its trajectory and time series"
        if self.problem is not None:
            return text + f" ({self.problem})"
        if not self.finished:
            return text + " (the view did not finish)"
        return text + (" (the view fell behind the radar)" if self.dropped else "")


class Drawing:
    """Draws what a drawer is handed into *scene* (a :class:`~.scene.Scene`): the tracks, the
    frame, the drop count; a drawing that raises stops the drawing (logged), not the pipeline."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.drawn = 0
        self.failure: str | None = scene.unreachable
        #: What closing the scene raised (Rerun's error of the last flush), if anything.
        self.close_error: Exception | None = None

    def draw(self, tracks: list[Track], frame: FramePayload | None, dropped: int, offered: int) -> None:
        if self.failure is not None:
            return
        try:
            for track in tracks:
                self.scene.track(track)
            if frame is not None:
                self.scene.frame(*frame)
                self.drawn += 1
            self.scene.dropped(dropped, offered)
        except Exception as exc:  # noqa: BLE001 (a view's failure must not stop the radar)
            self.failure = f"the view failed: {type(exc).__name__}: {exc}"
            log.warning("%s; it stopped drawing", self.failure)

    def close(self, lost: Callable[[Exception], str] | None = None) -> None:
        """Close the scene; what that raises is the failure (unless one came before), said as
        *lost* says it when given (a viewer's connection lost: :func:`.target.lost_viewer`)."""
        try:
            self.scene.close()
        except Exception as exc:  # noqa: BLE001 (what the radar recorded matters more than the view)
            self.close_error = exc
            said = (f"Rerun failed as the view closed: {exc or type(exc).__name__}" if lost is None
                    else lost(exc))
            if self.failure is None:  # (a file's writer that failed, a full disk, says so only here)
                self.failure = said  # said by the view's summary (and a saved file's error): once
                log.debug("%s", said)
            else:
                log.warning("%s", said)


class ThreadDrawer:
    """Draws into *scene* (a :class:`~.scene.Scene` on a Rerun recording of your own) in a thread
    of this process, from a queue of *queue_frames* frames."""

    def __init__(self, scene: Scene, where: str = "a recording of this process", *, queue_frames: int = 4) -> None:
        self.where = where
        self.unreachable = scene.unreachable
        self.drawing = Drawing(scene)
        self._queue: queue.Queue = queue.Queue(maxsize=queue_frames)
        self._thread = threading.Thread(target=self._work, name="radarodom-view", daemon=True)
        self._thread.start()

    def ready(self) -> bool:
        return not self._queue.full()  # only the pipeline's thread puts: room now is room at the put

    def offer(self, tracks: list[Track], frame: FramePayload, dropped: int, offered: int) -> None:
        self._queue.put_nowait((tracks, frame, dropped, offered))

    def close(self, tracks: list[Track], dropped: int, offered: int, timeout_s: float) -> tuple[int | None, str | None]:
        deadline = time.monotonic() + timeout_s
        try:
            self._queue.put((tracks, None, dropped, offered), timeout=timeout_s)
            self._queue.put(_END, timeout=max(0.0, deadline - time.monotonic()))
        except queue.Full:
            return None, self.drawing.failure
        self._thread.join(max(0.0, deadline - time.monotonic()))
        if self._thread.is_alive():
            return None, self.drawing.failure  # the scene is still in use: it cannot be closed from here
        self.drawing.close()
        return self.drawing.drawn, self.drawing.failure

    def _work(self) -> None:
        while (item := self._queue.get()) is not _END:
            self.drawing.draw(*item)
