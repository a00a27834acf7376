"""Publisher-side pacing: keep-last publishers skip samples no remote subscription can take."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from types import SimpleNamespace
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from zenoh import ZBytes

from visnav.graph import Context, DurabilityPolicy, HistoryPolicy, Node, QoSProfile
from visnav.graph.transport_pace import (
    PACE_CHUNK,
    PACE_LEASE_S,
    PaceTracker,
    pace_key,
    parse_pace_report,
)
from visnav.msgs import String, Twist

RELIABLE_ALL = QoSProfile(depth=1, history=HistoryPolicy.KEEP_ALL)


@pytest.fixture
def pair(domain: int) -> Iterator[tuple[Node, Node]]:
    with Context(domain) as a, Context(domain) as b:
        yield Node("sender", context=a), Node("receiver", context=b)


def _wait(what: str, cond: Callable[[], bool], timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not cond():
        assert time.monotonic() < deadline, what
        time.sleep(0.005)


def _matched(pub: Any, subs: int = 1) -> None:
    zpub = pub._zpub
    key = zpub._pace._key
    ctx = pub.node.context
    _wait("publisher never matched", lambda: zpub.has_subscribers)
    _wait("subscriptions not in the graph", lambda: len(ctx.remote_subscriptions(key)) == subs)
    time.sleep(0.2)  # the pace reporters' and trackers' declarations


def _publish_until_skipping(pub: Any, timeout_s: float = 10.0) -> None:
    """Publish until the publisher has heard of the pause (it then skips)."""
    deadline = time.monotonic() + timeout_s
    while pub._zpub.skipped == 0:
        assert time.monotonic() < deadline, "the publisher never heard of the pause"
        pub.publish(String(data="-1"))
        time.sleep(0.002)


def _spin_until_quiet(ctx: Context, quiet_s: float = 0.5) -> None:
    last = time.monotonic()
    while time.monotonic() - last < quiet_s:
        if ctx.spin_once(0.05):
            last = time.monotonic()


def test_publisher_skips_samples_while_its_only_subscription_is_paused(
    pair: tuple[Node, Node],
) -> None:
    tx, rx = pair
    got: list[int] = []
    sub = rx.create_subscription(String, "/p", lambda m: got.append(int(m.data)), 3, paced=True)
    pub = tx.create_publisher(String, "/p", 3)
    _matched(pub)
    pub.publish(String(data="0"))
    rx.context.spin_until(lambda: got == [0], 10.0)
    sub.pause()
    _publish_until_skipping(pub)
    skipped = pub._zpub.skipped
    for i in range(50):
        pub.publish(String(data=str(i)))
    assert pub._zpub.skipped == skipped + 50  # none of them was serialized or sent
    time.sleep(3 * PACE_LEASE_S)  # the paused report is repeated: still skipping
    pub.publish(String(data="50"))
    assert pub._zpub.skipped == skipped + 51
    _spin_until_quiet(rx.context, 0.2)
    got.clear()
    sub.resume()
    _wait("the publisher never heard of the resume", pub._zpub.wants_sample)
    for i in range(100, 103):
        pub.publish(String(data=str(i)))
    _spin_until_quiet(rx.context)
    assert got[-3:] == [100, 101, 102]
    assert sub.dropped >= 51  # the skipped samples are gaps in the publisher's numbering


def test_a_subscription_that_is_not_paced_keeps_samples_flowing(domain: int) -> None:
    with Context(domain) as a, Context(domain) as b, Context(domain) as c:
        tx = Node("sender", context=a)
        paced = Node("paced", context=b).create_subscription(
            String, "/q", lambda m: None, 3, paced=True
        )
        got: list[str] = []
        Node("plain", context=c).create_subscription(String, "/q", lambda m: got.append(m.data), 5)
        pub = tx.create_publisher(String, "/q", 3)
        _matched(pub, subs=2)
        paced.pause()
        tracker = pub._zpub._pace
        _wait("the pause report never came", lambda: bool(tracker._paused))
        for i in range(20):
            pub.publish(String(data=str(i)))
        assert pub._zpub.skipped == 0
        assert c.spin_until(lambda: "19" in got, 10.0)


def test_a_paused_report_that_is_not_repeated_expires(pair: tuple[Node, Node]) -> None:
    tx, rx = pair
    sub = rx.create_subscription(String, "/r", lambda m: None, 3, paced=True)
    pub = tx.create_publisher(String, "/r", 3)
    _matched(pub)
    sub.pause()
    _publish_until_skipping(pub)
    z = rx.context.zenoh
    assert z is not None
    z._refresher.close()  # as if the subscriber hung: no more "paused" reports
    time.sleep(PACE_LEASE_S + 0.1)
    assert pub._zpub.wants_sample()


def test_destroying_a_paused_subscription_ends_the_skipping_at_once(
    pair: tuple[Node, Node],
) -> None:
    tx, rx = pair
    sub = rx.create_subscription(String, "/s", lambda m: None, 3, paced=True)
    pub = tx.create_publisher(String, "/s", 3)
    _matched(pub)
    sub.pause()
    _publish_until_skipping(pub)
    sub.destroy()  # says "room" before going: no lease to wait for
    tracker = pub._zpub._pace
    _wait("the publisher kept the destroyed subscription paused", lambda: not tracker._paused, 1.0)


def test_latched_and_keep_all_publishers_never_skip(domain: int) -> None:
    with Context(domain) as ctx:
        node = Node("n", context=ctx)
        latched = node.create_publisher(
            String, "/l", QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        )
        keep_all = node.create_publisher(String, "/k", RELIABLE_ALL)
        keep_last = node.create_publisher(String, "/v", 2)
        assert latched._zpub._pace is None
        assert keep_all._zpub._pace is None
        assert keep_last._zpub._pace is not None


def test_reports_of_other_keys_or_malformed_ones_are_ignored(pair: tuple[Node, Node]) -> None:
    tx, rx = pair
    rx.create_subscription(String, "/t", lambda m: None, 3, paced=True)
    pub = tx.create_publisher(String, "/t", 3)
    _matched(pub)
    tracker = pub._zpub._pace
    session = rx.context.zenoh.session  # type: ignore[union-attr]
    session.put(f"{tracker._key}/_pace/zid/not-a-number", b"0")
    session.put(pace_key(tracker._key, "somebody", 7), b"0")  # not a subscription of the graph
    _wait("the report never came", lambda: ("somebody", 7) in tracker._paused)
    assert ("zid", "not-a-number") not in tracker._paused
    assert pub._zpub.wants_sample()  # the graph's subscription did not pause


def test_remote_subscriptions_are_those_of_other_sessions_with_the_key(
    pair: tuple[Node, Node],
) -> None:
    tx, rx = pair
    tx.create_subscription(String, "/u", lambda m: None, 3)  # same session: not remote
    remote = rx.create_subscription(String, "/u", lambda m: None, 3)
    rx.create_subscription(Twist, "/w", lambda m: None, 3)  # another topic
    pub = tx.create_publisher(String, "/u", 3)
    key = pub._zpub._pace._key
    ctx = tx.context
    rx_zid = rx.context.zid
    _wait("remote subscription not in the graph", lambda: bool(ctx.remote_subscriptions(key)))
    assert ctx.remote_subscriptions(key) == {(rx_zid, remote.entity_id)}
    assert ctx.remote_subscriptions("not/a key") == frozenset()


def test_parse_pace_report() -> None:
    key = pace_key("0/cam/sensor_msgs::msg::dds_::Image_/RIHS01_ab", "z1", 12)
    assert parse_pace_report(key, b"0") == (("z1", 12), False)
    assert parse_pace_report(key, b"1") == (("z1", 12), True)
    assert parse_pace_report(key, b"2") is None
    assert parse_pace_report("0/cam/_pace/z1/x", b"0") is None
    assert parse_pace_report("0/cam/_latched/z1/3", b"0") is None
    assert parse_pace_report("z1/3", b"0") is None


@settings(max_examples=300, deadline=None)
@given(key=st.text(max_size=80), payload=st.binary(max_size=4))
def test_parse_pace_report_fuzz_never_raises(key: str, payload: bytes) -> None:
    report = parse_pace_report(key, payload)
    if report is not None:
        (zid, entity), room = report
        last = key.rsplit("/", 1)[1]
        assert key.endswith(f"/{PACE_CHUNK}/{zid}/{last}")
        assert int(last) == entity >= 0
        assert room is (payload == b"1")


def test_tracker_leases_and_prunes_subscriptions_gone_paused(domain: int) -> None:
    now = [100.0]
    subs = {("z", 1)}
    with Context(domain) as ctx:
        z = ctx.zenoh
        assert z is not None
        tracker = PaceTracker(z.session, "0/t/T/H", lambda _key: subs, clock=lambda: now[0])

        def report(zid: str, entity: int, payload: bytes) -> None:
            sample = SimpleNamespace(
                key_expr=pace_key("0/t/T/H", zid, entity), payload=ZBytes(payload)
            )
            tracker._on_report(sample)  # type: ignore[arg-type]

        assert not tracker.all_paused()  # nobody reported
        report("z", 1, b"0")
        assert tracker.all_paused()
        now[0] += PACE_LEASE_S + 0.01
        assert not tracker.all_paused()  # the lease ran out
        report("z", 1, b"0")
        subs.add(("z", 2))
        assert not tracker.all_paused()  # a subscription that never paused
        report("z", 2, b"0")
        assert tracker.all_paused()
        report("z", 2, b"1")
        assert not tracker.all_paused()
        assert tracker.skipped == 2
        for entity in range(100, 170):
            report("gone", entity, b"0")
        now[0] += PACE_LEASE_S + 0.01
        report("z", 1, b"0")
        assert set(tracker._paused) == {("z", 1)}  # the expired ones were pruned
        tracker.close()


def test_a_publish_racing_the_publishers_destruction_sends_nothing_and_raises_nothing(
    pair: tuple[Node, Node],
) -> None:
    """A status publisher of an action server firing from a timer thread while its node is
    destroyed (a remote subscriber listening) raised zenoh's "Undeclared publisher"."""
    sender, receiver = pair
    got: list[String] = []
    receiver.create_subscription(String, "chatter", got.append, 10)
    pub = sender.create_publisher(String, "chatter", 10)
    _wait("the remote subscription", pub.has_listeners)
    pub.publish(String(data="before"))
    _wait("the first message", lambda: bool(receiver.context.spin_once(0.01) or got))
    pub.destroy()
    pub.publish(String(data="after"))  # from a thread that has not seen the destruction yet
    assert not pub.has_listeners()
