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
from visnav.msgs.types import Path as PathMsg
from visnav.scenarios import observer_results
from visnav.scenarios.errors import ScenarioError
from visnav.scenarios.observer import ObserverNode
from visnav.slam import ate, read_tum

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


def _slam_pose(t_ns: int, x: float, y: float) -> PoseStamped:
    msg: PoseStamped = make(PoseStamped)
    msg.header = Header(stamp=ns_to_time(t_ns), frame_id="map")
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.w = 1.0
    return msg


def test_car_slam_scores_and_files_from_slam_topics(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """slam/path + later slam/pose against interpolated truth; trajectories computed once."""
    calls = []
    original = observer_results.slam_trajectories

    def counted(node: ObserverNode) -> observer_results.SlamTrajectories:
        calls.append(node)
        return original(node)

    monkeypatch.setattr(observer_results, "slam_trajectories", counted)
    params = _params(tmp_path, slam=True, exit_when_done=False)
    ms = 1_000_000
    with Context(transport="local") as ctx:
        obs = ObserverNode(context=ctx, use_sim_time=True, parameter_overrides=params)
        feed = Feed(ctx)
        node = Node("slam_feed", context=ctx)
        path_pub = node.create_publisher(PathMsg, "/slam/path", 1)
        pose_pub = node.create_publisher(PoseStamped, "/slam/pose", 10)
        for k in range(51):  # truth at 50 Hz on a curve (x, y) = (t, t^2)
            feed.pose(k * 20 * ms, 0.02 * k, (0.02 * k) ** 2)
            ctx.spin_some()
        # SLAM at 10 Hz, 3 cm off in y: a path of 5 poses, then 5 poses (one a repeat)
        poses = [_slam_pose(k * 100 * ms, 0.1 * k, (0.1 * k) ** 2 + 0.03) for k in range(10)]
        path_pub.publish(make(PathMsg, header=poses[0].header, poses=poses[:5]))
        for msg in poses[4:]:
            pose_pub.publish(msg)
        kv = [make(KV, key=k, value=v) for k, v in (("frames", "10"), ("keyframes", "3"))]
        kv.append(make(KV, key="cpu_s", value="1.234"))
        feed.diag.publish(make(DIAG, status=[make(DSTATUS, name="/slam", values=kv)]))
        feed.tick(1000 * ms)
        summary = obs.finish()
    slam = summary["slam"]
    assert len(calls) == 1  # the summary and the TUM files share one computation
    assert slam["tracked"] == 10  # the path's 5 and the 5 later poses
    assert slam["evaluated"] == 10
    assert slam["ate_unaligned_rmse_m"] == pytest.approx(0.03, abs=1e-6)
    assert slam["ate_rmse_m"] == pytest.approx(0.0, abs=1e-6)
    assert slam["rpe_trans_rmse_m"] == pytest.approx(0.0, abs=1e-6)
    assert (slam["frames"], slam["keyframes"], slam["cpu_s"]) == (10, 3, 1.23)
    est = read_tum(tmp_path / "slam_trajectory.tum")
    gt = read_tum(tmp_path / "ground_truth.tum")
    assert len(est) == len(gt) == 10
    assert est.stamps.tolist() == gt.stamps.tolist()
    assert ate(est, gt).rmse == pytest.approx(0.03, abs=1e-6)


def test_an_unknown_scenario_is_refused() -> None:
    with Context(transport="local") as ctx, pytest.raises(ScenarioError, match="car or drone"):
        ObserverNode(context=ctx, parameter_overrides={"scenario": "boat"})


def test_slam_frames_include_the_frames_tracked_after_the_last_status(tmp_path: Path) -> None:
    """The counters are a status up to 1 s old: ``frames`` adds the poses after it."""
    params = _params(tmp_path, slam=True, exit_when_done=False)
    ms = 1_000_000
    with Context(transport="local") as ctx:
        obs = ObserverNode(context=ctx, use_sim_time=True, parameter_overrides=params)
        feed = Feed(ctx)
        node = Node("slam_feed", context=ctx)
        pose_pub = node.create_publisher(PoseStamped, "/slam/pose", 20)
        for k in range(51):
            feed.pose(k * 20 * ms, 0.02 * k, 0.0)
        # 10 tracked frames at 0..900 ms; the last status counted 7 frames up to the one
        # of 500 ms (one of them lost, so no pose), then the node tracked 4 more.
        for k in range(10):
            pose_pub.publish(_slam_pose(k * 100 * ms, 0.1 * k, 0.0))
        values = {"frames": "7", "keyframes": "2", "last_frame_stamp_ns": str(500 * ms)}
        kv = [make(KV, key=k, value=v) for k, v in values.items()]
        feed.diag.publish(make(DIAG, status=[make(DSTATUS, name="/slam", values=kv)]))
        feed.tick(1000 * ms)
        slam = obs.finish()["slam"]
        assert slam["tracked"] == 10
        assert slam["frames"] == 7 + 4
        assert slam["tracked"] <= slam["frames"]
        assert "last_frame_stamp_ns" not in slam
        # A SLAM node that does not say which frames it counted: its counter as it is.
        del values["last_frame_stamp_ns"]
        kv = [make(KV, key=k, value=v) for k, v in values.items()]
        feed.diag.publish(make(DIAG, status=[make(DSTATUS, name="/slam", values=kv)]))
        feed.tick(1001 * ms)
        assert obs.results()["slam"]["frames"] == 7


def test_shortest_path_ends_where_the_robot_stopped(tmp_path: Path) -> None:
    # The navigator stops within its tolerance short of the goal (0.3 m here, inside the
    # observer's 0.5 m): the shortest path is measured to the same point, ratio >= 1.
    params = _params(tmp_path, exit_when_done=False)
    ms = 1_000_000
    with Context(transport="local") as ctx:
        obs = ObserverNode(context=ctx, use_sim_time=True, parameter_overrides=params)
        feed = Feed(ctx)
        for k in range(28):
            feed.pose(k * 100 * ms, -6.0, -1.5 + 0.1 * k)  # stops at y = 1.2
            if k == 0:
                feed.send_goal(0, -6.0, 1.5)
            feed.tick(k * 100 * ms)
        feed.end_goal(1, 3, 0, 2800 * ms)
        feed.tick(2800 * ms)
        out = obs.results()
    assert out["goals_reached"] == 1
    assert out["path_length_m"] == pytest.approx(2.7, abs=1e-3)
    assert 2.65 < out["shortest_path_m"] <= 2.75  # to y = 1.2, not to the goal at 1.5
    assert out["path_ratio"] >= 0.98
