"""The density of the points' map (``point_yaw.density_weighted``, docs/heading.md item 38): at
each map point, the map's Gaussians summed there, its own included, kept up to date as frames enter
and leave the map rather than worked out anew each frame.

A frame entering adds its Gaussians' values at the map's points to their densities, and the map's
Gaussians' values at its own points to its own, held per older frame: the map drops its frames
oldest first, so when a frame leaves, every frame still in the map drops the row it holds for it,
and a frame's Gaussians at points entered after it never need taking out (those leave after it).
A Gaussian is left out wherever its value is below exp(-4.5) = 0.011 (a squared Mahalanobis
distance above 9), so that each pair's term is the same whenever the pair met.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

#: The squared Mahalanobis distance beyond which a Gaussian is left out of the density.
_CUT = 9.0

#: A frame's points placed in the world (k, 2) m, their inverse covariances (k, 2, 2) 1/m^2 and
#: largest standard deviations (k,) m, as the map holds them.
Gaussians = tuple[np.ndarray, np.ndarray, np.ndarray]


def gaussian_values(d: np.ndarray, inverse: np.ndarray) -> np.ndarray:
    """The values (pairs,) of Gaussians (inverse covariances *inverse* (pairs, 2, 2) 1/m^2, 1 at
    their centres) at the offsets *d* (pairs, 2) m from their centres; 0 beyond the cut."""
    m = np.einsum("pi,pij,pj->p", d, inverse, d)
    return np.where(m <= _CUT, np.exp(-0.5 * m), 0.0)


@dataclass
class _FrameDensity:
    gaussians: Gaussians
    #: 1, its own Gaussians and those of the frames entered after it, at its points (k,).
    own: np.ndarray
    #: The Gaussians of each older frame in the map when it entered, at its points (older, k) ...
    older: np.ndarray
    #: ... and how many frames had left the map by then (those leaving since own its first rows).
    departed: int

    def density(self, departed: int) -> np.ndarray:
        """Its density (k,) once *departed* frames in all have left the map."""
        return self.own + self.older[departed - self.departed:].sum(0)


class MapDensity:
    """The density at each point of a map of the last *frames* frames (:meth:`enter`)."""

    def __init__(self, frames: int) -> None:
        self._frames: deque[_FrameDensity] = deque()
        self._capacity = frames
        self._departed = 0

    def enter(self, gaussians: Gaussians) -> None:
        """A frame's *gaussians* join the map, the newest; its oldest frame leaves when it is full."""
        if len(self._frames) == self._capacity:
            self._frames.popleft()
            self._departed += 1
        from scipy.spatial import cKDTree

        points, inverse, sigma = gaussians
        own = np.ones(len(points))
        if len(points) > 1:
            pairs = cKDTree(points).query_pairs(3.0 * float(sigma.max()), output_type="ndarray")
            j, k = pairs[:, 0], pairs[:, 1]
            d = points[j] - points[k]
            own += np.bincount(j, gaussian_values(d, inverse[k]), len(points))
            own += np.bincount(k, gaussian_values(d, inverse[j]), len(points))
        older = np.zeros((len(self._frames), len(points)))
        if self._frames and len(points):
            sizes = [len(f.own) for f in self._frames]
            centres, inverses, sigmas = (np.concatenate([f.gaussians[i] for f in self._frames]) for i in range(3))
            radius = 3.0 * max(float(sigma.max()), float(sigmas.max()))
            found = cKDTree(points).sparse_distance_matrix(cKDTree(centres), radius, output_type="ndarray")
            i, j = found["i"], found["j"]
            d = points[i] - centres[j]  # (pairs, 2) m: the new point less the map's
            at_map = np.bincount(j, gaussian_values(d, inverse[i]), len(centres))
            for frame, values in zip(self._frames, np.split(at_map, np.cumsum(sizes)[:-1])):
                frame.own += values
            owner = np.repeat(np.arange(len(sizes)), sizes)[j]
            older = np.bincount(owner * len(points) + i, gaussian_values(d, inverses[j]),
                                older.size).reshape(older.shape)
        self._frames.append(_FrameDensity(gaussians, own, older, self._departed))

    def log_density(self) -> np.ndarray:
        """The log of the density (m,) at each of the map's points, oldest frame's first."""
        if not self._frames:
            return np.zeros(0)
        return np.log(np.concatenate([f.density(self._departed) for f in self._frames]))
