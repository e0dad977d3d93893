"""The view's colours: a perceptual map for heatmaps and a diverging one for radial velocities.

Small tables interpolated when a view opens (no matplotlib: the view needs only Rerun).
"""

from __future__ import annotations

import numpy as np

#: viridis at nine evenly spaced values, 8-bit RGB (matplotlib's table, sampled).
_VIRIDIS = ((68, 1, 84), (71, 44, 122), (59, 81, 139), (44, 113, 142), (33, 144, 141), (39, 173, 129),
            (92, 200, 99), (170, 220, 50), (253, 231, 37))
#: Approaching (blue), still (light grey), receding (red).
_DIVERGING = ((33, 102, 172), (220, 220, 220), (178, 24, 43))


def _table(anchors: tuple[tuple[int, int, int], ...], size: int = 256) -> np.ndarray:
    """*anchors* interpolated to *size* colours, uint8 (size, 3)."""
    a = np.asarray(anchors, float)
    at = np.linspace(0.0, 1.0, len(a))
    x = np.linspace(0.0, 1.0, size)
    return np.stack([np.interp(x, at, a[:, c]) for c in range(3)], axis=1).round().astype(np.uint8)


class ColorMaps:
    """Values in [0, 1] to viridis, radial velocities to blue-grey-red (symmetric about zero)."""

    def __init__(self) -> None:
        self.sequential = _table(_VIRIDIS)
        self.diverging = _table(_DIVERGING)

    def heat(self, unit: np.ndarray) -> np.ndarray:
        """uint8 RGB (..., 3) of finite values in [0, 1] (a heatmap :func:`normalised`)."""
        return self.sequential[(unit * (len(self.sequential) - 1) + 0.5).astype(np.uint8)]

    def velocity(self, velocity_mps: np.ndarray, limit_mps: float) -> np.ndarray:
        """uint8 RGB (n, 3): blue approaching, red receding, full colour at +-*limit_mps*."""
        unit = 0.5 + 0.5 * np.asarray(velocity_mps, float) / max(limit_mps, 1e-6)
        return self.diverging[_index(unit, len(self.diverging))]


def _index(unit: np.ndarray, size: int) -> np.ndarray:
    u = np.nan_to_num(np.asarray(unit, float), nan=0.0)
    return np.clip((u * (size - 1)).round(), 0, size - 1).astype(np.intp)


def decibels(intensity: np.ndarray) -> np.ndarray:
    """10 log10 of a linear power map (float32), floored at the smallest positive value."""
    power = np.asarray(intensity, np.float32)
    positive = power[power > 0]
    floor = float(positive.min()) if positive.size else 1e-12
    return 10.0 * np.log10(np.maximum(power, floor))


def normalised(db: np.ndarray) -> np.ndarray:
    """A dB map scaled to [0, 1] between its median (the noise floor of a sparse scene) and its
    maximum: the same reflector keeps its colour while the noise floor stays dark."""
    lo, hi = float(np.median(db)), float(db.max())
    return np.clip((db - lo) / max(hi - lo, 1e-6), 0.0, 1.0)
