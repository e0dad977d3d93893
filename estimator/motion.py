"""SE(2) motion of one step: the chord of an arc, and the pose and its covariance integrated
through it."""

from __future__ import annotations

import math

import numpy as np


def chord(yaw: float, dyaw: float, v: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """World displacement (2,) m of a body at heading *yaw* (rad) moving at body velocity *v*
    (2,) m/s for *dt* s while turning by *dyaw* (rad): along an arc, the chord points half the
    turn off the mid velocity.  Also the rotation (2, 2) from the body to the chord's heading."""
    half = yaw + 0.5 * dyaw
    c, s = math.cos(half), math.sin(half)
    turn = np.array([[c, -s], [s, c]])
    return turn @ v * dt, turn


def integrate(pose: tuple[float, float, float], pose_covariance: np.ndarray, v: np.ndarray, v_cov: np.ndarray,
              dyaw: float, var_yaw: float, dt: float,
              pose_var_yaw: float | None = None) -> tuple[tuple[float, float, float], np.ndarray, np.ndarray]:
    """The pose (x, y m, yaw rad) after a step of body velocity *v* (2,) m/s of covariance
    *v_cov* (2, 2) and yaw increment *dyaw* rad of variance *var_yaw* rad^2 over *dt* s; its
    covariance (3, 3) propagated through the step's Jacobians, the step adding *pose_var_yaw*
    rad^2 to its yaw (None: *var_yaw*); and the step's twist covariance (3, 3) of (vx, vy, yaw
    rate)."""
    x0, y0, yaw0 = pose
    step, turn = chord(yaw0, dyaw, v, dt)
    x, y = x0 + step[0], y0 + step[1]
    f = np.eye(3)
    f[0, 2], f[1, 2] = -step[1], step[0]
    g = np.zeros((3, 3))
    g[:2, :2] = turn * dt
    g[2, 2] = dt
    twist = np.zeros((3, 3))
    twist[:2, :2] = v_cov
    twist[2, 2] = var_yaw / (dt * dt)
    added = twist
    if pose_var_yaw is not None:
        added = twist.copy()
        added[2, 2] = pose_var_yaw / (dt * dt)
    covariance = f @ pose_covariance @ f.T + g @ added @ g.T
    return (float(x), float(y), float(yaw0 + dyaw)), covariance, twist
