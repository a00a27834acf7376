"""Small rigid-transform helpers shared by the robot-description modules.

Conventions: ``T_a_b`` is a 4x4 homogeneous transform mapping points from frame
``b`` into frame ``a``. URDF/SDF ``rpy`` are fixed-axis roll, pitch, yaw
(``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``). Quaternions returned by
:func:`matrix_to_quat_xyzw` are x, y, z, w (ROS order); MuJoCo wants w, x, y, z
(:func:`matrix_to_quat_wxyz`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "R_SENSOR_MJCAM",
    "R_SENSOR_OPTICAL",
    "axis_angle_matrix",
    "make_transform",
    "matrix_to_quat_wxyz",
    "matrix_to_quat_xyzw",
    "quat_xyzw_to_matrix",
    "rpy_to_matrix",
]

Vec3 = tuple[float, float, float]


def rpy_to_matrix(rpy: Sequence[float]) -> NDArray[np.float64]:
    """Return the 3x3 rotation of fixed-axis roll, pitch, yaw (URDF ``origin rpy``)."""
    r, p, y = (float(v) for v in rpy)
    cr, sr = math.cos(r), math.sin(r)
    cp, sp = math.cos(p), math.sin(p)
    cy, sy = math.cos(y), math.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def make_transform(
    xyz: Sequence[float] = (0.0, 0.0, 0.0), rpy: Sequence[float] = (0.0, 0.0, 0.0)
) -> NDArray[np.float64]:
    """Return the 4x4 transform of a translation ``xyz`` and rotation ``rpy``."""
    out = np.eye(4)
    out[:3, :3] = rpy_to_matrix(rpy)
    out[:3, 3] = np.asarray(xyz, dtype=np.float64)
    return out


def axis_angle_matrix(axis: Sequence[float], angle: float) -> NDArray[np.float64]:
    """Return the 3x3 rotation of ``angle`` radians about the unit vector ``axis``."""
    x, y, z = (float(v) for v in axis)
    c, s = math.cos(angle), math.sin(angle)
    t = 1.0 - c
    return np.array(
        [
            [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
            [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
            [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
        ]
    )


def matrix_to_quat_xyzw(rot: NDArray[np.float64]) -> tuple[float, float, float, float]:
    """Return the unit quaternion (x, y, z, w), w >= 0, of a 3x3 rotation matrix."""
    # Python floats (the same IEEE arithmetic as numpy scalars, without their overhead)
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = np.asarray(rot, dtype=np.float64).tolist()
    trace = m00 + m11 + m22
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        w = 0.25 * s
        x = (m21 - m12) / s
        y = (m02 - m20) / s
        z = (m10 - m01) / s
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        w = (m21 - m12) / s
        x = 0.25 * s
        y = (m01 + m10) / s
        z = (m02 + m20) / s
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        w = (m02 - m20) / s
        x = (m01 + m10) / s
        y = 0.25 * s
        z = (m12 + m21) / s
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        w = (m10 - m01) / s
        x = (m02 + m20) / s
        y = (m12 + m21) / s
        z = 0.25 * s
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    sign = -1.0 if w < 0.0 else 1.0
    return (
        float(sign * x / norm),
        float(sign * y / norm),
        float(sign * z / norm),
        float(sign * w / norm),
    )


def matrix_to_quat_wxyz(rot: NDArray[np.float64]) -> tuple[float, float, float, float]:
    """Return the unit quaternion in MuJoCo's (w, x, y, z) order."""
    x, y, z, w = matrix_to_quat_xyzw(rot)
    return (w, x, y, z)


def quat_xyzw_to_matrix(q: Sequence[float]) -> NDArray[np.float64]:
    """Return the 3x3 rotation of a quaternion given x, y, z, w (normalised first)."""
    x, y, z, w = (float(v) for v in q)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


R_SENSOR_MJCAM: NDArray[np.float64] = np.array(
    [[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
)
"""Axes of a MuJoCo camera (x right, y up, looking along -z) in a Gazebo sensor
frame (x forward, y left, z up): columns are the camera's x, y, z."""

R_SENSOR_OPTICAL: NDArray[np.float64] = np.array(
    [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]
)
"""Axes of the optical frame (x right, y down, z forward; REP 103) in a Gazebo
sensor frame; equals ``rpy_to_matrix((-pi/2, 0, -pi/2))``."""
