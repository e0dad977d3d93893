"""Beyond the paper, for arrays without a raised antenna row (2 TX on the xWR18xx): each heatmap
cell's elevation from its dominant Doppler and the frame's own velocity
(``features.doppler_elevation``).

A static reflector at elevation el on the azimuth axis u = cos(el) sin(az) (TI frame, positive to
the right) seen from a sensor moving at (vx, vy) in its body frame has the radial velocity
v_r = -(vx cos(el) cos(az) - vy u), so that cos(el)^2 = ((vy u - v_r) / vx)^2 + u^2: the cone of
one Doppler crossed with the array's cone of one u.  The sign of el is not observable; the
registration needs only its cosine (features at r cos(el), sampled at cos(el) sin(bearing)).
Cells without a Doppler are taken as level.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .config import FeatureConfig


class DopplerElevation:
    """:meth:`__call__` gives a heatmap without elevation its cells' elevation from the Doppler."""

    def __init__(self, config: FeatureConfig) -> None:
        self._min_mps = config.doppler_elevation_min_mps
        self._turn_radps = config.doppler_elevation_turn_radps if config.doppler_elevation == "turns" else None

    def __call__(self, heatmap, velocity: np.ndarray | None, yaw_rate_radps: float):
        """*heatmap* with ``elevation_rad`` (n_range, n_azimuth) rad from its ``doppler_mps`` and
        the frame's own body *velocity* (2,) m/s; unchanged when it has an elevation or no
        Doppler, without a velocity, below the forward speed, or (with "turns") while the last
        measured *yaw_rate_radps* is below the turn rate."""
        if (not dataclasses.is_dataclass(heatmap) or getattr(heatmap, "elevation_rad", None) is not None
                or getattr(heatmap, "doppler_mps", None) is None):
            return heatmap
        if velocity is None or velocity[0] < self._min_mps:
            return heatmap
        if self._turn_radps is not None and abs(yaw_rate_radps) < self._turn_radps:
            return heatmap
        u = np.sin(np.asarray(heatmap.azimuth_rad, dtype=float))[None, :]
        radial = np.asarray(heatmap.doppler_mps, dtype=float)
        w = (velocity[1] * u - radial) / velocity[0]
        cos2 = np.clip(w * w + u * u, 0.0, 1.0)
        elevation = np.where(np.isfinite(radial), np.arccos(np.sqrt(cos2)), 0.0).astype(np.float32)
        return dataclasses.replace(heatmap, elevation_rad=elevation)


def doppler_elevation_part(config: FeatureConfig) -> DopplerElevation | None:
    """The part for ``features.doppler_elevation`` (None when "off")."""
    return None if config.doppler_elevation == "off" else DopplerElevation(config)
