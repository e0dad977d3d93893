"""Near points left out of the scan in a moving turn (``icp.moving_turn_min_range_m``,
estimator/yaw_measurement.py; docs/heading.md item 18).

While the radar drives through a turn near walls, the cells within a metre are mostly the
walls', which do not move as the fixed reflectors the registration moves them as: the scan's
points (which the field search scores too) nearer than the option are left out then, and only
then: driving straight, turning in place, or facing a close obstacle that holds most of the
points' weight, they stay.  ICP's features keep them.
"""

from __future__ import annotations

import math

import estimator_synth as synth
import numpy as np
import pytest
from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig, IcpConfig
from radarodom.estimator.features import Features
from radarodom.estimator.yaw_measurement import CurrentFrame, YawMeasurement, far_in_moving_turn

DT = 0.1
TURN = math.radians(45.0) * DT  # 45 deg/s
DRIVING = np.array([0.8, 0.0])
#: Reflectors 0.6-0.9 m away on both sides and ahead, and others 3-8 m away.
NEAR = np.array([(0.6, 0.3), (0.7, -0.4), (0.5, 0.6), (0.8, 0.0), (0.4, -0.7)])
FAR = np.array([(r * math.cos(b), r * math.sin(b)) for r, b in
                zip((3.0, 5.0, 7.0, 4.0, 8.0, 6.0, 3.5, 5.5), np.radians((-45, -30, -15, 0, 10, 25, 40, 50)))])


def keep(velocity, turn_rad: float, dt: float | None = DT, *, near_amplitude: float = 1.0,
         option: float | None = 1.0, far: np.ndarray = FAR):
    cfg = EstimatorConfig().with_(icp={"moving_turn_min_range_m": option})
    yaw = YawMeasurement(cfg, math.radians(0.25))
    world = np.vstack([NEAR, far])
    amplitude = np.concatenate([np.full(len(NEAR), near_amplitude), np.ones(len(far))])
    v = (0.0, 0.0) if velocity is None else tuple(velocity)
    frame = CurrentFrame(0.0, synth.heatmap(world, amplitude, velocity_xy=v), cfg)
    return yaw.keep(frame, None if velocity is None else np.asarray(velocity, float), turn_rad=turn_rad, dt=dt)


def near_weight(points) -> float:
    return float(points.weight[points.range_m < 1.0].sum())


def test_in_a_moving_turn_the_scan_leaves_the_near_points_out():
    kept = keep(DRIVING, TURN)
    assert len(kept.guide) >= 3 and kept.guide.range_m.min() >= 1.0
    assert math.isclose(kept.guide.weight.sum(), 1.0)
    # The field search scores the same points (weighed by their peaks' shape, item 22).
    np.testing.assert_array_equal(kept.field.points.range_m, kept.guide.range_m)
    np.testing.assert_array_equal(kept.field.points.bearing_rad, kept.guide.bearing_rad)
    assert np.any(kept.features.range_m < 1.0)  # ICP's features keep them
    # Turning the other way, or backing through the turn: the same.
    for velocity, turn in ((DRIVING, -TURN), (-DRIVING, TURN)):
        assert keep(velocity, turn).guide.range_m.min() >= 1.0


@pytest.mark.parametrize("velocity, turn, dt", [
    (DRIVING, 0.0, DT),                          # driving straight
    (DRIVING, math.radians(5.0) * DT, DT),       # a gentle curve, under 10 deg/s
    (np.zeros(2), TURN, DT),                     # turning in place
    (np.array([0.15, 0.0]), TURN, DT),           # crawling, under 0.2 m/s
    (None, TURN, DT),                            # the frame's velocity unknown
    (DRIVING, TURN, None),                       # the first frame
])
def test_otherwise_the_near_points_stay(velocity, turn, dt):
    kept = keep(velocity, turn, dt)
    assert near_weight(kept.guide) > 0.05


def test_a_close_obstacle_holding_most_of_the_weight_stays():
    # Few, faint reflectors beyond it: the near cells are what the turn is measured by.
    kept = keep(DRIVING, TURN, near_amplitude=1e4, far=FAR[:2])
    assert near_weight(kept.guide) > 0.5


def test_off_the_near_points_stay():
    assert near_weight(keep(DRIVING, TURN, option=None).guide) > 0.05


@pytest.mark.parametrize("value", [0.0, -1.0, math.inf, math.nan])
def test_the_option_must_be_a_positive_finite_range(value):
    with pytest.raises(ConfigError, match="moving_turn_min_range_m"):
        EstimatorConfig().with_(icp={"moving_turn_min_range_m": value})


# --------------------------------------------------------------- the rule itself, on given points
def points(near_weight: float, n_far: int = 3, *, near_height: float = 0.0) -> Features:
    """Three points 0.9 m away (horizontally; at *near_height*) holding *near_weight*, *n_far*
    points 3 m away holding the rest."""
    n = 3 + n_far
    weight = np.concatenate([np.full(3, near_weight / 3), np.full(n_far, (1 - near_weight) / n_far)])
    height = np.concatenate([np.full(3, near_height), np.zeros(n_far)])
    return Features(np.array([0.9] * 3 + [3.0] * n_far), np.linspace(-0.5, 0.5, n), weight, weight.copy(), height)


def cut(p: Features, velocity=(0.8, 0.0), turn=TURN, dt: float | None = DT) -> bool:
    out = far_in_moving_turn(p, 1.0, None if velocity is None else np.asarray(velocity, float), turn, dt)
    if out is p:
        return False
    assert out.range_m.min() >= 1.0 and np.count_nonzero(out.range_m >= 1.0) == np.count_nonzero(p.range_m >= 1.0)
    np.testing.assert_allclose(out.weight, p.weight[p.range_m >= 1.0] / p.weight[p.range_m >= 1.0].sum())
    return True


def test_the_near_points_go_while_they_hold_at_most_half_the_weight():
    assert cut(points(0.2)) and cut(points(0.49)) and cut(points(0.5))
    assert not cut(points(0.51)) and not cut(points(0.9))


def test_the_range_is_the_horizontal_one():
    # 0.9 m away horizontally, 0.6 m below: 1.08 m slant, still near.
    assert cut(points(0.3, near_height=-0.6))


def test_fewer_than_three_far_points_keep_them_all():
    assert not cut(points(0.3, n_far=2)) and cut(points(0.3, n_far=3))


def test_just_above_the_speed_and_turn_rate_it_acts_and_at_them_it_does_not():
    assert cut(points(0.3), velocity=(0.25, 0.0), turn=math.radians(12.0) * DT)
    assert cut(points(0.3), velocity=(0.0, -0.25))  # sideways counts as moving
    assert not cut(points(0.3), velocity=(0.2, 0.0))
    assert not cut(points(0.3), turn=math.radians(9.0) * DT)


@pytest.mark.parametrize("velocity, turn, dt", [
    ((math.nan, 0.0), TURN, DT), ((math.inf, 0.0), TURN, DT), ((0.8, 0.0), math.nan, DT),
    ((0.8, 0.0), math.inf, DT), ((0.8, 0.0), TURN, math.nan), ((0.8, 0.0), TURN, 0.0), ((0.8, 0.0), TURN, -DT),
])
def test_a_velocity_turn_or_time_that_is_not_a_number_changes_nothing(velocity, turn, dt):
    assert not cut(points(0.3), velocity=velocity, turn=turn, dt=dt)


def test_the_option_reads_and_writes_as_json(tmp_path):
    for value in (0.8, None):
        path = tmp_path / "estimator.json"
        EstimatorConfig().with_(icp={"moving_turn_min_range_m": value}).dump(str(path))
        assert EstimatorConfig.load(str(path)).icp.moving_turn_min_range_m == value
    with pytest.raises(ConfigError, match="moving_turn_min_range_m"):
        IcpConfig(moving_turn_min_range_m=math.inf)
