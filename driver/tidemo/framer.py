"""Cutting the demo's UART byte stream into whole packets, whatever the line did to it.

:class:`TlvFramer` is pure (no I/O, no clock), in the way pyserial keeps framing apart from
the port: the reader feeds it the bytes as they come (:meth:`TlvFramer.feed`), tells it when the
line went quiet (:meth:`TlvFramer.idle`) and when the stream ended (:meth:`TlvFramer.finish`),
and gets whole packets back (:class:`~.wire.Packet`), each checked by :func:`~.wire.parse_packet`.

A packet starts at the magic word; its header says how long it is.  What a serial line does and
what the framer makes of it:

- bytes before a magic word (a port opened mid-packet, line noise, a stale boot message) are
  discarded;
- a header that cannot be the demo's (SDK version, a length that is no multiple of 32 or too
  long, too many TLVs, another platform, a sub-frame) is a false magic word: it is skipped and
  the search goes on;
- a packet inside which another magic word starts, its padding included, lost bytes (or was cut
  short): it is rejected and framing resumes at that magic word, so the next packet is kept;
- a packet whose TLVs disagree with its header (unknown types, lengths, more than padding after
  them) is rejected;
- a packet is delivered once the next magic word follows it, or the line goes quiet after it; a
  packet followed by other bytes is rejected: had it lost bytes, its length would have been made
  up by what followed (the next packet's first bytes, line noise), and nothing inside tells (the
  3.x header has no checksum).  A whole packet followed by line noise is lost with it;
- a packet the stream ends in (:meth:`TlvFramer.finish`) is rejected as cut at the end.

A packet is delivered whole or not at all.  Every byte fed ends up in exactly one of
:attr:`FramerStats.packet_bytes` (delivered) and :attr:`FramerStats.discarded_bytes`, or is
still buffered (:attr:`TlvFramer.buffered`).  What no framing can see: bytes changed in a
packet's payload, or lost ones made up by as many stray bytes right before the next packet.
"""

from __future__ import annotations

import collections
from dataclasses import dataclass, field

import numpy as np

from .wire import HEADER_DTYPE, MAGIC, Packet, header_problem, parse_packet

#: Why packets were rejected (FramerStats.rejected's keys).
BAD_HEADER = "bad header"
CUT_SHORT = "cut short"
BAD_TLVS = "bad TLVs"
CUT_AT_END = "cut at end"
FOLLOWED_BY_STRAY_BYTES = "followed by stray bytes"


@dataclass
class FramerStats:
    """What the framer saw.  ``packets``: delivered whole; ``rejected``: packets (and false
    magic words) given up, by reason (:data:`BAD_HEADER`, :data:`CUT_SHORT`, :data:`BAD_TLVS`,
    :data:`FOLLOWED_BY_STRAY_BYTES`, :data:`CUT_AT_END`); bytes delivered in packets and discarded
    (garbage and rejected packets)."""

    packets: int = 0
    packet_bytes: int = 0
    discarded_bytes: int = 0
    rejected: collections.Counter = field(default_factory=collections.Counter)

    @property
    def rejected_packets(self) -> int:
        return sum(self.rejected.values())

    def as_dict(self) -> dict:
        return {"packets": self.packets, "packet_bytes": self.packet_bytes,
                "discarded_bytes": self.discarded_bytes, "rejected_packets": self.rejected_packets,
                **{f"rejected_{reason.replace(' ', '_')}": n for reason, n in sorted(self.rejected.items())}}


class TlvFramer:
    """Packets of a byte stream; see the module docstring.  *max_length*: the longest packet to
    wait for (a longer header is a false magic word)."""

    def __init__(self, max_length: int = 1 << 24, *, note_rejections: bool = False) -> None:
        self.max_length = int(max_length)
        self.stats = FramerStats()
        #: (stream offset, reason) of each rejection, in stream order, when *note_rejections* (a
        #: file's replay tells what the part it played lost; a live stream would grow it forever).
        self.rejections: list[tuple[int, str]] | None = [] if note_rejections else None
        #: Why the first header rejected as BAD_HEADER could not be the demo's (None: none was).
        self.first_bad_header: str | None = None
        self._buf = bytearray()
        self._offset = 0  # stream offset of _buf[0]
        self._scanned = len(MAGIC)  # _buf[1:_scanned] holds no magic word's start (when _buf starts with one)

    @property
    def buffered(self) -> int:
        """Bytes fed and not yet delivered or discarded."""
        return len(self._buf)

    @property
    def offset(self) -> int:
        """Bytes fed so far (the stream offset of the next byte)."""
        return self._offset + len(self._buf)

    def feed(self, data: bytes) -> list[Packet]:
        """Take *data*; the packets it completes."""
        self._buf += data
        return self._frame(quiet=False)

    def idle(self) -> list[Packet]:
        """The line went quiet: a packet waiting to see what follows it is whole."""
        return self._frame(quiet=True)

    def finish(self) -> list[Packet]:
        """The stream ended: the last whole packets, then a started packet counted as cut at the
        end and everything left discarded."""
        out = self._frame(quiet=True)
        if self._buf:
            if self._buf.startswith(MAGIC) and len(self._buf) >= len(MAGIC):
                self._reject(CUT_AT_END)
            self._discard(len(self._buf))
        return out

    # ------------------------------------------------------------------ framing
    def _reject(self, reason: str) -> None:
        self.stats.rejected[reason] += 1
        if self.rejections is not None:
            self.rejections.append((self._offset, reason))

    def _discard(self, n: int) -> None:
        del self._buf[:n]
        self._offset += n
        self.stats.discarded_bytes += n
        self._scanned = len(MAGIC)

    def _frame(self, quiet: bool) -> list[Packet]:
        out: list[Packet] = []
        while True:
            if not self._to_magic():
                return out
            if len(self._buf) < HEADER_DTYPE.itemsize:
                return out
            header = np.frombuffer(bytes(self._buf[:HEADER_DTYPE.itemsize]), HEADER_DTYPE)[0]
            problem = header_problem(header, self.max_length)
            if problem is not None:
                if self.first_bad_header is None:
                    self.first_bad_header = problem
                self._reject(BAD_HEADER)
                self._discard(1)
                continue
            total = int(header["total_packet_len"])
            inner = self._buf.find(MAGIC, self._scanned - len(MAGIC) + 1, total)
            if inner > 0:  # the next packet starts inside this one: this one lost bytes
                self._reject(CUT_SHORT)
                self._discard(inner)
                continue
            self._scanned = max(self._scanned, min(len(self._buf), total))
            if len(self._buf) < total:
                return out
            packet = parse_packet(bytes(self._buf[:total]), self.max_length)
            if isinstance(packet, str):
                self._reject(BAD_TLVS)
                self._discard(1)
                continue
            verdict = self._successor(total, quiet)
            if verdict == "wait":
                return out
            if verdict == "stray":
                continue
            packet.offset = self._offset
            del self._buf[:total]
            self._offset += total
            self._scanned = len(MAGIC)
            self.stats.packets += 1
            self.stats.packet_bytes += total
            out.append(packet)

    def _to_magic(self) -> bool:
        """Discard up to the next magic word; False when there is none yet (the last bytes that
        could begin one are kept)."""
        at = self._buf.find(MAGIC)
        if at < 0:
            keep = _magic_prefix_at_end(self._buf, 0)
            self._discard(len(self._buf) - keep)
            return False
        if at:
            self._discard(at)
        return True

    def _successor(self, total: int, quiet: bool) -> str:
        """"ok" (the next magic word, or quiet, follows the packet), "wait" (too few bytes yet
        to tell) or "stray" (other bytes follow: the packet was rejected)."""
        after = bytes(self._buf[total:total + len(MAGIC)])
        if len(after) == len(MAGIC) and after == MAGIC:
            return "ok"
        if MAGIC.startswith(after):
            return "ok" if quiet else "wait"
        # A packet that lost bytes has its length made up by whatever followed it: the next
        # packet's first bytes, line noise.  Nothing inside tells (no checksum), so the bytes
        # after it must be the next packet's start.
        self._reject(FOLLOWED_BY_STRAY_BYTES)
        self._discard(1)  # the next magic word may start inside this packet's last bytes
        return "stray"


def _magic_prefix_at_end(buf: bytearray, lo: int) -> int:
    """Length of the longest proper prefix of the magic word that ends *buf* and starts at or
    after *lo* (the magic word has no border, so there is at most one)."""
    for n in range(min(len(MAGIC) - 1, len(buf) - lo), 0, -1):
        if buf[len(buf) - n:] == MAGIC[:n]:
            return n
    return 0
