"""How a translation moves a feature with an elevation (``features.parallax``, docs/heading.md
item 21): "slant" as a reflector level with the radar at its slant range, keeping its elevation
angle; "horizontal" as a fixed reflector at its horizontal range and height."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from estimator_synth import AZIMUTH_RAD, RANGE_M
from radarodom.dsp.heatmap import RangeAzimuth
from radarodom.estimator.config import FeatureConfig
from radarodom.estimator.features import Features, SlantFeatures, extract

EL = math.radians(30.0)


def _one(cls, slant_m: float, bearing_rad: float, elevation_rad: float = EL):
    return cls(np.array([slant_m * math.cos(elevation_rad)]), np.array([bearing_rad]), np.ones(1), np.ones(1),
               np.array([slant_m * math.sin(elevation_rad)]))


def test_driving_up_to_a_feature_shortens_its_slant_range_by_the_step_and_keeps_its_elevation():
    moved = _one(SlantFeatures, 2.0, 0.0).shifted(np.array([0.5, 0.0]))
    assert isinstance(moved, SlantFeatures)
    assert moved.slant_m[0] == pytest.approx(1.5) and moved.bearing_rad[0] == pytest.approx(0.0)
    assert math.acos(moved.cos_elevation[0]) == pytest.approx(EL)
    # A fixed reflector keeps its height instead: it rises in the view as the radar nears it.
    fixed = _one(Features, 2.0, 0.0).shifted(np.array([0.5, 0.0]))
    assert fixed.height_m[0] == pytest.approx(1.0)
    assert fixed.range_m[0] == pytest.approx(2.0 * math.cos(EL) - 0.5)


def test_a_feature_beside_the_path_swings_by_its_slant_range_parallax():
    # 2 m to the left at 30 degrees of elevation, the radar 0.5 m on: the level point at 2 m swings
    # to atan2(2, -0.5); the fixed reflector, 1.73 m out horizontally, further.
    step = np.array([0.5, 0.0])
    slant = _one(SlantFeatures, 2.0, math.pi / 2).shifted(step)
    fixed = _one(Features, 2.0, math.pi / 2).shifted(step)
    assert slant.bearing_rad[0] == pytest.approx(math.atan2(2.0, -0.5))
    assert fixed.bearing_rad[0] == pytest.approx(math.atan2(2.0 * math.cos(EL), -0.5))
    assert slant.slant_m[0] == pytest.approx(math.hypot(2.0, 0.5))
    assert math.acos(slant.cos_elevation[0]) == pytest.approx(EL)


def test_level_features_move_alike_either_way_and_the_kind_survives_each_operation():
    rng = np.random.default_rng(3)
    r, b = rng.uniform(1, 5, 20), rng.uniform(-1, 1, 20)
    w = np.full(20, 0.05)
    level = [cls(r, b, w, w) for cls in (Features, SlantFeatures)]
    a, c = (f.turned(0.1).shifted(np.array([0.3, -0.1])) for f in level)
    np.testing.assert_allclose(a.xy, c.xy)
    high = SlantFeatures(r, b, w, w, 0.3 * r)
    for out in (high.turned(0.2), high.subset(r > 2.0), high.shifted(np.array([0.1, 0.0])), high.subset(r > 2.0)
                .turned(-0.1).shifted(np.array([0.0, 0.2]))):
        assert type(out) is SlantFeatures
        np.testing.assert_allclose(out.height_m / out.slant_m, 0.3 / math.hypot(1.0, 0.3))  # the angle kept


def _heatmap() -> RangeAzimuth:
    rng = np.random.default_rng(4)
    intensity = rng.exponential(1.0, (len(RANGE_M), len(AZIMUTH_RAD))).astype(np.float32)
    doppler = np.full(intensity.shape, np.nan, np.float32)
    elevation = np.full(intensity.shape, np.radians(10.0), np.float32)
    return RangeAzimuth(intensity, intensity, doppler, RANGE_M.copy(), AZIMUTH_RAD.copy(), elevation)


@pytest.mark.parametrize("parallax, kind", [("slant", SlantFeatures), ("horizontal", Features)])
def test_the_option_chooses_the_features_kind_once_at_extraction(parallax, kind):
    config = FeatureConfig(method="topk", k=30, peaks_only=False, subbin=False, parallax=parallax)
    features = extract(_heatmap(), config)
    assert type(features) is kind and features.height_m is not None
    ignored = extract(_heatmap(), dataclasses.replace(config, elevation="ignore"))
    assert ignored.height_m is None  # level: both kinds move alike
