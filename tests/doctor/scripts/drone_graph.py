"""A faulty drone graph in another process: the cloud is published under /drone, the mapper
subscribes to the absolute /camera/depth/points; a best-effort image feeds a reliable viewer."""

from __future__ import annotations

import sys
import time

import numpy as np

from visnav.graph import Context, Node, QoSProfile, ReliabilityPolicy
from visnav.msgs import Header, Image, PointCloud2, ns_to_time, numpy_to_image, xyz_to_cloud

with Context() as ctx:
    cam = Node("camera_driver", namespace="/drone", context=ctx)
    cloud_pub = cam.create_publisher(PointCloud2, "camera/depth/points", 10)
    image_pub = cam.create_publisher(
        Image, "camera/image_raw", QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
    )
    mapper = Node("mapper", context=ctx)
    mapper.create_subscription(PointCloud2, "/camera/depth/points", lambda m: None, 10)
    viewer = Node("viewer", context=ctx)
    viewer.create_subscription(Image, "/drone/camera/image_raw", lambda m: None, 10)
    points = np.random.default_rng(0).uniform(1, 3, size=(100, 3))
    print("ready", flush=True)
    end = time.monotonic() + float(sys.argv[1])
    k = 0
    while time.monotonic() < end:
        header = Header(stamp=ns_to_time(cam.get_clock().now_ns()), frame_id="camera_optical_frame")
        cloud_pub.publish(xyz_to_cloud(points, header=header))
        image_pub.publish(
            numpy_to_image(np.full((8, 8, 3), k % 255, np.uint8), "rgb8", header=header)
        )
        k += 1
        ctx.spin_once(0.1)
