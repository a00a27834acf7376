"""explore_lite's node on an in-process graph: a fake move_base "reaches" a goal by moving the
robot to the nearest free cell it can reach and revealing the map around it, on a known
synthetic world; exploring ends with "Exploration stopped." when no frontier is left."""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.graph.action_server import ActionServer, ServerGoalHandle
from visnav.graph.action_types import CancelResponse
from visnav.msgs import (
    Header,
    MapMetaData,
    MarkerArray,
    OccupancyGrid,
    Quaternion,
    Transform,
    TransformStamped,
    Vector3,
    make,
    ns_to_time,
)
from visnav.msgs.action import get_action_type
from visnav.node_registry import resolve_node_class
from visnav.planning.explore import occupancy_to_costs, search_frontiers
from visnav.planning.explore.node import ExploreNode
from visnav.tf.ros import TransformBroadcaster

RES = 0.1
RANGE_M = 2.5
MoveBase = get_action_type("move_base_msgs/action/MoveBase")


def _world() -> np.ndarray:
    """True obstacles of a 6 x 4 m flat: two rooms joined by a door, a pillar, a corridor."""
    g = np.zeros((40, 60), dtype=bool)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = True
    g[:, 30] = True
    g[16:22, 30] = False  # door
    g[8:12, 12:16] = True  # pillar
    g[25:, 45] = True  # a wall making a dead-end corridor in the east room
    return g


class FakeWorld:
    """Ground truth, what has been seen, and the robot's cell; thread-safe."""

    def __init__(self, obstacles: np.ndarray, start: tuple[int, int]) -> None:
        self.obstacles = obstacles
        self.known = np.zeros_like(obstacles)
        self.robot = start  # (col, row)
        self.lock = threading.Lock()
        self.version = 0
        self.forbidden_x: float | None = None
        self.visited: list[tuple[int, int]] = [start]
        self.reveal()

    def reveal(self) -> None:
        """Mark what a 360-degree sensor of RANGE_M sees (free cells reached around walls)."""
        h, w = self.obstacles.shape
        c0, r0 = self.robot
        reach = int(RANGE_M / RES)
        seen = np.zeros_like(self.obstacles)
        queue = deque([(c0, r0)])
        seen[r0, c0] = True
        while queue:
            c, r = queue.popleft()
            for dc in (-1, 0, 1):
                for dr in (-1, 0, 1):
                    cc, rr = c + dc, r + dr
                    if not (0 <= cc < w and 0 <= rr < h) or seen[rr, cc]:
                        continue
                    if (cc - c0) ** 2 + (rr - r0) ** 2 > reach**2:
                        continue
                    seen[rr, cc] = True
                    if not self.obstacles[rr, cc]:
                        queue.append((cc, rr))
        self.known |= seen
        self.version += 1

    def occupancy(self) -> np.ndarray:
        data = np.full(self.obstacles.shape, -1, dtype=np.int8)
        data[self.known & ~self.obstacles] = 0
        data[self.known & self.obstacles] = 100
        return data

    def reachable(self) -> np.ndarray:
        """Truly free cells 4-connected to the robot."""
        h, w = self.obstacles.shape
        out = np.zeros_like(self.obstacles)
        c0, r0 = self.robot
        out[r0, c0] = True
        queue = deque([(c0, r0)])
        while queue:
            c, r = queue.popleft()
            for cc, rr in ((c + 1, r), (c - 1, r), (c, r + 1), (c, r - 1)):
                if 0 <= cc < w and 0 <= rr < h and not out[rr, cc] and not self.obstacles[rr, cc]:
                    out[rr, cc] = True
                    queue.append((cc, rr))
        return out

    def drive_to(self, x: float, y: float) -> bool:
        """Move to the reachable free cell nearest (x, y) if within 0.4 m; False: abort."""
        with self.lock:
            if self.forbidden_x is not None and x > self.forbidden_x:
                return False
            rows, cols = np.nonzero(self.reachable())
            d = np.hypot((cols + 0.5) * RES - x, (rows + 0.5) * RES - y)
            k = int(np.argmin(d))
            if d[k] > 0.4:
                return False
            self.robot = (int(cols[k]), int(rows[k]))
            self.visited.append(self.robot)
            self.reveal()
            return True


class FakeMoveBase:
    """A move_base action server that teleports the robot (FakeWorld.drive_to)."""

    def __init__(self, ctx: Context, world: FakeWorld) -> None:
        self.world = world
        self.node = Node("move_base", context=ctx)
        self.goals: list[tuple[float, float]] = []
        self.aborted = 0
        self.published = 0
        self.hang = False
        self.cancelled = 0
        self.server = ActionServer(
            self.node,
            MoveBase,
            "move_base",
            self._execute,
            cancel_callback=lambda _goal: CancelResponse.ACCEPT,
        )

    def _execute(self, goal: ServerGoalHandle) -> Any:
        pose = goal.request.target_pose
        assert pose.header.frame_id == "map"
        assert pose.pose.orientation.w == 1.0
        x, y = pose.pose.position.x, pose.pose.position.y
        self.goals.append((x, y))
        if self.hang:  # a robot that never gets anywhere, until cancelled
            deadline = time.monotonic() + 10.0
            while not goal.is_cancel_requested and time.monotonic() < deadline:
                time.sleep(0.005)
            self.cancelled += 1
            goal.canceled()
            return make(MoveBase.Result)
        time.sleep(0.02)  # "driving"
        if goal.is_cancel_requested:
            goal.canceled()
        elif self.world.drive_to(x, y):
            deadline = time.monotonic() + 2.0  # let the new map go out first
            while self.published < self.world.version and time.monotonic() < deadline:
                time.sleep(0.005)
            goal.succeed()
        else:
            self.aborted += 1
            goal.abort()
        return make(MoveBase.Result)


class MapAndTf:
    """Publishes the seen map (``map``) and map -> base_link at the robot's cell."""

    def __init__(self, ctx: Context, world: FakeWorld, server: FakeMoveBase) -> None:
        self.world = world
        self.server = server
        self.node = Node("fake_slam", context=ctx)
        self.map_pub = self.node.create_publisher(OccupancyGrid, "map", 1)
        self.tf = TransformBroadcaster(self.node)

    def publish(self) -> None:
        with self.world.lock:
            data = self.world.occupancy()
            version = self.world.version
            c, r = self.world.robot
        now = self.node.get_clock().now_ns()
        h, w = data.shape
        msg = make(OccupancyGrid, info=make(MapMetaData, resolution=RES, width=w, height=h))
        msg.header.frame_id = "map"
        msg.header.stamp = ns_to_time(now)
        msg.data = data.reshape(-1)
        self.map_pub.publish(msg)
        self.tf.send_transform(
            TransformStamped(
                header=Header(stamp=ns_to_time(now), frame_id="map"),
                child_frame_id="base_link",
                transform=Transform(
                    translation=Vector3(x=(c + 0.5) * RES, y=(r + 0.5) * RES, z=0.0),
                    rotation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
                ),
            )
        )
        self.server.published = version


PARAMS = {
    "costmap_topic": "map",
    "robot_base_frame": "base_link",
    "planner_frequency": 5.0,
    "progress_timeout": 3.0,
    "potential_scale": 3.0,
    "min_frontier_size": 0.3,
    "visualize": True,
}


def _run(
    ctx: Context, world: FakeWorld, *, hang: bool = False, **overrides: Any
) -> tuple[ExploreNode, FakeMoveBase, list[Any]]:
    server = FakeMoveBase(ctx, world)
    server.hang = hang
    source = MapAndTf(ctx, world, server)
    explore = ExploreNode(context=ctx, parameter_overrides={**PARAMS, **overrides})
    markers: list[Any] = []
    Node("viewer", context=ctx).create_subscription(
        MarkerArray, "/explore/frontiers", markers.append, 10
    )
    deadline = time.monotonic() + 40.0
    while not explore.stopped and time.monotonic() < deadline:
        source.publish()
        ctx.spin_once(0.01)
    for _ in range(5):
        ctx.spin_once(0.01)
    return explore, server, markers


@pytest.fixture
def ctx() -> Any:
    with Context(transport="local") as c:
        yield c


def test_registry_name() -> None:
    assert resolve_node_class("explore_lite") is ExploreNode


def test_explores_until_no_frontier_is_left(ctx: Context, caplog: pytest.LogCaptureFixture) -> None:
    world = FakeWorld(_world(), start=(5, 5))
    with caplog.at_level(logging.INFO):
        explore, server, markers = _run(ctx, world)
    assert explore.stopped
    messages = [r.getMessage().removeprefix("[/explore] ") for r in caplog.records]
    assert "Exploration stopped." in messages
    assert "Connected to move_base server" in messages
    # the whole flat (both rooms, the corridor behind the wall) has been seen
    reachable = world.reachable()
    seen = world.known & reachable
    assert seen.sum() / reachable.sum() > 0.97
    assert world.known[:, 46:].any()  # the corridor beyond the east wall
    # nothing the search would still pursue
    costs = occupancy_to_costs(world.occupancy())
    x, y = (world.robot[0] + 0.5) * RES, (world.robot[1] + 0.5) * RES
    assert search_frontiers(costs, (x, y), resolution=RES, min_frontier_size=0.3) == []
    assert 3 <= explore.goals_sent == len(server.goals) < 40
    assert server.aborted == 0
    # markers: points and a sphere per frontier, in the map frame
    assert markers
    first = markers[0].markers
    assert {m.type for m in first} == {8, 2}  # POINTS, SPHERE
    assert all(m.header.frame_id == "map" and m.ns == "frontiers" for m in first)
    # later arrays delete markers of frontiers that are gone
    assert any(m.action == 2 for arr in markers for m in arr.markers)


def test_aborted_goals_are_blacklisted_and_exploring_stops(
    ctx: Context, caplog: pytest.LogCaptureFixture
) -> None:
    world = FakeWorld(_world(), start=(5, 5))
    world.forbidden_x = 3.0  # move_base cannot pass the door: the east room's goals abort
    with caplog.at_level(logging.INFO):
        explore, server, markers = _run(ctx, world)
    assert explore.stopped
    messages = [r.getMessage() for r in caplog.records]
    assert "[/explore] Exploration stopped." in messages
    assert any("frontiers are blacklisted (move_base aborted them" in m for m in messages)
    assert server.aborted >= 1
    assert explore.selector.blacklist
    assert all(c * RES < 3.05 for c, _ in world.visited)
    # the frontier at the door is still there, but blacklisted (drawn red)
    assert explore.frontiers
    red = [m for m in markers[-1].markers if m.type == 8 and m.color.r == 1.0]
    assert red


def test_waits_for_costmap_and_move_base(ctx: Context, caplog: pytest.LogCaptureFixture) -> None:
    explore = ExploreNode(context=ctx, parameter_overrides={"planner_frequency": 50.0})
    with caplog.at_level(logging.INFO):
        deadline = time.monotonic() + 0.3
        while time.monotonic() < deadline:
            ctx.spin_once(0.01)
    messages = [r.getMessage().removeprefix("[/explore] ") for r in caplog.records]
    assert "Waiting for costmap to become available, topic: /costmap" in messages
    assert messages.count("Waiting for costmap to become available, topic: /costmap") == 1
    assert not explore.stopped
    assert explore.goals_sent == 0
    assert explore.get_parameter("progress_timeout").value == 30.0
    assert explore.get_parameter("potential_scale").value == 1e-3
    assert explore.get_parameter("min_frontier_size").value == 0.5
    assert explore.get_parameter("transform_tolerance").value == 0.3
    assert explore.get_parameter("robot_base_frame").value == "base_link"
    assert explore.get_parameter("costmap_updates_topic").value == "costmap_updates"


def test_an_all_unknown_first_map_is_waited_out(
    ctx: Context, caplog: pytest.LogCaptureFixture
) -> None:
    world = FakeWorld(_world(), start=(5, 5))
    world.known[:] = False
    server = FakeMoveBase(ctx, world)
    source = MapAndTf(ctx, world, server)
    explore = ExploreNode(context=ctx, parameter_overrides=PARAMS)
    with caplog.at_level(logging.INFO):
        deadline = time.monotonic() + 0.6
        while time.monotonic() < deadline:
            source.publish()
            ctx.spin_once(0.01)
    assert not explore.stopped
    assert explore.goals_sent == 0
    messages = [r.getMessage() for r in caplog.records]
    assert "[/explore] map: no free cell in the map yet; waiting" in messages
    # the first scan arrives: exploring starts
    with world.lock:
        world.reveal()
    deadline = time.monotonic() + 5.0
    while explore.goals_sent == 0 and time.monotonic() < deadline:
        source.publish()
        ctx.spin_once(0.01)
    assert explore.goals_sent >= 1


def test_parameters_are_checked_and_read_once(ctx: Context) -> None:
    from visnav.graph.errors import ParameterError
    from visnav.graph.parameters import Parameter

    with pytest.raises(ParameterError, match="planner_frequency"):
        ExploreNode(context=ctx, parameter_overrides={"planner_frequency": 0.0})
    explore = ExploreNode("explore2", context=ctx)
    (result,) = explore.set_parameters([Parameter("gain_scale", 2.0)])
    assert not result.successful
    assert "read once" in result.reason


def test_goals_without_progress_time_out_one_after_another(ctx: Context) -> None:
    world = FakeWorld(_world(), start=(29, 18))  # in the door: frontiers on both sides
    initial = search_frontiers(
        occupancy_to_costs(world.occupancy()),
        (2.95, 1.85),
        resolution=RES,
        min_frontier_size=0.3,
    )
    assert len(initial) >= 2
    t0 = time.monotonic()
    explore, server, _ = _run(ctx, world, hang=True, progress_timeout=0.3, planner_frequency=20.0)
    took = time.monotonic() - t0
    assert explore.stopped
    # every frontier was tried once, given up after progress_timeout, and blacklisted
    assert len(server.goals) == len(initial) == len(explore.selector.blacklist)
    np.testing.assert_allclose(sorted(server.goals), sorted(f.centroid for f in initial))
    assert took > 0.3 * len(initial)
    assert world.visited == [(29, 18)]
    # stop() cancels move_base's goals: every hanging goal ends CANCELED
    deadline = time.monotonic() + 2.0
    while server.cancelled < len(initial) and time.monotonic() < deadline:
        ctx.spin_once(0.01)
    assert server.cancelled == len(initial)
