"""``bag play``: timing, rate, topic filter, remap, /clock, offset, loop, latched topics."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from visnav.bag import BagError, BagPlayer, BagWriter, TopicNotInBagError
from visnav.bag.qos import latched_qos
from visnav.graph import Context, MessageInfo, Node
from visnav.graph.qos import qos_profile_latched
from visnav.msgs import Clock, String, serialize, time_to_ns

MS = 1_000_000
T0 = 1_700_000_000 * 1_000_000_000
OFFSETS_MS = [0, 50, 100, 150, 250, 300]


@pytest.fixture
def timed_bag(tmp_path: Path) -> Path:
    """/a at OFFSETS_MS, /b once at 20 ms, /latched (transient local) at 10 ms."""
    with BagWriter(tmp_path / "timed") as w:
        a = w.add_topic("/a", "std_msgs/msg/String")
        b = w.add_topic("/b", "std_msgs/msg/String")
        lat = w.add_topic("/latched", "std_msgs/msg/String", qos=[latched_qos()])
        w.write(lat, T0 + 10 * MS, serialize(String(data="map")))
        w.write(b, T0 + 20 * MS, serialize(String(data="b")))
        for i, off in enumerate(OFFSETS_MS):
            w.write(a, T0 + off * MS, serialize(String(data=str(i))))
    return w.path


def _collect(ctx: Context, topic: str, out: list[tuple[int, str]]) -> None:
    node = Node(f"sub{len(ctx.nodes)}", context=ctx)

    def cb(msg: Any, info: MessageInfo) -> None:
        out.append((info.received_timestamp_ns, msg.data))

    node.create_subscription(String, topic, cb, 100)


def _play(ctx: Context, player: BagPlayer, timeout: float = 5.0) -> None:
    player.start()
    assert ctx.spin_until(lambda: player.done, timeout)
    ctx.spin_some()
    player.wait()


@pytest.mark.parametrize("rate", [1.0, 2.0])
def test_play_keeps_recorded_timing(local_ctx: Context, timed_bag: Path, rate: float) -> None:
    got: list[tuple[int, str]] = []
    _collect(local_ctx, "/a", got)
    player = BagPlayer(local_ctx, timed_bag, rate=rate)
    _play(local_ctx, player)
    assert [d for _, d in got] == [str(i) for i in range(len(OFFSETS_MS))]
    # ms after the first /a message minus the recorded offset / rate: never early (the player
    # waits for each message's time), and never late by half the bag: a player that ignored the
    # rate or did not wait would be 150 ms off. How close it keeps the timing on a quiet machine
    # is measured in bench/bench_bag.py (a loaded machine adds tens of ms of scheduling jitter).
    errors = [
        ((t - got[0][0]) - off * MS / rate) / MS
        for (t, _), off in zip(got, OFFSETS_MS, strict=True)
    ]
    first_late_ms = player.stats.lateness_ns[0] / MS  # /a "0" is the bag's first message
    assert min(errors) >= -first_late_ms - 0.5, (errors, first_late_ms)
    assert max(errors) < 100.0, errors
    assert player.stats.published == {"/a": 6, "/b": 1, "/latched": 1}


def test_play_topics_and_remap(local_ctx: Context, timed_bag: Path) -> None:
    x: list[tuple[int, str]] = []
    b: list[tuple[int, str]] = []
    _collect(local_ctx, "/x", x)
    _collect(local_ctx, "/b", b)
    player = BagPlayer(local_ctx, timed_bag, rate=4.0, topics=["/a"], remap=["/a:=/x"])
    _play(local_ctx, player)
    assert [d for _, d in x] == ["0", "1", "2", "3", "4", "5"]
    assert b == []
    assert player.stats.published == {"/x": 6}


def test_play_publishes_clock(local_ctx: Context, timed_bag: Path) -> None:
    node = Node("clock_listener", context=local_ctx)
    clocks: list[int] = []
    node.create_subscription(Clock, "/clock", lambda m: clocks.append(time_to_ns(m.clock)), 100)
    player = BagPlayer(local_ctx, timed_bag, clock_hz=100.0)
    _play(local_ctx, player)
    assert len(clocks) >= 20  # 300 ms at 100 Hz
    assert clocks == sorted(clocks)
    assert T0 <= clocks[0] < T0 + 20 * MS
    assert T0 + 280 * MS <= clocks[-1] <= T0 + 400 * MS
    assert player.stats.clock_messages == len(clocks)


def test_play_start_offset(local_ctx: Context, timed_bag: Path) -> None:
    got: list[tuple[int, str]] = []
    _collect(local_ctx, "/a", got)
    _play(local_ctx, BagPlayer(local_ctx, timed_bag, start_offset_s=0.12, rate=4.0))
    assert [d for _, d in got] == ["3", "4", "5"]
    with pytest.raises(BagError, match="past the end"):
        BagPlayer(local_ctx, timed_bag, start_offset_s=5.0)


def test_play_loop_until_stopped(local_ctx: Context, timed_bag: Path) -> None:
    got: list[tuple[int, str]] = []
    _collect(local_ctx, "/a", got)
    player = BagPlayer(local_ctx, timed_bag, rate=10.0, loop=True, topics=["/a"])
    player.start()
    assert local_ctx.spin_until(lambda: len(got) >= 14, 5.0)
    player.stop()
    assert player.wait(2.0)
    assert player.stats.loops >= 2
    assert [d for _, d in got[:12]] == [str(i) for i in range(6)] * 2


def test_play_latched_topic_reaches_late_subscriber(local_ctx: Context, timed_bag: Path) -> None:
    """/latched keeps transient local: a subscription made after it was played still gets it."""
    player = BagPlayer(local_ctx, timed_bag, rate=10.0, loop=True, topics=["/latched", "/a"])
    player.start()
    try:
        assert local_ctx.spin_until(lambda: player.stats.published.get("/latched", 0) >= 1, 3.0)
        node = Node("late", context=local_ctx)
        got: list[str] = []
        qos = qos_profile_latched
        node.create_subscription(String, "/latched", lambda m: got.append(m.data), qos)
        assert local_ctx.spin_until(lambda: got == ["map"], 1.0)
    finally:
        player.stop()
        player.wait(2.0)


def test_play_bad_arguments(local_ctx: Context, timed_bag: Path) -> None:
    with pytest.raises(TopicNotInBagError, match=r"did you mean /a\b"):
        BagPlayer(local_ctx, timed_bag, topics=["/aa"])
    with pytest.raises(BagError, match="rate"):
        BagPlayer(local_ctx, timed_bag, rate=0.0)
    with pytest.raises(BagError, match="from:=to"):
        BagPlayer(local_ctx, timed_bag, remap=["/a=/b"])
