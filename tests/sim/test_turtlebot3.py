"""ROBOTIS' TurtleBot3 (noetic packages as written) in turtlebot3_world and turtlebot3_house.

The robots, worlds and launch files are the fixtures in ``tests/data/turtlebot3`` (the house's
database models in ``tests/data/gazebo_models``). The laser's true ranges come from an oracle
that shares nothing with the simulator: each world's collision geometry rebuilt here from its
``model.sdf`` (boxes, cylinders, and the Collada meshes in Gazebo's units: ``<unit meter>``
times the SDF ``<scale>``; nested model, link and collision poses composed) and intersected
with trimesh's ray-triangle tests.
"""

from __future__ import annotations

import math
import os
import re
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET
from collections import defaultdict
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from visnav.graph import Context, Node
from visnav.msgs import CameraInfo, Image, Imu, JointState, LaserScan, Odometry, TFMessage, Twist
from visnav.msgs.construct import message_from_dict
from visnav.sim.simulator import RobotSpawn, Simulator

DATA = Path(__file__).resolve().parent.parent / "data" / "turtlebot3"
DESCRIPTION = DATA / "turtlebot3_description"
GAZEBO = DATA / "turtlebot3_gazebo"
WORLD = GAZEBO / "worlds" / "turtlebot3_world.world"
MODEL_SDF = GAZEBO / "models" / "turtlebot3_world" / "model.sdf"
HOUSE_SDF = GAZEBO / "models" / "turtlebot3_house" / "model.sdf"
GAZEBO_MODELS = DATA.parent / "gazebo_models"  # Gazebo's database models the house includes
LDS_SIGMA = 0.01  # <noise><stddev> of the burger's lds_lfcd_sensor


def stamp_s(msg: Any) -> float:
    return float(msg.header.stamp.sec) + 1e-9 * float(msg.header.stamp.nanosec)


def _pose(element: ET.Element) -> np.ndarray:
    text = element.findtext("pose") or "0 0 0 0 0 0"
    x, y, z, r, p, yaw = (float(v) for v in text.split())
    t = np.eye(4)
    t[:3, :3] = Rotation.from_euler("xyz", [r, p, yaw]).as_matrix()
    t[:3, 3] = (x, y, z)
    return t


def world_collision_mesh() -> trimesh.Trimesh:
    """turtlebot3_world's collision geometry as Gazebo builds it (the test's own reading)."""
    root = ET.parse(MODEL_SDF).getroot()
    parts: list[trimesh.Trimesh] = []
    for collision in root.iter("collision"):
        geometry = collision.find("geometry")
        assert geometry is not None
        cylinder = geometry.find("cylinder")
        mesh = geometry.find("mesh")
        if cylinder is not None:
            part = trimesh.creation.cylinder(
                radius=float(cylinder.findtext("radius") or 0),
                height=float(cylinder.findtext("length") or 0),
                sections=128,
            )
        else:
            assert mesh is not None
            uri = mesh.findtext("uri") or ""
            path = GAZEBO / "models" / uri.removeprefix("model://")
            unit = float(re.search(r'<unit[^>]*meter="([0-9.eE+-]+)"', path.read_text())[1])  # type: ignore[index]
            scale = np.array([float(v) for v in (mesh.findtext("scale") or "1 1 1").split()])
            part = trimesh.load(path, force="mesh")
            part.vertices = part.vertices * unit * scale
        part.apply_transform(_pose(collision))
        parts.append(part)
    return trimesh.util.concatenate(parts)


def _mesh_file(uri: str) -> Path:
    name = uri.removeprefix("model://").lstrip("/")
    for root in (GAZEBO / "models", GAZEBO_MODELS):
        if (root / name).is_file():
            return root / name
    raise FileNotFoundError(uri)


def _collision_part(geometry: ET.Element) -> trimesh.Trimesh | None:
    box, cylinder, mesh = geometry.find("box"), geometry.find("cylinder"), geometry.find("mesh")
    if box is not None:
        return trimesh.creation.box(extents=[float(v) for v in box.findtext("size", "").split()])
    if cylinder is not None:
        return trimesh.creation.cylinder(
            radius=float(cylinder.findtext("radius") or 0),
            height=float(cylinder.findtext("length") or 0),
            sections=128,
        )
    if mesh is None:
        return None
    path = _mesh_file(mesh.findtext("uri") or "")
    found = re.search(r'<unit[^>]*meter="([0-9.eE+-]+)"', path.read_text(errors="replace"))
    unit = float(found[1]) if found else 1.0
    scale = np.array([float(v) for v in (mesh.findtext("scale") or "1 1 1").split()])
    part = trimesh.load(path, force="mesh")
    part.vertices = part.vertices * unit * scale
    return part


def sdf_collision_mesh(model: ET.Element, t_parent: np.ndarray) -> list[trimesh.Trimesh]:
    """Every collision of ``model`` (nested models, links, collisions; poses composed)."""
    t_model = t_parent @ _pose(model)
    parts = []
    for child in model:
        if child.tag == "model":
            parts += sdf_collision_mesh(child, t_model)
        elif child.tag == "link":
            t_link = t_model @ _pose(child)
            for collision in child.findall("collision"):
                geometry = collision.find("geometry")
                part = None if geometry is None else _collision_part(geometry)
                if part is not None:
                    part.apply_transform(t_link @ _pose(collision))
                    parts.append(part)
    return parts


def true_ranges(mesh: trimesh.Trimesh, origin: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Distance to the first surface along horizontal beams from ``origin`` (inf: none)."""
    n = len(angles)
    directions = np.stack([np.cos(angles), np.sin(angles), np.zeros(n)], axis=1)
    origins = np.repeat(origin[None, :], n, axis=0)
    locations, index_ray, _ = mesh.ray.intersects_location(origins, directions, multiple_hits=True)
    ranges = np.full(n, np.inf)
    distance = np.linalg.norm(locations - origins[index_ray], axis=1)
    np.minimum.at(ranges, index_ray, distance)
    return ranges


class Recorder:
    def __init__(self, ctx: Context, topics: dict[str, type[Any]]) -> None:
        self.node = Node("tb3_recorder", context=ctx)
        self.messages: dict[str, list[Any]] = defaultdict(list)
        for topic, msg_type in topics.items():
            self.node.create_subscription(msg_type, topic, self._keep(topic), 10_000)

    def _keep(self, topic: str) -> Callable[[Any], None]:
        return self.messages[topic].append


@pytest.fixture
def ctx(mujoco_gl: str, monkeypatch: pytest.MonkeyPatch) -> Iterator[Context]:
    del mujoco_gl
    monkeypatch.setenv("GAZEBO_MODEL_PATH", f"{GAZEBO / 'models'}:{GAZEBO_MODELS}")
    with Context(transport="local") as context:
        yield context


def spawn(model: str, x: float = -2.0, y: float = -0.5, yaw: float = 0.0) -> RobotSpawn:
    return RobotSpawn(
        source=DESCRIPTION / "urdf" / f"turtlebot3_{model}.urdf.xacro",
        packages={"turtlebot3_description": DESCRIPTION},
        spawn=(x, y, 0.0, yaw),
    )


def house_collision_mesh() -> trimesh.Trimesh:
    """turtlebot3_house's collision geometry (boxes, cylinders, the database models' meshes)."""
    root = ET.parse(HOUSE_SDF).getroot()
    model = root.find("model")
    assert model is not None
    return trimesh.util.concatenate(sdf_collision_mesh(model, np.eye(4)))


WORLD_ORACLES: dict[str, Callable[[], trimesh.Trimesh]] = {
    "turtlebot3_world": world_collision_mesh,
    "turtlebot3_house": house_collision_mesh,
}


@pytest.mark.parametrize(
    ("world", "x", "y", "yaw"),
    [
        ("turtlebot3_world", -2.0, -0.5, 0.0),
        ("turtlebot3_world", 0.5, 0.55, 1.2),
        ("turtlebot3_world", 1.6, -1.0, -2.5),
        ("turtlebot3_house", -3.0, 1.0, 0.0),
        ("turtlebot3_house", 2.5, -2.0, 1.0),
        ("turtlebot3_house", -1.5, 3.5, -2.0),
    ],
)
def test_burger_scan_matches_the_worlds_walls_and_pillars(
    ctx: Context, world: str, x: float, y: float, yaw: float
) -> None:
    rec = Recorder(ctx, {"/scan": LaserScan})
    world_file = GAZEBO / "worlds" / f"{world}.world"
    with Simulator(world_file, [spawn("burger", x, y, yaw)], context=ctx) as sim:
        sim.run(1.25)
        body = sim.model.body(f"{sim.robot().name}/base_scan")
        origin = np.array(sim.data.xpos[body.id])
        rot = np.array(sim.data.xmat[body.id]).reshape(3, 3)
    scans = rec.messages["/scan"]
    assert [round(stamp_s(s), 6) for s in scans] == [0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2]
    scan = scans[-1]
    assert scan.header.frame_id == "base_scan"
    assert len(scan.ranges) == 360
    assert (scan.range_min, scan.range_max) == pytest.approx((0.12, 3.5))
    assert scan.angle_min == pytest.approx(0.0)
    assert scan.angle_max == pytest.approx(6.28319)
    assert scan.angle_increment == pytest.approx(6.28319 / 359, rel=1e-6)
    sensor_yaw = math.atan2(rot[1, 0], rot[0, 0])
    angles = sensor_yaw + scan.angle_min + np.arange(360) * scan.angle_increment
    truth = true_ranges(WORLD_ORACLES[world](), origin, angles)
    ranges = np.asarray(scan.ranges, dtype=float)
    hits = (truth > 0.12 + 3 * LDS_SIGMA) & (truth < 3.5 - 3 * LDS_SIGMA)
    assert hits.sum() >= 40, f"too few beams hit anything from ({x}, {y})"
    within = np.abs(ranges[hits] - truth[hits]) <= 3 * LDS_SIGMA
    assert within.mean() >= 0.95, (
        f"{within.mean():.3f} of {hits.sum()} beams within 3 sigma; worst "
        f"{np.max(np.abs(ranges[hits] - truth[hits])):.3f} m"
    )
    # beams that see nothing within range report inf (gazebo_ros_laser's convention)
    empty = truth > 3.5 + 3 * LDS_SIGMA
    assert np.all(np.isinf(ranges[empty]) | (ranges[empty] > 3.5))


def test_burger_topics_rates_and_driving(ctx: Context) -> None:
    topics = {
        "/scan": LaserScan,
        "/imu": Imu,
        "/odom": Odometry,
        "/joint_states": JointState,
        "/tf": TFMessage,
    }
    rec = Recorder(ctx, topics)
    driver = Node("driver", context=ctx)
    cmd = driver.create_publisher(Twist, "/cmd_vel", 1)
    with Simulator(WORLD, [spawn("burger")], context=ctx) as sim:
        cmd.publish(message_from_dict("geometry_msgs/msg/Twist", {"linear": {"x": 0.2}}))
        sim.run(2.0)
    m = rec.messages
    # ROS 1's gazebo_ros_imu with updateRate 0 publishes every world update (1 ms steps here)
    imu_dt = np.diff([stamp_s(msg) for msg in m["/imu"]])
    assert np.median(imu_dt) == pytest.approx(0.001, rel=1e-3)
    assert m["/imu"][-1].header.frame_id == "imu_link"
    odom_dt = np.diff([stamp_s(msg) for msg in m["/odom"]])
    assert np.median(odom_dt) == pytest.approx(1 / 30, rel=0.05)  # diff drive updateRate 30
    odom = m["/odom"][-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_footprint")
    # odometrySource world: gazebo_ros_diff_drive publishes the model's world pose as /odom
    assert odom.pose.pose.position.x == pytest.approx(-2.0 + 0.2 * 2.0, abs=0.12)
    names = set(m["/joint_states"][-1].name)
    assert {"wheel_left_joint", "wheel_right_joint"} <= names
    frames = {(t.header.frame_id, t.child_frame_id) for msg in m["/tf"] for t in msg.transforms}
    assert ("odom", "base_footprint") in frames
    assert ("base_link", "wheel_left_link") in frames
    assert ("base_link", "wheel_right_link") in frames


def test_waffle_pi_camera_at_its_plugin_rate_with_gazebo_ros_names(ctx: Context) -> None:
    rec = Recorder(ctx, {"/camera/rgb/image_raw": Image, "/camera/rgb/camera_info": CameraInfo})
    with Simulator(WORLD, [spawn("waffle_pi")], context=ctx) as sim:
        sim.run(1.0)
    images = rec.messages["/camera/rgb/image_raw"]
    stamps = [stamp_s(msg) for msg in images]
    assert np.median(np.diff(stamps)) == pytest.approx(1 / 30, rel=0.05)
    assert len(images) in (30, 31)
    image = images[-1]
    info = rec.messages["/camera/rgb/camera_info"][-1]
    assert (image.encoding, image.width, image.height) == ("rgb8", 640, 480)
    assert image.header.frame_id == info.header.frame_id == "camera_rgb_optical_frame"
    focal = 320.0 / math.tan(1.085595 / 2.0)
    assert list(info.k) == pytest.approx([focal, 0, 320.5, 0, focal, 240.5, 0, 0, 1], abs=0.6)


@pytest.mark.slow
@pytest.mark.ci
@pytest.mark.parametrize(
    ("launch", "model"),
    [("turtlebot3_world.launch", "burger"), ("turtlebot3_house.launch", "waffle_pi")],
)
def test_turtlebot3_gazebo_launch_files_as_written(domain: int, launch: str, model: str) -> None:
    env = {
        **os.environ,
        "VISNAV_DOMAIN": str(domain),
        "TURTLEBOT3_MODEL": model,
        "GAZEBO_MODEL_PATH": str(GAZEBO_MODELS),
    }
    cmd = [
        sys.executable, "-m", "visnav.cli.main", "launch", str(GAZEBO / "launch" / launch),
        "--package", f"turtlebot3_description={DESCRIPTION}",
        "--package", f"turtlebot3_gazebo={GAZEBO}",
    ]  # fmt: skip
    proc = subprocess.Popen(cmd, env=env, text=True, stderr=subprocess.PIPE)
    topics: dict[str, type[Any]] = {"/scan": LaserScan, "/odom": Odometry}
    if model == "waffle_pi":
        topics["/camera/rgb/image_raw"] = Image
    try:
        with Context(domain) as ctx:
            rec = Recorder(ctx, topics)
            ok = ctx.spin_until(lambda: len(rec.messages["/scan"]) >= 6, 180.0)
            assert ok, f"no /scan from {launch}: {proc.poll()}"
        scans = rec.messages["/scan"]
        dt = np.diff([stamp_s(s) for s in scans])
        assert np.allclose(dt, 0.2, atol=1e-6), dt
        ranges = np.asarray(scans[-1].ranges)
        assert len(ranges) == 360
        assert np.isfinite(ranges).sum() > 60, "the world's obstacles are not in the scan"
        if model == "waffle_pi":
            images = rec.messages["/camera/rgb/image_raw"]
            assert len(images) >= 20
            assert images[-1].header.frame_id == "camera_rgb_optical_frame"
            stamps = [stamp_s(m) for m in images]
            assert (stamps[-1] - stamps[0]) / (len(stamps) - 1) == pytest.approx(1 / 30, rel=0.02)
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    assert "Traceback" not in err, err
