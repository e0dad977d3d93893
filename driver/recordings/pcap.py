"""A small reader of classic libpcap files holding UDP/IPv4 over Ethernet.

Enough to replay or inspect real DCA1000 traffic captured with tcpdump or
Wireshark (``.pcap``, not ``.pcapng``), with the standard library only.
"""

from __future__ import annotations

import ipaddress
import os
import struct
from dataclasses import dataclass
from typing import Iterator

from ...errors import CaptureFormatError

#: Global header: magic, version major/minor, thiszone, sigfigs, snaplen, link type.
_GLOBAL = struct.Struct("IHHiIII")
#: Per-record header: seconds, sub-seconds, captured length, original length.
_RECORD = struct.Struct("IIII")
#: Ethernet II header: destination MAC, source MAC, EtherType (big-endian).
_ETHERNET = struct.Struct("!6s6sH")
#: IPv4 header without options: version/IHL, TOS, total length, id, flags/fragment,
#: TTL, protocol, checksum, source, destination.
_IPV4 = struct.Struct("!BBHHHBBH4s4s")
#: UDP header: source port, destination port, length, checksum.
_UDP = struct.Struct("!HHHH")

_MAGIC_US, _MAGIC_NS = 0xA1B2C3D4, 0xA1B23C4D
_LINKTYPE_ETHERNET = 1
_ETHERTYPE_IPV4 = 0x0800
_IPPROTO_UDP = 17


@dataclass(frozen=True)
class UdpDatagram:
    """One UDP datagram from a capture."""

    time: float  # seconds since the epoch
    src: tuple[str, int]
    dst: tuple[str, int]
    payload: bytes


def read_udp(path: str | os.PathLike) -> Iterator[UdpDatagram]:
    """Yield the UDP/IPv4 datagrams of an Ethernet pcap file, in file order.

    Other frames (ARP, IPv6, fragments) are skipped.
    """
    with open(path, "rb") as fh:
        data = fh.read()
    if len(data) < _GLOBAL.size:
        raise CaptureFormatError(f"{os.fspath(path)}: too short for a pcap file")
    for order in "<>":
        magic = struct.unpack_from(order + "I", data)[0]
        if magic in (_MAGIC_US, _MAGIC_NS):
            break
    else:
        raise CaptureFormatError(f"{os.fspath(path)}: not a libpcap file (pcapng is not supported)")
    ticks = 1e-9 if magic == _MAGIC_NS else 1e-6
    glob = struct.Struct(order + _GLOBAL.format)
    rec = struct.Struct(order + _RECORD.format)
    linktype = glob.unpack_from(data)[6]
    if linktype != _LINKTYPE_ETHERNET:
        raise CaptureFormatError(f"{os.fspath(path)}: link type {linktype}, expected Ethernet (1)")
    offset = glob.size
    while offset + rec.size <= len(data):
        sec, sub, caplen, _ = rec.unpack_from(data, offset)
        offset += rec.size
        frame = data[offset: offset + caplen]
        offset += caplen
        if len(frame) < caplen:
            raise CaptureFormatError(f"{os.fspath(path)}: truncated record at byte {offset - caplen}")
        datagram = _udp_of(frame, sec + sub * ticks)
        if datagram is not None:
            yield datagram


def _udp_of(frame: bytes, time: float) -> UdpDatagram | None:
    if len(frame) < _ETHERNET.size + _IPV4.size + _UDP.size:
        return None
    _, _, ethertype = _ETHERNET.unpack_from(frame)
    if ethertype != _ETHERTYPE_IPV4:
        return None
    ip_at = _ETHERNET.size
    ver_ihl, _, total, _, frag, _, proto, _, src, dst = _IPV4.unpack_from(frame, ip_at)
    if ver_ihl >> 4 != 4 or proto != _IPPROTO_UDP or frag & 0x1FFF or frag & 0x2000:
        return None
    udp_at = ip_at + (ver_ihl & 0x0F) * 4
    sport, dport, length, _ = _UDP.unpack_from(frame, udp_at)
    payload = frame[udp_at + _UDP.size: udp_at + length]
    return UdpDatagram(time, (str(ipaddress.IPv4Address(src)), sport),
                       (str(ipaddress.IPv4Address(dst)), dport), payload)
