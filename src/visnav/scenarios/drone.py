"""The drone scenario: the quadrotor flies through the seeded forest with EGO-Planner.

Sequence (sim time): take off to 1 m with a hold command on ``/drone/command/pose``;
at 3 s start ``ego_planner_node`` and ``traj_server`` in ``/drone`` (depth camera ->
grid map -> planner -> trajectory commands -> the SO(3) controller); at 3.5 s send the
forest's goal on ``/move_base_simple/goal``. The task is done when the planner's FSM
reports the goal reached.

Metrics: ``goals_total`` / ``goals_reached`` (reached = FSM done and within 0.5 m of
the goal in x-y), ``collisions`` (contact events between the drone and anything else after
take-off: MuJoCo contacts sampled at 200 Hz of sim time, a run of touching samples
counts once), ``min_clearance_m`` (exact obstacle distance of the body
centre along the odometry), ``mean_speed_mps`` (path length / flight time) and
``planning_time_ms`` (median, p95, max over the replans).

Where visnav differs from upstream's defaults: ``grid_map.obstacles_inflation`` is
0.3 m, not 0.099 m: the built-in quadrotor's collision box reaches 0.26 m from its
centre, and with upstream's value 6 of 20 seeded flights touched a column.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from visnav.graph.context import Context
from visnav.graph.node import Node
from visnav.msgs.construct import make
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header, Odometry, PoseStamped
from visnav.scenarios.contacts import ContactCounter
from visnav.sim.simulator import Simulator
from visnav.sim.world_geometry import obstacle_distance

__all__ = ["DroneTask", "build_drone_pipeline"]

TAKEOFF_HEIGHT_M = 1.0
START_PLANNER_S = 3.0
SEND_GOAL_S = 3.5
INFLATION_M = 0.3


def _pose(x: float, y: float, z: float, stamp_ns: int) -> PoseStamped:
    msg: PoseStamped = make(PoseStamped)
    msg.header = Header(stamp=ns_to_time(stamp_ns), frame_id="world")
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = x, y, z
    msg.pose.orientation.w = 1.0
    return msg


class DroneTask:
    """Drives the flight and measures it (see the module docstring)."""

    def __init__(self, ctx: Context, sim: Simulator) -> None:
        self._ctx, self._sim = ctx, sim
        self._world = sim.world
        self._start = tuple(self._world.metadata["start"])
        self._goal = tuple(self._world.metadata["goal"])
        self._node = Node("drone_scenario", context=ctx, use_sim_time=True)
        self._odom: list[tuple[float, float, float]] = []
        self._node.create_subscription(Odometry, "/drone/odom", self._on_odom, 100)
        self._hold = self._node.create_publisher(PoseStamped, "/drone/command/pose", 1)
        self._goal_pub = self._node.create_publisher(PoseStamped, "/move_base_simple/goal", 1)
        self._hold.publish(_pose(self._start[0], self._start[1], TAKEOFF_HEIGHT_M, 0))
        model = sim.model
        root = model.body(sim.robot().handles.root_body).id
        drone = {b for b in range(model.nbody) if model.body_rootid[b] == root}
        self._contacts = ContactCounter(sim, drone, ignore_planes=False)
        self._planner: Any = None
        self._goal_sent_ns: int | None = None
        self._flight_start_index = 0
        self._node.create_timer(0.005, self._tick)

    def _on_odom(self, msg: Odometry) -> None:
        p = msg.pose.pose.position
        self._odom.append((p.x, p.y, p.z))

    def _tick(self) -> None:
        sim = self._sim
        if self._goal_sent_ns is not None:  # resting on the ground before take-off is no collision
            self._contacts.update(sim.sim_time_s)
        t = sim.sim_time_s
        if self._planner is None and t >= START_PLANNER_S:
            from visnav.planning.ego_planner.nodes import (  # noqa: PLC0415 - numba warm-up
                EgoPlannerNode,
                TrajServerNode,
            )

            common = {"use_sim_time": True}
            self._planner = EgoPlannerNode(
                context=self._ctx,
                namespace="/drone",
                parameter_overrides={**common, "grid_map.obstacles_inflation": INFLATION_M},
            )
            TrajServerNode(context=self._ctx, namespace="/drone", parameter_overrides=common)
        if self._planner is not None and self._goal_sent_ns is None and t >= SEND_GOAL_S:
            self._goal_pub.publish(
                _pose(self._goal[0], self._goal[1], TAKEOFF_HEIGHT_M, sim.now_ns)
            )
            self._goal_sent_ns = sim.now_ns
            self._flight_start_index = len(self._odom)

    def done(self) -> bool:
        """True when the planner reached the goal."""
        return self._planner is not None and self._planner.fsm.goals_reached > 0

    def results(self) -> dict[str, Any]:
        """The drone summary keys."""
        nan3 = (math.nan, math.nan, math.nan)
        flight = np.array(self._odom[self._flight_start_index :] or self._odom or [nan3])
        reached = bool(self.done() and math.dist(flight[-1, :2].tolist(), self._goal[:2]) < 0.5)
        flight_s = (
            (self._sim.now_ns - self._goal_sent_ns) / 1e9 if self._goal_sent_ns is not None else 0.0
        )
        length = (
            float(np.linalg.norm(np.diff(flight, axis=0), axis=1).sum()) if len(flight) > 1 else 0.0
        )
        times = (
            [r.total_s * 1e3 for r in self._planner.manager.records]
            if self._planner is not None
            else []
        )
        clearance = float(obstacle_distance(self._world, flight).min()) if len(self._odom) else None
        return {
            "goals_total": 1,
            "goals_reached": int(reached),
            "collisions": self._contacts.events,
            "min_clearance_m": round(clearance, 4) if clearance is not None else None,
            "mean_speed_mps": round(length / flight_s, 4) if flight_s > 0 else 0.0,
            "path_length_m": round(length, 3),
            "planning_time_ms": {
                "median": round(float(np.median(times)), 3) if times else None,
                "p95": round(float(np.percentile(times, 95)), 3) if times else None,
                "max": round(float(np.max(times)), 3) if times else None,
            },
        }


def build_drone_pipeline(ctx: Context, sim: Simulator, seed: int) -> list[Any]:
    """Start the drone's flight task on ``ctx``."""
    del seed
    return [DroneTask(ctx, sim)]
