"""The grid map on the graph: clouds in a camera frame via TF, depth + odometry sync, output."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.mapping.grid_map_node import GridMapNode
from visnav.msgs import (
    CameraInfo,
    Header,
    Image,
    Odometry,
    PointCloud2,
    Quaternion,
    Transform,
    TransformStamped,
    Vector3,
    cloud_to_xyz,
    make,
    ns_to_time,
    numpy_to_image,
    xyz_to_cloud,
)
from visnav.tf.ros import StaticTransformBroadcaster, TransformBroadcaster

# optical frame (z forward, x right, y down) in a body frame (x forward, z up)
Q_BODY_OPTICAL = (-0.5, 0.5, -0.5, 0.5)
BODY = (1.0, 2.0, 1.0)
YAW = math.pi / 2  # the body looks along +y


def _tf(
    parent: str,
    child: str,
    xyz: tuple[float, float, float],
    q: tuple[float, float, float, float],
    t_ns: int,
) -> TransformStamped:
    return TransformStamped(
        header=Header(stamp=ns_to_time(t_ns), frame_id=parent),
        child_frame_id=child,
        transform=Transform(
            translation=Vector3(x=xyz[0], y=xyz[1], z=xyz[2]),
            rotation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]),
        ),
    )


def _yaw_q(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def _params(**extra: object) -> dict[str, object]:
    return {
        "grid_map.map_size_x": 12.0,
        "grid_map.map_size_y": 12.0,
        "grid_map.map_size_z": 3.0,
        "grid_map.vis_period": 0.01,
        **extra,
    }


def test_cloud_in_a_camera_frame_lands_in_the_world_via_tf(ctx: Context) -> None:
    node = GridMapNode(
        context=ctx,
        namespace="/drone",
        parameter_overrides=_params(**{"grid_map.cloud_topic": "points"}),
    )
    probe = Node("probe", context=ctx)
    StaticTransformBroadcaster(probe).send_transform(
        _tf("base_link", "camera", (0.1, 0.0, 0.0), Q_BODY_OPTICAL, 0)
    )
    tfb = TransformBroadcaster(probe)
    pub = probe.create_publisher(PointCloud2, "/drone/points", 10)
    occupied: list[PointCloud2] = []
    probe.create_subscription(PointCloud2, "/drone/grid_map/occupancy", occupied.append, 10)
    # a 1 m x 0.6 m patch 3 m in front of the camera (optical z = 3)
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, 21), np.linspace(-0.3, 0.3, 13))
    patch = np.column_stack([u.ravel(), v.ravel(), np.full(u.size, 3.0)])
    for k in range(8):
        t_ns = 1_000_000_000 + k * 50_000_000
        tfb.send_transform(_tf("world", "base_link", BODY, _yaw_q(YAW), t_ns))
        pub.publish(xyz_to_cloud(patch, header=Header(stamp=ns_to_time(t_ns), frame_id="camera")))
        ctx.spin_some()
    assert node.grid.updates == 8
    cells = node.grid.map.occupied_cells()
    assert len(cells) > 50
    # camera at body + 0.1 m forward = (1, 2.1, 1); forward is +y: the patch is the plane y = 5.1
    assert np.allclose(np.median(cells, axis=0), [1.05, 5.15, 1.05], atol=0.11)
    assert cells[:, 1].min() >= 5.0
    assert cells[:, 1].max() < 5.2
    assert cells[:, 0].min() >= 0.4
    assert cells[:, 0].max() <= 1.6
    assert node.grid.map.occupancy([(1.0, 3.5, 1.0)])[0] == 0  # cleared on the way
    # the vis timer may have published the empty map before the first update arrived:
    # wait for the publication of the final map (it comes within one vis_period)
    assert ctx.spin_until(
        lambda: len(occupied) > 0 and len(cloud_to_xyz(occupied[-1])) == len(cells),
        timeout_s=2.0,
    )
    assert occupied[-1].header.frame_id == "world"


def test_depth_and_odometry_are_paired_and_use_the_camera_extrinsics(ctx: Context) -> None:
    node = GridMapNode(context=ctx, namespace="/drone", parameter_overrides=_params())
    probe = Node("probe", context=ctx)
    StaticTransformBroadcaster(probe).send_transform(
        _tf("base_link", "depth_optical", (0.1, 0.0, 0.0), Q_BODY_OPTICAL, 0)
    )
    odom_pub = probe.create_publisher(Odometry, "/drone/odom", 100)
    depth_pub = probe.create_publisher(Image, "/drone/depth_camera/depth/image_raw", 10)
    info_pub = probe.create_publisher(CameraInfo, "/drone/depth_camera/depth/camera_info", 10)
    info = make(CameraInfo, width=64, height=48)
    info.k[:] = [40.0, 0.0, 32.0, 0.0, 40.0, 24.0, 0.0, 0.0, 1.0]
    info_pub.publish(info)
    depth = np.full((48, 64), 2.5, np.float32)
    q = _yaw_q(YAW)
    for k in range(60):
        t_ns = 1_000_000_000 + k * 10_000_000
        odom = make(Odometry)
        odom.header = Header(stamp=ns_to_time(t_ns), frame_id="world")
        odom.child_frame_id = "base_link"
        odom.pose.pose.position.x, odom.pose.pose.position.y, odom.pose.pose.position.z = BODY
        o = odom.pose.pose.orientation
        o.x, o.y, o.z, o.w = q
        odom_pub.publish(odom)
        if k % 5 == 0:
            header = Header(stamp=ns_to_time(t_ns), frame_id="depth_optical")
            depth_pub.publish(numpy_to_image(depth, "32FC1", header=header))
        ctx.spin_some()
    assert node.grid.updates >= 10
    assert node.grid.dropped == 0
    cells = node.grid.map.occupied_cells()
    assert len(cells) > 50
    # camera (1, 2.1, 1) looking along +y, wall 2.5 m ahead: y = 4.6
    assert np.allclose(cells[:, 1], 4.65, atol=0.051)
