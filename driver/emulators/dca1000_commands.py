"""The fake DCA1000's config port: the commands it takes, its answers and its asynchronous
status (:class:`CommandPort`, a part of :class:`~.fake_dca1000.FakeDca1000`; its methods use the
board's state, which :class:`~.fake_dca1000.FakeDca1000` sets up)."""

from __future__ import annotations

import logging
import socket
import time
from typing import Callable

from ..live.dca1000_wire import (
    AsyncStatus, CaptureMode, Command, EepromConfig, FormatMode, FpgaConfig, LogMode, LvdsMode, PacketConfig,
    Request, Response, Status, TransferMode, WireError)
from ...cfg_physics import DCA1000_PACKET_DELAY_RANGE_US
from .dca1000_faults import StreamStats
from .dca1000_streamer import _WAIT_SLICE_S

log = logging.getLogger(__name__)

#: CONFIG_PACKET_DATA packet sizes the board accepts (DG: 48..1472).
MIN_PACKET_SIZE = 48
MAX_PACKET_SIZE = 1472
#: Largest datagram the config socket reads (a request is at most 512 bytes).
_RECV_BYTES = 65535
#: The two response statuses a command gets.
_OK, _FAILURE = int(Status.SUCCESS), int(Status.FAILURE)


class CommandPort:
    """The board's config port: its thread serves :class:`~radarodom.driver.live.dca1000_wire.Request`
    datagrams, carries each command out and answers it."""

    # ------------------------------------------------------------------ config port
    def _serve_commands(self) -> None:
        sock = self._cmd_sock
        while not self._closed:
            with self._cond:
                next_due = min((e[0] for e in self._events), default=None)
            timeout = _WAIT_SLICE_S if next_due is None else \
                min(_WAIT_SLICE_S, max(next_due - time.monotonic(), 0.0005))
            try:
                sock.settimeout(timeout)
                payload, addr = sock.recvfrom(_RECV_BYTES)
            except socket.timeout:
                pass
            except OSError:
                if self._closed:
                    break
                log.exception("fake DCA1000: config socket error")
                time.sleep(_WAIT_SLICE_S)
            else:
                try:
                    self._handle_request(payload, addr)
                except Exception:
                    log.exception("fake DCA1000: handling a request failed")
            self._run_due_events()

    def _handle_request(self, payload: bytes, addr: tuple[str, int]) -> None:
        try:
            request = Request.parse(payload)
        except WireError as exc:
            with self._cond:
                self._malformed_requests += 1
            log.warning("fake DCA1000: malformed request from %s:%d ignored: %s", *addr, exc)
            return
        code = request.command
        with self._cond:
            self._host_config_address = addr
            self._commands[code] += 1
        name = _command_name(code)
        if code in self.faults.silent_commands:
            log.info("fake DCA1000: %s not answered (fault)", name)
            return
        if code in self.faults.fail_commands:
            log.info("fake DCA1000: %s answered FAILURE (fault)", name)
            status = int(Status.FAILURE)
        else:
            status = self._execute(request)
        log.debug("fake DCA1000: %s -> status 0x%04X", name, status)
        self._send(self._src_sock, Response(code, status).pack(), addr)

    def _execute(self, request: Request) -> int:
        """Carry out one command; returns the response status."""
        handler = self._handlers.get(request.command)
        if handler is None:  # PLAYBACK_*, CONFIG_DATA_MODE_AR_DEV, INIT_FPGA_PLAYBACK, unknown codes
            log.warning("fake DCA1000: %s is not supported: FAILURE", _command_name(request.command))
            return _FAILURE
        return handler(request.data)

    @property
    def _handlers(self) -> dict[int, Callable[[bytes], int]]:
        return {Command.SYSTEM_CONNECT: self._system_connect, Command.READ_FPGA_VERSION: self._read_fpga_version,
                Command.SYSTEM_ERROR: self._system_error, Command.RESET_FPGA: self._reset_fpga,
                Command.RESET_AR_DEV: self._reset_ar_dev, Command.CONFIG_FPGA_GEN: self._config_fpga_gen,
                Command.CONFIG_PACKET_DATA: self._config_packet_data, Command.CONFIG_EEPROM: self._config_eeprom,
                Command.RECORD_START: self._record_start, Command.RECORD_STOP: self._record_stop}

    def _system_connect(self, data: bytes) -> int:
        return _OK

    def _read_fpga_version(self, data: bytes) -> int:
        return self.fpga_version.to_status()

    def _system_error(self, data: bytes) -> int:
        # The real board answers a host's SYSTEM_ERROR query with status 0,
        # even after an LVDS timeout (test_cmd.pcap; mmwave-capture-std notes).
        return _OK

    def _reset_fpga(self, data: bytes) -> int:
        with self._cond:
            if self._recording:
                log.info("fake DCA1000: RESET_FPGA stops the recording")
            self._recording = False
            self._abort_id += 1
            self._fpga_config = None
            self._packet_config = PacketConfig()
            self._events = [e for e in self._events if e[1] != "no_lvds"]
            self._cond.notify_all()
        return _OK

    def _reset_ar_dev(self, data: bytes) -> int:
        self.lvds_stop()  # a radar in reset streams nothing
        callback = self.on_reset_ar_dev
        if callback is not None:
            try:
                callback()
            except Exception:
                log.exception("fake DCA1000: on_reset_ar_dev failed")
                return _FAILURE
        return _OK

    def _config_fpga_gen(self, data: bytes) -> int:
        cfg = _parsed(FpgaConfig, "CONFIG_FPGA_GEN", data)
        if cfg is None:
            return _FAILURE
        problem = _fpga_config_problem(cfg)
        if problem:
            log.warning("fake DCA1000: CONFIG_FPGA_GEN refused: %s", problem)
            return _FAILURE
        with self._cond:
            self._fpga_config = cfg
        return _OK

    def _config_packet_data(self, data: bytes) -> int:
        pkt = _parsed(PacketConfig, "CONFIG_PACKET_DATA", data)
        if pkt is None:
            return _FAILURE
        if not MIN_PACKET_SIZE <= pkt.packet_size <= MAX_PACKET_SIZE:
            log.warning("fake DCA1000: CONFIG_PACKET_DATA refused: packet size %d outside "
                        "%d..%d", pkt.packet_size, MIN_PACKET_SIZE, MAX_PACKET_SIZE)
            return _FAILURE
        lo, hi = DCA1000_PACKET_DELAY_RANGE_US
        if not lo <= pkt.delay_us <= hi:  # its pacing (and the link rate it reports) is not known there
            log.warning("fake DCA1000: CONFIG_PACKET_DATA refused: packet delay %.3f us is outside the "
                        "documented %g..%g us", pkt.delay_us, lo, hi)
            return _FAILURE
        with self._cond:
            self._packet_config = pkt
        return _OK

    def _config_eeprom(self, data: bytes) -> int:
        eeprom = _parsed(EepromConfig, "CONFIG_EEPROM", data)
        if eeprom is None:
            return _FAILURE
        with self._cond:
            self._eeprom_config = eeprom
        return _OK

    def _record_start(self, data: bytes) -> int:
        with self._cond:
            if self._fpga_config is None:
                log.warning("fake DCA1000: RECORD_START refused: no CONFIG_FPGA_GEN since "
                            "power-up or RESET_FPGA")
                return _FAILURE
            if self._recording:
                log.info("fake DCA1000: RECORD_START while recording restarts the stream")
            self._recording = True
            self._recording_id += 1
            self._abort_id += 1
            self._stats = StreamStats(recording=self._recording_id)
            self._lost = {}
            self._lvds_seen = self._lvds
            self._events = [e for e in self._events if e[1] != "no_lvds"]
            if not self._lvds:
                self._events.append((time.monotonic() + self.no_lvds_timeout_s, "no_lvds",
                                     self._recording_id))
            self._cond.notify_all()
        log.info("fake DCA1000: recording %d started", self._recording_id)
        return _OK

    def _record_stop(self, data: bytes) -> int:
        with self._cond:
            if self._recording:
                self._recording = False
                due = time.monotonic() + self.record_completed_delay_s
                self._tail_due[self._recording_id] = due
                self._events.append((due, "record_completed", self._recording_id))
                self._cond.notify_all()
                log.info("fake DCA1000: recording %d stopped", self._recording_id)
        return _OK

    def _run_due_events(self) -> None:
        now = time.monotonic()
        send: list[int] = []
        with self._cond:
            keep = []
            for due, kind, rec in self._events:
                if due > now:
                    keep.append((due, kind, rec))
                elif kind == "record_completed":
                    still_sending = self._streamer_busy or self._held_tail[0] == rec and self._held_tail[1] > 0
                    if still_sending and not self._recording and rec == self._recording_id:
                        keep.append((now + 0.01, kind, rec))  # the stream or its tail is still going out
                    else:
                        send.append(int(AsyncStatus.RECORD_COMPLETED))
                elif kind == "no_lvds":
                    if self._recording and rec == self._recording_id and not self._lvds_seen:
                        send.append(int(AsyncStatus.NO_LVDS_DATA))
            self._events = keep
        for status in send:
            self._send_async(status)

    def _send_async(self, status: int) -> None:
        addr = self._host_config_address
        if addr is None:
            log.warning("fake DCA1000: async status 0x%04X dropped: no host has sent a command",
                        status)
            return
        with self._cond:
            self._async_log.append(int(status))
        log.info("fake DCA1000: async status %s", AsyncStatus(status))
        self._send(self._src_sock, Response(Command.SYSTEM_ERROR, int(status)).pack(), addr)

    def _send(self, sock: socket.socket, payload: bytes, addr: tuple[str, int]) -> bool:
        try:
            sock.sendto(payload, addr)
            return True
        except OSError as exc:
            log.debug("fake DCA1000: sendto %s:%d failed: %s", *addr, exc)
            with self._cond:
                self._stats.send_errors += 1
            return False


def _parsed(wire: type, command: str, data: bytes):
    """*data* parsed as the *wire* structure (its ``parse``), or None, logged as *command*
    refused, when it is malformed."""
    try:
        return wire.parse(data)
    except WireError as exc:
        log.warning("fake DCA1000: %s refused: %s", command, exc)
        return None


def _fpga_config_problem(cfg: FpgaConfig) -> str:
    """Why the fake refuses a CONFIG_FPGA_GEN ('' when it accepts it): only raw
    Ethernet capture of 16-bit samples over 2 LVDS lanes (the AWR1843) is supported."""
    wanted = (("log mode", cfg.log_mode, LogMode.RAW), ("LVDS mode", cfg.lvds_mode, LvdsMode.TWO_LANE),
              ("transfer mode", cfg.transfer_mode, TransferMode.CAPTURE),
              ("capture mode", cfg.capture_mode, CaptureMode.ETHERNET),
              ("format mode", cfg.format_mode, FormatMode.BIT16))
    bad = [f"{name} {value} (expected {int(want)} = {want.name})"
           for name, value, want in wanted if value != want]
    return "; ".join(bad)


def _command_name(code: int) -> str:
    try:
        return Command(code).name
    except ValueError:
        return f"command 0x{code:04X}"
