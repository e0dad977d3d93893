"""TI's demo UART output (driver/tidemo): the packet format, the framer on damaged streams
(property-tested), a packet's points and static antenna values, and their heatmap by the raw
path's angle processing (dsp/static_heatmap.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from radarodom.cfg import RadarConfig
from radarodom.driver.tidemo import wire
from radarodom.driver.tidemo.framer import (BAD_TLVS, CUT_AT_END, CUT_SHORT, FOLLOWED_BY_STRAY_BYTES,
                                            TlvFramer)
from radarodom.driver.tidemo.layout import DemoGeometry
from radarodom.driver.tidemo.products import FrameIndexer, points, static_antennas
from radarodom.dsp.config import DspConfig
from radarodom.dsp.heatmap import HeatmapMaker
from radarodom.dsp.processor import FrameProcessor
from radarodom.dsp.static_heatmap import StaticHeatmapMaker
from radarodom.errors import CaptureFormatError, ConfigError

from tidemo_helpers import TIDEMO_CFG

LAYOUT = wire.PacketLayout(range_bins=16, doppler_bins=8, azimuth_antennas=8)


def packet(number: int, n_points: int = 3, layout: wire.PacketLayout = LAYOUT, seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed + number)
    pts = np.zeros(n_points, wire.POINT_DTYPE)
    for name in ("x", "y", "z", "velocity"):
        pts[name] = rng.normal(size=n_points)
    side = np.zeros(n_points, wire.SIDE_INFO_DTYPE)
    side["snr"], side["noise"] = rng.integers(0, 400, n_points), rng.integers(-100, 100, n_points)
    heat = np.zeros((layout.range_bins, layout.azimuth_antennas), wire.HEATMAP_DTYPE)
    heat["real"] = rng.integers(-3000, 3000, heat.shape)
    heat["imag"] = rng.integers(-3000, 3000, heat.shape)
    return wire.encode_packet(layout, number, pts, side, heat)


# ------------------------------------------------------------------ the format
def test_the_named_dtypes_have_the_sizes_of_ti_structs():
    assert wire.HEADER_DTYPE.itemsize == 40  # MmwDemo_output_message_header
    assert wire.TL_DTYPE.itemsize == 8
    assert wire.POINT_DTYPE.itemsize == 16  # DPIF_PointCloudCartesian
    assert wire.SIDE_INFO_DTYPE.itemsize == 4  # DPIF_PointCloudSideInfo
    assert wire.HEATMAP_DTYPE.itemsize == 4  # cmplx16ImRe_t
    assert wire.STATS_DTYPE.itemsize == 24
    assert wire.TEMPERATURE_DTYPE.itemsize == 28  # int32 + rlRfTempData_t


def test_a_packet_round_trips_with_the_demos_tlv_order_and_padding():
    gui = wire.GuiSelection(1, True, True, True, True, True)
    layout = wire.PacketLayout(16, 8, 8, gui)
    data = packet(7, 5, layout)
    assert data[:8] == bytes.fromhex("0201040306050807") and len(data) % 32 == 0
    p = wire.parse_packet(data)
    assert not isinstance(p, str), p
    assert p.frame_number == 7 and p.num_points == 5 and int(p.header["platform"]) == 0xA1843
    assert wire.sdk_version(int(p.header["version"])) == "03.05.00.04"
    assert list(p.payloads) == [wire.Tlv.DETECTED_POINTS, wire.Tlv.DETECTED_POINTS_SIDE_INFO, wire.Tlv.RANGE_PROFILE,
                                wire.Tlv.NOISE_PROFILE, wire.Tlv.AZIMUT_STATIC_HEAT_MAP,
                                wire.Tlv.RANGE_DOPPLER_HEAT_MAP, wire.Tlv.STATS, wire.Tlv.TEMPERATURE_STATS]
    assert len(data) == layout.packet_bytes(5)
    assert p.array(wire.Tlv.AZIMUT_STATIC_HEAT_MAP, wire.HEATMAP_DTYPE).shape == (16 * 8,)


def test_points_tlv_without_points_follows_the_firmwares_condition():
    """detectedObjects 1 sends the points TLV with length 0 and no side info; 2 sends neither."""
    one = wire.parse_packet(packet(1, 0))
    assert one.payloads[wire.Tlv.DETECTED_POINTS].nbytes == 0
    assert wire.Tlv.DETECTED_POINTS_SIDE_INFO not in one.payloads
    two = wire.parse_packet(packet(1, 0, wire.PacketLayout(16, 8, 8, wire.GuiSelection(detected_objects=2))))
    assert wire.Tlv.DETECTED_POINTS not in two.payloads and list(two.payloads) == [wire.Tlv.AZIMUT_STATIC_HEAT_MAP]


@pytest.mark.parametrize("damage, reason", [
    (lambda d: d[:40] + bytes([10]) + d[41:], "unknown TLV type 10"),
    (lambda d: d[:44] + (1000).to_bytes(4, "little") + d[48:], "runs past the packet"),
    (lambda d: d[:8] + (0x02050004).to_bytes(4, "little") + d[12:], "SDK version 02.05"),
    (lambda d: d[:12] + (len(d) + 5).to_bytes(4, "little") + d[16:], "no multiple of 32"),
    (lambda d: d[:-32], "bytes where totalPacketLen says"),
    # Another radar's demo (the xWR16xx's), and a sub-frame a frame-based cfg never has.
    (lambda d: d[:16] + (0xA1642).to_bytes(4, "little") + d[20:], "platform 0xA1642, not the xWR18xx's 0xA1843"),
    (lambda d: d[:36] + (7).to_bytes(4, "little") + d[40:], "subFrameNumber 7, where a frame-based demo sends 0"),
])
def test_a_damaged_packet_is_refused_with_the_reason(damage, reason):
    assert reason in wire.parse_packet(damage(packet(3)))


# ------------------------------------------------------------------ the framer
def frame_all(stream: bytes, chunks: list[int], idle_at: set[int] = frozenset()) -> tuple[list, TlvFramer]:
    """Feed *stream* in pieces ending at *chunks* offsets (idle after those in *idle_at*)."""
    framer, out, at = TlvFramer(), [], 0
    for end in sorted(set(chunks) | {len(stream)}):
        out += framer.feed(stream[at:end])
        if end in idle_at:
            out += framer.idle()
        at = end
    return out + framer.finish(), framer


noise = st.binary(min_size=0, max_size=40).map(lambda b: b.replace(b"\x02", b"\x03"))


@settings(max_examples=60)
@given(n=st.integers(1, 6), gaps=st.lists(noise, min_size=7, max_size=7), cuts=st.lists(st.integers(0, 4000)),
       points=st.lists(st.integers(0, 5), min_size=6, max_size=6))
def test_packets_with_line_noise_between_come_through_whole(n, gaps, cuts, points):
    """Noise between packets (before each, the line quiet after each) costs no packet, whatever
    the read sizes; every byte is accounted for."""
    packets = [packet(i + 1, points[i]) for i in range(n)]
    stream, quiet = b"", set()
    for i, p in enumerate(packets):
        stream += gaps[i] + p
        quiet.add(len(stream))
    out, framer = frame_all(stream, cuts + sorted(quiet), quiet)
    assert [p.data for p in out] == packets
    assert framer.stats.packet_bytes + framer.stats.discarded_bytes == len(stream)
    assert framer.stats.discarded_bytes == sum(len(g) for g in gaps[:n])


@settings(max_examples=80)
@given(n=st.integers(2, 7), seed=st.integers(0, 2**31), cuts=st.lists(st.integers(0, 5000)),
       fault=st.lists(st.sampled_from(["whole", "truncate", "drop", "noise"]), min_size=7, max_size=7))
def test_a_damaged_stream_never_delivers_half_a_packet(n, seed, cuts, fault):
    """Packets cut short or with bytes lost are rejected and counted; the packets after them are
    delivered; nothing delivered differs from a packet sent whole; noise glued to a packet's end
    costs that packet (nothing tells it from lost bytes made up)."""
    rng = np.random.default_rng(seed)
    stream, whole = b"", []
    for i in range(n):
        p = packet(i + 1, int(rng.integers(0, 4)))
        kind = fault[i]
        if kind == "truncate":
            p = p[:int(rng.integers(8, len(p)))]
        elif kind == "drop":
            run = int(rng.integers(1, 40))
            at = int(rng.integers(8, len(p) - run))
            p = p[:at] + p[at + run:]
        elif kind == "noise":
            p = p + bytes([0x55] * int(rng.integers(1, 20)))
        else:
            whole.append(p)
        stream += p
    out, framer = frame_all(stream, cuts)
    assert all(p.data in whole for p in out)
    # A packet is lost only by its own damage or, at most, with the one damaged before it.
    assert len(out) >= len(whole) - sum(1 for k in fault[:n] if k != "whole")
    assert framer.stats.packet_bytes + framer.stats.discarded_bytes == len(stream)
    assert framer.stats.packets == len(out)
    damaged = sum(1 for k in fault[:n] if k != "whole")
    assert framer.stats.rejected_packets >= damaged - (fault[n - 1] != "whole")


def test_each_damage_is_counted_by_its_reason():
    a, b, c, d = (packet(i) for i in (1, 2, 3, 4))
    stream = a + b[:-100] + c + d[:-2] + a[:50]
    out, framer = frame_all(stream, [], {len(a)})
    assert [p.frame_number for p in out] == [1, 3]
    assert framer.stats.rejected == {CUT_SHORT: 1, FOLLOWED_BY_STRAY_BYTES: 1, CUT_AT_END: 1}
    bad = bytearray(a)
    side_info = 40 + 8 + 3 * 16
    bad[side_info:side_info + 4] = (1).to_bytes(4, "little")  # the side info claims to be points again
    out, framer = frame_all(bytes(bad) + b, [])
    assert [p.frame_number for p in out] == [2] and framer.stats.rejected[BAD_TLVS] == 1


def test_a_packet_is_held_until_what_follows_it_is_known():
    a, b = packet(1), packet(2)
    framer = TlvFramer()
    assert framer.feed(a) == []  # the next bytes could make it a packet that lost some
    assert [p.frame_number for p in framer.feed(b[:5])] == []
    assert [p.frame_number for p in framer.feed(b[5:])] == [1]  # the next magic word follows it
    assert [p.frame_number for p in framer.idle()] == [2]  # the line went quiet after it


def test_frame_indices_follow_the_frame_numbers():
    index = FrameIndexer()
    assert [index(n) for n in (5, 6, 8, 9, 1, 2)] == [0, 1, 3, 4, 5, 6]
    assert index.skipped == 1


# ------------------------------------------------------------------ products
def test_points_come_in_the_ti_sensor_frame_with_their_side_info():
    cfg = RadarConfig.from_text(TIDEMO_CFG, "t.cfg")
    g = DemoGeometry.from_config(cfg)
    pts = np.zeros(2, wire.POINT_DTYPE)
    pts[0] = (1.0, 2.0, 0.5, -0.3)
    pts[1] = (-2.0, 3.0, 0.0, 0.4)
    side = np.array([(153, -12), (88, 40)], wire.SIDE_INFO_DTYPE)
    heat = np.zeros((g.range_bins, len(g.heatmap_elements)), wire.HEATMAP_DTYPE)
    p = wire.parse_packet(wire.encode_packet(g.layout(wire.GuiSelection()), 1, pts, side, heat))
    out = points(p, g)
    assert out["range"][0] == pytest.approx(math.sqrt(1 + 4 + 0.25))
    assert out["azimuth"][0] == pytest.approx(math.atan2(1.0, 2.0))  # positive to the right
    assert out["azimuth"][1] < 0 and out["elevation"][0] == pytest.approx(math.asin(0.5 / math.sqrt(5.25)))
    assert list(out["snr_db"]) == pytest.approx([15.3, 8.8]) and list(out["noise_db"]) == pytest.approx([-1.2, 4.0])
    assert out["range_bin"][0] == round(math.sqrt(5.25) / g.range_step_m)
    assert out["doppler_bin"][1] == round(0.4 / g.doppler_step_mps)


def test_static_antennas_are_read_imaginary_part_first():
    cfg = RadarConfig.from_text(TIDEMO_CFG, "t.cfg")
    g = DemoGeometry.from_config(cfg)
    heat = np.zeros((g.range_bins, 8), wire.HEATMAP_DTYPE)
    heat["imag"][3, 5], heat["real"][3, 5] = 7, -2
    p = wire.parse_packet(wire.encode_packet(g.layout(wire.GuiSelection()), 1, np.zeros(0, wire.POINT_DTYPE),
                                             np.zeros(0, wire.SIDE_INFO_DTYPE), heat))
    values = static_antennas(p, g)
    assert values.shape == (g.range_bins, 8) and values[3, 5] == -2 + 7j and np.count_nonzero(values) == 1
    other = DemoGeometry(32, g.range_step_m, 8, 1.0, 0.0, g.heatmap_elements)
    with pytest.raises(CaptureFormatError, match="another cfg"):
        static_antennas(p, other)


def test_the_static_map_needs_the_azimuth_tx_first():
    text = TIDEMO_CFG.replace("chirpCfg 1 1 0 0 0 0 0 4", "chirpCfg 1 1 0 0 0 0 0 2").replace(
        "chirpCfg 2 2 0 0 0 0 0 2", "chirpCfg 2 2 0 0 0 0 0 4")
    with pytest.raises(ConfigError, match="TX1 and TX3 chirp before TX2"):
        DemoGeometry.from_config(RadarConfig.from_text(text, "xwr_order.cfg"))


# ------------------------------------------------------------------ the heatmap
def plane_wave(cfg: RadarConfig, azimuth_rad: float, range_bin: int, n_bins: int, n_el: int = 8) -> np.ndarray:
    """Zero-Doppler values of a reflector at *azimuth_rad* (a plane wave on the azimuth row)."""
    h = cfg.virtual_array.h.ravel()[:n_el]
    values = np.zeros((n_bins, n_el), np.complex64)
    values[range_bin] = 1000 * np.exp(1j * np.pi * h * math.sin(azimuth_rad))
    return values


def test_the_static_map_uses_the_raw_paths_axes_and_azimuth_convention():
    """A reflector to the right (positive azimuth, element phase pi h sin(theta) as the simulator
    and docs/conventions.md have it) peaks at the same azimuth bin as the raw path's heatmaps."""
    cfg = RadarConfig.from_text(TIDEMO_CFG, "t.cfg")
    proc = FrameProcessor(cfg, DspConfig())
    maker = StaticHeatmapMaker(proc)
    raw = HeatmapMaker(proc)
    assert np.array_equal(maker.azimuth_rad, raw.azimuth_rad)
    hm = maker.range_azimuth(plane_wave(cfg, math.radians(20), 10, proc.n_range))
    np.testing.assert_allclose(hm.range_m, raw.range_m)
    r, a = np.unravel_index(np.argmax(hm.intensity), hm.intensity.shape)
    assert r == 10 and abs(math.degrees(hm.azimuth_rad[a]) - 20) < 3
    assert np.all(np.isnan(hm.doppler_mps)) and hm.static is hm.intensity


def test_the_chips_calibration_is_kept_or_undone_as_the_raw_path_would_have_it():
    """The chip multiplied the values by the cfg's line: the DSP with the cfg's line leaves them,
    without a calibration (channel_calibration false) it divides the line out again."""
    cal = " ".join(f"{np.cos(p):.5f} {np.sin(p):.5f}" for p in np.linspace(0, 2.5, 12))
    text = TIDEMO_CFG.replace("compRangeBiasAndRxChanPhase 0.0 " + " ".join(["1 0"] * 12),
                              f"compRangeBiasAndRxChanPhase 0.05 {cal}")
    cfg = RadarConfig.from_text(text, "cal.cfg")
    proc = FrameProcessor(cfg, DspConfig())
    chip = cfg.channel_calibration.for_array(cfg.virtual_array).ravel()[:8]
    truth = plane_wave(cfg, math.radians(-15), 12, proc.n_range)
    sent = truth * chip  # what the chip sends: calibrated
    calibrated = StaticHeatmapMaker(proc).range_azimuth(sent)
    assert StaticHeatmapMaker(proc).parts(sent.shape).weights is None
    assert calibrated.range_m[0] == pytest.approx(-0.05)  # the range bias comes off, as on the raw path
    plain = StaticHeatmapMaker(FrameProcessor(cfg, DspConfig(channel_calibration=False)))
    undone = plain.range_azimuth(sent)
    parts = plain.parts(sent.shape)
    expected = np.abs(truth[:parts.rows] @ parts.dft_t) ** 2  # the raw values, nothing multiplied
    np.testing.assert_allclose(undone.intensity, expected, rtol=1e-3, atol=1.0)
    assert undone.range_m[0] == 0.0
