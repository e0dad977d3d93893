"""Where every frame and every missing byte of a live capture went, counted two ways.

A frame's missing bytes are what it did not receive (the frame assembler's count); the bytes
lost on the way are read off the packet headers alone, from sequence and byte-count gaps
(``stream_gaps.ByteGaps``); the bytes cut at stop are those after the newest packet when the
board did not confirm the end.  missing = lost + cut is therefore a check, not a definition:
here against a model of the stream, and on the emulators under real CPU contention (busy
processes on every core) with packet loss, a slow consumer and a stop that cuts a frame, the
board's own 2 s RECORD_COMPLETED delay, and the fake board's ground truth of what it sent.
Nothing here asserts a speed.
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest
from conftest import warning_messages
from hypothesis import given, settings
from hypothesis import strategies as st
from live_helpers import URL_TIMEOUTS, CpuHogs, assert_frames_match, collect_until_stopped
from test_frame_assembler import packetize, stream_bytes

from radarodom.driver.emulators.fake_dca1000 import RECORD_COMPLETED_DELAY_S, Faults
from radarodom.driver.emulators.rig import EmulatedRig
from radarodom.driver.live.dca1000_wire import MAX_DATA_BYTES
from radarodom.driver.live.frame_assembler import FrameAssembler
from radarodom.driver.live.frame_ring import FrameRing
from radarodom.driver.live.stream_gaps import ByteGaps
from radarodom.driver.sources import open_source

UNATTRIBUTED = "the accounting does not add up"


# ---------------------------------------------------------------------- the headers' count
def test_byte_gaps_from_sequence_and_byte_count_gaps():
    gaps = ByteGaps()
    gaps.add(1, 0, 1456)
    gaps.add(3, 2912, 4368)  # seq 2 (bytes 1456..2912) never came
    gaps.add(4, 4368, 5000)  # truncated: seq 5 starts at 5824
    gaps.add(5, 5824, 7280)
    assert gaps.take(0, 3000) == 1456
    assert gaps.take(3000, 6000) == 824
    assert gaps.take(6000, 7280) == 0


def test_byte_gaps_late_packets_fill_their_part_until_it_is_settled():
    gaps = ByteGaps()
    for seq in (1, 4, 5):  # 2 and 3 are late
        gaps.add(seq, (seq - 1) * 1456, seq * 1456)
    gaps.add(3, 2912, 4368)  # in time: fills its part
    assert gaps.take(0, 2000) == 2000 - 1456  # seq 2's bytes below 2000
    gaps.add(2, 1456, 2912)  # too late for bytes below 2000, in time for the rest
    assert gaps.take(2000, 7280) == 0
    gaps.add(2, 1456, 2912)  # a repeat, after everything was settled
    assert gaps.take(7280, 8000) == 0


def test_byte_gaps_end_confirmed_by_the_sender_counts_the_packets_that_never_came():
    gaps = ByteGaps()
    gaps.add(1, 0, 1456)
    gaps.add(2, 1456, 2000)  # truncated, and the last to come
    assert gaps.end_at(4500) == 2  # the packets at 2912 and 4368 (the short last one)
    assert gaps.take(0, 4500) == 4500 - 2000


def _assemble(wire, frame_bytes, *, sent_all):
    ring = FrameRing(frame_bytes, 64)
    got = []

    def take(frame):
        got.append(frame)
        ring.release(frame.slot)

    asm = FrameAssembler(frame_bytes, ring, reorder_bytes=3 * MAX_DATA_BYTES, on_frame=take)
    for seq, count, data in wire:
        asm.add(seq, count, memoryview(data), 0.0)
    asm.expire(sent_all=sent_all)
    return asm, got


@settings(max_examples=150, deadline=None)
@given(n_frames=st.integers(1, 8), frame_bytes=st.sampled_from([1000, 3072, 4096, 5000]),
       seed=st.integers(0, 2**32 - 1), loss=st.floats(0, 0.6), dup=st.floats(0, 0.3),
       reorder=st.floats(0, 0.3), truncate=st.floats(0, 0.2), tail_lost=st.integers(0, 3),
       burst=st.booleans(), sent_all=st.booleans())
def test_lost_and_cut_bytes_are_what_the_stream_lost_and_never_sent(
        n_frames, frame_bytes, seed, loss, dup, reorder, truncate, tail_lost, burst, sent_all):
    """Any loss, duplication, reordering (within the window) and truncation, the stream's last
    packets never arriving, the end confirmed or not: each frame's lost bytes (from the headers)
    are exactly the bytes sent and not received up to the stream's known end, its cut bytes
    exactly those after it, and the two add up to its missing bytes (the frame's own count)."""
    rng = np.random.default_rng(seed)
    stream = stream_bytes(n_frames, frame_bytes, seed)
    sent = packetize(stream, frame_bytes=frame_bytes if burst else None)
    keys = [i + (rng.uniform(0, 2.5) if rng.random() < reorder else 0.0) for i in range(len(sent))]
    order = sorted(range(len(sent)), key=lambda i: keys[i])
    never = set(range(len(sent) - tail_lost, len(sent)))  # the last packets the board sent
    delivered = np.zeros(len(stream), bool)
    wire = []
    for i in order:
        seq, count, data = sent[i]
        if i in never or rng.random() < loss:
            continue
        if rng.random() < truncate and len(data) > 1:
            data = data[: int(rng.integers(1, len(data)))]
        delivered[count: count + len(data)] = True
        wire.append((seq, count, data))
        if rng.random() < dup:
            wire.append((seq, count, data))
    asm, got = _assemble(wire, frame_bytes, sent_all=sent_all)

    newest = max((c + len(d) for _, c, d in wire), default=0)
    for frame in got:
        lo, hi = frame.index * frame_bytes, (frame.index + 1) * frame_bytes
        known_end = hi if sent_all else min(hi, max(lo, newest))
        lost = int((~delivered[lo:known_end]).sum())
        assert (frame.lost_bytes, frame.cut_bytes) == (lost, hi - known_end), frame.index
        assert frame.missing_bytes == frame.lost_bytes + frame.cut_bytes
    st_ = asm.stats
    assert st_.missing_bytes == st_.lost_bytes + st_.cut_bytes
    if sent_all and got and not burst:  # the board's own cut: full packets from the first byte
        end = (got[-1].index + 1) * frame_bytes
        assert st_.tail_packets_lost == sum(1 for _, c, _ in sent if newest <= c < end)


def _two_frames_but(lose: set[int], truncate: dict[int, int] | None = None):
    """Two 3072-byte frames (packets 1-4 full, 5 the 320-byte rest) with packets *lose* lost
    and packets cut to the lengths in *truncate*."""
    truncate = truncate or {}
    return [(seq, count, data[:truncate.get(seq, len(data))])
            for seq, count, data in packetize(stream_bytes(2, 3072)) if seq not in lose]


@pytest.mark.parametrize("lose, truncate, sent_all, lost, cut, tail_packets", [
    ({2}, {}, True, 1456, 0, 0),  # a gap, the stream's end received: nothing after it
    ({4, 5}, {}, True, 1776, 0, 2),  # the last two never came, and the board said it sent them
    ({4, 5}, {}, False, 0, 1776, 0),  # ... without the board saying so: cut at stop
    ({5}, {4: 100}, True, 1356 + 320, 0, 1),  # the newest packet truncated: only 5 never came
], ids=["gap", "tail-confirmed", "tail-unconfirmed", "truncated-newest"])
def test_packets_that_never_came_after_a_confirmed_end(lose, truncate, sent_all, lost, cut, tail_packets):
    asm, got = _assemble(_two_frames_but(lose, truncate), 3072, sent_all=sent_all)
    s = asm.stats
    assert (s.lost_bytes, s.cut_bytes, s.tail_packets_lost) == (lost, cut, tail_packets)
    assert s.missing_bytes == lost + cut == sum(f.missing_bytes for f in got)


def test_headers_that_contradict_the_bytes_received_are_warned_about(warnings_log):
    """No board sends this (packet 4 carries the bytes that packet 3's header said packet 2
    carried), but if the two counts ever disagree, a warning says so."""
    stream = stream_bytes(1, 3000)
    wire = [(1, 0, stream[:1000]), (3, 2000, stream[2000:]), (4, 1000, stream[1000:2000])]
    asm, got = _assemble(wire, 3000, sent_all=False)
    assert [(f.missing_bytes, f.lost_bytes, f.cut_bytes) for f in got] == [(0, 1000, 0)]
    warned = [m for m in warning_messages(warnings_log) if UNATTRIBUTED in m]
    assert len(warned) == 1 and "frame 0 misses 0 bytes" in warned[0], warned


def test_a_frame_dropped_for_a_slow_consumer_takes_its_lost_bytes_with_it():
    """Lost bytes are those of the frames handed on: a frame with no buffer (policy queue)
    settles its gaps without counting them."""
    fb = 2912
    ring = FrameRing(fb, 2, "queue")
    asm = FrameAssembler(fb, ring, reorder_bytes=MAX_DATA_BYTES)
    packets = packetize(stream_bytes(4, fb))
    for seq, count, data in packets:
        if seq != 6:  # frame 2's second packet: frame 2 gets no buffer anyway
            asm.add(seq, count, data, 0.0)
    asm.expire()
    assert ring.dropped_frames == 2
    assert (asm.stats.missing_bytes, asm.stats.lost_bytes, asm.stats.cut_bytes) == (0, 0, 0)


# ---------------------------------------------------------------------- on the emulators
#: Busy processes: one more than the cores this test may run on (at most 8), so that the
#: test's own threads compete for every core.
HOGS = min(8, len(os.sched_getaffinity(0)) + 1)


def tail_bytes(frames: int, frame_bytes: int) -> int:
    """Bytes of the short last packet a board holds back after *frames* frames."""
    return frames * frame_bytes % MAX_DATA_BYTES


@pytest.mark.parametrize("stop", ["cut", "confirmed"])
def test_under_cpu_contention_every_frame_and_every_missing_byte_is_accounted_for(
        loss_capture, loss_cfg, stop, warnings_log):
    """Busy processes on every core, 5 % packet loss, a consumer 2.5 frame periods per frame
    with 3 buffers, and a stop with the board's own 2 s RECORD_COMPLETED delay: waited for
    (confirmed) or given up after 1 s (cut: the held-back tail of the last frame is cut).
    complete + incomplete + dropped = the frames the board sent; missing = lost (from the
    headers) + cut; packets_lost covers every fault the board injected that the host could see."""
    directory, frames = loss_capture
    fb, period = loss_cfg.frame_bytes, loss_cfg.frame_period_s
    url = dict(policy="latest", buffers=3, **URL_TIMEOUTS)
    if stop == "cut":
        url["stop_timeout"] = 1.0
    assert RECORD_COMPLETED_DELAY_S == 2.0  # the real board's (pcaps): this test keeps it

    with CpuHogs(HOGS) as hogs, EmulatedRig(f"replay://{directory}", config=loss_cfg,
                                            faults=Faults(loss=0.05), seed=11) as rig:
        with open_source(rig.url(**url), loss_cfg) as src:
            def slow_then_stop(frame, got):
                time.sleep(2.5 * period)
                # Stop where the board holds a short tail back whatever the stop's delay (the
                # tail is empty every 91 frames of 12288 bytes), so that a cut stop cuts bytes.
                streamed = rig.board.stats.frames_in
                if len(got) >= 30 and all(tail_bytes(k, fb) for k in range(streamed, streamed + 40)):
                    src.stop()

            got = collect_until_stopped(src, 10**6, timeout=30.0, on_frame=slow_then_stop)
            described = src.describe()
            last_seq = src.receiver.gaps.last
        sent = rig.board.stats
        truth = rig.board.lost_bytes_per_frame

    assert len(hogs.cpu_s) == HOGS and min(hogs.cpu_s) > 0, f"the busy processes never ran: {hogs.cpu_s}"
    assert sent.dropped > 0, "the fault injector lost nothing: the test proves nothing"
    assert described["frames_dropped"] > 0, "a consumer 2.5 times too slow dropped nothing"
    # Frames: every frame the board sent is complete, incomplete or dropped.
    counted = described["frames_complete"] + described["frames_incomplete"] + described["frames_dropped"]
    assert counted == sent.frames_in, (counted, sent, described)
    assert described["frames_complete"] + described["frames_incomplete"] == len(got)
    indices = [g.index for g in got]
    assert indices == sorted(set(indices)) and indices[-1] == sent.frames_in - 1, indices
    assert_frames_match(got, frames)
    # Bytes: the frames' own count = the headers' count + the cut, in total and frame by frame.
    assert described["missing_bytes"] == sum(g.missing_bytes for g in got)
    assert described["missing_bytes"] == described["lost_bytes"] + described["cut_bytes"], described
    assert not [m for m in warning_messages(warnings_log) if UNATTRIBUTED in m]
    assert described["lost_bytes"] > 0, described
    short = [(g.index, g.missing_bytes, truth[g.index]) for g in got if g.missing_bytes < truth.get(g.index, 0)]
    assert not short, f"(frame, missing, lost by the board): {short}"
    *before, last = got
    assert all(g.cut_bytes == 0 for g in before)
    if stop == "cut":
        tail = tail_bytes(sent.frames_in, fb)
        assert described["cut_bytes"] == last.cut_bytes >= tail > 0, (tail, described)
        # Faults on packets after the last one received are invisible to the host.
        unseen = sent.packets_sent - last_seq
        assert described["packets_lost"] >= sent.dropped - unseen, (described, sent, last_seq)
    else:
        assert described["cut_bytes"] == 0, described
        assert described["packets_lost"] >= sent.dropped, (described, sent)
        if described["packets_lost"] == sent.dropped:  # the kernel lost nothing: exact, frame by frame
            wrong = [(g.index, g.missing_bytes, truth.get(g.index, 0)) for g in got
                     if g.missing_bytes != truth.get(g.index, 0)]
            assert not wrong, f"(frame, missing, lost by the board): {wrong}"
