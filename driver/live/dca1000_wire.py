"""DCA1000EVM wire formats as named structures (protocol.md).

Sources: DCA1000EVM User's Guide (SPRUIJ4A) tables 11-14 and 19, TI's DCA1000
CLI (``rf_api.h``, ``rf_api.cpp``, ``recorddatarecv.cpp``), and the real
captures in ``shared/reference/pcaps``.

Config port (UDP 4096): the host sends a request, the board answers with a
fixed 8-byte response, and also sends asynchronous status messages
(``SYSTEM_ERROR``, a bitmask).  Data port (UDP 4098): raw ADC bytes, each
packet with a sequence number and the count of bytes sent before it.
"""

from __future__ import annotations

import enum
import ipaddress
import struct
from dataclasses import dataclass

from ...errors import CaptureError

#: UDP ports (UG Table 11); the board sends from BOARD_SOURCE_PORT (pcaps).
CONFIG_PORT = 4096
DATA_PORT = 4098
BOARD_SOURCE_PORT = 1024
#: Default addresses (UG Table 11).
BOARD_IP = "192.168.33.180"
HOST_IP = "192.168.33.30"
BOARD_MAC = "12:34:56:78:90:12"

#: Request/response framing (UG Tables 13-14).
HEADER_MAGIC = 0xA55A
FOOTER_MAGIC = 0xEEAA
#: Request header: magic, command code, data size; then data; then FOOTER (u16).
REQUEST_HEADER = struct.Struct("<HHH")
FOOTER = struct.Struct("<H")
#: Response and async status: magic, command code, status, footer.
RESPONSE = struct.Struct("<HHHH")
#: Largest request data (TI-CLI MAX_DATA_BYTES).
MAX_REQUEST_DATA = 504

#: Raw data packet header: u32 sequence number (1 after RECORD_START), then a
#: 48-bit count of the ADC bytes sent *before* this packet (little-endian).
DATA_HEADER = struct.Struct("<I6s")
#: ADC bytes in a full data packet.
MAX_DATA_BYTES = 1456


class Command(enum.IntEnum):
    """Config port command codes (UG Table 12)."""

    RESET_FPGA = 0x01
    RESET_AR_DEV = 0x02
    CONFIG_FPGA_GEN = 0x03
    CONFIG_EEPROM = 0x04
    RECORD_START = 0x05
    RECORD_STOP = 0x06
    PLAYBACK_START = 0x07
    PLAYBACK_STOP = 0x08
    SYSTEM_CONNECT = 0x09
    SYSTEM_ERROR = 0x0A  # asynchronous status, board to host
    CONFIG_PACKET_DATA = 0x0B
    CONFIG_DATA_MODE_AR_DEV = 0x0C
    INIT_FPGA_PLAYBACK = 0x0D
    READ_FPGA_VERSION = 0x0E


class Status(enum.IntEnum):
    """Response status (UG Table 14)."""

    SUCCESS = 0
    FAILURE = 1


class AsyncStatus(enum.IntFlag):
    """Bits of the asynchronous SYSTEM_ERROR status (TI-CLI SYS_ASYNC_STATUS)."""

    NO_LVDS_DATA = 1 << 0
    NO_HEADER = 1 << 1
    EEPROM_FAILURE = 1 << 2
    SD_CARD_DETECTED = 1 << 3
    SD_CARD_REMOVED = 1 << 4
    SD_CARD_FULL = 1 << 5
    MODE_CONFIG_FAILURE = 1 << 6
    DDR_FULL = 1 << 7
    RECORD_COMPLETED = 1 << 8
    LVDS_BUFFER_FULL = 1 << 9
    PLAYBACK_COMPLETED = 1 << 10
    PLAYBACK_OUT_OF_SEQ = 1 << 11


#: What each async bit means for a person, and whether it is a problem.
ASYNC_MEANING = {
    AsyncStatus.NO_LVDS_DATA: ("no LVDS data from the radar (is lvdsStreamCfg -1 0 1 0 set and the "
                               "sensor started?)", True),
    AsyncStatus.NO_HEADER: ("LVDS data without the expected header", True),
    AsyncStatus.EEPROM_FAILURE: ("EEPROM failure", True),
    AsyncStatus.SD_CARD_DETECTED: ("SD card detected", False),
    AsyncStatus.SD_CARD_REMOVED: ("SD card removed", False),
    AsyncStatus.SD_CARD_FULL: ("SD card full", True),
    AsyncStatus.MODE_CONFIG_FAILURE: ("mode configuration failed", True),
    AsyncStatus.DDR_FULL: ("the board's DDR buffer is full: the host is not reading fast enough or "
                           "the data rate exceeds the link", True),
    AsyncStatus.RECORD_COMPLETED: ("recording completed", False),
    AsyncStatus.LVDS_BUFFER_FULL: ("the board's LVDS buffer is full: data was lost", True),
    AsyncStatus.PLAYBACK_COMPLETED: ("playback completed", False),
    AsyncStatus.PLAYBACK_OUT_OF_SEQ: ("playback out of sequence", True),
}


class LogMode(enum.IntEnum):
    RAW = 1
    MULTI = 2


class LvdsMode(enum.IntEnum):
    FOUR_LANE = 1
    TWO_LANE = 2  # xWR18xx / xWR16xx


class TransferMode(enum.IntEnum):
    CAPTURE = 1
    PLAYBACK = 2


class CaptureMode(enum.IntEnum):
    SD_CARD = 1
    ETHERNET = 2


class FormatMode(enum.IntEnum):
    BIT12 = 1
    BIT14 = 2
    BIT16 = 3


#: CONFIG_FPGA_GEN data: log, LVDS, transfer, capture, format modes, LVDS timer (u8 each).
FPGA_CONFIG = struct.Struct("<6B")
#: CONFIG_PACKET_DATA data: packet size (bytes), delay in 8 ns ticks, reserved 0.
PACKET_CONFIG = struct.Struct("<HHH")
#: CONFIG_EEPROM data: PC IP, board IP and MAC byte-reversed, then config and data port.
EEPROM_CONFIG = struct.Struct("<4s4s6sHH")
#: Default LVDS timer of CONFIG_FPGA_GEN (TI-CLI FPGA_CONFIG_DEFAULT_TIMER).
FPGA_DEFAULT_TIMER = 30
#: One tick of the packet delay, ns.
PACKET_DELAY_TICK_NS = 8
#: UDP payload of a full data packet (CONFIG_PACKET_DATA's "packet size" in TI's CLI).
DEFAULT_PACKET_SIZE = 1472


class WireError(CaptureError, ValueError):
    """Bytes that are not a well-formed DCA1000 message (says what is wrong)."""


@dataclass(frozen=True)
class Request:
    command: int
    data: bytes = b""

    def pack(self) -> bytes:
        if len(self.data) > MAX_REQUEST_DATA:
            raise WireError(f"request data of {len(self.data)} bytes exceeds {MAX_REQUEST_DATA}")
        return REQUEST_HEADER.pack(HEADER_MAGIC, self.command, len(self.data)) + self.data + \
            FOOTER.pack(FOOTER_MAGIC)

    @classmethod
    def parse(cls, payload: bytes) -> "Request":
        if len(payload) < REQUEST_HEADER.size + FOOTER.size:
            raise WireError(f"request of {len(payload)} bytes is shorter than a header and footer")
        magic, cmd, size = REQUEST_HEADER.unpack_from(payload)
        if magic != HEADER_MAGIC:
            raise WireError(f"request header 0x{magic:04X}, expected 0x{HEADER_MAGIC:04X}")
        if len(payload) != REQUEST_HEADER.size + size + FOOTER.size:
            raise WireError(f"request says {size} data bytes but holds "
                            f"{len(payload) - REQUEST_HEADER.size - FOOTER.size}")
        (footer,) = FOOTER.unpack_from(payload, REQUEST_HEADER.size + size)
        if footer != FOOTER_MAGIC:
            raise WireError(f"request footer 0x{footer:04X}, expected 0x{FOOTER_MAGIC:04X}")
        return cls(cmd, bytes(payload[REQUEST_HEADER.size: REQUEST_HEADER.size + size]))


@dataclass(frozen=True)
class Response:
    """A command response, or an asynchronous status (command SYSTEM_ERROR)."""

    command: int
    status: int

    def pack(self) -> bytes:
        return RESPONSE.pack(HEADER_MAGIC, self.command, self.status, FOOTER_MAGIC)

    @classmethod
    def parse(cls, payload: bytes) -> "Response":
        if len(payload) != RESPONSE.size:
            raise WireError(f"response of {len(payload)} bytes, expected {RESPONSE.size}")
        magic, cmd, status, footer = RESPONSE.unpack(payload)
        if magic != HEADER_MAGIC or footer != FOOTER_MAGIC:
            raise WireError(f"response framing 0x{magic:04X}/0x{footer:04X}, expected "
                            f"0x{HEADER_MAGIC:04X}/0x{FOOTER_MAGIC:04X}")
        return cls(cmd, status)

    @property
    def is_async(self) -> bool:
        return self.command == Command.SYSTEM_ERROR


@dataclass(frozen=True)
class FpgaConfig:
    """CONFIG_FPGA_GEN: what the AWR1843 raw capture needs by default."""

    log_mode: int = LogMode.RAW
    lvds_mode: int = LvdsMode.TWO_LANE
    transfer_mode: int = TransferMode.CAPTURE
    capture_mode: int = CaptureMode.ETHERNET
    format_mode: int = FormatMode.BIT16
    timer: int = FPGA_DEFAULT_TIMER

    def pack(self) -> bytes:
        return FPGA_CONFIG.pack(self.log_mode, self.lvds_mode, self.transfer_mode, self.capture_mode,
                                self.format_mode, self.timer)

    @classmethod
    def parse(cls, data: bytes) -> "FpgaConfig":
        if len(data) != FPGA_CONFIG.size:
            raise WireError(f"CONFIG_FPGA_GEN data of {len(data)} bytes, expected {FPGA_CONFIG.size}")
        return cls(*FPGA_CONFIG.unpack(data))


@dataclass(frozen=True)
class PacketConfig:
    """CONFIG_PACKET_DATA: UDP packet size and the delay between packets."""

    packet_size: int = DEFAULT_PACKET_SIZE
    delay_us: float = 25.0

    def pack(self) -> bytes:
        ticks = round(self.delay_us * 1000 / PACKET_DELAY_TICK_NS)
        return PACKET_CONFIG.pack(self.packet_size, ticks, 0)

    @classmethod
    def parse(cls, data: bytes) -> "PacketConfig":
        if len(data) != PACKET_CONFIG.size:
            raise WireError(f"CONFIG_PACKET_DATA data of {len(data)} bytes, expected {PACKET_CONFIG.size}")
        size, ticks, _ = PACKET_CONFIG.unpack(data)
        return cls(size, ticks * PACKET_DELAY_TICK_NS / 1000)


@dataclass(frozen=True)
class EepromConfig:
    """CONFIG_EEPROM: the addresses the board boots with (written to flash!)."""

    host_ip: str = HOST_IP
    board_ip: str = BOARD_IP
    board_mac: str = BOARD_MAC
    config_port: int = CONFIG_PORT
    data_port: int = DATA_PORT

    def pack(self) -> bytes:
        mac = bytes(int(b, 16) for b in self.board_mac.replace("-", ":").split(":"))
        if len(mac) != 6:
            raise WireError(f"MAC address {self.board_mac!r} is not six bytes")
        return EEPROM_CONFIG.pack(ipaddress.IPv4Address(self.host_ip).packed[::-1],
                                  ipaddress.IPv4Address(self.board_ip).packed[::-1], mac[::-1],
                                  self.config_port, self.data_port)

    @classmethod
    def parse(cls, data: bytes) -> "EepromConfig":
        if len(data) != EEPROM_CONFIG.size:
            raise WireError(f"CONFIG_EEPROM data of {len(data)} bytes, expected {EEPROM_CONFIG.size}")
        host, board, mac, cport, dport = EEPROM_CONFIG.unpack(data)
        return cls(str(ipaddress.IPv4Address(host[::-1])), str(ipaddress.IPv4Address(board[::-1])),
                   ":".join(f"{b:02x}" for b in mac[::-1]), cport, dport)


@dataclass(frozen=True)
class FpgaVersion:
    """READ_FPGA_VERSION answers in the status field: major = s & 0x7F,
    minor = (s >> 7) & 0x7F, bit 0x4000 set for the playback image."""

    major: int
    minor: int
    playback: bool

    @classmethod
    def from_status(cls, status: int) -> "FpgaVersion":
        return cls(status & 0x7F, (status >> 7) & 0x7F, bool(status & 0x4000))

    def to_status(self) -> int:
        return (self.major & 0x7F) | (self.minor & 0x7F) << 7 | (0x4000 if self.playback else 0)

    def __str__(self) -> str:
        return f"{self.major}.{self.minor} [{'Playback' if self.playback else 'Record'}]"


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
            raise WireError(f"data packet of {len(payload)} bytes: expected "
                            f"{DATA_HEADER.size + 1}..{DATA_HEADER.size + MAX_DATA_BYTES}")
        seq, count = DATA_HEADER.unpack_from(payload)
        return cls(seq, int.from_bytes(count, "little"), bytes(payload[DATA_HEADER.size:]))

    def pack(self) -> bytes:
        return DATA_HEADER.pack(self.seq, self.byte_count.to_bytes(6, "little")) + self.data
