"""How much a heatmap cell's azimuth peak looks like one reflector's (``icp.field_shape_width``,
docs/heading.md item 22).

A reflector alone in its range bin draws the array's beam on the azimuth axis: a peak whose
log power curves as the beam does.  Several scatterers within one beam (a wall's, a piece of
furniture's) interfere: their peak is broader or sharper than the beam and lies where their
phases put it, which changes as the radar moves or turns, not as a fixed reflector would.  The
field search takes its points for fixed reflectors, so it weighs each by how like the frame's
usual peak (most are single reflectors') its peak is."""

from __future__ import annotations

import numpy as np

from .features import Features, PolarHeatmap

#: How far along its range bin a cell climbs to the peak it lies on, azimuth bins: a beam's
#: main lobe spans some eight bins of 64 for eight antennas, a cell on its flank is within four.
#: Climbing stops at the first maximum, so a narrower beam's cells stop at their own peak too.
CLIMB_BINS = 4


def cells_of(points: Features, heatmap: PolarHeatmap) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The heatmap's range and azimuth bin of each of *points* ((n,) each): the nearest bin to
    its slant range and to its direction cosine on the azimuth axis (cos(el) sin(azimuth), the
    bearing counter-clockwise, the azimuth axis clockwise); and whether that is its cell ((n,)
    bool): not for a point at the radar, nor for one whose bearing was clipped at 90 degrees
    when its elevation was taken out (``features.horizontal``: its direction cosine is lost)."""
    cos_el = points.cos_elevation
    sine = np.sin(points.bearing_rad)
    rows = _nearest(np.asarray(heatmap.range_m, float), points.slant_m)
    cols = _nearest(np.sin(np.asarray(heatmap.azimuth_rad, float)), -sine * (1.0 if cos_el is None else cos_el))
    return rows, cols, (np.abs(sine) < 1.0 - 1e-9) & (points.slant_m > 0)


def _nearest(axis: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Index of the nearest of the ascending *axis* (n_bins,) to each of *values* (n,)."""
    i = np.clip(np.searchsorted(axis, values), 1, len(axis) - 1)
    return np.where(values - axis[i - 1] < axis[i] - values, i - 1, i)


def peak_curvature(intensity: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """The second difference of the log power (nepers of power per bin squared, negative at a
    peak) along its range bin at the azimuth peak each cell (*rows*, *cols*: (n,) bin indices
    into *intensity*, (n_range, n_azimuth >= 3) linear power) climbs to within CLIMB_BINS; a
    peak on the axis's edge is taken one bin inside it; NaN where a power is NaN."""
    n_az = intensity.shape[1]
    flat = np.ascontiguousarray(intensity).ravel()
    start = np.asarray(rows, dtype=np.intp) * n_az  # each row's first cell in *flat*
    col = np.asarray(cols, dtype=np.intp).copy()
    for _ in range(CLIMB_BINS):
        here = flat[start + col]
        left = flat[start + np.maximum(col - 1, 0)]
        right = flat[start + np.minimum(col + 1, n_az - 1)]
        up = (right > here) & (right >= left) & (col < n_az - 1)
        down = (left > here) & ~up & (col > 0)
        col += up.astype(np.intp) - down.astype(np.intp)
    at = start + np.clip(col, 1, n_az - 2)
    log = np.log(np.maximum(flat[np.stack([at - 1, at, at + 1])].astype(float), 1e-30))
    return log[0] + log[2] - 2.0 * log[1]


def shape_weighted(points: Features, heatmap: PolarHeatmap, width: float, floor: float) -> Features:
    """*points* (cells of *heatmap*) with each weight times floor + (1 - floor) exp(-((q - 1) /
    width)^2), q its peak's curvature over the median of the points' peaks' (the frame's usual
    peak: most are single reflectors'), renormalised; a point whose peak cannot be read (its
    cell unknown, a NaN power) counts as unlike one (the floor).  As they are when fewer than
    three have a peak, or the azimuth axis has fewer than three bins."""
    intensity = np.asarray(heatmap.intensity)
    if len(points) < 3 or intensity.ndim != 2 or intensity.shape[1] < 3:
        return points
    rows, cols, known = cells_of(points, heatmap)
    curvature = peak_curvature(intensity, rows, cols)
    readable = known & np.isfinite(curvature)
    peaks = curvature[readable & (curvature < 0)]
    if len(peaks) < 3:
        return points
    q = curvature[readable] / float(np.median(peaks))
    like = np.zeros(len(points))
    like[readable] = np.exp(-np.square((q - 1.0) / width))
    weight = points.weight * (floor + (1.0 - floor) * like)
    return points.reweighted(weight) if weight.sum() > 0 else points
