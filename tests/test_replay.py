"""replay:// sources (capture directories and TI recorder files), URL handling,
and the capture loop (Pipeline.run without processing)."""

from __future__ import annotations

import json
import re
import threading
import time

import numpy as np
import pytest

from conftest import SMALL_CFG, make_capture, random_frames, warning_messages

from radarodom.cfg import RadarConfig
from radarodom.driver.recordings.capture_dir import CaptureDirectory, CaptureWriter
from radarodom.driver.sources import SCHEMES, open_source
from radarodom.errors import CaptureFormatError, ConfigError, SourceError, UsageError
from radarodom.pipeline import CaptureSink, Pipeline
from radarodom.rawframe import RawLayout

T0 = 1000.0
PERIOD = 0.05  # SMALL_CFG frame period


@pytest.fixture
def capture(tmp_path, small_cfg):
    """A 6-frame capture directory with an incomplete frame and poses."""
    d = tmp_path / "cap"
    frames = make_capture(d, small_cfg, 6, t0=T0, incomplete={2: 99}, poses=True)
    return d, frames


# --------------------------------------------------------------- capture directories

def test_replay_yields_recorded_frames(capture, small_cfg):
    d, frames = capture
    url = f"replay://{d}?rate=max"
    layout = RawLayout.from_config(small_cfg)
    with open_source(url) as src:
        assert src.url == url
        assert src.config.frame_bytes == small_cfg.frame_bytes
        assert src.describe()["rate"] == "max"
        got = list(src)
    assert [f.index for f in got] == list(range(6))
    for i, f in enumerate(got):
        assert f.timestamp == pytest.approx(T0 + i * PERIOD, abs=1e-9)
        assert f.raw.dtype == np.uint8 and bytes(f.raw) == frames[i]
        assert f.missing_bytes == (99 if i == 2 else 0)
        assert f.complete == (i != 2)
        assert f.pose == pytest.approx((0.1 * i, 0, 0, 0, 0, 0, 1))
        assert f.layout == layout
        cube = f.cube()
        assert cube.shape == (4, 3, 4, 16)
        np.testing.assert_array_equal(cube, layout.decode(frames[i]))
        out = np.zeros(layout.shape, np.complex64)
        assert f.cube(out) is out
        np.testing.assert_array_equal(out, cube)


def test_frame_cube_refuses_a_wrong_out_naming_it(capture):
    """Frame.cube(out=...) of the wrong shape, dtype or kind: the package's UsageError saying what
    out must be and what it got (once numpy's ValueError, or AttributeError for a list)."""
    d, _ = capture
    with open_source(f"replay://{d}?rate=max") as src:
        frame = next(iter(src))
    wanted = ("out: a writable complex64 array shaped (4, 3, 4, 16) or (1, 4, 3, 4, 16) (one frame), "
              "or None for a new one")
    for out, got in ((np.zeros((4, 3, 4, 16), np.complex128), "complex128 shaped (4, 3, 4, 16)"),
                     (np.zeros((4, 3, 4, 8), np.complex64), "complex64 shaped (4, 3, 4, 8)"),
                     ([], "list []")):
        with pytest.raises(UsageError) as info:
            frame.cube(out)
        assert str(info.value) == f"{wanted}; got {got}"


def test_loop_twice(capture):
    d, frames = capture
    with open_source(f"replay://{d}?rate=max&loop=2") as src:
        got = list(src)
    assert [f.index for f in got] == list(range(12))
    assert [bytes(f.raw) for f in got] == frames + frames
    stamps = np.array([f.timestamp for f in got])
    assert np.all(np.diff(stamps) > 0)
    # the second pass continues the clock one frame period after the first
    np.testing.assert_allclose(stamps, T0 + PERIOD * np.arange(12), atol=1e-9)


def test_loop_forever_until_stopped(capture):
    d, frames = capture
    got = []
    with open_source(f"replay://{d}?rate=max&loop=0") as src:
        for f in src:
            got.append(f)
            if len(got) == 23:
                src.stop()
        assert src.stop_requested
    assert len(got) == 23
    assert [f.index for f in got] == list(range(23))
    assert [bytes(f.raw) for f in got] == [frames[i % 6] for i in range(23)]
    assert np.all(np.diff([f.timestamp for f in got]) > 0)


@pytest.mark.parametrize("option, first", [("start=3", 3), ("start=0.15s", 3), ("start=0.14s", 3),
                                           ("start=0s", 0), ("start=0", 0), ("start=5", 5),
                                           ("start=0.25s", 5)])
def test_start(capture, option, first):
    d, frames = capture
    with open_source(f"replay://{d}?rate=max&{option}") as src:
        got = list(src)
    assert [bytes(f.raw) for f in got] == frames[first:]
    assert [f.index for f in got] == list(range(6 - first))
    assert got[0].timestamp == pytest.approx(T0 + first * PERIOD, abs=1e-9)
    assert got[0].missing_bytes == (99 if first == 2 else 0)


@pytest.mark.parametrize("option, words", [
    ("start=6", "start=6 is past the recording's last frame (6 frames, numbered from 0)"),
    ("start=1e3s", "start=1000s is past the recording's last frame, 0.25 s after its first"),
])
def test_a_start_past_the_end_says_where_the_end_is(capture, option, words):
    d, _ = capture
    with pytest.raises(SourceError) as info:
        open_source(f"replay://{d}?rate=max&{option}")
    assert str(info.value) == f"replay://{d}?rate=max&{option}: {words}"  # the URL too, as every option's


def test_a_file_that_is_no_recording_is_said_to_be_so(capture):
    d, _ = capture
    with pytest.raises(ConfigError) as info:
        open_source(f"replay://{d}/capture.json")
    assert str(info.value).endswith("capture.json: not a recording (a capture directory, or TI's adc_data.bin or "
                                    "*_Raw_<n>.bin files)")


def test_frames_option(capture):
    d, frames = capture
    with open_source(f"replay://{d}?rate=max&frames=2") as src:
        assert [bytes(f.raw) for f in src] == frames[:2]
    with open_source(f"replay://{d}?rate=max&start=4&frames=10") as src:
        assert [bytes(f.raw) for f in src] == frames[4:]
    with open_source(f"replay://{d}?rate=max&start=1&frames=2&loop=2") as src:
        got = list(src)
    assert [bytes(f.raw) for f in got] == [frames[1], frames[2], frames[1], frames[2]]
    np.testing.assert_allclose([f.timestamp for f in got], T0 + PERIOD * np.arange(1, 5), atol=1e-9)


@pytest.mark.parametrize("option", ["start=6", "start=100", "start=1s", "start=0.2501s"])
def test_start_past_the_end(capture, option):
    d, _ = capture
    with pytest.raises(SourceError) as info:
        open_source(f"replay://{d}?{option}")
    assert info.value.exit_code == 2


def _arrivals(url: str) -> list[float]:
    with open_source(url) as src:
        t0 = time.monotonic()
        return [time.monotonic() - t0 for _ in src]


def test_rate_paces_in_real_time(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 10, t0=T0)
    paced = _arrivals(f"replay://{d}?rate=1.0")
    assert len(paced) == 10
    assert paced[-1] >= 0.35  # the last frame is due 0.45 s after the first
    for k, t in enumerate(paced):
        assert t >= k * PERIOD - 0.01, f"frame {k} came at {t:.3f} s, due at {k * PERIOD:.3f} s"
    fast = _arrivals(f"replay://{d}?rate=max")
    assert len(fast) == 10
    assert fast[-1] < paced[-1] / 3
    double = _arrivals(f"replay://{d}?rate=2")
    assert double[-1] >= 0.45 / 2 - 0.03
    for k, t in enumerate(double):
        assert t >= k * PERIOD / 2 - 0.01


def test_stop_during_pacing_ends_promptly(tmp_path, small_cfg):
    d = tmp_path / "slow"
    frames = random_frames(small_cfg, 3)
    with CaptureWriter(d, small_cfg) as w:
        for i, raw in enumerate(frames):
            w.write(raw, 10.0 * i)  # frames 10 s apart
    with open_source(f"replay://{d}?rate=1") as src:
        timer = threading.Timer(0.2, src.stop)
        t0 = time.monotonic()
        timer.start()
        try:
            got = list(src)
        finally:
            timer.cancel()
        elapsed = time.monotonic() - t0
    assert len(got) == 1
    # Stopped at 0.2 s, not after the next frame's 10 s (the rest is slack for a loaded machine).
    assert 0.15 <= elapsed < 8.0, elapsed


# --------------------------------------------------------------- URL errors

OPTIONS = ("rate=", "loop=", "start=", "frames=", "reordered=")


def test_unknown_option_lists_supported(capture):
    d, _ = capture
    with pytest.raises(SourceError) as info:
        open_source(f"replay://{d}?rate=max&speed=2")
    msg = str(info.value)
    assert "speed" in msg
    assert all(o in msg for o in OPTIONS), msg
    assert info.value.exit_code == 2


@pytest.mark.parametrize("option, name", [
    ("rate=0", "rate"), ("rate=abc", "rate"), ("rate=-1", "rate"), ("rate=inf", "rate"),
    ("rate=nan", "rate"), ("rate=", "rate"), ("loop=-1", "loop"), ("loop=1.5", "loop"),
    ("loop=x", "loop"), ("frames=0", "frames"), ("frames=-3", "frames"), ("start=x", "start"),
    ("start=-1", "start"), ("start=-1s", "start"), ("start=1.5", "start"), ("reordered=2", "reordered"),
    ("rate=1&rate=2", "rate"),
])
def test_bad_option_values(capture, option, name):
    d, _ = capture
    with pytest.raises(SourceError) as info:
        open_source(f"replay://{d}?{option}")
    assert info.value.exit_code == 2
    assert name in str(info.value)


@pytest.mark.parametrize("url", ["nosuchscheme://192.168.33.180", "ftp://host/x", "file:///tmp/x"])
def test_unknown_scheme_lists_supported(url):
    with pytest.raises(SourceError) as info:
        open_source(url)
    assert url.split("://")[0] in str(info.value)
    assert "replay://" in str(info.value)
    assert all(f"{scheme}://" in str(info.value) for scheme in SCHEMES)
    assert info.value.exit_code == 2


def test_url_without_scheme(capture):
    d, _ = capture
    for url in (str(d), "", "://x"):
        with pytest.raises(SourceError) as info:
            open_source(url)
        assert "replay" in str(info.value)


@pytest.mark.parametrize("url", ["replay://", "replay://?rate=max"])
def test_missing_path(url):
    with pytest.raises(SourceError):
        open_source(url)


def test_nonexistent_path(tmp_path):
    with pytest.raises(SourceError) as info:
        open_source(f"replay://{tmp_path / 'nothing'}")
    assert "nothing" in str(info.value)


def test_directory_without_cfg_needs_config(capture, small_cfg):
    d, frames = capture
    (d / "radar.cfg").unlink()
    with pytest.raises(ConfigError) as info:
        open_source(f"replay://{d}?rate=max")
    assert info.value.exit_code == 2
    with open_source(f"replay://{d}?rate=max", small_cfg) as src:
        assert [bytes(f.raw) for f in src] == frames


def test_given_config_overrides_recorded(capture, warnings_log):
    d, frames = capture
    i_first = RadarConfig.from_text(SMALL_CFG.replace("adcbufCfg -1 0 1 1 1", "adcbufCfg -1 0 0 1 1"),
                                    "i_first.cfg")
    with open_source(f"replay://{d}?rate=max", i_first) as src:
        assert src.config is i_first
        got = list(src)
    assert len(got) == 6
    assert not got[0].layout.q_first
    np.testing.assert_array_equal(got[1].cube(), RawLayout(4, 3, 4, 16, q_first=False).decode(frames[1]))
    # a configuration with other frames contradicts capture.json
    half = RadarConfig.from_text(SMALL_CFG.replace("0 96 1 16 8000", "0 96 1 8 8000"))
    with pytest.raises(CaptureFormatError, match="makes frames of 1536 bytes, capture.json says the "
                                                 "recording's are 3072"):
        open_source(f"replay://{d}?rate=max", half)


# --------------------------------------------------------------- TI recorder files

def _cubes(cfg, n, seed=0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    shape = (n, *cfg.cube_shape)
    return (rng.integers(-2000, 2000, shape) + 1j * rng.integers(-2000, 2000, shape)).astype(np.complex64)


def _write_split(directory, data: bytes, cuts, prefix="adc_data_Raw_", numbers=None):
    directory.mkdir(exist_ok=True)
    edges = [0, *cuts, len(data)]
    numbers = numbers if numbers is not None else range(len(edges) - 1)
    for k, n in enumerate(numbers):
        (directory / f"{prefix}{n}.bin").write_bytes(data[edges[k]: edges[k + 1]])


def test_ti_series_split_inside_frames(tmp_path, small_cfg, warnings_log):
    cubes = _cubes(small_cfg, 5)
    data = RawLayout.from_config(small_cfg, iq_interleaved=True).encode(cubes)
    fb = small_cfg.frame_bytes
    assert len(data) == 5 * fb
    d = tmp_path / "ti"
    # frame 1 (bytes 3072..6144) spans all three files; frame 3 spans the last cut
    _write_split(d, data, [4100, 5000])
    for path in (d / "adc_data_Raw_0.bin", d / "adc_data_Raw_1.bin", d):
        with open_source(f"replay://{path}?rate=max", small_cfg) as src:
            got = list(src)
        assert len(got) == 5, path
        for k, f in enumerate(got):
            assert bytes(f.raw) == data[k * fb:(k + 1) * fb]
            assert f.layout.iq_interleaved
            np.testing.assert_array_equal(f.cube(), cubes[k])
            assert f.timestamp == pytest.approx(k * PERIOD)
            assert f.missing_bytes == 0 and f.pose is None
    assert warning_messages(warnings_log) == []


def test_ti_series_cut_off_tail_warns(tmp_path, small_cfg, warnings_log):
    cubes = _cubes(small_cfg, 3)
    data = RawLayout.from_config(small_cfg, iq_interleaved=True).encode(cubes)
    d = tmp_path / "ti"
    _write_split(d, data + b"\x01" * 1000, [5000])
    with open_source(f"replay://{d / 'adc_data_Raw_0.bin'}?rate=max", small_cfg) as src:
        got = [f.cube() for f in src]
    assert len(got) == 3
    np.testing.assert_array_equal(np.stack(got), cubes)
    assert any("1000" in m for m in warning_messages(warnings_log))


def test_reordered_flag_matters(tmp_path, small_cfg):
    """The same raw-order bytes decode right only with reordered=0."""
    cubes = _cubes(small_cfg, 2)
    raw_order = RawLayout.from_config(small_cfg).encode(cubes)
    d = tmp_path / "ti"
    _write_split(d, raw_order, [])
    url = f"replay://{d / 'adc_data_Raw_0.bin'}?rate=max"
    with open_source(url + "&reordered=0", small_cfg) as src:
        got = [f.cube() for f in src]
    np.testing.assert_array_equal(np.stack(got), cubes)
    with open_source(url, small_cfg) as src:  # series default: reordered
        wrong = [f.cube() for f in src]
    assert not np.array_equal(np.stack(wrong), cubes)


def test_mmwave_studio_single_file(tmp_path, small_cfg):
    """adc_data.bin from mmWave Studio: raw order by default, I first with SampleSwap 0."""
    i_first = RadarConfig.from_text(SMALL_CFG.replace("adcbufCfg -1 0 1 1 1", "adcbufCfg -1 0 0 1 1"))
    cubes = _cubes(i_first, 3, seed=4)
    d = tmp_path / "studio"
    d.mkdir()
    path = d / "adc_data.bin"
    path.write_bytes(RawLayout.from_config(i_first).encode(cubes))
    for query in ("rate=max", "rate=max&reordered=0"):
        with open_source(f"replay://{path}?{query}", i_first) as src:
            got = list(src)
        assert not got[0].layout.iq_interleaved and not got[0].layout.q_first
        np.testing.assert_array_equal(np.stack([f.cube() for f in got]), cubes)
    # a reordered single file needs reordered=1
    path.write_bytes(RawLayout.from_config(small_cfg, iq_interleaved=True).encode(cubes))
    with open_source(f"replay://{path}?rate=max&reordered=1", small_cfg) as src:
        np.testing.assert_array_equal(np.stack([f.cube() for f in src]), cubes)


def test_ti_series_gap_warns(tmp_path, small_cfg, warnings_log):
    cubes = _cubes(small_cfg, 4)
    data = RawLayout.from_config(small_cfg, iq_interleaved=True).encode(cubes)
    d = tmp_path / "ti"
    _write_split(d, data, [2 * small_cfg.frame_bytes], numbers=[0, 2])
    with open_source(f"replay://{d / 'adc_data_Raw_0.bin'}?rate=max", small_cfg) as src:
        got = [f.cube() for f in src]
    assert len(got) == 2
    np.testing.assert_array_equal(np.stack(got), cubes[:2])
    assert any("gap" in m for m in warning_messages(warnings_log))


def test_ti_series_without_its_first_file_is_refused(tmp_path, small_cfg):
    """Its _Raw_1 begins mid-frame: played, every frame was misaligned (exit 0, odometry of noise)."""
    data = RawLayout.from_config(small_cfg, iq_interleaved=True).encode(_cubes(small_cfg, 4))
    d = tmp_path / "ti"
    _write_split(d, data, [5000], numbers=[1, 2])
    for path in (d / "adc_data_Raw_1.bin", d / "adc_data_Raw_2.bin", d):
        with pytest.raises(CaptureFormatError) as info:
            open_source(f"replay://{path}?rate=max", small_cfg)
        assert str(info.value) == (f"{d / 'adc_data_Raw_1.bin'}: the series starts at number 1: "
                                   f"{d / 'adc_data_Raw_0.bin'} is missing, and without the stream's start its "
                                   "frames cannot be found (each file goes on where the one before ended); put it "
                                   "back beside the others")


def test_a_ti_series_file_that_is_a_directory_is_named_so(tmp_path, small_cfg):
    (tmp_path / "ti" / "adc_data_Raw_0.bin").mkdir(parents=True)  # it said "no such file", exit 1
    with pytest.raises(CaptureFormatError) as info:
        open_source(f"replay://{tmp_path / 'ti'}?rate=max", small_cfg)
    assert str(info.value) == f"{tmp_path / 'ti' / 'adc_data_Raw_0.bin'}: is a directory: a TI recording's " \
                              "adc_data_Raw_0.bin is a file"


@pytest.mark.parametrize("size", [0, 100, 3071])
def test_ti_file_shorter_than_a_frame(tmp_path, small_cfg, size):
    d = tmp_path / "ti"
    d.mkdir()
    (d / "adc_data_Raw_0.bin").write_bytes(b"\x07" * size)
    with pytest.raises(CaptureFormatError):
        open_source(f"replay://{d / 'adc_data_Raw_0.bin'}?rate=max", small_cfg)


def test_ti_file_needs_config(tmp_path, small_cfg):
    d = tmp_path / "ti"
    _write_split(d, bytes(2 * small_cfg.frame_bytes), [])
    with pytest.raises(ConfigError):
        open_source(f"replay://{d / 'adc_data_Raw_0.bin'}?rate=max")
    with pytest.raises(ConfigError):
        open_source(f"replay://{d}?rate=max")


# --------------------------------------------------------------- the run loop (Pipeline.run)

def test_pipeline_run_to_end(capture):
    d, _ = capture
    with open_source(f"replay://{d}?rate=max") as src:
        stats = Pipeline(src).run()
    assert stats.frames == 6 and stats.reason == "end of source"
    assert stats.incomplete_frames == 1 and stats.missing_bytes == 99
    assert stats.first_timestamp == pytest.approx(T0)
    assert stats.stream_duration_s == pytest.approx(5 * PERIOD)


def test_pipeline_run_max_frames(capture):
    d, frames = capture
    seen = []
    with open_source(f"replay://{d}?rate=max&loop=0") as src:
        stats = Pipeline(src, max_frames=9).run(lambda r, s: seen.append(bytes(r.frame.raw)))
    assert stats.frames == 9 and stats.reason == "frame limit"
    assert seen == [frames[i % 6] for i in range(9)]


def test_pipeline_run_max_duration_is_stream_time(capture):
    d, _ = capture
    seen = []
    with open_source(f"replay://{d}?rate=max&loop=0") as src:
        # loop=0 at rate=max: a wall-clock limit would let thousands of frames through
        stats = Pipeline(src, max_duration_s=0.175).run(lambda r, s: seen.append(r.frame.timestamp))
    assert stats.frames == 4 and stats.reason == "duration limit"
    np.testing.assert_allclose(seen, T0 + PERIOD * np.arange(4), atol=1e-9)
    # looping: 0.5 s of stream is 10 frames of a 6-frame capture
    with open_source(f"replay://{d}?rate=max&loop=0") as src:
        stats = Pipeline(src, max_duration_s=0.475).run()
    assert stats.frames == 10


def test_pipeline_run_stopped(capture):
    d, _ = capture

    def on_frame(result, stats):
        if stats.frames == 3:
            src.stop()

    with open_source(f"replay://{d}?rate=max&loop=0") as src:
        stats = Pipeline(src).run(on_frame)
    assert stats.frames == 3 and stats.reason == "stopped"


def test_pipeline_run_records_identical_capture(capture, tmp_path):
    d, frames = capture
    out = tmp_path / "out"
    url = f"replay://{d}?rate=max"
    with open_source(url) as src:
        writer = CaptureWriter(out, src.config, source=url)
        pipe = Pipeline(src, sinks=[CaptureSink(writer, src)])
        assert pipe.products is None  # recording alone: no DSP
        stats = pipe.run()
    assert stats.frames == 6
    for name in ("adc_data.bin", "timestamps.txt", "groundtruth.tum", "radar.cfg"):
        assert (out / name).read_bytes() == (d / name).read_bytes(), name
    rec = CaptureDirectory(out)
    assert rec.metadata["closed"] is True and rec.metadata["source"] == url
    assert rec.metadata["incomplete_frames"] == [{"frame": 2, "missing_bytes": 99}]
    assert rec.missing_bytes(2) == 99
    assert "dropped_frames" not in rec.metadata  # a replay drops none: only a live source says


def test_pipeline_run_closes_writer_on_exception(capture, tmp_path):
    d, frames = capture
    out = tmp_path / "out"

    class Boom(RuntimeError):
        pass

    def on_frame(result, stats):
        if stats.frames == 3:
            raise Boom("consumer failed")

    with open_source(f"replay://{d}?rate=max") as src:
        writer = CaptureWriter(out, src.config)
        with pytest.raises(Boom):
            Pipeline(src, sinks=[CaptureSink(writer, src)]).run(on_frame)
    rec = CaptureDirectory(out)
    assert rec.metadata["closed"] is True
    assert rec.metadata["frame_count"] == 3
    assert [bytes(rec.raw(i)) for i in range(3)] == frames[:3]


def test_pipeline_closes_every_sink_when_one_fails_to_close(capture, tmp_path):
    from radarodom.pipeline import PointsCsvSink, Sink

    class BadClose(Sink):
        def write(self, result, stats):
            pass

        def close(self, stats):
            raise OSError("disk full")

    d, frames = capture
    csv = PointsCsvSink(tmp_path / "points.csv")
    with open_source(f"replay://{d}?rate=max") as src:
        writer = CaptureWriter(tmp_path / "out", src.config)
        with pytest.raises(OSError, match="disk full"):
            Pipeline(src, sinks=[BadClose(), csv, CaptureSink(writer, src)]).run()
    assert csv._fh.closed
    assert (tmp_path / "points.csv").read_text().startswith("frame,t,")
    rec = CaptureDirectory(tmp_path / "out")  # the recording too: closed, every frame in it
    assert rec.metadata["closed"] is True and rec.metadata["frame_count"] == 6
    assert [bytes(rec.raw(i)) for i in range(6)] == frames


def test_the_failure_that_stopped_a_run_is_reported_and_a_later_close_failure_follows_it(capture, capsys):
    from radarodom.errors import CaptureError
    from radarodom.pipeline import Sink
    from radarodom.tools import cli

    class FullDisk(Sink):  # as a recording on a full disk: its write fails, then its close
        def write(self, result, stats):
            if result.frame.index == 2:
                raise CaptureError("out: writing frame 2 failed: No space left on device")

        def close(self, stats):
            raise CaptureError("closing out failed: No space left on device")

    d, _ = capture

    def main(args):
        with open_source(f"replay://{d}?rate=max") as src:
            Pipeline(src, sinks=[FullDisk()]).run()

    import argparse
    assert cli.run(main, argparse.ArgumentParser(prog="prog"), []) == 1
    assert capsys.readouterr().err.splitlines() == [
        "prog: error: out: writing frame 2 failed: No space left on device",
        "prog: warning: then closing the outputs failed too: closing out failed: No space left on device"]


def test_pipeline_records_a_frame_before_its_processing_fails(capture, tmp_path):
    """The recording takes each frame before the DSP, the estimator and the other sinks (whatever
    the sinks' order): a frame whose processing raises is in the capture, closed."""
    from radarodom.pipeline import Sink

    class FailsAtFrame3(Sink):
        def write(self, result, stats):
            if result.frame.index == 3:
                raise RuntimeError("processing failed")

    d, frames = capture
    out = tmp_path / "out"
    with open_source(f"replay://{d}?rate=max") as src:
        writer = CaptureWriter(out, src.config)
        with pytest.raises(RuntimeError, match="processing failed"):
            Pipeline(src, sinks=[FailsAtFrame3(), CaptureSink(writer, src)]).run()
    rec = CaptureDirectory(out)
    assert rec.metadata["closed"] is True and rec.metadata["frame_count"] == 4
    assert [bytes(rec.raw(i)) for i in range(4)] == frames[:4]


@pytest.mark.parametrize("path", [None, 7, "ti\0x", b"ti\0x"])
def test_ti_recording_path_that_is_no_path_is_a_capture_error(small_cfg, path):
    from radarodom.driver.recordings.ti_recorder import TiRecording
    from radarodom.errors import CaptureError
    with pytest.raises(CaptureError, match="path"):
        TiRecording(path, small_cfg)


def test_a_directory_without_a_recording_is_said_to_hold_none(tmp_path, small_cfg):
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(CaptureFormatError) as info:
        open_source(f"replay://{empty}", small_cfg)
    assert str(info.value) == (f"{empty}: holds no recording: neither a capture (adc_data.bin with capture.json) "
                               "nor a TI recording (*_Raw_<n>.bin)")
    with pytest.raises(ConfigError) as info:  # without a cfg: not asked for one
        open_source(f"replay://{empty}")
    assert "holds no recording" in str(info.value) and "--cfg" not in str(info.value)


def test_a_start_in_seconds_on_a_recording_without_a_whole_frame_says_it_holds_none(tmp_path, small_cfg):
    d = tmp_path / "cap"
    make_capture(d, small_cfg, 1)
    with open(d / "adc_data.bin", "r+b") as fh:
        fh.truncate(100)  # a run killed within its first frame
    (d / "timestamps.txt").write_text("")
    meta = json.loads((d / "capture.json").read_text())
    (d / "capture.json").write_text(json.dumps({**meta, "closed": False, "frame_count": 0}))
    with pytest.raises(CaptureFormatError, match="holds no whole frame"):  # was an IndexError
        open_source(f"replay://{d}?start=1s")


def test_a_long_wait_for_a_frame_is_said(tmp_path, small_cfg, warnings_log):
    """A recording whose times jump (an hour, here 30 s) waited at rate=1 without a word: the run looked hung."""
    d = tmp_path / "gap"
    with CaptureWriter(d, small_cfg, source="test") as writer:
        for t, raw in zip((100.0, 100.05, 130.0), random_frames(small_cfg, 3, 1)):
            writer.write(raw, t, 0, None)
    with open_source(f"replay://{d}", small_cfg) as src:
        got = []

        def take():
            for frame in src:
                got.append(frame.index)
                if len(got) == 2:
                    threading.Timer(0.3, src.stop).start()  # while it waits for the third

        reader = threading.Thread(target=take)
        reader.start()
        reader.join(20)
    assert not reader.is_alive() and got == [0, 1]
    said = [m for m in warning_messages(warnings_log) if "due in" in m]
    assert len(said) == 1 and re.fullmatch(  # the seconds left: 30 less what a loaded machine took since
        rf"replay://{re.escape(str(d))}: the next frame is due in \d+ s, at 30\.0 s of stream "
        r"\(a gap of (29\.9|30\.0) s in the recording's times\); waiting for it \(rate=max plays without waiting\)",
        said[0]), said


def _stopped_source(url: str):
    """A source of no frames, asked to stop: a Pacer given it decides what to say, then does not wait."""
    from radarodom.driver.sources import Source

    class Stopped(Source):
        def _frames(self):
            return iter(())

    source = Stopped()
    source.url = url
    source.stop()
    return source


def test_a_slow_rate_waits_long_for_every_frame_without_a_word(warnings_log):
    """At rate=0.004 each 50 ms step is a 12.5 s wait, no gap in the times: it was said, every
    frame.  (A source asked to stop: the pacer decides what to say, then does not wait.)"""
    from radarodom.driver.sources import Pacer

    pacer = Pacer(0.004, _stopped_source("sim://slow"))
    for k in range(5):
        pacer.wait(0.05 * k)
    assert not [m for m in warning_messages(warnings_log) if "due in" in m]
    pacer.wait(30.0)  # a gap, at that rate too
    assert len([m for m in warning_messages(warnings_log) if "due in" in m]) == 1


@pytest.mark.parametrize("offsets, said_at", [
    ((0.0, 20.0, 20.05, 20.1), [20.0]),  # a gap right after the first frame: no step before it
    ((0.0, 0.05, 0.1, 20.0, 40.0, 40.05), [20.0, 40.0]),  # a gap after a gap is one too
    ((0.0, 5.0, 5.05), []),  # 5 s of stream: no wait of 10 s at rate 1
])
def test_a_gap_is_said_after_the_first_frame_and_after_another_gap(warnings_log, offsets, said_at):
    """The pacer compared a step with the one before it only: after the first frame there was none
    (a 20 s gap waited without a word), and after a gap the gap was the usual step."""
    from radarodom.driver.sources import Pacer

    pacer = Pacer(1.0, _stopped_source("replay://gappy"))
    for offset in offsets:
        pacer.wait(offset)
    said = [m for m in warning_messages(warnings_log) if "due in" in m]
    assert [float(re.search(r"at ([\d.]+) s of stream", m).group(1)) for m in said] == said_at, said


def test_a_replays_time_span_covers_its_passes_and_names_its_times_file(tmp_path, small_cfg):
    """What radar-capture checks --ros2 and --mcap against before any output opens."""
    make_capture(tmp_path / "r", small_cfg, 4, t0=10.0)
    period = small_cfg.frame_period_s
    times = str(tmp_path / "r" / "timestamps.txt")
    with open_source(f"replay://{tmp_path / 'r'}", small_cfg) as src:
        first, last, where = src.time_span()
        assert (first, last) == pytest.approx((10.0, 10.0 + 3 * period)) and where == times
    # A loop's passes are not counted: loop=500000000 with --frames 3 was refused as reaching 2038.
    for loop in ("3", "0", "500000000"):
        with open_source(f"replay://{tmp_path / 'r'}?loop={loop}&start=1", small_cfg) as src:
            first, last, _ = src.time_span()
            assert (first, last) == pytest.approx((10.0 + period, 10.0 + 3 * period))
    with open_source("sim://corridor?duration=1", small_cfg) as src:
        assert src.time_span() is None
