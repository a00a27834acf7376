"""``<sensor type="camera|depth|imu">`` blocks and their gazebo_ros plugins (internal)."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import Literal, cast

from visnav.description._sdf_reader import SdfReader, has_any, plugin_node
from visnav.description.gazebo_specs import (
    CameraSpec,
    GaussianNoise,
    ImuSpec,
    LensDistortion,
    default_principal_point,
    ros1_join,
    tf_resolve,
)
from visnav.description.noise_specs import parse_depth_noise

__all__ = ["parse_camera", "parse_imu"]

_FORMATS: dict[str, str] = {
    "R8G8B8": "rgb8",
    "RGB_INT8": "rgb8",
    "B8G8R8": "bgr8",
    "BGR_INT8": "bgr8",
    "L8": "mono8",
    "L_INT8": "mono8",
    "L16": "mono16",
    "L_INT16": "mono16",
    "R16G16B16": "rgb16",
    "RGB_INT16": "rgb16",
}

_CAMERA_PLUGINS = ("libgazebo_ros_camera.so",)
_DEPTH_PLUGINS_ROS1 = ("libgazebo_ros_depth_camera.so", "libgazebo_ros_openni_kinect.so")
# Sensor elements visnav honours by construction or that only affect Gazebo itself
# (always on, gzclient visualisation, Gazebo transport topic, metrics).
_SENSOR_COMMON = (
    "always_on",
    "update_rate",
    "visualize",
    "pose",
    "plugin",
    "topic",
    "enable_metrics",
)
_IMU_PLUGINS = ("libgazebo_ros_imu_sensor.so",)

_CAMERA_ROS1_MARKERS = (
    "robotNamespace", "cameraName", "imageTopicName", "cameraInfoTopicName", "frameName",
    "updateRate", "pointCloudTopicName", "depthImageTopicName", "depthImageCameraInfoTopicName",
    "pointCloudCutoff", "pointCloudCutoffMax", "hackBaseline", "distortionK1", "distortionK2",
    "distortionK3", "distortionT1", "distortionT2", "CxPrime", "Cx", "Cy", "focalLength",
    "borderCrop", "useDepth16UC1Format",
)  # fmt: skip
_CAMERA_ROS2_KNOWN = (
    "ros", "camera_name", "frame_name", "hack_baseline", "min_depth", "max_depth", "cx", "cy",
    "focal_length", "border_crop", "pointcloud", "depth_format", "use_depth_16uc1_format",
    "depth_noise",
)  # fmt: skip


def parse_camera(
    reader: SdfReader,
    sensor: ET.Element,
    link: str,
    kind: Literal["camera", "depth"],
    robot_name: str,
) -> CameraSpec:
    name = sensor.get("name") or f"{link}_{kind}"
    owner = f"sensor {name!r}: "
    camera = sensor.find("camera")
    if camera is None:
        raise reader.error(
            sensor,
            f"{owner}a {kind} sensor needs a <camera> element",
            "add <camera><horizontal_fov>..</horizontal_fov><image>..</image></camera>",
        )
    hfov = reader.number(camera, "horizontal_fov", 1.047, owner=owner)
    if not 0.0 < hfov < math.pi:
        found = camera.find("horizontal_fov")
        raise reader.error(
            found if found is not None else camera,
            f"{owner}horizontal_fov = {hfov:g} rad is outside (0, pi)",
            "give the field of view in radians, e.g. 1.047 for 60 degrees",
        )
    image = camera.find("image")
    width, height, fmt = 320, 240, "R8G8B8"
    if image is not None:
        width = reader.integer(image, "width", 320, owner=owner)
        height = reader.integer(image, "height", 240, owner=owner)
        fmt = reader.text(image, "format") or "R8G8B8"
        reader.unknown(image, ("width", "height", "format"), owner=owner, what="<image>")
    if fmt not in _FORMATS:
        found = image.find("format") if image is not None else camera
        raise reader.error(
            found if found is not None else camera,
            f"{owner}image format {fmt!r} is not supported",
            f"use one of {', '.join(_FORMATS)}",
        )
    clip = camera.find("clip")
    near, far = 0.1, 100.0
    if clip is not None:
        near = reader.number(clip, "near", 0.1, owner=owner, minimum=0.0, strict=True)
        far = reader.number(clip, "far", 100.0, owner=owner)
        if far <= near:
            raise reader.error(
                clip,
                f"{owner}clip far = {far:g} is not beyond near = {near:g}",
                "set <far> greater than <near>",
            )
    noise = reader.noise(camera.find("noise"), owner=owner)
    distortion = LensDistortion()
    dist_el = camera.find("distortion")
    if dist_el is not None:
        center = reader.vector(dist_el, "center", (0.5, 0.5), owner=owner)
        distortion = LensDistortion(
            k1=reader.number(dist_el, "k1", 0.0, owner=owner),
            k2=reader.number(dist_el, "k2", 0.0, owner=owner),
            k3=reader.number(dist_el, "k3", 0.0, owner=owner),
            p1=reader.number(dist_el, "p1", 0.0, owner=owner),
            p2=reader.number(dist_el, "p2", 0.0, owner=owner),
            center=(center[0], center[1]),
        )
        if distortion.center != (0.5, 0.5):
            reader.warn(
                dist_el,
                f"{owner}distortion <center> {distortion.center} is ignored; "
                "the distortion centre is the principal point (cx, cy)",
            )
    for child in camera:
        if child.tag == "lens":
            reader.warn(
                child,
                f"{owner}<lens> is not supported; the camera is a pinhole with "
                "K from horizontal_fov",
            )
        elif child.tag == "save":
            reader.warn(child, f"{owner}<save> (writing frames to disk) is not supported")
        elif child.tag == "depth_camera":
            output = (reader.text(child, "output") or "depths").lower()
            if output not in ("depths", "depth"):
                reader.warn(
                    child,
                    f"{owner}depth_camera output {output!r} is not supported; depth is published",
                )
        elif child.tag not in ("horizontal_fov", "image", "clip", "noise", "distortion"):
            reader.warn(child, f"{owner}<camera><{child.tag}> is not supported and is ignored")
    update_rate = reader.number(sensor, "update_rate", 0.0, owner=owner, minimum=0.0)
    reader.unknown(sensor, (*_SENSOR_COMMON, "camera"), owner=owner, what="a camera sensor")
    spec: dict[str, object] = {
        "name": name, "link": link, "pose": reader.pose(sensor, owner=owner), "kind": kind,
        "update_rate": update_rate, "width": width, "height": height, "hfov": hfov,
        "image_format": fmt, "encoding": _FORMATS[fmt], "clip_near": near, "clip_far": far,
        "noise": noise, "distortion": distortion, "frame_id": link,
    }  # fmt: skip
    focal = width / (2.0 * math.tan(hfov / 2.0))
    cx, cy = default_principal_point(width, height)
    plugin = reader.sensor_plugin(
        sensor, _CAMERA_PLUGINS + _DEPTH_PLUGINS_ROS1, owner=owner, what="camera",
        add='<plugin filename="libgazebo_ros_camera.so">',
    )  # fmt: skip
    if plugin is None:
        spec.update(fx=focal, fy=focal, cx=cx, cy=cy)
        return CameraSpec(**spec)  # type: ignore[arg-type]
    filename = plugin.get("filename") or ""
    spec["plugin"] = filename
    spec["plugin_name"] = plugin.get("name") or ""
    ros1 = filename in _DEPTH_PLUGINS_ROS1 or (
        plugin.find("ros") is None and has_any(plugin, _CAMERA_ROS1_MARKERS)
    )
    if ros1:
        _camera_ros1(reader, plugin, spec, owner=owner, kind=kind, robot_name=robot_name)
    else:
        _camera_ros2(reader, plugin, spec, owner=owner, kind=kind)
    if kind == "depth":
        spec["depth_noise"] = parse_depth_noise(reader, plugin, owner=owner)
    elif plugin.find("depth_noise") is not None:
        reader.warn(plugin, f"{owner}<depth_noise> only applies to depth sensors; ignored")
    focal_given = float(spec.pop("focal_length", 0.0))  # type: ignore[arg-type]
    if focal_given and not math.isclose(focal_given, focal, rel_tol=1e-6):
        reader.warn(
            plugin,
            f"{owner}focal_length {focal_given:g} is inconsistent with width "
            f"{width} and horizontal_fov {hfov:g} (expected {focal:g}); like "
            "Gazebo, the given value is published and rendered",
        )
    fx = focal_given or focal
    spec["fx"] = spec["fy"] = fx
    spec["cx"] = float(spec.pop("cx_given", 0.0) or cx)  # type: ignore[arg-type]
    spec["cy"] = float(spec.pop("cy_given", 0.0) or cy)  # type: ignore[arg-type]
    return CameraSpec(**spec)  # type: ignore[arg-type]


def _camera_ros2(
    reader: SdfReader,
    plugin: ET.Element,
    spec: dict[str, object],
    *,
    owner: str,
    kind: Literal["camera", "depth"],
) -> None:
    node = plugin_node(reader, plugin, owner=owner)
    camera_name = reader.text(plugin, "camera_name") or str(spec["name"])
    spec["ros_version"] = 2
    spec["frame_id"] = reader.text(plugin, "frame_name") or spec["link"]
    spec["image_topic"] = node.resolve(f"{camera_name}/image_raw")
    spec["camera_info_topic"] = node.resolve(f"{camera_name}/camera_info")
    spec["hack_baseline"] = reader.number(plugin, "hack_baseline", 0.0, owner=owner)
    spec["focal_length"] = reader.number(plugin, "focal_length", 0.0, owner=owner, minimum=0.0)
    spec["cx_given"] = reader.number(plugin, "cx", 0.0, owner=owner)
    spec["cy_given"] = reader.number(plugin, "cy", 0.0, owner=owner)
    if kind == "depth":
        spec["depth_topic"] = node.resolve(f"{camera_name}/depth/image_raw")
        spec["depth_info_topic"] = node.resolve(f"{camera_name}/depth/camera_info")
        spec["min_depth"] = reader.number(plugin, "min_depth", 0.4, owner=owner, minimum=0.0)
        spec["max_depth"] = reader.number(plugin, "max_depth", math.inf, owner=owner)
        spec["pointcloud"] = reader.boolean(plugin, "pointcloud", True, owner=owner)
        spec["points_topic"] = node.resolve(f"{camera_name}/points") if spec["pointcloud"] else None
        spec["depth_encoding"] = _depth_encoding(reader, plugin, owner=owner)
    else:
        for tag in ("min_depth", "max_depth", "pointcloud"):
            found = plugin.find(tag)
            if found is not None:
                reader.warn(found, f"{owner}<{tag}> only applies to depth sensors; ignored")
    known = (*_CAMERA_ROS2_KNOWN, "triggered")
    for child in plugin:
        if child.tag == "triggered":
            reader.warn(
                child,
                f"{owner}triggered cameras are not supported; frames are rendered at update_rate",
            )
        elif child.tag not in known:
            reader.warn(
                child, f"{owner}plugin element <{child.tag}> is not supported and is ignored"
            )


def _depth_encoding(
    reader: SdfReader, plugin: ET.Element, *, owner: str
) -> Literal["32FC1", "16UC1"]:
    if reader.boolean(
        plugin, ("useDepth16UC1Format", "use_depth_16uc1_format"), False, owner=owner
    ):
        return "16UC1"
    text = reader.text(plugin, "depth_format")
    if text is None or text.upper() == "32FC1":
        return "32FC1"
    if text.upper() == "16UC1":
        return "16UC1"
    found = plugin.find("depth_format")
    raise reader.error(
        found if found is not None else plugin,
        f"{owner}depth_format {text!r} is not supported",
        "use 32FC1 (metres) or 16UC1 (millimetres)",
    )


def _camera_ros1(
    reader: SdfReader,
    plugin: ET.Element,
    spec: dict[str, object],
    *,
    owner: str,
    kind: Literal["camera", "depth"],
    robot_name: str,
) -> None:
    del robot_name  # gazebo_ros_camera_utils defaults the namespace to "" (not the model)
    ns = reader.text(plugin, "robotNamespace") or ""
    camera_name = reader.text(plugin, "cameraName") or ""
    filename = str(spec["plugin"])
    depth_plugin = filename in _DEPTH_PLUGINS_ROS1
    if depth_plugin and kind != "depth":
        raise reader.error(
            plugin,
            f'{owner}{filename} needs <sensor type="depth">',
            "change the sensor type to depth (or use libgazebo_ros_camera.so)",
        )
    image_default = "ir/image_raw" if depth_plugin else "image_raw"
    info_default = "ir/camera_info" if depth_plugin else "camera_info"

    def topic(tag: str, default: str) -> str:
        name = reader.text(plugin, tag) or default
        return ros1_join(name) if name.startswith("/") else ros1_join(ns, camera_name, name)

    spec["ros_version"] = 1
    frame = reader.text(plugin, "frameName")
    if frame is None:
        reader.warn(
            plugin,
            f"{owner}<frameName> is missing (gazebo_ros_camera_utils would "
            f"publish an empty frame id); visnav uses the link {spec['link']!r}",
        )
        frame = str(spec["link"])
    spec["frame_id"] = tf_resolve(ns, frame)
    spec["image_topic"] = topic("imageTopicName", image_default)
    spec["camera_info_topic"] = topic("cameraInfoTopicName", info_default)
    spec["hack_baseline"] = reader.number(plugin, "hackBaseline", 0.0, owner=owner)
    spec["focal_length"] = reader.number(plugin, "focalLength", 0.0, owner=owner, minimum=0.0)
    spec["cx_given"] = reader.number(plugin, "Cx", 0.0, owner=owner)
    spec["cy_given"] = reader.number(plugin, "Cy", 0.0, owner=owner)
    plugin_distortion = LensDistortion(
        k1=reader.number(plugin, "distortionK1", 0.0, owner=owner),
        k2=reader.number(plugin, "distortionK2", 0.0, owner=owner),
        k3=reader.number(plugin, "distortionK3", 0.0, owner=owner),
        p1=reader.number(plugin, "distortionT1", 0.0, owner=owner),
        p2=reader.number(plugin, "distortionT2", 0.0, owner=owner),
    )
    sdf_distortion = cast(LensDistortion, spec["distortion"])
    if not plugin_distortion.is_zero:
        if not sdf_distortion.is_zero and sdf_distortion.d != plugin_distortion.d:
            reader.warn(
                plugin,
                f"{owner}plugin distortion {plugin_distortion.d} differs from the "
                f"sensor's <distortion> {sdf_distortion.d}; Gazebo would render "
                "one and publish the other, visnav renders and publishes the "
                "sensor's <distortion>",
            )
        else:
            spec["distortion"] = plugin_distortion
    # gazebo_ros_camera_utils: <updateRate> throttles what the plugin publishes of the
    # sensor's frames (0 = every frame the sensor makes, at its <update_rate>)
    spec["plugin_update_rate"] = reader.number(plugin, "updateRate", 0.0, owner=owner, minimum=0.0)
    if kind == "depth":
        spec["depth_topic"] = topic("depthImageTopicName", "depth/image_raw")
        spec["depth_info_topic"] = topic("depthImageCameraInfoTopicName", "depth/camera_info")
        spec["points_topic"] = topic("pointCloudTopicName", "points")
        spec["min_depth"] = reader.number(plugin, "pointCloudCutoff", 0.4, owner=owner)
        max_default = 5.0 if filename == "libgazebo_ros_openni_kinect.so" else -1.0
        cutoff_max = reader.number(plugin, "pointCloudCutoffMax", max_default, owner=owner)
        spec["max_depth"] = cutoff_max if cutoff_max > 0 else math.inf
        spec["pointcloud"] = reader.boolean(plugin, "pointcloud", True, owner=owner)
        if not spec["pointcloud"]:
            spec["points_topic"] = None
        spec["depth_encoding"] = _depth_encoding(reader, plugin, owner=owner)
    known = (*_CAMERA_ROS1_MARKERS, "alwaysOn", "pointcloud", "depth_format", "depth_noise")
    for child in plugin:
        if child.tag == "alwaysOn":
            continue  # visnav sensors are always on
        if child.tag not in known:
            reader.warn(
                child, f"{owner}plugin element <{child.tag}> is not supported and is ignored"
            )


def parse_imu(reader: SdfReader, sensor: ET.Element, link: str, robot_name: str) -> ImuSpec:
    name = sensor.get("name") or f"{link}_imu"
    owner = f"sensor {name!r}: "
    update_rate = reader.number(sensor, "update_rate", 0.0, owner=owner, minimum=0.0)
    reader.unknown(sensor, (*_SENSOR_COMMON, "imu"), owner=owner, what="an IMU sensor")
    gyro = [GaussianNoise()] * 3
    accel = [GaussianNoise()] * 3
    imu_el = sensor.find("imu")
    if imu_el is not None:
        for group, target in (("angular_velocity", gyro), ("linear_acceleration", accel)):
            group_el = imu_el.find(group)
            if group_el is None:
                continue
            for i, axis in enumerate("xyz"):
                axis_el = group_el.find(axis)
                if axis_el is not None:
                    target[i] = reader.noise(axis_el.find("noise"), owner=owner)
        legacy = imu_el.find("noise")
        if legacy is not None:  # SDF 1.4: <noise><rate>..</rate><accel>..</accel></noise>
            for tag, target in (("rate", gyro), ("accel", accel)):
                part = legacy.find(tag)
                if part is not None:
                    legacy_kind = reader.text(legacy, "type") or "gaussian"
                    target[:] = [reader.noise(part, owner=owner, kind=legacy_kind)] * 3
        for child in imu_el:
            if child.tag not in ("angular_velocity", "linear_acceleration", "noise"):
                reader.warn(child, f"{owner}<imu><{child.tag}> is not supported and is ignored")
    spec: dict[str, object] = {
        "name": name, "link": link, "pose": reader.pose(sensor, owner=owner),
        "update_rate": update_rate, "frame_id": link,
        "angular_velocity_noise": tuple(gyro), "linear_acceleration_noise": tuple(accel),
    }  # fmt: skip
    plugin = reader.sensor_plugin(
        sensor, _IMU_PLUGINS, owner=owner, what="IMU",
        add='<plugin filename="libgazebo_ros_imu_sensor.so">',
    )  # fmt: skip
    if plugin is None:
        return ImuSpec(**spec)  # type: ignore[arg-type]
    spec["plugin"] = plugin.get("filename")
    spec["plugin_name"] = plugin.get("name") or ""
    ros1_markers = (
        "robotNamespace",
        "topicName",
        "frameName",
        "updateRateHZ",
        "gaussianNoise",
        "bodyName",
        "xyzOffset",
        "rpyOffset",
    )
    if plugin.find("ros") is None and has_any(plugin, ros1_markers):
        ns = reader.text(plugin, "robotNamespace")
        if ns is None:
            ns = f"/{robot_name}/"
        spec["ros_version"] = 1
        spec["topic"] = ros1_join(ns, reader.text(plugin, "topicName") or "imu_data")
        frame = reader.text(plugin, "frameName")
        if frame is None:
            raise reader.error(
                plugin,
                f"{owner}gazebo_ros_imu_sensor (ROS 1) needs <frameName>",
                f"add <frameName>{link}</frameName>",
            )
        spec["frame_id"] = frame
        plugin_rate = reader.number(plugin, "updateRateHZ", 1.0, owner=owner, minimum=0.0)
        spec["update_rate"] = (
            min(r for r in (plugin_rate, update_rate) if r > 0)
            if (plugin_rate > 0 or update_rate > 0)
            else 0.0
        )
        sigma = reader.number(plugin, "gaussianNoise", 0.0, owner=owner, minimum=0.0)
        if sigma:
            spec["angular_velocity_noise"] = (GaussianNoise(stddev=sigma),) * 3
            spec["linear_acceleration_noise"] = (GaussianNoise(stddev=sigma),) * 3
            spec["orientation_noise_stddev"] = sigma
        reader.unknown(plugin, ros1_markers, owner=owner, what="the IMU plugin")
    else:
        node = plugin_node(reader, plugin, owner=owner)
        spec["ros_version"] = 2
        spec["topic"] = node.resolve("~/out")
        spec["frame_id"] = reader.text(plugin, "frame_name") or link
        spec["initial_orientation_as_reference"] = reader.boolean(
            plugin, "initial_orientation_as_reference", False, owner=owner
        )
        reader.unknown(
            plugin,
            ("ros", "frame_name", "initial_orientation_as_reference"),
            owner=owner,
            what="the IMU plugin",
        )
    return ImuSpec(**spec)  # type: ignore[arg-type]
