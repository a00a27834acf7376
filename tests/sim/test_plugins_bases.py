"""``libgazebo_ros_skid_steer_drive.so`` and ``libgazebo_ros_planar_move.so`` against their
gazebo_ros semantics: topics, frames, rates in sim time, odometry and how ``cmd_vel`` moves
the robot."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from visnav.graph import Context, Node
from visnav.msgs import Odometry, TFMessage, Twist, Vector3
from visnav.sim.bases import PlanarMovePlugin, SkidSteerPlugin
from visnav.sim.errors import SimulatorError
from visnav.sim.simulator import RobotSpawn, Simulator

INERTIA = '<inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/>'
WHEEL_INERTIA = '<inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/>'


def stamp_ns(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def yaw_of(q: Any) -> float:
    return float(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_euler("xyz")[2])


class Recorder:
    def __init__(self, ctx: Context, topics: dict[str, type[Any]], cmd: str = "/cmd_vel") -> None:
        self.node = Node("bases_recorder", context=ctx)
        self.messages: dict[str, list[Any]] = defaultdict(list)
        for topic, msg_type in topics.items():
            self.node.create_subscription(msg_type, topic, self._keep(topic), 100_000)
        self._cmd = self.node.create_publisher(Twist, cmd, 1)

    def _keep(self, topic: str) -> Callable[[Any], None]:
        return self.messages[topic].append

    def drive(self, x: float, y: float, yaw_rate: float) -> None:
        self._cmd.publish(
            Twist(linear=Vector3(x=x, y=y, z=0.0), angular=Vector3(x=0.0, y=0.0, z=yaw_rate))
        )

    def tf_pairs(self) -> set[tuple[str, str]]:
        return {
            (t.header.frame_id, t.child_frame_id)
            for msg in self.messages["/tf"]
            for t in msg.transforms
        }


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as context:
        yield context


def _wheel(name: str, x: float, y: float) -> str:
    return f"""
  <link name="{name}"><inertial><mass value="0.5"/>{WHEEL_INERTIA}</inertial>
    <collision><origin rpy="1.5708 0 0"/>
      <geometry><cylinder radius="0.08" length="0.05"/></geometry></collision></link>
  <joint name="{name}_joint" type="continuous"><parent link="base_link"/><child link="{name}"/>
    <origin xyz="{x} {y} 0"/><axis xyz="0 1 0"/></joint>"""


def skid_steer(plugin: str) -> RobotSpawn:
    text = f"""<?xml version="1.0"?>
<robot name="skid">
  <link name="base_footprint"/>
  <link name="base_link"><inertial><mass value="10"/>{INERTIA}</inertial>
    <collision><origin xyz="0 0 0.05"/><geometry><box size="0.5 0.3 0.1"/></geometry></collision>
  </link>
  <joint name="base_joint" type="fixed"><parent link="base_footprint"/><child link="base_link"/>
    <origin xyz="0 0 0.08"/></joint>
  {_wheel("front_left", 0.2, 0.22)}{_wheel("front_right", 0.2, -0.22)}
  {_wheel("rear_left", -0.2, 0.22)}{_wheel("rear_right", -0.2, -0.22)}
  <gazebo><plugin name="skid_steer" filename="libgazebo_ros_skid_steer_drive.so">
    <leftFrontJoint>front_left_joint</leftFrontJoint>
    <rightFrontJoint>front_right_joint</rightFrontJoint>
    <leftRearJoint>rear_left_joint</leftRearJoint><rightRearJoint>rear_right_joint</rightRearJoint>
    <wheelSeparation>0.44</wheelSeparation><wheelDiameter>0.16</wheelDiameter>
    <torque>20</torque>{plugin}</plugin></gazebo>
</robot>"""
    return RobotSpawn(source=text)


def floating_box(plugin: str, *, fixed: bool = False) -> RobotSpawn:
    anchor = (
        '<link name="world"/><joint name="anchor" type="fixed"><parent link="world"/>'
        '<child link="base_footprint"/></joint>'
        if fixed
        else ""
    )
    text = f"""<?xml version="1.0"?>
<robot name="mover">{anchor}
  <link name="base_footprint"><inertial><mass value="5"/>{INERTIA}</inertial>
    <collision><origin xyz="0 0 0.1"/><geometry><box size="0.4 0.3 0.2"/></geometry></collision>
  </link>
  <gazebo reference="base_footprint"><mu1>0</mu1><mu2>0</mu2></gazebo>
  <gazebo><plugin name="planar" filename="libgazebo_ros_planar_move.so">{plugin}</plugin></gazebo>
</robot>"""
    return RobotSpawn(source=text)


# --------------------------------------------------------------------------- skid steer


def test_skid_steer_drives_four_wheels_and_reports_world_odometry(ctx: Context) -> None:
    rec = Recorder(ctx, {"/odom": Odometry, "/tf": TFMessage})
    with Simulator("empty", [skid_steer("<updateRate>50</updateRate>")], context=ctx) as sim:
        (plugin,) = [p for p in sim.robot().plugins if isinstance(p, SkidSteerPlugin)]
        sim.run(0.2)
        rec.drive(0.4, 0.0, 0.0)
        sim.run(2.0)
        speeds = plugin.controller.wheel_speeds(sim.data)
        body = sim.model.body(f"{sim.robot().name}/base_footprint").id
        truth = np.array(sim.data.xpos[body])
        dt, end = sim.timestep_ns, sim.now_ns
    assert speeds == pytest.approx([0.4] * 4, abs=0.03)  # every wheel at v (rim speed)
    odoms = rec.messages["/odom"]
    odom = odoms[-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_footprint")
    assert odom.pose.pose.position.x == pytest.approx(truth[0], abs=0.01)  # <= 20 ms old
    assert odom.pose.pose.position.x > 0.5
    assert odom.twist.twist.linear.x == pytest.approx(0.4, abs=0.04)
    cov = [0.0001, 0.0001, 1e12, 1e12, 1e12, 0.01]
    assert list(odom.pose.covariance[[0, 7, 14, 21, 28, 35]]) == pytest.approx(cov)
    assert list(odom.twist.covariance[[0, 7, 14, 21, 28, 35]]) == pytest.approx(cov)
    stamps = np.array([stamp_ns(m) for m in odoms])
    assert np.all(np.diff(stamps) == 20_000_000)  # updateRate 50, drift-free
    assert len(stamps) == len(range(20_000_000, end, 20_000_000))
    assert dt == 2_000_000
    assert ("odom", "base_footprint") not in rec.tf_pairs()  # broadcastTF defaults to false


def test_skid_steer_turns_left_on_positive_yaw_rate_and_broadcasts_tf(ctx: Context) -> None:
    rec = Recorder(ctx, {"/odom": Odometry, "/tf": TFMessage}, cmd="/base/cmd")
    spawn = skid_steer("<broadcastTF>true</broadcastTF><commandTopic>/base/cmd</commandTopic>")
    with Simulator("empty", [spawn], context=ctx) as sim:
        (plugin,) = [p for p in sim.robot().plugins if isinstance(p, SkidSteerPlugin)]
        rec.drive(0.0, 0.0, 1.0)
        sim.run(0.1)
        desired = plugin.controller.desired_wheel_speeds()
        sim.run(1.5)
    # both left wheels at -w b / 2, both right wheels at +w b / 2
    assert desired == pytest.approx([-0.22, -0.22, 0.22, 0.22])
    assert yaw_of(rec.messages["/odom"][-1].pose.pose.orientation) > 0.3
    assert ("odom", "base_footprint") in rec.tf_pairs()


# --------------------------------------------------------------------------- planar move


def test_planar_move_ros1_sets_the_planar_velocity_in_the_base_frame(ctx: Context) -> None:
    rec = Recorder(ctx, {"/odom": Odometry, "/tf": TFMessage})
    spawn = replace(floating_box(""), spawn=(0.0, 0.0, 0.0, 0.8))
    with Simulator("empty", [spawn], context=ctx) as sim:
        (plugin,) = [p for p in sim.robot().plugins if isinstance(p, PlanarMovePlugin)]
        sim.run(0.2)
        rec.drive(0.3, 0.2, 0.5)
        sim.run(1.0)
        # what one update writes: the body-frame command rotated by the yaw, no vertical
        # velocity, the yaw rate about the world z (MuJoCo's free joint: body frame)
        dof = sim.model.joint(sim.robot().handles.free_joint).dofadr[0]
        body = sim.model.body(f"{sim.robot().name}/base_footprint").id
        rot = np.array(sim.data.xmat[body]).reshape(3, 3)
        yaw = float(Rotation.from_matrix(rot).as_euler("xyz")[2])
        plugin.control(sim.data, sim.now_ns)
        qvel = np.array(sim.data.qvel[dof : dof + 6])
        dt, end = sim.timestep_ns, sim.now_ns
    c, s = np.cos(yaw), np.sin(yaw)
    assert qvel[:3] == pytest.approx([0.3 * c - 0.2 * s, 0.2 * c + 0.3 * s, 0.0], abs=1e-3)
    assert rot @ qvel[3:] == pytest.approx([0.0, 0.0, 0.5], abs=1e-3)
    assert yaw > 0.8 + 0.5 * 0.8  # it turned (the ground's friction acts within each step)
    odoms = rec.messages["/odom"]
    stamps = np.array([stamp_ns(m) for m in odoms])
    assert np.all(np.diff(stamps) == 50_000_000)  # odometryRate 20 (default)
    assert len(stamps) == len(range(50_000_000, end, 50_000_000))
    odom = odoms[-1]
    assert odom.pose.pose.position.z == 0.0  # ROS 1 writes x and y only
    # twist from the pose change, in the base frame: along the commanded body velocity
    twist = odom.twist.twist
    assert np.arctan2(twist.linear.y, twist.linear.x) == pytest.approx(
        np.arctan2(0.2, 0.3), abs=0.1
    )
    assert 0.8 * 0.5 < twist.angular.z <= 0.5 + 1e-6
    assert not any(odom.twist.covariance)
    assert ("odom", "base_footprint") in rec.tf_pairs()
    assert dt == 2_000_000


def test_planar_move_cmd_timeout_stops_the_model(ctx: Context) -> None:
    rec = Recorder(ctx, {"/odom": Odometry})
    with Simulator("empty", [floating_box("<cmdTimeout>0.3</cmdTimeout>")], context=ctx) as sim:
        (plugin,) = [p for p in sim.robot().plugins if isinstance(p, PlanarMovePlugin)]
        rec.drive(0.5, 0.0, 0.0)
        sim.run(0.2)
        assert plugin.target == (0.5, 0.0, 0.0)
        sim.run(0.5)
        assert plugin.target == (0.0, 0.0, 0.0)
        sim.run(0.3)
    assert abs(rec.messages["/odom"][-1].twist.twist.linear.x) < 0.01


def test_planar_move_ros2_names_rates_and_twist(ctx: Context) -> None:
    plugin = (
        "<ros><namespace>/demo</namespace></ros><update_rate>500</update_rate>"
        "<publish_rate>10</publish_rate><publish_odom_tf>false</publish_odom_tf>"
        "<covariance_x>0.5</covariance_x>"
    )
    rec = Recorder(ctx, {"/demo/odom": Odometry, "/tf": TFMessage}, cmd="/demo/cmd_vel")
    with Simulator("empty", [floating_box(plugin)], context=ctx) as sim:
        rec.drive(0.2, 0.0, 0.0)
        sim.run(1.0)
    odoms = rec.messages["/demo/odom"]
    assert np.all(np.diff([stamp_ns(m) for m in odoms]) == 100_000_000)
    odom = odoms[-1]
    assert 0.8 * 0.2 < odom.twist.twist.linear.x <= 0.2 + 1e-6  # less the ground's friction
    assert odom.pose.covariance[0] == odom.twist.covariance[0] == 0.5
    assert ("odom", "base_footprint") not in rec.tf_pairs()


def test_planar_move_needs_a_floating_model(ctx: Context) -> None:
    with pytest.raises(SimulatorError, match="root link is fixed"):
        Simulator("empty", [floating_box("", fixed=True)], context=ctx)
