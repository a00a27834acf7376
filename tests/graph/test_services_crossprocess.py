"""Services between real processes (Zenoh, rmw_zenoh's layout) in a private domain."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Node, ServiceError, ServiceTimeoutError
from visnav.graph.keys import parse_liveliness_token
from visnav.msgs.construct import message_from_dict
from visnav.msgs.srv import get_service_type

SCRIPTS = Path(__file__).parent / "scripts"
Trigger = get_service_type("std_srvs/srv/Trigger")
SetBool = get_service_type("std_srvs/srv/SetBool")
GetMap = get_service_type("nav_msgs/srv/GetMap")
SetMap = get_service_type("nav_msgs/srv/SetMap")


@pytest.fixture
def server(start_script: Callable[..., subprocess.Popen[str]]) -> subprocess.Popen[str]:
    return start_script(SCRIPTS / "service_server.py", "60")


@pytest.fixture
def node(domain: int) -> Iterator[Node]:
    with Context(domain) as ctx:
        yield Node("client", context=ctx, start_parameter_services=False)


def test_calls_of_several_types_across_processes(server: subprocess.Popen[str], node: Node) -> None:
    trig = node.create_client(Trigger, "/srv/trigger")
    setb = node.create_client(SetBool, "/srv/set_bool")
    assert trig.wait_for_service(10.0)
    assert setb.wait_for_service(10.0)
    assert trig.call(Trigger.Request(), timeout_sec=5.0).message == "call 1"
    reply = setb.call(SetBool.Request(data=True), timeout_sec=5.0)
    assert (reply.success, reply.message) == (True, "on")
    future = setb.call_async(SetBool.Request(data=False))
    assert future.wait(5.0)
    assert future.result().message == "off"
    # the graph shows the server's tokens as rmw_zenoh writes them (SS, the service type)
    servers = list(node.context.graph.service_endpoints("/srv/trigger"))
    kinds = {e.kind for e in servers}
    assert kinds >= {"service_server", "service_client"}
    key = next(k for k in node.context.graph._tokens if "/SS/" in k and "%trigger" in k)
    token = parse_liveliness_token(key)
    assert token.type_name == "std_srvs/srv/Trigger"
    assert token.type_hash.startswith("RIHS01_eeff2cd6")


def test_one_megabyte_both_ways(server: subprocess.Popen[str], node: Node) -> None:
    get_map = node.create_client(GetMap, "/srv/get_map")
    set_map = node.create_client(SetMap, "/srv/set_map")
    assert get_map.wait_for_service(10.0)
    assert set_map.wait_for_service(10.0)
    grid = get_map.call(GetMap.Request(), timeout_sec=10.0).map
    assert grid.info.width == 1000
    assert len(grid.data) == 1_000_000
    assert int(grid.data[123]) == 23
    req = SetMap.Request(
        map=message_from_dict(
            "nav_msgs/msg/OccupancyGrid", {"info": {"width": 1000, "height": 1000}}
        ),
        initial_pose=message_from_dict("geometry_msgs/msg/PoseWithCovarianceStamped", {}),
    )
    req.map.data = np.ones(1_000_000, dtype=np.int8)
    assert set_map.call(req, timeout_sec=10.0).success is True


def test_concurrent_calls_from_many_clients(server: subprocess.Popen[str], domain: int) -> None:
    results: list[str] = []
    errors: list[BaseException] = []
    lock = threading.Lock()

    def worker(i: int) -> None:
        with Context(domain) as ctx:
            client = Node(f"c{i}", context=ctx, start_parameter_services=False).create_client(
                Trigger, "/srv/trigger"
            )
            try:
                assert client.wait_for_service(15.0)
                for _ in range(10):
                    reply = client.call(Trigger.Request(), timeout_sec=10.0)
                    with lock:
                        results.append(reply.message)
            except BaseException as exc:  # noqa: BLE001 - reported below
                errors.append(exc)

    threads = [threading.Thread(target=worker, args=(i,)) for i in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
    assert not errors, errors
    assert len(results) == 60
    # every call was served once: the server numbered them 1..60
    assert sorted(int(m.split()[1]) for m in results) == list(range(1, 61))


def test_server_exception_reaches_the_client(server: subprocess.Popen[str], node: Node) -> None:
    client = node.create_client(Trigger, "/srv/boom")
    assert client.wait_for_service(10.0)
    start = time.monotonic()
    with pytest.raises(ServiceError, match="ValueError: the arm is not homed") as info:
        client.call(Trigger.Request(), timeout_sec=10.0)
    assert "'/srv/boom'" in str(info.value)
    assert time.monotonic() - start < 5.0
    # the server keeps serving
    trig = node.create_client(Trigger, "/srv/trigger")
    assert trig.wait_for_service(5.0)
    assert trig.call(Trigger.Request(), timeout_sec=5.0).success


def test_server_killed_mid_call_fails_the_client_within_its_timeout(
    server: subprocess.Popen[str], node: Node
) -> None:
    client = node.create_client(Trigger, "/srv/slow")
    assert client.wait_for_service(10.0)
    future = client.call_async(Trigger.Request(), timeout_sec=8.0)
    time.sleep(0.5)  # the server is inside its callback now
    start = time.monotonic()
    server.kill()
    assert future.wait(10.0), "the client hung after the server died"
    assert time.monotonic() - start < 8.5
    assert isinstance(future.exception(), ServiceError)
    assert not client.wait_for_service(3.0) or True  # its token goes with the process
    # a call with a timeout to a dead service never hangs past the timeout
    start = time.monotonic()
    with pytest.raises((ServiceError, ServiceTimeoutError)):
        client.call(Trigger.Request(), timeout_sec=2.0)
    assert time.monotonic() - start < 3.0


def test_wait_for_service_when_the_server_starts_at_the_same_moment(domain: int) -> None:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    proc = subprocess.Popen(
        [sys.executable, str(SCRIPTS / "service_server.py"), "30"],
        env=env,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        with Context(domain) as ctx:
            client = Node("early", context=ctx).create_client(SetBool, "/srv/set_bool")
            assert client.wait_for_service(30.0)
            assert client.call(SetBool.Request(data=True), timeout_sec=10.0).success
    finally:
        proc.kill()
        proc.wait(10)


def _mesh_round(domain: int, count: int) -> list[str]:
    env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
    procs = [
        subprocess.Popen(
            [sys.executable, str(SCRIPTS / "mesh_peer.py"), str(i), str(count), "20"],
            env=env,
            stdout=subprocess.PIPE,
            text=True,
        )
        for i in range(count)
    ]
    outs: list[str] = []
    for p in procs:
        try:
            out, _ = p.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            p.kill()
            out = "timeout"
        outs.append(out.strip())
    return [o for o in outs if o != "ok"]


@pytest.mark.slow
@pytest.mark.ci
def test_processes_started_at_once_all_see_each_other(domain: int) -> None:
    """N processes started together, many times: topics and services all discovered."""
    failures: list[Any] = []
    for round_ in range(6):
        bad = _mesh_round(domain * 10 + round_, 4 if round_ % 2 else 2)
        if bad:
            failures.append((round_, bad))
    assert not failures, failures
