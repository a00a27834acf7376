"""Republish a bag on the graph with its recorded timing (``ros2 bag play``).

Each message is published when ``(t - t_start) / rate`` has passed on the wall clock since
playback began, where ``t_start`` is the bag's start (plus ``start_offset_s``); the gap
before the first message is kept, as ``ros2 bag play`` does. Publishers use the QoS the
recorded publishers offered (transient local only if all of them were: ``/tf_static``
stays latched). With ``clock_hz`` the player publishes ``/clock`` (bag time) at that rate,
so nodes with ``use_sim_time`` follow the bag.

A message whose bytes do not decode as its type (a damaged payload in a bag whose index and
chunks are intact) is skipped, logged once per topic and counted
(:attr:`PlayStats.undecodable`); playback goes on. ``ros2 bag play`` publishes the
serialized bytes without decoding them and leaves the failure to each subscriber; visnav
decodes before publishing (in-process subscribers get message objects), so it skips instead.

Images recorded through image_transport's compressed transports are played as ``rosbag
play`` plays them: the ``<topic>/compressed`` / ``<topic>/compressedDepth`` topics, as
recorded (``sensor_msgs/CompressedImage``). Subscribers of raw images (visnav's SLAM, depth
to scan, image_proc) then need them decoded: ``decompress=True`` (``visnav bag play
--decompress``) also publishes each one decoded as a ``sensor_msgs/Image`` on ``<topic>``,
what ``rosrun image_transport republish compressed in:=<topic> raw out:=<topic>`` does in
ROS (skipped for a topic whose raw form is in the bag too).

Playback runs in the calling thread (:meth:`BagPlayer.play`) or a background thread
(:meth:`BagPlayer.start`); publishing is thread-safe, and subscribers in the same context
are served by whoever spins it.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from visnav.bag.errors import BagError, CorruptBagError
from visnav.bag.image_compression import decode_image, image_topics
from visnav.bag.qos import playback_qos
from visnav.bag.reader import BagReader
from visnav.graph.context import Context
from visnav.graph.names import parse_remap_rule
from visnav.graph.node import Node, Publisher
from visnav.graph.qos import QoSProfile, ReliabilityPolicy
from visnav.msgs.serde import get_message_class
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Clock as ClockMsg
from visnav.msgs.types import Image

__all__ = ["BagPlayer", "PlayStats", "parse_remaps"]

_LOG = logging.getLogger("visnav.bag")

_CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)


def parse_remaps(remap: Mapping[str, str] | Sequence[str] | None) -> dict[str, str]:
    """Parse ``["from:=to", ...]`` (or a mapping) into ``{from: to}`` of absolute topic names.

    Raises:
        BagError: a rule is not ``from:=to``.
    """
    if remap is None:
        return {}
    items = remap.items() if isinstance(remap, Mapping) else [_split(r) for r in remap]
    out: dict[str, str] = {}
    for src, dst in items:
        parse_remap_rule(f"{src}:={dst}")  # validates both names
        out["/" + src.lstrip("/")] = "/" + dst.lstrip("/")
    return out


def _split(rule: str) -> tuple[str, str]:
    src, sep, dst = rule.partition(":=")
    if not sep or not src or not dst:
        msg = f"remap rule {rule!r}: expected 'from:=to', e.g. /camera/image:=/image"
        raise BagError(msg)
    return src, dst


@dataclasses.dataclass
class PlayStats:
    """What a playback did.

    Attributes:
        published: messages published per (output) topic.
        lateness_ns: per message, actual publish time minus the scheduled time (wall ns).
        skipped_topics: topics not played (type unknown to visnav), with the reason.
        clock_messages: ``/clock`` messages published.
        loops: passes over the bag completed.
        undecodable: per topic, messages skipped because their bytes do not decode.
    """

    published: dict[str, int] = dataclasses.field(default_factory=dict)
    lateness_ns: list[int] = dataclasses.field(default_factory=list)
    skipped_topics: dict[str, str] = dataclasses.field(default_factory=dict)
    clock_messages: int = 0
    loops: int = 0
    undecodable: dict[str, int] = dataclasses.field(default_factory=dict)

    @property
    def message_count(self) -> int:
        """Messages published in total."""
        return sum(self.published.values())


class BagPlayer:
    """Play a bag into ``context``'s graph.

    Args:
        context: the graph context to publish in.
        path: the bag (any format visnav reads).
        rate: playback speed factor (> 0; 2.0 plays twice as fast).
        clock_hz: publish ``/clock`` at this rate (None: no clock).
        loop: start over at the end, until :meth:`stop`.
        start_offset_s: skip this many seconds from the bag's start.
        topics: play only these topics (default all).
        remap: topic remappings ``{"from": "to"}`` or ``["from:=to"]``.
        delay_s: wait this long after creating the publishers before the first message
            (lets other processes discover them; ``ros2 bag play --delay``).
        decompress: also publish compressed image topics decoded, as Images on their base
            topic (module docstring).
        node_name: the player node's name.

    Raises:
        BagError: bad rate or offset, a topic not in the bag (closest suggested), or a bag
            that does not read.
    """

    def __init__(
        self,
        context: Context,
        path: str | Path,
        *,
        rate: float = 1.0,
        clock_hz: float | None = None,
        loop: bool = False,
        start_offset_s: float = 0.0,
        topics: Sequence[str] | None = None,
        remap: Mapping[str, str] | Sequence[str] | None = None,
        delay_s: float = 0.0,
        node_name: str = "visnav_bag_player",
        decompress: bool = False,
    ) -> None:
        if not rate > 0:
            msg = f"rate is {rate}: expected a positive factor (1.0 = recorded speed)"
            raise BagError(msg)
        if clock_hz is not None and not clock_hz > 0:
            msg = f"clock rate is {clock_hz} Hz: expected a positive rate"
            raise BagError(msg)
        if start_offset_s < 0 or delay_s < 0:
            msg = f"start offset {start_offset_s} s / delay {delay_s} s: expected >= 0"
            raise BagError(msg)
        self.context = context
        self.rate = rate
        self.clock_hz = clock_hz
        self.loop = loop
        self.delay_s = delay_s
        self.remap = parse_remaps(remap)
        self._reader = BagReader(path)
        self.path = self._reader.path
        self.topics = self._reader.check_topics(topics)
        self.start_ns = self._reader.start_ns + round(start_offset_s * 1e9)
        if self._reader.message_count and self.start_ns > self._reader.end_ns:
            duration = (self._reader.end_ns - self._reader.start_ns) / 1e9
            msg = (
                f"start offset {start_offset_s} s is past the end of bag '{self.path}' "
                f"(duration {duration:.3f} s)"
            )
            raise BagError(msg)
        self._node_name = node_name
        self.decompress = decompress
        self._decoded: dict[str, tuple[Publisher[Any], str]] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.stats = PlayStats()
        self.error: Exception | None = None

    # ------------------------------------------------------------------ control
    def start(self) -> None:
        """Play in a background thread (see :meth:`wait` and :meth:`stop`)."""
        if self._thread is not None:
            return
        self._thread = threading.Thread(
            target=self._run_thread, name="visnav-bag-play", daemon=True
        )
        self._thread.start()

    def _run_thread(self) -> None:
        try:
            self.play()
        except Exception as exc:  # noqa: BLE001 - re-raised by wait()
            self.error = exc

    def stop(self) -> None:
        """Ask playback to end (returns at once; see :meth:`wait`)."""
        self._stop.set()

    def wait(self, timeout_s: float | None = None) -> bool:
        """Wait for a background playback to end; True if it ended.

        Raises:
            Exception: what the playback thread raised, if anything.
        """
        if self._thread is not None:
            self._thread.join(timeout_s)
            if self._thread.is_alive():
                return False
        if self.error is not None:
            raise self.error
        return True

    def close(self) -> None:
        """Release the bag without playing (play() does this itself when it ends)."""
        self._reader.close()

    @property
    def done(self) -> bool:
        """True once a background playback ended."""
        return self._thread is not None and not self._thread.is_alive()

    # ------------------------------------------------------------------ playback
    def _publishers(self, node: Node) -> dict[str, tuple[Publisher[Any], str]]:
        pubs: dict[str, tuple[Publisher[Any], str]] = {}
        for name in self.topics:
            meta = self._reader.topics[name]
            if not meta.native:
                reason = (
                    f"type {meta.type_name} is not visnav's (or its definition in the bag "
                    "differs), so it cannot be published"
                )
                self.stats.skipped_topics[name] = reason
                node.get_logger().warning(f"not playing '{name}': {reason}")
                continue
            out = self.remap.get(name, name)
            cls = get_message_class(meta.type_name)
            pubs[name] = (node.create_publisher(cls, out, playback_qos(meta.qos)), out)
            self.stats.published.setdefault(out, 0)
        if self.decompress:
            all_topics = ((n, m.type_name) for n, m in self._reader.topics.items())
            for base, stored in image_topics(all_topics).items():
                if stored != base and stored in pubs:
                    out = self.remap.get(base, base)
                    qos = playback_qos(self._reader.topics[stored].qos)
                    self._decoded[stored] = (node.create_publisher(Image, out, qos), out)
                    self.stats.published.setdefault(out, 0)
        return pubs

    def _decode_image(self, topic: str, msg: Any) -> Image | None:
        """``msg`` decoded for ``--decompress`` (ahead of its time), None if it does not decode."""
        try:
            return decode_image(msg)
        except ValueError as exc:
            skipped = self.stats.undecodable.get(topic, 0) + 1
            self.stats.undecodable[topic] = skipped
            if skipped == 1:
                out = self._decoded[topic][1]
                _LOG.warning("%s: not decoded to %s: %s (counting any more)", topic, out, exc)
            return None

    def play(self) -> PlayStats:
        """Publish the bag (blocking) and return the statistics.

        Raises:
            BagError: the bag does not read.
        """
        node = Node(self._node_name, context=self.context)
        try:
            pubs = self._publishers(node)
            clock_pub = (
                node.create_publisher(ClockMsg, "/clock", _CLOCK_QOS) if self.clock_hz else None
            )
            if self.delay_s and self._stop.wait(self.delay_s):
                return self.stats
            while not self._stop.is_set():
                self._pass(pubs, clock_pub)
                self.stats.loops += 1
                if not self.loop or not pubs:
                    break
        finally:
            node.destroy_node()
            self._reader.close()
        return self.stats

    def _pass(
        self, pubs: dict[str, tuple[Publisher[Any], str]], clock_pub: Publisher[Any] | None
    ) -> None:
        t0 = self.start_ns
        period = round(1e9 / self.clock_hz) if self.clock_hz else 0
        stats = self.stats
        inv_rate = 1.0 / self.rate
        w0 = 0  # wall time (monotonic ns) of bag time t0, set when the first message is ready
        next_clock = 0

        def clock_until(deadline: int) -> bool:
            """Wait until ``deadline`` (monotonic ns), publishing /clock; False if stopped."""
            nonlocal next_clock
            while True:
                now = time.monotonic_ns()
                if clock_pub is not None and now >= next_clock:
                    bag_now = t0 + round((now - w0) * self.rate)
                    clock_pub.publish(ClockMsg(clock=ns_to_time(bag_now)))
                    stats.clock_messages += 1
                    next_clock += period * max(1, (now - next_clock) // period + 1)
                if now >= deadline:
                    return True
                wake = deadline if clock_pub is None else min(deadline, next_clock)
                if self._stop.wait(max(0, wake - now) / 1e9):
                    return False

        for raw in self._reader.raw_messages(list(pubs), start_ns=t0):
            try:
                msg = self._reader.decode(raw)  # read and decode ahead of the message's time
            except CorruptBagError as exc:
                skipped = stats.undecodable.get(raw.topic, 0) + 1
                stats.undecodable[raw.topic] = skipped
                if skipped == 1:
                    _LOG.warning("%s; skipping it (and counting any more on that topic)", exc)
                continue
            image = self._decode_image(raw.topic, msg) if raw.topic in self._decoded else None
            if not w0:
                # Start the clock once the first message is in hand, so opening the bag and
                # reading its first chunk does not delay the first message against the rest.
                w0 = next_clock = time.monotonic_ns()
            target = w0 + round((raw.t_ns - t0) * inv_rate)
            if not clock_until(target):
                return
            pub, out = pubs[raw.topic]
            stats.lateness_ns.append(time.monotonic_ns() - target)
            pub.publish(msg)
            stats.published[out] += 1
            if image is not None:
                decoded_pub, decoded_out = self._decoded[raw.topic]
                decoded_pub.publish(image)
                stats.published[decoded_out] += 1
        if clock_pub is not None and w0 and not self._stop.is_set():
            clock_until(time.monotonic_ns())
