"""``visnav image view TOPIC``: one image topic (rqt_image_view), usable with no display.

``--snapshot out.png`` waits for one image (raw, or the ``compressed`` /
``compressedDepth`` transport when the topic ends so), writes it as a PNG (depth
scaled to a visible range) and exits: no display and no viewer extra needed.
Without ``--snapshot`` the stream is shown in Rerun (``--web`` for a browser).
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from visnav.cli._common import cli_node
from visnav.errors import VisnavError
from visnav.graph.introspect import subscription_qos_for
from visnav.msgs.time import ns_to_sec, time_to_ns
from visnav.msgs.types import CompressedImage, Image

__all__ = ["add_arguments", "cmd_view", "image_type_for"]


class ImageViewError(VisnavError, ValueError):
    """``visnav image view`` cannot get or show an image."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``image`` sub-commands."""
    sub = parser.add_subparsers(dest="cmd", metavar="CMD")
    sub.required = True
    p = sub.add_parser(
        "view",
        help="show an image topic (rqt_image_view); --snapshot writes one PNG",
        description=(
            "Show one image topic. The transport follows the topic name: "
            "camera/image_raw (raw), camera/image_raw/compressed, .../compressedDepth."
        ),
    )
    p.add_argument("topic")
    p.add_argument("--snapshot", metavar="OUT.png", help="write one image as PNG and exit")
    p.add_argument(
        "--timeout", type=float, default=10.0, help="give up after S seconds without an image"
    )
    p.add_argument(
        "--range",
        nargs=2,
        type=float,
        metavar=("MIN", "MAX"),
        default=None,
        help="values shown black..white for depth (m) and one-channel images (default: min..max)",
    )
    p.add_argument(
        "--colormap",
        default="gray",
        help="colour map of depth / one-channel images: gray, turbo, jet, viridis, inferno, bone",
    )
    p.add_argument("--web", action="store_true", help="(without --snapshot) browser viewer")
    p.add_argument("--save", default=None, metavar="FILE.rrd", help="(without --snapshot) .rrd")
    p.add_argument(
        "--duration", type=float, default=None, help="(without --snapshot) stop after S seconds"
    )
    p.set_defaults(func=cmd_view)


def image_type_for(topic: str, graph_types: dict[str, list[str]]) -> type[Any]:
    """The message class of an image topic: from the graph, else from the transport name."""
    types = graph_types.get(topic)
    if types:
        if types[0] == "sensor_msgs/msg/CompressedImage":
            return CompressedImage
        if types[0] == "sensor_msgs/msg/Image":
            return Image
        text = (
            f"topic {topic!r} carries {types[0]}: expected sensor_msgs/msg/Image or CompressedImage"
        )
        raise ImageViewError(text)
    from visnav.perception.image_transport import split_transport_topic

    _, transport = split_transport_topic(topic)
    return Image if transport == "raw" else CompressedImage


def cmd_view(args: argparse.Namespace) -> int:
    """``image view``."""
    if args.snapshot is None:
        return _stream(args)
    from visnav.outpaths import check_output_file
    from visnav.viz.display import message_to_display, write_png

    check_output_file(args.snapshot, what="the snapshot (--snapshot)")  # before waiting

    value_range = tuple(args.range) if args.range else None
    with cli_node(args) as node:
        ctx = node.context
        cls = image_type_for(args.topic, dict(ctx.graph.topic_names_and_types()))
        got: list[Any] = []
        node.create_subscription(cls, args.topic, got.append, subscription_qos_for(ctx, args.topic))
        deadline = time.monotonic() + args.timeout
        while not got:
            if time.monotonic() >= deadline:
                pubs = len(node.get_publishers_info_by_topic(args.topic))
                text = (
                    f"no image on {args.topic!r} within {args.timeout} s ({pubs} publisher(s) "
                    "in the graph); check the name with 'visnav topic list' or raise --timeout"
                )
                raise ImageViewError(text)
            ctx.spin_once(0.05)
        msg = got[0]
    rgb = message_to_display(msg, value_range=value_range, colormap=args.colormap)
    out = write_png(args.snapshot, rgb)
    kind = msg.encoding if cls is Image else msg.format
    stamp = ns_to_sec(time_to_ns(msg.header.stamp))
    print(
        f"wrote {out} ({rgb.shape[1]}x{rgb.shape[0]}, {kind}, frame "
        f"'{msg.header.frame_id}', stamp {stamp:.3f})"
    )
    return 0


def _stream(args: argparse.Namespace) -> int:
    """Show the topic in Rerun until Ctrl-C."""
    from visnav.viz import LiveFeed, RerunSink, open_viewer

    with open_viewer(save=args.save, web=args.web) as viewer:
        if viewer.url:
            print(f"web viewer: {viewer.url}", flush=True)
        sink = RerunSink(viewer.recording)
        with cli_node(args) as node:
            feed = LiveFeed(sink, node.context, topics=[args.topic])
            try:
                feed.run(duration_s=args.duration)
            except KeyboardInterrupt:
                pass
            finally:
                feed.close()
                sink.close()
                print(f"{sink.counts.get(args.topic, 0)} images", file=sys.stderr)
    return 0
