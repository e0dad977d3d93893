"""The frame processor: raw cube to range-Doppler map and point cloud.

Built once per radar configuration (sizes, windows, axes, the virtual array,
TDM phase tables), then run on every frame:

1. range FFT over the ADC samples (windowed), per loop, TX slot and RX;
2. optional static clutter removal, done on the Doppler-windowed data (a
   least-squares fit of the window's own shape), so that a moving target's
   range bin gets no false zero-Doppler return;
3. Doppler FFT over the loops (windowed, centred: bin ``n_doppler // 2`` is
   zero velocity, higher bins recede);
4. range-Doppler power summed over the virtual array, and CFAR detection
   (:mod:`.cfar`);
5. per detection: TDM-MIMO Doppler phase compensation (optionally over the
   N_tx velocity hypotheses), the azimuth FFT over the azimuth row of the
   virtual array (zero-padded), its peak placed between bins from the peak's
   bin and its neighbours (DspConfig.azimuth_interpolation), and the elevation
   from the raised row, giving x, y, z in the TI sensor frame;
6. per detection and azimuth peak: the radial velocity between Doppler bins, from the
   magnitudes of the peak's row and its two neighbours beamformed toward that azimuth, by
   inverting the Doppler window's own three-bin response to a tone (``three_bin_response``).
   Bin centres would bias the Doppler ego-velocity: the static world ahead piles up near the
   largest |radial velocity| (cos is flat around the heading), so its rounding errors do not
   average out.  Beamforming makes it the velocity of the point's own direction, not that of
   its whole range ring.

Angles follow conventions.md: the azimuth row's FFT peak k (plus its sub-bin
offset) gives ``Wx = 2k/N`` and ``x = r Wx``; with the raised row's FFT taken at the
elements' true horizontal positions, ``Wz = angle(A conj(E)) / pi`` at that
peak (the same as TI's ``angle(A conj(E))/pi + 2 Wx`` with the raised row
indexed from its first element), ``z = r Wz``.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
import scipy.fft
import scipy.signal

from ..calibration import ChannelCalibration, RangeCoupling
from ..cfg import RadarConfig
from ..errors import ConfigError
from .azimuth_peaks import CellCleaner, apart
from .cfar import CfarParams, cfar_2d_ti, fov_mask, params_from_ti
from .cfar_peaks import cfar_peaks
from .config import DspConfig
from .fft import SpectrumFFTs, resolve_backend

log = logging.getLogger(__name__)

#: One detected point (TI sensor frame; SI units, radians).
POINT_DTYPE = np.dtype([
    ("x", "f4"), ("y", "f4"), ("z", "f4"),  # m
    ("range", "f4"),  # m
    ("azimuth", "f4"), ("elevation", "f4"),  # rad; azimuth positive to the right
    ("velocity", "f4"),  # m/s radial, positive receding
    ("snr_db", "f4"), ("noise_db", "f4"),  # dB (noise: 10 log10 of the summed power's CFAR estimate)
    ("range_bin", "i2"), ("doppler_bin", "i2"),  # Doppler bin signed: 0 is zero velocity
])


def make_window(name: str, n: int) -> np.ndarray:
    """A float32 window of length *n* by scipy's name ("rect" for none)."""
    if name in ("rect", "boxcar", "none"):
        return np.ones(n, np.float32)
    try:
        return scipy.signal.get_window(name, n, fftbins=False).astype(np.float32)
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"unknown window {name!r}: {exc}", field="window") from None


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


def three_bin_response(window: np.ndarray, n_fft: int, setting: str = "doppler_interpolation"
                       ) -> tuple[np.ndarray, np.ndarray]:
    """How an FFT of *n_fft* points of the *window*ed tone answers the tone's offset from a bin.

    Returns (ratio, offset): for a tone ``offset`` bins from bin k (-0.5 .. 0.5, 1001 steps),
    ``ratio = (|X(k+1)| - |X(k-1)|) / |X(k)|``, increasing, so that
    ``np.interp(measured_ratio, ratio, offset)`` inverts it (clamped to the bin).  Taken from
    the window itself, so it holds for any window and zero padding (a window with zero taps
    is an aperture with gaps).  *setting* is the DspConfig field that asked, for errors.
    """
    if n_fft < 3:
        raise ConfigError(f"interpolating between FFT bins needs three bins, the FFT has {n_fft}: "
                          f"set {setting} false", field=setting)
    offset = np.linspace(-0.5, 0.5, 1001)
    taps = np.arange(len(window))
    weights = np.asarray(window, dtype=float)

    def magnitude(f: np.ndarray) -> np.ndarray:  # |DTFT of the window| f bins from its peak
        return np.abs(np.exp(-2j * np.pi * np.outer(f, taps) / n_fft) @ weights)

    ratio = (magnitude(1.0 - offset) - magnitude(-1.0 - offset)) / magnitude(-offset)
    if not np.all(np.diff(ratio) > 0):
        raise ConfigError("the window's three-bin response does not grow with the tone's offset, "
                          f"so it cannot be inverted: set {setting} false", field=setting)
    return ratio, offset


def _invert(below: np.ndarray, centre: np.ndarray, above: np.ndarray,
            table: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Sub-bin offsets from the magnitudes of a peak's bin and its neighbours, through a
    :func:`three_bin_response` table."""
    ratio = (above - below) / np.maximum(centre, np.finfo(np.float32).tiny)
    return np.interp(ratio, *table)


def _fitted(params: CfarParams, n: int, axis: str) -> CfarParams:
    """*params* with guard and training cells cut down to fit an axis of *n* cells (small
    test configurations), with a warning; unchanged when they fit."""
    if n >= params.window:
        return params
    room = (n - 1) // 2  # guard + train that fit around the cell under test
    if room < 1:
        raise ConfigError(f"the {axis} axis has {n} cells: too few for any CFAR window", field=f"{axis} CFAR")
    guard = min(params.guard, room - 1)
    train = room - guard
    os_rank = params.os_rank if params.os_rank is None or params.os_rank <= 2 * train else None
    log.info("the %s axis has only %d cells: CFAR guard %d -> %d and train %d -> %d cells", axis, n,
                params.guard, guard, params.train, train)
    return dataclasses.replace(params, guard=guard, train=train, os_rank=os_rank)


class FrameProcessor:
    """Range/Doppler/angle processing for one radar configuration.

    *coupling*: a dataset's TX-to-RX coupling in the range domain (ColoRadar's), removed from
    every chirp's range spectrum; the range FFT then uses the window it was measured with.
    """

    def __init__(self, cfg: RadarConfig, params: DspConfig | None = None, *,
                 coupling: RangeCoupling | None = None) -> None:
        params = params or DspConfig()
        if params.ti_like:
            params = ti_like_params(cfg, params)
        # The map CFAR runs on sums the power of every virtual antenna: thresholds
        # from a Pfa must be derived for that sum, not for one antenna.
        n_virtual = cfg.num_tx_slots * cfg.num_rx
        loops, slots, nrx, ns = cfg.cube_shape
        self.n_range = params.range_fft_size or ns
        self.n_doppler = params.doppler_fft_size or loops
        params = dataclasses.replace(
            params,
            range_cfar=_fitted(dataclasses.replace(params.range_cfar, channels=n_virtual), self.n_range, "range"),
            doppler_cfar=_fitted(dataclasses.replace(params.doppler_cfar, channels=n_virtual), self.n_doppler,
                                 "Doppler"))
        self.cfg = cfg
        self.params = params
        self.w_range = make_window(params.range_window, ns)
        if coupling is not None and coupling.is_zero:
            coupling = None
        if coupling is not None:
            _check_coupling(coupling, cfg, self.n_range)
            log.info("%s: range FFT behind the coupling's own window", coupling.origin)
            self.w_range = coupling.window
        self.w_doppler = make_window(params.doppler_window, loops)
        #: The board's channel calibration in use (the cfg's compRangeBiasAndRxChanPhase, unless
        #: DspConfig.channel_calibration is off).
        self.calibration = (ChannelCalibration.from_config(cfg) if params.channel_calibration
                            else ChannelCalibration.identity())
        beat_range_m = np.arange(self.n_range) * cfg.range_resolution_m * ns / self.n_range
        #: Range of each range bin, m, (n_range,), the calibration's range bias taken off.
        self.range_m = beat_range_m - self.calibration.range_bias_m
        #: Signed Doppler bin of each row of the centred spectrum, (n_doppler,).
        self.doppler_bins = np.arange(self.n_doppler) - self.n_doppler // 2
        #: Radial velocity of each row, m/s, (n_doppler,).
        self.velocity_mps = self.doppler_bins * cfg.velocity_resolution_mps * loops / self.n_doppler
        #: The FFT backend in use ("scipy" or "fftw"; DspConfig.fft).
        self.fft_backend = resolve_backend(params.fft)
        self._ffts = SpectrumFFTs(cfg.cube_shape, self.n_range, self.n_doppler, self.fft_backend, params.workers)
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
        # Virtual array: which flat (slot, rx) element sits where.
        va = cfg.virtual_array
        h = va.h.ravel()
        self.az_elements = va.azimuth_row
        self.az_h = h[self.az_elements]
        self.el_elements = va.elevation_row
        self.el_h = h[self.el_elements]
        self.n_az = max(params.azimuth_fft_size, int(h.max()) + 1)
        aperture = np.zeros(int(self.az_h.max()) + 1)
        aperture[self.az_h] = 1.0
        #: (ratio, offset) of three_bin_response for sub-bin azimuth, or None (the FFT grid).
        self._azimuth_table = (three_bin_response(aperture, self.n_az, "azimuth_interpolation")
                               if params.azimuth_interpolation else None)
        self._cleaner = CellCleaner(self.az_elements, self.az_h, self.el_elements, self.el_h)
        # Two reflectors closer than three quarters of the azimuth row's resolution (2 / its length
        # in Wx) are one peak: a further peak nearer a taken one is what removing it left.
        self._peak_separation_bins = 0.75 * self.n_az / (int(self.az_h.max()) + 1)
        self._slot_of_element = np.repeat(np.arange(slots), nrx)
        self._tdm = self._slot_phases(self.doppler_bins)  # (n_doppler, slots)
        coefficients = self.calibration.for_array(va).ravel()
        #: Each virtual element's calibration coefficient, complex64 (elements,); None when
        #: every one is 1 (then nothing is multiplied).
        self._calib = None if np.all(coefficients == 1) else coefficients
        weights = (self._tdm[:, self._slot_of_element] if params.tdm_compensation
                   else np.ones((self.n_doppler, slots * nrx), np.complex64))
        #: What each virtual element's Doppler spectrum is multiplied by before angle processing,
        #: per row of the centred spectrum: its TX slot's TDM-MIMO phase and its calibration
        #: coefficient.  complex64 (n_doppler, elements); the heatmaps use it.
        self.angle_weights = weights if self._calib is None else (weights * self._calib).astype(np.complex64)
        #: (ratio, offset) of three_bin_response for sub-bin Doppler, or None (bin centres).
        self._offset_table = (three_bin_response(self.w_doppler, self.n_doppler)
                              if params.doppler_interpolation else None)
        #: Shortest and longest range of a detection, m: from DspConfig.min_range_m (or the cfg's
        #: cfarFovCfg minimum, if higher) to DspConfig.max_range_m, else the cfg's cfarFovCfg
        #: maximum, else the usable range (beat frequencies up to 80 % of the IF band,
        #: RadarConfig.max_range_m).
        self.detection_range_m = _detection_range(cfg, params, self.calibration.range_bias_m)
        lo, hi = self.detection_range_m
        self._range_ok = (self.range_m >= lo) & (self.range_m <= hi)
        #: Range bins the heatmaps span: from 0 to the last bin within the detection range
        #: (beyond it lie the IF filter's roll-off and the TX-RX leakage's negative-frequency side).
        self.heatmap_range_bins = int(np.searchsorted(self.range_m, hi, side="right"))
        #: The cfg's cfarFovCfg Doppler limits, with ti_like.
        self._fov = {k: v for k, v in cfg.cfar_fov.items() if k == 1} if params.ti_like else {}
        self._aoa = cfg.aoa_fov if params.ti_like else None

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
        return spec if self._centred_by_sign else scipy.fft.fftshift(spec, axes=0)

    def power(self, spectrum: np.ndarray) -> np.ndarray:
        """Power summed over the virtual array: float32 (n_doppler, n_range)."""
        p = spectrum.real**2
        p += spectrum.imag**2
        np.sum(p, axis=(1, 2), out=self._power)
        return self._power

    def process(self, cube: np.ndarray) -> FrameResult:
        """A raw cube, complex (loops, tx_slots, rx, samples), to detections."""
        if cube.shape != self.cfg.cube_shape:
            raise ConfigError(f"cube shaped {cube.shape}, the cfg gives {self.cfg.cube_shape}")
        spectrum = self.doppler_fft(self.range_fft(cube))
        power = self.power(spectrum)
        if self.params.peak_grouping:
            det = cfar_peaks(power, self.params.range_cfar, self.params.doppler_cfar, range_bins=self._range_ok)
        else:
            det = cfar_2d_ti(power, self.params.range_cfar, self.params.doppler_cfar, peak_grouping=False)
        keep = self._range_ok[det.range_idx]
        if self._fov:
            keep &= fov_mask(self.range_m[det.range_idx], self.velocity_mps[det.doppler_idx], self._fov)
        points = self.points(spectrum, det.doppler_idx[keep], det.range_idx[keep], det.snr_db[keep],
                             det.noise[keep])
        return FrameResult(power, spectrum, points)

    # ---------------------------------------------------------------- angles
    def points(self, spectrum: np.ndarray, doppler_idx: np.ndarray, range_idx: np.ndarray,
               snr_db: np.ndarray, noise: np.ndarray) -> np.ndarray:
        """Angles and positions of detections (row indices into the centred spectrum)."""
        n = len(range_idx)
        slots = self.cfg.num_tx_slots
        elements = spectrum[doppler_idx, :, :, range_idx].reshape(n, slots * self.cfg.num_rx)
        if self._calib is not None:
            elements *= self._calib
        doppler = self.doppler_bins[doppler_idx].astype(float)
        if self.params.tdm_compensation and self.params.velocity_disambiguation and slots > 1:
            elements, doppler = self._disambiguate(elements, doppler)
        elif self.params.tdm_compensation:
            elements = elements * self._tdm[doppler_idx][:, self._slot_of_element]
        neighbours = (self._neighbours(spectrum, doppler_idx, range_idx, doppler)
                      if self._offset_table is not None else None)
        az_in = np.zeros((n, self.n_az), np.complex64)
        az_in[:, self.az_h] = elements[:, self.az_elements]
        az = scipy.fft.fft(az_in, axis=1, workers=self.params.workers)
        mag = np.abs(az)
        peak = mag.argmax(axis=1)
        out = self._points_at(az, peak, elements, range_idx, doppler, snr_db, noise, neighbours)
        if self.params.second_peak_threshold is not None and n:
            second = self._second_peaks(mag, peak)
            if second is not None:
                rows, k2 = second
                more = self._points_at(az[rows], k2, elements[rows], range_idx[rows], doppler[rows],
                                       snr_db[rows], noise[rows], None if neighbours is None else neighbours[rows])
                out = np.concatenate([out, more])
        elif self.params.max_azimuth_peaks > 1 and n:
            out = np.concatenate([out, *self._further_peaks(az, peak, elements, range_idx, doppler, snr_db, noise,
                                                            neighbours)])
        if self._aoa is not None and len(out):
            a = self._aoa
            az_deg, el_deg = np.degrees(out["azimuth"]), np.degrees(out["elevation"])
            out = out[(az_deg >= a.min_azimuth_deg) & (az_deg <= a.max_azimuth_deg)
                      & (el_deg >= a.min_elevation_deg) & (el_deg <= a.max_elevation_deg)]
        return out

    def _points_at(self, az, peak, elements, range_idx, doppler, snr_db, noise, neighbours) -> np.ndarray:
        """Points at azimuth FFT bins *peak*; *doppler* is each detection's (signed) Doppler bin,
        *neighbours* its azimuth row in the Doppler rows either side (:meth:`_neighbours`), or
        None for bin-centre velocities."""
        n = len(peak)
        wx = np.clip(2.0 * self._bins_at(az, peak) / self.n_az, -1.0, 1.0)
        wz = np.zeros(n)
        if len(self.el_elements):
            el_in = np.zeros((n, self.n_az), np.complex64)
            el_in[:, self.el_h] = elements[:, self.el_elements]
            el = scipy.fft.fft(el_in, axis=1, workers=self.params.workers)
            rows = np.arange(n)
            wz = np.angle(az[rows, peak] * np.conj(el[rows, peak])) / np.pi
        wz = np.clip(wz, -1.0, 1.0)
        # (Wx, Wz) are the direction's x and z components: noise and sidelobes can put them
        # outside the unit circle at the edge of the field of view; the direction is then the
        # nearest one on it, so that |xyz| stays the range.
        length = np.hypot(wx, wz)
        outside = length > 1.0
        if outside.any():
            wx = np.where(outside, wx / np.maximum(length, 1e-12), wx)
            wz = np.where(outside, wz / np.maximum(length, 1e-12), wz)
        wy = np.sqrt(np.maximum(1.0 - wx * wx - wz * wz, 0.0))
        r = self.range_m[range_idx]
        pts = np.empty(n, POINT_DTYPE)
        pts["x"], pts["y"], pts["z"], pts["range"] = r * wx, r * wy, r * wz, r
        pts["azimuth"] = np.arctan2(wx, wy)
        pts["elevation"] = np.arcsin(wz)
        velocity_bins = doppler
        if neighbours is not None:
            velocity_bins = doppler + self._doppler_offsets(az[np.arange(n), peak], peak, neighbours)
        pts["velocity"] = velocity_bins * self.cfg.velocity_resolution_mps * self.cfg.num_loops / self.n_doppler
        pts["snr_db"] = snr_db
        pts["noise_db"] = 10 * np.log10(np.maximum(noise, 1e-30))
        pts["range_bin"] = range_idx
        pts["doppler_bin"] = np.round(doppler).astype(np.int16)
        return pts

    def _bins_at(self, az: np.ndarray, peak: np.ndarray) -> np.ndarray:
        """Signed azimuth FFT bins of peaks *peak* of the FFTs *az*, between bins where
        DspConfig.azimuth_interpolation asks (n,)."""
        k = np.where(peak >= self.n_az // 2, peak - self.n_az, peak)
        return k + self._azimuth_offsets(az, peak) if self._azimuth_table is not None else k.astype(float)

    def _further_peaks(self, az, peak, elements, range_idx, doppler, snr_db, noise, neighbours) -> list[np.ndarray]:
        """Points of further reflectors in the detections' cells (:mod:`.azimuth_peaks`): up to
        DspConfig.max_azimuth_peaks a cell, each azimuth_peak_snr_db over the cell's noise (the
        range CFAR's estimate, per element, through the azimuth row's gain) and at most
        -azimuth_peak_ratio_db under the cell's first peak."""
        p = self.params
        rows = np.arange(len(peak))
        first = np.abs(az[rows, peak]) ** 2
        n_row = len(self.az_elements)
        per_element = noise / (self.cfg.num_tx_slots * self.cfg.num_rx)
        floor = np.maximum(10 ** (p.azimuth_peak_snr_db / 10) * n_row * per_element,
                           10 ** (p.azimuth_peak_ratio_db / 10) * first)
        elements = elements.copy()
        sides = None if neighbours is None else neighbours.copy()
        taken = [self._bins_at(az, peak)]
        az_in = np.zeros((len(peak), self.n_az), np.complex64)
        out = []
        for _ in range(1, p.max_azimuth_peaks):
            self._cleaner.remove(elements, sides, 2.0 * taken[-1] / self.n_az)
            az_in[:, self.az_h] = elements[:, self.az_elements]
            az = scipy.fft.fft(az_in, axis=1, workers=p.workers)
            peak = np.abs(az).argmax(axis=1)
            power = np.abs(az[np.arange(len(peak)), peak]) ** 2
            k = self._bins_at(az, peak)
            ok = (power > floor) & apart(k, taken, self.n_az, self._peak_separation_bins)
            if not ok.any():
                break
            gain_db = 10 * np.log10(power[ok] / first[ok])
            out.append(self._points_at(az[ok], peak[ok], elements[ok], range_idx[ok], doppler[ok],
                                       snr_db[ok] + gain_db, noise[ok], None if sides is None else sides[ok]))
            elements, range_idx, doppler, snr_db, noise = elements[ok], range_idx[ok], doppler[ok], snr_db[ok], noise[ok]
            sides = None if sides is None else sides[ok]
            first, floor, az_in = first[ok], floor[ok], az_in[ok]
            taken = [t[ok] for t in taken] + [k[ok]]
        return out

    def _slot_phases(self, doppler: np.ndarray) -> np.ndarray:
        """TDM-MIMO phase correction of each TX slot for (signed, possibly disambiguated,
        fractional) Doppler bins *doppler* (n,): complex64 (n, slots).  Slot m of a target in
        Doppler bin k (k / n_doppler cycles a loop) lags by 2 pi k m / (slots n_doppler)."""
        slots = self.cfg.num_tx_slots
        return np.exp(-2j * np.pi * np.outer(doppler, np.arange(slots))
                      / (slots * self.n_doppler)).astype(np.complex64)

    def _compensation(self, doppler: np.ndarray) -> np.ndarray:
        """:meth:`_slot_phases` for every virtual element: complex64 (n, elements)."""
        return self._slot_phases(doppler)[:, self._slot_of_element]

    def _neighbours(self, spectrum: np.ndarray, doppler_idx: np.ndarray, range_idx: np.ndarray,
                    doppler: np.ndarray) -> np.ndarray:
        """The azimuth row of the Doppler rows either side of each detection, each row
        TDM-compensated for its own bin (the peak's row is compensated the same way):
        complex64 (n, 2, azimuth elements), below then above."""
        n = len(doppler_idx)
        out = np.empty((n, 2, len(self.az_elements)), np.complex64)
        for j, step in enumerate((-1, 1)):
            rows = (doppler_idx + step) % self.n_doppler  # the spectrum is periodic in Doppler
            side = spectrum[rows, :, :, range_idx].reshape(n, self.cfg.num_tx_slots * self.cfg.num_rx)
            if self._calib is not None:
                side *= self._calib
            if self.params.tdm_compensation:
                side = side * self._compensation(doppler + step)
            out[:, j] = side[:, self.az_elements]
        return out

    def _doppler_offsets(self, centre: np.ndarray, peak: np.ndarray, neighbours: np.ndarray) -> np.ndarray:
        """Sub-bin Doppler offsets (-0.5 .. 0.5) of detections whose azimuth FFT gave *centre*
        at bins *peak*: the neighbouring rows beamformed toward the same azimuth bin (the
        Doppler of what the point's direction sees, not of the whole range ring), their
        magnitudes against the window's three-bin response."""
        steer = np.exp(-2j * np.pi * np.outer(peak, self.az_h) / self.n_az)  # the azimuth FFT at bin peak
        side = np.abs(np.einsum("nse,ne->ns", neighbours, steer))
        return _invert(side[:, 0], np.abs(centre), side[:, 1], self._offset_table)

    def _azimuth_offsets(self, az: np.ndarray, peak: np.ndarray) -> np.ndarray:
        """Sub-bin offsets (-0.5 .. 0.5) of the azimuth FFT *az*'s peaks at bins *peak*, from
        each peak's bin and its neighbours (the FFT is cyclic)."""
        rows = np.arange(len(peak))
        below, centre, above = (np.abs(az[rows, (peak + step) % self.n_az]) for step in (-1, 0, 1))
        return _invert(below, centre, above, self._azimuth_table)

    def _disambiguate(self, elements: np.ndarray, doppler: np.ndarray):
        """TI's extended velocity: of the N_tx Doppler hypotheses k + j n_doppler,
        keep the one whose compensation gives the strongest azimuth peak."""
        slots = self.cfg.num_tx_slots
        js = np.arange(slots) - (slots - 1) // 2
        best_power = np.full(len(doppler), -1.0)
        best_el = elements
        best_k = doppler
        for j in js:  # a handful of hypotheses, each vectorised over detections
            k = doppler + j * self.n_doppler
            cand = elements * self._compensation(k)
            az_in = np.zeros((len(k), self.n_az), np.complex64)
            az_in[:, self.az_h] = cand[:, self.az_elements]
            peak_power = np.abs(scipy.fft.fft(az_in, axis=1)).max(axis=1)
            better = peak_power > best_power
            best_power = np.where(better, peak_power, best_power)
            best_el = np.where(better[:, None], cand, best_el)
            best_k = np.where(better, k, best_k)
        return best_el, best_k

    def _second_peaks(self, mag: np.ndarray, peak: np.ndarray):
        """(rows, bins) of azimuth local maxima at least second_peak_threshold of the first."""
        left, right = np.roll(mag, 1, axis=1), np.roll(mag, -1, axis=1)
        local = (mag > left) & (mag >= right)
        rows = np.arange(len(peak))
        local[rows, peak] = False
        cand = np.where(local, mag, 0.0)
        k2 = cand.argmax(axis=1)
        ok = cand[rows, k2] >= self.params.second_peak_threshold * mag[rows, peak]
        return (rows[ok], k2[ok]) if ok.any() else None


def _check_coupling(coupling: RangeCoupling, cfg: RadarConfig, n_range: int) -> None:
    where = coupling.origin
    if coupling.values.shape[:2] != (cfg.num_tx_slots, cfg.num_rx):
        raise ConfigError(f"the coupling is for {coupling.values.shape[0]} TX x {coupling.values.shape[1]} RX, the cfg "
                          f"has {cfg.num_tx_slots} TX slots x {cfg.num_rx} RX", path=where)
    if len(coupling.window) != cfg.num_samples or n_range != cfg.num_samples:
        raise ConfigError(f"the coupling was measured behind a {len(coupling.window)}-point range FFT without zero "
                          f"padding; the cfg has {cfg.num_samples} samples and the DSP a {n_range}-point FFT "
                          "(leave DspConfig.range_fft_size unset)", path=where)


def _detection_range(cfg: RadarConfig, params: DspConfig, range_bias_m: float) -> tuple[float, float]:
    """(shortest, longest) range of a detection, m (see FrameProcessor.detection_range_m)."""
    fov = cfg.cfar_fov.get(0)
    lo = params.min_range_m if fov is None else max(params.min_range_m, fov.min_value)
    if params.max_range_m is not None:
        hi = params.max_range_m
    elif fov is not None:
        hi = fov.max_value
    else:  # the IF band's limit is on the beat frequency, before the range bias comes off
        hi = cfg.max_range_m - range_bias_m
    if hi <= lo:
        raise ConfigError(f"no range is left to detect in: {lo:g} m to {hi:g} m (DspConfig min_range_m, "
                          "max_range_m and the cfg's cfarFovCfg range limits)", field="max_range_m")
    return lo, hi


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
    # One azimuth peak a cell, and multiObjBeamForming's second one, as TI's demo.
    return dataclasses.replace(params, ti_like=True, max_azimuth_peaks=1, **changes)


__all__ = ["POINT_DTYPE", "FrameProcessor", "FrameResult", "CfarParams", "make_window", "three_bin_response",
           "ti_like_params"]
