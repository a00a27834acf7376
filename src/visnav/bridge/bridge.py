"""The ROS 1 bridge: visnav topics appear in a ROS 1 graph and ROS 1 topics come in on demand.

Services cross both ways too (:mod:`visnav.bridge.services`), and visnav actions are offered
as ROS 1 actionlib servers (:mod:`visnav.bridge.actionlib`).

Out (visnav -> ROS 1): every topic with a visnav publisher is advertised to the ROS 1 master;
its messages are taken from the visnav graph only while a ROS 1 node is connected (latched
topics always, to hold the last message for late joiners). In (ROS 1 -> visnav): every topic a
visnav node subscribes to is subscribed in ROS 1; messages from ROS 1 publishers are published
on the visnav graph. The bridge never forwards what it published itself, so a topic with
publishers on both sides does not loop.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import functools
import logging
import struct
import threading
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from visnav.bridge.actionlib import ActionlibBridge
from visnav.bridge.bytetail import head_plan, split_cdr_to_ros1
from visnav.bridge.errors import BridgeError, TcprosError, UnconvertibleTypeError
from visnav.bridge.ros1_node import Ros1Node
from visnav.bridge.services import ServiceBridge
from visnav.bridge.typemap import Ros1Type, cdr_to_ros1, ros1_to_cdr, ros1_type
from visnav.graph import (
    DurabilityPolicy,
    MessageInfo,
    Node,
    Publisher,
    QoSProfile,
    SerializedMessage,
    Subscription,
)
from visnav.graph.names import is_hidden_name
from visnav.msgs.errors import MessageError
from visnav.msgs.serde import CdrSerializer, deserialize, get_message_class

__all__ = ["LATCHED_TOPICS", "BridgeOptions", "Ros1Bridge", "topic_selected"]

_log = logging.getLogger("visnav.bridge")
_U32 = struct.Struct("<I")

LATCHED_TOPICS = frozenset({"/tf_static", "/map"})
"""Topics ROS 1 nodes expect latched, whatever the visnav publisher's durability."""


def topic_selected(topic: str, include: Sequence[str], exclude: Sequence[str]) -> bool:
    """Whether ``topic`` passes the ``--topics`` / ``--exclude`` shell-style patterns."""
    if include and not any(fnmatch.fnmatchcase(topic, p) for p in include):
        return False
    return not any(fnmatch.fnmatchcase(topic, p) for p in exclude)


@dataclass(frozen=True)
class BridgeOptions:
    """What the bridge carries.

    Attributes:
        topics: shell-style patterns of topics to bridge (empty: all).
        exclude: patterns of topics and services never bridged.
        scan_period_s: how often the graphs are compared.
        queue_size: messages kept per ROS 1 subscriber that cannot keep up.
        services: shell-style patterns of services to bridge (empty: all whose types
            cross to ROS 1).
        service_timeout_s: the longest a service call through the bridge may take.
        actions: shell-style patterns of visnav actions offered to ROS 1 as actionlib
            servers (empty: all whose types cross).
    """

    topics: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    scan_period_s: float = 0.25
    queue_size: int = 10
    services: tuple[str, ...] = ()
    service_timeout_s: float = 10.0
    actions: tuple[str, ...] = ()


class _Out:
    """One visnav topic published into ROS 1."""

    def __init__(self, topic: str, rtype: Ros1Type, latch: bool) -> None:
        self.topic = topic
        self.rtype = rtype
        self.latch = latch
        self.serializer = CdrSerializer(rtype.ros2_name)
        self.convert_lock = threading.Lock()  # conversions may run on connection threads
        self.plan = head_plan(rtype)  # byte-tail types: no deserialization when forwarding
        self.sub: Subscription[Any] | None = None
        self.count = 0


class _In:
    """One ROS 1 topic published into visnav (the publisher made once ROS 1 has one)."""

    def __init__(self, topic: str, rtype: Ros1Type, queue_size: int) -> None:
        self.topic = topic
        self.rtype = rtype
        self.pub: Publisher[Any] | None = None
        self.pending: deque[Any] = deque(maxlen=queue_size)
        self.lock = threading.Lock()
        self.count = 0


class Ros1Bridge:
    """Keeps one visnav node and one ROS 1 node in step.

    Args:
        node: the visnav node the bridge publishes and subscribes with.
        ros1: the ROS 1 node (started, registered with a master).
        options: what to bridge.
    """

    def __init__(self, node: Node, ros1: Ros1Node, options: BridgeOptions | None = None) -> None:
        self.node = node
        self.ros1 = ros1
        self.options = options or BridgeOptions()
        self._fqn = node.get_fully_qualified_name()
        self._out: dict[str, _Out] = {}
        self._in: dict[str, _In] = {}
        self._refused: set[tuple[str, str]] = set()
        self._own_pub_ids: set[int] = set()
        ros1.on_room = self._on_room
        self._sim_time_set = False
        self._description: str | None = None
        self._last_error = ""
        self.services = ServiceBridge(
            node, ros1, selected=self._wanted_service, timeout_s=self.options.service_timeout_s
        )
        self.actionlib = ActionlibBridge(
            node, ros1, selected=self._wanted_action, release=self._release_topics
        )
        self._timer = node.create_timer(self.options.scan_period_s, self.scan)

    # ------------------------------------------------------------------ bookkeeping
    def out_topics(self) -> list[str]:
        """Topics bridged visnav -> ROS 1."""
        return sorted(self._out)

    def in_topics(self) -> list[str]:
        """Topics bridged ROS 1 -> visnav."""
        return sorted(self._in)

    def counts(self) -> dict[str, int]:
        """Messages forwarded per direction and topic, e.g. ``{"out /odom": 12}``."""
        out = {f"out {t}": o.count for t, o in self._out.items()}
        out.update({f"in {t}": i.count for t, i in self._in.items()})
        return out

    def _wanted(self, topic: str) -> bool:
        if is_hidden_name(topic) or topic in self.actionlib.owned_topics():
            return False
        return topic_selected(topic, self.options.topics, self.options.exclude)

    def _wanted_service(self, name: str) -> bool:
        if is_hidden_name(name):
            return False
        return topic_selected(name, self.options.services, self.options.exclude)

    def _release_topics(self, topics: list[str]) -> None:
        """Stop bridging ``topics`` (an actionlib server takes them over)."""
        for topic in topics:
            if topic in self._out:
                self._drop_out(topic)
            if topic in self._in:
                self._drop_in(topic)

    def _wanted_action(self, name: str) -> bool:
        if is_hidden_name(name):
            return False
        return topic_selected(name, self.options.actions, self.options.exclude)

    def _convertible(self, topic: str, type_name: str) -> Ros1Type | None:
        try:
            return ros1_type(type_name)
        except UnconvertibleTypeError as exc:
            if (topic, type_name) not in self._refused:
                self._refused.add((topic, type_name))
                self.node.get_logger().warning(f"not bridging {topic}: {exc}")
            return None

    # ------------------------------------------------------------------ scan
    def scan(self) -> None:
        """Compare the graphs once: bridge new topics, drop gone ones, follow ROS 1 demand."""
        pubs: dict[str, set[str]] = {}
        subs: dict[str, set[str]] = {}
        latched: set[str] = set()
        for e in self.node.context.graph.endpoints():
            if e.node_fqn == self._fqn or not self._wanted(e.topic):
                continue
            if e.kind == "publisher":
                pubs.setdefault(e.topic, set()).add(e.type_name)
                if e.durability == "transient_local":
                    latched.add(e.topic)
            else:
                subs.setdefault(e.topic, set()).add(e.type_name)
        try:
            self._scan_out(pubs, latched)
            self._scan_in(subs)
            self.services.scan()
            self.actionlib.scan()  # takes its topics from the topic bridge (_release_topics)
        except BridgeError as exc:
            if str(exc) != self._last_error:  # once per distinct failure, not every scan
                self._last_error = str(exc)
                self.node.get_logger().error(f"{exc}; retrying")
        else:
            self._last_error = ""

    def _scan_out(self, pubs: dict[str, set[str]], latched: set[str]) -> None:
        for topic in list(self._out):
            if topic not in pubs:
                self._drop_out(topic)
        for topic, types in sorted(pubs.items()):
            if topic not in self._out:
                if len(types) != 1:
                    continue
                rtype = self._convertible(topic, next(iter(types)))
                if rtype is None:
                    continue
                latch = topic in latched or topic in LATCHED_TOPICS
                self.ros1.advertise(topic, rtype, latch=latch)
                self._out[topic] = _Out(topic, rtype, latch)
                self.node.get_logger().info(f"visnav -> ROS 1: {topic} [{rtype.ros1_name}]")
                if topic == "/clock" and not self._sim_time_set:
                    self.ros1.master.set_param("/use_sim_time", True)
                    self._sim_time_set = True
            out = self._out[topic]
            needed = (
                out.latch or topic == "/robot_description" or self.ros1.subscriber_count(topic) > 0
            )
            if needed and out.sub is None:
                out.sub = self._subscribe_visnav(out)
            elif not needed and out.sub is not None:
                self.node.destroy_subscription(out.sub)
                out.sub = None

    def _subscribe_visnav(self, out: _Out) -> Subscription[Any]:
        cls = get_message_class(out.rtype.ros2_name)
        durability = DurabilityPolicy.TRANSIENT_LOCAL if out.latch else DurabilityPolicy.VOLATILE
        qos = QoSProfile(depth=self.options.queue_size, durability=durability)
        if out.rtype.byte_tail is not None and not out.latch:
            return self._subscribe_visnav_raw(out, cls, qos)

        def forward(msg: Any, info: MessageInfo) -> None:
            if info.from_this_process and info.publisher_entity_id in self._own_pub_ids:
                return  # came from ROS 1 through this bridge
            if out.topic == "/robot_description" and msg.data != self._description:
                try:
                    self.ros1.master.set_param("/robot_description", str(msg.data))
                    self._description = str(msg.data)
                except BridgeError as exc:
                    self.node.get_logger().error(f"/robot_description parameter not set: {exc}")
            try:
                payload, tail = self._to_ros1(out, msg, copy=info.from_this_process)
            except (TcprosError, MessageError) as exc:
                self.node.get_logger().warning(f"dropped a message on {out.topic}: {exc}")
                return
            out.count += 1
            seq = out.count if out.rtype.header_first else None  # header.seq, as rospy numbers it
            self.ros1.publish(out.topic, payload, seq=seq, tail=tail)

        return self.node.create_subscription(cls, out.topic, forward, qos)

    def _subscribe_visnav_raw(
        self, out: _Out, cls: type[Any], qos: QoSProfile
    ) -> Subscription[Any]:
        """Forward a bulk type (images, clouds) undecoded, paced by the ROS 1 subscribers.

        The subscription hands over the CDR bytes still in the transport's buffer; each ROS 1
        connection queues the message as it is and the conversion (and the one copy out of
        the transport) runs when a connection sends it. The subscription is paced: once
        every connection has :data:`~visnav.bridge.ros1_node.PACE_AHEAD` messages queued
        behind the one it sends, it is paused until one is down to
        :data:`~visnav.bridge.ros1_node.PACE_RESUME`. While paused, messages wait in Zenoh
        (older ones dropped there, costing no Python code) and the topic's visnav publishers
        hear of the pause and skip their samples (:mod:`visnav.graph.transport_pace`), so a
        visnav publisher flooding thousands of images a second costs the bridge about what
        the ROS 1 subscribers take.
        """

        def forward(data: SerializedMessage, info: MessageInfo) -> None:
            if info.from_this_process and info.publisher_entity_id in self._own_pub_ids:
                return  # came from ROS 1 through this bridge
            out.count += 1
            seq = out.count if out.rtype.header_first else None  # header.seq, as rospy numbers it
            make = functools.partial(self._convert, out, data)
            sub = out.sub
            if not self.ros1.publish_deferred(out.topic, make, seq=seq) and sub is not None:
                sub.pause()
                if self.ros1.can_resume(out.topic):  # queues emptied before the pause
                    sub.resume()

        return self.node.create_subscription(cls, out.topic, forward, qos, raw=True, paced=True)

    def _on_room(self, topic: str) -> None:
        """A ROS 1 subscriber of ``topic`` can take more (runs on a connection's thread)."""
        out = self._out.get(topic)
        sub = None if out is None else out.sub
        if sub is not None and sub.paced and sub.paused and self.ros1.can_resume(topic):
            sub.resume()

    def _convert(
        self, out: _Out, data: SerializedMessage
    ) -> tuple[memoryview, memoryview | None] | None:
        """A raw message's ROS 1 bytes as ``(head, tail)``, or None if it does not convert.

        The one copy is out of the transport (:meth:`SerializedMessage.to_bytes`); a type
        with a :func:`~visnav.bridge.bytetail.head_plan` then has the fields before its
        tail rewritten byte by byte and its tail sent from those bytes; any other (or a
        big-endian message) is deserialized and converted as in :meth:`_to_ros1`.
        """
        try:
            cdr = data.to_bytes()  # its own buffer: its bytes are sent without a copy
            if out.plan is not None and cdr[1:2] == b"\x01":
                head, tail = split_cdr_to_ros1(cdr, out.plan)
                return memoryview(head), tail
            msg = data.deserialize()
            with out.convert_lock:
                return self._to_ros1(out, msg, copy=False)
        except (TcprosError, MessageError) as exc:
            self.node.get_logger().warning(f"dropped a message on {out.topic}: {exc}")
            return None

    @staticmethod
    def _to_ros1(out: _Out, msg: Any, *, copy: bool) -> tuple[memoryview, memoryview | None]:
        """A message's ROS 1 bytes: ``(payload, None)``, or ``(head, bytes)`` for a byte tail.

        A type whose last field is ``uint8[]`` (an image's pixels) is converted without that
        field, and its bytes are sent from the message as they are: for a 921,600-byte image
        this saves two copies and two passes over the pixels (CDR serialization and the
        CDR -> ROS 1 conversion). A message from another process owns its buffer alone, so
        the bytes are sent without a copy; one from this process is copied, because its
        publisher may reuse the array once ``publish`` returns.
        """
        field = out.rtype.byte_tail
        data = None if field is None else getattr(msg, field, None)
        if (
            field is None
            or not isinstance(data, np.ndarray)
            or data.ndim != 1
            or data.dtype.itemsize != 1
            or not data.flags.c_contiguous
        ):
            return cdr_to_ros1(memoryview(out.serializer.serialize(msg)), out.rtype), None
        head_msg = dataclasses.replace(msg, **{field: np.empty(0, dtype=data.dtype)})
        head = bytearray(cdr_to_ros1(memoryview(out.serializer.serialize(head_msg)), out.rtype))
        head[-4:] = _U32.pack(data.size)  # the empty sequence's length -> the real one
        tail = memoryview(data.tobytes()) if copy else data.data.cast("B")
        return memoryview(head), tail

    def _drop_out(self, topic: str) -> None:
        out = self._out.pop(topic)
        if out.sub is not None:
            self.node.destroy_subscription(out.sub)
        self.ros1.unadvertise(topic)
        self.node.get_logger().info(f"visnav -> ROS 1: {topic} gone")

    def _scan_in(self, subs: dict[str, set[str]]) -> None:
        for topic in list(self._in):
            if topic not in subs:
                self._drop_in(topic)
        for topic, types in sorted(subs.items()):
            if topic in self._in or len(types) != 1 or (topic == "/clock" and topic in self._out):
                continue
            rtype = self._convertible(topic, next(iter(types)))
            if rtype is None:
                continue
            inc = _In(topic, rtype, self.options.queue_size)
            self.ros1.subscribe(topic, rtype, functools.partial(self._forward_in, inc))
            self._in[topic] = inc
            self.node.get_logger().info(f"ROS 1 -> visnav: {topic} [{rtype.ros1_name}]")
        for inc in self._in.values():
            if inc.pub is None and self.ros1.publisher_uris(inc.topic):
                self._make_publisher(inc)

    def _make_publisher(self, inc: _In) -> None:
        """Publish a ROS 1 topic in visnav once it has a ROS 1 publisher.

        Not before: the visnav graph shows no bridge publisher for topics ROS 1 lacks.
        """
        durability = (
            DurabilityPolicy.TRANSIENT_LOCAL
            if inc.topic in LATCHED_TOPICS
            else DurabilityPolicy.VOLATILE
        )
        pub = self.node.create_publisher(
            get_message_class(inc.rtype.ros2_name),
            inc.topic,
            QoSProfile(depth=self.options.queue_size, durability=durability),
        )
        self._own_pub_ids.add(pub.entity_id)
        with inc.lock:
            inc.pub = pub
            while inc.pending:  # what arrived first (a latched message) goes out now
                pub.publish(inc.pending.popleft())

    def _drop_in(self, topic: str) -> None:
        inc = self._in.pop(topic)
        self.ros1.unsubscribe(topic)
        if inc.pub is not None:
            self._own_pub_ids.discard(inc.pub.entity_id)
            self.node.destroy_publisher(inc.pub)

    def _forward_in(self, inc: _In, raw: bytearray) -> None:
        """Publish one ROS 1 message on the visnav graph (runs on a TCPROS thread)."""
        try:
            msg = deserialize(ros1_to_cdr(memoryview(raw), inc.rtype), inc.rtype.ros2_name)
        except (TcprosError, MessageError) as exc:
            self.node.get_logger().warning(f"dropped a ROS 1 message on {inc.topic}: {exc}")
            return
        with inc.lock:
            inc.count += 1
            if inc.pub is None:
                inc.pending.append(msg)
            else:
                inc.pub.publish(msg)

    def close(self) -> None:
        """Stop scanning and drop every bridged topic (the ROS 1 node stays open)."""
        self._timer.cancel()
        self.services.close()
        self.actionlib.close()
        for topic in list(self._out):
            self._drop_out(topic)
        for topic in list(self._in):
            self._drop_in(topic)
