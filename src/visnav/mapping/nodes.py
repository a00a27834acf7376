"""Graph nodes of the mapping algorithms.

* :class:`CostmapNode` (costmap_2d's ``costmap_2d_node``): one :class:`CostmapROS`
  named ``costmap``; parameters ``costmap.*`` (see :mod:`visnav.mapping.costmap_ros`),
  publishes ``~/costmap/costmap``.
* :class:`MapperNode` (a gmapping-shaped log-odds mapper with known poses): subscribes
  ``scan`` (LaserScan), looks the scan frame up in ``map_frame`` through TF at the scan
  stamp (the pose may come from odometry, ground truth or SLAM), and publishes ``map``
  (``nav_msgs/OccupancyGrid``, reliable, transient local) and ``map_metadata`` every
  ``map_update_interval`` seconds. Parameters: ``map_frame`` ("map"), ``resolution``
  (0.05), ``width`` / ``height`` (20 m), ``origin_x`` / ``origin_y`` (-10), ``grow``
  (true), ``grow_margin`` (2.0), ``prob_hit`` (0.7), ``prob_miss`` (0.4), ``clamp_min``
  (0.12), ``clamp_max`` (0.97), ``occupied_thresh`` (0.65), ``free_thresh`` (0.196),
  ``free_on_max_range`` (true), ``max_free_range`` (5.0), ``trinary`` (true),
  ``map_update_interval`` (1.0 s; gmapping's 5.0 is slow for exploring),
  ``max_usable_range`` (gmapping's ``maxUrange``: beams cropped to it; 0: not cropped),
  ``far_clear_ratio`` (a cropped return clears this share of its range instead; 0: only up
  to ``max_usable_range``, as gmapping),
  ``linear_update`` / ``angular_update`` (gmapping's ``linearUpdate`` /
  ``angularUpdate``: a scan is integrated after the sensor moved this far or turned this
  much; 0 / 0, every scan, unlike gmapping's 1.0 m / 0.5 rad, which suit a particle
  filter's cost, not a known-pose grid's), ``temporal_update`` (gmapping's
  ``temporalUpdate``: ... or after this many seconds; -1: not by time).

  With ``trajectory_topic`` (a ``nav_msgs/Path`` of ``base_frame`` in the map, e.g.
  the SLAM node's ``slam/path``) the integrated scans are kept with their
  ``odom_frame`` poses, and when a new path moves any of them by more than
  ``rebuild_distance`` (m, at 3 m range) from where the previous path put it (a loop
  closure corrected the past) the grid is rebuilt from all of them at their corrected
  poses, as RTAB-Map assembles its grid from its optimised graph
  (:mod:`visnav.mapping.scan_history`). The rebuild count is in ``rebuilds``.

A scan whose transform is not available yet waits (up to 5 scans) and is retried
with the next scan; one whose transform cannot be found is dropped with one log line
per distinct reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.graph.qos import qos_profile_sensor_data
from visnav.mapping.costmap_ros import MAP_QOS, CostmapROS
from visnav.mapping.occupancy import OccupancyMapper
from visnav.mapping.scan_history import PathProbe, ScanHistory, pose_displacement
from visnav.msgs.time import time_to_ns
from visnav.msgs.types import LaserScan, MapMetaData, OccupancyGrid, Path
from visnav.tf.buffer import Buffer
from visnav.tf.errors import ExtrapolationException, TransformException
from visnav.tf.ros import TransformListener

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["STARTUP_GRACE_S", "CostmapNode", "MapperNode", "MapperParams"]

_DROP_LOG_PERIOD_S = 5.0  # at most one "dropped a scan" warning per 5 s
STARTUP_GRACE_S = 10.0
"""Seconds (scan stamps) after the first scan during which a missing transform is expected
until one scan was mapped (the map frame appears once localisation starts): such dropped
scans are logged at debug level, the others as warnings."""
_REBUILD_REACH_M = 3.0  # a heading change counts by how far it moves a wall 3 m away


@dataclass(frozen=True)
class MapperParams:
    """The mapper's parameters (gmapping's names where it has them)."""

    map_frame: str = param("map", description="frame of the map")
    trinary: bool = param(True, description="publish free / occupied / unknown only")
    resolution: float = param(0.05, description="cell size (m)")
    width: float = param(20.0, description="initial width (m)")
    height: float = param(20.0, description="initial height (m)")
    origin_x: float = param(-10.0, description="initial origin x (m)")
    origin_y: float = param(-10.0, description="initial origin y (m)")
    grow: bool = param(True, description="grow the map when scans leave it")
    grow_margin: float = param(2.0, description="margin added when growing (m)")
    prob_hit: float = param(0.7, description="hit probability", range=(0.0, 1.0))
    prob_miss: float = param(0.4, description="miss probability", range=(0.0, 1.0))
    clamp_min: float = param(0.12, description="lower clamp probability", range=(0.0, 1.0))
    clamp_max: float = param(0.97, description="upper clamp probability", range=(0.0, 1.0))
    occupied_thresh: float = param(0.65, description="occupied from", range=(0.0, 1.0))
    free_thresh: float = param(0.196, description="free below", range=(0.0, 1.0))
    free_on_max_range: bool = param(True, description="max-range beams clear space")
    max_free_range: float = param(5.0, description="longest clearing ray (m)")
    map_update_interval: float = param(1.0, description="map publishing period (s)")
    max_usable_range: float = param(0.0, description="beams cropped to this range (m; 0: none)")
    far_clear_ratio: float = param(0.0, description="share of a cropped return's range cleared")
    linear_update: float = param(0.0, description="integrate a scan after moving (m; 0: all)")
    angular_update: float = param(0.0, description="integrate a scan after turning (rad; 0: all)")
    temporal_update: float = param(-1.0, description="integrate a scan every N s (<= 0: off)")
    trajectory_topic: str = param("", description="nav_msgs/Path to rebuild on ('': never)")
    base_frame: str = param("base_footprint", description="frame of the trajectory's poses")
    odom_frame: str = param("odom", description="continuous frame the kept scans are held in")
    rebuild_distance: float = param(0.025, description="rebuild when a scan moves this far (m)")


class CostmapNode(Node):
    """costmap_2d_node: a standalone costmap.

    Args:
        name: node name (default ``costmap_2d``).
        **node_kwargs: passed to :class:`~visnav.graph.Node` (context, namespace, ...).
    """

    def __init__(self, name: str = "costmap_2d", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        self.tf_buffer = Buffer()
        self.tf_listener = TransformListener(self.tf_buffer, self)
        self.costmap = CostmapROS(self, "costmap", self.tf_buffer)


class MapperNode(Node):
    """Occupancy grid mapping from scans with poses from TF.

    Args:
        name: node name (default ``mapper``).
        **node_kwargs: passed to :class:`~visnav.graph.Node`.
    """

    def __init__(self, name: str = "mapper", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        p = self.params = declare_params(self, MapperParams)
        self.map_frame = p.map_frame
        self.trinary = p.trinary
        self.mapper = OccupancyMapper(
            resolution=p.resolution,
            width=p.width,
            height=p.height,
            origin_x=p.origin_x,
            origin_y=p.origin_y,
            grow=p.grow,
            grow_margin=p.grow_margin,
            prob_hit=p.prob_hit,
            prob_miss=p.prob_miss,
            clamp_min=p.clamp_min,
            clamp_max=p.clamp_max,
            occupied_thresh=p.occupied_thresh,
            free_thresh=p.free_thresh,
            free_on_max_range=p.free_on_max_range,
            max_free_range=p.max_free_range,
            max_usable_range=p.max_usable_range if p.max_usable_range > 0 else math.inf,
            far_clear_ratio=p.far_clear_ratio,
        )
        self._keep = bool(p.trajectory_topic)
        self._gate = self._keep or p.linear_update > 0 or p.angular_update > 0
        self.history = ScanHistory(
            p.linear_update, p.angular_update, keep=self._keep, temporal_update=p.temporal_update
        )
        self.rebuilds = 0
        self._path_poses = np.zeros((0, 4, 4))
        self._probe = PathProbe()
        if self._keep:
            self.create_subscription(Path, p.trajectory_topic, self._on_path, 1)
        interval = p.map_update_interval
        self.tf_buffer = Buffer()
        self.tf_listener = TransformListener(self.tf_buffer, self)
        self._map_pub = self.create_publisher(OccupancyGrid, "map", MAP_QOS)
        self._meta_pub = self.create_publisher(MapMetaData, "map_metadata", MAP_QOS)
        self.create_subscription(LaserScan, "scan", self._on_scan, qos_profile_sensor_data)
        self.create_timer(interval, self.publish_map)
        self._pending: list[LaserScan] = []
        self.dropped = 0
        self._first_scan_ns: int | None = None

    def _integrate(self, msg: LaserScan) -> bool:
        stamp = time_to_ns(msg.header.stamp)
        try:
            T = self.tf_buffer.lookup_transform_matrix(self.map_frame, msg.header.frame_id, stamp)  # noqa: N806
        except ExtrapolationException as exc:
            if exc.requested_ns > exc.latest_ns:
                return False
            return self._drop(msg, exc)
        except TransformException as exc:
            return self._drop(msg, exc)
        if self._gate:
            p = self.params
            frame = msg.header.frame_id
            try:
                t_odom = self.tf_buffer.lookup_transform_matrix(p.odom_frame, frame, stamp)
                if not self.history.wants(t_odom, stamp):
                    return True
                # the base pose only serves a rebuild: looked up only for scans that are kept
                t_base = (
                    self.tf_buffer.lookup_transform_matrix(p.base_frame, frame, stamp)
                    if self._keep
                    else None
                )
            except TransformException as exc:
                return self._drop(msg, exc)
            self.history.add(msg, t_odom, t_base)
        self.mapper.integrate_scan(msg, T)
        return True

    def _on_path(self, msg: Path) -> None:
        """Rebuild the grid when the trajectory's past moved a kept scan (module docstring)."""
        if self._probe.same_past(msg):  # only appended: nothing to rebuild
            return
        self._probe = PathProbe.of(msg)
        poses = self.history.poses_from_path(msg)
        if poses is None:
            return
        before, self._path_poses = self._path_poses, poses
        n = min(len(before), len(poses))
        if n == 0:
            return
        moved = pose_displacement(poses[:n], before[:n], _REBUILD_REACH_M)
        if float(moved.max()) <= self.params.rebuild_distance:
            return
        self.mapper.clear()
        for scan, pose in zip(self.history.scans, poses, strict=True):
            self.mapper.integrate_scan(scan, pose)
        self.rebuilds += 1
        self.get_logger().info(
            f"map rebuilt on the corrected trajectory: {len(poses)} scans, "
            f"largest move {float(moved.max()):.3f} m (rebuild {self.rebuilds})"
        )

    def _drop(self, msg: LaserScan, exc: TransformException) -> bool:
        self.dropped += 1
        frame = msg.header.frame_id
        text = f"dropped a scan: no transform from '{frame}' to '{self.map_frame}': {exc}"
        first = self._first_scan_ns
        early = first is not None and time_to_ns(msg.header.stamp) - first < STARTUP_GRACE_S * 1e9
        if early and self.mapper.scans == 0:  # the map frame has never been there yet
            self.get_logger().debug(f"{text} (expected while the stack starts)")
            return True
        self.get_logger().warning(text, throttle_duration_sec=_DROP_LOG_PERIOD_S)
        return True

    def _on_scan(self, msg: LaserScan) -> None:
        if self._first_scan_ns is None:
            self._first_scan_ns = time_to_ns(msg.header.stamp)
        self._pending.append(msg)
        while self._pending and self._integrate(self._pending[0]):
            self._pending.pop(0)
        if len(self._pending) > 5:
            self._pending.pop(0)
            self.dropped += 1

    def publish_map(self) -> None:
        """Publish ``map`` and ``map_metadata`` (after at least one scan)."""
        if self.mapper.scans == 0:
            return
        grid = self.mapper.to_occupancy_grid(
            self.map_frame, self.get_clock().now_ns(), trinary=self.trinary
        )
        self._map_pub.publish(grid)
        self._meta_pub.publish(grid.info)
