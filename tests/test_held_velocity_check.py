"""A held velocity's translation checked against none (``odometry.held_velocity_yaw_check``,
estimator/yaw_measurement.py): on a step whose velocity is held, the rotation measured without
the translation widens the measurement's variance, so that a robot braking while its velocity
goes unmeasured does not turn its heading to make up for features moved too far."""

from __future__ import annotations

import math

import estimator_synth as synth
import numpy as np
import pytest
from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.odometry import RadarOdometry
from radarodom.estimator.quality import Flag
from radarodom.estimator.yaw_measurement import CurrentFrame, YawMeasurement

DEG = math.radians(1.0)
#: Reflectors 0.6-0.8 m to the left of a straight path, every 0.35 m: near enough that a
#: translation 0.2 m too long moves their bearings by degrees.
WALL = np.array([(x, 0.6 + 0.2 * (k % 2)) for k, x in enumerate(np.arange(0.0, 8.0, 0.35))])


def config(check: float | None) -> EstimatorConfig:
    return EstimatorConfig().with_(odometry={"held_velocity_yaw_check": check})


def measure(check: float | None, translation, *, held: bool):
    """The rotation between two frames seen from the same place, the first moved by *translation*."""
    cfg = config(check)
    yaw = YawMeasurement(cfg, math.radians(0.25))
    frames = [CurrentFrame(0.1 * i, synth.scene_heatmap((1.0, 0.0, 0.0), WALL), cfg) for i in range(2)]
    kept = [yaw.keep(f, np.zeros(2)) for f in frames]
    flags: list[Flag] = []
    step = yaw.measure(kept[0], kept[1], frames[1], np.asarray(translation, float), 0.0, flags,
                       translation_held=held)
    # The scan's usual scores take the step's first look only (icp.scan_score_fraction).
    assert len(yaw.guess._scores) == 1
    return step, flags


def test_a_held_steps_variance_widens_by_the_rotation_measured_without_its_translation():
    plain, plain_flags = measure(1.0, (0.2, 0.0), held=False)
    unmoved, _ = measure(1.0, (0.0, 0.0), held=False)
    difference = unmoved.rotation - plain.rotation
    assert abs(difference) > 0.5 * DEG  # the wrong translation turns the measurement
    for check in (1.0, 2.0):
        held, flags = measure(check, (0.2, 0.0), held=True)
        assert held.rotation == plain.rotation  # the measurement itself unchanged
        assert held.variance == pytest.approx(plain.variance + (check * difference) ** 2, rel=1e-9)
        assert flags == plain_flags  # the second measurement flags nothing
    # Off, or a measured velocity: as before.
    for check, held_flag in ((None, True), (1.0, False)):
        step, _ = measure(check, (0.2, 0.0), held=held_flag)
        assert (step.rotation, step.variance) == (plain.rotation, plain.variance)


def run(check: float | None):
    """Driving at 2 m/s past the wall, then standing while three frames' velocity goes
    unmeasured (no points, no Doppler), so that 2 m/s is held; the heading is 0 throughout."""
    odom = RadarOdometry(config(check))
    states = []
    for i in range(18):
        speed = 2.0 if i < 12 else 0.0
        weak = 12 <= i < 15
        cloud = synth.static_cloud((speed, 0.0), n=0 if weak else 40, seed=i)
        pose = (0.2 * min(i, 11), 0.0, 0.0)
        hm = synth.scene_heatmap(pose, WALL, velocity_xy=(speed, 0.0), doppler_channel=not weak)
        states.append(odom.step(0.1 * i, cloud, hm))
    return states


def test_in_the_odometry_only_held_steps_change_and_the_heading_turns_less():
    checked, unchecked = run(1.0), run(None)
    held = [Flag.VELOCITY_HELD in s.flags for s in checked]
    assert held == [False] * 12 + [True] * 3 + [False] * 3
    assert [Flag.VELOCITY_HELD in s.flags for s in unchecked] == held
    for a, b in zip(checked[:12], unchecked[:12]):
        assert (a.yaw, a.x, a.y) == (b.yaw, b.x, b.y)
    # The truth does not turn: each held step's heading is nearer it with the check.
    for a, b in zip(checked[12:15], unchecked[12:15]):
        assert abs(a.yaw) < abs(b.yaw)


@pytest.mark.parametrize("bad", [0.0, -1.0, math.inf])
def test_the_factor_is_checked(bad):
    with pytest.raises(ConfigError) as exc:
        EstimatorConfig.from_dict({"odometry": {"held_velocity_yaw_check": bad}})
    assert exc.value.field == "odometry.held_velocity_yaw_check"
    off = EstimatorConfig.from_dict({"odometry": {"held_velocity_yaw_check": None}})
    assert off.odometry.held_velocity_yaw_check is None
