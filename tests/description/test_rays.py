"""Ray sensors (``ray``, ``gpu_ray``, ``lidar``) and their gazebo_ros plugins: names, errors."""

from __future__ import annotations

import math
import warnings

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.description.gazebo import GazeboExtensions, parse_gazebo_extensions
from visnav.description.gazebo_specs import RayScan, RaySpec
from visnav.description.urdf import RobotDescriptionError, parse_urdf
from visnav.errors import VisnavError

INERTIA = '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'
LINKS = f"""
  <link name="base_link"><inertial><mass value="5"/>{INERTIA}</inertial></link>
  <link name="base_scan"/>
  <joint name="scan_joint" type="fixed"><parent link="base_link"/><child link="base_scan"/>
    <origin xyz="0 0 0.2"/></joint>
"""
RAY = """<ray><scan><horizontal><samples>360</samples><resolution>1</resolution>
  <min_angle>0.0</min_angle><max_angle>6.28319</max_angle></horizontal></scan>
  <range><min>0.12</min><max>3.5</max><resolution>0.015</resolution></range>
  <noise><type>gaussian</type><mean>0.0</mean><stddev>0.01</stddev></noise></ray>"""


def extensions(gazebo: str) -> GazeboExtensions:
    text = f'<?xml version="1.0"?>\n<robot name="bot">{LINKS}\n{gazebo}\n</robot>'
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return parse_gazebo_extensions(parse_urdf(text, source="bot.urdf"))


def sensor(plugin: str, *, ray: str = RAY, kind: str = "ray", extra: str = "") -> str:
    return f"""<gazebo reference="base_scan"><sensor type="{kind}" name="lds">
      <pose>0.01 0 0.02 0 0 0.1</pose><update_rate>5</update_rate>{ray}{extra}{plugin}
    </sensor></gazebo>"""


def one_ray(gazebo: str) -> RaySpec:
    rays = extensions(gazebo).rays
    assert len(rays) == 1
    return rays[0]


def bad(gazebo: str) -> str:
    with pytest.raises(RobotDescriptionError) as info:
        extensions(gazebo)
    text = str(info.value)
    assert text.startswith("bot.urdf:")
    assert "Fix:" in text
    return text


def warned(gazebo: str) -> list[str]:
    return list(extensions(gazebo).warnings)


# --------------------------------------------------------------------------- SDF


def test_turtlebot3_lds_block() -> None:
    plugin = """<plugin name="lds_ctrl" filename="libgazebo_ros_laser.so">
      <topicName>scan</topicName><frameName>base_scan</frameName></plugin>"""
    ray = one_ray(sensor(plugin))
    assert (ray.name, ray.link, ray.kind, ray.update_rate) == ("lds", "base_scan", "ray", 5.0)
    assert ray.horizontal == RayScan(samples=360, resolution=1.0, min_angle=0.0, max_angle=6.28319)
    assert ray.vertical == RayScan()
    assert (ray.range_min, ray.range_max, ray.range_resolution) == (0.12, 3.5, 0.015)
    assert (ray.noise.mean, ray.noise.stddev) == (0.0, 0.01)
    assert ray.pose.xyz == (0.01, 0.0, 0.02)
    assert ray.pose.rpy == (0.0, 0.0, 0.1)
    assert (ray.flavor, ray.output, ray.ros_version) == ("laser", "LaserScan", 1)
    assert (ray.topic, ray.frame_id) == ("/scan", "base_scan")
    assert (ray.plugin, ray.plugin_name) == ("libgazebo_ros_laser.so", "lds_ctrl")
    assert ray.horizontal.step == pytest.approx(6.28319 / 359)


def test_scan_defaults_and_lidar_element() -> None:
    lidar = """<lidar><scan><horizontal><samples>100</samples><min_angle>-1</min_angle>
      <max_angle>1</max_angle></horizontal><vertical><samples>4</samples><resolution>2</resolution>
      <min_angle>-0.1</min_angle><max_angle>0.1</max_angle></vertical></scan>
      <range><min>0.1</min><max>30</max></range></lidar>"""
    plugin = '<plugin name="p" filename="libgazebo_ros_velodyne_laser.so"><topicName>pts'
    plugin += "</topicName></plugin>"
    ray = one_ray(sensor(plugin, ray=lidar, kind="gpu_lidar"))
    assert ray.kind == "gpu_lidar"
    assert ray.horizontal.resolution == 1.0
    assert (ray.vertical.samples, ray.vertical.count) == (4, 8)
    assert ray.vertical.step == pytest.approx(0.2 / 7)
    assert ray.noise.active is False
    no_scan = one_ray(sensor("", ray="<ray><range><min>0</min><max>5</max></range></ray>"))
    assert no_scan.horizontal == RayScan(samples=640)  # SDF's default


# --------------------------------------------------------------------------- plugins


def test_ros1_laser_names_frames_and_defaults() -> None:
    ns = """<plugin name="l" filename="libgazebo_ros_gpu_laser.so">
      <robotNamespace>/r1</robotNamespace><topicName>scan</topicName>
      <frameName>base_scan</frameName></plugin>"""
    ray = one_ray(sensor(ns, kind="gpu_ray"))
    assert (ray.topic, ray.frame_id, ray.flavor) == ("/r1/scan", "r1/base_scan", "laser")
    absolute = ns.replace("<topicName>scan", "<topicName>/scan").replace(">base_scan", ">/laser")
    ray = one_ray(sensor(absolute))
    assert (ray.topic, ray.frame_id) == ("/scan", "laser")  # absolute names: no namespace
    empty_ns = ns.replace("<robotNamespace>/r1</robotNamespace>", "<robotNamespace/>")
    assert one_ray(sensor(empty_ns)).topic == "/bot/scan"  # empty: the model's name
    bare = '<plugin name="l" filename="libgazebo_ros_laser.so"/>'
    ray = one_ray(sensor(bare))
    assert (ray.topic, ray.frame_id) == ("/world", "world")  # gazebo_ros_laser's defaults
    texts = warned(sensor(bare))
    assert any("<frameName> is missing" in w for w in texts)
    assert any("<topicName> is missing" in w for w in texts)


def test_ros2_ray_sensor_outputs_names_and_frames() -> None:
    plugin = """<plugin name="lidar" filename="libgazebo_ros_ray_sensor.so">
      <ros><namespace>/tb</namespace><remapping>~/out:=scan</remapping></ros>
      <output_type>sensor_msgs/LaserScan</output_type><frame_name>base_scan</frame_name>
    </plugin>"""
    ray = one_ray(sensor(plugin))
    assert (ray.flavor, ray.output, ray.ros_version) == ("ray_sensor", "LaserScan", 2)
    assert (ray.topic, ray.frame_id) == ("/tb/scan", "base_scan")
    bare = '<plugin name="lidar" filename="libgazebo_ros_ray_sensor.so"/>'
    ray = one_ray(sensor(bare))
    assert (ray.output, ray.topic, ray.frame_id) == ("PointCloud2", "/lidar/out", "base_scan")
    assert any("<output_type> is missing" in w for w in warned(sensor(bare)))
    for output in ("PointCloud", "PointCloud2", "Range"):
        text = plugin.replace("LaserScan", output)
        assert one_ray(sensor(text)).output == output
    msg2 = plugin.replace("sensor_msgs/LaserScan", "sensor_msgs/msg/Range")
    rng = plugin.replace(
        "</output_type>", "</output_type><radiation_type>ultrasound</radiation_type>"
    )
    ray = one_ray(sensor(rng.replace("LaserScan", "Range")))
    assert (ray.output, ray.radiation_type) == ("Range", 0)
    assert ray.field_of_view == pytest.approx(6.28319)
    assert one_ray(sensor(msg2)).radiation_type == 1  # infrared by default
    intensity = plugin.replace("</frame_name>", "</frame_name><min_intensity>5</min_intensity>")
    assert one_ray(sensor(intensity)).min_intensity == 5.0


def test_velodyne_ros1_and_ros2() -> None:
    ros1 = """<plugin name="vlp" filename="libgazebo_ros_velodyne_laser.so">
      <robotNamespace>/car</robotNamespace><topicName>velodyne_points</topicName>
      <frameName>velodyne</frameName><min_range>0.9</min_range><max_range>130.0</max_range>
      <gaussianNoise>0.008</gaussianNoise><min_intensity>10</min_intensity>
      <organize_cloud>true</organize_cloud></plugin>"""
    ray = one_ray(sensor(ros1))
    assert (ray.flavor, ray.output, ray.ros_version) == ("velodyne", "PointCloud2", 1)
    assert (ray.topic, ray.frame_id) == ("/car/velodyne_points", "car/velodyne")
    assert (ray.plugin_min_range, ray.plugin_max_range) == (0.9, 130.0)
    assert (ray.gaussian_noise, ray.min_intensity, ray.organize_cloud) == (0.008, 10.0, True)
    bare = '<plugin name="v" filename="libgazebo_ros_velodyne_gpu_laser.so"><topicName>p'
    bare += "</topicName></plugin>"
    ray = one_ray(sensor(bare))
    assert (ray.topic, ray.frame_id) == ("/p", "world")
    assert (ray.min_intensity, ray.plugin_max_range, ray.organize_cloud) == (
        -math.inf,
        math.inf,
        False,
    )
    ros2 = """<plugin name="vlp" filename="libgazebo_ros_velodyne_laser.so">
      <ros><namespace>/car</namespace><remapping>~/out:=velodyne_points</remapping></ros>
      <frame_name>velodyne</frame_name><gaussian_noise>0.01</gaussian_noise></plugin>"""
    ray = one_ray(sensor(ros2))
    assert (ray.ros_version, ray.topic, ray.frame_id) == (2, "/car/velodyne_points", "velodyne")
    assert ray.gaussian_noise == 0.01


def test_ros1_range_plugin() -> None:
    plugin = """<plugin name="sonar" filename="libgazebo_ros_range.so">
      <robotNamespace>/r</robotNamespace><topicName>sonar_front</topicName>
      <frameName>base_scan</frameName><radiation>infrared</radiation><fov>0.3</fov>
      <gaussianNoise>0.005</gaussianNoise><updateRate>2</updateRate></plugin>"""
    ray = one_ray(sensor(plugin))
    assert (ray.flavor, ray.output, ray.ros_version) == ("range", "Range", 1)
    assert (ray.topic, ray.frame_id) == ("/r/sonar_front", "base_scan")  # no tf prefix
    assert (ray.radiation_type, ray.field_of_view, ray.gaussian_noise) == (1, 0.3, 0.005)
    assert ray.update_rate == 2.0  # the slower of sensor (5) and plugin (2)
    bare = '<plugin name="s" filename="libgazebo_ros_range.so"/>'
    ray = one_ray(sensor(bare))
    assert (ray.topic, ray.frame_id, ray.radiation_type) == ("/range", "world", 0)
    assert ray.field_of_view == 0.05
    assert any("<radiation> is missing" in w for w in warned(sensor(bare)))


def test_sensor_without_plugin_publishes_nothing_and_unknowns_warn() -> None:
    ray = one_ray(sensor(""))
    assert ray.topic is None
    assert ray.flavor is None
    texts = warned(sensor("", extra="<camera/>"))
    assert any("no gazebo_ros ray plugin" in w for w in texts)
    assert any("<camera> in a ray sensor is not supported" in w for w in texts)
    block = '<plugin name="b" filename="libgazebo_ros_block_laser.so"/>'
    assert any("libgazebo_ros_block_laser.so" in w for w in warned(sensor(block)))
    odd = '<plugin name="l" filename="libgazebo_ros_laser.so"><topicName>s</topicName>'
    odd += "<frameName>f</frameName><hokuyoMinIntensity>101</hokuyoMinIntensity></plugin>"
    assert any("<hokuyoMinIntensity>" in w for w in warned(sensor(odd)))
    assert all("bot.urdf:" in w for w in warned(sensor(odd)))


# --------------------------------------------------------------------------- errors

LASER = '<plugin name="l" filename="libgazebo_ros_laser.so"><topicName>s</topicName></plugin>'


@pytest.mark.parametrize(
    ("ray", "words"),
    [
        ("", "needs a <ray>"),
        ("<ray><scan/></ray>", "needs <range>"),
        ("<ray><range><min>1</min><max>0.5</max></range></ray>", "not beyond min"),
        ("<ray><range><min>-1</min><max>5</max></range></ray>", "out of range"),
        ("<ray><range><min>0</min><max>inf</max></range></ray>", "not a finite number"),
        (
            "<ray><scan><horizontal><samples>0</samples></horizontal></scan>"
            "<range><min>0</min><max>5</max></range></ray>",
            "not a positive integer",
        ),
        (
            "<ray><scan><horizontal><samples>ten</samples></horizontal></scan>"
            "<range><min>0</min><max>5</max></range></ray>",
            "not a positive integer",
        ),
        (
            "<ray><scan><horizontal><samples>4</samples><min_angle>1</min_angle>"
            "<max_angle>-1</max_angle></horizontal></scan><range><min>0</min><max>5</max>"
            "</range></ray>",
            "below min_angle",
        ),
        (
            "<ray><scan><vertical><samples>2</samples><resolution>0.1</resolution></vertical>"
            "</scan><range><min>0</min><max>5</max></range></ray>",
            "less than one range",
        ),
    ],
)
def test_bad_ray_blocks_are_located_errors(ray: str, words: str) -> None:
    text = bad(sensor(LASER, ray=ray))
    assert words in text
    assert "lds" in text


def test_bad_plugin_values_are_located_errors() -> None:
    ray2 = '<plugin name="p" filename="libgazebo_ros_ray_sensor.so"><output_type>{}</output_type>'
    assert "sensor_msgs/Image" in bad(sensor(ray2.format("sensor_msgs/Image") + "</plugin>"))
    radiation = ray2.format("sensor_msgs/Range") + "<radiation_type>sonar</radiation_type></plugin>"
    assert "neither ultrasound nor infrared" in bad(sensor(radiation))
    organize = '<plugin name="v" filename="libgazebo_ros_velodyne_laser.so"><topicName>p'
    organize += "</topicName><organize_cloud>maybe</organize_cloud></plugin>"
    assert "not a boolean" in bad(sensor(organize))
    noise = LASER.replace("</plugin>", "") + "</plugin>"
    assert "not a finite number" in bad(sensor(noise, ray=RAY.replace("<stddev>0.01", "<stddev>x")))


# --------------------------------------------------------------------------- fuzz

_FILENAMES = (
    "libgazebo_ros_laser.so",
    "libgazebo_ros_gpu_laser.so",
    "libgazebo_ros_ray_sensor.so",
    "libgazebo_ros_velodyne_laser.so",
    "libgazebo_ros_range.so",
    "libother.so",
)
_TAGS = (
    "topicName", "frameName", "robotNamespace", "output_type", "frame_name", "min_intensity",
    "radiation_type", "radiation", "fov", "gaussianNoise", "gaussian_noise", "min_range",
    "max_range", "organize_cloud", "updateRate", "tf_prefix", "alwaysOn",
)  # fmt: skip
_values = st.one_of(
    st.sampled_from(
        [
            "",
            "0",
            "1",
            "-1",
            "5",
            "0.5",
            "1e9",
            "nan",
            "inf",
            "true",
            "maybe",
            "scan",
            "/a/b",
            "sensor_msgs/LaserScan",
            "sensor_msgs/Range",
            "sensor_msgs/PointCloud",
            "ultrasound",
        ]
    ),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-5, 5000).map(str),
    st.text(alphabet="ab/~:=_ .-", max_size=8),
)


@st.composite
def ray_blocks(draw: st.DrawFn) -> str:
    def element(tag: str) -> str:
        return f"<{tag}>{draw(_values)}</{tag}>" if draw(st.booleans()) else ""

    def axis(tag: str) -> str:
        inner = "".join(element(t) for t in ("samples", "resolution", "min_angle", "max_angle"))
        return f"<{tag}>{inner}</{tag}>" if draw(st.booleans()) else ""

    scan = f"<scan>{axis('horizontal')}{axis('vertical')}</scan>" if draw(st.booleans()) else ""
    rng = "<range>" + "".join(element(t) for t in ("min", "max", "resolution")) + "</range>"
    noise = "<noise>" + element("type") + element("mean") + element("stddev") + "</noise>"
    body = scan + (rng if draw(st.booleans()) else "") + (noise if draw(st.booleans()) else "")
    ray = f"<{draw(st.sampled_from(['ray', 'lidar']))}>{body}</ray>"
    ray = ray.replace("</ray>", "</lidar>") if ray.startswith("<lidar>") else ray
    tags = draw(st.lists(st.sampled_from(_TAGS), max_size=6))
    ros = "<ros><namespace>/n</namespace><remapping>~/out:=x</remapping></ros>"
    plugin_body = "".join(f"<{t}>{draw(_values)}</{t}>" for t in tags)
    plugin_body += ros if draw(st.booleans()) else ""
    filename = draw(st.sampled_from(_FILENAMES))
    plugin = f'<plugin name="p" filename="{filename}">{plugin_body}</plugin>'
    kind = draw(st.sampled_from(["ray", "gpu_ray", "lidar", "gpu_lidar"]))
    rate = element("update_rate")
    return f"""<gazebo reference="base_scan"><sensor type="{kind}" name="s">{rate}{ray}
      {plugin if draw(st.booleans()) else ""}</sensor></gazebo>"""


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(ray_blocks())
def test_random_ray_blocks_raise_only_visnav_errors(block: str) -> None:
    try:
        rays = extensions(block).rays
    except VisnavError:
        return
    assert len(rays) == 1
    ray = rays[0]
    assert ray.range_max > ray.range_min >= 0.0
    assert ray.horizontal.count >= 1
    assert ray.vertical.count >= 1
    assert ray.topic is None or ray.topic.startswith("/")


def test_two_sensors_of_one_name_are_refused_across_kinds() -> None:
    laser = (
        '<plugin name="l" filename="libgazebo_ros_laser.so"><topicName>scan</topicName></plugin>'
    )
    imu = '<gazebo reference="base_link"><sensor type="imu" name="lds"/></gazebo>'
    text = bad(sensor(laser) + imu)
    assert "two sensors are named 'lds'" in text
