"""CFAR detection: cell-averaging (CA), greatest-of (CAGO), smallest-of (CASO) and
ordered-statistic (OS), along one axis of a linear-power array, and TI's two-pass
range-then-Doppler detection on a range-Doppler map.

Conventions
-----------
* Input is **linear power** (``|X|^2``, or its sum over the virtual array), never dB.
* Each side of the cell under test (CUT) has ``guard`` guard cells next to it and
  ``train`` training cells beyond them; ``N = 2 * train`` training cells in all.
* The noise estimate of a cell is, in the power units of the input:

  - ``ca``: the mean of the N training cells;
  - ``cago`` / ``caso``: the greater / smaller of the left and right training means;
  - ``os``: the ``k``-th smallest of the N training cells (``k = os_rank``, by default
    0.75 N rounded half up).  This is the order statistic itself, not a mean-power
    estimate: for exponential noise of mean ``mu`` its expectation is
    ``mu * sum_{i=0}^{k-1} 1 / (N - i)`` (about ``1.30 mu`` for N = 16, k = 12);
    :attr:`CfarParams.noise_factor` gives that ratio for every method, so that an SNR can be
    against the mean noise.

* A cell is detected when ``power > scale * noise``.  ``scale`` (alpha, a linear power
  ratio) is either ``10 ** (threshold_db / 10)`` or derived from a false-alarm
  probability ``pfa`` (:mod:`.cfar_pfa` has the formulas): for exponentially distributed
  power independent from cell to cell, for cells that sum several channels' powers
  (:attr:`CfarParams.channels`), and for neighbouring cells correlated by a window
  (:attr:`CfarParams.correlation`).

* Edges.  ``cyclic=True`` wraps the window around (right for Doppler, whose FFT bins
  are periodic).  ``cyclic=False`` uses, for a cell whose window runs off one end, the
  ``train`` training cells of the other side only (as TI's ``cfarCfg`` with cyclic 0
  does); every method is then CA over those ``train`` cells (OS: rank ``k * train / N``,
  rounded half up, at least 1), and with ``pfa`` the edge cells get their own scale
  (:attr:`CfarParams.edge_scale`) so the false-alarm rate holds there too.  With
  ``threshold_db`` the one threshold applies everywhere, as on the radar.

The implementation is vectorised: shifted sums for the cell-averaging family and
``sliding_window_view`` + ``np.partition`` for OS; no Python loop runs over cells.

Imports neither :mod:`radarodom.driver` nor zenoh.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ..errors import UsageError
from .cfar_params import METHODS, CfarParams, _round_half_up  # noqa: F401 (CfarParams' home, re-exported)

log = logging.getLogger(__name__)

# --------------------------------------------------------------------------- 1-D CFAR
def _check_power(power: Any, name: str = "power") -> np.ndarray:
    arr = np.asarray(power)
    if arr.dtype.kind not in "uif":
        raise UsageError(f"{name} must be real linear power (float or int), got dtype {arr.dtype}"
                         + ("; pass |X|**2" if arr.dtype.kind == "c" else ""))
    if arr.ndim == 0:
        raise UsageError(f"{name} must have at least one axis")
    if arr.size and not np.isfinite(arr).all():
        raise UsageError(f"{name} holds NaN or infinite values")
    if arr.size and arr.min() < 0:
        raise UsageError(f"{name} holds negative values; CFAR works on linear power (>= 0)")
    return arr


def _check_length(n: int, params: CfarParams, what: str) -> None:
    if n < params.window:
        raise UsageError(f"{what} has {n} cells; a CFAR window of guard {params.guard} and train "
                         f"{params.train} needs at least 2 * (guard + train) + 1 = {params.window}")


def _pad_last(x: np.ndarray, p: int, cyclic: bool) -> np.ndarray:
    """*x* padded by *p* cells each side of its last axis: zeros, or wrapped around.  The
    same values as np.pad's "constant" and "wrap", by slices (np.pad's generality cost
    70 us a call, a tenth of the map's CFAR)."""
    n = x.shape[-1]
    if p > n:  # wraps more than once: np.pad's rule
        widths = [(0, 0)] * (x.ndim - 1) + [(p, p)]
        return np.pad(x, widths, mode="wrap") if cyclic else np.pad(x, widths, mode="constant")
    out = np.empty(x.shape[:-1] + (n + 2 * p,), x.dtype)
    out[..., p:p + n] = x
    if cyclic:
        out[..., :p] = x[..., n - p:]
        out[..., p + n:] = x[..., :p]
    else:
        out[..., :p] = 0
        out[..., p + n:] = 0
    return out


def _noise_ca_family(x: np.ndarray, params: CfarParams) -> np.ndarray:
    """Noise estimate (shape and float type of *x*) along the last axis for ca/cago/caso.

    With p = guard + train and the input padded by p each side, the left training
    cells of cell i are padded [i, i + train) and the right ones
    [i + 2p + 1 - train, i + 2p + 1): both are sums of *train* consecutive cells,
    formed once for every start by adding *train* shifted slices.  (A cumulative
    sum would need float64 to survive the map's dynamic range, and costs 7x more.)
    """
    n, g, t = x.shape[-1], params.guard, params.train
    p = g + t
    xp = _pad_last(x, p, params.cyclic)
    m = xp.shape[-1] - t + 1
    sums = xp[..., 0:m].copy()
    for k in range(1, t):
        sums += xp[..., k:k + m]
    sums /= t
    left = sums[..., 0:n]
    right = sums[..., 2 * p + 1 - t:2 * p + 1 - t + n]
    if params.method == "ca":
        noise = 0.5 * (left + right)
    elif params.method == "cago":
        noise = np.maximum(left, right)
    else:
        noise = np.minimum(left, right)
    if not params.cyclic:  # (noise is a new array here, never a view of sums)
        noise[..., :p] = right[..., :p]          # left window off the start
        noise[..., n - p:] = left[..., n - p:]   # right window off the end
    return noise


def _kth(windows: np.ndarray, k: int) -> np.ndarray:
    """k-th smallest (1-based) along the last axis."""
    return np.partition(windows, k - 1, axis=-1)[..., k - 1]


def _noise_os(x: np.ndarray, params: CfarParams) -> np.ndarray:
    """Noise estimate (float64, shape of *x*) along the last axis for OS."""
    n, g, t = x.shape[-1], params.guard, params.train
    p = g + t
    x = x.astype(np.float64, copy=False)
    train_cols = np.r_[0:t, t + 2 * g + 1:2 * p + 1]  # positions of the training cells in a window
    if params.cyclic:
        win = sliding_window_view(_pad_last(x, p, True), 2 * p + 1, axis=-1)  # (..., n, 2p+1)
        return _kth(win[..., train_cols], params.rank)
    interior = _kth(sliding_window_view(x, 2 * p + 1, axis=-1)[..., train_cols], params.rank)
    k_e = params.edge_rank
    # Cells 0..p-1: right training cells [i+g+1, i+g+t]; cells n-p..n-1: left [i-p, i-p+t-1].
    start = _kth(sliding_window_view(x[..., g + 1:g + p + t], t, axis=-1), k_e)
    end = _kth(sliding_window_view(x[..., n - 2 * p:n - p - 1 + t], t, axis=-1), k_e)
    return np.concatenate([start, interior, end], axis=-1)


def _cfar_last_axis(x: np.ndarray, params: CfarParams) -> tuple[np.ndarray, np.ndarray]:
    """CFAR along the last axis of validated power *x*: (detections, noise float64)."""
    n = x.shape[-1]
    if params.method == "os":
        noise = _noise_os(x, params)
    else:
        noise = _noise_ca_family(x, params)
    if params.cyclic or params.edge_scale == params.scale:
        threshold = params.scale * noise
    else:
        i = np.arange(n)
        p = params.guard + params.train
        scale = np.where((i < p) | (i > n - 1 - p), params.edge_scale, params.scale)
        threshold = scale * noise
    return x > threshold, noise


def cfar_1d(power: np.ndarray, params: CfarParams, axis: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """CFAR along one axis of a linear-power array.

    Parameters
    ----------
    power
        Linear power (>= 0, finite), any shape ``S``, float32/float64 (ints accepted);
        units: any power unit (e.g. ADC counts^2).  The CFAR runs along ``axis``, which
        needs at least ``params.window`` = 2 * (guard + train) + 1 cells.
    params
        The detector (:class:`CfarParams`).
    axis
        Axis to slide the window along (range or Doppler bins).

    Returns
    -------
    detections
        bool, shape ``S``: ``power > scale * noise`` (``edge_scale`` at non-cyclic ends).
    noise
        Noise estimate per cell, shape ``S``, in the units of *power*; dtype that of
        *power* if floating, else float64.  Computed in float64.

    Raises :class:`UsageError` for non-real, negative or non-finite power, a bad axis or
    an axis shorter than the window.
    """
    if not isinstance(params, CfarParams):
        raise UsageError(f"params must be CfarParams, got {type(params).__name__}")
    arr = _check_power(power)
    try:
        x = np.moveaxis(arr, axis, -1)
    except ValueError:  # numpy's AxisError is a ValueError
        raise UsageError(f"axis {axis} is out of range for power shaped {arr.shape}") from None
    _check_length(x.shape[-1], params, f"axis {axis} of power shaped {arr.shape}")
    det, noise = _cfar_last_axis(x, params)
    out_dtype = arr.dtype if arr.dtype.kind == "f" else np.float64
    return np.moveaxis(det, -1, axis), np.moveaxis(noise.astype(out_dtype, copy=False), -1, axis)


# --------------------------------------------------------------------------- 2-D, TI-like
@dataclass(frozen=True, eq=False)
class Detections:
    """Cells detected on a range-Doppler map, in row-major (Doppler, range) order.

    Arrays are 1-D, one entry per detection (length ``len(self)``).
    """

    #: Row (Doppler bin) of the map, int (np.intp).
    doppler_idx: np.ndarray
    #: Column (range bin) of the map, int (np.intp).
    range_idx: np.ndarray
    #: 10 log10(power / noise) of the range pass, dB (float64; inf if the noise is 0).
    snr_db: np.ndarray
    #: Range-pass noise estimate, linear power in the map's units (float64).
    noise: np.ndarray

    def __len__(self) -> int:
        return int(self.range_idx.size)


def _local_max(p: np.ndarray, cells: tuple[np.ndarray, np.ndarray], axis: int, cyclic: bool) -> np.ndarray:
    """For each of *cells* (row indices, column indices into 2-D *p*): True where its value
    is >= both its neighbours along *axis* (missing neighbours at non-cyclic ends are
    ignored).  Only the given cells are read (a few hundred detections, not the map's tens
    of thousands of cells)."""
    n = p.shape[axis]
    value = p[cells]
    if n < 2:
        return np.ones(value.shape, dtype=bool)
    i = cells[axis]
    before, after = list(cells), list(cells)
    if cyclic:
        before[axis], after[axis] = (i - 1) % n, (i + 1) % n
    else:  # at an end the clamped neighbour is the cell itself: value >= value holds
        before[axis], after[axis] = np.maximum(i - 1, 0), np.minimum(i + 1, n - 1)
    return (value >= p[tuple(before)]) & (value >= p[tuple(after)])


def check_map(power_rd: Any, range_params: CfarParams, doppler_params: CfarParams) -> np.ndarray:
    """*power_rd* as an array, after checking it is a linear-power (doppler_bins, range_bins) map
    on which both detectors' windows fit (:class:`UsageError` otherwise)."""
    for name, prm in (("range_params", range_params), ("doppler_params", doppler_params)):
        if not isinstance(prm, CfarParams):
            raise UsageError(f"{name} must be CfarParams, got {type(prm).__name__}")
    p = _check_power(power_rd, "power_rd")
    if p.ndim != 2:
        raise UsageError(f"power_rd must be 2-D (doppler_bins, range_bins), got shape {p.shape}")
    n_d, n_r = p.shape
    _check_length(n_r, range_params, f"the range axis of power_rd shaped {p.shape}")
    _check_length(n_d, doppler_params, f"the Doppler axis of power_rd shaped {p.shape}")
    return p


def cfar_2d_ti(power_rd: np.ndarray, range_params: CfarParams, doppler_params: CfarParams, *,
               peak_grouping: bool = True) -> Detections:
    """TI-like two-pass CFAR on a range-Doppler power map.

    Pass 1 runs ``range_params`` along range for every Doppler bin; pass 2 runs
    ``doppler_params`` along Doppler, only over the range bins pass 1 found something
    in, and a cell is kept when both passes detect it (the order of the xWR18xx demo's
    ``cfarCfg`` lines: range with procDirection 0, Doppler with 1).  With
    ``peak_grouping``, a cell is kept only if its power is >= that of its neighbours at
    +/-1 range bin and at +/-1 Doppler bin, read from the map whether detected or not
    (TI's detection-matrix based grouping); neighbours wrap around where the pass is
    cyclic.

    Parameters
    ----------
    power_rd
        Linear power, shape (doppler_bins, range_bins), float32/float64, >= 0.
        Doppler rows may be in FFT or fftshifted order; indices are rows as given.
    range_params, doppler_params
        Detectors of the two passes.

    Returns
    -------
    :class:`Detections`; ``noise`` and ``snr_db`` come from the range pass.
    """
    p = check_map(power_rd, range_params, doppler_params)
    det, noise_r = _cfar_last_axis(p, range_params)
    cols = np.flatnonzero(det.any(axis=0))
    if cols.size:
        det_d, _ = _cfar_last_axis(np.ascontiguousarray(p[:, cols].T), doppler_params)
        det[:, cols] &= det_d.T
    d_idx, r_idx = np.nonzero(det)
    if peak_grouping and d_idx.size:
        peak = (_local_max(p, (d_idx, r_idx), 1, range_params.cyclic)
                & _local_max(p, (d_idx, r_idx), 0, doppler_params.cyclic))
        d_idx, r_idx = d_idx[peak], r_idx[peak]
    noise = noise_r[d_idx, r_idx]
    with np.errstate(divide="ignore"):
        snr_db = 10.0 * np.log10(p[d_idx, r_idx].astype(np.float64) / noise)
    return Detections(d_idx, r_idx, snr_db, noise)


__all__ = ["METHODS", "CfarParams", "Detections", "cfar_1d", "cfar_2d_ti", "check_map"]
