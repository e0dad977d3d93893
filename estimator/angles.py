"""Angle helpers shared by the registration, the features and the evaluation."""

from __future__ import annotations

import numpy as np


def wrap(angle):
    """Angle(s) in rad (any shape) wrapped into [-pi, pi)."""
    return (np.asarray(angle, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def wrap_line(angle):
    """A difference of lines' directions (rad; a float or an array), which have no sense, into
    [-pi/2, pi/2)."""
    return (angle + np.pi / 2) % np.pi - np.pi / 2
