"""What the data packets' headers say never arrived.

Every DCA1000 data packet carries a sequence number (1 after RECORD_START) and the count of
stream bytes the board sent before it (:data:`.dca1000_wire.DATA_HEADER`), so what is missing
can be read off the packets that did arrive, without looking at their data:
:class:`SeqGaps` counts the sequence numbers never received.
"""

from __future__ import annotations


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
