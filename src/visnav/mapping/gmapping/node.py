"""``slam_gmapping``: laser SLAM with gmapping's particle filter, slam_gmapping's interface.

Topics (relative names, so namespaces and remappings apply):

* in: ``scan`` (``sensor_msgs/LaserScan``), ``/tf`` and ``/tf_static``
  (``odom_frame -> base_frame`` odometry and the base -> laser mounting);
* out: ``map`` (``nav_msgs/OccupancyGrid``) and ``map_metadata`` (``nav_msgs/MapMetaData``),
  both latched (transient local), rebuilt from the best particle at the first processed
  scan and then when a processed scan is more than ``map_update_interval`` seconds after
  the last rebuild; ``~/entropy`` (``std_msgs/Float64``, latched) with each rebuild;
  ``map_frame -> odom_frame`` on ``/tf`` every ``transform_publish_period`` seconds,
  stamped ahead by that period (slam_gmapping's ``tf_delay``), identity until the first
  scan is processed.

Service: ``dynamic_map`` (``nav_msgs/srv/GetMap``): the last published map (an empty
map before the first one).

Parameters: :class:`~visnav.mapping.gmapping.params.GmappingParams` and
:class:`~visnav.mapping.gmapping.params.GmappingNodeParams`, gmapping's names without a
prefix. The laser's pose in ``base_frame`` is looked up from TF once, at the first scan;
a laser mounted upside down (its z axis pointing down) is used with its beams mirrored,
as slam_gmapping does; a tilted laser is refused by name (gmapping ignores roll and
pitch and requires a planar mounting).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params
from visnav.graph.qos import qos_profile_latched, qos_profile_sensor_data
from visnav.mapping.costmap_ros import MAP_QOS
from visnav.mapping.gmapping.params import GmappingError, GmappingNodeParams, GmappingParams
from visnav.mapping.gmapping.particle_filter import GmappingFilter, GridMap, LaserGeometry
from visnav.msgs.serde import get_message_class
from visnav.msgs.srv import get_service_type
from visnav.msgs.time import ns_to_time, time_to_ns
from visnav.msgs.types import (
    Header,
    LaserScan,
    MapMetaData,
    OccupancyGrid,
    Point,
    Pose,
    Transform,
    TransformStamped,
    Vector3,
)
from visnav.tf.buffer import Buffer
from visnav.tf.errors import ExtrapolationException, TransformException
from visnav.tf.ros import TransformBroadcaster, TransformListener
from visnav.tf.transforms import quaternion_from_yaw
from visnav.tf.transforms import yaw_from_matrix as yaw_of

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["SlamGmappingNode", "laser_geometry"]

_NS = 1_000_000_000


def laser_geometry(
    T_base_laser: np.ndarray,  # noqa: N803
    scan: LaserScan,
    *,
    max_range: float = 0.0,
    usable_range: float = 0.0,
) -> LaserGeometry:
    """The laser as gmapping uses it: origin and beam directions in the base frame.

    Args:
        T_base_laser: 4x4 pose of the scan's frame in the base frame.
        scan: A scan of this laser (angles, range_max).
        max_range: ``maxRange``; 0: ``range_max - 0.01`` (slam_gmapping's default).
        usable_range: ``maxUrange``; 0: the max range.

    Raises:
        GmappingError: The laser is not mounted planar (its z axis is not +-z of the base).
    """
    R = np.asarray(T_base_laser, dtype=np.float64)[:3, :3]  # noqa: N806
    up = float(R[2, 2])
    if abs(abs(up) - 1.0) > 0.001:
        msg = (
            f"scan frame '{scan.header.frame_id}': the laser is tilted (its z axis has "
            f"z = {up:.5f} in the base frame); gmapping needs a planar laser, z = 1 or -1. "
            "Fix: mount the laser level, upright or upside down, in the URDF / static TF"
        )
        raise GmappingError(msg)
    n = len(scan.ranges)
    a = float(scan.angle_min) + float(scan.angle_increment) * np.arange(n)
    d = R[:2, :2] @ np.stack([np.cos(a), np.sin(a)])
    angles = np.arctan2(d[1], d[0])
    mr = max_range if max_range > 0 else float(scan.range_max) - 0.01
    ur = usable_range if usable_range > 0 else mr
    return LaserGeometry(
        x=float(T_base_laser[0, 3]),
        y=float(T_base_laser[1, 3]),
        angles=angles,
        max_range=mr,
        usable_range=ur,
    )


class SlamGmappingNode(Node):
    """slam_gmapping on the visnav graph (module docstring).

    Args:
        name: Node name (default ``slam_gmapping``).
        **node_kwargs: Passed to :class:`~visnav.graph.Node` (context, overrides, ...).
    """

    def __init__(self, name: str = "slam_gmapping", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        self.filter_params = declare_params(self, GmappingParams)
        p = self.params = declare_params(self, GmappingNodeParams)
        self.filter: GmappingFilter | None = None
        self.tf_buffer = Buffer()
        self.tf_listener = TransformListener(self.tf_buffer, self)
        self._tf = TransformBroadcaster(self)
        self._map_pub = self.create_publisher(OccupancyGrid, "map", MAP_QOS)
        self._meta_pub = self.create_publisher(MapMetaData, "map_metadata", MAP_QOS)
        self._float64 = get_message_class("std_msgs/msg/Float64")
        self._entropy_pub = self.create_publisher(self._float64, "~/entropy", qos_profile_latched)
        self.create_subscription(LaserScan, "scan", self._on_scan, qos_profile_sensor_data)
        self.create_service(
            get_service_type("nav_msgs/srv/GetMap"), "dynamic_map", self._on_get_map
        )
        self.map_to_odom: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.map: OccupancyGrid | None = None
        self.grid: GridMap | None = None
        self.scans_received = 0
        self.scans_processed = 0
        self.map_updates = 0
        self._last_map_ns: int | None = None
        self._pending: LaserScan | None = None
        self._refused = ""
        if p.transform_publish_period > 0:
            self.create_timer(p.transform_publish_period, self._publish_transform)

    # ---------------------------------------------------------------- scans
    def _on_scan(self, msg: LaserScan) -> None:
        self.scans_received += 1
        if self.scans_received % self.params.throttle_scans != 0:
            return
        pending, self._pending = self._pending, None
        if pending is not None:
            self._process(pending, retry=False)
        self._process(msg, retry=True)

    def _odom_pose(self, msg: LaserScan, *, retry: bool) -> tuple[float, float, float] | None:
        p = self.params
        stamp = time_to_ns(msg.header.stamp)
        try:
            T = self.tf_buffer.lookup_transform_matrix(p.odom_frame, p.base_frame, stamp)  # noqa: N806
        except ExtrapolationException as exc:
            if retry and exc.requested_ns > exc.latest_ns:  # odometry not here yet
                self._pending = msg
                return None
            self._warn_no_odom(stamp, exc)
            return None
        except TransformException as exc:
            self._warn_no_odom(stamp, exc)
            return None
        return float(T[0, 3]), float(T[1, 3]), yaw_of(T)

    def _warn_no_odom(self, stamp: int, exc: Exception) -> None:
        p = self.params
        self.get_logger().warning(
            f"scan at {stamp / _NS:.3f} s dropped: no odometry '{p.odom_frame}' -> "
            f"'{p.base_frame}' at its time: {exc}",
            throttle_duration_sec=5.0,
        )

    def _start(self, msg: LaserScan, odom: tuple[float, float, float]) -> bool:
        p, fp = self.params, self.filter_params
        frame = msg.header.frame_id
        try:
            T = self.tf_buffer.lookup_transform_matrix(p.base_frame, frame, 0)  # noqa: N806
        except TransformException as exc:
            self.get_logger().warning(
                f"scan frame '{frame}' has no transform to '{p.base_frame}' yet: {exc}",
                throttle_duration_sec=5.0,
            )
            return False
        try:
            laser = laser_geometry(T, msg, max_range=fp.maxRange, usable_range=fp.maxUrange)
            self.filter = GmappingFilter(fp, laser, initial_pose=odom)
        except GmappingError as exc:
            if str(exc) != self._refused:
                self._refused = str(exc)
                self.get_logger().error(f"scan: {exc}")
            return False
        side = "upwards" if T[2, 2] > 0 else "upside down"
        self.get_logger().info(
            f"laser '{frame}' mounted {side}, {len(msg.ranges)} beams, maxRange "
            f"{laser.max_range:g} m, maxUrange {laser.usable_range:g} m, {fp.particles} particles"
        )
        return True

    def _process(self, msg: LaserScan, *, retry: bool) -> None:
        odom = self._odom_pose(msg, retry=retry)
        if odom is None:
            return
        if self.filter is None and not self._start(msg, odom):
            return
        f = self.filter
        if f is None:
            return
        stamp = time_to_ns(msg.header.stamp)
        ranges = np.asarray(msg.ranges, dtype=np.float64)
        # slam_gmapping: a range below range_min reads as range_max (no return)
        ranges = np.where(ranges < float(msg.range_min), float(msg.range_max), ranges)
        try:
            processed = f.process_scan(odom, ranges, stamp / _NS)
        except GmappingError as exc:
            self.get_logger().error(f"scan: {exc}", throttle_duration_sec=5.0)
            return
        if not processed:
            return
        self.scans_processed += 1
        self.map_to_odom = f.map_to_odom()
        interval = int(self.params.map_update_interval * _NS)
        if self._last_map_ns is None or stamp - self._last_map_ns > interval:
            self.update_map()
            self._last_map_ns = stamp

    # ---------------------------------------------------------------- outputs
    def update_map(self) -> None:
        """Rebuild the map from the best particle and publish it (slam_gmapping's updateMap)."""
        f = self.filter
        if f is None:
            return
        grid = f.build_map()
        self.grid = grid
        h, w = grid.data.shape
        stamp = ns_to_time(self.get_clock().now_ns())
        info = MapMetaData(
            map_load_time=stamp,
            resolution=float(grid.resolution),
            width=int(w),
            height=int(h),
            origin=Pose(
                position=Point(x=float(grid.origin[0]), y=float(grid.origin[1]), z=0.0),
                orientation=quaternion_from_yaw(0.0),
            ),
        )
        self.map = OccupancyGrid(
            header=Header(stamp=stamp, frame_id=self.params.map_frame),
            info=info,
            data=np.ascontiguousarray(grid.data).reshape(-1).copy(),
        )
        self._map_pub.publish(self.map)
        self._meta_pub.publish(info)
        self._entropy_pub.publish(self._float64(data=f.entropy()))
        self.map_updates += 1

    def _publish_transform(self) -> None:
        p = self.params
        x, y, yaw = self.map_to_odom
        t = self.get_clock().now_ns() + int(p.transform_publish_period * _NS)
        self._tf.send_transform(
            TransformStamped(
                header=Header(stamp=ns_to_time(t), frame_id=p.map_frame),
                child_frame_id=p.odom_frame,
                transform=Transform(
                    translation=Vector3(x=x, y=y, z=0.0), rotation=quaternion_from_yaw(yaw)
                ),
            )
        )

    def _on_get_map(self, request: object, response: Any) -> Any:
        """``nav_msgs/GetMap``: the last published map."""
        del request
        if self.map is not None:
            response.map = self.map
        return response

    @property
    def pose(self) -> tuple[float, float, float] | None:
        """The best particle's base pose in the map frame (None before the first scan)."""
        return None if self.filter is None else self.filter.best_pose
