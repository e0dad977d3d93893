"""--overwrite (issue 19): an output file is replaced; an output directory only when radarodom
wrote it, and then only radarodom's files in it go; anything else is refused and left alone.
And --version on every program."""

from __future__ import annotations

import importlib
import os
import signal
import stat
import json
import re
import tomllib

import pytest
from conftest import REPO

from radarodom import __version__
from radarodom.tools import radar_capture, radar_sim

URL = "sim://calibration?rate=max&duration=0.3"


def capture(capsys, *args) -> tuple[int, str]:
    rc = radar_capture.main(["--source", URL, "--no-publish", "-q", *map(str, args)])
    return rc, capsys.readouterr().err


def test_every_program_prints_its_version(capsys):
    scripts = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["scripts"]
    assert len(scripts) >= 9
    for name, target in scripts.items():
        module, _, func = target.partition(":")
        assert getattr(importlib.import_module(module), func)(["--version"]) == 0, name
        out, err = capsys.readouterr()
        assert out == f"radarodom {__version__}\n" and err == "", name
    assert re.fullmatch(r"\d+\.\d+\.\d+", __version__)


@pytest.mark.parametrize("option, name", [("--odom-out", "odom.tum"), ("--points-out", "points.csv")])
def test_a_file_output_is_replaced_only_with_overwrite(tmp_path, capsys, option, name):
    out = tmp_path / name
    out.write_text("the user's own\n")
    rc, err = capture(capsys, option, out)
    assert rc == 2 and "already exists" in err and "--overwrite" in err
    assert out.read_text() == "the user's own\n"
    rc, err = capture(capsys, option, out, "--overwrite")
    assert rc == 0, err
    text = out.read_text()
    assert "the user's own" not in text and len(text.splitlines()) >= 2


def test_overwrite_refuses_a_directory_in_place_of_a_file(tmp_path, capsys):
    folder = tmp_path / "odom.tum"
    folder.mkdir()
    (folder / "keep").write_text("x")
    rc, err = capture(capsys, "--odom-out", folder, "--overwrite")
    assert rc == 2 and "is a directory" in err
    assert (folder / "keep").read_text() == "x"
    # Without --overwrite it is not offered as the fix: it would be refused next.
    rc, err = capture(capsys, "--odom-out", folder)
    assert rc == 2 and err.endswith(f"error: {folder} is a directory; choose a file's name (--overwrite replaces "
                                    "only a file)\n"), err


def test_a_heatmap_directory_is_replaced_keeping_other_files(tmp_path, capsys):
    out = tmp_path / "maps"
    rc, err = capture(capsys, "--heatmap-out", out, "--no-odom")
    assert rc == 0, err
    first = json.loads((out / "index.json").read_text())
    (out / "999999_intensity.npy").write_bytes(b"old")  # a heatmap of the earlier run
    (out / "notes.txt").write_text("mine")
    rc, err = capture(capsys, "--heatmap-out", out, "--no-odom")
    assert rc == 2 and "already holds heatmaps; choose a new directory (or --overwrite)" in err
    rc, err = capture(capsys, "--heatmap-out", out, "--no-odom", "--overwrite")
    assert rc == 0, err
    again = json.loads((out / "index.json").read_text())
    assert again["frames"] == first["frames"]
    assert not (out / "999999_intensity.npy").exists() and (out / "notes.txt").read_text() == "mine"
    npy = sorted(p.name for p in out.glob("*.npy"))
    assert len(npy) == 3 * len(again["frames"])


def test_a_recording_is_replaced_only_when_radarodom_wrote_it(tmp_path, capsys):
    out = tmp_path / "rec"
    rc, err = capture(capsys, "--record", out, "--no-odom")
    assert rc == 0, err
    (out / "notes.txt").write_text("mine")
    size = (out / "adc_data.bin").stat().st_size
    rc, err = capture(capsys, "--record", out, "--no-odom")
    assert rc == 2 and "already holds a capture (adc_data.bin); choose a new directory (or --overwrite)" in err
    rc, err = capture(capsys, "--record", out, "--no-odom", "--frames", "1", "--overwrite")
    assert rc == 0, err
    assert 0 < (out / "adc_data.bin").stat().st_size < size  # the new one-frame recording
    assert json.loads((out / "capture.json").read_text())["frame_count"] == 1
    assert (out / "notes.txt").read_text() == "mine"
    # A directory with someone else's adc_data.bin (no capture.json) is never replaced.
    foreign = tmp_path / "ti"
    foreign.mkdir()
    (foreign / "adc_data.bin").write_bytes(b"\x01" * 64)
    rc, err = capture(capsys, "--record", foreign, "--no-odom", "--overwrite")
    assert rc == 2 and "already holds adc_data.bin not written by radarodom (no capture.json of its own), " \
        "which a recording would replace and --overwrite leaves alone" in err
    assert (foreign / "adc_data.bin").read_bytes() == b"\x01" * 64 and len(list(foreign.iterdir())) == 1


def test_overwrite_does_not_apply_to_a_heatmap_run_over_a_capture(tmp_path, capsys):
    out = tmp_path / "rec"
    assert capture(capsys, "--record", out, "--no-odom")[0] == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    rc, err = capture(capsys, "--heatmap-out", out, "--no-odom", "--frames", "1")
    assert rc == 0, err  # heatmaps into the recording's directory: no heatmaps there yet
    rc, err = capture(capsys, "--heatmap-out", out, "--no-odom", "--overwrite", "--frames", "1")
    assert rc == 0, err  # heatmaps written beside the capture, which stays whole
    assert all((out / name).read_bytes() == data for name, data in before.items() if name != "capture.json")


def test_radar_sim_out_is_replaced_with_overwrite(tmp_path, capsys):
    out = tmp_path / "sim"
    argv = ["calibration", "--duration", "0.2", "--out", str(out), "-q"]
    assert radar_sim.main(argv) == 0
    (out / "notes.txt").write_text("mine")
    assert radar_sim.main(argv) == 2
    assert "already holds a capture (adc_data.bin); choose a new directory (or --overwrite)" in capsys.readouterr().err
    assert radar_sim.main([*argv, "--seed", "1", "--overwrite"]) == 0
    assert json.loads((out / "capture.json").read_text())["source"].endswith("seed=1")
    assert (out / "notes.txt").read_text() == "mine"
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert radar_sim.main(["calibration", "--duration", "0.2", "--out", str(blocker), "--overwrite"]) == 2
    assert "is a file" in capsys.readouterr().err and blocker.read_text() == "x"


def test_radar_sim_refuses_a_recording_the_disk_has_no_room_for_before_replacing_anything(tmp_path, capsys):
    """A --duration off by a few zeros once wrote 10 000 frames (7.8 GB) with a warning only."""
    from radarodom.cfg import RadarConfig, shipped_config_path

    out = tmp_path / "sim"
    assert radar_sim.main(["calibration", "--duration", "0.2", "--out", str(out), "-q"]) == 0
    before = (out / "adc_data.bin").read_bytes()
    cfg = RadarConfig.from_file(shipped_config_path())
    st = os.statvfs(tmp_path)
    frames = (st.f_bavail * st.f_frsize + len(before)) // cfg.frame_bytes + 1000
    duration = f"{frames * cfg.frame_period_s:.1f}"
    for target, extra in ((tmp_path / "new" / "run", []), (out, ["--overwrite"])):
        assert radar_sim.main(["calibration", "--duration", duration, "--out", str(target), "-q", *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"radar-sim: error: --out {target}: ") \
            and f"frames of {cfg.frame_bytes} bytes" in err[0] and "is free there" in err[0], err
    assert not (tmp_path / "new").exists() and (out / "adc_data.bin").read_bytes() == before


def test_two_outputs_naming_one_file_are_refused_before_anything_is_written(tmp_path, capsys):
    out = tmp_path / "odom.tum"
    rc, err = capture(capsys, "--odom-out", out, "--odom-json", out)
    assert rc == 2 and "--odom-out and --odom-json both name" in err
    assert not out.exists()  # a corrected retry is not refused by a leftover
    assert capture(capsys, "--odom-out", out, "--odom-json", tmp_path / "odom.jsonl")[0] == 0


def test_an_output_never_replaces_what_the_run_reads(tmp_path, capsys):
    rec = tmp_path / "rec"
    assert capture(capsys, "--record", rec, "--no-odom")[0] == 0
    truth = (rec / "groundtruth.tum").read_bytes()
    replay = ["--source", f"replay://{rec}?rate=max", "--no-publish", "-q"]
    for argv in (["--odom-out", rec / "groundtruth.tum"], ["--record", rec]):
        assert radar_capture.main([*replay, *map(str, argv), "--overwrite"]) == 2
        assert "would write over the input --source" in capsys.readouterr().err
    assert (rec / "groundtruth.tum").read_bytes() == truth
    cfg = tmp_path / "radar.cfg"
    cfg.write_bytes((rec / "radar.cfg").read_bytes())
    rc, err = capture(capsys, "--cfg", cfg, "--odom-out", cfg, "--overwrite")
    assert rc == 2 and "the input --cfg" in err and cfg.read_bytes() == (rec / "radar.cfg").read_bytes()
    # New files beside a replayed recording, and heatmaps into it, are fine; and so is replacing
    # them on a second run.
    assert radar_capture.main([*replay, "--odom-out", str(rec / "odom.tum"), "--heatmap-out", str(rec)]) == 0
    assert (rec / "odom.tum").exists() and (rec / "index.json").exists()
    assert radar_capture.main([*replay, "--odom-out", str(rec / "odom.tum"), "--overwrite"]) == 0


def test_overwrite_replaces_only_a_regular_file(tmp_path, capsys):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    rc, err = capture(capsys, "--odom-out", fifo, "--overwrite")
    assert rc == 2 and "is not a regular file" in err and stat.S_ISFIFO(os.lstat(fifo).st_mode)
    # Without --overwrite it said 'already exists; choose a new file (or --overwrite)', which --overwrite refused.
    for device in (fifo, "/dev/null"):
        rc, err = capture(capsys, "--odom-out", device)
        assert rc == 2 and "is not a regular file" in err and "leave the option out" in err and "already" not in err


@pytest.mark.parametrize("option", ["--record", "--odom-out", "--cfg", "--estimator-config", "--source"])
def test_an_empty_path_is_a_usage_error(tmp_path, capsys, option):
    source = [] if option == "--source" else ["--source", URL]  # an option is given once
    rc = radar_capture.main([*source, "--no-publish", "-q", option, ""])
    assert rc == 2 and f"argument {option}: empty value" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("option", ["--record", "--heatmap-out", "radar-sim --out"])
def test_a_file_where_a_directory_goes_is_a_usage_error(tmp_path, capsys, option):
    blocker = tmp_path / "run.tum"
    blocker.write_text("mine\n")
    if option == "radar-sim --out":
        rc = radar_sim.main(["calibration", "--duration", "0.2", "--out", str(blocker), "-q"])
        err = capsys.readouterr().err
    else:
        rc, err = capture(capsys, option, blocker)
    assert rc == 2 and err.endswith(f"error: {blocker} is a file, not a directory\n")
    assert blocker.read_text() == "mine\n"
    under = blocker / "run"  # a directory under the file: refused before the work, exit 2 as well
    if option == "radar-sim --out":
        rc = radar_sim.main(["calibration", "--duration", "0.2", "--out", str(under), "-q"])
        err = capsys.readouterr().err
    else:
        rc, err = capture(capsys, option, under)
    name = "--out" if option == "radar-sim --out" else option
    assert rc == 2 and err.endswith(f"error: {name} {under}: {blocker} is a file, not a directory; choose a "
                                    "writable destination\n"), err


def test_no_output_replaces_a_file_of_another_recording(tmp_path, capsys):
    """--overwrite replaced an existing recording's ground truth with this run's odometry (and
    radar-calibrate --write-cfg its cfg, radar-coloradar --out its groundtruth.tum): refused, the
    recording unchanged; a file of another name beside it is written as before."""
    from radarodom.tools import radar_cfg

    rec = tmp_path / "rec"
    assert radar_sim.main(["calibration", "--duration", "0.2", "--out", str(rec), "-q"]) == 0
    capsys.readouterr()
    before = {p.name: p.read_bytes() for p in rec.iterdir()}
    for option, name in (("--odom-out", "groundtruth.tum"), ("--points-out", "timestamps.txt")):
        rc, err = capture(capsys, option, rec / name, "--overwrite")
        assert rc == 2 and err == (f"radar-capture: error: {option} {rec / name}: {name} is a file of the recording "
                                   f"in {rec}, which no output replaces (--overwrite or not); choose another name or "
                                   "directory\n"), err
    assert radar_cfg.main(["--copy", "awr1843_raw.cfg", str(rec / "radar.cfg"), "--overwrite"]) == 2
    assert "radar.cfg is a file of the recording in" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in rec.iterdir()} == before
    rc, err = capture(capsys, "--odom-out", rec / "odom.tum")
    assert rc == 0 and (rec / "odom.tum").is_file(), err


def test_a_link_to_nothing_or_a_loop_where_a_directory_goes_is_named(tmp_path, capsys):
    """A dangling link or a link loop as --record, --heatmap-out or radar-sim --out: one line,
    exit 2, that says what it is (it was "File exists", exit 1)."""
    (tmp_path / "dang").symlink_to(tmp_path / "nowhere" / "zz")
    (tmp_path / "loopA").symlink_to(tmp_path / "loopB")
    (tmp_path / "loopB").symlink_to(tmp_path / "loopA")
    for option, name, what in (("--record", "dang", "a link to nothing"), ("--heatmap-out", "dang", "a link to nothing"),
                               ("--record", "loopA", "a link in a loop")):
        rc, err = capture(capsys, option, tmp_path / name)
        assert rc == 2 and err == (f"radar-capture: error: {option} {tmp_path / name}: {tmp_path / name} is {what}, "
                                   "not a directory; choose a directory's name\n"), err
    rc = radar_sim.main(["calibration", "--duration", "0.2", "--out", str(tmp_path / "loopA" / "run"), "-q"])
    assert rc == 2 and f"{tmp_path / 'loopA'} is a link in a loop, not a directory" in capsys.readouterr().err


def test_a_file_output_path_longer_than_the_system_takes_is_one_short_line(tmp_path, capsys):
    """5000 characters of path for --odom-out: said in one line of a few hundred characters (the
    path shortened), not 15 kB suggesting a mkdir -p that cannot work."""
    long = tmp_path / "/".join(["d" * 200] * 25) / "odom.tum"
    rc, err = capture(capsys, "--odom-out", long)
    assert rc == 2 and err.count("\n") == 1 and len(err) < 400, err
    assert "the path is longer than this system takes" in err and "mkdir" not in err, err


def test_a_device_where_a_directory_goes_is_named_a_device(tmp_path, capsys):
    """/dev/null as radar-sim --out (and under it): "a device", not "a file"."""
    rc = radar_sim.main(["calibration", "--duration", "0.2", "--out", os.devnull, "-q"])
    assert rc == 2 and capsys.readouterr().err.endswith(f"error: {os.devnull} is a device, not a directory\n")
    rc = radar_sim.main(["calibration", "--duration", "0.2", "--out", os.path.join(os.devnull, "run"), "-q"])
    assert rc == 2 and f"{os.devnull} is a device, not a directory; choose a" in capsys.readouterr().err


@pytest.mark.parametrize("option", ["--points-out", "--odom-json", "--odom-out", "--mcap", "--heatmap-out"])
def test_an_output_the_system_will_not_take_says_why_in_one_line(capsys, option):
    out = "/proc/radarodom-test-output"  # a directory no file can be made in, for root too
    rc, err = capture(capsys, option, out)
    assert rc == 1 and err.endswith(f"error: cannot create {out}: the directory /proc takes no new files (the "
                                    "system says: No such file or directory); choose a writable destination\n"), err


@pytest.mark.parametrize("option", ["--odom-out", "--points-out", "--odom-json"])
def test_a_file_name_too_long_for_the_file_system_is_refused_before_the_work(tmp_path, capsys, option):
    # It was "File name too long" with exit 1 once the source had opened.
    longest = os.pathconf(tmp_path, "PC_NAME_MAX")
    name = "x" * (longest + 1)
    rc, err = capture(capsys, option, tmp_path / name)
    assert rc == 2 and err.endswith(f"its name is {len(name)} bytes, more than the {longest} this file "
                                    "system takes; choose a shorter name\n"), err
    assert list(tmp_path.iterdir()) == []
    rc, err = capture(capsys, option, tmp_path / name[1:], "--frames", "1")
    assert rc == 0, err


def test_an_output_directory_is_made_with_its_parents(tmp_path, capsys):
    rc, err = capture(capsys, "--heatmap-out", tmp_path / "a" / "b" / "maps", "--record", tmp_path / "c" / "rec",
                      "--frames", "1")
    assert rc == 0, err
    assert (tmp_path / "a" / "b" / "maps" / "index.json").exists()
    assert (tmp_path / "c" / "rec" / "capture.json").exists()


def _overwrite_run(program: str, out, tmp_path, capsys) -> tuple[int, str, str]:
    """Run *program* writing its one file output to *out* with --overwrite: its exit code, stdout
    and stderr."""
    from radarodom.tools import radar_calibrate, radar_cfg, radar_eval

    if program == "radar-capture --odom-out":
        rc = radar_capture.main(["--source", URL, "--no-publish", "-q", "--odom-out", str(out), "--overwrite"])
    elif program == "radar-cfg --copy":
        rc = radar_cfg.main(["--copy", "awr1843_raw", str(out), "--overwrite"])
    elif program == "radar-calibrate --write-cfg":
        rc = radar_calibrate.main(["--source", "sim://calibration?rate=max", "--distance", "3", "--frames", "4",
                                   "--write-cfg", str(out), "--overwrite"])
    else:
        truth = tmp_path / "gt.tum"
        truth.write_text("0 0 0 0 0 0 0 1\n0.1 0.1 0 0 0 0 0 1\n0.2 0.2 0 0 0 0 0 1\n")
        rc = radar_eval.main([str(truth), str(truth), "--json", str(out), "--overwrite", "-q"])
    captured = capsys.readouterr()
    return rc, captured.out, captured.err


PROGRAMS = ["radar-capture --odom-out", "radar-cfg --copy", "radar-calibrate --write-cfg", "radar-eval --json"]


@pytest.mark.parametrize("program", PROGRAMS)
def test_overwrite_replaces_a_link_not_the_file_it_names(tmp_path, capsys, program):
    theirs = tmp_path / "elsewhere.txt"
    theirs.write_text("the user's own\n")
    out = tmp_path / "out"
    out.symlink_to(theirs)
    rc, stdout, err = _overwrite_run(program, out, tmp_path, capsys)
    assert rc == 0, err
    assert not out.is_symlink() and out.stat().st_size > 0
    assert theirs.read_text() == "the user's own\n"
    assert sorted(p.name for p in tmp_path.iterdir() if p.name != "gt.tum") == ["elsewhere.txt", "out"]


@pytest.mark.parametrize("program", PROGRAMS[1:])
def test_a_file_output_is_written_beside_itself_under_a_name_of_its_own(tmp_path, capsys, program):
    out = tmp_path / "out"
    out.write_text("before\n")
    out.chmod(0o640)
    (tmp_path / "out.tmp").symlink_to(tmp_path / "victim")  # a name the new copy must not take
    rc, stdout, err = _overwrite_run(program, out, tmp_path, capsys)
    assert rc == 0, err
    assert (out.stat().st_mode & 0o777) == 0o640 and out.read_text() != "before\n"  # replaced, its mode kept
    assert not (tmp_path / "victim").exists() and (tmp_path / "out.tmp").is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name != "gt.tum") == ["out", "out.tmp"]


@pytest.mark.parametrize("program", PROGRAMS[1:])
def test_a_file_output_that_cannot_be_made_is_one_line(tmp_path, capsys, program):
    out = "/proc/radarodom-test-output"  # a directory no file can be made in, for root too
    rc, stdout, err = _overwrite_run(program, out, tmp_path, capsys)
    what = "the copy of awr1843_raw.cfg to " if program == "radar-cfg --copy" else ""
    assert rc == 1 and err.endswith(f"error: cannot write {what}{out}: the directory /proc takes no new files (the "
                                    "system says: No such file or directory); choose a writable destination\n"), err
    assert err.count("\n") == 1
    if program == "radar-calibrate --write-cfg":  # the measurement is not lost with the file
        assert stdout.startswith("compRangeBiasAndRxChanPhase ")


@pytest.mark.parametrize("program", PROGRAMS)
def test_a_file_output_whose_path_ends_in_a_slash_is_refused_before_the_work(tmp_path, capsys, program):
    """'nodir/' passed the checks (made on the path without its '/') and failed after the work:
    'Is a directory' or 'Not a directory', exit 1, radar-calibrate's measurement made first."""
    out = f"{tmp_path / 'nodir'}/"
    rc, stdout, err = _overwrite_run(program, out, tmp_path, capsys)
    lead = {"radar-capture --odom-out": f"--odom-out {out}", "radar-eval --json": f"--json {out}",
            "radar-cfg --copy": f"cannot write the copy of awr1843_raw.cfg to {out}",
            "radar-calibrate --write-cfg": f"cannot create {out}"}[program]
    assert rc == 2 and err.endswith(f"error: {lead}: the path ends in '/', which names a directory; give a "
                                    "file's name\n"), err
    assert err.count("\n") == 1 and stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) in ([], ["gt.tum"])


def test_file_outputs_may_go_into_the_directories_the_run_makes(tmp_path, capsys):
    rec, maps = tmp_path / "out" / "rec", tmp_path / "out" / "maps"
    rc, err = capture(capsys, "--record", rec, "--odom-out", rec / "odom.tum", "--heatmap-out", maps,
                      "--points-out", maps / "points.csv")
    assert rc == 0, err
    assert (rec / "capture.json").exists() and len((rec / "odom.tum").read_text().splitlines()) >= 2
    assert (maps / "index.json").exists() and (maps / "points.csv").exists()
    rc, err = capture(capsys, "--record", rec, "--odom-out", rec / "odom.tum", "--overwrite")
    assert rc == 0, err


@pytest.mark.parametrize("directory, name", [("--record", "timestamps.txt"), ("--record", "adc_data.bin"),
                                             ("--heatmap-out", "index.json"), ("--heatmap-out", "000003_static.npy")])
def test_a_file_output_never_names_a_file_of_a_directory_output(tmp_path, capsys, directory, name):
    out = tmp_path / "dir"
    rc, err = capture(capsys, directory, out, "--odom-out", out / name)
    assert rc == 2 and err.endswith(f"error: --odom-out {out / name} is a file {directory} writes: "
                                    "choose another name\n")
    assert not out.exists()


def test_an_output_file_in_a_directory_that_is_not_there_is_a_usage_error(tmp_path, capsys):
    from radarodom.tools import radar_eval

    rc, err = capture(capsys, "--odom-out", tmp_path / "nodir" / "odom.tum")
    assert rc == 2 and err.endswith(f"error: cannot create {tmp_path / 'nodir' / 'odom.tum'}: "
                                    f"no directory {tmp_path / 'nodir'}; make it first (mkdir -p {tmp_path / 'nodir'}) "
                                    "or choose a writable destination\n")
    truth = tmp_path / "gt.tum"
    truth.write_text("0 0 0 0 0 0 0 1\n0.1 0.1 0 0 0 0 0 1\n")
    assert radar_eval.main([str(truth), str(truth), "--json", str(tmp_path / "nodir" / "e.json"), "-q"]) == 2
    assert not (tmp_path / "nodir").exists()


def test_radar_calibrate_never_writes_over_what_it_reads(tmp_path, capsys):
    from radarodom.tools import radar_calibrate, radar_cfg

    cfg = tmp_path / "board.cfg"
    assert radar_cfg.main(["--copy", "awr1843_raw", str(cfg)]) == 0
    before = cfg.read_bytes()
    rec = tmp_path / "rec"
    assert radar_sim.main(["calibration", "--duration", "0.5", "--out", str(rec), "-q"]) == 0
    recorded = (rec / "radar.cfg").read_bytes()
    capsys.readouterr()
    for source, given, out, what, extra in (
            ("sim://calibration?rate=max", ["--cfg", str(cfg)], cfg, f"--cfg {cfg}", []),
            ("sim://calibration?rate=max", ["--cfg", str(cfg)], cfg, f"--cfg {cfg}", ["--overwrite"]),
            (f"replay://{rec}?rate=max", [], rec / "radar.cfg", f"--source {rec}", ["--overwrite"])):
        rc = radar_calibrate.main(["--source", source, "--distance", "3", "--frames", "3", *given,
                                   "--write-cfg", str(out), *extra])
        err = capsys.readouterr().err
        assert rc == 2 and err.endswith(f"error: --write-cfg {out} would write over the input {what}: "
                                        "choose another path\n"), err
    assert cfg.read_bytes() == before and (rec / "radar.cfg").read_bytes() == recorded
    assert radar_calibrate.main(["--source", f"replay://{rec}?rate=max", "--distance", "3", "--frames", "3",
                                 "--write-cfg", str(rec / "measured.cfg")]) == 0  # beside it: fine


def test_a_file_output_never_names_a_directory_output(tmp_path, capsys):
    rc, err = capture(capsys, "--heatmap-out", tmp_path / "hm", "--odom-out", tmp_path / "hm")
    assert rc == 2 and "--odom-out and --heatmap-out both name" in err
    assert list(tmp_path.iterdir()) == []


def test_overwrite_leaves_every_output_when_the_recording_directory_is_not_radarodoms(tmp_path, capsys):
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "adc_data.bin").write_bytes(b"\x01" * 64)  # another tool's capture
    old = tmp_path / "old.tum"
    old.write_text("mine\n")
    rc, err = capture(capsys, "--record", foreign, "--odom-out", old, "--overwrite")
    assert rc == 2 and "already holds adc_data.bin not written by radarodom" in err
    assert old.read_text() == "mine\n" and sorted(p.name for p in foreign.iterdir()) == ["adc_data.bin"]


def test_a_run_that_fails_before_its_first_frame_leaves_no_output_behind(tmp_path, capsys):
    # The bag cannot be made after the other outputs opened: each is taken back, so the same
    # command with the bag elsewhere runs (it found "already exists" before).
    pytest.importorskip("rosbags.typesys")
    pytest.importorskip("mcap.writer")
    run = tmp_path / "out" / "run"
    outputs = ["--record", run, "--odom-out", run / "odom.tum", "--points-out", tmp_path / "p.csv",
               "--odom-json", tmp_path / "o.jsonl"]
    rc, err = capture(capsys, *outputs, "--mcap", "/proc/radarodom-test.mcap")
    assert rc == 1 and "cannot create /proc/radarodom-test.mcap" in err
    assert list(tmp_path.iterdir()) == [tmp_path / "out"] and list((tmp_path / "out").iterdir()) == []
    rc, err = capture(capsys, *outputs, "--mcap", tmp_path / "run.mcap")
    assert rc == 0, err
    assert len((run / "odom.tum").read_text().splitlines()) >= 2 and (tmp_path / "run.mcap").stat().st_size > 0


def test_an_output_in_a_read_only_directory_is_refused_before_the_work(tmp_path, capsys, monkeypatch):
    # Root writes anywhere, so the directory is read-only as os.access tells it (the check asks it).
    locked = tmp_path / "locked"
    locked.mkdir()
    (locked / "odom.tum").write_text("old\n")
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: os.fspath(path) != str(locked)
                        and real_access(path, mode, **kw))
    for name, extra in (("new.tum", []), ("odom.tum", ["--overwrite"])):  # a replacement is a new file too
        rc, err = capture(capsys, "--odom-out", locked / name, *extra)
        assert rc == 2 and err.endswith(f"cannot create {locked / name}: the directory {locked} is not writable; "
                                        "choose a writable destination\n"), err
    assert (locked / "odom.tum").read_text() == "old\n"
    rc, err = capture(capsys, "--record", locked / "run" / "rec")  # a new directory, made with its parents
    assert rc == 2 and f"--record {locked / 'run' / 'rec'}: the directory {locked} is not writable" in err
    assert sorted(p.name for p in locked.iterdir()) == ["odom.tum"]
    # An existing directory is written into, whatever is above it.
    (locked / "existing").mkdir()
    rc, err = capture(capsys, "--record", locked / "existing")
    assert rc == 0, err


def test_a_ctrl_c_while_a_program_imports_is_one_line(monkeypatch, capsys):
    # The programs' modules take tenths of a second to import (numpy, scipy): a Ctrl-C then ended
    # in Python's traceback, before the program's own handling was in place.
    from radarodom.tools import launch

    def interrupted(name, *args, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(importlib, "import_module", interrupted)
    assert launch.radar_capture(["--version"]) == 130
    assert capsys.readouterr().err == "radar-capture: interrupted\n"


def test_a_ctrl_c_while_a_programs_options_are_parsed_is_one_line(monkeypatch, capsys):
    # radar-echo and others build their parser before the program's handling is in place.
    import argparse

    from radarodom.tools import launch

    def interrupted(self, *args, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", interrupted)
    for name in ("radar_echo", "radar_cfg", "radar_capture"):
        assert getattr(launch, name)(["--version"]) == 130
        assert capsys.readouterr().err == f"{name.replace('_', '-')}: interrupted\n"


def test_a_ctrl_c_python_wrapped_in_another_error_is_still_an_interruption(capsys):
    # A Ctrl-C while a class is made (a lazy import's dataclass, in __set_name__) reaches the
    # program as a RuntimeError: it is not an internal error.
    import argparse

    from radarodom.tools import cli

    class Interrupting:
        def __set_name__(self, owner, name):
            raise KeyboardInterrupt

    def work(args):
        type("Made", (), {"field": Interrupting()})

    parser = argparse.ArgumentParser(prog="radar-test")
    assert cli.run(work, parser, []) == 130
    assert capsys.readouterr().err == "radar-test: interrupted\n"

    def bug(args):
        raise RuntimeError("a real bug")

    assert cli.run(bug, parser, []) == 1
    assert "radar-test: internal error: RuntimeError: a real bug" in capsys.readouterr().err


def test_a_directory_path_longer_than_the_system_takes_is_refused_before_any_is_made(tmp_path, capsys):
    """25 names of 200 characters: the recording made 20 nested directories, then failed with a
    message of some 5000 characters."""
    long = tmp_path.joinpath(*["c" * 200] * 25)
    rc, err = capture(capsys, "--record", long)
    assert rc == 2 and err.count("\n") == 1 and len(err) < 400, err
    assert "the path is longer than this system takes" in err and f"({len(str(long))} characters)" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("short_of_path_max", [1, 5, 15, 16, 17, 40])
def test_a_path_within_its_files_names_of_the_systems_limit_is_refused_before_any_is_made(tmp_path, capsys,
                                                                                          short_of_path_max):
    """Paths 15-17 bytes short of PATH_MAX passed the check (it allowed for '/index.json.tmp' and
    not the NUL), made 20 nested directories and failed on '.capture.json...tmp' (exit 1)."""
    target = os.pathconf(tmp_path, "PC_PATH_MAX") - short_of_path_max
    parts, length = [], len(str(tmp_path))
    while target - length > 202:  # the last name gets 1 to 201 characters (an empty one added no '/')
        parts.append("c" * 200)
        length += 201
    parts.append("d" * (target - length - 1))
    long = tmp_path.joinpath(*parts)
    assert len(os.fsencode(str(long))) == target
    rc, err = capture(capsys, "--record", long)
    assert rc == 2 and "the path is longer than this system takes" in err, err
    assert list(tmp_path.iterdir()) == []


def _tree(folder) -> dict:
    """Every file under *folder* (hidden ones too) and its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_overwrite_keeps_every_old_output_when_the_run_fails_before_its_first_frame(tmp_path, capsys):
    # It removed them all first: a later output that could not be made lost the earlier run's.
    rec, odom, points = tmp_path / "rec", tmp_path / "odom.tum", tmp_path / "points.csv"
    assert radar_sim.main(["calibration", "--duration", "0.2", "--out", str(rec), "-q"]) == 0
    (rec / "notes.txt").write_text("mine")
    odom.write_text("the earlier run's\n")
    points.write_text("the earlier run's points\n")
    before = _tree(tmp_path)
    rc, err = capture(capsys, "--record", rec, "--odom-out", odom, "--points-out", points,
                      "--odom-json", "/proc/radarodom-test.jsonl", "--overwrite")
    assert rc == 1 and "cannot create /proc/radarodom-test.jsonl" in err, err
    assert _tree(tmp_path) == before  # byte for byte, and nothing hidden left beside them
    rc, err = capture(capsys, "--record", rec, "--odom-out", odom, "--points-out", points, "--overwrite")
    assert rc == 0, err
    after = _tree(tmp_path)
    assert sorted(after) == sorted(before) and not any(name.startswith(".") or "/." in name for name in after)
    assert after["odom.tum"] != before["odom.tum"] and after["rec/adc_data.bin"] != before["rec/adc_data.bin"]
    assert after["rec/notes.txt"] == b"mine"


@pytest.mark.parametrize("kind", ["capture", "heatmaps"])
def test_replaced_outputs_wait_aside_until_new_ones_hold_data(tmp_path, kind):
    from radarodom.tools.replaced_outputs import ReplacedOutputs

    out = tmp_path / "out"
    if kind == "capture":
        assert radar_sim.main(["calibration", "--duration", "0.2", "--out", str(out), "-q"]) == 0
    else:
        assert capture_heatmaps(out) == 0
    (out / "notes.txt").write_text("mine")
    single = tmp_path / "odom.tum"
    single.write_text("old\n")
    # A killed run's leftover (a container gives every run the same PID): never touched.
    leftover = tmp_path / ".radarodom-replaced-1"
    leftover.mkdir()
    (leftover / "odom.tum").write_text("a killed run's\n")
    before = _tree(tmp_path)
    outputs = [(str(out), kind), (str(single), "file"), (str(tmp_path / "absent.tum"), "file")]
    aside = ReplacedOutputs(outputs)
    visible = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file()
                     and not any(part.startswith(".radarodom-replaced-") and part != leftover.name
                                 for part in p.relative_to(tmp_path).parts))
    assert visible == [".radarodom-replaced-1/odom.tum", "out/notes.txt"]  # only what radarodom wrote went
    aside.settle()  # the run wrote nothing: each put back
    assert _tree(tmp_path) == before
    aside = ReplacedOutputs(outputs)
    single.write_text("")  # an empty new file holds nothing ...
    aside.drop_replaced()
    single.write_text("new\n")  # ... one with a byte does: its old one goes at once
    aside.drop_replaced()
    assert [p.name for p in tmp_path.glob(".radarodom-replaced-*")] == [leftover.name]  # its own went with it
    aside.settle()
    after = _tree(tmp_path)
    assert after == {**before, "odom.tum": b"new\n"}  # the directory put back, the file replaced


@pytest.mark.skipif(not hasattr(signal, "SIGXFSZ"), reason="needs a POSIX file-size limit to make the write fail")
def test_overwrite_puts_the_old_recording_back_when_the_first_frame_cannot_be_written(tmp_path):
    # The run counted the frame before its recording failed to write it: the old recording was
    # removed and the new one, empty, too; both runs lost.
    import resource
    import subprocess
    import sys

    rec = tmp_path / "rec"
    assert radar_sim.main(["calibration", "--duration", "0.3", "--out", str(rec), "-q"]) == 0
    (tmp_path / "odom.tum").write_text("the earlier run's\n")
    before = _tree(tmp_path)

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails instead of killing
        resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, 100_000))  # less than one frame (786 kB)

    proc = subprocess.run([sys.executable, "-m", "radarodom.tools.radar_capture", "--source", URL, "--no-publish",
                           "--record", str(rec), "--odom-out", str(tmp_path / "odom.tum"), "--overwrite"],
                          capture_output=True, text=True, timeout=300, preexec_fn=small_files)
    assert proc.returncode == 1 and "writing frame 0" in proc.stderr, proc.stderr
    assert _tree(tmp_path) == before


def capture_heatmaps(out) -> int:
    return radar_capture.main(["--source", URL, "--no-publish", "--no-odom", "-q", "--heatmap-out", str(out)])


@pytest.mark.skipif(not hasattr(signal, "SIGXFSZ"), reason="needs a POSIX file-size limit to make the write fail")
def test_a_first_frame_that_cannot_be_written_leaves_no_output_file_behind(tmp_path):
    # The frame was counted before its recording failed: the other outputs, holding nothing
    # whole, stayed (an empty odom.tum, a header-only CSV) and blocked the same command's rerun.
    import resource
    import subprocess
    import sys

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, 100_000))  # less than one frame (786 kB)

    argv = [sys.executable, "-m", "radarodom.tools.radar_capture", "--source", URL, "--no-publish",
            "--record", str(tmp_path / "rec"), "--odom-out", str(tmp_path / "odom.tum"),
            "--points-out", str(tmp_path / "points.csv"), "--odom-json", str(tmp_path / "odom.jsonl")]
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=300, preexec_fn=small_files)
    assert proc.returncode == 1 and "writing frame 0" in proc.stderr, proc.stderr
    assert list(tmp_path.iterdir()) == []
    assert subprocess.run(argv, capture_output=True, text=True, timeout=300).returncode == 0  # the rerun
