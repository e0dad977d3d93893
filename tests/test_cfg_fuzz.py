"""Property-based robustness of the cfg parser: whatever text or bytes it is
given, :class:`RadarConfig` either builds a sound config or raises
:class:`ConfigError` -- never any other exception."""

from __future__ import annotations

import dataclasses
import math

from conftest import REPO, SMALL_CFG
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from radarodom import cfg_commands as cc
from radarodom.cfg import RadarConfig
from radarodom.errors import ConfigError

SHIPPED_CFG = (REPO / "configs" / "awr1843_raw.cfg").read_text(encoding="utf-8")
BASES = (SMALL_CFG, SHIPPED_CFG)

SPECIAL_TOKENS = (
    "nan", "NaN", "inf", "-inf", "Infinity", "1e999", "-1e999", "1e-999", "", "-", "+", ".", "0x10",
    "1_0", "\u0661\u0662", "\uff11", "-0", "+0", "1.", ".5", "-1", "1e308", "4.9e-324",
    "9" * 5000, "1" + "0" * 400, "-" + "9" * 4300, "\u00b5", "\U0001f4e1", "%", "\x00", "\ufeff",
    "\u2028", "\x0c", "\r", "\t", "chirpCfg", "sensorStart", "profileCfg", "bpmCfg",
    # issue 18: what reached the radar unchecked
    "None", "1,5", "\u00e9", "\u00a0", "5\u00a05", "0x1F0000", "0X10", "1e308", "-1e308", "x" * 3000,
)
#: Every command the radar can be sent, for random lines.
COMMAND_NAMES = sorted({*cc.TYPED_COMMANDS, *cc.VERBATIM_COMMANDS, *cc.UNSUPPORTED_COMMANDS, "fancyCmd"})

tokens = st.one_of(
    st.sampled_from(SPECIAL_TOKENS),
    st.integers(-3, 600).map(str),  # near the valid ranges: keeps many configs valid
    st.integers().map(str),  # arbitrarily large ints
    st.integers(min_value=-(10**40), max_value=10**40).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(min_value=-100, max_value=100).map(lambda x: f"{x:.3f}"),
    st.text(max_size=8),
)
junk = st.one_of(st.text(max_size=12), st.binary(max_size=12).map(lambda b: b.decode("latin-1")))


@st.composite
def mutated_cfg(draw) -> str:
    lines = draw(st.sampled_from(BASES)).splitlines()
    for _ in range(draw(st.integers(0, 5))):
        if not lines:
            lines = [draw(junk)]
        i = draw(st.integers(0, len(lines) - 1))
        op = draw(st.sampled_from(["delete", "duplicate", "swap", "token", "token", "token",
                                   "insert_token", "drop_token", "junk_in_line", "junk_line", "command_line"]))
        if op == "delete":
            del lines[i]
        elif op == "duplicate":
            lines.insert(draw(st.integers(0, len(lines))), lines[i])
        elif op == "swap":
            j = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        elif op in ("token", "insert_token", "drop_token"):
            toks = lines[i].split(" ")
            k = draw(st.integers(0, len(toks) - 1))
            if op == "token":
                toks[k] = draw(tokens)
            elif op == "insert_token":
                toks.insert(k, draw(tokens))
            else:
                del toks[k]
            lines[i] = " ".join(toks)
        elif op == "junk_in_line":
            pos = draw(st.integers(0, len(lines[i])))
            lines[i] = lines[i][:pos] + draw(junk) + lines[i][pos:]
        elif op == "command_line":
            args = draw(st.lists(tokens, max_size=26))
            lines.insert(i, " ".join([draw(st.sampled_from(COMMAND_NAMES)), *args]))
        else:
            lines.insert(i, draw(junk))
    text = draw(st.sampled_from(["\n", "\r\n"])).join(lines) + "\n"
    if draw(st.integers(0, 9)) == 0:
        text = text[: draw(st.integers(0, len(text)))]
    return text


def _check_fields_in_range(cfg: RadarConfig) -> None:
    """Every typed or checked field of an accepted config is a finite number its field takes."""
    for ln in cfg.commands():
        if ln.value is None or isinstance(ln.value, cc.CompRangeBiasAndRxChanPhase):
            continue
        for fld in dataclasses.fields(ln.value):
            value, meta = getattr(ln.value, fld.name), fld.metadata
            assert isinstance(value, (int, float)) and math.isfinite(value), (ln, fld.name)
            if meta.get("choices") is not None:
                assert value in meta["choices"], (ln, fld.name)
            if meta.get("lo") is not None:
                assert meta["lo"] <= value <= meta["hi"], (ln, fld.name)


def _check_sound(cfg: RadarConfig) -> None:
    """A config that was accepted: finite physics, consistent layout, round trip."""
    summary = cfg.summary()
    for key, value in summary.items():
        if isinstance(value, float):
            assert math.isfinite(value), (key, value)
    for name in ("range_resolution_m", "max_range_m", "max_velocity_mps", "velocity_resolution_mps",
                 "wavelength_m", "frame_period_s", "chirp_time_s", "active_frame_time_s"):
        assert summary.get(name, getattr(cfg, name)) > 0, name
    assert 0 < cfg.duty_cycle <= 1 + 1e-9
    assert cfg.frame_bytes == cfg.num_chirps_per_frame * cfg.num_rx * cfg.num_samples * 4
    assert len(cfg.tx_order) == cfg.num_tx_slots
    _check_fields_in_range(cfg)
    again = RadarConfig.from_text(cfg.to_text())
    assert again == cfg
    assert again.to_text() == cfg.to_text()
    assert again.summary() == summary


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_cfg())
def test_mutated_text_parses_or_raises_config_error(text):
    try:
        cfg = RadarConfig.from_text(text, "fuzz.cfg")
    except ConfigError as exc:
        event("ConfigError")
        assert str(exc).startswith("fuzz.cfg")
        assert len(str(exc)) < 400, "echoed input is cut"
        return
    event("accepted")
    _check_sound(cfg)


@settings(max_examples=150, deadline=None)
@given(data=st.one_of(
    st.binary(max_size=300),
    mutated_cfg().flatmap(lambda t: st.tuples(st.just(t.encode("utf-8", "surrogatepass")),
                                              st.integers(0, 40), st.binary(max_size=4))).map(
        lambda x: x[0][: x[1] * 20] + x[2] + x[0][x[1] * 20:]),
))
def test_random_bytes_from_file_raise_only_config_error(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("fuzz") / "random.cfg"
    path.write_bytes(data)
    try:
        cfg = RadarConfig.from_file(path)
    except ConfigError as exc:
        assert str(exc).startswith(str(path))
        return
    _check_sound(cfg)


#: Lines the radar can receive beyond the shipped cfg's, each valid as written.
EXTRA_LINES = ("bpmCfg -1 0 0 0", "configDataPort 921600 1", "calibData 0 1 0x1F0000", "idlePowerCycle 0 1")


@st.composite
def hostile_field_cfg(draw) -> tuple[str, int]:
    """The shipped cfg (and EXTRA_LINES) with one argument of one command replaced by a hostile
    token; returns (text, 1-based number of the edited line)."""
    lines = SHIPPED_CFG.splitlines()
    at = lines.index("sensorStart")
    lines[at:at] = list(EXTRA_LINES)
    commands = [i for i, ln in enumerate(lines) if ln and not ln.startswith("%") and len(ln.split()) > 1]
    i = draw(st.sampled_from(commands))
    toks = lines[i].split(" ")
    k = draw(st.integers(1, len(toks) - 1))
    toks[k] = draw(st.one_of(st.sampled_from(SPECIAL_TOKENS), tokens))
    lines[i] = " ".join(toks)
    return "\n".join(lines) + "\n", i + 1


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(hostile_field_cfg())
def test_hostile_token_in_any_field_is_refused_at_its_line_or_is_a_number_it_takes(case):
    text, lineno = case
    try:
        cfg = RadarConfig.from_text(text, "fuzz.cfg")
    except ConfigError as exc:
        event("ConfigError")
        # At the edited line, or where another line stops agreeing with it.
        assert exc.path == "fuzz.cfg" and (exc.line is None or 1 <= exc.line <= text.count("\n"))
        assert exc.line == lineno or exc.field is not None or exc.line is None, str(exc)
        assert len(str(exc)) < 400, "echoed input is cut"
        return
    event("accepted")
    _check_sound(cfg)
