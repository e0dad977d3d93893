"""The simulated board's imperfections: the gains and phases of its TX and RX paths, its front
end's range bias, and the leakage from its transmitters into its receivers.

A real AWR1843BOOST is not the perfect array of the signal model: every TX and RX path has
its own complex gain (tens of degrees and about a dB apart), the front end delays the beat
signal (every range reads a few centimetres long), and some of the transmitted chirp leaks
straight into the receivers (a strong static return at almost zero range, whose negative
frequencies land at the far end of the range FFT).  The cfg's ``compRangeBiasAndRxChanPhase``
line corrects the first two (:mod:`radarodom.calibration`); :meth:`Board.calibration` is the line
that corrects a simulated board exactly, and ``radar-calibrate`` measures it as on a real one.

A path through TX t and RX r has the complex gain ``tx_gain[t] * rx_gain[r]``; the thermal noise
is added after it (at the ADC).  Boards are TOML files (``boards/`` beside this module holds the
built-in ``uncalibrated`` one; ``ideal`` is the perfect board and the default)::

    name = "my board"
    range_bias_m = 0.07                  # every range reads this much long
    tx_gain_db = [0.0, -0.8, 0.6]        # TX1, TX2, TX3
    tx_phase_deg = [0.0, 25.0, -35.0]
    rx_gain_db = [0.0, 0.7, -1.0, 0.4]   # RX1 .. RX4
    rx_phase_deg = [0.0, -30.0, 20.0, 40.0]
    leakage_counts = 300.0               # TX-to-RX leakage, ADC counts per I and Q (0: none)
    leakage_range_m = 0.01               # its path's half length, before the range bias
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass
from importlib import resources
from typing import Any

import numpy as np

from ...antenna import NUM_RX_ANTENNAS, NUM_TX_ANTENNAS, VirtualArray
from ...calibration import ChannelCalibration
from ...errors import ConfigError
from .scene_values import builtin_or_there, decode_utf8, read_bounded, toml_error

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: Built-in boards: "ideal" (the default) and the files in ``boards/``.
BUILTIN_BOARDS = ("ideal", "uncalibrated")


@dataclass(frozen=True)
class Board:
    """One simulated board (see the module docstring); the defaults are the perfect board."""

    name: str = "ideal"
    range_bias_m: float = 0.0
    tx_gain_db: tuple[float, ...] = (0.0,) * NUM_TX_ANTENNAS
    tx_phase_deg: tuple[float, ...] = (0.0,) * NUM_TX_ANTENNAS
    rx_gain_db: tuple[float, ...] = (0.0,) * NUM_RX_ANTENNAS
    rx_phase_deg: tuple[float, ...] = (0.0,) * NUM_RX_ANTENNAS
    leakage_counts: float = 0.0
    leakage_range_m: float = 0.01

    @property
    def tx_gain(self) -> np.ndarray:
        """Complex gain of TX1..TX3, (3,)."""
        return _complex(self.tx_gain_db, self.tx_phase_deg)

    @property
    def rx_gain(self) -> np.ndarray:
        """Complex gain of RX1..RX4, (4,)."""
        return _complex(self.rx_gain_db, self.rx_phase_deg)

    @property
    def response(self) -> np.ndarray:
        """Complex gain of every physical path, (3, 4) [TX - 1, RX]."""
        return self.tx_gain[:, None] * self.rx_gain[None, :]

    @property
    def has_channel_errors(self) -> bool:
        return bool(np.any(self.response != 1.0))

    @property
    def is_ideal(self) -> bool:
        return not self.has_channel_errors and self.range_bias_m == 0.0 and self.leakage_counts == 0.0

    def for_array(self, array: VirtualArray) -> np.ndarray:
        """The complex gain of each element of a frame's virtual array, complex64 (tx_slots, rx)."""
        return array.per_element(self.response).astype(np.complex64)

    def calibration(self) -> ChannelCalibration:
        """The compRangeBiasAndRxChanPhase line that corrects this board exactly."""
        return ChannelCalibration.from_response(self.response, self.range_bias_m)

    def fits(self, cfg) -> bool:
        """True when the cfg's (:class:`radarodom.cfg.RadarConfig`) compRangeBiasAndRxChanPhase line
        corrects this board (to :meth:`ChannelCalibration.matches`' tolerances; no line: the
        identity)."""
        return ChannelCalibration.from_config(cfg).matches(self.calibration())


def _complex(gain_db, phase_deg) -> np.ndarray:
    return 10 ** (np.asarray(gain_db, float) / 20) * np.exp(1j * np.radians(np.asarray(phase_deg, float)))


def board_from_dict(spec: dict[str, Any], where: str = "<board>") -> Board:
    """A board from its parsed TOML table (errors name the file and the key)."""
    if not isinstance(spec, dict):
        raise ConfigError("a board must be a table", path=where)
    known = {"name", "range_bias_m", "tx_gain_db", "tx_phase_deg", "rx_gain_db", "rx_phase_deg",
             "leakage_counts", "leakage_range_m"}
    unknown = sorted(set(spec) - known)
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(unknown)}: the keys are {', '.join(sorted(known))}",
                          path=where, field=unknown[0])
    values: dict[str, Any] = {"name": str(spec.get("name", os.path.splitext(os.path.basename(where))[0]))}
    for key, n in (("tx_gain_db", NUM_TX_ANTENNAS), ("tx_phase_deg", NUM_TX_ANTENNAS),
                   ("rx_gain_db", NUM_RX_ANTENNAS), ("rx_phase_deg", NUM_RX_ANTENNAS)):
        if key in spec:
            values[key] = tuple(_number(v, where, key) for v in _list(spec[key], n, where, key))
    for key, lo, hi in (("range_bias_m", -1.0, 1.0), ("leakage_counts", 0.0, 20000.0),
                        ("leakage_range_m", 0.0, 1.0)):
        if key in spec:
            value = _number(spec[key], where, key)
            if not lo <= value <= hi:
                raise ConfigError(f"must be within {lo:g} .. {hi:g}, got {value:g}", path=where, field=key)
            values[key] = value
    for key in ("tx_gain_db", "rx_gain_db"):
        gains = values.get(key, ())
        if any(abs(g) > 20.0 for g in gains):
            raise ConfigError(f"each channel's gain must be within +/- 20 dB, got {list(gains)!r}", path=where,
                              field=key)
    return Board(**values)


def _list(value: Any, n: int, where: str, key: str) -> list:
    if not isinstance(value, list) or len(value) != n:
        raise ConfigError(f"must be a list of {n} numbers, got {value!r}", path=where, field=key)
    return value


def _number(value: Any, where: str, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"must be a finite number, got {value!r}", path=where, field=key)
    return float(value)


def load_board(name_or_path: str) -> Board:
    """A built-in board by name (:data:`BUILTIN_BOARDS`) or a board file (``.toml``)."""
    if name_or_path == "ideal":
        return Board()
    if name_or_path in BUILTIN_BOARDS:
        text = resources.files(__package__).joinpath("boards", f"{name_or_path}.toml").read_text(encoding="utf-8")
        return board_from_dict(tomllib.loads(text), where=f"builtin:{name_or_path}")
    if not builtin_or_there(name_or_path, BUILTIN_BOARDS):
        raise ConfigError(f"no such board: use one of {', '.join(BUILTIN_BOARDS)} or a .toml file", path=name_or_path)
    path = os.path.expanduser(name_or_path)
    if os.path.isdir(path):
        raise ConfigError("a directory, not a board file: give a .toml file", path=name_or_path)
    try:
        spec = tomllib.loads(decode_utf8(read_bounded(path, "board file"), path))
    except ValueError as exc:  # TOMLDecodeError is a ValueError
        raise toml_error(exc, path, "a board file is a TOML table of the board's impairments") from None
    return board_from_dict(spec, where=path)


__all__ = ["BUILTIN_BOARDS", "Board", "board_from_dict", "load_board"]
