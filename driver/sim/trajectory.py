"""Smooth planar sensor trajectories for the simulator.

A trajectory is a start pose and a list of segments, each a commanded forward
speed and yaw rate of the robot's base (its rotation axis) held for a time:

- ``{"straight": 5.0, "speed": 1.0}``: 5 m ahead at 1 m/s;
- ``{"turn": 90, "radius": 1.5, "speed": 0.8}``: an arc, left for positive degrees;
- ``{"rotate": -180, "rate": 60}``: turn in place, degrees at degrees/s;
- ``{"pause": 2.0}``: stand still for 2 s.

or waypoints ``[[x, y], ...]`` visited in order (turn in place toward the next
point at ``turn_rate``, then drive to it at ``speed``).

The commands are sampled every millisecond and smoothed twice by a moving
average (``smoothing_s``): speeds and yaw rates then ramp continuously with
bounded acceleration, and the distance and angle of each segment are kept
exactly (a moving average preserves integrals).  Poses are the integral,
interpolated to any time.  Units: metres, seconds, radians (degrees only in
the segment text).

The radar sits on the base at its *mount* (x ahead, y left, yaw; default the
rotation axis, looking ahead).  A wheeled base cannot slide sideways, so a
radar mounted ahead of or behind its axis moves sideways at yaw rate x lever
arm: the trajectory's poses are the radar's, its ``base_*`` the base's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ...errors import ConfigError, quoted
from ...plain_numbers import beyond_text, finite_float
from .scene_values import MAX_COORDINATE_M, check_coordinates

#: Integration step of the pose table, s.
STEP_S = 1e-3


@dataclass(frozen=True)
class Trajectory:
    """Sensor body pose in the scene's world frame as a function of time."""

    #: Sample times (n,), s, from 0 at STEP_S spacing.
    times: np.ndarray
    #: World x, y (m) and yaw (rad, unwrapped) of the body frame at ``times``.
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    #: Sensor height above the floor, m.
    height: float = 0.4
    #: The radar on the base: x ahead, y left (m), yaw (rad); the poses above are the radar's.
    mount: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def base_pose(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, yaw) of the base (its rotation axis) at times *t*: the radar's pose less the mount."""
        x, y, yaw = self.pose(t)
        mx, my, myaw = self.mount
        yaw_b = yaw - myaw
        c, s = np.cos(yaw_b), np.sin(yaw_b)
        return x - (c * mx - s * my), y - (s * mx + c * my), yaw_b

    @property
    def duration_s(self) -> float:
        return float(self.times[-1])

    def pose(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, yaw) at times *t* (any shape, s); held at the ends."""
        t = np.asarray(t, dtype=float)
        return (np.interp(t, self.times, self.x), np.interp(t, self.times, self.y),
                np.interp(t, self.times, self.yaw))

    def velocity(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World-frame (vx, vy) in m/s and yaw rate in rad/s at times *t*."""
        t = np.asarray(t, dtype=float)
        g = [np.gradient(a, self.times) for a in (self.x, self.y, self.yaw)]
        return tuple(np.interp(t, self.times, a) for a in g)  # type: ignore[return-value]

    @property
    def length_m(self) -> float:
        return float(np.hypot(np.diff(self.x), np.diff(self.y)).sum())


#: The longest trajectory a scene file gives, s: its poses are sampled every STEP_S (an hour is
#: some 300 MB while it is built); a longer run repeats it (``sim://SCENE?loop=0``).
MAX_DURATION_S = 3600.0
#: The longest speed and turn-rate ramp, s (smoothing_s; 0.3 s in the built-in scenes): its moving
#: average is STEP_S wide per sample (1e300 s was an internal error, an hour's ramp a long wait).
MAX_SMOOTHING_S = 10.0
#: The fastest a trajectory drives, m/s, and turns, deg/s: a robot's or a car's; more is a unit
#: mistaken (a speed of 1e300 m/s was "the segments add up to no motion and no time").
MAX_SPEED_MPS = 100.0
MAX_TURN_RATE_DPS = 3600.0
#: The keys of each kind of segment.
SEGMENT_KEYS = {"straight": ("straight", "speed"), "turn": ("turn", "radius", "speed"),
                "rotate": ("rotate", "rate"), "pause": ("pause",)}
#: The largest yaw a start or a mount is given at, degrees (ten turns either way).
MAX_YAW_DEG = 3600.0
#: The keys of a scene file's [trajectory] table.
TRAJECTORY_KEYS = ("start", "mount", "height", "smoothing_s", "segments", "waypoints", "speed", "turn_rate")


def _fail(message: str, where: str) -> ConfigError:
    return ConfigError(message, path=where, field="trajectory")


def check_keys(table: dict, known: Sequence[str], where: str, what: str) -> None:
    """Refuse a key of *table* not in *known* (a typo would silently take the default),
    naming it, the table (*what*) and the keys it takes."""
    unknown = [key for key in table if key not in known]
    if unknown:
        raise ConfigError(f"unknown key {unknown[0]!r}{f' in {what}' if what else ''}; "
                          f"{f'{what} takes' if what else 'a scene takes'} {', '.join(known)}",
                          path=where, field=f"{what}.{unknown[0]}" if what and " " not in what else unknown[0])


def _number(seg: dict, key: str, where: str, default: float | None = None, positive: bool = False,
            maximum: tuple[float, str] | None = None) -> float:
    """*seg*'s number *key*; *maximum*: (the largest, its unit and why)."""
    value = seg.get(key, default)
    if value is None:
        raise _fail(f"{quoted(seg)} needs {key!r}", where)
    number = finite_float(value)
    if number is None:
        raise _fail(f"{key} must be a number, got {quoted(value)}", where)
    if positive and number <= 0:
        raise _fail(f"{key} must be above 0, got {quoted(value)}", where)
    if maximum is not None and number > maximum[0]:
        raise _fail(f"{key} must be at most {maximum[0]:g} {maximum[1]}, got {beyond_text(number, maximum[0])}", where)
    return number


#: _number's maxima of a speed and of a turn's rate.
_SPEED = (MAX_SPEED_MPS, "m/s (a robot's or a car's)")
_RATE = (MAX_TURN_RATE_DPS, "deg/s (ten turns a second)")


def polyline(value: Any, where: str, what: str) -> np.ndarray:
    """Two or more finite [x, y] points as a float array (n, 2), or ConfigError."""
    try:
        pts = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):  # (an integer of 309 digits overflows a float)
        pts = np.zeros((0, 0))
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.all(np.isfinite(pts)):
        raise ConfigError(f"must be two or more [x, y] points of numbers, got {value!r}"[:200],
                          path=where, field=what)
    check_coordinates(pts, value, where, what)
    return pts


def _lasting(amount: float, rate: float) -> float:
    """How long *amount* takes at *rate*, s: infinite where the rate underflowed to 0 (a rate of
    5e-324 deg/s is 0 rad/s), which the trajectory's longest duration then refuses."""
    return amount / rate if rate > 0.0 else (math.inf if amount > 0.0 else 0.0)


def _commands(segments: Sequence[dict], where: str) -> list[tuple[float, float, float]]:
    """(duration s, speed m/s, yaw rate rad/s) per segment."""
    out = []
    for i, seg in enumerate(segments):
        kind = next((k for k in SEGMENT_KEYS if k in seg), None) if isinstance(seg, dict) else None
        try:
            out.append(_command(seg, kind, where))
        except ConfigError as exc:  # told which segment of the list, counted from 0, and its kind
            raise exc.located(field=f"trajectory.segments[{i}]" + (f" ({kind})" if kind else "")) from None
    total = sum(duration for duration, _, _ in out)
    if total > MAX_DURATION_S:
        raise _fail(f"the segments last {total:.4g} s, more than the {MAX_DURATION_S:g} s a scene's trajectory "
                    "may (a longer run repeats it: sim://SCENE?loop=0)", where)
    return out


def _command(seg: Any, kind: str | None, where: str) -> tuple[float, float, float]:
    """One segment's (duration s, speed m/s, yaw rate rad/s); *kind*: its first key of SEGMENT_KEYS."""
    if not isinstance(seg, dict):
        raise _fail(f"a segment must be a table, got {seg!r}", where)
    if kind is None:
        raise _fail(f"unknown segment {seg!r}: use straight, turn, rotate or pause", where)
    check_keys(seg, SEGMENT_KEYS[kind], where, f"a {kind} segment")
    if kind == "straight":
        dist = _number(seg, "straight", where, positive=True)
        speed = _number(seg, "speed", where, 1.0, positive=True, maximum=_SPEED)
        return dist / speed, speed, 0.0
    if kind == "turn":
        angle = math.radians(_number(seg, "turn", where))
        radius = _number(seg, "radius", where, 1.0, positive=True)
        speed = _number(seg, "speed", where, 1.0, positive=True, maximum=_SPEED)
        rate = speed / radius
        if math.degrees(rate) > MAX_TURN_RATE_DPS:
            shown = beyond_text(math.degrees(rate), MAX_TURN_RATE_DPS)
            raise _fail(f"a turn at {speed:g} m/s on a radius of {radius:g} m turns at {shown} deg/s, more than "
                        f"{MAX_TURN_RATE_DPS:g} (ten turns a second): a larger radius or a rotate segment", where)
        return _lasting(abs(angle), rate), speed, math.copysign(rate, angle)
    if kind == "rotate":
        angle = math.radians(_number(seg, "rotate", where))
        rate = math.radians(_number(seg, "rate", where, 45.0, positive=True, maximum=_RATE))
        return _lasting(abs(angle), rate), 0.0, math.copysign(rate, angle)
    return _number(seg, "pause", where, positive=True), 0.0, 0.0


def from_segments(segments: Sequence[dict], *, start: Sequence[float] = (0.0, 0.0, 0.0),
                  smoothing_s: float = 0.3, height: float = 0.4, mount: Sequence[float] = (0.0, 0.0, 0.0),
                  where: str = "<scene>") -> Trajectory:
    """Build a trajectory; *start* is the base's (x m, y m, yaw deg), *mount* the radar's
    (x m ahead, y m left, yaw deg) on the base."""
    cmds = _commands(segments, where)
    if not cmds:
        raise _fail("no segments (waypoints make none when they are all at one place)", where)
    speeds, rates = [], []
    for duration, v, w in cmds:
        # A segment shorter than a step takes one, at the speed that keeps its distance and angle
        # (left out, many short ones added up to a turn or a distance lost); a zero turn takes none.
        n = max(1, round(duration / STEP_S)) if duration > 0.0 else 0
        if n == 0:
            continue
        # Rounding the duration to whole steps would change the distance and angle:
        # scale the command instead so that its integral stays exact.
        stretch = duration / (n * STEP_S)
        speeds.append(np.full(n, v * stretch))
        rates.append(np.full(n, w * stretch))
    if not speeds:
        raise _fail("the segments add up to no motion and no time (every turn of 0 degrees)", where)
    speed, rate = np.concatenate(speeds), np.concatenate(rates)
    width = max(1, round(smoothing_s / STEP_S))
    box = np.full(width, 1.0 / width)
    for _ in range(2):  # twice: continuous speed and continuous acceleration
        speed = np.convolve(speed, box)
        rate = np.convolve(rate, box)
    x0, y0, yaw0 = float(start[0]), float(start[1]), math.radians(float(start[2]))
    yaw = yaw0 + np.concatenate([[0.0], np.cumsum(rate) * STEP_S])
    mid_yaw = 0.5 * (yaw[1:] + yaw[:-1])  # midpoint rule: exact for constant-rate arcs to O(dt^2)
    x = x0 + np.concatenate([[0.0], np.cumsum(speed * np.cos(mid_yaw)) * STEP_S])
    y = y0 + np.concatenate([[0.0], np.cumsum(speed * np.sin(mid_yaw)) * STEP_S])
    times = np.arange(len(yaw)) * STEP_S
    mx, my, myaw = float(mount[0]), float(mount[1]), math.radians(float(mount[2]))
    if (mx, my, myaw) != (0.0, 0.0, 0.0):
        c, s = np.cos(yaw), np.sin(yaw)
        x, y, yaw = x + c * mx - s * my, y + s * mx + c * my, yaw + myaw
    return Trajectory(times, x, y, yaw, height, (mx, my, myaw))


def waypoint_segments(points: Sequence[Sequence[float]], *, start_yaw_deg: float = 0.0,
                      speed: float = 1.0, turn_rate_deg: float = 45.0, where: str = "<scene>") -> list[dict]:
    """Segments that visit *points* in order: rotate toward each, then drive to it."""
    pts = polyline(points, where, "trajectory.waypoints")
    segs: list[dict] = []
    heading = math.radians(start_yaw_deg)
    for a, b in zip(pts[:-1], pts[1:]):
        d = b - a
        dist = float(np.hypot(*d))
        if dist < 1e-9:
            continue
        want = math.atan2(d[1], d[0])
        turn = (want - heading + math.pi) % (2 * math.pi) - math.pi
        if abs(turn) > 1e-6:
            segs.append({"rotate": math.degrees(turn), "rate": turn_rate_deg})
        segs.append({"straight": dist, "speed": speed})
        heading = want
    return segs


def from_spec(spec: dict[str, Any], where: str = "<scene>") -> Trajectory:
    """A trajectory from a scene file's ``[trajectory]`` table."""
    if not isinstance(spec, dict):
        raise _fail("must be a table", where)
    check_keys(spec, TRAJECTORY_KEYS, where, "trajectory")
    start = _triple(spec, "start", where)
    mount = _triple(spec, "mount", where)
    height = _number(spec, "height", where, 0.4, positive=True,
                     maximum=(MAX_COORDINATE_M, "m (a scene is metres high)"))
    smoothing = _number(spec, "smoothing_s", where, 0.3, positive=True)
    if smoothing > MAX_SMOOTHING_S:
        raise _fail(f"smoothing_s must be at most {MAX_SMOOTHING_S:g} s (the speed and turn-rate ramps), "
                    f"got {smoothing:g}", where)
    if "waypoints" in spec:
        if "segments" in spec:
            raise _fail("give either segments or waypoints, not both", where)
        segments = waypoint_segments(spec["waypoints"], start_yaw_deg=start[2],
                                     speed=_number(spec, "speed", where, 1.0, positive=True, maximum=_SPEED),
                                     turn_rate_deg=_number(spec, "turn_rate", where, 45.0, positive=True,
                                                           maximum=_RATE),
                                     where=where)
    else:
        segments = spec.get("segments")
        if not isinstance(segments, list):
            raise _fail("needs a list of segments or waypoints", where)
        given = [key for key in ("speed", "turn_rate") if key in spec]
        if given:  # else left unused, the segments' own speeds (default 1 m/s) taken instead
            verb = "goes" if len(given) == 1 else "go"
            raise _fail(f"{' and '.join(given)} {verb} with waypoints; with segments each segment takes its own "
                        "(straight = 2, speed = 0.5; rotate = 90, rate = 30)", where)
    return from_segments(segments, start=start, smoothing_s=smoothing, height=height, mount=mount,
                         where=where)


def _triple(spec: dict[str, Any], key: str, where: str) -> list[float]:
    """An optional [x m, y m, yaw deg] (default zeros), or ConfigError."""
    value = spec.get(key, [0.0, 0.0, 0.0])
    if not (isinstance(value, (list, tuple)) and len(value) == 3 and all(finite_float(v) is not None for v in value)):
        raise _fail(f"{key} must be [x, y, yaw_deg], got {quoted(value)}", where)
    x, y, yaw = (float(v) for v in value)
    check_coordinates(np.array([x, y]), value, where, f"trajectory.{key}")
    if abs(yaw) > MAX_YAW_DEG:  # cos and sin of 1e300 degrees are numbers, but of no heading meant
        raise ConfigError(f"yaw must be within {MAX_YAW_DEG:g} degrees either way, got {beyond_text(yaw, MAX_YAW_DEG)}",
                          path=where, field=f"trajectory.{key}")
    return [x, y, yaw]
