"""Subscriptions: one message type on one topic, with the QoS queue the executor serves.

Each subscription holds its own pending messages in a queue sized by its QoS
history: keep-last(N) keeps the newest N and drops the oldest when a new one
arrives (counted in :attr:`Subscription.dropped`); keep-all keeps every message.
The executor (:class:`~visnav.graph.Context`) takes one message per turn from
each subscription that has any, round-robin (see its module docstring).

Remote samples are queued as undecoded CDR bytes and deserialized only when
their callback runs, so samples that keep-last drops cost nothing.
"""

from __future__ import annotations

import functools
import inspect
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Generic, TypeVar

from zenoh import ZBytes

from visnav.graph.message_info import MessageInfo, decode_attachment
from visnav.graph.qos import DurabilityPolicy, QoSProfile
from visnav.msgs.serde import deserialize, msg_type_name

if TYPE_CHECKING:
    from visnav.graph.node import Node

__all__ = ["RemotePayload", "Subscription"]

MsgT = TypeVar("MsgT")
RemotePayload = ZBytes | bytes
"""A remote sample's CDR bytes as the transport hands them over (copied out when taken)."""


class Subscription(Generic[MsgT]):
    """Receives one message type on one topic; made by :meth:`Node.create_subscription`."""

    def __init__(
        self,
        node: Node,
        msg_type: type[MsgT],
        topic_name: str,
        callback: Callable[[MsgT], Any] | Callable[[MsgT, MessageInfo], Any],
        qos: QoSProfile,
    ) -> None:
        self.node = node
        self.msg_type = msg_type
        self.type_name = msg_type_name(msg_type)
        self.topic_name = topic_name
        self.callback = callback
        self.qos = qos
        self.entity_id = node.context.next_id()
        # (message or undecoded remote payload, info, whether it is a remote payload)
        self.queue: deque[tuple[Any, MessageInfo | None, bool]] = deque(maxlen=qos.queue_limit)
        self.wants_history = qos.durability is DurabilityPolicy.TRANSIENT_LOCAL
        self.wants_info = _takes_two_args(callback)
        self._zsub: Any = None
        self._zkey: str | None = None
        self._latest_seq: dict[tuple[str, int], int] = {}
        self._seq_lock = threading.Lock()
        self.dropped = 0
        """Messages keep-last dropped from the queue before their callback ran."""

    def describe(self) -> str:
        """``subscription on '/topic' (pkg/msg/Type)`` (for logs)."""
        return f"subscription on '{self.topic_name}' ({self.type_name})"

    def enqueue(self, msg: MsgT, info: MessageInfo | None = None) -> None:
        """Queue a message (keep-last drops the oldest, counted in :attr:`dropped`)."""
        queue = self.queue
        if len(queue) == queue.maxlen:
            self.dropped += 1
        queue.append((msg, info, False))

    def enqueue_remote(self, payload: RemotePayload, info: MessageInfo | None = None) -> None:
        """Queue an undecoded remote payload (keep-last drops the oldest, never decoded)."""
        queue = self.queue
        if len(queue) == queue.maxlen:
            self.dropped += 1
        queue.append((payload, info, True))

    def pending(self) -> bool:
        """Whether messages wait in the queue."""
        return bool(self.queue)

    def take_call(self) -> Callable[[], None] | None:
        """Pop the oldest queued message as a ready-to-run callback, or None.

        A remote payload is copied out of the transport and deserialized when the
        callback runs (outside the context's lock), so samples that keep-last drops
        cost nothing and each callback gets its own message.
        """
        if not self.queue:
            return None
        item, info, remote = self.queue.popleft()
        cb: Any = self.callback
        if remote:
            return functools.partial(self._run_remote, item, info)
        if self.wants_info:
            return lambda: cb(item, info)
        return lambda: cb(item)

    def _run_remote(self, payload: RemotePayload, info: MessageInfo | None) -> None:
        data = _as_bytes(payload)
        try:
            # a memoryview: rosbags slices off the CDR header, and slicing bytes would copy
            # (and page-fault) the whole payload once more. The message's arrays are views
            # on ``data``, a fresh buffer that only this message holds.
            msg = deserialize(memoryview(data), self.type_name)
        except ValueError as exc:
            self.node.get_logger().warning(f"dropped a sample on '{self.topic_name}': {exc}")
            return
        cb: Any = self.callback
        if self.wants_info:
            cb(msg, info)
        else:
            cb(msg)

    def on_remote(self, payload: RemotePayload, attachment: RemotePayload | None) -> None:
        """Queue a remote sample for the executor (runs on a transport thread).

        Only the small attachment is read here (for :class:`MessageInfo` and latched
        de-duplication); the payload stays in the transport's buffer until taken.
        """
        info = None
        if self.wants_info or self.wants_history:
            received_ns = time.time_ns()
            att = None if attachment is None else _as_bytes(attachment)
            info = decode_attachment(att, received_ns)
        if self.wants_history and info is not None:
            # latched samples may arrive twice (live and from a cache query): keep each once
            source = (info.publisher_zid, info.publisher_entity_id)
            with self._seq_lock:
                if info.publication_sequence_number <= self._latest_seq.get(source, 0):
                    return
                self._latest_seq[source] = info.publication_sequence_number
        self.node.context.deliver_remote(self, payload, info if self.wants_info else None)

    def on_remote_publisher(self, zid: str) -> None:
        """A transient-local publisher appeared in another session: fetch its cache."""
        z = self.node.context.zenoh
        if z is not None and self._zkey is not None and self._zsub is not None:
            z.fetch_latched(self._zkey, self.on_remote, zid)

    def destroy(self) -> None:
        """Remove the subscription."""
        self.node.destroy_subscription(self)


def _as_bytes(payload: RemotePayload) -> bytes:
    """Copy a transport buffer out into a new ``bytes`` (no copy if it already is one)."""
    return payload if isinstance(payload, bytes) else payload.to_bytes()


def _takes_two_args(callback: Callable[..., Any]) -> bool:
    try:
        params = inspect.signature(callback).parameters.values()
    except (TypeError, ValueError):
        return False
    positional = [
        p
        for p in params
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.default is p.empty
    ]
    return len(positional) >= 2 or any(p.kind is p.VAR_POSITIONAL for p in params)
