"""Typed configurations of Gazebo sensors and ``gazebo_ros`` plugins, and ROS name rules.

These are the results of :func:`visnav.description.gazebo.parse_gazebo_extensions`:
one frozen dataclass per sensor or plugin holding the resolved, fully
qualified topic names and frame ids the plugin publishes. Name helpers
reproduce rcl's expansion and remapping (ROS 2, :class:`RosNodeNames`) and
ROS 1's ``NodeHandle`` nesting and ``tf::resolve`` (:func:`ros1_join`,
:func:`tf_resolve`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

from visnav.description.noise_specs import DepthNoise, WheelOdometryNoise
from visnav.description.urdf import Origin

__all__ = [
    "CameraSpec",
    "DiffDriveSpec",
    "GaussianNoise",
    "GazeboExtensions",
    "ImuModelSpec",
    "ImuSpec",
    "JointStatePublisherSpec",
    "LensDistortion",
    "LinkProperties",
    "OdometrySpec",
    "PlanarMoveSpec",
    "QuadrotorSpec",
    "RosControlSpec",
    "RosNodeNames",
    "SkidSteerSpec",
    "TransmissionSpec",
    "default_principal_point",
    "normalize_namespace",
    "ros1_join",
    "tf_resolve",
]


def ros1_join(*parts: str) -> str:
    """Join ROS 1 name parts as ``NodeHandle`` nesting does (one leading slash, no doubles)."""
    pieces = [p.strip("/") for p in parts if p.strip("/")]
    return "/" + "/".join(pieces)


def tf_resolve(prefix: str, frame: str) -> str:
    """Return ROS 1 ``tf::resolve(prefix, frame)`` (the tf_prefix rule, without leading slash)."""
    if frame.startswith("/"):
        return frame.lstrip("/")
    prefix = prefix.strip("/")
    return f"{prefix}/{frame}" if prefix else frame


def normalize_namespace(namespace: str) -> str:
    """Return a namespace with one leading slash and no trailing slash (``/`` for root)."""
    ns = "/" + namespace.strip("/")
    return ns if ns != "/" else "/"


@dataclass(frozen=True)
class RosNodeNames:
    """The ROS 2 node a ``gazebo_ros`` plugin creates: name, namespace and remap rules.

    ``remappings`` are ``(node or None, from, to)`` rules, first match wins, matched
    on fully expanded names as rcl does.
    """

    name: str
    namespace: str = "/"
    remappings: tuple[tuple[str | None, str, str], ...] = ()

    def expand(self, topic: str) -> str:
        """Expand a relative (``a/b``) or private (``~/a``) name to a fully qualified one."""
        ns = self.namespace.rstrip("/")
        if topic.startswith("/"):
            return "/" + topic.strip("/")
        if topic.startswith("~"):
            rest = topic[1:].strip("/")
            base = f"{ns}/{self.name}"
            return f"{base}/{rest}" if rest else base
        return f"{ns}/{topic.strip('/')}"

    def resolve(self, topic: str) -> str:
        """Return the topic name the plugin actually uses after remapping."""
        expanded = self.expand(topic)
        for node, src, dst in self.remappings:
            if node is not None and node != self.name:
                continue
            if self.expand(src) == expanded:
                return self.expand(dst)
        return expanded


def default_principal_point(width: int, height: int) -> tuple[float, float]:
    """visnav's default principal point, ``(width / 2, height / 2)``.

    visnav's cameras put the principal point at cx = width / 2, cy = height / 2 and render
    exactly that K. Where this differs from Gazebo: gazebo_ros_camera (ROS 2) and
    gazebo_ros_camera_utils (ROS 1) publish ``(width + 1) / 2`` while Gazebo renders
    the optical axis at ``(width - 1) / 2``, so Gazebo's camera_info is one pixel off
    its own image; visnav's image and camera_info agree. ``<cx>``/``<cy>`` override it.
    """
    return width / 2.0, height / 2.0


# --------------------------------------------------------------------------- dataclasses


@dataclass(frozen=True)
class GaussianNoise:
    """Additive gaussian noise (SDF ``<noise type="gaussian">``)."""

    mean: float = 0.0
    stddev: float = 0.0
    bias_mean: float = 0.0
    bias_stddev: float = 0.0

    @property
    def active(self) -> bool:
        """True if the noise changes values at all."""
        return any(v != 0.0 for v in (self.mean, self.stddev, self.bias_mean, self.bias_stddev))


@dataclass(frozen=True)
class LensDistortion:
    """Brown-Conrady (plumb_bob) coefficients; ``center`` in normalised image coordinates."""

    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    center: tuple[float, float] = (0.5, 0.5)

    @property
    def d(self) -> tuple[float, float, float, float, float]:
        """``D`` in CameraInfo / OpenCV order: k1, k2, p1, p2, k3."""
        return (self.k1, self.k2, self.p1, self.p2, self.k3)

    @property
    def is_zero(self) -> bool:
        """True when there is no distortion."""
        return not any(self.d)


@dataclass(frozen=True, kw_only=True)
class CameraSpec:
    """A camera or depth camera sensor with the topics and frame its plugin publishes.

    Topics are fully qualified (``None`` when not published). ``fx``, ``fy``,
    ``cx``, ``cy`` are the published intrinsics (see :meth:`k`). ``pose`` is the
    sensor frame (x forward, y left, z up) in the link frame. ``update_rate`` is
    in Hz; 0 means every physics step (Gazebo: as fast as possible).
    """

    name: str
    link: str
    pose: Origin = field(default_factory=Origin)
    kind: Literal["camera", "depth"] = "camera"
    update_rate: float = 0.0
    width: int = 320
    height: int = 240
    hfov: float = 1.047
    image_format: str = "R8G8B8"
    encoding: str = "rgb8"
    clip_near: float = 0.1
    clip_far: float = 100.0
    noise: GaussianNoise = field(default_factory=GaussianNoise)
    distortion: LensDistortion = field(default_factory=LensDistortion)
    fx: float = 0.0
    fy: float = 0.0
    cx: float = 0.0
    cy: float = 0.0
    hack_baseline: float = 0.0
    frame_id: str = ""
    image_topic: str | None = None
    camera_info_topic: str | None = None
    depth_topic: str | None = None
    depth_info_topic: str | None = None
    points_topic: str | None = None
    depth_encoding: Literal["32FC1", "16UC1"] = "32FC1"
    min_depth: float = 0.0
    max_depth: float = math.inf
    pointcloud: bool = True
    depth_noise: DepthNoise = field(default_factory=DepthNoise)
    plugin: str | None = None
    plugin_name: str | None = None
    ros_version: Literal[1, 2] | None = None
    plugin_update_rate: float = 0.0
    """ROS 1 ``<updateRate>`` of the plugin (Hz, 0 = none): throttles publishing below the
    sensor's ``update_rate`` as gazebo_ros_camera_utils does; frames are rendered only when
    both are due."""

    def k(self) -> tuple[float, ...]:
        """Row-major 3x3 camera matrix K as published in ``CameraInfo.k``."""
        return (self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)

    def p(self) -> tuple[float, ...]:
        """Row-major 3x4 projection P (``P[3] = -fx * hack_baseline`` as Gazebo writes)."""
        return (
            self.fx, 0.0, self.cx, -self.fx * self.hack_baseline,
            0.0, self.fy, self.cy, 0.0,
            0.0, 0.0, 1.0, 0.0,
        )  # fmt: skip

    @property
    def depth_range(self) -> tuple[float, float]:
        """Open interval of valid depths: clip and the plugin's min/max depth combined."""
        return (max(self.clip_near, self.min_depth), min(self.clip_far, self.max_depth))


@dataclass(frozen=True, kw_only=True)
class ImuSpec:
    """An IMU sensor; noise per axis x, y, z (angular velocity rad/s, acceleration m/s^2)."""

    name: str
    link: str
    pose: Origin = field(default_factory=Origin)
    update_rate: float = 0.0
    topic: str | None = None
    frame_id: str = ""
    angular_velocity_noise: tuple[GaussianNoise, GaussianNoise, GaussianNoise] = (
        GaussianNoise(), GaussianNoise(), GaussianNoise(),
    )  # fmt: skip
    linear_acceleration_noise: tuple[GaussianNoise, GaussianNoise, GaussianNoise] = (
        GaussianNoise(), GaussianNoise(), GaussianNoise(),
    )  # fmt: skip
    orientation_noise_stddev: float = 0.0
    initial_orientation_as_reference: bool = False
    plugin: str | None = None
    plugin_name: str | None = None
    ros_version: Literal[1, 2] | None = None


@dataclass(frozen=True, kw_only=True)
class OdometrySpec:
    """``libgazebo_ros_p3d.so``: ground-truth ``nav_msgs/Odometry`` of a link.

    Noise (``gaussian_noise`` stddev) is added to the twist only, as in gazebo_ros_p3d;
    the pose covariance diagonal and twist covariance diagonal are its square.
    ``publish_tf`` broadcasts ``frame_id -> child_frame_id``.
    """

    plugin_name: str
    body_name: str
    frame_id: str = "world"
    child_frame_id: str = ""
    topic: str = "/odom"
    update_rate: float = 0.0
    gaussian_noise: float = 0.0
    xyz_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    publish_tf: bool = False
    ros_version: Literal[1, 2] = 2


@dataclass(frozen=True, kw_only=True)
class DiffDriveSpec:
    """``libgazebo_ros_diff_drive.so`` configuration (metres; one entry per wheel pair)."""

    plugin_name: str
    left_joints: tuple[str, ...]
    right_joints: tuple[str, ...]
    wheel_separation: tuple[float, ...] = (0.34,)
    wheel_diameter: tuple[float, ...] = (0.15,)
    max_wheel_acceleration: float = 0.0
    max_wheel_torque: float = 5.0
    command_topic: str = "/cmd_vel"
    odometry_topic: str = "/odom"
    odometry_frame: str = "odom"
    robot_base_frame: str = "base_footprint"
    publish_odom: bool = False
    publish_odom_tf: bool = False
    publish_wheel_tf: bool = False
    odometry_source: Literal["world", "encoder"] = "world"
    update_rate: float = 100.0
    covariance: tuple[float, float, float] = (0.00001, 0.00001, 0.001)
    odometry_noise: WheelOdometryNoise = field(default_factory=WheelOdometryNoise)
    ros_version: Literal[1, 2] = 2
    publish_wheel_joint_state: bool = False
    """ROS 1 ``publishWheelJointState``: wheel positions on ``joint_states_topic``."""
    joint_states_topic: str = "/joint_states"
    legacy_mode: bool = False
    """ROS 1 (kinetic) ``legacyMode``: left and right wheel speeds swapped."""


@dataclass(frozen=True, kw_only=True)
class JointStatePublisherSpec:
    """``libgazebo_ros_joint_state_publisher.so``: joints published on ``topic``."""

    plugin_name: str
    joints: tuple[str, ...]
    topic: str = "/joint_states"
    update_rate: float = 100.0
    ros_version: Literal[1, 2] = 2


@dataclass(frozen=True, kw_only=True)
class QuadrotorSpec:
    """``libvisnav_quadrotor.so``: visnav's quadrotor (no Gazebo counterpart).

    The root link (or ``<body_name>``) is flown by
    :class:`visnav.sim.vehicles.quadrotor.QuadrotorController`; ``parameters`` are
    the plugin's other elements as text, for
    :meth:`~visnav.sim.vehicles.quadrotor.QuadrotorParams.from_plugin_params`.
    References arrive on ``trajectory_topic`` (``trajectory_msgs/MultiDOFJointTrajectory``,
    RotorS' ``command/trajectory``) and ``pose_topic`` (``geometry_msgs/PoseStamped``,
    RotorS' ``command/pose``), both resolved in the plugin's ``<ros>`` namespace.
    """

    plugin_name: str
    body_name: str
    parameters: tuple[tuple[str, str], ...] = ()
    trajectory_topic: str = "/command/trajectory"
    pose_topic: str = "/command/pose"


@dataclass(frozen=True, kw_only=True)
class ImuModelSpec:
    """``libgazebo_ros_imu.so`` (ROS 1 model plugin): ``sensor_msgs/Imu`` of a link.

    As gazebo_ros_imu: the orientation is the link's in the world with ``rpy_offset``
    applied; angular velocity and the linear acceleration (the link velocity's finite
    difference, gravity not included) are expressed in the link frame, each with
    ``gaussian_noise``; every covariance diagonal is its square. ``update_rate`` 0 = every
    physics step. ``service`` is the ``std_srvs/Empty`` calibration service (always succeeds).
    """

    plugin_name: str
    body_name: str
    frame_id: str = ""
    topic: str | None = "/default_imu"
    service: str | None = "/default_imu"
    update_rate: float = 0.0
    gaussian_noise: float = 0.0
    xyz_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True, kw_only=True)
class SkidSteerSpec:
    """``libgazebo_ros_skid_steer_drive.so`` (ROS 1): four driven wheels, ``cmd_vel`` in.

    Both wheels of a side turn at ``v -/+ w * wheel_separation / 2`` (left / right);
    odometry is the model's world pose (always published), its TF only with
    ``broadcast_tf``.
    """

    plugin_name: str
    left_front_joint: str
    right_front_joint: str
    left_rear_joint: str
    right_rear_joint: str
    wheel_separation: float = 0.4
    wheel_diameter: float = 0.15
    torque: float = 5.0
    command_topic: str = "/cmd_vel"
    odometry_topic: str = "/odom"
    odometry_frame: str = "odom"
    robot_base_frame: str = "base_footprint"
    broadcast_tf: bool = False
    update_rate: float = 100.0
    covariance: tuple[float, float, float] = (0.0001, 0.0001, 0.01)


@dataclass(frozen=True, kw_only=True)
class PlanarMoveSpec:
    """``libgazebo_ros_planar_move.so``: ``cmd_vel`` sets the model's planar velocity.

    ``linear.x``, ``linear.y`` (body frame) and ``angular.z`` are applied directly to the
    model every ``update_rate`` (ROS 1: every step); odometry (the model's world pose) on
    ``odometry_topic`` and ``odometry_frame -> robot_base_frame`` on TF at ``odometry_rate``.
    ``cmd_timeout`` >= 0 (ROS 1 ``cmdTimeout``) stops the model when no command came for
    that long.
    """

    plugin_name: str
    command_topic: str = "/cmd_vel"
    odometry_topic: str = "/odom"
    odometry_frame: str = "odom"
    robot_base_frame: str = "base_footprint"
    update_rate: float = 0.0
    odometry_rate: float = 20.0
    publish_odom: bool = True
    publish_odom_tf: bool = True
    cmd_timeout: float = -1.0
    covariance: tuple[float, float, float] = (0.00001, 0.00001, 0.001)
    ros_version: Literal[1, 2] = 1


@dataclass(frozen=True, kw_only=True)
class TransmissionSpec:
    """A URDF ``<transmission>`` as gazebo_ros_control's ``DefaultRobotHWSim`` reads it.

    ``interface`` is the joint's first ``<hardwareInterface>`` (``hardware_interface/``
    prefix dropped): ``VelocityJointInterface``, ``EffortJointInterface`` or
    ``PositionJointInterface``. ``mechanical_reduction`` is kept for reference;
    ``DefaultRobotHWSim`` (and visnav) command the joint directly.
    """

    name: str
    joint: str
    interface: Literal["VelocityJointInterface", "EffortJointInterface", "PositionJointInterface"]
    mechanical_reduction: float = 1.0


@dataclass(frozen=True, kw_only=True)
class RosControlSpec:
    """``libgazebo_ros_control.so``: a ros_control controller manager for the robot.

    ``robot_namespace`` (``<robotNamespace>``, default the robot's name) is where the
    controller manager lives: controllers read their parameters and publish under
    ``<robot_namespace>/<controller>``. ``control_period`` 0 means every physics step
    (the plugin's default, the physics period). ``e_stop_topic`` (``std_msgs/Bool``)
    zeroes every command while true. ``transmissions`` are the joints the hardware
    interface offers, in URDF order.
    """

    plugin_name: str
    robot_namespace: str
    control_period: float = 0.0
    robot_param: str = "robot_description"
    e_stop_topic: str | None = None
    transmissions: tuple[TransmissionSpec, ...] = ()


@dataclass(frozen=True)
class RayScan:
    """One axis of a ray sensor's ``<scan>``: ``samples`` rays from ``min_angle`` to ``max_angle``.

    ``resolution`` multiplies ``samples`` into the number of published ranges (Gazebo
    interpolates between rays when it is not 1). Angles in radians.
    """

    samples: int = 1
    resolution: float = 1.0
    min_angle: float = 0.0
    max_angle: float = 0.0

    @property
    def count(self) -> int:
        """Ranges published along this axis (``int(samples * resolution)``, at least 1)."""
        return max(1, int(self.samples * self.resolution))

    @property
    def step(self) -> float:
        """Angle between published ranges (0 for a single one)."""
        count = self.count
        return (self.max_angle - self.min_angle) / (count - 1) if count > 1 else 0.0


@dataclass(frozen=True, kw_only=True)
class RaySpec:
    """A ray sensor (``ray``, ``gpu_ray``, ``lidar``, ``gpu_lidar``) and its gazebo_ros plugin.

    ``flavor`` says which plugin's conventions the output follows:

    * ``laser``: ROS 1 ``libgazebo_ros_laser.so`` / ``libgazebo_ros_gpu_laser.so``,
      ``sensor_msgs/LaserScan`` of every ray (all vertical rows);
    * ``ray_sensor``: ROS 2 ``libgazebo_ros_ray_sensor.so``, ``output`` one of
      ``LaserScan`` (the middle vertical row), ``PointCloud2``, ``PointCloud``, ``Range``;
    * ``velodyne``: velodyne_simulator's ``libgazebo_ros_velodyne_laser.so`` (and
      ``_gpu_``), ``PointCloud2`` with x, y, z, intensity, ring, time;
    * ``range``: ROS 1 ``libgazebo_ros_range.so``, ``sensor_msgs/Range``.

    Ranges follow REP 117 as Gazebo's ray sensor does: no return within ``range_max``
    is +inf, a return at or below ``range_min`` -inf (see :mod:`visnav.sim.lidar`).
    ``topic`` is fully qualified (None when nothing is published); ``pose`` is the
    sensor frame in the link frame; ``update_rate`` in Hz (0: every physics step).
    """

    name: str
    link: str
    pose: Origin = field(default_factory=Origin)
    kind: str = "ray"
    update_rate: float = 0.0
    horizontal: RayScan = field(default_factory=lambda: RayScan(samples=640))
    vertical: RayScan = field(default_factory=RayScan)
    range_min: float = 0.0
    range_max: float = 10.0
    range_resolution: float = 0.0
    noise: GaussianNoise = field(default_factory=GaussianNoise)
    flavor: Literal["laser", "ray_sensor", "velodyne", "range"] | None = None
    output: Literal["LaserScan", "PointCloud2", "PointCloud", "Range"] = "LaserScan"
    topic: str | None = None
    frame_id: str = ""
    min_intensity: float = 0.0
    """``ray_sensor``: intensities below it are raised to it; ``velodyne``: points below
    it are dropped (default ``-inf``, no filtering)."""
    plugin_min_range: float = 0.0
    """``velodyne`` ``<min_range>``: points at or below it (or ``range_min``) are dropped."""
    plugin_max_range: float = math.inf
    """``velodyne`` ``<max_range>``: points at or beyond it (or ``range_max``) are dropped."""
    gaussian_noise: float = 0.0
    """``velodyne`` / ``range`` plugin noise (stddev, m), added by the plugin."""
    organize_cloud: bool = False
    """``velodyne``: keep dropped points as NaN (width = vertical rays, height = azimuths)."""
    radiation_type: int = 0
    """``Range.radiation_type``: 0 ULTRASOUND, 1 INFRARED."""
    field_of_view: float = 0.0
    """``Range.field_of_view`` (rad)."""
    plugin: str | None = None
    plugin_name: str | None = None
    ros_version: Literal[1, 2] | None = None


@dataclass(frozen=True)
class LinkProperties:
    """``<gazebo reference="link">`` surface properties visnav applies."""

    rgba: tuple[float, float, float, float] | None = None
    mu1: float | None = None
    mu2: float | None = None


@dataclass(frozen=True)
class GazeboExtensions:
    """Everything the ``<gazebo>`` blocks of one robot configure."""

    cameras: tuple[CameraSpec, ...] = ()
    imus: tuple[ImuSpec, ...] = ()
    odometry: tuple[OdometrySpec, ...] = ()
    diff_drives: tuple[DiffDriveSpec, ...] = ()
    joint_state_publishers: tuple[JointStatePublisherSpec, ...] = ()
    quadrotors: tuple[QuadrotorSpec, ...] = ()
    link_properties: Mapping[str, LinkProperties] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()
    imu_plugins: tuple[ImuModelSpec, ...] = ()
    skid_steer_drives: tuple[SkidSteerSpec, ...] = ()
    planar_moves: tuple[PlanarMoveSpec, ...] = ()
    ros_control: tuple[RosControlSpec, ...] = ()
    rays: tuple[RaySpec, ...] = ()
