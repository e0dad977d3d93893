"""Range-azimuth heatmaps from zero-Doppler antenna values a radar computed itself.

TI's demo firmware sends, per range bin, the zero-Doppler value of its first ``numVirtualAntAzim``
virtual antennas in chirp order, already multiplied by the cfg's compRangeBiasAndRxChanPhase
coefficients (its azimuth static heatmap; ``tidemo://``, docs/tidemo.md).  This module turns them
into the raw path's heatmap with the raw path's own parts, taken from its
:class:`~radarodom.dsp.processor.FrameProcessor`:

- the antennas' horizontal positions from the cfg's virtual array (TX order read from the chirps);
- the same zero-padded azimuth DFT as :class:`~radarodom.dsp.heatmap.HeatmapMaker` (the same bins,
  ascending azimuth, positive to the right);
- the same weights: the raw path multiplies a zero-Doppler value by its TDM phase (1 at zero
  Doppler) and by the calibration in use; the chip multiplied by the cfg's calibration, so the
  values are multiplied by the ratio (1 when the DSP uses the cfg's line, the line's inverse with
  ``DspConfig(channel_calibration=False)``): calibrated exactly once, like the raw path;
- the same range axis: the chip's bins (its FFT size is the samples rounded up to a power of
  two) less the range bias in use, up to the detection range.

The heatmap's ``intensity`` and ``static`` are both the zero-Doppler power (the demo sends no
other Doppler), and ``doppler_mps`` is NaN (unknown: the estimator keeps such cells).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..calibration import ChannelCalibration
from ..errors import ConfigError
from ..products import RangeAzimuth
from .processor import FrameProcessor


@dataclass(frozen=True)
class _Parts:
    """What one shape of antenna values needs: rows kept, weights, DFT, axes."""

    rows: int
    weights: np.ndarray | None  # complex64 (antennas,)
    dft_t: np.ndarray  # complex64 (antennas, n_az)
    range_m: np.ndarray
    doppler_mps: np.ndarray  # NaN, (rows, n_az)


class StaticHeatmapMaker:
    """Heatmaps of zero-Doppler antenna values (complex (range bins, antennas)) on the axes and
    with the calibration of *processor*'s raw path."""

    def __init__(self, processor: FrameProcessor) -> None:
        self.proc = processor
        n_az = processor.n_az
        k = np.arange(n_az) - n_az // 2  # ascending signed bins, as fft + fftshift give
        self._k = k
        #: Azimuth of each heatmap column, rad (HeatmapMaker's).
        self.azimuth_rad = np.arcsin(np.clip(2.0 * k / n_az, -1.0, 1.0))
        self._parts: dict[tuple[int, int], _Parts] = {}

    def parts(self, shape: tuple[int, int]) -> _Parts:
        """The parts for values shaped (range bins, antennas), made once per shape."""
        if shape not in self._parts:
            self._parts[shape] = self._make(*shape)
        return self._parts[shape]

    def _make(self, n_bins: int, n_el: int) -> _Parts:
        proc, cfg = self.proc, self.proc.cfg
        va = cfg.virtual_array
        h, v = va.h.ravel(), va.v.ravel()
        if not 0 < n_el <= len(h) or v[:n_el].any() or len(set(h[:n_el].tolist())) != n_el:
            raise ConfigError(f"{n_el} zero-Doppler antennas in chirp order are not one row of this cfg's virtual "
                              f"array (TX order {', '.join(f'TX{t}' for t in cfg.tx_order)})", path=cfg.path,
                              command="chirpCfg")
        dft = np.exp(-2j * np.pi * np.outer(self._k, h[:n_el]) / proc.n_az).astype(np.complex64)
        step = cfg.range_resolution_m * cfg.num_samples / n_bins
        range_m = np.arange(n_bins) * step - proc.calibration.range_bias_m
        rows = int(np.searchsorted(range_m, proc.detection_range_m[1], side="right"))
        used = proc.angle_weights[proc.n_doppler // 2, :n_el]
        chip = ChannelCalibration.from_config(cfg).for_array(va).ravel()[:n_el]
        ratio = np.divide(used, chip, out=np.zeros(n_el, np.complex128), where=chip != 0).astype(np.complex64)
        weights = None if np.allclose(ratio, 1.0, rtol=0, atol=1e-6) else ratio
        return _Parts(rows, weights, np.ascontiguousarray(dft.T), range_m[:rows],
                      np.full((rows, proc.n_az), np.nan, np.float32))

    def range_azimuth(self, values: np.ndarray) -> RangeAzimuth:
        """The heatmap of *values*, complex (range bins, antennas)."""
        p = self.parts(values.shape)
        x = np.asarray(values[:p.rows], np.complex64)
        if p.weights is not None:
            x = x * p.weights
        az = x @ p.dft_t  # (rows, n_az)
        power = (az.real ** 2 + az.imag ** 2).astype(np.float32)
        return RangeAzimuth(power, power, p.doppler_mps, p.range_m, self.azimuth_rad)
