"""Rates as gazebo_ros: a plugin's ``updateRate`` throttles publishing below the sensor's
``<update_rate>``; nothing renders or publishes more often than due (sim time)."""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.msgs import CameraInfo, Image, Imu, JointState, Odometry
from visnav.sim.simulator import RobotSpawn, Simulator

TB3 = Path(__file__).resolve().parent.parent / "data" / "turtlebot3" / "turtlebot3_description"
INERTIA = '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'


def stamp_ns(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


class Recorder:
    def __init__(self, ctx: Context, topics: dict[str, type[Any]]) -> None:
        self.node = Node("rate_recorder", context=ctx)
        self.messages: dict[str, list[Any]] = defaultdict(list)
        for topic, msg_type in topics.items():
            self.node.create_subscription(msg_type, topic, self._keep(topic), 10_000)

    def _keep(self, topic: str) -> Callable[[Any], None]:
        return self.messages[topic].append


@pytest.fixture
def ctx(mujoco_gl: str) -> Iterator[Context]:
    del mujoco_gl
    with Context(transport="local") as context:
        yield context


def tb3(model: str) -> RobotSpawn:
    return RobotSpawn(
        source=TB3 / "urdf" / f"turtlebot3_{model}.urdf.xacro",
        packages={"turtlebot3_description": TB3},
    )


def due_grid(rate_hz: float, dt_ns: int, end_ns: int, *, first: int = 0) -> list[int]:
    """The first physics step at or after each ``k / rate`` (k >= first) before ``end_ns``."""
    out = []
    k = first
    while True:
        target = round(k * 1e9 / rate_hz)
        step = math.ceil(target / dt_ns) * dt_ns
        if step >= end_ns:
            return out
        out.append(step)
        k += 1


def robot(body: str) -> str:
    return f"""<?xml version="1.0"?>
<robot name="bot">
  <link name="base_link"><inertial><mass value="2"/>{INERTIA}</inertial>
    <collision><geometry><box size="0.3 0.3 0.1"/></geometry></collision></link>
  <link name="cam_link"/>
  <joint name="cam_joint" type="fixed"><parent link="base_link"/><child link="cam_link"/>
    <origin xyz="0.1 0 0.1"/></joint>
  <link name="arm"><inertial><mass value="0.1"/>{INERTIA}</inertial></link>
  <joint name="arm_joint" type="revolute"><parent link="base_link"/><child link="arm"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  {body}
</robot>"""


def test_waffle_pi_camera_renders_at_its_plugin_update_rate(ctx: Context) -> None:
    # the sensor has no <update_rate> (every step); its ROS 1 plugin says <updateRate>30
    rec = Recorder(ctx, {"/camera/rgb/image_raw": Image, "/camera/rgb/camera_info": CameraInfo})
    with Simulator("empty", [tb3("waffle_pi")], context=ctx) as sim:
        stats = sim.run(1.0)
        dt, end = sim.timestep_ns, sim.now_ns
    images = rec.messages["/camera/rgb/image_raw"]
    infos = rec.messages["/camera/rgb/camera_info"]
    expected = due_grid(30.0, dt, end)
    assert [stamp_ns(m) for m in images] == expected
    assert [stamp_ns(m) for m in infos] == expected
    assert stats.frames == len(expected)  # nothing rendered that was not published
    image, info = images[-1], infos[-1]
    assert (image.width, image.height, image.encoding) == (640, 480, "rgb8")
    assert image.header.frame_id == info.header.frame_id == "camera_rgb_optical_frame"
    focal = 320.0 / math.tan(1.085595 / 2.0)
    assert info.k[0] == pytest.approx(focal)
    assert info.k[4] == pytest.approx(focal)
    assert info.p[3] == pytest.approx(-focal * 0.07)  # hackBaseline 0.07


@pytest.mark.parametrize(("sensor_hz", "plugin_hz", "frames"), [(30, 20, 20), (20, 30, 20)])
def test_camera_publishes_when_sensor_and_plugin_are_both_due(
    ctx: Context, sensor_hz: float, plugin_hz: float, frames: int
) -> None:
    camera = f"""<gazebo reference="cam_link"><sensor type="camera" name="cam">
      <update_rate>{sensor_hz}</update_rate>
      <camera><horizontal_fov>1.0</horizontal_fov><image><width>32</width><height>24</height>
      </image></camera>
      <plugin name="cam_plugin" filename="libgazebo_ros_camera.so">
        <cameraName>cam</cameraName><frameName>cam_link</frameName>
        <updateRate>{plugin_hz}</updateRate></plugin></sensor></gazebo>"""
    rec = Recorder(ctx, {"/cam/image_raw": Image})
    with Simulator("empty", [RobotSpawn(source=robot(camera))], context=ctx) as sim:
        stats = sim.run(1.0)
        dt = sim.timestep_ns
    stamps = np.array([stamp_ns(m) for m in rec.messages["/cam/image_raw"]])
    assert len(stamps) == frames == stats.frames
    sensor_steps = set(due_grid(sensor_hz, dt, 1_000_000_000))
    assert set(stamps.tolist()) <= sensor_steps  # only frames the sensor made
    assert np.diff(stamps).min() >= 1e9 / max(sensor_hz, plugin_hz) - dt


def test_burger_odometry_joint_states_and_imu_rates(ctx: Context) -> None:
    rec = Recorder(ctx, {"/odom": Odometry, "/joint_states": JointState, "/imu": Imu})
    with Simulator("empty", [tb3("burger")], context=ctx) as sim:
        sim.run(1.0)
        dt, end = sim.timestep_ns, sim.now_ns
    # diff drive <updateRate>30: odometry and wheel joint states one period in, drift-free
    odom = [stamp_ns(m) for m in rec.messages["/odom"]]
    assert odom == due_grid(30.0, dt, end, first=1)
    assert [stamp_ns(m) for m in rec.messages["/joint_states"]] == odom
    # gazebo_ros_imu <updateRate>0: every world update
    imu = [stamp_ns(m) for m in rec.messages["/imu"]]
    assert imu == list(range(0, end, dt))


def test_ros1_imu_and_joint_state_publisher_update_rates(ctx: Context) -> None:
    body = """<gazebo>
      <plugin name="imu" filename="libgazebo_ros_imu.so"><bodyName>base_link</bodyName>
        <topicName>imu</topicName><updateRate>100</updateRate></plugin>
      <plugin name="jsp" filename="libgazebo_ros_joint_state_publisher.so">
        <jointName>arm_joint</jointName><updateRate>40</updateRate></plugin></gazebo>"""
    rec = Recorder(ctx, {"/imu": Imu, "/joint_states": JointState})
    with Simulator("empty", [RobotSpawn(source=robot(body))], context=ctx) as sim:
        sim.run(0.5)
        dt, end = sim.timestep_ns, sim.now_ns
    assert [stamp_ns(m) for m in rec.messages["/imu"]] == due_grid(100.0, dt, end)
    states = rec.messages["/joint_states"]
    assert [stamp_ns(m) for m in states] == due_grid(40.0, dt, end)
    assert list(states[-1].name) == ["arm_joint"]


def test_unsubscribed_camera_renders_nothing(ctx: Context) -> None:
    with Simulator("empty", [tb3("waffle_pi")], context=ctx) as sim:
        stats = sim.run(0.5)
    assert stats.frames == 0
