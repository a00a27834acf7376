"""Camera and depth processing: image_geometry, image_proc, depth_image_proc, depth -> scan.

The algorithms are plain classes and functions with numpy arrays and ROS messages
in and out; the graph nodes that wire them to topics live next to them.
"""

from __future__ import annotations

from visnav.perception.camera_model import (
    DISTORTION_MODELS,
    EQUIDISTANT,
    PLUMB_BOB,
    RATIONAL_POLYNOMIAL,
    PinholeCameraModel,
)
from visnav.perception.depth_image_proc import (
    PointCloudXyz,
    PointCloudXyzrgb,
    convert_metric,
    depth_ray_tables,
    depth_to_points,
    point_cloud_xyz,
    point_cloud_xyzrgb,
)
from visnav.perception.depth_to_scan import (
    DepthImageToLaserScan,
    ScanGeometry,
    depth_rows_to_ranges,
    scan_debug_image,
    scan_geometry,
    scan_rows,
)
from visnav.perception.errors import (
    CameraModelError,
    DepthImageError,
    DepthToScanError,
    ImageProcError,
    PerceptionError,
)
from visnav.perception.image_proc import (
    DEBAYER_BILINEAR,
    DEBAYER_EDGE_AWARE,
    DEBAYER_EDGE_AWARE_WEIGHTED,
    DEBAYER_VNG,
    Rectifier,
    debayer,
    image_color,
    image_mono,
    to_color,
    to_mono,
)
from visnav.perception.nodes import (
    ConvertMetricNode,
    DepthImageToLaserScanNode,
    ImageProcNode,
    PointCloudXyzNode,
    PointCloudXyzrgbNode,
)

__all__ = [
    "ConvertMetricNode",
    "DepthImageToLaserScanNode",
    "ImageProcNode",
    "PointCloudXyzNode",
    "PointCloudXyzrgbNode",
    "DEBAYER_BILINEAR",
    "DEBAYER_EDGE_AWARE",
    "DEBAYER_EDGE_AWARE_WEIGHTED",
    "DEBAYER_VNG",
    "DISTORTION_MODELS",
    "EQUIDISTANT",
    "PLUMB_BOB",
    "RATIONAL_POLYNOMIAL",
    "CameraModelError",
    "DepthImageError",
    "DepthImageToLaserScan",
    "DepthToScanError",
    "ImageProcError",
    "PerceptionError",
    "PinholeCameraModel",
    "PointCloudXyz",
    "PointCloudXyzrgb",
    "Rectifier",
    "ScanGeometry",
    "convert_metric",
    "debayer",
    "depth_ray_tables",
    "depth_rows_to_ranges",
    "depth_to_points",
    "image_color",
    "image_mono",
    "point_cloud_xyz",
    "point_cloud_xyzrgb",
    "scan_debug_image",
    "scan_geometry",
    "scan_rows",
    "to_color",
    "to_mono",
]
