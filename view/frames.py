"""What the view is handed of each frame: its :class:`Track` (kept for every frame) and, when
the frame is drawn, its :class:`ViewHeatmap` beside its point cloud (:data:`FramePayload`).
The sink (:mod:`.sink`) makes them, the drawers hand them over, the scene (:mod:`.scene`)
draws them."""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..estimator.odometry import OdometryState

if TYPE_CHECKING:
    from ..products import RangeAzimuth


class Track(NamedTuple):
    """What the view keeps of every frame (never dropped): its index and time (s), the new
    odometry (None on a velocity-only frame or without an estimator), the point count (None
    without a point cloud), the latency until the view got it (s) and the true pose."""

    frame: int
    t: float
    state: OdometryState | None
    points: int | None
    latency_s: float
    pose: tuple[float, ...] | None


class ViewHeatmap(NamedTuple):
    """What the view draws of a frame's :class:`~radarodom.products.RangeAzimuth` (and the
    estimator's features read): all but the zero-Doppler map, a quarter less to hand over."""

    intensity: np.ndarray
    doppler_mps: np.ndarray
    range_m: np.ndarray
    azimuth_rad: np.ndarray
    elevation_rad: np.ndarray | None

    @classmethod
    def of(cls, heatmap: RangeAzimuth | None) -> ViewHeatmap | None:
        if heatmap is None:
            return None
        return cls(heatmap.intensity, heatmap.doppler_mps, heatmap.range_m, heatmap.azimuth_rad,
                   getattr(heatmap, "elevation_rad", None))


#: A frame to draw: its track, point cloud (POINT_DTYPE) and heatmap (either may be None).
FramePayload = tuple[Track, "np.ndarray | None", "ViewHeatmap | None"]
