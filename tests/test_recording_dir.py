"""A recording never replaces or removes files it did not write: a directory holding files of a
recording's names (radar.cfg, groundtruth.tum, timestamps.txt, capture.json, ...) without a
capture.json of radarodom's is refused before anything in it changes, by radar-capture --record,
radar-sim --out and the TI demo's recorder alike; a recording of radarodom's that holds no data
(a run killed before its first frame) is recorded over."""

from __future__ import annotations

import json

import pytest

from radarodom.driver.recordings.capture_writer import CaptureWriter
from radarodom.driver.tidemo.recording import UartRecorder
from radarodom.errors import CaptureExistsError
from radarodom.tools import radar_capture, radar_sim

URL = "sim://calibration?rate=max&duration=0.3"


def _snapshot(directory) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())}


@pytest.mark.parametrize("name, content", [
    ("groundtruth.tum", b"0 0 0 0 0 0 0 1\n"),
    ("radar.cfg", b"% my own cfg\nsensorStop\n"),
    ("timestamps.txt", b"1.0\n"),
    ("capture.json", b'{"format": "another-tool", "frames": 3}\n'),
    ("uart.bin", b""),
])
def test_radar_sim_refuses_a_directory_holding_a_users_file_of_a_recordings_name(tmp_path, capsys, name, content):
    out = tmp_path / "mine"
    out.mkdir()
    (out / name).write_bytes(content)
    (out / "notes.txt").write_text("mine")
    before = _snapshot(out)
    assert radar_sim.main(["calibration", "--duration", "0.2", "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert f"already holds {name} not written by radarodom" in err and "nothing in it was changed" in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert _snapshot(out) == before


def test_radar_capture_refuses_it_with_overwrite_too_and_names_every_such_file(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "radar.cfg").write_text("% my own cfg\n")
    (out / "groundtruth.tum").write_text("0 0 0 0 0 0 0 1\n")
    odom = tmp_path / "old.tum"
    odom.write_text("mine\n")
    before = _snapshot(out)
    for extra in ([], ["--overwrite"]):
        rc = radar_capture.main(["--source", URL, "--no-publish", "-q", "--record", str(out),
                                 "--odom-out", str(odom), *extra])
        err = capsys.readouterr().err
        assert rc == 2 and "already holds groundtruth.tum, radar.cfg not written by radarodom" in err, err
        assert _snapshot(out) == before and odom.read_text() == "mine\n"


def test_the_writer_refuses_before_writing_anything(tmp_path, small_cfg):
    cfg = small_cfg
    for recorder in (lambda d: CaptureWriter(d, cfg), lambda d: UartRecorder(d, cfg)):
        out = tmp_path / "d"
        out.mkdir(exist_ok=True)
        (out / "timestamps.txt").write_text("5.0\n")
        with pytest.raises(CaptureExistsError, match="already holds timestamps.txt not written by radarodom"):
            recorder(out)
        assert _snapshot(out) == {"timestamps.txt": b"5.0\n"}


def test_a_recording_of_no_frame_is_recorded_over_and_one_with_frames_kept(tmp_path, small_cfg):
    cfg = small_cfg
    out = tmp_path / "rec"
    CaptureWriter(out, cfg)  # never closed: a run killed before its first frame
    assert json.loads((out / "capture.json").read_text())["frame_count"] == 0
    with CaptureWriter(out, cfg) as writer:
        writer.write(bytes(cfg.frame_bytes), 1.0)
    assert json.loads((out / "capture.json").read_text())["frame_count"] == 1
    with pytest.raises(CaptureExistsError, match=r"already holds a capture \(adc_data.bin\); choose a new directory"):
        CaptureWriter(out, cfg)
    with pytest.raises(CaptureExistsError, match=r"already holds a capture \(adc_data.bin\)"):
        UartRecorder(out, cfg)
    assert json.loads((out / "capture.json").read_text())["frame_count"] == 1


def test_a_recording_that_records_nothing_removes_only_its_own_files(tmp_path, small_cfg):
    cfg = small_cfg
    out = tmp_path / "rec"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    CaptureWriter(out, cfg).close()
    UartRecorder(out, cfg).close()
    assert _snapshot(out) == {"notes.txt": b"mine"}
