"""TurtleBot3 in turtlebot3_world: the simulator's real-time factor with ROBOTIS' own descriptions.

Run: ``python bench/bench_turtlebot3.py [--repeat N] [--seconds S]``. Headless, software OpenGL.
The robots and the world are the test fixtures in ``tests/data/turtlebot3`` (ROBOTIS' noetic
packages as written), the world's models found through ``GAZEBO_MODEL_PATH`` as Gazebo finds them.

* burger (LDS-01 360 beams @ 5 Hz, IMU, diff drive @ 30 Hz), physics only (no subscriber: the
  laser is not cast, as gazebo_ros_laser without a connection) and with ``/scan`` subscribed:
  the laser's share of the step budget (goal <= 5 %) and the real-time factor (goal >= 5x);
* waffle_pi (LDS + R200-style camera 640x480 @ 30 Hz + IMU), alone and with ``/scan`` and the
  camera subscribed.

Each configuration is timed ``--repeat`` times, alternating, driving a slow circle; the figure is
the median real-time factor, the reference the same robot with nothing subscribed in the same run.
"""

from __future__ import annotations

import argparse
import os
import statistics
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")

from visnav.graph import Context, Node
from visnav.msgs import Image, Imu, LaserScan, Twist
from visnav.msgs.construct import message_from_dict
from visnav.sim.simulator import RobotSpawn, Simulator

DATA = Path(__file__).resolve().parent.parent / "tests" / "data" / "turtlebot3"
DESCRIPTION = DATA / "turtlebot3_description"
GAZEBO = DATA / "turtlebot3_gazebo"
WORLD = GAZEBO / "worlds" / "turtlebot3_world.world"


def _counter(counts: dict[str, int], topic: str) -> Callable[[Any], None]:
    def count(_: Any) -> None:
        counts[topic] += 1

    return count


def run(model: str, topics: dict[str, type[Any]], seconds: float) -> tuple[float, dict[str, int]]:
    """One run: real-time factor over ``seconds`` after a 0.5 s warm-up, and message counts."""
    with Context(transport="local") as ctx:
        counts = dict.fromkeys(topics, 0)
        node = Node("bench_tb3", context=ctx)
        for topic, msg_type in topics.items():
            node.create_subscription(msg_type, topic, _counter(counts, topic), 10)
        cmd = node.create_publisher(Twist, "/cmd_vel", 1)
        spawn = RobotSpawn(
            source=DESCRIPTION / "urdf" / f"turtlebot3_{model}.urdf.xacro",
            packages={"turtlebot3_description": DESCRIPTION},
            spawn=(-2.0, -0.5, 0.0, 0.0),
        )
        with Simulator(WORLD, [spawn], context=ctx) as sim:
            cmd.publish(
                message_from_dict(
                    "geometry_msgs/msg/Twist", {"linear": {"x": 0.1}, "angular": {"z": 0.3}}
                )
            )
            sim.run(0.5)
            stats = sim.run(seconds)
        return stats.real_time_factor, counts


def bench(
    model: str, configs: dict[str, dict[str, type[Any]]], seconds: float, repeat: int
) -> None:
    rtfs: dict[str, list[float]] = {name: [] for name in configs}
    counts: dict[str, dict[str, int]] = {}
    for _ in range(repeat):
        for name, topics in configs.items():
            rtf, counts[name] = run(model, topics, seconds)
            rtfs[name].append(rtf)
    reference = statistics.median(rtfs["nothing subscribed"])
    for name, values in rtfs.items():
        median = statistics.median(values)
        budget = 100.0 * (reference / median - 1.0)
        each = ", ".join(f"{v:.2f}" for v in values)
        print(
            f"{model}, {name}: real-time factor {median:.2f} (runs {each}); "
            f"ratio to nothing subscribed {median / reference:.3f} "
            f"(+{budget:.1f} % of the step budget); messages {counts[name]}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per configuration")
    parser.add_argument("--seconds", type=float, default=10.0, help="sim seconds per run")
    args = parser.parse_args()
    os.environ["GAZEBO_MODEL_PATH"] = str(GAZEBO / "models")
    print(f"load average before: {os.getloadavg()[0]:.2f} (2 cores; noisy when others run)")
    bench(
        "burger",
        {"nothing subscribed": {}, "/scan subscribed": {"/scan": LaserScan}},
        args.seconds,
        args.repeat,
    )
    bench(
        "waffle_pi",
        {
            "nothing subscribed": {},
            "/scan + camera + imu subscribed": {
                "/scan": LaserScan,
                "/camera/rgb/image_raw": Image,
                "/imu": Imu,
            },
        },
        args.seconds,
        args.repeat,
    )


if __name__ == "__main__":
    main()
