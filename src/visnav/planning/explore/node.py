"""``explore_lite``: greedy frontier exploration through move_base (m-explore's node).

The node (default name ``explore``, as explore_lite's executable) sends move_base goals
to frontiers of a map until none is left, then cancels move_base's goals, logs
``Exploration stopped.`` and stops planning.

Topics (relative names, so namespaces and remappings apply):

* in: ``costmap`` (``nav_msgs/OccupancyGrid``; parameter ``costmap_topic``: a SLAM map
  such as ``map`` or move_base's ``move_base/global_costmap/costmap``; its header frame is
  the global frame goals are sent in), ``/tf`` and ``/tf_static`` (global frame ->
  ``robot_base_frame``);
* out: ``~/frontiers`` (``visualization_msgs/MarkerArray``, only with ``visualize``: per
  frontier its cells as POINTS, blue, red when blacklisted, and a green SPHERE at the
  cell where the search met it, smaller for costlier frontiers);
* action client: ``move_base`` (``move_base_msgs/action/MoveBase``).

Every ``1 / planner_frequency`` seconds and at once when a goal ends, the node finds the
frontiers from the robot's position
(:func:`~visnav.planning.explore.frontier_search.search_frontiers`), picks the cheapest
one not blacklisted (:class:`~visnav.planning.explore.goals.GoalSelector`)
and sends its centroid (orientation identity, stamped now) unless it is the goal already
pursued. A goal move_base aborts, or one without progress for ``progress_timeout``, is
blacklisted. No frontier left (or only blacklisted ones): exploring stops.

Parameters: :class:`ExploreParams` (explore_lite's names and defaults, read once).

Where visnav differs from explore_lite (noetic 2.1.4):

* it does not block at start waiting for the costmap, the transform and move_base: each
  planning cycle is skipped (with one log line saying what is awaited) until all three
  are there;
* a map without a single free cell (a mapper's first grid, before any scan) is waited
  out; explore_lite finds no frontier in it and stops for good;
* a robot pose that cannot be looked up (or is older than ``transform_tolerance``)
  skips the cycle with a warning; explore_lite searches from the map origin then, and a
  robot outside the map stops exploring there (visnav logs an error and waits);
* ``costmap_updates`` (``map_msgs/OccupancyGridUpdate``) is subscribed only when the type
  store has ``map_msgs`` (visnav's ROS 2 Humble store has not yet); every visnav map and
  costmap publisher sends full grids, so nothing is lost;
* the costmap subscription is volatile (depth 1): it hears every new grid from a latched
  or a volatile publisher, but not a grid latched before the node started;
* frontier centroids count every frontier cell (see
  :mod:`~visnav.planning.explore.frontier_search`).

``orientation_scale`` is accepted and, as in explore_lite, unused. Neither noetic's
explore_lite nor this node has ``return_to_init`` or an ``explore/resume`` topic (those
came with the ROS 2 port).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.graph.action_client import ActionClient, ClientGoalHandle
from visnav.graph.action_types import GoalStatus, goal_id_from_bytes
from visnav.graph.future import Future
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.msgs.action import get_action_type
from visnav.msgs.construct import make
from visnav.msgs.errors import UnknownMessageTypeError
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time, time_to_ns
from visnav.msgs.types import (
    ColorRGBA,
    Marker,
    MarkerArray,
    OccupancyGrid,
    Point,
    Pose,
    PoseStamped,
    Quaternion,
    Vector3,
)
from visnav.planning.explore.costmap_client import ExploreCostmap
from visnav.planning.explore.frontier_search import (
    FREE_SPACE,
    Frontier,
    FrontierSearchError,
    search_frontiers,
)
from visnav.planning.explore.goals import Decision, GoalSelector
from visnav.tf.buffer import Buffer
from visnav.tf.errors import TransformException
from visnav.tf.ros import TransformListener

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["ExploreNode", "ExploreParams"]

_NS = 1_000_000_000
_UPDATE_TYPE = "map_msgs/msg/OccupancyGridUpdate"


@dataclass(frozen=True)
class ExploreParams:
    """explore_lite's parameters, names and defaults (read once at start)."""

    robot_base_frame: str = param("base_link", description="robot base frame")
    costmap_topic: str = param("costmap", description="OccupancyGrid to explore")
    costmap_updates_topic: str = param(
        "costmap_updates", description="map_msgs/OccupancyGridUpdate partial updates"
    )
    visualize: bool = param(False, description="publish the frontiers on ~/frontiers")
    planner_frequency: float = param(
        1.0, description="frontier search and goal choice rate (Hz)", range=(1e-3, 1000.0)
    )
    progress_timeout: float = param(
        30.0, description="blacklist a goal without progress for this long (s)", range=(0.0, 1e9)
    )
    potential_scale: float = param(1e-3, description="weight of a frontier's distance")
    orientation_scale: float = param(0.0, description="unused, as in explore_lite")
    gain_scale: float = param(1.0, description="weight of a frontier's size")
    transform_tolerance: float = param(
        0.3, description="oldest acceptable robot pose transform (s)", range=(0.0, 1e9)
    )
    min_frontier_size: float = param(
        0.5, description="shortest frontier pursued (m)", range=(0.0, 1e9)
    )


_BLUE = ColorRGBA(r=0.0, g=0.0, b=1.0, a=1.0)
_RED = ColorRGBA(r=1.0, g=0.0, b=0.0, a=1.0)
_GREEN = ColorRGBA(r=0.0, g=1.0, b=0.0, a=1.0)


class ExploreNode(Node):
    """explore_lite on the visnav graph (module docstring).

    Args:
        name: Node name (default ``explore``, explore_lite's).
        **node_kwargs: Passed to :class:`~visnav.graph.Node` (context, overrides, ...).

    Attributes:
        costmap: The latest grid, or None before the first one.
        selector: Blacklist and progress state.
        stopped: Exploring has ended (no frontier left).
        goals_sent: Goals sent to move_base so far.
        frontiers: The frontiers of the latest planning cycle.
    """

    def __init__(self, name: str = "explore", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        p = self.params = declare_params(self, ExploreParams)
        self.costmap: ExploreCostmap | None = None
        self.selector = GoalSelector(round(p.progress_timeout * _NS))
        self.stopped = False
        self.goals_sent = 0
        self.frontiers: list[Frontier] = []
        self.tf_buffer = Buffer()
        self.tf_listener = TransformListener(self.tf_buffer, self)
        self._move_base_type = get_action_type("move_base_msgs/action/MoveBase")
        self.move_base = ActionClient(self, self._move_base_type, "move_base")
        self._connected = False
        self._goal_seq = 0
        self._last_markers = 0
        self._markers = (
            self.create_publisher(MarkerArray, "~/frontiers", 10) if p.visualize else None
        )
        self.create_subscription(OccupancyGrid, p.costmap_topic, self._on_costmap, 1)
        try:
            update_type = get_message_class(_UPDATE_TYPE)
        except UnknownMessageTypeError:
            self.get_logger().debug(
                f"{_UPDATE_TYPE} is not in visnav's type store: '{p.costmap_updates_topic}' "
                "is not subscribed (full grids only)"
            )
        else:
            self.create_subscription(
                update_type, p.costmap_updates_topic, self._on_costmap_update, 10
            )
        self._timer = self.create_timer(1.0 / p.planner_frequency, self.make_plan)
        # load the compiled search now, not in the first cycle (it would age the pose)
        search_frontiers(np.zeros((1, 1), dtype=np.uint8), (0.5, 0.5), resolution=1.0)

    # ------------------------------------------------------------------ inputs
    def _on_costmap(self, msg: OccupancyGrid) -> None:
        try:
            self.costmap = ExploreCostmap.from_msg(msg, topic=self.params.costmap_topic)
        except FrontierSearchError as exc:
            self.get_logger().error(f"{exc}; grid ignored", throttle_duration_sec=5.0)

    def _on_costmap_update(self, msg: Any) -> None:
        if self.costmap is None:
            return
        note = self.costmap.apply_update(
            int(msg.x), int(msg.y), int(msg.width), int(msg.height), msg.data
        )
        if msg.header.frame_id:
            self.costmap.frame_id = str(msg.header.frame_id)
        if note:
            self.get_logger().warning(
                f"{self.params.costmap_updates_topic}: {note}", throttle_duration_sec=5.0
            )

    # ------------------------------------------------------------------ planning
    def _robot_xy(self, costmap: ExploreCostmap) -> tuple[float, float] | None:
        base, frame = self.params.robot_base_frame, costmap.frame_id
        try:
            ts = self.tf_buffer.lookup_transform(frame, base, 0)
        except TransformException as exc:
            self.get_logger().warning(
                f"no transform from '{base}' to '{frame}' (the costmap's frame): {exc}; "
                "waiting (set robot_base_frame, check the localiser)",
                throttle_duration_sec=5.0,
            )
            return None
        now = self.get_clock().now_ns()
        stamp = time_to_ns(ts.header.stamp)
        if stamp and now - stamp > self.params.transform_tolerance * _NS:
            self.get_logger().warning(
                f"the transform from '{base}' to '{frame}' is {(now - stamp) / _NS:.3f} s "
                f"old (transform_tolerance {self.params.transform_tolerance:g} s); waiting",
                throttle_duration_sec=5.0,
            )
            return None
        t = ts.transform.translation
        return float(t.x), float(t.y)

    def _ready(self) -> ExploreCostmap | None:
        costmap = self.costmap
        if costmap is None:
            self.get_logger().info(
                "Waiting for costmap to become available, topic: "
                f"{self.resolve_topic_name(self.params.costmap_topic)}",
                once=True,
            )
            return None
        if not self._connected:
            if not self.move_base.server_is_ready():
                self.get_logger().info("Waiting to connect to move_base server", once=True)
                return None
            self._connected = True
            self.get_logger().info("Connected to move_base server")
        return costmap

    def make_plan(self) -> None:
        """One planning cycle (the timer's callback; also run when a goal ends)."""
        if self.stopped:
            return
        costmap = self._ready()
        if costmap is None:
            return
        if not (costmap.costs == FREE_SPACE).any():
            self.get_logger().info(
                f"{self.params.costmap_topic}: no free cell in the map yet; waiting", once=True
            )
            return
        robot = self._robot_xy(costmap)
        if robot is None:
            return
        p = self.params
        try:
            frontiers = search_frontiers(
                costmap.costs,
                robot,
                resolution=costmap.resolution,
                origin=costmap.origin,
                potential_scale=p.potential_scale,
                gain_scale=p.gain_scale,
                min_frontier_size=p.min_frontier_size,
            )
        except FrontierSearchError as exc:
            self.get_logger().error(f"{exc}; waiting", throttle_duration_sec=5.0)
            return
        self.frontiers = frontiers
        self.get_logger().debug(f"found {len(frontiers)} frontiers")
        if frontiers and self._markers is not None:
            self._publish_markers(frontiers, costmap)
        now = self.get_clock().now_ns()
        choice = self.selector.select(frontiers, now, costmap.resolution)
        for x, y in choice.blacklisted:
            self.get_logger().debug(f"goal ({x:.2f}, {y:.2f}) made no progress: blacklisted")
        if choice.decision is Decision.STOP:
            if frontiers:  # a visnav addition: say why frontiers are left unexplored
                self.get_logger().info(
                    f"{choice.reason} (move_base aborted them or made no progress for "
                    f"progress_timeout {p.progress_timeout:g} s)"
                )
            self.stop()
        elif choice.decision is Decision.SEND and choice.goal is not None:
            self._send(choice.goal, costmap.frame_id, now)

    def _send(self, target: tuple[float, float], frame: str, now: int) -> None:
        pose = make(
            PoseStamped,
            pose=make(
                Pose,
                position=Point(x=target[0], y=target[1], z=0.0),
                orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )
        pose.header.frame_id = frame
        pose.header.stamp = ns_to_time(now)
        goal = make(self._move_base_type.Goal, target_pose=pose)
        self._goal_seq += 1
        seq = self._goal_seq
        self.goals_sent += 1
        future = self.move_base.send_goal_async(goal)
        future.add_done_callback(lambda f: self._on_goal_response(f, seq, target))

    def _on_goal_response(
        self, future: Future[ClientGoalHandle], seq: int, target: tuple[float, float]
    ) -> None:
        if seq != self._goal_seq:
            return
        handle = future.result() if future.exception() is None else None
        if handle is None or not handle.accepted:
            why = future.exception() or "rejected"
            self._reached(GoalStatus.STATUS_UNKNOWN, seq, target, f"goal not accepted: {why}")
            return
        handle.get_result_async().add_done_callback(lambda f: self._on_result(f, seq, target))

    def _on_result(self, future: Future[Any], seq: int, target: tuple[float, float]) -> None:
        response = future.result() if future.exception() is None else None
        if response is None:
            why = future.exception() or "no result"
            self._reached(GoalStatus.STATUS_UNKNOWN, seq, target, f"({why})")
            return
        self._reached(int(response.status), seq, target, "")

    def _reached(self, status: int, seq: int, target: tuple[float, float], note: str) -> None:
        # as actionlib's SimpleActionClient: only the latest goal's end is reported
        if seq != self._goal_seq or self.stopped:
            return
        self.get_logger().debug(
            f"goal ({target[0]:.2f}, {target[1]:.2f}) ended: status {status} {note}"
        )
        if status == GoalStatus.STATUS_ABORTED:
            self.selector.goal_aborted(target)
            self.get_logger().debug("Adding current goal to black list")
        self.make_plan()  # a new goal at once, whatever planner_frequency is

    def stop(self) -> None:
        """Cancel move_base's goals and stop exploring (explore_lite's ``stop``)."""
        if self.move_base.server_is_ready():
            self.move_base.cancel_goal_async(goal_id_from_bytes(bytes(16)))
        self._timer.cancel()
        self._goal_seq += 1
        self.stopped = True
        self.get_logger().info("Exploration stopped.")

    # ------------------------------------------------------------------ markers
    def _publish_markers(self, frontiers: list[Frontier], costmap: ExploreCostmap) -> None:
        if self._markers is None:
            return
        stamp = ns_to_time(self.get_clock().now_ns())
        min_cost = frontiers[0].cost
        markers: list[Marker] = []

        def marker(kind: int, action: int = Marker.ADD) -> Marker:
            m = make(Marker, ns="frontiers", id=len(markers), type=kind, action=action)
            m.header.frame_id = costmap.frame_id
            m.header.stamp = stamp
            m.frame_locked = True
            m.pose.orientation.w = 1.0
            return m

        for f in frontiers:
            pts = marker(Marker.POINTS)
            pts.scale = Vector3(x=0.1, y=0.1, z=0.1)
            pts.points = [Point(x=float(x), y=float(y), z=0.0) for x, y in f.points]
            blacklisted = self.selector.on_blacklist(f.centroid, costmap.resolution)
            pts.color = _RED if blacklisted else _BLUE
            markers.append(pts)
            sphere = marker(Marker.SPHERE)
            sphere.pose.position = Point(x=f.initial[0], y=f.initial[1], z=0.0)
            size = min(abs(min_cost * 0.4 / f.cost), 0.5) if f.cost else 0.5
            sphere.scale = Vector3(x=size, y=size, z=size)
            sphere.color = _GREEN
            markers.append(sphere)
        count = len(markers)
        for _ in range(count, self._last_markers):
            markers.append(marker(Marker.POINTS, Marker.DELETE))
        self._last_markers = count
        self._markers.publish(make(MarkerArray, markers=markers))
