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
``seed``            ``-1``           sensor noise and world seed; -1: the world's own, noise 0
``realtime``        ``true``         pace sim time to the wall clock
``real_time_factor`` ``1.0``         target sim / wall ratio when ``realtime``
``duration``        ``0.0``          sim seconds to run; 0: until shutdown
==================  ===============  =====================================================

Two ways to drive it:

* :meth:`SimulatorNode.spin` runs the simulation as the context's executor loop:
  lock-step, every step followed by the ready callbacks (what ``visnav sim`` does);
* under a plain ``context.spin()`` (a launch process), a steady-clock timer advances
  the simulation in batches (catching up with the wall clock when ``realtime``,
  else about 10 ms of work per batch) and the executor delivers the messages between
  batches; nodes in the same context then react a batch late, not lock-step.

The node itself publishes ``/clock``; the simulator's sensor and plugin nodes are
created in the same context.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping, Sequence
from typing import Any

from visnav.errors import VisnavError
from visnav.graph.clock import Clock, ClockType
from visnav.graph.context import Context
from visnav.graph.node import Node
from visnav.safe_yaml import load_yaml
from visnav.sim.guards import SimulationUnstableError
from visnav.sim.simulator import RobotSpawn, SimStats, Simulator
from visnav.sim.world import load_world

__all__ = ["SimulatorNode", "SimulatorNodeError"]

_LOG = logging.getLogger("visnav.sim")
_BATCH_WALL_S = 0.01  # work per timer callback when not pacing to the wall clock
_MAX_CATCH_UP_S = 0.1  # sim seconds at most per timer callback when pacing


class SimulatorNodeError(VisnavError, ValueError):
    """A simulator node parameter is malformed."""


def _assignments(values: Sequence[Any], parameter: str) -> dict[str, str]:
    out: dict[str, str] = {}
    for item in values:
        name, sep, value = str(item).partition(":=")
        if not sep or not name.strip():
            msg = f"parameter {parameter}: {item!r} is not name:=value. Fix: e.g. 'camera_rate:=15'"
            raise SimulatorNodeError(msg)
        out[name.strip()] = value
    return out


class SimulatorNode(Node):
    """A node that owns a :class:`~visnav.sim.simulator.Simulator` (see the module docstring).

    Args:
        node_name: the node's name (launch files usually call it ``sim``).
        context: the graph context; the simulator's nodes join it.
        **node_kwargs: passed to :class:`~visnav.graph.Node` (namespace,
            parameter_overrides, remappings).

    Raises:
        VisnavError: a bad parameter, world or robot (one line naming it).
    """

    def __init__(
        self, node_name: str = "sim", *, context: Context | None = None, **node_kwargs: Any
    ) -> None:
        super().__init__(node_name, context=context, **node_kwargs)
        try:
            self.sim = self._build()
        except BaseException:
            super().destroy_node()
            raise
        self._wall0 = time.perf_counter()
        self._sim0 = self.sim.now_ns
        steady = Clock(ClockType.STEADY_TIME)
        self._timer = self.create_timer(self.sim.timestep_ns * 1e-9, self._advance, clock=steady)

    def _build(self) -> Simulator:
        p = self._parameters()
        self.duration_s = float(p["duration"])
        seed = int(p["seed"])
        spawn = [float(v) for v in p["spawn"]]
        if spawn and len(spawn) != 4:
            msg = f"parameter spawn is {spawn}: expected [x, y, z, yaw] or []"
            raise SimulatorNodeError(msg)
        world_params: dict[str, Any] = {}
        for name, text in _assignments(p["world_params"], "world_params").items():
            source = f"parameter world_params: {name}:={text!r}"
            world_params[name] = load_yaml(
                text, source=source, what="the value", error=SimulatorNodeError
            )
        world = load_world(
            str(p["world"]), params=world_params or None, seed=None if seed < 0 else seed
        )
        robot = RobotSpawn(
            source=str(p["robot"]),
            args=_assignments(p["robot_args"], "robot_args"),
            spawn=(spawn[0], spawn[1], spawn[2], spawn[3]) if spawn else None,
            namespace=str(p["robot_namespace"]),
            frame_prefix=str(p["frame_prefix"]),
        )
        return Simulator(
            world,
            [robot],
            context=self.context,
            seed=max(seed, 0),
            realtime=bool(p["realtime"]),
            real_time_factor=float(p["real_time_factor"]),
            node=self,
        )

    def _parameters(self) -> Mapping[str, Any]:
        defaults: dict[str, Any] = {
            "world": "office",
            "world_params": [""],
            "robot": "car",
            "robot_args": [""],
            "spawn": [0.0],
            "robot_namespace": "/",
            "frame_prefix": "",
            "seed": -1,
            "realtime": True,
            "real_time_factor": 1.0,
            "duration": 0.0,
        }
        values = {name: self.declare_parameter(name, d).value for name, d in defaults.items()}
        # array defaults carry a typed placeholder; an untouched one means "empty"
        for name in ("world_params", "robot_args", "spawn"):
            if list(values[name]) == defaults[name]:
                values[name] = []
        return values

    def _done(self) -> bool:
        return self.duration_s > 0 and self.sim.now_ns - self._sim0 >= self.duration_s * 1e9

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
        if sim.realtime:
            wall = time.perf_counter() - self._wall0
            target = self._sim0 + round(wall * sim.real_time_factor * 1e9)
            ahead = min(target - sim.now_ns, round(_MAX_CATCH_UP_S * 1e9))
            steps = max(0, ahead // sim.timestep_ns)
            if steps:
                sim.step(steps, spin=False)
            return
        stop = time.perf_counter() + _BATCH_WALL_S
        while time.perf_counter() < stop and not self._done():
            sim.step(1, spin=False)

    def spin(self) -> SimStats:
        """Run the simulation lock-step as this context's executor loop.

        Runs for ``duration`` (or until the context shuts down, or Ctrl-C) and
        returns the timing of the run.
        """
        self._timer.cancel()
        duration = self.duration_s - (self.sim.now_ns - self._sim0) * 1e-9
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
