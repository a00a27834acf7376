"""gazebo_ros model plugins as users write them: ROS 1 IMU, diff drive (ROS 1), skid steer,
planar move, and the camera's ROS 1 ``<updateRate>``; names and defaults are gazebo_ros'."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.description.gazebo import GazeboExtensions, parse_gazebo_extensions
from visnav.description.robot import load_robot
from visnav.description.urdf import RobotDescriptionError, parse_urdf
from visnav.errors import VisnavError

TB3 = Path(__file__).resolve().parent.parent / "data" / "turtlebot3" / "turtlebot3_description"

INERTIA = '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'


def _wheel(name: str, x: float, y: float) -> str:
    return f"""
  <link name="{name}"><inertial><mass value="0.5"/>{INERTIA}</inertial></link>
  <joint name="{name}_joint" type="continuous"><parent link="base_link"/>
    <child link="{name}"/><origin xyz="{x} {y} 0"/><axis xyz="0 1 0"/></joint>"""


LINKS = f"""
  <link name="base_footprint"/>
  <link name="base_link"><inertial><mass value="5"/>{INERTIA}</inertial></link>
  <joint name="base_joint" type="fixed"><parent link="base_footprint"/><child link="base_link"/>
  </joint>
  <link name="imu_link"/>
  <joint name="imu_joint" type="fixed"><parent link="base_link"/><child link="imu_link"/>
    <origin xyz="0 0 0.1"/></joint>
  {_wheel("lf", 0.2, 0.25)}{_wheel("rf", 0.2, -0.25)}{_wheel("lr", -0.2, 0.25)}
  {_wheel("rr", -0.2, -0.25)}
"""


def extensions(gazebo: str) -> GazeboExtensions:
    text = f'<?xml version="1.0"?>\n<robot name="bot">{LINKS}\n{gazebo}\n</robot>'
    return parse_gazebo_extensions(parse_urdf(text, source="bot.urdf"))


def plugin(filename: str, body: str, name: str = "p") -> GazeboExtensions:
    return extensions(
        f'<gazebo><plugin name="{name}" filename="{filename}">{body}</plugin></gazebo>'
    )


def bad(filename: str, body: str) -> str:
    with pytest.raises(RobotDescriptionError) as info:
        plugin(filename, body)
    text = str(info.value)
    assert text.startswith("bot.urdf:")
    assert "Fix:" in text
    return text


def tb3(model: str) -> GazeboExtensions:
    urdf = TB3 / "urdf" / f"turtlebot3_{model}.urdf.xacro"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_robot(urdf, packages={"turtlebot3_description": TB3}).gazebo


# --------------------------------------------------------------------------- ROS 1 IMU


def test_ros1_imu_model_plugin_names_and_defaults() -> None:
    ext = plugin("libgazebo_ros_imu.so", "<bodyName>imu_link</bodyName>")
    (imu,) = ext.imu_plugins
    # gazebo_ros_imu: topic and service default to /default_imu, the frame to the body
    assert (imu.topic, imu.service, imu.frame_id) == ("/default_imu", "/default_imu", "imu_link")
    assert (imu.update_rate, imu.gaussian_noise) == (0.0, 0.0)
    assert ext.imus == ()  # not the <sensor type="imu"> plugin


def test_ros1_imu_topic_in_robot_namespace_and_offsets() -> None:
    (imu,) = plugin(
        "libgazebo_ros_imu.so",
        "<robotNamespace>/r1</robotNamespace><bodyName>base_link</bodyName>"
        "<topicName>imu/data</topicName><serviceName>calib</serviceName>"
        "<frameName>imu_frame</frameName><gaussianNoise>0.01</gaussianNoise>"
        "<updateRate>50</updateRate><xyzOffset>0 0 0.1</xyzOffset><rpyOffset>0 0 1.57</rpyOffset>",
    ).imu_plugins
    assert (imu.topic, imu.service) == ("/r1/imu/data", "/r1/calib")
    assert imu.frame_id == "imu_frame"  # frameName is used as written (no tf_prefix)
    assert (imu.update_rate, imu.gaussian_noise) == (50.0, 0.01)
    assert imu.rpy_offset == (0.0, 0.0, 1.57)
    assert imu.xyz_offset == (0.0, 0.0, 0.1)


def test_ros1_imu_empty_topic_publishes_nothing_and_body_is_required() -> None:
    (imu,) = plugin(
        "libgazebo_ros_imu.so", "<bodyName>base_link</bodyName><topicName></topicName>"
    ).imu_plugins
    assert imu.topic is None
    assert imu.service is None
    assert "missing <bodyName>" in bad("libgazebo_ros_imu.so", "<topicName>imu</topicName>")
    assert "'nope' is not a link" in bad("libgazebo_ros_imu.so", "<bodyName>nope</bodyName>")


def test_turtlebot3_imu_plugin_reads_no_imu_noise_block() -> None:
    for model in ("burger", "waffle_pi"):
        ext = tb3(model)
        (imu,) = ext.imu_plugins
        assert (imu.topic, imu.frame_id, imu.update_rate) == ("/imu", "imu_link", 0.0)
        assert imu.gaussian_noise == 0.0  # the <imu><noise> block is not read by the plugin
        assert any("reads no <imu> block" in w for w in ext.warnings)


# --------------------------------------------------------------------------- diff drive (ROS 1)


def test_turtlebot3_diff_drive_as_ros1_reads_it() -> None:
    (drive,) = tb3("burger").diff_drives
    assert drive.ros_version == 1
    assert (drive.command_topic, drive.odometry_topic) == ("/cmd_vel", "/odom")
    assert (drive.odometry_frame, drive.robot_base_frame) == ("odom", "base_footprint")
    assert drive.publish_odom
    assert drive.publish_odom_tf
    assert not drive.publish_wheel_tf
    assert drive.publish_wheel_joint_state
    assert drive.joint_states_topic == "/joint_states"
    assert not drive.legacy_mode
    assert drive.update_rate == 30.0
    assert (drive.wheel_separation, drive.wheel_diameter) == ((0.16,), (0.066,))
    assert (drive.max_wheel_acceleration, drive.max_wheel_torque) == (1.0, 10.0)


DIFF = (
    "<leftJoint>lf_joint</leftJoint><rightJoint>rf_joint</rightJoint>"
    "<wheelSeparation>0.5</wheelSeparation><wheelDiameter>0.1</wheelDiameter>"
)


def test_ros1_diff_drive_flags_and_namespace() -> None:
    (drive,) = plugin(
        "libgazebo_ros_diff_drive.so",
        DIFF + "<robotNamespace>r2</robotNamespace><publishTf>false</publishTf>"
        "<publishWheelTF>1</publishWheelTF><publishWheelJointState>true</publishWheelJointState>"
        "<legacyMode>true</legacyMode><rosDebugLevel>Debug</rosDebugLevel>",
    ).diff_drives
    # publishTf false: no odometry topic and no odom TF (publishOdomTF defaults true)
    assert not drive.publish_odom
    assert not drive.publish_odom_tf
    assert drive.publish_wheel_tf
    assert drive.publish_wheel_joint_state
    assert drive.joint_states_topic == "/r2/joint_states"
    assert drive.command_topic == "/r2/cmd_vel"
    assert (drive.odometry_frame, drive.robot_base_frame) == ("r2/odom", "r2/base_footprint")
    assert drive.legacy_mode


@pytest.mark.parametrize(
    ("text", "source", "warns"),
    [
        ("world", "world", False),
        ("encoder", "encoder", False),
        ("0", "world", True),  # the ROS 1 lookup has no "0": world, with a warning
        ("1", "world", True),
        ("Encoder", "world", True),  # case-sensitive, as gazebo_ros_utils' map
    ],
)
def test_ros1_odometry_source_lookup(text: str, source: str, warns: bool) -> None:
    ext = plugin("libgazebo_ros_diff_drive.so", DIFF + f"<odometrySource>{text}</odometrySource>")
    assert ext.diff_drives[0].odometry_source == source
    assert any("odometrySource" in w for w in ext.warnings) == warns


def test_ros2_diff_drive_names_unchanged() -> None:
    (drive,) = plugin(
        "libgazebo_ros_diff_drive.so",
        "<ros><namespace>/r</namespace></ros><left_joint>lf_joint</left_joint>"
        "<right_joint>rf_joint</right_joint><publish_odom>true</publish_odom>"
        "<publish_odom_tf>true</publish_odom_tf><publish_wheel_tf>true</publish_wheel_tf>"
        "<odometry_source>0</odometry_source><update_rate>50</update_rate>",
    ).diff_drives
    assert drive.ros_version == 2
    assert (drive.command_topic, drive.odometry_topic) == ("/r/cmd_vel", "/r/odom")
    assert drive.publish_odom
    assert drive.publish_odom_tf
    assert drive.publish_wheel_tf
    assert drive.odometry_source == "encoder"
    assert not drive.publish_wheel_joint_state


# --------------------------------------------------------------------------- skid steer


SKID = (
    "<leftFrontJoint>lf_joint</leftFrontJoint><rightFrontJoint>rf_joint</rightFrontJoint>"
    "<leftRearJoint>lr_joint</leftRearJoint><rightRearJoint>rr_joint</rightRearJoint>"
)


def test_skid_steer_defaults_are_gazebo_ros() -> None:
    (skid,) = plugin("libgazebo_ros_skid_steer_drive.so", SKID).skid_steer_drives
    assert (skid.wheel_separation, skid.wheel_diameter, skid.torque) == (0.4, 0.15, 5.0)
    assert (skid.command_topic, skid.odometry_topic) == ("/cmd_vel", "/odom")
    assert (skid.odometry_frame, skid.robot_base_frame) == ("odom", "base_footprint")
    assert not skid.broadcast_tf
    assert skid.update_rate == 100.0
    assert skid.covariance == (0.0001, 0.0001, 0.01)


def test_skid_steer_parameters() -> None:
    (skid,) = plugin(
        "libgazebo_ros_skid_steer_drive.so",
        SKID + "<robotNamespace>/husky</robotNamespace><wheelSeparation>0.55</wheelSeparation>"
        "<wheelDiameter>0.33</wheelDiameter><torque>35</torque><commandTopic>/cmd</commandTopic>"
        "<odometryTopic>odometry</odometryTopic><broadcastTF>true</broadcastTF>"
        "<covariance_x>0.1</covariance_x><covariance_yaw>0.3</covariance_yaw>"
        "<updateRate>50</updateRate>",
    ).skid_steer_drives
    assert (skid.wheel_separation, skid.wheel_diameter, skid.torque) == (0.55, 0.33, 35.0)
    assert (skid.command_topic, skid.odometry_topic) == ("/cmd", "/husky/odometry")
    assert skid.odometry_frame == "husky/odom"
    assert skid.broadcast_tf
    assert skid.covariance == (0.1, 0.0001, 0.3)
    assert (skid.left_front_joint, skid.right_rear_joint) == ("lf_joint", "rr_joint")


def test_skid_steer_joint_errors_name_the_default() -> None:
    text = bad("libgazebo_ros_skid_steer_drive.so", "<leftFrontJoint>lf_joint</leftFrontJoint>")
    assert "'right_front_joint' is not a joint" in text
    assert "default of a missing element" in text
    assert "is fixed" in bad(
        "libgazebo_ros_skid_steer_drive.so", SKID.replace("lf_joint", "imu_joint")
    )


# --------------------------------------------------------------------------- planar move


def test_planar_move_ros1_defaults() -> None:
    (planar,) = plugin(
        "libgazebo_ros_planar_move.so", "<commandTopic>cmd_vel</commandTopic>"
    ).planar_moves
    assert planar.ros_version == 1
    assert (planar.command_topic, planar.odometry_topic) == ("/cmd_vel", "/odom")
    assert (planar.odometry_frame, planar.robot_base_frame) == ("odom", "base_footprint")
    assert planar.update_rate == 0.0  # every world update
    assert planar.odometry_rate == 20.0
    assert planar.publish_odom
    assert planar.publish_odom_tf
    assert planar.cmd_timeout == -1.0


def test_planar_move_ros1_no_odometry_at_rate_zero_and_tf_switch() -> None:
    (planar,) = plugin(
        "libgazebo_ros_planar_move.so", "<odometryRate>0</odometryRate><cmdTimeout>0.5</cmdTimeout>"
    ).planar_moves
    assert not planar.publish_odom
    assert not planar.publish_odom_tf
    assert planar.cmd_timeout == 0.5
    ext = plugin("libgazebo_ros_planar_move.so", "<publishOdometryTf>false</publishOdometryTf>")
    assert not ext.planar_moves[0].publish_odom_tf
    assert any("publishOdometryTf" in w for w in ext.warnings)


def test_planar_move_ros2_names() -> None:
    (planar,) = plugin(
        "libgazebo_ros_planar_move.so",
        "<ros><namespace>/demo</namespace><remapping>cmd_vel:=cmd_demo</remapping></ros>"
        "<update_rate>100</update_rate><publish_rate>10</publish_rate>"
        "<publish_odom_tf>false</publish_odom_tf><odometry_frame>odom_demo</odometry_frame>",
    ).planar_moves
    assert planar.ros_version == 2
    assert (planar.command_topic, planar.odometry_topic) == ("/demo/cmd_demo", "/demo/odom")
    assert (planar.update_rate, planar.odometry_rate) == (100.0, 10.0)
    assert planar.publish_odom
    assert not planar.publish_odom_tf
    assert planar.odometry_frame == "odom_demo"


# --------------------------------------------------------------------------- camera rate


def test_waffle_pi_camera_plugin_update_rate_throttles() -> None:
    (camera,) = tb3("waffle_pi").cameras
    assert camera.update_rate == 0.0  # the sensor has no <update_rate>
    assert camera.plugin_update_rate == 30.0  # gazebo_ros_camera_utils' <updateRate>
    assert camera.image_topic == "/camera/rgb/image_raw"
    assert camera.camera_info_topic == "/camera/rgb/camera_info"
    assert camera.frame_id == "camera_rgb_optical_frame"
    focal = 640 / (2 * math.tan(1.085595 / 2))
    assert camera.fx == pytest.approx(focal)


# --------------------------------------------------------------------------- fuzz

_FILENAMES = (
    "libgazebo_ros_imu.so",
    "libgazebo_ros_skid_steer_drive.so",
    "libgazebo_ros_planar_move.so",
    "libgazebo_ros_diff_drive.so",
)
_TAGS = (
    "bodyName", "frameName", "topicName", "serviceName", "gaussianNoise", "updateRate",
    "xyzOffset", "rpyOffset", "robotNamespace", "leftFrontJoint", "rightFrontJoint",
    "leftRearJoint", "rightRearJoint", "wheelSeparation", "wheelDiameter", "torque",
    "commandTopic", "odometryTopic", "odometryFrame", "robotBaseFrame", "broadcastTF",
    "covariance_x", "odometryRate", "cmdTimeout", "publishOdometryTf", "update_rate",
    "publish_rate", "publish_odom", "leftJoint", "rightJoint", "publishWheelJointState",
    "legacyMode", "odometrySource", "imu", "ros", "bogus",
)  # fmt: skip
_VALUES = st.one_of(
    st.sampled_from(["", "0", "1", "-1", "nan", "inf", "true", "world", "encoder", "1 2 3",
                     "base_link", "imu_link", "lf_joint", "rr_joint", "imu_joint", "a b",
                     "1e400", "/abs/topic", "~/priv"]),
    st.text(alphabet="abc_/0123456789.- ", max_size=8),
)  # fmt: skip


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    filename=st.sampled_from(_FILENAMES),
    elements=st.lists(st.tuples(st.sampled_from(_TAGS), _VALUES), max_size=8),
)
def test_fuzzed_plugins_raise_only_visnav_errors(
    filename: str, elements: list[tuple[str, str]]
) -> None:
    from xml.sax.saxutils import escape

    body = "".join(f"<{tag}>{escape(value)}</{tag}>" for tag, value in elements)
    try:
        ext = plugin(filename, body)
    except VisnavError as exc:
        message = str(exc)
        ext = None
    if ext is None:
        assert "Fix:" in message
        return
    for spec in (*ext.imu_plugins, *ext.skid_steer_drives, *ext.planar_moves):
        for value in vars(spec).values():
            if isinstance(value, float):
                assert math.isfinite(value) or value == math.inf
