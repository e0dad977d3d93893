"""The DCA1000EVM over Ethernet: its configuration client.

:class:`Dca1000Client` sends commands on the config port and checks every
response (framing, command echo, status), with bounded timeouts and retries;
asynchronous status messages that arrive meanwhile are decoded into log
warnings and counters.  The data stream's receiver is :mod:`.dca1000_receiver`.
"""

from __future__ import annotations

import collections
import logging
import socket
import time
from dataclasses import dataclass, field

from ...errors import DeviceError, DeviceTimeout
from .dca1000_wire import (
    ASYNC_MEANING,
    BOARD_IP,
    CONFIG_PORT,
    DATA_PORT,
    HOST_IP,
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
from .host_network import bind_problem, send_problem

log = logging.getLogger(__name__)


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

    def async_count(self, bit: AsyncStatus) -> int:
        """Status messages with *bit* received so far."""
        return self.async_status.counts.get(bit.name, 0)

    def await_async(self, bit: AsyncStatus, timeout: float) -> bool:
        """Wait up to *timeout* s for a status message with *bit* (one not seen before this
        call); True when it came."""
        if self._sock is None:
            return False
        seen = self.async_count(bit)
        deadline = time.monotonic() + timeout
        while self.async_count(bit) == seen:
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
