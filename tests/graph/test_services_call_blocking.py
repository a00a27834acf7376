"""Blocking ``Client.call`` across processes (the reply read from a Zenoh channel by the caller)."""

from __future__ import annotations

import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from visnav.graph import Context, Node, ServiceError, ServiceTimeoutError
from visnav.msgs.srv import get_service_type

SCRIPTS = Path(__file__).parent / "scripts"
Trigger = get_service_type("std_srvs/srv/Trigger")
SetBool = get_service_type("std_srvs/srv/SetBool")


@pytest.fixture
def server(start_script: Callable[..., subprocess.Popen[str]]) -> subprocess.Popen[str]:
    return start_script(SCRIPTS / "service_server.py", "60")


@pytest.fixture
def node(domain: int) -> Iterator[Node]:
    with Context(domain) as ctx:
        yield Node("client", context=ctx, start_parameter_services=False)


def test_blocking_call_answers_errors_and_times_out(
    server: subprocess.Popen[str], node: Node
) -> None:
    setb = node.create_client(SetBool, "/srv/set_bool")
    assert setb.wait_for_service(10.0)
    assert setb.call(SetBool.Request(data=True), timeout_sec=10.0).message == "on"
    assert setb.call(SetBool.Request(data=False)).message == "off"  # no timeout
    with pytest.raises(ServiceError, match="expected std_srvs/srv/SetBool_Request"):
        setb.call(Trigger.Request(), timeout_sec=1.0)  # type: ignore[arg-type]
    boom = node.create_client(Trigger, "/srv/boom")
    assert boom.wait_for_service(10.0)
    with pytest.raises(ServiceError, match="ValueError: the arm is not homed"):
        boom.call(Trigger.Request(), timeout_sec=10.0)
    slow = node.create_client(Trigger, "/srv/slow")
    assert slow.wait_for_service(10.0)
    start = time.monotonic()
    with pytest.raises(ServiceTimeoutError, match="no response within 1 s"):
        slow.call(Trigger.Request(), timeout_sec=1.0)
    assert 0.9 < time.monotonic() - start < 3.0
    nobody = node.create_client(Trigger, "/srv/nobody")
    start = time.monotonic()
    with pytest.raises(ServiceError, match="no response"):
        nobody.call(Trigger.Request(), timeout_sec=5.0)  # no queryable: fails at once
    assert time.monotonic() - start < 2.0


def test_blocking_call_fails_at_once_when_the_server_dies_mid_call(
    server: subprocess.Popen[str], node: Node
) -> None:
    client = node.create_client(Trigger, "/srv/slow")
    assert client.wait_for_service(10.0)
    outcome: list[Any] = []

    def call() -> None:
        start = time.monotonic()
        try:
            client.call(Trigger.Request(), timeout_sec=20.0)
        except Exception as exc:  # noqa: BLE001 - checked below
            outcome.append(exc)
        outcome.append(time.monotonic() - start)

    caller = threading.Thread(target=call)
    caller.start()
    time.sleep(1.0)  # the server is inside its callback now
    server.kill()
    caller.join(15.0)
    assert not caller.is_alive(), "call() hung after the server died"
    exc, elapsed = outcome
    assert isinstance(exc, ServiceError)
    assert not isinstance(exc, ServiceTimeoutError)
    assert "the server went away before answering" in str(exc)
    assert elapsed < 12.0  # well before its 20 s timeout
