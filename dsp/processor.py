"""The frame processor: raw cube to range-Doppler map and point cloud.

Built once per radar configuration (sizes, windows, axes, tables), then run on every frame:

1. range FFT over the ADC samples (windowed), per loop, TX slot and RX, a dataset's TX-to-RX
   coupling taken out where one is given;
2. optional static clutter removal, done on the Doppler-windowed data (a
   least-squares fit of the window's own shape), so that a moving target's
   range bin gets no false zero-Doppler return;
3. Doppler FFT over the loops (windowed, centred: bin ``n_doppler // 2`` is
   zero velocity, higher bins recede);
4. range-Doppler power summed over the virtual array, and CFAR detection at the map's peaks
   within the detection range (:mod:`.cfar_peaks`, :mod:`.cfar`), strong targets' range skirts
   dropped;
5. per detection, its points (:mod:`.points`): calibrated and TDM-compensated antennas, the
   azimuth and elevation, the radial velocity between Doppler bins, further reflectors in the
   cell.

Ranges are the bins' beat ranges less the board's range bias (the cfg's
compRangeBiasAndRxChanPhase line, :mod:`radarodom.calibration`).
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np

from ..calibration import ChannelCalibration, RangeCoupling
from ..cfg import RadarConfig, require_config
from ..errors import ConfigError, UsageError
from ..rawframe import unusable_samples
from .cfar import CfarParams, cfar_2d_ti
from .cfar_peaks import above_skirts, cfar_peaks
from .cfar_ti import fov_mask, params_from_ti
from .config import DspConfig
from .detection_range import detection_range
from .fft import resolve_backend, spectrum_ffts
from .points import POINT_DTYPE, PointMaker, three_bin_response

log = logging.getLogger(__name__)


#: The windows numpy makes, the same to the last bit in float32 as scipy's symmetric ones of
#: those names: importing scipy.signal for them is most of the start-up of every program that
#: runs the DSP (docs/benchmarks.md, "Start-up").
_NUMPY_WINDOWS = {"hann": np.hanning, "hamming": np.hamming, "blackman": np.blackman, "bartlett": np.bartlett}


def make_window(name: str, n: int) -> np.ndarray:
    """A float32 window of length *n* by scipy's name ("rect" for none)."""
    if name in ("rect", "boxcar", "none"):
        return np.ones(n, np.float32)
    if name in _NUMPY_WINDOWS:
        return _NUMPY_WINDOWS[name](n).astype(np.float32)
    import scipy.signal  # any other of scipy's windows, by name
    try:
        return scipy.signal.get_window(name, n, fftbins=False).astype(np.float32)
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"unknown window {name!r}: {exc}", field="window") from None


def window_correlation(window: np.ndarray, n_fft: int, lags: int) -> tuple[float, ...]:
    """Correlation of the powers of noise cells 1 .. *lags* bins apart behind *window* and an
    *n_fft*-point FFT: ``|sum w^2 exp(-j 2 pi k n / n_fft)|^2 / (sum w^2)^2`` for lag k (white
    noise's FFT bins are correlated by the window's own spectrum)."""
    w2 = np.asarray(window, dtype=float) ** 2
    n = np.arange(len(w2))
    r = [abs(np.sum(w2 * np.exp(-2j * np.pi * k * n / n_fft))) / np.sum(w2) for k in range(1, lags + 1)]
    # Rounded: a smooth window's far correlations are rounding noise, and equal settings should
    # give equal (cached) scales.
    return tuple(round(float(v) ** 2, 9) for v in r)


@dataclass
class FrameResult:
    """What one frame gave.  Arrays are the processor's buffers: valid until
    the next :meth:`FrameProcessor.process`; copy what you keep."""

    #: Range-Doppler power summed over the virtual array, linear, (doppler_bins, range_bins).
    power: np.ndarray
    #: Doppler spectrum per virtual element, complex64 (doppler_bins, tx_slots, rx, range_bins).
    spectrum: np.ndarray
    #: The detections, POINT_DTYPE (n,).
    points: np.ndarray


def _fitted(params: CfarParams, n: int, axis: str) -> CfarParams:
    """*params* with guard and training cells cut down to fit an axis of *n* cells (small
    test configurations; logged), an OS rank kept at the same quantile; unchanged when they fit."""
    if n >= params.window:
        return params
    room = (n - 1) // 2  # guard + train that fit around the cell under test
    if room < 1:
        raise ConfigError(f"the {axis} axis has {n} cells: too few for any CFAR window", field=f"{axis} CFAR")
    guard = min(params.guard, room - 1)
    train = room - guard
    log.info("the %s axis has only %d cells: CFAR guard %d -> %d and train %d -> %d cells", axis, n,
             params.guard, guard, params.train, train)
    return dataclasses.replace(params, guard=guard, train=train, os_rank=_scaled_rank(params, train))


def _scaled_rank(params: CfarParams, train: int) -> int | None:
    """An explicit OS rank for *train* cells a side, at the quantile it has in *params*."""
    if params.os_rank is None:
        return None
    return min(max(round(params.os_rank * train / params.train), 1), 2 * train)


def cells_per_bin(n_fft: int, samples: int) -> int:
    """FFT cells per resolution bin of a *samples*-point window zero-padded to *n_fft* (1 unpadded;
    the nearest whole number)."""
    return max(1, round(n_fft / samples))


class FrameProcessor:
    """Range/Doppler/angle processing for one radar configuration.

    *coupling*: a dataset's TX-to-RX coupling in the range domain (ColoRadar's), removed from
    every chirp's range spectrum; the range FFT then uses the window it was measured with.
    *calibrated*: whether the cfg's channel calibration is known to fit the board that made the
    frames (``Source.calibrated``: a simulation knows its board); None: unknown, so a line other
    than the identity is taken to be the board's.

    Guard and training cells, and the peak's neighbourhood, are counted in resolution bins: with
    zero padding (DspConfig.range_fft_size, doppler_fft_size) each spans as many map cells as a
    bin has, so that a window's sidelobes, which padding resolves, are neither a peak nor noise.
    """

    def __init__(self, cfg: RadarConfig, params: DspConfig | None = None, *,
                 coupling: RangeCoupling | None = None, calibrated: bool | None = None) -> None:
        params = _params_for(cfg, params)
        # The map CFAR runs on sums the power of every virtual antenna: thresholds
        # from a Pfa must be derived for that sum, not for one antenna.
        n_virtual = cfg.num_tx_slots * cfg.num_rx
        loops, slots, nrx, ns = cfg.cube_shape
        self.n_range = params.range_fft_size or ns
        self.n_doppler = params.doppler_fft_size or loops
        if coupling is not None and coupling.is_zero:
            coupling = None
        if coupling is not None:
            _check_coupling(coupling, cfg, self.n_range)
            log.info("%s: range FFT behind the coupling's own window", coupling.origin)
        self.w_range = (make_window(params.range_window, ns) if coupling is None
                        else coupling.window.astype(np.float32))
        self.w_doppler = make_window(params.doppler_window, loops)
        # ... and from windows, which correlate neighbouring cells: fewer independent ones.
        params = dataclasses.replace(
            params,
            range_cfar=_fitted(_for_map(params.range_cfar, n_virtual, self.w_range, self.n_range), self.n_range, "range"),
            doppler_cfar=_fitted(_for_map(params.doppler_cfar, n_virtual, self.w_doppler, self.n_doppler),
                                 self.n_doppler, "Doppler"))
        #: The board's channel calibration in use (the cfg's compRangeBiasAndRxChanPhase, unless
        #: DspConfig.channel_calibration is off).
        self.calibration = _calibration_in_use(cfg, params)
        #: True when the array's paths are lined up: the calibration in use is known to fit the
        #: board (*calibrated*), or, unknown, is not the identity.  Further azimuth peaks in a cell
        #: are looked for on a calibrated array only: on an uncalibrated one, what a removed plane
        #: wave leaves of itself is a second, false peak (docs/calibration.md).
        self.array_calibrated = (calibrated if calibrated is not None and params.channel_calibration
                                 else not self.calibration.is_identity)
        if not self.array_calibrated and params.max_azimuth_peaks > 1 and params.second_peak_threshold is None:
            log.info("%s: the channel calibration is the identity: one azimuth a range-Doppler cell "
                     "(DspConfig.max_azimuth_peaks needs a calibrated board)", cfg.path)
            params = dataclasses.replace(params, max_azimuth_peaks=1)
        self.cfg = cfg
        self.params = params
        # The CFAR's estimate to the mean noise power (an order statistic or a greatest-of sits
        # above it), so that snr_db and noise_db mean the same whatever the method.
        self._noise_factor = params.range_cfar.noise_factor
        #: Range of each range bin, m, (n_range,), the calibration's range bias taken off.
        self.range_m = _range_axis(cfg, self.n_range, self.calibration.range_bias_m)
        #: Signed Doppler bin of each row of the centred spectrum, (n_doppler,).
        self.doppler_bins = np.arange(self.n_doppler) - self.n_doppler // 2
        #: Radial velocity of each row, m/s, (n_doppler,).
        self.velocity_mps = self.doppler_bins * cfg.velocity_resolution_mps * loops / self.n_doppler
        #: The FFT backend in use ("scipy" or "fftw"; DspConfig.fft).
        self.fft_backend = resolve_backend(params.fft)
        self._ffts = spectrum_ffts(cfg.cube_shape, self.n_range, self.n_doppler, self.fft_backend, params.workers)
        # (-1)^l shifts the spectrum by half the FFT size: the fftshift, for free.
        self._centred_by_sign = self.n_doppler % 2 == 0
        sign = np.where(np.arange(loops) % 2, -1.0, 1.0) if self._centred_by_sign else np.ones(loops)
        self._doppler_weights = (self.w_doppler * sign).astype(np.float32)
        self._window_2d = (self._doppler_weights[:, None, None, None]
                           * self.w_range[None, None, None, :]).astype(np.float32)
        # The coupling as the range FFT of the windowed cube carries it: each chirp's coupling
        # times that chirp's Doppler weight (both windows are applied before the range FFT).
        self._coupling = None if coupling is None else (
            self._doppler_weights[:, None, None, None] * coupling.spectrum(self.n_range)[None]).astype(np.complex64)
        self._power = np.empty((self.n_doppler, self.n_range), np.float32)
        #: The detections' points (angles, positions, velocities: :mod:`.points`).
        self.point_maker = PointMaker(cfg, params, self.calibration, self.w_doppler, self.doppler_bins,
                                      self.range_m)
        pm = self.point_maker
        # What the heatmaps share with the points: the virtual array's rows and the weights
        # every element is multiplied by before angle processing (TDM phases, calibration).
        self.az_elements, self.az_h, self.el_elements, self.el_h = pm.az_elements, pm.az_h, pm.el_elements, pm.el_h
        self.n_az, self.angle_weights = pm.n_az, pm.angle_weights
        #: Shortest and longest range of a detection, m: from DspConfig.min_range_m (or the cfg's
        #: cfarFovCfg minimum, if higher) to DspConfig.max_range_m, else the cfg's cfarFovCfg
        #: maximum capped at the usable range, else the usable range (beat frequencies up to 80 %
        #: of the IF band, RadarConfig.max_range_m, less the range bias).
        self.detection_range_m = detection_range(cfg, params, self.calibration.range_bias_m)
        lo, hi = self.detection_range_m
        self._range_ok = (self.range_m >= lo) & (self.range_m <= hi)
        #: Range bins the heatmaps span: from 0 to the last bin within the detection range
        #: (beyond it lie the IF filter's roll-off and the TX-RX leakage's negative-frequency side).
        self.heatmap_range_bins = _bins_to(self.range_m, hi)
        # A peak is the strongest within a resolution bin either side (one map cell unpadded).
        self._peak_reach = (cells_per_bin(self.n_doppler, loops), cells_per_bin(self.n_range, ns))
        #: The cfg's cfarFovCfg Doppler limits, with ti_like.
        self._fov = {k: v for k, v in cfg.cfar_fov.items() if k == 1} if params.ti_like else {}

    # ---------------------------------------------------------------- stages
    def range_fft(self, cube: np.ndarray) -> np.ndarray:
        """Windowed range FFT: complex64 (loops, tx_slots, rx, n_range).

        Both windows (and, for an even Doppler size, the (-1)^loop factor that
        centres the Doppler spectrum) are applied here in one multiply, since
        they commute with the range FFT.
        """
        np.multiply(cube, self._window_2d, out=self._ffts.samples)
        spectrum = self._ffts.range()
        if self._coupling is not None:
            spectrum -= self._coupling
        return spectrum

    def doppler_fft(self, range_spectrum: np.ndarray) -> np.ndarray:
        """Centred Doppler FFT of the (already windowed) range spectrum, which it may
        overwrite: complex64 (n_doppler, tx_slots, rx, n_range)."""
        data = range_spectrum
        if self.params.clutter_removal:
            # Static returns are w_l * s in the windowed data: fit s per cell and remove
            # w * s, which takes their leakage with them (a plain mean would not).
            w = self._doppler_weights
            s = np.einsum("l,lmrn->mrn", w, data) / float(w @ w)
            data -= w[:, None, None, None] * s[None]
        spec = self._ffts.doppler(data)
        if self._centred_by_sign:
            return spec
        import scipy.fft

        return scipy.fft.fftshift(spec, axes=0)

    def power(self, spectrum: np.ndarray) -> np.ndarray:
        """Power summed over the virtual array: float32 (n_doppler, n_range)."""
        p = spectrum.real**2
        p += spectrum.imag**2
        np.sum(p, axis=(1, 2), out=self._power)
        return self._power

    def check_cube(self, cube: np.ndarray, who: str) -> None:
        """A :class:`UsageError` (from *who*) for a cube that is no numeric array, a
        :class:`ConfigError` for one not shaped as the cfg's (loops, tx_slots, rx, samples)."""
        if not isinstance(cube, np.ndarray) or cube.dtype.kind not in "iufc":
            got = f"{cube.dtype} array" if isinstance(cube, np.ndarray) else type(cube).__name__
            raise UsageError(f"{who}: cube must be a complex array shaped {self.cfg.cube_shape} "
                             f"(Frame.cube() gives one), got {got}")
        if cube.shape != self.cfg.cube_shape:
            raise ConfigError(f"{who}: cube shaped {cube.shape}, the cfg gives {self.cfg.cube_shape}")

    def process(self, cube: np.ndarray) -> FrameResult:
        """A raw cube, complex (loops, tx_slots, rx, samples), to detections.  A cube that is no
        numeric array, or whose samples hold NaN or infinite values or are too large for the
        float32 power, is a :class:`UsageError` saying so."""
        self.check_cube(cube, "FrameProcessor.process")
        # A NaN or inf sample (inf x a window's zero) or an overflowing power makes numpy warn in
        # the middle of the arithmetic; the power's one check below says it in the cube's terms.
        with np.errstate(invalid="ignore", over="ignore"):
            spectrum = self.doppler_fft(self.range_fft(cube))
            power = self.power(spectrum)
        if not np.isfinite(power).all():
            raise UsageError(f"FrameProcessor.process: {unusable_samples(cube)}")
        if self.params.peak_grouping:
            det = cfar_peaks(power, self.params.range_cfar, self.params.doppler_cfar, range_bins=self._range_ok,
                             reach=self._peak_reach)
        else:
            det = cfar_2d_ti(power, self.params.range_cfar, self.params.doppler_cfar, peak_grouping=False)
        keep = self._range_ok[det.range_idx]
        if self.params.range_skirt_db is not None:
            span = self.params.range_cfar.guard + self.params.range_cfar.train
            keep &= above_skirts(power, det, self.params.range_skirt_db, span)
        if self._fov:
            keep &= fov_mask(self.range_m[det.range_idx], self.velocity_mps[det.doppler_idx], self._fov)
        factor = self._noise_factor
        points = self.points(spectrum, det.doppler_idx[keep], det.range_idx[keep],
                             det.snr_db[keep] + 10 * np.log10(factor), det.noise[keep] / factor)
        return FrameResult(power, spectrum, points)

    def points(self, spectrum: np.ndarray, doppler_idx: np.ndarray, range_idx: np.ndarray,
               snr_db: np.ndarray, noise: np.ndarray) -> np.ndarray:
        """Points (POINT_DTYPE) of detections at rows *doppler_idx* and range bins *range_idx*
        of the centred *spectrum* (:meth:`.points.PointMaker.points`)."""
        return self.point_maker.points(spectrum, doppler_idx, range_idx, snr_db, noise)

    # ---------------------------------------------------------------- angles
def _for_map(params: CfarParams, channels: int, window: np.ndarray, n_fft: int) -> CfarParams:
    """*params* for the processor's map: guard and training cells counted in resolution bins,
    so as many map cells as a bin has after zero padding; cells summing *channels* antennas'
    powers, neighbours correlated by *window* (what a Pfa's scale and the noise factor depend on;
    a threshold in dB depends on neither)."""
    per_bin = cells_per_bin(n_fft, len(window))
    if per_bin > 1:
        params = dataclasses.replace(params, guard=params.guard * per_bin, train=params.train * per_bin,
                                     os_rank=_scaled_rank(params, params.train * per_bin))
    correlation = window_correlation(window, n_fft, params.train)
    return dataclasses.replace(params, channels=channels, correlation=correlation)


def _check_coupling(coupling: RangeCoupling, cfg: RadarConfig, n_range: int) -> None:
    where = coupling.origin
    if coupling.values.shape[:2] != (cfg.num_tx_slots, cfg.num_rx):
        raise ConfigError(f"the coupling is for {coupling.values.shape[0]} TX x {coupling.values.shape[1]} RX, the cfg "
                          f"has {cfg.num_tx_slots} TX slots x {cfg.num_rx} RX", path=where)
    if len(coupling.window) != cfg.num_samples or n_range != cfg.num_samples:
        raise ConfigError(f"the coupling was measured behind a {len(coupling.window)}-point range FFT without zero "
                          f"padding; the cfg has {cfg.num_samples} samples and the DSP a {n_range}-point FFT "
                          "(leave DspConfig.range_fft_size unset)", path=where)


def heatmap_range_bins(cfg: RadarConfig, params: DspConfig | None = None) -> int:
    """The range bins the DSP's heatmaps of *cfg* span (:attr:`FrameProcessor.heatmap_range_bins`),
    without building the processor: what a program checks the estimator's settings against
    before it opens its outputs."""
    params = _params_for(cfg, params)
    bias = _calibration_in_use(cfg, params).range_bias_m
    _, hi = detection_range(cfg, params, bias)
    return _bins_to(_range_axis(cfg, params.range_fft_size or cfg.cube_shape[3], bias), hi)


def _params_for(cfg: RadarConfig, params: DspConfig | None) -> DspConfig:
    """The DSP's settings for *cfg*: *params* (default: ``DspConfig()``), TI's own with ``ti_like``;
    :class:`UsageError` for settings of another kind, :class:`ConfigError` for a range FFT shorter than
    the cfg's ADC samples a chirp or a Doppler FFT shorter than its loops (zero padding lengthens)."""
    require_config(cfg)
    if params is None:
        params = DspConfig()
    elif not isinstance(params, DspConfig):
        raise UsageError(f"the DSP's settings must be a DspConfig (DspConfig.from_dict makes one from a dict), "
                         f"got {type(params).__name__}")
    loops, _, _, samples = cfg.cube_shape
    for name, least, what in (("range_fft_size", samples, "ADC samples a chirp (profileCfg)"),
                              ("doppler_fft_size", loops, "loops a frame (frameCfg)")):
        size = getattr(params, name)
        if size is not None and size < least:
            raise ConfigError(f"must be at least the cfg's {least} {what}, got {size} (leave it unset for no "
                              "zero padding)", field=name)
    return ti_like_params(cfg, params) if params.ti_like else params


def _calibration_in_use(cfg: RadarConfig, params: DspConfig) -> ChannelCalibration:
    """The cfg's compRangeBiasAndRxChanPhase, unless ``DspConfig.channel_calibration`` is off."""
    return ChannelCalibration.from_config(cfg) if params.channel_calibration else ChannelCalibration.identity()


def _range_axis(cfg: RadarConfig, n_range: int, range_bias_m: float) -> np.ndarray:
    """Each range bin's range, m, (n_range,): the beat frequency's, less the range bias."""
    return np.arange(n_range) * cfg.range_resolution_m * cfg.cube_shape[3] / n_range - range_bias_m


def _bins_to(range_m: np.ndarray, hi: float) -> int:
    """Bins from 0 to the last within *hi* m (beyond lie the IF filter's roll-off and the TX-RX
    leakage's negative-frequency side)."""
    return int(np.searchsorted(range_m, hi, side="right"))


def ti_like_params(cfg: RadarConfig, params: DspConfig) -> DspConfig:
    """*params* with detection set from the cfg's own TI lines, where present."""
    changes = {}
    cfar = cfg.cfar
    if 0 in cfar:
        changes["range_cfar"] = params_from_ti(cfar[0])
        changes["peak_grouping"] = bool(cfar[0].peak_grouping)
    if 1 in cfar:
        changes["doppler_cfar"] = params_from_ti(cfar[1])
    if cfg.clutter_removal is not None:
        changes["clutter_removal"] = bool(cfg.clutter_removal.enabled)
    mobf = cfg.multi_obj_beam_forming
    if mobf is not None:
        changes["second_peak_threshold"] = mobf.threshold if mobf.enabled and mobf.threshold > 0 else None
    if cfg.extended_max_velocity is not None:
        changes["velocity_disambiguation"] = bool(cfg.extended_max_velocity.enabled)
    # One azimuth peak a cell, and multiObjBeamForming's second one, and no skirt rule, as TI's demo.
    return dataclasses.replace(params, ti_like=True, max_azimuth_peaks=1, range_skirt_db=None, **changes)


__all__ = ["POINT_DTYPE", "FrameProcessor", "FrameResult", "CfarParams", "make_window", "three_bin_response",
           "ti_like_params"]
