"""``visnav calibrate``: chessboard calibration from images, a bag or a live topic."""

from __future__ import annotations

import argparse

from visnav.cli._common import cli_node
from visnav.outpaths import check_output_file
from visnav.perception.calibration import CalibrationError, calibrate

__all__ = ["add_arguments"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``calibrate`` options."""
    src = parser.add_mutually_exclusive_group()
    src.add_argument(
        "--images",
        metavar="DIR",
        help="a directory of chessboard images (images of another size than most views "
        "are skipped, each with a warning)",
    )
    src.add_argument("--bag", metavar="BAG", help="a bag (rosbag2 or ROS 1); needs --topic")
    parser.add_argument("--topic", help="image topic: live without --bag, else in the bag")
    parser.add_argument("--pattern", default="9x6", help="inner corners, COLSxROWS (default 9x6)")
    parser.add_argument("--square", type=float, default=0.025, help="square side in metres")
    parser.add_argument("-o", "--output", help="write a camera_info YAML here")
    parser.add_argument("--camera-name", default=None, help="camera_name in the YAML")
    parser.add_argument("--max-views", type=int, default=40, help="views to collect (topic/bag)")
    parser.add_argument("--timeout", type=float, default=60.0, help="live topic: give up after S s")
    parser.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Run the calibration and print its report (RMS and per-image errors)."""
    if args.output:  # refused before the views are collected, not after
        check_output_file(args.output, what="the camera_info YAML (-o)", error=CalibrationError)
    common = {
        "pattern": args.pattern,
        "square": args.square,
        "output": args.output,
        "camera_name": args.camera_name,
        "max_views": args.max_views,
    }
    if args.images is not None:
        result = calibrate(images=args.images, **common)
    elif args.bag is not None:
        result = calibrate(bag=args.bag, topic=args.topic, **common)
    elif args.topic is not None:
        return _live(args)
    else:
        raise CalibrationError(
            "visnav calibrate needs a source: --images DIR, --bag BAG --topic T, or --topic T"
        )
    print(result.summary())
    if args.output:
        print(f"wrote {args.output}")
    return 0


def _live(args: argparse.Namespace) -> int:
    with cli_node(args) as node:
        result = calibrate(
            topic=args.topic,
            node=node,
            spin_until=node.context.spin_until,
            pattern=args.pattern,
            square=args.square,
            output=args.output,
            camera_name=args.camera_name,
            max_views=args.max_views,
            timeout_s=args.timeout,
        )
    print(result.summary())
    if args.output:
        print(f"wrote {args.output}")
    return 0
