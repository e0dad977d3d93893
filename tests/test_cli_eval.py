"""radar-eval, the command-line program: the table, --json, --plot, and errors
as one line with exit status 2."""

from __future__ import annotations

import json
import math
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from conftest import console_command
from test_evaluation import drive, integrate, write_tum

from radarodom.estimator.evaluation import evaluate, se2_compose
from radarodom.estimator.heading_metrics import heading_metrics
from radarodom.tools import radar_eval
from radarodom.tum import read_tum


def run_eval_script(*args) -> subprocess.CompletedProcess:
    """The console script in a subprocess: the end-to-end check, and the runs given a pipe or a device
    as a file (a regression would hang, or fill the memory of, the child and not the tests)."""
    return subprocess.run(console_command("radar-eval") + [str(a) for a in args], stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=120)


@pytest.fixture
def run_eval(run_main):
    """radar-eval in this process (conftest's run_main): what these tests check is its answer."""
    return lambda *args: run_main("radar-eval", *args)


@pytest.fixture
def run_files(tmp_path):
    """(estimate, ground truth) TUM files of a 20 s run with a biased, noisy estimate."""
    t, ref, est = drive(200, seed=3, scale=1.03, yaw_bias_deg=0.1, trans_noise_m=0.003, yaw_noise_deg=0.3)
    return write_tum(tmp_path / "est.tum", t, est), write_tum(tmp_path / "gt.tum", t, ref)


def test_prints_the_table(run_files):
    est, gt = run_files
    proc = run_eval_script(est, gt)  # the console script itself, end to end (the other runs are in-process)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    out = proc.stdout
    assert out.startswith(f"{est} against {gt}\n  200 poses matched")
    result = evaluate(read_tum(est), read_tum(gt))
    rows = {line[:32].strip(): line[32:].split() for line in out.splitlines()
            if line.startswith(("RPE", "yaw", "ATE"))}
    assert list(rows) == ["RPE per frame, translation m", "RPE per frame, rotation deg",
                          "RPE per 1 m, translation m", "RPE per 1 m, translation %", "RPE per 1 m, rotation deg",
                          "yaw-increment error deg", "ATE (Umeyama-aligned) m"]
    assert float(rows["yaw-increment error deg"][0]) == pytest.approx(result.yaw_rmse_deg, abs=6e-5)
    assert rows["RPE per frame, rotation deg"][-1] == "199"
    assert f"final drift (aligned at the first pose): {result.drift_m:.3f} m" in out


def test_json_and_plots(run_files, tmp_path):
    pytest.importorskip("matplotlib", reason="--plot needs matplotlib (the plot or test extra)")
    est, gt = run_files
    # A subprocess: the plots' work (seconds) dominates, and in this process it was no quicker.
    proc = run_eval_script(est, gt, "--json", tmp_path / "eval.json", "--plot", tmp_path / "plots", "--delta-m", "2")
    assert proc.returncode == 0, proc.stderr
    data = json.loads((tmp_path / "eval.json").read_text())
    result = evaluate(read_tum(est), read_tum(gt), delta_m=2.0)
    heading = data.pop("heading")
    assert data == json.loads(json.dumps(result.to_dict()))
    expected = heading_metrics(result.times, result.ref, result.est).to_dict()
    assert {k: v for k, v in heading.items() if k != "drift_parts"} == json.loads(json.dumps(expected))
    assert data["rpe_per_distance"]["delta_m"] == 2.0 and "RPE per 2 m, rotation deg" in proc.stdout
    names = ["report.png", "trajectories.png", "yaw.png", "speed.png", "position_error.png", "yaw_error.png",
             "yaw_cumulative_error.png"]  # no flags.png without --flags
    assert proc.stdout.splitlines()[-1] == "plots: " + ", ".join(str(tmp_path / "plots" / n) for n in names)
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == sorted(names)
    for name in names:
        png = (tmp_path / "plots" / name).read_bytes()
        assert png.startswith(b"\x89PNG\r\n\x1a\n") and len(png) > 10_000, name


def test_json_without_matplotlib_plot_asks_for_the_extra(run_files, tmp_path, monkeypatch, capsys):
    est, gt = run_files
    for name in {"matplotlib", *(m for m in sys.modules if m.startswith("matplotlib."))}:
        monkeypatch.setitem(sys.modules, name, None)  # as if it were not installed
    assert radar_eval.main([est, gt, "--json", str(tmp_path / "a.json")]) == 0
    assert json.loads((tmp_path / "a.json").read_text())["poses"]["matched"] == 200
    capsys.readouterr()
    assert radar_eval.main([est, gt, "--plot", str(tmp_path / "plots")]) == 2
    err = capsys.readouterr().err
    assert err == 'radar-eval: error: plots need matplotlib: pip install "radarodom[plot]"\n'
    assert not (tmp_path / "plots").exists()


def test_a_malformed_line_is_one_error_line_with_file_and_line(run_files, tmp_path, run_eval):
    est, gt = run_files
    lines = pathlib.Path(est).read_text().splitlines(keepends=True)
    lines[41] = "1004.1 0.5 oops 0 0 0 0 1\n"
    bad = tmp_path / "bad.tum"
    bad.write_text("".join(lines))
    proc = run_eval(bad, gt)
    assert proc.returncode == 2
    assert proc.stderr == (f"radar-eval: error: {bad}:42: expected 't x y z qx qy qz qw', "
                           f"got '1004.1 0.5 oops 0 0 0 0 1'\n")
    assert proc.stdout == ""
    verbose = run_eval(bad, gt, "--verbose")
    assert verbose.returncode == 2 and "Traceback" in verbose.stderr


def test_no_common_times_and_missing_files_exit_2(run_files, tmp_path, run_eval):
    est, gt = run_files
    shifted = read_tum(est)
    late = write_tum(tmp_path / "late.tum", shifted.times + 60.0, shifted.se2())
    proc = run_eval(late, gt)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1 and f"{late} (200 poses, t 1060.000 .. 1079.900 s)" in proc.stderr
    assert f"{gt} (200 poses, t 1000.000 .. 1019.900 s)" in proc.stderr
    proc = run_eval(tmp_path / "nope.tum", gt)
    assert (proc.returncode, proc.stderr) == (2, f"radar-eval: error: {tmp_path / 'nope.tum'}: no such file\n")
    # --odom a pipe no one writes to waited forever, /dev/zero read until the memory ran out.
    os.mkfifo(tmp_path / "odom.fifo")
    for odom in (tmp_path / "odom.fifo", "/dev/zero"):
        proc = run_eval_script(est, gt, "--odom", odom)  # (a subprocess: a regression hangs or fills it)
        assert (proc.returncode, proc.stderr) == (2, f"radar-eval: error: --odom {odom}: not a file\n")


def test_bad_options_are_usage_errors(run_files, run_eval):
    est, gt = run_files
    for option in (["--delta-m", "0"], ["--max-diff", "-1"]):
        proc = run_eval(est, gt, *option)
        assert proc.returncode == 2 and "expected a number > 0" in proc.stderr, option


# =========================================================================== issue 18: no NaN in JSON
def _strict(text: str):
    def refuse(name):
        raise AssertionError(f"{name} in the --json file: not JSON")
    return json.loads(text, parse_constant=refuse)


def test_json_of_a_run_that_never_moves_says_null(tmp_path, run_eval):
    """Regression (issue 18): a path of zero length leaves the drift in % and every per-distance
    figure undefined; --json writes them as null (standard JSON), never NaN."""
    t = 1000.0 + np.arange(5) / 10.0
    still = np.zeros((5, 3))
    est, gt = write_tum(tmp_path / "est.tum", t, still), write_tum(tmp_path / "gt.tum", t, still)
    proc = run_eval(est, gt, "--json", tmp_path / "eval.json")
    assert proc.returncode == 0, proc.stderr
    data = _strict((tmp_path / "eval.json").read_text())
    assert data["final_drift"] == {"position_m": 0.0, "percent_of_path": None, "yaw_deg": 0.0}
    assert data["rpe_per_distance"]["translation_m"] == {
        "rmse": None, "mean": None, "median": None, "std": None, "min": None, "max": None, "n": 0}
    assert "- % of the path" in proc.stdout


def test_json_of_coordinates_that_overflow_says_null_with_one_warning(tmp_path, run_eval):
    """Regression (issue 18): positions near the float limit made path lengths and errors
    infinite, and --json wrote "Infinity" (and numpy printed a RuntimeWarning per operation):
    now one warning, and null in the file."""
    t = 1000.0 + np.arange(3) / 10.0
    ref = np.array([[-1e308, 0.0, 0.0], [1e308, 0.0, 0.0], [-1e308, 0.0, 0.0]])
    est, gt = write_tum(tmp_path / "est.tum", t, ref[::-1]), write_tum(tmp_path / "gt.tum", t, ref)
    proc = run_eval(est, gt, "--json", tmp_path / "eval.json")
    assert proc.returncode == 0, proc.stderr
    text = (tmp_path / "eval.json").read_text()
    assert "Infinity" not in text and "NaN" not in text
    data = _strict(text)
    assert data["reference_path_length_m"] is None and data["estimate_path_length_m"] is None
    assert data["poses"]["matched"] == 3
    assert proc.stderr.count("\n") == 1 and "radar-eval: warning: the coordinates are too large" in proc.stderr
    assert "null in --json" in proc.stderr and "RuntimeWarning" not in proc.stderr
    # The table keeps its columns: a figure near the float limit in exponent form, not 309 digits.
    rows = [ln for ln in proc.stdout.splitlines() if ln.startswith(("RPE per frame, translation m", "ATE"))]
    assert rows and all(len(ln) == len("RPE per frame, translation m".ljust(32)) + 6 * 10 + 7 for ln in rows), rows


def test_plots_of_coordinates_that_overflow_are_refused_before_any_output(tmp_path, run_eval):
    # matplotlib cannot scale an axis that overflows: "radar-eval: internal error: ValueError:
    # 'box_aspect' and 'fig_aspect' must be positive" after the table and the --json file.
    pytest.importorskip("matplotlib")
    t = 1000.0 + np.arange(3) / 10.0
    ref = np.array([[-1e308, 0.0, 0.0], [1e308, 0.0, 0.0], [-1e308, 0.0, 0.0]])
    est, gt = write_tum(tmp_path / "est.tum", t, ref[::-1]), write_tum(tmp_path / "gt.tum", t, ref)
    proc = run_eval(est, gt, "--plot", tmp_path / "plots", "--json", tmp_path / "eval.json")
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == ("radar-eval: error: --plot: the coordinates are too large to draw: lengths overflow (are "
                           "the files in metres?); without --plot the table shows what can be computed\n")
    assert proc.stdout == "" and not (tmp_path / "eval.json").exists()
    assert not list((tmp_path / "plots").glob("*.png"))


def test_a_plot_directory_the_system_will_not_make_says_why_and_the_fix(tmp_path, run_eval):
    # It was "cannot create /proc/plots: No such file or directory": neither the directory that
    # refused nor what to do.
    pytest.importorskip("matplotlib")
    if not os.path.isdir("/proc/self"):
        pytest.skip("no /proc")
    t = np.arange(5) / 10.0
    ref = np.column_stack([t, np.zeros(5), np.zeros(5)])
    est, gt = write_tum(tmp_path / "est.tum", t, ref), write_tum(tmp_path / "gt.tum", t, ref)
    proc = run_eval(est, gt, "--plot", "/proc/plots", "-q")
    assert proc.returncode == 1
    assert proc.stderr == ("radar-eval: error: cannot create the plot directory /proc/plots: the directory /proc "
                           "takes no new files (the system says: No such file or directory); choose a writable "
                           "destination\n")


def test_the_table_keeps_its_columns_for_large_errors(tmp_path, run_eval):
    # 1e4-1e6 m figures took 11 characters in a 10-character column: the cells ran together.
    t = np.arange(20) / 10.0
    ref = np.column_stack([t, np.zeros(20), np.zeros(20)])
    est = np.column_stack([t * 3e5, -t * 2e5, np.zeros(20)])
    proc = run_eval(write_tum(tmp_path / "est.tum", t, est), write_tum(tmp_path / "gt.tum", t, ref))
    assert proc.returncode == 0, proc.stderr
    header = next(ln for ln in proc.stdout.splitlines() if ln.strip().startswith("rmse"))
    rows = [ln for ln in proc.stdout.splitlines() if ln.startswith(("RPE", "yaw-increment", "ATE"))]
    assert len(rows) == 7 and all(len(ln) == len(header) for ln in rows), rows
    assert all(len(ln[32:-7].split()) == 6 for ln in rows), rows  # six cells apart on every row


# =========================================================================== issue 20: heading figures
def _loop(rate_hz: float = 10.0):
    """A base's loop as body-frame steps (n, 3) at *rate_hz*, and each step's kind: 4 m straight at
    0.8 m/s, a 90 degree turn in place at 45 deg/s, 4 m straight, a 90 degree moving turn (0.8 m/s,
    45 deg/s), 4 m straight."""
    dt = 1.0 / rate_hz
    straight = [((0.8 * dt, 0.0, math.radians(0.0)), "straight")] * 50
    in_place = [((0.0, 0.0, math.radians(45.0) * dt), "in place")] * 20
    moving = [((0.8 * dt, 0.0, math.radians(45.0) * dt), "moving")] * 20
    steps = straight + in_place + straight + moving + straight
    return np.array([s for s, _ in steps]), np.array([k for _, k in steps])


def _with_errors(steps, kinds, *, straight_rad=0.0, in_place=1.0, moving=1.0):
    out = steps.copy()
    out[kinds == "straight", 2] += straight_rad
    out[kinds == "in place", 2] *= in_place
    out[kinds == "moving", 2] *= moving
    return out


def test_heading_figures_of_straights_and_turns(tmp_path, run_eval):
    """radar-eval prints (and --json writes) the heading figures of docs/heading.md: the straight
    drives' heading bias, each kind of turn's measured share of the truth's, and the drift each
    kind of frame's yaw errors make alone."""
    steps, kinds = _loop()
    t = 100.0 + np.arange(len(steps) + 1) / 10.0
    est_steps = _with_errors(steps, kinds, straight_rad=math.radians(0.01), in_place=1.05, moving=0.97)
    gt = write_tum(tmp_path / "gt.tum", t, integrate(steps))
    est = write_tum(tmp_path / "est.tum", t, integrate(est_steps))
    proc = run_eval(est, gt, "--json", tmp_path / "eval.json")
    assert proc.returncode == 0, proc.stderr
    h = _strict((tmp_path / "eval.json").read_text())["heading"]
    # Straight: 150 frames of 0.08 m, each 0.01 degree off (the straight frames after a turn too).
    assert h["straight_frames"] == 150 and h["straight_m"] == pytest.approx(12.0)
    assert h["straight_bias_deg_per_frame"] == pytest.approx(0.01)
    assert h["straight_bias_deg_per_m"] == pytest.approx(0.125)
    assert h["straights"] == 3 and h["straight_max_deg_per_m"] == pytest.approx(0.125)
    assert (h["inplace_turns"], h["moving_turns"]) == (1, 1)
    assert h["inplace_turn_deg"] == pytest.approx(90.0) and h["inplace_turn_ratio"] == pytest.approx(1.05)
    assert h["moving_turn_deg"] == pytest.approx(90.0) and h["moving_turn_ratio"] == pytest.approx(0.97)
    parts = h["drift_parts"]
    # (the TUM files round the positions: the translation is off by their last digit)
    assert parts["other"] == pytest.approx(0.0, abs=1e-9) and parts["translation"] == pytest.approx(0.0, abs=1e-5)
    assert parts["turn in place"] > parts["moving turn"] > 0.0 and parts["straight"] > 0.0
    lines = proc.stdout.splitlines()
    start = lines.index("heading (the truth drives straight where it turns under 2 deg/s and moves; "
                        "a turn turns 10 deg or more):")
    # The ten straight frames after each of the two turns apart: 0.20 degrees, the rest 0.01 a frame.
    assert h["straight_after_turn_frames"] == 20 and h["straight_after_turn_deg"] == pytest.approx(0.2)
    assert h["straight_own_bias_deg_per_frame"] == pytest.approx(0.01)
    assert lines[start + 1:start + 7] == [
        "  straight drives   12.00 m in 15.0 s, heading bias +0.125 deg/m = +6.00 deg/min = +0.0100 deg/frame",
        "                    each of 3 straight(s) of 1 m or more: RMS 0.125, worst 0.125 deg/m",
        "                    in the 10 frames after each turn +0.20 deg in all; the rest +0.0100 deg/frame",
        "  moving turns      1, 90.0 deg in all, measured 0.970 of it",
        "  turns in place    1, 90.0 deg in all, measured 1.050 of it",
        "  drift parts, % of the path (each kind of frame's yaw errors alone, and the translation's):"]
    assert lines[start + 7] == "                    " + ", ".join(
        f"{name} {parts[name]:.2f}" for name in ("straight", "after turn", "moving turn", "turn in place", "other",
                                                 "translation"))


def test_mount_tells_a_mounted_radars_turn_in_place(tmp_path, run_eval):
    """A radar 0.3 m ahead of its base's rotation axis moves on a circle in the base's turn in
    place: without --mount that turn is a moving one, with it a turn in place, as the base made it."""
    steps, kinds = _loop()
    base = integrate(steps)
    radar = se2_compose(base, np.array([0.3, 0.0, 0.0])[None, :])
    est_radar = se2_compose(integrate(_with_errors(steps, kinds, in_place=1.02)), np.array([0.3, 0.0, 0.0])[None, :])
    t = 100.0 + np.arange(len(base)) / 10.0
    gt, est = write_tum(tmp_path / "gt.tum", t, radar), write_tum(tmp_path / "est.tum", t, est_radar)
    figures = {}
    for mount in (None, "0.3,0,0.2,0", "-0.3,0,0.2,0"):
        out = tmp_path / f"{mount}.json"
        proc = run_eval(est, gt, "--json", out, *(("--mount", mount) if mount else ()))
        assert proc.returncode == 0, proc.stderr
        figures[mount] = _strict(out.read_text())["heading"]
    assert (figures[None]["inplace_turns"], figures[None]["moving_turns"]) == (0, 2)
    mounted = figures["0.3,0,0.2,0"]
    assert (mounted["inplace_turns"], mounted["moving_turns"]) == (1, 1)
    assert mounted["inplace_turn_ratio"] == pytest.approx(1.02) and mounted["moving_turn_ratio"] == pytest.approx(1.0)
    assert mounted["drift_pct"] == figures[None]["drift_pct"]  # the path and drift stay the radar's
    # Behind the axle: a negative x given as argparse would not take it (a value starting with a
    # dash), read as the mount; the radar's turn is then a circle the other way round the axis.
    assert figures["-0.3,0,0.2,0"]["inplace_turns"] == 0


def test_a_bad_mount_is_a_usage_error(run_files, run_eval):
    est, gt = run_files
    proc = run_eval(est, gt, "--mount", "0.3,0")
    assert proc.returncode == 2 and proc.stdout == ""
    assert "--mount: a mount is x,y,z,yaw_deg (four numbers: m, m, m, degrees), got '0.3,0'" in proc.stderr


def test_json_never_replaces_an_input_or_an_existing_file_unasked(run_files, tmp_path, run_eval):
    est, gt = run_files
    truth = pathlib.Path(gt).read_bytes()
    for argv in ([est, gt, "--json", gt], [est, gt, "--json", gt, "--overwrite"]):
        proc = run_eval(*argv)
        assert proc.returncode == 2 and "would write over the input GT.tum" in proc.stderr
    assert pathlib.Path(gt).read_bytes() == truth
    out = tmp_path / "eval.json"
    out.write_text("mine")
    proc = run_eval(est, gt, "--json", out)
    assert proc.returncode == 2 and "already exists" in proc.stderr and proc.stdout == ""  # before the work
    assert run_eval(est, gt, "--json", out, "--overwrite").returncode == 0
    assert json.loads(out.read_text())["poses"]["matched"] == 200
    proc = run_eval(est, gt, "--json", "/dev/null", "--overwrite")
    assert proc.returncode == 2 and "not a regular file" in proc.stderr
    proc = run_eval(est, gt, "--plot", gt)
    assert proc.returncode == 2 and "is a file, not a directory" in proc.stderr


def test_json_beside_a_recording_given_as_the_ground_truth(tmp_path, run_eval):
    from radarodom.tools import radar_sim

    rec = tmp_path / "rec"
    assert radar_sim.main(["calibration", "--duration", "0.5", "--out", str(rec), "-q"]) == 0
    est = rec / "odom.tum"
    est.write_bytes((rec / "groundtruth.tum").read_bytes())
    for extra in ([], ["--overwrite"]):  # written beside it, then replaced
        assert run_eval(est, f"replay://{rec}", "--json", rec / "eval.json", *extra).returncode == 0
    proc = run_eval(est, f"replay://{rec}", "--json", rec / "groundtruth.tum", "--overwrite")
    assert proc.returncode == 2 and "would write over the input GT.tum|URL" in proc.stderr


def test_a_simulated_stream_is_its_own_ground_truth(corridor_run, capsys):
    """radar-eval EST.tum sim://... compares with the poses the simulator drives, without making
    a frame: the same numbers as against the run's recording (it said "the source knows no
    ground truth")."""
    from conftest import CORRIDOR_URL

    assert radar_eval.main([str(corridor_run.tum), CORRIDOR_URL, "--json", str(corridor_run.base / "sim.json")]) == 0
    assert radar_eval.main([str(corridor_run.tum), str(corridor_run.rec / "groundtruth.tum"),
                            "--json", str(corridor_run.base / "rec.json")]) == 0
    capsys.readouterr()
    sim = json.loads((corridor_run.base / "sim.json").read_text())
    rec = json.loads((corridor_run.base / "rec.json").read_text())
    assert sim["poses"]["matched"] == rec["poses"]["matched"] == 30
    assert sim["yaw_increment_error_deg"] == pytest.approx(rec["yaw_increment_error_deg"], abs=1e-6)
    assert sim["final_drift"] == pytest.approx(rec["final_drift"], abs=1e-6)


def test_an_estimate_whose_spread_overflows_is_aligned_by_translation_not_an_internal_error(tmp_path, run_eval):
    # Positions of +/-1.7e308 made the alignment's covariance infinite and numpy's SVD failed:
    # "radar-eval: internal error: LinAlgError: SVD did not converge".
    t = 1000.0 + np.arange(20) / 10.0
    ref = np.column_stack([t - 1000.0, np.zeros(20), np.zeros(20)])
    est = np.column_stack([np.where(np.arange(20) % 3, 1.7e308, -1.7e308), t - 1000.0, np.zeros(20)])
    for i, (a, b) in enumerate(((est, ref), (ref, est))):
        pa, pb = write_tum(tmp_path / f"a{i}.tum", t, a), write_tum(tmp_path / f"b{i}.tum", t, b)
        proc = run_eval(pa, pb, "--json", tmp_path / "eval.json", "--overwrite")
        assert proc.returncode == 0, proc.stderr
        assert "internal error" not in proc.stderr and "RuntimeWarning" not in proc.stderr
        assert "radar-eval: warning: the coordinates are too large to compute with" in proc.stderr
        assert _strict((tmp_path / "eval.json").read_text())["poses"]["matched"] == 20
        ate = [ln for ln in proc.stdout.splitlines() if ln.startswith("ATE")]
        assert ate and "inf" in ate[0]


def test_odom_checks_the_reported_covariances_against_the_truth(corridor_run, tmp_path, run_eval):
    """--odom (radar-capture --odom-json's messages): how their covariances cover the errors, in the
    table and --json; the heading's figures worked out here from the messages and the truth."""
    from radarodom.tools.odometry_log import read_odometry_log

    gt = corridor_run.rec / "groundtruth.tum"
    proc = run_eval(corridor_run.tum, gt, "--odom", corridor_run.odom, "--json", tmp_path / "eval.json")
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    odom = read_odometry_log(corridor_run.odom)
    assert len(odom) == 30 and odom.pose_covariance.shape == (30, 3, 3)
    np.testing.assert_allclose(odom.poses, read_tum(corridor_run.tum).se2(), atol=1e-6)  # the TUM file's poses
    truth = read_tum(gt)
    np.testing.assert_allclose(truth.times, odom.times, atol=1e-6)  # the simulator's frames: a truth pose each
    ref = truth.se2()
    err = np.angle(np.exp(1j * ((odom.poses[:, 2] - odom.poses[0, 2]) - (ref[:, 2] - ref[0, 2]))))
    sd = np.sqrt(odom.pose_covariance[:, 2, 2] - odom.pose_covariance[0, 2, 2])
    z = err[1:] / sd[1:]
    block = proc.stdout.split("reported covariance (")[1].splitlines()
    assert "live.jsonl: 30 of 30 odometry messages compared with the truth at its t;" in block[0]
    assert block[2].startswith(f"  heading           RMS {np.sqrt(np.mean(z ** 2)):.2f}, within 1 sd "
                               f"{100 * np.mean(abs(z) <= 1):.0f} %, within 2 sd {100 * np.mean(abs(z) <= 2):.0f} %")
    assert f"after the run: error {math.degrees(err[-1]):+.2f} deg, sd {math.degrees(sd[-1]):.2f} deg" in block[2]
    assert block[3].startswith("  position          RMS ") and block[4].startswith("  yaw rate          RMS ")
    assert block[5].startswith("  forward speed     RMS ") and block[6].startswith("  sideways speed    RMS ")
    got = json.loads((tmp_path / "eval.json").read_text())["covariance"]
    assert got["yaw"]["z_rms"] == pytest.approx(np.sqrt(np.mean(z ** 2)), rel=1e-6)
    # 3 s of a corridor drive, mostly standing and speeding up: the heading's sd about a degree,
    # the error within it.
    assert 0.5 < math.degrees(sd[-1]) < 2.0 and got["yaw"]["within_2sigma"] == 1.0
    # --flags is the same option; without either, no covariance block.
    with_odom = run_eval(corridor_run.tum, gt, "--odom", corridor_run.odom).stdout
    assert run_eval(corridor_run.tum, gt, "--flags", corridor_run.odom).stdout == with_odom
    without = run_eval(corridor_run.tum, gt).stdout
    assert "reported covariance" not in without and with_odom.startswith(without.rstrip("\n"))


def test_measured_at_compares_the_truth_where_the_odometry_describes_the_radar(corridor_run, tmp_path, run_eval):
    # The odometry describes the radar at the middle of each frame's chirps (the shipped cfg's 13.44
    # ms after the stamp): --measured-at compares it with the truth there, interpolated.
    from radarodom.cfg import RadarConfig, shipped_config_path
    from radarodom.estimator.consistency import odometry_consistency
    from radarodom.tools.odometry_log import read_odometry_log

    at = RadarConfig.from_file(shipped_config_path()).measured_at_s
    assert at == pytest.approx(0.01344)
    gt = corridor_run.rec / "groundtruth.tum"
    proc = run_eval(corridor_run.tum, gt, "--odom", corridor_run.odom, "--measured-at", f"{at!r}",
                    "--json", tmp_path / "eval.json")
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert ("live.jsonl: 29 of 30 odometry messages compared with the truth 13.44 ms after its t;"
            in proc.stdout)  # (the last one's truth would be after the truth's end)
    odom = read_odometry_log(corridor_run.odom)
    expected, used = odometry_consistency(odom.times, odom.poses, odom.pose_covariance, odom.twist_covariance,
                                          odom.yaw_rates, odom.frames, read_tum(gt), measured_at_s=at)
    got = json.loads((tmp_path / "eval.json").read_text())["covariance"]
    assert used == 29 and got["measured_at_s"] == at
    assert got["forward_speed"]["z_rms"] == pytest.approx(expected["forward_speed"]["z_rms"])
    # The run speeds up from standing: against the truth at the stamps its speed reads ahead.
    paired, _ = odometry_consistency(odom.times, odom.poses, odom.pose_covariance, odom.twist_covariance,
                                     odom.yaw_rates, odom.frames, read_tum(gt))
    assert got["forward_speed"]["z_rms"] < paired["forward_speed"]["z_rms"]
    for args, message in ((("--measured-at", "0.01"), "--measured-at is for the covariance check: add --odom"),
                          # (0 was taken for not given: exit 0 without a word)
                          (("--measured-at", "0"), "--measured-at is for the covariance check: add --odom"),
                          (("--odom", corridor_run.odom, "--measured-at", "2"), "expected a number in -1..1 s")):
        proc = run_eval(corridor_run.tum, gt, *args)
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and message in proc.stderr, proc.stderr


def test_measured_at_defaults_to_a_raw_sources_chirps_middle(corridor_run, tmp_path, run_eval):
    # With the recording itself as the reference (replay://), its cfg says where the odometry
    # describes the radar: the messages are compared there without --measured-at; 0 says the stamps.
    from radarodom.cfg import RadarConfig
    at = RadarConfig.from_file(str(corridor_run.rec / "radar.cfg")).measured_at_s
    url = f"replay://{corridor_run.rec}"
    proc = run_eval(corridor_run.tum, url, "--odom", corridor_run.odom, "--json", tmp_path / "eval.json")
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert f"29 of 30 odometry messages compared with the truth {1e3 * at:.2f} ms after its t;" in proc.stdout
    assert json.loads((tmp_path / "eval.json").read_text())["covariance"]["measured_at_s"] == at
    given = run_eval(corridor_run.tum, url, "--odom", corridor_run.odom, "--measured-at", f"{at!r}").stdout
    assert given == proc.stdout
    at_stamps = run_eval(corridor_run.tum, url, "--odom", corridor_run.odom, "--measured-at", "0").stdout
    assert "30 of 30 odometry messages compared with the truth at its t;" in at_stamps
    # A TUM file's truth knows no cfg: the stamps.
    gt = run_eval(corridor_run.tum, corridor_run.rec / "groundtruth.tum", "--odom", corridor_run.odom).stdout
    assert "30 of 30 odometry messages compared with the truth at its t;" in gt


def test_odom_messages_that_miss_the_truth_are_one_line(corridor_run, tmp_path, run_eval):
    late = tmp_path / "late.jsonl"
    late.write_text("".join(line.replace('"t":', '"t":1000') for line in
                            corridor_run.odom.read_text().splitlines(keepends=True)[:3]))
    proc = run_eval(corridor_run.tum, corridor_run.rec / "groundtruth.tum", "--odom", late)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert proc.stderr.startswith("radar-eval: error: ") and "late.jsonl" in proc.stderr


def test_times_far_out_are_shown_short(tmp_path, run_eval):
    # A file's times of 1e300 were written out in 300 digits in the "match in time" error.
    t = np.arange(5) / 10.0
    pose = np.zeros((5, 3))
    far, near = write_tum(tmp_path / "far.tum", 1e300 * (1 + t), pose), write_tum(tmp_path / "near.tum", t, pose)
    proc = run_eval(far, near)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "(5 poses, t 1e+300 .. 1.4e+300 s)" in proc.stderr and len(proc.stderr) < 400


@pytest.mark.parametrize("url", ["dca1000://", "dca1000://192.168.33.180?cli=/dev/ttyACM0", "tidemo://"])
def test_a_live_radar_as_the_truth_is_refused_before_a_radar_is_looked_for(tmp_path, capsys, url):
    from radarodom.tools import radar_eval

    est = tmp_path / "est.tum"
    est.write_text("0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0 1\n")
    assert radar_eval.main([str(est), url]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{url}: a live radar" in err[0] and "knows no ground truth; give the truth as " \
        "GT.tum" in err[0], err


def test_a_recordings_directory_as_the_reference_is_told_its_url(run_files, tmp_path, run_eval):
    """'cap: not a file', where the recording's ground truth is read through replay://cap."""
    est, _ = run_files
    proc = run_eval(est, tmp_path)
    assert (proc.returncode, proc.stderr) == (
        2, f"radar-eval: error: {tmp_path}: not a file (a recording's ground truth: give replay://{tmp_path})\n")


def test_odom_messages_whose_variances_are_too_small_to_divide_by_are_named(corridor_run, tmp_path, run_eval):
    """Variances of 1e-320 overflowed the normalized errors, and the warning blamed the coordinates
    ("are the files in metres?"), which were fine."""
    import json

    messages = [json.loads(line) for line in corridor_run.odom.read_text().splitlines()]
    for m in messages:
        m["pose_covariance"] = m["twist_covariance"] = [1e-320, 0, 0, 0, 1e-320, 0, 0, 0, 1e-320]
    tiny = tmp_path / "tiny.jsonl"
    tiny.write_text("".join(json.dumps(m) + "\n" for m in messages))
    proc = run_eval(corridor_run.tum, corridor_run.rec / "groundtruth.tum", "--odom", tiny)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == (f"radar-eval: warning: {tiny}: its variances are too small to divide by (the smallest "
                           "1e-320), so its normalized errors show as inf or nan\n"), proc.stderr


def test_odom_messages_too_large_to_compute_with_are_warned_of(corridor_run, tmp_path, run_eval):
    # A message's x of 1e308 gave a position and speed RMS of inf without a word (the TUM path warns).
    import json

    lines = corridor_run.odom.read_text().splitlines(keepends=True)
    message = json.loads(lines[5])
    message["x"] = 1e308
    huge = tmp_path / "huge.jsonl"
    huge.write_text("".join(lines[:5]) + json.dumps(message) + "\n" + "".join(lines[6:]))
    proc = run_eval(corridor_run.tum, corridor_run.rec / "groundtruth.tum", "--odom", huge)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.startswith("radar-eval: warning: the coordinates are too large to compute with: lengths "
                                  "overflow, so figures show as inf or nan"), proc.stderr
    assert "Warning" not in proc.stderr and proc.stderr.count("\n") == 1, proc.stderr


def test_a_count_of_millions_keeps_the_tables_columns_apart():
    """Hunt 4: on 2 000 000 poses a row ended "0.0000    0.00001999999", the max and the count
    run together."""
    from radarodom.estimator.evaluation import Stats
    from radarodom.tools.eval_summary import _row

    for n in (7, 999_999, 2_000_000, 20_000_000):
        row = _row("yaw-increment error deg", Stats(0.1, 0.0, 0.0, 0.1, -0.5, 0.00001, n))
        assert row.split()[-2:] == ["0.0000", str(n)], row
        assert len(row) == 32 + 60 + max(7, len(str(n)) + 1), row
