"""Issue 18, sources: ``coloradar://`` (radar-capture) and radar-coloradar refuse a broken run
with the same error, before anything is written; a missing run directory is a usage error
(exit 2) as with replay://; messages show plain numbers.

Both programs run in this process (their ``main``), each case on a run of coloradar_synth with
one piece of damage."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
from coloradar_synth import T0, write_run

from radarodom.driver.coloradar.run import ColoRadarRun
from radarodom.driver.coloradar.source import ColoRadarSource
from radarodom.errors import CaptureFormatError, UsageError
from radarodom.tools import radar_capture, radar_coloradar


def _error_line(capsys, prog: str) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err, err
    lines = [ln for ln in err.splitlines() if ln.startswith(f"{prog}: error: ")]
    assert len(lines) == 1, err
    return lines[0][len(f"{prog}: error: "):]


def _both_refuse(run: pathlib.Path, capsys, tmp_path, query: str = "", coloradar_args=()) -> str:
    """radar-capture on coloradar://RUN and radar-coloradar RUN: both exit 2 with the same
    message, and neither leaves an output file behind.  Returns the message."""
    tmp_path.mkdir(exist_ok=True)  # (outputs in a missing directory are refused before the run is read)
    odom, out = tmp_path / "odom.tum", tmp_path / "tables"
    url = f"coloradar://{run}?rate=max" + (f"&{query}" if query else "")
    assert radar_capture.main(["--source", url, "--no-publish", "-q", "--odom-out", str(odom)]) == 2
    capture_says = _error_line(capsys, "radar-capture")
    assert radar_coloradar.main([str(run), "--out", str(out), "--json", str(tmp_path / "n.json"),
                                 *coloradar_args]) == 2
    coloradar_says = _error_line(capsys, "radar-coloradar")
    assert capture_says.replace(url + ": ", "") == coloradar_says
    assert not odom.exists() and not out.exists() and not (tmp_path / "n.json").exists()
    return coloradar_says


@pytest.mark.parametrize("how", ["zero_byte_files", "no_records"])
def test_empty_cascade_heatmaps_are_refused_by_both_programs(tmp_path, capsys, how):
    """The issue's first case: coloradar:// said "8 frames" and wrote an empty TUM file."""
    run = write_run(tmp_path, frames=8)
    folder = run / "cascade" / "heatmaps" / "data"
    for f in folder.iterdir():
        if how == "zero_byte_files":
            f.write_bytes(b"")
        else:
            f.unlink()
    if how == "no_records":
        (run / "cascade" / "heatmaps" / "timestamps.txt").write_text("")
    said = _both_refuse(run, capsys, tmp_path / "out")
    if how == "zero_byte_files":
        assert f"{folder / 'heatmap_0.bin'}: 0 bytes, expected 16384" in said
    else:
        assert "cascade/heatmaps/timestamps.txt: the run's cascade/heatmaps holds no records" in said


@pytest.mark.parametrize("stream, name, cut", [
    ("cascade/heatmaps", "heatmap_7.bin", 8),  # the last frame: met only at the end before
    ("single_chip/pointclouds", "radar_pointcloud_5.bin", 3),  # not a whole number of points
])
def test_a_truncated_file_is_found_before_any_output(tmp_path, capsys, stream, name, cut):
    run = write_run(tmp_path, frames=8)
    path = run / stream / "data" / name
    path.write_bytes(path.read_bytes()[:-cut])
    said = _both_refuse(run, capsys, tmp_path / "out")
    assert said.startswith(f"{path}: ")


@pytest.mark.parametrize("stream, name", [("cascade/heatmaps", "heatmap_3.bin"),
                                          ("single_chip/pointclouds", "radar_pointcloud_2.bin")])
def test_a_directory_in_place_of_a_record_file_is_found_before_any_output(tmp_path, capsys, stream, name):
    """A heatmap's directory whose size matched passed the check and failed mid-run (exit 1); a point
    cloud's was '4096 bytes is not a whole number of 20-byte points'."""
    run = write_run(tmp_path, frames=6)
    path = run / stream / "data" / name
    path.unlink()
    path.mkdir()
    said = _both_refuse(run, capsys, tmp_path / "out")
    assert said.startswith(f"{path}: not a file (a record of the run is a file of its data)"), said


def test_a_truncated_adc_frame_is_found_before_recording(tmp_path, capsys):
    run = write_run(tmp_path, frames=6)
    path = run / "single_chip" / "adc_samples" / "data" / "frame_5.bin"
    path.write_bytes(path.read_bytes()[:-4])
    query = "velocity=single_chip_adc&heatmap=single_chip_adc"
    record = tmp_path / "rec"
    assert radar_capture.main(["--source", f"coloradar://{run}?rate=max&{query}", "--no-publish", "-q",
                               "--record", str(record)]) == 2
    said = _error_line(capsys, "radar-capture")
    assert f"{path}: 6140 bytes, expected 6144" in said and "waveform_cfg.txt" in said
    assert not record.exists()
    with pytest.raises(CaptureFormatError, match="6140 bytes"):
        ColoRadarSource(ColoRadarRun(run), velocity="single_chip_adc", heatmap="single_chip_adc")
    _both_refuse(run, capsys, tmp_path / "out", query,
                 ["--velocity", "single_chip_adc", "--heatmap", "single_chip_adc"])


def test_mismatched_counts_are_refused_by_both_programs(tmp_path, capsys):
    run = write_run(tmp_path, frames=6)
    times = run / "cascade" / "heatmaps" / "timestamps.txt"
    times.write_text(times.read_text() + repr(T0 + 9.0) + "\n")
    said = _both_refuse(run, capsys, tmp_path / "out")
    assert said.startswith(f"{times} has 7 timestamps but there are 6 files in")


@pytest.mark.parametrize("line3, words", [
    ("same", "time does not advance (1608589800.27 after 1608589800.27)"),
    ("back", "time goes backwards (1608589800.07 after 1608589800.27)"),
])
def test_times_that_do_not_advance_are_refused_with_plain_numbers(tmp_path, capsys, line3, words):
    """The issue's numpy repr: "np.float64(1608589800.07)" in a message."""
    run = write_run(tmp_path, frames=6)
    path = run / "cascade" / "heatmaps" / "timestamps.txt"
    lines = path.read_text().splitlines()
    lines[2] = lines[1] if line3 == "same" else repr(T0 + 0.07)
    path.write_text("\n".join(lines) + "\n")
    said = _both_refuse(run, capsys, tmp_path / "out")
    assert said == f"{path}:3: {words}"
    assert "np." not in said


def test_ground_truth_times_that_do_not_advance_are_refused_where_it_is_the_reference(tmp_path, capsys):
    from radarodom.tools import radar_eval

    run = write_run(tmp_path, frames=6)
    path = run / "groundtruth" / "timestamps.txt"
    lines = path.read_text().splitlines()
    lines[2] = lines[1]
    path.write_text("\n".join(lines) + "\n")
    words = f"{path}:3: time does not advance ({float(lines[1])!r} after {float(lines[1])!r})"
    with pytest.raises(CaptureFormatError) as caught:
        ColoRadarRun(run).groundtruth()
    assert str(caught.value) == words
    estimate = tmp_path / "est.tum"
    estimate.write_text("".join(f"{T0 + 0.1 * k!r} {0.1 * k} 0 0 0 0 0 1\n" for k in range(5)))
    assert radar_eval.main([str(estimate), f"coloradar://{run}"]) == 2
    assert _error_line(capsys, "radar-eval") == words


def test_a_missing_run_or_calibration_is_a_usage_error_everywhere(tmp_path, capsys):
    absent = tmp_path / "no_such_run"
    assert radar_capture.main(["--source", f"coloradar://{absent}", "--no-publish", "-q"]) == 2
    assert _error_line(capsys, "radar-capture") == f"{absent}: no such run directory"
    assert radar_coloradar.main([str(absent)]) == 2
    assert _error_line(capsys, "radar-coloradar") == f"{absent}: no such run directory"
    a_file = tmp_path / "est.tum"
    a_file.write_text("0 0 0 0 0 0 0 1\n")
    assert radar_coloradar.main([str(a_file)]) == 2
    assert _error_line(capsys, "radar-coloradar") == f"{a_file}: a file, not a ColoRadar run directory"
    run = write_run(tmp_path, frames=3)
    assert radar_coloradar.main([str(run), "--calib", str(tmp_path / "nowhere")]) == 2
    assert _error_line(capsys, "radar-coloradar") == f"{tmp_path / 'nowhere'}: no such calibration directory"
    (tmp_path / "calib").rename(tmp_path / "elsewhere")
    _both_refuse(run, capsys, tmp_path / "out")
    with pytest.raises(UsageError, match="NUL"):
        ColoRadarRun(f"{run}\0x")
    with pytest.raises(UsageError, match="is a path"):
        ColoRadarRun(str(run).encode())


def test_a_missing_data_folder_is_refused_as_an_incomplete_run(tmp_path, capsys):
    run = write_run(tmp_path, frames=3, faults=["missing_data_dir"])
    said = _both_refuse(run, capsys, tmp_path / "out")
    assert "cascade/heatmaps/data: no such folder (the run is incomplete)" in said


@pytest.mark.parametrize("stream, name", [("cascade/heatmaps", "heatmap_3.bin"),
                                          ("single_chip/pointclouds", "radar_pointcloud_3.bin")])
def test_nan_in_a_data_file_is_one_error_naming_the_file_in_both_programs(tmp_path, capsys, stream, name):
    """radar-coloradar stopped on "power holds NaN or infinite values" (no file named) while
    radar-capture went on to exit 0."""
    run = write_run(tmp_path, frames=6)
    path = run / stream / "data" / name
    values = np.frombuffer(path.read_bytes(), "<f4").copy()
    values[::7] = np.nan
    values[1] = np.inf
    path.write_bytes(values.tobytes())
    bad = int((~np.isfinite(values)).sum())
    odom = tmp_path / "odom.tum"
    assert radar_capture.main(["--source", f"coloradar://{run}?rate=max", "--no-publish", "-q",
                               "--odom-out", str(odom)]) == 2
    said = _error_line(capsys, "radar-capture")
    assert said == f"{path}: {bad} of {values.size} values are NaN or infinite"
    assert len(odom.read_text().splitlines()) >= 2  # the frames before it are kept
    assert radar_coloradar.main([str(run)]) == 2
    assert _error_line(capsys, "radar-coloradar") == said


@pytest.mark.parametrize("part", ["groundtruth/groundtruth_poses.txt", "groundtruth/timestamps.txt",
                                  "cascade/heatmaps/data/heatmap_1.bin", "cascade/heatmaps/timestamps.txt",
                                  "../calib/cascade/heatmap_cfg.txt", "../calib/transforms/base_to_cascade.txt"])
@pytest.mark.parametrize("kind", ["pipe", "device", "directory"])
def test_a_pipe_a_device_or_a_directory_in_place_of_a_runs_file_is_named_so(tmp_path, capsys, part, kind):
    # A pipe waited forever, a link to /dev/zero read until memory ran out; directories were
    # "no such file" or "missing".
    import os

    run = write_run(tmp_path / "data", frames=4)
    path = pathlib.Path(os.path.normpath(run / part))
    path.unlink()
    {"pipe": lambda: os.mkfifo(path), "device": lambda: path.symlink_to("/dev/zero"), "directory": path.mkdir}[kind]()
    said = _both_refuse(run, capsys, tmp_path / "out")
    what = ("a directory, not a file" if kind == "directory" else "not a regular file (a pipe or a device"
            ) if not part.endswith(".bin") else "not a file (a record of the run is a file of its data)"
    assert str(path) in said and what in said, said


def test_a_timestamp_out_of_any_recordings_range_is_refused_where_it_is(tmp_path, capsys):
    # 1e300 s passed the checks and overflowed the estimator's steps: "internal error: OverflowError".
    run = write_run(tmp_path / "data", frames=4)
    times = run / "cascade" / "heatmaps" / "timestamps.txt"
    lines = times.read_text().splitlines()
    times.write_text("\n".join(lines[:-1] + ["1e300"]) + "\n")
    said = _both_refuse(run, capsys, tmp_path / "out")
    assert said == f"{times}:{len(lines)}: timestamp 1e+300 s is out of range (at most 1e+10 s from 1970)"


def test_a_run_that_fails_leaves_no_new_output_and_puts_replaced_ones_back(tmp_path, capsys):
    # Its groundtruth.tum stayed behind, and the same command then said "already exists".
    run = write_run(tmp_path / "data", frames=6)  # 16 range bins: too few for the paper's CFAR window
    out = tmp_path / "tables"
    argv = [str(run), "--heatmap", "single_chip", "--out", str(out), "--json", str(tmp_path / "t.json")]
    assert radar_coloradar.main(argv) == 2
    said = _error_line(capsys, "radar-coloradar")
    # Said before the run is read, of the file that sets the heatmaps (it came after, of the settings).
    calib = tmp_path / "data" / "calib" / "single_chip" / "heatmap_cfg.txt"
    assert said == (f"{calib}: the 'CFAR' variant cannot run on these heatmaps: a window of guard 2 and train 8 "
                    "spans 21 range cells, more than the heatmap's 16 (radar-coloradar runs the paper's settings as "
                    "they are; radar-capture --source coloradar://RUN --estimator-config FILE runs others)"), said
    assert not out.exists() and not (tmp_path / "t.json").exists()
    out.mkdir()
    (out / "groundtruth.tum").write_text("an earlier run's\n")
    (tmp_path / "t.json").write_text("{}\n")
    assert radar_coloradar.main([*argv, "--overwrite"]) == 2
    capsys.readouterr()
    assert sorted(p.name for p in out.iterdir()) == ["groundtruth.tum"]
    assert (out / "groundtruth.tum").read_text() == "an earlier run's\n" and (tmp_path / "t.json").read_text() == "{}\n"
    # Part-way: the tables' TUM files written, then --json into a place that takes no file.
    good = write_run(tmp_path / "good", frames=6)
    assert radar_coloradar.main([str(good), "--out", str(out), "--json", "/proc/radarodom-test.json",
                                 "--overwrite"]) == 1
    assert "cannot write /proc/radarodom-test.json" in _error_line(capsys, "radar-coloradar")
    assert sorted(p.name for p in out.iterdir()) == ["groundtruth.tum"]
    assert (out / "groundtruth.tum").read_text() == "an earlier run's\n"


def test_negative_heatmap_intensities_are_taken_as_none_and_said_once_naming_the_file(tmp_path, capsys):
    # The paper's CFAR features stopped the run on them: "power holds negative values", no file named.
    from coloradar_synth import write_moving_run

    run = write_moving_run(tmp_path / "data")
    files = sorted((run / "cascade" / "heatmaps" / "data").iterdir())
    for path in files[2:4]:
        cells = np.fromfile(path, "<f4").reshape(-1, 2)
        cells[::2, 0] = -5.0
        cells.tofile(path)
    rc = radar_capture.main(["--source", f"coloradar://{run}?rate=max", "--no-publish", "--estimator-config",
                             str(_paper_cfar_settings(tmp_path)), "--odom-out", str(tmp_path / "o.tum")])
    err = capsys.readouterr().err
    assert rc == 0, err
    said = [ln for ln in err.splitlines() if "intensities are negative" in ln]
    assert len(said) == 1 and str(files[2]) in said[0] and "taken as 0 (said once a run)" in said[0], err


def _paper_cfar_settings(tmp_path) -> pathlib.Path:
    """The paper's settings (CFAR features), as radar-coloradar runs them."""
    from radarodom.estimator.config import paper_variants

    path = tmp_path / "paper.json"
    next(iter(paper_variants().values()))[1].dump(path)
    return path


def test_times_that_do_not_overlap_the_ground_truth_are_refused_with_both_spans(tmp_path, capsys):
    run = write_run(tmp_path / "data", frames=4)
    truth = run / "groundtruth" / "timestamps.txt"
    truth.write_text("".join(f"{float(t) + 1000:.6f}\n" for t in truth.read_text().split()))
    assert radar_coloradar.main([str(run)]) == 2
    said = _error_line(capsys, "radar-coloradar")
    assert said.startswith(f"{run}: fewer than two cascade heatmaps fall inside the ground truth: the heatmaps run "
                           "from "), said
    assert ", the ground truth run from 160859" in said and said.endswith("(s; each timestamps.txt in seconds?)"), said


def test_radar_coloradar_says_each_warning_once_not_once_a_variant(tmp_path, capsys):
    # Seven variants estimate the same frames: the same warning came seven times.
    from coloradar_synth import write_moving_run

    run = write_moving_run(tmp_path / "data")
    path = sorted((run / "single_chip" / "pointclouds" / "data").iterdir())[2]
    points = np.fromfile(path, "<f4").reshape(-1, 5)
    points[:, 4] = 3e38  # a Doppler no radar measures: the estimator leaves the points out, saying so
    points.tofile(path)
    assert radar_coloradar.main([str(run)]) == 0
    warnings = [ln for ln in capsys.readouterr().err.splitlines() if ": warning: " in ln]
    assert warnings and len(warnings) == len(set(warnings)), warnings


def test_numbers_too_large_for_metres_are_refused_where_they_are_and_quaternions_of_any_scale_read(tmp_path):
    # 1e300 m went on into the metrics: numpy's overflow warnings and an RPE of inf; a quaternion
    # of 1e-300 parts was "zero", one of 1e300 parts overflowed.
    import warnings

    run = write_run(tmp_path / "data", frames=4)
    poses = run / "groundtruth" / "groundtruth_poses.txt"
    rows = [line.split() for line in poses.read_text().splitlines()]
    mount = tmp_path / "data" / "calib" / "transforms" / "base_to_cascade.txt"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for scale in ("1e300", "1e-300"):
            rows[1][3:] = ["0", "0", scale, scale]
            poses.write_text("".join(" ".join(r) + "\n" for r in rows))
            truth = ColoRadarRun(run).groundtruth()
            np.testing.assert_allclose(truth.quaternions[1], [0, 0, 2 ** -0.5, 2 ** -0.5])
        rows[2][0] = "1e300"
        poses.write_text("".join(" ".join(r) + "\n" for r in rows))
        with pytest.raises(CaptureFormatError) as info:
            ColoRadarRun(run).groundtruth()
        assert str(info.value) == (f"{poses}:3: a position 1e+300 m from the origin (at most 1e+08 m; metres "
                                   "expected)")
        mount.write_text("1e300 0 0\n0 0 0 1\n")
        with pytest.raises(CaptureFormatError) as info:
            ColoRadarRun(run).base_to_sensor("cascade")
        assert str(info.value) == (f"{mount}:1: a sensor 1e+300 m from its base is no mounting (at most 1000 m; "
                                   "metres expected)")


def test_velocity_frames_outside_the_heatmaps_span_are_refused_with_both_spans(tmp_path, capsys):
    # Shifted by 1000 s, no velocity reached any heatmap: the odometry ran blind, exit 0, nothing said.
    run = write_run(tmp_path / "data", frames=4)
    times = run / "single_chip" / "pointclouds" / "timestamps.txt"
    times.write_text("".join(f"{float(t) + 1000:.6f}\n" for t in times.read_text().split()))
    said = _both_refuse(run, capsys, tmp_path / "out")
    assert said.startswith(f"{run}: the velocity stream's frames run from "), said
    assert said.endswith("they do not overlap (is each timestamps.txt in seconds of the same clock?)"), said
