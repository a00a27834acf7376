"""``libgazebo_ros_diff_drive.so`` as ROS 1 defines it, on ROBOTIS' TurtleBot3 burger:
``/cmd_vel`` drives it, ``/odom`` and ``odom -> base_footprint``, ``publishWheelJointState``
feeds robot_state_publisher (wheel frames on ``/tf``), ``publishWheelTF``, ``legacyMode``."""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from visnav.description.robot import expand_xacro
from visnav.graph import Context, Node
from visnav.msgs import JointState, Odometry, TFMessage, Twist, Vector3
from visnav.sim.simulator import RobotSpawn, Simulator

TB3 = Path(__file__).resolve().parent.parent / "data" / "turtlebot3" / "turtlebot3_description"
PACKAGES = {"turtlebot3_description": TB3}
WHEEL_RADIUS = 0.033


class Recorder:
    def __init__(self, ctx: Context, topics: dict[str, type[Any]]) -> None:
        self.node = Node("dd_recorder", context=ctx)
        self.messages: dict[str, list[Any]] = defaultdict(list)
        for topic, msg_type in topics.items():
            self.node.create_subscription(msg_type, topic, self._keep(topic), 100_000)
        self._cmd = self.node.create_publisher(Twist, "/cmd_vel", 1)

    def _keep(self, topic: str) -> Callable[[Any], None]:
        return self.messages[topic].append

    def drive(self, linear: float, angular: float) -> None:
        self._cmd.publish(
            Twist(linear=Vector3(x=linear, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=angular))
        )

    def transforms(self) -> list[Any]:
        return [t for msg in self.messages["/tf"] for t in msg.transforms]


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as context:
        yield context


def burger(**replace: str) -> RobotSpawn:
    """The burger as ROBOTIS wrote it, with some ``<tag>value</tag>`` of its diff drive changed."""
    path = TB3 / "urdf" / "turtlebot3_burger.urdf.xacro"
    if not replace:
        return RobotSpawn(source=path, packages=PACKAGES)
    text = expand_xacro(path, packages=PACKAGES)
    for tag, value in replace.items():
        before = f"<{tag}>"
        start = text.index(before)
        end = text.index(f"</{tag}>", start)
        text = text[: start + len(before)] + value + text[end:]
    return RobotSpawn(source=text, packages=PACKAGES)


def yaw_of(q: Any) -> float:
    return float(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_euler("xyz")[2])


def test_burger_drives_on_cmd_vel_with_odom_joint_states_and_wheel_frames(ctx: Context) -> None:
    rec = Recorder(ctx, {"/odom": Odometry, "/joint_states": JointState, "/tf": TFMessage})
    with Simulator("empty", [burger()], context=ctx) as sim:
        sim.run(0.2)
        rec.drive(0.2, 0.0)
        sim.run(2.0)
        body = sim.model.body(f"{sim.robot().name}/base_footprint").id
        truth = np.array(sim.data.xpos[body])
    odom = rec.messages["/odom"][-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_footprint")
    p = odom.pose.pose.position
    assert p.x == pytest.approx(truth[0], abs=0.01)  # odometrySource world: the true pose
    assert p.x == pytest.approx(0.2 * 2.0 - 0.02, abs=0.06)  # ramp at wheelAcceleration 1
    assert odom.twist.twist.linear.x == pytest.approx(0.2, abs=0.02)
    assert list(odom.pose.covariance[[0, 7, 35]]) == pytest.approx([1e-5, 1e-5, 1e-3])
    states = rec.messages["/joint_states"][-1]
    assert list(states.name) == ["wheel_right_joint", "wheel_left_joint"]  # ROS 1's order
    assert len(states.velocity) == len(states.effort) == 0  # positions only
    travelled = np.asarray(states.position) * WHEEL_RADIUS
    assert travelled == pytest.approx([p.x, p.x], abs=0.03)
    pairs = {(t.header.frame_id, t.child_frame_id) for t in rec.transforms()}
    assert ("odom", "base_footprint") in pairs
    # robot_state_publisher turns the wheel joint states into the wheel frames
    assert {("base_link", "wheel_left_link"), ("base_link", "wheel_right_link")} <= pairs


def test_positive_angular_z_turns_left_and_legacy_mode_turns_right(ctx: Context) -> None:
    yaws = {}
    for legacy in ("false", "true"):
        with Context(transport="local") as local:
            rec = Recorder(local, {"/odom": Odometry})
            with Simulator("empty", [burger(legacyMode=legacy)], context=local) as sim:
                rec.drive(0.0, 1.0)
                sim.run(1.0)
            yaws[legacy] = yaw_of(rec.messages["/odom"][-1].pose.pose.orientation)
    assert yaws["false"] > 0.5
    assert yaws["true"] < -0.5


def test_publish_wheel_tf_and_no_odometry_without_publish_tf(ctx: Context) -> None:
    rec = Recorder(ctx, {"/odom": Odometry, "/tf": TFMessage})
    spawn = burger(publishWheelTF="true", publishTf="false", publishWheelJointState="false")
    with Simulator("empty", [spawn], context=ctx) as sim:
        rec.drive(0.1, 0.0)
        sim.run(0.5)
    assert rec.messages["/odom"] == []  # publishTf false: no odometry, no odom TF
    by_pair = defaultdict(list)
    for t in rec.transforms():
        by_pair[(t.header.frame_id, t.child_frame_id)].append(t)
    assert ("odom", "base_footprint") not in by_pair
    wheel = by_pair[("base_link", "wheel_left_link")]
    assert len(wheel) == 14  # from the diff drive at its updateRate 30: k / 30 s, k = 1..14
    q = wheel[-1].transform.rotation
    angle = 2.0 * math.atan2(math.hypot(q.x, q.y, q.z), q.w)
    assert angle > 0.5  # the wheel turned (about its axis)


def test_encoder_odometry_starts_at_the_origin(ctx: Context) -> None:
    rec = Recorder(ctx, {"/odom": Odometry})
    spawn = burger(odometrySource="encoder")
    spawn = RobotSpawn(source=spawn.source, packages=PACKAGES, spawn=(1.0, 2.0, 0.0, 0.5))
    with Simulator("empty", [spawn], context=ctx) as sim:
        rec.drive(0.2, 0.0)
        sim.run(1.0)
    p = rec.messages["/odom"][-1].pose.pose.position
    assert p.x == pytest.approx(0.15, abs=0.05)  # from where it started, not the world
    assert abs(p.y) < 0.01
