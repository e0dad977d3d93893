"""What the data packets' headers say never arrived.

Every DCA1000 data packet carries a sequence number (1 after RECORD_START) and the count of
stream bytes the board sent before it (:data:`.dca1000_wire.DATA_HEADER`), so what is missing
can be read off the packets that did arrive, without looking at their data:
:class:`SeqGaps` counts the sequence numbers never received, :class:`ByteGaps` the stream
bytes they carried.  The frame assembler counts missing bytes its own way, from the bytes
each frame received; the two counts meeting is the accounting's check.
"""

from __future__ import annotations

import math

from .dca1000_wire import MAX_DATA_BYTES


class SeqGaps:
    """Sequence numbers not (yet) received: a late packet closes its gap, so
    reordering is not counted as loss.  Gaps more than ``horizon`` packets old
    are final."""

    def __init__(self, horizon: int = 4096) -> None:
        self.horizon = horizon
        self.last = 0
        self._open: set[int] = set()
        self._final = 0

    def add(self, seq: int) -> None:
        if seq > self.last + 1:
            self._open.update(range(self.last + 1, seq))
            if len(self._open) > 2 * self.horizon:
                old = {s for s in self._open if s < seq - self.horizon}
                self._open -= old
                self._final += len(old)
        elif seq <= self.last:
            self._open.discard(seq)
        self.last = max(self.last, seq)

    @property
    def lost(self) -> int:
        """Packets missing so far (the open gaps and the final ones)."""
        return self._final + len(self._open)


class ByteGaps:
    """Stream bytes lost on the way, from the packet headers alone.

    Between two packets received with sequence numbers a < b and none received between
    them, packets a+1 .. b-1 carried the stream bytes from the end of a to the start of b;
    with b = a + 1 those bytes were cut from a (truncated).  A late packet with a number in
    a gap fills its part of it.  :meth:`take` settles a range of the stream (a frame handed
    on): the gaps in it are lost for good, late packets for it change nothing, and what is
    kept stays as short as the reordering window.  Bytes after the newest packet are not
    known to have been sent until the sender says where the stream ended (:meth:`end_at`).
    """

    def __init__(self) -> None:
        self.last_seq = 0
        #: End of the stream bytes received so far (the newest packet's end).
        self.last_end = 0
        #: Open gaps in stream order: [seq before, seq after, first byte, end byte).
        self._gaps: list[list] = []

    def add(self, seq: int, start: int, end: int) -> None:
        """A packet numbered *seq* carrying stream bytes [start, end)."""
        if seq > self.last_seq:
            if start > self.last_end:
                self._gaps.append([self.last_seq, seq, self.last_end, start])
            self.last_seq = seq
            self.last_end = max(self.last_end, end)
            return
        for i, (before, after, lo, hi) in enumerate(self._gaps):
            if before < seq < after:  # a late packet: what it carried was not lost
                self._gaps[i:i + 1] = [g for g in ([before, seq, lo, min(hi, start)],
                                                   [seq, after, max(lo, end), hi]) if g[2] < g[3]]
                return
        # Otherwise a repeat, or a packet whose bytes were settled already: nothing to fill.

    def end_at(self, end: int) -> int:
        """The sender says the stream ended at byte *end*: the bytes after the newest packet
        were sent and never came.  Returns how many packets carried them, as the board cuts
        its stream: MAX_DATA_BYTES each from the recording's first byte."""
        newest = self.last_end
        if end <= newest:
            return 0
        self._gaps.append([self.last_seq, math.inf, newest, end])
        self.last_end = end
        return -(-end // MAX_DATA_BYTES) - -(-newest // MAX_DATA_BYTES)

    def take(self, lo: int, hi: int) -> int:
        """Bytes of stream range [lo, hi) lost on the way, *lo* the end of the range taken
        before (a frame handed on after the one before it): everything below *hi* is settled."""
        lost = sum(max(0, min(g[3], hi) - max(g[2], lo)) for g in self._gaps)
        self._gaps = [g for g in self._gaps if g[3] > hi]
        return lost
