"""What a user hands the recording readers (issue 18): paths of any type, and the capture
directory's files in shapes no writer makes (a directory where adc_data.bin should be, blank
lines and odd characters in timestamps.txt).  Only the package's own errors come out, saying
what and where."""

from __future__ import annotations

import os

import numpy as np
import pytest
from conftest import make_capture

from radarodom.driver.recordings.capture_dir import CaptureDirectory, CaptureWriter
from radarodom.errors import CaptureError, CaptureFormatError
from radarodom.tum import TumWriter, read_tum

T0 = 1000.0


# ------------------------------------------------------------------ paths
def test_capture_directory_takes_a_bytes_path(tmp_path, small_cfg):
    d = tmp_path / "cap"
    frames = make_capture(d, small_cfg, 3, t0=T0)
    cap = CaptureDirectory(os.fsencode(d))
    assert cap.directory == str(d) and bytes(cap.raw(2)) == frames[2]
    with pytest.raises(CaptureError, match=f"^{tmp_path / 'none'}: no such capture directory$"):
        CaptureDirectory(os.fsencode(tmp_path / "none"))


@pytest.mark.parametrize("path, words", [
    (None, "expected a directory path, got NoneType"), (5, "expected a directory path, got int"),
    (["cap"], "expected a directory path, got list"),
    ("a\0b", r"a path cannot contain a NUL character: 'a\\x00b'"),
    (b"a\0b", r"a path cannot contain a NUL character: 'a\\x00b'")])
def test_capture_directory_of_no_path_is_a_capture_error(path, words):
    """Once a TypeError (None, 5) or ValueError (NUL): the package's own error now."""
    with pytest.raises(CaptureError, match=f"^{words}$"):
        CaptureDirectory(path)


def test_capture_writer_paths(tmp_path, small_cfg):
    d = tmp_path / "cap"
    with CaptureWriter(os.fsencode(d), small_cfg) as writer:
        assert writer.directory == str(d)
        writer.write(bytes(small_cfg.frame_bytes), T0)
    assert CaptureDirectory(d).num_frames == 1
    for bad in (None, 5, "x\0y"):
        with pytest.raises(CaptureError, match="expected a file path|NUL character"):
            CaptureWriter(bad, small_cfg)


def test_read_tum_of_no_path_is_a_capture_error(tmp_path):
    path = tmp_path / "gt.tum"
    with TumWriter(os.fsencode(path)) as writer:
        writer.write(1.0, 2.0, 3.0, 0.0)
    for given in (path, str(path), os.fsencode(path)):
        traj = read_tum(given)
        assert traj.source == str(path) and traj.positions.tolist() == [[2.0, 3.0, 0.0]]
    for bad, words in ((None, "expected a file path, got NoneType"), (1.5, "expected a file path, got float"),
                       ("a\0b", r"a path cannot contain a NUL character: 'a\\x00b'")):
        with pytest.raises(CaptureError, match=f"^{words}$"):
            read_tum(bad)
        with pytest.raises(CaptureError, match=f"^{words}$"):
            TumWriter(bad)
    with pytest.raises(CaptureError, match=f"^cannot read {tmp_path / 'none.tum'}: "):
        read_tum(os.fsencode(tmp_path / "none.tum"))


# ------------------------------------------------------------------ adc_data.bin
def test_adc_data_that_is_a_directory_says_so(tmp_path, small_cfg):
    """It once said "timestamps.txt:1: more lines than the 0 whole frames"."""
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 3, t0=T0)
    os.remove(d / "adc_data.bin")
    os.mkdir(d / "adc_data.bin")
    with pytest.raises(CaptureFormatError, match=f"^{d / 'adc_data.bin'}: is a directory: a capture's "
                                                 "adc_data.bin is a file; put the recording's own back in its place$"):
        CaptureDirectory(d)
    os.rmdir(d / "adc_data.bin")
    os.mkfifo(d / "adc_data.bin")
    with pytest.raises(CaptureFormatError, match="adc_data.bin: is not a regular file"):
        CaptureDirectory(d)


# ------------------------------------------------------------------ timestamps.txt
def _with_timestamps(tmp_path, cfg, text: bytes, n: int = 4):
    d = tmp_path / "cap"
    make_capture(d, cfg, n, t0=T0)
    (d / "timestamps.txt").write_bytes(text)
    return d


def _lines(cfg, n: int = 4) -> bytes:
    return "".join(f"{T0 + i * cfg.frame_period_s:.9f}\n" for i in range(n)).encode()


@pytest.mark.parametrize("trailing", [b"\n", b"\n\n", b"  \n\t\n", b"\r\n", b" \r\n   ", b"\n" * 100],
                         ids=["blank", "two-blank", "spaces-and-tab", "crlf", "spaces-no-end", "hundred"])
def test_blank_lines_at_the_end_of_timestamps_are_accepted(tmp_path, small_cfg, trailing):
    """An editor's or a copy's blank last line once counted as a fifth line of a 4-frame recording."""
    d = _with_timestamps(tmp_path, small_cfg, _lines(small_cfg) + trailing)
    cap = CaptureDirectory(d)
    assert cap.num_frames == 4
    np.testing.assert_allclose(cap.timestamps, T0 + small_cfg.frame_period_s * np.arange(4))


def test_a_blank_line_among_timestamps_is_refused(tmp_path, small_cfg):
    lines = _lines(small_cfg).splitlines(keepends=True)
    d = _with_timestamps(tmp_path, small_cfg, b"".join(lines[:2]) + b" \n" + b"".join(lines[2:]))
    with pytest.raises(CaptureFormatError, match=r"timestamps.txt:3: a blank line among the timestamps"):
        CaptureDirectory(d)


def test_a_file_of_blank_lines_after_the_timestamps_is_refused(tmp_path, small_cfg):
    d = _with_timestamps(tmp_path, small_cfg, _lines(small_cfg) + b"\n" * 1_000_000)
    with pytest.raises(CaptureFormatError, match=r"timestamps.txt:5: 101 blank lines from here on"):
        CaptureDirectory(d)


@pytest.mark.parametrize("line, words", [
    ("1000.1\u00a0", "column 7: character U+00A0 (no-break space)"),
    ("\u00a01000.1", "column 1: character U+00A0 (no-break space)"),
    ("1000\u30021", "column 5: character U+3002 (ideographic full stop)"),
    ("1000.1\x1b[2J", "column 7: character U+001B (control character)"),
    ("1000.1\x00", "column 7: character U+0000 (control character)"),
    ("1000.1\ufeff", "column 7: character U+FEFF (zero width no-break space)")])
def test_an_odd_character_in_timestamps_is_named(tmp_path, small_cfg, line, words):
    """Not shown as mojibake ('1000.1\\ufffd\\ufffd'): which character, in which column."""
    lines = _lines(small_cfg).splitlines(keepends=True)
    d = _with_timestamps(tmp_path, small_cfg, lines[0] + line.encode("utf-8") + b"\n" + b"".join(lines[2:]))
    with pytest.raises(CaptureFormatError) as info:
        CaptureDirectory(d)
    assert str(info.value) == (f"{d / 'timestamps.txt'}:2: {words}: expected a timestamp (a plain decimal "
                               f"number of seconds in ASCII)")


def test_a_byte_that_is_no_utf8_in_timestamps_is_named(tmp_path, small_cfg):
    lines = _lines(small_cfg).splitlines(keepends=True)
    d = _with_timestamps(tmp_path, small_cfg, lines[0] + b"1000.\xff1\n" + b"".join(lines[2:]))
    with pytest.raises(CaptureFormatError, match=r"timestamps.txt:2: column 6: byte 0xFF, which is not UTF-8 text"):
        CaptureDirectory(d)


def test_a_capture_directorys_frame_data_given_alone_names_the_directory_to_give(tmp_path, small_cfg):
    from radarodom.driver.sources import open_source
    from radarodom.errors import ConfigError

    make_capture(tmp_path / "rec", small_cfg, 2)
    with pytest.raises(ConfigError, match=r"the frame data of the capture directory .*rec: give the directory "
                                          r"\(replay://.*rec\)"):
        open_source(f"replay://{tmp_path / 'rec' / 'adc_data.bin'}?rate=max")
    # TI's own adc_data.bin (no capture.json beside it) still needs its cfg.
    (tmp_path / "ti").mkdir()
    (tmp_path / "ti" / "adc_data.bin").write_bytes(bytes(small_cfg.frame_bytes))
    with pytest.raises(ConfigError, match="a recording without its radar.cfg: give the radar configuration"):
        open_source(f"replay://{tmp_path / 'ti' / 'adc_data.bin'}")
