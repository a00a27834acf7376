"""Deferred responses: a service callback returns a Future and answers later from any thread."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from visnav.graph import Context, Future, Node, ServiceError
from visnav.msgs import String
from visnav.msgs.srv import get_service_type

Trigger = get_service_type("std_srvs/srv/Trigger")
SetBool = get_service_type("std_srvs/srv/SetBool")


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def _later(delay_s: float, complete: Any) -> None:
    timer = threading.Timer(delay_s, complete)
    timer.daemon = True
    timer.start()


def _deferred(delay_s: float) -> Any:
    """A SetBool callback that answers from a timer thread after ``delay_s``."""

    def callback(req: Any, resp: Any) -> Future[Any]:
        future: Future[Any] = Future()

        def finish() -> None:
            resp.success = bool(req.data)
            resp.message = "late"
            future.set_result(resp)

        _later(delay_s, finish)
        return future

    return callback


def test_deferred_response_answers_later_and_the_executor_runs_meanwhile(ctx: Context) -> None:
    node = Node("n", context=ctx)
    node.create_service(SetBool, "slow", _deferred(0.5))
    node.create_service(Trigger, "fast", lambda _q, r: r)
    got: list[str] = []
    node.create_subscription(String, "chatter", lambda m: got.append(m.data), 10)
    pub = node.create_publisher(String, "chatter", 10)
    slow = node.create_client(SetBool, "slow").call_async(SetBool.Request(data=True))
    ctx.spin_some()  # the slow callback has run and returned its future
    fast = node.create_client(Trigger, "fast").call_async(Trigger.Request())
    pub.publish(String(data="meanwhile"))
    assert ctx.spin_until(lambda: fast.done() and got == ["meanwhile"], 2.0)
    assert not slow.done()
    assert slow.wait(5.0)
    assert (slow.result().success, slow.result().message) == (True, "late")


def test_deferred_failures_answer_the_caller(ctx: Context) -> None:
    node = Node("n", context=ctx)

    def failing(_req: Any, _resp: Any) -> Future[Any]:
        future: Future[Any] = Future()
        _later(0.05, lambda: future.set_exception(RuntimeError("the arm jammed")))
        return future

    def wrong(_req: Any, _resp: Any) -> Future[Any]:
        future: Future[Any] = Future()
        future.set_result("not a response")  # already done: answered at once
        return future

    def cancelled(_req: Any, _resp: Any) -> Future[Any]:
        future: Future[Any] = Future()
        _later(0.05, future.cancel)
        return future

    node.create_service(Trigger, "failing", failing)
    node.create_service(Trigger, "wrong", wrong)
    node.create_service(Trigger, "cancelled", cancelled)
    futures = {
        name: node.create_client(Trigger, name).call_async(Trigger.Request(), timeout_sec=5.0)
        for name in ("failing", "wrong", "cancelled")
    }
    assert ctx.spin_until(lambda: all(f.done() for f in futures.values()), 5.0)
    texts = {name: str(f.exception()) for name, f in futures.items()}
    assert all(isinstance(f.exception(), ServiceError) for f in futures.values()), texts
    assert "raised RuntimeError: the arm jammed" in texts["failing"]
    assert "returned str, expected std_srvs/srv/Trigger_Response" in texts["wrong"]
    assert "cancelled the call before answering" in texts["cancelled"]
    assert ctx.faults.count() == 0  # deferred failures are logged, not executor faults


def test_deferred_response_across_processes(domain: int) -> None:
    with Context(domain) as server_ctx, Context(domain) as client_ctx:
        Node("server", context=server_ctx).create_service(SetBool, "/d/slow", _deferred(0.3))
        client = Node("client", context=client_ctx, start_parameter_services=False).create_client(
            SetBool, "/d/slow"
        )
        spinner = threading.Thread(target=server_ctx.spin, args=(20.0,), daemon=True)
        spinner.start()
        assert client.wait_for_service(10.0)
        start = time.monotonic()
        calls = [
            client.call_async(SetBool.Request(data=i % 2 == 0), timeout_sec=10.0) for i in range(8)
        ]
        assert all(f.wait(10.0) for f in calls)
        # the eight waits overlap: the executor took each request while the others waited
        assert time.monotonic() - start < 8 * 0.3
        assert [f.result().success for f in calls] == [i % 2 == 0 for i in range(8)]
        server_ctx.shutdown()
        spinner.join(5.0)
