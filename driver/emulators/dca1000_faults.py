"""The fake DCA1000's faults (what it does wrong on purpose, :class:`Faults`) and the ground
truth of what one recording's data stream went through (:class:`StreamStats`)."""

from __future__ import annotations

from dataclasses import dataclass


def _probability(name: str, value: float) -> float:
    value = float(value)
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"Faults.{name} = {value}: expected a probability in [0, 1]")
    return value


@dataclass(frozen=True)
class Faults:
    """What the fake board does wrong.  All off by default.

    Probabilities are per data packet and drawn independently (in a fixed
    order, so a seed reproduces a run); when several hit one packet,
    ``malformed`` wins over ``loss``, which wins over the rest.
    """

    #: Probability a data packet is not sent (a seq gap on the wire).
    loss: float = 0.0
    #: Probability a data packet is sent twice in a row.
    duplicate: float = 0.0
    #: Probability a data packet is held back and sent after the next
    #: 1..``reorder_depth`` packets (it still arrives).
    reorder: float = 0.0
    reorder_depth: int = 3
    #: Probability a data packet's data is cut to a random shorter length
    #: (1..n-1 bytes; the header is unchanged).
    truncate: float = 0.0
    #: Probability a garbage datagram shorter than a header (1..9 random bytes)
    #: is sent instead of the packet, which is lost.
    malformed: float = 0.0
    #: Probability a packet is ALSO sent from another address (``foreign_ip``):
    #: same header and length, data bitwise inverted, so a host that does not
    #: filter by source address corrupts its frames visibly.
    foreign: float = 0.0
    #: End every frame with a short packet instead of letting packets straddle frames.
    burst_flush: bool = False
    #: Command codes answered with FAILURE (and not carried out).
    fail_commands: frozenset[int] = frozenset()
    #: Command codes never answered (and not carried out, as if not heard).
    silent_commands: frozenset[int] = frozenset()
    #: (frame index in the recording, status) pairs: the async status is sent
    #: when that frame starts streaming.
    async_errors: tuple[tuple[int, int], ...] = ()

    def __post_init__(self) -> None:
        for name in ("loss", "duplicate", "reorder", "truncate", "malformed", "foreign"):
            object.__setattr__(self, name, _probability(name, getattr(self, name)))
        if int(self.reorder_depth) < 1:
            raise ValueError(f"Faults.reorder_depth = {self.reorder_depth}: expected >= 1")
        object.__setattr__(self, "reorder_depth", int(self.reorder_depth))
        object.__setattr__(self, "fail_commands", frozenset(int(c) for c in self.fail_commands))
        object.__setattr__(self, "silent_commands", frozenset(int(c) for c in self.silent_commands))
        object.__setattr__(self, "async_errors",
                           tuple((int(k), int(s)) for k, s in self.async_errors))

    @property
    def any_packet_faults(self) -> bool:
        return any((self.loss, self.duplicate, self.reorder, self.truncate, self.malformed,
                    self.foreign))


@dataclass
class StreamStats:
    """Ground truth of one recording's data stream (reset by ``RECORD_START``).

    A "packet" is a numbered data packet (one ``seq``), whatever happened to
    it; ``datagrams`` counts what was actually written to the data port from
    the board's address (first copies, duplicates, garbage).
    """

    #: Recordings started since power-up (1 for the first RECORD_START).
    recording: int = 0
    #: Data packets numbered (= the last seq), dropped and malformed ones included.
    packets_sent: int = 0
    #: ADC bytes in those packets (= the stream length so far).
    bytes_sent: int = 0
    #: Frames all of whose bytes have been packetized.
    frames_sent: int = 0
    #: Frames the radar has streamed into the board (the last one's short tail may still be
    #: held back: it goes out when the recording stops).
    frames_in: int = 0
    #: Packets not sent (``Faults.loss``).
    dropped: int = 0
    #: Packets replaced by a garbage datagram (``Faults.malformed``).
    malformed: int = 0
    truncated: int = 0
    duplicates: int = 0
    reordered: int = 0
    #: Copies sent from the foreign address.
    foreign: int = 0
    #: Datagrams sent to the data port from the board's address.
    datagrams: int = 0
    #: Stream bytes that never arrived intact in a first copy (sum of
    #: ``lost_bytes_per_frame``).
    lost_bytes: int = 0
    #: Datagrams the kernel refused (sendto errors).
    send_errors: int = 0
