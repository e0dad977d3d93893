"""The heatmap frame being processed, and what is made of it once for every chain that asks.

With ``point_yaw.blend`` two estimators (the heatmaps' chain and the points', estimator/heading_blend.py)
take each heatmap frame in the same call and, for the same heatmap and mostly the same velocity,
derive the same features, moving cells, log heatmap and likelihood field from it.  A
:class:`FrameProducts` lives for one such call: each product is made by the first chain that asks
and handed to the other when everything it depends on is the same (the heatmap object, the
settings, the velocity to the last bit), so that both chains get exactly what they would have made
themselves.
"""

from __future__ import annotations

import json
from functools import cached_property
from typing import Any, Callable, Hashable

import numpy as np

from .config import EstimatorConfig, FeatureConfig
from .features import Features, PolarHeatmap, extract
from .icp import Region
from .log_heatmap import LogHeatmap


def settings_key(section: Any) -> str:
    """A settings section (a config dataclass with ``to_dict``) as a key: equal settings, equal keys."""
    return json.dumps(section.to_dict(), sort_keys=True)


def velocity_key(velocity: np.ndarray | None) -> tuple[float, ...] | None:
    """A velocity (2,) m/s (None: unknown) as a key, exact to the bit."""
    return None if velocity is None else tuple(float(v) for v in np.asarray(velocity).ravel())


def features_key(points: Features) -> tuple[bytes, ...]:
    """*points* by their contents: the same cells with the same weights, the same key."""
    height = b"" if points.height_m is None else np.asarray(points.height_m).tobytes()
    return tuple(np.asarray(a).tobytes() for a in (points.range_m, points.bearing_rad, points.weight,
                                                   points.intensity)) + (height,)


class FrameProducts:
    """What one heatmap frame's call has made, by what it was made from (see the module docstring)."""

    def __init__(self) -> None:
        self._made: dict[Hashable, Any] = {}
        #: The heatmaps whose identity keys the products: kept alive while the products are, so
        #: that no other heatmap can take one's identity.
        self._heatmaps: dict[int, PolarHeatmap] = {}

    def get_for(self, heatmap: PolarHeatmap, key: tuple, make: Callable[[], Any]) -> Any:
        """The product of *heatmap* (that very object) under *key*, made by *make* the first time
        it is asked for."""
        full = (id(heatmap),) + key
        try:
            return self._made[full]
        except KeyError:
            self._heatmaps[id(heatmap)] = heatmap
            made = self._made[full] = make()
            return made


class CurrentFrame:
    """The heatmap being processed and its log heatmap, made once when first needed (the scan
    guess, the field and the keyframe share it).  Not kept: the heatmap is the caller's.
    *products*: the products of the call, shared with another chain (:class:`FrameProducts`);
    None: a chain alone, which makes each once anyway."""

    def __init__(self, t: float, heatmap: PolarHeatmap, config: EstimatorConfig,
                 products: FrameProducts | None = None) -> None:
        self.t = t
        self.heatmap = heatmap
        self._features_config = config.features
        self.products = products
        features = config.features
        #: Where the frame can see, as a registration target.
        self.region = Region(features.min_range_m, features.max_range_m or float(np.max(heatmap.range_m)),
                             features.max_azimuth_rad)
        self._moving: np.ndarray | None = None
        self._moving_key: Hashable = None

    def made(self, key: tuple | Callable[[], tuple], make: Callable[[], Any]) -> Any:
        """The product of this frame's heatmap under *key* (what else it is made from; or a
        function giving it, called only when there is a chain to share with), made by *make*
        unless a chain made it already in this call."""
        if self.products is None:
            return make()
        return self.products.get_for(self.heatmap, key() if callable(key) else key, make)

    def features(self, config: FeatureConfig, key: str, velocity: np.ndarray | None = None) -> Features:
        """The heatmap's features by *config* (whose :func:`settings_key` is *key*, worked out once
        by the caller), moving ones left out given the *velocity* (2,) m/s (:func:`.features.extract`)."""
        return self.made(("features", key, velocity_key(velocity)), lambda: extract(self.heatmap, config, velocity))

    @cached_property
    def _features_key(self) -> str:
        return settings_key(self._features_config)

    @property
    def moving(self) -> np.ndarray | None:
        """Cells whose Doppler says they move (n_range, n_azimuth), to leave out of the log
        heatmap; None: none left out.  Set by :meth:`set_moving`, before :attr:`log` is first made."""
        return self._moving

    def set_moving(self, make: Callable[[], np.ndarray], key: tuple) -> None:
        """The moving cells, made by *make* from what *key* names (unless made already)."""
        self._moving_key = key
        self._moving = self.made(("moving",) + key, make)

    @cached_property
    def log(self) -> LogHeatmap:
        return self.made(lambda: ("log", self._features_key, self._moving_key),
                         lambda: LogHeatmap(self.heatmap, self._features_config, self.moving))

    def smoothed(self, sigma_bins: float, upsampling: int) -> LogHeatmap:
        """:attr:`log` smoothed (:meth:`LogHeatmap.smoothed`): the likelihood field."""
        return self.made(lambda: ("smoothed", self._features_key, self._moving_key, sigma_bins, upsampling),
                         lambda: self.log.smoothed(sigma_bins, upsampling))
