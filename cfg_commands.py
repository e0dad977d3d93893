"""Typed commands of the TI mmWave SDK 3.x CLI for the xWR18xx demo firmware.

Each command that decides the raw data, or that the DSP reads, is a frozen
dataclass.  Its fields are in the order of the CLI arguments; each field's
metadata gives the argument's name as TI's SDK user guide spells it, its unit
and the values the firmware accepts.  One generic parser
(:func:`parse_args`) turns CLI tokens into these objects, so a field is
described exactly once.

Commands that only need to reach the radar unchanged are listed in
:data:`VERBATIM_COMMANDS` with their argument counts; those of them in
:data:`CHECKED_COMMANDS` have their fields checked the same way (and are still
sent as written), the rest (:data:`UNCHECKED_COMMANDS`) are sent with a warning
that they are not checked.  How tokens are read is :mod:`radarodom.cfg_fields`.

Source: TI mmWave SDK 3.5 user guide, "Configuration (.cfg) File Format", and
the demo's ``mmw_cli.c``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Sequence

from .errors import UsageError, quoted
from .cfg_fields import (LEGACY_SUBFRAME, arg, config_error, convert, check_range, flag_arg,
                         format_fields, format_number, parse_fields, subframe_arg)

__all__ = ["LEGACY_SUBFRAME", "TYPED_COMMANDS", "CHECKED_COMMANDS", "VERBATIM_COMMANDS",
           "UNCHECKED_COMMANDS", "UNSUPPORTED_COMMANDS", "parse_args", "format_args", "format_number",
           "cli_name", "COEFFICIENT_PART_LIMIT", "coefficient_ok", "coefficient_part_ok"]


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


#: (2**23 - 1) LSB of 3.6 GHz / 2**26: the largest per-chirp start frequency step mmWaveLink
#: (rlChirpCfg_t.startFreqVar, unsigned) takes, Hz.
MAX_START_FREQ_VAR_HZ = (2**23 - 1) * 3.6e9 / 2**26
#: 63 LSB of 3.6e6 * 900 / 2**26 kHz/us (rlChirpCfg_t.freqSlopeVar, 6 bits unsigned).
MAX_FREQ_SLOPE_VAR_KHZ_US = 63 * 3.6e6 * 900 / 2**26
#: 4095 LSB of 10 ns (rlChirpCfg_t.idleTimeVar and adcStartTimeVar, 12 bits unsigned).
MAX_TIME_VAR_US = 40.95


@dataclass(frozen=True)
class ChirpCfg:
    start_idx: int = arg("chirpStartIndex", lo=0, hi=511)
    end_idx: int = arg("chirpEndIndex", lo=0, hi=511)
    profile_id: int = arg("profileId", lo=0, hi=3)
    start_freq_var_hz: float = arg("startFreqVar", unit="Hz", lo=0.0, hi=MAX_START_FREQ_VAR_HZ)
    freq_slope_var_khz_us: float = arg("freqSlopeVar", unit="kHz/us", lo=0.0, hi=MAX_FREQ_SLOPE_VAR_KHZ_US)
    idle_time_var_us: float = arg("idleTimeVar", unit="us", lo=0.0, hi=MAX_TIME_VAR_US)
    adc_start_time_var_us: float = arg("adcStartTimeVar", unit="us", lo=0.0, hi=MAX_TIME_VAR_US)
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


#: Bound of cfarFovCfg's min and max, m or m/s.
CFAR_FOV_LIMIT = 1000.0


@dataclass(frozen=True)
class CfarFovCfg:
    subframe: int = subframe_arg()
    proc_direction: int = arg("procDirection", choices=(0, 1))  # 0: range in m, 1: Doppler in m/s
    # TI documents no bounds; these keep the numbers finite and beyond any xWR18xx range or speed.
    min_value: float = arg("min (meters or m/s)", lo=-CFAR_FOV_LIMIT, hi=CFAR_FOV_LIMIT)
    max_value: float = arg("max (meters or m/s)", lo=-CFAR_FOV_LIMIT, hi=CFAR_FOV_LIMIT)


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
#: Each part of a compRangeBiasAndRxChanPhase coefficient is within -1..1 (the firmware's Q15).
COEFFICIENT_PART_LIMIT = 1.0


def coefficient_part_ok(x):
    """Whether *x* may be a part (Re or Im) of a coefficient: within -1..1; elementwise for arrays."""
    return abs(x) <= COEFFICIENT_PART_LIMIT


def coefficient_ok(re, im):
    """Whether re + im j may be a coefficient of the line: each part within -1..1, not both 0 (the antenna
    off); a bool, or one per element of arrays.  The parser takes each part's range from the limit."""
    return coefficient_part_ok(re) & coefficient_part_ok(im) & ((re != 0) | (im != 0))


@dataclass(frozen=True)
class CompRangeBiasAndRxChanPhase:
    range_bias_m: float = arg("rangeBias", unit="m", lo=-10.0, hi=10.0)
    #: One complex correction per virtual antenna, TX-major (TX1 RX0..3, TX2 ..., TX3 ...),
    #: given on the CLI as Re Im pairs in [-1, 1].
    rx_chan_phase: tuple[complex, ...] = arg("virtual antenna Re/Im pairs", lo=-COEFFICIENT_PART_LIMIT,
                                             hi=COEFFICIENT_PART_LIMIT)


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

# Commands the radar receives that radarodom does not use: their fields are checked like the
# typed commands' (syntax and the SDK user guide's ranges) but the line is sent as written.
@dataclass(frozen=True)
class SensorStart:
    do_reconfig: int = flag_arg("doReconfig")


@dataclass(frozen=True)
class GuiMonitor:
    subframe: int = subframe_arg()
    detected_objects: int = arg("detected objects", choices=(0, 1, 2))  # 2: without side info
    log_mag_range: int = flag_arg("log magnitude range")
    noise_profile: int = flag_arg("noise profile")
    range_azimuth_heat_map: int = flag_arg("rangeAzimuthHeatMap")
    range_doppler_heat_map: int = flag_arg("rangeDopplerHeatMap")
    stats_info: int = flag_arg("statsInfo")


@dataclass(frozen=True)
class MeasureRangeBiasAndRxChanPhase:
    enabled: int = flag_arg("enabled")
    target_distance_m: float = arg("targetDistance", unit="m", lo=0.0, hi=100.0)
    search_window_m: float = arg("searchWin", unit="m", lo=0.0, hi=100.0)


@dataclass(frozen=True)
class CQRxSatMonitor:
    profile: int = arg("profile", lo=0, hi=3)
    sat_mon_sel: int = arg("satMonSel", lo=0, hi=3)
    primary_slice_duration: int = arg("priSliceDuration", unit="x 0.16 us", lo=4, hi=65535)
    num_slices: int = arg("numSlices", lo=1, hi=127)
    rx_channel_mask: int = arg("rxChanMask", lo=0, hi=15)


@dataclass(frozen=True)
class CQSigImgMonitor:
    profile: int = arg("profile", lo=0, hi=3)
    num_slices: int = arg("numSlices", lo=1, hi=127)
    num_samples_per_slice: int = arg("numSamplePerSlice", lo=4, hi=255)


@dataclass(frozen=True)
class AnalogMonitor:
    rx_saturation: int = flag_arg("rxSaturation")
    sig_img_band: int = flag_arg("sigImgBand")


@dataclass(frozen=True)
class CalibData:
    save_enable: int = flag_arg("save enable")
    restore_enable: int = flag_arg("restore enable")
    #: Read by the firmware with sscanf("0x%x"): hexadecimal, or 0 (no offset).
    flash_offset: int = arg("Flash offset", syntax="hex")


@dataclass(frozen=True)
class BpmCfg:
    subframe: int = subframe_arg()
    enabled: int = flag_arg("enabled")
    chirp0_idx: int = arg("chirp0Idx", lo=0, hi=511)
    chirp1_idx: int = arg("chirp1Idx", lo=0, hi=511)


@dataclass(frozen=True)
class ConfigDataPort:
    baud_rate: int = arg("baudrate", lo=1, hi=2**32 - 1)
    ack_ping: int = flag_arg("ackPing")


#: Commands the radar receives whose fields are checked, but which are sent as written:
#: CLI name -> command class.
CHECKED_COMMANDS: dict[str, type] = {
    "sensorStart": SensorStart,
    "guiMonitor": GuiMonitor,
    "measureRangeBiasAndRxChanPhase": MeasureRangeBiasAndRxChanPhase,
    "CQRxSatMonitor": CQRxSatMonitor,
    "CQSigImgMonitor": CQSigImgMonitor,
    "analogMonitor": AnalogMonitor,
    "calibData": CalibData,
    "bpmCfg": BpmCfg,
    "configDataPort": ConfigDataPort,
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

#: Known commands whose arguments radarodom does not check (no documented layout for the
#: xWR18xx demo): sent as written, with a warning that says so.
UNCHECKED_COMMANDS = ("idlePowerCycle",)

#: Commands that belong to modes radarodom does not support, with the reason.
UNSUPPORTED_COMMANDS: dict[str, str] = {
    "advFrameCfg": "advanced frame configuration (sub-frames) is not supported; use frameCfg",
    "subFrameCfg": "sub-frames are not supported; use frameCfg",
}


def parse_args(name: str, tokens: Sequence[str], *, path=None, line=None) -> Any:
    """Turn the argument tokens of command *name* (typed or checked) into its dataclass.

    Raises :class:`ConfigError` naming the command and the field at fault.
    """
    cls = TYPED_COMMANDS.get(name) or CHECKED_COMMANDS[name]
    fail = config_error(path, line, name)
    if cls is CompRangeBiasAndRxChanPhase:
        return _parse_comp_range_bias(tokens, fail)
    if cls is SensorStart and not tokens:
        return SensorStart(0)
    value = parse_fields(cls, tokens, fail)
    if cls is CalibData and value.save_enable and value.restore_enable:
        raise fail("save and restore cannot both be enabled (the firmware refuses it)", "restore enable")
    return value


def _parse_comp_range_bias(tokens: Sequence[str], fail) -> CompRangeBiasAndRxChanPhase:
    fields = dataclasses.fields(CompRangeBiasAndRxChanPhase)
    expected = 1 + 2 * NUM_COMP_VIRTUAL_ANTENNAS
    if len(tokens) != expected:
        raise fail(f"expected {expected} arguments (rangeBias and {NUM_COMP_VIRTUAL_ANTENNAS} "
                   f"Re/Im pairs), got {len(tokens)}", None)
    values = []
    for i, token in enumerate(tokens):
        meta = fields[0 if i == 0 else 1].metadata
        try:
            v = convert(token, float)
            check_range(v, meta)
        except ValueError as exc:
            raise fail(str(exc), meta["ti_name"] if i == 0 else f"value {i}") from None
        values.append(v)
    pairs = tuple(complex(values[k], values[k + 1]) for k in range(1, expected, 2))
    return CompRangeBiasAndRxChanPhase(values[0], pairs)


def format_args(command: Any) -> tuple[str, ...]:
    """The CLI argument tokens of a typed command (inverse of :func:`parse_args`)."""
    if isinstance(command, CompRangeBiasAndRxChanPhase):
        out = [format_number(command.range_bias_m)]
        for c in command.rx_chan_phase:
            out += [format_number(c.real), format_number(c.imag)]
        return tuple(out)
    return format_fields(command)


def cli_name(command: Any) -> str:
    """The CLI name of a typed command object."""
    for name, cls in (*TYPED_COMMANDS.items(), *CHECKED_COMMANDS.items()):
        if type(command) is cls:
            return name
    raise UsageError(f"not a typed cfg command: {quoted(command)} (a command is one of radarodom.cfg_commands' "
                     f"classes, e.g. {next(iter(TYPED_COMMANDS.values())).__name__}; RadarConfig.from_text parses text)")
