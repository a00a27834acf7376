"""The Foxglove server against a Python WebSocket client speaking the published protocol."""

from __future__ import annotations

import asyncio
import base64
import json
import socket
import struct
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from websockets.exceptions import InvalidStatus

from visnav.bridge.foxglove import FoxgloveError, FoxgloveOptions, FoxgloveServer
from visnav.graph import Context, DurabilityPolicy, Node, QoSProfile
from visnav.msgs.construct import default_message
from visnav.msgs.image import numpy_to_image
from visnav.msgs.serde import deserialize, get_message_class, message_definition, serialize
from visnav.msgs.srv import get_service_type
from visnav.msgs.time import ns_to_time

from .conftest import Spun, channels_until, client, recv_binary, recv_json

Image = get_message_class("sensor_msgs/msg/Image")
OccupancyGrid = get_message_class("nav_msgs/msg/OccupancyGrid")
PoseStamped = get_message_class("geometry_msgs/msg/PoseStamped")
Clock = get_message_class("rosgraph_msgs/msg/Clock")
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def _image(value: int) -> Any:
    return numpy_to_image(np.full((6, 8, 3), value, np.uint8), "rgb8")


def _grid() -> Any:
    grid = default_message("nav_msgs/msg/OccupancyGrid")
    grid.header.frame_id = "map"
    grid.info.width, grid.info.height, grid.info.resolution = 4, 3, 0.05
    grid.data = np.array([0, 100, -1, 0] * 3, dtype=np.int8)
    return grid


def _run(coro: Any) -> Any:
    return asyncio.run(coro)


@pytest.mark.parametrize("subprotocol", ["foxglove.websocket.v1", "foxglove.sdk.v1"])
def test_both_subprotocols_are_accepted(
    make_server: Callable[..., FoxgloveServer], subprotocol: str
) -> None:
    server = make_server()

    async def go() -> dict[str, Any]:
        async with client(server.url, subprotocol) as ws:
            assert ws.subprotocol == subprotocol
            return await recv_json(ws, "serverInfo")

    info = _run(go())
    assert set(info["capabilities"]) == {
        "clientPublish",
        "parameters",
        "parametersSubscribe",
        "services",
        "connectionGraph",
        "assets",
    }
    assert info["supportedEncodings"] == ["cdr", "json"]
    assert info["metadata"]["ROS_DISTRO"] == "humble"


def test_a_client_offering_no_foxglove_subprotocol_is_refused(
    make_server: Callable[..., FoxgloveServer],
) -> None:
    server = make_server()

    async def go() -> None:
        async with client(server.url, "chat"):
            pass

    with pytest.raises(InvalidStatus, match="400"):
        _run(go())


def test_binds_loopback_by_default_and_names_a_busy_port(graph: Spun) -> None:
    assert FoxgloveOptions().address == "127.0.0.1"
    assert FoxgloveOptions().port == 8765
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        node = Node("fg_busy", context=graph.ctx)
        server = FoxgloveServer(node, FoxgloveOptions(port=port))
        with pytest.raises(FoxgloveError, match=rf"127\.0\.0\.1:{port}.*--port"):
            server.start()


def test_bad_options_are_refused() -> None:
    with pytest.raises(FoxgloveError, match="topic_whitelist"):
        FoxgloveOptions(topic_whitelist=("(",))
    with pytest.raises(FoxgloveError, match="playback"):
        FoxgloveOptions(capabilities=("playback",))


def test_topics_advertised_with_schema_and_sent_as_published(
    graph: Spun, make_server: Callable[..., FoxgloveServer]
) -> None:
    pubs = Node("pubs", context=graph.ctx)
    grid_pub = pubs.create_publisher(OccupancyGrid, "/map", LATCHED)
    grid_pub.publish(_grid())
    server = make_server()

    async def go() -> tuple[dict[str, Any], dict[str, Any], bytes, bytes]:
        async with client(server.url) as ws:
            chans = await channels_until(ws, {"/map"})
            # a topic that appears later is advertised then
            img_pub = pubs.create_publisher(Image, "/camera/image_raw", 10)
            chans |= await channels_until(ws, {"/camera/image_raw"})
            sub = [
                {"id": 1, "channelId": chans["/map"]["id"]},
                {"id": 2, "channelId": chans["/camera/image_raw"]["id"]},
            ]
            await ws.send(json.dumps({"op": "subscribe", "subscriptions": sub}))
            grid_frame = await recv_binary(ws, 1)
            await asyncio.sleep(0.2)
            img_pub.publish(_image(9))
            img_frame = await recv_binary(ws, 1)
            return chans["/map"], chans["/camera/image_raw"], grid_frame, img_frame

    map_ch, img_ch, grid_frame, img_frame = _run(go())
    assert map_ch["encoding"] == "cdr"
    assert map_ch["schemaEncoding"] == "ros2msg"
    assert map_ch["schemaName"] == "nav_msgs/msg/OccupancyGrid"
    assert map_ch["schema"] == message_definition("nav_msgs/msg/OccupancyGrid")
    assert "MSG: nav_msgs/MapMetaData" in map_ch["schema"]
    _op, sid, stamp = struct.unpack_from("<BIQ", grid_frame)
    assert sid == 1
    assert abs(stamp - time.time_ns()) < 10e9
    assert grid_frame[13:] == serialize(_grid())  # latched: delivered to the late subscriber
    assert img_ch["schemaName"] == "sensor_msgs/msg/Image"
    _op, sid, _stamp = struct.unpack_from("<BIQ", img_frame)
    assert sid == 2
    assert img_frame[13:] == serialize(_image(9))


def test_remote_cdr_bytes_are_forwarded_unchanged(domain: int) -> None:
    """Between processes (Zenoh) the payload is the publisher's bytes, not re-serialized."""
    with Context(domain) as pctx, Context(domain) as sctx:
        spun = Spun(sctx)
        try:
            pub = Node("cam", context=pctx).create_publisher(Image, "/camera/image_raw", 10)
            server = FoxgloveServer(Node("fg", context=sctx), FoxgloveOptions(port=0))
            server.start()

            async def go() -> bytes:
                async with client(server.url) as ws:
                    chans = await channels_until(ws, {"/camera/image_raw"}, timeout=10)
                    cid = chans["/camera/image_raw"]["id"]
                    sub = {"op": "subscribe", "subscriptions": [{"id": 7, "channelId": cid}]}
                    await ws.send(json.dumps(sub))
                    async with asyncio.timeout(10):
                        while True:
                            pub.publish(_image(3))
                            try:
                                return await recv_binary(ws, 1, timeout=0.2)
                            except TimeoutError:
                                continue

            frame = _run(go())
            server.close()
        finally:
            spun.stop()
    assert frame[13:] == serialize(_image(3))
    assert deserialize(frame[13:], "sensor_msgs/msg/Image").width == 8


def test_unadvertised_when_the_last_publisher_leaves(
    graph: Spun, make_server: Callable[..., FoxgloveServer]
) -> None:
    pubs = Node("pubs", context=graph.ctx)
    pub = pubs.create_publisher(Image, "/tmp_topic", 10)
    server = make_server()

    async def go() -> tuple[int, list[int]]:
        async with client(server.url) as ws:
            chans = await channels_until(ws, {"/tmp_topic"})
            cid = chans["/tmp_topic"]["id"]
            sub = {"op": "subscribe", "subscriptions": [{"id": 3, "channelId": cid}]}
            await ws.send(json.dumps(sub))
            await asyncio.sleep(0.3)
            assert len(server.node.subscriptions) >= 1
            pubs.destroy_publisher(pub)
            gone = await recv_json(ws, "unadvertise")
            await asyncio.sleep(0.3)
            return cid, gone["channelIds"]

    before = len(server.node.subscriptions)
    cid, gone = _run(go())
    assert cid in gone
    assert len(server.node.subscriptions) == before  # the client's subscription went with it


def test_topic_whitelist_and_hidden_topics(
    graph: Spun, make_server: Callable[..., FoxgloveServer]
) -> None:
    pubs = Node("pubs", context=graph.ctx)
    for topic in ("/camera/image_raw", "/camera/_hidden", "/other"):
        pubs.create_publisher(Image, topic, 10)
    server = make_server(topic_whitelist=("/camera/.*",))

    async def go() -> set[str]:
        async with client(server.url) as ws:
            chans = await channels_until(ws, {"/camera/image_raw"})
            await asyncio.sleep(0.5)
            return set(chans)

    assert _run(go()) == {"/camera/image_raw"}


def test_send_buffer_limit_drops_data_not_control(
    graph: Spun, make_server: Callable[..., FoxgloveServer]
) -> None:
    pubs = Node("pubs", context=graph.ctx)
    pub = pubs.create_publisher(Image, "/camera/image_raw", 10)
    server = make_server(send_buffer_limit=1000)
    big = numpy_to_image(np.zeros((100, 100, 3), np.uint8), "rgb8")  # 30 kB each

    async def go() -> int:
        async with client(server.url) as ws:
            chans = await channels_until(ws, {"/camera/image_raw"})
            cid = chans["/camera/image_raw"]["id"]
            await ws.send(
                json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": cid}]})
            )
            await asyncio.sleep(0.3)
            for _ in range(50):
                pub.publish(big)
            await asyncio.sleep(0.5)
            assert server.ws.clients[0].dropped >= 1
            n = 0
            while True:
                try:
                    await recv_binary(ws, 1, timeout=0.5)
                except TimeoutError:
                    return n
                n += 1

    received = _run(go())
    (conn,) = server.ws.clients or [None]
    assert 1 <= received < 50
    # the rest: dropped at the send buffer (counted) or by the keep-last subscription queue
    assert conn is None or (conn.dropped >= 1 and received + conn.dropped <= 50)


def test_client_publish_cdr_and_json(
    graph: Spun, make_server: Callable[..., FoxgloveServer]
) -> None:
    got: list[Any] = []
    Node("mb", context=graph.ctx).create_subscription(
        PoseStamped, "/move_base_simple/goal", got.append, 10
    )
    server = make_server()
    goal = default_message("geometry_msgs/msg/PoseStamped")
    goal.header.frame_id = "map"
    goal.pose.position.x = 2.5
    goal.pose.orientation.w = 1.0

    async def go() -> None:
        async with client(server.url) as ws:
            await recv_json(ws, "serverInfo")
            channels = [
                {
                    "id": 1,
                    "topic": "/move_base_simple/goal",
                    "encoding": "cdr",
                    "schemaName": "geometry_msgs/msg/PoseStamped",
                },
                {
                    "id": 2,
                    "topic": "/move_base_simple/goal",
                    "encoding": "json",
                    "schemaName": "geometry_msgs/PoseStamped",
                },
            ]
            await ws.send(json.dumps({"op": "advertise", "channels": channels}))
            await ws.send(b"\x01" + struct.pack("<I", 1) + serialize(goal))
            doc = {"header": {"frame_id": "map"}, "pose": {"position": {"x": -1.0, "y": 4.0}}}
            await ws.send(b"\x01" + struct.pack("<I", 2) + json.dumps(doc).encode())
            # not advertised, and not CDR: each answered with a status, the server goes on
            await ws.send(b"\x01" + struct.pack("<I", 9) + b"x")
            warning = await recv_json(ws, "status")
            assert "client channel 9" in warning["message"]
            await ws.send(b"\x01" + struct.pack("<I", 1) + b"\x00\x01\x00\x00\x01")
            warning = await recv_json(ws, "status")
            assert "geometry_msgs/msg/PoseStamped" in warning["message"]
            await ws.send(json.dumps({"op": "unadvertise", "channelIds": [1, 2]}))
            await asyncio.sleep(0.3)

    _run(go())
    assert [(g.pose.position.x, g.pose.position.y) for g in got] == [(2.5, 0.0), (-1.0, 4.0)]
    assert got[0].header.frame_id == "map"


def test_pose_estimate_reaches_initialpose(
    graph: Spun, make_server: Callable[..., FoxgloveServer]
) -> None:
    """Foxglove's "Publish pose estimate": PoseWithCovarianceStamped on /initialpose (AMCL)."""
    got: list[Any] = []
    cls = get_message_class("geometry_msgs/msg/PoseWithCovarianceStamped")
    Node("amcl", context=graph.ctx).create_subscription(cls, "/initialpose", got.append, 1)
    server = make_server()
    estimate = default_message("geometry_msgs/msg/PoseWithCovarianceStamped")
    estimate.header.frame_id = "map"
    estimate.pose.pose.position.x = -6.0
    estimate.pose.covariance[0] = 0.25

    async def go() -> None:
        async with client(server.url) as ws:
            ch = {
                "id": 4,
                "topic": "/initialpose",
                "encoding": "cdr",
                "schemaName": "geometry_msgs/msg/PoseWithCovarianceStamped",
            }
            await ws.send(json.dumps({"op": "advertise", "channels": [ch]}))
            await ws.send(b"\x01" + struct.pack("<I", 4) + serialize(estimate))
            await asyncio.sleep(0.3)

    _run(go())
    assert [(m.pose.pose.position.x, m.pose.covariance[0]) for m in got] == [(-6.0, 0.25)]


def test_client_topic_whitelist(make_server: Callable[..., FoxgloveServer]) -> None:
    server = make_server(client_topic_whitelist=("/move_base_simple/goal",))

    async def go() -> str:
        async with client(server.url) as ws:
            ch = {
                "id": 1,
                "topic": "/cmd_vel",
                "encoding": "cdr",
                "schemaName": "geometry_msgs/Twist",
            }
            await ws.send(json.dumps({"op": "advertise", "channels": [ch]}))
            return str((await recv_json(ws, "status"))["message"])

    assert "client_topic_whitelist" in _run(go())


def test_services_are_advertised_and_called(
    graph: Spun, make_server: Callable[..., FoxgloveServer]
) -> None:
    trigger = get_service_type("std_srvs/srv/Trigger")

    def answer(_req: Any, resp: Any) -> Any:
        resp.success, resp.message = True, "done"
        return resp

    Node("srv", context=graph.ctx).create_service(trigger, "/do_it", answer)
    server = make_server(service_whitelist=("/do_it", "/missing"))

    async def go() -> tuple[dict[str, Any], bytes, dict[str, Any]]:
        async with client(server.url) as ws:
            services = (await recv_json(ws, "advertiseServices"))["services"]
            svc = next(s for s in services if s["name"] == "/do_it")
            request = serialize(trigger.Request())
            frame = struct.pack("<BIII", 2, svc["id"], 42, 3) + b"cdr" + request
            await ws.send(frame)
            reply = await recv_binary(ws, 3)
            await ws.send(struct.pack("<BIII", 2, 999, 43, 3) + b"cdr" + request)
            failure = await recv_json(ws, "serviceCallFailure")
            return svc, reply, failure

    svc, reply, failure = _run(go())
    assert svc["name"] == "/do_it"
    assert svc["type"] == "std_srvs/srv/Trigger"
    assert svc["request"]["schemaName"] == "std_srvs/srv/Trigger_Request"
    assert svc["response"]["schema"] == message_definition("std_srvs/srv/Trigger_Response")
    _op, sid, call_id, n = struct.unpack_from("<BIII", reply)
    assert (sid, call_id, reply[13 : 13 + n]) == (svc["id"], 42, b"cdr")
    response = deserialize(reply[13 + n :], "std_srvs/srv/Trigger_Response")
    assert (response.success, response.message) == (True, "done")
    assert failure["callId"] == 43
    assert "not advertised" in failure["message"]


def test_parameters_get_set_and_updates(
    graph: Spun, make_server: Callable[..., FoxgloveServer]
) -> None:
    node = Node("planner", context=graph.ctx)
    node.declare_parameter("frequency", 5.0)
    node.declare_parameter("name", "x")
    node.declare_parameter("blob", b"\x01\x02")
    server = make_server()

    async def go() -> list[dict[str, Any]]:
        async with client(server.url) as ws:
            await recv_json(ws, "serverInfo")
            names = ["/planner.frequency", "/planner.name", "/planner.blob"]
            await ws.send(json.dumps({"op": "getParameters", "parameterNames": names, "id": "q"}))
            out = [await recv_json(ws, "parameterValues")]
            everything = {"op": "getParameters", "parameterNames": [], "id": "all"}
            await ws.send(json.dumps(everything))
            out.append(await recv_json(ws, "parameterValues"))
            sub = {"op": "subscribeParameterUpdates", "parameterNames": ["/planner.frequency"]}
            await ws.send(json.dumps(sub))
            new = [{"name": "/planner.frequency", "value": 8, "type": "float64"}]
            await ws.send(json.dumps({"op": "setParameters", "parameters": new, "id": "s"}))
            out.append(await recv_json(ws, "parameterValues"))
            out.append(await recv_json(ws, "parameterValues"))
            bad = [{"name": "/planner.frequency", "value": "fast"}]
            await ws.send(json.dumps({"op": "setParameters", "parameters": bad}))
            out.append(await recv_json(ws, "status"))
            return out

    got, everything, first, second, refused = _run(go())
    assert got["id"] == "q"
    assert got["parameters"] == [
        {"name": "/planner.frequency", "value": 5.0, "type": "float64"},
        {"name": "/planner.name", "value": "x"},
        {
            "name": "/planner.blob",
            "value": base64.b64encode(b"\x01\x02").decode(),
            "type": "byte_array",
        },
    ]
    assert everything["id"] == "all"
    names = {p["name"] for p in everything["parameters"]}
    assert {"/planner.frequency", "/planner.use_sim_time"} <= names
    # the update (no id) and the reply to setParameters (id "s"), in either order
    by_id = {m.get("id"): m for m in (first, second)}
    assert by_id["s"]["parameters"] == [
        {"name": "/planner.frequency", "value": 8.0, "type": "float64"}
    ]
    assert by_id[None]["parameters"][0]["value"] == 8.0
    assert node.get_parameter("frequency").value == 8.0
    assert "frequency" in refused["message"]


def test_time_from_clock(graph: Spun, make_server: Callable[..., FoxgloveServer]) -> None:
    clock_pub = Node("sim", context=graph.ctx).create_publisher(Clock, "/clock", 10)
    server = make_server(use_sim_time=True)
    assert "time" in server.capabilities

    async def go() -> int:
        async with client(server.url) as ws:
            info = await recv_json(ws, "serverInfo")
            assert "time" in info["capabilities"]
            await asyncio.sleep(0.3)
            clock_pub.publish(Clock(clock=ns_to_time(12_500_000_000)))
            frame = await recv_binary(ws, 2)
            return int(struct.unpack_from("<Q", frame, 1)[0])

    assert _run(go()) == 12_500_000_000


def test_close_disconnects_clients_and_frees_the_port(
    make_server: Callable[..., FoxgloveServer],
) -> None:
    server = make_server()
    port = server.port

    async def go() -> None:
        async with client(server.url) as ws:
            await recv_json(ws, "serverInfo")
            await asyncio.to_thread(server.close)
            async with asyncio.timeout(5):
                await ws.wait_closed()

    _run(go())
    assert server.ws.clients == []
    again = make_server(port=port)  # a restart gets the same port
    assert again.port == port
