"""ego_planner_node and traj_server on an in-process graph with sim time and a fake vehicle."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.msgs import Clock, Header, Odometry, Path, PoseStamped, make, ns_to_time
from visnav.planning.ego_planner.fsm import FSMState
from visnav.planning.ego_planner.messages import (
    MultiDOFJointTrajectory,
    PositionReference,
    command_fields,
    msg_to_reference,
    reference_to_msg,
)
from visnav.planning.ego_planner.nodes import EgoPlannerNode, TrajServerNode
from visnav.sim.vehicles.quadrotor import PositionCommand

_NS = 1_000_000_000


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def _odom(pos: np.ndarray, vel: np.ndarray, t_ns: int) -> Odometry:
    msg = make(Odometry)
    msg.header = Header(stamp=ns_to_time(t_ns), frame_id="world")
    msg.child_frame_id = "base_link"
    p = msg.pose.pose
    p.position.x, p.position.y, p.position.z = (float(v) for v in pos)
    p.orientation.w = 1.0
    tw = msg.twist.twist.linear
    tw.x, tw.y, tw.z = (float(v) for v in vel)
    return msg


def test_command_message_round_trip_into_the_simulator_command() -> None:
    ref = PositionReference(
        123, "world", (1.0, 2.0, 3.0), (0.5, 0.0, -0.1), (0.0, 0.2, 0.0), math.radians(100), 0.3
    )
    msg = reference_to_msg(ref)
    back = msg_to_reference(msg)
    assert back.position == ref.position
    assert back.velocity == ref.velocity
    assert back.acceleration == ref.acceleration
    assert back.yaw == pytest.approx(ref.yaw)
    assert back.yaw_dot == pytest.approx(ref.yaw_dot)
    command = PositionCommand(**command_fields(msg))
    assert command.position == (1.0, 2.0, 3.0)
    assert command.yaw == pytest.approx(math.radians(100))
    assert command.stamp_ns == 123


def test_planner_and_traj_server_fly_a_fake_vehicle_to_a_goal(ctx: Context) -> None:
    common = {"use_sim_time": True}
    planner = EgoPlannerNode(
        context=ctx,
        namespace="/drone",
        parameter_overrides={
            **common,
            "warm_up": False,
            "grid_map.map_size_x": 24.0,
            "grid_map.map_size_y": 12.0,
            "grid_map.depth_topic": "",
        },
    )
    server = TrajServerNode(context=ctx, namespace="/drone", parameter_overrides=common)
    assert planner.resolve_topic_name("odom") == "/drone/odom"
    # a column on the straight line, known in advance
    zs = np.arange(0.0, 3.0, 0.05)
    th = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    for r in np.arange(0.0, 0.41, 0.05):
        ring = np.column_stack([r * np.cos(th), 0.1 + r * np.sin(th)])
        planner.grid.map.mark_occupied(
            np.column_stack([np.repeat(ring, len(zs), axis=0), np.tile(zs, len(th))])
        )
    probe = Node("vehicle", context=ctx)
    clock = probe.create_publisher(Clock, "/clock", 1)
    odom_pub = probe.create_publisher(Odometry, "/drone/odom", 10)
    goal_pub = probe.create_publisher(PoseStamped, "/move_base_simple/goal", 10)
    trajectories: list[MultiDOFJointTrajectory] = []
    commands: list[MultiDOFJointTrajectory] = []
    paths: list[Path] = []
    probe.create_subscription(
        MultiDOFJointTrajectory, "/drone/planning/trajectory", trajectories.append, 10
    )
    probe.create_subscription(
        MultiDOFJointTrajectory, "/drone/command/trajectory", commands.append, 100
    )
    probe.create_subscription(Path, "/drone/planning/path", paths.append, 10)
    pos = np.array([-8.0, 0.0, 1.0])
    vel = np.zeros(3)
    now = _NS
    track = []

    def step() -> None:
        nonlocal now, pos, vel
        now += 10_000_000
        clock.publish(Clock(clock=ns_to_time(now)))
        ctx.spin_some()
        if commands:
            cmd = PositionCommand(**command_fields(commands[-1]))  # perfect tracking
            pos, vel = np.array(cmd.position), np.array(cmd.velocity)
        odom_pub.publish(_odom(pos, vel, now))
        ctx.spin_some()
        track.append(pos.copy())

    for _ in range(5):
        step()
    assert planner.fsm.state == FSMState.WAIT_TARGET
    goal = make(PoseStamped)
    goal.header = Header(stamp=ns_to_time(now), frame_id="world")
    goal.pose.position.x, goal.pose.position.y, goal.pose.position.z = 8.0, 0.0, 0.0
    goal.pose.orientation.w = 1.0
    goal_pub.publish(goal)
    for _ in range(3000):
        step()
        if planner.fsm.goals_reached:
            break
    assert planner.fsm.goals_reached == 1
    assert np.linalg.norm(pos - [8.0, 0.0, 1.0]) < 0.2  # z is fsm.flight_height
    assert len(trajectories) >= 3
    assert trajectories[0].header.frame_id == "world"
    assert len(paths) >= 1
    assert server.commands > 100
    first = msg_to_reference(commands[0])
    assert first.frame_id == "world"
    track_arr = np.array(track)
    assert not planner.grid.map.inflate_occupancy(track_arr).any()
    assert np.min(np.hypot(track_arr[:, 0], track_arr[:, 1] - 0.1)) > 0.5
    # heading follows the path (x forward): mostly +x
    yaws = [msg_to_reference(c).yaw for c in commands[len(commands) // 2 :]]
    assert abs(float(np.median(yaws))) < 0.5
