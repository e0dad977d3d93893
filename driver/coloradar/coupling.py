"""ColoRadar's TX-to-RX coupling calibration, ``calib/<sensor>/coupling_calib.txt``.

Each radar of the dataset ships the leakage from its transmitters into its receivers as its
official processing removes it (coloradar-library, ``cubeToHeatmap``; the dataset's Python tools,
``read_coupling_cfg``): every chirp's samples times a periodic Blackman window, an unnormalised
FFT of as many points as samples, and the coupling subtracted from bins 1 .. num_range_bins (the
DC bin is skipped: value r belongs to FFT bin r + 1), the same for every chirp.

The file is ``key: value`` lines, in this order::

    num_tx: 3
    num_rx: 4
    num_range_bins: 64
    num_doppler_bins: 16
    data: re,im,re,im,...      2 * num_tx * num_rx * num_range_bins numbers

with the values ordered [tx][rx][range bin] (range fastest), real and imaginary interleaved;
tx is the ADC frame's TX index (the cube's TX slot, :func:`.coloradar.adc_to_cube`).
"""

from __future__ import annotations

import math
import os

import numpy as np

from ...calibration import RangeCoupling
from ...errors import CaptureError, CaptureFormatError
from .files import check_run_file

_KEYS = ("num_tx", "num_rx", "num_range_bins", "num_doppler_bins", "data")
#: Range-FFT bin of the first value (the official processing skips the DC bin).
FIRST_BIN = 1


def periodic_blackman(n: int) -> np.ndarray:
    """The official processing's window: 0.42 - 0.5 cos(2 pi i / n) + 0.08 cos(4 pi i / n), (n,)."""
    return np.blackman(n + 1)[:-1]


#: A coupling value's part larger than this is no range FFT of a chirp of 16-bit samples (the
#: largest, 32768 times the samples, is some 1e7 for the 256 a chirp takes at most here).
MAX_COUPLING = 1e9


def read_coupling(path: str | os.PathLike, num_samples: int) -> RangeCoupling:
    """The coupling of a radar whose chirps have *num_samples* samples; errors name the file."""
    path = os.fspath(path)
    check_run_file(path)
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            lines = [(n, line.strip()) for n, line in enumerate(fh, start=1) if line.strip()]
    except OSError as exc:
        raise CaptureError(f"cannot read {path}: {exc.strerror or exc}") from None
    fields: dict[str, tuple[int, str]] = {}
    for lineno, text in lines:
        key, sep, rest = text.partition(":")
        key = key.strip()
        if not sep or key not in _KEYS:
            raise CaptureFormatError(f"{path}:{lineno}: expected one of {', '.join(k + ':' for k in _KEYS)}, "
                                     f"got {text[:60]!r}")
        if key in fields:
            raise CaptureFormatError(f"{path}:{lineno}: {key} given twice")
        fields[key] = (lineno, rest.strip())
    missing = [k for k in _KEYS if k not in fields]
    if missing:
        raise CaptureFormatError(f"{path}: missing {', '.join(missing)}")
    sizes = {}
    for key in _KEYS[:4]:
        lineno, text = fields[key]
        if not text.isdigit() or int(text) <= 0:
            raise CaptureFormatError(f"{path}:{lineno}: {key} must be a positive integer, got {text!r}")
        sizes[key] = int(text)
    lineno, text = fields["data"]
    try:
        data = np.array([float(v) for v in text.replace(",", " ").split()])
    except ValueError:
        raise CaptureFormatError(f"{path}:{lineno}: data must be numbers separated by commas") from None
    expected = 2 * sizes["num_tx"] * sizes["num_rx"] * sizes["num_range_bins"]
    if len(data) != expected:
        raise CaptureFormatError(f"{path}:{lineno}: data holds {len(data)} numbers; 2 x num_tx x num_rx x "
                                 f"num_range_bins is {expected}")
    if not np.all(np.isfinite(data)):
        raise CaptureFormatError(f"{path}:{lineno}: data holds a number that is not finite")
    too_large = np.flatnonzero(np.abs(data) > MAX_COUPLING)
    if len(too_large):  # (it overflowed the DSP's float32, and the error blamed the ADC frame)
        raise CaptureFormatError(f"{path}:{lineno}: data's number {too_large[0] + 1} is {data[too_large[0]]:g}, more "
                                 f"than {MAX_COUPLING:g}: no range FFT of a 16-bit ADC's chirp comes near it")
    if FIRST_BIN + sizes["num_range_bins"] > num_samples:
        raise CaptureFormatError(f"{path}: {sizes['num_range_bins']} range bins from bin {FIRST_BIN} do not fit "
                                 f"a {num_samples}-point range FFT (waveform_cfg.txt's samples per chirp)")
    values = (data[0::2] + 1j * data[1::2]).reshape(sizes["num_tx"], sizes["num_rx"], sizes["num_range_bins"])
    return RangeCoupling(values, FIRST_BIN, periodic_blackman(num_samples), origin=path)


def coupling_file_text(values: np.ndarray, num_doppler_bins: int) -> str:
    """A coupling_calib.txt holding complex *values* (tx, rx, range bins) (the inverse of
    :func:`read_coupling`, for tests and tools)."""
    v = np.asarray(values)
    pairs = np.stack([v.real.ravel(), v.imag.ravel()], axis=1).ravel()
    if not all(math.isfinite(x) for x in pairs):
        raise CaptureFormatError("coupling values must be finite")
    return (f"num_tx: {v.shape[0]}\nnum_rx: {v.shape[1]}\nnum_range_bins: {v.shape[2]}\n"
            f"num_doppler_bins: {num_doppler_bins}\ndata: " + ",".join(repr(float(x)) for x in pairs) + "\n")


__all__ = ["FIRST_BIN", "coupling_file_text", "periodic_blackman", "read_coupling"]
