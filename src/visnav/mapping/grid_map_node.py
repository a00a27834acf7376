"""The grid map on the graph: depth + pose (ApproximateTime) or clouds in any frame, via TF.

:class:`GridMapRos` attaches ego-planner's ``GridMap::initMap`` behaviour to a node
(the planner node owns its map, as upstream); :class:`GridMapNode` is a node that
only maps. Parameters are declared under a prefix (``grid_map.``), with
ego-planner's names:

* map and fusion: ``resolution``, ``map_size_x/y/z``, ``map_center_x/y``,
  ``ground_height``, ``local_update_range_x/y/z``, ``obstacles_inflation``,
  ``local_map_margin``, ``use_depth_filter``, ``depth_filter_*``,
  ``k_depth_scaling_factor``, ``skip_pixel``, ``p_hit/p_miss/p_min/p_max/p_occ``,
  ``min_ray_length``, ``max_ray_length``, ``virtual_ceil_height``,
  ``virtual_ground_height`` (visnav; below the map disables it),
  ``visualization_truncate_height``;
* camera: ``fx``, ``fy``, ``cx``, ``cy`` (<= 0: read from ``camera_info_topic``);
* inputs: ``pose_type`` (1 ``geometry_msgs/PoseStamped``, 2 ``nav_msgs/Odometry``),
  ``depth_topic``, ``camera_info_topic``, ``pose_topic``, ``odom_topic``,
  ``cloud_topic`` (an empty name turns an input off); ``frame_id`` is the map
  (global) frame, ``local_frame`` the body frame the pose describes when the
  odometry names no child frame;
* ``show_occ_time``: log each update's fusion time and the running mean (upstream's
  debugging switch);
* output: ``vis_period`` (s) of ``grid_map/occupancy`` and
  ``grid_map/occupancy_inflate`` (``sensor_msgs/PointCloud2`` in the map frame,
  published only while someone subscribes).

Depth images are paired with poses by the ApproximateTime policy; the camera
pose is ``T_map_posframe (TF) @ pose @ T_body_camera (TF)``. A cloud is moved
into the map frame with TF at its stamp and ray cast from its frame's origin; a
cloud already in the map frame is cast from the latest pose, as upstream does.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav import message_filters
from visnav.errors import VisnavError
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.mapping.grid_map import GridMap, GridMapError, GridMapParams, UpdateResult
from visnav.msgs.image import image_to_numpy
from visnav.msgs.pointcloud import cloud_to_xyz, xyz_to_cloud
from visnav.msgs.time import time_to_ns
from visnav.msgs.types import CameraInfo, Header, Image, Odometry, PointCloud2, PoseStamped
from visnav.tf.buffer import Buffer
from visnav.tf.errors import ExtrapolationException, TransformException
from visnav.tf.ros import TransformListener
from visnav.tf.transforms import pose_to_matrix

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["GridMapNode", "GridMapRosParams", "GridMapRos", "POSE_STAMPED", "ODOMETRY"]

POSE_STAMPED = 1
ODOMETRY = 2
_DROP_LOG_PERIOD_S = 5.0  # at most one "grid map: ..." warning per node per 5 s

_MAP = GridMapParams()


@dataclass(frozen=True, kw_only=True)
class GridMapRosParams:
    """The ``grid_map.*`` parameters: :class:`GridMapParams` flattened, plus inputs/outputs.

    Map and fusion defaults come from :class:`GridMapParams`; the names are ego-planner's
    (``map_size_x`` ...). See the module docs for what each does.
    """

    resolution: float = param(_MAP.resolution, description="voxel edge (m)")
    map_size_x: float = param(_MAP.map_size[0], description="map extent x (m)")
    map_size_y: float = param(_MAP.map_size[1], description="map extent y (m)")
    map_size_z: float = param(_MAP.map_size[2], description="map extent z (m)")
    map_center_x: float = param(_MAP.map_center[0], description="map centre x (m)")
    map_center_y: float = param(_MAP.map_center[1], description="map centre y (m)")
    ground_height: float = param(_MAP.ground_height, description="bottom of the map (m)")
    local_update_range_x: float = param(_MAP.local_update_range[0], description="half-box x (m)")
    local_update_range_y: float = param(_MAP.local_update_range[1], description="half-box y (m)")
    local_update_range_z: float = param(_MAP.local_update_range[2], description="half-box z (m)")
    obstacles_inflation: float = param(_MAP.obstacles_inflation, description="inflation (m)")
    local_map_margin: int = param(_MAP.local_map_margin, description="voxels kept around")
    use_depth_filter: bool = param(_MAP.use_depth_filter, description="apply the depth filter")
    depth_filter_maxdist: float = param(_MAP.depth_filter_maxdist, description="max depth (m)")
    depth_filter_mindist: float = param(_MAP.depth_filter_mindist, description="min depth (m)")
    depth_filter_margin: int = param(_MAP.depth_filter_margin, description="border (pixels)")
    k_depth_scaling_factor: float = param(
        _MAP.k_depth_scaling_factor, description="16UC1 units per metre"
    )
    skip_pixel: int = param(_MAP.skip_pixel, description="depth pixel stride")
    p_hit: float = param(_MAP.p_hit, description="hit probability", range=(0.0, 1.0))
    p_miss: float = param(_MAP.p_miss, description="miss probability", range=(0.0, 1.0))
    p_min: float = param(_MAP.p_min, description="lower clamp probability", range=(0.0, 1.0))
    p_max: float = param(_MAP.p_max, description="upper clamp probability", range=(0.0, 1.0))
    p_occ: float = param(_MAP.p_occ, description="occupied threshold", range=(0.0, 1.0))
    min_ray_length: float = param(_MAP.min_ray_length, description="nearest point (m)")
    max_ray_length: float = param(_MAP.max_ray_length, description="longest ray (m)")
    virtual_ceil_height: float = param(_MAP.virtual_ceil_height, description="ceiling (m)")
    virtual_ground_height: float = param(
        _MAP.virtual_ground_height if _MAP.virtual_ground_height is not None else -1.0,
        description="virtual ground (m); below the map disables it",
    )
    visualization_truncate_height: float = param(
        _MAP.visualization_truncate_height, description="published cells below (m)"
    )
    fx: float = param(-1.0, description="focal x (px); <= 0 reads camera_info_topic")
    fy: float = param(-1.0, description="focal y (px); <= 0 reads camera_info_topic")
    cx: float = param(-1.0, description="centre x (px); <= 0 reads camera_info_topic")
    cy: float = param(-1.0, description="centre y (px); <= 0 reads camera_info_topic")
    pose_type: int = param(ODOMETRY, description="1 PoseStamped, 2 Odometry", range=(1, 2))
    frame_id: str = param("world", description="map (global) frame")
    local_frame: str = param("base_link", description="body frame of the pose")
    depth_topic: str = param("depth_camera/depth/image_raw", description="depth image input")
    camera_info_topic: str = param(
        "depth_camera/depth/camera_info", description="camera info input"
    )
    pose_topic: str = param("camera_pose", description="PoseStamped input (pose_type 1)")
    odom_topic: str = param("odom", description="Odometry input (pose_type 2)")
    cloud_topic: str = param("", description="PointCloud2 input (empty: off)")
    vis_period: float = param(0.05, description="occupancy publishing period (s)")
    show_occ_time: bool = param(False, description="log fusion times")


def params_from_values(v: GridMapRosParams) -> GridMapParams:
    """:class:`GridMapParams` from the flat ego-planner-named parameters."""
    return GridMapParams(
        resolution=v.resolution,
        map_size=(v.map_size_x, v.map_size_y, v.map_size_z),
        map_center=(v.map_center_x, v.map_center_y),
        ground_height=v.ground_height,
        local_update_range=(
            v.local_update_range_x,
            v.local_update_range_y,
            v.local_update_range_z,
        ),
        obstacles_inflation=v.obstacles_inflation,
        local_map_margin=v.local_map_margin,
        use_depth_filter=v.use_depth_filter,
        depth_filter_maxdist=v.depth_filter_maxdist,
        depth_filter_mindist=v.depth_filter_mindist,
        depth_filter_margin=v.depth_filter_margin,
        k_depth_scaling_factor=v.k_depth_scaling_factor,
        skip_pixel=v.skip_pixel,
        p_hit=v.p_hit,
        p_miss=v.p_miss,
        p_min=v.p_min,
        p_max=v.p_max,
        p_occ=v.p_occ,
        min_ray_length=v.min_ray_length,
        max_ray_length=v.max_ray_length,
        virtual_ceil_height=v.virtual_ceil_height,
        virtual_ground_height=v.virtual_ground_height,
        visualization_truncate_height=v.visualization_truncate_height,
    )


class GridMapRos:
    """Feeds a :class:`~visnav.mapping.grid_map.GridMap` from a node's topics.

    Args:
        node: The node that owns the subscriptions, publishers and timer.
        prefix: Parameter prefix (``grid_map``).
        defaults: Defaults replacing :class:`GridMapRosParams`'s (before parameter overrides).
        tf_buffer: A TF buffer to share; None creates one with its own listener on ``node``.

    Attributes:
        map: The grid map.
        updates: Successful updates so far.
        dropped: Inputs dropped (the reason is logged at most once per 5 s, with the count).
    """

    def __init__(
        self,
        node: Node,
        *,
        prefix: str = "grid_map",
        defaults: Mapping[str, Any] | None = None,
        tf_buffer: Buffer | None = None,
    ) -> None:
        self.node = node
        self.params = declare_params(node, GridMapRosParams, prefix=f"{prefix}.", defaults=defaults)
        values = dataclasses.asdict(self.params)
        self.values = values
        self.map = GridMap(params_from_values(self.params))
        self.frame_id = str(values["frame_id"])
        self.local_frame = str(values["local_frame"])
        if tf_buffer is None:
            tf_buffer = Buffer()
            self._listener: TransformListener | None = TransformListener(tf_buffer, node)
        else:
            self._listener = None
        self.tf = tf_buffer
        self.updates = 0
        self.fusion_s = 0.0
        self.dropped = 0
        self.last_update: UpdateResult | None = None
        self._info: CameraInfo | None = None
        self._published_at = -1
        self._last_sensor: np.ndarray | None = None
        pose_type = int(values["pose_type"])
        if pose_type not in (POSE_STAMPED, ODOMETRY):
            msg = f"{prefix}.pose_type is {pose_type}: expected 1 (PoseStamped) or 2 (Odometry)"
            raise GridMapError(msg)
        pose_cls: type[Any] = Odometry if pose_type == ODOMETRY else PoseStamped
        pose_topic = str(values["odom_topic"] if pose_type == ODOMETRY else values["pose_topic"])
        if values["depth_topic"] and pose_topic:
            depth = message_filters.Subscriber(node, Image, str(values["depth_topic"]), 50)
            pose = message_filters.Subscriber(node, pose_cls, pose_topic, 100)
            self._sync = message_filters.ApproximateTime([depth, pose], 100)
            self._sync.register_callback(self._on_depth)
            if values["camera_info_topic"]:
                node.create_subscription(
                    CameraInfo, str(values["camera_info_topic"]), self._on_info, 5
                )
        if pose_topic:
            node.create_subscription(pose_cls, pose_topic, self._on_pose, 10)
        if values["cloud_topic"]:
            node.create_subscription(PointCloud2, str(values["cloud_topic"]), self._on_cloud, 10)
        self._occ_pub = node.create_publisher(PointCloud2, f"{prefix}/occupancy", 10)
        self._inf_pub = node.create_publisher(PointCloud2, f"{prefix}/occupancy_inflate", 10)
        period = float(values["vis_period"])
        if period > 0:
            node.create_timer(period, self.publish)

    # ------------------------------------------------------------------ helpers
    def _fail(self, text: str) -> None:
        self.dropped += 1
        self.node.get_logger().warning(
            f"grid map: {text} ({self.dropped} inputs dropped so far)",
            throttle_duration_sec=_DROP_LOG_PERIOD_S,
        )

    def _lookup(self, target: str, source: str, stamp_ns: int) -> np.ndarray | None:
        if not source or source == target:
            return np.eye(4)
        try:
            return self.tf.lookup_transform_matrix(target, source, stamp_ns)
        except ExtrapolationException:
            try:
                return self.tf.lookup_transform_matrix(target, source, 0)
            except TransformException as exc:
                self._fail(f"no transform {target} <- {source}: {exc}")
        except TransformException as exc:
            self._fail(f"no transform {target} <- {source}: {exc}")
        return None

    def _body_pose(self, msg: Any) -> tuple[np.ndarray, str] | None:
        """``(T_map_body, body frame)`` of an Odometry or PoseStamped message."""
        pose = msg.pose.pose if isinstance(msg, Odometry) else msg.pose
        try:
            t_frame_body = pose_to_matrix(pose)
        except (VisnavError, ValueError) as exc:
            self._fail(f"invalid pose: {exc}")
            return None
        t_map_frame = self._lookup(self.frame_id, msg.header.frame_id, time_to_ns(msg.header.stamp))
        if t_map_frame is None:
            return None
        child = msg.child_frame_id if isinstance(msg, Odometry) and msg.child_frame_id else ""
        return t_map_frame @ t_frame_body, child or self.local_frame

    def _intrinsics(self, image: Image) -> tuple[float, float, float, float] | None:
        v = self.values
        if min(float(v["fx"]), float(v["fy"])) > 0:
            return float(v["fx"]), float(v["fy"]), float(v["cx"]), float(v["cy"])
        info = self._info
        if info is None:
            self._fail(
                f"no camera_info on {self.node.resolve_topic_name(str(v['camera_info_topic']))} "
                "and no grid_map.fx/fy/cx/cy parameters; waiting"
            )
            return None
        if info.width and (info.width != image.width or info.height != image.height):
            self._fail(
                f"camera_info is {info.width}x{info.height} but the depth image is "
                f"{image.width}x{image.height}; set grid_map.fx/fy/cx/cy"
            )
            return None
        k = info.k
        return float(k[0]), float(k[4]), float(k[2]), float(k[5])

    # ------------------------------------------------------------------ callbacks
    def _on_info(self, msg: CameraInfo) -> None:
        self._info = msg

    def _on_pose(self, msg: Any) -> None:
        body = self._body_pose(msg)
        if body is not None:
            self._last_sensor = body[0][:3, 3].copy()

    def _on_depth(self, image: Image, pose_msg: Any) -> None:
        intrinsics = self._intrinsics(image)
        body = self._body_pose(pose_msg)
        if intrinsics is None or body is None:
            return
        t_map_body, body_frame = body
        t_body_cam = self._lookup(body_frame, image.header.frame_id, time_to_ns(image.header.stamp))
        if t_body_cam is None:
            return
        start = time.perf_counter()
        try:
            depth = image_to_numpy(image)
            result = self.map.update_from_depth(
                depth, intrinsics=intrinsics, T_world_camera=t_map_body @ t_body_cam
            )
        except (VisnavError, ValueError) as exc:
            self._fail(f"dropped a depth image: {exc}")
            return
        self._done(result, time.perf_counter() - start)

    def _on_cloud(self, msg: PointCloud2) -> None:
        frame = msg.header.frame_id
        try:
            pts = cloud_to_xyz(msg).astype(np.float64)
        except (VisnavError, ValueError) as exc:
            self._fail(f"dropped a cloud: {exc}")
            return
        if not frame or frame == self.frame_id:
            origin = self._last_sensor
            if origin is None:
                self._fail("a map-frame cloud arrived before any pose; waiting for a pose")
                return
        else:
            t_map_cloud = self._lookup(self.frame_id, frame, time_to_ns(msg.header.stamp))
            if t_map_cloud is None:
                return
            pts = pts @ t_map_cloud[:3, :3].T + t_map_cloud[:3, 3]
            origin = t_map_cloud[:3, 3].copy()
        start = time.perf_counter()
        result = self.map.update_from_points(pts, sensor_origin=origin)
        self._done(result, time.perf_counter() - start)

    def _done(self, result: UpdateResult | None, spent_s: float) -> None:
        if result is None:
            self._fail(
                "the sensor is outside the map; update skipped (enlarge grid_map.map_size_*)"
            )
            return
        self.updates += 1
        self.last_update = result
        self.fusion_s += spent_s
        if self.values["show_occ_time"]:
            self.node.get_logger().info(
                f"grid map: fusion {spent_s * 1e3:.2f} ms, mean "
                f"{self.fusion_s / self.updates * 1e3:.2f} ms over {self.updates} updates"
            )

    def publish(self) -> None:
        """Publish occupied and inflated cells to existing subscribers, when the map changed."""
        if self.map.update_count == self._published_at:
            return
        header = Header(stamp=self.node.get_clock().now().to_msg(), frame_id=self.frame_id)
        margin = int(self.values["local_map_margin"])
        trunc = float(self.values["visualization_truncate_height"])
        sent = False
        if self._occ_pub.get_subscription_count() > 0:
            cells = self.map.occupied_cells(margin=margin // 2, truncate_height=trunc)
            self._occ_pub.publish(xyz_to_cloud(cells, header=header))
            sent = True
        if self._inf_pub.get_subscription_count() > 0:
            cells = self.map.occupied_cells(inflated=True, margin=margin, truncate_height=trunc)
            self._inf_pub.publish(xyz_to_cloud(cells, header=header))
            sent = True
        if sent:
            self._published_at = self.map.update_count


class GridMapNode(Node):
    """A node that only maps (``grid_map`` parameters and topics as :class:`GridMapRos`).

    Args:
        name: Node name (default ``grid_map``).
        **node_kwargs: Passed to :class:`~visnav.graph.Node` (context, namespace, ...).
    """

    def __init__(self, name: str = "grid_map", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        self.grid = GridMapRos(self)
