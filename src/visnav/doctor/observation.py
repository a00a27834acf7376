"""What doctor saw: a graph snapshot plus per-topic message records, TF and /clock.

An :class:`Observation` is the one input of every check, whether it came from a live
graph (:mod:`visnav.doctor.live`) or a bag (:mod:`visnav.doctor.bag_source`):

* ``graph``: nodes and endpoints (topic, type, node, QoS) of the live graph, or None
  for a bag (whose per-topic offered QoS is in ``topic_qos``);
* ``topics``: per topic, the receive time, header stamp, frame_id and publisher of
  every message, plus a few decimated sample messages (not every image);
* ``tf``: every transform received on ``/tf`` and ``/tf_static``;
* ``clock``: every ``/clock`` message with its receive time;
* ``robot_description``: the URDF text, when published.

Receive times are integer nanoseconds of the observer's clock: the wall clock for a
live graph, the bag's record time for a bag. :class:`ClockModel` maps them to the
graph's ROS time (``/clock`` when present).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from visnav.graph.graph_cache import EndpointInfo, NodeInfo
from visnav.graph.qos import QoSProfile

__all__ = [
    "NO_STAMP",
    "ClockModel",
    "GraphSnapshot",
    "Observation",
    "Sample",
    "TfRecord",
    "TopicData",
]

NO_STAMP = -1
"""``TopicData.stamp_ns`` value of a message without a header stamp."""


@dataclass(frozen=True)
class Sample:
    """One kept message: when it arrived, who sent it, the message itself."""

    receive_ns: int
    msg: Any
    publisher: str = ""


@dataclass(frozen=True)
class TopicData:
    """Every message of one topic (as parallel arrays) and a few samples.

    Attributes:
        name: topic name.
        type_name: ROS 2 type name.
        receive_ns: receive time of each message (int64).
        stamp_ns: ``header.stamp`` of each message, :data:`NO_STAMP` if it has none.
        frame_ids: ``header.frame_id`` of each message ('' if none).
        publishers: publisher identity of each message (``zid:entity`` live, '' in a bag).
        samples: decimated messages (first message always kept).
        latched: all publishers offer transient local durability.
    """

    name: str
    type_name: str
    receive_ns: NDArray[np.int64]
    stamp_ns: NDArray[np.int64]
    frame_ids: tuple[str, ...]
    publishers: tuple[str, ...]
    samples: tuple[Sample, ...]
    latched: bool = False

    @property
    def count(self) -> int:
        """Number of messages received."""
        return int(self.receive_ns.size)

    @property
    def has_stamps(self) -> bool:
        """True when the messages carry a header stamp."""
        return bool(self.count) and bool((self.stamp_ns != NO_STAMP).all())

    @property
    def frame_id(self) -> str:
        """The most frequent frame_id ('' when none)."""
        if not self.frame_ids:
            return ""
        values, counts = np.unique(np.asarray(self.frame_ids, dtype=object), return_counts=True)
        return str(values[int(np.argmax(counts))])


@dataclass(frozen=True)
class TfRecord:
    """One transform received on ``/tf`` or ``/tf_static`` (quaternion x, y, z, w)."""

    parent: str
    child: str
    stamp_ns: int
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]
    is_static: bool
    authority: str
    receive_ns: int


@dataclass(frozen=True)
class GraphSnapshot:
    """Nodes and endpoints of a live graph (hidden ``_`` nodes such as doctor's own left out)."""

    nodes: tuple[NodeInfo, ...]
    endpoints: tuple[EndpointInfo, ...]
    publisher_names: Mapping[str, str] = field(default_factory=dict)

    def of_topic(self, topic: str, kind: str | None = None) -> list[EndpointInfo]:
        """Endpoints of ``topic`` (``kind`` ``"publisher"`` / ``"subscription"`` / None)."""
        return [e for e in self.endpoints if e.topic == topic and (kind is None or e.kind == kind)]

    def topics(self) -> set[str]:
        """Every topic name with an endpoint."""
        return {e.topic for e in self.endpoints}


class ClockModel:
    """Maps receive times to ROS time: ``/clock`` when it was published, else identity.

    Between ``/clock`` messages the time is interpolated linearly; before the first
    and after the last it continues at the observed rate (1.0 with one sample).
    """

    def __init__(self, receive_ns: NDArray[np.int64], clock_ns: NDArray[np.int64]) -> None:
        order = np.argsort(receive_ns, kind="stable")
        self._rx = np.asarray(receive_ns, dtype=np.int64)[order]
        self._clk = np.asarray(clock_ns, dtype=np.int64)[order]

    @property
    def has_clock(self) -> bool:
        """True when ``/clock`` messages were received."""
        return bool(self._rx.size)

    @property
    def first_ns(self) -> int:
        """The first ``/clock`` value (0 without /clock)."""
        return int(self._clk[0]) if self._rx.size else 0

    @property
    def last_ns(self) -> int:
        """The last ``/clock`` value (0 without /clock)."""
        return int(self._clk[-1]) if self._rx.size else 0

    @property
    def rate(self) -> float:
        """ROS seconds per receive second over the observation (the real-time factor)."""
        if self._rx.size < 2 or self._rx[-1] == self._rx[0]:
            return 1.0
        return float(self._clk[-1] - self._clk[0]) / float(self._rx[-1] - self._rx[0])

    def at(self, receive_ns: NDArray[np.int64] | int) -> NDArray[np.int64]:
        """ROS time at the given receive times (int64 nanoseconds)."""
        rx: NDArray[np.int64] = np.atleast_1d(np.asarray(receive_ns, dtype=np.int64))
        if not self._rx.size:
            return np.array(rx, dtype=np.int64)
        base_rx, base_clk = int(self._rx[0]), int(self._clk[0])
        x = (rx - base_rx).astype(np.float64)
        xp = (self._rx - base_rx).astype(np.float64)
        fp = (self._clk - base_clk).astype(np.float64)
        out = np.interp(x, xp, fp)
        rate = self.rate
        before = x < xp[0]
        after = x > xp[-1]
        out[before] = fp[0] + (x[before] - xp[0]) * rate
        out[after] = fp[-1] + (x[after] - xp[-1]) * rate
        result: NDArray[np.int64] = np.round(out).astype(np.int64) + base_clk
        return result


@dataclass(frozen=True)
class Observation:
    """Everything the checks look at (see the module docs).

    Attributes:
        source: ``"live"`` or ``"bag"``.
        label: human description (``live graph, domain 0`` or the bag path).
        start_ns: first receive time of the observation window.
        end_ns: last receive time of the observation window.
        topics: per topic data.
        tf: every transform received, in receive order.
        clock_receive_ns: receive time of each ``/clock`` message.
        clock_ns: the ``/clock`` value of each.
        robot_description: the newest URDF text on a ``robot_description`` topic, if any.
        robot_description_topic: the topic it came from.
        graph: the live graph, None for a bag.
        topic_qos: offered QoS per topic (live: from the graph; bag: from its metadata).
        undecodable: topics whose type visnav cannot decode, with the type.
    """

    source: str
    label: str
    start_ns: int
    end_ns: int
    topics: Mapping[str, TopicData]
    tf: tuple[TfRecord, ...] = ()
    clock_receive_ns: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    clock_ns: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    robot_description: str | None = None
    robot_description_topic: str = ""
    graph: GraphSnapshot | None = None
    topic_qos: Mapping[str, tuple[QoSProfile, ...]] = field(default_factory=dict)
    undecodable: Mapping[str, str] = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        """Length of the observation window in receive seconds."""
        return max(0, self.end_ns - self.start_ns) / 1e9

    def clock_model(self) -> ClockModel:
        """A :class:`ClockModel` from the ``/clock`` messages."""
        return ClockModel(self.clock_receive_ns, self.clock_ns)

    def topic(self, name: str) -> TopicData | None:
        """The data of one topic, or None if no message arrived on it."""
        return self.topics.get(name)
