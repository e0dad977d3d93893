"""Beyond the paper, for arrays without a raised antenna row (2 TX on the xWR18xx): each heatmap
cell's elevation from its dominant Doppler and the frame's own velocity
(``features.doppler_elevation``), and at rest the elevation each range bin had when the radar
last moved.

A static reflector at elevation el on the azimuth axis u = cos(el) sin(az) (TI frame, positive to
the right) seen from a sensor moving at (vx, vy) in its body frame has the radial velocity
v_r = -(vx cos(el) cos(az) - vy u), so that cos(el)^2 = ((vy u - v_r) / vx)^2 + u^2: the cone of
one Doppler crossed with the array's cone of one u.  The sign of el is not observable; the
registration needs only its cosine (features at r cos(el), sampled at cos(el) sin(bearing)).
Cells without a Doppler are taken as level.  A radar at rest (turning in place) has no Doppler
to tell elevation by, but it keeps its distance to everything around it: each range bin keeps
the elevation of its cells, power-weighted, from the frames that moved (floors and ceilings are
where they were), averaged over the last ``doppler_elevation_memory_s`` or so of them, for
``doppler_elevation_rest_s``.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .config import FeatureConfig


class DopplerElevation:
    """:meth:`__call__` gives a heatmap without elevation its cells' elevation (module docstring)."""

    def __init__(self, config: FeatureConfig) -> None:
        self._min_mps = config.doppler_elevation_min_mps
        self._turn_radps = config.doppler_elevation_turn_radps if config.doppler_elevation == "turns" else None
        self._rest_s = config.doppler_elevation_rest_s
        self._memory_s = config.doppler_elevation_memory_s
        #: The last moving frame's time (s) and, over the moving frames, each range bin's weighted
        #: sum of cos(elevation) and of the weights, (n_range,) each (a bin none of whose cells
        #: had a Doppler adds nothing).
        self._profile: tuple[float, np.ndarray, np.ndarray] | None = None

    def __call__(self, heatmap, t: float, velocity: np.ndarray | None, yaw_rate_radps: float):
        """*heatmap* (taken at *t*, s) with ``elevation_rad`` (n_range, n_azimuth) rad: from its
        ``doppler_mps`` and the frame's own body *velocity* (2,) m/s when it moves forward or
        backward at ``doppler_elevation_min_mps`` or more (with "turns", only while the last
        measured *yaw_rate_radps* is above ``doppler_elevation_turn_radps``); slower than that
        every way, each range bin's from the moving frames before.  Unchanged when it has an
        elevation or no Doppler, or without a velocity of its own."""
        if (not dataclasses.is_dataclass(heatmap) or getattr(heatmap, "elevation_rad", None) is not None
                or getattr(heatmap, "doppler_mps", None) is None or velocity is None):
            return heatmap
        doppler = np.asarray(heatmap.doppler_mps)
        # The DSP gives a Doppler to the strongest cells only: the arithmetic is on those.
        cells = np.flatnonzero(np.isfinite(doppler))
        if len(cells) == 0:
            return heatmap
        shape = doppler.shape
        if abs(velocity[0]) < self._min_mps:
            # Too slow along the boresight to tell: at rest the moving frames' profile; sliding
            # sideways, nothing.
            if (float(np.hypot(*velocity)) >= self._min_mps or self._profile is None
                    or t - self._profile[0] > self._rest_s):
                return heatmap
            _, cos_sum, weight = self._profile
            level = np.where(weight > 0, cos_sum / np.maximum(weight, 1e-30), 1.0)
            rows = np.arccos(np.clip(level, 0.0, 1.0)).astype(np.float32)
            return dataclasses.replace(heatmap, elevation_rad=np.repeat(rows[:, None], shape[1], axis=1))
        r, a = np.divmod(cells, shape[1])
        u = np.sin(np.asarray(heatmap.azimuth_rad, dtype=float)[a])
        w = (velocity[1] * u - doppler.ravel()[cells].astype(float)) / velocity[0]
        cos_el = np.sqrt(np.clip(w * w + u * u, 0.0, 1.0))
        power = np.asarray(heatmap.intensity).ravel()[cells].astype(float)
        total = np.bincount(r, power, minlength=shape[0])
        weighted = np.bincount(r, power * cos_el, minlength=shape[0])
        self._remember(t, float(velocity[0]) ** 2, weighted / np.maximum(total, 1e-30), total > 0)
        if self._turn_radps is not None and abs(yaw_rate_radps) < self._turn_radps:
            return heatmap
        elevation = np.zeros(shape, np.float32)
        elevation.ravel()[cells] = np.arccos(cos_el)
        return dataclasses.replace(heatmap, elevation_rad=elevation)

    def _remember(self, t: float, weight: float, cos_el: np.ndarray, seen: np.ndarray) -> None:
        """Add a moving frame's range profile *cos_el* (n_range,) where *seen*, weighing it by
        *weight* and the profiles before by their fading age."""
        shape = cos_el.shape
        cos_sum, total = (np.zeros(shape), np.zeros(shape)) if self._profile is None else self._profile[1:]
        fade = 0.0 if self._profile is None else np.exp(-(t - self._profile[0]) / self._memory_s)
        w = np.where(seen, weight, 0.0)
        self._profile = (t, fade * cos_sum + w * np.where(seen, cos_el, 0.0), fade * total + w)


def doppler_elevation_part(config: FeatureConfig) -> DopplerElevation | None:
    """The part for ``features.doppler_elevation`` (None when "off")."""
    return None if config.doppler_elevation == "off" else DopplerElevation(config)
