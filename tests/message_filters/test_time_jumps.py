"""ROS time jumping back (bag loop, simulator reset) empties the stamp-keyed queues.

rospy's ApproximateTimeSynchronizer (Noetic) is the oracle: the same messages and
clock readings are fed to it in the system Python (python3-message-filters,
rospy's sim time set by hand) and to visnav's, and the emitted sets compared.
"""

from __future__ import annotations

import itertools
import json
import logging
import random
import subprocess
from typing import Any

import pytest

from visnav.message_filters import (
    ApproximateTimeSynchronizer,
    Cache,
    SimpleFilter,
    TimeSynchronizer,
)
from visnav.msgs import Header, Time

S = 1_000_000_000
SYSTEM_PYTHON = "/usr/bin/python3"


class Msg:
    def __init__(self, ns: int) -> None:
        self.header = Header(stamp=Time(sec=ns // S, nanosec=ns % S), frame_id="")
        self.ns = ns


class FakeClock:
    def __init__(self) -> None:
        self.now = 0

    def __call__(self) -> int:
        return self.now


Event = tuple[int, int, int]  # (input, stamp ns, ROS time ns at arrival)


def run_visnav(events: list[Event], queue_size: int, slop: float) -> list[list[int]]:
    clock = FakeClock()
    a, b = SimpleFilter(), SimpleFilter()
    sync = ApproximateTimeSynchronizer([a, b], queue_size, slop, clock=clock)
    out: list[list[int]] = []
    sync.register_callback(lambda x, y: out.append([x.ns, y.ns]))
    for index, stamp, now in events:
        clock.now = now
        (a, b)[index].signal_message(Msg(stamp))
    return out


ORACLE = r"""
import json, sys
import rospy, rospy.rostime as rt
import message_filters as mf
from std_msgs.msg import Header
rt.set_rostime_initialized(True)
class M:
    def __init__(self, ns):
        self.header = Header(stamp=rospy.Time(ns // 10**9, ns % 10**9))
def run(events, queue_size, slop):
    a, b = mf.SimpleFilter(), mf.SimpleFilter()
    sync = mf.ApproximateTimeSynchronizer([a, b], queue_size, slop)
    out = []
    sync.registerCallback(
        lambda x, y: out.append([x.header.stamp.to_nsec(), y.header.stamp.to_nsec()]))
    for index, stamp, now in events:
        rt._set_rostime(rospy.Time(now // 10**9, now % 10**9))
        (a, b)[index].signalMessage(M(stamp))
    return out
print(json.dumps([run(*case) for case in json.loads(sys.argv[1])]))
"""


def rospy_available() -> bool:
    probe = subprocess.run(
        [SYSTEM_PYTHON, "-c", "import rospy, message_filters, std_msgs.msg"],
        capture_output=True,
        check=False,
    )
    return probe.returncode == 0


def run_rospy(cases: list[tuple[list[Event], int, float]]) -> list[list[list[int]]]:
    """Run rospy's synchronizer on each (events, queue_size, slop) in one subprocess."""
    done = subprocess.run(
        [SYSTEM_PYTHON, "-c", ORACLE, json.dumps(cases)],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    result: list[list[list[int]]] = json.loads(done.stdout)
    return result


# A bag of 2 s played twice: stamps and ROS time restart at 1 s.
LOOP: list[Event] = [
    (0, 1_000_000_000, 1_000_000_000),
    (1, 1_010_000_000, 1_010_000_000),  # -> (1.00, 1.01)
    (0, 2_000_000_000, 2_000_000_000),  # waits for its partner when the bag starts over
    (0, 1_000_000_000, 1_000_000_000),  # jump back: every queue cleared, this one too
    (0, 1_100_000_000, 1_100_000_000),
    (1, 1_110_000_000, 1_110_000_000),  # -> (1.10, 1.11)
    (1, 2_010_000_000, 2_010_000_000),  # would pair with the stale 2.00 without the reset
]


def test_approximate_sync_clears_every_queue_on_a_jump_back(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with caplog.at_level(logging.INFO, logger="visnav.message_filters"):
        out = run_visnav(LOOP, 10, 0.05)
    assert out == [[1_000_000_000, 1_010_000_000], [1_100_000_000, 1_110_000_000]]
    assert "Detected jump back in time of 1.000 s. Clearing buffer." in caplog.text


@pytest.mark.skipif(not rospy_available(), reason="python3-message-filters (rospy) absent")
def test_loop_equals_rospy() -> None:
    assert [run_visnav(LOOP, 10, 0.05)] == run_rospy([(LOOP, 10, 0.05)])


def jumpy_events(rng: random.Random) -> list[Event]:
    """Stamps near a ROS time that advances and sometimes jumps back."""
    now = 5 * S
    events: list[Event] = []
    for _ in range(rng.randint(2, 40)):
        if rng.random() < 0.1:
            now = max(S // 10, now - rng.randint(1, 3 * S))  # jump back
        else:
            now += rng.randint(0, 40_000_000)
        stamp = max(0, now - rng.randint(0, 60_000_000))
        events.append((rng.randint(0, 1), stamp, now))
    return events


@pytest.mark.skipif(not rospy_available(), reason="python3-message-filters (rospy) absent")
def test_random_jumps_equal_rospy() -> None:
    rng = random.Random(18)
    cases = [(jumpy_events(rng), rng.randint(1, 5), 0.03) for _ in range(60)]
    expected = run_rospy(cases)
    jumps = 0
    for (events, queue_size, slop), want in zip(cases, expected, strict=True):
        assert run_visnav(events, queue_size, slop) == want, (events, queue_size)
        jumps += any(b[2] < a[2] for a, b in itertools.pairwise(events))
    assert jumps > 20  # the cases do exercise the reset


def test_time_synchronizer_clears_on_jump_but_keeps_the_new_message() -> None:
    clock = FakeClock()
    a, b = SimpleFilter(), SimpleFilter()
    sync = TimeSynchronizer([a, b], 10, clock=clock)
    out: list[tuple[int, int]] = []
    sync.register_callback(lambda x, y: out.append((x.ns, y.ns)))
    clock.now = 2 * S
    a.signal_message(Msg(2 * S))  # stale: never completed before the loop
    clock.now = 1 * S
    b.signal_message(Msg(1 * S))  # jump back: clears, then queues this one
    b.signal_message(Msg(2 * S))
    a.signal_message(Msg(1 * S))
    assert out == [(S, S)]  # not (2 s, 2 s) from the two sides of the jump
    clock.now = 2 * S
    a.signal_message(Msg(2 * S))
    assert out == [(S, S), (2 * S, 2 * S)]


def test_cache_clears_on_jump_back() -> None:
    clock = FakeClock()
    source = SimpleFilter()
    cache = Cache(source, 10, clock=clock)
    for k in range(1, 4):
        clock.now = k * S
        source.signal_message(Msg(k * S))
    assert len(cache) == 3
    clock.now = S // 2
    source.signal_message(Msg(S // 2))
    assert len(cache) == 1
    assert cache.get_oldest_time() == S // 2
    assert cache.get_elem_before_time(3 * S) is cache.get_last()


def test_default_clock_is_the_subscribers_node_clock() -> None:
    class FakeNode:
        def __init__(self) -> None:
            self.clock = FakeClock()

        def get_clock(self) -> Any:
            outer = self

            class C:
                def now_ns(self) -> int:
                    return outer.clock.now

            return C()

    node = FakeNode()
    source = SimpleFilter()
    source.node = node  # type: ignore[attr-defined]  # as Subscriber has
    cache = Cache(source, 10)
    node.clock.now = 5 * S
    source.signal_message(Msg(5 * S))
    node.clock.now = S
    source.signal_message(Msg(S))
    assert len(cache) == 1
