"""What a caller gives the estimator, checked before it is used (:class:`~.odometry.RadarOdometry`'s
inputs): a time, a point cloud, a heatmap, a velocity.  Each wrong one is a :class:`UsageError`
(or :class:`TimeOrderError`) naming what was expected, rather than numpy's error from deep inside.
A NaN or inf where a measurement goes (a ROS point cloud pads with NaN) is no measurement: such
points are left out and such heatmap cells hold no power (:func:`finite_points`,
:func:`finite_heatmap`); so are a cloud's repeated points, and its weakest past
:data:`MAX_CLOUD_POINTS` (:func:`distinct_points`, :func:`strongest_points`)."""

from __future__ import annotations

import copy
import math

import numpy as np

from ..errors import TimeOrderError, UsageError
from ..plain_numbers import is_number
from .velocity import VelocityEstimate

#: What the velocity fit reads of each point (the DSP's POINT_DTYPE has them).
POINT_FIELDS = ("azimuth", "elevation", "velocity")
#: ... and what the points' yaw (``point_yaw``, the blend's) reads too.
POINT_YAW_FIELDS = (*POINT_FIELDS, "x", "y")
#: A point's position (m) or radial velocity (m/s) larger than this is no measurement: no radar
#: the estimator reads sees so far or so fast, and the points' map's covariances of such a point
#: cannot be inverted (a garbled packet's 1e30 m stopped the run).
MAX_POINT_VALUE = 1e4
#: The most points of a frame the estimator takes (the strongest). The radars it reads give dozens to
#: a few hundred a frame; the points' map pairs each point with the others near it, so thousands
#: crowded into a place (a record repeated with a jitter) took time and memory growing with their
#: square, gigabytes a frame.
MAX_CLOUD_POINTS = 500


def check_time(t: float, what: str) -> None:
    if not is_number(t):
        raise UsageError(f"{what} at t={t!r}: a time is a number of seconds, got {type(t).__name__}")
    if not math.isfinite(t):
        raise TimeOrderError(f"{what} at t={t}: a time must be a finite number of seconds")


def check_points(points, fields: tuple[str, ...] = POINT_FIELDS) -> None:
    """:class:`UsageError` unless *points* is a point cloud: a (n,) structured array with *fields*
    (those the estimator reads), each a real number a point."""
    names = getattr(getattr(points, "dtype", None), "names", None) or ()
    if not isinstance(points, np.ndarray) or points.ndim != 1 or any(f not in names for f in fields):
        shape = f" {points.shape}" if isinstance(points, np.ndarray) else ""
        raise UsageError(f"points: a (n,) structured array with fields {', '.join(fields)} "
                         f"(radarodom.products.POINT_DTYPE), got {type(points).__name__}{shape}"
                         + (f" with fields {', '.join(names)}" if names else ""))
    for name in fields:
        kind = points.dtype[name]
        if kind.shape or kind.kind not in "fiu":
            raise UsageError(f"points: field {name} must be a real number a point (float), got {kind}")


def check_heatmap(heatmap) -> None:
    """:class:`UsageError` unless *heatmap* has a (n_range, n_azimuth) intensity of real numbers on
    its axes (1-D arrays of at least 2 increasing finite numbers), and its other cell arrays the
    intensity's shape, of real numbers too."""
    try:
        shape = np.shape(heatmap.intensity)
        axes = (len(heatmap.range_m), len(heatmap.azimuth_rad))
    except (AttributeError, TypeError):
        raise UsageError("heatmap: a range-azimuth heatmap (radarodom.products.RangeAzimuth: intensity, "
                         f"range_m, azimuth_rad), got {type(heatmap).__name__}") from None
    if shape != axes or 0 in axes:
        raise UsageError(f"heatmap: its intensity {shape} must be (range bins, azimuth bins) = {axes}, none empty")
    for name in ("range_m", "azimuth_rad"):
        axis = getattr(heatmap, name)
        if not isinstance(axis, np.ndarray) or axis.ndim != 1 or axis.dtype.kind not in "fiu":
            got = f"{axis.dtype} array" if isinstance(axis, np.ndarray) else type(axis).__name__
            raise UsageError(f"heatmap: {name} must be a (n,) numpy array of numbers, got {got}")
        if not np.isfinite(axis).all():
            raise UsageError(f"heatmap: {name} holds NaN or inf; its axes must be finite")
    for name in ("intensity", "static", "doppler_mps", "elevation_rad"):
        cells = getattr(heatmap, name, None)
        if cells is None:
            continue
        if np.shape(cells) != shape:
            raise UsageError(f"heatmap: {name} {np.shape(cells)} must be the intensity's shape, (range bins, "
                             f"azimuth bins) = {shape}")
        if np.asarray(cells).dtype.kind not in "fiu":
            raise UsageError(f"heatmap: {name} must hold real numbers, got {np.asarray(cells).dtype}")
    for name in ("range_m", "azimuth_rad"):  # the log-polar resampling divides by each one's span
        axis = getattr(heatmap, name)
        if len(axis) < 2 or not (np.diff(axis) > 0).all():
            raise UsageError(f"heatmap: {name} must hold at least 2 bins, increasing (" + (
                f"{len(axis)} given)" if len(axis) < 2 else f"{axis[0]:g} .. {axis[-1]:g} given, not increasing)"))


def finite_points(points: np.ndarray, fields: tuple[str, ...] = POINT_FIELDS) -> np.ndarray:
    """*points* (a checked cloud, :func:`check_points`) without those whose *fields* hold NaN or
    inf, or a position or velocity past :data:`MAX_POINT_VALUE`; *points* itself when there are none."""
    keep = np.ones(len(points), bool)
    for name in fields:
        values = points[name]
        keep &= np.abs(values) <= MAX_POINT_VALUE if name in ("x", "y", "velocity") else np.isfinite(values)
    return points if keep.all() else points[keep]


def distinct_points(points: np.ndarray, fields: tuple[str, ...] = POINT_FIELDS) -> np.ndarray:
    """*points* (finite ones, :func:`finite_points`) without those equal in all *fields* to an
    earlier one, in their order; *points* itself when none repeats. A repeated record (a source
    that sends a point twice) measures nothing new, and a frame of one point repeated many times
    would pair every copy with every other in the points' map."""
    if len(points) < 2:
        return points
    values = np.stack([np.asarray(points[name], float) for name in fields])  # (fields, n)
    order = np.lexsort(values)  # stable: a repeat sorts after the point it repeats
    repeat = (values[:, order[1:]] == values[:, order[:-1]]).all(0)
    if not repeat.any():
        return points
    keep = np.ones(len(points), bool)
    keep[order[1:][repeat]] = False
    return points[keep]


def strongest_points(points: np.ndarray, limit: int = MAX_CLOUD_POINTS) -> np.ndarray:
    """The *limit* strongest of *points* by their ``snr_db`` (the first *limit* of a cloud without
    one), in their order; *points* itself when it holds no more."""
    if len(points) <= limit:
        return points
    if "snr_db" not in (points.dtype.names or ()):
        return points[:limit]
    strength = np.nan_to_num(np.asarray(points["snr_db"], float), nan=-np.inf)
    return points[np.sort(np.argsort(-strength, kind="stable")[:limit])]


def finite_heatmap(heatmap):
    """*heatmap* (a checked one, :func:`check_heatmap`) with the cells whose intensity or static
    power is NaN or inf given none (0); *heatmap* itself when there are none, else a shallow copy
    with new intensity / static arrays (the caller's arrays are left as they are)."""
    changed = {}
    for name in ("intensity", "static"):
        cells = getattr(heatmap, name, None)
        if cells is not None and not np.isfinite(cells).all():
            changed[name] = np.where(np.isfinite(cells), cells, 0).astype(np.asarray(cells).dtype, copy=False)
    if not changed:
        return heatmap
    heatmap = copy.copy(heatmap)
    for name, cells in changed.items():
        setattr(heatmap, name, cells)
    return heatmap


def check_velocity(est) -> None:
    """:class:`UsageError` unless *est* is a :class:`~.velocity.VelocityEstimate`."""
    if not isinstance(est, VelocityEstimate):
        raise UsageError(f"velocity: a VelocityEstimate (radarodom.estimator.velocity), got {type(est).__name__}")
