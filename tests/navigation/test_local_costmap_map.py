"""The map in a rolling local costmap: placed through TF at every update (costmap_2d's rolling
static layer), kept while its transform is missing, and keeping a wall corner that the
depth camera's edge rays cleared from the obstacle layer (the car's seed-5 collision)."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.mapping.costmap_2d import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE
from visnav.mapping.costmap_ros import MAP_QOS, CostmapROS
from visnav.mapping.footprint import Footprint
from visnav.mapping.inflation_layer import InflationLayer
from visnav.mapping.layered_costmap import LayeredCostmap
from visnav.mapping.observation import ObservationSource
from visnav.mapping.obstacle_layer import ObstacleLayer
from visnav.mapping.static_layer import StaticLayer
from visnav.msgs import (
    Header,
    MapMetaData,
    OccupancyGrid,
    Quaternion,
    Transform,
    TransformStamped,
    Vector3,
    make,
    ns_to_time,
)
from visnav.planning.local_planner import footprint_in_collision
from visnav.tf.buffer import Buffer

RES = 0.05


def _tf(parent: str, child: str, x: float, y: float, yaw: float = 0.0) -> TransformStamped:
    return TransformStamped(
        header=Header(stamp=ns_to_time(0), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=x, y=y, z=0.0),
            rotation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
        ),
    )


def _map_with_wall() -> OccupancyGrid:
    """A 4 x 4 m map from (-2, -2): one occupied cell at map (1.025, 0.025)."""
    n = 80
    data = np.zeros((n, n), np.int8)
    data[40, 60] = 100
    msg = make(OccupancyGrid, info=make(MapMetaData, resolution=RES, width=n, height=n))
    msg.info.origin.position.x = -2.0
    msg.info.origin.position.y = -2.0
    msg.info.origin.orientation.w = 1.0
    msg.header.frame_id = "map"
    msg.data = data.reshape(-1)
    return msg


@pytest.fixture
def setup() -> Iterator[tuple[Context, Node, Buffer, CostmapROS]]:
    with Context(transport="local") as ctx:
        node = Node("move_base", context=ctx)
        tf = Buffer()
        costmap = CostmapROS(
            node,
            "local_costmap",
            tf,
            defaults={
                "global_frame": "odom",
                "robot_base_frame": "base_footprint",
                "rolling_window": True,
                "width": 3.0,
                "height": 3.0,
                "plugins": ["static_layer", "inflation_layer"],
            },
            start_timers=False,
        )
        yield ctx, node, tf, costmap


def _lethal_odom_x(costmap: CostmapROS) -> float:
    cm = costmap.layered.costmap
    _, ii = np.nonzero(cm.data == LETHAL_OBSTACLE)
    assert len(ii) == 1, f"expected the one wall cell, found {len(ii)}"
    return float(cm.origin_x + (ii[0] + 0.5) * cm.resolution)


def test_map_follows_map_to_odom_at_every_update(
    setup: tuple[Context, Node, Buffer, CostmapROS],
) -> None:
    ctx, node, tf, costmap = setup
    tf.set_transform(_tf("odom", "base_footprint", 0.0, 0.0), "test")
    tf.set_transform(_tf("map", "odom", 0.0, 0.0), "test")
    pub = node.create_publisher(OccupancyGrid, "map", MAP_QOS)
    pub.publish(_map_with_wall())
    ctx.spin_some()
    costmap.update()
    assert costmap.is_current()
    assert _lethal_odom_x(costmap) == pytest.approx(1.025, abs=1e-6)
    # the localizer corrects map -> odom by 0.2 m (no new map message): the wall moves
    # in odom with it, as costmap_2d's rolling static layer looks TF up every update
    tf.set_transform(_tf("map", "odom", 0.2, 0.0), "test")
    costmap.update()
    assert _lethal_odom_x(costmap) == pytest.approx(1.025 - 0.2, abs=1e-6)


def test_a_map_received_before_its_transform_waits_for_it(
    setup: tuple[Context, Node, Buffer, CostmapROS],
) -> None:
    ctx, node, tf, costmap = setup
    tf.set_transform(_tf("odom", "base_footprint", 0.0, 0.0), "test")
    pub = node.create_publisher(OccupancyGrid, "map", MAP_QOS)
    pub.publish(_map_with_wall())  # latched once (map_server), before AMCL's map -> odom
    ctx.spin_some()
    costmap.update()
    assert not costmap.is_current()
    assert "no map" in costmap.layered.reason
    tf.set_transform(_tf("map", "odom", 0.5, 0.0), "test")
    costmap.update()
    assert costmap.is_current()
    assert _lethal_odom_x(costmap) == pytest.approx(1.025 - 0.5, abs=1e-6)


def _corner_costmap(*, with_map: bool) -> tuple[LayeredCostmap, ObstacleLayer]:
    """A rolling local costmap (odom = map) around (0, 0) with the car's 0.33 m radius."""
    source = ObservationSource("scan", clearing=True, marking=True, raytrace_range=8.0)
    obstacles = ObstacleLayer(sources=[source])
    static = StaticLayer() if with_map else None
    layers: list[StaticLayer | ObstacleLayer | InflationLayer] = [obstacles, InflationLayer()]
    if static is not None:
        layers.insert(0, static)
    lc = LayeredCostmap(
        "odom",
        width=5.0,
        height=5.0,
        rolling_window=True,
        footprint=Footprint.from_params(robot_radius=0.33),
        layers=layers,
    )
    if static is not None:
        static.set_map(_corner_map())
    return lc, obstacles


def _corner_map() -> OccupancyGrid:
    """A wall corner: the cell of (0.25, 0.0) and the wall behind it, map = odom."""
    n = 100
    data = np.zeros((n, n), np.int8)
    data[0:50, 55] = 100  # map cells x [0.25, 0.30) from y -2.5 up to the corner at y 0
    msg = make(OccupancyGrid, info=make(MapMetaData, resolution=RES, width=n, height=n))
    msg.info.origin.position.x = -2.5
    msg.info.origin.position.y = -2.5
    msg.info.origin.orientation.w = 1.0
    msg.header.frame_id = "odom"
    msg.data = data.reshape(-1)
    return msg


@pytest.mark.parametrize("with_map", [False, True])
def test_a_grazing_ray_clears_a_corner_only_the_map_keeps(with_map: bool) -> None:
    lc, obstacles = _corner_costmap(with_map=with_map)
    corner = (0.275, -0.025)  # centre of the corner cell
    eye = np.eye(4)
    # 1. the camera sees the corner: a beam ends in its cell
    origin = np.eye(4)
    origin[:3, 3] = (-1.0, 0.6, 0.3)
    end = np.array([[corner[0], corner[1], 0.3]])
    obstacles.add_points("scan", end, eye, stamp_ns=1, now_ns=1, T_global_origin=origin)
    lc.update_map(-1.0, 0.6, 0.0, now_ns=1)
    cell = lc.costmap.world_to_map(*corner)
    assert cell is not None
    assert lc.costmap.get_cost(*cell) == LETHAL_OBSTACLE
    # 2. the edge beam of the next frame grazes the corner and ends at a far wall: ray
    # tracing clears the corner cell (costmap_2d's rule), and no beam ends in it
    far = np.array([corner[0] + 6 * (corner[0] + 1.0), corner[1] + 6 * (corner[1] - 0.6), 0.3])
    obstacles.add_points("scan", far[None], eye, stamp_ns=2, now_ns=2, T_global_origin=origin)
    lc.update_map(-1.0, 0.6, 0.0, now_ns=2)
    kept = lc.costmap.get_cost(*cell) == LETHAL_OBSTACLE
    assert kept is with_map
    # the car's centre 0.22 m from the corner: a collision only the map still shows
    assert footprint_in_collision((0.45, 0.12, -1.4), lc.costmap, lc.footprint) is with_map
    if not with_map:
        assert lc.costmap.get_cost(*lc.costmap.world_to_map(0.45, 0.12)) < (  # type: ignore[misc]
            INSCRIBED_INFLATED_OBSTACLE
        )
