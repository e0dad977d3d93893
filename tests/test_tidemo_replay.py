"""Recording the demo's UART stream (driver/tidemo/recording.py) and playing it again, or a serial
logger's file of it, through replay:// (driver/tidemo/replay.py)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver import open_source
from radarodom.driver.emulators.fake_demo_uart import DemoUartRig
from radarodom.driver.tidemo import wire
from radarodom.driver.tidemo.layout import DemoGeometry, gui_selection
from radarodom.driver.tidemo.recording import UartRecorder
from radarodom.errors import CaptureExistsError, CaptureFormatError, ConfigError, SourceError
from radarodom.pipeline import Pipeline

from tidemo_helpers import TIDEMO_CFG


@pytest.fixture(scope="module")
def cfg() -> RadarConfig:
    return RadarConfig.from_text(TIDEMO_CFG, "tidemo.cfg")


def packets(cfg: RadarConfig, numbers) -> list[bytes]:
    g = DemoGeometry.from_config(cfg)
    out = []
    for n in numbers:
        pts = np.zeros(n % 4, wire.POINT_DTYPE)
        pts["y"] = n
        heat = np.zeros((g.range_bins, 8), wire.HEATMAP_DTYPE)
        heat["imag"][n % g.range_bins, 2] = n
        out.append(wire.encode_packet(g.layout(gui_selection(cfg)), n, pts, np.zeros(len(pts), wire.SIDE_INFO_DTYPE),
                                      heat))
    return out


def test_a_serial_loggers_file_plays_with_the_cfgs_period(tmp_path, cfg):
    """``cat /dev/ttyACM1 > uart.bin``: noise from opening the port mid-packet, packets, a lost one,
    one cut short; played with --cfg, frame times from the cfg's period by frame number."""
    p = packets(cfg, range(3, 10))
    data = p[1][100:] + p[1] + p[2] + p[4] + p[5][:-50] + p[6]  # from frame 4; 6 lost, 8 cut short
    path = tmp_path / "uart.bin"
    path.write_bytes(data)
    with pytest.raises(ConfigError, match="give the cfg the radar ran with --cfg"):
        open_source(f"replay://{path}?format=tidemo")
    with open_source(f"replay://{path}?format=tidemo&rate=max", cfg) as source:
        frames = list(source)
        about = source.describe()
    assert [f.index for f in frames] == [0, 1, 3, 5]
    assert [f.points["y"][0] if len(f.points) else None for f in frames] == [None, 5, 7, 9]
    assert [f.timestamp for f in frames] == pytest.approx([0.0, 0.1, 0.3, 0.5])
    assert frames[2].static_antennas[7 % 64, 2] == 7j and frames[2].wire == p[4]
    assert about["frames_skipped"] == 2 and about["rejected_cut_short"] == 1
    assert about["discarded_bytes"] == len(p[1]) - 100 + len(p[5]) - 50


def test_a_demo_stream_given_without_its_format_plays_as_one(tmp_path, cfg):
    """A serial logger's file under any name, replayed with --cfg but without ?format=tidemo, is
    the demo's stream (was decoded as raw ADC samples: made-up odometry and a cut-off warning);
    a directory's capture without that magic word stays raw."""
    from radarodom.driver.sources import REPLAY_FORMAT_MAGIC

    assert REPLAY_FORMAT_MAGIC["tidemo"] == wire.MAGIC
    p = packets(cfg, range(3, 10))
    path = tmp_path / "log.bin"
    path.write_bytes(p[0][50:] + b"".join(p[1:]))  # opened mid-packet
    with open_source(f"replay://{path}?rate=max", cfg) as given, \
            open_source(f"replay://{path}?format=tidemo&rate=max", cfg) as told:
        assert [(f.index, f.wire) for f in given] == [(f.index, f.wire) for f in told]
        assert type(given) is type(told)
    with pytest.raises(ConfigError, match="give the cfg the radar ran with --cfg"):
        open_source(f"replay://{path}")
    raw = tmp_path / "adc.bin"
    raw.write_bytes(bytes(cfg.frame_bytes * 2))
    with open_source(f"replay://{raw}?rate=max", cfg) as source:
        assert len(list(source)) == 2 and type(source).__name__ == "ReplaySource"


def test_timestamps_beside_the_file_are_one_line_per_frame_number(tmp_path, cfg):
    p = packets(cfg, [1, 2, 4])
    (tmp_path / "uart.bin").write_bytes(b"".join(p))
    (tmp_path / "timestamps.txt").write_text("10.0\n10.11\n10.2\n10.32\n")
    with open_source(f"replay://{tmp_path / 'uart.bin'}?format=tidemo&rate=max", cfg) as source:
        assert [(f.index, f.timestamp) for f in source] == [(0, 10.0), (1, 10.11), (3, 10.32)]
    (tmp_path / "timestamps.txt").write_text("10.0\n10.11\n10.2\n")
    with pytest.raises(CaptureFormatError, match="3 lines, but the stream's frame numbers need 4"):
        open_source(f"replay://{tmp_path / 'uart.bin'}?format=tidemo", cfg)
    (tmp_path / "timestamps.txt").write_text("10.0\nnan\n")
    with pytest.raises(CaptureFormatError, match="timestamps.txt:2"):
        open_source(f"replay://{tmp_path / 'uart.bin'}?format=tidemo", cfg)


def test_a_file_without_a_packet_and_a_bad_format_are_refused(tmp_path, cfg):
    (tmp_path / "noise.bin").write_bytes(b"\x00\x01" * 500)
    with pytest.raises(CaptureFormatError, match="no whole demo packet in 1000 bytes"):
        open_source(f"replay://{tmp_path / 'noise.bin'}?format=tidemo", cfg)
    with pytest.raises(SourceError, match="format"):
        open_source(f"replay://{tmp_path / 'noise.bin'}?format=visualizer", cfg)


def test_packets_begun_and_given_up_are_told_apart_from_no_magic_word(tmp_path, cfg):
    """Magic words whose packets' TLVs overrun their length (a length field damaged): said so,
    with the reason and where, not as if the magic word were missing."""
    damaged = b""
    for packet in packets(cfg, range(1, 4)):
        raw = bytearray(packet)
        at = wire.HEADER_DTYPE.itemsize + wire.TL_DTYPE.fields["length"][1]  # the first TLV's length
        raw[at:at + 4] = (0xFFFFFFF0).to_bytes(4, "little")
        damaged += bytes(raw)
    (tmp_path / "damaged.bin").write_bytes(damaged)
    with pytest.raises(CaptureFormatError) as info:
        open_source(f"replay://{tmp_path / 'damaged.bin'}?format=tidemo", cfg)
    assert str(info.value).endswith(f"no whole demo packet in {len(damaged)} bytes: 3 begun with the magic word, "
                                    "all given up (bad TLVs 3; the first at byte 0)"), str(info.value)


def test_a_stream_of_another_radars_demo_says_which_platform_it_is(tmp_path, cfg):
    """Packets whose header names another platform (an xWR68xx's demo: another antenna array)
    were played as the xWR18xx's; one such packet among others is rejected and counted."""
    good = packets(cfg, range(1, 4))
    foreign = [p[:16] + (0xA6843).to_bytes(4, "little") + p[20:] for p in good]
    (tmp_path / "other.bin").write_bytes(b"".join(foreign))
    with pytest.raises(CaptureFormatError) as info:
        open_source(f"replay://{tmp_path / 'other.bin'}?format=tidemo", cfg)
    assert str(info.value).endswith("3 begun with the magic word, all given up (bad header 3; the first at byte 0; "
                                    "the first bad header's platform 0xA6843, not the xWR18xx's 0xA1843 (another "
                                    "radar's demo))"), str(info.value)
    (tmp_path / "one.bin").write_bytes(good[0] + foreign[1] + good[2])
    with open_source(f"replay://{tmp_path / 'one.bin'}?format=tidemo&rate=max", cfg) as source:
        assert [f.index for f in source] == [0, 2]
        assert source.describe()["rejected_packets"] == 1


def test_a_recorded_stream_replays_frame_for_frame(tmp_path, cfg):
    """The live stream recorded by its recorder sink while the pipeline runs the odometry, then
    replay://DIR (its format found by uart.bin, its cfg by radar.cfg): the same frames, indices,
    times, points and static values."""
    out = tmp_path / "rec"
    with DemoUartRig("sim://corridor", boot_time_s=0.05) as rig:
        with open_source(rig.url(), cfg) as source:
            live = []

            class Keep:
                takes_raw, wants_heatmaps, full_heatmaps = True, False, False

                def write_raw(self, frame, stats):
                    live.append(frame)

                def close(self, stats):
                    pass

            with Pipeline(source, sinks=[source.recorder(str(out)), Keep()], max_frames=12) as pipe:
                pipe.run()
    assert sorted(os.listdir(out)) == ["capture.json", "radar.cfg", "timestamps.txt", "uart.bin"]
    assert RadarConfig.from_file(out / "radar.cfg") == cfg
    with open_source(f"replay://{out}?rate=max") as replay:
        played = list(replay)
    assert len(played) == len(live) == 12
    for a, b in zip(live, played):
        assert (a.index, a.wire) == (b.index, b.wire)
        assert a.timestamp == pytest.approx(b.timestamp, abs=1e-9)
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.static_antennas, b.static_antennas)
    with pytest.raises(CaptureExistsError):
        UartRecorder(out, cfg)
    # Given a cfg of other packets (hunt 5): "frame 1: ... the radar runs another cfg than the one
    # given", of a replay; the same cfg given is taken.
    other = RadarConfig.from_file(shipped_config_path())
    with pytest.raises(ConfigError) as info:
        open_source(f"replay://{out}?rate=max", other)
    assert str(info.value) == (
        f"{other.path}: the cfg given makes the demo's packets of 256 range bins, 64 Doppler bins and 8 antennas, "
        f"and {out / 'radar.cfg'}, which the radar ran, of 64 range bins, 16 Doppler bins and 8 antennas: leave "
        "the cfg out (the recording's is used) or give the one it was recorded with"), info.value
    with open_source(f"replay://{out}?rate=max&frames=2", cfg) as replay:
        assert len(list(replay)) == 2


def test_lost_frames_keep_their_timestamp_lines(tmp_path, cfg):
    p = packets(cfg, [5, 6, 9])
    rec = UartRecorder(tmp_path / "rec", cfg, source="test")
    for data, index, t in zip(p, (0, 1, 4), (1.0, 1.1, 1.4)):
        rec.write_packet(data, index, t)
    rec.close()
    lines = (tmp_path / "rec" / "timestamps.txt").read_text().split()
    assert [float(x) for x in lines] == pytest.approx([1.0, 1.1, 1.2, 1.3, 1.4])
    with open_source(f"replay://{tmp_path / 'rec'}?rate=max") as source:
        assert [(f.index, round(f.timestamp, 9)) for f in source] == [(0, 1.0), (1, 1.1), (4, 1.4)]
    empty = UartRecorder(tmp_path / "none", cfg)
    empty.close()
    assert not (tmp_path / "none").exists()  # a recording of nothing is removed


def lossy_file(tmp_path, cfg):
    """The packets of frames 3-9 and a serial logger's file of them: a cut one's end first, then
    frames 4, 5 and 7, 8 cut short, 9, and 3's start cut at the end (frame numbers 6 and 8 lost)."""
    p = packets(cfg, range(3, 10))
    path = tmp_path / "uart.bin"
    path.write_bytes(p[1][100:] + p[1] + p[2] + p[4] + p[5][:-50] + p[6] + p[0][:60])
    return p, path


@pytest.mark.parametrize("played, skipped, cut_short", [(2, 0, 0), (3, 1, 0), (4, 2, 1)])
def test_a_run_stopped_early_tells_what_the_part_it_played_lost(tmp_path, cfg, played, skipped, cut_short):
    """radar-capture --duration on a replay said the whole file's frame numbers skipped, packets
    rejected and bytes discarded, however little of it was played."""
    p, path = lossy_file(tmp_path, cfg)
    garbage = len(p[1]) - 100
    with open_source(f"replay://{path}?format=tidemo&rate=max", cfg) as source:
        with Pipeline(source, sinks=[], max_frames=played) as pipe:
            assert pipe.run().frames == played
        about = source.describe()
    assert about["frames"] == 4 and about["packets"] == played and about["frames_skipped"] == skipped
    assert about["rejected_packets"] == about.get("rejected_cut_short", 0) == cut_short
    assert about["discarded_bytes"] == garbage + (len(p[5]) - 50 if cut_short else 0)
    assert about["packet_bytes"] == sum(len(q) for q in [p[1], p[2], p[4], p[6]][:played])


def test_each_pass_of_a_looped_replay_counts_the_files_losses_and_a_cut_selection_its_own(tmp_path, cfg):
    p, path = lossy_file(tmp_path, cfg)
    with open_source(f"replay://{path}?format=tidemo&rate=max&loop=2", cfg) as source:
        assert len(list(source)) == 8
        about = source.describe()
    assert about["packets"] == 8 and about["frames_skipped"] == 4
    assert about["rejected_cut_short"] == about["rejected_cut_at_end"] == 2 and about["rejected_packets"] == 4
    assert about["discarded_bytes"] == 2 * (len(p[1]) - 100 + len(p[5]) - 50 + 60)
    with open_source(f"replay://{path}?format=tidemo&rate=max&loop=2&frames=3", cfg) as source:
        assert len(list(source)) == 6
        about = source.describe()
    assert about["packets"] == 6 and about["frames_skipped"] == 2 and about["rejected_packets"] == 0
    assert about["discarded_bytes"] == 2 * (len(p[1]) - 100)


_RECORD_SCRIPT = """
import os, sys
from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.tidemo.recording import UartRecorder
from radarodom.errors import CaptureError
src, out, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
try:
    recorder = UartRecorder(out, RadarConfig.from_file(os.path.join(src, "radar.cfg")))
except CaptureError as exc:
    sys.exit(str(exc))
try:
    for i in range(n):
        with open(os.path.join(src, f"{i}.bin"), "rb") as fh:
            recorder.write_packet(fh.read(), i, 100.0 + 0.1 * i)
except CaptureError as exc:
    print(exc)
recorder.close()
"""


def _record_with_room_for(tmp_path, cfg, n: int, limit: int) -> subprocess.CompletedProcess:
    """UartRecorder records *n* packets into tmp_path/rec in a process whose files may hold at
    most *limit* bytes (a full disk, as the process's file-size limit)."""
    import resource
    import signal

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    src = tmp_path / "in"
    src.mkdir()
    (src / "radar.cfg").write_text(cfg.to_text())
    for i, data in enumerate(packets(cfg, range(1, n + 1))):
        (src / f"{i}.bin").write_bytes(data)
    return subprocess.run([sys.executable, "-c", _RECORD_SCRIPT, str(src), str(tmp_path / "rec"), str(n)],
                          capture_output=True, text=True, timeout=120, preexec_fn=small_files)


def test_a_recording_that_runs_out_of_room_keeps_whole_packets_and_plays(tmp_path, cfg):
    """A full disk mid-packet left the packet's first part in uart.bin (and said only 'No space
    left on device')."""
    sizes = [len(data) for data in packets(cfg, range(1, 9))]
    proc = _record_with_room_for(tmp_path, cfg, 8, sum(sizes[:3]) + sizes[3] // 2)
    out = tmp_path / "rec"
    assert proc.stdout == (f"{out}: writing frame 3's packet failed: File too large; free some space, or choose "
                           "another disk; the 3 frames before it are kept\n"), proc.stdout + proc.stderr
    assert (out / "uart.bin").stat().st_size == sum(sizes[:3])
    with open_source(f"replay://{out}?rate=max") as replay:
        played = list(replay)
        assert replay.describe()["rejected_packets"] == 0
    assert [f.index for f in played] == [0, 1, 2]


def test_a_recording_that_cannot_start_leaves_nothing(tmp_path, cfg):
    """No room for the cfg: capture.json and a cut radar.cfg were left (and the error was a
    ConfigError, exit 2)."""
    proc = _record_with_room_for(tmp_path, cfg, 2, 500)
    assert len(cfg.to_text()) > 500
    assert proc.returncode == 1 and proc.stderr.startswith(f"cannot create recording directory {tmp_path / 'rec'}: "
                                                           "File too large; free some space"), proc.stderr
    assert not (tmp_path / "rec").exists()


def _recorded(directory, cfg, numbers) -> None:
    recorder = UartRecorder(directory, cfg)
    for k, (n, data) in enumerate(zip(numbers, packets(cfg, numbers))):
        recorder.write_packet(data, n - numbers[0], 100.0 + 0.1 * (n - numbers[0]))
    recorder.close()


def _edit_metadata(directory, **changes) -> None:
    import json

    meta = json.loads((directory / "capture.json").read_text())
    meta.update(changes)
    (directory / "capture.json").write_text(json.dumps(meta))


@pytest.mark.parametrize("damage, where, words", [
    (lambda d: os.truncate(d / "uart.bin", (d / "uart.bin").stat().st_size - 200), "uart.bin",
     "4 whole packets, but capture.json says the recording holds 5: the file was cut short or changed"),
    (lambda d: _edit_metadata(d, packets=99), "uart.bin",
     "5 whole packets, but capture.json says the recording holds 99"),
    (lambda d: (d / "timestamps.txt").write_text("100.0\n100.1\n"), "timestamps.txt",
     "2 lines, but the stream's frame numbers need 6"),
    (lambda d: (d / "timestamps.txt").write_text("".join(f"{100 + k / 10}\n" for k in range(8))), "timestamps.txt",
     "8 lines, but capture.json says the recording wrote 6"),
    (lambda d: (d / "timestamps.txt").unlink(), "timestamps.txt", "no such file: the recording's frame times are in it"),
    (lambda d: _edit_metadata(d, baud=-5), "capture.json", "baud: expected a whole number > 0 or null, got -5"),
    (lambda d: _edit_metadata(d, packets="5"), "capture.json", "packets: expected a whole number >= 0, got '5'"),
    # Each named for what it is (the raw capture's words were said of a demo recording's files).
    (lambda d: (d / "uart.bin").unlink(), "", "no uart.bin: the demo UART recording's stream is missing"),
    (lambda d: ((d / "uart.bin").unlink(), (d / "uart.bin").mkdir()), "uart.bin", "is a directory"),
    (lambda d: ((d / "capture.json").unlink(), (d / "capture.json").mkdir()), "capture.json", "is a directory"),
    (lambda d: ((d / "timestamps.txt").unlink(), (d / "timestamps.txt").mkdir()), "timestamps.txt",
     "is a directory"),
    (lambda d: (d / "capture.json").write_text("[]"), "capture.json", "expected a JSON object, got list"),
    (lambda d: (d / "capture.json").write_text('{"packets": 5}'), "capture.json", "format: missing"),
    (lambda d: (d / "capture.json").write_text('{"format": '), "capture.json", "repair it or move it away"),
    (lambda d: _edit_metadata(d, format_version=10 ** 300), "capture.json", "format_version 10000000000000000"),
])
def test_a_damaged_recording_is_refused_naming_the_file(tmp_path, cfg, damage, where, words):
    """A closed recording whose uart.bin was cut short played its packets left (exit 0, 'rejected'
    in the summary); without timestamps.txt it was timed anew by the cfg; capture.json's counts
    were not read.  The raw capture refuses the same damage."""
    rec = tmp_path / "rec"
    _recorded(rec, cfg, [3, 4, 5, 7, 8])  # frame number 6 lost on the line: six frame lines
    with open_source(f"replay://{rec}?rate=max") as source:  # intact: plays
        assert [f.index for f in source] == [0, 1, 2, 4, 5]
    damage(rec)
    with pytest.raises(CaptureFormatError) as info:
        open_source(f"replay://{rec}?rate=max")
    assert str(info.value).startswith(f"{rec / where}: " if where else f"{rec}: ") and words in str(info.value), \
        str(info.value)
    assert len(str(info.value)) < 400


def test_a_recording_without_its_cfg_says_so(tmp_path, cfg):
    rec = tmp_path / "rec"
    _recorded(rec, cfg, [3, 4])
    (rec / "radar.cfg").unlink()
    with pytest.raises(ConfigError) as info:
        open_source(f"replay://{rec}?rate=max")
    assert str(info.value) == (f"{rec}: no radar.cfg: the recording's cfg is missing; put it back, or give the cfg "
                               "the radar ran with --cfg (open_source(url, config) in Python)")
    with open_source(f"replay://{rec}?rate=max", cfg) as source:
        assert len(list(source)) == 2


def test_a_recording_whose_process_died_plays_what_it_holds(tmp_path, cfg, caplog):
    """Not closed: capture.json's counts lag its files (saved every ten packets) and are not held against them."""
    rec = tmp_path / "rec"
    _recorded(rec, cfg, [3, 4, 5])
    _edit_metadata(rec, closed=False, packets=1, frame_lines=1)
    with open_source(f"replay://{rec}?rate=max") as source:
        assert len(list(source)) == 3
    assert "was not closed" in caplog.text


def test_a_garbled_frame_number_continues_the_indices(tmp_path, cfg, caplog):
    # A flipped byte read as frame 4 000 000 005 made the replay ask for 30 GB of timestamps.
    p = packets(cfg, [3, 4, 5, 6, 7, 60])
    garbled = bytearray(p[2])
    garbled[20:24] = (4_000_000_005).to_bytes(4, "little")  # the header's frameNumber
    path = tmp_path / "uart.bin"
    path.write_bytes(p[0] + p[1] + bytes(garbled) + p[3] + p[4] + p[5])
    with caplog.at_level("WARNING"), open_source(f"replay://{path}?format=tidemo&rate=max", cfg) as source:
        frames = list(source)
        about = source.describe()
    assert [f.index for f in frames] == [0, 1, 2, 3, 4, 57]  # a real gap (52 frames lost) still counts
    assert about["frames_skipped"] == 52
    said = [r.getMessage() for r in caplog.records if "frame number" in r.getMessage()]
    assert said[0] == ("frame number 4000000005 after 4: a leap of more than 1048576 frames: a garbled header or "
                       "another run; indices continue") and "after 4000000005: the radar restarted" in said[1]


def test_points_the_chip_cannot_have_measured_are_left_out_naming_the_packet(tmp_path, cfg, caplog):
    import warnings

    g = DemoGeometry.from_config(cfg)
    pts = np.zeros(4, wire.POINT_DTYPE)
    pts["y"], pts["velocity"] = [1.0, 2.0, 3.0, 4.0], [0.5, -0.5, 0.25, 0.0]
    pts["x"][1], pts["y"][2], pts["velocity"][3] = 1e30, np.nan, np.inf
    side = np.zeros(4, wire.SIDE_INFO_DTYPE)
    side["snr"] = [100, 200, 300, 400]
    heat = np.zeros((g.range_bins, 8), wire.HEATMAP_DTYPE)
    first = packets(cfg, [1])[0]
    path = tmp_path / "uart.bin"
    path.write_bytes(first + wire.encode_packet(g.layout(gui_selection(cfg)), 2, pts, side, heat))
    with warnings.catch_warnings(), caplog.at_level("WARNING"):
        warnings.simplefilter("error")  # numpy's overflow and cast warnings were printed with a source line
        with open_source(f"replay://{path}?format=tidemo&rate=max", cfg) as source:
            frames = list(source)
    kept = frames[1].points
    assert kept["y"].tolist() == [1.0] and kept["snr_db"].tolist() == [10.0]
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 1 and said[0].startswith(f"frame 2 (the packet at byte {len(first)} of its stream): 3 of 4 "
                                                 "points hold NaN, inf or values past"), said
