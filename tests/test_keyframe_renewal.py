"""The keyframe taken in a turn, renewed when the turn ends (``odometry.keyframe_turn_renew_radps``,
estimator/keyframe.py): the rule on its own, then in the streaming odometry on a synthetic turn in
place followed by a stop (tests/estimator_synth.py)."""

from __future__ import annotations

import math

import estimator_synth as synth
import pytest
from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.odometry import RadarOdometry
from radarodom.estimator.yaw_measurement import CurrentFrame

DEG = math.radians(1.0)


def heatmap(yaw: float):
    return synth.scene_heatmap((0.0, 0.0, yaw))


def odometry(renew_degps: float | None) -> RadarOdometry:
    renew = None if renew_degps is None else renew_degps * DEG
    return RadarOdometry(synth.heatmap_chain(odometry={"keyframe_turn_renew_radps": renew}))


def kept(odom: RadarOdometry, t: float):
    return odom.yaw.keep(CurrentFrame(t, heatmap(0.0), odom.config), None)


@pytest.mark.parametrize("renew_degps", [30.0, None])
def test_a_keyframe_taken_in_a_turn_is_renewed_when_the_step_turns_less_than_half_as_fast(renew_degps):
    odom = odometry(renew_degps)
    keys = odom.keyframes
    frames = [kept(odom, 0.1 * i) for i in range(5)]
    keys.update((0.0, 0.0, 0.0), frames[0], measured=True, rate=40 * DEG)  # the first: taken in the turn
    first = keys.key
    assert first.frame is frames[0] and first.in_turn == (renew_degps is not None)
    # Slower but not yet below half the threshold (15 deg/s), and near: kept.
    keys.update((0.0, 0.0, 2 * DEG), frames[1], measured=True, rate=-20 * DEG)
    assert keys.key is first
    # Below half: renewed with the option, kept without (0.5 m and 10 degrees not reached).
    keys.update((0.0, 0.0, 3 * DEG), frames[2], measured=True, rate=10 * DEG)
    if renew_degps is None:
        assert keys.key is first
        return
    assert keys.key.frame is frames[2] and not keys.key.in_turn
    # A keyframe taken out of a turn is renewed by distance and angle alone, as before.
    renewed = keys.key
    keys.update((0.0, 0.0, 4 * DEG), frames[3], measured=True, rate=0.0)
    assert keys.key is renewed
    keys.update((0.0, 0.0, 14 * DEG), frames[4], measured=True, rate=0.0)
    assert keys.key.frame is frames[4]


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_keyframe_is_in_a_turn_by_its_own_steps_rate_either_way(sign):
    odom = odometry(30.0)
    keys = odom.keyframes
    frames = [kept(odom, 0.1 * i) for i in range(6)]
    keys.update((0.0, 0.0, 0.0), frames[0], measured=True, rate=sign * 20 * DEG)  # between half and all of it
    assert not keys.key.in_turn
    keys.update((0.0, 0.0, sign * 12 * DEG), frames[1], measured=True, rate=sign * 40 * DEG)  # renewed by angle
    assert keys.key.frame is frames[1] and keys.key.in_turn
    # Renewed by angle again while the turn slows (20 deg/s): by its own rate, not in the turn
    # (counted in it, as the one before, did worse on the robustness matrix: docs/heading.md) ...
    keys.update((0.0, 0.0, sign * 24 * DEG), frames[2], measured=True, rate=sign * 20 * DEG)
    assert keys.key.frame is frames[2] and not keys.key.in_turn
    # ... so it stays when the turn ends.
    keys.update((0.0, 0.0, sign * 25 * DEG), frames[3], measured=True, rate=sign * 5 * DEG)
    assert keys.key.frame is frames[2]
    keys.update((0.0, 0.0, sign * 36 * DEG), frames[3], measured=True, rate=sign * 5 * DEG)  # by angle
    assert keys.key.frame is frames[3] and not keys.key.in_turn
    # An unmeasured frame (the chain broke) is always the new keyframe; in a turn only by its own rate.
    keys.update((0.0, 0.0, sign * 26 * DEG), frames[4], measured=True, rate=sign * 40 * DEG)
    assert keys.key.frame is frames[3]
    keys.update((0.0, 0.0, sign * 27 * DEG), frames[5], measured=False, rate=sign * 20 * DEG)
    assert keys.key.frame is frames[5] and not keys.key.in_turn


def test_in_the_odometry_the_heading_holds_after_a_turn_in_place():
    # A turn in place at 60 deg/s for 1 s, then 1.5 s standing.  Without the option the last keyframe
    # the turn took, whose pose lags it, stays (the rest is within 10 degrees of it) and the keyframe
    # corrections pull the heading back towards it after the stop; with it, the first frame whose
    # step turns less than 15 deg/s becomes the keyframe and the heading stays where the turn ended.
    dt, turn = 0.1, 60 * DEG
    yaws = [turn * min(i * dt, 1.0) for i in range(26)]
    runs = {}
    for renew in (30.0, None):
        odom = odometry(renew)
        states = [odom.step(i * dt, synth.static_cloud((0.0, 0.0)), heatmap(yaw)) for i, yaw in enumerate(yaws)]
        runs[renew] = odom, states
    odom, states = runs[30.0]
    ended = next(s for s in states if s.t > 1.0 and abs(s.yaw_rate) < 15 * DEG)
    assert odom.keyframes.key.frame.t == pytest.approx(ended.t) and not odom.keyframes.key.in_turn
    assert abs(states[-1].yaw - ended.yaw) < 0.15 * DEG
    odom, states = runs[None]
    assert odom.keyframes.key.frame.t <= 1.0 + 1e-9
    assert states[-1].yaw < ended.yaw - 0.2 * DEG  # slid back, further from the true 60 degrees


def test_the_threshold_is_checked():
    with pytest.raises(ConfigError) as exc:
        EstimatorConfig.from_dict({"odometry": {"keyframe_turn_renew_radps": 0.0}})
    assert exc.value.field == "odometry.keyframe_turn_renew_radps"
