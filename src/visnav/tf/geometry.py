"""Applying a ``TransformStamped`` to stamped messages (tf2_geometry_msgs, tf2_sensor_msgs).

The ``do_transform_*`` functions follow tf2's conventions:

* the transform is ``T_target_source`` as :meth:`visnav.tf.Buffer.lookup_transform`
  returns it (``header.frame_id`` = target, ``child_frame_id`` = source);
* points, poses and clouds are rotated and translated; vectors (``Vector3Stamped``)
  and wrenches (force and torque) are only rotated;
* the result is a new message whose header is the transform's (its frame and
  stamp); the input is not modified (ROS 1's ``do_transform_vector3`` zeroes the
  transform's translation in place, visnav does not).

Supported: ``PointStamped``, ``Vector3Stamped``, ``PoseStamped``, ``Pose`` (ROS 2's
``do_transform_pose`` takes an unstamped Pose and returns one),
``PoseWithCovarianceStamped`` (the 6x6 covariance rotated as ``R6 C R6^T``),
``WrenchStamped`` and ``PointCloud2`` (``x``, ``y``, ``z`` transformed, every other
field copied unchanged, NaN points stay NaN, as tf2_sensor_msgs).

:func:`transform_object` is ``tf2_ros.Buffer.transform``: look up the transform
from the object's ``header.frame_id`` at its ``header.stamp`` and apply it;
``new_type=numpy.ndarray`` converts the result (a point or vector to a (3,) array,
a pose to its 4x4 matrix, a cloud to (N, 3) xyz).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from visnav.msgs.errors import MessageError
from visnav.msgs.pointcloud import cloud_to_structured, cloud_to_xyz, structured_to_cloud
from visnav.msgs.types import (
    Header,
    Point,
    PointCloud2,
    PointStamped,
    Pose,
    PoseStamped,
    PoseWithCovariance,
    PoseWithCovarianceStamped,
    Quaternion,
    Time,
    TransformStamped,
    Vector3,
    Vector3Stamped,
    Wrench,
    WrenchStamped,
)
from visnav.tf import _scalar
from visnav.tf._scalar import Pose7
from visnav.tf.errors import InvalidArgumentException, TransformException

if TYPE_CHECKING:
    from visnav.msgs.types import Duration
    from visnav.tf.buffer import Buffer

__all__ = [
    "TRANSFORMABLE_TYPES",
    "do_transform_cloud",
    "do_transform_point",
    "do_transform_pose",
    "do_transform_pose_stamped",
    "do_transform_pose_with_covariance_stamped",
    "do_transform_vector3",
    "do_transform_wrench",
    "transform_full_object",
    "transform_object",
]


def _pose7(transform: TransformStamped) -> Pose7:
    """The transform as a unit-quaternion pose (refusing what tf2 would refuse)."""
    if not isinstance(transform, TransformStamped):
        text = (
            f"transform is a {type(transform).__name__}: expected a TransformStamped "
            "(from Buffer.lookup_transform(target, source, time))"
        )
        raise InvalidArgumentException(text)
    t, r = transform.transform.translation, transform.transform.rotation
    values = (float(t.x), float(t.y), float(t.z), float(r.x), float(r.y), float(r.z), float(r.w))
    norm2 = values[3] ** 2 + values[4] ** 2 + values[5] ** 2 + values[6] ** 2
    if not all(math.isfinite(v) for v in values) or abs(norm2 - 1.0) >= 0.01:
        text = (
            f"transform {transform.header.frame_id!r} <- {transform.child_frame_id!r} has "
            f"translation {values[:3]} and rotation (x, y, z, w) {values[3:]}: expected finite "
            "values and a unit quaternion"
        )
        raise InvalidArgumentException(text)
    inv = 1.0 / math.sqrt(norm2)
    return (*values[:3], values[3] * inv, values[4] * inv, values[5] * inv, values[6] * inv)


def _header(transform: TransformStamped) -> Header:
    stamp = transform.header.stamp
    return Header(Time(int(stamp.sec), int(stamp.nanosec)), str(transform.header.frame_id))


def _rotate(p: Pose7, x: float, y: float, z: float) -> tuple[float, float, float]:
    """Rotate (x, y, z) by the rotation of ``p`` (no translation)."""
    rx, ry, rz, *_ = _scalar.compose((0.0, 0.0, 0.0, p[3], p[4], p[5], p[6]), (x, y, z, *_UNIT))
    return rx, ry, rz


_UNIT = (0.0, 0.0, 0.0, 1.0)


def _apply_pose(p: Pose7, pose: Pose) -> Pose:
    q = pose.orientation
    pos = pose.position
    out = _scalar.compose(
        p,
        (
            float(pos.x),
            float(pos.y),
            float(pos.z),
            float(q.x),
            float(q.y),
            float(q.z),
            float(q.w),
        ),
    )
    return Pose(Point(out[0], out[1], out[2]), Quaternion(out[3], out[4], out[5], out[6]))


def do_transform_point(point: PointStamped, transform: TransformStamped) -> PointStamped:
    """Return ``point`` in the transform's target frame (rotated and translated)."""
    p = _pose7(transform)
    q = point.point
    x, y, z, *_ = _scalar.compose(p, (float(q.x), float(q.y), float(q.z), *_UNIT))
    return PointStamped(_header(transform), Point(x, y, z))


def do_transform_vector3(vector3: Vector3Stamped, transform: TransformStamped) -> Vector3Stamped:
    """Return ``vector3`` in the target frame: rotated only (a direction, not a position)."""
    v = vector3.vector
    x, y, z = _rotate(_pose7(transform), float(v.x), float(v.y), float(v.z))
    return Vector3Stamped(_header(transform), Vector3(x, y, z))


def do_transform_pose_stamped(pose: PoseStamped, transform: TransformStamped) -> PoseStamped:
    """Return ``pose`` in the transform's target frame."""
    return PoseStamped(_header(transform), _apply_pose(_pose7(transform), pose.pose))


def do_transform_pose(pose: Pose | PoseStamped, transform: TransformStamped) -> Pose | PoseStamped:
    """Return ``pose`` in the transform's target frame.

    A ``PoseStamped`` gives a ``PoseStamped`` with the transform's header (ROS 1's
    tf2_geometry_msgs); a ``Pose`` gives a ``Pose`` (ROS 2's).
    """
    if isinstance(pose, PoseStamped):
        return do_transform_pose_stamped(pose, transform)
    if isinstance(pose, Pose):
        return _apply_pose(_pose7(transform), pose)
    text = f"pose is a {type(pose).__name__}: expected a Pose or a PoseStamped"
    raise InvalidArgumentException(text)


def _rotation_matrix(p: Pose7) -> NDArray[np.float64]:
    return np.array(_scalar.pose_to_rows(p))[:3, :3]


def do_transform_pose_with_covariance_stamped(
    pose: PoseWithCovarianceStamped, transform: TransformStamped
) -> PoseWithCovarianceStamped:
    """Return the pose in the target frame, its 6x6 covariance rotated (``R6 C R6^T``).

    ``R6`` is ``diag(R, R)``: position and orientation blocks both rotate, as
    tf2_geometry_msgs does.

    Raises:
        InvalidArgumentException: the covariance does not hold 36 values.
    """
    p = _pose7(transform)
    cov = np.asarray(pose.pose.covariance, dtype=np.float64)
    if cov.size != 36:
        text = f"pose.covariance has {cov.size} values: expected 36 (row-major 6x6)"
        raise InvalidArgumentException(text)
    r6 = np.zeros((6, 6))
    r6[:3, :3] = r6[3:, 3:] = _rotation_matrix(p)
    rotated = r6 @ cov.reshape(6, 6) @ r6.T
    return PoseWithCovarianceStamped(
        _header(transform),
        PoseWithCovariance(_apply_pose(p, pose.pose.pose), rotated.reshape(-1)),
    )


def do_transform_wrench(wrench: WrenchStamped, transform: TransformStamped) -> WrenchStamped:
    """Return the wrench in the target frame: force and torque rotated only (tf2's rule)."""
    p = _pose7(transform)
    f, m = wrench.wrench.force, wrench.wrench.torque
    force = _rotate(p, float(f.x), float(f.y), float(f.z))
    torque = _rotate(p, float(m.x), float(m.y), float(m.z))
    return WrenchStamped(_header(transform), Wrench(Vector3(*force), Vector3(*torque)))


def do_transform_cloud(cloud: PointCloud2, transform: TransformStamped) -> PointCloud2:
    """Return the cloud with ``x``, ``y``, ``z`` in the target frame; other fields copied.

    Height, width (organized clouds stay organized) and ``is_dense`` are kept; NaN
    points stay NaN.

    Raises:
        InvalidArgumentException: the cloud is malformed or has no x, y, z fields.
    """
    p = _pose7(transform)
    try:
        points = cloud_to_structured(cloud)
    except MessageError as exc:
        text = f"cannot transform the cloud: {exc}"
        raise InvalidArgumentException(text) from exc
    names = points.dtype.names or ()
    if not {"x", "y", "z"} <= set(names):
        text = f"the cloud has fields {list(names)}: expected x, y and z to transform"
        raise InvalidArgumentException(text)
    out = points.copy()
    xyz = np.stack([points["x"], points["y"], points["z"]], axis=-1).astype(np.float64)
    moved = xyz @ _rotation_matrix(p).T + np.array(p[:3])
    for k, name in enumerate(("x", "y", "z")):
        out[name] = moved[:, k]
    if int(cloud.height) > 1:
        out = out.reshape(int(cloud.height), int(cloud.width))
    return structured_to_cloud(out, header=_header(transform), is_dense=bool(cloud.is_dense))


_DO_TRANSFORM: dict[type[Any], Callable[[Any, TransformStamped], Any]] = {
    PointStamped: do_transform_point,
    Vector3Stamped: do_transform_vector3,
    PoseStamped: do_transform_pose_stamped,
    PoseWithCovarianceStamped: do_transform_pose_with_covariance_stamped,
    WrenchStamped: do_transform_wrench,
    PointCloud2: do_transform_cloud,
}
TRANSFORMABLE_TYPES: tuple[type[Any], ...] = tuple(_DO_TRANSFORM)
"""The stamped message types :func:`transform_object` accepts."""


def _do_transform(obj: Any) -> Callable[[Any, TransformStamped], Any]:
    do = _DO_TRANSFORM.get(type(obj))
    if do is None:
        names = ", ".join(t.__msgtype__.split("/")[-1] for t in TRANSFORMABLE_TYPES)
        text = (
            f"Type {type(obj).__name__} is not a registered type for tf2 transform: "
            f"expected one of {names}"
        )
        raise TransformException(text)
    return do


def _as_new_type(result: Any, new_type: type[Any] | None) -> Any:
    if new_type is None or isinstance(result, new_type):
        return result
    if new_type is np.ndarray:
        if isinstance(result, PointStamped):
            return np.array([result.point.x, result.point.y, result.point.z])
        if isinstance(result, Vector3Stamped):
            return np.array([result.vector.x, result.vector.y, result.vector.z])
        if isinstance(result, (PoseStamped, PoseWithCovarianceStamped)):
            pose = result.pose if isinstance(result, PoseStamped) else result.pose.pose
            o, q = pose.position, pose.orientation
            return np.array(_scalar.pose_to_rows((o.x, o.y, o.z, q.x, q.y, q.z, q.w)))
        if isinstance(result, PointCloud2):
            return cloud_to_xyz(result, skip_nans=False).astype(np.float64)
    text = (
        f"new_type is {getattr(new_type, '__name__', new_type)!r}: a transformed "
        f"{type(result).__name__} converts only to numpy.ndarray (or pass None)"
    )
    raise TransformException(text)


def transform_object(
    buffer: Buffer,
    obj: Any,
    target_frame: str,
    *,
    timeout: float | Duration = 0.0,
    new_type: type[Any] | None = None,
) -> Any:
    """``tf2_ros.Buffer.transform``: ``obj`` (stamped) expressed in ``target_frame``.

    Raises:
        TransformException: an unsupported type or ``new_type``; lookup errors as
            :meth:`visnav.tf.Buffer.lookup_transform`.
    """
    do = _do_transform(obj)
    header = obj.header
    transform = buffer.lookup_transform(
        target_frame, header.frame_id, header.stamp, timeout=timeout
    )
    return _as_new_type(do(obj, transform), new_type)


def transform_full_object(
    buffer: Buffer,
    obj: Any,
    target_frame: str,
    target_time: int | Time,
    fixed_frame: str,
    *,
    timeout: float | Duration = 0.0,
    new_type: type[Any] | None = None,
) -> Any:
    """``tf2_ros.Buffer.transform_full``: through ``fixed_frame`` to ``target_frame`` at a time.

    Raises:
        TransformException: as :func:`transform_object`.
    """
    do = _do_transform(obj)
    header = obj.header
    transform = buffer.lookup_transform_full(
        target_frame, target_time, header.frame_id, header.stamp, fixed_frame, timeout=timeout
    )
    return _as_new_type(do(obj, transform), new_type)
