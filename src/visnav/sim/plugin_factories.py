"""Per-plugin factories: one Gazebo sensor / plugin spec -> its simulator runtime.

The simulator builds a robot's plugins through :data:`SIM_PLUGINS`: for each kind
(a field of :class:`~visnav.description.gazebo_specs.GazeboExtensions`, in registry
order, which is also the order plugins sense and act in every step) it imports the
registered factory and calls it once per spec of that kind with a :class:`RobotBuild`.
A factory pushes the robot's namespace and frame prefix onto the spec, builds the
runtime (a :class:`~visnav.sim.plugins.SimPlugin`) and returns it, or None when the
spec publishes nothing. Adding a plugin is writing its factory (in its own module or
here) and adding one line to :data:`SIM_PLUGINS`.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from visnav.graph.node import Node
from visnav.plugin_registry import UnknownPluginError, resolve_factory
from visnav.sim.camera import CameraSensor, RenderContext
from visnav.sim.plugins import (
    CameraPlugin,
    DiffDrivePlugin,
    ImuPlugin,
    JointStatePlugin,
    OdometryPlugin,
    SimPlugin,
)
from visnav.sim.quadrotor_plugin import QuadrotorPlugin
from visnav.sim.sensor_timing import sensor_seed
from visnav.sim.vehicles.diff_drive import DiffDriveController
from visnav.sim.vehicles.quadrotor import QuadrotorController, QuadrotorParams

if TYPE_CHECKING:
    import mujoco

    from visnav.description.gazebo_specs import (
        CameraSpec,
        DiffDriveSpec,
        ImuSpec,
        JointStatePublisherSpec,
        OdometrySpec,
        QuadrotorSpec,
    )
    from visnav.description.robot import RobotDescription
    from visnav.graph.context import Context
    from visnav.sim.robot import RobotHandles
    from visnav.tf.robot_state import RobotStateModel

__all__ = [
    "SIM_PLUGINS",
    "RobotBuild",
    "build_plugins",
    "diff_drive_controller",
    "make_camera",
    "make_diff_drive",
    "make_imu",
    "make_joint_state_publisher",
    "make_p3d",
    "make_quadrotor",
    "node_name",
    "publishes",
    "push_namespace",
]

SIM_PLUGINS: Mapping[str, str] = {
    "cameras": "visnav.sim.plugin_factories:make_camera",
    "imus": "visnav.sim.plugin_factories:make_imu",
    "rays": "visnav.sim.ray_plugin:make_ray",
    "odometry": "visnav.sim.plugin_factories:make_p3d",
    "diff_drives": "visnav.sim.plugin_factories:make_diff_drive",
    "joint_state_publishers": "visnav.sim.plugin_factories:make_joint_state_publisher",
    "quadrotors": "visnav.sim.plugin_factories:make_quadrotor",
    "imu_plugins": "visnav.sim.imu_model:make_imu_model",
    "skid_steer_drives": "visnav.sim.bases:make_skid_steer",
    "planar_moves": "visnav.sim.bases:make_planar_move",
    "ros_control": "visnav.sim.ros_control:make_ros_control",
}
"""Spec kind (a ``GazeboExtensions`` field) -> ``module:function`` factory, in step order."""

_NODE_NAME = re.compile(r"[^A-Za-z0-9_]")

SimPluginFactory = Callable[["RobotBuild", Any], SimPlugin | None]


def node_name(text: str) -> str:
    """A valid node name from ``text`` (other characters become ``_``)."""
    name = _NODE_NAME.sub("_", text) or "plugin"
    return name if not name[0].isdigit() else "_" + name


def push_namespace(ns: str, topic: str | None) -> str | None:
    """``topic`` in namespace ``ns`` (absolute topics too, like ``-robot_namespace``)."""
    if topic is None or ns == "/":
        return topic
    return ns + "/" + topic.lstrip("/")


def publishes(camera: CameraSpec) -> bool:
    """Whether a camera has a ROS plugin (a sensor without one publishes nothing)."""
    return bool(camera.image_topic or camera.depth_topic or camera.points_topic)


@dataclass
class RobotBuild:
    """What a factory needs to build one robot's plugins, and what factories report back.

    Attributes:
        model: the compiled MuJoCo model.
        context: the graph context the plugin nodes live in.
        name: the robot's name (its MuJoCo prefix without the slash).
        description: the loaded robot.
        handles: its MuJoCo element names.
        namespace: its topic namespace (``/`` or ``/ns``).
        frame_prefix: its TF frame prefix.
        seed: the run's seed (each plugin derives its own from it).
        state_model: the robot's kinematics (diff-drive wheels update it).
        render_context: the shared offscreen renderer, if any robot has cameras.
        cameras: camera plugins built so far (the simulator frees their renderers).
        covered_joints: joints some joint-state publisher publishes.
        joint_states_topic: where robot_state_publisher reads joint states.
        quadrotor: the robot's quadrotor plugin, if it flies.
        sim_node: the node that owns the simulation; its parameters are the ROS 1
            parameter-server view ros_control controllers read (``controllers``, ...).
        start_ns: sim time the robot enters the simulation (a spawned model starts late).
    """

    model: mujoco.MjModel
    context: Context
    name: str
    description: RobotDescription
    handles: RobotHandles
    namespace: str
    frame_prefix: str
    seed: int
    state_model: RobotStateModel
    render_context: RenderContext | None = None
    cameras: list[CameraPlugin] = field(default_factory=list)
    covered_joints: set[str] = field(default_factory=set)
    joint_states_topic: str = "/joint_states"
    quadrotor: QuadrotorPlugin | None = None
    sim_node: Node | None = None
    start_ns: int = 0

    def frame(self, frame_id: str) -> str:
        """``frame_id`` with the robot's prefix (``world`` and ``map`` stay as they are)."""
        prefix = self.frame_prefix
        if frame_id.lstrip("/") in ("world", "map") or not prefix:
            return frame_id
        return prefix + frame_id

    def push(self, topic: str | None) -> str | None:
        """``topic`` in the robot's namespace."""
        return push_namespace(self.namespace, topic)

    def node(self, label: str) -> Node:
        """A new node for a plugin, in the robot's namespace."""
        return Node(node_name(label), namespace=self.namespace, context=self.context)

    def seed_of(self, label: str) -> int:
        """The seed of the plugin or sensor ``label`` of this robot."""
        return sensor_seed(self.seed, f"{self.name}/{label}")


def make_camera(build: RobotBuild, cam: CameraSpec) -> SimPlugin | None:
    """``libgazebo_ros_camera.so`` and the depth plugins: a rendering camera."""
    if not publishes(cam):
        return None
    push = build.push
    spec = replace(
        cam,
        frame_id=build.frame(cam.frame_id),
        image_topic=push(cam.image_topic),
        camera_info_topic=push(cam.camera_info_topic),
        depth_topic=push(cam.depth_topic),
        depth_info_topic=push(cam.depth_info_topic),
        points_topic=push(cam.points_topic),
    )
    sensor = CameraSensor(
        build.model,
        spec,
        camera=build.handles.cameras[cam.name],
        seed=build.seed_of(cam.name),
        context=build.render_context,
    )
    plugin = CameraPlugin(build.node(cam.plugin_name or cam.name), spec, sensor)
    build.cameras.append(plugin)
    return plugin


def make_imu(build: RobotBuild, imu: ImuSpec) -> SimPlugin | None:
    """``libgazebo_ros_imu_sensor.so``: MuJoCo gyro, accelerometer and orientation."""
    if imu.topic is None:
        return None
    spec = replace(imu, topic=build.push(imu.topic), frame_id=build.frame(imu.frame_id))
    return ImuPlugin(
        build.node(imu.plugin_name or imu.name),
        spec,
        build.model,
        build.handles.imu_sensors[imu.name],
        rng=np.random.default_rng(build.seed_of(imu.name)),
    )


def make_p3d(build: RobotBuild, odom: OdometrySpec) -> SimPlugin | None:
    """``libgazebo_ros_p3d.so``: ground-truth odometry of a body."""
    model, bodies = build.model, build.handles.bodies
    reference = None
    if odom.frame_id in build.description.urdf.links and odom.frame_id != "world":
        reference = model.body(bodies[odom.frame_id]).id
    spec = replace(
        odom,
        topic=build.push(odom.topic) or odom.topic,
        frame_id=build.frame(odom.frame_id),
        child_frame_id=build.frame(odom.child_frame_id),
    )
    return OdometryPlugin(
        build.node(odom.plugin_name),
        spec,
        model,
        body=model.body(bodies[odom.body_name]).id,
        reference=reference,
        rng=np.random.default_rng(build.seed_of(odom.plugin_name)),
    )


def diff_drive_controller(
    build: RobotBuild, drive: DiffDriveSpec
) -> tuple[DiffDriveSpec, DiffDriveController]:
    """``drive`` with the robot's namespace and frame prefix pushed on, and its controller.

    The odometry body is the link named ``robot_base_frame``, else the URDF root.
    """
    urdf = build.description.urdf
    base_link = drive.robot_base_frame if drive.robot_base_frame in urdf.links else urdf.root
    spec = replace(
        drive,
        command_topic=build.push(drive.command_topic) or drive.command_topic,
        odometry_topic=build.push(drive.odometry_topic) or drive.odometry_topic,
        odometry_frame=build.frame(drive.odometry_frame),
        robot_base_frame=build.frame(drive.robot_base_frame),
    )
    controller = DiffDriveController(
        build.model,
        spec,
        base_body=build.handles.bodies[base_link],
        prefix=f"{build.name}/",
        start_ns=build.start_ns,
        seed=build.seed_of(drive.plugin_name),
    )
    return spec, controller


def make_diff_drive(build: RobotBuild, drive: DiffDriveSpec) -> SimPlugin | None:
    """``libgazebo_ros_diff_drive.so``: ``cmd_vel`` in, wheel torques, odometry out."""
    model = build.model
    spec, controller = diff_drive_controller(build, drive)
    joints = build.handles.joints
    wheels = [
        (j, int(model.joint(joints[j]).qposadr[0]))
        for j in (*drive.left_joints, *drive.right_joints)
    ]
    if drive.publish_wheel_joint_state:
        spec = replace(spec, joint_states_topic=build.push(drive.joint_states_topic) or "")
        build.covered_joints.update((*drive.left_joints, *drive.right_joints))
        build.joint_states_topic = spec.joint_states_topic
    return DiffDrivePlugin(
        build.node(drive.plugin_name),
        spec,
        controller,
        wheels=wheels,
        robot_state=build.state_model,
    )


def make_joint_state_publisher(build: RobotBuild, jsp: JointStatePublisherSpec) -> SimPlugin:
    """``libgazebo_ros_joint_state_publisher.so``: ``JointState`` of the listed joints."""
    handles = build.handles.joints
    joints = [(j, handles[j]) for j in jsp.joints if j in handles]
    build.covered_joints.update(j for j, _ in joints)
    spec = replace(jsp, topic=build.push(jsp.topic) or jsp.topic)
    build.joint_states_topic = spec.topic
    return JointStatePlugin(build.node(jsp.plugin_name), spec, build.model, joints)


def make_quadrotor(build: RobotBuild, quad: QuadrotorSpec) -> SimPlugin:
    """``libvisnav_quadrotor.so``: position commands in, thrust and moments out."""
    spec = replace(
        quad,
        trajectory_topic=build.push(quad.trajectory_topic) or quad.trajectory_topic,
        pose_topic=build.push(quad.pose_topic) or quad.pose_topic,
    )
    controller = QuadrotorController(
        build.model,
        body=build.handles.bodies[quad.body_name],
        params=QuadrotorParams.from_plugin_params(dict(quad.parameters)),
        seed=build.seed_of(quad.plugin_name),
    )
    plugin = QuadrotorPlugin(build.node(quad.plugin_name), spec, controller)
    build.quadrotor = plugin
    return plugin


def build_plugins(
    build: RobotBuild, *, registry: Mapping[str, str] = SIM_PLUGINS
) -> list[SimPlugin]:
    """Build every plugin of the robot, kind by kind in registry order.

    Raises:
        UnknownPluginError: a registry line does not import to a callable.
    """
    plugins: list[SimPlugin] = []
    extensions = build.description.gazebo
    for kind in registry:
        factory = cast("SimPluginFactory", resolve_factory(kind, registry, what="sim plugin"))
        specs = getattr(extensions, kind, None)
        if specs is None:
            msg = (
                f"sim plugin {kind!r} is registered but GazeboExtensions has no field {kind!r}; "
                "add the field (and its parser) to visnav.description.gazebo_specs"
            )
            raise UnknownPluginError(msg)
        for spec in specs:
            plugin = factory(build, spec)
            if plugin is not None:
                plugins.append(plugin)
    return plugins
