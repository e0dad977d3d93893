"""Issue 18: a simulation's length is checked like any option: sim://corridor?duration=1e308
ended in "internal error: OverflowError" (ceil of an infinite frame count)."""

from __future__ import annotations

import math

import pytest

from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.sim.scene import load_scene
from radarodom.driver.sim.simulator import MAX_FRAMES, Simulator
from radarodom.errors import UsageError
from radarodom.tools import radar_capture


@pytest.mark.parametrize("duration", [1e308, math.inf, math.nan, 0.0, -1.0, (MAX_FRAMES + 1) * 0.1])
def test_an_impossible_duration_is_a_usage_error(duration):
    with pytest.raises(UsageError, match="duration"):
        Simulator(RadarConfig.from_file(shipped_config_path()), load_scene("corridor"), duration_s=duration)


@pytest.mark.parametrize("duration", ["1e308", "inf", "nan", "0", "1e999"])
def test_sim_url_with_an_impossible_duration_exits_2_with_one_line(duration, capsys):
    assert radar_capture.main(["--source", f"sim://corridor?duration={duration}&rate=max", "--no-publish",
                               "-q", "--frames", "1"]) == 2
    err = capsys.readouterr().err
    assert "internal error" not in err and "Traceback" not in err, err
    assert len([ln for ln in err.splitlines() if ln.startswith("radar-capture: error:") and "duration" in ln]) == 1
