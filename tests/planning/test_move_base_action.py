"""move_base as an action server: MoveBase / NavigateToPose goals, cancel, preempt, abort,
and the clear_costmaps / make_plan services, with the kinematic robot of test_navigator_node."""

from __future__ import annotations

import importlib.util
import logging
import math
from pathlib import Path
from typing import Any

import pytest

from visnav.graph import Context, Node
from visnav.graph.action_client import ActionClient, ClientGoalHandle
from visnav.graph.action_types import GoalStatus
from visnav.graph.future import Future
from visnav.msgs.action import get_action_type
from visnav.msgs.construct import make
from visnav.msgs.srv import get_service_type

_spec = importlib.util.spec_from_file_location(
    "_navigator_node_tests", Path(__file__).with_name("test_navigator_node.py")
)
assert _spec is not None
assert _spec.loader is not None
_helpers = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_helpers)
FakeRobot = _helpers.FakeRobot
_room = _helpers._room
_navigator = _helpers._navigator

MoveBase = get_action_type("move_base_msgs/action/MoveBase")
NavigateToPose = get_action_type("nav2_msgs/action/NavigateToPose")
S = GoalStatus


@pytest.fixture
def ctx() -> Any:
    with Context(transport="local") as c:
        yield c


def _pose(x: float, y: float, frame: str = "map") -> Any:
    pose = make(get_service_type("nav_msgs/srv/GetPlan").Request).goal
    pose.header.frame_id = frame
    pose.pose.position.x, pose.pose.position.y = x, y
    pose.pose.orientation.w = 1.0
    return pose


def _run(robot: Any, until: Any, steps: int = 1200) -> bool:
    for _ in range(steps):
        robot.step()
        if until():
            return True
    return False


def _settle(robot: Any, future: Future[Any], steps: int = 10) -> Any:
    """Step until ``future`` is done; a goal's result comes from its execute thread."""
    for _ in range(steps):
        robot.step()
        if future.wait(0.05):
            return future.result()
    raise AssertionError(f"{future} not done after {steps} steps")


def _handle(robot: Any, future: Future[ClientGoalHandle]) -> ClientGoalHandle:
    assert _run(robot, future.done, 20)
    handle = future.result()
    assert handle is not None
    assert handle.accepted
    return handle


def test_move_base_goal_reaches_with_feedback(ctx: Context) -> None:
    nav = _navigator(ctx)
    robot = FakeRobot(ctx, _room())
    client = ActionClient(Node("user", context=ctx), MoveBase, "/move_base")
    robot.step()
    assert client.server_is_ready()
    feedback: list[Any] = []
    future = client.send_goal_async(
        make(MoveBase.Goal, target_pose=_pose(3.5, 0.5)), feedback_callback=feedback.append
    )
    handle = _handle(robot, future)
    result = handle.get_result_async()
    assert _run(robot, result.done)
    assert result.result().status == S.STATUS_SUCCEEDED, nav.handle
    assert math.hypot(robot.x - 3.5, robot.y - 0.5) < 0.3
    assert len(feedback) > 5
    last = feedback[-1].feedback.base_position
    assert last.header.frame_id == "map"
    assert math.hypot(last.pose.position.x - 3.5, last.pose.position.y - 0.5) < 0.5
    robot.step()
    assert robot.cmd == (0.0, 0.0)


def test_navigate_to_pose_preempt_and_cancel_stop_the_robot(ctx: Context) -> None:
    _navigator(ctx)
    robot = FakeRobot(ctx, _room())
    client = ActionClient(Node("user", context=ctx), NavigateToPose, "/navigate_to_pose")
    robot.step()
    feedback: list[Any] = []
    first = _handle(
        robot,
        client.send_goal_async(
            make(NavigateToPose.Goal, pose=_pose(3.5, 0.5)), feedback_callback=feedback.append
        ),
    )
    _run(robot, lambda: False, 30)
    assert robot.cmd != (0.0, 0.0)
    fb = feedback[-1].feedback
    assert fb.distance_remaining > 1.0
    assert fb.navigation_time.sec + fb.navigation_time.nanosec > 0
    # a new goal (here: from the other action) preempts the running one
    mb = ActionClient(Node("user2", context=ctx), MoveBase, "/move_base")
    second = _handle(robot, mb.send_goal_async(make(MoveBase.Goal, target_pose=_pose(0.5, 2.0))))
    assert _settle(robot, first.get_result_async()).status == S.STATUS_CANCELED
    # cancelling the running goal stops the robot
    _run(robot, lambda: False, 10)
    cancel = second.cancel_goal_async()
    assert _run(robot, cancel.done, 5)
    assert len(cancel.result().goals_canceling) == 1
    assert _settle(robot, second.get_result_async()).status == S.STATUS_CANCELED
    robot.step()
    robot.step()
    assert robot.cmd == (0.0, 0.0)


def test_unreachable_goal_aborts_with_the_reason_logged(
    ctx: Context, caplog: pytest.LogCaptureFixture
) -> None:
    _navigator(ctx)
    robot = FakeRobot(ctx, _room())
    client = ActionClient(Node("user", context=ctx), NavigateToPose, "/navigate_to_pose")
    robot.step()
    with caplog.at_level(logging.ERROR):
        handle = _handle(
            robot, client.send_goal_async(make(NavigateToPose.Goal, pose=_pose(40.0, 0.0)))
        )
        assert _settle(robot, handle.get_result_async(), 40).status == S.STATUS_ABORTED
    assert any("goal aborted" in r.getMessage() and "outside" in r.getMessage()
               for r in caplog.records)  # fmt: skip
    # a goal in a frame without a transform aborts too (move_base accepts, then aborts)
    handle = _handle(
        robot,
        client.send_goal_async(make(NavigateToPose.Goal, pose=_pose(1.0, 0.0, frame="mars"))),
    )
    assert _settle(robot, handle.get_result_async()).status == S.STATUS_ABORTED


def test_goal_without_orientation_means_any_heading(ctx: Context) -> None:
    nav = _navigator(ctx)
    robot = FakeRobot(ctx, _room())
    client = ActionClient(Node("user", context=ctx), MoveBase, "/move_base")
    robot.step()
    pose = _pose(1.0, 0.0)
    pose.pose.orientation.w = 0.0  # all zeros: what a YAML goal without orientation gives
    handle = _handle(robot, client.send_goal_async(make(MoveBase.Goal, target_pose=pose)))
    assert _settle(robot, handle.get_result_async(), 400).status == S.STATUS_SUCCEEDED
    assert nav.handle is not None
    assert nav.handle.goal[2] == 0.0


def test_make_plan_and_clear_costmaps(ctx: Context) -> None:
    _navigator(ctx)
    robot = FakeRobot(ctx, _room())
    user = Node("user", context=ctx)
    GetPlan = get_service_type("nav_msgs/srv/GetPlan")
    plan = user.create_client(GetPlan, "/move_base/make_plan")
    clear = user.create_client("std_srvs/srv/Empty", "/move_base/clear_costmaps")
    _run(robot, lambda: False, 5)
    request = make(GetPlan.Request, goal=_pose(3.5, 0.5))  # start: the robot
    future = plan.call_async(request)
    assert _run(robot, future.done, 5)
    poses = future.result().plan.poses
    assert future.result().plan.header.frame_id == "map"
    assert len(poses) > 10
    assert math.hypot(poses[0].pose.position.x, poses[0].pose.position.y) < 0.2
    assert math.hypot(poses[-1].pose.position.x - 3.5, poses[-1].pose.position.y - 0.5) < 0.1
    assert max(p.pose.position.y for p in poses) > 1.5  # around the wall
    request = make(GetPlan.Request, start=_pose(0.0, 0.0), goal=_pose(40.0, 0.0))
    future = plan.call_async(request)
    assert _run(robot, future.done, 5)
    assert list(future.result().plan.poses) == []
    future = clear.call_async(clear.srv_type.Request())
    assert _run(robot, future.done, 5)
    assert future.exception() is None
