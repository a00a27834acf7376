"""``amcl``: localise a robot in a saved map from its laser scans (nav2_amcl's node).

Topics (relative names, so namespaces and remappings apply):

* in: ``map`` (``nav_msgs/OccupancyGrid``, latched, from map_server), ``scan``
  (``sensor_msgs/LaserScan``), ``initialpose`` (``geometry_msgs/PoseWithCovarianceStamped``
  in the global frame, RViz's "2D Pose Estimate"), ``/tf`` and ``/tf_static``
  (``odom -> base_frame_id`` and the base -> laser transform);
* out: ``map -> odom`` on ``/tf`` (stamped with the scan's time plus
  ``transform_tolerance``, at every scan), ``amcl_pose``
  (``geometry_msgs/PoseWithCovarianceStamped``, latched, after every filter update),
  ``particlecloud`` (``geometry_msgs/PoseArray``, as ROS 1 amcl; nav2 uses its own
  ``nav2_msgs/ParticleCloud``), ``~/status`` (``std_msgs/String``, latched: the
  :class:`~visnav.mapping.amcl.LocalizationStatus` state and reason).

Parameters: :class:`~visnav.mapping.amcl.AmclParams` (the filter's, nav2's names and
defaults), :class:`AmclNodeParams` (frames, topics, ``transform_tolerance``,
``tf_broadcast``, ``set_initial_pose``, ``first_map_only``) and ``initial_pose.x``,
``initial_pose.y``, ``initial_pose.z``, ``initial_pose.yaw`` (nav2's). Without
``set_initial_pose`` the node waits for ``initialpose`` (nav2's behaviour; ROS 1 amcl
starts at ``(0, 0, 0)``).

Where visnav differs: ``map -> odom`` is published only while the filter is localised
(the scan fits the map at the estimate; see :mod:`visnav.mapping.amcl`), so a robot
started outside its map, or lost, stops instead of driving on a wrong pose; the reason
is logged as an error and latched on ``~/status``.

Services (``std_srvs/srv/Empty``, relative names as ROS 1 amcl's): ``global_localization``
(nav2 also: ``reinitialize_global_localization``) spreads the particles over the map's free
space (:meth:`AmclNode.global_localization`); ``request_nomotion_update`` makes the next
scan update the filter although the robot did not move (amcl's ``m_force_update``: the
update runs when that scan arrives, not in the call). Before a map has arrived both only
log a warning (amcl answers them without effect too).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.graph.qos import qos_profile_latched, qos_profile_sensor_data
from visnav.mapping.amcl import Amcl, AmclParams
from visnav.mapping.amcl_models import select_beams
from visnav.mapping.costmap_ros import MAP_QOS
from visnav.mapping.likelihood_field import LikelihoodField, LikelihoodFieldError
from visnav.msgs.serde import get_message_class
from visnav.msgs.srv import get_service_type
from visnav.msgs.time import ns_to_time, time_to_ns
from visnav.msgs.types import (
    Header,
    LaserScan,
    OccupancyGrid,
    Point,
    Pose,
    PoseWithCovariance,
    PoseWithCovarianceStamped,
    String,
    Transform,
    TransformStamped,
    Vector3,
)
from visnav.tf.buffer import Buffer
from visnav.tf.errors import ExtrapolationException, InvalidArgumentException, TransformException
from visnav.tf.initial_pose import InitialPoseParams
from visnav.tf.ros import TransformBroadcaster, TransformListener
from visnav.tf.transforms import quaternion_from_yaw, yaw_from_quaternion
from visnav.tf.transforms import yaw_from_matrix as yaw_of

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["AmclNode", "AmclNodeParams"]

_NS = 1_000_000_000


@dataclass(frozen=True)
class AmclNodeParams:
    """nav2_amcl's frame, topic and transform parameters."""

    global_frame_id: str = param("map", description="map frame", read_only=True)
    odom_frame_id: str = param("odom", description="odometry frame", read_only=True)
    base_frame_id: str = param("base_footprint", description="robot base frame", read_only=True)
    scan_topic: str = param("scan", description="laser scan topic", read_only=True)
    map_topic: str = param("map", description="map topic", read_only=True)
    transform_tolerance: float = param(
        1.0, description="map -> odom is post-dated by this (s)", range=(0.0, 100.0)
    )
    tf_broadcast: bool = param(True, description="publish map -> odom")
    set_initial_pose: bool = param(False, description="start at initial_pose.*")
    first_map_only: bool = param(False, description="ignore maps after the first")


class AmclNode(Node):
    """nav2_amcl on the visnav graph (module docstring).

    Args:
        name: Node name (default ``amcl``).
        **node_kwargs: Passed to :class:`~visnav.graph.Node` (context, overrides, ...).
    """

    def __init__(self, name: str = "amcl", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        self.filter_params = declare_params(self, AmclParams)
        p = self.params = declare_params(self, AmclNodeParams)
        self.initial = declare_params(self, InitialPoseParams, prefix="initial_pose.")
        self.filter: Amcl | None = None
        self.tf_buffer = Buffer()
        self.tf_listener = TransformListener(self.tf_buffer, self)
        self._tf = TransformBroadcaster(self)
        self._pose_pub = self.create_publisher(
            PoseWithCovarianceStamped, "amcl_pose", qos_profile_latched
        )
        self._pose_array = get_message_class("geometry_msgs/msg/PoseArray")
        self._cloud_pub = self.create_publisher(self._pose_array, "particlecloud", 1)
        self._status_pub = self.create_publisher(String, "~/status", qos_profile_latched)
        self.create_subscription(OccupancyGrid, p.map_topic, self._on_map, MAP_QOS)
        self.create_subscription(LaserScan, p.scan_topic, self._on_scan, qos_profile_sensor_data)
        self.create_subscription(PoseWithCovarianceStamped, "initialpose", self._on_initial_pose, 1)
        self._lasers: dict[str, tuple[float, float, float]] = {}
        self._pending_scan: LaserScan | None = None
        self._pending_pose: tuple[float, float, float, tuple[float, float, float] | None] | None
        self._pending_pose = None
        if p.set_initial_pose:
            self._pending_pose = (self.initial.x, self.initial.y, self.initial.yaw, None)
        self._last_status = ""
        self.updates = 0
        empty = get_service_type("std_srvs/srv/Empty")
        self.create_service(empty, "global_localization", self._on_global_localization)
        self.create_service(
            empty, "reinitialize_global_localization", self._on_global_localization
        )  # nav2's name
        self.create_service(empty, "request_nomotion_update", self._on_nomotion_update)

    # ------------------------------------------------------------------ inputs
    def _on_map(self, msg: OccupancyGrid) -> None:
        if self.filter is not None and self.params.first_map_only:
            return
        try:
            field = LikelihoodField.from_msg(
                msg, max_dist=self.filter_params.laser_likelihood_max_dist
            )
        except LikelihoodFieldError as exc:
            self.get_logger().error(f"{self.params.map_topic}: {exc}")
            return
        if self.filter is None:
            self.filter = Amcl(field, self.filter_params)
        else:
            self.filter.set_map(field)
        self.get_logger().info(
            f"map {field.width} x {field.height} cells at {field.resolution:g} m, "
            f"{field.free_count} free"
        )
        if self._pending_pose is not None:
            self._apply_initial_pose(*self._pending_pose)
            self._pending_pose = None

    def _on_initial_pose(self, msg: PoseWithCovarianceStamped) -> None:
        frame = msg.header.frame_id or self.params.global_frame_id
        pose = msg.pose.pose
        try:
            yaw = yaw_from_quaternion(pose.orientation)
        except InvalidArgumentException as exc:
            self.get_logger().error(
                f"initialpose: pose.pose.orientation: {exc}; expected a unit quaternion "
                "(x, y, z, w). Fix: send a rotation, e.g. w = 1 for heading 0; pose ignored"
            )
            return
        x, y = float(pose.position.x), float(pose.position.y)
        if frame != self.params.global_frame_id:
            try:
                T = self.tf_buffer.lookup_transform_matrix(self.params.global_frame_id, frame, 0)  # noqa: N806
            except TransformException as exc:
                self.get_logger().error(
                    f"initialpose: frame '{frame}' has no transform to "
                    f"'{self.params.global_frame_id}' ({exc}); expected a pose in "
                    f"'{self.params.global_frame_id}'. Fix: set header.frame_id"
                )
                return
            c, s = float(T[0, 0]), float(T[1, 0])
            x, y = float(T[0, 3]) + c * x - s * y, float(T[1, 3]) + s * x + c * y
            yaw += yaw_of(T)
        cov = np.asarray(msg.pose.covariance, dtype=np.float64)
        variances = (float(cov[0]), float(cov[7]), float(cov[35]))
        given = variances if all(v > 0 for v in variances) else None
        if self.filter is None:
            self._pending_pose = (x, y, yaw, given)
            return
        self._apply_initial_pose(x, y, yaw, given)

    def _apply_initial_pose(
        self, x: float, y: float, yaw: float, cov: tuple[float, float, float] | None
    ) -> None:
        if self.filter is None:
            return
        self.filter.set_initial_pose(x, y, yaw, cov)
        self.get_logger().info(f"initial pose ({x:.3f}, {y:.3f}, {yaw:.3f})")
        self._report()

    def global_localization(self) -> bool:
        """Spread the particles over the map's free space (amcl's service); False: no map."""
        if self.filter is None:
            return False
        self.filter.global_localization()
        self._report()
        return True

    def request_nomotion_update(self) -> bool:
        """Make the next scan update the filter without motion; False: no particles yet."""
        if self.filter is None or not self.filter.initialized:
            return False
        self.filter.force_update()
        return True

    def _on_global_localization(self, request: object, response: Any) -> Any:
        del request
        if not self.global_localization():
            self.get_logger().warning(
                f"global_localization: no map on '{self.params.map_topic}' yet, nothing done"
            )
        else:
            self.get_logger().info("global_localization: particles spread over the free space")
        return response

    def _on_nomotion_update(self, request: object, response: Any) -> Any:
        del request
        if not self.request_nomotion_update():
            self.get_logger().warning(
                "request_nomotion_update: the filter has no particles yet (no map or initial "
                "pose), nothing done"
            )
        return response

    def _laser_pose(self, frame: str) -> tuple[float, float, float] | None:
        if frame not in self._lasers:
            try:
                T = self.tf_buffer.lookup_transform_matrix(self.params.base_frame_id, frame, 0)  # noqa: N806
            except TransformException as exc:
                self.get_logger().warning(
                    f"scan frame '{frame}' has no transform to '{self.params.base_frame_id}' "
                    f"yet: {exc}",
                    throttle_duration_sec=5.0,
                )
                return None
            self._lasers[frame] = (float(T[0, 3]), float(T[1, 3]), yaw_of(T))
        return self._lasers[frame]

    def _on_scan(self, msg: LaserScan) -> None:
        pending, self._pending_scan = self._pending_scan, None
        if pending is not None:
            self._process(pending, retry=False)
        self._process(msg, retry=True)

    def _process(self, msg: LaserScan, *, retry: bool) -> None:
        f = self.filter
        if f is None or not f.initialized:
            return
        p = self.params
        laser = self._laser_pose(msg.header.frame_id)
        if laser is None:
            return
        stamp = time_to_ns(msg.header.stamp)
        try:
            T = self.tf_buffer.lookup_transform_matrix(p.odom_frame_id, p.base_frame_id, stamp)  # noqa: N806
        except ExtrapolationException as exc:
            if retry and exc.requested_ns > exc.latest_ns:  # odometry not here yet: next scan
                self._pending_scan = msg
                return
            self.get_logger().warning(
                f"scan at {stamp / _NS:.3f} s dropped: no odometry '{p.odom_frame_id}' -> "
                f"'{p.base_frame_id}' at its time: {exc}",
                throttle_duration_sec=5.0,
            )
            return
        except TransformException as exc:
            self.get_logger().warning(
                f"scan at {stamp / _NS:.3f} s: no odometry '{p.odom_frame_id}' -> "
                f"'{p.base_frame_id}' at its time: {exc}",
                throttle_duration_sec=5.0,
            )
            return
        odom = (float(T[0, 3]), float(T[1, 3]), yaw_of(T))
        fp = self.filter_params
        range_max = float(msg.range_max)
        if fp.laser_max_range > 0:
            range_max = min(range_max, fp.laser_max_range)
        range_min = fp.laser_min_range if fp.laser_min_range > 0 else float(msg.range_min)
        beams = select_beams(
            np.asarray(msg.ranges), float(msg.angle_min), float(msg.angle_increment),
            range_min=range_min, range_max=range_max, max_beams=fp.max_beams,
        )  # fmt: skip
        if f.update(odom, beams, laser):
            self.updates += 1
            self._publish_estimate(msg.header.stamp)
            self._report()
        if p.tf_broadcast and f.status.localized:
            self._publish_tf(stamp)

    # ------------------------------------------------------------------ outputs
    def _publish_tf(self, stamp_ns: int) -> None:
        f = self.filter
        mo = f.map_to_odom() if f is not None else None
        if mo is None:
            return
        p = self.params
        t = stamp_ns + int(p.transform_tolerance * _NS)
        self._tf.send_transform(
            TransformStamped(
                header=Header(stamp=ns_to_time(t), frame_id=p.global_frame_id),
                child_frame_id=p.odom_frame_id,
                transform=Transform(
                    translation=Vector3(x=mo[0], y=mo[1], z=0.0),
                    rotation=quaternion_from_yaw(mo[2]),
                ),
            )
        )

    def _publish_estimate(self, stamp: Any) -> None:
        f = self.filter
        if f is None or f.estimate is None:
            return
        e = f.estimate
        header = Header(stamp=stamp, frame_id=self.params.global_frame_id)
        cov = np.zeros(36)
        cov[0], cov[1], cov[6], cov[7] = e.cov[0, 0], e.cov[0, 1], e.cov[1, 0], e.cov[1, 1]
        cov[35] = e.cov[2, 2]
        pose = Pose(position=Point(x=e.x, y=e.y, z=0.0), orientation=quaternion_from_yaw(e.yaw))
        self._pose_pub.publish(
            PoseWithCovarianceStamped(
                header=header, pose=PoseWithCovariance(pose=pose, covariance=cov)
            )
        )
        poses = [
            Pose(
                position=Point(x=float(x), y=float(y), z=0.0),
                orientation=quaternion_from_yaw(float(a)),
            )
            for x, y, a in f.poses
        ]
        self._cloud_pub.publish(self._pose_array(header=header, poses=poses))

    def _report(self) -> None:
        """Log and latch the status when it changes."""
        f = self.filter
        if f is None:
            return
        st = f.status
        line = f"{st.state}: {st.text}"
        # once per change of state: the text (fit, pose) changes at every update
        if st.state == self._last_status.split(":", 1)[0]:
            return
        self._last_status = line
        if st.state in ("not_converged", "lost"):
            self.get_logger().error(line)
        else:
            self.get_logger().info(line)
        self._status_pub.publish(String(data=line))
