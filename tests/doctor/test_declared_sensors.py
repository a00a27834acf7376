"""Sensors robot_description declares against the graph; an empty graph is an error."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from visnav.cli.main import main
from visnav.doctor import LiveObserver, Severity, diagnose
from visnav.doctor.declared import declared_from, declared_sensors, spec_output_topics
from visnav.doctor.synthetic import StreamEvent, events_to_observation
from visnav.graph import Context, Node
from visnav.graph.qos import qos_profile_latched
from visnav.msgs import CameraInfo, Image, JointState, LaserScan, String, make

from .conftest import endpoint, graph, none_of, one, run, stream

URDF = """<?xml version="1.0"?>
<robot name="probe">
  <link name="base_link"/>
  <link name="camera_link"/>
  <link name="lidar_link"/>
  <joint name="camera_joint" type="fixed">
    <parent link="base_link"/><child link="camera_link"/>
  </joint>
  <joint name="lidar_joint" type="fixed">
    <parent link="base_link"/><child link="lidar_link"/>
  </joint>
  <gazebo reference="camera_link">
    <sensor type="camera" name="front_camera">
      <update_rate>10</update_rate>
      <camera>
        <horizontal_fov>1.0</horizontal_fov><image><width>64</width><height>48</height></image>
      </camera>
      <plugin name="front_camera_plugin" filename="libgazebo_ros_camera.so"/>
    </sensor>
  </gazebo>
  <gazebo reference="lidar_link">
    <sensor type="ray" name="lidar">
      <update_rate>5</update_rate>
      <ray>
        <scan><horizontal><samples>90</samples>
          <min_angle>-1.5</min_angle><max_angle>1.5</max_angle></horizontal></scan>
        <range><min>0.1</min><max>8</max></range>
      </ray>
      <plugin name="lidar_plugin" filename="libgazebo_ros_ray_sensor.so">
        <ros><remapping>~/out:=scan</remapping></ros>
        <output_type>sensor_msgs/LaserScan</output_type>
      </plugin>
    </sensor>
    <sensor type="sonar" name="front_sonar"><update_rate>5</update_rate></sensor>
  </gazebo>
  <link name="wheel_link"/>
  <joint name="wheel_joint" type="continuous">
    <parent link="base_link"/><child link="wheel_link"/><axis xyz="0 1 0"/>
  </joint>
  <gazebo>
    <plugin name="states" filename="libgazebo_ros_joint_state_publisher.so">
      <joint_name>wheel_joint</joint_name>
    </plugin>
  </gazebo>
</robot>
"""


def _publish_some(ctx: Context, observer: LiveObserver, *, scan: bool) -> None:
    """A "simulator" publishing robot_description and the camera, a SLAM node wanting /scan."""
    sim = Node("sim", context=ctx)
    slam = Node("slam", context=ctx)
    slam.create_subscription(LaserScan, "/scan", lambda _msg: None, 10)
    desc = sim.create_publisher(String, "/robot_description", qos_profile_latched)
    image = sim.create_publisher(Image, "/front_camera/image_raw", 10)
    info = sim.create_publisher(CameraInfo, "/front_camera/camera_info", 10)
    joint_states = sim.create_publisher(JointState, "/joint_states", 10)
    scan_pub = sim.create_publisher(LaserScan, "/scan", 10) if scan else None
    observer.poll()
    desc.publish(String(data=URDF))
    for _ in range(3):
        image.publish(make(Image, height=48, width=64, encoding="rgb8", step=192, data=bytes(9216)))
        info.publish(make(CameraInfo, height=48, width=64))
        joint_states.publish(make(JointState, name=["wheel_joint"], position=[0.0]))
        if scan_pub is not None:
            scan_pub.publish(make(LaserScan, ranges=[1.0] * 90))
        ctx.spin_some()
    ctx.spin_some()


def _live_report(*, scan: bool):  # type: ignore[no-untyped-def]
    with Context(transport="local") as ctx:
        observer = LiveObserver(ctx)
        _publish_some(ctx, observer, scan=scan)
        obs = observer.observation()
        observer.close()
    assert obs.robot_description == URDF
    return diagnose(obs)


def test_a_declared_sensor_nobody_publishes_is_an_error() -> None:
    report = _live_report(scan=False)
    found = one(
        report,
        "description.sensor_unpublished",
        subject="/scan",
        severity=Severity.ERROR,
        sensor="lidar",
        unpublished_topics=["/scan"],
    )
    assert found.evidence["declared_as"] == '<sensor type="ray"> with libgazebo_ros_ray_sensor.so'
    assert found.evidence["subscribers_waiting"] == ["/slam"]
    assert "sensor 'lidar'" in found.title
    assert "/scan" in found.title
    # the camera and the joint state publisher publish what they declare
    assert [f.subject for f in report.find("description.sensor_unpublished")] == ["/scan"]


def test_a_declared_sensor_that_publishes_is_quiet() -> None:
    report = _live_report(scan=True)
    none_of(report, "description.sensor_unpublished")


def test_an_ignored_sensor_is_named_as_not_simulated() -> None:
    report = _live_report(scan=True)
    found = one(report, "description.sensor_ignored", subject="front_sonar")
    assert found.severity is Severity.ERROR
    assert found.evidence["tag"] == "sensor"
    assert "of type 'sonar' is not supported" in found.title
    assert "not simulated by visnav" in found.title


def test_in_a_bag_the_ignored_sensor_is_a_warning_and_topics_are_not_required() -> None:
    report = run(stream(duration_s=1.0), robot_description=URDF)
    one(report, "description.sensor_ignored", subject="front_sonar", severity=Severity.WARNING)
    none_of(report, "description.sensor_unpublished")  # a bag may hold a selection


def test_a_namespaced_description_declares_namespaced_topics() -> None:
    declared = declared_from(URDF, "/r1/robot_description", None)
    assert [s.topics for s in declared.sensors] == [
        ("/r1/front_camera/image_raw", "/r1/front_camera/camera_info"),
        ("/r1/joint_states",),
        ("/r1/scan",),
    ]
    evs = stream(duration_s=1.0)
    evs.insert(
        0, StreamEvent("/r1/robot_description", "std_msgs/msg/String", evs[0].receive_ns,
                       String(data=URDF))
    )  # fmt: skip
    snapshot = graph(
        endpoint("publisher", "/r1/robot_description", "std_msgs/msg/String", "sim"),
        endpoint("publisher", "/r1/front_camera/image_raw", "sensor_msgs/msg/Image", "sim"),
        endpoint("publisher", "/r1/front_camera/camera_info", "sensor_msgs/msg/CameraInfo", "sim"),
        endpoint("publisher", "/r1/joint_states", "sensor_msgs/msg/JointState", "sim"),
        endpoint("publisher", "/scan", "sensor_msgs/msg/LaserScan", "other"),
    )
    report = diagnose(events_to_observation(evs, source="live", graph=snapshot))
    found = report.find("description.sensor_unpublished")
    assert [f.subject for f in found] == ["/r1/scan"]  # /scan at the root is not the robot's
    assert found[0].evidence["exists_under_other_namespace"] == ["/scan"]
    assert "published as /scan" in found[0].fix


# --------------------------------------------------------------------------- generic specs


@dataclass(frozen=True)
class _NewSensorSpec:
    """A spec another helper might add: found by its *_topic fields alone."""

    name: str
    link: str
    kind: str = "thermal"
    topic: str | None = "/thermal/image"
    info_topic: str = "/thermal/info"
    command_topic: str = "/thermal/cmd"
    publish_info: bool = True
    plugin: str | None = "libthermal.so"


@dataclass(frozen=True)
class _NewPluginSpec:
    plugin_name: str
    odometry_topic: str = "/odom"
    joint_states_topic: str = "/joint_states"
    publish_odom: bool = False
    publish_odom_tf: bool = True
    publish_wheel_joint_state: bool = True


@dataclass(frozen=True)
class _Extensions:
    thermals: tuple[_NewSensorSpec, ...] = ()
    bases: tuple[_NewPluginSpec, ...] = ()
    warnings: tuple[str, ...] = ()


def test_output_topics_of_any_spec() -> None:
    spec = _NewSensorSpec(name="t", link="l")
    assert spec_output_topics(spec) == ["/thermal/image", "/thermal/info"]  # command left out
    assert spec_output_topics(_NewSensorSpec(name="t", link="l", publish_info=False)) == [
        "/thermal/image"
    ]
    assert spec_output_topics(_NewSensorSpec(name="t", link="l", topic=None)) == ["/thermal/info"]
    # publish_odom false turns odometry_topic off; publish_odom_tf (TF) is not about topics
    assert spec_output_topics(_NewPluginSpec(plugin_name="drive")) == ["/joint_states"]


def test_every_tuple_field_of_the_extensions_is_enumerated() -> None:
    ext = _Extensions(
        thermals=(_NewSensorSpec(name="rear", link="l"),),
        bases=(_NewPluginSpec(plugin_name="drive", publish_odom=True),),
    )
    sensors = declared_sensors(ext, "/r2")
    assert [(s.name, s.kind, s.declared_as, s.topics) for s in sensors] == [
        (
            "rear",
            "thermals",
            '<sensor type="thermal"> with libthermal.so',
            ("/r2/thermal/image", "/r2/thermal/info"),
        ),
        ("drive", "bases", "<plugin> base", ("/r2/odom", "/r2/joint_states")),
    ]


# --------------------------------------------------------------------------- empty graph


def test_an_empty_graph_is_a_one_line_error_with_exit_code_1(
    domain: int, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["doctor", "--duration", "0.3"])
    out, err = capsys.readouterr()
    assert code == 1
    assert "healthy" not in out
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(lines) == 1, err
    assert lines[0].startswith(
        f"error: no topics in graph domain {domain}: is anything running, in this VISNAV_DOMAIN?"
    )
