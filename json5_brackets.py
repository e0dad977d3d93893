"""Where a JSON5 text's brackets or strings fail to close, for an error message.

Zenoh's JSON5 parser reports a text cut short (a missing ``}``, an unclosed string) as a value
expected somewhere else, which sends the user to the wrong line.  :func:`unbalanced` reads only
the structure (strings, comments, brackets) and says where it breaks, or nothing when it does
not.
"""

from __future__ import annotations

_CLOSER = {"{": "}", "[": "]"}


def _position(text: str, index: int) -> str:
    """*index* into *text* as ``line:column``, both from 1."""
    line = text.count("\n", 0, index) + 1
    return f"{line}:{index - (text.rfind(chr(10), 0, index) + 1) + 1}"


def unbalanced(text: str) -> str | None:
    """``line:column: what`` of the first bracket closed by the wrong kind, closed never opened
    or never closed, or of a string or block comment the text ends inside; None if none."""
    opened: list[int] = []  # indices of the open brackets, innermost last
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c in "\"'":
            end = i + 1
            while end < n and text[end] != c and text[end] != "\n":
                end += 2 if text[end] == "\\" else 1
            if end >= n or text[end] != c:
                return f"{_position(text, i)}: this string has no closing {c} on its line"
            i = end + 1
            continue
        if text.startswith("//", i):
            end = text.find("\n", i)
            i = n if end < 0 else end + 1
            continue
        if text.startswith("/*", i):
            end = text.find("*/", i + 2)
            if end < 0:
                return f"{_position(text, i)}: this /* comment is never closed by */"
            i = end + 2
            continue
        if c in _CLOSER:
            opened.append(i)
        elif c in "}]":
            if not opened:
                return f"{_position(text, i)}: this {c!r} closes nothing"
            start = opened.pop()
            if _CLOSER[text[start]] != c:
                return (f"{_position(text, i)}: this {c!r} closes the {text[start]!r} opened at "
                        f"{_position(text, start)}, which needs {_CLOSER[text[start]]!r}")
        i += 1
    if opened:
        start = opened[-1]
        return f"{_position(text, start)}: this {text[start]!r} is never closed (the text ends first)"
    return None
