"""Where the radar sits on the robot: its mounting in the robot's base frame (base_link).

REP-103 axes: x ahead, y left, z up (m); yaw counter-clockwise from the base's x axis (rad).
``radar-capture --mount x,y,z,yaw_deg`` gives one; without it the radar is the base (all zero).
The mounting is what ROS calls the static transform base_link -> radar, and what makes a wheeled
base's yaw rate visible in the radar's Doppler: a radar ahead of (or behind) the rotation axis of
a base that cannot slide sideways moves sideways at yaw rate x lever arm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .errors import UsageError
from .plain_numbers import beyond_text, plain_float

__all__ = ["Mount", "parse_mount"]


@dataclass(frozen=True)
class Mount:
    """The radar's pose on the base: position (m) and yaw (rad)."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x", "y", "z", "yaw"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise UsageError(f"mount {name} must be a finite number, got {value!r}"[:200])

    @property
    def is_identity(self) -> bool:
        return (self.x, self.y, self.z, self.yaw) == (0.0, 0.0, 0.0, 0.0)

    @property
    def lever_arm_m(self) -> float:
        """Distance of the radar from the base's vertical rotation axis, m."""
        return math.hypot(self.x, self.y)


def parse_mount(text: str) -> Mount:
    """``x,y,z,yaw_deg`` (m, m, m, degrees; plain decimal numbers) as a :class:`Mount`, or a
    :class:`UsageError` naming what is wrong."""
    parts = text.split(",")
    if len(parts) != 4:
        raise UsageError(f"a mount is x,y,z,yaw_deg (four numbers: m, m, m, degrees), got {text!r}"[:200])
    values = []
    for name, part in zip(("x", "y", "z", "yaw_deg"), parts):
        value = plain_float(part.strip())
        if value is None or not math.isfinite(value):
            raise UsageError(f"mount {name}: expected a plain decimal number, got {part!r}"[:200])
        values.append(value)
    x, y, z, yaw_deg = values
    if max(abs(x), abs(y), abs(z)) > 100.0:
        raise UsageError(f"mount {text!r}: a radar more than 100 m from its base's origin is no mounting")
    if abs(yaw_deg) > 360.0:
        raise UsageError(f"mount {text!r}: a yaw of {beyond_text(yaw_deg, 360.0, -360.0)} degrees is more than a "
                         f"whole turn: give it within -360..360 degrees ({math.remainder(yaw_deg, 360.0) + 0.0:g} "
                         "here, the same direction)")
    return Mount(x, y, z, math.radians(yaw_deg))
