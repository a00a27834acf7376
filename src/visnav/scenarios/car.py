"""The car scenario: the move_base data chain on the simulated car in the ``office``.

Pipeline (all nodes with ``use_sim_time``): depth camera -> depthimage_to_laserscan
(``/scan``) -> log-odds mapper (``/map``, the car explores a world it does not know)
-> navigator (global + local costmaps, Dijkstra planner, DWA with nav2's rotation shim)
-> ``/cmd_vel`` -> the diff drive. With ``--no-ideal-sensors`` odometry (``/odom``,
``odom -> base_footprint``) comes from the diff drive's wheel encoders with the car's slip
and encoder errors, so it drifts, and ``map -> odom`` is a static transform to the spawn
pose (the initial pose a user gives AMCL): until SLAM publishes ``map -> odom`` the drift
goes straight into navigation, which is why ``--ideal-sensors`` (the simulator's ground
truth: diff drive ``world`` source, whose ``odom`` is the world frame, ``map -> odom`` the
identity, clean cameras) is still the default. Only this observer reads the ground truth
(``/ground_truth/odom``).

Task: a seeded sequence of goals (room centres and corridor corners of the office's
free-space graph, each different from the last). Metrics: ``goals_total``,
``goals_reached``, ``collisions`` (contact events between the car and anything but the
floor, sampled at 200 Hz of sim time; contacts less than 0.2 s apart are one event),
``path_length_m`` (travelled, ground truth),
``shortest_path_m`` (sum over goals of the shortest grid path on the true map with the
car's radius), ``path_ratio``, ``goal_times_s`` and ``odometry``: ``source`` (``encoder``
or ``world``), ``drift_m`` and ``heading_drift_deg`` (final ``map -> base_footprint`` by
odometry against ground truth), ``distance_m`` (driven, ground truth). Files: the mapped
grid as ``map.yaml`` + ``map.pgm`` (map_saver's format) in the run directory.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from visnav.graph.context import Context
from visnav.graph.node import Node
from visnav.mapping import LETHAL_OBSTACLE, Costmap2D
from visnav.mapping.map_io import save_map
from visnav.mapping.nodes import MapperNode
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header, Odometry, Quaternion, Transform, TransformStamped, Vector3
from visnav.perception.nodes import DepthImageToLaserScanNode
from visnav.planning import GlobalPlanner, GlobalPlannerParams, GoalStatus
from visnav.planning.nodes import NavigatorNode
from visnav.scenarios.car_slam import CarSlamTask
from visnav.scenarios.contacts import ContactCounter
from visnav.scenarios.runner import ScenarioError
from visnav.sim.gazebo_specs import DiffDriveSpec
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


def wheel_odometry(sim: Simulator, *, encoders: bool) -> DiffDriveSpec:
    """The robot's diff drive; with ``encoders``, one whose odometry comes from its wheels.

    Raises:
        ScenarioError: no diff drive plugin, or (with ``encoders``) a ``world`` source.
    """
    robot = sim.robot()
    drives = robot.description.gazebo.diff_drives
    if not drives:
        msg = (
            f"robot {robot.name!r} has no libgazebo_ros_diff_drive.so plugin: the car scenario "
            "drives it through /cmd_vel and reads its wheel odometry. Fix: add a <gazebo><plugin "
            'filename="libgazebo_ros_diff_drive.so"> with its <left_joint>/<right_joint>'
        )
        raise ScenarioError(msg)
    drive = drives[0]
    if encoders and drive.odometry_source != "encoder":
        msg = (
            f"robot {robot.name!r}: plugin {drive.plugin_name!r} (libgazebo_ros_diff_drive.so) "
            "has odometry_source world (ground truth, like the p3d plugin) but the scenario "
            "needs wheel-encoder odometry. Fix: set <odometry_source>0</odometry_source> "
            "(ROS 1: <odometrySource>encoder</odometrySource>) in the plugin, or run with "
            "--ideal-sensors"
        )
        raise ScenarioError(msg)
    return drive


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

    def __init__(self, ctx: Context, sim: Simulator, seed: int, *, encoders: bool = True) -> None:
        import mujoco  # noqa: PLC0415 - the simulator already imported it

        self._sim = sim
        drive = wheel_odometry(sim, encoders=encoders)
        self.odometry_source = drive.odometry_source
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
        self.mapper = MapperNode(
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
        # encoder odometry starts at the spawn pose (Gazebo's does too): map -> odom is it
        x0, y0, yaw0 = self._spawn() if drive.odometry_source == "encoder" else (0.0, 0.0, 0.0)
        self._map_odom = (x0, y0, yaw0)
        map_odom = TransformStamped(
            header=Header(stamp=ns_to_time(0), frame_id="map"),
            child_frame_id=drive.odometry_frame,
            transform=Transform(
                translation=Vector3(x=x0, y=y0, z=0.0),
                rotation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw0 / 2), w=math.cos(yaw0 / 2)),
            ),
        )
        StaticTransformBroadcaster(self._node).send_transform(map_odom)
        self._truth_xy: list[tuple[float, float]] = []
        self._truth_pose: tuple[float, float, float] | None = None
        self._odom_pose: tuple[float, float, float] | None = None
        self._node.create_subscription(Odometry, "/ground_truth/odom", self._on_truth, 50)
        self._node.create_subscription(Odometry, drive.odometry_topic, self._on_odom, 50)
        self._index = -1
        self._handle: Any = None
        self._starts: list[int] = []
        self._results: list[tuple[bool, float, float, float]] = []  # ok, travelled, best, time
        self._node.create_timer(0.005, self._tick)

    def _spawn(self) -> tuple[float, float, float]:
        """The robot's start pose ``(x, y, yaw)`` in the world (the map frame)."""
        spawn = self._sim.world.metadata.get("spawn")
        if isinstance(spawn, (list, tuple)) and len(spawn) >= 2:
            yaw = float(spawn[2]) if len(spawn) >= 3 else 0.0
            return float(spawn[0]), float(spawn[1]), yaw
        return 0.0, 0.0, 0.0

    def _on_truth(self, msg: Odometry) -> None:
        p = msg.pose.pose.position
        self._truth_xy.append((p.x, p.y))
        self._truth_pose = (p.x, p.y, _yaw(msg))

    def _on_odom(self, msg: Odometry) -> None:
        p = msg.pose.pose.position
        x0, y0, yaw0 = self._map_odom
        c, s = math.cos(yaw0), math.sin(yaw0)
        self._odom_pose = (x0 + c * p.x - s * p.y, y0 + s * p.x + c * p.y, yaw0 + _yaw(msg))

    def odometry_drift(self) -> dict[str, Any]:
        """The ``odometry`` summary key: the final odometry pose against ground truth."""
        out: dict[str, Any] = {"source": self.odometry_source}
        path = np.array(self._truth_xy) if self._truth_xy else np.zeros((0, 2))
        out["distance_m"] = (
            round(float(np.hypot(*np.diff(path, axis=0).T).sum()), 3) if len(path) > 1 else 0.0
        )
        if self._truth_pose is None or self._odom_pose is None:
            return {**out, "drift_m": None, "heading_drift_deg": None}
        (tx, ty, tyaw), (ox, oy, oyaw) = self._truth_pose, self._odom_pose
        heading = math.remainder(oyaw - tyaw, 2 * math.pi)
        out["drift_m"] = round(math.hypot(ox - tx, oy - ty), 4)
        out["heading_drift_deg"] = round(math.degrees(heading), 3)
        return out

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

    def write_outputs(self, out_dir: Path) -> list[Path]:
        """Write the mapped grid as ``map.yaml`` + ``map.pgm`` (map_saver's format)."""
        if self.mapper.mapper.scans == 0:
            return []
        grid = self.mapper.mapper.to_occupancy_grid(
            self.mapper.map_frame, self.mapper.get_clock().now_ns(), trinary=True
        )
        out_dir.mkdir(parents=True, exist_ok=True)
        return list(save_map(grid, out_dir / "map"))

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
            "odometry": self.odometry_drift(),
        }


def _yaw(msg: Odometry) -> float:
    q = msg.pose.pose.orientation  # x, y, z, w (ROS order)
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def build_car_pipeline(
    ctx: Context, sim: Simulator, seed: int, *, slam: bool = True, encoders: bool = False
) -> list[Any]:
    """Start the car's nodes on ``ctx``; return its navigation (and SLAM) tasks.

    Args:
        ctx: The graph context.
        sim: The simulation holding the car.
        seed: Seeds the goals and SLAM.
        slam: Run the visual SLAM beside the navigation.
        encoders: Require wheel-encoder odometry (an error names the plugin element to set).
    """
    tasks: list[Any] = [CarTask(ctx, sim, seed, encoders=encoders)]
    if slam:
        tasks.append(CarSlamTask(ctx, seed))
    return tasks
