"""``visnav plot /TOPIC/FIELD...``: live scalar plots of message fields (rqt_plot) in the viewer.

Fields are spelled as rqt_plot spells them (``/odom/twist/twist/linear/x``,
``/imu/linear_acceleration/x:y:z``, ``/scan/ranges[0]``); see :mod:`visnav.viz.plot`.
Needs the viewer extra (``pip install 'visnav[viz]'``).
"""

from __future__ import annotations

import argparse
import sys

from visnav.cli._common import cli_node

__all__ = ["add_arguments", "cmd_plot"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``plot`` arguments."""
    parser.add_argument(
        "fields", nargs="+", metavar="/TOPIC/FIELD", help="e.g. /odom/twist/twist/linear/x"
    )
    parser.add_argument(
        "--web", action="store_true", help="serve the web viewer on 127.0.0.1 (open the URL)"
    )
    parser.add_argument("--port", type=int, default=9090, help="web viewer page port (--web)")
    parser.add_argument("--grpc-port", type=int, default=9876, help="viewer data port (--web)")
    parser.add_argument("--save", default=None, metavar="FILE.rrd", help="also write a .rrd file")
    parser.add_argument(
        "--connect", default=None, metavar="URL", help="stream to a running viewer (rerun+http://…)"
    )
    parser.add_argument(
        "--wait", type=float, default=5.0, help="seconds to wait for the topics to appear"
    )
    parser.add_argument("--duration", type=float, default=None, help="stop after S seconds")
    parser.set_defaults(func=cmd_plot)


def cmd_plot(args: argparse.Namespace) -> int:
    """``visnav plot FIELD...``."""
    import time

    from visnav.viz import open_viewer
    from visnav.viz.plot import PlotFeed

    with (
        open_viewer(
            save=args.save,
            web=args.web,
            port=args.port,
            grpc_port=args.grpc_port,
            connect=args.connect,
            application_id="visnav_plot",
        ) as viewer,
        cli_node(args, discover=True) as node,
    ):
        if viewer.url:
            print(f"web viewer: {viewer.url}", flush=True)
        feed = PlotFeed(viewer.recording, node, args.fields)
        fields = feed.resolve(wait_s=args.wait)
        print("plotting " + ", ".join(f.name for f in fields), file=sys.stderr, flush=True)
        end = None if args.duration is None else time.monotonic() + args.duration
        try:
            while end is None or time.monotonic() < end:
                node.context.spin_once(0.05)
        except KeyboardInterrupt:
            pass
        finally:
            feed.close()
        for field in fields:
            print(f"{field.name}: {feed.counts.get(field.name, 0)} values", file=sys.stderr)
    if args.save:
        print(f"wrote {args.save}", file=sys.stderr)
    return 0
