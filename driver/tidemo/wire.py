"""The UART output of TI's mmWave SDK 3.x xWR18xx out-of-box demo: one packet per frame.

Sources (the tables these dtypes follow):

- ``ti/demo/xwr18xx/mmw/include/mmw_output.h`` (SDK 3.4/3.5): ``MmwDemo_output_message_header``
  (the 40-byte header), ``MmwDemo_output_message_tl`` (type, length), the TLV types
  ``MmwDemo_output_message_type`` (1..9), ``MmwDemo_output_message_stats``;
  ``MMWDEMO_OUTPUT_MSG_SEGMENT_LEN`` (32: a packet is padded to a multiple of it).
- ``ti/datapath/dpif/dpif_pointcloud.h``: ``DPIF_PointCloudCartesian`` (x, y, z, velocity, float32,
  TI sensor frame, velocity positive receding) and ``DPIF_PointCloudSideInfo`` (snr, noise: int16,
  0.1 dB steps).
- ``ti/demo/xwr18xx/mmw/mss/mss_main.c`` ``MmwDemo_transmitProcessedOutput``: the TLV order
  (points, side info, range profile, noise profile, azimuth static heatmap, range-Doppler heatmap,
  stats, temperature), their lengths, and the padding.  Its condition ``detectedObjects == 1 ||
  detectedObjects == 2 && numObj > 0`` sends the points TLV with length 0 when a frame has no
  point and guiMonitor's detectedObjects is 1; side info only with points.
- ``mmw_mss.h`` ``MmwDemo_temperatureStats`` (int32 valid + mmWaveLink's ``rlRfTempData_t``).
- ``aoaprochwa.c`` ``AoAProcHWA_PrepareRangeAzimuthHeatmap``: the azimuth static heatmap is, per
  range bin, the zero-Doppler bin of the (windowed) Doppler FFT of the first ``numVirtualAntAzim``
  virtual antennas in chirp order (TX slot-major, RX-minor), ``cmplx16ImRe_t`` (imaginary part
  first), after the Rx channel compensation of the cfg's ``compRangeBiasAndRxChanPhase``.
- TI's "Understanding the Out of Box Demo Data Output" (mmWave industrial toolbox) for the
  header's field meanings.

All fields are little-endian.  Nothing here does I/O; :mod:`.framer` cuts a byte stream into
packets and :func:`parse_packet` checks one.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np

#: The sync word ``{0x0102, 0x0304, 0x0506, 0x0708}`` as uint16 little-endian.
MAGIC = bytes([0x02, 0x01, 0x04, 0x03, 0x06, 0x05, 0x08, 0x07])
#: MMWDEMO_OUTPUT_MSG_SEGMENT_LEN: packets are padded to a multiple of this many bytes.
SEGMENT_LEN = 32
#: ``header.platform`` of the xWR18xx demo.
PLATFORM_XWR18XX = 0xA1843
#: SDK major version of this format (``header.version >> 24``); 2.x demos sent another one.
SDK_MAJOR = 3

#: MmwDemo_output_message_header (40 bytes).
HEADER_DTYPE = np.dtype([
    ("magic", "<u2", (4,)),
    ("version", "<u4"),  # major << 24 | minor << 16 | bugfix << 8 | build
    ("total_packet_len", "<u4"),  # bytes, header and padding included
    ("platform", "<u4"),
    ("frame_number", "<u4"),  # frameStartIntCounter: 1 for the first frame after sensorStart
    ("time_cpu_cycles", "<u4"),
    ("num_detected_obj", "<u4"),
    ("num_tlvs", "<u4"),
    ("subframe_number", "<u4"),
])
#: MmwDemo_output_message_tl (8 bytes).
TL_DTYPE = np.dtype([("type", "<u4"), ("length", "<u4")])
#: DPIF_PointCloudCartesian: m, m, m, m/s (16 bytes).
POINT_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("velocity", "<f4")])
#: DPIF_PointCloudSideInfo: CFAR SNR and noise of each point, 0.1 dB steps (4 bytes).
SIDE_INFO_DTYPE = np.dtype([("snr", "<i2"), ("noise", "<i2")])
#: cmplx16ImRe_t, one azimuth static heatmap value (4 bytes).
HEATMAP_DTYPE = np.dtype([("imag", "<i2"), ("real", "<i2")])
#: MmwDemo_output_message_stats: microseconds, and CPU loads in percent (24 bytes).
STATS_DTYPE = np.dtype([
    ("inter_frame_processing_time_us", "<u4"), ("transmit_output_time_us", "<u4"),
    ("inter_frame_processing_margin_us", "<u4"), ("inter_chirp_processing_margin_us", "<u4"),
    ("active_frame_cpu_load", "<u4"), ("inter_frame_cpu_load", "<u4"),
])
#: MmwDemo_temperatureStats: tempReportValid, then rlRfTempData_t (time, ms; sensors, deg C) (28 bytes).
TEMPERATURE_DTYPE = np.dtype([
    ("report_valid", "<i4"), ("time_ms", "<u4"),
    ("rx0", "<i2"), ("rx1", "<i2"), ("rx2", "<i2"), ("rx3", "<i2"),
    ("tx0", "<i2"), ("tx1", "<i2"), ("tx2", "<i2"), ("pm", "<i2"), ("dig0", "<i2"), ("dig1", "<i2"),
])
#: Range profile, noise profile and range-Doppler heatmap cells: the HWA's log2 magnitude
#: (fixed point, summed over the virtual antennas), as uint16.
LOG_MAGNITUDE_DTYPE = np.dtype("<u2")


class Tlv(enum.IntEnum):
    """MmwDemo_output_message_type."""

    DETECTED_POINTS = 1
    RANGE_PROFILE = 2
    NOISE_PROFILE = 3
    AZIMUT_STATIC_HEAT_MAP = 4
    RANGE_DOPPLER_HEAT_MAP = 5
    STATS = 6
    DETECTED_POINTS_SIDE_INFO = 7
    AZIMUT_ELEVATION_STATIC_HEAT_MAP = 8  # declared, never sent by the xWR18xx demo
    TEMPERATURE_STATS = 9


#: TLVs whose length is fixed (bytes).
FIXED_LENGTHS = {Tlv.STATS: STATS_DTYPE.itemsize, Tlv.TEMPERATURE_STATS: TEMPERATURE_DTYPE.itemsize}
#: Bytes per element of each variable-length TLV.
ITEM_SIZES = {Tlv.DETECTED_POINTS: POINT_DTYPE.itemsize, Tlv.DETECTED_POINTS_SIDE_INFO: SIDE_INFO_DTYPE.itemsize,
              Tlv.RANGE_PROFILE: 2, Tlv.NOISE_PROFILE: 2, Tlv.AZIMUT_STATIC_HEAT_MAP: HEATMAP_DTYPE.itemsize,
              Tlv.RANGE_DOPPLER_HEAT_MAP: 2, Tlv.AZIMUT_ELEVATION_STATIC_HEAT_MAP: HEATMAP_DTYPE.itemsize}


@dataclass(frozen=True)
class GuiSelection:
    """guiMonitor's fields (``guiMonitor <subFrameIdx> <detectedObjects> <logMagRange>
    <noiseProfile> <rangeAzimuthHeatMap> <rangeDopplerHeatMap> <statsInfo>``): which TLVs every
    packet carries.  detected_objects: 0 none, 1 points and side info, 2 points only."""

    detected_objects: int = 1
    log_mag_range: bool = False
    noise_profile: bool = False
    range_azimuth_heat_map: bool = True
    range_doppler_heat_map: bool = False
    stats_info: bool = False

    def line(self) -> str:
        """The cfg line (subframe -1: every sub-frame)."""
        flags = (self.detected_objects, self.log_mag_range, self.noise_profile, self.range_azimuth_heat_map,
                 self.range_doppler_heat_map, self.stats_info)
        return "guiMonitor -1 " + " ".join(str(int(f)) for f in flags)


@dataclass(frozen=True)
class PacketLayout:
    """What the demo's packets hold for one configuration: range bins (numRangeBins, the ADC
    samples rounded up to a power of two), Doppler bins (the loops, likewise), the azimuth
    antennas of the static heatmap (numVirtualAntAzim) and the guiMonitor selection."""

    range_bins: int
    doppler_bins: int
    azimuth_antennas: int
    gui: GuiSelection = field(default_factory=GuiSelection)

    def tlv_lengths(self, n_points: int) -> list[tuple[Tlv, int]]:
        """The TLVs a packet with *n_points* points carries, in the demo's order, with their
        payload lengths (``MmwDemo_transmitProcessedOutput``)."""
        g, out = self.gui, []
        if g.detected_objects == 1 or (g.detected_objects == 2 and n_points > 0):
            out.append((Tlv.DETECTED_POINTS, POINT_DTYPE.itemsize * n_points))
        if g.detected_objects == 1 and n_points > 0:
            out.append((Tlv.DETECTED_POINTS_SIDE_INFO, SIDE_INFO_DTYPE.itemsize * n_points))
        if g.log_mag_range:
            out.append((Tlv.RANGE_PROFILE, 2 * self.range_bins))
        if g.noise_profile:
            out.append((Tlv.NOISE_PROFILE, 2 * self.range_bins))
        if g.range_azimuth_heat_map:
            out.append((Tlv.AZIMUT_STATIC_HEAT_MAP, HEATMAP_DTYPE.itemsize * self.range_bins * self.azimuth_antennas))
        if g.range_doppler_heat_map:
            out.append((Tlv.RANGE_DOPPLER_HEAT_MAP, 2 * self.range_bins * self.doppler_bins))
        if g.stats_info:
            out += [(Tlv.STATS, STATS_DTYPE.itemsize), (Tlv.TEMPERATURE_STATS, TEMPERATURE_DTYPE.itemsize)]
        return out

    def packet_bytes(self, n_points: int) -> int:
        """totalPacketLen of a packet with *n_points* points: header, TLVs, padding."""
        used = HEADER_DTYPE.itemsize + sum(TL_DTYPE.itemsize + n for _, n in self.tlv_lengths(n_points))
        return padded(used)


def padded(n: int) -> int:
    """*n* bytes rounded up to a whole number of segments."""
    return SEGMENT_LEN * ((n + SEGMENT_LEN - 1) // SEGMENT_LEN)


def sdk_version(version: int) -> str:
    """``header.version`` as TI writes it: ``03.05.00.04``."""
    return ".".join(f"{(version >> s) & 0xFF:02d}" for s in (24, 16, 8, 0))


def header_problem(header: np.void, max_length: int) -> str | None:
    """Why a header (HEADER_DTYPE) cannot start an SDK 3.x xWR18xx packet, or None."""
    length = int(header["total_packet_len"])
    if int(header["version"]) >> 24 != SDK_MAJOR:
        return f"SDK version {sdk_version(int(header['version']))}, not {SDK_MAJOR}.x"
    if length % SEGMENT_LEN or not HEADER_DTYPE.itemsize <= length <= max_length:
        return f"totalPacketLen {length} is no multiple of {SEGMENT_LEN} in [{HEADER_DTYPE.itemsize}, {max_length}]"
    if int(header["num_tlvs"]) > len(Tlv):
        return f"numTLVs {int(header['num_tlvs'])} is more than the {len(Tlv)} types"
    if int(header["platform"]) != PLATFORM_XWR18XX:
        return f"platform 0x{int(header['platform']):X}, not the xWR18xx's 0x{PLATFORM_XWR18XX:X} (another radar's demo)"
    if int(header["subframe_number"]):
        # radarodom takes frame-based cfgs only (dfeDataOutputMode 1), whose one sub-frame is 0.
        return f"subFrameNumber {int(header['subframe_number'])}, where a frame-based demo sends 0"
    return None


@dataclass
class Packet:
    """One checked packet: its header (a HEADER_DTYPE record) and each TLV's payload, a view of
    the packet's bytes by type.  ``used``: bytes before the padding."""

    data: bytes
    header: np.void
    payloads: dict[Tlv, memoryview]
    used: int
    #: Where the packet starts in its byte stream (set by the framer).
    offset: int = 0

    @property
    def frame_number(self) -> int:
        return int(self.header["frame_number"])

    @property
    def num_points(self) -> int:
        return int(self.header["num_detected_obj"])

    def array(self, tlv: Tlv, dtype: np.dtype) -> np.ndarray | None:
        """The TLV's payload as an array of *dtype* (a read-only view), None when absent."""
        view = self.payloads.get(tlv)
        return None if view is None else np.frombuffer(view, dtype)


def parse_packet(data: bytes, max_length: int = 1 << 24) -> Packet | str:
    """Check that *data* is exactly one packet (magic, header, the TLVs its header announces with
    their lengths, fewer than :data:`SEGMENT_LEN` bytes of padding) and return it; or the reason
    it is not, as text."""
    if len(data) < HEADER_DTYPE.itemsize or data[:len(MAGIC)] != MAGIC:
        return "no header"
    header = np.frombuffer(data, HEADER_DTYPE, count=1)[0]
    problem = header_problem(header, max_length)
    if problem is not None:
        return problem
    total = int(header["total_packet_len"])
    if len(data) != total:
        return f"{len(data)} bytes where totalPacketLen says {total}"
    n_points = int(header["num_detected_obj"])
    view, at, payloads = memoryview(data), HEADER_DTYPE.itemsize, {}
    for _ in range(int(header["num_tlvs"])):
        if at + TL_DTYPE.itemsize > total:
            return "a TLV header runs past the packet"
        tl = np.frombuffer(data, TL_DTYPE, count=1, offset=at)[0]
        kind, length = int(tl["type"]), int(tl["length"])
        at += TL_DTYPE.itemsize
        if kind not in Tlv._value2member_map_:
            return f"unknown TLV type {kind}"
        tlv = Tlv(kind)
        if tlv in payloads:
            return f"TLV {tlv.name} twice"
        if at + length > total:
            return f"TLV {tlv.name} of {length} bytes runs past the packet"
        problem = _length_problem(tlv, length, n_points)
        if problem is not None:
            return problem
        payloads[tlv] = view[at:at + length]
        at += length
    if total - at >= SEGMENT_LEN:
        return f"{total - at} bytes after the last TLV, more than padding"
    return Packet(data, header, payloads, at)


def _length_problem(tlv: Tlv, length: int, n_points: int) -> str | None:
    if tlv in FIXED_LENGTHS and length != FIXED_LENGTHS[tlv]:
        return f"TLV {tlv.name} of {length} bytes, not {FIXED_LENGTHS[tlv]}"
    if tlv in (Tlv.DETECTED_POINTS, Tlv.DETECTED_POINTS_SIDE_INFO) and length != ITEM_SIZES[tlv] * n_points:
        return f"TLV {tlv.name} of {length} bytes for numDetectedObj {n_points}"
    if tlv in ITEM_SIZES and length % ITEM_SIZES[tlv]:
        return f"TLV {tlv.name} of {length} bytes, not whole items of {ITEM_SIZES[tlv]}"
    return None


def encode_packet(layout: PacketLayout, frame_number: int, points: np.ndarray, side_info: np.ndarray,
                  heatmap: np.ndarray, *, time_cpu_cycles: int = 0, version: int = 0x03050004,
                  platform: int = PLATFORM_XWR18XX, log_magnitude: np.ndarray | None = None,
                  stats: np.ndarray | None = None, temperature: np.ndarray | None = None) -> bytes:
    """A packet as the demo sends it (:meth:`PacketLayout.tlv_lengths` order, zero padding).

    *points*: POINT_DTYPE (n,); *side_info*: SIDE_INFO_DTYPE (n,); *heatmap*: HEATMAP_DTYPE
    (range_bins, azimuth_antennas); *log_magnitude*: uint16 (range_bins, doppler_bins), whose
    Doppler bin 0 is the range profile and bin doppler_bins/2 - 1 the noise profile (as the demo
    takes them from its detection matrix); *stats*, *temperature*: one record each (zeros when
    None)."""
    n = len(points)
    rd = (np.zeros((layout.range_bins, layout.doppler_bins), LOG_MAGNITUDE_DTYPE) if log_magnitude is None
          else np.asarray(log_magnitude, LOG_MAGNITUDE_DTYPE))
    payload = {
        Tlv.DETECTED_POINTS: np.asarray(points, POINT_DTYPE).tobytes(),
        Tlv.DETECTED_POINTS_SIDE_INFO: np.asarray(side_info, SIDE_INFO_DTYPE).tobytes(),
        Tlv.RANGE_PROFILE: np.ascontiguousarray(rd[:, 0]).tobytes(),
        Tlv.NOISE_PROFILE: np.ascontiguousarray(rd[:, layout.doppler_bins // 2 - 1]).tobytes(),
        Tlv.AZIMUT_STATIC_HEAT_MAP: np.asarray(heatmap, HEATMAP_DTYPE).tobytes(),
        Tlv.RANGE_DOPPLER_HEAT_MAP: rd.tobytes(),
        Tlv.STATS: (np.zeros(1, STATS_DTYPE) if stats is None else np.asarray(stats, STATS_DTYPE)).tobytes(),
        Tlv.TEMPERATURE_STATS: (np.zeros(1, TEMPERATURE_DTYPE) if temperature is None
                                else np.asarray(temperature, TEMPERATURE_DTYPE)).tobytes(),
    }
    body = []
    for tlv, length in layout.tlv_lengths(n):
        data = payload[tlv]
        if len(data) != length:
            raise ValueError(f"TLV {tlv.name}: {len(data)} bytes given, the layout needs {length}")
        body += [np.array([(int(tlv), length)], TL_DTYPE).tobytes(), data]
    tlvs = layout.tlv_lengths(n)
    total = layout.packet_bytes(n)
    header = np.zeros(1, HEADER_DTYPE)
    header[0] = ((0x0102, 0x0304, 0x0506, 0x0708), version, total, platform, frame_number,
                 time_cpu_cycles & 0xFFFFFFFF, n, len(tlvs), 0)
    data = header.tobytes() + b"".join(body)
    return data + bytes(total - len(data))
