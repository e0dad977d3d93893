"""Capture directories: CaptureWriter / CaptureDirectory round trip, damaged
directories, and crash safety against a real process killed with SIGKILL."""

from __future__ import annotations

import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import SMALL_CFG, make_capture, random_frames, warning_messages

import radarodom
from radarodom.cfg import RadarConfig
from radarodom.driver.recordings.capture_dir import CaptureDirectory, CaptureWriter
from radarodom.driver.sources import open_source
from radarodom.errors import CaptureError, CaptureExistsError, CaptureFormatError, ConfigError
from radarodom.tum import read_tum

T0 = 1000.0
PERIOD = 0.05  # SMALL_CFG frame period


def _files(directory) -> dict[str, bytes]:
    return {name: open(os.path.join(directory, name), "rb").read() for name in sorted(os.listdir(directory))}


# --------------------------------------------------------------- round trip

def test_round_trip(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    before = time.time()
    frames = make_capture(d, small_cfg, 10, t0=T0, incomplete={2: 100, 7: 3072}, poses=True)
    after = time.time()
    assert sorted(os.listdir(d)) == ["adc_data.bin", "capture.json", "groundtruth.tum",
                                     "radar.cfg", "timestamps.txt"]
    assert (d / "adc_data.bin").read_bytes() == b"".join(frames)

    cap = CaptureDirectory(d)
    assert len(cap) == cap.num_frames == 10
    assert cap.config.frame_bytes == small_cfg.frame_bytes == 3072
    assert cap.config.cube_shape == small_cfg.cube_shape
    assert cap.layout.shape == (4, 3, 4, 16)
    for i, raw in enumerate(frames):
        got = cap.raw(i)
        assert got.dtype == np.uint8 and got.shape == (3072,)
        assert bytes(got) == raw
        assert not got.flags.writeable
    np.testing.assert_allclose(cap.timestamps, T0 + PERIOD * np.arange(10), rtol=0, atol=1e-9)
    assert [cap.missing_bytes(i) for i in range(10)] == [0, 0, 100, 0, 0, 0, 0, 3072, 0, 0]
    for i in range(10):
        assert cap.pose(i) == pytest.approx((0.1 * i, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0))
    np.testing.assert_allclose(cap.groundtruth.times, cap.timestamps, atol=1e-9)
    with pytest.raises(IndexError):
        cap.raw(10)
    with pytest.raises(IndexError):
        cap.raw(-1)

    meta = json.loads((d / "capture.json").read_text())
    assert meta == cap.metadata
    assert meta["format"] == "radarodom-capture"
    assert meta["format_version"] == 1
    assert meta["software"] == f"radarodom {radarodom.__version__}"
    assert meta["source"] == "test"
    assert before - 1 <= meta["start_time_unix"] <= after + 1
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\dZ", meta["start_time"])
    assert meta["start_time"] == time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(meta["start_time_unix"]))
    assert meta["frame_bytes"] == 3072
    assert meta["frame_count"] == 10
    assert meta["first_timestamp"] == pytest.approx(T0)
    assert meta["last_timestamp"] == pytest.approx(T0 + 9 * PERIOD)
    assert meta["incomplete_frames"] == [{"frame": 2, "missing_bytes": 100},
                                         {"frame": 7, "missing_bytes": 3072}]
    assert meta["lost_bytes"] == 3172
    assert meta["closed"] is True
    assert warning_messages(warnings_log) == []


def test_text_files_format(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 3, t0=T0, poses=True)
    lines = (d / "timestamps.txt").read_text().splitlines()
    assert [float(x) for x in lines] == pytest.approx([T0, T0 + PERIOD, T0 + 2 * PERIOD], abs=1e-9)
    tum = [line.split() for line in (d / "groundtruth.tum").read_text().splitlines()]
    assert all(len(row) == 8 for row in tum)
    assert float(tum[2][0]) == pytest.approx(T0 + 2 * PERIOD) and float(tum[2][1]) == pytest.approx(0.2)
    gt = read_tum(d / "groundtruth.tum")
    assert gt.positions.shape == (3, 3) and gt.quaternions.shape == (3, 4)
    # radar.cfg is the configuration itself
    assert RadarConfig.from_file(d / "radar.cfg").cube_shape == small_cfg.cube_shape


def test_no_groundtruth_without_poses(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 2)
    assert not (d / "groundtruth.tum").exists()
    cap = CaptureDirectory(d)
    assert cap.groundtruth is None and cap.pose(0) is None


def test_poses_stay_with_their_frames_when_some_are_missing(tmp_path, small_cfg):
    d = tmp_path / "cap"
    frames = random_frames(small_cfg, 4)
    poses = [(1.0, 0, 0, 0, 0, 0, 1), None, (3.0, 0, 0, 0, 0, 0, 1), (4.0, 0, 0, 0, 0, 0, 1)]
    with CaptureWriter(d, small_cfg) as w:
        for i, (raw, pose) in enumerate(zip(frames, poses)):
            w.write(raw, T0 + PERIOD * i, pose=pose)
    cap = CaptureDirectory(d)
    assert cap.pose(0) == pytest.approx(poses[0])
    assert cap.pose(1) is None
    assert cap.pose(2) == pytest.approx(poses[2])
    assert cap.pose(3) == pytest.approx(poses[3])


def test_writer_extra_metadata_and_frame_count(tmp_path, small_cfg):
    frames = random_frames(small_cfg, 3)
    with CaptureWriter(tmp_path / "c", small_cfg, source="replay://x", extra={"operator": "me"}) as w:
        for i, raw in enumerate(frames):
            assert w.frame_count == i
            w.write(raw, float(i))
        assert w.frame_count == 3
    meta = json.loads((tmp_path / "c" / "capture.json").read_text())
    assert meta["operator"] == "me" and meta["source"] == "replay://x" and meta["frame_count"] == 3


def test_incomplete_frames_reach_capture_json_at_once(tmp_path, small_cfg, warnings_log):
    """A frame with lost bytes is listed in capture.json before the next write,
    so a crash cannot lose that information."""
    d = tmp_path / "c"
    frames = random_frames(small_cfg, 3)
    w = CaptureWriter(d, small_cfg, metadata_interval_s=3600)
    w.write(frames[0], 1.0)
    w.write(frames[1], 1.05, missing_bytes=1456)
    w.write(frames[2], 1.10)
    meta = json.loads((d / "capture.json").read_text())
    assert meta["incomplete_frames"] == [{"frame": 1, "missing_bytes": 1456}]
    assert meta["closed"] is False
    cap = CaptureDirectory(d)  # readable while still open
    assert cap.num_frames == 3 and cap.missing_bytes(1) == 1456
    assert bytes(cap.raw(2)) == frames[2]
    assert any("not closed" in m for m in warning_messages(warnings_log))
    w.close()
    w.close()  # idempotent
    assert json.loads((d / "capture.json").read_text())["closed"] is True
    with pytest.raises(CaptureError):
        w.write(frames[0], 2.0)


def test_writer_refuses_existing_capture(tmp_path, small_cfg, shipped_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 4, poses=True)
    before = _files(d)
    with pytest.raises(CaptureExistsError) as info:
        CaptureWriter(d, shipped_cfg, source="second")
    assert info.value.exit_code == 2
    assert isinstance(info.value, CaptureError)
    assert str(d) in str(info.value)
    assert _files(d) == before  # radar.cfg, capture.json, data: all untouched
    assert CaptureDirectory(d).num_frames == 4


def test_writer_accepts_existing_empty_directory(tmp_path, small_cfg):
    d = tmp_path / "empty"
    d.mkdir()
    make_capture(d, small_cfg, 1)
    assert CaptureDirectory(d).num_frames == 1


def test_writer_rejects_wrong_frame_size(tmp_path, small_cfg):
    d = tmp_path / "c"
    with CaptureWriter(d, small_cfg) as w:
        w.write(bytes(3072), 0.0)
        for n in (3071, 3073, 0, 6144):
            with pytest.raises(CaptureFormatError) as info:
                w.write(bytes(n), 1.0)
            assert str(n) in str(info.value) and "3072" in str(info.value)
        assert w.frame_count == 1
    assert (d / "adc_data.bin").stat().st_size == 3072
    assert len((d / "timestamps.txt").read_text().splitlines()) == 1
    assert CaptureDirectory(d).num_frames == 1


def test_writer_cannot_create_directory(tmp_path, small_cfg):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(CaptureError):
        CaptureWriter(blocker / "cap", small_cfg)


# --------------------------------------------------------------- damaged directories

def _crashed(d, **changes) -> None:
    """Make capture.json say what it says while the writer runs (not closed), as a kill leaves it."""
    meta = json.loads((d / "capture.json").read_text())
    meta.update(closed=False, **changes)
    (d / "capture.json").write_text(json.dumps(meta))


def test_cut_off_frame_of_a_crashed_capture_is_ignored_with_warning(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    frames = make_capture(d, small_cfg, 6)
    _crashed(d)
    with open(d / "adc_data.bin", "ab") as fh:
        fh.write(b"\x55" * 1536)  # half a frame: the writer was killed in the middle of it
    cap = CaptureDirectory(d)
    assert cap.num_frames == 6
    assert [bytes(cap.raw(i)) for i in range(6)] == frames
    warnings = warning_messages(warnings_log)
    assert any("not closed" in m and "6 whole frames" in m and "1536 bytes of a cut-off frame" in m
               for m in warnings), warnings


def test_a_crashed_capture_of_one_frame_says_frame(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 1)
    _crashed(d)
    assert CaptureDirectory(d).num_frames == 1
    assert any(m.endswith("playing its 1 whole frame") for m in warning_messages(warnings_log))  # was "frames"


def test_cut_off_frame_without_capture_json_is_ignored_with_warning(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    frames = make_capture(d, small_cfg, 6)
    os.remove(d / "capture.json")
    with open(d / "adc_data.bin", "ab") as fh:
        fh.write(b"\x55" * 1536)
    cap = CaptureDirectory(d)
    assert [bytes(cap.raw(i)) for i in range(cap.num_frames)] == frames
    assert any("1536 bytes of a cut-off frame" in m for m in warning_messages(warnings_log))


@pytest.mark.parametrize("extra", [1536, 3072, 3 * 3072 + 5])
def test_data_appended_to_a_closed_capture_is_refused(tmp_path, small_cfg, extra):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 6)
    with open(d / "adc_data.bin", "ab") as fh:
        fh.write(b"\x55" * extra)
    with pytest.raises(CaptureFormatError) as info:
        CaptureDirectory(d)
    message = str(info.value)
    assert str(d) in message and "closed recording has 6 frames" in message, message
    assert f"{6 * 3072 + extra} bytes" in message and "appended" in message, message


def test_partial_last_timestamp_line_is_ignored(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 6, t0=T0)
    _crashed(d)
    with open(d / "adc_data.bin", "ab") as fh:
        fh.write(b"\x55" * 100)  # a seventh frame begun ...
    with open(d / "timestamps.txt", "a") as fh:
        fh.write("1000.3")  # ... and its line cut short (not the writer's order, but harmless)
    cap = CaptureDirectory(d)
    np.testing.assert_allclose(cap.timestamps, T0 + PERIOD * np.arange(6), atol=1e-9)
    assert any("partly written" in m for m in warning_messages(warnings_log))


def test_a_closed_recordings_last_timestamp_line_without_its_end_of_line_is_read(tmp_path, small_cfg,
                                                                                 warnings_log):
    """An editor that saves without a final newline made the closed recording's last line 'partly
    written': ignored with a warning, then 'the files disagree' (5 lines for 6 frames)."""
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 6, t0=T0)
    path = d / "timestamps.txt"
    path.write_bytes(path.read_bytes().rstrip(b"\n"))
    cap = CaptureDirectory(d)
    np.testing.assert_allclose(cap.timestamps, T0 + PERIOD * np.arange(6), atol=1e-9)
    assert warning_messages(warnings_log) == []
    path.write_bytes(path.read_bytes() + b"x")  # what it holds is still checked
    with pytest.raises(CaptureFormatError, match=r"timestamps\.txt:6: "):
        CaptureDirectory(d)


def test_cut_timestamp_of_last_frame_is_extrapolated(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 6, t0=T0)
    _crashed(d, frame_count=5)
    text = (d / "timestamps.txt").read_text()
    (d / "timestamps.txt").write_text(text[:-8])  # the last line loses its end
    cap = CaptureDirectory(d)
    assert cap.num_frames == 6
    np.testing.assert_allclose(cap.timestamps, T0 + PERIOD * np.arange(6), atol=1e-9)
    assert any("last frame has no timestamp" in m for m in warning_messages(warnings_log))


@pytest.mark.parametrize("closed", [True, False])
def test_frames_without_timestamps_are_refused(tmp_path, small_cfg, closed):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 6, t0=T0)
    if not closed:
        _crashed(d, frame_count=3)
    lines = (d / "timestamps.txt").read_text().splitlines(keepends=True)
    (d / "timestamps.txt").write_text("".join(lines[:3]))
    with pytest.raises(CaptureFormatError) as info:
        CaptureDirectory(d)
    message = str(info.value)
    assert "timestamps.txt has 3 lines" in message and "6 frames" in message, message


def test_no_timestamps_file_without_capture_json_starts_at_zero(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 4, t0=T0)
    os.remove(d / "timestamps.txt")
    os.remove(d / "capture.json")
    cap = CaptureDirectory(d)
    np.testing.assert_allclose(cap.timestamps, PERIOD * np.arange(4), atol=1e-12)


def test_no_timestamps_file_with_capture_json_is_refused(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 4, t0=T0)
    os.remove(d / "timestamps.txt")
    with pytest.raises(CaptureFormatError, match="timestamps.txt is missing, capture.json counts 4 frames"):
        CaptureDirectory(d)


def test_extra_timestamps_are_refused(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 4, t0=T0)
    with open(d / "timestamps.txt", "a") as fh:
        fh.write("2000.0\n2000.05\n")
    with pytest.raises(CaptureFormatError, match=r"timestamps.txt:5: more lines than the 4 whole frames"):
        CaptureDirectory(d)


def test_garbage_timestamp_line_is_an_error(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 2)
    (d / "timestamps.txt").write_text("1000.0\nhello\n")
    with pytest.raises(CaptureFormatError, match="timestamps.txt:2"):
        CaptureDirectory(d)


def test_missing_capture_json_still_readable(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    frames = make_capture(d, small_cfg, 5, incomplete={1: 10})
    os.remove(d / "capture.json")
    cap = CaptureDirectory(d)
    assert cap.metadata == {}
    assert cap.num_frames == 5
    assert [bytes(cap.raw(i)) for i in range(5)] == frames
    assert cap.missing_bytes(1) == 0  # the record of the loss went with capture.json
    assert warning_messages(warnings_log) == []


def test_unreadable_capture_json_is_refused(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 3)
    (d / "capture.json").write_text('{"format": "radarodom-capt')
    with pytest.raises(CaptureFormatError) as info:
        CaptureDirectory(d)
    message = str(info.value)
    assert f"{d / 'capture.json'}: not JSON" in message and "move it away" in message, message


def test_not_closed_capture_warns(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    frames = make_capture(d, small_cfg, 3)
    meta = json.loads((d / "capture.json").read_text())
    meta["closed"] = False
    (d / "capture.json").write_text(json.dumps(meta))
    cap = CaptureDirectory(d)
    assert [bytes(cap.raw(i)) for i in range(3)] == frames
    assert any("not closed" in m for m in warning_messages(warnings_log))


def test_fewer_poses_than_frames_warns(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 4, poses=True)
    lines = (d / "groundtruth.tum").read_text().splitlines(keepends=True)
    (d / "groundtruth.tum").write_text("".join(lines[:2]) + lines[2][:10])  # third pose cut
    cap = CaptureDirectory(d)
    assert cap.pose(1) == pytest.approx((0.1, 0, 0, 0, 0, 0, 1))
    assert cap.pose(2) is None and cap.pose(3) is None
    assert any("no pose for 2 of 4 frames" in m for m in warning_messages(warnings_log))


def test_missing_radar_cfg(tmp_path, small_cfg):
    d = tmp_path / "cap"
    frames = make_capture(d, small_cfg, 2)
    os.remove(d / "radar.cfg")
    with pytest.raises(ConfigError) as info:
        CaptureDirectory(d)
    assert info.value.exit_code == 2
    cap = CaptureDirectory(d, small_cfg)
    assert bytes(cap.raw(1)) == frames[1]


def test_not_a_capture_directory(tmp_path, small_cfg):
    with pytest.raises(CaptureError):
        CaptureDirectory(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(CaptureFormatError):
        CaptureDirectory(tmp_path / "empty")


def test_given_config_with_other_frames_is_refused(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 4)
    half = RadarConfig.from_text(SMALL_CFG.replace("0 96 1 16 8000", "0 96 1 8 8000"), "half.cfg")
    with pytest.raises(CaptureFormatError) as info:
        CaptureDirectory(d, half)
    assert "half.cfg makes frames of 1536 bytes, capture.json says the recording's are 3072" in str(info.value)


def test_given_config_without_capture_json_overrides_recorded(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    frames = make_capture(d, small_cfg, 4)
    os.remove(d / "capture.json")
    os.remove(d / "timestamps.txt")
    half = RadarConfig.from_text(SMALL_CFG.replace("0 96 1 16 8000", "0 96 1 8 8000"), "half.cfg")
    cap = CaptureDirectory(d, half)
    assert cap.config is half
    assert cap.num_frames == 8
    assert bytes(cap.raw(1)) == frames[0][1536:]
    assert any("differs" in m for m in warning_messages(warnings_log))


# --------------------------------------------------------------- hostile files (issue 18)

def _set_meta_text(d, text: str) -> None:
    (d / "capture.json").write_text(text)


def _meta_with(d, **changes) -> str:
    meta = json.loads((d / "capture.json").read_text())
    meta.update(changes)
    return json.dumps(meta)


def _meta_entry(d, **entry) -> str:
    return _meta_with(d, incomplete_frames=[{"frame": 1, "missing_bytes": 10, **entry}], lost_bytes=10)


# Each case: capture.json's text made from the 6-frame capture in d, and what the message says.
BAD_METADATA = {
    "incomplete-frames-a-number": (lambda d: _meta_with(d, incomplete_frames=5),
                                   "incomplete_frames: expected a list"),
    "frame-a-string": (lambda d: _meta_entry(d, frame="x"), "incomplete_frames[0].frame: expected an integer"),
    "frame-nan": (lambda d: _meta_entry(d).replace('"frame": 1', '"frame": NaN'), "NaN is not a number JSON"),
    "frame-past-the-count": (lambda d: _meta_entry(d, frame=6), "incomplete_frames[0].frame: expected an "
                                                                  "integer from 0 to 5, got 6"),
    "frames-out-of-order": (lambda d: _meta_with(d, incomplete_frames=[{"frame": 3, "missing_bytes": 1},
                                                                       {"frame": 3, "missing_bytes": 1}]),
                            "incomplete_frames[1].frame: expected an integer from 4 to 5, got 3"),
    "missing-bytes-a-list": (lambda d: _meta_entry(d, missing_bytes=[1]),
                             "incomplete_frames[0].missing_bytes: expected an integer from 1 to 3072, got [1]"),
    "missing-bytes-negative": (lambda d: _meta_entry(d, missing_bytes=-5),
                               "incomplete_frames[0].missing_bytes: expected an integer from 1 to 3072, got -5"),
    "missing-bytes-absurd": (lambda d: _meta_entry(d, missing_bytes=99999999999),
                             "missing_bytes: expected an integer from 1 to 3072, got 99999999999"),
    "missing-bytes-a-float": (lambda d: _meta_entry(d, missing_bytes=10.0), "expected an integer from 1 to 3072"),
    "missing-bytes-true": (lambda d: _meta_entry(d, missing_bytes=True), "expected an integer from 1 to 3072"),
    "cut-beyond-missing": (lambda d: _meta_entry(d, cut_bytes=11),
                           "incomplete_frames[0].cut_bytes: expected an integer from 0 to 10, got 11"),
    "lost-bytes-disagree": (lambda d: _meta_with(d, lost_bytes=99999999994),
                            "lost_bytes: expected 0, the sum of the missing_bytes"),
    "entry-not-an-object": (lambda d: _meta_with(d, incomplete_frames=[[1, 2]]),
                            "incomplete_frames[0]: expected an object"),
    "nested-200000-deep": (lambda d: "[" * 200_000, "nested 200000 deep, more than the 32 allowed"),
    "not-an-object": (lambda d: "[1, 2]", "expected a JSON object, got list"),
    "overflowing-number": (lambda d: _meta_with(d, frame_count=1).replace('"frame_count": 1',
                                                                           '"frame_count": 1e999'),
                           "out of range"),
    "frame-count-a-string": (lambda d: _meta_with(d, frame_count="6"), "frame_count: expected an integer >= 0"),
    "frame-count-negative": (lambda d: _meta_with(d, frame_count=-1), "frame_count: expected an integer >= 0"),
    "frame-count-missing": (lambda d: _meta_with(d).replace('"frame_count"', '"frame_countX"'),
                            "frame_count: missing (a required field)"),
    "frame-bytes-zero": (lambda d: _meta_with(d, frame_bytes=0), "frame_bytes: expected an integer >= 1"),
    "closed-a-string": (lambda d: _meta_with(d, closed="yes"), "closed: expected true or false"),
    "wrong-format": (lambda d: _meta_with(d, format="other"), "format: expected 'radarodom-capture'"),
    "newer-version": (lambda d: _meta_with(d, format_version=2), "written by a newer radarodom"),
    "version-a-string": (lambda d: _meta_with(d, format_version="1"), "format_version: expected the integer 1"),
    "source-a-number": (lambda d: _meta_with(d, source=5), "source: expected a string"),
    "first-timestamp-huge": (lambda d: _meta_with(d, first_timestamp=1e300), "first_timestamp: expected null or"),
    "start-time-negative": (lambda d: _meta_with(d, start_time_unix=-1), "start_time_unix: expected a number"),
    # An integer beyond any float: "OverflowError: int too large to convert to float" escaped.
    "start-time-400-digits": (lambda d: _meta_with(d, start_time_unix=10 ** 400), "start_time_unix: expected a number"),
    "first-timestamp-400-digits": (lambda d: _meta_with(d, first_timestamp=10 ** 400),
                                   "first_timestamp: expected null or"),
    "board-calibration-bias-400-digits": (lambda d: _meta_with(d, simulator={"board_calibration": {
        "range_bias_m": 10 ** 400, "coefficients": [[1, 0]] * 12}}),
        "simulator.board_calibration.range_bias_m: expected a number of metres within -10..10, got 1000"),
    "dropped-frames-negative": (lambda d: _meta_with(d, dropped_frames=-3), "dropped_frames: expected an integer"),
    "not-utf8": (lambda d: b"\xff\xfe{}", "not UTF-8"),
    # simulator: a replay took any value for any field without a word (a board's calibration it
    # could not read was an info line, and the board taken as unknown).
    "simulator-a-list": (lambda d: _meta_with(d, simulator=[1]), "simulator: expected an object {scene, seed, board, "
                                                                 "board_calibration}, got [1]"),
    "simulator-seed-a-string": (lambda d: _meta_with(d, simulator={"seed": "x"}),
                                "simulator.seed: expected an integer >= 0, got 'x'"),
    "simulator-seed-negative": (lambda d: _meta_with(d, simulator={"seed": -1}),
                                "simulator.seed: expected an integer >= 0, got -1"),
    "simulator-seed-a-float": (lambda d: _meta_with(d, simulator={"seed": 1.5}), "simulator.seed: expected an integer"),
    "simulator-noise-seed-negative": (lambda d: _meta_with(d, simulator={"seed": 1, "noise_seed": -2}),
                                      "simulator.noise_seed: expected an integer >= 0, got -2"),
    "simulator-scene-a-number": (lambda d: _meta_with(d, simulator={"scene": 5}),
                                 "simulator.scene: expected a string, got 5"),
    "simulator-board-null": (lambda d: _meta_with(d, simulator={"board": None}),
                             "simulator.board: expected a string, got null"),
    "board-calibration-a-string": (lambda d: _meta_with(d, simulator={"board_calibration": "x"}),
                                   "simulator.board_calibration: expected an object {range_bias_m, coefficients}"),
    "board-calibration-without-bias": (lambda d: _meta_with(d, simulator={"board_calibration": {"coefficients": []}}),
                                       "simulator.board_calibration.range_bias_m: missing (a required field)"),
    "board-calibration-bias-true": (lambda d: _meta_with(d, simulator={"board_calibration": {
        "range_bias_m": True, "coefficients": [[1, 0]] * 12}}),
        "simulator.board_calibration.range_bias_m: expected a number of metres within -10..10, got true"),
    # Taken, and every replayed range moved by it:
    "board-calibration-bias-1e300": (lambda d: _meta_with(d, simulator={"board_calibration": {
        "range_bias_m": 1e300, "coefficients": [[1, 0]] * 12}}),
        "simulator.board_calibration.range_bias_m: expected a number of metres within -10..10, got 1e+300"),
    "board-calibration-three-pairs": (lambda d: _meta_with(d, simulator={"board_calibration": {
        "range_bias_m": 0, "coefficients": [[1, 0]] * 3}}),
        "simulator.board_calibration.coefficients: expected a list of 12 [re, im] pairs"),
    "board-calibration-pair-of-strings": (lambda d: _meta_with(d, simulator={"board_calibration": {
        "range_bias_m": 0, "coefficients": [[1, 0]] * 11 + [["1", "0"]]}}),
        'simulator.board_calibration.coefficients[11]: expected [re, im]: two numbers within -1..1, not both 0, '
        'got ["1", "0"]'),
    "board-calibration-beyond-one": (lambda d: _meta_with(d, simulator={"board_calibration": {
        "range_bias_m": 0, "coefficients": [[1, 0]] + [[0, 2]] * 11}}),
        "simulator.board_calibration.coefficients[1]: expected [re, im]: two numbers within -1..1"),
    "board-calibration-zero": (lambda d: _meta_with(d, simulator={"board_calibration": {
        "range_bias_m": 0, "coefficients": [[0, 0]] * 12}}), "coefficients[0]: expected [re, im]"),
}


@pytest.mark.parametrize("case", sorted(BAD_METADATA))
def test_bad_capture_json_is_refused_naming_file_and_field(tmp_path, small_cfg, case):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 6)
    make, expected = BAD_METADATA[case]
    text = make(d)
    if isinstance(text, bytes):
        (d / "capture.json").write_bytes(text)
    else:
        _set_meta_text(d, text)
    with pytest.raises(CaptureFormatError) as info:
        CaptureDirectory(d)
    message = str(info.value)
    assert message.startswith(f"{d / 'capture.json'}: "), message
    assert expected in message, message


def test_capture_json_size_is_bounded(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 2)
    _set_meta_text(d, _meta_with(d, padding="x" * (2 << 20)))
    with pytest.raises(CaptureFormatError, match=r"capture.json: more than \d+ bytes, the most allowed"):
        CaptureDirectory(d)


def test_unknown_capture_json_fields_are_kept(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 2)
    _set_meta_text(d, _meta_with(d, operator="me", note={"a": [1, 2]}))
    assert CaptureDirectory(d).metadata["note"] == {"a": [1, 2]}
    # The simulator's fields too, and a simulator that says nothing.
    for sim in ({}, {"scene": "lab", "seed": 3, "fidelity": "fast", "board_calibration": {
            "range_bias_m": 0.0, "coefficients": [[1.0, 0.0]] * 12, "identity": True}}):
        _set_meta_text(d, _meta_with(d, simulator=sim))
        assert CaptureDirectory(d).metadata["simulator"] == sim


BAD_TIMESTAMPS = {
    "nan": ("nan", "expected a timestamp (a plain decimal number of seconds), got 'nan'"),
    "inf": ("inf", "got 'inf'"),
    "underscore": ("1000.0_5", "got '1000.0_5'"),
    "hex": ("0x10", "got '0x10'"),
    "overflow": ("1e300", "timestamp 1e300 is out of range"),
    "overflow-to-infinity": ("1e999", "timestamp 1e999 is out of range"),
    "duplicate": ("1000.050000000", "timestamp 1000.050000000 is not after the previous line's 1000.050000000"),
    "out-of-order": ("999.0", "timestamp 999.0 is not after the previous line's 1000.050000000"),
    "empty-line": ("", "a blank line among the timestamps"),
    "two-numbers": ("1000.1 1000.2", "got '1000.1 1000.2'"),
    "full-width-digits": ("\uff11\uff10\uff10\uff10", "expected a timestamp"),
}


@pytest.mark.parametrize("case", sorted(BAD_TIMESTAMPS))
def test_bad_timestamp_is_refused_with_file_and_line(tmp_path, small_cfg, case):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 4, t0=T0)
    bad, expected = BAD_TIMESTAMPS[case]
    lines = (d / "timestamps.txt").read_text().splitlines()
    lines[2] = bad
    (d / "timestamps.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(CaptureFormatError) as info:
        CaptureDirectory(d)
    message = str(info.value)
    assert message.startswith(f"{d / 'timestamps.txt'}:3: "), message
    assert expected in message, message


def test_timestamps_ended_by_a_carriage_return_alone_are_named_so(tmp_path, small_cfg):
    # It said "a line longer than 256 bytes: not a timestamp" of a classic Mac's line ends.
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 4, t0=T0)
    (d / "timestamps.txt").write_bytes((d / "timestamps.txt").read_bytes().replace(b"\n", b"\r"))
    with pytest.raises(CaptureFormatError) as info:
        CaptureDirectory(d)
    assert str(info.value) == (f"{d / 'timestamps.txt'}:1: a line ended by a carriage return alone (an old Mac's "
                               "line ends): one timestamp a line, ended by LF or CR LF; convert the file (tr '\\r' "
                               "'\\n')")
    (d / "timestamps.txt").write_bytes((d / "timestamps.txt").read_bytes().replace(b"\r", b"\r\n"))
    assert len(CaptureDirectory(d).timestamps) == 4  # CR LF reads


def test_bad_timestamp_is_refused_before_the_first_frame(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 4, t0=T0)
    (d / "timestamps.txt").write_text("1000.0\n1000.05\nnan\n1000.15\n")
    with pytest.raises(CaptureFormatError, match="timestamps.txt:3"):
        open_source(f"replay://{d}?rate=max")


def test_a_very_long_timestamp_line_is_refused(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 2, t0=T0)
    (d / "timestamps.txt").write_text("1" * 10_000_000 + "\n1000.05\n")
    with pytest.raises(CaptureFormatError, match=r"timestamps.txt:1: a line longer than 256 bytes"):
        CaptureDirectory(d)


def test_edited_radar_cfg_with_other_frames_is_refused(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 30)
    (d / "radar.cfg").write_text(SMALL_CFG.replace("0 96 1 16 8000", "0 96 1 8 8000"))
    with pytest.raises(CaptureFormatError) as info:
        CaptureDirectory(d)
    message = str(info.value)
    assert "radar.cfg makes frames of 1536 bytes, capture.json says the recording's are 3072 bytes" in message


@pytest.mark.parametrize("closed", [True, False])
def test_frame_count_beyond_the_data_is_refused(tmp_path, small_cfg, closed):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 30)
    _set_meta_text(d, _meta_with(d, frame_count=100, closed=closed))
    with pytest.raises(CaptureFormatError) as info:
        CaptureDirectory(d)
    message = str(info.value)
    assert "100 frames" in message and "92160 bytes: 30 frames of 3072 bytes" in message, message


def test_frame_count_below_the_data_of_a_closed_capture_is_refused(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 30)
    _set_meta_text(d, _meta_with(d, frame_count=20))
    with pytest.raises(CaptureFormatError, match="closed recording has 20 frames"):
        CaptureDirectory(d)


def test_metadata_behind_the_data_of_a_crashed_capture_plays_every_frame(tmp_path, small_cfg, warnings_log):
    # capture.json is rewritten about once a second, so a killed writer leaves it behind the data.
    d = tmp_path / "cap"
    frames = make_capture(d, small_cfg, 30, incomplete={4: 8})
    _crashed(d, frame_count=20)
    cap = CaptureDirectory(d)
    assert cap.num_frames == 30 and [bytes(cap.raw(i)) for i in range(30)] == frames
    assert cap.missing_bytes(4) == 8
    assert any("not closed" in m and "30 whole frames" in m for m in warning_messages(warnings_log))


def test_missing_adc_data_says_so(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 2)
    os.remove(d / "adc_data.bin")
    for opener in (lambda: CaptureDirectory(d), lambda: open_source(f"replay://{d}"),
                   lambda: open_source(f"replay://{d}", small_cfg)):
        with pytest.raises(CaptureFormatError) as info:
            opener()
        message = str(info.value)
        assert f"{d}: no adc_data.bin: the capture's frame data is missing" in message, message
        assert "has no radar.cfg" not in message


def test_writer_refuses_times_the_reader_would_refuse(tmp_path, small_cfg):
    d = tmp_path / "cap"
    raw = bytes(small_cfg.frame_bytes)
    with CaptureWriter(d, small_cfg) as w:
        w.write(raw, 10.0)
        for bad in (float("nan"), float("inf"), 1e300, 10.0, 9.0, 10.0 + 1e-12):
            with pytest.raises(CaptureError, match="frame 1: timestamp"):
                w.write(raw, bad)
        with pytest.raises(CaptureError, match="missing 3073 of 3072"):
            w.write(raw, 11.0, missing_bytes=3073)
        w.write(raw, 10.05)
    cap = CaptureDirectory(d)
    assert cap.num_frames == 2
    np.testing.assert_allclose(cap.timestamps, [10.0, 10.05])


def test_capture_of_no_frame_leaves_nothing(tmp_path, small_cfg):
    made = tmp_path / "new" / "cap"
    CaptureWriter(made, small_cfg).close()
    assert not made.exists() and (tmp_path / "new").is_dir()
    given = tmp_path / "given"
    given.mkdir()
    CaptureWriter(given, small_cfg).close()
    assert given.is_dir() and os.listdir(given) == []


def test_capture_of_no_frame_left_by_a_killed_run_is_recorded_over(tmp_path, small_cfg):
    d = tmp_path / "cap"
    left = CaptureWriter(d, small_cfg)  # never closed: as a run killed before its first frame
    assert (d / "adc_data.bin").stat().st_size == 0
    frames = make_capture(d, small_cfg, 2)
    assert [bytes(CaptureDirectory(d).raw(i)) for i in range(2)] == frames
    os.close(left._data_fd)
    os.close(left._ts_fd)


# --------------------------------------------------------------- crash safety

CHILD_WRITER = r"""
import sys
import numpy as np
from radarodom.cfg import RadarConfig
from radarodom.driver.recordings.capture_dir import CaptureWriter

out, cfg_text = sys.argv[1], sys.argv[2]
cfg = RadarConfig.from_text(cfg_text, "small.cfg")
writer = CaptureWriter(out, cfg, source="crash-test", metadata_interval_s=0.002)
i = 0
while True:
    raw = np.random.default_rng(i).integers(-32768, 32768, cfg.frame_bytes // 2, dtype="<i2").tobytes()
    missing = 17 + i % 1000 if i % 50 == 7 else 0
    writer.write(raw, 1000.0 + 0.05 * i, missing, (0.01 * i, -0.5, 0.0, 0.0, 0.0, 0.0, 1.0))
    i += 1
"""


def _child_frame(i: int, frame_bytes: int) -> bytes:
    return np.random.default_rng(i).integers(-32768, 32768, frame_bytes // 2, dtype="<i2").tobytes()


def _wait_for_size(path, nbytes: int, proc: subprocess.Popen, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if os.path.exists(path) and os.path.getsize(path) >= nbytes:
            return
        if proc.poll() is not None:
            out, err = proc.communicate()
            pytest.fail(f"child exited with {proc.returncode} before writing: {err!r}")
        time.sleep(0.002)
    proc.kill()
    proc.wait()
    pytest.fail(f"{path} did not reach {nbytes} bytes in {timeout} s")


def _sigkill(proc: subprocess.Popen) -> None:
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL


def _complete_lines(path) -> int:
    return open(path, "rb").read().count(b"\n")


def test_writer_survives_sigkill(tmp_path, small_cfg, warnings_log):
    fb = small_cfg.frame_bytes
    rnd = random.Random(20240611)
    delays = [0.0] + [rnd.uniform(0.0, 0.25) for _ in range(4)]
    for k, delay in enumerate(delays):
        d = tmp_path / f"crash{k}"
        proc = subprocess.Popen([sys.executable, "-c", CHILD_WRITER, str(d), SMALL_CFG],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            _wait_for_size(d / "adc_data.bin", 3 * fb, proc)
            time.sleep(delay)
        finally:
            _sigkill(proc)
        where = f"kill {k} after {delay:.3f} s"
        size = os.path.getsize(d / "adc_data.bin")
        warnings_log.clear()
        cap = CaptureDirectory(d)
        n = cap.num_frames
        assert n == size // fb >= 3, where
        for i in range(n):
            assert bytes(cap.raw(i)) == _child_frame(i, fb), f"{where}: frame {i} of {n}"
        # timestamps: one line per frame handed to the kernel, the last may be missing
        assert n - 1 <= _complete_lines(d / "timestamps.txt") <= n, where
        np.testing.assert_allclose(cap.timestamps, 1000.0 + 0.05 * np.arange(n), rtol=0, atol=1e-6,
                                   err_msg=where)
        # capture.json was replaced atomically: always a whole JSON object
        assert cap.metadata["format"] == "radarodom-capture", where
        assert cap.metadata["closed"] is False, where
        assert cap.metadata["frame_count"] <= n, where
        assert any("not closed" in m for m in warning_messages(warnings_log)), where
        for i in range(n - 1):  # the last frame's loss may not have reached capture.json
            assert cap.missing_bytes(i) == (17 + i % 1000 if i % 50 == 7 else 0), f"{where}: frame {i}"
        # poses: written after the timestamp, so at most the last one is missing
        assert cap.groundtruth is not None
        assert n - 1 <= len(cap.groundtruth.times) <= n, where
        assert cap.pose(n - 2) == pytest.approx((0.01 * (n - 2), -0.5, 0, 0, 0, 0, 1))
        # and the crashed directory replays
        with open_source(f"replay://{d}?rate=max") as src:
            assert sum(1 for _ in src) == n


def _radar_capture() -> list[str]:
    exe = shutil.which("radar-capture", path=os.path.dirname(sys.executable))
    # These runs record; they need no Zenoh session (and must never take the user's port).
    return ([exe] if exe else [sys.executable, "-m", "radarodom.tools.radar_capture"]) + ["--no-publish"]


def _check_recording(out, frames, n_src, warnings_log) -> int:
    cap = CaptureDirectory(out)
    n = cap.num_frames
    assert n >= 2 * n_src
    for i in range(n):
        assert bytes(cap.raw(i)) == frames[i % n_src], f"frame {i} of {n}"
    # loops continue the clock: frame i at T0 + i * period
    np.testing.assert_allclose(cap.timestamps, T0 + PERIOD * np.arange(n), rtol=0, atol=1e-6)
    for i in range(n - 1):
        assert cap.missing_bytes(i) == (50 if i % n_src == 3 else 0), f"frame {i}"
    assert cap.groundtruth is not None and len(cap.groundtruth.times) >= n - 1
    for i in range(n - 1):
        assert cap.pose(i) == pytest.approx((0.1 * (i % n_src), 0, 0, 0, 0, 0, 1)), f"frame {i}"
    assert cap.config.frame_bytes == 3072
    return n


def test_radar_capture_record_survives_sigkill(tmp_path, small_cfg, warnings_log):
    src = tmp_path / "src"
    n_src = 7
    frames = make_capture(src, small_cfg, n_src, t0=T0, incomplete={3: 50}, poses=True)
    url = f"replay://{src}?rate=max&loop=0"
    for k, delay in enumerate([0.0, 0.05, 0.2]):
        out = tmp_path / f"out{k}"
        proc = subprocess.Popen([*_radar_capture(), "--source", url, "--record", str(out), "-q"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            _wait_for_size(out / "adc_data.bin", 2 * n_src * 3072, proc)
            time.sleep(delay)
        finally:
            _sigkill(proc)
        _check_recording(out, frames, n_src, warnings_log)
        meta = json.loads((out / "capture.json").read_text())
        assert meta["source"] == url and meta["closed"] is False


def test_radar_capture_sigterm_closes_recording(tmp_path, small_cfg, warnings_log):
    src = tmp_path / "src"
    n_src = 7
    frames = make_capture(src, small_cfg, n_src, t0=T0, incomplete={3: 50}, poses=True)
    out = tmp_path / "out"
    proc = subprocess.Popen([*_radar_capture(), "--source", f"replay://{src}?rate=max&loop=0",
                             "--record", str(out), "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for_size(out / "adc_data.bin", 2 * n_src * 3072, proc)
        proc.send_signal(signal.SIGTERM)
        stdout, stderr = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, stderr
    assert "stopped" in stdout and str(out) in stdout
    warnings_log.clear()
    n = _check_recording(out, frames, n_src, warnings_log)
    meta = json.loads((out / "capture.json").read_text())
    assert meta["closed"] is True and meta["frame_count"] == n
    assert (out / "adc_data.bin").stat().st_size == n * 3072
    assert all(e["missing_bytes"] == 50 and e["frame"] % n_src == 3 for e in meta["incomplete_frames"])
    assert len(meta["incomplete_frames"]) == len([i for i in range(n) if i % n_src == 3])
    assert warning_messages(warnings_log) == []


# radar-capture --record into a directory that holds another capture: refused (exit 2, "already
# holds a capture"), the capture's files untouched: test_cli_capture.py's
# test_record_into_an_existing_capture_is_refused (its bytes and times, and the one error line).


def test_a_closed_recordings_data_cut_short_is_said_so_not_blamed_on_its_timestamps(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 30)
    with open(d / "adc_data.bin", "r+b") as fh:  # a copy that stopped part way
        fh.truncate(3072 * 4 + 1000)
    with pytest.raises(CaptureFormatError) as info:
        CaptureDirectory(d)
    assert str(info.value) == (f"{d}: capture.json says the closed recording has 30 frames, adc_data.bin holds "
                               "fewer (13288 bytes: 4 frames of 3072 bytes and 1000 bytes more): was it cut short "
                               "(a copy that stopped part way)?")


def test_capture_json_is_read_with_a_bom_and_quoted_in_json_words(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 3)
    text = (d / "capture.json").read_text()
    (d / "capture.json").write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert CaptureDirectory(d).num_frames == 3
    (d / "capture.json").write_text(json.dumps({**json.loads(text), "frame_count": None}))
    with pytest.raises(CaptureFormatError, match=r"frame_count: expected .*, got null$"):
        CaptureDirectory(d)


@pytest.mark.parametrize("name", ["radar.cfg", "capture.json", "timestamps.txt", "groundtruth.tum"])
def test_a_directory_in_place_of_a_capture_file_is_named(tmp_path, small_cfg, name):
    # Was "cannot read ...: Is a directory" (exit 1), or for radar.cfg a cfg error.
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 3)
    (d / name).unlink(missing_ok=True)
    (d / name).mkdir()
    with pytest.raises(CaptureFormatError, match=f"{name}: is a directory: a capture's {name} is a file"):
        CaptureDirectory(d)


def test_an_empty_groundtruth_is_said(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 3)
    (d / "groundtruth.tum").write_text("# t x y z qx qy qz qw\n")
    cap = CaptureDirectory(d)
    assert cap.pose(0) is None
    assert any("groundtruth.tum holds no pose" in m for m in warning_messages(warnings_log))


def test_capture_json_and_timestamps_that_disagree_on_the_first_frame_are_said(tmp_path, small_cfg, warnings_log):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 3)
    assert not any("one was edited" in m for m in warning_messages(warnings_log))
    meta = json.loads((d / "capture.json").read_text())
    (d / "capture.json").write_text(json.dumps({**meta, "first_timestamp": meta["first_timestamp"] - 1.0}))
    cap = CaptureDirectory(d)
    assert cap.timestamps[0] == meta["first_timestamp"]  # played at timestamps.txt's times
    assert any("capture.json says the first frame is at" in m and "one was edited" in m
               for m in warning_messages(warnings_log))
