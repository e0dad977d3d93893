"""What the demo sends for a cfg: its packets' layout, the guiMonitor line radarodom needs, the
static heatmap's antennas, and whether the UART can carry it at the frame rate.

The demo's sizes (``mmwdemo_rfparser.c``): numRangeBins is the ADC samples rounded up to a power
of two, numDopplerBins the loops likewise; numVirtualAntAzim is the RX count times the TX slots on
TX1 or TX3 (the azimuth TX), and its azimuth static heatmap holds the *first* numVirtualAntAzim
virtual antennas in chirp order (``aoaprochwa.c``), which are the azimuth row only when the
azimuth TX chirp first (TI's order TX1, TX3, TX2; not TX1, TX2, TX3).

The UART: 8N1, 10 bits a byte.  The demo sends a frame's packet after the frame's chirps and its
processing, and its next frame's start asserts when the packet has not left by then
(``objectdetection.c`` ``DPC_ObjectDetection_frameStart``: ``interSubFrameProcToken == 0``; the CLI
prints ``Obj Det DPC Exception: ...objectdetection.c, line ...`` and the data stops).  So a packet
must fit in ``frame period - active chirping time``, less the (unmeasured) processing time.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from ...cfg import CfgLine, RadarConfig
from ...errors import ConfigError
from .wire import HEADER_DTYPE, TL_DTYPE, GuiSelection, PacketLayout, Tlv

log = logging.getLogger(__name__)

#: The data port's default baud rate (the XDS110's interface 3).
DEFAULT_BAUD = 921600
#: The data port's baud rates the demo and the XDS110 take: TI's Demo Visualizer offers custom rates
#: up to 3125000 (its user's guide, SWRU529C, 1.3 Serial Port Setup); 1200 is the slowest UART rate.
MIN_BAUD, MAX_BAUD = 1200, 3_125_000
#: The points a frame the UART budget is checked for unless told (``tidemo://...?max_points=``).
DEFAULT_MAX_POINTS = 64
#: Bits on the wire per byte (8N1).
BITS_PER_BYTE = 10
#: Azimuth TX: TX1 and TX3 of the xWR18xx (TX2 is raised).
AZIMUTH_TX = (1, 3)


def pow2_up(n: int) -> int:
    """mathUtils_pow2roundup: the smallest power of two >= *n*."""
    return 1 << max(0, int(n) - 1).bit_length()


@dataclass(frozen=True)
class DemoGeometry:
    """The demo's axes for a cfg: range bins and their step (m, numRangeBins-point FFT), Doppler
    bins and their step (m/s), the range bias the demo takes off its points (m), and the flat
    virtual-element indices of the static heatmap's antennas (chirp order)."""

    range_bins: int
    range_step_m: float
    doppler_bins: int
    doppler_step_mps: float
    range_bias_m: float
    heatmap_elements: tuple[int, ...]

    @classmethod
    def from_config(cls, cfg: RadarConfig) -> "DemoGeometry":
        n_range, n_doppler = pow2_up(cfg.num_samples), pow2_up(cfg.num_loops)
        azimuth_slots = sum(1 for t in cfg.tx_order if t in AZIMUTH_TX)
        n_az = azimuth_slots * cfg.num_rx
        va = cfg.virtual_array
        h, v = va.h.ravel()[:n_az], va.v.ravel()[:n_az]
        if n_az == 0 or v.any() or len(set(h.tolist())) != n_az:
            order = ", ".join(f"TX{t}" for t in cfg.tx_order)
            raise ConfigError(f"the demo's azimuth static heatmap holds the first {n_az} virtual antennas in chirp "
                              f"order ({order}), which are not one row of the array: make TX1 and TX3 chirp "
                              f"before TX2 (chirpCfg TX masks 1, 4, 2, as TI's profiles)", path=cfg.path,
                              command="chirpCfg")
        return cls(n_range, cfg.range_resolution_m * cfg.num_samples / n_range, n_doppler,
                   cfg.velocity_resolution_mps * cfg.num_loops / n_doppler,
                   cfg.channel_calibration.range_bias_m, tuple(range(n_az)))

    def layout(self, gui: GuiSelection) -> PacketLayout:
        return PacketLayout(self.range_bins, self.doppler_bins, len(self.heatmap_elements), gui)


def gui_selection(cfg: RadarConfig) -> GuiSelection:
    """The cfg's guiMonitor with what radarodom needs set: points with side info and the azimuth
    static heatmap; the profiles, range-Doppler map and stats as the cfg asks (default off)."""
    ln = cfg.line_of("guiMonitor")
    if ln is None:
        return GuiSelection()
    g = ln.value
    return GuiSelection(1, bool(g.log_mag_range), bool(g.noise_profile), True, bool(g.range_doppler_heat_map),
                        bool(g.stats_info))


def demo_config(cfg: RadarConfig, gui: GuiSelection, baud: int = DEFAULT_BAUD) -> RadarConfig:
    """*cfg* as sent to the demo: its guiMonitor line set to *gui* (in place, or added before
    sensorStart), and a ``configDataPort <baud> 0`` line when *baud* is not the default.  A cfg
    whose configDataPort says another baud rate, or one the data port does not take, is refused."""
    lines = list(cfg.lines)
    wanted = CfgLine("command", "guiMonitor", tuple(gui.line().split()[1:]))
    port = cfg.line_of("configDataPort")
    if port is not None and not MIN_BAUD <= port.value.baud_rate <= MAX_BAUD:
        raise ConfigError(f"sets the data port to {port.value.baud_rate} baud; the demo's data port takes {MIN_BAUD} "
                          f"to {MAX_BAUD}", path=cfg.path, line=port.line, command=str(port))
    if port is not None and port.value.baud_rate != baud:
        raise ConfigError(f"sets the data port to {port.value.baud_rate} baud, the source reads it at {baud}: give "
                          f"baud={port.value.baud_rate} in the tidemo:// URL, or change the line", path=cfg.path,
                          line=port.line, command=str(port))
    extra = [] if baud == DEFAULT_BAUD or port is not None else [CfgLine("command", "configDataPort", (str(baud), "0"))]
    at = next((i for i, ln in enumerate(lines) if ln.kind == "command" and ln.text == "guiMonitor"), None)
    if at is not None:
        if lines[at].args != wanted.args:
            log.info("%s:%s: guiMonitor %s sent as '%s' (points with side info and the static heatmap)",
                     cfg.path, lines[at].line, " ".join(lines[at].args), gui.line())
        lines[at] = CfgLine("command", "guiMonitor", wanted.args, None, lines[at].line)
    else:
        extra.insert(0, wanted)
    end = next((i for i, ln in enumerate(lines) if ln.kind == "command" and ln.text == "sensorStart"), len(lines))
    lines[end:end] = extra
    return RadarConfig(lines, cfg.path)


@dataclass(frozen=True)
class UartBudget:
    """A packet's bytes and time on the UART against the time the demo has to send it."""

    packet_bytes: int
    transmit_s: float
    available_s: float
    baud: int
    max_points: int

    @property
    def fits(self) -> bool:
        return self.transmit_s <= self.available_s


def uart_budget(cfg: RadarConfig, layout: PacketLayout, baud: int, max_points: int) -> UartBudget:
    n = layout.packet_bytes(max_points)
    return UartBudget(n, n * BITS_PER_BYTE / baud, cfg.frame_period_s - cfg.active_frame_time_s, baud, max_points)


def check_uart_budget(cfg: RadarConfig, layout: PacketLayout, baud: int, max_points: int) -> UartBudget:
    """The budget, or :class:`ConfigError` with the arithmetic and the fixes when a packet with
    *max_points* points cannot leave the UART before the next frame starts."""
    b = uart_budget(cfg, layout, baud, max_points)
    if b.fits:
        return b
    parts = [f"{HEADER_DTYPE.itemsize} header"]
    names = {Tlv.DETECTED_POINTS: f"points ({max_points} x 16)", Tlv.DETECTED_POINTS_SIDE_INFO: "side info",
             Tlv.RANGE_PROFILE: "range profile", Tlv.NOISE_PROFILE: "noise profile",
             Tlv.AZIMUT_STATIC_HEAT_MAP: f"static heatmap ({layout.range_bins} range bins x "
                                         f"{layout.azimuth_antennas} antennas x 4)",
             Tlv.RANGE_DOPPLER_HEAT_MAP: f"range-Doppler map ({layout.range_bins} x {layout.doppler_bins} x 2)",
             Tlv.STATS: "stats", Tlv.TEMPERATURE_STATS: "temperature"}
    parts += [f"{TL_DTYPE.itemsize + n} {names[t]}" for t, n in layout.tlv_lengths(max_points)]
    active_ms, period_ms = cfg.active_frame_time_s * 1e3, cfg.frame_period_s * 1e3
    fixes = [f"a frameCfg period of at least {active_ms + b.transmit_s * 1e3:.0f} ms"]
    if layout.gui.range_doppler_heat_map:
        fixes.insert(0, "no range-Doppler map (guiMonitor's rangeDopplerHeatMap 0)")
    heatmap_bytes = layout.range_bins * layout.azimuth_antennas * 4
    others = b.packet_bytes - heatmap_bytes
    room = int((b.available_s * baud / BITS_PER_BYTE - others) // (4 * layout.azimuth_antennas))
    bins = 1 << (room.bit_length() - 1) if room > 0 else 0  # the demo's range bins are a power of two
    if 16 <= bins < layout.range_bins:
        fixes.append(f"fewer range bins (profileCfg's numAdcSamples {bins} or less)")
    if uart_budget(cfg, layout, baud, 0).fits:
        n = max_points
        while n > 0 and not uart_budget(cfg, layout, baud, n).fits:
            n -= 1
        fixes.append(f"fewer points (max_points={n} fits)")
    raise ConfigError(
        f"the UART cannot carry this cfg's frames: a packet is up to {b.packet_bytes} bytes ({' + '.join(parts)}, "
        f"padded to 32), {b.transmit_s * 1e3:.1f} ms at {baud} baud (10 bits a byte), but the demo must send it "
        f"between the end of a frame's chirps ({active_ms:.1f} ms) and the next frame ({period_ms:g} ms period): "
        f"{b.available_s * 1e3:.1f} ms.  The demo would stop with an exception.  Fix: "
        + "; or ".join(fixes), path=cfg.path, command="frameCfg")
