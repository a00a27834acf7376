"""Graph nodes of ego-planner: the planner (map + FSM) and the trajectory server.

:class:`EgoPlannerNode` (``ego_planner_node``) owns a grid map
(:class:`~visnav.mapping.grid_map_node.GridMapRos`, parameters ``grid_map.*``),
the planner (``manager.*``, ``optimization.*``) and the FSM (``fsm.*``); it runs
the FSM at 100 Hz and the collision check at 20 Hz and publishes each new local
trajectory on ``trajectory_topic`` (``planning/trajectory``,
``trajectory_msgs/MultiDOFJointTrajectory`` sampled at the knots, see
:mod:`~visnav.planning.ego_planner.messages`) and, for viewers, as a
``nav_msgs/Path`` on ``planning/path``. Goals: ``goal_topic``
(``/move_base_simple/goal``, ``geometry_msgs/PoseStamped``; the height becomes
``fsm.flight_height``) with ``fsm.flight_type`` 1, or ``fsm.waypoints`` (flat
``[x0, y0, z0, x1, ...]``) with ``fsm.flight_type`` 2. ``odometry_topic``
(``odom``) feeds both the FSM and the map. ``global_frame`` (``world``) is the
planning frame: odometry and goals in other frames are moved into it with TF.

:class:`TrajServerNode` (``traj_server``) samples the latest trajectory at 100 Hz
(``traj_server.period``) and publishes the position command on ``command_topic``
(``command/trajectory``, where visnav's simulated quadrotor listens; upstream's
``/position_cmd``), a one-point ``MultiDOFJointTrajectory``.

All topic names are relative by default, so they resolve under the drone's
namespace (``/drone/odom``, ``/drone/command/trajectory``).

At construction the planner node runs every numba kernel once on a tiny map
(parameter ``warm_up``, default true; about a second with warm caches, a minute
on a machine that never compiled them), so its first replans in flight are not
slowed by compilation or cache loading.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.errors import VisnavError
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.mapping.grid_map_node import GridMapRos
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time, time_to_ns
from visnav.msgs.types import Header, Odometry, Path, Point, Pose, PoseStamped, Quaternion
from visnav.planning.ego_planner.fsm import FSMError, FSMParams, ReplanFSM
from visnav.planning.ego_planner.manager import (
    LocalTrajectory,
    PlannerManager,
    PlannerParams,
    warm_up,
)
from visnav.planning.ego_planner.messages import (
    MultiDOFJointTrajectory,
    msg_to_trajectory,
    reference_to_msg,
    trajectory_to_msg,
)
from visnav.planning.ego_planner.optimizer import OptimizerParams
from visnav.planning.ego_planner.traj_server import TrajectoryServer
from visnav.tf.errors import TransformException
from visnav.tf.transforms import euler_from_quaternion, pose_to_matrix

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "EgoPlannerNode",
    "EgoPlannerNodeParams",
    "TrajServerNode",
    "TrajServerParams",
    "TrajServerTiming",
]

_WARN_PERIOD_S = 5.0  # a repeated warning is logged at most once per 5 s


@dataclass(frozen=True, kw_only=True)
class EgoPlannerNodeParams:
    """The top-level parameters of ``ego_planner_node`` (``fsm.*`` etc. are the algorithm's)."""

    odometry_topic: str = param("odom", description="nav_msgs/Odometry input")
    goal_topic: str = param("/move_base_simple/goal", description="PoseStamped goals ('' off)")
    trajectory_topic: str = param("planning/trajectory", description="trajectory output")
    path_topic: str = param("planning/path", description="nav_msgs/Path output for viewers")
    global_frame: str = param("world", description="planning frame")
    local_frame: str = param("base_link", description="body frame (trajectory joint name)")
    seed: int = param(0, description="seed of the random initial paths")
    warm_up: bool = param(True, description="compile the numba kernels at start")


@dataclass(frozen=True)
class _FsmWaypoints:
    """``fsm.waypoints``: flat ``[x0, y0, z0, x1, ...]`` (FSMParams holds them as triples)."""

    waypoints: list[float] = param([], description="preset waypoints for flight_type 2")  # noqa: RUF009


@dataclass(frozen=True)
class TrajServerParams:
    """The parameters of ``traj_server``."""

    trajectory_topic: str = param("planning/trajectory", description="trajectory input")
    command_topic: str = param("command/trajectory", description="position command output")
    odometry_topic: str = param("odom", description="odometry, for the initial yaw ('' off)")
    local_frame: str = param("base_link", description="joint name of the commands")


@dataclass(frozen=True)
class TrajServerTiming:
    """``traj_server.*``: sampling of the trajectory."""

    time_forward: float = param(1.0, description="look-ahead (s)")
    period: float = param(0.01, description="command period (s)", range=(1e-4, 10.0))


_FSM_FIELDS: tuple[str, ...] = (
    "flight_type",
    "thresh_replan",
    "thresh_no_replan",
    "planning_horizon",
    "emergency_time",
    "flight_height",
)
_OPT_FIELDS: tuple[str, ...] = (
    "lambda_smooth",
    "lambda_collision",
    "lambda_feasibility",
    "lambda_fitness",
    "dist0",
    "max_vel",
    "max_acc",
)
"""The optimizer's parameters ego-planner reads; the other fields are solver settings."""


class EgoPlannerNode(Node):
    """ego_planner_node: grid map, planner and replan FSM on the graph.

    Args:
        name: Node name (default ``ego_planner_node``).
        seed: Seed of the random initial paths (also parameter ``seed``).
        **node_kwargs: Passed to :class:`~visnav.graph.Node` (context, namespace, ...).
    """

    def __init__(
        self, name: str = "ego_planner_node", *, seed: int = 0, **node_kwargs: Unpack[NodeOptions]
    ) -> None:
        super().__init__(name, **node_kwargs)
        top = declare_params(self, EgoPlannerNodeParams, defaults={"seed": seed})
        self.global_frame = top.global_frame
        self.local_frame = top.local_frame
        flat = [float(v) for v in declare_params(self, _FsmWaypoints, prefix="fsm.").waypoints]
        if len(flat) % 3 != 0:
            msg = (
                f"fsm.waypoints has {len(flat)} numbers: expected [x0, y0, z0, x1, ...] "
                "for fsm.flight_type 2"
            )
            raise FSMError(msg)
        waypoints = tuple((flat[i], flat[i + 1], flat[i + 2]) for i in range(0, len(flat), 3))
        fsm = declare_params(
            self, FSMParams, prefix="fsm.", names=_FSM_FIELDS, fixed={"waypoints": waypoints}
        )
        planner_params = declare_params(self, PlannerParams, prefix="manager.")
        optimizer_params = declare_params(
            self, OptimizerParams, prefix="optimization.", names=_OPT_FIELDS
        )
        self.grid = GridMapRos(
            self,
            defaults={
                "odom_topic": top.odometry_topic,
                "frame_id": self.global_frame,
                "local_frame": self.local_frame,
            },
        )
        self.tf = self.grid.tf
        if top.warm_up:
            spent = warm_up(planner_params)
            self.get_logger().debug(f"ego_planner: numba kernels ready in {spent:.2f} s")
        self.manager = PlannerManager(
            self.grid.map,
            planner_params,
            optimizer_params,
            seed=top.seed,
        )
        self.fsm = ReplanFSM(
            self.manager,
            fsm,
            on_trajectory=self._publish_trajectory,
        )
        self._traj_pub = self.create_publisher(MultiDOFJointTrajectory, top.trajectory_topic, 10)
        self._path_pub = self.create_publisher(Path, top.path_topic, 10)
        self.create_subscription(Odometry, top.odometry_topic, self._on_odom, 10)
        if top.goal_topic:
            self.create_subscription(PoseStamped, top.goal_topic, self._on_goal, 10)
        self.create_timer(0.01, self._on_exec)
        self.create_timer(0.05, self._on_safety)
        self._diag = _PlannerDiagnostics(self)

    def _to_global(self, frame: str, stamp_ns: int) -> np.ndarray | None:
        if not frame or frame == self.global_frame:
            return np.eye(4)
        try:
            return self.tf.lookup_transform_matrix(self.global_frame, frame, stamp_ns)
        except TransformException:
            pass
        try:
            return self.tf.lookup_transform_matrix(self.global_frame, frame, 0)
        except TransformException as exc:
            self.get_logger().warning(
                f"ego_planner: no transform {self.global_frame} <- {frame}: {exc}",
                throttle_duration_sec=_WARN_PERIOD_S,
            )
        return None

    def _now(self) -> int:
        return self.get_clock().now_ns()

    def _on_odom(self, msg: Odometry) -> None:
        t = self._to_global(msg.header.frame_id, time_to_ns(msg.header.stamp))
        if t is None:
            return
        try:
            pose = t @ pose_to_matrix(msg.pose.pose)
        except (VisnavError, ValueError) as exc:
            self.get_logger().warning(
                f"ego_planner: invalid odometry pose: {exc}", throttle_duration_sec=_WARN_PERIOD_S
            )
            return
        lin = msg.twist.twist.linear
        # nav_msgs/Odometry twist is in child_frame_id; ego-planner's simulators publish
        # world-frame velocities there, which visnav's p3d odometry matches (world frame)
        vel = t[:3, :3] @ np.array([lin.x, lin.y, lin.z])
        self.fsm.set_odometry(pose[:3, 3], vel, now_ns=self._now())

    def _on_goal(self, msg: PoseStamped) -> None:
        t = self._to_global(msg.header.frame_id, time_to_ns(msg.header.stamp))
        if t is None:
            return
        p = msg.pose.position
        goal = t @ np.array([p.x, p.y, p.z, 1.0])
        if not self.fsm.set_goal(goal[:2], now_ns=self._now()):
            self.get_logger().warning(
                "ego_planner: goal ignored (no odometry yet or no global trajectory)",
                throttle_duration_sec=_WARN_PERIOD_S,
            )

    def _on_exec(self) -> None:
        self.fsm.step(self._now())
        self._diag.update(self.fsm.goals_reached, self.manager.records)

    def _on_safety(self) -> None:
        self.fsm.check_collision(self._now())
        self._diag.update(self.fsm.goals_reached, self.manager.records)

    def _publish_trajectory(self, traj: LocalTrajectory) -> None:
        self._traj_pub.publish(
            trajectory_to_msg(traj, frame_id=self.global_frame, joint_name=self.local_frame)
        )
        if self._path_pub.get_subscription_count() > 0:
            times = np.arange(0.0, traj.duration + 1e-9, 0.05)
            pts = traj.position.evaluate(times)
            header = Header(stamp=ns_to_time(traj.start_time_ns), frame_id=self.global_frame)
            poses = []
            for i, pt in enumerate(pts):
                ps = PoseStamped(
                    header=Header(
                        stamp=ns_to_time(traj.start_time_ns + round(times[i] * 1e9)),
                        frame_id=self.global_frame,
                    ),
                    pose=_pose(pt),
                )
                poses.append(ps)
            self._path_pub.publish(Path(header=header, poses=poses))


class _PlannerDiagnostics:
    """``/diagnostics`` (``diagnostic_msgs/DiagnosticArray``, as diagnostic_updater) on change.

    One status named after the node, published when a replan finished or a goal was
    reached: ``goals_reached``, ``replans`` (so far) and ``planning_time_ms`` (the new
    replans' total times, comma-separated, full precision). The scenario observer reads
    them; upstream ego-planner reports neither on a topic.
    """

    def __init__(self, node: Node) -> None:
        self._node = node
        self._status = get_message_class("diagnostic_msgs/msg/DiagnosticStatus")
        self._kv = get_message_class("diagnostic_msgs/msg/KeyValue")
        array = get_message_class("diagnostic_msgs/msg/DiagnosticArray")
        self._pub = node.create_publisher(array, "/diagnostics", 100)
        self._seen = (0, 0)

    def update(self, goals_reached: int, records: Sequence[Any]) -> None:
        if (goals_reached, len(records)) == self._seen:
            return
        new = records[self._seen[1] :]
        self._seen = (goals_reached, len(records))
        values = {
            "goals_reached": str(goals_reached),
            "replans": str(len(records)),
            "planning_time_ms": ",".join(repr(r.total_s * 1e3) for r in new),
        }
        status = self._status(
            level=0,
            name=self._node.get_fully_qualified_name(),
            message="goal reached" if goals_reached else "planning",
            hardware_id="",
            values=[self._kv(key=k, value=v) for k, v in values.items()],
        )
        now = self._node.get_clock().now_ns()
        header = Header(stamp=ns_to_time(now), frame_id="")
        self._pub.publish(self._pub.msg_type(header=header, status=[status]))


def _pose(pt: np.ndarray) -> Pose:
    return Pose(
        position=Point(x=float(pt[0]), y=float(pt[1]), z=float(pt[2])),
        orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
    )


class TrajServerNode(Node):
    """traj_server: trajectory in, position commands out at 100 Hz.

    Parameters: ``trajectory_topic`` (``planning/trajectory``), ``command_topic``
    (``command/trajectory``), ``odometry_topic`` (``odom``, only for the initial yaw),
    ``traj_server.time_forward`` (1.0 s), ``traj_server.period`` (0.01 s).

    Args:
        name: Node name (default ``traj_server``).
        **node_kwargs: Passed to :class:`~visnav.graph.Node`.
    """

    def __init__(self, name: str = "traj_server", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        p = declare_params(self, TrajServerParams)
        timing = declare_params(self, TrajServerTiming, prefix="traj_server.")
        traj_topic, cmd_topic, odom_topic = p.trajectory_topic, p.command_topic, p.odometry_topic
        self.joint_name = p.local_frame
        time_forward, period = timing.time_forward, timing.period
        self.server = TrajectoryServer(time_forward=time_forward)
        self._pub = self.create_publisher(MultiDOFJointTrajectory, cmd_topic, 50)
        self.create_subscription(MultiDOFJointTrajectory, traj_topic, self._on_traj, 10)
        if odom_topic:
            self.create_subscription(Odometry, odom_topic, self._on_odom, 10)
        self.create_timer(period, self._on_timer)
        self.commands = 0

    def _on_traj(self, msg: MultiDOFJointTrajectory) -> None:
        try:
            start_ns, traj = msg_to_trajectory(msg)
        except VisnavError as exc:
            self.get_logger().error(f"traj_server: dropped a trajectory: {exc}")
            return
        self.server.frame_id = msg.header.frame_id or self.server.frame_id
        self.server.set_trajectory(traj, start_ns)

    def _on_odom(self, msg: Odometry) -> None:
        q = msg.pose.pose.orientation
        if math.isfinite(q.w) and (q.x, q.y, q.z, q.w) != (0.0, 0.0, 0.0, 0.0):
            self.server.set_yaw(euler_from_quaternion([q.x, q.y, q.z, q.w])[2])

    def _on_timer(self) -> None:
        ref = self.server.command(self.get_clock().now_ns())
        if ref is not None:
            self._pub.publish(reference_to_msg(ref, joint_name=self.joint_name))
            self.commands += 1
