"""The Doppler yaw rate of a radar mounted off a wheeled base's rotation axis (issue 20, beyond
the paper: Kellner et al. 2014): with odometry.base "wheeled" and the mounting, the sideways part
of the radar's Doppler velocity measures the yaw rate, fused with the heatmap registration and
standing in for it when the registration fails; on the axis the radar does not slide sideways."""

from __future__ import annotations

import functools
import math

import estimator_synth as synth
import numpy as np
import pytest

from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.doppler_yaw import DopplerYawRate, NoSideSlip, fuse
from radarodom.estimator.odometry import RadarOdometry
from radarodom.estimator.quality import Flag
from radarodom.estimator.velocity import FEW_POINTS, OK, VelocityEstimate
from radarodom.estimator.velocity_track import VelocityTrack
from radarodom.products import RangeAzimuth

LEVER = 0.3
DT = 0.1


def _radar_pose(base_pose, mount=(LEVER, 0.0, 0.0)):
    x, y, yaw = base_pose
    mx, my, myaw = mount
    c, s = math.cos(yaw), math.sin(yaw)
    return x + c * mx - s * my, y + s * mx + c * my, yaw + myaw


def _radar_velocity(v, w, mount=(LEVER, 0.0, 0.0)):
    mx, my, myaw = mount
    bx, by = v - w * my, w * mx  # base axes
    c, s = math.cos(myaw), math.sin(myaw)
    return c * bx + s * by, -s * bx + c * by  # radar axes


def _blank_heatmap(rng):
    """A heatmap of noise alone: nothing to register."""
    shape = (len(synth.RANGE_M), len(synth.AZIMUTH_RAD))
    noise = (1e-3 * rng.exponential(size=shape)).astype(np.float32)
    return RangeAzimuth(noise, noise.copy(), np.full(shape, np.nan, np.float32), synth.RANGE_M.copy(),
                        synth.AZIMUTH_RAD.copy())


def _run(config, phases, *, blank=False, mount=(LEVER, 0.0, 0.0), seed=3):
    traj = synth.Trajectory(phases)
    world, amp = synth.scene(traj, 120, seed=seed, separation_m=1.0)
    rng = np.random.default_rng(seed)
    odom = RadarOdometry(config)
    n = int(round(traj.duration / DT))
    states = []
    for k in range(n + 1):
        t = k * DT
        v, _, w = traj.twist(t)
        pose = _radar_pose(traj.pose(t), mount)
        cloud, hm = synth.frame(world, amp, pose, _radar_velocity(v, w, mount), rng)
        states.append(odom.step(t, cloud, _blank_heatmap(rng) if blank else hm))
    true_turn = traj.pose(n * DT)[2] - traj.pose(0.0)[2]
    return states, true_turn


def _wheeled(mount=(LEVER, 0.0, 0.0), **odometry):
    # These phases change speed in a step (0 -> 0.6 m/s between two frames, which no platform
    # does): the velocity's acceleration check (velocity.max_accel_mps2) would refuse it.  They
    # turn before they drive straight: the mount's yaw as given (axis_learn_frames 0), unless said.
    return EstimatorConfig().with_(odometry={"base": "wheeled", "mount_x_m": mount[0], "mount_y_m": mount[1],
                                             "mount_yaw_rad": mount[2], "axis_learn_frames": 0, **odometry},
                                   velocity={"max_accel_mps2": None})


SPIN = [(0.5, 0.0, 0.0), (4.0, 0.0, math.radians(45.0)), (0.5, 0.0, 0.0)]
ARC = [(0.5, 0.0, 0.0), (1.0, 0.6, 0.0), (3.0, 0.6, math.radians(-30.0)), (1.0, 0.6, 0.0)]


@pytest.fixture(scope="module")
def blank_run():
    """``_run(_wheeled(mount), phases, blank=True, mount=mount)`` (heatmaps of noise alone; the mount
    by default 0.3 m ahead of the axis, _run's and _wheeled's), each made once for the tests that
    read it (never changed): a whole simulated run, and the same inputs give the same states (the
    estimator is deterministic)."""
    @functools.cache
    def made(phases: tuple, mount: tuple):
        return _run(_wheeled(mount), list(phases), blank=True, mount=mount)
    return lambda phases, mount=(LEVER, 0.0, 0.0): made(tuple(phases), mount)


@pytest.mark.parametrize("phases, mount", [
    (SPIN, (LEVER, 0.0, 0.0)), (ARC, (LEVER, 0.0, 0.0)), (ARC, (-0.25, 0.1, 0.0)),
    # Yawed on the base, the radar's forward speed leaks into the base's sideways axis: a
    # 1 % speed error is some 2 % of this moving turn's rate, so the yawed mount turns in place.
    (SPIN, (-0.25, 0.1, math.radians(20.0)))],
    ids=["in place, ahead", "moving, ahead", "moving, behind", "in place, behind and yawed"])
def test_the_doppler_alone_measures_the_turn_when_the_heatmap_holds_nothing(phases, mount, blank_run):
    states, true_turn = blank_run(phases, mount)
    assert all("no_structure" in s.flags for s in states[1:])  # the registration measured nothing
    # In a moving turn the fit's sideways speed runs long (docs/heading.md, the mounted radar's
    # moving turns): 2 % in place, 4 % moving.
    assert states[-1].yaw == pytest.approx(true_turn, rel=0.02 if phases is SPIN else 0.04)


@pytest.mark.parametrize("phases", [SPIN, ARC], ids=["in place", "moving"])
def test_a_frame_the_doppler_alone_measured_is_not_corrected_against_the_keyframe(phases, blank_run):
    # The keyframe's registration against a heatmap of noise measures noise: the yaw is the
    # Doppler's, as without keyframes, to the last bit.
    with_keyframes, _ = blank_run(phases)
    without, _ = _run(_wheeled(keyframe_distance_m=0.0), phases, blank=True)
    assert [s.yaw for s in with_keyframes] == [s.yaw for s in without]


def test_without_a_wheeled_base_the_doppler_says_nothing_of_the_yaw():
    # (The heatmaps' registration alone: the points' would measure the turn from the clouds.)
    states, true_turn = _run(synth.heatmap_chain(odometry={"mount_x_m": LEVER}), SPIN, blank=True)
    assert abs(states[-1].yaw) < 0.2 * abs(true_turn)  # the held rate stops after hold_s


def test_a_radar_on_the_axis_uses_no_doppler_yaw_rate():
    config = _wheeled((0.0, 0.0, 0.0)).with_(point_yaw={"blend": 0.0})  # (as above)
    states, true_turn = _run(config, SPIN, blank=True, mount=(0.0, 0.0, 0.0))
    assert abs(states[-1].yaw) < 0.2 * abs(true_turn)


def test_on_the_axis_a_fit_leaning_sideways_does_not_move_the_radar_sideways():
    # The point clouds say 4 cm/s to the left for one second (a fit leaning with elevated
    # returns, as a 2-TX array's does, passing a shelf) while the radar drives straight ahead at
    # 0.6 m/s for 6 s; the base's axis was learnt from the straight frames before.
    traj = synth.Trajectory([(0.5, 0.0, 0.0), (6.0, 0.6, 0.0)])
    world, amp = synth.scene(traj, 160, seed=3, separation_m=1.0)
    # Both bases see the same frames (made once: the estimator leaves its inputs alone).
    rng = np.random.default_rng(3)
    frames = []
    for k in range(int(round(traj.duration / DT)) + 1):
        t = k * DT
        v, _, _ = traj.twist(t)
        cloud, _ = synth.frame(world, amp, traj.pose(t), (v, 0.04 if 4.0 <= t < 5.0 else 0.0), rng)
        _, heatmap = synth.frame(world, amp, traj.pose(t), (v, 0.0), rng)
        frames.append((t, cloud, heatmap))
    ends = {}
    for base in ("wheeled", "any"):
        odom = RadarOdometry(_wheeled((0.0, 0.0, 0.0)).with_(odometry={"base": base}))
        for t, cloud, heatmap in frames:
            state = odom.step(t, cloud, heatmap)
            if base == "wheeled" and 4.0 <= t < 5.0:
                # The lean gone: what is left is the learnt axis's own error (its median is the clean frames').
                assert abs(state.vy) < 0.006
        ends[base] = state
    # The lean's 4 cm: all of it without the constraint; with it, what the learnt axis's error of a
    # few tenths of a degree puts into the 3.8 m driven.
    assert ends["any"].y > 0.035
    assert abs(ends["wheeled"].y) < 0.02
    assert ends["wheeled"].x == pytest.approx(ends["any"].x, rel=0.02)


def _slip(**odometry):
    return NoSideSlip(EstimatorConfig().odometry.__class__(base="wheeled", **odometry))


def _est(vx, vy, t=1.0):
    return VelocityEstimate(t=t, vx=vx, vy=vy, covariance=np.diag([1e-4, 4e-4]), status=OK)


def test_no_sideways_slip_keeps_the_forward_part_along_the_bases_axes():
    # The mount's yaw as given (no learning): 30 degrees, 3 cm ahead of the axis, turning at
    # 0.5 rad/s: the base's forward axis in the radar's is (cos 30, -sin 30), its left (sin 30, cos 30).
    forward, left = np.array([math.sqrt(3) / 2, -0.5]), np.array([0.5, math.sqrt(3) / 2])
    part = _slip(mount_x_m=0.03, mount_yaw_rad=math.radians(30.0), axis_learn_frames=0)
    out = part(_est(0.5, 0.05), yaw_rate=0.5)
    along = forward @ np.array([0.5, 0.05])
    np.testing.assert_allclose(out.velocity, along * forward + 0.5 * 0.03 * left, atol=1e-12)
    side_var = (math.radians(1.0) * along) ** 2  # no_slip_angle_std_rad x the forward speed
    expected = (forward @ np.diag([1e-4, 4e-4]) @ forward) * np.outer(forward, forward) + side_var * np.outer(left, left)
    np.testing.assert_allclose(out.covariance, expected, atol=1e-15)
    # Standing: the sideways variance's floor, 1 mm/s, so that the covariance can be inverted.
    assert np.linalg.det(_slip(axis_learn_frames=0)(_est(0.0, 0.0), 0.0).covariance) > 0
    failed = VelocityEstimate(t=1.0, vx=0.5, vy=0.05, status=FEW_POINTS)
    assert _slip(axis_learn_frames=0)(failed, 0.0) is failed  # not measured: nothing to constrain


def test_the_bases_forward_axis_is_learnt_from_the_straight_drives(caplog):
    # The mount said 4 degrees to the left; the radar looks straight ahead along the base.
    part = _slip(mount_yaw_rad=math.radians(4.0), axis_learn_frames=20)
    assert part.axes.offset_rad is None
    with caplog.at_level("WARNING", logger="radarodom.estimator.doppler_yaw"):
        # A turn and a creep teach nothing; nineteen straight frames pass as measured.
        assert part(_est(0.6, 0.1), yaw_rate=0.5).vy == 0.1
        assert part(_est(0.2, 0.01), yaw_rate=0.0).vy == 0.01
        for k in range(19):
            assert part(_est(0.6, 0.0, t=k), yaw_rate=0.0).vy == 0.0
            assert part.axes.offset_rad is None
        out = part(_est(0.6, 0.0, t=19), yaw_rate=0.0)
    assert part.axes.offset_rad == pytest.approx(math.radians(4.0))
    assert out.velocity == pytest.approx([0.6, 0.0], abs=1e-12)
    assert "4.0 degrees left of the base's forward axis as a mount yaw of 4.0 degrees places it: the radar " \
        "is likely yawed 0.0 degrees on the base" in caplog.text
    # A lean (4 cm/s) is now taken out along the learnt axis, not along the mount's; the median
    # learns nothing from it; reversing, the same axis.
    for vx in (0.6, -0.6):
        out = part(_est(vx, 0.04, t=20), yaw_rate=0.0)
        assert out.velocity == pytest.approx([vx, 0.0], abs=1e-12)


def test_the_heatmaps_doppler_standing_in_for_the_clouds_does_not_slide_either():
    # No point cloud's velocity: the step's comes from the heatmap's Doppler (velocity_fallback),
    # which passes through the same constraint as the clouds' (here the mount's axis as given).
    part = _slip(axis_learn_frames=0)
    track = VelocityTrack(EstimatorConfig(), lambda est: part(est, 0.0))
    flags = []
    step = track.for_step(0.9, 1.0, synth.scene_heatmap(velocity_xy=(0.8, 0.05)), flags)
    assert Flag.VELOCITY_FROM_HEATMAP in flags
    assert step.velocity[0] == pytest.approx(0.8, rel=0.05) and step.velocity[1] == 0.0
    free = VelocityTrack(EstimatorConfig()).for_step(0.9, 1.0, synth.scene_heatmap(velocity_xy=(0.8, 0.05)), [])
    assert free.velocity[1] > 0.02  # without it, the sideways part its fit found


@pytest.mark.parametrize("learn", [20, 0], ids=["learnt", "as given"])
def test_a_mounts_yaw_given_wrongly_is_learnt_before_the_doppler_measures_turns(learn):
    # The radar 0.3 m ahead looks straight along the base, the mount says 5 degrees to the left:
    # 0.6 m/s x sin(5 degrees) over the lever arm would read as 10 deg/s of turn. Three seconds
    # straight (learning), then a moving turn over a heatmap that holds nothing (the Doppler alone).
    phases = [(0.5, 0.0, 0.0), (3.0, 0.6, 0.0), (3.0, 0.6, math.radians(-30.0)), (0.5, 0.6, 0.0)]
    config = _wheeled(axis_learn_frames=learn, mount_yaw_rad=math.radians(5.0))
    states, true_turn = _run(config, phases, blank=True)
    if learn:
        assert states[-1].yaw == pytest.approx(true_turn, rel=0.04)
    else:
        assert abs(states[-1].yaw - true_turn) > 0.15 * abs(true_turn)


def test_fused_with_the_registration_the_turn_is_measured():
    states, true_turn = _run(_wheeled(), SPIN)
    assert states[-1].yaw == pytest.approx(true_turn, rel=0.02)
    assert not any("no_structure" in s.flags for s in states[1:])


def test_the_yaw_rate_is_the_sideways_velocity_over_the_lever_arm_and_fusion_weights_by_variance():
    part = DopplerYawRate(EstimatorConfig().odometry.__class__(base="wheeled", mount_x_m=0.5, axis_learn_frames=0,
                                                               doppler_yaw_rate_noise_radps=1e-3))
    rate, var = part(np.array([0.3, 0.2]), np.diag([1e-4, 4e-4]), True)
    assert rate == pytest.approx(0.4) and var == pytest.approx(4e-4 / 0.25)
    # Below doppler_yaw_min_rate_radps it stands in only for a registration that measured nothing.
    assert part(np.array([0.3, 0.05]), np.diag([1e-4, 4e-4]), True) is None
    assert part(np.array([0.3, 0.05]), np.diag([1e-4, 4e-4]), False)[0] == pytest.approx(0.1)
    assert fuse(0.1, 1.0, (2.0, 1.0), 0.1) == pytest.approx(((0.1 + 0.2 / 0.01) / (1 + 100), 1 / 101))
    assert fuse(None, 1.0, (2.0, 1.0), 0.1) == pytest.approx((0.2, 0.01))
    assert fuse(0.1, 1.0, None, 0.1) == (0.1, 1.0)


@pytest.mark.parametrize("field, value", [("base", "omni"), ("mount_x_m", float("nan")), ("min_lever_arm_m", 0.0)])
def test_bad_settings_are_refused_naming_the_field(field, value):
    with pytest.raises(ConfigError, match=field):
        EstimatorConfig().with_(odometry={field: value})


def test_through_a_blank_run_the_last_keyframe_with_structure_stays_and_its_doubt_grows():
    # An arc with structure, then frames 12-29 blank (a covered radome: the Doppler alone
    # measures them), then structure again.
    traj = synth.Trajectory(ARC)
    world, amp = synth.scene(traj, 120, seed=3, separation_m=1.0)
    rng = np.random.default_rng(3)
    odom = RadarOdometry(_wheeled())
    blank = range(12, 30)
    keys = []  # per frame: the keyframe's frame index and its yaw variance, rad^2
    for k in range(int(round(traj.duration / DT)) + 1):
        t = k * DT
        v, _, w = traj.twist(t)
        cloud, hm = synth.frame(world, amp, _radar_pose(traj.pose(t)), _radar_velocity(v, w), rng)
        state = odom.step(t, cloud, _blank_heatmap(rng) if k in blank else hm)
        # The step out of the run (its first frame blank) measures nothing either.
        assert ("no_structure" in state.flags) == (blank.start <= k <= blank.stop)
        key = odom.keyframes.key
        keys.append((round(key.frame.t / DT), key.yaw_var))
    assert not any(frame in blank for frame, _ in keys)  # a blank frame never becomes the keyframe
    during = keys[blank.start:blank.stop + 1]
    assert len({frame for frame, _ in during}) == 1  # the last one before the run stays
    assert all(later > earlier for (_, earlier), (_, later) in zip(during, during[1:]))
    assert keys[-1][0] >= blank.stop  # and a frame with structure takes over after it
