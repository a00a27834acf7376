"""The perception nodes on a real (in-process) graph: topic names, sync, outputs, errors."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node, qos_profile_sensor_data
from visnav.msgs import CameraInfo, Image, LaserScan, PointCloud2, cloud_to_xyz, numpy_to_image
from visnav.perception.nodes import (
    ConvertMetricNode,
    DepthImageToLaserScanNode,
    ImageProcNode,
    PointCloudXyzNode,
)


@pytest.fixture
def ctx() -> Any:
    with Context(transport="local") as c:
        yield c


def _wall(info: CameraInfo, distance: float) -> Image:
    depth = np.full((info.height, info.width), distance, np.float32)
    return numpy_to_image(depth, "32FC1", header=info.header)


def test_depth_to_scan_node_on_a_flat_wall(ctx: Context, make_info: Any) -> None:
    info = make_info(width=64, height=48, fx=40.0)
    node = DepthImageToLaserScanNode(
        context=ctx,
        namespace="/camera",
        parameter_overrides={"scan_height": 5, "output_frame": "laser"},
    )
    probe = Node("probe", context=ctx)
    scans: list[LaserScan] = []
    probe.create_subscription(LaserScan, "/camera/scan", scans.append, qos_profile_sensor_data)
    info_pub = probe.create_publisher(CameraInfo, "/camera/depth_camera_info", 5)
    depth_pub = probe.create_publisher(Image, "/camera/depth", 5)
    depth_pub.publish(_wall(info, 2.0))  # before any camera_info: waits, no scan
    ctx.spin_some()
    assert scans == []
    info_pub.publish(info)
    depth_pub.publish(_wall(info, 2.0))
    ctx.spin_some()
    assert len(scans) == 1
    scan = scans[0]
    assert scan.header.frame_id == "laser"
    assert node.converter.scan_height == 5
    assert len(scan.ranges) == 64
    finite = scan.ranges[np.isfinite(scan.ranges)]
    edge = 2.0 / np.cos(max(abs(scan.angle_min), abs(scan.angle_max)))
    assert finite.min() == pytest.approx(2.0, rel=2e-3)
    assert finite.max() <= edge * 1.001
    assert finite.size > 50


def test_depth_to_scan_node_rejects_colour_encoding(ctx: Context, make_info: Any) -> None:
    info = make_info(width=16, height=12, fx=10.0)
    node = DepthImageToLaserScanNode(context=ctx)
    probe = Node("probe", context=ctx)
    probe.create_publisher(CameraInfo, "depth_camera_info", 5).publish(info)
    rgb = numpy_to_image(np.zeros((12, 16, 3), np.uint8), "rgb8", header=info.header)
    probe.create_publisher(Image, "depth", 5).publish(rgb)
    ctx.spin_some()
    assert node.dropped == 1


def test_point_cloud_xyz_node_syncs_exact_stamps(ctx: Context, make_info: Any) -> None:
    info = make_info(width=8, height=6, fx=5.0)
    PointCloudXyzNode(context=ctx, namespace="/depth")
    probe = Node("probe", context=ctx)
    clouds: list[PointCloud2] = []
    probe.create_subscription(PointCloud2, "/depth/points", clouds.append, 10)
    probe.create_publisher(Image, "/depth/image_rect", 5).publish(_wall(info, 1.5))
    ctx.spin_some()
    assert clouds == []  # waits for the camera_info with the same stamp
    probe.create_publisher(CameraInfo, "/depth/camera_info", 5).publish(info)
    ctx.spin_some()
    assert len(clouds) == 1
    xyz = cloud_to_xyz(clouds[0])
    assert xyz.shape == (48, 3)
    assert np.allclose(xyz[:, 2], 1.5)
    assert clouds[0].header.frame_id == info.header.frame_id


def test_image_proc_node_publishes_four_images(ctx: Context, make_info: Any) -> None:
    info = make_info(width=8, height=6, fx=5.0, d=[0.1, 0.0, 0.0, 0.0, 0.0])
    ImageProcNode(context=ctx, namespace="/cam")
    probe = Node("probe", context=ctx)
    got: dict[str, Image] = {}
    for t in ("image_mono", "image_color", "image_rect", "image_rect_color"):
        probe.create_subscription(Image, f"/cam/{t}", lambda m, t=t: got.__setitem__(t, m), 5)
    bayer = numpy_to_image(
        np.random.default_rng(0).integers(0, 255, (6, 8), dtype=np.uint8),
        "bayer_rggb8",
        header=info.header,
    )
    probe.create_publisher(Image, "/cam/image_raw", 5).publish(bayer)
    probe.create_publisher(CameraInfo, "/cam/camera_info", 5).publish(info)
    ctx.spin_some()
    assert {k: v.encoding for k, v in got.items()} == {
        "image_mono": "mono8",
        "image_color": "bgr8",
        "image_rect": "mono8",
        "image_rect_color": "bgr8",
    }


def test_convert_metric_node(ctx: Context) -> None:
    ConvertMetricNode(context=ctx)
    probe = Node("probe", context=ctx)
    out: list[Image] = []
    probe.create_subscription(Image, "image", out.append, 5)
    mm = numpy_to_image(np.array([[0, 1500]], np.uint16), "16UC1")
    probe.create_publisher(Image, "image_raw", 5).publish(mm)
    ctx.spin_some()
    assert out[0].encoding == "32FC1"
    values = np.frombuffer(out[0].data, np.float32)
    assert np.isnan(values[0])
    assert values[1] == pytest.approx(1.5)
