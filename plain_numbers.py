"""Numbers as people and radar tools write them: plain ASCII decimal.

One syntax for every number radarodom reads from text: cfg fields, command-line options, source
URL options, timestamps.txt and the other text files.  Python's ``int()`` and ``float()`` also
take ``1_0``, non-ASCII digits, surrounding spaces, ``nan`` and ``inf``, which no cfg, option or
writer of these files means.  And the one test of a number given in Python (an API's argument, a
setting built in code): :func:`is_number`, :func:`is_whole_number`, a bool being neither.
"""

from __future__ import annotations

import math
import numbers
import re
from typing import Any

#: A whole number: decimal digits with an optional sign.
INT_TEXT = re.compile(r"[+-]?[0-9]+\Z")
#: A number: decimal digits with an optional sign, point and exponent.
FLOAT_TEXT = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")
#: More digits than this is no count, port or seed anyone means (and int() of thousands of
#: digits is slow).
MAX_INT_DIGITS = 30
#: The largest whole number an option takes (a command-line option's, a URL option's): a seed
#: recorded in a URL is then one radar-sim --seed takes too.
MAX_WHOLE_OPTION = 2**63 - 1


def plain_int(text: str) -> int | None:
    """*text* as an int when it is a plain whole number of at most :data:`MAX_INT_DIGITS`
    digits, else None."""
    if not INT_TEXT.match(text):
        return None
    digits = text.lstrip("+-").lstrip("0") or "0"  # leading zeros count for nothing
    if len(digits) > MAX_INT_DIGITS:
        return None
    return int(digits, 10) * (-1 if text.startswith("-") else 1)


def whole_beyond(text: str, hi: int) -> bool:
    """Whether *text* is a plain whole number (digits, however many) greater than *hi*: what a
    refusal then says is the range, not that it is no number."""
    if not re.fullmatch(r"\+?[0-9]+", text):  # one sign at most, as plain_int takes
        return False
    digits = text.lstrip("+").lstrip("0") or "0"
    return len(digits) > len(str(hi)) or int(digits) > hi


def plain_float(text: str) -> float | None:
    """*text* as a float when it is a plain decimal number, else None.  The value may still be
    infinite (``1e999``)."""
    return float(text) if FLOAT_TEXT.match(text) else None


def is_number(value: Any) -> bool:
    """Whether *value*, given in Python, is a number: any real (numpy's too), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def is_whole_number(value: Any) -> bool:
    """Whether *value*, given in Python, is a whole number: any integral (numpy's too), not a bool."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def finite_float(value: Any) -> float | None:
    """*value*, read from a file (JSON, TOML), as a float when it is a finite number (an int or a
    float, not a bool), else None: an integer of 309 digits or more is no float (float() overflows)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


def beyond_text(value: float, *bounds: float) -> str:
    """*value* as a message about the *bounds* it broke shows it: short (``%g``) unless that would
    round it onto one of them (100.00000000001 shown as 100 would not be beyond 100)."""
    short = f"{value:g}"
    return repr(value) if float(short) != value and float(short) in bounds else short


def time_text(t: float, decimals: int = 3) -> str:
    """A time in s as a message shows it: to *decimals* places (the millisecond), but in exponent
    form past some 30000 years (a file's time of 1e300 is not written out in 300 digits)."""
    return f"{t:.{decimals}f}" if abs(t) < 1e12 else f"{t:.{decimals + 6}g}"
