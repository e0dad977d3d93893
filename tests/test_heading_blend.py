"""The heading of the heatmaps' and the points' registrations blended (``point_yaw.blend``,
estimator/heading_blend.py; docs/heading.md item 30), on a synthetic scene of point reflectors
whose point clouds are the reflectors in view: a straight drive into a moving turn, and a turn in
place; then frames lost and a long run the points did not measure, where the heatmap chain's turn
stands, and steps only one of the two measured, blended."""

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
HEATMAPS = synth.heatmap_chain()
POINTS = EstimatorConfig().with_(point_yaw={"use": True})


def _frames(trajectory, *, drop=(), blind=(), dark=(), sparse=(), seed=2):
    """(t, cloud, heatmap) of each frame along *trajectory* at 10 Hz; frames whose index is in
    *drop* lost, those in *blind* seeing nothing (an empty cloud, a heatmap of noise), those in
    *dark* a heatmap of noise beside their cloud, those in *sparse* one point in their cloud."""
    world, amp = synth.scene(trajectory, 40, seed=seed)
    rng = np.random.default_rng(seed + 100)
    out = []
    for i in range(round(trajectory.duration * 10) + 1):
        t = i / 10
        vx, vy, _ = trajectory.twist(t)
        cloud, hm = synth.frame(world, amp, trajectory.pose(t), (vx, vy), rng)
        if i in blind or i in dark:
            hm = synth.heatmap(np.zeros((0, 2)), noise=1.0, rng=rng)
            cloud = cloud[:0] if i in blind else cloud
        if i in sparse:
            cloud = cloud[:1]
        if i not in drop:
            out.append((t, cloud, hm))
    return out


def _run(config, frames):
    odom = RadarOdometry(config)
    return [odom.step(t, cloud, hm) for t, cloud, hm in frames]


def _three(share, frames, *, where_held=False):
    """The states of the heatmaps' estimator, the points' and the blend's, frame by frame (the
    share everywhere unless *where_held*: ``point_yaw.blend_points_where_held``)."""
    blend = EstimatorConfig().with_(point_yaw={"blend": share, "blend_points_where_held": where_held})
    return list(zip(*(_run(config, frames) for config in (HEATMAPS, POINTS, blend))))


def _turns(states):
    return np.diff([s.yaw for s in states])


@pytest.mark.parametrize("share", [0.3, 0.5])
def test_each_steps_turn_is_the_share_of_the_way_from_the_heatmaps_to_the_points(share):
    frames = _three(share, _frames(DRIVE))
    field, points, blend = (_turns(chain) for chain in zip(*frames))
    # The two chains differ (else the test could not tell a share), and every step measured by
    # both (all of them here) is blended.
    assert np.max(np.abs(np.cumsum(points - field))) > math.radians(0.2)
    assert all(a.ok and b.ok for a, b, _ in frames[1:])
    np.testing.assert_allclose(blend, field + share * (points - field), rtol=0, atol=1e-12)
    np.testing.assert_allclose(blend, [c.yaw_increment for _, _, c in frames[1:]], atol=1e-12)
    np.testing.assert_allclose([c.yaw_rate for _, _, c in frames],
                               [a.yaw_rate + share * (b.yaw_rate - a.yaw_rate) for a, b, _ in frames], atol=1e-12)
    same = np.ones((3, 3), bool)  # the pose covariance's entries but the heading's variance
    same[2, 2] = False
    for (a0, _, c0), (a1, b1, c1) in zip(frames, frames[1:]):
        # Each step of the position is the heatmap chain's, turned by the two headings' difference.
        turn = c0.yaw - a0.yaw
        rot = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
        np.testing.assert_allclose([c1.x - c0.x, c1.y - c0.y], rot @ [a1.x - a0.x, a1.y - a0.y], atol=1e-12)
        assert (c1.vx, c1.vy, c1.flags) == (a1.vx, a1.vy, a1.flags)
        # The covariances the heatmap chain's (the points' chain's grow by every step's variance),
        # the heading's walked by the turn the blend added, as the chain's by its turns.
        np.testing.assert_array_equal(c1.twist_covariance, a1.twist_covariance)
        np.testing.assert_array_equal(c1.pose_covariance[same], a1.pose_covariance[same])
        assert b1.pose_covariance[2, 2] != a1.pose_covariance[2, 2]
    walk = EstimatorConfig().odometry.yaw_walk_per_sqrt_rad ** 2
    np.testing.assert_allclose([c.pose_covariance[2, 2] - a.pose_covariance[2, 2] for a, _, c in frames[1:]],
                               walk * np.cumsum(np.abs(blend - field)), rtol=1e-9, atol=1e-15)


def test_frames_lost_or_long_unmeasured_by_the_points_take_the_heatmaps_turn():
    standing_turn = synth.Trajectory([(1.0, 0.8, 0.0), (3.0, 0.0, math.radians(30.0)), (2.5, 0.8, 0.0)])
    frames = _three(0.5, _frames(standing_turn, drop={12, 13, 14}, blind={30, 31}, dark={36, 37},
                                 sparse=set(range(45, 62))))
    field, points, blend = (_turns(chain) for chain in zip(*frames))
    lost = np.array([frames[k + 1][0].t - frames[k][0].t > 0.15 for k in range(len(frames) - 1)])
    # The points' chain's steps since its last measured one: within lag_frames (10) it still makes
    # up for what it held, and its held steps are blended; beyond, the heatmaps' turn stands.
    unmeasured, alive = math.inf, []
    for _, b, _ in frames[1:]:
        unmeasured = 0 if b.ok else unmeasured + 1
        alive.append(unmeasured <= EstimatorConfig().point_yaw.lag_frames)
    alive = np.array(alive)
    points_held = np.array([not b.ok for _, b, _ in frames[1:]])
    heatmaps_held = np.array([not a.ok for a, _, _ in frames[1:]])
    # The test sees each kind: frames lost; held steps of the points' chain blended (the blind
    # run), and the heatmaps' turn alone after ten of them (the sparse clouds); steps only the
    # points measured (heatmaps of noise beside clouds), blended.
    assert lost.sum() == 1 and (points_held & alive & ~lost).any() and (~alive & ~lost).any()
    assert (heatmaps_held & ~points_held & ~lost).any()
    for k in range(len(field)):
        expected = 0.5 * (field[k] + points[k]) if alive[k] and not lost[k] else field[k]
        assert blend[k] == pytest.approx(expected, abs=1e-12), k
    assert np.max(np.abs(blend - field)[heatmaps_held & ~points_held & ~lost]) > 1e-4
    assert all(c.flags == a.flags for a, _, c in frames)


def test_where_the_heatmaps_held_their_rate_the_points_turn_is_taken_whole():
    # point_yaw.blend_points_where_held (docs/heading.md item 39; the default): a step whose heatmap
    # showed the heatmaps' chain nothing (it stood in its held rate) but whose points the points'
    # chain measured publishes the points' turn; every other step as the share has it.
    from radarodom.estimator.quality import Flag
    standing_turn = synth.Trajectory([(1.0, 0.8, 0.0), (3.0, 0.0, math.radians(30.0)), (2.5, 0.8, 0.0)])
    frames = _frames(standing_turn, drop={12, 13, 14}, blind={30, 31}, dark={36, 37, 38})
    option = EstimatorConfig()
    assert option.point_yaw.blend_points_where_held and option.point_yaw.blend == 0.5
    triples = list(zip(*(_run(config, frames) for config in (HEATMAPS, POINTS, option))))
    field, points, blend = (_turns(chain) for chain in zip(*triples))
    plain = _turns([c for _, _, c in _three(0.5, frames)])
    held = np.array([bool({Flag.YAW_HELD, Flag.MOTION_LOST} & set(a.flags)) and b.ok for a, b, _ in triples[1:]])
    lost = np.array([triples[k + 1][0].t - triples[k][0].t > 0.15 for k in range(len(triples) - 1)])
    assert (held & ~lost).sum() >= 2  # the dark heatmaps beside their clouds
    np.testing.assert_allclose(blend[held & ~lost], points[held & ~lost], rtol=0, atol=1e-12)
    np.testing.assert_allclose(blend[~held | lost], plain[~held | lost], rtol=0, atol=1e-12)
    assert np.max(np.abs(points - field)[held & ~lost]) > 1e-4  # (else the test could not tell)


def test_without_a_share_or_with_the_points_alone_nothing_is_blended():
    assert RadarOdometry(HEATMAPS).blend is None
    assert RadarOdometry(POINTS.with_(point_yaw={"blend": 0.5})).blend is None
    frames = _frames(DRIVE)[:20]
    assert [s.pose for s in _run(POINTS.with_(point_yaw={"blend": 0.5}), frames)] == \
        [s.pose for s in _run(POINTS, frames)]
    # The paper's method has no option beyond it; the default blends half of each.
    assert EstimatorConfig.paper().point_yaw.blend == 0.0
    assert EstimatorConfig().point_yaw.blend == 0.5 and RadarOdometry(EstimatorConfig()).blend is not None


@pytest.mark.parametrize("value", [-0.1, 1.0, 2.0])
def test_a_share_outside_zero_to_one_is_refused_naming_the_field(value):
    with pytest.raises(ConfigError, match=r"point_yaw\.blend.*\[0, 1\)"):
        EstimatorConfig.from_dict({"point_yaw": {"blend": value}})
