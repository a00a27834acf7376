"""The robots of a simulation: where they go, the MuJoCo spec they compose, their runtimes.

:class:`~visnav.sim.simulator.Simulator` composes its model from the world and a list of
:class:`Placement` (robots in order; MuJoCo ids follow that order), and builds each robot's
sensor and plugin runtimes with :func:`build_robot`. Spawning or deleting a model composes
the list again (:mod:`visnav.sim.rebind`).
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from visnav.description.robot import RobotDescription
from visnav.description.robots import resolve_robot
from visnav.description.worldmodel import WorldDescription
from visnav.graph.context import Context
from visnav.graph.node import Node
from visnav.sim.camera import RenderContext, render_layout
from visnav.sim.contact_sensor import ContactSensor
from visnav.sim.guards import check_spawn_pose
from visnav.sim.plugin_factories import (
    RobotBuild,
    build_plugins,
    node_name,
    publishes,
    push_namespace,
)
from visnav.sim.plugins import CameraPlugin, SimPlugin
from visnav.sim.quadrotor_plugin import QuadrotorPlugin
from visnav.sim.robot import RobotHandles, add_robot_to_spec
from visnav.sim.world_spec import build_world_spec
from visnav.tf.robot_state import RobotStateModel
from visnav.tf.robot_state_node import RobotStatePublisher

__all__ = [
    "BuildContext",
    "Placement",
    "RobotSpawn",
    "SimRobot",
    "build_robot",
    "compose_spec",
    "default_spawn",
    "place_robots",
    "render_context_for",
    "rest_on_ground",
]

_LOG = logging.getLogger("visnav.sim")


@dataclass(frozen=True, kw_only=True)
class RobotSpawn:
    """One robot to put into the world.

    Attributes:
        source: a built-in name (``car``, ``quadrotor``), a URDF / Xacro file, URDF
            XML text, or a loaded :class:`~visnav.sim.robot.RobotDescription`.
        args: Xacro ``name:=value`` arguments.
        packages: package name -> directory for ``package://`` / ``$(find pkg)``.
        name: the robot's MuJoCo name prefix (``<name>/``); default the URDF
            ``<robot name>``, made unique.
        spawn: ``(x, y, z, yaw)`` of the root link in the world (m, rad); default
            the world's ``spawn`` ([x, y, yaw]) or ``start`` metadata (facing ``goal``),
            else the origin, with a free-floating robot resting on the ground.
        namespace: pushed onto every topic of the robot (``/r1`` makes
            ``/camera/image_raw`` ``/r1/camera/image_raw``), like spawning a Gazebo
            robot with ``-robot_namespace``; the robot's nodes live in it.
        frame_prefix: prepended to every TF frame id of the robot (``r1/`` makes
            ``base_link`` ``r1/base_link``), as robot_state_publisher's
            ``frame_prefix``; ``world`` and ``map`` stay unprefixed.
    """

    source: str | os.PathLike[str] | RobotDescription = "car"
    args: Mapping[str, str] = field(default_factory=dict)
    packages: Mapping[str, Path | str] | None = None
    name: str | None = None
    spawn: tuple[float, float, float, float] | None = None
    namespace: str = "/"
    frame_prefix: str = ""


@dataclass
class SimRobot:
    """One robot in the running simulation.

    Attributes:
        name: its name (MuJoCo prefix without the slash).
        description: the loaded robot.
        handles: its MuJoCo element names.
        namespace: its topic namespace.
        frame_prefix: its TF frame prefix.
        plugins: its sensor and plugin runtimes.
        robot_state: its robot_state_publisher.
        quadrotor: its quadrotor plugin, if it flies.
        cameras: its rendering cameras (also in ``plugins``).
    """

    name: str
    description: RobotDescription
    handles: RobotHandles
    namespace: str
    frame_prefix: str
    plugins: list[SimPlugin] = field(default_factory=list)
    robot_state: RobotStatePublisher | None = None
    quadrotor: QuadrotorPlugin | None = None
    cameras: list[CameraPlugin] = field(default_factory=list)


@dataclass(frozen=True)
class Placement:
    """A robot in the composed spec: what it is, its name and its spawn pose.

    Attributes:
        description: the loaded robot.
        spawn: how it was asked for.
        name: its unique name (MuJoCo prefix without the slash).
        pose: ``(x, y, z, yaw)`` of its root link.
        quat_wxyz: a full orientation (SpawnModel's ``initial_pose``), overriding the yaw.
    """

    description: RobotDescription
    spawn: RobotSpawn
    name: str
    pose: tuple[float, float, float, float]  # x, y, z, yaw
    quat_wxyz: tuple[float, float, float, float] | None = None  # overrides the yaw


def _namespace(ns: str) -> str:
    stripped = ns.strip("/")
    return "/" + stripped if stripped else "/"


def default_spawn(world: WorldDescription) -> tuple[float, float, float]:
    """``(x, y, yaw)`` from the world's ``spawn`` or ``start`` metadata (facing ``goal``)."""
    meta = world.metadata
    spawn = meta.get("spawn")
    if isinstance(spawn, (list, tuple)) and len(spawn) >= 2:
        yaw = float(spawn[2]) if len(spawn) >= 3 else 0.0
        return float(spawn[0]), float(spawn[1]), yaw
    start = meta.get("start")
    if isinstance(start, (list, tuple)) and len(start) >= 2:
        x, y = float(start[0]), float(start[1])
        goal = meta.get("goal")
        yaw = 0.0
        if isinstance(goal, (list, tuple)) and len(goal) >= 2:
            yaw = math.atan2(float(goal[1]) - y, float(goal[0]) - x)
        return x, y, yaw
    return 0.0, 0.0, 0.0


def place_robots(world: WorldDescription, spawns: Sequence[RobotSpawn]) -> list[Placement]:
    """Load each robot, give it a unique name and a checked spawn pose.

    Raises:
        RobotDescriptionError: a robot cannot be loaded.
        SpawnPoseError: a spawn pose is not finite or outside the world.
    """
    placed: list[Placement] = []
    used: set[str] = set()
    default_xy_yaw = default_spawn(world)
    for spawn in spawns:
        desc = resolve_robot(spawn.source, args=spawn.args, packages=spawn.packages)
        base = node_name(spawn.name or desc.name)
        name, k = base, 2
        while name in used:
            name, k = f"{base}_{k}", k + 1
        used.add(name)
        if spawn.spawn is None:
            x, y, yaw = default_xy_yaw
            pose: tuple[float, float, float, float] = (x, y, 0.0, yaw)
        else:
            pose = check_spawn_pose(spawn.spawn, world, robot=name)
        placed.append(Placement(desc, spawn, name, pose))
    return placed


def compose_spec(
    world: WorldDescription, placements: Sequence[Placement], *, msaa_samples: int = 0
) -> tuple[mujoco.MjSpec, list[RobotHandles]]:
    """A new spec of the world with these robots, in order (ids follow that order)."""
    spec = build_world_spec(world)
    spec.visual.quality.offsamples = int(msaa_samples)
    handles = []
    for p in placements:
        h = add_robot_to_spec(spec, p.description, prefix=f"{p.name}/", spawn_xyz_yaw=p.pose)
        if p.quat_wxyz is not None and h.free_joint is not None:
            root = spec.body(h.root_body)  # a full orientation (SpawnModel's initial_pose)
            root.pos = [float(v) for v in p.pose[:3]]
            root.quat = [float(v) for v in p.quat_wxyz]
        handles.append(h)
    return spec, handles


def render_context_for(
    model: mujoco.MjModel, placements: Sequence[Placement]
) -> RenderContext | None:
    """The offscreen renderer every camera of these robots shares (None: no camera)."""
    cameras = [c for p in placements for c in p.description.gazebo.cameras if publishes(c)]
    if not cameras:
        return None
    layouts = [render_layout(c, with_maps=False) for c in cameras]
    return RenderContext(
        model,
        max_width=max(layout.width for layout in layouts),
        max_height=max(layout.height for layout in layouts),
    )


def rest_on_ground(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    world: WorldDescription,
    placed: Sequence[tuple[RobotHandles, RobotSpawn]],
) -> None:
    """Lift free-floating robots without an explicit spawn height onto the ground."""
    mujoco.mj_kinematics(model, data)
    ground = world.ground.z if world.ground is not None else 0.0
    for handles, spawn in placed:
        if spawn.spawn is not None or handles.free_joint is None:
            continue
        root = model.body(handles.root_body).id
        lowest = math.inf
        for g in range(model.ngeom):
            body = int(model.geom_bodyid[g])
            if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
                continue
            if body != root and not _is_descendant(model, body, root):
                continue
            centre, half = model.geom_aabb[g][:3], model.geom_aabb[g][3:]
            signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
            corners = centre + signs * half
            world_corners = data.geom_xpos[g] + corners @ data.geom_xmat[g].reshape(3, 3).T
            lowest = min(lowest, float(world_corners[:, 2].min()))
        if math.isfinite(lowest):
            adr = model.joint(handles.free_joint).qposadr[0]
            data.qpos[adr + 2] += ground - lowest


@dataclass(frozen=True, kw_only=True)
class BuildContext:
    """What every robot of one simulation is built with.

    Attributes:
        model: the compiled model the plugins bind to.
        context: the graph context of the plugin nodes.
        seed: the run's seed.
        sim_node: the simulator's node.
        now_ns: sim time the robot enters the simulation.
        contact_rate: > 0: a contact sensor at this rate.
        render_context: the shared renderer, if any robot has cameras.
    """

    model: mujoco.MjModel
    context: Context
    seed: int
    sim_node: Node
    now_ns: int = 0
    contact_rate: float = 0.0
    render_context: RenderContext | None = None


def build_robot(
    where: BuildContext, desc: RobotDescription, handles: RobotHandles, spawn: RobotSpawn, name: str
) -> SimRobot:
    """A robot's sensor and plugin runtimes and robot_state_publisher (closed on failure).

    Raises:
        SimulatorError, VisnavError: a plugin does not fit the robot or the model.
    """
    model = where.model
    ns = _namespace(spawn.namespace)
    prefix = spawn.frame_prefix
    robot = SimRobot(name, desc, handles, ns, prefix)
    state_model = RobotStateModel(desc.urdf, frame_prefix=prefix)
    build = RobotBuild(
        model=model,
        context=where.context,
        name=name,
        description=desc,
        handles=handles,
        namespace=ns,
        frame_prefix=prefix,
        seed=where.seed,
        state_model=state_model,
        render_context=where.render_context,
        joint_states_topic=push_namespace(ns, "/joint_states") or "/joint_states",
        sim_node=where.sim_node,
        start_ns=where.now_ns,
    )
    try:
        robot.plugins.extend(build_plugins(build))
    except Exception:
        for camera in build.cameras:
            camera.close()
            camera.sensor.close()
        raise
    finally:
        robot.cameras = list(build.cameras)
        robot.quadrotor = build.quadrotor
    if where.contact_rate > 0:
        root = model.body(handles.root_body).id
        sensor = ContactSensor(build.node("bumper"), model, root, where.contact_rate)
        robot.plugins.append(sensor)
    missing = [j for j in state_model.moving_joints if j not in build.covered_joints]
    if missing:
        _LOG.warning(
            "robot %r: moving joints %s are in no libgazebo_ros_joint_state_publisher.so "
            "plugin, so robot_state_publisher puts their child frames on no /tf",
            name,
            missing,
        )
    robot.robot_state = RobotStatePublisher(
        build.node("robot_state_publisher"),
        state_model,
        desc.xml,
        joint_states_topic=build.joint_states_topic,
        stamp_ns=where.now_ns,
    )
    return robot


def _is_descendant(model: mujoco.MjModel, body: int, root: int) -> bool:
    while body > 0:
        body = int(model.body_parentid[body])
        if body == root:
            return True
    return False
