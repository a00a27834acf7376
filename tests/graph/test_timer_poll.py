"""TimerPoll: the cheap "which timers are due" gives what asking every timer gives."""

from __future__ import annotations

import itertools
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.graph import Context, Node
from visnav.graph.clock import Clock, ClockType
from visnav.graph.timer import Timer
from visnav.graph.timer_poll import TimerPoll


class _Ctx:
    def __init__(self) -> None:
        self._ids = itertools.count(1)
        self.poll: TimerPoll | None = None

    def next_id(self) -> int:
        return next(self._ids)

    def wake(self, *, timers: bool = False) -> None:
        if timers and self.poll is not None:
            self.poll.invalidate()


class _Node:
    def __init__(self) -> None:
        self.context = _Ctx()


def _world(periods: list[int], n_clocks: int) -> tuple[list[Clock], list[Timer], _Node]:
    node = _Node()
    clocks = [Clock() for _ in range(n_clocks)]
    for c in clocks:
        c.enable_sim_time()
    timers = [Timer(node, p, lambda: None, clocks[i % n_clocks]) for i, p in enumerate(periods)]  # type: ignore[arg-type]
    return clocks, timers, node


def _naive(timers: list[Timer], queued: set[Any]) -> list[int]:
    due = [t for t in timers if t not in queued and t.is_ready()]
    due.sort(key=lambda t: (t.next_call_ns, t.entity_id))
    return [timers.index(t) for t in due]


_OPS = st.lists(
    st.tuples(
        st.sampled_from(["advance", "jump_back", "poll", "take", "reset", "cancel"]),
        st.integers(0, 5),
        st.integers(0, 400),
    ),
    max_size=60,
)


@settings(max_examples=150, deadline=None)
@given(
    periods=st.lists(st.integers(10, 200), min_size=1, max_size=6),
    n_clocks=st.integers(1, 3),
    ops=_OPS,
)
def test_due_matches_asking_every_timer(periods: list[int], n_clocks: int, ops: list[Any]) -> None:
    """Same operations on two copies: TimerPoll.due == the full check, at every poll."""
    a_clocks, a_timers, a_node = _world(periods, n_clocks)
    b_clocks, b_timers, _ = _world(periods, n_clocks)
    poll = TimerPoll()
    a_node.context.poll = poll
    for t in a_timers:
        poll.add(t)
    a_queued: set[Any] = set()
    b_queued: set[Any] = set()
    for op, k, amount in ops:
        i = k % len(periods)
        c = k % n_clocks
        if op == "advance":
            for clocks in (a_clocks, b_clocks):
                clocks[c].set_sim_time_ns(clocks[c].now_ns() + amount)
        elif op == "jump_back":
            for clocks in (a_clocks, b_clocks):
                clocks[c].set_sim_time_ns(max(0, clocks[c].now_ns() - amount))
        elif op == "poll":
            got = [a_timers.index(t) for t in poll.due(a_queued)]
            want = _naive(b_timers, b_queued)
            assert got == want
            a_queued.update(a_timers[j] for j in got)
            b_queued.update(b_timers[j] for j in want)
        elif op == "take":  # the executor takes timer i from the ring and runs it if due
            for timers, queued, p in ((a_timers, a_queued, poll), (b_timers, b_queued, None)):
                if timers[i] in queued:
                    queued.discard(timers[i])
                    if p is not None:
                        p.taken(timers[i])
                    timers[i].take_call()
        elif op == "reset":
            a_timers[i].reset()
            b_timers[i].reset()
        else:
            a_timers[i].cancel()
            b_timers[i].cancel()


def test_a_wall_clock_timer_is_always_checked() -> None:
    """A steady-clock timer falls due by itself; the poll sees it without any notice."""
    node = _Node()
    clock = Clock(ClockType.STEADY_TIME)
    timer = Timer(node, 1_000_000, lambda: None, clock)  # type: ignore[arg-type]
    poll = TimerPoll()
    poll.add(timer)
    assert poll.due(set()) == []
    while clock.now_ns() < timer.next_call_ns:
        pass
    assert poll.due(set()) == [timer]


def test_sim_timers_fire_on_time_through_the_executor() -> None:
    """Sim-time timers of several nodes fire at their periods while /clock advances."""
    from visnav.msgs.time import ns_to_time
    from visnav.msgs.types import Clock as ClockMsg

    with Context(transport="local") as ctx:
        pub = Node("clock", context=ctx).create_publisher(ClockMsg, "/clock", 1)
        fired: list[tuple[str, int]] = []
        for name, period in (("a", 0.01), ("b", 0.025), ("c", 0.04)):
            n = Node(name, context=ctx, use_sim_time=True)
            n.create_timer(period, lambda n=n: fired.append((n.get_name(), n.get_clock().now_ns())))
        for k in range(1, 101):
            pub.publish(ClockMsg(clock=ns_to_time(k * 1_000_000)))
            ctx.spin_some()
    for name, period_ms in (("a", 10), ("b", 25), ("c", 40)):
        times = [t for n, t in fired if n == name]
        assert times == [j * period_ms * 1_000_000 for j in range(1, 100 // period_ms + 1)]


def _one_timer(period: int) -> tuple[Clock, Timer, TimerPoll]:
    clocks, timers, node = _world([period], 1)
    poll = TimerPoll()
    node.context.poll = poll
    poll.add(timers[0])
    return clocks[0], timers[0], poll


def test_a_taken_timer_is_due_again_at_its_next_deadline() -> None:
    clock, timer, poll = _one_timer(100)
    assert poll.due(set()) == []
    clock.set_sim_time_ns(100)
    assert poll.due(set()) == [timer]
    poll.taken(timer)
    timer.take_call()
    clock.set_sim_time_ns(150)
    assert poll.due(set()) == []
    clock.set_sim_time_ns(200)
    assert poll.due(set()) == [timer]


def test_a_reset_timer_is_watched_again() -> None:
    clock, timer, poll = _one_timer(100)
    timer.cancel()
    clock.set_sim_time_ns(500)
    assert poll.due(set()) == []
    timer.reset()  # un-canceled: due one period from now
    clock.set_sim_time_ns(600)
    assert poll.due(set()) == [timer]


def test_a_jump_back_restarts_the_period() -> None:
    clock, timer, poll = _one_timer(100)
    clock.set_sim_time_ns(1000)
    assert poll.due(set()) == [timer]
    poll.taken(timer)
    timer.take_call()  # next deadline 1100
    clock.set_sim_time_ns(50)  # the bag starts over
    assert poll.due(set()) == []
    assert timer.next_call_ns == 150
    clock.set_sim_time_ns(150)
    assert poll.due(set()) == [timer]


def test_spin_some_runs_a_timer_made_due_by_a_clock_callback_after_the_queued_work() -> None:
    """The /clock callback moves the node's time; its timer joins the ring behind /data."""
    from visnav.msgs.time import ns_to_time
    from visnav.msgs.types import Clock as ClockMsg
    from visnav.msgs.types import String

    with Context(transport="local") as ctx:
        src = Node("src", context=ctx)
        clock_pub = src.create_publisher(ClockMsg, "/clock", 1)
        data_pub = src.create_publisher(String, "/data", 10)
        node = Node("n", context=ctx, use_sim_time=True)
        order: list[str] = []
        node.create_subscription(String, "/data", lambda m: order.append(m.data), 10)
        node.create_timer(0.01, lambda: order.append("timer"))
        clock_pub.publish(ClockMsg(clock=ns_to_time(10_000_000)))
        data_pub.publish(String(data="data"))
        ran = ctx.spin_some()
        assert order == ["data", "timer"]
        assert ran == 3  # the clock callback, /data, the timer
        assert ctx.spin_some() == 0
