"""Two-pass CFAR on a range-Doppler map, evaluated at the map's peaks only.

With peak grouping (a detection must be at least as strong as its neighbours at +/-1 range bin
and +/-1 Doppler bin), only the map's local maxima can be detected.  This detector therefore
finds those first, a fifth of the cells in noise and a few hundred on a radar frame, and runs
the range and the Doppler CFAR (:class:`~.cfar.CfarParams`, any method) on them alone, by
gathering each one's training cells.  The result is that of :func:`~.cfar.cfar_2d_ti` with
``peak_grouping=True``, cell for cell, for a fraction of the work; above all it makes the
ordered-statistic CFAR affordable (a partial sort of 16 cells per peak instead of per cell).

Edges follow :mod:`.cfar`: a cyclic axis wraps; on a non-cyclic one a cell whose window runs off
one end uses the other side's ``train`` cells only, with the one-sided scale
(:attr:`~.cfar.CfarParams.edge_scale`) and, for OS, the one-sided rank.
"""

from __future__ import annotations

import numpy as np

from .cfar import CfarParams, Detections, _cfar_last_axis, check_map


def local_maxima(power: np.ndarray, range_cyclic: bool = False, doppler_cyclic: bool = True,
                 reach: tuple[int, int] = (1, 1)) -> np.ndarray:
    """Cells at least as strong as their neighbours up to *reach* = (Doppler, range) cells either
    side (1, 1: the +/-1 bin neighbours): bool, the shape of *power* (doppler_bins, range_bins).
    A neighbour beyond a non-cyclic end does not count."""
    p = power
    peak = np.ones(p.shape, bool)
    for axis, cyclic, cells in ((1, range_cyclic, reach[1]), (0, doppler_cyclic, reach[0])):
        q = np.moveaxis(p, axis, 0)
        out = np.moveaxis(peak, axis, 0)  # a view: writing it writes peak
        n = q.shape[0]
        for s in range(1, min(cells, n - 1) + 1):
            out[s:] &= q[s:] >= q[:-s]
            out[:-s] &= q[:-s] >= q[s:]
            if cyclic:
                out[:s] &= q[:s] >= q[n - s:]
                out[n - s:] &= q[n - s:] >= q[:s]
    return peak


def _noise_at(take, centre: np.ndarray, length: int, params: CfarParams) -> tuple[np.ndarray, np.ndarray]:
    """Noise estimates of cells at positions *centre* (n,) along an axis of *length* cells;
    ``take(idx)`` reads the cells at positions idx (n, k) on each one's line.  Returns (noise
    float64 (n,), scale (n,)), the scale one-sided where the window runs off a non-cyclic end."""
    n_cells = len(centre)
    g, t = params.guard, params.train
    offsets = np.arange(g + 1, g + t + 1)
    left_idx = centre[:, None] - offsets[None, ::-1]
    right_idx = centre[:, None] + offsets[None, :]
    if params.cyclic:
        left = take(left_idx % length).astype(np.float64)
        right = take(right_idx % length).astype(np.float64)
        return _estimate(left, right, params), np.full(n_cells, params.scale)
    left_ok = centre - g - t >= 0
    right_ok = centre + g + t <= length - 1
    left = take(np.clip(left_idx, 0, length - 1)).astype(np.float64)
    right = take(np.clip(right_idx, 0, length - 1)).astype(np.float64)
    noise = _estimate(left, right, params)
    scale = np.full(n_cells, params.scale)
    for side, values in ((~left_ok, right), (~right_ok, left)):  # windows off one end: the other side
        if side.any():
            noise[side] = _one_sided(values[side], params)
            scale[side] = params.edge_scale
    return noise, scale


def _estimate(left: np.ndarray, right: np.ndarray, params: CfarParams) -> np.ndarray:
    """Two-sided noise from each cell's left and right training cells, (n, train) each."""
    if params.method == "os":
        both = np.concatenate([left, right], axis=1)
        return np.partition(both, params.rank - 1, axis=1)[:, params.rank - 1]
    a, b = left.mean(axis=1), right.mean(axis=1)
    if params.method == "ca":
        return 0.5 * (a + b)
    return np.maximum(a, b) if params.method == "cago" else np.minimum(a, b)


def _one_sided(values: np.ndarray, params: CfarParams) -> np.ndarray:
    if params.method == "os":
        return np.partition(values, params.edge_rank - 1, axis=1)[:, params.edge_rank - 1]
    return values.mean(axis=1)


def cfar_peaks(power_rd: np.ndarray, range_params: CfarParams, doppler_params: CfarParams, *,
               range_bins: np.ndarray | None = None, reach: tuple[int, int] = (1, 1)) -> Detections:
    """The map's local maxima that both CFAR passes detect.

    Parameters
    ----------
    power_rd
        Linear power, (doppler_bins, range_bins), float32/float64, >= 0.
    range_params, doppler_params
        The detectors along range and along Doppler.
    range_bins
        Optional bool (range_bins,): only peaks in these range bins are tested (the rest of the
        map still serves as their training cells).
    reach
        (Doppler, range) cells either side a peak is the strongest of (:func:`local_maxima`).

    Returns
    -------
    :class:`~.cfar.Detections` in row-major (Doppler, range) order; ``noise`` and ``snr_db`` from
    the range pass, as :func:`~.cfar.cfar_2d_ti`.
    """
    p = check_map(power_rd, range_params, doppler_params)
    n_d, n_r = p.shape
    peaks = local_maxima(p, range_params.cyclic, doppler_params.cyclic, reach)
    if range_bins is not None:
        peaks &= np.asarray(range_bins, bool)[None, :]
    # The Doppler pass first: it leaves the range pass (the ordered statistic, by default) a few
    # peaks per hundred; the order changes no result.  A cell-averaging pass runs on the whole
    # map by shifted sums, cheaper than gathering each peak's training cells.
    if doppler_params.method != "os":
        detected, _ = _cfar_last_axis(np.ascontiguousarray(p.T), doppler_params)
        peaks &= detected.T
    d_idx, r_idx = np.nonzero(peaks)
    value = p[d_idx, r_idx].astype(np.float64)
    if doppler_params.method == "os":
        noise_d, scale_d = _noise_at(lambda idx: p[idx, r_idx[:, None]], d_idx, n_d, doppler_params)
        keep = value > scale_d * noise_d
        d_idx, r_idx, value = d_idx[keep], r_idx[keep], value[keep]
    noise_r, scale_r = _noise_at(lambda idx: p[d_idx[:, None], idx], r_idx, n_r, range_params)
    keep = value > scale_r * noise_r
    d_idx, r_idx, value, noise_r = d_idx[keep], r_idx[keep], value[keep], noise_r[keep]
    with np.errstate(divide="ignore"):
        snr_db = 10.0 * np.log10(value / noise_r)
    return Detections(d_idx, r_idx, snr_db, noise_r)


def above_skirts(power_rd: np.ndarray, det: Detections, below_db: float, span: int) -> np.ndarray:
    """bool (len(det),): detections that are not more than *below_db* weaker than another
    detection within *span* range bins in their Doppler row.

    A strong target's range spectrum has a skirt: the window's sidelobes (a Hann window's are
    31 dB down at 2.5 bins and fall 18 dB an octave) lifted by its range migration over the
    frame; an ordered-statistic or smallest-of CFAR, which looks past the strong target, can
    find a peak of that skirt.  A reflector that much weaker that close is below the range
    spectrum's dynamic range anyway.
    """
    n = len(det)
    if n < 2:
        return np.ones(n, bool)
    value = power_rd[det.doppler_idx, det.range_idx].astype(np.float64)
    # The detections alone on a map of zeros, each cell's strongest within span along range:
    # linear in the map's size whatever the number of detections.
    only = np.zeros(power_rd.shape, np.float64)
    only[det.doppler_idx, det.range_idx] = value
    import scipy.ndimage  # here: a program that never detects does not import it

    strongest = scipy.ndimage.maximum_filter1d(only, size=2 * span + 1, axis=1, mode="constant", cval=0.0)
    return value * 10 ** (below_db / 10) >= strongest[det.doppler_idx, det.range_idx]


__all__ = ["above_skirts", "cfar_peaks", "local_maxima"]
