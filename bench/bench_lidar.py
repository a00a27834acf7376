"""Benchmark: ray sensors (issue 27.1) — batched casting, the burger's LDS, a VLP-16.

Rows (medians of repeated runs, ratio to the reference measured in the same run):

* rays per second of :meth:`visnav.sim.lidar.RayCaster.cast` (one ``mj_multiRay`` call)
  vs a naive Python loop of ``mujoco.mj_ray`` over the same rays, from the TurtleBot3
  burger's LDS (360 rays) and from a VLP-16 (16 x 1800 rays), in a room with pillars;
* the burger's LDS (``/scan`` at 5 Hz: cast, LaserScan, publish) vs the burger's physics
  (the simulator's steps of one scan period, the LDS idle), timed in alternation, in the
  room and in ROBOTIS' turtlebot3_world (the test fixture); the goal is <= 5 %;
* a VLP-16 (16 x 1800 at 10 Hz: cast, velodyne cloud, publish) per simulated second vs
  one second of wall time (the real-time budget).

Run: python bench/bench_lidar.py [--repeats N]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from visnav.description.world_yaml import world_from_dict
from visnav.graph import Context
from visnav.sim.lidar import RayCaster
from visnav.sim.ray_plugin import RayPlugin
from visnav.sim.simulator import RobotSpawn, Simulator

DATA = Path(__file__).resolve().parent.parent / "tests/data/turtlebot3"
TB3 = DATA / "turtlebot3_description"
TB3_WORLD = DATA / "turtlebot3_gazebo" / "worlds" / "turtlebot3_world.world"

VLP16 = """<robot name="vlp_rig">
  <link name="world"/>
  <link name="velodyne"><inertial><mass value="0.8"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
    <collision><geometry><cylinder radius="0.05" length="0.07"/></geometry></collision></link>
  <joint name="mount" type="fixed"><parent link="world"/><child link="velodyne"/>
    <origin xyz="0.3 0.2 1.0"/></joint>
  <gazebo reference="velodyne"><sensor type="ray" name="vlp16"><update_rate>10</update_rate>
    <ray><scan><horizontal><samples>1800</samples><resolution>1</resolution>
      <min_angle>-3.14159265</min_angle><max_angle>3.14159265</max_angle></horizontal>
      <vertical><samples>16</samples><resolution>1</resolution>
      <min_angle>-0.261799</min_angle><max_angle>0.261799</max_angle></vertical></scan>
      <range><min>0.3</min><max>131</max><resolution>0.001</resolution></range>
      <noise><type>gaussian</type><mean>0</mean><stddev>0.0</stddev></noise></ray>
    <plugin name="vlp" filename="libgazebo_ros_velodyne_laser.so">
      <topicName>velodyne_points</topicName><frameName>velodyne</frameName>
      <min_range>0.9</min_range><max_range>130</max_range><gaussianNoise>0.008</gaussianNoise>
    </plugin></sensor></gazebo>
</robot>"""


def room() -> Any:
    walls: list[dict[str, Any]] = [
        {"type": "box", "name": "e", "pos": [4.1, 0, 1], "size": [0.2, 6.4, 2]},
        {"type": "box", "name": "w", "pos": [-4.1, 0, 1], "size": [0.2, 6.4, 2]},
        {"type": "box", "name": "n", "pos": [0, 3.1, 1], "size": [8.4, 0.2, 2]},
        {"type": "box", "name": "s", "pos": [0, -3.1, 1], "size": [8.4, 0.2, 2]},
    ]
    for k in range(12):
        angle = 2 * math.pi * k / 12
        pos = [2.2 * math.cos(angle), 1.6 * math.sin(angle), 0.5]
        walls.append({"type": "cylinder", "name": f"p{k}", "pos": pos, "radius": 0.1, "length": 1})
    doc = {"name": "bench_room", "ground": {"size": [20, 20]}, "objects": walls}
    return world_from_dict(doc, source="bench_room")


def _median_ms(fn: Callable[[], object], repeats: int, inner: int = 1) -> float:
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(inner):
            fn()
        times.append((time.perf_counter() - t0) / inner * 1e3)
    return statistics.median(times)


def naive_cast(caster: RayCaster, data: mujoco.MjData) -> np.ndarray:
    """The reference: one ``mj_ray`` per ray from Python, same rays, filters and exclusion."""
    origin, rot = caster.sensor_pose(data)
    dirs = caster.directions @ rot.T
    out = np.empty(caster.rays)
    gid = np.zeros(1, dtype=np.int32)
    groups = np.ones(mujoco.mjNGROUP, dtype=np.uint8)
    groups[1] = 0
    for k in range(caster.rays):
        out[k] = mujoco.mj_ray(caster.model, data, origin, dirs[k], groups, 1, caster.body, gid)
    return out


def ray_plugin(sim: Simulator) -> RayPlugin:
    return next(p for p in sim.robot().plugins if isinstance(p, RayPlugin))


def bench_rays_per_second(sim: Simulator, label: str, repeats: int) -> None:
    plugin = ray_plugin(sim)
    caster, data = plugin.caster, sim.data
    fast = _median_ms(lambda: caster.cast(data), repeats, inner=5)
    slow = _median_ms(lambda: naive_cast(caster, data), max(3, repeats // 3))
    batched = np.asarray(caster.cast(data)).reshape(-1)
    naive = naive_cast(caster, data)
    naive = np.where(naive < 0, caster.spec.range_max, np.minimum(naive, caster.spec.range_max))
    same = np.mean(np.isclose(batched, naive, atol=1e-9))
    n = caster.rays
    print(
        f"{label}: {n} rays  batched {fast:.3f} ms ({n / fast / 1e3:.2f} M rays/s)  naive "
        f"mj_ray loop {slow:.2f} ms ({n / slow / 1e3:.3f} M rays/s)  speed-up "
        f"{slow / fast:.1f}x  (same range on {100 * same:.1f} % of rays)"
    )


def _paired(
    fn: Callable[[], object], ref: Callable[[], object], repeats: int
) -> tuple[float, float, float]:
    """Medians (ms) of ``fn`` and ``ref`` timed in alternation, and the median per-pair ratio.

    Alternating keeps the load of other processes on the machine in both.
    """
    fn()
    ref()
    a, b, ratios = [], [], []
    for _ in range(repeats):
        pair = []
        for f in (fn, ref):
            t0 = time.perf_counter()
            f()
            pair.append((time.perf_counter() - t0) * 1e3)
        a.append(pair[0])
        b.append(pair[1])
        ratios.append(pair[0] / pair[1])
    return statistics.median(a), statistics.median(b), statistics.median(ratios)


def bench_burger(repeats: int, *, world: Any, label: str, xy_yaw: tuple[float, ...]) -> None:
    spawn = RobotSpawn(
        source=TB3 / "urdf" / "turtlebot3_burger.urdf.xacro",
        packages={"turtlebot3_description": TB3},
        spawn=(xy_yaw[0], xy_yaw[1], 0.0, xy_yaw[2]),
    )
    with Context(transport="local") as ctx, Simulator(world, [spawn], context=ctx) as sim:
        sim.run(0.5)  # settle
        bench_rays_per_second(sim, f"burger LDS in {label}", repeats)
        plugin = ray_plugin(sim)
        rate = plugin.spec.update_rate
        # one LDS period of the burger's physics (the LDS idle: nobody subscribes), paired
        # with one scan (cast, LaserScan, publish); the share is their ratio
        steps = round(1e9 / rate / sim.timestep_ns)
        scan, physics, share = _paired(
            lambda: plugin.scan(sim.data, sim.now_ns), lambda: sim.step(steps), 3 * repeats
        )
        print(
            f"burger in {label}: physics {physics * rate:.1f} ms per simulated s ({steps} steps of "
            f"{sim.timestep_ns / 1e6:g} ms per scan period)  LDS {scan:.3f} ms per scan x "
            f"{rate:g} Hz = {scan * rate:.2f} ms per simulated s  share {100 * share:.2f} % "
            "(goal <= 5 %)"
        )


def bench_vlp16(repeats: int) -> None:
    with Context(transport="local") as ctx:
        spawn = RobotSpawn(source=VLP16)
        with Simulator(room(), [spawn], context=ctx) as sim:
            sim.step(1)
            bench_rays_per_second(sim, "VLP-16", max(5, repeats // 2))
            plugin = ray_plugin(sim)
            cloud = _median_ms(lambda: plugin.scan(sim.data, sim.now_ns), max(5, repeats // 2))
            rate = plugin.spec.update_rate
            per_s = cloud * rate
            print(
                f"VLP-16 (16 x 1800 at {rate:g} Hz): {cloud:.1f} ms per cloud = {per_s:.0f} ms "
                f"per simulated s = {100 * per_s / 1000:.1f} % of real time"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    bench_burger(args.repeats, world=room(), label="the room", xy_yaw=(0.3, -0.2, 0.4))
    if TB3_WORLD.exists():  # ROBOTIS' world: 51 Collada meshes, 91,688 faces
        os.environ.setdefault("GAZEBO_MODEL_PATH", str(TB3_WORLD.parent.parent / "models"))
        bench_burger(args.repeats, world=TB3_WORLD, label="turtlebot3_world", xy_yaw=(-2, -0.5, 0))
    bench_vlp16(args.repeats)


if __name__ == "__main__":
    main()
