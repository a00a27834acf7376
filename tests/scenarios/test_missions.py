"""The mission nodes on a real (in-process) graph: goals out, status in."""

from __future__ import annotations

import itertools
from typing import Any

import pytest

from visnav.description.world import load_world
from visnav.graph import Context, Node
from visnav.graph.qos import QoSProfile, ReliabilityPolicy, qos_profile_latched
from visnav.msgs.construct import make
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Clock, Odometry, PoseStamped
from visnav.scenarios.errors import ScenarioError
from visnav.scenarios.missions import CarGoalSender, DroneMission, goal_sequence

NODES = {"N1": (1.0, 2.0), "S1": (3.0, 4.0), "C1": (5.0, 6.0), "corr_n": (0.0, 0.0)}
CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
STATUS = get_message_class("actionlib_msgs/msg/GoalStatusArray")
GOAL_STATUS = get_message_class("actionlib_msgs/msg/GoalStatus")
GOAL_ID = get_message_class("actionlib_msgs/msg/GoalID")


def test_goal_sequence_is_seeded_and_never_repeats_a_goal_in_a_row() -> None:
    for seed in range(20):
        goals = goal_sequence(NODES, seed, count=6)
        assert goals == goal_sequence(NODES, seed, count=6)
        assert len(goals) == 6
        assert all(a != b for a, b in itertools.pairwise(goals))
        assert set(goals) <= {NODES["N1"], NODES["S1"], NODES["C1"]}  # only goal nodes
    assert len({tuple(goal_sequence(NODES, s)) for s in range(20)}) > 1
    with pytest.raises(ScenarioError, match="none of the goal nodes"):
        goal_sequence({"corr_n": (0.0, 0.0)}, 0)


def _status(goal: int, code: int, stamp_ns: int) -> Any:
    return make(
        STATUS,
        status_list=[
            make(
                GOAL_STATUS,
                goal_id=make(GOAL_ID, id=f"goal_{goal}", stamp=ns_to_time(0)),
                status=code,
            )
        ],
        header=make(get_message_class("std_msgs/msg/Header"), stamp=ns_to_time(stamp_ns)),
    )


def test_car_goals_wait_for_odometry_and_follow_move_base_status() -> None:
    with Context(transport="local") as ctx:
        sender = CarGoalSender(context=ctx, use_sim_time=True, parameter_overrides={"seed": 3})
        test = Node("test", context=ctx)
        clock = test.create_publisher(Clock, "/clock", CLOCK_QOS)
        odom = test.create_publisher(Odometry, "/odom", 10)
        status = test.create_publisher(STATUS, "/move_base/status", 10)
        got: list[PoseStamped] = []
        test.create_subscription(PoseStamped, "/move_base_simple/goal", got.append, 10)

        def at(t_ns: int) -> None:
            clock.publish(Clock(clock=ns_to_time(t_ns)))
            ctx.spin_some()

        for t in range(0, 700_000_000, 5_000_000):
            at(t)
        assert got == []  # no odometry yet: no goal
        odom.publish(make(Odometry))
        at(700_000_000)
        assert len(got) == 1
        assert (got[0].pose.position.x, got[0].pose.position.y) == sender.goals[0]
        assert got[0].header.frame_id == "map"
        status.publish(_status(1, 1, 800_000_000))  # ACTIVE: keep going
        at(800_000_000)
        assert len(got) == 1
        status.publish(_status(1, 4, 900_000_000))  # ABORTED: the next goal goes out at once
        ctx.spin_some()
        assert len(got) == 2
        assert (got[1].pose.position.x, got[1].pose.position.y) == sender.goals[1]
        graph = load_world("office", seed=3).metadata["graph"]["nodes"]
        assert sender.goals == goal_sequence(graph, 3, 4)


def test_drone_mission_holds_then_sends_the_goal() -> None:
    with Context(transport="local") as ctx:
        test = Node("test", context=ctx)
        latched = qos_profile_latched
        holds: list[PoseStamped] = []
        goals: list[PoseStamped] = []
        mission = DroneMission(context=ctx, namespace="/drone", use_sim_time=True)
        test.create_subscription(PoseStamped, "/drone/command/pose", holds.append, latched)
        test.create_subscription(PoseStamped, "/move_base_simple/goal", goals.append, latched)
        clock = test.create_publisher(Clock, "/clock", CLOCK_QOS)
        for t in range(0, 3_500_000_001, 100_000_000):
            clock.publish(Clock(clock=ns_to_time(t)))
            ctx.spin_some()
            if t < 3_500_000_000:
                assert goals == []
        assert len(holds) == 1
        assert holds[0].pose.position.z == 1.0
        assert len(goals) == 1
        assert (goals[0].pose.position.x, goals[0].pose.position.y) == mission.goal[:2]


def test_a_world_without_a_goal_graph_is_refused() -> None:
    with Context(transport="local") as ctx, pytest.raises(ScenarioError, match="free-space"):
        CarGoalSender(context=ctx, parameter_overrides={"world": "forest"})
