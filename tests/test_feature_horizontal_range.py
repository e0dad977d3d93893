"""Features placed nearer than the region's range are dropped (docs/heading.md item 17).

With the heatmap's elevation used, a feature is placed at its horizontal range r cos(el): a
cell within the region's slant range whose elevation is steep (the floor beneath the radar, or
an elevation's noise) lands nearer the radar's axis than the region allows, where its bearing
would be swung by any error of a step's translation.  Such features are dropped (the others'
weights normalised again), unless fewer than three would be left.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from estimator_synth import AZIMUTH_RAD, RANGE_M
from radarodom.dsp.heatmap import RangeAzimuth
from radarodom.estimator.config import FeatureConfig
from radarodom.estimator.features import extract

CONFIG = FeatureConfig(method="topk", k=50, peaks_only=False, subbin=False, min_range_m=0.5)
NEAR = (RANGE_M >= 0.5) & (RANGE_M <= 1.0)
LEFT = np.arange(len(AZIMUTH_RAD)) < len(AZIMUTH_RAD) // 2


def _heatmap(elevation_deg: np.ndarray) -> RangeAzimuth:
    """Random cells, the strongest (by 100 times) 0.5-1 m from the radar, at *elevation_deg*
    (n_range, n_azimuth)."""
    rng = np.random.default_rng(4)
    intensity = rng.exponential(1.0, (len(RANGE_M), len(AZIMUTH_RAD))).astype(np.float32)
    intensity[NEAR] *= 100.0
    doppler = np.full(intensity.shape, np.nan, np.float32)
    return RangeAzimuth(intensity, intensity, doppler, RANGE_M.copy(), AZIMUTH_RAD.copy(),
                        np.radians(elevation_deg).astype(np.float32))


def _elevation(near_left_deg: float) -> np.ndarray:
    """Level everywhere but the near cells of the left half of the azimuth bins."""
    elevation = np.zeros((len(RANGE_M), len(AZIMUTH_RAD)))
    elevation[np.ix_(NEAR, LEFT)] = near_left_deg
    return elevation


def test_features_placed_nearer_than_the_region_are_dropped():
    level = extract(_heatmap(_elevation(0.0)), CONFIG)
    assert len(level) == CONFIG.k and level.range_m.max() <= 1.0 + 1e-9  # the near cells
    # At 70 degrees the left half's near cells lie 0.17-0.34 m from the radar's axis.
    steep = extract(_heatmap(_elevation(-70.0)), CONFIG)
    assert steep.range_m.min() >= CONFIG.min_range_m
    dropped = np.count_nonzero(level.bearing_rad > 0)  # the left half's (bearing = -azimuth)
    assert 0 < dropped < CONFIG.k
    assert len(steep) == CONFIG.k - dropped
    kept = level.bearing_rad < 0
    np.testing.assert_allclose(np.sort(steep.intensity), np.sort(level.intensity[kept]))
    # Each kept feature's weight is its weight among the k, normalised again.
    order, level_order = np.argsort(steep.intensity), np.argsort(level.intensity[kept])
    np.testing.assert_allclose(steep.weight[order], level.weight[kept][level_order] / level.weight[kept].sum())


def test_a_moderate_elevation_places_the_cells_and_drops_only_those_it_brings_inside():
    level = extract(_heatmap(_elevation(0.0)), CONFIG)
    features = extract(_heatmap(_elevation(-30.0)), CONFIG)
    # The left half's near cells at 30 degrees lie at r cos(30) = 0.43-0.87 m: those under 0.5 m
    # (slant 0.5-0.55 m) are dropped, the others placed there, at their height.
    cos30 = math.cos(math.radians(30.0))
    left = level.bearing_rad > 0
    inside = ~left | (level.range_m * cos30 >= CONFIG.min_range_m)
    assert 0 < np.count_nonzero(~inside) and len(features) == np.count_nonzero(inside)
    placed = features.height_m < -0.1
    np.testing.assert_allclose(np.sort(features.range_m[placed]), np.sort(level.range_m[left & inside] * cos30))
    np.testing.assert_allclose(features.height_m[placed], -features.range_m[placed] * math.tan(math.radians(30.0)))


@pytest.mark.parametrize("left, kept", [(2, 50), (3, 3)])
def test_fewer_than_three_left_keeps_them_all(left, kept):
    # Every near cell steep but *left* of them level: those alone would be left.
    elevation = np.zeros((len(RANGE_M), len(AZIMUTH_RAD)))
    elevation[NEAR] = -70.0
    rows = np.flatnonzero(NEAR)
    middle = slice(len(AZIMUTH_RAD) // 2, len(AZIMUTH_RAD) // 2 + left)  # near boresight
    elevation[rows[-1], middle] = 0.0
    heatmap = _heatmap(elevation)
    heatmap.intensity[rows[-1], middle] *= 1000.0  # among the k strongest
    features = extract(heatmap, CONFIG)
    assert len(features) == kept
    if kept == 3:
        np.testing.assert_allclose(features.range_m, RANGE_M[rows[-1]])


def test_a_frame_of_only_such_features_keeps_them():
    elevation = np.zeros((len(RANGE_M), len(AZIMUTH_RAD)))
    elevation[NEAR] = -70.0
    features = extract(_heatmap(elevation), CONFIG)
    assert len(features) == CONFIG.k and features.range_m.max() < CONFIG.min_range_m


def test_without_the_elevation_the_slant_range_is_the_region():
    features = extract(_heatmap(_elevation(-70.0)), dataclasses.replace(CONFIG, elevation="ignore"))
    assert features.height_m is None
    assert len(features) == CONFIG.k and features.range_m.max() <= 1.0 + 1e-9
