"""A cfg file as text: read with a size bound, split into lines and tokens the way the radar's
CLI splits them, and the warnings about its lines summarised.

The radar's CLI reads ASCII: only CR/LF end a line, only spaces and tabs separate arguments.
Python's ``str.split`` and ``splitlines`` also split at no-break spaces, form feeds and Unicode
line separators, so a line the radar reads as one garbled token would parse here as clean
numbers; such characters are refused with the line and column.
"""

from __future__ import annotations

import codecs
import logging
import re
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any

from .errors import ConfigError, given_path, named_character

#: Largest cfg file read.  A cfg is a few KB; anything this large is another file.
MAX_CFG_BYTES = 1 << 20
#: Warnings of one kind shown in full before the rest are counted.
WARNINGS_SHOWN = 5

_LINE_END = re.compile(r"\r\n|\r|\n")
_LINE_END_BYTES = re.compile(rb"(\r\n|\r|\n)")
_SEPARATORS = re.compile(r"[ \t]+")
#: Anything but printable ASCII and tab: only these need a closer look.
_NOT_PLAIN = re.compile(r"[^ -~\t]")


@dataclass(frozen=True)
class CfgLine:
    """One line of a cfg file: a command, a ``%`` comment, or a blank line.

    Two configurations are equal when their lines are; the line number is
    where the line came from and does not take part.
    """

    kind: str  # "command", "comment" or "blank"
    #: Command name, or the whole comment text (with its ``%``).
    text: str = ""
    #: Argument tokens exactly as written.
    args: tuple[str, ...] = ()
    #: The typed command object for typed and checked commands, else None.
    value: Any = field(default=None, compare=False)
    line: int | None = field(default=None, compare=False)

    def __str__(self) -> str:
        return " ".join((self.text, *self.args)) if self.kind == "command" else self.text


def read_cfg_file(path: Any) -> tuple[str, str]:
    """(the path as text, the file's text): at most :data:`MAX_CFG_BYTES`, UTF-8 (a leading BOM
    dropped).  Every failure, a bad path included, is a :class:`ConfigError` naming the file."""
    where = given_path(path, ConfigError)
    try:
        with open(where, "rb") as fh:
            data = fh.read(MAX_CFG_BYTES + 1)
    except OSError as exc:
        hint = "; for standard input give /dev/stdin" if where == "-" else ""
        raise ConfigError(f"cannot read the file: {exc.strerror or exc}{hint}", path=where) from None
    if len(data) > MAX_CFG_BYTES:
        raise ConfigError(f"larger than {MAX_CFG_BYTES // (1 << 20)} MiB, the most a cfg is read to "
                          f"(a cfg is a few KB): not a radar configuration?", path=where)
    data = data.removeprefix(codecs.BOM_UTF8)  # Windows editors save one
    wide = _wide_encoding(data)
    if wide:
        raise ConfigError(f"{wide} text (as some Windows editors save it): save it as UTF-8 or ASCII", path=where)
    # Split at CR, LF or CRLF, as the radar and tokenize do, keeping the ends so the text is unchanged.
    pieces = _LINE_END_BYTES.split(data)
    for index in range(0, len(pieces), 2):
        line = pieces[index]
        try:
            pieces[index] = line.decode("utf-8")
        except UnicodeDecodeError as exc:
            if line.lstrip(b" \t").startswith(b"%"):  # a comment in another encoding (Latin-1): never sent
                pieces[index] = line.decode("latin-1")
                continue
            column = len(line[:exc.start].decode("utf-8")) + 1
            raise ConfigError(f"column {column}: byte 0x{line[exc.start]:02X} is not UTF-8 text: save the "
                              "file as UTF-8 or ASCII (commands are plain ASCII)", path=where,
                              line=index // 2 + 1) from None
    return where, "".join(piece if isinstance(piece, str) else piece.decode("ascii") for piece in pieces)


def _wide_encoding(data: bytes) -> str | None:
    """"UTF-32" or "UTF-16" if *data* looks like it (its byte order mark, or text that is mostly
    ASCII, whose wide form has zero bytes in fixed places), else None."""
    if data.startswith((codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE)):
        return "UTF-32"
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return "UTF-16"
    head = data[:256]
    if len(head) < 4:
        return None

    def mostly_zero(step: int, start: int) -> bool:
        picked = head[start::step]
        return picked.count(0) >= 0.9 * len(picked)

    if any(mostly_zero(4, k) and mostly_zero(4, (k + 1) % 4) and mostly_zero(4, (k + 2) % 4) for k in range(4)):
        return "UTF-32"
    return "UTF-16" if mostly_zero(2, 0) or mostly_zero(2, 1) else None


def _bad_character(stripped: str) -> tuple[int, str] | None:
    """(column, name) of the first character in a command line the radar would not read as
    written: a control character or a space other than ASCII space and tab."""
    first = _NOT_PLAIN.search(stripped)
    if first is None:
        return None
    for col, ch in enumerate(stripped[first.start():], start=first.start() + 1):
        if ch in " \t" or (ch.isprintable() and not ch.isspace()):
            continue
        return col, named_character(ch)
    return None


def tokenize(text: str, path: str) -> list[CfgLine]:
    """The lines of *text*, commands split into name and argument tokens."""
    lines: list[CfgLine] = []
    pieces = _LINE_END.split(text.removeprefix("\ufeff"))
    if pieces and pieces[-1] == "":
        pieces.pop()
    for lineno, raw in enumerate(pieces, start=1):
        stripped = raw.strip(" \t")
        if not stripped:
            lines.append(CfgLine("blank", line=lineno))
        elif stripped.startswith("%"):
            lines.append(CfgLine("comment", stripped, line=lineno))
        else:
            bad = _bad_character(stripped)
            if bad is not None:
                col, what = bad
                raise ConfigError(f"column {col}: character {what}: only ASCII spaces and tabs "
                                  f"separate arguments, and the radar reads printable characters only",
                                  path=path, line=lineno)
            name, *args = _SEPARATORS.split(stripped)
            lines.append(CfgLine("command", name, tuple(args), line=lineno))
    return lines


class WarningSummary:
    """Warnings about cfg lines, grouped by kind: the first few of each kind logged in full,
    the rest counted in one line, so a file of repeated mistakes gives a readable log."""

    def __init__(self, logger: logging.Logger, path: str) -> None:
        self._log = logger
        self._path = path
        self._by_kind: dict[str, list[tuple[int | None, str]]] = defaultdict(list)
        self._counts: dict[str, int] = defaultdict(int)

    def add(self, kind: str, line: int | None, message: str) -> None:
        self._counts[kind] += 1
        if len(self._by_kind[kind]) < WARNINGS_SHOWN:
            self._by_kind[kind].append((line, message))

    def emit(self) -> None:
        for kind, shown in self._by_kind.items():
            for line, message in shown:
                self._log.warning("%s:%s: %s", self._path, line, message)
            more = self._counts[kind] - len(shown)
            if more:
                self._log.warning("%s: ... and %d more lines like this (%s)", self._path, more, kind)
