"""``visnav run car | drone | FILE``: a scenario launch file end to end, with a summary."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from visnav.outpaths import check_output_dir
from visnav.scenarios.run_control import RunInterrupt
from visnav.scenarios.runner import SCENARIOS, format_summary, run_scenario
from visnav.scenarios.saved_map import MAP_LOCALIZATIONS, saved_map_launch_args

__all__ = ["add_arguments"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``run`` options."""
    parser.add_argument(
        "scenario",
        help=f"one of: {', '.join(SCENARIOS)}, or a scenario launch file (.yaml) "
        "(visnav/scenarios/launch/car.launch.yaml shows what one needs)",
    )
    parser.add_argument("--duration", type=float, default=None, help="simulated seconds")
    parser.add_argument("--seed", type=int, default=0, help="seed of world, sensors and task")
    parser.add_argument("--out", default=None, help="output directory (default runs/<time>)")
    parser.add_argument("--record-all", action="store_true", help="also record images and clouds")
    parser.add_argument(
        "--record-images",
        action="store_true",
        help="also record the camera images (for `visnav view BAG`), not the clouds, through "
        "compressed transport: <image topic>/compressed (JPEG), depth <topic>/compressedDepth",
    )
    parser.add_argument(
        "--raw-images",
        action="store_true",
        help="record the camera images raw (sensor_msgs/Image: the car's bag ~6x bigger, "
        "34 MB per simulated second); implies --record-images",
    )
    parser.add_argument("--realtime", action="store_true", help="pace to the wall clock")
    parser.add_argument("--view", action="store_true", help="stream to the Rerun web viewer")
    parser.add_argument(
        "--no-slam",
        action="store_true",
        help="car: no visual SLAM (map -> odom is then the static spawn pose, or AMCL's)",
    )
    parser.add_argument(
        "--ideal-sensors",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="car: ground-truth odometry and noise-free cameras, SLAM beside the navigation "
        "(the behaviour before SLAM closed the loop); default: wheel-encoder odometry with "
        "slip, camera and depth noise, SLAM publishes map -> odom (docs/slam.md)",
    )
    parser.add_argument(
        "--map",
        default=None,
        metavar="MAP.yaml",
        help="car: localise in this saved map (its map.yaml is the static layer; launch args "
        "use_map, map)",
    )
    parser.add_argument(
        "--map-localization",
        choices=MAP_LOCALIZATIONS,
        default="slam",
        help="car with --map: slam = visual SLAM in localisation mode in the slam_map.npz "
        "beside MAP.yaml (default), amcl = AMCL on the depth scan (docs/navigation.md)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=cmd_run)


def cmd_run(args: argparse.Namespace) -> int:
    """Run the scenario and print the summary table.

    Exit code 1 if failed; after Ctrl-C 130, after SIGTERM 143 (the run is stopped and
    summarised either way).
    """
    with RunInterrupt().installed() as interrupt:  # Ctrl-C, SIGTERM: stop, summarise
        summary = _run(args, interrupt)
    print(format_summary(summary))
    return {"interrupted": interrupt.exit_code, "failed": 1}.get(summary.get("status", ""), 0)


def _run(args: argparse.Namespace, interrupt: RunInterrupt) -> dict[str, Any]:
    if args.out is not None:
        check_output_dir(args.out, what="the run's output directory (--out)")
    from visnav.graph.context import Context

    launch_args = (
        saved_map_launch_args(args.map, args.map_localization, slam=not args.no_slam, check=True)
        if args.map and not args.scenario.startswith("tb3-")
        else {"map": args.map}  # the TurtleBot3 scenarios: map_file of their launch files
        if args.map
        else {}
    )
    context = Context(args.domain) if getattr(args, "domain", None) is not None else None
    return run_scenario(
        args.scenario,
        seed=args.seed,
        duration_s=args.duration,
        out=args.out,
        record_all=args.record_all,
        record_images=args.record_images or args.raw_images,
        raw_images=args.raw_images,
        realtime=args.realtime,
        view=args.view,
        slam=not args.no_slam,
        ideal_sensors=args.ideal_sensors,
        launch_args=launch_args,
        context=context,
        progress=None if args.quiet else sys.stderr,
        interrupt=interrupt,
    )
