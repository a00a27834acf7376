"""The simulator's Gazebo-style sensors and plugins on the graph: one node each.

Each class wires one parsed ``<gazebo>`` block (:mod:`visnav.description.gazebo`) to
topics the way its ``gazebo_ros`` plugin does; :class:`~visnav.sim.simulator.Simulator`
creates them. Per physics step ``k`` (sim time ``t = k * dt``) the simulator calls,
in this order:

1. :meth:`SimPlugin.sense` after ``mj_step1``: kinematics and position / velocity
   sensors describe time ``t`` (cameras, p3d, joint states);
2. :meth:`SimPlugin.control`: controllers read the state at ``t`` and write forces
   (diff drive, quadrotor); the diff drive's odometry is stamped ``t``;
3. the simulator spins the context, so in-process nodes react at sim time ``t``;
4. :meth:`SimPlugin.after_step` after ``mj_step2``: acceleration-stage sensors
   (the IMU's accelerometer) describe ``t``.

Every message is stamped with sim time; each sensor fires at its own
``update_rate`` on a drift-free :class:`~visnav.sim.sensor_timing.SensorClock`.

QoS: every publisher is reliable, keep-last (depth 5 for sensor data, 10
otherwise), which feeds reliable and best-effort subscriptions alike. (gazebo_ros
uses best-effort ``SensorDataQoS`` for the IMU, which default-QoS subscribers
never receive.)
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import mujoco
import numpy as np

from visnav.description.rigid import matrix_to_quat_xyzw, quat_xyzw_to_matrix, rpy_to_matrix
from visnav.graph.qos import QoSProfile
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import (
    CameraInfo,
    Header,
    Image,
    Imu,
    JointState,
    Odometry,
    Point,
    PointCloud2,
    Pose,
    PoseWithCovariance,
    Quaternion,
    Transform,
    TransformStamped,
    Twist,
    TwistWithCovariance,
    Vector3,
)
from visnav.sim.sensor_timing import SensorClock
from visnav.sim.vehicles._state import BodyReader
from visnav.tf.ros import TransformBroadcaster

if TYPE_CHECKING:
    from collections.abc import Sequence

    from numpy.typing import NDArray

    from visnav.description.gazebo_specs import (
        CameraSpec,
        DiffDriveSpec,
        GaussianNoise,
        ImuSpec,
        JointStatePublisherSpec,
        OdometrySpec,
    )
    from visnav.graph.node import Node
    from visnav.sim.camera import CameraSensor
    from visnav.sim.rebind import IdMap
    from visnav.sim.vehicles.diff_drive import DiffDriveController
    from visnav.tf.robot_state import RobotStateModel

__all__ = [
    "DEFAULT_QOS",
    "SENSOR_QOS",
    "CameraPlugin",
    "DiffDrivePlugin",
    "ImuPlugin",
    "JointStatePlugin",
    "OdometryPlugin",
    "SimPlugin",
]

SENSOR_QOS = QoSProfile(depth=5)
DEFAULT_QOS = QoSProfile(depth=10)


def _header(stamp_ns: int, frame_id: str) -> Header:
    return Header(stamp=ns_to_time(stamp_ns), frame_id=frame_id)


def _quaternion(q: Sequence[float]) -> Quaternion:
    return Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))


def _vector(v: Sequence[float] | NDArray[np.float64]) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


class SimPlugin:
    """One sensor or plugin of a robot, with its graph node; hooks default to no-ops.

    Attributes:
        node: the plugin's node (destroyed by :meth:`close`).
        name: a label for statistics and messages.
    """

    def __init__(self, node: Node, name: str) -> None:
        self.node = node
        self.name = name

    def sense(self, data: mujoco.MjData, now_ns: int) -> None:
        """Measure the state at ``now_ns`` (after ``mj_step1``)."""

    def control(self, data: mujoco.MjData, now_ns: int) -> None:
        """Apply controls for the step starting at ``now_ns``."""

    def after_step(self, data: mujoco.MjData, now_ns: int) -> None:
        """Read acceleration-stage sensors of ``now_ns`` (after ``mj_step2``)."""

    def reset(self, data: mujoco.MjData, now_ns: int) -> None:
        """Gazebo's plugin ``Reset()`` (``/gazebo/reset_world``): the bodies are back at start."""

    def rewind(self, now_ns: int) -> None:
        """Sim time went back to ``now_ns`` (``/gazebo/reset_simulation``).

        Every :class:`~visnav.sim.sensor_timing.SensorClock` attribute of the plugin
        restarts at ``now_ns``, and so does any attribute object with a ``rewind(now_ns)``
        method (a controller); a plugin that keeps other times overrides this.
        """
        for value in vars(self).values():
            if isinstance(value, SensorClock):
                value.restart(now_ns)
            elif callable(getattr(value, "rewind", None)) and value is not self:
                value.rewind(now_ns)

    def rebind(self, ids: IdMap) -> None:
        """Move onto a recompiled model (a model was spawned or deleted; :mod:`visnav.sim.rebind`).

        A plugin that keeps MuJoCo ids, addresses or the model overrides this and takes
        the new ones from ``ids``; its own state (schedules, commands, odometry, noise)
        stays as it was. The default keeps nothing model-specific.
        """

    def close(self) -> None:
        """Destroy the node."""
        self.node.destroy_node()


class _Noise:
    """Gazebo's ``GaussianNoiseModel``: a bias drawn once (random sign), plus N(mean, std)."""

    def __init__(self, noise: GaussianNoise, rng: np.random.Generator) -> None:
        self.mean = noise.mean
        self.stddev = noise.stddev
        self.active = noise.active
        bias = float(rng.normal(noise.bias_mean, noise.bias_stddev)) if noise.active else 0.0
        self.bias = -bias if noise.active and rng.uniform() < 0.5 else bias

    def apply(self, value: float, rng: np.random.Generator) -> float:
        if not self.active:
            return value
        return value + float(rng.normal(self.mean, self.stddev)) + self.bias


# --------------------------------------------------------------------------- cameras


class CameraPlugin(SimPlugin):
    """``libgazebo_ros_camera.so`` (and the depth plugins): renders when due and publishes.

    An image and its camera_info share one header (stamp and frame_id). Rendering
    happens only at the sensor's update rate (0: every step), further throttled by the
    ROS 1 plugin's ``<updateRate>`` (``plugin_update_rate``: a frame is made only when
    both are due, as gazebo_ros_camera_utils publishes the sensor's frames at most that
    often), and only while something subscribes to
    one of the camera's topics (as gazebo_ros_camera activates its sensor on connect):
    a due frame nobody wants is counted in ``skipped`` and not rendered. Of a frame,
    only the outputs with a subscriber are made (the colour image, the depth image with
    its camera_info, the point cloud; :meth:`CameraSensor.render`): a cloud nobody
    subscribes to is not built.

    Args:
        node: the plugin's node.
        spec: the camera with its final topics and frame.
        sensor: the renderer of ``spec``.
        start_ns: sim time of the first possible frame.
    """

    def __init__(
        self, node: Node, spec: CameraSpec, sensor: CameraSensor, *, start_ns: int = 0
    ) -> None:
        super().__init__(node, spec.name)
        self.spec = spec
        self.sensor = sensor
        self.clock = SensorClock(spec.update_rate, start_ns=start_ns)
        # ROS 1 <updateRate>: publishes the sensor's frames at most this often
        self.throttle = (
            SensorClock(spec.plugin_update_rate, start_ns=start_ns)
            if spec.plugin_update_rate > 0.0
            else None
        )
        self.render_ns = 0
        self.frames = 0
        self.skipped = 0
        self._wanted = (-1, (True, True, True, True))  # version, (any, image, depth, points)

        def pub(msg_type: type[Any], topic: str | None) -> Any:
            return node.create_publisher(msg_type, topic, SENSOR_QOS) if topic else None

        self._image = pub(Image, spec.image_topic) if sensor.render_color else None
        self._info = pub(CameraInfo, spec.camera_info_topic) if sensor.render_color else None
        depth = spec.kind == "depth"
        self._depth = pub(Image, spec.depth_topic) if depth else None
        self._depth_info = pub(CameraInfo, spec.depth_info_topic) if depth else None
        self._points = pub(PointCloud2, spec.points_topic) if depth and spec.pointcloud else None
        self._pubs = [
            p
            for p in (self._image, self._info, self._depth, self._depth_info, self._points)
            if p is not None
        ]

    def _outputs(self) -> tuple[bool, bool, bool, bool]:
        """(any topic, image, depth or its info, points) subscribed; checked on graph changes."""
        version = self.node.context.graph.version
        if version != self._wanted[0]:

            def subscribed(*pubs: Any) -> bool:
                return any(p is not None and p.get_subscription_count() > 0 for p in pubs)

            self._wanted = (
                version,
                (
                    subscribed(*self._pubs),
                    subscribed(self._image),
                    subscribed(self._depth, self._depth_info),
                    subscribed(self._points),
                ),
            )
        return self._wanted[1]

    def wanted(self) -> bool:
        """True when any of the camera's topics has a subscriber (checked on graph changes)."""
        return self._outputs()[0]

    def rebind(self, ids: IdMap) -> None:
        """Render the same camera of a recompiled model (with its new render context)."""
        self.sensor.rebind(ids)

    def sense(self, data: mujoco.MjData, now_ns: int) -> None:
        """Measure at ``now_ns`` when due and wanted, and publish."""
        if not self.clock.due(now_ns):
            return
        if self.throttle is not None and not self.throttle.due(now_ns):
            return
        wanted, image, depth, points = self._outputs()
        if not wanted:
            self.skipped += 1
            return
        start = time.perf_counter_ns()
        frame = self.sensor.render(data, stamp_ns=now_ns, image=image, depth=depth, points=points)
        self.render_ns += time.perf_counter_ns() - start
        self.frames += 1
        if self._image is not None and frame.image is not None:
            self._image.publish(frame.image)
        if self._info is not None:
            self._info.publish(frame.camera_info)
        if self._depth is not None and frame.depth_image is not None:
            self._depth.publish(frame.depth_image)
        if self._depth_info is not None and frame.depth_camera_info is not None:
            self._depth_info.publish(frame.depth_camera_info)
        if self._points is not None and frame.points is not None:
            self._points.publish(frame.points)


# --------------------------------------------------------------------------- IMU


class ImuPlugin(SimPlugin):
    """``libgazebo_ros_imu_sensor.so``: MuJoCo gyro, accelerometer and frame orientation.

    Angular velocity and linear acceleration (including the reaction to gravity,
    +9.81 m/s^2 up at rest, as a real IMU) are in the sensor frame; the orientation
    is the sensor frame's in the world (or relative to the first sample with
    ``initial_orientation_as_reference``). Noise follows Gazebo's gaussian model per
    axis (a bias drawn once, plus white noise); covariances are the noise variances.

    Args:
        node: the plugin's node.
        spec: the IMU with its final topic and frame.
        model: the compiled model.
        sensors: MuJoCo gyro, accelerometer and framequat sensor names.
        rng: the noise generator.
        start_ns: sim time of the first possible sample.
    """

    def __init__(
        self,
        node: Node,
        spec: ImuSpec,
        model: mujoco.MjModel,
        sensors: tuple[str, str, str],
        *,
        rng: np.random.Generator,
        start_ns: int = 0,
    ) -> None:
        super().__init__(node, spec.name)
        self.spec = spec
        self.clock = SensorClock(spec.update_rate, start_ns=start_ns)
        self._adr = [int(model.sensor(name).adr[0]) for name in sensors]
        self._rng = rng
        self._gyro_noise = [_Noise(n, rng) for n in spec.angular_velocity_noise]
        self._accel_noise = [_Noise(n, rng) for n in spec.linear_acceleration_noise]
        self._reference: NDArray[np.float64] | None = None
        gyro_var = [n.stddev**2 for n in spec.angular_velocity_noise]
        accel_var = [n.stddev**2 for n in spec.linear_acceleration_noise]
        orient_var = spec.orientation_noise_stddev**2
        self._cov_gyro = np.diag(gyro_var).reshape(-1)
        self._cov_accel = np.diag(accel_var).reshape(-1)
        self._cov_orient = np.diag([orient_var] * 3).reshape(-1)
        topic = spec.topic or f"/{spec.name}/out"
        self._pub = node.create_publisher(Imu, topic, SENSOR_QOS)

    def rebind(self, ids: IdMap) -> None:
        """Read the same MuJoCo sensors of a recompiled model."""
        self._adr = [int(a) for a in ids.sensordata(self._adr)]

    def after_step(self, data: mujoco.MjData, now_ns: int) -> None:
        """Read the sensor at ``now_ns`` when due and publish."""
        if not self.clock.due(now_ns):
            return
        rng = self._rng
        g, a, q = self._adr
        raw = data.sensordata
        gyro = [self._gyro_noise[i].apply(float(raw[g + i]), rng) for i in range(3)]
        accel = [self._accel_noise[i].apply(float(raw[a + i]), rng) for i in range(3)]
        w, x, y, z = (float(v) for v in raw[q : q + 4])  # MuJoCo order w, x, y, z
        rot = quat_xyzw_to_matrix((x, y, z, w))
        if self.spec.initial_orientation_as_reference:
            if self._reference is None:
                self._reference = rot.copy()
            rot = self._reference.T @ rot
        if self.spec.orientation_noise_stddev > 0.0:
            tilt = rng.normal(0.0, self.spec.orientation_noise_stddev, 3)
            rot = rot @ rpy_to_matrix([float(v) for v in tilt])
        self._pub.publish(
            Imu(
                header=_header(now_ns, self.spec.frame_id),
                orientation=_quaternion(matrix_to_quat_xyzw(rot)),
                orientation_covariance=self._cov_orient.copy(),
                angular_velocity=_vector(gyro),
                angular_velocity_covariance=self._cov_gyro.copy(),
                linear_acceleration=_vector(accel),
                linear_acceleration_covariance=self._cov_accel.copy(),
            )
        )


# --------------------------------------------------------------------------- p3d


class OdometryPlugin(SimPlugin):
    """``libgazebo_ros_p3d.so``: ground-truth ``nav_msgs/Odometry`` of a body.

    As gazebo_ros_p3d: the pose is the body frame's in the world (or relative to
    ``frame_name`` when that is a link), ``xyz_offset`` is added to the position and
    ``rpy_offset`` rotates the orientation; the twist is the body origin's velocity
    expressed in that reference frame (not in the body frame), with gaussian noise;
    both covariance diagonals are the noise variance. ``publish_tf`` broadcasts
    ``frame_id -> child_frame_id``.

    Args:
        node: the plugin's node.
        spec: the plugin with its final topic and frames.
        model: the compiled model.
        body: MuJoCo body id of the tracked link.
        reference: MuJoCo body id of ``frame_name`` when it is a link, else None (world).
        rng: the noise generator.
        start_ns: sim time of the first possible sample.
    """

    def __init__(
        self,
        node: Node,
        spec: OdometrySpec,
        model: mujoco.MjModel,
        *,
        body: int,
        reference: int | None,
        rng: np.random.Generator,
        start_ns: int = 0,
    ) -> None:
        super().__init__(node, spec.plugin_name)
        self.spec = spec
        self.clock = SensorClock(spec.update_rate, start_ns=start_ns)
        self._body = BodyReader(model, body)
        self._reference = BodyReader(model, reference) if reference is not None else None
        self._rng = rng
        self._offset_xyz = np.asarray(spec.xyz_offset, dtype=np.float64)
        self._offset_rot = rpy_to_matrix(spec.rpy_offset)
        self._has_offset = bool(np.any(self._offset_xyz)) or any(spec.rpy_offset)
        cov = np.zeros(36)
        cov[[0, 7, 14, 21, 28, 35]] = spec.gaussian_noise**2
        self._cov = cov
        self._pub = node.create_publisher(Odometry, spec.topic, DEFAULT_QOS)
        self._tf = TransformBroadcaster(node) if spec.publish_tf else None

    def rebind(self, ids: IdMap) -> None:
        """Track the same bodies of a recompiled model."""
        self._body.rebind(ids)
        if self._reference is not None:
            self._reference.rebind(ids)

    def sense(self, data: mujoco.MjData, now_ns: int) -> None:
        """Measure at ``now_ns`` when due and publish."""
        if not self.clock.due(now_ns):
            return
        state = self._body.read(data)
        pos, rot, lin, ang = state.position, state.rotation, state.linear, state.angular
        if self._reference is not None:
            ref = self._reference.read(data)
            r_t = ref.rotation.T
            pos = r_t @ (pos - ref.position)
            rot = r_t @ rot
            lin = r_t @ (lin - ref.linear)
            ang = r_t @ (ang - ref.angular)
        if self._has_offset:
            pos = pos + self._offset_xyz
            rot = self._offset_rot @ rot
        noise = self.spec.gaussian_noise
        if noise > 0.0:
            lin = lin + self._rng.normal(0.0, noise, 3)
            ang = ang + self._rng.normal(0.0, noise, 3)
        header = _header(now_ns, self.spec.frame_id)
        quat = _quaternion(matrix_to_quat_xyzw(rot))
        self._pub.publish(
            Odometry(
                header=header,
                child_frame_id=self.spec.child_frame_id,
                pose=PoseWithCovariance(
                    pose=Pose(position=Point(x=pos[0], y=pos[1], z=pos[2]), orientation=quat),
                    covariance=self._cov.copy(),
                ),
                twist=TwistWithCovariance(
                    twist=Twist(linear=_vector(lin), angular=_vector(ang)),
                    covariance=self._cov.copy(),
                ),
            )
        )
        if self._tf is not None:
            self._tf.send_transform(
                TransformStamped(
                    header=header,
                    child_frame_id=self.spec.child_frame_id,
                    transform=Transform(translation=_vector(pos), rotation=quat),
                )
            )


# --------------------------------------------------------------------------- diff drive


class DiffDrivePlugin(SimPlugin):
    """``libgazebo_ros_diff_drive.so``: ``cmd_vel`` in; ``odom`` and its TF out.

    The wheels are driven by :class:`~visnav.sim.vehicles.diff_drive.DiffDriveController`
    (its docstring lists where it differs from Gazebo). With ``publish_wheel_tf``
    the wheel joints' transforms go on ``/tf`` at the plugin's update rate; with
    ``publish_wheel_joint_state`` (ROS 1) the wheel positions go on ``joint_states``
    (right wheel first, positions only, as the ROS 1 plugin), where
    robot_state_publisher turns them into the wheel frames.

    Args:
        node: the plugin's node.
        spec: the plugin with its final topics and frames.
        controller: drives the wheels and produces the odometry.
        wheels: ``(URDF joint, qpos address)`` of the wheel joints, for the wheel TF.
        robot_state: the robot's kinematics (with its frame prefix), for the wheel TF.
    """

    def __init__(
        self,
        node: Node,
        spec: DiffDriveSpec,
        controller: DiffDriveController,
        *,
        wheels: Sequence[tuple[str, int]] = (),
        robot_state: RobotStateModel | None = None,
    ) -> None:
        super().__init__(node, spec.plugin_name)
        self.spec = spec
        self.controller = controller
        self._odom = (
            node.create_publisher(Odometry, spec.odometry_topic, DEFAULT_QOS)
            if spec.publish_odom
            else None
        )
        publish_tf = spec.publish_odom_tf or (spec.publish_wheel_tf and bool(wheels))
        self._tf = TransformBroadcaster(node) if publish_tf else None
        self._wheels = list(wheels) if spec.publish_wheel_tf else []
        self._robot_state = robot_state
        self._joint_states = None
        if spec.publish_wheel_joint_state and wheels:
            # gazebo_ros_diff_drive (ROS 1) lists the right wheel, then the left
            pairs = len(wheels) // 2
            order = [w for i in range(pairs) for w in (wheels[pairs + i], wheels[i])]
            self._wheel_names = [joint for joint, _ in order]
            self._wheel_qpos = np.array([adr for _, adr in order], dtype=np.int64)
            self._joint_states = node.create_publisher(
                JointState, spec.joint_states_topic, DEFAULT_QOS
            )
        node.create_subscription(Twist, spec.command_topic, self._on_cmd_vel, DEFAULT_QOS)

    def _on_cmd_vel(self, msg: Twist) -> None:
        self.controller.set_command(float(msg.linear.x), float(msg.angular.z))

    def reset(self, data: mujoco.MjData, now_ns: int) -> None:
        """As gazebo_ros_diff_drive's ``Reset()``: command and encoder odometry back to zero."""
        del data, now_ns
        self.controller.reset()

    def rebind(self, ids: IdMap) -> None:
        """Drive the same wheels of a recompiled model (command and odometry kept)."""
        self.controller.rebind(ids)
        self._wheels = [(joint, int(ids.qpos([adr])[0])) for joint, adr in self._wheels]
        if self._joint_states is not None:
            self._wheel_qpos = ids.qpos(self._wheel_qpos)

    def control(self, data: mujoco.MjData, now_ns: int) -> None:
        """Apply the controller for the step at ``now_ns``."""
        sample = self.controller.step(data, now_ns)
        if sample is None:
            return
        if self._odom is not None:
            self._odom.publish(sample.to_msg())
        if self._joint_states is not None:
            empty = np.zeros(0, dtype=np.float64)
            self._joint_states.publish(
                JointState(
                    header=_header(now_ns, ""),
                    name=list(self._wheel_names),
                    position=np.array(data.qpos[self._wheel_qpos], dtype=np.float64),
                    velocity=empty,
                    effort=empty,
                )
            )
        if self._tf is None:
            return
        transforms = [sample.to_transform()] if self.spec.publish_odom_tf else []
        if self._wheels and self._robot_state is not None:
            stamp = ns_to_time(now_ns)
            rs = self._robot_state
            for joint, qpos in self._wheels:
                spec = rs.moving_joints[joint]
                matrix = rs.joint_transform(joint, float(data.qpos[qpos]))
                transforms.append(
                    TransformStamped(
                        header=Header(stamp=stamp, frame_id=rs.frame(spec.parent)),
                        child_frame_id=rs.frame(spec.child),
                        transform=Transform(
                            translation=_vector(matrix[:3, 3]),
                            rotation=_quaternion(matrix_to_quat_xyzw(matrix[:3, :3])),
                        ),
                    )
                )
        if transforms:
            self._tf.send_transform(transforms)


# --------------------------------------------------------------------------- joint states


class JointStatePlugin(SimPlugin):
    """``libgazebo_ros_joint_state_publisher.so``: position, velocity and effort of joints.

    Effort is the generalized force applied to the joint (``qfrc_applied`` plus
    ``qfrc_actuator``), as Gazebo reports the joint's applied force.

    Args:
        node: the plugin's node.
        spec: the plugin with its final topic.
        model: the compiled model.
        joints: ``(URDF joint name, MuJoCo joint name)`` of the published joints.
        start_ns: sim time of the first possible message.
    """

    def __init__(
        self,
        node: Node,
        spec: JointStatePublisherSpec,
        model: mujoco.MjModel,
        joints: Sequence[tuple[str, str]],
        *,
        start_ns: int = 0,
    ) -> None:
        super().__init__(node, spec.plugin_name)
        self.spec = spec
        self.clock = SensorClock(spec.update_rate, start_ns=start_ns)
        self._names = [name for name, _ in joints]
        ids = [model.joint(mj).id for _, mj in joints]
        self._qpos = np.array([model.jnt_qposadr[i] for i in ids], dtype=np.int64)
        self._dof = np.array([model.jnt_dofadr[i] for i in ids], dtype=np.int64)
        self._pub = node.create_publisher(JointState, spec.topic, DEFAULT_QOS)

    def rebind(self, ids: IdMap) -> None:
        """Read the same joints of a recompiled model."""
        self._qpos = ids.qpos(self._qpos)
        self._dof = ids.dof(self._dof)

    def sense(self, data: mujoco.MjData, now_ns: int) -> None:
        """Measure at ``now_ns`` when due and publish."""
        if not self.clock.due(now_ns):
            return
        dof = self._dof
        self._pub.publish(
            JointState(
                header=_header(now_ns, ""),
                name=list(self._names),
                position=np.array(data.qpos[self._qpos], dtype=np.float64),
                velocity=np.array(data.qvel[dof], dtype=np.float64),
                effort=np.asarray(data.qfrc_applied[dof] + data.qfrc_actuator[dof]),
            )
        )
