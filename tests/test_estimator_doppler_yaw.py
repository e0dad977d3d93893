"""The Doppler yaw rate of a radar mounted off a wheeled base's rotation axis (issue 20, beyond
the paper: Kellner et al. 2014): with odometry.base "wheeled" and the mounting, the sideways part
of the radar's Doppler velocity measures the yaw rate, fused with the heatmap registration and
standing in for it when the registration fails; on the axis the radar does not slide sideways."""

from __future__ import annotations

import math

import estimator_synth as synth
import numpy as np
import pytest

from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.doppler_yaw import DopplerYawRate, NoSideSlip, fuse
from radarodom.estimator.odometry import RadarOdometry
from radarodom.estimator.velocity import FEW_POINTS, OK, VelocityEstimate
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
    # does): the velocity's acceleration check (velocity.max_accel_mps2) would refuse it.
    return EstimatorConfig().with_(odometry={"base": "wheeled", "mount_x_m": mount[0], "mount_y_m": mount[1],
                                             "mount_yaw_rad": mount[2], **odometry},
                                   velocity={"max_accel_mps2": None})


SPIN = [(0.5, 0.0, 0.0), (4.0, 0.0, math.radians(45.0)), (0.5, 0.0, 0.0)]
ARC = [(0.5, 0.0, 0.0), (1.0, 0.6, 0.0), (3.0, 0.6, math.radians(-30.0)), (1.0, 0.6, 0.0)]


@pytest.mark.parametrize("phases, mount", [
    (SPIN, (LEVER, 0.0, 0.0)), (ARC, (LEVER, 0.0, 0.0)), (ARC, (-0.25, 0.1, 0.0)),
    # Yawed on the base, the radar's forward speed leaks into the base's sideways axis: a
    # 1 % speed error is some 2 % of this moving turn's rate, so the yawed mount turns in place.
    (SPIN, (-0.25, 0.1, math.radians(20.0)))],
    ids=["in place, ahead", "moving, ahead", "moving, behind", "in place, behind and yawed"])
def test_the_doppler_alone_measures_the_turn_when_the_heatmap_holds_nothing(phases, mount):
    states, true_turn = _run(_wheeled(mount), phases, blank=True, mount=mount)
    assert all("no_structure" in s.flags for s in states[1:])  # the registration measured nothing
    # In a moving turn the fit's sideways speed runs long (docs/heading.md, the mounted radar's
    # moving turns): 2 % in place, 4 % moving.
    assert states[-1].yaw == pytest.approx(true_turn, rel=0.02 if phases is SPIN else 0.04)


@pytest.mark.parametrize("phases", [SPIN, ARC], ids=["in place", "moving"])
def test_a_frame_the_doppler_alone_measured_is_not_corrected_against_the_keyframe(phases):
    # The keyframe's registration against a heatmap of noise measures noise: the yaw is the
    # Doppler's, as without keyframes, to the last bit.
    with_keyframes, _ = _run(_wheeled(), phases, blank=True)
    without, _ = _run(_wheeled(keyframe_distance_m=0.0), phases, blank=True)
    assert [s.yaw for s in with_keyframes] == [s.yaw for s in without]


def test_without_a_wheeled_base_the_doppler_says_nothing_of_the_yaw():
    states, true_turn = _run(EstimatorConfig().with_(odometry={"mount_x_m": LEVER}), SPIN, blank=True)
    assert abs(states[-1].yaw) < 0.2 * abs(true_turn)  # the held rate stops after hold_s


def test_a_radar_on_the_axis_uses_no_doppler_yaw_rate():
    states, true_turn = _run(_wheeled((0.0, 0.0, 0.0)), SPIN, blank=True, mount=(0.0, 0.0, 0.0))
    assert abs(states[-1].yaw) < 0.2 * abs(true_turn)


def test_on_the_axis_a_fit_leaning_sideways_does_not_move_the_radar_sideways():
    # The point clouds say 4 cm/s to the left (a fit leaning with elevated returns, as a 2-TX
    # array's does) while the radar drives straight ahead at 0.6 m/s for 3 s.
    traj = synth.Trajectory([(0.5, 0.0, 0.0), (3.0, 0.6, 0.0)])
    world, amp = synth.scene(traj, 120, seed=3, separation_m=1.0)
    ends = {}
    for base in ("wheeled", "any"):
        rng = np.random.default_rng(3)
        odom = RadarOdometry(_wheeled((0.0, 0.0, 0.0)).with_(odometry={"base": base}))
        for k in range(int(round(traj.duration / DT)) + 1):
            t = k * DT
            v, _, _ = traj.twist(t)
            cloud, _ = synth.frame(world, amp, traj.pose(t), (v, 0.04 if v else 0.0), rng)
            _, heatmap = synth.frame(world, amp, traj.pose(t), (v, 0.0), rng)
            state = odom.step(t, cloud, heatmap)
        ends[base] = state
    assert ends["wheeled"].vy == 0.0 and abs(ends["wheeled"].y) < 0.02
    assert ends["any"].vy == pytest.approx(0.04, abs=0.01) and ends["any"].y > 0.08
    assert ends["wheeled"].x == pytest.approx(ends["any"].x, rel=0.02)


def test_no_sideways_slip_keeps_the_forward_part_along_the_bases_axes():
    make = EstimatorConfig().odometry.__class__
    est = VelocityEstimate(t=1.0, vx=0.5, vy=0.05, covariance=np.diag([1e-4, 4e-4]), status=OK)
    on_axis = NoSideSlip(make(base="wheeled"))(est, yaw_rate=0.5)
    assert (on_axis.vx, on_axis.vy) == (0.5, 0.0) and on_axis.t == 1.0
    np.testing.assert_array_equal(on_axis.covariance, np.diag([1e-4, 0.0]))
    # Yawed 90 degrees on the base (looking left), 3 cm ahead of the axis: the radar's x is the
    # base's sideways axis (yaw rate x lever arm), its -y the base's forward.
    yawed = NoSideSlip(make(base="wheeled", mount_x_m=0.03, mount_yaw_rad=math.pi / 2))(est, yaw_rate=0.5)
    assert (yawed.vx, yawed.vy) == pytest.approx((0.015, 0.05))
    np.testing.assert_allclose(yawed.covariance, np.diag([0.0, 4e-4]), atol=1e-12)
    failed = VelocityEstimate(t=1.0, vx=0.5, vy=0.05, status=FEW_POINTS)
    assert NoSideSlip(make(base="wheeled"))(failed, 0.0) is failed  # not measured: nothing to constrain


def test_fused_with_the_registration_the_turn_is_measured():
    states, true_turn = _run(_wheeled(), SPIN)
    assert states[-1].yaw == pytest.approx(true_turn, rel=0.02)
    assert not any("no_structure" in s.flags for s in states[1:])


def test_the_yaw_rate_is_the_sideways_velocity_over_the_lever_arm_and_fusion_weights_by_variance():
    part = DopplerYawRate(EstimatorConfig().odometry.__class__(base="wheeled", mount_x_m=0.5,
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
