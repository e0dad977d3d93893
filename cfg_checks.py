"""The checks a cfg passes when :class:`radarodom.cfg.RadarConfig` is built: the commands the raw
data layout needs, the modes radarodom supports, the profile's ADC window and RF range, the
chirps and the frame, the virtual array's azimuth row, the fields of view; each failure a
:class:`ConfigError` naming ``file:line: command: field``."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .cfg_physics import MAX_RF_FREQUENCY_HZ, SYNTHESIZER_RANGES_GHZ
from .errors import ConfigError

if TYPE_CHECKING:
    from .cfg_text import CfgLine, WarningSummary

#: The fewest loops a frame and ADC samples a chirp radarodom's DSP takes: its Doppler FFT and
#: CFAR, and its range FFT's peak interpolation, need that many bins.
MIN_LOOPS = 4
MIN_ADC_SAMPLES = 4
#: The fewest places on the virtual array's azimuth row the DSP measures an azimuth with.
MIN_AZIMUTH_PLACES = 2

#: The largest range bias, m, taken without a warning: a board's (its antenna feeds and traces)
#: is centimetres, so metres are a typo or another quantity.
MAX_PLAUSIBLE_RANGE_BIAS_M = 1.0

#: Commands that must appear once, and describe the raw data layout.
REQUIRED_COMMANDS = ("channelCfg", "adcCfg", "adcbufCfg", "profileCfg", "chirpCfg", "frameCfg")


class ConfigChecks:
    """The validation of a parsed configuration (mixed into RadarConfig, whose indexed lines
    it reads; its physics, such as the active frame time, come from ConfigPhysics)."""

    path: str | None
    _warnings: WarningSummary
    _first: dict[str, CfgLine]
    _keyed: dict[str, dict[int, CfgLine]]
    _chirp_lines: tuple[CfgLine, ...]

    # --------------------------------------------------------------- validation
    def _validate(self) -> None:
        for name in REQUIRED_COMMANDS:
            if name not in self._first and not (name == "chirpCfg" and self._chirp_lines):
                raise ConfigError("missing: the raw data layout depends on it", path=self.path,
                                  command=name)
        self._validate_modes()
        self._validate_profile()
        self._validate_chirps_and_frame()
        self._validate_array()
        self._validate_fov()
        self._check_range_bias()

    def _validate_modes(self) -> None:
        ln = self._first.get("dfeDataOutputMode")
        if ln is not None and ln.value.mode != 1:
            raise self._fail("only frame-based chirps (1) are supported; continuous (2) and "
                             "advanced frame (3) modes are not", ln, "modeType")
        ln = self._first["adcCfg"]
        if ln.value.num_adc_bits != 2:
            raise self._fail("12- and 14-bit ADC output is not supported: use 2 (16-bit)", ln, "numADCBits")
        if ln.value.adc_output_fmt == 0:
            raise self._fail("real-only ADC output is not supported: use 1 (complex 1x)", ln, "adcOutputFmt")
        if ln.value.adc_output_fmt == 2:
            raise self._fail("complex 2x ADC output is not supported: use 1 (complex 1x)", ln, "adcOutputFmt")
        ln = self._first["adcbufCfg"]
        if ln.value.output_fmt != 0:
            raise self._fail("real ADC buffer format is not supported: use 0 (complex)", ln, "adcOutputFmt")
        if ln.value.chan_interleave != 1:
            raise self._fail("interleaved channels are not supported by the xWR18xx demo: use 1", ln,
                             "ChanInterleave")

    def _validate_profile(self) -> None:
        ln = self._first["profileCfg"]
        p = ln.value
        if p.num_adc_samples % 2:
            raise self._fail("must be even: the LVDS stream carries samples in pairs", ln, "numAdcSamples")
        if p.num_adc_samples < MIN_ADC_SAMPLES:
            raise self._fail(f"must be at least {MIN_ADC_SAMPLES}: radarodom's DSP needs that many range bins, "
                             f"got {p.num_adc_samples}", ln, "numAdcSamples")
        window_us = p.adc_start_time_us + p.num_adc_samples * 1000.0 / p.sample_rate_ksps
        if window_us > p.ramp_end_time_us + 1e-9:
            raise self._fail(
                f"ADC sampling ends at {window_us:.2f} us (adcStartTime {p.adc_start_time_us:g} + "
                f"numAdcSamples {p.num_adc_samples} / digOutSampleRate {p.sample_rate_ksps} ksps), "
                f"after the ramp ends at {p.ramp_end_time_us:g} us", ln, "rampEndTime")
        top_ghz = p.start_freq_ghz + p.freq_slope_mhz_us * p.ramp_end_time_us / 1000.0
        if top_ghz * 1e9 > MAX_RF_FREQUENCY_HZ + 1e6:
            raise self._fail(f"the ramp reaches {top_ghz:.3f} GHz, above the xWR18xx's 81 GHz",
                             ln, "freqSlopeConst")
        if not any(lo - 1e-3 <= p.start_freq_ghz and top_ghz <= hi + 1e-3 for lo, hi in SYNTHESIZER_RANGES_GHZ):
            ranges = " or ".join(f"{lo:g}-{hi:g} GHz" for lo, hi in SYNTHESIZER_RANGES_GHZ)
            raise self._fail(
                f"the ramp sweeps {p.start_freq_ghz:g}-{top_ghz:.3f} GHz, across the synthesizer's two "
                f"ranges ({ranges}: one chirp stays within one); start at 77 GHz or more, or end the "
                f"ramp by 78 GHz", ln, "startFreq")

    def _validate_chirps_and_frame(self) -> None:
        channel = self._first["channelCfg"]
        profile = self._first["profileCfg"].value
        owner: dict[int, CfgLine] = {}
        for ln in self._chirp_lines:
            c = ln.value
            if c.end_idx < c.start_idx:
                raise self._fail(f"chirpEndIndex {c.end_idx} is below chirpStartIndex {c.start_idx}",
                                 ln, "chirpEndIndex")
            if c.profile_id != profile.profile_id:
                raise self._fail(f"profile {c.profile_id} is not defined (profileCfg defines "
                                 f"{profile.profile_id})", ln, "profileId")
            if c.tx_mask == 0:
                raise self._fail("the chirp transmits on no TX", ln, "txEnable")
            if c.tx_mask & ~channel.value.tx_mask:
                raise self._fail(f"TX mask {c.tx_mask} is not a subset of channelCfg txChannelEn "
                                 f"{channel.value.tx_mask} (line {channel.line})", ln, "txEnable")
            if c.tx_mask not in (1, 2, 4):
                raise self._fail(f"TX mask {c.tx_mask} enables several TX at once; only TDM-MIMO "
                                 f"(one TX per chirp) is supported", ln, "txEnable")
            if any((c.start_freq_var_hz, c.freq_slope_var_khz_us, c.idle_time_var_us,
                    c.adc_start_time_var_us)):
                self._warnings.add("chirp variations", ln.line,
                                   "chirpCfg variations are ignored by radarodom's signal model")
            for i in range(c.start_idx, c.end_idx + 1):
                if i in owner:
                    raise self._fail(f"chirp {i} is already defined at line {owner[i].line}", ln,
                                     "chirpStartIndex")
                owner[i] = ln
        frame_ln = self._first["frameCfg"]
        f = frame_ln.value
        if f.chirp_end_idx < f.chirp_start_idx:
            raise self._fail(f"chirpEndIndex {f.chirp_end_idx} is below chirpStartIndex "
                             f"{f.chirp_start_idx}", frame_ln, "chirpEndIndex")
        if f.num_loops < MIN_LOOPS:
            raise self._fail(f"must be at least {MIN_LOOPS}: radarodom's DSP needs that many Doppler bins "
                             f"(its Doppler FFT and CFAR), got {f.num_loops}", frame_ln, "numLoops")
        for i in range(f.chirp_start_idx, f.chirp_end_idx + 1):
            if i not in owner:
                raise self._fail(f"chirp {i} is not defined by any chirpCfg", frame_ln,
                                 "chirpStartIndex" if i == f.chirp_start_idx else "chirpEndIndex")
        # Both are the radar's to honour, not radarodom's: its stream would then end, or never
        # begin, in a timeout whose message names the cable or the network.
        if f.num_frames:
            self._warnings.add("frame count", frame_ln.line,
                               f"frameCfg: numFrames {f.num_frames}: the radar stops after {f.num_frames} frames "
                               f"({f.num_frames * f.frame_period_ms / 1e3:g} s), and a live run then ends in a data "
                               "timeout; 0 streams until stopped (radar-capture --frames N ends a run)")
        if f.trigger_select == 2:
            self._warnings.add("hardware trigger", frame_ln.line,
                               "frameCfg: triggerSelect 2: each frame waits for a pulse on the radar's SYNC_IN pin, "
                               "and without one no frame comes (a live run ends in a data timeout); 1 starts the "
                               "frames at sensorStart")
        if self.active_frame_time_s > self.frame_period_s + 1e-12:
            raise self._fail(
                f"{f.frame_period_ms:g} ms is shorter than the active frame time "
                f"{self.active_frame_time_s * 1e3:.3f} ms ({f.num_loops} loops x "
                f"{self.num_tx_slots} chirps x {self.chirp_time_s * 1e6:g} us)",
                frame_ln, "framePeriodicity")

    def _validate_array(self) -> None:
        """The frame's chirps must place antennas at two places or more on the azimuth row (TX1
        and TX3 with the enabled RX; TX2 is the raised row), or there is no azimuth to measure."""
        va = self.virtual_array
        places = len(set(va.h.ravel()[va.azimuth_row].tolist()))
        if places >= MIN_AZIMUTH_PLACES:
            return
        ln = self._first["channelCfg"]
        need = f"radarodom's DSP needs antennas at {MIN_AZIMUTH_PLACES} places of it or more to measure azimuth"
        if places == 0:
            raise self._fail(f"the frame's chirps transmit on TX2 only, the raised antenna, which leaves the "
                             f"azimuth row empty; {need}: chirp TX1 or TX3 too (chirpCfg txEnable 1 or 4)",
                             ln, "txChannelEn")
        tx = next(t for t in va.tx_order if t != 2)
        raise self._fail(f"the frame's chirps put one antenna on the azimuth row (TX{tx} x 1 RX); {need}: "
                         f"enable two RX or more (rxChannelEn), or chirp TX1 and TX3", ln, "rxChannelEn")

    def _validate_fov(self) -> None:
        for key, ln in self._keyed["cfarFovCfg"].items():
            if ln.value.min_value > ln.value.max_value:
                raise self._fail("min is above max", ln, "min (meters or m/s)")
        ln = self._first.get("aoaFovCfg")
        if ln is not None:
            a = ln.value
            if a.min_azimuth_deg > a.max_azimuth_deg:
                raise self._fail("minAzimuthDeg is above maxAzimuthDeg", ln, "minAzimuthDeg")
            if a.min_elevation_deg > a.max_elevation_deg:
                raise self._fail("minElevationDeg is above maxElevationDeg", ln, "minElevationDeg")

    def _check_range_bias(self) -> None:
        ln = self._first.get("compRangeBiasAndRxChanPhase")
        if ln is None or abs(ln.value.range_bias_m) <= MAX_PLAUSIBLE_RANGE_BIAS_M:
            return
        bias = ln.value.range_bias_m
        self._warnings.add("range bias", ln.line,
                           f"compRangeBiasAndRxChanPhase: rangeBias {bias:g} m, where a board's is a few "
                           f"centimetres: every range is taken {abs(bias):g} m {'shorter' if bias > 0 else 'longer'}"
                           f" and the usable range moves with it; is it the board's? radar-calibrate measures it")
