"""What the graph looks like: nodes, publishers and subscriptions of every process.

Entities are known by their liveliness token keys (rmw_zenoh layout, see
:mod:`visnav.graph.keys`). Local entities are added directly; remote ones arrive
through the transport's liveliness subscription. Both paths use the same key,
so an entity seen both ways is counted once.
"""

from __future__ import annotations

import dataclasses
import threading
from collections.abc import Callable

from visnav.graph.keys import LivelinessToken, parse_liveliness_token

__all__ = ["EndpointInfo", "GraphCache", "NodeInfo"]


@dataclasses.dataclass(frozen=True)
class NodeInfo:
    """A node in the graph."""

    name: str
    namespace: str
    zid: str
    node_id: int

    @property
    def fully_qualified_name(self) -> str:
        """``/ns/name``."""
        return f"{self.namespace.rstrip('/')}/{self.name}"


@dataclasses.dataclass(frozen=True)
class EndpointInfo:
    """A publisher, subscription, service server or client in the graph (rclpy's TopicEndpointInfo).

    ``kind`` is ``"publisher"``, ``"subscription"``, ``"service_server"`` or
    ``"service_client"``; for the last two ``topic`` is the service name and
    ``type_name`` the service type (``pkg/srv/Name``).
    """

    kind: str
    topic: str
    type_name: str
    node_name: str
    node_namespace: str
    reliability: str
    durability: str
    depth: int
    zid: str
    node_id: int
    entity_id: int

    @property
    def node_fqn(self) -> str:
        """The owning node's fully qualified name."""
        return f"{self.node_namespace.rstrip('/')}/{self.node_name}"


class GraphCache:
    """Thread-safe view of the graph built from liveliness tokens."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._tokens: dict[str, LivelinessToken] = {}
        self._listeners: list[Callable[[], None]] = []
        self._token_listeners: list[Callable[[LivelinessToken], None]] = []
        self.version = 0

    def add_listener(self, callback: Callable[[], None]) -> None:
        """Call ``callback`` (from any thread) whenever the graph changes."""
        self._listeners.append(callback)

    def add_token_listener(self, callback: Callable[[LivelinessToken], None]) -> None:
        """Call ``callback(token)`` (from any thread) for every token that appears."""
        self._token_listeners.append(callback)

    def _changed(self) -> None:
        self.version += 1
        for cb in list(self._listeners):
            cb()

    def put(self, key: str, token: LivelinessToken | None = None) -> None:
        """Add a token key (ignored if it is not a visnav/rmw_zenoh token).

        ``token`` is its parsed form when the caller has it (local entities), else the
        key is parsed.
        """
        if key in self._tokens:  # e.g. a local entity's own token coming back from Zenoh
            return
        if token is None:
            try:
                token = parse_liveliness_token(key)
            except ValueError:
                return
        with self._lock:
            if key in self._tokens:
                return
            self._tokens[key] = token
        for cb in list(self._token_listeners):
            cb(token)
        self._changed()

    def delete(self, key: str) -> None:
        """Remove a token key."""
        with self._lock:
            if self._tokens.pop(key, None) is None:
                return
        self._changed()

    def nodes(self) -> list[NodeInfo]:
        """Return every node, sorted by fully qualified name."""
        with self._lock:
            toks = list(self._tokens.values())
        seen = {
            NodeInfo(t.node_name, t.namespace, t.zid, t.node_id) for t in toks if t.kind == "NN"
        }
        return sorted(seen, key=lambda n: (n.fully_qualified_name, n.zid, n.node_id))

    def endpoints(self, topic: str | None = None) -> list[EndpointInfo]:
        """Return publishers and subscriptions (optionally of one topic)."""
        return self._endpoints(("MP", "MS"), topic)

    def service_endpoints(self, service: str | None = None) -> list[EndpointInfo]:
        """Return service servers and clients (optionally of one service)."""
        return self._endpoints(("SS", "SC"), service)

    def has_service_server(self, service: str, type_name: str) -> bool:
        """Whether a server of ``service`` with ``type_name`` is in the graph."""
        with self._lock:
            toks = list(self._tokens.values())
        return any(t.kind == "SS" and t.topic == service and t.type_name == type_name for t in toks)

    def service_names_and_types(self) -> list[tuple[str, list[str]]]:
        """Return ``[(service, [types])]`` of every service with a server, sorted."""
        types: dict[str, set[str]] = {}
        for e in self.service_endpoints():
            if e.kind == "service_server":
                types.setdefault(e.topic, set()).add(e.type_name)
        return [(t, sorted(v)) for t, v in sorted(types.items())]

    def _endpoints(self, kinds: tuple[str, str], topic: str | None) -> list[EndpointInfo]:
        with self._lock:
            toks = list(self._tokens.values())
        names = {"MP": "publisher", "MS": "subscription", "SS": "service_server"}
        out = []
        for t in toks:
            if t.kind not in kinds or t.topic is None:
                continue
            if topic is not None and t.topic != topic:
                continue
            out.append(
                EndpointInfo(
                    kind=names.get(t.kind, "service_client"),
                    topic=t.topic,
                    type_name=t.type_name or "",
                    node_name=t.node_name,
                    node_namespace=t.namespace,
                    reliability=t.reliability or "reliable",
                    durability=t.durability or "volatile",
                    depth=t.depth if t.depth is not None else 0,
                    zid=t.zid,
                    node_id=t.node_id,
                    entity_id=t.entity_id,
                )
            )
        return sorted(out, key=lambda e: (e.topic, e.kind, e.node_fqn, e.entity_id))

    def publisher_node(self, zid: str, entity_id: int) -> str | None:
        """Return the fully qualified node name of a publisher, or None if unknown."""
        with self._lock:
            toks = list(self._tokens.values())
        for t in toks:
            if t.kind == "MP" and t.zid == zid and t.entity_id == entity_id:
                return f"{t.namespace.rstrip('/')}/{t.node_name}"
        return None

    def topic_names_and_types(self) -> list[tuple[str, list[str]]]:
        """Return ``[(topic, [types])]`` sorted by topic (rclpy's get_topic_names_and_types)."""
        types: dict[str, set[str]] = {}
        for e in self.endpoints():
            types.setdefault(e.topic, set()).add(e.type_name)
        return [(t, sorted(v)) for t, v in sorted(types.items())]
