"""A heatmap's log intensity as a field to sample at any polar point: what the scan guess and
the likelihood-field search score rotations on (:mod:`.icp`)."""

from __future__ import annotations

import copy

import numpy as np

from .angles import wrap
from .config import FeatureConfig
from .features import PolarHeatmap, roi_mask


class LogHeatmap:
    """A heatmap's log intensity over its region of interest, for sampling at any polar point.

    The median is subtracted so that scores of different frames are comparable; sampling
    is bilinear in (range bin, sin(azimuth)), where the FFT bins are uniform."""

    def __init__(self, heatmap: PolarHeatmap, config: FeatureConfig, masked: np.ndarray | None = None) -> None:
        """*masked*: cells (n_range, n_azimuth) to set to the median, as a moving reflector's."""
        # float32 like the heatmaps themselves: the scan and the field gather these values
        # some 40 000 times a frame, and half the bytes is most of the speed.  In place in one
        # copy of the caller's heatmap (a few 64 kB temporaries fewer).
        log_i = np.array(heatmap.intensity, dtype=np.float32)
        np.log(np.maximum(log_i, 1e-30, out=log_i), out=log_i)
        valid = roi_mask(heatmap, config)
        if valid.any():
            log_i -= np.median(log_i[valid], overwrite_input=True)  # the boolean index copied
        if masked is not None:
            log_i[masked] = 0.0
        self._set_values(log_i)
        self._range = _Axis(np.asarray(heatmap.range_m, dtype=float))
        self.region = config
        self._sin_max = float(np.sin(config.max_azimuth_rad))
        self._set_azimuth(np.sin(np.asarray(heatmap.azimuth_rad, dtype=float)))

    def _set_azimuth(self, sin_azimuth: np.ndarray) -> None:
        """The azimuth axis, in sin(azimuth) (n_azimuth,), ascending."""
        self._sin_az = _Axis(sin_azimuth)
        # Rounding is monotonic: when |sin| = sin(max) maps inside the azimuth axis, every
        # smaller |sin| does too, and the fast path need not test the index against the axis.
        bounds = (np.array([-self._sin_max, self._sin_max]) - self._sin_az.start) * (1.0 / self._sin_az.step)
        self._sin_max_inside = bool(bounds[0] >= 0.0 and bounds[1] <= len(self._sin_az.axis) - 1)

    def _set_values(self, values: np.ndarray) -> None:
        """Keep the log intensity (n_range, n_azimuth) and, for bilinear sampling, its
        differences to the next azimuth bin, to the next range bin and across both (0 past
        the last bin), so that a sample is four gathers at one index and two multiply-adds."""
        self.values = values
        d_az = np.zeros_like(values)
        np.subtract(values[:, 1:], values[:, :-1], out=d_az[:, :-1])
        d_r = np.zeros_like(values)
        np.subtract(values[1:], values[:-1], out=d_r[:-1])
        d_both = np.zeros_like(values)
        np.subtract(d_az[1:], d_az[:-1], out=d_both[:-1])
        self._cells = tuple(a.ravel() for a in (values, d_az, d_r, d_both))

    def smoothed(self, sigma_bins: float, upsampling: int = 1) -> "LogHeatmap":
        """A copy whose log intensity is smoothed by a Gaussian of *sigma_bins* (the median
        is not computed again): a likelihood field, each bright cell's basin widened and
        speckle averaged.  With *upsampling* > 1 the smoothed field is interpolated every
        1/upsampling azimuth bin by cubic splines (smooth where the bins' bilinear interpolation
        is kinked), and sampled bilinearly on that grid."""
        out = copy.copy(self)
        if sigma_bins <= 0:
            return out
        import scipy.ndimage

        smooth = scipy.ndimage.gaussian_filter(self.values, sigma_bins, mode="nearest")
        if upsampling <= 1:
            out._set_values(smooth)
            return out
        n = self.values.shape[1]
        out._set_values(_catmull_rom(smooth, int(upsampling)))
        out._set_azimuth(np.interp(np.arange((n - 1) * upsampling + 1) / upsampling, np.arange(n), self._sin_az.axis))
        return out

    def sample_rotated(self, range_m: np.ndarray, bearing_rad: np.ndarray, shifts: np.ndarray,
                       cos_elevation: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Log intensity at the points (n,) rotated by each of *shifts* (m,) about the vertical:
        values and whether inside, both (m, n) (values 0 outside).  *range_m* is the range the
        heatmap measures (slant), *bearing_rad* horizontal; a point at elevation el
        (*cos_elevation*, None: level) lies at cos(el) sin(bearing) on the azimuth axis.  The same numbers as :meth:`sample`
        up to rounding, computed for speed (it is most of the scan guess's and the field's
        time): the range index once for all rotations, sin(bearing + shift) from the
        angle-sum formula."""
        shifts = np.asarray(shifts, dtype=float)
        if not self._sin_az.uniform:
            # A non-uniform azimuth axis (ColoRadar's) has no arithmetic index: the general path.
            values = self.sample(range_m[None, :], wrap(bearing_rad[None, :] + shifts[:, None]),
                                 None if cos_elevation is None else cos_elevation[None, :])
            inside = np.isfinite(values)
            return np.where(inside, values, 0.0), inside
        na = self.values.shape[1]
        r0, dr, ok_r = self._range_cells(range_m)
        inv_step = 1.0 / self._sin_az.step
        sin_b, cos_b = np.sin(bearing_rad), np.cos(bearing_rad)
        if cos_elevation is not None:
            sin_b, cos_b = sin_b * cos_elevation, cos_b * cos_elevation
        sin_s, cos_s = np.sin(shifts), np.cos(shifts)
        # sin(azimuth) / step = -sin(bearing + shift) / step, in float32 like the values (a
        # bin's 1e-7 of rounding is nothing to an interpolation, half the bytes is speed).
        fa = np.multiply.outer((-inv_step * cos_s).astype(np.float32), sin_b.astype(np.float32))
        fa -= np.multiply.outer((inv_step * sin_s).astype(np.float32), cos_b.astype(np.float32))
        # Within the front half-plane |bearing| <= max is |sin(azimuth)| <= sin(max).
        inside = np.abs(fa) <= self._sin_max * inv_step
        fa -= self._sin_az.start * inv_step
        if not self._sin_max_inside:
            inside &= (fa >= 0.0) & (fa <= na - 1)
        inside &= ok_r
        if np.abs(bearing_rad).max(initial=0.0) + np.abs(shifts).max() >= 0.5 * np.pi:
            # Some points may turn past the side, where the sine repeats the front's: only
            # the front half-plane, cos(bearing + shift) > 0, is inside (cos(el) > 0 keeps the sign).
            front = np.multiply.outer(cos_s, cos_b)
            front -= np.multiply.outer(sin_s, sin_b)
            inside &= front > 0.0
        np.clip(fa, 0.0, na - 1, out=fa)
        return np.where(inside, self._bilinear(r0, dr, fa), np.float32(0.0)), inside

    def sample(self, range_m: np.ndarray, bearing_rad: np.ndarray,
               cos_elevation: np.ndarray | None = None) -> np.ndarray:
        """Log intensity at body-frame polar points (any shape; *range_m* slant, *bearing_rad*
        horizontal, *cos_elevation* None: level); NaN outside the heatmap."""
        sin_az = np.sin(-bearing_rad) if cos_elevation is None else np.sin(-bearing_rad) * cos_elevation
        fa, ok_a = self._sin_az.fraction(sin_az)
        r0, dr, ok_r = self._range_cells(range_m)
        inside = ok_a & ok_r & (np.abs(bearing_rad) <= self.region.max_azimuth_rad)
        return np.where(inside, self._bilinear(r0, dr, fa), np.nan)

    def _range_cells(self, range_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Lower range bin, fraction above it and whether inside the axis (bin 0, fraction 0
        outside), each of range_m's shape."""
        fr, inside = self._range.fraction(range_m)
        r0 = np.minimum(fr.astype(np.intp), self.values.shape[0] - 2)
        return r0, fr - r0, inside

    def _bilinear(self, r0: np.ndarray, dr: np.ndarray, fa: np.ndarray) -> np.ndarray:
        """The log intensity interpolated at lower range bin *r0*, fraction *dr* above it and
        fractional azimuth index *fa* (within the axis), all broadcast together; float32."""
        na = self.values.shape[1]
        a0 = fa.astype(np.intp)
        np.minimum(a0, na - 2, out=a0)
        da = np.subtract(fa, a0, dtype=fa.dtype)  # not float64, as an integer operand would make it
        a0 += r0 * na
        value, d_az, d_r, d_both = (a.take(a0) for a in self._cells)
        d_az *= da
        value += d_az
        d_both *= da
        d_both += d_r
        d_both *= dr
        value += d_both
        return value


class _Axis:
    """Fractional index of values on an ascending axis: arithmetic when the axis is uniform
    (FFT bins are: range, and azimuth in sin), interpolation otherwise (ColoRadar's bins)."""

    def __init__(self, axis: np.ndarray) -> None:
        self.axis = axis
        step = np.diff(axis)
        # np.allclose(step, step[0], rtol=1e-6, atol=0) written out: the same test for finite
        # steps, without its 30 us of overhead (a log heatmap makes two axes every frame).
        self.uniform = len(axis) > 1 and bool(np.all(np.abs(step - step[0]) <= 1e-6 * abs(step[0])))
        self.start, self.step = float(axis[0]), float(step[0]) if len(axis) > 1 else 1.0

    def fraction(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fractional indices of *values* (0 outside the axis) and whether inside, both of
        values' shape."""
        if self.uniform:
            f = (values - self.start) * (1.0 / self.step)
            inside = (f >= 0.0) & (f <= len(self.axis) - 1)
        else:
            f = np.interp(values, self.axis, np.arange(len(self.axis)), left=np.nan, right=np.nan)
            inside = np.isfinite(f)
        f[~inside] = 0.0
        return f, inside


def _catmull_rom(values: np.ndarray, upsampling: int) -> np.ndarray:
    """*values* (n_range, n) float32 interpolated along their last axis every 1/upsampling bin
    by Catmull-Rom splines (cubic, continuous slopes, through every bin's value; the edge bins
    repeated beyond the axis): (n_range, (n - 1) * upsampling + 1) float32."""
    n = values.shape[1]
    padded = np.concatenate([values[:, :1], values, values[:, -1:], values[:, -1:]], axis=1)
    before, at, after, next_ = (padded[:, j:j + n - 1] for j in range(4))
    out = np.empty((values.shape[0], (n - 1) * upsampling + 1), np.float32)
    out[:, ::upsampling] = values
    for phase in range(1, upsampling):
        t = phase / upsampling
        w = np.float32([(-t**3 + 2 * t**2 - t) / 2, (3 * t**3 - 5 * t**2 + 2) / 2,
                        (-3 * t**3 + 4 * t**2 + t) / 2, (t**3 - t**2) / 2])
        out[:, phase::upsampling] = w[0] * before + w[1] * at + w[2] * after + w[3] * next_
    return out
