"""DWA with a circular robot that stands in the inscribed band: it may leave, never get closer."""

from __future__ import annotations

import numpy as np
import pytest

from visnav.mapping.costmap_2d import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE
from visnav.mapping.footprint import Footprint
from visnav.mapping.inflation_layer import InflationLayer
from visnav.mapping.layered_costmap import LayeredCostmap
from visnav.mapping.obstacle_layer import ObstacleLayer
from visnav.planning.dwa import DWAParams, DWAPlanner
from visnav.planning.local_planners import DWA_DEFAULTS


def _wall_costmap() -> LayeredCostmap:
    """A 4 x 4 m costmap from (-2, -2) with a wall of lethal cells along y in [-0.35, -0.30)."""
    obstacles = ObstacleLayer(footprint_clearing_enabled=False)
    lc = LayeredCostmap(
        "odom",
        width=4.0,
        height=4.0,
        origin_x=-2.0,
        origin_y=-2.0,
        footprint=Footprint.from_params(robot_radius=0.33),
        layers=[obstacles, InflationLayer()],
    )
    obstacles.grid.data[33, :] = LETHAL_OBSTACLE  # cell row 33: y in [-0.35, -0.30)
    lc.request_full_update()
    lc.update_map(0.0, 0.0, 0.0)
    return lc


def _distance_to_wall(y: np.ndarray) -> np.ndarray:
    return np.asarray(y) - (-0.325)  # to the wall cells' centres


@pytest.mark.parametrize("yaw", [0.6, 1.0, 1.57])
def test_a_robot_in_the_band_leaves_without_getting_closer(yaw: float) -> None:
    # seed 5: stopped at the edge of a corner's inscribed band, facing away from it; every
    # rollout at rest (0.125 m/s, |w| <= 0.16 rad/s) starts in an inscribed cell
    lc = _wall_costmap()
    cm = lc.costmap
    pose = (0.025, -0.02, yaw)  # 0.305 m from the wall cells: inscribed (0.34 m)
    cell = cm.world_to_map(*pose[:2])
    assert cell is not None
    assert cm.get_cost(*cell) == INSCRIBED_INFLATED_OBSTACLE
    dwa = DWAPlanner(DWAParams(**DWA_DEFAULTS))
    s = np.linspace(0.0, 1.5, 31)
    plan = np.stack([0.025 + s * np.cos(yaw), -0.02 + s * np.sin(yaw), np.full_like(s, yaw)], 1)
    dwa.set_plan(plan)
    r = dwa.compute_velocity(pose, (0.0, 0.0), cm, lc.footprint, (0.0, 0.0, 0.0))
    # before: "all 21 DWA trajectories collide" (every rollout starts in an inscribed cell)
    assert r.ok, r.reason
    assert r.v > 0
    d = _distance_to_wall(r.trajectory[:, 1])
    assert d.min() >= d[0] - 1e-9


def test_a_robot_in_the_band_is_not_let_closer() -> None:
    lc = _wall_costmap()
    cm = lc.costmap
    pose = (0.025, -0.02, -0.5)  # in the band, heading toward the wall
    dwa = DWAPlanner(DWAParams(**DWA_DEFAULTS))
    s = np.linspace(0.0, 1.5, 31)
    dwa.set_plan(np.stack([s * np.cos(-0.5), s * np.sin(-0.5), np.full_like(s, -0.5)], 1))
    v, w = dwa._samples((0.0, 0.0))
    xs, ys, ths, mask, _ = dwa._rollout(pose, v, w)
    valid, _ = dwa._obstacle_costs(xs, ys, ths, mask, v, cm, lc.footprint, robot=pose[:2])
    # every rollout at rest drives toward the wall: none may start
    assert not valid.any()
    r = dwa.compute_velocity(pose, (0.0, 0.0), cm, lc.footprint, (0.0, 0.0, 0.0))
    assert not r.ok


def test_outside_the_band_nothing_changes() -> None:
    lc = _wall_costmap()
    cm = lc.costmap
    pose = (0.025, 0.2, -0.5)  # 0.525 m from the wall, heading toward it
    dwa = DWAPlanner(DWAParams(**DWA_DEFAULTS))
    v, w = dwa._samples((0.3, 0.0))
    xs, ys, ths, mask, _ = dwa._rollout(pose, v, w)
    valid, _ = dwa._obstacle_costs(xs, ys, ths, mask, v, cm, lc.footprint, robot=pose[:2])
    centre = cm.costs_at(np.stack([xs[mask], ys[mask]], 1))
    hits = np.zeros(xs.shape, bool)
    hits[mask] = centre >= INSCRIBED_INFLATED_OBSTACLE
    np.testing.assert_array_equal(valid, ~hits.any(axis=1))
    assert valid.any()
    assert not valid.all()


def test_points_are_checked_against_the_lethal_cell_not_their_cell() -> None:
    """The inscribed band is made of whole cells: a point in a band cell may lie outside
    the inscribed radius (0.34 m) of the lethal cell, or well inside it."""
    obstacles = ObstacleLayer(footprint_clearing_enabled=False)
    lc = LayeredCostmap(
        "odom",
        width=2.0,
        height=2.0,
        origin_x=-1.0,
        origin_y=-1.0,
        footprint=Footprint.from_params(robot_radius=0.33),
        layers=[obstacles, InflationLayer()],
    )
    obstacles.grid.set_cost(20, 20, LETHAL_OBSTACLE)  # centre (0.025, 0.025)
    lc.request_full_update()
    lc.update_map(0.5, 0.5, 0.0)
    cm = lc.costmap
    # the cell of centre (0.325, 0.125): 0.316 m from the lethal centre, inscribed
    cell = cm.world_to_map(0.325, 0.125)
    assert cell is not None
    assert cm.get_cost(*cell) == INSCRIBED_INFLATED_OBSTACLE
    far = (0.349, 0.149)  # in that cell, 0.347 m from the lethal centre
    near = (0.301, 0.101)  # in that cell, 0.286 m from it
    dwa = DWAPlanner(DWAParams(**DWA_DEFAULTS))
    start = (0.7, 0.7)  # well outside the band
    for point, collides in ((far, False), (near, True)):
        xs = np.array([[start[0], point[0]]])
        ys = np.array([[start[1], point[1]]])
        mask = np.ones((1, 2), bool)
        valid, _ = dwa._obstacle_costs(
            xs, ys, np.zeros((1, 2)), mask, np.array([0.3]), cm, lc.footprint, robot=start
        )
        assert bool(valid[0]) is not collides
