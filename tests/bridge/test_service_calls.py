"""The bridge's pool for calls to ROS 1 services: bounded, never blocking its caller."""

from __future__ import annotations

import threading
import time

import pytest

from visnav.bridge.errors import BridgeError
from visnav.bridge.services import CallPool


def test_calls_run_concurrently_up_to_the_worker_count() -> None:
    pool = CallPool(workers=3, max_pending=10)
    running = 0
    peak = 0
    lock = threading.Lock()

    def call(i: int) -> int:
        nonlocal running, peak
        with lock:
            running += 1
            peak = max(peak, running)
        time.sleep(0.2)
        with lock:
            running -= 1
        return i * 10

    start = time.monotonic()
    futures = [pool.submit(lambda i=i: call(i), what="t") for i in range(6)]
    assert time.monotonic() - start < 0.1  # submit never waits for a call
    assert all(f.wait(5.0) for f in futures)
    assert [f.result() for f in futures] == [i * 10 for i in range(6)]
    assert peak == 3
    assert pool.pending == 0
    pool.close()


def test_backlog_is_bounded_and_failures_and_close_reach_the_futures() -> None:
    pool = CallPool(workers=1, max_pending=2)
    gate = threading.Event()
    first = pool.submit(lambda: gate.wait(10.0), what="ROS 1 service /a")
    second = pool.submit(lambda: 1, what="ROS 1 service /a")
    refused = pool.submit(lambda: 2, what="ROS 1 service /a")
    assert refused.done()
    with pytest.raises(
        BridgeError, match=r"ROS 1 service /a: .* 2 calls .* in flight \(at most 2\)"
    ):
        refused.result()
    gate.set()
    assert first.wait(5.0)
    assert second.wait(5.0)
    assert second.result() == 1

    def boom() -> None:
        raise RuntimeError("no provider")

    failed = pool.submit(boom, what="t")
    assert failed.wait(5.0)
    assert isinstance(failed.exception(), RuntimeError)

    stuck = pool.submit(lambda: threading.Event().wait(3.0), what="t")
    pool.close()
    assert stuck.done()
    with pytest.raises(BridgeError, match="the bridge stopped"):
        stuck.result()
    late = pool.submit(lambda: 3, what="ROS 1 service /b")
    with pytest.raises(BridgeError, match="shutting down"):
        late.result()
