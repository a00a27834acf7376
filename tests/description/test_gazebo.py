"""``<gazebo>`` blocks written the way Gazebo users write them: topics, K, frames, errors."""

from __future__ import annotations

import math

import pytest

from visnav.description.gazebo import (
    GazeboExtensions,
    RosNodeNames,
    parse_gazebo_extensions,
    ros1_join,
    tf_resolve,
)
from visnav.description.urdf import RobotDescriptionError, parse_urdf

INERTIA = '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'
LINKS = f"""
  <link name="base_footprint"/>
  <link name="base_link"><inertial><mass value="5"/>{INERTIA}</inertial></link>
  <joint name="base_joint" type="fixed"><parent link="base_footprint"/><child link="base_link"/>
  </joint>
  <link name="camera_link"/>
  <joint name="camera_joint" type="fixed"><parent link="base_link"/><child link="camera_link"/>
    <origin xyz="0.2 0 0.3"/></joint>
  <link name="left_wheel"><inertial><mass value="0.5"/>{INERTIA}</inertial></link>
  <link name="right_wheel"><inertial><mass value="0.5"/>{INERTIA}</inertial></link>
  <joint name="left_wheel_joint" type="continuous"><parent link="base_link"/>
    <child link="left_wheel"/><origin xyz="0 0.2 0"/><axis xyz="0 1 0"/></joint>
  <joint name="right_wheel_joint" type="continuous"><parent link="base_link"/>
    <child link="right_wheel"/><origin xyz="0 -0.2 0"/><axis xyz="0 1 0"/></joint>
"""


def extensions(gazebo: str) -> GazeboExtensions:
    text = f'<?xml version="1.0"?>\n<robot name="bot">{LINKS}\n{gazebo}\n</robot>'
    return parse_gazebo_extensions(parse_urdf(text, source="bot.urdf"))


def bad(gazebo: str) -> str:
    with pytest.raises(RobotDescriptionError) as info:
        extensions(gazebo)
    text = str(info.value)
    assert text.startswith("bot.urdf:")
    assert "Fix:" in text
    return text


# --------------------------------------------------------------------------- names


def test_ros2_name_expansion_and_remapping() -> None:
    node = RosNodeNames(
        name="cam_plugin",
        namespace="/robot",
        remappings=(
            (None, "cam/image_raw", "cam/image"),
            (None, "~/out", "/imu"),
            ("other_node", "cam/camera_info", "nope"),
            (None, "/abs/topic", "rel"),
        ),
    )
    assert node.resolve("cam/image_raw") == "/robot/cam/image"
    assert node.resolve("cam/camera_info") == "/robot/cam/camera_info"  # rule for another node
    assert node.resolve("~/out") == "/imu"
    assert node.expand("~/out") == "/robot/cam_plugin/out"
    assert node.resolve("/abs/topic") == "/robot/rel"
    assert RosNodeNames(name="n").resolve("odom") == "/odom"


def test_ros1_names() -> None:
    assert ros1_join("/", "camera", "image_raw") == "/camera/image_raw"
    assert ros1_join("robot/", "", "/x/") == "/robot/x"
    assert tf_resolve("/robot/", "camera_link") == "robot/camera_link"
    assert tf_resolve("", "/camera_link") == "camera_link"
    assert tf_resolve("robot", "/abs") == "abs"


# --------------------------------------------------------------------------- cameras


CAMERA_ROS2 = """
<gazebo reference="camera_link">
  <sensor type="camera" name="front_camera">
    <always_on>true</always_on>
    <update_rate>30.0</update_rate>
    <pose>0 0 0 0 0 0</pose>
    <camera name="front">
      <horizontal_fov>1.3962634</horizontal_fov>
      <image><width>640</width><height>480</height><format>R8G8B8</format></image>
      <clip><near>0.02</near><far>300</far></clip>
      <noise><type>gaussian</type><mean>0.0</mean><stddev>0.007</stddev></noise>
      <distortion><k1>-0.25</k1><k2>0.12</k2><k3>0.0</k3><p1>-0.00028</p1><p2>-0.00005</p2>
        <center>0.5 0.5</center></distortion>
    </camera>
    <plugin name="camera_controller" filename="libgazebo_ros_camera.so">
      <ros>
        <namespace>demo_cam</namespace>
        <remapping>mycamera/image_raw:=mycamera/image_demo</remapping>
      </ros>
      <camera_name>mycamera</camera_name>
      <hack_baseline>0.07</hack_baseline>
    </plugin>
  </sensor>
</gazebo>
"""


def test_ros2_camera_topics_k_and_frame() -> None:
    ext = extensions(CAMERA_ROS2)
    assert ext.warnings == ()
    (cam,) = ext.cameras
    assert cam.ros_version == 2
    assert cam.kind == "camera"
    assert cam.image_topic == "/demo_cam/mycamera/image_demo"
    assert cam.camera_info_topic == "/demo_cam/mycamera/camera_info"
    assert cam.depth_topic is None
    assert cam.points_topic is None
    assert cam.frame_id == "camera_link"  # no <frame_name>: the sensor's link
    assert (cam.width, cam.height, cam.update_rate) == (640, 480, 30.0)
    assert cam.encoding == "rgb8"
    focal = 640 / (2 * math.tan(1.3962634 / 2))
    assert cam.fx == pytest.approx(focal)
    assert cam.fy == pytest.approx(focal)
    assert (cam.cx, cam.cy) == (320.0, 240.0)  # issue 3: width / 2 (Gazebo: (w + 1) / 2)
    assert cam.k() == pytest.approx((focal, 0, 320.0, 0, focal, 240.0, 0, 0, 1))
    assert cam.p()[3] == pytest.approx(-focal * 0.07)
    assert cam.distortion.d == (-0.25, 0.12, -0.00028, -0.00005, 0.0)  # k1 k2 p1 p2 k3
    assert cam.noise.stddev == 0.007
    assert (cam.clip_near, cam.clip_far) == (0.02, 300.0)


def test_ros2_camera_defaults_to_sensor_name() -> None:
    ext = extensions(
        """<gazebo reference="camera_link"><sensor type="camera" name="cam1">
        <camera><image><width>64</width><height>48</height><format>B8G8R8</format></image>
        </camera><plugin name="p" filename="libgazebo_ros_camera.so">
        <frame_name>camera_optical_frame</frame_name></plugin></sensor></gazebo>"""
    )
    (cam,) = ext.cameras
    assert cam.image_topic == "/cam1/image_raw"
    assert cam.camera_info_topic == "/cam1/camera_info"
    assert cam.frame_id == "camera_optical_frame"
    assert cam.encoding == "bgr8"
    assert cam.hfov == pytest.approx(1.047)


CAMERA_ROS1 = """
<gazebo reference="camera_link">
  <sensor type="camera" name="camera1">
    <update_rate>30.0</update_rate>
    <camera name="head">
      <horizontal_fov>1.3962634</horizontal_fov>
      <image><width>800</width><height>800</height><format>L8</format></image>
      <clip><near>0.02</near><far>300</far></clip>
    </camera>
    <plugin name="camera_controller" filename="libgazebo_ros_camera.so">
      <alwaysOn>true</alwaysOn>
      <updateRate>0.0</updateRate>
      <cameraName>rrbot/camera1</cameraName>
      <imageTopicName>image_raw</imageTopicName>
      <cameraInfoTopicName>camera_info</cameraInfoTopicName>
      <frameName>camera_link_optical</frameName>
      <hackBaseline>0.0</hackBaseline>
      <distortionK1>0.01</distortionK1>
      <distortionK2>0.0</distortionK2>
      <distortionK3>0.0</distortionK3>
      <distortionT1>0.0</distortionT1>
      <distortionT2>0.0</distortionT2>
    </plugin>
  </sensor>
</gazebo>
"""


def test_ros1_camera_spellings() -> None:
    ext = extensions(CAMERA_ROS1)
    assert ext.warnings == ()
    (cam,) = ext.cameras
    assert cam.ros_version == 1
    assert cam.image_topic == "/rrbot/camera1/image_raw"
    assert cam.camera_info_topic == "/rrbot/camera1/camera_info"
    assert cam.frame_id == "camera_link_optical"
    assert cam.encoding == "mono8"
    assert (cam.cx, cam.cy) == (400.0, 400.0)
    assert cam.distortion.k1 == 0.01


def test_ros1_robot_namespace_prefixes_topics_and_frame() -> None:
    ext = extensions(
        CAMERA_ROS1.replace(
            "<alwaysOn>", "<robotNamespace>/bot1</robotNamespace><alwaysOn>"
        ).replace("<imageTopicName>image_raw", "<imageTopicName>/abs/image")
    )
    (cam,) = ext.cameras
    assert cam.image_topic == "/abs/image"
    assert cam.camera_info_topic == "/bot1/rrbot/camera1/camera_info"
    assert cam.frame_id == "bot1/camera_link_optical"


DEPTH_ROS2 = """
<gazebo reference="camera_link">
  <sensor type="depth" name="depth_camera">
    <update_rate>20</update_rate>
    <camera>
      <horizontal_fov>1.047</horizontal_fov>
      <image><width>320</width><height>240</height></image>
      <clip><near>0.05</near><far>10</far></clip>
    </camera>
    <plugin name="depth_camera_controller" filename="libgazebo_ros_camera.so">
      <ros><namespace>car</namespace>
        <remapping>custom_camera/image_raw:=custom_camera/custom_image</remapping>
        <remapping>custom_camera/depth/image_raw:=custom_camera/custom_depth</remapping>
        <remapping>custom_camera/points:=custom_camera/custom_points</remapping>
      </ros>
      <camera_name>custom_camera</camera_name>
      <frame_name>custom_frame</frame_name>
      <hack_baseline>0.07</hack_baseline>
      <min_depth>0.001</min_depth>
      <max_depth>300.0</max_depth>
    </plugin>
  </sensor>
</gazebo>
"""


def test_ros2_depth_camera_topics() -> None:
    ext = extensions(DEPTH_ROS2)
    assert ext.warnings == ()
    (cam,) = ext.cameras
    assert cam.kind == "depth"
    assert cam.ros_version == 2
    assert cam.image_topic == "/car/custom_camera/custom_image"
    assert cam.camera_info_topic == "/car/custom_camera/camera_info"
    assert cam.depth_topic == "/car/custom_camera/custom_depth"
    assert cam.depth_info_topic == "/car/custom_camera/depth/camera_info"
    assert cam.points_topic == "/car/custom_camera/custom_points"
    assert cam.frame_id == "custom_frame"
    assert cam.depth_encoding == "32FC1"
    assert cam.pointcloud
    assert cam.depth_range == (0.05, 10.0)  # clip planes are tighter than min/max depth
    assert (cam.cx, cam.cy) == (160.0, 120.0)


def test_ros2_depth_defaults_and_options() -> None:
    ext = extensions(
        """<gazebo reference="camera_link"><sensor type="depth" name="d">
        <camera><clip><near>0.01</near><far>50</far></clip></camera>
        <plugin name="p" filename="libgazebo_ros_camera.so"><depth_format>16UC1</depth_format>
        <pointcloud>false</pointcloud></plugin></sensor></gazebo>"""
    )
    (cam,) = ext.cameras
    assert cam.depth_topic == "/d/depth/image_raw"
    assert cam.points_topic is None
    assert cam.depth_range == (0.4, 50.0)  # gazebo_ros_camera's min_depth default 0.4
    assert cam.depth_encoding == "16UC1"
    assert not cam.pointcloud


DEPTH_ROS1 = """
<gazebo reference="camera_link">
  <sensor type="depth" name="kinect">
    <update_rate>20</update_rate>
    <camera><horizontal_fov>1.0472</horizontal_fov>
      <image><width>640</width><height>480</height><format>R8G8B8</format></image>
      <clip><near>0.05</near><far>8.0</far></clip></camera>
    <plugin name="kinect_controller" filename="{plugin}">
      <baseline>0.2</baseline>
      <alwaysOn>true</alwaysOn>
      <updateRate>0.0</updateRate>
      <cameraName>kinect_ir</cameraName>
      <imageTopicName>/kinect/color/image_raw</imageTopicName>
      <cameraInfoTopicName>/kinect/color/camera_info</cameraInfoTopicName>
      <depthImageTopicName>/kinect/depth/image_raw</depthImageTopicName>
      <depthImageCameraInfoTopicName>/kinect/depth/camera_info</depthImageCameraInfoTopicName>
      <pointCloudTopicName>/kinect/depth/points</pointCloudTopicName>
      <frameName>camera_depth_optical_frame</frameName>
      <pointCloudCutoff>0.3</pointCloudCutoff>
      <pointCloudCutoffMax>6.0</pointCloudCutoffMax>
    </plugin>
  </sensor>
</gazebo>
"""


def test_ros1_depth_camera_spellings() -> None:
    ext = extensions(DEPTH_ROS1.format(plugin="libgazebo_ros_openni_kinect.so"))
    (cam,) = ext.cameras
    assert cam.ros_version == 1
    assert cam.image_topic == "/kinect/color/image_raw"
    assert cam.camera_info_topic == "/kinect/color/camera_info"
    assert cam.depth_topic == "/kinect/depth/image_raw"
    assert cam.depth_info_topic == "/kinect/depth/camera_info"
    assert cam.points_topic == "/kinect/depth/points"
    assert cam.frame_id == "camera_depth_optical_frame"
    assert cam.depth_range == (0.3, 6.0)
    assert any("<baseline>" in w for w in ext.warnings)  # unknown element: named


def test_ros1_depth_camera_defaults() -> None:
    ext = extensions(
        """<gazebo reference="camera_link"><sensor type="depth" name="d"><camera/>
        <plugin name="p" filename="libgazebo_ros_depth_camera.so">
        <cameraName>cam</cameraName><frameName>cam_optical</frameName>
        <useDepth16UC1Format>true</useDepth16UC1Format></plugin></sensor></gazebo>"""
    )
    (cam,) = ext.cameras
    assert cam.image_topic == "/cam/ir/image_raw"
    assert cam.camera_info_topic == "/cam/ir/camera_info"
    assert cam.depth_topic == "/cam/depth/image_raw"
    assert cam.depth_info_topic == "/cam/depth/camera_info"
    assert cam.points_topic == "/cam/points"
    assert cam.depth_range == (0.4, 100.0)  # pointCloudCutoff default, no max
    assert cam.depth_encoding == "16UC1"


def test_openni_kinect_far_cutoff_default() -> None:
    ext = extensions(
        DEPTH_ROS1.format(plugin="libgazebo_ros_openni_kinect.so").replace(
            "<pointCloudCutoffMax>6.0</pointCloudCutoffMax>", ""
        )
    )
    assert ext.cameras[0].depth_range == (0.3, 5.0)


def test_camera_without_plugin_publishes_nothing_and_warns() -> None:
    ext = extensions(
        '<gazebo reference="camera_link"><sensor type="camera" name="c"><camera/></sensor></gazebo>'
    )
    assert ext.cameras[0].image_topic is None
    assert any("no gazebo_ros camera plugin" in w for w in ext.warnings)


def test_unsupported_things_warn_by_name() -> None:
    ext = extensions(
        """<gazebo reference="camera_link">
          <material>Gazebo/Red</material><mu1>0.8</mu1><kp>1e6</kp>
          <sensor type="sonar" name="lidar"/>
          <sensor type="camera" name="c"><camera><lens><type>gnomonical</type></lens></camera>
            <visualize>true</visualize><ray_thing/>
            <plugin name="p" filename="libgazebo_ros_camera.so"><unknown_tag/></plugin>
            <plugin name="q" filename="libfancy.so"/></sensor></gazebo>
        <gazebo><plugin name="ctrl" filename="libgazebo_ros_vacuum_gripper.so"/>
        <static>false</static></gazebo>
        <gazebo reference="camera_joint"><preserveFixedJoint>true</preserveFixedJoint>
        <stopCfm>0.1</stopCfm></gazebo>"""
    )
    joined = "\n".join(ext.warnings)
    for needle in (
        "<kp>",
        "'sonar'",
        "<lens>",
        "<unknown_tag>",
        "'libfancy.so'",
        "'libgazebo_ros_vacuum_gripper.so'",
        "<static>",
        "<stopCfm>",
        "<ray_thing>",
    ):
        assert needle in joined, needle
    assert "preserveFixedJoint" not in joined
    assert "<visualize>" not in joined
    props = ext.link_properties["camera_link"]
    assert props.rgba == (1.0, 0.0, 0.0, 1.0)
    assert props.mu1 == 0.8


@pytest.mark.parametrize(
    ("camera", "needle"),
    [
        ("<image><width>0</width></image>", "<width> = 0 must be positive"),
        ("<image><height>abc</height></image>", "not an integer"),
        ("<horizontal_fov>0</horizontal_fov>", "outside (0, pi)"),
        ("<horizontal_fov>3.2</horizontal_fov>", "outside (0, pi)"),
        ("<horizontal_fov>-1</horizontal_fov>", "outside (0, pi)"),
        ("<clip><near>1</near><far>0.5</far></clip>", "far = 0.5 is not beyond near = 1"),
        ("<clip><near>0</near></clip>", "<near> = 0 is out of range"),
        ("<image><format>R8G8B8A8</format></image>", "format 'R8G8B8A8' is not supported"),
    ],
)
def test_bad_camera_is_one_clear_error(camera: str, needle: str) -> None:
    text = bad(
        f"""<gazebo reference="camera_link"><sensor type="camera" name="c"><camera>{camera}
        </camera><plugin name="p" filename="libgazebo_ros_camera.so"/></sensor></gazebo>"""
    )
    assert needle in text
    assert "sensor 'c'" in text


def test_sensor_on_missing_link_is_an_error() -> None:
    text = bad(
        '<gazebo reference="kamera_link"><sensor type="camera" name="c"><camera/></sensor></gazebo>'
    )
    assert "'kamera_link' is not a link" in text
    assert "camera_link" in text


def test_sensor_without_reference_or_on_joint_is_an_error() -> None:
    assert "needs a link" in bad('<gazebo><sensor type="camera" name="c"/></gazebo>')
    text = bad('<gazebo reference="camera_joint"><sensor type="camera" name="c"/></gazebo>')
    assert "'camera_link'" in text


def test_duplicate_sensor_names_are_an_error() -> None:
    block = '<sensor type="camera" name="c"><camera/></sensor>'
    with pytest.raises(RobotDescriptionError, match="two sensors are named 'c'"):
        extensions(f'<gazebo reference="camera_link">{block}{block}</gazebo>')


# --------------------------------------------------------------------------- p3d


def test_ros2_p3d() -> None:
    ext = extensions(
        """<gazebo><plugin name="p3d_base" filename="libgazebo_ros_p3d.so">
          <ros><namespace>demo</namespace><remapping>odom:=ground_truth</remapping></ros>
          <body_name>base_footprint</body_name><frame_name>world</frame_name>
          <update_rate>50</update_rate><xyz_offset>1 2 3</xyz_offset>
          <rpy_offset>0.1 0.2 0.3</rpy_offset><gaussian_noise>0.01</gaussian_noise>
        </plugin></gazebo>"""
    )
    (odom,) = ext.odometry
    assert odom.topic == "/demo/ground_truth"
    assert (odom.frame_id, odom.child_frame_id) == ("world", "base_footprint")
    assert odom.update_rate == 50.0
    assert odom.gaussian_noise == 0.01
    assert odom.xyz_offset == (1.0, 2.0, 3.0)
    assert odom.rpy_offset == (0.1, 0.2, 0.3)
    assert odom.publish_tf  # the root link: world -> base_footprint is a tree edge
    default = extensions(
        '<gazebo><plugin name="p" filename="libgazebo_ros_p3d.so"><body_name>base_link'
        "</body_name></plugin></gazebo>"
    )
    assert default.odometry[0].topic == "/odom"
    assert default.odometry[0].frame_id == "world"
    assert not default.odometry[0].publish_tf  # base_link already has a parent


def test_ros1_p3d() -> None:
    ext = extensions(
        """<gazebo><plugin name="p3d_base_controller" filename="libgazebo_ros_p3d.so">
          <alwaysOn>true</alwaysOn><updateRate>50.0</updateRate><bodyName>base_link</bodyName>
          <topicName>ground_truth/state</topicName><gaussianNoise>0.01</gaussianNoise>
          <frameName>world</frameName><xyzOffsets>0 0 0</xyzOffsets>
          <rpyOffsets>0 0 0</rpyOffsets></plugin></gazebo>"""
    )
    (odom,) = ext.odometry
    assert odom.ros_version == 1
    assert odom.topic == "/ground_truth/state"
    assert (odom.frame_id, odom.child_frame_id) == ("world", "base_link")
    assert ext.warnings == ()


@pytest.mark.parametrize(
    ("plugin", "needle"),
    [
        ("<body_name>chassis</body_name>", "'chassis' is not a link"),
        ("<update_rate>5</update_rate>", "missing <body_name>"),
        ("<bodyName>base_link</bodyName>", "missing <topicName>"),
        ("<body_name>base_link</body_name><update_rate>-1</update_rate>", "out of range"),
    ],
)
def test_bad_p3d(plugin: str, needle: str) -> None:
    assert needle in bad(
        f'<gazebo><plugin name="p" filename="libgazebo_ros_p3d.so">{plugin}</plugin></gazebo>'
    )


# --------------------------------------------------------------------------- diff drive


def test_ros2_diff_drive() -> None:
    ext = extensions(
        """<gazebo><plugin name="diff_drive" filename="libgazebo_ros_diff_drive.so">
          <ros><namespace>/demo</namespace><remapping>cmd_vel:=cmd_demo</remapping>
            <remapping>odom:=odom_demo</remapping></ros>
          <left_joint>left_wheel_joint</left_joint><right_joint>right_wheel_joint</right_joint>
          <wheel_separation>0.4</wheel_separation><wheel_diameter>0.2</wheel_diameter>
          <max_wheel_torque>20</max_wheel_torque><max_wheel_acceleration>1.0</max_wheel_acceleration>
          <publish_odom>true</publish_odom><publish_odom_tf>true</publish_odom_tf>
          <publish_wheel_tf>true</publish_wheel_tf>
          <odometry_frame>odom_demo</odometry_frame><robot_base_frame>base_footprint</robot_base_frame>
        </plugin></gazebo>"""
    )
    assert ext.warnings == ()
    (drive,) = ext.diff_drives
    assert drive.command_topic == "/demo/cmd_demo"
    assert drive.odometry_topic == "/demo/odom_demo"
    assert drive.left_joints == ("left_wheel_joint",)
    assert drive.right_joints == ("right_wheel_joint",)
    assert drive.wheel_separation == (0.4,)
    assert drive.wheel_diameter == (0.2,)
    assert drive.max_wheel_torque == 20
    assert drive.max_wheel_acceleration == 1.0
    assert drive.publish_odom
    assert drive.publish_odom_tf
    assert drive.publish_wheel_tf
    assert (drive.odometry_frame, drive.robot_base_frame) == ("odom_demo", "base_footprint")
    assert drive.odometry_source == "world"
    assert drive.update_rate == 100.0


def test_ros2_diff_drive_defaults_warn_about_silence() -> None:
    ext = extensions(
        """<gazebo><plugin name="dd" filename="libgazebo_ros_diff_drive.so">
        <left_joint>left_wheel_joint</left_joint><right_joint>right_wheel_joint</right_joint>
        </plugin></gazebo>"""
    )
    drive = ext.diff_drives[0]
    assert drive.command_topic == "/cmd_vel"
    assert drive.odometry_topic == "/odom"
    assert not drive.publish_odom
    assert not drive.publish_odom_tf
    assert drive.wheel_separation == (0.34,)
    assert drive.wheel_diameter == (0.15,)
    assert any("publishes neither odom" in w for w in ext.warnings)


def test_ros1_diff_drive() -> None:
    ext = extensions(
        """<gazebo><plugin name="differential_drive_controller"
            filename="libgazebo_ros_diff_drive.so">
          <rosDebugLevel>Debug</rosDebugLevel><publishWheelTF>false</publishWheelTF>
          <robotNamespace>/</robotNamespace><publishTf>1</publishTf>
          <publishWheelJointState>false</publishWheelJointState><alwaysOn>true</alwaysOn>
          <updateRate>100.0</updateRate><leftJoint>left_wheel_joint</leftJoint>
          <rightJoint>right_wheel_joint</rightJoint><wheelSeparation>0.5</wheelSeparation>
          <wheelDiameter>0.2</wheelDiameter><broadcastTF>1</broadcastTF>
          <wheelTorque>30</wheelTorque><commandTopic>cmd_vel</commandTopic>
          <odometryFrame>odom</odometryFrame><odometryTopic>odom</odometryTopic>
          <robotBaseFrame>base_footprint</robotBaseFrame></plugin></gazebo>"""
    )
    (drive,) = ext.diff_drives
    assert drive.ros_version == 1
    assert drive.command_topic == "/cmd_vel"
    assert drive.odometry_topic == "/odom"
    assert drive.publish_odom
    assert drive.publish_odom_tf
    assert drive.wheel_separation == (0.5,)
    assert drive.max_wheel_torque == 30
    assert (drive.odometry_frame, drive.robot_base_frame) == ("odom", "base_footprint")
    joined = "\n".join(ext.warnings)
    assert "<alwaysOn>" in joined
    assert "<broadcastTF>" in joined


def test_bad_diff_drive_joints() -> None:
    text = bad(
        """<gazebo><plugin name="dd" filename="libgazebo_ros_diff_drive.so">
        <left_joint>left_wheel</left_joint><right_joint>right_wheel_joint</right_joint>
        </plugin></gazebo>"""
    )
    assert "'left_wheel' is not a joint" in text
    assert "left_wheel_joint" in text
    text = bad(
        """<gazebo><plugin name="dd" filename="libgazebo_ros_diff_drive.so">
        <left_joint>camera_joint</left_joint><right_joint>right_wheel_joint</right_joint>
        </plugin></gazebo>"""
    )
    assert "is fixed" in text


# --------------------------------------------------------------------------- imu and joint states


def test_ros2_imu() -> None:
    ext = extensions(
        """<gazebo reference="base_link"><sensor name="my_imu" type="imu">
          <always_on>true</always_on><update_rate>100</update_rate>
          <imu><angular_velocity><x><noise type="gaussian"><mean>0.0</mean><stddev>2e-4</stddev>
            </noise></x></angular_velocity>
            <linear_acceleration><z><noise type="gaussian"><stddev>1.7e-2</stddev></noise></z>
            </linear_acceleration></imu>
          <plugin name="imu_plugin" filename="libgazebo_ros_imu_sensor.so">
            <ros><namespace>/demo</namespace><remapping>~/out:=imu</remapping></ros>
            <initial_orientation_as_reference>false</initial_orientation_as_reference>
          </plugin></sensor></gazebo>"""
    )
    assert ext.warnings == ()
    (imu,) = ext.imus
    assert imu.topic == "/demo/imu"
    assert imu.frame_id == "base_link"
    assert imu.update_rate == 100
    assert imu.angular_velocity_noise[0].stddev == 2e-4
    assert imu.linear_acceleration_noise[2].stddev == 1.7e-2
    unmapped = extensions(
        """<gazebo reference="base_link"><sensor name="i" type="imu">
        <plugin name="imu_plugin" filename="libgazebo_ros_imu_sensor.so"/></sensor></gazebo>"""
    )
    assert unmapped.imus[0].topic == "/imu_plugin/out"  # ~/out of the plugin's node


def test_ros1_imu() -> None:
    ext = extensions(
        """<gazebo reference="base_link"><sensor name="imu_sensor" type="imu">
          <update_rate>100</update_rate>
          <plugin name="imu_plugin" filename="libgazebo_ros_imu_sensor.so">
            <topicName>imu</topicName><bodyName>base_link</bodyName>
            <updateRateHZ>50.0</updateRateHZ><gaussianNoise>0.01</gaussianNoise>
            <xyzOffset>0 0 0</xyzOffset><rpyOffset>0 0 0</rpyOffset>
            <frameName>imu_link</frameName></plugin></sensor></gazebo>"""
    )
    (imu,) = ext.imus
    assert imu.ros_version == 1
    assert imu.topic == "/bot/imu"
    assert imu.frame_id == "imu_link"
    assert imu.update_rate == 50.0
    assert imu.angular_velocity_noise[1].stddev == 0.01


def test_joint_state_publisher() -> None:
    ext = extensions(
        """<gazebo><plugin name="jsp" filename="libgazebo_ros_joint_state_publisher.so">
        <ros><namespace>/demo</namespace></ros><update_rate>20</update_rate>
        <joint_name>left_wheel_joint</joint_name><joint_name>right_wheel_joint</joint_name>
        </plugin></gazebo>
        <gazebo><plugin name="jsp1" filename="libgazebo_ros_joint_state_publisher.so">
        <robotNamespace>r1</robotNamespace>
        <jointName>left_wheel_joint, right_wheel_joint</jointName></plugin></gazebo>"""
    )
    ros2, ros1 = ext.joint_state_publishers
    assert ros2.topic == "/demo/joint_states"
    assert ros2.update_rate == 20
    assert ros2.joints == ("left_wheel_joint", "right_wheel_joint")
    assert ros1.topic == "/r1/joint_states"
    assert ros1.joints == ros2.joints


def test_p3d_tf_is_off_where_the_diff_drive_parents_the_body() -> None:
    drive = """<plugin name="dd" filename="libgazebo_ros_diff_drive.so">
        <left_joint>left_wheel_joint</left_joint><right_joint>right_wheel_joint</right_joint>
        <publish_odom_tf>true</publish_odom_tf></plugin>"""
    p3d = """<plugin name="truth" filename="libgazebo_ros_p3d.so">
        <body_name>base_footprint</body_name>{extra}</plugin>"""
    alone = extensions(f"<gazebo>{p3d.format(extra='')}</gazebo>")
    assert alone.odometry[0].publish_tf  # the root link: world -> base_footprint
    both = extensions(f"<gazebo>{p3d.format(extra='')}{drive}</gazebo>")
    assert not both.odometry[0].publish_tf  # odom -> base_footprint already
    forced = extensions(
        f"<gazebo>{p3d.format(extra='<publish_tf>true</publish_tf>')}{drive}</gazebo>"
    )
    assert forced.odometry[0].publish_tf
    assert any("second parent" in w for w in forced.warnings)


def test_quadrotor_plugin_topics_and_parameters() -> None:
    ext = extensions(
        """<gazebo><plugin name="fc" filename="libvisnav_quadrotor.so">
        <ros><namespace>/uav</namespace><remapping>command/pose:=goal</remapping></ros>
        <max_thrust>30</max_thrust><max_moment>1 1 0.3</max_moment>
        </plugin></gazebo>"""
    )
    (quad,) = ext.quadrotors
    assert quad.body_name == "base_footprint"  # the root link by default
    assert quad.trajectory_topic == "/uav/command/trajectory"
    assert quad.pose_topic == "/uav/goal"
    assert dict(quad.parameters) == {"max_thrust": "30", "max_moment": "1 1 0.3"}
    assert not ext.warnings


@pytest.mark.parametrize(
    ("plugin", "needle"),
    [
        ("<max_thrust>lots</max_thrust>", "must be numbers"),
        ("<thrust>3</thrust>", "unknown parameter <thrust>"),
        ("<max_moment>1</max_moment>", "needs 3 number"),
        ("<body_name>rotor</body_name>", "'rotor' is not a link"),
    ],
)
def test_bad_quadrotor_plugin(plugin: str, needle: str) -> None:
    text = bad(
        f'<gazebo><plugin name="fc" filename="libvisnav_quadrotor.so">{plugin}</plugin></gazebo>'
    )
    assert needle in text
