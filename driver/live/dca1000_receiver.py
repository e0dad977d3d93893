"""The DCA1000EVM's data stream: :class:`Dca1000Receiver` takes it in its own thread.

Packets from any address but the board's, with a malformed header, or of an earlier
recording are dropped and counted; frames are assembled by byte count into a
preallocated ring (:mod:`.frame_assembler`), so capture never waits for the consumer.
(Moved out of :mod:`.dca1000`, which keeps the board's configuration client.)
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from dataclasses import dataclass

from ...errors import DeviceError
from .dca1000 import Dca1000Settings
from .dca1000_wire import DATA_HEADER, MAX_DATA_BYTES
from .frame_assembler import DEFAULT_REORDER_PACKETS, FrameAssembler
from .frame_ring import FrameRing
from .host_network import bind_problem
from .stream_gaps import SeqGaps

log = logging.getLogger(__name__)

#: Receive buffer asked for the data socket; Linux grants up to net.core.rmem_max.
WANTED_RCVBUF = 64 * 1024 * 1024
#: At most this long, s, is spent on the datagrams still queued when the receiver stops (an
#: 8 MiB buffer at the board's 706 Mbit/s is under 0.1 s of work).
DRAIN_S = 0.5


@dataclass
class ReceiverStats:
    packets: int = 0
    bytes: int = 0
    foreign_packets: int = 0
    malformed_packets: int = 0
    #: Packets that arrived shorter than the stream says they were (the next packet's byte
    #: count starts past their end, with no sequence number between).
    truncated_packets: int = 0
    #: Data packets of an earlier recording: waiting on the port before this one started, or
    #: claiming more of the stream than the board could have sent since it started (a board
    #: still streaming from a run killed before it could stop it).
    stale_packets: int = 0
    rcvbuf_bytes: int = 0


class Dca1000Receiver:
    """Receives the data port in a thread and assembles frames into a ring."""

    def __init__(self, settings: Dca1000Settings, frame_bytes: int, ring: FrameRing, *,
                 reorder_bytes: int | None = None, frame_period_s: float | None = None) -> None:
        self.settings = settings
        self.frame_bytes = frame_bytes
        #: The radar's frame period (None: unknown), which bounds how much of the stream the board
        #: can have sent since the recording started: a first packet beyond it is an earlier one's.
        self.frame_period_s = frame_period_s
        self.ring = ring
        if reorder_bytes is None:
            # Every frame open for reordering holds a ring buffer: with small frames
            # the window must stay within the ring, leaving room for the consumer.
            reorder_bytes = min(DEFAULT_REORDER_PACKETS * MAX_DATA_BYTES,
                                max(MAX_DATA_BYTES, (ring.slots - 3) * frame_bytes))
        self.assembler = FrameAssembler(frame_bytes, ring, reorder_bytes=reorder_bytes)
        self.gaps = SeqGaps()
        #: time.monotonic() of the last data packet of this recording taken (0: none yet).
        self.last_packet_monotonic = 0.0
        #: (frame index, time.time()) of the recording's first packet taken (None: none yet).
        self.first_packet: tuple[int, float] | None = None
        self._started_monotonic = 0.0
        self.stats = ReceiverStats()
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._running = threading.Event()
        self._error: BaseException | None = None

    def open(self) -> "Dca1000Receiver":
        s = self.settings
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, WANTED_RCVBUF)
            sock.bind((s.host_ip, s.data_port))
        except OSError as exc:
            sock.close()
            raise DeviceError(bind_problem(exc, s.host_ip, s.data_port, "receive DCA1000 data")) from None
        granted = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
        self.stats.rcvbuf_bytes = granted
        if granted < 2 * self.frame_bytes:
            log.warning(
                "the data socket's receive buffer is %d KiB, less than two %d KiB frames: bursts will be "
                "lost. Raise the limit with: sudo sysctl -w net.core.rmem_max=%d (and add it to "
                "/etc/sysctl.conf to keep it)", granted // 1024, self.frame_bytes // 1024, WANTED_RCVBUF)
        self._sock = sock
        self.flush()
        return self

    @property
    def local_port(self) -> int:
        return self._sock.getsockname()[1] if self._sock else 0

    def flush(self) -> int:
        """Drop datagrams already waiting (from an earlier run: the board's counted stale, others
        foreign); returns how many."""
        dropped = 0
        self._sock.setblocking(False)
        try:
            while True:
                try:
                    _, addr = self._sock.recvfrom(65536)
                except (BlockingIOError, InterruptedError):
                    break
                dropped += 1
                if addr[0] == self.settings.board_ip:
                    self.stats.stale_packets += 1
                else:
                    self.stats.foreign_packets += 1
        finally:
            self._sock.setblocking(True)
        if dropped:
            log.info("flushed %d stale datagrams from the data port", dropped)
        return dropped

    def start(self) -> None:
        """Receive in a thread, from the recording's start (RECORD_START just sent)."""
        self._started_monotonic = time.monotonic()
        self._running.set()
        self._thread = threading.Thread(target=self._run, name="dca1000-receiver", daemon=True)
        self._thread.start()

    def stop(self, *, hand_on: bool = True, sent_all: bool = False) -> None:
        """Stop receiving (after the datagrams already queued), hand on the frames still open
        (or, without *hand_on*, drop them uncounted: nobody will take them), and close the ring.
        *sent_all*: the board reported the recording complete, so bytes still missing were lost
        on the way rather than cut at stop (:meth:`FrameAssembler.expire`)."""
        self._running.clear()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        if hand_on:
            self.assembler.expire(sent_all=sent_all)
        else:
            self.assembler.discard()
        self.ring.close()

    def close(self) -> None:
        self.stop(hand_on=False)
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def _could_be_this_recordings(self, byte_count: int) -> bool:
        """Whether a first packet at stream offset *byte_count* can be this recording's: the
        board cannot have sent more than the frames of the time since it started, and two more."""
        if not self.frame_period_s:
            return True
        elapsed = time.monotonic() - self._started_monotonic
        return byte_count <= self.frame_bytes * (elapsed / self.frame_period_s + 2)

    @property
    def error(self) -> BaseException | None:
        """What ended the receive thread, if it failed."""
        return self._error

    def _run(self) -> None:
        sock = self._sock
        sock.settimeout(0.05)
        buf = bytearray(DATA_HEADER.size + MAX_DATA_BYTES + 64)
        view = memoryview(buf)
        board = self.settings.board_ip
        st = self.stats
        asm = self.assembler
        header = DATA_HEADER
        gaps = self.gaps
        prev_seq, prev_end = -1, 0
        draining = False
        try:
            while True:
                if not draining and not self._running.is_set():
                    # Asked to stop: the datagrams the kernel already holds are part of the
                    # capture (a loaded machine may lag by a frame); take them, then end.
                    # Bounded in time, should a sender never pause.
                    draining = True
                    drain_until = time.monotonic() + DRAIN_S
                    sock.setblocking(False)
                elif draining and time.monotonic() > drain_until:
                    break
                try:
                    n, addr = sock.recvfrom_into(buf)
                except socket.timeout:
                    # No frame is given up for a pause: the board holds a frame's last short
                    # packet until the next frame's bytes fill it, or until the recording stops
                    # (pcaps: 2 s later, with RECORD_COMPLETED).  stop() hands on what is open.
                    continue
                except (BlockingIOError, InterruptedError):
                    break  # drained
                now = time.time()
                if addr[0] != board:
                    st.foreign_packets += 1
                    continue
                if n <= header.size or n > header.size + MAX_DATA_BYTES:
                    st.malformed_packets += 1
                    continue
                seq, count = header.unpack_from(buf)
                byte_count = int.from_bytes(count, "little")
                if self.first_packet is None:
                    if not self._could_be_this_recordings(byte_count):
                        st.stale_packets += 1
                        continue
                    self.first_packet = (byte_count // self.frame_bytes, now)
                self.last_packet_monotonic = time.monotonic()
                st.packets += 1
                st.bytes += n - header.size
                if seq == prev_seq + 1 and byte_count > prev_end:
                    st.truncated_packets += 1
                prev_seq, prev_end = seq, byte_count + n - header.size
                gaps.add(seq)
                asm.add(seq, byte_count, view[header.size:n], now)
        except Exception as exc:  # reported by the source, which owns the user interface
            self._error = exc
            log.error("the DCA1000 receiver stopped: %s", exc)
        finally:
            self.ring.close()
