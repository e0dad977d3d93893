"""An earlier recording's packets: a board left streaming by a run killed before it could stop
it.  Its packets, waiting on the data port or arriving while the board and the radar are set up,
were taken for the new recording's: frames of zeros timed near 1970 (the clock had no packet to
place them by), the new stream's first seconds counted as late packets, and odometry in the
billions of metres.  Now they are flushed before RECORD_START, a first packet that claims more of
the stream than the board can have sent since it started is ignored, and both are counted
(``stale_packets``).  Real sockets on loopback, the emulated rig."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest
from live_helpers import URL_TIMEOUTS, assert_continuous, collect

from radarodom.driver.emulators.rig import EmulatedRig
from radarodom.driver.live.dca1000 import Dca1000Settings
from radarodom.driver.live.dca1000_receiver import Dca1000Receiver
from radarodom.driver.live.dca1000_wire import DATA_HEADER, MAX_DATA_BYTES
from radarodom.driver.live.frame_ring import FrameRing
from radarodom.driver.sources import open_source
from radarodom.errors import DeviceTimeout

N_SRC = 5
STALE_SEQ = 200_000


def stale_packet(seq: int) -> bytes:
    """A data packet of a recording long under way: its sequence number and stream offset far on (a
    terabyte in: beyond what any wait of a loaded machine lets this recording's bound reach)."""
    offset = 2**40 + (seq - STALE_SEQ) * MAX_DATA_BYTES
    return DATA_HEADER.pack(seq, offset.to_bytes(6, "little")) + bytes(MAX_DATA_BYTES)


def test_packets_of_an_earlier_recording_during_set_up_are_not_frames(small_capture, small_cfg):
    directory, frames = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        sent = []
        done, streaming = threading.Event(), threading.Event()

        def old_board():  # streams from the board's address until the new recording starts, and a bit on
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
                s.bind((rig.board.board_ip, 0))
                seq = STALE_SEQ
                while not done.is_set() and not rig.board.recording:
                    s.sendto(stale_packet(seq), (rig.host_ip, rig.data_port))
                    sent.append(seq)
                    streaming.set()
                    seq += 1
                    time.sleep(0.002)

        sender = threading.Thread(target=old_board, daemon=True)
        sender.start()
        # On a busy machine the thread may first run once the set-up is through: the old board is
        # streaming before the new recording is opened, as a board left running is.
        assert streaming.wait(10), "the old board sent nothing"
        try:
            with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
                got = collect(src, 10, timeout=10.0)
                described = src.describe()
        finally:
            done.set()
            sender.join(5)
    assert sent, "the old board sent nothing"
    assert len(got) == 10
    assert_continuous([g.index for g in got])
    for g in got:
        assert g.missing_bytes == 0 and g.raw == frames[g.index % N_SRC]
    stamps = np.array([g.timestamp for g in got])
    assert (np.abs(stamps - np.array([g.received for g in got])) < 60).all(), stamps  # this run's times
    assert described["stale_packets"] > 0 and described["late_packets"] == 0, described
    assert described["frames_dropped"] == 0 and described["seq_gaps"] == 0, described


def test_a_first_packet_beyond_what_the_board_can_have_sent_is_stale(small_cfg):
    """Packets of an earlier recording arriving after RECORD_START, before the new one's first."""
    frame_bytes = small_cfg.frame_bytes
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    settings = Dca1000Settings(host_ip="127.0.0.1", board_ip="127.0.0.1", data_port=port)
    ring = FrameRing(frame_bytes, 8)
    receiver = Dca1000Receiver(settings, frame_bytes, ring, frame_period_s=small_cfg.frame_period_s).open()
    data = np.random.default_rng(1).integers(0, 256, 3 * frame_bytes, dtype=np.uint8).tobytes()
    try:
        receiver.start()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as board:
            for seq in range(STALE_SEQ, STALE_SEQ + 5):
                board.sendto(stale_packet(seq), ("127.0.0.1", port))
            for seq, start in enumerate(range(0, len(data), MAX_DATA_BYTES), start=1):
                board.sendto(DATA_HEADER.pack(seq, start.to_bytes(6, "little")) + data[start:start + MAX_DATA_BYTES],
                             ("127.0.0.1", port))
        got = []
        while len(got) < 2 and (frame := ring.get(timeout=5)) is not None:  # the third is open until more come
            got.append((frame.index, bytes(frame.data), frame.missing_bytes))
            ring.release(frame.slot)
    finally:
        receiver.close()
    assert [(i, m) for i, _, m in got] == [(0, 0), (1, 0)]
    assert [d for _, d, _ in got] == [data[:frame_bytes], data[frame_bytes:2 * frame_bytes]]
    assert receiver.stats.stale_packets == 5
    assert receiver.first_packet[0] == 0


def test_data_sent_to_another_port_says_where_the_board_sends(small_capture, small_cfg):
    """The board answers its commands, but its data goes elsewhere (a data_port= or host= that is
    not the EEPROM's): the message said 'Was the radar reset, or its cable moved?'.  It comes after
    the URL's data_timeout, which it names."""
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.bind((rig.host_ip, 0))
            elsewhere = probe.getsockname()[1]
        url = rig.url(**URL_TIMEOUTS, data_timeout=0.5).replace(f"data_port={rig.data_port}", f"data_port={elsewhere}")
        with open_source(url, small_cfg) as src:
            with pytest.raises(DeviceTimeout) as info:
                collect(src, 1, timeout=30.0)
    message = str(info.value)
    assert f"no data packet of the DCA1000's reached {rig.host_ip}:{elsewhere} in " in message, message
    assert "s since the radar started (data_timeout=0.5, frame period " in message, message
    assert "EEPROM (192.168.33.30:4098 unless changed)" in message and "data_port=" in message, message


def test_a_frame_lost_late_in_a_drifting_stream_keeps_the_times_increasing(caplog):
    """The first packet's offset was observed for every wholly lost frame: 25 minutes into a stream
    whose clock drifts 60 ppm against the host's, it came back into the window and the lost frame
    was timed 40 ms before the one before it (the estimator's TimeOrderError).  It places the
    grid only while nothing has (the rule LiveSource takes, in FrameClock.stamp)."""
    from radarodom.driver.live.source import FrameClock

    period, first = 0.05, (0, 1.7e9 + 0.001)
    clock = FrameClock(period)
    assert not clock.placed
    stamps = []
    for i in range(31000):
        received = 0.0 if i in (0, 30000) else 1.7e9 + i * period * (1 + 60e-6) + 0.001
        stamps.append(clock.stamp(i, received, first_packet=first))
    assert clock.placed and (np.diff(stamps) > 0).all()
    assert stamps[0] == first[1]  # the first frame, wholly lost, placed by the stream's first packet
    # The frame lost late lies on the grid of the frames around it, no warning of a clock set back.
    assert stamps[30000] - stamps[29999] == pytest.approx(period, abs=1e-6)
    assert not [r for r in caplog.records if "set back" in r.getMessage()]


def test_frame_times_go_on_when_the_hosts_clock_is_set_back(caplog):
    """An NTP step back of 5 s: the next frame was timed before the one before, and the recording
    and the estimator stopped the run.  Its times go on from the last frame's on its grid."""
    from radarodom.driver.live.source import FrameClock

    clock, period = FrameClock(0.1), 0.1
    stamps = [clock.stamp(i, 1.7e9 + i * period + (0 if i < 50 else -5.0) + 0.001) for i in range(200)]
    assert (np.abs(np.diff(stamps) - period) < 1e-6).all()
    said = [r.getMessage() for r in caplog.records if "set back" in r.getMessage()]
    assert len(said) == 1 and said[0].startswith("this computer's clock was set back by 5.000 s")


@pytest.mark.parametrize("period", [0.1, 1 / 30])
def test_frame_times_follow_the_hosts_clock_set_forward_within_eight_frames(caplog, period):
    """A chrony step forward of 30 s at frame 100 (a robot's computer syncing after boot), with a
    few ms of jitter: the frames were timed on the old grid for a whole window (64 frames), 30 s
    behind the robot's other sensors.  The grid follows within eight frames, once, and stays."""
    from radarodom.driver.live.source import FrameClock

    rng = np.random.default_rng(0)
    clock = FrameClock(period)
    received = [1.7e9 + i * period + (30.0 if i >= 100 else 0.0) + 0.001 + rng.uniform(0, 0.004) for i in range(300)]
    stamps = np.array([clock.stamp(i, r) for i, r in enumerate(received)])
    behind = np.array(received) - stamps
    assert (behind[:100] < 0.01).all() and (behind[100:107] > 29.9).all() and (behind[107:] < 0.01).all()
    assert (np.diff(stamps) > 0).all()
    said = [r.getMessage() for r in caplog.records if "set forward" in r.getMessage()]
    assert len(said) == 1 and said[0].startswith("this computer's clock was set forward by 30.00"), said
    assert said[0].endswith("from frame 100")


@pytest.mark.parametrize("drain", [1.25, 1.1])
def test_a_stalls_backlog_drained_slowly_is_no_clock_set_forward(caplog, drain):
    """A 3 s stall read back at 1.25 times the frame rate: eight late frames agreed within two
    periods and the grid jumped to the lateness, 2.9 s off for frames the window would have kept."""
    from radarodom.driver.live.source import FrameClock

    period, clock = 0.1, FrameClock(0.1)
    received = [1.7e9 + i * period + 0.001 for i in range(100)]
    for i in range(100, 600):
        on_time = 1.7e9 + i * period + 0.001
        received.append(max(on_time, (received[-1] + period / drain) if i > 100 else on_time + 3.0))
    stamps = [clock.stamp(i, r) for i, r in enumerate(received)]
    assert not [r for r in caplog.records if "set forward" in r.getMessage()]
    assert stamps[-1] == pytest.approx(received[-1], abs=1e-6)  # on the radar's grid once drained


def test_a_clock_set_forward_among_lost_frames_names_the_first_late_frame(caplog):
    """Every other frame from the step on wholly lost: the warning named frame 107 (index less
    seven), and the grid moved at the eighth late frame that came, frame 114."""
    from radarodom.driver.live.source import FrameClock

    period, clock = 0.1, FrameClock(0.1)
    for i in range(200):
        lost = 100 <= i < 140 and i % 2
        clock.stamp(i, 0.0 if lost else 1.7e9 + i * period + (30.0 if i >= 100 else 0.0) + 0.001)
    said = [r.getMessage() for r in caplog.records if "set forward" in r.getMessage()]
    assert len(said) == 1 and said[0].endswith("from frame 100"), said


def test_a_stall_drained_at_once_does_not_move_the_grid(caplog):
    """The host stalled 3 s and then read the 30 frames waiting for it at once: they came late, a
    period earlier each, and the grid (the radar's) stays where it was."""
    from radarodom.driver.live.source import FrameClock

    period, clock = 0.1, FrameClock(0.1)
    received = [1.7e9 + i * period + 0.001 for i in range(300)]
    for i in range(100, 130):
        received[i] = 1.7e9 + 130 * period + 0.001 + (i - 100) * 1e-5
    stamps = np.array([clock.stamp(i, r) for i, r in enumerate(received)])
    assert np.allclose(stamps, 1.7e9 + np.arange(300) * period + 0.001, atol=1e-6, rtol=0)
    assert not [r for r in caplog.records if "set forward" in r.getMessage()]
