"""The simulator as a node, for launch files: ``SimulatorNode`` (``executable: sim``).

Parameters (ROS names; all optional):

==================  ===============  =====================================================
``world``           ``office``       built-in world or a world file
``world_params``    ``[]``           ``name:=value`` parameters of a built-in world
``robot``           ``car``          built-in robot or a URDF / Xacro file
``robot_args``      ``[]``           Xacro ``name:=value`` arguments
``spawn``           ``[]``           ``[x, y, z, yaw]``; empty: the world's spawn point
``robot_namespace`` ``/``            pushed onto every topic of the robot
``frame_prefix``    ``""``           prepended to the robot's TF frames
``packages``        ``[]``           ``name=DIR`` package directories (``package://``,
                                     ``$(find pkg)``, ``model://`` of the packages' models)
``skip_missing_models`` ``false``    an SDF world loads without its models not found
``seed``            ``-1``           sensor noise and world seed; -1: the world's own, noise 0
``realtime``        ``true``         pace sim time to the wall clock
``real_time_factor`` ``1.0``         target sim / wall ratio when ``realtime``
``duration``        ``0.0``          sim seconds to run; 0: until shutdown
``contact_rate``    ``0.0``          Hz: each robot's contacts on ``bumper_states``; 0: off
``lockstep``        ``false``        a launch drives the shared process lock-step (below)
``controllers``     ``[]``           ros_control controllers to start (``spawner``)
``stopped_controllers`` ``[]``       ros_control controllers only loaded (``--stopped``)
==================  ===============  =====================================================

A controller's configuration is the parameters ``<name>.<key>`` (ROS 1's
``/<name>/<key>``, ``/`` as ``.``); see :mod:`visnav.sim.ros_control`.

``require_wheel_odometry`` (default false) refuses a robot whose odometry is not from wheel
encoders (no diff drive, or its ``odometry_source`` world, i.e. ground truth like p3d), with
the plugin element to set: SLAM in the loop has nothing to correct without it.

Two ways to drive it:

* :meth:`SimulatorNode.spin` runs the simulation as the context's executor loop:
  lock-step, every step followed by the ready callbacks (what ``visnav sim`` does);
* :meth:`SimulatorNode.run_lockstep` does the same a slice at a time: a launch whose
  shared ``sim`` node has ``lockstep: true`` is driven by it (the scenario launch files
  are), so every shared node reacts at the sim time of each step and a seed gives the
  same run; the launch ends when ``duration`` is over;
* under a plain ``context.spin()`` (a launch process), a steady-clock timer advances
  the simulation in batches (catching up with the wall clock when ``realtime``,
  else about 10 ms of work per batch) and the executor delivers the messages between
  batches; nodes in the same context then react a batch late, not lock-step.

The node itself publishes ``/clock``; the simulator's sensor and plugin nodes are
created in the same context. It refuses to start (``SecondSimulationError``) when
another node already publishes ``/clock`` in its graph domain, as ``visnav sim`` and
``visnav run`` do: two simulations in one domain mix their clocks, TF and maps.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from visnav.description.world import load_world
from visnav.graph.clock import Clock, ClockType
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.safe_yaml import load_yaml
from visnav.sim.errors import SimulatorNodeError
from visnav.sim.guards import SimulationUnstableError, refuse_second_simulation
from visnav.sim.ros_control import RosControlError, check_spawned_controllers
from visnav.sim.simulator import RobotSpawn, SimStats, Simulator

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["SimParams", "SimulatorNode", "SimulatorNodeError", "check_wheel_odometry"]

_LOG = logging.getLogger("visnav.sim")
_BATCH_WALL_S = 0.01  # work per timer callback when not pacing to the wall clock
_MAX_CATCH_UP_S = 0.1  # sim seconds at most per timer callback when pacing


def _assignments(values: Sequence[Any], parameter: str) -> dict[str, str]:
    out: dict[str, str] = {}
    for item in values:
        name, sep, value = str(item).partition(":=")
        if not sep or not name.strip():
            msg = f"parameter {parameter}: {item!r} is not name:=value. Fix: e.g. 'camera_rate:=15'"
            raise SimulatorNodeError(msg)
        out[name.strip()] = value
    return out


def _packages(values: Sequence[Any]) -> dict[str, str]:
    """The ``packages`` parameter (``name=DIR`` strings) as ``name -> DIR``."""
    out: dict[str, str] = {}
    for item in values:
        name, sep, folder = str(item).partition("=")
        if not sep or not name.strip() or not folder.strip():
            msg = (
                f"parameter packages: {item!r} is not name=DIR. Fix: e.g. "
                "'turtlebot3_description=/ws/src/turtlebot3/turtlebot3_description'"
            )
            raise SimulatorNodeError(msg)
        out[name.strip()] = folder.strip()
    return out


def check_wheel_odometry(sim: Simulator) -> None:
    """Refuse a robot whose odometry is not from wheel encoders (SLAM in the loop needs it).

    Raises:
        SimulatorNodeError: no diff drive plugin, or one with ``odometry_source`` world
            (ground truth, like a p3d plugin); the text names the plugin element to set.
    """
    robot = sim.robot()
    drives = robot.description.gazebo.diff_drives
    if not drives:
        msg = (
            f"robot {robot.name!r} has no libgazebo_ros_diff_drive.so plugin, so no wheel "
            "odometry (odom -> base) for SLAM in the loop to correct (a p3d plugin is ground "
            'truth). Fix: add a <gazebo><plugin filename="libgazebo_ros_diff_drive.so"> with '
            "<odometry_source>0</odometry_source> (encoder), or set require_wheel_odometry false"
        )
        raise SimulatorNodeError(msg)
    drive = drives[0]
    if drive.odometry_source != "encoder":
        msg = (
            f"robot {robot.name!r}: plugin {drive.plugin_name!r} (libgazebo_ros_diff_drive.so) "
            f"has odometry_source {drive.odometry_source} (ground truth, like the p3d plugin) but "
            "SLAM in the loop needs wheel-encoder odometry to correct. Fix: set "
            "<odometry_source>0</odometry_source> (ROS 1: "
            "<odometrySource>encoder</odometrySource>) in that plugin (the car: "
            "ideal_sensors:=false), or run with --ideal-sensors"
        )
        raise SimulatorNodeError(msg)


@dataclass(frozen=True)
class SimParams:
    """The simulator node's parameters (the module docstring's table; read once at start).

    The array defaults hold a typed placeholder (``[""]``, ``[0.0]``) that means "empty".
    """

    world: str = param("office", description="built-in world or a world file")
    world_params: tuple[str, ...] = param(("",), description="name:=value parameters of the world")
    robot: str = param("car", description="built-in robot or a URDF / Xacro file")
    robot_args: tuple[str, ...] = param(("",), description="Xacro name:=value arguments")
    spawn: tuple[float, ...] = param((0.0,), description="[x, y, z, yaw]; empty: the world's spawn")
    robot_namespace: str = param("/", description="pushed onto every topic of the robot")
    frame_prefix: str = param("", description="prepended to the robot's TF frames")
    packages: tuple[str, ...] = param(("",), description="name=DIR package directories")
    skip_missing_models: bool = param(
        False, description="load an SDF world without the models not found"
    )
    seed: int = param(-1, description="sensor noise and world seed; -1: the world's, noise 0")
    realtime: bool = param(True, description="pace sim time to the wall clock")
    real_time_factor: float = param(1.0, description="target sim / wall ratio when realtime")
    duration: float = param(0.0, description="sim seconds to run; 0: until shutdown")
    contact_rate: float = param(0.0, description="Hz of bumper_states contacts; 0: off")
    lockstep: bool = param(False, description="a launch drives the shared process lock-step")
    require_wheel_odometry: bool = param(False, description="refuse a robot without encoders")


class SimulatorNode(Node):
    """A node that owns a :class:`~visnav.sim.simulator.Simulator` (see the module docstring).

    Args:
        name: the node's name (launch files usually call it ``sim``).
        **node_kwargs: :class:`~visnav.graph.Node`'s keyword parameters; the simulator's
            nodes join its ``context``.
        **node_kwargs: passed to :class:`~visnav.graph.Node` (namespace,
            parameter_overrides, remappings).

    Raises:
        VisnavError: a bad parameter, world or robot (one line naming it).
        SecondSimulationError: another node publishes ``/clock`` in the domain.
    """

    def __init__(self, name: str = "sim", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        try:
            refuse_second_simulation(self.context, command="visnav launch", owner=self)
            self.sim = self._build()
        except BaseException:
            super().destroy_node()
            raise
        self._wall0 = time.perf_counter()
        self._sim0 = self.sim.elapsed_ns
        self._pace0 = (self._wall0, self._sim0)  # wall and sim time pacing counts from
        steady = Clock(ClockType.STEADY_TIME)
        self._timer = self.create_timer(self.sim.timestep_ns * 1e-9, self._advance, clock=steady)

    def _build(self) -> Simulator:
        p = self._parameters()
        self.duration_s = float(p["duration"])
        self.lockstep = bool(p["lockstep"])
        seed = int(p["seed"])
        spawn = [float(v) for v in p["spawn"]]
        if spawn and len(spawn) != 4:
            msg = f"parameter spawn is {spawn}: expected [x, y, z, yaw] or []"
            raise SimulatorNodeError(msg)
        self.packages = _packages(p["packages"])
        world_params: dict[str, Any] = {}
        for name, text in _assignments(p["world_params"], "world_params").items():
            source = f"parameter world_params: {name}:={text!r}"
            world_params[name] = load_yaml(
                text, source=source, what="the value", error=SimulatorNodeError
            )
        world = load_world(
            str(p["world"]),
            params=world_params or None,
            seed=None if seed < 0 else seed,
            packages=self.packages or None,
            skip_missing_models=bool(p["skip_missing_models"]),
        )
        robot = RobotSpawn(
            source=str(p["robot"]),
            args=_assignments(p["robot_args"], "robot_args"),
            spawn=(spawn[0], spawn[1], spawn[2], spawn[3]) if spawn else None,
            namespace=str(p["robot_namespace"]),
            frame_prefix=str(p["frame_prefix"]),
            packages=self.packages or None,
        )
        sim = Simulator(
            world,
            [robot],
            context=self.context,
            seed=max(seed, 0),
            realtime=bool(p["realtime"]),
            real_time_factor=float(p["real_time_factor"]),
            node=self,
            contact_rate=float(p["contact_rate"]),
        )
        try:  # spawned ros_control controllers that no robot's controller manager took
            check_spawned_controllers(self, [p for r in sim.robots for p in r.plugins])
        except RosControlError:
            sim.close()
            raise
        if bool(p["require_wheel_odometry"]):
            try:
                check_wheel_odometry(sim)
            except SimulatorNodeError:
                sim.close()
                raise
        return sim

    def _parameters(self) -> Mapping[str, Any]:
        values = dataclasses.asdict(declare_params(self, SimParams))
        # array defaults carry a typed placeholder; an untouched one means "empty"
        for name in ("world_params", "robot_args", "spawn", "packages"):
            if list(values[name]) == list(getattr(SimParams, name)):
                values[name] = []
        return values

    def _done(self) -> bool:
        return self.duration_s > 0 and self.sim.elapsed_ns - self._sim0 >= self.duration_s * 1e9

    def _advance(self) -> None:
        """Steady-timer callback: advance a batch without spinning (the executor spins).

        An unstable simulation stops the timer (it cannot recover) before the error goes
        to the executor's fault boundary, which logs it (or stops the launch).
        """
        try:
            self._advance_batch()
        except SimulationUnstableError:
            self._timer.cancel()
            raise

    def _advance_batch(self) -> None:
        sim = self.sim
        if self._done():
            self._timer.cancel()
            _LOG.info("%s: %s", self.get_fully_qualified_name(), sim.stats.summary())
            return
        if sim.paused:  # /gazebo/pause_physics: pace from the unpause on, no catching up
            self._pace0 = (time.perf_counter(), sim.elapsed_ns)
            return
        if sim.realtime:
            wall0, sim0 = self._pace0
            wall = time.perf_counter() - wall0
            target = sim0 + round(wall * sim.real_time_factor * 1e9)
            ahead = min(target - sim.elapsed_ns, round(_MAX_CATCH_UP_S * 1e9))
            steps = max(0, ahead // sim.timestep_ns)
            if self.duration_s > 0:  # a catch-up batch stops at the end, not past it
                left = round(self.duration_s * 1e9) - (sim.elapsed_ns - self._sim0)
                steps = min(steps, max(0, -(-left // sim.timestep_ns)))
            if steps:
                sim.step(steps, spin=False)
            return
        stop = time.perf_counter() + _BATCH_WALL_S
        while time.perf_counter() < stop and not self._done():
            sim.step(1, spin=False)

    def run_lockstep(self, slice_s: float, *, until: Callable[[], bool] | None = None) -> bool:
        """Advance lock-step (as :meth:`spin`) by at most ``slice_s`` simulated seconds.

        Call it from the thread that owns the context, not from a callback.

        Args:
            slice_s: sim seconds to advance at most.
            until: stop early as soon as this returns True (checked before every step).

        Returns:
            False once ``duration`` is over (or the context is shut down), else True.
        """
        self._timer.cancel()
        if self._done() or not self.context.ok:
            return False
        left = slice_s
        if self.duration_s > 0:
            left = min(left, self.duration_s - (self.sim.elapsed_ns - self._sim0) * 1e-9)
        self.sim.run(max(left, 0.0), until=until)
        return not self._done() and self.context.ok

    def spin(self) -> SimStats:
        """Run the simulation lock-step as this context's executor loop.

        Runs for ``duration`` (or until the context shuts down, or Ctrl-C) and
        returns the timing of the run.
        """
        self._timer.cancel()
        duration = self.duration_s - (self.sim.elapsed_ns - self._sim0) * 1e-9
        try:
            return self.sim.run(duration if self.duration_s > 0 else None)
        except KeyboardInterrupt:
            return self.sim.stats

    def destroy_node(self) -> None:
        """Close the simulator, then destroy this node."""
        sim = getattr(self, "sim", None)
        if sim is not None:
            sim.close()
        super().destroy_node()
