"""Services in one process: rclpy's API, the executor's fairness and fault isolation."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from visnav.graph import Context, Future, GraphError, Node, ServiceError, ServiceTimeoutError
from visnav.graph.qos import QoSProfile
from visnav.graph.service import decode_service_attachment, encode_service_attachment
from visnav.msgs import String
from visnav.msgs.construct import message_from_dict
from visnav.msgs.errors import UnknownMessageTypeError
from visnav.msgs.serde import deserialize, serialize, typestore
from visnav.msgs.srv import SERVICE_DEFINITIONS, get_service_type

Trigger = get_service_type("std_srvs/srv/Trigger")
SetBool = get_service_type("std_srvs/srv/SetBool")
Empty = get_service_type("std_srvs/srv/Empty")
GetPlan = get_service_type("nav_msgs/srv/GetPlan")


@pytest.fixture
def ctx() -> Iterator[Context]:
    with Context(transport="local") as c:
        yield c


def _echo(req: Any, resp: Any) -> Any:
    resp.success = bool(req.data)
    resp.message = "on" if req.data else "off"
    return resp


def test_service_types_round_trip_and_hash_as_jazzy() -> None:
    for name in SERVICE_DEFINITIONS:
        stype = get_service_type(name)
        for cls in (stype.Request, stype.Response):
            msg = message_from_dict(cls.__msgtype__, {})
            data = serialize(msg)
            assert serialize(deserialize(data, cls.__msgtype__)) == data
    # the RIHS01 hashes of ROS 2 Jazzy's generated code (std_srvs), so keys match rmw_zenoh's
    store = typestore()
    assert store.hash_rihs01("std_srvs/srv/SetBool") == (
        "RIHS01_abe9e4bb6b41b40e6789712c00ec8871923e089af3f667a79992a428cff2da0a"
    )
    assert store.hash_rihs01("std_srvs/srv/Trigger") == (
        "RIHS01_eeff2cd6fa5ad9d27cdf4dec64818317839b62f212a91e6b5304b634b2062c5f"
    )
    assert get_service_type("std_srvs/Trigger") is Trigger  # ROS 1 spelling
    with pytest.raises(UnknownMessageTypeError, match="did you mean std_srvs/srv/SetBool"):
        get_service_type("std_srvs/srv/SetBol")


def test_attachment_layout() -> None:
    gid = bytes(range(16))
    data = encode_service_attachment(7, 123, gid)
    assert len(data) == 33
    assert decode_service_attachment(data) == (7, 123, gid)
    assert decode_service_attachment(data[:-1]) is None
    assert decode_service_attachment(None) is None


def test_call_async_in_process_returns_the_response_object(ctx: Context) -> None:
    server = Node("server", context=ctx)
    server.create_service(SetBool, "set", _echo)
    client = Node("client", context=ctx).create_client(SetBool, "/set")
    assert client.service_is_ready()
    assert client.wait_for_service(0.0)
    future = client.call_async(SetBool.Request(data=True))
    assert not future.done()
    assert ctx.spin_until(future.done, 2.0)
    assert future.result().success is True
    assert future.result().message == "on"


def test_several_types_including_nested_requests(ctx: Context) -> None:
    node = Node("planner", context=ctx)

    def plan(req: Any, resp: Any) -> Any:
        resp.plan.header.frame_id = req.goal.header.frame_id
        resp.plan.poses = [req.start, req.goal]
        return resp

    node.create_service(GetPlan, "make_plan", plan)
    node.create_service(Empty, "clear", lambda _q, r: r)
    req = message_from_dict(
        GetPlan.request_type_name,
        {"start": {"pose": {"position": {"x": 1.0}}}, "goal": {"header": {"frame_id": "map"}}},
    )
    f1 = node.create_client(GetPlan, "make_plan").call_async(req)
    f2 = node.create_client(Empty, "clear").call_async(Empty.Request())
    assert ctx.spin_until(lambda: f1.done() and f2.done(), 2.0)
    assert f1.result().plan.header.frame_id == "map"
    assert f1.result().plan.poses[0].pose.position.x == 1.0
    assert isinstance(f2.result(), Empty.Response)


def test_done_callbacks_run_in_the_executor(ctx: Context) -> None:
    node = Node("n", context=ctx)
    node.create_service(Trigger, "t", lambda _q, r: r)
    client = node.create_client(Trigger, "t")
    seen: list[tuple[bool, int]] = []
    future = client.call_async(Trigger.Request())
    future.add_done_callback(lambda f: seen.append((f.done(), threading.get_ident())))
    assert ctx.spin_until(lambda: bool(seen), 2.0)
    assert seen == [(True, threading.get_ident())]
    # added after completion: still runs in the executor
    future.add_done_callback(lambda f: seen.append((f.done(), 0)))
    assert ctx.spin_until(lambda: len(seen) == 2, 2.0)


def test_blocking_call_from_another_thread(ctx: Context) -> None:
    node = Node("n", context=ctx)
    node.create_service(SetBool, "s", _echo)
    client = node.create_client(SetBool, "s")
    out: list[Any] = []
    worker = threading.Thread(target=lambda: out.append(client.call(SetBool.Request(data=False))))
    worker.start()
    assert ctx.spin_until(lambda: bool(out), 5.0)
    worker.join()
    assert out[0].message == "off"


def test_call_from_inside_a_callback_is_an_error_not_a_deadlock(ctx: Context) -> None:
    node = Node("n", context=ctx)
    node.create_service(Trigger, "t", lambda _q, r: r)
    client = node.create_client(Trigger, "t")
    errors: list[BaseException] = []

    def tick() -> None:
        try:
            client.call(Trigger.Request(), timeout_sec=1.0)
        except GraphError as exc:
            errors.append(exc)

    timer = node.create_timer(0.001, tick)
    assert ctx.spin_until(lambda: bool(errors), 2.0)
    timer.cancel()
    assert "call_async" in str(errors[0])


def test_server_exception_fails_the_future_and_the_node_keeps_running(ctx: Context) -> None:
    node = Node("n", context=ctx)

    def boom(_req: Any, _resp: Any) -> Any:
        raise RuntimeError("motor driver offline")

    node.create_service(Trigger, "boom", boom)
    client = node.create_client(Trigger, "boom")
    future = client.call_async(Trigger.Request())
    assert ctx.spin_until(future.done, 2.0)
    exc = future.exception()
    assert isinstance(exc, ServiceError)
    assert "'/boom'" in str(exc)
    assert "RuntimeError: motor driver offline" in str(exc)
    with pytest.raises(ServiceError, match="motor driver offline"):
        future.result()
    assert ctx.faults.count("/n") == 1  # logged at the fault boundary, node and service named
    # still serving
    again = client.call_async(Trigger.Request())
    assert ctx.spin_until(again.done, 2.0)
    assert isinstance(again.exception(), ServiceError)


def test_wrong_request_and_response_types(ctx: Context) -> None:
    node = Node("n", context=ctx)
    node.create_service(Trigger, "bad", lambda _q, _r: String(data="x"))
    client = node.create_client(Trigger, "bad")
    with pytest.raises(ServiceError, match="expected std_srvs/srv/Trigger_Request"):
        client.call_async(SetBool.Request(data=True))
    future = client.call_async(Trigger.Request())
    assert ctx.spin_until(future.done, 2.0)
    assert "returned std_msgs/msg/String" in str(future.exception())


def test_full_queue_answers_the_oldest_request_with_an_error(ctx: Context) -> None:
    node = Node("n", context=ctx)
    node.create_service(Trigger, "t", lambda _q, r: r, qos_profile=QoSProfile(depth=2))
    client = node.create_client(Trigger, "t")
    futures = [client.call_async(Trigger.Request()) for _ in range(3)]
    assert futures[0].done()
    assert "queue (depth 2) was full" in str(futures[0].exception())
    assert ctx.spin_until(lambda: all(f.done() for f in futures), 2.0)
    assert all(f.exception() is None for f in futures[1:])


def test_requests_are_served_fairly_beside_a_busy_topic(ctx: Context) -> None:
    node = Node("n", context=ctx)
    order: list[str] = []
    node.create_subscription(String, "busy", lambda m: order.append("msg"), 100)
    node.create_service(Trigger, "t", lambda _q, r: (order.append("srv"), r)[1])
    pub = node.create_publisher(String, "busy", 100)
    for _ in range(20):
        pub.publish(String(data="x"))
    client = node.create_client(Trigger, "t")
    futures = [client.call_async(Trigger.Request()) for _ in range(3)]
    ctx.spin_until(lambda: all(f.done() for f in futures), 2.0)
    # one request per turn of the ring: each waits for at most one message callback
    first = order.index("srv")
    assert first <= 1
    assert order[first : first + 5] == ["srv", "msg", "srv", "msg", "srv"]


def test_names_follow_namespace_and_remapping(ctx: Context) -> None:
    node = Node("cam", namespace="/robot", context=ctx, remappings={"reset": "/hw/reset"})
    s1 = node.create_service(Trigger, "calibrate", lambda _q, r: r)
    s2 = node.create_service(Trigger, "reset", lambda _q, r: r)
    s3 = node.create_service(Trigger, "~/private", lambda _q, r: r)
    assert (s1.srv_name, s2.srv_name, s3.srv_name) == (
        "/robot/calibrate",
        "/hw/reset",
        "/robot/cam/private",
    )
    names = dict(node.get_service_names_and_types())
    assert names["/hw/reset"] == ["std_srvs/srv/Trigger"]
    assert "/robot/cam/get_parameters" in names


def test_timeouts_and_missing_servers(ctx: Context) -> None:
    node = Node("n", context=ctx)
    node.create_service(Trigger, "slow", lambda _q, r: r)
    client = node.create_client(Trigger, "slow")
    start = time.monotonic()
    with pytest.raises(ServiceTimeoutError, match=r"no response within 0\.2 s"):
        client.call(Trigger.Request(), timeout_sec=0.2)  # nobody spins: never served
    assert time.monotonic() - start < 1.0
    future = client.call_async(Trigger.Request(), timeout_sec=0.1)
    assert future.wait(2.0)
    assert isinstance(future.exception(), TimeoutError)
    missing = node.create_client(Trigger, "nobody")
    assert not missing.wait_for_service(0.1)
    with pytest.raises(ServiceError, match="no server"):
        missing.call(Trigger.Request(), timeout_sec=1.0)


def test_destroying_a_server_fails_its_queued_calls(ctx: Context) -> None:
    node = Node("n", context=ctx)
    server = node.create_service(Trigger, "t", lambda _q, r: r)
    client = node.create_client(Trigger, "t")
    future = client.call_async(Trigger.Request())
    node.destroy_service(server)
    assert "destroyed before answering" in str(future.exception())
    assert not client.service_is_ready()
    assert server not in node.services
    node.destroy_client(client)
    assert client not in node.clients


def test_future_basics() -> None:
    fut: Future[int] = Future()
    calls: list[int | None] = []
    fut.add_done_callback(lambda f: calls.append(f.result()))
    assert fut.result() is None
    assert not fut.wait(0.01)
    fut.set_result(3)
    fut.set_result(4)  # ignored once done
    assert calls == [3]
    assert fut.done()
    assert fut.result() == 3
    other: Future[int] = Future()
    other.cancel()
    assert other.cancelled()
    assert other.done()
    other.set_exception(ValueError("late"))
    assert other.exception() is None


def test_future_wait_wakes_every_waiting_thread_and_times_out() -> None:
    fut: Future[int] = Future()
    woke: list[bool] = []
    threads = [threading.Thread(target=lambda: woke.append(fut.wait(5.0))) for _ in range(4)]
    for t in threads:
        t.start()
    time.sleep(0.05)
    assert woke == []
    t0 = time.monotonic()
    assert not Future().wait(0.05)
    assert time.monotonic() - t0 >= 0.04
    assert not Future().wait(0.0)
    fut.set_result(1)
    for t in threads:
        t.join(5.0)
    assert woke == [True] * 4
    assert fut.wait(0.0)
    assert fut.wait(None)
    hooks: list[str] = []
    late: Future[int] = Future()
    late.on_complete(lambda: hooks.append("before"))
    late.set_exception(ValueError("x"))
    late.on_complete(lambda: hooks.append("after"))
    assert hooks == ["before", "after"]
    assert late.wait(1.0)


def test_service_codecs_match_the_general_serde_and_word_its_errors() -> None:
    from visnav.graph.service_codec import Decoder, Encoder, message_factory
    from visnav.msgs.construct import default_message
    from visnav.msgs.errors import MessageError

    for name in SERVICE_DEFINITIONS:
        stype = get_service_type(name)
        for type_name in (stype.request_type_name, stype.response_type_name):
            fresh = message_factory(type_name)()
            assert repr(fresh) == repr(default_message(type_name))
            assert fresh is not message_factory(type_name)()
            data = bytes(Encoder(type_name)(fresh))
            assert data == serialize(fresh)
            assert repr(Decoder(type_name)(data)) == repr(fresh)
    msg = SetBool.Response(success=True, message="héllo")
    data = bytes(Encoder(SetBool.response_type_name)(msg))
    assert data == serialize(msg)
    assert Decoder(SetBool.response_type_name)(data) == msg
    with pytest.raises(MessageError, match="cannot deserialize"):
        Decoder(SetBool.response_type_name)(data[:-3])
    with pytest.raises(MessageError, match="cannot deserialize"):
        Decoder(SetBool.response_type_name)(b"\x00\x01")
    with pytest.raises(MessageError, match="cannot serialize"):
        Encoder(SetBool.response_type_name)(SetBool.Response(success=True, message=5))
    big_endian = b"\x00\x00\x00\x00\x01"  # CDR_BE: the general path decodes it
    assert Decoder(SetBool.request_type_name)(big_endian) == SetBool.Request(data=True)
    # a large message is decoded from a view of its buffer, a small one from a copy
    big = SetBool.Response(success=False, message="x" * 10_000)
    data = bytes(Encoder(SetBool.response_type_name)(big))
    assert Decoder(SetBool.response_type_name)(data) == big
    with pytest.raises(MessageError, match="cannot deserialize"):
        Decoder(SetBool.response_type_name)(data[:-3])


def test_large_in_process_request_is_not_copied(ctx: Context) -> None:
    set_map = get_service_type("nav_msgs/srv/SetMap")
    node = Node("n", context=ctx)
    seen: list[Any] = []
    node.create_service(set_map, "set_map", lambda q, r: (seen.append(q), r)[1])
    req = set_map.Request(
        map=message_from_dict("nav_msgs/msg/OccupancyGrid", {}),
        initial_pose=message_from_dict("geometry_msgs/msg/PoseWithCovarianceStamped", {}),
    )
    req.map.data = np.zeros(1_000_000, dtype=np.int8)
    future = node.create_client(set_map, "set_map").call_async(req)
    assert ctx.spin_until(future.done, 2.0)
    assert seen[0] is req


def test_token_declarer_declares_in_order_and_honours_early_undeclare() -> None:
    from visnav.graph.token_declarer import TokenDeclarer

    declared: list[str] = []
    gate = threading.Event()

    class Handle:
        def __init__(self, key: str) -> None:
            self.key = key

        def undeclare(self) -> None:
            declared.remove(self.key)

    def declare(key: str) -> Handle:
        gate.wait(5.0)
        declared.append(key)
        return Handle(key)

    declarer = TokenDeclarer(declare)
    a, b, c = (declarer.submit(k) for k in "abc")
    b.undeclare()  # before the thread got to it: never declared
    gate.set()
    assert declarer.flush(5.0)
    assert declared == ["a", "c"]
    a.undeclare()
    assert declared == ["c"]
    declarer.close()
    assert declarer.submit("d") is not None
    assert declared == ["c"]
    c.undeclare()
