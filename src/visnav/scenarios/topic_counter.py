"""Message counts and sim-time rates of every topic of a scenario run."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from visnav.graph.context import Context
from visnav.graph.introspect import new_published_topics, subscription_qos_for
from visnav.graph.node import Node
from visnav.msgs.serde import get_message_class

__all__ = ["TopicCounter"]


class TopicCounter:
    """Counts messages and measures the sim-time rate of every (visible) topic.

    Subscribes to each topic of the graph as it appears, with a QoS compatible
    with its publishers; callbacks only count (in-process delivery is zero-copy).
    Topics of ``skip_types`` are listed with count None but not subscribed to: the
    simulator renders a camera only while its topics have subscribers.
    """

    def __init__(
        self, ctx: Context, clock_ns: Callable[[], int], *, skip_types: tuple[str, ...] = ()
    ) -> None:
        self._ctx = ctx
        self._skip_types = skip_types
        self._node = Node("_visnav_topic_counter", context=ctx)
        self._clock_ns = clock_ns
        self._version = -1
        self.counts: dict[str, list[int]] = {}  # topic -> [count, first_ns, last_ns]
        self.types: dict[str, str] = {}

    def poll(self) -> None:
        """Subscribe to topics that appeared since the last poll."""
        if self._ctx.graph.version == self._version:
            return
        self._version = self._ctx.graph.version
        for found in new_published_topics(self._ctx, self.types):
            topic, types = found.name, found.types
            if len(types) != 1:
                continue
            self.types[topic] = types[0]
            stats = self.counts.setdefault(topic, [0, 0, 0])
            if types[0] in self._skip_types:
                continue  # not subscribed: a camera renders only for subscribers

            def on_msg(_msg: Any, stats: list[int] = stats) -> None:
                now = self._clock_ns()
                if stats[0] == 0:
                    stats[1] = now
                stats[0] += 1
                stats[2] = now

            qos = subscription_qos_for(self._ctx, topic)
            self._node.create_subscription(get_message_class(types[0]), topic, on_msg, qos)

    def summary(self) -> dict[str, dict[str, Any]]:
        """``{topic: {type, count, rate_hz}}`` (rate over sim time; 0 with < 2 messages).

        A topic of ``skip_types`` has ``count`` and ``rate_hz`` None (not counted).
        """
        out: dict[str, dict[str, Any]] = {}
        for topic in sorted(self.types):
            if self.types[topic] in self._skip_types:
                out[topic] = {"type": self.types[topic], "count": None, "rate_hz": None}
                continue
            count, first, last = self.counts[topic]
            rate = (count - 1) / ((last - first) / 1e9) if count > 1 and last > first else 0.0
            out[topic] = {"type": self.types[topic], "count": count, "rate_hz": round(rate, 3)}
        return out
