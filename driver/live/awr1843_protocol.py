"""The mmWave SDK demo firmware's CLI on the AWR1843's UART, as bytes.

Each command line sent is echoed; the firmware may print message lines, then
``Done`` or ``Error <N>``, then the prompt ``mmwDemo:/>``.  Lines end in
``\\n``, ``\\r\\n`` or ``\\n\\r`` depending on where they come from (a real
trace: ``b'sensorStop\\nIgnored: Sensor is already stopped\\n\\rDone\\n\\rmmwDemo:/>'``,
pyRadar issue #2).  A ``%`` line gets ``Skipped``; an unknown command
``'<cmd>' is not recognized as a CLI command``.  Source: mmWave SDK 3.5
``cli.c`` / ``mmw_cli.c`` and protocol.md.

:class:`ReplyFramer` cuts a byte stream into replies at the prompt and
:func:`classify` says what a reply means; both are pure (no I/O), so the
driver and the firmware emulator share them.
"""

from __future__ import annotations

import enum
import re
from dataclasses import dataclass

PROMPT = b"mmwDemo:/>"
DONE = "Done"
SKIPPED = "Skipped"
IGNORED_PREFIX = "Ignored:"
NOT_RECOGNIZED = "is not recognized as a CLI command"
ALREADY_STOPPED = "Ignored: Sensor is already stopped"
ALREADY_STARTED = "Ignored: Sensor is already started"
NOT_ALLOWED_AFTER_START = "Ignored: This command is not allowed after sensor has started"
FULL_CONFIG_NEEDED = "Error: Full configuration must be provided before sensor can be started the first time"
#: Line end the firmware uses after its own messages.
FIRMWARE_EOL = "\n\r"
#: Default baud rate of the CLI port.
CLI_BAUDRATE = 115200

_ERROR = re.compile(r"^Error\s+(-?\d+)\s*$")
#: Commands that change nothing when sent twice, so one a booting radar may have lost can be
#: sent again (a configuration line cannot: "chirp 0 is already defined").
REPEATABLE = frozenset({"sensorStop", "flushCfg", "version", "queryDemoStatus"})
#: The line the demo prints at boot, between rows of asterisks ("xWR18xx MMW Demo 03.05.00.04").
_BANNER = re.compile(r"^xWR\d\dxx MMW Demo\b")


class Outcome(enum.Enum):
    DONE = "done"  # the command was accepted
    ERROR = "error"  # "Error <N>": the command was refused
    IGNORED = "ignored"  # "Ignored: ..." then Done: no effect, not a failure
    SKIPPED = "skipped"  # a % comment line
    UNKNOWN_COMMAND = "unknown command"
    UNCLEAR = "unclear"  # a prompt without any of the above


@dataclass(frozen=True)
class Reply:
    """One reply: the echoed command, the other lines, and what they mean."""

    echo: str
    lines: tuple[str, ...]
    outcome: Outcome
    #: The N of "Error <N>", when there is one.
    error_code: int | None = None

    @property
    def text(self) -> str:
        """The firmware's own words (all lines but the echo), for messages."""
        return " | ".join(self.lines)


class ReplyFramer:
    """Cuts the CLI byte stream into replies at each prompt.

    Feed it bytes as they arrive; it returns the completed replies' text (the
    bytes before each prompt, decoded leniently) and keeps the rest.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()

    def feed(self, data: bytes) -> list[str]:
        self._buffer += data
        replies = []
        while True:
            at = self._buffer.find(PROMPT)
            if at < 0:
                return replies
            replies.append(self._buffer[:at].decode("ascii", errors="replace"))
            del self._buffer[: at + len(PROMPT)]

    @property
    def pending(self) -> bytes:
        """Bytes received after the last prompt."""
        return bytes(self._buffer)

    def clear(self) -> None:
        self._buffer.clear()


def is_boot_banner(text: str) -> bool:
    """True when *text* (the bytes before a prompt) is the banner a radar prints
    as it boots, unasked: whatever it was sent before was lost."""
    return any(_BANNER.match(ln) for ln in split_lines(text))


def split_lines(text: str) -> list[str]:
    """Non-empty lines, whatever mix of CR and LF ends them."""
    return [ln.strip() for ln in re.split(r"[\r\n]+", text) if ln.strip()]


def classify(text: str, command: str) -> Reply:
    """What the reply *text* (the bytes before a prompt) to *command* means."""
    lines = split_lines(text)
    echo = ""
    if lines and lines[0] == command.strip():
        echo, lines = lines[0], lines[1:]
    outcome, code = Outcome.UNCLEAR, None
    for ln in lines:
        m = _ERROR.match(ln)
        if m:
            return Reply(echo, tuple(lines), Outcome.ERROR, int(m.group(1)))
        if ln.startswith("Error"):  # "Error: Full configuration must be provided ..."
            outcome = Outcome.ERROR
        elif NOT_RECOGNIZED in ln:
            return Reply(echo, tuple(lines), Outcome.UNKNOWN_COMMAND)
        elif ln == SKIPPED and outcome is Outcome.UNCLEAR:
            outcome = Outcome.SKIPPED
        elif ln.startswith(IGNORED_PREFIX) and outcome is not Outcome.ERROR:
            outcome = Outcome.IGNORED
        elif ln == DONE and outcome is Outcome.UNCLEAR:
            outcome = Outcome.DONE
    return Reply(echo, tuple(lines), outcome, code)
