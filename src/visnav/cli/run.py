"""``visnav run car | drone | FILE``: a scenario launch file end to end, with a summary."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from visnav.bag.image_compression import image_transport_from_args
from visnav.outpaths import check_output_dir
from visnav.perception.transport_codecs import ImageTransportError
from visnav.scenarios.run_control import RunInterrupt
from visnav.scenarios.runner import SCENARIOS, format_summary, run_scenario
from visnav.scenarios.saved_map import MAP_LOCALIZATIONS, saved_map_launch_args
from visnav.viz.errors import VizError
from visnav.viz.ports import DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT
from visnav.viz.view_process import ViewPorts

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
    parser.add_argument(
        "--record-all",
        action="store_true",
        help="also record images, clouds and the simulator's /gazebo/model_states, link_states",
    )
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
    parser.add_argument(
        "--image-transport",
        action="append",
        default=None,
        metavar="NAME=VALUE",
        help="an image_transport plugin parameter of the recorded images (repeat the flag "
        "for several): "
        "compressed.jpeg_quality (80), compressed.png_level (9), compressedDepth.format "
        "(png or rvl), compressedDepth.png_level (1), compressedDepth.depth_max (10), "
        "compressedDepth.depth_quantization (100); implies --record-images",
    )
    parser.add_argument("--realtime", action="store_true", help="pace to the wall clock")
    parser.add_argument(
        "--view",
        action="store_true",
        help="stream to the Rerun web viewer (in a process of its own; page on 127.0.0.1)",
    )
    parser.add_argument(
        "--port",
        type=int,
        default=None,
        help="web viewer page port (--view; default 9090, 0: a free one)",
    )
    parser.add_argument(
        "--grpc-port",
        type=int,
        default=None,
        help="viewer data port (--view; default 9876, 0: a free one)",
    )
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


def _view_ports(args: argparse.Namespace) -> ViewPorts | bool:
    """``--view``'s ports, checked before anything starts (a refused run leaves no folder).

    Raises:
        VizError: a port is taken or out of range (naming it and its option), the Rerun
            SDK is missing, or ``--port`` / ``--grpc-port`` came without ``--view``.
    """
    port, grpc_port = getattr(args, "port", None), getattr(args, "grpc_port", None)
    if not args.view:
        if port is not None or grpc_port is not None:
            given = "--port" if port is not None else "--grpc-port"
            text = f"{given} sets the viewer's port: add --view (or leave {given} out)"
            raise VizError(text)
        return False
    ports = ViewPorts(
        port=DEFAULT_WEB_PORT if port is None else port,
        grpc_port=DEFAULT_GRPC_PORT if grpc_port is None else grpc_port,
    )
    ports.check()
    return ports


def _run(args: argparse.Namespace, interrupt: RunInterrupt) -> dict[str, Any]:
    if args.out is not None:
        check_output_dir(args.out, what="the run's output directory (--out)")
    view = _view_ports(args)
    image_transport = image_transport_from_args(args.image_transport)
    if args.raw_images and args.image_transport:
        text = (
            "--image-transport sets how images are compressed, --raw-images stores them raw: "
            "give one of the two"
        )
        raise ImageTransportError(text)
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
        record_images=args.record_images or args.raw_images or bool(args.image_transport),
        raw_images=args.raw_images,
        image_transport=image_transport,
        realtime=args.realtime,
        view=view,
        slam=not args.no_slam,
        ideal_sensors=args.ideal_sensors,
        launch_args=launch_args,
        context=context,
        progress=None if args.quiet else sys.stderr,
        interrupt=interrupt,
    )
