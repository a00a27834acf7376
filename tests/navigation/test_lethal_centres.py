"""Costmap2D.lethal_centres (one helper for DWA's band test and rotate_recovery) and DWA's
explicit robot position."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.mapping.costmap_2d import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, Costmap2D
from visnav.mapping.footprint import Footprint
from visnav.mapping.inflation_layer import InflationLayer
from visnav.mapping.layered_costmap import LayeredCostmap
from visnav.mapping.obstacle_layer import ObstacleLayer
from visnav.planning.dwa import _circle_collisions
from visnav.planning.recovery import nearest_lethal


def _reference(cm: Costmap2D, box: tuple[float, float, float, float]) -> set[tuple[float, float]]:
    """Centres of the lethal cells between the cells holding the box's corners (the
    costmap's own floor rule decides a point on a cell boundary), one cell at a time."""
    x0, y0 = cm.world_to_map_no_bounds(box[0], box[1])
    x1, y1 = cm.world_to_map_no_bounds(box[2], box[3])
    out = set()
    for my, mx in zip(*np.nonzero(cm.data == LETHAL_OBSTACLE), strict=True):
        if x0 <= mx <= x1 and y0 <= my <= y1:
            out.add(cm.map_to_world(int(mx), int(my)))
    return out


def _map(rng: np.random.Generator) -> Costmap2D:
    cm = Costmap2D(12, 9, 0.25, -1.0, 0.5)
    cm.data[:] = np.where(rng.random((9, 12)) < 0.3, LETHAL_OBSTACLE, 0)
    return cm


@settings(max_examples=150, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    x=st.floats(-3.0, 3.5),
    y=st.floats(-1.5, 4.5),
    w=st.floats(0.0, 3.0),
    h=st.floats(0.0, 3.0),
)
def test_matches_a_cell_by_cell_reference(
    seed: int, x: float, y: float, w: float, h: float
) -> None:
    # the grid spans x in [-1, 2), y in [0.5, 2.75): boxes inside, across every edge and off it
    cm = _map(np.random.default_rng(seed))
    box = (x, y, x + w, y + h)
    got = cm.lethal_centres(*box)
    assert got.shape[1] == 2
    assert got.dtype == np.float64
    assert {(float(a), float(b)) for a, b in got} == _reference(cm, box)
    assert len(got) == len(_reference(cm, box))


def test_map_edges_and_empty_results() -> None:
    cm = Costmap2D(4, 3, 0.5, 0.0, 0.0)
    cm.set_cost(0, 0, LETHAL_OBSTACLE)  # centre (0.25, 0.25): lower-left corner cell
    cm.set_cost(3, 2, LETHAL_OBSTACLE)  # centre (1.75, 1.25): upper-right corner cell
    cm.set_cost(2, 1, INSCRIBED_INFLATED_OBSTACLE)  # not lethal
    # a box hanging over the lower-left corner
    np.testing.assert_array_equal(cm.lethal_centres(-5.0, -5.0, 0.1, 0.1), [[0.25, 0.25]])
    # over the upper-right corner
    np.testing.assert_array_equal(cm.lethal_centres(1.9, 1.4, 9.0, 9.0), [[1.75, 1.25]])
    # the whole grid and beyond: row-major order
    np.testing.assert_array_equal(
        cm.lethal_centres(-1.0, -1.0, 3.0, 3.0), [[0.25, 0.25], [1.75, 1.25]]
    )
    # boxes that miss the grid give nothing (clamping to the edge cells would find them)
    for box in ((-2.0, -2.0, -0.01, -0.01), (2.01, 0.0, 3.0, 1.0), (0.0, 1.51, 2.0, 2.0)):
        assert cm.lethal_centres(*box).shape == (0, 2)
    # an inverted box and an empty grid
    assert cm.lethal_centres(1.0, 1.0, 0.0, 0.0).shape == (0, 2)
    assert Costmap2D(0, 0, 0.5).lethal_centres(-1.0, -1.0, 1.0, 1.0).shape == (0, 2)


def test_circle_collisions_take_the_robot_position_not_the_first_point() -> None:
    """A robot 0.24 m from a lethal centre (inside the 0.33 m inscribed radius) may move
    to a point 0.29 m away; the first trajectory point used to stand for the robot."""
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
    robot = (0.265, 0.025)  # 0.24 m from the lethal centre
    point = (0.315, 0.025)  # 0.29 m: farther than the robot, inside the inscribed radius
    far = (0.9, 0.9)  # a free point listed first
    x = np.array([far[0], point[0]])
    y = np.array([far[1], point[1]])
    cost = cm.costs_at(np.stack([x, y], axis=1))
    assert cost[1] == INSCRIBED_INFLATED_OBSTACLE
    assert cost[0] < INSCRIBED_INFLATED_OBSTACLE
    bad = _circle_collisions(x, y, cost, cm, lc.footprint, robot=robot)
    assert not bad.any()
    # the same point seen from a robot outside the band collides
    bad = _circle_collisions(x, y, cost, cm, lc.footprint, robot=far)
    assert bad.tolist() == [False, True]


@pytest.mark.parametrize("within", [0.1, 0.3, 1.0])
def test_nearest_lethal_uses_the_window(within: float) -> None:
    cm = Costmap2D(10, 10, 0.1, 0.0, 0.0)
    cm.set_cost(9, 9, LETHAL_OBSTACLE)  # centre (0.95, 0.95), at the map's corner
    d = nearest_lethal(cm, 0.75, 0.95, within)
    assert d == (pytest.approx(0.2) if within >= 0.2 else np.inf)
