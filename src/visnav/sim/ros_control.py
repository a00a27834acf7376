"""``libgazebo_ros_control.so``: a ros_control controller manager inside the simulator.

As gazebo_ros_control (ROS 1) with ``DefaultRobotHWSim``: the robot's hardware interface
offers the joints of its URDF ``<transmission>`` elements with their command interface
(velocity, effort or position); a controller manager in ``<robotNamespace>`` (pushed into the
robot's namespace) updates the running controllers every ``controlPeriod`` of sim time
(default: every physics step) and the hardware writes their commands every physics step.

Which controllers run. The simulator's node (the ``sim`` / ``gazebo`` node of a launch) holds
the ROS 1 parameter-server view: parameter ``controllers`` lists the controllers to start
(what ``controller_manager spawner NAME ...`` does; the roslaunch import sets it), and
``stopped_controllers`` those only loaded (``spawner --stopped``). An entry is the
controller's name relative to the root namespace (``husky_velocity_controller``, or
``r1/diff_drive`` for a controller manager in ``/r1``); its configuration is the
parameters ``<entry with . for />.<param with . for />`` (``husky_velocity_controller.type``,
``husky_velocity_controller.linear.x.max_velocity``): what ``<rosparam command="load">``
put under ``/husky_velocity_controller``. A controller manager takes the entries of its own
namespace. Controller types (:data:`CONTROLLER_TYPES`):

* ``diff_drive_controller/DiffDriveController`` (needs ``VelocityJointInterface`` wheels);
* ``joint_state_controller/JointStateController``.

See :mod:`visnav.sim.ros_controllers` for what they publish. An unknown type, a
missing or badly typed parameter, a wheel without a velocity transmission or a joint
claimed by two controllers is one :class:`RosControlError` naming it.

The hardware drives a velocity joint with a PI velocity servo computed every physics step
(the proportional part is 0.9 of the one-step correction of the joint's own inertia, the
integral part removes the steady error under load within ~0.05 s) applied through
``qfrc_applied``, clipped at the URDF ``<limit effort>`` (none: unclipped), the command
first clipped at ``<limit velocity>``; an effort joint gets its command as a generalized
force. ``<eStopTopic>`` (``std_msgs/Bool``) true zeroes every command.

Where visnav differs from gazebo_ros_control: Gazebo sets the ODE joint motor's velocity
(reached within a step with the effort limit as the motor's force) where visnav servoes
the velocity with a torque; controllers start at sim time 0 (the spawner starts them once
it has loaded them, after Gazebo started); there are no ``controller_manager`` services (a
controller cannot be switched at run time); position joints are offered but no controller
visnav has commands them; PID gains (``gazebo_ros_control/pid_gains``) are not read.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from rosbags.typesys.stores.ros2_humble import std_msgs__msg__Bool as Bool

from visnav.description.gazebo_specs import RosControlSpec, ros1_join
from visnav.description.urdf_model import Cylinder, Sphere
from visnav.graph.node import Node
from visnav.sim.errors import SimError
from visnav.sim.plugin_factories import node_name, push_namespace
from visnav.sim.plugins import SimPlugin
from visnav.sim.ros_controllers import (
    DiffDriveControllerConfig,
    DiffDriveRosController,
    JointStateRosController,
    SpeedLimiter,
)
from visnav.sim.vehicles.servo import VelocityServo

if TYPE_CHECKING:
    import mujoco
    from numpy.typing import NDArray

    from visnav.description.urdf import Urdf
    from visnav.sim.plugin_factories import RobotBuild
    from visnav.sim.rebind import IdMap

__all__ = [
    "CONTROLLER_TYPES",
    "ControllerParameters",
    "RobotHWSim",
    "RosControlError",
    "RosControlPlugin",
    "check_spawned_controllers",
    "make_ros_control",
]

_DIFF_DRIVE = "diff_drive_controller/DiffDriveController"
_JOINT_STATE = "joint_state_controller/JointStateController"


class RosControlError(SimError, ValueError):
    """A ros_control controller that cannot be loaded or started."""


# --------------------------------------------------------------------------- parameters


class ControllerParameters:
    """One controller's ROS 1 parameters, read from (and declared on) the sim node.

    Args:
        node: the node holding the parameter-server view (the sim node).
        entry: the controller's name relative to the root (``a`` or ``ns/a``).
    """

    def __init__(self, node: Node, entry: str) -> None:
        self.node = node
        self.entry = entry
        self.prefix = entry.replace("/", ".")

    def ros_name(self, name: str) -> str:
        """The parameter's ROS 1 name (``/entry/name``)."""
        return f"/{self.entry}/{name}"

    def raw(self, name: str) -> Any:
        """The value of ``name`` (``a/b`` style), None when not set; declares it."""
        full = f"{self.prefix}.{name.replace('/', '.')}"
        if not self.node.has_parameter(full):
            self.node.declare_parameter(full, None)
        return self.node.get_parameter(full).value

    def _bad(self, name: str, value: Any, expected: str) -> RosControlError:
        return RosControlError(
            f"controller {self.entry!r}: parameter {self.ros_name(name)} is {value!r}: expected "
            f'{expected}. Fix: set it in the controller\'s YAML (<rosparam command="load">)'
        )

    def number(self, name: str, default: float | None, *, minimum: float | None = None) -> Any:
        """A finite float (ints accepted), or ``default`` when unset."""
        value = self.raw(name)
        if value is None:
            return default
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self._bad(name, value, "a number")
        out = float(value)
        if not math.isfinite(out) or (minimum is not None and out < minimum):
            bound = f" >= {minimum:g}" if minimum is not None else ""
            raise self._bad(name, value, f"a finite number{bound}")
        return out

    def integer(self, name: str, default: int, *, minimum: int = 1) -> int:
        """An integer >= ``minimum``."""
        value = self.raw(name)
        if value is None:
            return default
        if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
            raise self._bad(name, value, f"an integer >= {minimum}")
        return int(value)

    def boolean(self, name: str, default: bool) -> bool:
        """A bool."""
        value = self.raw(name)
        if value is None:
            return default
        if not isinstance(value, bool):
            raise self._bad(name, value, "true or false")
        return value

    def string(self, name: str, default: str) -> str:
        """A string."""
        value = self.raw(name)
        if value is None:
            return default
        if not isinstance(value, str):
            raise self._bad(name, value, "a string")
        return value

    def names(self, name: str, *, required: bool) -> tuple[str, ...] | None:
        """A string or a non-empty list of strings (diff_drive_controller's wheel lists)."""
        value = self.raw(name)
        if value is None:
            if required:
                raise RosControlError(
                    f"controller {self.entry!r}: parameter {self.ros_name(name)} is not set. "
                    "Fix: give the joint name(s) in the controller's YAML"
                )
            return None
        if isinstance(value, str) and value:
            return (value,)
        if isinstance(value, list) and value and all(isinstance(v, str) and v for v in value):
            return tuple(value)
        raise self._bad(name, value, "a joint name or a non-empty list of joint names")

    def diagonal(self, name: str) -> tuple[float, ...]:
        """Six numbers (a covariance diagonal); unset: zeros."""
        value = self.raw(name)
        if value is None:
            return (0.0,) * 6
        if (
            not isinstance(value, list)
            or len(value) != 6
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
        ):
            raise self._bad(name, value, "a list of 6 numbers")
        return tuple(float(v) for v in value)


def _limiter(p: ControllerParameters, axis: str) -> SpeedLimiter:
    return SpeedLimiter(
        has_velocity_limits=p.boolean(f"{axis}/has_velocity_limits", False),
        has_acceleration_limits=p.boolean(f"{axis}/has_acceleration_limits", False),
        has_jerk_limits=p.boolean(f"{axis}/has_jerk_limits", False),
        max_velocity=p.number(f"{axis}/max_velocity", 0.0),
        min_velocity=p.number(f"{axis}/min_velocity", None),
        max_acceleration=p.number(f"{axis}/max_acceleration", 0.0),
        min_acceleration=p.number(f"{axis}/min_acceleration", None),
        max_jerk=p.number(f"{axis}/max_jerk", 0.0),
        min_jerk=p.number(f"{axis}/min_jerk", None),
    )


def diff_drive_config(p: ControllerParameters) -> DiffDriveControllerConfig:
    """Read a DiffDriveController's parameters (the controller's defaults where unset).

    Raises:
        RosControlError: a missing wheel list or a value of the wrong type.
    """
    left = p.names("left_wheel", required=True) or ()
    right = p.names("right_wheel", required=True) or ()
    if len(left) != len(right):
        msg = (
            f"controller {p.entry!r}: {len(left)} left wheels {list(left)} but {len(right)} "
            f"right wheels {list(right)}. Fix: list as many {p.ros_name('left_wheel')} as "
            f"{p.ros_name('right_wheel')}"
        )
        raise RosControlError(msg)
    radius = p.number("wheel_radius_multiplier", None)
    return DiffDriveControllerConfig(
        left_wheel=left,
        right_wheel=right,
        publish_rate=p.number("publish_rate", 50.0, minimum=0.0),
        open_loop=p.boolean("open_loop", False),
        wheel_separation_multiplier=p.number("wheel_separation_multiplier", 1.0),
        left_wheel_radius_multiplier=(
            radius if radius is not None else p.number("left_wheel_radius_multiplier", 1.0)
        ),
        right_wheel_radius_multiplier=(
            radius if radius is not None else p.number("right_wheel_radius_multiplier", 1.0)
        ),
        velocity_rolling_window_size=p.integer("velocity_rolling_window_size", 10),
        cmd_vel_timeout=p.number("cmd_vel_timeout", 0.5),
        allow_multiple_cmd_vel_publishers=p.boolean("allow_multiple_cmd_vel_publishers", True),
        base_frame_id=p.string("base_frame_id", "base_link"),
        odom_frame_id=p.string("odom_frame_id", "odom"),
        enable_odom_tf=p.boolean("enable_odom_tf", True),
        publish_cmd=p.boolean("publish_cmd", False),
        wheel_separation=p.number("wheel_separation", None),
        wheel_radius=p.number("wheel_radius", None),
        pose_covariance_diagonal=p.diagonal("pose_covariance_diagonal"),
        twist_covariance_diagonal=p.diagonal("twist_covariance_diagonal"),
        linear=_limiter(p, "linear/x"),
        angular=_limiter(p, "angular/z"),
    )


def wheel_geometry_from_urdf(urdf: Urdf, left: str, right: str, entry: str) -> tuple[float, float]:
    """``(separation, radius)`` as diff_drive_controller reads them from the URDF.

    The separation is the distance between the two joints' origins in their parents; the
    radius is the left wheel link's first collision shape, a cylinder or a sphere.

    Raises:
        RosControlError: a joint is missing or the wheel is not a cylinder or sphere.
    """
    for joint in (left, right):
        if joint not in urdf.joints:
            msg = (
                f"controller {entry!r}: wheel joint {joint!r} is not in robot {urdf.name!r}. "
                f"Fix: use one of {', '.join(urdf.joints) or 'no joints'}"
            )
            raise RosControlError(msg)
    a = np.asarray(urdf.joints[left].origin.xyz)
    b = np.asarray(urdf.joints[right].origin.xyz)
    separation = float(np.linalg.norm(a - b))
    link = urdf.links[urdf.joints[left].child]
    shape = link.collisions[0].geometry if link.collisions else None
    if not isinstance(shape, Cylinder | Sphere):
        msg = (
            f"controller {entry!r}: wheel link {link.name!r} is not modelled as a cylinder or "
            "sphere (its first <collision>), so the wheel radius cannot be read from the URDF. "
            f"Fix: set /{entry}/wheel_radius"
        )
        raise RosControlError(msg)
    return separation, float(shape.radius)


# --------------------------------------------------------------------------- hardware


class RobotHWSim:
    """``DefaultRobotHWSim``: the transmission joints, their state and their commands.

    Args:
        model: the compiled model.
        joints: ``(URDF joint, MuJoCo joint, interface, effort limit, velocity limit)``
            (limits <= 0: none).
    """

    def __init__(
        self, model: mujoco.MjModel, joints: Sequence[tuple[str, str, str, float, float]]
    ) -> None:
        self.names = [j[0] for j in joints]
        self.interfaces = [j[2] for j in joints]
        ids = [model.joint(j[1]).id for j in joints]
        self._qpos = np.array([model.jnt_qposadr[i] for i in ids], dtype=np.int64)
        self._dof = np.array([model.jnt_dofadr[i] for i in ids], dtype=np.int64)
        self._effort_limit = np.array([j[3] if j[3] > 0 else np.inf for j in joints])
        self._velocity_limit = np.array([j[4] if j[4] > 0 else np.inf for j in joints])
        self._velocity = np.array(
            [i == "VelocityJointInterface" for i in self.interfaces], dtype=bool
        )
        self._effort = np.array([i == "EffortJointInterface" for i in self.interfaces], dtype=bool)
        self.command = np.zeros(len(joints))
        self.claimed: dict[str, str] = {}
        self.e_stop = False
        self._servo = VelocityServo(
            model, self._dof[self._velocity].tolist(), self._effort_limit[self._velocity].tolist()
        )

    def rebind(self, ids: IdMap) -> None:
        """The same joints of a recompiled model (commands kept)."""
        self._qpos = ids.qpos(self._qpos)
        self._dof = ids.dof(self._dof)
        self._servo.rebind(ids)

    def index(self, joint: str) -> int:
        """The hardware index of ``joint``."""
        return self.names.index(joint)

    def positions(self, data: mujoco.MjData) -> NDArray[np.float64]:
        """Joint positions (rad or m)."""
        return np.asarray(data.qpos[self._qpos], dtype=np.float64)

    def velocities(self, data: mujoco.MjData) -> NDArray[np.float64]:
        """Joint velocities."""
        return np.asarray(data.qvel[self._dof], dtype=np.float64)

    def efforts(self, data: mujoco.MjData) -> NDArray[np.float64]:
        """Applied generalized forces (what Gazebo reports as the joint force)."""
        return np.asarray(data.qfrc_applied[self._dof] + data.qfrc_actuator[self._dof])

    def claim(self, joint: str, interface: str, controller: str) -> int:
        """Claim ``joint``'s ``interface`` for ``controller``; returns its index.

        Raises:
            RosControlError: no such transmission joint, another interface, or claimed.
        """
        if joint not in self.names:
            msg = (
                f"controller {controller!r}: joint {joint!r} has no transmission (the hardware "
                f"interface offers {', '.join(self.names) or 'no joints'}). Fix: add a "
                f"<transmission> with <joint name={joint!r}> and "
                f"<hardwareInterface>hardware_interface/{interface}</hardwareInterface>"
            )
            raise RosControlError(msg)
        i = self.index(joint)
        if self.interfaces[i] != interface:
            msg = (
                f"controller {controller!r} needs {interface} on joint {joint!r}, but its "
                f"transmission offers {self.interfaces[i]}. Fix: set <hardwareInterface>"
                f"hardware_interface/{interface}</hardwareInterface> in its <transmission>"
            )
            raise RosControlError(msg)
        owner = self.claimed.get(joint)
        if owner is not None and owner != controller:
            msg = (
                f"controllers {owner!r} and {controller!r} both command joint {joint!r} "
                "(a resource conflict: ros_control refuses to start the second). Fix: start one"
            )
            raise RosControlError(msg)
        self.claimed[joint] = controller
        return i

    def write(self, data: mujoco.MjData) -> None:
        """Apply the commands for one physics step."""
        command = np.zeros_like(self.command) if self.e_stop else self.command
        dof = self._dof
        if self._servo.dofs:
            v = self._velocity
            target = np.clip(command[v], -self._velocity_limit[v], self._velocity_limit[v])
            self._servo.apply(data, target.tolist())
        if self._effort.any():
            # Gazebo adds an effort joint's command to the joint's force (SetForce), so an
            # effort joint no controller drives leaves other plugins' forces alone (the
            # ROSbot's skid steer drives its four effort-interface wheels)
            e = self._effort & np.array([name in self.claimed for name in self.names], dtype=bool)
            if e.any():
                limit = self._effort_limit
                data.qfrc_applied[dof[e]] = np.clip(command, -limit, limit)[e]


# --------------------------------------------------------------------------- manager


Controller = DiffDriveRosController | JointStateRosController


@dataclass(frozen=True)
class _Context:
    node: Node
    namespace: str
    hw: RobotHWSim
    urdf: Urdf
    frame: Callable[[str], str]


def _make_diff_drive(ctx: _Context, entry: str, params: ControllerParameters) -> Controller:
    config = diff_drive_config(params)
    for joint in (*config.left_wheel, *config.right_wheel):
        ctx.hw.claim(joint, "VelocityJointInterface", entry)
    separation, radius = config.wheel_separation, config.wheel_radius
    if separation is None or radius is None:
        urdf_sep, urdf_radius = wheel_geometry_from_urdf(
            ctx.urdf, config.left_wheel[0], config.right_wheel[0], entry
        )
        separation = urdf_sep if separation is None else separation
        radius = urdf_radius if radius is None else radius
    name = entry.rsplit("/", 1)[-1]
    return DiffDriveRosController(
        ctx.node, name, ros1_join(ctx.namespace, name), config, ctx.hw,
        separation=separation, radius=radius, frame=ctx.frame,
    )  # fmt: skip


def _make_joint_state(ctx: _Context, entry: str, params: ControllerParameters) -> Controller:
    rate = params.number("publish_rate", None, minimum=0.0)
    if rate is None:
        msg = (
            f"controller {entry!r}: parameter {params.ros_name('publish_rate')} is not set "
            "(joint_state_controller requires it). Fix: e.g. publish_rate: 50"
        )
        raise RosControlError(msg)
    joints = params.names("joints", required=False) or tuple(sorted(ctx.hw.names))
    for joint in joints:
        if joint not in ctx.hw.names:
            msg = (
                f"controller {entry!r}: joint {joint!r} of {params.ros_name('joints')} has no "
                f"transmission (the hardware offers {', '.join(ctx.hw.names) or 'no joints'})"
            )
            raise RosControlError(msg)
    if params.raw("extra_joints") is not None:
        ctx.node.get_logger().warning(
            f"controller {entry!r}: extra_joints are not published by visnav", once=True
        )
    return JointStateRosController(
        ctx.node, ros1_join(ctx.namespace, "joint_states"), ctx.hw, joints, publish_rate=rate
    )


CONTROLLER_TYPES: Mapping[str, Callable[[_Context, str, ControllerParameters], Controller]] = {
    _DIFF_DRIVE: _make_diff_drive,
    _JOINT_STATE: _make_joint_state,
}
"""Controller type (the ``type`` parameter) -> its loader."""


def _names(node: Node, parameter: str) -> list[str]:
    if not node.has_parameter(parameter):
        node.declare_parameter(parameter, None)
    value = node.get_parameter(parameter).value
    if value is None:
        return []
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        msg = f"sim node parameter {parameter} is {value!r}: expected a list of controller names"
        raise RosControlError(msg)
    return [v.strip("/") for v in value if v.strip("/")]


def _parent(entry: str) -> str:
    head, _, _ = entry.rpartition("/")
    return ros1_join(head)


class RosControlPlugin(SimPlugin):
    """The controller manager of one robot (see the module docstring).

    Args:
        node: the manager's node (topics of its controllers).
        spec: the plugin with its final namespace and e-stop topic.
        hw: the robot hardware.
        controllers: the started controllers, by name.
        loaded: names of controllers only loaded (``--stopped``).
        control_period_ns: update period (0: every physics step).
    """

    def __init__(
        self,
        node: Node,
        spec: RosControlSpec,
        hw: RobotHWSim,
        controllers: Mapping[str, Controller],
        *,
        loaded: Sequence[str] = (),
        control_period_ns: int = 0,
    ) -> None:
        super().__init__(node, spec.plugin_name)
        self.spec = spec
        self.hw = hw
        self.controllers = dict(controllers)
        self.loaded = tuple(loaded)
        self._period_ns = control_period_ns
        self._last_ns: int | None = None
        if spec.e_stop_topic:
            node.create_subscription(Bool, spec.e_stop_topic, self._on_e_stop, 10)

    def rewind(self, now_ns: int) -> None:
        """Sim time went back to ``now_ns``: the control period and controllers restart."""
        self._last_ns = None
        for controller in self.controllers.values():
            starting = getattr(controller, "starting", None)
            if callable(starting):
                starting(now_ns)

    def rebind(self, ids: IdMap) -> None:
        """Drive the same joints of a recompiled model (controllers keep their state)."""
        self.hw.rebind(ids)

    def _on_e_stop(self, msg: Bool) -> None:
        self.hw.e_stop = bool(msg.data)

    def control(self, data: mujoco.MjData, now_ns: int) -> None:
        """Update the controllers when a control period has passed; write every step."""
        if self._last_ns is None:
            for controller in self.controllers.values():
                controller.starting(now_ns)
            self._last_ns = now_ns - self._period_ns
        period = now_ns - self._last_ns
        if period >= self._period_ns:
            self._last_ns = now_ns
            for controller in self.controllers.values():
                controller.update(data, now_ns, period)
        self.hw.write(data)


def make_ros_control(build: RobotBuild, spec: RosControlSpec) -> SimPlugin | None:
    """``libgazebo_ros_control.so``: the controller manager with the spawned controllers.

    Raises:
        RosControlError: a spawned controller cannot be loaded (see the module docstring).
    """
    namespace = ros1_join(push_namespace(build.namespace, spec.robot_namespace) or "/")
    e_stop = spec.e_stop_topic
    if e_stop:  # relative to the plugin's namespace, as the plugin's NodeHandle resolves it
        e_stop = build.push(e_stop) if e_stop.startswith("/") else ros1_join(namespace, e_stop)
    spec = replace(spec, robot_namespace=namespace, e_stop_topic=e_stop)
    model, urdf = build.model, build.description.urdf
    params_node = build.sim_node
    joints = []
    for t in spec.transmissions:
        limit = urdf.joints[t.joint].limit
        joints.append((
            t.joint, build.handles.joints[t.joint], t.interface,
            limit.effort if limit is not None else 0.0,
            limit.velocity if limit is not None else 0.0,
        ))  # fmt: skip
    hw = RobotHWSim(model, joints)
    node = Node(node_name("controller_manager"), namespace=namespace, context=build.context)
    ctx = _Context(node, namespace, hw, urdf, build.frame)
    started: dict[str, Controller] = {}
    stopped: list[str] = []
    try:
        if params_node is not None:
            for parameter, run in (("controllers", True), ("stopped_controllers", False)):
                for entry in _names(params_node, parameter):
                    if _parent(entry) != namespace:
                        continue
                    controller = _load(ctx, params_node, entry)
                    if run:
                        started[entry.rsplit("/", 1)[-1]] = controller
                    else:
                        stopped.append(entry)
                        for joint, owner in list(hw.claimed.items()):
                            if owner == entry:
                                del hw.claimed[joint]
    except BaseException:
        node.destroy_node()
        raise
    period_ns = round(spec.control_period * 1e9)
    if period_ns and period_ns < round(float(model.opt.timestep) * 1e9):
        node.get_logger().warning(
            f"plugin {spec.plugin_name!r}: controlPeriod {spec.control_period} s is shorter than "
            f"the physics step; the controllers update every step"
        )
        period_ns = 0
    for controller in started.values():
        if isinstance(controller, JointStateRosController):
            build.covered_joints.update(controller.joints)
            build.joint_states_topic = controller.topic
    return RosControlPlugin(node, spec, hw, started, loaded=stopped, control_period_ns=period_ns)


def _load(ctx: _Context, params_node: Node, entry: str) -> Controller:
    params = ControllerParameters(params_node, entry)
    kind = params.raw("type")
    if kind is None:
        msg = (
            f"controller {entry!r} was spawned but parameter /{entry}/type is not set (no "
            'configuration loaded for it). Fix: load its YAML with <rosparam command="load"> '
            "before the spawner, with type: diff_drive_controller/DiffDriveController or "
            "joint_state_controller/JointStateController"
        )
        raise RosControlError(msg)
    loader = CONTROLLER_TYPES.get(str(kind))
    if loader is None:
        msg = (
            f"controller {entry!r}: type {kind!r} is not simulated; visnav has "
            f"{', '.join(CONTROLLER_TYPES)}. Fix: use one of those, or drive the robot with a "
            "gazebo plugin (libgazebo_ros_diff_drive.so)"
        )
        raise RosControlError(msg)
    return loader(ctx, entry, params)


def check_spawned_controllers(node: Node, plugins: Sequence[SimPlugin]) -> None:
    """Refuse ``controllers`` / ``stopped_controllers`` that no controller manager took.

    Args:
        node: the sim node (its parameters).
        plugins: every plugin of the simulation.

    Raises:
        RosControlError: an entry whose namespace has no robot with libgazebo_ros_control.so.
    """
    managers = [p for p in plugins if isinstance(p, RosControlPlugin)]
    namespaces = sorted({m.spec.robot_namespace for m in managers})
    for parameter in ("controllers", "stopped_controllers"):
        for entry in _names(node, parameter):
            if _parent(entry) in namespaces:
                continue
            where = (
                f"the controller managers are in {', '.join(namespaces)}"
                if namespaces
                else "no robot has a libgazebo_ros_control.so plugin"
            )
            msg = (
                f"controller {entry!r} ({parameter}) is for a controller manager in "
                f"{_parent(entry)}, but {where}. Fix: add <gazebo><plugin "
                'name="gazebo_ros_control" filename="libgazebo_ros_control.so">'
                "<robotNamespace>...</robotNamespace></plugin></gazebo> to the robot, or run the "
                "spawner in the robot's namespace"
            )
            raise RosControlError(msg)
