"""radarodom.strict_json: bounded reading and standard writing of JSON, fuzzed."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from radarodom import strict_json


@pytest.mark.parametrize("text, words", [
    ("[" * 1000, "nested 1000 deep"),
    ('{"a":' * 40 + "1" + "}" * 40, "nested 40 deep"),
    ('{"t": NaN}', "NaN is not a number"),
    ('{"t": -Infinity}', "-Infinity is not a number"),
    ('{"t": 1e999}', "out of range"),
    ("[1, 2", "not JSON"),
    (b"\xff\xfe", "not UTF-8"),
    ("x" * 2000, "more than 1024 bytes, the most allowed"),
    ('{"icp": {"a": 1}, "icp": {"b": 2}}', "the key 'icp' appears twice in one object"),  # json kept the last
    ('[{"t": 1, "x": 2, "t": 3}]', "the key 't' appears twice"),
])
def test_hostile_text_is_refused_with_the_reason(text, words):
    with pytest.raises(ValueError, match=words):
        strict_json.loads(text, max_bytes=1024)


def test_a_5000_digit_integer_is_refused_in_our_words():
    """Python's json says "use sys.set_int_max_str_digits() to increase the limit"."""
    for text, digits in (("9" * 5000, 5000), ("[-" + "9" * 5000 + "]", 5000), ('{"a": ' + "1" * 4301 + "}", 4301)):
        with pytest.raises(ValueError) as info:
            strict_json.loads(text, max_bytes=10_000)
        assert str(info.value) == f"an integer of {digits} digits, more than the 4300 allowed"
    assert strict_json.loads("-" + "9" * 4300, max_bytes=10_000) == -int("9" * 4300)


@pytest.mark.parametrize("text, bad", [
    (r'"\ud800"', "'\\ud800'"), (r'["a", {"k": "x\udfffy"}]', "'x\\udfffy'"), (r'{"\udc00": 1}', "'\\udc00'"),
    (r'"\ude00\ud83d"', "'\\ude00\\ud83d'")])
def test_a_lone_surrogate_is_refused(text, bad):
    """A \\u escape of half a surrogate pair is no Unicode text; strict parsers refuse it."""
    with pytest.raises(ValueError) as info:
        strict_json.loads(text, max_bytes=100)
    assert str(info.value).startswith(f"the string {bad} holds a lone surrogate, U+D"), str(info.value)


def test_surrogate_pairs_and_escaped_backslashes_are_fine():
    assert strict_json.loads(r'["\ud83d\ude00", "\\ud800", "\\\ud83d\ude00"]', max_bytes=100) == [
        "\U0001F600", "\\ud800", "\\\U0001F600"]


def test_brackets_inside_strings_do_not_count():
    text = json.dumps({"s": "[" * 500 + '\\"{' * 100})
    assert strict_json.nesting_depth(text) == 1
    assert strict_json.loads(text, max_bytes=10_000)["s"].startswith("[[[")


def test_writing_gives_standard_json():
    obj = {"a": math.nan, "b": [np.float32(1.5), np.inf, np.int64(3)], "c": np.array([[1.0, -np.inf]]),
           "d": (np.bool_(True), None), 4: "x"}
    text = strict_json.dumps(obj)
    assert json.loads(text, parse_constant=lambda c: pytest.fail(c)) == {
        "a": None, "b": [1.5, None, 3], "c": [[1.0, None]], "d": [True, None], "4": "x"}


#: JSON-ish text with \\u escapes of surrogates and long digit runs among its pieces.
JSONISH = st.lists(st.sampled_from(['"', "\\", "\\ud800", "\\udc00", "\\ud83d\\ude00", "\\u0041", "[", "]", "{", "}",
                                    ":", ",", "1", "-", "9" * 4301, "a", " "]), max_size=40).map("".join)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300) | st.text(max_size=300) | JSONISH)
def test_any_input_is_a_value_or_a_value_error(data):
    try:
        value = strict_json.loads(data, max_bytes=20_000, max_depth=8)
    except ValueError as exc:
        assert "sys." not in str(exc) and len(str(exc)) < 200, str(exc)
        return
    # What it returns is standard JSON again, and Unicode text.
    json.dumps(value, allow_nan=False, ensure_ascii=False).encode("utf-8")


@settings(max_examples=200, deadline=None)
@given(st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=5),
                    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=4), inner, max_size=4),
                    max_leaves=20))
def test_whatever_is_written_reads_back(obj):
    text = strict_json.dumps(obj)
    assert strict_json.loads(text, max_bytes=10**6, max_depth=64) == strict_json.finite(obj)


def test_a_byte_order_mark_is_ignored():
    # Windows editors write one; json.loads said "Unexpected UTF-8 BOM (decode using utf-8-sig)".
    assert strict_json.loads(b'\xef\xbb\xbf{"a": [1]}', max_bytes=100) == {"a": [1]}
    assert strict_json.loads('\ufeff{"a": null}', max_bytes=100) == {"a": None}
