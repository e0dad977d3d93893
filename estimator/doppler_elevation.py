"""Beyond the paper, for arrays without a raised antenna row (2 TX on the xWR18xx): each heatmap
cell's elevation from its dominant Doppler and the frame's own velocity
(``features.doppler_elevation``), and at rest the elevation each range bin had while the radar
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
``doppler_elevation_rest_s`` (a bin not seen within that time is taken as level).

The same frame's point cloud, where it has no elevation either (every point level: such an array
gives 0), gets its points' elevation the same way (:meth:`DopplerElevation.points_cos_elevation`):
in a turn each point's from its own radial velocity, at rest its range bin's; placed as level, a
reflector above or below the radar sits at cos(el) of its bearing's sine, and the points' map
measured turns short by the scene's cos(el) where the heatmap's cells had it (docs/heading.md,
item 33).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .config import FeatureConfig


class _RangeProfile:
    """Each range bin's cos(elevation) averaged over the moving frames, a frame's weight fading as
    exp(-age / *memory_s*): the weighted sums and when each bin was last seen, (n_range,) each."""

    def __init__(self, memory_s: float) -> None:
        self._memory_s = memory_s
        self.t = -math.inf  # the last moving frame's time, s
        self._cos_sum = self._weight = self._seen_t = np.zeros(0)

    def add(self, t: float, weight: float, cos_el: np.ndarray, seen: np.ndarray) -> None:
        """A moving frame at *t* (s): its bins' *cos_el* (n_range,) where *seen*, weighing *weight*.
        A heatmap of another range axis starts the profile afresh; a value that is not finite is
        left out."""
        seen = seen & np.isfinite(cos_el)
        if not math.isfinite(weight) or not seen.any():
            return
        if cos_el.shape != self._weight.shape:
            self._cos_sum, self._weight = np.zeros(cos_el.shape), np.zeros(cos_el.shape)
            self._seen_t = np.full(cos_el.shape, -math.inf)
        fade = math.exp(-max(t - self.t, 0.0) / self._memory_s) if math.isfinite(self.t) else 0.0
        w = np.where(seen, weight, 0.0)
        self._cos_sum = fade * self._cos_sum + w * np.where(seen, cos_el, 0.0)
        self._weight = fade * self._weight + w
        self._seen_t = np.where(seen, t, self._seen_t)
        self.t = t

    def cos_elevation(self, t: float, within_s: float, n_range: int) -> np.ndarray | None:
        """Each bin's cos(elevation) at *t* (n_range,), 1 (level) for a bin not seen within
        *within_s* before; None when no moving frame of this range axis was."""
        if self._weight.shape != (n_range,) or t - self.t > within_s:
            return None
        recent = (self._weight > 0) & (t - self._seen_t <= within_s)
        return np.divide(self._cos_sum, self._weight, out=np.ones(n_range), where=recent)


@dataclasses.dataclass(frozen=True)
class _FrameElevation:
    """How the last heatmap's cells got their elevation, for its frame's points: at rest its range
    axis (n_range,) m and each bin's cos(elevation) (n_range,); moving, the body velocity (2,) m/s
    the cells' Doppler was read against."""

    range_m: np.ndarray | None = None
    cos_per_bin: np.ndarray | None = None
    velocity: np.ndarray | None = None


class DopplerElevation:
    """:meth:`__call__` gives a heatmap without elevation its cells' elevation, and
    :meth:`points_cos_elevation` the same frame's points theirs (module docstring)."""

    def __init__(self, config: FeatureConfig) -> None:
        self._min_mps = config.doppler_elevation_min_mps
        self._turn_radps = config.doppler_elevation_turn_radps if config.doppler_elevation == "turns" else None
        self._rest_s = config.doppler_elevation_rest_s
        self._profile = _RangeProfile(config.doppler_elevation_memory_s)
        self._last: _FrameElevation | None = None  # the last heatmap's, None: it kept its own

    def __call__(self, heatmap, t: float, velocity: np.ndarray | None, yaw_rate_radps: float):
        """*heatmap* (taken at *t*, s) with ``elevation_rad`` (n_range, n_azimuth) rad: from its
        ``doppler_mps`` and the frame's own body *velocity* (2,) m/s when it moves forward or
        backward at ``doppler_elevation_min_mps`` or more (with "turns", only while the last
        measured *yaw_rate_radps* is above ``doppler_elevation_turn_radps``); slower than that
        every way, each range bin's from the moving frames before.  Unchanged when it has an
        elevation or no Doppler, or without a velocity of its own."""
        self._last = None
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
            per_bin = self._profile.cos_elevation(t, self._rest_s, shape[0])
            if float(np.hypot(*velocity)) >= self._min_mps or per_bin is None:
                return heatmap
            self._last = _FrameElevation(range_m=np.asarray(heatmap.range_m, dtype=float), cos_per_bin=per_bin)
            rows = np.arccos(np.clip(per_bin, 0.0, 1.0)).astype(np.float32)
            return dataclasses.replace(heatmap, elevation_rad=np.repeat(rows[:, None], shape[1], axis=1))
        r, a = np.divmod(cells, shape[1])
        u = np.sin(np.asarray(heatmap.azimuth_rad, dtype=float)[a])
        cos_el = _cos_elevation(u, doppler.ravel()[cells].astype(float), velocity)
        power = np.asarray(heatmap.intensity).ravel()[cells].astype(float)
        total = np.bincount(r, power, minlength=shape[0])
        weighted = np.bincount(r, power * cos_el, minlength=shape[0])
        # A bin's Doppler error is a part of the speed that shrinks as the speed grows: a frame
        # counts as its forward speed squared.
        with np.errstate(invalid="ignore"):  # a power that is not finite: left out by add
            per_bin = weighted / np.maximum(total, 1e-30)
        self._profile.add(t, float(velocity[0]) ** 2, per_bin, total > 0)
        if self._turn_radps is not None and abs(yaw_rate_radps) < self._turn_radps:
            return heatmap
        self._last = _FrameElevation(velocity=np.asarray(velocity, dtype=float))
        elevation = np.zeros(shape, np.float32)
        elevation.ravel()[cells] = np.arccos(cos_el)
        return dataclasses.replace(heatmap, elevation_rad=elevation)

    def points_cos_elevation(self, points: np.ndarray) -> np.ndarray | None:
        """The cos(elevation) (n,) of the *points* (TI frame, products.POINT_DTYPE) of the frame
        whose heatmap :meth:`__call__` was last given, as its cells got theirs: at rest their range
        bin's (at the point's slant range), moving from each one's radial velocity; None where the
        cells kept their own (or none) or the cloud has an elevation of its own."""
        frame = self._last
        if frame is None or len(points) == 0 or np.any(points["elevation"]):
            return None
        x, y = points["x"].astype(float), points["y"].astype(float)
        slant = np.hypot(x, y)  # level points: the measured range
        if frame.cos_per_bin is not None:
            return np.interp(slant, frame.range_m, frame.cos_per_bin)
        return _cos_elevation(x / np.maximum(slant, 1e-9), points["velocity"].astype(float), frame.velocity)


def _cos_elevation(u: np.ndarray, radial_mps: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """cos(elevation) (n,) of static reflectors on the azimuth axis *u* (n,) whose radial velocity
    is *radial_mps* (n,) m/s, seen from a sensor moving at the body *velocity* (2,) m/s (forward
    part nonzero): cos(el)^2 = ((vy u - v_r) / vx)^2 + u^2, at most 1."""
    w = (velocity[1] * u - radial_mps) / velocity[0]
    return np.sqrt(np.clip(w * w + u * u, 0.0, 1.0))


def doppler_elevation_part(config: FeatureConfig) -> DopplerElevation | None:
    """The part for ``features.doppler_elevation`` (None when "off")."""
    return None if config.doppler_elevation == "off" else DopplerElevation(config)
