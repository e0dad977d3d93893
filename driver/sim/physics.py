"""FMCW beat-signal synthesis for the AWR1843BOOST (docs/conventions.md signal model).

For chirp c (loop l, TX slot m), RX r and ADC sample n the complex ADC output
is a sum over propagation paths k::

    s = sum_k a_k exp(j 2 pi (f0 tau + S tau t_n))

with ``t_n = adcStartTime + n / f_s`` measured from the start of the ramp and
``f0`` the ramp's start frequency, and ``tau`` the round-trip delay of path k
evaluated at chirp c's own time, from the TX of slot m to the scatterer and
back to RX r.  Doppler, range migration across the frame and the TDM-MIMO
phase between TX slots therefore come from the geometry alone.

The sum is computed as a matrix product per chunk of a few loops (the
separable structure): ``f0 tau + S tau t_n = f_c tau + S tau (t_n - t_mid)``
with ``f_c = f0 + S t_mid`` the frequency at the centre of the ADC window
(:attr:`RadarConfig.carrier_frequency_hz`).  The first term, per (chirp, RX,
path), carries all phase information exactly; the second, the beat tone over
the samples, uses each path's delay at the chunk's centre and the array's
centre.  What that neglects is a phase ramp over the samples of at most
``2 pi S dtau T_adc / 2``: the chunks are made short enough, from the frame's
own motion, to keep it within 0.25 rad (4 chunks of the shipped cfg at 1 m/s,
one chunk when nothing moves in range); and 0.25 rad for the 8 mm antenna
offsets.

The sum over paths is the one reduction whose order could vary: a BLAS matrix product sums in
an order that depends on its thread count and kernel, and float rounding then differs by an
ADC count now and then.  :func:`exact_product` makes every term an integer held exactly in
float64, so any order gives the same sum: with ``fidelity="exact"`` a seed gives the same bytes
with any BLAS thread count (on one machine: numpy's own sin, cos and float32
arithmetic may round differently on another CPU).  ``fidelity="fast"`` keeps the float32 BLAS
product, half the cost, for real-time streaming: its bytes are the same for a seed at the same
BLAS thread count.

Antenna elements are placed in the TI sensor frame with the wavelength at
``f_c``, so the spatial phase between virtual elements is exactly
``pi h sin(azimuth)`` at the frequency the DSP assumes.  Each leg of a path is
treated in the far field (``|p - e| = |p| - u.e``), an error below 0.2 rad of
phase beyond 0.3 m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...antenna import TX_OFFSETS_HALF_WAVELENGTHS
from ...cfg import SPEED_OF_LIGHT, RadarConfig
from ...errors import UsageError


@dataclass(frozen=True)
class AntennaPattern:
    """One-way power gain of the AWR1843BOOST patch antennas, ``cos^n`` in
    azimuth and elevation fitted to a half-power beam width."""

    azimuth_hpbw_deg: float = 100.0
    elevation_hpbw_deg: float = 40.0

    @staticmethod
    def _exponent(hpbw_deg: float) -> float:
        return np.log(0.5) / np.log(np.cos(np.radians(hpbw_deg / 2.0)))

    def amplitude(self, azimuth: np.ndarray, elevation: np.ndarray) -> np.ndarray:
        """Two-way voltage gain (TX times RX pattern), 1 on boresight, 0 behind."""
        na = self._exponent(self.azimuth_hpbw_deg)
        ne = self._exponent(self.elevation_hpbw_deg)
        ca = np.clip(np.cos(azimuth), 0.0, None)
        ce = np.clip(np.cos(elevation), 0.0, None)
        # One-way power gain G = ca^na * ce^ne; two-way voltage = sqrt(G_tx G_rx) = G.
        return ca**na * ce**ne


def _norm(p: np.ndarray) -> np.ndarray:
    """Lengths of (3, C, K) vectors: (C, K)."""
    r = p[0] * p[0]
    r += p[1] * p[1]
    r += p[2] * p[2]
    return np.sqrt(r, out=r)


def _unit_phasor(cycles: np.ndarray) -> np.ndarray:
    """exp(j 2 pi cycles) as complex64; *cycles* already reduced mod 1 so that
    float32 keeps the phase exact to ~1e-7 cycles."""
    phase = (2.0 * np.pi * cycles).astype(np.float32)
    out = np.empty(phase.shape, np.complex64)
    np.cos(phase, out=out.real)
    np.sin(phase, out=out.imag)
    return out


#: Columns summed by one BLAS call of exact_product, and the bits each factor is rounded to:
#: 2 * 2**(2 * bits) * columns is at most 2**53, so every partial sum is an exact integer.
EXACT_PRODUCT_COLUMNS = 512
EXACT_PRODUCT_BITS = 21


def _to_integers(x: np.ndarray) -> tuple[np.ndarray, float]:
    """*x* (complex64) as complex128 with integer parts of at most EXACT_PRODUCT_BITS bits, and
    the power of two it was divided by (0 when *x* is all zero)."""
    peak = float(max(np.abs(x.real).max(initial=0.0), np.abs(x.imag).max(initial=0.0)))
    if peak == 0.0:
        return x.astype(np.complex128), 0.0
    scale = math.ldexp(1.0, math.frexp(peak)[1] - EXACT_PRODUCT_BITS)
    factor = 1.0 / scale  # a power of two: the scaling is exact
    # float32 holds the integers exactly; float64 only where the factor would overflow float32.
    y = x * np.float32(factor) if factor < 2.0**120 else x.astype(np.complex128) * factor
    np.rint(y, out=y)
    return y.astype(np.complex128), scale


def exact_product(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """``out[...] = a @ b`` for complex64 *a* (m, k), *b* (k, n), the same bytes whatever the
    BLAS kernel or thread count.

    Per block of EXACT_PRODUCT_COLUMNS columns both factors are rounded to integers of
    EXACT_PRODUCT_BITS bits (a step of 2**-21 of the block's largest part, far below the one count
    the ADC rounds to), so the block's product is an exact integer sum in float64 whatever order
    BLAS adds in; blocks are then added in a fixed order.
    """
    acc = np.zeros(out.shape, np.complex128)
    for j0 in range(0, a.shape[1], EXACT_PRODUCT_COLUMNS):
        j1 = j0 + EXACT_PRODUCT_COLUMNS
        ai, sa = _to_integers(a[:, j0:j1])
        bi, sb = _to_integers(b[j0:j1])
        if sa == 0.0 or sb == 0.0:
            continue
        block = np.matmul(ai, bi)
        block *= sa * sb
        acc += block
    out[...] = acc


#: fidelity="exact": largest error of the drifting-delay expansion, rad, and the
#: largest drift phase a chunk may span (keeps the Taylor series short).
EXACT_PHASE_ERROR_RAD = 1e-3
EXACT_CHUNK_PHASE_RAD = 0.7
#: fidelity="fast": largest phase error the chunked beat tone may make at the ADC window's edges, rad:
#: a tone held 0.25 rad off at its ends is a beat frequency off by 0.25 / pi of a
#: range bin at the chunk's first and last chirps, under 1/12 of a bin, and 0 on average.
MAX_BEAT_PHASE_ERROR_RAD = 0.25


#: Synthesis modes: exact (for recordings and evaluation) or fast (real-time streaming).
FIDELITIES = ("exact", "fast")


class FmcwSynthesizer:
    """Turns propagation paths into one frame's complex ADC cube.

    Built once per configuration; buffers are preallocated for up to
    ``max_paths`` paths and grown when needed.
    """

    def __init__(self, cfg: RadarConfig, *, loops_per_chunk: int | None = None,
                 fidelity: str = "exact", extra_path_m: float = 0.0) -> None:
        if fidelity not in FIDELITIES:
            raise UsageError(f"fidelity {fidelity!r}: use {' or '.join(FIDELITIES)}")
        #: "exact": every chirp's delay drift to 1e-3 rad; "fast": chunked, for real-time streaming.
        self.fidelity = fidelity
        #: Added to every path's round trip, m: the front end's delay (twice a board's range bias).
        self.extra_path_m = float(extra_path_m)
        self.cfg = cfg
        loops, slots, rx, samples = cfg.cube_shape
        self.shape = cfg.cube_shape
        p = cfg.profile
        #: ADC sample times from the start of the ramp, s, (samples,).
        self.t_n = p.adc_start_time_us * 1e-6 + np.arange(samples) / cfg.sample_rate_hz
        self.t_mid = float(self.t_n.mean())
        self.f_c = cfg.start_frequency_hz + cfg.slope_hz_per_s * self.t_mid
        self.slope = cfg.slope_hz_per_s
        #: Start time of every chirp from the frame start, s, (loops * slots,).
        self.chirp_offsets_s = np.arange(loops * slots) * cfg.chirp_time_s
        half = SPEED_OF_LIGHT / self.f_c / 2.0
        tx = [TX_OFFSETS_HALF_WAVELENGTHS[t - 1] for t in cfg.tx_order]
        #: TX antenna of each slot and each enabled RX, TI frame, m: (slots, 3), (rx, 3).
        self.tx_pos = np.array([[-h * half, 0.0, v * half] for h, v in tx])
        self.rx_pos = np.array([[-r * half, 0.0, 0.0] for r in cfg.rx_indices])  # documents the geometry
        self.rx_index = np.array(cfg.rx_indices)
        self.loops_per_chunk = None if loops_per_chunk is None else max(1, min(loops_per_chunk, loops))
        # Block length for the beat tone: the largest power of two dividing the
        # sample count up to 16 (samples are even, so at least 2).
        self._block = next(b for b in (16, 8, 4, 2, 1) if samples % b == 0)
        self._inner_n = np.arange(self._block, dtype=float)
        self._outer_n = self._block * np.arange(samples // self._block, dtype=float)

    @property
    def chirps_per_frame(self) -> int:
        return self.shape[0] * self.shape[1]

    def synthesize(self, p_tx: np.ndarray, p_rx: np.ndarray | None, amp: np.ndarray,
                   out: np.ndarray | None = None) -> np.ndarray:
        """The noiseless cube of one frame.

        p_tx, p_rx: path end points in the TI sensor frame at every chirp's
            time, m, float (3, chirps, paths): the x, y, z planes; the TX leg ends at ``p_tx`` and
            the RX leg at ``p_rx`` (the same array for a direct path; a mirror
            image for a leg that bounces off a wall).  ``p_rx`` None means direct.
        amp: complex amplitude of each path, (paths,), ADC counts at 1 m
            equivalent (the caller applies 1/R^2, pattern and reflectivity).
        Returns complex64 (loops, tx_slots, rx, samples), filled into *out*.
        """
        loops, slots, nrx, ns = self.shape
        if out is None:
            out = np.empty(self.shape, np.complex64)
        k = amp.shape[0]
        if k == 0:
            out[...] = 0
            return out
        direct = p_rx is None
        p_rx = p_tx if direct else p_rx
        r_tx = _norm(p_tx)  # (C, K)
        r_rx = r_tx if direct else _norm(p_rx)
        # Far-field leg lengths |p - e| = |p| - u.e.  The TX element depends on
        # the chirp's slot; the RX elements sit on the x axis at -r lambda/2,
        # so RX r adds a phase pi r u_x (u toward the path's RX end).
        slot_of_chirp = np.tile(np.arange(slots), loops)
        tx = self.tx_pos[slot_of_chirp]  # (C, 3); TX antennas lie in the x-z plane
        tx_term = (p_tx[0] * tx[:, 0:1] + p_tx[2] * tx[:, 2:3]) / r_tx
        cycles = (r_tx + r_rx - tx_term + self.extra_path_m) * (self.f_c / SPEED_OF_LIGHT)  # (C, K)
        main = _unit_phasor(np.mod(cycles, 1.0))
        main *= amp.astype(np.complex64)[None, :]
        step = _unit_phasor(0.5 * p_rx[0] / r_rx)  # exp(j pi u_x), (C, K)
        a = np.empty((loops * slots, nrx, k), np.complex64)
        power = main  # main * step**r, by repeated products (complex ** is slow)
        for r in range(int(self.rx_index[-1]) + 1):
            if r:
                power = power * step
            for i in np.flatnonzero(self.rx_index == r):
                a[:, i] = power

        flat = out.reshape(loops * slots, nrx, ns)
        if self.fidelity == "fast":
            chunk = self._chunk_loops(r_tx, r_rx) * slots
            for c0 in range(0, loops * slots, chunk):
                c1 = min(c0 + chunk, loops * slots)
                tau = ((r_tx[c0:c1] + r_rx[c0:c1]).mean(axis=0) + self.extra_path_m) / SPEED_OF_LIGHT  # (K,)
                beat = self.beat_tone(tau)
                # BLAS in float32 for real time: the sum's order, so an ADC count now and then,
                # may change with the BLAS thread count (exact_product would cost twice as much).
                np.matmul(a[c0:c1].reshape((c1 - c0) * nrx, k), beat,
                          out=flat[c0:c1].reshape((c1 - c0) * nrx, ns))
            return out
        self._synthesize_exact(a, r_tx, r_rx, flat)
        return out

    def _synthesize_exact(self, a: np.ndarray, r_tx: np.ndarray, r_rx: np.ndarray, flat: np.ndarray) -> None:
        """The beat tone with each path's delay drifting chirp by chirp, to
        EXACT_PHASE_ERROR_RAD.

        Per chunk, a path's delay is tau + d_c (d_c its drift from the chunk's
        mean); over the samples that multiplies the tone at tau by
        exp(j z_c y_n), y_n in [-1, 1] across the ADC window and
        z_c = 2 pi S d_c T_adc / 2.  Its Taylor series in z_c y_n has separable
        terms (j z_c)^m / m! times y_n^m, so M terms are one matrix product
        with M stacked blocks: error at most |z|^M / M!, and not periodic.
        """
        chirps, nrx, k = a.shape
        ns = flat.shape[-1]
        tau_all = ((r_tx + r_rx).astype(np.float64) + self.extra_path_m) / SPEED_OF_LIGHT  # (C, K)
        half_window = (ns - 1) / (2 * self.cfg.sample_rate_hz)
        z_scale = 2 * np.pi * self.slope * half_window
        spread = float((tau_all.max(axis=0) - tau_all.min(axis=0)).max()) / 2 * z_scale
        loops = self.shape[0]
        slots = chirps // loops
        chunks = min(loops, max(1, int(np.ceil(spread / EXACT_CHUNK_PHASE_RAD))))
        per = int(np.ceil(loops / chunks)) * slots
        y = ((self.t_n - self.t_mid) / half_window).astype(np.float32)
        for c0 in range(0, chirps, per):
            c1 = min(c0 + per, chirps)
            tau = tau_all[c0:c1].mean(axis=0)
            z = ((tau_all[c0:c1] - tau) * z_scale).astype(np.float32)  # (c, K)
            zmax = float(np.abs(z).max())
            terms, bound = 1, zmax
            while bound > EXACT_PHASE_ERROR_RAD and terms < 12:
                terms += 1
                bound *= zmax / terms
            tone = self.beat_tone(tau)  # (K, ns)
            rows = (c1 - c0) * nrx
            a_stack = np.empty((c1 - c0, nrx, terms * k), np.complex64)
            b_stack = np.empty((terms * k, ns), np.complex64)
            coeff = np.ones_like(z, dtype=np.complex64)
            basis = np.ones(ns, np.float32)
            for m in range(terms):
                if m:
                    coeff *= (1j * z) / m
                    basis *= y
                a_stack[:, :, m * k:(m + 1) * k] = a[c0:c1] * coeff[:, None, :]
                np.multiply(tone, basis[None, :], out=b_stack[m * k:(m + 1) * k])
            exact_product(a_stack.reshape(rows, terms * k), b_stack, out=flat[c0:c1].reshape(rows, ns))

    def _chunk_loops(self, r_tx: np.ndarray, r_rx: np.ndarray) -> int:
        """Loops per chunk: the fewest chunks that keep the beat tone's phase error
        within MAX_BEAT_PHASE_ERROR_RAD (one chunk when nothing moves in range:
        a pause, a turn in place), unless ``loops_per_chunk`` fixes it.

        Within a chunk a path's delay drifts linearly; holding it at the chunk's
        mean is off by half the chunk's drift, which misphases the window's
        edge samples by 2 pi S (drift / 2) (T_adc / 2).
        """
        loops = self.shape[0]
        if self.loops_per_chunk is not None:
            return self.loops_per_chunk
        drift = float(np.abs((r_tx[-1] + r_rx[-1]) - (r_tx[0] + r_rx[0])).max()) / SPEED_OF_LIGHT  # s
        half_window = self.shape[3] / self.cfg.sample_rate_hz / 2
        error_one_chunk = 2 * np.pi * self.slope * (drift / 2) * half_window
        chunks = max(1, int(np.ceil(error_one_chunk / MAX_BEAT_PHASE_ERROR_RAD)))
        return max(1, loops // chunks)

    def beat_tone(self, tau: np.ndarray) -> np.ndarray:
        """exp(j 2 pi S tau (t_n - t_mid)) for delays *tau* (K,): complex64 (K, samples).

        A tone over n factors into blocks, z^n = z^(b q) z^j for n = b q + j, so
        it costs two small exponentials and one product instead of K x samples.
        """
        ns = self.shape[3]
        cycles_per_sample = self.slope * tau / self.cfg.sample_rate_hz  # (K,)
        first = -(ns - 1) / 2.0  # t_n - t_mid in samples, at n = 0
        block = self._block
        inner = _unit_phasor(np.mod(cycles_per_sample[:, None] * self._inner_n, 1.0))
        outer = _unit_phasor(np.mod(cycles_per_sample[:, None] * (first + self._outer_n), 1.0))
        tone = np.empty((len(tau), ns // block, block), np.complex64)
        np.multiply(outer[:, :, None], inner[:, None, :], out=tone)
        return tone.reshape(len(tau), ns)
