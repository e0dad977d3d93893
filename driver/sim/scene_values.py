"""A scene file read, and its values checked as they are read: each a :class:`ConfigError` naming the scene
file and the key when it is missing, of the wrong type or out of range; and the keys each of the
file's tables takes."""

from __future__ import annotations

import math
import os
import re
import sys

import numpy as np

from ... import strict_json
from ...plain_numbers import beyond_text, finite_float
from ...errors import ConfigError, quoted

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def need(d: dict, key: str, where: str, kind=None):
    if key not in d:
        raise ConfigError(f"missing {key!r}", path=where, field=key)
    return d[key]


#: The farthest a scene's point may lie from its origin, m: beyond it a scene is no room or site
#: (and past float32's 3e38 the simulator's arithmetic overflows).
MAX_COORDINATE_M = 1e6


def vec(value, n: int, where: str, what: str, *, place: bool = True) -> np.ndarray:
    """*n* finite numbers; a *place*'s within :data:`MAX_COORDINATE_M` (a size is bounded by the
    scatterers it makes: :func:`cells`)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):  # (an integer of 309 digits overflows a float)
        arr = None
    if arr is None or arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ConfigError(f"must be {n} numbers, got {quoted(value)}", path=where, field=what)
    if place:
        check_coordinates(arr, value, where, what)
    return arr


def check_coordinates(arr: np.ndarray, value, where: str, what: str) -> None:
    """ConfigError unless every number of *arr* (read from *value*) is within :data:`MAX_COORDINATE_M`."""
    if arr.size and float(np.abs(arr).max()) > MAX_COORDINATE_M:
        raise ConfigError(f"a coordinate beyond {MAX_COORDINATE_M:g} m (a scene is metres across, not thousands of "
                          f"km): got {value!r}"[:240], path=where, field=what)


def num(d: dict, key: str, default: float, where: str, *, positive: bool = False, name: str | None = None) -> float:
    """A number at *key* (*name*: its path in the file, when its table is not the top one)."""
    value = d.get(key, default)
    number = finite_float(value)
    if number is None or (positive and number <= 0):
        raise ConfigError(f"must be a {'positive ' if positive else ''}number, got {quoted(value)}",
                          path=where, field=name or key)
    return number


def cross_section(d: dict, key: str, default: float, where: str, name: str | None = None) -> float:
    """A radar cross-section (m^2) or a surface's backscatter (m^2 per m^2) at *key*: positive and
    at most :data:`MAX_RCS_M2`."""
    return within(num(d, key, default, where, positive=True, name=name), 0.0, MAX_RCS_M2, where, name or key,
                  " (a ship's 60 dBsm; more overflows the simulated signal)")


def flag(d: dict, key: str, default: bool, where: str, name: str | None = None) -> bool:
    """A true/false key (a quoted "false" would read as true)."""
    value = d.get(key, default)
    if not isinstance(value, bool):
        raise ConfigError(f"must be true or false, got {value!r}", path=where, field=name or key)
    return value


def within(value: float, lo: float, hi: float, where: str, key: str, unit: str = "") -> float:
    if not lo <= value <= hi:
        raise ConfigError(f"must be from {lo:g} to {hi:g}{unit}, got {beyond_text(value, lo, hi)}", path=where,
                          field=key)
    return value


#: The most scatterers a scene holds: its walls, objects and surfaces are sampled every 0.1 to
#: 0.35 m (the built-in scenes hold about 5000 to 10000); a size of kilometres is a unit mistaken,
#: and a square kilometre of floor (8 million) would take gigabytes.
MAX_SCATTERERS = 4_000_000


def cells(along: float, across: float, what: str, room: int) -> tuple[int, int]:
    """How many sampling cells a surface takes each way (*along*, *across*: its sizes over the
    spacings), each at least 1; :class:`ConfigError` when that would take the scene past
    :data:`MAX_SCATTERERS` (*room*: how many it has left), or a size overflowed to infinity.  The
    error names neither file nor key: :func:`scene.scene_from_dict` tells it where."""
    if not max(along, 1.0) * max(across, 1.0) <= room:  # NaN and inf too
        raise ConfigError(f"{what} would take the scene past the {MAX_SCATTERERS} scatterers it may hold "
                          "(surfaces are sampled every 0.1 to 0.35 m; the built-in scenes hold 5000 to 10000): "
                          "are its sizes in metres?")
    return max(1, math.ceil(along)), max(1, math.ceil(across))


#: A scene's SNR, dB: beyond it the simulated signal overflows (and far below, it is noise).
SNR_DB_RANGE = (-100.0, 100.0)
#: Thermal noise, ADC counts RMS: the 16-bit ADC's full scale at most.
MAX_NOISE_COUNTS = 32767.0
#: An antenna pattern's half-power beam width, degrees: a pencil beam's to all but flat (at 180 the
#: cos^n pattern would be flat behind the array too).
HPBW_DEG_RANGE = (1.0, 179.0)

#: The keys of a scene file's tables, and of each kind of object.
SCENE_KEYS = ("name", "walls", "objects", "movers", "surfaces", "trajectory", "radar", "multipath", "wall_reflection",
              "flat")
WALL_KEYS = ("points", "height", "sigma0")
SURFACE_KEYS = ("min", "max", "floor", "floor_sigma0", "ceiling", "ceiling_sigma0")
RADAR_KEYS = ("snr_db", "noise_counts", "azimuth_hpbw_deg", "elevation_hpbw_deg")
MOVER_KEYS = ("type", "path", "speed", "rcs")
OBJECT_KEYS = {"point": ("position", "rcs"), "corner_reflector": ("position", "rcs_dbsm"),
               "box": ("center", "size", "yaw", "sigma0", "z", "edge_rcs", "occludes"),
               "cylinder": ("center", "radius", "height", "sigma0", "occludes"),
               "door": ("a", "b", "height", "recess", "sigma0", "frame_rcs")}
#: A corner reflector's radar cross-section, dBsm: from a marble's to a ship's.
RCS_DBSM_RANGE = (-60.0, 60.0)
#: The largest radar cross-section (a point's, an edge's, a person's, m^2) or backscatter (sigma0, m^2
#: per m^2) a scene gives: a ship's, as RCS_DBSM_RANGE (1e100 overflowed the simulated signal to NaN).
MAX_RCS_M2 = 10 ** (RCS_DBSM_RANGE[1] / 10)


#: The largest scene (or board) file read, bytes (the built-in scenes are a few kB).
MAX_SCENE_BYTES = 16 * 2**20


def read_bounded(path: str, what: str) -> bytes:
    """The bytes of *path*, a scene or board file (*what*): at most :data:`MAX_SCENE_BYTES`, read no
    further (a wrong path to a disk image, or /dev/zero, would fill the memory), else ConfigError."""
    with open(path, "rb") as fh:
        raw = fh.read(MAX_SCENE_BYTES + 1)
    if len(raw) > MAX_SCENE_BYTES:
        raise ConfigError(f"larger than {MAX_SCENE_BYTES >> 20} MiB, the most a {what} is read to (one is a "
                          f"few kB): not a {what}?", path=path)
    return raw


def builtin_or_there(name: str, builtins: tuple[str, ...]) -> bool:
    """Whether *name* is one of *builtins* or names something on disk (a directory too: the loader
    then says it is one); the one rule for ``sim://``'s URL check and the scene and board loaders."""
    return name in builtins or os.path.exists(os.path.expanduser(name))


def decode_utf8(raw: bytes, path: str) -> str:
    """A scene or board file's text (a BOM, a Windows editor's, ignored), or :class:`ConfigError`
    naming the line of the first byte that is not UTF-8 (Python's own words give its offset)."""
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise ConfigError(f"not UTF-8 text (byte 0x{raw[exc.start]:02x}): save the file as UTF-8", path=path,
                          line=line) from None


def toml_error(exc: ValueError, path: str, what: str) -> ConfigError:
    """A TOML (or JSON) reader's error as ``path:line`` (TOML's "(at line N, column M)" moved
    there), saying what the file should be; a radar .cfg given in its place is named so."""
    message, line = str(exc), None
    m = re.search(r"\s*\(at line (\d+), column (\d+)\)$", message)
    if m:
        message, line = f"{message[:m.start()]} (column {m.group(2)})", int(m.group(1))
    hint = (" (a .cfg is the radar's configuration: give it with --cfg)" if path.endswith(".cfg")
            else "")
    return ConfigError(f"cannot parse: {message}: {what}{hint}", path=path, line=line)


def read_scene_file(path: str) -> dict:
    """The table of a scene file (``.json``, else TOML), or :class:`ConfigError` naming it."""
    try:
        text = decode_utf8(read_bounded(path, "scene file"), path)
        # (strict JSON: nesting and number sizes bounded, no key twice; tomllib refuses a key twice
        # itself but recurses once per nesting level)
        return strict_json.loads(text, max_bytes=MAX_SCENE_BYTES) if path.endswith(".json") else tomllib.loads(text)
    except (UnicodeDecodeError, ValueError) as exc:  # TOMLDecodeError and JSONDecodeError are ValueErrors
        raise toml_error(exc, path, "a scene file is a TOML (or .json) table of walls, objects and a path") from None
    except RecursionError:
        raise ConfigError(f"cannot parse: nested more deeply than Python's TOML reader can follow (a scene "
                          f"nests {strict_json.MAX_DEPTH} deep at most)", path=path) from None
