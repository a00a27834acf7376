"""One TCPROS connection each way: a subscriber we send to, a publisher we read from.

Each connection has its own thread, so a slow or broken peer holds up nobody else. An outgoing
connection keeps a small queue and drops the oldest message when the peer cannot keep up
(roscpp's ``queue_size``); an incoming one hands every message to a callback.

A queued message may be a :class:`LazyParts`: its bytes are made (converted, copied out of
the visnav transport) only when a connection is about to send it, once for all connections,
so messages the queues drop while a publisher floods cost no conversion.
"""

from __future__ import annotations

import contextlib
import logging
import socket
import struct
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from visnav.bridge.errors import BridgeError, TcprosError
from visnav.bridge.master_api import xmlrpc_proxy
from visnav.bridge.tcpros import encode_header, read_frame, read_header
from visnav.bridge.typemap import Ros1Type, ros1_type

__all__ = [
    "ConnectionStats",
    "framed",
    "send_views",
    "InConnection",
    "LazyParts",
    "OutConnection",
    "Parts",
    "md5_mismatch",
    "send_parts",
]

_log = logging.getLogger("visnav.bridge")
_U32 = struct.Struct("<I")


@dataclass
class ConnectionStats:
    """What ``getBusInfo``/``getBusStats`` report of one connection."""

    conn_id: int
    peer: str
    direction: str
    topic: str
    endpoint: str
    messages: int = 0
    bytes: int = 0
    dropped: int = 0
    connected: bool = True
    opened: float = field(default_factory=time.monotonic)


def md5_mismatch(topic: str, ours: Ros1Type, their_type: str, their_md5: str, peer: str) -> str:
    """The refusal text of ROS 1 for a connection whose md5sum differs ('' when they match)."""
    if "*" in (their_md5, ours.md5sum) or their_md5 == ours.md5sum:
        return ""
    return (
        f"{peer} wants topic {topic} to have datatype/md5sum [{their_type}/{their_md5}], "
        f"but visnav's version has [{ours.ros1_name}/{ours.md5sum}]; connection refused "
        "(both sides must build the same message definition)"
    )


Parts = tuple[bytes | memoryview, ...]
"""One message as buffers sent back to back (no copy to join them)."""


class LazyParts:
    """One message's :data:`Parts`, made on first use and shared by every connection.

    Args:
        make: returns the parts, or None when the message cannot be converted (it is then
            skipped; ``make`` logs why). Called once, by the first connection that sends.
    """

    __slots__ = ("_lock", "_made", "_make", "_parts")

    def __init__(self, make: Callable[[], Parts | None]) -> None:
        self._make: Callable[[], Parts | None] | None = make
        self._parts: Parts | None = None
        self._made = False
        self._lock = threading.Lock()

    def get(self) -> Parts | None:
        """The parts (made now if no connection needed them before)."""
        with self._lock:
            if not self._made:
                make, self._make = self._make, None
                self._parts = make() if make is not None else None
                self._made = True
            return self._parts


def framed(parts: Parts) -> list[memoryview]:
    """The buffers of one frame: the 4-byte length, then ``parts`` (no copy)."""
    views = [memoryview(p).cast("B") for p in parts]
    views.insert(0, memoryview(_U32.pack(sum(v.nbytes for v in views))))
    return views


def send_views(sock: socket.socket, views: list[memoryview], *, wait: bool = True) -> int:
    """Send buffers back to back, as few system calls as possible; ``views`` is consumed.

    With ``wait=False`` it stops when the socket buffer is full and leaves the rest in
    ``views``.

    Returns:
        The bytes sent.
    """
    flags = 0 if wait else socket.MSG_DONTWAIT
    total = 0
    while views:
        try:
            sent = sock.sendmsg(views, (), flags)
        except BlockingIOError:
            return total
        total += sent
        while views and sent >= views[0].nbytes:
            sent -= views[0].nbytes
            views.pop(0)
        if views and sent:
            views[0] = views[0][sent:]
    return total


def send_parts(sock: socket.socket, parts: Parts) -> int:
    """Send one frame (length prefix, then ``parts``); return the bytes sent."""
    return send_views(sock, framed(parts))


class OutConnection:
    """A subscriber connected to one of our publications.

    A message is sent at once by the publishing thread when nothing is queued and the socket
    takes it without blocking (one thread hop less); otherwise it is queued, and its own
    thread sends the queue in order. When the queue is full the oldest whole message is
    dropped; a message the socket took in part is never dropped (its rest is kept apart from
    the queue), so the byte stream always stays in frames.

    Args:
        sock: the accepted socket, handshake done.
        stats: its statistics entry.
        queue_size: messages kept while the peer is slow (oldest dropped).
        on_close: called once when the connection ends.
        on_room: called (on the connection's thread) each time a message leaves the queue
            to be sent: a publisher that holds messages back while every queue has some
            (:meth:`queued`) can send more.
    """

    def __init__(
        self,
        sock: socket.socket,
        stats: ConnectionStats,
        *,
        queue_size: int = 10,
        on_close: Callable[[OutConnection], None],
        on_room: Callable[[], None] | None = None,
    ) -> None:
        self.sock = sock
        self.stats = stats
        self._queue: deque[list[memoryview] | LazyParts] = deque(maxlen=max(1, queue_size))
        self._rest: list[memoryview] = []  # the unsent end of a frame already started
        self._cond = threading.Condition()
        self._closed = False
        self._busy = False
        self._on_close = on_close
        self._on_room = on_room

    def queued(self) -> int:
        """Messages waiting behind the one being sent."""
        return len(self._queue)

    def push(self, payload: Parts | LazyParts) -> None:
        """Send or queue one message (ROS 1 bytes in parts, or parts made when sent)."""
        item: list[memoryview] | LazyParts = (
            payload if isinstance(payload, LazyParts) else framed(payload)
        )
        with self._cond:
            if self._closed:
                return
            if self._queue or self._busy or self._rest:
                if len(self._queue) == self._queue.maxlen:
                    self.stats.dropped += 1
                self._queue.append(item)
                self._cond.notify()
                return
            self._busy = True
        if isinstance(item, LazyParts):
            parts = item.get()  # sent at once: the socket is idle
            views = [] if parts is None else framed(parts)
        else:
            views = item
        if not views:
            with self._cond:
                self._busy = False
                self._cond.notify()
            return
        try:
            sent = send_views(self.sock, views, wait=False)
        except OSError:
            sent = 0
            views = []
            self._closed = True
        with self._cond:
            self._busy = False
            self.stats.bytes += sent
            if views:  # the socket is full: the rest goes first, from the sender thread
                self._rest = views
            else:
                self.stats.messages += 1
            self._cond.notify()

    def run(self) -> None:
        """Send queued messages until closed or the peer goes away."""
        try:
            while True:
                with self._cond:
                    while (self._busy or not (self._rest or self._queue)) and not self._closed:
                        self._cond.wait()
                    if self._closed:
                        return
                    item: list[memoryview] | LazyParts
                    room = False
                    if self._rest:
                        item, self._rest = self._rest, []
                    else:
                        item = self._queue.popleft()
                        room = True
                    self._busy = True
                if room and self._on_room is not None:
                    self._on_room()
                try:
                    if isinstance(item, LazyParts):
                        parts = item.get()
                        views = [] if parts is None else framed(parts)
                    else:
                        views = item
                    sent = send_views(self.sock, views) if views else 0
                    self.stats.bytes += sent
                finally:
                    with self._cond:
                        self._busy = False
                if sent:
                    self.stats.messages += 1
        except OSError as exc:
            if not self._closed:
                _log.info(
                    "ROS 1 subscriber %s of %s went away: %s",
                    self.stats.peer,
                    self.stats.topic,
                    exc,
                )
        finally:
            self.close()

    def close(self) -> None:
        """End the connection (idempotent)."""
        with self._cond:
            if self._closed and not self.stats.connected:
                return
            self._closed = True
            self.stats.connected = False
            self._cond.notify_all()
        with contextlib.suppress(OSError):
            self.sock.shutdown(socket.SHUT_RDWR)
        self.sock.close()
        self._on_close(self)


class InConnection:
    """Reads one ROS 1 publisher of a topic we subscribe to, from its own thread.

    Args:
        topic: the topic.
        rtype: the type visnav expects.
        publisher_uri: the publisher's slave API URI.
        caller_id: our node name.
        stats: its statistics entry.
        on_message: called with each message's ROS 1 bytes (on this thread).
        on_close: called once when the connection ends.
    """

    def __init__(
        self,
        topic: str,
        rtype: Ros1Type,
        publisher_uri: str,
        *,
        caller_id: str,
        stats: ConnectionStats,
        on_message: Callable[[bytearray], None],
        on_close: Callable[[InConnection], None],
    ) -> None:
        self.topic = topic
        self.rtype = rtype
        self.publisher_uri = publisher_uri
        self.caller_id = caller_id
        self.stats = stats
        self._on_message = on_message
        self._on_close = on_close
        self._sock: socket.socket | None = None
        self._closed = False
        self._lock = threading.Lock()
        self.thread = threading.Thread(target=self.run, name=f"tcpros-in {topic}", daemon=True)

    def _connect(self) -> socket.socket:
        proxy = xmlrpc_proxy(self.publisher_uri, timeout_s=5.0)
        reply: Any = proxy.requestTopic(self.caller_id, self.topic, [["TCPROS"]])
        try:
            code, text, proto = reply
            if code != 1 or proto[0] != "TCPROS":
                msg = f"publisher {self.publisher_uri} refused {self.topic}: {text}"
                raise TcprosError(msg)
            host, port = str(proto[1]), int(proto[2])
        except (TypeError, ValueError, IndexError) as exc:
            msg = f"publisher {self.publisher_uri} answered requestTopic with {reply!r}"
            raise TcprosError(msg) from exc
        sock = socket.create_connection((host, port), timeout=5.0)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        return sock

    def _their_type(self) -> str:
        """The publisher's type of the topic and its md5sum, asked from its slave API."""
        try:
            proxy = xmlrpc_proxy(self.publisher_uri, timeout_s=2.0)
            reply: Any = proxy.getPublications(self.caller_id)
            pubs = reply[2]
            their = next(str(ty) for t, ty in pubs if t == self.topic)
        except Exception:  # noqa: BLE001 - only for the message: any failure means "unknown"
            return "its type is unknown"
        try:
            md5 = ros1_type(their).md5sum
        except BridgeError:
            md5 = "unknown to visnav"
        return f"it publishes {their} md5sum {md5}"

    def _handshake(self, sock: socket.socket) -> None:
        sock.sendall(
            encode_header(
                {
                    "callerid": self.caller_id,
                    "topic": self.topic,
                    "type": self.rtype.ros1_name,
                    "md5sum": self.rtype.md5sum,
                    "message_definition": self.rtype.definition,
                    "tcp_nodelay": "1",
                }
            )
        )
        header = read_header(sock)
        if "error" in header:
            msg = (
                f"ROS 1 publisher {self.publisher_uri} refused {self.topic}: {header['error']} "
                f"({self._their_type()}; visnav's is {self.rtype.ros1_name} "
                f"md5sum {self.rtype.md5sum})"
            )
            raise TcprosError(msg)
        missing = [k for k in ("md5sum", "type") if k not in header]
        if missing:
            msg = (
                f"ROS 1 publisher {self.publisher_uri} of {self.topic} sent a header without "
                f"{' and '.join(missing)} (fields: {', '.join(sorted(header))})"
            )
            raise TcprosError(msg)
        peer = header.get("callerid", self.publisher_uri)
        self.stats.peer = peer
        refusal = md5_mismatch(self.topic, self.rtype, header["type"], header["md5sum"], peer)
        if refusal:
            raise TcprosError(refusal)

    def run(self) -> None:
        """Connect, handshake and read messages until closed; log why it ended."""
        try:
            sock = self._connect()
            with self._lock:
                if self._closed:
                    sock.close()
                    return
                self._sock = sock
            self._handshake(sock)
            sock.settimeout(None)
            while not self._closed:
                payload = read_frame(sock)
                self.stats.messages += 1
                self.stats.bytes += len(payload) + 4
                self._on_message(payload)
        except (TcprosError, OSError, ValueError) as exc:
            if self._closed:
                pass
            elif str(exc).startswith("peer closed the connection after 0 of 4 bytes"):
                # between two messages: the publisher left (a rospy node exiting), no fault
                _log.info("ROS 1 publisher %s of %s left", self.stats.peer, self.topic)
            else:
                _log.warning("dropped ROS 1 connection on %s: %s", self.topic, exc)
        except Exception as exc:  # noqa: BLE001 - xmlrpc faults etc.: the connection ends, not the bridge
            if not self._closed:
                _log.warning("dropped ROS 1 connection on %s: %r", self.topic, exc)
        finally:
            self.close()

    def close(self) -> None:
        """End the connection (idempotent)."""
        with self._lock:
            first = self.stats.connected
            self._closed = True
            self.stats.connected = False
            sock = self._sock
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
            sock.close()
        if first:
            self._on_close(self)
