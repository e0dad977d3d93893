"""Indoor scenes for the simulator: geometry turned into radar scatterers.

A scene is a floor plan in a world frame (x, y on the floor, z up, metres)
with:

- walls: polylines with a height, sampled into dense scatterers with fixed
  random phases and a reflectivity that falls with the angle of incidence
  (``sigma0 * area * cos(incidence)^m``), so that speckle and changing wall
  returns appear as the sensor moves; walls also hide what is behind them;
- objects: ``box`` (furniture, cabinets), ``cylinder`` (pillars, bins),
  ``door`` (a door leaf set into a wall with strong frame edges),
  ``corner_reflector`` and ``point`` targets;
- a floor and a ceiling (weak diffuse returns);
- movers: a walking ``person`` (torso plus swinging arms and legs);
- optionally first-order multipath: one bounce off a wall on the way out or
  back, for the point-like targets;
- a sensor trajectory (see :mod:`.trajectory`).

Scatterer sets, the sampling of surfaces into them and the walking person live in
:mod:`.scatterers`; this module reads a scene's description and builds a :class:`Scene` of them.
Scenes are written as TOML or JSON (the format is documented in ``scenes/README.md`` beside this
file, and the built-in scenes are examples).
Everything random (scatterer jitter, phases) comes from the seed, so a scene
and a seed always give the same scatterers.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

import numpy as np

from ...errors import ConfigError, quoted_json
from .physics import AntennaPattern
from .scene_values import (HPBW_DEG_RANGE, MAX_COORDINATE_M, MAX_SCATTERERS, MOVER_KEYS, OBJECT_KEYS, RADAR_KEYS,
                           RCS_DBSM_RANGE, SCENE_KEYS, SNR_DB_RANGE, MAX_NOISE_COUNTS, SURFACE_KEYS, WALL_KEYS, cells,
                           flag, need, num, builtin_or_there, cross_section, read_scene_file, vec, within)
from .scatterers import Person, Scatterers, point_scatterers, sample_plane, sample_surface
from .trajectory import MAX_SPEED_MPS, Trajectory, check_keys, from_spec, polyline

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

#: Built-in scene names (files ``scenes/<name>.toml`` in this package).
BUILTIN_SCENES = ("corridor", "room", "lab", "hall", "calibration")


@dataclass
class Scene:
    name: str
    trajectory: Trajectory
    static: Scatterers
    #: Occluding wall segments on the floor plan: (W, 2) start and end points.
    wall_a: np.ndarray
    wall_b: np.ndarray
    movers: list[Person]
    multipath: bool = False
    #: Every scatterer seen at the sensor's height, none above or below it (a diagnosis).
    flat: bool = False
    #: Amplitude reflection coefficient of a wall for multipath.
    wall_reflection: float = 0.3
    #: Per-sample SNR of a 1 m^2 target 5 m away on boresight, dB.
    snr_db: float = 0.0
    #: Thermal noise, ADC counts RMS per I and Q component.
    noise_counts: float = 5.0
    #: The antennas' gain over azimuth and elevation (``[radar]`` azimuth_hpbw_deg, elevation_hpbw_deg).
    pattern: AntennaPattern = field(default_factory=AntennaPattern)
    source: str = "<scene>"

    @property
    def num_static(self) -> int:
        return len(self.static.rcs)


# ----------------------------------------------------------------- loading
def _object(obj: dict, rng: np.random.Generator, where: str, walls_out: list, room: int) -> Scatterers:
    kind = obj.get("type")
    if not isinstance(kind, str) or kind not in OBJECT_KEYS:  # a list or table is no type either
        said = "missing 'type'" if kind is None else f"unknown object type {quoted_json(kind)}"
        raise ConfigError(f"{said}: use point, corner_reflector, box, cylinder or door", path=where,
                          field="objects.type")
    w = where  # the entry (objects[i], its type) is told by the caller
    check_keys(obj, ("type", *OBJECT_KEYS[kind]), where, f"a {kind} object")
    if kind == "point":
        return point_scatterers(vec(need(obj, "position", w), 3, w, "position"), cross_section(obj, "rcs", 1.0, w),
                                rng, pointlike=True)
    if kind == "corner_reflector":
        rcs_dbsm = num(obj, "rcs_dbsm", 15.0, w)
        if not RCS_DBSM_RANGE[0] <= rcs_dbsm <= RCS_DBSM_RANGE[1]:
            raise ConfigError(f"must be from {RCS_DBSM_RANGE[0]:g} to {RCS_DBSM_RANGE[1]:g} dBsm, got {rcs_dbsm:g}",
                              path=w, field="rcs_dbsm")
        rcs = 10 ** (rcs_dbsm / 10)
        return point_scatterers(vec(need(obj, "position", w), 3, w, "position"), rcs, rng, pointlike=True)
    if kind == "box":
        c = vec(need(obj, "center", w), 2, w, "center")
        size = vec(need(obj, "size", w), 3, w, "size", place=False)
        if not (size > 0).all():
            raise ConfigError(f"must be 3 positive numbers (x, y and height, m), got {obj['size']!r}", path=w,
                              field="size")
        yaw = math.radians(num(obj, "yaw", 0.0, w))
        sigma0 = cross_section(obj, "sigma0", 0.3, w)
        z0 = within(num(obj, "z", 0.0, w), -MAX_COORDINATE_M, MAX_COORDINATE_M, w, "z", " m")
        rot = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        hx, hy = size[0] / 2, size[1] / 2
        corners = c + np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]) @ rot.T
        faces = [sample_surface(corners[i], corners[(i + 1) % 4], z0, z0 + size[2], sigma0, rng,
                                spacing=0.1, row_spacing=0.25, what="a box's face", room=room // 4)
                 for i in range(4)]
        # Corners and edges of furniture are the strong, compact returns.
        edges = point_scatterers(np.column_stack([corners, np.full(4, z0 + size[2])]),
                                 cross_section(obj, "edge_rcs", 0.2, w), rng, pointlike=True)
        if flag(obj, "occludes", False, w):
            walls_out.extend((corners[i], corners[(i + 1) % 4]) for i in range(4))
        return Scatterers.concat(faces + [edges])
    if kind == "cylinder":
        c = vec(need(obj, "center", w), 2, w, "center")
        radius = num(obj, "radius", 0.2, w, positive=True)
        height = num(obj, "height", 2.7, w, positive=True)
        sigma0 = cross_section(obj, "sigma0", 0.3, w)
        n, rows = cells(2 * math.pi * radius / 0.08, height / 0.3,
                        f"a cylinder of radius {radius:g} m and {height:g} m high", room)
        n = max(8, n)
        ang = (np.arange(n) + rng.uniform(0, 1, n)) * 2 * math.pi / n
        z = (np.arange(rows)[:, None] + rng.uniform(0.1, 0.9, (rows, n))) * height / rows
        pos = np.column_stack([np.tile(c[0] + radius * np.cos(ang), rows),
                               np.tile(c[1] + radius * np.sin(ang), rows), z.ravel()])
        normal = np.column_stack([np.tile(np.cos(ang), rows), np.tile(np.sin(ang), rows), np.zeros(rows * n)])
        area = 2 * math.pi * radius / n * height / rows
        s = point_scatterers(pos, sigma0 * area, rng, normal=normal, exponent=2.0)
        if flag(obj, "occludes", True, w):  # two crossed diameters hide what is behind
            walls_out.append((c - [radius, 0.0], c + [radius, 0.0]))
            walls_out.append((c - [0.0, radius], c + [0.0, radius]))
        return s
    # a door, the one type left
    a = vec(need(obj, "a", w), 2, w, "a")
    b = vec(need(obj, "b", w), 2, w, "b")
    if np.array_equal(a, b):
        raise ConfigError(f"is a, {obj['a']!r}: a door spans from a to b; give b its other post", path=w, field="b")
    height = num(obj, "height", 2.1, w, positive=True)
    recess = within(num(obj, "recess", 0.1, w), -MAX_COORDINATE_M, MAX_COORDINATE_M, w, "recess", " m")
    d = (b - a) / max(float(np.hypot(*(b - a))), 1e-9)
    n = np.array([-d[1], d[0]])
    cells(height / 0.3, 2, f"a door {height:g} m high", room)  # its posts
    leaf = sample_surface(a - recess * n, b - recess * n, 0.0, height, cross_section(obj, "sigma0", 0.2, w),
                          rng, what="a door", room=room)
    frame_rcs = cross_section(obj, "frame_rcs", 0.3, w)
    zs = np.arange(0.15, height, 0.3)
    posts = np.vstack([np.column_stack([np.full(len(zs), p[0]), np.full(len(zs), p[1]), zs]) for p in (a, b)])
    return Scatterers.concat([leaf, point_scatterers(posts, frame_rcs, rng, pointlike=True)])


@contextlib.contextmanager
def _entry(key: str, index: int, kind: Any):
    """A ConfigError in the *index*-th table of the scene's list *key* is told which, and of what
    type (a file may hold a dozen of one kind): ``objects[5] (box): size: ...``."""
    try:
        yield
    except ConfigError as exc:
        field = exc.field
        if field and (field == key or field.startswith(key + ".")):  # the list's name said already
            field = field[len(key) + 1:] or None
        said = f" ({kind})" if isinstance(kind, str) and kind else ""
        raise exc.located(field=f"{key}[{index}]{said}" + (f": {field}" if field else "")) from None


def _static_parts(spec: dict[str, Any], rng: np.random.Generator, where: str, segments: list) -> list[Scatterers]:
    """The scatterers of a scene's walls, objects and surfaces (their occluding segments into
    *segments*), at most about :data:`MAX_SCATTERERS` in all."""
    parts: list[Scatterers] = []
    counted = [0, 0]  # how many of the parts are counted, and their scatterers

    def room() -> int:  # how many more scatterers the scene may hold
        counted[1] += sum(len(part.rcs) for part in parts[counted[0]:])
        counted[0] = len(parts)
        return MAX_SCATTERERS - counted[1]

    for i, wall in enumerate(spec.get("walls", [])):
        with _entry("walls", i, None):
            if not isinstance(wall, dict):
                raise ConfigError(f"a wall must be a table, got {wall!r}", path=where)
            check_keys(wall, WALL_KEYS, where, "walls")
            pts = polyline(need(wall, "points", where), where, "points")
            same = np.flatnonzero((pts[1:] == pts[:-1]).all(axis=1))
            if len(same):
                raise ConfigError(f"points {same[0] + 1} and {same[0] + 2} (counted from 1) are both "
                                  f"{pts[same[0]].tolist()}: a wall runs from each point to the next; leave "
                                  "the repeat out",
                                  path=where, field="points")
            height = num(wall, "height", 2.7, where, positive=True)
            sigma0 = cross_section(wall, "sigma0", 0.1, where)
            for a, b in zip(pts[:-1], pts[1:]):
                parts.append(sample_surface(a, b, 0.0, height, sigma0, rng, what="a wall's segment", room=room()))
                segments.append((a, b))
    for i, obj in enumerate(spec.get("objects", [])):
        with _entry("objects", i, obj.get("type") if isinstance(obj, dict) else None):
            if not isinstance(obj, dict):
                raise ConfigError(f"an object must be a table, got {obj!r}", path=where)
            parts.append(_object(obj, rng, where, segments, room()))
    surfaces = spec.get("surfaces", {})
    if surfaces:
        lo = vec(need(surfaces, "min", where), 2, where, "surfaces.min")
        hi = vec(need(surfaces, "max", where), 2, where, "surfaces.max")
        if not (lo < hi).all():
            raise ConfigError(f"must be above surfaces.min {surfaces['min']!r} in x and y, got {surfaces['max']!r}",
                              path=where, field="surfaces.max")
        if flag(surfaces, "floor", True, where, "surfaces.floor"):
            floor_sigma0 = cross_section(surfaces, "floor_sigma0", 0.02, where, name="surfaces.floor_sigma0")
            parts.append(sample_plane(lo, hi, 0.0, floor_sigma0, rng, what="the floor", room=room()))
        if "ceiling" in surfaces:
            ceiling = within(num(surfaces, "ceiling", 2.7, where, positive=True, name="surfaces.ceiling"), 0.0,
                             MAX_COORDINATE_M, where, "surfaces.ceiling", " m")
            ceil = sample_plane(lo, hi, ceiling,
                                cross_section(surfaces, "ceiling_sigma0", 0.02, where,
                                    name="surfaces.ceiling_sigma0"), rng, what="the ceiling", room=room())
            ceil.normal[:, 2] = -1.0
            parts.append(ceil)
    return parts


def scene_from_dict(spec: dict[str, Any], *, seed: int = 0, where: str = "<scene>") -> Scene:
    """Build a scene from its parsed TOML/JSON table."""
    if not isinstance(spec, dict):
        raise ConfigError("a scene must be a table", path=where)
    rng = np.random.default_rng([seed, 0x5CE9E])
    segments: list[tuple] = []
    for key in ("walls", "objects", "movers"):
        if not isinstance(spec.get(key, []), list):
            raise ConfigError(f"must be a list of tables ([[{key}]] in TOML)", path=where, field=key)
    for key in ("surfaces", "radar"):
        if not isinstance(spec.get(key, {}), dict):
            raise ConfigError(f"must be a table ([{key}] in TOML), got {quoted_json(spec[key])}", path=where,
                              field=key)
    check_keys(spec, SCENE_KEYS, where, "")
    check_keys(spec.get("surfaces", {}), SURFACE_KEYS, where, "surfaces")
    check_keys(spec.get("radar", {}), RADAR_KEYS, where, "radar")
    try:
        parts = _static_parts(spec, rng, where, segments)
    except ConfigError as exc:  # too many scatterers (scene_values.cells) is told where here
        raise exc.located(path=where) from None
    movers = []
    for i, m in enumerate(spec.get("movers", [])):
        with _entry("movers", i, None):
            if not isinstance(m, dict) or m.get("type") != "person":
                kind = m.get("type") if isinstance(m, dict) else m
                raise ConfigError(f"unknown mover {kind!r}: use type = \"person\"", path=where)
            check_keys(m, MOVER_KEYS, where, "movers")
            path = polyline(need(m, "path", where), where, "path")
            if not np.hypot(*np.diff(path, axis=0).T).all():
                raise ConfigError("a person's path has two equal points in a row", path=where, field="path")
            speed = within(num(m, "speed", 1.2, where, positive=True), 0.0, MAX_SPEED_MPS, where,
                           "speed", " m/s (a person walks at 1-2)")
            movers.append(Person(path, speed, cross_section(m, "rcs", 0.5, where),
                                 float(rng.uniform(0, 2 * np.pi)), rng.uniform(0, 2 * np.pi, len(Person.BODY))))
    trajectory = from_spec(need(spec, "trajectory", where), where)
    radar = spec.get("radar", {})
    wall_a = np.array([s[0] for s in segments], float).reshape(-1, 2)
    wall_b = np.array([s[1] for s in segments], float).reshape(-1, 2)
    name = spec.get("name", os.path.basename(where))
    if not isinstance(name, str):
        raise ConfigError(f"must be a string, got {name!r}", path=where, field="name")
    return Scene(
        name=name,
        trajectory=trajectory,
        static=Scatterers.concat(parts),
        wall_a=wall_a,
        wall_b=wall_b,
        movers=movers,
        multipath=flag(spec, "multipath", False, where),
        flat=flag(spec, "flat", False, where),
        wall_reflection=within(num(spec, "wall_reflection", 0.3, where), 0.0, 1.0, where, "wall_reflection",
                                " (an amplitude reflection coefficient)"),
        snr_db=within(num(radar, "snr_db", 0.0, where, name="radar.snr_db"), *SNR_DB_RANGE, where, "radar.snr_db",
                      " dB"),
        noise_counts=within(num(radar, "noise_counts", 5.0, where, positive=True, name="radar.noise_counts"), 0.0,
                            MAX_NOISE_COUNTS, where, "radar.noise_counts", " ADC counts"),
        pattern=_pattern(radar, where),
        source=where,
    )


def _pattern(radar: dict, where: str) -> AntennaPattern:
    """The ``[radar]`` table's antenna pattern: its half-power beam widths, the defaults' where not given."""
    widths = {}
    for key in ("azimuth_hpbw_deg", "elevation_hpbw_deg"):
        value = num(radar, key, getattr(AntennaPattern, key), where, name=f"radar.{key}")
        widths[key] = within(value, *HPBW_DEG_RANGE, where, f"radar.{key}", " degrees")
    return AntennaPattern(**widths)


def load_scene(name_or_path: str, *, seed: int = 0) -> Scene:
    """A built-in scene by name, or a scene file (``.toml`` or ``.json``)."""
    if name_or_path in BUILTIN_SCENES:
        ref = resources.files(__package__).joinpath("scenes", f"{name_or_path}.toml")
        return scene_from_dict(tomllib.loads(ref.read_text(encoding="utf-8")), seed=seed,
                               where=f"builtin:{name_or_path}")
    if not builtin_or_there(name_or_path, BUILTIN_SCENES):
        raise ConfigError(f"no such scene: use one of {', '.join(BUILTIN_SCENES)} or a .toml/.json file",
                          path=name_or_path)
    path = os.path.expanduser(name_or_path)
    if os.path.isdir(path):
        raise ConfigError("a directory, not a scene file: give a .toml or .json file", path=name_or_path)
    return scene_from_dict(read_scene_file(path), seed=seed, where=path)
