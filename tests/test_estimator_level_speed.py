"""The forward speed of point clouds without elevation (estimator/level_speed.py,
``velocity.level_edge_quantile``): a 2-TX array reads every reflector as level, so the fit's
forward speed is the points' mean cos(elevation) of the truth; the edge of the pooled ratios
gives it back.

Clouds are made by hand in the TI frame (azimuth positive to the right, radial velocity
positive receding): a reflector at elevation el and azimuth az is reported at asin(cos(el)
sin(az)) with elevation 0, as an array without a raised row sees it.
"""

from __future__ import annotations

import math

import estimator_synth as synth
import numpy as np
import pytest
from radarodom.dsp.processor import POINT_DTYPE
from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig, VelocityConfig
from radarodom.estimator.level_speed import LevelSpeed, level_speed_part
from radarodom.estimator.odometry import RadarOdometry
from radarodom.estimator.velocity import OK, ZERO, VelocityEstimate, estimate_velocity
from radarodom.estimator.velocity_track import HeatmapVelocity, VelocityHistory


def cloud(rng, vx, vy, n=30, max_elevation_deg=25.0, noise_mps=0.005, measured_elevation=False):
    """*n* static reflectors at elevations uniform within +/- *max_elevation_deg* and azimuths
    within +/- 60 degrees, seen moving at (vx, vy) m/s (body frame: x forward, y left)."""
    el = np.radians(rng.uniform(-max_elevation_deg, max_elevation_deg, n))
    az = np.radians(rng.uniform(-60.0, 60.0, n))
    bearing = -az
    radial = -(vx * np.cos(el) * np.cos(bearing) + vy * np.cos(el) * np.sin(bearing))
    out = np.zeros(n, POINT_DTYPE)
    if measured_elevation:
        out["azimuth"], out["elevation"] = az, el
    else:
        out["azimuth"] = np.arcsin(np.cos(el) * np.sin(az))
    out["velocity"] = radial + rng.normal(0.0, noise_mps, n)
    return out


def drive(level, rng, vx, vy, frames=20, t0=0.0, **kw):
    """Each frame's (raw fit, estimate after *level*) over *frames* clouds 0.1 s apart."""
    config, fits = VelocityConfig(), []
    fit_rng = np.random.default_rng(0)
    for i in range(frames):
        t = t0 + 0.1 * i
        points = cloud(rng, vx, vy, **kw)
        est = estimate_velocity(points, t, config, fit_rng)
        fits.append((est, level(t, points, est)))
    return fits


@pytest.mark.parametrize("vx, vy", [(0.8, 0.0), (0.8, 0.1), (1.5, 0.0), (-0.8, 0.05)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_edge_gives_the_forward_speed_back(vx, vy, seed):
    fits = drive(LevelSpeed(VelocityConfig()), np.random.default_rng(seed), vx, vy)
    raw, scaled = fits[-1]
    assert raw.vx / vx < 0.98  # the level fit is the points' mean cos(el), 3-4 % low here
    assert scaled.vx / vx == pytest.approx(1.0, abs=0.015)
    assert scaled.vy == raw.vy and scaled.level_scale > 1.0
    np.testing.assert_allclose(scaled.level_velocity, raw.velocity)
    # The forward variance grows with the square of the scale, the sideways one is kept.
    assert scaled.covariance[0, 0] == pytest.approx(raw.covariance[0, 0] * scaled.level_scale ** 2)
    assert scaled.covariance[1, 1] == raw.covariance[1, 1]


def test_level_reflectors_with_a_fine_doppler_leave_the_speed_as_fitted():
    # Everything at the radar's height: the fit is right, and the edge (never below 1) keeps it
    # while the Doppler's noise (0.005 m/s here) is a small share of the speed; with 0.02 m/s it
    # would read some 3 % fast (docs/heading.md item 26: turn the edge off in such a world).
    fits = drive(LevelSpeed(VelocityConfig()), np.random.default_rng(4), 0.8, 0.0, max_elevation_deg=0.0)
    raw, scaled = fits[-1]
    assert raw.vx == pytest.approx(0.8, abs=0.005)
    assert scaled.vx == pytest.approx(0.8, abs=0.01)


def test_clouds_with_elevation_pass_unchanged():
    level = LevelSpeed(VelocityConfig())
    for raw, scaled in drive(level, np.random.default_rng(5), 0.8, 0.0, measured_elevation=True):
        assert scaled is raw
    assert level.scale == 1.0


def test_no_scale_before_enough_points_then_kept_through_a_stop():
    level = LevelSpeed(VelocityConfig())
    rng = np.random.default_rng(6)
    first = drive(level, rng, 0.8, 0.0, frames=1)  # 30 ratios: fewer than an edge needs
    assert first[0][1] is first[0][0]
    moving = drive(level, rng, 0.8, 0.0, frames=10, t0=0.1)
    scale = moving[-1][1].level_scale
    assert scale > 1.02
    # Standing still for longer than the window: nothing to pool, the speed is zero.
    for raw, scaled in drive(level, rng, 0.0, 0.0, frames=30, t0=1.1):
        assert raw.status == ZERO and scaled is raw
    # Moving again: the first clouds are too few for an edge of their own and keep the last one.
    again = drive(level, rng, 0.8, 0.0, frames=1, t0=5.0)
    assert again[0][1].level_scale == scale


def test_a_cloud_earlier_than_the_pool_pools_nothing():
    level = LevelSpeed(VelocityConfig())
    drive(level, np.random.default_rng(9), 0.8, 0.0, frames=10, t0=5.0)
    scale = level.scale
    drive(level, np.random.default_rng(10), 1.2, 0.0, frames=3, t0=1.0)  # the odometry refuses these
    assert level.scale == scale


@pytest.mark.parametrize("vx, vy", [(0.3, 0.8),   # sideways: its bearings' errors would be read as speed
                                    (0.3, 0.0)])  # below level_edge_min_mps: its Doppler's noise would
def test_sideways_or_slow_motion_pools_nothing(vx, vy):
    level = LevelSpeed(VelocityConfig())
    for raw, scaled in drive(level, np.random.default_rng(11), vx, vy, frames=20, noise_mps=0.02):
        assert scaled is raw
    assert level.scale == 1.0


def test_the_heatmap_fallback_takes_the_clouds_edge():
    # The heatmap's cells carry no elevation either: its Doppler fit is scaled by the edge the
    # clouds found (on 2-TX straights it is 0.94-0.95 of the truth, docs/heading.md item 26).
    config = EstimatorConfig()
    level = LevelSpeed(config.velocity)
    drive(level, np.random.default_rng(12), 0.8, 0.0)
    assert level.scale > 1.02
    heatmap = synth.scene_heatmap(velocity_xy=(0.8, 0.0))
    plain = HeatmapVelocity(config, VelocityHistory(5), None)(0.9, 1.0, heatmap)
    scaled = HeatmapVelocity(config, VelocityHistory(5), level)(0.9, 1.0, heatmap)
    assert plain is not None and scaled is not None
    assert scaled[0][0] == pytest.approx(plain[0][0] * level.scale)
    assert scaled[0][1] == pytest.approx(plain[0][1])


def test_an_interpolated_velocity_keeps_its_level_fit():
    history = VelocityHistory(5)
    for t, scale in ((1.0, 1.0), (1.1, 1.04)):
        history.add(VelocityEstimate(t=t, vx=0.8 * scale, covariance=np.eye(2), status=OK, level_scale=scale))
    mid = history.interpolated(1.05)
    assert mid.level_scale == pytest.approx(1.02)
    assert mid.level_velocity[0] == pytest.approx(mid.vx / 1.02)


def test_the_odometry_scales_elevationless_clouds_and_the_paper_does_not():
    rng = np.random.default_rng(7)
    clouds = [cloud(rng, 0.8, 0.0) for _ in range(20)]
    ours, paper = RadarOdometry(EstimatorConfig()), RadarOdometry(EstimatorConfig.paper())
    for i, points in enumerate(clouds):
        mine, theirs = ours.add_points(0.1 * i, points), paper.add_points(0.1 * i, points)
    assert mine.vx == pytest.approx(0.8, abs=0.012)
    assert theirs.vx < 0.785 and theirs.level_scale == 1.0
    assert EstimatorConfig.tidemo().velocity.level_edge_quantile is None


@pytest.mark.parametrize("field, value", [("level_edge_quantile", 1.0), ("level_edge_quantile", 0.0),
                                          ("level_edge_window_s", 0.0), ("level_edge_min_mps", -0.1)])
def test_bad_settings_name_their_field(field, value):
    with pytest.raises(ConfigError, match=field):
        VelocityConfig(**{field: value})


def test_off_gives_no_part():
    assert level_speed_part(VelocityConfig(level_edge_quantile=None)) is None
    assert isinstance(level_speed_part(VelocityConfig()), LevelSpeed)
    assert math.isclose(VelocityConfig().level_edge_quantile, 0.85)
