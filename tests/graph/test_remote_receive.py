"""The remote receive path: two contexts (two Zenoh sessions) in one process, same domain."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
import zenoh

from visnav.graph import (
    Context,
    HistoryPolicy,
    MessageInfo,
    Node,
    Publisher,
    QoSProfile,
    Subscription,
)
from visnav.msgs import Header, Image, String, make, ns_to_time
from visnav.msgs.serde import serialize

RELIABLE_ALL = QoSProfile(depth=1, history=HistoryPolicy.KEEP_ALL)  # blocks, never drops


@pytest.fixture
def pair(domain: int) -> Iterator[tuple[Node, Node]]:
    with Context(domain) as a, Context(domain) as b:
        yield Node("sender", context=a), Node("receiver", context=b)


def _wait_matched(pub: Publisher[Any], rx: Context, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        rx.spin_once(0.01)
        pub.node.context.spin_once(0.0)
        zpub = pub._zpub
        if pub.get_subscription_count() >= 1 and zpub is not None and zpub.has_subscribers:
            return
    pytest.fail(f"publisher on {pub.topic_name} never matched a remote subscription")


def _wait_queued(sub: Subscription[Any], last_seq: int, timeout_s: float = 10.0) -> None:
    """Wait (without spinning) until the sample with ``last_seq`` sits in ``sub``'s queue."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        queue = list(sub.queue)
        info = queue[-1][1] if queue else None
        if info is not None and info.publication_sequence_number >= last_seq:
            return
        time.sleep(0.005)
    pytest.fail(f"sample {last_seq} never reached the queue of {sub.topic_name}")


def _image(value: int) -> Any:
    return make(
        Image,
        header=Header(stamp=ns_to_time(value), frame_id="cam"),
        height=480,
        width=640,
        encoding="rgb8",
        step=640 * 3,
        data=np.full(480 * 640 * 3, value, np.uint8),
    )


def test_keep_last_depth_is_respected_across_processes(pair: tuple[Node, Node]) -> None:
    tx, rx = pair
    got: list[tuple[str, MessageInfo]] = []
    sub = rx.create_subscription(String, "/t", lambda m, i: got.append((m.data, i)), 3)
    pub = tx.create_publisher(String, "/t", RELIABLE_ALL)
    _wait_matched(pub, rx.context)
    t0 = time.time_ns()
    for i in range(10):
        pub.publish(String(data=str(i)))
    _wait_queued(sub, 10)
    assert len(sub.queue) == 3
    # small payloads are copied on arrival: they must not pin Zenoh's receive batches
    assert all(isinstance(p, bytes) for p, _, _ in sub.queue)
    assert rx.context.spin_some() == 3
    assert [d for d, _ in got] == ["7", "8", "9"]
    infos = [i for _, i in got]
    assert [i.publication_sequence_number for i in infos] == [8, 9, 10]
    assert all(not i.from_this_process and i.publisher_zid == tx.context.zid for i in infos)
    assert all(t0 <= i.source_timestamp_ns <= i.received_timestamp_ns for i in infos)


def test_received_images_stay_valid_after_later_ones(pair: tuple[Node, Node]) -> None:
    # the receiver holds 150 undelivered full-size images, more than the sender's 64 MiB
    # shared-memory pool: the sender falls back to the socket instead of blocking, and
    # every message keeps its own bytes (nothing is reused or overwritten)
    tx, rx = pair
    got: list[Any] = []
    sub = rx.create_subscription(Image, "/img", lambda m, i: got.append(m), 200)
    pub = tx.create_publisher(Image, "/img", RELIABLE_ALL)
    _wait_matched(pub, rx.context)
    n = 150

    def send() -> None:
        for i in range(n):
            pub.publish(_image(i))

    sender = threading.Thread(target=send, daemon=True)
    sender.start()
    sender.join(20.0)
    assert not sender.is_alive(), "publishing blocked on the full shared-memory pool"
    _wait_queued(sub, n)
    assert any(p.as_shm() is None for p, _, _ in sub.queue)  # some went by socket
    assert rx.context.spin_some() == n
    for i, m in enumerate(got):  # checked only after all arrived and all were delivered
        assert m.header.stamp.nanosec == i
        assert m.data.shape == (480 * 640 * 3,)
        assert m.data.min() == m.data.max() == i
    assert len({id(m.data.base) for m in got}) == n  # no two messages share a buffer


def test_malformed_remote_sample_is_dropped_with_a_warning(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with Context(transport="local") as ctx:
        node = Node("n", context=ctx)
        got: list[str] = []
        sub = node.create_subscription(String, "/s", lambda m: got.append(m.data), 5)
        sub.on_remote(zenoh.ZBytes(b"\x00\x01\x00\x00\xff\xff\xff\x7f"), None)
        sub.on_remote(serialize(String(data="ok")), None)
        with caplog.at_level(logging.WARNING):
            ctx.spin_some()
    assert got == ["ok"]
    assert "dropped a sample on '/s'" in caplog.text


def test_destroyed_subscription_gets_no_pending_messages() -> None:
    with Context(transport="local") as ctx:
        node = Node("n", context=ctx)
        got: list[str] = []
        sub = node.create_subscription(String, "/s", lambda m: got.append(m.data), 5)
        sub.on_remote(serialize(String(data="late")), None)
        node.create_publisher(String, "/s", 5).publish(String(data="local"))
        sub.destroy()
        assert ctx.spin_some() == 0
    assert got == []
