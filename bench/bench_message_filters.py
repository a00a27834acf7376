"""Throughput of the message_filters synchronizers (input messages per second).

Three inputs at 30 Hz with +-2 ms stamp jitter, delivered through SimpleFilter
inputs in arrival order with up to 5 ms of random delivery delay per message.
Prints the median of repeated runs for each synchronizer and its ratio to the
issue's target of 20,000 input messages/s (and to ROS 1 Python's
ApproximateTimeSynchronizer, the reference implementation measured here).

Run: python bench/bench_message_filters.py
"""

from __future__ import annotations

import random
import statistics
import time
from collections.abc import Callable
from typing import Any

from visnav.message_filters import (
    ApproximateTime,
    ApproximateTimeSynchronizer,
    SimpleFilter,
    TimeSynchronizer,
)
from visnav.msgs import Header, Time

TARGET = 20_000.0
N_INPUTS = 3
N_MESSAGES = 30_000
REPEATS = 7
PERIOD_NS = 33_333_333


class Msg:
    __slots__ = ("header",)

    def __init__(self, ns: int) -> None:
        self.header = Header(
            stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=""
        )


def make_stream(seed: int, *, jitter_ns: int) -> list[tuple[int, Msg]]:
    rng = random.Random(seed)
    events = []
    per_input = N_MESSAGES // N_INPUTS
    for i in range(N_INPUTS):
        for k in range(per_input):
            stamp = 1_000_000_000 + k * PERIOD_NS + rng.randint(-jitter_ns, jitter_ns)
            arrival = stamp + rng.randint(0, 5_000_000)
            events.append((arrival, i, stamp))
    events.sort()
    # Per input, stamps must stay in order (the arrival delay may reorder them).
    last = [0] * N_INPUTS
    out = []
    for _, i, raw in events:
        stamp = max(raw, last[i])
        last[i] = stamp
        out.append((i, Msg(stamp)))
    return out


def run(
    factory: Callable[[list[SimpleFilter]], Any], stream: list[tuple[int, Msg]]
) -> tuple[float, int]:
    inputs = [SimpleFilter() for _ in range(N_INPUTS)]
    sync = factory(inputs)
    sets = [0]

    def cb(*_msgs: Any) -> None:
        sets[0] += 1

    sync.register_callback(cb)
    signals = [f.signal_message for f in inputs]
    t0 = time.perf_counter()
    for i, msg in stream:
        signals[i](msg)
    elapsed = time.perf_counter() - t0
    return len(stream) / elapsed, sets[0]


def main() -> None:
    jittered = make_stream(1, jitter_ns=2_000_000)
    exact = make_stream(2, jitter_ns=0)
    cases: list[tuple[str, Callable[[list[SimpleFilter]], Any], list[tuple[int, Msg]]]] = [
        ("ApproximateTime(queue 10)", lambda fs: ApproximateTime(fs, 10), jittered),
        (
            "ApproximateTime(queue 10, bounds 25 ms)",
            lambda fs: ApproximateTime(fs, 10, inter_message_lower_bounds=0.025),
            jittered,
        ),
        (
            "ApproximateTimeSynchronizer(queue 10, slop 10 ms) [ROS 1 reference]",
            lambda fs: ApproximateTimeSynchronizer(fs, 10, 0.010),
            jittered,
        ),
        ("TimeSynchronizer(queue 10), exact stamps", lambda fs: TimeSynchronizer(fs, 10), exact),
    ]
    results = {}
    for name, factory, stream in cases:
        rates = []
        for _ in range(REPEATS):
            rate, sets = run(factory, stream)
            rates.append(rate)
        results[name] = (statistics.median(rates), sets)
    reference = results[cases[2][0]][0]
    print(f"{N_INPUTS} inputs, {N_MESSAGES} messages, median of {REPEATS} runs")
    for name, (rate, sets) in results.items():
        print(
            f"  {name:<68} {rate:>10,.0f} msgs/s  {sets:>6} sets  "
            f"x{rate / TARGET:.2f} of the 20,000 target  x{rate / reference:.2f} of ROS 1 ATS"
        )


if __name__ == "__main__":
    main()
