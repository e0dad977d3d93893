"""The packets TI's demo firmware would send for a raw frame: what the fake AWR1843's data port
streams (:mod:`.fake_demo_uart`).

The chip's processing is modelled with radarodom's DSP in TI's mode (``DspConfig(ti_like=True)``:
the cfg's cfarCfg thresholds and peak grouping, its clutterRemoval, multiObjBeamForming,
aoaFovCfg and cfarFovCfg), on the demo's FFT sizes (samples and loops rounded up to powers of two):

- points: the detections' x, y, z and radial velocity, on the FFTs' bins as the demo places them
  (radial velocity at its Doppler bin's centre, Wx from the azimuth FFT's peak bin, no sub-bin
  interpolation); side info: their SNR and noise in 0.1 dB;
- the azimuth static heatmap: the zero-Doppler bin of the windowed Doppler spectrum of the first
  ``numVirtualAntAzim`` antennas in chirp order, multiplied by the cfg's compRangeBiasAndRxChanPhase
  coefficients (``aoaprochwa.c`` ``AoAProcHWA_PrepareRangeAzimuthHeatmap``), as int16 (imaginary,
  real).  The HWA's fixed-point scaling is not documented to the bit: the values are scaled so that
  a tone of amplitude *a* ADC LSB reads 256 *a* (:data:`HEATMAP_GAIN`), which keeps the simulator's
  scenes inside int16 (the strongest cell of the room about 14000, of the corridor about 6000; the
  corridor's median cell about 40) and saturates beyond, counted in :attr:`DemoFrameMaker.saturated`;
- range profile, noise profile and range-Doppler map (when guiMonitor asks): the log2 magnitude of
  the power summed over the antennas, in Q9 (uint16), Doppler bin 0 first as the chip's matrix.

With ``measureRangeBiasAndRxChanPhase 1 <targetDistance> <searchWin>`` in the cfg, each frame also
gives the line the demo prints on its CLI port (:meth:`DemoFrameMaker.measurement_line`), measured
as TI's DPC does (``DPC_ObjDet_rangeBiasRxChPhaseMeasure``): the first chirp of each TX, the peak of
the power summed over the 12 antennas within targetDistance +/- searchWin / 2, a parabola through
its magnitude for the range bias, and ``conj(x) * min|x| / |x|^2`` of each antenna's sample x,
printed in physical TX, RX order with the demo's decimals (``MmwDemo_measurementResultOutput``).
With ``clutterRemoval`` on, the static clutter is taken out of the cube before the measurement,
as the DPC runs it first (a still reflector then measures as noise).

The chip's own quirks beyond these (its fixed-point CFAR, its exact windows) are not modelled.
"""

from __future__ import annotations

import numpy as np

from ...calibration import ChannelCalibration
from ...cfg import RadarConfig
from ...dsp.config import DspConfig
from ...dsp.processor import FrameProcessor
from ...rawframe import RawLayout
from ..tidemo import wire
from ..tidemo.layout import DemoGeometry, gui_selection

#: Heatmap value of a tone of amplitude 1 ADC LSB.
HEATMAP_GAIN = 256.0
#: The DSP's clock, whose cycles the header's timeCpuCycles counts (xWR18xx: 600 MHz C674x).
DSP_CLOCK_HZ = 600e6


class DemoFrameMaker:
    """Demo packets of *config*'s raw frames."""

    def __init__(self, config: RadarConfig) -> None:
        self.config = config
        self.geometry = g = DemoGeometry.from_config(config)
        self.layout = g.layout(gui_selection(config))
        # The demo places a point on its cell's bins: radial velocity dopplerStep x the Doppler bin,
        # Wx = 2 k / 64 of the azimuth FFT's peak bin k (aoaprochwa.c, AoAProcHWA_XYZestimation),
        # not between them as radarodom's DSP does.
        params = DspConfig(ti_like=True, doppler_interpolation=False, azimuth_interpolation=False,
                           range_fft_size=g.range_bins if g.range_bins != config.num_samples else None,
                           doppler_fft_size=g.doppler_bins if g.doppler_bins != config.num_loops else None)
        self.processor = p = FrameProcessor(config, params)
        self.raw_layout = RawLayout.from_config(config)
        self._cube = np.empty(config.cube_shape, np.complex64)
        n_ant = len(g.heatmap_elements)
        calibration = ChannelCalibration.from_config(config).for_array(config.virtual_array).ravel()[:n_ant]
        self._weights = (calibration * HEATMAP_GAIN / (float(p.w_range.sum()) * float(p.w_doppler.sum()))
                         ).astype(np.complex64)
        #: Heatmap values clipped to int16 so far.
        self.saturated = 0
        self._measure = config.channel_measurement
        clutter = config.clutter_removal
        self._clutter_removed = clutter is not None and bool(clutter.enabled)
        #: The measurement line of the last frame made (None when the cfg does not ask for it).
        self.measurement: str | None = None

    def packet(self, raw, frame_number: int, time_s: float) -> tuple[bytes, int]:
        """The packet of the raw frame *raw* (bytes of the DCA1000 layout) and its point count."""
        g, p = self.geometry, self.processor
        cube = self.raw_layout.decode(np.frombuffer(raw, np.uint8), self._cube)
        if self._measure is not None:
            self.measurement = self.measurement_line(cube)
        result = p.process(cube)
        pts = result.points
        points = np.zeros(len(pts), wire.POINT_DTYPE)
        for name in ("x", "y", "z", "velocity"):
            points[name] = pts[name]
        side = np.zeros(len(pts), wire.SIDE_INFO_DTYPE)
        side["snr"] = _int16(np.nan_to_num(pts["snr_db"]) * 10)
        side["noise"] = _int16(np.nan_to_num(pts["noise_db"]) * 10)
        n_ant = len(g.heatmap_elements)
        slots, nrx = self.config.num_tx_slots, self.config.num_rx
        zero = result.spectrum[p.n_doppler // 2].reshape(slots * nrx, -1)[:n_ant, :g.range_bins].T * self._weights
        heat = np.empty(zero.shape, wire.HEATMAP_DTYPE)
        for part, values in (("real", zero.real), ("imag", zero.imag)):
            rounded = np.round(values)
            self.saturated += int(np.count_nonzero(np.abs(rounded) > 32767))
            heat[part] = np.clip(rounded, -32768, 32767)
        log_mag = None
        gui = self.layout.gui
        if gui.log_mag_range or gui.noise_profile or gui.range_doppler_heat_map:
            power = np.fft.ifftshift(result.power, axes=0).T[:g.range_bins]  # (range, Doppler), bin 0 first
            log_mag = np.clip(np.round(0.5 * np.log2(np.maximum(power, 1.0)) * 512), 0, 65535)
        packet = wire.encode_packet(self.layout, frame_number, points, side, heat, log_magnitude=log_mag,
                                    time_cpu_cycles=int(time_s * DSP_CLOCK_HZ))
        return packet, len(points)


    def measurement_line(self, cube: np.ndarray) -> str:
        """The ``compRangeBiasAndRxChanPhase ...`` line the demo prints for the raw cube *cube*,
        complex (loops, tx_slots, rx, samples); see the module docstring."""
        g, m = self.geometry, self._measure
        chirp = cube[0]
        if self._clutter_removed:  # the DPC takes each cell's mean over the chirps out of the cube first
            chirp = chirp - cube.mean(axis=0)
        first = np.fft.fft(chirp * self.processor.w_range, n=g.range_bins, axis=-1)  # (slots, rx, bins)
        power = (np.abs(first) ** 2).sum(axis=(0, 1))
        lo = min(max(int(np.ceil((m.target_distance_m - m.search_window_m / 2) / g.range_step_m)), 1),
                 g.range_bins - 2)  # a window past the last bins: the chip reads its edge
        hi = min(int(np.floor((m.target_distance_m + m.search_window_m / 2) / g.range_step_m)), g.range_bins - 2)
        k = lo + int(np.argmax(power[lo:hi + 1])) if hi >= lo else lo
        y0, y1, y2 = np.sqrt(power[k - 1:k + 2])
        curve = y0 - 2 * y1 + y2
        offset = 0.5 * (y0 - y2) / curve if curve < 0 else 0.0
        bias = (k + offset) * g.range_step_m - m.target_distance_m
        x = first[:, :, k].astype(np.complex128)
        mag2 = np.abs(x) ** 2
        coefficients = np.conj(x) * np.sqrt(mag2.min()) / mag2
        table = self.config.virtual_array.per_path(coefficients, fill=1.0)
        parts = [f"{v:.5f}" for c in table.ravel() for v in (c.real, c.imag)]
        return f"compRangeBiasAndRxChanPhase {bias:.7f} " + " ".join(parts)


def _int16(values: np.ndarray) -> np.ndarray:
    return np.clip(np.round(values), -32768, 32767).astype(np.int16)
