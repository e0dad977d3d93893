"""DCA1000EVM wire formats as named structures (protocol.md).

Sources: DCA1000EVM User's Guide (SPRUIJ4A) tables 11-14, TI's DCA1000 CLI
(``rf_api.h``, ``recorddatarecv.cpp``), and the real captures in
``shared/reference/pcaps``.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

#: UDP ports of the board (UG Table 11).
CONFIG_PORT = 4096
DATA_PORT = 4098
#: Default addresses (UG Table 11).
BOARD_IP = "192.168.33.180"
HOST_IP = "192.168.33.30"

#: Raw data packet header: u32 sequence number (1 after RECORD_START), then a
#: 48-bit count of the ADC bytes sent *before* this packet (little-endian).
DATA_HEADER = struct.Struct("<I6s")
#: ADC bytes in a full data packet.
MAX_DATA_BYTES = 1456


@dataclass(frozen=True)
class DataPacket:
    """One raw-data UDP datagram from port 4098."""

    seq: int
    #: ADC bytes the board sent before this packet: where ``data`` starts in the stream.
    byte_count: int
    data: bytes

    @classmethod
    def parse(cls, payload: bytes) -> "DataPacket":
        if len(payload) <= DATA_HEADER.size or len(payload) > DATA_HEADER.size + MAX_DATA_BYTES:
            raise ValueError(f"data packet of {len(payload)} bytes: expected "
                             f"{DATA_HEADER.size + 1}..{DATA_HEADER.size + MAX_DATA_BYTES}")
        seq, count = DATA_HEADER.unpack_from(payload)
        return cls(seq, int.from_bytes(count, "little"), bytes(payload[DATA_HEADER.size:]))

    def pack(self) -> bytes:
        return DATA_HEADER.pack(self.seq, self.byte_count.to_bytes(6, "little")) + self.data
