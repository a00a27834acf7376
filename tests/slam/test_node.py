"""The SLAM node on an in-process graph: map -> odom keeps odom -> base_link continuous."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node
from visnav.msgs import (
    CameraInfo,
    Header,
    Image,
    Path,
    PointCloud2,
    PoseStamped,
    TransformStamped,
    make,
)
from visnav.msgs.image import numpy_to_image
from visnav.msgs.pointcloud import cloud_to_xyz
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time
from visnav.slam.node import SlamNode
from visnav.slam.synthetic import camera_info_for
from visnav.tf import Buffer, matrix_to_transform, pose_to_matrix
from visnav.tf.ros import StaticTransformBroadcaster, TransformBroadcaster, TransformListener

from .conftest import Sequence, feed_rgbd

T_BASE_CAM = np.array([[0, 0, 1, 0.1], [-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, 0, 1]], dtype=float)


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def _tf(parent: str, child: str, m: np.ndarray, t_ns: int) -> TransformStamped:
    return make(
        TransformStamped,
        header=Header(stamp=ns_to_time(t_ns), frame_id=parent),
        child_frame_id=child,
        transform=matrix_to_transform(m),
    )


def _drift(i: int) -> np.ndarray:
    """Odometry drift after i frames: 2 mm and 0.05 degrees of yaw per frame."""
    a = np.radians(0.05 * i)
    d = np.eye(4)
    d[:2, :2] = [[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]
    d[0, 3] = 0.002 * i
    return d


def test_node_publishes_map_to_odom_pose_path_and_clouds(
    ctx: Context, short_sequence: Sequence
) -> None:
    seq = short_sequence
    slam = SlamNode(
        context=ctx,
        parameter_overrides={
            "n_features": 400,
            "map_cloud_period": 0.001,
            "tf_publish_period": 0.0,
            "path_publish_period": 0.0,
        },
    )
    feeder = Node("feeder", context=ctx)
    pubs: dict[str, Any] = {
        "image": feeder.create_publisher(Image, "rgb/image", 10),
        "depth": feeder.create_publisher(Image, "depth/image", 10),
        "info": feeder.create_publisher(CameraInfo, "rgb/camera_info", 10),
        "tf": TransformBroadcaster(feeder),
        "static": StaticTransformBroadcaster(feeder),
        "dense": feeder.create_publisher(
            get_message_class("std_msgs/msg/Empty"), "slam/dense_cloud_request", 1
        ),
    }
    got: dict[str, list[Any]] = {"pose": [], "path": [], "map": [], "dense": []}
    feeder.create_subscription(PoseStamped, "slam/pose", got["pose"].append, 10)
    feeder.create_subscription(Path, "slam/path", got["path"].append, 10)
    feeder.create_subscription(PointCloud2, "slam/map_points", got["map"].append, 10)
    feeder.create_subscription(PointCloud2, "slam/dense_cloud", got["dense"].append, 10)
    buffer = Buffer()
    TransformListener(buffer, feeder)
    pubs["static"].send_transform(_tf("base_link", "camera_optical", T_BASE_CAM, 0))
    info = camera_info_for(seq.camera, frame_id="camera_optical")
    n = 15
    t_base_cam_inv = np.linalg.inv(T_BASE_CAM)
    for i in range(n):
        t = int(seq.stamps_ns[i])
        header = Header(stamp=ns_to_time(t), frame_id="camera_optical")
        t_world_base = seq.poses[i] @ t_base_cam_inv
        t_odom_base = _drift(i) @ np.linalg.inv(seq.poses[0] @ t_base_cam_inv) @ t_world_base
        pubs["tf"].send_transform(_tf("odom", "base_link", t_odom_base, t))
        info.header = header
        pubs["info"].publish(info)
        pubs["image"].publish(numpy_to_image(seq.rgb[i], "rgb8", header=header))
        pubs["depth"].publish(numpy_to_image(seq.depth[i], "32FC1", header=header))
        ctx.spin_some()
    pubs["dense"].publish(get_message_class("std_msgs/msg/Empty")())
    ctx.spin_until(lambda: bool(got["dense"]) and bool(got["map"]), timeout_s=5.0)

    assert slam.system is not None
    assert slam.dropped == 0
    assert len(got["pose"]) >= n - 2  # the approximate synchroniser may hold the newest set
    assert got["pose"][-1].header.frame_id == "map"
    assert len(got["path"][-1].poses) == len(got["pose"])
    # map -> odom undoes the odometry drift: map -> base_link follows the ground truth
    k = len(got["pose"]) - 1
    t_map_odom = buffer.lookup_transform_matrix("map", "odom", 0)
    np.testing.assert_allclose(t_map_odom[:3, 3], np.linalg.inv(_drift(k))[:3, 3], atol=0.01)
    start = seq.poses[0] @ t_base_cam_inv
    truth = np.linalg.inv(start) @ seq.poses[k] @ t_base_cam_inv
    pose = pose_to_matrix(got["pose"][-1].pose)
    assert np.linalg.norm(pose[:3, 3] - truth[:3, 3]) < 0.02
    assert len(cloud_to_xyz(got["map"][-1])) > 100
    assert len(cloud_to_xyz(got["dense"][-1])) > 100


def test_node_publishes_the_whole_path_at_most_every_path_publish_period(
    ctx: Context, short_sequence: Sequence
) -> None:
    seq = short_sequence
    period = 3 * float(np.median(np.diff(seq.stamps_ns))) * 1e-9  # every third frame
    SlamNode(
        context=ctx,
        parameter_overrides={
            "odom_frame": "",
            "base_frame": "camera_optical",
            "n_features": 400,
            "approx_sync": False,
            "path_publish_period": period * 0.999,
        },
    )
    feeder = Node("feeder", context=ctx)
    poses: list[PoseStamped] = []
    paths: list[Path] = []
    feeder.create_subscription(PoseStamped, "slam/pose", poses.append, 10)
    feeder.create_subscription(Path, "slam/path", paths.append, 10)
    feed_rgbd(feeder, seq, 10)
    assert len(poses) == 10
    assert [len(p.poses) for p in paths] == [1, 4, 7, 10]  # frames 0, 3, 6, 9
    assert paths[-1].poses[-1].header.stamp == poses[-1].header.stamp


def test_node_reports_a_changed_camera_info(
    ctx: Context, short_sequence: Sequence, caplog: pytest.LogCaptureFixture
) -> None:
    seq = short_sequence
    slam = SlamNode(
        context=ctx, parameter_overrides={"odom_frame": "", "base_frame": "camera_optical"}
    )
    feeder = Node("feeder", context=ctx)
    img = feeder.create_publisher(Image, "rgb/image", 10)
    dep = feeder.create_publisher(Image, "depth/image", 10)
    inf = feeder.create_publisher(CameraInfo, "rgb/camera_info", 10)
    info = camera_info_for(seq.camera, frame_id="camera_optical")
    for i in range(4):
        header = Header(stamp=ns_to_time(int(seq.stamps_ns[i])), frame_id="camera_optical")
        if i == 2:
            info = camera_info_for(seq.camera, frame_id="camera_optical")
            info.k = np.array([200.0, 0, 80, 0, 200.0, 60, 0, 0, 1])
            info.p = np.array([200.0, 0, 80, 0, 0, 200.0, 60, 0, 0, 0, 1, 0])
        info.header = header
        inf.publish(info)
        img.publish(numpy_to_image(seq.rgb[i], "rgb8", header=header))
        dep.publish(numpy_to_image(seq.depth[i], "32FC1", header=header))
        ctx.spin_some()
    ctx.spin_some()
    assert slam.dropped >= 1
    assert "changed (size, K or P) after SLAM started" in caplog.text
