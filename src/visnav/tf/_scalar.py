"""Rigid transforms as 7-tuples of Python floats: the buffer's hot path.

A pose is ``(tx, ty, tz, qx, qy, qz, qw)`` (quaternion x, y, z, w as in ROS),
always with a unit quaternion. For one transform at a time, plain float
arithmetic is several times faster than numpy (whose per-call overhead is
about a microsecond) and than building ``scipy.spatial.transform.Rotation``
objects; :mod:`visnav.tf.transforms` offers the numpy API for users.
"""

from __future__ import annotations

import math

__all__ = [
    "IDENTITY",
    "Pose7",
    "compose",
    "interpolate",
    "inverse",
    "pose_to_rows",
    "slerp",
]

Pose7 = tuple[float, float, float, float, float, float, float]
"""Translation x, y, z then quaternion x, y, z, w."""

IDENTITY: Pose7 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)

# Below this arc (rad, on the unit 4-sphere) normalised linear interpolation differs
# from slerp by ~1e-14 rad and avoids dividing by a tiny sin(theta).
_NLERP_THETA = 1e-4


def compose(a: Pose7, b: Pose7) -> Pose7:
    """Return ``a * b``: the transform that applies ``b`` first, then ``a``."""
    atx, aty, atz, ax, ay, az, aw = a
    btx, bty, btz, bx, by, bz, bw = b
    # Rotate b's translation by a's rotation: v + w*t + q x t with t = 2 q x v.
    cx = 2.0 * (ay * btz - az * bty)
    cy = 2.0 * (az * btx - ax * btz)
    cz = 2.0 * (ax * bty - ay * btx)
    return (
        btx + aw * cx + ay * cz - az * cy + atx,
        bty + aw * cy + az * cx - ax * cz + aty,
        btz + aw * cz + ax * cy - ay * cx + atz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    )


def inverse(a: Pose7) -> Pose7:
    """Return the inverse rigid transform of ``a``."""
    tx, ty, tz, x, y, z, w = a
    # Rotate -t by the conjugate (-x, -y, -z, w).
    x, y, z = -x, -y, -z
    cx = 2.0 * (y * -tz + z * ty)
    cy = 2.0 * (z * -tx + x * tz)
    cz = 2.0 * (x * -ty + y * tx)
    return (
        -tx + w * cx + y * cz - z * cy,
        -ty + w * cy + z * cx - x * cz,
        -tz + w * cz + x * cy - y * cx,
        x,
        y,
        z,
        w,
    )


def slerp(
    q0: tuple[float, float, float, float], q1: tuple[float, float, float, float], ratio: float
) -> tuple[float, float, float, float]:
    """Spherical linear interpolation along the shorter arc between unit quaternions.

    ``ratio`` 0 gives ``q0`` and 1 gives ``q1`` (or ``-q1``, the same rotation).
    """
    x0, y0, z0, w0 = q0
    x1, y1, z1, w1 = q1
    dot = x0 * x1 + y0 * y1 + z0 * z1 + w0 * w1
    if dot < 0.0:
        x1, y1, z1, w1 = -x1, -y1, -z1, -w1
    # The arc between the two 4-vectors from |q1 - q0| and |q1 + q0|: exact at any
    # angle, where acos(dot) loses half the digits near dot = 1.
    dx, dy, dz, dw = x1 - x0, y1 - y0, z1 - z0, w1 - w0
    sx, sy, sz, sw = x1 + x0, y1 + y0, z1 + z0, w1 + w0
    theta = 2.0 * math.atan2(
        math.sqrt(dx * dx + dy * dy + dz * dz + dw * dw),
        math.sqrt(sx * sx + sy * sy + sz * sz + sw * sw),
    )
    if theta < _NLERP_THETA:
        s0 = 1.0 - ratio
        s1 = ratio
    else:
        inv_sin = 1.0 / math.sin(theta)
        s0 = math.sin((1.0 - ratio) * theta) * inv_sin
        s1 = math.sin(ratio * theta) * inv_sin
    x = s0 * x0 + s1 * x1
    y = s0 * y0 + s1 * y1
    z = s0 * z0 + s1 * z1
    w = s0 * w0 + s1 * w1
    n = 1.0 / math.sqrt(x * x + y * y + z * z + w * w)
    return (x * n, y * n, z * n, w * n)


def interpolate(a: Pose7, b: Pose7, ratio: float) -> Pose7:
    """Linear interpolation of the translation and slerp of the rotation (tf2's scheme)."""
    r0 = 1.0 - ratio
    qx, qy, qz, qw = slerp((a[3], a[4], a[5], a[6]), (b[3], b[4], b[5], b[6]), ratio)
    return (
        r0 * a[0] + ratio * b[0],
        r0 * a[1] + ratio * b[1],
        r0 * a[2] + ratio * b[2],
        qx,
        qy,
        qz,
        qw,
    )


def pose_to_rows(p: Pose7) -> list[list[float]]:
    """Return the 4x4 homogeneous matrix of ``p`` as nested lists (for ``np.array``)."""
    tx, ty, tz, x, y, z, w = p
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return [
        [1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy), tx],
        [2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx), ty],
        [2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy), tz],
        [0.0, 0.0, 0.0, 1.0],
    ]
