"""Fuzz services on the wire: malformed requests and replies never kill a server or a client.

A raw Zenoh session sends random request payloads (and attachments) to a visnav
server's key, and answers a visnav client's requests with random bytes or random
error replies. The server answers each bad request with an error reply (logged once,
then counted) and keeps serving; the client's future completes with a response or a
:class:`~visnav.graph.ServiceError`, never with another exception and never hangs.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator
from typing import Any

import pytest
import zenoh
from hypothesis import given
from hypothesis import strategies as st

from visnav.graph import Context, Node, ServiceError
from visnav.graph.node import _service_key
from visnav.msgs.serde import serialize
from visnav.msgs.srv import get_service_type

from .conftest import FUZZ, mutated

SetBool = get_service_type("std_srvs/srv/SetBool")
Trigger = get_service_type("std_srvs/srv/Trigger")
VALID_REQUEST = serialize(SetBool.Request(data=True))
VALID_REPLY = serialize(Trigger.Response(success=True, message="fine"))


@pytest.fixture
def graph(domain: int) -> Iterator[tuple[Context, Node, Context]]:
    """A spinning server context with node /fz and a second (raw) context."""
    with Context(domain) as server_ctx, Context(domain) as raw_ctx:
        node = Node("fz", context=server_ctx)
        node.create_service(
            SetBool,
            "/fz/set",
            lambda q, r: (setattr(r, "success", bool(q.data)), r)[1],
        )
        stop = threading.Event()
        thread = threading.Thread(target=lambda: server_ctx.spin_until(stop.is_set, 600))
        thread.start()
        try:
            yield server_ctx, node, raw_ctx
        finally:
            stop.set()
            thread.join()


def _raw_get(
    session: zenoh.Session, key: str, payload: bytes, attachment: bytes | None
) -> list[Any]:
    replies: list[Any] = []
    done = threading.Event()
    session.get(
        key,
        zenoh.handlers.Callback(replies.append, done.set),
        payload=payload,
        attachment=attachment,
        timeout=5.0,
    )
    assert done.wait(10.0), "the server never finished the query"
    return replies


def test_malformed_requests_get_error_replies_and_the_server_keeps_serving(
    graph: tuple[Context, Node, Context], domain: int, caplog: pytest.LogCaptureFixture
) -> None:
    _server_ctx, node, raw_ctx = graph
    raw = raw_ctx.zenoh
    assert raw is not None
    key = _service_key(domain, "/fz/set", "std_srvs/srv/SetBool")
    client = Node("fz_client", context=raw_ctx, start_parameter_services=False).create_client(
        SetBool, "/fz/set"
    )
    assert client.wait_for_service(10.0)
    service = node.services[-1]
    caplog.set_level(logging.WARNING)

    @FUZZ
    @given(
        payload=st.one_of(st.binary(max_size=64), mutated(VALID_REQUEST)),
        attachment=st.one_of(st.none(), st.binary(max_size=40)),
    )
    def check(payload: bytes, attachment: bytes | None) -> None:
        replies = _raw_get(raw.session, key, payload, attachment)
        assert len(replies) == 1
        reply = replies[0]
        if reply.ok is None:
            text = reply.err.payload.to_bytes().decode()
            assert "could not read the request" in text
            assert "'/fz/set'" in text

    check()
    assert service.bad_requests > 0
    logged = [r for r in caplog.records if "could not read the request" in r.getMessage()]
    assert len(logged) == 1  # once, then only counted
    assert client.call(SetBool.Request(data=True), timeout_sec=5.0).success


def test_malformed_replies_fail_the_client_future_cleanly(domain: int) -> None:
    with Context(domain) as fake_ctx, Context(domain) as client_ctx:
        fake = fake_ctx.zenoh
        assert fake is not None
        key = _service_key(domain, "/fz/trigger", "std_srvs/srv/Trigger")
        answer: dict[str, Any] = {}

        def on_query(query: Any) -> None:
            if answer["error"]:
                query.reply_err(answer["payload"])
            else:
                query.reply(query.key_expr, answer["payload"])

        queryable = fake.session.declare_queryable(key, on_query)
        client = Node("c", context=client_ctx, start_parameter_services=False).create_client(
            Trigger, "/fz/trigger"
        )

        @FUZZ
        @given(
            payload=st.one_of(st.binary(max_size=64), mutated(VALID_REPLY)),
            error=st.booleans(),
        )
        def check(payload: bytes, error: bool) -> None:
            answer.update(payload=payload, error=error)
            future = client.call_async(Trigger.Request(), timeout_sec=5.0)
            assert future.wait(10.0), "the client hung on a malformed reply"
            exc = future.exception()
            if exc is not None:
                assert isinstance(exc, ServiceError)
                assert "/fz/trigger" in str(exc)
            else:
                assert isinstance(future.result(), Trigger.Response)
                assert not error
            # the blocking call() reads the reply from a channel: the same outcomes, raised
            if exc is not None:
                with pytest.raises(ServiceError, match="/fz/trigger"):
                    client.call(Trigger.Request(), timeout_sec=5.0)
            else:
                assert isinstance(client.call(Trigger.Request(), timeout_sec=5.0), Trigger.Response)

        try:
            check()
        finally:
            queryable.undeclare()
