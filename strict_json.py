"""JSON read from anyone and written for anyone: bounded on the way in, standard on the way out.

Python's :mod:`json` accepts what the standard does not (``NaN``, ``Infinity``, and ``1e999``,
which it reads as infinity), writes them back out, and recurses once per nesting level, so a
payload of a thousand ``[`` ends in a ``RecursionError``.  :func:`loads` bounds the size and the
nesting before it parses and refuses every non-finite number; :func:`dumps` writes only
standard JSON (a non-finite number becomes ``null``, numpy scalars and arrays plain numbers and
lists).  Both raise :class:`ValueError` with a message that says what is wrong; callers turn it
into the error of what they read (a message, a capture's metadata, a settings file).
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

#: Nesting deeper than this is refused before parsing (radarodom's own documents nest 4 deep).
MAX_DEPTH = 32


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"the number {text[:40]} is out of range")
    return value


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


def loads(data: bytes | bytearray | memoryview | str, *, max_bytes: int, max_depth: int = MAX_DEPTH) -> Any:
    """The JSON value in *data* (UTF-8 bytes or text): at most *max_bytes* long and *max_depth*
    deep, every number finite.  Raises :class:`ValueError` saying which bound or rule failed."""
    size = len(data)
    if size > max_bytes:
        raise ValueError(f"{size} bytes, more than the {max_bytes} allowed")
    if isinstance(data, str):
        text = data
    else:
        try:
            text = bytes(data).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ValueError(f"not UTF-8 (byte {exc.start})") from None
    depth = nesting_depth(text)
    if depth > max_depth:
        raise ValueError(f"nested {depth} deep, more than the {max_depth} allowed")
    try:
        return json.loads(text, parse_constant=_no_constant, parse_float=_finite_float)
    except json.JSONDecodeError as exc:
        raise ValueError(f"not JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None


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


__all__ = ["MAX_DEPTH", "dumps", "finite", "loads", "nesting_depth"]
