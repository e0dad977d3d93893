"""A board's channel calibration from the measurements TI's demo firmware makes on the chip.

A board streamed without a DCA1000 (``tidemo://``) gives no raw ADC frames, but the mmWave SDK 3.x
demo measures the line itself: with ``measureRangeBiasAndRxChanPhase 1 <targetDistance>
<searchWin>`` in the cfg it prints, every frame, on its CLI port, the ``compRangeBiasAndRxChanPhase``
line that corrects what it saw (``MmwDemo_measurementResultOutput``; TI's method, one frame's first
chirp of each TX: :mod:`.calibrate` has it).  One such line carries one chirp's noise, so
:func:`combine_demo_measurements` averages the lines' responses and refuses what the raw path
refuses where a line can tell it (:class:`CalibrationError`):

- fewer than :data:`MIN_LINES` whole lines (their scatter could not be told);
- lines that scatter so much that their mean's phases are uncertain by more than
  :data:`MAX_MEAN_PHASE_ERROR_DEG` (a weak reflector, something moving in the window: the chip
  measures whatever is strongest there, and says nothing of its SNR);
- a range that changes by more than :data:`~.calibrate.MAX_RANGE_SPREAD_BINS` of a bin over the
  lines (the reflector or the radar moves), or by more than :data:`WANDERING_BINS` (no steady
  reflector in the window: the chip measures whatever is strongest there);
- a mean response that is not one point's, or looks off boresight (the raw path's checks,
  :meth:`.calibrate.ChannelCalibrator.line_of_response`).

Its ``residual_phase_deg`` is the lines' scatter about their mean (RMS over lines and paths,
degrees); the chip reports no SNR (``snr_db`` is NaN).
"""

from __future__ import annotations

import logging
import math
from typing import Sequence

import numpy as np

from .. import cfg_commands as cc
from ..calibration import CALIBRATION_COMMAND, ChannelCalibration
from ..cfg import RadarConfig
from ..errors import CalibrationError, ConfigError
from .calibrate import MAX_APPARENT_AZIMUTH_DEG, MAX_RANGE_SPREAD_BINS, CalibrationMeasurement, ChannelCalibrator

log = logging.getLogger(__name__)

#: What a measurement line starts with: the cfg command it is.
LINE_PREFIX = CALIBRATION_COMMAND
#: Lines combined, at least: their scatter is what says how far their mean can be trusted (one
#: chirp's line alone can be several degrees off, and nothing would say so).
MIN_LINES = 5
#: The lines' ranges spread over more than this many bins: no steady peak in the window at all
#: (noise, or something passing), rather than a reflector that creeps.
WANDERING_BINS = 2.0
#: The lines' mean phase per path, its standard error (scatter / sqrt(lines)), degrees, at most:
#: the raw path's ten frames at its weakest allowed SNR (25 dB) leave about 0.7.
MAX_MEAN_PHASE_ERROR_DEG = 1.0


def parse_measurement(line: str) -> ChannelCalibration:
    """One line the demo printed, as the calibration it measured; :class:`ConfigError` when it
    is not a whole ``compRangeBiasAndRxChanPhase`` line (cut or garbled on the UART)."""
    name, *tokens = line.split() or [""]
    if name != LINE_PREFIX:
        raise ConfigError(f"not a {LINE_PREFIX} line: {line[:60]!r}", command=name or None)
    return ChannelCalibration.from_command(cc.parse_args(LINE_PREFIX, tokens))


def combine_demo_measurements(cfg: RadarConfig, lines: Sequence[str], distance_m: float, window_m: float = 0.2, *,
                              max_azimuth_deg: float = MAX_APPARENT_AZIMUTH_DEG) -> CalibrationMeasurement:
    """The line from the demo's measurement *lines* of a corner reflector at *distance_m* on
    boresight, made with *cfg* (searched within distance +/- *window_m*); see the module
    docstring.  *cfg* is checked as :class:`~.calibrate.ChannelCalibrator` checks it."""
    checker = ChannelCalibrator(cfg, distance_m, window_m, max_azimuth_deg=max_azimuth_deg)
    measured, unreadable = [], []
    for line in lines:
        try:
            measured.append(parse_measurement(line))
        except ConfigError as exc:
            unreadable.append(exc.message)
    if unreadable:
        log.warning("%d of the demo's %d measurement line(s) could not be read (cut or garbled on the line), the "
                    "first: %s", len(unreadable), len(lines), unreadable[0])
    if not measured:
        raise CalibrationError("no measurement to combine: the demo printed no whole compRangeBiasAndRxChanPhase "
                               "line" + (f" ({len(lines)} unreadable)" if lines else ""))
    n = len(measured)
    if n < MIN_LINES:  # one line's noise cannot be told from the board's own errors
        raise CalibrationError(
            f"only {n} whole measurement line(s) from the demo" + (f" ({len(unreadable)} unreadable)" if unreadable
                                                                  else "")
            + f": at least {MIN_LINES} are needed to tell their noise from the board's errors; average more --frames")
    # Each line's response up to a scale and a phase common to its paths (the chip's frame, the
    # reflector's phase), brought to the first line's by all twelve paths, not by TX1 RX1 alone.
    responses = np.stack([1.0 / c.coefficients for c in measured])  # (n, 3, 4)
    responses /= np.sqrt(np.mean(np.abs(responses) ** 2, axis=(1, 2), keepdims=True))
    common = np.einsum("nij,ij->n", responses, np.conj(responses[0]))
    responses *= np.exp(-1j * np.angle(common))[:, None, None]
    biases = np.array([c.range_bias_m for c in measured])
    ranges = checker.distance_m + biases
    spread = float(biases.max() - biases.min())
    if spread > WANDERING_BINS * checker.bin_m:  # the chip takes whatever is strongest in the window
        raise CalibrationError(
            f"no still reflector within {checker.distance_m:g} m +/- {checker.window_m:g} m: the demo's {n} "
            f"measurements put the strongest return anywhere from {ranges.min():.2f} m to {ranges.max():.2f} m; "
            "nothing strong is there (check --distance; use a larger corner reflector or bring it closer) or it "
            "moves (keep the reflector and the radar still)")
    if spread > MAX_RANGE_SPREAD_BINS * checker.bin_m:
        raise CalibrationError(
            f"the reflector at {ranges.mean():.2f} m moves: its range changed by {spread * 100:.1f} cm over the demo's "
            f"{n} measurements; keep the reflector and the radar still while measuring")
    mean = responses.mean(axis=0)
    scatter = float(np.degrees(np.sqrt(np.mean(np.angle(responses * np.conj(mean)[None]) ** 2))))
    if scatter / math.sqrt(n) > MAX_MEAN_PHASE_ERROR_DEG:
        raise CalibrationError(
            f"the demo's {n} measurements of the reflector at {ranges.mean():.2f} m disagree by {scatter:.1f} deg RMS, "
            f"so their mean is uncertain by {scatter / math.sqrt(n):.1f} deg (at most {MAX_MEAN_PHASE_ERROR_DEG:g}): a "
            "weak reflector or something moving in the window; use a larger corner reflector or bring it closer, "
            "clear the window, or average more --frames")
    calibration, rank_one, azimuth = checker.line_of_response(mean, float(ranges.mean()))
    return CalibrationMeasurement(calibration, checker.distance_m, float(ranges.mean()), math.nan, scatter, rank_one,
                                  azimuth, n, measured_by="demo firmware")


__all__ = ["LINE_PREFIX", "MAX_MEAN_PHASE_ERROR_DEG", "MIN_LINES", "combine_demo_measurements", "parse_measurement"]
