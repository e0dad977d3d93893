"""The fields of TI mmWave CLI commands: how each is described, read and written back.

A command is a frozen dataclass whose fields are its CLI arguments in order; each field's
metadata (:func:`arg`) gives TI's name for it, its unit and the values the firmware accepts.
:func:`parse_fields` reads the tokens of a line into such a dataclass and refuses, naming the
field, anything the radar would read differently from what the text says: Python's ``int`` and
``float`` take ``1_0``, non-ASCII digits, ``nan`` and ``1e999``, the firmware's ``atoi``/``atof``
do not (or read them as something else), so tokens are matched against the radar's number
syntax before they are converted.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import field
from typing import Any, Sequence

from .errors import ConfigError, quoted
from .plain_numbers import FLOAT_TEXT, INT_TEXT

#: The only sub-frame index the legacy (non-advanced) frame accepts.
LEGACY_SUBFRAME = -1

#: Characters of user input a message quotes; longer input is cut with its length said.
SHOWN_CHARS = 40

#: Hexadecimal as the firmware's ``sscanf("0x%x")`` reads it (calibData's flash offset), 32 bit.
_HEX_TOKEN = re.compile(r"0x[0-9a-fA-F]{1,8}\Z")


def shown(text: str, limit: int = SHOWN_CHARS) -> str:
    """*text* quoted for a message (:func:`radarodom.errors.quoted`)."""
    return quoted(text, limit)


def arg(
    ti_name: str,
    *,
    unit: str | None = None,
    lo: float | None = None,
    hi: float | None = None,
    choices: Sequence[int] | None = None,
    syntax: str | None = None,
) -> Any:
    """Describe one CLI argument: TI's name, unit, accepted values, and (``"hex"``) a syntax
    other than the decimal number its type implies."""
    return field(metadata={"ti_name": ti_name, "unit": unit, "lo": lo, "hi": hi, "choices": choices,
                           "syntax": syntax})


def subframe_arg() -> Any:
    return arg("subFrameIdx", choices=(LEGACY_SUBFRAME,))


def flag_arg(ti_name: str) -> Any:
    """An on/off argument (0 or 1)."""
    return arg(ti_name, choices=(0, 1))


def convert(token: str, kind: type, syntax: str | None = None) -> int | float:
    """One CLI token as int or float; raises ValueError with a reason."""
    if syntax == "hex":
        if token == "0":
            return 0
        if not _HEX_TOKEN.match(token):
            raise ValueError(f"expected 0 or a hexadecimal number 0x0..0xFFFFFFFF, got {shown(token)}")
        return int(token, 16)
    if kind is int:
        if not INT_TEXT.match(token):
            raise ValueError(f"expected an integer, got {shown(token)}")
        try:
            return int(token, 10)
        except ValueError:  # more digits than Python converts
            raise ValueError(f"integer too large: {shown(token, 20)}") from None
    if not FLOAT_TEXT.match(token):
        if token.lower().lstrip("+-") in ("nan", "inf", "infinity"):
            raise ValueError(f"expected a finite number, got {shown(token)}")
        raise ValueError(f"expected a number, got {shown(token)}")
    value = float(token)
    if not math.isfinite(value):
        raise ValueError(f"expected a finite number, got {shown(token)}")
    return value


def check_range(value: float, meta: dict) -> None:
    """ValueError unless *value* is one of the field's choices and inside its lo..hi."""
    choices = meta.get("choices")
    if choices is not None and value not in choices:
        raise ValueError(f"{_number(value)} is not one of {', '.join(map(str, choices))}")
    lo, hi = meta.get("lo"), meta.get("hi")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        unit = f" {meta['unit']}" if meta.get("unit") else ""
        raise ValueError(f"{_number(value)} is outside {lo:g}..{hi:g}{unit}")


def _number(value: float) -> str:
    """A checked value in a message: a float as its repr (the digits the user wrote), an integer
    in full unless it is longer than a message should be."""
    text = repr(value)
    return text if len(text) <= SHOWN_CHARS else f"{text[:20]}... ({len(text)} digits)"


def field_kind(fld: dataclasses.Field) -> type:
    return int if fld.type in ("int", int) else float


def parse_fields(cls: type, tokens: Sequence[str], fail) -> Any:
    """The dataclass *cls* from one token per field, every token checked for syntax and range;
    *fail(message, field)* builds the error to raise."""
    fields = dataclasses.fields(cls)
    if len(tokens) != len(fields):
        names = " ".join(f.metadata["ti_name"].split()[0] for f in fields)
        raise fail(f"expected {len(fields)} arguments ({names}), got {len(tokens)}", None)
    values = []
    for fld, token in zip(fields, tokens):
        meta = fld.metadata
        try:
            value = convert(token, field_kind(fld), meta.get("syntax"))
            check_range(value, meta)
        except ValueError as exc:
            raise fail(str(exc), meta["ti_name"]) from None
        values.append(value)
    return cls(*values)


def format_number(value: float) -> str:
    """Shortest text that parses back to exactly *value* (``77``, ``57.14``)."""
    if isinstance(value, int):
        return str(value)
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def format_fields(command: Any) -> tuple[str, ...]:
    """The CLI tokens of a command dataclass (inverse of :func:`parse_fields`)."""
    out = []
    for fld in dataclasses.fields(command):
        value = getattr(command, fld.name)
        out.append(hex(value) if fld.metadata.get("syntax") == "hex" and value else format_number(value))
    return tuple(out)


def config_error(path, line, command):
    """A *fail* for :func:`parse_fields` that raises :class:`ConfigError` at file:line: command."""
    def fail(message: str, fld: str | None) -> ConfigError:
        return ConfigError(message, path=path, line=line, command=command, field=fld)
    return fail
