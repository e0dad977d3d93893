"""The points of detections: angles, positions and radial velocities.

Per detection (a range-Doppler cell the CFAR found) the 12 virtual antennas' samples are
calibrated (the cfg's compRangeBiasAndRxChanPhase) and TDM-compensated (optionally over the
N_tx velocity hypotheses, TI's extended velocity); the azimuth row's zero-padded FFT gives the
azimuth, its peak placed between bins from the peak's bin and its neighbours
(DspConfig.azimuth_interpolation); the raised row gives the elevation; the Doppler rows either
side, beamformed toward the point's azimuth, place its radial velocity between Doppler bins
(DspConfig.doppler_interpolation: Doppler bin centres would bias the ego-velocity, since the
static world ahead piles up near the largest |radial velocity| where their rounding does not
average out); and further reflectors in the cell come one at a time (:mod:`.azimuth_peaks`).

Angles follow docs/conventions.md: the azimuth row's FFT peak k (plus its sub-bin offset) gives
``Wx = 2k/N`` and ``x = r Wx``; with the raised row's FFT taken at the elements' true
horizontal positions, ``Wz = angle(A conj(E)) / pi`` at that peak (the same as TI's
``angle(A conj(E))/pi + 2 Wx`` with the raised row indexed from its first element), ``z = r Wz``.
"""

from __future__ import annotations

import numpy as np

from ..calibration import ChannelCalibration
from ..cfg import RadarConfig
from ..errors import ConfigError
from ..products import POINT_DTYPE
from .azimuth_peaks import CellCleaner, apart
from .config import DspConfig



#: How far from its cell's Doppler bin a point's radial velocity may be placed, bins (the
#: neighbouring bin's centre; see PointMaker._offset_table).
DOPPLER_SPAN_BINS = 1.0

#: A cell whose strongest azimuth peak grows by this factor (0.6 dB) under another TDM
#: hypothesis holds one aliased target, not several reflectors (_further_peaks; chosen between
#: what the two cases measure, docs/dsp.md, "Several reflectors in one cell").
ALIASED_GAIN = 10 ** 0.06


def three_bin_response(window: np.ndarray, n_fft: int, setting: str = "doppler_interpolation",
                       fix: str | None = None, span: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """How an FFT of *n_fft* points of the *window*ed tone answers the tone's offset from a bin.

    Returns (ratio, offset): for a tone ``offset`` bins from bin k (-span .. span, 1000 steps a
    bin), ``ratio = (|X(k+1)| - |X(k-1)|) / |X(k)|``, increasing, so that
    ``np.interp(measured_ratio, ratio, offset)`` inverts it (clamped to the span).  A *span*
    beyond half a bin is for a bin that need not be the tone's own (a cell's further reflector,
    :class:`PointMaker`): it is cut to the offsets over which the ratio still grows (a tapered
    window's to nearly two bins, where the tone's main lobe leaves bin k; a rectangular one's to
    one, where bin k falls on its null), and never below half a bin.  Taken from
    the window itself, so it holds for any window and zero padding (a window with zero taps
    is an aperture with gaps).  *setting* is the DspConfig field that asked, for errors, and
    *fix* what to do about one (default: set it false).
    """
    fix = fix or f"set {setting} false"
    if n_fft < 3:
        raise ConfigError(f"interpolating between FFT bins needs three bins, the FFT has {n_fft}: {fix}",
                          field=setting)
    steps = int(round(1000 * span))
    offset = np.linspace(-span, span, 2 * steps + 1)
    taps = np.arange(len(window))
    weights = np.asarray(window, dtype=float)

    def magnitude(f: np.ndarray) -> np.ndarray:  # |DTFT of the window| f bins from its peak
        return np.abs(np.exp(-2j * np.pi * np.outer(f, taps) / n_fft) @ weights)

    centre = magnitude(-offset)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (magnitude(1.0 - offset) - magnitude(-1.0 - offset)) / centre
    grows = np.isfinite(ratio[1:]) & np.isfinite(ratio[:-1]) & (np.diff(ratio) > 0)
    # The widest span about zero over which the ratio grows both ways.
    reach = 0
    while reach < steps and grows[steps + reach] and grows[steps - reach - 1]:
        reach += 1
    if offset[steps + reach] < 0.5 - 1e-9:
        raise ConfigError("the window's three-bin response does not grow with the tone's offset, "
                          f"so it cannot be inverted: {fix}", field=setting)
    keep = slice(steps - reach, steps + reach + 1)
    return ratio[keep], offset[keep]


def invert_three_bins(below: np.ndarray, centre: np.ndarray, above: np.ndarray,
                      table: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Sub-bin offsets from the magnitudes of a peak's bin and its neighbours, through a
    :func:`three_bin_response` table."""
    ratio = (above - below) / np.maximum(centre, np.finfo(np.float32).tiny)
    return np.interp(ratio, *table)


def _angle_fft(elements: np.ndarray, workers: int) -> np.ndarray:
    """The FFT over the antennas (axis 1) of zero-padded elements (detections, n_angle), complex."""
    import scipy.fft  # at the first frame: a program that only checks its input starts without it

    return scipy.fft.fft(elements, axis=1, workers=workers)


class PointMaker:
    """Points of one radar configuration's detections (see the module docstring).

    *doppler_bins*: the signed Doppler bin of each row of the centred spectrum (n_doppler,);
    *range_m*: the range of each range bin (n_range,); *w_doppler*: the Doppler window.
    """

    def __init__(self, cfg: RadarConfig, params: DspConfig, calibration: ChannelCalibration,
                 w_doppler: np.ndarray, doppler_bins: np.ndarray, range_m: np.ndarray) -> None:
        self.cfg, self.params = cfg, params
        self.n_doppler = len(doppler_bins)
        self.doppler_bins = doppler_bins
        self.range_m = range_m
        slots, nrx = cfg.num_tx_slots, cfg.num_rx
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
        # Without TI's extended velocity, further azimuth peaks are checked for an aliased target.
        self._check_aliasing = (params.tdm_compensation and not params.velocity_disambiguation
                                and cfg.num_tx_slots > 1)
        # Two reflectors closer than three quarters of the azimuth row's resolution (2 / its length
        # in Wx) are one peak: a further peak nearer a taken one is what removing it left.
        self._peak_separation_bins = 0.75 * self.n_az / (int(self.az_h.max()) + 1)
        self._slot_of_element = np.repeat(np.arange(slots), nrx)
        self._tdm = self._slot_phases(self.doppler_bins)  # (n_doppler, slots)
        coefficients = calibration.for_array(va).ravel()
        #: Each virtual element's calibration coefficient, complex64 (elements,); None when
        #: every one is 1 (then nothing is multiplied).
        self.calibration_weights = None if np.all(coefficients == 1) else coefficients
        weights = (self._tdm[:, self._slot_of_element] if params.tdm_compensation
                   else np.ones((self.n_doppler, slots * nrx), np.complex64))
        #: What each virtual element's Doppler spectrum is multiplied by before angle processing,
        #: per row of the centred spectrum: its TX slot's TDM-MIMO phase and its calibration
        #: coefficient.  complex64 (n_doppler, elements); the heatmaps use it.
        self.angle_weights = (weights if self.calibration_weights is None
                              else (weights * self.calibration_weights).astype(np.complex64))
        #: (ratio, offset) of three_bin_response for sub-bin Doppler, or None (bin centres).  It
        #: reaches a bin each way: a cell's further reflector may lie up to a bin from the cell's
        #: own Doppler bin (its peak in the next cell, its main lobe strong enough here); clamped
        #: to half a bin, it read up to half a bin toward the cell's (docs/dsp.md, "Radial velocity
        #: between Doppler bins").
        self._offset_table = (three_bin_response(w_doppler, self.n_doppler, span=DOPPLER_SPAN_BINS)
                              if params.doppler_interpolation else None)
        self._aoa = cfg.aoa_fov if params.ti_like else None

    def points(self, spectrum: np.ndarray, doppler_idx: np.ndarray, range_idx: np.ndarray,
               snr_db: np.ndarray, noise: np.ndarray) -> np.ndarray:
        """Angles and positions of detections (row indices into the centred spectrum)."""
        n = len(range_idx)
        slots = self.cfg.num_tx_slots
        elements = spectrum[doppler_idx, :, :, range_idx].reshape(n, slots * self.cfg.num_rx)
        if self.calibration_weights is not None:
            elements *= self.calibration_weights
        doppler = self.doppler_bins[doppler_idx].astype(float)
        if self.params.tdm_compensation and self.params.velocity_disambiguation and slots > 1:
            elements, doppler = self._disambiguate(elements, doppler)
        elif self.params.tdm_compensation:
            elements = elements * self._tdm[doppler_idx][:, self._slot_of_element]
        neighbours = (self._neighbours(spectrum, doppler_idx, range_idx, doppler)
                      if self._offset_table is not None else None)
        az_in = np.zeros((n, self.n_az), np.complex64)
        az_in[:, self.az_h] = elements[:, self.az_elements]
        az = _angle_fft(az_in, self.params.workers)
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
            el = _angle_fft(el_in, self.params.workers)
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
        if self._azimuth_table is None:
            return k.astype(float)
        # The axis is cyclic: a peak in the last bin (-n/2, sin(azimuth) -1) whose offset points
        # below it lies at the other end (a reflector some 80-90 degrees to the right), not beyond -1.
        half = self.n_az / 2
        return (k + self._azimuth_offsets(az, peak) + half) % self.n_az - half

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
        if self._check_aliasing:
            # A target beyond the unambiguous velocity, compensated for the wrong TDM hypothesis,
            # splits its azimuth spectrum in two: another hypothesis that merges it into one
            # stronger peak marks the cell as that, not as two reflectors (ALIASED_GAIN's
            # measurement: docs/dsp.md, "Several reflectors in one cell").
            floor = np.where(self._aliased(elements) > ALIASED_GAIN * first, np.inf, floor)
        elements = elements.copy()
        sides = None if neighbours is None else neighbours.copy()
        taken = [self._bins_at(az, peak)]
        az_in = np.zeros((len(peak), self.n_az), np.complex64)
        out = []
        for _ in range(1, p.max_azimuth_peaks):
            self._cleaner.remove(elements, sides, 2.0 * taken[-1] / self.n_az)
            az_in[:, self.az_h] = elements[:, self.az_elements]
            az = _angle_fft(az_in, p.workers)
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

    def _aliased(self, elements: np.ndarray) -> np.ndarray:
        """The strongest azimuth peak power (n,) of detections' *elements* (compensated for
        their own Doppler bin) under the other TDM hypotheses (bin + j n_doppler, j != 0)."""
        best = np.zeros(len(elements))
        for _, _, peak in self._hypotheses(elements, np.zeros(len(elements)), skip_own=True):
            best = np.maximum(best, peak ** 2)
        return best

    def _hypotheses(self, elements: np.ndarray, doppler: np.ndarray, skip_own: bool = False):
        """Per TDM-MIMO hypothesis, Doppler bins ``doppler + j n_doppler`` (j centred on 0; j = 0
        left out with *skip_own*): those bins (n,), *elements* (n, elements) compensated for them,
        and the magnitude of their strongest azimuth peak (n,)."""
        slots = self.cfg.num_tx_slots
        az_in = np.zeros((len(elements), self.n_az), np.complex64)
        for j in np.arange(slots) - (slots - 1) // 2:
            if skip_own and j == 0:
                continue
            k = doppler + j * self.n_doppler
            turned = elements * self._compensation(k)
            az_in[:, self.az_h] = turned[:, self.az_elements]
            yield k, turned, np.abs(_angle_fft(az_in, self.params.workers)).max(axis=1)

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
            if self.calibration_weights is not None:
                side *= self.calibration_weights
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
        return invert_three_bins(side[:, 0], np.abs(centre), side[:, 1], self._offset_table)

    def _azimuth_offsets(self, az: np.ndarray, peak: np.ndarray) -> np.ndarray:
        """Sub-bin offsets (-0.5 .. 0.5) of the azimuth FFT *az*'s peaks at bins *peak*, from
        each peak's bin and its neighbours (the FFT is cyclic)."""
        rows = np.arange(len(peak))
        below, centre, above = (np.abs(az[rows, (peak + step) % self.n_az]) for step in (-1, 0, 1))
        return invert_three_bins(below, centre, above, self._azimuth_table)

    def _disambiguate(self, elements: np.ndarray, doppler: np.ndarray):
        """TI's extended velocity: of the N_tx Doppler hypotheses k + j n_doppler,
        keep the one whose compensation gives the strongest azimuth peak."""
        best_power = np.full(len(doppler), -1.0)
        best_el = elements
        best_k = doppler
        for k, cand, peak_power in self._hypotheses(elements, doppler):
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



__all__ = ["ALIASED_GAIN", "DOPPLER_SPAN_BINS", "POINT_DTYPE", "PointMaker", "three_bin_response"]
