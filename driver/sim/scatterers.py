"""What a scene is made of: sets of radar scatterers (:class:`Scatterers`), surfaces sampled into
them (walls, floors, ceilings: :func:`sample_surface`, :func:`sample_plane`) and a walking
:class:`Person`.  :mod:`.scene` builds a scene's parts from these."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .scene_values import MAX_SCATTERERS, cells

@dataclass
class Scatterers:
    """Static point scatterers in the world frame."""

    pos: np.ndarray  # (K, 3) m
    rcs: np.ndarray  # (K,) m^2 at normal incidence
    normal: np.ndarray  # (K, 3) unit surface normal, or zeros for isotropic
    exponent: np.ndarray  # (K,) incidence exponent m
    phase: np.ndarray  # (K,) rad, fixed
    #: True for compact strong targets that also get multipath images.
    pointlike: np.ndarray  # (K,) bool

    @classmethod
    def empty(cls) -> "Scatterers":
        return cls(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)), np.zeros(0), np.zeros(0),
                   np.zeros(0, bool))

    @classmethod
    def concat(cls, parts: Sequence["Scatterers"]) -> "Scatterers":
        parts = [p for p in parts if len(p.rcs)] or [cls.empty()]
        return cls(*(np.concatenate([getattr(p, f) for p in parts])
                     for f in ("pos", "rcs", "normal", "exponent", "phase", "pointlike")))


def point_scatterers(pos, rcs, rng, *, normal=None, exponent=0.0, pointlike=False) -> Scatterers:
    """Scatterers at *pos* ((K, 3) m) of cross-section *rcs* (m^2, one or K), each with a fixed
    random phase drawn from *rng*."""
    pos = np.atleast_2d(np.asarray(pos, dtype=float))
    k = len(pos)
    rcs = np.broadcast_to(np.asarray(rcs, dtype=float), (k,)).copy()
    normal = np.zeros((k, 3)) if normal is None else np.broadcast_to(normal, (k, 3)).astype(float)
    return Scatterers(pos, rcs, normal, np.full(k, float(exponent)),
                      rng.uniform(0, 2 * np.pi, k), np.full(k, pointlike))


def sample_surface(a, b, z0: float, z1: float, sigma0: float, rng: np.random.Generator, *,
                   spacing: float = 0.1, row_spacing: float = 0.35, exponent: float = 2.0,
                   what: str = "a surface", room: int = MAX_SCATTERERS) -> Scatterers:
    """Scatterers on the vertical rectangle above the floor segment a-b, z0..z1 (at most about
    *room* of them, else ConfigError naming *what*)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    with np.errstate(over="ignore"):  # a length beyond 1e308 is inf, and refused by cells
        length = float(np.hypot(*(b - a)))
    if length < 1e-6 or z1 <= z0:
        return Scatterers.empty()
    n_along, n_rows = cells(length / spacing, (z1 - z0) / row_spacing,
                            f"{what} {length:g} m long and {z1 - z0:g} m high", room)
    s = (np.arange(n_along) + rng.uniform(0.1, 0.9, (n_rows, n_along))) / n_along
    z = z0 + (np.arange(n_rows)[:, None] + rng.uniform(0.1, 0.9, (n_rows, n_along))) * (z1 - z0) / n_rows
    xy = a + s.reshape(-1, 1) * (b - a)
    pos = np.column_stack([xy, z.reshape(-1)])
    d = (b - a) / length
    normal = np.array([-d[1], d[0], 0.0])
    area = (length / n_along) * ((z1 - z0) / n_rows)
    return point_scatterers(pos, sigma0 * area, rng, normal=normal, exponent=exponent)


def sample_plane(lo, hi, z: float, sigma0: float, rng: np.random.Generator, *, spacing: float = 0.35,
                 exponent: float = 1.0, what: str = "a surface", room: int = MAX_SCATTERERS) -> Scatterers:
    """Scatterers on the horizontal rectangle lo..hi (x, y) at height z (floor, ceiling; at most
    about *room* of them, else ConfigError naming *what*)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    with np.errstate(over="ignore"):  # a size beyond 1e308 is inf, and refused by cells
        dx, dy = float(hi[0] - lo[0]), float(hi[1] - lo[1])
    nx, ny = cells(dx / spacing, dy / spacing, f"{what} {dx:g} m x {dy:g} m", room)
    gx = (np.arange(nx)[:, None] + rng.uniform(0.1, 0.9, (nx, ny))) * (hi[0] - lo[0]) / nx + lo[0]
    gy = (np.arange(ny)[None, :] + rng.uniform(0.1, 0.9, (nx, ny))) * (hi[1] - lo[1]) / ny + lo[1]
    pos = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z)])
    area = (hi[0] - lo[0]) / nx * (hi[1] - lo[1]) / ny
    return point_scatterers(pos, sigma0 * area, rng, normal=np.array([0.0, 0.0, 1.0]), exponent=exponent)


@dataclass
class Person:
    """A person walking back and forth along a polyline: a torso and four
    swinging limbs, so the return carries micro-Doppler."""

    path: np.ndarray  # (n, 2) waypoints, m
    speed: float = 1.0  # m/s
    rcs: float = 0.5  # m^2, whole body
    phase0: float = 0.0
    phases: np.ndarray = field(default_factory=lambda: np.zeros(9))

    #: (forward, side, height, swing amplitude, share of the rcs) per body scatterer.
    BODY = (
        (0.00, 0.00, 1.40, 0.00, 0.15), (0.05, 0.12, 1.20, 0.00, 0.15), (0.05, -0.12, 1.20, 0.00, 0.15),
        (0.05, 0.00, 1.00, 0.00, 0.15), (0.00, 0.00, 0.90, 0.00, 0.10),
        (0.00, 0.22, 1.00, 0.25, 0.07), (0.00, -0.22, 1.00, -0.25, 0.07),  # arms
        (0.00, 0.10, 0.45, -0.30, 0.08), (0.00, -0.10, 0.45, 0.30, 0.08),  # legs
    )
    STRIDE_HZ = 0.9

    def _along(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        seg = np.diff(self.path, axis=0)
        lens = np.hypot(seg[:, 0], seg[:, 1])
        total = lens.sum()
        # Ping-pong along the path at constant speed.
        s = np.mod(self.speed * t, 2 * total)
        back = s > total
        s = np.where(back, 2 * total - s, s)
        cum = np.concatenate([[0.0], np.cumsum(lens)])
        i = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(lens) - 1)
        frac = (s - cum[i]) / lens[i]
        xy = self.path[i] + frac[:, None] * seg[i]
        heading = np.arctan2(seg[i, 1], seg[i, 0]) + np.where(back, np.pi, 0.0)
        return xy, heading

    def positions(self, t: np.ndarray) -> np.ndarray:
        """Body scatterer positions at times *t*, world frame, (T, 9, 3)."""
        t = np.asarray(t, float)
        xy, heading = self._along(t)
        body = np.array(self.BODY)
        swing = np.sin(2 * np.pi * self.STRIDE_HZ * t + self.phase0)[:, None] * body[None, :, 3]
        fwd = body[None, :, 0] + swing
        side = body[None, :, 1]
        c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
        out = np.empty((len(t), len(body), 3))
        out[..., 0] = xy[:, 0:1] + c * fwd - s * side
        out[..., 1] = xy[:, 1:2] + s * fwd + c * side
        out[..., 2] = body[None, :, 2]
        return out

    @property
    def body_rcs(self) -> np.ndarray:
        return self.rcs * np.array(self.BODY)[:, 4]
