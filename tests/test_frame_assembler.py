"""Frame assembly by byte count: alignment can never be lost, accounting is exact."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from radarodom.driver.live.dca1000_wire import MAX_DATA_BYTES
from radarodom.driver.live.frame_assembler import FrameAssembler
from radarodom.driver.live.frame_ring import FrameRing


def stream_bytes(n_frames: int, frame_bytes: int, seed: int = 0) -> bytes:
    return np.random.default_rng(seed).integers(1, 256, n_frames * frame_bytes, dtype=np.uint8).tobytes()


def packetize(stream: bytes, size: int = MAX_DATA_BYTES, frame_bytes: int | None = None):
    """(seq, byte_count, data) as the board sends them; with frame_bytes, each
    frame ends with a short packet (burst flush) instead of straddling."""
    packets, pos, seq = [], 0, 1
    while pos < len(stream):
        end = min(pos + size, len(stream))
        if frame_bytes:
            end = min(end, (pos // frame_bytes + 1) * frame_bytes)
        packets.append((seq, pos, stream[pos:end]))
        seq, pos = seq + 1, end
    return packets


class Collector:
    def __init__(self, ring: FrameRing):
        self.ring = ring
        self.frames = []

    def __call__(self, frame):
        self.frames.append((frame.index, bytes(frame.data), frame.missing_bytes))
        self.ring.release(frame.slot)


def assemble(packets, frame_bytes, reorder_bytes=2 * MAX_DATA_BYTES, slots=8):
    ring = FrameRing(frame_bytes, slots)
    out = Collector(ring)
    asm = FrameAssembler(frame_bytes, ring, reorder_bytes=reorder_bytes, on_frame=out)
    for seq, count, data in packets:
        asm.add(seq, count, memoryview(data), 0.0)
    asm.expire()
    return asm, out.frames


@pytest.mark.parametrize("burst", [False, True])
def test_clean_stream_gives_every_frame_whole_and_in_order(burst):
    fb = 3072  # not a multiple of 1456: packets straddle frames
    stream = stream_bytes(10, fb)
    asm, frames = assemble(packetize(stream, frame_bytes=fb if burst else None), fb)
    assert [f[0] for f in frames] == list(range(10))
    assert b"".join(f[1] for f in frames) == stream
    assert all(f[2] == 0 for f in frames)
    assert asm.stats.frames_complete == 10 and asm.stats.missing_bytes == 0


def test_complete_frames_are_handed_on_without_waiting():
    fb = 2912  # exactly two full packets
    ring = FrameRing(fb, 4)
    out = Collector(ring)
    asm = FrameAssembler(fb, ring, on_frame=out)
    stream = stream_bytes(2, fb)
    for seq, count, data in packetize(stream)[:2]:
        asm.add(seq, count, data, 0.0)
    assert [f[0] for f in out.frames] == [0]  # frame 0 out as soon as its last byte is in


@settings(max_examples=150, deadline=None)
@given(
    n_frames=st.integers(1, 8),
    frame_bytes=st.sampled_from([1000, 3072, 4096, 5000]),
    seed=st.integers(0, 2**32 - 1),
    loss=st.floats(0, 0.6),
    dup=st.floats(0, 0.3),
    reorder=st.floats(0, 0.3),
    truncate=st.floats(0, 0.2),
    burst=st.booleans(),
)
def test_any_loss_duplication_reordering_or_truncation_keeps_alignment(
        n_frames, frame_bytes, seed, loss, dup, reorder, truncate, burst):
    rng = np.random.default_rng(seed)
    stream = stream_bytes(n_frames, frame_bytes, seed)
    sent = packetize(stream, frame_bytes=frame_bytes if burst else None)
    # Reorder within a short window (what a switch or a busy host can do): a
    # delayed packet lands at most 2 stream packets later; then loss and the rest.
    keys = [i + (rng.uniform(0, 2.5) if rng.random() < reorder else 0.0) for i in range(len(sent))]
    sent = [p for _, p in sorted(zip(keys, sent), key=lambda kp: kp[0])]
    delivered = np.zeros(len(stream), bool)
    wire = []
    for seq, count, data in sent:
        if rng.random() < loss:
            continue
        if rng.random() < truncate and len(data) > 1:
            data = data[: int(rng.integers(1, len(data)))]
        delivered[count: count + len(data)] = True
        wire.append((seq, count, data))
        if rng.random() < dup:
            wire.append((seq, count, data))
    # Reordered by up to 2 packets, each up to a full packet: 3 packets of tolerance.
    asm, frames = assemble(wire, frame_bytes, reorder_bytes=3 * MAX_DATA_BYTES, slots=n_frames + 4)

    # Frames come out once each, in order, with no gap in the numbering up to the last
    # frame any byte arrived for.
    received_frames = sorted({c // frame_bytes for _, c, d in wire} | {(c + len(d) - 1) // frame_bytes for _, c, d in wire})
    expected_count = (max(received_frames) + 1) if received_frames else 0
    assert [f[0] for f in frames] == list(range(expected_count))
    for index, data, missing in frames:
        lo, hi = index * frame_bytes, (index + 1) * frame_bytes
        got = np.frombuffer(data, np.uint8)
        want = np.where(delivered[lo:hi], np.frombuffer(stream[lo:hi], np.uint8), 0)
        np.testing.assert_array_equal(got, want)  # right bytes in the right place, gaps zero
        assert missing == int((~delivered[lo:hi]).sum())
    assert asm.stats.missing_bytes == sum(f[2] for f in frames if f[2])


def test_late_packet_after_the_window_is_dropped_and_counted():
    fb = 3000
    stream = stream_bytes(6, fb)
    packets = packetize(stream)
    late = packets.pop(1)  # a packet of frame 0 ...
    packets.append(late)  # ... arrives after everything else
    asm, frames = assemble(packets, fb, reorder_bytes=2 * MAX_DATA_BYTES)
    assert frames[0][2] == len(late[2]) and asm.stats.late_packets == 1
    assert [f[0] for f in frames] == list(range(6))


def test_duplicates_add_nothing():
    fb = 3000
    stream = stream_bytes(3, fb)
    packets = packetize(stream)
    doubled = [p for p in packets[:3] for _ in range(2)] + packets[3:]  # each sent twice at once
    asm, frames = assemble(doubled, fb)
    assert b"".join(f[1] for f in frames) == stream
    assert asm.stats.duplicate_packets == 3 and asm.stats.missing_bytes == 0


def test_repeats_after_their_frame_went_out_count_as_late():
    fb = 3000
    stream = stream_bytes(3, fb)
    packets = packetize(stream)
    asm, frames = assemble(packets + packets[:2], fb)
    assert b"".join(f[1] for f in frames) == stream
    assert asm.stats.late_packets == 2 and asm.stats.duplicate_packets == 0


def test_whole_frames_lost_are_handed_on_as_missing():
    fb = 2912
    stream = stream_bytes(6, fb)
    packets = [p for p in packetize(stream) if not (fb * 2 <= p[1] < fb * 4)]  # frames 2 and 3 gone
    asm, frames = assemble(packets, fb)
    assert [f[0] for f in frames] == list(range(6))
    assert [f[2] for f in frames] == [0, 0, fb, fb, 0, 0]
    assert frames[2][1] == bytes(fb)


def test_corrupt_byte_count_cannot_push_frames_out():
    fb = 3000
    stream = stream_bytes(3, fb)
    packets = packetize(stream)
    packets.insert(2, (3, 10**12, b"x" * 100))  # offset far beyond what seq 3 allows
    asm, frames = assemble(packets, fb)
    assert asm.stats.implausible_packets == 1
    assert b"".join(f[1] for f in frames) == stream


@pytest.mark.parametrize("policy,expected", [("latest", [3, 4]), ("queue", [0, 1])])
def test_slow_consumer_drops_whole_frames_by_policy(policy, expected):
    fb = 2912
    ring = FrameRing(fb, 2, policy)
    asm = FrameAssembler(fb, ring, reorder_bytes=MAX_DATA_BYTES)
    stream = stream_bytes(5, fb)
    for seq, count, data in packetize(stream):
        asm.add(seq, count, data, 0.0)
    got = []
    while (frame := ring.get(timeout=0)) is not None:
        got.append(frame.index)
        assert bytes(frame.data) == stream[frame.index * fb:(frame.index + 1) * fb]  # never half-overwritten
        ring.release(frame.slot)
    assert got == expected
    assert ring.dropped_frames == 3


def test_receiver_stopping_takes_the_datagrams_already_queued():
    """Packets that reached the socket before stop() are part of the capture: the receiver
    assembles them before it ends (here they are all queued before its thread even runs)."""
    import socket

    from radarodom.driver.live.dca1000 import Dca1000Settings
    from radarodom.driver.live.dca1000_receiver import Dca1000Receiver
    from radarodom.driver.live.dca1000_wire import DATA_HEADER

    fb, n = 5000, 3
    stream = stream_bytes(n, fb, seed=4)
    ring = FrameRing(fb, n + 2, "queue")
    settings = Dca1000Settings(host_ip="127.0.0.1", board_ip="127.0.0.1", data_port=0)
    receiver = Dca1000Receiver(settings, fb, ring).open()
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as board:
            for seq, count, data in packetize(stream):
                board.sendto(DATA_HEADER.pack(seq, count.to_bytes(6, "little")) + data,
                             ("127.0.0.1", receiver.local_port))
        receiver.start()
        receiver.stop()
    finally:
        receiver.close()
    got = []
    while (frame := ring.get(timeout=0)) is not None:
        got.append((frame.index, bytes(frame.data), frame.missing_bytes))
    assert got == [(i, stream[i * fb:(i + 1) * fb], 0) for i in range(n)]
    assert receiver.assembler.stats.frames_incomplete == 0


def _stopped_stream(sent_all: bool):
    """Two 3072-byte frames, the second without the 320-byte packet that ends it (a tail
    never received)."""
    fb = 3072
    stream = stream_bytes(2, fb)
    packets = packetize(stream)[:-1]
    assert len(packetize(stream)[-1][2]) == 320
    ring = FrameRing(fb, 4)
    got = []

    def take(frame):
        got.append((frame.index, frame.missing_bytes, frame.cut_bytes))
        ring.release(frame.slot)

    asm = FrameAssembler(fb, ring, on_frame=take)
    for seq, count, data in packets:
        asm.add(seq, count, memoryview(data), 0.0)
    asm.expire(sent_all=sent_all)
    return asm.stats, got


def test_a_tail_that_never_came_is_cut_at_stop():
    stats, got = _stopped_stream(sent_all=False)
    assert got == [(0, 0, 0), (1, 320, 320)]
    assert (stats.missing_bytes, stats.cut_bytes, stats.lost_bytes) == (320, 320, 0)


def test_a_tail_the_sender_confirmed_sending_was_lost_on_the_way():
    """After RECORD_COMPLETED (and a radar that ended its frame) every byte was sent."""
    stats, got = _stopped_stream(sent_all=True)
    assert got == [(0, 0, 0), (1, 320, 0)]
    assert (stats.missing_bytes, stats.cut_bytes, stats.lost_bytes) == (320, 0, 320)


def test_a_gap_before_the_newest_byte_is_lost_not_cut():
    fb = 3072
    packets = packetize(stream_bytes(2, fb))
    del packets[1]  # bytes 1456..2911 of frame 0
    asm, frames = assemble(packets, fb)
    assert [f[2] for f in frames] == [1456, 0]
    assert (asm.stats.lost_bytes, asm.stats.cut_bytes) == (1456, 0)
