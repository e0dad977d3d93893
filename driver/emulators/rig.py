"""An emulated radar rig: the fake AWR1843 CLI and the fake DCA1000, wired like
the real boards, and the ``dca1000://`` URL that reaches them.

The radar's ``sensorStart`` starts the board's LVDS stream and ``sensorStop``
stops it; the board's ``RESET_AR_DEV`` resets the radar.  The board streams the
frames of any source (a capture directory, the simulator).
"""

from __future__ import annotations

import socket
from urllib.parse import urlencode

from ...cfg import RadarConfig
from .fake_awr1843 import CliFaults, FakeAwr1843
from .fake_dca1000 import Faults, FakeDca1000

HOST_IP = "127.0.0.1"
BOARD_IP = "127.0.0.2"


def free_udp_port(ip: str = HOST_IP) -> int:
    """A UDP port free on *ip* right now (the board must know the host's data
    port before the host binds it, as with the real board's EEPROM)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((ip, 0))
        return s.getsockname()[1]


class EmulatedRig:
    """Both emulators, started; close it (or use ``with``) to stop them."""

    def __init__(self, frames_url: str, *, config: RadarConfig | None = None, faults: Faults | None = None,
                 cli_faults: CliFaults | None = None, rate: str = "paced", seed: int = 0,
                 host_ip: str = HOST_IP, board_ip: str = BOARD_IP) -> None:
        self.host_ip = host_ip
        self.data_port = free_udp_port(host_ip)
        self.board = FakeDca1000.from_url(frames_url, config, host_data_port=self.data_port,
                                          board_ip=board_ip, host_ip=host_ip, faults=faults,
                                          rate=rate, seed=seed)
        self.radar = FakeAwr1843(cli_faults, on_sensor_start=self.board.lvds_start,
                                 on_sensor_stop=self.board.lvds_stop)
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
