"""How a live capture (``dca1000://``) ends, against the emulated rig, with the boards' real
stop timing: the fake DCA1000 holds the last frame's short packet back until 2 s after
RECORD_STOP, then sends it with RECORD_COMPLETED, as the real capture in the pcaps shows.

Every frame the board sent must come out whole (library and command line), and the
accounting must add up: complete + incomplete + dropped = frames the board sent, and the
bytes missing = the bytes the board lost in delivered frames + the bytes cut at stop.
Nothing here asserts a speed: lower bounds on waits come from the protocol, upper bounds are
generous.
"""

from __future__ import annotations

import re
import time

import pytest
from conftest import SMALL_CFG, warning_messages
from live_helpers import (
    URL_TIMEOUTS,
    Emulator,
    Process,
    assert_continuous,
    assert_frames_match,
    collect,
    collect_until_stopped,
    wait_until,
)
from radarodom.pipeline import CaptureSink, Pipeline
from radarodom.driver.recordings.capture_dir import CaptureDirectory, CaptureWriter
from radarodom.driver.live.dca1000_wire import MAX_DATA_BYTES, AsyncStatus, Command
from radarodom.driver.emulators.fake_dca1000 import RECORD_COMPLETED_DELAY_S, Faults
from radarodom.driver.emulators.rig import EmulatedRig
from radarodom.driver.sources import open_source
from radarodom.errors import UsageError

N_SRC = 5


def tail_bytes(frames: int, frame_bytes: int) -> int:
    """Bytes of the short last packet a board holds back after *frames* frames."""
    return frames * frame_bytes % MAX_DATA_BYTES


def assert_adds_up(described: dict, frames_sent: int) -> None:
    counted = described["frames_complete"] + described["frames_incomplete"] + described["frames_dropped"]
    assert counted == frames_sent, f"{counted} frames accounted for, the board sent {frames_sent}: {described}"
    assert described["missing_bytes"] == described["lost_bytes"] + described["cut_bytes"], described


# ---------------------------------------------------------------------- the held-back tail
def test_the_tail_held_back_2_s_arrives_and_every_frame_is_complete(small_capture, small_cfg):
    directory, frames = small_capture
    assert RECORD_COMPLETED_DELAY_S == 2.0  # the real board's (pcaps): this test keeps it
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            stopped = []
            got = collect_until_stopped(src, 6, on_frame=lambda f, g: len(g) == 6 and stopped.append(time.monotonic()))
            ended = time.monotonic()
            described = src.describe()
        sent = rig.board.stats

    assert sent.frames_in == len(got) >= 6
    assert tail_bytes(len(got), small_cfg.frame_bytes), "the last frame ends on a packet boundary: nothing held"
    assert_continuous([g.index for g in got])
    assert all(g.missing_bytes == 0 for g in got), [(g.index, g.missing_bytes) for g in got]
    assert_frames_match(got, frames)
    # The last frame needed the packet the board sends 2 s after RECORD_STOP.
    assert ended - stopped[0] >= RECORD_COMPLETED_DELAY_S
    assert described["async_status"].get(AsyncStatus.RECORD_COMPLETED.name) == 1, described
    assert_adds_up(described, sent.frames_in)
    assert described["frames_incomplete"] == described["missing_bytes"] == described["cut_bytes"] == 0


def test_without_record_completed_in_time_the_tail_is_cut_and_counted_as_such(small_capture, small_cfg,
                                                                             warnings_log):
    """stop_timeout shorter than the board's 2 s: the last frame is handed on without its tail,
    whose bytes are counted as cut at stop, not as lost packets."""
    directory, frames = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        with open_source(rig.url(stop_timeout=0.3, **URL_TIMEOUTS), small_cfg) as src:
            got = collect_until_stopped(src, 4)
            described = src.describe()
        sent = rig.board.stats.frames_in

    assert len(got) == sent
    *whole, last = got
    assert all(g.missing_bytes == 0 for g in whole)
    tail = tail_bytes(len(got), small_cfg.frame_bytes)
    assert last.missing_bytes == last.cut_bytes == tail > 0
    assert_frames_match(got, frames)
    assert_adds_up(described, sent)
    assert described["cut_bytes"] == tail and described["lost_bytes"] == 0, described
    assert described["packets_lost"] == 0, described
    warned = [m for m in warning_messages(warnings_log) if "RECORD_COMPLETED" in m]
    assert len(warned) == 1 and "cut at stop" in warned[0] and "stop_timeout" in warned[0], warned


def test_an_aborted_runs_record_completed_does_not_end_the_next_run(small_capture, small_cfg):
    """Run A is aborted (closed without waiting for its RECORD_COMPLETED, as a second Ctrl-C
    does) and run B starts at once and stops before A's message comes: A's RECORD_COMPLETED,
    arriving while B waits for its own, was taken as B's end, and B's last frame lost the tail
    the board sends with B's own, counted as "lost on the way"."""
    directory, frames = small_capture
    delay = RECORD_COMPLETED_DELAY_S
    with EmulatedRig(f"replay://{directory}", config=small_cfg, record_completed_delay_s=delay) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            collect(src, 3)
        a_stopped = time.monotonic()  # close() sent RECORD_STOP and did not wait
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            stopped = []
            got = collect_until_stopped(src, 2, on_frame=lambda f, g: len(g) == 2 and stopped.append(time.monotonic()))
            ended = time.monotonic()
            described = src.describe()
        sent = rig.board.stats.frames_in

    # A's message came while B waited for its own: otherwise this run did not test anything.
    assert stopped[0] < a_stopped + delay, "B stopped after A's RECORD_COMPLETED came: too slow to test"
    assert described["async_status"].get("RECORD_COMPLETED") >= 1, described
    assert ended - stopped[0] >= delay  # B waited for its own, which brought its last frame's tail
    assert len(got) == sent
    assert tail_bytes(len(got), small_cfg.frame_bytes), "the last frame ends on a packet boundary: nothing held"
    assert_continuous([g.index for g in got])
    assert all(g.missing_bytes == 0 for g in got), [(g.index, g.missing_bytes) for g in got]
    assert_frames_match(got, frames)
    assert_adds_up(described, sent)
    assert described["lost_bytes"] == described["cut_bytes"] == described["packets_lost"] == 0, described


# ---------------------------------------------------------------------- accounting
@pytest.mark.parametrize("policy", ["latest", "queue"])
def test_accounting_adds_up_under_loss_and_a_slow_consumer(loss_capture, loss_cfg, policy):
    """5 % packet loss, a consumer 2.5 frame periods per frame with 3 buffers, then a stop:
    every frame the board sent is complete, incomplete or dropped, and the missing bytes of
    each delivered frame are exactly what the board lost of it."""
    directory, frames = loss_capture
    period = loss_cfg.frame_period_s

    def slow(frame, got):
        time.sleep(2.5 * period)

    with EmulatedRig(f"replay://{directory}", config=loss_cfg, faults=Faults(loss=0.05), seed=5,
                     record_completed_delay_s=0.3) as rig:
        with open_source(rig.url(policy=policy, buffers=3, **URL_TIMEOUTS), loss_cfg) as src:
            got = collect_until_stopped(src, 25, on_frame=slow)
            described = src.describe()
        truth = rig.board.lost_bytes_per_frame
        sent = rig.board.stats

    assert sent.dropped > 0, "the fault injector lost nothing: the test proves nothing"
    assert described["frames_dropped"] > 0, "a consumer 2.5 times too slow dropped nothing"
    assert_adds_up(described, sent.frames_in)
    assert described["frames_complete"] + described["frames_incomplete"] == len(got)
    indices = [g.index for g in got]
    assert indices == sorted(set(indices)), indices
    if policy == "latest":  # the newest frame is never the one dropped
        assert indices[-1] == sent.frames_in - 1, indices
    wrong = [(g.index, g.missing_bytes, truth.get(g.index, 0)) for g in got if g.missing_bytes != truth.get(g.index, 0)]
    assert not wrong, f"(frame, missing, lost by the board): {wrong}"
    assert_frames_match(got, frames)
    delivered_truth = sum(truth.get(k, 0) for k in indices)
    assert described["missing_bytes"] == delivered_truth + described["cut_bytes"], described
    assert described["cut_bytes"] == 0, described  # the board confirmed the end: nothing cut
    assert described["frames_incomplete"] == sum(1 for g in got if g.missing_bytes) > 0
    assert described["packets_lost"] == sent.dropped, (described, sent)


def test_a_duration_limit_leaves_the_frame_past_it_in_the_accounting(loss_capture, loss_cfg):
    """The frame that shows the duration is over is read, not streamed: the bytes it lost on the
    way are in the source's accounting (its packet headers), so the run keeps them apart, and the
    two add up (else the summary reports a mismatch, docs/live.md)."""
    directory, _ = loss_capture
    with EmulatedRig(f"replay://{directory}", config=loss_cfg, faults=Faults(loss=0.3), seed=2,
                     record_completed_delay_s=0.3) as rig:
        with open_source(rig.url(policy="queue", **URL_TIMEOUTS), loss_cfg) as src:
            stats = Pipeline(src, max_duration_s=0.15).run()
            described = src.describe()
    assert stats.reason == "duration limit"
    assert stats.lost_bytes > 0 and stats.unstreamed_lost_bytes > 0, "nothing lost: the test proves nothing"
    assert stats.lost_bytes + stats.unstreamed_lost_bytes == described["lost_bytes"], (stats, described)


def test_accounting_adds_up_when_the_board_makes_frames_slower_than_its_period(small_cfg, warnings_log):
    """The emulator's own CPU falling behind (its source takes 1.5 frame periods per frame):
    frames come late but whole, nothing is counted lost, and the emulator blames its CPU."""
    period = small_cfg.frame_period_s
    source = make_frames(small_cfg, 4)

    def slow_frames():
        for raw in source:
            time.sleep(1.5 * period)
            yield raw

    with EmulatedRig(lambda: slow_frames(), config=small_cfg, record_completed_delay_s=0.3) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            got = collect_until_stopped(src, 8)
            described = src.describe()
        sent = rig.board.stats.frames_in

    assert_continuous([g.index for g in got])
    assert len(got) == sent and all(g.missing_bytes == 0 for g in got)
    assert_frames_match(got, source)
    assert_adds_up(described, sent)
    assert described["missing_bytes"] == described["packets_lost"] == described["frames_dropped"] == 0
    late = [m for m in warning_messages(warnings_log) if "fake DCA1000: frame" in m and "late" in m]
    assert late and "CPU" in late[0] and "Mbit/s link needs" in late[0], late


def make_frames(cfg, n: int) -> list[bytes]:
    from conftest import random_frames

    return random_frames(cfg, n, seed=21)


# ---------------------------------------------------------------------- recording
def test_pipeline_records_cut_bytes_and_dropped_frames_in_capture_json(small_capture, small_cfg, tmp_path):
    directory, _ = small_capture
    out = tmp_path / "rec"
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        with open_source(rig.url(stop_timeout=0.3, **URL_TIMEOUTS), small_cfg) as src:
            writer = CaptureWriter(out, src.config, source=src.url)

            def stop_after_5(result, stats):
                if stats.frames == 5:
                    src.stop()

            stats = Pipeline(src, sinks=[CaptureSink(writer, src)]).run(stop_after_5)
        sent = rig.board.stats.frames_in

    tail = tail_bytes(sent, small_cfg.frame_bytes)
    assert stats.reason == "stopped" and stats.frames == sent
    assert stats.missing_bytes == stats.cut_bytes == tail and stats.lost_bytes == 0
    rec = CaptureDirectory(out)
    meta = rec.metadata
    assert meta["incomplete_frames"] == [{"frame": sent - 1, "missing_bytes": tail, "cut_bytes": tail}]
    assert meta["lost_bytes"] == meta["cut_bytes"] == tail  # lost_bytes: every zero-filled byte
    assert meta["dropped_frames"] == 0
    assert rec.cut_bytes(sent - 1) == tail and rec.missing_bytes(sent - 1) == tail
    # Replaying the recording hands the same attribution on.
    with open_source(f"replay://{out}?rate=max") as replay:
        replayed = list((f.missing_bytes, f.cut_bytes) for f in replay)
    assert replayed[-1] == (tail, tail) and set(replayed[:-1]) == {(0, 0)}


# ---------------------------------------------------------------------- command line
def capture_then_ctrl_c(emu: Emulator, out, *, frames_first: int = 4, url_extra: str = ""):
    """radar-capture --record OUT on the emulator, Ctrl-C once *frames_first* frames are
    recorded; (exit code, stdout, stderr)."""
    capture = Process(emu.capture_argv("--record", out, "--no-odom", "--no-publish", url_extra=url_extra))
    stamps = out / "timestamps.txt"
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and capture.proc.poll() is None:
        if stamps.exists() and stamps.read_text().count("\n") >= frames_first:
            break
        time.sleep(0.05)
    capture.interrupt()
    code = capture.wait(20)
    capture.kill()
    stdout, stderr = capture.output()
    return code, stdout, stderr


def frames_sent_by(emu: Emulator) -> int:
    """The frames the emulator's radar streamed in its last recording (the board says, on exit,
    how many it sent whole and of how many more it held the tail back)."""
    assert emu.stop() == 0
    emu_out, _ = emu.output()
    sent = re.search(r"radar-emulate: sent (\d+) frames .*?(?:; the tail of (\d+) more was held back|$)",
                     emu_out, re.M)
    assert sent, emu_out
    return int(sent.group(1)) + int(sent.group(2) or 0)


def test_cli_ctrl_c_records_every_frame_whole_and_the_summary_says_so(small_capture, tmp_path):
    """radar-emulate (the board's 2 s) -> radar-capture --record, Ctrl-C: the recording holds
    every frame the board sent, all complete, and the summary says where everything went."""
    directory, frames = small_capture
    out = tmp_path / "rec"
    with Emulator("--capture", directory) as emu:
        code, stdout, stderr = capture_then_ctrl_c(emu, out)
        sent = frames_sent_by(emu)
    assert code == 0, stderr
    assert "Traceback" not in stderr
    rec = CaptureDirectory(out)
    assert rec.num_frames == sent >= 4
    assert rec.metadata["incomplete_frames"] == [] and rec.metadata["lost_bytes"] == 0
    assert rec.metadata["cut_bytes"] == 0 and rec.metadata["dropped_frames"] == 0
    for k in range(rec.num_frames):
        assert bytes(rec.raw(k)) == frames[k % N_SRC], k
    assert f"{sent} frames (0 incomplete, 0 bytes missing) in" in stdout, stdout
    assert "; stopped; recorded to" in stdout
    assert "0 frames dropped by slow processing, 0 packets lost (sequence gaps), 0 truncated and 0 late" in stdout


def test_cli_summary_names_bytes_cut_at_stop(small_capture, small_cfg, tmp_path):
    """stop_timeout shorter than the board's 2 s: the summary says the last frame's missing
    bytes were cut at stop, and that no packet was lost."""
    directory, _ = small_capture
    out = tmp_path / "rec"
    with Emulator("--capture", directory) as emu:
        code, stdout, stderr = capture_then_ctrl_c(emu, out, url_extra="stop_timeout=0.2")
        sent = frames_sent_by(emu)
    assert code == 0, stderr
    tail = tail_bytes(sent, small_cfg.frame_bytes)
    assert f"{sent} frames (1 incomplete, {tail} bytes missing: {tail} cut at stop) in" in stdout, stdout
    assert "0 packets lost (sequence gaps)" in stdout, stdout
    assert "did not report RECORD_COMPLETED within 0.2 s" in stderr, stderr
    rec = CaptureDirectory(out)
    assert rec.metadata["incomplete_frames"] == [{"frame": sent - 1, "missing_bytes": tail, "cut_bytes": tail}]


def test_board_sees_the_stop_sequence_once(small_capture, small_cfg):
    """sensorStop, then RECORD_STOP once, then the receiver; close() repeats nothing."""
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg, record_completed_delay_s=0.2) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            collect_until_stopped(src, 2)
        assert rig.board.commands.get(Command.RECORD_STOP) == 1
        assert rig.radar.received[-1] == "sensorStop" and rig.radar.received.count("sensorStart") == 1
        # Closed, its sockets released: iterating it again was "AttributeError: 'NoneType' object has
        # no attribute 'setblocking'".
        with pytest.raises(UsageError, match=r"the source is closed; open a new one \(open_source\)"):
            next(iter(src))


def test_cli_a_board_that_stops_mid_run_still_gets_its_summary(small_capture, small_cfg, tmp_path, capsys):
    """The radar stops streaming mid-run (a reset, a cable): radar-capture prints what it kept and
    lost, then the one error line, and the recording is closed."""
    import threading

    from radarodom.tools import radar_capture

    directory, _ = small_capture
    out = tmp_path / "rec"
    (tmp_path / "small.cfg").write_text(SMALL_CFG)
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        def radar_dies():
            if wait_until(lambda: (out / "timestamps.txt").exists()
                          and len((out / "timestamps.txt").read_text().splitlines()) >= 3, 30.0):
                rig.board.lvds_stop()  # nothing else says so

        killer = threading.Thread(target=radar_dies, daemon=True)
        killer.start()
        code = radar_capture.main(["--source", rig.url(**URL_TIMEOUTS), "--cfg", str(tmp_path / "small.cfg"),
                                   "--no-publish", "--no-odom", "-q", "--record", str(out)])
        killer.join(30.0)
    stdout, stderr = capsys.readouterr()
    assert code == 1 and "Was the radar reset, or its cable moved?" in stderr, stderr
    rec = CaptureDirectory(out)
    assert rec.metadata["closed"] is True and rec.num_frames >= 3
    assert stdout.startswith(f"radar-capture: {rec.num_frames} frames (") and "; stopped by an error; recorded to" \
        in stdout and "packets lost (sequence gaps)" in stdout, stdout


def test_frames_after_the_consumer_left_are_not_counted_as_dropped(small_capture, small_cfg):
    """A consumer that leaves (a frame limit) while the board still sends: what arrives after is
    not its, neither delivered nor counted (it was counted as dropped by slow processing while
    the source stayed open, a slow view's close of 30 s giving 80 'dropped' in a 20-frame run)."""
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            for k, _frame in enumerate(src):
                if k == 2:
                    break
            left = src.describe()
            packets_per_frame = -(-small_cfg.frame_bytes // MAX_DATA_BYTES)
            assert wait_until(lambda: src.describe()["packets"] > left["packets"] + 12 * packets_per_frame, 30.0)
            after = src.describe()
    assert left["frames_dropped"] == after["frames_dropped"] == 0
    assert after["frames_complete"] + after["frames_incomplete"] == 3
