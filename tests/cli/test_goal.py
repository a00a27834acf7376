"""visnav goal and visnav initialpose: RViz's two buttons in a terminal, across processes."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import threading
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.cli.goal import GoalArgumentError, _finite
from visnav.graph import Context, Node
from visnav.graph.action_server import ActionServer
from visnav.msgs import PoseStamped, PoseWithCovarianceStamped
from visnav.msgs.action import get_action_type
from visnav.msgs.rviz_tools import INITIALPOSE_COVARIANCE, nav_goal, pose_estimate
from visnav.msgs.time import time_to_ns


def _cli(domain: int, *args: str) -> subprocess.Popen[str]:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    return subprocess.Popen(
        [sys.executable, "-m", "visnav.cli.main", *args],
        env=env,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )


def _yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


@given(
    st.floats(-1e3, 1e3),
    st.floats(-1e3, 1e3),
    st.floats(-math.pi + 1e-6, math.pi - 1e-6),
)
def test_messages_carry_the_pose(x: float, y: float, yaw: float) -> None:
    goal = nav_goal(x, y, yaw, frame_id="map", stamp_ns=5_000_000_001)
    assert (goal.pose.position.x, goal.pose.position.y, goal.pose.position.z) == (x, y, 0.0)
    assert _yaw(goal.pose.orientation) == pytest.approx(yaw, abs=1e-9)
    assert time_to_ns(goal.header.stamp) == 5_000_000_001
    est = pose_estimate(x, y, yaw, frame_id="odom", stamp_ns=7)
    assert est.header.frame_id == "odom"
    assert _yaw(est.pose.pose.orientation) == pytest.approx(yaw, abs=1e-9)
    assert list(est.pose.covariance) == list(INITIALPOSE_COVARIANCE)


def test_rviz_covariance() -> None:
    cov = INITIALPOSE_COVARIANCE
    assert (cov[0], cov[7], cov[35]) == (0.25, 0.25, pytest.approx((math.pi / 12) ** 2))
    assert sum(1 for c in cov if c) == 3


@pytest.mark.parametrize("text", ["nan", "inf", "one", ""])
def test_a_bad_number_is_one_clear_error(text: str) -> None:
    with pytest.raises(GoalArgumentError, match=f"x is {text!r}: expected a finite number"):
        _finite("x", text)


def test_bad_number_from_the_cli_has_no_traceback(domain: int) -> None:
    proc = _cli(domain, "goal", "1", "abc")
    _, err = proc.communicate(timeout=60)
    assert proc.returncode != 0
    assert "y is 'abc': expected a finite number" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("verb", ["goal", "initialpose"])
def test_one_call_reaches_a_subscriber_in_another_process(domain: int, verb: str) -> None:
    msg_type = PoseStamped if verb == "goal" else PoseWithCovarianceStamped
    topic = "/move_base_simple/goal" if verb == "goal" else "/initialpose"
    got: list[Any] = []
    with Context(domain) as ctx:
        node = Node("listener", context=ctx)
        node.create_subscription(msg_type, topic, got.append, 10)
        proc = _cli(domain, verb, "1.5", "-2", "1.2", "--frame", "map")
        assert ctx.spin_until(lambda: bool(got), 60.0), proc.communicate(timeout=30)
        out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert f"sent on {topic}" in out
    msg = got[0]
    pose = msg.pose if verb == "goal" else msg.pose.pose
    assert msg.header.frame_id == "map"
    assert (pose.position.x, pose.position.y) == (1.5, -2.0)
    assert _yaw(pose.orientation) == pytest.approx(1.2)
    if verb == "initialpose":
        assert msg.pose.covariance[35] == pytest.approx((math.pi / 12) ** 2)


def test_goal_wait_goes_through_the_move_base_action(domain: int) -> None:
    move_base = get_action_type("move_base_msgs/action/MoveBase")
    received: list[Any] = []

    def execute(handle: Any) -> Any:
        received.append(handle.request)
        handle.succeed()
        return move_base.Result()

    stop = threading.Event()
    with Context(domain) as ctx:
        node = Node("move_base", context=ctx)
        ActionServer(node, move_base, "move_base", execute)
        proc = _cli(domain, "goal", "3", "4", "--wait")
        spinner = threading.Thread(target=lambda: ctx.spin_until(stop.is_set, 90.0))
        spinner.start()
        try:
            out, err = proc.communicate(timeout=90)
        finally:
            stop.set()
            spinner.join()
    assert proc.returncode == 0, err
    assert "goal finished: SUCCEEDED" in out
    target = received[0].target_pose
    assert (target.header.frame_id, target.pose.position.x, target.pose.position.y) == (
        "map",
        3.0,
        4.0,
    )


def test_goal_wait_without_move_base_says_so(domain: int) -> None:
    proc = _cli(domain, "goal", "1", "2", "--wait", "--timeout", "1")
    _, err = proc.communicate(timeout=60)
    assert proc.returncode != 0
    assert "has no server after 1 s: is move_base running?" in err
    assert "Traceback" not in err
