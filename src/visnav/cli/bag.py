"""``visnav bag``: record, info, play, convert, reindex (the shape of ``ros2 bag``)."""

from __future__ import annotations

import argparse
import datetime
import json
import signal
import sys
import threading
import time
from collections.abc import Callable
from types import FrameType

from visnav.bag.errors import RecordError
from visnav.bag.storage import COMPRESSIONS, FORMATS

__all__ = ["add_arguments"]

_ALL_COMPRESSIONS = sorted({c for cs in COMPRESSIONS.values() for c in cs})


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``bag`` sub-commands."""
    sub = parser.add_subparsers(dest="cmd", metavar="CMD")
    sub.required = True

    p = sub.add_parser("record", help="record topics into a bag")
    p.add_argument("topics", nargs="*", metavar="TOPIC", help="topics to record")
    p.add_argument("-a", "--all", action="store_true", help="record every topic (also new ones)")
    p.add_argument("-o", "--output", help="output bag (default rosbag2_<date> / <date>.bag)")
    p.add_argument(
        "--format",
        choices=["mcap", "ros1"],
        default=None,
        help="default: ros1 for an output named *.bag, else mcap",
    )
    p.add_argument("--compression", choices=_ALL_COMPRESSIONS, default="none")
    p.add_argument(
        "-b",
        "--buffsize",
        type=float,
        default=256.0,
        metavar="MB",
        help="writer buffer in MiB before messages are dropped and counted (default 256)",
    )
    p.add_argument("-x", "--exclude", help="with -a: regular expression of topics to leave out")
    p.add_argument("--include-hidden-topics", action="store_true", help="with -a: also _hidden")
    p.add_argument("--use-sim-time", action="store_true", help="stamp with /clock time")
    p.add_argument("--duration", type=float, default=None, help="stop after S seconds")
    p.add_argument(
        "--compress-images",
        action="store_true",
        help="store sensor_msgs/Image topics as <topic>/compressed (JPEG) and depth as "
        "<topic>/compressedDepth (PNG), as image_transport publishes them (visnav run "
        "--record-images does this)",
    )
    p.add_argument(
        "--image-transport",
        action="append",
        default=None,
        metavar="NAME=VALUE",
        help="an image_transport plugin parameter for --compress-images, which it implies "
        "(repeat the flag for several): "
        "compressed.jpeg_quality, compressed.png_level, compressedDepth.format (png, rvl), "
        "compressedDepth.png_level, compressedDepth.depth_max, "
        "compressedDepth.depth_quantization",
    )
    p.set_defaults(func=cmd_record)

    p = sub.add_parser("info", help="summarise a bag")
    p.add_argument("bag")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("play", help="republish a bag with its recorded timing")
    p.add_argument("bag")
    p.add_argument(
        "--clock",
        nargs="?",
        type=float,
        const=40.0,
        default=None,
        metavar="HZ",
        help="publish /clock at HZ (default 40)",
    )
    p.add_argument("-r", "--rate", type=float, default=1.0, help="speed factor")
    p.add_argument("-l", "--loop", action="store_true", help="play again at the end")
    p.add_argument("--start-offset", type=float, default=0.0, help="skip S seconds")
    p.add_argument("--topics", nargs="+", default=None, help="play only these topics")
    p.add_argument("--remap", nargs="+", default=None, metavar="FROM:=TO", help="rename topics")
    p.add_argument("--delay", type=float, default=0.0, help="wait S seconds before playing")
    p.add_argument(
        "--decompress",
        action="store_true",
        help="also publish <topic>/compressed and /compressedDepth images decoded on <topic> "
        "(sensor_msgs/Image, for raw subscribers: image_transport republish)",
    )
    p.set_defaults(func=cmd_play)

    p = sub.add_parser("convert", help="write a bag in another format")
    p.add_argument("input")
    p.add_argument("output")
    p.add_argument(
        "--format",
        choices=list(FORMATS),
        default=None,
        help="default: ros1 for an output named *.bag, else mcap",
    )
    p.add_argument("--compression", choices=_ALL_COMPRESSIONS, default="none")
    p.add_argument("--topics", nargs="+", default=None, help="only these topics")
    p.set_defaults(func=cmd_convert)

    p = sub.add_parser("reindex", help="repair a bag whose recording was killed")
    p.add_argument("bag")
    p.set_defaults(func=cmd_reindex)


def _default_output(fmt: str) -> str:
    now = datetime.datetime.now()  # local time, as ros2 bag names bags
    if fmt == "ros1":
        return f"{now:%Y-%m-%d-%H-%M-%S}.bag"
    return f"rosbag2_{now:%Y_%m_%d-%H_%M_%S}"


class _StopFlag:
    """Set by SIGINT/SIGTERM so the recording loop ends and closes the bag.

    A second signal calls ``on_repeat`` (if set): ``bag record`` then drops the writer's
    backlog instead of waiting for a slow compressor.
    """

    def __init__(self) -> None:
        self.event = threading.Event()
        self.on_repeat: Callable[[], None] | None = None
        self._old: dict[int, object] = {}

    def __enter__(self) -> _StopFlag:
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._old[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.event.is_set() and self.on_repeat is not None:
            self.on_repeat()
        self.event.set()

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)  # type: ignore[arg-type]


def cmd_record(args: argparse.Namespace) -> int:
    """``bag record``."""
    from visnav.bag.image_compression import image_transport_from_args
    from visnav.bag.recorder import BagRecorder, compile_exclude
    from visnav.bag.writer import format_for_output
    from visnav.graph.context import Context

    if args.all == bool(args.topics):
        msg = "give the topics to record, or -a for all of them (not both)"
        raise RecordError(msg)
    if args.exclude is not None and not args.all:
        msg = f"-x/--exclude {args.exclude!r} needs -a (it filters the topics -a records)"
        raise RecordError(msg)
    compile_exclude(args.exclude)  # a bad pattern fails before anything is opened
    compress = args.compress_images or bool(args.image_transport)
    transport = image_transport_from_args(args.image_transport) if compress else None
    if not 1.0 <= args.buffsize <= 1 << 20:
        msg = f"--buffsize is {args.buffsize} MiB: expected 1 to 1048576"
        raise RecordError(msg)
    fmt = format_for_output(args.output, args.format) if args.output else args.format or "mcap"
    out = args.output or _default_output(fmt)
    with Context(args.domain) as ctx, _StopFlag() as stop:
        recorder = BagRecorder(
            ctx,
            None if args.all else args.topics,
            out,
            fmt=fmt,
            compression=args.compression,
            exclude=args.exclude,
            include_hidden=args.include_hidden_topics,
            use_sim_time=args.use_sim_time,
            buffer_bytes=round(args.buffsize * (1 << 20)),
            image_transport=transport,
        )
        recorder.start()
        try:
            print(f"Recording to '{recorder.bag_path}' (Ctrl-C to stop)", flush=True)
            end = None if args.duration is None else time.monotonic() + args.duration
            while not stop.event.is_set() and (end is None or time.monotonic() < end):
                ctx.spin_once(0.05)
                if recorder.failed:
                    break
        finally:
            backlog = recorder.pending_bytes
            stop.on_repeat = recorder.abandon
            if backlog > 16 << 20 and not recorder.failed:
                print(
                    f"Writing the {backlog / (1 << 20):.0f} MiB still queued "
                    f"({args.compression} compression; Ctrl-C again drops it)...",
                    flush=True,
                )
            path = recorder.stop()  # raises RecordError after a write failure
    print(
        f"Recorded {recorder.message_count} messages on {len(recorder.topics)} topics to '{path}'",
        flush=True,
    )
    drops = recorder.drops()
    if drops:
        lost = ", ".join(f"{t}: {n}" for t, n in sorted(drops.items()))
        print(
            f"warning: dropped {sum(drops.values())} messages ({lost}); the recorder could not "
            "keep up: record fewer topics, choose lighter compression, or raise --buffsize",
            file=sys.stderr,
            flush=True,
        )
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    """``bag info``."""
    from visnav.bag.info import bag_info, format_info

    info = bag_info(args.bag)
    print(json.dumps(info.to_dict(), indent=2) if args.json else format_info(info))
    return 0


def cmd_play(args: argparse.Namespace) -> int:
    """``bag play``."""
    from visnav.bag.player import BagPlayer
    from visnav.graph.context import Context
    from visnav.graph.introspect import wait_for_discovery

    with Context(args.domain) as ctx, _StopFlag() as stop:
        player = BagPlayer(
            ctx,
            args.bag,
            rate=args.rate,
            clock_hz=args.clock,
            loop=args.loop,
            start_offset_s=args.start_offset,
            topics=args.topics,
            remap=args.remap,
            delay_s=args.delay,
            decompress=args.decompress,
        )
        wait_for_discovery(ctx, timeout_s=1.0)
        print(f"Playing '{player.path}' (Ctrl-C to stop)", flush=True)
        player.start()
        while not player.done:
            if stop.event.wait(0.05):
                player.stop()
        player.wait()
        time.sleep(0.2)  # let the transport deliver the last samples before the session closes
    stats = player.stats
    for topic, reason in stats.skipped_topics.items():
        print(f"warning: not played '{topic}': {reason}", file=sys.stderr)
    for topic, n in stats.undecodable.items():
        print(f"warning: skipped {n} message(s) on '{topic}' that do not decode", file=sys.stderr)
    print(f"Published {stats.message_count} messages on {len(stats.published)} topics", flush=True)
    return 0


def cmd_convert(args: argparse.Namespace) -> int:
    """``bag convert``."""
    from visnav.bag.convert import convert_bag
    from visnav.bag.writer import format_for_output

    fmt = format_for_output(args.output, args.format)
    result = convert_bag(
        args.input, args.output, fmt=fmt, compression=args.compression, topics=args.topics
    )
    for topic, reason in result.skipped.items():
        print(f"warning: not converted '{topic}': {reason}", file=sys.stderr)
    print(
        f"Wrote {result.message_count} messages on {len(result.topics)} topics to '{result.path}'"
    )
    return 0


def cmd_reindex(args: argparse.Namespace) -> int:
    """``bag reindex``."""
    from visnav.bag.convert import reindex_bag

    result = reindex_bag(args.bag)
    if result.recovery:
        print(f"warning: '{result.path}': {result.recovery}", file=sys.stderr)
    print(f"Rewrote '{result.path}': {result.message_count} messages")
    return 0
