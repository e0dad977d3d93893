"""Heatmaps: range-azimuth (and range-azimuth-elevation) intensity with Doppler.

Like ColoRadar's heatmaps, each cell has an intensity and the radial velocity of its dominant
Doppler bin, placed between bins where the bins are wide
(``DspConfig.heatmap_doppler_between_bins_mps``: TI's SDK demo profiles' 3-4 ms frames make bins
of 0.43-0.64 m/s, whose centres misplace a static cell's Doppler by up to a third of a metre a
second, and the estimator tells static cells from moving ones by it); with a raised antenna row
(3 TX on the xWR18xx), also the elevation of its power: the phase between the raised row's and
the azimuth row's beams at the cell's azimuth, over all Doppler bins, as the point cloud's
elevation is taken per detection.  Two intensities: over all Doppler bins, and over the static
(zero-Doppler) bins only, which is what scan registration wants.

- Range-azimuth: for every Doppler and range bin the TDM-compensated azimuth
  row goes through the zero-padded azimuth DFT, as one matrix product with a
  small precomputed DFT matrix (8 elements onto 64 bins: cheaper than FFTs of
  mostly zeros); power is then summed (all), taken at zero Doppler (static),
  and its argmax over Doppler gives the dominant velocity.
- Range-azimuth-elevation: per range bin the spatial covariance of the whole
  virtual array over Doppler bins (12 x 12 for 3 TX x 4 RX) is formed once,
  and the Bartlett spectrum a^H R a evaluated on an azimuth x elevation grid
  as one matrix product, not per cell.
- Cartesian: a polar heatmap resampled (bilinear) onto an x-y grid, with the
  sample positions computed once per grid.
"""

from __future__ import annotations

import numpy as np

from ..errors import UsageError, quoted
from ..plain_numbers import is_whole_number
from ..products import RangeAzimuth, RangeAzimuthElevation
from .points import invert_three_bins, three_bin_response
from .processor import FrameProcessor

#: Doppler bins per block of the azimuth row's transposing copy (8 complex64: 64 bytes, a
#: cache line).
_DOPPLER_BLOCK = 8
#: Range bins per block of the full map's Doppler x azimuth spectrum.
_RANGE_BLOCK = 16


class HeatmapMaker:
    """Heatmaps from a :class:`FrameProcessor`'s Doppler spectrum."""

    def __init__(self, processor: FrameProcessor, *, static_bins: int = 0,
                 elevation_bins: int | None = None, doppler_cells: int | None = None) -> None:
        """*doppler_cells*: None gives every cell its dominant Doppler (a full
        Doppler x azimuth spectrum per range bin); a number N gives it to the N
        strongest cells only (NaN elsewhere) and takes the intensities from each
        range bin's spatial covariance, several times faster.  A bad argument is a
        :class:`UsageError` naming it, before any work."""
        static_bins, elevation_bins, doppler_cells = _checked_arguments(processor, static_bins, elevation_bins,
                                                                        doppler_cells)
        self.proc = processor
        #: The Doppler spectrum's shape the processor makes (doppler_fft), which the maps take.
        self._spectrum_shape = (processor.n_doppler, *processor.cfg.cube_shape[1:3], processor.n_range)
        self.static_bins = static_bins
        self.doppler_cells = doppler_cells
        n_az = processor.n_az
        k = np.arange(n_az) - n_az // 2  # after fftshift: ascending signed bins
        self.azimuth_rad = np.arcsin(np.clip(2.0 * k / n_az, -1.0, 1.0))
        velocity = processor.velocity_mps  # ascending
        #: The Doppler bins' spacing, m/s.
        self._doppler_step = float(velocity[1] - velocity[0]) if len(velocity) > 1 else 0.0
        between = processor.params.heatmap_doppler_between_bins_mps
        #: The Doppler window's three-bin response (points.three_bin_response) that places each
        #: cell's dominant Doppler between bins; None: bin centres (bins no wider than
        #: heatmap_doppler_between_bins_mps).
        self._doppler_table = (three_bin_response(processor.w_doppler, processor.n_doppler,
                                                  setting="heatmap_doppler_between_bins_mps",
                                                  fix="set heatmap_doppler_between_bins_mps null")
                               if between is not None and self._doppler_step > between else None)
        centre = processor.n_doppler // 2
        self._static_rows = slice(centre - static_bins, centre + static_bins + 1)
        weights = processor.angle_weights
        # TDM phases and calibration (FrameProcessor.angle_weights); None when all are 1.
        self._weights = None if np.all(weights == 1) else weights
        #: Range of each heatmap row, m: the processor's range bins up to its detection range.
        self.range_m = processor.range_m[:processor.heatmap_range_bins]
        # DFT of the azimuth row at its elements' positions onto the centred bins:
        # exp(-j 2 pi h k / n_az) for signed k ascending (what fft + fftshift give).
        self._az_dft_t = np.exp(-2j * np.pi * np.outer(k, processor.az_h) / n_az).astype(np.complex64)
        # a^H R a for every azimuth bin a and range bin, with R the azimuth row's covariance
        # (row x row) and a the DFT row: sum_hg R_hg D_ah conj(D_ag), one real matrix product
        # of R's interleaved (re, im) values with this (2 row^2, n_az) matrix (Re(R M) =
        # Re R Re M - Im R Im M).  Eight times faster than products per range bin.
        n_row = len(processor.az_elements)
        quad = (self._az_dft_t[:, :, None] * np.conj(self._az_dft_t)[:, None, :]).reshape(n_az, -1).T
        self._az_quad = np.empty((2 * n_row * n_row, n_az), np.float32)
        self._az_quad[0::2], self._az_quad[1::2] = quad.real, -quad.imag
        # The azimuth row's elements: a slice (a view of the spectrum, no copy) where they are
        # consecutive, as on the xWR18xx's, else their indices.
        az = processor.az_elements
        consecutive = len(az) > 0 and np.array_equal(az, np.arange(az[0], az[0] + len(az)))
        self._az_select = slice(int(az[0]), int(az[0]) + len(az)) if consecutive else az
        # Work buffers, reused by every frame (fresh large arrays cost page faults); the full
        # Doppler x azimuth spectrum's (tens of MB) only where it is made.  The azimuth row is
        # kept as (row, n_range, n_doppler): see _azimuth_row.
        nr, nd = len(self.range_m), processor.n_doppler
        self._row = np.empty((n_row, nr, nd), np.complex64)
        self._row_conj = np.empty((n_row, nr, nd), np.complex64) if doppler_cells is not None else None
        # The full map's Doppler x azimuth spectrum, _RANGE_BLOCK range bins at a time (1 MB:
        # it stays in cache from the product to the argmax; the whole map's is 16 MB).
        rb = min(_RANGE_BLOCK, nr)
        self._full = None if doppler_cells is not None else (
            np.empty((n_az, rb, nd), np.complex64), np.empty((n_az, rb, nd), np.float32),
            np.empty((n_az, rb, nd), np.float32))
        self._row_weights = (None if self._weights is None else np.ascontiguousarray(
            self._weights[:, az].T)[:, None, :])  # (row, 1, n_doppler)
        # Without calibration the first TX slot's phase is 1 at every Doppler bin: only the rows
        # from the first other slot's on are multiplied (half the row on the xWR18xx), a slice of
        # the buffer.
        self._weighted_rows = slice(0, n_row)
        if self._row_weights is not None:
            moved = np.flatnonzero(np.any(self._row_weights != 1, axis=(1, 2)))
            self._weighted_rows = slice(int(moved[0]), n_row) if len(moved) else slice(0, 0)
        # The raised row's beams at the azimuth bins, and the cross products a cell's elevation
        # needs: C = sum_hg R_hg D_ah conj(E_ag), with R the azimuth row x raised row covariance.
        self._el_elements = np.asarray(processor.el_elements)
        if len(self._el_elements):
            el_dft = np.exp(-2j * np.pi * np.outer(k, processor.el_h) / n_az).astype(np.complex64)
            self._el_dft = el_dft
            self._el_cross = (self._az_dft_t[:, :, None] * np.conj(el_dft)[:, None, :]).reshape(n_az, -1).T.copy()
            self._el_weights = (None if self._weights is None else
                                np.ascontiguousarray(self._weights[:, self._el_elements].T)[:, None, :])
        n_el = elevation_bins or processor.params.elevation_fft_size
        kz = np.arange(n_el) - n_el // 2
        self.elevation_rad = np.arcsin(np.clip(2.0 * kz / n_el, -1.0, 1.0))
        # Steering vectors of the whole virtual array on the (elevation, azimuth) grid.
        va = processor.cfg.virtual_array
        h, v = va.h.ravel().astype(float), va.v.ravel().astype(float)
        sx = np.sin(self.azimuth_rad)[None, :] * np.cos(self.elevation_rad)[:, None]  # x / r
        sz = np.sin(self.elevation_rad)[:, None] * np.ones_like(sx)  # z / r
        # Element phase pi (h Wx - v Wz) (see the simulator's geometry and docs/conventions.md).
        phase = np.pi * (h[None, None, :] * sx[..., None] - v[None, None, :] * sz[..., None])
        self._steer = np.exp(1j * phase).reshape(-1, len(h)).astype(np.complex64)  # (el*az, elems)

    def _compensated(self, spectrum: np.ndarray) -> np.ndarray:
        """Doppler spectrum per element over the heatmap's range bins, TDM-compensated and
        calibrated: (n_doppler, elements, n_range)."""
        nd, slots, nrx, _ = spectrum.shape
        data = spectrum.reshape(nd, slots * nrx, -1)[:, :, :len(self.range_m)]
        if self._weights is not None:
            data = data * self._weights[:, :, None]
        return data

    def _azimuth_row(self, spectrum: np.ndarray) -> np.ndarray:
        """The azimuth row's Doppler spectra, TDM-compensated and calibrated, in the work buffer:
        complex64 (n_range, row, n_doppler), Doppler along memory (so that matrix products and
        the sums and argmax over Doppler run along it); a view of the (row, n_range,
        n_doppler) buffer, whose (row, n_doppler) matrices are strided as BLAS takes them."""
        nd, slots, nrx, _ = spectrum.shape
        row = spectrum.reshape(nd, slots * nrx, -1)[:, self._az_select, :len(self.range_m)]  # (n_doppler, row, n_range)
        buf = self._row
        # The transposing copy, _DOPPLER_BLOCK Doppler bins at a time: each output line then
        # gets a whole cache line per pass, where one whole-array copy writes 8 bytes per line
        # and pass (measured 0.26 ms against 0.6-0.8 ms for this 2 MB on the 2-core EPYC).
        for d in range(0, nd, _DOPPLER_BLOCK):
            np.copyto(buf[:, :, d:d + _DOPPLER_BLOCK], np.transpose(row[d:d + _DOPPLER_BLOCK], (1, 2, 0)))
        if self._row_weights is not None:
            buf[self._weighted_rows] *= self._row_weights[self._weighted_rows]
        return np.transpose(buf, (1, 0, 2))

    def _check_spectrum(self, spectrum) -> None:
        """:class:`UsageError` unless *spectrum* is the processor's Doppler spectrum (doppler_fft's)."""
        want = self._spectrum_shape
        if not isinstance(spectrum, np.ndarray) or spectrum.shape != want or spectrum.dtype.kind != "c":
            got = f"{spectrum.dtype} {spectrum.shape}" if isinstance(spectrum, np.ndarray) else type(spectrum).__name__
            raise UsageError(f"spectrum: the processor's Doppler spectrum (FrameProcessor.doppler_fft), complex "
                             f"(n_doppler, tx_slots, rx, n_range) = {want}, got {got}")

    def range_azimuth(self, spectrum: np.ndarray) -> RangeAzimuth:
        self._check_spectrum(spectrum)
        if self._full is None:
            return self._range_azimuth_strong(spectrum)
        proc = self.proc
        self._azimuth_row(spectrum)
        row = self._row  # (row, n_range, n_doppler)
        n_row, nr, nd = row.shape
        az, power, scratch = self._full  # (n_az, range block, n_doppler)
        n_az, rb = az.shape[:2]
        intensity = np.empty((n_az, nr), np.float32)
        static = np.empty((n_az, nr), np.float32)
        best = np.empty((n_az, nr), np.intp)
        offset = None if self._doppler_table is None else np.empty((n_az, nr), np.float32)
        raised = self._raised_row(spectrum)  # (row_el, n_range, n_doppler) or None
        cross = None if raised is None else np.empty((n_az, nr), np.complex64)
        for r0 in range(0, nr, rb):
            m = min(rb, nr - r0)
            a, p, q = az[:, :m], power[:, :m], scratch[:, :m]
            # A zero-padded FFT of a few elements is a small DFT matrix: one matrix product for
            # the block's range and Doppler bins, azimuth bins ascending.
            np.matmul(self._az_dft_t, row[:, r0:r0 + m].reshape(n_row, m * nd), out=a.reshape(n_az, m * nd))
            np.square(a.real, out=p)
            np.square(a.imag, out=q)
            p += q
            p.sum(axis=-1, out=intensity[:, r0:r0 + m])
            p[..., self._static_rows].sum(axis=-1, out=static[:, r0:r0 + m])
            p.argmax(axis=-1, out=best[:, r0:r0 + m])
            if offset is not None:
                offset[:, r0:r0 + m] = self._doppler_offsets(p, best[:, r0:r0 + m])
            if raised is not None:
                el = np.matmul(self._el_dft, raised[:, r0:r0 + m].reshape(len(raised), m * nd)).reshape(n_az, m, nd)
                np.einsum("abd,abd->ab", a, np.conj(el), out=cross[:, r0:r0 + m])
        dominant = proc.velocity_mps[best.T]
        if offset is not None:
            dominant = dominant + offset.T * self._doppler_step
        dominant = dominant.astype(np.float32)
        return RangeAzimuth(np.ascontiguousarray(intensity.T), np.ascontiguousarray(static.T), dominant,
                            self.range_m, self.azimuth_rad, None if cross is None else _elevation(cross.T))

    def _range_azimuth_strong(self, spectrum: np.ndarray) -> RangeAzimuth:
        """Intensities from per-range covariances; dominant Doppler for the strongest cells."""
        proc = self.proc
        x = self._azimuth_row(spectrum)
        dft = self._az_dft_t  # (n_az, row)
        xc = np.transpose(np.conjugate(self._row, out=self._row_conj), (1, 2, 0))  # (n_range, n_doppler, row)
        cov = np.matmul(x, xc)  # (n_range, row, row)
        nr, n_row = cov.shape[:2]
        intensity = cov.view(np.float32).reshape(nr, 2 * n_row * n_row) @ self._az_quad  # (n_range, n_az)
        # A quadratic form of a covariance is >= 0, but in float32 a cell next to a huge one (a
        # saturated frame's DC) can come out a rounding step below (-8 beside 5e16).
        np.maximum(intensity, 0, out=intensity)
        zero = self._row[:, :, self._static_rows]  # (row, n_range, static Doppler bins)
        # One matrix product for all ranges and static bins (not one per range bin).
        zero_az = np.matmul(dft, zero.reshape(n_row, -1)).reshape(len(dft), nr, -1)  # (n_az, n_range, bins)
        static = np.ascontiguousarray((zero_az.real ** 2 + zero_az.imag ** 2).sum(axis=-1).T)
        dominant = np.full(intensity.shape, np.nan, np.float32)
        n = min(self.doppler_cells, intensity.size)
        # The strongest cells, sorted: those of one range bin are then consecutive, and get
        # their Doppler spectra in one matrix product straight from the work buffer, one
        # product per range bin (the cells crowd into a few dozen range bins; gathering every
        # cell's (row, n_doppler) block, 8 kB, for one batched product cost three times more).
        cells = np.sort(np.argpartition(intensity.ravel(), -n)[-n:])
        r, a = np.divmod(cells, intensity.shape[1])
        first = np.flatnonzero(np.diff(r, prepend=-1))  # first cell of each range bin
        last = np.append(first[1:], n)
        steer = dft[a]  # (cells, row)
        spectra = np.empty((n, x.shape[2]), np.complex64)  # (cells, n_doppler)
        for i, j in zip(first.tolist(), last.tolist()):
            np.matmul(steer[i:j], self._row[:, r[i], :], out=spectra[i:j])
        power = spectra.real**2 + spectra.imag**2
        best = power.argmax(axis=1)
        dominant[r, a] = proc.velocity_mps[best]
        if self._doppler_table is not None:
            dominant[r, a] += self._doppler_offsets(power, best) * self._doppler_step
        elevation = None
        raised = self._raised_row(spectrum)
        if raised is not None:
            # The azimuth row x raised row covariance over Doppler bins, (n_range, row, row_el).
            r_cross = np.matmul(x, np.conj(np.transpose(raised, (1, 2, 0))))
            elevation = _elevation(r_cross.reshape(nr, -1) @ self._el_cross)
        return RangeAzimuth(intensity, static, dominant, self.range_m, self.azimuth_rad, elevation)

    def _doppler_offsets(self, power: np.ndarray, best: np.ndarray) -> np.ndarray:
        """Sub-bin offsets (-0.5 .. 0.5 bins) of the peaks at Doppler bins *best* (...) of the
        Doppler power spectra *power* (..., n_doppler), from the peak's magnitude and its
        neighbours' (the spectrum is periodic in Doppler) against the window's three-bin response."""
        nd = power.shape[-1]
        at = best[..., None]
        centre, below, above = (np.sqrt(np.take_along_axis(power, (at + step) % nd, axis=-1)[..., 0])
                                for step in (0, -1, 1))
        return invert_three_bins(below, centre, above, self._doppler_table)

    def _raised_row(self, spectrum: np.ndarray) -> np.ndarray | None:
        """The raised row's Doppler spectra, TDM-compensated and calibrated: complex64
        (row_el, n_range, n_doppler); None without a raised row."""
        if not len(self._el_elements):
            return None
        nd, slots, nrx, _ = spectrum.shape
        row = spectrum.reshape(nd, slots * nrx, -1)[:, self._el_elements, :len(self.range_m)]  # (nd, row_el, nr)
        out = np.ascontiguousarray(np.transpose(row, (1, 2, 0)))
        if self._el_weights is not None:
            out *= self._el_weights
        return out

    def range_azimuth_elevation(self, spectrum: np.ndarray) -> RangeAzimuthElevation:
        self._check_spectrum(spectrum)
        data = self._compensated(spectrum)  # (n_doppler, elements, n_range)
        x = np.transpose(data, (2, 1, 0))  # (n_range, elements, n_doppler)
        cov = x @ np.conj(np.transpose(x, (0, 2, 1)))  # (n_range, elements, elements)
        a = self._steer  # (cells, elements)
        # a^H R a for every cell and range, as matrix products.
        intensity = np.maximum(np.einsum("ce,ref,cf->rc", np.conj(a), cov, a, optimize=True).real, 0)  # (as above)
        xs = data[self._static_rows].sum(axis=0).T  # (n_range, elements)
        static = np.abs(xs @ np.conj(a).T) ** 2  # (n_range, cells)
        shape = (len(self.range_m), len(self.elevation_rad), len(self.azimuth_rad))
        return RangeAzimuthElevation(intensity.reshape(shape).astype(np.float32),
                                     static.reshape(shape).astype(np.float32),
                                     self.range_m, self.azimuth_rad, self.elevation_rad)


def _checked_arguments(processor, static_bins, elevation_bins, doppler_cells) -> tuple[int, int | None, int | None]:
    """HeatmapMaker's arguments as ints, or :class:`UsageError` naming the first wrong one: numpy's
    errors from deep inside the first frame (a str or 0 cells) say neither which nor why."""
    if not isinstance(processor, FrameProcessor):
        raise UsageError(f"HeatmapMaker: processor must be a FrameProcessor (FrameProcessor(cfg) makes one), "
                         f"got {type(processor).__name__} {quoted(processor)}")
    # The static rows reach static_bins either side of zero Doppler, within the Doppler axis.
    most = (processor.n_doppler - 1) // 2
    if not (is_whole_number(static_bins) and 0 <= static_bins <= most):
        raise UsageError(f"HeatmapMaker: static_bins must be a whole number of Doppler bins each side of zero "
                         f"Doppler, from 0 to {most}, got {quoted(static_bins)}")
    if elevation_bins is not None and not (is_whole_number(elevation_bins) and elevation_bins >= 1):
        raise UsageError(f"HeatmapMaker: elevation_bins must be a whole number >= 1, or None for the DSP's "
                         f"elevation_fft_size, got {quoted(elevation_bins)}")
    if doppler_cells is not None and not (is_whole_number(doppler_cells) and doppler_cells >= 1):
        raise UsageError(f"HeatmapMaker: doppler_cells must be a whole number >= 1 (the strongest cells given "
                         f"their Doppler), or None for every cell's, got {quoted(doppler_cells)}")
    return (int(static_bins), None if elevation_bins is None else int(elevation_bins),
            None if doppler_cells is None else int(doppler_cells))


def _elevation(cross: np.ndarray) -> np.ndarray:
    """Elevation (rad, float32) from the azimuth beam x conj(raised beam) products: their
    phase is pi sin(elevation), as for a detection's elevation (dsp/points.py)."""
    wz = np.clip(np.angle(cross) / np.pi, -1.0, 1.0)
    return np.arcsin(wz).astype(np.float32)


class CartesianGrid:
    """An x-y grid (TI sensor frame: x right, y ahead) and how to resample polar
    range-azimuth arrays onto it (bilinear; zero outside the field of view)."""

    def __init__(self, range_m: np.ndarray, azimuth_rad: np.ndarray, *, resolution_m: float = 0.05,
                 max_range_m: float | None = None) -> None:
        r_max = float(max_range_m or range_m[-1])
        self.x = np.arange(-r_max, r_max + resolution_m / 2, resolution_m)
        self.y = np.arange(0.0, r_max + resolution_m / 2, resolution_m)
        xx, yy = np.meshgrid(self.x, self.y)  # (ny, nx)
        r = np.hypot(xx, yy)
        theta = np.arctan2(xx, yy)
        # Fractional indices into the polar arrays (range bins are uniform, from the range bias's
        # offset; azimuth is not uniform).
        ri = (r - range_m[0]) / (range_m[1] - range_m[0])
        ai = np.interp(theta, azimuth_rad, np.arange(len(azimuth_rad)), left=-1.0, right=-1.0)
        self._coords = np.stack([ri, ai])
        self._outside = (ai < 0) | (ri < 0) | (r > r_max)

    def resample(self, polar: np.ndarray) -> np.ndarray:
        """A (n_range, n_azimuth) array on the grid: (len(y), len(x))."""
        import scipy.ndimage

        out = scipy.ndimage.map_coordinates(polar, self._coords, order=1, mode="constant", cval=0.0)
        out[self._outside] = 0.0
        return out
