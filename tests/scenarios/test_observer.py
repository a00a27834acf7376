"""The observer node on a real (in-process) graph fed with synthetic topics."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from visnav.graph import Context, Node
from visnav.graph.qos import QoSProfile, ReliabilityPolicy
from visnav.msgs.construct import make
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Clock, Header, Odometry, PoseStamped
from visnav.scenarios.errors import ScenarioError
from visnav.scenarios.observer import ObserverNode

CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
DIAG = get_message_class("diagnostic_msgs/msg/DiagnosticArray")
DSTATUS = get_message_class("diagnostic_msgs/msg/DiagnosticStatus")
KV = get_message_class("diagnostic_msgs/msg/KeyValue")
STATUS = get_message_class("actionlib_msgs/msg/GoalStatusArray")
GOAL_STATUS = get_message_class("actionlib_msgs/msg/GoalStatus")
GOAL_ID = get_message_class("actionlib_msgs/msg/GoalID")


class Feed:
    """Publishes what the simulator and the stack would, at a given sim time."""

    def __init__(self, ctx: Context, ns: str = "") -> None:
        self.ctx = ctx
        node = Node("feed", context=ctx)
        self.clock = node.create_publisher(Clock, "/clock", CLOCK_QOS)
        self.truth = node.create_publisher(Odometry, f"{ns or '/ground_truth'}/odom", 50)
        self.odom = node.create_publisher(Odometry, "/odom", 50)
        self.goal = node.create_publisher(PoseStamped, "/move_base_simple/goal", 10)
        self.status = node.create_publisher(STATUS, "/move_base/status", 10)
        self.contacts = node.create_publisher(DIAG, f"{ns}/bumper_states", 50)
        self.diag = node.create_publisher(DIAG, "/diagnostics", 50)

    def tick(self, t_ns: int) -> None:
        self.clock.publish(Clock(clock=ns_to_time(t_ns)))
        self.ctx.spin_some()

    def pose(self, t_ns: int, x: float, y: float, z: float = 0.0) -> None:
        msg: Odometry = make(Odometry)
        msg.header = Header(stamp=ns_to_time(t_ns), frame_id="world")
        msg.child_frame_id = "base_footprint"
        msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
        msg.pose.pose.position.z = z
        msg.pose.pose.orientation.w = 1.0
        self.truth.publish(msg)
        self.odom.publish(msg)

    def touch(self, t_ns: int, shapes: list[str]) -> None:
        status = [make(DSTATUS, name="robot", hardware_id="wall", message=s) for s in shapes]
        self.contacts.publish(
            make(DIAG, header=Header(stamp=ns_to_time(t_ns), frame_id=""), status=status)
        )

    def send_goal(self, t_ns: int, x: float, y: float) -> None:
        msg: PoseStamped = make(PoseStamped)
        msg.header = Header(stamp=ns_to_time(t_ns), frame_id="map")
        msg.pose.position.x, msg.pose.position.y = x, y
        self.goal.publish(msg)

    def end_goal(self, goal: int, code: int, accepted_ns: int, t_ns: int) -> None:
        st = make(
            GOAL_STATUS,
            goal_id=make(GOAL_ID, id=f"goal_{goal}", stamp=ns_to_time(accepted_ns)),
            status=code,
        )
        self.status.publish(
            make(STATUS, header=Header(stamp=ns_to_time(t_ns), frame_id=""), status_list=[st])
        )


def _params(tmp: Path, **more: Any) -> dict[str, Any]:
    base = {
        "world": "office",
        "goals": 1,
        "output_dir": str(tmp),
        "localization_source": "",
        "map_topic": "",
    }
    return {**base, **more}


def test_car_summary_from_topics(tmp_path: Path) -> None:
    with Context(transport="local") as ctx:
        obs = ObserverNode(context=ctx, use_sim_time=True, parameter_overrides=_params(tmp_path))
        feed = Feed(ctx)
        ms = 1_000_000
        # the office spawn (-6, -1.5) north along x = -6 to (-6, 1.5); the floor never counts
        for k in range(31):
            t = k * 100 * ms
            feed.pose(t, -6.0, -1.5 + 0.1 * k)
            feed.touch(t, ["plane"] + (["box"] if k in (10, 11, 20) else []))
            if k == 1:
                feed.send_goal(t, -6.0, 1.5)
            feed.tick(t)
        assert not obs.done
        feed.end_goal(1, 3, 100 * ms, 3000 * ms)  # SUCCEEDED after 2.9 s
        feed.tick(3000 * ms)
        assert obs.done
        with pytest.raises(SystemExit):  # the first step after done ends the launch
            feed.tick(3001 * ms)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["scenario"] == "car"
    assert summary["goals_total"] == summary["goals_reached"] == 1
    assert summary["collisions"] == 2  # two runs of touching samples 1 s apart
    assert summary["path_length_m"] == pytest.approx(2.9, abs=1e-3)  # from the goal's start
    assert 2.85 < summary["shortest_path_m"] < 3.05  # the grid path of the straight drive
    assert summary["goal_times_s"] == [2.9]
    assert summary["odometry"]["source"] == "world"
    assert summary["odometry"]["drift_m"] == 0.0
    assert summary["odometry"]["distance_m"] == pytest.approx(3.0, abs=1e-3)


def test_a_goal_ended_far_from_the_goal_is_not_reached(tmp_path: Path) -> None:
    params = _params(tmp_path, exit_when_done=False)
    with Context(transport="local") as ctx:
        obs = ObserverNode(context=ctx, use_sim_time=True, parameter_overrides=params)
        feed = Feed(ctx)
        feed.pose(0, -6.0, -1.5)
        feed.send_goal(0, -6.0, 1.5)
        feed.tick(0)
        feed.end_goal(1, 3, 0, 10_000_000)  # "SUCCEEDED" 3 m short of the goal
        feed.tick(10_000_000)
        out = obs.results()
    assert out["goals_reached"] == 0
    assert out["goal_times_s"] == [0.01]


def test_drone_summary_from_planner_diagnostics(tmp_path: Path) -> None:
    params = _params(
        tmp_path,
        scenario="drone",
        world="forest",
        ground_truth_topic="/drone/odom",
        odom_topic="",
        contact_topic="/drone/bumper_states",
        contacts_ignore_ground=False,
        contacts_after_goal=True,
        contact_gap=0.0,
        planner_diagnostics=True,
        exit_when_done=False,
    )
    with Context(transport="local") as ctx:
        obs = ObserverNode(context=ctx, use_sim_time=True, parameter_overrides=params)
        feed = Feed(ctx, ns="/drone")
        ms = 1_000_000
        feed.pose(0, -17.0, 0.0)
        feed.touch(0, ["plane"])  # resting on the ground before the goal: no collision
        feed.tick(0)
        feed.tick(1000 * ms)
        feed.send_goal(1000 * ms, 17.0, 0.0)
        ctx.spin_some()
        for k in range(1, 11):
            feed.pose(1000 * ms + k * 1000 * ms, -17.0 + 3.4 * k, 0.0, 1.0)
            values = {"goals_reached": "1" if k == 10 else "0", "planning_time_ms": f"{k}.0"}
            status = make(
                DSTATUS,
                name="/drone/ego",
                values=[make(KV, key=a, value=b) for a, b in values.items()],
            )
            feed.diag.publish(make(DIAG, status=[status]))
            feed.tick(1000 * ms + k * 1000 * ms)
        assert obs.done
        summary = obs.finish()
    assert summary["goals_reached"] == 1
    assert summary["collisions"] == 0
    assert summary["path_length_m"] == pytest.approx(
        30.6, abs=1e-3
    )  # from the first pose after the goal
    assert summary["mean_speed_mps"] == pytest.approx(3.06, abs=1e-3)  # over 10 s since the goal
    assert summary["planning_time_ms"]["median"] == pytest.approx(5.5)
    assert summary["planning_time_ms"]["max"] == 10.0
    assert summary["min_clearance_m"] is not None


def test_an_unknown_scenario_is_refused() -> None:
    with Context(transport="local") as ctx, pytest.raises(ScenarioError, match="car or drone"):
        ObserverNode(context=ctx, parameter_overrides={"scenario": "boat"})
