"""``visnav sim``: run a world with a robot and publish its sensors on the graph.

``visnav sim --world office|forest|FILE --robot car|quadrotor|FILE [--spawn x y z yaw]
[--arg name:=value ...] [--package NAME=DIR ...] [--world-param name:=value ...] [--realtime]
[--duration S] [--seed N]`` wraps :func:`run_sim`. It prints the real-time factor at the end (also
after Ctrl-C).
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from visnav.errors import VisnavError
from visnav.safe_yaml import load_yaml

if TYPE_CHECKING:
    from visnav.graph.context import Context
    from visnav.sim.simulator import SimStats

__all__ = [
    "SimArgumentError",
    "add_arguments",
    "cmd_sim",
    "parse_assignments",
    "parse_packages",
    "run_sim",
]

_LOG = logging.getLogger("visnav.sim")


class SimArgumentError(VisnavError, ValueError):
    """A malformed ``name:=value`` argument or spawn pose."""


def parse_assignments(items: Sequence[str], *, what: str) -> dict[str, str]:
    """Parse ``name:=value`` strings (as ``xacro`` and ``ros2 launch`` take them).

    Raises:
        SimArgumentError: an item without ``:=`` or with an empty name.
    """
    out: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition(":=")
        if not sep or not name.strip():
            msg = f"{what} {item!r} is not name:=value. Fix: write e.g. camera_rate:=15"
            raise SimArgumentError(msg)
        out[name.strip()] = value
    return out


def parse_packages(items: Sequence[str]) -> dict[str, str]:
    """Parse ``--package NAME=DIR`` options (as ``visnav launch`` takes them).

    Raises:
        SimArgumentError: an item that is not ``NAME=DIR``, or a DIR that is not a directory.
    """
    out: dict[str, str] = {}
    for item in items:
        name, sep, path = item.partition("=")
        name, path = name.strip(), path.strip()
        if not sep or not name or not path:
            msg = (
                f"--package {item!r}: expected NAME=DIR "
                "(e.g. --package turtlebot3_description=~/ws/src/turtlebot3/turtlebot3_description)"
            )
            raise SimArgumentError(msg)
        directory = Path(path).expanduser()
        if not directory.is_dir():
            msg = (
                f"--package {item!r}: {str(directory)!r} is not a directory. Fix: give the "
                f"directory that holds package {name!r} (its package.xml)"
            )
            raise SimArgumentError(msg)
        out[name] = str(directory)
    return out


def _world_params(items: Mapping[str, str]) -> dict[str, Any]:
    params: dict[str, Any] = {}
    for name, text in items.items():
        source = f"--world-param {name}:={text!r}"
        params[name] = load_yaml(text, source=source, what="the value", error=SimArgumentError)
    return params


def run_sim(
    world: str,
    robot: str,
    *,
    context: Context,
    spawn: Sequence[float] | None = None,
    robot_args: Mapping[str, str] | None = None,
    packages: Mapping[str, str] | None = None,
    world_params: Mapping[str, Any] | None = None,
    realtime: bool = False,
    duration_s: float | None = None,
    seed: int | None = None,
    progress_every_s: float | None = None,
    skip_missing_models: bool = False,
) -> SimStats:
    """Load a world and a robot, simulate, and return the timing.

    Args:
        world: ``office``, ``forest`` or a world file (YAML / SDF).
        robot: ``car``, ``quadrotor`` or a URDF / Xacro file.
        context: the graph context the simulator's nodes join.
        spawn: ``(x, y, z, yaw)``; default the world's spawn point.
        robot_args: Xacro arguments of the robot.
        packages: package name -> directory, for the robot's ``package://`` meshes and
            ``$(find pkg)``, and the world's ``model://`` models these packages export
            (default: ROS_PACKAGE_PATH / AMENT_PREFIX_PATH and the directories around the
            robot file).
        world_params: parameters of a built-in world generator (``forest``).
        realtime: pace to the wall clock.
        duration_s: sim seconds to run; None runs until Ctrl-C or shutdown.
        seed: seeds sensor noise and re-rolls the world's generator and textures
            (None: the world keeps its own seed, sensors use 0).
        progress_every_s: log the real-time factor so far every this many wall
            seconds (logger ``visnav.sim``); None: never.
        skip_missing_models: load an SDF world without the models that are not
            found (one warning) instead of failing.

    Returns:
        The run's timing (sim time, wall time, real-time factor, rendering share);
        after Ctrl-C, the timing so far.

    Raises:
        VisnavError: an unknown world or robot (with the closest name), a malformed
            file, a bad spawn pose, no headless OpenGL.
    """
    from visnav.description.world import load_world
    from visnav.sim.simulator import RobotSpawn, SimStats, Simulator

    pose: tuple[float, float, float, float] | None = None
    if spawn is not None:
        if len(spawn) != 4:
            msg = f"--spawn takes x y z yaw, got {len(spawn)} numbers: {list(spawn)}"
            raise SimArgumentError(msg)
        pose = (float(spawn[0]), float(spawn[1]), float(spawn[2]), float(spawn[3]))
    loaded = load_world(
        world,
        params=world_params or None,
        seed=seed,
        packages=packages,
        skip_missing_models=skip_missing_models,
    )
    robots = [
        RobotSpawn(
            source=robot, args=dict(robot_args or {}), packages=dict(packages or {}), spawn=pose
        )
    ]
    sim_seed = 0 if seed is None else seed
    with Simulator(loaded, robots, context=context, seed=sim_seed, realtime=realtime) as sim:
        before = sim.stats

        def so_far() -> SimStats:
            after = sim.stats
            return SimStats(
                sim_time_s=after.sim_time_s - before.sim_time_s,
                wall_time_s=after.wall_time_s - before.wall_time_s,
                steps=after.steps - before.steps,
                render_time_s=after.render_time_s - before.render_time_s,
                frames=after.frames - before.frames,
            )

        until = None
        if progress_every_s is not None and progress_every_s > 0:
            start = time.monotonic()
            next_report = [start + progress_every_s]

            def report() -> bool:
                now = time.monotonic()
                if now >= next_report[0]:
                    next_report[0] = now + progress_every_s
                    progress = sim.stats.sim_time_s - before.sim_time_s
                    rtf = progress / (now - start)
                    _LOG.info("sim time %.1f s, real-time factor %.2f so far", progress, rtf)
                return False

            until = report
        with contextlib.suppress(KeyboardInterrupt):  # Ctrl-C ends the run, not the report
            sim.run(duration_s, until=until)
        return so_far()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``sim`` options."""
    parser.add_argument("--world", required=True, help="office, forest, or a .yaml/.sdf file")
    parser.add_argument("--robot", required=True, help="car, quadrotor, or a .urdf/.xacro file")
    parser.add_argument(
        "--spawn",
        nargs=4,
        type=float,
        metavar=("X", "Y", "Z", "YAW"),
        help="spawn pose (m, rad); default the world's spawn point, resting on the ground",
    )
    parser.add_argument(
        "--arg",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help="Xacro argument of the robot (repeatable)",
    )
    parser.add_argument(
        "--package",
        action="append",
        default=[],
        metavar="NAME=DIR",
        help="directory of a ROS package, for package://, $(find NAME) and the model:// "
        "models it exports (repeatable)",
    )
    parser.add_argument(
        "--world-param",
        action="append",
        default=[],
        metavar="NAME:=VALUE",
        help="parameter of a built-in world, e.g. obstacles:=150 (repeatable)",
    )
    parser.add_argument(
        "--skip-missing-models",
        action="store_true",
        help="load an SDF world without the model:// models that are not found",
    )
    parser.add_argument("--realtime", action="store_true", help="pace to the wall clock")
    parser.add_argument("--duration", type=float, default=None, help="sim seconds to run")
    parser.add_argument(
        "--seed",
        type=int,
        default=None,
        help="seed of sensor noise, world layout and textures (default: the world's own)",
    )
    parser.set_defaults(func=cmd_sim)


def cmd_sim(args: argparse.Namespace) -> int:
    """``visnav sim``."""
    from visnav.graph.context import Context
    from visnav.sim.guards import refuse_second_simulation

    # PyOpenGL logs "No OpenGL_accelerate module loaded" at INFO level on import.
    logging.getLogger("OpenGL.acceleratesupport").setLevel(logging.WARNING)
    robot_args = parse_assignments(args.arg, what="--arg")
    packages = parse_packages(args.package)
    world_params = _world_params(parse_assignments(args.world_param, what="--world-param"))
    with Context(getattr(args, "domain", None)) as ctx:
        refuse_second_simulation(ctx, command="visnav sim")
        stats = run_sim(
            args.world,
            args.robot,
            context=ctx,
            spawn=args.spawn,
            robot_args=robot_args,
            packages=packages,
            world_params=world_params,
            realtime=args.realtime,
            duration_s=args.duration,
            seed=args.seed,
            progress_every_s=10.0,
            skip_missing_models=args.skip_missing_models,
        )
    print(stats.summary())
    return 0
