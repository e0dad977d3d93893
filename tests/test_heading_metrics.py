"""The heading metrics of the robustness matrix (issue 20) on synthetic trajectories whose
answer is known: a truth from the simulator's trajectory model, an estimate built from it with a
chosen yaw bias on straights and chosen turn scale factors."""

import math

import numpy as np
import pytest
from radarodom.driver.sim.trajectory import from_segments
from radarodom.estimator.evaluation import se2_relative
from radarodom.estimator.heading_metrics import (AFTER_TURN_FRAMES, DRIFT_PARTS, drift_parts, heading_metrics,
                                               segment_turns, straight_runs)

SEGMENTS = [{"pause": 1.0}, {"straight": 4.0, "speed": 1.0}, {"turn": 90, "radius": 1.0, "speed": 0.8},
            {"straight": 3.0, "speed": 0.5}, {"rotate": 180, "rate": 60}, {"straight": 3.0, "speed": 0.5},
            {"turn": -90, "radius": 1.0, "speed": 0.8}, {"straight": 4.0, "speed": 1.0}, {"pause": 1.0}]


def truth(rate_hz=10.0):
    traj = from_segments(SEGMENTS)
    t = np.arange(0.0, traj.duration_s, 1.0 / rate_hz)
    x, y, yaw = traj.pose(t)
    return t, np.column_stack([x, y, yaw])


def estimate(t, ref, *, bias_deg=0.0, moving_k=1.0, inplace_k=1.0, speed_k=1.0, each_k=None):
    """The truth's body-frame steps re-integrated with a changed yaw: each straight frame turned
    by *bias_deg*, each turn scaled by its kind's factor (or by *each_k*'s, one per turn in
    order); each step's length by *speed_k*."""
    d_ref = np.diff(ref[:, 2])
    d_est = d_ref.copy()
    in_turn = np.zeros(len(d_ref), bool)
    for n, (i, j, in_place) in enumerate(segment_turns(t, ref)):
        d_est[i:j] *= each_k[n] if each_k else inplace_k if in_place else moving_k
        in_turn[i:j] = True
    speed = np.hypot(*np.diff(ref[:, :2], axis=0).T) * 10.0
    d_est[~in_turn & (speed > 0.05)] += math.radians(bias_deg)
    c, s = np.cos(ref[:-1, 2]), np.sin(ref[:-1, 2])
    dx, dy = np.diff(ref[:, 0]), np.diff(ref[:, 1])
    fwd, side = speed_k * (c * dx + s * dy), speed_k * (-s * dx + c * dy)  # the step in the body frame
    yaw = ref[0, 2] + np.concatenate([[0.0], np.cumsum(d_est)])
    c, s = np.cos(yaw[:-1]), np.sin(yaw[:-1])
    x = ref[0, 0] + np.concatenate([[0.0], np.cumsum(c * fwd - s * side)])
    y = ref[0, 1] + np.concatenate([[0.0], np.cumsum(s * fwd + c * side)])
    return np.column_stack([x, y, yaw])


def test_the_truth_is_segmented_into_its_two_moving_turns_and_its_turn_in_place():
    t, ref = truth()
    turns = segment_turns(t, ref)
    assert [ip for _, _, ip in turns] == [False, True, False]
    angles = [math.degrees(ref[j, 2] - ref[i, 2]) for i, j, _ in turns]
    assert angles == pytest.approx([90, 180, -90], abs=0.5)


def test_a_perfect_estimate_scores_zero_errors_and_unit_ratios():
    t, ref = truth()
    m = heading_metrics(t, ref, ref.copy())
    assert m.yaw_rmse_deg == pytest.approx(0.0, abs=1e-9)
    assert m.straight_bias_deg_per_m == pytest.approx(0.0, abs=1e-9)
    assert m.moving_turns == 2 and m.inplace_turns == 1
    assert m.moving_turn_deg == pytest.approx(180, abs=1) and m.inplace_turn_deg == pytest.approx(180, abs=1)
    assert m.moving_turn_ratio == pytest.approx(1.0) and m.inplace_turn_ratio == pytest.approx(1.0)
    assert m.drift_pct == pytest.approx(0.0, abs=1e-9) and m.final_heading_error_deg == pytest.approx(0.0, abs=1e-9)
    assert m.path_m == pytest.approx(14 + math.pi * 0.5 * 2, rel=1e-3)
    assert m.path_ratio == pytest.approx(1.0)


def test_each_turns_own_ratio_shows_what_the_kinds_ratio_cancels():
    # The left moving turn 4 % long, the right one 3 % short: 1.005 together, each off.
    t, ref = truth()
    m = heading_metrics(t, ref, estimate(t, ref, each_k=[1.04, 0.99, 0.97]))
    assert m.moving_turn_ratio == pytest.approx(1.005, abs=1e-4)  # (the turns are 90 degrees to 0.5)
    assert m.moving_turn_worst_ratio == pytest.approx(1.04, abs=1e-9)
    assert m.inplace_turn_ratio == pytest.approx(0.99, abs=1e-9) and m.inplace_turn_worst_ratio == m.inplace_turn_ratio
    m = heading_metrics(t, ref, estimate(t, ref, each_k=[1.01, 1.0, 0.97]))
    assert m.moving_turn_worst_ratio == pytest.approx(0.97, abs=1e-9)
    m = heading_metrics(t, ref, estimate(t, ref, each_k=[0.95, 1.0, 1.01]))  # the first farthest
    assert m.moving_turn_worst_ratio == pytest.approx(0.95, abs=1e-9)
    est = estimate(t, ref, each_k=[1.5, 1.0, 1.01])
    i, j, _ = segment_turns(t, ref)[2]
    est[(i + j) // 2, 2] = np.nan  # a pose lost in the second moving turn: undefined, as the pooled ratio
    m = heading_metrics(t, ref, est)
    assert math.isnan(m.moving_turn_ratio) and math.isnan(m.moving_turn_worst_ratio)
    m = heading_metrics(t[:30], ref[:30], ref[:30].copy())  # no turn: undefined
    assert math.isnan(m.moving_turn_worst_ratio) and m.to_dict()["inplace_turn_worst_ratio"] is None


def test_a_speed_scale_shows_in_the_path_ratio_not_in_a_closed_loops_drift():
    # Every step 4 % short: the loop (out and back) shrinks but still closes on its start.
    t, ref = truth()
    m = heading_metrics(t, ref, estimate(t, ref, speed_k=0.96))
    assert m.path_ratio == pytest.approx(0.96, abs=1e-9)
    assert np.hypot(*(ref[-1, :2] - ref[0, :2])) < 0.01 * m.path_m
    assert m.drift_pct < 0.1
    assert m.yaw_rmse_deg == pytest.approx(0.0, abs=1e-9)


def test_straight_bias_and_turn_ratios_are_measured_apart():
    t, ref = truth()
    est = estimate(t, ref, bias_deg=0.02, moving_k=1.05, inplace_k=0.91)
    m = heading_metrics(t, ref, est)
    assert m.moving_turn_ratio == pytest.approx(1.05, abs=1e-9)
    assert m.inplace_turn_ratio == pytest.approx(0.91, abs=1e-9)
    assert m.straight_bias_deg_per_frame == pytest.approx(0.02, abs=2e-4)
    # 0.02 degrees a frame at 10 Hz: 12 degrees a minute; per metre at the straights' speeds
    assert m.straight_bias_deg_per_min == pytest.approx(12.0, abs=0.15)
    assert m.straight_bias_deg_per_m == pytest.approx(0.02 * m.straight_frames / m.straight_m, rel=1e-2)
    # final heading: the turns' excess (+4.5 - 4.5 - 16.2 degrees: the two moving turns cancel)
    # plus the straights' bias
    expected = 0.05 * 90 - 0.05 * 90 - 0.09 * 180 + 0.02 * m.straight_frames
    assert m.final_heading_error_deg == pytest.approx(expected, abs=0.1)
    assert m.drift_pct > 1.0


def test_a_turns_error_taken_back_after_it_is_told_from_the_straights_own_bias():
    # The turn in place measured 2 % long (3.6 degrees), a third of it taken back over the five
    # straight frames after it, and every straight frame turned by 0.01 degrees besides: the
    # straight bias holds both, the after-turn frames' sum the taking back, the rest the 0.01.
    t, ref = truth()
    est = estimate(t, ref, bias_deg=0.01, inplace_k=1.02)
    (_, end, _), = [turn for turn in segment_turns(t, ref) if turn[2]]
    d_est = np.diff(est[:, 2])
    d_est[end:end + 5] -= math.radians(0.02 * 180 / 3) / 5
    est = estimate_with_yaw(ref, est, d_est)
    m = heading_metrics(t, ref, est)
    assert m.straight_after_turn_frames == 3 * AFTER_TURN_FRAMES  # ten after each of the three turns
    assert m.straight_after_turn_deg == pytest.approx(-1.2 + 0.01 * m.straight_after_turn_frames, abs=1e-6)
    assert m.straight_own_bias_deg_per_frame == pytest.approx(0.01, abs=1e-6)
    total = 0.01 * m.straight_frames - 1.2
    assert m.straight_bias_deg_per_frame == pytest.approx(total / m.straight_frames, abs=1e-6)
    assert heading_metrics(t, ref, est, after_turn_frames=0).straight_after_turn_frames == 0
    same = heading_metrics(t, ref, est, after_turn_frames=0)
    assert same.straight_own_bias_deg_per_frame == pytest.approx(same.straight_bias_deg_per_frame, abs=1e-12)


def estimate_with_yaw(ref, est, d_est):
    """*est* with its yaw increments replaced by *d_est* (n-1,) rad, its body-frame steps kept."""
    steps = se2_relative(est[:-1], est[1:])
    yaw = est[0, 2] + np.concatenate([[0.0], np.cumsum(d_est)])
    c, s = np.cos(yaw[:-1]), np.sin(yaw[:-1])
    x = est[0, 0] + np.concatenate([[0.0], np.cumsum(c * steps[:, 0] - s * steps[:, 1])])
    y = est[0, 1] + np.concatenate([[0.0], np.cumsum(s * steps[:, 0] + c * steps[:, 1])])
    return np.column_stack([x, y, yaw])


def test_straights_that_turn_opposite_ways_are_measured_each_though_they_cancel_in_the_bias():
    # The loop's four straights (4 m at 1 m/s, 3 m and 3 m at 0.5 m/s, 4 m at 1 m/s) turned by
    # +0.02, -0.02, +0.01 and -0.01 degrees a frame: about 0.2, -0.4, 0.2 and -0.1 degrees a metre.
    t, ref = truth()
    steps = np.hypot(*np.diff(ref[:, :2], axis=0).T)
    moving = (steps * 10.0 > 0.05) & (np.degrees(np.abs(np.diff(ref[:, 2]))) * 10.0 <= 2.0)
    runs = straight_runs(moving, steps, np.zeros(len(steps)), 1.0)
    assert [m for _, _, m, _ in runs] == pytest.approx([4.0, 3.0, 3.0, 4.0], abs=0.35)  # less the ramps
    d_est = np.diff(ref[:, 2])
    per_m = []
    for (i, j, m, _), bias in zip(runs, (0.02, -0.02, 0.01, -0.01)):
        d_est[i:j] += math.radians(bias)
        per_m.append(bias * (j - i) / m)
    est = ref.copy()
    est[1:, 2] = ref[0, 2] + np.cumsum(d_est)
    m = heading_metrics(t, ref, est)
    assert m.straights == 4
    assert per_m == pytest.approx([0.2, -0.4, 0.2, -0.1], rel=0.1)
    assert abs(m.straight_bias_deg_per_m) < 0.03  # about -0.1 degree over 14 m
    assert m.straight_max_deg_per_m == pytest.approx(abs(per_m[1]), rel=1e-9)
    assert m.straight_rms_deg_per_m == pytest.approx(math.sqrt(np.mean(np.square(per_m))), rel=1e-9)
    assert heading_metrics(t, ref, est, min_straight_m=3.5).straights == 2  # the 4 m ones


@pytest.mark.parametrize("mount", [(0.3, 0.0, 0.0), (0.2, -0.15, math.radians(90.0)), (-0.4, 0.1, math.radians(-30.0))])
def test_a_mounted_radars_figures_are_told_by_its_base(mount):
    """A radar on a base (*mount*: x, y, yaw in the base's frame) moves on circles in the base's
    turn in place and sideways in its moving turns: given where it sits (``radar_on_base``), its
    straight frames and turns are the base's, and so are the turn ratios (yaw alone); its path
    and drift stay its own."""
    t, base = truth()
    est_base = estimate(t, base, bias_deg=0.02, moving_k=1.05, inplace_k=0.91)

    def radar_of(poses):
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        return np.column_stack([poses[:, 0] + c * mount[0] - s * mount[1], poses[:, 1] + s * mount[0] + c * mount[1],
                                poses[:, 2] + mount[2]])

    radar, est_radar = radar_of(base), radar_of(est_base)
    by_base = heading_metrics(t, base, est_base)
    told = heading_metrics(t, radar, est_radar, radar_on_base=mount)
    for name in ("straight_frames", "moving_turns", "inplace_turns"):
        assert getattr(told, name) == getattr(by_base, name), name
    for name in ("moving_turn_ratio", "inplace_turn_ratio", "straight_bias_deg_per_frame"):
        assert getattr(told, name) == pytest.approx(getattr(by_base, name), abs=1e-9), name
    assert told.path_m != pytest.approx(by_base.path_m)  # the radar's own path
    untold = heading_metrics(t, radar, est_radar)
    assert untold.inplace_turns == 0  # the radar itself moves through the base's turn in place
    assert drift_parts(t, radar, est_radar, radar_on_base=mount)["turn in place"] > 0.5
    assert drift_parts(t, radar, est_radar)["turn in place"] == pytest.approx(0.0, abs=1e-9)


def test_a_mount_must_be_three_finite_numbers():
    t, ref = truth()
    for bad in ((0.3, 0.0), (0.3, float("nan"), 0.0)):
        with pytest.raises(ValueError, match="radar_on_base must be three finite numbers"):
            heading_metrics(t, ref, ref, radar_on_base=bad)


def test_a_pure_yaw_increment_noise_gives_its_rmse():
    t, ref = truth()
    rng = np.random.default_rng(1)
    est = ref.copy()
    est[1:, 2] += np.cumsum(rng.normal(0.0, math.radians(0.5), len(ref) - 1))
    m = heading_metrics(t, ref, est)
    assert m.yaw_rmse_deg == pytest.approx(0.5, rel=0.1)


def test_a_still_truth_has_no_straight_or_turn_numbers():
    t = np.arange(20) * 0.1
    ref = np.zeros((20, 3))
    m = heading_metrics(t, ref, ref)
    assert m.straight_frames == 0 and math.isnan(m.straight_bias_deg_per_m)
    assert m.straights == 0 and math.isnan(m.straight_rms_deg_per_m) and math.isnan(m.straight_max_deg_per_m)
    assert math.isnan(m.moving_turn_ratio) and m.to_dict()["moving_turn_ratio"] is None
    with pytest.raises(ValueError):
        heading_metrics(t, ref, ref[:5])


def test_drift_parts_of_a_perfect_estimate_are_all_zero():
    t, ref = truth()
    parts = drift_parts(t, ref, ref.copy())
    assert list(parts) == list(DRIFT_PARTS)
    assert all(v == pytest.approx(0.0, abs=1e-9) for v in parts.values())


def test_drift_parts_put_a_turn_in_place_scale_error_on_the_turn_in_place_alone():
    t, ref = truth()
    est = estimate(t, ref, inplace_k=1.05)
    parts = drift_parts(t, ref, est)
    assert parts["all"] == pytest.approx(heading_metrics(t, ref, est).drift_pct, rel=1e-9)
    assert parts["turn in place"] == pytest.approx(parts["all"], rel=1e-6)
    assert parts["turn in place"] > 5.0  # 9 degrees turned too far with 7 m still to drive
    for name in ("straight", "after turn", "moving turn", "other", "translation"):
        assert parts[name] == pytest.approx(0.0, abs=1e-9), name


def test_drift_parts_tell_straight_frames_from_the_first_ones_after_a_turn():
    t, ref = truth()
    est = estimate(t, ref, bias_deg=0.05)
    parts = drift_parts(t, ref, est)
    assert parts["all"] == pytest.approx(heading_metrics(t, ref, est).drift_pct, rel=1e-9)
    assert parts["straight"] > parts["after turn"] > 0.0  # 3 frames after each of 3 turns, the rest straight
    assert parts["moving turn"] == pytest.approx(0.0, abs=1e-9)
    assert parts["turn in place"] == pytest.approx(0.0, abs=1e-9)
    assert drift_parts(t, ref, est, after_turn_frames=0)["after turn"] == pytest.approx(0.0, abs=1e-9)


def test_drift_parts_put_a_speed_error_on_the_translation_alone():
    t, ref = truth()
    est = ref.copy()
    steps = np.diff(ref[:, :2], axis=0) * 1.1  # every step 10 % long, the headings true
    est[1:, :2] = ref[0, :2] + np.cumsum(steps, axis=0)
    parts = drift_parts(t, ref, est)
    assert parts["translation"] == pytest.approx(parts["all"], rel=1e-6)
    assert parts["translation"] == pytest.approx(10.0 * np.hypot(*(ref[-1, :2] - ref[0, :2]))
                                                 / np.hypot(*np.diff(ref[:, :2], axis=0).T).sum(), rel=1e-6)
    assert all(parts[name] == pytest.approx(0.0, abs=1e-9) for name in DRIFT_PARTS[1:-1])


def test_drift_parts_refuse_trajectories_of_different_lengths():
    t, ref = truth()
    with pytest.raises(ValueError, match=r"\(n, 3\) SE\(2\) arrays"):
        drift_parts(t, ref, ref[:-1])


def test_radar_eval_prints_each_turns_own_ratio_where_a_kind_has_several():
    from radarodom.tools.eval_summary import format_heading

    t, ref = truth()
    est = estimate(t, ref, each_k=[1.04, 0.99, 0.97])
    text = format_heading(heading_metrics(t, ref, est), drift_parts(t, ref, est))
    moving = next(line for line in text.splitlines() if line.strip().startswith("moving turns"))
    assert moving.endswith("measured 1.005 of it; each turn's own, farthest from 1: 1.040")
    in_place = next(line for line in text.splitlines() if line.strip().startswith("turns in place"))
    assert in_place.endswith("measured 0.990 of it")  # one turn: nothing more to say
