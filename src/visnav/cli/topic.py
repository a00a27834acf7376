"""``visnav topic``: list, info, echo, hz, bw, delay, pub (the shape of ``ros2 topic``)."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from typing import Any

from visnav.cli._common import cli_node
from visnav.errors import VisnavError
from visnav.graph.introspect import subscription_qos_for, topic_type
from visnav.graph.monitor import BandwidthMeter, DelayMeter, RateMeter
from visnav.graph.node import Node, Publisher
from visnav.graph.parameters import Parameter
from visnav.graph.qos import DurabilityPolicy, QoSProfile
from visnav.msgs.construct import get_field, message_from_dict, message_to_yaml
from visnav.msgs.errors import MessageError
from visnav.msgs.serde import get_message_class, serialize
from visnav.msgs.time import time_to_ns
from visnav.safe_yaml import load_yaml

__all__ = [
    "KEEP_ALIVE_S",
    "SubscriptionWaitTimeoutError",
    "TopicPubArgumentError",
    "add_arguments",
    "matching_subscription_count",
    "wait_for_matching_subscriptions",
]

KEEP_ALIVE_S = 0.2
"""Default of ``topic pub --keep-alive`` (ros2's is 0.1 s)."""


class TopicPubArgumentError(VisnavError, ValueError):
    """``topic pub`` was given options that do not go together."""


class SubscriptionWaitTimeoutError(VisnavError, TimeoutError):
    """``topic pub --max-wait-time-secs`` passed before the subscriptions appeared."""


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
    p.add_argument(
        "--offset",
        action="store_true",
        help="print every time in the message (header.stamp, ...) as seconds from now: "
        "sim time when a node publishes /clock (rostopic echo --offset)",
    )
    p.add_argument("--wall", action="store_true", help="with --offset: from the wall clock")
    p.set_defaults(func=cmd_echo)

    for name, helptext in (
        ("hz", "print the receive rate (in sim time when the graph has a /clock)"),
        ("bw", "print the bandwidth"),
        ("delay", "print receive time minus header.stamp (sim time when on /clock)"),
    ):
        p = sub.add_parser(name, help=helptext)
        p.add_argument("topic")
        p.add_argument("-w", "--window", type=int, default=10000 if name != "bw" else 100)
        p.add_argument("--duration", type=float, default=None, help="stop after S wall seconds")
        if name != "bw":
            p.add_argument(
                "--wall",
                action="store_true",
                help="measure in wall-clock time even when a node publishes /clock",
            )
        p.set_defaults(func=cmd_measure, measure=name)

    p = sub.add_parser("pub", help="publish a message")
    p.add_argument("topic")
    p.add_argument("type", help="message type, e.g. geometry_msgs/msg/Twist")
    p.add_argument("values", nargs="?", default="{}", help="YAML of the fields")
    p.add_argument(
        "-r", "--rate", type=_positive_float, default=1.0, help="publish rate in Hz (default 1)"
    )
    count = p.add_mutually_exclusive_group()
    count.add_argument("-1", "--once", action="store_true", help="publish once and exit")
    count.add_argument(
        "-t", "--times", type=_non_negative_int, default=0, help="publish N times and exit"
    )
    p.add_argument("--qos-durability", choices=["volatile", "transient_local"], default="volatile")
    p.add_argument(
        "-w",
        "--wait-matching-subscriptions",
        type=_non_negative_int,
        default=None,
        metavar="N",
        help="wait until N subscriptions of the type are in the graph before publishing "
        "(default: 1 with --once/--times, else 0)",
    )
    p.add_argument(
        "--max-wait-time-secs",
        type=_positive_float,
        default=None,
        metavar="S",
        help="give up waiting for the subscriptions after S seconds: exit 1 with an error "
        "(default: wait forever)",
    )
    p.add_argument(
        "--keep-alive",
        type=_positive_float,
        default=KEEP_ALIVE_S,
        metavar="S",
        help=f"stay S seconds after the last message so it leaves (default {KEEP_ALIVE_S})",
    )
    p.set_defaults(func=cmd_pub)


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0 or value == float("inf"):
        msg = f"{text!r} is not a positive number (e.g. 0.5)"
        raise argparse.ArgumentTypeError(msg)
    return value


def _non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        msg = f"{text!r} is not a whole number >= 0 (e.g. 2)"
        raise argparse.ArgumentTypeError(msg)
    return value


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
    """``topic echo``; with ``--offset`` times print as seconds from now (sim time on /clock)."""
    with cli_node(args) as node:
        cls = _resolve_type(node, args.topic, args.type)
        qos = subscription_qos_for(node.context, args.topic)
        done: list[bool] = [False]
        sim = args.offset and not args.wall and _graph_runs_on_clock(node)
        if sim:
            node.set_parameters([Parameter("use_sim_time", value=True)])
        clock = node.get_clock()

        def on_msg(msg: Any) -> None:
            offset = None
            if args.offset:
                offset = clock.now_ns() if sim else time.time_ns()
                if offset == 0:
                    return  # no /clock message yet: no now to offset from
            cut = args.truncate_length
            if args.field:
                value = get_field(msg, args.field)
                if (
                    offset is not None
                    and getattr(value, "__msgtype__", "") == "builtin_interfaces/msg/Time"
                ):
                    text = str((time_to_ns(value) - offset) / 1e9)
                elif hasattr(value, "__msgtype__"):
                    text = message_to_yaml(value, truncate_length=cut, time_offset_ns=offset)
                else:
                    text = str(value)
            else:
                text = message_to_yaml(msg, truncate_length=cut, time_offset_ns=offset)
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


def _graph_runs_on_clock(node: Node) -> bool:
    """Whether some node publishes ``/clock`` (a simulation or ``bag play --clock``)."""
    return any(e.kind == "publisher" for e in node.context.graph.endpoints("/clock"))


def cmd_measure(args: argparse.Namespace) -> int:
    """``topic hz | bw | delay``: print statistics every second.

    ``hz`` and ``delay`` count in sim time when a node publishes ``/clock`` (as rostopic
    under ``/use_sim_time``), unless ``--wall``; ``hz`` then prints the wall-clock rate
    on a third line. ``bw`` is always wall-clock (as rostopic bw).
    """
    with cli_node(args) as node:
        cls = get_message_class(topic_type(node.context, args.topic))
        qos = subscription_qos_for(node.context, args.topic)
        clock = node.get_clock()
        sim = args.measure != "bw" and not args.wall and _graph_runs_on_clock(node)
        if sim:
            node.set_parameters([Parameter("use_sim_time", value=True)])
        rate, wall_rate, bw, delay = (
            RateMeter(args.window),
            RateMeter(args.window),
            BandwidthMeter(args.window),
            DelayMeter(args.window),
        )

        def on_msg(msg: Any) -> None:
            now = time.time_ns()
            sim_now = clock.now_ns() if sim else 0
            if sim and sim_now == 0:
                return  # no /clock message yet: nothing to count in
            if args.measure == "hz":
                wall_rate.add(time.monotonic_ns())
                rate.add(sim_now if sim else time.monotonic_ns())
            elif args.measure == "bw":
                bw.add(time.monotonic_ns(), len(serialize(msg)))
            else:
                header = getattr(msg, "header", None)
                if header is None:
                    text = (
                        f"topic '{args.topic}' ({msg.__msgtype__}) has no header to measure delay"
                    )
                    raise MessageError(text)
                delay.add(sim_now if sim else now, time_to_ns(header.stamp))

        node.create_subscription(cls, args.topic, on_msg, qos)
        start = time.monotonic()
        next_print = start + 1.0
        while args.duration is None or time.monotonic() - start < args.duration:
            node.context.spin_once(0.05)
            if time.monotonic() >= next_print:
                next_print += 1.0
                meter: Any = {"hz": rate, "bw": bw, "delay": delay}[args.measure]
                stats = meter.stats()
                text = stats.format() if stats else "no new messages"
                if stats and sim:
                    text += "\n\tin sim time (/clock)"
                    wall = wall_rate.stats() if args.measure == "hz" else None
                    text += f"; wall-clock rate: {wall.rate_hz:.3f}" if wall else ""
                print(text, flush=True)
    return 0


def matching_subscription_count(pub: Publisher[Any]) -> int:
    """Subscriptions in the graph that receive what ``pub`` publishes.

    Those of the publisher's topic and message type, in any process (other types never
    receive: the type is part of the transport's key). QoS is not compared: between
    processes visnav delivers whatever the profiles (see :mod:`visnav.graph.qos`).
    """
    return sum(
        1
        for e in pub.node.get_subscriptions_info_by_topic(pub.topic_name)
        if e.type_name == pub.type_name
    )


def wait_for_matching_subscriptions(
    pub: Publisher[Any],
    count: int,
    *,
    max_wait_s: float | None = None,
    on_wait: Callable[[int], None] | None = None,
) -> int:
    """Spin ``pub``'s context until ``count`` matching subscriptions are in the graph.

    As ``ros2 topic pub --wait-matching-subscriptions N --max-wait-time-secs S``. A
    subscription is counted once its liveliness token arrived; Zenoh then has its
    subscriber too (it is declared first), and a sample published right away reaches it
    (:meth:`visnav.graph.transport.ZenohPublisher.wants_sample`).

    Args:
        pub: the publisher.
        count: how many subscriptions to wait for (0 returns at once).
        max_wait_s: give up after this many seconds; None waits forever.
        on_wait: called with the count seen after 1 s of waiting, then every 10 s.

    Returns:
        The number of matching subscriptions seen (at least ``count``).

    Raises:
        SubscriptionWaitTimeoutError: ``max_wait_s`` passed first.
    """
    ctx = pub.node.context
    start = time.monotonic()
    next_note = start + 1.0
    while (seen := matching_subscription_count(pub)) < count:
        now = time.monotonic()
        if max_wait_s is not None and now - start >= max_wait_s:
            text = (
                f"topic '{pub.topic_name}': {seen} of {count} matching subscription(s) "
                f"({pub.type_name}) after waiting {max_wait_s:g} s (--max-wait-time-secs); "
                "start the subscriber first, wait longer, or lower "
                "--wait-matching-subscriptions"
            )
            raise SubscriptionWaitTimeoutError(text)
        if on_wait is not None and now >= next_note:
            on_wait(seen)
            next_note = now + 10.0
        ctx.spin_once(0.05 if max_wait_s is None else min(0.05, start + max_wait_s - now))
    return seen


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
    if wait_n == 0 and args.max_wait_time_secs is not None:
        text = (
            f"--max-wait-time-secs {args.max_wait_time_secs:g}: nothing to wait for; add "
            "--wait-matching-subscriptions N, --once or --times N, or drop the option"
        )
        raise TopicPubArgumentError(text)
    with cli_node(args, discover=False) as node:
        qos = QoSProfile(depth=10, durability=DurabilityPolicy(args.qos_durability))
        pub = node.create_publisher(cls, args.topic, qos)

        def note(seen: int) -> None:
            print(
                f"waiting for {wait_n} matching subscription(s) on '{pub.topic_name}' "
                f"({pub.type_name}): {seen} so far",
                flush=True,
            )

        wait_for_matching_subscriptions(
            pub, wait_n, max_wait_s=args.max_wait_time_secs, on_wait=note
        )
        period = 1.0 / args.rate
        count = 0
        next_t = time.monotonic()
        while True:
            print(f"publishing #{count + 1}: {msg.__msgtype__}", flush=True)
            pub.publish(msg)
            count += 1
            if times and count >= times:
                time.sleep(args.keep_alive)  # let the transport send it before the session closes
                return 0
            next_t += period
            while time.monotonic() < next_t:
                node.context.spin_once(max(0.0, next_t - time.monotonic()))
