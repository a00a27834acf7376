"""Build an :class:`~visnav.doctor.observation.Observation` one message at a time.

Live observation and bag reading both feed :class:`ObservationBuilder.add`, so every
check sees the same data whatever the source. Per message the builder keeps only the
receive time, header stamp, frame_id and publisher; whole messages are kept as
samples, decimated in receive time (:class:`SamplingPolicy`): images and clouds at
most one per ``heavy_interval_s``, small messages more often. ``/tf``, ``/tf_static``,
``/clock`` and ``robot_description`` are also decoded into their own records.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from visnav.doctor.observation import (
    NO_STAMP,
    GraphSnapshot,
    Observation,
    Sample,
    TfRecord,
    TopicData,
)
from visnav.graph.introspect import endpoint_qos
from visnav.graph.qos import QoSProfile
from visnav.msgs.errors import MessageError
from visnav.msgs.time import time_to_ns

__all__ = ["HEAVY_TYPES", "ObservationBuilder", "SamplingPolicy"]

HEAVY_TYPES = frozenset(
    {
        "sensor_msgs/msg/Image",
        "sensor_msgs/msg/CompressedImage",
        "sensor_msgs/msg/PointCloud2",
        "sensor_msgs/msg/LaserScan",
        "nav_msgs/msg/OccupancyGrid",
    }
)
"""Types whose samples are decimated hardest (large messages)."""

TF_TYPE = "tf2_msgs/msg/TFMessage"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
STRING_TYPE = "std_msgs/msg/String"


@dataclass(frozen=True)
class SamplingPolicy:
    """How many whole messages to keep per topic.

    Attributes:
        heavy_interval_s: minimum receive-time spacing of kept images, clouds, scans.
        heavy_max: at most this many of those per topic.
        light_interval_s: spacing for other messages.
        light_max: at most this many of those per topic.
    """

    heavy_interval_s: float = 0.5
    heavy_max: int = 12
    light_interval_s: float = 0.05
    light_max: int = 400


class _TopicAcc:
    __slots__ = (
        "frame_ids",
        "interval_ns",
        "last_sample_ns",
        "latched",
        "max_samples",
        "name",
        "publishers",
        "receive",
        "samples",
        "stamps",
        "type_name",
    )

    def __init__(self, name: str, type_name: str, policy: SamplingPolicy) -> None:
        self.name = name
        self.type_name = type_name
        heavy = type_name in HEAVY_TYPES
        self.interval_ns = round(
            (policy.heavy_interval_s if heavy else policy.light_interval_s) * 1e9
        )
        self.max_samples = policy.heavy_max if heavy else policy.light_max
        self.receive: list[int] = []
        self.stamps: list[int] = []
        self.frame_ids: list[str] = []
        self.publishers: list[str] = []
        self.samples: list[Sample] = []
        self.last_sample_ns: int | None = None
        self.latched = False

    def wants_sample(self, receive_ns: int) -> bool:
        if len(self.samples) >= self.max_samples:
            return False
        last = self.last_sample_ns
        return last is None or receive_ns - last >= self.interval_ns or receive_ns < last

    def build(self) -> TopicData:
        return TopicData(
            name=self.name,
            type_name=self.type_name,
            receive_ns=np.asarray(self.receive, dtype=np.int64),
            stamp_ns=np.asarray(self.stamps, dtype=np.int64),
            frame_ids=tuple(self.frame_ids),
            publishers=tuple(self.publishers),
            samples=tuple(self.samples),
            latched=self.latched,
        )


def header_of(msg: Any) -> tuple[int, str]:
    """Return ``(stamp ns, frame_id)`` of a message's header (``NO_STAMP``, '' without one)."""
    header = getattr(msg, "header", None)
    stamp = getattr(header, "stamp", None)
    if stamp is None:
        return NO_STAMP, ""
    try:
        ns = time_to_ns(stamp)
    except MessageError:
        ns = NO_STAMP
    return ns, str(getattr(header, "frame_id", ""))


class ObservationBuilder:
    """Accumulates messages into an :class:`Observation`.

    Args:
        source: ``"live"`` or ``"bag"``.
        label: description of the input for the report.
        policy: sample decimation.
    """

    def __init__(self, *, source: str, label: str, policy: SamplingPolicy | None = None) -> None:
        self.source = source
        self.label = label
        self.policy = policy or SamplingPolicy()
        self._topics: dict[str, _TopicAcc] = {}
        self._tf: list[TfRecord] = []
        self._clock_rx: list[int] = []
        self._clock: list[int] = []
        self._robot_description: tuple[str, str] | None = None
        self._graph: GraphSnapshot | None = None
        self._qos: dict[str, tuple[QoSProfile, ...]] = {}
        self._undecodable: dict[str, str] = {}
        self._first: int | None = None
        self._last: int | None = None
        self._window: tuple[int, int] | None = None

    # ------------------------------------------------------------------ topics
    def declare_topic(self, topic: str, type_name: str, *, qos: Iterable[QoSProfile] = ()) -> None:
        """Make a topic known even if no message arrives (so 'no messages' can be reported)."""
        acc = self._topics.get(topic)
        if acc is None:
            acc = _TopicAcc(topic, type_name, self.policy)
            self._topics[topic] = acc
        profiles = tuple(qos)
        if profiles:
            self._qos[topic] = profiles
            acc.latched = all(q.durability.value == "transient_local" for q in profiles)

    def mark_undecodable(self, topic: str, type_name: str) -> None:
        """Record a topic whose type visnav cannot decode."""
        self._undecodable[topic] = type_name

    def wants_sample(self, topic: str, type_name: str, receive_ns: int) -> bool:
        """Whether the next message of ``topic`` would be kept whole (lets a reader skip work)."""
        acc = self._topics.get(topic)
        if acc is None:
            return True
        return type_name in (TF_TYPE, CLOCK_TYPE) or acc.wants_sample(receive_ns)

    def add(
        self,
        topic: str,
        type_name: str,
        receive_ns: int,
        msg: Any,
        *,
        publisher: str = "",
        authority: str = "",
    ) -> None:
        """Record one message.

        Args:
            topic: topic name.
            type_name: the message's ROS 2 type name.
            receive_ns: receive (or record) time in nanoseconds.
            msg: the deserialized message.
            publisher: publisher identity (distinguishes streams on one topic).
            authority: TF authority (publishing node) for ``/tf`` and ``/tf_static``.
        """
        stamp, frame_id = header_of(msg)
        if type_name == CLOCK_TYPE:
            try:
                stamp = time_to_ns(msg.clock)
            except MessageError:
                stamp = NO_STAMP
            else:
                self._clock_rx.append(receive_ns)
                self._clock.append(stamp)
        elif type_name == TF_TYPE:
            self._add_tf(topic, receive_ns, msg, authority or publisher)
            stamps = [s for s, _ in map(header_of, msg.transforms) if s != NO_STAMP]
            stamp = max(stamps) if stamps else NO_STAMP
        elif type_name == STRING_TYPE and topic.endswith("robot_description"):
            self._robot_description = (topic, str(msg.data))
        acc = self.add_header(topic, type_name, receive_ns, stamp, frame_id, publisher=publisher)
        if acc.wants_sample(receive_ns):
            acc.samples.append(Sample(receive_ns, msg, publisher))
            acc.last_sample_ns = receive_ns

    def add_header(
        self,
        topic: str,
        type_name: str,
        receive_ns: int,
        stamp_ns: int,
        frame_id: str,
        *,
        publisher: str = "",
    ) -> _TopicAcc:
        """Record a message by its header only (a reader that skipped decoding a large message).

        Not for ``/tf``, ``/clock`` or ``robot_description``, whose content is needed.
        """
        acc = self._topics.get(topic)
        if acc is None:
            acc = _TopicAcc(topic, type_name, self.policy)
            self._topics[topic] = acc
        acc.receive.append(receive_ns)
        acc.stamps.append(stamp_ns)
        acc.frame_ids.append(frame_id)
        acc.publishers.append(publisher)
        if self._first is None or receive_ns < self._first:
            self._first = receive_ns
        if self._last is None or receive_ns > self._last:
            self._last = receive_ns
        return acc

    def _add_tf(self, topic: str, receive_ns: int, msg: Any, authority: str) -> None:
        is_static = topic.rstrip("/").endswith("tf_static")
        for t in msg.transforms:
            stamp, parent = header_of(t)
            tr, rot = t.transform.translation, t.transform.rotation
            self._tf.append(
                TfRecord(
                    parent=parent,
                    child=str(t.child_frame_id),
                    stamp_ns=stamp,
                    translation=(float(tr.x), float(tr.y), float(tr.z)),
                    rotation=(float(rot.x), float(rot.y), float(rot.z), float(rot.w)),
                    is_static=is_static,
                    authority=authority,
                    receive_ns=receive_ns,
                )
            )

    # ------------------------------------------------------------------ graph
    def set_graph(self, graph: GraphSnapshot) -> None:
        """Attach the live graph snapshot (and the offered QoS of each topic)."""
        self._graph = graph
        for topic in graph.topics():
            pubs = graph.of_topic(topic, "publisher")
            if pubs:
                profiles = tuple(endpoint_qos(e) for e in pubs)
                self._qos[topic] = profiles
                if topic in self._topics:
                    self._topics[topic].latched = all(
                        p.durability.value == "transient_local" for p in profiles
                    )

    def set_window(self, start_ns: int, end_ns: int) -> None:
        """Set the observation window explicitly (default: first to last message)."""
        self._window = (start_ns, end_ns)

    def build(self) -> Observation:
        """Return the observation."""
        if self._window is not None:
            start, end = self._window
        else:
            start = self._first or 0
            end = self._last or start
        authorities: Mapping[str, str] = self._graph.publisher_names if self._graph else {}
        tf = tuple(
            TfRecord(**{**r.__dict__, "authority": authorities.get(r.authority, r.authority)})
            if r.authority in authorities
            else r
            for r in self._tf
        )
        return Observation(
            source=self.source,
            label=self.label,
            start_ns=start,
            end_ns=end,
            topics={name: acc.build() for name, acc in sorted(self._topics.items())},
            tf=tf,
            clock_receive_ns=np.asarray(self._clock_rx, dtype=np.int64),
            clock_ns=np.asarray(self._clock, dtype=np.int64),
            robot_description=self._robot_description[1] if self._robot_description else None,
            robot_description_topic=self._robot_description[0] if self._robot_description else "",
            graph=self._graph,
            topic_qos=dict(self._qos),
            undecodable=dict(self._undecodable),
        )
