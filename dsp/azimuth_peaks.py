"""Several reflectors in one range-Doppler cell: their azimuths one at a time (CLEAN).

A sensor at rest puts the whole static world in the zero-Doppler bin, and a robot driving
straight puts mirror-image directions (left and right at the same angle) in one Doppler bin:
reflectors at the same range then share a range-Doppler cell, and the strongest azimuth peak
alone would keep one of them.  After the strongest, its plane wave is taken out of the cell's
samples (the azimuth row, the raised row and the Doppler rows either side, each by its own
least-squares amplitude), which removes its sidelobes with it, and the next peak is looked
for in what is left.  A peak is a reflector when it stands far enough over the noise and not
too far under the cell's first peak (what a calibration error leaves of a removed plane
wave), and lies apart from the peaks before it.

Arrays: n detections; the azimuth row's elements at horizontal positions ``az_h`` (half
wavelengths), the raised row's at ``el_h``; a plane wave from direction Wx (the sine of the
azimuth times the cosine of the elevation) has phase ``pi h Wx`` on element h (the azimuth
FFT's convention: peak bin k at Wx = 2 k / n_az).
"""

from __future__ import annotations

import numpy as np


def plane_waves(wx: np.ndarray, h: np.ndarray) -> np.ndarray:
    """exp(j pi h Wx) for directions *wx* (n,) on elements at *h* (e,): complex64 (n, e)."""
    return np.exp(1j * np.pi * np.outer(wx, h)).astype(np.complex64)


def remove_plane_wave(samples: np.ndarray, steer: np.ndarray) -> None:
    """Take each row's least-squares multiple of its plane wave out of *samples* (n, e), in place."""
    amplitude = np.einsum("ne,ne->n", samples, np.conj(steer)) / steer.shape[1]
    samples -= amplitude[:, None] * steer


class CellCleaner:
    """Removes found reflectors' plane waves from detections' samples (see the module docstring).

    *az_elements*, *el_elements*: flat indices of the azimuth and the raised row's elements in a
    detection's (elements,) samples; *az_h*, *el_h*: their horizontal positions.
    """

    def __init__(self, az_elements: np.ndarray, az_h: np.ndarray, el_elements: np.ndarray,
                 el_h: np.ndarray) -> None:
        self.az_elements, self.az_h = az_elements, az_h.astype(float)
        self.el_elements, self.el_h = el_elements, el_h.astype(float)

    def remove(self, elements: np.ndarray, sides: np.ndarray | None, wx: np.ndarray) -> None:
        """Take the plane waves from directions *wx* (n,) out of *elements* (n, elements) and of
        *sides* (n, 2, azimuth row elements: the Doppler rows either side), in place."""
        steer = plane_waves(wx, self.az_h)
        row = elements[:, self.az_elements]
        remove_plane_wave(row, steer)
        elements[:, self.az_elements] = row
        if len(self.el_elements):
            raised = elements[:, self.el_elements]
            remove_plane_wave(raised, plane_waves(wx, self.el_h))
            elements[:, self.el_elements] = raised
        if sides is not None:
            for j in range(sides.shape[1]):
                side = sides[:, j]
                remove_plane_wave(side, steer)
                sides[:, j] = side


def apart(k: np.ndarray, taken: list[np.ndarray], n_az: int, min_bins: float) -> np.ndarray:
    """True where azimuth FFT bin *k* (n,) lies at least *min_bins* (cyclic) from every bin of
    *taken* (each (n,), fractional)."""
    ok = np.ones(len(k), bool)
    for t in taken:
        d = np.abs((k - t + n_az / 2) % n_az - n_az / 2)
        ok &= d >= min_bins
    return ok


__all__ = ["CellCleaner", "apart", "plane_waves", "remove_plane_wave"]
