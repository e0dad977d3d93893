"""Trajectory I/O (radarodom.tum) and evaluation (radarodom.estimator.evaluation):
metrics on hand-made trajectories with known answers, association, and the
numbers checked against evo on the same files."""

from __future__ import annotations

import logging

import json
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from conftest import warning_messages

from radarodom.driver.recordings.capture_dir import CaptureWriter
from radarodom.errors import CaptureExistsError, CaptureFormatError, EvaluationError, UsageError
from radarodom.estimator.angles import wrap
from radarodom.estimator.evaluation import (
    Stats,
    associate,
    distance_pairs,
    evaluate,
    se2_compose,
    umeyama_se2,
)
from radarodom.tum import TumTrajectory, TumWriter, quaternion_yaw, read_tum, unit_quaternions, yaw_quaternion

RATE_HZ = 10.0
T0 = 1000.0


def drive(n: int = 300, *, speed: float = 1.0, seed: int | None = None, scale: float = 1.0,
          yaw_bias_deg: float = 0.0, trans_noise_m: float = 0.0, yaw_noise_deg: float = 0.0):
    """A planar run at RATE_HZ: forward at *speed* m/s while the yaw rate swings
    between about +-30 deg/s (S-bends), and an estimate of it made by integrating
    the true per-frame motion with a *scale* error, a constant *yaw_bias_deg* per
    frame and Gaussian noise.  Returns times (n,) s, reference and estimate (n, 3)."""
    rng = np.random.default_rng(seed)
    k = np.arange(1, n)
    yaw_rate = 0.5 * np.sin(2 * np.pi * k / 150.0)  # rad/s
    steps = np.zeros((n - 1, 3))
    steps[:, 0] = speed / RATE_HZ
    steps[:, 2] = yaw_rate / RATE_HZ
    est_steps = steps * [scale, scale, 1.0]
    est_steps[:, 2] += math.radians(yaw_bias_deg)
    if seed is not None:
        est_steps[:, :2] += rng.normal(0.0, trans_noise_m, (n - 1, 2))
        est_steps[:, 2] += np.radians(rng.normal(0.0, yaw_noise_deg, n - 1))
    return T0 + np.arange(n) / RATE_HZ, integrate(steps), integrate(est_steps)


def integrate(steps: np.ndarray) -> np.ndarray:
    """Poses (n+1, 3) from the origin by body-frame increments *steps* (n, 3)."""
    poses = np.zeros((len(steps) + 1, 3))
    for i, step in enumerate(steps):
        poses[i + 1] = se2_compose(poses[i], step)
    return poses


def write_tum(path, times, poses) -> str:
    with TumWriter(path) as writer:
        for t, (x, y, yaw) in zip(times, poses):
            writer.write(t, x, y, yaw)
    return str(path)


def traj(times, poses, source="") -> TumTrajectory:
    return TumTrajectory.from_se2(times, poses, source=source)


# ------------------------------------------------------------------------ tum.py
def test_tum_writer_round_trip_planar_poses(tmp_path):
    t, ref, _ = drive(50)
    ref[:, 2] = wrap(ref[:, 2])
    gt = read_tum(write_tum(tmp_path / "a.tum", t, ref))
    assert gt.source == str(tmp_path / "a.tum") and len(gt) == 50
    np.testing.assert_allclose(gt.times, t, atol=1e-9)
    np.testing.assert_allclose(gt.se2(), ref, atol=1e-8)
    np.testing.assert_allclose(gt.yaw, ref[:, 2], atol=1e-8)
    assert np.all(gt.positions[:, 2] == 0) and np.all(gt.quaternions[:, :2] == 0)
    assert list(gt.lines) == list(range(1, 51))


def test_tum_line_format_and_one_formatter_with_the_capture_writer(tmp_path, small_cfg):
    pose = (1.5, -2.25, 0.0, *yaw_quaternion(0.3))
    with TumWriter(tmp_path / "b.tum") as writer:
        writer.write_pose(12.3456789012, pose[:3], pose[3:])
    line = (tmp_path / "b.tum").read_text()
    assert line.split()[0] == "12.345678901" and len(line.split()) == 8 and line.endswith("\n")
    with CaptureWriter(tmp_path / "cap", small_cfg) as cap:
        cap.write(bytes(small_cfg.frame_bytes), 12.3456789012, 0, pose)
    assert (tmp_path / "cap" / "groundtruth.tum").read_text() == line


def test_tum_writer_never_overwrites_and_refuses_bad_poses(tmp_path):
    path = tmp_path / "c.tum"
    path.write_text("keep me\n")
    with pytest.raises(CaptureExistsError, match="already exists"):
        TumWriter(path)
    assert path.read_text() == "keep me\n"
    with TumWriter(tmp_path / "d.tum") as writer:
        with pytest.raises(UsageError, match="non-finite"):
            writer.write(0.0, float("nan"), 0.0, 0.0)
        with pytest.raises(UsageError, match="position"):
            writer.write_pose(0.0, (1.0, 2.0), (0.0, 0.0, 0.0, 1.0))
    assert (tmp_path / "d.tum").read_text() == ""


def test_yaw_from_quaternions_also_when_tilted():
    yaw = np.radians([-179.0, -90.0, 0.0, 45.0, 179.0])
    np.testing.assert_allclose(quaternion_yaw(yaw_quaternion(yaw)), yaw, atol=1e-12)
    # yaw 30 deg then pitch 10 deg (z-y-x): the heading stays 30 deg; a non-unit norm does not matter.
    q = Rotation.from_euler("ZYX", [30.0, 10.0, 0.0], degrees=True).as_quat()
    assert quaternion_yaw(3.0 * q) == pytest.approx(math.radians(30), abs=1e-12)


def test_a_quaternion_however_small_or_large_gives_its_rotation_without_numpys_warnings(tmp_path, recwarn):
    """A TUM line's '1e-300 0 0 1e-300' squared to zero: numpy's divide-by-zero warning on stderr,
    roll/pitch said to reach 180 degrees; its rotation is 90 degrees of roll."""
    q = np.array([[1e-300, 0.0, 0.0, 1e-300], [0.0, 0.0, 3e-200, 3e-200], [0.0, 0.0, 1e200, 1e200]])
    np.testing.assert_allclose(unit_quaternions(q), [[2 ** -0.5, 0, 0, 2 ** -0.5], [0, 0, 2 ** -0.5, 2 ** -0.5],
                                                     [0, 0, 2 ** -0.5, 2 ** -0.5]])
    np.testing.assert_allclose(quaternion_yaw(q), [0.0, math.pi / 2, math.pi / 2])
    path = tmp_path / "tiny.tum"
    path.write_text("0 0 0 0 0 0 1e-300 1e-300\n1 1 0 0 0 0 1e-300 1e-300\n2 2 0 0 0 0 1e-300 1e-300\n")
    result = evaluate(read_tum(path), read_tum(path))
    assert result.matched == 3 and result.drift_yaw_deg == 0.0
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in recwarn]


@pytest.mark.parametrize("text, lineno, what", [
    ("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n", 2, "expected 8 numbers ('t x y z qx qy qz qw'), got 7: '1 0 0 0 0 0 1'"),
    # An extra column is quoted with the line's end, where it is.
    ("0 0 0 0 0 0 0 1\n1.000000000 0.0123456789 0.000000123 0.0 0.0 0.0 0.00262780049 0.99999654 7.5\n", 2,
     "expected 8 numbers ('t x y z qx qy qz qw'), got 9: '1.000000000 0.0123456789 0.0 ... .00262780049 0.99999654 7.5'"),
    ("# header\n\n0 0 0 0 0 0 0 1\n1 a 0 0 0 0 0 1\n", 4, "expected"),
    ("0 0 0 0 0 0 0 1\n1 nan 0 0 0 0 0 1\n", 2, "x is not a finite number ('nan')"),
    ("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1e999\n", 2, "qw is not a finite number ('1e999')"),
    ("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 0\n", 2, "the quaternion is zero"),
    ("\x00\x01\xff\xfe\x10\n", 1, "binary data, not text"),  # adc_data.bin given as the ground truth
    ("\x00\x01\xff\xfe\x10", 1, "binary data, not text"),  # ... a small one, without a newline
    ("0 0 0 0 0 0 0 1\n\x00\x01", 2, "binary data, not text"),
])
def test_read_tum_names_file_and_line_of_a_bad_line(tmp_path, text, lineno, what):
    path = tmp_path / "bad.tum"
    path.write_bytes(text.encode("latin-1"))
    with pytest.raises(CaptureFormatError) as info:
        read_tum(path)
    assert str(info.value).startswith(f"{path}:{lineno}: {what}")


def test_read_tum_skips_comments_and_a_cut_off_last_line(tmp_path, warnings_log):
    path = tmp_path / "cut.tum"
    path.write_text("# t x y z qx qy qz qw\n0 0 0 0 0 0 0 1\n\n0.1 0.1 0 0 0 0 0 1\n0.2 0.2 0 0 0")
    gt = read_tum(path)
    assert len(gt) == 2 and list(gt.lines) == [2, 4]
    assert warning_messages(warnings_log) == [f"{path}:5: ignoring a last line without end of line"]


# ------------------------------------------------------------------------ metrics, known answers
def test_a_perfect_estimate_has_zero_error_everywhere():
    t, ref, _ = drive(200)
    r = evaluate(traj(t, ref), traj(t, ref))
    for errors in (r.rpe_frame.translation_m, r.rpe_frame.rotation_deg, r.rpe_distance.translation_m,
                   r.rpe_distance.rotation_deg, r.yaw_error_deg, r.ate_m):
        assert np.max(np.abs(errors)) < 1e-9
    assert r.drift_m < 1e-9 and r.matched == 200 and r.rpe_frame.pairs.shape == (199, 2)
    assert r.ref_path_m == pytest.approx(19.9, rel=1e-9)


def test_a_constant_yaw_bias_per_frame():
    bias = 0.2  # deg per frame
    t, ref, est = drive(300, yaw_bias_deg=bias)
    r = evaluate(traj(t, est), traj(t, ref))
    np.testing.assert_allclose(r.yaw_error_deg, bias, atol=1e-9)
    assert r.yaw_rmse_deg == pytest.approx(bias, abs=1e-9)
    np.testing.assert_allclose(r.yaw_cumulative_sq_deg2, bias ** 2 * np.arange(1, 300), rtol=1e-9)
    np.testing.assert_allclose(r.rpe_frame.rotation_deg, bias, atol=1e-9)
    # The bias only turns the estimate: each step's length is right, its direction
    # off by the heading error accumulated before it.
    assert np.max(r.rpe_frame.translation_m) < 1e-9
    assert r.drift_yaw_deg == pytest.approx(bias * 299, abs=1e-6)
    # Per 1 m: every segment of k frames carries k times the bias.
    k = np.diff(r.rpe_distance.pairs, axis=1)[:, 0]
    np.testing.assert_allclose(r.rpe_distance.rotation_deg, bias * k, atol=1e-9)


def test_a_pure_scale_error_on_a_straight_line():
    n, scale = 101, 1.1
    t = T0 + np.arange(n) / RATE_HZ
    ref = np.column_stack([0.1 * np.arange(n), np.zeros(n), np.zeros(n)])
    est = ref * [scale, scale, 1.0]
    r = evaluate(traj(t, est), traj(t, ref))
    np.testing.assert_allclose(r.rpe_frame.translation_m, 0.01, atol=1e-9)
    np.testing.assert_allclose(r.rpe_distance.translation_pct, 10.0, atol=1e-6)
    assert np.max(r.rpe_frame.rotation_deg) < 1e-9 and np.max(np.abs(r.yaw_error_deg)) < 1e-9
    # Umeyama without scale centres the two lines on each other.
    x = ref[:, 0]
    assert Stats.of(r.ate_m).rmse == pytest.approx(0.1 * np.std(x), rel=1e-9)
    assert r.drift_m == pytest.approx(1.0, rel=1e-9) and r.drift_pct == pytest.approx(10.0, rel=1e-9)


def test_a_rotated_and_shifted_copy_aligns_to_zero_ate():
    t, ref, _ = drive(300)
    moved = se2_compose(np.array([3.0, -7.0, math.radians(135)]), ref)
    r = evaluate(traj(t, moved), traj(t, ref))
    assert np.max(r.ate_m) < 1e-9
    assert math.degrees(wrap(r.alignment[2])) == pytest.approx(-135.0, abs=1e-9)
    assert np.max(r.rpe_frame.translation_m) < 1e-9 and np.max(r.rpe_distance.rotation_deg) < 1e-9
    assert r.drift_m < 1e-9
    np.testing.assert_allclose(r.est_umeyama, r.ref, atol=1e-9)


def test_umeyama_without_motion_fits_the_translation_only():
    src = np.zeros((5, 2))
    np.testing.assert_allclose(umeyama_se2(src, src + [1.0, 2.0]), [1.0, 2.0, 0.0])


def test_distance_pairs_chain_segments_like_evo():
    xy = np.column_stack([np.cumsum([0.0, 0.5, 0.6, 0.2, 0.9, 0.3]), np.zeros(6)])
    assert distance_pairs(xy, 1.0).tolist() == [[0, 2], [2, 4]]
    assert distance_pairs(xy[:2], 1.0).shape == (0, 2)


def test_a_path_shorter_than_delta_gives_no_rpe_per_distance(warnings_log):
    t, ref, est = drive(5, yaw_bias_deg=0.1)
    r = evaluate(traj(t, est), traj(t, ref), delta_m=1.0)
    assert len(r.rpe_distance.pairs) == 0
    d = r.to_dict()
    assert d["rpe_per_distance"]["translation_m"] == {k: None for k in ("rmse", "mean", "median", "std",
                                                                      "min", "max")} | {"n": 0}
    assert d["rpe_per_frame"]["rotation_deg"]["n"] == 4
    assert any("shorter than 1 m" in m for m in warning_messages(warnings_log))


def test_stats_are_those_evo_reports():
    s = Stats.of([3.0, -4.0, 0.0, 1.0])
    assert (s.rmse, s.mean, s.median, s.min, s.max, s.n) == (pytest.approx(math.sqrt(6.5)), 0.0, 0.5,
                                                              -4.0, 3.0, 4)
    assert s.std == pytest.approx(math.sqrt(6.5))  # population std


def test_a_tilted_trajectory_is_evaluated_in_the_plane_with_a_warning(warnings_log):
    t, ref, _ = drive(50)
    tilted = traj(t, ref, "tilted.tum")
    tilted.positions[:, 2] = np.linspace(0.0, 0.5, 50)
    r = evaluate(tilted, traj(t, ref))
    assert np.max(r.ate_m) < 1e-9
    said = [m for m in warning_messages(warnings_log) if "tilted.tum" in m]
    assert said == ["tilted.tum: z varies by 0.5 m; the evaluation is planar and ignores them"]  # no roll/pitch
    pitched = traj(t, ref, "pitched.tum")
    pitched.positions[:, 2] = 1.0  # a constant height is no warning; a pitch of 5 degrees is
    pitched.quaternions[:] = Rotation.from_euler("ZYX", [0.0, 5.0, 0.0], degrees=True).as_quat()
    evaluate(traj(t, ref), pitched)
    assert [m for m in warning_messages(warnings_log) if "pitched.tum" in m] == [
        "pitched.tum: roll/pitch reach 5 deg; the evaluation is planar and ignores them"]
    # radar-coloradar evaluates several estimates against one ground truth: it warns with the first only.
    before = len(warning_messages(warnings_log))
    evaluate(traj(t, ref), tilted, warn_planar=False)
    assert len(warning_messages(warnings_log)) == before


# ------------------------------------------------------------------------ association
def test_associate_with_a_time_offset_and_missing_poses():
    t, ref, est = drive(100)
    keep = np.setdiff1d(np.arange(100), [0, 17, 18, 50, 99])
    e, g = associate(traj(t[keep] + 0.004, est[keep]), traj(t, ref), max_diff=0.01)
    assert len(e) == len(g) == 95
    np.testing.assert_allclose(e.times - g.times, 0.004, atol=1e-9)
    np.testing.assert_allclose(g.se2(), traj(t[keep], ref[keep]).se2())
    # The other way round (the first trajectory the longer one): the same pairs.
    g2, e2 = associate(traj(t, ref), traj(t[keep] + 0.004, est[keep]))
    np.testing.assert_array_equal(g2.times, g.times)
    np.testing.assert_array_equal(e2.times, e.times)


def test_associate_uses_each_pose_once_the_nearest_keeps_it():
    ref = traj(T0 + np.arange(10) / RATE_HZ, np.zeros((10, 3)))
    times = np.array([T0, T0 + 0.1, T0 + 0.104, T0 + 0.2])  # two near 0.1 s
    e, g = associate(traj(times, np.zeros((4, 3))), ref, max_diff=0.01)
    np.testing.assert_allclose(e.times, [T0, T0 + 0.1, T0 + 0.2])
    np.testing.assert_allclose(g.times, [T0, T0 + 0.1, T0 + 0.2])


def test_associate_refuses_trajectories_that_do_not_overlap_in_time():
    t, ref, est = drive(30)
    with pytest.raises(EvaluationError) as info:
        associate(traj(t - 900.0, est, "est.tum"), traj(t, ref, "gt.tum"))
    msg = str(info.value)
    assert "only 0 pose(s) of est.tum (30 poses, t 100.000 .. 102.900 s)" in msg
    assert "gt.tum (30 poses, t 1000.000 .. 1002.900 s)" in msg and "within 0.01 s" in msg
    # These were 'only 0 pose(s) of empty.tum (no poses) and ... match in time'.
    with pytest.raises(EvaluationError, match=r"^empty\.tum holds no poses \(an empty file, or only comments\): "
                                              r"at least 2 are needed$"):
        associate(traj([], np.zeros((0, 3)), "empty.tum"), traj(t, ref, "gt.tum"))
    with pytest.raises(EvaluationError, match=r"^gt\.tum holds 1 pose: at least 2 are needed$"):
        associate(traj(t, est, "est.tum"), traj(t[:1], ref[:1], "gt.tum"))


def test_trajectories_that_overlap_in_time_only_in_part_are_warned_of(caplog):
    """A truth 2 s off (another run's, another clock's): half of each matched and the figures were
    printed without a word."""
    t, ref, est = drive(40)
    with caplog.at_level(logging.WARNING, logger="radarodom"):
        e, _ = associate(traj(t, est, "est.tum"), traj(t + 2.0, ref, "gt.tum"))
    assert len(e) == 20
    assert [r.getMessage() for r in caplog.records] == [
        "the poses matched span 1.9 s, less than 80 % of est.tum (40 poses, t 1000.000 .. 1003.900 s) and gt.tum "
        "(40 poses, t 1002.000 .. 1005.900 s): the two overlap in time only in part (same run, same clock?)"]
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="radarodom"):  # an estimate of a part of the truth's run
        associate(traj(t[10:30], est[10:30], "est.tum"), traj(t, ref, "gt.tum"))
    assert not caplog.records


@pytest.mark.parametrize("factor, unit", [(1e9, "nanoseconds"), (1e6, "microseconds"), (1e3, "milliseconds")])
def test_times_in_another_unit_are_named_as_such(factor, unit):
    t, ref, est = drive(30)
    with pytest.raises(EvaluationError, match=f"est.tum's times span about a .* times gt.tum's: written in {unit}\\? "
                                              "TUM times are seconds"):
        associate(traj((t - t[0]) * factor, est, "est.tum"), traj(t - t[0], ref, "gt.tum"))


def test_timestamps_must_increase_and_the_message_says_where(tmp_path):
    t, ref, _ = drive(10)
    t[6] = t[5]
    gt = read_tum(write_tum(tmp_path / "dup.tum", t, ref))
    with pytest.raises(EvaluationError, match=r"dup\.tum:7: time 1000\.500000000 s is not after"):
        evaluate(gt, gt)


def test_evaluate_refuses_bad_parameters():
    t, ref, _ = drive(10)
    with pytest.raises(EvaluationError, match="delta_m"):
        evaluate(traj(t, ref), traj(t, ref), delta_m=0.0)
    with pytest.raises(EvaluationError, match="max_diff"):
        evaluate(traj(t, ref), traj(t, ref), max_diff=float("nan"))


# ------------------------------------------------------------------------ against evo
@pytest.fixture
def noisy_run(tmp_path):
    """A 40 s run (10 Hz, 1 m/s, S-bends) and a noisy, biased estimate of it in TUM
    files, the estimate 3 ms late and missing a few poses."""
    t, ref, est = drive(400, seed=7, scale=1.02, yaw_bias_deg=0.05, trans_noise_m=0.005,
                        yaw_noise_deg=0.5)
    keep = np.setdiff1d(np.arange(400), [3, 120, 121, 250])
    return (write_tum(tmp_path / "est.tum", t[keep] + 0.003, est[keep]),
            write_tum(tmp_path / "gt.tum", t, ref))


STAT_KEYS = ("rmse", "mean", "median", "std", "min", "max")


def _assert_stats_equal(ours: Stats, theirs: dict, what: str) -> None:
    for key in STAT_KEYS:
        assert getattr(ours, key) == pytest.approx(float(theirs[key]), rel=1e-9, abs=1e-12), (what, key)


def test_numbers_match_evo(noisy_run):
    pytest.importorskip("evo", reason="evo (PyPI) checks our metrics; pip install evo, or the test extra")
    from evo.core import metrics, sync
    from evo.tools import file_interface

    est_path, gt_path = noisy_run
    ours = evaluate(read_tum(est_path), read_tum(gt_path), delta_m=1.0, max_diff=0.01)
    ref, est = sync.associate_trajectories(file_interface.read_tum_trajectory_file(gt_path),
                                           file_interface.read_tum_trajectory_file(est_path),
                                           max_diff=0.01)
    np.testing.assert_allclose(ref.timestamps - ref.timestamps[0], ours.times, atol=1e-9)
    assert ours.matched == ref.num_poses == 396

    def rpe(relation, delta, unit, **options):
        metric = metrics.RPE(relation, delta=delta, delta_unit=unit, all_pairs=False, **options)
        metric.process_data((ref, est))
        return metric

    frames, meters = metrics.Unit.frames, metrics.Unit.meters
    trans, angle = metrics.PoseRelation.translation_part, metrics.PoseRelation.rotation_angle_deg
    _assert_stats_equal(Stats.of(ours.rpe_frame.translation_m), rpe(trans, 1, frames).get_all_statistics(),
                        "RPE per frame, translation")
    _assert_stats_equal(Stats.of(ours.rpe_frame.rotation_deg), rpe(angle, 1, frames).get_all_statistics(),
                        "RPE per frame, rotation")
    if "pairs_from_reference" not in metrics.RPE.__init__.__code__.co_varnames:
        pytest.skip("this evo picks per-distance pairs on the estimate only (no pairs_from_reference)")
    # Our per-distance pairs follow the ground truth's path: evo's --pairs_from_reference.
    per_m = rpe(trans, 1.0, meters, pairs_from_reference=True)
    assert per_m.delta_ids == ours.rpe_distance.pairs[:, 1].tolist()
    _assert_stats_equal(Stats.of(ours.rpe_distance.translation_m), per_m.get_all_statistics(),
                        "RPE per 1 m, translation")
    _assert_stats_equal(Stats.of(ours.rpe_distance.rotation_deg),
                        rpe(angle, 1.0, meters, pairs_from_reference=True).get_all_statistics(),
                        "RPE per 1 m, rotation")
    est.align(ref, correct_scale=False)  # evo_ape -a
    ape = metrics.APE(trans)
    ape.process_data((ref, est))
    _assert_stats_equal(Stats.of(ours.ate_m), ape.get_all_statistics(), "ATE")


def test_json_numbers_are_the_result(noisy_run):
    est_path, gt_path = noisy_run
    r = evaluate(read_tum(est_path), read_tum(gt_path))
    d = r.to_dict()
    assert d["poses"] == {"estimate": 396, "reference": 400, "matched": 396}
    assert d["rpe_per_distance"]["translation_pct"]["n"] == d["rpe_per_distance"]["rotation_deg"]["n"] > 30
    assert d["yaw_increment_error_deg"]["rmse"] == pytest.approx(r.yaw_rmse_deg)
    assert d["yaw_increment_error_deg"]["rmse"] == pytest.approx(d["rpe_per_frame"]["rotation_deg"]["rmse"])
    assert d["final_drift"]["percent_of_path"] == pytest.approx(100 * r.drift_m / r.ref_path_m)


def test_to_dict_is_standard_json_when_figures_are_undefined(tmp_path):
    """Issue 18: a result with undefined figures (no motion: no per-distance pairs, no drift in
    %) gives null for them; json.dumps(allow_nan=False) takes the whole dict."""
    t = T0 + np.arange(4) / RATE_HZ
    r = evaluate(read_tum(write_tum(tmp_path / "e.tum", t, np.zeros((4, 3)))),
                 read_tum(write_tum(tmp_path / "g.tum", t, np.zeros((4, 3)))))
    assert math.isnan(r.drift_pct)
    d = json.loads(json.dumps(r.to_dict(), allow_nan=False))
    assert d["final_drift"]["percent_of_path"] is None and d["ate_m"]["n"] == 4
    assert d["rpe_per_distance"]["rotation_deg"]["rmse"] is None


def test_a_tum_file_with_a_byte_order_mark_reads(tmp_path):
    # Notepad writes one; the first line was refused, quoted with its '\ufeff'.
    path = tmp_path / "bom.tum"
    path.write_bytes(b"\xef\xbb\xbf0.0 0 0 0 0 0 0 1\n0.1 0.1 0 0 0 0 0 1\n")
    assert read_tum(path).positions[:, 0].tolist() == [0.0, 0.1]
