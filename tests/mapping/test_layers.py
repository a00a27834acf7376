"""Static, obstacle and inflation layers inside a LayeredCostmap, against slow references."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from visnav.mapping import (
    FREE_SPACE,
    INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    Costmap2D,
    CostmapError,
    Footprint,
    InflationLayer,
    LayeredCostmap,
    ObservationError,
    ObservationSource,
    ObstacleLayer,
    StaticLayer,
    compute_cost,
)
from visnav.msgs import (
    Header,
    LaserScan,
    MapMetaData,
    OccupancyGrid,
    Quaternion,
    Transform,
    TransformStamped,
    Vector3,
    make,
    ns_to_time,
)
from visnav.tf import Buffer

S = 1_000_000_000


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


# ---------------------------------------------------------------------- inflation
def _reference_inflation(
    master: np.ndarray, res: float, insc: float, k: float, radius: float
) -> np.ndarray:
    """Slow reference: exact nearest-lethal distance per cell, costmap_2d's computeCost."""
    lethal = np.argwhere(master == LETHAL_OBSTACLE)
    out = master.copy()
    cell_r = math.ceil(radius / res - 1e-9)
    for (y, x), old in np.ndenumerate(master):
        if len(lethal) == 0:
            break
        d = float(np.min(np.hypot(lethal[:, 0] - y, lethal[:, 1] - x)))
        if d > cell_r:
            continue
        if d == 0:
            cost = LETHAL_OBSTACLE
        elif d * res <= insc:
            cost = INSCRIBED_INFLATED_OBSTACLE
        else:
            cost = int((INSCRIBED_INFLATED_OBSTACLE - 1) * math.exp(-k * (d * res - insc)))
        if old == NO_INFORMATION:
            out[y, x] = cost if cost >= INSCRIBED_INFLATED_OBSTACLE else NO_INFORMATION
        else:
            out[y, x] = max(old, cost)
    return out


def test_inflation_values_follow_the_formula() -> None:
    lc = LayeredCostmap(
        "map",
        width=3.0,
        height=3.0,
        resolution=0.05,
        footprint=Footprint.from_params(robot_radius=0.2, footprint_padding=0.0),
    )
    static = StaticLayer()
    lc.add_layer(static)
    lc.add_layer(InflationLayer(inflation_radius=0.55, cost_scaling_factor=10.0))
    grid = np.zeros((60, 60))
    grid[30, 30] = 100
    static.set_map(_grid_msg(grid, 0.05))
    lc.update_map(0.0, 0.0, 0.0)
    data = lc.costmap.data
    assert data[30, 30] == LETHAL_OBSTACLE
    for dx in range(15):
        d = dx * 0.05
        expected = compute_cost(dx, resolution=0.05, inscribed_radius=0.2, cost_scaling_factor=10.0)
        if dx > 11:  # ceil(0.55 / 0.05) = 11 cells
            expected = FREE_SPACE
        assert data[30, 30 + dx] == expected, dx
        if 0 < d <= 0.2:
            assert data[30, 30 + dx] == INSCRIBED_INFLATED_OBSTACLE
        elif 0.2 < d <= 0.55:
            assert data[30, 30 + dx] == int(252 * math.exp(-10.0 * (d - 0.2)))
    # diagonal distances use the Euclidean distance
    assert data[33, 34] == int(252 * math.exp(-10.0 * (5 * 0.05 - 0.2)))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), unknown=st.booleans())
def test_inflation_matches_a_slow_reference(seed: int, unknown: bool) -> None:
    rng = np.random.default_rng(seed)
    master = np.where(rng.random((24, 28)) < 0.03, LETHAL_OBSTACLE, 0).astype(np.uint8)
    if unknown:
        master[rng.random(master.shape) < 0.2] = NO_INFORMATION
    lc = LayeredCostmap(
        "map",
        width=28 * 0.1,
        height=24 * 0.1,
        resolution=0.1,
        footprint=Footprint.from_params(robot_radius=0.15, footprint_padding=0.0),
    )
    layer = InflationLayer(inflation_radius=0.45, cost_scaling_factor=5.0)
    lc.add_layer(layer)
    lc.costmap.data[:] = master
    layer.update_costs(lc.costmap, 0, 0, 28, 24)
    expected = _reference_inflation(master, 0.1, 0.15, 5.0, 0.45)
    np.testing.assert_array_equal(lc.costmap.data, expected)


def test_inflation_window_sees_obstacles_outside_it() -> None:
    lc = LayeredCostmap(
        "map",
        width=2.0,
        height=2.0,
        resolution=0.1,
        footprint=Footprint.from_params(robot_radius=0.1, footprint_padding=0.0),
    )
    layer = InflationLayer(inflation_radius=0.5)
    lc.add_layer(layer)
    lc.costmap.set_cost(5, 5, LETHAL_OBSTACLE)
    layer.update_costs(lc.costmap, 7, 0, 20, 20)  # window starts 2 cells right of the obstacle
    assert lc.costmap.get_cost(7, 5) == int(252 * math.exp(-10.0 * (0.2 - 0.1)))
    assert lc.costmap.get_cost(4, 5) == 0  # outside the window: untouched


# ---------------------------------------------------------------------- static layer
def test_static_layer_translation_and_resize() -> None:
    lc = LayeredCostmap("map", width=1.0, height=1.0, resolution=0.05, track_unknown_space=True)
    static = StaticLayer()
    lc.add_layer(static)
    values = np.array([[-1, 0, 50], [99, 100, 101]])
    static.set_map(_grid_msg(values, res=0.5, ox=-1.0, oy=2.0))
    cm = lc.costmap
    assert (cm.size_x, cm.size_y, cm.resolution, cm.origin_x, cm.origin_y) == (3, 2, 0.5, -1.0, 2.0)
    lc.update_map(0.0, 0.0, 0.0)
    assert cm.data.tolist() == [[NO_INFORMATION, 0, 0], [0, LETHAL_OBSTACLE, LETHAL_OBSTACLE]]


def test_static_layer_without_unknown_tracking_and_not_trinary() -> None:
    lc = LayeredCostmap("map", width=1.0, height=1.0, resolution=0.5, track_unknown_space=False)
    static = StaticLayer(trinary_costmap=False)
    lc.add_layer(static)
    static.set_map(_grid_msg(np.array([[-1, 0, 50, 100]]), res=0.5))
    lc.update_map(0.0, 0.0, 0.0)
    assert lc.costmap.data.tolist() == [[FREE_SPACE, 0, int(50 / 100 * 254), LETHAL_OBSTACLE]]


def test_static_layer_refuses_inconsistent_maps() -> None:
    lc = LayeredCostmap("map")
    static = StaticLayer()
    lc.add_layer(static)
    msg = _grid_msg(np.zeros((3, 3)))
    msg.info.width = 4
    with pytest.raises(CostmapError, match="9 cells but width x height is 4 x 3"):
        static.set_map(msg)


def test_static_layer_in_a_rolling_window_follows_the_map_transform() -> None:
    lc = LayeredCostmap("odom", width=1.0, height=1.0, resolution=0.1, rolling_window=True)
    static = StaticLayer()
    lc.add_layer(static)
    grid = np.zeros((40, 40))
    grid[20, 25] = 100  # map cell centre (2.55, 2.05)
    static.set_map(
        _grid_msg(grid, 0.1), transform=(-1.0, 0.0, 0.0)
    )  # odom = map shifted by -1 in x
    lc.update_map(1.55, 2.05, 0.0)
    cell = lc.costmap.world_to_map(1.55, 2.05)
    assert cell is not None
    assert lc.costmap.get_cost(*cell) == LETHAL_OBSTACLE
    assert (lc.costmap.data == LETHAL_OBSTACLE).sum() == 1


# ---------------------------------------------------------------------- obstacle layer
def _obstacle_costmap(**source_kw: object) -> tuple[LayeredCostmap, ObstacleLayer]:
    lc = LayeredCostmap(
        "map",
        width=4.0,
        height=4.0,
        resolution=0.1,
        origin_x=-2.0,
        origin_y=-2.0,
        footprint=Footprint.from_params(robot_radius=0.1, footprint_padding=0.0),
    )
    src = ObservationSource("scan", **source_kw)  # type: ignore[arg-type]
    layer = ObstacleLayer(sources=[src], footprint_clearing_enabled=False)
    lc.add_layer(layer)
    return lc, layer


def _bresenham(x0: int, y0: int, x1: int, y1: int) -> list[tuple[int, int]]:
    cells = []
    dx, dy = abs(x1 - x0), abs(y1 - y0)
    sx, sy = (1 if x1 > x0 else -1), (1 if y1 > y0 else -1)
    x, y = x0, y0
    if dx >= dy:
        err = dx // 2
        for _ in range(dx):
            cells.append((x, y))
            x += sx
            err += dy
            if err >= dx:
                y += sy
                err -= dx
    else:
        err = dy // 2
        for _ in range(dy):
            cells.append((x, y))
            y += sy
            err += dx
            if err >= dy:
                x += sx
                err -= dy
    cells.append((x, y))
    return cells


def test_marking_respects_obstacle_range_and_heights() -> None:
    lc, layer = _obstacle_costmap(
        obstacle_range=1.5, min_obstacle_height=0.1, max_obstacle_height=1.0
    )
    pts = np.array(
        [
            [1.0, 0.0, 0.5],  # marked
            [1.6, 0.0, 0.5],  # beyond obstacle_range
            [0.0, 1.0, 0.05],  # below min height
            [0.0, -1.0, 1.5],  # above max height
        ]
    )
    layer.add_points("scan", pts, np.eye(4), stamp_ns=0, now_ns=0)
    lc.update_map(0.0, 0.0, 0.0)
    cm = lc.costmap
    marked = {tuple(c) for c in np.argwhere(cm.data == LETHAL_OBSTACLE)}
    assert marked == {(20, 30)}


def test_raytrace_clears_bresenham_cells_up_to_raytrace_range() -> None:
    lc, layer = _obstacle_costmap(clearing=True, marking=False, raytrace_range=1.0)
    layer.grid.data[:] = LETHAL_OBSTACLE  # everything occupied
    origin = (0.05, 0.05, 0.0)
    target = (1.75, 0.95, 0.0)
    T = np.eye(4)
    T[:3, 3] = origin
    layer.add_points(
        "scan",
        np.array([[target[0] - origin[0], target[1] - origin[1], 0.0]]),
        T,
        stamp_ns=0,
        now_ns=0,
    )
    lc.update_map(0.0, 0.0, 0.0)
    cleared = {(int(x), int(y)) for y, x in np.argwhere(layer.grid.data == FREE_SPACE)}
    g = layer.grid
    x0, y0 = g.world_to_map(origin[0], origin[1])  # type: ignore[misc]
    x1, y1 = g.world_to_map(target[0], target[1])  # type: ignore[misc]
    line = _bresenham(x0, y0, x1, y1)
    dist = math.hypot(x1 - x0, y1 - y0)
    steps = int(min(1.0, 10 / dist) * max(abs(x1 - x0), abs(y1 - y0)))  # 1.0 m = 10 cells
    assert cleared == set(line[: steps + 1])
    assert len(cleared) < len(line)


def test_clearing_then_marking_keeps_the_hit_cell() -> None:
    lc, layer = _obstacle_costmap(clearing=True, marking=True)
    layer.grid.data[20, 25] = LETHAL_OBSTACLE  # a stale obstacle on the ray at (0.55, 0.05)
    layer.add_points("scan", np.array([[1.05, 0.05, 0.2]]), np.eye(4), stamp_ns=0, now_ns=0)
    lc.update_map(0.0, 0.0, 0.0)
    assert layer.grid.data[20, 25] == FREE_SPACE
    assert layer.grid.data[20, 30] == LETHAL_OBSTACLE


def test_observation_persistence_and_staleness() -> None:
    lc, layer = _obstacle_costmap(observation_persistence=1.0, expected_update_rate=0.5)
    buf = layer.buffers["scan"]
    assert not buf.is_current(0)[0]
    layer.add_points("scan", np.array([[0.5, 0.0, 0.1]]), np.eye(4), stamp_ns=0, now_ns=0)
    layer.add_points("scan", np.array([[0.0, 0.5, 0.1]]), np.eye(4), stamp_ns=S // 2, now_ns=S // 2)
    assert len(buf.get_observations()) == 2
    layer.add_points("scan", np.array([[-0.5, 0.0, 0.1]]), np.eye(4), stamp_ns=2 * S, now_ns=2 * S)
    assert len(buf.get_observations()) == 1
    assert layer.is_current(2 * S + S // 4)
    assert not lc.is_current(3 * S)
    assert "has not been updated for 1.00 s" in lc.reason


def test_observation_persistence_zero_keeps_only_the_newest() -> None:
    _lc, layer = _obstacle_costmap()
    for k in range(3):
        layer.add_points("scan", np.array([[0.1 * k, 0.0, 0.1]]), np.eye(4), stamp_ns=k, now_ns=k)
    obs = layer.buffers["scan"].get_observations()
    assert len(obs) == 1
    assert obs[0].points[0, 0] == pytest.approx(0.2)


def _scan(stamp_ns: int, ranges: list[float], frame: str = "laser") -> LaserScan:
    n = len(ranges)
    return make(
        LaserScan,
        header=Header(stamp=ns_to_time(stamp_ns), frame_id=frame),
        angle_min=-0.1,
        angle_max=0.1,
        angle_increment=0.2 / max(n - 1, 1),
        range_min=0.1,
        range_max=5.0,
        ranges=np.array(ranges, np.float32),
    )


def _tf(stamp_ns: int, parent: str, child: str, x: float, y: float, yaw: float) -> TransformStamped:
    return TransformStamped(
        header=Header(stamp=ns_to_time(stamp_ns), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=x, y=y, z=0.2),
            rotation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
        ),
    )


def test_laser_scans_go_through_tf_and_wait_for_it() -> None:
    tf = Buffer()
    lc = LayeredCostmap("map", width=4.0, height=4.0, resolution=0.1, origin_x=-2.0, origin_y=-2.0)
    layer = ObstacleLayer(sources=[ObservationSource("scan", data_type="LaserScan")], tf=tf)
    lc.add_layer(layer)
    tf.set_transform(_tf(0, "map", "laser", 0.5, 0.0, math.pi / 2), "test")
    assert not layer.add_scan("scan", _scan(S, [1.0, 1.0, 1.0]), S)  # transform not there yet
    tf.set_transform(_tf(2 * S, "map", "laser", 0.5, 0.0, math.pi / 2), "test")
    lc.update_map(0.0, 0.0, 0.0, now_ns=2 * S)
    cell = lc.costmap.world_to_map(0.5, 1.0)
    assert cell is not None
    assert lc.costmap.get_cost(*cell) == LETHAL_OBSTACLE
    # an unknown frame is dropped with the reason, not queued
    assert layer.add_scan("scan", _scan(2 * S, [1.0], frame="nowhere"), 2 * S)
    assert "nowhere" in layer.tf_error


def test_empty_scan_makes_the_layer_not_current() -> None:
    tf = Buffer()
    tf.set_transform_static(_tf(0, "map", "laser", 0.0, 0.0, 0.0), "test")
    lc = LayeredCostmap("map", width=4.0, height=4.0, resolution=0.1, origin_x=-2.0, origin_y=-2.0)
    layer = ObstacleLayer(sources=[ObservationSource("scan", data_type="LaserScan")], tf=tf)
    lc.add_layer(layer)
    layer.add_scan("scan", _scan(S, []), S)
    assert not lc.is_current(S)
    assert "was empty: the scan has no ranges" in lc.reason
    # all beams invalid (a wall closer than range_min) is not empty: nothing marked
    layer.add_scan("scan", _scan(S, [math.nan, math.inf, 0.05]), S)
    assert lc.is_current(S)
    lc.update_map(0.0, 0.0, 0.0, now_ns=S)
    assert (lc.costmap.data == LETHAL_OBSTACLE).sum() == 0
    layer.add_scan("scan", _scan(S, [1.0, 2.0, 3.0]), S)
    assert lc.is_current(S)


def test_inf_is_valid_clears_without_marking() -> None:
    tf = Buffer()
    tf.set_transform_static(_tf(0, "map", "laser", 0.0, 0.0, 0.0), "test")
    lc = LayeredCostmap("map", width=8.0, height=4.0, resolution=0.1, origin_x=-2.0, origin_y=-2.0)
    src = ObservationSource("scan", data_type="LaserScan", inf_is_valid=True, clearing=True)
    layer = ObstacleLayer(sources=[src], tf=tf, footprint_clearing_enabled=False)
    lc.add_layer(layer)
    layer.grid.data[20, 40] = LETHAL_OBSTACLE  # at x = 2.05 on the beam
    layer.add_scan("scan", _scan(S, [math.inf] * 3), S)  # the middle beam is along +x
    lc.update_map(0.0, 0.0, 0.0, now_ns=S)
    assert layer.grid.data[20, 40] == FREE_SPACE  # cleared up to raytrace_range 3.0
    assert (layer.grid.data == LETHAL_OBSTACLE).sum() == 0


def test_rolling_window_keeps_obstacles_in_place() -> None:
    lc = LayeredCostmap("odom", width=2.0, height=2.0, resolution=0.1, rolling_window=True)
    layer = ObstacleLayer(sources=[ObservationSource("scan")], footprint_clearing_enabled=False)
    lc.add_layer(layer)
    lc.add_layer(InflationLayer(inflation_radius=0.0))
    layer.add_points("scan", np.array([[0.55, 0.35, 0.2]]), np.eye(4), stamp_ns=0, now_ns=0)
    lc.update_map(0.0, 0.0, 0.0)
    assert lc.costmap.origin_x == pytest.approx(-1.0)
    assert lc.costmap.get_cost(*lc.costmap.world_to_map(0.55, 0.35)) == LETHAL_OBSTACLE  # type: ignore[misc]
    layer.buffers["scan"].clear()
    lc.update_map(0.42, -0.31, 0.0)
    cm = lc.costmap
    assert cm.origin_x == pytest.approx(-0.6)
    assert cm.origin_y == pytest.approx(-1.4)
    assert cm.get_cost(*cm.world_to_map(0.55, 0.35)) == LETHAL_OBSTACLE  # type: ignore[misc]
    lc.update_map(3.0, 0.0, 0.0)  # the obstacle left the window
    assert (lc.costmap.data == LETHAL_OBSTACLE).sum() == 0


def test_footprint_clearing_and_clear_outside() -> None:
    lc = LayeredCostmap("map", width=4.0, height=4.0, resolution=0.1, origin_x=-2.0, origin_y=-2.0)
    layer = ObstacleLayer(sources=[ObservationSource("scan")])
    lc.add_layer(layer)
    layer.add_points(
        "scan", np.array([[0.0, 0.0, 0.2], [1.5, 1.5, 0.2]]), np.eye(4), stamp_ns=0, now_ns=0
    )
    lc.update_map(0.0, 0.0, 0.0)  # the point under the robot is cleared by its footprint
    assert lc.costmap.get_cost(20, 20) == FREE_SPACE
    assert lc.costmap.get_cost(35, 35) == LETHAL_OBSTACLE
    layer.buffers["scan"].clear()
    layer.clear_outside(0.0, 0.0, 2.0)
    lc.request_full_update()
    lc.update_map(0.0, 0.0, 0.0)
    assert (lc.costmap.data == LETHAL_OBSTACLE).sum() == 0


def test_bad_sources_are_refused() -> None:
    with pytest.raises(ObservationError, match="data_type is 'PointCloud'"):
        ObservationSource("x", data_type="PointCloud")
    with pytest.raises(ObservationError, match="repeat"):
        ObstacleLayer(sources=[ObservationSource("a"), ObservationSource("a")])


def test_layered_update_resets_only_the_bounds() -> None:
    lc = LayeredCostmap("map", width=2.0, height=2.0, resolution=0.1, track_unknown_space=True)
    cm = lc.costmap
    assert (cm.data == NO_INFORMATION).all()
    layer = ObstacleLayer(
        sources=[ObservationSource("scan", clearing=True)], footprint_clearing_enabled=False
    )
    lc.add_layer(layer)
    layer.add_points("scan", np.array([[1.0, 0.0, 0.1]]), _shift(0.05, 1.05), stamp_ns=0, now_ns=0)
    lc.update_map(0.05, 1.05, 0.0)
    x0, y0, xn, yn = lc.last_window
    assert (x0, y0) == (0, 10)
    outside = np.ones(cm.data.shape, bool)
    outside[y0:yn, x0:xn] = False
    assert (cm.data[outside] == NO_INFORMATION).all()
    assert cm.get_cost(10, 10) == LETHAL_OBSTACLE
    assert cm.get_cost(5, 10) == FREE_SPACE


def _shift(x: float, y: float) -> np.ndarray:
    t = np.eye(4)
    t[0, 3], t[1, 3] = x, y
    return t


def test_inflation_table_distance_cost_helper() -> None:
    lc = LayeredCostmap(
        "map", footprint=Footprint.from_params(robot_radius=0.2, footprint_padding=0.0)
    )
    inf = InflationLayer()
    lc.add_layer(inf)
    assert inf.cell_inflation_radius == 11
    assert inf.cost_for_distance(0) == LETHAL_OBSTACLE
    assert inf.cost_for_distance(4) == INSCRIBED_INFLATED_OBSTACLE
    assert inf.cost_for_distance(12) == 0
    assert Costmap2D(1, 1, 0.05).cell_distance(0.55) == 11


def test_distance_transform_agrees_with_scipy() -> None:
    rng = np.random.default_rng(3)
    master = np.where(rng.random((50, 60)) < 0.02, LETHAL_OBSTACLE, 0).astype(np.uint8)
    ref = ndimage.distance_transform_edt(master != LETHAL_OBSTACLE)
    lc = LayeredCostmap(
        "map",
        width=6.0,
        height=5.0,
        resolution=0.1,
        footprint=Footprint.from_params(robot_radius=0.1, footprint_padding=0.0),
    )
    layer = InflationLayer(inflation_radius=2.0, cost_scaling_factor=1.0)
    lc.add_layer(layer)
    lc.costmap.data[:] = master
    layer.update_costs(lc.costmap, 0, 0, 60, 50)
    expected = compute_cost(ref, resolution=0.1, inscribed_radius=0.1, cost_scaling_factor=1.0)
    expected[ref > 20] = 0
    np.testing.assert_array_equal(lc.costmap.data, expected)
