"""A ROS 1 node without rospy: slave XML-RPC API, TCPROS server, publications, subscriptions.

The slave API answers what ``rosnode`` and other nodes call: ``getBusInfo``, ``getBusStats``,
``getPid``, ``getSubscriptions``, ``getPublications``, ``getMasterUri``, ``requestTopic``,
``publisherUpdate``, ``paramUpdate`` and ``shutdown``. The TCPROS server takes topic
subscribers and service clients (:mod:`~visnav.bridge.tcpros_service`) on one port, as rospy.
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import logging
import os
import socket
import socketserver
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any
from xmlrpc.server import SimpleXMLRPCRequestHandler, SimpleXMLRPCServer

from visnav.bridge.connections import (
    ConnectionStats,
    InConnection,
    LazyParts,
    OutConnection,
    Parts,
    md5_mismatch,
)
from visnav.bridge.errors import BridgeError, TcprosError
from visnav.bridge.master_api import MasterClient, bind_address
from visnav.bridge.srvmap import Ros1ServiceType
from visnav.bridge.tcpros import encode_header, read_header
from visnav.bridge.tcpros_service import ServedService, ServiceHandler, serve_service_connection
from visnav.bridge.typemap import Ros1Type, rosout_type

__all__ = [
    "PACE_AHEAD",
    "PACE_RESUME",
    "SEND_BUFFER_BYTES",
    "Ros1Node",
    "ThreadingXmlRpcServer",
    "message_parts",
]

_log = logging.getLogger("visnav.bridge")

PACE_AHEAD = 6
"""Messages queued behind the one being sent before :meth:`Ros1Node.wants_more` says no (of the
10 a connection keeps): enough that a connection never waits for the next message to be taken
from the visnav graph and keeps the socket full. With 2, a flooded rospy subscriber got its
frames one by one and deserialized each (rospy skips all but the newest ``queue_size`` of a
batch it reads at once): 286 against 363 images per CPU-second of the subscriber
(``bench/bench_ros1.py --flood-only``, 15 and 6 runs on a loaded machine)."""

PACE_RESUME = 3
"""A sender held back by :meth:`Ros1Node.wants_more` goes on once a subscriber of the topic has
this many messages queued or fewer (:meth:`Ros1Node.can_resume`): each pause then lets
``PACE_AHEAD - PACE_RESUME`` messages through, not one, so a flooded topic pauses and resumes
(and tells its visnav publishers so) a third as often, while every queue keeps at least this
many messages to send."""


SEND_BUFFER_BYTES = 512 * 1024
"""``SO_SNDBUF`` asked for on each connection to a ROS 1 subscriber (Linux doubles it: 1 MiB,
about one 640x480 rgb8 image; a kernel whose ``net.core.wmem_max`` is lower caps the request
there first: 212992, i.e. 416 KiB, on many distributions' defaults, where 256 KiB measured as
well as 512). The kernel's send buffer bounds how many bytes are on their way
to a subscriber; a message not yet in the socket stays in the connection's drop-oldest queue,
where a newer one replaces it for free. With the default (autotuned up to 4 MiB) a flooding
topic had ~4 images in the send buffer and ~3 in the subscriber's receive queue, and a rospy
subscriber, which keeps the newest ``queue_size`` of each read, read 2.2 images per image it
handed to its callback (1.05 with this size) while the bridge converted and sent twice the
images it needed to (``bench/bench_ros1.py``, BENCHMARKS.md). A remote subscriber over a
network gets at most this much per round trip (1 MiB / 10 ms: 100 MiB/s)."""


def message_parts(
    payload: bytes | memoryview, *, seq: int | None = None, tail: memoryview | None = None
) -> Parts:
    """One message's buffers: ``payload`` (first 4 bytes replaced by ``seq`` if given), ``tail``.

    Nothing is copied.
    """
    parts: Parts = (
        (payload,)
        if seq is None
        else ((seq & 0xFFFFFFFF).to_bytes(4, "little"), memoryview(payload)[4:])
    )
    return parts if tail is None else (*parts, tail)


class _QuietHandler(SimpleXMLRPCRequestHandler):
    def log_message(self, format: str, *args: Any) -> None:
        _log.debug("xmlrpc: " + format, *args)


class ThreadingXmlRpcServer(socketserver.ThreadingMixIn, SimpleXMLRPCServer):
    """An XML-RPC server answering each request on its own thread."""

    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, addr: tuple[str, int]) -> None:
        super().__init__(addr, requestHandler=_QuietHandler, logRequests=False, allow_none=True)


@dataclass
class _Publication:
    topic: str
    rtype: Ros1Type
    latch: bool
    conns: list[OutConnection] = field(default_factory=list)
    last: Parts | None = None
    messages: int = 0


@dataclass
class _Subscription:
    topic: str
    rtype: Ros1Type
    callback: Callable[[bytearray], None]
    conns: dict[str, InConnection] = field(default_factory=dict)


class Ros1Node:
    """A node of a ROS 1 graph.

    Args:
        name: the node name (``/visnav_bridge``).
        master_uri: the master's URI.
        host: the address peers use to reach this node.
        bind: the address its XML-RPC and TCPROS servers listen on (default: ``host``'s
            own, :func:`~visnav.bridge.master_api.bind_address`; never all interfaces
            unless asked with ``"0.0.0.0"``).
        on_shutdown: called when a peer calls ``shutdown`` (``rosnode kill``).
        on_demand: called with a topic when its number of ROS 1 subscribers changes.

    Attributes:
        on_room: called with a topic (on a connection's thread) when a message of it leaves a
            subscriber's queue to be sent, or a subscriber comes or goes: see :meth:`wants_more`.
    """

    def __init__(
        self,
        name: str,
        *,
        master_uri: str,
        host: str,
        bind: str | None = None,
        on_shutdown: Callable[[str], None] | None = None,
        on_demand: Callable[[str], None] | None = None,
    ) -> None:
        self.name = name if name.startswith("/") else f"/{name}"
        self.host = host
        self.master = MasterClient(master_uri, self.name)
        self._on_shutdown = on_shutdown
        self._on_demand = on_demand
        self.on_room: Callable[[str], None] | None = None
        self._lock = threading.RLock()
        self._pubs: dict[str, _Publication] = {}
        self._subs: dict[str, _Subscription] = {}
        self._services: dict[str, ServedService] = {}
        self._ids = itertools.count(1)
        self._closed = False
        self.bind = bind_address(host) if bind is None else bind
        try:
            self._xmlrpc = ThreadingXmlRpcServer((self.bind, 0))
        except OSError as exc:
            msg = (
                f"the ROS 1 node {self.name} cannot listen on {self.bind} ({exc}): "
                "ROS_IP / ROS_HOSTNAME must name an address of this machine"
            )
            raise BridgeError(msg) from exc
        for method in (
            "getBusStats",
            "getBusInfo",
            "getMasterUri",
            "shutdown",
            "getPid",
            "getSubscriptions",
            "getPublications",
            "paramUpdate",
            "publisherUpdate",
            "requestTopic",
        ):
            self._xmlrpc.register_function(getattr(self, f"_api_{method}"), method)
        self.uri = f"http://{host}:{self._xmlrpc.server_address[1]}/"
        self._tcp = socket.create_server((self.bind, 0))
        self.tcp_port = int(self._tcp.getsockname()[1])
        self._threads = [
            threading.Thread(
                target=self._xmlrpc.serve_forever, args=(0.1,), name="ros1-xmlrpc", daemon=True
            ),
            threading.Thread(target=self._accept_loop, name="ros1-tcpros", daemon=True),
        ]

    def start(self) -> None:
        """Start serving and advertise ``/rosout`` as every rospy node does.

        The ``/rosout`` registration makes the node visible to ``rosnode list`` even while
        it bridges no topic (the master lists nodes by their registrations).

        Raises:
            MasterUnreachableError: no master.
        """
        for t in self._threads:
            t.start()
        self.advertise("/rosout", rosout_type())

    # ------------------------------------------------------------------ topics
    def advertise(self, topic: str, rtype: Ros1Type, *, latch: bool = False) -> None:
        """Register a publication with the master.

        Raises:
            MasterUnreachableError: no master.
            MasterError: the master refused.
        """
        with self._lock:
            if topic in self._pubs:
                return
            self._pubs[topic] = _Publication(topic, rtype, latch)
        try:
            self.master.register_publisher(topic, rtype.ros1_name, self.uri)
        except BridgeError:
            with self._lock:
                self._pubs.pop(topic, None)
            raise

    def unadvertise(self, topic: str) -> None:
        """Unregister a publication and close its connections."""
        with self._lock:
            pub = self._pubs.pop(topic, None)
        if pub is None:
            return
        for conn in list(pub.conns):
            conn.close()
        with contextlib.suppress(BridgeError):
            self.master.unregister_publisher(topic, self.uri)

    def publish(
        self,
        topic: str,
        payload: bytes | memoryview,
        *,
        seq: int | None = None,
        tail: memoryview | None = None,
    ) -> None:
        """Send one message (ROS 1 bytes) to every subscriber of ``topic``.

        Args:
            topic: the topic.
            payload: the message's ROS 1 bytes (not copied: do not change them afterwards).
            seq: when given, sent in place of the first 4 bytes (a leading Header's ``seq``).
            tail: more bytes of the message, sent after ``payload`` without joining them (not
                copied either).
        """
        parts = message_parts(payload, seq=seq, tail=tail)
        with self._lock:
            pub = self._pubs.get(topic)
            if pub is None:
                return
            pub.messages += 1
            if pub.latch:
                pub.last = parts
            conns = list(pub.conns)
        for conn in conns:
            conn.push(parts)

    def publish_deferred(
        self,
        topic: str,
        make: Callable[[], tuple[bytes | memoryview, memoryview | None] | None],
        *,
        seq: int | None = None,
    ) -> bool:
        """Like :meth:`publish`, but the bytes are made only when a connection sends them.

        ``make()`` returns ``(payload, tail)`` as :meth:`publish` takes them, or None when the
        message cannot be converted (it logs why); it runs at most once, on whichever thread
        first sends the message (a connection's thread, or this one when a socket is idle).
        Messages that every subscriber's queue drops before sending are never made.

        Returns:
            :meth:`wants_more` after queueing the message.
        """

        def parts() -> Parts | None:
            made = make()
            return None if made is None else message_parts(made[0], seq=seq, tail=made[1])

        lazy = LazyParts(parts)
        with self._lock:
            pub = self._pubs.get(topic)
            if pub is None:
                return True
            pub.messages += 1
            latch = pub.latch
            conns = list(pub.conns)
        if latch:  # kept for later subscribers: made now
            made = lazy.get()
            with self._lock:
                if made is not None:
                    pub.last = made
        for conn in conns:
            conn.push(lazy)
        return not conns or any(c.queued() < PACE_AHEAD for c in conns)

    def wants_more(self, topic: str) -> bool:
        """Whether a subscriber of ``topic`` has fewer than :data:`PACE_AHEAD` messages queued.

        True also when there is none.

        A sender that stops while this is False must not wait past the next :attr:`on_room`
        call for ``topic``: check again after stopping.
        """
        with self._lock:
            pub = self._pubs.get(topic)
            conns = [] if pub is None else list(pub.conns)
        return not conns or any(c.queued() < PACE_AHEAD for c in conns)

    def can_resume(self, topic: str) -> bool:
        """Whether a subscriber of ``topic`` has :data:`PACE_RESUME` messages queued or fewer.

        True also when there is none. A sender held back by :meth:`wants_more` goes on when
        this is true (checked at each :attr:`on_room` call and right after stopping).
        """
        with self._lock:
            pub = self._pubs.get(topic)
            conns = [] if pub is None else list(pub.conns)
        return not conns or any(c.queued() <= PACE_RESUME for c in conns)

    def _room(self, topic: str) -> None:
        on_room = self.on_room
        if on_room is not None and not self._closed:
            on_room(topic)

    def subscriber_count(self, topic: str) -> int:
        """Number of ROS 1 subscribers connected to our publication of ``topic``."""
        with self._lock:
            pub = self._pubs.get(topic)
            return 0 if pub is None else len(pub.conns)

    def subscribe(self, topic: str, rtype: Ros1Type, callback: Callable[[bytearray], None]) -> None:
        """Register a subscription and connect to the topic's publishers.

        ``callback`` gets each message's ROS 1 bytes on the connection's thread.

        Raises:
            MasterUnreachableError: no master.
            MasterError: the master refused.
        """
        with self._lock:
            if topic in self._subs:
                return
            self._subs[topic] = _Subscription(topic, rtype, callback)
        try:
            uris = self.master.register_subscriber(topic, rtype.ros1_name, self.uri)
        except BridgeError:
            with self._lock:
                self._subs.pop(topic, None)
            raise
        self._update_publishers(topic, uris)

    def unsubscribe(self, topic: str) -> None:
        """Unregister a subscription and close its connections."""
        with self._lock:
            sub = self._subs.pop(topic, None)
        if sub is None:
            return
        for conn in list(sub.conns.values()):
            conn.close()
        with contextlib.suppress(BridgeError):
            self.master.unregister_subscriber(topic, self.uri)

    def publisher_uris(self, topic: str) -> list[str]:
        """Slave URIs of the ROS 1 publishers we read ``topic`` from."""
        with self._lock:
            sub = self._subs.get(topic)
            return [] if sub is None else sorted(sub.conns)

    def _update_publishers(self, topic: str, uris: list[str]) -> None:
        with self._lock:
            sub = self._subs.get(topic)
            if sub is None or self._closed:
                return
            wanted = {u for u in uris if u != self.uri}
            gone = [c for u, c in sub.conns.items() if u not in wanted]
            new: list[InConnection] = []
            for uri in sorted(wanted - set(sub.conns)):
                stats = ConnectionStats(next(self._ids), uri, "i", topic, uri)
                conn = InConnection(
                    topic,
                    sub.rtype,
                    uri,
                    caller_id=self.name,
                    stats=stats,
                    on_message=sub.callback,
                    on_close=self._in_closed,
                )
                sub.conns[uri] = conn
                new.append(conn)
        for conn in gone:
            conn.close()
        for conn in new:
            conn.thread.start()

    def _in_closed(self, conn: InConnection) -> None:
        with self._lock:
            sub = self._subs.get(conn.topic)
            if sub is not None and sub.conns.get(conn.publisher_uri) is conn:
                del sub.conns[conn.publisher_uri]

    # ------------------------------------------------------------------ services
    @property
    def service_uri(self) -> str:
        """``rosrpc://host:port``: where ROS 1 clients call this node's services."""
        return f"rosrpc://{self.host}:{self.tcp_port}"

    def advertise_service(self, name: str, stype: Ros1ServiceType, handler: ServiceHandler) -> None:
        """Serve a service to ROS 1 (``registerService`` at the master).

        ``handler(request_bytes) -> response_bytes`` runs on the caller's connection thread;
        what it raises is the caller's error reply.

        Raises:
            MasterUnreachableError: no master.
            MasterError: the master refused.
        """
        with self._lock:
            if name in self._services:
                return
            self._services[name] = ServedService(name, stype, handler)
        try:
            self.master.register_service(name, self.service_uri, self.uri)
        except BridgeError:
            with self._lock:
                self._services.pop(name, None)
            raise

    def unadvertise_service(self, name: str) -> None:
        """Stop serving a service (``unregisterService``)."""
        with self._lock:
            served = self._services.pop(name, None)
        if served is not None:
            with contextlib.suppress(BridgeError):
                self.master.unregister_service(name, self.service_uri)

    def served_services(self) -> list[str]:
        """Names of the services this node serves to ROS 1."""
        with self._lock:
            return sorted(self._services)

    def service_calls(self, name: str) -> tuple[int, int]:
        """``(calls, failures)`` ROS 1 clients made of a served service."""
        with self._lock:
            served = self._services.get(name)
        return (0, 0) if served is None else (served.calls, served.failures)

    # ------------------------------------------------------------------ TCPROS server
    def _accept_loop(self) -> None:
        while not self._closed:
            try:
                sock, addr = self._tcp.accept()
            except OSError:
                return
            threading.Thread(
                target=self._serve_subscriber,
                args=(sock, f"{addr[0]}:{addr[1]}"),
                name="tcpros-out",
                daemon=True,
            ).start()

    def _refuse(self, sock: socket.socket, text: str, peer: str) -> None:
        _log.warning("refused TCPROS connection from %s: %s", peer, text)
        with contextlib.suppress(OSError):
            sock.sendall(encode_header({"error": text}))
        sock.close()

    def _serve_subscriber(self, sock: socket.socket, addr: str) -> None:
        try:
            sock.settimeout(10.0)
            header = read_header(sock)
        except (TcprosError, OSError) as exc:
            _log.warning("dropped TCPROS connection from %s: %s", addr, exc)
            sock.close()
            return
        if "service" in header and "topic" not in header:
            self._serve_service(sock, header, addr)
            return
        missing = [k for k in ("topic", "md5sum", "callerid") if k not in header]
        if missing:
            self._refuse(sock, f"header from {addr} lacks {', '.join(missing)}", addr)
            return
        topic, peer = header["topic"], header["callerid"]
        with self._lock:
            pub = self._pubs.get(topic)
        if pub is None:
            self._refuse(sock, f"{self.name} does not publish {topic}", peer)
            return
        refusal = md5_mismatch(topic, pub.rtype, header.get("type", "?"), header["md5sum"], peer)
        if refusal:
            self._refuse(sock, refusal, peer)
            return
        if header.get("tcp_nodelay") == "1":
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER_BYTES)
        try:
            sock.sendall(
                encode_header(
                    {
                        "callerid": self.name,
                        "topic": topic,
                        "type": pub.rtype.ros1_name,
                        "md5sum": pub.rtype.md5sum,
                        "message_definition": pub.rtype.definition,
                        "latching": "1" if pub.latch else "0",
                    }
                )
            )
            sock.settimeout(None)
        except OSError as exc:
            _log.warning("dropped TCPROS connection from %s: %s", peer, exc)
            sock.close()
            return
        stats = ConnectionStats(next(self._ids), peer, "o", topic, addr)
        conn = OutConnection(
            sock, stats, on_close=self._out_closed, on_room=functools.partial(self._room, topic)
        )
        with self._lock:
            pub.conns.append(conn)
            if pub.last is not None:
                conn.push(pub.last)
        if self._on_demand is not None:
            self._on_demand(topic)
        self._room(topic)
        conn.run()

    def _serve_service(self, sock: socket.socket, header: dict[str, str], addr: str) -> None:
        name = header["service"]
        peer = header.get("callerid", addr)
        with self._lock:
            served = self._services.get(name)
        if served is None:
            self._refuse(sock, f"{self.name} does not provide service {name}", peer)
            return
        serve_service_connection(sock, header, served, caller_id=self.name, peer=peer)

    def _out_closed(self, conn: OutConnection) -> None:
        with self._lock:
            pub = self._pubs.get(conn.stats.topic)
            if pub is not None and conn in pub.conns:
                pub.conns.remove(conn)
        if self._on_demand is not None and not self._closed:
            self._on_demand(conn.stats.topic)
        self._room(conn.stats.topic)

    # ------------------------------------------------------------------ slave API
    def _all_stats(self) -> list[ConnectionStats]:
        with self._lock:
            out = [c.stats for p in self._pubs.values() for c in p.conns]
            out += [c.stats for s in self._subs.values() for c in s.conns.values()]
        return out

    def _api_getBusInfo(self, caller_id: str) -> list[Any]:  # noqa: N802 - ROS API name
        info = [
            [
                s.conn_id,
                s.peer,
                s.direction,
                "TCPROS",
                s.topic,
                s.connected,
                f"TCPROS connection on port {self.tcp_port} to [{s.endpoint}]",
            ]
            for s in self._all_stats()
        ]
        return [1, "bus info", info]

    def _api_getBusStats(self, caller_id: str) -> list[Any]:  # noqa: N802
        with self._lock:
            pub_stats = [
                [
                    p.topic,
                    sum(c.stats.bytes for c in p.conns),
                    [[c.stats.conn_id, c.stats.bytes, c.stats.messages, True] for c in p.conns],
                ]
                for p in self._pubs.values()
            ]
            sub_stats = [
                [
                    s.topic,
                    [
                        [c.stats.conn_id, c.stats.bytes, c.stats.dropped, True]
                        for c in s.conns.values()
                    ],
                ]
                for s in self._subs.values()
            ]
        return [1, "", [pub_stats, sub_stats, []]]

    def _api_getMasterUri(self, caller_id: str) -> list[Any]:  # noqa: N802
        return [1, "", self.master.uri]

    def _api_shutdown(self, caller_id: str, msg: str = "") -> list[Any]:
        _log.warning("shutdown requested by %s: %s", caller_id, msg)
        if self._on_shutdown is not None:
            threading.Thread(
                target=self._on_shutdown, args=(f"{caller_id}: {msg}",), daemon=True
            ).start()
        return [1, "shutdown", 0]

    def _api_getPid(self, caller_id: str) -> list[Any]:  # noqa: N802
        return [1, "", os.getpid()]

    def _api_getSubscriptions(self, caller_id: str) -> list[Any]:  # noqa: N802
        with self._lock:
            return [1, "subscriptions", [[t, s.rtype.ros1_name] for t, s in self._subs.items()]]

    def _api_getPublications(self, caller_id: str) -> list[Any]:  # noqa: N802
        with self._lock:
            return [1, "publications", [[t, p.rtype.ros1_name] for t, p in self._pubs.items()]]

    def _api_paramUpdate(self, caller_id: str, key: str, value: Any) -> list[Any]:  # noqa: N802
        return [1, "", 0]

    def _api_publisherUpdate(  # noqa: N802
        self, caller_id: str, topic: str, publishers: list[str]
    ) -> list[Any]:
        threading.Thread(
            target=self._update_publishers, args=(topic, list(publishers)), daemon=True
        ).start()
        return [1, "", 0]

    def _api_requestTopic(  # noqa: N802
        self, caller_id: str, topic: str, protocols: list[Any]
    ) -> list[Any]:
        with self._lock:
            if topic not in self._pubs:
                return [-1, f"{self.name} does not publish {topic}", []]
        if not any(isinstance(p, list) and p and p[0] == "TCPROS" for p in protocols):
            return [0, "no supported protocol: visnav speaks TCPROS only", []]
        return [1, f"ready on {self.host}:{self.tcp_port}", ["TCPROS", self.host, self.tcp_port]]

    # ------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        """Unregister everything from the master and close every connection (idempotent)."""
        with self._lock:
            if self._closed:
                return
            topics_out = list(self._pubs)
            topics_in = list(self._subs)
            services = list(self._services)
        for name in services:
            self.unadvertise_service(name)
        for topic in topics_out:
            self.unadvertise(topic)
        for topic in topics_in:
            self.unsubscribe(topic)
        with self._lock:
            self._closed = True
        with contextlib.suppress(OSError):
            self._tcp.shutdown(socket.SHUT_RDWR)
        self._tcp.close()
        if self._threads[0].is_alive():
            self._xmlrpc.shutdown()
        self._xmlrpc.server_close()
