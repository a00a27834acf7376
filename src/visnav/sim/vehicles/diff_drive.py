"""Differential drive with the semantics of Gazebo's ``libgazebo_ros_diff_drive.so``.

The plugin's behaviour (ROS 2 ``gazebo_plugins``), reproduced here on MuJoCo:

* ``cmd_vel`` sets targets ``linear.x`` (m/s) and ``angular.z`` (rad/s); each
  wheel pair's desired rim speeds are ``v -/+ w * wheel_separation / 2`` (left /
  right), and the wheel joints get velocity targets ``speed / (wheel_diameter / 2)``
  with their force capped at ``max_wheel_torque``;
* targets change only at ``update_rate``; with ``max_wheel_acceleration`` > 0 the
  instructed rim speed moves towards the desired one by at most
  ``max_wheel_acceleration * dt`` (m/s^2) per update, and jumps to it once both
  measured wheel speeds are within 0.01 m/s;
* odometry ``odometry_frame -> robot_base_frame``: ``odometry_source`` ``world``
  is the robot's world pose and velocity (the twist rotated into the base frame
  by yaw; the odom frame is the world origin), ``encoder`` integrates the first
  wheel pair every physics step (the odom frame is where the robot started);
  covariances are ``covariance_x``, ``covariance_y``, ``covariance_yaw`` on the
  diagonal and 1e12 for z, roll and pitch.

Encoder odometry can carry the errors of real wheels (visnav's plugin elements
``wheel_radius_error``, ``wheel_separation_error``, ``wheel_slip``,
``encoder_resolution``; see :mod:`visnav.sim.noise_models`): the encoder angles are
quantised to ticks, each wheel's travel is scaled by its effective-radius factor and
gets distance-proportional slip noise, and the heading uses the effective separation.
The generator is seeded (``seed``), so one seed gives one odometry.

Gazebo drives the wheels with ODE joint velocity motors (``vel`` and ``fmax``):
a constraint that reaches the target velocity within one step unless that needs
more than ``max_wheel_torque``. visnav approximates it with a torque computed
every physics step: a PI velocity servo whose proportional part
``0.9 * I * (omega_target - omega) / dt`` is the one-step correction of the
joint's inertia ``I`` (MuJoCo ``dof_M0``, armature included) and whose integral
part (0.05 s) removes the steady error under load; the sum is clipped to
+-``max_wheel_torque`` (no windup) and applied through ``qfrc_applied``, with its
reaction on the chassis. No actuators are needed in the model, so any URDF loaded
by :mod:`visnav.sim.robot` works, and a high torque limit cannot make the wheels
chatter as a stiff force-limited MuJoCo velocity actuator does.

A frictionless caster (``<mu1>0</mu1>`` in Gazebo) needs the caster geom's
friction to win MuJoCo's contact mixing (MuJoCo takes the larger friction of the
two geoms unless one has a higher ``priority``): give it ``priority`` 1 and
``condim`` 1, or the caster drags.

Where visnav differs, and why:

* the instructed speed ramps from its own previous value, not by
  ``desired - measured`` added on top of it: Gazebo's form winds up (overshoots)
  whenever the torque limit holds the wheel back;
* encoder odometry integrates joint *angle* increments (what an encoder
  measures) rather than joint velocity times the step, and keeps the sign of
  ``linear.x`` when reversing (the ROS 2 plugin reports ``|v|``);
* once the wheels reach the desired speed the instructed speed is set to it
  (the plugin leaves its ramp state stale, so the next ramp starts from an old
  value);
* a non-finite ``cmd_vel`` component is read as 0 (a stop), not passed to the joints.

``legacy_mode`` (ROS 1 ``<legacyMode>``, read by the kinetic plugin only) swaps the signs
of the turn as that plugin did: ``v + w * b / 2`` on the left wheel, ``v - w * b / 2`` on
the right, and the encoder heading integrates ``sl - sr``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal, Protocol

import numpy as np

from visnav.description.noise_specs import WheelOdometryNoise
from visnav.sim.errors import DiffDriveError
from visnav.sim.noise_models import WheelEncoderModel
from visnav.sim.sensor_timing import SensorClock
from visnav.sim.vehicles._state import BodyReader
from visnav.sim.vehicles.servo import VelocityServo
from visnav.tf.transforms import yaw_from_quaternion

if TYPE_CHECKING:
    from collections.abc import Sequence

    import mujoco
    import numpy.typing as npt

    from visnav.msgs import Odometry, TransformStamped
    from visnav.sim.rebind import IdMap

__all__ = [
    "DiffDriveConfig",
    "DiffDriveController",
    "DiffDriveError",
    "DiffDriveOdometry",
    "DiffDriveParameters",
    "EncoderOdometry",
]

_REACHED_TOLERANCE = 0.01  # m/s, as in the plugin
_UNKNOWN_COVARIANCE = 1.0e12


class DiffDriveParameters(Protocol):
    """What the controller reads; ``visnav.description.gazebo.DiffDriveSpec`` satisfies it."""

    @property
    def left_joints(self) -> tuple[str, ...]:
        """Left wheel joints, one per pair."""
        ...

    @property
    def right_joints(self) -> tuple[str, ...]:
        """Right wheel joints, one per pair."""
        ...

    @property
    def wheel_separation(self) -> tuple[float, ...]:
        """Wheel separation of each pair (m)."""
        ...

    @property
    def wheel_diameter(self) -> tuple[float, ...]:
        """Wheel diameter of each pair (m)."""
        ...

    @property
    def max_wheel_acceleration(self) -> float:
        """Rim acceleration limit (m/s^2); 0 = none."""
        ...

    @property
    def max_wheel_torque(self) -> float:
        """Wheel torque limit (N m)."""
        ...

    @property
    def odometry_source(self) -> Literal["world", "encoder"]:
        """``world`` or ``encoder``."""
        ...

    @property
    def update_rate(self) -> float:
        """Control and odometry rate (Hz); 0 = every step."""
        ...

    @property
    def odometry_frame(self) -> str:
        """Odometry frame id."""
        ...

    @property
    def robot_base_frame(self) -> str:
        """Odometry child frame id."""
        ...

    @property
    def covariance(self) -> tuple[float, float, float]:
        """Diagonal covariances of x, y and yaw."""
        ...

    @property
    def odometry_noise(self) -> WheelOdometryNoise:
        """Error model of the encoder odometry."""
        ...


@dataclass(frozen=True, kw_only=True)
class DiffDriveConfig:
    """The plugin's parameters (ROS 2 names; one tuple entry per wheel pair).

    Attributes:
        left_joints: Left wheel joints (``<left_joint>``, repeatable).
        right_joints: Right wheel joints (``<right_joint>``).
        wheel_separation: Distance between the wheels of each pair (m).
        wheel_diameter: Wheel diameter of each pair (m).
        max_wheel_acceleration: Rim acceleration limit (m/s^2); 0 = none.
        max_wheel_torque: Joint torque limit (N m).
        odometry_source: ``world`` (ground truth) or ``encoder``.
        update_rate: Control and odometry rate (Hz); 0 = every physics step.
        odometry_frame: Odometry frame id.
        robot_base_frame: Child frame id.
        covariance: ``covariance_x``, ``covariance_y``, ``covariance_yaw``.
        odometry_noise: Error model of the encoder odometry (default: exact).
    """

    left_joints: tuple[str, ...]
    right_joints: tuple[str, ...]
    wheel_separation: tuple[float, ...] = (0.34,)
    wheel_diameter: tuple[float, ...] = (0.15,)
    max_wheel_acceleration: float = 0.0
    max_wheel_torque: float = 5.0
    odometry_source: Literal["world", "encoder"] = "world"
    update_rate: float = 100.0
    odometry_frame: str = "odom"
    robot_base_frame: str = "base_footprint"
    covariance: tuple[float, float, float] = (1e-5, 1e-5, 1e-3)
    odometry_noise: WheelOdometryNoise = field(default_factory=WheelOdometryNoise)


def _check(config: DiffDriveParameters) -> None:
    pairs = len(config.left_joints)
    if pairs == 0 or len(config.right_joints) != pairs:
        msg = (
            f"diff drive: need as many left as right joints (at least one pair), got "
            f"left={list(config.left_joints)} right={list(config.right_joints)}"
        )
        raise DiffDriveError(msg)
    for label, values in (
        ("wheel_separation", config.wheel_separation),
        ("wheel_diameter", config.wheel_diameter),
    ):
        if len(values) != pairs or not all(math.isfinite(v) and v > 0 for v in values):
            msg = f"diff drive: {label} needs {pairs} positive value(s), got {list(values)}"
            raise DiffDriveError(msg)
    if not (math.isfinite(config.max_wheel_torque) and config.max_wheel_torque > 0):
        msg = f"diff drive: max_wheel_torque must be > 0 N m, got {config.max_wheel_torque}"
        raise DiffDriveError(msg)
    if not (math.isfinite(config.max_wheel_acceleration) and config.max_wheel_acceleration >= 0):
        msg = (
            "diff drive: max_wheel_acceleration must be >= 0 m/s^2 (0 = unlimited), "
            f"got {config.max_wheel_acceleration}"
        )
        raise DiffDriveError(msg)
    if not (math.isfinite(config.update_rate) and config.update_rate >= 0):
        msg = f"diff drive: update_rate must be >= 0 Hz, got {config.update_rate}"
        raise DiffDriveError(msg)
    if config.odometry_source not in ("world", "encoder"):
        source = config.odometry_source
        msg = f"diff drive: odometry_source must be 'world' or 'encoder', got {source!r}"
        raise DiffDriveError(msg)


@dataclass(frozen=True, kw_only=True)
class DiffDriveOdometry:
    """One odometry sample, shaped like ``nav_msgs/Odometry``.

    Attributes:
        stamp_ns: Sim time (ns).
        frame_id: ``odometry_frame``.
        child_frame_id: ``robot_base_frame``.
        position: x, y, z (m) in the odometry frame.
        orientation: Quaternion **x, y, z, w** (ROS order).
        linear: Linear velocity in the child frame (m/s).
        angular: Angular velocity (rad/s); z is the yaw rate.
        pose_covariance: Row-major 6 x 6 (x, y, z, roll, pitch, yaw).
        twist_covariance: Row-major 6 x 6.
    """

    stamp_ns: int
    frame_id: str
    child_frame_id: str
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]
    linear: tuple[float, float, float]
    angular: tuple[float, float, float]
    pose_covariance: tuple[float, ...] = field(repr=False)
    twist_covariance: tuple[float, ...] = field(repr=False)

    @property
    def yaw(self) -> float:
        """Heading (rad) from the orientation."""
        return yaw_from_quaternion(self.orientation)

    def to_msg(self) -> Odometry:
        """This sample as a ``nav_msgs/Odometry`` message."""
        from visnav.msgs import (  # noqa: PLC0415
            Header,
            Odometry,
            Point,
            Pose,
            PoseWithCovariance,
            Quaternion,
            Twist,
            TwistWithCovariance,
            Vector3,
        )
        from visnav.msgs.time import ns_to_time  # noqa: PLC0415

        return Odometry(
            header=Header(stamp=ns_to_time(self.stamp_ns), frame_id=self.frame_id),
            child_frame_id=self.child_frame_id,
            pose=PoseWithCovariance(
                pose=Pose(
                    position=Point(*self.position), orientation=Quaternion(*self.orientation)
                ),
                covariance=np.array(self.pose_covariance, dtype=np.float64),
            ),
            twist=TwistWithCovariance(
                twist=Twist(linear=Vector3(*self.linear), angular=Vector3(*self.angular)),
                covariance=np.array(self.twist_covariance, dtype=np.float64),
            ),
        )

    def to_transform(self) -> TransformStamped:
        """The ``frame_id -> child_frame_id`` transform (the odom TF)."""
        from visnav.msgs import Header, Quaternion, Transform, TransformStamped, Vector3  # noqa: PLC0415
        from visnav.msgs.time import ns_to_time  # noqa: PLC0415

        return TransformStamped(
            header=Header(stamp=ns_to_time(self.stamp_ns), frame_id=self.frame_id),
            child_frame_id=self.child_frame_id,
            transform=Transform(
                translation=Vector3(*self.position), rotation=Quaternion(*self.orientation)
            ),
        )


def _covariance(diagonal: Sequence[float]) -> tuple[float, ...]:
    cov = np.zeros(36)
    cx, cy, cyaw = diagonal
    for index, value in zip(
        (0, 7, 14, 21, 28, 35),
        (cx, cy, _UNKNOWN_COVARIANCE, _UNKNOWN_COVARIANCE, _UNKNOWN_COVARIANCE, cyaw),
        strict=True,
    ):
        cov[index] = value
    return tuple(float(v) for v in cov)


class EncoderOdometry:
    """Dead reckoning of a differential drive from wheel angle increments.

    The arc update of Siegwart et al. (2011, p. 337), as in the plugin: with
    rim travel ``sl``, ``sr`` and wheel separation ``b``, the heading advances by
    ``(sr - sl) / b`` and the position by ``(sl + sr) / 2`` along the mid-step
    heading.

    Args:
        wheel_separation: Nominal wheel separation (m).
        wheel_radius: Nominal wheel radius (m).
        model: Errors of real encoders and wheels (None: exact).
    """

    def __init__(
        self,
        wheel_separation: float,
        wheel_radius: float,
        *,
        model: WheelEncoderModel | None = None,
    ) -> None:
        self.model = model
        factor = model.separation_factor if model is not None else 1.0
        self.separation = float(wheel_separation) * factor
        self.radius = float(wheel_radius)
        self.x = 0.0
        self.y = 0.0
        self.theta = 0.0
        self.v = 0.0
        self.w = 0.0
        self._last: tuple[float, float] | None = None

    def reset(self, left_angle: float, right_angle: float) -> None:
        """Restart at the origin from these wheel angles (rad)."""
        self.x = self.y = self.theta = self.v = self.w = 0.0
        self._last = (left_angle, right_angle)

    def restart(self) -> None:
        """Restart at the origin from the wheel angles of the next update."""
        self.x = self.y = self.theta = self.v = self.w = 0.0
        self._last = None

    def update(self, left_angle: float, right_angle: float, dt: float) -> None:
        """Integrate the wheel angles (rad) reached after ``dt`` seconds."""
        model = self.model
        if model is not None:
            left_angle, right_angle = model.read(left_angle), model.read(right_angle)
        if self._last is None:
            self.reset(left_angle, right_angle)
            return
        if model is not None:
            sl = model.travel(0, left_angle - self._last[0], self.radius)
            sr = model.travel(1, right_angle - self._last[1], self.radius)
        else:
            sl = (left_angle - self._last[0]) * self.radius
            sr = (right_angle - self._last[1]) * self.radius
        self._last = (left_angle, right_angle)
        ssum = sl + sr
        sdiff = sr - sl
        heading = self.theta + sdiff / (2.0 * self.separation)
        self.x += 0.5 * ssum * math.cos(heading)
        self.y += 0.5 * ssum * math.sin(heading)
        self.theta += sdiff / self.separation
        if dt > 0:
            self.v = 0.5 * ssum / dt
            self.w = sdiff / self.separation / dt


class DiffDriveController:
    """Drives the wheel joints of a MuJoCo model like the Gazebo plugin.

    Call :meth:`set_command` from the ``cmd_vel`` subscription and :meth:`step`
    before every physics step (it writes the wheel torques into
    ``data.qfrc_applied``); :meth:`step` returns a new odometry sample at
    ``update_rate`` (None in between).

    Args:
        model: The compiled model.
        config: The plugin parameters.
        base_body: MuJoCo name of the body whose pose is the robot's
            (the ``robot_base_frame`` link, for example ``car/base_footprint``).
        prefix: The robot's name prefix in the model (joint names).
        start_ns: Sim time at which the controller starts.
        seed: Seed of the encoder error model (``config.odometry_noise``).

    Raises:
        DiffDriveError: A joint or body is missing, or a parameter is invalid.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        config: DiffDriveParameters,
        *,
        base_body: str,
        prefix: str = "",
        start_ns: int = 0,
        seed: int = 0,
    ) -> None:
        import mujoco  # noqa: PLC0415

        _check(config)
        self.config = config
        self.model = model
        joints = (*config.left_joints, *config.right_joints)
        pairs = len(config.left_joints)
        self._qpos = np.zeros(2 * pairs, dtype=np.int64)
        self._dof = np.zeros(2 * pairs, dtype=np.int64)
        for i, joint in enumerate(joints):
            jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, prefix + joint)
            if jid < 0:
                msg = f"diff drive: joint {prefix + joint!r} is not in the MuJoCo model"
                raise DiffDriveError(msg)
            if model.jnt_type[jid] != mujoco.mjtJoint.mjJNT_HINGE:
                msg = f"diff drive: joint {prefix + joint!r} must be a hinge (continuous) joint"
                raise DiffDriveError(msg)
            self._qpos[i] = model.jnt_qposadr[jid]
            self._dof[i] = model.jnt_dofadr[jid]
        body_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, base_body)
        if body_id < 0:
            msg = f"diff drive: base body {base_body!r} is not in the MuJoCo model"
            raise DiffDriveError(msg)
        self._reader = BodyReader(model, body_id)
        radius = np.asarray(config.wheel_diameter, dtype=np.float64) / 2.0
        self._radius = np.concatenate([radius, radius])  # left wheels, then right wheels
        self._separation = np.asarray(config.wheel_separation, dtype=np.float64)
        self._period_ns = 0 if config.update_rate == 0 else round(1e9 / config.update_rate)
        # drift-free updates at k * period after the start (the first one period in), as
        # the ROS 1 plugin's ``last_update_time_ += update_period_``
        self._clock = SensorClock(config.update_rate, start_ns=int(start_ns) + self._period_ns)
        self._legacy = bool(getattr(config, "legacy_mode", False))
        self._servo = VelocityServo(
            model, self._dof.tolist(), [config.max_wheel_torque] * (2 * pairs)
        )
        self._pose_cov = _covariance(config.covariance)
        self._target = (0.0, 0.0)
        self._instructed = np.zeros(2 * pairs)
        self._last_update_ns = int(start_ns)
        self._last_encoder_ns: int | None = None
        noise = config.odometry_noise
        self.encoder = EncoderOdometry(
            config.wheel_separation[0],
            config.wheel_diameter[0] / 2.0,
            model=WheelEncoderModel(noise, seed=seed) if noise.active else None,
        )
        self.odometry: DiffDriveOdometry | None = None

    def rebind(self, ids: IdMap) -> None:
        """Drive the same joints of a recompiled model; command and odometry are kept."""
        self.model = ids.model
        self._qpos = ids.qpos(self._qpos)
        self._dof = ids.dof(self._dof)
        self._reader.rebind(ids)
        self._servo.rebind(ids)

    def rewind(self, now_ns: int) -> None:
        """Sim time went back to ``now_ns``: the update schedule restarts from it."""
        self._clock.restart(int(now_ns) + self._period_ns)
        self._last_update_ns = int(now_ns)
        self._last_encoder_ns = None

    @property
    def target(self) -> tuple[float, float]:
        """The commanded ``(linear.x, angular.z)``."""
        return self._target

    def set_command(self, linear_x: float, angular_z: float) -> None:
        """Take a ``cmd_vel`` (non-finite values are treated as 0, like a stop)."""
        v = float(linear_x) if math.isfinite(linear_x) else 0.0
        w = float(angular_z) if math.isfinite(angular_z) else 0.0
        self._target = (v, w)

    def reset(self) -> None:
        """Stop and restart the encoder odometry at the origin (``/gazebo/reset_world``).

        As gazebo_ros_diff_drive's ``Reset()``: command, ramp and motor integrator zero.
        """
        self._target = (0.0, 0.0)
        self._instructed[:] = 0.0
        self._servo.reset()
        self._last_encoder_ns = None
        self.encoder.restart()

    def wheel_speeds(self, data: mujoco.MjData) -> npt.NDArray[np.float64]:
        """Measured rim speeds (m/s), left wheels then right wheels."""
        return np.asarray(data.qvel[self._dof] * self._radius)

    def desired_wheel_speeds(self) -> npt.NDArray[np.float64]:
        """Desired rim speeds (m/s) for the current command, left then right."""
        v, w = self._target
        half = self._separation / 2.0
        if self._legacy:  # kinetic's legacyMode: the signs of the turn swapped
            return np.concatenate([v + w * half, v - w * half])
        return np.concatenate([v - w * half, v + w * half])

    def step(self, data: mujoco.MjData, now_ns: int) -> DiffDriveOdometry | None:
        """Advance the controller to ``now_ns``; call it before every physics step.

        Args:
            data: The simulation data (``qfrc_applied`` of the wheel joints is written).
            now_ns: Current sim time in nanoseconds.

        Returns:
            A new odometry sample when an update happened, else None.
        """
        if self.config.odometry_source == "encoder":
            self._update_encoder(data, now_ns)
        due = self._clock.due(now_ns)
        if due:
            self._update(data, now_ns, (now_ns - self._last_update_ns) * 1e-9)
        odometry = self.odometry if due else None
        self._apply_motor(data)
        return odometry

    def _apply_motor(self, data: mujoco.MjData) -> None:
        self._servo.apply(data, (self._instructed / self._radius).tolist())

    def _update(self, data: mujoco.MjData, now_ns: int, dt: float) -> None:
        if self.config.odometry_source == "world":
            self.odometry = self._world_odometry(data, now_ns)
        else:
            self.odometry = self._encoder_odometry(now_ns)
        desired = self.desired_wheel_speeds()
        current = self.wheel_speeds(data)
        accel = self.config.max_wheel_acceleration
        pairs = len(self._separation)
        for i in range(pairs):
            left, right = i, pairs + i
            reached = (
                abs(desired[left] - current[left]) < _REACHED_TOLERANCE
                and abs(desired[right] - current[right]) < _REACHED_TOLERANCE
            )
            for k in (left, right):
                if accel == 0 or reached:
                    self._instructed[k] = desired[k]
                else:
                    change = np.clip(desired[k] - self._instructed[k], -accel * dt, accel * dt)
                    self._instructed[k] += change
        self._last_update_ns = now_ns

    def _update_encoder(self, data: mujoco.MjData, now_ns: int) -> None:
        pairs = len(self._separation)
        left = float(data.qpos[self._qpos[0]])
        right = float(data.qpos[self._qpos[pairs]])
        dt = 0.0 if self._last_encoder_ns is None else (now_ns - self._last_encoder_ns) * 1e-9
        if self._legacy:  # kinetic's legacyMode integrates sl - sr as the heading change
            left, right = right, left
        self.encoder.update(left, right, dt)
        self._last_encoder_ns = now_ns

    def _encoder_odometry(self, now_ns: int) -> DiffDriveOdometry:
        e = self.encoder
        half = 0.5 * e.theta
        return DiffDriveOdometry(
            stamp_ns=now_ns,
            frame_id=self.config.odometry_frame,
            child_frame_id=self.config.robot_base_frame,
            position=(e.x, e.y, 0.0),
            orientation=(0.0, 0.0, math.sin(half), math.cos(half)),
            linear=(e.v, 0.0, 0.0),
            angular=(0.0, 0.0, e.w),
            pose_covariance=self._pose_cov,
            twist_covariance=self._pose_cov,
        )

    def _world_odometry(self, data: mujoco.MjData, now_ns: int) -> DiffDriveOdometry:
        body = self._reader.read(data)
        pos, angular, linear = body.position, body.angular, body.linear
        w, x, y, z = (float(v) for v in body.quat_wxyz)  # MuJoCo order w, x, y, z
        yaw = yaw_from_quaternion((x, y, z, w))
        c, s = math.cos(yaw), math.sin(yaw)
        return DiffDriveOdometry(
            stamp_ns=now_ns,
            frame_id=self.config.odometry_frame,
            child_frame_id=self.config.robot_base_frame,
            position=(float(pos[0]), float(pos[1]), float(pos[2])),
            orientation=(x, y, z, w),
            linear=(
                c * linear[0] + s * linear[1],
                c * linear[1] - s * linear[0],
                0.0,
            ),
            angular=(0.0, 0.0, float(angular[2])),
            pose_covariance=self._pose_cov,
            twist_covariance=self._pose_cov,
        )
