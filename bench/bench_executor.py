"""Executor benchmarks (issue 13): starvation under overload, and dispatch overhead.

Run: ``python bench/bench_executor.py [--seconds S] [--repeats N]``.

* Starvation scenario of issue 13: ``/fast`` at 200 Hz whose callback busy-works
  for 10 ms (keep-last 10: twice more work than time, so the executor is always
  behind) and ``/slow`` (10 Hz here, 1 Hz in the issue: more samples for a 99th
  percentile; the lag does not depend on the rate of a rarely ready topic). The
  lag of ``/slow`` is the time from its publication to the start of its callback,
  reported relative to the measured ``/fast`` callback duration. Bound: p99 <= 2
  callback durations. Run in one process (publishing timers and subscriptions on
  one Context) and across processes (a real second process publishes both topics).
* Dispatch overhead: the time ``spin_some`` takes per callback to drain four
  topics' queued messages, against a bare loop calling the same callbacks with
  the same messages (the reference, measured in the same run).

Percentiles are taken over each run's samples; the figure printed is the median over
``--repeats`` runs. Each run uses its own private domain.
"""

from __future__ import annotations

import argparse
import bisect
import os
import statistics
import subprocess
import sys
import time
from typing import Any

import numpy as np

CALLBACK_S = 0.010
FAST_HZ = 200.0
SLOW_HZ = 10.0


def _busy(seconds: float) -> None:
    """Work for ``seconds`` of this thread's CPU time (a fixed amount of work)."""
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass


def _publisher_nodes(ctx: Any) -> None:
    """Timers publishing /fast and /slow (String, data = ``"time_ns thread_time_ns"``)."""
    from visnav.graph import HistoryPolicy, Node, QoSProfile
    from visnav.msgs import String

    qos = QoSProfile(depth=100, history=HistoryPolicy.KEEP_ALL)
    node = Node("fast_slow", context=ctx)
    fast = node.create_publisher(String, "/fast", qos)
    slow = node.create_publisher(String, "/slow", qos)

    def stamp() -> Any:
        return String(data=f"{time.time_ns()} {time.thread_time_ns()}")

    node.create_timer(1 / FAST_HZ, lambda: fast.publish(stamp()))
    node.create_timer(1 / SLOW_HZ, lambda: slow.publish(stamp()))


class _Receiver:
    """/fast with a 10 ms busy callback; /slow records (publication, callback start)."""

    def __init__(self, ctx: Any) -> None:
        from visnav.graph import Node
        from visnav.msgs import String

        self.node = Node("receiver", context=ctx)
        self.fast_starts: list[int] = []
        self.durations: list[int] = []
        self.slow: list[tuple[int, int]] = []
        self.received: list[int] = []
        self.cpu_lags: list[int] = []
        self.cpu_durations: list[int] = []
        self.node.create_subscription(String, "/fast", self.on_fast, 10)
        self.node.create_subscription(String, "/slow", self.on_slow, 10)

    def on_fast(self, msg: Any) -> None:
        self.fast_starts.append(time.time_ns())
        t0, c0 = time.perf_counter_ns(), time.thread_time_ns()
        _busy(CALLBACK_S)
        self.durations.append(time.perf_counter_ns() - t0)
        self.cpu_durations.append(time.thread_time_ns() - c0)

    def on_slow(self, msg: Any, info: Any) -> None:
        now, cpu = time.time_ns(), time.thread_time_ns()
        wall, pub_cpu = (int(x) for x in msg.data.split())
        self.slow.append((wall, now))
        self.cpu_lags.append(cpu - pub_cpu)  # meaningful when published by this thread
        self.received.append(info.received_timestamp_ns)

    def stats(self, seconds: float, warmup: int = 2) -> dict[str, float]:
        slow = self.slow[warmup:]
        lag = np.array([b - a for a, b in slow], dtype=np.float64) / 1e6
        received = self.received[warmup:]
        queued = np.array([b - r for (_, b), r in zip(slow, received, strict=True)]) / 1e6
        # /fast callbacks that started after /slow was published and before its callback
        starts = self.fast_starts
        waited = [bisect.bisect_left(starts, b) - bisect.bisect_right(starts, a) for a, b in slow]
        waited_arrival = [
            bisect.bisect_left(starts, b) - bisect.bisect_right(starts, r)
            for (_, b), r in zip(slow, received, strict=True)
        ]
        cb_ms = float(np.median(self.durations)) / 1e6
        return {
            "n": float(lag.size),
            "callback_ms": cb_ms,
            "p50_ms": float(np.percentile(lag, 50)),
            "p99_ms": float(np.percentile(lag, 99)),
            "max_ms": float(lag.max()),
            "p50_rel": float(np.percentile(lag, 50)) / cb_ms,
            "p99_rel": float(np.percentile(lag, 99)) / cb_ms,
            "p99_queued_rel": float(np.percentile(queued, 99)) / cb_ms,
            "p99_cpu_rel": float(np.percentile(self.cpu_lags[warmup:], 99))
            / float(np.median(self.cpu_durations)),
            "waited_p99": float(np.percentile(waited, 99)),
            "waited_max": float(max(waited)),
            "waited_arrival_p99": float(np.percentile(waited_arrival, 99)),
            "waited_arrival_max": float(max(waited_arrival)),
            "fast_per_s": len(self.durations) / seconds,
            "dropped": float(sum(getattr(s, "dropped", 0) for s in self.node.subscriptions)),
        }


def starvation_in_process(seconds: float) -> dict[str, float]:
    """Publishers and subscribers on one Context, one thread."""
    from visnav.graph import Context

    with Context(transport="local") as ctx:
        _publisher_nodes(ctx)
        receiver = _Receiver(ctx)
        ctx.spin(duration_s=seconds)
        return receiver.stats(seconds)


def _publisher_process(domain: int, seconds: float) -> None:
    from visnav.graph import Context

    with Context(domain) as ctx:
        _publisher_nodes(ctx)
        pubs = ctx.nodes[0].publishers
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not all(
            p._zpub is not None and p._zpub.has_subscribers for p in pubs
        ):
            time.sleep(0.01)
        print("ready", flush=True)
        ctx.spin(duration_s=seconds)


def starvation_cross_process(seconds: float, domain: int) -> dict[str, float]:
    """A second process publishes; this one's executor is overloaded by /fast."""
    from visnav.graph import Context

    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    with Context(domain) as ctx:
        receiver = _Receiver(ctx)
        proc = subprocess.Popen(
            [sys.executable, __file__, "--publisher", str(domain), str(seconds)],
            env=env,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert proc.stdout is not None
        if proc.stdout.readline().strip() != "ready":
            msg = "the publisher process did not start"
            raise RuntimeError(msg)
        start = time.monotonic()
        while proc.poll() is None:
            ctx.spin_once(0.05)
        return receiver.stats(time.monotonic() - start)


def dispatch_overhead(n_per_topic: int = 5000, topics: int = 4) -> dict[str, float]:
    """Per-callback time of spin_some draining queued messages vs a bare loop."""
    from visnav.graph import Context, HistoryPolicy, Node, QoSProfile
    from visnav.msgs import String

    count = [0]

    def cb(msg: Any) -> None:
        count[0] += 1

    qos = QoSProfile(depth=1, history=HistoryPolicy.KEEP_ALL)
    msgs = [String(data=str(i)) for i in range(n_per_topic)]
    with Context(transport="local") as ctx:
        node = Node("overhead", context=ctx)
        pubs = [node.create_publisher(String, f"/t{k}", qos) for k in range(topics)]
        for k in range(topics):
            node.create_subscription(String, f"/t{k}", cb, qos)
        for m in msgs:
            for p in pubs:
                p.publish(m)
        t0 = time.perf_counter_ns()
        ran = ctx.spin_some()
        executor_ns = (time.perf_counter_ns() - t0) / ran
    callbacks = [cb] * topics
    t0 = time.perf_counter_ns()
    for m in msgs:
        for c in callbacks:
            c(m)
    bare_ns = (time.perf_counter_ns() - t0) / (n_per_topic * topics)
    return {"executor_us": executor_ns / 1e3, "bare_us": bare_ns / 1e3}


def _median(runs: list[dict[str, float]], key: str) -> float:
    return statistics.median(r[key] for r in runs)


def _report(title: str, runs: list[dict[str, float]], *, cpu: bool) -> None:
    p99 = _median(runs, "p99_rel")
    verdict = "PASS" if p99 <= 2 else "FAIL"
    lines = [
        f"{title} (load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores):",
        f"  /slow lag, publication -> callback: p50 {_median(runs, 'p50_ms'):.1f} ms, p99 "
        f"{_median(runs, 'p99_ms'):.1f} ms, max {_median(runs, 'max_ms'):.1f} ms; /fast callback "
        f"{_median(runs, 'callback_ms'):.1f} ms -> p50 {_median(runs, 'p50_rel'):.2f}, p99 "
        f"{p99:.2f} callback durations  [bound p99 <= 2] {verdict}",
        f"  p99 per run: {[round(r['p99_rel'], 2) for r in runs]}; from arrival in this process: "
        f"p99 {_median(runs, 'p99_queued_rel'):.2f} callback durations",
    ]
    if cpu:
        lines.append(
            "  in executor-thread CPU time (what the executor ran before /slow, without the OS's "
            f"preemption): p99 {_median(runs, 'p99_cpu_rel'):.2f} callback durations"
        )
    lines += [
        "  /fast callbacks begun between a /slow publication and its callback: p99 "
        f"{_median(runs, 'waited_p99'):.0f}, max {max(r['waited_max'] for r in runs):.0f}; "
        f"between its arrival in this process and its callback: p99 "
        f"{_median(runs, 'waited_arrival_p99'):.0f}, "
        f"max {max(r['waited_arrival_max'] for r in runs):.0f}",
        f"  /fast served {_median(runs, 'fast_per_s'):.0f}/s of {FAST_HZ:.0f}/s, "
        f"{_median(runs, 'dropped'):.0f} dropped by keep-last(10); "
        f"{_median(runs, 'n'):.0f} /slow samples per run",
    ]
    print("\n".join(lines), flush=True)


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--publisher":
        _publisher_process(int(sys.argv[2]), float(sys.argv[3]))
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="length of one run")
    parser.add_argument("--repeats", type=int, default=3, help="runs per scenario")
    args = parser.parse_args()
    base = 4_000_000 + (os.getpid() % 1000) * 100
    inproc = [starvation_in_process(args.seconds) for _ in range(args.repeats)]
    _report("in-process starvation", inproc, cpu=True)
    cross = [starvation_cross_process(args.seconds, base + r) for r in range(args.repeats)]
    _report("cross-process starvation", cross, cpu=False)
    over = [dispatch_overhead() for _ in range(5)]
    ex, bare = _median(over, "executor_us"), _median(over, "bare_us")
    print(
        f"dispatch overhead: {ex:.2f} us per callback through the executor vs {bare:.3f} us in a "
        f"bare loop (reference): +{ex - bare:.2f} us per callback, ratio {ex / bare:.1f}x  "
        f"(4 topics x 5000 queued messages, median of 5)"
    )


if __name__ == "__main__":
    main()
