"""The simulator: a world, robots with Gazebo-style sensors and plugins, a sim clock.

::

    from visnav.graph import Context
    from visnav.sim.simulator import RobotSpawn, Simulator

    with Context() as ctx, Simulator("office", [RobotSpawn(source="car")], context=ctx) as sim:
        stats = sim.run(10.0)              # 10 s of sim time, lock-step, as fast as it goes
        print(stats.real_time_factor)

The world and the robots become one MuJoCo model; each ``<gazebo>`` sensor and
plugin of a robot becomes a graph node in the given context (see
:mod:`visnav.sim.plugins`): cameras and depth cameras (with point clouds), p3d
ground truth, the differential drive, IMUs, joint states, the quadrotor, and a
robot_state_publisher (``robot_description``, ``/tf_static`` for fixed joints,
``/tf`` from the joint states). A node ``/sim`` publishes ``/clock``
(``rosgraph_msgs/Clock``) and serves gazebo_ros' ``/gazebo/*`` services
(:mod:`visnav.sim.gazebo_services`).

Time. Physics advances in fixed steps of the world's ``physics.timestep``;
sim time is the integer ``k * dt`` in nanoseconds. Each step: ``mj_step1``
(state at ``t``), ``/clock`` = ``t``, sensors due at ``t`` publish (each on its
own drift-free schedule), controllers act, then the simulator runs the callbacks
ready in the context (:meth:`~visnav.graph.Context.spin_some`) so in-process
nodes react at sim time ``t`` (their ``use_sim_time`` timers fire), then
``mj_step2`` integrates to ``t + dt``. This is lock-step and, for a seed,
deterministic: two runs give identical messages (nodes in other processes see
the same messages but react asynchronously). With ``realtime=True`` the loop waits
for the wall clock (spinning the context meanwhile); either way
:attr:`Simulator.stats` reports the real-time factor and the share of wall time
spent rendering. Cameras render only when due, with MSAA off by default.

Robots. Built-in names (``car``, ``quadrotor``), URDF / Xacro files or XML text,
or loaded :class:`~visnav.sim.robot.RobotDescription`; see :class:`RobotSpawn`
for the spawn pose (default: the world's ``spawn`` / ``start`` metadata, resting
on the ground), a topic namespace and a TF frame prefix per robot.

Where visnav differs from Gazebo: ``/clock`` is published every physics step by
default (gazebo_ros publishes it at 10 Hz in ROS 2), so ``use_sim_time`` timers
fire on time; plugin nodes stamp with sim time but do not subscribe to ``/clock``
themselves; a robot namespace is prefixed to every topic of the robot, including
absolute remappings.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from visnav.description.robot import RobotDescription
from visnav.description.robots import resolve_robot
from visnav.description.world import load_world
from visnav.description.worldmodel import WorldDescription
from visnav.graph.context import Context
from visnav.graph.node import Node
from visnav.graph.qos import QoSProfile
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Clock
from visnav.sim.camera import RenderContext, render_layout
from visnav.sim.contact_sensor import ContactSensor
from visnav.sim.errors import SimulatorError
from visnav.sim.gazebo_services import GazeboServices
from visnav.sim.guards import InstabilityMonitor, check_spawn_pose, route_mujoco_warnings
from visnav.sim.model_states import model_states_publisher
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
from visnav.sim.sensor_timing import SensorClock
from visnav.sim.vehicles.quadrotor import PositionCommand
from visnav.sim.world_spec import build_world_spec
from visnav.tf.robot_state import RobotStateModel
from visnav.tf.robot_state_node import RobotStatePublisher

__all__ = [
    "RobotSpawn",
    "SimRobot",
    "SimStats",
    "Simulator",
    "SimulatorError",
]

_CLOCK_QOS = QoSProfile(depth=1)
_MAX_BACKLOG_NS = 100_000_000  # realtime: wall-clock lag dropped instead of caught up
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


@dataclass(frozen=True)
class SimStats:
    """Timing of a run (or of the whole simulation).

    Attributes:
        sim_time_s: simulated seconds.
        wall_time_s: wall-clock seconds.
        steps: physics steps.
        render_time_s: wall seconds spent rendering cameras.
        frames: camera frames rendered.
    """

    sim_time_s: float
    wall_time_s: float
    steps: int
    render_time_s: float
    frames: int

    @property
    def real_time_factor(self) -> float:
        """Sim time per wall time (inf for an instantaneous run)."""
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else math.inf

    @property
    def render_share(self) -> float:
        """Fraction of wall time spent rendering."""
        return self.render_time_s / self.wall_time_s if self.wall_time_s > 0 else 0.0

    def summary(self) -> str:
        """One line: sim time, wall time, real-time factor, rendering share."""
        return (
            f"sim time {self.sim_time_s:.2f} s in {self.wall_time_s:.2f} s wall: real-time "
            f"factor {self.real_time_factor:.2f} ({self.steps} steps, {self.frames} camera "
            f"frames, rendering {100.0 * self.render_share:.0f}% of wall time)"
        )


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
    """

    name: str
    description: RobotDescription
    handles: RobotHandles
    namespace: str
    frame_prefix: str
    plugins: list[SimPlugin] = field(default_factory=list)
    robot_state: RobotStatePublisher | None = None
    quadrotor: QuadrotorPlugin | None = None


def _namespace(ns: str) -> str:
    stripped = ns.strip("/")
    return "/" + stripped if stripped else "/"


def _default_spawn(world: WorldDescription) -> tuple[float, float, float]:
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


class Simulator:
    """A MuJoCo world with robots whose sensors and plugins publish on the graph.

    Args:
        world: a :class:`~visnav.description.worldmodel.WorldDescription`, a built-in world name or
            a world file (:func:`~visnav.description.world.load_world`).
        robots: the robots (:class:`RobotSpawn`, or just a source each).
        context: the graph context; every simulator node is created in it, so
            in-process subscribers get messages without copies.
        seed: seeds every sensor's noise and the vehicles' disturbances (per sensor,
            :func:`~visnav.sim.sensor_timing.sensor_seed`).
        realtime: pace sim time to the wall clock (otherwise as fast as possible).
        real_time_factor: the target ratio of sim to wall time when ``realtime``.
        clock_rate: ``/clock`` messages per simulated second; 0 = every physics step.
        msaa_samples: multisampling of the camera renders (0 = off, the cheap default;
            MuJoCo's default 4 costs about as much again in software GL).
        node: the node that publishes ``/clock`` (default: a new node ``sim``, destroyed
            by :meth:`close`).
        contact_rate: > 0: each robot publishes its contacts on ``<namespace>/bumper_states``
            at this rate (Hz of sim time; :mod:`visnav.sim.contact_sensor`).

    Raises:
        SimulatorError: MuJoCo rejects the composed model, or a plugin does not fit it.
        RobotDescriptionError, WorldError: a robot or the world cannot be loaded.
        RenderingUnavailableError: a robot has cameras but there is no headless OpenGL.
    """

    def __init__(
        self,
        world: WorldDescription | str | os.PathLike[str],
        robots: Sequence[RobotSpawn | str | os.PathLike[str] | RobotDescription] = (),
        *,
        context: Context,
        seed: int = 0,
        realtime: bool = False,
        real_time_factor: float = 1.0,
        clock_rate: float = 0.0,
        msaa_samples: int = 0,
        node: Node | None = None,
        contact_rate: float = 0.0,
    ) -> None:
        if not (math.isfinite(real_time_factor) and real_time_factor > 0):
            msg = f"real_time_factor is {real_time_factor}: expected a positive number"
            raise SimulatorError(msg)
        self.context = context
        self.seed = int(seed)
        self.realtime = realtime
        self.real_time_factor = float(real_time_factor)
        self.world = world if isinstance(world, WorldDescription) else load_world(world)
        spawns = [r if isinstance(r, RobotSpawn) else RobotSpawn(source=r) for r in robots]
        route_mujoco_warnings()  # not to stdout and MUJOCO_LOG.TXT in the cwd
        spec = build_world_spec(self.world)
        spec.visual.quality.offsamples = int(msaa_samples)
        placed = self._add_robots(spec, spawns)
        try:
            self.model = spec.compile()
        except Exception as exc:  # MuJoCo raises ValueError and others
            msg = f"MuJoCo cannot compile world {self.world.name!r} with the robots: {exc}"
            raise SimulatorError(msg) from exc
        self.data = mujoco.MjData(self.model)
        self._stability = InstabilityMonitor(self.data)
        self._rest_on_ground(placed)
        mujoco.mj_forward(self.model, self.data)
        self._dt_ns = round(float(self.model.opt.timestep) * 1e9)
        self._split = self.model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4
        self._now_ns = 0
        self._steps = 0
        self._wall_ns = 0
        self._render_ctx: RenderContext | None = None
        self._cameras: list[CameraPlugin] = []
        self._clock = SensorClock(clock_rate)
        self._pace_ref = (0, 0)
        self._closed = False
        self._paused = False  # /gazebo/pause_physics: run() spins without stepping
        self._in_step = False  # callbacks run inside a step (lock-step spin_some)
        self._edits: list[Callable[[], None]] = []  # state edits deferred to the step's end
        self.robots: list[SimRobot] = []
        cameras = [c for desc, *_ in placed for c in desc.gazebo.cameras if publishes(c)]
        if cameras:
            layouts = [render_layout(c, with_maps=False) for c in cameras]
            self._render_ctx = RenderContext(
                self.model,
                max_width=max(layout.width for layout in layouts),
                max_height=max(layout.height for layout in layouts),
            )
        self._contact_rate = float(contact_rate)  # > 0: each robot's bumper_states topic
        self._owns_node = node is None
        self._node = node if node is not None else Node("sim", context=context)
        self._clock_pub = self._node.create_publisher(Clock, "/clock", _CLOCK_QOS)
        try:
            for desc, handles, spawn, name in placed:
                self.robots.append(self._make_robot(desc, handles, spawn, name))
        except Exception:
            self.close()
            raise
        self.model_states = model_states_publisher(self)  # /gazebo/model_states, link_states
        plugins = [p for r in self.robots for p in r.plugins] + [self.model_states]
        self._sense = [p.sense for p in plugins if type(p).sense is not SimPlugin.sense]
        self._control = [p.control for p in plugins if type(p).control is not SimPlugin.control]
        self._after = [
            p.after_step for p in plugins if type(p).after_step is not SimPlugin.after_step
        ]
        self.gazebo_services = GazeboServices(self)  # /gazebo/* services on the node

    # ------------------------------------------------------------------ building

    def _add_robots(
        self, spec: mujoco.MjSpec, spawns: Sequence[RobotSpawn]
    ) -> list[tuple[RobotDescription, RobotHandles, RobotSpawn, str]]:
        placed = []
        used: set[str] = set()
        default_xy_yaw = _default_spawn(self.world)
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
                pose = check_spawn_pose(spawn.spawn, self.world, robot=name)
            handles = add_robot_to_spec(spec, desc, prefix=f"{name}/", spawn_xyz_yaw=pose)
            placed.append((desc, handles, spawn, name))
        return placed

    def _rest_on_ground(
        self, placed: Sequence[tuple[RobotDescription, RobotHandles, RobotSpawn, str]]
    ) -> None:
        """Lift free-floating robots without an explicit spawn height onto the ground."""
        model, data = self.model, self.data
        mujoco.mj_kinematics(model, data)
        ground = self.world.ground.z if self.world.ground is not None else 0.0
        for _, handles, spawn, _ in placed:
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
                world = data.geom_xpos[g] + corners @ data.geom_xmat[g].reshape(3, 3).T
                lowest = min(lowest, float(world[:, 2].min()))
            if math.isfinite(lowest):
                adr = model.joint(handles.free_joint).qposadr[0]
                data.qpos[adr + 2] += ground - lowest

    def _make_robot(
        self, desc: RobotDescription, handles: RobotHandles, spawn: RobotSpawn, name: str
    ) -> SimRobot:
        ns = _namespace(spawn.namespace)
        prefix = spawn.frame_prefix
        robot = SimRobot(name, desc, handles, ns, prefix)
        state_model = RobotStateModel(desc.urdf, frame_prefix=prefix)
        build = RobotBuild(
            model=self.model,
            context=self.context,
            name=name,
            description=desc,
            handles=handles,
            namespace=ns,
            frame_prefix=prefix,
            seed=self.seed,
            state_model=state_model,
            render_context=self._render_ctx,
            joint_states_topic=push_namespace(ns, "/joint_states") or "/joint_states",
            sim_node=self._node,
        )
        try:
            robot.plugins.extend(build_plugins(build))
        finally:
            self._cameras.extend(build.cameras)
            robot.quadrotor = build.quadrotor
        if self._contact_rate > 0:
            root = self.model.body(handles.root_body).id
            sensor = ContactSensor(build.node("bumper"), self.model, root, self._contact_rate)
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
            stamp_ns=self._now_ns,
        )
        return robot

    # ------------------------------------------------------------------ running

    @property
    def node(self) -> Node:
        """The simulator's node: ``/clock``, ``/gazebo/model_states`` and ``link_states``."""
        return self._node

    @property
    def now_ns(self) -> int:
        """Sim time of the current state (ns)."""
        return self._now_ns

    @property
    def sim_time_s(self) -> float:
        """Sim time of the current state (s)."""
        return self._now_ns * 1e-9

    @property
    def timestep_ns(self) -> int:
        """Physics step (ns)."""
        return self._dt_ns

    @property
    def stats(self) -> SimStats:
        """Timing since the simulator was created."""
        return SimStats(
            sim_time_s=self._now_ns * 1e-9,
            wall_time_s=self._wall_ns * 1e-9,
            steps=self._steps,
            render_time_s=sum(c.render_ns for c in self._cameras) * 1e-9,
            frames=sum(c.frames for c in self._cameras),
        )

    def robot(self, name: str | None = None) -> SimRobot:
        """The robot called ``name`` (default: the only or first robot).

        Raises:
            SimulatorError: no such robot.
        """
        if name is None and self.robots:
            return self.robots[0]
        for robot in self.robots:
            if robot.name == name:
                return robot
        names = [r.name for r in self.robots]
        msg = f"no robot {name!r} in the simulation (robots: {names})"
        raise SimulatorError(msg)

    def set_position_command(self, command: PositionCommand, *, robot: str | None = None) -> None:
        """Give a quadrotor a ``PositionCommand`` (the Python way to fly it).

        Raises:
            SimulatorError: the robot has no ``libvisnav_quadrotor.so`` plugin.
        """
        target = self.robot(robot)
        if target.quadrotor is None:
            msg = (
                f"robot {target.name!r} has no libvisnav_quadrotor.so plugin; position "
                "commands fly quadrotors (use cmd_vel for a diff drive)"
            )
            raise SimulatorError(msg)
        target.quadrotor.set_command(command)

    def _step_once(self, *, spin: bool = True) -> None:
        model, data, now = self.model, self.data, self._now_ns
        if self._split:
            mujoco.mj_step1(model, data)
        else:
            mujoco.mj_forward(model, data)
        if self._clock.due(now):
            self._clock_pub.publish(Clock(clock=ns_to_time(now)))
        for sense in self._sense:
            sense(data, now)
        for control in self._control:
            control(data, now)
        if spin:
            self._in_step = True
            try:
                self.context.spin_some()
            finally:
                self._in_step = False
        if self._split:
            mujoco.mj_step2(model, data)
        else:
            mujoco.mj_step(model, data)
        self._stability.check(now + self._dt_ns)
        for after in self._after:
            after(data, now)
        self._now_ns = now + self._dt_ns
        self._steps += 1
        while self._edits:
            self._edits.pop(0)()

    def step(self, n: int = 1, *, spin: bool = True) -> None:
        """Advance ``n`` physics steps (never paced to the wall clock).

        Args:
            n: physics steps.
            spin: run the context's ready callbacks after each step (lock-step). Each
                spin needs the context idle: do not step with ``spin`` (or :meth:`run`)
                from a callback of that context, nor while another thread spins it.
                ``spin=False`` is for stepping from a callback (the caller's executor
                then delivers the messages, after the ``n`` steps).
        """
        self._check_open()
        start = time.perf_counter_ns()
        for _ in range(n):
            self._step_once(spin=spin)
        self._wall_ns += time.perf_counter_ns() - start

    def run(
        self, duration_s: float | None = None, *, until: Callable[[], bool] | None = None
    ) -> SimStats:
        """Run for ``duration_s`` of sim time (None: until ``until()`` or shutdown).

        Args:
            duration_s: simulated seconds to run.
            until: stop as soon as this returns True (checked before every step).

        Returns:
            The timing of this run (real-time factor, rendering share).
        """
        self._check_open()
        if duration_s is not None and not (math.isfinite(duration_s) and duration_s >= 0):
            msg = f"duration is {duration_s}: expected a finite number of seconds >= 0"
            raise SimulatorError(msg)
        end_ns = None if duration_s is None else self._now_ns + round(duration_s * 1e9)
        before = self.stats
        wall0 = time.perf_counter_ns()
        self._pace_ref = (wall0, self._now_ns)
        ctx = self.context
        try:
            while ctx.ok:
                if end_ns is not None and self._now_ns >= end_ns:
                    break
                if until is not None and until():
                    break
                if self._paused:  # Gazebo's paused world: time stands, callbacks run
                    ctx.spin_once(0.01)
                    continue
                self._step_once()
                if self.realtime:
                    self._pace()
        finally:
            self._wall_ns += time.perf_counter_ns() - wall0
        after = self.stats
        return SimStats(
            sim_time_s=after.sim_time_s - before.sim_time_s,
            wall_time_s=after.wall_time_s - before.wall_time_s,
            steps=after.steps - before.steps,
            render_time_s=after.render_time_s - before.render_time_s,
            frames=after.frames - before.frames,
        )

    def _pace(self) -> None:
        """Wait (spinning the context) until the wall clock reaches the sim time.

        A backlog of more than :data:`_MAX_BACKLOG_NS` (the simulation ran slower
        than real time) is dropped rather than caught up in a burst, as Gazebo does.
        """
        wall0, sim0 = self._pace_ref
        target = wall0 + (self._now_ns - sim0) / self.real_time_factor
        now = time.perf_counter_ns()
        if target < now - _MAX_BACKLOG_NS:
            self._pace_ref = (now, self._now_ns)
            return
        while self.context.ok:
            remaining = (target - time.perf_counter_ns()) * 1e-9
            if remaining <= 0:
                return
            self.context.spin_once(remaining)

    @property
    def paused(self) -> bool:
        """True while physics is paused (``/gazebo/pause_physics``): sim time stands still."""
        return self._paused

    def pause(self) -> None:
        """Stop stepping: :meth:`run` keeps serving callbacks, ``/clock`` stops advancing.

        :meth:`step` still advances when called (Gazebo's single step while paused).
        """
        self._paused = True

    def unpause(self) -> None:
        """Resume stepping; realtime pacing restarts from now (no catching up)."""
        if self._paused:
            self._paused = False
            self._pace_ref = (time.perf_counter_ns(), self._now_ns)

    def edit(self, change: Callable[[], None]) -> None:
        """Change the physics state now, or at the end of the step a callback runs in.

        A service callback called by the lock-step spin (between ``mj_step1`` and
        ``mj_step2``) must not move bodies under the half-computed step; its change runs
        after the step instead, before the next one.
        """
        if self._in_step:
            self._edits.append(change)
        else:
            change()

    def _check_open(self) -> None:
        if self._closed:
            msg = "the simulator is closed; create a new Simulator"
            raise SimulatorError(msg)

    def close(self) -> None:
        """Destroy the simulator's nodes and free the renderer (idempotent)."""
        if self._closed:
            return
        self._closed = True
        for robot in self.robots:
            for plugin in robot.plugins:
                plugin.close()
            if robot.robot_state is not None:
                robot.robot_state.close()
        for camera in self._cameras:
            camera.sensor.close()
        if self._render_ctx is not None:
            self._render_ctx.close()
        services = getattr(self, "gazebo_services", None)
        if services is not None:
            services.close()
        states = getattr(self, "model_states", None)  # None: closed while being built
        if states is not None:
            states.close()
        if self._owns_node:
            self._node.destroy_node()

    def __enter__(self) -> Simulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _is_descendant(model: mujoco.MjModel, body: int, root: int) -> bool:
    while body > 0:
        body = int(model.body_parentid[body])
        if body == root:
            return True
    return False
