"""The ``connectionGraph`` capability: which nodes publish, subscribe and serve what.

Foxglove's Topic Graph panel asks for it with ``subscribeConnectionGraph``; the server
answers with a ``connectionGraphUpdate`` holding the whole graph, then sends what changes
(each entry replaces the previous ids of its topic or service; ``removedTopics`` and
``removedServices`` name what is gone), as foxglove_bridge does:

* every topic that passes ``topic_whitelist`` (and, as for the channels, is not hidden
  unless ``include_hidden``) is in both ``publishedTopics`` and ``subscribedTopics``, with
  the fully qualified names of the nodes publishing / subscribing (either list may be
  empty);
* every service with a server that passes ``service_whitelist`` is in
  ``advertisedServices`` with the names of the nodes serving it.

Pure functions over a :class:`~visnav.graph.graph_cache.GraphCache`; the server decides
when to call them (on a client's subscribe and on every graph change).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Protocol

from visnav.graph.names import is_hidden_name

__all__ = ["GraphSnapshot", "full_update", "graph_snapshot", "graph_update"]

_Ids = dict[str, tuple[str, ...]]


class _Graph(Protocol):
    def endpoints(self, topic: str | None = None) -> list[Any]: ...
    def service_endpoints(self, service: str | None = None) -> list[Any]: ...


@dataclass(frozen=True)
class GraphSnapshot:
    """The connection graph at one moment: ``name -> sorted node names``."""

    published: _Ids = field(default_factory=dict)
    subscribed: _Ids = field(default_factory=dict)
    services: _Ids = field(default_factory=dict)


def _ok(patterns: list[re.Pattern[str]], name: str) -> bool:
    return any(p.fullmatch(name) for p in patterns)


def graph_snapshot(
    graph: _Graph,
    *,
    topic_whitelist: list[re.Pattern[str]],
    service_whitelist: list[re.Pattern[str]],
    include_hidden: bool = False,
) -> GraphSnapshot:
    """The graph's topics and services with their nodes, filtered as the channels are."""
    pubs: dict[str, set[str]] = {}
    subs: dict[str, set[str]] = {}
    for e in graph.endpoints():
        name = e.topic
        if (not include_hidden and is_hidden_name(name)) or not _ok(topic_whitelist, name):
            continue
        pubs.setdefault(name, set())
        subs.setdefault(name, set())
        (pubs if e.kind == "publisher" else subs)[name].add(e.node_fqn)
    services: dict[str, set[str]] = {}
    for e in graph.service_endpoints():
        name = e.topic
        if e.kind != "service_server":
            continue
        if (not include_hidden and is_hidden_name(name)) or not _ok(service_whitelist, name):
            continue
        services.setdefault(name, set()).add(e.node_fqn)
    return GraphSnapshot(
        published={k: tuple(sorted(v)) for k, v in sorted(pubs.items())},
        subscribed={k: tuple(sorted(v)) for k, v in sorted(subs.items())},
        services={k: tuple(sorted(v)) for k, v in sorted(services.items())},
    )


def _entries(ids: _Ids, key: str, names: list[str] | None = None) -> list[dict[str, Any]]:
    return [{"name": n, key: list(ids[n])} for n in (ids if names is None else names)]


def full_update(snapshot: GraphSnapshot) -> dict[str, Any]:
    """The ``connectionGraphUpdate`` a newly subscribed client gets: the whole graph."""
    return {
        "op": "connectionGraphUpdate",
        "publishedTopics": _entries(snapshot.published, "publisherIds"),
        "subscribedTopics": _entries(snapshot.subscribed, "subscriberIds"),
        "advertisedServices": _entries(snapshot.services, "providerIds"),
        "removedTopics": [],
        "removedServices": [],
    }


def _changed(old: _Ids, new: _Ids) -> list[str]:
    return [name for name, ids in new.items() if old.get(name) != ids]


def graph_update(old: GraphSnapshot, new: GraphSnapshot) -> dict[str, Any] | None:
    """The ``connectionGraphUpdate`` from ``old`` to ``new``; None when nothing changed."""
    old_topics = set(old.published) | set(old.subscribed)
    new_topics = set(new.published) | set(new.subscribed)
    removed_topics = sorted(old_topics - new_topics)
    removed_services = sorted(set(old.services) - set(new.services))
    published = _changed(old.published, new.published)
    subscribed = _changed(old.subscribed, new.subscribed)
    services = _changed(old.services, new.services)
    if not (published or subscribed or services or removed_topics or removed_services):
        return None
    return {
        "op": "connectionGraphUpdate",
        "publishedTopics": _entries(new.published, "publisherIds", published),
        "subscribedTopics": _entries(new.subscribed, "subscriberIds", subscribed),
        "advertisedServices": _entries(new.services, "providerIds", services),
        "removedTopics": removed_topics,
        "removedServices": removed_services,
    }
