"""RawLayout: raw DCA1000 bytes <-> complex cubes, checked against bytes built
by hand and against real DCA1000 traffic (shared/reference/pcaps)."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from radarodom.driver.live.dca1000_wire import DataPacket
from radarodom.driver.recordings.pcap import read_udp
from radarodom.errors import CaptureError, CaptureFormatError, UsageError
from radarodom.rawframe import RawLayout

# A tiny cube: 2 loops, 2 TX slots, 2 RX, 4 samples, every I and Q distinct.
LOOPS, SLOTS, RX, SAMPLES = 2, 2, 2, 4


def _i(l, t, r, n):
    return 1000 * l + 100 * t + 10 * r + n + 1


def _q(l, t, r, n):
    return -(1000 * l + 100 * t + 10 * r + n + 1) - 5000


def _expected_cube() -> np.ndarray:
    cube = np.empty((LOOPS, SLOTS, RX, SAMPLES), np.complex64)
    for l in range(LOOPS):
        for t in range(SLOTS):
            for r in range(RX):
                for n in range(SAMPLES):
                    cube[l, t, r, n] = complex(_i(l, t, r, n), _q(l, t, r, n))
    return cube


def _hand_bytes(order: str) -> bytes:
    """The frame's bytes, written out sample by sample in stream order:
    loops, then slots, then RX, then the samples of that RX in groups."""
    out = bytearray()
    for l in range(LOOPS):
        for t in range(SLOTS):
            for r in range(RX):
                for g in range(0, SAMPLES, 2):
                    i0, i1 = _i(l, t, r, g), _i(l, t, r, g + 1)
                    q0, q1 = _q(l, t, r, g), _q(l, t, r, g + 1)
                    values = {
                        "lvds_q_first": (q0, q1, i0, i1),   # SampleSwap 1
                        "lvds_i_first": (i0, i1, q0, q1),   # SampleSwap 0
                        "ti_q_first": (q0, i0, q1, i1),     # TI reordered, SampleSwap 1
                        "ti_i_first": (i0, q0, i1, q1),     # TI reordered, SampleSwap 0
                    }[order]
                    out += struct.pack("<4h", *values)
    return bytes(out)


LAYOUTS = {
    "lvds_q_first": dict(q_first=True, iq_interleaved=False),
    "lvds_i_first": dict(q_first=False, iq_interleaved=False),
    "ti_q_first": dict(q_first=True, iq_interleaved=True),
    "ti_i_first": dict(q_first=False, iq_interleaved=True),
}


def _layout(name: str) -> RawLayout:
    return RawLayout(LOOPS, SLOTS, RX, SAMPLES, **LAYOUTS[name])


@pytest.mark.parametrize("name", sorted(LAYOUTS))
def test_decode_hand_built_bytes(name):
    layout = _layout(name)
    raw = _hand_bytes(name)
    assert layout.frame_bytes == len(raw) == LOOPS * SLOTS * RX * SAMPLES * 4
    cube = layout.decode(raw)
    assert cube.dtype == np.complex64
    assert cube.shape == (LOOPS, SLOTS, RX, SAMPLES) == layout.shape
    np.testing.assert_array_equal(cube, _expected_cube())


@pytest.mark.parametrize("name", sorted(LAYOUTS))
def test_encode_gives_hand_built_bytes(name):
    assert _layout(name).encode(_expected_cube()) == _hand_bytes(name)


def test_q_first_group_is_q0_q1_i0_i1():
    layout = RawLayout(1, 1, 1, 2, q_first=True)
    cube = layout.decode(struct.pack("<4h", 1, 2, 3, 4))
    np.testing.assert_array_equal(cube.ravel(), [3 + 1j, 4 + 2j])
    layout = RawLayout(1, 1, 1, 2, q_first=False)
    cube = layout.decode(struct.pack("<4h", 1, 2, 3, 4))
    np.testing.assert_array_equal(cube.ravel(), [1 + 3j, 2 + 4j])
    layout = RawLayout(1, 1, 1, 2, q_first=True, iq_interleaved=True)
    cube = layout.decode(struct.pack("<4h", 1, 2, 3, 4))
    np.testing.assert_array_equal(cube.ravel(), [2 + 1j, 4 + 3j])


def test_samples_are_signed_int16():
    # 0xFFFF must read as -1, not 65535 (the OpenRadar unsigned bug).
    raw = struct.pack("<4H", 0xFFFF, 0x8000, 0x7FFF, 0x0001)
    cube = RawLayout(1, 1, 1, 2, q_first=True).decode(raw)
    np.testing.assert_array_equal(cube.ravel(), [32767 - 1j, 1 - 32768j])
    cube = RawLayout(1, 1, 1, 2, q_first=False).decode(raw)
    np.testing.assert_array_equal(cube.ravel(), [-1 + 32767j, -32768 + 1j])
    assert cube.real.min() < 0


def test_multi_frame_decode_adds_leading_axis():
    layout = _layout("lvds_q_first")
    raw = _hand_bytes("lvds_q_first")
    other = layout.encode(_expected_cube() * 2)
    cubes = layout.decode(raw + other + raw)
    assert cubes.shape == (3, LOOPS, SLOTS, RX, SAMPLES)
    np.testing.assert_array_equal(cubes[0], _expected_cube())
    np.testing.assert_array_equal(cubes[1], _expected_cube() * 2)
    np.testing.assert_array_equal(cubes[2], _expected_cube())
    # the multi-frame cube encodes back to the same bytes
    assert layout.encode(cubes) == raw + other + raw


def test_decode_accepts_any_buffer():
    layout = _layout("lvds_i_first")
    raw = _hand_bytes("lvds_i_first")
    for buf in (bytearray(raw), memoryview(raw), np.frombuffer(raw, np.uint8),
                np.frombuffer(raw, "<i2")):
        np.testing.assert_array_equal(layout.decode(buf), _expected_cube())


def test_decode_fills_out_in_place():
    layout = _layout("lvds_q_first")
    raw = _hand_bytes("lvds_q_first")
    out = np.full(layout.shape, 99 + 99j, np.complex64)
    got = layout.decode(raw, out)
    assert got is out
    np.testing.assert_array_equal(out, _expected_cube())

    out5 = np.zeros((2, *layout.shape), np.complex64)
    got5 = layout.decode(raw + raw, out=out5)
    assert got5 is out5
    np.testing.assert_array_equal(out5[1], _expected_cube())

    # one frame into a frames-axis buffer of length 1
    out1 = np.zeros((1, *layout.shape), np.complex64)
    assert layout.decode(raw, out1) is out1
    np.testing.assert_array_equal(out1[0], _expected_cube())


def test_decode_rejects_bad_out():
    """The package's error naming the argument, what it got and what it takes (once a bare
    ValueError, and an AttributeError for a list)."""
    layout = _layout("lvds_q_first")
    raw = _hand_bytes("lvds_q_first")
    one = f"{layout.shape} or {(1, *layout.shape)} (one frame), or None for a new one; got "
    read_only = np.zeros(layout.shape, np.complex64)
    read_only.flags.writeable = False
    for out, got in ((np.zeros(layout.shape, np.complex128), f"complex128 shaped {layout.shape}"),
                     ([0j] * 4, "list [0j, 0j, 0j, 0j]"), (read_only, "a read-only array")):
        with pytest.raises(UsageError) as info:
            layout.decode(raw, out)
        assert str(info.value) == f"out: a writable complex64 array shaped {one}{got}"
    with pytest.raises(UsageError) as info:
        layout.decode(raw + raw, np.zeros(layout.shape, np.complex64))
    assert str(info.value) == (f"out: a writable complex64 array shaped {(2, *layout.shape)} (2 frames), or None for "
                               f"a new one; got complex64 shaped {layout.shape}")


@pytest.mark.parametrize("nbytes", [0, 4, 127, 129, 256 + 8])
def test_decode_rejects_partial_frames(nbytes):
    layout = _layout("lvds_q_first")
    assert layout.frame_bytes == 128
    with pytest.raises(CaptureFormatError) as info:
        layout.decode(bytes(nbytes))
    assert isinstance(info.value, CaptureError)
    assert str(nbytes) in str(info.value)


@pytest.mark.parametrize("name", sorted(LAYOUTS))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_encode_decode_roundtrip_random_bytes(name, seed):
    layout = _layout(name)
    raw = np.random.default_rng(seed).integers(0, 256, 3 * layout.frame_bytes, dtype=np.uint8).tobytes()
    assert layout.encode(layout.decode(raw)) == raw


@settings(max_examples=60, deadline=None)
@given(loops=st.integers(1, 3), slots=st.integers(1, 3), rx=st.integers(1, 4),
       half_samples=st.integers(1, 8), frames=st.integers(1, 3), q_first=st.booleans(),
       interleaved=st.booleans(), data=st.data())
def test_roundtrip_property(loops, slots, rx, half_samples, frames, q_first, interleaved, data):
    layout = RawLayout(loops, slots, rx, 2 * half_samples, q_first, interleaved)
    raw = data.draw(st.binary(min_size=frames * layout.frame_bytes, max_size=frames * layout.frame_bytes))
    cube = layout.decode(raw)
    assert cube.shape == ((frames,) if frames > 1 else ()) + layout.shape
    assert layout.encode(cube) == raw


def test_encode_rounds_to_nearest():
    layout = RawLayout(1, 1, 1, 2)
    raw = layout.encode(np.array([1.4 - 1.6j, -2.6 + 0.4j]).reshape(layout.shape))
    np.testing.assert_array_equal(layout.decode(raw).ravel(), [1 - 2j, -3 + 0j])


@pytest.mark.parametrize("value", [32768, -32769, 40000j, -1e6j, 32767.6, np.inf])
def test_encode_rejects_values_beyond_int16(value):
    layout = RawLayout(1, 1, 1, 4)
    cube = np.zeros(layout.shape, complex)
    cube[0, 0, 0, 2] = value
    with pytest.raises(CaptureFormatError):
        layout.encode(cube)


def test_encode_accepts_int16_extremes():
    layout = RawLayout(1, 1, 1, 2)
    cube = np.array([32767 - 32768j, -32768 + 32767j]).reshape(layout.shape)
    np.testing.assert_array_equal(layout.decode(layout.encode(cube)), cube)


def test_encode_rejects_nan():
    layout = RawLayout(1, 1, 1, 4)
    cube = np.zeros(layout.shape, complex)
    cube[0, 0, 0, 1] = complex(np.nan, 3)
    with pytest.raises(CaptureFormatError):
        layout.encode(cube)


def test_encode_rejects_bad_cube():
    """The package's error naming the argument, what it got and what it takes (once a bare
    ValueError for a wrong shape, numpy's TypeError for an object or str array, and nothing at all
    for a bool array or a (1, 2, ...) cube, taken as two frames)."""
    layout = RawLayout(1, 2, 2, 4)
    wanted = ("cube: a numeric (integer, float or complex) array shaped (1, 2, 2, 4) (one frame) or "
              "(frames, 1, 2, 2, 4) (frames >= 1); got ")
    for cube, got in ((np.zeros((1, 2, 4, 2), complex), "complex128 shaped (1, 2, 4, 2)"),
                      (np.zeros((2, 4)), "float64 shaped (2, 4)"),
                      (np.zeros((0, *layout.shape), np.complex64), "complex64 shaped (0, 1, 2, 2, 4)"),
                      (np.zeros((1, 2, *layout.shape), np.complex64), "complex64 shaped (1, 2, 1, 2, 2, 4)"),
                      (np.zeros(layout.shape, bool), "bool shaped (1, 2, 2, 4)"),
                      (np.zeros(layout.shape, object), "object shaped (1, 2, 2, 4)"),
                      (np.zeros(layout.shape, "U1"), "<U1 shaped (1, 2, 2, 4)"),
                      ([[0j] * 4] * 2, "list [[0j, 0j, 0j, 0j], [0j, 0j, 0j, 0j]]"),
                      (None, "NoneType None")):
        with pytest.raises(UsageError) as info:
            layout.encode(cube)
        assert str(info.value) == wanted + got
    # every numeric kind is taken, one frame or several
    for dtype in (np.int16, np.int64, np.uint8, np.float32, np.complex128):
        assert layout.encode(np.ones(layout.shape, dtype)) == layout.encode(np.ones(layout.shape, np.complex64))
    assert len(layout.encode(np.zeros((3, *layout.shape), np.complex64))) == 3 * layout.frame_bytes


def test_from_config_shipped(shipped_cfg):
    layout = RawLayout.from_config(shipped_cfg)
    assert layout.shape == (64, 3, 4, 256)
    assert layout.frame_bytes == shipped_cfg.frame_bytes == 64 * 3 * 4 * 256 * 4
    assert layout.q_first  # adcbufCfg SampleSwap 1
    assert not layout.iq_interleaved
    assert RawLayout.from_config(shipped_cfg, iq_interleaved=True).iq_interleaved


def test_from_config_sample_swap_0(small_cfg):
    from radarodom.cfg import RadarConfig
    from conftest import SMALL_CFG

    assert RawLayout.from_config(small_cfg).q_first
    cfg = RadarConfig.from_text(SMALL_CFG.replace("adcbufCfg -1 0 1 1 1", "adcbufCfg -1 0 0 1 1"))
    layout = RawLayout.from_config(cfg)
    assert not layout.q_first
    assert layout.shape == (4, 3, 4, 16)
    assert layout.frame_bytes == cfg.frame_bytes == 3072


# --------------------------------------------------------------- real DCA1000 traffic

ONE_FRAME = "pcaps/mmwave-capture-std__test_one_frame.pcap"
COMMANDS = "pcaps/mmwave-capture-std__test_cmd.pcap"


def _data_packets(path):
    grams = [d for d in read_udp(path) if d.dst[1] == 4098]
    return grams, [DataPacket.parse(d.payload) for d in grams]


def test_pcap_data_packets(shared_reference):
    grams, packets = _data_packets(shared_reference / ONE_FRAME)
    assert len(packets) == 12
    assert [p.seq for p in packets] == list(range(1, 13))
    assert [len(p.data) for p in packets] == [1456] * 11 + [368]
    before = 0
    for p in packets:
        assert p.byte_count == before
        before += len(p.data)
    assert before == 16384
    for d in grams:
        assert d.src == ("192.168.33.180", 1024)
        assert d.dst[0] == "192.168.33.30"
        assert DataPacket.parse(d.payload).pack() == d.payload


def test_pcap_config_replies_and_async_status(shared_reference):
    grams = list(read_udp(shared_reference / ONE_FRAME))
    config = [d for d in grams if d.dst[1] == 4096]
    assert len(config) == 6
    assert all(len(d.payload) == 8 and d.src == ("192.168.33.180", 1024) for d in config)
    replies = [struct.unpack("<4H", d.payload) for d in config]
    assert [r[1] for r in replies] == [0x09, 0x01, 0x03, 0x0B, 0x05, 0x0A]
    assert all(r[0] == 0xA55A and r[3] == 0xEEAA for r in replies)
    assert [r[2] for r in replies[:5]] == [0] * 5
    assert replies[5][2] == 0x0100  # record completed
    # The board flushes the short last packet with the "record completed" status,
    # about 2 s after the last full data packet.
    data_times = [d.time for d in grams if d.dst[1] == 4098]
    assert config[-1].time - data_times[-2] == pytest.approx(2.0, abs=0.1)
    assert config[-1].time - data_times[-1] == pytest.approx(0.0, abs=0.01)


def _frame_bytes(shared_reference) -> bytes:
    _, packets = _data_packets(shared_reference / ONE_FRAME)
    return b"".join(p.data for p in packets)


def test_pcap_frame_decodes_q_first(shared_reference):
    raw = _frame_bytes(shared_reference)
    cube = RawLayout(1, 1, 1, 4096, q_first=True).decode(raw)
    s = cube.ravel()
    assert s[4065] == 223 + 120j
    assert s[0] == -255 + 168j
    assert s[1] == -497 - 356j
    i_first = RawLayout(1, 1, 1, 4096, q_first=False).decode(raw).ravel()
    assert i_first[4065] == 120 + 223j
    np.testing.assert_array_equal(i_first, s.imag + 1j * s.real)


def _positive_over_negative_db(samples: np.ndarray) -> float:
    chirps = samples.reshape(-1, 256)
    power = np.abs(np.fft.fft(chirps, axis=1)) ** 2
    return 10 * np.log10(power[:, 1:128].sum() / power[:, 129:256].sum())


def test_pcap_frame_energy_in_positive_range_bins(shared_reference):
    raw = _frame_bytes(shared_reference)
    q_first = RawLayout(1, 1, 1, 4096, q_first=True).decode(raw).ravel()
    i_first = RawLayout(1, 1, 1, 4096, q_first=False).decode(raw).ravel()
    assert _positive_over_negative_db(q_first) > 15
    assert _positive_over_negative_db(i_first) < -15


def test_pcap_command_replies(shared_reference):
    grams = list(read_udp(shared_reference / COMMANDS))
    assert len(grams) == 10
    cmds = []
    for d in grams:
        p = d.payload
        assert len(p) == 8
        assert p[:2] == b"\x5a\xa5" and p[3] == 0 and p[6:] == b"\xaa\xee"
        assert d.src == ("192.168.33.180", 1024) and d.dst[1] == 4096
        cmds.append(p[2])
    assert cmds == [0x01, 0x02, 0x05, 0x06, 0x0B, 0x03, 0x04, 0x09, 0x0A, 0x0E]
    version = grams[cmds.index(0x0E)].payload
    assert version.hex() == "5aa50e000204aaee"
    status = struct.unpack_from("<H", version, 4)[0]
    assert status == 0x0402
    assert (status & 0x7F, (status >> 7) & 0x7F, bool(status & 0x4000)) == (2, 8, False)
    assert all(struct.unpack_from("<H", grams[k].payload, 4)[0] == 0 for k in range(9))


# --------------------------------------------------------------- pcap reader

def _eth_udp(payload: bytes, sport=1024, dport=4098, proto=17, frag=0, ethertype=0x0800) -> bytes:
    udp = struct.pack("!HHHH", sport, dport, 8 + len(payload), 0) + payload
    ip = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(udp), 0, frag, 64, proto, 0,
                     bytes([192, 168, 33, 180]), bytes([192, 168, 33, 30]))
    eth = b"\x00" * 6 + b"\x12\x34\x56\x78\x90\x12" + struct.pack("!H", ethertype)
    frame = eth + ip + udp
    return frame + b"\x00" * max(0, 60 - len(frame))  # Ethernet padding


def _pcap(records, order="<", nano=False, linktype=1) -> bytes:
    magic = 0xA1B23C4D if nano else 0xA1B2C3D4
    out = struct.pack(order + "IHHiIII", magic, 2, 4, 0, 0, 65535, linktype)
    for sec, sub, frame in records:
        out += struct.pack(order + "IIII", sec, sub, len(frame), len(frame)) + frame
    return out


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("nano", [False, True])
def test_read_udp_synthetic(tmp_path, order, nano):
    recs = [
        (100, 250, _eth_udp(b"hello")),
        (100, 500, _eth_udp(b"arp", ethertype=0x0806)),          # not IPv4: skipped
        (101, 0, _eth_udp(b"tcp", proto=6)),                      # not UDP: skipped
        (101, 1, _eth_udp(b"frag", frag=0x2000)),                 # first fragment: skipped
        (102, 7, _eth_udp(b"x" * 100, sport=1024, dport=4096)),
    ]
    path = tmp_path / "x.pcap"
    path.write_bytes(_pcap(recs, order, nano))
    grams = list(read_udp(path))
    assert [g.payload for g in grams] == [b"hello", b"x" * 100]
    tick = 1e-9 if nano else 1e-6
    assert grams[0].time == pytest.approx(100 + 250 * tick)
    assert grams[1].time == pytest.approx(102 + 7 * tick)
    assert grams[0].src == ("192.168.33.180", 1024) and grams[0].dst == ("192.168.33.30", 4098)
    assert grams[1].dst == ("192.168.33.30", 4096)


def test_read_udp_rejects_non_pcap(tmp_path):
    path = tmp_path / "notes.pcap"
    path.write_text("this is not a packet capture, just some text\n" * 3)
    with pytest.raises(CaptureFormatError):
        list(read_udp(path))


def test_read_udp_rejects_pcapng_short_and_other_links(tmp_path):
    ng = tmp_path / "a.pcapng"
    ng.write_bytes(struct.pack("<II", 0x0A0D0D0A, 28) + bytes(40))
    with pytest.raises(CaptureFormatError):
        list(read_udp(ng))
    short = tmp_path / "short.pcap"
    short.write_bytes(b"\xd4\xc3\xb2\xa1")
    with pytest.raises(CaptureFormatError):
        list(read_udp(short))
    raw_ip = tmp_path / "rawip.pcap"
    raw_ip.write_bytes(_pcap([(1, 0, _eth_udp(b"a"))], linktype=101))
    with pytest.raises(CaptureFormatError):
        list(read_udp(raw_ip))


def test_read_udp_rejects_truncated_record(tmp_path, shared_reference):
    data = (shared_reference / ONE_FRAME).read_bytes()
    cut = tmp_path / "cut.pcap"
    cut.write_bytes(data[:8000])  # inside a data packet's record
    with pytest.raises(CaptureFormatError):
        list(read_udp(cut))


def test_data_packet_parse_limits():
    with pytest.raises(ValueError):
        DataPacket.parse(bytes(10))  # header only
    with pytest.raises(ValueError):
        DataPacket.parse(bytes(10 + 1457))
    p = DataPacket.parse(struct.pack("<I", 7) + (123456789012).to_bytes(6, "little") + b"ab")
    assert (p.seq, p.byte_count, p.data) == (7, 123456789012, b"ab")
