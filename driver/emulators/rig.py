"""An emulated radar rig: the fake AWR1843 CLI and the fake DCA1000, wired like
the real boards, and the ``dca1000://`` URL that reaches them.

The radar's ``sensorStart`` starts the board's LVDS stream and ``sensorStop``
stops it; the board's ``RESET_AR_DEV`` resets the radar.  The board streams the
frames of any source (a capture directory, the simulator).
"""

from __future__ import annotations

import socket
from typing import Any, Callable, Iterable
from urllib.parse import urlencode

from ...cfg import RadarConfig
from ...errors import UsageError
from .fake_awr1843 import BOOT_TIME_S, CliFaults, FakeAwr1843
from .fake_dca1000 import NO_LVDS_TIMEOUT_S, RECORD_COMPLETED_DELAY_S, Faults, FakeDca1000

HOST_IP = "127.0.0.1"
BOARD_IP = "127.0.0.2"


def free_udp_port(ip: str = HOST_IP, *also: str) -> int:
    """A UDP port free on *ip* right now, and on every address in *also* (the board must know
    the host's data port before the host binds it, as with the real board's EEPROM; xwr binds
    the board's config port number on the host too)."""
    for _ in range(100):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind((ip, 0))
            port = s.getsockname()[1]
            if all(_udp_port_free(other, port) for other in also):
                return port
    raise OSError(f"no UDP port free on {', '.join((ip, *also))} after 100 tries")


def _udp_port_free(ip: str, port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind((ip, port))
        except OSError:
            return False
        return True


class EmulatedRig:
    """Both emulators, started; close it (or use ``with``) to stop them.

    *frames_url*: the source the board streams (a URL, or a callable returning an iterable of
    frames, with *config*).  *command_port*: the board's config port (0: any free one; the
    real board's is 4096).  *data_port*: the host port the board streams to (0: one free on
    *host_ip*; the real board's is 4098).  *record_completed_delay_s*, *no_lvds_timeout_s*
    (the fake DCA1000's) and *boot_time_s* (the fake radar's) default to the boards' own
    timings (docs/live.md says where each comes from)."""

    def __init__(self, frames_url: str | Callable[[], Iterable[Any]], *, config: RadarConfig | None = None,
                 faults: Faults | None = None, cli_faults: CliFaults | None = None, rate: str = "paced", seed: int = 0,
                 host_ip: str = HOST_IP, board_ip: str = BOARD_IP, command_port: int = 0,
                 data_port: int = 0, record_completed_delay_s: float = RECORD_COMPLETED_DELAY_S,
                 no_lvds_timeout_s: float = NO_LVDS_TIMEOUT_S, boot_time_s: float = BOOT_TIME_S) -> None:
        self.host_ip = host_ip
        self.data_port = data_port or free_udp_port(host_ip)
        board = dict(host_data_port=self.data_port, board_ip=board_ip, host_ip=host_ip, faults=faults,
                     rate=rate, seed=seed, command_port=command_port,
                     record_completed_delay_s=record_completed_delay_s, no_lvds_timeout_s=no_lvds_timeout_s)
        if callable(frames_url):  # frames made by the caller (a test's slow source, say)
            if config is None:
                raise UsageError("EmulatedRig: frames given as a callable need the config they follow")
            self.board = FakeDca1000(frames=frames_url, frame_period_s=config.frame_period_s, **board)
            self.board.config = config
        else:
            self.board = FakeDca1000.from_url(frames_url, config, **board)
        self.radar = FakeAwr1843(cli_faults, on_sensor_start=self.board.lvds_start,
                                 on_sensor_stop=self.board.lvds_stop, boot_time_s=boot_time_s)
        self.board.on_reset_ar_dev = self.radar.reset
        try:
            self.board.start()
            self.cli_path = self.radar.open_pty()
        except BaseException:
            self.close()
            raise

    def url(self, **extra) -> str:
        """The ``dca1000://`` URL of this rig (extra options appended)."""
        query = {"host": self.host_ip, "cli": self.cli_path, "config_port": 0,
                 "data_port": self.data_port, "board_port": self.board.command_port, **extra}
        return f"dca1000://{self.board.command_address[0]}?{urlencode(query)}"

    def close(self) -> None:
        self.radar.close()
        self.board.close()

    def __enter__(self) -> "EmulatedRig":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
