"""What a step of the estimator says about its own quality: the flags of an odometry state,
and the rule for how long a last good value may stand in for a failed one."""

from __future__ import annotations

import enum


class TextEnum(str, enum.Enum):
    """An enumeration whose members are their text everywhere a string is expected: JSON,
    ``join``, f-strings and comparisons with the plain string (``Flag.FIRST_FRAME ==
    "first_frame"``).  Python 3.11's ``enum.StrEnum``, for 3.10 as well."""

    __hash__ = str.__hash__  # equal to its text, so it hashes as its text does

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, spec: str) -> str:
        return format(str(self.value), spec)


class Flag(TextEnum):
    """Quality flags of an odometry state (``OdometryState.flags``)."""

    FIRST_FRAME = "first_frame"
    #: No good velocity near this frame ...
    VELOCITY_FAILED = "velocity_failed"
    #: ... the last good one was used ...
    VELOCITY_HELD = "velocity_held"
    #: ... the heatmap's Doppler gave it.
    VELOCITY_FROM_HEATMAP = "velocity_from_heatmap"
    FEW_FEATURES = "few_features"
    #: The heatmaps hold nothing to register (the scan guess's verdict).
    NO_STRUCTURE = "no_structure"
    #: Registration found too few matches.
    ICP_FAILED = "icp_failed"
    ICP_NOT_CONVERGED = "icp_not_converged"
    #: The last good yaw rate was used.
    YAW_HELD = "yaw_held"
    #: Nothing good for longer than ``odometry.hold_s``: no motion reported.
    MOTION_LOST = "motion_lost"


#: A step flagged with any of these had no velocity measured in it at all: one from before stood
#: in, or none did.  A step whose clouds' fit failed (``velocity_failed``) alone may still have the
#: heatmap's Doppler's (``velocity_from_heatmap``), which the Doppler yaw rate takes.
HELD_OR_NO_VELOCITY = frozenset({Flag.VELOCITY_HELD, Flag.MOTION_LOST})
#: A step flagged with any of these had no velocity of its own from its clouds: their fit failed,
#: or one from before stood in, or none did.
UNMEASURED_VELOCITY = HELD_OR_NO_VELOCITY | {Flag.VELOCITY_FAILED}
#: A step flagged with any of these measured no turn of its own: its yaw rate from before stood
#: in, or none did.
UNMEASURED_TURN = frozenset({Flag.YAW_HELD, Flag.MOTION_LOST})


def may_hold(good_t: float | None, t: float, hold_s: float, flag: Flag, flags: list[Flag]) -> bool:
    """Whether the last good value (taken at *good_t*, None: never) may still stand in at *t*:
    if so *flag* is added to *flags*, if not ``motion_lost`` (once)."""
    if good_t is not None and t - good_t <= hold_s:
        flags.append(flag)
        return True
    if Flag.MOTION_LOST not in flags:
        flags.append(Flag.MOTION_LOST)
    return False
