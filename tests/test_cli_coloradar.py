"""radar-coloradar end to end on a synthetic run written in the exact ColoRadar layout:
single-chip point clouds at 10 Hz (velocity), cascade heatmaps at 5 Hz (yaw), lidar ground
truth at 20 Hz; the paper's multi-rate pipeline and its two tables."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from conftest import console_command
from coloradar_synth import write_moving_run, write_run

from radarodom.tum import read_tum

@pytest.fixture(scope="module")
def synthetic_run(tmp_path_factory):
    return write_moving_run(tmp_path_factory.mktemp("coloradar"))


def test_the_paper_pipeline_runs_and_prints_both_tables(synthetic_run, tmp_path):
    out, js = tmp_path / "out", tmp_path / "numbers.json"
    proc = subprocess.run(console_command("radar-coloradar") + [str(synthetic_run), "--out", str(out),
                                                                  "--json", str(js)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    assert "yaw RMSE [deg] by preprocessing" in text and "relative pose error [m]" in text
    assert "| paper | 4.66 | 3.09 | 2.06 |" in text  # ec_hallways_run0's published numbers beside ours
    numbers = json.loads(js.read_text())
    results = numbers["results"]
    assert set(results) == {"CFAR", "Ray-max", "Top-k", "wICP", "Sampling + wICP", "Sampling + mwICP",
                            "radarodom default"}
    # 2 degrees a heatmap frame at 5 Hz, cascade-like beams: the method follows the arc.
    assert results["radarodom default"]["yaw_rmse_deg"] < 0.5, results
    assert results["Top-k"]["yaw_rmse_deg"] < 1.5, results
    assert results["radarodom default"]["rpe_m"] < 0.02
    # The trajectories and the ground truth for radar-eval.
    gt = read_tum(out / "groundtruth.tum")
    est = read_tum(out / "radarodom_default.tum")
    assert len(gt.times) == len(est.times) >= 15
    np.testing.assert_allclose(gt.times, est.times)
    ev = subprocess.run(console_command("radar-eval") + [str(out / "radarodom_default.tum"), str(out / "groundtruth.tum")],
                        capture_output=True, text=True, timeout=120)
    assert ev.returncode == 0, ev.stderr


def test_a_run_without_point_clouds_is_refused(tmp_path):
    run = write_run(tmp_path, "aspen_run5", faults=())
    (run / "single_chip" / "pointclouds" / "timestamps.txt").unlink()
    proc = subprocess.run(console_command("radar-coloradar") + [str(run)], capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0
    assert "Traceback" not in proc.stderr and "pointclouds" in proc.stderr


def test_a_run_without_its_ground_truth_times_or_folder_is_refused_by_name(tmp_path):
    """The truth's timestamps missing is a run cut short (the file named); no ground truth at all
    is what radar-coloradar needs and says so, with the command that runs without one."""
    run = write_run(tmp_path, "aspen_run5", faults=())
    times = run / "groundtruth" / "timestamps.txt"
    times.unlink()
    proc = subprocess.run(console_command("radar-coloradar") + [str(run), "-q"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2 and proc.stderr.strip().splitlines() == [
        f"radar-coloradar: error: {times}: no such file (the run is incomplete: its ground truth has no timestamps)"]
    for path in (run / "groundtruth").iterdir():
        path.unlink()
    (run / "groundtruth").rmdir()
    proc = subprocess.run(console_command("radar-coloradar") + [str(run), "-q"], capture_output=True, text=True,
                          timeout=120)
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(err) == 1 and "the run has no ground truth (no groundtruth/ folder)" in err[0] \
        and f"radar-capture --source coloradar://{run} estimates without one" in err[0], proc.stderr


def test_outputs_are_checked_before_the_work_and_never_write_over_an_input(tmp_path, capsys):
    """--json is a new file (or --overwrite), never one of the run's files nor one --out writes;
    --out is a directory; each refused with one line, exit 2, before the run is read."""
    run = write_moving_run(tmp_path / "data")
    stamps = run / "groundtruth" / "timestamps.txt"
    before = stamps.read_bytes()
    mine = tmp_path / "mine.json"
    mine.write_text("keep\n")
    (tmp_path / "f").write_text("")

    def coloradar(*args):  # in this process (the program's own run, exit code and output)
        from radarodom.tools import radar_coloradar

        rc = radar_coloradar.main([str(run), *map(str, args)])
        out, err = capsys.readouterr()
        return subprocess.CompletedProcess(["radar-coloradar", *args], rc, out, err)

    for args, message in [
            (["--json", mine], f"{mine} already exists; choose a new file (or --overwrite)"),
            (["--json", stamps, "--overwrite"], f"--json {stamps} would write over the input RUN_DIR {run}"),
            # a new file in one of the run's folders: not "over" anything (it said so), but into the dataset
            (["--json", stamps.parent / "new.json"], f"--json {stamps.parent / 'new.json'} would write into the "
             f"input RUN_DIR {run}'s own folders: choose another path (beside them is fine)"),
            (["--out", tmp_path / "o", "--json", tmp_path / "o" / "wicp.tum"],
             f"--out and --json both name {tmp_path / 'o' / 'wicp.tum'}: give each its own"),
            # (hunt 4: the directory itself, refused only once the run's TUM files were written, and removed)
            (["--out", tmp_path / "o", "--json", tmp_path / "o"], f"--out and --json both name {tmp_path / 'o'}: "
             "give each its own"),
            (["--json", tmp_path / "nodir" / "x.json"], f"cannot create {tmp_path / 'nodir' / 'x.json'}: no directory"),
            (["--out", tmp_path / "f"], f"--out {tmp_path / 'f'} is a file, not a directory")]:
        proc = coloradar(*args)
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1, (args, proc.stderr)
        assert proc.stderr.startswith(f"radar-coloradar: error: {message}"), (args, proc.stderr)
        assert proc.stdout == ""
    # The calib/ found beside the run is read too: none of its files may be written over.
    transform = next((tmp_path / "data" / "calib" / "transforms").iterdir())
    kept = transform.read_bytes()
    proc = coloradar("--json", transform, "--overwrite")
    assert proc.returncode == 2 and "would write over the input the run's calibration" in proc.stderr
    assert transform.read_bytes() == kept
    assert mine.read_text() == "keep\n" and stamps.read_bytes() == before and not (tmp_path / "o").exists()
    # A run refused once --out is made (no single-chip heatmaps here) takes back what it made, parents too.
    proc = coloradar("--heatmap", "single_chip", "--out", tmp_path / "a" / "b" / "c")
    assert proc.returncode == 2 and not (tmp_path / "a").exists(), proc.stderr
    out = tmp_path / "o"
    assert coloradar("--out", out, "--json", out / "n.json").returncode == 0
    proc = coloradar("--out", out)
    assert proc.returncode == 2 and f"{out / 'groundtruth.tum'} already exists" in proc.stderr
    proc = coloradar("--out", out, "--json", out / "n.json", "--overwrite")
    assert proc.returncode == 0, proc.stderr
    assert json.loads((out / "n.json").read_text())["run"] == "ec_hallways_run0"
    assert len(read_tum(out / "wicp.tum")) == len(read_tum(out / "groundtruth.tum"))
