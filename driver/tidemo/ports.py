"""The two serial ports of one AWR1843BOOST: its CLI (the XDS110's USB interface 0) and its data
port (interface 3), found through :mod:`radarodom.driver.live.discovery` when not given.

A port given is used as given; the other is the one of the same board (the same XDS110 serial
number, or the same udev link's board), else the only one there is.  Several boards and nothing
to tell them apart is refused with the ports to choose from.
"""

from __future__ import annotations

import os
from typing import Callable

from ...errors import SourceError
from ..live.discovery import SerialPortInfo, find_ports, no_radar_message


def _same(port: SerialPortInfo, path: str) -> bool:
    real = os.path.realpath(path)
    return real == port.device or path in port.links


def demo_ports(cli: str | None, data: str | None,
               ports: Callable[[], list[SerialPortInfo]] = find_ports) -> tuple[str, str]:
    """(CLI port, data port): *cli* and *data* where given, the rest found (*ports*: the XDS110
    serial ports, :func:`~radarodom.driver.live.discovery.find_ports` by default)."""
    if cli and data:
        return cli, data
    found = ports()
    clis = [p for p in found if p.role == "cli"]
    datas = [p for p in found if p.role == "data"]
    given = cli or data
    if given:
        mine = next((p for p in found if _same(p, given)), None)
        others = datas if cli else clis
        if mine is not None and mine.serial_number:
            others = [p for p in others if p.serial_number == mine.serial_number] or others
        if len(others) != 1:
            want = "data port (USB interface 3)" if cli else "CLI port (USB interface 0)"
            listed = ", ".join(p.path for p in others) or "none found"
            raise SourceError(f"cannot tell the radar's {want} for {given}: {listed}; give it "
                              + ("as tidemo://DATA_PORT" if cli else "with cli=PORT"))
        other = others[0].path
        return (cli, other) if cli else (other, data)
    if not clis or not datas:
        raise SourceError(no_radar_message() + " (tidemo:// needs both the CLI and the data port)")
    pairs = [(c, d) for c in clis for d in datas if c.serial_number and c.serial_number == d.serial_number]
    if not pairs and len(clis) == len(datas) == 1:
        pairs = [(clis[0], datas[0])]
    if len(pairs) != 1:
        raise SourceError("several radars: name one with tidemo://DATA_PORT?cli=CLI_PORT (CLI ports: "
                          + ", ".join(p.path for p in clis) + "; data ports: " + ", ".join(p.path for p in datas) + ")")
    return pairs[0][0].path, pairs[0][1].path
