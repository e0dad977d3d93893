"""The pose covariance's yaw (estimator/odometry.py, ``odometry.yaw_walk_per_sqrt_m`` and
``yaw_walk_per_sqrt_rad``, docs/heading.md item 28): where the keyframes bound the frames' own
noise, the yaw variance grows by the distance driven and the angle turned, not by the frames;
where nothing bounds it (a step whose yaw is held, no keyframes), the step's own variance adds.
Synthetic sequences of point reflectors (tests/estimator_synth.py) with their exact truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from estimator_synth import Trajectory, blind_heatmap, heatmap_chain, run_sequence, static_cloud

from radarodom.errors import ConfigError, EvaluationError
from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.consistency import covariance_consistency
from radarodom.estimator.odometry import Flag, RadarOdometry

DEG = math.radians(1.0)
#: 1 s standing, a straight, a moving left turn, a turn in place, a straight back.
LOOP = Trajectory([(1.0, 0.0, 0.0), (3.0, 0.8, 0.0), (2.0, 0.8, 45 * DEG), (2.0, 0.0, 45 * DEG),
                   (3.0, 0.8, 0.0)])
UNBOUNDED = (Flag.YAW_HELD, Flag.MOTION_LOST)


def walk(states, config: EstimatorConfig) -> np.ndarray:
    """The yaw variance (rad^2) each state's step adds by the walk: its distance and its turn."""
    odo = config.odometry
    out = [0.0]
    for a, b in zip(states, states[1:]):
        dt = b.t - a.t
        out.append(odo.yaw_walk_per_sqrt_m ** 2 * math.hypot(b.vx, b.vy) * dt
                   + odo.yaw_walk_per_sqrt_rad ** 2 * abs(b.yaw_increment))
    return np.array(out)


@pytest.fixture(scope="module")
def loop():
    """The heatmap chain's states over the loop: the covariance is that chain's, walked by its own
    steps (with ``point_yaw.blend`` the published heading's steps are partly the points')."""
    config = heatmap_chain()
    states, truths = run_sequence(config, LOOP)
    return config, states, truths


@pytest.fixture(scope="module")
def published_loop():
    """The default estimator's states over the loop, as published."""
    return run_sequence(EstimatorConfig(), LOOP)


def test_the_yaw_variance_is_the_walk_of_the_distance_and_the_turn(loop):
    config, states, _ = loop
    measured = [s for s in states[1:] if not set(s.flags) & set(UNBOUNDED)]
    assert len(measured) == len(states) - 1, [s.flags for s in states if s.flags]
    var = np.array([s.pose_covariance[2, 2] for s in states])
    np.testing.assert_allclose(var, np.cumsum(walk(states, config)), rtol=1e-9, atol=1e-15)
    # 6.4 m driven and 180 degrees turned: 1 degree per sqrt(m) and 0.16 per sqrt(degree), as the
    # matrix's straights and turns (docs/heading.md, item 28); a little more for the noise's turns.
    expected = 0.017 ** 2 * 6.4 + 0.022 ** 2 * math.pi
    assert 0.95 * expected < var[-1] < 1.1 * expected


def test_standing_still_does_not_grow_the_yaw_variance(loop):
    config, states, _ = loop
    standing = [s for s in states if s.t <= 1.0]
    assert len(standing) == 11
    # Ten frames of standing: only the turn each increment reads (noise) walks the yaw (summed, each
    # frame's own variance made 1.8 degrees of it).
    assert math.degrees(math.sqrt(standing[-1].pose_covariance[2, 2])) < 0.5
    driving = [s for s in states if 1.0 < s.t <= 4.0]
    assert math.degrees(math.sqrt(driving[-1].pose_covariance[2, 2])) > 1.4  # sqrt(2.4 m) at 1 deg/sqrt(m)


@pytest.mark.parametrize("which", ["loop", "published_loop"])
def test_the_truth_lies_within_the_yaw_covariance(which, request):
    states, truths = request.getfixturevalue(which)[-2:]
    err = np.array([math.remainder(s.yaw - t[2], math.tau) for s, t in zip(states, truths)])[1:]
    sigma = np.sqrt([s.pose_covariance[2, 2] for s in states])[1:]
    assert np.all(np.abs(err) <= 3 * sigma)
    # Nor so wide that it says nothing: a few degrees after the loop, not tens.
    assert 1.0 * DEG < sigma[-1] < 6.0 * DEG


def test_without_keyframes_each_step_adds_its_own_variance():
    config = heatmap_chain(odometry={"keyframe_distance_m": 0.0})
    states, _ = run_sequence(config, LOOP)
    var = np.array([s.pose_covariance[2, 2] for s in states])
    steps = var[1:] - var[:-1]
    own = np.array([s.twist_covariance[2, 2] * (s.t - a.t) ** 2 for a, s in zip(states, states[1:])])
    np.testing.assert_allclose(steps, walk(states, config)[1:] + own, rtol=1e-9, atol=1e-15)
    assert np.all(own > 0)


def test_a_held_step_adds_its_own_variance():
    # Frames that see nothing: the yaw is not measured, and its variance stays in the heading.
    config = EstimatorConfig()
    odom = RadarOdometry(config)
    states = [odom.step(0.1 * i, static_cloud((0.8, 0.0), seed=i), blind_heatmap()) for i in range(6)]
    assert states[0].pose_covariance[2, 2] == 0.0
    assert all(set(s.flags) & set(UNBOUNDED) for s in states[1:]), [s.flags for s in states]
    var = np.array([s.pose_covariance[2, 2] for s in states])
    own = np.array([s.twist_covariance[2, 2] * (s.t - a.t) ** 2 for a, s in zip(states, states[1:])])
    np.testing.assert_allclose(np.diff(var), walk(states, config)[1:] + own, rtol=1e-9, atol=1e-15)
    assert np.all(own > 0)


def test_zero_walk_keeps_the_measured_steps_out():
    config = EstimatorConfig().with_(odometry={"yaw_walk_per_sqrt_m": 0.0, "yaw_walk_per_sqrt_rad": 0.0})
    states, _ = run_sequence(config, LOOP)
    assert all(s.pose_covariance[2, 2] == 0.0 for s in states)
    # The position's covariance still grows with the velocity's.
    assert states[-1].pose_covariance[0, 0] > states[10].pose_covariance[0, 0] > 0.0


@pytest.mark.parametrize("field, value", [("yaw_walk_per_sqrt_m", -0.01), ("yaw_walk_per_sqrt_rad", 2.0),
                                          ("yaw_walk_per_sqrt_m", float("nan"))])
def test_walk_settings_out_of_range_are_refused(field, value):
    with pytest.raises(ConfigError) as exc:
        EstimatorConfig.from_dict({"odometry": {field: value}})
    assert exc.value.field == f"odometry.{field}"
    assert ("rad/sqrt" if math.isfinite(value) else "finite") in str(exc.value)


def test_the_walk_changes_the_covariance_only():
    still = EstimatorConfig().with_(odometry={"yaw_walk_per_sqrt_m": 0.0, "yaw_walk_per_sqrt_rad": 0.0})
    plain, _ = run_sequence(still, LOOP)
    walked, _ = run_sequence(EstimatorConfig(), LOOP)
    assert [(s.t, s.x, s.y, s.yaw, s.vx, s.vy, s.yaw_rate, s.flags) for s in plain] == \
        [(s.t, s.x, s.y, s.yaw, s.vx, s.vy, s.yaw_rate, s.flags) for s in walked]
    assert all(np.array_equal(a.twist_covariance, b.twist_covariance) for a, b in zip(plain, walked))


def test_the_papers_method_adds_each_steps_own_variance_alone():
    config = EstimatorConfig.paper()
    assert (config.odometry.yaw_walk_per_sqrt_m, config.odometry.yaw_walk_per_sqrt_rad) == (0.0, 0.0)
    states, _ = run_sequence(config, LOOP)
    own = [s.twist_covariance[2, 2] * (s.t - a.t) ** 2 for a, s in zip(states, states[1:])]
    np.testing.assert_allclose([s.pose_covariance[2, 2] for s in states[1:]], np.cumsum(own), rtol=1e-9)


def test_a_bridged_step_adds_its_own_variance():
    # Turning in place, blind for 0.8 s: the frame that sees again is measured across the run from
    # the last measured state, whose covariance it starts from, and adds its own variance as well.
    from test_estimator_bridge import run as turn_blind
    config = EstimatorConfig()
    states = turn_blind(1.0, range(5, 13), "blind")
    back, anchor = states[13], states[4]
    dyaw = back.yaw - anchor.yaw
    assert back.yaw_rate * (back.t - anchor.t) == pytest.approx(dyaw)  # the run's mean rate: bridged
    own = back.twist_covariance[2, 2] * (back.t - anchor.t) ** 2
    walk_part = config.odometry.yaw_walk_per_sqrt_rad ** 2 * abs(dyaw) + config.odometry.yaw_walk_per_sqrt_m ** 2 \
        * math.hypot(back.vx, back.vy) * (back.t - anchor.t)
    assert back.pose_covariance[2, 2] == pytest.approx(anchor.pose_covariance[2, 2] + walk_part + own, rel=1e-9)


def _arrays(states):
    return (np.array([s.t for s in states]), np.array([(s.x, s.y, s.yaw) for s in states]),
            np.array([s.pose_covariance for s in states]), np.array([s.twist_covariance for s in states]),
            np.array([s.yaw_rate for s in states]), np.array([s.frame for s in states]))


def test_consistency_of_the_synthetic_loop(loop):
    _, states, truths = loop
    times, est, pose_cov, twist_cov, rates, frames = _arrays(states)
    got = covariance_consistency(np.array(truths), est, pose_cov)
    assert got["yaw"]["within_2sigma"] == 1.0 and 0.1 < got["yaw"]["z_rms"] < 1.5
    assert 0.1 < got["position"]["z_rms"] < 1.5
    assert got["final_yaw_sigma_deg"] == pytest.approx(math.degrees(math.sqrt(states[-1].pose_covariance[2, 2])))
    assert got["final_yaw_error_deg"] == pytest.approx(math.degrees(states[-1].yaw - truths[-1][2]), abs=1e-9)
    assert got["yaw_rate"] is None
    with_twist = covariance_consistency(np.array(truths), est, pose_cov, twist_covariance=twist_cov, times=times,
                                        yaw_rates=rates, frames=frames)
    assert with_twist["yaw"] == got["yaw"] and 0.1 < with_twist["yaw_rate"]["z_rms"] < 1.5


def test_consistency_counts_from_the_first_compared_frame(loop):
    # Messages from the middle of a run (radar-echo started late): the covariance the odometry had
    # there is taken off, as the errors count from there.
    _, states, truths = loop
    _, est, pose_cov, *_ = _arrays(states)
    late = covariance_consistency(np.array(truths)[60:], est[60:], pose_cov[60:])
    sd = math.sqrt(states[-1].pose_covariance[2, 2] - states[60].pose_covariance[2, 2])
    assert late["final_yaw_sigma_deg"] == pytest.approx(math.degrees(sd))
    err = math.remainder((states[-1].yaw - truths[-1][2]) - (states[60].yaw - truths[60][2]), math.tau)
    assert late["final_yaw_error_deg"] == pytest.approx(math.degrees(err), abs=1e-9)


def test_consistency_puts_the_truth_in_the_estimates_world_and_counts_the_frames():
    # The truth starts elsewhere, facing elsewhere; the estimate is it, moved to the origin, with
    # heading errors of 0, 0.5, -1.5 and 3 degrees and a standard deviation of 1 degree.
    truth = np.array([[5.0, 2.0, 1.0], [6.0, 2.0, 1.0], [6.0, 3.0, 1.5], [5.0, 3.0, 2.0]])
    c, s = math.cos(-1.0), math.sin(-1.0)
    d = truth[:, :2] - truth[0, :2]
    est = np.c_[c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1], truth[:, 2] - 1.0]
    est[:, 2] += np.radians([0.0, 0.5, -1.5, 3.0])
    est[3, :2] += (0.3, 0.4)  # 0.5 m off at the last frame
    cov = np.zeros((4, 3, 3))
    cov[1:, 2, 2] = DEG ** 2
    cov[1:, 0, 0] = cov[1:, 1, 1] = 0.125  # a position sd of 0.5 m
    got = covariance_consistency(truth, est, cov)
    assert got["yaw"]["z_rms"] == pytest.approx(math.sqrt((0.25 + 2.25 + 9) / 3))  # the first frame has no variance
    assert got["yaw"]["within_1sigma"] == pytest.approx(1 / 3) and got["yaw"]["within_2sigma"] == pytest.approx(2 / 3)
    assert got["position"]["z_rms"] == pytest.approx(math.sqrt(1 / 3)) and got["position"]["within_1sigma"] == 1.0
    assert got["final_yaw_error_deg"] == pytest.approx(3.0) and got["final_yaw_sigma_deg"] == pytest.approx(1.0)
    # The yaw rate: each step's turn error (0.5, -2, 4.5 degrees) over its rate's sd (1 deg/s) times 0.4 s.
    times = np.arange(4) * 0.4
    twist = np.zeros((4, 3, 3))
    twist[:, 2, 2] = DEG ** 2
    rates = np.r_[0.0, np.diff(est[:, 2]) / 0.4]
    both = covariance_consistency(truth, est, cov, twist_covariance=twist, times=times, yaw_rates=rates)
    rate = both["yaw_rate"]
    assert rate["z_rms"] == pytest.approx(math.sqrt((1.25 ** 2 + 5 ** 2 + 11.25 ** 2) / 3))
    assert rate["within_1sigma"] == 0.0 and rate["within_2sigma"] == pytest.approx(1 / 3)
    assert both["forward_speed"]["z_rms"] is None and both["sideways_speed"]["z_rms"] is None  # (no speed variance)
    # A step whose rate is not its turn over its time (measured across a bridged run), or between
    # frames that do not follow (a message lost), is not one step: left out.
    bridged = rates.copy()
    bridged[2] /= 3
    rate = covariance_consistency(truth, est, cov, twist_covariance=twist, times=times, yaw_rates=bridged,
                                  frames=[0, 1, 2, 4])["yaw_rate"]
    assert rate["z_rms"] == pytest.approx(1.25)
    with pytest.raises(EvaluationError, match="same frames"):
        covariance_consistency(truth, est[:3], cov)
    with pytest.raises(EvaluationError, match="yaw rates"):
        covariance_consistency(truth, est, cov, twist_covariance=twist, times=times)


def test_a_step_across_half_a_turn_is_one_step():
    # Yaws read back from quaternions wrap at +/-180 degrees; a step from 179 to -179 degrees turned 2.
    yaw = np.radians([177.0, 179.0, -179.0, -177.0])
    est = np.c_[np.zeros(4), np.zeros(4), yaw]
    truth = est.copy()
    truth[:, 2] += np.radians([0.0, 0.5, 0.5, 0.5])  # the estimate's second step 0.5 degrees short
    cov = np.zeros((4, 3, 3))
    cov[:, 2, 2] = np.arange(4) * DEG ** 2
    twist = np.zeros((4, 3, 3))
    twist[:, 2, 2] = (0.5 * DEG / 0.1) ** 2  # a step's sd of 0.5 degrees
    rates = np.full(4, math.radians(2.0) / 0.1)
    got = covariance_consistency(truth, est, cov, twist_covariance=twist, times=np.arange(4) * 0.1, yaw_rates=rates)
    assert got["yaw_rate"]["z_rms"] == pytest.approx(math.sqrt(1 / 3))  # all three steps, one off by one sd


def test_the_speeds_error_over_the_twists_sd():
    # Straight along x at 1 m/s, 0.1 s steps; the estimate 2 cm/s fast and 1 cm/s to the left in its
    # second step, with a speed sd of 1 cm/s each way.
    truth = np.c_[np.arange(4) * 0.1, np.zeros(4), np.zeros(4)]
    est = truth.copy()
    est[2:, 0] += 0.002
    est[2:, 1] += 0.001
    twist = np.zeros((4, 3, 3))
    twist[:, 0, 0] = twist[:, 1, 1] = 0.01 ** 2
    twist[:, 2, 2] = DEG ** 2
    got = covariance_consistency(truth, est, np.zeros((4, 3, 3)), twist_covariance=twist, times=np.arange(4) * 0.1,
                                 yaw_rates=np.zeros(4))
    assert got["forward_speed"]["z_rms"] == pytest.approx(math.sqrt(4 / 3))
    assert got["sideways_speed"]["z_rms"] == pytest.approx(math.sqrt(1 / 3))
    assert got["forward_speed"]["within_1sigma"] == pytest.approx(2 / 3)



def _perfect_run(poses, stamps: np.ndarray, truth_stamps: np.ndarray | None = None, *, at: float = 0.0,
                 measured_at_s: float = 0.0, frames: bool = True, jump_at: float = math.inf):
    """odometry_consistency of states at *stamps* whose poses are *poses* (times -> (n, 3)) exactly
    *at* s later (5 cm further along x from *jump_at* s), against those poses at *truth_stamps*
    (default: the states' own); standard deviations of 1 cm, 1 cm/s and 1 degree (a second)."""
    from radarodom.estimator.consistency import odometry_consistency
    from radarodom.tum import TumTrajectory
    truth_stamps = stamps if truth_stamps is None else truth_stamps
    n = len(stamps)
    est = poses(stamps + at)
    est -= est[0]
    est[stamps >= jump_at, 0] += 0.05
    pose_cov = np.zeros((n, 3, 3))
    pose_cov[1:] = np.diag([0.01 ** 2, 0.01 ** 2, DEG ** 2])
    twist = np.zeros((n, 3, 3))
    twist[:] = np.diag([0.01 ** 2, 0.01 ** 2, DEG ** 2])
    rates = np.r_[0.0, np.diff(est[:, 2]) / np.diff(stamps)]
    return odometry_consistency(stamps, est, pose_cov, twist, rates, np.arange(n) if frames else None,
                                TumTrajectory.from_se2(truth_stamps, poses(truth_stamps)), measured_at_s=measured_at_s)


def _consistency_of_a_perfect_estimate(poses, at: float, measured_at_s: float = 0.0, n: int = 21):
    """:func:`_perfect_run` at *n* stamps 0.1 s apart, the truth at the stamps."""
    return _perfect_run(poses, np.arange(n) * 0.1, at=at, measured_at_s=measured_at_s)


def test_the_truth_compared_where_the_odometry_describes_the_radar():
    # The odometry describes the radar at the middle of a frame's chirps, 13.44 ms after its stamp
    # (RadarConfig.measured_at_s).  Speeding up at 2 m/s^2, a perfect estimate of that pose reads
    # 2.7 cm/s fast against the truth at the stamps, and nothing against the truth 13.44 ms later
    # (interpolated between its 10 Hz poses: for a steady acceleration, exactly the velocity there);
    # starting a turn at 100 deg/s^2, its yaw rate alike.
    at = 0.01344
    driving = lambda t: np.c_[t * t, np.zeros(len(t)), np.zeros(len(t))]  # noqa: E731
    turning = lambda t: np.c_[np.zeros(len(t)), np.zeros(len(t)), 0.5 * math.radians(100.0) * t * t]  # noqa: E731
    paired, count = _consistency_of_a_perfect_estimate(driving, at)
    assert count == 21 and paired["measured_at_s"] == 0.0
    assert paired["forward_speed"]["z_rms"] == pytest.approx(2.0 * at / 0.01, rel=1e-6)  # a * 13.44 ms over 1 cm/s
    shifted, count = _consistency_of_a_perfect_estimate(driving, at, at)
    assert count == 20 and shifted["measured_at_s"] == at  # the last message's truth would be after the truth's end
    for part in ("forward_speed", "sideways_speed", "yaw_rate", "yaw"):
        assert shifted[part]["z_rms"] < 1e-6, part
    assert shifted["position"]["z_rms"] < 0.1  # (linear between poses 0.1 s apart: a millimetre at most)
    paired, _ = _consistency_of_a_perfect_estimate(turning, at)
    assert paired["yaw_rate"]["z_rms"] == pytest.approx(100.0 * at / 1.0, rel=1e-6)
    shifted, _ = _consistency_of_a_perfect_estimate(turning, at, at)
    assert shifted["yaw_rate"]["z_rms"] < 1e-6 and shifted["yaw"]["z_rms"] < 0.1
    for bad in (1.5, -2.0, math.nan, math.inf, True, "0.01", 10 ** 400):
        with pytest.raises(EvaluationError, match="measured_at_s must be a time within"):
            _consistency_of_a_perfect_estimate(driving, at, bad)
    for offset, where in ((0.35, "350 ms after"), (-0.35, "350 ms before")):
        with pytest.raises(EvaluationError, match=rf"odometry: fewer than two of its 5 messages \(t 0.000 .. 0.400 s\) "
                                                  rf"have a ground truth "
                                                  rf"{where} their t \(the truth: t 0.000 .. 0.400 s, 5 poses\)"):
            _consistency_of_a_perfect_estimate(driving, at, offset, n=5)


def test_the_truth_is_not_interpolated_across_its_gaps():
    # A truth with 2 s missing: the message paired at its stamp before the gap would be compared with
    # a pose interpolated across it (a helper's hunt: forward speed 5.4 RMS where the truth gave 0.5).
    from radarodom.estimator.consistency import odometry_consistency
    from radarodom.tum import TumTrajectory
    stamps = np.arange(40) * 0.1
    truth = np.c_[stamps * stamps, np.zeros(40), np.zeros(40)]  # speeding up at 2 m/s^2
    keep = (stamps < 1.0) | (stamps > 2.95)
    n = 40
    cov = np.zeros((n, 3, 3))
    cov[:] = np.diag([1e-4, 1e-4, DEG ** 2])
    args = (stamps, truth - truth[0], cov, cov, np.zeros(n), np.arange(n), TumTrajectory.from_se2(stamps[keep],
                                                                                                  truth[keep]))
    whole, used = odometry_consistency(*args[:-1], TumTrajectory.from_se2(stamps, truth), measured_at_s=0.01)
    gapped, used_gapped = odometry_consistency(*args, measured_at_s=0.01)
    assert used == 39 and used_gapped == int(keep.sum()) - 2  # the last, and the last before the gap
    # The estimate is the truth at the stamps: 2 cm/s slow against the truth 10 ms later, 2 sd, either way.
    assert gapped["forward_speed"]["z_rms"] == pytest.approx(2.0)
    assert whole["forward_speed"]["z_rms"] == pytest.approx(2.0)
    # At 0 s, a message at a truth pose's time (to a microsecond: files round) is compared with it.
    at_stamps, used = odometry_consistency(stamps + 1e-7, *args[1:])
    assert used == int(keep.sum()) and at_stamps["measured_at_s"] == 0.0
    assert at_stamps["forward_speed"]["z_rms"] < 1e-3


def _driving(t: np.ndarray) -> np.ndarray:
    """Along x at 1 m/s."""
    return np.c_[t, np.zeros(len(t)), np.zeros(len(t))]


def test_every_message_within_the_truth_is_compared():
    # A review's findings: messages were first paired one to one with a truth pose within --max-diff,
    # so a truth slower than the odometry, or stamped off it, left most out (or all: "0 poses match").
    odometry = np.arange(60) / 30.0
    got, used = _perfect_run(_driving, odometry, np.arange(20) * 0.1)  # 30 Hz odometry, 10 Hz truth
    assert used == 58 and got["forward_speed"]["z_rms"] < 1e-9 and got["position"]["z_rms"] < 1e-9
    got, used = _perfect_run(_driving, odometry, np.arange(20) * 0.1 + 0.05)  # the truth's stamps 50 ms off
    assert used == 57 and got["forward_speed"]["z_rms"] < 1e-9  # (interpolated at t, not the nearest)
    # A fast truth's dropout of a few poses is interpolated across (the gap's floor, 50 ms) ...
    fast = np.arange(100) * 0.01
    _, used = _perfect_run(_driving, fast, np.delete(fast, [40, 41]))
    assert used == 100
    # ... and without frame numbers a step across messages left out is not a single step (here the
    # estimate jumps 5 cm ahead in the gap: were the step across it compared, its speed 10 sd off).
    truth = np.delete(np.arange(20) * 0.1, range(8, 12))  # 0.4 s missing: a gap
    numbered, used = _perfect_run(_driving, np.arange(20) * 0.1, truth, jump_at=1.0)
    unnumbered, used_too = _perfect_run(_driving, np.arange(20) * 0.1, truth, frames=False, jump_at=1.0)
    assert used == used_too == 16 and numbered["forward_speed"] == unnumbered["forward_speed"]
    assert unnumbered["forward_speed"]["z_rms"] < 1e-9 and unnumbered["position"]["z_rms"] > 0.1


def test_odometry_consistency_refuses_what_is_not_a_run():
    from radarodom.estimator.consistency import odometry_consistency
    from radarodom.tum import TumTrajectory
    t = np.arange(5) * 0.1
    poses, cov = np.zeros((5, 3)), np.zeros((5, 3, 3))
    truth = TumTrajectory.from_se2(t, poses)
    good = dict(times=t, poses=poses, pose_covariance=cov, twist_covariance=cov, yaw_rates=np.zeros(5),
                frames=np.arange(5), reference=truth)
    assert odometry_consistency(**{**good, "frames": None})[1] == 5  # (frame numbers are optional)
    for change, message in (({"pose_covariance": cov[:4]}, r"pose_covariance \(4, 3, 3\)"),
                            ({"frames": np.arange(4)}, r"frames \(4,\)"),
                            ({"times": t[:, None]}, r"got times \(5, 1\)"),
                            ({"poses": np.full((5, 3), np.inf)}, "poses: every value must be a finite number"),
                            ({"yaw_rates": ["a"] * 5}, "yaw_rates: numbers are needed"),
                            ({"frames": -np.arange(5)}, "frames: whole numbers from 0")):
        with pytest.raises(EvaluationError, match=message):
            odometry_consistency(**{**good, **change})
    for far in (1e15 + 10 * t, 1e12 + t):  # (t + 0.01 is t there, or 12 microseconds off)
        with pytest.raises(EvaluationError, match="are too large to be moved by 0.01 s in floating point"):
            odometry_consistency(**{**good, "times": far, "reference": TumTrajectory.from_se2(far, poses)},
                                 measured_at_s=0.01)
    with pytest.raises(EvaluationError, match="frames: whole numbers from 0"):
        odometry_consistency(**{**good, "frames": np.full(5, 2.0 ** 64)})
    with pytest.raises(EvaluationError, match="reference: a TumTrajectory"):
        odometry_consistency(**{**good, "reference": "gt.tum"})
    with pytest.raises(EvaluationError, match="timestamps must increase"):
        odometry_consistency(**{**good, "reference": TumTrajectory.from_se2(t[::-1], poses)})
    with pytest.raises(EvaluationError, match="the times must increase"):
        covariance_consistency(poses, poses, cov, twist_covariance=cov, times=np.zeros(5), yaw_rates=np.zeros(5))
