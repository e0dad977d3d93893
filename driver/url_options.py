"""The query options of a source URL (``scheme://path?name=value&...``) and the converters a
backend takes them with: each backend declares what it takes through :class:`UrlOptions`, so an
unknown or malformed option is one :class:`~radarodom.errors.SourceError` naming the URL, the
option and what it takes (:mod:`.sources` opens the URL)."""

from __future__ import annotations

from typing import Any, Callable
from urllib.parse import parse_qsl

from ..errors import SourceError, quoted
from ..plain_numbers import MAX_WHOLE_OPTION, plain_float, plain_int, whole_beyond

#: Largest number a URL option takes (seconds, factors, microseconds): far beyond any meant,
#: small enough that arithmetic on it stays finite.
MAX_URL_NUMBER = 1e9

#: Slowest ``rate=`` a source streams at: a thousandth of real time (a 10 Hz stream's frame every
#: 100 s); slower is a typing slip (``rate=1e-9`` would wait years for its second frame).
MIN_RATE = 1e-3


#: What every source's ``rate=`` option says it takes (:func:`parse_rate`).
RATE_EXPECTED = "max, or a speed factor (1: real time)"


def parse_rate(text: str) -> float:
    """A ``rate=`` option: a speed factor from :data:`MIN_RATE`, or ``max`` (infinite)."""
    if text == "max":
        return float("inf")
    value = positive_number(text)
    if value < MIN_RATE:
        raise ValueError(text)
    return value


def at_least(minimum: int) -> Callable[[str], int]:
    """A ``UrlOptions.take`` converter: a whole number from *minimum* to :data:`MAX_WHOLE_OPTION`
    (the limit said only when it is what is wrong)."""
    return _whole(minimum, MAX_WHOLE_OPTION, None)


def whole_in(lo: int, hi: int) -> Callable[[str], int]:
    """A ``UrlOptions.take`` converter: a whole number from *lo* to *hi*."""
    return _whole(lo, hi, f"from {lo} to {hi}")


def _whole(lo: int, hi: int, limit: str | None) -> Callable[[str], int]:
    def convert(text: str) -> int:
        beyond = whole_beyond(text, hi)
        value = None if beyond else plain_int(text)
        if value is None or not lo <= value <= hi:
            raise ValueError(text, limit or (f"at most {hi}" if beyond else ""))
        return value
    return convert


def positive_number(text: str) -> float:
    """A ``UrlOptions.take`` converter: a plain decimal number > 0 and at most
    :data:`MAX_URL_NUMBER`."""
    value = plain_float(text)
    if value is None or not 0 < value <= MAX_URL_NUMBER:
        raise ValueError(text)
    return value


positive_number.limit = f"at most {MAX_URL_NUMBER:g}"  # type: ignore[attr-defined]
parse_rate.limit = f"from {MIN_RATE:g} to {MAX_URL_NUMBER:g}"  # type: ignore[attr-defined]


def number_in(lo: float, hi: float) -> Callable[[str], float]:
    """A ``UrlOptions.take`` converter: a plain decimal number from *lo* to *hi*."""
    def convert(text: str) -> float:
        value = plain_float(text)
        if value is None or not lo <= value <= hi:
            raise ValueError(text)
        return value
    convert.limit = f"from {lo:g} to {hi:g}"  # type: ignore[attr-defined]
    return convert


def udp_port(text: str) -> int:
    """A ``UrlOptions.take`` converter: 0..65535 (0: any free port)."""
    value = plain_int(text)
    if value is None or not 0 <= value <= 65535:
        raise ValueError(text)
    return value


def given_text(text: str) -> str:
    """A ``UrlOptions.take`` converter: a path, a port or an address, not empty (``calib=``)."""
    if not text.strip():
        raise ValueError(text)
    return text


given_text.words = True  # type: ignore[attr-defined]


def one_of(*choices: str) -> Callable[[str], str]:
    """A ``UrlOptions.take`` converter: one of *choices*."""
    def convert(text: str) -> str:
        if text not in choices:
            raise ValueError(text)
        return text
    convert.words = True  # type: ignore[attr-defined]  # a word, not a number: the error says no more
    return convert


class UrlOptions:
    """The query options of a source URL, taken one by one by the backend."""

    def __init__(self, url: str, query: str) -> None:
        self.url = url
        self._values: dict[str, str] = {}
        for key, value in parse_qsl(query, keep_blank_values=True, strict_parsing=False):
            if key in self._values:
                raise SourceError(f"{url}: option {key!r} given twice")
            self._values[key] = value
        self._supported: list[str] = []

    def take(self, name: str, convert: Callable[[str], Any], default: Any, expect: str) -> Any:
        """Remove option *name* and convert it; *expect* says what it must be."""
        self._supported.append(f"{name}={expect}")
        if name not in self._values:
            return default
        text = self._values.pop(name)
        try:
            return convert(text)
        except (ValueError, TypeError) as exc:
            limit = exc.args[1] if len(exc.args) > 1 else getattr(convert, "limit", "")
            # (the hint only where the text is no plain number: '-1' or '1.5' is one, out of range)
            plain = getattr(convert, "words", False) or plain_float(text) is not None
            how = "" if plain else ", written as a plain decimal number"
            raise SourceError(f"{self.url}: option {name}={quoted(text)}: expected {expect}"
                              + (f" ({limit})" if limit else "") + how) from None

    def finish(self) -> None:
        """Raise if the URL had options no backend took."""
        if "" in self._values:  # "?=3": a value with no name to put it to
            raise SourceError(f"{self.url}: an option without a name ({'=' + self._values['']!r}); give "
                              f"NAME=VALUE, one of {', '.join(self._supported) or 'none'}")
        if self._values:
            names = ", ".join(sorted(self._values))
            raise SourceError(f"{self.url}: unknown option(s) {names}; supported: "
                              f"{', '.join(self._supported) or 'none'}")
