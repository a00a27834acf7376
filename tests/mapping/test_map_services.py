"""map_server's ``static_map`` / ``map_server/map`` and amcl's ``global_localization``,
``request_nomotion_update`` (and its ``initialpose`` topic), called from clients."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.graph import Context, Node
from visnav.graph.qos import qos_profile_latched
from visnav.mapping.amcl_node import AmclNode
from visnav.mapping.map_io import MapMetadata, OccupancyMap, save_map
from visnav.mapping.map_server_node import MapServerNode
from visnav.msgs.srv import get_service_type
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import (
    Header,
    LaserScan,
    OccupancyGrid,
    Point,
    Pose,
    PoseWithCovariance,
    PoseWithCovarianceStamped,
    Quaternion,
    Transform,
    TransformStamped,
    Vector3,
)
from visnav.tf.ros import StaticTransformBroadcaster, TransformBroadcaster

GetMap = get_service_type("nav_msgs/srv/GetMap")
Empty = get_service_type("std_srvs/srv/Empty")
GRID = np.array([[0, 0, 100], [-1, 100, 0]], dtype=np.int8)
ANGLES = np.linspace(-0.76, 0.76, 160)


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def call(ctx: Context, client: Any, request: Any) -> Any:
    future = client.call_async(request)
    assert ctx.spin_until(future.done, 5.0)
    return future.result()


# ---------------------------------------------------------------------- map_server


@pytest.mark.parametrize("namespace", ["/", "/robot1"])
def test_map_server_serves_the_map_under_both_names(
    ctx: Context, tmp_path: Path, namespace: str
) -> None:
    meta = MapMetadata(image=Path("x"), resolution=0.1, origin=(1.0, -2.0, 0.0))
    yaml_path, _ = save_map(OccupancyMap(GRID, meta).to_msg(), tmp_path / "saved")
    server = MapServerNode(
        context=ctx, namespace=namespace, parameter_overrides={"yaml_filename": str(yaml_path)}
    )
    prefix = namespace.rstrip("/")
    names = {s.srv_name for s in server.services}
    assert {f"{prefix}/static_map", f"{prefix}/map_server/map"} <= names
    node = Node("client", context=ctx)
    for name in (f"{prefix}/static_map", f"{prefix}/map_server/map"):
        reply = call(ctx, node.create_client(GetMap, name), GetMap.Request())
        grid = reply.map
        assert (grid.info.width, grid.info.height, grid.info.resolution) == (3, 2, 0.1)
        assert grid.info.origin.position.x == 1.0
        assert grid.header.frame_id == "map"
        np.testing.assert_array_equal(np.asarray(grid.data).reshape(2, 3), GRID)


# ---------------------------------------------------------------------- amcl


def _tf(parent: str, child: str, x: float, y: float, yaw: float, ns: int) -> TransformStamped:
    return TransformStamped(
        header=Header(stamp=ns_to_time(ns), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=x, y=y, z=0.0),
            rotation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
        ),
    )


class Feeder:
    """A map, TF and scans for an amcl node in the same context (odom = ground truth)."""

    def __init__(self, ctx: Context, world: SimpleNamespace) -> None:
        self.ctx, self.world = ctx, world
        self.grid = world.office_grid()
        self.node = Node("feeder", context=ctx)
        self.map_pub = self.node.create_publisher(OccupancyGrid, "/map", qos_profile_latched)
        self.scan_pub = self.node.create_publisher(LaserScan, "/scan", 5)
        self.pose_pub = self.node.create_publisher(PoseWithCovarianceStamped, "/initialpose", 1)
        self.tf = TransformBroadcaster(self.node)
        StaticTransformBroadcaster(self.node).send_transform(
            _tf("base_footprint", "laser", 0.0, 0.0, 0.0, 0)
        )
        self.k = 0

    def send_map(self) -> None:
        meta = MapMetadata(image=Path("x"), resolution=self.world.RES, origin=self.world.ORIGIN)
        self.map_pub.publish(OccupancyMap(self.grid, meta).to_msg())
        self.ctx.spin_some()

    def scan(self, pose: tuple[float, float, float]) -> None:
        self.k += 1
        ns = self.k * 100_000_000
        self.tf.send_transform(_tf("odom", "base_footprint", *pose, ns))
        self.ctx.spin_some()
        ranges = self.world.raycast(self.grid, pose, ANGLES).astype(np.float32)
        self.scan_pub.publish(
            LaserScan(
                header=Header(stamp=ns_to_time(ns), frame_id="laser"),
                angle_min=-0.76, angle_max=0.76, angle_increment=float(ANGLES[1] - ANGLES[0]),
                time_increment=0.0, scan_time=0.1, range_min=0.1, range_max=10.0,
                ranges=ranges, intensities=np.zeros(0, dtype=np.float32),
            )
        )  # fmt: skip
        self.ctx.spin_some()


def _amcl(ctx: Context, **overrides: Any) -> AmclNode:
    return AmclNode(
        context=ctx,
        parameter_overrides={"update_min_d": 0.1, "update_min_a": 0.1, "seed": 3, **overrides},
    )


def test_global_localization_spreads_particles_over_the_free_space(
    ctx: Context, amcl_world: SimpleNamespace, caplog: pytest.LogCaptureFixture
) -> None:
    node = _amcl(ctx)
    client = Node("client", context=ctx).create_client(Empty, "/global_localization")
    call(ctx, client, Empty.Request())  # before any map: a warning, nothing else
    assert node.filter is None
    assert any("no map" in r.getMessage() for r in caplog.records)
    feeder = Feeder(ctx, amcl_world)
    feeder.send_map()
    assert node.filter is not None
    assert not node.filter.initialized
    call(ctx, client, Empty.Request())
    f = node.filter
    poses = f.poses
    assert poses.shape == (node.filter_params.max_particles, 3)
    assert bool(np.all(f.field.is_free(poses[:, :2])))
    # spread over the whole floor (12 m x 9 m), every heading
    assert np.ptp(poses[:, 0]) > 8.0
    assert np.ptp(poses[:, 1]) > 6.0
    assert np.ptp(poses[:, 2]) > 5.0
    assert f.status.state == "initial"
    # nav2's name does the same
    nav2 = Node("nav2_client", context=ctx).create_client(
        Empty, "/reinitialize_global_localization"
    )
    before = f.poses.copy()
    call(ctx, nav2, Empty.Request())
    assert not np.array_equal(before, f.poses)


def test_request_nomotion_update_runs_the_next_scan_without_motion(
    ctx: Context, amcl_world: SimpleNamespace
) -> None:
    start = tuple(amcl_world.square_drive(1)[0])
    node = _amcl(
        ctx,
        set_initial_pose=True,
        **{"initial_pose.x": start[0], "initial_pose.y": start[1], "initial_pose.yaw": start[2]},
    )
    client = Node("client", context=ctx).create_client(Empty, "/request_nomotion_update")
    feeder = Feeder(ctx, amcl_world)
    call(ctx, client, Empty.Request())  # no filter yet: a warning, nothing else
    feeder.send_map()
    feeder.scan(start)  # the first scan always updates
    assert node.updates == 1
    feeder.scan(start)
    feeder.scan(start)
    assert node.updates == 1  # not moved: no update
    call(ctx, client, Empty.Request())
    assert node.updates == 1  # the update runs on the next scan, not in the call
    feeder.scan(start)
    assert node.updates == 2
    feeder.scan(start)
    assert node.updates == 2  # once per request


def test_initialpose_topic_puts_the_particles_there(
    ctx: Context, amcl_world: SimpleNamespace
) -> None:
    node = _amcl(ctx)
    feeder = Feeder(ctx, amcl_world)
    feeder.send_map()
    cov = np.zeros(36)
    cov[0] = cov[7] = 0.01
    cov[35] = 0.005
    yaw = 0.7
    feeder.pose_pub.publish(
        PoseWithCovarianceStamped(
            header=Header(stamp=ns_to_time(0), frame_id="map"),
            pose=PoseWithCovariance(
                pose=Pose(
                    position=Point(x=2.0, y=3.0, z=0.0),
                    orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
                ),
                covariance=cov,
            ),
        )
    )
    ctx.spin_some()
    f = node.filter
    assert f is not None
    assert f.initialized
    assert f.poses[:, 0].mean() == pytest.approx(2.0, abs=0.02)
    assert f.poses[:, 1].mean() == pytest.approx(3.0, abs=0.02)
    assert f.poses[:, 0].std() == pytest.approx(0.1, rel=0.15)  # the given variance
    assert np.median(f.poses[:, 2]) == pytest.approx(yaw, abs=0.02)


@settings(
    max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    calls=st.lists(
        st.sampled_from(
            ["/global_localization", "/request_nomotion_update", "/static_map", "map", "scan"]
        ),
        max_size=8,
    )
)
def test_fuzz_service_calls_in_any_order_never_break_the_nodes(
    amcl_world: SimpleNamespace, tmp_path_factory: pytest.TempPathFactory, calls: list[str]
) -> None:
    meta = MapMetadata(image=Path("x"), resolution=0.1, origin=(0.0, 0.0, 0.0))
    yaml_path, _ = save_map(OccupancyMap(GRID, meta).to_msg(), tmp_path_factory.mktemp("m") / "m")
    with Context(transport="local") as ctx:
        MapServerNode(context=ctx, parameter_overrides={"yaml_filename": str(yaml_path)})
        node = _amcl(ctx, map_topic="/amcl_map")
        feeder = Feeder(ctx, amcl_world)
        feeder.map_pub = feeder.node.create_publisher(
            OccupancyGrid, "/amcl_map", qos_profile_latched
        )
        client = Node("client", context=ctx)
        start = tuple(amcl_world.square_drive(1)[0])
        for name in [*calls, "/global_localization", "/static_map"]:
            if name == "map":
                feeder.send_map()
            elif name == "scan":
                feeder.scan(start)
            else:
                stype = GetMap if name == "/static_map" else Empty
                reply = call(ctx, client.create_client(stype, name), stype.Request())
                assert reply is not None
        assert node.updates >= 0
