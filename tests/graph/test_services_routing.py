"""How requests from other sessions reach a context's services (its query inbox).

Two contexts of one process are two Zenoh sessions: a request between them travels as a
Zenoh query, as between processes.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
import zenoh

from visnav.graph import Context, Node, ServiceError
from visnav.msgs.serde import deserialize, serialize
from visnav.msgs.srv import get_service_type

SetBool = get_service_type("std_srvs/srv/SetBool")
Trigger = get_service_type("std_srvs/srv/Trigger")


@pytest.fixture
def pair(domain: int) -> Iterator[tuple[Context, Context]]:
    with Context(domain) as server_ctx, Context(domain) as client_ctx:
        yield server_ctx, client_ctx


def _answer(tag: str) -> Callable[[Any, Any], Any]:
    def answer(req: Any, resp: Any) -> Any:
        resp.success = bool(req.data)
        resp.message = tag
        return resp

    return answer


def test_a_sleeping_executor_wakes_for_a_remote_request(pair: tuple[Context, Context]) -> None:
    server_ctx, client_ctx = pair
    Node("s", context=server_ctx).create_service(SetBool, "/a", _answer("a"))
    client = Node("c", context=client_ctx).create_client(SetBool, "/a")
    assert client.wait_for_service(10.0)
    ran: list[bool] = []
    # spin_once without a timeout: only the request can wake it
    spinner = threading.Thread(target=lambda: ran.append(server_ctx.spin_once(None)))
    spinner.start()
    time.sleep(0.2)
    t0 = time.monotonic()
    reply = client.call(SetBool.Request(data=True), timeout_sec=5.0)
    spinner.join(5.0)
    assert not spinner.is_alive()
    assert ran == [True]
    assert (reply.success, reply.message) == (True, "a")
    assert time.monotonic() - t0 < 2.0


def test_requests_from_other_sessions_reach_the_service_of_their_key(
    pair: tuple[Context, Context],
) -> None:
    server_ctx, client_ctx = pair
    node = Node("s", context=server_ctx)
    node.create_service(SetBool, "/a", _answer("a"))
    node.create_service(SetBool, "/b", _answer("b"))
    cnode = Node("c", context=client_ctx)
    ca, cb = cnode.create_client(SetBool, "/a"), cnode.create_client(SetBool, "/b")
    assert ca.wait_for_service(10.0)
    assert cb.wait_for_service(10.0)
    spinner = threading.Thread(target=server_ctx.spin, kwargs={"duration_s": 8.0}, daemon=True)
    spinner.start()
    futures = [c.call_async(SetBool.Request(data=i % 2 == 0)) for i in range(6) for c in (ca, cb)]
    got = []
    for f in futures:
        assert f.wait(5.0)
        result = f.result()
        assert result is not None
        got.append((result.message, result.success))
    assert got == [(tag, i % 2 == 0) for i in range(6) for tag in ("a", "b")]
    server_ctx.shutdown()
    spinner.join(5.0)


def test_a_wildcard_query_is_answered_once_by_each_matching_service(
    pair: tuple[Context, Context],
) -> None:
    server_ctx, client_ctx = pair
    node = Node("s", context=server_ctx)
    node.create_service(SetBool, "/w/a", _answer("a"))
    node.create_service(SetBool, "/w/b", _answer("b"))
    node.create_service(Trigger, "/other", lambda _q, r: r)
    client = Node("c", context=client_ctx).create_client(SetBool, "/w/b")
    assert client.wait_for_service(10.0)
    server_ctx.flush_tokens()
    z = client_ctx.zenoh
    assert z is not None
    spinner = threading.Thread(target=server_ctx.spin, kwargs={"duration_s": 8.0}, daemon=True)
    spinner.start()
    replies = z.session.get(
        f"{server_ctx.domain}/w/*/std_srvs::srv::dds_::SetBool_/*",
        payload=bytes(serialize(SetBool.Request(data=True))),
        consolidation=zenoh.ConsolidationMode.NONE,
        timeout=5.0,
    )
    tags = []
    for reply in replies:
        assert reply.ok is not None, reply.err
        tags.append(deserialize(reply.ok.payload.to_bytes(), SetBool.response_type_name).message)
    assert sorted(tags) == ["a", "b"]
    server_ctx.shutdown()
    spinner.join(5.0)


def test_requests_waiting_in_the_inbox_fail_when_the_server_goes(
    pair: tuple[Context, Context],
) -> None:
    server_ctx, client_ctx = pair
    node = Node("s", context=server_ctx)
    server = node.create_service(SetBool, "/gone", _answer("x"))
    client = Node("c", context=client_ctx).create_client(SetBool, "/gone")
    assert client.wait_for_service(10.0)
    # nobody spins the server: the requests wait in its context's inbox
    futures = [client.call_async(SetBool.Request(data=True), timeout_sec=5.0) for _ in range(3)]
    time.sleep(0.3)
    node.destroy_service(server)
    for f in futures:
        assert f.wait(5.0)
        exc = f.exception()
        assert isinstance(exc, ServiceError)
        assert "destroyed before answering" in str(exc)
