"""The scenarios' missions as nodes: what a user's script would send to the robot.

* :class:`CarGoalSender` (``car_goals``): a seeded sequence of goals from the office's
  free-space graph, sent one after another on ``move_base_simple/goal`` (the way
  ``rostopic pub`` / RViz's "2D Nav Goal" sends them); the next goal goes out when
  move_base's ``move_base/status`` reports the current one ended (succeeded, aborted,
  rejected or preempted).
* :class:`DroneMission` (``drone_mission``): take off with a hold command on
  ``command/pose``, then send the forest's goal on ``/move_base_simple/goal`` (ego-planner's
  waypoint_generator topic).

Both read only the world's description (its goal graph / start and goal) and the clock;
neither reads ground truth.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.description.world import load_world
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.graph.qos import qos_profile_latched
from visnav.msgs.construct import make
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header, Odometry, PoseStamped
from visnav.scenarios.errors import ScenarioError
from visnav.scenarios.observer_metrics import ENDED_STATUSES

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "GOAL_NODES",
    "CarGoalSender",
    "CarGoalsParams",
    "DroneMission",
    "DroneMissionParams",
    "goal_sequence",
    "pose_stamped",
]

GOAL_NODES = ("N1", "N2", "N3", "S1", "S2", "S3", "W", "E", "C1", "C2", "corr_nw", "corr_se")
"""Room centres and corridor corners of the office's free-space graph."""


def goal_sequence(
    graph_nodes: dict[str, Any], seed: int, count: int = 4
) -> list[tuple[float, float]]:
    """Return ``count`` seeded goals from the office's free-space graph (no repeats in a row).

    Raises:
        ScenarioError: none of :data:`GOAL_NODES` is in the graph.
    """
    rng = np.random.default_rng(seed)
    names = [n for n in GOAL_NODES if n in graph_nodes]
    if not names:
        msg = (
            f"the world's free-space graph has none of the goal nodes {list(GOAL_NODES)} "
            f"(it has {sorted(graph_nodes)[:8]}): the car's goals are picked from them"
        )
        raise ScenarioError(msg)
    out: list[str] = []
    while len(out) < count:
        pick = names[int(rng.integers(len(names)))]
        if not out or pick != out[-1]:
            out.append(pick)
    return [(float(graph_nodes[n][0]), float(graph_nodes[n][1])) for n in out]


def pose_stamped(x: float, y: float, z: float, stamp_ns: int, frame_id: str) -> PoseStamped:
    """A ``PoseStamped`` at ``(x, y, z)`` with the identity orientation."""
    msg: PoseStamped = make(PoseStamped)
    msg.header = Header(stamp=ns_to_time(stamp_ns), frame_id=frame_id)
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = x, y, z
    msg.pose.orientation.w = 1.0
    return msg


@dataclass(frozen=True)
class CarGoalsParams:
    """Parameters of :class:`CarGoalSender`."""

    world: str = param("office", description="world whose free-space graph gives the goals")
    seed: int = param(0, description="seeds the goal sequence (the run's seed)")
    goals: int = param(4, description="how many goals to send", range=(1, 1000))
    start_time: float = param(
        0.5, description="sim time of the first goal (s), once odometry arrived", range=(0, 1e6)
    )
    frame_id: str = param("map", description="frame of the goals")


class CarGoalSender(Node):
    """Sends the car's seeded goals to move_base one after another (module docstring).

    Parameters: :class:`CarGoalsParams`. Topics: out ``move_base_simple/goal``; in
    ``move_base/status`` (``actionlib_msgs/GoalStatusArray``), ``odom``.

    Args:
        name: node name (default ``car_goals``).
        **node_kwargs: passed to :class:`~visnav.graph.Node`.

    Raises:
        ScenarioError: a world without the goal graph.
    """

    def __init__(self, name: str = "car_goals", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        p = declare_params(self, CarGoalsParams)
        self._start_ns = round(p.start_time * 1e9)
        self._frame = p.frame_id
        graph = load_world(p.world, seed=p.seed).metadata.get("graph", {}).get("nodes")
        if not isinstance(graph, dict):
            msg = (
                f"node {self.get_fully_qualified_name()}: world {p.world!r} has no free-space "
                "graph (metadata graph.nodes) to pick goals from; use the office world"
            )
            raise ScenarioError(msg)
        self.goals = goal_sequence(graph, p.seed, p.goals)
        self._pub = self.create_publisher(PoseStamped, "move_base_simple/goal", 1)
        status = get_message_class("actionlib_msgs/msg/GoalStatusArray")
        self.create_subscription(status, "move_base/status", self._on_status, 10)
        self.create_subscription(Odometry, "odom", self._on_odom, 10)
        self._odom = False
        self._sent = 0
        self._ended: set[str] = set()
        self._timer = self.create_timer(0.005, self._tick)

    def _on_odom(self, _msg: Odometry) -> None:
        self._odom = True

    def _on_status(self, msg: Any) -> None:
        for status in msg.status_list:
            if int(status.status) in ENDED_STATUSES:
                self._ended.add(str(status.goal_id.id))
        # the next goal goes out at once, in the same step as the end of the last one
        if 0 < self._sent < len(self.goals) and len(self._ended) >= self._sent:
            self._send()

    def _tick(self) -> None:
        if self._sent == 0 and self._odom and self.get_clock().now_ns() >= self._start_ns:
            self._send()
        if self._sent:
            self._timer.cancel()

    def _send(self) -> None:
        x, y = self.goals[self._sent]
        self._sent += 1
        self._pub.publish(pose_stamped(x, y, 0.0, self.get_clock().now_ns(), self._frame))


@dataclass(frozen=True)
class DroneMissionParams:
    """Parameters of :class:`DroneMission`."""

    world: str = param("forest", description="world whose start / goal metadata is flown")
    seed: int = param(0, description="the world's seed (the run's seed)")
    takeoff_height: float = param(1.0, description="hover height (m)", range=(0.1, 100.0))
    goal_time: float = param(3.5, description="sim time the goal is sent (s)", range=(0, 1e6))
    frame_id: str = param("world", description="frame of the commands and the goal")


class DroneMission(Node):
    """Takes the quadrotor off and sends the forest's goal (module docstring).

    Parameters: :class:`DroneMissionParams`. Topics (relative names: the launch file puts
    the node in the drone's namespace): out ``command/pose`` (the hold command, latched),
    ``/move_base_simple/goal``.

    Args:
        name: node name (default ``drone_mission``).
        **node_kwargs: passed to :class:`~visnav.graph.Node`.

    Raises:
        ScenarioError: a world without start / goal metadata.
    """

    def __init__(self, name: str = "drone_mission", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        p = declare_params(self, DroneMissionParams)
        world = load_world(p.world, seed=p.seed)
        self._goal_ns = round(p.goal_time * 1e9)
        self._frame = p.frame_id
        try:
            start = [float(v) for v in world.metadata["start"]]
            goal = [float(v) for v in world.metadata["goal"]]
        except (KeyError, TypeError, ValueError):
            msg = (
                f"node {self.get_fully_qualified_name()}: world {p.world!r} has no start / "
                "goal metadata ([x, y]) for the flight; use the forest world"
            )
            raise ScenarioError(msg) from None
        self.goal = (goal[0], goal[1], p.takeoff_height)
        self._hold = self.create_publisher(PoseStamped, "command/pose", qos_profile_latched)
        self._hold_at: tuple[float, float, float] | None = (start[0], start[1], p.takeoff_height)
        self._pub = self.create_publisher(
            PoseStamped, "/move_base_simple/goal", qos_profile_latched
        )
        self._timer = self.create_timer(0.005, self._tick)

    def _tick(self) -> None:
        now = self.get_clock().now_ns()
        if self._hold_at is not None and now > 0:  # stamped once sim time has begun
            self._hold.publish(pose_stamped(*self._hold_at, now, self._frame))
            self._hold_at = None
        if now >= self._goal_ns:
            self._timer.cancel()
            self._pub.publish(pose_stamped(*self.goal, now, self._frame))
