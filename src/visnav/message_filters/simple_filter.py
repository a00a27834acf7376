"""``SimpleFilter`` (callback fan-out) and ``Subscriber`` (a topic as a filter input).

A filter is anything that calls its registered callbacks with its output:
``Subscriber`` with each message of a topic, ``Cache`` with each message it
stores, the synchronizers with one message per input. Filters chain by
registering one filter's ``add`` on another, exactly as in ROS::

    from visnav import message_filters

    image = message_filters.Subscriber(node, Image, "camera/image_raw")
    info = message_filters.Subscriber(node, CameraInfo, "camera/camera_info")
    sync = message_filters.TimeSynchronizer([image, info], queue_size=10)
    sync.register_callback(on_pair)  # on_pair(image_msg, info_msg)
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import Any, Protocol

from visnav.message_filters.errors import MessageFilterError

__all__ = ["NodeLike", "SimpleFilter", "Subscriber"]


class SimpleFilter:
    """The base of every filter: holds callbacks and calls them with the filter's output.

    ``register_callback(cb, *args)`` returns a connection id; ``signal_message(*msgs)``
    calls every registered ``cb(*msgs, *args)`` in registration order. The ROS 1
    camelCase names (``registerCallback``, ``signalMessage``) are kept as aliases
    so ported scripts run unchanged.
    """

    def __init__(self) -> None:
        self._callbacks: dict[int, tuple[Callable[..., object], tuple[Any, ...]]] = {}
        self._next_connection = itertools.count()

    def register_callback(self, cb: Callable[..., object], /, *args: Any) -> int:
        """Register ``cb`` to be called with this filter's output followed by ``args``.

        Args:
            cb: the callable; it receives the filter-dependent messages, then ``args``.
            *args: extra arguments appended to every call.

        Returns:
            A connection id for :meth:`remove_callback`.

        Raises:
            MessageFilterError: ``cb`` is not callable.
        """
        if not callable(cb):
            text = f"callback is {cb!r} ({type(cb).__name__}): expected a callable"
            raise MessageFilterError(text)
        connection = next(self._next_connection)
        self._callbacks[connection] = (cb, args)
        return connection

    def remove_callback(self, connection: int) -> None:
        """Disconnect the callback registered under ``connection``.

        Raises:
            MessageFilterError: no callback has that id (never registered or already removed).
        """
        if self._callbacks.pop(connection, None) is None:
            text = (
                f"connection is {connection!r}: no callback is registered under that id "
                f"(registered: {sorted(self._callbacks)})"
            )
            raise MessageFilterError(text)

    def signal_message(self, *msgs: Any) -> None:
        """Call every registered callback with ``msgs`` followed by its own extra args."""
        for cb, args in list(self._callbacks.values()):
            cb(*msgs, *args)

    # ROS 1 / ROS 2 Python spellings, for scripts ported from rospy/rclpy.
    registerCallback = register_callback  # noqa: N815
    signalMessage = signal_message  # noqa: N815


class NodeLike(Protocol):
    """What :class:`Subscriber` needs from a node (``visnav.graph.Node`` fits)."""

    def create_subscription(
        self, msg_type: Any, topic: str, callback: Callable[[Any], None], qos: Any, /
    ) -> Any:
        """Subscribe ``callback`` to ``topic``; return the subscription object."""


class Subscriber(SimpleFilter):
    """A topic subscription as the first filter of a chain.

    Wraps ``node.create_subscription(msg_type, topic, callback, qos)`` and passes
    each message on to the registered callbacks.

    Args:
        node: the node that owns the subscription (``visnav.graph.Node``).
        msg_type: the message class, e.g. ``visnav.msgs.Image``.
        topic: the topic name (relative names resolve in the node's namespace).
        qos: queue depth or a ``visnav.graph.QoSProfile`` (default depth 10).

    Attributes:
        node: the node.
        msg_type: the message class.
        topic: the topic name as given.
        sub: the underlying subscription object.
    """

    def __init__(self, node: NodeLike, msg_type: type[Any], topic: str, qos: Any = 10) -> None:
        super().__init__()
        if not isinstance(topic, str) or not topic:
            text = f"topic is {topic!r}: expected a non-empty topic name such as 'image_raw'"
            raise MessageFilterError(text)
        self.node = node
        self.msg_type = msg_type
        self.topic = topic
        self.sub: Any = node.create_subscription(msg_type, topic, self._callback, qos)

    def _callback(self, msg: Any) -> None:
        self.signal_message(msg)

    def get_topic(self) -> str:
        """Return the topic name (the resolved one when the subscription exposes it)."""
        resolved = getattr(self.sub, "topic_name", None)
        if isinstance(resolved, str):
            return resolved
        resolved = getattr(self.sub, "topic", None)
        return resolved if isinstance(resolved, str) else self.topic

    def unregister(self) -> None:
        """Destroy the underlying subscription (``node.destroy_subscription`` or ``sub.destroy``).

        Raises:
            MessageFilterError: neither the node nor the subscription offers a way to destroy it.
        """
        destroy_on_node = getattr(self.node, "destroy_subscription", None)
        if callable(destroy_on_node):
            destroy_on_node(self.sub)
            return
        destroy = getattr(self.sub, "destroy", None)
        if callable(destroy):
            destroy()
            return
        text = (
            f"cannot unregister the subscription to {self.topic!r}: the node has no "
            "destroy_subscription() and the subscription no destroy()"
        )
        raise MessageFilterError(text)
