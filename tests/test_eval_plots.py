"""radar-eval's plots (radarodom.tools.plots, plot_panels): what the figures hold, looked into
through matplotlib's objects (titles, texts, axes limits, markers, flag rows), not pixels; the
quality flags read from odometry messages; radar-eval --plot on a short simulated run."""

from __future__ import annotations

import io
import json
import os
import re
import shutil
import struct
import subprocess
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import console_command
from test_evaluation import drive, traj

from radarodom import messages
from radarodom.errors import CaptureFormatError, UsageError
from radarodom.estimator.evaluation import Stats, evaluate
from radarodom.estimator.heading_metrics import segment_turns
from radarodom.estimator.odometry import OdometryState
from radarodom.estimator.quality import Flag
from radarodom.tools import plots
from radarodom.tools import plot_panels
from radarodom.tools.odometry_log import OdometryLog, read_odometry_log
from radarodom.tools.radar_echo import format_message
from radarodom.tum import read_tum

pytest.importorskip("matplotlib", reason="the plots need matplotlib (the plot or test extra)")

SINGLE = ("trajectories.png", "yaw.png", "speed.png", "position_error.png", "yaw_error.png",
          "yaw_cumulative_error.png")


def odom_line(t: float, frame: int, flags=(), *, key: str | None = None) -> str:
    """One odometry message as radar-capture publishes it (with *key*: as radar-echo --json prints it)."""
    payload = messages.odometry_json(OdometryState(t=t, frame=frame, flags=tuple(flags)))
    return (format_message("odom", key, payload, as_json=True) if key else payload.decode()) + "\n"


def _figure_texts(fig) -> list[str]:
    """The texts and legend entries of *fig* and its subfigures."""
    texts = [t.get_text() for t in fig.texts]
    texts += [t.get_text() for legend in fig.legends for t in legend.get_texts()]
    for sub in fig.subfigs:
        texts += _figure_texts(sub)
    return texts


def all_text(fig) -> str:
    """Every text of *fig*: its header's, its legends', its axes' titles, labels, tick labels and
    annotations (``fig.axes`` has the subfigures' axes too)."""
    texts = _figure_texts(fig)
    for ax in fig.axes:
        texts += [ax.get_title(), ax.get_xlabel(), ax.get_ylabel()]
        texts += [t.get_text() for t in ax.texts + ax.get_yticklabels()]
    return "\n".join(texts)


def axes_titled(fig, start: str):
    (ax,) = [a for a in fig.axes if a.get_title().startswith(start)]
    return ax


@pytest.fixture(scope="module")
def s_bends():
    """An S-bend run (turns both ways) with a biased, noisy estimate, evaluated."""
    t, ref, est = drive(300, seed=3, scale=1.03, yaw_bias_deg=0.1, trans_noise_m=0.003, yaw_noise_deg=0.3)
    return evaluate(traj(t, est, "runs/est.tum"), traj(t, ref, "runs/gt.tum"))


@pytest.fixture(scope="module")
def s_bend_flags(s_bends):
    """Flags on the evaluation's clock: first_frame, icp_failed over frames 40-44 and 100,
    velocity_held with it at 42."""
    flags = [()] * 300
    flags[0] = (Flag.FIRST_FRAME,)
    for k in (40, 41, 43, 44, 100):
        flags[k] = (Flag.ICP_FAILED,)
    flags[42] = (Flag.ICP_FAILED, Flag.VELOCITY_HELD)
    return OdometryLog(s_bends.times.copy(), tuple(tuple(str(f) for f in step) for step in flags), "f.jsonl")


# ------------------------------------------------------------------ the figures
def test_every_figure_carries_the_name_and_the_numbers(s_bends, s_bend_flags):
    figures = plots.evaluation_figures(s_bends, name="hall-run-7", flags=s_bend_flags)
    assert list(figures) == [*SINGLE, "flags.png", "report.png"]
    r = s_bends
    numbers = [f"yaw-increment RMSE {r.yaw_rmse_deg:.3f} deg", f"drift {r.drift_m:.3f} m = {r.drift_pct:.2f} %",
               f"yaw {r.drift_yaw_deg:+.2f} deg", f"ATE RMSE {Stats.of(r.ate_m).rmse:.3f} m",
               f"RPE per 1 m: {Stats.of(r.rpe_distance.translation_pct).rmse:.2f} %",
               "runs/est.tum against runs/gt.tum: 300 poses over 29.9 s",
               "quality flags: 6 of 300 steps not ok (first_frame 1, velocity_held 1, icp_failed 6)"]
    for filename, fig in figures.items():
        text = all_text(fig)
        assert "hall-run-7" in text, filename
        for number in numbers:
            assert number in text, (filename, number)
    # The report also has the whole table radar-eval prints.
    assert f"yaw-increment error deg{'':<9}{r.yaw_rmse_deg:>10.4f}" in all_text(figures["report.png"])


def test_without_flags_the_figures_say_how_to_get_them(s_bends):
    figures = plots.evaluation_figures(s_bends, name="x")
    assert "flags.png" not in figures
    text = all_text(figures["report.png"])
    assert "quality flags: not given (radar-eval --odom ODOM.jsonl)" in text
    assert "not given: radar-eval --odom ODOM.jsonl" in text


def test_trajectory_axes_are_equal_and_tight_with_start_and_end_marked(s_bends):
    for filename in ("trajectories.png", "report.png"):
        fig = plots.evaluation_figures(s_bends, name="x")[filename]
        ax = axes_titled(fig, "Trajectory")
        assert ax.get_aspect() == 1.0 and ax.get_adjustable() == "box"
        r = s_bends
        xy = np.concatenate([r.ref[:, :2], r.est_umeyama[:, :2], r.est_first_pose[:, :2]])
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        pad = max(plot_panels.PAD_SHARE * (hi - lo).max(), plot_panels.PAD_MIN_M)
        assert ax.get_xlim() == pytest.approx((lo[0] - pad, hi[0] + pad))
        assert ax.get_ylim() == pytest.approx((lo[1] - pad, hi[1] + pad))
        assert pad < 0.05 * (hi - lo).max()  # tight: a few % of the run's extent
        markers = {line.get_label(): np.column_stack(line.get_data()) for line in ax.lines}
        np.testing.assert_allclose(markers[plot_panels.START], [r.ref[0, :2]])
        np.testing.assert_allclose(markers[plot_panels.END_TRUTH], [r.ref[-1, :2]])
        np.testing.assert_allclose(markers[plot_panels.END_ESTIMATE], [r.est_first_pose[-1, :2]])
        assert {plot_panels.START, plot_panels.END_TRUTH, plot_panels.END_ESTIMATE} <= set(_figure_texts(fig))


def test_a_straight_run_keeps_its_frame_near_the_line():
    """A 15 m straight corridor once spanned -5..6 m across: now 4 % of its length on each side."""
    t = 1000.0 + np.arange(151) / 10.0
    ref = np.column_stack([np.linspace(0, 15, 151), np.zeros(151), np.zeros(151)])
    r = evaluate(traj(t, ref), traj(t, ref))
    ax = axes_titled(plots.evaluation_figures(r, name="c")["trajectories.png"], "Trajectory")
    assert ax.get_xlim() == pytest.approx((-0.6, 15.6))
    assert ax.get_ylim() == pytest.approx((-0.6, 0.6))


def test_time_panels_show_truth_and_estimate_and_the_turns(s_bends):
    r = s_bends
    fig = plots.evaluation_figures(r, name="x")["report.png"]
    yaw = axes_titled(fig, "Yaw, aligned")
    truth, estimate = yaw.lines
    np.testing.assert_allclose(truth.get_ydata(), np.degrees(np.unwrap(r.ref[:, 2])))
    assert estimate.get_ydata()[-1] - truth.get_ydata()[-1] == pytest.approx(r.drift_yaw_deg, abs=1e-6)
    speed = axes_titled(fig, "Speed")
    v_truth, v_est = (line.get_ydata() for line in speed.lines)
    np.testing.assert_allclose(v_truth, 1.0, rtol=1e-9)  # drive() runs at 1 m/s
    assert np.mean(v_est) == pytest.approx(1.03, abs=0.01)  # its estimate 3 % too long
    err = axes_titled(fig, "Position error")
    x, y, dist = (line.get_ydata() for line in err.lines[:3])
    np.testing.assert_allclose(np.hypot(x, y), dist)
    assert dist[-1] == pytest.approx(r.drift_m)
    # The truth's turns: one band each in every time panel, their angles on the yaw error.
    expected = segment_turns(r.times, r.ref, straight_rate_dps=plot_panels.TURN_RATE_DPS,
                             min_turn_deg=plot_panels.TURN_MIN_DEG)
    assert len(expected) == 4
    for ax in (yaw, speed, err, axes_titled(fig, "Yaw-increment error")):
        assert len(ax.patches) == len(expected), ax.get_title()
    single = plots.evaluation_figures(r, name="x")["yaw.png"]
    assert [t.get_text() for sub in single.subfigs for lg in sub.legends for t in lg.get_texts()] == [
        "ground truth", f"estimate, aligned at the first pose (drift {r.drift_m:.2f} m)",
        f"turn of the truth (> {plot_panels.TURN_RATE_DPS:g} deg/s)"]
    angles = [t.get_text() for t in axes_titled(fig, "Yaw-increment error").texts]
    assert angles[0].startswith("+137\N{DEGREE SIGN}\nest +14") and angles[1].startswith("-137\N{DEGREE SIGN}")


def test_flags_timeline_has_a_row_per_flag_and_a_bar_per_run(s_bends, s_bend_flags):
    fig = plots.evaluation_figures(s_bends, name="x", flags=s_bend_flags)["flags.png"]
    ax = axes_titled(fig, "Estimator quality flags")
    assert [t.get_text() for t in ax.get_yticklabels()] == ["first_frame (1)", "velocity_held (1)",
                                                            "icp_failed (6)"]
    t = s_bends.times
    spans = [_bar_spans(c) for c in ax.collections]
    assert len(spans) == 3
    np.testing.assert_allclose(spans[0], [(0.0, 0.1)], atol=1e-9)
    np.testing.assert_allclose(spans[1], [(t[42], 0.1)])
    np.testing.assert_allclose(spans[2], [(t[40], 0.5), (t[100], 0.1)])


def _bar_spans(collection) -> list[tuple[float, float]]:
    """(start, width) of each bar of a broken_barh collection."""
    out = []
    for path in collection.get_paths():
        xs = path.vertices[:, 0]
        out.append((float(xs.min()), float(xs.max() - xs.min())))
    return out


def test_flag_runs_merge_consecutive_steps_only():
    tl = OdometryLog(np.array([0.0, 0.1, 0.2, 0.3, 0.5]), ((), ("a",), ("a",), (), ("a",)))
    np.testing.assert_allclose(plot_panels.flag_runs(tl, "a"), [(0.1, 0.2), (0.5, 0.1)])
    assert plot_panels.flag_runs(tl, "b") == []


# ------------------------------------------------------------------ the flags file
def test_flags_are_read_from_radar_echo_json_and_published_messages(tmp_path):
    path = tmp_path / "odom.jsonl"
    path.write_text(odom_line(10.0, 0, [Flag.FIRST_FRAME], key="radar/awr1843/odom")
                    + '{"key":"radar/awr1843/status","schema":"radarodom/status","version":1,"frames":1}\n'
                    + "\n"
                    + odom_line(10.1, 1, [Flag.ICP_FAILED, "a_newer_flag"])
                    + odom_line(10.2, 2))
    timeline = read_odometry_log(path)
    np.testing.assert_allclose(timeline.times, [10.0, 10.1, 10.2])
    assert timeline.flags == (("first_frame",), ("icp_failed", "a_newer_flag"), ())
    assert timeline.names() == ["first_frame", "icp_failed", "a_newer_flag"]
    shifted = timeline.since(10.0).within(0.05, 1.0)
    assert len(shifted) == 2 and shifted.times[0] == pytest.approx(0.1)


@pytest.mark.parametrize("text, message", [
    ("{not json\n", "odom.jsonl:2: not an odometry message: not JSON: Expecting property name"),
    ("[1, 2]\n", "odom.jsonl:2: not a JSON object"),
    ('{"schema": "radarodom/odom", "version": 1, "t": 1.0}\n',
     "odom.jsonl:2: radarodom/odom: field 'frame' is missing"),
    (odom_line(9.0, 1), "odom.jsonl:2: time 9.000000000 s is not after the previous message's 10.000000000 s"),
    # json recurses once per level: a thousand was "internal error: RecursionError" (a helper's hunt)
    ("[" * 1000 + "]" * 1000 + "\n", "odom.jsonl:2: not an odometry message: nested 1000 deep, more than the 32"),
    # (Python's own message advised sys.set_int_max_str_digits: a helper's hunt)
    ('{"schema": "radarodom/odom", "x": 1' + "0" * 5000 + "}\n",
     "odom.jsonl:2: not an odometry message: an integer of 5001 digits, more than the 4300 allowed"),
    (odom_line(10.1, 1).replace('"twist_covariance":[1.0,0.0,0.0,0.0,1.0', '"twist_covariance":[1.0,0.0,0.0,0.0,-2.5'),
     "odom.jsonl:2: twist_covariance: a variance (its diagonal: items 1, 5, 9) is negative (-2.5): not a covariance"),
])
def test_a_bad_flags_file_names_file_and_line(tmp_path, text, message):
    path = tmp_path / "odom.jsonl"
    path.write_text(odom_line(10.0, 0) + text)
    with pytest.raises(CaptureFormatError, match=re.escape(message)):
        read_odometry_log(path)


def test_an_odometry_log_path_that_is_no_path_is_one_error():
    for path, message in (("a\0b.jsonl", "a path cannot contain a NUL character"), (7, "expected a file path")):
        with pytest.raises(UsageError, match=message):
            read_odometry_log(path)


def test_a_twist_part_not_compared_says_why():
    # Steps with a variance that are no single estimator step (frames that skip, a rate that is not
    # the turn over the time): "no step with a variance" was the wrong reason (a helper's hunt).
    from radarodom.tools.eval_summary import format_covariance
    part = {"z_rms": 0.5, "within_1sigma": 0.9, "within_2sigma": 1.0}
    text = format_covariance({"yaw": part, "position": part, "yaw_rate": None, "forward_speed": None,
                              "sideways_speed": None, "final_yaw_error_deg": 1.0, "final_yaw_sigma_deg": 2.0,
                              "measured_at_s": -0.5}, "odom.jsonl", 10, 12)
    assert "10 of 12 odometry messages compared with the truth 500 ms before its t" in text
    assert ("  yaw rate          not compared: no single estimator step (frames that follow, whose yaw rate times "
            "time is their turn) with a variance") in text


def test_a_flags_files_cut_off_last_line_is_left_out_with_a_warning(tmp_path, caplog):
    path = tmp_path / "odom.jsonl"
    path.write_text(odom_line(10.0, 0) + odom_line(10.1, 1) + odom_line(10.2, 2)[:40])  # a killed --odom-json
    with caplog.at_level("WARNING"):
        timeline = read_odometry_log(path)
    np.testing.assert_allclose(timeline.times, [10.0, 10.1])
    assert [r.getMessage() for r in caplog.records] == [f"{path}:3: ignoring a last line without end of line"]


def test_a_flags_file_without_odometry_is_refused(tmp_path):
    path = tmp_path / "status.jsonl"
    path.write_text('{"schema":"radarodom/status","version":1}\n')
    with pytest.raises(UsageError, match="no odometry message .* radar-echo --json odom"):
        read_odometry_log(path)
    with pytest.raises(UsageError, match="no such file"):
        read_odometry_log(tmp_path / "nope.jsonl")
    # One message without its end of line: no warning besides the error, which says why.
    cut = tmp_path / "cut.jsonl"
    cut.write_text(odom_line(10.0, 0).rstrip("\n"))
    with pytest.raises(UsageError, match="no odometry message .* but line 1, which has no end of line"):
        read_odometry_log(cut)


# ------------------------------------------------------------------ radar-eval --plot on a simulated run
def run_cli(name: str, *args, timeout: float = 300) -> subprocess.CompletedProcess:
    """The console script in a subprocess: the runs that draw the plots (their work, seconds, dominates)."""
    return subprocess.run(console_command(name) + [str(a) for a in args], stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=timeout)


@pytest.fixture
def run_eval(run_main):
    """radar-eval in this process (conftest's run_main): the runs whose subject
    is its answer (the table, a refusal)."""
    return lambda *args: run_main("radar-eval", *args)


def png_size(path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data.startswith(b"\x89PNG\r\n\x1a\n") and data[12:16] == b"IHDR", path
    return struct.unpack(">II", data[16:24])


@pytest.fixture(scope="module")
def sim_run(tmp_path_factory, corridor_run):
    """3 s of the simulated corridor, recorded (its ground truth) with the odometry as TUM, and
    a flags file written by hand at the odometry's times.  The run is conftest's session-wide
    corridor_run (radar-capture --source CORRIDOR_URL --record --odom-out);
    its trajectory is copied here under this module's name for it."""
    assert corridor_run.proc.returncode == 0
    base = tmp_path_factory.mktemp("eval_plots")
    rec, tum = corridor_run.rec, base / "corridor.tum"
    shutil.copyfile(corridor_run.tum, tum)
    times = read_tum(tum).times
    flags = base / "corridor.odom.jsonl"
    flags.write_text("".join(odom_line(t, k, [Flag.FIRST_FRAME] if k == 0 else
                                       [Flag.FEW_FEATURES, Flag.YAW_HELD] if k in (20, 21) else [])
                             for k, t in enumerate(times)))
    return SimpleNamespace(base=base, rec=rec, tum=tum, flags=flags, frames=len(times))


def test_radar_eval_plot_writes_the_report_and_each_plot(sim_run):
    out = sim_run.base / "plots"
    proc = run_cli("radar-eval", sim_run.tum, f"replay://{sim_run.rec}", "--plot", out, "--flags", sim_run.flags,
                   "--name", "corridor 3 s", timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    written = ["report.png", *SINGLE, "flags.png"]
    assert proc.stdout.splitlines()[-1] == "plots: " + ", ".join(str(out / f) for f in written)
    assert png_size(out / "report.png") == (1700, 1100)
    for name in written:
        width, height = png_size(out / name)
        assert width >= 900 and height >= 600 and (out / name).stat().st_size > 20_000, name
    assert sim_run.frames == 30


def test_radar_eval_plot_figures_match_what_it_printed(sim_run, run_eval):
    """The same evaluation in the library: the figure's numbers are the table's, its flag rows the
    file's, and its name the estimate's file name when --name is not given."""
    r = evaluate(read_tum(sim_run.tum), read_tum(sim_run.rec / "groundtruth.tum"))
    flags = read_odometry_log(sim_run.flags)
    fig = plots.evaluation_figures(r, name="corridor", flags=flags.since(flags.times[0]))["report.png"]
    proc = run_eval(sim_run.tum, f"replay://{sim_run.rec}")
    assert f"{r.yaw_rmse_deg:.4f}" in proc.stdout and f"yaw-increment RMSE {r.yaw_rmse_deg:.3f} deg" in all_text(fig)
    ax = axes_titled(fig, "Estimator quality flags")
    assert [t.get_text() for t in ax.get_yticklabels()] == ["first_frame (1)", "few_features (2)", "yaw_held (2)"]
    assert "quality flags: 2 of 30 steps not ok" in all_text(fig)


def test_radar_eval_flags_errors_are_one_line(sim_run, tmp_path, run_eval):
    gt = sim_run.rec / "groundtruth.tum"
    proc = run_eval(sim_run.tum, gt, "--name", "x")
    assert (proc.returncode, proc.stderr) == (2, "radar-eval: error: --name is for the plots: add --plot DIR\n")
    # Without --plot the messages' covariances are still checked (these hand-written ones report none).
    proc = run_eval(sim_run.tum, gt, "--flags", sim_run.flags)
    assert proc.returncode == 0 and "  heading           not compared: no frame with a variance" in proc.stdout
    late = tmp_path / "late.jsonl"
    late.write_text(odom_line(5000.0, 0) + odom_line(5000.1, 1))
    proc = run_eval(sim_run.tum, gt, "--plot", tmp_path / "p", "--flags", late)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    # (its covariances are checked first: the messages' poses match none of the truth's)
    assert (f"radar-eval: error: {late}: fewer than two of its 2 messages (t 5000.000 .. 5000.100 s) have a ground "
            "truth at their t (the truth: t 0.000 .. 2.900 s, 30 poses)") in proc.stderr
    # Messages that match the truth but not the evaluated stretch of the estimate: no flags to plot.
    early = tmp_path / "early.tum"
    early.write_text("".join(sim_run.tum.read_text().splitlines(keepends=True)[:10]))
    later = tmp_path / "later.jsonl"
    later.write_text("".join(sim_run.flags.read_text().splitlines(keepends=True)[20:]))
    proc = run_eval(early, gt, "--plot", tmp_path / "p", "--flags", later, "--json", tmp_path / "e.json")
    assert proc.returncode == 2, proc.stderr  # (after a warning: the first second stands still, no RPE per metre)
    assert proc.stderr.splitlines()[-1].startswith(f"radar-eval: error: {later}: its 10 odometry messages (t 2.000 "
                                                   ".. 2.900 s) fall outside the evaluated poses (t 0.000 .. 0.900 s)")
    assert proc.stdout == "" and not (tmp_path / "e.json").exists() and not (tmp_path / "p").exists()
    bad = tmp_path / "bad.jsonl"
    bad.write_text(odom_line(1.0, 0) + "oops\n")
    proc = run_eval(sim_run.tum, gt, "--plot", tmp_path / "p", "--flags", bad)
    assert proc.returncode == 2 and proc.stderr.startswith(f"radar-eval: error: {bad}:2: not an odometry message: not JSON")
    assert proc.stdout == "" and not (tmp_path / "p").exists()


def test_radar_eval_plots_never_write_over_json_or_an_input(sim_run, tmp_path, run_eval):
    """--json naming one of --plot's files, or an input lying where a plot goes, is refused
    before the work: nothing is written, nothing read is replaced."""
    out = tmp_path / "plots"
    gt = sim_run.rec / "groundtruth.tum"
    proc = run_eval(sim_run.tum, gt, "--plot", out, "--json", out / "yaw.png")
    assert (proc.returncode, proc.stdout) == (2, "")
    assert proc.stderr == (f"radar-eval: error: --json and --plot's yaw.png both name {out / 'yaw.png'}: "
                           "give each its own\n")
    assert not out.exists()
    # The directory itself (hunt 4): refused only after the work, "appeared while this ran", and
    # the directory left empty.
    proc = run_eval(sim_run.tum, gt, "--plot", out, "--json", out)
    assert (proc.returncode, proc.stdout) == (2, "")
    assert proc.stderr == f"radar-eval: error: --plot and --json both name {out}: give each its own\n"
    assert not out.exists()
    out.mkdir()
    flags = out / "flags.png"  # an odometry log saved under a plot's name
    shutil.copyfile(sim_run.flags, flags)
    proc = run_eval(sim_run.tum, gt, "--plot", out, "--odom", flags)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert f"--plot's flags.png {flags} would write over the input --odom {flags}" in proc.stderr
    assert flags.read_bytes() == sim_run.flags.read_bytes() and sorted(p.name for p in out.iterdir()) == ["flags.png"]


@pytest.mark.parametrize("kind", ["directory", "fifo"])
def test_a_plot_whose_name_is_taken_by_no_file_is_refused_before_the_work(sim_run, tmp_path, kind, run_eval):
    """A directory (or a pipe) where yaw.png goes: the table was printed, two plots and the --json
    written, then 'cannot write .../yaw.png: Is a directory' (exit 1), the rest left behind."""
    out = tmp_path / "plots"
    out.mkdir()
    (out / "yaw.png").mkdir() if kind == "directory" else os.mkfifo(out / "yaw.png")
    proc = run_eval(sim_run.tum, sim_run.rec / "groundtruth.tum", "--plot", out, "--json", tmp_path / "eval.json")
    assert (proc.returncode, proc.stdout) == (2, ""), proc.stderr
    assert proc.stderr == (f"radar-eval: error: --plot's yaw.png {out / 'yaw.png'} is there and is not a file (a "
                           "directory, a pipe, a device): move it away or choose another --plot directory\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plots"] and [p.name for p in out.iterdir()] == ["yaw.png"]


def test_a_plot_directory_that_cannot_be_written_is_refused_before_the_work(sim_run, tmp_path, monkeypatch, capsys):
    from radarodom.tools import radar_eval

    real_access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: os.fspath(path) != str(tmp_path)
                        and real_access(path, mode, **kw))
    assert radar_eval.main([str(sim_run.tum), str(sim_run.rec / "groundtruth.tum"), "--plot",
                            str(tmp_path / "new" / "plots")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err == (f"radar-eval: error: --plot {tmp_path / 'new' / 'plots'}: the directory {tmp_path} "
                                 "is not writable; choose a writable destination\n")


def test_a_figure_that_runs_out_of_room_leaves_no_cut_png_and_the_old_one_whole(sim_run, tmp_path):
    """A full disk (here the process's file-size limit) under --plot: report.png was left cut
    short (0 bytes), the last run's report replaced by nothing."""
    import resource
    import signal

    def small_files():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))

    out = tmp_path / "plots"
    out.mkdir()
    (out / "report.png").write_bytes(b"the last run's report")
    proc = subprocess.run(console_command("radar-eval") + [str(sim_run.tum), str(sim_run.rec / "groundtruth.tum"),
                                                           "--plot", str(out)],
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=120, preexec_fn=small_files)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr == (f"radar-eval: error: cannot write {out / 'report.png'}: File too large; free some space, or "
                           "choose another disk; no figure was "
                           "written\n"), proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["report.png"]
    assert (out / "report.png").read_bytes() == b"the last run's report"


def test_figures_get_the_umasks_permissions_and_a_replaced_one_keeps_its_own(s_bends, tmp_path):
    # Written through a temporary file of their own (for a full disk), they came out 0600.
    (tmp_path / "report.png").write_bytes(b"old")
    os.chmod(tmp_path / "report.png", 0o640)
    old_umask = os.umask(0o022)
    try:
        paths = plots.plot_evaluation(s_bends, tmp_path, name="x")
    finally:
        os.umask(old_umask)
    modes = {os.path.basename(p): os.stat(p).st_mode & 0o777 for p in paths}
    assert modes.pop("report.png") == 0o640 and set(modes.values()) == {0o644}, modes
    assert sorted(os.listdir(tmp_path)) == sorted(os.path.basename(p) for p in paths)


def test_a_flags_file_with_a_byte_order_mark_reads(tmp_path):
    path = tmp_path / "flags.jsonl"
    path.write_bytes(b"\xef\xbb\xbf" + (odom_line(1.0, 0) + odom_line(1.1, 1)).encode())
    assert len(read_odometry_log(path).times) == 2


def test_the_json_may_go_into_the_plot_directory_the_run_makes(sim_run, tmp_path):
    out = tmp_path / "new" / "eval"
    proc = run_cli("radar-eval", sim_run.tum, sim_run.rec / "groundtruth.tum", "--plot", out, "--json", out / "n.json",
                   timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads((out / "n.json").read_text())["poses"]["matched"] == 30 and (out / "report.png").exists()


@pytest.mark.parametrize("name", ["run $x^$", "run $\\foo{$", "price $5 and $6", "bell\x07 esc\x1b"])
def test_a_name_with_dollars_or_control_characters_is_drawn_as_written(s_bends, tmp_path, name, recwarn):
    """'$x^$' was matplotlib's maths, and radar-eval --plot ended with 'internal error: ValueError';
    a control character drew a missing-glyph UserWarning.  Every figure's title is the same
    header's (plots._header), so the report alone is rendered here; writing them all is
    test_radar_eval_plot_writes_the_report_and_each_plot's."""
    report = plots.evaluation_figures(s_bends, name=name)["report.png"]
    png = io.BytesIO()
    report.savefig(png, format="png")  # the text is laid out, and maths parsed, as it is drawn
    assert png.getvalue().startswith(b"\x89PNG")
    shown = "".join(c if c.isprintable() else "?" for c in name)
    assert shown in all_text(report)
    assert not [w for w in recwarn if "Glyph" in str(w.message)], [str(w.message) for w in recwarn]
