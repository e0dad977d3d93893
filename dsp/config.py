"""The DSP's settings: one typed, dumpable configuration (like kiss-icp's).

Everything else follows from the radar's cfg (:class:`radarodom.cfg.RadarConfig`):
sizes, axes, the virtual array.  ``DspConfig.ti_like`` makes detection follow
the cfg's own ``cfarCfg``, ``cfarFovCfg``, ``aoaFovCfg``, ``multiObjBeamForming``
and ``clutterRemoval`` lines, as TI's demo does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..errors import ConfigError
from ..settings import Settings, check_choice
from .cfar import CfarParams
from .fft import BACKENDS


def _default_range_cfar() -> CfarParams:
    # Ordered statistic, the median of the 16 training cells: a reflector 3-6 bins from a
    # stronger one at the same Doppler (a sensor at rest puts the whole static world in one
    # Doppler bin) has up to 8 of the stronger one's cells in its window, which the median
    # passes over; greatest-of averaged them in and hid it.  Measured against CAGO, CASO and OS
    # at ranks 8, 10 and 12 on the velocity fit and the odometry (docs/dsp.md, "The DSP's settings,
    # measured"): the median's velocity fit and drift are smallest-of's, with range_skirt_db
    # keeping strong targets' skirts out.
    return CfarParams(method="os", guard=2, train=8, pfa=1e-5, cyclic=False, os_rank=8)


def _default_doppler_cfar() -> CfarParams:
    return CfarParams(method="ca", guard=1, train=4, pfa=1e-3, cyclic=True)


@dataclass
class DspConfig(Settings):
    _what = "DSP"

    #: Windows before the range and Doppler FFTs (scipy.signal.get_window names, or "rect"; from
    #: Python also its (name, parameter) tuples, e.g. ("kaiser", 8.0)).
    range_window: str | tuple = "hann"
    doppler_window: str | tuple = "hann"
    #: FFT sizes; None: the number of samples / loops (no zero padding).
    range_fft_size: int | None = None
    doppler_fft_size: int | None = None
    #: Zero-padded FFT sizes over the virtual array's azimuth row and its two rows in elevation.
    azimuth_fft_size: int = 64
    elevation_fft_size: int = 16
    #: Place each point's azimuth between the azimuth FFT's bins, from the peak's bin and its
    #: two neighbours, rather than on the grid.  The grid is coarse off boresight (Wx steps of
    #: 2/64: 3.6 deg at 60 deg, 7 deg at 75 deg), and the Doppler ego-velocity bends its
    #: errors into a bias, since the forward component cos(azimuth) is curved in Wx there:
    #: 60 points around a straight 0.6 m/s drive through a room came out 1.3 % slow, 0.2 %
    #: with this (tests/test_estimator_e2e.py has a case that came out fast).
    azimuth_interpolation: bool = True
    #: Undo the Doppler phase between TDM-MIMO TX slots before angle processing.
    tdm_compensation: bool = True
    #: Resolve velocities beyond +/- max velocity over the N_tx hypotheses (TI's extended velocity).
    velocity_disambiguation: bool = False
    #: Report each point's radial velocity between Doppler bins, from the three bins around its
    #: peak beamformed toward its azimuth, rather than at the bin's centre.  Centres bias the
    #: Doppler ego-velocity: the static world ahead piles up near the largest |radial velocity|
    #: (cos is flat around the heading), so its rounding errors do not average out: a straight
    #: drive at 0.6 m/s (8.5 bins on the shipped cfg) came out 2.2 % slow (tests/test_estimator_e2e.py).
    doppler_interpolation: bool = True
    #: Place each heatmap cell's dominant Doppler between bins too (the strongest bin's magnitude
    #: and its neighbours' at the cell's azimuth, against the window's three-bin response) where
    #: the Doppler bins are wider than this, m/s (None: never; 0: always).  A heatmap cell mixes
    #: every reflector of its beam, whose radial velocities differ by a tenth of a metre a second
    #: at walking speed: with bins of 0.07-0.11 m/s a bin's centre is the nearer, with TI's SDK
    #: demo profiles' 0.43-0.64 m/s the interpolation (docs/heading.md item 37).
    heatmap_doppler_between_bins_mps: float | None = 0.2
    #: Remove static returns (after windowing, so no false zero-Doppler detection appears).
    #: Keep it off where the Doppler ego-velocity estimator needs the static world.
    clutter_removal: bool = False
    range_cfar: CfarParams = field(default_factory=_default_range_cfar)
    doppler_cfar: CfarParams = field(default_factory=_default_doppler_cfar)
    #: Keep only detections that are local maxima in range and Doppler.
    peak_grouping: bool = True
    #: Drop a detection more than this much weaker (dB) than another within the range CFAR's
    #: window (guard + train bins) in its Doppler row: the strong target's range skirt (window
    #: sidelobes lifted by range migration), which an ordered-statistic CFAR looking past the
    #: strong target can otherwise detect.  None: keep them.
    range_skirt_db: float | None = 40.0
    #: A second azimuth peak per detection when at least this share of the first (None: off);
    #: TI's multiObjBeamForming rule.  When set, it replaces the further peaks below.
    second_peak_threshold: float | None = None
    #: Reflectors kept per detected range-Doppler cell, one azimuth peak at a time, each taken
    #: out of the cell before the next is looked for (dsp/azimuth_peaks.py): a sensor at rest
    #: puts the static world in one Doppler bin, and left and right at the same angle share
    #: one while driving.  1: the strongest azimuth only.
    max_azimuth_peaks: int = 2
    #: A further peak's beamformed power over the cell's noise, dB, at least.
    azimuth_peak_snr_db: float = 15.0
    #: A further peak's power against the cell's first peak, dB, at least (what a removed plane
    #: wave leaves of itself on an imperfectly calibrated array stays below it).
    azimuth_peak_ratio_db: float = -15.0
    #: Detections closer than this are dropped (the ADC's DC and TX-RX leakage live there), m.
    min_range_m: float = 0.3
    #: Detections farther than this are dropped, and the heatmaps end there, m.  None: the usable
    #: range, beat frequencies up to 80 % of the IF band (radar-cfg's "max range"), or the cfg's
    #: cfarFovCfg range maximum when it is shorter: the IF filter rolls off beyond, and the
    #: TX-RX leakage's negative-frequency side lies at the end of the range FFT.  (A cfarFovCfg
    #: range minimum above min_range_m applies too.)
    max_range_m: float | None = None
    #: Apply the board's channel calibration, the cfg's compRangeBiasAndRxChanPhase line (each
    #: virtual antenna times its coefficient before angle processing, the range bias taken off
    #: every range), as TI's firmware does.  Off: the samples as the board gives them.
    channel_calibration: bool = True
    #: Follow the radar cfg's cfarCfg, cfarFovCfg, aoaFovCfg, multiObjBeamForming, clutterRemoval.
    ti_like: bool = False
    #: FFT backend of the range and Doppler FFTs: "scipy" (scipy.fft), "fftw" (pyFFTW, the
    #: ``fftw`` extra; two to three times faster, bench/bench_dsp.py) or "auto" (FFTW when
    #: pyFFTW is installed, else scipy).
    fft: str = "auto"
    #: Threads per FFT (1 measured faster on 2 cores shared with capture and estimation).
    workers: int = 1

    def __post_init__(self) -> None:
        self.check_types()
        for name in ("azimuth_fft_size", "elevation_fft_size", "workers", "max_azimuth_peaks"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise ConfigError(f"must be an integer, got {value!r}", field=name)
            if value < 1:
                raise ConfigError(f"must be at least 1, got {value}", field=name)
        for name, lo, hi in (("range_skirt_db", 0.0, math.inf), ("azimuth_peak_snr_db", -math.inf, math.inf),
                             ("azimuth_peak_ratio_db", -math.inf, 0.0),
                             ("heatmap_doppler_between_bins_mps", 0.0, math.inf)):
            value = getattr(self, name)
            if value is None and name in ("range_skirt_db", "heatmap_doppler_between_bins_mps"):
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi \
                    or not math.isfinite(value):
                bounds = {"range_skirt_db": "a finite number of dB >= 0 (or null: keep every detection)",
                          "azimuth_peak_snr_db": "a finite number of dB",
                          "azimuth_peak_ratio_db": "a finite number of dB <= 0 (a further peak is weaker "
                                                   "than the first)",
                          "heatmap_doppler_between_bins_mps": "a finite number of m/s >= 0 (or null: never)"}[name]
                raise ConfigError(f"must be {bounds}, got {value!r}", field=name)
        for name in ("range_fft_size", "doppler_fft_size"):
            if getattr(self, name) is not None and getattr(self, name) < 2:
                raise ConfigError(f"must be at least 2, got {getattr(self, name)}", field=name)
        check_choice(self.fft, BACKENDS, "fft")
        if self.second_peak_threshold is not None and not 0 < self.second_peak_threshold <= 1:
            raise ConfigError("must be in (0, 1]", field="second_peak_threshold")
        if self.min_range_m < 0:
            raise ConfigError(f"must be >= 0, got {self.min_range_m}", field="min_range_m")
        if self.max_range_m is not None and not self.max_range_m > self.min_range_m:
            raise ConfigError(f"must be above min_range_m ({self.min_range_m}), got {self.max_range_m}",
                              field="max_range_m")
