from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from visnav import message_filters
from visnav.message_filters import MessageFilterError, SimpleFilter, Subscriber
from visnav.msgs import Header, Image, String, Time
from visnav.msgs.image import numpy_to_image


class FakeSubscription:
    def __init__(self, topic: str) -> None:
        self.topic_name = "/ns/" + topic
        self.destroyed = False


class FakeNode:
    """Just the graph API Subscriber uses: create_subscription / destroy_subscription."""

    def __init__(self) -> None:
        self.subs: list[tuple[Any, str, Callable[[Any], None], Any, FakeSubscription]] = []

    def create_subscription(
        self, msg_type: Any, topic: str, callback: Callable[[Any], None], qos: Any
    ) -> FakeSubscription:
        sub = FakeSubscription(topic)
        self.subs.append((msg_type, topic, callback, qos, sub))
        return sub

    def destroy_subscription(self, sub: FakeSubscription) -> None:
        sub.destroyed = True


def test_register_and_signal_in_order_with_extra_args() -> None:
    f = SimpleFilter()
    calls: list[tuple[Any, ...]] = []
    c0 = f.register_callback(lambda *a: calls.append(("first", *a)))
    c1 = f.register_callback(lambda *a: calls.append(("second", *a)), "extra", 7)
    assert c0 != c1
    f.signal_message("m1", "m2")
    assert calls == [("first", "m1", "m2"), ("second", "m1", "m2", "extra", 7)]


def test_remove_callback_and_ids_not_reused() -> None:
    f = SimpleFilter()
    seen: list[str] = []
    c0 = f.register_callback(lambda m: seen.append("a" + m))
    f.remove_callback(c0)
    c1 = f.register_callback(lambda m: seen.append("b" + m))
    assert c1 != c0
    f.signal_message("x")
    assert seen == ["bx"]
    with pytest.raises(MessageFilterError, match="no callback is registered"):
        f.remove_callback(c0)


def test_register_non_callable_rejected() -> None:
    with pytest.raises(MessageFilterError, match="expected a callable"):
        SimpleFilter().register_callback(42)  # type: ignore[arg-type]


def test_camel_case_aliases() -> None:
    f = SimpleFilter()
    seen: list[Any] = []
    f.registerCallback(seen.append)
    f.signalMessage(1)
    assert seen == [1]


def test_subscriber_wraps_create_subscription() -> None:
    node = FakeNode()
    sub = Subscriber(node, Image, "camera/image_raw", qos=5)
    msg_type, topic, callback, qos, handle = node.subs[0]
    assert (msg_type, topic, qos) == (Image, "camera/image_raw", 5)
    assert sub.sub is handle
    assert sub.get_topic() == "/ns/camera/image_raw"
    got: list[Any] = []
    sub.register_callback(got.append)
    msg = String(data="hi")
    callback(msg)  # what the executor does on delivery
    assert got == [msg]
    sub.unregister()
    assert handle.destroyed


def test_subscriber_default_qos_and_bad_topic() -> None:
    node = FakeNode()
    message_filters.Subscriber(node, String, "chatter")
    assert node.subs[0][3] == 10
    with pytest.raises(MessageFilterError, match="topic is ''"):
        Subscriber(node, String, "")


def test_subscriber_feeds_a_synchronizer() -> None:
    node = FakeNode()
    a = Subscriber(node, Image, "a")
    b = Subscriber(node, Image, "b")
    sync = message_filters.TimeSynchronizer([a, b], 5)
    pairs: list[tuple[Any, ...]] = []
    sync.register_callback(lambda x, y: pairs.append((x, y)))
    img_a = numpy_to_image(
        np.zeros((2, 2), np.uint8),
        "mono8",
        header=Header(stamp=Time(sec=3, nanosec=0), frame_id="a"),
    )
    img_b = numpy_to_image(
        np.zeros((2, 2), np.uint8),
        "mono8",
        header=Header(stamp=Time(sec=3, nanosec=0), frame_id="b"),
    )
    node.subs[0][2](img_a)
    assert pairs == []
    node.subs[1][2](img_b)
    assert pairs == [(img_a, img_b)]
