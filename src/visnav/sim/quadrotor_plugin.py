"""``libvisnav_quadrotor.so``: visnav's quadrotor on the graph (position commands in).

See :class:`QuadrotorPlugin`; the controller is
:class:`~visnav.sim.vehicles.quadrotor.QuadrotorController`.
"""

from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING

from rosbags.typesys.stores.ros2_humble import (
    trajectory_msgs__msg__MultiDOFJointTrajectory as MultiDOFJointTrajectory,
)

from visnav.msgs.time import duration_to_ns
from visnav.msgs.types import PoseStamped, Quaternion
from visnav.sim.plugins import DEFAULT_QOS, SimPlugin
from visnav.sim.vehicles.quadrotor import PositionCommand
from visnav.tf.transforms import yaw_from_quaternion

if TYPE_CHECKING:
    import mujoco

    from visnav.description.gazebo_specs import QuadrotorSpec
    from visnav.graph.node import Node
    from visnav.sim.rebind import IdMap
    from visnav.sim.vehicles.quadrotor import QuadrotorController

__all__ = ["MultiDOFJointTrajectory", "QuadrotorPlugin", "trajectory_point_command"]


def _command_yaw(q: Quaternion) -> float:
    """Heading of a commanded orientation; an unset (all-zero) quaternion means heading 0."""
    if q.x == 0.0 and q.y == 0.0 and q.z == 0.0 and q.w == 0.0:
        return 0.0
    return yaw_from_quaternion(q)


def trajectory_point_command(
    msg: MultiDOFJointTrajectory, index: int, *, stamp_ns: int = 0
) -> PositionCommand:
    """The :class:`PositionCommand` of one point of a ``MultiDOFJointTrajectory``.

    ``transforms[0]`` gives position and yaw, ``velocities[0]`` velocity and yaw rate
    (``angular.z``), ``accelerations[0]`` the feed-forward acceleration; a missing
    velocity or acceleration is zero (RotorS' convention). NaN components drop the
    term, as in ``so3_control``.
    """
    point = msg.points[index]
    transform = point.transforms[0]
    t = transform.translation
    velocity = point.velocities[0] if len(point.velocities) > 0 else None
    accel = point.accelerations[0] if len(point.accelerations) > 0 else None
    return PositionCommand(
        stamp_ns=stamp_ns,
        frame_id=msg.header.frame_id or "world",
        position=(float(t.x), float(t.y), float(t.z)),
        velocity=(
            (float(velocity.linear.x), float(velocity.linear.y), float(velocity.linear.z))
            if velocity is not None
            else (0.0, 0.0, 0.0)
        ),
        acceleration=(
            (float(accel.linear.x), float(accel.linear.y), float(accel.linear.z))
            if accel is not None
            else (0.0, 0.0, 0.0)
        ),
        yaw=_command_yaw(transform.rotation),
        yaw_dot=float(velocity.angular.z) if velocity is not None else 0.0,
    )


class QuadrotorPlugin(SimPlugin):
    """``libvisnav_quadrotor.so``: position commands in, thrust and moments on the body.

    Commands arrive three ways (each replaces the previous one):

    * ``trajectory_topic`` (``trajectory_msgs/MultiDOFJointTrajectory``, RotorS'
      ``command/trajectory``): the first point applies at once, each later point
      ``time_from_start`` after it (relative to the first point), in sim time;
    * ``pose_topic`` (``geometry_msgs/PoseStamped``, RotorS' ``command/pose``):
      hold that position and yaw;
    * :meth:`set_command` with a :class:`~visnav.sim.vehicles.quadrotor.PositionCommand`
      (the fields of ``quadrotor_msgs/PositionCommand``), from Python.

    Without a command the vehicle holds where it started.

    Args:
        node: the plugin's node.
        spec: the plugin with its final topics.
        controller: the SO(3) controller flying the body.
    """

    def __init__(self, node: Node, spec: QuadrotorSpec, controller: QuadrotorController) -> None:
        super().__init__(node, spec.plugin_name)
        self.spec = spec
        self.controller = controller
        self._queue: deque[tuple[int, PositionCommand]] = deque()
        self._now_ns = 0
        node.create_subscription(
            MultiDOFJointTrajectory, spec.trajectory_topic, self._on_trajectory, DEFAULT_QOS
        )
        node.create_subscription(PoseStamped, spec.pose_topic, self._on_pose, DEFAULT_QOS)

    def rewind(self, now_ns: int) -> None:
        """Sim time went back to ``now_ns``: trajectories are timed from it."""
        self._now_ns = int(now_ns)

    def rebind(self, ids: IdMap) -> None:
        """Fly the same body of a recompiled model."""
        self.controller.rebind(ids)

    def set_command(self, command: PositionCommand) -> None:
        """Track ``command`` from the next physics step on (drops queued trajectory points)."""
        self._queue.clear()
        self.controller.set_command(command)

    def _on_trajectory(self, msg: MultiDOFJointTrajectory) -> None:
        points = list(msg.points)
        usable = [i for i, p in enumerate(points) if len(p.transforms) > 0]
        if len(usable) < len(points):
            self.node.get_logger().warning(
                f"{self.spec.trajectory_topic}: {len(points) - len(usable)} of {len(points)} "
                "trajectory points have no transforms[0] (position and yaw) and were ignored"
            )
        if not usable:
            if not points:
                self.node.get_logger().warning(
                    f"{self.spec.trajectory_topic}: a trajectory without points was ignored"
                )
            return
        self._queue.clear()
        first = duration_to_ns(points[usable[0]].time_from_start)
        for i in usable:
            due = self._now_ns + duration_to_ns(points[i].time_from_start) - first
            self._queue.append((due, trajectory_point_command(msg, i, stamp_ns=due)))

    def _on_pose(self, msg: PoseStamped) -> None:
        p = msg.pose.position
        self.set_command(
            PositionCommand.hold(
                (float(p.x), float(p.y), float(p.z)),
                _command_yaw(msg.pose.orientation),
                stamp_ns=self._now_ns,
            )
        )

    def control(self, data: mujoco.MjData, now_ns: int) -> None:
        """Apply the controller for the step at ``now_ns``."""
        self._now_ns = now_ns  # commands arriving in this step's spin start now
        queue = self._queue
        while queue and queue[0][0] <= now_ns:
            self.controller.set_command(queue.popleft()[1])
        self.controller.step(data)
