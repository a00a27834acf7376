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
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco

from visnav.description.robot import RobotDescription
from visnav.description.robots import resolve_robot
from visnav.description.world import load_world
from visnav.description.worldmodel import WorldDescription
from visnav.graph.context import Context
from visnav.graph.node import Node
from visnav.graph.qos import QoSProfile
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Clock
from visnav.sim.camera import RenderContext
from visnav.sim.errors import SimulatorError
from visnav.sim.gazebo_services import GazeboServices
from visnav.sim.guards import InstabilityMonitor, check_spawn_pose, route_mujoco_warnings
from visnav.sim.model_states import model_states_publisher
from visnav.sim.plugin_factories import (
    node_name,
)
from visnav.sim.plugins import CameraPlugin, SimPlugin
from visnav.sim.rebind import IdMap, transfer_state
from visnav.sim.robot import RobotHandles
from visnav.sim.sensor_timing import SensorClock
from visnav.sim.sim_robots import (
    BuildContext,
    Placement,
    RobotSpawn,
    SimRobot,
    build_robot,
    compose_spec,
    default_spawn,
    place_robots,
    render_context_for,
    rest_on_ground,
)
from visnav.sim.vehicles.quadrotor import PositionCommand

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
        self._msaa = int(msaa_samples)
        self._placements = place_robots(self.world, spawns)
        spec, robot_handles = compose_spec(self.world, self._placements, msaa_samples=self._msaa)
        try:
            self.model = spec.compile()
        except Exception as exc:  # MuJoCo raises ValueError and others
            msg = f"MuJoCo cannot compile world {self.world.name!r} with the robots: {exc}"
            raise SimulatorError(msg) from exc
        self.data = mujoco.MjData(self.model)
        self._stability = InstabilityMonitor(self.data)
        placed = list(zip(self._placements, robot_handles, strict=True))
        rest_on_ground(self.model, self.data, self.world, [(h, p.spawn) for p, h in placed])
        mujoco.mj_forward(self.model, self.data)
        self._dt_ns = round(float(self.model.opt.timestep) * 1e9)
        self._split = self.model.opt.integrator != mujoco.mjtIntegrator.mjINT_RK4
        self._now_ns = 0
        self._elapsed_ns = 0  # simulated time stepped, never rewound (reset_simulation)
        self._steps = 0
        self._wall_ns = 0
        self._render_ctx = render_context_for(self.model, self._placements)
        self._cameras: list[CameraPlugin] = []
        self._clock = SensorClock(clock_rate)
        self._pace_ref = (0, 0)
        self._closed = False
        self._paused = False  # /gazebo/pause_physics: run() spins without stepping
        self._in_step = False  # callbacks run inside a step (lock-step spin_some)
        self._edits: list[Callable[[], None]] = []  # state edits deferred to the step's end
        self.robots: list[SimRobot] = []
        self._contact_rate = float(contact_rate)  # > 0: each robot's bumper_states topic
        self._owns_node = node is None
        self._node = node if node is not None else Node("sim", context=context)
        self._clock_pub = self._node.create_publisher(Clock, "/clock", _CLOCK_QOS)
        try:
            where = self._build_context(self.model, self._render_ctx)
            for p, handles in placed:
                robot = build_robot(where, p.description, handles, p.spawn, p.name)
                self.robots.append(robot)
                self._cameras.extend(robot.cameras)
        except Exception:
            self.close()
            raise
        self.model_states = model_states_publisher(self)  # /gazebo/model_states, link_states
        self._hooks()
        self.gazebo_services = GazeboServices(self)  # /gazebo/* services on the node

    def _build_context(self, model: mujoco.MjModel, render: RenderContext | None) -> BuildContext:
        return BuildContext(
            model=model,
            context=self.context,
            seed=self.seed,
            sim_node=self._node,
            now_ns=self._now_ns,
            contact_rate=self._contact_rate,
            render_context=render,
        )

    def _hooks(self) -> None:
        """The per-step call lists, from the robots' plugins (again after a model change)."""
        plugins = [p for r in self.robots for p in r.plugins] + [self.model_states]
        self._sense = [p.sense for p in plugins if type(p).sense is not SimPlugin.sense]
        self._control = [p.control for p in plugins if type(p).control is not SimPlugin.control]
        self._after = [
            p.after_step for p in plugins if type(p).after_step is not SimPlugin.after_step
        ]

    # ------------------------------------------------------------------ building

    # ------------------------------------------------------------------ spawn / delete

    @property
    def model_names(self) -> list[str]:
        """The robots' names, including a spawn or delete not applied yet (end of step)."""
        return [p.name for p in self._placements]

    def spawn_robot(
        self,
        spawn: RobotSpawn,
        *,
        quat_wxyz: tuple[float, float, float, float] | None = None,
    ) -> str:
        """Add a robot to the running simulation (gazebo_ros' ``SpawnModel``).

        The robot's MuJoCo model is composed with the world and the other robots and
        compiled, and its plugins are built, before this returns; the simulation moves
        onto the new model between two steps (:meth:`edit`). Every other body keeps its
        state; the new robot starts at its spawn pose, at rest.

        Args:
            spawn: the robot; ``spawn.spawn`` is ``(x, y, z, yaw)`` (default: the world's
                spawn point; no resting on the ground: it falls from where it is put).
            quat_wxyz: a full orientation of the root link, overriding the yaw.

        Returns:
            The robot's name.

        Raises:
            SimulatorError: the name is taken, or MuJoCo or a plugin rejects the robot.
            RobotDescriptionError: the description cannot be loaded.
        """
        self._check_open()
        desc = resolve_robot(spawn.source, args=spawn.args, packages=spawn.packages)
        name = node_name(spawn.name or desc.name)
        if name in self.model_names:
            msg = f"model name {name} already exists"
            raise SimulatorError(msg)
        if spawn.spawn is None:
            x, y, yaw = default_spawn(self.world)
            pose: tuple[float, float, float, float] = (x, y, 0.0, yaw)
        else:
            pose = check_spawn_pose(spawn.spawn, self.world, robot=name)
        placement = Placement(desc, spawn, name, pose, quat_wxyz)
        placements = [*self._placements, placement]
        model, handles = self._compile(placements)
        render = render_context_for(model, placements)
        try:
            robot = build_robot(self._build_context(model, render), desc, handles[-1], spawn, name)
        except Exception:
            if render is not None:
                render.close()
            raise
        self._placements = placements
        self.edit(lambda: self._adopt(model, render, placements, add=robot))
        return name

    def delete_robot(self, name: str) -> None:
        """Remove a robot, its plugins and their topics (gazebo_ros' ``DeleteModel``).

        Raises:
            SimulatorError: no such robot, or the remaining model does not compile.
        """
        self._check_open()
        if name not in self.model_names:
            msg = f"no robot {name!r} in the simulation (robots: {self.model_names})"
            raise SimulatorError(msg)
        placements = [p for p in self._placements if p.name != name]
        model, _ = self._compile(placements)
        render = render_context_for(model, placements)
        self._placements = placements
        self.edit(lambda: self._adopt(model, render, placements, remove=name))

    def _compile(
        self, placements: Sequence[Placement]
    ) -> tuple[mujoco.MjModel, list[RobotHandles]]:
        spec, handles = compose_spec(self.world, placements, msaa_samples=self._msaa)
        try:
            model = spec.compile()
        except Exception as exc:  # MuJoCo raises ValueError and others
            names = [p.name for p in placements]
            msg = f"MuJoCo cannot compile world {self.world.name!r} with robots {names}: {exc}"
            raise SimulatorError(msg) from exc
        if model.opt.timestep != self.model.opt.timestep:  # the world's, never a robot's
            msg = "the recompiled model has another physics timestep"
            raise SimulatorError(msg)
        return model, handles

    def _adopt(
        self,
        model: mujoco.MjModel,
        render: RenderContext | None,
        placements: Sequence[Placement],
        *,
        add: SimRobot | None = None,
        remove: str | None = None,
    ) -> None:
        """Move the running simulation onto ``model`` (between steps)."""
        del placements
        if remove is not None:
            for robot in [r for r in self.robots if r.name == remove]:
                for plugin in robot.plugins:
                    plugin.close()
                if robot.robot_state is not None:
                    robot.robot_state.close()
                self.robots.remove(robot)
                self._cameras = [c for c in self._cameras if c not in robot.cameras]
        ids = IdMap(self.model, model, render_context=render)
        data = mujoco.MjData(model)
        transfer_state(self.model, self.data, ids, data)
        old_model, old_render = self.model, self._render_ctx
        for robot in self.robots:
            for plugin in robot.plugins:
                plugin.rebind(ids)
        self.model, self.data, self._render_ctx = model, data, render
        if add is not None:
            self.robots.append(add)
            self._cameras.extend(add.cameras)
        self._stability = InstabilityMonitor(self.data)
        self.model_states.close()
        self.model_states = model_states_publisher(self)
        self._hooks()
        self.gazebo_services.rebind(old_model, ids)
        if old_render is not None and old_render is not render:
            old_render.close()

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
    def elapsed_ns(self) -> int:
        """Simulated time stepped since the start (ns).

        Unlike :attr:`now_ns` it never goes back (``/gazebo/reset_simulation`` rewinds
        sim time to 0).
        """
        return self._elapsed_ns

    def rewind(self) -> None:
        """Sim time back to 0, as Gazebo's ``reset_simulation`` (call between steps).

        ``/clock`` starts again from 0; every sensor's and plugin's schedule restarts
        (:meth:`~visnav.sim.plugins.SimPlugin.rewind`). The bodies are not moved: reset
        them with the gazebo services' ``reset_world``.
        """
        self._now_ns = 0
        self.data.time = 0.0
        self._clock = SensorClock(self._clock.rate_hz)
        for robot in self.robots:
            for plugin in robot.plugins:
                plugin.rewind(0)
        self.model_states.rewind(0)

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
            sim_time_s=self._elapsed_ns * 1e-9,
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
        self._elapsed_ns += self._dt_ns
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
        end_ns = None if duration_s is None else self._elapsed_ns + round(duration_s * 1e9)
        before = self.stats
        wall0 = time.perf_counter_ns()
        self._pace_ref = (wall0, self._elapsed_ns)
        ctx = self.context
        try:
            while ctx.ok:
                if end_ns is not None and self._elapsed_ns >= end_ns:
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
        target = wall0 + (self._elapsed_ns - sim0) / self.real_time_factor
        now = time.perf_counter_ns()
        if target < now - _MAX_BACKLOG_NS:
            self._pace_ref = (now, self._elapsed_ns)
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
            self._pace_ref = (time.perf_counter_ns(), self._elapsed_ns)

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
