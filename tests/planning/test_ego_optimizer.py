"""A*, {p, v} pairs, the rebound optimisation, time re-allocation and whole replans."""

from __future__ import annotations

import numpy as np
import pytest

from visnav.mapping.grid_map import GridMap, GridMapParams
from visnav.planning.ego_planner.astar import AStar
from visnav.planning.ego_planner.bspline import UniformBspline, parameterize_to_bspline
from visnav.planning.ego_planner.manager import PlannerManager, PlannerParams
from visnav.planning.ego_planner.optimizer import BsplineOptimizer, OptimizerError


def _column_points(x: float, y: float, radius: float, height: float = 3.0) -> np.ndarray:
    zs = np.arange(0.0, height, 0.05)
    rs = np.linspace(0.0, radius, max(2, int(radius / 0.05) + 1))
    th = np.linspace(0.0, 2 * np.pi, 72, endpoint=False)
    r, t, z = np.meshgrid(rs, th, zs, indexing="ij")
    return np.column_stack([x + (r * np.cos(t)).ravel(), y + (r * np.sin(t)).ravel(), z.ravel()])


def _column_map(x: float = 3.0, y: float = 0.05, radius: float = 0.5) -> GridMap:
    gm = GridMap(GridMapParams(map_size=(20.0, 20.0, 3.0)))
    gm.mark_occupied(_column_points(x, y, radius))
    return gm


def _clearance(points: np.ndarray, x: float, y: float) -> float:
    return float(np.min(np.hypot(points[:, 0] - x, points[:, 1] - y)))


def test_astar_goes_around_a_column() -> None:
    gm = _column_map()
    path = AStar().search(gm.view(), [1.0, 0.0, 1.0], [5.0, 0.0, 1.0])
    assert len(path) > 0
    assert np.allclose(path[0], [1.0, 0.0, 1.0], atol=0.051)
    assert np.allclose(path[-1], [5.0, 0.0, 1.0], atol=0.051)
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    assert steps.max() <= np.sqrt(3) * 0.1 + 1e-9  # 26-connected moves of one node
    assert not gm.inflate_occupancy(path).any()
    assert _clearance(path, 3.0, 0.05) > 0.5
    # a goal inside the obstacle is pushed out, away from the start
    inside = AStar().search(gm.view(), [1.0, 0.0, 1.0], [3.0, 0.0, 1.0])
    assert len(inside) > 0
    assert not gm.inflate_occupancy(inside[-1:])[0]
    # walled in: no path
    boxed = GridMap(GridMapParams(map_size=(20.0, 20.0, 3.0), virtual_ceil_height=-1.0))
    wall = np.array([[2.0, y, z] for y in np.arange(-10, 10, 0.05) for z in np.arange(0, 3, 0.05)])
    boxed.mark_occupied(wall)
    assert len(AStar(max_expansions=20_000).search(boxed.view(), [1, 0, 1], [3, 0, 1])) == 0


def test_optimizer_pulls_a_straight_line_out_of_a_column() -> None:
    gm = _column_map()
    ts = 0.24
    line = np.linspace([0.0, 0.0, 1.0], [7.0, 0.0, 1.0], 30)
    ctrl = parameterize_to_bspline(ts, line, np.zeros((4, 3)))
    opt = BsplineOptimizer(gm, AStar())
    assert opt.init_control_points(ctrl) == 1
    with_pairs = np.nonzero(opt.counts)[0]
    assert len(with_pairs) > 3
    # every pair points out of the column, sideways
    v = opt.directions[with_pairs, 0]
    assert np.all(np.abs(v[:, 1]) > 0.5)
    before = UniformBspline(ctrl, 3, ts)
    assert opt.first_collision_time(before) is not None
    result = opt.optimize_rebound(ctrl, ts)
    assert result.success, result.reason
    after = UniformBspline(result.control_points, 3, ts)
    samples = after.evaluate(np.linspace(0.0, after.duration, 400))
    assert not gm.inflate_occupancy(samples).any()
    assert _clearance(samples, 3.0, 0.05) > 0.6  # column radius 0.5 + inflation
    # the ends stay fixed (only the inner control points are variables)
    assert np.allclose(result.control_points[:3], ctrl[:3])
    assert np.allclose(result.control_points[-3:], ctrl[-3:])


def test_a_hit_in_the_first_interval_fails() -> None:
    gm = _column_map(x=0.4, y=0.0, radius=0.3)
    line = np.linspace([0.0, 0.0, 1.0], [7.0, 0.0, 1.0], 30)
    ctrl = parameterize_to_bspline(0.24, line, np.zeros((4, 3)))
    opt = BsplineOptimizer(gm, AStar())
    opt.init_control_points(ctrl)
    result = opt.optimize_rebound(ctrl, 0.24)
    assert not result.success
    assert result.reason


def test_time_reallocation_and_refinement_make_the_trajectory_feasible() -> None:
    gm = GridMap(GridMapParams(map_size=(20.0, 20.0, 3.0)))
    manager = PlannerManager(gm)
    # from rest to rest, 4 m/s in between: too fast and too abrupt for the limits
    ts = 0.2
    points = np.column_stack(
        [np.linspace(0, 12, 16), 0.3 * np.sin(np.linspace(0, 6, 16)), np.ones(16)]
    )
    derivatives = np.zeros((4, 3))
    spline = UniformBspline(parameterize_to_bspline(ts, points, derivatives), 3, ts)
    p = manager.params
    ok, ratio = spline.check_feasibility(p.max_vel, p.max_acc, p.feasibility_tolerance)
    assert not ok
    assert ratio > 1.5
    success, refined = manager._refine(spline, derivatives, ratio)
    assert success
    ok, new_ratio = refined.check_feasibility(p.max_vel, p.max_acc, p.feasibility_tolerance)
    assert ok, new_ratio
    # the middle knots (5 .. len - 6) were stretched by the ratio
    inner = spline.knots[-6] - spline.knots[5]
    assert refined.duration == pytest.approx(spline.duration + (ratio - 1.0) * inner)
    # the shape is kept: the refined curve stays near the original path
    samples = refined.evaluate(np.linspace(0, refined.duration, 200))
    orig = spline.evaluate(np.linspace(0, spline.duration, 2000))
    dist = np.min(np.linalg.norm(samples[:, None] - orig[None], axis=2), axis=1)
    assert dist.max() < 0.3


def test_replan_through_a_small_forest() -> None:
    gm = GridMap(GridMapParams(map_size=(20.0, 20.0, 3.0)))
    rng = np.random.default_rng(3)
    columns = []
    while len(columns) < 14:
        x, y = rng.uniform([-3.0, -4.0], [6.0, 4.0])
        if all(np.hypot(x - cx, y - cy) > 1.6 for cx, cy, _ in columns):
            columns.append((x, y, rng.uniform(0.15, 0.45)))
    for x, y, r in columns:
        gm.mark_occupied(_column_points(x, y, r))
    manager = PlannerManager(gm, seed=1)
    start, goal = np.array([-6.0, 0.0, 1.0]), np.array([1.5, 0.0, 1.0])
    ok = manager.rebound_replan(
        start, np.zeros(3), np.zeros(3), goal, np.zeros(3), now_ns=0, poly_init=True
    )
    assert ok, manager.records[-1].reason
    local = manager.local
    assert local is not None
    samples = local.position.evaluate(np.linspace(0.0, local.duration, 600))
    assert np.allclose(samples[0], start, atol=0.01)  # a least-squares fit
    assert np.allclose(samples[-1], goal, atol=0.05)
    # ego-planner guarantees the first two thirds; the rest is replanned on the way
    trusted = samples[:400]
    assert not gm.inflate_occupancy(trusted).any()
    assert min(_clearance(trusted, x, y) - r for x, y, r in columns) > 0.1
    feasible, _ = local.position.check_feasibility(2.0, 3.0, 0.25)
    assert feasible
    record = manager.records[-1]
    assert record.success
    assert record.total_s == pytest.approx(record.init_s + record.optimize_s + record.refine_s)
    # too close to the target: refused, as upstream
    assert not manager.rebound_replan(
        goal, np.zeros(3), np.zeros(3), goal + 0.1, np.zeros(3), now_ns=0, poly_init=True
    )


def test_optimizer_input_errors() -> None:
    gm = GridMap(GridMapParams(map_size=(10.0, 10.0, 3.0)))
    opt = BsplineOptimizer(gm, AStar((20, 20, 20)))
    with pytest.raises(OptimizerError, match="N >= 7"):
        opt.init_control_points(np.zeros((5, 3)))
    with pytest.raises(OptimizerError, match="ref_pts"):
        opt.optimize_refine(np.zeros((9, 3)), 0.1, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="max_vel"):
        PlannerParams(max_vel=0.0)
