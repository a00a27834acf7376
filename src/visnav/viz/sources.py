"""Feeding a :class:`~visnav.viz.RerunSink`: live topics of the graph, or a recorded bag.

:class:`LiveFeed` subscribes, like RViz, to ``/tf`` and ``/tf_static`` always and to every
topic of a supported type (or the topics asked for), re-reading the graph every second
so topics that appear later are shown too. :func:`feed_bag` logs a bag in time order.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Collection, Sequence
from pathlib import Path
from typing import Any

from visnav.graph.context import Context
from visnav.graph.introspect import new_published_topics, subscription_qos_for
from visnav.graph.node import Node
from visnav.msgs.serde import get_message_class
from visnav.tf.ros import DYNAMIC_QOS, STATIC_LISTENER_QOS
from visnav.viz.display_sink import DisplaySink
from visnav.viz.sink import RerunSink, shows

__all__ = ["LiveFeed", "feed_bag"]

_LOG = logging.getLogger("visnav.viz")
_TF_TOPICS = {"/tf": DYNAMIC_QOS, "/tf_static": STATIC_LISTENER_QOS}  # all broadcasters' sets


def feed_bag(
    sink: RerunSink | DisplaySink,
    path: str | Path,
    *,
    topics: Sequence[str] | None = None,
    progress: Callable[[int], None] | None = None,
    missing_ok: bool = False,
) -> int:
    """Log every message of a bag (of a supported type) to ``sink``, in time order.

    ``/tf`` and ``/tf_static`` are always read (the data are placed through them) even
    when ``topics`` names others.

    Args:
        sink: the sink.
        path: the bag (any format :func:`visnav.bag.read_bag` reads).
        topics: only these topics (default all).
        progress: called with the count of messages read so far, every 100 messages.
        missing_ok: skip ``topics`` the bag does not have (an RViz config's displays
            show "no messages"); else a missing topic is an error.

    Returns:
        The number of messages logged.

    A message whose bytes do not decode is skipped and counted under ``errors`` in
    ``sink.stats()`` (warned once per topic).

    Raises:
        BagError: the bag cannot be read (missing, corrupt, a topic not in it, ...).
    """
    from visnav.bag import BagReader  # noqa: PLC0415  (bags are only needed here)
    from visnav.bag.errors import CorruptBagError  # noqa: PLC0415

    logged = 0
    with BagReader(path) as reader:
        wanted: list[str] | None = None
        if topics is not None:
            present = set(reader.topics)
            named = [t for t in topics if t in present] if missing_ok else list(topics)
            wanted = list(dict.fromkeys([*named, *(t for t in _TF_TOPICS if t in present)]))
        for i, raw in enumerate(reader.raw_messages(wanted)):
            try:
                msg = reader.decode(raw)
            except CorruptBagError as exc:  # one bad message: skip it, show the rest (RViz)
                sink.log_error(raw.topic, raw.type_name, str(exc))
                continue
            if sink.log(raw.topic, msg):
                logged += 1
            if progress is not None and (i + 1) % 100 == 0:
                progress(i + 1)
    sink.close()
    return logged


class LiveFeed:
    """Subscribes a node to the graph's topics and logs every message to a sink.

    Args:
        sink: the sink.
        context: the graph context to join.
        topics: only these topics (plus ``/tf`` and ``/tf_static``); default every topic
            of a type the sink shows.
        node_name: name of the (hidden) viewer node.
        rescan_s: how often the graph is re-read for new topics.
        accept: ``accept(topic, type)`` false leaves a topic out for now (asked again
            at the next scan).
    """

    def __init__(
        self,
        sink: RerunSink | DisplaySink,
        context: Context,
        *,
        topics: Collection[str] | None = None,
        node_name: str | None = None,
        rescan_s: float = 1.0,
        accept: Callable[[str, str], bool] | None = None,
    ) -> None:
        self._accept = accept
        self.sink = sink
        self.context = context
        self.node = Node(node_name or f"_visnav_viewer_{os.getpid()}", context=context)
        self._wanted = None if topics is None else set(topics)
        self._rescan_s = rescan_s
        self._next_scan = 0.0
        self._subscribed: dict[str, Any] = {}
        self.received = 0
        """Messages received so far."""
        for topic, qos in _TF_TOPICS.items():
            self._subscribe(topic, "tf2_msgs/msg/TFMessage", qos)

    @property
    def topics(self) -> list[str]:
        """The topics subscribed to."""
        return list(self._subscribed)

    def _subscribe(self, topic: str, type_name: str, qos: Any) -> None:
        cls = get_message_class(type_name)

        def on_msg(msg: Any) -> None:
            self.received += 1
            self.sink.log(topic, msg)

        self._subscribed[topic] = self.node.create_subscription(cls, topic, on_msg, qos)
        _LOG.debug("viewer: subscribed to %s (%s)", topic, type_name)

    def scan(self) -> list[str]:
        """Subscribe to topics that appeared since the last scan; return the new ones."""
        new: list[str] = []
        for found in new_published_topics(
            self.context, self._subscribed, include_hidden=self._wanted is not None
        ):
            topic, types = found.name, found.types
            if len(types) != 1:
                continue
            if self._wanted is not None and topic not in self._wanted:
                continue
            if self._wanted is None and not shows(topic, types[0]):
                continue
            if self._accept is not None and not self._accept(topic, types[0]):
                continue
            self._subscribe(topic, types[0], subscription_qos_for(self.context, topic))
            new.append(topic)
        return new

    def spin_once(self, timeout_s: float = 0.05) -> None:
        """Run callbacks for up to ``timeout_s``; rescan the graph and expire TF waits when due."""
        now = time.monotonic()
        if now >= self._next_scan:
            self._next_scan = now + self._rescan_s
            self.scan()
            self.sink.poll()
        self.context.spin_once(timeout_s)

    def run(
        self, *, duration_s: float | None = None, stop: Callable[[], bool] | None = None
    ) -> None:
        """Spin until ``duration_s`` wall-clock seconds pass or ``stop()`` is true (or Ctrl-C)."""
        end = None if duration_s is None else time.monotonic() + duration_s
        while (end is None or time.monotonic() < end) and not (stop is not None and stop()):
            self.spin_once(0.05)

    def missing_topics(self) -> list[str]:
        """Topics asked for that are not subscribed (not in the graph yet)."""
        if self._wanted is None:
            return []
        return sorted(self._wanted - set(self._subscribed))

    def close(self) -> None:
        """Destroy the viewer node (and its subscriptions)."""
        self._subscribed.clear()
        self.node.destroy_node()
