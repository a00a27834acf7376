"""Record topics of a live graph into a bag (``ros2 bag record``).

The recorder is a node in the caller's :class:`~visnav.graph.Context`: its callbacks run in
that context's executor, so the caller spins the context (``ctx.spin()``) while recording.
It subscribes to the chosen topics (or every topic with ``all``) as soon as a publisher
announces them, with a QoS compatible with every publisher, and stores the profiles the
publishers offered. Messages are written serialized (one reused CDR buffer per topic).

Timestamps are receive times (what ROS 2 records): the wall clock when the message reached
this process, or, with ``use_sim_time=True``, the ``/clock`` time at the callback
(0 before the first ``/clock`` message, as in ROS 2). A flush every ``flush_period_s``
(0.5 s) puts the open chunk into the file, so a killed recorder loses at most that much.
"""

from __future__ import annotations

import dataclasses
import re
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from visnav.bag.qos import endpoint_qos
from visnav.bag.storage import check_format
from visnav.bag.writer import BagWriter, default_bag_path
from visnav.errors import VisnavError
from visnav.graph.clock import Clock, ClockType
from visnav.graph.context import Context
from visnav.graph.introspect import new_published_topics, subscription_qos_for
from visnav.graph.message_info import MessageInfo
from visnav.graph.names import is_hidden_name
from visnav.graph.node import Node, Subscription, Timer
from visnav.msgs.serde import CdrSerializer, get_message_class

__all__ = ["BagRecorder", "RecordedTopic"]


@dataclasses.dataclass
class RecordedTopic:
    """A topic being recorded.

    Attributes:
        name: topic name.
        type_name: message type.
        count: messages written.
        qos: the subscription's QoS (short form).
    """

    name: str
    type_name: str
    count: int = 0
    qos: str = ""


class BagRecorder:
    """Record topics of ``context``'s graph into a bag.

    Args:
        context: the graph context (its executor runs the recorder's callbacks).
        topics: topic names to record, or None for every topic (``-a``); named topics that
            have no publisher yet are subscribed when one appears.
        path: output bag (directory for ``mcap``, ``.bag`` file for ``ros1``).
        fmt: ``"mcap"`` (rosbag2, default) or ``"ros1"``.
        compression: ``"none"`` (default), ``"zstd"``/``"lz4"`` (MCAP), ``"lz4"``/``"bz2"`` (ROS 1).
        exclude: with all topics, a regular expression of topic names to leave out.
        include_hidden: with all topics, also record hidden topics (a name part starting with
            ``_``).
        use_sim_time: stamp messages with ``/clock`` time instead of the wall clock.
        flush_period_s: put buffered messages into the file at least this often.
        node_name: the recorder node's name.

    Raises:
        UnknownStorageError: unknown format or compression.
        BagExistsError: the output exists.

    Example::

        with Context() as ctx:
            rec = BagRecorder(ctx, None, "run_bag")
            rec.start()
            ctx.spin(duration_s=10.0)
            rec.stop()
    """

    def __init__(
        self,
        context: Context,
        topics: Sequence[str] | None,
        path: str | Path,
        *,
        fmt: str = "mcap",
        compression: str = "none",
        exclude: str | None = None,
        include_hidden: bool = False,
        use_sim_time: bool = False,
        flush_period_s: float = 0.5,
        node_name: str = "visnav_bag_recorder",
    ) -> None:
        self.fmt, self.compression = check_format(fmt, compression)
        if self.fmt not in ("mcap", "ros1"):
            msg = f"recording format {fmt!r}: expected 'mcap' or 'ros1' (convert afterwards)"
            raise VisnavError(msg)
        if flush_period_s <= 0 or flush_period_s > 1.0:
            msg = f"flush_period_s is {flush_period_s}: expected 0 < period <= 1 s"
            raise VisnavError(msg)
        self.context = context
        self.path = Path(path)
        self.all_topics = topics is None
        self._wanted = list(topics or [])
        self._exclude = re.compile(exclude) if exclude else None
        self._include_hidden = include_hidden
        self.use_sim_time = use_sim_time
        self._flush_period = flush_period_s
        self._node_name = node_name
        self._node: Node | None = None
        self._writer: BagWriter | None = None
        self._timers: list[Timer] = []
        self._subs: list[Subscription[Any]] = []
        self._graph_version = -1
        self._skipped: set[str] = set()
        self.topics: dict[str, RecordedTopic] = {}
        self.last_flush_monotonic = 0.0

    # ------------------------------------------------------------------ lifecycle
    @property
    def running(self) -> bool:
        """True between :meth:`start` and :meth:`stop`."""
        return self._writer is not None

    @property
    def message_count(self) -> int:
        """Messages written so far."""
        return sum(t.count for t in self.topics.values())

    @property
    def bag_path(self) -> Path:
        """The bag's path (a ``.bag`` suffix is added for ROS 1)."""
        if self._writer is not None:
            return self._writer.path
        return default_bag_path(self.path, self.fmt)

    def start(self) -> None:
        """Open the bag, create the recorder node and subscribe to what exists now."""
        if self._writer is not None:
            return
        self._writer = BagWriter(self.path, fmt=self.fmt, compression=self.compression)
        self._node = Node(self._node_name, context=self.context, use_sim_time=self.use_sim_time)
        steady = Clock(ClockType.STEADY_TIME)
        self._timers = [
            self._node.create_timer(self._flush_period, self.flush, clock=steady),
            self._node.create_timer(0.1, self.poll, clock=steady),
        ]
        self._wanted = [self._node.resolve_topic_name(t) for t in self._wanted]
        self.last_flush_monotonic = time.monotonic()
        self.poll()

    def stop(self) -> Path:
        """Stop recording, finish the bag and return its path (idempotent)."""
        writer, self._writer = self._writer, None
        node, self._node = self._node, None
        if node is not None:
            node.destroy_node()
        if writer is None:
            return self.bag_path
        writer.close()
        return writer.path

    def flush(self) -> None:
        """Put everything received so far into the file (runs on the recorder's timer)."""
        if self._writer is not None:
            self._writer.flush()
            self.last_flush_monotonic = time.monotonic()

    # ------------------------------------------------------------------ discovery
    def _selected(self, topic: str) -> bool:
        if not self.all_topics:
            return topic in self._wanted
        if not self._include_hidden and is_hidden_name(topic):
            return False
        return not (self._exclude is not None and self._exclude.search(topic))

    def poll(self) -> None:
        """Subscribe to newly announced topics (runs every 0.1 s on the recorder's timer)."""
        node = self._node
        if node is None or self._writer is None:
            return
        version = self.context.graph.version
        if version == self._graph_version:
            return
        self._graph_version = version
        taken = self.topics.keys() | self._skipped
        for found in new_published_topics(self.context, taken, include_hidden=True):
            topic, types = found.name, found.types
            if not self._selected(topic):
                continue
            if len(types) != 1:
                node.get_logger().warning(
                    f"not recording '{topic}': it carries several types ({', '.join(types)})"
                )
                self._skipped.add(topic)
                continue
            self._subscribe(node, topic, types[0], list(found.publishers))

    def _subscribe(self, node: Node, topic: str, type_name: str, pubs: list[Any]) -> None:
        assert self._writer is not None
        try:
            cls = get_message_class(type_name)
        except VisnavError as exc:
            node.get_logger().warning(f"not recording '{topic}': {exc}")
            self._skipped.add(topic)
            return
        qos = subscription_qos_for(self.context, topic)
        handle = self._writer.add_topic(topic, type_name, qos=[endpoint_qos(e) for e in pubs])
        rec = RecordedTopic(topic, type_name, qos=qos.short())
        self.topics[topic] = rec
        callback = self._callback(rec, handle, CdrSerializer(type_name))
        self._subs.append(node.create_subscription(cls, topic, callback, qos))
        node.get_logger().info(f"recording '{topic}' ({type_name}, {qos.short()})")

    def _callback(
        self, rec: RecordedTopic, handle: int, cdr: CdrSerializer
    ) -> Callable[[Any, MessageInfo | None], None]:
        writer = self._writer
        assert writer is not None
        assert self._node is not None
        clock = self._node.get_clock()
        sim = self.use_sim_time

        def on_message(msg: Any, info: MessageInfo | None) -> None:
            if self._writer is None:
                return
            if sim:
                t = pub = clock.now_ns()
            elif info is not None:
                t, pub = info.received_timestamp_ns, info.source_timestamp_ns
            else:
                t = pub = time.time_ns()
            writer.write(handle, t, cdr.serialize(msg), publish_ns=pub)
            rec.count += 1

        return on_message
