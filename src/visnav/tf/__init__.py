"""Coordinate frames and transforms with tf2 semantics, without ROS.

:class:`Buffer` stores stamped transforms and answers ``T_target_source`` at
any stored time (interpolating between samples, as tf2). The errors keep
tf2's names. :mod:`visnav.tf.geometry` applies transforms to stamped messages
(tf2_geometry_msgs' and tf2_sensor_msgs' ``do_transform_*``; ``Buffer.transform``).
:mod:`visnav.tf.transforms` holds the numpy/message math used
across visnav (quaternions x, y, z, w; ``T_a_b`` maps points from ``b`` into ``a``).

Broadcasters, the listener and the state publishers build on the graph and
live in their own modules.
"""

from __future__ import annotations

from visnav.tf.buffer import Buffer, FrameInfo, TimeLike
from visnav.tf.errors import (
    ConnectivityException,
    ExtrapolationException,
    InvalidArgumentException,
    LookupException,
    TransformException,
)
from visnav.tf.geometry import (
    do_transform_cloud,
    do_transform_point,
    do_transform_pose,
    do_transform_pose_stamped,
    do_transform_pose_with_covariance_stamped,
    do_transform_vector3,
    do_transform_wrench,
)
from visnav.tf.transforms import (
    check_transform_matrix,
    compose,
    euler_from_quaternion,
    invert,
    matrix_to_pose,
    matrix_to_quaternion,
    matrix_to_transform,
    matrix_to_translation_quaternion,
    pose_to_matrix,
    quaternion_from_euler,
    quaternion_inverse,
    quaternion_multiply,
    quaternion_normalize,
    quaternion_to_matrix,
    slerp,
    transform_points,
    transform_to_matrix,
    translation_quaternion_to_matrix,
)

__all__ = [
    "Buffer",
    "FrameInfo",
    "TimeLike",
    "ConnectivityException",
    "ExtrapolationException",
    "InvalidArgumentException",
    "LookupException",
    "TransformException",
    "check_transform_matrix",
    "compose",
    "do_transform_cloud",
    "do_transform_point",
    "do_transform_pose",
    "do_transform_pose_stamped",
    "do_transform_pose_with_covariance_stamped",
    "do_transform_vector3",
    "do_transform_wrench",
    "euler_from_quaternion",
    "invert",
    "matrix_to_pose",
    "matrix_to_quaternion",
    "matrix_to_transform",
    "matrix_to_translation_quaternion",
    "pose_to_matrix",
    "quaternion_from_euler",
    "quaternion_inverse",
    "quaternion_multiply",
    "quaternion_normalize",
    "quaternion_to_matrix",
    "slerp",
    "transform_points",
    "transform_to_matrix",
    "translation_quaternion_to_matrix",
]
