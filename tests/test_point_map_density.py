"""The points' map weighed by its density (``point_yaw.density_weighted``, docs/heading.md item
38): a wall seen by many frames from behind is densest where they all saw it, and a sum of
Gaussians draws a frame's points on it toward there, a turn the weights take out."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.odometry import RadarOdometry
from radarodom.estimator.point_map import _gaussians, _log_density


def _wall_turn(weighted: bool, frames: int, wall_m: float = 1.5, bin_m: float = 0.1) -> float:
    """The turn (degrees) the points' registration finds for a frame at the truth whose points lie
    where its range bins meet a wall *wall_m* to the left, on a map of *frames* frames driven
    toward it along the wall (8 cm apart), each frame's points where its own range bins meet it;
    the map's weights as a moving step takes them (None unless *weighted*)."""
    config = EstimatorConfig.tidemo()
    config = replace(config, point_yaw=replace(config.point_yaw, density_weighted=weighted))
    part = RadarOdometry(config).point_yaw
    ranges = np.arange(wall_m / math.sin(math.radians(75.0)), wall_m / math.sin(math.radians(15.0)), bin_m)
    for k in range(frames):
        origin = np.array([-0.08 * (frames - k), 0.0])
        wall = np.stack([origin[0] + np.sqrt(ranges ** 2 - wall_m ** 2), np.full(len(ranges), wall_m)], 1)
        part.map._frames.append(_gaussians(wall, origin, part._config))
    part.map.pose = (0.0, 0.0, 0.0)
    seen = ranges + 0.5 * bin_m  # the frame's own range bins fall between the map's
    xy = np.stack([np.sqrt(seen ** 2 - wall_m ** 2), np.full(len(seen), wall_m)], 1)
    found = part._register(xy, np.zeros(2), 0.0, weighted=True)
    assert found is not None
    return math.degrees(found[0])


def test_a_wall_seen_by_many_frames_turns_the_unweighted_points_and_not_the_weighted():
    # No noise at all: every point lies on the wall, so what turns the frame is the map's density.
    unweighted = [_wall_turn(False, n) for n in (10, 30, 80)]
    weighted = [_wall_turn(True, n) for n in (10, 30, 80)]
    assert unweighted[2] > 0.04 and unweighted[0] < unweighted[1] < unweighted[2]  # the longer the map, the more
    assert all(abs(w) < 0.02 for w in weighted)
    assert abs(weighted[2]) < 0.3 * unweighted[2]


def test_the_maps_density_is_its_gaussians_summed_at_each_point():
    # Against every pair summed: those left out (beyond three of the map's largest spread) add little.
    rng = np.random.default_rng(4)
    points = np.concatenate([rng.uniform(0, 4, (150, 2)), rng.normal([2.0, 2.0], 0.1, (50, 2))])
    centres, inverse, sigma = _gaussians(points, np.zeros(2), EstimatorConfig().point_yaw)
    d = centres[:, None] - centres[None]  # (m, m, 2): point j less point k
    every = np.exp(-0.5 * np.einsum("jki,kil,jkl->jk", d, inverse, d)).sum(1)
    found = np.exp(_log_density(centres, inverse, sigma))
    assert found == pytest.approx(every, rel=0.03)
    assert found.min() >= 1.0 and found[150:].mean() > 5 * found[:150].mean()  # the cluster is denser
    assert _log_density(centres[:1], inverse[:1], sigma[:1]) == pytest.approx([0.0])
