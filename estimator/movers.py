"""Movers followed across the radar's view (``icp.track_movers``, docs/heading.md item 16).

A cell is left out of the registration when its Doppler differs from what a static reflector
shows at the frame's velocity (``icp.reject_moving_mps``).  A person walking square to the line
of sight has almost no radial velocity, and for a second or more its cells pass that test and
are registered as the world's, which turns the heading by the person's own bearing rate.  The
Doppler does see the person while it walks towards or away from the radar, so the blob it flags
there is followed from frame to frame as a track, and while the track crosses unflagged the
points the registration scores (the scan's strongest cells) around it are left out too.  Only
the points: a heatmap filled in around the track would move a hole through the likelihood
field, itself structure that does not turn with the world.

A track starts from a blob of strong flagged cells whose Doppler is well off the static world's;
it is predicted by the radar's own motion (the frame's velocity and the last yaw rate) and by its
own; it takes the nearest flagged blob within reach, and counts a hit when that blob's Doppler
is off the same way.  Only after three hits, and only while it moves at a walking-to-running
speed, does it follow the strong cells near its prediction without flags: static structure,
whose flags come and go and whose blobs do not move by themselves, is not followed.  Pure
functions of the heatmap and the motion, apart from the tracks kept between frames.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .features import Features, PolarHeatmap

#: The cells a blob is made of: the frame's strongest 1 % (a person a few metres away is among
#: them; weak cells' Doppler is noise), by the order statistic at this fraction of the cells.
STRONG_QUANTILE = 0.99
#: Flagged cells nearer than this or further off boresight than that start nothing: near
#: structure's Doppler disagrees while the robot brakes, and the field of view's edges are the
#: antennas' sidelobes.
MIN_RANGE_M = 1.0
MAX_BEARING_RAD = math.radians(60.0)
#: A blob whose Doppler is this far off the static world's (m/s) starts a track or counts a hit.
BIRTH_MPS = 0.5
#: A track takes the nearest flagged blob within this of its prediction, m.
GATE_M = 0.5
#: Unflagged, a confirmed track follows the strong cells within this of its prediction, m.
FOLLOW_M = 0.35
#: Hits before a track is followed without flags.
CONFIRM_HITS = 3
#: A track followed without flags for longer than this (frames), or moving slower or faster
#: than these (m/s), or without strong cells near it for more than LOST frames in a row, ends.
MAX_UNFLAGGED = 15
SPEED_RANGE_MPS = (0.4, 3.0)
LOST = 2
#: The points within this of a track followed without flags are left out, m.
MASK_M = 0.5


@dataclass
class _Grid:
    """A heatmap's axes, its cells' places x, y (n_range, n_azimuth) m, the cosine and sine of
    their bearings (1, n_azimuth) and the cells where a track may start."""

    range_m: np.ndarray
    azimuth_rad: np.ndarray
    x: np.ndarray
    y: np.ndarray
    cos: np.ndarray
    sin: np.ndarray
    region: np.ndarray


@dataclass
class Track:
    """A mover: its place (2,) m in the latest frame's body axes, its own velocity (2,) m/s
    over the ground in the same axes, the sign of its Doppler less the static world's, its
    hits, the frames since it was last flagged and the frames in a row it was not seen."""

    position: np.ndarray
    velocity: np.ndarray
    sign: float
    hits: int = 1
    unflagged: int = 0
    lost: int = 0
    #: Whether *velocity* has been measured (a track starts at rest, unknown).
    moved: bool = False


class MoverTracks:
    """The tracks (:meth:`update` each frame) and the points near them left out (:meth:`leave_out`)."""

    def __init__(self) -> None:
        self.tracks: list[Track] = []
        self._grid: _Grid | None = None

    def update(self, heatmap: PolarHeatmap, moving: np.ndarray | None, velocity: np.ndarray | None,
               turn_rad: float, dt: float | None) -> None:
        """Follow the tracks into this frame.  *moving* (n_range, n_azimuth) bool: the cells
        flagged by their Doppler; *velocity* (2,) m/s body axes: the frame's; *turn_rad*: the
        radar's turn since the previous frame, counter-clockwise; *dt* (s): the time since it
        (None: the first frame).  A frame without its velocity (*moving* and *velocity* None) or
        a heatmap without Doppler ends every track: none is followed through it."""
        doppler = getattr(heatmap, "doppler_mps", None)
        if doppler is None or velocity is None or moving is None:
            self.tracks.clear()
            return
        grid = self._geometry(heatmap)
        candidates = moving & grid.region
        if not self.tracks and not candidates.any():
            return  # nothing to follow, nothing to start from: most frames of a static scene
        intensity = np.asarray(heatmap.intensity, float)
        k = int(STRONG_QUANTILE * (intensity.size - 1))
        strong = (intensity >= np.partition(intensity.ravel(), k)[k]) & (intensity > 0)
        x, y = grid.x, grid.y
        static = -(velocity[0] * grid.cos + velocity[1] * grid.sin)
        off = np.asarray(doppler, float) - static  # a mover's own radial speed, m/s
        flagged = candidates & strong
        blobs = _blobs(flagged, intensity, off, x, y)
        used = [False] * len(blobs)
        kept: list[Track] = []
        if dt is not None:
            for track in self.tracks:
                if self._update(track, blobs, used, strong, intensity, x, y, velocity, turn_rad, dt):
                    kept.append(track)
        for (place, speed), taken in zip(blobs, used):
            if not taken and abs(speed) > BIRTH_MPS:
                kept.append(Track(place, np.zeros(2), float(np.sign(speed))))
        self.tracks = kept

    def _geometry(self, heatmap: PolarHeatmap) -> _Grid:
        """The cells' places and where tracks may start, computed again only for new axes."""
        range_m = np.asarray(heatmap.range_m, float)
        azimuth = np.asarray(heatmap.azimuth_rad, float)
        grid = self._grid
        if grid is None or not (np.array_equal(grid.range_m, range_m) and np.array_equal(grid.azimuth_rad, azimuth)):
            bearing = -azimuth[None, :]
            cos, sin = np.cos(bearing), np.sin(bearing)
            region = (np.abs(bearing) < MAX_BEARING_RAD) & (range_m[:, None] > MIN_RANGE_M)
            grid = self._grid = _Grid(range_m.copy(), azimuth.copy(), range_m[:, None] * cos,
                                      range_m[:, None] * sin, cos, sin, region)
        return grid

    def leave_out(self, points: Features) -> Features:
        """*points* without those within MASK_M of a track followed without flags (weights
        normalised again); as they are when that would leave fewer than three."""
        near = np.zeros(len(points), bool)
        for track in self.tracks:
            if track.unflagged > 0:
                near |= np.hypot(*(points.xy - track.position).T) < MASK_M
        return points.subset(~near)

    @staticmethod
    def _update(track: Track, blobs: list[tuple[np.ndarray, float]], used: list[bool], strong: np.ndarray,
                intensity: np.ndarray, x: np.ndarray, y: np.ndarray, velocity: np.ndarray, turn_rad: float,
                dt: float) -> bool:
        """Move *track* to this frame (False: it ends): *blobs* as :func:`_blobs` gives them
        (*used* marks those taken), *strong*, *intensity*, *x* and *y* the cells' (n_range,
        n_azimuth), the radar's *velocity* (2,) m/s, *turn_rad* and *dt* (s) as in :meth:`update`."""
        c, s = math.cos(-turn_rad), math.sin(-turn_rad)
        turn = np.array([[c, -s], [s, c]])
        # Where the track would be now were it static: the radar moved and turned under it.
        carried = turn @ (track.position - np.asarray(velocity, float) * dt)
        own = turn @ track.velocity
        predicted = carried + own * dt
        best, index = GATE_M, None
        for i, (place, _) in enumerate(blobs):
            distance = float(np.hypot(*(place - predicted)))
            if distance < best and not used[i]:
                best, index = distance, i
        seen = None
        if index is not None:
            used[index] = True
            seen, speed = blobs[index]
            track.unflagged = 0
            if abs(speed) > BIRTH_MPS and np.sign(speed) == track.sign:
                track.hits += 1
        elif track.hits >= CONFIRM_HITS:
            near = strong & (np.hypot(x - predicted[0], y - predicted[1]) < FOLLOW_M)
            if near.any():
                seen = _centroid(near, intensity, x, y)
            track.unflagged += 1
        else:
            return False
        if seen is None:
            track.position, track.velocity = predicted, own
            track.lost += 1
        else:
            moved = (seen - carried) / dt
            track.velocity = 0.5 * own + 0.5 * moved if track.moved else moved
            track.position, track.lost, track.moved = seen, 0, True
        speed = float(np.hypot(*track.velocity))
        return not (track.lost > LOST or track.unflagged > MAX_UNFLAGGED
                    or (track.unflagged > 0 and not SPEED_RANGE_MPS[0] < speed < SPEED_RANGE_MPS[1]))


def _blobs(flagged: np.ndarray, intensity: np.ndarray, off: np.ndarray, x: np.ndarray,
           y: np.ndarray) -> list[tuple[np.ndarray, float]]:
    """The flagged cells grouped by touching (a cell apart at most): each group's place (2,) m
    (intensity-weighted) and its median Doppler less the static world's, m/s."""
    if not flagged.any():
        return []
    from scipy.ndimage import binary_dilation, label

    labels, count = label(binary_dilation(flagged, np.ones((3, 3), bool)))
    out = []
    for k in range(1, count + 1):
        cells = (labels == k) & flagged
        out.append((_centroid(cells, intensity, x, y), float(np.nanmedian(off[cells]))))
    return out


def _centroid(cells: np.ndarray, intensity: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The intensity-weighted place (2,) m of *cells* (n_range, n_azimuth) bool, whose
    intensities are positive, given the cells' places *x*, *y* (n_range, n_azimuth) m."""
    w = intensity[cells]
    return np.array([(x[cells] * w).sum() / w.sum(), (y[cells] * w).sum() / w.sum()])
