"""``<sensor type="ray|gpu_ray|lidar|gpu_lidar">`` blocks and their gazebo_ros plugins (internal).

Names, defaults and frames as the plugins resolve them:

* ROS 1 ``libgazebo_ros_laser.so`` / ``libgazebo_ros_gpu_laser.so``: ``LaserScan`` on
  ``<robotNamespace>/<topicName>`` (default topic ``/world``, as the plugin's), frame
  ``tf::resolve(robotNamespace without trailing '/', frameName)`` (default ``/world``);
  a present but empty ``<robotNamespace>`` is the model (robot) name.
* ROS 2 ``libgazebo_ros_ray_sensor.so``: ``~/out`` of the plugin's node
  (``<ros><namespace>``, ``<remapping>~/out:=scan</remapping>``), ``<output_type>``
  ``sensor_msgs/LaserScan | PointCloud2 | PointCloud | Range`` (default PointCloud2),
  frame ``<frame_name>`` or the sensor's link, ``<min_intensity>``, ``<radiation_type>``.
* velodyne_simulator's ``libgazebo_ros_velodyne_laser.so`` / ``_gpu_laser.so``: ROS 1
  ``<robotNamespace>/<topicName>`` (default ``/points``), frame prefixed by a
  ``<robotNamespace>`` other than ``/``; ROS 2 (with ``<ros>``) ``~/out`` and
  ``<frame_name>``; ``min_range``, ``max_range``, ``gaussianNoise`` (ROS 2
  ``gaussian_noise``), ``min_intensity``, ``organize_cloud``.
* ROS 1 ``libgazebo_ros_range.so``: ``Range`` on ``<robotNamespace>/<topicName>``
  (default ``/range``), frame ``frameName`` (default ``/world``, no namespace prefix),
  ``radiation`` (``ultrasound``, anything else infrared), ``fov`` (default 0.05),
  ``gaussianNoise``, ``updateRate`` (throttles below the sensor's rate).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import Literal, cast

from visnav.description._sdf_reader import SdfReader, has_any, plugin_node
from visnav.description.gazebo_specs import RayScan, RaySpec, ros1_join, tf_resolve

__all__ = ["RAY_SENSOR_TYPES", "parse_ray"]

RAY_SENSOR_TYPES = ("ray", "gpu_ray", "lidar", "gpu_lidar")
"""Sensor ``type`` values read as ray sensors."""

_LASER = ("libgazebo_ros_laser.so", "libgazebo_ros_gpu_laser.so")
_RAY_SENSOR = ("libgazebo_ros_ray_sensor.so",)
_VELODYNE = ("libgazebo_ros_velodyne_laser.so", "libgazebo_ros_velodyne_gpu_laser.so")
_RANGE = ("libgazebo_ros_range.so",)
_PLUGINS = (*_LASER, *_RAY_SENSOR, *_VELODYNE, *_RANGE)
_SENSOR_COMMON = (
    "always_on", "update_rate", "visualize", "pose", "plugin", "topic", "enable_metrics",
)  # fmt: skip
_OUTPUTS: dict[str, Literal["LaserScan", "PointCloud2", "PointCloud", "Range"]] = {
    "sensor_msgs/LaserScan": "LaserScan",
    "sensor_msgs/PointCloud2": "PointCloud2",
    "sensor_msgs/PointCloud": "PointCloud",
    "sensor_msgs/Range": "Range",
}
_VELODYNE_ROS1 = ("robotNamespace", "topicName", "frameName", "gaussianNoise")
_VELODYNE_COMMON = ("min_range", "max_range", "min_intensity", "organize_cloud")


def _scan_axis(
    reader: SdfReader, scan: ET.Element | None, tag: str, default: RayScan, *, owner: str
) -> RayScan:
    axis = scan.find(tag) if scan is not None else None
    if axis is None:
        return default
    found = axis.find("samples")
    samples = default.samples
    if found is not None:
        raw = (found.text or "").strip()
        try:
            samples = int(raw)
        except ValueError:
            samples = 0
        if samples <= 0:
            raise reader.error(
                found,
                f"{owner}<{tag}><samples>{raw}</samples> is not a positive integer",
                "write the number of rays, e.g. 360",
            )
    resolution = reader.number(axis, "resolution", 1.0, owner=owner, minimum=0.0, strict=True)
    if int(samples * resolution) < 1:
        raise reader.error(
            axis,
            f"{owner}<{tag}> samples {samples} x resolution {resolution:g} is less than one range",
            "use resolution 1 (one range per ray)",
        )
    lo = reader.number(axis, "min_angle", 0.0, owner=owner)
    hi = reader.number(axis, "max_angle", 0.0, owner=owner)
    if hi < lo:
        raise reader.error(
            axis,
            f"{owner}<{tag}> max_angle {hi:g} is below min_angle {lo:g}",
            "swap them: rays go from min_angle to max_angle",
        )
    reader.unknown(
        axis, ("samples", "resolution", "min_angle", "max_angle"), owner=owner, what=f"<{tag}>"
    )
    return RayScan(samples=samples, resolution=resolution, min_angle=lo, max_angle=hi)


def _ray_element(
    reader: SdfReader, sensor: ET.Element, *, owner: str
) -> tuple[ET.Element, dict[str, object]]:
    ray = sensor.find("ray")
    if ray is None:
        ray = sensor.find("lidar")
    if ray is None:
        raise reader.error(
            sensor,
            f"{owner}a ray sensor needs a <ray> (or <lidar>) element",
            "add <ray><scan><horizontal>..</horizontal></scan><range>..</range></ray>",
        )
    scan = ray.find("scan")
    if scan is not None:
        reader.unknown(scan, ("horizontal", "vertical"), owner=owner, what="<scan>")
    horizontal = _scan_axis(reader, scan, "horizontal", RayScan(samples=640), owner=owner)
    vertical = _scan_axis(reader, scan, "vertical", RayScan(), owner=owner)
    range_el = ray.find("range")
    if range_el is None:
        raise reader.error(
            ray,
            f"{owner}<{ray.tag}> needs <range><min>..</min><max>..</max></range>",
            "add the sensor's range limits in metres, e.g. <min>0.1</min><max>10</max>",
        )
    lo = reader.number(range_el, "min", 0.0, owner=owner, minimum=0.0)
    hi = reader.number(range_el, "max", 10.0, owner=owner)
    if hi <= lo:
        raise reader.error(
            range_el,
            f"{owner}range max = {hi:g} is not beyond min = {lo:g}",
            "set <max> greater than <min>",
        )
    resolution = reader.number(range_el, "resolution", 0.0, owner=owner, minimum=0.0)
    reader.unknown(range_el, ("min", "max", "resolution"), owner=owner, what="<range>")
    reader.unknown(ray, ("scan", "range", "noise"), owner=owner, what=f"<{ray.tag}>")
    fields: dict[str, object] = {
        "horizontal": horizontal, "vertical": vertical, "range_min": lo, "range_max": hi,
        "range_resolution": resolution, "noise": reader.noise(ray.find("noise"), owner=owner),
    }  # fmt: skip
    return ray, fields


def parse_ray(reader: SdfReader, sensor: ET.Element, link: str, robot_name: str) -> RaySpec:
    """Read one ray sensor and its plugin into a :class:`RaySpec`.

    Raises:
        RobotDescriptionError: no ``<ray>``/``<range>``, bad samples, angles or ranges,
            an unknown ``<output_type>`` or ``<radiation_type>``, malformed numbers.
    """
    kind = sensor.get("type") or "ray"
    name = sensor.get("name") or f"{link}_{kind}"
    owner = f"sensor {name!r}: "
    _, fields = _ray_element(reader, sensor, owner=owner)
    update_rate = reader.number(sensor, "update_rate", 0.0, owner=owner, minimum=0.0)
    reader.unknown(sensor, (*_SENSOR_COMMON, "ray", "lidar"), owner=owner, what="a ray sensor")
    spec: dict[str, object] = {
        "name": name, "link": link, "pose": reader.pose(sensor, owner=owner), "kind": kind,
        "update_rate": update_rate, "frame_id": link, **fields,
    }  # fmt: skip
    plugin = reader.sensor_plugin(
        sensor, _PLUGINS, owner=owner, what="ray",
        add='<plugin filename="libgazebo_ros_laser.so"> or libgazebo_ros_ray_sensor.so',
    )  # fmt: skip
    if plugin is None:
        return RaySpec(**spec)  # type: ignore[arg-type]
    filename = plugin.get("filename") or ""
    spec["plugin"] = filename
    spec["plugin_name"] = plugin.get("name") or ""
    if filename in _LASER:
        _laser_ros1(reader, plugin, spec, owner=owner, robot_name=robot_name)
    elif filename in _RAY_SENSOR:
        _ray_sensor_ros2(reader, plugin, spec, owner=owner)
    elif filename in _VELODYNE:
        _velodyne(reader, plugin, spec, owner=owner)
    else:
        _range_ros1(reader, plugin, spec, owner=owner)
    return RaySpec(**spec)  # type: ignore[arg-type]


def _ros1_namespace(reader: SdfReader, plugin: ET.Element, robot_name: str) -> str:
    """``GetRobotNamespace``: absent -> "", present but empty -> the model's name."""
    ns = reader.text(plugin, "robotNamespace")
    if ns is None:
        return ""
    return ns or robot_name


def _ros1_topic(ns: str, topic: str) -> str:
    """``NodeHandle(ns).advertise(topic)``: an absolute topic ignores the namespace."""
    return ros1_join(topic) if topic.startswith("/") else ros1_join(ns, topic)


def _missing_default(
    reader: SdfReader, plugin: ET.Element, tag: str, default: str, *, owner: str
) -> str:
    value = reader.text(plugin, tag)
    if value is None:
        reader.warn(
            plugin,
            f"{owner}<{tag}> is missing; like {plugin.get('filename')} visnav uses {default!r}",
        )
        return default
    return value


def _laser_ros1(
    reader: SdfReader, plugin: ET.Element, spec: dict[str, object], *, owner: str, robot_name: str
) -> None:
    ns = _ros1_namespace(reader, plugin, robot_name)
    frame = _missing_default(reader, plugin, "frameName", "/world", owner=owner)
    topic = _missing_default(reader, plugin, "topicName", "/world", owner=owner)
    spec.update(flavor="laser", output="LaserScan", ros_version=1)
    spec["frame_id"] = tf_resolve(ns.rstrip("/"), frame)
    spec["topic"] = _ros1_topic(ns, topic) if topic else None
    vertical = spec["vertical"]
    if isinstance(vertical, RayScan) and vertical.count > 1:
        reader.warn(
            plugin,
            f"{owner}{vertical.count} vertical rays: like gazebo_ros_laser, the LaserScan holds "
            "every row one after another (use libgazebo_ros_velodyne_laser.so for a 3D cloud)",
        )
    _unknown_plugin_elements(
        reader, plugin, ("robotNamespace", "frameName", "topicName"), owner=owner
    )


def _ray_sensor_ros2(
    reader: SdfReader, plugin: ET.Element, spec: dict[str, object], *, owner: str
) -> None:
    node = plugin_node(reader, plugin, owner=owner)
    spec.update(flavor="ray_sensor", ros_version=2)
    spec["frame_id"] = reader.text(plugin, "frame_name") or spec["link"]
    spec["topic"] = node.resolve("~/out")
    text = reader.text(plugin, "output_type")
    if text is None:
        reader.warn(
            plugin,
            f"{owner}<output_type> is missing; like gazebo_ros_ray_sensor visnav publishes "
            "sensor_msgs/PointCloud2",
        )
        text = "sensor_msgs/PointCloud2"
    output = _OUTPUTS.get(text.replace("/msg/", "/"))
    if output is None:
        found = plugin.find("output_type")
        raise reader.error(
            found if found is not None else plugin,
            f"{owner}output_type {text!r} is not one gazebo_ros_ray_sensor publishes",
            f"use one of {', '.join(_OUTPUTS)}",
        )
    spec["output"] = output
    spec["min_intensity"] = reader.number(plugin, "min_intensity", 0.0, owner=owner)
    radiation = reader.text(plugin, "radiation_type")
    if radiation is not None and radiation not in ("ultrasound", "infrared"):
        found = plugin.find("radiation_type")
        raise reader.error(
            found if found is not None else plugin,
            f"{owner}radiation_type {radiation!r} is neither ultrasound nor infrared",
            "write ultrasound or infrared",
        )
    spec["radiation_type"] = 0 if radiation == "ultrasound" else 1
    horizontal, vertical = cast(RayScan, spec["horizontal"]), cast(RayScan, spec["vertical"])
    spec["field_of_view"] = max(
        horizontal.max_angle - horizontal.min_angle, vertical.max_angle - vertical.min_angle
    )
    if output != "Range" and radiation is not None:
        reader.warn(plugin, f"{owner}<radiation_type> only applies to output_type Range")
    _unknown_plugin_elements(
        reader,
        plugin,
        ("ros", "frame_name", "output_type", "min_intensity", "radiation_type"),
        owner=owner,
    )


def _velodyne(
    reader: SdfReader, plugin: ET.Element, spec: dict[str, object], *, owner: str
) -> None:
    spec.update(flavor="velodyne", output="PointCloud2")
    ros1 = plugin.find("ros") is None and has_any(plugin, _VELODYNE_ROS1)
    spec["plugin_min_range"] = reader.number(plugin, "min_range", 0.0, owner=owner)
    spec["plugin_max_range"] = reader.number(plugin, "max_range", math.inf, owner=owner)
    spec["min_intensity"] = reader.number(plugin, "min_intensity", -math.inf, owner=owner)
    spec["organize_cloud"] = reader.boolean(plugin, "organize_cloud", False, owner=owner)
    if ros1:
        ns = reader.text(plugin, "robotNamespace")
        ns = "/" if ns is None else ns
        prefix = ns.rstrip("/") if ns != "/" else ""
        frame = _missing_default(reader, plugin, "frameName", "/world", owner=owner)
        topic = reader.text(plugin, "topicName")
        topic = "/points" if topic is None else topic
        spec["ros_version"] = 1
        spec["frame_id"] = tf_resolve(prefix, frame)
        spec["topic"] = _ros1_topic(ns, topic) if topic else None
        spec["gaussian_noise"] = reader.number(
            plugin, "gaussianNoise", 0.0, owner=owner, minimum=0.0
        )
        known: tuple[str, ...] = (*_VELODYNE_ROS1, *_VELODYNE_COMMON)
    else:
        node = plugin_node(reader, plugin, owner=owner)
        spec["ros_version"] = 2
        prefix = reader.text(plugin, "tf_prefix") or ""
        spec["frame_id"] = tf_resolve(
            prefix, reader.text(plugin, "frame_name") or str(spec["link"])
        )
        spec["topic"] = node.resolve("~/out")
        spec["gaussian_noise"] = reader.number(
            plugin, "gaussian_noise", 0.0, owner=owner, minimum=0.0
        )
        known = ("ros", "frame_name", "tf_prefix", "gaussian_noise", *_VELODYNE_COMMON)
    _unknown_plugin_elements(reader, plugin, known, owner=owner)


def _range_ros1(
    reader: SdfReader, plugin: ET.Element, spec: dict[str, object], *, owner: str
) -> None:
    ns = reader.text(plugin, "robotNamespace")
    ns = "" if ns is None else ns + "/"
    frame = _missing_default(reader, plugin, "frameName", "/world", owner=owner)
    topic = reader.text(plugin, "topicName")
    topic = "/range" if topic is None else topic
    spec.update(flavor="range", output="Range", ros_version=1)
    spec["frame_id"] = tf_resolve("", frame)
    spec["topic"] = _ros1_topic(ns, topic) if topic else None
    radiation = reader.text(plugin, "radiation")
    if radiation is None:
        reader.warn(
            plugin, f"{owner}<radiation> is missing; like gazebo_ros_range visnav uses ultrasound"
        )
        radiation = "ultrasound"
    spec["radiation_type"] = 0 if radiation == "ultrasound" else 1
    spec["field_of_view"] = reader.number(plugin, "fov", 0.05, owner=owner)
    spec["gaussian_noise"] = reader.number(plugin, "gaussianNoise", 0.0, owner=owner, minimum=0.0)
    rate = reader.number(plugin, "updateRate", 0.0, owner=owner, minimum=0.0)
    sensor_rate = float(spec["update_rate"])  # type: ignore[arg-type]
    positive = [r for r in (rate, sensor_rate) if r > 0.0]
    spec["update_rate"] = min(positive) if positive else 0.0
    _unknown_plugin_elements(
        reader,
        plugin,
        ("robotNamespace", "frameName", "topicName", "radiation", "fov", "gaussianNoise",
         "updateRate"),
        owner=owner,
    )  # fmt: skip


def _unknown_plugin_elements(
    reader: SdfReader, plugin: ET.Element, known: tuple[str, ...], *, owner: str
) -> None:
    for child in plugin:
        if child.tag == "alwaysOn":
            continue  # visnav sensors are always on
        if child.tag not in known:
            reader.warn(
                child, f"{owner}plugin element <{child.tag}> is not supported and is ignored"
            )
