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
    out = part(_heatmap(elevation, velocity), velocity, 0.0)
    found = np.degrees(out.elevation_rad)
    # The sign of the elevation is not observable, its size is.
    assert np.allclose(found, np.abs(elevation), atol=0.05)
    # Cells without a Doppler are level.
    partly = _heatmap(elevation, velocity)
    partly.doppler_mps[:, :5] = np.nan
    assert np.all(part(partly, velocity, 0.0).elevation_rad[:, :5] == 0.0)


def test_it_stands_aside_where_it_cannot_tell_or_is_not_asked():
    elevation = np.full((len(RANGE), len(AZIMUTH)), 10.0)
    velocity = np.array([0.8, 0.0])
    config = EstimatorConfig().with_(features={"doppler_elevation": "turns"}).features
    part = doppler_elevation_part(config)
    heatmap = _heatmap(elevation, velocity)
    assert part(heatmap, velocity, math.radians(20.0)).elevation_rad is not None  # turning: given
    assert part(heatmap, velocity, math.radians(2.0)) is heatmap  # driving straight: "turns" only
    assert part(heatmap, None, math.radians(20.0)) is heatmap  # no velocity of the frame's own
    assert part(heatmap, np.array([0.1, 0.0]), math.radians(20.0)) is heatmap  # too slow to say
    raised = _heatmap(elevation, velocity, array_elevation=np.zeros_like(elevation, dtype=np.float32))
    assert part(raised, velocity, math.radians(20.0)) is raised  # the array's own elevation stands
    assert doppler_elevation_part(EstimatorConfig().features) is None  # off by default
    assert RadarOdometry(EstimatorConfig()).doppler_elevation is None


def test_a_bad_setting_names_the_field():
    with pytest.raises(ConfigError) as info:
        EstimatorConfig.from_dict({"features": {"doppler_elevation": "sometimes"}})
    assert "doppler_elevation" in str(info.value)
    with pytest.raises(ConfigError):
        EstimatorConfig.from_dict({"features": {"doppler_elevation_min_mps": 0.0}})
