"""ColoRadar's single-chip radar description as a radarodom :class:`~radarodom.cfg.RadarConfig`.

The dataset does not keep the ``.cfg`` its AWR1843BOOST ran; it keeps the chirp
(``calib/single_chip/waveform_cfg.txt``) and the antenna layout (``antenna_cfg.txt``).  From
them :func:`waveform_to_config` writes the cfg text a radar would have needed for those
frames, so the DSP runs on ColoRadar's ADC frames as on our own recordings.

The ADC frame's ``tx`` axis is taken as the order the TX transmit in (the chirp order of
one loop), and ``antenna_cfg.txt``'s ``tx k`` line says which antenna transmits k-th.
That order decides the virtual array, so it is derived from the positions
(:func:`tx_order_from_antennas`), never assumed.  Without an antenna file TI's order
(TX1, TX3, TX2) is used, with a warning.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass

import numpy as np

from ...antenna import NUM_RX_ANTENNAS, NUM_TX_ANTENNAS, TX_OFFSETS_HALF_WAVELENGTHS
from ...cfg import RadarConfig
from ...errors import CaptureFormatError, ConfigError
from ...tum import parse_numbers
from .files import WaveformConfig, _read_lines

log = logging.getLogger(__name__)

#: TX numbers in TI's chirp order (chirpCfg masks 1, 4, 2), used when no antenna file says.
TI_TX_ORDER = (1, 3, 2)


@dataclass(frozen=True, eq=False)
class AntennaConfig:
    """A radar's antenna layout from ``calib/<sensor>/antenna_cfg.txt``.

    Positions are as stored (the dataset's tools read them as integers, in half wavelengths
    at the design frequency): column 0 horizontal, column 1 vertical.
    """

    rx_positions: np.ndarray  # (num_rx, 2)
    tx_positions: np.ndarray  # (num_tx, 2)
    design_frequency: float | None  # as stored (GHz in the dataset's files), None if absent
    path: str = "<antenna_cfg>"

    @property
    def num_rx(self) -> int:
        return len(self.rx_positions)

    @property
    def num_tx(self) -> int:
        return len(self.tx_positions)


def read_antenna_config(path: str | os.PathLike) -> AntennaConfig:
    """Parse an ``antenna_cfg.txt``: ``num_rx N``, ``num_tx N``, ``rx k h v``, ``tx k h v`` and
    ``F_design f`` lines, ``#`` comments.  Every antenna must be placed once."""
    path = os.fspath(path)
    counts: dict[str, int] = {}
    placed: dict[str, dict[int, tuple[float, float]]] = {"rx": {}, "tx": {}}
    design = None
    for lineno, text in _read_lines(path):
        if text.startswith("#"):
            continue
        key, _, rest = text.partition(" ")
        if key in ("num_rx", "num_tx"):
            (n,) = parse_numbers(path, lineno, rest, 1, f"{key} N")
            if n != int(n) or n <= 0:
                raise CaptureFormatError(f"{path}:{lineno}: {key} must be a positive integer, got {rest.strip()!r}")
            counts[key] = int(n)
        elif key in ("rx", "tx"):
            k, h, v = parse_numbers(path, lineno, rest, 3, f"'{key} index horizontal vertical'")
            if k != int(k) or k < 0:
                raise CaptureFormatError(f"{path}:{lineno}: bad {key} index {k!r}")
            if int(k) in placed[key]:
                raise CaptureFormatError(f"{path}:{lineno}: {key} {int(k)} placed twice")
            placed[key][int(k)] = (h, v)
        elif key == "F_design":
            (design,) = parse_numbers(path, lineno, rest, 1, "F_design f")
        else:
            log.debug("%s:%d: ignoring unknown key %r", path, lineno, key)
    arrays = {}
    for kind in ("rx", "tx"):
        n = counts.get(f"num_{kind}")
        if n is None:
            raise CaptureFormatError(f"{path}: missing num_{kind}")
        if sorted(placed[kind]) != list(range(n)):
            raise CaptureFormatError(f"{path}: num_{kind} is {n} but {kind} lines place "
                                     f"{sorted(placed[kind]) or 'none'}")
        arrays[kind] = np.array([placed[kind][k] for k in range(n)], dtype=float)
    return AntennaConfig(arrays["rx"], arrays["tx"], design, path)


def tx_order_from_antennas(antenna: AntennaConfig) -> tuple[int, ...]:
    """The AWR1843 TX number (1..3) of each of the file's TX (in file order).

    Positions are put in units of the RX spacing (lambda/2) with the horizontal axis pointing
    the way the RX indices grow, as radarodom's antenna model does (antenna.py).  TX2 is the
    one off the other two's row; of those two, TX1 is where the RX row starts and TX3 two
    wavelengths further.  Any other layout is not an AWR1843BOOST's and is refused.
    """
    where = antenna.path
    if antenna.num_rx != NUM_RX_ANTENNAS or antenna.num_tx != NUM_TX_ANTENNAS:
        raise CaptureFormatError(f"{where}: {antenna.num_tx} TX x {antenna.num_rx} RX is not the AWR1843's "
                                 f"{NUM_TX_ANTENNAS} x {NUM_RX_ANTENNAS} (the cascade radar's ADC is not supported)")
    rx_h = antenna.rx_positions[:, 0]
    step = np.diff(rx_h)
    if not (np.allclose(step, step[0]) and step[0] != 0 and np.allclose(antenna.rx_positions[:, 1],
                                                                          antenna.rx_positions[0, 1])):
        raise CaptureFormatError(f"{where}: the RX are not evenly spaced in one row ({antenna.rx_positions.tolist()})")
    # Horizontal in RX spacings from RX0, growing with the RX index; vertical in the same unit.
    h = (antenna.tx_positions[:, 0] - rx_h[0]) / step[0]
    v = antenna.tx_positions[:, 1] / abs(step[0])
    row_mates = [int(np.sum(np.isclose(v, v[k]))) for k in range(3)]
    known = {(th, tv): number for number, (th, tv) in enumerate(TX_OFFSETS_HALF_WAVELENGTHS, start=1)}
    if sorted(row_mates) == [1, 2, 2]:
        raised = row_mates.index(1)
        row = [k for k in range(3) if k != raised]
        base = min(row, key=lambda k: h[k])
        # Offsets from TX1 with the raised TX one row up, whichever way the file counts rows.
        offsets = [(round(h[k] - h[base], 6), 0 if k != raised else 1) for k in range(3)]
        order = tuple(known.get(o) for o in offsets)
        if None not in order and sorted(order) == [1, 2, 3]:
            return order  # type: ignore[return-value]
    raise CaptureFormatError(
        f"{where}: the TX positions {antenna.tx_positions.tolist()} (RX at {antenna.rx_positions.tolist()}) "
        f"are not an AWR1843BOOST's: TX1 and TX3 two wavelengths apart, TX2 one wavelength from TX1 "
        f"and half a wavelength off their row")


def _g(value: float) -> str:
    """A cfg number without float noise (6 significant digits, as TI's tools print), written out
    plain (1000000, not 1e+06, which a cfg's whole-number field does not read)."""
    return np.format_float_positional(float(f"{value:.6g}"), trim="-")


#: The waveform file's key (and its unit) each field of the cfg made from it comes from.
_FILE_KEYS = {"startFreq": ("start_frequency", "Hz"), "idleTime": ("idle_time", "s"),
              "adcStartTime": ("adc_start_time", "s"), "rampEndTime": ("ramp_end_time", "s"),
              "freqSlopeConst": ("frequency_slope", "Hz/s"), "numAdcSamples": ("num_adc_samples_per_chirp", ""),
              "digOutSampleRate": ("adc_sample_frequency", "Hz"), "numLoops": ("num_chirps_per_frame", "")}


def waveform_to_config(wf: WaveformConfig, *, tx_order: tuple[int, ...] = TI_TX_ORDER,
                       frame_period_s: float = 0.1, origin: str = "waveform_cfg.txt",
                       period_origin: str | None = None) -> RadarConfig:
    """The radar configuration of ColoRadar frames chirped as *wf*.

    *tx_order*: TX number (1..3) of each TX slot in chirp order (the ADC frame's tx axis);
    *frame_period_s*: the frames' period (the dataset does not store it: take it from the
    timestamps).  The cfg's other settings are what a raw capture needs (16-bit complex 1x
    samples, all four RX); *origin* names the source in messages and in the cfg's comments,
    *period_origin* where the period came from (a refusal of it names that file).
    """
    if wf.num_rx != NUM_RX_ANTENNAS or wf.num_tx != len(tx_order):
        raise CaptureFormatError(f"{origin}: {wf.num_tx} TX x {wf.num_rx} RX does not match the AWR1843's "
                                 f"{len(tx_order)} x {NUM_RX_ANTENNAS} (the cascade radar's ADC is not supported)")
    masks = [1 << (t - 1) for t in tx_order]
    period_ms = frame_period_s * 1e3
    text = "\n".join([
        f"% radarodom: the AWR1843 configuration of ColoRadar frames, written from {origin}",
        "sensorStop",
        "flushCfg",
        "dfeDataOutputMode 1",
        "channelCfg 15 7 0",
        "adcCfg 2 1",
        "adcbufCfg -1 0 1 1 1",
        # profileCfg: id, start GHz, idle us, ADC start us, ramp end us, tx power/phase, slope
        # MHz/us, tx start us, samples, ksps, HPF corners, RX gain (not stored: 30 dB).
        f"profileCfg 0 {_g(wf.start_frequency / 1e9)} {_g(wf.idle_time * 1e6)} {_g(wf.adc_start_time * 1e6)} "
        f"{_g(wf.ramp_end_time * 1e6)} 0 0 {_g(wf.frequency_slope / 1e12)} 0 {wf.num_adc_samples_per_chirp} "
        f"{_g(wf.adc_sample_frequency / 1e3)} 0 0 30",
        *(f"chirpCfg {k} {k} 0 0 0 0 0 {m}" for k, m in enumerate(masks)),
        f"frameCfg 0 {len(masks) - 1} {wf.num_chirps_per_frame} 0 {_g(period_ms)} 1 0",
        "lowPower 0 0",
        "lvdsStreamCfg -1 0 1 0",
        "sensorStart",
        "",
    ])
    try:
        return RadarConfig.from_text(text, f"{origin} (as a cfg)")
    except ConfigError as exc:
        # The made-up cfg's line would mean nothing to the file's reader: the file's key, its value,
        # and the cfg's command and field it became.
        cfg_field = ": ".join(part for part in (exc.command, exc.field) if part)
        if exc.field == "framePeriodicity" and period_origin is not None:
            raise CaptureFormatError(f"{period_origin}: the frames' period, {_g(period_ms)} ms (the median step of "
                                     f"its times), makes no valid AWR1843 frame: {cfg_field}: {exc.message}") from None
        key, unit = _FILE_KEYS.get(exc.field or "", (None, ""))
        said = f"{key} {getattr(wf, key):.6g}{' ' + unit if unit else ''} (the cfg's {cfg_field}): " if key else (
            f"{cfg_field}: " if cfg_field else "")
        raise CaptureFormatError(f"{origin}: {said}the waveform does not make a valid AWR1843 configuration: "
                                 f"{exc.message}") from None
