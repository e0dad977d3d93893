"""The FFT backend of the frame processor: scipy.fft, or FFTW through pyFFTW.

The processor's FFTs have fixed shapes, so they can be planned once per
configuration.  FFTW (``pip install "radarodom[fftw]"``) runs such planned,
batched single-precision transforms two to three times faster than scipy's
pocketfft on this project's frames (bench/bench_dsp.py measures both);
scipy.fft stays the backend of a plain install.

Plans use ``FFTW_ESTIMATE``: the plan then depends on the shapes alone, not on
timings taken while planning, so a frame gives the same bits in every run.
"""

from __future__ import annotations

import functools
import importlib.util
import logging
import sys

import numpy as np

from ..errors import ConfigError

log = logging.getLogger(__name__)

#: The names DspConfig.fft takes.
BACKENDS = ("auto", "scipy", "fftw")


def _import_pyfftw():
    """pyFFTW, imported without its Dask interface where Dask is not imported yet: pyFFTW's
    interfaces import dask.array when it is installed, for an interface this package never uses,
    and that import was a good part of a program's start (docs/benchmarks.md, "Start-up")."""
    hide = "dask" not in sys.modules
    if hide:
        sys.modules["dask"] = None  # an import of dask raises ImportError, which pyFFTW expects
    try:
        import pyfftw
    finally:
        if hide and "dask" in sys.modules and sys.modules["dask"] is None:
            del sys.modules["dask"]
    return pyfftw


@functools.cache
def fftw_available() -> bool:
    """Whether pyFFTW imports (installed, and its bundled FFTW loads)."""
    try:
        _import_pyfftw()
    except ImportError as exc:
        if importlib.util.find_spec("pyfftw") is not None:
            log.warning("pyFFTW is installed but does not import (%s): using scipy.fft", exc)
        return False
    return True


def resolve_backend(name: str) -> str:
    """"scipy" or "fftw" for a (validated) DspConfig.fft value ("auto": FFTW when installed)."""
    if name == "auto":
        name = "fftw" if fftw_available() else "scipy"
        log.debug("FFT backend: %s", name)
        return name
    if name == "fftw" and not fftw_available():
        raise ConfigError('FFTW was asked for but pyFFTW is not installed: pip install "radarodom[fftw]"',
                          field="fft")
    return name


def spectrum_ffts(cube_shape: tuple[int, int, int, int], n_range: int, n_doppler: int, backend: str,
                  workers: int) -> SpectrumFFTs:
    """The frame processor's two transforms by *backend* ("scipy" or "fftw": :func:`resolve_backend`)."""
    return (FftwFFTs if backend == "fftw" else ScipyFFTs)(cube_shape, n_range, n_doppler, workers)


class SpectrumFFTs:
    """The frame processor's two transforms for one cube shape, with their buffers.

    *cube_shape*: (loops, tx_slots, rx, samples); the range FFT has *n_range* points over the
    samples and the Doppler FFT *n_doppler* over the loops (zero-padded when larger).
    Write the windowed samples into :attr:`samples`, then call :meth:`range` and
    :meth:`doppler`.  Results may live in reused buffers: valid until the next frame.
    """

    samples: np.ndarray

    def __init__(self, n_range: int, n_doppler: int, workers: int) -> None:
        self.n_range, self.n_doppler, self.workers = n_range, n_doppler, workers

    def range(self) -> np.ndarray:
        """FFT of :attr:`samples` over the samples: complex64 (loops, tx_slots, rx, n_range)."""
        raise NotImplementedError

    def doppler(self, range_spectrum: np.ndarray) -> np.ndarray:
        """FFT over the loops of a range spectrum (loops, tx_slots, rx, n_range), which it may
        overwrite: complex64 (n_doppler, tx_slots, rx, n_range), uncentred."""
        raise NotImplementedError


class ScipyFFTs(SpectrumFFTs):
    """scipy.fft's pocketfft, which pads to the transform's length itself."""

    def __init__(self, cube_shape: tuple[int, int, int, int], n_range: int, n_doppler: int, workers: int) -> None:
        import scipy.fft  # here: a program that refuses its input before any frame does not import it

        super().__init__(n_range, n_doppler, workers)
        self._fft = scipy.fft.fft
        self.samples = np.empty(cube_shape, np.complex64)

    def range(self) -> np.ndarray:
        # The samples are rewritten every frame, so they may go.
        return self._fft(self.samples, n=self.n_range, axis=-1, workers=self.workers, overwrite_x=True)

    def doppler(self, range_spectrum: np.ndarray) -> np.ndarray:
        return self._fft(range_spectrum, n=self.n_doppler, axis=0, workers=self.workers, overwrite_x=True)


class FftwFFTs(SpectrumFFTs):
    """pyFFTW's plans of the two transforms, made once, over aligned buffers."""

    def __init__(self, cube_shape: tuple[int, int, int, int], n_range: int, n_doppler: int, workers: int) -> None:
        pyfftw = _import_pyfftw()
        super().__init__(n_range, n_doppler, workers)
        loops, slots, nrx, ns = cube_shape
        # Zeros past the samples are the range FFT's zero padding: written once, never
        # overwritten.  The Doppler FFT runs in place, so its padding rows (past the loops)
        # are zeroed again before each run.
        self._padded = pyfftw.zeros_aligned((loops, slots, nrx, n_range), np.complex64)
        self.samples = self._padded[..., :ns]
        self._spectrum = pyfftw.zeros_aligned((n_doppler, slots, nrx, n_range), np.complex64)
        self._range_out = self._spectrum[:loops]
        flags = ("FFTW_ESTIMATE",)
        self._range_plan = pyfftw.FFTW(self._padded, self._range_out, axes=(3,), flags=flags, threads=workers)
        self._doppler_plan = pyfftw.FFTW(self._spectrum, self._spectrum, axes=(0,), flags=flags, threads=workers)

    def range(self) -> np.ndarray:
        self._range_plan.execute()
        return self._range_out

    def doppler(self, range_spectrum: np.ndarray) -> np.ndarray:
        loops = len(self._range_out)
        if range_spectrum is not self._range_out:
            self._range_out[...] = range_spectrum
        if self.n_doppler > loops:
            self._spectrum[loops:] = 0
        self._doppler_plan.execute()
        return self._spectrum
