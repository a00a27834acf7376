"""Graph nodes for the perception algorithms, with the ROS packages' topic and parameter names.

* :class:`ImageProcNode` (image_proc): ``image_raw`` + ``camera_info`` (exact sync) ->
  ``image_mono``, ``image_color``, ``image_rect``, ``image_rect_color``; parameters
  ``interpolation`` (1), ``debayer`` (3 = VNG), ``queue_size`` (5).
* :class:`PointCloudXyzNode` (depth_image_proc): ``image_rect`` + ``camera_info`` ->
  ``points``; ``queue_size``, ``invalid_depth``.
* :class:`PointCloudXyzrgbNode`: ``depth_registered/image_rect``, ``rgb/image_rect_color``,
  ``rgb/camera_info`` -> ``depth_registered/points``; ``queue_size``, ``exact_sync``.
* :class:`ConvertMetricNode`: ``image_raw`` -> ``image``.
* :class:`DepthImageToLaserScanNode`: ``depth`` + ``depth_camera_info`` -> ``scan``;
  ``scan_height`` (1), ``range_min`` (0.45), ``range_max`` (10.0), ``scan_time`` (0.033),
  ``output_frame``.

Topic names are relative, so a node in namespace ``/camera`` (or with remappings)
connects to ``/camera/image_raw`` etc. Processing errors of one message are logged
(at most once per 5 s per node, with the count dropped so far) and the message is
dropped; the node keeps running.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from visnav import message_filters
from visnav.errors import VisnavError
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params
from visnav.graph.qos import qos_profile_sensor_data
from visnav.msgs.image import check_image
from visnav.msgs.types import CameraInfo, Image, LaserScan, PointCloud2
from visnav.perception.depth_image_proc import PointCloudXyz, PointCloudXyzrgb, convert_metric
from visnav.perception.depth_to_scan import DepthImageToLaserScan
from visnav.perception.image_proc import Rectifier, image_color, image_mono
from visnav.perception.node_params import (
    DepthImageToLaserScanParams,
    ImageProcParams,
    PointCloudXyzParams,
    PointCloudXyzrgbParams,
)

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "ConvertMetricNode",
    "DepthImageToLaserScanNode",
    "ImageProcNode",
    "PointCloudXyzNode",
    "PointCloudXyzrgbNode",
]


_WARN_AFTER_FRAMES = 10
_DROP_LOG_PERIOD_S = 5.0  # at most one "dropped a message" error per node per 5 s


class _PerceptionNode(Node):
    def __init__(self, name: str, **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        self.dropped = 0

    def _fail(self, exc: VisnavError, *inputs: str) -> None:
        self.dropped += 1
        names = " + ".join(self.resolve_topic_name(t) for t in inputs)
        self.get_logger().error(
            f"dropped a message on {names} ({self.dropped} so far): {exc}",
            throttle_duration_sec=_DROP_LOG_PERIOD_S,
        )


class ImageProcNode(_PerceptionNode):
    """image_proc: debayer and rectify a camera stream.

    Args:
        name: node name (default ``image_proc``).
        **node_kwargs: passed to :class:`~visnav.graph.Node` (context, namespace, ...).
    """

    def __init__(self, name: str = "image_proc", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        p = self.params = declare_params(self, ImageProcParams)
        self.interpolation, self.debayer, queue = p.interpolation, p.debayer, p.queue_size
        self._rect = Rectifier(interpolation=self.interpolation)
        self._pubs = {
            t: self.create_publisher(Image, t, 5)
            for t in ("image_mono", "image_color", "image_rect", "image_rect_color")
        }
        image = message_filters.Subscriber(self, Image, "image_raw", 5)
        info = message_filters.Subscriber(self, CameraInfo, "camera_info", 5)
        self._sync = message_filters.TimeSynchronizer([image, info], queue)
        self._sync.register_callback(self._on_image)

    def _on_image(self, raw: Image, info: CameraInfo) -> None:
        try:
            check_image(raw)  # also where image_mono / image_color pass the message on
            mono = image_mono(raw)
            color = image_color(raw, algorithm=self.debayer)
            self._pubs["image_mono"].publish(mono)
            self._pubs["image_color"].publish(color)
            self._pubs["image_rect"].publish(self._rect.rectify(mono, info))
            self._pubs["image_rect_color"].publish(self._rect.rectify(color, info))
        except VisnavError as exc:
            self._fail(exc, "image_raw", "camera_info")


class PointCloudXyzNode(_PerceptionNode):
    """depth_image_proc/point_cloud_xyz: depth image + camera_info -> ``points``."""

    def __init__(self, name: str = "point_cloud_xyz", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        p = self.params = declare_params(self, PointCloudXyzParams)
        queue, invalid = p.queue_size, p.invalid_depth
        self._conv = PointCloudXyz(invalid_depth=invalid)
        self._pub = self.create_publisher(PointCloud2, "points", 5)
        depth = message_filters.Subscriber(self, Image, "image_rect", queue)
        info = message_filters.Subscriber(self, CameraInfo, "camera_info", queue)
        self._sync = message_filters.TimeSynchronizer([depth, info], queue)
        self._sync.register_callback(self._on_depth)

    def _on_depth(self, depth: Image, info: CameraInfo) -> None:
        try:
            self._pub.publish(self._conv.convert(depth, info))
        except VisnavError as exc:
            self._fail(exc, "image_rect", "camera_info")


class PointCloudXyzrgbNode(_PerceptionNode):
    """depth_image_proc/point_cloud_xyzrgb: registered depth + colour -> coloured cloud."""

    def __init__(
        self, name: str = "point_cloud_xyzrgb", **node_kwargs: Unpack[NodeOptions]
    ) -> None:
        super().__init__(name, **node_kwargs)
        p = self.params = declare_params(self, PointCloudXyzrgbParams)
        queue, exact = p.queue_size, p.exact_sync
        self._conv = PointCloudXyzrgb()
        self._pub = self.create_publisher(PointCloud2, "depth_registered/points", 5)
        depth = message_filters.Subscriber(self, Image, "depth_registered/image_rect", queue)
        rgb = message_filters.Subscriber(self, Image, "rgb/image_rect_color", queue)
        info = message_filters.Subscriber(self, CameraInfo, "rgb/camera_info", queue)
        self._sync: message_filters.SimpleFilter = (
            message_filters.TimeSynchronizer([depth, rgb, info], queue)
            if exact
            else message_filters.ApproximateTime([depth, rgb, info], queue)
        )
        self._sync.register_callback(self._on_set)

    def _on_set(self, depth: Image, rgb: Image, info: CameraInfo) -> None:
        try:
            self._pub.publish(self._conv.convert(depth, rgb, info))
        except VisnavError as exc:
            self._fail(
                exc, "depth_registered/image_rect", "rgb/image_rect_color", "rgb/camera_info"
            )


class ConvertMetricNode(_PerceptionNode):
    """depth_image_proc/convert_metric: 16UC1 mm -> 32FC1 m (``image_raw`` -> ``image``)."""

    def __init__(self, name: str = "convert_metric", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        self._pub = self.create_publisher(Image, "image", 5)
        self.create_subscription(Image, "image_raw", self._on_image, 5)

    def _on_image(self, msg: Image) -> None:
        try:
            self._pub.publish(convert_metric(msg))
        except VisnavError as exc:
            self._fail(exc, "image_raw")


class DepthImageToLaserScanNode(_PerceptionNode):
    """depthimage_to_laserscan: ``depth`` + ``depth_camera_info`` -> ``scan``.

    As the ROS 2 node, the newest camera_info is kept and used for each depth image
    (no stamp matching between them).
    """

    def __init__(
        self, name: str = "depthimage_to_laserscan", **node_kwargs: Unpack[NodeOptions]
    ) -> None:
        super().__init__(name, **node_kwargs)
        p = self.params = declare_params(self, DepthImageToLaserScanParams)
        self.converter = DepthImageToLaserScan(
            scan_height=p.scan_height,
            range_min=p.range_min,
            range_max=p.range_max,
            scan_time=p.scan_time,
            output_frame_id=p.output_frame,
        )
        self._info: CameraInfo | None = None
        self._waiting = 0
        self._pub = self.create_publisher(LaserScan, "scan", qos_profile_sensor_data)
        self.create_subscription(
            CameraInfo, "depth_camera_info", self._on_info, qos_profile_sensor_data
        )
        self.create_subscription(Image, "depth", self._on_depth, qos_profile_sensor_data)

    def _on_info(self, msg: CameraInfo) -> None:
        self._info = msg

    def _on_depth(self, msg: Image) -> None:
        if self._info is None:
            self._waiting += 1
            # A publisher that sends the image just before its camera_info (as Gazebo does)
            # loses the first frame; only a stream that never brings camera_info is reported.
            if self._waiting == _WARN_AFTER_FRAMES:
                self.get_logger().warning(
                    f"{self._waiting} depth images received but no camera_info on "
                    f"{self.resolve_topic_name('depth_camera_info')}; waiting for it"
                )
            return
        try:
            self._pub.publish(self.converter.convert(msg, self._info))
        except VisnavError as exc:
            self._fail(exc, "depth", "depth_camera_info")
