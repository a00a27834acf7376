"""tf2_ros on the visnav graph: broadcasters and the listener that fills a :class:`Buffer`.

As in tf2_ros: ``/tf`` carries dynamic transforms (reliable, volatile, depth 100)
and ``/tf_static`` static ones (reliable, transient local, depth 1). A
:class:`StaticTransformBroadcaster` republishes the whole set it has been given
(one child frame once), so a late subscriber receives every static transform.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Sequence
from typing import Any

from visnav.graph.context import Context
from visnav.graph.message_info import MessageInfo
from visnav.graph.node import Node
from visnav.graph.qos import DurabilityPolicy, QoSProfile, qos_profile_tf_static
from visnav.msgs.types import TFMessage, TransformStamped
from visnav.tf.buffer import Buffer

__all__ = [
    "DYNAMIC_QOS",
    "STATIC_LISTENER_QOS",
    "STATIC_QOS",
    "StaticTransformBroadcaster",
    "TransformBroadcaster",
    "TransformListener",
]

DYNAMIC_QOS = QoSProfile(depth=100)
STATIC_QOS = qos_profile_tf_static
"""tf2_ros's StaticBroadcasterQoS: each broadcaster keeps its one (whole-set) message."""
STATIC_LISTENER_QOS = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
"""tf2_ros's StaticListenerQoS: room for the latched messages of many broadcasters."""


def _as_list(transform: TransformStamped | Iterable[TransformStamped]) -> list[TransformStamped]:
    if isinstance(transform, TransformStamped):
        return [transform]
    return list(transform)


class TransformBroadcaster:
    """Publishes dynamic transforms on ``/tf``.

    Args:
        node: the publishing node.
        qos: QoS of ``/tf`` (default depth 100, reliable, volatile).
    """

    def __init__(self, node: Node, qos: QoSProfile | int = DYNAMIC_QOS) -> None:
        self._pub = node.create_publisher(TFMessage, "/tf", qos)

    def send_transform(self, transform: TransformStamped | Sequence[TransformStamped]) -> None:
        """Publish one transform or a list of them in one TFMessage."""
        self._pub.publish(TFMessage(transforms=_as_list(transform)))


class StaticTransformBroadcaster:
    """Publishes static transforms on ``/tf_static`` (transient local, latched).

    Args:
        node: the publishing node.
        qos: QoS of ``/tf_static`` (default depth 1, reliable, transient local).
    """

    def __init__(self, node: Node, qos: QoSProfile | int = STATIC_QOS) -> None:
        self._pub = node.create_publisher(TFMessage, "/tf_static", qos)
        self._net: dict[str, TransformStamped] = {}

    def send_transform(self, transform: TransformStamped | Sequence[TransformStamped]) -> None:
        """Add transforms (replacing earlier ones of the same child frame) and publish the set."""
        for t in _as_list(transform):
            self._net[t.child_frame_id] = t
        self._pub.publish(TFMessage(transforms=list(self._net.values())))


class TransformListener:
    """Subscribes ``/tf`` and ``/tf_static`` and fills a :class:`Buffer`.

    As tf2_ros's listener, it reads the node's ROS time on every message and clears
    the buffer's dynamic transforms when that time jumped back (``bag play --loop``,
    a simulator reset under ``use_sim_time``): "Detected jump back in time of X s.
    Clearing TF buffer." Static transforms are kept (tf2's ``clear``).

    Args:
        buffer: the buffer to fill.
        node: the node whose executor runs the callbacks; None makes a private node.
        spin_thread: run a private node in a background thread (tf2_ros's option),
            so lookups work while the caller does not spin.
        qos: QoS of ``/tf``.
        static_qos: QoS of ``/tf_static``.
    """

    def __init__(
        self,
        buffer: Buffer,
        node: Node | None = None,
        *,
        spin_thread: bool = False,
        qos: QoSProfile | int = DYNAMIC_QOS,
        static_qos: QoSProfile | int = STATIC_LISTENER_QOS,
    ) -> None:
        self.buffer = buffer
        self._thread: threading.Thread | None = None
        self._own_ctx: Context | None = None
        if spin_thread:
            domain = node.context.domain if node is not None else None
            kind = node.context.transport_kind if node is not None else None
            self._own_ctx = Context(domain, transport=kind)
            node = Node("transform_listener", context=self._own_ctx)
        elif node is None:
            node = Node("transform_listener")
        self.node = node
        self._now_ns = node.get_clock().now_ns
        self._last_update_ns: int | None = None
        self._authorities: dict[tuple[str, int], str] = {}
        self._tf = node.create_subscription(TFMessage, "/tf", self._on_tf, qos)
        self._static = node.create_subscription(
            TFMessage, "/tf_static", self._on_static, static_qos
        )
        if self._own_ctx is not None:
            ctx = self._own_ctx
            self._thread = threading.Thread(target=ctx.spin, name="tf_listener", daemon=True)
            self._thread.start()

    def _authority(self, info: MessageInfo | None) -> str:
        if info is None:
            return "default_authority"
        key = (info.publisher_zid, info.publisher_entity_id)
        name = self._authorities.get(key)
        if name is None:
            name = self.node.context.graph.publisher_node(*key)
            if name is None:
                return "default_authority"
            self._authorities[key] = name
        return name

    def _check_for_reset(self) -> None:
        now = self._now_ns()
        last = self._last_update_ns
        if last is not None and now < last:
            self.node.get_logger().warning(
                f"Detected jump back in time of {(last - now) / 1e9:.6f}s. Clearing TF buffer."
            )
            self.buffer.clear()
        self._last_update_ns = now

    def _on_tf(self, msg: Any, info: MessageInfo | None) -> None:
        self._check_for_reset()
        authority = self._authority(info)
        for t in msg.transforms:
            self.buffer.set_transform(t, authority)

    def _on_static(self, msg: Any, info: MessageInfo | None) -> None:
        self._check_for_reset()
        authority = self._authority(info)
        for t in msg.transforms:
            self.buffer.set_transform_static(t, authority)

    def unregister(self) -> None:
        """Stop listening (and stop the background thread)."""
        self.node.destroy_subscription(self._tf)
        self.node.destroy_subscription(self._static)
        if self._own_ctx is not None:
            self._own_ctx.shutdown()
            if self._thread is not None:
                self._thread.join(timeout=2.0)
