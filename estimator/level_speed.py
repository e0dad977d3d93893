"""Beyond the paper, for point clouds without elevation (an array without a raised antenna row:
2 TX on the xWR18xx, or TI's demo run with such a cfg): the forward speed from the upper edge of
the points' Doppler (``velocity.level_edge_quantile``).

A static reflector at elevation el on the azimuth axis u = cos(el) sin(az) (TI frame, positive
to the right) seen from a sensor moving at (vx, vy) (body frame, y to the left) has
-v_r = vx sqrt(cos(el)^2 - u^2) - vy u.  A cloud without elevation is fitted as if every point were
level (reported at az = asin(u)), so a point above or below the horizon reads less forward speed
and the fit's vx is, roughly, the points' mean of sqrt(cos(el)^2 - u^2) / cos(az) times the truth:
2-5 % low in rooms and corridors (docs/heading.md, "2-TX arrays").  Each inlier's own forward speed,
(-v_r + vy u) / cos(az), is at most vx but for the Doppler's noise, reached by the level
reflectors, and cos(el) is flattest at the horizon, so the points pile up just under vx: the ratios
of those speeds to the fit's vx, pooled over the clouds of the last ``level_edge_window_s`` that
moved mostly forward or backward, have that edge at a high quantile, by which the fit's vx is
scaled.  The quantile reads the noise as speed where the noise is a large share of the speed
(slow, or among reflectors all at the radar's height: docs/heading.md item 26).  A cloud that
measures elevation passes unchanged.
"""

from __future__ import annotations

import collections
import dataclasses
import math

import numpy as np

from .config_velocity import VelocityConfig
from .velocity import OK, VelocityEstimate

#: Only points within this of boresight give a ratio: the ratio's noise grows as 1 / cos(az).
_MAX_AZIMUTH_RAD = math.radians(60.0)
#: Fewer pooled ratios than this give no edge (the fit is left as it is): some five clouds' inliers.
_MIN_RATIOS = 50
#: The largest scale: points reading their forward speed 23 % low would lie 40 degrees above or
#: below the horizon on average, beyond the antennas' beams; a larger edge is noise's or a crowd's.
_MAX_SCALE = 1.305  # 1 / cos(40 degrees)


class LevelSpeed:
    """Scales each elevation-less cloud's forward velocity by the edge of the pooled ratios."""

    def __init__(self, config: VelocityConfig) -> None:
        self._quantile = config.level_edge_quantile
        self._window_s = config.level_edge_window_s
        self._min_mps = config.level_edge_min_mps
        self._pool: collections.deque[tuple[float, np.ndarray]] = collections.deque()
        self.scale = 1.0  # the last edge used, for diagnosis

    def __call__(self, t: float, points: np.ndarray, est: VelocityEstimate) -> VelocityEstimate:
        """*est*, fitted to *points* at *t* (s), with vx scaled (:meth:`scaled`); its inliers'
        ratios pooled first when it moves forward or backward at ``level_edge_min_mps`` or more,
        and more so than sideways (a sideways speed puts its bearings' errors into the ratios).
        A cloud earlier than the last pooled one (the odometry refuses it) pools nothing."""
        if not self._applies(points, est):
            return est
        if self._pool and t < self._pool[-1][0]:
            return self._scaled(est)
        if abs(est.vx) >= self._min_mps and abs(est.vx) >= abs(est.vy):
            inliers = points[est.inlier_mask]
            az = np.asarray(inliers["azimuth"], dtype=float)
            near = np.abs(az) <= _MAX_AZIMUTH_RAD
            az = az[near]
            # The fit's bearing is -azimuth (TI frame): -v_r - vy sin(bearing) = -v_r + vy sin(az).
            own = -np.asarray(inliers["velocity"][near], dtype=float) + est.vy * np.sin(az)
            self._pool.append((t, own / (np.cos(az) * est.vx)))
        while self._pool and t - self._pool[0][0] > self._window_s:
            self._pool.popleft()
        ratios = [r for _, r in self._pool]
        if sum(len(r) for r in ratios) >= _MIN_RATIOS:
            # Fewer (after a stop, say) keep the edge found last: the scene has hardly changed.
            self.scale = float(np.clip(np.quantile(np.concatenate(ratios), self._quantile), 1.0, _MAX_SCALE))
        return self._scaled(est)

    def scaled(self, points: np.ndarray, est: VelocityEstimate) -> VelocityEstimate:
        """*est*, fitted to *points*, with vx and its variance scaled by the last edge found (none
        before one is), when *points* carry no elevation; also for the heatmap's Doppler
        fallback, which pools nothing (its cells are the heatmap's strongest, not the cloud's)."""
        return self._scaled(est) if self._applies(points, est) else est

    def _scaled(self, est: VelocityEstimate) -> VelocityEstimate:
        if self.scale == 1.0:
            return est
        gain = np.diag([self.scale, 1.0])
        return dataclasses.replace(est, vx=est.vx * self.scale, covariance=gain @ est.covariance @ gain,
                                   level_scale=self.scale)

    @staticmethod
    def _applies(points: np.ndarray, est: VelocityEstimate) -> bool:
        return est.status == OK and len(points) > 0 and not np.any(points["elevation"] != 0.0)


def level_speed_part(config: VelocityConfig) -> LevelSpeed | None:
    """The part for ``velocity.level_edge_quantile`` (None when it is off)."""
    return None if config.level_edge_quantile is None else LevelSpeed(config)
