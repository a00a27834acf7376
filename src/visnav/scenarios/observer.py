"""The scenario observer: the run's summary from topics only (``exec: scenario_observer``).

:class:`ObserverNode` subscribes to what the robot's stack publishes and to the
simulator's ground truth (the only node of a scenario that reads it), and writes
``summary.json`` (plus ``map.yaml`` / ``map.pgm`` and the SLAM trajectories) into
``output_dir`` when the task is done or the node shuts down. When the task is done
(every goal ended; the drone's planner reached its goal) it writes the summary at the
next simulation step and ends the launch with ``sys.exit(0)`` (``exit_when_done``), as a
``required`` node whose exit ends a roslaunch.

Sources (parameter names in brackets):

* goals: the goals on ``goal_topic`` and, for the car, move_base's ``status_topic``
  (``actionlib_msgs/GoalStatusArray``: end state, accepted / ended stamps); for the drone
  the planner's ``/diagnostics`` (``planner_diagnostics``: goals reached, planning times);
* collisions: the simulator's ``contact_topic`` (``bumper_states``,
  :mod:`visnav.sim.contact_sensor`), floor contacts left out with
  ``contacts_ignore_ground``, contacts before the goal left out with
  ``contacts_after_goal`` (resting on the ground before take-off is no collision);
* path length: ``ground_truth_topic``; shortest path: the world's true occupancy with
  ``robot_radius``; clearance (drone): the world's exact obstacle distance. ``path_ratio``
  is the travelled length over the shortest, summed over the goals reached; each
  shortest path joins the drive's own start and end (where the robot stopped, within the
  navigator's tolerance of the goal) keeping ``robot_radius`` from the true obstacles
  (global_planner's gradient path on a 5 cm grid). It can still read a little below 1
  where the robot passed a corner closer than ``robot_radius`` (its costmap's map is a cell
  off the truth) or the grid path's ends snap to cell centres (a few cm per goal);
* odometry drift: ``odom_topic`` against ground truth (``odometry`` key), and
  ``odometry_drift_m``: the final ``odom -> base`` from TF against ground truth, both
  anchored at the first sample;
* localization: ``map -> base`` from TF against ground truth sampled at 10 Hz of sim
  time (``localization``: ``source`` = ``localization_source``, ``rmse_m``, ``max_m``,
  ``heading_rmse_deg``);
* SLAM (``slam``): the last ``slam/path`` plus the later ``slam/pose`` messages against
  ground truth interpolated at their stamps (ATE aligned and not, RPE): ``tracked`` counts
  those poses (one per tracked frame), ``evaluated`` the ones with ground truth. The SLAM
  node's counters come from its latest ``/diagnostics`` status (``frames``,
  ``tracking_lost``, ``relocalized``, ``keyframes``, ``loop_closures``, ``skipped``,
  ``dropped``, ``cpu_s``; published every second and on tracking loss); ``frames`` adds
  the frames tracked after the last frame that status counted (its
  ``last_frame_stamp_ns``), so ``tracked <= frames`` (frames lost in that last second are
  not known), the other counters may lag the end by up to 1 s.

Summary keys are those of ``visnav run`` (:mod:`visnav.scenarios.runner`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.graph.qos import qos_profile_latched
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import time_to_ns
from visnav.msgs.types import OccupancyGrid, Odometry, PoseStamped
from visnav.msgs.types import Path as PathMsg
from visnav.scenarios.errors import ScenarioError
from visnav.scenarios.observer_metrics import (
    ENDED_STATUSES,
    SUCCEEDED_STATUS,
    ContactEvents,
    FloatArray,
    GoalRecord,
    PoseErrors,
    path_length,
)
from visnav.tf import Buffer, pose_to_matrix
from visnav.tf.errors import TransformException
from visnav.tf.ros import TransformListener

if TYPE_CHECKING:
    from typing_extensions import Unpack

    from visnav.scenarios.observer_results import SlamTrajectories

__all__ = ["ObserverNode", "ObserverParams", "parse_planner_status"]


@dataclass(frozen=True)
class ObserverParams:
    """Parameters of :class:`ObserverNode` (module docstring)."""

    scenario: str = param("car", description="car or drone: which summary keys", read_only=True)
    world: str = param("office", description="the world (shortest paths, clearance, spawn)")
    seed: int = param(0, description="the world's seed (the run's seed)")
    packages: list[str] = param(  # noqa: RUF009
        [], description="name=DIR packages an SDF world's model:// models come from"
    )
    map_quality: bool = param(False, description="score the map on map_topic against the world")
    goals: int = param(4, description="goals the task has (done when all ended)", range=(1, 1000))
    output_dir: str = param("", description="where summary.json goes ('': nowhere)")
    ground_truth_topic: str = param("/ground_truth/odom", description="ground truth Odometry")
    odom_topic: str = param("/odom", description="the robot's odometry ('': none)")
    odometry_source: str = param("world", description="encoder or world (summary only)")
    goal_topic: str = param("/move_base_simple/goal", description="goals (PoseStamped)")
    status_topic: str = param("/move_base/status", description="move_base GoalStatusArray")
    contact_topic: str = param("/bumper_states", description="the simulator's contacts")
    contacts_ignore_ground: bool = param(True, description="floor (plane) contacts do not count")
    contacts_after_goal: bool = param(False, description="count contacts once a goal was sent")
    contact_gap: float = param(0.2, description="contacts closer (s) are one event", range=(0, 60))
    goal_tolerance: float = param(0.5, description="reached: within this (m, x-y)", range=(0, 100))
    robot_radius: float = param(0.33, description="for the shortest path (m)", range=(0, 10))
    planner_diagnostics: bool = param(False, description="goals / planning times on /diagnostics")
    localization_source: str = param("static", description="what publishes map->odom ('': none)")
    map_frame: str = param("map", description="the localization frame")
    odom_frame: str = param("odom", description="the odometry frame")
    slam: bool = param(False, description="score slam/pose and slam/path")
    slam_pose_topic: str = param("/slam/pose", description="SLAM pose (PoseStamped)")
    slam_path_topic: str = param("/slam/path", description="SLAM path (Path)")
    map_topic: str = param("/map", description="the mapped grid, saved as map.yaml ('': none)")
    exit_when_done: bool = param(True, description="end the launch when the task is done")


class ObserverNode(Node):
    """Computes the scenario summary from topics (module docstring).

    Args:
        name: node name (default ``observer``).
        **node_kwargs: passed to :class:`~visnav.graph.Node` (``use_sim_time`` expected).

    Raises:
        ScenarioError: an unknown ``scenario``.
    """

    def __init__(self, name: str = "observer", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        p = self.params = declare_params(self, ObserverParams)
        if p.scenario not in ("car", "drone"):
            msg = (
                f"node {self.get_fully_qualified_name()}: parameter scenario is "
                f"{p.scenario!r}: expected car or drone"
            )
            raise ScenarioError(msg)
        from visnav.description.world import load_world  # noqa: PLC0415

        packages = dict(item.split("=", 1) for item in p.packages if "=" in item)
        self.world = load_world(p.world, seed=p.seed, packages=packages)
        self._truth: list[tuple[float, float, float]] = []
        self._truth_ns: list[int] = []
        self._truth_poses: list[FloatArray] = []
        self._truth_frame = ""
        self._odom_pose: FloatArray | None = None
        self._goals: list[GoalRecord] = []
        self._goal_sent_ns: int | None = None
        self._flight_start = 0
        self._contacts = ContactEvents(p.contact_gap)
        self._planning_ms: list[float] = []
        self._planner_reached = 0
        self._loc = PoseErrors()
        self._odom_tf: tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None = None
        self._slam_path: list[tuple[int, FloatArray]] = []
        self._slam_poses: list[tuple[int, FloatArray]] = []
        self._map: OccupancyGrid | None = None
        self._slam_counters: dict[str, str] = {}
        self._done_ns: int | None = None
        self._written = False
        self._truth_costmap: Any = None
        self.summary: dict[str, Any] | None = None
        self._subscribe(p)

    # ------------------------------------------------------------------ wiring
    def _subscribe(self, p: ObserverParams) -> None:
        self.create_subscription(Odometry, p.ground_truth_topic, self._on_truth, 50)
        if p.odom_topic:
            self.create_subscription(Odometry, p.odom_topic, self._on_odom, 50)
        self.create_subscription(PoseStamped, p.goal_topic, self._on_goal, 10)
        if p.scenario == "car":
            status = get_message_class("actionlib_msgs/msg/GoalStatusArray")
            self.create_subscription(status, p.status_topic, self._on_status, 10)
        diag = get_message_class("diagnostic_msgs/msg/DiagnosticArray")
        self.create_subscription(diag, p.contact_topic, self._on_contacts, 50)
        if p.planner_diagnostics or p.slam:
            self.create_subscription(diag, "/diagnostics", self._on_diagnostics, 100)
        if p.slam:
            self.create_subscription(PoseStamped, p.slam_pose_topic, self._on_slam_pose, 10)
            self.create_subscription(PathMsg, p.slam_path_topic, self._on_slam_path, 1)
        if p.map_topic and p.scenario == "car":
            self.create_subscription(OccupancyGrid, p.map_topic, self._on_map, qos_profile_latched)
        if p.localization_source:
            self.tf_buffer = Buffer()
            self.tf_listener = TransformListener(self.tf_buffer, self)
            self.create_timer(0.1, self._sample_localization)

    # ------------------------------------------------------------------ callbacks
    def _on_truth(self, msg: Odometry) -> None:
        pos = msg.pose.pose.position
        stamp = time_to_ns(msg.header.stamp)
        self._truth.append((pos.x, pos.y, pos.z))
        self._truth_frame = msg.child_frame_id
        if not self._truth_ns or stamp > self._truth_ns[-1]:
            self._truth_ns.append(stamp)
            self._truth_poses.append(pose_to_matrix(msg.pose.pose))

    def _on_odom(self, msg: Odometry) -> None:
        self._odom_pose = pose_to_matrix(msg.pose.pose)

    def _on_goal(self, msg: PoseStamped) -> None:
        pos = msg.pose.position
        self._goals.append(GoalRecord(float(pos.x), float(pos.y), max(len(self._truth) - 1, 0)))
        if self._goal_sent_ns is None:
            self._goal_sent_ns = self.get_clock().now_ns()
            self._flight_start = len(self._truth)

    def _on_status(self, msg: Any) -> None:
        stamp = time_to_ns(msg.header.stamp)
        for status in msg.status_list:
            index = _goal_index(str(status.goal_id.id))
            if (
                index is None
                or index >= len(self._goals)
                or int(status.status) not in ENDED_STATUSES
            ):
                continue
            goal = self._goals[index]
            if goal.ended:
                continue
            goal.ended = True
            goal.succeeded = int(status.status) == SUCCEEDED_STATUS
            goal.duration_s = (stamp - time_to_ns(status.goal_id.stamp)) / 1e9
            self._score_drive(goal)
        ended = sum(g.ended for g in self._goals)
        if self._done_ns is None and ended >= self.params.goals:
            self._task_done()

    def _score_drive(self, goal: GoalRecord) -> None:
        from visnav.planning import GlobalPlanner, GlobalPlannerParams  # noqa: PLC0415

        path = np.asarray(self._truth[goal.start_index :] or [(math.nan,) * 3])[:, :2]
        goal.travelled_m = path_length(path)
        start = (float(path[0, 0]), float(path[0, 1]))
        # Between the same two points as the drive: to where the robot stopped (within the
        # navigator's tolerance of the goal), else to the goal (the end is inside the
        # robot_radius band of a true obstacle, where no plan may end).
        planner = GlobalPlanner(GlobalPlannerParams(cost_factor=0.0))
        best = planner.make_plan(self._true_costmap(), start, (path[-1, 0], path[-1, 1], 0.0))
        if not best.ok:
            best = planner.make_plan(self._true_costmap(), start, (goal.x, goal.y, 0.0))
        goal.shortest_m = best.length if best.ok else math.nan
        end_error = math.hypot(path[-1, 0] - goal.x, path[-1, 1] - goal.y)
        goal.reached = goal.succeeded and end_error < self.params.goal_tolerance

    def _true_costmap(self) -> Any:
        if self._truth_costmap is None:
            from scipy import ndimage  # noqa: PLC0415

            from visnav.mapping import LETHAL_OBSTACLE, Costmap2D  # noqa: PLC0415
            from visnav.sim.world_geometry import true_occupancy_grid  # noqa: PLC0415

            grid, origin = true_occupancy_grid(self.world, 0.05)
            cm = Costmap2D(grid.shape[1], grid.shape[0], 0.05, origin[0], origin[1])
            clearance = ndimage.distance_transform_edt(~grid) * 0.05
            cm.data[:] = np.where(clearance <= self.params.robot_radius, LETHAL_OBSTACLE, 0)
            self._truth_costmap = cm
        return self._truth_costmap

    def _on_contacts(self, msg: Any) -> None:
        p = self.params
        if p.contacts_after_goal and self._goal_sent_ns is None:
            return
        touching = any(not (p.contacts_ignore_ground and s.message == "plane") for s in msg.status)
        self._contacts.sample(time_to_ns(msg.header.stamp) / 1e9, touching=touching)

    def _on_diagnostics(self, msg: Any) -> None:
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if self.params.slam and "frames" in values and "keyframes" in values:
                self._slam_counters = values  # the SLAM node's latest counters
                continue
            if "planning_time_ms" not in values or "goals_reached" not in values:
                continue  # another node's diagnostics
            parsed = parse_planner_status(values)
            if parsed is None:
                self.get_logger().warning(
                    f"observer: /diagnostics status {status.name!r} has goals_reached "
                    f"{values['goals_reached']!r} and planning_time_ms "
                    f"{values['planning_time_ms'][:80]!r}: expected an integer and "
                    "comma-separated numbers; left out",
                    throttle_duration_sec=5.0,
                )
                continue
            reached, times = parsed
            self._planning_ms.extend(times)
            self._planner_reached = max(self._planner_reached, reached)
        if self._done_ns is None and self._planner_reached > 0:
            self._task_done()

    def _task_done(self) -> None:
        self._done_ns = self.get_clock().now_ns()
        self.create_timer(1e-9, self._on_step)  # fires at the next step of sim time

    def _on_slam_pose(self, msg: PoseStamped) -> None:
        self._slam_poses.append((time_to_ns(msg.header.stamp), pose_to_matrix(msg.pose)))

    def _on_slam_path(self, msg: PathMsg) -> None:
        self._slam_path = [
            (time_to_ns(ps.header.stamp), pose_to_matrix(ps.pose)) for ps in msg.poses
        ]

    def _on_map(self, msg: OccupancyGrid) -> None:
        self._map = msg

    def _on_step(self) -> None:
        """At the first step after the task is done: write the summary, end the launch."""
        if self._done_ns is None or self._written:
            return
        if self.get_clock().now_ns() <= self._done_ns:
            return
        self.finish()
        if self.params.exit_when_done:
            raise SystemExit(0)

    def _sample_localization(self) -> None:
        """10 Hz: ``map -> base`` and ``odom -> base`` at the newest ground-truth stamp TF has.

        The newest ground truth is often a step ahead of the robot's TF of the same stamp
        (published later in that step), so the sample before it is tried next.
        """
        p, base = self.params, self._truth_frame
        for k in (-1, -2):
            if len(self._truth_ns) < -k:
                return
            stamp, truth = self._truth_ns[k], self._truth_poses[k]
            try:
                est = self.tf_buffer.lookup_transform_matrix(p.map_frame, base, stamp)
                odom = self.tf_buffer.lookup_transform_matrix(p.odom_frame, base, stamp)
            except TransformException:
                continue
            self._loc.add(est, truth)
            first = self._odom_tf[:2] if self._odom_tf is not None else (truth, odom)
            self._odom_tf = (first[0], first[1], truth, odom)
            return

    # ------------------------------------------------------------------ results
    @property
    def done(self) -> bool:
        """True once the task is done (every goal ended; the drone reached its goal)."""
        return self._done_ns is not None

    def results(self, slam: SlamTrajectories | None = None) -> dict[str, Any]:
        """The task's summary keys.

        Args:
            slam: the SLAM trajectories if already computed
                (:func:`~visnav.scenarios.observer_results.slam_trajectories`).
        """
        from visnav.scenarios.observer_results import car_results, drone_results  # noqa: PLC0415

        return car_results(self, slam) if self.params.scenario == "car" else drone_results(self)

    def finish(self) -> dict[str, Any]:
        """Compute the summary and write it (and the map / SLAM files) to ``output_dir``."""
        from visnav.scenarios.observer_results import (  # noqa: PLC0415
            slam_trajectories,
            write_outputs,
        )

        now = self.get_clock().now_ns()
        summary: dict[str, Any] = {
            "scenario": self.params.scenario,
            "seed": self.params.seed,
            "sim_duration_s": round(now / 1e9, 6),
        }
        slam = slam_trajectories(self) if self.params.slam else None  # once: summary + files
        summary.update(self.results(slam))
        self.summary = summary
        self._written = True
        if self.params.output_dir:
            out = Path(self.params.output_dir)
            out.mkdir(parents=True, exist_ok=True)
            write_outputs(self, out, slam)
            tmp = out / "summary.json.tmp"  # whole or absent, even if this process is killed
            tmp.write_text(json.dumps(summary, indent=2) + "\n")
            tmp.replace(out / "summary.json")
        return summary

    def destroy_node(self) -> None:
        """Write the summary (if the task did not finish), then destroy the node."""
        if not getattr(self, "_written", True) and not getattr(self, "_destroyed_once", False):
            self._destroyed_once = True
            try:
                self.finish()
            except Exception as exc:  # noqa: BLE001 - shutting down: report and go on
                self.get_logger().error(f"observer: could not write the summary: {exc}")
        super().destroy_node()


def _goal_index(goal_id: str) -> int | None:
    """``goal_3`` (move_base's id of the third goal) -> 2; None for another id."""
    _, _, number = goal_id.rpartition("_")
    if not (number.isascii() and number.isdigit()) or len(number) > 9 or int(number) == 0:
        return None
    return int(number) - 1


def parse_planner_status(values: dict[str, str]) -> tuple[int, list[float]] | None:
    """``(goals_reached, planning times ms)`` of the planner's diagnostics; None if malformed."""
    text = values.get("goals_reached", "")
    if not (text.isascii() and text.isdigit()) or len(text) > 9:
        return None
    times: list[float] = []
    for item in values.get("planning_time_ms", "").split(","):
        if not item:
            continue
        try:
            value = float(item)
        except ValueError:
            return None
        if not math.isfinite(value):
            return None
        times.append(value)
    return int(text), times
