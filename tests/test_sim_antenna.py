"""The simulator's antenna pattern and elevations as a scene sets them: the ``[radar]`` table's
half-power beam widths, and a ``flat`` scene in which every scatterer lies at the radar's height
(the diagnoses of docs/heading.md, "The turns in place's length")."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sim_helpers import decode, detect, point_scene

from radarodom.driver.sim.physics import AntennaPattern
from radarodom.driver.sim.scene import load_scene, scene_from_dict
from radarodom.driver.sim.simulator import Simulator
from radarodom.errors import ConfigError


def _power_at(cfg, azimuth_deg: float, **radar) -> float:
    """The strongest range-Doppler cell's power of a corner 3 m away at *azimuth_deg* (to the
    left), the scene's ``[radar]`` table given *radar* besides its SNR."""
    a = math.radians(azimuth_deg)
    scene = point_scene([(3.0 * math.cos(a), 3.0 * math.sin(a), 0.4)], extra={"radar": {"snr_db": 10.0, **radar}})
    sim = Simulator(cfg, scene, seed=3)
    return detect(cfg, decode(sim, sim.frame(0))).power


def test_a_scene_without_beam_widths_has_the_boards_pattern():
    scene = scene_from_dict({"objects": [], "trajectory": {"segments": [{"pause": 1.0}]}})
    assert scene.pattern == AntennaPattern() == AntennaPattern(100.0, 40.0)
    assert scene.flat is False


def test_the_beam_widths_set_the_gain_off_boresight(shipped_cfg):
    pattern = AntennaPattern(azimuth_hpbw_deg=140.0)
    wide = _power_at(shipped_cfg, 50.0, azimuth_hpbw_deg=140.0)
    default = _power_at(shipped_cfg, 50.0)
    # Power goes as the two-way voltage gain squared; the same corner on boresight is unchanged.
    expected = float(pattern.amplitude(math.radians(50), 0.0) / AntennaPattern().amplitude(math.radians(50), 0.0))
    assert wide / default == pytest.approx(expected**2, rel=0.05)
    assert expected > 1.5
    assert _power_at(shipped_cfg, 0.0, azimuth_hpbw_deg=140.0) == pytest.approx(_power_at(shipped_cfg, 0.0), rel=1e-6)


def test_a_flat_scene_puts_a_raised_corner_level_and_leaves_its_azimuth(shipped_cfg):
    corner = (3.0, -1.0, 1.9)  # 1.5 m above the radar, to its right
    found = {}
    for flat in (False, True):
        scene = point_scene([corner], extra={"flat": flat})
        sim = Simulator(shipped_cfg, scene, seed=5)
        found[flat] = detect(shipped_cfg, decode(sim, sim.frame(0)))
    raised, level = found[False], found[True]
    # wz is the direction's vertical component (sin of the elevation), wx its sideways one.
    slant = math.dist(corner, (0.0, 0.0, 0.4))
    assert raised.wz == pytest.approx(1.5 / slant, abs=0.03)
    assert abs(level.wz) < 0.03
    # Level, the corner's horizontal direction is all of it: its sideways component grows to
    # 1/sqrt(10) from 1/slant (within half of detect's angle bin of 1/32, apart by almost one).
    assert level.wx == pytest.approx(1.0 / math.sqrt(10.0), abs=1 / 64)
    assert raised.wx == pytest.approx(1.0 / slant, abs=1 / 64)


@pytest.mark.parametrize("text, field", [
    ("[radar]\nazimuth_hpbw_deg = 180\n", "radar.azimuth_hpbw_deg"),
    ("[radar]\nelevation_hpbw_deg = 0\n", "radar.elevation_hpbw_deg"),
    ("[radar]\nazimuth_hpbw_deg = \"wide\"\n", "radar.azimuth_hpbw_deg"),
    ("flat = \"yes\"\n", "flat"),
])
def test_a_bad_beam_width_or_flat_is_refused_naming_it(tmp_path, text, field):
    path = tmp_path / "scene.toml"
    path.write_text(text + "[trajectory]\nsegments = [{ pause = 1 }]\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_scene(str(path))
    message = str(info.value)
    assert str(path) in message and field in message


def test_the_pattern_is_flat_nowhere_behind_the_array():
    """The widest beam allowed still gives nothing behind the array (at 180 degrees cos^n's
    exponent would be 0 and 0**0 is 1)."""
    widest = AntennaPattern(azimuth_hpbw_deg=179.0)
    gains = widest.amplitude(np.radians([0.0, 80.0, 100.0, 180.0]), np.zeros(4))
    assert gains[0] == 1.0 and 0.5 < gains[1] < 1.0 and gains[2] == 0.0 and gains[3] == 0.0
