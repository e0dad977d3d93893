"""Pure conversions of ColoRadar data: quaternions (xyzw, Hamilton), ADC frames to radarodom's
cube, point clouds and heatmaps from the dataset's frame (x forward, y left, z up) to the TI
sensor frame (x right, y forward; docs/conventions.md).

Split out of :mod:`.coloradar`, which re-exports all of it.
"""

from __future__ import annotations

import numpy as np

from ...errors import UsageError
from ...products import POINT_DTYPE, RangeAzimuth
from .files import HeatmapConfig

# ---------------------------------------------------------------------------------------------
# Quaternions (xyzw, Hamilton)


def quaternion_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b of quaternions (..., 4) xyzw (broadcasting)."""
    ax, ay, az, aw = np.moveaxis(np.asarray(a, float), -1, 0)
    bx, by, bz, bw = np.moveaxis(np.asarray(b, float), -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def quaternion_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Vectors (..., 3) rotated by unit quaternions (..., 4) xyzw (broadcasting)."""
    q = np.asarray(q, float)
    u, w = q[..., :3], q[..., 3:]
    # v' = v + 2 w (u x v) + 2 u x (u x v): the rotation without building matrices.
    uv = np.cross(u, v)
    return v + 2.0 * (w * uv + np.cross(u, uv))


def slerp(q0: np.ndarray, q1: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Spherical interpolation between unit quaternions (n, 4) at fractions *alpha* (n,) in [0, 1],
    along the shorter arc."""
    q0 = np.asarray(q0, float)
    q1 = np.asarray(q1, float).copy()
    alpha = np.asarray(alpha, float)[:, None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1[dot[:, 0] < 0] *= -1.0  # q and -q are the same rotation: take the short way
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    near = sin_theta < 1e-6  # (almost) equal: the linear blend is exact to rounding
    safe = np.where(near, 1.0, sin_theta)
    w0 = np.where(near, 1.0 - alpha, np.sin((1.0 - alpha) * theta) / safe)
    w1 = np.where(near, alpha, np.sin(alpha * theta) / safe)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


# ---------------------------------------------------------------------------------------------
# Pure conversions


def adc_to_cube(adc: np.ndarray) -> np.ndarray:
    """A ColoRadar ADC frame (tx, rx, chirp, sample) as radarodom's cube (loops, tx_slots, rx,
    samples) complex64 (rawframe.RawLayout): a chirp of ColoRadar's frame is one loop of ours,
    its TX is the slot.  The values are unchanged (I real, Q imaginary, ADC counts)."""
    adc = np.asarray(adc)
    if adc.ndim != 4:
        raise UsageError(f"an ADC frame is (tx, rx, chirp, sample), got shape {adc.shape}")
    return np.ascontiguousarray(adc.transpose(2, 0, 1, 3), dtype=np.complex64)


def pointcloud_to_points(pc: np.ndarray) -> np.ndarray:
    """A ColoRadar radar point cloud (n, 5) x, y, z (m; x forward, y left, z up), intensity (SNR
    dB), doppler (m/s, positive receding) as POINT_DTYPE (n,) in the TI sensor frame:
    x_TI = -y, y_TI = x, z_TI = z; azimuth atan2(x_TI, y_TI) (positive to the right); elevation
    asin(z / r).  TI's point clouds carry no noise estimate nor bins: noise_db 0, bins -1."""
    pc = np.asarray(pc)
    if pc.ndim != 2 or pc.shape[1] != 5:
        raise UsageError(f"a ColoRadar point cloud is (n, 5), got shape {pc.shape}")
    pts = np.zeros(len(pc), POINT_DTYPE)
    x_ti, y_ti, z_ti = -pc[:, 1], pc[:, 0], pc[:, 2]
    r = np.sqrt(x_ti.astype(float) ** 2 + y_ti.astype(float) ** 2 + z_ti.astype(float) ** 2)
    pts["x"], pts["y"], pts["z"], pts["range"] = x_ti, y_ti, z_ti, r
    pts["azimuth"] = np.arctan2(x_ti, y_ti)
    pts["elevation"] = np.arcsin(np.clip(z_ti / np.maximum(r, 1e-9), -1.0, 1.0))
    pts["velocity"] = pc[:, 4]
    pts["snr_db"] = pc[:, 3]
    pts["range_bin"] = -1
    pts["doppler_bin"] = -1
    return pts


def points_in_frame(points: np.ndarray, bearing_offset_rad: float) -> np.ndarray:
    """*points* (POINT_DTYPE, TI sensor frame of one radar) as seen from a radar at the same
    place turned *bearing_offset_rad* to the right of it (the lever arm between the two is
    ignored, as the paper does): azimuth minus the offset, x and y turned with it."""
    out = points.copy()
    out["azimuth"] = points["azimuth"] - bearing_offset_rad
    horizontal = np.hypot(points["x"], points["y"])
    out["x"] = horizontal * np.sin(out["azimuth"])
    out["y"] = horizontal * np.cos(out["azimuth"])
    return out


def heatmap_to_polar(hm: np.ndarray, cfg: HeatmapConfig, *, reduce: str = "max") -> RangeAzimuth:
    """A ColoRadar heatmap (el, az, range, 2) as a range-azimuth map in the TI convention.

    The elevation axis is reduced by ``"max"`` or ``"sum"`` of the intensity; the Doppler of
    each cell is that of its brightest elevation bin in both cases.  ColoRadar's azimuth is
    positive to the left, TI's to the right: azimuth_TI = -az, and the azimuth axis is reversed
    so that it ascends.  Returns arrays (range, az) float32; ``static`` is a copy of the
    intensity (ColoRadar keeps no zero-Doppler channel).
    """
    if reduce not in ("max", "sum"):
        raise UsageError(f"reduce must be 'max' or 'sum', got {reduce!r}")
    hm = np.asarray(hm)
    if hm.shape != cfg.shape:
        raise UsageError(f"the heatmap is shaped {hm.shape}, its config says {cfg.shape}")
    intensity, doppler = hm[..., 0], hm[..., 1]  # (el, az, range)
    best = np.argmax(intensity, axis=0)[None]  # (1, az, range)
    best_doppler = np.take_along_axis(doppler, best, axis=0)[0]
    reduced = intensity.max(axis=0) if reduce == "max" else intensity.sum(axis=0)
    # (az, range) -> (range, az), then reverse the azimuth axis for TI's sign.
    inten = np.ascontiguousarray(reduced.T[:, ::-1], dtype=np.float32)
    return RangeAzimuth(intensity=inten, static=inten.copy(),
                        doppler_mps=np.ascontiguousarray(best_doppler.T[:, ::-1], dtype=np.float32),
                        range_m=cfg.range_m, azimuth_rad=-np.asarray(cfg.azimuth_bins)[::-1].copy())
