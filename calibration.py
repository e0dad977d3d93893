"""A board's channel calibration: TI's ``compRangeBiasAndRxChanPhase`` line as numbers.

Every AWR1843BOOST leaves the factory with its own gain and phase on each TX and RX path (tens
of degrees apart) and a range offset of its front end.  TI's demo firmware corrects both with
the cfg line ``compRangeBiasAndRxChanPhase <rangeBias> <Re Im> x 12``, measured once per board
with a corner reflector (``radar-calibrate``, :mod:`radarodom.dsp.calibrate`).  What the
firmware does with it (mmWave SDK 3.5, xWR18xx demo: ``mmw_cli.c``
``MmwDemo_CLICompRangeBiasAndRxChanPhaseCfg``, ``objectdetection.c``
``DPC_ObjDet_GetRxChPhaseComp``, ``aoaprochwa.c``), and radarodom with it:

- pair ``t * 4 + r`` belongs to physical TX t (TX1, TX2, TX3 as 0, 1, 2) and RX r, whatever
  order the chirps transmit in: the firmware reorders the table into the frame's TX-slot order
  (``rxChPhaseComp[slot * numRx + i] = table[txAntOrder[slot] * 4 + rxAntOrder[i]]``, the i-th
  enabled RX by its physical index), as
  :meth:`ChannelCalibration.for_array` does;
- every virtual antenna's sample is multiplied by its coefficient before any angle processing
  (the detected points' 12 antennas, the azimuth heatmap, the elevation row);
- ``rangeBias`` (m) is subtracted from every range;
- the firmware reads each value as Q15 (``atof * 32768``, saturated): each part in [-1, 1).

A measurement gives ``conj(x) * min|x| / |x|^2`` for the reflector's sample x on each virtual
antenna: corrected, every antenna has the weakest one's magnitude and the same phase.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import cfg_commands as cc
from .antenna import NUM_RX_ANTENNAS, NUM_TX_ANTENNAS, VirtualArray
from .errors import ConfigError

#: The cfg command that carries a board's channel calibration; TI's SDK 3.x demo prints what it
#: measured as one such line (MmwDemo_measurementResultOutput, mss_main.c).
CALIBRATION_COMMAND = "compRangeBiasAndRxChanPhase"
#: Decimals of the coefficients in a written line: 1e-5 is a third of a Q15 step (3.05e-5), as
#: TI's measurement prints them.
COEFFICIENT_DECIMALS = 5
#: Decimals of the range bias in a written line (0.1 mm; TI prints 7).
BIAS_DECIMALS = 5


@dataclass(frozen=True, eq=False)
class ChannelCalibration:
    """The range bias and one complex correction per physical (TX, RX) path."""

    #: Measured range minus true range, m; subtracted from every range.
    range_bias_m: float
    #: The correction each path's samples are multiplied by: complex128 (3, 4),
    #: [TX number - 1, RX index] (TI's order, row-major).
    coefficients: np.ndarray

    def __post_init__(self) -> None:
        c = np.asarray(self.coefficients, dtype=np.complex128)
        if c.shape != (NUM_TX_ANTENNAS, NUM_RX_ANTENNAS):
            raise ConfigError(f"coefficients must be shaped ({NUM_TX_ANTENNAS}, {NUM_RX_ANTENNAS}), got "
                              f"{c.shape}", command=CALIBRATION_COMMAND)
        if not np.all(np.isfinite(c)) or not math.isfinite(self.range_bias_m):
            raise ConfigError("coefficients and range bias must be finite", command=CALIBRATION_COMMAND)
        if np.any(c == 0):
            tx, rx = np.argwhere(c == 0)[0]
            raise ConfigError(f"the coefficient of TX{tx + 1} RX{rx + 1} is 0: that antenna would be "
                              "switched off", command=CALIBRATION_COMMAND)
        c.setflags(write=False)
        object.__setattr__(self, "coefficients", c)
        object.__setattr__(self, "range_bias_m", float(self.range_bias_m))

    # ------------------------------------------------------------------ building
    @classmethod
    def identity(cls) -> "ChannelCalibration":
        """No correction: bias 0, every coefficient 1 (the line ``0 1 0 1 0 ...``)."""
        return cls(0.0, np.ones((NUM_TX_ANTENNAS, NUM_RX_ANTENNAS)))

    @classmethod
    def from_command(cls, command: cc.CompRangeBiasAndRxChanPhase) -> "ChannelCalibration":
        pairs = np.array(command.rx_chan_phase, dtype=np.complex128)
        return cls(command.range_bias_m, pairs.reshape(NUM_TX_ANTENNAS, NUM_RX_ANTENNAS))

    @classmethod
    def from_config(cls, cfg) -> "ChannelCalibration":
        """The cfg's ``compRangeBiasAndRxChanPhase`` line (a :class:`radarodom.cfg.RadarConfig`);
        the identity when it has none."""
        command = cfg.comp_range_bias_and_rx_chan_phase
        if command is None:
            return cls.identity()
        try:
            return cls.from_command(command)
        except ConfigError as exc:  # the parser accepted each value; say which line holds them
            at = cfg.line_of(CALIBRATION_COMMAND)
            raise ConfigError(exc.message, path=cfg.path, line=None if at is None else at.line,
                              command=exc.command, field=exc.field) from None

    @classmethod
    def from_description(cls, description) -> "ChannelCalibration":
        """Back from :meth:`describe`'s ``range_bias_m`` and ``coefficients`` (12 [re, im])."""
        try:
            pairs = np.array(description["coefficients"], dtype=float)
            bias = float(description["range_bias_m"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"not a channel calibration: {exc}", command=CALIBRATION_COMMAND) from None
        if pairs.shape != (NUM_TX_ANTENNAS * NUM_RX_ANTENNAS, 2):
            raise ConfigError(f"12 [re, im] coefficients expected, got shape {pairs.shape}",
                              command=CALIBRATION_COMMAND)
        # The cfg line's own rule (each part within -1..1, not both 0), and a finite bias.
        if not (np.all(cc.coefficient_ok(pairs[:, 0], pairs[:, 1])) and math.isfinite(bias)):
            raise ConfigError("the coefficients' parts must be within -1..1, none 0 + 0j, and the bias finite",
                              command=CALIBRATION_COMMAND)
        return cls(bias, (pairs[:, 0] + 1j * pairs[:, 1]).reshape(NUM_TX_ANTENNAS, NUM_RX_ANTENNAS))

    @classmethod
    def from_response(cls, response: np.ndarray, range_bias_m: float) -> "ChannelCalibration":
        """The correction of paths that answer a boresight reflector with *response*, complex
        (3, 4) [TX - 1, RX]: ``conj(x) * min|x| / |x|^2``, TI's measurement formula, turned so
        that TX1 RX1's coefficient is real (the reflector's own phase, common to all, changes no
        angle; a perfect board then gives the identity)."""
        x = np.asarray(response, dtype=np.complex128)
        mag2 = np.abs(x) ** 2
        c = np.conj(x) * math.sqrt(float(mag2.min())) / mag2
        c = c * np.exp(-1j * np.angle(c[0, 0]))
        c[0, 0] = abs(c[0, 0])
        return cls(range_bias_m, c)

    # ------------------------------------------------------------------ reading
    @property
    def is_identity(self) -> bool:
        """True for the line that changes nothing (bias 0, every coefficient 1)."""
        return self.range_bias_m == 0.0 and bool(np.all(self.coefficients == 1.0))

    @property
    def response(self) -> np.ndarray:
        """The paths' gain and phase that the line corrects, relative to TX1 RX1: complex128 (3, 4)
        (the inverse of the coefficients, scaled so that TX1 RX1 is 1)."""
        inv = 1.0 / self.coefficients
        return inv / inv[0, 0]

    @property
    def gain_db(self) -> np.ndarray:
        """Each path's gain relative to TX1 RX1, dB, (3, 4)."""
        return 20.0 * np.log10(np.abs(self.response))

    @property
    def phase_deg(self) -> np.ndarray:
        """Each path's phase relative to TX1 RX1, degrees in (-180, 180], (3, 4)."""
        return np.degrees(np.angle(self.response))

    def for_array(self, array: VirtualArray) -> np.ndarray:
        """The coefficient of each element of a frame's virtual array: complex64 (tx_slots, rx),
        slot s transmitting on TX ``array.tx_order[s]`` (the firmware's txAntOrder reordering)."""
        return array.per_element(self.coefficients).astype(np.complex64)

    def matches(self, other: "ChannelCalibration", *, phase_deg: float = 1.0, gain_db: float = 0.1,
                bias_m: float = 1e-3) -> bool:
        """True when both lines correct the same paths to within *phase_deg*, *gain_db* and
        *bias_m* (a common gain and phase, which changes no angle, does not count)."""
        ratio = self.response / other.response
        return (abs(self.range_bias_m - other.range_bias_m) <= bias_m
                and float(np.abs(20 * np.log10(np.abs(ratio))).max()) <= gain_db
                and float(np.abs(np.degrees(np.angle(ratio))).max()) <= phase_deg)

    # ------------------------------------------------------------------ writing
    def to_command(self) -> cc.CompRangeBiasAndRxChanPhase:
        """The cfg command, rounded as written (:data:`COEFFICIENT_DECIMALS`).  The coefficients
        are scaled down together, if need be, so that every part fits the firmware's [-1, 1]."""
        c = self.coefficients
        peak = float(max(np.abs(c.real).max(), np.abs(c.imag).max()))
        if peak > 1.0:
            c = c / peak  # a common factor changes no angle
        pairs = tuple(complex(round(v.real, COEFFICIENT_DECIMALS) + 0.0, round(v.imag, COEFFICIENT_DECIMALS) + 0.0)
                      for v in c.ravel())
        return cc.CompRangeBiasAndRxChanPhase(round(self.range_bias_m, BIAS_DECIMALS) + 0.0, pairs)

    def cfg_line(self) -> str:
        """The line for a cfg file: ``compRangeBiasAndRxChanPhase <bias> <Re Im> x 12``."""
        command = self.to_command()
        values = [f"{command.range_bias_m:.{BIAS_DECIMALS}f}"]
        for v in command.rx_chan_phase:
            values += [f"{v.real:.{COEFFICIENT_DECIMALS}f}", f"{v.imag:.{COEFFICIENT_DECIMALS}f}"]
        return "compRangeBiasAndRxChanPhase " + " ".join(values)

    def describe(self) -> dict:
        """JSON-ready: ``range_bias_m``, ``coefficients`` (12 [re, im] in TI's order),
        ``gain_db`` and ``phase_deg`` (12 each, relative to TX1 RX1), ``identity``, ``cfg_line``."""
        return {"range_bias_m": self.range_bias_m,
                "coefficients": [[float(v.real), float(v.imag)] for v in self.coefficients.ravel()],
                "gain_db": [float(v) for v in self.gain_db.ravel()],
                "phase_deg": [float(v) for v in self.phase_deg.ravel()],
                "identity": self.is_identity, "cfg_line": self.cfg_line()}

    def table(self) -> list[str]:
        """Human lines: the bias, then each TX's row of (gain dB, phase deg) per RX."""
        lines = [f"range bias {self.range_bias_m * 100:+.2f} cm"]
        gain, phase = np.round(self.gain_db, 2) + 0.0, np.round(self.phase_deg, 1) + 0.0  # no "-0.00"
        for t in range(NUM_TX_ANTENNAS):
            cells = "  ".join(f"RX{r + 1} {gain[t, r]:+5.2f} dB {phase[t, r]:+7.1f} deg" for r in range(NUM_RX_ANTENNAS))
            lines.append(f"TX{t + 1}  {cells}")
        return lines


@dataclass(frozen=True, eq=False)
class RangeCoupling:
    """The leakage from the transmitters into the receivers as a dataset measured it, in the range
    domain: removed from every chirp's range spectrum before the Doppler FFT.  This is how
    ColoRadar calibrates its radars (``calib/<sensor>/coupling_calib.txt``, read by
    :func:`radarodom.driver.coloradar.read_coupling`); the values only mean something behind the
    very window and FFT they were measured with, so the frame processor then takes *window*
    for its range FFT (unnormalised, as many points as samples, no zero padding).
    """

    #: The coupling at range bins first_bin .. first_bin + n_bins - 1: complex64 (tx_slots, rx, n_bins)
    #: in the cube's order (TX slots in chirp order, enabled RX).
    values: np.ndarray
    #: Range-FFT bin of values[..., 0].
    first_bin: int
    #: The window the values were measured behind, float (samples,).
    window: np.ndarray
    #: Where the values came from, for messages.
    origin: str = "<coupling>"

    def __post_init__(self) -> None:
        values = np.asarray(self.values, dtype=np.complex64)
        window = np.asarray(self.window, dtype=np.float32)
        if values.ndim != 3 or window.ndim != 1 or self.first_bin < 0:
            raise ConfigError(f"coupling values must be (tx_slots, rx, bins) and the window 1-D, got "
                              f"{values.shape} and {window.shape}", path=self.origin)
        if self.first_bin + values.shape[2] > len(window):
            raise ConfigError(f"coupling bins {self.first_bin}..{self.first_bin + values.shape[2] - 1} run past "
                              f"a {len(window)}-point range FFT", path=self.origin)
        for array in (values, window):
            array.setflags(write=False)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "window", window)

    @property
    def is_zero(self) -> bool:
        """True when there is nothing to remove."""
        return not np.any(self.values)

    def spectrum(self, n_range: int) -> np.ndarray:
        """The coupling on every bin of an *n_range*-point range FFT (0 where not measured):
        complex64 (tx_slots, rx, n_range)."""
        out = np.zeros(self.values.shape[:2] + (n_range,), np.complex64)
        out[:, :, self.first_bin:self.first_bin + self.values.shape[2]] = self.values
        return out


def uncalibrated_note(cfg) -> str | None:
    """A warning for a cfg (:class:`radarodom.cfg.RadarConfig`) whose compRangeBiasAndRxChanPhase
    is the identity or missing, when it is meant for a real board; None otherwise."""
    command_line = cfg.line_of(CALIBRATION_COMMAND)
    if command_line is not None and not ChannelCalibration.from_config(cfg).is_identity:
        return None
    where = f"{cfg.path}:{command_line.line}" if command_line is not None and command_line.line else cfg.path
    what = "is the identity" if command_line is not None else "is missing"
    return (f"{where}: compRangeBiasAndRxChanPhase {what}: the board's TX and RX paths are uncalibrated, so "
            "azimuths, elevations and ranges carry its own errors (tens of degrees, centimetres); measure its "
            "line once with radar-calibrate --distance M --write-cfg NEW.cfg (a corner reflector on boresight) "
            "and use that cfg")


__all__ = ["BIAS_DECIMALS", "COEFFICIENT_DECIMALS", "ChannelCalibration", "RangeCoupling", "uncalibrated_note"]
