"""JSON read from anyone and written for anyone: bounded on the way in, standard on the way out.

Python's :mod:`json` accepts what the standard does not (``NaN``, ``Infinity``, ``1e999``, which
it reads as infinity, and a lone surrogate such as ``"\\ud800"``, which is no Unicode text),
writes them back out, recurses once per nesting level, so a payload of a thousand ``[`` ends in
a ``RecursionError``, and refuses an integer of over 4300 digits with a message about
``sys.set_int_max_str_digits``.  :func:`loads` bounds the size and the nesting before it
parses, and refuses every non-finite number, every integer of more than :data:`MAX_INT_DIGITS`
digits and every lone surrogate, each with a message of its own; :func:`dumps` writes only
standard JSON (a non-finite number becomes ``null``, numpy scalars and arrays plain numbers and
lists).  Both raise :class:`ValueError` with a message that says what is wrong; callers turn it
into the error of what they read (a message, a capture's metadata, a settings file).
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

import numpy as np

from .errors import quoted

#: Nesting deeper than this is refused before parsing (radarodom's own documents nest 4 deep).
MAX_DEPTH = 32
#: Digits an integer may have: Python's own default limit (beyond it int() refuses, advising a
#: programmer to call sys.set_int_max_str_digits), so that the message is ours.
MAX_INT_DIGITS = 4300
#: A \u escape of a surrogate code point: only where one is may a string hold a lone surrogate
#: (UTF-8 cannot carry one), so only then are the strings looked through.
_SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F]")


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"the number {text[:40]} is out of range")
    return value


def _plain_int(text: str) -> int:
    digits = len(text.lstrip("-"))
    if digits > MAX_INT_DIGITS:
        raise ValueError(f"an integer of {digits} digits, more than the {MAX_INT_DIGITS} allowed")
    return int(text)


def _lone_surrogate(obj: Any) -> str | None:
    """The first string (key or value) in *obj* holding a lone surrogate, or None."""
    if isinstance(obj, str):
        try:
            obj.encode("utf-8")
        except UnicodeEncodeError:
            return obj
        return None
    if isinstance(obj, dict):
        obj = [s for pair in obj.items() for s in pair]
    if isinstance(obj, list):
        for item in obj:
            found = _lone_surrogate(item)
            if found is not None:
                return found
    return None


def _no_constant(name: str) -> None:
    raise ValueError(f"{name} is not a number JSON allows")


def nesting_depth(text: str) -> int:
    """Deepest nesting of arrays and objects in *text* (brackets inside strings do not count);
    a linear scan that never recurses."""
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """An object whose keys are its own: a key given twice is refused (json takes the last one
    silently, so a settings file's second "icp" section would hide its first)."""
    obj = dict(pairs)
    if len(obj) < len(pairs):
        seen: set[str] = set()
        twice = next(key for key, _ in pairs if key in seen or seen.add(key))
        raise ValueError(f"the key {quoted(twice)} appears twice in one object")
    return obj


def loads(data: bytes | bytearray | memoryview | str, *, max_bytes: int, max_depth: int = MAX_DEPTH) -> Any:
    """The JSON value in *data* (UTF-8 bytes or text): at most *max_bytes* long and *max_depth*
    deep, every number finite, every integer at most :data:`MAX_INT_DIGITS` digits, every
    string Unicode text (no lone surrogate), no key twice in an object.  Raises
    :class:`ValueError` saying which bound or rule failed."""
    size = len(data)
    if size > max_bytes:
        raise ValueError(f"more than {max_bytes} bytes, the most allowed")  # callers read no more than one past it
    if isinstance(data, str):
        text = data.removeprefix("\ufeff")
    else:
        try:  # a byte-order mark (Windows editors write one) is ignored, as RFC 8259 allows
            text = bytes(data).decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise ValueError(f"not UTF-8 (byte {exc.start})") from None
    depth = nesting_depth(text)
    if depth > max_depth:
        raise ValueError(f"nested {depth} deep, more than the {max_depth} allowed")
    try:
        value = json.loads(text, parse_constant=_no_constant, parse_float=_finite_float, parse_int=_plain_int,
                           object_pairs_hook=_unique_keys)
    except json.JSONDecodeError as exc:
        raise ValueError(f"not JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
    if _SURROGATE_ESCAPE.search(text):
        bad = _lone_surrogate(value)
        if bad is not None:
            where = next(i for i, ch in enumerate(bad) if 0xD800 <= ord(ch) <= 0xDFFF)
            raise ValueError(f"the string {quoted(bad)} holds a lone surrogate, U+{ord(bad[where]):04X} at "
                             f"character {where + 1}: not Unicode text")
    return value


def finite(obj: Any) -> Any:
    """*obj* as plain JSON values: numpy scalars and arrays as numbers and lists, tuples as lists,
    every non-finite float as None (JSON has no NaN or infinity)."""
    if isinstance(obj, dict):
        return {str(k): finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return finite(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        value = float(obj)
        return value if math.isfinite(value) else None
    return obj


def dumps(obj: Any, **kwargs: Any) -> str:
    """Standard JSON text of *obj* (:func:`finite` first); *kwargs* as :func:`json.dumps`'s."""
    return json.dumps(finite(obj), allow_nan=False, **kwargs)


__all__ = ["MAX_DEPTH", "MAX_INT_DIGITS", "dumps", "finite", "loads", "nesting_depth"]
