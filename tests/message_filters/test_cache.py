from __future__ import annotations

import logging
from typing import Any

import pytest

from visnav.message_filters import Cache, MessageFilterError, SimpleFilter
from visnav.msgs import Header, String, Time

S = 1_000_000_000


class Stamped:
    def __init__(self, ns: int) -> None:
        self.header = Header(stamp=Time(sec=ns // S, nanosec=ns % S), frame_id="")
        self.ns = ns

    def __repr__(self) -> str:
        return f"Stamped({self.ns})"


def filled(stamps: list[int], size: int) -> tuple[Cache, dict[int, Stamped]]:
    source = SimpleFilter()
    cache = Cache(source, cache_size=size)
    msgs = {}
    for t in stamps:
        msgs[t] = Stamped(t)
        source.signal_message(msgs[t])
    return cache, msgs


def test_ring_buffer_keeps_latest_and_signals() -> None:
    source = SimpleFilter()
    cache = Cache(source, cache_size=3)
    out: list[Any] = []
    cache.register_callback(out.append)
    msgs = [Stamped(t * S) for t in range(5)]
    for m in msgs:
        source.signal_message(m)
    assert out == msgs
    assert len(cache) == 3
    assert cache.get_oldest_time() == 2 * S
    assert cache.get_latest_time() == 4 * S
    assert cache.get_last() is msgs[4]


def test_queries() -> None:
    cache, m = filled([10, 20, 30, 40], size=10)
    assert cache.get_elem_after_time(20) is m[20]  # at or after
    assert cache.get_elem_after_time(21) is m[30]
    assert cache.get_elem_after_time(41) is None
    assert cache.get_elem_before_time(20) is m[20]  # at or before
    assert cache.get_elem_before_time(19) is m[10]
    assert cache.get_elem_before_time(9) is None
    assert cache.get_interval(15, 30) == [m[20], m[30]]
    assert cache.get_interval(20, 20) == [m[20]]
    assert cache.get_interval(41, 50) == []
    assert cache.get_surrounding_interval(15, 25) == [m[10], m[20], m[30]]
    assert cache.get_surrounding_interval(20, 30) == [m[20], m[30]]
    assert cache.get_surrounding_interval(0, 5) == [m[10]]
    assert cache.get_surrounding_interval(45, 50) == [m[40]]


def test_queries_accept_time_messages() -> None:
    cache, m = filled([S, 2 * S], size=2)
    assert cache.get_elem_after_time(Time(sec=1, nanosec=1)) is m[2 * S]
    assert cache.get_interval(Time(sec=0, nanosec=0), Time(sec=1, nanosec=0)) == [m[S]]


def test_out_of_order_inserted_sorted() -> None:
    cache, m = filled([30, 10, 20], size=10)
    assert cache.get_interval(0, 100) == [m[10], m[20], m[30]]
    assert cache.get_oldest_time() == 10
    assert cache.get_last() is m[30]


def test_empty_cache() -> None:
    cache = Cache(SimpleFilter(), cache_size=2)
    assert cache.get_latest_time() is None
    assert cache.get_oldest_time() is None
    assert cache.get_last() is None
    assert cache.get_elem_after_time(0) is None
    assert cache.get_surrounding_interval(0, 1) == []


def test_bad_arguments() -> None:
    with pytest.raises(MessageFilterError, match="cache_size is 0"):
        Cache(SimpleFilter(), cache_size=0)
    cache, _ = filled([1], size=1)
    with pytest.raises(MessageFilterError, match="from_stamp 5 ns is after to_stamp 4 ns"):
        cache.get_interval(5, 4)
    with pytest.raises(MessageFilterError, match="expected integer nanoseconds"):
        cache.get_elem_after_time(1.5)  # type: ignore[arg-type]


def test_headerless_dropped_with_warning(caplog: pytest.LogCaptureFixture) -> None:
    source = SimpleFilter()
    cache = Cache(source, cache_size=2)
    with caplog.at_level(logging.WARNING, logger="visnav.message_filters"):
        source.signal_message(String(data="x"))
    assert len(cache) == 0
    assert "without header.stamp" in caplog.text


def test_headerless_allowed_uses_clock() -> None:
    source = SimpleFilter()
    cache = Cache(source, cache_size=2, allow_headerless=True, clock=lambda: 1234)
    msg = String(data="x")
    source.signal_message(msg)
    assert cache.get_latest_time() == 1234
    assert cache.get_elem_before_time(1234) is msg
