"""Rigid-transform math on numpy arrays and ROS messages.

Conventions (see the design notes):

* Quaternions are ``(x, y, z, w)`` as in ROS messages and scipy (not w-first
  as in Eigen's constructor, transforms3d or pytransform3d).
* ``T_a_b`` is a 4x4 homogeneous matrix that maps points from frame ``b``
  into frame ``a``: ``p_a = T_a_b @ p_b``. ``compose(T_a_b, T_b_c) == T_a_c``.
* Euler angles are ROS's roll, pitch, yaw: rotations about the fixed x, then
  y, then z axes, i.e. ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (tf's ``setRPY``
  and ``tf_transformations``' default ``'sxyz'``).

Every function validates its input and names the offending shape or value in
an :class:`~visnav.tf.errors.InvalidArgumentException` (a ``ValueError``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from visnav.description.rigid import rpy_to_matrix
from visnav.msgs.types import Point, Pose, Quaternion, Transform, TransformStamped, Vector3
from visnav.tf import _scalar
from visnav.tf.errors import InvalidArgumentException

__all__ = [
    "check_transform_matrix",
    "compose",
    "euler_from_quaternion",
    "invert",
    "matrix_to_pose",
    "matrix_to_quaternion",
    "matrix_from_euler",
    "matrix_to_transform",
    "matrix_to_translation_quaternion",
    "pose_to_matrix",
    "quaternion_from_euler",
    "quaternion_from_yaw",
    "quaternion_inverse",
    "quaternion_multiply",
    "quaternion_normalize",
    "quaternion_to_matrix",
    "slerp",
    "transform_points",
    "transform_to_matrix",
    "translation_quaternion_to_matrix",
    "yaw_from_matrix",
    "yaw_from_quaternion",
]

FloatArray = NDArray[np.float64]

_ROTATION_TOLERANCE = 1e-6


def _floats(value: object, name: str) -> FloatArray:
    """``value`` as a float64 array, or InvalidArgumentException naming ``name``."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        msg = f"{name} is {value!r:.80}: expected numbers ({exc})"
        raise InvalidArgumentException(msg) from exc


def _as_vector(value: ArrayLike, size: int, name: str) -> FloatArray:
    arr = _floats(value, name)
    if arr.shape != (size,):
        msg = f"{name} has shape {arr.shape}: expected ({size},)"
        raise InvalidArgumentException(msg)
    if not np.all(np.isfinite(arr)):
        msg = f"{name} is {arr.tolist()}: expected finite values"
        raise InvalidArgumentException(msg)
    return arr


def quaternion_normalize(q: ArrayLike) -> FloatArray:
    """Return ``q`` (x, y, z, w) scaled to unit length.

    Raises:
        InvalidArgumentException: ``q`` is not 4 finite numbers or has zero length.
    """
    arr = _as_vector(q, 4, "quaternion (x, y, z, w)")
    norm = float(np.linalg.norm(arr))
    if norm < 1e-12:
        msg = f"quaternion (x, y, z, w) {arr.tolist()} has zero length: it is not a rotation"
        raise InvalidArgumentException(msg)
    return arr / norm


def quaternion_multiply(q1: ArrayLike, q2: ArrayLike) -> FloatArray:
    """Return the Hamilton product ``q1 * q2`` (rotation ``q2`` applied first), x, y, z, w."""
    x1, y1, z1, w1 = _as_vector(q1, 4, "q1 (x, y, z, w)").tolist()
    x2, y2, z2, w2 = _as_vector(q2, 4, "q2 (x, y, z, w)").tolist()
    return np.array(
        [
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        ]
    )


def quaternion_inverse(q: ArrayLike) -> FloatArray:
    """Return the inverse of ``q`` (the conjugate divided by the squared norm), x, y, z, w."""
    arr = _as_vector(q, 4, "quaternion (x, y, z, w)")
    n2 = float(arr @ arr)
    if n2 < 1e-24:
        msg = f"quaternion (x, y, z, w) {arr.tolist()} has zero length: it has no inverse"
        raise InvalidArgumentException(msg)
    return np.array([-arr[0], -arr[1], -arr[2], arr[3]]) / n2


def quaternion_to_matrix(q: ArrayLike) -> FloatArray:
    """Return the 3x3 rotation matrix of quaternion ``q`` (x, y, z, w; normalised first)."""
    x, y, z, w = quaternion_normalize(q).tolist()
    rows = _scalar.pose_to_rows((0.0, 0.0, 0.0, x, y, z, w))
    return np.array(rows)[:3, :3]


def matrix_to_quaternion(matrix: ArrayLike) -> FloatArray:
    """Return the unit quaternion (x, y, z, w, with ``w >= 0``) of a rotation matrix.

    Args:
        matrix: a 3x3 rotation, or a 4x4 homogeneous transform whose rotation part is used.

    Raises:
        InvalidArgumentException: wrong shape, non-finite, or not a rotation (R R^T != I,
            det != 1, tolerance 1e-6).
    """
    m = _floats(matrix, "rotation matrix")
    if m.shape == (4, 4):
        m = m[:3, :3]
    if m.shape != (3, 3):
        msg = f"rotation matrix has shape {np.shape(matrix)}: expected (3, 3) or (4, 4)"
        raise InvalidArgumentException(msg)
    _check_rotation(m, "rotation matrix")
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = m.tolist()
    trace = m00 + m11 + m22
    # Shepperd's method: divide by the largest of the four candidate components.
    if trace > 0.0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = [(m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s]
    elif m00 >= m11 and m00 >= m22:
        s = 2.0 * math.sqrt(max(1.0 + m00 - m11 - m22, 0.0))
        q = [0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s]
    elif m11 >= m22:
        s = 2.0 * math.sqrt(max(1.0 + m11 - m00 - m22, 0.0))
        q = [(m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s]
    else:
        s = 2.0 * math.sqrt(max(1.0 + m22 - m00 - m11, 0.0))
        q = [(m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s]
    arr = np.array(q)
    if arr[3] < 0.0:
        arr = -arr
    return arr / float(np.linalg.norm(arr))


def _check_rotation(m: FloatArray, name: str) -> None:
    if not np.all(np.isfinite(m)):
        msg = f"{name} has non-finite entries: {m.tolist()}"
        raise InvalidArgumentException(msg)
    err = float(np.max(np.abs(m @ m.T - np.eye(3))))
    det = float(np.linalg.det(m))
    if err > _ROTATION_TOLERANCE or abs(det - 1.0) > _ROTATION_TOLERANCE:
        msg = (
            f"{name} is not a rotation: max |R R^T - I| = {err:.3g}, det = {det:.6g} "
            f"(expected orthonormal with det 1 within {_ROTATION_TOLERANCE:g}); "
            "a scaled or reflected matrix cannot be a ROS transform"
        )
        raise InvalidArgumentException(msg)


def slerp(q0: ArrayLike, q1: ArrayLike, t: float) -> FloatArray:
    """Spherical linear interpolation between two rotations along the shorter arc.

    Args:
        q0: the rotation at ``t = 0`` (x, y, z, w; normalised first).
        q1: the rotation at ``t = 1``.
        t: the fraction; values outside [0, 1] extrapolate along the same great circle.

    Returns:
        The unit quaternion (x, y, z, w). At ``t = 1`` it may be ``-q1`` (the same rotation).
    """
    a = quaternion_normalize(q0).tolist()
    b = quaternion_normalize(q1).tolist()
    if not math.isfinite(t):
        msg = f"slerp fraction t is {t}: expected a finite number"
        raise InvalidArgumentException(msg)
    return np.array(_scalar.slerp((a[0], a[1], a[2], a[3]), (b[0], b[1], b[2], b[3]), float(t)))


def quaternion_from_euler(roll: float, pitch: float, yaw: float) -> FloatArray:
    """Return the quaternion (x, y, z, w) of ROS roll, pitch, yaw (fixed axes x, y, z).

    ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``, as tf2's ``Quaternion::setRPY``.
    """
    hr, hp, hy = 0.5 * float(roll), 0.5 * float(pitch), 0.5 * float(yaw)
    if not (math.isfinite(hr) and math.isfinite(hp) and math.isfinite(hy)):
        msg = f"roll, pitch, yaw = ({roll}, {pitch}, {yaw}): expected finite angles in radians"
        raise InvalidArgumentException(msg)
    cr, sr = math.cos(hr), math.sin(hr)
    cp, sp = math.cos(hp), math.sin(hp)
    cy, sy = math.cos(hy), math.sin(hy)
    return np.array(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ]
    )


def euler_from_quaternion(q: ArrayLike) -> tuple[float, float, float]:
    """Return ROS ``(roll, pitch, yaw)`` in radians of quaternion ``q`` (x, y, z, w).

    ``pitch`` is in [-pi/2, pi/2]; ``roll`` and ``yaw`` in (-pi, pi]. At gimbal lock
    (``|pitch| = pi/2``) yaw is reported as 0 and the rotation about z goes into roll.
    """
    m = quaternion_to_matrix(q)
    r20 = float(m[2, 0])
    pitch = math.atan2(-r20, math.hypot(float(m[0, 0]), float(m[1, 0])))
    if abs(r20) < 1.0 - 1e-12:
        roll = math.atan2(float(m[2, 1]), float(m[2, 2]))
        yaw = math.atan2(float(m[1, 0]), float(m[0, 0]))
    elif r20 < 0.0:  # pitch = +pi/2
        roll, yaw = math.atan2(float(m[0, 1]), float(m[0, 2])), 0.0
    else:  # pitch = -pi/2
        roll, yaw = math.atan2(-float(m[0, 1]), -float(m[0, 2])), 0.0
    return roll, pitch, yaw


def matrix_from_euler(roll: float, pitch: float, yaw: float) -> FloatArray:
    """Return the 3x3 rotation matrix of ROS roll, pitch, yaw (fixed axes x, then y, then z).

    ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``: URDF's ``<origin rpy>``, tf2's ``Matrix3x3::setRPY``
    and ``tf_transformations.euler_matrix(roll, pitch, yaw)`` (its 3x3 part).

    Raises:
        InvalidArgumentException: an angle is not finite.
    """
    r, p, y = float(roll), float(pitch), float(yaw)
    if not (math.isfinite(r) and math.isfinite(p) and math.isfinite(y)):
        msg = f"roll, pitch, yaw = ({roll}, {pitch}, {yaw}): expected finite angles in radians"
        raise InvalidArgumentException(msg)
    return rpy_to_matrix((r, p, y))


def quaternion_from_yaw(yaw: float) -> Quaternion:
    """Return the ``geometry_msgs/Quaternion`` of a heading: a rotation of ``yaw`` about z.

    ``(0, 0, sin(yaw / 2), cos(yaw / 2))``: nav2_util's ``orientationAroundZAxis``, the
    orientation of a planar pose (a goal, a map origin, a 2D pose estimate).
    :func:`yaw_from_quaternion` is its inverse (up to a multiple of 2 pi).

    Raises:
        InvalidArgumentException: ``yaw`` is not a finite number.
    """
    half = 0.5 * float(yaw)
    if not math.isfinite(half):
        msg = f"yaw is {yaw}: expected a finite angle in radians"
        raise InvalidArgumentException(msg)
    return Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))


def _xyzw(q: Quaternion | ArrayLike) -> tuple[float, float, float, float]:
    """The 4 finite components of a quaternion message or sequence (fast for both)."""
    name = "quaternion (x, y, z, w)"
    if isinstance(q, Quaternion):
        values: Any = (q.x, q.y, q.z, q.w)
    elif isinstance(q, (tuple, list)) and len(q) == 4:
        values = q
    else:
        values = _as_vector(q, 4, name).tolist()
    try:
        x, y, z, w = float(values[0]), float(values[1]), float(values[2]), float(values[3])
    except (TypeError, ValueError) as exc:
        msg = f"{name} is {values!r:.80}: expected 4 numbers ({exc})"
        raise InvalidArgumentException(msg) from exc
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z) and math.isfinite(w)):
        msg = f"{name} is ({x}, {y}, {z}, {w}): expected finite values"
        raise InvalidArgumentException(msg)
    return x, y, z, w


def yaw_from_quaternion(q: Quaternion | ArrayLike) -> float:
    """Return the heading (yaw, radians in [-pi, pi]) of a quaternion.

    The heading is the angle of the rotated x axis projected on the x-y plane,
    ``atan2(R[1, 0], R[0, 0])``: the yaw of :func:`euler_from_quaternion` and of tf2's
    ``tf2::getYaw`` away from gimbal lock. At ``|pitch| = pi/2`` the heading is undefined:
    this returns the angle of the rounding residue (often 0) where tf2 moves the roll into
    the yaw.

    Args:
        q: a ``geometry_msgs/Quaternion`` or 4 numbers x, y, z, w. A quaternion that is
            not of unit length is used as the rotation it represents (its direction).

    Raises:
        InvalidArgumentException: not 4 finite numbers, or of zero length.
    """
    x, y, z, w = _xyzw(q)
    n2 = x * x + y * y + z * z + w * w
    if not math.isfinite(n2):  # finite components too large to square: scale them down
        big = max(abs(x), abs(y), abs(z), abs(w))
        x, y, z, w = x / big, y / big, z / big, w / big
        n2 = x * x + y * y + z * z + w * w
    if n2 < 1e-24:
        msg = f"quaternion (x, y, z, w) ({x}, {y}, {z}, {w}) has zero length: it is not a rotation"
        raise InvalidArgumentException(msg)
    # R00 = n2 - 2 (y^2 + z^2) and R10 = 2 (x y + w z) for any scale; a unit quaternion
    # (within rounding) uses 1 exactly so the result is bit-identical to the textbook form.
    scale = 1.0 if abs(n2 - 1.0) < 1e-9 else n2
    return math.atan2(2.0 * (w * z + x * y), scale - 2.0 * (y * y + z * z))


def yaw_from_matrix(matrix: ArrayLike) -> float:
    """Return the heading (yaw, radians) of a 3x3 rotation or 4x4 transform: ``atan2(R10, R00)``.

    The same angle as :func:`yaw_from_quaternion` of the matrix's rotation; the matrix is
    not checked for orthonormality (it is read, not inverted).

    Raises:
        InvalidArgumentException: not 3x3 or 4x4, or its entries ``R00``, ``R10`` are not
            finite.
    """
    m = _floats(matrix, "rotation matrix")
    if m.shape not in ((3, 3), (4, 4)):
        msg = f"rotation matrix has shape {m.shape}: expected (3, 3) or (4, 4)"
        raise InvalidArgumentException(msg)
    r00, r10 = float(m[0, 0]), float(m[1, 0])
    if not (math.isfinite(r00) and math.isfinite(r10)):
        msg = f"rotation matrix has R00 = {r00}, R10 = {r10}: expected finite values"
        raise InvalidArgumentException(msg)
    return math.atan2(r10, r00)


def translation_quaternion_to_matrix(translation: ArrayLike, quaternion: ArrayLike) -> FloatArray:
    """Return the 4x4 transform of a translation (3,) and a quaternion (x, y, z, w)."""
    t = _as_vector(translation, 3, "translation")
    x, y, z, w = quaternion_normalize(quaternion).tolist()
    return np.array(_scalar.pose_to_rows((float(t[0]), float(t[1]), float(t[2]), x, y, z, w)))


def matrix_to_translation_quaternion(matrix: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Return ``(translation (3,), quaternion (4,) x, y, z, w with w >= 0)`` of a 4x4 transform."""
    m = check_transform_matrix(matrix)
    return m[:3, 3].copy(), matrix_to_quaternion(m[:3, :3])


def check_transform_matrix(matrix: ArrayLike, *, name: str = "transform") -> FloatArray:
    """Validate a 4x4 rigid transform and return it as a float64 array.

    Raises:
        InvalidArgumentException: not 4x4, non-finite, last row not ``[0, 0, 0, 1]``, or a
            rotation part that is not orthonormal with determinant 1 (tolerance 1e-6).
    """
    m = _floats(matrix, name)
    if m.shape != (4, 4):
        msg = f"{name} has shape {m.shape}: expected a (4, 4) homogeneous matrix"
        raise InvalidArgumentException(msg)
    if not np.all(np.isfinite(m)):
        msg = f"{name} has non-finite entries: {m.tolist()}"
        raise InvalidArgumentException(msg)
    if not np.allclose(m[3], [0.0, 0.0, 0.0, 1.0], atol=_ROTATION_TOLERANCE, rtol=0.0):
        msg = f"{name} has last row {m[3].tolist()}: expected [0, 0, 0, 1]"
        raise InvalidArgumentException(msg)
    _check_rotation(m[:3, :3], f"rotation part of {name}")
    return m


def _as_matrix(matrix: ArrayLike, name: str) -> FloatArray:
    m = _floats(matrix, name)
    if m.shape != (4, 4):
        msg = f"{name} has shape {m.shape}: expected a (4, 4) homogeneous matrix"
        raise InvalidArgumentException(msg)
    return m


def compose(*matrices: ArrayLike) -> FloatArray:
    """Return the product of 4x4 transforms, left to right: ``compose(T_a_b, T_b_c) = T_a_c``.

    With no argument, the identity.
    """
    out = np.eye(4)
    for i, m in enumerate(matrices):
        out = out @ _as_matrix(m, f"transform {i}")
    return out


def invert(matrix: ArrayLike) -> FloatArray:
    """Return the inverse of a rigid 4x4 transform (``T_b_a`` from ``T_a_b``): R^T, -R^T t."""
    m = _as_matrix(matrix, "transform")
    out = np.eye(4)
    rt = m[:3, :3].T
    out[:3, :3] = rt
    out[:3, 3] = -rt @ m[:3, 3]
    return out


def transform_points(matrix: ArrayLike, points: ArrayLike) -> NDArray[Any]:
    """Map points through a 4x4 transform: ``T_a_b`` takes points in ``b`` into ``a``.

    Args:
        matrix: the 4x4 transform.
        points: one point (3,) or many (N, 3). float32 input stays float32 (point clouds);
            anything else is computed in float64.

    Returns:
        The transformed points, same shape as ``points``.
    """
    m = _as_matrix(matrix, "transform")
    pts = np.asarray(points)
    if pts.shape[-1:] != (3,) or pts.ndim not in (1, 2):
        msg = f"points have shape {pts.shape}: expected (3,) or (N, 3)"
        raise InvalidArgumentException(msg)
    dtype = np.float32 if pts.dtype == np.float32 else np.float64
    rot = m[:3, :3].astype(dtype)
    trans = m[:3, 3].astype(dtype)
    pts = pts.astype(dtype, copy=False)
    out: NDArray[Any] = pts @ rot.T + trans
    return out


def transform_to_matrix(transform: Transform | TransformStamped) -> FloatArray:
    """Return the 4x4 matrix of a ``geometry_msgs/Transform`` (or ``TransformStamped``).

    For a stamped transform with ``header.frame_id = a`` and ``child_frame_id = b``, this is
    ``T_a_b``. The quaternion is normalised; a zero or non-finite one is refused.
    """
    tf = transform.transform if isinstance(transform, TransformStamped) else transform
    t, r = tf.translation, tf.rotation
    return translation_quaternion_to_matrix([t.x, t.y, t.z], [r.x, r.y, r.z, r.w])


def matrix_to_transform(matrix: ArrayLike) -> Transform:
    """Return a ``geometry_msgs/Transform`` of a validated rigid 4x4 matrix (``w >= 0``)."""
    t, q = matrix_to_translation_quaternion(matrix)
    return Transform(
        translation=Vector3(x=float(t[0]), y=float(t[1]), z=float(t[2])),
        rotation=Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])),
    )


def pose_to_matrix(pose: Pose) -> FloatArray:
    """Return the 4x4 matrix of a ``geometry_msgs/Pose`` (the pose of a body in its header frame).

    A pose of frame ``b`` expressed in ``a`` is the transform ``T_a_b``.
    """
    p, r = pose.position, pose.orientation
    return translation_quaternion_to_matrix([p.x, p.y, p.z], [r.x, r.y, r.z, r.w])


def matrix_to_pose(matrix: ArrayLike) -> Pose:
    """Return a ``geometry_msgs/Pose`` of a validated rigid 4x4 matrix (``w >= 0``)."""
    t, q = matrix_to_translation_quaternion(matrix)
    return Pose(
        position=Point(x=float(t[0]), y=float(t[1]), z=float(t[2])),
        orientation=Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])),
    )
