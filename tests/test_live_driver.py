"""The live driver (``dca1000://``) end to end against the emulated rig: a fake
AWR1843 on a pty and a fake DCA1000 on loopback UDP, speaking the real protocols.

Clean streaming (bytes, indices, timestamps, counters), the start and stop order
both boards see, drop policies with a slow consumer, the receive-buffer warning,
recording with Pipeline.run, and the command-line programs (radar-emulate ->
radar-capture) including Ctrl-C.  Faults are in test_live_faults.py.

Frames are SMALL_CFG's (3072 bytes every 50 ms) unless a test says otherwise.
"""

from __future__ import annotations

import json
import os
import re
import socket
import time

import numpy as np
import pytest
from conftest import console_command, warning_messages
from live_helpers import (
    BIG_CFG,
    URL_TIMEOUTS,
    Emulator,
    Process,
    assert_continuous,
    assert_frames_match,
    collect,
    config,
    frame_problem,
)
from radarodom.driver.live.awr1843 import Awr1843Cli
from radarodom.driver.live.awr1843_protocol import Outcome
from radarodom.pipeline import CaptureSink, Pipeline
from radarodom.driver.recordings.capture_dir import CaptureDirectory, CaptureWriter
from radarodom.driver.live.dca1000_receiver import WANTED_RCVBUF
from radarodom.driver.live.dca1000_wire import Command
from radarodom.driver.emulators.fake_dca1000 import Faults
from radarodom.driver.emulators.rig import EmulatedRig
from radarodom.driver.sources import open_source
from radarodom.errors import DeviceTimeout

N_SRC = 5  # frames in the streamed capture (the board loops it)


def spy_on_sensor(rig: EmulatedRig) -> list[tuple]:
    """Log (event, board recording?, RECORD_START count, RECORD_STOP count) each
    time the fake radar starts or stops its sensor."""
    events: list[tuple] = []
    board, radar = rig.board, rig.radar
    start, stop = radar.on_sensor_start, radar.on_sensor_stop

    def snapshot(name):
        cmds = board.commands
        return (name, board.recording, cmds.get(Command.RECORD_START, 0), cmds.get(Command.RECORD_STOP, 0))

    def on_start(cfg):
        events.append(snapshot("sensorStart"))
        start(cfg)

    def on_stop():
        events.append(snapshot("sensorStop"))
        stop()

    radar.on_sensor_start, radar.on_sensor_stop = on_start, on_stop
    return events


# ---------------------------------------------------------------------- clean run
def test_clean_run_delivers_the_source_frames_in_order_on_the_frame_grid(small_capture, small_cfg,
                                                                           warnings_log):
    directory, frames = small_capture
    period = small_cfg.frame_period_s
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        with open_source(rig.url(**URL_TIMEOUTS), small_cfg) as src:
            got = collect(src, 20, timeout=5.0)
            during = src.describe()
        after = src.describe()

    assert len(got) == 20
    assert_continuous([g.index for g in got])
    assert all(g.missing_bytes == 0 for g in got)
    for g in got:
        assert g.raw == frames[g.index % N_SRC], f"frame {g.index} differs from source frame {g.index % N_SRC}"

    ts = np.array([g.timestamp for g in got])
    assert (np.diff(ts) > 0).all(), np.diff(ts)
    on_grid = ts - np.arange(len(ts)) * period
    # The clock's grid start is the least delay seen so far: it can only move earlier (the
    # first frames may sit late by a loaded machine's jitter), and settles within a few frames.
    assert (np.diff(on_grid) <= 1e-6).all(), f"grid start moved later: {on_grid - on_grid.min()}"
    # A frame's time is that of its first chirp: never after the consumer had it.  (How long
    # before depends on the machine's load: not asserted.)
    late = np.array([g.received for g in got]) - ts
    assert (late >= 0).all(), late

    for d in (during, after):
        assert d["foreign_packets"] == d["malformed_packets"] == d["late_packets"] == 0, d
        assert d["duplicate_packets"] == d["seq_gaps"] == 0, d
        assert d["missing_bytes"] == d["frames_incomplete"] == d["frames_dropped"] == 0, d
    # Every delivered frame was complete, so at least its bytes came in packets of <= 1456 bytes.
    assert during["packets"] >= -(-20 * small_cfg.frame_bytes // 1456), during
    assert during["async_status"] == {}, during
    assert during["fpga"] == "2.8 [Record]"
    assert during["rcvbuf_bytes"] >= 2 * small_cfg.frame_bytes
    assert not [m for m in warning_messages(warnings_log) if "rmem_max" in m]
    # The small cfg has no compRangeBiasAndRxChanPhase line: a real board's live stream says so, once.
    uncalibrated = [m for m in warning_messages(warnings_log) if "compRangeBiasAndRxChanPhase is missing" in m]
    assert len(uncalibrated) == 1 and "radar-calibrate" in uncalibrated[0], warning_messages(warnings_log)


def test_start_order_record_before_sensor_start_and_stop_in_reverse(small_capture, small_cfg):
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        events = spy_on_sensor(rig)
        with open_source(rig.url(delay=10, **URL_TIMEOUTS), small_cfg) as src:
            # Configured, not yet started: the board is set up, the radar configured.
            assert rig.radar.received == ["sensorStop", "flushCfg",
                                          *[str(ln) for ln in small_cfg.commands_to_send()]]
            assert not rig.board.recording and not rig.radar.started
            assert rig.board.packet_config.delay_us == pytest.approx(10, abs=0.01)
            got = collect(src, 3)
            assert len(got) == 3
            assert rig.radar.started and rig.board.recording
        # Closed: the radar stopped last, then the board.
        assert rig.radar.received == ["sensorStop", "flushCfg", *[str(ln) for ln in small_cfg.commands_to_send()],
                                      "sensorStart", "sensorStop"]
        assert not rig.radar.started
        assert not rig.board.recording
        assert events == [("sensorStart", True, 1, 0),  # RECORD_START answered before sensorStart
                          ("sensorStop", True, 1, 0)]  # sensorStop before RECORD_STOP
        assert rig.board.commands == {Command.SYSTEM_CONNECT: 1, Command.READ_FPGA_VERSION: 1,
                                      Command.RESET_FPGA: 1, Command.CONFIG_FPGA_GEN: 1,
                                      Command.CONFIG_PACKET_DATA: 1, Command.RECORD_START: 1,
                                      Command.RECORD_STOP: 1}
        assert rig.board.malformed_requests == 0


# ---------------------------------------------------------------------- drop policies
@pytest.mark.parametrize("policy", ["latest", "queue"])
def test_slow_consumer_drops_whole_frames_by_policy_and_never_sees_a_frame_rewritten(
        small_capture, small_cfg, policy):
    """A consumer taking 2.4 frame periods per frame, with only 2 buffers."""
    directory, frames = small_capture
    rewritten = []
    newest_sent = []

    def slow(frame, got):
        newest_sent.append(rig.board.stats.frames_sent)
        time.sleep(2.4 * small_cfg.frame_period_s)
        # The buffer is still ours: nothing may have written into it meanwhile.
        if frame.raw.tobytes() != got[-1].raw:
            rewritten.append(frame.index)

    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        with open_source(rig.url(policy=policy, buffers=2, **URL_TIMEOUTS), small_cfg) as src:
            got = collect(src, 10, timeout=6.0, on_frame=slow)
            dropped = src.describe()["frames_dropped"]

    assert len(got) == 10
    assert not rewritten, f"frames {rewritten} changed while the consumer held them"
    assert_frames_match(got, frames)
    assert all(g.missing_bytes == 0 for g in got)
    indices = [g.index for g in got]
    assert indices == sorted(set(indices)), indices
    assert max(np.diff(indices)) > 1, f"a consumer 2.4x too slow got every frame: {indices}"
    assert dropped > 0
    lag = [sent - 1 - g.index for sent, g in zip(newest_sent, got)]
    if policy == "latest":
        # About the freshest frame there is (the newest one sent, or one before while it completes).
        assert max(lag[1:]) <= 2, f"lag behind the newest frame sent: {lag}"


@pytest.mark.parametrize("policy", ["latest", "queue"])
def test_after_a_consumer_pause_latest_gives_fresh_frames_and_queue_the_unbroken_old_run(
        small_capture, small_cfg, policy):
    """The consumer holds frame 0 for ten frame periods, then reads fast (4 buffers)."""
    directory, frames = small_capture
    sent_at_resume = []

    def pause_once(frame, got):
        if len(got) == 1:
            time.sleep(10 * small_cfg.frame_period_s)
            sent_at_resume.append(rig.board.stats.frames_sent)

    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        with open_source(rig.url(policy=policy, buffers=4, **URL_TIMEOUTS), small_cfg) as src:
            got = collect(src, 4, timeout=5.0, on_frame=pause_once)
            dropped = src.describe()["frames_dropped"]

    assert len(got) == 4
    assert_frames_match(got, frames)
    indices = [g.index for g in got]
    assert dropped > 0
    assert sent_at_resume[0] >= 9, "the board did not stream during the pause"
    if policy == "queue":
        assert indices == [0, 1, 2, 3], indices  # the oldest frames, none skipped
    else:
        assert indices[0] == 0
        assert indices[1:] == list(range(indices[1], indices[1] + 3)), indices  # consecutive
        assert indices[1] >= sent_at_resume[0] - 4, (indices, sent_at_resume)  # and fresh


# ---------------------------------------------------------------------- receive buffer
def _granted_rcvbuf() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, WANTED_RCVBUF)
        return s.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)


def test_frames_larger_than_half_the_receive_buffer_warn_about_rmem_max(small_capture, small_cfg,
                                                                        warnings_log):
    big = config(BIG_CFG, "big.cfg")
    assert big.frame_bytes == 6 * 1024 * 1024
    granted = _granted_rcvbuf()
    if granted >= 2 * big.frame_bytes:
        pytest.skip(f"net.core.rmem_max grants {granted} bytes, enough for two 6 MiB frames: "
                    f"the warning cannot trigger here")
    directory, _ = small_capture
    with EmulatedRig(f"replay://{directory}", config=small_cfg) as rig:
        with open_source(rig.url(buffers=2, **URL_TIMEOUTS), big) as src:
            assert src.describe()["rcvbuf_bytes"] == granted
        assert rig.radar.received[-1] == "sensorStop"
    warned = [m for m in warning_messages(warnings_log) if "rmem_max" in m]
    assert len(warned) == 1, warning_messages(warnings_log)
    assert "sysctl" in warned[0] and str(granted // 1024) in warned[0], warned[0]


# ---------------------------------------------------------------------- recording
def test_pipeline_records_incomplete_frames_with_their_missing_bytes(loss_capture, loss_cfg, tmp_path):
    directory, frames = loss_capture
    out = tmp_path / "rec"
    # Buffers enough that a loaded machine's slow consumer drops no frame: frame k recorded is
    # then the board's frame k (dropped frames are test_live_accounting's subject).
    with EmulatedRig(f"replay://{directory}", config=loss_cfg, faults=Faults(loss=0.1), seed=3) as rig:
        with open_source(rig.url(buffers=64, **URL_TIMEOUTS), loss_cfg) as src:
            writer = CaptureWriter(out, src.config, source=src.url)
            stats = Pipeline(src, sinks=[CaptureSink(writer, src)], max_frames=40).run()
            assert src.describe()["frames_dropped"] == 0
        lost = rig.board.lost_bytes_per_frame

    truth = {k: n for k, n in lost.items() if k < 40}
    assert truth, "the fault injector lost nothing: the test proves nothing"
    assert stats.frames == 40 and stats.reason == "frame limit"
    assert stats.incomplete_frames == len(truth)
    assert stats.missing_bytes == sum(truth.values())

    meta = json.loads((out / "capture.json").read_text())
    assert meta["closed"] is True and meta["frame_count"] == 40
    assert meta["incomplete_frames"] == [{"frame": k, "missing_bytes": truth[k]} for k in sorted(truth)]
    assert meta["lost_bytes"] == sum(truth.values())

    rec = CaptureDirectory(out)
    assert rec.num_frames == 40
    for k in range(40):
        assert rec.missing_bytes(k) == truth.get(k, 0)
        assert frame_problem(rec.raw(k), frames[k % len(frames)], rec.missing_bytes(k)) is None, k
    assert (np.diff(rec.timestamps) > 0).all()


# ---------------------------------------------------------------------- command line
def _check_recording(out, frames, n_frames=None) -> CaptureDirectory:
    rec = CaptureDirectory(out)
    assert rec.metadata["closed"] is True
    if n_frames is not None:
        assert rec.num_frames == n_frames
    assert rec.metadata["frame_count"] == rec.num_frames
    for k in range(rec.num_frames):
        problem = frame_problem(rec.raw(k), frames[k % len(frames)], rec.missing_bytes(k))
        assert problem is None, f"recorded frame {k}: {problem}"
    return rec


def assert_one_period_apart(timestamps, period: float) -> None:
    """No frame skipped or repeated: consecutive stamps more than 0 and less than 1.5 periods
    apart.  A step may be much shorter than a period: the frame clock's grid starts at the
    least receive delay seen so far, which a loaded machine (the first frames delayed by
    several ms) lowers later, shortening that step; it never lengthens one (these captures
    fit in the clock's window), so a skipped frame still shows as two periods."""
    steps = np.diff(timestamps)
    assert ((steps > 0) & (steps < 1.5 * period)).all(), steps


def test_cli_emulate_then_capture_records_the_source_frames(small_capture, tmp_path):
    directory, frames = small_capture
    out = tmp_path / "rec"
    with Emulator("--capture", directory) as emu:
        assert emu.command[:2] == ["radar-capture", "--source"]
        assert emu.command[2].startswith("dca1000://127.0.0.2?")
        assert emu.command[3:] == ["--cfg", os.path.join(directory, "radar.cfg")]
        capture = Process(emu.capture_argv("--record", out, "--frames", 10))
        code = capture.wait(30)
        capture.kill()
        stdout, stderr = capture.output()
        assert code == 0, stderr
        emu_code = emu.stop()
    assert "Traceback" not in stderr
    assert "10 frames (0 incomplete, 0 bytes missing) in" in stdout, stdout
    assert "0 frames dropped by slow processing, 0 packets lost (sequence gaps)" in stdout, stdout
    rec = _check_recording(out, frames, 10)
    assert rec.metadata["incomplete_frames"] == [] and rec.metadata["lost_bytes"] == 0
    assert_one_period_apart(rec.timestamps, 0.05)
    assert emu_code == 0
    emu_out, _ = emu.output()
    assert re.search(r"radar-emulate: sent \d+ frames in \d+ packets \(0 dropped, 0 duplicated, 0 reordered, 0 "
                     r"truncated, 0 replaced by garbage and 0 copied from another address by the fault injector\)",
                     emu_out), emu_out


def test_cli_capture_with_packet_loss_lists_incomplete_frames(loss_capture, tmp_path):
    directory, frames = loss_capture
    out = tmp_path / "rec"
    with Emulator("--capture", directory, "--loss", "0.1", "--seed", "3") as emu:
        # Recording only, with buffers enough: at 100 frames/s even a recording on a loaded
        # 2-core machine dropped a frame (policy latest) in a full-suite run, and this test is
        # about what the recording says of the loss.
        capture = Process(emu.capture_argv("--record", out, "--frames", 40, "--no-odom", "--no-publish",
                                           url_extra="buffers=64"))
        code = capture.wait(30)
        capture.kill()
        stdout, stderr = capture.output()
        assert code == 0, stderr
        assert emu.stop() == 0
    rec = CaptureDirectory(out)
    assert rec.metadata["closed"] is True and rec.num_frames == rec.metadata["frame_count"] == 40
    # Each recorded frame's place in the stream from the stamps' steps (a shortened step, the
    # frame clock's grid moving earlier, is still one frame). A loaded machine may drop whole
    # frames before the recording (the ring's policy): then the recording and the summary count them.
    steps = np.diff(rec.timestamps)
    assert (steps > 0).all(), steps
    place = np.concatenate([[0], np.cumsum(np.maximum(1, np.rint(steps / 0.01)).astype(int))])
    skipped = int(place[-1] + 1 - len(place))
    dropped = rec.metadata.get("dropped_frames", 0)
    assert dropped >= skipped, (dropped, np.flatnonzero(np.diff(place) > 1))
    assert f"; {dropped} frames dropped by slow processing" in stdout, stdout
    first = [j for j in range(len(frames)) if frame_problem(rec.raw(0), frames[j], rec.missing_bytes(0)) is None]
    assert first, "the first recorded frame is none of the source's"
    for k in range(rec.num_frames):
        problem = frame_problem(rec.raw(k), frames[(first[0] + place[k]) % len(frames)], rec.missing_bytes(k))
        assert problem is None, f"recorded frame {k}: {problem}"
    incomplete = rec.metadata["incomplete_frames"]
    assert incomplete, "10 % loss and no incomplete frame"
    assert all(0 < e["missing_bytes"] <= rec.config.frame_bytes for e in incomplete)
    assert rec.metadata["lost_bytes"] == sum(e["missing_bytes"] for e in incomplete)
    lost = rec.metadata["lost_bytes"]
    assert f"40 frames ({len(incomplete)} incomplete, {lost} bytes missing: {lost} lost on the way)" in stdout, stdout
    packets_lost = re.search(r"(\d+) packets lost \(sequence gaps", stdout)
    assert packets_lost and int(packets_lost.group(1)) > 0, stdout
    if not dropped:  # the headers' count agrees with the frames (a dropped frame's lost packets are not theirs)
        assert "packet headers account" not in stdout, stdout
    emu_out, _ = emu.output()
    dropped = re.search(r"\((\d+) dropped", emu_out)
    assert dropped and int(dropped.group(1)) > 0, emu_out


def test_cli_ctrl_c_during_capture_exits_0_with_a_closed_recording(small_capture, tmp_path):
    directory, frames = small_capture
    out = tmp_path / "rec"
    with Emulator("--capture", directory) as emu:
        capture = Process(emu.capture_argv("--record", out))
        stamps = out / "timestamps.txt"
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and capture.proc.poll() is None:
            if stamps.exists() and stamps.read_text().count("\n") >= 4:
                break
            time.sleep(0.05)
        capture.interrupt()
        t0 = time.monotonic()
        code = capture.wait(10)
        elapsed = time.monotonic() - t0
        capture.kill()
        stdout, stderr = capture.output()
        assert emu.stop() == 0
    assert code == 0, stderr
    # The stop waits for the board's RECORD_COMPLETED (2 s after RECORD_STOP, as the real board
    # sends it); wait(10) above is the hang guard.
    assert 2.0 <= elapsed, elapsed
    assert "; stopped; recorded to" in stdout, stdout
    rec = _check_recording(out, frames)
    assert rec.num_frames >= 4


def _wait_for_hung_start(emu: Emulator, capture: Process) -> None:
    """Until the fake radar has received sensorStart (radar-emulate -v says so)."""
    line = emu.stderr.wait_for(lambda ln: "hangs on 'sensorStart'" in ln, timeout=20)
    if line is None:
        capture.kill()
        raise AssertionError("radar-capture never sent sensorStart:\n" + capture.output()[1])


def test_cli_ctrl_c_while_sensor_start_hangs(small_capture, tmp_path):
    """One Ctrl-C while sensorStart waits does not cut the wait short: radar-capture
    gives up after start_timeout, resets the radar through the DCA1000 and exits 1
    (SensorStartHung).  The radar then answers the next session."""
    directory, _ = small_capture
    out = tmp_path / "rec"
    with Emulator("--capture", directory, "--hang-on-start", "-v") as emu:
        capture = Process(emu.capture_argv("--record", out, url_extra="start_timeout=1.5"))
        _wait_for_hung_start(emu, capture)
        capture.interrupt()
        code = capture.wait(10)
        capture.kill()
        _, stderr = capture.output()
        assert code == 1, stderr  # the wait ran out (SensorStartHung), the Ctrl-C did not abort it
        assert "sensorStart got no answer" in stderr and "RESET_AR_DEV" in stderr, stderr
        assert "stopping once the radar has started" in stderr, stderr  # said at the Ctrl-C, not after the wait
        assert "Traceback" not in stderr
        if out.exists():
            rec = CaptureDirectory(out)
            assert rec.num_frames == 0 and rec.metadata["closed"] is True

        # The radar was reset, so a new session configures it (and then hangs at sensorStart again).
        again = Process(emu.capture_argv("--frames", 1, url_extra="start_timeout=0.5"))
        code2 = again.wait(15)
        again.kill()
        _, stderr2 = again.output()
        assert code2 == 1
        assert "sensorStart got no answer" in stderr2, stderr2
        assert emu.stop() == 0


def test_cli_sigterm_while_the_radar_is_set_up_is_handled_as_ctrl_c(small_capture, tmp_path):
    """SIGTERM (a service manager's stop) where a program has no stop handler of its own (here
    radar-calibrate while sensorStart hangs) killed it at once, the radar left configured; now it
    is a Ctrl-C there: the radar is reset through the DCA1000, 'terminated', status 143."""
    import signal

    directory, _ = small_capture
    with Emulator("--capture", directory, "--hang-on-start", "-v") as emu:
        argv = list(emu.command)
        url = argv[argv.index("--source") + 1] + "&start_timeout=30"
        cfg = argv[argv.index("--cfg") + 1] if "--cfg" in argv else None
        calibrate = Process([*console_command("radar-calibrate"), "--source", url, "--distance", "3",
                             "--search-window", "1.2", *(["--cfg", cfg] if cfg else [])])
        _wait_for_hung_start(emu, calibrate)
        calibrate.proc.send_signal(signal.SIGTERM)
        code = calibrate.wait(20)
        calibrate.kill()
        _, stderr = calibrate.output()
        assert code == 143 and "radar-calibrate: terminated" in stderr, stderr
        assert "interrupted during sensorStart" in stderr and "Traceback" not in stderr, stderr


def test_cli_double_ctrl_c_while_sensor_start_hangs_leaves_a_usable_radar(small_capture, tmp_path):
    """Two Ctrl-C abort at once (exit 130, documented in radar_capture.py); the radar
    must still be left answering its CLI for the next session."""
    directory, _ = small_capture
    with Emulator("--capture", directory, "--hang-on-start", "-v") as emu:
        # A start_timeout far longer than the waits below: exit 130 can only come from the abort.
        capture = Process(emu.capture_argv(url_extra="start_timeout=60"))
        _wait_for_hung_start(emu, capture)
        capture.interrupt()
        time.sleep(0.3)
        capture.interrupt()
        code = capture.wait(30)
        capture.kill()
        _, stderr = capture.output()
        assert code == 130, stderr
        # Does the radar answer its CLI again?  (A new session would start with sensorStop.)
        with Awr1843Cli(emu.cli_path, command_timeout_s=0.5) as cli:
            try:
                answer = cli.send("sensorStop").outcome
            except DeviceTimeout as exc:
                answer = f"no answer: {exc}"
        assert emu.stop() == 0
    assert answer in (Outcome.DONE, Outcome.IGNORED), answer


def test_a_second_capture_on_the_same_ports_is_refused():
    # With SO_REUSEADDR both bound: the second reset the board and each stop ended the other's stream.
    from radarodom.driver.live.dca1000 import Dca1000Client, Dca1000Settings
    from radarodom.driver.live.dca1000_receiver import Dca1000Receiver
    from radarodom.driver.live.frame_ring import FrameRing
    from radarodom.errors import DeviceError

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    settings = Dca1000Settings(host_ip="127.0.0.1", board_ip="127.0.0.1", config_port=port, data_port=port)
    first = Dca1000Client(settings).open()
    try:
        with pytest.raises(DeviceError, match=f"127.0.0.1:{port}: .*Another program holds that port"):
            Dca1000Client(settings).open()
        with pytest.raises(DeviceError, match="Another program holds that port"):
            Dca1000Receiver(settings, 1536, FrameRing(1536)).open()
    finally:
        first.close()


def test_a_file_or_folder_given_as_the_cli_port_is_named_as_that(tmp_path):
    # A mistake in the URL, exit 2 as a port that is not there (hunt 5: it was a device's error, exit 1).
    from radarodom.errors import DeviceError, SourceError

    a_file = tmp_path / "radar.cfg"
    a_file.write_text("sensorStop\n")
    for path, kind in ((a_file, "a regular file"), (tmp_path, "a folder")):
        with pytest.raises(SourceError, match=rf"the radar's CLI port {path} is {kind}, not a serial port: give "
                                              r"the XDS110's port \(/dev/ttyACM0, COM3; radar-devices lists them\)"):
            Awr1843Cli(str(path)).open()
    with pytest.raises(DeviceError, match=r"cannot open the radar's CLI port /dev/nonexistent-tty: .*Is the "
                                          r"AWR1843BOOST plugged in"):
        Awr1843Cli("/dev/nonexistent-tty").open()
