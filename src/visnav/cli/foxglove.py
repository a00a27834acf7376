"""``visnav foxglove``: serve the live graph to Foxglove / Lichtblick (foxglove_bridge)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from visnav.graph import Context

if TYPE_CHECKING:
    from visnav.bridge.foxglove.server import FoxgloveServer

__all__ = ["add_arguments", "cmd_foxglove"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``foxglove`` options."""
    parser.description = (
        "Serve every topic of the graph over the Foxglove WebSocket protocol "
        "(foxglove.websocket.v1 and foxglove.sdk.v1). In Foxglove or Lichtblick: Open "
        "connection > Foxglove WebSocket > ws://localhost:8765. Clients may publish (Publish "
        "pose to /move_base_simple/goal), read and set parameters and call services. "
        "See docs/foxglove.md."
    )
    parser.add_argument("--port", type=int, default=8765, help="TCP port (default %(default)s)")
    parser.add_argument(
        "--address",
        default="127.0.0.1",
        help="address to bind (default %(default)s: this machine only; 0.0.0.0: every interface)",
    )
    parser.add_argument(
        "--topics",
        nargs="+",
        default=[".*"],
        metavar="REGEX",
        help="advertise only topics matching these regular expressions (topic_whitelist)",
    )
    parser.add_argument(
        "--services",
        nargs="+",
        default=[".*"],
        metavar="REGEX",
        help="advertise only services matching these (service_whitelist)",
    )
    parser.add_argument(
        "--send-buffer-limit",
        type=int,
        default=10_000_000,
        metavar="BYTES",
        help="bytes queued per client before messages are dropped (default %(default)s)",
    )
    parser.add_argument(
        "--capabilities",
        nargs="*",
        default=None,
        metavar="CAP",
        help=(
            "offer only these: clientPublish parameters parametersSubscribe services "
            "connectionGraph assets time (default: all)"
        ),
    )
    parser.add_argument(
        "--asset-uri-allowlist",
        nargs="+",
        default=None,
        metavar="REGEX",
        help=(
            "asset URIs clients may fetch (asset_uri_allowlist; default foxglove_bridge's: "
            "meshes, textures and URDFs under package://)"
        ),
    )
    parser.add_argument(
        "--package",
        action="append",
        default=[],
        metavar="NAME=DIR",
        help="a package for package:// assets besides ROS_PACKAGE_PATH (repeatable)",
    )
    time = parser.add_mutually_exclusive_group()
    time.add_argument(
        "--sim-time", dest="sim_time", action="store_true", default=None, help="use /clock time"
    )
    time.add_argument(
        "--wall-time", dest="sim_time", action="store_false", help="use the wall clock"
    )
    parser.add_argument(
        "--include-hidden", action="store_true", help="also advertise hidden topics (_name)"
    )
    parser.add_argument("--duration", type=float, default=None, help="stop after S seconds")
    parser.set_defaults(func=cmd_foxglove)


def cmd_foxglove(args: argparse.Namespace) -> int:
    """``foxglove``: serve until Ctrl-C (or ``--duration``)."""
    from visnav.bridge.foxglove.assets import DEFAULT_ASSET_URI_ALLOWLIST
    from visnav.bridge.foxglove.node import run_foxglove
    from visnav.bridge.foxglove.protocol import CAPABILITIES
    from visnav.bridge.foxglove.server import FoxgloveOptions
    from visnav.graph.introspect import wait_for_discovery

    options = FoxgloveOptions(
        address=args.address,
        port=args.port,
        topic_whitelist=tuple(args.topics),
        service_whitelist=tuple(args.services),
        send_buffer_limit=args.send_buffer_limit,
        capabilities=CAPABILITIES if args.capabilities is None else tuple(args.capabilities),
        include_hidden=args.include_hidden,
        asset_uri_allowlist=(
            DEFAULT_ASSET_URI_ALLOWLIST
            if args.asset_uri_allowlist is None
            else tuple(args.asset_uri_allowlist)
        ),
        packages=_packages(args.package),
    )
    with Context(args.domain) as ctx:
        if args.sim_time is None:
            wait_for_discovery(ctx, timeout_s=1.0)
        run_foxglove(
            ctx,
            options,
            use_sim_time=args.sim_time,
            duration_s=args.duration,
            on_ready=_announce,
        )
    return 0


def _packages(items: list[str]) -> dict[str, str]:
    from visnav.bridge.foxglove.errors import FoxgloveError

    out = {}
    for item in items:
        name, sep, folder = item.partition("=")
        if not sep or not name or not folder:
            msg = f"--package {item!r}: expected NAME=DIR, e.g. turtlebot3_description=./tb3"
            raise FoxgloveError(msg)
        out[name] = folder
    return out


def _announce(server: FoxgloveServer) -> None:
    sim = "sim time from /clock" if server.sim_time else "wall clock"
    print(
        f"Foxglove WebSocket server at {server.url} ({sim}); connect Foxglove or Lichtblick "
        "to it (Open connection > Foxglove WebSocket). Ctrl-C stops.",
        flush=True,
    )
