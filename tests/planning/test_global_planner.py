"""The global planner against brute-force Dijkstra, A* against Dijkstra, and its refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from visnav.mapping import LETHAL_OBSTACLE, NO_INFORMATION, Costmap2D
from visnav.planning import (
    GlobalPlanner,
    GlobalPlannerParams,
    PlanningError,
    PlanStatus,
    path_to_msg,
    weight_table,
)


def _brute_force(weights: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    """8-connected graph distances (edge into m costs step * weight[m], no corner cutting)."""
    h, w = weights.shape
    rows, cols, vals = [], [], []
    for y in range(h):
        for x in range(w):
            for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)):
                nx, ny = x + dx, y + dy
                if not (0 <= nx < w and 0 <= ny < h) or not np.isfinite(weights[ny, nx]):
                    continue
                if dx and dy and not (np.isfinite(weights[y, nx]) and np.isfinite(weights[ny, x])):
                    continue
                if not np.isfinite(weights[y, x]) and (x, y) != start:
                    continue
                rows.append(y * w + x)
                cols.append(ny * w + nx)
                vals.append(math.hypot(dx, dy) * weights[ny, nx])
    graph = coo_matrix((vals, (rows, cols)), shape=(h * w, h * w)).tocsr()
    return dijkstra(graph, indices=start[1] * w + start[0]).reshape(h, w)


def _random_costmap(seed: int, h: int = 14, w: int = 17) -> Costmap2D:
    rng = np.random.default_rng(seed)
    cm = Costmap2D(w, h, 0.1)
    cm.data[:] = rng.choice([0, 0, 0, 20, 80, 200, LETHAL_OBSTACLE, NO_INFORMATION], size=(h, w))
    return cm


def _free_cell(cm: Costmap2D, rng: np.random.Generator) -> tuple[int, int]:
    free = np.argwhere(cm.data[1:-1, 1:-1] < 200) + 1
    y, x = free[rng.integers(len(free))]
    return int(x), int(y)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 100_000), allow_unknown=st.booleans(), astar=st.booleans())
def test_graph_potential_equals_brute_force_dijkstra(
    seed: int, allow_unknown: bool, astar: bool
) -> None:
    cm = _random_costmap(seed)
    rng = np.random.default_rng(seed + 1)
    params = GlobalPlannerParams(
        use_quadratic=False, allow_unknown=allow_unknown, use_dijkstra=not astar
    )
    planner = GlobalPlanner(params)
    s = _free_cell(cm, rng)
    g = _free_cell(cm, rng)
    start = cm.map_to_world(*s)
    goal = (*cm.map_to_world(*g), 0.0)
    result = planner.make_plan(cm, start, goal)
    weights = planner.weights(cm)
    weights[s[1], s[0]] = min(weights[s[1], s[0]], params.neutral_cost)
    ref = _brute_force(weights, s)
    if not np.isfinite(ref[g[1], g[0]]):
        assert result.status is not PlanStatus.OK
        return
    assert result.ok
    assert result.cost == pytest.approx(ref[g[1], g[0]], rel=1e-5)
    if not astar:  # Dijkstra settles every cell cheaper than the goal exactly
        pot = result.potential
        assert pot is not None
        settled = np.isfinite(pot) & (pot <= result.cost)
        np.testing.assert_allclose(pot[settled], ref[settled], rtol=1e-5)
    # the grid path's own cost is the optimum and it only crosses passable cells
    cells = np.floor((result.poses[1:-1, :2] - [cm.origin_x, cm.origin_y]) / cm.resolution).astype(
        int
    )
    assert np.isfinite(weights[cells[:, 1], cells[:, 0]]).all()


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 100_000))
def test_astar_cost_equals_dijkstra_cost(seed: int) -> None:
    cm = _random_costmap(seed, 30, 30)
    rng = np.random.default_rng(seed)
    s, g = _free_cell(cm, rng), _free_cell(cm, rng)
    start, goal = cm.map_to_world(*s), (*cm.map_to_world(*g), 0.0)
    for quadratic in (False, True):
        d = GlobalPlanner(GlobalPlannerParams(use_quadratic=quadratic)).make_plan(cm, start, goal)
        a = GlobalPlanner(
            GlobalPlannerParams(use_quadratic=quadratic, use_dijkstra=False)
        ).make_plan(cm, start, goal)
        assert d.status == a.status
        if d.ok:
            if quadratic:  # A* orders the eikonal front differently: nearly equal
                assert a.cost == pytest.approx(d.cost, rel=0.03)
            else:
                assert a.cost == pytest.approx(d.cost, rel=1e-6)
            assert a.expanded <= d.expanded


def test_quadratic_potential_is_near_euclidean_in_free_space() -> None:
    cm = Costmap2D(100, 100, 0.05)
    planner = GlobalPlanner()
    r = planner.make_plan(cm, (0.5, 0.5), (4.0, 3.0, 1.0))
    assert r.ok
    straight = math.hypot(3.5, 2.5)
    assert straight <= r.length <= 1.01 * straight
    cells = straight / 0.05
    assert r.cost == pytest.approx(cells * 50.0, rel=0.02)  # eikonal: ~ distance x neutral cost
    assert r.poses[0, :2].tolist() == [0.5, 0.5]
    assert r.poses[-1].tolist() == [4.0, 3.0, 1.0]
    # the graph version is longer (8-connected moves)
    g = GlobalPlanner(GlobalPlannerParams(use_quadratic=False)).make_plan(
        cm, (0.5, 0.5), (4.0, 3.0, 1.0)
    )
    assert g.cost > r.cost


def test_path_goes_around_a_wall() -> None:
    cm = Costmap2D(60, 40, 0.05)
    cm.data[0:30, 30] = LETHAL_OBSTACLE
    r = GlobalPlanner().make_plan(cm, (0.5, 0.5), (2.5, 0.5, 0.0))
    assert r.ok
    assert r.poses[:, 1].max() > 1.5  # over the top of the wall
    cells = cm.world_to_map_array(r.poses[:, :2])
    assert (cm.data[cells[1], cells[0]] != LETHAL_OBSTACLE).all()


def test_refusals_name_the_problem() -> None:
    cm = Costmap2D(40, 40, 0.05)
    cm.data[15:25, 15:25] = LETHAL_OBSTACLE
    cm.data[30:35, 30] = LETHAL_OBSTACLE
    cm.data[30:35, 34] = LETHAL_OBSTACLE
    cm.data[30, 30:35] = LETHAL_OBSTACLE
    cm.data[34, 30:35] = LETHAL_OBSTACLE
    p = GlobalPlanner()
    r = p.make_plan(cm, (0.2, 0.2), (5.0, 1.0, 0.0))
    assert r.status is PlanStatus.GOAL_OUTSIDE_MAP
    assert "outside the global costmap" in r.reason
    r = p.make_plan(cm, (-1.0, 0.2), (1.0, 1.0, 0.0))
    assert r.status is PlanStatus.START_OUTSIDE_MAP
    r = p.make_plan(cm, (0.2, 0.2), (1.0, 1.0, 0.0))
    assert r.status is PlanStatus.GOAL_IN_OBSTACLE
    assert "in an obstacle (cost 254" in r.reason
    r = p.make_plan(cm, (0.2, 0.2), (1.6, 1.6, 0.0))  # enclosed free cell
    assert r.status is PlanStatus.NO_PATH
    assert "not connected" in r.reason
    cm.data[5, 5] = NO_INFORMATION
    r = GlobalPlanner(GlobalPlannerParams(allow_unknown=False)).make_plan(
        cm, (0.2, 0.2), (0.27, 0.27, 0.0)
    )
    assert r.status is PlanStatus.GOAL_IN_OBSTACLE
    assert "unknown space" in r.reason


def test_tolerance_plans_to_the_closest_reachable_cell() -> None:
    cm = Costmap2D(40, 40, 0.05)
    cm.data[15:25, 15:25] = LETHAL_OBSTACLE
    p = GlobalPlanner(GlobalPlannerParams(default_tolerance=0.5))
    r = p.make_plan(cm, (0.2, 0.2), (1.0, 1.0, 0.0))
    assert r.ok
    assert r.goal_used is not None
    gx, gy = r.goal_used
    assert math.hypot(gx - 1.0, gy - 1.0) <= 0.5 * math.sqrt(2)
    assert cm.data[cm.world_to_map(gx, gy)[::-1]] != LETHAL_OBSTACLE  # type: ignore[index]
    r = p.make_plan(cm, (0.2, 0.2), (1.0, 1.0, 0.0), tolerance=0.1)
    assert r.status is PlanStatus.GOAL_IN_OBSTACLE


def test_weight_table_is_global_planners_get_cost() -> None:
    t = weight_table(GlobalPlannerParams())
    assert t[0] == 50
    assert t[10] == 80
    assert t[67] == 50 + 3 * 67
    assert t[100] == 252  # clamped to lethal_cost - 1
    assert np.isinf(t[252])
    assert np.isinf(t[253])
    assert np.isinf(t[254])
    assert t[255] == 252
    assert np.isinf(weight_table(GlobalPlannerParams(allow_unknown=False))[255])
    with pytest.raises(PlanningError, match="neutral_cost is 0"):
        GlobalPlannerParams(neutral_cost=0)


def test_path_message() -> None:
    msg = path_to_msg(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, math.pi / 2]]), "map", 3)
    assert msg.header.frame_id == "map"
    assert len(msg.poses) == 2
    assert msg.poses[1].pose.orientation.z == pytest.approx(math.sin(math.pi / 4))
