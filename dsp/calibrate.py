"""Measuring a board's channel calibration (``compRangeBiasAndRxChanPhase``) from a corner reflector.

The method is TI's ``measureRangeBiasAndRxChanPhase`` (mmWave SDK 3.5, ``objectdetection.c``
``DPC_ObjDet_rangeBiasRxChPhaseMeasure``): a corner reflector on boresight at a known distance;
the strongest zero-Doppler range peak within distance +/- window; its complex value x on each of
the 12 virtual antennas; the coefficient ``conj(x) * min|x| / |x|^2`` (so that, corrected, all
antennas agree); the range bias the peak's range minus the true distance.  Where it differs, for
accuracy: TI takes one frame's first chirp of each TX at the peak's bin; here the zero-Doppler
bin of the Doppler FFT (every loop integrated) is averaged over frames, and the peak is placed
between range bins through the range window's own three-bin response (TI fits a parabola).

A set-up that would give a wrong line is refused with the reason (:class:`CalibrationError`):

- the reflector too weak: its zero-Doppler cell less than :data:`MIN_SNR_DB` over the noise
  (the phases would carry the noise);
- not alone: another return in the window within :data:`ALONE_MARGIN_DB` of it, or its 12
  responses not those of one point (a 3 x 4 matrix of TX times RX paths is of rank one for one
  reflector; a second reflector at the same range or multipath breaks that by more than
  :data:`MAX_RANK_ONE_RESIDUAL_DEG`);
- off boresight: the azimuth row's phases fit a plane wave from more than
  :data:`MAX_APPARENT_AZIMUTH_DEG` (or the caller's limit) to the side.  A board's own errors
  give an apparent direction too, small for nearly every board (docs/calibration.md has the
  measurement); a reflector farther off would be built into the line and turn every angle.
  (The elevation cannot be checked this way: one raised row's phase is all it has, and that is
  what the line corrects.)
- moving (or the radar): its range changing by more than :data:`MAX_RANGE_SPREAD_BINS` of a bin
  over the frames, or its strongest Doppler bin more than one bin off zero.

The residual phase error reported is what remains after the correction: the RMS over frames
and antennas of each corrected sample's phase against its frame's mean phase (noise and
instability; 0 for a perfect measurement).
"""

from __future__ import annotations

import math
import logging
from dataclasses import dataclass

import numpy as np

from ..antenna import NUM_RX_ANTENNAS
from ..calibration import ChannelCalibration, RangeCoupling
from ..cfg import RadarConfig, require_config
from ..errors import CalibrationError, ConfigError, UsageError
from ..plain_numbers import is_number
from ..rawframe import unusable_samples
from .config import DspConfig
from .points import invert_three_bins
from .processor import FrameProcessor, three_bin_response

log = logging.getLogger(__name__)

#: The reflector's zero-Doppler cell over the noise, dB, at least (summed over the antennas,
#: one frame): 25 dB leaves each antenna's phase within 2.3 degrees RMS in one frame.
MIN_SNR_DB = 25.0
#: Another return inside the window (outside the reflector's main lobe) must be this much
#: weaker than the reflector, dB.
ALONE_MARGIN_DB = 15.0
#: The 12 responses' phase against their best rank-one (TX times RX) fit, RMS, degrees, at most:
#: between what noise at MIN_SNR_DB makes and what a second reflector ALONE_MARGIN_DB weaker at
#: the same range makes (docs/calibration.md, "What it refuses").
MAX_RANK_ONE_RESIDUAL_DEG = 3.0
#: The azimuth row's plane-wave direction, degrees from boresight, at most.
MAX_APPARENT_AZIMUTH_DEG = 8.0
#: A measured range this far from the distance given is more likely a distance measured wrong
#: than a board's range bias (a few centimetres): said, not refused, m.
LARGE_RANGE_BIAS_M = 0.10
#: The reflector's range over the frames, max - min, in range bins, at most.
MAX_RANGE_SPREAD_BINS = 0.5
#: Another local maximum of the range profile this many bins or more from the reflector's peak
#: is another return (a single reflector's main lobe has one maximum; its sidelobes are more
#: than ALONE_MARGIN_DB down for the Hann and Blackman windows).
SEPARATE_PEAK_BINS = 2


@dataclass(frozen=True)
class CalibrationMeasurement:
    """What :class:`ChannelCalibrator` measured."""

    #: The line: coefficients and range bias.
    calibration: ChannelCalibration
    #: The reflector's true distance, and its range as measured (before the bias is taken off), m.
    distance_m: float
    measured_range_m: float
    #: The reflector's zero-Doppler cell over the noise, dB (mean over frames, summed antennas).
    snr_db: float
    #: Phase error left after the correction, RMS over frames and antennas, degrees.
    residual_phase_deg: float
    #: The responses' phase against their rank-one fit, RMS, degrees.
    rank_one_residual_deg: float
    #: The azimuth row's plane-wave direction, degrees (positive right).
    apparent_azimuth_deg: float
    #: Frames averaged (measured on the chip: the demo's measurements combined).
    frames: int
    #: Who measured the reflector's samples: "radarodom" (raw frames) or "demo firmware" (TI's
    #: measureRangeBiasAndRxChanPhase on the chip, :mod:`.demo_calibration`).
    measured_by: str = "radarodom"

    def describe(self) -> dict:
        """JSON-ready: ``range_bias_m``, ``coefficients`` (12 [re, im], TI's order), ``cfg_line``,
        ``snr_db``, ``residual_phase_deg``, and ``gain_db``, ``phase_deg``, ``distance_m``,
        ``measured_range_m``, ``frames``, ``rank_one_residual_deg``, ``apparent_azimuth_deg``,
        ``measured_by``."""
        cal = self.calibration.describe()
        return {"range_bias_m": cal["range_bias_m"], "coefficients": cal["coefficients"],
                "cfg_line": cal["cfg_line"], "snr_db": self.snr_db,
                "residual_phase_deg": self.residual_phase_deg, "gain_db": cal["gain_db"],
                "phase_deg": cal["phase_deg"], "distance_m": self.distance_m,
                "measured_range_m": self.measured_range_m, "frames": self.frames,
                "rank_one_residual_deg": self.rank_one_residual_deg,
                "apparent_azimuth_deg": self.apparent_azimuth_deg, "measured_by": self.measured_by}


class ChannelCalibrator:
    """Accumulates raw frames of a corner reflector at *distance_m* on boresight and measures
    the line from them (:meth:`add`, then :meth:`result`).

    *window_m*: the reflector's peak is searched within distance +/- window (TI's searchWin is
    the whole width, twice this).  The cfg must use all 3 TX, each once a loop, and all 4 RX.
    *max_azimuth_deg*: the apparent direction allowed (a board with larger errors of its own).
    *coupling*: the source's TX-to-RX coupling (``Source.coupling``), taken out first.
    """

    def __init__(self, cfg: RadarConfig, distance_m: float, window_m: float = 0.2, *,
                 max_azimuth_deg: float = MAX_APPARENT_AZIMUTH_DEG, coupling: RangeCoupling | None = None) -> None:
        require_config(cfg)
        for name, value in (("distance_m", distance_m), ("window_m", window_m), ("max_azimuth_deg", max_azimuth_deg)):
            if not is_number(value):
                raise UsageError(f"{name}: a number, got {type(value).__name__} {value!r}")
        if not (math.isfinite(distance_m) and distance_m > 0):
            raise UsageError(f"the reflector's distance must be a positive number of metres, got {distance_m!r}")
        if not (math.isfinite(window_m) and window_m > 0):
            raise UsageError(f"the search window must be a positive number of metres, got {window_m!r}")
        if not (math.isfinite(max_azimuth_deg) and 0 < max_azimuth_deg <= 90):  # (90: any direction)
            raise UsageError(f"max_azimuth_deg: the largest apparent azimuth must be above 0 and at most 90 degrees, "
                             f"got {max_azimuth_deg!r}")
        self.max_azimuth_deg = float(max_azimuth_deg)
        if sorted(cfg.tx_order) != [1, 2, 3] or cfg.num_rx != NUM_RX_ANTENNAS:
            line = cfg.line_of("channelCfg")
            raise ConfigError(
                "the calibration line has a coefficient for every TX and RX path: measure it with a cfg that "
                f"uses TX1, TX2 and TX3 once a loop and all four RX (this one uses TX "
                f"{', '.join(map(str, cfg.tx_order))} and RX {', '.join(str(r + 1) for r in cfg.rx_indices)})",
                path=cfg.path, line=line.line if line is not None else None, command="channelCfg")
        self.cfg = cfg
        self.distance_m = float(distance_m)
        self.window_m = float(window_m)
        # The board's samples as they come: no calibration, no clutter removal.
        self.proc = FrameProcessor(cfg, DspConfig(channel_calibration=False, clutter_removal=False),
                                   coupling=coupling)
        step = float(self.proc.range_m[1] - self.proc.range_m[0])
        self.bin_m = step
        lo, hi = self.distance_m - self.window_m, self.distance_m + self.window_m
        bins = np.flatnonzero((self.proc.range_m >= lo) & (self.proc.range_m <= hi))
        near, far = self.proc.detection_range_m  # beyond: the IF filter's roll-off
        if hi > far or lo < near:
            room = min(self.distance_m - near, far - self.distance_m)  # the widest window that fits there
            fix = (f"narrow the search window (at most +/- {room:.2f} m here)" if room >= 1.5 * step else
                   f"place the reflector within it, at least {1.5 * step:.2f} m from its ends")
            raise UsageError(f"the reflector at {self.distance_m:g} m +/- {self.window_m:g} m (the search window) "
                             f"spans {lo:.2f} m to {hi:.2f} m, outside the range this cfg measures well "
                             f"({near:g} m to {far:.2f} m): {fix}")
        if len(bins) < 3:
            raise UsageError(f"the search window +/- {self.window_m:g} m holds {len(bins)} range bin(s) of "
                                   f"{step * 100:.1f} cm: widen it to at least {1.5 * step:.2f} m")
        # One bin more either side, to tell a peak at the window's edge from a slope.
        self._bins = np.arange(max(bins[0] - 1, 0), min(bins[-1] + 2, self.proc.n_range))
        self._inside = (self._bins >= bins[0]) & (self._bins <= bins[-1])
        self._zero = self.proc.n_doppler // 2
        self._frames: list[np.ndarray] = []  # (n_doppler, slots, rx, window bins) per frame
        self._table = three_bin_response(self.proc.w_range, self.proc.n_range, "range_window",
                                         fix="measure with a Hann or Blackman range window")

    def add(self, cube: np.ndarray) -> None:
        """One frame's raw cube, complex (loops, tx_slots, rx, samples).  A cube that is no numeric
        array, is shaped otherwise, or whose samples hold NaN or infinite values or are too large
        for the float32 power, is refused saying so (as :meth:`FrameProcessor.process` says it);
        the frame is not taken."""
        who = f"ChannelCalibrator.add (frame {self.frames + 1} of the measurement)"
        self.proc.check_cube(cube, who)
        # A NaN or inf sample spreads over every range bin of its antenna: kept, it made result()
        # blame the set-up ("no reflector peak ... at the window's edge"), after numpy's warnings.
        with np.errstate(invalid="ignore", over="ignore"):
            kept = self.proc.doppler_fft(self.proc.range_fft(cube))[:, :, :, self._bins]
            finite = np.isfinite((kept.real ** 2 + kept.imag ** 2).sum())
        if not finite:
            raise UsageError(f"{who}: {unusable_samples(cube)}")
        self._frames.append(kept.copy())

    @property
    def frames(self) -> int:
        return len(self._frames)

    def result(self) -> CalibrationMeasurement:
        """The measurement, or :class:`CalibrationError` saying what is wrong with the set-up."""
        if not self._frames:
            raise CalibrationError("no frame to measure: none was added (a source that gave no complete frame?)")
        data = np.stack(self._frames)  # (frames, n_doppler, slots, rx, bins)
        power = (np.abs(data) ** 2).sum(axis=(2, 3))  # (frames, n_doppler, bins)
        zero = power[:, self._zero].mean(axis=0)  # (bins,)
        # Noise per cell: Doppler rows far from zero hold no static return.
        far = np.abs(np.arange(self.proc.n_doppler) - self._zero) >= self.proc.n_doppler // 4
        noise = float(np.median(power[:, far]))
        inside = np.flatnonzero(self._inside)
        k = int(inside[np.argmax(zero[inside])])
        bins = self._bins
        range_of = lambda j: float(self.proc.range_m[bins[j]])  # noqa: E731
        snr_db = 10 * math.log10(zero[k] / max(noise, 1e-30))
        if k in (0, len(bins) - 1) or not (zero[k] >= zero[k - 1] and zero[k] >= zero[k + 1]):
            raise CalibrationError(
                f"no reflector peak within {self.distance_m:g} m +/- {self.window_m:g} m: the strongest return there "
                f"is at the window's edge ({range_of(k):.2f} m), the slope of something outside it; check "
                f"--distance, or widen --search-window")
        if snr_db < MIN_SNR_DB:
            raise CalibrationError(
                f"no reflector strong enough within {self.distance_m:g} m +/- {self.window_m:g} m: the strongest "
                f"return there, at {range_of(k):.2f} m, is {snr_db:.1f} dB over the noise (at least {MIN_SNR_DB:g} dB "
                "needed); check --distance, use a larger corner reflector, or bring it closer")
        self._check_alone(zero, k, range_of)
        self._check_still(data, power, k, range_of)
        # The reflector's range between bins, from the summed magnitude's three bins (range
        # migration is ruled out above, so the frames' mean profile is the reflector's).
        measured = float(self.proc.range_m[bins[k]]) + float(self._offsets(zero[None], np.array([k]))[0]) * self.bin_m
        # The responses: each frame's zero-Doppler sample at the peak, turned to the first frame's
        # common phase (a frame-to-frame phase drift common to all antennas changes no coefficient).
        samples = data[:, self._zero, :, :, k].reshape(len(data), -1)  # (frames, elements)
        turn = np.exp(-1j * np.angle(samples @ np.conj(samples[0])))
        response_elements = (samples * turn[:, None]).mean(axis=0)
        response = self.cfg.virtual_array.per_path(response_elements.astype(np.complex128))
        calibration, rank_one, azimuth = self.line_of_response(response, measured)
        corrected = samples * calibration.for_array(self.cfg.virtual_array).ravel()[None, :]
        common = np.sum(corrected, axis=1, keepdims=True)
        residual = float(np.degrees(np.sqrt(np.mean(np.angle(corrected * np.conj(common)) ** 2))))
        return CalibrationMeasurement(calibration, self.distance_m, measured, snr_db, residual, rank_one,
                                      azimuth, len(self._frames))

    def line_of_response(self, response: np.ndarray, measured: float) -> tuple[ChannelCalibration, float, float]:
        """The line correcting the paths' *response* to the reflector, complex (3, 4) [TX - 1, RX],
        measured at range *measured* (m), with the response's rank-one residual and apparent
        azimuth (degrees); :class:`CalibrationError` when it is not one point on boresight."""
        rank_one = _rank_one_residual_deg(response)
        if rank_one > MAX_RANK_ONE_RESIDUAL_DEG:
            raise CalibrationError(
                f"the reflector at {measured:.2f} m does not answer as one point: its 12 antenna phases are "
                f"{rank_one:.1f} deg RMS from any TX-times-RX pattern (more than {MAX_RANK_ONE_RESIDUAL_DEG:g}); another "
                "reflector at the same range or a reflection off something nearby; clear the area around it")
        azimuth = self._apparent_azimuth_deg(self.cfg.virtual_array.per_element(response).ravel())
        if abs(azimuth) > self.max_azimuth_deg:
            side = "right" if azimuth > 0 else "left"
            raise CalibrationError(
                f"the reflector at {measured:.2f} m looks {abs(azimuth):.1f} deg {side} of boresight (its azimuth "
                f"phases fit a plane wave from there, more than {self.max_azimuth_deg:g} deg): put it on the radar's "
                "boresight, at the antennas' height; if it is there, the board's own errors are that large: allow "
                "them with --max-azimuth DEG")
        calibration = ChannelCalibration.from_response(response, measured - self.distance_m)
        if abs(measured - self.distance_m) > LARGE_RANGE_BIAS_M:
            log.warning("the reflector reads %.3f m, %.0f cm from the distance given (%g m): a board's range bias "
                        "is a few centimetres; check the distance (to the reflector's corner, from the antennas)",
                        measured, 100 * abs(measured - self.distance_m), self.distance_m)
        return calibration, rank_one, azimuth

    def _check_alone(self, zero: np.ndarray, k: int, range_of) -> None:
        peaks = [j for j in np.flatnonzero(self._inside) if 0 < j < len(zero) - 1
                 and abs(j - k) >= SEPARATE_PEAK_BINS and zero[j] >= zero[j - 1] and zero[j] >= zero[j + 1]]
        for j in sorted(peaks, key=lambda j: -zero[j]):
            below = 10 * math.log10(zero[k] / zero[j])
            if below < ALONE_MARGIN_DB:
                raise CalibrationError(
                    f"the reflector at {range_of(k):.2f} m is not alone in the window: another return at "
                    f"{range_of(j):.2f} m is only {below:.1f} dB weaker (at least {ALONE_MARGIN_DB:g} dB needed); "
                    "clear the area around the reflector, or narrow --search-window")

    def _check_still(self, data: np.ndarray, power: np.ndarray, k: int, range_of) -> None:
        # Strongest Doppler row at the reflector's bin, frame by frame.
        rows = power[:, :, k].argmax(axis=1) - self._zero
        moving = np.abs(rows) > 1
        if np.any(moving):
            # (once things move, a range bin's strongest Doppler may be anything's: the count, not a speed)
            raise CalibrationError(
                f"the reflector at {range_of(k):.2f} m moves: its range bin's strongest return is off zero Doppler "
                f"in {int(moving.sum())} of {len(rows)} frames; keep the reflector and the radar still while measuring")
        zero = power[:, self._zero]  # (frames, bins)
        peaks = zero.argmax(axis=1)
        spread = 0.0
        if len(zero) > 1 and np.all((peaks > 0) & (peaks < zero.shape[1] - 1)):
            position = peaks + self._offsets(zero, peaks)
            spread = float(position.max() - position.min())
        elif len(set(peaks.tolist())) > 1:
            spread = float(peaks.max() - peaks.min())
        if spread > MAX_RANGE_SPREAD_BINS:
            raise CalibrationError(
                f"the reflector at {range_of(k):.2f} m moves: its range changed by {spread * self.bin_m * 100:.1f} cm "
                f"over {len(zero)} frames; keep the reflector and the radar still while measuring")

    def _offsets(self, power: np.ndarray, peaks: np.ndarray) -> np.ndarray:
        """Sub-bin offsets (-0.5 .. 0.5) of range profiles *power* (n, bins) peaking at bins
        *peaks* (n,), from the magnitudes of each peak's three bins (the range window's response)."""
        mag = np.sqrt(power)
        f = np.arange(len(peaks))
        return invert_three_bins(mag[f, peaks - 1], mag[f, peaks], mag[f, peaks + 1], self._table)

    def _apparent_azimuth_deg(self, elements: np.ndarray) -> float:
        """Direction of the plane wave that best fits the azimuth row's responses, degrees."""
        proc = self.proc
        wx = np.linspace(-1.0, 1.0, 2001)
        steer = np.exp(-1j * np.pi * np.outer(wx, proc.az_h))  # the DSP's azimuth FFT, continuous
        beam = np.abs(steer @ elements[proc.az_elements])
        return float(np.degrees(np.arcsin(wx[int(np.argmax(beam))])))


def _rank_one_residual_deg(response: np.ndarray) -> float:
    """RMS phase of a (3, 4) response against its best rank-one fit, degrees."""
    u, s, vh = np.linalg.svd(response)
    fit = s[0] * np.outer(u[:, 0], vh[0])
    return float(np.degrees(np.sqrt(np.mean(np.angle(response * np.conj(fit)) ** 2))))


def measure(cfg: RadarConfig, cubes, distance_m: float, window_m: float = 0.2, **options) -> CalibrationMeasurement:
    """The line measured from an iterable of raw cubes of a corner reflector on boresight
    (*options*: :class:`ChannelCalibrator`'s)."""
    calibrator = ChannelCalibrator(cfg, distance_m, window_m, **options)
    for cube in cubes:
        calibrator.add(cube)
    return calibrator.result()


__all__ = ["ALONE_MARGIN_DB", "CalibrationMeasurement", "ChannelCalibrator", "MAX_APPARENT_AZIMUTH_DEG",
           "MAX_RANGE_SPREAD_BINS", "MAX_RANK_ONE_RESIDUAL_DEG", "MIN_SNR_DB", "measure"]
