"""Ray sensor plugins on the graph: LaserScan, PointCloud2, PointCloud and Range.

:class:`RayPlugin` publishes one :class:`~visnav.description.gazebo_specs.RaySpec`
the way its gazebo_ros plugin does (``spec.flavor``):

* ``laser`` (ROS 1 ``gazebo_ros_laser`` / ``gpu_laser``): ``LaserScan`` of every ray,
  ``angle_increment = (max - min) / (count - 1)``, ``time_increment`` and ``scan_time`` 0
  (an instantaneous scan), ``range_min`` / ``range_max`` the sensor's, out-of-range
  +/-inf (:func:`~visnav.sim.lidar.scan_ranges`);
* ``ray_sensor`` (ROS 2 ``gazebo_ros_ray_sensor``): ``LaserScan`` of the middle
  vertical row, intensities raised to ``min_intensity``; ``PointCloud2`` (x, y, z,
  intensity float32, unorganized, dense: non-finite ranges skipped), ``PointCloud``
  (the same points, channel ``intensity``) or ``Range`` (the minimum of the ranges,
  ``field_of_view = max(horizontal, vertical span)``);
* ``velodyne``: velodyne_simulator's ``PointCloud2`` (:func:`~visnav.sim.lidar.velodyne_points`);
* ``range`` (ROS 1 ``gazebo_ros_range``): ``Range`` of the minimum raw ray distance
  (``max_range`` when nothing is hit), ``gaussianNoise`` added below ``max_range`` and
  clamped to it; the sensor's ``<noise>`` does not apply (the plugin reads the rays).

Rays are cast only when due (``update_rate`` on a drift-free
:class:`~visnav.sim.sensor_timing.SensorClock`) and only while the topic has a
subscriber, as the gazebo_ros laser plugins activate their sensor on connect; a due scan
nobody wants is counted in ``skipped``. Stamps are the sim time of the cast.

Where visnav differs: ROS 2 ``Range`` with no return is +inf (REP 117; gazebo_ros's
conversion leaves FLT_MAX there); a single-ray axis has ``angle_increment`` 0 (Gazebo
divides by zero).
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__ChannelFloat32 as ChannelFloat32,
)
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__PointCloud as PointCloud,
)
from rosbags.typesys.stores.ros2_humble import (
    sensor_msgs__msg__Range as Range,
)

from visnav.msgs.pointcloud import structured_to_cloud
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header, LaserScan, Point32, PointCloud2
from visnav.sim.lidar import (
    RayCaster,
    RayNoise,
    published_angles,
    scan_ranges,
    spherical_to_xyz,
    velodyne_points,
)
from visnav.sim.plugins import SENSOR_QOS, SimPlugin
from visnav.sim.sensor_timing import SensorClock

if TYPE_CHECKING:
    import mujoco
    from numpy.typing import NDArray

    from visnav.description.gazebo_specs import RaySpec
    from visnav.graph.node import Node
    from visnav.sim.plugin_factories import RobotBuild
    from visnav.sim.rebind import IdMap

__all__ = ["ChannelFloat32", "PointCloud", "Range", "RayPlugin", "make_ray", "ray_message"]

_GAZEBO_CLOUD_DTYPE = np.dtype(
    {"names": ["x", "y", "z", "intensity"], "formats": ["<f4"] * 4, "offsets": [0, 4, 8, 12]}
)


def _laser_scan(
    spec: RaySpec, header: Header, ranges: NDArray[np.float64], intensities: NDArray[np.float64]
) -> LaserScan:
    h = spec.horizontal
    return LaserScan(
        header=header,
        angle_min=h.min_angle,
        angle_max=h.max_angle,
        angle_increment=h.step,
        time_increment=0.0,
        scan_time=0.0,
        range_min=spec.range_min,
        range_max=spec.range_max,
        ranges=np.ascontiguousarray(ranges, dtype=np.float32).reshape(-1),
        intensities=np.ascontiguousarray(intensities, dtype=np.float32).reshape(-1),
    )


def _gazebo_points(
    spec: RaySpec, ranges: NDArray[np.float64], intensities: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Finite-range points ``(N, 3)`` and intensities ``(N,)``, rows outer (gazebo_ros)."""
    azimuth, inclination = published_angles(spec)
    finite = np.isfinite(ranges)
    xyz = spherical_to_xyz(np.where(finite, ranges, 0.0), azimuth, inclination)
    return xyz[finite], np.maximum(intensities[finite], spec.min_intensity)


def ray_message(
    spec: RaySpec,
    raw: NDArray[np.float64],
    *,
    stamp_ns: int,
    noise: RayNoise | None,
    rng: np.random.Generator,
) -> Any:
    """The message ``spec``'s plugin publishes for raw ranges ``raw`` (see :mod:`.lidar`).

    Args:
        spec: the sensor with its final topic and frame.
        raw: :meth:`~visnav.sim.lidar.RayCaster.cast` output (``range_max`` = no hit).
        stamp_ns: the header stamp.
        noise: the sensor's ``<noise>`` model (None for none).
        rng: the generator of every random draw.
    """
    header = Header(stamp=ns_to_time(stamp_ns), frame_id=spec.frame_id)
    if spec.flavor == "range":
        value = float(np.min(raw))
        if value < spec.range_max and spec.gaussian_noise > 0.0:
            value = min(value + float(rng.normal(0.0, spec.gaussian_noise)), spec.range_max)
        return _range(spec, header, value)
    ranges = scan_ranges(raw, spec, noise, rng)
    intensities = np.zeros(ranges.shape)
    if spec.flavor == "velodyne":
        cloud = velodyne_points(ranges, spec, rng, intensities)
        return structured_to_cloud(cloud, header=header, is_dense=not spec.organize_cloud)
    if spec.flavor == "laser":
        return _laser_scan(spec, header, ranges, intensities)
    if spec.output == "LaserScan":
        row = spec.vertical.count // 2
        clipped = np.maximum(intensities[row], spec.min_intensity)
        return _laser_scan(spec, header, ranges[row], clipped)
    if spec.output == "Range":
        return _range(spec, header, float(np.min(ranges)))
    xyz, inten = _gazebo_points(spec, ranges, intensities)
    if spec.output == "PointCloud":
        points = [Point32(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in xyz]
        channel = ChannelFloat32(name="intensity", values=inten.astype(np.float32))
        return PointCloud(header=header, points=points, channels=[channel])
    cloud = np.zeros(len(xyz), dtype=_GAZEBO_CLOUD_DTYPE)
    cloud["x"], cloud["y"], cloud["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    cloud["intensity"] = inten
    return structured_to_cloud(cloud, header=header, is_dense=True)


def _range(spec: RaySpec, header: Header, value: float) -> Range:
    return Range(
        header=header,
        radiation_type=spec.radiation_type,
        field_of_view=spec.field_of_view,
        min_range=spec.range_min,
        max_range=spec.range_max,
        range=value if not math.isnan(value) else spec.range_max,
    )


_MESSAGE_TYPES: dict[str, type[Any]] = {
    "LaserScan": LaserScan,
    "PointCloud2": PointCloud2,
    "PointCloud": PointCloud,
    "Range": Range,
}


class RayPlugin(SimPlugin):
    """A ray sensor's gazebo_ros plugin: casts when due and subscribed, publishes one message.

    Args:
        node: the plugin's node.
        spec: the sensor with its final topic and frame.
        caster: the sensor's rays in the model.
        rng: the noise generator (seed it per sensor).
        start_ns: sim time of the first possible scan.
    """

    def __init__(
        self,
        node: Node,
        spec: RaySpec,
        caster: RayCaster,
        *,
        rng: np.random.Generator,
        start_ns: int = 0,
    ) -> None:
        super().__init__(node, spec.name)
        self.spec = spec
        self.caster = caster
        self.clock = SensorClock(spec.update_rate, start_ns=start_ns)
        self.cast_ns = 0
        self.scans = 0
        self.skipped = 0
        self._rng = rng
        self._noise = RayNoise(spec.noise, rng)
        topic = spec.topic or f"/{spec.name}/out"
        self._pub = node.create_publisher(_MESSAGE_TYPES[spec.output], topic, SENSOR_QOS)
        self._wanted = (-1, True)

    def rebind(self, ids: IdMap) -> None:
        """Cast in a recompiled model."""
        self.caster.rebind(ids)

    def wanted(self) -> bool:
        """True while the topic has a subscriber (checked when the graph changes)."""
        version = self.node.context.graph.version
        if version != self._wanted[0]:
            self._wanted = (version, self._pub.get_subscription_count() > 0)
        return self._wanted[1]

    def sense(self, data: mujoco.MjData, now_ns: int) -> None:
        """Cast and publish at ``now_ns`` when due and wanted."""
        if not self.clock.due(now_ns):
            return
        if not self.wanted():
            self.skipped += 1
            return
        self.scan(data, now_ns)

    def scan(self, data: mujoco.MjData, stamp_ns: int) -> None:
        """Cast now and publish the message stamped ``stamp_ns`` (no rate or subscriber check)."""
        start = time.perf_counter_ns()
        raw = self.caster.cast(data)
        msg = ray_message(self.spec, raw, stamp_ns=stamp_ns, noise=self._noise, rng=self._rng)
        self._pub.publish(msg)
        self.cast_ns += time.perf_counter_ns() - start
        self.scans += 1


def make_ray(build: RobotBuild, ray: RaySpec) -> SimPlugin | None:
    """The :data:`~visnav.sim.plugin_factories.SIM_PLUGINS` factory of ray sensors.

    Pushes the robot's namespace onto the topic and its frame prefix onto the frame;
    a sensor without a gazebo_ros plugin (no topic) publishes nothing and gets no runtime.
    """
    if ray.topic is None:
        return None
    spec = replace(
        ray, topic=build.push(ray.topic) or ray.topic, frame_id=build.frame(ray.frame_id)
    )
    body = build.model.body(build.handles.bodies[ray.link]).id
    caster = RayCaster(build.model, spec, body=body, t_link_sensor=ray.pose.matrix())
    return RayPlugin(
        build.node(ray.plugin_name or ray.name),
        spec,
        caster,
        rng=np.random.default_rng(build.seed_of(ray.name)),
    )
