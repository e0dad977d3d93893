"""The fake DCA1000's state as tests and tools read it: its addresses, the configuration the host
sent, and the ground truth of what the stream did (:class:`BoardInspection`, a part of
:class:`~.fake_dca1000.FakeDca1000`; its properties read the board's state, which
:class:`~.fake_dca1000.FakeDca1000` sets up)."""

from __future__ import annotations

import dataclasses
import time

from ...cfg import dca1000_capacity_mbps
from ..live.dca1000_wire import EepromConfig, FpgaConfig, PacketConfig
from .dca1000_faults import StreamStats
from .dca1000_streamer import _WAIT_SLICE_S


class BoardInspection:
    """What a :class:`~.fake_dca1000.FakeDca1000` was told and what it did, read under its lock."""

    @property
    def command_address(self) -> tuple[str, int]:
        """Where the host sends requests (the real board's 192.168.33.180:4096)."""
        return (self.board_ip, self.command_port)

    @property
    def source_address(self) -> tuple[str, int]:
        """Where replies, async status and data come from (the real board's port 1024)."""
        return (self.board_ip, self.source_port)

    @property
    def foreign_address(self) -> tuple[str, int] | None:
        """Where ``Faults.foreign`` copies come from (None without that fault)."""
        return None if self._foreign_sock is None else self._foreign_sock.getsockname()

    @property
    def recording(self) -> bool:
        return self._recording

    @property
    def lvds_active(self) -> bool:
        return self._lvds

    @property
    def fpga_config(self) -> FpgaConfig | None:
        """The accepted CONFIG_FPGA_GEN (None since power-up or RESET_FPGA)."""
        return self._fpga_config

    @property
    def packet_config(self) -> PacketConfig:
        """The accepted CONFIG_PACKET_DATA (the board default before one)."""
        return self._packet_config

    @property
    def eeprom_config(self) -> EepromConfig | None:
        """The last CONFIG_EEPROM (stored only; the fake keeps its addresses)."""
        return self._eeprom_config

    @property
    def host_config_address(self) -> tuple[str, int] | None:
        """Where async status goes: the address the last command came from."""
        return self._host_config_address

    @property
    def link_rate_mbps(self) -> float:
        """The paced data rate at the configured packet delay, Mbit/s of ADC data."""
        return dca1000_capacity_mbps(self._packet_config.delay_us)

    @property
    def stats(self) -> StreamStats:
        """A snapshot of the current (or last) recording's ground truth."""
        with self._cond:
            return dataclasses.replace(self._stats)

    @property
    def lost_bytes_per_frame(self) -> dict[int, int]:
        """Frame index -> bytes of it that never arrived intact in a first copy
        (dropped, malformed, truncated away; duplicates restore nothing,
        reordered packets arrive).  Only frames with losses are listed; bytes of
        a frame cut short by RESET_FPGA or close() count as lost."""
        with self._cond:
            return dict(self._lost)

    @property
    def async_sent(self) -> list[int]:
        """Async statuses sent so far, in order (ints of AsyncStatus bits)."""
        with self._cond:
            return list(self._async_log)

    @property
    def malformed_requests(self) -> int:
        """Config datagrams that were not well-formed requests (not answered)."""
        with self._cond:
            return self._malformed_requests

    @property
    def commands(self) -> dict[int, int]:
        """Well-formed requests received, by command code."""
        with self._cond:
            return dict(self._commands)

    def wait_frames(self, n: int, timeout: float = 5.0, *, streamed: bool = False) -> bool:
        """Wait until the current recording has packetized *n* frames (with *streamed*: until
        the radar has streamed *n* frames into the board, the last one's tail perhaps held
        back); False on timeout."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while (self._stats.frames_in if streamed else self._stats.frames_sent) < n:
                left = deadline - time.monotonic()
                if left <= 0 or self._closed:
                    return False
                self._cond.wait(min(left, _WAIT_SLICE_S))
            return True


__all__ = ["BoardInspection"]
