"""Typed commands of the TI mmWave SDK 3.x CLI for the xWR18xx demo firmware.

Each command that decides the raw data, or that the DSP reads, is a frozen
dataclass.  Its fields are in the order of the CLI arguments; each field's
metadata gives the argument's name as TI's SDK user guide spells it, its unit
and the values the firmware accepts.  One generic parser
(:func:`parse_args`) turns CLI tokens into these objects, so a field is
described exactly once.

Commands that only need to reach the radar unchanged are listed in
:data:`VERBATIM_COMMANDS` with their argument counts.

Source: TI mmWave SDK 3.5 user guide, "Configuration (.cfg) File Format", and
the demo's ``mmw_cli.c``.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from typing import Any, Sequence

from .errors import ConfigError

#: The only sub-frame index the legacy (non-advanced) frame accepts.
LEGACY_SUBFRAME = -1


def arg(
    ti_name: str,
    *,
    unit: str | None = None,
    lo: float | None = None,
    hi: float | None = None,
    choices: Sequence[int] | None = None,
) -> Any:
    """Describe one CLI argument: TI's name, unit, and accepted values."""
    return field(
        metadata={"ti_name": ti_name, "unit": unit, "lo": lo, "hi": hi, "choices": choices}
    )


def subframe_arg() -> Any:
    return arg("subFrameIdx", choices=(LEGACY_SUBFRAME,))


@dataclass(frozen=True)
class DfeDataOutputMode:
    mode: int = arg("modeType", choices=(1, 2, 3))


@dataclass(frozen=True)
class ChannelCfg:
    rx_mask: int = arg("rxChannelEn", lo=1, hi=15)
    tx_mask: int = arg("txChannelEn", lo=1, hi=7)
    cascading: int = arg("cascading", choices=(0,))


@dataclass(frozen=True)
class AdcCfg:
    num_adc_bits: int = arg("numADCBits", choices=(0, 1, 2))  # 0: 12, 1: 14, 2: 16 bit
    adc_output_fmt: int = arg("adcOutputFmt", choices=(0, 1, 2))  # 0 real, 1 complex 1x, 2 complex 2x


@dataclass(frozen=True)
class AdcbufCfg:
    subframe: int = subframe_arg()
    output_fmt: int = arg("adcOutputFmt", choices=(0, 1))  # 0 complex, 1 real
    sample_swap: int = arg("SampleSwap", choices=(0, 1))  # 1: Q in LSB -> Q0 Q1 I0 I1 on the wire
    chan_interleave: int = arg("ChanInterleave", choices=(0, 1))  # 1: non-interleaved
    chirp_threshold: int = arg("ChirpThreshold", lo=0, hi=8)


@dataclass(frozen=True)
class ProfileCfg:
    profile_id: int = arg("profileId", lo=0, hi=3)
    start_freq_ghz: float = arg("startFreq", unit="GHz", lo=76.0, hi=81.0)
    idle_time_us: float = arg("idleTime", unit="us", lo=0.0, hi=5242.87)
    adc_start_time_us: float = arg("adcStartTime", unit="us", lo=0.0, hi=4095.0)
    ramp_end_time_us: float = arg("rampEndTime", unit="us", lo=0.01, hi=5242.87)
    tx_out_power: int = arg("txOutPower", lo=0, hi=255)
    tx_phase_shifter: int = arg("txPhaseShifter", lo=0, hi=2**32 - 1)
    freq_slope_mhz_us: float = arg("freqSlopeConst", unit="MHz/us", lo=0.001, hi=100.0)
    tx_start_time_us: float = arg("txStartTime", unit="us", lo=-40.0, hi=40.0)
    num_adc_samples: int = arg("numAdcSamples", lo=2, hi=1024)
    sample_rate_ksps: int = arg("digOutSampleRate", unit="ksps", lo=1000, hi=12500)
    hpf_corner1: int = arg("hpfCornerFreq1", choices=(0, 1, 2, 3))
    hpf_corner2: int = arg("hpfCornerFreq2", choices=(0, 1, 2, 3))
    rx_gain: int = arg("rxGain", lo=0, hi=255)


@dataclass(frozen=True)
class ChirpCfg:
    start_idx: int = arg("chirpStartIndex", lo=0, hi=511)
    end_idx: int = arg("chirpEndIndex", lo=0, hi=511)
    profile_id: int = arg("profileId", lo=0, hi=3)
    start_freq_var_hz: float = arg("startFreqVar", unit="Hz")
    freq_slope_var_khz_us: float = arg("freqSlopeVar", unit="kHz/us")
    idle_time_var_us: float = arg("idleTimeVar", unit="us")
    adc_start_time_var_us: float = arg("adcStartTimeVar", unit="us")
    tx_mask: int = arg("txEnable", lo=0, hi=7)


@dataclass(frozen=True)
class FrameCfg:
    chirp_start_idx: int = arg("chirpStartIndex", lo=0, hi=511)
    chirp_end_idx: int = arg("chirpEndIndex", lo=0, hi=511)
    num_loops: int = arg("numLoops", lo=1, hi=255)
    num_frames: int = arg("numFrames", lo=0, hi=65535)  # 0: until sensorStop
    frame_period_ms: float = arg("framePeriodicity", unit="ms", lo=0.001, hi=1342.17728 * 1000)
    trigger_select: int = arg("triggerSelect", choices=(1, 2))  # 1 software, 2 hardware
    trigger_delay_ms: float = arg("frameTriggerDelay", unit="ms", lo=0.0, hi=1e6)


@dataclass(frozen=True)
class LowPower:
    dont_care: int = arg("dontCare", choices=(0,))
    adc_mode: int = arg("adcMode", choices=(0, 1))  # 0 regular, 1 low power


@dataclass(frozen=True)
class LvdsStreamCfg:
    subframe: int = subframe_arg()
    enable_header: int = arg("enableHeader", choices=(0, 1))
    data_fmt: int = arg("dataFmt", choices=(0, 1, 4))  # 0 off, 1 ADC, 4 CP_ADC_CQ
    enable_sw: int = arg("enableSW", choices=(0, 1))


@dataclass(frozen=True)
class CfarCfg:
    subframe: int = subframe_arg()
    proc_direction: int = arg("procDirection", choices=(0, 1))  # 0 range, 1 Doppler
    mode: int = arg("mode", choices=(0, 1, 2))  # 0 CA, 1 CAGO, 2 CASO
    noise_win: int = arg("noiseWin", lo=1, hi=64)
    guard_len: int = arg("guardLen", lo=0, hi=64)
    div_shift: int = arg("divShift", lo=0, hi=16)
    cyclic: int = arg("cyclic mode or Wrapped around mode", choices=(0, 1))
    threshold_db: float = arg("Threshold scale", unit="dB", lo=0.0, hi=100.0)
    peak_grouping: int = arg("peak grouping", choices=(0, 1))


@dataclass(frozen=True)
class CfarFovCfg:
    subframe: int = subframe_arg()
    proc_direction: int = arg("procDirection", choices=(0, 1))  # 0: range in m, 1: Doppler in m/s
    min_value: float = arg("min (meters or m/s)")
    max_value: float = arg("max (meters or m/s)")


@dataclass(frozen=True)
class AoaFovCfg:
    subframe: int = subframe_arg()
    min_azimuth_deg: float = arg("minAzimuthDeg", unit="deg", lo=-90.0, hi=90.0)
    max_azimuth_deg: float = arg("maxAzimuthDeg", unit="deg", lo=-90.0, hi=90.0)
    min_elevation_deg: float = arg("minElevationDeg", unit="deg", lo=-90.0, hi=90.0)
    max_elevation_deg: float = arg("maxElevationDeg", unit="deg", lo=-90.0, hi=90.0)


@dataclass(frozen=True)
class MultiObjBeamForming:
    subframe: int = subframe_arg()
    enabled: int = arg("Feature Enabled", choices=(0, 1))
    threshold: float = arg("threshold", lo=0.0, hi=1.0)


@dataclass(frozen=True)
class ClutterRemoval:
    subframe: int = subframe_arg()
    enabled: int = arg("enabled", choices=(0, 1))


@dataclass(frozen=True)
class CalibDcRangeSig:
    subframe: int = subframe_arg()
    enabled: int = arg("enabled", choices=(0, 1))
    negative_bin_idx: int = arg("negativeBinIdx", lo=-256, hi=0)
    positive_bin_idx: int = arg("positiveBinIdx", lo=0, hi=256)
    num_avg: int = arg("numAvg", choices=tuple(2**k for k in range(10)))


@dataclass(frozen=True)
class ExtendedMaxVelocity:
    subframe: int = subframe_arg()
    enabled: int = arg("enabled", choices=(0, 1))


#: Virtual antennas whose phase compRangeBiasAndRxChanPhase corrects (3 TX x 4 RX).
NUM_COMP_VIRTUAL_ANTENNAS = 12


@dataclass(frozen=True)
class CompRangeBiasAndRxChanPhase:
    range_bias_m: float = arg("rangeBias", unit="m", lo=-10.0, hi=10.0)
    #: One complex correction per virtual antenna, TX-major (TX1 RX0..3, TX2 ..., TX3 ...),
    #: given on the CLI as Re Im pairs in [-1, 1].
    rx_chan_phase: tuple[complex, ...] = arg("virtual antenna Re/Im pairs", lo=-1.0, hi=1.0)


#: CLI name -> typed command class.
TYPED_COMMANDS: dict[str, type] = {
    "dfeDataOutputMode": DfeDataOutputMode,
    "channelCfg": ChannelCfg,
    "adcCfg": AdcCfg,
    "adcbufCfg": AdcbufCfg,
    "profileCfg": ProfileCfg,
    "chirpCfg": ChirpCfg,
    "frameCfg": FrameCfg,
    "lowPower": LowPower,
    "lvdsStreamCfg": LvdsStreamCfg,
    "cfarCfg": CfarCfg,
    "cfarFovCfg": CfarFovCfg,
    "aoaFovCfg": AoaFovCfg,
    "multiObjBeamForming": MultiObjBeamForming,
    "clutterRemoval": ClutterRemoval,
    "calibDcRangeSig": CalibDcRangeSig,
    "compRangeBiasAndRxChanPhase": CompRangeBiasAndRxChanPhase,
    "extendedMaxVelocity": ExtendedMaxVelocity,
}

#: Known commands kept as text: CLI name -> accepted argument counts.
VERBATIM_COMMANDS: dict[str, tuple[int, ...]] = {
    "sensorStart": (0, 1),
    "sensorStop": (0,),
    "flushCfg": (0,),
    "guiMonitor": (7,),
    "measureRangeBiasAndRxChanPhase": (3,),
    "CQRxSatMonitor": (5,),
    "CQSigImgMonitor": (3,),
    "analogMonitor": (2,),
    "calibData": (3,),
    "bpmCfg": (4,),
    "configDataPort": (2,),
    "queryDemoStatus": (0,),
    "idlePowerCycle": (1, 2, 3, 4, 5, 6),
    "version": (0,),
    "help": (0,),
}

#: Commands that belong to modes radarodom does not support, with the reason.
UNSUPPORTED_COMMANDS: dict[str, str] = {
    "advFrameCfg": "advanced frame configuration (sub-frames) is not supported; use frameCfg",
    "subFrameCfg": "sub-frames are not supported; use frameCfg",
}


#: Number syntax the radar's CLI reads (atoi/atof on ASCII digits).  Python's
#: int()/float() also take "1_6" and non-ASCII digits, which the radar would
#: read differently, so tokens are matched first.
_INT_TOKEN = re.compile(r"[+-]?[0-9]+\Z")
_FLOAT_TOKEN = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?\Z")


def _convert(token: str, kind: type, name: str) -> int | float:
    """One CLI token as int or float; raises ValueError with a reason."""
    if kind is int:
        if not _INT_TOKEN.match(token):
            raise ValueError(f"expected an integer, got {token!r}")
        try:
            return int(token, 10)
        except ValueError:  # more digits than Python converts
            raise ValueError(f"integer too large: {token[:20]}...") from None
    if not _FLOAT_TOKEN.match(token):
        if token.lower().lstrip("+-") in ("nan", "inf", "infinity"):
            raise ValueError(f"expected a finite number, got {token!r}")
        raise ValueError(f"expected a number, got {token!r}")
    value = float(token)
    if not math.isfinite(value):
        raise ValueError(f"expected a finite number, got {token!r}")
    return value


def _check_range(value: float, meta: dict) -> None:
    choices = meta.get("choices")
    if choices is not None and value not in choices:
        raise ValueError(f"{value!r} is not one of {', '.join(map(str, choices))}")
    lo, hi = meta.get("lo"), meta.get("hi")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        unit = f" {meta['unit']}" if meta.get("unit") else ""
        raise ValueError(f"{value!r} is outside {lo:g}..{hi:g}{unit}")


def parse_args(name: str, tokens: Sequence[str], *, path=None, line=None) -> Any:
    """Turn the argument tokens of typed command *name* into its dataclass.

    Raises :class:`ConfigError` naming the command and the field at fault.
    """
    cls = TYPED_COMMANDS[name]
    fields = dataclasses.fields(cls)

    def fail(message: str, fld: str | None = None) -> ConfigError:
        return ConfigError(message, path=path, line=line, command=name, field=fld)

    if cls is CompRangeBiasAndRxChanPhase:
        expected = 1 + 2 * NUM_COMP_VIRTUAL_ANTENNAS
        if len(tokens) != expected:
            raise fail(f"expected {expected} arguments (rangeBias and {NUM_COMP_VIRTUAL_ANTENNAS} "
                       f"Re/Im pairs), got {len(tokens)}")
        values = []
        for i, token in enumerate(tokens):
            meta = fields[0 if i == 0 else 1].metadata
            try:
                v = _convert(token, float, meta["ti_name"])
                _check_range(v, meta)
            except ValueError as exc:
                raise fail(str(exc), meta["ti_name"] if i == 0 else f"value {i}") from None
            values.append(v)
        pairs = tuple(complex(values[k], values[k + 1]) for k in range(1, expected, 2))
        return cls(values[0], pairs)

    if len(tokens) != len(fields):
        raise fail(f"expected {len(fields)} arguments "
                   f"({' '.join(f.metadata['ti_name'].split()[0] for f in fields)}), got {len(tokens)}")
    values = []
    for fld, token in zip(fields, tokens):
        meta = fld.metadata
        kind = int if fld.type in ("int", int) else float
        try:
            v = _convert(token, kind, meta["ti_name"])
            _check_range(v, meta)
        except ValueError as exc:
            raise fail(str(exc), meta["ti_name"]) from None
        values.append(v)
    return cls(*values)


def format_number(value: float) -> str:
    """Shortest text that parses back to exactly *value* (``77``, ``57.14``)."""
    if isinstance(value, int):
        return str(value)
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def format_args(command: Any) -> tuple[str, ...]:
    """The CLI argument tokens of a typed command (inverse of :func:`parse_args`)."""
    if isinstance(command, CompRangeBiasAndRxChanPhase):
        out = [format_number(command.range_bias_m)]
        for c in command.rx_chan_phase:
            out += [format_number(c.real), format_number(c.imag)]
        return tuple(out)
    return tuple(format_number(getattr(command, f.name)) for f in dataclasses.fields(command))


def cli_name(command: Any) -> str:
    """The CLI name of a typed command object."""
    for name, cls in TYPED_COMMANDS.items():
        if type(command) is cls:
            return name
    raise TypeError(f"not a typed cfg command: {command!r}")
