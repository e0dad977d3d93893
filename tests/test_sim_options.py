"""Issue 18: a simulation's length is checked like any option: sim://corridor?duration=1e308
ended in "internal error: OverflowError" (ceil of an infinite frame count)."""

from __future__ import annotations

import math
from urllib.parse import quote

import pytest
from conftest import REPO, warning_messages
from hypothesis import given, settings
from hypothesis import strategies as st

from radarodom.cfg import RadarConfig, shipped_config_path
from radarodom.driver.sim.scene import load_scene
from radarodom.driver.sim.simulator import MAX_FRAMES, Simulator
from radarodom.driver.sources import open_source
from radarodom.driver.url_options import MAX_URL_NUMBER
from radarodom.errors import SourceError, UsageError
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


# Issue 18, "option values are checked like cfg fields": URL options took Python's float() and
# int(), which accept 1_0, non-ASCII digits, surrounding spaces, nan and inf.
@pytest.mark.parametrize("option", ["duration=1_0", "duration=%20%201", "duration=\u0663", "duration=0x10",
                                    "rate=nan", "rate=inf", "seed=1_0"])
def test_url_options_take_plain_decimal_numbers_only(option):
    with pytest.raises(SourceError, match=option.split("=")[0] + "=.*written as a plain decimal number"):
        open_source(f"sim://corridor?{option}")


@pytest.mark.parametrize("option, expected", [
    ("seed=-1", "expected an integer >= 0"), ("seed=1.5", "expected an integer >= 0"),
    ("rate=1e308", "(from 0.001 to 1e+09)"), ("seed=" + "9" * 40, "expected an integer >= 0 (at most "),
    ("duration=-1", "expected seconds > 0 (at most 1e+09)")])
def test_a_plain_number_out_of_range_is_told_its_range_not_how_to_write_it(option, expected):
    """'seed=-1: expected an integer >= 0, written as a plain decimal number': -1 is one."""
    with pytest.raises(SourceError) as err:
        open_source(f"sim://corridor?{option}")
    said = str(err.value)
    assert expected in said and "plain decimal" not in said, said


@pytest.mark.parametrize("seed", ["9223372036854775808", "18446744073709551615", "9" * 38])
def test_a_seed_past_the_largest_option_says_the_range_in_the_url_and_in_radar_sim(seed, tmp_path, capsys):
    """A URL took 2**63 and recorded it, which radar-sim --seed refused; and radar-sim said of a
    whole number too large that it was none ('expected a whole number >= 0')."""
    with pytest.raises(SourceError) as info:
        open_source(f"sim://corridor?seed={seed}")
    assert f"option seed='{seed}': expected an integer >= 0 (at most 9223372036854775807)" in str(info.value)
    from radarodom.tools import radar_sim

    assert radar_sim.main(["corridor", "--seed", seed, "--out", str(tmp_path / "x")]) == 2
    assert f"--seed: expected a whole number in 0..9223372036854775807, got '{seed}'" in capsys.readouterr().err
    with open_source("sim://corridor?seed=9223372036854775807&duration=0.1") as src:  # the largest is taken
        assert next(iter(src)).index == 0


@pytest.mark.parametrize("scheme", ["sim://corridor", "replay://runs/x", "replay://runs/uart.bin?format=tidemo",
                                    "coloradar://runs/x"])
def test_a_rate_that_would_wait_for_ever_is_refused_with_its_range(scheme):
    # A tiny positive rate (a typing slip) made a stream wait years for its second frame.
    for text in ("5e-324", "0.0000001", "0.0009"):
        with pytest.raises(SourceError, match=f"rate='{text}'.*from 0.001 to 1e\\+09"):
            open_source(f"{scheme}{'&' if '?' in scheme else '?'}rate={text}")


def test_the_slowest_rate_streams():
    with open_source("sim://corridor?rate=0.001&duration=0.1") as src:
        assert src.rate == 0.001
        assert next(iter(src)).index == 0  # the first frame is due at once


def test_a_word_option_says_its_words_not_numbers():
    with pytest.raises(SourceError) as info:
        open_source("sim://corridor?fidelity=quick")
    assert str(info.value).endswith("option fidelity='quick': expected exact or fast")


@settings(max_examples=60, deadline=None)
@given(st.text(max_size=12))
def test_any_url_option_text_is_taken_in_range_or_refused_naming_the_option(text):
    # Whatever follows duration=, the source opens with a duration in range or refuses it by name.
    try:
        src = open_source(f"sim://corridor?rate=max&duration={quote(text, safe='')}")
    except UsageError as exc:  # SourceError, or the simulator's refusal of too many frames
        assert "duration" in str(exc) and "\n" not in str(exc)
    else:
        with src:
            value = float(text)
            assert 0 < value <= MAX_URL_NUMBER and src.sim.num_frames >= 1


def test_a_duration_beyond_the_trajectory_is_said(warnings_log):
    # The sensor silently stood at the trajectory's end for the rest (400 frames of a 32 s scene).
    scene = load_scene("corridor")
    Simulator(RadarConfig.from_file(shipped_config_path()), scene, duration_s=scene.trajectory.duration_s)
    assert not warning_messages(warnings_log)
    Simulator(RadarConfig.from_file(shipped_config_path()), scene, duration_s=scene.trajectory.duration_s + 5)
    assert any("longer than scene corridor's trajectory" in m and "loop=N" in m for m in warning_messages(warnings_log))


@pytest.mark.parametrize("given, name", [("sim://room?seed=3", "room"), ("sim://", "corridor"), ("sim:lab", "lab")])
def test_radar_sim_given_a_sim_url_says_to_give_the_scene(given, name, tmp_path, capsys):
    """radar-capture's --source given to radar-sim was 'no such scene'."""
    from radarodom.tools import radar_sim

    assert radar_sim.main([given, "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err == (f"radar-sim: error: {given}: radar-sim takes a scene's name or file, not a "
                                       f"sim:// URL: radar-sim {name} --out DIR (the URL's options are radar-sim's: "
                                       "--seed, --duration, --board, --fidelity, --noise-seed)\n")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("option", ["loop=-1", "seed=x", "rate=max&duration=1&loop=1.5"])
def test_a_number_below_the_minimum_or_none_is_not_told_the_upper_limit(option):
    """Every refusal of a whole-number option ended '(at most 9223372036854775807)'."""
    with pytest.raises(SourceError) as info:
        open_source(f"sim://corridor?{option}")
    assert "at most" not in str(info.value), str(info.value)


@pytest.mark.parametrize("url, option", [("coloradar:///tmp/run?calib=", "calib"), ("dca1000://?cli=", "cli"),
                                         ("tidemo:///dev/ttyACM1?cli=%20", "cli"),
                                         ("dca1000://?host=&cli=/dev/null", "host")])
def test_an_empty_path_or_address_option_is_refused(url, option):
    """calib= was taken as no calib= at all (sim:// refuses rate=, as every number)."""
    with pytest.raises(SourceError) as info:
        open_source(url)
    assert f"option {option}=" in str(info.value) and "expected" in str(info.value), str(info.value)


def test_a_path_faster_than_the_cfg_measures_is_said(tmp_path, warnings_log):
    # 5 m/s past the shipped cfg's +/-2.28 m/s was simulated in silence: every static point's
    # Doppler folded over, and the odometry's velocity with it.
    text = (REPO / "driver" / "sim" / "scenes" / "corridor.toml").read_text()
    fast = tmp_path / "fast.toml"
    fast.write_text(text.replace("{ straight = 14.5, speed = 1.2 }", "{ straight = 14.5, speed = 5.0 }"))
    cfg = RadarConfig.from_file(shipped_config_path())
    Simulator(cfg, load_scene("corridor"), duration_s=1.0)
    assert not warning_messages(warnings_log)
    Simulator(cfg, load_scene(str(fast)), duration_s=1.0)
    (message,) = warning_messages(warnings_log)
    assert ("drives the radar at up to 5.00 m/s, beyond the cfg's unambiguous radial velocity of "
            f"+/-{cfg.max_velocity_mps:.2f} m/s") in message
