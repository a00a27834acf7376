"""A layered costmap wired to a node: costmap_2d's ``Costmap2DROS``.

:class:`CostmapROS` declares its parameters under a prefix on a node you give it
(``global_costmap.resolution``, ``local_costmap.obstacle_layer.scan.topic``, ...),
builds the layers, subscribes the map and the observation sources, updates at
``update_frequency`` and publishes ``<prefix>/costmap`` (``nav_msgs/OccupancyGrid``,
costmap_2d's cost translation) at ``publish_frequency``.

Parameters (costmap_2d's names and defaults; nav2's plugin list style)::

    global_frame "map"           robot_base_frame "base_link"   transform_tolerance 0.3
    update_frequency 5.0         publish_frequency 0.0 (off)    rolling_window false
    width 10  height 10 (m)      resolution 0.05                origin_x 0.0  origin_y 0.0
    track_unknown_space false    footprint "[]"                 robot_radius 0.46
    footprint_padding 0.01       plugins [static_layer, obstacle_layer, inflation_layer]
    <layer>.plugin               StaticLayer | ObstacleLayer | InflationLayer (from the name)
    static_layer: map_topic "map", lethal_cost_threshold 100, unknown_cost_value -1,
        trinary_costmap true, use_maximum false, first_map_only false, enabled true
    obstacle_layer: observation_sources "" (space separated), max_obstacle_height 2.0,
        combination_method 1, footprint_clearing_enabled true, enabled true; per source
        <layer>.<source>.topic (source name), data_type "PointCloud2" | "LaserScan",
        sensor_frame "", observation_persistence 0.0, expected_update_rate 0.0,
        min_obstacle_height 0.0, max_obstacle_height 2.0, obstacle_range 2.5,
        raytrace_range 3.0, inf_is_valid false, clearing false, marking true
    inflation_layer: inflation_radius 0.55, cost_scaling_factor 10.0,
        inflate_unknown false, enabled true

The parameters are the dataclasses of :mod:`visnav.mapping.costmap_layers`, and layer
types are looked up in its registry :data:`~visnav.mapping.costmap_layers.COSTMAP_LAYERS`.
A caller (the navigator) may pass other defaults; explicit parameter overrides win.
Sensor topics are subscribed best-effort (``qos_profile_sensor_data``), the map
reliable and transient local (it is latched).

A static layer whose map frame is not the costmap's global frame (a ``map`` in the
rolling local costmap in ``odom``) is placed through TF at every update, as costmap_2d's
rolling static layer looks ``map -> global_frame`` up in each ``updateCosts``: a
localizer (SLAM, AMCL) moves ``map -> odom`` all the time. A map that arrives before its
transform exists (map_server latches it once, before AMCL publishes) is kept and placed
at the first update that has the transform.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from visnav.graph.node import Node, Publisher
from visnav.graph.param_dataclass import declare_params
from visnav.graph.qos import qos_profile_latched, qos_profile_sensor_data
from visnav.mapping.costmap_2d import costmap_to_occupancy_grid
from visnav.mapping.costmap_layers import CostmapParams, layer_defaults, make_layer
from visnav.mapping.errors import CostmapError
from visnav.mapping.footprint import Footprint
from visnav.mapping.layered_costmap import LayeredCostmap
from visnav.mapping.observation import ObservationSource
from visnav.mapping.obstacle_layer import ObstacleLayer
from visnav.mapping.static_layer import StaticLayer
from visnav.msgs.types import LaserScan, OccupancyGrid, PointCloud2
from visnav.tf.buffer import Buffer
from visnav.tf.errors import TransformException
from visnav.tf.transforms import yaw_from_matrix, yaw_from_quaternion

__all__ = ["MAP_QOS", "CostmapROS"]

MAP_QOS = qos_profile_latched
"""map_server's ``map`` QoS (latched: depth 1, reliable, transient local)."""

_NS = 1_000_000_000


class CostmapROS:
    """A :class:`LayeredCostmap` configured from, and publishing through, a node.

    Args:
        node: the node that owns parameters, subscriptions and timers.
        name: parameter prefix and topic namespace (``global_costmap``).
        tf: the transform buffer (filled by the node's listener).
        defaults: parameter defaults replacing costmap_2d's (flat dotted names relative
            to ``name``, e.g. ``{"rolling_window": True, "obstacle_layer.scan.clearing": True}``).
        start_timers: create the update and publish timers (False: call :meth:`update`).
    """

    def __init__(
        self,
        node: Node,
        name: str,
        tf: Buffer,
        *,
        defaults: Mapping[str, Any] | None = None,
        start_timers: bool = True,
    ) -> None:
        self.node = node
        self.name = name
        self.tf = tf
        self._defaults = dict(defaults or {})
        self.pose_error = ""
        self.params = declare_params(
            node, CostmapParams, prefix=f"{name}.", defaults=layer_defaults(self._defaults, "")
        )
        c = self.params
        self.global_frame = c.global_frame
        self.robot_base_frame = c.robot_base_frame
        self.transform_tolerance = c.transform_tolerance
        self.update_frequency = c.update_frequency
        self.publish_frequency = c.publish_frequency
        footprint = Footprint.from_params(
            footprint=c.footprint,
            robot_radius=c.robot_radius,
            footprint_padding=c.footprint_padding,
        )
        self.layered = LayeredCostmap(
            self.global_frame,
            width=c.width,
            height=c.height,
            resolution=c.resolution,
            origin_x=c.origin_x,
            origin_y=c.origin_y,
            rolling_window=c.rolling_window,
            track_unknown_space=c.track_unknown_space,
            footprint=footprint,
        )
        for plugin in c.plugins:
            self.layered.add_layer(make_layer(self, str(plugin), self._defaults))
        self._maps: dict[str, tuple[StaticLayer, OccupancyGrid | None, str]] = {}
        """Static layers by name: the layer, a map waiting for its transform, its frame."""
        self._pub: Publisher[OccupancyGrid] | None = None
        if self.publish_frequency > 0:
            self._pub = node.create_publisher(OccupancyGrid, f"~/{name}/costmap", 1)
        if start_timers:
            if self.update_frequency > 0:
                node.create_timer(1.0 / self.update_frequency, self.update)
            if self._pub is not None:
                node.create_timer(1.0 / self.publish_frequency, self.publish)

    # ------------------------------------------------------------------ layer wiring
    def subscribe_map(self, layer: StaticLayer, topic: str) -> None:
        """Feed ``layer`` from the (latched) map ``topic``; called by the layer's factory."""
        self.node.create_subscription(
            OccupancyGrid, topic, lambda m, la=layer: self._on_map(la, m), MAP_QOS
        )

    def subscribe_observations(
        self, layer: ObstacleLayer, sources: Sequence[ObservationSource]
    ) -> None:
        """Feed ``layer`` from its sources' topics (sensor data QoS); called by its factory."""
        for s in sources:
            msg_type: type[Any] = LaserScan if s.data_type == "LaserScan" else PointCloud2
            self.node.create_subscription(
                msg_type,
                s.resolved_topic,
                lambda m, la=layer, n=s.name: self._on_observation(la, n, m),
                qos_profile_sensor_data,
            )

    # ------------------------------------------------------------------ callbacks
    def _on_map(self, layer: StaticLayer, msg: OccupancyGrid) -> None:
        frame = msg.header.frame_id
        self._maps[layer.name] = (layer, msg, frame)
        self._place_map(layer.name)

    def _map_transform(self, frame: str) -> tuple[float, float, float] | None:
        """Pose ``(x, y, yaw)`` of ``frame`` in the global frame (None: no transform yet)."""
        try:
            T = self.tf.lookup_transform_matrix(self.global_frame, frame, 0)  # noqa: N806
        except TransformException as exc:
            self.node.get_logger().warning(
                f"{self.name}: map in frame '{frame}' has no transform to "
                f"'{self.global_frame}' yet ({exc}); its static layer waits for it",
                throttle_duration_sec=5.0,
            )
            return None
        return float(T[0, 3]), float(T[1, 3]), yaw_from_matrix(T)

    def _place_map(self, name: str) -> None:
        """Hand a waiting map to its layer, or move a placed one to the current transform."""
        layer, msg, frame = self._maps[name]
        transform = None
        if frame and frame != self.global_frame:
            transform = self._map_transform(frame)
            if transform is None:
                return
        if msg is None:
            if transform is not None:
                layer.set_map_transform(*transform)
            return
        try:
            layer.set_map(msg, transform=transform)
        except CostmapError as exc:
            self.node.get_logger().error(str(exc))
        self._maps[name] = (layer, None, frame)

    def _on_observation(
        self, layer: ObstacleLayer, source: str, msg: LaserScan | PointCloud2
    ) -> None:
        now = self.node.get_clock().now_ns()
        if isinstance(msg, LaserScan):
            layer.add_scan(source, msg, now)
        else:
            layer.add_cloud(source, msg, now)

    # ------------------------------------------------------------------ state
    def get_robot_pose(self) -> tuple[float, float, float] | None:
        """The robot's ``(x, y, yaw)`` in the global frame, or None (``pose_error`` says why)."""
        try:
            ts = self.tf.lookup_transform(self.global_frame, self.robot_base_frame, 0)
        except TransformException as exc:
            self.pose_error = (
                f"{self.name}: no transform from '{self.robot_base_frame}' to "
                f"'{self.global_frame}': {exc}"
            )
            return None
        now = self.node.get_clock().now_ns()
        stamp = ts.header.stamp.sec * _NS + ts.header.stamp.nanosec
        if stamp and now - stamp > self.transform_tolerance * _NS:
            self.pose_error = (
                f"{self.name}: the transform from '{self.robot_base_frame}' to "
                f"'{self.global_frame}' is {(now - stamp) / _NS:.3f} s old "
                f"(transform_tolerance {self.transform_tolerance:.3f} s)"
            )
            return None
        t = ts.transform
        q = t.rotation
        yaw = yaw_from_quaternion(q)
        self.pose_error = ""
        return float(t.translation.x), float(t.translation.y), yaw

    def update(self) -> None:
        """One update cycle at the robot's pose (skipped, with a warning, without a pose)."""
        pose = self.get_robot_pose()
        if pose is None:
            return
        for name in self._maps:
            self._place_map(name)
        self.layered.update_map(*pose, now_ns=self.node.get_clock().now_ns())

    def publish(self) -> None:
        """Publish the costmap as ``nav_msgs/OccupancyGrid``."""
        if self._pub is not None and self.layered.initialized:
            now = self.node.get_clock().now_ns()
            self._pub.publish(
                costmap_to_occupancy_grid(self.layered.costmap, self.global_frame, now)
            )

    def is_current(self) -> bool:
        """Whether every layer's data are current (see ``LayeredCostmap.is_current``)."""
        return self.layered.is_current(self.node.get_clock().now_ns())

    def clear(self) -> None:
        """Reset every layer (the ``clear_costmaps`` service)."""
        self.layered.reset_layers()
        self.layered.request_full_update()
