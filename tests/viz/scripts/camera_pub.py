"""A camera process for the viewer tests: publishes until killed or for argv[1] seconds.

At 10 Hz, in frame ``cam_optical`` (static TF ``map -> cam_optical``):
/cam/image_raw (rgb8 64x48: left half red, right half blue), its ``compressed`` transport
(PNG), /cam/camera_info, /depth/image_raw (32FC1: 1 m .. 3 m left to right) and
/points (PointCloud2, 100 green points).
"""

from __future__ import annotations

import sys

import numpy as np

from visnav.graph import Context, Node
from visnav.msgs import (
    CameraInfo,
    CompressedImage,
    Header,
    Image,
    PointCloud2,
    TransformStamped,
    make,
    ns_to_time,
    numpy_to_image,
    xyz_to_cloud,
)
from visnav.perception.image_transport import compress
from visnav.tf.ros import StaticTransformBroadcaster

duration = float(sys.argv[1]) if len(sys.argv) > 1 else 20.0
W, H = 64, 48
rgb = np.zeros((H, W, 3), np.uint8)
rgb[:, : W // 2, 0] = 255
rgb[:, W // 2 :, 2] = 255
depth = np.tile(np.linspace(1.0, 3.0, W, dtype=np.float32), (H, 1))
points = np.random.default_rng(0).uniform(-1, 1, (100, 3)).astype(np.float32)
green = np.tile(np.array([[0, 255, 0]], np.uint8), (100, 1))

with Context() as ctx:
    node = Node("camera", context=ctx)
    pub_img = node.create_publisher(Image, "/cam/image_raw", 5)
    pub_cmp = node.create_publisher(CompressedImage, "/cam/image_raw/compressed", 5)
    pub_info = node.create_publisher(CameraInfo, "/cam/camera_info", 5)
    pub_depth = node.create_publisher(Image, "/depth/image_raw", 5)
    pub_cloud = node.create_publisher(PointCloud2, "/points", 5)
    static = StaticTransformBroadcaster(node)
    tf = make(TransformStamped, child_frame_id="cam_optical")
    tf.header.frame_id = "map"
    tf.transform.translation.z = 1.0
    tf.transform.rotation.w = 1.0
    static.send_transform(tf)

    def tick() -> None:
        header = Header(stamp=ns_to_time(node.get_clock().now_ns()), frame_id="cam_optical")
        image = numpy_to_image(rgb, "rgb8", header=header)
        pub_img.publish(image)
        pub_cmp.publish(compress(image, format="png"))
        info = make(CameraInfo, header=header, width=W, height=H)
        info.k[:] = [50.0, 0.0, W / 2, 0.0, 50.0, H / 2, 0.0, 0.0, 1.0]
        pub_info.publish(info)
        pub_depth.publish(numpy_to_image(depth, "32FC1", header=header))
        pub_cloud.publish(xyz_to_cloud(points, header=header, rgb=green))

    node.create_timer(0.1, tick)
    print("ready", flush=True)
    ctx.spin(duration_s=duration)
