"""``/gazebo/model_states`` and ``/gazebo/link_states`` as gazebo_ros_api_plugin publishes them:
every model and link in the world frame, every world update, only while subscribed."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.msgs import Odometry, Twist, Vector3, get_message_class
from visnav.msgs.serde import typestore
from visnav.sim.model_states import ModelStatesPublisher
from visnav.sim.simulator import RobotSpawn, Simulator

TB3 = Path(__file__).resolve().parent.parent / "data" / "turtlebot3" / "turtlebot3_description"
ModelStates = get_message_class("gazebo_msgs/msg/ModelStates")
LinkStates = get_message_class("gazebo_msgs/msg/LinkStates")


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as context:
        yield context


def burger(x: float = 0.0, y: float = 0.0, name: str | None = None) -> RobotSpawn:
    return RobotSpawn(
        source=TB3 / "urdf" / "turtlebot3_burger.urdf.xacro",
        packages={"turtlebot3_description": TB3},
        spawn=(x, y, 0.0, 0.0),
        name=name,
    )


def listen(ctx: Context, msg_type: type[Any], topic: str) -> list[Any]:
    out: list[Any] = []
    Node("states_listener", context=ctx).create_subscription(msg_type, topic, out.append, 100_000)
    return out


def test_gazebo_msgs_types_match_gazebo_ros() -> None:
    store = typestore()
    # the ROS 1 checksums of gazebo_msgs/ModelStates and LinkStates (same definition)
    for name in ("gazebo_msgs/msg/ModelStates", "gazebo_msgs/msg/LinkStates"):
        assert store.generate_msgdef(name, ros_version=1)[1] == "48c080191eb15c41858319b4d8a609c2"
    assert [f[0] for f in store.fielddefs["gazebo_msgs/msg/ModelState"][1]] == [
        "model_name", "pose", "twist", "reference_frame",
    ]  # fmt: skip


def test_model_states_every_step_with_every_robot(ctx: Context) -> None:
    states = listen(ctx, ModelStates, "/gazebo/model_states")
    odoms = listen(ctx, Odometry, "/r2/odom")
    robots = [burger(0.0, 0.0, "tb_a"), replace(burger(1.0, 2.0, "tb_b"), namespace="/r2")]
    with Simulator("empty", robots, context=ctx) as sim:
        cmd = Node("driver", context=ctx).create_publisher(Twist, "/r2/cmd_vel", 1)
        cmd.publish(
            Twist(linear=Vector3(x=0.2, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0))
        )
        sim.run(1.0)
        steps = sim.stats.steps
        body = sim.model.body("tb_b/base_footprint").id
        truth = np.array(sim.data.xpos[body])
    assert len(states) == steps  # every world update
    last = states[-1]
    assert list(last.name) == ["ground_plane", "tb_a", "tb_b"]
    b = last.pose[2]
    # the state before the last step; the robot moved < 1 mm since
    assert (b.position.x, b.position.y) == pytest.approx((truth[0], truth[1]), abs=1e-3)
    assert b.position.x > 1.1
    assert last.twist[2].linear.x == pytest.approx(0.2, abs=0.02)  # world frame
    assert last.twist[1].linear.x == pytest.approx(0.0, abs=1e-3)
    odom = odoms[-1].pose.pose.position
    assert (odom.x, odom.y) == pytest.approx((b.position.x, b.position.y), abs=0.01)
    g = last.pose[0]
    assert (g.position.x, g.orientation.w) == (0.0, 1.0)


def test_link_states_scoped_names_and_only_while_subscribed(ctx: Context) -> None:
    with Simulator("empty", [burger(0.5, -0.5)], context=ctx) as sim:
        publisher = sim.model_states
        assert isinstance(publisher, ModelStatesPublisher)
        sim.run(0.1)
        assert publisher.published == 0  # nobody listens: nothing is built
        links = listen(ctx, LinkStates, "/gazebo/link_states")
        sim.run(0.1)
        name = sim.robot().name
    assert publisher.published == len(links) == 50
    last = links[-1]
    names = list(last.name)
    assert names[0] == "ground_plane::link"
    assert f"{name}::base_footprint" in names
    assert f"{name}::wheel_left_link" in names
    wheel = last.pose[names.index(f"{name}::wheel_left_link")]
    # TurtleBot3's wheel_left_joint is at (0, 0.08, 0.023) from base_link, 0.010 above the footprint
    assert (wheel.position.x, wheel.position.y) == pytest.approx((0.5, -0.42), abs=0.01)
