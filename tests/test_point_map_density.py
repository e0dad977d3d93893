"""The points' map weighed by its density (``point_yaw.density_weighted``, docs/heading.md item
38): a wall seen by many frames from behind is densest where they all saw it, and a sum of
Gaussians draws a frame's points on it toward there, a turn the weights take out."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from radarodom.estimator.config import EstimatorConfig, PointYawConfig
from radarodom.estimator.odometry import RadarOdometry
from radarodom.estimator.map_density import MapDensity, gaussian_values
from radarodom.estimator.point_map import LocalMap, _gaussians


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
        part.map.add(_gaussians(wall, origin, part._config))
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


def _every_pair(centres: np.ndarray, inverse: np.ndarray) -> np.ndarray:
    """The map's density at each point, every pair summed (within the cut)."""
    d = centres[:, None] - centres[None]  # (m, m, 2): point j less point k
    return gaussian_values(d.reshape(-1, 2), np.broadcast_to(inverse[None], (len(centres),) + inverse.shape)
                           .reshape(-1, 2, 2)).reshape(len(centres), len(centres)).sum(1)


def test_the_maps_density_kept_as_frames_enter_and_leave_is_its_gaussians_summed_at_each_point():
    # Frames of a few points each, about a cluster, through a map of 6 frames: each time, the
    # density kept equals every pair summed anew.
    rng = np.random.default_rng(4)
    config = PointYawConfig(map_frames=6, density_weighted=True)
    local = LocalMap(config)
    for n in range(15):
        origin = np.array([0.3 * n, 0.0])
        points = np.concatenate([rng.uniform(0, 4, (int(rng.integers(1, 12)), 2)), rng.normal([2.0, 2.0], 0.1, (5, 2))])
        local.add(_gaussians(points, origin, config))
        centres, inverse, _ = local.arrays()
        assert len(centres) == sum(len(f[0]) for f in list(local._frames)[-6:])
        assert np.exp(-local.log_weights()) == pytest.approx(_every_pair(centres, inverse), rel=1e-12)
    found = np.exp(-local.log_weights())
    assert found.min() >= 1.0 and found[-5:].mean() > 5 * found[:-5].min()  # the cluster is denser


def test_the_density_of_a_map_of_one_point_is_one_and_of_none_empty():
    density = MapDensity(80)
    assert len(density.log_density()) == 0
    density.enter(_gaussians(np.array([[1.0, 2.0]]), np.zeros(2), PointYawConfig()))
    assert density.log_density() == pytest.approx([0.0])
