"""Frames from DCA1000 data packets, by byte count (never by counting packets).

Every data packet says how many stream bytes the board sent before it, so
each byte's place is known: stream byte ``b`` belongs to frame
``b // frame_bytes`` at offset ``b % frame_bytes``.  The assembler copies
each packet's bytes there, splitting packets that straddle a frame boundary.
Frame alignment therefore cannot be lost, whatever is lost, duplicated,
reordered or truncated on the way:

- a gap stays zero and is counted in the frame's ``missing_bytes`` (the bytes the frame did not
  receive), and attributed, on each :class:`RingFrame` and in :class:`AssemblyStats`: bytes the
  packet headers show were sent and never came (``lost_bytes``: lost, malformed, truncated or
  late packets, counted from sequence and byte-count gaps by :class:`.stream_gaps.ByteGaps`,
  independently of the frame's own count; the bytes after the newest packet too when the
  sender confirmed the stream's end, :meth:`expire` with ``sent_all``), and bytes after the
  newest packet, never sent before the stream stopped (``cut_bytes``).  The two add up to
  ``missing_bytes``; a frame where they do not is a bug, and warned about;
- bytes already received (a duplicate) are not counted twice;
- a packet for a frame already handed on is too late: dropped and counted;
- frames are handed on in order: a frame is complete when all its bytes are
  in, and given up on (incomplete) once the stream has moved ``reorder_bytes``
  past its end (packets that late are taken as lost), or by :meth:`expire`;
- frames the stream skipped entirely are handed on too, all zero, so the
  frame numbering stays continuous.

Pure bookkeeping: no sockets, no threads (the receiver calls it).
"""

from __future__ import annotations

import bisect
import logging
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .dca1000_wire import MAX_DATA_BYTES
from .frame_ring import FrameRing, RingFrame
from .stream_gaps import ByteGaps

log = logging.getLogger(__name__)

#: Default reordering tolerance, in full packets: a packet arriving more than
#: this many packets' worth of stream behind the newest one is taken as lost.
DEFAULT_REORDER_PACKETS = 32


@dataclass
class AssemblyStats:
    packets: int = 0
    bytes: int = 0
    #: Packets (and their bytes) that added nothing new: exact or partial repeats.
    duplicate_packets: int = 0
    duplicate_bytes: int = 0
    #: Packets for frames already handed on.
    late_packets: int = 0
    late_bytes: int = 0
    #: Packets whose byte count cannot be right for their sequence number.
    implausible_packets: int = 0
    frames_complete: int = 0
    frames_incomplete: int = 0
    #: Bytes missing from frames handed on incomplete (not received): lost_bytes + cut_bytes.
    missing_bytes: int = 0
    #: Bytes of those frames the packet headers show were sent and never came.
    lost_bytes: int = 0
    #: Missing bytes the stream had not reached when their frame was handed on: cut at stop.
    cut_bytes: int = 0
    #: Packets after the newest one received that the sender's confirmed end shows were sent
    #: (counted as the board cuts its stream: full packets but for the recording's last).
    tail_packets_lost: int = 0
    #: Frames the ring had no buffer for (consumer too slow, policy ``queue``).
    frames_dropped: int = 0
    #: Frames still open when the stream was closed with nobody to take them.
    frames_discarded: int = 0


@dataclass
class _OpenFrame:
    index: int
    slot: int | None  # None: no buffer (dropped), bytes are only accounted
    first_time: float
    received: int = 0
    #: Sorted, disjoint [start, end) byte ranges received.
    covered: list = field(default_factory=list)

    def add_range(self, start: int, end: int) -> int:
        """Record [start, end); return how many of its bytes are new."""
        cov = self.covered
        if not cov or start >= cov[-1][1]:  # the usual case: in order
            if cov and start == cov[-1][1]:
                cov[-1][1] = end
            else:
                cov.append([start, end])
            self.received += end - start
            return end - start
        # Out of order or overlapping: merge with whatever it touches.
        i = bisect.bisect_left(cov, [start, start])
        if i > 0 and cov[i - 1][1] >= start:
            i -= 1
        new, lo, hi, j = end - start, start, end, i
        while j < len(cov) and cov[j][0] <= end:
            s, e = cov[j]
            new -= max(0, min(e, end) - max(s, start))
            lo, hi = min(lo, s), max(hi, e)
            j += 1
        cov[i:j] = [[lo, hi]]
        self.received += new
        return new


class FrameAssembler:
    """Feed it packets with :meth:`add`; complete frames go to ``on_frame``
    (default: published to the ring)."""

    def __init__(self, frame_bytes: int, ring: FrameRing, *,
                 reorder_bytes: int = DEFAULT_REORDER_PACKETS * MAX_DATA_BYTES,
                 on_frame: Callable[[RingFrame], None] | None = None) -> None:
        self.frame_bytes = frame_bytes
        self.ring = ring
        self.reorder_bytes = max(0, reorder_bytes)
        self.on_frame = on_frame or ring.publish
        self.stats = AssemblyStats()
        #: The next frame index to hand on; everything below is done.
        self.next_index = 0
        self._open: dict[int, _OpenFrame] = {}
        self._newest_end = 0
        self.byte_gaps = ByteGaps()
        self._warned_unattributed = False

    def add(self, seq: int, byte_count: int, data, now: float) -> None:
        """One packet: sequence number, stream offset of its first byte, its
        ADC bytes (bytes-like), host receive time."""
        size = len(data)
        st = self.stats
        # The board sends at most MAX_DATA_BYTES per sequence number: a larger
        # offset is a corrupt header, and must not push frames out.
        if seq < 1 or byte_count > (seq - 1) * MAX_DATA_BYTES:
            st.implausible_packets += 1
            return
        st.packets += 1
        st.bytes += size
        fb = self.frame_bytes
        end = byte_count + size
        self.byte_gaps.add(seq, byte_count, end)
        first, last = byte_count // fb, (end - 1) // fb
        if last < self.next_index:
            st.late_packets += 1
            st.late_bytes += size
            return
        if end > self._newest_end:
            self._newest_end = end
            # Frames ending reorder_bytes or more before the newest byte are done.
            self._give_up_before((end - self.reorder_bytes) // fb)
        src = np.frombuffer(data, np.uint8)  # a view: bytes and memoryviews alike
        new_total = 0
        offset = 0
        for f in range(first, last + 1):
            seg_start = max(byte_count, f * fb)
            seg_end = min(end, (f + 1) * fb)
            n = seg_end - seg_start
            if f < self.next_index:  # this part's frame is already handed on
                st.late_bytes += n
                offset += n
                continue
            frame = self._open.get(f) or self._open_frame(f, now)
            new = frame.add_range(seg_start - f * fb, seg_end - f * fb)
            if new and frame.slot is not None:
                self.ring.buffer(frame.slot)[seg_start - f * fb: seg_end - f * fb] = \
                    src[offset: offset + n]
            new_total += new
            offset += n
        if new_total < size:
            st.duplicate_bytes += size - new_total
            if new_total == 0:
                st.duplicate_packets += 1
        self._hand_on_complete()

    def _open_frame(self, index: int, now: float) -> _OpenFrame:
        slot = self.ring.acquire()
        if slot is None:
            self.stats.frames_dropped += 1
        frame = _OpenFrame(index, slot, now)
        self._open[index] = frame
        return frame

    def _hand_on_complete(self) -> None:
        while True:
            frame = self._open.get(self.next_index)
            if frame is None or frame.received < self.frame_bytes:
                return
            self._hand_on(frame)

    def _give_up_before(self, index: int) -> None:
        """Hand on every frame below *index*, complete or not."""
        while self.next_index < index:
            frame = self._open.get(self.next_index)
            if frame is None:  # skipped entirely by the stream
                frame = self._open_frame(self.next_index, 0.0)
            self._hand_on(frame)

    def _hand_on(self, frame: _OpenFrame) -> None:
        del self._open[frame.index]
        self.next_index = frame.index + 1
        missing = self.frame_bytes - frame.received
        start, end = frame.index * self.frame_bytes, (frame.index + 1) * self.frame_bytes
        lost = self.byte_gaps.take(start, end)  # settled even for a frame with no buffer
        st = self.stats
        if frame.slot is None:
            return
        # Bytes past the newest one received were not sent yet (unless the sender said so).
        cut = max(0, end - max(self._newest_end, start))
        if missing != lost + cut:
            self._warn_unattributed(frame.index, missing, lost, cut)
        if missing:
            st.frames_incomplete += 1
            st.missing_bytes += missing
            st.cut_bytes += cut
            st.lost_bytes += lost
        else:
            st.frames_complete += 1
        self.on_frame(RingFrame(frame.slot, frame.index, self.ring.buffer(frame.slot), missing,
                                frame.first_time, time.monotonic(), cut, lost))

    def _warn_unattributed(self, index: int, missing: int, lost: int, cut: int) -> None:
        if not self._warned_unattributed:
            self._warned_unattributed = True
            log.warning("frame %d misses %d bytes, but the packet headers show %d lost and %d were cut "
                        "at stop: the accounting does not add up (a radarodom bug: please report it "
                        "with the capture's packets)", index, missing, lost, cut)

    def expire(self, *, sent_all: bool = False) -> None:
        """Hand on every frame still open (the stream stopped).  With *sent_all* the sender has
        said it sent everything (the DCA1000's RECORD_COMPLETED; the radar stops at a frame's
        end), so what is missing was lost on the way; otherwise the bytes the stream had not
        reached are counted as cut at stop."""
        if self._open:
            last = max(self._open)
            if sent_all:
                end = (last + 1) * self.frame_bytes
                self.stats.tail_packets_lost += self.byte_gaps.end_at(end)
                self._newest_end = max(self._newest_end, end)
            self._give_up_before(last + 1)

    def discard(self) -> None:
        """Drop every frame still open, uncounted (nobody will take them: the consumer left);
        their buffers go back to the ring."""
        for frame in self._open.values():
            if frame.slot is not None:
                self.ring.discard(frame.slot)
        self.stats.frames_discarded += len(self._open)
        self._open.clear()

    @property
    def open_frames(self) -> int:
        return len(self._open)
