"""Public ROS 1 robot packages, started through their own launch files as written.

Fixtures (``tests/data``, each with its licence and SOURCE.md):

* ``rosbot``: Husarion's ROSbot 2.0 (``rosbot_description``, ``rosbot_gazebo``; MIT), the robot of
  Husarion's ROS tutorials: Orbbec Astra RGB-D (``gazebo_ros_openni_kinect``), RPLidar A2
  (``gazebo_ros_laser``), four ultrasonic rangers (``gazebo_ros_range``), an IMU
  (``gazebo_ros_imu_sensor``), ``gazebo_ros_skid_steer_drive`` and ``gazebo_ros_control`` with
  the ``joint_state_controller`` spawner. ``roslaunch rosbot_description rosbot.launch``.
* ``ros_controllers/joint_state_controller``: the one file of ros-controls' package that
  ``rosbot_gazebo.launch`` loads (``$(find joint_state_controller)/joint_state_controller.yaml``),
  at the place the noetic Debian package installs it.
* ``velodyne_simulator``: Dataspeed's ``velodyne_description`` (BSD) with its example robot: a
  VLP-16 and an HDL-32E (``libgazebo_ros_velodyne_laser.so``) on a box, in ``example.world``
  (one unit box). ``roslaunch velodyne_description example.launch``.

Expected values are gazebo_ros's (ROS 1 noetic) for the files as written.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.errors import VisnavError
from visnav.graph import Context, Node
from visnav.launch import load_launch
from visnav.msgs import (
    CameraInfo,
    Image,
    Imu,
    JointState,
    LaserScan,
    Odometry,
    PointCloud2,
    TFMessage,
    Twist,
)
from visnav.msgs.construct import message_from_dict
from visnav.msgs.image import image_to_numpy
from visnav.msgs.pointcloud import cloud_to_structured
from visnav.sim.ray_plugin import Range

DATA = Path(__file__).resolve().parent.parent / "data"
ROSBOT = DATA / "rosbot"
ROSBOT_DESCRIPTION = ROSBOT / "rosbot_description"
ROSBOT_GAZEBO = ROSBOT / "rosbot_gazebo"
JOINT_STATE_CONTROLLER = DATA / "ros_controllers" / "joint_state_controller"
VELODYNE = DATA / "velodyne_simulator" / "velodyne_description"

ROSBOT_PACKAGES = {
    "rosbot_description": ROSBOT_DESCRIPTION,
    "rosbot_gazebo": ROSBOT_GAZEBO,
    "joint_state_controller": JOINT_STATE_CONTROLLER,
}
VELODYNE_PACKAGES = {"velodyne_description": VELODYNE}

FLOAT32, UINT16 = 7, 4  # sensor_msgs/PointField datatypes


def stamp_s(msg: Any) -> float:
    return float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)


def period(messages: list[Any]) -> float:
    """Mean period in sim time (as rostopic hz): a 40 Hz sensor on 2 ms physics steps fires
    24 or 26 ms apart, on the drift-free grid of k / 40 s."""
    stamps = [stamp_s(m) for m in messages]
    return (stamps[-1] - stamps[0]) / (len(stamps) - 1)


def yaw_of(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


class Recorder:
    def __init__(self, ctx: Context, topics: dict[str, type[Any]]) -> None:
        self.node = Node("public_robot_recorder", context=ctx)
        self.messages: dict[str, list[Any]] = defaultdict(list)
        for topic, msg_type in topics.items():
            self.node.create_subscription(msg_type, topic, self._keep(topic), 10_000)

    def _keep(self, topic: str) -> Callable[[Any], None]:
        return self.messages[topic].append


class Launched:
    """A ``visnav launch`` subprocess and a recorder in its graph domain."""

    def __init__(self, proc: subprocess.Popen[str], ctx: Context, rec: Recorder) -> None:
        self.proc, self.ctx, self.rec = proc, ctx, rec
        self.stderr = ""

    def wait_for(self, predicate: Callable[[], bool], timeout_s: float, what: str) -> None:
        ok = self.ctx.spin_until(lambda: predicate() or self.proc.poll() is not None, timeout_s)
        if self.proc.poll() is not None:
            _, err = self.proc.communicate(timeout=30)
            errors = [line for line in err.splitlines() if line.startswith("error")]
            code = self.proc.returncode
            pytest.fail(f"visnav launch exited ({code}) before {what}: {errors or err[-2000:]}")
        assert ok, f"timed out waiting for {what}"


@contextmanager
def launch(
    domain: int,
    path: Path,
    packages: dict[str, Path],
    topics: dict[str, type[Any]],
    *args: str,
) -> Iterator[Launched]:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    env.setdefault("MUJOCO_GL", "egl")
    cmd = [sys.executable, "-m", "visnav.cli.main", "launch", str(path), *args]
    for name, directory in packages.items():
        cmd += ["--package", f"{name}={directory}"]
    proc = subprocess.Popen(cmd, env=env, text=True, stderr=subprocess.PIPE)
    launched: Launched | None = None
    try:
        with Context(domain) as ctx:
            launched = Launched(proc, ctx, Recorder(ctx, topics))
            yield launched
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                _, err = proc.communicate(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
                _, err = proc.communicate()
            if launched is not None:
                launched.stderr = err
            assert "Traceback" not in err, err


# --- ROSbot 2.0 -------------------------------------------------------------------------------


def test_rosbot_launch_imports_as_one_simulation() -> None:
    desc = load_launch(ROSBOT_DESCRIPTION / "launch" / "rosbot.launch", packages=ROSBOT_PACKAGES)
    (sim,) = desc.nodes
    assert (sim.executable, sim.fqn, sim.use_sim_time) == ("sim", "/gazebo", True)
    assert 'name="rosbot"' in sim.params["robot"]
    assert sim.params["controllers"] == ["joint_state_controller"]
    assert (
        sim.params["joint_state_controller.type"] == "joint_state_controller/JointStateController"
    )


def test_rosbot_without_joint_state_controller_names_the_package() -> None:
    packages = {k: v for k, v in ROSBOT_PACKAGES.items() if k != "joint_state_controller"}
    with pytest.raises(VisnavError, match="joint_state_controller") as info:
        load_launch(ROSBOT_DESCRIPTION / "launch" / "rosbot.launch", packages=packages, env={})
    assert "--package joint_state_controller=DIR" in str(info.value)


def test_rosbot_tutorial_launch_with_gmapping_imports() -> None:
    """Husarion's tutorial: ``roslaunch rosbot_description rosbot_rviz_gmapping.launch``
    (rosbot_rviz.launch in turtlebot_playground.world + slam_gmapping + rviz)."""
    desc = load_launch(
        ROSBOT_DESCRIPTION / "launch" / "rosbot_rviz_gmapping.launch",
        packages=ROSBOT_PACKAGES,
        skip_unmapped=True,
    )
    # gmapping -> visnav's slam_gmapping, rviz -> the viewer
    assert sorted(n.executable for n in desc.nodes) == ["sim", "slam_gmapping", "viz"]
    (sim,) = (n for n in desc.nodes if n.executable == "sim")
    assert sim.params["world"] == str(ROSBOT_GAZEBO / "worlds" / "turtlebot_playground.world")


@pytest.mark.slow
@pytest.mark.ci
def test_rosbot_sensors_and_driving_as_gazebo_ros_publishes(domain: int) -> None:
    topics = {
        "/scan": LaserScan,
        "/camera/rgb/image_raw": Image,
        "/camera/rgb/camera_info": CameraInfo,
        "/camera/depth/image_raw": Image,
        "/camera/depth/points": PointCloud2,
        "/range/fl": Range,
        "/range/rr": Range,
        # gazebo_ros_imu_sensor's namespace: spawn_model's "/" (the spawn service adds a
        # <robotNamespace> to every plugin that has none), not the model name
        "/imu": Imu,
        "/joint_states": JointState,  # joint_state_controller, publish_rate 50
        "/odom": Odometry,
        "/tf": TFMessage,
    }
    with launch(
        domain, ROSBOT_DESCRIPTION / "launch" / "rosbot.launch", ROSBOT_PACKAGES, topics
    ) as run:
        m = run.rec.messages
        run.wait_for(
            lambda: len(m["/scan"]) >= 20 and len(m["/odom"]) >= 5, 240.0, "/scan and /odom"
        )
        driver = Node("driver", context=run.ctx)
        cmd = driver.create_publisher(Twist, "/cmd_vel", 1)
        run.wait_for(
            lambda: driver.count_subscribers("/cmd_vel") >= 1, 30.0, "a /cmd_vel subscriber"
        )
        start = m["/odom"][-1]
        twist = message_from_dict("geometry_msgs/msg/Twist", {"linear": {"x": 0.2}})

        def drove() -> bool:
            cmd.publish(twist)
            return stamp_s(m["/odom"][-1]) - stamp_s(start) >= 3.0

        run.wait_for(drove, 240.0, "3 s of driving")
        end = m["/odom"][-1]

    # RPLidar A2 (gazebo_ros_laser): 720 beams over [-pi, pi], 0.2..12 m, 40 Hz, frame laser
    scan = m["/scan"][-1]
    assert scan.header.frame_id == "laser"
    assert len(scan.ranges) == 720
    assert (scan.angle_min, scan.angle_max) == pytest.approx((-3.14159265, 3.14159265))
    assert scan.angle_increment == pytest.approx(2 * 3.14159265 / 719, rel=1e-6)
    assert (scan.range_min, scan.range_max) == pytest.approx((0.2, 12.0))
    assert period(m["/scan"]) == pytest.approx(1 / 40, rel=0.02)
    # Astra (gazebo_ros_openni_kinect, updateRate 10): rgb8 640x480 and 32FC1 depth in frameName
    image, info = m["/camera/rgb/image_raw"][-1], m["/camera/rgb/camera_info"][-1]
    assert (image.encoding, image.width, image.height) == ("rgb8", 640, 480)
    assert image.header.frame_id == info.header.frame_id == "camera_depth_frame"
    focal = 320.0 / math.tan(1.047 / 2.0)
    assert list(info.k) == pytest.approx([focal, 0, 320.5, 0, focal, 240.5, 0, 0, 1], abs=0.6)
    assert period(m["/camera/rgb/image_raw"]) == pytest.approx(0.1, rel=0.02)
    depth = m["/camera/depth/image_raw"][-1]
    assert (depth.encoding, depth.width, depth.height) == ("32FC1", 640, 480)
    assert depth.header.frame_id == "camera_depth_frame"
    # openni_kinect: depth NaN outside (pointCloudCutoff 0.4, pointCloudCutoffMax 5.0); the cloud
    # is organized 640x480 (x y z rgb), optical axes (z = depth) in frameName, NaN there too
    d = image_to_numpy(depth)
    finite = np.isfinite(d)
    assert finite.any()
    assert np.all((d[finite] > 0.4) & (d[finite] < 5.0))
    cloud = m["/camera/depth/points"][-1]
    assert cloud.header.frame_id == "camera_depth_frame"
    assert (cloud.height, cloud.width) == (480, 640)
    assert [f.name for f in cloud.fields] == ["x", "y", "z", "rgb"]
    assert not cloud.is_dense
    points = cloud_to_structured(cloud)
    z = np.asarray(points["z"], dtype=float).reshape(480, 640)
    y = np.asarray(points["y"], dtype=float).reshape(480, 640)
    assert np.array_equal(np.isfinite(z), finite)
    # empty world: every finite pixel is the ground, one camera height (0.04 + 0.18 m) below
    assert np.median(y[finite]) == pytest.approx(0.22, abs=0.02)
    # ultrasonic rangers (gazebo_ros_range): 5 Hz, fov 0.1, 0.01..0.9 m, ULTRASOUND
    for name in ("fl", "rr"):
        rng = m[f"/range/{name}"][-1]
        assert rng.header.frame_id == f"range_{name}"
        assert rng.radiation_type == 0
        assert rng.field_of_view == pytest.approx(0.1)
        assert (rng.min_range, rng.max_range) == pytest.approx((0.01, 0.9))
        stamps = [round(stamp_s(r), 3) for r in m[f"/range/{name}"]]
        assert period(m[f"/range/{name}"]) == pytest.approx(0.2, rel=0.02), stamps
    imu = m["/imu"][-1]
    assert imu.header.frame_id == "imu_link"
    assert period(m["/imu"]) == pytest.approx(0.1, rel=0.02)
    wheels = {f"{w}_wheel_hinge" for w in ("front_left", "front_right", "rear_left", "rear_right")}
    assert wheels <= set(m["/joint_states"][-1].name)
    assert period(m["/joint_states"]) == pytest.approx(1 / 50, rel=0.02)
    # skid steer: /odom at updateRate 10 in odom -> base_link ("/odom", "/base_link" as written:
    # tf::resolve drops the leading slash), broadcastTF
    assert (end.header.frame_id, end.child_frame_id) == ("odom", "base_link")
    assert period(m["/odom"]) == pytest.approx(0.1, rel=0.02)
    frames = {(t.header.frame_id, t.child_frame_id) for msg in m["/tf"] for t in msg.transforms}
    assert ("odom", "base_link") in frames
    dt = stamp_s(end) - stamp_s(start)
    p0, p1 = start.pose.pose.position, end.pose.pose.position
    travelled = math.hypot(p1.x - p0.x, p1.y - p0.y)
    assert travelled == pytest.approx(0.2 * dt, rel=0.25), (travelled, dt)
    assert abs(yaw_of(end.pose.pose.orientation) - yaw_of(start.pose.pose.orientation)) < 0.1


@pytest.mark.slow
def test_rosbot_spawned_into_a_running_world_is_refused_with_the_fix(domain: int) -> None:
    """Two terminals, as ROS users do: ``roslaunch rosbot_gazebo maze_world.launch``, then
    ``roslaunch rosbot_description rosbot_gazebo.launch`` spawns the robot into that Gazebo.
    visnav builds world and robots together (no spawning into a running simulation): the
    second launch is refused at once with one error that says how to start both together."""
    world = ROSBOT_GAZEBO / "launch" / "maze_world.launch"
    with launch(domain, world, ROSBOT_PACKAGES, {}) as run:
        clock = Node("clock_probe", context=run.ctx)
        run.wait_for(lambda: clock.count_publishers("/clock") >= 1, 240.0, "the world's /clock")
        spawn = ROSBOT_DESCRIPTION / "launch" / "rosbot_gazebo.launch"
        cmd = [sys.executable, "-m", "visnav.cli.main", "launch", str(spawn)]
        for name, path in ROSBOT_PACKAGES.items():
            cmd += ["--package", f"{name}={path}"]
        env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
        done = subprocess.run(
            cmd, check=False, env=env, text=True, capture_output=True, timeout=120
        )
    assert done.returncode == 1
    errors = [line for line in done.stderr.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1, done.stderr
    assert "empty_world.launch" in errors[0]
    assert "spawn_model" in errors[0]
    assert "Traceback" not in done.stderr


# --- velodyne_simulator's example robot -----------------------------------------------------


def test_velodyne_example_launch_imports() -> None:
    path = VELODYNE / "launch" / "example.launch"
    desc = load_launch(path, packages=VELODYNE_PACKAGES)
    assert sorted(n.executable for n in desc.nodes) == ["sim", "viz"]  # rviz -> viewer
    desc = load_launch(path, {"rviz": "false"}, packages=VELODYNE_PACKAGES)
    (sim,) = desc.nodes
    assert sim.params["world"] == str(VELODYNE / "world" / "example.world")
    assert "libgazebo_ros_velodyne_laser.so" in sim.params["robot"]


BOX_MIN = np.array([-2.0, 2.0, 0.0])  # example.world's unit box at (-1.5, 2.5, 0.5)
BOX_MAX = np.array([-1.0, 3.0, 1.0])


def _check_velodyne_cloud(
    msgs: list[PointCloud2], *, frame: str, lasers: int, lowest_deg: float, sensor_z: float
) -> None:
    cloud = msgs[-1]
    assert cloud.header.frame_id == frame
    fields = {f.name: (f.datatype, f.count) for f in cloud.fields}
    # velodyne_gazebo_plugins (noetic 1.0.13): x y z intensity float32, ring uint16, time float32
    assert fields == {
        "x": (FLOAT32, 1),
        "y": (FLOAT32, 1),
        "z": (FLOAT32, 1),
        "intensity": (FLOAT32, 1),
        "ring": (UINT16, 1),
        "time": (FLOAT32, 1),
    }
    assert cloud.height == 1
    assert cloud.is_dense
    assert period(msgs) == pytest.approx(0.1, rel=0.02)  # hz 10
    points = cloud_to_structured(cloud)
    assert set(np.unique(points["ring"]).tolist()) <= set(range(lasers))
    xyz = np.stack([points["x"], points["y"], points["z"]], axis=1).astype(float)
    r = np.linalg.norm(xyz, axis=1)
    assert r.min() >= 0.9 - 0.05  # min_range / max_range of the macro
    assert r.max() <= 130.0
    # ring = vertical row from the lowest beam up (velodyne_gazebo_plugins' layout)
    elevation = np.degrees(np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1])))
    rings = np.unique(points["ring"])
    by_ring = [float(np.median(elevation[points["ring"] == k])) for k in rings]
    assert np.all(np.diff(by_ring) > 0)
    assert by_ring[0] == pytest.approx(lowest_deg, abs=0.2)
    world = xyz + np.array([0.0, 0.0, sensor_z])  # the robot stands at the origin, unrotated
    ground = np.abs(world[:, 2]) < 0.05
    assert ground.sum() > 200, "the ground plane is not in the cloud"
    on_box = np.all((world > BOX_MIN - 0.05) & (world < BOX_MAX + 0.05), axis=1)
    assert on_box.sum() > 20, "example.world's unit box is not in the cloud"
    # the box's near faces: x = -1 (facing the sensor) or y = 2
    near_face = np.minimum(np.abs(world[on_box, 0] + 1.0), np.abs(world[on_box, 1] - 2.0))
    assert np.median(near_face) < 0.03


@pytest.mark.slow
def test_velodyne_example_clouds_as_velodyne_simulator_publishes(domain: int) -> None:
    topics = {
        "/velodyne_points": PointCloud2,
        "/velodyne_points2": PointCloud2,
        "/tf_static": TFMessage,
    }
    path = VELODYNE / "launch" / "example.launch"
    with launch(domain, path, VELODYNE_PACKAGES, topics, "rviz:=false") as run:
        m = run.rec.messages
        run.wait_for(
            lambda: len(m["/velodyne_points"]) >= 5 and len(m["/velodyne_points2"]) >= 5,
            240.0,
            "5 clouds from each Velodyne",
        )
    # base_footprint -> base_link 0.05, -> velodyne_base_link 0.4 (0.6), -> velodyne 0.0377
    _check_velodyne_cloud(
        m["/velodyne_points"],
        frame="velodyne",
        lasers=16,
        lowest_deg=-15.0,
        sensor_z=0.05 + 0.4 + 0.0377,
    )
    _check_velodyne_cloud(
        m["/velodyne_points2"],
        frame="velodyne2",
        lasers=32,
        lowest_deg=-30.67,
        sensor_z=0.05 + 0.6 + 0.09081,
    )
    frames = {
        (t.header.frame_id, t.child_frame_id) for msg in m["/tf_static"] for t in msg.transforms
    }
    assert {("base_footprint", "base_link"), ("velodyne_base_link", "velodyne")} <= frames
