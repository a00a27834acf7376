"""``visnav bridge ros1``: join a ROS 1 graph (ros1_bridge's dynamic_bridge, without ROS 2)."""

from __future__ import annotations

import argparse

from visnav.graph import Context

__all__ = ["add_arguments", "cmd_ros1"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``bridge`` sub-commands."""
    sub = parser.add_subparsers(dest="cmd", metavar="CMD")
    sub.required = True
    p = sub.add_parser(
        "ros1",
        help="bridge this graph with a ROS 1 master (ROS_MASTER_URI, ROS_IP/ROS_HOSTNAME)",
        description=(
            "Every visnav topic appears in ROS 1; every ROS 1 topic a visnav node subscribes "
            "to is brought in. Services cross both ways; visnav actions appear as actionlib "
            "servers. See docs/ros1.md."
        ),
    )
    p.add_argument(
        "--topics", nargs="+", default=[], metavar="PAT", help="bridge only these (shell patterns)"
    )
    p.add_argument(
        "--exclude",
        nargs="+",
        default=[],
        metavar="PAT",
        help="never bridge topics, services or actions matching these patterns",
    )
    p.add_argument(
        "--services",
        nargs="+",
        default=[],
        metavar="PAT",
        help="bridge only these services (shell patterns; default: all whose types exist in ROS 1)",
    )
    p.add_argument(
        "--actions",
        nargs="+",
        default=[],
        metavar="PAT",
        help="offer only these visnav actions as ROS 1 actionlib servers (default: all)",
    )
    p.add_argument(
        "--serve-master",
        nargs="?",
        const=11311,
        type=int,
        default=None,
        metavar="PORT",
        help="run a minimal ROS 1 master on 127.0.0.1:PORT (default 11311) instead of roscore",
    )
    p.add_argument("--name", default="visnav_bridge", help="ROS 1 node name (default %(default)s)")
    p.add_argument("--duration", type=float, default=None, help="stop after S seconds")
    p.set_defaults(func=cmd_ros1)


def cmd_ros1(args: argparse.Namespace) -> int:
    """``bridge ros1``."""
    from visnav.bridge.runner import run_bridge

    with Context(args.domain) as ctx:
        run_bridge(
            ctx,
            topics=args.topics,
            exclude=args.exclude,
            services=args.services,
            actions=args.actions,
            serve_master_port=args.serve_master,
            node_name=args.name,
            duration_s=args.duration,
        )
    return 0
