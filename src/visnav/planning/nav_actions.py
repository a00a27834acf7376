"""move_base's actions and services on the graph (the glue of :class:`NavigatorNode`).

* Actions ``move_base`` (``move_base_msgs/action/MoveBase``, ROS 1 users' name, which the
  ROS 1 bridge offers as actionlib's ``/move_base/goal`` etc.) and ``navigate_to_pose``
  (``nav2_msgs/action/NavigateToPose``). Every goal is accepted and handed to the
  navigator; the goal then ends as the navigator's does: reached -> SUCCEEDED; given up
  (no plan, no control, goal outside the map or in an obstacle, a goal frame without a
  transform) -> ABORTED, the reason logged; cancelled -> CANCELED and the robot stops;
  a newer goal (from either action or ``move_base_simple/goal``) preempts the running
  one, which ends CANCELED (ROS 1's PREEMPTED). Feedback carries the robot's pose in the
  global frame (nav2's also time, distance and recoveries), at 5 Hz.
* Services ``~/clear_costmaps`` (``std_srvs/srv/Empty``) and ``~/make_plan``
  (``nav_msgs/srv/GetPlan``: the global planner's path from ``start`` (empty frame: the
  robot) to ``goal`` within ``tolerance``, in the global frame; empty when none).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.graph.action_server import ActionServer, ServerGoalHandle
from visnav.graph.action_types import CancelResponse
from visnav.msgs.construct import make
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time
from visnav.planning.global_planner import path_to_msg
from visnav.planning.navigator import GoalHandle, GoalStatus
from visnav.tf.errors import TransformException
from visnav.tf.transforms import pose_to_matrix, yaw_from_matrix

if TYPE_CHECKING:
    from visnav.planning.nodes import NavigatorNode

__all__ = ["FEEDBACK_PERIOD_NS", "NavigationActions"]

FEEDBACK_PERIOD_NS = 200_000_000
"""Feedback every 0.2 s of the node's clock (5 Hz)."""

_MOVE_BASE = "move_base_msgs/action/MoveBase"
_NAV2 = "nav2_msgs/action/NavigateToPose"


@dataclass
class _Tracked:
    """An action goal and the navigator goal behind it."""

    action: str
    goal: ServerGoalHandle
    nav: GoalHandle
    done: threading.Event = field(default_factory=threading.Event)
    last_feedback_ns: int = -(1 << 62)


class NavigationActions:
    """Serves move_base's actions and services for ``node``.

    Args:
        node: the navigator node (its navigator, costmaps and planner are used).
    """

    def __init__(self, node: NavigatorNode) -> None:
        self.node = node
        self._lock = threading.Lock()
        self._tracked: list[_Tracked] = []
        self.servers = [
            self._server(_MOVE_BASE, "move_base"),
            self._server(_NAV2, "navigate_to_pose"),
        ]
        node.create_service("std_srvs/srv/Empty", "~/clear_costmaps", self._on_clear)
        node.create_service("nav_msgs/srv/GetPlan", "~/make_plan", self._on_make_plan)

    def _server(self, type_name: str, name: str) -> ActionServer:
        return ActionServer(
            self.node,
            type_name,
            name,
            self._execute,
            handle_accepted_callback=lambda gh: self._accepted(type_name, gh),
            cancel_callback=lambda gh: CancelResponse.ACCEPT,
        )

    # ------------------------------------------------------------------ goals
    def _accepted(self, action: str, goal: ServerGoalHandle) -> None:
        """Runs in the executor: start navigating (preempting whatever runs)."""
        pose = goal.request.target_pose if action == _MOVE_BASE else goal.request.pose
        q = pose.pose.orientation
        if q.x == q.y == q.z == q.w == 0.0:
            # ROS 2's Quaternion defaults to w = 1; a goal written as YAML without an
            # orientation (``{pose: {pose: {position: ...}}}``) means "any heading" there
            q.w = 1.0
            self.node.get_logger().info(
                "goal orientation is all zeros: read as the identity (ROS 2's default w=1)",
                once=True,
            )
        nav = self.node.go_to(pose)
        with self._lock:
            self._tracked.append(_Tracked(action, goal, nav))
        goal.execute()
        self.sync()

    def _execute(self, goal: ServerGoalHandle) -> Any:
        """Runs on the goal's thread: wait until :meth:`sync` ends the goal."""
        with self._lock:
            tracked = next((t for t in self._tracked if t.goal is goal), None)
        if tracked is not None:
            while not tracked.done.wait(0.5):
                if not self.node.context.ok:
                    break
        is_move_base = goal.request.__msgtype__.startswith("move_base_msgs/")
        server = self.servers[0] if is_move_base else self.servers[1]
        return make(server.action_type.Result)

    def sync(self) -> None:
        """Carry the navigator's outcomes to the action goals (the executor calls it)."""
        now = self.node.get_clock().now_ns()
        with self._lock:
            tracked = list(self._tracked)
        for t in tracked:
            if not t.goal.is_active:
                self._forget(t)
                continue
            nav = t.nav
            if t.goal.is_cancel_requested and not nav.done and nav is self.node.handle:
                self.node.cancel()
            if nav.done:
                self._finish(t)
            elif now - t.last_feedback_ns >= FEEDBACK_PERIOD_NS:
                t.last_feedback_ns = now
                self._feedback(t, now)

    def _finish(self, t: _Tracked) -> None:
        nav, goal = t.nav, t.goal
        if nav.status is GoalStatus.SUCCEEDED:
            goal.succeed()
        elif nav.status is GoalStatus.PREEMPTED:
            goal.canceled()
        else:
            self.node.get_logger().error(
                f"action {t.action.rsplit('/', 1)[-1]} goal aborted: {nav.text}"
            )
            goal.abort()
        self._forget(t)

    def _forget(self, t: _Tracked) -> None:
        t.done.set()
        with self._lock:
            if t in self._tracked:
                self._tracked.remove(t)

    def _feedback(self, t: _Tracked, now: int) -> None:
        pose = self.node.global_costmap.get_robot_pose()
        if pose is None:
            return
        frame = self.node.global_costmap.global_frame
        current = _pose_stamped(pose, frame, now)
        server = self.servers[0] if t.action == _MOVE_BASE else self.servers[1]
        fb_cls = server.action_type.Feedback
        if t.action == _MOVE_BASE:
            t.goal.publish_feedback(make(fb_cls, base_position=current))
            return
        remaining = _remaining(self.node.navigator.plan, pose, t.nav.goal)
        speed = max(abs(self.node.velocity[0]), abs(self.node.last_cmd[0]))
        eta_ns = round(remaining / speed * 1e9) if speed > 0.01 else 0
        fb = make(
            fb_cls,
            current_pose=current,
            number_of_recoveries=len(t.nav.recoveries),
            distance_remaining=float(remaining),
        )
        fb.navigation_time = _duration(now - t.nav.accepted_ns, fb.navigation_time)
        fb.estimated_time_remaining = _duration(eta_ns, fb.estimated_time_remaining)
        t.goal.publish_feedback(fb)

    # ------------------------------------------------------------------ services
    def _on_clear(self, _request: Any, response: Any) -> Any:
        self.node.global_costmap.clear()
        self.node.local_costmap.clear()
        self.node.get_logger().info("costmaps cleared (clear_costmaps service)")
        return response

    def _on_make_plan(self, request: Any, response: Any) -> Any:
        """move_base's make_plan: empty plan when there is none (the reason logged)."""
        node = self.node
        frame = node.global_costmap.global_frame
        now = node.get_clock().now_ns()
        response.plan = path_to_msg(np.empty((0, 3)), frame, now)
        try:
            start: tuple[float, float, float] | None
            if request.start.header.frame_id:
                start = self._to_global(request.start)
            else:
                start = node.global_costmap.get_robot_pose()
                if start is None:
                    node.get_logger().warning(
                        f"make_plan: no start given and no robot pose: "
                        f"{node.global_costmap.pose_error}"
                    )
                    return response
            goal = self._to_global(request.goal)
        except (TransformException, ValueError) as exc:
            node.get_logger().warning(f"make_plan: {exc}")
            return response
        tol = float(request.tolerance)
        result = node.planner.make_plan(
            node.global_costmap.layered.costmap, start, goal, tolerance=tol if tol > 0 else None
        )
        if not result.ok:
            node.get_logger().warning(f"make_plan: no plan: {result.reason}")
            return response
        response.plan = path_to_msg(result.poses, frame, now)
        return response

    def _to_global(self, pose: Any) -> tuple[float, float, float]:
        g_frame = self.node.global_costmap.global_frame
        frame = pose.header.frame_id or g_frame
        T = self.node.tf_buffer.lookup_transform_matrix(g_frame, frame, 0)  # noqa: N806
        M = T @ pose_to_matrix(pose.pose)  # noqa: N806
        if not np.isfinite(M).all():
            msg = f"the pose in '{frame}' is not finite"
            raise ValueError(msg)
        return float(M[0, 3]), float(M[1, 3]), yaw_from_matrix(M)


def _pose_stamped(pose: tuple[float, float, float], frame: str, now: int) -> Any:
    cls = get_message_class("geometry_msgs/msg/PoseStamped")
    msg = make(cls)
    msg.header.frame_id = frame
    msg.header.stamp = ns_to_time(now)
    msg.pose.position.x, msg.pose.position.y = float(pose[0]), float(pose[1])
    msg.pose.orientation.z = math.sin(pose[2] / 2)
    msg.pose.orientation.w = math.cos(pose[2] / 2)
    return msg


def _duration(ns: int, template: Any) -> Any:
    ns = max(int(ns), 0)
    return type(template)(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _remaining(
    plan: np.ndarray[Any, Any], pose: tuple[float, float, float], goal: tuple[float, ...]
) -> float:
    """Path length left along ``plan`` from its point nearest the robot (else straight)."""
    if len(plan) < 2:
        return math.hypot(goal[0] - pose[0], goal[1] - pose[1])
    xy = plan[:, :2]
    i = int(np.argmin(np.hypot(xy[:, 0] - pose[0], xy[:, 1] - pose[1])))
    tail = xy[i:]
    along = float(np.hypot(*np.diff(tail, axis=0).T).sum()) if len(tail) > 1 else 0.0
    return along + math.hypot(tail[0, 0] - pose[0], tail[0, 1] - pose[1])
