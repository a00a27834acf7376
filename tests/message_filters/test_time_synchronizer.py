"""TimeSynchronizer (exact) and ROS 1 Python's ApproximateTimeSynchronizer.

Expected outputs are derived by hand from the ROS 1 Noetic algorithm: on each
message, other inputs' stamps within slop sorted by distance, product order,
first set with span < slop wins, at most one set per message.
"""

from __future__ import annotations

import logging
from typing import Any

import pytest

from visnav.message_filters import (
    ApproximateTimeSynchronizer,
    MessageFilterError,
    SimpleFilter,
    TimeSynchronizer,
)
from visnav.msgs import Header, String, Time

S = 1_000_000_000


class Msg:
    def __init__(self, topic: int, t: float) -> None:
        ns = round(t * S)
        self.header = Header(stamp=Time(sec=ns // S, nanosec=ns % S), frame_id="")
        self.topic = topic
        self.t = t

    def __repr__(self) -> str:
        return f"Msg({self.topic}, {self.t})"


def feed(
    sync: TimeSynchronizer, inputs: list[SimpleFilter], seq: list[tuple[int, float]]
) -> tuple[list[tuple[float, ...]], list[int]]:
    """Feed (input, seconds) pairs; return emitted stamp tuples and the count after each."""
    out: list[tuple[float, ...]] = []
    counts = []
    sync.register_callback(lambda *msgs: out.append(tuple(m.t for m in msgs)))
    for topic, t in seq:
        inputs[topic].signal_message(Msg(topic, t))
        counts.append(len(out))
    return out, counts


def make(cls: type[TimeSynchronizer], n: int, *args: Any, **kwargs: Any) -> tuple[Any, list[Any]]:
    inputs = [SimpleFilter() for _ in range(n)]
    return cls(inputs, *args, **kwargs), inputs


# ---------------------------------------------------------------- exact


def test_exact_pairs() -> None:
    sync, fs = make(TimeSynchronizer, 2, 10)
    out, counts = feed(sync, fs, [(0, 1), (0, 2), (1, 2), (0, 3), (1, 1), (1, 4), (1, 3)])
    assert out == [(2, 2), (1, 1), (3, 3)]
    assert counts == [0, 0, 1, 1, 2, 2, 3]


def test_exact_three_inputs_and_extra_args() -> None:
    sync, fs = make(TimeSynchronizer, 3, 10)
    got: list[Any] = []
    sync.register_callback(lambda a, b, c, tag: got.append((a.t, b.t, c.t, tag)), "tag")
    for topic in (2, 0, 1):
        fs[topic].signal_message(Msg(topic, 5))
    assert got == [(5, 5, 5, "tag")]


def test_exact_queue_evicts_oldest_stamp() -> None:
    sync, fs = make(TimeSynchronizer, 2, 2)
    out, _ = feed(sync, fs, [(0, 1), (0, 2), (0, 3), (1, 1), (1, 2)])
    assert out == [(2, 2)]  # stamp 1 was evicted from input 0 when 3 arrived


def test_exact_via_add_and_bad_index() -> None:
    sync, _ = make(TimeSynchronizer, 2, 3)
    got: list[Any] = []
    sync.register_callback(lambda a, b: got.append((a, b)))
    a, b = Msg(0, 1), Msg(1, 1)
    sync.add(0, a)
    sync.add(1, b)
    assert got == [(a, b)]
    with pytest.raises(MessageFilterError, match=r"expected an input number in \[0, 2\)"):
        sync.add(2, a)


def test_exact_headerless_dropped(caplog: pytest.LogCaptureFixture) -> None:
    sync, fs = make(TimeSynchronizer, 2, 3)
    with caplog.at_level(logging.WARNING, logger="visnav.message_filters"):
        fs[1].signal_message(String(data="no header"))
    assert "input 1 received a" in caplog.text
    assert sync.queues == [{}, {}]


def test_bad_construction() -> None:
    with pytest.raises(MessageFilterError, match="at least one input"):
        TimeSynchronizer([], 3)
    with pytest.raises(MessageFilterError, match="queue_size is 0"):
        TimeSynchronizer([SimpleFilter()], 0)
    with pytest.raises(MessageFilterError, match=r"slop is -0\.1"):
        ApproximateTimeSynchronizer([SimpleFilter()], 3, -0.1)
    with pytest.raises(MessageFilterError, match="slop is nan"):
        ApproximateTimeSynchronizer([SimpleFilter()], 3, float("nan"))


# ----------------------------------------------------- ROS 1 approximate


def test_approx_pairs_each_new_message_matched() -> None:
    sync, fs = make(ApproximateTimeSynchronizer, 2, 10, 0.5)
    seq = [(0, 0.0), (1, 0.3), (0, 1.0), (1, 1.2), (1, 2.0), (0, 2.6), (1, 2.5)]
    out, counts = feed(sync, fs, seq)
    # 2.6 has nothing within 0.5 (2.0 is 0.6 away); 2.5 then pairs with it.
    assert out == [(0.0, 0.3), (1.0, 1.2), (2.6, 2.5)]
    assert counts == [0, 1, 1, 2, 2, 2, 3]
    assert list(sync.queues[1]) == [2 * S]  # 2.0 stays queued, never used


def test_approx_span_must_be_strictly_below_slop() -> None:
    sync, fs = make(ApproximateTimeSynchronizer, 2, 10, 0.5)
    out, _ = feed(sync, fs, [(0, 0.0), (1, 0.5), (1, 0.4999)])
    assert out == [(0.0, 0.4999)]


def test_approx_nearest_first_in_product_order() -> None:
    sync, fs = make(ApproximateTimeSynchronizer, 3, 10, 1.0)
    seq = [(0, 0.0), (0, 0.5), (1, 0.2), (1, 0.9), (2, 0.6), (2, 0.1)]
    out, counts = feed(sync, fs, seq)
    # At 0.6: input 0 sorted by distance is [0.5, 0.0], input 1 [0.9, 0.2]; the
    # first product combination (0.5, 0.9) spans 0.4 < 1 and is taken; the next
    # message, 0.1, then matches the leftovers (0.0, 0.2).
    assert out == [(0.5, 0.9, 0.6), (0.0, 0.2, 0.1)]
    assert counts == [0, 0, 0, 0, 1, 2]


def test_approx_first_combination_not_tightest() -> None:
    sync, fs = make(ApproximateTimeSynchronizer, 3, 10, 1.0)
    # New message on input 2 at 1.0; input 0 has 1.1 (0.1 away) and 0.8 (0.2 away),
    # input 1 has 0.3 (0.7 away) only. product: (1.1, 0.3) spans 0.8 < 1: emitted,
    # though (0.8, 0.3, 1.0) would span only 0.7.
    out, _ = feed(sync, fs, [(0, 0.8), (0, 1.1), (1, 0.3), (2, 1.0)])
    assert out == [(1.1, 0.3, 1.0)]


def test_approx_sets_can_go_back_in_time(caplog: pytest.LogCaptureFixture) -> None:
    sync, fs = make(ApproximateTimeSynchronizer, 2, 10, 1.0)
    with caplog.at_level(logging.WARNING, logger="visnav.message_filters"):
        out, _ = feed(sync, fs, [(0, 0.0), (0, 2.0), (1, 2.1), (1, 0.2)])
    assert out == [(2.0, 2.1), (0.0, 0.2)]  # the second set is older: ROS 1 does this too
    assert "input 1 stamp went backwards" in caplog.text


def test_approx_queue_trim_can_drop_the_new_message() -> None:
    sync, fs = make(ApproximateTimeSynchronizer, 2, 1, 0.5)
    # Input 1 holds 5.0; 4.0 arrives, the queue (size 1) evicts the oldest stamp,
    # which is 4.0 itself, so (4.0, 4.0) cannot be emitted.
    out, _ = feed(sync, fs, [(0, 4.0), (1, 5.0), (1, 4.0)])
    assert out == []
    assert list(sync.queues[1]) == [5 * S]


def test_approx_queue_trim() -> None:
    sync, fs = make(ApproximateTimeSynchronizer, 2, 2, 0.5)
    out, _ = feed(sync, fs, [(0, 0.0), (0, 1.0), (0, 2.0), (1, 0.1), (1, 1.1)])
    assert out == [(1.0, 1.1)]  # 0.0 was evicted before 0.1 arrived


def test_approx_same_stamp_replaces() -> None:
    sync, fs = make(ApproximateTimeSynchronizer, 2, 5, 0.5)
    first, second = Msg(0, 1.0), Msg(0, 1.0)
    got: list[Any] = []
    sync.register_callback(lambda a, b: got.append(a))
    fs[0].signal_message(first)
    fs[0].signal_message(second)
    fs[1].signal_message(Msg(1, 1.0))
    assert got == [second]


def test_approx_slop_conversion_truncates_like_rospy() -> None:
    sync, _ = make(ApproximateTimeSynchronizer, 2, 5, 2.3)
    assert sync.slop == 2_299_999_999
    sync, _ = make(ApproximateTimeSynchronizer, 2, 5, 0.1)
    assert sync.slop == 100_000_000


def test_approx_headerless(caplog: pytest.LogCaptureFixture) -> None:
    sync, fs = make(ApproximateTimeSynchronizer, 2, 5, 0.1)
    with caplog.at_level(logging.WARNING, logger="visnav.message_filters"):
        fs[1].signal_message(String(data="x"))
    assert "allow_headerless=True" in caplog.text
    now = [3 * S]
    sync, fs = make(ApproximateTimeSynchronizer, 2, 5, 0.1, True, clock=lambda: now[0])
    got: list[Any] = []
    sync.register_callback(lambda a, b: got.append((a.t, b.data)))
    fs[0].signal_message(Msg(0, 3.05))
    fs[1].signal_message(String(data="x"))  # stamped 3.0 on arrival
    assert got == [(3.05, "x")]


def test_approx_single_input_passes_through() -> None:
    sync, fs = make(ApproximateTimeSynchronizer, 1, 5, 0.1)
    out, _ = feed(sync, fs, [(0, 1.0), (0, 2.0)])
    assert out == [(1.0,), (2.0,)]
