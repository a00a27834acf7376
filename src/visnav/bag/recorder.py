"""Record topics of a live graph into a bag (``ros2 bag record``).

The recorder is a node in the caller's :class:`~visnav.graph.Context`: its callbacks run in
that context's executor, so the caller spins the context (``ctx.spin()``) while recording.
It subscribes to the chosen topics (or every topic with ``all``) as soon as a publisher
announces them, with a QoS compatible with every publisher, and stores the profiles the
publishers offered.

No silent loss: the subscriptions are raw (``raw=True``: a message from another process
is never deserialized, its CDR bytes are copied out of the transport once, as ``ros2 bag
record`` takes serialized messages) and a callback only hands the bytes to a writer thread
(:mod:`visnav.bag.write_queue`), which compresses and writes, so the executor never waits
for bz2 or the disk. The subscription queues are deeper than the publishers' (keep-last
1000, 100 for images and clouds; ``rosbag record`` subscribes with 100) so that a busy
executor does not lose small high-rate topics such as ``/clock``. What is lost anyway (a
subscription queue overflowed, or the writer fell ``buffer_bytes`` behind) is counted per
topic (:meth:`BagRecorder.drops`), stored in the bag (:mod:`visnav.bag.metadata`) and shown
by ``bag record`` and ``bag info``.

Timestamps are receive times (what ROS 2 records): the wall clock when the message reached
this process, or, with ``use_sim_time=True``, the ``/clock`` time at the callback
(0 before the first ``/clock`` message, as in ROS 2). A flush every ``flush_period_s``
(0.5 s) puts the open chunk into the file, so a killed recorder loses at most that much.
A write error (disk full, file size limit) stops the recording: :attr:`BagRecorder.error`
is set, and :meth:`BagRecorder.stop` closes the bag and raises :class:`RecordError`.

With ``image_transport=ImageCompression()`` the camera images are stored as image_transport's
compressed transports publish them: a ``sensor_msgs/Image`` topic ``T`` becomes ``T/compressed``
(JPEG) or, for depth, ``T/compressedDepth`` (PNG), of type ``sensor_msgs/CompressedImage``
(:mod:`visnav.bag.image_compression`), chosen from the first message; the compression runs on
the writer thread. ``rosbag record`` stores what is published, so a ROS user records the
``/compressed`` topics the camera driver publishes; visnav's simulated cameras publish raw
images only, and the recorder makes the same messages itself.
"""

from __future__ import annotations

import dataclasses
import errno
import logging
import re
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from visnav.bag.errors import BagError, RecordError
from visnav.bag.image_compression import IMAGE, ImageCompression
from visnav.bag.qos import endpoint_qos
from visnav.bag.storage import check_format
from visnav.bag.write_queue import DEFAULT_BUFFER_BYTES, WriteQueue
from visnav.bag.writer import BagWriter, default_bag_path
from visnav.errors import VisnavError
from visnav.graph.clock import Clock, ClockType
from visnav.graph.context import Context
from visnav.graph.introspect import new_published_topics, subscription_qos_for
from visnav.graph.message_info import MessageInfo
from visnav.graph.names import is_hidden_name
from visnav.graph.node import Node, Subscription, Timer
from visnav.graph.qos import HistoryPolicy
from visnav.graph.subscription import SerializedMessage
from visnav.msgs.serde import get_message_class

__all__ = ["BagRecorder", "RecordedTopic", "compile_exclude"]

_LOG = logging.getLogger("visnav.bag")

RECORD_DEPTH = 1000
"""Keep-last depth of the recorder's subscriptions (a busy executor loses nothing small)."""
LARGE_RECORD_DEPTH = 100
"""The depth for image and cloud topics (``rosbag record``'s queue size)."""
_LARGE_TYPES = frozenset(
    {
        "sensor_msgs/msg/Image",
        "sensor_msgs/msg/CompressedImage",
        "sensor_msgs/msg/PointCloud2",
        "stereo_msgs/msg/DisparityImage",
    }
)


def compile_exclude(pattern: str | None) -> re.Pattern[str] | None:
    """Compile the ``--exclude`` regular expression.

    Raises:
        RecordError: the pattern is not a regular expression (names the pattern and error).
    """
    if not pattern:
        return None
    try:
        return re.compile(pattern)
    except re.error as exc:
        msg = (
            f"--exclude {pattern!r} is not a regular expression ({exc}): fix the pattern "
            "(escape a literal '(' '[' '*' '+' '?' with a backslash)"
        )
        raise RecordError(msg) from exc


@dataclasses.dataclass
class RecordedTopic:
    """A topic being recorded.

    Attributes:
        name: topic name.
        type_name: message type.
        count: messages received and handed to the writer.
        qos: the subscription's QoS (short form).
        buffer_drops: messages dropped because the writer was ``buffer_bytes`` behind
            (or had failed).
    """

    name: str
    type_name: str
    count: int = 0
    qos: str = ""
    buffer_drops: int = 0


class BagRecorder:
    """Record topics of ``context``'s graph into a bag.

    Args:
        context: the graph context (its executor runs the recorder's callbacks).
        topics: topic names to record, or None for every topic (``-a``); named topics that
            have no publisher yet are subscribed when one appears.
        path: output bag (directory for ``mcap``, ``.bag`` file for ``ros1``).
        fmt: ``"mcap"`` (rosbag2, default) or ``"ros1"``.
        compression: ``"none"`` (default), ``"zstd"``/``"lz4"`` (MCAP), ``"lz4"``/``"bz2"`` (ROS 1).
        exclude: with all topics, a regular expression of topic names to leave out.
        include_hidden: with all topics, also record hidden topics (a name part starting with
            ``_``).
        use_sim_time: stamp messages with ``/clock`` time instead of the wall clock.
        flush_period_s: put buffered messages into the file at least this often.
        node_name: the recorder node's name.
        buffer_bytes: most bytes of messages waiting for the writer thread before new ones
            are dropped (and counted); ``rosbag record --buffsize``.
        topic_log_level: the :mod:`logging` level of the "recording '/topic'" line logged
            per topic (``logging.DEBUG`` keeps a scenario run's terminal quiet).
        image_transport: store Image topics compressed (see the module docstring); None
            (default) stores them raw.

    Raises:
        UnknownStorageError: unknown format or compression.
        BagExistsError: the output exists.
        RecordError: ``exclude`` is not a regular expression, or a bad period/buffer size.

    Example::

        with Context() as ctx:
            rec = BagRecorder(ctx, None, "run_bag")
            rec.start()
            ctx.spin(duration_s=10.0)
            rec.stop()
    """

    def __init__(
        self,
        context: Context,
        topics: Sequence[str] | None,
        path: str | Path,
        *,
        fmt: str = "mcap",
        compression: str = "none",
        exclude: str | None = None,
        include_hidden: bool = False,
        use_sim_time: bool = False,
        flush_period_s: float = 0.5,
        node_name: str = "visnav_bag_recorder",
        buffer_bytes: int = DEFAULT_BUFFER_BYTES,
        topic_log_level: int = logging.INFO,
        image_transport: ImageCompression | None = None,
    ) -> None:
        self._topic_log_level = topic_log_level
        self.fmt, self.compression = check_format(fmt, compression)
        if self.fmt not in ("mcap", "ros1"):
            msg = f"recording format {fmt!r}: expected 'mcap' or 'ros1' (convert afterwards)"
            raise RecordError(msg)
        if not 0 < flush_period_s <= 1.0:
            msg = f"flush_period_s is {flush_period_s}: expected 0 < period <= 1 s"
            raise RecordError(msg)
        if buffer_bytes < 1 << 20:
            msg = f"buffer_bytes is {buffer_bytes}: expected at least 1 MiB (default 256 MiB)"
            raise RecordError(msg)
        self.context = context
        self.path = Path(path)
        self.all_topics = topics is None
        self._wanted = list(topics or [])
        self._exclude = compile_exclude(exclude)
        self._buffer_bytes = buffer_bytes
        self._queue: WriteQueue | None = None
        self._handles: dict[str, int] = {}
        self._include_hidden = include_hidden
        self.use_sim_time = use_sim_time
        self._flush_period = flush_period_s
        self._node_name = node_name
        self._node: Node | None = None
        self._writer: BagWriter | None = None
        self._timers: list[Timer] = []
        self._subs: list[Subscription[Any]] = []
        self._graph_version = -1
        self._skipped: set[str] = set()
        self.image_transport = image_transport
        self._stored_as: dict[str, str] = {}  # subscribed image topic -> stored topic
        self._offered: dict[str, list[Any]] = {}  # image topic -> publishers' QoS
        self.topics: dict[str, RecordedTopic] = {}
        self.error: BaseException | None = None
        """The write error that stopped the recording (None while all is well)."""

    # ------------------------------------------------------------------ lifecycle
    @property
    def running(self) -> bool:
        """True between :meth:`start` and :meth:`stop`."""
        return self._writer is not None

    @property
    def message_count(self) -> int:
        """Messages received and handed to the writer so far."""
        return sum(t.count for t in self.topics.values())

    @property
    def failed(self) -> bool:
        """True once writing the bag failed (:attr:`error`); the caller should stop."""
        return self._queue is not None and self._queue.failed

    @property
    def pending_bytes(self) -> int:
        """Bytes received but not yet written (the writer thread's backlog)."""
        return 0 if self._queue is None else self._queue.pending_bytes

    @property
    def last_flush_monotonic(self) -> float:
        """``time.monotonic()`` of the writer's last flush into the file."""
        return 0.0 if self._queue is None else self._queue.last_flush_monotonic

    def drops(self) -> dict[str, int]:
        """Messages lost per topic so far: subscription queue overflows + writer buffer.

        Only topics that lost messages are listed.
        """
        out: dict[str, int] = {}
        queue_drops = self._queue.dropped if self._queue is not None else {}
        for sub in self._subs:
            n = sub.dropped
            if n:
                name = self._stored_as.get(sub.topic_name, sub.topic_name)
                out[name] = out.get(name, 0) + n
        for name, rec in self.topics.items():
            handle = self._handles.get(name)
            rec.buffer_drops = 0 if handle is None else queue_drops.get(handle, 0)
            if rec.buffer_drops:
                out[name] = out.get(name, 0) + rec.buffer_drops
        return out

    @property
    def bag_path(self) -> Path:
        """The bag's path (a ``.bag`` suffix is added for ROS 1)."""
        if self._writer is not None:
            return self._writer.path
        return default_bag_path(self.path, self.fmt)

    def start(self) -> None:
        """Open the bag, create the recorder node and subscribe to what exists now."""
        if self._writer is not None:
            return
        self._writer = BagWriter(self.path, fmt=self.fmt, compression=self.compression)
        self._queue = WriteQueue(
            self._writer, max_bytes=self._buffer_bytes, flush_period_s=self._flush_period
        )
        self._node = Node(self._node_name, context=self.context, use_sim_time=self.use_sim_time)
        steady = Clock(ClockType.STEADY_TIME)
        self._timers = [self._node.create_timer(0.1, self.poll, clock=steady)]
        self._wanted = [self._node.resolve_topic_name(t) for t in self._wanted]
        self.poll()

    def stop(self) -> Path:
        """Stop recording, write what is queued, finish the bag and return its path.

        The drop counts (:meth:`drops`) are stored in the bag. Idempotent.

        Raises:
            RecordError: writing the bag failed (disk full, file size limit, ...); the bag
                was closed as far as possible and holds what was flushed before the error.
        """
        if self._writer is not None:
            self._drain()
        writer, self._writer = self._writer, None
        node, self._node = self._node, None
        drops = self.drops()  # before the subscriptions go with the node
        if node is not None:
            node.destroy_node()
        if writer is None:
            return self.bag_path
        queue = self._queue
        if queue is not None:
            queue.close()
            self.error = queue.error
            drops = self.drops()
            names = {h: n for n, h in self._handles.items()}
            for handle, text in queue.job_errors.items():
                name = names.get(handle, "?")
                _LOG.warning("'%s': %d image(s) not stored: %s", name, drops.get(name, 0), text)
        writer.set_drops(drops)
        try:
            writer.close()
        except (OSError, BagError) as exc:
            self.error = self.error or exc
        if self.error is not None:
            raise self._record_error(writer.path, self.error)
        return writer.path

    def abandon(self) -> None:
        """Drop the writer's backlog (counted as drops) so that :meth:`stop` returns soon.

        ``bag record`` calls it on a second Ctrl-C while a slow compressor catches up.
        """
        if self._queue is not None:
            self._queue.abandon()

    def _drain(self) -> None:
        """Run the callbacks of messages still queued in the recorder's subscriptions.

        Only the recorder's own callbacks run (not the rest of the caller's context), so
        what arrived before :meth:`stop` is written rather than silently discarded.
        """
        for sub in self._subs:
            for _ in range(len(sub.queue)):
                call = sub.take_call()
                if call is None:
                    break
                call()

    def _record_error(self, path: Path, exc: BaseException) -> RecordError:
        text, code = str(exc), ""
        if isinstance(exc, OSError) and exc.strerror:
            text = exc.strerror
            if exc.errno is not None:
                code = f" ({errno.errorcode.get(exc.errno, exc.errno)})"
        msg = (
            f"writing bag '{path}' failed: {text}{code}; recording stopped after "
            f"{self.message_count} messages. The bag keeps what was flushed before the error "
            f"(read it, or 'visnav bag reindex {path}'); free disk space or raise the file "
            "size limit (ulimit -f)"
        )
        return RecordError(msg)

    def flush(self) -> None:
        """Ask the writer thread to put everything received so far into the file."""
        if self._queue is not None:
            self._queue.request_flush()

    # ------------------------------------------------------------------ discovery
    def _selected(self, topic: str) -> bool:
        if not self.all_topics:
            return topic in self._wanted
        if not self._include_hidden and is_hidden_name(topic):
            return False
        return not (self._exclude is not None and self._exclude.search(topic))

    def poll(self) -> None:
        """Subscribe to newly announced topics (runs every 0.1 s on the recorder's timer)."""
        node = self._node
        if node is None or self._writer is None:
            return
        version = self.context.graph.version
        if version == self._graph_version:
            return
        self._graph_version = version
        taken = self.topics.keys() | self._skipped | self._offered.keys()
        for found in new_published_topics(self.context, taken, include_hidden=True):
            topic, types = found.name, found.types
            if not self._selected(topic):
                continue
            if len(types) != 1:
                node.get_logger().warning(
                    f"not recording '{topic}': it carries several types ({', '.join(types)})"
                )
                self._skipped.add(topic)
                continue
            self._subscribe(node, topic, types[0], list(found.publishers))

    def _subscribe(self, node: Node, topic: str, type_name: str, pubs: list[Any]) -> None:
        if self._writer is None:  # pragma: no cover - poll() checks it
            return
        try:
            cls = get_message_class(type_name)
        except VisnavError as exc:
            node.get_logger().warning(f"not recording '{topic}': {exc}")
            self._skipped.add(topic)
            return
        qos = subscription_qos_for(self.context, topic)
        if qos.history is HistoryPolicy.KEEP_LAST:
            depth = LARGE_RECORD_DEPTH if type_name in _LARGE_TYPES else RECORD_DEPTH
            qos = dataclasses.replace(qos, depth=max(qos.depth, depth))
        offered = [endpoint_qos(e) for e in pubs]
        if self._queue is None:  # pragma: no cover - start() sets it
            return
        if self.image_transport is not None and type_name == IMAGE:
            self._offered[topic] = offered
            callback = self._image_callback(topic, qos.short())
            self._subs.append(node.create_subscription(cls, topic, callback, qos, raw=True))
            text = f"recording '{topic}' through a compressed transport ({qos.short()})"
            node.get_logger().log(text, self._topic_log_level)
            return
        with self._queue.writer_lock:  # the writer thread may be writing
            handle = self._writer.add_topic(topic, type_name, qos=offered)
        self._handles[topic] = handle
        rec = RecordedTopic(topic, type_name, qos=qos.short())
        self.topics[topic] = rec
        callback = self._callback(rec, handle)
        self._subs.append(node.create_subscription(cls, topic, callback, qos, raw=True))
        text = f"recording '{topic}' ({type_name}, {qos.short()})"
        node.get_logger().log(text, self._topic_log_level)

    def _stamp(self, info: MessageInfo | None) -> tuple[int, int]:
        """(record time, publish time) of a message received now."""
        if self.use_sim_time and self._node is not None:
            t = self._node.get_clock().now_ns()
            return t, t
        if info is not None:
            return info.received_timestamp_ns, info.source_timestamp_ns
        t = time.time_ns()
        return t, t

    def _image_callback(
        self, topic: str, qos: str
    ) -> Callable[[SerializedMessage, MessageInfo | None], None]:
        """Callback of an Image topic stored through a compressed transport."""
        policy = self.image_transport
        state: dict[str, Any] = {}  # transport, handle, rec once the first message came

        def on_message(msg: SerializedMessage, info: MessageInfo | None) -> None:
            queue, writer = self._queue, self._writer
            if writer is None or queue is None or policy is None:
                return
            data = msg.to_bytes()
            if not state:
                try:
                    encoding = str(msg.deserialize().encoding)
                except ValueError as exc:
                    if self._node is not None:
                        self._node.get_logger().warning(f"not recording '{topic}': {exc}")
                    return
                transport = policy.transport_for(encoding)
                stored = policy.topic(topic, transport)
                type_name = IMAGE if transport == "raw" else "sensor_msgs/msg/CompressedImage"
                with queue.writer_lock:
                    handle = writer.add_topic(stored, type_name, qos=self._offered.get(topic, []))
                rec = RecordedTopic(stored, type_name, qos=qos)
                self.topics[stored] = rec
                self._handles[stored] = handle
                self._stored_as[topic] = stored
                state.update(transport=transport, handle=handle, rec=rec)
                if self._node is not None:
                    how = "raw: not compressible" if transport == "raw" else transport
                    text = f"recording '{topic}' ({encoding}) as '{stored}' ({how})"
                    self._node.get_logger().log(text, self._topic_log_level)
            handle, rec, transport = state["handle"], state["rec"], state["transport"]
            t, pub = self._stamp(info)
            if not 0 <= t < writer.max_time_ns:
                queue.dropped[handle] = queue.dropped.get(handle, 0) + 1
                return
            pub = pub if pub >= 0 else t
            if transport == "raw":
                ok = queue.put(handle, t, data, pub)
            else:

                def job(data: bytes = data) -> bytes:
                    return policy.encode_cdr(memoryview(data), transport)

                ok = queue.put_job(handle, t, job, pub, size=len(data))
            if ok:
                rec.count += 1

        return on_message

    def _callback(
        self, rec: RecordedTopic, handle: int
    ) -> Callable[[SerializedMessage, MessageInfo | None], None]:
        queue, node, writer = self._queue, self._node, self._writer
        if queue is None or node is None or writer is None:  # pragma: no cover - start() sets them
            msg = "the recorder is not started"
            raise RecordError(msg)
        clock = node.get_clock()
        sim = self.use_sim_time
        max_time = writer.max_time_ns

        def on_message(msg: SerializedMessage, info: MessageInfo | None) -> None:
            if self._writer is None:
                return
            if sim:
                t = pub = clock.now_ns()
            elif info is not None:
                t, pub = info.received_timestamp_ns, info.source_timestamp_ns
            else:
                t = pub = time.time_ns()
            if not 0 <= t < max_time:  # cannot be stored: count it, do not stop the writer
                queue.dropped[handle] = queue.dropped.get(handle, 0) + 1
                return
            if queue.put(handle, t, msg.to_bytes(), pub if pub >= 0 else t):
                rec.count += 1

        return on_message
