"""Every validation rule of :class:`radarodom.cfg.RadarConfig`, one test each.

Each bad cfg is SMALL_CFG (conftest) with one edit; the expected line number is
computed from the edited text, and every error must read
``file:line: command: field: message``.
"""

from __future__ import annotations

import dataclasses
import logging

import pytest
from conftest import SMALL_CFG

from radarodom import cfg_commands as cc
from radarodom.cfg import REQUIRED_COMMANDS, RadarConfig
from radarodom.errors import ConfigError

NAME = "small.cfg"


# ----------------------------------------------------------------- helpers
def edit(old: str, new: str, text: str = SMALL_CFG) -> str:
    """*text* with the one line *old* replaced by *new* (which may hold several
    lines, or be empty to delete the line)."""
    lines = text.split("\n")  # not splitlines(): it also splits at \f and friends
    if lines[-1] == "":
        lines.pop()
    hits = [i for i, ln in enumerate(lines) if ln == old]
    assert len(hits) == 1, f"{old!r} occurs {len(hits)} times"
    i = hits[0]
    lines[i:i + 1] = new.split("\n") if new else []
    return "\n".join(lines) + "\n"


def insert_before(anchor: str, new: str, text: str = SMALL_CFG) -> str:
    return edit(anchor, new + "\n" + anchor, text)


def set_arg(prefix: str, index: int, value: str, text: str = SMALL_CFG) -> str:
    """Replace argument *index* (0-based, after the command) of the line *prefix*."""
    tokens = prefix.split()
    tokens[index + 1] = value
    return edit(prefix, " ".join(tokens), text)


def line_of(text: str, line: str, occurrence: int = 1) -> int:
    """1-based number of the *occurrence*-th line equal to *line*."""
    hits = [i for i, ln in enumerate(text.splitlines(), 1) if ln.strip() == line]
    return hits[occurrence - 1]


def expect_error(text: str, line: int | None, command: str, field: str | None, *words: str) -> ConfigError:
    """Parse *text* and check the ConfigError names where and what."""
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_text(text, NAME)
    err = info.value
    msg = str(err)
    where = NAME if line is None else f"{NAME}:{line}"
    prefix = f"{where}: {command}: " + (f"{field}: " if field else "")
    assert msg.startswith(prefix), f"{msg!r} does not start with {prefix!r}"
    assert (err.path, err.line, err.command, err.field) == (NAME, line, command, field)
    for w in words:
        assert w in err.message, f"{w!r} not in {err.message!r}"
    return err


PROFILE = "profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30"
CHIRP0 = "chirpCfg 0 0 0 0 0 0 0 1"
CHIRP1 = "chirpCfg 1 1 0 0 0 0 0 4"
CHIRP2 = "chirpCfg 2 2 0 0 0 0 0 2"
FRAME = "frameCfg 0 2 4 0 50 1 0"
CHANNEL = "channelCfg 15 7 0"
ADC = "adcCfg 2 1"
ADCBUF = "adcbufCfg -1 0 1 1 1"
LVDS = "lvdsStreamCfg -1 0 1 0"
SENSOR_START = "sensorStart"

# profileCfg argument indices
START_FREQ, IDLE, ADC_START, RAMP_END, SLOPE, NUM_SAMPLES, SAMPLE_RATE, RX_GAIN = 1, 2, 3, 4, 7, 9, 10, 13


def test_small_cfg_is_valid():
    """The base of every edit below parses (so each error comes from its edit)."""
    cfg = RadarConfig.from_text(SMALL_CFG, NAME)
    assert cfg.frame_bytes == 3072
    assert line_of(SMALL_CFG, PROFILE) == 8


# --------------------------------------------------- token-level rules
@pytest.mark.parametrize("bad, missing", [
    ("channelCfg 15 7", "cascading"),
    ("channelCfg 15", "txChannelEn"),
])
def test_wrong_argument_count_too_few(bad, missing):
    text = edit(CHANNEL, bad)
    err = expect_error(text, 5, "channelCfg", None, "expected 3 arguments", f"got {len(bad.split()) - 1}")
    # The message lists the argument names, so the missing one is named.
    assert missing in str(err)


def test_wrong_argument_count_too_many():
    text = edit(FRAME, FRAME + " 7")
    expect_error(text, line_of(text, FRAME + " 7"), "frameCfg", None, "expected 7 arguments", "got 8",
                 "framePeriodicity")


def test_wrong_argument_count_verbatim_command():
    text = insert_before(SENSOR_START, "guiMonitor -1 0 0")
    expect_error(text, line_of(text, "guiMonitor -1 0 0"), "guiMonitor", None, "expected 7 arguments", "got 3")


def test_wrong_argument_count_comp_range_bias():
    bad = "compRangeBiasAndRxChanPhase 0.0 1 0 1 0"
    text = insert_before(SENSOR_START, bad)
    expect_error(text, line_of(text, bad), "compRangeBiasAndRxChanPhase", None, "expected 25 arguments", "got 5")


@pytest.mark.parametrize("token", ["abc", "77GHz", "0x4D", "--1", "1..2", "%"])
def test_non_number(token):
    text = set_arg(PROFILE, START_FREQ, token)
    expect_error(text, 8, "profileCfg", "startFreq", "expected a number", repr(token))


@pytest.mark.parametrize("token", ["1.5", "16.0", "1e1", "abc"])
def test_integer_field_rejects_non_integer(token):
    text = set_arg(PROFILE, NUM_SAMPLES, token)
    expect_error(text, 8, "profileCfg", "numAdcSamples", "expected an integer", repr(token))


@pytest.mark.parametrize("token", ["1_6", "\u0661\u0666", "\uff11\uff16"])
def test_number_syntax_the_firmware_cannot_read(token):
    text = set_arg(PROFILE, NUM_SAMPLES, token)
    expect_error(text, 8, "profileCfg", "numAdcSamples", "expected an integer")


@pytest.mark.parametrize("token", ["nan", "NaN", "inf", "-inf", "Infinity", "1e999", "-1e999"])
def test_non_finite_number(token):
    text = set_arg(PROFILE, START_FREQ, token)
    expect_error(text, 8, "profileCfg", "startFreq", "finite", repr(token))


@pytest.mark.parametrize("token", ["nan", "inf"])
def test_non_finite_number_in_integer_field(token):
    text = set_arg(PROFILE, NUM_SAMPLES, token)
    expect_error(text, 8, "profileCfg", "numAdcSamples", "expected an integer")


@pytest.mark.parametrize("prefix, index, value, field, words", [
    (PROFILE, START_FREQ, "82", "startFreq", ("82.0 is outside 76..81 GHz",)),
    (PROFILE, START_FREQ, "75.99", "startFreq", ("outside 76..81",)),
    (PROFILE, NUM_SAMPLES, "2048", "numAdcSamples", ("2048 is outside 2..1024",)),
    (PROFILE, RX_GAIN, "256", "rxGain", ("outside 0..255",)),
    (PROFILE, SLOPE, "0", "freqSlopeConst", ("outside",)),
    (CHANNEL, 0, "0", "rxChannelEn", ("outside 1..15",)),
    (CHANNEL, 1, "8", "txChannelEn", ("outside 1..7",)),
    (FRAME, 2, "0", "numLoops", ("outside 1..255",)),
    (FRAME, 2, str(10**30), "numLoops", ("outside 1..255",)),
    (FRAME, 5, "3", "triggerSelect", ("3 is not one of 1, 2",)),
    (CHANNEL, 2, "1", "cascading", ("1 is not one of 0",)),
])
def test_out_of_range(prefix, index, value, field, words):
    text = set_arg(prefix, index, value)
    command = prefix.split()[0]
    expect_error(text, line_of(SMALL_CFG, prefix), command, field, *words)


@pytest.mark.parametrize("prefix, index, value, field, words", [
    (FRAME, 2, "3", "numLoops", ("must be at least 4", "Doppler bins", "got 3")),
    (FRAME, 2, "1", "numLoops", ("must be at least 4",)),
    (PROFILE, NUM_SAMPLES, "2", "numAdcSamples", ("must be at least 4", "range bins")),
])
def test_fewer_bins_than_the_dsp_takes(prefix, index, value, field, words):
    # radar-cfg called such cfgs valid; the DSP then failed at the first frame with a message of
    # its window's correlations (NaN) naming neither the file nor the field.
    text = set_arg(prefix, index, value)
    expect_error(text, line_of(SMALL_CFG, prefix), prefix.split()[0], field, *words)


def test_out_of_range_comp_range_bias_value():
    bad = "compRangeBiasAndRxChanPhase 0.0 1 0 1 0 1.5 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0 1 0"
    text = insert_before(SENSOR_START, bad)
    expect_error(text, line_of(text, bad), "compRangeBiasAndRxChanPhase", "value 5", "outside -1..1")


# ------------------------------------------------------------ chirps
def test_chirp_tx_mask_not_subset_of_channel_tx():
    text = edit(CHANNEL, "channelCfg 15 5 0")  # TX1 + TX3 only; chirp 2 uses TX2
    expect_error(text, line_of(text, CHIRP2), "chirpCfg", "txEnable", "not a subset", "line 5")


def test_chirp_tx_mask_several_tx():
    bad = "chirpCfg 2 2 0 0 0 0 0 3"
    text = edit(CHIRP2, bad)
    expect_error(text, line_of(text, bad), "chirpCfg", "txEnable", "several TX")


def test_chirp_tx_mask_zero():
    bad = "chirpCfg 2 2 0 0 0 0 0 0"
    text = edit(CHIRP2, bad)
    expect_error(text, line_of(text, bad), "chirpCfg", "txEnable", "no TX")


def _frame_of_chirps(text: str, *tx_masks: int) -> str:
    """*text* with its frame's chirps one on each TX mask given, in that order."""
    chirps = "\n".join(f"chirpCfg {i} {i} 0 0 0 0 0 {m}" for i, m in enumerate(tx_masks))
    text = edit(CHIRP0, chirps, edit(CHIRP2, "", edit(CHIRP1, "", text)))
    return edit(FRAME, f"frameCfg 0 {len(tx_masks) - 1} 4 0 50 1 0", text)


@pytest.mark.parametrize("rx, tx_masks, field, words", [
    (15, (2,), "txChannelEn", ("TX2 only", "azimuth row empty", "chirp TX1 or TX3 too")),
    (1, (1,), "rxChannelEn", ("one antenna on the azimuth row (TX1 x 1 RX)", "enable two RX or more")),
    (8, (4, 2), "rxChannelEn", ("one antenna on the azimuth row (TX3 x 1 RX)", "or chirp TX1 and TX3")),
])
def test_a_frame_with_no_azimuth_to_measure_is_refused_at_channelCfg(rx, tx_masks, field, words):
    """TX2 alone (the raised antenna) or one antenna on the azimuth row leave the DSP no azimuth:
    refused where the cfg is read (the DSP failed inside on them before)."""
    text = _frame_of_chirps(edit(CHANNEL, f"channelCfg {rx} 7 0"), *tx_masks)
    expect_error(text, line_of(text, f"channelCfg {rx} 7 0"), "channelCfg", field, *words)


@pytest.mark.parametrize("rx, tx_masks", [(3, (1,)), (1, (1, 4)), (9, (4, 2)), (15, (2, 1))])
def test_two_places_on_the_azimuth_row_are_enough(rx, tx_masks):
    """Two RX with one TX, or TX1 and TX3 with one RX: the DSP is made for them."""
    from radarodom.dsp.processor import FrameProcessor

    cfg = RadarConfig.from_text(_frame_of_chirps(edit(CHANNEL, f"channelCfg {rx} 7 0"), *tx_masks), NAME)
    assert len(FrameProcessor(cfg).point_maker.az_h) >= 2


def test_chirp_end_below_start():
    bad = "chirpCfg 2 1 0 0 0 0 0 2"
    text = edit(CHIRP2, bad)
    expect_error(text, line_of(text, bad), "chirpCfg", "chirpEndIndex", "below")


def test_frame_chirp_end_not_covered():
    bad = "frameCfg 0 3 4 0 50 1 0"
    text = edit(FRAME, bad)
    expect_error(text, line_of(text, bad), "frameCfg", "chirpEndIndex", "chirp 3 is not defined")


def test_frame_chirp_start_not_covered():
    text = edit(CHIRP0, "chirpCfg 5 5 0 0 0 0 0 1")
    expect_error(text, line_of(text, FRAME), "frameCfg", "chirpStartIndex", "chirp 0 is not defined")


def test_frame_end_below_start():
    bad = "frameCfg 2 0 4 0 50 1 0"
    text = edit(FRAME, bad)
    expect_error(text, line_of(text, bad), "frameCfg", "chirpEndIndex", "below")


def test_overlapping_chirp_cfg():
    bad = "chirpCfg 0 1 0 0 0 0 0 4"
    text = edit(CHIRP1, bad)
    expect_error(text, line_of(text, bad), "chirpCfg", "chirpStartIndex",
                 "chirp 0 is already defined at line 9")


def test_chirp_references_undefined_profile():
    bad = "chirpCfg 2 2 1 0 0 0 0 2"
    text = edit(CHIRP2, bad)
    expect_error(text, line_of(text, bad), "chirpCfg", "profileId", "profile 1 is not defined")


def test_chirp_variations_warn(caplog):
    text = edit(CHIRP1, "chirpCfg 1 1 0 0 0 1 0 4")
    with caplog.at_level(logging.WARNING, logger="radarodom.cfg"):
        RadarConfig.from_text(text, NAME)
    assert f"{NAME}:10:" in caplog.text and "variations" in caplog.text


def test_a_frame_count_and_a_hardware_trigger_warn_what_a_live_run_meets(caplog):
    """Hunt 5: numFrames > 0 and triggerSelect 2 passed every check, and a live radar's stream
    then stops after N frames, or never starts, in a timeout that names the cable or the network."""
    counted = "frameCfg 0 2 4 5 50 2 0"  # FRAME with numFrames 5 and triggerSelect 2
    text = edit(FRAME, counted)
    with caplog.at_level(logging.WARNING, logger="radarodom.cfg"):
        RadarConfig.from_text(text, NAME)
    said = [r.getMessage() for r in caplog.records]
    line = line_of(text, counted)
    assert any(m.startswith(f"{NAME}:{line}: frameCfg: numFrames 5: the radar stops after 5 frames")
               for m in said), said
    assert any(m.startswith(f"{NAME}:{line}: frameCfg: triggerSelect 2: each frame waits for a pulse on the "
                            "radar's SYNC_IN pin") for m in said), said
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="radarodom.cfg"):
        RadarConfig.from_text(SMALL_CFG, NAME)
    assert "frameCfg" not in caplog.text


# ----------------------------------------------------------- profile
def test_adc_window_longer_than_ramp():
    # 6 us + 16 samples / 8 Msps = 8 us of sampling; the ramp ends at 7.99 us.
    text = set_arg(PROFILE, RAMP_END, "7.99")
    expect_error(text, 8, "profileCfg", "rampEndTime", "8.00 us", "7.99 us")


def test_adc_window_equal_to_ramp_is_accepted():
    cfg = RadarConfig.from_text(set_arg(PROFILE, RAMP_END, "8"), NAME)
    assert cfg.profile.ramp_end_time_us == 8


def test_adc_window_longer_than_ramp_by_samples():
    # 6 us + 400 samples / 8 Msps = 56 us > 40 us
    text = set_arg(PROFILE, NUM_SAMPLES, "400")
    expect_error(text, 8, "profileCfg", "rampEndTime", "56.00 us")


def test_frame_period_shorter_than_active_frame():
    # 4 loops x 3 chirps x (100 + 40) us = 1.68 ms of chirping
    bad = "frameCfg 0 2 4 0 1.679 1 0"
    text = edit(FRAME, bad)
    expect_error(text, line_of(text, bad), "frameCfg", "framePeriodicity", "1.680 ms")


def test_frame_period_equal_to_active_frame_is_accepted():
    cfg = RadarConfig.from_text(edit(FRAME, "frameCfg 0 2 4 0 1.68 1 0"), NAME)
    assert cfg.duty_cycle == pytest.approx(1.0)


def test_ramp_above_81_ghz():
    # 80 GHz + 96 MHz/us * 40 us = 83.84 GHz
    text = set_arg(PROFILE, START_FREQ, "80")
    expect_error(text, 8, "profileCfg", "freqSlopeConst", "83.840 GHz", "81 GHz")


def test_ramp_across_the_two_synthesizer_ranges():
    # 76 GHz + 96 MHz/us * 40 us = 79.84 GHz: below 77 GHz only VCO1 (76-78 GHz) runs, and it stops at 78
    text = set_arg(PROFILE, START_FREQ, "76")
    err = expect_error(text, 8, "profileCfg", "startFreq", "76-79.840 GHz", "76-78 GHz or 77-81 GHz")
    assert "start at 77 GHz" in str(err)


@pytest.mark.parametrize("start, slope", [("76", "48"), ("76.08", "48"), ("77", "96"), ("76.5", "10")])
def test_ramp_within_one_synthesizer_range_is_accepted(start, slope):
    # 76 + 48 * 40 / 1000 = 77.92 and 76.08 + 1.92 = 78.0 GHz (VCO1); 77 + 3.84 = 80.84 GHz (VCO2)
    tokens = PROFILE.split()
    tokens[START_FREQ + 1], tokens[SLOPE + 1] = start, slope
    cfg = RadarConfig.from_text(edit(PROFILE, " ".join(tokens)), NAME)
    assert cfg.start_frequency_hz == pytest.approx(float(start) * 1e9)


def test_ramp_ending_at_81_ghz_is_accepted():
    # 77.16 + 96 * 40 / 1000 = 81.0 GHz exactly
    cfg = RadarConfig.from_text(set_arg(PROFILE, START_FREQ, "77.16"), NAME)
    assert cfg.start_frequency_hz + cfg.ramp_bandwidth_hz == pytest.approx(81e9)


def test_odd_num_adc_samples():
    text = set_arg(PROFILE, NUM_SAMPLES, "15")
    expect_error(text, 8, "profileCfg", "numAdcSamples", "even")


# ------------------------------------------------------------- modes
def test_real_only_adc():
    text = edit(ADC, "adcCfg 2 0")
    expect_error(text, 6, "adcCfg", "adcOutputFmt", "real-only")


@pytest.mark.parametrize("bits", ["0", "1"])
def test_12_or_14_bit_adc(bits):
    text = edit(ADC, f"adcCfg {bits} 1")
    expect_error(text, 6, "adcCfg", "numADCBits", "16-bit")


def test_complex_2x_adc():
    text = edit(ADC, "adcCfg 2 2")
    expect_error(text, 6, "adcCfg", "adcOutputFmt", "complex 2x")


def test_adcbuf_real():
    text = edit(ADCBUF, "adcbufCfg -1 1 1 1 1")
    expect_error(text, 7, "adcbufCfg", "adcOutputFmt", "real ADC buffer")


def test_adcbuf_interleaved():
    text = edit(ADCBUF, "adcbufCfg -1 0 1 0 1")
    expect_error(text, 7, "adcbufCfg", "ChanInterleave", "interleaved")


@pytest.mark.parametrize("line", ["advFrameCfg 1 0 0 1 0", "subFrameCfg 0 0 0 1 1 100 0 1 1 1"])
def test_advanced_frame_commands_rejected(line):
    text = insert_before(FRAME, line)
    name = line.split()[0]
    err = expect_error(text, line_of(text, line), name, None, "not supported", "frameCfg")
    assert err.message == cc.UNSUPPORTED_COMMANDS[name]


@pytest.mark.parametrize("mode", ["2", "3"])
def test_dfe_output_mode_not_frame_based(mode):
    text = edit("dfeDataOutputMode 1", f"dfeDataOutputMode {mode}")
    expect_error(text, 4, "dfeDataOutputMode", "modeType", "only frame-based")


@pytest.mark.parametrize("prefix, value", [(LVDS, "0"), (ADCBUF, "1"), (LVDS, "-2")])
def test_subframe_index_other_than_minus_one(prefix, value):
    text = set_arg(prefix, 0, value)
    expect_error(text, line_of(SMALL_CFG, prefix), prefix.split()[0], "subFrameIdx", "is not one of -1")


# ------------------------------------------------ duplicates / missing
def test_duplicated_channel_cfg():
    text = edit(CHANNEL, CHANNEL + "\nchannelCfg 15 5 0")
    err = expect_error(text, 6, "channelCfg", None, "given twice", "first at line 5")
    assert err.line == line_of(text, "channelCfg 15 5 0")


def test_duplicated_profile_cfg():
    text = insert_before(SENSOR_START, PROFILE)
    expect_error(text, line_of(text, PROFILE, 2), "profileCfg", None, "given twice", "first at line 8")


def test_a_second_profile_is_refused_as_one_more_than_radarodom_takes():
    """Another profileId is no repeat: the message says radarodom takes one profile."""
    second = "profileCfg 1" + PROFILE[len("profileCfg 0"):]
    text = insert_before(SENSOR_START, second)
    expect_error(text, line_of(text, second), "profileCfg", "profileId", "a second profile (profileId 1; profileId 0 "
                 "at line 8)", "radarodom takes one profile")


CFAR_RANGE = "cfarCfg -1 0 2 8 4 3 0 15 1"
CFAR_DOPPLER = "cfarCfg -1 1 0 8 4 4 1 15 1"


def test_duplicated_cfar_cfg_same_direction():
    second = "cfarCfg -1 0 0 4 2 3 0 12 0"
    text = insert_before(SENSOR_START, f"{CFAR_RANGE}\n{CFAR_DOPPLER}\n{second}")
    first_line = line_of(text, CFAR_RANGE)
    expect_error(text, line_of(text, second), "cfarCfg", None, "procDirection 0",
                 f"first at line {first_line}")


def test_two_cfar_cfg_different_directions_are_fine():
    text = insert_before(SENSOR_START, f"{CFAR_RANGE}\n{CFAR_DOPPLER}")
    cfg = RadarConfig.from_text(text, NAME)
    assert set(cfg.cfar) == {0, 1}
    assert cfg.cfar[0].mode == 2 and cfg.cfar[1].mode == 0


def test_duplicated_cfar_fov_same_direction():
    text = insert_before(SENSOR_START, "cfarFovCfg -1 1 -2 2\ncfarFovCfg -1 1 -1 1")
    expect_error(text, line_of(text, "cfarFovCfg -1 1 -1 1"), "cfarFovCfg", None, "procDirection 1")


@pytest.mark.parametrize("name", REQUIRED_COMMANDS)
def test_missing_required_command(name):
    lines = [ln for ln in SMALL_CFG.splitlines() if ln.split()[:1] != [name]]
    assert len(lines) < len(SMALL_CFG.splitlines())
    text = "\n".join(lines) + "\n"
    expect_error(text, None, name, None, "missing")


def test_required_commands_cover_the_raw_layout():
    assert set(REQUIRED_COMMANDS) == {"channelCfg", "adcCfg", "adcbufCfg", "profileCfg", "chirpCfg", "frameCfg"}


# --------------------------------------------------------------- bpm
def test_bpm_enabled_rejected():
    bad = "bpmCfg -1 1 0 1"
    text = insert_before(SENSOR_START, bad)
    expect_error(text, line_of(text, bad), "bpmCfg", "enabled", "BPM-MIMO", "bpmCfg -1 0 0 0")


def test_bpm_disabled_accepted():
    cfg = RadarConfig.from_text(insert_before(SENSOR_START, "bpmCfg -1 0 0 0"), NAME)
    assert "bpmCfg -1 0 0 0" in [str(ln) for ln in cfg.commands_to_send()]


# ------------------------------------------------------ unknown, syntax
def test_unknown_command_is_kept_and_warned(caplog):
    unknown = "fancyNewCmd 1 2.5 abc"
    text = insert_before(SENSOR_START, unknown)
    lineno = line_of(text, unknown)
    with caplog.at_level(logging.WARNING, logger="radarodom.cfg"):
        cfg = RadarConfig.from_text(text, NAME)
    assert unknown + "\n" in cfg.to_text()
    sent = [str(ln) for ln in cfg.commands_to_send()]
    assert sent[-1] == unknown
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1
    assert f"{NAME}:{lineno}:" in warnings[0].getMessage()
    assert "fancyNewCmd" in warnings[0].getMessage()
    assert RadarConfig.from_text(cfg.to_text()) == cfg


def test_crlf_blank_lines_and_comments():
    text = SMALL_CFG.replace("\n", "\r\n")
    text = text.replace("adcCfg 2 1\r\n", "adcCfg 2 1\r\n\r\n   \r\n  % indented comment\r\n\t\r\n")
    text = text.replace(PROFILE, "  " + PROFILE.replace(" ", " \t ") + "   ")
    cfg = RadarConfig.from_text(text, NAME)
    ref = RadarConfig.from_text(SMALL_CFG, NAME)
    assert [str(ln) for ln in cfg.commands()] == [str(ln) for ln in ref.commands()]
    assert cfg.profile == ref.profile and cfg.frame_bytes == ref.frame_bytes
    kinds = [ln.kind for ln in cfg.lines]
    assert kinds.count("blank") == 3 and kinds.count("comment") == 2
    assert all("\r" not in str(ln) for ln in cfg.lines)
    assert RadarConfig.from_text(cfg.to_text()) == cfg
    # Line numbers count CRLF lines: the profile moved from line 8 to line 12.
    bad = text.replace(ADC + "\r\n", "adcCfg 2 0\r\n")
    expect_error(bad, 6, "adcCfg", "adcOutputFmt")
    bad = text.replace(" \t 16 \t ", " \t 15 \t ")
    expect_error(bad, 12, "profileCfg", "numAdcSamples")


def test_line_numbers_count_newlines_only():
    text = edit("% small test profile", "% small\x0ctest profile")
    text = edit(ADC, "adcCfg 2 0", text)
    expect_error(text, 6, "adcCfg", "adcOutputFmt")


# --------------------------------------------------------------- fov
def test_cfar_fov_min_above_max():
    bad = "cfarFovCfg -1 0 10 0"
    text = insert_before(SENSOR_START, "cfarFovCfg -1 1 -2 2\n" + bad)
    expect_error(text, line_of(text, bad), "cfarFovCfg", "min (meters or m/s)", "min is above max")


def test_cfar_fov_min_equal_max_is_fine():
    cfg = RadarConfig.from_text(insert_before(SENSOR_START, "cfarFovCfg -1 0 3 3"), NAME)
    assert cfg.cfar_fov[0].min_value == cfg.cfar_fov[0].max_value == 3


@pytest.mark.parametrize("args, field", [
    ("-1 30 -30 -90 90", "minAzimuthDeg"),
    ("-1 -90 90 10 -10", "minElevationDeg"),
])
def test_aoa_fov_min_above_max(args, field):
    bad = f"aoaFovCfg {args}"
    text = insert_before(SENSOR_START, bad)
    expect_error(text, line_of(text, bad), "aoaFovCfg", field, f"{field} is above")


# -------------------------------------------------------------- files
def test_a_latin1_comment_is_read_and_a_latin1_command_is_refused_with_the_fix(tmp_path):
    """A comment in Latin-1 (never sent to the radar) made the whole cfg 'not a text file'."""
    path = tmp_path / "latin1.cfg"
    lines = SMALL_CFG.encode().splitlines(keepends=True)
    lines.insert(7, b"% caf\xe9 profile\n")  # line 8 is Latin-1
    path.write_bytes(b"".join(lines))
    cfg = RadarConfig.from_file(path)
    assert "% caf\u00e9 profile" in [line.text for line in cfg.lines]
    assert cfg.profile == RadarConfig.from_text(SMALL_CFG).profile
    lines[7] = b"sensorStop \xe9\n"
    path.write_bytes(b"".join(lines))
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file(path)
    assert info.value.line == 8
    assert str(info.value) == (f"{path}:8: column 12: byte 0xE9 is not UTF-8 text: save the file as UTF-8 or "
                               "ASCII (commands are plain ASCII)")


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le", "utf-16-be"])
def test_a_utf16_file_is_refused_with_the_fix(tmp_path, encoding):
    """It was 'not a text file (invalid UTF-8)' (with its byte order mark) or a NUL character at
    line 1 column 2 (without)."""
    path = tmp_path / "utf16.cfg"
    path.write_bytes(SMALL_CFG.encode(encoding))
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file(path)
    assert str(info.value) == f"{path}: UTF-16 text (as some Windows editors save it): save it as UTF-8 or ASCII"


@pytest.mark.parametrize("encoding, text, called", [
    ("utf-32", SMALL_CFG, "UTF-32"),  # its byte order mark begins as UTF-16's: it was called UTF-16
    ("utf-32-le", SMALL_CFG, "UTF-32"),
    ("utf-16-le", "% \u96f7\u9054 \u8a2d\u5b9a\n" + SMALL_CFG, "UTF-16"),  # a CJK comment first: it was missed
])
def test_wide_encodings_are_named_right(tmp_path, encoding, text, called):
    path = tmp_path / "wide.cfg"
    path.write_bytes(text.encode(encoding))
    with pytest.raises(ConfigError, match=f"{path}: {called} text .*: save it as UTF-8 or ASCII"):
        RadarConfig.from_file(path)


def test_a_bad_byte_is_placed_by_character_and_lines_end_at_cr_too(tmp_path):
    path = tmp_path / "cr.cfg"
    lines = SMALL_CFG.encode().splitlines()
    lines.insert(1, b"% caf\xe9")  # Latin-1 comment, in a file whose lines end with CR alone
    path.write_bytes(b"\r".join(lines) + b"\r")
    cfg = RadarConfig.from_file(path)  # the whole file was read as one Latin-1 comment line
    assert cfg.profile == RadarConfig.from_text(SMALL_CFG).profile
    lines[2] = b"% \xc3\xa9t\xc3\xa9\rsensorStop \xc3\xa9\xff"  # UTF-8 characters before the bad byte
    path.write_bytes(b"\r\n".join(lines))
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file(path)
    assert info.value.line == 4 and "column 13: byte 0xFF" in str(info.value)  # it said column 14, in bytes


def test_missing_file(tmp_path):
    path = tmp_path / "nope.cfg"
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file(path)
    assert str(info.value).startswith(f"{path}: ")
    assert info.value.line is None
    assert "cannot read" in str(info.value)


def test_a_dash_for_standard_input_is_told_the_file_that_is(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file("-")
    assert str(info.value) == "-: cannot read the file: No such file or directory; for standard input give /dev/stdin"


def test_directory_instead_of_file(tmp_path):
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file(tmp_path)
    assert str(tmp_path) in str(info.value)


def test_from_file_names_the_file(tmp_path):
    path = tmp_path / "bad.cfg"
    path.write_text(edit(ADC, "adcCfg 2 0"))
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file(path)
    assert str(info.value).startswith(f"{path}:6: adcCfg: adcOutputFmt: ")


def test_from_file_with_utf8_bom(tmp_path):
    path = tmp_path / "bom.cfg"
    path.write_bytes(b"\xef\xbb\xbf" + SMALL_CFG.encode())
    cfg = RadarConfig.from_file(path)
    assert cfg == RadarConfig.from_text(SMALL_CFG)
    assert all(not str(ln).startswith("\ufeff") for ln in cfg.commands_to_send())


# ----------------------------------------------------------- replace
def test_replace_profile():
    cfg = RadarConfig.from_text(SMALL_CFG, NAME)
    new_profile = dataclasses.replace(cfg.profile, num_adc_samples=32, rx_gain=36, idle_time_us=50.5)
    new = cfg.replace(new_profile)
    assert new.profile == new_profile
    text = new.to_text()
    assert "profileCfg 0 77 50.5 6 40 0 0 96 1 32 8000 0 0 36\n" in text
    assert PROFILE not in text
    assert RadarConfig.from_text(text) == new
    assert new.frame_bytes == 2 * cfg.frame_bytes
    # the original is untouched, and every other line is kept in place
    assert cfg.profile.num_adc_samples == 16 and cfg.to_text() == SMALL_CFG
    assert [str(a) for a in new.lines if a.text != "profileCfg"] == \
           [str(a) for a in cfg.lines if a.text != "profileCfg"]
    assert new.line_of("profileCfg").line == 8


def test_replace_inserts_missing_command_before_sensor_start():
    cfg = RadarConfig.from_text(SMALL_CFG, NAME)
    fov = cc.AoaFovCfg(-1, -60.0, 60.0, -20.0, 20.0)
    new = cfg.replace(fov)
    cmds = [str(ln) for ln in new.commands()]
    assert cmds[-2:] == ["aoaFovCfg -1 -60 60 -20 20", "sensorStart"]
    assert new.aoa_fov == fov
    assert RadarConfig.from_text(new.to_text()) == new


def test_replace_keyed_command_by_direction():
    cfg = RadarConfig.from_text(insert_before(SENSOR_START, f"{CFAR_RANGE}\n{CFAR_DOPPLER}"), NAME)
    new = cfg.replace(dataclasses.replace(cfg.cfar[1], threshold_db=12.5))
    assert new.cfar[1].threshold_db == 12.5 and new.cfar[0] == cfg.cfar[0]
    assert "cfarCfg -1 1 0 8 4 4 1 12.5 1\n" in new.to_text()
    assert RadarConfig.from_text(new.to_text()) == new


def test_replace_making_config_invalid_raises():
    cfg = RadarConfig.from_text(SMALL_CFG, NAME)
    with pytest.raises(ConfigError) as info:
        cfg.replace(dataclasses.replace(cfg.profile, num_adc_samples=15))
    assert str(info.value).startswith(f"{NAME}:8: profileCfg: numAdcSamples: ")
    with pytest.raises(ConfigError) as info:
        cfg.replace(dataclasses.replace(cfg.frame, frame_period_ms=1.0))
    assert info.value.command == "frameCfg" and info.value.field == "framePeriodicity"


@pytest.mark.parametrize("change", [
    {"rx_gain": 1000},
    {"hpf_corner1": 7},
    {"idle_time_us": float("nan")},
    {"start_freq_ghz": 70.0},
])
def test_replace_checks_field_ranges(change):
    cfg = RadarConfig.from_text(SMALL_CFG, NAME)
    with pytest.raises(ConfigError):
        cfg.replace(dataclasses.replace(cfg.profile, **change))


# -------------------------------------------------- commands_to_send
def test_commands_to_send_excludes_session_commands():
    cfg = RadarConfig.from_text(SMALL_CFG, NAME)
    sent = [str(ln) for ln in cfg.commands_to_send()]
    expected = [ln for ln in SMALL_CFG.splitlines()
                if ln and not ln.startswith("%") and ln not in ("sensorStop", "flushCfg", "sensorStart")]
    assert sent == expected
    assert not {"sensorStop", "flushCfg", "sensorStart"} & {ln.text for ln in cfg.commands_to_send()}
    # and the session commands are still part of the file
    assert {"sensorStop", "flushCfg", "sensorStart"} <= {ln.text for ln in cfg.commands()}


def test_commands_to_send_with_sensor_start_argument():
    cfg = RadarConfig.from_text(edit(SENSOR_START, "sensorStart 0"), NAME)
    assert "sensorStart" not in {ln.text for ln in cfg.commands_to_send()}


@pytest.mark.parametrize("line, measures", [(None, False), ("measureRangeBiasAndRxChanPhase 0 1.5 0.2", False),
                                            ("measureRangeBiasAndRxChanPhase 1 1.5 0.2", True)])
def test_channel_measurement_only_when_enabled(line, measures):
    cfg = RadarConfig.from_text(SMALL_CFG if line is None else SMALL_CFG.replace("sensorStart", f"{line}\nsensorStart"))
    measure = cfg.channel_measurement
    assert (measure is not None) is measures
    if measures:
        assert (measure.target_distance_m, measure.search_window_m) == (1.5, 0.2)
