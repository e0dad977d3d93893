"""radarodom's frames in ROS's TF tree, ``odom -> base_link -> radar``, and the arithmetic that
moves the estimator's radar motion onto the robot's base.

- ``radar``: the radar's own REP-103 frame (x along the boresight, y left, z up); the TI sensor
  frame of point clouds is turned into it (``x = y_TI``, ``y = -x_TI``, ``z = z_TI``).
- ``base_link``: the robot's base; ``base_link -> radar`` is the mount
  (:class:`radarodom.mount.Mount`, ``radar-capture --mount x,y,z,yaw_deg``; without one the
  radar is the base and the transform is the identity).
- ``odom``: base_link at the first odometry frame.

The estimator works in the radar's frame: its pose is the radar's, relative to the radar at the
first frame (``R0``).  With the mount ``M`` (base_link -> radar) the base's pose in odom is
``M * R * M^-1``; for a yaw-only mount this is planar again (the mount's height cancels):

    yaw_B = yaw_R
    p_B   = t_M + Rot(yaw_M) p_R - Rot(yaw_R) t_M           (xy of the mount, t_M)

and the base's twist in base_link, from the radar's (a point t_M ahead of the rotation axis moves
sideways at yaw rate x lever arm):

    v_B = Rot(yaw_M) v_R + yaw_rate * (t_My, -t_Mx),   yaw_rate_B = yaw_rate_R

The covariances are carried through the Jacobians of these maps.  Ground truth (a 3-D pose of the
radar in the dataset's world ``W``) goes the same way, from the first true pose ``T_W,R0``:
``M * T_W,R0^-1 * T_W,Rk * M^-1``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .message_format import ODOM_FRAME_ID
from .mount import Mount

BASE_FRAME_ID = "base_link"
RADAR_FRAME_ID = "radar"
__all__ = ["BASE_FRAME_ID", "RADAR_FRAME_ID", "ODOM_FRAME_ID", "Rigid", "BasePose", "base_pose", "TruthInOdom",
           "ti_to_radar"]


Vector = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]


def _quat_mul(a: Quaternion, b: Quaternion) -> Quaternion:
    """Hamilton product of (x, y, z, w) quaternions (plain floats: faster than numpy for one)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def _rotate(q: Quaternion, v: Vector) -> Vector:
    """*v* turned by the unit quaternion *q* (x, y, z, w): v + 2w (u x v) + 2 u x (u x v)."""
    ux, uy, uz, w = q
    vx, vy, vz = v
    tx, ty, tz = 2.0 * (uy * vz - uz * vy), 2.0 * (uz * vx - ux * vz), 2.0 * (ux * vy - uy * vx)
    return (vx + w * tx + uy * tz - uz * ty,
            vy + w * ty + uz * tx - ux * tz,
            vz + w * tz + ux * ty - uy * tx)


@dataclass(frozen=True)
class Rigid:
    """A rigid transform: translation (x, y, z) m and unit quaternion (x, y, z, w)."""

    translation: Vector
    rotation: Quaternion

    @classmethod
    def planar(cls, x: float, y: float, yaw: float, z: float = 0.0) -> Rigid:
        return cls((float(x), float(y), float(z)), (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)))

    @classmethod
    def of_mount(cls, mount: Mount) -> Rigid:
        """base_link -> radar."""
        return cls.planar(mount.x, mount.y, mount.yaw, mount.z)

    @classmethod
    def of_pose(cls, pose: Sequence[float]) -> Rigid:
        """A pose (x, y, z, qx, qy, qz, qw) as sources give ground truth; the quaternion normalised."""
        qx, qy, qz, qw = (float(v) for v in pose[3:7])
        norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        x, y, z = (float(v) for v in pose[:3])
        return cls((x, y, z), (qx / norm, qy / norm, qz / norm, qw / norm))

    def __mul__(self, other: Rigid) -> Rigid:
        moved = _rotate(self.rotation, other.translation)
        return Rigid(tuple(a + b for a, b in zip(self.translation, moved)),  # type: ignore[arg-type]
                     _quat_mul(self.rotation, other.rotation))

    def inverse(self) -> Rigid:
        qx, qy, qz, qw = self.rotation
        conj = (-qx, -qy, -qz, qw)
        back = _rotate(conj, self.translation)
        return Rigid((-back[0], -back[1], -back[2]), conj)

    @property
    def yaw(self) -> float:
        x, y, z, w = self.rotation
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _rot2(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


@dataclass(frozen=True)
class BasePose:
    """base_link's planar odometry in odom: pose (x, y, yaw; yaw unwrapped as the estimator's),
    twist in base_link (vx, vy, yaw_rate), and their 3x3 covariances."""

    x: float
    y: float
    yaw: float
    vx: float
    vy: float
    yaw_rate: float
    pose_covariance: np.ndarray
    twist_covariance: np.ndarray


def base_pose(state, mount: Mount) -> BasePose:
    """The base's odometry of an estimator state (the radar's; module docstring)."""
    pose_cov = np.asarray(state.pose_covariance, float)
    twist_cov = np.asarray(state.twist_covariance, float)
    x, y, yaw = float(state.x), float(state.y), float(state.yaw)
    vx, vy, rate = float(state.vx), float(state.vy), float(state.yaw_rate)
    if mount.is_identity:
        return BasePose(x, y, yaw, vx, vy, rate, pose_cov, twist_cov)
    rot_m, t_m = _rot2(mount.yaw), np.array([mount.x, mount.y])
    p = t_m + rot_m @ np.array([x, y]) - _rot2(yaw) @ t_m
    s, c = math.sin(yaw), math.cos(yaw)
    j_pose = np.eye(3)
    j_pose[:2, :2] = rot_m
    j_pose[:2, 2] = [s * mount.x + c * mount.y, -c * mount.x + s * mount.y]
    v = rot_m @ np.array([vx, vy]) + rate * np.array([mount.y, -mount.x])
    j_twist = np.eye(3)
    j_twist[:2, :2] = rot_m
    j_twist[:2, 2] = [mount.y, -mount.x]
    return BasePose(float(p[0]), float(p[1]), yaw, float(v[0]), float(v[1]), rate,
                    j_pose @ pose_cov @ j_pose.T, j_twist @ twist_cov @ j_twist.T)


class TruthInOdom:
    """Ground truth (the radar's poses in a world frame) as base_link's pose in odom: relative
    to the first true pose given, through the mount (module docstring)."""

    def __init__(self, mount: Mount) -> None:
        self._mount = Rigid.of_mount(mount)
        self._mount_inv = self._mount.inverse()
        self._first_inv: Rigid | None = None

    def __call__(self, pose: Sequence[float]) -> Rigid:
        radar = Rigid.of_pose(pose)
        if self._first_inv is None:
            self._first_inv = radar.inverse()
        return self._mount * self._first_inv * radar * self._mount_inv


def ti_to_radar(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x, y, z) in the radar's REP-103 frame of points in the TI sensor frame
    (:data:`radarodom.products.POINT_DTYPE`'s x right, y boresight, z up)."""
    return points["y"], -points["x"], points["z"]
