"""ROS frames worked out independently of radarodom.ros2_frames, for the tests of the ROS 2
outputs: 4x4 homogeneous matrices from positions and (x, y, z, w) quaternions."""

from __future__ import annotations

import math

import numpy as np

from radarodom.mount import Mount


def matrix(x=0.0, y=0.0, z=0.0, q=(0.0, 0.0, 0.0, 1.0)) -> np.ndarray:
    qx, qy, qz, qw = q
    m = np.eye(4)
    m[:3, :3] = [[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
                 [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
                 [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]]
    m[:3, 3] = x, y, z
    return m


def planar(x, y, yaw, z=0.0) -> np.ndarray:
    return matrix(x, y, z, (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)))


def of_msg(translation, rotation) -> np.ndarray:
    return matrix(translation.x, translation.y, translation.z, (rotation.x, rotation.y, rotation.z, rotation.w))


def mount_matrix(mount: Mount) -> np.ndarray:
    return planar(mount.x, mount.y, mount.yaw, mount.z)


def base_in_odom(state, mount: Mount) -> np.ndarray:
    """base_link in odom: the radar's motion (the estimator's, relative to the radar at the first
    frame) seen from the base: M R M^-1."""
    m = mount_matrix(mount)
    return m @ planar(state.x, state.y, state.yaw) @ np.linalg.inv(m)


def seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9
