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
    ("x" * 2000, "2000 bytes"),
])
def test_hostile_text_is_refused_with_the_reason(text, words):
    with pytest.raises(ValueError, match=words):
        strict_json.loads(text, max_bytes=1024)


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


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300) | st.text(max_size=300))
def test_any_input_is_a_value_or_a_value_error(data):
    try:
        value = strict_json.loads(data, max_bytes=200, max_depth=8)
    except ValueError:
        return
    json.dumps(value, allow_nan=False)  # what it returns is standard JSON again


@settings(max_examples=200, deadline=None)
@given(st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=5),
                    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=4), inner, max_size=4),
                    max_leaves=20))
def test_whatever_is_written_reads_back(obj):
    text = strict_json.dumps(obj)
    assert strict_json.loads(text, max_bytes=10**6, max_depth=64) == strict_json.finite(obj)
