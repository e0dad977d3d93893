"""The programs' entry points: each imports its module, then runs its ``main``.

Importing a program's module takes a few tenths of a second (numpy, scipy, the estimator); a
Ctrl-C in that time, or while its options are parsed, would end in Python's traceback, before
the program's own handling is in place.  Here it is the one line every program prints for it,
with status 130.
"""

from __future__ import annotations

import importlib
import sys
from typing import Callable, Sequence


def _launch(module: str, argv: Sequence[str] | None) -> int:
    # The program's own handling covers its work; a Ctrl-C while its module is imported or its
    # options are parsed (before that handling is in place) comes here.
    try:
        return importlib.import_module(f"radarodom.tools.{module}").main(argv)
    except KeyboardInterrupt:
        print(f"{module.replace('_', '-')}: interrupted", file=sys.stderr)
        return 130


def _entry(module: str) -> Callable[[Sequence[str] | None], int]:
    def run(argv: Sequence[str] | None = None) -> int:
        return _launch(module, argv)
    run.__name__ = run.__qualname__ = module
    return run


radar_capture = _entry("radar_capture")
radar_cfg = _entry("radar_cfg")
radar_sim = _entry("radar_sim")
radar_devices = _entry("radar_devices")
radar_emulate = _entry("radar_emulate")
radar_eval = _entry("radar_eval")
radar_coloradar = _entry("radar_coloradar")
radar_echo = _entry("radar_echo")
radar_calibrate = _entry("radar_calibrate")
