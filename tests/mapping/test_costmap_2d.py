"""Costmap2D geometry, rolling, resizing, polygons, footprints and the OccupancyGrid translation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.mapping import (
    INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    Costmap2D,
    CostmapError,
    Footprint,
    cost_translation_table,
    costmap_to_occupancy_grid,
    min_max_distances,
    parse_footprint,
)


def test_translation_table_matches_costmap_2d_publisher() -> None:
    t = cost_translation_table()
    assert t[0] == 0
    assert t[1] == 1
    assert t[252] == 98
    assert t[INSCRIBED_INFLATED_OBSTACLE] == 99
    assert t[LETHAL_OBSTACLE] == 100
    assert t[NO_INFORMATION] == -1
    # 1 + 97 * (c - 1) // 251, integer division, monotone
    for c in (2, 100, 200, 251):
        assert t[c] == 1 + (97 * (c - 1)) // 251
    assert np.all(np.diff(t[1:253].astype(int)) >= 0)


@settings(max_examples=60, deadline=None)
@given(
    ox=st.floats(-50, 50),
    oy=st.floats(-50, 50),
    res=st.sampled_from([0.025, 0.05, 0.1, 0.5]),
    fx=st.floats(0, 0.999),
    fy=st.floats(0, 0.999),
)
def test_world_map_round_trip(ox: float, oy: float, res: float, fx: float, fy: float) -> None:
    cm = Costmap2D(40, 30, res, ox, oy)
    wx = ox + fx * cm.size_in_meters_x
    wy = oy + fy * cm.size_in_meters_y
    cell = cm.world_to_map(wx, wy)
    assert cell is not None
    cx, cy = cm.map_to_world(*cell)
    assert abs(cx - wx) <= res / 2 + 1e-9
    assert abs(cy - wy) <= res / 2 + 1e-9
    mx, my, inside = cm.world_to_map_array([[wx, wy]])
    assert inside[0]
    assert (int(mx[0]), int(my[0])) == cell


def test_world_to_map_refuses_outside_points() -> None:
    cm = Costmap2D(10, 10, 0.1, -0.5, -0.5)
    assert cm.world_to_map(-0.51, 0.0) is None
    assert cm.world_to_map(0.0, 0.5) is None  # the far edge belongs to no cell
    assert cm.world_to_map(0.49, 0.49) == (9, 9)
    assert cm.world_to_map_enforce_bounds(100.0, -100.0) == (9, 0)


def test_bad_geometry_is_refused_with_the_value() -> None:
    with pytest.raises(CostmapError, match="resolution is 0"):
        Costmap2D(10, 10, 0.0)
    with pytest.raises(CostmapError, match="-1 x 10"):
        Costmap2D(-1, 10, 0.1)


def test_update_origin_keeps_the_overlap_in_world_coordinates() -> None:
    cm = Costmap2D(20, 20, 0.1, 0.0, 0.0, default_value=NO_INFORMATION)
    cm.data[:] = 0
    cm.set_cost(15, 12, LETHAL_OBSTACLE)
    wx, wy = cm.map_to_world(15, 12)
    cm.update_origin(0.73, -0.41)  # shifts by whole cells: floor -> (7, -5)
    assert cm.origin_x == pytest.approx(0.7)
    assert cm.origin_y == pytest.approx(-0.5)
    cell = cm.world_to_map(wx, wy)
    assert cell == (8, 17)
    assert cm.get_cost(*cell) == LETHAL_OBSTACLE
    # cells that came into view are the default value
    assert (cm.data[:, -7:] == NO_INFORMATION).all()
    assert (cm.data[:5, :] == NO_INFORMATION).all()
    assert (cm.data == LETHAL_OBSTACLE).sum() == 1


def test_resize_keep_copies_aligned_content() -> None:
    cm = Costmap2D(10, 10, 0.1, 0.0, 0.0)
    cm.set_cost(3, 4, LETHAL_OBSTACLE)
    cm.resize_map(20, 20, 0.1, -0.5, -0.3, keep=True)
    assert cm.get_cost(8, 7) == LETHAL_OBSTACLE
    cm.resize_map(20, 20, 0.2, 0.0, 0.0, keep=True)  # other resolution: cleared
    assert (cm.data == 0).all()


def test_polygon_cells_cover_a_square() -> None:
    cm = Costmap2D(20, 20, 0.1, 0.0, 0.0)
    cm.set_convex_polygon_cost([[0.5, 0.5], [1.0, 0.5], [1.0, 1.0], [0.5, 1.0]], 7)
    rows, cols = np.nonzero(cm.data == 7)
    assert rows.min() == 5
    assert rows.max() == 10
    assert cols.min() == 5
    assert cols.max() == 10


def test_occupancy_grid_message() -> None:
    cm = Costmap2D(4, 3, 0.5, -1.0, 2.0)
    cm.data[:] = [[0, 1, 252, 253], [254, 255, 0, 0], [100, 0, 0, 0]]
    msg = costmap_to_occupancy_grid(cm, "odom", 1_500_000_000)
    assert msg.header.frame_id == "odom"
    assert msg.header.stamp.sec == 1
    assert msg.info.width == 4
    assert msg.info.height == 3
    assert msg.info.origin.position.x == -1.0
    assert msg.data.tolist() == [0, 1, 98, 99, 100, -1, 0, 0, 39, 0, 0, 0]


def test_footprint_parsing_and_radii() -> None:
    pts = parse_footprint("[[0.3, 0.2], [0.3, -0.2], [-0.3, -0.2], [-0.3, 0.2]]")
    assert pts.shape == (4, 2)
    insc, circ = min_max_distances(pts)
    assert insc == pytest.approx(0.2)
    assert circ == pytest.approx(math.hypot(0.3, 0.2))
    fp = Footprint.from_params(footprint=pts.tolist(), footprint_padding=0.01)
    assert not fp.is_circular
    assert fp.inscribed_radius == pytest.approx(0.21)
    circle = Footprint.from_params(robot_radius=0.3)
    assert circle.is_circular
    assert circle.inscribed_radius == pytest.approx(0.31)  # robot_radius + footprint_padding
    assert len(circle.points) == 16
    with pytest.raises(CostmapError, match="at least 3"):
        parse_footprint("[[0, 1], [1, 0]]")
    with pytest.raises(CostmapError, match="not a list"):
        parse_footprint("[[0, 1], [1, 0")
