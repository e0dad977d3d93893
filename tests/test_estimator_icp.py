"""Heatmap features (paper III-B; estimator/features.py) and rotation-only weighted ICP
(paper eqs. 4-6; estimator/icp.py) on synthetic heatmaps and feature sets.

Heatmaps are point reflectors seen through the AWR1843's 8-element azimuth array and a
Hann-windowed range FFT (tests/estimator_synth.py), in the TI sensor frame; features
come out in the body frame (bearing = -azimuth).  Registration convention: ``y = R x``,
source x onto target y, so a scene that turned by +a in the body frame (the sensor turned
by -a) registers as rotation +a.
"""

from __future__ import annotations

import math

import estimator_synth as synth
import numpy as np
import pytest
import scipy.ndimage
from estimator_synth import AZIMUTH_RAD, RANGE_M, heatmap, rot
from hypothesis import given, settings
from hypothesis import strategies as st
from radarodom.dsp.heatmap import RangeAzimuth
from radarodom.estimator import icp
from radarodom.estimator.config import FeatureConfig, IcpConfig
from radarodom.estimator.features import Features, extract, roi_mask, static_mask
from radarodom.estimator.icp import (
    Region,
    register_rotation,
    register_two_way,
    rotation_svd,
)

DEG = math.radians(1.0)


def polar_xy(r, b) -> np.ndarray:
    r, b = np.asarray(r, float), np.asarray(b, float)
    return np.column_stack([r * np.cos(b), r * np.sin(b)])


def random_heatmap(seed: int, doppler=None) -> RangeAzimuth:
    rng = np.random.default_rng(seed)
    intensity = rng.exponential(1.0, (len(RANGE_M), len(AZIMUTH_RAD))).astype(np.float32)
    dop = np.full(intensity.shape, np.nan, np.float32) if doppler is None else doppler
    return RangeAzimuth(intensity, intensity, dop, RANGE_M.copy(), AZIMUTH_RAD.copy())


def feats(r, b, w=None) -> Features:
    r, b = np.asarray(r, float), np.asarray(b, float)
    w = np.ones(len(r)) if w is None else np.asarray(w, float)
    return Features(r, b, w / w.sum(), w)


def sparse_scene(seed: int, n: int = 14) -> Features:
    """Well separated point features: one per 8 degrees of bearing, ranges 2..10 m."""
    rng = np.random.default_rng(seed)
    b = np.radians(np.linspace(-52.0, 52.0, n)) + rng.uniform(-2, 2, n) * DEG
    return feats(rng.uniform(2.0, 10.0, n), b, rng.uniform(0.5, 2.0, n))


def rotated(f: Features, angle: float) -> Features:
    return Features(f.range_m.copy(), f.bearing_rad + angle, f.weight.copy(), f.intensity.copy())


# =========================================================================== features
class TestTopK:
    def test_k_largest_cells_inside_roi(self):
        hm = random_heatmap(0)
        cfg = FeatureConfig(method="topk", k=150, peaks_only=False, subbin=False, max_range_m=9.0)
        f = extract(hm, cfg)
        assert len(f) == 150
        valid = roi_mask(hm, cfg)
        expected = np.sort(hm.intensity[valid])[::-1][:150]
        np.testing.assert_allclose(np.sort(f.intensity)[::-1], expected)
        # ... and they are those cells: each feature's intensity is the heatmap's at its cell.
        ri = np.searchsorted(RANGE_M, f.range_m - 1e-9)
        ai = np.searchsorted(-AZIMUTH_RAD[::-1], f.bearing_rad - 1e-9)
        ai = len(AZIMUTH_RAD) - 1 - ai
        np.testing.assert_allclose(RANGE_M[ri], f.range_m)
        np.testing.assert_allclose(-AZIMUTH_RAD[ai], f.bearing_rad)
        np.testing.assert_allclose(hm.intensity[ri, ai], f.intensity)
        assert valid[ri, ai].all()

    def test_k_larger_than_roi_gives_every_cell(self):
        hm = random_heatmap(1)
        cfg = FeatureConfig(method="topk", k=100000, peaks_only=False, subbin=False,
                            min_range_m=5.0, max_range_m=6.0, max_azimuth_rad=math.radians(20.0))
        f = extract(hm, cfg)
        assert len(f) == int(roi_mask(hm, cfg).sum()) > 0

    def test_strongest_of_few_valid_cells_in_raster_order(self):
        # As with peaks_only, most cells invalid: the k strongest valid cells that a full sort
        # finds, in raster order (range bin, then azimuth bin); all of them when fewer than k.
        from radarodom.estimator.features import _top_k

        rng = np.random.default_rng(3)
        intensity = rng.random((64, 32)).astype(np.float32)
        valid = rng.random((64, 32)) < 0.05
        cells = np.flatnonzero(valid)
        expected = np.sort(cells[np.argsort(intensity.ravel()[cells])[-20:]])
        np.testing.assert_array_equal(np.ravel_multi_index(_top_k(intensity, valid, 20), intensity.shape), expected)
        np.testing.assert_array_equal(np.ravel_multi_index(_top_k(intensity, valid, 10000), intensity.shape), cells)
        assert all(len(i) == 0 for i in _top_k(intensity, np.zeros_like(valid), 20))

    def test_default_k_is_200(self):
        assert FeatureConfig().k == 200
        f = extract(random_heatmap(2), FeatureConfig(method="topk", peaks_only=False))
        assert len(f) == 200


class TestRayMax:
    def test_one_per_ray_inside_roi(self):
        hm = random_heatmap(3)
        cfg = FeatureConfig(method="raymax", peaks_only=False, subbin=False, min_range_m=1.0,
                            max_range_m=8.0, max_azimuth_rad=math.radians(50.0))
        f = extract(hm, cfg)
        rays = np.flatnonzero(np.abs(AZIMUTH_RAD) <= cfg.max_azimuth_rad)
        assert len(f) == len(rays)
        np.testing.assert_allclose(np.sort(f.bearing_rad), np.sort(-AZIMUTH_RAD[rays]))
        rows = (RANGE_M >= 1.0) & (RANGE_M <= 8.0)
        for a in rays:
            got = f.intensity[np.isclose(f.bearing_rad, -AZIMUTH_RAD[a])]
            assert got == pytest.approx(hm.intensity[rows, a].max())

    def test_strongest_reflector_of_each_ray(self):
        # Two reflectors on different rays: those rays' features are at the reflectors.
        xy = polar_xy([3.0, 7.0], np.radians([20.0, -35.0]))
        hm = heatmap(xy, [1.0, 1.0], noise=1e-6)
        f = extract(hm, FeatureConfig(method="raymax", peaks_only=False, subbin=False))
        for r, b in zip([3.0, 7.0], np.radians([20.0, -35.0])):
            ray = np.argmin(np.abs(f.bearing_rad - b))
            assert f.range_m[ray] == pytest.approx(r, abs=0.05)


class TestCfar:
    def test_finds_isolated_strong_reflectors(self):
        rng = np.random.default_rng(4)
        truth_r, truth_b = np.array([2.5, 5.0, 8.5]), np.radians([-30.0, 10.0, 40.0])
        hm = heatmap(polar_xy(truth_r, truth_b), [1.0, 0.5, 2.0], noise=1e-4, rng=rng)
        f = extract(hm, FeatureConfig(method="cfar", peaks_only=False, subbin=False))
        assert len(f) > 0
        for r, b in zip(truth_r, truth_b):
            near = (np.abs(f.range_m - r) <= 0.1) & (np.abs(f.bearing_rad - b) <= 3 * DEG)
            assert near.any(), (r, math.degrees(b))
        # The strongest feature is a reflector, not noise.
        best = np.argmax(f.weight)
        d = np.min(np.hypot(f.range_m[best] - truth_r, (f.bearing_rad[best] - truth_b) / DEG * 0.05))
        assert d < 0.2

    def test_nothing_in_pure_noise(self):
        hm = heatmap(np.zeros((0, 2)), noise=1.0, rng=np.random.default_rng(5))
        f = extract(hm, FeatureConfig(method="cfar", peaks_only=False, subbin=False,
                                      cfar=FeatureConfig().cfar))
        # 10 dB over a 16-cell CA estimate in exponential noise: a few false alarms at most.
        assert len(f) < 0.005 * hm.intensity.size

    @pytest.mark.xfail(strict=True, reason="LIMITATION of the paper's setting: CFAR (both passes) keeps "
                       "each reflector's whole main lobe (~37 cells for 8 elements), and ICP from a zero "
                       "guess on such blobs locks near zero (0.4 deg for 3); peaks_only and the scan "
                       "guess, the defaults, are what fixes it")
    def test_cfar_features_register_a_rotation(self):
        rng = np.random.default_rng(6)
        n = 12
        r = rng.uniform(2, 10, n)
        b = np.radians(np.linspace(-50, 50, n))
        cfg = FeatureConfig(method="cfar", peaks_only=False, subbin=False)
        a = extract(heatmap(polar_xy(r, b), 1.0, noise=1e-4), cfg)
        c = extract(heatmap(polar_xy(r, b + 3 * DEG), 1.0, noise=1e-4), cfg)
        assert len(a) < 50 * n  # detections near the reflectors (main lobes), not on every ray
        reg, _ = register_two_way(a, c, IcpConfig())
        assert abs(reg.rotation_rad - 3 * DEG) < 0.5 * DEG


class TestCommon:
    @pytest.mark.parametrize("method", ["topk", "raymax", "cfar"])
    def test_bearings_are_body_frame(self, method):
        # A reflector 30 degrees to the left: TI azimuth -30, body bearing +30.
        xy = polar_xy([4.0], [math.radians(30.0)])
        hm = heatmap(xy, 1.0, noise=1e-6)
        f = extract(hm, FeatureConfig(method=method, k=1, peaks_only=False, subbin=False))
        best = np.argmax(f.intensity)
        assert f.bearing_rad[best] == pytest.approx(math.radians(30.0), abs=1.5 * DEG)
        assert f.range_m[best] == pytest.approx(4.0, abs=0.05)
        np.testing.assert_allclose(f.xy[best], xy[0], atol=0.15)

    @pytest.mark.parametrize("method", ["topk", "raymax", "cfar"])
    @pytest.mark.parametrize("weighting", ["linear", "db"])
    def test_weights_sum_to_one(self, method, weighting):
        rng = np.random.default_rng(7)
        xy = polar_xy(rng.uniform(1, 10, 10), rng.uniform(-1, 1, 10))
        hm = heatmap(xy, rng.uniform(0.5, 2, 10), noise=1e-3, rng=rng)
        f = extract(hm, FeatureConfig(method=method, weighting=weighting))
        assert len(f) > 0
        assert f.weight.sum() == pytest.approx(1.0)
        assert np.all(f.weight > 0) and np.all(np.isfinite(f.weight))
        # Stronger cells weigh more.
        order = np.argsort(f.intensity)
        assert np.all(np.diff(f.weight[order]) >= -1e-12)
        if weighting == "linear":
            np.testing.assert_allclose(f.weight, f.intensity / f.intensity.sum(), rtol=1e-6)

    @pytest.mark.parametrize("method", ["topk", "raymax", "cfar"])
    @pytest.mark.parametrize("subbin", [False, True])
    def test_roi_limits(self, method, subbin):
        rng = np.random.default_rng(8)
        n = 40
        xy = polar_xy(rng.uniform(0.2, 12.5, n), np.radians(rng.uniform(-85, 85, n)))
        hm = heatmap(xy, rng.uniform(0.5, 2, n), noise=1e-3, rng=rng)
        cfg = FeatureConfig(method=method, min_range_m=2.0, max_range_m=7.0,
                            max_azimuth_rad=math.radians(40.0), subbin=subbin)
        f = extract(hm, cfg)
        assert len(f) > 0
        slack_r = 0.05 if subbin else 1e-9  # a sub-bin position may move half a bin
        slack_b = 2 * DEG if subbin else 1e-9
        assert np.all(f.range_m >= 2.0 - slack_r) and np.all(f.range_m <= 7.0 + slack_r)
        assert np.all(np.abs(f.bearing_rad) <= math.radians(40.0) + slack_b)

    def test_strong_reflectors_outside_the_range_limits_are_not_features(self):
        xy = polar_xy([0.3, 10.0, 6.0], np.radians([0.0, 10.0, 10.0]))
        hm = heatmap(xy, [100.0, 100.0, 1.0], noise=1e-6)
        for method in ("topk", "raymax"):
            f = extract(hm, FeatureConfig(method=method, k=1, peaks_only=False, subbin=False,
                                          min_range_m=0.5, max_range_m=8.0))
            best = np.argmax(f.intensity)
            assert f.range_m[best] == pytest.approx(6.0, abs=0.05)
            assert f.bearing_rad[best] == pytest.approx(math.radians(10.0), abs=1.5 * DEG)

    def test_peaks_only_keeps_local_maxima(self):
        rng = np.random.default_rng(9)
        xy = polar_xy(rng.uniform(1, 10, 8), rng.uniform(-1, 1, 8))
        hm = heatmap(xy, 1.0, noise=1e-3, rng=rng)
        f = extract(hm, FeatureConfig(method="topk", k=50, peaks_only=True, subbin=False))
        local_max = hm.intensity >= scipy.ndimage.maximum_filter(hm.intensity, size=3, mode="nearest")
        ri = np.rint(f.range_m / 0.05).astype(int)
        ai = np.array([np.argmin(np.abs(-AZIMUTH_RAD - b)) for b in f.bearing_rad])
        assert local_max[ri, ai].all()
        dense = extract(hm, FeatureConfig(method="topk", k=50, peaks_only=False, subbin=False))
        ri2 = np.rint(dense.range_m / 0.05).astype(int)
        ai2 = np.array([np.argmin(np.abs(-AZIMUTH_RAD - b)) for b in dense.bearing_rad])
        assert not local_max[ri2, ai2].all()  # without the option, blobs give many cells

    @pytest.mark.parametrize("shape", [(256, 64), (5, 3), (2, 2), (1, 7), (7, 1), (1, 1)])
    def test_neighbourhood_max_is_scipys_maximum_filter(self, shape):
        # The peaks' fast 3 x 3 maximum, on continuous values and on plateaus (ties), at the
        # edges and on maps too thin to have neighbours on one axis.
        from radarodom.estimator.features import _neighbourhood_max

        rng = np.random.default_rng(12)
        for a in (rng.standard_normal(shape), rng.integers(0, 3, shape)):
            a = a.astype(np.float32)
            expected = scipy.ndimage.maximum_filter(a, size=3, mode="nearest")
            got = _neighbourhood_max(a)
            assert got.dtype == expected.dtype
            np.testing.assert_array_equal(got, expected)

    @pytest.mark.parametrize("bearing_deg,range_m", [(0.9, 3.025), (-12.2, 6.513), (30.1, 4.04),
                                                     (-47.7, 8.77), (5.3, 2.2)])
    def test_subbin_moves_features_toward_the_truth(self, bearing_deg, range_m):
        xy = polar_xy([range_m], [math.radians(bearing_deg)])
        hm = heatmap(xy, 1.0, noise=1e-6)
        centre = extract(hm, FeatureConfig(method="topk", k=1, peaks_only=True, subbin=False))
        sub = extract(hm, FeatureConfig(method="topk", k=1, peaks_only=True, subbin=True))
        b_err_centre = abs(centre.bearing_rad[0] - math.radians(bearing_deg))
        b_err_sub = abs(sub.bearing_rad[0] - math.radians(bearing_deg))
        assert b_err_sub < b_err_centre
        assert b_err_sub < 0.2 * DEG
        assert abs(sub.range_m[0] - range_m) < max(abs(centre.range_m[0] - range_m), 0.005)
        assert abs(sub.range_m[0] - range_m) < 0.01

    def test_subbin_at_bin_centre_stays(self):
        b = -AZIMUTH_RAD[40]
        xy = polar_xy([RANGE_M[100]], [b])
        f = extract(heatmap(xy, 1.0, noise=1e-6), FeatureConfig(method="topk", k=1, subbin=True))
        assert f.bearing_rad[0] == pytest.approx(b, abs=1e-4)
        assert f.range_m[0] == pytest.approx(RANGE_M[100], abs=1e-4)

    def test_shape_mismatch_raises(self):
        hm = random_heatmap(10)
        bad = RangeAzimuth(hm.intensity[:, :10], hm.static, hm.doppler_mps, hm.range_m, hm.azimuth_rad)
        with pytest.raises(ValueError):
            extract(bad, FeatureConfig())

    @pytest.mark.parametrize("method", ["topk", "raymax"])
    def test_empty_heatmap_gives_no_features(self, method):
        z = np.zeros((len(RANGE_M), len(AZIMUTH_RAD)), np.float32)
        hm = RangeAzimuth(z, z, np.full_like(z, np.nan), RANGE_M.copy(), AZIMUTH_RAD.copy())
        assert len(extract(hm, FeatureConfig(method=method))) == 0

    def test_input_heatmap_not_modified(self):
        hm = random_heatmap(11)
        before = hm.intensity.copy()
        extract(hm, FeatureConfig(subbin=True, peaks_only=True))
        np.testing.assert_array_equal(hm.intensity, before)


class TestDynamicRejection:
    def scene(self):
        """Static reflectors seen moving forward at 1 m/s, one car approaching fast, and one
        strong reflector whose Doppler is unknown (NaN)."""
        v = (1.0, 0.0)
        r = np.array([3.0, 6.0, 9.0, 5.0, 7.5])
        b = np.radians([-40.0, 0.0, 35.0, -10.0, 20.0])
        static_vr = -(v[0] * np.cos(b) + v[1] * np.sin(b))
        vr = static_vr.copy()
        vr[3] = -4.0  # the car (index 3)
        hm = heatmap(polar_xy(r, b), [1.0, 1.0, 1.0, 5.0, 3.0], radial_velocity=vr, noise=1e-5)
        # The last reflector's cells: Doppler unknown.
        near = np.abs(RANGE_M[:, None] - r[4]) < 0.2
        near = near & (np.abs(-AZIMUTH_RAD[None, :] - b[4]) < 8 * DEG)
        hm.doppler_mps[near] = np.nan
        return hm, v, r, b

    def test_static_mask_sign_convention(self):
        hm, v, _, _ = self.scene()
        m = static_mask(hm, np.array(v), 0.15)
        # Ahead, a static cell seen while moving forward approaches: doppler -1.
        ahead = np.argmin(np.abs(AZIMUTH_RAD))
        row = np.rint(6.0 / 0.05).astype(int)
        assert hm.doppler_mps[row, ahead] == pytest.approx(-1.0, abs=1e-6)
        assert m[row, ahead]
        assert not static_mask(hm, np.array([-1.0, 0.0]), 0.15)[row, ahead]

    def test_moving_cells_dropped_nan_kept(self):
        hm, v, r, b = self.scene()
        cfg = FeatureConfig(method="topk", k=5, peaks_only=True, subbin=False, dynamic_rejection_mps=0.15)
        kept = extract(hm, cfg, np.array(v))
        near = lambda f, i: np.any((np.abs(f.range_m - r[i]) < 0.1) & (np.abs(f.bearing_rad - b[i]) < 3 * DEG))
        assert not near(kept, 3), "the car is a feature"
        assert near(kept, 4), "the NaN-Doppler reflector was dropped"
        for i in (0, 1, 2):
            assert near(kept, i)
        # Off (config) or without a velocity: the car is the strongest feature.
        off = FeatureConfig(method="topk", k=5, peaks_only=True, subbin=False, dynamic_rejection_mps=None)
        for f in (extract(hm, off, np.array(v)),
                  extract(hm, cfg)):
            assert near(f, 3)

    def test_wrong_velocity_rejects_the_static_world(self):
        hm, _, r, b = self.scene()
        cfg = FeatureConfig(method="topk", k=5, peaks_only=True, subbin=False, dynamic_rejection_mps=0.15)
        f = extract(hm, cfg, np.array([-1.0, 0.0]))
        for i in (0, 1, 2):
            assert not np.any((np.abs(f.range_m - r[i]) < 0.1) & (np.abs(f.bearing_rad - b[i]) < 3 * DEG))


class TestFeaturesObject:
    def test_xy_and_from_xy(self):
        f = feats([1.0, 2.0, 3.0], np.radians([0.0, 90.0, -45.0]))
        np.testing.assert_allclose(f.xy, [[1, 0], [0, 2], [3 / math.sqrt(2), -3 / math.sqrt(2)]], atol=1e-12)
        g = Features.from_xy(f.xy, f.weight, f.intensity)
        np.testing.assert_allclose(g.range_m, f.range_m)
        np.testing.assert_allclose(g.bearing_rad, f.bearing_rad, atol=1e-12)
        mine = np.array([[1.0, 1.0], [2.0, -1.0]])
        Features.from_xy(mine, np.ones(2), np.ones(2))
        mine[0, 0] = 5.0  # the caller's array stays the caller's

    def test_shifted_is_p_minus_dxy(self):
        rng = np.random.default_rng(12)
        f = feats(rng.uniform(1, 10, 20), rng.uniform(-1, 1, 20), rng.uniform(0.1, 1, 20))
        dxy = np.array([0.1, -0.03])
        g = f.shifted(dxy)
        np.testing.assert_allclose(g.xy, f.xy - dxy, atol=1e-12)
        np.testing.assert_array_equal(g.weight, f.weight)
        np.testing.assert_array_equal(g.intensity, f.intensity)
        # Moving forward brings the world closer.
        assert np.all(f.shifted([0.2, 0.0]).range_m[np.abs(f.bearing_rad) < 0.5] < f.range_m[np.abs(f.bearing_rad) < 0.5])
        assert len(g) == 20


# =========================================================================== ICP
class TestRotationSvd:
    @settings(max_examples=50)
    @given(angle=st.floats(-math.pi + 1e-6, math.pi - 1e-6), n=st.integers(2, 40), seed=st.integers(0, 2 ** 16))
    def test_recovers_exact_rotation(self, angle, n, seed):
        rng = np.random.default_rng(seed)
        x = rng.uniform(-10, 10, (n, 2))
        w = rng.uniform(0.01, 1.0, n)
        y = x @ rot(angle).T
        if np.linalg.matrix_rank(x) < 1 or np.min(np.hypot(*x.T)) < 1e-3:
            return
        got = rotation_svd(x, y, w)
        assert abs(icp.wrap(got - angle)) < 1e-7

    @settings(max_examples=50)
    @given(n=st.integers(3, 30), seed=st.integers(0, 2 ** 16))
    def test_equals_closed_form(self, n, seed):
        rng = np.random.default_rng(seed)
        x = rng.uniform(-5, 5, (n, 2))
        y = x @ rot(rng.uniform(-0.5, 0.5)).T + 0.3 * rng.standard_normal((n, 2))
        w = rng.uniform(0.01, 1.0, n)
        closed = math.atan2(np.sum(w * (x[:, 0] * y[:, 1] - x[:, 1] * y[:, 0])), np.sum(w * np.sum(x * y, 1)))
        assert abs(icp.wrap(rotation_svd(x, y, w) - closed)) < 1e-9
        # The ICP loop's closed form is the SVD solution.
        assert abs(icp.wrap(rotation_svd(x, y, w) - icp.rotation_2d(x, y, w))) < 1e-9

    def test_weights_matter(self):
        x = np.array([[1.0, 0.0], [0.0, 1.0]])
        y = np.array([rot(0.1) @ x[0], rot(-0.1) @ x[1]])
        assert rotation_svd(x, y, np.array([1.0, 0.0])) == pytest.approx(0.1, abs=1e-9)
        assert rotation_svd(x, y, np.array([0.0, 1.0])) == pytest.approx(-0.1, abs=1e-9)
        assert rotation_svd(x, y, np.array([1.0, 1.0])) == pytest.approx(0.0, abs=1e-9)

    def test_large_rotation_is_a_rotation_not_a_reflection(self):
        x = np.array([[1.0, 0.0], [2.0, 0.5], [0.5, -3.0]])
        for angle in (2.5, -2.9, math.pi / 2):
            assert abs(icp.wrap(rotation_svd(x, x @ rot(angle).T, np.ones(3)) - angle)) < 1e-9


class TestNearestTargets:
    """ICP's nearest-target search (range bands listed once) against brute force."""

    @pytest.mark.parametrize("bound", [5.0, 0.3, math.inf])
    @pytest.mark.parametrize("seed", range(3))
    def test_matches_brute_force(self, seed, bound):
        rng = np.random.default_rng(seed)
        # Scaled polar coordinates like ICP's: ranges 0-12 m x sqrt(100), bearings x sqrt(820);
        # clusters at one range (a wall) make wide bands.
        tr = np.concatenate([rng.uniform(0, 120, 150), np.full(40, 37.5)])
        tb = rng.uniform(-30, 30, len(tr))
        sr = np.concatenate([rng.uniform(-5, 125, 120), np.full(10, 37.5), [500.0]])
        sb = rng.uniform(-30, 30, len(sr))
        search = icp._NearestTargets(tr, tb, sr, bound)
        for turn in (0.0, 2.5, -7.0):
            e, nearest = search(sb + turn)
            full = (sr[:, None] - tr[None, :]) ** 2 + (sb[:, None] + turn - tb[None, :]) ** 2
            want = full.min(axis=1)
            found = want <= bound ** 2
            np.testing.assert_allclose(e[found], want[found], rtol=1e-12)
            np.testing.assert_array_equal(full[found, nearest[found]], want[found])  # a nearest one
            # Beyond the bound: either infinite or at least the bound (and removed by eps_max).
            assert np.all(e[~found] > bound ** 2)
            # The far source has a target only without a bound.
            assert found.any() and found[-1] == (bound == math.inf)

    def test_no_targets_in_any_band(self):
        search = icp._NearestTargets(np.array([1.0, 2.0]), np.zeros(2), np.array([50.0, 60.0]), 5.0)
        e, nearest = search(np.zeros(2))
        assert np.all(np.isinf(e)) and nearest.shape == (2,)


class TestRegisterRotation:
    @pytest.mark.parametrize("angle_deg", [3.0, -5.0, 1.0, 0.3, 8.0])
    @pytest.mark.parametrize("sampling", [True, False])
    def test_recovers_known_rotation_of_sparse_features(self, angle_deg, sampling):
        src = sparse_scene(0)
        tgt = rotated(src, math.radians(angle_deg))
        reg = register_rotation(src, tgt, IcpConfig(sampling=sampling))
        assert reg.ok, reg
        assert abs(reg.rotation_rad - math.radians(angle_deg)) < 0.1 * DEG
        assert 1 <= reg.iterations <= IcpConfig().iterations

    @pytest.mark.parametrize("seed", range(4))
    def test_recovers_rotation_with_small_noise_and_partial_overlap(self, seed):
        rng = np.random.default_rng(seed)
        src = sparse_scene(10 + seed, 16)
        tgt = rotated(src, -4 * DEG)
        tgt.bearing_rad += 0.3 * DEG * rng.standard_normal(len(tgt))
        tgt.range_m += 0.02 * rng.standard_normal(len(tgt))
        reg = register_rotation(src, tgt, IcpConfig(sampling=False))
        assert reg.ok
        assert abs(reg.rotation_rad + 4 * DEG) < 0.25 * DEG

    def test_initial_guess_is_used(self):
        # 12 degrees is beyond the basin of nearest-neighbour matching from zero for features
        # 8 degrees apart; from a guess nearby it is found exactly.
        src = sparse_scene(1)
        tgt = rotated(src, 12 * DEG)
        reg = register_rotation(src, tgt, IcpConfig(), initial_rad=11 * DEG)
        assert reg.ok and abs(reg.rotation_rad - 12 * DEG) < 0.05 * DEG

    def test_outliers_beyond_eps_max_are_removed(self):
        src = sparse_scene(2)
        tgt = rotated(src, 2 * DEG)
        far = feats([11.5, 12.0, 12.5], np.radians([-50.0, 0.0, 50.0]), [5.0, 5.0, 5.0])
        # Range 11.5+ m is more than 1.5 m from any target: e = 100 * 1.5^2 > eps_max = 25.
        assert np.max(tgt.range_m) < 10.0
        src_out = Features(np.r_[src.range_m, far.range_m], np.r_[src.bearing_rad, far.bearing_rad],
                           np.r_[src.weight, far.weight] / np.r_[src.weight, far.weight].sum(),
                           np.r_[src.intensity, far.intensity])
        reg = register_rotation(src_out, tgt, IcpConfig(sampling=True))
        assert reg.removed == 3
        assert reg.ok and abs(reg.rotation_rad - 2 * DEG) < 0.1 * DEG
        # Without sampling the same outliers are matched and pull the rotation away.
        plain = register_rotation(src_out, tgt, IcpConfig(sampling=False))
        assert plain.removed == 0 and plain.neglected == 0 and plain.matches == len(src_out)
        assert abs(plain.rotation_rad - 2 * DEG) > 0.3 * DEG

    def test_region_neglects_source_points_outside(self):
        src = sparse_scene(3)
        tgt = rotated(src, 3 * DEG)
        region = Region(0.5, 12.75, math.radians(45.0))
        reg = register_rotation(src, tgt, IcpConfig(), region=region)
        outside = int(np.sum(np.abs(src.bearing_rad + reg.rotation_rad) > math.radians(45.0)))
        assert outside > 0 and reg.neglected >= outside
        assert reg.ok and abs(reg.rotation_rad - 3 * DEG) < 0.1 * DEG
        np.testing.assert_array_equal(region.contains(np.array([0.4, 1.0, 13.0, 5.0]), np.radians([0, 0, 0, 46.0])),
                                      [False, True, False, False])

    def test_few_matches_when_features_do_not_overlap(self):
        near = feats(np.linspace(2.0, 3.0, 10), np.radians(np.linspace(-40, 40, 10)))
        far = feats(np.linspace(8.0, 9.0, 10), np.radians(np.linspace(-40, 40, 10)))
        reg = register_rotation(near, far, IcpConfig(sampling=True))
        assert reg.status == icp.FEW_MATCHES and not reg.ok
        assert reg.removed == 10
        two, _ = register_two_way(near, far, IcpConfig())
        assert not two.ok

    def test_empty_features(self):
        src = sparse_scene(4)
        empty = feats([], [])
        for a, b in ((src, empty), (empty, src)):
            reg = register_rotation(a, b, IcpConfig(), initial_rad=0.01)
            assert reg.status == icp.FEW_MATCHES and not reg.ok
            assert reg.rotation_rad == 0.01

    def test_not_converged_within_one_iteration(self):
        src = sparse_scene(5)
        tgt = rotated(src, 3 * DEG)
        reg = register_rotation(src, tgt, IcpConfig(sampling=False, iterations=1))
        assert reg.status == icp.NOT_CONVERGED and reg.iterations == 1

    def test_variance_is_finite_and_small_for_a_good_match(self):
        src = sparse_scene(6)
        rng = np.random.default_rng(6)
        tgt = rotated(src, 2 * DEG)
        tgt.bearing_rad += 0.2 * DEG * rng.standard_normal(len(tgt))
        reg = register_rotation(src, tgt, IcpConfig(sampling=False))
        assert reg.ok and 0 < reg.variance < (1 * DEG) ** 2

    def test_product_weighting_runs(self):
        src = sparse_scene(7)
        reg = register_rotation(src, rotated(src, -2 * DEG), IcpConfig(weight="product"))
        assert reg.ok and abs(reg.rotation_rad + 2 * DEG) < 0.1 * DEG

    def test_aligned_except_a_few_points_is_ok(self):
        src = sparse_scene(8, 33)
        tgt = rotated(src, 3 * DEG)
        tgt.bearing_rad[:3] += 0.5 * DEG  # three features a little off (e.g. a bin-quantised peak)
        reg = register_rotation(src, tgt, IcpConfig(sampling=True))
        assert abs(reg.rotation_rad - 3 * DEG) < 0.1 * DEG  # the rotation is fine ...
        assert reg.ok, reg  # ... but it is called a failure

    def test_nothing_inside_the_region_is_not_ok(self):
        src = sparse_scene(9)
        reg = register_rotation(src, rotated(src, 2 * DEG), IcpConfig(), initial_rad=0.0,
                                region=Region(20.0, 30.0, 1.0))
        assert not reg.ok

    def test_sampling_with_weak_clutter_converges(self):
        errors = []
        for seed in range(6):
            src, tgt, angle = clutter_pair(seed)
            reg, _ = register_two_way(src, tgt, IcpConfig(sampling=True))
            errors.append((abs(reg.rotation_rad - angle) / DEG, reg.status))
        assert all(e < 0.1 and s == icp.OK for e, s in errors), errors

    def test_plain_wicp_with_weak_clutter(self):
        # The data of the test above is well posed: without sampling it registers.
        for seed in range(6):
            src, tgt, angle = clutter_pair(seed)
            reg, _ = register_two_way(src, tgt, IcpConfig(sampling=False))
            assert reg.ok and abs(reg.rotation_rad - angle) < 0.1 * DEG


def clutter_pair(seed: int) -> tuple[Features, Features, float]:
    """12 strong features seen in both frames, rotated by -3 degrees, plus 150 weak clutter
    features (1e-3 of the strong ones' intensity) different in each frame."""
    rng = np.random.default_rng(seed)
    n, m = 12, 150
    r = rng.uniform(2, 10, n)
    b = np.radians(np.linspace(-55, 55, n)) + rng.uniform(-0.05, 0.05, n)
    w = rng.uniform(0.5, 2, n)
    angle = -3 * DEG

    def clutter():
        return rng.uniform(1, 12, m), rng.uniform(-1.13, 1.13, m), rng.uniform(1e-3, 3e-3, m)

    c1, c2 = clutter(), clutter()
    src = feats(np.r_[r, c1[0]], np.r_[b, c1[1]], np.r_[w, c1[2]])
    tgt = feats(np.r_[r, c2[0]], np.r_[b + angle, c2[1]], np.r_[w, c2[2]])
    return src, tgt, angle


class TestTwoWay:
    def asymmetric_pair(self):
        # Extra target-only features make the two directions disagree a little.
        src = sparse_scene(20)
        tgt = rotated(src, 2 * DEG)
        rng = np.random.default_rng(20)
        extra_r, extra_b = rng.uniform(2, 10, 4), rng.uniform(-0.9, 0.9, 4)
        tgt = feats(np.r_[tgt.range_m, extra_r], np.r_[tgt.bearing_rad, extra_b], np.r_[tgt.intensity, np.ones(4)])
        return src, tgt

    def test_two_way_is_the_mean_of_both_directions(self):
        src, tgt = self.asymmetric_pair()
        cfg = IcpConfig(sampling=False)
        fwd = register_rotation(src, tgt, cfg)
        bwd = register_rotation(tgt, src, cfg)
        assert fwd.ok and bwd.ok
        assert abs(fwd.rotation_rad + bwd.rotation_rad) > 1e-4  # they do differ
        combined, forward = register_two_way(src, tgt, cfg)
        assert combined.ok
        assert combined.rotation_rad == pytest.approx(0.5 * (fwd.rotation_rad - bwd.rotation_rad), abs=1e-12)
        assert forward.rotation_rad == pytest.approx(fwd.rotation_rad, abs=1e-12)
        assert combined.matches == fwd.matches + bwd.matches

    def test_one_way(self):
        src, tgt = self.asymmetric_pair()
        cfg = IcpConfig(sampling=False, two_way=False)
        combined, forward = register_two_way(src, tgt, cfg)
        assert combined.rotation_rad == pytest.approx(register_rotation(src, tgt, cfg).rotation_rad, abs=1e-12)
        assert forward is combined

    def test_backward_alone_is_negated(self):
        # Three previous features, fifteen current ones around them (five per feature, same
        # bearing turned by 2 degrees, ranges spread): forward has too few matches, backward
        # works, and the result is the backward rotation negated.
        b0 = np.radians([-30.0, 0.0, 30.0])
        r0 = np.array([4.0, 6.0, 8.0])
        previous = feats(r0, b0)
        offsets = np.array([-0.2, -0.1, 0.0, 0.1, 0.2])
        current = feats((r0[:, None] + offsets).ravel(), np.repeat(b0 + 2 * DEG, 5))
        cfg = IcpConfig(sampling=True)
        fwd = register_rotation(previous, current, cfg)
        bwd = register_rotation(current, previous, cfg)
        assert fwd.status == icp.FEW_MATCHES and bwd.ok
        combined, forward = register_two_way(previous, current, cfg)
        assert forward.status == icp.FEW_MATCHES
        assert combined.ok
        assert combined.rotation_rad == pytest.approx(-bwd.rotation_rad, abs=1e-12)
        assert combined.rotation_rad == pytest.approx(2 * DEG, abs=1e-9)

    def test_two_way_mean_when_neither_converged(self):
        src, tgt = TestTwoWay().asymmetric_pair()
        cfg = IcpConfig(sampling=False, iterations=1)
        fwd = register_rotation(src, tgt, cfg)
        bwd = register_rotation(tgt, src, cfg)
        assert fwd.status == bwd.status == icp.NOT_CONVERGED
        combined, _ = register_two_way(src, tgt, cfg)
        assert combined.rotation_rad == pytest.approx(0.5 * (fwd.rotation_rad - bwd.rotation_rad), abs=1e-12)


class TestHeatmapRegistration:
    """Features of synthetic AWR1843 heatmaps of a rotated scene, registered."""

    @staticmethod
    def reflectors():
        """12 reflectors across the field of view (range m, bearing rad, amplitude) and the
        feature settings that suit them."""
        rng = np.random.default_rng(30)
        n = 12
        r = rng.uniform(2, 10, n)
        b = np.radians(np.linspace(-50, 50, n)) + rng.uniform(-0.03, 0.03, n)
        amp = rng.uniform(0.5, 2, n)
        return r, b, amp, FeatureConfig(method="topk", peaks_only=True, subbin=True)

    @pytest.mark.parametrize("angle_deg", [3.0, -5.0, 2.0])
    def test_rotation_from_heatmaps_peaks_subbin_wicp(self, angle_deg):
        r, b, amp, cfg = self.reflectors()
        a = extract(heatmap(polar_xy(r, b), amp, noise=1e-4), cfg)
        c = extract(heatmap(polar_xy(r, b + math.radians(angle_deg)), amp, noise=1e-4), cfg)
        reg, _ = register_two_way(a, c, IcpConfig(sampling=False))
        assert abs(reg.rotation_rad - math.radians(angle_deg)) < 0.15 * DEG

    def test_rotation_from_heatmaps_with_sampling(self):
        r, b, amp, cfg = self.reflectors()
        a = extract(heatmap(polar_xy(r, b), amp, noise=1e-4), cfg)
        errors = []
        for angle in (3 * DEG, -5 * DEG, 2 * DEG):
            c = extract(heatmap(polar_xy(r, b + angle), amp, noise=1e-4), cfg)
            reg, _ = register_two_way(a, c, IcpConfig(sampling=True))
            errors.append(abs(reg.rotation_rad - angle) / DEG)
        assert max(errors) < 0.15, errors

    def test_translation_then_rectification(self):
        # The sensor moves 0.1 m forward and turns 2 degrees left; rectifying the previous
        # features by the translation leaves the rotation, -2 degrees for the world.
        rng = np.random.default_rng(31)
        n = 12
        r = rng.uniform(2, 10, n)
        b = np.radians(np.linspace(-50, 50, n))
        world = polar_xy(r, b)
        amp = rng.uniform(0.5, 2, n)
        turn = 2 * DEG
        pose1 = (0.1 * math.cos(turn / 2), 0.1 * math.sin(turn / 2), turn)
        cfg = FeatureConfig(method="topk", peaks_only=True, subbin=True)
        prev = extract(heatmap(world, amp, noise=1e-4), cfg)
        cur = extract(heatmap(synth.world_to_body(world, pose1), amp, noise=1e-4), cfg)
        reg, _ = register_two_way(prev.shifted([0.1, 0.0]), cur, IcpConfig(sampling=False))
        assert abs(reg.rotation_rad + turn) < 0.15 * DEG


class TestCorrelationGuess:
    grid = np.arange(-60.0, 60.0 + 1e-9, 0.25) * DEG

    def profile(self, shift: float = 0.0) -> np.ndarray:
        centres = np.radians([-41.0, -20.0, -3.0, 12.0, 33.0, 50.0])
        heights = np.array([10.0, 4.0, 8.0, 12.0, 5.0, 7.0])
        g = self.grid[:, None] - shift - centres[None, :]
        return 10 * np.log10(1e-3 + (heights * np.exp(-0.5 * (g / (4 * DEG)) ** 2)).sum(axis=1))

    @pytest.mark.parametrize("shift_deg", [2.3, -4.6, 0.0, 7.1, -0.4])
    def test_recovers_a_known_shift(self, shift_deg):
        previous = self.profile()
        current = self.profile(math.radians(shift_deg))  # current(b + s) = previous(b)
        got = icp.correlation_guess(previous, current, 0.25 * DEG, 15 * DEG)
        assert got is not None
        assert abs(got - math.radians(shift_deg)) < 0.1 * DEG
        # ... the rotation source -> target, as register_rotation would give it.

    def test_search_is_centred(self):
        previous, current = self.profile(), self.profile(math.radians(12.0))
        assert icp.correlation_guess(previous, current, 0.25 * DEG, 3 * DEG, centre_rad=11 * DEG) == \
            pytest.approx(12 * DEG, abs=0.1 * DEG)
        # Outside the search range the best is at its edge, not the true shift.
        got = icp.correlation_guess(previous, current, 0.25 * DEG, 3 * DEG)
        assert got is None or abs(got) <= 3.01 * DEG

    def test_nan_edges_and_no_overlap(self):
        previous, current = self.profile(), self.profile(math.radians(-3.0))
        previous[:40] = np.nan
        current[-40:] = np.nan
        got = icp.correlation_guess(previous, current, 0.25 * DEG, 10 * DEG)
        assert got == pytest.approx(-3 * DEG, abs=0.1 * DEG)
        nothing = np.full_like(previous, np.nan)
        assert icp.correlation_guess(nothing, current, 0.25 * DEG, 10 * DEG) is None

    def test_agrees_with_icp_convention(self):
        # The same scene turned +3 degrees (body frame): ICP and the profile agree on the sign.
        src = sparse_scene(40)
        reg = register_rotation(src, rotated(src, 3 * DEG), IcpConfig())
        previous, current = self.profile(), self.profile(3 * DEG)
        guess = icp.correlation_guess(previous, current, 0.25 * DEG, 10 * DEG)
        assert math.copysign(1, guess) == math.copysign(1, reg.rotation_rad) == 1.0


def test_wrap():
    np.testing.assert_allclose(icp.wrap(np.array([0.0, math.pi, -math.pi, 3 * math.pi / 2, -7.0])),
                               [0.0, -math.pi, -math.pi, -math.pi / 2, -7.0 + 2 * math.pi])


class TestLogHeatmap:
    """The scan guess's sampler: exact at the bins, bilinear between, NaN outside; uniform
    (FFT) and non-uniform (ColoRadar-like) axes alike."""

    @staticmethod
    def _random_map(rng, uniform: bool, sin_span: float, max_azimuth_rad: float):
        """A random 40 x 32 log heatmap over +/- *sin_span* in sin(azimuth), uniform or not;
        returns it, its range axis and its azimuth axis."""
        from radarodom.dsp.heatmap import RangeAzimuth
        from radarodom.estimator.log_heatmap import LogHeatmap

        n_r, n_a = 40, 32
        range_m = 0.1 * np.arange(n_r) + 0.2
        sin_az = (np.linspace(-sin_span, sin_span, n_a) if uniform
                  else np.sort(rng.uniform(-sin_span, sin_span, n_a)))
        az = np.arcsin(sin_az)
        intensity = np.exp(rng.uniform(0, 5, (n_r, n_a))).astype(np.float32)
        cfg = FeatureConfig(max_azimuth_rad=max_azimuth_rad, min_range_m=0.0)
        return LogHeatmap(RangeAzimuth(intensity, intensity, intensity * np.nan, range_m, az), cfg), range_m, az

    @pytest.mark.parametrize("uniform", [True, False])
    def test_samples_at_and_between_bins(self, uniform):
        rng = np.random.default_rng(40)
        lh, range_m, az = self._random_map(rng, uniform, 0.9, math.radians(89.0))
        i, j = 7, 11
        # Body bearing = -TI azimuth.
        # The log heatmap is float32: equal to its rounding.
        assert lh.sample(np.array([range_m[i]]), np.array([-az[j]]))[0] == pytest.approx(lh.values[i, j], abs=1e-6)
        mid_r = 0.5 * (range_m[i] + range_m[i + 1])
        mid = lh.sample(np.array([mid_r]), np.array([-az[j]]))[0]
        assert mid == pytest.approx(0.5 * (lh.values[i, j] + lh.values[i + 1, j]), abs=1e-6)
        assert np.isnan(lh.sample(np.array([100.0]), np.array([0.0]))[0])
        assert np.isnan(lh.sample(np.array([range_m[i]]), np.array([math.radians(80.0)]))[0])

    @pytest.mark.parametrize("uniform", [True, False])
    @pytest.mark.parametrize("max_azimuth_deg", [65.0, 89.0])
    @pytest.mark.parametrize("max_bearing_rad", [1.2, 3.1])
    def test_sample_rotated_equals_sample(self, uniform, max_azimuth_deg, max_bearing_rad):
        # The fast path of the scan and the field gives sample()'s numbers (0 and not inside
        # where sample() says NaN), on uniform and non-uniform azimuth axes, with the region
        # inside the azimuth axis (65 degrees) and beyond its ends (89), and with points that
        # stay in front or turn past the side (whose sine repeats a point's in front).
        rng = np.random.default_rng(41)
        lh, range_m, _ = self._random_map(rng, uniform, 0.95, math.radians(max_azimuth_deg))
        r = rng.uniform(0.0, 5.0, 300)  # some beyond the last range bin
        b = rng.uniform(-max_bearing_rad, max_bearing_rad, 300)  # some outside the region
        shifts = np.radians(np.arange(-5.0, 5.01, 0.5))
        values, inside = lh.sample_rotated(r, b, shifts)
        ref = lh.sample(r[None, :], icp.wrap(b[None, :] + shifts[:, None]))
        np.testing.assert_array_equal(inside, np.isfinite(ref))
        np.testing.assert_allclose(values[inside], ref[inside], atol=1e-5)  # float32 index and values
        assert np.all(values[~inside] == 0.0)
        assert 0 < inside.sum() < inside.size

    def test_smoothed_copy_leaves_the_original(self):
        from radarodom.estimator.log_heatmap import LogHeatmap

        hm = random_heatmap(5)
        lh = LogHeatmap(hm, FeatureConfig())
        before = lh.values.copy()
        smooth = lh.smoothed(2.0)
        np.testing.assert_array_equal(lh.values, before)
        assert smooth.values.std() < 0.5 * before.std()  # speckle averaged
        assert lh.smoothed(0.0).values is lh.values


    def test_upsampled_field_is_the_smoothing_at_the_bins(self):
        # Interpolated every quarter bin, the smoothed field holds the smoothing's own values at
        # the bins and samples the same there; half way between two bins it is the cubic
        # spline through four (-1, 9, 9, -1) / 16, within a hundredth of the Gaussian centred there.
        rng = np.random.default_rng(6)
        lh, range_m, az = self._random_map(rng, True, 0.95, math.radians(89.0))
        coarse, fine = lh.smoothed(2.0), lh.smoothed(2.0, 4)
        assert fine.values.shape == (coarse.values.shape[0], 4 * (coarse.values.shape[1] - 1) + 1)
        np.testing.assert_array_equal(fine.values[:, ::4], coarse.values)
        r = rng.uniform(range_m[0], range_m[-1], 200)
        b = -az[rng.integers(2, len(az) - 2, 200)]
        np.testing.assert_allclose(fine.sample(r, b), coarse.sample(r, b), atol=1e-5)
        i, j = 12, 15
        row = coarse.values[i]
        assert fine.values[i, 4 * j + 2] == pytest.approx((-row[j - 1] + 9 * row[j] + 9 * row[j + 1] - row[j + 2]) / 16,
                                                          abs=1e-5)
        # Every quarter bin of the row (away from its ends) within a hundredth of the Gaussian
        # centred there, where the mean of the two bins around it errs by up to several times that.
        along_range = scipy.ndimage.gaussian_filter1d(lh.values, 2.0, axis=0, mode="nearest")[i]
        places = np.arange(4 * 8, 4 * (len(az) - 9) + 1) / 4
        g = np.exp(-0.5 * ((np.arange(len(az))[None, :] - places[:, None]) / 2.0) ** 2)
        exact = (g @ along_range) / g.sum(axis=1)
        spline = fine.values[i, (4 * places).astype(int)]
        linear = np.interp(places, np.arange(len(az)), coarse.values[i])
        assert np.abs(spline - exact).max() < 0.01
        assert np.abs(linear - exact).max() > 3 * np.abs(spline - exact).max()


class TestFieldRotation:
    """The likelihood-field refinement (icp.refinement = "field")."""

    def test_upsampled_field_is_not_drawn_to_whole_bins(self):
        # The same reflectors turned by angles between the bins (a bin is 1.8 degrees at
        # boresight), searched on a fine grid from the truth: sampled bilinearly between the
        # heatmap's bins the field scores whole-bin turns highest and errs by up to 0.7 degrees
        # (RMS 0.4); interpolated every quarter bin it finds each turn within 0.2 degrees.
        from radarodom.estimator.log_heatmap import LogHeatmap

        cfg = FeatureConfig(method="topk", k=400, weighting="db", peaks_only=False, subbin=False,
                            dynamic_rejection_mps=None)
        errors = {1: [], 4: []}
        for seed in range(3):
            rng = np.random.default_rng(seed)
            world = polar_xy(rng.uniform(2.0, 9.0, 25), np.radians(rng.uniform(-55, 55, 25)))
            amp = rng.uniform(0.5, 2.0, 25)
            hp = heatmap(world, amp)
            fp = extract(hp, cfg)
            for angle_deg in (0.7, 1.4, 2.2, 3.1):
                angle = math.radians(angle_deg)
                hc = heatmap(world @ rot(-angle).T, amp)
                fc = extract(hc, cfg)
                for up, found_errors in errors.items():
                    lp, lc = LogHeatmap(hp, cfg).smoothed(2.0, up), LogHeatmap(hc, cfg).smoothed(2.0, up)
                    found = icp.field_rotation(fp, fc, lp, lc, np.zeros(2), -angle, 2.0 * DEG, 0.05 * DEG)
                    found_errors.append((found + angle) / DEG)
        fine, coarse = np.abs(errors[4]), np.abs(errors[1])
        assert fine.max() < 0.2
        assert math.sqrt(np.mean(fine ** 2)) < 0.3 * math.sqrt(np.mean(coarse ** 2))

    @pytest.mark.parametrize("angle_deg", [-2.3, 0.0, 1.4, 4.0])
    def test_recovers_rotation_and_translation_from_a_wrong_start(self, angle_deg):
        # Two heatmaps of the same reflectors, the sensor moved by t and turned by angle: from a
        # start 2 degrees off, the field finds the rotation within half a degree.  (Not better:
        # the cells sit on the bin grid and are sampled bilinearly between bins, which leaves
        # errors of 0.1-0.35 degrees on these 25 reflectors even without translation.)
        from radarodom.estimator.log_heatmap import LogHeatmap

        rng = np.random.default_rng(7)
        world = polar_xy(rng.uniform(2.0, 9.0, 25), np.radians(rng.uniform(-55, 55, 25)))
        t = np.array([0.12, -0.03])
        angle = math.radians(angle_deg)  # the sensor turns by angle: the world by -angle
        cur_xy = (world - t) @ rot(-angle).T
        amp = rng.uniform(0.5, 2.0, 25)
        hp, hc = heatmap(world, amp), heatmap(cur_xy, amp)
        cfg = FeatureConfig(method="topk", k=400, weighting="db", peaks_only=False, subbin=False,
                            dynamic_rejection_mps=None)
        fp, fc = extract(hp, cfg), extract(hc, cfg)
        lp, lc = LogHeatmap(hp, cfg).smoothed(2.0), LogHeatmap(hc, cfg).smoothed(2.0)
        found = icp.field_rotation(fp, fc, lp, lc, t, -angle + 2.0 * DEG, 4.0 * DEG, 0.5 * DEG)
        assert found is not None
        assert found == pytest.approx(-angle, abs=0.5 * DEG)

    def test_nothing_inside_gives_none(self):
        from radarodom.estimator.log_heatmap import LogHeatmap

        cfg = FeatureConfig()
        far = feats([50.0, 60.0, 70.0], [0.1, 0.2, 0.3])  # beyond the heatmap's range
        lh = LogHeatmap(random_heatmap(3), cfg)
        assert icp.field_rotation(far, far, lh, lh, np.zeros(2), 0.0, 3 * DEG, 0.5 * DEG) is None

    def test_config_validation(self):
        from radarodom.errors import ConfigError

        with pytest.raises(ConfigError, match="refinement"):
            IcpConfig(refinement="gradient")
        with pytest.raises(ConfigError, match="field_smoothing_bins"):
            IcpConfig(field_smoothing_bins=-1.0)
        with pytest.raises(ConfigError, match="field_search_rad"):
            IcpConfig(field_search_rad=0.0)
        with pytest.raises(ConfigError, match="field_step_rad"):
            IcpConfig(field_step_rad=0.0)
        with pytest.raises(ConfigError, match="field_upsampling"):
            IcpConfig(field_upsampling=0)
        with pytest.raises(ConfigError, match="scan_step_rad"):
            IcpConfig(scan_step_rad=-1.0)
        assert IcpConfig.from_dict(IcpConfig().to_dict()) == IcpConfig()
