"""Property-based robustness of the numeric command-line options (issue 18).

Whatever text a numeric option of any radarodom program is given, it is either refused by
argparse (exit 2, the option named) or taken as a finite number inside the option's range;
``radar-cfg`` never ends in an internal error and its ``--json`` is always standard JSON.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import json
import math

import pytest
from conftest import SMALL_CFG
from hypothesis import given, settings
from hypothesis import strategies as st

from radarodom.tools import cli, radar_cfg

TOOLS = ("radar_capture", "radar_cfg", "radar_sim", "radar_emulate", "radar_eval", "radar_coloradar",
         "radar_echo", "radar_calibrate", "radar_devices")

HOSTILE = ("inf", "-inf", "nan", "NaN", "Infinity", "1e308", "-1e308", "1e999", "-5", "0", "-0", "1_0",
           "0x10", "1,5", "None", "\u00e9", "\u0665", "\uff15", " 5", "5 ", "", "-", ".", "1e", "\x00",
           "9" * 5000, "1" + "0" * 400, "4.9e-324", "2.5", "25", "65536", "233", "90", "90.0001")

values = st.one_of(
    st.sampled_from(HOSTILE),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(min_value=-1000, max_value=1000).map(lambda x: f"{x:g}"),
    st.integers().map(str),
    st.integers(min_value=-10, max_value=70000).map(str),
    st.text(max_size=12),
)


def _numeric_options() -> list[tuple[str, str, argparse.Action]]:
    """(tool, option, action) of every option of every program whose value is converted."""
    found = []
    for tool in TOOLS:
        parser = importlib.import_module(f"radarodom.tools.{tool}").build_parser()
        for action in parser._actions:
            # radar-capture's --mount is four numbers (x,y,z,yaw_deg): tests/test_mount.py.
            if action.type is not None and action.option_strings \
                    and not getattr(action.type, "not_a_number", False):
                found.append((tool, action.option_strings[-1], action))
    return found


NUMERIC_OPTIONS = _numeric_options()


def test_every_numeric_option_has_a_range_checked_type():
    """No bare int/float: every converted option is one of tools/cli's range-checked types
    (radar-echo's message kinds are names, not numbers)."""
    assert NUMERIC_OPTIONS
    for tool, option, action in NUMERIC_OPTIONS:
        assert action.type not in (int, float), (tool, option)
        assert hasattr(action.type, "bounds"), (tool, option)


def _in_bounds(value, bounds) -> bool:
    lo, hi, lo_open = bounds
    return math.isfinite(value) and (lo < value if lo_open else lo <= value) and value <= hi


@settings(max_examples=300, deadline=None)
@given(choice=st.sampled_from(NUMERIC_OPTIONS), text=values)
def test_numeric_option_takes_a_number_in_range_or_refuses(choice, text):
    tool, option, action = choice
    try:
        value = action.type(text)
    except argparse.ArgumentTypeError as exc:
        assert len(str(exc)) < 200
        return
    assert _in_bounds(value, action.type.bounds), (tool, option, text, value)


@settings(max_examples=60, deadline=None)
@given(choice=st.sampled_from(NUMERIC_OPTIONS), text=values)
def test_argparse_names_the_option_it_refuses(choice, text):
    tool, option, action = choice
    parser = importlib.import_module(f"radarodom.tools.{tool}").build_parser()
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            args = parser.parse_args([f"{option}={text}"])
    except SystemExit as exc:  # a refused value, or a missing positional argument
        assert exc.code == 2
        try:
            action.type(text)
        except argparse.ArgumentTypeError:
            assert f"argument {option}" in err.getvalue()
        return
    assert _in_bounds(getattr(args, action.dest), action.type.bounds)


@pytest.fixture(scope="module")
def cfg_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("cfg") / "small.cfg"
    path.write_text(SMALL_CFG)
    return path


def _strict(text: str):
    return json.loads(text, parse_constant=lambda c: pytest.fail(f"{c} is not JSON"))


@settings(max_examples=120, deadline=None)
@given(text=values, as_json=st.booleans())
def test_radar_cfg_packet_delay_exits_0_or_2_and_prints_strict_json(cfg_path, text, as_json):
    out, err = io.StringIO(), io.StringIO()
    argv = [str(cfg_path), f"--packet-delay-us={text}"] + (["--json"] if as_json else [])
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = radar_cfg.main(argv)
    assert code in (0, 2), err.getvalue()
    assert "internal error" not in err.getvalue() and "Traceback" not in err.getvalue()
    if code == 2:
        assert out.getvalue() == "" and "--packet-delay-us" in err.getvalue()
        return
    if as_json:
        data = _strict(out.getvalue())
        assert 5 <= data["packet_delay_us"] <= 500
        assert all(math.isfinite(v) for v in data.values() if isinstance(v, float))


def test_cli_types_take_plain_numbers_at_their_bounds():
    assert cli.positive_int("1") == 1 and cli.non_negative_int("0") == 0
    assert cli.positive_float("1e9") == 1e9 and cli.port("65535") == 65535
    assert cli.probability("0") == 0.0 and cli.probability("1") == 1.0
    assert cli.boresight_angle("90") == 90.0 and cli.ros2_domain("232") == 232
    for parse, text in ((cli.positive_int, "0"), (cli.positive_float, "0"), (cli.positive_float, "1.1e9"),
                        (cli.port, "65536"), (cli.ros2_domain, "233"), (cli.boresight_angle, "0")):
        with pytest.raises(argparse.ArgumentTypeError):
            parse(text)


def test_leading_zeros_and_signs_are_read_as_plain_int_reads_them():
    """A seed of 37 digits, most of them leading zeros, was refused as no whole number >= 0; two
    plus signs were told the range, as if they made a number too large."""
    seed = cli.int_in(0, what="a whole number")
    assert seed("0" * 36 + "5") == 5 and seed("+0" + "0" * 40) == 0
    with pytest.raises(argparse.ArgumentTypeError) as err:
        seed("++" + "9" * 25)
    assert "expected a whole number >= 0" in str(err.value)
    with pytest.raises(argparse.ArgumentTypeError) as err:
        seed("0" * 5000 + "9" * 25)
    assert "in 0..9223372036854775807" in str(err.value)
