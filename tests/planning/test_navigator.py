"""The navigator driving a kinematic unicycle with a ray-cast scanner (no graph, no MuJoCo)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from visnav.mapping import (
    Footprint,
    InflationLayer,
    LayeredCostmap,
    ObservationSource,
    ObstacleLayer,
    StaticLayer,
    scan_points,
)
from visnav.msgs import LaserScan, MapMetaData, OccupancyGrid, make
from visnav.planning import (
    ControlResult,
    DWAPlanner,
    GlobalPlanner,
    GoalStatus,
    NavError,
    Navigator,
    NavigatorParams,
    NavState,
    RegulatedPurePursuit,
)

RES = 0.05
ORIGIN = (-0.5, -0.5)
RADIUS = 0.2
DT = 0.05


def _world() -> np.ndarray:
    """A 7 x 5 m room with an inner wall and a closed box (the unreachable region)."""
    g = np.zeros((100, 140), bool)
    g[:2, :] = g[-2:, :] = True
    g[:, :2] = g[:, -2:] = True
    g[0:60, 60:62] = True  # inner wall from the bottom, open at the top
    g[70:92, 100:102] = g[70:92, 122:124] = True  # box walls
    g[70:72, 100:124] = g[90:92, 100:124] = True
    return g


def _map_msg(grid: np.ndarray) -> OccupancyGrid:
    h, w = grid.shape
    msg = make(OccupancyGrid, info=make(MapMetaData, resolution=RES, width=w, height=h))
    msg.info.origin.position.x, msg.info.origin.position.y = ORIGIN
    msg.info.origin.orientation.w = 1.0
    msg.header.frame_id = "map"
    msg.data = np.where(grid, 100, 0).astype(np.int8).reshape(-1)
    return msg


def _scan(grid: np.ndarray, x: float, y: float, th: float, *, n: int = 90) -> LaserScan:
    fov = 1.52
    rel = np.linspace(-fov / 2, fov / 2, n)
    steps = np.arange(0.0, 6.0, RES / 2)
    px = x + np.cos(th + rel)[:, None] * steps
    py = y + np.sin(th + rel)[:, None] * steps
    ix = np.floor((px - ORIGIN[0]) / RES).astype(int)
    iy = np.floor((py - ORIGIN[1]) / RES).astype(int)
    inside = (ix >= 0) & (iy >= 0) & (ix < grid.shape[1]) & (iy < grid.shape[0])
    occ = np.zeros(ix.shape, bool)
    occ[inside] = grid[iy[inside], ix[inside]]
    first = np.where(occ.any(axis=1), occ.argmax(axis=1), -1)
    r = np.where(first >= 0, steps[np.maximum(first, 0)], np.inf)
    return make(
        LaserScan,
        angle_min=-fov / 2,
        angle_max=fov / 2,
        angle_increment=fov / (n - 1),
        range_min=0.1,
        range_max=6.0,
        ranges=r.astype(np.float32),
    )


def _collides(grid: np.ndarray, x: float, y: float) -> bool:
    ys, xs = np.nonzero(grid)
    cx = ORIGIN[0] + (xs + 0.5) * RES
    cy = ORIGIN[1] + (ys + 0.5) * RES
    return bool((np.hypot(cx - x, cy - y) < RADIUS - RES).any())


@dataclass
class Robot:
    """A unicycle in a world, feeding the navigator's costmaps like the node would."""

    navigator: Navigator
    grid: np.ndarray
    x: float = 0.5
    y: float = 0.5
    th: float = 0.0
    v: float = 0.0
    w: float = 0.0
    t: float = 0.0
    scans: bool = True
    empty_scans: bool = False
    travelled: float = 0.0
    states: list[NavState] = field(default_factory=list)
    collided: bool = False

    def step(self) -> None:
        now = round(self.t * 1e9)
        nav = self.navigator
        obstacle_layers = [la for cm in (nav.global_costmap, nav.local_costmap) for la in cm.layers]
        if self.scans:
            msg = _scan(self.grid, self.x, self.y, self.th)
            if self.empty_scans:
                msg.ranges = np.empty(0, np.float32)
            pts, n = scan_points(msg)
            c, s = math.cos(self.th), math.sin(self.th)
            T = np.array([[c, -s, 0, self.x], [s, c, 0, self.y], [0, 0, 1, 0.3], [0, 0, 0, 1.0]])
            for layer in obstacle_layers:
                if isinstance(layer, ObstacleLayer):
                    layer.add_points(
                        "scan",
                        pts,
                        T,
                        stamp_ns=now,
                        now_ns=now,
                        empty_text="" if n else "no ranges",
                    )
        pose = (self.x, self.y, self.th)
        nav.global_costmap.update_map(*pose, now_ns=now)
        nav.local_costmap.update_map(*pose, now_ns=now)
        self.v, self.w = nav.step(now, pose, pose, (self.v, self.w))
        self.states.append(nav.state)
        nx = self.x + self.v * math.cos(self.th) * DT
        ny = self.y + self.v * math.sin(self.th) * DT
        self.travelled += math.hypot(nx - self.x, ny - self.y)
        self.x, self.y = nx, ny
        self.th += self.w * DT
        self.t += DT
        self.collided |= _collides(self.grid, self.x, self.y)

    def run(self, limit_s: float) -> None:
        h = self.navigator.handle
        assert h is not None
        end = self.t + limit_s
        while not h.done and self.t < end:
            self.step()


def _navigator(controller: str = "dwa", **params: float) -> tuple[Navigator, list[tuple[str, str]]]:
    fp = Footprint.from_params(robot_radius=RADIUS)
    gc = LayeredCostmap("map", resolution=RES, track_unknown_space=True, footprint=fp)
    static = StaticLayer()
    gc.add_layer(static)
    gc.add_layer(ObstacleLayer(sources=[ObservationSource("scan", clearing=True)]))
    gc.add_layer(InflationLayer())
    static.set_map(_map_msg(_world()))
    lc = LayeredCostmap(
        "odom", width=4.0, height=4.0, resolution=RES, rolling_window=True, footprint=fp
    )
    src = ObservationSource("scan", clearing=True, expected_update_rate=0.3)
    lc.add_layer(ObstacleLayer(sources=[src]))
    lc.add_layer(InflationLayer())
    log: list[tuple[str, str]] = []
    ctl = DWAPlanner() if controller == "dwa" else RegulatedPurePursuit()
    nav = Navigator(
        gc,
        lc,
        GlobalPlanner(),
        ctl,
        NavigatorParams(**params),  # type: ignore[arg-type]
        log=lambda level, text: log.append((level, text)),
    )
    return nav, log


@pytest.mark.parametrize("controller", ["dwa", "rpp"])
def test_reaches_a_goal_behind_the_wall(controller: str) -> None:
    nav, log = _navigator(controller)
    robot = Robot(nav, _world())
    h = nav.go_to((4.5, 1.0, -math.pi / 2))
    assert h.status is GoalStatus.ACTIVE
    assert nav.state is NavState.PLANNING
    robot.run(60.0)
    assert h.status is GoalStatus.SUCCEEDED, h.text
    assert h.error is NavError.NONE
    assert not robot.collided
    assert NavState.CONTROLLING in robot.states
    assert math.hypot(robot.x - 4.5, robot.y - 1.0) < 0.3
    assert h.plans >= 2  # replanned at planner_frequency
    assert robot.travelled < 1.3 * 7.4  # around the wall: ~7 m
    assert nav.state is NavState.IDLE
    assert any("succeeded" in text for _, text in log)


def test_unreachable_goal_aborts_after_the_recoveries() -> None:
    nav, log = _navigator(planner_patience=0.5)
    robot = Robot(nav, _world())
    h = nav.go_to((5.05, 3.55, 0.0))  # inside the closed box
    robot.run(120.0)
    assert h.status is GoalStatus.ABORTED
    assert h.error is NavError.NO_PATH
    assert "even after 5 recovery behaviours" in h.text
    assert "not connected" in h.text
    assert h.recoveries == [
        "conservative_reset",
        "rotate_recovery",
        "aggressive_reset",
        "back_up",
        "rotate_recovery_2",
    ]
    assert not robot.collided
    assert robot.v == 0.0
    assert robot.w == 0.0
    assert ("error", f"goal {h.goal_id} aborted: {h.text}") in log


def test_bad_goals_stop_with_a_reason() -> None:
    nav, _ = _navigator()
    robot = Robot(nav, _world())
    h = nav.go_to((20.0, 1.0, 0.0))
    robot.step()
    assert h.status is GoalStatus.ABORTED
    assert h.error is NavError.GOAL_OUTSIDE_MAP
    assert "outside the global costmap" in h.text
    h = nav.go_to((2.525, 1.0, 0.0))  # in the inner wall
    robot.run(2.0)
    assert h.status is GoalStatus.ABORTED
    assert h.error is NavError.GOAL_IN_OBSTACLE
    assert "is in an obstacle" in h.text
    h = nav.go_to((math.nan, 1.0, 0.0))
    assert h.status is GoalStatus.REJECTED
    assert h.error is NavError.INVALID_GOAL
    assert robot.v == 0.0


def test_stale_and_empty_scans_stop_the_robot_until_data_return() -> None:
    nav, log = _navigator()
    robot = Robot(nav, _world())
    h = nav.go_to((1.8, 3.5, 0.0))
    for _ in range(30):
        robot.step()
    assert robot.v > 0.1
    robot.scans = False
    for _ in range(10):
        robot.step()
    assert h.status is GoalStatus.ACTIVE
    assert robot.v == 0.0
    assert robot.w == 0.0
    assert "has not been updated for" in h.text
    warnings = [t for level, t in log if level == "warning" and "not current" in t]
    assert len(warnings) == 1  # one log line, not one per cycle
    robot.scans = True
    robot.empty_scans = True
    robot.step()
    assert robot.v == 0.0
    assert "was empty" in h.text
    robot.empty_scans = False
    robot.run(40.0)
    assert h.status is GoalStatus.SUCCEEDED, h.text
    assert not robot.collided


def test_preempt_and_cancel() -> None:
    nav, _ = _navigator()
    robot = Robot(nav, _world())
    first = nav.go_to((1.8, 3.5, 0.0))
    robot.step()
    second = nav.go_to((0.5, 3.5, 0.0))
    assert first.status is GoalStatus.PREEMPTED
    assert first.error is NavError.PREEMPTED
    assert second.status is GoalStatus.ACTIVE
    robot.step()
    nav.cancel()
    assert second.status is GoalStatus.PREEMPTED
    assert second.error is NavError.CANCELED
    robot.step()
    assert (robot.v, robot.w) == (0.0, 0.0)


class _Stuck:
    """A local planner that never moves the robot (valid zero commands) or always fails."""

    def __init__(self, *, fail: bool) -> None:
        self.fail = fail

    def set_plan(self, plan: np.ndarray) -> None:
        pass

    def compute_velocity(self, *args: object) -> ControlResult:
        return (
            ControlResult(False, reason="boxed in") if self.fail else ControlResult(True, 0.0, 0.0)
        )

    def is_goal_reached(
        self, pose: tuple[float, float, float], velocity: tuple[float, float]
    ) -> bool:
        return False

    def reset(self) -> None:
        pass


@pytest.mark.parametrize(
    ("fail", "error"), [(False, NavError.OSCILLATING), (True, NavError.CONTROL_FAILED)]
)
def test_no_progress_and_no_control_end_in_recoveries(fail: bool, error: NavError) -> None:
    nav, _ = _navigator(oscillation_timeout=2.0, controller_patience=1.0)
    nav.controller = _Stuck(fail=fail)
    robot = Robot(nav, _world())
    h = nav.go_to((4.5, 1.0, 0.0))
    robot.run(200.0)
    assert h.status is GoalStatus.ABORTED
    assert h.error is error
    assert len(h.recoveries) == 5
    if fail:
        assert "boxed in" in h.text
    else:
        assert "oscillating" in h.text
