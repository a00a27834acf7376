"""Observe a live graph: subscribe to every topic for a while, keep statistics and samples.

:class:`LiveObserver` adds a hidden node (``_visnav_doctor_*``) to a context and
subscribes to every published topic with a QoS compatible with its publishers (best
effort if any publisher is, transient local if all are), picking up topics that appear
later. Its callbacks run in the context's executor: :func:`observe_live` spins the
context itself; a caller that already spins it (a simulator running in-process) just
creates the observer, runs, and asks for :meth:`LiveObserver.observation`.
"""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Callable
from typing import Any

from visnav.doctor.builder import HEAVY_TYPES, ObservationBuilder, SamplingPolicy
from visnav.doctor.errors import DoctorError
from visnav.doctor.observation import GraphSnapshot, Observation
from visnav.graph.context import Context
from visnav.graph.errors import GraphError
from visnav.graph.introspect import new_published_topics, subscription_qos_for, wait_for_discovery
from visnav.graph.message_info import MessageInfo
from visnav.graph.names import is_hidden_name
from visnav.graph.node import Node, Subscription
from visnav.graph.qos import QoSProfile
from visnav.msgs.errors import MessageError
from visnav.msgs.serde import get_message_class

__all__ = ["LiveObserver", "graph_snapshot", "observe_live"]

_ids = itertools.count()


def graph_snapshot(ctx: Context) -> GraphSnapshot:
    """The graph of ``ctx`` without hidden nodes (doctor's own, CLI helpers)."""
    nodes = tuple(n for n in ctx.graph.nodes() if not n.name.startswith("_"))
    endpoints = tuple(
        e
        for e in ctx.graph.endpoints()
        if not e.node_name.startswith("_") and not is_hidden_name(e.topic)
    )
    names = {f"{e.zid}:{e.entity_id}": e.node_fqn for e in endpoints if e.kind == "publisher"}
    return GraphSnapshot(nodes, endpoints, names)


class LiveObserver:
    """Subscribes to every topic of a context's graph and records what arrives.

    Args:
        context: the graph context (its executor runs the callbacks).
        policy: sample decimation.
    """

    def __init__(self, context: Context, *, policy: SamplingPolicy | None = None) -> None:
        self.context = context
        self._node = Node(f"_visnav_doctor_{os.getpid()}_{next(_ids)}", context=context)
        self._builder = ObservationBuilder(
            source="live", label=f"live graph, domain {context.domain}", policy=policy
        )
        self._subs: dict[str, Subscription[Any]] = {}
        self._skipped: set[str] = set()
        self._start = time.time_ns()
        self.poll()

    def poll(self) -> None:
        """Subscribe to topics that appeared since the last call."""
        taken = self._subs.keys() | self._skipped
        for found in new_published_topics(self.context, taken, include_tool_publishers=False):
            topic, pub_types = found.name, found.types
            if len(pub_types) != 1:
                self._skipped.add(topic)  # topics.type_mismatch reports it
                continue
            type_name = pub_types[0]
            try:
                cls = get_message_class(type_name)
            except MessageError:
                self._builder.mark_undecodable(topic, type_name)
                self._skipped.add(topic)
                continue
            base = subscription_qos_for(self.context, topic)
            depth = 10 if type_name in HEAVY_TYPES else 200
            qos = QoSProfile(depth=depth, reliability=base.reliability, durability=base.durability)
            try:
                sub = self._node.create_subscription(
                    cls, topic, self._callback(topic, type_name), qos
                )
            except GraphError:
                self._skipped.add(topic)
                continue
            self._subs[topic] = sub
            self._builder.declare_topic(topic, type_name)

    def _callback(self, topic: str, type_name: str) -> Callable[[Any, MessageInfo | None], None]:
        builder = self._builder

        def on_message(msg: Any, info: MessageInfo | None) -> None:
            if info is not None and not info.from_this_process:
                receive = info.received_timestamp_ns
            else:
                receive = time.time_ns()
            publisher = f"{info.publisher_zid}:{info.publisher_entity_id}" if info else ""
            builder.add(topic, type_name, receive, msg, publisher=publisher)

        return on_message

    def observation(self) -> Observation:
        """The observation so far (graph snapshot taken now)."""
        self.poll()
        graph = graph_snapshot(self.context)
        for e in graph.endpoints:
            if e.kind == "publisher":
                self._builder.declare_topic(e.topic, e.type_name)
        self._builder.set_graph(graph)
        self._builder.set_window(self._start, time.time_ns())
        return self._builder.build()

    def close(self) -> None:
        """Remove the observer's node."""
        self._node.destroy_node()


def observe_live(
    *,
    context: Context | None = None,
    domain: str | int | None = None,
    duration_s: float = 5.0,
    policy: SamplingPolicy | None = None,
) -> Observation:
    """Listen to a live graph for ``duration_s`` and return what was observed.

    Args:
        context: the context to observe (default: a new one in ``domain``).
        domain: the graph domain when no context is given.
        duration_s: how long to listen (seconds, wall clock).
        policy: sample decimation.

    Raises:
        DoctorError: a non-positive duration.
    """
    if not duration_s > 0:
        msg = f"--duration is {duration_s}: expected seconds > 0"
        raise DoctorError(msg)
    own = context is None
    ctx = context if context is not None else Context(domain)
    try:
        wait_for_discovery(ctx)
        observer = LiveObserver(ctx, policy=policy)
        end = time.monotonic() + duration_s
        next_poll = time.monotonic() + 0.25
        while (now := time.monotonic()) < end:
            ctx.spin_once(min(0.05, end - now))
            if now >= next_poll:
                observer.poll()
                next_poll = now + 0.25
        ctx.spin_some()
        obs = observer.observation()
        observer.close()
        return obs
    finally:
        if own:
            ctx.shutdown()
