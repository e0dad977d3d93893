"""The heading of the heatmaps' and the points' registrations blended (``point_yaw.blend``,
estimator/heading_blend.py; docs/heading.md item 30), on a synthetic scene of point reflectors: a
straight drive into a moving turn, and a turn in place."""

from __future__ import annotations

import math

import estimator_synth as synth
import numpy as np
import pytest

from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.odometry import RadarOdometry

DRIVE = synth.Trajectory([(1.0, 0.8, 0.0), (2.0, 0.8, math.radians(40.0)), (1.0, 0.8, 0.0),
                          (2.0, 0.0, math.radians(60.0)), (0.5, 0.0, 0.0)])


def _three(share: float):
    """The states of the heatmaps' estimator, the points' and the blend's, frame by frame."""
    states = [synth.run_sequence(config, DRIVE)[0] for config in (
        EstimatorConfig(), EstimatorConfig().with_(point_yaw={"use": True}),
        EstimatorConfig().with_(point_yaw={"blend": share}))]
    return list(zip(*states))


@pytest.mark.parametrize("share", [0.3, 0.5])
def test_the_heading_is_the_share_of_the_way_from_the_heatmaps_chain_to_the_points(share):
    frames = _three(share)
    field = np.array([a.yaw for a, _, _ in frames])
    points = np.array([b.yaw for _, b, _ in frames])
    blend = np.array([c.yaw for _, _, c in frames])
    # The two chains differ (else the test could not tell a share), and the blend lies between.
    assert np.max(np.abs(points - field)) > math.radians(0.2)
    np.testing.assert_allclose(blend, field + share * (points - field), rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.diff(blend), [c.yaw_increment for _, _, c in frames[1:]], atol=1e-12)
    np.testing.assert_allclose([c.yaw_rate for _, _, c in frames],
                               [a.yaw_rate + share * (b.yaw_rate - a.yaw_rate) for a, b, _ in frames], atol=1e-12)
    for (a0, _, c0), (a1, _, c1) in zip(frames, frames[1:]):
        # Each step of the position is the heatmap chain's, turned by the two headings' difference.
        step_a = np.array([a1.x - a0.x, a1.y - a0.y])
        step_c = np.array([c1.x - c0.x, c1.y - c0.y])
        turn = c0.yaw - a0.yaw
        rot = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
        np.testing.assert_allclose(step_c, rot @ step_a, atol=1e-12)
        assert (c1.vx, c1.vy) == (a1.vx, a1.vy)
    # The covariance between the two chains' (a convex sum); the speeds' the velocity fit's.
    last_a, last_b, last_c = frames[-1]
    lo, hi = sorted((last_a.pose_covariance[2, 2], last_b.pose_covariance[2, 2]))
    assert lo <= last_c.pose_covariance[2, 2] <= hi
    np.testing.assert_array_equal(last_c.twist_covariance[:2, :2], last_a.twist_covariance[:2, :2])


def test_the_flags_are_both_chains_and_the_compute_time_both():
    frames = _three(0.5)
    for a, b, c in frames:
        assert set(c.flags) == set(a.flags) | set(b.flags)
        assert c.flags[:len(a.flags)] == a.flags
        assert c.compute_s > a.compute_s


def test_without_a_share_or_with_the_points_alone_nothing_is_blended():
    assert RadarOdometry(EstimatorConfig()).blend is None
    alone = EstimatorConfig().with_(point_yaw={"use": True})
    assert RadarOdometry(alone.with_(point_yaw={"blend": 0.5})).blend is None
    points = synth.run_sequence(alone, DRIVE)[0]
    both = synth.run_sequence(alone.with_(point_yaw={"blend": 0.5}), DRIVE)[0]
    assert [s.pose for s in both] == [s.pose for s in points]


@pytest.mark.parametrize("value", [-0.1, 1.0, 2.0])
def test_a_share_outside_zero_to_one_is_refused_naming_the_field(value):
    with pytest.raises(ConfigError, match=r"point_yaw\.blend.*\[0, 1\)"):
        EstimatorConfig.from_dict({"point_yaw": {"blend": value}})
