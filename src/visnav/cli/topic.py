"""``visnav topic``: list, info, echo, hz, bw, delay, pub (the shape of ``ros2 topic``)."""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from visnav.cli._common import cli_node
from visnav.graph.introspect import subscription_qos_for, topic_type
from visnav.graph.monitor import BandwidthMeter, DelayMeter, RateMeter
from visnav.graph.qos import DurabilityPolicy, QoSProfile
from visnav.msgs.construct import get_field, message_from_dict, message_to_yaml
from visnav.msgs.errors import MessageError
from visnav.msgs.serde import get_message_class, serialize
from visnav.msgs.time import time_to_ns
from visnav.safe_yaml import load_yaml

__all__ = ["add_arguments"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``topic`` sub-commands."""
    sub = parser.add_subparsers(dest="cmd", metavar="CMD")
    sub.required = True

    p = sub.add_parser("list", help="list topics")
    p.add_argument("-t", "--show-types", action="store_true", help="show message types")
    p.add_argument("-a", "--include-hidden-topics", action="store_true")
    p.set_defaults(func=cmd_list)

    p = sub.add_parser("info", help="type, publishers and subscriptions of a topic")
    p.add_argument("topic")
    p.add_argument("-v", "--verbose", action="store_true", help="list every endpoint with QoS")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("echo", help="print messages of a topic")
    p.add_argument("topic")
    p.add_argument("type", nargs="?", help="message type (default: from the graph)")
    p.add_argument("--once", action="store_true", help="print one message and exit")
    p.add_argument("--field", help="print only this field (dotted path, e.g. header.stamp)")
    p.add_argument("--truncate-length", type=int, default=128, help="cut arrays/strings")
    p.add_argument("--timeout", type=float, default=None, help="give up after S seconds")
    p.set_defaults(func=cmd_echo)

    for name, helptext in (
        ("hz", "print the receive rate"),
        ("bw", "print the bandwidth"),
        ("delay", "print receive time minus header.stamp"),
    ):
        p = sub.add_parser(name, help=helptext)
        p.add_argument("topic")
        p.add_argument("-w", "--window", type=int, default=10000 if name != "bw" else 100)
        p.add_argument("--duration", type=float, default=None, help="stop after S seconds")
        p.set_defaults(func=cmd_measure, measure=name)

    p = sub.add_parser("pub", help="publish a message")
    p.add_argument("topic")
    p.add_argument("type", help="message type, e.g. geometry_msgs/msg/Twist")
    p.add_argument("values", nargs="?", default="{}", help="YAML of the fields")
    p.add_argument("-r", "--rate", type=float, default=1.0, help="publish rate in Hz")
    p.add_argument("-1", "--once", action="store_true", help="publish once and exit")
    p.add_argument("-t", "--times", type=int, default=0, help="publish N times and exit")
    p.add_argument("--qos-durability", choices=["volatile", "transient_local"], default="volatile")
    p.add_argument(
        "-w",
        "--wait-matching-subscriptions",
        type=int,
        default=None,
        help="wait for N subscriptions before publishing (default 1 with --once)",
    )
    p.set_defaults(func=cmd_pub)


def cmd_list(args: argparse.Namespace) -> int:
    """``topic list``."""
    with cli_node(args) as node:
        for topic, types in node.get_topic_names_and_types():
            if not args.include_hidden_topics and any(
                part.startswith("_") for part in topic.split("/")
            ):
                continue
            print(f"{topic} [{', '.join(types)}]" if args.show_types else topic)
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    """``topic info``."""
    with cli_node(args) as node:
        ctx = node.context
        type_name = topic_type(ctx, args.topic)
        eps = [e for e in ctx.graph.endpoints(args.topic) if not e.node_name.startswith("_")]
        pubs = [e for e in eps if e.kind == "publisher"]
        subs = [e for e in eps if e.kind == "subscription"]
        print(f"Type: {type_name}")
        print(f"Publisher count: {len(pubs)}")
        print(f"Subscription count: {len(subs)}")
        if args.verbose:
            for e in pubs + subs:
                print()
                print(f"Node name: {e.node_name}")
                print(f"Node namespace: {e.node_namespace}")
                print(f"Topic type: {e.type_name}")
                print(f"Endpoint type: {e.kind.upper()}")
                print("QoS profile:")
                print(f"  Reliability: {e.reliability.upper()}")
                print(f"  Durability: {e.durability.upper()}")
                print(f"  Depth: {e.depth}")
    return 0


def _resolve_type(node: Any, topic: str, type_arg: str | None) -> type[Any]:
    if type_arg:
        return get_message_class(type_arg)
    return get_message_class(topic_type(node.context, topic))


def cmd_echo(args: argparse.Namespace) -> int:
    """``topic echo``."""
    with cli_node(args) as node:
        cls = _resolve_type(node, args.topic, args.type)
        qos = subscription_qos_for(node.context, args.topic)
        done: list[bool] = [False]

        def on_msg(msg: Any) -> None:
            if args.field:
                value = get_field(msg, args.field)
                if hasattr(value, "__msgtype__"):
                    text = message_to_yaml(value, truncate_length=args.truncate_length)
                else:
                    text = str(value)
            else:
                text = message_to_yaml(msg, truncate_length=args.truncate_length)
            print(text)
            print("---", flush=True)
            if args.once:
                done[0] = True

        node.create_subscription(cls, args.topic, on_msg, qos)
        end = None if args.timeout is None else time.monotonic() + args.timeout
        while not done[0]:
            if end is not None and time.monotonic() >= end:
                print(
                    f"error: no message on '{args.topic}' within {args.timeout} s", file=sys.stderr
                )
                return 1
            node.context.spin_once(0.1)
    return 0


def cmd_measure(args: argparse.Namespace) -> int:
    """``topic hz | bw | delay``: print statistics every second."""
    with cli_node(args) as node:
        cls = get_message_class(topic_type(node.context, args.topic))
        qos = subscription_qos_for(node.context, args.topic)
        clock = node.get_clock()
        rate, bw, delay = (
            RateMeter(args.window),
            BandwidthMeter(args.window),
            DelayMeter(args.window),
        )

        def on_msg(msg: Any) -> None:
            now = time.time_ns()
            if args.measure == "hz":
                rate.add(time.monotonic_ns())
            elif args.measure == "bw":
                bw.add(time.monotonic_ns(), len(serialize(msg)))
            else:
                header = getattr(msg, "header", None)
                if header is None:
                    text = (
                        f"topic '{args.topic}' ({msg.__msgtype__}) has no header to measure delay"
                    )
                    raise MessageError(text)
                delay.add(
                    clock.now_ns() if clock.ros_time_is_active else now, time_to_ns(header.stamp)
                )

        node.create_subscription(cls, args.topic, on_msg, qos)
        start = time.monotonic()
        next_print = start + 1.0
        while args.duration is None or time.monotonic() - start < args.duration:
            node.context.spin_once(0.05)
            if time.monotonic() >= next_print:
                next_print += 1.0
                meter: Any = {"hz": rate, "bw": bw, "delay": delay}[args.measure]
                stats = meter.stats()
                print(stats.format() if stats else "no new messages", flush=True)
    return 0


def cmd_pub(args: argparse.Namespace) -> int:
    """``topic pub``."""
    values = (
        load_yaml(
            args.values,
            source=f"values {args.values!r}",
            what='the text (write e.g. "{linear: {x: 0.5}}")',
            error=MessageError,
        )
        or {}
    )
    if not isinstance(values, dict):
        text = f"values {args.values!r}: expected a YAML mapping of fields"
        raise MessageError(text)
    cls = get_message_class(args.type)
    msg = message_from_dict(cls.__msgtype__, values)
    times = 1 if args.once else args.times
    wait_n = args.wait_matching_subscriptions
    if wait_n is None:
        wait_n = 1 if times else 0
    with cli_node(args, discover=False) as node:
        qos = QoSProfile(depth=10, durability=DurabilityPolicy(args.qos_durability))
        pub = node.create_publisher(cls, args.topic, qos)
        deadline = time.monotonic() + 5.0
        while wait_n and pub.get_subscription_count() < wait_n and time.monotonic() < deadline:
            node.context.spin_once(0.05)
        period = 1.0 / args.rate if args.rate > 0 else 1.0
        count = 0
        next_t = time.monotonic()
        while True:
            print(f"publishing #{count + 1}: {msg.__msgtype__}", flush=True)
            pub.publish(msg)
            count += 1
            if times and count >= times:
                time.sleep(0.2)  # let the transport flush before the session closes
                return 0
            next_t += period
            while time.monotonic() < next_t:
                node.context.spin_once(max(0.0, next_t - time.monotonic()))
