"""The point cloud and the heatmap of a source frame: the source's own, or the DSP's.

Most sources give raw ADC frames, and the DSP makes both products.  A dataset may ship them
instead (ColoRadar's on-chip point clouds, its cascade radar's heatmaps), or ship one kind for
some frames and raw frames for others; TI's demo firmware ships points and zero-Doppler antenna
values, which the DSP's angle processing makes a heatmap of (``dsp.static_heatmap``).
:class:`FrameProducts` hides the difference from the pipeline: built once per source, called
once per frame.
"""

from __future__ import annotations

import math

import numpy as np

from ..calibration import RangeCoupling
from ..cfg import RadarConfig
from ..driver.sources import Frame, Source
from ..dsp.config import DspConfig
from ..dsp.heatmap import HeatmapMaker
from ..dsp.processor import FrameProcessor, heatmap_range_bins
from ..dsp.static_heatmap import StaticHeatmapMaker
from ..errors import CaptureError, ConfigError, UsageError
from ..estimator.config import FeatureConfig
from ..products import Products, RangeAzimuth


class FrameProducts:
    """Products of the frames of one source.

    *config*: the radar configuration of the source's raw frames (None when it has none: then
    no DSP is built); *dsp*: the DSP's settings (default: ``DspConfig()``).  *doppler_cells*:
    how many of the heatmap's strongest cells get their dominant Doppler (None: every cell, the
    full map; see dsp.heatmap.HeatmapMaker).  *full_heatmaps*: the outputs show full maps
    although *doppler_cells* limits the heatmaps made for the estimator (:meth:`shown_heatmap`).
    *coupling*: the source's TX-to-RX coupling to remove (``Source.coupling``); *calibrated*:
    whether the cfg's channel calibration is known to fit the source's board (``Source.calibrated``).
    """

    def __init__(self, config: RadarConfig | None, dsp: DspConfig | None = None, *,
                 doppler_cells: int | None = None, full_heatmaps: bool = False,
                 coupling: RangeCoupling | None = None, calibrated: bool | None = None) -> None:
        self.processor = (FrameProcessor(config, dsp, coupling=coupling, calibrated=calibrated)
                          if config is not None else None)
        self.heatmaps = None if self.processor is None else HeatmapMaker(self.processor, doppler_cells=doppler_cells)
        # The outputs' full maps, made apart: the estimator's heatmaps, and so its odometry, are
        # the same whatever the outputs show.
        self._full_maps = (HeatmapMaker(self.processor) if full_heatmaps and doppler_cells is not None
                           and self.processor is not None else None)
        # The DSP spectrum of the frame last called for, where it made (or could make) its heatmap.
        self._spectrum = None
        # A radar's own zero-Doppler antenna values (TI's demo): the same axes and calibration.
        self.static_maps = None if self.processor is None else StaticHeatmapMaker(self.processor)
        # Reused: no allocation per frame.
        self._cube = None if config is None else np.empty(config.cube_shape, np.complex64)

    @classmethod
    def for_estimator(cls, config: RadarConfig | None, features: FeatureConfig, dsp: DspConfig | None = None, *,
                      coupling: RangeCoupling | None = None, calibrated: bool | None = None) -> "FrameProducts":
        """Products for an estimator whose features are *features*: the Doppler of its
        ``doppler_cells`` strongest cells (``FeatureConfig.doppler_cells``), enough for its
        dynamic-object rejection and much cheaper than the full map's."""
        if not isinstance(features, FeatureConfig):
            hint = " (EstimatorConfig's .features)" if hasattr(features, "features") else ""
            raise UsageError(f"features: a FeatureConfig{hint}, got {type(features).__name__}")
        return cls(config, dsp, doppler_cells=features.doppler_cells, coupling=coupling, calibrated=calibrated)

    def __call__(self, frame: Frame, *, heatmap: bool = True) -> Products:
        """The products of *frame*.  The DSP's heatmap is made only when *heatmap* is true (it
        is the costly half of a velocity-only frame)."""
        if not isinstance(frame, Frame):
            raise UsageError(f"frame: a source's Frame (radarodom.driver.sources.Frame), got {type(frame).__name__}"
                             + (": the products are made of the frame, not its cube"
                                if isinstance(frame, np.ndarray) else ""))
        result = None
        self._spectrum = None
        if frame.raw is not None:
            if self.processor is None:
                raise CaptureError(f"frame {frame.index} carries raw samples but the source gave no radar "
                                   "configuration")
            result = self.processor.process(frame.cube(out=self._cube))
        points = frame.points if frame.points is not None else (None if result is None else result.points)
        hm = frame.heatmap
        if hm is None and result is not None:
            self._spectrum = result.spectrum
            if heatmap:
                hm = self.heatmaps.range_azimuth(result.spectrum)
        if hm is None and frame.static_antennas is not None and heatmap:
            if self.static_maps is None:
                raise CaptureError(f"frame {frame.index} carries antenna values but the source gave no radar "
                                   "configuration")
            hm = self.static_maps.range_azimuth(frame.static_antennas)
        return Products(points, hm)

    def shown_heatmap(self, products: Products) -> RangeAzimuth | None:
        """The heatmap the outputs show of the frame this was last called for (*products*, what
        the call gave): with *full_heatmaps*, the full map of the same DSP spectrum (made here,
        also for a frame whose heatmap the call did not make); else, or where the frame brought
        its own, the products' heatmap."""
        if self._full_maps is None or self._spectrum is None:
            return products.heatmap
        return self._full_maps.range_azimuth(self._spectrum)


def check_features_fit(source: Source, features: FeatureConfig, dsp: DspConfig | None = None) -> None:
    """Raise :class:`ConfigError` (field ``features.cfar``) when *features* cannot run on the
    heatmaps *source*'s frames will give: its own (``Source.heatmap_range_bins``) or the DSP's of
    its cfg (``Source.heatmaps_from_raw``); nothing when they are not known before the frames
    come (then the features' CFAR says so at the first).  What a pipeline checks when it is
    built, and a program before it replaces its outputs."""
    bins, reach = source.heatmap_range_bins, source.heatmap_reach_m
    if bins is None and source.heatmaps_from_raw and source.config is not None:
        bins = heatmap_range_bins(source.config, dsp)
        # (its heatmaps end at the cfg's usable range, or nearer: DspConfig.max_range_m, cfarFovCfg)
        reach = min(source.config.max_range_m, (dsp or DspConfig()).max_range_m or math.inf)
    if reach is not None and features.min_range_m >= reach:
        raise ConfigError(f"{features.min_range_m:g} m: the heatmaps reach {reach:.2f} m at most, so no cell "
                          f"would be a feature; features nearer than it are left out (default "
                          f"{FeatureConfig.min_range_m:g} m)", field="features.min_range_m")
    if bins is not None:
        features.check_heatmap_range(bins)
