"""The navigation node: move_base on the visnav graph.

:class:`NavigatorNode` (default name ``move_base``) owns two costmaps
(``global_costmap``: static + obstacle + inflation layers in ``map``, tracking unknown
space; ``local_costmap``: a 5 x 5 m rolling window of obstacle + inflation in ``odom``),
the global planner (parameters ``GlobalPlanner.*``), a local planner
(``base_local_planner``: ``dwa_local_planner/DWAPlannerROS`` with ``DWAPlannerROS.*`` or
``nav2_regulated_pure_pursuit_controller/RegulatedPurePursuitController`` with
``RegulatedPurePursuit.*``) and the :class:`~visnav.planning.navigator.Navigator`.

Topics (relative names, so namespaces and remappings apply):

* in: ``move_base_simple/goal`` (``geometry_msgs/PoseStamped``, any frame with a
  transform to the global frame), ``odom`` (``nav_msgs/Odometry``, the velocity the
  local planner starts from), ``scan`` (``sensor_msgs/LaserScan``, both costmaps'
  default observation source), ``map`` (the static layer), ``/tf``, ``/tf_static``;
* out: ``cmd_vel`` (``geometry_msgs/Twist``), ``~/GlobalPlanner/plan`` and
  ``~/DWAPlannerROS/local_plan`` (``nav_msgs/Path``), ``~/status``
  (``actionlib_msgs/GoalStatusArray``, the status text carries the reason),
  ``~/global_costmap/costmap`` and ``~/local_costmap/costmap`` (1 Hz and 2 Hz).

Actions and services (:mod:`visnav.planning.nav_actions`): ``move_base``
(``move_base_msgs/action/MoveBase``) and ``navigate_to_pose``
(``nav2_msgs/action/NavigateToPose``) with feedback, result, cancel and preemption;
``~/clear_costmaps`` (``std_srvs/srv/Empty``) and ``~/make_plan`` (``nav_msgs/srv/GetPlan``).

Python API: ``handle = node.go_to(pose)`` with a ``PoseStamped`` (any frame) or
``(x, y, yaw)`` in the global frame; ``handle.status`` / ``handle.text`` /
``handle.error``; ``node.cancel()``.

Parameters: move_base's (``planner_frequency`` 1.0, ``controller_frequency`` 20.0,
``planner_patience`` 5.0, ``controller_patience`` 15.0, ``max_planning_retries`` -1,
``oscillation_timeout`` 10.0, ``oscillation_distance`` 0.5,
``recovery_behavior_enabled``, ``clearing_rotation_allowed``, ``conservative_reset_dist``
3.0), the costmaps' (see :mod:`visnav.mapping.costmap_ros`), the planners' (their
dataclass fields). The built-in defaults of the costmaps are those of a typical
configuration file: source ``scan`` (LaserScan, marking and clearing, and in the local
costmap ``expected_update_rate`` 0.5 s so a stale scan stops the robot).

The local planner is wrapped in nav2's RotationShimController (``use_rotation_shim``,
parameters ``RotationShim.*``; see :mod:`visnav.planning.rotation_shim` for why), and
DWA ships with ``xy_goal_tolerance`` 0.15 and ``latch_xy_goal_tolerance`` true
(:data:`~visnav.planning.local_planners.DWA_DEFAULTS`). Local planners are
looked up in :data:`~visnav.planning.local_planners.LOCAL_PLANNERS`.

A goal whose frame has no transform to the global frame is REJECTED with the TF
error; a failing robot pose lookup stops the robot (status text says why).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.mapping.costmap_ros import CostmapROS
from visnav.msgs.construct import make
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time, time_to_ns
from visnav.msgs.types import Header, Odometry, Path, PoseStamped, Twist, Vector3
from visnav.planning.global_planner import GlobalPlanner, GlobalPlannerParams, path_to_msg
from visnav.planning.local_planner import LocalPlanner, Pose2D
from visnav.planning.local_planners import DWA_DEFAULTS, make_local_planner
from visnav.planning.nav_actions import NavigationActions
from visnav.planning.navigator import GoalHandle, NavError, Navigator, NavigatorParams
from visnav.planning.rotation_shim import RotationShim
from visnav.tf.buffer import Buffer
from visnav.tf.errors import TransformException
from visnav.tf.ros import TransformListener
from visnav.tf.transforms import pose_to_matrix, yaw_from_matrix

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "DWA_DEFAULTS",
    "GLOBAL_COSTMAP_DEFAULTS",
    "LOCAL_COSTMAP_DEFAULTS",
    "NavigatorNode",
    "NavigatorNodeParams",
    "RotationShimParams",
]

GLOBAL_COSTMAP_DEFAULTS: dict[str, Any] = {
    "global_frame": "map",
    "robot_base_frame": "base_footprint",
    "update_frequency": 5.0,
    "publish_frequency": 1.0,
    "plugins": ["static_layer", "obstacle_layer", "inflation_layer"],
    "obstacle_layer.observation_sources": "scan",
    "obstacle_layer.scan.data_type": "LaserScan",
    "obstacle_layer.scan.marking": True,
    "obstacle_layer.scan.clearing": True,
}
LOCAL_COSTMAP_DEFAULTS: dict[str, Any] = {
    "global_frame": "odom",
    "robot_base_frame": "base_footprint",
    "update_frequency": 10.0,
    "publish_frequency": 2.0,
    "rolling_window": True,
    "width": 5.0,
    "height": 5.0,
    "plugins": ["obstacle_layer", "inflation_layer"],
    "obstacle_layer.observation_sources": "scan",
    "obstacle_layer.scan.data_type": "LaserScan",
    "obstacle_layer.scan.marking": True,
    "obstacle_layer.scan.clearing": True,
    "obstacle_layer.scan.expected_update_rate": 0.5,
}

_NS = 1_000_000_000


@dataclass(frozen=True)
class RotationShimParams:
    """nav2's RotationShimController parameters (``RotationShim.*``)."""

    angular_dist_threshold: float = param(0.785, description="rotate first above (rad)")
    forward_sampling_distance: float = param(0.5, description="plan point heading from (m)")
    rotate_to_heading_angular_vel: float = param(1.8, description="turn rate (rad/s)")
    max_angular_accel: float = param(3.2, description="angular acceleration (rad/s^2)")
    simulate_ahead_time: float = param(1.0, description="collision look-ahead (s)")


@dataclass(frozen=True)
class NavigatorNodeParams:
    """move_base's plugin choice (the algorithms' parameters are their dataclasses)."""

    base_local_planner: str = param(
        "dwa_local_planner/DWAPlannerROS",
        description="local planner plugin (see visnav.planning.local_planners)",
        read_only=True,
    )
    use_rotation_shim: bool = param(
        True,
        description="wrap the local planner in nav2's RotationShimController",
        read_only=True,
    )


class NavigatorNode(Node):
    """move_base: costmaps, planners and the navigator on the graph.

    Args:
        name: node name (default ``move_base``).
        **node_kwargs: passed to :class:`~visnav.graph.Node` (context, namespace,
            parameter_overrides, remappings, use_sim_time).
    """

    def __init__(self, name: str = "move_base", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        self.tf_buffer = Buffer()
        self.tf_listener = TransformListener(self.tf_buffer, self)
        self.params = declare_params(self, NavigatorParams)
        self.global_costmap = CostmapROS(
            self, "global_costmap", self.tf_buffer, defaults=GLOBAL_COSTMAP_DEFAULTS
        )
        self.local_costmap = CostmapROS(
            self, "local_costmap", self.tf_buffer, defaults=LOCAL_COSTMAP_DEFAULTS
        )
        self.planner = GlobalPlanner(
            declare_params(self, GlobalPlannerParams, prefix="GlobalPlanner.")
        )
        choice = declare_params(self, NavigatorNodeParams)
        freq = self.params.controller_frequency
        built = make_local_planner(choice.base_local_planner, self, controller_frequency=freq)
        self._local_plan_topic = built.local_plan_topic
        self.controller: LocalPlanner = built.planner
        if choice.use_rotation_shim:
            shim = declare_params(self, RotationShimParams, prefix="RotationShim.")
            self.controller = RotationShim(
                built.planner, **dataclasses.asdict(shim), controller_frequency=freq
            )
        self.navigator = Navigator(
            self.global_costmap.layered,
            self.local_costmap.layered,
            self.planner,
            self.controller,
            self.params,
            log=self._log,
        )
        self.navigator.plan_listeners.append(self._publish_plan)
        self._cmd_pub = self.create_publisher(Twist, "cmd_vel", 1)
        self._plan_pub = self.create_publisher(Path, "~/GlobalPlanner/plan", 1)
        self._local_pub = self.create_publisher(Path, self._local_plan_topic, 1)
        status_type = get_message_class("actionlib_msgs/msg/GoalStatusArray")
        self._status_cls = get_message_class("actionlib_msgs/msg/GoalStatus")
        self._goal_id_cls = get_message_class("actionlib_msgs/msg/GoalID")
        self._status_pub = self.create_publisher(status_type, "~/status", 1)
        self.create_subscription(PoseStamped, "move_base_simple/goal", self._on_goal, 1)
        self.create_subscription(Odometry, "odom", self._on_odom, 10)
        self.create_timer(1.0 / freq, self.control_cycle)
        self.create_timer(0.2, self._publish_status)
        self._velocity: tuple[float, float] | None = None
        self._last_cmd = (0.0, 0.0)
        self._pose_text = ""
        self._was_active = False
        self._last_status: tuple[int, int, str] | None = None
        self.actions = NavigationActions(self)

    # ------------------------------------------------------------------ API
    @property
    def velocity(self) -> tuple[float, float]:
        """The robot's ``(v, w)``: from ``odom``, else the last command (before any odom)."""
        return self._velocity if self._velocity is not None else self._last_cmd

    @property
    def last_cmd(self) -> tuple[float, float]:
        """The last ``(v, w)`` published on ``cmd_vel``."""
        return self._last_cmd

    @property
    def handle(self) -> GoalHandle | None:
        """The current (or last) goal."""
        return self.navigator.handle

    def go_to(self, goal: PoseStamped | Pose2D) -> GoalHandle:
        """Send a goal: a ``PoseStamped`` in any frame, or ``(x, y, yaw)`` in the global frame."""
        now = self.get_clock().now_ns()
        if isinstance(goal, PoseStamped):
            frame = goal.header.frame_id or self.global_costmap.global_frame
            g_frame = self.global_costmap.global_frame
            pose2d = (
                float(goal.pose.position.x),
                float(goal.pose.position.y),
                0.0,
            )
            try:
                stamp = time_to_ns(goal.header.stamp)
                try:
                    T = self.tf_buffer.lookup_transform_matrix(g_frame, frame, stamp)  # noqa: N806
                except TransformException:
                    T = self.tf_buffer.lookup_transform_matrix(g_frame, frame, 0)  # noqa: N806
                M = T @ pose_to_matrix(goal.pose)  # noqa: N806
            except (TransformException, ValueError) as exc:
                reason = f"cannot transform the goal from '{frame}' into '{g_frame}': {exc}"
                return self.navigator.reject(pose2d, NavError.NO_TRANSFORM, reason, now_ns=now)
            target = (float(M[0, 3]), float(M[1, 3]), yaw_from_matrix(M))
        else:
            target = (float(goal[0]), float(goal[1]), float(goal[2]))
        return self.navigator.go_to(target, now_ns=now)

    def cancel(self) -> None:
        """Cancel the running goal."""
        self.navigator.cancel(now_ns=self.get_clock().now_ns())
        self._publish_cmd(0.0, 0.0)

    # ------------------------------------------------------------------ callbacks
    def _log(self, level: str, text: str) -> None:
        logger = self.get_logger()
        log = {"debug": logger.debug, "info": logger.info, "warning": logger.warning}
        log.get(level, logger.error)(text)

    def _on_goal(self, msg: PoseStamped) -> None:
        self.go_to(msg)

    def _on_odom(self, msg: Odometry) -> None:
        t = msg.twist.twist
        self._velocity = (float(t.linear.x), float(t.angular.z))

    def _publish_cmd(self, v: float, w: float) -> None:
        self._last_cmd = (v, w)
        self._cmd_pub.publish(
            make(Twist, linear=Vector3(x=v, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=w))
        )

    def _publish_plan(self, poses: NDArray[np.float64]) -> None:
        now = self.get_clock().now_ns()
        self._plan_pub.publish(path_to_msg(poses, self.global_costmap.global_frame, now))

    def control_cycle(self) -> None:
        """One move_base cycle: poses from TF, navigator step, ``cmd_vel``, actions."""
        self.actions.sync()
        h = self.navigator.handle
        active = h is not None and not h.done
        if not active:
            if self._was_active:
                self._publish_cmd(0.0, 0.0)
                self._was_active = False
            return
        self._was_active = True
        now = self.get_clock().now_ns()
        pg = self.global_costmap.get_robot_pose()
        pl = self.local_costmap.get_robot_pose()
        if pg is None or pl is None:
            text = "stopped: " + (self.global_costmap.pose_error or self.local_costmap.pose_error)
            if text != self._pose_text:
                self.get_logger().warning(text)
                self._pose_text = text
            assert h is not None
            h.text = text
            self._publish_cmd(0.0, 0.0)
            return
        self._pose_text = ""
        velocity = self._velocity if self._velocity is not None else self._last_cmd
        v, w = self.navigator.step(now, pg, pl, velocity)
        if not (math.isfinite(v) and math.isfinite(w)):
            v = w = 0.0
        self._publish_cmd(v, w)
        if h is not None and h.done:
            self._publish_status()
            self.actions.sync()
        last = self.navigator.last_control
        if last is not None and last.ok and len(last.trajectory):
            self._local_pub.publish(
                path_to_msg(last.trajectory, self.local_costmap.global_frame, now)
            )

    def _publish_status(self) -> None:
        h = self.navigator.handle
        if h is None:
            return
        key = (h.goal_id, int(h.status), h.text)
        if key == self._last_status and h.done:
            return
        self._last_status = key
        now = self.get_clock().now_ns()
        status = make(
            self._status_cls,
            goal_id=make(
                self._goal_id_cls, stamp=ns_to_time(h.accepted_ns), id=f"goal_{h.goal_id}"
            ),
            status=int(h.status),
            text=h.text,
        )
        msg = make(
            self._status_pub.msg_type,
            header=Header(stamp=ns_to_time(now), frame_id=""),
            status_list=[status],
        )
        self._status_pub.publish(msg)
