"""The simulator runtime: topics, frames, rates in sim time, lock-step determinism, vehicles."""

from __future__ import annotations

import itertools
import math
import os
import subprocess
import sys
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from visnav.description.robot import RobotDescription
from visnav.description.robots import resolve_robot
from visnav.description.urdf import RobotDescriptionError
from visnav.description.world_yaml import world_from_dict
from visnav.description.worldmodel import WorldDescription
from visnav.graph import Context, Node
from visnav.graph.qos import qos_profile_latched
from visnav.msgs import (
    CameraInfo,
    Clock,
    Image,
    Imu,
    JointState,
    Odometry,
    PointCloud2,
    PoseStamped,
    String,
    TFMessage,
    Twist,
    message_from_dict,
    msg_type_name,
    serialize,
)
from visnav.msgs.image import image_to_numpy
from visnav.msgs.pointcloud import cloud_to_xyz
from visnav.msgs.time import time_to_ns
from visnav.sim.quadrotor_plugin import MultiDOFJointTrajectory
from visnav.sim.simulator import RobotSpawn, Simulator, SimulatorError
from visnav.sim.vehicles.quadrotor import PositionCommand
from visnav.tf import Buffer
from visnav.tf.ros import TransformListener

W, H = 64, 48

WORLD = {
    "name": "test_room",
    "ground": {"size": [20, 20]},
    "textures": {"grain": {"type": "noise", "rgb1": [0.9, 0.8, 0.6], "rgb2": [0.2, 0.2, 0.3]}},
    "materials": {"wall": {"texture": "grain", "tile": 1.0}},
    "objects": [
        {"type": "box", "name": "front", "pos": [4, 0, 1], "size": [0.3, 6, 2], "material": "wall"},
        {"type": "box", "name": "left", "pos": [1, 3, 1], "size": [6, 0.3, 2], "material": "wall"},
        {"type": "cylinder", "pos": [2, -1, 1], "radius": 0.3, "length": 2},
    ],
    "metadata": {"spawn": [0.0, 0.0, 0.0]},
}

IMU_ROBOT = """<robot name="imu_box">
  <link name="base_link">
    <inertial><mass value="2"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial>
    <collision><geometry><box size="0.3 0.3 0.2"/></geometry></collision>
  </link>
  <gazebo reference="base_link">
    <sensor name="imu" type="imu"><update_rate>100</update_rate>
      <plugin name="imu_plugin" filename="libgazebo_ros_imu_sensor.so"/></sensor>
  </gazebo>
</robot>"""


def build(msg_type: type[Any], **values: Any) -> Any:
    """A message from nested plain values (unset fields at their ROS defaults)."""
    return message_from_dict(msg_type_name(msg_type), values)


P3D_ROBOT = """<robot name="tracked">
  <link name="base_link">
    <inertial><mass value="2"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial>
    <collision><geometry><box size="0.3 0.3 0.2"/></geometry></collision>
  </link>
  <link name="marker"/>
  <joint name="marker_joint" type="fixed"><parent link="base_link"/><child link="marker"/>
    <origin xyz="0.5 0 0" rpy="0 0 1.5707963"/></joint>
  <gazebo><plugin name="offset" filename="libgazebo_ros_p3d.so">
    <ros><remapping>odom:=offset</remapping></ros><body_name>base_link</body_name>
    <xyz_offset>1 2 3</xyz_offset><rpy_offset>0 0 0.5</rpy_offset>
    <gaussian_noise>0.01</gaussian_noise><update_rate>10</update_rate></plugin></gazebo>
  <gazebo><plugin name="relative" filename="libgazebo_ros_p3d.so">
    <ros><remapping>odom:=relative</remapping></ros><body_name>base_link</body_name>
    <frame_name>marker</frame_name><publish_tf>false</publish_tf></plugin></gazebo>
</robot>"""


def small_world() -> WorldDescription:
    return world_from_dict(WORLD, source="test_room")


def small_cameras(desc: RobotDescription, width: int = W, height: int = H) -> RobotDescription:
    """The robot with every camera at ``width`` x ``height`` (same field of view)."""
    cameras = []
    for cam in desc.gazebo.cameras:
        focal = width / (2.0 * math.tan(cam.hfov / 2.0))
        centre = {"cx": width / 2.0, "cy": height / 2.0}
        cameras.append(replace(cam, width=width, height=height, fx=focal, fy=focal, **centre))
    return replace(desc, gazebo=replace(desc.gazebo, cameras=tuple(cameras)))


def car(**args: str) -> RobotDescription:
    return small_cameras(resolve_robot("car", args=args))


def quadrotor(**args: str) -> RobotDescription:
    return small_cameras(resolve_robot("quadrotor", args=args))


class Recorder:
    """Subscribes to topics in the simulator's context and keeps every message."""

    def __init__(self, ctx: Context, topics: dict[str, type[Any]]) -> None:
        self.node = Node("recorder", context=ctx)
        self.messages: dict[str, list[Any]] = defaultdict(list)
        for topic, msg_type in topics.items():
            self.node.create_subscription(msg_type, topic, self._keep(topic), 1000)

    def _keep(self, topic: str) -> Callable[[Any], None]:
        return self.messages[topic].append


@pytest.fixture
def ctx(mujoco_gl: str) -> Iterator[Context]:
    del mujoco_gl
    with Context(transport="local") as context:
        yield context


CAR_TOPICS: dict[str, type[Any]] = {
    "/camera/image_raw": Image,
    "/camera/camera_info": CameraInfo,
    "/depth_camera/image_raw": Image,
    "/depth_camera/depth/image_raw": Image,
    "/depth_camera/depth/camera_info": CameraInfo,
    "/depth_camera/points": PointCloud2,
    "/ground_truth/odom": Odometry,
    "/odom": Odometry,
    "/joint_states": JointState,
    "/clock": Clock,
    "/tf": TFMessage,
}


def test_car_topics_types_and_frames(ctx: Context) -> None:
    rec = Recorder(ctx, CAR_TOPICS)
    with Simulator(small_world(), [car()], context=ctx) as sim:
        sim.run(0.2)
    m = rec.messages
    for topic in CAR_TOPICS:
        assert m[topic], f"nothing on {topic}"
    image, info = m["/camera/image_raw"][0], m["/camera/camera_info"][0]
    assert (image.encoding, image.width, image.height) == ("rgb8", W, H)
    assert image.header.frame_id == info.header.frame_id == "camera_optical_frame"
    for img, inf in zip(m["/camera/image_raw"], m["/camera/camera_info"], strict=True):
        assert img.header.stamp == inf.header.stamp
    focal = W / (2 * math.tan(1.3962634 / 2))
    assert list(info.k) == pytest.approx([focal, 0, W / 2, 0, focal, H / 2, 0, 0, 1])
    depth = m["/depth_camera/depth/image_raw"][0]
    assert depth.encoding == "32FC1"
    assert depth.header.frame_id == "depth_camera_optical_frame"
    assert depth.header.stamp == m["/depth_camera/depth/camera_info"][0].header.stamp
    metres = image_to_numpy(depth)
    assert np.nanmin(metres) > 0.1  # the wall 4 m ahead and the floor are seen
    cloud = m["/depth_camera/points"][0]
    assert cloud.header.frame_id == "depth_camera_optical_frame"
    assert (cloud.height, cloud.width) == (H, W)
    xyz = cloud_to_xyz(cloud)
    assert np.isclose(np.median(xyz[:, 2]), np.nanmedian(metres), rtol=1e-6)
    truth = m["/ground_truth/odom"][-1]
    assert (truth.header.frame_id, truth.child_frame_id) == ("world", "base_footprint")
    odom = m["/odom"][-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_footprint")
    assert list(m["/joint_states"][0].name) == ["left_wheel_joint", "right_wheel_joint"]
    # p3d's default TF is off for the car: the diff drive already parents base_footprint.
    parents = {(t.header.frame_id, t.child_frame_id) for msg in m["/tf"] for t in msg.transforms}
    assert ("odom", "base_footprint") in parents
    assert ("world", "base_footprint") not in parents


def test_depth_matches_ray_casts_through_the_simulator(ctx: Context) -> None:
    import mujoco

    rec = Recorder(ctx, {"/depth_camera/depth/image_raw": Image})
    # exact geometry: without the car's depth noise model (1-2 cm at these ranges)
    with Simulator(small_world(), [car(ideal_sensors="true")], context=ctx) as sim:
        sim.run(0.01)
        robot = sim.robot()
        spec = next(c for c in robot.description.gazebo.cameras if c.kind == "depth")
        site = sim.model.site(robot.handles.sites[spec.name]).id
        own = int(sim.model.site_bodyid[site])  # the ray starts on the camera's housing
        origin = sim.data.site_xpos[site].copy()
        rot = sim.data.site_xmat[site].reshape(3, 3)
        depth = image_to_numpy(rec.messages["/depth_camera/depth/image_raw"][0])
        errors = []
        geomid = np.zeros(1, dtype=np.int32)
        groups = np.array([1, 1, 1, 0, 0, 0], dtype=np.uint8)
        for v in range(2, H, 7):
            for u in range(2, W, 9):
                ray = np.array([(u - spec.cx) / spec.fx, (v - spec.cy) / spec.fy, 1.0])
                direction = rot @ np.array([ray[2], -ray[0], -ray[1]])  # optical -> sensor
                hit = mujoco.mj_ray(sim.model, sim.data, origin, direction, groups, 1, own, geomid)
                if hit > 0 and np.isfinite(depth[v, u]):
                    errors.append(abs(hit - depth[v, u]))
    assert len(errors) > 30
    assert np.median(errors) < 1e-3


def test_tf_tree_and_robot_description(ctx: Context) -> None:
    node = Node("listener", context=ctx)
    buffer = Buffer()
    TransformListener(buffer, node)
    descriptions: list[str] = []
    qos = qos_profile_latched
    with Simulator(small_world(), [car()], context=ctx) as sim:
        node.create_subscription(
            String, "/robot_description", lambda msg: descriptions.append(msg.data), qos
        )
        sim.run(0.3)
        assert descriptions
        assert descriptions[0].startswith("<?xml")
        chain = [
            "camera_optical_frame",
            "camera_link",
            "base_link",
            "base_footprint",
            "odom",
        ]
        for child, parent in itertools.pairwise(chain):
            assert buffer.get_parent(child, 0) == parent
        assert buffer.get_parent("left_wheel", 0) == "base_link"  # from /joint_states
        assert buffer.get_parent("depth_camera_optical_frame", 0) == "depth_camera_link"
        t = buffer.lookup_transform_matrix("odom", "camera_optical_frame", 0)
        # optical z (forward) is the car's x (it starts facing +x)
        np.testing.assert_allclose(t[:3, 2], [1, 0, 0], atol=1e-3)


def test_sensor_rates_follow_sim_time(ctx: Context) -> None:
    rec = Recorder(ctx, CAR_TOPICS)
    with Simulator(small_world(), [car()], context=ctx) as sim:
        stats = sim.run(2.0)
    assert stats.sim_time_s == pytest.approx(2.0)
    assert stats.steps == 1000
    expected = {
        "/camera/image_raw": 60,
        "/depth_camera/depth/image_raw": 40,
        "/depth_camera/points": 40,
        "/ground_truth/odom": 100,
        "/odom": 100,
        "/joint_states": 100,
        "/clock": 1000,
    }
    for topic, count in expected.items():
        assert abs(len(rec.messages[topic]) - count) <= 1, (topic, len(rec.messages[topic]))
    stamps = [time_to_ns(m.header.stamp) for m in rec.messages["/camera/image_raw"]]
    periods = np.diff(stamps)
    # each frame at the first physics step at or after k / 30 s: no drift
    assert np.all(np.abs(np.array(stamps) - np.arange(len(stamps)) * 1e9 / 30) < 2_000_000)
    assert periods.min() >= 32_000_000


def test_clock_and_sim_time_timers(ctx: Context) -> None:
    rec = Recorder(ctx, {"/clock": Clock})
    user = Node("user", context=ctx, use_sim_time=True)
    ticks: list[int] = []
    user.create_timer(0.1, lambda: ticks.append(user.get_clock().now_ns()))
    with Simulator(small_world(), [], context=ctx) as sim:
        sim.run(1.0)
        clocks = [time_to_ns(m.clock) for m in rec.messages["/clock"]]
        assert np.all(np.diff(clocks) > 0)
        assert clocks[-1] == sim.now_ns - sim.timestep_ns
        assert user.get_clock().now_ns() == clocks[-1]
    assert abs(len(ticks) - 10) <= 1
    # the timers fire in sim time, on their period (a physics step of jitter at most)
    np.testing.assert_allclose(np.diff(ticks), 100_000_000, atol=2_000_000)


def test_cmd_vel_drives_the_car(ctx: Context) -> None:
    rec = Recorder(ctx, {"/ground_truth/odom": Odometry, "/odom": Odometry})
    driver = Node("driver", context=ctx)
    pub = driver.create_publisher(Twist, "/cmd_vel", 10)
    with Simulator(small_world(), [car()], context=ctx) as sim:
        sim.run(0.2)
        pub.publish(build(Twist, linear={"x": 0.5}))
        sim.run(2.0)
    truth = rec.messages["/ground_truth/odom"]
    x = [m.pose.pose.position.x for m in truth]
    assert x[-1] - x[0] > 0.6  # ramped at 1 m/s^2 to 0.5 m/s
    assert abs(truth[-1].pose.pose.position.y) < 0.05
    odom = rec.messages["/odom"][-1]
    assert odom.twist.twist.linear.x == pytest.approx(0.5, abs=0.05)


def _run_recorded(seed: int) -> dict[str, list[bytes]]:
    topics = {
        "/camera/image_raw": Image,
        "/depth_camera/depth/image_raw": Image,
        "/ground_truth/odom": Odometry,
        "/odom": Odometry,
    }
    with Context(transport="local") as context:
        rec = Recorder(context, topics)
        driver = Node("driver", context=context)
        pub = driver.create_publisher(Twist, "/cmd_vel", 10)

        def react(msg: Odometry) -> None:  # a closed loop in sim time
            turn = 0.4 if msg.pose.pose.position.x < 0.3 else -0.4
            pub.publish(build(Twist, linear={"x": 0.4}, angular={"z": turn}))

        driver.create_subscription(Odometry, "/odom", react, 10)
        with Simulator(small_world(), [car()], context=context, seed=seed) as sim:
            sim.run(1.0)
        return {t: [bytes(serialize(m)) for m in rec.messages[t]] for t in topics}


def test_two_runs_with_one_seed_give_identical_messages(mujoco_gl: str) -> None:
    del mujoco_gl
    first, second = _run_recorded(7), _run_recorded(7)
    for topic, messages in first.items():
        assert messages, topic
        assert messages == second[topic], topic
    other = _run_recorded(8)  # the camera's noise changes with the seed
    assert other["/camera/image_raw"] != first["/camera/image_raw"]
    assert other["/ground_truth/odom"] == first["/ground_truth/odom"]


def test_quadrotor_takes_off_and_holds_a_setpoint(ctx: Context) -> None:
    rec = Recorder(ctx, {"/odom": Odometry, "/depth_camera/points": PointCloud2})
    commander = Node("commander", context=ctx)
    pose = commander.create_publisher(PoseStamped, "/command/pose", 10)
    with Simulator(small_world(), [quadrotor()], context=ctx) as sim:
        sim.run(0.3)
        ground = rec.messages["/odom"][-1].pose.pose.position
        assert ground.z < 0.1
        pose.publish(build(PoseStamped, pose={"position": {"x": 0.0, "y": 0.5, "z": 1.0}}))
        sim.run(3.0)
        p = rec.messages["/odom"][-1].pose.pose.position
        assert (p.x, p.y, p.z) == pytest.approx((0.0, 0.5, 1.0), abs=0.05)
        # the Python API and a trajectory move it on
        sim.set_position_command(PositionCommand.hold((0.5, 0.5, 1.2)))
        sim.run(2.5)
        p = rec.messages["/odom"][-1].pose.pose.position
        assert (p.x, p.y, p.z) == pytest.approx((0.5, 0.5, 1.2), abs=0.05)
    assert rec.messages["/depth_camera/points"]


def test_quadrotor_trajectory_points_follow_time_from_start(ctx: Context) -> None:
    rec = Recorder(ctx, {"/odom": Odometry})
    commander = Node("commander", context=ctx)
    pub = commander.create_publisher(MultiDOFJointTrajectory, "/command/trajectory", 10)
    trajectory = build(
        MultiDOFJointTrajectory,
        points=[
            {"transforms": [{"translation": {"z": 0.8}, "rotation": {"w": 1.0}}]},
            {
                "transforms": [{"translation": {"z": 1.5}, "rotation": {"w": 1.0}}],
                "time_from_start": {"sec": 2},
            },
        ],
    )
    with Simulator(small_world(), [quadrotor()], context=ctx) as sim:
        sim.run(0.1)
        pub.publish(trajectory)
        sim.run(1.9)
        assert rec.messages["/odom"][-1].pose.pose.position.z == pytest.approx(0.8, abs=0.06)
        sim.run(2.5)
        assert rec.messages["/odom"][-1].pose.pose.position.z == pytest.approx(1.5, abs=0.06)


def test_imu_reads_gravity_at_rest(ctx: Context) -> None:
    rec = Recorder(ctx, {"/imu_plugin/out": Imu})
    with Simulator(small_world(), [RobotSpawn(source=IMU_ROBOT)], context=ctx) as sim:
        sim.run(0.5)
    msgs = rec.messages["/imu_plugin/out"]
    assert abs(len(msgs) - 50) <= 1
    last = msgs[-1]
    assert last.header.frame_id == "base_link"
    acc = last.linear_acceleration
    assert (acc.x, acc.y, acc.z) == pytest.approx((0.0, 0.0, 9.81), abs=0.05)
    q = last.orientation
    assert abs(q.w) == pytest.approx(1.0, abs=1e-3)


def test_p3d_offsets_noise_and_reference_link(ctx: Context) -> None:
    rec = Recorder(ctx, {"/offset": Odometry, "/relative": Odometry, "/tf": TFMessage})
    spawn = RobotSpawn(source=P3D_ROBOT, spawn=(0.5, -0.5, 0.1, 0.0))
    with Simulator(small_world(), [spawn], context=ctx, seed=3) as sim:
        sim.run(1.0)
    offset = rec.messages["/offset"]
    assert abs(len(offset) - 10) <= 1
    last = offset[-1]
    p, q = last.pose.pose.position, last.pose.pose.orientation
    assert (p.x, p.y) == pytest.approx((1.5, 1.5), abs=1e-3)
    assert p.z == pytest.approx(3.1, abs=0.01)  # resting: the box centre 0.1 m up
    assert 2 * math.atan2(q.z, q.w) == pytest.approx(0.5, abs=1e-3)
    twists = np.array([[m.twist.twist.linear.x, m.twist.twist.angular.z] for m in offset[3:]])
    assert 0.002 < twists.std() < 0.03  # gaussian_noise on the twist
    assert last.pose.covariance[0] == pytest.approx(1e-4)
    relative = rec.messages["/relative"][-1]
    assert relative.header.frame_id == "marker"
    rp = relative.pose.pose.position
    # base_link in the marker frame (marker at x 0.5, turned 90 deg): (0, 0.5, 0)
    assert (rp.x, rp.y, rp.z) == pytest.approx((0.0, 0.5, 0.0), abs=1e-6)
    # the root link's p3d publishes world -> base_link; the one with publish_tf false not
    edges = {
        (t.header.frame_id, t.child_frame_id) for m in rec.messages["/tf"] for t in m.transforms
    }
    assert edges == {("world", "base_link")}


def test_diff_drive_wheel_tf_and_encoder_odometry(ctx: Context) -> None:
    desc = car(odometry_source="0")
    drive = replace(desc.gazebo.diff_drives[0], publish_wheel_tf=True)
    # no joint state publisher: only the diff drive can put the wheels on /tf
    gazebo = replace(desc.gazebo, diff_drives=(drive,), cameras=(), joint_state_publishers=())
    desc = replace(desc, gazebo=gazebo)
    rec = Recorder(ctx, {"/tf": TFMessage, "/odom": Odometry})
    driver = Node("driver", context=ctx)
    pub = driver.create_publisher(Twist, "/cmd_vel", 10)
    with Simulator(
        small_world(), [RobotSpawn(source=desc, spawn=(1, 1, 0, 0))], context=ctx
    ) as sim:
        pub.publish(build(Twist, linear={"x": 0.3}))
        sim.run(1.0)
    by_node = defaultdict(set)
    for msg in rec.messages["/tf"]:
        for t in msg.transforms:
            by_node[t.header.frame_id].add(t.child_frame_id)
    assert {"left_wheel", "right_wheel"} <= by_node["base_link"]
    odom = rec.messages["/odom"][-1]
    # encoder odometry starts where the robot started, not at the world origin
    assert odom.pose.pose.position.x == pytest.approx(0.2, abs=0.1)
    assert abs(odom.pose.pose.position.y) < 0.02


def test_namespaces_and_frame_prefixes_for_two_robots(ctx: Context) -> None:
    rec = Recorder(
        ctx, {"/r1/camera/image_raw": Image, "/r2/ground_truth/odom": Odometry, "/tf": TFMessage}
    )
    robots = [
        RobotSpawn(source=car(), namespace="r1", frame_prefix="r1/", spawn=(0, 0, 0, 0)),
        RobotSpawn(source=car(), namespace="/r2", frame_prefix="r2/", spawn=(0, 1.5, 0, 0)),
    ]
    with Simulator(small_world(), robots, context=ctx) as sim:
        assert [r.name for r in sim.robots] == ["car", "car_2"]
        sim.run(0.1)
    assert rec.messages["/r1/camera/image_raw"][0].header.frame_id == "r1/camera_optical_frame"
    truth = rec.messages["/r2/ground_truth/odom"][0]
    assert (truth.header.frame_id, truth.child_frame_id) == ("world", "r2/base_footprint")
    assert truth.pose.pose.position.y == pytest.approx(1.5, abs=1e-3)
    children = {t.child_frame_id for m in rec.messages["/tf"] for t in m.transforms}
    assert {"r1/base_footprint", "r2/base_footprint", "r1/left_wheel"} <= children


def test_realtime_paces_to_the_wall_clock(ctx: Context) -> None:
    with Simulator(small_world(), [], context=ctx, realtime=True) as sim:
        start = time.perf_counter()
        stats = sim.run(0.4)
        elapsed = time.perf_counter() - start
    assert elapsed >= 0.39
    assert stats.real_time_factor == pytest.approx(1.0, abs=0.05)


def test_bad_input_is_one_clear_error(ctx: Context) -> None:
    with pytest.raises(RobotDescriptionError, match="did you mean 'quadrotor'"):
        resolve_robot("quadrotr")
    with pytest.raises(RobotDescriptionError, match="does not exist"):
        resolve_robot("/nonexistent/robot.urdf")
    with pytest.raises(SimulatorError, match="expected"):
        Simulator(small_world(), [], context=ctx, real_time_factor=0.0)
    with Simulator(small_world(), [car()], context=ctx) as sim:
        with pytest.raises(SimulatorError, match=r"no libvisnav_quadrotor\.so"):
            sim.set_position_command(PositionCommand.hold((0, 0, 1)))
        with pytest.raises(SimulatorError, match="no robot 'x'"):
            sim.robot("x")
        with pytest.raises(SimulatorError, match="duration"):
            sim.run(-1.0)


def test_cli_errors_are_one_line(capsys: pytest.CaptureFixture[str], domain: int) -> None:
    from visnav.cli.main import main

    del domain  # VISNAV_DOMAIN: a simulation running elsewhere in domain 0 would be refused

    assert main(["sim", "--world", "ofice", "--robot", "car"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error: unknown world 'ofice'; did you mean 'office'?")
    assert main(["sim", "--world", "office", "--robot", "cr", "--duration", "0"]) == 1
    assert "did you mean 'car'?" in capsys.readouterr().err
    assert main(["sim", "--world", "office", "--robot", "car", "--arg", "nope"]) == 1
    assert "is not name:=value" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.ci
def test_cli_publishes_to_another_process(mujoco_gl: str) -> None:
    del mujoco_gl
    domain = str(100 + os.getpid() % 100)
    env = {**os.environ, "VISNAV_DOMAIN": domain}
    env.pop("VISNAV_TRANSPORT", None)
    seen: dict[str, list[Any]] = defaultdict(list)
    with Context(domain, transport="zenoh") as context:
        node = Node("watcher", context=context)
        node.create_subscription(Clock, "/clock", seen["/clock"].append, 10)
        node.create_subscription(Odometry, "/ground_truth/odom", seen["odom"].append, 10)
        command = [
            sys.executable, "-m", "visnav.cli.main", "sim", "--world", "forest",
            "--robot", "car", "--arg", "camera_rate:=2", "--arg", "depth_rate:=2",
            "--duration", "6", "--realtime",
        ]  # fmt: skip
        proc = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            context.spin_until(lambda: len(seen["odom"]) >= 5, timeout_s=25.0)
        finally:
            out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err.decode()
    assert "real-time factor" in out.decode()
    assert len(seen["odom"]) >= 5
    assert seen["/clock"]
    assert seen["odom"][-1].child_frame_id == "base_footprint"


def test_run_sim_reports_progress_and_timing(
    mujoco_gl: str, tmp_path: Any, caplog: pytest.LogCaptureFixture
) -> None:
    del mujoco_gl
    import yaml

    from visnav.cli.sim import run_sim

    world = tmp_path / "room.yaml"
    world.write_text(yaml.safe_dump(WORLD))
    caplog.set_level("INFO", logger="visnav.sim")
    with Context(transport="local") as context:
        stats = run_sim(
            str(world),
            "quadrotor",
            context=context,
            robot_args={"depth_rate": "2", "odom_rate": "50"},
            duration_s=1.0,
            seed=1,
            progress_every_s=1e-3,
        )
    assert stats.sim_time_s == pytest.approx(1.0)
    assert stats.frames == 0  # nobody subscribes: not rendered (gazebo_ros_camera does so too)
    assert stats.real_time_factor > 0
    assert "real-time factor" in stats.summary()
    assert any("real-time factor" in r.getMessage() for r in caplog.records)
