"""ros_control controllers run by :mod:`visnav.sim.ros_control`: the algorithms and their topics.

* ``diff_drive_controller/DiffDriveController`` (ros_controllers, Noetic):
  ``<controller>/cmd_vel`` (``geometry_msgs/Twist``) in; ``<controller>/odom``
  (``nav_msgs/Odometry``), ``odom_frame_id -> base_frame_id`` on ``/tf`` with
  ``enable_odom_tf`` and ``<controller>/cmd_vel_out`` (``TwistStamped``, the limited
  command) with ``publish_cmd``. Every control update: the odometry integrates the mean
  left and right wheel angle increments (:class:`WheelOdometry`, odometry.cpp's exact
  arc integration, velocities as a rolling mean over ``velocity_rolling_window_size``
  updates); an odometry message is due when ``last + 1 / publish_rate < now`` (then
  ``last += 1 / publish_rate``); a command older than ``cmd_vel_timeout`` becomes a stop;
  :class:`SpeedLimiter` applies the jerk, acceleration and velocity limits of
  ``linear/x`` and ``angular/z``; each wheel gets the velocity command
  ``(v -/+ w * ws / 2) / r`` with ``ws = wheel_separation * wheel_separation_multiplier``
  and ``r = wheel_radius * (left|right)_wheel_radius_multiplier``.
* ``joint_state_controller/JointStateController``: ``joint_states`` in the controller
  manager's namespace at ``publish_rate``, the hardware interface's joints (every
  transmission) sorted by name as ros_control's resource manager lists them, or the
  ``joints`` parameter's order; position, velocity and effort.

Where visnav differs: commands and messages use sim time (the stamp of a command is the
sim time of the step it arrived in); ``publish_wheel_joint_controller_state`` and the
dynamic_reconfigure server are not provided (the parameters are read once);
``extra_joints`` of the JointStateController are not published.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.msgs.time import ns_to_time
from visnav.msgs.types import (
    Header,
    JointState,
    Odometry,
    Point,
    Pose,
    PoseWithCovariance,
    Quaternion,
    Transform,
    TransformStamped,
    Twist,
    TwistStamped,
    TwistWithCovariance,
    Vector3,
)
from visnav.tf.ros import TransformBroadcaster

if TYPE_CHECKING:
    from collections.abc import Sequence

    import mujoco

    from visnav.graph.node import Node
    from visnav.sim.ros_control import RobotHWSim

__all__ = [
    "DiffDriveControllerConfig",
    "DiffDriveRosController",
    "JointStateRosController",
    "SpeedLimiter",
    "WheelOdometry",
]

_QOS = 10


@dataclass(frozen=True)
class SpeedLimiter:
    """diff_drive_controller's ``SpeedLimiter`` for one axis (``linear/x`` or ``angular/z``).

    A ``min_*`` of None is ``-max_*`` (the controller's default).
    """

    has_velocity_limits: bool = False
    has_acceleration_limits: bool = False
    has_jerk_limits: bool = False
    max_velocity: float = 0.0
    min_velocity: float | None = None
    max_acceleration: float = 0.0
    min_acceleration: float | None = None
    max_jerk: float = 0.0
    min_jerk: float | None = None

    def limit(self, v: float, v0: float, v1: float, dt: float) -> float:
        """The command ``v`` limited given the last two commands ``v0``, ``v1`` and ``dt`` (s)."""
        if self.has_jerk_limits:
            low = -self.max_jerk if self.min_jerk is None else self.min_jerk
            dv, dv0, dt2 = v - v0, v0 - v1, 2.0 * dt * dt
            v = v0 + dv0 + min(max(dv - dv0, low * dt2), self.max_jerk * dt2)
        if self.has_acceleration_limits:
            low = -self.max_acceleration if self.min_acceleration is None else self.min_acceleration
            v = v0 + min(max(v - v0, low * dt), self.max_acceleration * dt)
        if self.has_velocity_limits:
            low = -self.max_velocity if self.min_velocity is None else self.min_velocity
            v = min(max(v, low), self.max_velocity)
        return v


class WheelOdometry:
    """diff_drive_controller's odometry from wheel angles (rad).

    Args:
        separation: wheel separation (m, multiplier applied).
        left_radius: left wheel radius (m, multiplier applied).
        right_radius: right wheel radius (m).
        window: velocity rolling-mean window (updates).
    """

    def __init__(
        self, separation: float, left_radius: float, right_radius: float, *, window: int = 10
    ) -> None:
        self.separation = separation
        self.left_radius = left_radius
        self.right_radius = right_radius
        self.x = 0.0
        self.y = 0.0
        self.heading = 0.0
        self.linear = 0.0
        self.angular = 0.0
        self._left_old = 0.0
        self._right_old = 0.0
        self._stamp_ns = 0
        self._lin: deque[float] = deque(maxlen=max(1, window))
        self._ang: deque[float] = deque(maxlen=max(1, window))

    def init(self, now_ns: int) -> None:
        """Start (``starting``): clear the velocity windows, take ``now_ns`` as the last time."""
        self._lin.clear()
        self._ang.clear()
        self._stamp_ns = now_ns

    def _integrate(self, linear: float, angular: float) -> None:
        if abs(angular) < 1e-6:  # second-order Runge-Kutta
            direction = self.heading + 0.5 * angular
            self.x += linear * math.cos(direction)
            self.y += linear * math.sin(direction)
            self.heading += angular
            return
        old = self.heading
        r = linear / angular
        self.heading += angular
        self.x += r * (math.sin(self.heading) - math.sin(old))
        self.y += -r * (math.cos(self.heading) - math.cos(old))

    def update(self, left_pos: float, right_pos: float, now_ns: int) -> bool:
        """Integrate the wheel angles (rad) read at ``now_ns``; False when dt < 0.1 ms.

        As odometry.cpp, the first call integrates the whole angle from 0 (the wheels'
        start position counts as travel when it is not 0).
        """
        left = left_pos * self.left_radius
        right = right_pos * self.right_radius
        dl, dr = left - self._left_old, right - self._right_old
        self._left_old, self._right_old = left, right
        linear = 0.5 * (dl + dr)
        angular = (dr - dl) / self.separation
        self._integrate(linear, angular)
        dt = (now_ns - self._stamp_ns) * 1e-9
        if dt < 0.0001:
            return False
        self._stamp_ns = now_ns
        self._lin.append(linear / dt)
        self._ang.append(angular / dt)
        self.linear = sum(self._lin) / len(self._lin)
        self.angular = sum(self._ang) / len(self._ang)
        return True

    def update_open_loop(self, linear: float, angular: float, now_ns: int) -> None:
        """Integrate the commanded velocities (``open_loop``)."""
        self.linear, self.angular = linear, angular
        dt = (now_ns - self._stamp_ns) * 1e-9
        self._stamp_ns = now_ns
        self._integrate(linear * dt, angular * dt)


@dataclass(frozen=True, kw_only=True)
class DiffDriveControllerConfig:
    """The parameters of a ``diff_drive_controller/DiffDriveController`` (ROS names).

    ``wheel_separation`` and ``wheel_radius`` None: taken from the URDF (the first
    wheel pair's joint origins and the left wheel's collision cylinder or sphere).
    """

    left_wheel: tuple[str, ...]
    right_wheel: tuple[str, ...]
    publish_rate: float = 50.0
    open_loop: bool = False
    wheel_separation_multiplier: float = 1.0
    left_wheel_radius_multiplier: float = 1.0
    right_wheel_radius_multiplier: float = 1.0
    velocity_rolling_window_size: int = 10
    cmd_vel_timeout: float = 0.5
    allow_multiple_cmd_vel_publishers: bool = True
    base_frame_id: str = "base_link"
    odom_frame_id: str = "odom"
    enable_odom_tf: bool = True
    publish_cmd: bool = False
    wheel_separation: float | None = None
    wheel_radius: float | None = None
    pose_covariance_diagonal: tuple[float, ...] = (0.0,) * 6
    twist_covariance_diagonal: tuple[float, ...] = (0.0,) * 6
    linear: SpeedLimiter = field(default_factory=SpeedLimiter)
    angular: SpeedLimiter = field(default_factory=SpeedLimiter)


def _diagonal(values: Sequence[float]) -> np.ndarray[Any, np.dtype[np.float64]]:
    cov = np.zeros(36)
    cov[[0, 7, 14, 21, 28, 35]] = values
    return cov


class DiffDriveRosController:
    """A running ``diff_drive_controller/DiffDriveController`` (see the module docstring).

    Args:
        node: the controller manager's node (topics are created on it).
        name: the controller's name.
        topic_ns: ``<controller manager namespace>/<name>``.
        config: its parameters.
        hw: the robot hardware (velocity command handles of the wheels).
        separation: wheel separation (m) before the multiplier.
        radius: wheel radius (m) before the multipliers.
        frame: the robot's frame prefix function (visnav's ``frame_prefix``).
    """

    def __init__(
        self,
        node: Node,
        name: str,
        topic_ns: str,
        config: DiffDriveControllerConfig,
        hw: RobotHWSim,
        *,
        separation: float,
        radius: float,
        frame: Any = None,
    ) -> None:
        self.name = name
        self.config = config
        self.hw = hw
        self.node = node
        self._left = [hw.index(j) for j in config.left_wheel]
        self._right = [hw.index(j) for j in config.right_wheel]
        c = config
        self.separation = c.wheel_separation_multiplier * separation
        self.left_radius = c.left_wheel_radius_multiplier * radius
        self.right_radius = c.right_wheel_radius_multiplier * radius
        self.odometry = WheelOdometry(
            self.separation, self.left_radius, self.right_radius,
            window=c.velocity_rolling_window_size,
        )  # fmt: skip
        self._period_ns = round(1e9 / c.publish_rate) if c.publish_rate > 0 else 0
        self._last_publish_ns = 0
        self._command = (0.0, 0.0, -(2**62))  # lin, ang, stamp (ns): none yet
        self._last0 = (0.0, 0.0)
        self._last1 = (0.0, 0.0)
        self._now_ns = 0
        odom_frame = frame(c.odom_frame_id) if frame is not None else c.odom_frame_id
        base_frame = frame(c.base_frame_id) if frame is not None else c.base_frame_id
        self._frames = (odom_frame, base_frame)
        self._pose_cov = _diagonal(c.pose_covariance_diagonal)
        self._twist_cov = _diagonal(c.twist_covariance_diagonal)
        self.cmd_vel_topic = f"{topic_ns}/cmd_vel"
        self.odom_topic = f"{topic_ns}/odom"
        self._odom_pub = node.create_publisher(Odometry, self.odom_topic, _QOS)
        self._tf = TransformBroadcaster(node) if c.enable_odom_tf else None
        self._cmd_out = (
            node.create_publisher(TwistStamped, f"{topic_ns}/cmd_vel_out", _QOS)
            if c.publish_cmd
            else None
        )
        self._sub = node.create_subscription(Twist, self.cmd_vel_topic, self._on_cmd_vel, 1)
        self.running = False

    def _on_cmd_vel(self, msg: Twist) -> None:
        if not self.running:
            self.node.get_logger().error(
                f"{self.cmd_vel_topic}: can't accept new commands: controller {self.name!r} is "
                "not running (spawned --stopped)",
                throttle_duration_sec=1.0,
            )
            return
        lin, ang = float(msg.linear.x), float(msg.angular.z)
        if not (math.isfinite(lin) and math.isfinite(ang)):
            self.node.get_logger().warning(
                f"{self.cmd_vel_topic}: received NaN in velocity command; ignoring",
                throttle_duration_sec=1.0,
            )
            return
        if not self.config.allow_multiple_cmd_vel_publishers:
            publishers = self.node.count_publishers(self.cmd_vel_topic)
            if publishers > 1:
                self.node.get_logger().error(
                    f"{self.cmd_vel_topic}: detected {publishers} publishers, only 1 is "
                    "allowed (allow_multiple_cmd_vel_publishers false); braking",
                    throttle_duration_sec=1.0,
                )
                self._command = (0.0, 0.0, self._now_ns)
                return
        self._command = (lin, ang, self._now_ns)

    def starting(self, now_ns: int) -> None:
        """Brake, reset the publish time and the odometry's time."""
        self.running = True
        self._brake()
        self._now_ns = now_ns
        self._last_publish_ns = now_ns
        self.odometry.init(now_ns)

    def stopping(self) -> None:
        """Brake."""
        self.running = False
        self._brake()

    def _brake(self) -> None:
        for i in (*self._left, *self._right):
            self.hw.command[i] = 0.0

    def update(self, data: mujoco.MjData, now_ns: int, period_ns: int) -> None:
        """One control update at ``now_ns`` (``period_ns`` since the previous one)."""
        self._now_ns = now_ns
        c, odom = self.config, self.odometry
        if c.open_loop:
            odom.update_open_loop(self._last0[0], self._last0[1], now_ns)
        else:
            pos = self.hw.positions(data)
            left = float(np.mean(pos[self._left]))
            right = float(np.mean(pos[self._right]))
            if math.isnan(left) or math.isnan(right):
                return
            odom.update(left, right, now_ns)
        if self._period_ns and self._last_publish_ns + self._period_ns < now_ns:
            self._last_publish_ns += self._period_ns
            self._publish(now_ns)
        lin, ang, stamp_ns = self._command
        if (now_ns - stamp_ns) * 1e-9 > c.cmd_vel_timeout:
            lin = ang = 0.0
        dt = period_ns * 1e-9
        lin = c.linear.limit(lin, self._last0[0], self._last1[0], dt)
        ang = c.angular.limit(ang, self._last0[1], self._last1[1], dt)
        self._last1 = self._last0
        self._last0 = (lin, ang)
        if self._cmd_out is not None:
            self._cmd_out.publish(
                TwistStamped(
                    header=Header(stamp=ns_to_time(now_ns), frame_id=""),
                    twist=Twist(
                        linear=Vector3(x=lin, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=ang)
                    ),
                )
            )
        half = ang * self.separation / 2.0
        vel_left = (lin - half) / self.left_radius
        vel_right = (lin + half) / self.right_radius
        for i in self._left:
            self.hw.command[i] = vel_left
        for i in self._right:
            self.hw.command[i] = vel_right

    def _publish(self, now_ns: int) -> None:
        odom = self.odometry
        half = 0.5 * odom.heading
        quat = Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))
        header = Header(stamp=ns_to_time(now_ns), frame_id=self._frames[0])
        self._odom_pub.publish(
            Odometry(
                header=header,
                child_frame_id=self._frames[1],
                pose=PoseWithCovariance(
                    pose=Pose(position=Point(x=odom.x, y=odom.y, z=0.0), orientation=quat),
                    covariance=self._pose_cov.copy(),
                ),
                twist=TwistWithCovariance(
                    twist=Twist(
                        linear=Vector3(x=odom.linear, y=0.0, z=0.0),
                        angular=Vector3(x=0.0, y=0.0, z=odom.angular),
                    ),
                    covariance=self._twist_cov.copy(),
                ),
            )
        )
        if self._tf is not None:
            self._tf.send_transform(
                TransformStamped(
                    header=header,
                    child_frame_id=self._frames[1],
                    transform=Transform(
                        translation=Vector3(x=odom.x, y=odom.y, z=0.0), rotation=quat
                    ),
                )
            )


class JointStateRosController:
    """A running ``joint_state_controller/JointStateController``.

    Args:
        node: the controller manager's node.
        topic: ``<controller manager namespace>/joint_states``.
        hw: the robot hardware.
        joints: the published joints, in order.
        publish_rate: Hz (0: never publishes, as the controller).
    """

    def __init__(
        self,
        node: Node,
        topic: str,
        hw: RobotHWSim,
        joints: Sequence[str],
        *,
        publish_rate: float,
    ) -> None:
        self.hw = hw
        self.topic = topic
        self.joints = tuple(joints)
        self._index = np.array([hw.index(j) for j in joints], dtype=np.int64)
        self._period_ns = round(1e9 / publish_rate) if publish_rate > 0 else 0
        self._last_ns: int | None = None
        self._pub = node.create_publisher(JointState, topic, _QOS)

    def starting(self, now_ns: int) -> None:
        """Publish in the first update (the last publish is set 1.001 periods back)."""
        if self._last_ns is None:
            self._last_ns = now_ns - round(1.001 * self._period_ns)

    def stopping(self) -> None:
        """Nothing to do."""

    def update(self, data: mujoco.MjData, now_ns: int, period_ns: int) -> None:
        """Publish when ``last + 1 / publish_rate < now`` (then ``last += 1 / publish_rate``)."""
        del period_ns
        if not self._period_ns or self._last_ns is None:
            return
        if self._last_ns + self._period_ns >= now_ns:
            return
        self._last_ns += self._period_ns
        i = self._index
        self._pub.publish(
            JointState(
                header=Header(stamp=ns_to_time(now_ns), frame_id=""),
                name=list(self.joints),
                position=np.asarray(self.hw.positions(data)[i], dtype=np.float64),
                velocity=np.asarray(self.hw.velocities(data)[i], dtype=np.float64),
                effort=np.asarray(self.hw.efforts(data)[i], dtype=np.float64),
            )
        )
