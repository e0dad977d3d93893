"""A run of frames that see nothing, bridged (``odometry.bridge_s``, estimator/odometry.py;
docs/estimator.md, "Frames lost").

A radar blinded for a moment (covered, or a person right in front of it: no heatmap structure
and no point cloud to fit a velocity to) used to register each frame against the blind one
before it: the turn made while blind was held for ``hold_s`` and then lost.  Within ``bridge_s``
the next frame that sees the scene is registered against the last one that did, across the run,
like frames lost on the link.  Weak frames whose point cloud still gives a velocity are not
bridged (at -15 dB a second look across them found false turns).
"""

from __future__ import annotations

import math

import estimator_synth as synth
import numpy as np
import pytest
from estimator_synth import blind_heatmap, points_polar, scene_heatmap, static_cloud
from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.odometry import RadarOdometry
from radarodom.estimator.quality import Flag

DEG = math.radians(1.0)
RATE = 20 * DEG  # rad/s


def noise_heatmap(rng):
    return synth.heatmap(np.zeros((0, 2)), noise=1.0, rng=rng)


def no_cloud():
    """No detections: no velocity."""
    return points_polar(np.zeros(0), 0.0, (0.0, 0.0))


def run(bridge_s: float, blind_frames: range, kind: str, n: int = 20, cloud_when_blind: bool = False):
    """Turning in place at 20 deg/s for *n* frames at 10 Hz, blind during *blind_frames* (the
    point cloud too, unless *cloud_when_blind*)."""
    rng = np.random.default_rng(1)
    odom = RadarOdometry(synth.heatmap_chain(odometry={"bridge_s": bridge_s}))
    states = []
    for i in range(n):
        t = 0.1 * i
        cloud = static_cloud((0.0, 0.0), seed=i)
        if i in blind_frames:
            hm = noise_heatmap(rng) if kind == "noise" else blind_heatmap()
            cloud = cloud if cloud_when_blind else no_cloud()
        else:
            hm = scene_heatmap((0.0, 0.0, RATE * t))
        states.append(odom.step(t, cloud, hm))
    return states


@pytest.mark.parametrize("kind", ["noise", "blind"])
def test_a_turn_made_while_blind_is_measured_across_the_run(kind):
    blind = range(5, 13)  # 0.8 s, longer than hold_s
    states = run(1.0, blind, kind)
    assert [s.frame for s in states] == list(range(20))
    for s in states[5:13]:
        assert Flag.NO_STRUCTURE in s.flags or Flag.FEW_FEATURES in s.flags
        assert Flag.VELOCITY_FAILED in s.flags
    first = states[13]
    assert first.ok, first.flags
    assert first.yaw == pytest.approx(RATE * first.t, abs=1.0 * DEG)
    assert states[-1].yaw == pytest.approx(RATE * states[-1].t, abs=1.0 * DEG)
    # The increments add up to the yaw, over the run and across it.
    assert sum(s.yaw_increment for s in states) == pytest.approx(states[-1].yaw, abs=1e-9)
    for s in states:
        assert all(math.isfinite(v) for v in (s.x, s.y, s.yaw, s.yaw_rate, s.yaw_increment))


@pytest.mark.parametrize("kind", ["noise", "blind"])
@pytest.mark.parametrize("bridge_s, cloud_when_blind", [(0.0, False), (1.0, True)], ids=["off", "cloud_seen"])
def test_without_the_bridge_the_turn_made_blind_after_hold_s_is_lost(kind, bridge_s, cloud_when_blind):
    # Off, or the frames' point clouds still fit a velocity (they saw the world): held for
    # hold_s (0.5 s) of the 0.8 s, then nothing: some 6 degrees short ever after.
    states = run(bridge_s, range(5, 13), kind, cloud_when_blind=cloud_when_blind)
    assert RATE * states[-1].t - states[-1].yaw > 4 * DEG


def test_while_blind_the_states_hold_the_last_motion_and_never_step_back():
    states = run(1.0, range(5, 13), "noise")
    yaws = [s.yaw for s in states[4:13]]
    assert all(b >= a - 1e-12 for a, b in zip(yaws, yaws[1:]))
    held = [s for s in states[5:13] if Flag.YAW_HELD in s.flags]
    lost = [s for s in states[5:13] if Flag.MOTION_LOST in s.flags]
    assert held and lost and held[-1].t < lost[0].t  # held for hold_s, then none
    for s in lost:
        assert s.yaw_rate == 0.0 and s.yaw_increment == 0.0


def test_a_run_longer_than_the_bridge_starts_afresh():
    # Blind for 1.5 s: beyond bridge_s the blind frame becomes the one registered against (as
    # without the bridge), so the first frame after the run holds no structure, and the next
    # ones are measured frame to frame again.
    states = run(1.0, range(5, 20), "noise", n=26)
    after = states[20:]
    assert Flag.NO_STRUCTURE in after[0].flags
    assert all(s.ok for s in after[1:])
    for prev, s in zip(after[1:], after[2:]):
        assert s.yaw - prev.yaw == pytest.approx(RATE * 0.1, abs=0.5 * DEG)


@pytest.mark.parametrize("value", [-0.1, math.inf, math.nan])
def test_the_bridge_must_be_a_finite_time(value):
    with pytest.raises(ConfigError, match="bridge_s"):
        EstimatorConfig().with_(odometry={"bridge_s": value})


def test_a_standing_radar_blinded_stays_put():
    odom = RadarOdometry(synth.heatmap_chain())
    rng = np.random.default_rng(2)
    states = [odom.step(0.1 * i, no_cloud() if 5 <= i < 17 else static_cloud((0.0, 0.0), seed=i),
                        noise_heatmap(rng) if 5 <= i < 17 else scene_heatmap()) for i in range(22)]
    assert states[17].ok, states[17].flags
    for s in states:
        assert abs(s.yaw) < 0.2 * DEG and abs(s.x) < 0.01 and abs(s.y) < 0.01


def drive(blind: set[int], *, cloud_back: bool = True, n: int = 24, speed: float = 0.5, **odometry):
    """Driving straight at *speed* m/s past the scene for *n* frames at 10 Hz, blind (heatmap and
    cloud) at the frames in *blind*; the first frame after each run without a point cloud unless
    *cloud_back*; *odometry*: settings."""
    rng = np.random.default_rng(4)
    odom = RadarOdometry(synth.heatmap_chain(odometry=odometry))
    states = []
    for i in range(n):
        t = 0.1 * i
        back = i not in blind and (i - 1) in blind
        cloud = no_cloud() if i in blind or (back and not cloud_back) else static_cloud((speed, 0.0), seed=i)
        hm = noise_heatmap(rng) if i in blind else scene_heatmap((speed * t, 0.0, 0.0), velocity_xy=(speed, 0.0))
        states.append(odom.step(t, cloud, hm))
    return states


def test_driving_blind_the_distance_comes_back_across_the_run():
    # Held for hold_s, then no motion while blind: the distance of the rest of the run is what
    # the step across it restores.
    states = drive(set(range(5, 14)))
    assert states[13].x < 0.5 * 1.25  # the run's states fell behind
    first = states[14]
    assert first.ok, first.flags
    assert first.x == pytest.approx(0.5 * first.t, abs=0.03)
    assert states[-1].x == pytest.approx(0.5 * states[-1].t, abs=0.05)
    assert abs(states[-1].yaw) < 0.5 * DEG


def test_a_first_frame_back_without_its_point_cloud_is_not_bridged():
    # Its velocity would be none (no heatmap fallback either): the step across the run would move
    # the pose back to the last measured frame's. Such a frame is measured from the one before
    # it, as without the bridge.
    states = drive(set(range(5, 14)), cloud_back=False, velocity_fallback="hold")
    assert Flag.VELOCITY_FAILED in states[14].flags
    assert states[14].x >= states[13].x - 1e-9


def test_two_runs_one_seeing_frame_apart_are_each_bridged():
    # The step across the first run makes its frame the one the second run is bridged from.
    states = run(2.0, set(range(5, 10)) | set(range(11, 16)), "noise", n=22)
    for i in (10, 16):
        assert states[i].ok, (i, states[i].flags)
        assert states[i].yaw == pytest.approx(RATE * states[i].t, abs=1.0 * DEG)


def _jump(gap_s: float, **odometry):
    """Driving straight at 0.5 m/s, frames 10 and on *gap_s* s later than their place (frames lost,
    or a clock that jumped), the scene going on where it was."""
    odom = RadarOdometry(synth.heatmap_chain(odometry=odometry))
    states = []
    for i in range(16):
        t = 0.1 * i + (gap_s if i >= 10 else 0.0)
        hm = scene_heatmap((0.05 * i, 0.0, 0.0), velocity_xy=(0.5, 0.0))
        states.append(odom.step(t, static_cloud((0.5, 0.0), seed=i), hm))
    return states


@pytest.mark.parametrize("gap_s", [30.0, 1.7e9])
def test_a_step_longer_than_max_step_s_moves_the_pose_by_nothing(gap_s):
    """Integrated, the velocities at its ends moved the pose by v x gap (a clock that jumped by
    years: billions of metres) and the rate filter turned it by millions of radians."""
    states = _jump(gap_s)
    before, across = states[9], states[10]
    assert (across.x, across.y, across.yaw) == (before.x, before.y, before.yaw)
    assert Flag.MOTION_LOST in across.flags and across.yaw_rate == 0.0 and across.vx == 0.0
    assert np.isfinite(across.pose_covariance).all() and across.pose_covariance[0, 0] > before.pose_covariance[0, 0]
    # The odometry goes on from there, at the speed it measures.
    assert states[-1].x - across.x == pytest.approx(0.5 * 0.5, abs=0.03) and abs(states[-1].yaw) < 0.5 * DEG


@pytest.mark.parametrize("hold_s", [0.5, 3600.0])
def test_a_step_longer_than_max_step_s_turns_the_pose_by_nothing_whatever_the_hold(hold_s):
    """Turning in place at 20 deg/s, then 30 s lost: with the rate allowed to stand in for an hour
    (hold_s 3600) the held rate times the gap turned the pose by 600 degrees."""
    rate = math.radians(20.0)
    odom = RadarOdometry(synth.heatmap_chain(odometry={"hold_s": hold_s}))
    states = [odom.step(0.1 * i + (30.0 if i >= 10 else 0.0), static_cloud((0.0, 0.0), seed=i),
                        scene_heatmap((0.0, 0.0, rate * 0.1 * i))) for i in range(12)]
    before, across = states[9], states[10]
    assert abs(before.yaw) > math.radians(10.0)  # it was turning, and the rate was measured
    assert across.yaw == before.yaw and across.yaw_rate == 0.0 and Flag.MOTION_LOST in across.flags


def test_a_step_within_max_step_s_moves_by_the_velocity_at_its_ends():
    """Frames lost for 5 s: the step goes on at the velocity measured either side (as before)."""
    states = _jump(5.0)
    assert states[10].x - states[9].x == pytest.approx(0.5 * 5.1, abs=0.05)
    states = _jump(5.0, max_step_s=4.0)
    assert states[10].x == states[9].x and Flag.MOTION_LOST in states[10].flags
