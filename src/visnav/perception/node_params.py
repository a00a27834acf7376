"""Parameters of the perception nodes (image_proc, depth_image_proc, depthimage_to_laserscan).

One frozen dataclass per node, declared with
:func:`~visnav.graph.param_dataclass.declare_params`; names and defaults are those of
the ROS 2 nodes.
"""

from __future__ import annotations

from dataclasses import dataclass

from visnav.graph.param_dataclass import param
from visnav.perception.image_proc import DEBAYER_VNG

__all__ = [
    "DepthImageToLaserScanParams",
    "ImageProcParams",
    "PointCloudXyzParams",
    "PointCloudXyzrgbParams",
]


@dataclass(frozen=True)
class ImageProcParams:
    """image_proc's parameters."""

    interpolation: int = param(1, description="cv2 interpolation of rectify (1 linear)")
    debayer: int = param(DEBAYER_VNG, description="debayer method (0 bilinear, ... 3 VNG)")
    queue_size: int = param(5, description="synchroniser queue size", range=(1, 10_000))


@dataclass(frozen=True)
class PointCloudXyzParams:
    """depth_image_proc point_cloud_xyz's parameters."""

    queue_size: int = param(5, description="synchroniser queue size", range=(1, 10_000))
    invalid_depth: float = param(0.0, description="depth given to invalid pixels (0: NaN)")


@dataclass(frozen=True)
class PointCloudXyzrgbParams:
    """depth_image_proc point_cloud_xyzrgb's parameters."""

    queue_size: int = param(5, description="synchroniser queue size", range=(1, 10_000))
    exact_sync: bool = param(False, description="exact instead of approximate time sync")


@dataclass(frozen=True)
class DepthImageToLaserScanParams:
    """depthimage_to_laserscan's parameters."""

    scan_height: int = param(1, description="image rows used (pixels)")
    range_min: float = param(0.45, description="nearest range (m)")
    range_max: float = param(10.0, description="farthest range (m)")
    scan_time: float = param(0.033, description="time between scans (s)")
    output_frame: str = param("camera_depth_frame", description="frame of the scan")
