"""robot_state_publisher as a node: static TF once, /tf per JointState, robot_description."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from visnav.description.robots import resolve_robot
from visnav.description.urdf import RobotDescriptionError
from visnav.graph import Context, Node
from visnav.graph.qos import qos_profile_latched
from visnav.msgs import String, TFMessage
from visnav.tf.robot_state import joint_state_message
from visnav.tf.robot_state_node import (
    RobotStatePublisherNode,
    RobotStatePublisherNodeError,
    kinematics_only,
)

LATCHED = qos_profile_latched


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as context:
        yield context


def test_static_and_dynamic_transforms(ctx: Context) -> None:
    xml = resolve_robot("car").xml
    RobotStatePublisherNode(
        context=ctx, namespace="/car", parameter_overrides={"robot_description": xml,
                                                            "frame_prefix": "car/"}
    )  # fmt: skip
    probe = Node("probe", context=ctx)
    static: list[TFMessage] = []
    dynamic: list[TFMessage] = []
    described: list[String] = []
    probe.create_subscription(TFMessage, "/tf_static", static.append, LATCHED)
    probe.create_subscription(TFMessage, "/tf", dynamic.append, 10)
    probe.create_subscription(String, "/car/robot_description", described.append, LATCHED)
    joints = probe.create_publisher(type(joint_state_message([], [])), "/car/joint_states", 10)
    joints.publish(joint_state_message(["left_wheel_joint"], [0.5], stamp_ns=123))
    ctx.spin_some()
    assert described[0].data == xml
    edges = {(t.header.frame_id, t.child_frame_id) for t in static[-1].transforms}
    assert ("car/base_footprint", "car/base_link") in edges
    assert ("car/camera_link", "car/camera_optical_frame") in edges
    (moving,) = dynamic[0].transforms
    assert (moving.header.frame_id, moving.child_frame_id) == ("car/base_link", "car/left_wheel")
    assert moving.header.stamp.nanosec == 123


def test_meshes_are_not_needed_and_errors_are_clear(ctx: Context) -> None:
    text = """<robot name="m"><link name="a"><visual><geometry><mesh filename="nowhere.stl"/>
      </geometry></visual></link><link name="b"/><joint name="j" type="fixed">
      <parent link="a"/><child link="b"/></joint></robot>"""
    assert "nowhere" not in kinematics_only(text)
    RobotStatePublisherNode("rsp1", context=ctx, parameter_overrides={"robot_description": text})
    with pytest.raises(RobotStatePublisherNodeError, match="robot_description is empty"):
        RobotStatePublisherNode("rsp2", context=ctx)
    with pytest.raises(RobotDescriptionError, match="robot_description"):
        RobotStatePublisherNode(
            "rsp3", context=ctx, parameter_overrides={"robot_description": "<robot"}
        )
    assert [n.get_name() for n in ctx.nodes] == ["rsp1"]
