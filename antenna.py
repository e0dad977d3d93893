"""AWR1843BOOST antenna geometry and the TDM-MIMO virtual array.

Positions are in half-wavelength units: ``h`` horizontal, ``v`` vertical.
The element index grows toward the sensor's *left*, so the physical position
of a virtual element in the TI sensor frame (x right, y boresight, z up) is
``x_TI = -h * lambda/2``, ``z_TI = +v * lambda/2`` (docs/conventions.md).

- 4 RX in a row, lambda/2 apart: RX r at h = r.
- TX1 at h = 0, TX3 two wavelengths away at h = 4, TX2 one wavelength from
  TX1 (h = 2) and half a wavelength higher (v = 1).

So TX1 x RX -> h 0..3, TX3 x RX -> h 4..7 (the 8-element azimuth row), and
TX2 x RX -> h 2..5 at v = 1 (the raised row).  Source: AWR1843BOOST user guide
antenna figure, as drawn in the xwr package and OpenRadar.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: (h, v) offset of each physical TX, indexed by TX number - 1 (TX1, TX2, TX3).
TX_OFFSETS_HALF_WAVELENGTHS = ((0, 0), (2, 1), (4, 0))
#: Number of physical TX and RX antennas on the board.
NUM_TX_ANTENNAS = 3
NUM_RX_ANTENNAS = 4


def tx_number(mask: int) -> int:
    """TX number (1..3) of a chirpCfg ``txEnable`` mask selecting one TX."""
    if mask not in (1, 2, 4):
        raise ValueError(f"txEnable mask {mask} does not select exactly one TX")
    return mask.bit_length()


def enabled_rx(rx_mask: int) -> tuple[int, ...]:
    """RX indices (0..3), ascending, enabled in a channelCfg ``rxChannelEn`` mask."""
    return tuple(r for r in range(NUM_RX_ANTENNAS) if rx_mask >> r & 1)


@dataclass(frozen=True)
class VirtualArray:
    """The virtual array of one TDM-MIMO frame layout.

    Elements are ordered like the raw cube's (tx_slot, rx) axes: element
    ``slot * num_rx + i`` is TX slot ``slot`` with the ``i``-th enabled RX.
    """

    #: TX number (1..3) transmitting in each TX slot, in chirp order.
    tx_order: tuple[int, ...]
    #: Enabled RX indices (0..3), ascending.
    rx: tuple[int, ...]

    @property
    def num_tx_slots(self) -> int:
        return len(self.tx_order)

    @property
    def num_rx(self) -> int:
        return len(self.rx)

    @property
    def h(self) -> np.ndarray:
        """Horizontal index, half wavelengths, int array shaped (tx_slots, rx)."""
        tx_h = np.array([TX_OFFSETS_HALF_WAVELENGTHS[t - 1][0] for t in self.tx_order])
        return tx_h[:, None] + np.array(self.rx)[None, :]

    @property
    def v(self) -> np.ndarray:
        """Vertical index, half wavelengths, int array shaped (tx_slots, rx)."""
        tx_v = np.array([TX_OFFSETS_HALF_WAVELENGTHS[t - 1][1] for t in self.tx_order])
        return np.broadcast_to(tx_v[:, None], (self.num_tx_slots, self.num_rx)).copy()

    def positions_m(self, wavelength_m: float) -> np.ndarray:
        """Element positions in the TI sensor frame, metres, shaped (tx_slots, rx, 3)."""
        half = wavelength_m / 2.0
        pos = np.zeros((self.num_tx_slots, self.num_rx, 3))
        pos[..., 0] = -self.h * half
        pos[..., 2] = self.v * half
        return pos

    @property
    def azimuth_row(self) -> np.ndarray:
        """Flat element indices of the v = 0 row, sorted by h (int array)."""
        return self._row(0)

    @property
    def elevation_row(self) -> np.ndarray:
        """Flat element indices of the raised v = 1 row, sorted by h (int array)."""
        return self._row(1)

    def per_element(self, paths: np.ndarray) -> np.ndarray:
        """A value per physical path, *paths* shaped (3, 4) [TX number - 1, RX index], as one per
        element of this array: shaped (tx_slots, rx), slot s on TX ``tx_order[s]``."""
        tx = np.array(self.tx_order) - 1
        return np.asarray(paths)[tx[:, None], np.array(self.rx)[None, :]]

    def per_path(self, elements: np.ndarray, fill: complex = 0) -> np.ndarray:
        """The inverse of :meth:`per_element`: a value per element, *elements* (tx_slots * rx,
        or shaped so), as one per physical path (3, 4) [TX number - 1, RX index]; *fill* on the
        paths this array does not use."""
        values = np.asarray(elements)
        out = np.full((NUM_TX_ANTENNAS, NUM_RX_ANTENNAS), fill, dtype=np.result_type(values, fill))
        tx = np.array(self.tx_order) - 1
        out[tx[:, None], np.array(self.rx)[None, :]] = values.reshape(len(tx), -1)
        return out

    def _row(self, v: int) -> np.ndarray:
        flat_h, flat_v = self.h.ravel(), self.v.ravel()
        idx = np.flatnonzero(flat_v == v)
        return idx[np.argsort(flat_h[idx], kind="stable")]
