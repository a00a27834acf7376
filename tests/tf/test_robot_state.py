"""robot_state_publisher's algorithm: static and dynamic transforms from URDF + JointState."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.description.rigid import quat_xyzw_to_matrix, rpy_to_matrix
from visnav.description.urdf import parse_urdf
from visnav.msgs.time import time_to_ns
from visnav.msgs.types import TransformStamped
from visnav.tf.robot_state import (
    RobotStateError,
    RobotStateModel,
    dynamic_transforms,
    joint_state_message,
    static_transforms,
)

INERTIA = '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'
URDF = parse_urdf(
    f"""<robot name="arm">
  <link name="base"/>
  <link name="upper"><inertial><mass value="1"/>{INERTIA}</inertial></link>
  <link name="slider"><inertial><mass value="1"/>{INERTIA}</inertial></link>
  <link name="wheel"><inertial><mass value="1"/>{INERTIA}</inertial></link>
  <link name="finger"><inertial><mass value="1"/>{INERTIA}</inertial></link>
  <link name="camera_link"/>
  <link name="camera_optical"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.5" rpy="0 0 0.3"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="upper"/><child link="slider"/>
    <origin xyz="0.2 0 0"/><axis xyz="1 1 0"/><limit lower="0" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="spin" type="continuous"><parent link="base"/><child link="wheel"/>
    <origin xyz="0 0.3 0"/><axis xyz="0 0 1"/></joint>
  <joint name="grip" type="revolute"><parent link="slider"/><child link="finger"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
    <mimic joint="shoulder" multiplier="-0.5" offset="0.1"/></joint>
  <joint name="camera_joint" type="fixed"><parent link="upper"/><child link="camera_link"/>
    <origin xyz="0.1 0 0.05" rpy="0 0.2 0"/></joint>
  <joint name="optical_joint" type="fixed"><parent link="camera_link"/>
    <child link="camera_optical"/><origin rpy="-1.5707963267948966 0 -1.5707963267948966"/>
  </joint>
</robot>"""
)


def matrix(t: TransformStamped) -> np.ndarray:
    out = np.eye(4)
    r = t.transform.rotation
    out[:3, :3] = quat_xyzw_to_matrix((r.x, r.y, r.z, r.w))
    v = t.transform.translation
    out[:3, 3] = (v.x, v.y, v.z)
    return out


def by_child(transforms: list[TransformStamped]) -> dict[str, TransformStamped]:
    return {t.child_frame_id: t for t in transforms}


def test_static_transforms_of_fixed_joints() -> None:
    out = by_child(static_transforms(URDF, stamp_ns=5_000_000_001))
    assert set(out) == {"camera_link", "camera_optical"}
    cam = out["camera_link"]
    assert cam.header.frame_id == "upper"
    assert time_to_ns(cam.header.stamp) == 5_000_000_001
    np.testing.assert_allclose(matrix(cam)[:3, 3], [0.1, 0, 0.05])
    np.testing.assert_allclose(matrix(cam)[:3, :3], rpy_to_matrix((0, 0.2, 0)), atol=1e-12)
    optical = matrix(out["camera_optical"])[:3, :3]
    # Optical frame: z forward (= camera x), x right (= camera -y), y down (= camera -z).
    np.testing.assert_allclose(optical, [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], atol=1e-12)


def test_dynamic_transforms_follow_joint_states() -> None:
    msg = joint_state_message(
        ["shoulder", "slide", "spin", "not_a_joint", "camera_joint"],
        [0.4, 0.25, math.pi, 9.0, 1.0],
        stamp_ns=7_000,
    )
    out = by_child(dynamic_transforms(URDF, msg))
    # fixed / unknown names ignored; the mimic joint follows its master
    assert set(out) == {"upper", "slider", "wheel", "finger"}
    assert all(time_to_ns(t.header.stamp) == 7_000 for t in out.values())
    upper = matrix(out["upper"])
    expected = rpy_to_matrix((0, 0, 0.3)) @ rpy_to_matrix((0, 0.4, 0))
    np.testing.assert_allclose(upper[:3, :3], expected, atol=1e-12)
    np.testing.assert_allclose(upper[:3, 3], [0, 0, 0.5])
    slider = matrix(out["slider"])
    np.testing.assert_allclose(slider[:3, 3], [0.2 + 0.25 / math.sqrt(2), 0.25 / math.sqrt(2), 0])
    np.testing.assert_allclose(slider[:3, :3], np.eye(3), atol=1e-12)
    wheel = matrix(out["wheel"])
    np.testing.assert_allclose(wheel[:3, :3], rpy_to_matrix((0, 0, math.pi)), atol=1e-12)
    finger = matrix(out["finger"])
    np.testing.assert_allclose(finger[:3, :3], rpy_to_matrix((0, 0, -0.5 * 0.4 + 0.1)), atol=1e-12)
    assert out["finger"].header.frame_id == "slider"


def test_mimic_given_explicitly_wins_and_prefix_applies() -> None:
    model = RobotStateModel(URDF, frame_prefix="r1/")
    msg = joint_state_message(["shoulder", "grip"], [0.4, -0.7], stamp_ns=1)
    assert model.joint_positions(msg) == {"shoulder": 0.4, "grip": -0.7}
    out = by_child(model.dynamic_transforms(msg, stamp_ns=99))
    assert set(out) == {"r1/upper", "r1/finger"}
    assert out["r1/upper"].header.frame_id == "r1/base"
    assert time_to_ns(out["r1/upper"].header.stamp) == 99
    assert {t.child_frame_id for t in model.static_transforms()} == {
        "r1/camera_link",
        "r1/camera_optical",
    }


def test_bad_joint_states_are_clear_errors() -> None:
    msg = joint_state_message(["shoulder", "slide"], [0.1], stamp_ns=0)
    with pytest.raises(RobotStateError, match="2 names but 1 positions"):
        dynamic_transforms(URDF, msg)
    msg = joint_state_message(["shoulder"], [math.nan])
    with pytest.raises(RobotStateError, match="'shoulder' is nan"):
        dynamic_transforms(URDF, msg)
    with pytest.raises(RobotStateError, match="not a revolute, continuous or prismatic"):
        RobotStateModel(URDF).joint_transform("camera_joint", 0.0)


@settings(max_examples=100, deadline=None)
@given(st.floats(-10, 10, allow_nan=False), st.floats(-2, 2, allow_nan=False))
def test_joint_transforms_are_rigid_and_keep_the_axis(angle: float, offset: float) -> None:
    model = RobotStateModel(URDF)
    t = model.joint_transform("shoulder", angle)
    origin = URDF.joints["shoulder"].origin.matrix()
    motion = np.linalg.inv(origin) @ t
    rot = motion[:3, :3]
    np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(rot @ np.array([0, 1, 0]), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(motion[:3, 3], 0, atol=1e-12)
    assert rot[0, 2] == pytest.approx(math.sin(angle), abs=1e-12)
    assert rot[0, 0] == pytest.approx(math.cos(angle), abs=1e-12)
    slide = np.linalg.inv(URDF.joints["slide"].origin.matrix()) @ model.joint_transform(
        "slide", offset
    )
    assert np.linalg.norm(slide[:3, 3]) == pytest.approx(abs(offset))
