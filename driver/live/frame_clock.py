"""Frame times for a live radar: the host's receive times of each frame's first packet, smoothed
onto the radar's frame grid (:class:`FrameClock`), and how long its stream may stay quiet
(:func:`stream_timeout_s`); used by ``dca1000://`` and ``tidemo://``."""

from __future__ import annotations

import collections
import logging

from ...errors import DeviceError

log = logging.getLogger(__name__)


def stream_timeout_s(frame_period_s: float, given: float | None = None) -> float:
    """Seconds without a packet before a live stream is declared dead: *given* (the URL's
    ``data_timeout``), else 10 frame periods and at least 2 s."""
    return max(2.0, 10 * frame_period_s) if given is None else given


class FrameClock:
    """Frame times from host receive times, smoothed onto the radar's frame grid.

    The radar's frames come exactly one period apart; host receive times add a
    positive, jittery delay.  The smallest ``receive - index * period`` over the
    last ``window`` frames is the best estimate of the grid's start, so each
    frame gets ``start + index * period``: the time its first packet would
    arrive with the least delay seen (within a millisecond of the first chirp).

    The times only go forward: were the host's clock set back (an NTP step), the frames go on
    from the last one's time on its grid (a frame timed before the one before stopped the run).
    Set forward, the grid follows it as soon as the last :attr:`STEP_FRAMES` frames that came
    all came more than :attr:`STEP_S` late on the old grid and agree with one another within half
    a period, rather than a window later.  A stall's backlog comes earlier each frame as it is
    drained and does not agree so, unless drained at less than about 1.08 times the frame rate
    (8 frames' fall within half a period); then, as with no such rule, the grid follows the
    lateness (here at once, else a window later).
    """

    #: Frames, and the lateness in s, that together say the host's clock was set forward.
    STEP_FRAMES, STEP_S = 8, 1.0

    def __init__(self, period_s: float, window: int = 64) -> None:
        self.period = period_s
        self._offsets: collections.deque[float] = collections.deque(maxlen=window)
        # (index, offset) of the last frames observed
        self._recent: collections.deque[tuple[int, float]] = collections.deque(maxlen=self.STEP_FRAMES)
        self._last: tuple[int, float] | None = None  # (index, time) of the last frame stamped
        self._set_back = False

    @property
    def placed(self) -> bool:
        """Whether a packet has placed the grid yet."""
        return bool(self._offsets)

    def observe(self, index: int, receive_time: float) -> None:
        """A packet of frame *index* received at *receive_time* (time.time())."""
        offset = receive_time - index * self.period
        self._offsets.append(offset)
        self._recent.append((index, offset))
        if len(self._recent) < self._recent.maxlen:
            return
        recent = [late for _, late in self._recent]
        if min(recent) - min(self._offsets) > self.STEP_S and max(recent) - min(recent) < self.period / 2:
            log.warning("this computer's clock was set forward by %.3f s (or the radar's packets come that much "
                        "later): the frames' times follow it from frame %d", min(recent) - min(self._offsets),
                        self._recent[0][0])
            self._offsets = collections.deque(recent, maxlen=self._offsets.maxlen)

    def stamp(self, index: int, receive_time: float,
              first_packet: tuple[int, float] | None = None) -> float:
        """Frame *index*'s time; *receive_time* its first packet's (0: none came, the frame
        wholly lost: the grid's time, which needs a packet observed before).  *first_packet*:
        (frame index, receive time) of the stream's first packet, which places the grid for a
        frame wholly lost before any frame's packet has (only then: later it would bring back
        an offset the window has let go, and time would go back)."""
        if receive_time > 0:
            self.observe(index, receive_time)
        elif not self.placed and first_packet is not None:
            self.observe(*first_packet)
        if not self._offsets:
            raise DeviceError(f"frame {index} has no packet and none came before it: its time is unknown")
        t = min(self._offsets) + index * self.period
        if self._last is not None and t <= self._last[1]:
            if not self._set_back:
                log.warning("this computer's clock was set back by %.3f s: the frames' times go on from the "
                            "last one's, ahead of the clock", self._last[1] - t + (index - self._last[0]) * self.period)
                self._set_back = True
            t = self._last[1] + (index - self._last[0]) * self.period
        self._last = (index, t)
        return t
