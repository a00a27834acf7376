"""Subscriptions: one message type on one topic, with the QoS queue the executor serves.

Each subscription holds its own pending messages in a queue sized by its QoS
history: keep-last(N) keeps the newest N and drops the oldest when a new one
arrives (counted in :attr:`Subscription.dropped`); keep-all keeps every message.
The executor (:class:`~visnav.graph.Context`) takes one message per turn from
each subscription that has any, round-robin (see its module docstring).

Remote samples are queued as undecoded CDR bytes and deserialized only when
their callback runs, so samples that keep-last drops cost nothing.

A *raw* subscription (``raw=True``, rclpy's name) hands its callback a
:class:`SerializedMessage` instead of a message: the CDR bytes of a remote sample
stay in the transport's buffer (for large payloads, the sender's shared memory)
until the callback asks for them, so a consumer that queues messages further on
(the ROS 1 bridge's per-connection queues) copies only those it really sends.

A *paced* subscription (``paced=True``, keep-last and volatile only) keeps its
queue of remote samples inside Zenoh (a ring buffer of ``depth`` samples): a
sample crosses into Python only when the executor has taken the previous one,
so while a publisher floods, the samples keep-last drops cost no Python code at
all (no callback, no thread hand-off). :meth:`Subscription.pause` stops taking
samples (the ring keeps the newest ``depth``) until :meth:`Subscription.resume`:
a consumer that forwards messages can take them only as fast as it passes them
on. It costs one thread per paced subscription; its :class:`MessageInfo`'s
``received_timestamp_ns`` is when a sample left the ring, and :attr:`Subscription.dropped`
counts the gaps in each publisher's sequence numbers. rclpy has no paced mode: there
the middleware's queue (rmw_zenoh's, in C++) is what makes drops cheap.

A paced subscription also tells the publishers of its topic when it pauses and resumes
(:mod:`visnav.graph.transport_pace`): a volatile keep-last publisher whose remote
subscriptions are all paused skips its samples (no serialization, no transfer), as a
ROS 1 publisher's per-subscriber queue drops what the subscriber's socket does not take.
While paused the ring then holds the samples sent before the publishers heard of the
pause, not the newest ones; the skipped samples count in :attr:`Subscription.dropped`.
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

from visnav.graph.errors import GraphError
from visnav.graph.message_info import MessageInfo, decode_attachment
from visnav.graph.qos import DurabilityPolicy, QoSProfile
from visnav.graph.transport import ZenohTransport, detach_small
from visnav.graph.transport_pace import PaceReporter
from visnav.msgs.serde import CdrSerializer, deserialize, msg_type_name

if TYPE_CHECKING:
    from visnav.graph.node import Node

__all__ = ["RemotePayload", "SerializedMessage", "Subscription"]

MsgT = TypeVar("MsgT")
RemotePayload = ZBytes | bytes
"""A remote sample's CDR bytes as the transport hands them over (copied out when taken)."""


class SerializedMessage:
    """One message's CDR bytes, copied out of the transport only when asked.

    What a ``raw=True`` subscription's callback gets (rclpy passes ``bytes`` there;
    visnav passes this so that a message that is never read is never copied). It may
    be kept after the callback returns and read from any thread. Holding one holds
    the transport's buffer (for a large remote payload, a chunk of the sender's
    shared-memory pool): keep only a few.

    Args:
        payload: CDR bytes (with the encapsulation header) as the transport handed them.
        type_name: the message type, e.g. ``sensor_msgs/msg/Image``.
    """

    __slots__ = ("_data", "_payload", "type_name")

    def __init__(self, payload: RemotePayload, type_name: str) -> None:
        self._payload: RemotePayload | None = payload
        self._data: bytes | None = payload if isinstance(payload, bytes) else None
        self.type_name = type_name

    def __len__(self) -> int:
        """Size of the CDR bytes (no copy)."""
        data = self._data
        if data is not None:
            return len(data)
        return len(self._payload) if self._payload is not None else 0

    def to_bytes(self) -> bytes:
        """The CDR bytes, copied out of the transport on the first call only."""
        data = self._data
        if data is None:
            payload = self._payload
            data = _as_bytes(payload) if payload is not None else b""
            self._data, self._payload = data, None  # release the transport's buffer
        return data

    def deserialize(self) -> Any:
        """The message; its arrays are views on :meth:`to_bytes` (no second copy).

        Raises:
            MessageError: the bytes do not decode as :attr:`type_name`.
        """
        return deserialize(memoryview(self.to_bytes()), self.type_name)


class Subscription(Generic[MsgT]):
    """Receives one message type on one topic; made by :meth:`Node.create_subscription`."""

    def __init__(
        self,
        node: Node,
        msg_type: type[MsgT],
        topic_name: str,
        callback: Callable[[MsgT], Any] | Callable[[MsgT, MessageInfo], Any],
        qos: QoSProfile,
        *,
        raw: bool = False,
        paced: bool = False,
    ) -> None:
        if paced and (
            qos.queue_limit is None or qos.durability is DurabilityPolicy.TRANSIENT_LOCAL
        ):
            msg = (
                f"subscription on '{topic_name}': paced=True needs a keep-last volatile QoS, "
                f"got {qos.short()}; drop paced=True or use QoSProfile(depth=N)"
            )
            raise GraphError(msg)
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
        self.raw = raw
        """The callback gets a :class:`SerializedMessage` (rclpy's ``raw=True``)."""
        self._serializer: CdrSerializer | None = None
        self.paced = paced
        """Remote samples wait in Zenoh and cross into Python one at a time (see module doc)."""
        self._want = threading.Event()  # the pump may take the next sample from Zenoh
        self._want.set()
        self._paused = False
        self._stopped = False
        self._pump: threading.Thread | None = None
        self._reporter: PaceReporter | None = None
        self._zsub: Any = None
        self._zkey: str | None = None
        self._latest_seq: dict[tuple[str, int], int] = {}
        self._seq_lock = threading.Lock()
        self.dropped = 0
        """Messages keep-last dropped from the queue before their callback ran (for a paced
        subscription: the gaps in its publishers' sequence numbers, which also counts
        samples the transport lost)."""

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
        if self.paced and not self.queue and not self._paused:
            self._want.set()
        cb: Any = self.callback
        if remote:
            return functools.partial(self._run_remote, item, info)
        if self.raw:
            return functools.partial(self._run_local_raw, item, info)
        if self.wants_info:
            return lambda: cb(item, info)
        return lambda: cb(item)

    def _run_local_raw(self, msg: Any, info: MessageInfo | None) -> None:
        """An in-process message to a raw callback: serialized now (its publisher may reuse it)."""
        if self._serializer is None:
            self._serializer = CdrSerializer(self.type_name)
        self._call(SerializedMessage(bytes(self._serializer.serialize(msg)), self.type_name), info)

    def _call(self, msg: Any, info: MessageInfo | None) -> None:
        cb: Any = self.callback
        if self.wants_info:
            cb(msg, info)
        else:
            cb(msg)

    def _run_remote(self, payload: RemotePayload, info: MessageInfo | None) -> None:
        if self.raw:
            self._call(SerializedMessage(payload, self.type_name), info)
            return
        data = _as_bytes(payload)
        try:
            # a memoryview: rosbags slices off the CDR header, and slicing bytes would copy
            # (and page-fault) the whole payload once more. The message's arrays are views
            # on ``data``, a fresh buffer that only this message holds.
            msg = deserialize(memoryview(data), self.type_name)
        except ValueError as exc:
            self.node.get_logger().warning(f"dropped a sample on '{self.topic_name}': {exc}")
            return
        self._call(msg, info)

    def attach_transport(self, z: ZenohTransport, key: str) -> None:
        """Subscribe to remote samples on ``key`` (called by :meth:`Node.create_subscription`)."""
        self._zkey = key
        if not self.paced:
            self._zsub = z.subscriber(key, self.on_remote, history=self.wants_history)
            return
        self._zsub = z.ring_subscriber(key, self.qos.queue_limit or 1)
        self._reporter = z.pace_reporter(key, self.entity_id, lambda: not self._paused)
        self._pump = threading.Thread(
            target=self._pump_loop,
            args=(self._zsub.handler,),
            name=f"visnav-pump {self.topic_name}",
            daemon=True,
        )
        self._pump.start()

    def _pump_loop(self, handler: Any) -> None:
        """Move one sample at a time from Zenoh's ring into the queue (paced subscriptions)."""
        while True:
            while not self._want.wait(1.0):
                if self._stopped:
                    return
            if self._stopped:
                return
            try:
                sample = handler.recv()  # blocks without the GIL
            except Exception:  # noqa: BLE001 - zenoh.ZError: undeclared or session closed
                return
            self._want.clear()
            if self._stopped:
                return
            self.on_remote(detach_small(sample.payload), sample.attachment)

    def pause(self) -> None:
        """Stop taking remote samples; Zenoh keeps the newest ``depth`` (paced only).

        A sample the subscription was already waiting for when paused may still arrive.

        Raises:
            GraphError: the subscription is not paced.
        """
        self._check_paced("pause")
        self._paused = True
        self._want.clear()
        self._report()

    def resume(self) -> None:
        """Take remote samples again after :meth:`pause` (paced only).

        Raises:
            GraphError: the subscription is not paced.
        """
        self._check_paced("resume")
        self._paused = False
        if not self.queue:
            self._want.set()
        self._report()

    def _report(self) -> None:
        """Tell the topic's publishers whether this subscription takes samples now."""
        reporter = self._reporter
        if reporter is not None:
            reporter.report()

    @property
    def paused(self) -> bool:
        """Whether :meth:`pause` holds remote samples back."""
        return self._paused

    def _check_paced(self, what: str) -> None:
        if not self.paced:
            msg = (
                f"{self.describe()}: {what}() needs a paced subscription; create it with "
                "create_subscription(..., paced=True)"
            )
            raise GraphError(msg)

    def stop(self) -> None:
        """End the pump thread of a paced subscription (called when it is destroyed)."""
        self._stopped = True
        self._want.set()
        if self._reporter is not None:
            self._reporter.close()

    def on_remote(self, payload: RemotePayload, attachment: RemotePayload | None) -> None:
        """Queue a remote sample for the executor (runs on a transport thread).

        Only the small attachment is read here (for :class:`MessageInfo` and latched
        de-duplication); the payload stays in the transport's buffer until taken.
        """
        info = None
        if self.wants_info or self.wants_history or self.paced:
            received_ns = time.time_ns()
            att = None if attachment is None else _as_bytes(attachment)
            info = decode_attachment(att, received_ns)
        if self.paced and info is not None:
            # Zenoh's ring drops silently: count the gaps in each publisher's numbering
            source = (info.publisher_zid, info.publisher_entity_id)
            last = self._latest_seq.get(source)
            if last is not None and info.publication_sequence_number > last + 1:
                self.dropped += info.publication_sequence_number - last - 1
            self._latest_seq[source] = info.publication_sequence_number
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
