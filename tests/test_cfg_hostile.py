"""Issue 18, "cfg and options": what a hostile or unlucky cfg does to :class:`RadarConfig`.

Every command the radar receives has its numbers checked (or is sent with a warning that says
it is not), only ASCII spaces and tabs separate arguments, files are read with a size bound, any
path argument ends in :class:`ConfigError` at worst, echoed input is cut, and repeated warnings
are summarised.
"""

from __future__ import annotations

import logging
import os

import pytest
from conftest import SMALL_CFG
from test_cfg_validation import NAME, SENSOR_START, edit, expect_error, insert_before, line_of

from radarodom import cfg_commands as cc
from radarodom.cfg import MAX_CFG_BYTES, RadarConfig, dca1000_capacity_mbps
from radarodom.errors import ConfigError, UsageError

#: Tokens that are no number the radar reads as written (NUL is refused for the whole line).
HOSTILE = ("nan", "\u00e9", "None", "0x10", "1,5", "1e308", "-inf", "1_0", "")

#: (a valid line, index of a numeric argument, that argument's name in messages): every
#: field of the commands the issue found unchecked.
CHECKED_FIELDS = [
    ("guiMonitor -1 0 0 0 0 0 0", i, name) for i, name in enumerate(
        ("subFrameIdx", "detected objects", "log magnitude range", "noise profile",
         "rangeAzimuthHeatMap", "rangeDopplerHeatMap", "statsInfo"))
] + [
    ("calibData 0 0 0", 0, "save enable"),
    ("calibData 0 0 0", 1, "restore enable"),
    ("CQRxSatMonitor 0 3 4 99 0", 0, "profile"),
    ("CQRxSatMonitor 0 3 4 99 0", 1, "satMonSel"),
    ("CQRxSatMonitor 0 3 4 99 0", 2, "priSliceDuration"),
    ("CQRxSatMonitor 0 3 4 99 0", 3, "numSlices"),
    ("CQRxSatMonitor 0 3 4 99 0", 4, "rxChanMask"),
    ("CQSigImgMonitor 0 127 4", 0, "profile"),
    ("CQSigImgMonitor 0 127 4", 1, "numSlices"),
    ("CQSigImgMonitor 0 127 4", 2, "numSamplePerSlice"),
    ("analogMonitor 0 0", 0, "rxSaturation"),
    ("analogMonitor 0 0", 1, "sigImgBand"),
    ("measureRangeBiasAndRxChanPhase 0 1.5 0.2", 0, "enabled"),
    ("measureRangeBiasAndRxChanPhase 0 1.5 0.2", 1, "targetDistance"),
    ("measureRangeBiasAndRxChanPhase 0 1.5 0.2", 2, "searchWin"),
    ("cfarFovCfg -1 0 0 10.0", 2, "min (meters or m/s)"),
    ("cfarFovCfg -1 0 0 10.0", 3, "max (meters or m/s)"),
    ("bpmCfg -1 0 0 0", 2, "chirp0Idx"),
    ("configDataPort 921600 1", 0, "baudrate"),
    ("sensorStart 0", 0, "doReconfig"),
]
CHIRP_VARIATIONS = [(3, "startFreqVar"), (4, "freqSlopeVar"), (5, "idleTimeVar"), (6, "adcStartTimeVar")]
CHIRP0 = "chirpCfg 0 0 0 0 0 0 0 1"


def _with_line(line: str) -> str:
    if line.startswith("sensorStart"):
        return edit(SENSOR_START, line)
    return insert_before(SENSOR_START, line)


def _set(line: str, index: int, token: str) -> str:
    tokens = line.split(" ")
    tokens[index + 1] = token
    return " ".join(tokens)


@pytest.mark.parametrize("line, index, field", CHECKED_FIELDS)
def test_every_field_the_radar_receives_is_valid_as_shipped(line, index, field):
    cfg = RadarConfig.from_text(_with_line(line), NAME)
    assert line in [str(ln) for ln in cfg.commands()]


@pytest.mark.parametrize("token", HOSTILE)
@pytest.mark.parametrize("line, index, field", CHECKED_FIELDS)
def test_hostile_token_in_a_field_the_radar_receives_is_refused(line, index, field, token):
    bad = _set(line, index, token)
    text = _with_line(bad)
    if token == "":  # one argument fewer (sensorStart's is optional)
        if line.startswith("sensorStart"):
            return
        with pytest.raises(ConfigError):
            RadarConfig.from_text(text, NAME)
        return
    expect_error(text, line_of(text, bad), bad.split()[0], field)


@pytest.mark.parametrize("token", HOSTILE[:-1])
@pytest.mark.parametrize("index, field", CHIRP_VARIATIONS)
def test_hostile_token_in_a_chirp_variation_is_refused(index, field, token):
    bad = _set(CHIRP0, index, token)
    expect_error(edit(CHIRP0, bad), line_of(SMALL_CFG, CHIRP0), "chirpCfg", field)


@pytest.mark.parametrize("index, field, value", [
    (3, "startFreqVar", "-1"), (3, "startFreqVar", "5e8"), (4, "freqSlopeVar", "3100"),
    (5, "idleTimeVar", "41"), (6, "adcStartTimeVar", "-0.01"),
])
def test_chirp_variation_outside_what_mmwavelink_takes(index, field, value):
    bad = _set(CHIRP0, index, value)
    expect_error(edit(CHIRP0, bad), line_of(SMALL_CFG, CHIRP0), "chirpCfg", field, "outside")


def test_calib_data_flash_offset_is_hexadecimal_as_the_firmware_reads_it():
    cfg = RadarConfig.from_text(_with_line("calibData 0 1 0x1F0000"), NAME)
    assert "calibData 0 1 0x1F0000" in [str(ln) for ln in cfg.commands_to_send()]
    for token in ("16", "0x", "0x1G", "0x123456789", "nan"):
        bad = f"calibData 0 1 {token}"
        text = _with_line(bad)
        expect_error(text, line_of(text, bad), "calibData", "Flash offset", "hexadecimal")


def test_calib_data_save_and_restore_together_is_refused():
    text = _with_line("calibData 1 1 0")
    expect_error(text, line_of(text, "calibData 1 1 0"), "calibData", "restore enable", "both")


@pytest.mark.parametrize("char", ["\x00", "\u00a0", "\u2007", "\x0b", "\x1f", "\u200b", "\u3000"])
def test_only_ascii_space_and_tab_separate_arguments(char):
    bad = "profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30".replace(" 96 ", f" 96{char}")
    text = edit("profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30", bad)
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_text(text, NAME)
    err = info.value
    assert str(err).startswith(f"{NAME}:8: column {bad.index(char) + 1}: character U+{ord(char):04X}")
    assert "ASCII spaces and tabs" in str(err)


def test_non_ascii_in_a_line_sent_as_written_is_refused():
    bad = "fancyNewCmd caf\u00e9"
    text = _with_line(bad)
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_text(text, NAME)
    assert str(info.value).startswith(f"{NAME}:{line_of(text, bad)}: argument 1 ")
    assert "not ASCII" in str(info.value)


def test_unchecked_command_is_sent_with_a_warning_that_says_so(caplog):
    text = _with_line("idlePowerCycle 0 1")
    with caplog.at_level(logging.WARNING, logger="radarodom.cfg"):
        cfg = RadarConfig.from_text(text, NAME)
    assert "idlePowerCycle 0 1" in [str(ln) for ln in cfg.commands_to_send()]
    messages = [r.getMessage() for r in caplog.records]
    assert [m for m in messages if "idlePowerCycle" in m and "not checked" in m]


def test_800000_unknown_command_lines_warn_in_a_summary(caplog):
    n = 800_000
    text = SMALL_CFG.replace(SENSOR_START + "\n", "") + "fancyCmd 1\n" * n + SENSOR_START + "\n"
    with caplog.at_level(logging.WARNING, logger="radarodom.cfg"):
        cfg = RadarConfig.from_text(text, NAME)
    assert sum(1 for ln in cfg.commands() if ln.text == "fancyCmd") == n  # all kept, in order
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 6
    first = SMALL_CFG.count("\n")  # the unknown lines follow the cfg's lines but sensorStart
    assert [m.split(": ")[0] for m in messages[:5]] == [f"{NAME}:{first + k}" for k in range(5)]
    assert f"... and {n - 5} more lines like this" in messages[5]


def test_warnings_are_said_even_when_the_cfg_is_refused_later(caplog):
    text = insert_before(SENSOR_START, "fancyCmd 1") + "frameCfg 0 2 4 0 50 1 0\n"
    with caplog.at_level(logging.WARNING, logger="radarodom.cfg"), pytest.raises(ConfigError):
        RadarConfig.from_text(text, NAME)
    assert any("fancyCmd" in r.getMessage() for r in caplog.records)


def test_a_10_mb_token_is_not_echoed_whole(caplog):
    token = "9" * 10_500_000
    with caplog.at_level(logging.WARNING, logger="radarodom.cfg"):
        RadarConfig.from_text(insert_before(SENSOR_START, "x" * 10_500_000), NAME)
    assert caplog.records and max(len(r.getMessage()) for r in caplog.records) < 300
    assert "10500000 characters" in caplog.records[0].getMessage()
    text = edit("profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30",
                f"profileCfg 0 {token} 100 6 40 0 0 96 1 16 8000 0 0 30")
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_text(text, NAME)
    assert len(str(info.value)) < 300
    text = edit("profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30",
                f"profileCfg 0 77 100 6 40 0 0 96 1 {token} 8000 0 0 30")
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_text(text, NAME)
    assert len(str(info.value)) < 300


# -------------------------------------------------------------- files
def test_from_file_reads_at_most_the_bound(tmp_path):
    path = tmp_path / "huge.cfg"
    path.write_text(SMALL_CFG + "%" * MAX_CFG_BYTES)
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file(path)
    assert str(info.value).startswith(f"{path}: ") and "1 MiB" in str(info.value)


def test_from_file_dev_zero_says_the_limit():
    if not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero")
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file("/dev/zero")
    assert "1 MiB" in str(info.value)


def test_from_file_path_with_nul_is_a_config_error():
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file("bad\0name.cfg")
    assert "NUL" in str(info.value)


def test_from_file_bytes_path_reads_the_file(tmp_path):
    path = tmp_path / "small.cfg"
    path.write_text(SMALL_CFG)
    cfg = RadarConfig.from_file(os.fsencode(path))
    assert cfg == RadarConfig.from_text(SMALL_CFG) and cfg.path == str(path)
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file(os.fsencode(tmp_path / "missing.cfg"))
    assert str(info.value).startswith(str(tmp_path / "missing.cfg"))


@pytest.mark.parametrize("path", [3, None, 1.5, ["a.cfg"]])
def test_from_file_with_no_path_is_a_config_error(path):
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file(path)
    assert "expected a file path" in str(info.value)


def test_from_file_directory_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file(tmp_path)
    assert str(info.value).startswith(f"{tmp_path}: cannot read the file")


def test_from_file_unreadable_file_is_a_config_error(tmp_path):
    if os.path.exists("/proc/self/mem"):  # opens, then fails to read (even as root)
        with pytest.raises(ConfigError) as info:
            RadarConfig.from_file("/proc/self/mem")
        assert "cannot read the file" in str(info.value)
    path = tmp_path / "locked.cfg"
    path.write_text(SMALL_CFG)
    path.chmod(0)
    if os.access(path, os.R_OK):
        return  # root reads it anyway
    with pytest.raises(ConfigError) as info:
        RadarConfig.from_file(path)
    assert "cannot read the file" in str(info.value)


def test_from_text_with_no_text_is_a_config_error():
    with pytest.raises(ConfigError):
        RadarConfig.from_text(b"sensorStop\n", NAME)  # type: ignore[arg-type]


# ------------------------------------------------------- packet delay
@pytest.mark.parametrize("delay", [float("inf"), float("nan"), 1e308, -5.0, 0.0, 4.9, 501.0])
def test_capacity_refuses_a_packet_delay_outside_the_documented_range(delay):
    with pytest.raises(UsageError) as info:
        dca1000_capacity_mbps(delay)
    assert "5..500" in str(info.value)


def test_capacity_at_the_documented_ends_is_finite():
    assert dca1000_capacity_mbps(5.0) == pytest.approx(706.0)
    assert 0 < dca1000_capacity_mbps(500.0) < dca1000_capacity_mbps(50.0)


def test_checked_commands_are_verbatim_commands():
    """What is checked is also sent as written (the emulator knows every one of them)."""
    assert set(cc.CHECKED_COMMANDS) <= set(cc.VERBATIM_COMMANDS)
    assert set(cc.UNCHECKED_COMMANDS) <= set(cc.VERBATIM_COMMANDS)


# ---------------------------------------------------- settings files (--estimator-config)
def test_settings_file_with_nan_or_infinity_is_refused(tmp_path):
    from radarodom.estimator.config import EstimatorConfig

    for text in ('{"odometry": {"keyframe_noise_rad": NaN}}', '{"odometry": {"keyframe_noise_rad": 1e999}}',
                 '{"odometry": {"keyframe_noise_rad": -Infinity}}'):
        path = tmp_path / "est.json"
        path.write_text(text)
        with pytest.raises(ConfigError) as info:
            EstimatorConfig.load(path)
        assert str(info.value).startswith(f"{path}: cannot read estimator settings")


@pytest.mark.parametrize("value", [float("nan"), float("inf"), 10**400])
def test_settings_non_finite_value_names_the_field(value):
    from radarodom.estimator.config import EstimatorConfig

    with pytest.raises(ConfigError) as info:
        EstimatorConfig.from_dict({"odometry": {"keyframe_noise_rad": value}})
    assert info.value.field == "odometry.keyframe_noise_rad" and "finite" in str(info.value)
    assert len(str(info.value)) < 200


def test_settings_file_is_read_with_a_bound(tmp_path):
    from radarodom.estimator.config import EstimatorConfig
    from radarodom.settings import MAX_SETTINGS_BYTES

    path = tmp_path / "big.json"
    path.write_text('{"odometry": {}}' + " " * MAX_SETTINGS_BYTES)
    with pytest.raises(ConfigError) as info:
        EstimatorConfig.load(path)
    assert "more than" in str(info.value) and str(MAX_SETTINGS_BYTES) in str(info.value)
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ConfigError) as info:
        EstimatorConfig.load(path)
    assert "nested" in str(info.value)


def test_settings_path_with_nul_or_no_path_is_a_config_error(tmp_path):
    from radarodom.estimator.config import EstimatorConfig

    for path in ("a\0b.json", 3, None):
        with pytest.raises(ConfigError):
            EstimatorConfig.load(path)
    path = tmp_path / "default.json"
    EstimatorConfig().dump(path)
    assert EstimatorConfig.load(os.fsencode(path)) == EstimatorConfig()


@pytest.mark.parametrize("text", ["", "\n\n", "% a comment only\n\n% and another\n"])
def test_a_file_with_no_command_is_refused_as_that(text):
    with pytest.raises(ConfigError, match=r"^mine.cfg: no command in it \(empty, or only comments and blank "
                                          r"lines\): not a TI mmWave cfg"):
        RadarConfig.from_text(text, "mine.cfg")


def test_another_file_given_as_a_cfg_is_refused_before_a_warning_a_line(caplog):
    with pytest.raises(ConfigError, match=r"^est.tum:1: not a TI mmWave cfg: none of its 2 command line\(s\) is a "
                                          r"cfg command \(the first: '0.0'\)$"):
        RadarConfig.from_text("0.0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0 1\n", "est.tum")
    assert "unknown command" not in caplog.text


def test_radar_cfg_on_an_empty_file_says_so_in_one_line(tmp_path, capsys):
    from radarodom.tools import radar_cfg

    (tmp_path / "empty.cfg").write_text("")
    assert radar_cfg.main([str(tmp_path / "empty.cfg")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"radar-cfg: error: {tmp_path / 'empty.cfg'}: no command in it"), err
