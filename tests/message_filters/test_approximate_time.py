"""roscpp's ApproximateTime policy on hand-built sequences.

Each expected output was derived by stepping through the policy by hand
(pivot = latest queue head, candidate = the heads, advance the earliest head,
keep a candidate when (end - cand_end) * (1 + age_penalty) < start - cand_start,
publish when the pivot is the earliest head or no future set can be better).
"""

from __future__ import annotations

import logging
from typing import Any

import pytest

from visnav.message_filters import ApproximateTime, MessageFilterError, SimpleFilter
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


def run(
    seq: list[tuple[int, float]], n: int = 2, queue_size: int = 10, **kwargs: Any
) -> tuple[list[tuple[float, ...]], list[int]]:
    """Feed (input, seconds); return the emitted stamp tuples and the count after each."""
    sync = ApproximateTime(None, queue_size, num_inputs=n, **kwargs)
    out: list[tuple[float, ...]] = []
    counts = []
    sync.register_callback(lambda *msgs: out.append(tuple(m.t for m in msgs)))
    for topic, t in seq:
        sync.add(topic, Msg(topic, t))
        counts.append(len(out))
    return out, counts


# A: 0 . . 10 . . 20 . . 30      B: 2 . . 13 . 19 . . 31 (arrival in stamp order)
JITTER = [(0, 0), (1, 2), (0, 10), (1, 13), (1, 19), (0, 20), (0, 30), (1, 31)]


def test_exact_stamps_published_immediately() -> None:
    out, counts = run([(0, 0), (1, 0), (0, 3), (1, 3), (1, 6), (0, 6)])
    assert out == [(0, 0), (3, 3), (6, 6)]
    assert counts == [0, 1, 1, 2, 2, 3]


def test_jitter_pairs_and_latency() -> None:
    out, counts = run(JITTER)
    # (0, 2) is only known optimal when A's next message (10) shows that no later
    # A message can be closer to B's 2; (30, 31) is still waiting at the end.
    assert out == [(0, 2), (10, 13), (20, 19)]
    assert counts == [0, 0, 1, 1, 1, 2, 2, 3]


def test_jitter_with_lower_bounds_publishes_earlier_same_sets() -> None:
    out, counts = run(JITTER, inter_message_lower_bounds=5.0)
    # A next message cannot come before last + 5 s: (0, 2) is proved optimal as
    # soon as B's 2 arrives, (20, 19) as soon as A's 20 arrives, (30, 31) at 31.
    assert out == [(0, 2), (10, 13), (20, 19), (30, 31)]
    assert counts == [0, 1, 1, 1, 1, 3, 3, 4]


def test_per_input_lower_bounds() -> None:
    out, _ = run(JITTER, inter_message_lower_bounds=[5.0, 0.0])
    assert out[:3] == [(0, 2), (10, 13), (20, 19)]


def test_arrival_interleaving_does_not_change_sets() -> None:
    a_first = sorted(JITTER, key=lambda item: item[0])  # all of A, then all of B
    out, counts = run(a_first)
    assert out == [(0, 2), (10, 13), (20, 19)]
    assert counts == [0, 0, 0, 0, 1, 2, 2, 3]


def test_age_penalty_trades_quality_for_earliness() -> None:
    seq = [(0, 0.0), (1, 5.0), (0, 9.6)]
    # Candidate (0, 5) spans 5; (9.6, 5) spans 4.6 but is 4.6 s later:
    # 4.6 * 1.1 = 5.06 >= 5, so with the default penalty the earlier set is kept.
    assert run(seq)[0] == [(0.0, 5.0)]
    assert run(seq, age_penalty=0.0)[0] == [(9.6, 5.0)]


def test_max_interval_duration_drops_wide_sets() -> None:
    seq = [(0, 0), (1, 5), (0, 10), (1, 11), (0, 20)]
    assert run(seq)[0] == [(0, 5), (10, 11)]
    out, counts = run(seq, max_interval_duration=3.0)
    assert out == [(10, 11)]  # 0 and 5 are dropped: no set with them spans <= 3 s
    assert counts == [0, 0, 0, 0, 1]


def test_dropped_messages_disqualify_the_pivot_input() -> None:
    # Queue size 2: A's 0 is dropped when 2 arrives. B's 0.5 would make A's head (1)
    # the pivot, but A lost a message that might have matched 0.5 better, so 0.5 is
    # dropped instead; then (2, 1.6) beats (1, 1.6).
    out, _ = run([(0, 0), (0, 1), (0, 2), (1, 0.5), (1, 1.6)], queue_size=2)
    assert out == [(2, 1.6)]


def test_equal_span_keeps_the_earlier_candidate() -> None:
    # (10, 5) spans 5 like (0, 5): only a strictly better candidate replaces one.
    assert run([(0, 0), (1, 5), (0, 10)], age_penalty=0.0)[0] == [(0, 5)]


def test_ties_for_latest_head_pick_the_last_input_as_pivot() -> None:
    # Queue size 1: A's 3 is evicted by 6, so A has dropped messages. The heads
    # tie (A 6, B 6); roscpp takes the last input with the latest stamp, B, as
    # pivot, so the set is formed (A as pivot would have been refused).
    assert run([(0, 3), (0, 6), (1, 6)], queue_size=1)[0] == [(6, 6)]


def test_queue_size_one_drops_more() -> None:
    seq = [(0, 0), (1, 1), (1, 3), (0, 4), (1, 7), (0, 8), (0, 10), (1, 11)]
    big, _ = run(seq, queue_size=10)
    small, _ = run(seq, queue_size=1)
    assert big == [(0, 1), (4, 3), (8, 7)]
    # Size 1: B's 3 evicts 1 (B has dropped messages, so A's 0 cannot pair with B
    # as pivot and is dropped); A's 10 evicts 8 the same way, dropping B's 7.
    assert small == [(4, 3)]


def test_three_inputs() -> None:
    a = [(0, 0), (0, 10), (0, 20), (0, 30)]
    b = [(1, 1), (1, 11), (1, 19), (1, 31)]
    c = [(2, 3), (2, 9), (2, 21), (2, 29)]
    seq = sorted(a + b + c, key=lambda item: item[1])
    out, _ = run(seq, n=3)
    assert out == [(0, 1, 3), (10, 11, 9), (20, 19, 21)]


def test_each_message_once_when_one_input_is_faster() -> None:
    # A at 10 Hz, B at 2 Hz: every B message gets the nearest A message.
    seq = [(0, t / 10) for t in range(31)] + [(1, 0.02), (1, 0.51), (1, 1.04), (1, 1.49)]
    seq.sort(key=lambda item: item[1])
    out, _ = run(seq, queue_size=20)
    assert out == [(0.0, 0.02), (0.5, 0.51), (1.0, 1.04), (1.5, 1.49)]


@pytest.mark.parametrize(
    "arrival",
    [
        [(0, 1.000), (1, 1.040), (0, 1.030), (1, 1.005), (0, 1.060), (1, 1.100)],
        [(0, 1.000), (0, 1.030), (0, 1.060), (1, 1.040), (1, 1.005), (1, 1.100)],
        [(1, 1.040), (1, 1.005), (1, 1.100), (0, 1.000), (0, 1.030), (0, 1.060)],
    ],
)
def test_backwards_stamp_kept_with_one_warning_as_roscpp(
    arrival: list[tuple[int, float]], caplog: pytest.LogCaptureFixture
) -> None:
    # Issue 18 item 2: roscpp (Noetic) queues the out-of-order 1.005 and emits
    # (1.030, 1.040) then (1.060, 1.100); dropping it loses the second set.
    with caplog.at_level(logging.DEBUG, logger="visnav.message_filters"):
        out, _ = run(arrival, queue_size=5)
    assert out == [(1.030, 1.040), (1.060, 1.100)]
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1
    assert "input 1 stamp went backwards (1040000000 ns -> 1005000000 ns)" in warnings[0].message
    assert "message kept" in warnings[0].message


def test_backwards_stamp_warned_once_then_debug(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.DEBUG, logger="visnav.message_filters"):
        run([(0, 0), (0, 10), (0, 5), (0, 4)])
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1
    assert "(10000000000 ns -> 5000000000 ns)" in warnings[0].message
    assert any(
        "-> 4000000000 ns" in r.message for r in caplog.records if r.levelno == logging.DEBUG
    )


def test_backwards_stamp_with_reset_restarts_the_input(caplog: pytest.LogCaptureFixture) -> None:
    # A bag loop: both inputs jump from ~20 s back to 0 s.
    seq = [(0, 10), (1, 10), (0, 20), (1, 20.1), (0, 0), (1, 0.1), (0, 5), (1, 5)]
    with caplog.at_level(logging.WARNING, logger="visnav.message_filters"):
        out, _ = run(seq, reset=True)
    # The set still waiting at the jump, (20, 20.1), is discarded with the queues.
    assert out == [(10, 10), (0, 0.1), (5, 5)]
    assert "jumped back in time" in caplog.text


def test_lower_bound_violation_warns_and_keeps(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING, logger="visnav.message_filters"):
        out, _ = run([(0, 0), (0, 1), (1, 1)], inter_message_lower_bounds=[5.0, 0.0])
    assert "closer than its inter_message_lower_bound" in caplog.text
    assert out == [(1, 1)]


def test_headerless_dropped_and_explicit_stamp(caplog: pytest.LogCaptureFixture) -> None:
    sync = ApproximateTime(None, 5, num_inputs=2)
    got: list[Any] = []
    sync.register_callback(lambda a, b: got.append((a.data, b.data)))
    with caplog.at_level(logging.WARNING, logger="visnav.message_filters"):
        sync.add(0, String(data="a"))
    assert "without header.stamp" in caplog.text
    sync.add(0, String(data="a"), stamp=S)
    sync.add(1, String(data="b"), stamp=S)
    assert got == [("a", "b")]


def test_with_input_filters_and_topic_names(caplog: pytest.LogCaptureFixture) -> None:
    a, b = SimpleFilter(), SimpleFilter()
    a.topic = "left/image"  # type: ignore[attr-defined]  # as Subscriber has
    sync = ApproximateTime([a, b], 5)
    got: list[Any] = []
    sync.register_callback(lambda x, y: got.append((x.t, y.t)))
    a.signal_message(Msg(0, 1.0))
    b.signal_message(Msg(1, 1.0))
    assert got == [(1.0, 1.0)]
    with caplog.at_level(logging.WARNING, logger="visnav.message_filters"):
        a.signal_message(Msg(0, 0.5))
    assert "input 0 (left/image) stamp went backwards" in caplog.text


def test_callback_may_feed_the_synchronizer_again() -> None:
    sync = ApproximateTime(None, 5, num_inputs=2)
    got: list[Any] = []

    def cb(x: Msg, y: Msg) -> None:
        got.append((x.t, y.t))
        if x.t == 1:
            sync.add(0, Msg(0, 2))
            sync.add(1, Msg(1, 2))

    sync.register_callback(cb)
    sync.add(0, Msg(0, 1))
    sync.add(1, Msg(1, 1))
    assert got == [(1, 1), (2, 2)]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"num_inputs": 1}, "expected at least 2"),
        ({}, "expected at least 2"),
        ({"num_inputs": 2, "age_penalty": -0.5}, "age_penalty is -0.5"),
        ({"num_inputs": 2, "max_interval_duration": -1.0}, "max_interval_duration is -1.0"),
        ({"num_inputs": 2, "inter_message_lower_bounds": [0.1]}, "has 1 values"),
        ({"num_inputs": 2, "inter_message_lower_bounds": [0.1, -1]}, r"bounds\[1\] is -1"),
    ],
)
def test_bad_parameters(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(MessageFilterError, match=match):
        ApproximateTime(None, 5, **kwargs)


def test_bad_queue_size_and_index() -> None:
    with pytest.raises(MessageFilterError, match="queue_size is 0"):
        ApproximateTime(None, 0, num_inputs=2)
    with pytest.raises(MessageFilterError, match="num_inputs is 3 but fs has 2"):
        ApproximateTime([SimpleFilter(), SimpleFilter()], 5, num_inputs=3)
    sync = ApproximateTime(None, 5, num_inputs=2)
    with pytest.raises(
        MessageFilterError, match=r"index is 2: expected an input number in \[0, 2\)"
    ):
        sync.add(2, Msg(0, 1))
    with pytest.raises(MessageFilterError, match=r"stamp is 1\.5"):
        sync.add(0, Msg(0, 1), stamp=1.5)  # type: ignore[arg-type]
