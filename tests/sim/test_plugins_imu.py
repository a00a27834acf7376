"""``libgazebo_ros_imu.so`` (the ROS 1 model plugin TurtleBot3 uses) against its semantics:
world orientation with ``rpyOffset``, rates and the differentiated velocity (no gravity) in
the link frame, ``gaussianNoise`` on every axis, messages only while subscribed."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from visnav.graph import Context, Node
from visnav.msgs import Imu, Twist, Vector3
from visnav.sim.imu_model import ImuModelPlugin
from visnav.sim.simulator import RobotSpawn, Simulator

TB3 = Path(__file__).resolve().parent.parent / "data" / "turtlebot3" / "turtlebot3_description"
INERTIA = '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as context:
        yield context


def burger(yaw: float = 0.0) -> RobotSpawn:
    return RobotSpawn(
        source=TB3 / "urdf" / "turtlebot3_burger.urdf.xacro",
        packages={"turtlebot3_description": TB3},
        spawn=(0.0, 0.0, 0.0, yaw),
    )


def box(plugin: str) -> RobotSpawn:
    text = f"""<?xml version="1.0"?>
<robot name="box">
  <link name="base_link"><inertial><mass value="2"/>{INERTIA}</inertial>
    <collision><geometry><box size="0.3 0.3 0.1"/></geometry></collision></link>
  <gazebo><plugin name="imu" filename="libgazebo_ros_imu.so">{plugin}</plugin></gazebo>
</robot>"""
    return RobotSpawn(source=text)


def listen(ctx: Context, topic: str = "/imu") -> list[Any]:
    out: list[Any] = []
    Node("imu_listener", context=ctx).create_subscription(Imu, topic, out.append, 100_000)
    return out


def cmd_vel(ctx: Context, linear: float, angular: float) -> None:
    pub = Node("imu_driver", context=ctx).create_publisher(Twist, "/cmd_vel", 1)
    pub.publish(
        Twist(linear=Vector3(x=linear, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=angular))
    )


def yaw_of(msg: Any) -> float:
    q = msg.orientation
    return float(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_euler("xyz")[2])


def vec(v: Any) -> np.ndarray:
    return np.array([v.x, v.y, v.z])


def test_burger_at_rest_reads_no_gravity(ctx: Context) -> None:
    msgs = listen(ctx)
    with Simulator("empty", [burger(yaw=1.0)], context=ctx) as sim:
        sim.run(1.0)
    last = msgs[-1]
    assert last.header.frame_id == "imu_link"
    assert yaw_of(last) == pytest.approx(1.0, abs=0.01)
    # the plugin differentiates the link velocity: a robot at rest reads ~0, not +9.81 up
    settled = np.array([vec(m.linear_acceleration) for m in msgs[-100:]])
    assert np.abs(settled).max() < 0.5
    assert np.abs(vec(last.angular_velocity)).max() < 0.05
    assert not any(last.orientation_covariance)  # gaussianNoise 0


def test_forward_acceleration_and_yaw_rate_in_link_frame(ctx: Context) -> None:
    msgs = listen(ctx)
    with Simulator("empty", [burger(yaw=2.0)], context=ctx) as sim:
        sim.run(0.3)
        start = len(msgs)
        cmd_vel(ctx, 0.2, 0.0)
        sim.run(0.15)
        forward = len(msgs)
        cmd_vel(ctx, 0.0, 1.0)
        sim.run(1.5)
    # accelerating forward (wheelAcceleration 1 m/s^2) reads +x in the link frame whatever
    # the heading: the vector is rotated into the link, not by the orientation
    accel = np.array([vec(m.linear_acceleration) for m in msgs[start + 5 : forward]])
    assert np.median(accel[:, 0]) > 0.3
    assert abs(np.median(accel[:, 1])) < 0.1
    rates = np.array([vec(m.angular_velocity) for m in msgs[-100:]])
    assert np.median(rates[:, 2]) == pytest.approx(1.0, abs=0.1)  # body z = world z


def test_gaussian_noise_rate_and_covariance(ctx: Context) -> None:
    msgs = listen(ctx, "/r/imu")
    spawn = box(
        "<robotNamespace>r</robotNamespace><bodyName>base_link</bodyName><topicName>imu</topicName>"
        "<gaussianNoise>0.1</gaussianNoise><updateRate>100</updateRate>"
    )
    with Simulator("empty", [spawn], context=ctx, seed=3) as sim:
        sim.run(3.0)
    assert len(msgs) == 300
    gyro = np.array([vec(m.angular_velocity) for m in msgs[50:]])
    assert gyro.std(axis=0) == pytest.approx([0.1, 0.1, 0.1], rel=0.2)
    assert abs(gyro.mean()) < 0.02
    for cov in (
        msgs[-1].orientation_covariance,
        msgs[-1].angular_velocity_covariance,
        msgs[-1].linear_acceleration_covariance,
    ):
        assert list(cov) == pytest.approx([0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.01])
    q = msgs[-1].orientation  # the orientation itself is not noised by gazebo_ros_imu
    assert abs(q.w) == pytest.approx(1.0, abs=1e-3)


def test_rpy_offset_rotates_the_reported_orientation(ctx: Context) -> None:
    msgs = listen(ctx)
    spawn = box(
        "<bodyName>base_link</bodyName><topicName>imu</topicName><rpyOffset>0 0 0.5</rpyOffset>"
    )
    with Simulator("empty", [spawn], context=ctx) as sim:
        sim.run(0.2)
    assert yaw_of(msgs[-1]) == pytest.approx(0.5, abs=1e-3)
    assert msgs[-1].header.frame_id == "base_link"  # frameName defaults to bodyName


def test_nothing_is_computed_without_a_subscriber(ctx: Context) -> None:
    with Simulator("empty", [burger()], context=ctx) as sim:
        sim.run(0.2)
        (plugin,) = [p for p in sim.robot().plugins if isinstance(p, ImuModelPlugin)]
        assert plugin.samples == 0
        msgs = listen(ctx)
        sim.run(0.1)
        assert plugin.samples == len(msgs) == 50
    # the first message after subscribing reads no acceleration (no previous velocity)
    assert not any(vec(msgs[0].linear_acceleration))
    assert math.isfinite(msgs[-1].linear_acceleration.z)
