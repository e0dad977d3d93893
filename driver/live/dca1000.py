"""The DCA1000EVM over Ethernet: its configuration client and its data receiver.

:class:`Dca1000Client` sends commands on the config port and checks every
response (framing, command echo, status), with bounded timeouts and retries;
asynchronous status messages that arrive meanwhile are decoded into log
warnings and counters.  :class:`Dca1000Receiver` takes the raw data stream in
its own thread: packets from any address but the board's, or with a malformed
header, are dropped and counted; frames are assembled by byte count into a
preallocated ring (:mod:`.frame_assembler`), so capture never waits for the
consumer.
"""

from __future__ import annotations

import collections
import logging
import socket
import threading
import time
from dataclasses import dataclass, field

from ...errors import DeviceError, DeviceTimeout
from .dca1000_wire import (
    ASYNC_MEANING,
    BOARD_IP,
    CONFIG_PORT,
    DATA_HEADER,
    DATA_PORT,
    HOST_IP,
    MAX_DATA_BYTES,
    AsyncStatus,
    Command,
    EepromConfig,
    FpgaConfig,
    FpgaVersion,
    PacketConfig,
    Request,
    Response,
    Status,
    WireError,
)
from .frame_assembler import DEFAULT_REORDER_PACKETS, FrameAssembler
from .frame_ring import FrameRing
from .host_network import bind_problem, send_problem
from .stream_gaps import SeqGaps

log = logging.getLogger(__name__)

#: Receive buffer asked for the data socket; Linux grants up to net.core.rmem_max.
WANTED_RCVBUF = 64 * 1024 * 1024
#: At most this long, s, is spent on the datagrams still queued when the receiver stops (an
#: 8 MiB buffer at the board's 706 Mbit/s is under 0.1 s of work).
DRAIN_S = 0.5


@dataclass
class Dca1000Settings:
    """Where the board and the host are (defaults: UG Table 11)."""

    host_ip: str = HOST_IP
    board_ip: str = BOARD_IP
    #: Host port the board answers commands on (4096); 0 picks a free one (emulators).
    config_port: int = CONFIG_PORT
    #: Board port commands go to.
    board_port: int = CONFIG_PORT
    #: Host port the board streams data to.
    data_port: int = DATA_PORT
    #: Delay between data packets, us (5..500; larger is gentler, smaller is faster).
    packet_delay_us: float = 25.0
    #: Seconds to wait for one command's response, and how many tries.
    timeout_s: float = 1.0
    retries: int = 3
    #: Seconds to wait after RECORD_STOP for RECORD_COMPLETED and the last frame's held-back
    #: packet (the real board sent both 2.0 s after the last data: pcaps).
    stop_timeout_s: float = 3.0


@dataclass
class AsyncCounts:
    """Asynchronous status messages received, by bit."""

    counts: collections.Counter = field(default_factory=collections.Counter)
    last: int = 0

    def add(self, status: int) -> None:
        self.last = status
        for bit in AsyncStatus:
            if status & bit:
                self.counts[bit.name] += 1


class Dca1000Client:
    """Commands to the board on its config port."""

    def __init__(self, settings: Dca1000Settings | None = None) -> None:
        self.settings = settings or Dca1000Settings()
        self.async_status = AsyncCounts()
        self._sock: socket.socket | None = None

    def open(self) -> "Dca1000Client":
        s = self.settings
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.bind((s.host_ip, s.config_port))
        except OSError as exc:
            sock.close()
            raise DeviceError(bind_problem(exc, s.host_ip, s.config_port,
                                           "talk to the DCA1000's config port")) from None
        self._sock = sock
        return self

    @property
    def local_port(self) -> int:
        return self._sock.getsockname()[1] if self._sock else 0

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self) -> "Dca1000Client":
        return self.open() if self._sock is None else self

    def __exit__(self, *exc) -> None:
        self.close()

    # ---------------------------------------------------------------- commands
    def command(self, command: Command, data: bytes = b"") -> Response:
        """Send one command and return its checked response (READ_FPGA_VERSION's
        status field is the version, not a success flag)."""
        if self._sock is None:
            self.open()
        s = self.settings
        request = Request(command, data).pack()
        for attempt in range(1, s.retries + 1):
            try:
                self._sock.sendto(request, (s.board_ip, s.board_port))
            except OSError as exc:
                raise DeviceError(send_problem(exc, command.name, (s.board_ip, s.board_port), s.host_ip)) from None
            response = self._await(command, s.timeout_s)
            if response is not None:
                if response.status != Status.SUCCESS and command != Command.READ_FPGA_VERSION:
                    raise DeviceError(f"the DCA1000 refused {command.name} (status {response.status})")
                return response
            log.debug("no answer to %s (try %d of %d)", command.name, attempt, s.retries)
        raise DeviceTimeout(
            f"the DCA1000 at {s.board_ip}:{s.board_port} did not answer {command.name} after "
            f"{s.retries} tries of {s.timeout_s:g} s: is it powered (and switched to Ethernet), its cable "
            f"plugged in, and does this host have the address {s.host_ip}?")

    def _await(self, command: Command | None, timeout: float, *, wait: bool = False) -> Response | None:
        """The response to *command* within *timeout* s, handling asynchronous
        status messages on the way; with *command* None, read only what is
        waiting (non-blocking; up to *timeout* s for the first datagram when *wait*) and
        return None."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0 and (command is not None or wait):
                return None
            self._sock.settimeout(max(left, 0.0))  # 0: non-blocking, to drain
            try:
                payload, addr = self._sock.recvfrom(2048)
            except (socket.timeout, BlockingIOError, InterruptedError):
                return None
            if addr[0] != self.settings.board_ip:
                log.debug("ignoring a datagram from %s on the config port", addr[0])
                continue
            try:
                response = Response.parse(payload)
            except WireError as exc:
                log.warning("malformed datagram from the DCA1000's config port: %s", exc)
                continue
            if response.is_async:
                self._on_async(response.status)
            elif command is not None and response.command == command:
                return response
            else:
                log.debug("stale response to command 0x%02X ignored", response.command)

    def _on_async(self, status: int) -> None:
        self.async_status.add(status)
        for bit, (meaning, bad) in ASYNC_MEANING.items():
            if status & bit:
                (log.warning if bad else log.info)("DCA1000: %s", meaning)

    def poll_async(self) -> None:
        """Read the status messages waiting on the config port (non-blocking)."""
        if self._sock is not None:
            self._await(None, 0.0)

    def await_async(self, bit: AsyncStatus, timeout: float) -> bool:
        """Wait up to *timeout* s for a status message with *bit* (one not seen before this
        call); True when it came."""
        if self._sock is None:
            return False
        seen = self.async_status.counts.get(bit.name, 0)
        deadline = time.monotonic() + timeout
        while self.async_status.counts.get(bit.name, 0) == seen:
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            self._await(None, min(left, 0.05), wait=True)
        return True

    def connect(self) -> None:
        self.command(Command.SYSTEM_CONNECT)

    def read_fpga_version(self) -> FpgaVersion:
        return FpgaVersion.from_status(self.command(Command.READ_FPGA_VERSION).status)

    def reset_fpga(self) -> None:
        self.command(Command.RESET_FPGA)

    def reset_radar(self) -> None:
        """RESET_AR_DEV: reset the radar chip (recovers a hung sensorStart)."""
        self.command(Command.RESET_AR_DEV)

    def configure_fpga(self, config: FpgaConfig | None = None) -> None:
        self.command(Command.CONFIG_FPGA_GEN, (config or FpgaConfig()).pack())

    def configure_packets(self, config: PacketConfig | None = None) -> None:
        config = config or PacketConfig(delay_us=self.settings.packet_delay_us)
        self.command(Command.CONFIG_PACKET_DATA, config.pack())

    def configure_eeprom(self, config: EepromConfig) -> None:
        """Write the board's boot addresses to its EEPROM.  Mistakes here can make
        the board unreachable until it is reconfigured over USB: use with care."""
        log.warning("writing the DCA1000's EEPROM (host %s, board %s, MAC %s, ports %d/%d): the board "
                    "uses these addresses from its next power-up", config.host_ip, config.board_ip,
                    config.board_mac, config.config_port, config.data_port)
        self.command(Command.CONFIG_EEPROM, config.pack())

    def start_recording(self) -> None:
        self.command(Command.RECORD_START)

    def stop_recording(self) -> None:
        self.command(Command.RECORD_STOP)


@dataclass
class ReceiverStats:
    packets: int = 0
    bytes: int = 0
    foreign_packets: int = 0
    malformed_packets: int = 0
    #: Packets that arrived shorter than the stream says they were (the next packet's byte
    #: count starts past their end, with no sequence number between).
    truncated_packets: int = 0
    rcvbuf_bytes: int = 0


class Dca1000Receiver:
    """Receives the data port in a thread and assembles frames into a ring."""

    def __init__(self, settings: Dca1000Settings, frame_bytes: int, ring: FrameRing, *,
                 reorder_bytes: int | None = None) -> None:
        self.settings = settings
        self.frame_bytes = frame_bytes
        self.ring = ring
        if reorder_bytes is None:
            # Every frame open for reordering holds a ring buffer: with small frames
            # the window must stay within the ring, leaving room for the consumer.
            reorder_bytes = min(DEFAULT_REORDER_PACKETS * MAX_DATA_BYTES,
                                max(MAX_DATA_BYTES, (ring.slots - 3) * frame_bytes))
        self.assembler = FrameAssembler(frame_bytes, ring, reorder_bytes=reorder_bytes)
        self.gaps = SeqGaps()
        #: time.monotonic() of the last packet from the board (0: none yet).
        self.last_packet_monotonic = 0.0
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
        """Drop datagrams already waiting (from an earlier run); returns how many."""
        dropped = 0
        self._sock.setblocking(False)
        try:
            while True:
                try:
                    self._sock.recv(65536)
                    dropped += 1
                except (BlockingIOError, InterruptedError):
                    break
        finally:
            self._sock.setblocking(True)
        if dropped:
            log.info("flushed %d stale datagrams from the data port", dropped)
        return dropped

    def start(self) -> None:
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
                self.last_packet_monotonic = time.monotonic()
                if addr[0] != board:
                    st.foreign_packets += 1
                    continue
                if n <= header.size or n > header.size + MAX_DATA_BYTES:
                    st.malformed_packets += 1
                    continue
                seq, count = header.unpack_from(buf)
                byte_count = int.from_bytes(count, "little")
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
