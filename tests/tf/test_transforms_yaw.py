"""Tests of the heading and Euler helpers of visnav.tf.transforms, checked against scipy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from visnav.msgs import Quaternion
from visnav.tf.errors import InvalidArgumentException
from visnav.tf.transforms import (
    euler_from_quaternion,
    matrix_from_euler,
    quaternion_from_euler,
    quaternion_from_yaw,
    quaternion_to_matrix,
    translation_quaternion_to_matrix,
    yaw_from_matrix,
    yaw_from_quaternion,
)

finite = st.floats(-1.0, 1.0, allow_nan=False)
raw_quaternions = st.tuples(finite, finite, finite, finite).filter(
    lambda q: sum(c * c for c in q) > 0.01
)
angles = st.floats(-10.0, 10.0, allow_nan=False)
# No per-example deadline: the machine is shared, and these check values, not speed.
relaxed = settings(deadline=None)


def _wrapped_diff(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2.0 * math.pi))


def _away_from_gimbal_lock(q: tuple[float, float, float, float]) -> bool:
    m = quaternion_to_matrix(q)
    return math.hypot(float(m[0, 0]), float(m[1, 0])) > 1e-3


@relaxed
@given(raw_quaternions.filter(_away_from_gimbal_lock))
def test_yaw_from_quaternion_matches_scipy(q: tuple[float, float, float, float]) -> None:
    # scipy's lower-case 'xyz' is extrinsic x, y, z: R = Rz(yaw) Ry(pitch) Rx(roll), ROS's RPY.
    expected = float(Rotation.from_quat(q).as_euler("xyz")[2])
    assert _wrapped_diff(yaw_from_quaternion(q), expected) < 1e-9
    assert _wrapped_diff(yaw_from_quaternion(np.array(q)), euler_from_quaternion(q)[2]) < 1e-9


@relaxed
@given(raw_quaternions.filter(_away_from_gimbal_lock), st.floats(0.01, 100.0))
def test_yaw_from_quaternion_ignores_scale(
    q: tuple[float, float, float, float], scale: float
) -> None:
    unit = np.array(q) / np.linalg.norm(q)
    assert _wrapped_diff(yaw_from_quaternion(unit * scale), yaw_from_quaternion(unit)) < 1e-9


def test_yaw_of_huge_finite_quaternions() -> None:
    # Squaring 1e200 overflows; the components are scaled down first.
    assert yaw_from_quaternion((0.0, 0.0, 1e200, 1e200)) == pytest.approx(math.pi / 2)
    assert yaw_from_quaternion([0.0, 0.0, -1e300, 1e300]) == pytest.approx(-math.pi / 2)


@relaxed
@given(raw_quaternions)
def test_yaw_from_quaternion_message_equals_array(q: tuple[float, float, float, float]) -> None:
    msg = Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])
    assert yaw_from_quaternion(msg) == yaw_from_quaternion(q)


@relaxed
@given(raw_quaternions)
def test_unit_quaternion_yaw_is_the_textbook_formula_bit_for_bit(
    q: tuple[float, float, float, float],
) -> None:
    # The callers replaced by this helper used this closed form; same bits keep trajectories.
    x, y, z, w = (np.array(q) / np.linalg.norm(q)).tolist()
    textbook = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    assert yaw_from_quaternion((x, y, z, w)) == textbook


@relaxed
@given(angles)
def test_yaw_of_a_pure_heading(yaw: float) -> None:
    q = quaternion_from_euler(0.0, 0.0, yaw)
    assert _wrapped_diff(yaw_from_quaternion(q), yaw) < 1e-12
    assert -math.pi <= yaw_from_quaternion(q) <= math.pi


@pytest.mark.parametrize(
    "bad",
    [(0.0, 0.0, 0.0, 0.0), (0.0, 0.0, math.nan, 1.0), (math.inf, 0.0, 0.0, 1.0), (0.0, 1.0)],
)
def test_yaw_from_quaternion_refuses_non_rotations(bad: tuple[float, ...]) -> None:
    with pytest.raises(InvalidArgumentException, match="quaternion"):
        yaw_from_quaternion(bad)
    if len(bad) == 4:
        with pytest.raises(InvalidArgumentException, match="quaternion"):
            yaw_from_quaternion(Quaternion(x=bad[0], y=bad[1], z=bad[2], w=bad[3]))


@relaxed
@given(angles, angles, angles)
def test_matrix_from_euler_matches_scipy(roll: float, pitch: float, yaw: float) -> None:
    expected = Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix()
    np.testing.assert_allclose(matrix_from_euler(roll, pitch, yaw), expected, atol=1e-12)
    np.testing.assert_allclose(
        matrix_from_euler(roll, pitch, yaw),
        quaternion_to_matrix(quaternion_from_euler(roll, pitch, yaw)),
        atol=1e-12,
    )


@relaxed
@given(angles)
def test_quaternion_from_yaw_matches_scipy_and_inverts_yaw(yaw: float) -> None:
    q = quaternion_from_yaw(yaw)
    assert isinstance(q, Quaternion)
    xyzw = (q.x, q.y, q.z, q.w)
    expected = Rotation.from_euler("z", yaw).as_matrix()
    np.testing.assert_allclose(quaternion_to_matrix(xyzw), expected, atol=1e-12)
    np.testing.assert_allclose(quaternion_from_euler(0.0, 0.0, yaw), xyzw, atol=1e-15)
    assert _wrapped_diff(yaw_from_quaternion(q), yaw) < 1e-12
    # the callers it replaced wrote this form; the same bits keep trajectories
    assert xyzw == (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_quaternion_from_yaw_refuses_non_finite(bad: float) -> None:
    with pytest.raises(InvalidArgumentException, match="yaw is"):
        quaternion_from_yaw(bad)


def test_matrix_from_euler_refuses_non_finite_angles() -> None:
    with pytest.raises(InvalidArgumentException, match="roll, pitch, yaw"):
        matrix_from_euler(0.0, math.nan, 0.0)


@relaxed
@given(raw_quaternions.filter(_away_from_gimbal_lock), st.tuples(finite, finite, finite))
def test_yaw_from_matrix_equals_yaw_from_quaternion(
    q: tuple[float, float, float, float], t: tuple[float, float, float]
) -> None:
    transform = translation_quaternion_to_matrix(t, q)
    assert _wrapped_diff(yaw_from_matrix(transform), yaw_from_quaternion(q)) < 1e-9
    assert yaw_from_matrix(transform[:3, :3]) == yaw_from_matrix(transform)


def test_yaw_from_matrix_refuses_bad_input() -> None:
    with pytest.raises(InvalidArgumentException, match="shape"):
        yaw_from_matrix(np.eye(2))
    bad = np.eye(3)
    bad[1, 0] = math.nan
    with pytest.raises(InvalidArgumentException, match="finite"):
        yaw_from_matrix(bad)


anything = st.one_of(
    st.lists(st.floats(), max_size=6),
    st.floats(),
    st.text(max_size=4),
    st.none(),
    st.lists(st.lists(st.floats(), max_size=5), max_size=5),
)


@relaxed
@given(anything)
def test_only_visnav_errors_escape(value: object) -> None:
    for fn in (yaw_from_quaternion, yaw_from_matrix):
        try:
            result = fn(value)  # type: ignore[arg-type]
        except InvalidArgumentException:
            continue
        assert math.isfinite(result)
