"""The TurtleBot3 navigation tutorial's user, as a node (``exec: tb3_goals``).

What the user does in RViz after ``turtlebot3_navigation.launch``: "2D Pose Estimate"
(one ``geometry_msgs/PoseWithCovarianceStamped`` on ``initialpose`` at the robot's start,
with RViz's covariance: 0.25 m^2 in x and y, (pi/12)^2 rad^2 in yaw), then "2D Nav Goal"
(``geometry_msgs/PoseStamped`` on ``move_base_simple/goal``), the next one when move_base's
``move_base/status`` says the last one ended.

The goals are a seeded sample of the saved map's free cells (:func:`map_goals`): cells at
least ``clearance`` from any occupied or unknown cell of the map, each at least
``min_step`` from the one before, with a seeded heading. The node reads only the map file
and the clock, never ground truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.mapping.map_io import OccupancyMap, load_map
from visnav.msgs.rviz_tools import nav_goal, pose_estimate
from visnav.msgs.serde import get_message_class
from visnav.msgs.types import PoseStamped, PoseWithCovarianceStamped
from visnav.scenarios.errors import ScenarioError
from visnav.scenarios.observer_metrics import ENDED_STATUSES

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["Tb3Goals", "Tb3GoalsParams", "map_goals"]


def map_goals(
    occupancy: OccupancyMap,
    *,
    seed: int,
    count: int,
    clearance: float = 0.3,
    min_step: float = 1.0,
    start: tuple[float, float] | None = None,
) -> list[tuple[float, float, float]]:
    """``count`` seeded goals ``(x, y, yaw)`` in the free space of a saved map.

    Args:
        occupancy: the map (map_server's YAML and image).
        seed: seeds the choice.
        count: how many goals.
        clearance: fewest metres from any occupied or unknown cell.
        min_step: fewest metres from the previous goal (from ``start`` for the first).
        start: where the robot starts (x, y in the map frame).

    Raises:
        ScenarioError: the map has no cell that clear of obstacles.
    """
    data = occupancy.data
    res = occupancy.metadata.resolution
    ox, oy, _ = occupancy.metadata.origin
    free = (data >= 0) & (data < 25)
    dist = ndimage.distance_transform_edt(free) * res
    rows, cols = np.nonzero(dist >= clearance)
    if len(rows) == 0:
        msg = (
            f"map {occupancy.metadata.image}: no free cell is {clearance} m from an occupied "
            "or unknown cell; lower the clearance or use a map of a larger space"
        )
        raise ScenarioError(msg)
    xs = ox + (cols + 0.5) * res
    ys = oy + (rows + 0.5) * res
    rng = np.random.default_rng(seed)
    out: list[tuple[float, float, float]] = []
    prev = start
    for _ in range(count):
        ok: NDArray[np.bool_] = np.ones(len(xs), dtype=bool)
        if prev is not None:
            ok = np.hypot(xs - prev[0], ys - prev[1]) >= min_step
        idx = np.flatnonzero(ok) if ok.any() else np.arange(len(xs))
        k = int(idx[int(rng.integers(len(idx)))])
        yaw = float(rng.uniform(-math.pi, math.pi))
        out.append((float(xs[k]), float(ys[k]), yaw))
        prev = (float(xs[k]), float(ys[k]))
    return out


@dataclass(frozen=True)
class Tb3GoalsParams:
    """Parameters of :class:`Tb3Goals`."""

    map: str = param("", description="the saved map YAML the goals are drawn from (required)")
    seed: int = param(0, description="seeds the goal sequence (the run's seed)")
    goals: int = param(10, description="how many goals to send", range=(1, 1000))
    clearance: float = param(0.3, description="goal distance from obstacles (m)", range=(0, 10))
    min_step: float = param(1.0, description="distance between goals (m)", range=(0, 100))
    initial_x: float = param(-2.0, description="2D Pose Estimate x (turtlebot3_world's spawn)")
    initial_y: float = param(-0.5, description="2D Pose Estimate y")
    initial_yaw: float = param(0.0, description="2D Pose Estimate heading (rad)")
    pose_estimate: bool = param(True, description="publish the 2D Pose Estimate first")
    pose_time: float = param(0.5, description="sim time of the pose estimate (s)", range=(0, 1e6))
    start_time: float = param(2.0, description="sim time of the first goal (s)", range=(0, 1e6))
    frame_id: str = param("map", description="frame of the pose estimate and the goals")


class Tb3Goals(Node):
    """Gives AMCL its initial pose and move_base its goals, as a user in RViz (module docs).

    Parameters: :class:`Tb3GoalsParams`. Topics: out ``initialpose``,
    ``move_base_simple/goal``; in ``move_base/status``.

    Args:
        name: node name (default ``tb3_goals``).
        **node_kwargs: passed to :class:`~visnav.graph.Node`.

    Raises:
        ScenarioError: no ``map`` given, or no free cell clear enough.
    """

    def __init__(self, name: str = "tb3_goals", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        p = self.params = declare_params(self, Tb3GoalsParams)
        if not p.map:
            msg = (
                f"node {self.get_fully_qualified_name()}: parameter map is empty; expected the "
                "map YAML the goals are drawn from (map:=PATH/map.yaml)"
            )
            raise ScenarioError(msg)
        self.goals = map_goals(
            load_map(p.map),
            seed=p.seed,
            count=p.goals,
            clearance=p.clearance,
            min_step=p.min_step,
            start=(p.initial_x, p.initial_y),
        )
        self._pose_pub = self.create_publisher(PoseWithCovarianceStamped, "initialpose", 1)
        self._goal_pub = self.create_publisher(PoseStamped, "move_base_simple/goal", 1)
        status = get_message_class("actionlib_msgs/msg/GoalStatusArray")
        self.create_subscription(status, "move_base/status", self._on_status, 10)
        self._pose_sent = not p.pose_estimate
        self._sent = 0
        self._ended: set[str] = set()
        self._timer = self.create_timer(0.01, self._tick)

    def _on_status(self, msg: Any) -> None:
        for status in msg.status_list:
            if int(status.status) in ENDED_STATUSES:
                self._ended.add(str(status.goal_id.id))
        if 0 < self._sent < len(self.goals) and len(self._ended) >= self._sent:
            self._send_goal()

    def _tick(self) -> None:
        now = self.get_clock().now_ns()
        p = self.params
        if not self._pose_sent and now >= round(p.pose_time * 1e9):
            self._send_pose(now)
        if self._pose_sent and self._sent == 0 and now >= round(p.start_time * 1e9):
            self._send_goal()
        if self._sent:
            self._timer.cancel()

    def _send_pose(self, now: int) -> None:
        p = self.params
        msg = pose_estimate(
            p.initial_x, p.initial_y, p.initial_yaw, frame_id=p.frame_id, stamp_ns=now
        )
        self._pose_pub.publish(msg)
        self._pose_sent = True

    def _send_goal(self) -> None:
        x, y, yaw = self.goals[self._sent]
        self._sent += 1
        now = self.get_clock().now_ns()
        self._goal_pub.publish(nav_goal(x, y, yaw, frame_id=self.params.frame_id, stamp_ns=now))
