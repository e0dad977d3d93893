"""Property-based robustness of the cfg parser: whatever text or bytes it is
given, :class:`RadarConfig` either builds a sound config or raises
:class:`ConfigError` -- never any other exception."""

from __future__ import annotations

import math

from conftest import REPO, SMALL_CFG
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from radarodom.cfg import RadarConfig
from radarodom.errors import ConfigError

SHIPPED_CFG = (REPO / "configs" / "awr1843_raw.cfg").read_text(encoding="utf-8")
BASES = (SMALL_CFG, SHIPPED_CFG)

SPECIAL_TOKENS = (
    "nan", "NaN", "inf", "-inf", "Infinity", "1e999", "-1e999", "1e-999", "", "-", "+", ".", "0x10",
    "1_0", "\u0661\u0662", "\uff11", "-0", "+0", "1.", ".5", "-1", "1e308", "4.9e-324",
    "9" * 5000, "1" + "0" * 400, "-" + "9" * 4300, "\u00b5", "\U0001f4e1", "%", "\x00", "\ufeff",
    "\u2028", "\x0c", "\r", "\t", "chirpCfg", "sensorStart", "profileCfg", "bpmCfg",
)

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
                                   "insert_token", "drop_token", "junk_in_line", "junk_line"]))
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
        else:
            lines.insert(i, draw(junk))
    text = draw(st.sampled_from(["\n", "\r\n"])).join(lines) + "\n"
    if draw(st.integers(0, 9)) == 0:
        text = text[: draw(st.integers(0, len(text)))]
    return text


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
