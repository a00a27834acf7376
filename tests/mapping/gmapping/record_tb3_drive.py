"""Record the gmapping fixture: a TurtleBot3 burger driving a loop in turtlebot3_world.

Not a test: run ``python tests/mapping/gmapping/record_tb3_drive.py`` to rewrite
``data/tb3_world_loop.npz``. The robot and world are ROBOTIS' files in tests/data/turtlebot3,
simulated by visnav's simulator; a waypoint controller drives from the ground-truth pose
(the burger's diff drive publishes the world pose on /odom: ``odometrySource world``).
Saved: every /scan (ranges float32, stamps), the true base pose at each scan (odom
interpolated to the scan stamp), the laser mounting, and the world's walls and pillars cut
at the laser's height (2D segments, from the collision meshes with trimesh) for scoring
maps. Drifting wheel odometry is made from the true increments in the test (seeded).
"""

from __future__ import annotations

import math
import os
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

HERE = Path(__file__).resolve().parent
DATA = HERE.parent.parent / "data" / "turtlebot3"
DESCRIPTION = DATA / "turtlebot3_description"
GAZEBO = DATA / "turtlebot3_gazebo"
WORLD = GAZEBO / "worlds" / "turtlebot3_world.world"
MODEL_SDF = GAZEBO / "models" / "turtlebot3_world" / "model.sdf"
OUT = HERE / "data" / "tb3_world_loop.npz"
# a loop through the lanes between the pillars (pillars at -1.1, 0, 1.1 on both axes)
WAYPOINTS = [
    (-1.65, -0.55),
    (1.65, -0.55),
    (1.65, 0.55),
    (-1.65, 0.55),
    (-1.65, -0.55),
    (0.0, -0.55),
]


def _pose(element: ET.Element) -> np.ndarray:
    x, y, z, r, p, yaw = (float(v) for v in (element.findtext("pose") or "0 0 0 0 0 0").split())
    t = np.eye(4)
    t[:3, :3] = Rotation.from_euler("xyz", [r, p, yaw]).as_matrix()
    t[:3, 3] = (x, y, z)
    return t


def world_mesh() -> trimesh.Trimesh:
    """turtlebot3_world's collision geometry (cylinders and the hexagon mesh, in metres)."""
    parts = []
    for collision in ET.parse(MODEL_SDF).getroot().iter("collision"):
        geometry = collision.find("geometry")
        assert geometry is not None
        cylinder, mesh = geometry.find("cylinder"), geometry.find("mesh")
        if cylinder is not None:
            part = trimesh.creation.cylinder(
                radius=float(cylinder.findtext("radius") or 0),
                height=float(cylinder.findtext("length") or 0),
                sections=256,
            )
        else:
            assert mesh is not None
            path = GAZEBO / "models" / (mesh.findtext("uri") or "").removeprefix("model://")
            unit = float(re.search(r'<unit[^>]*meter="([0-9.eE+-]+)"', path.read_text())[1])  # type: ignore[index]
            scale = np.array([float(v) for v in (mesh.findtext("scale") or "1 1 1").split()])
            part = trimesh.load(path, force="mesh")
            part.vertices = part.vertices * unit * scale
        part.apply_transform(_pose(collision))
        parts.append(part)
    return trimesh.util.concatenate(parts)


def wall_segments(z: float) -> np.ndarray:
    """(S, 4) segments ``x0 y0 x1 y1`` of the world's surfaces at height ``z``."""
    section = world_mesh().section(plane_origin=[0, 0, z], plane_normal=[0, 0, 1])
    segs = [np.concatenate([line[:-1, :2], line[1:, :2]], axis=1) for line in section.discrete]
    return np.concatenate(segs).astype(np.float64)


def main() -> int:
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ["GAZEBO_MODEL_PATH"] = str(GAZEBO / "models")
    from visnav.graph import Context, Node
    from visnav.msgs import LaserScan, Odometry, TFMessage, Twist, Vector3
    from visnav.sim.simulator import RobotSpawn, Simulator

    scans: list[Any] = []
    odoms: list[tuple[float, float, float, float]] = []
    tf_static: list[Any] = []
    with Context(transport="local") as ctx:
        node = Node("recorder", context=ctx)
        node.create_subscription(LaserScan, "/scan", scans.append, 10_000)
        node.create_subscription(TFMessage, "/tf_static", tf_static.append, 10_000)

        def on_odom(msg: Odometry) -> None:
            q = msg.pose.pose.orientation
            yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
            t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            odoms.append((t, msg.pose.pose.position.x, msg.pose.pose.position.y, yaw))

        node.create_subscription(Odometry, "/odom", on_odom, 10_000)
        cmd = node.create_publisher(Twist, "/cmd_vel", 1)
        spawn = RobotSpawn(
            source=DESCRIPTION / "urdf" / "turtlebot3_burger.urdf.xacro",
            packages={"turtlebot3_description": DESCRIPTION},
            spawn=(-2.0, -0.5, 0.0, 0.0),
        )
        goal = 0
        with Simulator(WORLD, [spawn], context=ctx) as sim:
            base = sim.model.body(f"{sim.robot().name}/base_footprint")
            laser = sim.model.body(f"{sim.robot().name}/base_scan")
            for _ in range(2000):
                sim.run(0.1)
                if not odoms:
                    continue
                _, x, y, yaw = odoms[-1]
                gx, gy = WAYPOINTS[goal]
                if math.hypot(gx - x, gy - y) < 0.06:
                    goal += 1
                    if goal == len(WAYPOINTS):
                        break
                    continue
                err = math.atan2(
                    math.sin(math.atan2(gy - y, gx - x) - yaw),
                    math.cos(math.atan2(gy - y, gx - x) - yaw),
                )
                w = float(np.clip(2.0 * err, -1.0, 1.0))
                v = 0.18 if abs(err) < 0.3 else 0.0
                cmd.publish(
                    Twist(linear=Vector3(x=v, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=w))
                )
            R_wb = np.array(sim.data.xmat[base.id]).reshape(3, 3)
            R_wl = np.array(sim.data.xmat[laser.id]).reshape(3, 3)
            T_base_laser = np.eye(4)
            T_base_laser[:3, :3] = R_wb.T @ R_wl
            T_base_laser[:3, 3] = R_wb.T @ (
                np.array(sim.data.xpos[laser.id]) - np.array(sim.data.xpos[base.id])
            )
            laser_z = float(sim.data.xpos[laser.id][2])
    od = np.array(odoms)
    stamps = np.array([s.header.stamp.sec + 1e-9 * s.header.stamp.nanosec for s in scans])
    keep = stamps <= od[-1, 0]
    stamps = stamps[keep]
    yaw_u = np.unwrap(od[:, 3])
    truth = np.stack(
        [
            np.interp(stamps, od[:, 0], od[:, 1]),
            np.interp(stamps, od[:, 0], od[:, 2]),
            np.interp(stamps, od[:, 0], yaw_u),
        ],
        axis=1,
    )
    ranges = np.array([np.asarray(s.ranges, dtype=np.float32) for s in scans])[keep]
    first = scans[0]
    OUT.parent.mkdir(exist_ok=True)
    np.savez_compressed(
        OUT,
        ranges=ranges,
        stamps=stamps,
        truth=truth,
        T_base_laser=T_base_laser,
        angle_min=float(first.angle_min),
        angle_increment=float(first.angle_increment),
        range_min=float(first.range_min),
        range_max=float(first.range_max),
        frame_id=str(first.header.frame_id),
        walls=wall_segments(laser_z),
    )
    print(
        f"{OUT}: {len(stamps)} scans over {stamps[-1] - stamps[0]:.1f} s, "
        f"goal {goal}/{len(WAYPOINTS)}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
