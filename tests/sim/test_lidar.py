"""Ray sensors in the simulator: ranges, noise, conventions, message layouts, rates, on-demand.

The robots stand in a square room whose inner wall faces are at x = +-X and y = +-Y from
the room's centre, so the true range of a horizontal beam at yaw ``a`` from a point ``p``
is the distance to the first face: computed here in closed form, not by the simulator.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from visnav.description.gazebo_specs import GaussianNoise, RayScan, RaySpec
from visnav.description.world_yaml import world_from_dict
from visnav.description.worldmodel import WorldDescription
from visnav.graph import Context, Node
from visnav.msgs import LaserScan, PointCloud2
from visnav.msgs.pointcloud import cloud_to_structured
from visnav.sim.lidar import VELODYNE_DTYPE, RayNoise, ray_directions, scan_ranges
from visnav.sim.ray_plugin import PointCloud, Range, RayPlugin
from visnav.sim.simulator import RobotSpawn, Simulator

X, Y = 2.9, 1.9  # inner wall faces (m) from the room centre
TB3 = Path(__file__).resolve().parent.parent / "data" / "turtlebot3" / "turtlebot3_description"


def room(extra: list[dict[str, Any]] | None = None) -> WorldDescription:
    walls = [
        {"type": "box", "name": "east", "pos": [X + 0.1, 0, 1], "size": [0.2, 2 * Y + 0.4, 2]},
        {"type": "box", "name": "west", "pos": [-X - 0.1, 0, 1], "size": [0.2, 2 * Y + 0.4, 2]},
        {"type": "box", "name": "north", "pos": [0, Y + 0.1, 1], "size": [2 * X + 0.4, 0.2, 2]},
        {"type": "box", "name": "south", "pos": [0, -Y - 0.1, 1], "size": [2 * X + 0.4, 0.2, 2]},
    ]
    doc = {
        "name": "lidar_room",
        "ground": {"size": [20, 20]},
        "objects": walls + (extra or []),
        "metadata": {"spawn": [0.0, 0.0, 0.0]},
    }
    return world_from_dict(doc, source="lidar_room")


def true_ranges(origin: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Distance from ``origin`` (x, y) to the room's walls along world yaws ``angles``."""
    c, s = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (X - origin[0]) / c, np.where(c < 0, (-X - origin[0]) / c, np.inf))
        ty = np.where(s > 0, (Y - origin[1]) / s, np.where(s < 0, (-Y - origin[1]) / s, np.inf))
    return np.minimum(tx, ty)


def fixed_robot(sensor: str, *, links: str = "", height: float = 0.5) -> str:
    """A robot fixed to the world with a ``sensor_link`` at ``height`` holding ``sensor``."""
    return f"""<robot name="rig">
  <link name="world"/>
  <link name="sensor_link">
    <inertial><mass value="0.5"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
    <collision><geometry><box size="0.3 0.3 0.3"/></geometry></collision>
  </link>
  <joint name="mount" type="fixed"><parent link="world"/><child link="sensor_link"/>
    <origin xyz="0 0 {height}"/></joint>
  {links}
  <gazebo reference="sensor_link">{sensor}</gazebo>
</robot>"""


def ray_sensor(
    plugin: str,
    *,
    samples: int = 361,
    lo: float = -math.pi,
    hi: float = math.pi,
    vertical: str = "",
    rmin: float = 0.1,
    rmax: float = 10.0,
    noise: float = 0.0,
    rate: float = 10.0,
    kind: str = "ray",
    pose: str = "0 0 0 0 0 0",
) -> str:
    noise_el = (
        f"<noise><type>gaussian</type><mean>0</mean><stddev>{noise}</stddev></noise>"
        if noise
        else ""
    )
    return f"""<sensor type="{kind}" name="lidar"><update_rate>{rate}</update_rate>
      <pose>{pose}</pose>
      <ray><scan><horizontal><samples>{samples}</samples><resolution>1</resolution>
        <min_angle>{lo}</min_angle><max_angle>{hi}</max_angle></horizontal>{vertical}</scan>
        <range><min>{rmin}</min><max>{rmax}</max><resolution>0.01</resolution></range>
        {noise_el}</ray>{plugin}</sensor>"""


LASER = """<plugin name="laser" filename="libgazebo_ros_laser.so">
  <topicName>scan</topicName><frameName>sensor_link</frameName></plugin>"""


class Recorder:
    def __init__(self, ctx: Context, topics: dict[str, type[Any]]) -> None:
        self.node = Node("lidar_recorder", context=ctx)
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


def run(
    ctx: Context,
    urdf: str,
    topics: dict[str, type[Any]],
    *,
    duration: float = 0.05,
    world: WorldDescription | None = None,
    seed: int = 0,
) -> dict[str, list[Any]]:
    rec = Recorder(ctx, topics)
    with Simulator(world or room(), [RobotSpawn(source=urdf)], context=ctx, seed=seed) as sim:
        sim.run(duration)
    return rec.messages


def stamp_s(msg: Any) -> float:
    return float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)


def test_ranges_are_exact_without_noise(ctx: Context) -> None:
    scan = run(ctx, fixed_robot(ray_sensor(LASER)), {"/scan": LaserScan})["/scan"][-1]
    angles = scan.angle_min + np.arange(len(scan.ranges)) * scan.angle_increment
    truth = true_ranges(np.zeros(2), angles)
    assert np.asarray(scan.ranges) == pytest.approx(truth, abs=2e-6)  # float32 ranges
    assert scan.ranges[180] == pytest.approx(X, abs=1e-6)  # yaw 0: the east wall


def test_laser_scan_fields_as_gazebo_ros_laser(ctx: Context) -> None:
    scan = run(ctx, fixed_robot(ray_sensor(LASER, samples=720)), {"/scan": LaserScan})["/scan"][0]
    assert scan.header.frame_id == "sensor_link"
    assert stamp_s(scan) == 0.0
    assert (scan.angle_min, scan.angle_max) == pytest.approx((-math.pi, math.pi))
    assert scan.angle_increment == pytest.approx(2 * math.pi / 719)
    assert (scan.time_increment, scan.scan_time) == (0.0, 0.0)
    assert (scan.range_min, scan.range_max) == pytest.approx((0.1, 10.0))
    assert len(scan.ranges) == len(scan.intensities) == 720
    assert not np.any(scan.intensities)


def test_noise_has_the_configured_stddev_and_stays_in_range(ctx: Context) -> None:
    urdf = fixed_robot(ray_sensor(LASER, noise=0.02, rate=100))
    scans = run(ctx, urdf, {"/scan": LaserScan}, duration=0.2)["/scan"]
    assert len(scans) == 20
    angles = scans[0].angle_min + np.arange(361) * scans[0].angle_increment
    errors = np.stack([np.asarray(s.ranges) for s in scans]) - true_ranges(np.zeros(2), angles)
    assert abs(errors.mean()) < 0.002
    assert errors.std() == pytest.approx(0.02, rel=0.05)
    assert not np.allclose(scans[0].ranges, scans[1].ranges)  # fresh noise every scan


def test_out_of_range_is_inf_and_closer_than_min_is_not_seen(ctx: Context) -> None:
    post = '<link name="post"><visual><geometry><box size="0.02 0.02 0.2"/></geometry></visual>'
    post += '<collision><geometry><box size="0.02 0.02 0.2"/></geometry></collision>'
    post += '<inertial><mass value="0.1"/><inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" '
    post += 'iyz="0" izz="1e-4"/></inertial></link><joint name="post_joint" type="fixed">'
    post += '<parent link="sensor_link"/><child link="post"/><origin xyz="0.3 0 0"/></joint>'
    near = fixed_robot(ray_sensor(LASER, rmin=0.5, rmax=2.5), links=post)
    scan = run(ctx, near, {"/scan": LaserScan})["/scan"][-1]
    ranges = np.asarray(scan.ranges)
    angles = scan.angle_min + np.arange(361) * scan.angle_increment
    truth = true_ranges(np.zeros(2), angles)
    assert np.all(np.isposinf(ranges[truth >= 2.5]))
    assert ranges[truth < 2.49] == pytest.approx(truth[truth < 2.49], abs=2e-6)
    # the robot's own post at 0.3 m (inside range_min 0.5) is not seen: the wall behind is
    assert ranges[180] == np.inf  # yaw 0: east wall at 2.9 > 2.5
    seen = run(ctx, fixed_robot(ray_sensor(LASER, rmin=0.1), links=post), {"/scan": LaserScan})
    assert seen["/scan"][-1].ranges[180] == pytest.approx(0.29, abs=1e-6)  # own other link


def test_own_link_is_excluded_and_visual_only_shapes_are_looked_through(ctx: Context) -> None:
    glass: dict[str, Any] = {"type": "box", "name": "glass", "pos": [1.0, 0, 1]}
    glass.update(size=[0.1, 1, 2], collision=False)
    pillar: dict[str, Any] = {"type": "cylinder", "name": "pillar", "pos": [0, 1.0, 1]}
    pillar.update(radius=0.1, length=2)
    world = room([glass, pillar])
    scan = run(ctx, fixed_robot(ray_sensor(LASER)), {"/scan": LaserScan}, world=world)["/scan"][-1]
    # the sensor sits inside its link's 0.3 m collision box, which it does not see
    assert scan.ranges[180] == pytest.approx(X, abs=1e-6)  # through the visual-only glass
    assert scan.ranges[270] == pytest.approx(0.9, abs=1e-6)  # yaw +90 deg: the pillar


def test_sensor_pose_and_other_robots(ctx: Context) -> None:
    turned = fixed_robot(ray_sensor(LASER, pose="0.5 0 0 0 0 1.5707963"))
    scan = run(ctx, turned, {"/scan": LaserScan})["/scan"][-1]
    assert scan.ranges[180] == pytest.approx(Y, abs=1e-5)  # yaw 0 of the sensor is +y
    assert scan.ranges[90] == pytest.approx(X - 0.5, abs=1e-5)  # -90 deg is +x, from x = 0.5
    crate = """<robot name="crate"><link name="box"><inertial><mass value="3"/>
      <inertia ixx="0.05" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial>
      <visual><geometry><box size="0.8 0.8 1"/></geometry></visual>
      <collision><geometry><box size="0.4 0.4 1"/></geometry></collision></link></robot>"""
    rec = Recorder(ctx, {"/scan": LaserScan})
    robots = [
        RobotSpawn(source=fixed_robot(ray_sensor(LASER))),
        RobotSpawn(source=crate, spawn=(1.5, 0.0, 0.0, 0.0)),
    ]
    with Simulator(room(), robots, context=ctx) as sim:
        sim.run(0.05)
    assert rec.messages["/scan"][-1].ranges[180] == pytest.approx(1.3, abs=1e-4)  # not visual 1.1


def test_rate_is_update_rate_in_sim_time(ctx: Context) -> None:
    scans = run(ctx, fixed_robot(ray_sensor(LASER, rate=7)), {"/scan": LaserScan}, duration=1.0)
    stamps = np.array([stamp_s(s) for s in scans["/scan"]])
    late = stamps - np.arange(7) / 7  # each scan at the first 2 ms step at or after k / 7 s
    assert len(stamps) == 7
    assert np.all((late >= -1e-9) & (late < 0.002))


def test_nothing_is_cast_while_nobody_subscribes(ctx: Context) -> None:
    with Simulator(room(), [RobotSpawn(source=fixed_robot(ray_sensor(LASER)))], context=ctx) as sim:
        plugin = next(p for p in sim.robot().plugins if isinstance(p, RayPlugin))
        sim.run(0.5)
        assert (plugin.scans, plugin.cast_ns) == (0, 0)
        assert plugin.skipped == 5
        rec = Recorder(ctx, {"/scan": LaserScan})
        sim.run(0.5)
    assert plugin.scans == len(rec.messages["/scan"]) == 5


def test_two_runs_with_one_seed_give_identical_noisy_scans(ctx: Context) -> None:
    urdf = fixed_robot(ray_sensor(LASER, noise=0.01))
    first = run(ctx, urdf, {"/scan": LaserScan}, seed=4)["/scan"][-1]
    second = run(ctx, urdf, {"/scan": LaserScan}, seed=4)["/scan"][-1]
    assert np.array_equal(first.ranges, second.ranges)


VELODYNE = """<plugin name="vlp" filename="libgazebo_ros_velodyne_laser.so">
  <topicName>velodyne_points</topicName><frameName>velodyne</frameName>
  <min_range>0.9</min_range><max_range>{max_range}</max_range>{extra}</plugin>"""
VERTICAL_16 = """<vertical><samples>16</samples><resolution>1</resolution>
  <min_angle>-0.2618</min_angle><max_angle>0.2618</max_angle></vertical>"""


def velodyne_robot(extra: str = "", max_range: float = 130.0) -> str:
    plugin = VELODYNE.format(extra=extra, max_range=max_range)
    sensor = ray_sensor(plugin, samples=90, vertical=VERTICAL_16)
    return fixed_robot(sensor, height=1.0)


def test_velodyne_cloud_layout_rings_and_geometry(ctx: Context) -> None:
    msg = run(ctx, velodyne_robot(), {"/velodyne_points": PointCloud2})["/velodyne_points"][-1]
    assert msg.header.frame_id == "velodyne"
    layout = [(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
    assert layout == [
        ("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("intensity", 12, 7, 1),
        ("ring", 16, 4, 1), ("time", 18, 7, 1),
    ]  # fmt: skip
    assert (msg.point_step, msg.height, msg.is_dense) == (22, 1, True)
    points = cloud_to_structured(msg)
    assert points.dtype.itemsize == VELODYNE_DTYPE.itemsize
    assert set(np.unique(points["ring"]).tolist()) == set(range(16))
    assert not np.any(points["time"])
    xyz = np.stack([points[c] for c in "xyz"], axis=1).astype(float)
    pitch = -0.2618 + points["ring"] * (2 * 0.2618 / 15)
    assert np.arctan2(xyz[:, 2], np.hypot(xyz[:, 0], xyz[:, 1])) == pytest.approx(pitch, abs=1e-5)
    yaw = np.arctan2(xyz[:, 1], xyz[:, 0])
    flat = np.hypot(xyz[:, 0], xyz[:, 1])
    walls = xyz[:, 2] > -0.99  # not the ground (1 m below the sensor)
    expected = true_ranges(np.zeros(2), yaw[walls])
    assert flat[walls] == pytest.approx(expected, abs=1e-4)


def test_velodyne_drops_out_of_range_points_or_organizes_them_as_nan(ctx: Context) -> None:
    urdf = velodyne_robot("<organize_cloud>true</organize_cloud>", max_range=2.5)
    msg = run(ctx, urdf, {"/velodyne_points": PointCloud2})["/velodyne_points"][-1]
    assert (msg.height, msg.width, msg.is_dense) == (90, 16, False)
    points = cloud_to_structured(msg).reshape(msg.height, msg.width)
    assert np.array_equal(points["ring"], np.tile(np.arange(16, dtype=np.uint16), (90, 1)))
    r = np.sqrt(sum(points[c].astype(float) ** 2 for c in "xyz"))
    valid = np.isfinite(r)
    assert valid.any()
    assert not valid.all()
    assert np.all((r[valid] > 0.9) & (r[valid] < 2.5))
    topics = {"/velodyne_points": PointCloud2}
    dense = run(ctx, velodyne_robot(max_range=2.5), topics)["/velodyne_points"][-1]
    assert dense.width == int(valid.sum())


RANGE_1 = """<plugin name="sonar" filename="libgazebo_ros_range.so">
  <topicName>sonar</topicName><frameName>sensor_link</frameName>
  <radiation>infrared</radiation><fov>0.1</fov></plugin>"""
VERTICAL_5 = """<vertical><samples>5</samples><resolution>1</resolution>
  <min_angle>-0.05</min_angle><max_angle>0.05</max_angle></vertical>"""


def test_range_is_the_minimum_over_the_rays(ctx: Context) -> None:
    sensor = ray_sensor(RANGE_1, samples=5, lo=-0.05, hi=0.05, vertical=VERTICAL_5, rmin=0.02)
    msg = run(ctx, fixed_robot(sensor), {"/sonar": Range})["/sonar"][-1]
    assert msg.range == pytest.approx(X, abs=1e-6)  # the middle ray, straight at the wall
    assert (msg.radiation_type, msg.field_of_view) == (Range.INFRARED, pytest.approx(0.1))
    assert (msg.min_range, msg.max_range) == pytest.approx((0.02, 10.0))
    short = ray_sensor(RANGE_1, samples=5, lo=-0.05, hi=0.05, vertical=VERTICAL_5, rmax=2.0)
    far = run(ctx, fixed_robot(short), {"/sonar": Range})["/sonar"][-1]
    assert far.range == pytest.approx(2.0)  # ROS 1 gazebo_ros_range: max_range, not inf


RAY_2 = """<plugin name="lidar_node" filename="libgazebo_ros_ray_sensor.so">
  <ros><namespace>/r1</namespace><remapping>~/out:={out}</remapping></ros>
  <output_type>sensor_msgs/{output}</output_type><frame_name>lidar_frame</frame_name></plugin>"""


def test_ros2_ray_sensor_point_cloud2_and_range(ctx: Context) -> None:
    sensor = ray_sensor(RAY_2.format(out="points", output="PointCloud2"), rmax=2.5)
    msg = run(ctx, fixed_robot(sensor), {"/r1/points": PointCloud2})["/r1/points"][-1]
    assert msg.header.frame_id == "lidar_frame"
    layout = [(f.name, f.offset, f.datatype) for f in msg.fields]
    assert layout == [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7)]
    assert (msg.point_step, msg.height, msg.is_dense) == (16, 1, True)
    points = cloud_to_structured(msg)
    yaw = np.arctan2(points["y"], points["x"]).astype(float)
    r = np.hypot(points["x"], points["y"]).astype(float)
    assert r == pytest.approx(true_ranges(np.zeros(2), yaw), abs=1e-5)
    assert np.all(r < 2.5)  # beams beyond range_max are not in the cloud
    assert 0 < len(points) < 361
    one = ray_sensor(RAY_2.format(out="range", output="Range"), samples=1, lo=0, hi=0, rmax=2)
    rng = run(ctx, fixed_robot(one), {"/r1/range": Range})["/r1/range"][-1]
    assert rng.range == math.inf  # nothing within 2 m: REP 117's +inf


def test_ros2_point_cloud_and_middle_row_laser_scan(ctx: Context) -> None:
    cloud = ray_sensor(RAY_2.format(out="cloud", output="PointCloud"), rmax=2.5)
    msg = run(ctx, fixed_robot(cloud), {"/r1/cloud": PointCloud})["/r1/cloud"][-1]
    assert [c.name for c in msg.channels] == ["intensity"]
    assert len(msg.points) == len(msg.channels[0].values) > 0
    assert all(math.hypot(p.x, p.y) < 2.5 for p in msg.points)
    scan3d = ray_sensor(RAY_2.format(out="scan", output="LaserScan"), vertical=VERTICAL_5)
    scan = run(ctx, fixed_robot(scan3d), {"/r1/scan": LaserScan})["/r1/scan"][-1]
    assert len(scan.ranges) == 361  # the middle of the 5 rows, which is horizontal
    assert scan.ranges[180] == pytest.approx(X, abs=1e-6)


def test_burger_lds_at_5_hz_within_3_sigma(ctx: Context) -> None:
    spawn = RobotSpawn(
        source=TB3 / "urdf" / "turtlebot3_burger.urdf.xacro",
        packages={"turtlebot3_description": TB3},
        spawn=(0.4, -0.3, 0.0, 0.5),
    )
    rec = Recorder(ctx, {"/scan": LaserScan})
    with Simulator(room(), [spawn], context=ctx) as sim:
        sim.run(1.1)
        body = sim.model.body(f"{sim.robot().name}/base_scan").id
        origin = np.array(sim.data.xpos[body])
        rot = np.array(sim.data.xmat[body]).reshape(3, 3)
    scans = rec.messages["/scan"]
    assert [round(stamp_s(s), 6) for s in scans] == [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
    scan = scans[-1]
    assert scan.header.frame_id == "base_scan"
    assert len(scan.ranges) == 360
    yaw = math.atan2(rot[1, 0], rot[0, 0])
    angles = yaw + scan.angle_min + np.arange(360) * scan.angle_increment
    truth = true_ranges(origin[:2], angles)
    ranges = np.asarray(scan.ranges, dtype=float)
    hits = truth < 3.5 - 0.03
    assert hits.sum() > 200
    within = np.abs(ranges[hits] - truth[hits]) <= 0.03
    assert within.mean() >= 0.95
    assert np.all(np.isinf(ranges[truth > 3.53]))


# --------------------------------------------------------------------------- pure functions


def test_scan_ranges_interpolate_mask_and_clamp_noise() -> None:
    spec = RaySpec(
        name="s", link="l", horizontal=RayScan(samples=3, resolution=2.0), range_min=0.5,
        range_max=4.0,
    )  # fmt: skip
    raw = np.array([[1.0, 2.0, 3.0]])
    assert scan_ranges(raw, spec) == pytest.approx(np.array([[1.0, 1.4, 1.8, 2.2, 2.6, 3.0]]))
    masked = scan_ranges(np.array([[0.5, 2.0, 4.0]]), spec)
    assert masked == pytest.approx(np.array([[-math.inf, 1.1, 1.7, 2.4, 3.2, math.inf]]))
    rng = np.random.default_rng(1)
    loud = RayNoise(GaussianNoise(stddev=10.0), rng)
    noisy = scan_ranges(np.full((1, 3), 2.0), spec, loud, rng)
    assert np.all((noisy >= 0.5) & (noisy <= 4.0))  # clamped to the range limits
    assert np.isin(noisy, [0.5, 4.0]).any()  # N(0, 10 m) mostly leaves the limits


@given(
    st.integers(1, 40),
    st.floats(-math.pi, 0.0),
    st.floats(0.0, math.pi),
    st.integers(1, 8),
    st.floats(-1.5, 0.0),
    st.floats(0.0, 1.5),
)
def test_ray_directions_are_unit_vectors_at_the_scan_angles(
    h: int, h_lo: float, h_hi: float, v: int, v_lo: float, v_hi: float
) -> None:
    horizontal = RayScan(samples=h, min_angle=h_lo, max_angle=h_hi)
    vertical = RayScan(samples=v, min_angle=v_lo, max_angle=v_hi)
    dirs = ray_directions(horizontal, vertical).reshape(v, h, 3)
    assert np.linalg.norm(dirs, axis=-1) == pytest.approx(np.ones((v, h)))
    yaw = np.zeros(1) if h == 1 else np.linspace(h_lo, h_hi, h)
    pitch = np.zeros(1) if v == 1 else np.linspace(v_lo, v_hi, v)
    assert np.arcsin(np.clip(dirs[..., 2], -1, 1)) == pytest.approx(
        np.repeat(pitch[:, None], h, axis=1), abs=1e-9
    )
    az = np.arctan2(dirs[..., 1], dirs[..., 0])
    assert np.cos(az - yaw[None, :]) == pytest.approx(np.ones((v, h)))
