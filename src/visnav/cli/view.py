"""``visnav view``: live topics or a bag in Rerun, placed in a fixed frame through TF (RViz).

Needs the viewer extra (``pip install 'visnav[viz]'``); without it the command says so.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
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
        help="frame everything is shown in (default: map, odom or world, else the TF root)",
    )
    parser.add_argument(
        "--topics", nargs="+", default=None, help="only these topics (plus /tf, /tf_static)"
    )
    parser.add_argument(
        "--display-config",
        "-d",
        default=None,
        metavar="FILE.rviz",
        help="an RViz config: its fixed frame, enabled displays' topics and colours (rviz -d)",
    )
    parser.add_argument(
        "--save", default=None, metavar="FILE.rrd", help="also write a .rrd file (else nothing)"
    )
    parser.add_argument(
        "--web", action="store_true", help="serve the web viewer on 127.0.0.1 (open the URL)"
    )
    parser.add_argument(
        "--port", type=int, default=9090, help="web viewer page port (--web; 0: a free one)"
    )
    parser.add_argument(
        "--grpc-port", type=int, default=9876, help="viewer data port (--web; 0: a free one)"
    )
    parser.add_argument(
        "--memory-limit",
        default="512MB",
        help="what the web viewer's server keeps for late pages, oldest dropped (512MB, 10%%)",
    )
    parser.add_argument(
        "--connect", default=None, metavar="URL", help="stream to a running viewer (rerun+http://…)"
    )
    parser.add_argument(
        "--world",
        default=None,
        help="draw this world (built-in name or file; 'none': no world). Default: live, the "
        "sim node's world; a bag of `visnav run`, its scenario's world",
    )
    parser.add_argument(
        "--max-points",
        type=int,
        default=20_000,
        help="decimate clouds to at most N points (0: keep all)",
    )
    parser.add_argument(
        "--all-frames",
        action="store_true",
        help="every image and cloud, not at the display rate (5 Hz images/clouds, 10 Hz scans)",
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
    head = f"{'topic':<{width}}  {'type':<36} {'logged':>7} {'skipped':>7} {'dropped':>7}"
    lines = [f"{head} {'errors':>7}"]
    for topic, row in sorted(stats.items()):
        type_name = row["type"] if row["supported"] else f"{row['type']} (not shown)"
        skipped = row.get("skipped", 0)
        counts = f"{row['logged']:>7} {skipped:>7} {row['dropped']:>7} {row['errors']:>7}"
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


def _world_loader(args: argparse.Namespace, node: Any) -> Callable[[], Any] | None:
    from visnav.viz.scene import load_sim_world, world_for_bag, world_from_graph

    if args.world == "none":
        return None
    if args.world is not None:
        return lambda: load_sim_world(args.world)
    if args.bag is not None:
        return lambda: world_for_bag(args.bag)
    if node is not None:
        return lambda: world_from_graph(node)
    return None


def cmd_view(args: argparse.Namespace) -> int:
    """``visnav view [BAG]``."""
    from visnav.viz import LiveFeed, RerunSink, VizError, feed_bag, open_viewer
    from visnav.viz.display_sink import DisplaySink
    from visnav.viz.paced_feed import PacedFeed

    if args.max_points < 0:
        text = f"--max-points is {args.max_points}: expected 0 (keep all) or a positive count"
        raise VizError(text)
    if args.bag is not None and not Path(args.bag).exists():
        text = f"bag {args.bag!r} does not exist"
        raise VizError(text)
    viewer = open_viewer(
        save=args.save,
        web=args.web,
        port=args.port,
        grpc_port=args.grpc_port,
        memory_limit=args.memory_limit,
        connect=args.connect,
    )
    rviz = None
    if args.display_config is not None:
        from visnav.viz.rviz_config import load_rviz_config

        rviz = load_rviz_config(args.display_config)
        if rviz.note:
            print(rviz.note, file=sys.stderr)
        if args.topics is None:
            args.topics = rviz.topics
    rates: dict[str, float] | None = {} if args.all_frames else None
    sink: DisplaySink | None = None
    try:
        if viewer.url:
            print(f"web viewer: {viewer.url}", flush=True)
            print(f"viewer log: {viewer.log_path}", file=sys.stderr, flush=True)
        rerun_sink = RerunSink(
            viewer.recording,
            fixed_frame=args.fixed_frame,
            max_points=args.max_points or None,
            rviz=rviz,
        )
        try:
            if args.bag is not None:
                loader = _world_loader(args, None)
                sink = DisplaySink(
                    rerun_sink, rates_hz=rates, world_loader=loader, block=True, max_pending=16
                )
                start = time.perf_counter()
                count = feed_bag(sink, args.bag, topics=args.topics, missing_ok=rviz is not None)
                wall = time.perf_counter() - start
                print(f"logged {count} messages of {args.bag} in {wall:.1f} s", file=sys.stderr)
                if args.web:
                    _serve(args)
            else:
                with cli_node(args, discover=True) as node:
                    # paced: the graph's publishers send only what is shown (not --all-frames)
                    feed_type = LiveFeed if args.all_frames else PacedFeed
                    feed = feed_type(rerun_sink, node.context, topics=args.topics)
                    sink = DisplaySink(
                        rerun_sink, rates_hz=rates, world_loader=_world_loader(args, feed.node)
                    )
                    feed.sink = sink
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
            if sink is not None:
                sink.close()
            else:
                rerun_sink.close()
            stats = sink.stats() if sink is not None else rerun_sink.stats()
            frame = rerun_sink.fixed_frame or "(none chosen: no data)"
            print(f"fixed frame: {frame}", file=sys.stderr)
            print(format_stats(stats), file=sys.stderr)
    finally:
        viewer.close()
    if args.save:
        print(f"wrote {args.save}", file=sys.stderr)
    return 0
