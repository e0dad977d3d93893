"""Issue 18: the --json outputs of radar-calibrate and radar-devices are standard JSON, a
figure that is not finite written as null (radar-eval's are tested in test_cli_eval.py,
radar-echo's in test_cli_echo.py and test_fuzz_messages.py)."""

from __future__ import annotations

import json
import math

from radarodom.calibration import ChannelCalibration
from radarodom.dsp.calibrate import CalibrationMeasurement
from radarodom.tools import radar_calibrate, radar_devices


def strict_loads(text: str):
    def refuse(name):
        raise AssertionError(f"{name} in output that claims to be JSON")
    return json.loads(text, parse_constant=refuse)


def test_radar_calibrate_json_writes_an_undefined_figure_as_null():
    """A measurement whose gates let NaN through (every comparison with NaN is false) used to be
    printed as NaN by --json."""
    result = CalibrationMeasurement(ChannelCalibration.identity(), distance_m=3.0, measured_range_m=3.02,
                                    snr_db=math.inf, residual_phase_deg=math.nan, rank_one_residual_deg=math.nan,
                                    apparent_azimuth_deg=-math.inf, frames=5)
    data = strict_loads(radar_calibrate.json_report(result))
    assert (data["snr_db"], data["residual_phase_deg"], data["rank_one_residual_deg"],
            data["apparent_azimuth_deg"]) == (None, None, None, None)
    assert data["distance_m"] == 3.0 and data["frames"] == 5 and data["coefficients"][0] == [1.0, 0.0]
    assert data["cfg_line"].startswith("compRangeBiasAndRxChanPhase 0")


def test_radar_devices_json_is_standard_json(capsys):
    assert radar_devices.main(["--json"]) == 0
    data = strict_loads(capsys.readouterr().out)
    assert {"radars", "dca1000", "hints"} <= set(data)
