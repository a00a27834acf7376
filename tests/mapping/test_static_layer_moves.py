"""A static layer whose map moves in a non-rolling costmap leaves no stale costs behind."""

from __future__ import annotations

import numpy as np
import pytest

from visnav.mapping import (
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    Bounds,
    Footprint,
    InflationLayer,
    LayeredCostmap,
    ObstacleLayer,
    StaticLayer,
)
from visnav.msgs import MapMetaData, OccupancyGrid, make


def _grid_msg(
    values: np.ndarray, res: float = 0.1, ox: float = 0.0, oy: float = 0.0
) -> OccupancyGrid:
    h, w = values.shape
    msg = make(OccupancyGrid, info=make(MapMetaData, resolution=res, width=w, height=h))
    msg.info.origin.position.x = ox
    msg.info.origin.position.y = oy
    msg.info.origin.orientation.w = 1.0
    msg.header.frame_id = "map"
    msg.data = values.astype(np.int8).reshape(-1)
    return msg


def _room() -> np.ndarray:
    """A 1 x 1 m map (0.1 m cells): a lethal wall on its left column, free, one unknown."""
    values = np.zeros((10, 10))
    values[:, 0] = 100
    values[9, 9] = -1
    return values


def _costmap(
    track_unknown: bool, inflation: bool
) -> tuple[LayeredCostmap, StaticLayer, ObstacleLayer]:
    """A fixed 4 x 3 m odom costmap; the inflation layer (when asked) also repaints the
    previous update's window, as costmap_2d's does, which hid the stale cells."""
    static = StaticLayer()
    obstacles = ObstacleLayer(footprint_clearing_enabled=False)
    lc = LayeredCostmap(
        "odom",
        width=4.0,
        height=3.0,
        resolution=0.1,
        origin_x=-1.0,
        origin_y=-1.0,
        track_unknown_space=track_unknown,
        footprint=Footprint.from_params(robot_radius=0.1),
        layers=[static, obstacles, *([InflationLayer(inflation_radius=0.25)] if inflation else [])],
    )
    obstacles.grid.set_cost(5, 25, LETHAL_OBSTACLE)  # (-0.45, 1.55): outside both placements
    obstacles.grid.set_cost(12, 12, LETHAL_OBSTACLE)  # (0.25, 0.25): inside the first one
    lc.request_full_update()
    return lc, static, obstacles


@pytest.mark.parametrize("inflation", [False, True])
@pytest.mark.parametrize("track_unknown", [True, False])
@pytest.mark.parametrize("pose", [(1.5, 0.5, 0.0), (0.4, 0.0, 0.0), (1.0, 1.0, 0.7)])
def test_a_moved_map_clears_its_old_extent(
    track_unknown: bool, pose: tuple[float, float, float], inflation: bool
) -> None:
    """Placed at (0.2, 0) in odom, then moved: the costmap equals one that only ever had
    the map at its new pose (before: without an inflation layer the old wall stayed)."""
    lc, static, _ = _costmap(track_unknown, inflation)
    static.set_map(_grid_msg(_room()), transform=(0.2, 0.0, 0.0))
    lc.update_map(0.0, 0.0, 0.0)
    wall = lc.costmap.world_to_map(0.25, 0.55)
    assert wall is not None
    assert lc.costmap.get_cost(*wall) == LETHAL_OBSTACLE
    static.set_map_transform(*pose)
    lc.update_map(0.0, 0.0, 0.0)

    fresh, fresh_static, _ = _costmap(track_unknown, inflation)
    fresh_static.set_map(_grid_msg(_room()), transform=pose)
    fresh.update_map(0.0, 0.0, 0.0)
    np.testing.assert_array_equal(lc.costmap.data, fresh.costmap.data)
    assert lc.costmap.get_cost(*wall) != LETHAL_OBSTACLE  # the old wall is gone
    # the obstacle layer's own marks stay wherever they are
    assert lc.costmap.get_cost(12, 12) == LETHAL_OBSTACLE
    assert lc.costmap.get_cost(5, 25) == LETHAL_OBSTACLE


def test_a_smaller_map_in_a_locked_costmap_clears_the_rest() -> None:
    lc = LayeredCostmap("map", width=2.0, height=2.0, resolution=0.1, track_unknown_space=True)
    static = StaticLayer()
    lc.add_layer(static)
    lc.size_locked = True
    static.set_map(_grid_msg(np.full((20, 20), 100)))
    lc.update_map(0.0, 0.0, 0.0)
    assert (lc.costmap.data == LETHAL_OBSTACLE).all()
    static.set_map(_grid_msg(np.zeros((10, 10))))  # the lower-left quarter, free
    lc.update_map(0.0, 0.0, 0.0)
    assert (lc.costmap.data[:10, :10] == 0).all()
    rest = lc.costmap.data.copy()
    rest[:10, :10] = NO_INFORMATION
    assert (rest == NO_INFORMATION).all()  # before: the rest stayed lethal


def test_an_unmoved_growing_map_touches_only_its_own_extent() -> None:
    """The global costmap's case (identity transform, a map that grows): the bounds are
    the new map's extent, as before, so nothing else is recomputed."""
    lc = LayeredCostmap("map", width=1.0, height=1.0, resolution=0.1)
    static = StaticLayer()
    lc.add_layer(static)
    for k, (ox, size) in enumerate(((0.0, 10), (-0.5, 20), (-0.5, 20), (-1.0, 30))):
        static.set_map(_grid_msg(np.zeros((size, size)), ox=ox, oy=ox))
        bounds = Bounds()
        static.update_bounds(0.0, 0.0, 0.0, bounds)
        extent = ox + size * 0.1
        assert (bounds.min_x, bounds.min_y) == (ox, ox), k
        assert (bounds.max_x, bounds.max_y) == pytest.approx((extent, extent)), k
