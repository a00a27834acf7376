"""Simulator benchmarks (issue 3), headless, software OpenGL.

Run: ``python bench/bench_sim.py [--repeat N] [--seconds S]``. Prints medians of
repeated runs:

* (a) the built-in car in ``office``: RGB 640x480 @ 30 Hz, depth 640x480 @ 20 Hz
  with its colour image and point cloud, p3d ground truth and diff-drive odometry
  @ 50 Hz, TF, joint states, driving a slow circle; in-process subscribers on every
  sensor topic. Real-time factor (target >= 1.0) and the share of wall time spent
  rendering; then visnav's render rate of the RGB camera (``CameraSensor.render``:
  render, read back, noise, message) against bare ``mujoco.Renderer`` rendering of
  the same camera in the same state, timed alternately (target >= 0.85).
* (b) the built-in quadrotor in ``forest``: depth 640x480 @ 20 Hz with point
  cloud (and the colour image the ROS 2 depth plugin publishes), p3d @ 100 Hz,
  flying forward at 1.5 m. Real-time factor (target >= 3).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

# mujoco picks its OpenGL platform when imported (for mujoco.Renderer): headless EGL.
os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco

from visnav.graph import Context, Node
from visnav.msgs import CameraInfo, Image, Odometry, PointCloud2, TFMessage, Twist
from visnav.msgs.construct import message_from_dict
from visnav.sim.plugins import CameraPlugin
from visnav.sim.simulator import RobotSpawn, SimStats, Simulator
from visnav.sim.vehicles.quadrotor import PositionCommand

SENSOR_TOPICS: dict[str, type[Any]] = {
    "/camera/image_raw": Image,
    "/camera/camera_info": CameraInfo,
    "/depth_camera/image_raw": Image,
    "/depth_camera/depth/image_raw": Image,
    "/depth_camera/points": PointCloud2,
    "/ground_truth/odom": Odometry,
    "/odom": Odometry,
    "/tf": TFMessage,
}


def consumers(ctx: Context) -> dict[str, int]:
    """In-process subscribers counting messages on every sensor topic."""
    node = Node("bench_consumer", context=ctx)
    counts = dict.fromkeys(SENSOR_TOPICS, 0)

    def counter(topic: str) -> Callable[[Any], None]:
        def count(_: Any) -> None:
            counts[topic] += 1

        return count

    for topic, msg_type in SENSOR_TOPICS.items():
        node.create_subscription(msg_type, topic, counter(topic), 10)
    return counts


def runs(sim: Simulator, seconds: float, repeat: int) -> list[SimStats]:
    sim.run(0.5)  # warm up (GL programs, first frames)
    return [sim.run(seconds) for _ in range(repeat)]


def report(label: str, stats: list[SimStats], target: float) -> None:
    rtf = statistics.median(s.real_time_factor for s in stats)
    share = statistics.median(s.render_share for s in stats)
    each = ", ".join(f"{s.real_time_factor:.2f}" for s in stats)
    verdict = "ok" if rtf >= target else "BELOW TARGET"
    print(
        f"{label}: real-time factor {rtf:.2f} (runs {each}; target >= {target}: {verdict}), "
        f"rendering {100 * share:.0f}% of wall time"
    )


def render_ratio(sim: Simulator, plugin: CameraPlugin, repeat: int) -> tuple[float, float]:
    """Median ms per frame of visnav's camera and of bare mujoco.Renderer, alternated."""
    spec = plugin.spec
    renderer = mujoco.Renderer(sim.model, height=spec.height, width=spec.width)
    flags = renderer.scene.flags
    flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0  # as visnav's cameras
    flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
    camera = plugin.sensor.camera_id
    data = sim.data

    def bare() -> None:
        renderer.update_scene(data, camera=camera)
        renderer.render()

    def ours() -> None:
        plugin.sensor.render(data, stamp_ns=sim.now_ns)

    for _ in range(5):
        bare()
        ours()
    a: list[float] = []
    b: list[float] = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        ours()
        t1 = time.perf_counter()
        bare()
        t2 = time.perf_counter()
        a.append(t1 - t0)
        b.append(t2 - t1)
    renderer.close()
    return statistics.median(a) * 1e3, statistics.median(b) * 1e3


def bench_car(seconds: float, repeat: int) -> None:
    with Context(transport="local") as ctx:
        counts = consumers(ctx)
        driver = Node("bench_driver", context=ctx)
        cmd = driver.create_publisher(Twist, "/cmd_vel", 1)
        with Simulator("office", [RobotSpawn(source="car")], context=ctx) as sim:
            cmd.publish(
                message_from_dict(
                    "geometry_msgs/msg/Twist", {"linear": {"x": 0.3}, "angular": {"z": 0.25}}
                )
            )
            stats = runs(sim, seconds, repeat)
            report("(a) car, office, RGB@30 + depth@20 + cloud + odom@50 + TF", stats, 1.0)
            rgb = next(p for p in sim.robot().plugins if isinstance(p, CameraPlugin))
            in_run = rgb.render_ns / rgb.frames * 1e-6
            ours, bare = render_ratio(sim, rgb, 60)
            ratio = bare / ours
            verdict = "ok" if ratio >= 0.85 else "BELOW TARGET"
            print(
                f"    RGB camera 640x480: visnav {ours:.2f} ms/frame (in the run: {in_run:.2f}), "
                f"bare mujoco.Renderer {bare:.2f} ms/frame: render-rate ratio {ratio:.2f} "
                f"(target >= 0.85: {verdict})"
            )
            total = sum(s.sim_time_s for s in stats) + 0.5
            print(
                f"    messages over {total:.1f} s of sim time: "
                + ", ".join(f"{t} {n}" for t, n in counts.items())
            )


def bench_quadrotor(seconds: float, repeat: int) -> None:
    with Context(transport="local") as ctx:
        counts = consumers(ctx)
        with Simulator("forest", [RobotSpawn(source="quadrotor")], context=ctx) as sim:
            x = sim.robot().handles.root_body
            start = sim.data.xpos[sim.model.body(x).id]
            goal = (float(start[0]) + 30.0, float(start[1]), 1.5)
            sim.set_position_command(PositionCommand.hold(goal))
            stats = runs(sim, seconds, repeat)
            report("(b) quadrotor, forest, depth@20 + cloud + odom@100", stats, 3.0)
            print(
                f"    depth frames {counts['/depth_camera/depth/image_raw']}, clouds "
                f"{counts['/depth_camera/points']}, odometry {counts['/odom']}"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per scenario")
    parser.add_argument("--seconds", type=float, default=4.0, help="sim seconds per run")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    print(f"load average before: {load:.2f} (2 cores; figures are noisy when others run)")
    bench_car(args.seconds, args.repeat)
    bench_quadrotor(args.seconds, args.repeat)


if __name__ == "__main__":
    main()
