"""Rigid transforms as 7-tuples of Python floats: the buffer's hot path.

A pose is ``(tx, ty, tz, qx, qy, qz, qw)`` (quaternion x, y, z, w as in ROS),
always with a unit quaternion. For one transform at a time, plain float
arithmetic is several times faster than numpy (whose per-call overhead is
about a microsecond) and than building ``scipy.spatial.transform.Rotation``
objects; :mod:`visnav.tf.transforms` offers the numpy API for users.

:func:`jit_kernels` returns the hot functions compiled by numba, for
``Buffer(jit=True)``: a call with tuples of floats then costs about a third of the
interpreted arithmetic, for a one-time import and compile cost (measured in
bench/bench_tf.py). The default lookup path does not call these functions: it has the
same arithmetic written out in its chain loop (:func:`visnav.tf._plan.side`); the
``*_py`` functions are the reference the tests compare both with.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from math import acos, sin

__all__ = [
    "COS_TINY_THETA",
    "IDENTITY",
    "Pose7",
    "compose",
    "compose_py",
    "interpolate",
    "interpolate_compose",
    "interpolate_compose_py",
    "interpolate_py",
    "inverse",
    "inverse_py",
    "jit_kernels",
    "pose_to_rows",
    "slerp",
]

Pose7 = tuple[float, float, float, float, float, float, float]
"""Translation x, y, z then quaternion x, y, z, w."""

IDENTITY: Pose7 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)

# Below this arc (rad, on the unit 4-sphere) normalised linear interpolation differs
# from slerp by ~1e-14 rad and avoids dividing by a tiny sin(theta).
_NLERP_THETA = 1e-4
# interpolate(): below this angle between the quaternions the slerp weights are linear.
_TINY_THETA = 1e-7
_COS_TINY_THETA = math.cos(_TINY_THETA)
COS_TINY_THETA = _COS_TINY_THETA
"""Quaternion dot products at or above this interpolate with linear weights."""


def compose_py(a: Pose7, b: Pose7) -> Pose7:
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


def inverse_py(a: Pose7) -> Pose7:
    """Return the inverse rigid transform of ``a``: ``(-R^T t, conjugate(q))``."""
    tx, ty, tz, x, y, z, w = a
    # R^T t with c = 2 v x t (v the vector part): R^T t = t - w c + v x c.
    cx = 2.0 * (y * tz - z * ty)
    cy = 2.0 * (z * tx - x * tz)
    cz = 2.0 * (x * ty - y * tx)
    return (
        w * cx - tx - y * cz + z * cy,
        w * cy - ty - z * cx + x * cz,
        w * cz - tz - x * cy + y * cx,
        -x,
        -y,
        -z,
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


def interpolate_py(a: Pose7, b: Pose7, ratio: float) -> Pose7:
    """Linear interpolation of the translation and slerp of the rotation (tf2's scheme).

    One flat function (no helper calls, no intermediate tuples): it runs on every
    interpolated link of every lookup. The slerp weights come from ``acos`` of the
    dot product, as tf2's do: its rounding near dot = 1 changes the weights only by
    about ``theta * error``, far below 1e-12. Below ``_TINY_THETA`` (where
    ``sin(theta)`` underflows the division) the weights are linear, exact to
    ``theta**2``.
    """
    atx, aty, atz, x0, y0, z0, w0 = a
    btx, bty, btz, x1, y1, z1, w1 = b
    r0 = 1.0 - ratio
    dot = x0 * x1 + y0 * y1 + z0 * z1 + w0 * w1
    if dot < 0.0:  # the shorter arc: -q1 is the same rotation
        dot = -dot
        x1 = -x1
        y1 = -y1
        z1 = -z1
        w1 = -w1
    if dot < _COS_TINY_THETA:
        theta = acos(dot)
        inv_sin = 1.0 / sin(theta)
        s0 = sin(r0 * theta) * inv_sin
        s1 = sin(ratio * theta) * inv_sin
    else:
        s0 = r0
        s1 = ratio
    return (
        r0 * atx + ratio * btx,
        r0 * aty + ratio * bty,
        r0 * atz + ratio * btz,
        s0 * x0 + s1 * x1,
        s0 * y0 + s1 * y1,
        s0 * z0 + s1 * z1,
        s0 * w0 + s1 * w1,
    )


def interpolate_compose_py(a: Pose7, b: Pose7, ratio: float, acc: Pose7) -> Pose7:
    """Return ``interpolate(a, b, ratio) * acc`` in one call (the lookup's hot step).

    Written out flat: whole-tuple unpacking and no helper calls measured 9 % faster
    than indexing (this runs once per interpolated link of every lookup).
    """
    atx, aty, atz, x0, y0, z0, w0 = a
    btx, bty, btz, x1, y1, z1, w1 = b
    r0 = 1.0 - ratio
    dot = x0 * x1 + y0 * y1 + z0 * z1 + w0 * w1
    if dot < 0.0:  # the shorter arc: -q1 is the same rotation
        dot = -dot
        x1 = -x1
        y1 = -y1
        z1 = -z1
        w1 = -w1
    if dot < _COS_TINY_THETA:
        theta = acos(dot)
        inv_sin = 1.0 / sin(theta)
        s0 = sin(r0 * theta) * inv_sin
        s1 = sin(ratio * theta) * inv_sin
    else:
        s0 = r0
        s1 = ratio
    ax = s0 * x0 + s1 * x1
    ay = s0 * y0 + s1 * y1
    az = s0 * z0 + s1 * z1
    aw = s0 * w0 + s1 * w1
    tx, ty, tz, bx, by, bz, bw = acc
    cx = 2.0 * (ay * tz - az * ty)
    cy = 2.0 * (az * tx - ax * tz)
    cz = 2.0 * (ax * ty - ay * tx)
    return (
        tx + aw * cx + ay * cz - az * cy + r0 * atx + ratio * btx,
        ty + aw * cy + az * cx - ax * cz + r0 * aty + ratio * bty,
        tz + aw * cz + ax * cy - ay * cx + r0 * atz + ratio * btz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
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


compose = compose_py
inverse = inverse_py
interpolate = interpolate_py
interpolate_compose = interpolate_compose_py


@functools.cache  # compiled code, like numba's own dispatcher cache: once per process
def jit_kernels() -> tuple[
    Callable[[Pose7, Pose7, float], Pose7],
    Callable[[Pose7, Pose7, float, Pose7], Pose7],
    Callable[[Pose7, Pose7], Pose7],
]:
    """Return :func:`interpolate`, :func:`interpolate_compose`, :func:`compose`, compiled.

    Imports numba and compiles them now, for tuples of floats (``cache=True``: about a
    second of CPU once per machine, then about 0.4 s per process to import numba and
    load the cache). A call then costs about a third of the interpreted arithmetic.
    """
    import numba  # noqa: PLC0415 - only for Buffer(jit=True): numba's import is slow

    jit = numba.njit(cache=True)
    kernels = jit(interpolate_py), jit(interpolate_compose_py), jit(compose_py)
    kernels[0](IDENTITY, IDENTITY, 0.5)  # compile (or load) for float tuples now
    kernels[1](IDENTITY, IDENTITY, 0.5, IDENTITY)
    kernels[2](IDENTITY, IDENTITY)
    return kernels
