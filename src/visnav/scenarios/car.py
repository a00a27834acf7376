"""The car scenario: the move_base data chain on the simulated car in the ``office``.

Pipeline (all nodes with ``use_sim_time``): depth camera -> depthimage_to_laserscan
(``/scan``) -> log-odds mapper (``/map``, the car explores a world it does not know)
-> navigator (global + local costmaps, Dijkstra planner, DWA with nav2's rotation shim)
-> ``/cmd_vel`` -> the diff drive. ``map -> odom`` is the identity (a static transform):
odometry here is the simulator's ground-truth odometry (diff drive ``world`` source).

Task: a seeded sequence of goals (room centres and corridor corners of the office's
free-space graph, each different from the last). Metrics: ``goals_total``,
``goals_reached``, ``collisions`` (contact events between the car and anything but the
floor, sampled at 200 Hz of sim time; contacts less than 0.2 s apart are one event),
``path_length_m`` (travelled, ground truth),
``shortest_path_m`` (sum over goals of the shortest grid path on the true map with the
car's radius), ``path_ratio`` and ``goal_times_s``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import ndimage

from visnav.graph.context import Context
from visnav.graph.node import Node
from visnav.mapping import LETHAL_OBSTACLE, Costmap2D
from visnav.mapping.nodes import MapperNode
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header, Odometry, Quaternion, Transform, TransformStamped, Vector3
from visnav.perception.nodes import DepthImageToLaserScanNode
from visnav.planning import GlobalPlanner, GlobalPlannerParams, GoalStatus
from visnav.planning.nodes import NavigatorNode
from visnav.scenarios.car_slam import CarSlamTask
from visnav.scenarios.contacts import ContactCounter
from visnav.scenarios.runner import ScenarioError
from visnav.sim.simulator import Simulator
from visnav.sim.world import true_occupancy_grid
from visnav.tf.ros import StaticTransformBroadcaster

__all__ = ["CarTask", "build_car_pipeline", "depth_range_min", "goal_sequence"]

ROBOT_RADIUS_M = 0.33
"""The car's corners reach 0.305 m from its centre; 0.3 let it scrape a wall (seeds 4, 5)."""
CONTACT_GAP_S = 0.2
"""Contacts closer together than this are one collision event."""
GOALS = 4
GOAL_NODES = ("N1", "N2", "N3", "S1", "S2", "S3", "W", "E", "C1", "C2", "corr_nw", "corr_se")


def depth_range_min(sim: Simulator) -> float:
    """The nearest valid depth of the robot's depth camera (its clip / plugin minimum), m."""
    for cam in sim.robot().description.gazebo.cameras:
        if cam.kind == "depth":
            return float(cam.depth_range[0])
    msg = f"robot {sim.robot().name!r} has no depth camera: the car scenario scans its depth"
    raise ScenarioError(msg)


def goal_sequence(
    graph_nodes: dict[str, Any], seed: int, count: int = GOALS
) -> list[tuple[float, float]]:
    """Return ``count`` seeded goals from the office's free-space graph (no repeats in a row)."""
    rng = np.random.default_rng(seed)
    names = [n for n in GOAL_NODES if n in graph_nodes]
    out: list[str] = []
    while len(out) < count:
        pick = names[int(rng.integers(len(names)))]
        if not out or pick != out[-1]:
            out.append(pick)
    return [(float(graph_nodes[n][0]), float(graph_nodes[n][1])) for n in out]


class CarTask:
    """Sends the goals one after another and measures the drive (module docstring)."""

    def __init__(self, ctx: Context, sim: Simulator, seed: int) -> None:
        import mujoco  # noqa: PLC0415 - the simulator already imported it

        self._sim = sim
        world = sim.world
        self.goals = goal_sequence(world.metadata["graph"]["nodes"], seed)
        grid, origin = true_occupancy_grid(world, 0.05)
        self._truth = Costmap2D(grid.shape[1], grid.shape[0], 0.05, origin[0], origin[1])
        clearance = ndimage.distance_transform_edt(~grid) * 0.05
        self._truth.data[:] = np.where(clearance <= ROBOT_RADIUS_M, LETHAL_OBSTACLE, 0)
        self._shortest = GlobalPlanner(GlobalPlannerParams(cost_factor=0.0))
        robot = {
            mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, b)
            for b in sim.robot().handles.bodies.values()
        }
        self._contacts = ContactCounter(sim, robot, ignore_planes=True, gap_s=CONTACT_GAP_S)
        bounds = world.metadata["bounds"]
        sim_time = {"use_sim_time": True}
        DepthImageToLaserScanNode(
            context=ctx,
            remappings={
                "depth": "/depth_camera/depth/image_raw",
                "depth_camera_info": "/depth_camera/depth/camera_info",
            },
            parameter_overrides={
                **sim_time,
                "output_frame": "depth_camera_link",
                "scan_height": 10,
                # the camera's own minimum depth, not depthimage_to_laserscan's 0.45 m (a
                # Kinect's): with 0.45 a wall 0.3 m ahead of the lens was invisible and the
                # planner drove the car into it through "unknown" space (seed 4)
                "range_min": depth_range_min(sim),
            },
        )
        MapperNode(
            context=ctx,
            parameter_overrides={
                **sim_time,
                "width": float(bounds[2] - bounds[0]) + 4.0,
                "height": float(bounds[3] - bounds[1]) + 4.0,
                "origin_x": float(bounds[0]) - 2.0,
                "origin_y": float(bounds[1]) - 2.0,
            },
        )
        self.nav = NavigatorNode(
            context=ctx,
            parameter_overrides={
                **sim_time,
                "global_costmap.robot_radius": ROBOT_RADIUS_M,
                "local_costmap.robot_radius": ROBOT_RADIUS_M,
            },
        )
        ctx.spin_some()  # take the simulator's latched /tf_static first
        self._node = Node("car_scenario", context=ctx, use_sim_time=True)
        identity = TransformStamped(
            header=Header(stamp=ns_to_time(0), frame_id="map"),
            child_frame_id="odom",
            transform=Transform(
                translation=Vector3(x=0.0, y=0.0, z=0.0),
                rotation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )
        StaticTransformBroadcaster(self._node).send_transform(identity)
        self._truth_xy: list[tuple[float, float]] = []
        self._node.create_subscription(Odometry, "/ground_truth/odom", self._on_truth, 50)
        self._index = -1
        self._handle: Any = None
        self._starts: list[int] = []
        self._results: list[tuple[bool, float, float, float]] = []  # ok, travelled, best, time
        self._node.create_timer(0.005, self._tick)

    def _on_truth(self, msg: Odometry) -> None:
        p = msg.pose.pose.position
        self._truth_xy.append((p.x, p.y))

    def _tick(self) -> None:
        self._contacts.update(self._sim.sim_time_s)
        if self._sim.sim_time_s < 0.5 or not self._truth_xy:
            return
        if self._handle is not None and not self._handle.done:
            return
        if self._handle is not None:
            self._finish_goal()
        if self._index + 1 < len(self.goals):
            self._index += 1
            gx, gy = self.goals[self._index]
            self._starts.append(len(self._truth_xy) - 1)
            self._handle = self.nav.go_to((gx, gy, 0.0))

    def _finish_goal(self) -> None:
        gx, gy = self.goals[self._index]
        k0 = self._starts[self._index]
        path = np.array(self._truth_xy[k0:])
        travelled = float(np.hypot(*np.diff(path, axis=0).T).sum()) if len(path) > 1 else 0.0
        best = self._shortest.make_plan(self._truth, tuple(path[0]), (gx, gy, 0.0))
        ok = (
            self._handle.status is GoalStatus.SUCCEEDED
            and math.hypot(path[-1, 0] - gx, path[-1, 1] - gy) < 0.5
        )
        duration = (self._handle.finished_ns - self._handle.accepted_ns) / 1e9
        self._results.append((ok, travelled, best.length if best.ok else math.nan, duration))
        self._handle = None

    def done(self) -> bool:
        """True when every goal has ended."""
        return self._index == len(self.goals) - 1 and self._handle is None and bool(self._results)

    def results(self) -> dict[str, Any]:
        """The car summary keys."""
        if self._handle is not None and self._handle.done:
            self._finish_goal()
        reached = [r for r in self._results if r[0]]
        travelled = sum(r[1] for r in reached)
        shortest = sum(r[2] for r in reached)
        return {
            "goals_total": len(self.goals),
            "goals_reached": len(reached),
            "collisions": self._contacts.events,
            "path_length_m": round(travelled, 3),
            "shortest_path_m": round(shortest, 3),
            "path_ratio": round(travelled / shortest, 4) if shortest > 0 else None,
            "goal_times_s": [round(r[3], 2) for r in self._results],
        }


def build_car_pipeline(ctx: Context, sim: Simulator, seed: int, *, slam: bool = True) -> list[Any]:
    """Start the car's nodes on ``ctx``; return its navigation (and SLAM) tasks."""
    tasks: list[Any] = [CarTask(ctx, sim, seed)]
    if slam:
        tasks.append(CarSlamTask(ctx, seed))
    return tasks
