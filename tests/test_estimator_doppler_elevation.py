"""Each heatmap cell's elevation from its Doppler for arrays without a raised row
(``features.doppler_elevation``, issue 20): a static reflector's radial velocity fixes the cosine of
its elevation given the sensor's velocity and the cell's azimuth axis."""

from __future__ import annotations

import math

import numpy as np
import pytest

from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig
from radarodom.estimator.doppler_elevation import doppler_elevation_part
from radarodom.estimator.odometry import RadarOdometry
from radarodom.products import RangeAzimuth

AZIMUTH = np.arcsin(np.linspace(-0.9, 0.9, 19))  # the heatmap's axis: arcsin of the sideways cosine
RANGE = np.linspace(0.5, 5.0, 10)


def _heatmap(elevation_deg: np.ndarray, velocity, with_doppler=True, array_elevation=None) -> RangeAzimuth:
    """Cells whose sideways cosine is the axis's, at *elevation_deg* (n_range, n_az), with the
    Doppler a static reflector there has from a sensor moving at *velocity* (body frame, m/s)."""
    el = np.radians(elevation_deg)
    u = np.sin(AZIMUTH)[None, :] * np.ones_like(el)
    # The direction: sideways cosine u (TI: to the right), up sin(el), forward the rest.
    forward = np.sqrt(np.clip(1.0 - u * u - np.sin(el) ** 2, 0.0, 1.0))
    radial = -(velocity[0] * forward - velocity[1] * u)
    shape = el.shape
    doppler = radial.astype(np.float32) if with_doppler else np.full(shape, np.nan, np.float32)
    power = np.ones(shape, np.float32)
    return RangeAzimuth(power, power, doppler, RANGE.copy(), AZIMUTH.copy(), array_elevation)


def test_the_cosine_of_each_cells_elevation_comes_from_its_doppler():
    rng = np.random.default_rng(3)
    elevation = rng.uniform(-25.0, 25.0, size=(len(RANGE), len(AZIMUTH)))
    velocity = np.array([0.8, 0.03])
    part = doppler_elevation_part(EstimatorConfig().with_(features={"doppler_elevation": "always"}).features)
    out = part(_heatmap(elevation, velocity), 0.0, velocity, 0.0)
    found = np.degrees(out.elevation_rad)
    # The sign of the elevation is not observable, its size is.
    assert np.allclose(found, np.abs(elevation), atol=0.05)
    # Cells without a Doppler are level.
    partly = _heatmap(elevation, velocity)
    partly.doppler_mps[:, :5] = np.nan
    assert np.all(part(partly, 0.0, velocity, 0.0).elevation_rad[:, :5] == 0.0)


def test_it_stands_aside_where_it_cannot_tell_or_is_not_asked():
    elevation = np.full((len(RANGE), len(AZIMUTH)), 10.0)
    velocity = np.array([0.8, 0.0])
    config = EstimatorConfig().features
    assert config.doppler_elevation == "turns"  # the default
    part = doppler_elevation_part(config)
    heatmap = _heatmap(elevation, velocity)
    assert part(heatmap, 0.0, None, math.radians(20.0)) is heatmap  # no velocity of the frame's own
    assert part(heatmap, 0.1, velocity, math.radians(2.0)) is heatmap  # driving straight: "turns" only
    assert part(heatmap, 0.2, velocity, math.radians(20.0)).elevation_rad is not None  # turning: given
    raised = _heatmap(elevation, velocity, array_elevation=np.zeros_like(elevation, dtype=np.float32))
    assert part(raised, 0.3, velocity, math.radians(20.0)) is raised  # the array's own elevation stands
    no_doppler = _heatmap(elevation, velocity, with_doppler=False)
    assert part(no_doppler, 0.3, velocity, math.radians(20.0)) is no_doppler  # TI's zero-Doppler map
    assert doppler_elevation_part(EstimatorConfig().with_(features={"doppler_elevation": "off"}).features) is None
    assert RadarOdometry(EstimatorConfig.paper()).doppler_elevation is None


def test_at_rest_each_range_bin_keeps_the_elevation_it_had_when_the_radar_last_moved():
    # Turning in place there is no Doppler to tell elevation by, but every reflector stays at its
    # range: a floor 10 degrees below at every range, seen while driving straight, then at rest.
    elevation = np.full((len(RANGE), len(AZIMUTH)), 10.0)
    part = doppler_elevation_part(EstimatorConfig().features)
    moving = np.array([0.8, 0.0])
    assert part(_heatmap(elevation, moving), 0.0, moving, 0.0).elevation_rad is None  # straight: not used
    standing = np.zeros(2)
    at_rest = part(_heatmap(elevation, standing), 1.0, standing, math.radians(45.0))
    assert np.allclose(np.degrees(at_rest.elevation_rad), 10.0, atol=0.05)
    # ... for doppler_elevation_rest_s (5 s) after the last frame that moved.
    assert part(_heatmap(elevation, standing), 6.0, standing, math.radians(45.0)).elevation_rad is None
    # Backing up it is measured as driving forward; sliding sideways it is left alone.
    backing = np.array([-0.8, 0.0])
    turned = part(_heatmap(elevation, backing), 7.0, backing, math.radians(20.0))
    assert np.allclose(np.degrees(turned.elevation_rad), 10.0, atol=0.05)
    sideways = np.array([0.0, 0.5])
    assert part(_heatmap(elevation, sideways), 7.1, sideways, math.radians(20.0)).elevation_rad is None


def test_at_rest_the_range_profile_is_the_moving_frames_average_weighted_by_speed():
    # Braking into a turn in place, the last frames that move are the slowest, where a Doppler bin
    # is a large part of the speed: their reading (here 20 degrees, for a floor at 10) counts as
    # their speed squared against the faster frames before, which fade over
    # doppler_elevation_memory_s (0.5 s).
    config = EstimatorConfig().features
    part = doppler_elevation_part(config)
    fast, slow = np.array([0.8, 0.0]), np.array([0.25, 0.0])
    part(_heatmap(np.full((len(RANGE), len(AZIMUTH)), 10.0), fast), 0.0, fast, 0.0)
    part(_heatmap(np.full((len(RANGE), len(AZIMUTH)), 20.0), slow), 0.3, slow, 0.0)
    standing = np.zeros(2)
    at_rest = part(_heatmap(np.zeros((len(RANGE), len(AZIMUTH))), standing), 0.4, standing, math.radians(45.0))
    w_fast, w_slow = 0.8**2 * math.exp(-0.3 / config.doppler_elevation_memory_s), 0.25**2
    cos_el = (w_fast * math.cos(math.radians(10.0)) + w_slow * math.cos(math.radians(20.0))) / (w_fast + w_slow)
    assert np.allclose(at_rest.elevation_rad, math.acos(cos_el), atol=1e-4)
    assert 10.0 < np.degrees(at_rest.elevation_rad).mean() < 12.5


def test_the_range_profile_forgets_bins_left_unseen_and_survives_odd_frames():
    part = doppler_elevation_part(EstimatorConfig().features)  # doppler_elevation_rest_s 5 s
    moving, standing = np.array([0.8, 0.0]), np.zeros(2)
    floor = np.full((len(RANGE), len(AZIMUTH)), 10.0)
    part(_heatmap(floor, moving), 0.0, moving, 0.0)
    # Then 8 s of driving where the first range bin holds no Doppler: it is level at rest, the
    # others keep their 10 degrees.
    for i in range(1, 81):
        frame = _heatmap(floor, moving)
        frame.doppler_mps[0] = np.nan
        part(frame, 0.1 * i, moving, 0.0)
    # A frame whose power is not finite adds nothing to the profile.
    broken = _heatmap(floor, moving)
    broken.intensity[:] = np.inf
    part(broken, 8.05, moving, 0.0)
    at_rest = np.degrees(part(_heatmap(floor, standing), 8.1, standing, math.radians(45.0)).elevation_rad)
    assert np.all(at_rest[0] == 0.0) and np.allclose(at_rest[1:], 10.0, atol=0.05)
    # A heatmap of another range axis is not given the old profile at rest, and starts it afresh.
    assert part(_first_bins(_heatmap(floor, standing), 5), 8.2, standing, math.radians(45.0)).elevation_rad is None
    part(_first_bins(_heatmap(np.full_like(floor, 20.0), moving), 5), 8.3, moving, 0.0)
    again = part(_first_bins(_heatmap(floor, standing), 5), 8.4, standing, math.radians(45.0))
    assert np.allclose(np.degrees(again.elevation_rad), 20.0, atol=0.05)


def _first_bins(heatmap: RangeAzimuth, n: int) -> RangeAzimuth:
    """*heatmap*'s first *n* range bins."""
    return RangeAzimuth(heatmap.intensity[:n], heatmap.static[:n], heatmap.doppler_mps[:n], heatmap.range_m[:n],
                        heatmap.azimuth_rad)


def test_a_bad_setting_names_the_field():
    with pytest.raises(ConfigError) as info:
        EstimatorConfig.from_dict({"features": {"doppler_elevation": "sometimes"}})
    assert "doppler_elevation" in str(info.value)
    with pytest.raises(ConfigError):
        EstimatorConfig.from_dict({"features": {"doppler_elevation_min_mps": 0.0}})
    with pytest.raises(ConfigError) as info:
        EstimatorConfig.from_dict({"features": {"doppler_elevation_memory_s": 0.0}})
    assert "doppler_elevation_memory_s" in str(info.value)
