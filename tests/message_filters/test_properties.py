"""Hypothesis property tests of the synchronizers on random stamp streams.

Stamps are small integer nanoseconds so that ties and equal stamps are common.
The brute-force references enumerate every candidate set, so inputs stay small.
"""

from __future__ import annotations

import itertools
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.message_filters import ApproximateTime, ApproximateTimeSynchronizer, SimpleFilter
from visnav.msgs import Header, Time

Streams = list[list[int]]


@st.composite
def streams_and_order(
    draw: st.DrawFn, *, max_len: int = 7, min_gap: int = 0, n_inputs: tuple[int, int] = (2, 3)
) -> tuple[Streams, list[int]]:
    """Per-input non-decreasing stamps (gaps >= min_gap) and an arrival order of inputs."""
    n = draw(st.integers(*n_inputs))
    streams = []
    for _ in range(n):
        gaps = draw(st.lists(st.integers(min_gap, 12), max_size=max_len))
        start = draw(st.integers(0, 10))
        streams.append(list(itertools.accumulate(gaps, initial=start))[1:])
    order = [i for i, s in enumerate(streams) for _ in s]
    order = draw(st.permutations(order))
    return streams, list(order)


def run_policy(
    streams: Streams, order: list[int], queue_size: int = 1000, **kw: Any
) -> list[tuple[int, ...]]:
    """Feed the streams in the given arrival order; return the sets as per-input indices."""
    sync = ApproximateTime(None, queue_size, num_inputs=len(streams), **kw)
    out: list[tuple[int, ...]] = []

    def cb(*payloads: tuple[int, int]) -> None:
        assert [p[0] for p in payloads] == list(range(len(streams)))  # input i in slot i
        out.append(tuple(p[1] for p in payloads))

    sync.register_callback(cb)
    nxt = [0] * len(streams)
    for i in order:
        sync.add(i, (i, nxt[i]), stamp=streams[i][nxt[i]])
        nxt[i] += 1
    return out


def span(streams: Streams, idx: tuple[int, ...]) -> int:
    stamps = [streams[i][k] for i, k in enumerate(idx)]
    return max(stamps) - min(stamps)


def check_once_and_never_cross(sets: list[tuple[int, ...]]) -> None:
    n = len(sets[0]) if sets else 0
    for i in range(n):
        used = [s[i] for s in sets]
        assert len(used) == len(set(used)), f"input {i} message reused: {sets}"
    # Brute force over all pairs: either S_i <= T_i for every i, or T_i <= S_i for every i.
    for a, b in itertools.combinations(sets, 2):
        assert all(x < y for x, y in zip(a, b, strict=True)) or all(
            x > y for x, y in zip(a, b, strict=True)
        ), f"sets cross: {a} {b}"
    # ... and they come out in time order.
    for a, b in itertools.pairwise(sets):
        assert all(x < y for x, y in zip(a, b, strict=True)), f"set went back in time: {a} {b}"


@settings(max_examples=300, deadline=None)
@given(
    data=streams_and_order(),
    queue_size=st.integers(1, 6),
    age_penalty=st.sampled_from([0.0, 0.1, 1.0]),
    max_interval=st.none() | st.integers(0, 15),
    bound=st.none() | st.integers(0, 6),
)
def test_policy_once_monotone_never_cross(
    data: tuple[Streams, list[int]],
    queue_size: int,
    age_penalty: float,
    max_interval: int | None,
    bound: int | None,
) -> None:
    streams, order = data
    sets = run_policy(
        streams,
        order,
        queue_size,
        age_penalty=age_penalty,
        max_interval_duration=None if max_interval is None else max_interval * 1e-9,
        inter_message_lower_bounds=None if bound is None else bound * 1e-9,
    )
    check_once_and_never_cross(sets)
    if max_interval is not None:
        assert all(span(streams, s) <= max_interval for s in sets)


def contiguous_min_span(streams: Streams, prev: tuple[int, ...] | None) -> int | None:
    """Brute force: the smallest span of a set after ``prev`` contiguous to it."""
    first = [0] * len(streams) if prev is None else [k + 1 for k in prev]
    best = None
    for idx in itertools.product(*(range(f, len(s)) for f, s in zip(first, streams, strict=True))):
        if any(k == f for k, f in zip(idx, first, strict=True)):
            size = span(streams, idx)
            best = size if best is None else min(best, size)
    return best


@settings(max_examples=300, deadline=None)
@given(data=streams_and_order(max_len=6))
def test_policy_sets_are_minimal_among_contiguous_sets(data: tuple[Streams, list[int]]) -> None:
    streams, order = data
    sets = run_policy(streams, order, age_penalty=0.0)
    prev = None
    for s in sets:
        first = [0] * len(streams) if prev is None else [k + 1 for k in prev]
        assert any(k == f for k, f in zip(s, first, strict=True)), f"{s} not contiguous to {prev}"
        assert span(streams, s) == contiguous_min_span(streams, prev), (streams, sets, s)
        prev = s


@settings(max_examples=200, deadline=None)
@given(data=streams_and_order(), other=st.randoms(use_true_random=False))
def test_policy_output_depends_only_on_stamps(data: tuple[Streams, list[int]], other: Any) -> None:
    streams, order = data
    shuffled = list(order)
    other.shuffle(shuffled)
    a = run_policy(streams, order)
    b = run_policy(streams, shuffled)
    shorter, longer = sorted((a, b), key=len)
    assert longer[: len(shorter)] == shorter  # same sets; only how many are proved so far differs


@settings(max_examples=200, deadline=None)
@given(data=streams_and_order(min_gap=4), bound=st.integers(0, 4))
def test_true_lower_bounds_do_not_change_sets(data: tuple[Streams, list[int]], bound: int) -> None:
    streams, order = data
    plain = run_policy(streams, order)
    bounded = run_policy(streams, order, inter_message_lower_bounds=bound * 1e-9)
    assert bounded[: len(plain)] == plain
    assert len(bounded) >= len(plain)  # the bounds only prove sets sooner


class _Msg:
    def __init__(self, i: int, k: int, ns: int) -> None:
        self.header = Header(stamp=Time(sec=0, nanosec=ns), frame_id="")
        self.key = (i, k)
        self.ns = ns


@settings(max_examples=300, deadline=None)
@given(data=streams_and_order(), queue_size=st.integers(1, 6), slop=st.integers(1, 15))
def test_ros1_approximate_properties(
    data: tuple[Streams, list[int]], queue_size: int, slop: int
) -> None:
    streams, order = data
    inputs = [SimpleFilter() for _ in streams]
    sync = ApproximateTimeSynchronizer(inputs, queue_size, slop * 1e-9)
    out: list[tuple[_Msg, ...]] = []
    sync.register_callback(lambda *msgs: out.append(msgs))
    nxt = [0] * len(streams)
    for i in order:
        before = len(out)
        msg = _Msg(i, nxt[i], streams[i][nxt[i]])
        inputs[i].signal_message(msg)
        nxt[i] += 1
        assert len(out) - before <= 1  # at most one set per message
        if len(out) > before:
            assert out[-1][i] is msg  # the set contains the message that completed it
    keys = [m.key for s in out for m in s]
    assert len(keys) == len(set(keys))  # no message used twice
    for s in out:
        assert [m.key[0] for m in s] == list(range(len(streams)))
        assert max(m.ns for m in s) - min(m.ns for m in s) < slop
