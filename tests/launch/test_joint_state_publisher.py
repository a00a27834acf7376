"""joint_state_publisher (and _gui, headless): defaults, zeros, mimic, sources; RSP's throttle."""

from __future__ import annotations

import logging
from collections.abc import Iterator

import pytest

from visnav.description.urdf import parse_urdf
from visnav.graph import Context, Node
from visnav.graph.qos import qos_profile_latched
from visnav.msgs import JointState, String, TFMessage
from visnav.node_registry import resolve_node_class
from visnav.tf.joint_state_publisher import (
    JointStatePublisherError,
    JointStatePublisherNode,
    joint_defaults,
)
from visnav.tf.robot_state import joint_state_message
from visnav.tf.robot_state_node import RobotStatePublisherNode

ROBOT = """<robot name="arm">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="l4"/>
  <link name="l5"/><link name="l6"/>
  <joint name="fixed" type="fixed"><parent link="base"/><child link="l1"/></joint>
  <joint name="wheel" type="continuous"><parent link="base"/><child link="l2"/>
    <axis xyz="0 1 0"/></joint>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="l3"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="lifted" type="revolute"><parent link="base"/><child link="l4"/>
    <limit lower="0.5" upper="1.5" effort="1" velocity="1"/></joint>
  <joint name="slide" type="prismatic"><parent link="base"/><child link="l5"/>
    <limit lower="-0.4" upper="-0.2" effort="1" velocity="1"/></joint>
  <joint name="finger" type="revolute"><parent link="base"/><child link="l6"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
    <mimic joint="shoulder" multiplier="2" offset="0.1"/></joint>
</robot>"""


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as context:
        yield context


def test_defaults_are_joint_state_publishers() -> None:
    urdf = parse_urdf(ROBOT)
    d = joint_defaults(urdf)
    assert d.names == ("wheel", "shoulder", "lifted", "slide", "finger")  # no fixed joint
    # 0, or the middle of limits that do not contain 0
    assert d.positions == pytest.approx(
        {"wheel": 0.0, "shoulder": 0.0, "lifted": 1.0, "slide": -0.3}
    )
    assert d.resolve({"shoulder": 0.5})["finger"] == pytest.approx(1.1)  # 2 * 0.5 + 0.1
    free = joint_defaults(urdf, zeros={"wheel": 3.0}, use_mimic_tags=False)
    assert free.positions["wheel"] == 3.0
    assert free.positions["finger"] == 0.0
    with pytest.raises(JointStatePublisherError, match=r"zeros\.whel: robot 'arm' has no free"):
        joint_defaults(urdf, zeros={"whel": 1.0})


def _collect(ctx: Context, topic: str = "/joint_states") -> list[JointState]:
    got: list[JointState] = []
    Node("probe", context=ctx).create_subscription(JointState, topic, got.append, 10)
    return got


def test_node_publishes_at_its_rate_with_zeros_and_sources(ctx: Context) -> None:
    got = _collect(ctx)
    source = Node("driver", context=ctx).create_publisher(JointState, "/wheels", 10)
    node = resolve_node_class("joint_state_publisher")(
        context=ctx,
        parameter_overrides={
            "robot_description": ROBOT,
            "rate": 50,  # roslaunch gives an int
            "source_list": ["/wheels"],
            "zeros.shoulder": 0.25,
        },
    )
    assert isinstance(node, JointStatePublisherNode)
    assert ctx.spin_until(lambda: len(got) >= 2, timeout_s=5.0)
    msg = got[-1]
    assert list(msg.name) == ["wheel", "shoulder", "lifted", "slide", "finger"]
    assert list(msg.position) == pytest.approx([0.0, 0.25, 1.0, -0.3, 0.6])
    assert len(msg.velocity) == 0
    assert len(msg.effort) == 0
    source.publish(joint_state_message(["wheel"], [1.5]))
    assert ctx.spin_until(lambda: got[-1].position[0] == 1.5, timeout_s=5.0)
    assert node.parameters["zeros.shoulder"] == 0.25


def test_gui_runs_headless_with_one_line_and_waits_for_the_topic(
    ctx: Context, caplog: pytest.LogCaptureFixture
) -> None:
    got = _collect(ctx)
    caplog.set_level(logging.INFO)
    resolve_node_class("joint_state_publisher_gui")(
        context=ctx, parameter_overrides={"rate": 100.0}
    )
    gui_lines = [r for r in caplog.records if "no slider window" in r.getMessage()]
    assert len(gui_lines) == 1
    ctx.spin_until(lambda: False, timeout_s=0.1)
    assert got == []  # no robot yet: nothing to publish
    latched = Node("rsp", context=ctx).create_publisher(
        String, "/robot_description", qos_profile_latched
    )
    latched.publish(String(data=ROBOT))
    assert ctx.spin_until(lambda: len(got) >= 1, timeout_s=5.0)
    assert "lifted" in list(got[-1].name)


def test_use_gui_and_default_arrays(ctx: Context, caplog: pytest.LogCaptureFixture) -> None:
    got = _collect(ctx)
    caplog.set_level(logging.INFO)
    JointStatePublisherNode(
        context=ctx,
        parameter_overrides={
            "robot_description": ROBOT,
            "use_gui": True,
            "publish_default_velocities": True,
            "publish_default_efforts": True,
        },
    )
    assert any("no slider window" in r.getMessage() for r in caplog.records)
    assert ctx.spin_until(lambda: len(got) >= 1, timeout_s=5.0)
    assert list(got[-1].velocity) == [0.0] * 5
    assert list(got[-1].effort) == [0.0] * 5


def test_robot_state_publisher_throttles_per_joint(ctx: Context) -> None:
    tf: list[TFMessage] = []
    Node("tf_probe", context=ctx).create_subscription(TFMessage, "/tf", tf.append, 100)
    joints = Node("js", context=ctx).create_publisher(JointState, "/joint_states", 100)
    RobotStatePublisherNode(
        context=ctx,
        parameter_overrides={"robot_description": ROBOT, "publish_frequency": 10.0},
    )
    for i in range(10):  # 100 Hz of stamps for 0.1 s: one publish at 10 Hz
        joints.publish(joint_state_message(["wheel"], [0.1 * i], stamp_ns=10_000_000 * i))
        ctx.spin_some()
    assert len(tf) == 1
    joints.publish(joint_state_message(["wheel"], [1.0], stamp_ns=100_000_000))
    joints.publish(joint_state_message(["shoulder"], [1.0], stamp_ns=100_000_001))  # new joint
    joints.publish(joint_state_message(["wheel"], [1.0], stamp_ns=5))  # time went backwards
    ctx.spin_some()
    assert len(tf) == 4
