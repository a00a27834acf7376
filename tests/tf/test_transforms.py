"""Tests of visnav.tf.transforms and the buffer's scalar math (visnav.tf._scalar)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from visnav.msgs import Header, Pose, Time, TransformStamped
from visnav.tf import _scalar
from visnav.tf.errors import InvalidArgumentException
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

finite = st.floats(-1.0, 1.0, allow_nan=False)
quaternions = (
    st.tuples(finite, finite, finite, finite)
    .filter(lambda q: sum(c * c for c in q) > 0.01)
    .map(lambda q: np.array(q) / np.linalg.norm(q))
)
translations = st.tuples(*[st.floats(-100.0, 100.0, allow_nan=False)] * 3).map(np.array)
transforms = st.builds(translation_quaternion_to_matrix, translations, quaternions)
fractions = st.floats(0.0, 1.0, allow_nan=False)


def angle_between(q0: NDArray[np.float64], q1: NDArray[np.float64]) -> float:
    """Rotation angle (rad) between two unit quaternions, sign-agnostic (atan2: exact near 0)."""
    d = quaternion_multiply(quaternion_inverse(q0), q1)
    return 2.0 * math.atan2(float(np.linalg.norm(d[:3])), abs(float(d[3])))


@given(quaternions)
def test_quaternion_to_matrix_matches_scipy(q: NDArray[np.float64]) -> None:
    np.testing.assert_allclose(
        quaternion_to_matrix(q), Rotation.from_quat(q).as_matrix(), atol=1e-12
    )


@given(quaternions)
def test_matrix_to_quaternion_round_trip(q: NDArray[np.float64]) -> None:
    back = matrix_to_quaternion(quaternion_to_matrix(q))
    assert back[3] >= 0.0
    assert abs(abs(float(np.dot(back, q))) - 1.0) < 1e-9


@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (0, 1, 1)])
def test_matrix_to_quaternion_half_turns(axis: tuple[int, int, int]) -> None:
    # 180-degree rotations have trace -1: the non-trace branches of Shepperd's method.
    rot = Rotation.from_rotvec(math.pi * np.array(axis) / np.linalg.norm(axis))
    q = matrix_to_quaternion(rot.as_matrix())
    np.testing.assert_allclose(quaternion_to_matrix(q), rot.as_matrix(), atol=1e-12)


def test_matrix_to_quaternion_refuses_non_rotations() -> None:
    with pytest.raises(InvalidArgumentException, match="not a rotation"):
        matrix_to_quaternion(2.0 * np.eye(3))
    with pytest.raises(InvalidArgumentException, match="not a rotation"):
        matrix_to_quaternion(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(InvalidArgumentException, match=r"shape \(2, 2\)"):
        matrix_to_quaternion(np.eye(2))
    np.testing.assert_allclose(matrix_to_quaternion(np.eye(4)), [0, 0, 0, 1])


def test_quaternion_validation() -> None:
    with pytest.raises(InvalidArgumentException, match="zero length"):
        quaternion_normalize([0, 0, 0, 0])
    with pytest.raises(InvalidArgumentException, match="finite"):
        quaternion_to_matrix([0, 0, math.nan, 1])
    with pytest.raises(InvalidArgumentException, match=r"shape \(3,\)"):
        quaternion_to_matrix([0, 0, 1])
    np.testing.assert_allclose(quaternion_normalize([0, 0, 0, 2]), [0, 0, 0, 1])


@given(quaternions, quaternions)
def test_quaternion_multiply_matches_scipy(
    q1: NDArray[np.float64], q2: NDArray[np.float64]
) -> None:
    expected = (Rotation.from_quat(q1) * Rotation.from_quat(q2)).as_matrix()
    np.testing.assert_allclose(
        quaternion_to_matrix(quaternion_multiply(q1, q2)), expected, atol=1e-12
    )


@given(quaternions)
def test_quaternion_inverse(q: NDArray[np.float64]) -> None:
    np.testing.assert_allclose(
        quaternion_multiply(q, quaternion_inverse(q)), [0, 0, 0, 1], atol=1e-12
    )
    np.testing.assert_allclose(quaternion_inverse(2.0 * q), quaternion_inverse(q) / 2.0, atol=1e-12)


def test_quaternion_from_euler_known_values() -> None:
    s = math.sqrt(0.5)
    np.testing.assert_allclose(quaternion_from_euler(0, 0, math.pi / 2), [0, 0, s, s], atol=1e-15)
    np.testing.assert_allclose(quaternion_from_euler(math.pi / 2, 0, 0), [s, 0, 0, s], atol=1e-15)
    np.testing.assert_allclose(quaternion_from_euler(0, math.pi / 2, 0), [0, s, 0, s], atol=1e-15)
    with pytest.raises(InvalidArgumentException, match="finite"):
        quaternion_from_euler(0.0, math.inf, 0.0)


angles = st.floats(-math.pi, math.pi, allow_nan=False)


@given(angles, st.floats(-1.5, 1.5), angles)
def test_euler_matches_ros_convention(roll: float, pitch: float, yaw: float) -> None:
    # ROS rpy: fixed axes x, y, z = scipy's lowercase (extrinsic) 'xyz' = intrinsic 'ZYX'.
    q = quaternion_from_euler(roll, pitch, yaw)
    expected = Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix()
    np.testing.assert_allclose(quaternion_to_matrix(q), expected, atol=1e-12)
    np.testing.assert_allclose(
        quaternion_to_matrix(q),
        Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix(),
        atol=1e-12,
    )
    r, p, y = euler_from_quaternion(q)
    assert p == pytest.approx(pitch, abs=1e-9)
    assert math.remainder(r - roll, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)
    assert math.remainder(y - yaw, 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("pitch", [math.pi / 2, -math.pi / 2])
@pytest.mark.parametrize("roll", [0.3, -2.0])
def test_euler_at_gimbal_lock_reproduces_rotation(pitch: float, roll: float) -> None:
    q = quaternion_from_euler(roll, pitch, 0.7)
    r, p, y = euler_from_quaternion(q)
    assert y == 0.0
    assert p == pytest.approx(pitch, abs=1e-6)
    np.testing.assert_allclose(
        quaternion_to_matrix(quaternion_from_euler(r, p, y)), quaternion_to_matrix(q), atol=1e-6
    )


@given(quaternions, quaternions)
def test_slerp_endpoints(q0: NDArray[np.float64], q1: NDArray[np.float64]) -> None:
    assert angle_between(slerp(q0, q1, 0.0), q0) < 1e-6
    assert angle_between(slerp(q0, q1, 1.0), q1) < 1e-6


@given(quaternions, quaternions, fractions, fractions)
def test_slerp_is_monotonic_and_constant_speed(
    q0: NDArray[np.float64], q1: NDArray[np.float64], a: float, b: float
) -> None:
    lo, hi = sorted((a, b))
    total = angle_between(q0, q1)
    d_lo = angle_between(q0, slerp(q0, q1, lo))
    d_hi = angle_between(q0, slerp(q0, q1, hi))
    assert d_lo <= d_hi + 1e-9
    # Constant angular speed along the shorter arc.
    assert d_hi == pytest.approx(hi * total, abs=1e-9)


def test_slerp_takes_the_shorter_arc() -> None:
    q0 = quaternion_from_euler(0, 0, 0.1)
    q1 = -quaternion_from_euler(0, 0, 0.3)  # same rotation as +q, opposite hemisphere
    mid = slerp(q0, q1, 0.5)
    assert euler_from_quaternion(mid)[2] == pytest.approx(0.2, abs=1e-12)
    with pytest.raises(InvalidArgumentException, match="fraction"):
        slerp(q0, q1, math.nan)


@given(transforms)
def test_compose_invert_round_trip(mat: NDArray[np.float64]) -> None:
    np.testing.assert_allclose(compose(mat, invert(mat)), np.eye(4), atol=1e-9)
    np.testing.assert_allclose(compose(invert(mat), mat), np.eye(4), atol=1e-9)
    np.testing.assert_allclose(invert(invert(mat)), mat, atol=1e-9)
    np.testing.assert_allclose(invert(mat), np.linalg.inv(mat), atol=1e-9)


@given(transforms, transforms, transforms)
def test_compose_is_associative_and_inverts(
    ma: NDArray[np.float64], mb: NDArray[np.float64], mc: NDArray[np.float64]
) -> None:
    np.testing.assert_allclose(compose(ma, mb, mc), ma @ mb @ mc, atol=1e-9)
    np.testing.assert_allclose(invert(compose(ma, mb)), compose(invert(mb), invert(ma)), atol=1e-9)
    np.testing.assert_allclose(compose(), np.eye(4))


def test_compose_refuses_bad_shape() -> None:
    with pytest.raises(InvalidArgumentException, match=r"transform 1 has shape \(3, 3\)"):
        compose(np.eye(4), np.eye(3))


@given(transforms)
def test_matrix_message_round_trips(mat: NDArray[np.float64]) -> None:
    msg = matrix_to_transform(mat)
    assert msg.rotation.w >= 0.0
    np.testing.assert_allclose(transform_to_matrix(msg), mat, atol=1e-9)
    np.testing.assert_allclose(pose_to_matrix(matrix_to_pose(mat)), mat, atol=1e-9)
    t, q = matrix_to_translation_quaternion(mat)
    np.testing.assert_allclose(translation_quaternion_to_matrix(t, q), mat, atol=1e-9)


def test_transform_to_matrix_accepts_stamped_and_pose() -> None:
    T = translation_quaternion_to_matrix([1, 2, 3], quaternion_from_euler(0.1, 0.2, 0.3))
    stamped = TransformStamped(Header(Time(1, 0), "a"), "b", matrix_to_transform(T))
    np.testing.assert_allclose(transform_to_matrix(stamped), T, atol=1e-12)
    pose = matrix_to_pose(T)
    assert isinstance(pose, Pose)
    assert (pose.position.x, pose.position.y, pose.position.z) == pytest.approx((1, 2, 3))


def test_check_transform_matrix_errors() -> None:
    bad_row = np.eye(4)
    bad_row[3, 0] = 0.5
    with pytest.raises(InvalidArgumentException, match="last row"):
        check_transform_matrix(bad_row)
    reflect = np.diag([1.0, -1.0, 1.0, 1.0])
    with pytest.raises(InvalidArgumentException, match="det"):
        matrix_to_transform(reflect)
    nan = np.eye(4)
    nan[0, 3] = math.nan
    with pytest.raises(InvalidArgumentException, match="non-finite"):
        check_transform_matrix(nan, name="T_map_odom")
    with pytest.raises(InvalidArgumentException, match=r"T_x has shape \(3, 4\)"):
        check_transform_matrix(np.zeros((3, 4)), name="T_x")


@given(transforms, st.lists(translations, min_size=1, max_size=5))
def test_transform_points_matches_homogeneous(
    mat: NDArray[np.float64], pts: list[NDArray[np.float64]]
) -> None:
    P = np.array(pts)
    homog = np.c_[P, np.ones(len(P))] @ mat.T
    np.testing.assert_allclose(transform_points(mat, P), homog[:, :3], atol=1e-9)
    np.testing.assert_allclose(transform_points(mat, P[0]), homog[0, :3], atol=1e-9)


def test_transform_points_dtype_and_shape() -> None:
    T = translation_quaternion_to_matrix([1, 0, 0], [0, 0, 0, 1])
    pts32 = np.zeros((4, 3), dtype=np.float32)
    out = transform_points(T, pts32)
    assert out.dtype == np.float32
    np.testing.assert_array_equal(out[:, 0], 1.0)
    assert transform_points(T, [[0, 0, 0]]).dtype == np.float64
    with pytest.raises(InvalidArgumentException, match=r"shape \(4, 2\)"):
        transform_points(T, np.zeros((4, 2)))


@settings(max_examples=200)
@given(transforms, transforms, fractions)
def test_scalar_math_matches_numpy(
    ma: NDArray[np.float64], mb: NDArray[np.float64], ratio: float
) -> None:
    def pose7(mat: NDArray[np.float64]) -> _scalar.Pose7:
        t, q = matrix_to_translation_quaternion(mat)
        return (t[0], t[1], t[2], q[0], q[1], q[2], q[3])

    A, B = ma, mb
    a, b = pose7(A), pose7(B)
    np.testing.assert_allclose(
        np.array(_scalar.pose_to_rows(_scalar.compose(a, b))), A @ B, atol=1e-9
    )
    np.testing.assert_allclose(
        np.array(_scalar.pose_to_rows(_scalar.inverse(a))), invert(A), atol=1e-9
    )
    mid = _scalar.interpolate(a, b, ratio)
    np.testing.assert_allclose(mid[:3], (1 - ratio) * A[:3, 3] + ratio * B[:3, 3], atol=1e-9)
    np.testing.assert_allclose(mid[3:], slerp(a[3:], b[3:], ratio), atol=1e-12)
