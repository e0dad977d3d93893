"""A demo packet as radarodom's products: its points (:data:`radarodom.products.POINT_DTYPE`) and
its azimuth static heatmap's antenna values.

The points are the chip's: x, y, z and radial velocity in the TI sensor frame (the frame radarodom's
points use, docs/conventions.md: x right, y along the boresight, z up; velocity positive receding),
with the range bias already taken off by the demo.  radarodom adds range, azimuth and elevation
from them, the range and Doppler bins they fall in, and the side info's SNR and noise (the chip's
CFAR figures, 0.1 dB steps on the wire; NaN without side info).

The static heatmap stays complex: complex64 (range bins, antennas), the demo's first
``numVirtualAntAzim`` antennas in chirp order, as the chip calibrated them.  Its angle processing
is radarodom's DSP's (:mod:`radarodom.dsp.static_heatmap`), where the raw path's axes and
calibration are.
"""

from __future__ import annotations

import logging
from typing import Callable

import numpy as np

from ...errors import CaptureFormatError
from ...products import POINT_DTYPE
from ..sources import Frame
from . import wire
from .layout import DemoGeometry

log = logging.getLogger(__name__)


#: A point past this many times the cfg's range or Doppler span was not measured by the chip
#: (its header has no checksum: a garbled byte on the line reads as any float).
PLAUSIBLE_SPAN = 2.0


def points(packet: wire.Packet, geometry: DemoGeometry) -> np.ndarray:
    """The packet's points as POINT_DTYPE (n,) (none: an empty array); those the chip cannot have
    measured (NaN, inf, past :data:`PLAUSIBLE_SPAN` times the cfg's range or Doppler span) are
    left out, with a warning naming the frame and the packet's place in its stream."""
    chip = packet.array(wire.Tlv.DETECTED_POINTS, wire.POINT_DTYPE)
    if chip is None or not len(chip):
        return np.zeros(0, POINT_DTYPE)
    reach = PLAUSIBLE_SPAN * geometry.range_bins * geometry.range_step_m
    speed = PLAUSIBLE_SPAN * geometry.doppler_bins * geometry.doppler_step_mps
    with np.errstate(over="ignore", invalid="ignore"):
        kept = ((np.abs(chip["x"]) <= reach) & (np.abs(chip["y"]) <= reach) & (np.abs(chip["z"]) <= reach)
                & (np.abs(chip["velocity"]) <= speed))
    side = packet.array(wire.Tlv.DETECTED_POINTS_SIDE_INFO, wire.SIDE_INFO_DTYPE)
    if not kept.all():
        log.warning("frame %d (the packet at byte %d of its stream): %d of %d points hold NaN, inf or values past "
                    "%.3g m or %.3g m/s, which the cfg's chip cannot have measured (a garbled packet): left out",
                    packet.frame_number, packet.offset, int((~kept).sum()), len(chip), reach, speed)
        chip = chip[kept]
        side = None if side is None or len(side) != len(kept) else side[kept]
    n = len(chip)
    out = np.zeros(n, POINT_DTYPE)
    if not n:
        return out
    for name in ("x", "y", "z", "velocity"):
        out[name] = chip[name]
    r = np.sqrt(chip["x"].astype(np.float64) ** 2 + chip["y"] ** 2 + chip["z"] ** 2)
    out["range"] = r
    out["azimuth"] = np.arctan2(chip["x"], chip["y"])
    out["elevation"] = np.arcsin(np.clip(np.divide(chip["z"], r, out=np.zeros(n), where=r > 0), -1.0, 1.0))
    out["snr_db"] = np.nan if side is None else side["snr"] / 10.0
    out["noise_db"] = np.nan if side is None else side["noise"] / 10.0
    out["range_bin"] = np.clip(np.round((r + geometry.range_bias_m) / geometry.range_step_m), 0, 32767)
    doppler = np.round(chip["velocity"] / geometry.doppler_step_mps)
    out["doppler_bin"] = np.clip(doppler, -32768, 32767)
    return out


def static_antennas(packet: wire.Packet, geometry: DemoGeometry) -> np.ndarray | None:
    """The azimuth static heatmap: complex64 (range bins, antennas), None when the packet has none."""
    cells = packet.array(wire.Tlv.AZIMUT_STATIC_HEAT_MAP, wire.HEATMAP_DTYPE)
    if cells is None:
        return None
    n_ant = len(geometry.heatmap_elements)
    if len(cells) != geometry.range_bins * n_ant:
        raise CaptureFormatError(
            f"frame {packet.frame_number}: the static heatmap holds {len(cells)} values, the cfg's "
            f"{geometry.range_bins} range bins x {n_ant} antennas make {geometry.range_bins * n_ant}: "
            "the radar runs another cfg than the one given")
    values = np.empty(len(cells), np.complex64)
    values.real, values.imag = cells["real"], cells["imag"]
    return values.reshape(geometry.range_bins, n_ant)


#: A frame number more than this far past the last is not frames lost but a garbled header (the
#: packet has no checksum) or another run of the radar: over a day of frames at 10 Hz.
MAX_FRAME_JUMP = 1 << 20


class FrameIndexer:
    """Stream indices from the demo's frame numbers: the first seen is 0, a skipped number
    skips an index, and a number that does not increase (a restarted radar) or leaps more than
    :data:`MAX_FRAME_JUMP` ahead (a garbled one) continues the indices."""

    def __init__(self) -> None:
        self._base: int | None = None
        self._last_index = -1
        self._last_number = -1
        #: Frame numbers skipped between the packets seen.
        self.skipped = 0

    def __call__(self, number: int) -> int:
        if self._base is None or not 0 < number - self._last_number <= MAX_FRAME_JUMP:
            if self._base is not None:
                why = ("the radar restarted" if number <= self._last_number else
                       f"a leap of more than {MAX_FRAME_JUMP} frames: a garbled header or another run")
                log.warning("frame number %d after %d: %s; indices continue", number, self._last_number, why)
            self._base = number - self._last_index - 1
        index = number - self._base
        self.skipped += index - self._last_index - 1
        self._last_index, self._last_number = index, number
        return index


class PacketFrames:
    """Turns a demo stream's packets into frames: the products, the index (:class:`FrameIndexer`),
    the timestamp from *stamp* ``(index, packet) -> s``."""

    def __init__(self, geometry: DemoGeometry, stamp: Callable[[int, wire.Packet], float]) -> None:
        self.geometry = geometry
        self.stamp = stamp
        self.indexer = FrameIndexer()

    @property
    def skipped(self) -> int:
        return self.indexer.skipped

    def __call__(self, packet: wire.Packet, ready_monotonic: float) -> Frame:
        index = self.indexer(packet.frame_number)
        return Frame(index=index, timestamp=self.stamp(index, packet), raw=None, layout=None,
                     ready_monotonic=ready_monotonic, points=points(packet, self.geometry),
                     static_antennas=static_antennas(packet, self.geometry), wire=packet.data)
