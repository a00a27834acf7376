"""``visnav view``: live topics or a bag in Rerun, placed in a fixed frame through TF (RViz).

Needs the viewer extra (``pip install 'visnav[viz]'``); without it the command says so.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from visnav.cli._common import cli_node

__all__ = ["add_arguments", "cmd_view", "format_stats"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``view`` arguments."""
    parser.add_argument("bag", nargs="?", help="show this bag instead of live topics")
    parser.add_argument(
        "--fixed-frame",
        "-f",
        default=None,
        help="frame everything is shown in (default: the root of the TF tree)",
    )
    parser.add_argument(
        "--topics", nargs="+", default=None, help="only these topics (plus /tf, /tf_static)"
    )
    parser.add_argument("--save", default=None, metavar="FILE.rrd", help="write a .rrd file")
    parser.add_argument(
        "--web", action="store_true", help="serve the web viewer on 127.0.0.1 (open the URL)"
    )
    parser.add_argument("--web-port", type=int, default=None, help="web viewer port")
    parser.add_argument("--grpc-port", type=int, default=None, help="data server port (--web)")
    parser.add_argument(
        "--connect", default=None, metavar="URL", help="stream to a running viewer (rerun+http://…)"
    )
    parser.add_argument(
        "--max-points",
        type=int,
        default=50_000,
        help="decimate clouds to at most N points (0: keep all)",
    )
    parser.add_argument(
        "--duration", type=float, default=None, help="stop after S seconds (live, or serving)"
    )
    parser.set_defaults(func=cmd_view)


def format_stats(stats: dict[str, dict[str, Any]]) -> str:
    """A table of what the sink showed, per topic."""
    if not stats:
        return "no messages"
    width = max(len(t) for t in stats)
    lines = [f"{'topic':<{width}}  {'type':<36} {'logged':>7} {'dropped':>7} {'errors':>7}"]
    for topic, row in sorted(stats.items()):
        type_name = row["type"] if row["supported"] else f"{row['type']} (not shown)"
        counts = f"{row['logged']:>7} {row['dropped']:>7} {row['errors']:>7}"
        lines.append(f"{topic:<{width}}  {type_name:<36} {counts}")
        if row["dropped"] and row["reason"]:
            lines.append(f"{'':<{width}}    last drop: {row['reason'][:160]}")
    return "\n".join(lines)


def _serve(args: argparse.Namespace) -> None:
    """Keep the web viewer up until Ctrl-C (or --duration)."""
    print("serving; press Ctrl-C to stop", file=sys.stderr, flush=True)
    end = None if args.duration is None else time.monotonic() + args.duration
    while end is None or time.monotonic() < end:
        time.sleep(0.2)


def cmd_view(args: argparse.Namespace) -> int:
    """``visnav view [BAG]``."""
    from visnav.viz import LiveFeed, RerunSink, VizError, feed_bag, open_viewer

    if args.max_points < 0:
        text = f"--max-points is {args.max_points}: expected 0 (keep all) or a positive count"
        raise VizError(text)
    if args.bag is not None and not Path(args.bag).exists():
        text = f"bag {args.bag!r} does not exist"
        raise VizError(text)
    viewer = open_viewer(
        save=args.save,
        web=args.web,
        web_port=args.web_port,
        grpc_port=args.grpc_port,
        connect=args.connect,
    )
    try:
        if viewer.url:
            print(f"web viewer: {viewer.url}", flush=True)
        sink = RerunSink(
            viewer.recording,
            fixed_frame=args.fixed_frame,
            max_points=args.max_points or None,
        )
        try:
            if args.bag is not None:
                count = feed_bag(sink, args.bag, topics=args.topics)
                print(f"logged {count} messages of {args.bag}", file=sys.stderr)
                if args.web:
                    _serve(args)
            else:
                with cli_node(args, discover=True) as node:
                    feed = LiveFeed(sink, node.context, topics=args.topics)
                    feed.scan()
                    missing = feed.missing_topics()
                    if missing:
                        print(f"waiting for {', '.join(missing)}", file=sys.stderr, flush=True)
                    try:
                        feed.run(duration_s=args.duration)
                    finally:
                        feed.close()
        except KeyboardInterrupt:
            pass
        finally:
            sink.close()
            frame = sink.fixed_frame or "(none chosen: no data)"
            print(f"fixed frame: {frame}", file=sys.stderr)
            print(format_stats(sink.stats()), file=sys.stderr)
    finally:
        viewer.close()
    if args.save:
        print(f"wrote {args.save}", file=sys.stderr)
    return 0
