"""Mobile bases besides the differential drive: skid steer and planar move.

* :class:`SkidSteerPlugin` (``libgazebo_ros_skid_steer_drive.so``, ROS 1): four wheel
  joints, both of a side at ``v -/+ w * wheelSeparation / 2`` (left / right) rim speed,
  their force capped at ``torque``, new targets at ``updateRate``. The wheels are driven
  by the diff drive's :class:`~visnav.sim.vehicles.diff_drive.DiffDriveController` with
  two wheel pairs (front, rear) and no acceleration limit; the odometry is the model's
  world pose and velocity (twist in the base frame, both covariances
  ``covariance_x|y|yaw`` and 1e12 for z, roll and pitch), always published, its TF
  ``odometryFrame -> robotBaseFrame`` only with ``broadcastTF``.
* :class:`PlanarMovePlugin` (``libgazebo_ros_planar_move.so``): no wheels at all. Each
  update it *sets* the model's velocity: ``cmd_vel`` ``linear.x``/``linear.y`` (base frame)
  rotated by the model's yaw, vertical velocity 0, angular velocity ``(0, 0, angular.z)``;
  physics (gravity, contacts) acts between updates. The model must float (a free root
  link). ROS 1 updates every physics step and stops after ``cmdTimeout`` without a
  command; ROS 2 updates at ``update_rate``. The odometry is the model's world pose at
  ``odometryRate`` / ``publish_rate``: ROS 1 reports z = 0 and a twist from the pose change
  since the previous message (pose covariance only), ROS 2 the model's velocity (both
  covariances ``covariance_x|y|yaw``); the TF ``odometry_frame -> robot_base_frame`` carries
  the full pose.

Where visnav differs: the skid steer's wheels reach their speed through the diff drive's
torque-limited velocity servo, not by Gazebo setting the joint velocity outright
(``SetVelocity``) every update.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from visnav.description.gazebo_specs import DiffDriveSpec
from visnav.description.rigid import matrix_to_quat_xyzw
from visnav.msgs.types import (
    Odometry,
    Point,
    Pose,
    PoseWithCovariance,
    Transform,
    TransformStamped,
    Twist,
    TwistWithCovariance,
)
from visnav.sim.errors import SimulatorError
from visnav.sim.plugin_factories import RobotBuild, diff_drive_controller
from visnav.sim.plugins import (
    DEFAULT_QOS,
    DiffDrivePlugin,
    SimPlugin,
    _header,
    _quaternion,
    _vector,
)
from visnav.sim.sensor_timing import SensorClock
from visnav.sim.vehicles._state import BodyReader
from visnav.tf.ros import TransformBroadcaster
from visnav.tf.transforms import yaw_from_matrix

if TYPE_CHECKING:
    import mujoco

    from visnav.description.gazebo_specs import PlanarMoveSpec, SkidSteerSpec
    from visnav.graph.node import Node
    from visnav.sim.rebind import IdMap

__all__ = [
    "PlanarMovePlugin",
    "SkidSteerPlugin",
    "make_planar_move",
    "make_skid_steer",
    "odometry_covariance",
    "skid_steer_as_diff_drive",
]

_UNKNOWN = 1.0e12


def odometry_covariance(diagonal: tuple[float, float, float]) -> np.ndarray:
    """The 6 x 6 row-major covariance gazebo_ros writes: x, y, yaw given, z/roll/pitch 1e12."""
    cov = np.zeros(36)
    cov[[0, 7, 14, 21, 28, 35]] = (diagonal[0], diagonal[1], _UNKNOWN, _UNKNOWN, _UNKNOWN,
                                    diagonal[2])  # fmt: skip
    return cov


class SkidSteerPlugin(DiffDrivePlugin):
    """``libgazebo_ros_skid_steer_drive.so``: a :class:`DiffDrivePlugin` over two wheel pairs.

    Built by :func:`visnav.sim.plugin_factories.make_skid_steer` from the skid steer's
    parameters (front pair, then rear pair; see the module docstring).
    """


class PlanarMovePlugin(SimPlugin):
    """``libgazebo_ros_planar_move.so``: ``cmd_vel`` sets the model's planar velocity.

    Args:
        node: the plugin's node.
        spec: the plugin with its final topics and frames.
        model: the compiled model.
        body: MuJoCo body id of the model's root link (it must have a free joint).
        dof: the free joint's first velocity address.
        start_ns: sim time at which the plugin starts.
    """

    def __init__(
        self,
        node: Node,
        spec: PlanarMoveSpec,
        model: mujoco.MjModel,
        *,
        body: int,
        dof: int,
        start_ns: int = 0,
    ) -> None:
        super().__init__(node, spec.plugin_name)
        self.spec = spec
        self._body = BodyReader(model, body)
        self._dof = dof
        self._target = (0.0, 0.0, 0.0)
        self._now_ns = int(start_ns)
        self._last_cmd_ns = int(start_ns)
        # ROS 2: the first update and message one period after the start
        update_period = 0 if spec.update_rate == 0 else round(1e9 / spec.update_rate)
        publish_period = 0 if spec.odometry_rate == 0 else round(1e9 / spec.odometry_rate)
        self._update = SensorClock(spec.update_rate, start_ns=start_ns + update_period)
        self._publish = SensorClock(spec.odometry_rate, start_ns=start_ns + publish_period)
        self._pose_cov = odometry_covariance(spec.covariance)
        self._twist_cov = (
            self._pose_cov.copy() if spec.ros_version == 2 else np.zeros(36, dtype=np.float64)
        )
        if spec.ros_version == 1:  # ROS 1 writes its fixed pose covariance
            self._pose_cov = odometry_covariance((0.00001, 0.00001, 0.001))
        self._last_pose: tuple[int, np.ndarray, float] | None = None
        self._odom = (
            node.create_publisher(Odometry, spec.odometry_topic, DEFAULT_QOS)
            if spec.publish_odom
            else None
        )
        self._tf = TransformBroadcaster(node) if spec.publish_odom_tf else None
        node.create_subscription(Twist, spec.command_topic, self._on_cmd_vel, DEFAULT_QOS)

    @property
    def target(self) -> tuple[float, float, float]:
        """The commanded ``(linear.x, linear.y, angular.z)``."""
        return self._target

    def rewind(self, now_ns: int) -> None:
        """Sim time went back to ``now_ns``: schedules and the command timeout restart."""
        spec = self.spec
        update_period = 0 if spec.update_rate == 0 else round(1e9 / spec.update_rate)
        publish_period = 0 if spec.odometry_rate == 0 else round(1e9 / spec.odometry_rate)
        self._update.restart(now_ns + update_period)
        self._publish.restart(now_ns + publish_period)
        self._now_ns = self._last_cmd_ns = int(now_ns)
        self._last_pose = None

    def rebind(self, ids: IdMap) -> None:
        """Move the same body of a recompiled model (command kept)."""
        self._body.rebind(ids)
        self._dof = int(ids.dof([self._dof])[0])

    def reset(self, data: mujoco.MjData, now_ns: int) -> None:
        """As gazebo_ros_planar_move's ``Reset()``: command zero, odometry from the new pose."""
        del data, now_ns
        self._target = (0.0, 0.0, 0.0)
        self._last_pose = None

    def _on_cmd_vel(self, msg: Twist) -> None:
        values = (float(msg.linear.x), float(msg.linear.y), float(msg.angular.z))
        vx, vy, wz = (v if math.isfinite(v) else 0.0 for v in values)
        self._target = (vx, vy, wz)
        self._last_cmd_ns = self._now_ns

    def control(self, data: mujoco.MjData, now_ns: int) -> None:
        """Set the model's velocity when an update is due; publish the odometry when due."""
        self._now_ns = now_ns
        timeout = self.spec.cmd_timeout
        if timeout >= 0.0 and (now_ns - self._last_cmd_ns) * 1e-9 > timeout:
            self._target = (0.0, 0.0, 0.0)
        state = self._body.read(data)
        if self.spec.ros_version == 1 and self._last_pose is None:
            self._last_pose = (now_ns, np.array(state.position), yaw_from_matrix(state.rotation))
        if self._update.due(now_ns):
            vx, vy, wz = self._target
            yaw = yaw_from_matrix(state.rotation)
            c, s = math.cos(yaw), math.sin(yaw)
            dof = self._dof
            data.qvel[dof : dof + 3] = (vx * c - vy * s, vy * c + vx * s, 0.0)
            # MuJoCo's free joint takes the angular velocity in the body frame
            data.qvel[dof + 3 : dof + 6] = state.rotation.T @ np.array([0.0, 0.0, wz])
        if (self._odom is not None or self._tf is not None) and self._publish.due(now_ns):
            self._publish_odometry(state.position, state.rotation, state.linear,
                                   state.angular, now_ns)  # fmt: skip

    def _publish_odometry(
        self,
        position: np.ndarray,
        rotation: np.ndarray,
        linear: np.ndarray,
        angular: np.ndarray,
        now_ns: int,
    ) -> None:
        spec = self.spec
        yaw = yaw_from_matrix(rotation)
        quat = _quaternion(matrix_to_quat_xyzw(rotation))
        header = _header(now_ns, spec.odometry_frame)
        pos = np.asarray(position, dtype=np.float64)
        if spec.ros_version == 1:
            # the pose change since the previous message, the yaw rate from the yaw change
            last = self._last_pose
            if last is None or now_ns <= last[0]:
                velocity = np.zeros(3)
                yaw_rate = 0.0
            else:
                dt = (now_ns - last[0]) * 1e-9
                velocity = (pos - last[1]) / dt
                turn = (yaw - last[2] + math.pi) % (2.0 * math.pi) - math.pi
                yaw_rate = turn / dt
            self._last_pose = (now_ns, pos.copy(), yaw)
            odom_pos = (float(pos[0]), float(pos[1]), 0.0)
        else:
            velocity = np.asarray(linear, dtype=np.float64)
            yaw_rate = float(angular[2])
            odom_pos = (float(pos[0]), float(pos[1]), float(pos[2]))
        c, s = math.cos(yaw), math.sin(yaw)
        twist = Twist(
            linear=_vector((c * velocity[0] + s * velocity[1], c * velocity[1] - s * velocity[0],
                            0.0)),
            angular=_vector((0.0, 0.0, yaw_rate)),
        )  # fmt: skip
        if self._odom is not None:
            self._odom.publish(
                Odometry(
                    header=header,
                    child_frame_id=spec.robot_base_frame,
                    pose=PoseWithCovariance(
                        pose=Pose(position=Point(*odom_pos), orientation=quat),
                        covariance=self._pose_cov.copy(),
                    ),
                    twist=TwistWithCovariance(twist=twist, covariance=self._twist_cov.copy()),
                )
            )
        if self._tf is not None:
            self._tf.send_transform(
                TransformStamped(
                    header=header,
                    child_frame_id=spec.robot_base_frame,
                    transform=Transform(translation=_vector(pos), rotation=quat),
                )
            )


def skid_steer_as_diff_drive(skid: SkidSteerSpec) -> DiffDriveSpec:
    """The skid steer as a two-pair diff drive (front pair, then rear), world odometry."""
    return DiffDriveSpec(
        plugin_name=skid.plugin_name,
        left_joints=(skid.left_front_joint, skid.left_rear_joint),
        right_joints=(skid.right_front_joint, skid.right_rear_joint),
        wheel_separation=(skid.wheel_separation, skid.wheel_separation),
        wheel_diameter=(skid.wheel_diameter, skid.wheel_diameter),
        max_wheel_acceleration=0.0,
        max_wheel_torque=skid.torque,
        command_topic=skid.command_topic,
        odometry_topic=skid.odometry_topic,
        odometry_frame=skid.odometry_frame,
        robot_base_frame=skid.robot_base_frame,
        publish_odom=True,
        publish_odom_tf=skid.broadcast_tf,
        odometry_source="world",
        update_rate=skid.update_rate,
        covariance=skid.covariance,
        ros_version=1,
    )


def make_skid_steer(build: RobotBuild, skid: SkidSteerSpec) -> SimPlugin:
    """``libgazebo_ros_skid_steer_drive.so``: four wheels, ``cmd_vel`` in, odometry out."""
    spec, controller = diff_drive_controller(build, skid_steer_as_diff_drive(skid))
    return SkidSteerPlugin(build.node(skid.plugin_name), spec, controller)


def make_planar_move(build: RobotBuild, planar: PlanarMoveSpec) -> SimPlugin:
    """``libgazebo_ros_planar_move.so``: ``cmd_vel`` sets the floating model's velocity.

    Raises:
        SimulatorError: the robot's root link is fixed to the world (nothing to move).
    """
    free = build.handles.free_joint
    if free is None:
        msg = (
            f"robot {build.name!r}: libgazebo_ros_planar_move.so plugin "
            f"{planar.plugin_name!r} moves the whole model, but its root link is fixed to the "
            "world; remove the URDF joint to 'world' so the robot floats"
        )
        raise SimulatorError(msg)
    model = build.model
    spec = replace(
        planar,
        command_topic=build.push(planar.command_topic) or planar.command_topic,
        odometry_topic=build.push(planar.odometry_topic) or planar.odometry_topic,
        odometry_frame=build.frame(planar.odometry_frame),
        robot_base_frame=build.frame(planar.robot_base_frame),
    )
    return PlanarMovePlugin(
        build.node(planar.plugin_name),
        spec,
        model,
        body=model.body(build.handles.root_body).id,
        dof=int(model.joint(free).dofadr[0]),
    )
