"""Action benchmark: goal -> result latency of a trivial action, in and across processes.

Run: ``python bench/bench_actions.py``. A trivial ``example_interfaces/action/Fibonacci``
server (its execute callback succeeds at once) is timed with the blocking
``ActionClient.send_goal`` (send_goal service call, execute thread, get_result service
call), in one process (the executor spinning on another thread) and across processes
(server in a child process). The reference, measured interleaved in the same run against
the same process, is two ``std_srvs/srv/SetBool`` calls (an action's two round trips, the
least it can cost); the ratio is action / reference. Each run uses a private domain.
The server keeps results 0.1 s (``result_timeout``): every status message lists the goals
kept, so at hundreds of goals per second a longer retention measures the status array's
size, not the round trips (with 1 s, ~150 goals kept: 6.6 ms instead of 3.4 ms across
processes).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

N_GOALS = 500
REPEATS = 3
BLOCK = 50


def _stats(samples_s: list[float]) -> tuple[float, float]:
    ordered = sorted(samples_s)
    median = statistics.median(ordered) * 1e3
    p99 = ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))] * 1e3
    return median, p99


def _serve_on(node: Any) -> None:
    from visnav.graph.action_server import ActionServer
    from visnav.msgs.action import get_action_type
    from visnav.msgs.construct import make
    from visnav.msgs.srv import get_service_type

    fib = get_action_type("example_interfaces/action/Fibonacci")

    def execute(handle: Any) -> Any:
        handle.succeed()
        return make(fib.Result)

    ActionServer(node, fib, "/bench/fib", execute, result_timeout=0.1)
    node.create_service(get_service_type("std_srvs/srv/SetBool"), "/bench/set", lambda q, r: r)


def serve(seconds: float) -> None:
    """Child process: the trivial action server and a SetBool server."""
    from visnav.graph import Context, Node

    with Context() as ctx:
        _serve_on(Node("bench_server", context=ctx, start_parameter_services=False))
        ctx.flush_tokens()
        print("ready", flush=True)
        ctx.spin(duration_s=seconds)


def _measure(ctx: Any, node: Any, n: int) -> dict[str, tuple[float, float]]:
    from visnav.graph.action_client import ActionClient
    from visnav.msgs.action import get_action_type
    from visnav.msgs.construct import make
    from visnav.msgs.srv import get_service_type

    fib = get_action_type("example_interfaces/action/Fibonacci")
    set_bool = get_service_type("std_srvs/srv/SetBool")
    client = ActionClient(node, fib, "/bench/fib")
    service = node.create_client(set_bool, "/bench/set")
    if not (client.wait_for_server(20.0) and service.wait_for_service(20.0)):
        msg = "the servers did not appear"
        raise RuntimeError(msg)
    goal = make(fib.Goal, order=1)
    request = set_bool.Request(data=True)

    def action() -> None:
        if client.send_goal(goal, timeout_sec=10.0) is None:
            msg = "goal rejected"
            raise RuntimeError(msg)

    def two_calls() -> None:
        service.call(request, timeout_sec=10.0)
        service.call(request, timeout_sec=10.0)

    for _ in range(50):
        action()
        two_calls()
    samples: dict[str, list[float]] = {"action": [], "reference": []}
    jobs: dict[str, Callable[[], None]] = {"action": action, "reference": two_calls}
    for _ in range(n // BLOCK):
        for name, job in jobs.items():
            for _ in range(BLOCK):
                t = time.perf_counter()
                job()
                samples[name].append(time.perf_counter() - t)
    del ctx
    return {k: _stats(v) for k, v in samples.items()}


def _spinning(ctx: Any) -> tuple[threading.Event, threading.Thread]:
    stop = threading.Event()
    thread = threading.Thread(target=lambda: ctx.spin_until(stop.is_set, 600), daemon=True)
    thread.start()
    return stop, thread


def bench_in_process(n: int = N_GOALS) -> dict[str, tuple[float, float]]:
    """Server and client in one local context, spun by a second thread."""
    from visnav.graph import Context, Node

    with Context(transport="local") as ctx:
        node = Node("bench", context=ctx, start_parameter_services=False)
        _serve_on(node)
        stop, thread = _spinning(ctx)
        try:
            return _measure(ctx, node, n)
        finally:
            stop.set()
            thread.join(5)


def bench_cross_process(n: int = N_GOALS) -> dict[str, tuple[float, float]]:
    """Client here, server in a child process."""
    from visnav.graph import Context, Node

    domain = 2_500_000 + os.getpid() % 100_000
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    child = subprocess.Popen(
        [sys.executable, __file__, "--serve", "600"], env=env, stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout is not None
        if child.stdout.readline().strip() != "ready":
            msg = "the server process did not start"
            raise RuntimeError(msg)
        with Context(domain) as ctx:
            node = Node("bench_client", context=ctx, start_parameter_services=False)
            stop, thread = _spinning(ctx)
            try:
                return _measure(ctx, node, n)
            finally:
                stop.set()
                thread.join(5)
    finally:
        child.kill()
        child.wait(10)


def main() -> None:
    """Run both benchmarks REPEATS times and print medians."""
    for label, bench in (
        ("in process", bench_in_process),
        ("across processes", bench_cross_process),
    ):
        runs = [bench() for _ in range(REPEATS)]
        am = statistics.median(r["action"][0] for r in runs)
        ap = statistics.median(r["action"][1] for r in runs)
        rm = statistics.median(r["reference"][0] for r in runs)
        rp = statistics.median(r["reference"][1] for r in runs)
        print(f"{label}: goal -> result (send_goal) median {am:.3f} ms, p99 {ap:.3f} ms")
        print(f"{label}: reference, two SetBool calls: median {rm:.3f} ms, p99 {rp:.3f} ms")
        print(f"{label}: ratio action / two calls: median {am / rm:.2f}x, p99 {ap / rp:.2f}x")


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--serve":
        serve(float(sys.argv[2]))
    else:
        main()
