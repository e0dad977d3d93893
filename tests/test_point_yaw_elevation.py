"""A point cloud without elevation (a 2-TX array has no raised antenna row) among reflectors above
the radar: placed as level, a point sits at cos(el) of its bearing's sine, and the points' map
measures turns short by about the scene's cos(el).  The points take the elevation the same frame's
heatmap cells get from their Doppler (``features.doppler_elevation``: in a turn each one's own, at
rest its range bin's from the frames that moved; docs/heading.md item 33)."""

from __future__ import annotations

import math

import estimator_synth as synth
import numpy as np

from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.doppler_elevation import doppler_elevation_part
from radarodom.estimator.odometry import RadarOdometry
from radarodom.estimator.point_yaw import static_points

DT = 0.1
#: Every reflector this far above the radar, within 5 m of the turn: 11-34 degrees of elevation.
HEIGHT_M = 1.0
#: Driving, braking, turning 180 degrees in place, standing.
IN_PLACE = [(2.0, 0.8, 0.0), (0.2, 0.0, 0.0), (3.0, 0.0, math.radians(60.0)), (0.5, 0.0, 0.0)]


def _level_array_frame(world, amplitude, pose, velocity, rng):
    """The point cloud and heatmap an array without elevation gives of reflectors HEIGHT_M above
    it: each at its slant range and azimuth axis cos(el) sin(bearing), as if level; its Doppler a
    static reflector's at the true direction."""
    r, b = synth.polar_body(synth.world_to_body(world, pose))
    slant = np.hypot(r, HEIGHT_M)
    cos_el = r / slant
    sideways = cos_el * np.sin(b)
    apparent = np.column_stack([slant * np.sqrt(1.0 - sideways ** 2), slant * sideways])
    radial = -cos_el * (velocity[0] * np.cos(b) + velocity[1] * np.sin(b))
    seen = (np.abs(b) < math.radians(60.0)) & (r > 0.5) & (r < 10.0)
    cloud = synth.points(apparent[seen], velocity, radial_velocity=radial[seen], noise_mps=0.01, rng=rng)
    heatmap = synth.heatmap(apparent, amplitude, radial_velocity=radial, noise=1e-3, rng=rng)
    return cloud, heatmap


def _turn_in_place(config: EstimatorConfig) -> float:
    """The points' chain's turn in place against the truth's (their heatmap registration only where
    the points give none: these synthetic heatmaps are not what it is tuned on)."""
    config = config.with_(point_yaw={"use": True, "blend": 0.0, "heatmap_use": "fallback"})
    traj = synth.Trajectory(IN_PLACE)
    world, amplitude = synth.scene(traj, 40, seed=4, separation_m=1.0, box=((-4.0, -5.0), (7.0, 5.0)))
    rng = np.random.default_rng(4)
    odom = RadarOdometry(config)
    yaws = []
    for k in range(int(round(traj.duration / DT)) + 1):
        v, _, _ = traj.twist(k * DT)
        cloud, heatmap = _level_array_frame(world, amplitude, traj.pose(k * DT), (v, 0.0), rng)
        yaws.append(odom.step(k * DT, cloud, heatmap).yaw)
    return (yaws[-1] - yaws[0]) / traj.pose(traj.duration)[2]


def test_turning_in_place_points_without_elevation_take_their_range_bins_and_the_turn_is_whole():
    placed = _turn_in_place(EstimatorConfig())
    level = _turn_in_place(EstimatorConfig().with_(features={"doppler_elevation": "off"}))
    assert level < 0.97, level  # read as level: short by the scene's cos(el)
    assert abs(placed - 1.0) < 0.01, placed


def test_a_frames_points_get_the_elevation_its_heatmap_cells_got():
    part = doppler_elevation_part(EstimatorConfig().features)  # "turns": in turns and at rest
    bearing, elevation, slant = np.radians([-40.0, -10.0, 25.0]), np.radians([15.0, 5.0, 20.0]), 3.0
    # As a level array reports them: elevation 0, the azimuth axis cos(el) sin(bearing).
    sideways = np.cos(elevation) * np.sin(bearing)
    flat = np.column_stack([slant * np.sqrt(1.0 - sideways ** 2), slant * sideways])
    moving = np.array([0.8, 0.0])
    radial = -moving[0] * np.cos(elevation) * np.cos(bearing)
    cloud = synth.points(flat, moving, radial_velocity=radial)
    world = np.array([[3.0, 0.0]])

    def heatmap(velocity):
        return synth.heatmap(world, 1.0, velocity_xy=tuple(velocity), radial_velocity=-velocity[:1])

    part(heatmap(moving), 0.0, moving, 0.0)  # driving straight: the cells keep none, nor the points
    assert part.points_cos_elevation(cloud) is None
    part(heatmap(moving), 0.1, moving, math.radians(30.0))  # turning: each point's from its Doppler
    assert np.allclose(part.points_cos_elevation(cloud), np.cos(elevation), atol=1e-6)
    xy = static_points(cloud, moving, 0.1, part.points_cos_elevation(cloud))
    # Placed at their horizontal range and true bearing.
    assert np.allclose(np.hypot(xy[:, 0], xy[:, 1]), slant * np.cos(elevation), atol=1e-6)
    assert np.allclose(np.arctan2(xy[:, 1], xy[:, 0]), bearing, atol=1e-6)
    # At rest, the range bin's cos(el) from the moving frames (the one reflector's at 3 m: level).
    standing = np.zeros(2)
    part(heatmap(standing), 0.2, standing, math.radians(45.0))
    at_rest = part.points_cos_elevation(synth.points(flat, standing))
    assert at_rest is not None and np.allclose(at_rest, 1.0, atol=1e-6)
    # A cloud with an elevation of its own keeps it.
    assert part.points_cos_elevation(synth.points_polar(bearing, elevation, standing, range_m=slant)) is None
