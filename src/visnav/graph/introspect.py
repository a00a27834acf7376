"""Library functions behind ``visnav topic | node`` (the CLI only parses and prints).

They work on any :class:`~visnav.graph.Context`; with the Zenoh transport they
see every process of the domain.
"""

from __future__ import annotations

import difflib
import time
from collections.abc import Container
from dataclasses import dataclass

from visnav.graph.context import Context
from visnav.graph.errors import GraphError
from visnav.graph.graph_cache import EndpointInfo
from visnav.graph.names import is_hidden_name
from visnav.graph.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

__all__ = [
    "PublishedTopic",
    "UnknownTopicError",
    "endpoint_qos",
    "new_published_topics",
    "node_summary",
    "subscription_qos_for",
    "topic_type",
    "wait_for_discovery",
]


class UnknownTopicError(GraphError, LookupError):
    """A topic (or node) named on the command line is not in the graph."""


def wait_for_discovery(ctx: Context, *, timeout_s: float = 2.0, settle_s: float = 0.3) -> None:
    """Wait until the graph view of ``ctx`` stops changing (peers connected, tokens in).

    Returns after ``settle_s`` without change once a peer is connected, or after
    ``timeout_s``. With no other process in the domain it returns after ~0.5 s.
    """
    z = ctx.zenoh
    if z is None:
        return
    start = time.monotonic()
    last = (-1, -1)
    last_change = start
    while True:
        now = time.monotonic()
        state = (len(z.peers()), ctx.graph.version)
        if state != last:
            last, last_change = state, now
        quiet = now - last_change
        if state[0] > 0 and quiet >= settle_s:
            return
        if state[0] == 0 and now - start >= 0.5:
            return
        if now - start >= timeout_s:
            return
        time.sleep(0.02)


def _suggest(name: str, names: list[str]) -> str:
    close = difflib.get_close_matches(name, names, n=3, cutoff=0.5)
    return f"; did you mean {', '.join(close)}?" if close else ""


def topic_type(ctx: Context, topic: str) -> str:
    """Return the message type of ``topic`` in the graph.

    Raises:
        UnknownTopicError: the topic is not in the graph (closest names suggested), or it
            carries several types.
    """
    topics = dict(ctx.graph.topic_names_and_types())
    types = topics.get(topic)
    if not types:
        hint = _suggest(topic, list(topics))
        msg = f"topic '{topic}' is not in the graph (domain {ctx.domain}){hint}"
        raise UnknownTopicError(msg)
    if len(types) > 1:
        msg = (
            f"topic '{topic}' carries several types ({', '.join(types)}); pass the type explicitly"
        )
        raise UnknownTopicError(msg)
    return types[0]


def endpoint_qos(e: EndpointInfo) -> QoSProfile:
    """Return the QoS profile an endpoint announced."""
    return QoSProfile(
        depth=max(1, e.depth),
        reliability=ReliabilityPolicy(e.reliability),
        durability=DurabilityPolicy(e.durability),
    )


@dataclass(frozen=True)
class PublishedTopic:
    """A topic with at least one publisher.

    Attributes:
        name: the topic.
        types: the distinct types its publishers announce, sorted (one, unless they disagree).
        publishers: its publishers.
    """

    name: str
    types: tuple[str, ...]
    publishers: tuple[EndpointInfo, ...]


def new_published_topics(
    ctx: Context,
    known: Container[str],
    *,
    include_hidden: bool = False,
    include_tool_publishers: bool = True,
) -> list[PublishedTopic]:
    """Topics with a publisher that are not in ``known`` (for tools that take every topic).

    ``ros2 bag record -a``, the viewer, doctor and the scenario counter subscribe to
    each topic once its first publisher shows up; this is their shared scan.

    Args:
        ctx: the graph.
        known: topics the caller has taken (or refused) already.
        include_hidden: also topics with a name token starting with ``_``.
        include_tool_publishers: count publishers of hidden nodes (``_visnav_*`` tools);
            without them a topic only tools publish is left out.
    """
    out: list[PublishedTopic] = []
    for topic, _types in ctx.graph.topic_names_and_types():
        if topic in known or (not include_hidden and is_hidden_name(topic)):
            continue
        pubs = tuple(
            e
            for e in ctx.graph.endpoints(topic)
            if e.kind == "publisher"
            and (include_tool_publishers or not e.node_name.startswith("_"))
        )
        if pubs:
            out.append(PublishedTopic(topic, tuple(sorted({e.type_name for e in pubs})), pubs))
    return out


def subscription_qos_for(ctx: Context, topic: str) -> QoSProfile:
    """Return a subscription QoS compatible with every publisher of ``topic`` (as ros2 echo).

    Best effort if any publisher is best effort; transient local if all are.
    """
    pubs = [e for e in ctx.graph.endpoints(topic) if e.kind == "publisher"]
    if not pubs:
        return QoSProfile(depth=10)
    rel = (
        ReliabilityPolicy.BEST_EFFORT
        if any(p.reliability == "best_effort" for p in pubs)
        else ReliabilityPolicy.RELIABLE
    )
    dur = (
        DurabilityPolicy.TRANSIENT_LOCAL
        if all(p.durability == "transient_local" for p in pubs)
        else DurabilityPolicy.VOLATILE
    )
    return QoSProfile(depth=10, reliability=rel, durability=dur)


def node_summary(ctx: Context, fqn: str) -> dict[str, list[tuple[str, str]]]:
    """Return a node's endpoints: ``{kind: [(topic or service, type)]}``.

    Kinds: ``publishers``, ``subscribers``, ``service_servers``, ``service_clients``.

    Raises:
        UnknownTopicError: no such node (closest names suggested).
    """
    nodes = [n.fully_qualified_name for n in ctx.graph.nodes()]
    if fqn not in nodes:
        msg = f"node '{fqn}' is not in the graph (domain {ctx.domain!r}){_suggest(fqn, nodes)}"
        raise UnknownTopicError(msg)
    out: dict[str, list[tuple[str, str]]] = {
        "publishers": [],
        "subscribers": [],
        "service_servers": [],
        "service_clients": [],
    }
    keys = {
        "publisher": "publishers",
        "subscription": "subscribers",
        "service_server": "service_servers",
        "service_client": "service_clients",
    }
    for e in [*ctx.graph.endpoints(), *ctx.graph.service_endpoints()]:
        if e.node_fqn != fqn:
            continue
        key = keys[e.kind]
        if (e.topic, e.type_name) not in out[key]:
            out[key].append((e.topic, e.type_name))
    return out
