"""The detection range: a cfg's cfarFovCfg range maximum is capped at the usable range (beat
frequencies up to 80 % of the IF band, less the board's range bias), where the simulated
uncalibrated board's TX-to-RX leakage would otherwise make a fake zero-Doppler point, and
radar-cfg warns about such a cfg; a window closed by the cfg is refused at its line."""

from __future__ import annotations

import dataclasses
import math
import subprocess

import numpy as np
import pytest
from conftest import console_command

from radarodom.cfg import RadarConfig
from radarodom.driver.sim.board import load_board
from radarodom.driver.sources import open_source
from radarodom.dsp.config import DspConfig
from radarodom.dsp.processor import FrameProcessor

SHIPPED_FOV = "cfarFovCfg -1 0 0 10.0"


def with_range_fov(cfg: RadarConfig, maximum: float, line: bool = True) -> RadarConfig:
    """*cfg* (the shipped one) with its cfarFovCfg range maximum set to *maximum*, and the
    uncalibrated board's calibration line when *line*."""
    if line:
        cfg = cfg.replace(load_board("uncalibrated").calibration().to_command())
    text = cfg.to_text()
    assert SHIPPED_FOV in text
    return RadarConfig.from_text(text.replace(SHIPPED_FOV, f"cfarFovCfg -1 0 0 {maximum}"), "fov.cfg")


def _points(url: str, cfg: RadarConfig, params: DspConfig | None = None) -> np.ndarray:
    with open_source(url, cfg) as source:
        proc = FrameProcessor(source.config, params or DspConfig(), calibrated=source.calibrated)
        return np.concatenate([proc.process(frame.cube()).points for frame in source])


@pytest.mark.parametrize("line", [True, False], ids=["its-line", "identity"])
def test_range_fov_beyond_the_usable_range_makes_no_leakage_point(shipped_cfg, line):
    """cfarFovCfg -1 0 0 15.0 on the uncalibrated board (sim://, a reflector at 4.1 m): the
    leakage's negative-frequency side at ~12.4 m is there, but detection stops at the usable range."""
    cfg = with_range_fov(shipped_cfg, 15.0, line)
    usable = cfg.max_range_m - cfg.channel_calibration.range_bias_m
    assert FrameProcessor(cfg).detection_range_m[1] == pytest.approx(usable)
    url = "sim://calibration?board=uncalibrated&rate=max&duration=0.2"
    # The leakage is in the frames: with the range limit lifted, zero-Doppler points beyond it.
    everything = _points(url, cfg, DspConfig(max_range_m=20.0))
    far = everything[everything["range"] > usable]
    assert len(far) and np.all(far["doppler_bin"] == 0), everything[["range", "doppler_bin"]]
    points = _points(url, cfg)
    assert len(points) and points["range"].max() <= usable, points[["range", "doppler_bin"]]
    # A shorter cfarFovCfg maximum still applies as written.
    assert FrameProcessor(with_range_fov(shipped_cfg, 6.0, line)).detection_range_m[1] == 6.0


def _radar_cfg(path) -> subprocess.CompletedProcess:
    return subprocess.run(console_command("radar-cfg") + [str(path)], stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=60)


def test_radar_cfg_warns_of_a_range_fov_beyond_the_usable_range(tmp_path, shipped_cfg):
    """One warning naming the line, the usable range it is capped to, and the fix; the board's
    range bias counts.  Within two range bins (cfgs round the limit: the shipped 10 m for
    9.993 m, 9.928 m with the board's line) the cap is silent."""
    bias = load_board("uncalibrated").range_bias_m
    with_line = shipped_cfg.max_range_m - bias
    for maximum, line, usable in ((15.0, False, shipped_cfg.max_range_m), (10.05, True, with_line)):
        less = f", less the range bias of {bias:g} m" if line else ""
        cfg = with_range_fov(shipped_cfg, maximum, line)
        path = tmp_path / "fov.cfg"
        cfg.write(path)
        proc = _radar_cfg(path)
        assert proc.returncode == 0, proc.stderr
        at = next(n for n, text in enumerate(path.read_text().splitlines(), start=1)
                  if text.startswith("cfarFovCfg -1 0 "))
        warning = [ln for ln in proc.stderr.splitlines() if "cfarFovCfg" in ln]
        assert warning == [f"radar-cfg: warning: {path}:{at}: cfarFovCfg range maximum {maximum:g} m reaches beyond "
                           f"the usable range, {usable:.2f} m (beat frequencies up to 80 % of the IF band{less}): detection "
                           f"is capped there, since the IF filter's roll-off and the TX-to-RX leakage lie beyond; "
                           f"set the maximum to {usable:.2f} m or less"], proc.stderr
        assert math.isclose(FrameProcessor(cfg).detection_range_m[1], usable)
    for maximum in (9.9, 10.0):  # within the usable range, or beyond it by less than two bins: no word
        path = tmp_path / "ok.cfg"
        with_range_fov(shipped_cfg, maximum).write(path)
        proc = _radar_cfg(path)
        assert proc.returncode == 0 and "cfarFovCfg" not in proc.stderr, proc.stderr
    assert FrameProcessor(with_range_fov(shipped_cfg, 10.0)).detection_range_m[1] == pytest.approx(with_line)


@pytest.mark.parametrize("bias, words", [(9.5, "taken 9.5 m shorter"), (-2, "taken 2 m longer")])
def test_a_range_bias_of_metres_is_warned_of_at_its_line(tmp_path, shipped_cfg, caplog, bias, words):
    """A board's range bias is centimetres: 9.5 m left the frames without a point and nothing
    said why but the range window's warning (radar-cfg's alone)."""
    line = load_board("uncalibrated").calibration()
    path = tmp_path / "bias.cfg"
    shipped_cfg.replace(dataclasses.replace(line, range_bias_m=bias).to_command()).write(path)
    caplog.clear()
    RadarConfig.from_file(path)
    at = _cfg_line(path, "compRangeBiasAndRxChanPhase")
    warned = [r.getMessage() for r in caplog.records if "rangeBias" in r.getMessage()]
    assert warned == [f"{path}:{at}: compRangeBiasAndRxChanPhase: rangeBias {bias:g} m, where a board's is a few "
                      f"centimetres: every range is {words} and the usable range moves with it; is it the "
                      "board's? radar-calibrate measures it"], caplog.text
    caplog.clear()
    shipped_cfg.replace(line.to_command())  # the uncalibrated board's own: a few centimetres
    assert "rangeBias" not in caplog.text


def _cfg_line(path, prefix: str) -> int:
    return next(n for n, text in enumerate(path.read_text().splitlines(), start=1) if text.startswith(prefix))


@pytest.mark.parametrize("edit, prefix, where, words", [
    (("cfarFovCfg -1 0 0 10.0", "cfarFovCfg -1 0 0 0.1"), "cfarFovCfg -1 0 ", "cfarFovCfg: max (meters or m/s)",
     "the range window ends at 0.1 m, at or below radarodom's shortest range (0.3 m)"),
    (("cfarFovCfg -1 0 0 10.0", "cfarFovCfg -1 0 10.5 12"), "cfarFovCfg -1 0 ", "cfarFovCfg: min (meters or m/s)",
     "the range window starts at 10.5 m, beyond the usable range"),
    (("compRangeBiasAndRxChanPhase 0.0 ", "compRangeBiasAndRxChanPhase 9.99 "), "compRangeBiasAndRxChanPhase",
     "compRangeBiasAndRxChanPhase: rangeBias", "a range bias of 9.99 m leaves 0.00 m of the profile's usable"),
])
def test_a_cfg_that_leaves_nothing_to_detect_in_is_refused_at_its_line(tmp_path, capsys, shipped_cfg, edit, prefix,
                                                                          where, words):
    """Its range window, or a range bias that eats the usable range: refused by radar-cfg and by
    radar-capture, naming the line that closed the window (they once blamed "the estimator's
    settings" and a DspConfig field no option reaches, and radar-cfg called the cfg valid)."""
    text = shipped_cfg.to_text()
    assert edit[0] in text
    path = tmp_path / "closed.cfg"
    path.write_text(text.replace(edit[0], edit[1]))
    expected = f"{path}:{_cfg_line(path, prefix)}: {where}: {words}"
    from radarodom.tools import radar_capture, radar_cfg

    for program, main, argv in (
            ("radar-cfg", radar_cfg.main, [str(path)]),
            ("radar-capture", radar_capture.main,
             ["--cfg", str(path), "--no-publish", "--source", "sim://lab?rate=max&duration=0.2"])):
        rc = main(argv)
        stderr = capsys.readouterr().err
        errors = [ln for ln in stderr.splitlines() if ": error: " in ln]
        assert rc == 2 and len(errors) == 1, stderr
        assert errors[0].startswith(f"{program}: error: {expected}"), errors
        assert "nothing is left to detect in between " in errors[0], errors


def test_the_dsps_own_limits_are_named_when_they_close_the_window(shipped_cfg):
    from radarodom.errors import ConfigError

    cfg = RadarConfig.from_text(shipped_cfg.to_text().replace(SHIPPED_FOV, "cfarFovCfg -1 0 2 10"), "fov.cfg")
    with pytest.raises(ConfigError) as info:  # the window's 2 m beyond the DSP's own longest range
        FrameProcessor(cfg, DspConfig(max_range_m=1.0))
    assert str(info.value).startswith("max_range_m: nothing is left to detect in between 2 m and 1 m (DspConfig "
                                      "min_range_m 0.3 m and max_range_m 1 m"), str(info.value)
