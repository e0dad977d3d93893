"""Point features from a range-azimuth heatmap (paper III-B): Top-k, Ray-max, CFAR.

The input is any polar heatmap: an intensity array (n_range, n_azimuth) with
its axes ``range_m`` (n_range,) and ``azimuth_rad`` (n_azimuth,) ascending in
the TI sensor frame (positive to the right), and optionally ``doppler_mps``
(n_range, n_azimuth), the radial velocity of each cell's dominant Doppler bin
(NaN where unknown).  :class:`radarodom.dsp.heatmap.RangeAzimuth` is one;
ColoRadar's heatmaps, reduced over elevation, are another.

Features come out in the body frame (REP-103): bearing = -azimuth, positive
to the left, with weights from their intensities normalised to sum to one.
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..dsp.cfar import cfar_1d
from .config import FeatureConfig

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())


class PolarHeatmap(Protocol):
    intensity: np.ndarray
    range_m: np.ndarray
    azimuth_rad: np.ndarray


@dataclass
class Features:
    """Polar point features in the body frame; arrays (n,).  Range and bearing are horizontal;
    *height_m* is each feature's height above the radar (None: all level with it)."""

    range_m: np.ndarray
    bearing_rad: np.ndarray  # counter-clockwise from x (forward)
    weight: np.ndarray  # normalised: sums to one
    intensity: np.ndarray  # the heatmap's value, linear
    height_m: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.range_m)

    @functools.cached_property
    def slant_m(self) -> np.ndarray:
        """The range the radar measures, (n,) m: horizontal range and height together."""
        return self.range_m if self.height_m is None else np.hypot(self.range_m, self.height_m)

    @functools.cached_property
    def cos_elevation(self) -> np.ndarray | None:
        """Horizontal over slant range, (n,); None when every feature is level (all 1)."""
        if self.height_m is None:
            return None
        return self.range_m / np.maximum(self.slant_m, 1e-12)

    @functools.cached_property
    def xy(self) -> np.ndarray:
        """Cartesian positions (n, 2), m; read-only.  Computed once: a frame's features are
        a registration's target, the other's source, and moved again in the next frame."""
        xy = np.stack([self.range_m * np.cos(self.bearing_rad), self.range_m * np.sin(self.bearing_rad)], 1)
        xy.flags.writeable = False
        return xy

    @classmethod
    def from_xy(cls, xy: np.ndarray, weight: np.ndarray, intensity: np.ndarray,
                height_m: np.ndarray | None = None) -> "Features":
        return cls(np.hypot(xy[:, 0], xy[:, 1]), np.arctan2(xy[:, 1], xy[:, 0]), weight, intensity, height_m)

    def subset(self, keep: np.ndarray) -> "Features":
        """The points where *keep* (n,) bool, their weights normalised again (the kept weights
        must not all be zero); all of them, as they are, when none would go or fewer than three
        would stay (too few to register by)."""
        if keep.all() or np.count_nonzero(keep) < 3:
            return self
        height = None if self.height_m is None else self.height_m[keep]
        weight = self.weight[keep]
        return type(self)(self.range_m[keep], self.bearing_rad[keep], weight / weight.sum(), self.intensity[keep],
                          height)

    def reweighted(self, weight: np.ndarray) -> "Features":
        """The same points weighed by *weight* (n,), normalised again (not all zero)."""
        out = type(self)(self.range_m, self.bearing_rad, weight / weight.sum(), self.intensity, self.height_m)
        # The same places: what was computed of them already holds (cached properties).
        out.__dict__.update((k, v) for k, v in self.__dict__.items() if k in _PLACES)
        return out

    def turned(self, angle_rad: float) -> "Features":
        """The same points with bearings turned by *angle_rad* (counter-clockwise)."""
        return type(self)(self.range_m, self.bearing_rad + angle_rad, self.weight, self.intensity, self.height_m)

    def shifted(self, dxy: np.ndarray) -> "Features":
        """The same points seen from a sensor moved by *dxy* (2,), m: ``p - dxy`` (paper eq. 3);
        their heights stay (fixed reflectors)."""
        xy = self.xy - np.asarray(dxy, dtype=float)[None, :]
        out = type(self).from_xy(xy, self.weight, self.intensity, self.height_m)
        # The positions are known: ICP would otherwise make them again from range and bearing.
        xy.flags.writeable = False
        out.__dict__["xy"] = xy
        return out


#: The cached properties of :class:`Features` that depend on the points' places only.
_PLACES = ("slant_m", "cos_elevation", "xy", "_level_xy")


class SlantFeatures(Features):
    """Features moved by a translation as reflectors level with the radar at their slant range,
    each keeping its elevation angle (``features.parallax`` "slant"): a heatmap cell's elevation
    is the power-weighted mean of what it holds, noisy and mixed over heights, and its slant range
    is what the radar measures; over the robustness matrix this moved cells better than fixed
    reflectors at their estimated height (docs/heading.md item 21)."""

    @functools.cached_property
    def _level_xy(self) -> np.ndarray:
        """Where each point would be level with the radar at its slant range, (n, 2) m: computed
        once, as a frame's features are moved several times (the field, the scan, the keyframe)."""
        slant = self.slant_m
        return np.stack([slant * np.cos(self.bearing_rad), slant * np.sin(self.bearing_rad)], 1)

    def shifted(self, dxy: np.ndarray) -> "Features":
        if self.height_m is None:
            return super().shifted(dxy)
        level = self._level_xy - np.asarray(dxy, dtype=float)[None, :]
        moved = np.hypot(level[:, 0], level[:, 1])
        cos_el = self.cos_elevation
        out = SlantFeatures(moved * cos_el, np.arctan2(level[:, 1], level[:, 0]), self.weight, self.intensity,
                            moved * (self.height_m / np.maximum(self.slant_m, 1e-12)))
        # Known already: the scores sample at each point's slant range and elevation.
        out.__dict__["slant_m"], out.__dict__["cos_elevation"] = moved, cos_el
        return out


#: The features' class by ``features.parallax``.
PARALLAX = {"horizontal": Features, "slant": SlantFeatures}


def roi_mask(heatmap: PolarHeatmap, config: FeatureConfig) -> np.ndarray:
    """Cells inside the region of interest, (n_range, n_azimuth) bool."""
    r = heatmap.range_m
    rmask = r >= config.min_range_m
    if config.max_range_m is not None:
        rmask &= r <= config.max_range_m
    amask = np.abs(heatmap.azimuth_rad) <= config.max_azimuth_rad
    return rmask[:, None] & amask[None, :]


def static_mask(heatmap: PolarHeatmap, velocity_xy: np.ndarray, threshold_mps: float) -> np.ndarray:
    """Cells whose dominant Doppler is what a static reflector would show at body-frame
    velocity *velocity_xy* (2,), m/s, within *threshold_mps*; unknown Doppler counts as
    static.  (n_range, n_azimuth) bool."""
    doppler = getattr(heatmap, "doppler_mps", None)
    if doppler is None:
        return np.ones(heatmap.intensity.shape, bool)
    bearing = -heatmap.azimuth_rad
    predicted = -(velocity_xy[0] * np.cos(bearing) + velocity_xy[1] * np.sin(bearing))  # (n_az,)
    return ~(np.abs(doppler - predicted[None, :]) > threshold_mps)  # NaN compares False: kept


def extract(heatmap: PolarHeatmap, config: FeatureConfig,
            velocity_xy: np.ndarray | None = None) -> Features:
    """Features of one heatmap by ``config.method``; *velocity_xy* enables the
    dynamic-object rejection when the config asks for it.  With ``config.elevation`` "use",
    features placed (at their sub-bin range with ``config.subbin``, times cos(el)) nearer than
    ``config.min_range_m`` are dropped, unless fewer than three would be left."""
    intensity = np.asarray(heatmap.intensity, dtype=np.float32)
    if intensity.shape != (len(heatmap.range_m), len(heatmap.azimuth_rad)):
        raise ValueError(f"heatmap intensity {intensity.shape} does not match its axes "
                         f"({len(heatmap.range_m)}, {len(heatmap.azimuth_rad)})")
    # Cells with no power carry nothing (an empty or blocked heatmap gives no features).
    valid = roi_mask(heatmap, config) & (intensity > 0)
    if config.dynamic_rejection_mps is not None and velocity_xy is not None:
        valid &= static_mask(heatmap, velocity_xy, config.dynamic_rejection_mps)
    if config.peaks_only:
        valid &= intensity >= _neighbourhood_max(intensity)
    if config.method == "topk":
        ri, ai = _top_k(intensity, valid, config.k)
    elif config.method == "raymax":
        ri, ai = _ray_max(intensity, valid)
    else:
        ri, ai = _cfar(intensity, valid, config)
    values = intensity[ri, ai].astype(float)
    if config.subbin:
        rng, az = _subbin(intensity, ri, ai, heatmap.range_m, heatmap.azimuth_rad)
    else:
        rng, az = heatmap.range_m[ri].astype(float), heatmap.azimuth_rad[ai].astype(float)
    weights = _weights(values, intensity, valid, config.weighting)
    elevation = getattr(heatmap, "elevation_rad", None)
    if config.elevation == "use" and elevation is not None:
        rng, az, height = horizontal(rng, az, np.nan_to_num(elevation[ri, ai].astype(float)))
        # Placed nearer than the region's range (the floor beneath the radar, a steep elevation's
        # noise), a feature's bearing is swung by any error of a step's translation: dropped
        # (docs/heading.md item 17).
        features = PARALLAX[config.parallax](rng, -az, weights, values, height)
        return features.subset(rng >= config.min_range_m)
    return Features(rng, -az, weights, values)


def horizontal(slant_m: np.ndarray, azimuth_rad: np.ndarray, elevation_rad: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Horizontal range (m), horizontal azimuth (rad, TI frame) and height (m) of cells at
    *slant_m* on the heatmap's azimuth axis *azimuth_rad* (arcsin of the sideways direction
    cosine) at elevation *elevation_rad*; all (n,)."""
    c = np.maximum(np.cos(elevation_rad), 1e-6)
    az = np.arcsin(np.clip(np.sin(azimuth_rad) / c, -1.0, 1.0))
    return slant_m * c, az, slant_m * np.sin(elevation_rad)


def _top_k(intensity: np.ndarray, valid: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column indices of the *k* strongest valid cells (all when fewer), in raster order."""
    cells = np.flatnonzero(valid)
    if len(cells) > k:
        # Partition the valid cells only: with peaks_only most of the heatmap is invalid, and
        # partitioning the whole over as many equal fillers takes 20 times longer.  Raster
        # order makes the features' order independent of the partition algorithm.
        strongest = np.argpartition(intensity.ravel()[cells], len(cells) - k)[len(cells) - k:]
        cells = np.sort(cells[strongest])
    return np.unravel_index(cells, intensity.shape)


def _ray_max(intensity: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    masked = np.where(valid, intensity, -np.inf)
    ri = masked.argmax(axis=0)
    ai = np.flatnonzero(np.isfinite(masked[ri, np.arange(intensity.shape[1])]))
    return ri[ai], ai


def _cfar(intensity: np.ndarray, valid: np.ndarray, config: FeatureConfig) -> tuple[np.ndarray, np.ndarray]:
    """Cells detected along range and along azimuth (each pass alone lets a strong
    reflector's range or angle sidelobes through on every neighbouring ray)."""
    config.check_heatmap_range(intensity.shape[0])
    along_range, _ = cfar_1d(intensity, config.cfar, axis=0)
    if intensity.shape[1] >= config.cfar_azimuth.window:
        along_azimuth, _ = cfar_1d(intensity, config.cfar_azimuth, axis=1)
        along_range &= along_azimuth
    return np.nonzero(along_range & valid)


def _neighbourhood_max(a: np.ndarray) -> np.ndarray:
    """The maximum over each cell's 3 x 3 neighbourhood, edges clamped: what
    ``scipy.ndimage.maximum_filter(a, size=3, mode="nearest")`` gives (for NaN-free *a*),
    as whole-array maxima along each axis, several times faster on a heatmap."""
    out = a.copy()
    # Each axis's lower and upper neighbours by slicing (np.moveaxis would make the inner
    # loops strided and the whole twice as slow).
    for lower, upper in (((slice(0, -1),), (slice(1, None),)),
                         ((slice(None), slice(0, -1)), (slice(None), slice(1, None)))):
        before = out.copy()
        np.fmax(out[upper], before[lower], out=out[upper])
        np.fmax(out[lower], before[upper], out=out[lower])
    return out


def _weights(values: np.ndarray, intensity: np.ndarray, valid: np.ndarray, weighting: str) -> np.ndarray:
    if len(values) == 0:
        return values
    if weighting == "db":
        # Decibels over the median of the valid cells (the heatmap's noise and clutter floor),
        # so weak features still count but never negatively.  The boolean index copies, so
        # the median may partition in place.
        background = intensity[valid]
        floor = float(np.median(background, overwrite_input=True)) if background.size else 0.0
        w = np.maximum(10.0 * np.log10(np.maximum(values, 1e-30) / max(floor, 1e-30)), 1e-3)
    else:
        w = np.maximum(values, 1e-30)
    return w / w.sum()


def _parabolic(left: np.ndarray, centre: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Vertex offset in bins of a parabola through three log values; 0 unless the
    centre is a peak (a slope has no vertex within half a bin)."""
    curvature = left - 2.0 * centre + right
    peak = (centre >= left) & (centre >= right) & (curvature < 0)
    offset = np.where(peak, 0.5 * (left - right) / np.where(peak, curvature, -1.0), 0.0)
    return np.clip(offset, -0.5, 0.5)


def _subbin(intensity: np.ndarray, ri: np.ndarray, ai: np.ndarray, range_m: np.ndarray,
            azimuth_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Range and azimuth of each feature from a parabola through the log intensity of its
    neighbours.  Azimuth bins are interpolated in sin(azimuth), where FFT bins are uniform."""
    nr, na = intensity.shape
    # Neighbours clamped at the edges (the indices are inside, so one bound each).
    a0, a1 = np.maximum(ai - 1, 0), np.minimum(ai + 1, na - 1)
    r0, r1 = np.maximum(ri - 1, 0), np.minimum(ri + 1, nr - 1)
    # The log of the five cells each feature needs, not of the whole heatmap.
    centre, left, right, below, above = np.log(np.maximum(
        intensity[np.stack([ri, ri, ri, r0, r1]), np.stack([ai, a0, a1, ai, ai])], 1e-30))
    inner_a = (ai > 0) & (ai < na - 1)
    da = np.zeros(len(ai))
    da[inner_a] = _parabolic(left, centre, right)[inner_a]
    inner_r = (ri > 0) & (ri < nr - 1)
    dr = np.zeros(len(ri))
    dr[inner_r] = _parabolic(below, centre, above)[inner_r]
    sin_az = np.interp(ai + da, np.arange(na), np.sin(azimuth_rad))
    rng = np.interp(ri + dr, np.arange(nr), range_m)
    return rng, np.arcsin(np.clip(sin_az, -1.0, 1.0))


def heatmap_doppler_points(heatmap: PolarHeatmap, config: FeatureConfig, cells: int) -> np.ndarray | None:
    """The *cells* strongest local maxima of the heatmap in the region of interest whose
    dominant Doppler is known, as a point cloud for :func:`~.velocity.estimate_velocity`:
    a structured array (n,), in raster order, with fields azimuth (rad, TI frame), elevation (0:
    a range-azimuth heatmap has none), velocity (m/s, positive receding) and intensity (the
    heatmap's, linear; :func:`strongest_points` takes fewer of them).  Local maxima only: a strong
    reflector's sidelobes carry its Doppler and would outvote the rest.  None when the
    heatmap has no Doppler channel."""
    doppler = getattr(heatmap, "doppler_mps", None)
    if doppler is None:
        return None
    intensity = np.asarray(heatmap.intensity, dtype=np.float32)
    valid = roi_mask(heatmap, config) & (intensity > 0) & np.isfinite(doppler)
    valid &= intensity >= _neighbourhood_max(intensity)
    ri, ai = _top_k(intensity, valid, cells)
    out = np.zeros(len(ri), dtype=[("azimuth", "f8"), ("elevation", "f8"), ("velocity", "f8"), ("intensity", "f8")])
    out["azimuth"] = heatmap.azimuth_rad[ai]
    out["velocity"] = doppler[ri, ai]
    out["intensity"] = intensity[ri, ai]
    elevation = getattr(heatmap, "elevation_rad", None)
    if config.elevation == "use" and elevation is not None:
        el = np.nan_to_num(elevation[ri, ai].astype(float))
        _, out["azimuth"], _ = horizontal(heatmap.range_m[ri].astype(float), out["azimuth"], el)
        out["elevation"] = el
    return out


def strongest_points(points: np.ndarray, cells: int) -> np.ndarray:
    """The *cells* strongest of :func:`heatmap_doppler_points`' *points* (all when fewer), still
    in raster order: the same cells as asking it for *cells* directly (but for equal intensities
    at the last place, either of which may be taken)."""
    if len(points) <= cells:
        return points
    strongest = np.argpartition(points["intensity"], len(points) - cells)[len(points) - cells:]
    return points[np.sort(strongest)]


def azimuth_profile(heatmap: PolarHeatmap, config: FeatureConfig, grid_rad: np.ndarray) -> np.ndarray:
    """The heatmap's power summed over range in the region of interest, in dB, resampled
    onto body-frame bearings *grid_rad* (ascending, uniform); for the correlation guess
    of the rotation.  (len(grid_rad),)"""
    valid = roi_mask(heatmap, config)
    power = np.where(valid, heatmap.intensity, 0.0).sum(axis=0)
    db = 10.0 * np.log10(np.maximum(power, 1e-30))
    bearing = -heatmap.azimuth_rad[::-1]
    inside = np.abs(bearing) <= config.max_azimuth_rad
    return np.interp(grid_rad, bearing[inside], db[::-1][inside], left=np.nan, right=np.nan)
