"""The view as a pipeline sink that never slows the pipeline.

The pipeline's thread does two cheap things per frame (microseconds): it appends the frame's
:class:`Track` (time, odometry state, point count, latency, true pose) to a list the view never
drops, and offers the frame's point cloud and heatmap to a bounded queue.  When the queue is
full (the drawing, or the viewer, lags behind the radar) that frame's drawing is dropped and
counted: the pipeline's frames never wait for the view.  A sender thread hands the tracks, in
order, and each queued frame to a drawer: :class:`~.process.ProcessDrawer` (what radar-capture
uses: Rerun in a process of its own, so that drawing never holds this process's interpreter
lock and a viewer that stops reading cannot hold up the end of the run) or
:class:`ThreadDrawer` (draws in the sender thread, into a recording of your own).
"""

from __future__ import annotations

import collections
import logging
import queue
import threading
import time
from typing import TYPE_CHECKING, NamedTuple, Protocol

from ..estimator.odometry import OdometryState
from ..pipeline.sinks import FrameResult, Sink

if TYPE_CHECKING:
    import numpy as np

    from ..pipeline.stats import PipelineStats
    from ..products import RangeAzimuth
    from .scene import Scene

log = logging.getLogger(__name__)

_END = object()


class Track(NamedTuple):
    """What the view keeps of every frame (never dropped): its index and time (s), the new
    odometry (None on a velocity-only frame or without an estimator), the point count (None
    without a point cloud), the latency until the view got it (s) and the true pose."""

    frame: int
    t: float
    state: OdometryState | None
    points: int | None
    latency_s: float
    pose: tuple[float, ...] | None


#: A frame to draw: its track, point cloud (POINT_DTYPE) and heatmap (either may be None).
FramePayload = tuple[Track, "np.ndarray | None", "RangeAzimuth | None"]


class Drawer(Protocol):
    """Where a :class:`ViewSink` hands what it draws (from its sender thread)."""

    #: Where the view goes, for the user (one line).
    where: str

    def draw(self, tracks: list[Track], frame: FramePayload | None, dropped: int, offered: int) -> None:
        """Draw *tracks* in order, then *frame*; *dropped* of *offered* frames were dropped so far.
        May block while the drawing lags: the sink's queue absorbs it."""

    def close(self, timeout_s: float) -> tuple[int | None, str | None]:
        """Finish (within about *timeout_s*): the frames drawn (None: unknown, the drawing did not
        finish) and the failure that stopped the drawing, if one did."""

    def abandon(self) -> tuple[int | None, str | None]:
        """Give up while a :meth:`draw` is still blocked: as :meth:`close`, without waiting."""


class ViewSink(Sink):
    """Hands each frame's results to *drawer* from a sender thread (see the module docstring).

    *queue_frames*: frames waiting for the drawer before new ones are dropped; *close_timeout_s*:
    how long :meth:`close` waits for the frames still queued to be drawn.  :attr:`offered` and
    :attr:`dropped` count the frames as the run goes; once closed, :attr:`drawn` is what the
    drawer drew and ``offered = drawn + dropped`` (frames a failure or the timeout left undrawn
    count as dropped).
    """

    wants_heatmaps = True

    def __init__(self, drawer: Drawer, *, queue_frames: int = 4, close_timeout_s: float = 30.0) -> None:
        self.drawer = drawer
        self.close_timeout_s = close_timeout_s
        self.offered = self.dropped = self.drawn = 0
        self.failure: str | None = None
        self.finished = True
        self._queue: queue.Queue = queue.Queue(maxsize=queue_frames)
        self._tracks: collections.deque[Track] = collections.deque()
        self._closed = False
        self._sender = threading.Thread(target=self._send, name="radarodom-view", daemon=True)
        self._sender.start()

    @property
    def where(self) -> str:
        return self.drawer.where

    # ------------------------------------------------------------------ the pipeline's thread
    def write(self, result: FrameResult, stats: PipelineStats) -> None:
        frame = result.frame
        points = result.points
        track = Track(frame.index, frame.timestamp, result.state, None if points is None else len(points),
                      time.monotonic() - frame.ready_monotonic, frame.pose)
        self._tracks.append(track)
        self.offered += 1
        try:
            self._queue.put_nowait((track, points, result.heatmap))
        except queue.Full:
            self.dropped += 1

    def close(self, stats: PipelineStats | None = None) -> None:
        """Hand over what is queued and let the drawer finish, within *close_timeout_s*."""
        if self._closed:
            return
        self._closed = True
        deadline = time.monotonic() + self.close_timeout_s
        try:
            self._queue.put(_END, timeout=self.close_timeout_s)
        except queue.Full:
            pass
        self._sender.join(max(0.0, deadline - time.monotonic()))
        if self._sender.is_alive():  # stuck handing a frame over: the drawer is not to be waited for
            drawn, self.failure = self.drawer.abandon()
        else:
            drawn, self.failure = self.drawer.close(max(1.0, deadline - time.monotonic()))
        self.finished = drawn is not None
        if drawn is None:
            log.warning("the view did not finish within %.0f s (a viewer that stopped reading?); what it had "
                        "not sent is lost", self.close_timeout_s)
        self.drawn = drawn or 0
        self.dropped = self.offered - self.drawn

    @property
    def summary(self) -> str:
        """"300 frames drawn, 2 dropped (the view fell behind the radar)"."""
        text = f"{self.drawn} frame{'' if self.drawn == 1 else 's'} drawn, {self.dropped} dropped"
        if self.failure is not None:
            return text + f" (the view failed: {self.failure})"
        if not self.finished:
            return text + " (the view did not finish)"
        return text + (" (the view fell behind the radar)" if self.dropped else "")

    # ------------------------------------------------------------------ the sender thread
    def _send(self) -> None:
        while True:
            item = self._queue.get()
            if item is _END:
                break
            self.drawer.draw(self._tracks_until(item[0]), item, self.dropped, self.offered)
        self.drawer.draw(self._tracks_until(None), None, self.dropped, self.offered)

    def _tracks_until(self, last: Track | None) -> list[Track]:
        """The tracks kept so far, in order, up to *last* (None: all)."""
        out = []
        while self._tracks:
            out.append(self._tracks.popleft())
            if out[-1] is last:
                break
        return out


class ThreadDrawer:
    """Draws into *scene* (a :class:`~.scene.Scene` on a Rerun recording of your own) in the
    sink's sender thread; a drawing that raises stops the drawing (logged), not the pipeline."""

    def __init__(self, scene: Scene, where: str = "a recording of this process") -> None:
        self.scene = scene
        self.where = where
        self.drawn = 0
        self.failure: str | None = None

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
            self.failure = f"{type(exc).__name__}: {exc}"
            log.warning("the view stopped drawing: %s", self.failure)

    def close(self, timeout_s: float) -> tuple[int | None, str | None]:
        try:
            self.scene.close()
        except Exception as exc:  # noqa: BLE001 (what the radar recorded matters more than the view)
            log.warning("the view did not close cleanly: %s: %s", type(exc).__name__, exc)
        return self.drawn, self.failure

    def abandon(self) -> tuple[int | None, str | None]:
        return None, self.failure  # the scene is still in use: it cannot be closed from here
