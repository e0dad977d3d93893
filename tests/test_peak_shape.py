"""The field's points weighed by how like one reflector's their azimuth peak is
(``icp.field_shape_width``, estimator/peak_shape.py; docs/heading.md item 22).

A reflector alone in its range bin draws the array's beam: its peak's log power curves the same
wherever it lies between bins, and a cell on its flank climbs to it.  Two scatterers sharing a beam
interfere into a peak broader or sharper than the beam, and their cells lose weight in the field.
"""

from __future__ import annotations

import dataclasses
import math

import estimator_synth as synth
import numpy as np
import pytest
from radarodom.dsp.heatmap import RangeAzimuth
from radarodom.errors import ConfigError
from radarodom.estimator.config import EstimatorConfig, FeatureConfig
from radarodom.estimator.features import Features, SlantFeatures, _top_k, extract, roi_mask
from radarodom.estimator.peak_shape import cells_of, peak_curvature, shape_weighted
from radarodom.estimator.yaw_measurement import CurrentFrame, YawMeasurement

SINES = np.sin(synth.AZIMUTH_RAD)
BIN = SINES[1] - SINES[0]  # the azimuth bins' spacing in sin(azimuth)


def beam(sine: float, amplitude: complex = 1.0) -> np.ndarray:
    """The complex response (n_az,) of the 8-element row to a reflector at *sine* (TI azimuth)."""
    h = np.arange(synth.N_ELEMENTS)
    return amplitude * np.exp(1j * np.pi * h[None, :] * (SINES[:, None] - sine)).sum(axis=1) / synth.N_ELEMENTS


def heatmap_of(rows: dict[int, np.ndarray], noise: float = 1e-6) -> RangeAzimuth:
    """A heatmap whose range bins *rows* hold these complex azimuth responses, the rest noise."""
    intensity = np.full((len(synth.RANGE_M), len(SINES)), noise)
    for r, response in rows.items():
        intensity[r] += np.abs(response) ** 2
    intensity = intensity.astype(np.float32)
    return RangeAzimuth(intensity, intensity.copy(), np.full(intensity.shape, np.nan, np.float32),
                        synth.RANGE_M.copy(), synth.AZIMUTH_RAD.copy())


def test_each_feature_is_found_at_its_own_cell_unless_its_bearing_was_clipped():
    world = np.array([(2.0, 0.5), (3.5, -1.0), (5.0, 2.0), (1.5, -0.3), (6.0, 0.0), (2.0, 2.4), (3.0, -3.0)])
    plain = synth.heatmap(world, np.array([1.0, 0.8, 0.6, 0.9, 0.5, 0.7, 0.6]), rng=np.random.default_rng(1))
    shape = plain.intensity.shape
    noisy = np.random.default_rng(2).uniform(-0.5, 0.5, shape).astype(np.float32)
    steep = np.full(shape, 0.9, np.float32)  # cos 0.62: a cell beyond 38 degrees has no level bearing
    for elevation_rad in (None, noisy, steep):
        hm = dataclasses.replace(plain, elevation_rad=elevation_rad)
        config = FeatureConfig(method="topk", k=60, peaks_only=False, subbin=False,
                               elevation="ignore" if elevation_rad is None else "use", min_range_m=0.0,
                               max_azimuth_rad=math.radians(85.0))
        features = extract(hm, config)
        ri, ai = _top_k(hm.intensity, roi_mask(hm, config) & (hm.intensity > 0), 60)  # extract's cells, in order
        rows, cols, known = cells_of(features, hm)
        cos_el = 1.0 if elevation_rad is None else np.cos(elevation_rad[ri, ai])
        clipped = np.abs(np.sin(hm.azimuth_rad[ai])) >= cos_el - 1e-6
        np.testing.assert_array_equal(known, ~clipped)
        np.testing.assert_array_equal(rows[known], ri[known])
        np.testing.assert_array_equal(cols[known], ai[known])
        assert clipped.any() == (elevation_rad is steep)


@pytest.mark.parametrize("offset", [0.0, 0.2, 0.5, 0.8])
def test_one_reflectors_peak_curves_as_the_beam_wherever_it_lies_and_its_flank_climbs_to_it(offset):
    centre = 0.3 / BIN  # about 17 degrees to the right of boresight, then off by a part of a bin
    sine = SINES[int(round(centre)) + 32] + offset * BIN
    hm = heatmap_of({40: beam(sine)})
    peak = int(np.argmax(hm.intensity[40]))
    cols = np.arange(peak - 3, peak + 4)
    curvature = peak_curvature(hm.intensity, np.full(len(cols), 40), cols)
    np.testing.assert_allclose(curvature, curvature[3])  # the flank climbs to the peak
    at_centre = peak_curvature(heatmap_of({40: beam(SINES[42])}).intensity, np.array([40]), np.array([42]))[0]
    assert curvature[3] < 0 and curvature[3] == pytest.approx(at_centre, rel=0.01)


@pytest.mark.parametrize("phase, apart", [(0.0, 0.6), (math.pi, 0.6), (math.pi / 2, 1.0), (0.0, 1.0)])
def test_two_reflectors_sharing_a_beam_peak_unlike_one(phase, apart):
    # The beam's null-to-null width is 2 / 8 in sin(azimuth); these two lie *apart* of it apart.
    # Not every pair shows: two within a fifth of the beam (unless in antiphase), or in quadrature
    # within half of it, peak nearly as one does, and between them (docs/heading.md item 22).
    sine = SINES[40]
    pair = beam(sine) + beam(sine + apart * 0.25, np.exp(1j * phase))
    single = peak_curvature(heatmap_of({40: beam(sine)}).intensity, np.array([40]), np.array([40]))[0]
    hm = heatmap_of({40: pair})
    peak = int(np.argmax(hm.intensity[40]))
    q = peak_curvature(hm.intensity, np.array([40]), np.array([peak]))[0] / single
    assert abs(q - 1.0) > 0.3


def _points_at(hm: RangeAzimuth, cells: list[tuple[int, int]]) -> Features:
    rows = np.array([c[0] for c in cells])
    cols = np.array([c[1] for c in cells])
    return SlantFeatures(hm.range_m[rows], -hm.azimuth_rad[cols], np.full(len(cells), 1.0 / len(cells)),
                         hm.intensity[rows, cols].astype(float))


def test_the_cells_of_a_pair_sharing_a_beam_lose_weight_and_lone_reflectors_keep_theirs():
    lone = {r: beam(SINES[c] + 0.3 * BIN) for r, c in ((30, 20), (50, 28), (70, 36), (90, 44), (110, 30))}
    pair = beam(SINES[38]) + beam(SINES[38] + 0.15, np.exp(1j * 0.3))
    hm = heatmap_of({**lone, 130: pair})
    cells = [(r, int(np.argmax(hm.intensity[r]))) for r in sorted(lone)] + [(130, int(np.argmax(hm.intensity[130])))]
    cells += [(130, cells[-1][1] + 1)]  # the pair's flank: weighed as its peak
    points = _points_at(hm, cells)
    weighed = shape_weighted(points, hm, width=0.3, floor=0.3)
    assert type(weighed) is SlantFeatures and weighed.weight.sum() == pytest.approx(1.0)
    lone_w, pair_w = weighed.weight[:5], weighed.weight[5:]
    assert np.ptp(lone_w) < 0.05 * lone_w.mean()  # alike
    assert pair_w[0] == pytest.approx(pair_w[1])
    assert 0.3 * lone_w.mean() <= pair_w[0] < 0.5 * lone_w.mean()  # never below the floor's share
    np.testing.assert_array_equal(weighed.range_m, points.range_m)
    np.testing.assert_array_equal(weighed.bearing_rad, points.bearing_rad)


def test_a_peak_that_cannot_be_read_counts_as_unlike_one():
    lone = {r: beam(SINES[c] + 0.3 * BIN) for r, c in ((30, 20), (50, 28), (70, 36), (90, 44))}
    hm = heatmap_of(lone)
    cells = [(r, int(np.argmax(hm.intensity[r]))) for r in sorted(lone)]
    hm.intensity[90, cells[-1][1] - 1] = np.nan  # beside the last one's peak
    points = _points_at(hm, cells)
    weighed = shape_weighted(points, hm, width=0.3, floor=0.3)
    assert np.all(np.isfinite(weighed.weight)) and weighed.weight.sum() == pytest.approx(1.0)
    assert weighed.weight[3] == pytest.approx(0.3 * weighed.weight[0], rel=0.02)
    # A point at the radar has no cell: the floor too.
    at_radar = SlantFeatures(np.append(points.range_m[:3], 0.0), np.append(points.bearing_rad[:3], 0.0),
                             np.full(4, 0.25), np.ones(4))
    assert shape_weighted(at_radar, heatmap_of(lone), 0.3, 0.3).weight[3] == pytest.approx(
        0.3 * shape_weighted(at_radar, heatmap_of(lone), 0.3, 0.3).weight[0], rel=0.02)


def test_too_few_points_or_peaks_are_left_as_they_are():
    hm = heatmap_of({40: beam(SINES[30]), 60: beam(SINES[35])})
    two = _points_at(hm, [(40, 30), (60, 35)])
    assert shape_weighted(two, hm, 0.3, 0.3) is two
    flat = heatmap_of({})  # noise alone, flat: no cell is a peak
    three = _points_at(flat, [(40, 30), (60, 35), (80, 20)])
    assert shape_weighted(three, flat, 0.3, 0.3) is three
    narrow = dataclasses.replace(hm, intensity=hm.intensity[:, 30:32], azimuth_rad=hm.azimuth_rad[30:32])
    few_bins = _points_at(narrow, [(40, 0), (60, 1), (80, 0)])
    assert shape_weighted(few_bins, narrow, 0.3, 0.3) is few_bins


def test_the_field_keeps_weighed_points_and_the_option_turns_it_off():
    world = np.array([(2.0, 0.5), (3.5, -1.0), (5.0, 2.0), (4.0, 0.0), (6.0, -2.0)])
    hm = synth.heatmap(world, 1.0)
    kept = {}
    for width in (0.3, None):
        cfg = EstimatorConfig().with_(icp={"field_shape_width": width})
        kept[width] = YawMeasurement(cfg, math.radians(0.25)).keep(CurrentFrame(0.0, hm, cfg), None)
    on, off = kept[0.3].field.points, kept[None].field.points
    np.testing.assert_array_equal(on.range_m, off.range_m)
    np.testing.assert_array_equal(kept[None].guide.weight, off.weight)  # off: the scan's own weights
    assert on.weight.sum() == pytest.approx(1.0) and not np.array_equal(on.weight, off.weight)


@pytest.mark.parametrize("fields", [{"field_shape_width": 0.0}, {"field_shape_width": math.inf},
                                    {"field_shape_floor": -0.1}, {"field_shape_floor": 1.5}])
def test_a_bad_setting_is_refused_by_name(fields):
    with pytest.raises(ConfigError, match=next(iter(fields))):
        EstimatorConfig().with_(icp=fields)
