"""What a frame yields: a point cloud and a range-azimuth heatmap.

The types every layer shares: the DSP makes them, datasets ship them (ColoRadar's on-chip
point clouds, its cascade radar's heatmaps), the estimator, the sinks and the wire formats
take them.  This module imports nothing of ``dsp/`` or ``driver/``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: One detected point (TI sensor frame; SI units, radians).
POINT_DTYPE = np.dtype([
    ("x", "f4"), ("y", "f4"), ("z", "f4"),  # m
    ("range", "f4"),  # m
    ("azimuth", "f4"), ("elevation", "f4"),  # rad; azimuth positive to the right
    ("velocity", "f4"),  # m/s radial, positive receding
    # dB: the cell over the mean noise power of the summed map (the CFAR estimate over its
    # method's bias, CfarParams.noise_factor), and that mean noise power
    ("snr_db", "f4"), ("noise_db", "f4"),
    ("range_bin", "i2"), ("doppler_bin", "i2"),  # Doppler bin signed: 0 is zero velocity
])


@dataclass
class RangeAzimuth:
    """A polar range-azimuth heatmap; arrays (n_range, n_azimuth)."""

    intensity: np.ndarray  # power over all Doppler bins, linear
    static: np.ndarray  # power in the zero-Doppler bin(s), linear (ColoRadar's: a copy of intensity)
    doppler_mps: np.ndarray  # radial velocity of the strongest Doppler bin, m/s (between bins where they are wide)
    range_m: np.ndarray  # (n_range,)
    azimuth_rad: np.ndarray  # (n_azimuth,), ascending, positive to the right
    #: The elevation of each cell's power, rad, positive up (from the raised antennas' phase);
    #: None where the array has no raised row.  The azimuth axis is arcsin of the direction's
    #: sideways component: a cell at elevation el lies at azimuth arcsin(sin(az_axis) / cos(el)),
    #: horizontal range r cos(el), height r sin(el).
    elevation_rad: np.ndarray | None = None


@dataclass
class RangeAzimuthElevation:
    """A polar 3-D heatmap; arrays (n_range, n_elevation, n_azimuth)."""

    intensity: np.ndarray
    static: np.ndarray
    range_m: np.ndarray
    azimuth_rad: np.ndarray
    elevation_rad: np.ndarray


@dataclass
class Products:
    """What one frame gives: a point cloud (:data:`POINT_DTYPE`, (n,)) and a range-azimuth
    heatmap; either may be None (a velocity-only frame has no heatmap)."""

    points: np.ndarray | None
    heatmap: RangeAzimuth | None
