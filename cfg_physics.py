"""The frame layout and physics a radar configuration implies, and the DCA1000's capacity.

:class:`ConfigPhysics` is the half of :class:`radarodom.cfg.RadarConfig` that derives numbers
from the validated commands (``self.profile``, ``self.frame``, ``self.chirps``,
``self.channel``), with units in the property names.  See :mod:`radarodom.cfg` for the
wavelength convention.
"""

from __future__ import annotations

from typing import Any

from . import cfg_commands as cc
from .antenna import VirtualArray, enabled_rx, tx_number
from .cfg_fields import shown
from .errors import UsageError

#: Speed of light, m/s.
SPEED_OF_LIGHT = 299_792_458.0
#: Bytes per complex sample on the LVDS stream (int16 I + int16 Q).
BYTES_PER_COMPLEX_SAMPLE = 4
#: Highest RF frequency of the xWR18xx, Hz.
MAX_RF_FREQUENCY_HZ = 81e9
#: The RF ranges of the 77 GHz devices' two VCOs, GHz: a chirp's whole sweep lies within one of
#: them (mmWaveLink rlProfileCfg_t, rampEndTime and pfVcoSelect).
SYNTHESIZER_RANGES_GHZ = ((76.0, 78.0), (77.0, 81.0))
#: ADC data bytes in a full DCA1000 data packet (protocol.md).
DCA1000_PACKET_DATA_BYTES = 1456
#: Measured DCA1000 Ethernet throughput, (packet delay us, Mbit/s): UG Table 19.
DCA1000_THROUGHPUT_TABLE = ((5.0, 706.0), (10.0, 545.0), (25.0, 325.0), (50.0, 193.0))
#: The packet delay TI's DCA1000 CLI uses by default, us.
DCA1000_DEFAULT_PACKET_DELAY_US = 25.0
#: Packet delays the DCA1000 documents, us.
DCA1000_PACKET_DELAY_RANGE_US = (5.0, 500.0)


def dca1000_capacity_mbps(packet_delay_us: float) -> float:
    """DCA1000 Ethernet throughput at a packet delay, Mbit/s of ADC data.

    Interpolates UG Table 19 in time per packet (linear in the delay), and
    extrapolates along the end segments.  A delay outside
    :data:`DCA1000_PACKET_DELAY_RANGE_US` is a :class:`UsageError`.
    """
    lo, hi = DCA1000_PACKET_DELAY_RANGE_US
    if not (isinstance(packet_delay_us, (int, float)) and lo <= packet_delay_us <= hi):
        raise UsageError(f"packet delay: expected a number of us in {lo:g}..{hi:g} (the DCA1000's "
                         f"documented range), got {shown(str(packet_delay_us))}")
    bits = DCA1000_PACKET_DATA_BYTES * 8
    pts = [(d, bits / r) for d, r in DCA1000_THROUGHPUT_TABLE]  # (delay us, us per packet)
    for (d0, t0), (d1, t1) in zip(pts, pts[1:]):
        if packet_delay_us <= d1 or (d1, t1) == pts[-1]:
            t = t0 + (t1 - t0) * (packet_delay_us - d0) / (d1 - d0)
            return bits / max(t, 1e-9)
    raise AssertionError("unreachable")  # pragma: no cover


class ConfigPhysics:
    """Frame layout and physics of a validated configuration (mixed into RadarConfig)."""

    # ------------------------------------------------------------ frame layout
    def _frame_chirps(self) -> list[cc.ChirpCfg]:
        by_idx = {}
        for c in self.chirps:
            for i in range(c.start_idx, c.end_idx + 1):
                by_idx[i] = c
        f = self.frame
        return [by_idx[i] for i in range(f.chirp_start_idx, f.chirp_end_idx + 1)]

    @property
    def tx_order(self) -> tuple[int, ...]:
        """TX number (1..3) of each chirp of a loop, in transmission order."""
        return tuple(tx_number(c.tx_mask) for c in self._frame_chirps())

    @property
    def num_tx_slots(self) -> int:
        """Chirps per loop (one TX each): the cube's tx_slots axis."""
        return self.frame.chirp_end_idx - self.frame.chirp_start_idx + 1

    @property
    def num_tx(self) -> int:
        """Distinct TX antennas used by the frame."""
        return len(set(self.tx_order))

    @property
    def rx_indices(self) -> tuple[int, ...]:
        """Enabled RX (0..3), ascending: the cube's rx axis."""
        return enabled_rx(self.channel.rx_mask)

    @property
    def num_rx(self) -> int:
        return len(self.rx_indices)

    @property
    def num_loops(self) -> int:
        return self.frame.num_loops

    @property
    def num_samples(self) -> int:
        """ADC samples per chirp."""
        return self.profile.num_adc_samples

    @property
    def num_chirps_per_frame(self) -> int:
        return self.num_loops * self.num_tx_slots

    @property
    def cube_shape(self) -> tuple[int, int, int, int]:
        """Shape of one frame's raw cube: (loops, tx_slots, rx, samples)."""
        return (self.num_loops, self.num_tx_slots, self.num_rx, self.num_samples)

    @property
    def frame_bytes(self) -> int:
        """Bytes of one frame on the LVDS stream (16-bit complex samples)."""
        return self.num_chirps_per_frame * self.num_rx * self.num_samples * BYTES_PER_COMPLEX_SAMPLE

    @property
    def virtual_array(self) -> VirtualArray:
        """The TDM-MIMO virtual array from the chirpCfg TX masks and enabled RX."""
        return VirtualArray(self.tx_order, self.rx_indices)

    # ----------------------------------------------------------------- physics
    @property
    def sample_rate_hz(self) -> float:
        return self.profile.sample_rate_ksps * 1e3

    @property
    def slope_hz_per_s(self) -> float:
        return self.profile.freq_slope_mhz_us * 1e12

    @property
    def adc_sampling_time_s(self) -> float:
        """Duration of the ADC sampling window of one chirp, s."""
        return self.num_samples / self.sample_rate_hz

    @property
    def bandwidth_hz(self) -> float:
        """Sweep bandwidth covered while the ADC samples, Hz."""
        return self.slope_hz_per_s * self.adc_sampling_time_s

    @property
    def ramp_bandwidth_hz(self) -> float:
        """Bandwidth of the whole ramp (to rampEndTime), Hz."""
        return self.slope_hz_per_s * self.profile.ramp_end_time_us * 1e-6

    @property
    def start_frequency_hz(self) -> float:
        return self.profile.start_freq_ghz * 1e9

    @property
    def carrier_frequency_hz(self) -> float:
        """RF frequency at the centre of the ADC sampling window, Hz."""
        p = self.profile
        centre_s = p.adc_start_time_us * 1e-6 + (self.num_samples - 1) / (2.0 * self.sample_rate_hz)
        return self.start_frequency_hz + self.slope_hz_per_s * centre_s

    @property
    def wavelength_m(self) -> float:
        """Wavelength at :attr:`carrier_frequency_hz`, m."""
        return SPEED_OF_LIGHT / self.carrier_frequency_hz

    @property
    def range_resolution_m(self) -> float:
        """Range resolution and range-FFT bin size (N-point FFT), m."""
        return SPEED_OF_LIGHT / (2.0 * self.bandwidth_hz)

    @property
    def unambiguous_range_m(self) -> float:
        """Range at the sample rate's beat frequency (complex 1x), m."""
        return self.sample_rate_hz * SPEED_OF_LIGHT / (2.0 * self.slope_hz_per_s)

    @property
    def max_range_m(self) -> float:
        """Usable maximum range: beat frequency at 80 % of the sample rate, as TI's tools, m."""
        return 0.8 * self.unambiguous_range_m

    def range_fov_note(self, range_bias_m: float = 0.0) -> str | None:
        """A warning when the cfarFovCfg range maximum reaches more than two range bins beyond
        the usable range (:attr:`max_range_m` less *range_bias_m*, the board's range bias: the IF
        band limits the beat frequency), where radarodom's detection stops; None otherwise."""
        ln = self._keyed["cfarFovCfg"].get(0)
        usable = self.max_range_m - range_bias_m
        # Cfgs round the limit up (TI's own: 8.64 m for 8.634) and a board's range bias moves it
        # by centimetres: the cap is silent there.
        if ln is None or ln.value.max_value <= usable + 2 * self.range_resolution_m:
            return None
        return (f"{self.path}:{ln.line}: cfarFovCfg range maximum {ln.value.max_value:g} m reaches beyond the "
                f"usable range, {usable:.2f} m (beat frequencies up to 80 % of the IF band"
                f"{f', less the range bias of {range_bias_m:g} m' if range_bias_m else ''}): detection is "
                f"capped there, since the IF filter's roll-off and the TX-to-RX leakage lie beyond; "
                f"set the maximum to {usable:.2f} m or less")

    @property
    def chirp_time_s(self) -> float:
        """One chirp: idle time plus ramp end time, s."""
        p = self.profile
        return (p.idle_time_us + p.ramp_end_time_us) * 1e-6

    @property
    def chirp_repetition_s(self) -> float:
        """Time between two chirps of the same TX slot (one loop), s."""
        return self.num_tx_slots * self.chirp_time_s

    @property
    def active_frame_time_s(self) -> float:
        """Time the radar chirps in each frame, s."""
        return self.num_loops * self.chirp_repetition_s

    @property
    def measured_at_s(self) -> float:
        """When a frame's heatmap and points describe the radar, s after the frame's timestamp (its
        first chirp): the middle of its chirps, half the active frame time.  The odometry of a frame is
        the radar's then."""
        return 0.5 * self.active_frame_time_s

    @property
    def frame_period_s(self) -> float:
        return self.frame.frame_period_ms * 1e-3

    @property
    def frame_rate_hz(self) -> float:
        return 1.0 / self.frame_period_s

    @property
    def duty_cycle(self) -> float:
        """Share of the frame period spent chirping, 0..1."""
        return self.active_frame_time_s / self.frame_period_s

    @property
    def max_velocity_mps(self) -> float:
        """Maximum unambiguous radial velocity (+/-), m/s."""
        return self.wavelength_m / (4.0 * self.chirp_repetition_s)

    @property
    def velocity_resolution_mps(self) -> float:
        """Radial velocity per Doppler bin (numLoops-point FFT), m/s."""
        return self.wavelength_m / (2.0 * self.num_loops * self.chirp_repetition_s)

    @property
    def data_rate_mbps(self) -> float:
        """Average raw ADC data rate, Mbit/s."""
        return self.frame_bytes * 8 / self.frame_period_s / 1e6

    def dca1000_load(self, packet_delay_us: float = DCA1000_DEFAULT_PACKET_DELAY_US) -> float:
        """Share (0..) of the DCA1000's Ethernet capacity at *packet_delay_us* that
        :attr:`data_rate_mbps` uses; above 1 the board cannot keep up."""
        return self.data_rate_mbps / dca1000_capacity_mbps(packet_delay_us)

    def summary(self, packet_delay_us: float = DCA1000_DEFAULT_PACKET_DELAY_US) -> dict[str, Any]:
        """Derived quantities with stable keys (the ``radar-cfg --json`` schema)."""
        return {
            "range_resolution_m": self.range_resolution_m,
            "max_range_m": self.max_range_m,
            "velocity_resolution_mps": self.velocity_resolution_mps,
            "max_velocity_mps": self.max_velocity_mps,
            "frame_bytes": self.frame_bytes,
            "frame_period_s": self.frame_period_s,
            "data_rate_mbps": self.data_rate_mbps,
            "num_tx": self.num_tx,
            "num_rx": self.num_rx,
            "num_samples": self.num_samples,
            "num_loops": self.num_loops,
            "tx_order": list(self.tx_order),
            "num_tx_slots": self.num_tx_slots,
            "rx_indices": list(self.rx_indices),
            "carrier_frequency_hz": self.carrier_frequency_hz,
            "wavelength_m": self.wavelength_m,
            "bandwidth_hz": self.bandwidth_hz,
            "unambiguous_range_m": self.unambiguous_range_m,
            "chirp_time_s": self.chirp_time_s,
            "active_frame_time_s": self.active_frame_time_s,
            "measured_at_s": self.measured_at_s,
            "duty_cycle": self.duty_cycle,
            "packet_delay_us": packet_delay_us,
            "dca1000_capacity_mbps": dca1000_capacity_mbps(packet_delay_us),
            "dca1000_load": self.dca1000_load(packet_delay_us),
            "streams_raw_adc": self.streams_raw_adc,
            "calibration": self.channel_calibration.describe(),
        }
